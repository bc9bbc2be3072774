//! The fast path's Hermite certificate (docs/numerics.md section 6.2):
//! after a sample that failed the margin test, the kernel also sums the
//! slope row and clears the samples whose cubic Hermite interpolant, less
//! its remainder, stays above zero. Those samples were stepped by the slow
//! path before; the outcome must be the same to rounding. Checked here on
//! every preset and stability case, and on strikes of a ringing 200-mode
//! object, against the same engine with the certificate left to the slow
//! path: the same switches, samples within 1e-12 of the peak, energy
//! within 1e-12 of its scale, in blocks of 64 and sample by sample (the
//! output must not depend on how blocks are split).

use modal_contact::compile::{compile_one, CompiledScene};
use modal_contact::engine::EngineState;
use modal_contact::presets;
use modal_contact::scene::Scene;
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder, RATE};
use modal_testkit::stability;

/// Output, energy and switch count of `n` samples in blocks of `block`
/// (1: sample by sample through `tick`), struck again every `every`
/// samples (0: never).
fn run(
    sc: &CompiledScene,
    n: usize,
    block: usize,
    every: usize,
    fast: bool,
) -> (Vec<f64>, f64, u64, u64) {
    let mut st = EngineState::new(sc);
    st.set_fast_hermite(fast);
    let mut out = Vec::with_capacity(n);
    let (mut l, mut r) = (vec![0.0; block], vec![0.0; block]);
    let mut done = 0;
    while done < n {
        if every > 0 && done % every == 0 && done > 0 {
            st.strike(sc, 0.0, -1.0);
        }
        let k = block
            .min(n - done)
            .min(if every > 0 { every - done % every } else { n });
        if block == 1 {
            out.push(st.tick(sc)[0]);
        } else {
            st.process_block(sc, &mut l[..k], &mut r[..k]);
            out.extend_from_slice(&l[..k]);
        }
        done += k;
    }
    let x = st.exact_stats;
    (out, st.energy(sc), x.located, x.hermite_cleared)
}

/// The largest difference of two outputs, relative to the second one's
/// peak.
fn rel_diff(on: &[f64], off: &[f64]) -> f64 {
    let peak = off.iter().fold(1e-300f64, |m, v| m.max(v.abs()));
    let diff = on
        .iter()
        .zip(off)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    diff / peak
}

fn ringing(n: usize) -> Scene {
    let mut object = Modal::new("bar", &["c", "p"]);
    for i in 0..n {
        let f = 220.0 * (18000.0f64 / 220.0).powf(i as f64 / (n - 1) as f64);
        let w = 1.0 / (1.0 + 0.02 * i as f64).sqrt();
        let wp = if i % 2 == 0 { 0.8 * w } else { -0.6 * w };
        object = object.mode(f, 2.5 / (1.0 + f / 1500.0), &[w, wp]);
    }
    SceneBuilder::new("ringing")
        .object(object)
        .hammer(Hammer::new(0.03).height(1e-3).velocity(-1.0))
        .contact(Contact::new("bar", 2e6).point("c").damping(20.0))
        .pickup(Pickup::new("bar", "p"))
        .build()
}

/// Every preset (0.5 s; a driven one 50 ms), every stability case (at most 20000 samples) and
/// a ringing 200-mode object struck every 1000 samples: (name, scene,
/// samples, strike period or 0).
fn cases() -> Vec<(String, Scene, usize, usize)> {
    let mut cases: Vec<(String, Scene, usize, usize)> = presets::one_contact()
        .map(|i| {
            let s = presets::scene(i).unwrap();
            // a ball rolling over roughness is chaotic: each landing's
            // instant moves the next, so any rounding grows; 50 ms, over
            // which both certificates give the same bounces
            let seconds = if s.drive.is_some() { 0.05 } else { 0.5 };
            let n = (s.duration_s.min(seconds) * RATE) as usize;
            (format!("preset {}", presets::NAMES[i]), s, n, 0)
        })
        .collect();
    for c in stability::cases() {
        let n = c.samples.min(20_000);
        cases.push((format!("stability {}", c.label), c.scene, n, 0));
    }
    cases.push((
        "ringing 200 modes, struck every 1000 samples".into(),
        ringing(200),
        8000,
        1000,
    ));
    cases
}

#[test]
fn the_fast_paths_hermite_certificate_changes_only_rounding() {
    let cases = cases();
    let mut worst = 0.0f64;
    for (name, scene, n, every) in &cases {
        let sc = compile_one(scene, RATE).unwrap();
        let (off, e_off, sw_off, slow_off) = run(&sc, *n, 64, *every, false);
        for block in [64, 1] {
            let (on, e_on, sw_on, slow_on) = run(&sc, *n, block, *every, true);
            assert!(
                slow_on <= slow_off,
                "{name}: more samples left to the slow path"
            );
            if *every > 0 {
                // the strikes on the ringing object: the kernel clears most
                // of what the slow path's certificate cleared alone
                println!(
                    "{name}, blocks of {block}: slow-path Hermite clears {slow_off} -> {slow_on}"
                );
                assert!(4 * slow_on < slow_off, "{slow_on} of {slow_off}");
            }
            assert_eq!(sw_on, sw_off, "{name}: the same switches");
            let rel = rel_diff(&on, &off);
            worst = worst.max(rel);
            let scale = e_off.abs().max(1e-300);
            assert!(
                rel <= 1e-12,
                "{name}, blocks of {block}: output differs by {rel:e} of the peak"
            );
            assert!(
                (e_on - e_off).abs() <= 1e-12 * scale,
                "{name}, blocks of {block}: energy {e_on:e} against {e_off:e}"
            );
        }
    }
    println!(
        "{} cases: output within {worst:.1e} of the peak",
        cases.len()
    );
}

/// The rest of a sample after a located switch, cleared by the Hermite
/// certificate instead of a second model and search, is the search's own
/// result bit for bit: every preset and stability case, and strikes on a
/// ringing 200-mode object, with and without it.
#[test]
fn the_certificate_after_a_switch_changes_nothing() {
    let cases = cases();
    let (mut cleared, mut switches) = (0, 0);
    for (name, scene, n, every) in &cases {
        let sc = compile_one(scene, RATE).unwrap();
        let render = |on: bool| {
            let mut st = EngineState::new(&sc);
            st.set_hermite_after_switch(on);
            let mut out = Vec::with_capacity(*n);
            let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
            let mut done = 0;
            while done < *n {
                if *every > 0 && done % every == 0 && done > 0 {
                    st.strike(&sc, 0.0, -1.0);
                }
                let k = 64.min(n - done);
                st.process_block(&sc, &mut l[..k], &mut r[..k]);
                out.extend(l[..k].iter().chain(&r[..k]).map(|x| x.to_bits()));
                done += k;
            }
            (out, st.exact_stats)
        };
        let (with, x_on) = render(true);
        let (without, x_off) = render(false);
        assert_eq!(x_off.hermite_after_switch, 0);
        assert_eq!(x_on.located, x_off.located, "{name}: the same switches");
        assert!(
            with == without,
            "{name}: output not bit for bit the search's"
        );
        println!(
            "{name}: {} switches, {} rests cleared",
            x_on.located, x_on.hermite_after_switch
        );
        cleared += x_on.hermite_after_switch;
        switches += x_on.located;
    }
    println!("{switches} located switches; the rest of the sample cleared by the certificate after {cleared}");
    assert!(
        cleared * 2 > switches,
        "the certificate should clear most rests"
    );
}

/// A strike that puts the hammer on the moving surface (height 0) begins
/// its contact at its own instant when the hammer moves into the surface
/// (`phi = 0` exactly there, `phi' < 0`), without a search; the search
/// found the same crossing through its model's sums, a rounding above or
/// below zero, and for some strikes located it up to a few 1e-14 of a
/// sample later. Against the engine that leaves it to the search, on
/// ringing objects of 50 and 200 modes struck at 1 m/s and at 1 mm/s (the
/// slow hammer often meets a surface moving away faster: no contact at
/// the instant, the search finds it later): at 1 m/s the same switches,
/// samples within 1e-12 of the peak; at 1 mm/s fewer switches (the search
/// alone made contacts of a rounding's length where the surface moved
/// away) and samples within 1e-10; energies within 1e-12; every fast
/// strike enters at its instant.
#[test]
fn a_strike_on_the_surface_enters_at_its_instant() {
    for (n, speed) in [(50, 1.0), (200, 1.0), (50, 1e-3), (200, 1e-3)] {
        let sc = compile_one(&ringing(n), RATE).unwrap();
        let render = |on: bool| {
            let mut st = EngineState::new(&sc);
            st.set_strike_entry(on);
            let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
            let mut out = Vec::new();
            // strikes, entries at the strike's instant, entries later in
            // its first sample
            let mut c = [0; 3];
            for k in 0..40 {
                // ring for a while (a varied length, so strikes meet the
                // surface in every state of its motion)
                for _ in 0..(4 + k % 5) {
                    st.process_block(&sc, &mut l, &mut r);
                    out.extend_from_slice(&l);
                }
                st.strike(&sc, 0.0, -speed);
                c[0] += 1;
                out.push(st.tick(&sc)[0]);
                if let Some(e) = st.switch_events().first().filter(|e| e.entered) {
                    c[if e.after_s == 0.0 { 1 } else { 2 }] += 1;
                }
            }
            let x = st.exact_stats;
            (out, st.energy(&sc), x.located, x.strike_entries, c)
        };
        let (on, e_on, sw_on, entries_on, c_on) = render(true);
        let (off, e_off, sw_off, entries_off, c_off) = render(false);
        println!(
            "{n} modes at {speed} m/s: {} strikes; entered at the instant {} (search: {}), later in the first sample {} (search: {}); {sw_on} switches (search: {sw_off})",
            c_on[0], c_on[1], c_off[1], c_on[2], c_off[2]
        );
        assert_eq!(entries_off, 0);
        // where the surface moves away faster than a slow hammer, the
        // search's model could put `phi(0)` a rounding below zero and make
        // a contact that ended a rounding later (two changes of basis for
        // nothing): fewer switches then, and the output moves by their
        // round trip's rounding
        let tol = if speed == 1.0 {
            assert_eq!(sw_on, sw_off, "{n} modes at {speed} m/s: the same switches");
            1e-12
        } else {
            assert!(
                sw_on < sw_off,
                "{n} modes at {speed} m/s: {sw_on} switches against {sw_off}"
            );
            1e-10
        };
        assert_eq!(
            c_on[2], 0,
            "an entry in the first sample that was not at its instant"
        );
        // every entry at a strike's instant is the strike's own decision
        assert_eq!(entries_on, c_on[1] as u64);
        if speed == 1.0 {
            assert_eq!(c_on[1], c_on[0], "every fast strike enters at its instant");
        } else {
            assert!(
                c_on[1] < c_on[0],
                "some slow strikes meet a surface moving away"
            );
        }
        let rel = rel_diff(&on, &off);
        println!("  output within {rel:.1e} of the peak, energy {e_on:e} against {e_off:e}");
        assert!(
            rel <= tol,
            "{n} modes: output differs by {rel:e} of the peak"
        );
        assert!((e_on - e_off).abs() <= 1e-12 * e_off.abs().max(1e-300));
    }
}

/// The root refinement (docs/numerics.md section 6.4) brackets each root
/// within the resolution in a few model evaluations: its steps aim just
/// past the estimate towards the end of the bracket that did not move,
/// instead of bisecting the rest of a bracket whose other end Halley's
/// steps never approached (10 to 16 evaluations a root before). On every
/// preset and stability case, and on strikes of a ringing 200-mode object
/// at time scales 0.6 to 4.5 (its modes up to 4.5 times higher).
#[test]
fn roots_are_refined_in_a_few_model_evaluations() {
    let (mut roots, mut evals) = (0u64, 0u64);
    for (name, scene, n, every) in cases() {
        let sc = compile_one(&scene, RATE).unwrap();
        let mut scales = vec![1.0];
        if every > 0 {
            scales.extend([0.6, 1.9, 3.4, 4.5]);
        }
        for s in scales {
            let mut st = EngineState::new(&sc);
            st.set_time_scale(&sc, s).unwrap();
            // every switch through the search, the strikes from rest too
            // (their certified stored switches otherwise need no root)
            st.set_rest_trust(false);
            let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
            let mut done = 0;
            while done < n {
                if every > 0 && done % every == 0 && done > 0 {
                    st.strike(&sc, 0.0, -1.0);
                }
                st.process_block(&sc, &mut l, &mut r);
                done += 64;
            }
            let x = st.exact_stats;
            let per = x.root_evals as f64 / x.roots_refined.max(1) as f64;
            println!(
                "{name} at scale {s}: {} roots, {per:.1} evaluations a root",
                x.roots_refined
            );
            assert!(
                x.root_evals <= 8 * x.roots_refined,
                "{name} at scale {s}: {per:.1} evaluations a root"
            );
            roots += x.roots_refined;
            evals += x.root_evals;
        }
    }
    println!(
        "{roots} roots refined in {evals} model evaluations ({:.2} a root)",
        evals as f64 / roots as f64
    );
    assert!(roots > 100);
}
