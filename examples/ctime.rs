// scratch: compile time and peak RSS per scene, unlimited budget
fn rss_mb() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap();
    let l = s.lines().find(|l| l.starts_with("VmHWM")).unwrap();
    l.split_whitespace().nth(1).unwrap().parse::<f64>().unwrap() / 1024.0
}
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let scene = modal_contact::scene::Scene::from_file(std::path::Path::new(&path)).unwrap();
    let opts = modal_contact::compile::CompileOptions {
        budget: modal_contact::compile::CompileBudget::UNLIMITED,
        ..Default::default()
    };
    let ci = scene.object_index(&scene.contact.object).unwrap();
    let est = modal_contact::compile::CompileCost::estimate(
        &scene.object[ci],
        scene.contact.point.as_deref(),
        false,
        true,
    );
    let t0 = std::time::Instant::now();
    let c = modal_contact::compile::compile_opts(&scene, 44100.0, None, &opts).unwrap();
    eprintln!(
        "{path}: compile {:.3} s, peak RSS {:.0} MB; estimate {:.2e} flops {:.0} MB; {}",
        t0.elapsed().as_secs_f64(),
        rss_mb(),
        est.flops,
        est.bytes / 1e6,
        c.summary
            .lines()
            .find(|l| l.starts_with("contact phase"))
            .unwrap()
            .chars()
            .take(70)
            .collect::<String>()
    );
}
