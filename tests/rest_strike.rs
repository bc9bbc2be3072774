//! A strike on an object at rest takes both switches in O(N): the entry
//! skips the product with the zero object state, and the release writes the
//! free state the compiler stored (`compile::rest`; docs/numerics.md, "A
//! strike on an object at rest"). Checked here against a closed form (the
//! release instant of a hammer on a wall) and against the dense change of
//! basis it replaces, on every preset and stability case: same samples to
//! rounding, the same energy, no energy gain at the release. The independent
//! solver's comparisons (`tests/stiff.rs`, `tests/closed_forms.rs`) run on
//! the default engine, so they check this path too.

use modal_contact::compile::{compile, compile_with, CompiledScene};
use modal_contact::engine::EngineState;
use modal_contact::presets;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::scenes::{c_for, wall_strike, ModalStrike, RATE};
use modal_testkit::stability;

#[test]
fn the_release_of_a_hammer_on_a_wall_is_half_a_damped_period() {
    for (m, k, zeta) in [
        (0.01, 1e6, 0.0),
        (0.01, 1e6, 0.3),
        (0.5, 2e4, 0.9),
        (1e-4, 1e9, 0.05),
    ] {
        let c = c_for(m, k, zeta);
        let sc = compile(&wall_strike(m, k, c, 0.0, -1.0), RATE).unwrap();
        let r = sc.rest.as_ref().expect("a wall strike has a rest release");
        let sigma = c / (2.0 * m);
        let wd = (k / m - sigma * sigma).sqrt();
        let want = std::f64::consts::PI / wd;
        let rel = (r.t_r - want).abs() / want;
        println!(
            "m {m} k {k} zeta {zeta}: t_r {:.17e} s, pi/w_d {want:.17e} s, rel {rel:.1e}",
            r.t_r
        );
        assert!(rel <= 1e-14, "{rel}");
        // the engine releases there and takes the stored state
        let mut st = EngineState::new(&sc);
        for _ in 0..((want / sc.h) as usize + 3) {
            st.tick(&sc);
        }
        assert!(!st.in_contact());
        assert_eq!(
            (st.exact_stats.rest_releases, st.exact_stats.rest_misses),
            (1, 0)
        );
    }
}

/// Every scene the comparison runs: the presets and the stability
/// catalogue, with their lengths.
fn scenes() -> Vec<(String, Scene, usize)> {
    let mut v: Vec<(String, Scene, usize)> = presets::one_contact()
        .map(|i| {
            let s = presets::scene(i).unwrap();
            let n = (s.duration_s.min(1.0) * RATE) as usize;
            (format!("preset {}", presets::NAMES[i]), s, n)
        })
        .collect();
    for c in stability::cases() {
        v.push((format!("stability {}", c.label), c.scene, c.samples));
    }
    v
}

struct Run {
    out: Vec<[f64; 2]>,
    /// Per sample: energy after the step.
    energy: Vec<f64>,
    st: EngineState,
}

fn run(sc: &CompiledScene, n: usize, rest: bool, time_scale: f64) -> Run {
    let mut st = EngineState::new(sc);
    st.set_rest_strike(rest);
    st.set_time_scale(sc, time_scale).unwrap();
    st.reset(sc);
    let (mut out, mut energy) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        out.push(st.tick(sc));
        energy.push(st.energy(sc));
    }
    Run { out, energy, st }
}

#[test]
fn a_strike_from_rest_plays_as_the_dense_change_of_basis_does() {
    let mut used = 0;
    println!("scene | rest t_r ms | releases stored/dense | max |out diff| / peak | max energy diff / E0 | max energy gain / E0");
    for (name, scene, n) in scenes() {
        let sc = compile_with(&scene, RATE, Some(Switching::Exact)).unwrap();
        let Some(r) = sc.rest.as_ref() else {
            // gravity (an affine contact), a dense contact, or a contact
            // that never ends (a critically damped wall: p_eff only tends
            // to 0, until the state underflows to zero), which the engine
            // must then show too
            let endless = sc.g == 0.0 && sc.contact.dense.is_none();
            if endless {
                let b = run(&sc, n, false, 1.0);
                let e0 = b.energy.iter().fold(0.0f64, |m, &e| m.max(e));
                let e_end = b.energy[n - 1];
                assert!(
                    b.st.contacts_started == 1 && (b.st.in_contact() || e_end <= 1e-250 * e0),
                    "{name}: no rest release, but the contact ended with energy {e_end:e} of {e0:e}"
                );
            }
            println!(
                "{name} | none (gravity {}, dense {}, endless contact {endless})",
                sc.g,
                sc.contact.dense.is_some()
            );
            continue;
        };
        for ts in [1.0, 1.37] {
            if ts != 1.0 && sc.free.dense.is_some() {
                continue;
            }
            let (a, b) = (run(&sc, n, true, ts), run(&sc, n, false, ts));
            let peak = b.out.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            let d_out = a
                .out
                .iter()
                .flatten()
                .zip(b.out.iter().flatten())
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            let e0 = a.energy.iter().fold(0.0f64, |m, &e| m.max(e));
            let d_e = a
                .energy
                .iter()
                .zip(&b.energy)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            let gain = a.energy.windows(2).fold(0.0f64, |m, w| m.max(w[1] - w[0]));
            let st = &a.st.exact_stats;
            println!(
                "{name} x{ts} | {:.4} | {}/{} | {:.1e} | {:.1e} | {:.1e}",
                r.t_r * 1e3,
                st.rest_releases,
                st.rest_misses,
                d_out / peak,
                d_e / e0,
                gain / e0
            );
            assert!(
                st.rest_releases >= 1,
                "{name} x{ts}: the stored release was never used"
            );
            assert_eq!(b.st.exact_stats.rest_releases, 0);
            assert_eq!(a.st.contacts_started, b.st.contacts_started, "{name} x{ts}");
            assert!(
                d_out <= 1e-11 * peak,
                "{name} x{ts}: outputs differ by {d_out:e} (peak {peak:e})"
            );
            assert!(
                d_e <= 1e-11 * e0,
                "{name} x{ts}: energies differ by {d_e:e} (E0 {e0:e})"
            );
            let gain_dense = b.energy.windows(2).fold(0.0f64, |m, w| m.max(w[1] - w[0]));
            assert!(
                gain <= gain_dense.max(0.0) + 1e-13 * e0,
                "{name} x{ts}: energy gain {gain:e} vs dense {gain_dense:e} (E0 {e0:e})"
            );
            used += 1;
        }
    }
    assert!(used >= 20, "only {used} runs used the stored release");
}

#[test]
fn a_ringing_object_or_a_pitch_change_in_contact_takes_the_dense_product() {
    let sc = compile(&ModalStrike::new(30, 200.0, 8000.0).scene("ring"), RATE).unwrap();
    assert!(sc.rest.is_some());
    // a second strike while the object rings: its state is not zero
    let mut st = EngineState::new(&sc);
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert_eq!(st.exact_stats.rest_releases, 1);
    st.strike(&sc, 0.0, -1.0);
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert_eq!(st.contacts_started, 2);
    assert_eq!(
        (st.exact_stats.rest_releases, st.exact_stats.rest_misses),
        (1, 0)
    );
    // a change of pitch during a strike from rest: the contact is then
    // counted in steps of two lengths, and the dense product is taken
    let mut st = EngineState::new(&sc);
    while !st.in_contact() {
        st.tick(&sc);
    }
    st.set_time_scale(&sc, 1.5).unwrap();
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert_eq!(st.exact_stats.rest_releases, 0);
    // a strike in the middle of a contact from rest ends it early: a miss
    let mut st = EngineState::new(&sc);
    while !st.in_contact() {
        st.tick(&sc);
    }
    st.tick(&sc);
    st.strike(&sc, 0.001, -1.0);
    assert!(!st.in_contact());
    assert_eq!(
        (st.exact_stats.rest_releases, st.exact_stats.rest_misses),
        (0, 1)
    );
}
