//! The engine against closed forms: free damped sinusoids, and the linear
//! spring-damper impact on a rigid wall.

use modal_contact::compile::{compile_one, compile_with};
use modal_contact::engine::EngineState;
use modal_testkit::metrics::rel_l2;
use modal_testkit::scenes::{preset, wall_strike, Contact, Hammer, Modal, SceneBuilder};
use std::f64::consts::PI;

/// A free modal object (three modes, one undamped) started with unit modal
/// velocities rings as `sum_i w_i e^{-sigma_i t} sin(omega_d,i t) / omega_d,i`
/// (the impulse response of `x'' + 2 sigma x' + omega^2 x = 0`, `x(0) = 0`,
/// `x'(0) = 1`, unit modal mass).
#[test]
fn free_modal_object_matches_damped_sinusoids() {
    let modes = [
        (220.0, Some(0.8), 2.0),
        (950.0, Some(0.4), 1.5),
        (3500.0, None, 1.2),
    ];
    let mut object = Modal::new("o", &["c"]);
    for (f, t60, w) in modes {
        object = object.mode(f, t60, &[w]);
    }
    // hammer flying away upwards: never touches
    let scene = SceneBuilder::new("free")
        .object(object)
        .hammer(Hammer::new(0.01).height(1.0).velocity(1.0))
        .contact(Contact::new("o", 1e5).point("c"))
        .build();
    let sc = compile_one(&scene, 44100.0).unwrap();
    let mut st = EngineState::new(&sc);
    {
        let s = st.free_state_mut();
        // structure of arrays: s[i] = omega_i q_i, s[n + i] = q_i'
        let n = modes.len();
        for i in 0..n {
            s[n + i] = 1.0; // q_i' = 1
        }
    }
    let n = 100_000;
    let h = 1.0 / 44100.0;
    let mut got = Vec::with_capacity(n);
    let mut want = Vec::with_capacity(n);
    for i in 0..n {
        let obs = st.observe(&sc);
        got.push(obs.x_contact);
        let t = i as f64 * h;
        let mut x = 0.0;
        for (f, t60, w) in modes {
            let omega = 2.0 * PI * f;
            let sigma = t60.map_or(0.0, |t| 1000f64.ln() / t);
            let wd = (omega * omega - sigma * sigma).sqrt();
            x += w * (-sigma * t).exp() * (wd * t).sin() / wd;
        }
        want.push(x);
        st.tick(&sc);
    }
    let err = rel_l2(&got, &want);
    let max_abs = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let peak = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    println!("free modal object over {n} samples: rel L2 error {err:.2e}, max abs error {max_abs:.2e} (peak {peak:.2e})");
    assert!(err < 1e-12, "relative L2 error {err:e}");
}

/// Contact time and rebound speed of a hammer against a rigid wall.
fn wall_impact(rate: f64, m: f64, k: f64, c: f64) -> (f64, f64) {
    let v0 = -1.0;
    let mut scene = wall_strike(m, k, c, 0.0, v0);
    scene.contact.switching = Some(modal_contact::scene::Switching::OffsetRod);
    let sc = compile_one(&scene, rate).unwrap();
    let mut st = EngineState::new(&sc);
    let mut start = None;
    for i in 0..(rate as usize) {
        st.tick(&sc);
        match (start, st.in_contact()) {
            (None, true) => start = Some(i),
            (Some(s), false) => {
                let (_, v) = st.hammer_in_flight().unwrap();
                // Offset rod: contact runs from the decision at sample s to the
                // decision at sample i; both decisions happen at sample instants.
                return ((i - s) as f64 / rate, v / -v0);
            }
            _ => {}
        }
    }
    panic!("no complete contact");
}

#[test]
fn rigid_wall_restitution_and_contact_time_converge_to_closed_form() {
    let m: f64 = 0.01;
    let rates = [44100.0, 96000.0, 192000.0, 384000.0, 1_000_000.0];
    for zeta in [0.1f64, 0.5] {
        // The offset rod makes each contact last the exact time rounded up to
        // whole samples, so a single impact's error jumps around inside
        // [0, h]. Averaging over 25 stiffnesses shows the first-order trend.
        let mut mean = vec![(0.0, 0.0); rates.len()];
        let ks: Vec<f64> = (0..25).map(|j| 1e6 * (1.0 + 0.02 * j as f64)).collect();
        for &k in &ks {
            let c = zeta * 2.0 * (k * m).sqrt();
            let w0 = (k / m).sqrt();
            let wd = w0 * (1.0 - zeta * zeta).sqrt();
            let t_exact = PI / wd;
            let e_exact = (-zeta * PI / (1.0 - zeta * zeta).sqrt()).exp();
            for (ri, &rate) in rates.iter().enumerate() {
                let (t, e) = wall_impact(rate, m, k, c);
                let et = (t - t_exact).abs() / t_exact;
                let ee = (e - e_exact).abs() / e_exact;
                // bounded by one sample late at each rate
                assert!(
                    t >= t_exact * (1.0 - 1e-9) && t - t_exact <= 1.0 / rate + 1e-12,
                    "contact time {t} not within one sample above {t_exact}"
                );
                assert!(
                    ee <= 2.0 * w0 / rate,
                    "restitution error {ee} > 2 omega_0 h"
                );
                mean[ri].0 += et / ks.len() as f64;
                mean[ri].1 += ee / ks.len() as f64;
            }
        }
        println!("zeta {zeta}: mean relative errors over {} stiffnesses (closed forms t = pi/omega_d, e = exp(-zeta pi/sqrt(1-zeta^2)))", ks.len());
        for (rate, (et, ee)) in rates.iter().zip(&mean) {
            println!("  {rate:>9} Hz: contact time {et:.2e}, restitution {ee:.2e}");
        }
        for w in mean.windows(2) {
            assert!(
                w[1].0 < w[0].0 && w[1].1 < w[0].1,
                "errors must shrink as the rate rises: {mean:?}"
            );
        }
        let (first, last) = (mean[0], mean[mean.len() - 1]);
        assert!(
            last.0 < first.0 / 8.0 && last.1 < first.1 / 8.0,
            "not first order: {mean:?}"
        );
    }
}

/// Exact switching against the rigid-wall closed forms at 44.1 kHz: the
/// contact starts and ends inside samples, so contact time and restitution
/// are right to ~1e-9, where the offset rod is off by up to a sample.
#[test]
fn exact_switching_hits_rigid_wall_closed_forms_at_44k() {
    use modal_contact::scene::Switching;
    let rate = 44100.0;
    let h = 1.0 / rate;
    let m: f64 = 0.01;
    let v0 = -1.0;
    for (k, zeta) in [(1e6f64, 0.1f64), (1e6, 0.5), (3.3e6, 0.05), (2e5, 0.9)] {
        let c = zeta * 2.0 * (k * m).sqrt();
        let w0 = (k / m).sqrt();
        let wd = w0 * (1.0 - zeta * zeta).sqrt();
        let t_exact = PI / wd;
        let e_exact = (-zeta * PI / (1.0 - zeta * zeta).sqrt()).exp();
        let mut sc = wall_strike(m, k, c, 0.0, v0);
        // start 0.37 sample above the wall: the touch is inside a sample
        let gap = 0.37 * h * -v0;
        sc.hammer.height_m = gap;
        sc.contact.switching = Some(Switching::Exact);
        let compiled = compile_one(&sc, rate).unwrap();
        let mut st = EngineState::new(&compiled);
        let t_in = gap / -v0;
        let mut was = false;
        let mut result = None;
        for i in 0..(rate as usize) {
            st.tick(&compiled);
            let t = (i + 1) as f64 * h;
            if st.in_contact() {
                was = true;
            } else if was {
                // flying freely again: x_h(t) = v_out (t - t_out)
                let (x, v) = st.hammer_in_flight().unwrap();
                let t_out = t - x / v;
                result = Some((t_out - t_in, v / -v0));
                break;
            }
        }
        let (t_c, e) = result.expect("contact ended");
        let et = (t_c - t_exact).abs() / t_exact;
        let ee = (e - e_exact).abs() / e_exact;
        // offset rod on the same case, for comparison
        sc.contact.switching = Some(Switching::OffsetRod);
        let (t_rod, e_rod) = wall_impact(rate, m, k, c);
        println!(
            "k {k:e}, zeta {zeta}: exact: contact time rel err {et:.2e}, restitution rel err {ee:.2e} \
             ({} located switches); offset rod: {:.2e}, {:.2e}",
            st.exact_stats.located,
            (t_rod - t_exact).abs() / t_exact,
            (e_rod - e_exact).abs() / e_exact
        );
        assert!(et < 1e-9, "contact time error {et:e}");
        assert!(ee < 1e-9, "restitution error {ee:e}");
        assert_eq!(st.exact_stats.rod_fallbacks, 0);
    }
}

/// Every contact start and end is logged by `switch_events()`, in both
/// switching modes and through both the plain and the observed tick (the
/// report and the trace read them): one start per contact, each end after
/// its start.
#[test]
fn switch_events_log_every_contact_in_both_modes() {
    use modal_contact::scene::Switching;
    let scene = preset("paper-bounce");
    for sw in [Switching::OffsetRod, Switching::Exact] {
        for observed in [false, true] {
            let sc = compile_with(&scene, 44100.0, Some(sw)).unwrap();
            let mut st = EngineState::new(&sc);
            let (mut starts, mut ends) = (0u64, 0u64);
            for _ in 0..44100 {
                if observed {
                    st.tick_observed(&sc);
                } else {
                    st.tick(&sc);
                }
                for e in st.switch_events() {
                    if e.entered {
                        starts += 1;
                    } else {
                        ends += 1;
                    }
                }
            }
            println!(
                "{sw:?} observed={observed}: {} contacts, {starts} starts, {ends} ends logged",
                st.contacts_started
            );
            assert_eq!(starts, st.contacts_started, "{sw:?} observed={observed}");
            assert!(
                ends + 1 >= starts && ends <= starts,
                "{sw:?} observed={observed}"
            );
        }
    }
}
