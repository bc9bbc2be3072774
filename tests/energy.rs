//! Energy: the discrete system never gains energy (paper section 2.2).
//!
//! Lossless case: constant within each phase, unchanged by each contact start
//! (the offset rod starts the spring unstretched), lowered by exactly the cut
//! spring's energy at each release. Damped case: never increasing from one
//! sample to the next beyond a rounding bound.

use modal_contact::compile::compile_one;
use modal_contact::engine::EngineState;
use modal_contact::scene::Scene;
use modal_testkit::scenes::{preset, Contact, Hammer, Modal, Pickup, SceneBuilder};

/// f64 unit roundoff.
const U: f64 = f64::EPSILON / 2.0;

/// The paper's bouncing ball (10 g from 2 cm onto three modes, gravity),
/// lossless or with decaying modes and a damped contact.
fn bouncing_scene(damped: bool) -> Scene {
    let t60 = |t: f64| damped.then_some(t);
    SceneBuilder::new("bounce")
        .object(
            Modal::new("plate", &["contact", "pickup"])
                .mode(220.0, t60(0.8), &[2.0, 1.0])
                .mode(950.0, t60(0.4), &[1.5, -1.2])
                .mode(3500.0, t60(0.15), &[1.2, 0.9]),
        )
        .hammer(Hammer::new(0.01).height(0.02).gravity(9.81))
        .contact(
            Contact::new("plate", 2e5)
                .point("contact")
                .damping(if damped { 2.0 } else { 0.0 }),
        )
        .pickup(Pickup::new("plate", "pickup"))
        .build()
}

#[test]
fn lossless_energy_is_conserved_in_phases_and_only_lost_at_releases() {
    // the offset rod: releases cut a stretched spring
    let sc = modal_contact::compile::compile_with(
        &bouncing_scene(false),
        44100.0,
        Some(modal_contact::scene::Switching::OffsetRod),
    )
    .unwrap();
    let mut st = EngineState::new(&sc);
    let n = 1_000_000;
    let e0 = st.observe(&sc).energy;
    let mut phase_start_e = e0;
    let mut worst_in_phase = 0.0f64;
    let mut worst_entry = 0.0f64;
    let mut worst_release = 0.0f64;
    let (mut entries, mut releases) = (0u32, 0u32);
    let mut prev = st.observe(&sc);
    for _ in 0..n {
        let was_in = st.in_contact();
        let pen = st.penetration(&sc);
        let before = st.observe(&sc); // state at t_n, before the decision
        let (_, obs) = st.tick_observed(&sc);
        // drift within the phase: compare with the phase's first value
        let drift = (before.energy - phase_start_e).abs() / e0;
        worst_in_phase = worst_in_phase.max(drift);
        if obs.in_contact && !was_in {
            entries += 1;
            worst_entry = worst_entry.max((obs.energy - before.energy).abs() / e0);
            phase_start_e = obs.energy;
        } else if !obs.in_contact && was_in {
            releases += 1;
            let cut = 0.5 * sc.k * pen * pen;
            assert!(pen <= 0.0, "released with p_eff = {pen}");
            worst_release = worst_release.max((obs.energy - (before.energy - cut)).abs() / e0);
            assert!(
                obs.energy <= before.energy + 1e-12 * e0,
                "release raised energy"
            );
            phase_start_e = obs.energy;
        }
        prev = obs;
    }
    let _ = prev;
    println!(
        "lossless, 1e6 samples: {entries} contact starts, {releases} releases; \
         worst in-phase drift {worst_in_phase:.2e} E0, worst entry change {worst_entry:.2e} E0, \
         worst release mismatch vs 0.5 k p_eff^2 {worst_release:.2e} E0; final E/E0 = {:.6}",
        st.observe(&sc).energy / e0
    );
    assert!(entries > 10, "the ball should bounce many times");
    assert!(worst_in_phase < 1e-9, "in-phase drift {worst_in_phase:e}");
    assert!(
        worst_entry < 1e-12,
        "entry changed energy by {worst_entry:e}"
    );
    assert!(worst_release < 1e-12, "release mismatch {worst_release:e}");
}

#[test]
fn damped_energy_never_increases() {
    for (name, sc) in [
        ("bounce (damped)", bouncing_scene(true)),
        ("paper-string", preset("paper-string")),
        ("marimba-bar", preset("marimba-bar")),
    ] {
        let sc = compile_one(&sc, 44100.0).unwrap();
        let kappa = sc.free.diag.kappa.max(sc.contact.diag.kappa);
        let dim = sc.contact.dim as f64;
        // Rounding bound per step: each of the ~dim terms of a row is rounded
        // once (relative u); the change of basis to energy coordinates
        // amplifies by kappa(V). So |dE| <= 4 dim kappa u E per step.
        let bound = 4.0 * dim * kappa * U;
        let mut st = EngineState::new(&sc);
        let first = st.observe(&sc);
        let mut prev = first.energy;
        let mut prev_x_h = first.x_hammer;
        let e0 = prev;
        let mut worst = f64::NEG_INFINITY;
        let mg = sc.m_h * sc.g;
        let n = if sc.contact.dim > 50 { 20_000 } else { 200_000 };
        for _ in 0..n {
            let (_, obs) = st.tick_observed(&sc);
            // Gravity's potential m g x_h has an arbitrary zero (and is
            // negative when the ball rests in the dent it makes), so the
            // rounding scale is |E| plus the magnitude of that term.
            let scale = prev.abs() + 2.0 * mg * prev_x_h.abs() + 1e-300;
            let rel = (obs.energy - prev) / scale;
            worst = worst.max(rel);
            assert!(
                rel <= bound,
                "{name}: energy rose from {prev:e} to {:e} (rel {rel:e} > bound {bound:e})",
                obs.energy
            );
            prev = obs.energy;
            prev_x_h = obs.x_hammer;
        }
        println!(
            "{name}: {n} samples, worst relative step change {worst:.2e} (bound {bound:.1e}), E_end/E0 = {:.3e}",
            prev / e0
        );
    }
}

/// Stability case X14 (docs/numerics.md, "The stability cases"): contact stiffness, damping and hammer mass changed every
/// 64 samples during contact and flight; the state is carried over by
/// `rebind` and the energy never increases, neither within steps nor at swaps.
#[test]
fn parameter_swaps_never_raise_energy() {
    let base = bouncing_scene(true);
    let variants: Vec<_> = [(1.0, 1.0), (4.0, 0.5), (0.25, 3.0), (2.0, 1.0)]
        .iter()
        .map(|&(kf, cf)| {
            let mut s = base.clone();
            s.contact.stiffness_n_per_m *= kf;
            s.contact.damping_n_s_per_m *= cf;
            compile_one(&s, 44100.0).unwrap()
        })
        .collect();
    let mut cur = 0;
    let mut st = EngineState::new(&variants[cur]);
    let mut prev = st.observe(&variants[cur]);
    let mut swaps_in_contact = 0;
    let mg = variants[0].m_h * variants[0].g;
    let bound = 1e-13;
    for i in 0..44100 {
        if i % 64 == 63 {
            let next = (cur + 1) % variants.len();
            let before = st.observe(&variants[cur]);
            assert!(st.rebind(&variants[cur], &variants[next]));
            let after = st.observe(&variants[next]);
            if before.in_contact {
                swaps_in_contact += 1;
            }
            let scale = before.energy.abs() + 2.0 * mg * before.x_hammer.abs();
            assert!(
                (after.energy - before.energy) / scale <= bound,
                "swap at {i} raised energy {:e} -> {:e}",
                before.energy,
                after.energy
            );
            assert!(
                (after.x_hammer - before.x_hammer).abs() <= 1e-12 * (1.0 + before.x_hammer.abs())
            );
            cur = next;
            prev = after;
        }
        let (_, obs) = st.tick_observed(&variants[cur]);
        let scale = prev.energy.abs() + 2.0 * mg * prev.x_hammer.abs() + 1e-300;
        assert!(
            (obs.energy - prev.energy) / scale <= bound,
            "step {i} raised energy"
        );
        prev = obs;
    }
    println!("{swaps_in_contact} swaps happened during contact");
    assert!(swaps_in_contact > 5);
}

/// Exact switching with all damping zero: the spring starts and is cut at
/// zero length, so the energy stays constant through every switch (1e6
/// samples, hundreds of contacts).
#[test]
fn lossless_exact_switching_conserves_energy_through_every_switch() {
    use modal_contact::compile::compile_with;
    use modal_contact::scene::Switching;
    let sc = compile_with(&bouncing_scene(false), 44100.0, Some(Switching::Exact)).unwrap();
    let mut st = EngineState::new(&sc);
    let e0 = st.observe(&sc).energy;
    let mut worst = 0.0f64;
    for _ in 0..1_000_000 {
        let (_, obs) = st.tick_observed(&sc);
        worst = worst.max((obs.energy - e0).abs() / e0);
    }
    println!(
        "exact, lossless, 1e6 samples: {} contacts, {} located switches, {} rod fallbacks; worst |E/E0 - 1| = {worst:.2e}",
        st.contacts_started, st.exact_stats.located, st.exact_stats.rod_fallbacks
    );
    assert!(st.contacts_started > 10);
    assert!(worst < 1e-9, "energy drifted by {worst:e}");
}
