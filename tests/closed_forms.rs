//! The engine against closed forms: free damped sinusoids, and the linear
//! spring-damper impact on a rigid wall (DESIGN.md section 6).

mod common;

use common::*;
use modal_contact::compile::compile;
use modal_contact::engine::EngineState;
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
    let mut text = String::from(
        "version = 1\nname = \"free\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\"]\n",
    );
    for (f, t60, w) in modes {
        text += &format!("[[object.mode]]\nfreq_hz = {f}\nweights = [{w}]\n");
        if let Some(t) = t60 {
            text += &format!("t60_s = {t}\n");
        }
    }
    // hammer flying away upwards: never touches
    text += "[hammer]\nmass_kg = 0.01\nheight_m = 1.0\nvelocity_m_per_s = 1.0\n[contact]\nobject = \"o\"\npoint = \"c\"\nstiffness_n_per_m = 1e5\n";
    let sc = compile(&scene(&text), 44100.0).unwrap();
    let mut st = EngineState::new(&sc);
    {
        let s = st.free_state_mut();
        for i in 0..modes.len() {
            s[2 * i + 1] = 1.0; // q_i' = 1
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
    let sc = compile(&wall_scene(m, k, c, v0), rate).unwrap();
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
