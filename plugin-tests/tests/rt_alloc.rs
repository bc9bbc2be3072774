//! The allocation check really covers the plugin's `process`.
//!
//! The `rt-checks` bundles are built with debug assertions and nice-plug's
//! `assert_process_allocs`: any allocation inside `process` aborts the host
//! process. A stress render (many note-ons, voice stealing, releases on the
//! damped scene, parameter swaps including a preset change with its fade-out,
//! a switching change and a strike-position change) runs in a child process
//! (this test binary re-executed with `MODAL_CONTACT_CHILD_BUNDLE` set), so an
//! abort is observed rather than killing the test run. The `alloc-bug` build
//! allocates in `process` on purpose and must die; the clean build must not.

use modal_contact::plugin::params::ids;
use modal_contact::presets;
use plugin_tests::*;
use std::path::Path;
use std::process::{Command, Output};

const CHILD_ENV: &str = "MODAL_CONTACT_CHILD_BUNDLE";

fn param(at: usize, id: &str, value: f64) -> HostEvent {
    HostEvent::Param {
        at,
        id: param_id(id),
        value,
    }
}

/// Renders the stress script; returns (output, the same notes without the
/// parameter changes).
fn stress(bundle: &Path) -> ([Vec<f32>; 2], [Vec<f32>; 2], usize) {
    let rate = 44_100.0;
    let total = (rate * 3.0) as usize;
    let mut notes = Vec::new();
    for i in 0..48usize {
        let at = 50 + i * 1500;
        let key = 40 + (i * 7 % 36) as u8;
        notes.push(HostEvent::NoteOn {
            at,
            key,
            velocity: 0.1 + 0.018 * i as f64,
        });
        if i % 3 == 0 {
            notes.push(HostEvent::NoteOff { at: at + 700, key });
        }
    }
    // repeated notes on one key
    for i in 0..10usize {
        notes.push(HostEvent::NoteOn {
            at: 20_000 + 211 * i,
            key: 57,
            velocity: 0.7,
        });
    }
    let first_change = 30_000;
    let mut events = notes.clone();
    events.push(param(first_change, ids::HARDNESS, 0.6));
    events.push(param(first_change, ids::DECAY, 0.4));
    events.push(param(45_000, ids::STRIKE_CUSTOM, 1.0));
    events.push(param(45_000, ids::STRIKE_POS, 0.8));
    events.push(param(60_000, ids::SWITCHING, 0.0));
    events.push(param(75_000, ids::DAMPER, 1.0));
    events.push(param(
        90_000,
        ids::SCENE,
        presets::index_of("paper-string").unwrap() as f64,
    ));
    events.push(param(
        105_000,
        ids::SCENE,
        presets::index_of("steel-plate").unwrap() as f64,
    ));
    let mut spec = RenderSpec::new(rate, 256, total, events);
    spec.settle_after = vec![first_change, 45_000, 60_000, 75_000, 90_000, 105_000];
    spec.settle_ms = 300;
    let with = LoadedPlugin::load(bundle).render(&spec);
    let without = LoadedPlugin::load(bundle).render(&RenderSpec::new(rate, 256, total, notes));
    (with, without, first_change)
}

/// Does nothing unless spawned by `run_child`.
#[test]
fn child_render() {
    if let Ok(bundle) = std::env::var(CHILD_ENV) {
        let (with, without, change) = stress(Path::new(&bundle));
        let finite = with.iter().flatten().all(|v| v.is_finite());
        let swapped = with[0][change..] != without[0][change..];
        write_wav(&out_dir().join("rt-checks-stress.wav"), 44_100.0, &with);
        println!(
            "CHILD_RENDER_OK finite={finite} swapped={swapped} peak={:.4}",
            peak(&with[0])
        );
    }
}

fn run_child(bundle: &Path) -> Output {
    Command::new(std::env::current_exe().expect("test exe"))
        .args(["--exact", "child_render", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, bundle)
        .output()
        .expect("spawn child test process")
}

#[test]
fn rt_checks_build_runs_the_stress_render_without_allocating() {
    let out = run_child(&clap_bundle(Variant::RtChecks));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stdout
        .lines()
        .find(|l| l.contains("CHILD_RENDER_OK"))
        .unwrap_or_else(|| panic!("child failed: {:?}\n{stdout}\n{stderr}", out.status));
    println!("{line}");
    assert!(out.status.success(), "{:?}\n{stderr}", out.status);
    assert!(line.contains("finite=true"), "{line}");
    assert!(line.contains("swapped=true"), "{line}");
}

#[test]
fn alloc_bug_build_aborts_in_process() {
    let out = run_child(&clap_bundle(Variant::AllocBug));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        !out.status.success(),
        "child should die; stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(
            out.status.signal(),
            Some(6),
            "expected SIGABRT, got {:?}",
            out.status
        );
    }
    assert!(!stdout.contains("CHILD_RENDER_OK"));
    assert!(
        stderr.contains("memory allocation of"),
        "missing the allocation-check message; stderr:\n{stderr}"
    );
    println!(
        "alloc-bug build aborted as expected: {:?}; {}",
        out.status,
        stderr
            .lines()
            .find(|l| l.contains("memory allocation of"))
            .unwrap_or("")
    );
}
