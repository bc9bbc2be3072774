//! Tests of the competitor integrators (`modal_testkit::competitors`): convergence order
//! against closed forms, the hammer-on-wall restitution and contact time,
//! stability limits, and a smoke run on the paper's bouncing preset.
//!
//! Run with `--nocapture` to see the measured orders and errors.

use modal_contact::scene::Scene;
use modal_testkit::competitors::{simulate, Method, PwlSystem, SimOutput};
use modal_testkit::metrics::rel_l2;
use modal_testkit::scenes::{preset, wall_strike, Contact, Hammer, Modal, Pickup, SceneBuilder};
use std::f64::consts::PI;

const RATE: f64 = 44_100.0;
const LN_1000: f64 = 6.907_755_278_982_137;

/// One mode of frequency `f_hz` (optional T60) with weight 1 at the contact
/// point and `w_pick` at the pickup (velocity, or `displacement`); the hammer
/// starts well above the object and moves away (no gravity), so it never
/// touches.
fn one_mode_scene(f_hz: f64, t60: Option<f64>, w_pick: f64, displacement: bool) -> Scene {
    let pickup = Pickup::new("obj", "pickup");
    SceneBuilder::new("one-mode")
        .object(Modal::new("obj", &["contact", "pickup"]).mode(f_hz, t60, &[1.0, w_pick]))
        .hammer(Hammer::new(0.01).height(0.05).velocity(0.1))
        .contact(Contact::new("obj", 1e5).point("contact").damping(1.0))
        .pickup(if displacement {
            pickup.displacement()
        } else {
            pickup
        })
        .build()
}

/// System of [`one_mode_scene`] started with `xi = 0`, `u = 1` (energy 0.5 J).
fn one_mode_system(f_hz: f64, t60: Option<f64>, w_pick: f64, displacement: bool) -> PwlSystem {
    let mut sys = PwlSystem::from_scene(&one_mode_scene(f_hz, t60, w_pick, displacement)).unwrap();
    assert_eq!(sys.n(), 1);
    sys.z0 = vec![0.0, 1.0];
    sys
}

fn assert_finite(out: &SimOutput, what: &str) {
    assert!(!out.diverged, "{what}: diverged");
    for (name, v) in [
        ("pickup", &out.pickup),
        ("x_hammer", &out.x_hammer),
        ("energy", &out.energy),
    ] {
        assert!(v.iter().all(|x| x.is_finite()), "{what}: non-finite {name}");
    }
}

/// (1) Free damped mode: each method converges to the closed-form damped
/// sinusoid with its order.
#[test]
fn free_mode_converges_with_expected_order() {
    let f = 1000.0;
    let t60 = 0.2;
    let w_pick = 0.7;
    let omega = 2.0 * PI * f;
    let sigma = LN_1000 / t60;
    let omega_d = (omega * omega - sigma * sigma).sqrt();
    let n_out = 882; // 20 ms, 20 periods
                     // xi(0) = 0, u(0) = 1: q = e^{-sigma t} sin(omega_d t) / omega_d, u = q'
    let exact: Vec<f64> = (0..n_out)
        .map(|j| {
            let t = j as f64 / RATE;
            w_pick
                * (-sigma * t).exp()
                * ((omega_d * t).cos() - sigma / omega_d * (omega_d * t).sin())
        })
        .collect();
    let sys = one_mode_system(f, Some(t60), w_pick, false);
    let oversamples = [1usize, 2, 4, 8, 16];
    println!(
        "free mode f = {f} Hz, T60 = {t60} s, omega h = {:.4} at 1x; rel L2 of the velocity pickup over 20 ms",
        omega / RATE
    );
    for (method, expected) in [
        (Method::SymplecticEuler, 1.0),
        (Method::StormerVerlet, 2.0),
        (Method::Rk4, 4.0),
        (Method::Trapezoid, 2.0),
    ] {
        let errs: Vec<f64> = oversamples
            .iter()
            .map(|&os| {
                let out = simulate(&sys, method, RATE, os, n_out);
                assert_finite(&out, method.name());
                assert!(out.contacts.is_empty(), "{}: hammer touched", method.name());
                rel_l2(&out.pickup, &exact)
            })
            .collect();
        let orders: Vec<f64> = errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
        println!(
            "  {:17} errors {}  orders {}",
            method.name(),
            errs.iter()
                .map(|e| format!("{e:.3e}"))
                .collect::<Vec<_>>()
                .join(" "),
            orders
                .iter()
                .map(|o| format!("{o:.3}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        // the asymptotic orders: the last two refinements
        for &o in &orders[orders.len() - 2..] {
            assert!(
                (o - expected).abs() < 0.25,
                "{}: observed order {o:.3}, expected {expected}",
                method.name()
            );
        }
        assert!(errs[4] < errs[0], "{}: no convergence", method.name());
    }
    // displacement pickups use the displacement row: x = w q
    let exact_disp: Vec<f64> = (0..n_out)
        .map(|j| {
            let t = j as f64 / RATE;
            w_pick * (-sigma * t).exp() * (omega_d * t).sin() / omega_d
        })
        .collect();
    let sys = one_mode_system(f, Some(t60), w_pick, true);
    let out = simulate(&sys, Method::Rk4, RATE, 4, n_out);
    let err = rel_l2(&out.pickup, &exact_disp);
    println!("  rk4 displacement pickup at 4x: rel L2 {err:.3e}");
    assert!(err < 1e-5, "displacement pickup: rel L2 {err}");
}

/// (2) Hammer against a rigid wall, no gravity: contact time -> pi / omega_d
/// and restitution -> exp(-zeta pi / sqrt(1 - zeta^2)).
#[test]
fn wall_contact_time_and_restitution_converge() {
    let (m, k, v0): (f64, f64, f64) = (0.01, 1e5, -1.0);
    let zeta: f64 = 0.1;
    let c = 2.0 * zeta * (k * m).sqrt();
    let omega_n = (k / m).sqrt();
    let omega_d = omega_n * (1.0 - zeta * zeta).sqrt();
    let t_exact = PI / omega_d;
    let e_exact = (-zeta * PI / (1.0 - zeta * zeta).sqrt()).exp();
    let sys = PwlSystem::from_scene(&wall_strike(m, k, c, 0.0, v0)).unwrap();
    assert_eq!(sys.n(), 0);
    let n_out = 221; // 5 ms; the contact lasts ~1 ms
    println!(
        "wall: m = {m}, k = {k:e}, zeta = {zeta}: contact time {t_exact:.6e} s, restitution {e_exact:.6}"
    );
    println!("  relative errors (contact time / restitution) at oversampling 1, 2, 4, ..., 64");
    for method in Method::ALL {
        let mut line = format!("  {:17}", method.name());
        for os in [1usize, 2, 4, 8, 16, 32, 64] {
            let out = simulate(&sys, method, RATE, os, n_out);
            assert_finite(&out, method.name());
            assert_eq!(
                out.contacts.len(),
                1,
                "{} at {os}x: contacts {:?}",
                method.name(),
                out.contacts
            );
            let (t0, t1) = out.contacts[0];
            let x = &out.x_hammer;
            let v_out = (x[n_out - 1] - x[n_out - 2]) * RATE;
            let te = ((t1 - t0) - t_exact) / t_exact;
            let ee = (v_out / v0.abs() - e_exact) / e_exact;
            line += &format!("  {te:+.2e}/{ee:+.2e}");
            let h = 1.0 / (RATE * os as f64);
            assert!(
                te.abs() <= 2.5 * h / t_exact,
                "{} at {os}x: contact time error {te:.3e} beyond the grid",
                method.name()
            );
            if os == 64 {
                assert!(
                    te.abs() < 2e-3 && ee.abs() < 2e-3,
                    "{} at 64x: contact time error {te:.3e}, restitution error {ee:.3e}",
                    method.name()
                );
            }
        }
        println!("{line}");
    }
}

/// Run one undamped 1 kHz mode at `omega h` (oversampling 1).
fn undamped_at(method: Method, omega_h: f64, n_out: usize) -> SimOutput {
    let f = 1000.0;
    let sys = one_mode_system(f, None, 1.0, false);
    let rate = 2.0 * PI * f / omega_h;
    simulate(&sys, method, rate, 1, n_out)
}

/// (3) Stability limits on an undamped mode: symplectic Euler and Verlet at
/// omega h <= 2, RK4 at 2 sqrt 2, the trapezoid for any omega h (and it
/// conserves the undamped free energy to round-off per step).
#[test]
fn stability_limits() {
    let n_out = 2000;
    for method in [Method::SymplecticEuler, Method::StormerVerlet] {
        let bounded = undamped_at(method, 1.95, n_out);
        assert_finite(&bounded, method.name());
        let emax = bounded.energy.iter().cloned().fold(0.0, f64::max);
        let unstable = undamped_at(method, 2.05, n_out);
        println!(
            "{:17} omega h = 1.95: max E/E0 = {:.3}; omega h = 2.05: diverged = {} after {} steps",
            method.name(),
            emax / bounded.energy[0],
            unstable.diverged,
            unstable.fine_steps
        );
        assert!(emax < 100.0 * bounded.energy[0], "{}", method.name());
        assert!(unstable.diverged, "{} at omega h = 2.05", method.name());
        assert!(unstable.pickup.last().unwrap().is_nan());
    }
    let bounded = undamped_at(Method::Rk4, 2.75, n_out);
    assert_finite(&bounded, "rk4");
    let unstable = undamped_at(Method::Rk4, 2.9, n_out);
    println!(
        "rk4               omega h = 2.75: E_end/E0 = {:.3e}; omega h = 2.9: diverged = {} after {} steps",
        bounded.energy[n_out - 1] / bounded.energy[0],
        unstable.diverged,
        unstable.fine_steps
    );
    assert!(bounded.energy[n_out - 1] <= bounded.energy[0]);
    assert!(unstable.diverged, "rk4 at omega h = 2.9");

    for omega_h in [0.1, 2.05, 2.9, 10.0, 1e3, 1e6] {
        let out = undamped_at(Method::Trapezoid, omega_h, 10_000);
        assert_finite(&out, "trapezoid");
        let e0 = out.energy[0];
        let max_step = out
            .energy
            .windows(2)
            .map(|w| (w[1] - w[0]).abs() / e0)
            .fold(0.0, f64::max);
        let drift = (out.energy[out.energy.len() - 1] / e0 - 1.0).abs();
        println!(
            "trapezoid         omega h = {omega_h:e}: max |dE|/E0 per step {max_step:.2e}, drift over 1e4 steps {drift:.2e}"
        );
        assert!(max_step < 1e-12, "trapezoid at omega h = {omega_h}");
        assert!(drift < 1e-10, "trapezoid at omega h = {omega_h}");
        assert!(out.max_energy_increase < 1e-12);
    }
}

/// (4) The paper's bouncing preset at 64x: finite output and a bounce pattern
/// from every method.
#[test]
fn paper_bounce_bounces() {
    let sc = preset("paper-bounce");
    let sys = PwlSystem::from_scene(&sc).unwrap();
    let n_out = (sc.duration_s * RATE) as usize + 1;
    let mut first_starts = Vec::new();
    for method in Method::ALL {
        let out = simulate(&sys, method, RATE, 64, n_out);
        assert_finite(&out, method.name());
        println!(
            "paper-bounce {:17} 64x: {} contacts, first at {:.6} s, last at {:.4} s, max step energy increase {:+.2e} E0, E_end/E0 {:.3e}, resolves {}, ambiguous {}",
            method.name(),
            out.contacts.len(),
            out.contacts.first().map_or(f64::NAN, |c| c.0),
            out.contacts.last().map_or(f64::NAN, |c| c.0),
            out.max_energy_increase,
            out.energy[n_out - 1] / out.energy[0],
            out.resolves,
            out.ambiguous_steps
        );
        assert!(
            out.contacts.len() > 3,
            "{}: {} contacts",
            method.name(),
            out.contacts.len()
        );
        assert!(out.pickup.iter().any(|v| v.abs() > 0.0));
        first_starts.push(out.contacts[0].0);
    }
    // free fall from 2 cm: first impact at sqrt(2 h / g) (the object rests at 0)
    let t_fall = (2.0 * 0.02 / 9.81f64).sqrt();
    for t in first_starts {
        assert!(
            (t - t_fall).abs() < 1e-5,
            "first contact at {t}, free fall {t_fall}"
        );
    }
}

/// The string preset (dense object, 102 states): every method is finite at 4x
/// and close to RK4 at 32x over the first 20 ms.
#[test]
fn paper_string_methods_agree() {
    let sc = preset("paper-string");
    let sys = PwlSystem::from_scene(&sc).unwrap();
    assert_eq!(sys.dim(), 102);
    println!("paper-string nnz (B, -B^T, -D, d, f) = {:?}", sys.nnz());
    let n_out = 883;
    let reference = simulate(&sys, Method::Rk4, RATE, 32, n_out);
    assert_finite(&reference, "rk4 reference");
    for method in Method::ALL {
        let t = std::time::Instant::now();
        let out = simulate(&sys, method, RATE, 4, n_out);
        let dt = t.elapsed().as_secs_f64();
        assert_finite(&out, method.name());
        let err = rel_l2(&out.pickup, &reference.pickup);
        println!(
            "paper-string {:17} 4x: rel L2 vs rk4 32x {err:.3e}, {} contacts, max step energy increase {:+.2e} E0, {:.0} ns per fine step",
            method.name(),
            out.contacts.len(),
            out.max_energy_increase,
            dt * 1e9 / out.fine_steps as f64
        );
        assert!(err < 0.5, "{}: rel L2 {err}", method.name());
    }
}
