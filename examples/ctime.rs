fn main() {
    let path = std::env::args().nth(1).unwrap();
    let scene = modal_contact::scene::Scene::from_file(std::path::Path::new(&path)).unwrap();
    let t0 = std::time::Instant::now();
    let c = modal_contact::compile::compile(&scene, 44100.0).unwrap();
    eprintln!("compile {:.2} s\n{}", t0.elapsed().as_secs_f64(), c.summary);
}
