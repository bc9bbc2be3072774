//! `cargo xtask render` as a batch, through the library the command runs:
//! every job renders and writes its sidecar even when another fails, the
//! failure names the job and fails the command, outputs are checked before
//! any work, and a job is a pure function of its inputs (same bytes twice).

use modal_testkit::scenes::preset_path;
use std::path::{Path, PathBuf};
use xtask::render::{plan, run, RenderArgs};

fn args(scenes: Vec<PathBuf>, out: &Path) -> RenderArgs {
    RenderArgs {
        scenes,
        out: out.to_path_buf(),
        trace: None,
        trace_format: Default::default(),
        plot: None,
        seconds: Some(0.25),
        rate: 44100.0,
        switching: None,
        notes: None,
        velocities: None,
        jobs: Some(2),
    }
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("xtask-batch-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn a_failing_job_does_not_stop_the_others_and_fails_the_command() {
    let dir = temp("fail");
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    std::fs::copy(preset_path("wood-block"), scenes.join("a-wood.toml")).unwrap();
    std::fs::write(scenes.join("b-broken.toml"), "version = 1\nname = 3\n").unwrap();
    std::fs::copy(preset_path("steel-plate"), scenes.join("c-plate.toml")).unwrap();
    let out = dir.join("out");
    let mut a = args(vec![scenes.clone()], &out);
    a.notes = Some("60,67".into());
    a.velocities = Some("40,127".into());
    let err = run(&a).expect_err("a job failed");
    assert!(err.to_string().contains("4 of 12 jobs failed"), "{err}");
    let names: Vec<String> = files(&out).into_iter().map(|f| f.0).collect();
    assert_eq!(names.len(), 16, "{names:?}");
    assert!(names.iter().all(|n| !n.starts_with("b-broken")));
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("c-plate_n067_v040.json")).unwrap())
            .unwrap();
    assert_eq!(side["note"], 67);
    assert_eq!(side["velocity"], 40);
    assert_eq!(side["rate_hz"], 44100.0);
    assert_eq!(side["samples"], 11025);
    assert_eq!(
        side["compile"]["contact"]["route"],
        "rank-one secular eigenvectors"
    );
    assert!(side["contacts"].as_u64().unwrap() >= 1);
    assert!(side["peak"].as_f64().unwrap() > 0.0);
    // a louder strike of the same note is louder (the velocity mapping)
    let loud: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("c-plate_n067_v127.json")).unwrap())
            .unwrap();
    assert!(loud["peak"].as_f64().unwrap() > side["peak"].as_f64().unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outputs_are_checked_before_any_work() {
    let dir = temp("paths");
    let blocker = dir.join("not-a-dir");
    std::fs::write(&blocker, "x").unwrap();
    let a = args(
        vec![preset_path("wood-block"), preset_path("bell")],
        &blocker.join("out"),
    );
    assert!(run(&a).is_err());
    // one scene: --out is the WAV, whose directory must exist
    let a = args(vec![preset_path("wood-block")], &dir.join("missing/x.wav"));
    let t0 = std::time::Instant::now();
    let e = run(&a).expect_err("missing directory");
    assert!(e.to_string().contains("does not exist"), "{e}");
    assert!(t0.elapsed().as_secs_f64() < 5.0);
    // two scene files with one stem would write one WAV twice
    let other = dir.join("x");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::copy(preset_path("bell"), other.join("wood-block.toml")).unwrap();
    let a = args(
        vec![preset_path("wood-block"), other.join("wood-block.toml")],
        &dir.join("out"),
    );
    let e = run(&a).expect_err("same output twice");
    assert!(e.to_string().contains("written twice"), "{e}");
    assert!(!dir.join("out").join("wood-block.wav").exists());
    // path arguments in a batch go next to each WAV
    let mut a = args(vec![preset_path("wood-block"), preset_path("bell")], &dir);
    a.trace = Some(Some(dir.join("t.csv")));
    assert!(plan(&a).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Each job is a pure function of its scene file and parameters: the same
/// batch twice (different thread counts) writes the same WAV bytes, and the
/// same trace and plot.
#[test]
fn the_same_job_twice_gives_the_same_bytes() {
    let dir = temp("det");
    let mut out = Vec::new();
    for (k, jobs) in [1, 2].into_iter().enumerate() {
        let d = dir.join(format!("run{k}"));
        let mut a = args(
            vec![preset_path("paper-bounce"), preset_path("marimba-bar")],
            &d,
        );
        a.jobs = Some(jobs);
        a.trace = Some(None);
        a.plot = Some(None);
        run(&a).unwrap();
        let mut a = args(vec![preset_path("glockenspiel-bar")], &d);
        a.notes = Some("72,79".into());
        a.jobs = Some(jobs);
        run(&a).unwrap();
        // sidecars hold timings: compare everything else
        out.push(
            files(&d)
                .into_iter()
                .filter(|(n, _)| !n.ends_with(".json"))
                .collect::<Vec<_>>(),
        );
    }
    assert_eq!(out[0].len(), 8);
    for (a, b) in out[0].iter().zip(&out[1]) {
        assert_eq!(a.0, b.0);
        assert!(a.1 == b.1, "{} differs between two runs", a.0);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
