//! The stiff and extreme cases of docs/numerics.md ("The stability cases"),
//! for both switching modes: the engine never produces NaN/inf and never
//! increases the energy from one sample to the next (beyond a stated
//! rounding bound).
//!
//! Every case of the catalogue (`modal_testkit::stability::cases`, the
//! report's stability table) runs as it is; the other tests check more on
//! the same scene families, at lengths and variants of their own.

use modal_contact::compile::{compile_one, compile_with, CompiledScene};
use modal_contact::engine::EngineState;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::metrics::{energy_rounding_bound, energy_scale};
use modal_testkit::scenes::{Contact, Hammer, Modal, ModalStrike, Pickup, SceneBuilder, T60Law};
use modal_testkit::stability::{
    self, contact_at, critical_one_mode, critical_wall, grazing, many_modes, mass_ratio,
    modes_above_nyquist, overdamped, settling, stiff_chattering,
};
use std::f64::consts::PI;

const MODES: [Switching; 2] = [Switching::OffsetRod, Switching::Exact];

struct RunStats {
    max_rel_increase: f64,
    contacts: u64,
    e0: f64,
    e_end: f64,
    located: u64,
    capped: u64,
    fallbacks: u64,
    uncertified: u64,
    max_nodes: u64,
    max_switches: u64,
}

/// Run `n` samples with per-sample energy checks. The rounding bound per step
/// is `64 dim kappa u` relative to the energy scale (|E| plus the gravity
/// term's magnitude): a row of `dim` terms, each rounded once, amplified by
/// the condition of the change of basis, with a safety factor.
fn run_checked(label: &str, sc: &CompiledScene, n: usize, stride: usize) -> RunStats {
    let mut st = EngineState::new(sc);
    let bound = energy_rounding_bound(sc);
    let first = st.observe(sc);
    let mut prev = first;
    let mut max_rel = f64::NEG_INFINITY;
    let mg = sc.m_h * sc.g;
    for i in 0..n {
        let out = st.tick(sc);
        assert!(
            out[0].is_finite() && out[1].is_finite(),
            "{label}: non-finite output at {i}"
        );
        if i % stride == 0 || i + 1 == n {
            let obs = st.observe(sc);
            assert!(obs.energy.is_finite(), "{label}: non-finite energy at {i}");
            if stride == 1 {
                let scale = energy_scale(&prev, mg) + 1e-300;
                let rel = (obs.energy - prev.energy) / scale;
                max_rel = max_rel.max(rel);
                assert!(
                    rel <= bound,
                    "{label}: energy rose at sample {i}: {:e} -> {:e} (rel {rel:e} > {bound:e})",
                    prev.energy,
                    obs.energy
                );
            } else {
                let scale =
                    first.energy.abs() + 2.0 * mg * (first.x_hammer.abs() + obs.x_hammer.abs());
                assert!(
                    obs.energy <= prev.energy + bound * scale * stride as f64,
                    "{label}: energy rose between samples {} and {i}",
                    i - stride
                );
            }
            prev = obs;
        }
    }
    if sc.switching == Switching::Exact {
        // exact switching never falls back on the rod, never gives up on a
        // node and never reaches its (provably unreachable) switch bound
        let x = &st.exact_stats;
        assert!(
            x.capped == 0 && x.rod_fallbacks == 0 && x.uncertified == 0 && x.nonfinite == 0,
            "{label}: {x:?}"
        );
        assert_eq!(st.events_dropped, 0, "{label}");
    }
    RunStats {
        max_rel_increase: max_rel,
        contacts: st.contacts_started,
        e0: first.energy,
        e_end: prev.energy,
        located: st.exact_stats.located,
        capped: st.exact_stats.capped,
        fallbacks: st.exact_stats.rod_fallbacks,
        uncertified: st.exact_stats.uncertified,
        max_nodes: st.exact_stats.max_nodes_in_sample,
        max_switches: st.exact_stats.max_switches_in_sample,
    }
}

fn report(label: &str, s: &RunStats) {
    let de = if s.max_rel_increase.is_finite() {
        format!("{:>9.2e}", s.max_rel_increase)
    } else {
        "  sampled".to_string()
    };
    println!(
        "{label:<40} contacts {:>5}  located {:>5}  capped {}  rod-fallbacks {}  uncertified {}  nodes/sample <= {:>4}  switches/sample <= {}  max dE/E {de}  E_end/E0 {:.3e}",
        s.contacts, s.located, s.capped, s.fallbacks, s.uncertified, s.max_nodes, s.max_switches, s.e_end / s.e0
    );
}

/// A family of the catalogue as these tests run it: damped modes decay by
/// [`T60Law::FallingWithFrequency`], the law the tests were written with
/// (their printed numbers are for it; the report's cases use
/// [`T60Law::Geometric`] and run as they are in
/// `every_catalogue_case_is_stable_in_both_modes`).
fn tested(family: ModalStrike) -> Scene {
    family.t60_law(T60Law::FallingWithFrequency).scene("x")
}

/// The report's stability table, case by case, as the report runs it.
#[test]
fn every_catalogue_case_is_stable_in_both_modes() {
    for case in stability::cases() {
        for sw in MODES {
            let compiled = compile_with(&case.scene, 44100.0, Some(sw)).unwrap();
            let label = format!("{} ({}), {}", case.name, case.label, sw.as_str());
            let s = run_checked(&label, &compiled, case.samples, 1);
            report(&label, &s);
        }
    }
}

#[test]
fn contact_frequency_up_to_1000x_nyquist() {
    let rate = 44100.0;
    for ratio in [1.0, 10.0, 100.0, 1000.0] {
        let fc = ratio * rate / 2.0;
        let sc = tested(contact_at(ratio));
        for sw in MODES {
            let compiled = compile_with(&sc, rate, Some(sw)).unwrap();
            let label = format!("X3 f_c = {ratio}x Nyquist, {}", sw.as_str());
            let s = run_checked(&label, &compiled, 20_000, 1);
            report(&label, &s);
            // one contact at every stiffness (the hammer bounces off and
            // flies away; checked against an independent solver in
            // tests/stiff_switching.rs)
            if sw == Switching::Exact {
                assert_eq!(s.contacts, 1, "{label}");
                // the compile summary's cost estimate grows with the
                // contact frequency (|mu| h / 1.4 nodes per sample)
                let est = compiled.search_nodes_estimate;
                let expect = (2.0 * PI * fc / rate) / 1.4;
                assert!(
                    est >= 0.5 * expect && est <= 2.0 * expect + 4.0,
                    "{label}: estimate {est} for |mu| h / 1.4 = {expect}"
                );
                if ratio >= 100.0 {
                    assert!(est > modal_contact::compile::REALTIME_SEARCH_NODES);
                }
            } else {
                assert!(s.contacts >= 1);
            }
        }
    }
}

#[test]
fn zero_damping_everywhere_and_stiff_chattering() {
    let rate = 44100.0;
    // X2-like: f_c = 0.45 f_Nyq, mass ratio 0.2; X6: all damping zero
    for damped in [false, true] {
        let sc = tested(stiff_chattering(damped));
        for sw in MODES {
            let compiled = compile_with(&sc, rate, Some(sw)).unwrap();
            let label = format!("X2/X6 stiff, damped={damped}, {}", sw.as_str());
            let s = run_checked(&label, &compiled, 20_000, 1);
            report(&label, &s);
            if !damped && sw == Switching::Exact {
                // lossless and exact: no energy leaves at all
                let drift = (s.e_end - s.e0).abs() / s.e0;
                assert!(drift < 1e-9, "lossless exact drift {drift:e}");
            }
        }
    }
}

#[test]
fn critical_damping_is_exact_and_matches_closed_form() {
    // X4: hammer vs rigid wall with zeta = 1 exactly: A is a Jordan block,
    // which the eigenvector route cannot take; as a single 2x2 block it is
    // stepped in closed form (exp2). Closed form of the penetration:
    // p(t) = |v0| t e^{-w0 t} (never returns to zero: critically damped
    // contacts do not release).
    let rate = 44100.0;
    let (m, k): (f64, f64) = (0.01, 1e6);
    let w0 = (k / m).sqrt();
    for sw in MODES {
        let mut sc = critical_wall();
        let h = &sc.hammer;
        assert_eq!(
            (
                h.mass_kg,
                h.height_m,
                h.velocity_m_per_s,
                sc.contact.stiffness_n_per_m
            ),
            (m, 0.0, -1.0, k),
            "the closed form below is for this strike"
        );
        sc.contact.switching = Some(sw);
        let compiled = compile_one(&sc, rate).unwrap();
        assert!(
            compiled.contact.dense.is_none() && compiled.contact.diag.fallback_reason.is_none(),
            "the 2x2 contact phase should be one closed-form block: {}",
            compiled.summary
        );
        assert_eq!(compiled.switching, sw, "{}", compiled.summary);
        let mut st = EngineState::new(&compiled);
        let mut worst: f64 = 0.0;
        // contact starts at t = 0 (exact) or after one sample (rod)
        let t0 = if sw == Switching::Exact {
            0.0
        } else {
            1.0 / rate
        };
        let mut n_in = 0;
        for i in 0..2000 {
            let obs = st.observe(&compiled);
            let t = i as f64 / rate - t0;
            if obs.in_contact && t > 0.0 {
                let p_model = -obs.x_hammer
                    - if sw == Switching::Exact {
                        0.0
                    } else {
                        1.0 / rate
                    };
                let p_exact = t * (-w0 * t).exp();
                worst = worst.max((p_model - p_exact).abs() / (1.0 / (w0 * std::f64::consts::E)));
                n_in += 1;
            }
            st.tick(&compiled);
        }
        println!(
            "X4 critical damping, {}: {}, worst |p - t e^(-w t)| / max p = {worst:.2e} over {n_in} samples",
            sw.as_str(),
            compiled.contact.diag.method
        );
        assert!(n_in > 1000, "critically damped contact must not release");
        assert!(worst < 1e-9, "{worst:e}");
        let s = run_checked(
            &format!("X4 wall zeta=1 {}", sw.as_str()),
            &compiled,
            5000,
            1,
        );
        report(&format!("X4 wall zeta=1 {}", sw.as_str()), &s);
    }
    // and a single mode with a critically damped contact (coupling splits it)
    let sc = tested(critical_one_mode());
    for sw in MODES {
        let compiled = compile_with(&sc, 44100.0, Some(sw)).unwrap();
        let s = run_checked(
            &format!("X4 one mode zeta=1 {}", sw.as_str()),
            &compiled,
            20_000,
            1,
        );
        report(&format!("X4 one mode zeta=1 {}", sw.as_str()), &s);
    }
}

#[test]
fn modes_above_nyquist_and_overdamped_contacts() {
    let rate = 44100.0;
    for sw in MODES {
        // X8: 40 modes up to 2.7 f_Nyq
        let sc = tested(modes_above_nyquist());
        let compiled = compile_with(&sc, rate, Some(sw)).unwrap();
        let s = run_checked(
            &format!("X8 modes to 2.7 f_Nyq {}", sw.as_str()),
            &compiled,
            20_000,
            1,
        );
        report(&format!("X8 modes to 2.7 f_Nyq {}", sw.as_str()), &s);
        // X5: overdamped contact, zeta 10 and 1e3
        for zeta in [10.0, 1e3] {
            let sc = tested(overdamped(zeta));
            let compiled = compile_with(&sc, rate, Some(sw)).unwrap();
            let label = format!("X5 overdamped zeta={zeta} {}", sw.as_str());
            let s = run_checked(&label, &compiled, 20_000, 1);
            report(&label, &s);
        }
    }
}

#[test]
fn hammer_mass_ratios_from_1e_minus_6_to_1e3() {
    let rate = 44100.0;
    // the object's effective mass at the contact point for mode 0 is 1/w^2 = 1 kg
    for ratio in [1e-6, 1e-3, 1.0, 1e3] {
        // the contact frequency stays at 2 kHz for every mass
        let sc = tested(mass_ratio(ratio));
        for sw in MODES {
            let compiled = compile_with(&sc, rate, Some(sw)).unwrap();
            let label = format!("X7 m_h/m_k = {ratio:e} {}", sw.as_str());
            let s = run_checked(&label, &compiled, 20_000, 1);
            report(&label, &s);
            println!("   kappa(V) contact {:.2}", compiled.contact.diag.kappa);
            assert!(compiled.contact.diag.kappa < 1e3);
            // bounded work: a heavy hammer's slow mode once left ~360
            // intervals per sample uncertified with a global curvature
            // bound; the event search now resolves each block on its own
            // time scale
            assert!(
                s.max_nodes <= 200,
                "search nodes in one sample: {}",
                s.max_nodes
            );
        }
    }
}

#[test]
fn one_to_1000_modes() {
    let rate = 44100.0;
    for n in [1usize, 10, 100, 1000] {
        let sc = tested(many_modes(n));
        let t0 = std::time::Instant::now();
        let compiled = compile_with(&sc, rate, Some(Switching::Exact)).unwrap();
        let compile_s = t0.elapsed().as_secs_f64();
        let samples = if n >= 1000 { 2000 } else { 10_000 };
        for sw in MODES {
            let compiled = if sw == Switching::Exact {
                compiled.clone()
            } else {
                let mut c = compiled.clone();
                c.switching = sw;
                c
            };
            // per-sample energy checks are O(N^2): sample them for big scenes
            let stride = if n >= 1000 { 50 } else { 1 };
            let label = format!("X9 {n} modes {}", sw.as_str());
            let s = run_checked(&label, &compiled, samples, stride);
            report(&label, &s);
        }
        println!(
            "   compile of {n} modes: {compile_s:.2} s, contact {}",
            compiled.contact.diag.method
        );
    }
}

#[test]
fn ten_million_samples_of_continuous_contact() {
    // X12/X13: a heavy ball dropped on a three-mode object settles into
    // continuous contact and stays there for 1e7 samples (227 s).
    let rate = 44100.0;
    let sc = tested(settling());
    for sw in MODES {
        let compiled = compile_with(&sc, rate, Some(sw)).unwrap();
        let mut st = EngineState::new(&compiled);
        let mut prev = st.observe(&compiled);
        let mg = compiled.m_h * compiled.g;
        let mut max_rel: f64 = f64::NEG_INFINITY;
        let mut last_switch = 0usize;
        let n = 10_000_000;
        for i in 0..n {
            let was = st.in_contact();
            st.tick(&compiled);
            if st.in_contact() != was {
                last_switch = i;
            }
            if i % 64 == 0 {
                let obs = st.observe(&compiled);
                let scale = prev.energy.abs() + 2.0 * mg * prev.x_hammer.abs() + 1e-300;
                max_rel = max_rel.max((obs.energy - prev.energy) / scale);
                assert!(obs.energy.is_finite());
                prev = obs;
            }
        }
        let obs = st.observe(&compiled);
        // static equilibrium: the ball rests where k p = m g (plus the
        // object's static deflection under m g)
        println!(
            "X12/X13 {}: last switch at sample {last_switch}, in contact {}, x_hammer {:.6e}, energy {:.6e}, max rel dE per 64 samples {max_rel:.2e}",
            sw.as_str(),
            st.in_contact(),
            obs.x_hammer,
            obs.energy
        );
        assert!(st.in_contact());
        assert!(last_switch < 441_000, "still switching after 10 s");
        assert!(max_rel <= 1e-12);
        // the ball sits at rest: velocity ~ 0
        assert!(obs.v_hammer.abs() < 1e-9, "v = {}", obs.v_hammer);
    }
}

#[test]
fn grazing_contacts_do_not_hang() {
    // X11: impact speeds down to 1e-9 m/s, for both modes.
    for v in [1e-3, 1e-6, 1e-9] {
        let sc = tested(grazing(v));
        for sw in MODES {
            let compiled = compile_with(&sc, 44100.0, Some(sw)).unwrap();
            let label = format!("X11 grazing v = {v:e} {}", sw.as_str());
            let s = run_checked(&label, &compiled, 20_000, 1);
            report(&label, &s);
        }
    }
}

#[test]
fn fast_modes_fall_through_the_subnormal_range_without_changing_the_output() {
    // X13: a long-ringing mode (T60 100 s) keeps the object sounding while
    // eight fast ones (T60 10..20 ms) decay by e^-708 (the bottom of the
    // normal f64 range) 1..2 s after the strike, and would then spend 50..100
    // ms as subnormal numbers, the slow path of the floating-point unit.
    let mut object = Modal::new("o", &["c", "p"]).mode(180.0, 100.0, &[1.0, 0.5]);
    for i in 0..8 {
        let f = 1000.0 + 900.0 * i as f64;
        let t60 = 0.010 + 0.010 * i as f64 / 7.0;
        object = object.mode(f, t60, &[0.8, 0.6]);
    }
    let tail = SceneBuilder::new("tail")
        .object(object)
        .hammer(Hammer::new(0.02).velocity(-1.0))
        .contact(Contact::new("o", 1e6).point("c").damping(5.0))
        .pickup(Pickup::new("o", "p"))
        .build();
    let n = 130_000; // 2.9 s
    for sw in MODES {
        let sc = compile_with(&tail, 44100.0, Some(sw)).unwrap();
        let run = |flush: bool| {
            let mut st = EngineState::new(&sc);
            st.set_flush_denormals(flush);
            let mut out = Vec::with_capacity(n);
            let mut subnormal_samples = 0usize;
            let mut first_subnormal = None;
            let mut at_end = 0;
            for i in 0..n {
                out.push(st.tick(&sc));
                let k = st.phase_state().iter().filter(|x| x.is_subnormal()).count();
                if k > 0 {
                    subnormal_samples += 1;
                    first_subnormal.get_or_insert(i);
                }
                at_end = k;
            }
            (
                out,
                subnormal_samples,
                first_subnormal,
                at_end,
                st.in_contact(),
            )
        };
        let (with, sub_with, _, _, contact_end) = run(true);
        let (without, sub_without, first, at_end, _) = run(false);
        let max_diff = with
            .iter()
            .zip(&without)
            .flat_map(|(a, b)| [(a[0] - b[0]).abs(), (a[1] - b[1]).abs()])
            .fold(0.0f64, f64::max);
        let tail_peak = with[n - 4410..]
            .iter()
            .fold(0.0f64, |m, o| m.max(o[0].abs()));
        println!(
            "X13 {sw:?}: without the flush {sub_without} of {n} samples hold a subnormal state (first at {:.3} s; \
             {at_end} state numbers still subnormal at the end); with it {sub_with}; output difference {max_diff:e}; \
             the slow mode still sounds at {tail_peak:.2e}",
            first.map_or(f64::NAN, |i| i as f64 / 44100.0)
        );
        assert!(!contact_end, "{sw:?}: the hammer must have left");
        assert!(
            sub_without > 1000,
            "{sw:?}: the scene must reach the subnormal range without the flush"
        );
        assert_eq!(sub_with, 0, "{sw:?}: a subnormal number in the state");
        assert!(tail_peak > 1e-4, "{sw:?}: the object must still sound");
        // a flushed number is below 2.2e-308: nothing at the output
        assert!(max_diff <= 1e-290, "{sw:?}: output changed by {max_diff:e}");
    }
}

/// A hammer of 1e-12 kg riding on a 17-mass string through a contact damper
/// whose pole (c / m_h = 1.4e13 /s) is 1e9 times the string's fastest mode
/// (a case the scene fuzzer found): after the hammer settles on the string,
/// the contact and free phases disagree on its relative velocity (4e-18
/// m/s) by more than it is, each sees the other's start as a crossing, and
/// the switches followed one another at the root resolution, up to 3e14 of
/// them in a sample (a hang). docs/numerics.md, "Why it terminates, and what
/// it costs": the switches of a sample are capped, and the capped samples
/// add no energy.
#[test]
fn a_feather_light_hammer_riding_on_a_string_is_bounded() {
    use modal_contact::engine::MAX_SWITCHES_PER_SAMPLE;
    let text = r#"
version = 1
name = "feather on a string"
[[object]]
name = "o0"
kind = "string"
masses = 17
mass_kg = 6.658489234035998e-4
spring_n_per_m = 1.824125766070555e4
rayleigh_alpha_per_s = 0.557502799185875
points = { c = 13 }
[hammer]
mass_kg = 1e-12
height_m = 9.58412229092028e-5
velocity_m_per_s = -0.016193417265352256
[contact]
object = "o0"
point = "c"
stiffness_n_per_m = 1.5381904967072227e4
damping_n_s_per_m = 13.79395038801944
[[pickup]]
object = "o0"
point = "c"
"#;
    let scene = Scene::from_toml_str(text).unwrap();
    for rate in [44100.0, 8000.0] {
        for sw in MODES {
            let sc = compile_with(&scene, rate, Some(sw)).unwrap();
            let label = format!("feather on a string at {rate} Hz, {}", sw.as_str());
            let bound = energy_rounding_bound(&sc);
            let mg = sc.m_h * sc.g;
            let mut st = EngineState::new(&sc);
            let n = (rate / 44.1) as usize;
            for segment in 0..2 {
                if segment == 1 {
                    // struck again, 1 mm above the string at 0.5 m/s
                    st.strike(&sc, 1e-3, -0.5);
                }
                let mut prev = st.observe(&sc);
                for i in 0..2 * n {
                    let out = st.tick(&sc);
                    let obs = st.observe(&sc);
                    assert!(
                        out[0].is_finite() && out[1].is_finite() && obs.energy.is_finite(),
                        "{label}: not finite at {segment}/{i}"
                    );
                    let rel = (obs.energy - prev.energy) / (energy_scale(&prev, mg) + 1e-300);
                    assert!(
                        rel <= bound,
                        "{label}: energy rose at {segment}/{i}: {:e} -> {:e} (rel {rel:e} > {bound:e})",
                        prev.energy,
                        obs.energy
                    );
                    prev = obs;
                }
            }
            let x = &st.exact_stats;
            assert!(
                x.max_switches_in_sample <= MAX_SWITCHES_PER_SAMPLE,
                "{label}: {x:?}"
            );
            assert!(st.contacts_started > 0, "{label}: the hammer never landed");
            println!(
                "{label}: contacts {}, located {}, capped samples {}, switches/sample <= {}, nodes/sample <= {}",
                st.contacts_started, x.located, x.capped, x.max_switches_in_sample, x.max_nodes_in_sample
            );
        }
    }
}
