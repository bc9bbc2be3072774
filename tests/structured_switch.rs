//! The structured (hierarchical low-rank) changes of basis of large modal
//! objects (docs/numerics.md, "Structured changes of basis"), checked
//! against products the structure does not compute:
//!
//! - each product against the exact product (double-double sums, error
//!   below `u` of the result), next to the plain dense product's own error;
//! - the round trip free -> contact -> free is the identity;
//! - strikes on ringing objects: the same output as through the dense
//!   matrices (to rounding), and no energy gained at any switch (lossless
//!   objects: the energy stays constant through every contact) or step;
//! - the several-contact engine's switch products (a law's pieces on a
//!   200-mode object): the same output as through the dense products, no
//!   energy gained.

use modal_contact::compile::{compile_one, CompiledScene};
use modal_contact::engine::EngineState;
use modal_contact::multi::{CompiledMulti, MultiModel, MultiState};
use modal_contact::physics::hodlr::Hodlr;
use modal_testkit::metrics::energy_rounding_bound;
use modal_testkit::scenes::ModalStrike;

const U: f64 = f64::EPSILON / 2.0;

/// `n` modes from 100 Hz to 18 kHz, a 30 g hammer on a stiff contact
/// (`damped`: decaying modes and contact damping).
fn object(n: usize, damped: bool) -> CompiledScene {
    let s = ModalStrike::new(n, 100.0, 18_000.0).hammer(0.03);
    let s = if damped {
        s.damped().contact(1e6, 10.0)
    } else {
        s.contact(1e6, 0.0)
    };
    compile_one(&s.scene("structured"), 48_000.0).unwrap()
}

/// `sum a_i b_i` to about `u` of the result: TwoProd (FMA) and TwoSum,
/// accumulated in double-double.
fn dot_exact(a: impl Iterator<Item = f64>, b: &[f64]) -> f64 {
    let (mut hi, mut lo) = (0.0f64, 0.0f64);
    for (x, &y) in a.zip(b) {
        let p = x * y;
        let pe = x.mul_add(y, -p);
        let s = hi + p;
        let bb = s - hi;
        let se = (hi - (s - bb)) + (p - bb);
        hi = s;
        lo += se + pe;
    }
    hi + lo
}

fn vector(n: usize, seed: usize) -> Vec<f64> {
    (0..n)
        .map(|j| ((j * 7919 + seed * 104_729) as f64 * 0.618_033_988_7).sin())
        .collect()
}

/// Max over rows of `|computed - exact| / (|W|_2 |x|)`, in units of `u`.
fn error_u(w: &nalgebra::DMatrix<f64>, norm2: f64, x: &[f64], y: &[f64]) -> f64 {
    let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    (0..w.nrows())
        .map(|i| (y[i] - dot_exact(w.row(i).iter().copied(), x)).abs() / (norm2 * xn * U))
        .fold(0.0, f64::max)
}

#[test]
fn structured_products_are_as_exact_as_the_dense_ones() {
    for n in [150, 300, 600] {
        let sc = object(n, true);
        assert!(
            sc.summary.contains("W_cf hierarchical") && sc.summary.contains("W_fc hierarchical"),
            "{}",
            sc.summary
        );
        let forms: [(&str, &nalgebra::DMatrix<f64>, &Hodlr); 2] = [
            ("W_cf", &sc.w_cf, sc.w_cf_h.as_ref().unwrap()),
            ("W_fc", &sc.w_fc, sc.w_fc_h.as_ref().unwrap()),
        ];
        for (name, w, h) in forms {
            let (mut worst_h, mut worst_d) = (0.0f64, 0.0f64);
            for seed in 0..4 {
                let x = vector(w.ncols(), seed);
                let mut yh = vec![0.0; w.nrows()];
                h.apply_add_reference(&x, &mut yh);
                let yd: Vec<f64> = (w * nalgebra::DVector::from_vec(x.clone()))
                    .iter()
                    .copied()
                    .collect();
                worst_h = worst_h.max(error_u(w, h.norm2, &x, &yh));
                worst_d = worst_d.max(error_u(w, h.norm2, &x, &yd));
            }
            println!(
                "{n} modes, {name}: {:.0} % of the entries, ranks <= {}; error vs exact: \
                 hierarchical {worst_h:.2} u |W| |x|, dense {worst_d:.2} u |W| |x|",
                100.0 * h.stored() as f64 / w.len() as f64,
                h.max_rank
            );
            assert!(
                (h.stored() as f64) < 0.7 * w.len() as f64,
                "{name} at {n} modes stores {} of {}",
                h.stored(),
                w.len()
            );
            // within a few rounding units of the exact product, and of the
            // same order as the dense product's own rounding
            assert!(worst_h < 8.0, "{name} at {n} modes: {worst_h} u");
            assert!(
                worst_h < 4.0 * worst_d.max(1.0),
                "{name}: {worst_h} u vs dense {worst_d} u"
            );
        }
        // free -> contact -> free through both structured forms
        let x = vector(sc.free.dim, 9);
        let mut c = vec![0.0; sc.contact.dim];
        sc.w_cf_h.as_ref().unwrap().apply_add_reference(&x, &mut c);
        let mut back = vec![0.0; sc.free.dim];
        sc.w_fc_h
            .as_ref()
            .unwrap()
            .apply_add_reference(&c, &mut back);
        let err = x
            .iter()
            .zip(&back)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!("{n} modes: round trip max error {err:.1e}");
        assert!(err < 1e-12, "round trip {err:e}");
    }
}

/// Strike a ringing object again and again (every 300 samples, a new
/// strike from 0.5 mm at 1 m/s while the previous ones still ring): the
/// samples with the structured and the dense switches, and the energy.
fn strike_run(sc: &CompiledScene, structured: bool) -> (Vec<f64>, f64, usize) {
    let mut st = EngineState::new(sc);
    st.set_structured_switch(structured);
    let bound = energy_rounding_bound(sc);
    let mut out = Vec::new();
    let mut worst: f64 = 0.0;
    let mut switches = 0;
    for k in 0..12 {
        st.strike(sc, 5e-4, -1.0 - 0.1 * k as f64);
        let mut prev = st.observe(sc);
        for _ in 0..300 {
            let was = prev.in_contact;
            let (y, obs) = st.tick_observed(sc);
            out.push(y[0]);
            if obs.in_contact != was {
                switches += 1;
            }
            // never a gain beyond rounding, switches included
            let rel = (obs.energy - prev.energy) / prev.energy.abs().max(1e-300);
            worst = worst.max(rel);
            assert!(
                rel <= bound,
                "energy rose by {rel:e} (bound {bound:e}), structured {structured}"
            );
            prev = obs;
        }
    }
    (out, worst, switches)
}

#[test]
fn strikes_on_ringing_objects_match_the_dense_switches_and_gain_no_energy() {
    for (n, damped) in [(200, false), (200, true), (400, true)] {
        let sc = object(n, damped);
        assert!(sc.w_cf_h.is_some() && sc.w_fc_h.is_some());
        let (ys, worst_s, sw_s) = strike_run(&sc, true);
        let (yd, worst_d, sw_d) = strike_run(&sc, false);
        let peak = yd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = ys
            .iter()
            .zip(&yd)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!(
            "{n} modes, damped {damped}: {sw_s} switches; output differs by {:.1e} of the peak; \
             worst relative energy step: structured {worst_s:.1e}, dense {worst_d:.1e} (bound {:.1e})",
            diff / peak,
            energy_rounding_bound(&sc)
        );
        assert_eq!(sw_s, sw_d, "the same contacts");
        assert!(sw_s >= 24, "every strike makes contact: {sw_s}");
        assert!(diff <= 1e-11 * peak, "output differs by {:e}", diff / peak);
    }
}

/// The traced block path (the CSV's) takes a coupled contact phase's
/// energy through the structured `W_fc` and the free phase's sparse `V`
/// (O(N r log N) instead of the dense `V`'s O(dim^2)): on repeated strikes
/// of a ringing 300-mode object it equals the per-sample path's dense
/// energy to within the structured form's tolerance, sample by sample, in
/// contact and out, and gives the same audio bit for bit. (It also
/// caught the energy an observed run keeps for the next run's first sample
/// outliving a strike between the runs: 53 % off at that sample.)
#[test]
fn traced_energy_in_contact_through_the_structured_form_matches_the_dense_one() {
    for damped in [false, true] {
        let sc = object(300, damped);
        assert!(sc.w_fc_h.is_some() && sc.free.v_sparse.is_some());
        let mut fast = EngineState::new(&sc);
        let mut slow = EngineState::new(&sc);
        let (mut worst, mut contact_samples) = (0.0f64, 0);
        for k in 0..6 {
            let v = -1.0 - 0.1 * k as f64;
            fast.strike(&sc, 5e-4, v);
            slow.strike(&sc, 5e-4, v);
            let n = 400;
            let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
            let mut m = vec![Default::default(); n];
            let mut e = vec![0.0; n];
            fast.process_block_traced(&sc, &mut l, &mut r, &mut m, &mut e);
            for i in 0..n {
                let (y, (obs, energy)) = slow.tick_with(&sc, |st| (st.motion(&sc), st.energy(&sc)));
                assert_eq!(y[0], l[i], "audio, strike {k} sample {i}");
                let rel = (e[i] - energy).abs() / energy.abs();
                worst = worst.max(rel);
                if obs.in_contact {
                    contact_samples += 1;
                }
            }
        }
        println!(
            "damped {damped}: {contact_samples} samples in contact; traced energy vs the dense \
             per-sample energy: worst relative difference {worst:.1e}"
        );
        assert!(contact_samples >= 6, "every strike makes contact");
        assert!(worst <= 1e-12, "{worst:e}");
    }
}

/// A 200-mode object struck through a law in three pieces (a scene of
/// several contacts: each piece a phase), lossless or damped: its
/// compile and the same compile with the switches' products dense.
fn law_object(damped: bool) -> (CompiledMulti, CompiledMulti) {
    let s = ModalStrike::new(200, 100.0, 18_000.0).hammer(0.03);
    let s = if damped {
        s.damped().contact(1e6, 10.0)
    } else {
        s.contact(1e6, 0.0)
    };
    let spring = s.scene("structured-law");
    // F = K p^1.5 through the spring's force at 0.1 mm, in three pieces
    // from 0.01 to 0.3 mm (a 1 m/s strike of the 30 g hammer reaches
    // about 0.2 mm)
    let k = 1e6 * 1e-4 / 1e-4f64.powf(1.5);
    let scene = modal_testkit::scenes::with_power_law(&spring, (1.5, k), 3, (1e-5, 3e-4));
    let model = MultiModel::from_scene(&scene, 48_000.0).unwrap();
    let sc = CompiledMulti::new(&model, 48_000.0).unwrap();
    let mut dense = sc.clone();
    dense.forget_structured();
    (sc, dense)
}

/// Strike the ringing law object again and again (every 300 samples, from
/// rest on its surface at 0.5 to 1.6 m/s): the samples, the worst energy
/// rise from one sample to the next over its bound, and the switches.
fn law_run(sc: &CompiledMulti) -> (Vec<f64>, f64, u64) {
    let mut st = MultiState::new(sc);
    let bound = 64.0 * sc.max_dim() as f64 * sc.kappa() * U;
    let mut out = Vec::new();
    let mut worst: f64 = 0.0;
    for k in 0..12 {
        st.strike(sc, 0, 0.0, -0.5 - 0.1 * k as f64).unwrap();
        let mut prev = st.observe(sc);
        for _ in 0..300 {
            let y = st.tick(sc);
            out.push(y[0]);
            let obs = st.observe(sc);
            let rel = (obs.energy - prev.energy) / prev.energy.abs().max(1e-300);
            worst = worst.max(rel / bound);
            prev = obs;
        }
    }
    (out, worst, st.stats.switches)
}

/// The several-contact engine's switches through the structured products
/// (docs/numerics.md section 14, "Structured switches"): on a 200-mode
/// object with a three-piece law, lossless and damped, the same
/// contacts, outputs within 1e-12 of the peak of the dense products', and
/// no energy gained beyond the bound at any sample.
#[test]
fn several_contacts_switch_through_structured_products_as_through_dense_ones() {
    for damped in [false, true] {
        let (sc, dense) = law_object(damped);
        let (n, all) = sc.structured_products();
        assert!(n > 0, "no product in hierarchical form");
        let (ys, worst_s, sw_s) = law_run(&sc);
        let (yd, worst_d, sw_d) = law_run(&dense);
        let peak = yd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = ys
            .iter()
            .zip(&yd)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!(
            "damped {damped}: {n} of {all} products structured; {sw_s} switches; output differs \
             by {:.1e} of the peak; worst energy rise over its bound: structured {worst_s:.2}, \
             dense {worst_d:.2}",
            diff / peak
        );
        assert_eq!(sw_s, sw_d, "the same switches");
        assert!(
            sw_s >= 48,
            "every strike crosses the pieces: {sw_s} switches"
        );
        assert!(diff <= 1e-12 * peak, "output differs by {:e}", diff / peak);
        assert!(worst_s <= 1.0, "energy rose {worst_s} times its bound");
    }
}
