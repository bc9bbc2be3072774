//! Activation never waits for a long compile (docs/plugin.md, "Parameter
//! changes: the swap design", items 5 and 6), through the BUILT release
//! plugin in clack-host: a user scene of 600 coupled modes takes far longer
//! to compile than `activate` may wait, so a realtime activation returns
//! before its scene is there (the first blocks are silent: a note struck
//! in them is not heard), the scene arrives a little later and plays;
//! `deactivate` while that compile runs returns, and the instance is
//! destroyed cleanly; an offline activation of the same state renders the
//! note in its first block (offline renders wait for their scenes).
//!
//! `cargo bench -p plugin-tests --bench activation` times activation over
//! every scene and a parameter sweep.

use plugin_tests::*;
use std::time::{Duration, Instant};

const RATE: f64 = 48_000.0;
const BLOCK: usize = 256;

/// A modal object of `n` modes, every one of them at the contact point.
fn big_scene(n: usize) -> String {
    let mut s = String::from(
        "version = 1\nname = \"big\"\nduration_s = 1.0\n\n[[object]]\nname = \"plate\"\n\
         kind = \"modal\"\npoints = [\"contact\", \"pickup\"]\n",
    );
    for k in 0..n {
        let f = 110.0 * (1.0 + k as f64).powf(1.3);
        let w = 1.0 / (1.0 + k as f64 * 0.01);
        s += &format!(
            "\n[[object.mode]]\nfreq_hz = {f}\nt60_s = {}\nweights = [{w}, {}]\n",
            2.0 / (1.0 + k as f64 * 0.02),
            if k % 2 == 0 { w } else { -w }
        );
    }
    s += "\n[hammer]\nmass_kg = 0.03\nheight_m = 0.001\nvelocity_m_per_s = -2.0\n\n\
          [contact]\nobject = \"plate\"\npoint = \"contact\"\nstiffness_n_per_m = 3e5\n\
          damping_n_s_per_m = 40.0\n\n[[pickup]]\nobject = \"plate\"\npoint = \"pickup\"\n\
          quantity = \"velocity\"\ngain = 0.5\n";
    s
}

fn big_state(bundle: &std::path::Path) -> Vec<u8> {
    let mut p = LoadedPlugin::load(bundle);
    let base = p.save_state();
    let path = out_dir().join("big-600-modes.toml");
    let text = big_scene(600);
    std::fs::write(&path, &text).unwrap();
    with_user_scene(&base, "big-600-modes", &text, &path)
}

fn silent(b: &[&[f32]; 2]) -> bool {
    b.iter().all(|c| c.iter().all(|x| *x == 0.0))
}

#[test]
fn a_long_compile_never_holds_activate_or_deactivate() {
    let bundle = clap_bundle(Variant::Release);
    let state = big_state(&bundle);

    // realtime: activate returns before the scene is compiled
    let mut p = LoadedPlugin::load_realtime(&bundle);
    p.load_state(&state);
    let t0 = Instant::now();
    let mut s = p.activate(RATE, 1, BLOCK);
    let activate_ms = t0.elapsed().as_secs_f64() * 1e3;
    let first = s.process(BLOCK, 0, &[on(0, 60, 0.9)]);
    assert!(
        silent(&first),
        "the first block sounds: activate waited for the whole compile"
    );
    let t0 = Instant::now();
    let mut pos = BLOCK;
    let mut heard = None;
    while t0.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
        let b = s.process(BLOCK, pos, &[on(pos, 60, 0.9)]);
        assert!(b.iter().all(|c| c.iter().all(|x| x.is_finite())));
        if !silent(&b) {
            heard = Some(t0.elapsed().as_secs_f64());
            break;
        }
        pos += BLOCK;
    }
    let heard = heard.expect("the scene never arrived");
    s.deactivate();
    println!(
        "600 coupled modes: activate returned after {activate_ms:.1} ms; the scene played \
         {heard:.2} s later"
    );

    // deactivate while the compile runs, then destroy
    let mut q = LoadedPlugin::load_realtime(&bundle);
    q.load_state(&state);
    let s = q.activate(RATE, 1, BLOCK);
    let t0 = Instant::now();
    s.deactivate();
    let deactivate_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t0 = Instant::now();
    drop(q);
    println!(
        "deactivate during the compile: {deactivate_ms:.2} ms; destroy (cancels and joins \
         the worker) {:.0} ms",
        t0.elapsed().as_secs_f64() * 1e3
    );

    // offline: the first block waits for the scene and plays the note
    let mut r = LoadedPlugin::load(&bundle);
    r.load_state(&state);
    let mut s = r.activate(RATE, 1, BLOCK);
    let first = s.process(BLOCK, 0, &[on(0, 60, 0.9)]);
    assert!(
        !silent(&first),
        "offline: the first block must play the note"
    );
    s.deactivate();
}
