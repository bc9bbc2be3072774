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

use modal_contact::compile::{compile, CompiledScene};
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

/// Every preset (0.5 s), every stability case (at most 20000 samples) and
/// a ringing 200-mode object struck every 1000 samples: (name, scene,
/// samples, strike period or 0).
fn cases() -> Vec<(String, Scene, usize, usize)> {
    let mut cases: Vec<(String, Scene, usize, usize)> = presets::one_contact()
        .map(|i| {
            let s = presets::scene(i).unwrap();
            let n = (s.duration_s.min(0.5) * RATE) as usize;
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
        let sc = compile(scene, RATE).unwrap();
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
            let peak = off.iter().fold(1e-300f64, |m, v| m.max(v.abs()));
            let diff = on
                .iter()
                .zip(&off)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            let rel = diff / peak;
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
        let sc = compile(scene, RATE).unwrap();
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
