//! The reference checked against what it must reproduce: closed forms for a
//! hammer on a rigid wall, and an unrelated integrator (DOP853) on modal
//! objects. Run with `--nocapture` to see the residuals.

use crate::{dop853, horizon, solve, BackMass, Contact, Hammer, Mode, Model, Solution};
use std::f64::consts::PI;

const RATE: f64 = 44_100.0;
const NYQUIST: f64 = RATE / 2.0;

/// A hammer of mass `m` moving down at 1 m/s from 0.1 mm above a rigid wall,
/// contact at `ratio` times the Nyquist frequency with damping ratio `zeta`.
fn wall(m: f64, ratio: f64, zeta: f64) -> Model {
    let w0 = 2.0 * PI * ratio * NYQUIST;
    let k = m * w0 * w0;
    Model {
        modes: Vec::new(),
        hammer: Hammer {
            mass_kg: m,
            height_m: 1e-4,
            velocity_m_per_s: -1.0,
            gravity_m_per_s2: 0.0,
        },
        contact: Contact {
            stiffness_n_per_m: k,
            damping_n_s_per_m: 2.0 * zeta * (k * m).sqrt(),
        },
        back: None,
        extra: Vec::new(),
    }
}

/// Hammer on a rigid wall: with `p = -x_h`, contact obeys `m p'' = -k p -
/// c p'`, so from `p(0) = 0`, `p'(0) = v` the penetration is `v/w_d
/// e^{-zeta w0 t} sin(w_d t)`: the contact lasts `pi / w_d` and the hammer
/// leaves at `exp(-zeta pi / sqrt(1 - zeta^2))` of its impact speed.
///
/// Tolerance 1e-10 relative: the instants are located to one time unit
/// (1e-15 of a sample, 1e-12 of the shortest contact here, 5e-4 samples at
/// 1000x Nyquist) and the flows are double-double, so what remains is the
/// f64 rounding of the parameters, of the result and of the instants'
/// sums (measured <= 3e-12); a located switch off by one sub-step, or an
/// unbalanced exponential (whose `sin(w t)/w` entry would be off by `u w^2
/// ~ 1`), misses by orders more.
#[test]
fn rigid_wall_closed_forms() {
    let m = 0.02;
    let mut worst: f64 = 0.0;
    for zeta in [0.0, 0.1, 0.7] {
        for ratio in [1.0, 3.7, 31.9, 317.3, 1000.0] {
            let model = wall(m, ratio, zeta);
            let w0 = 2.0 * PI * ratio * NYQUIST;
            let wd = w0 * (1.0 - zeta * zeta).sqrt();
            let t_in = 1e-4;
            let dur = PI / wd;
            let e = (-zeta * PI / (1.0 - zeta * zeta).sqrt()).exp();
            let n = ((t_in + dur) * RATE).ceil() as usize + 2;
            let sol = solve(&model, RATE, n);
            assert_eq!(
                sol.contacts.len(),
                1,
                "zeta {zeta} ratio {ratio}: {:?}",
                sol.contacts
            );
            let c = sol.contacts[0];
            let end = c.end_s.expect("contact ended");
            let err_start = (c.start_s - t_in).abs() / t_in;
            let err_dur = ((end - c.start_s) - dur).abs() / dur;
            // no gravity: the hammer keeps its release velocity
            let v_out = sol.samples[n].v_hammer;
            let err_e = (v_out - e).abs() / e;
            // elastic: the energy comes back whole
            let e0 = sol.samples[0].energy;
            let err_energy = if zeta == 0.0 {
                (sol.samples[n].energy - e0).abs() / e0
            } else {
                0.0
            };
            println!(
                "wall zeta {zeta:3} f_c {ratio:6.1}x Nyquist: contact {:.3e} samples, sub-steps {:>5}/sample; \
                 start {err_start:.1e}, duration {err_dur:.1e}, restitution {err_e:.1e}, energy {err_energy:.1e}",
                dur * RATE,
                sol.stats.substeps_per_sample[1]
            );
            for (what, err) in [
                ("start", err_start),
                ("duration", err_dur),
                ("restitution", err_e),
                ("energy", err_energy),
            ] {
                assert!(
                    err < 1e-10,
                    "wall zeta {zeta} ratio {ratio}: {what} off by {err:e} (relative)"
                );
                worst = worst.max(err);
            }
        }
    }
    println!("wall: worst relative error {worst:.1e}");
}

/// Hammer on a rigid wall with critical (`zeta = 1`) or overdamped (`zeta =
/// 5`) contact: from `p(0) = 0`, `p'(0) = v` the penetration is `v t
/// e^{-w0 t}` or `v (e^{r1 t} - e^{r2 t}) / (r1 - r2)`, `r1,2 = -w0 (zeta
/// -+ sqrt(zeta^2 - 1))`, and never returns to zero: one contact that does
/// not end while `p` is representable (it underflows to 0 after ~700 / w0
/// and then counts as released), and the hammer height `-p` at every
/// sample.
///
/// The contact starts `3 / w0` before a sample instant. Tolerance 1e-10
/// relative to the exact value at each sample (while it is above 1e-250 m): the critical case is the defective matrix a modal
/// decomposition cannot take, and the overdamped one is stiff (decay rates
/// 0.1 w0 and 9.9 w0, up to 1.4e9 1/s here); the balanced exponentials keep
/// the slow decay to ~`u |B| t` (measured <= 2e-11).
#[test]
fn rigid_wall_critical_and_overdamped_traces() {
    let m = 0.02;
    let mut worst: f64 = 0.0;
    for zeta in [1.0, 5.0] {
        for ratio in [1.0, 3.7, 31.9, 317.3, 1000.0] {
            let mut model = wall(m, ratio, zeta);
            let w0 = 2.0 * PI * ratio * NYQUIST;
            // enter 3 / w0 before sample 5, so that the stiffest cases
            // still have a sample before p underflows
            let t_in = 5.0 / RATE - 3.0 / w0;
            model.hammer.height_m = t_in;
            let n = 60;
            let sol = solve(&model, RATE, n);
            let p_exact = |t: f64| {
                if zeta == 1.0 {
                    t * (-w0 * t).exp()
                } else {
                    let s = (zeta * zeta - 1.0).sqrt();
                    let (r1, r2) = (-w0 * (zeta - s), -w0 * (zeta + s));
                    ((r1 * t).exp() - (r2 * t).exp()) / (r1 - r2)
                }
            };
            let mut err: f64 = 0.0;
            let mut checked = 0;
            let mut last_checked = 0.0;
            for (i, s) in sol.samples.iter().enumerate() {
                let t = i as f64 / RATE - t_in;
                if t <= 0.0 {
                    continue;
                }
                let exact = -p_exact(t);
                if exact.abs() > 1e-250 {
                    err = err.max((s.x_hammer - exact).abs() / exact.abs());
                    checked += 1;
                    last_checked = i as f64 / RATE;
                }
            }
            println!(
                "wall zeta {zeta} f_c {ratio:6.1}x Nyquist: {} contact(s), {checked} samples checked, max relative error {err:.1e}",
                sol.contacts.len()
            );
            assert_eq!(sol.contacts.len(), 1, "zeta {zeta} ratio {ratio}");
            if let Some(end) = sol.contacts[0].end_s {
                assert!(
                    end > last_checked,
                    "zeta {zeta} ratio {ratio}: the contact ended at {end:e} s, before p underflowed"
                );
            }
            assert!(checked > 0);
            assert!(
                err < 1e-10,
                "zeta {zeta} ratio {ratio}: hammer height off by {err:e} (relative)"
            );
            worst = worst.max(err);
        }
    }
    println!("wall, critical and overdamped: worst relative error {worst:.1e}");
}

/// A 4-mode object (one mode above Nyquist, the rest damped) struck by a
/// hammer of mass `m_h` at `v0` from `x0`, under gravity `g`, contact at
/// `ratio` times Nyquist (two-mass frequency, see the body) with damping
/// ratio `zeta`.
fn object(m_h: f64, x0: f64, v0: f64, g: f64, ratio: f64, zeta: f64) -> Model {
    let modes = vec![
        Mode {
            freq_hz: 311.0,
            t60_s: Some(0.6),
            weight: 2.0,
        },
        Mode {
            freq_hz: 1303.0,
            t60_s: Some(0.3),
            weight: -1.5,
        },
        Mode {
            freq_hz: 7411.0,
            t60_s: None,
            weight: 1.2,
        },
        Mode {
            freq_hz: 1.2 * NYQUIST,
            t60_s: Some(0.02),
            weight: 0.9,
        },
    ];
    // 1/m_eff = sum w^2: the object's mass at the contact point for a
    // contact much shorter than its modes' periods
    let inv_eff: f64 = modes.iter().map(|m| m.weight * m.weight).sum();
    let inv_m = 1.0 / m_h + inv_eff;
    let w = 2.0 * PI * ratio * NYQUIST;
    let k = w * w / inv_m;
    Model {
        modes,
        hammer: Hammer {
            mass_kg: m_h,
            height_m: x0,
            velocity_m_per_s: v0,
            gravity_m_per_s2: g,
        },
        contact: Contact {
            stiffness_n_per_m: k,
            damping_n_s_per_m: 2.0 * zeta * (k / inv_m).sqrt(),
        },
        back: None,
        extra: Vec::new(),
    }
}

/// Relative L2 difference `|a - b| / |b|` (0 when both are zero).
fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    if num == 0.0 {
        0.0
    } else {
        (num / den).sqrt()
    }
}

/// Largest difference of matched contact instants [samples] among the
/// contacts that start within the first `t_max` seconds (`None` when their
/// counts differ). An end is compared when both runs have it.
fn max_dt(a: &Solution, b: &Solution, t_max: f64) -> Option<f64> {
    let ca: Vec<_> = a.contacts.iter().filter(|c| c.start_s <= t_max).collect();
    let cb: Vec<_> = b.contacts.iter().filter(|c| c.start_s <= t_max).collect();
    if ca.len() != cb.len() {
        return None;
    }
    let mut dt: f64 = 0.0;
    for (x, y) in ca.iter().zip(&cb) {
        dt = dt.max((x.start_s - y.start_s).abs());
        if let (Some(ex), Some(ey)) = (x.end_s, y.end_s) {
            dt = dt.max((ex - ey).abs());
        }
    }
    Some(dt * RATE)
}

/// The expm reference against DOP853 on moderately stiff cases (contact at
/// 0.45x to 3.1x Nyquist, hammer 0.03x to 10x the object's effective mass,
/// elastic to critically damped, with and without gravity; the 4-mode
/// object has a mode above Nyquist, overdamped contacts are stiff).
///
/// Where: chaotic cases (rattles, a heavy hammer chattering) amplify any
/// difference ~10x per contact, DOP853's truncation error included. So each
/// case is compared on its predictability horizon ([`crate::horizon`]): the
/// window on which a second expm run, disturbed by 1e-9 (relative;
/// [`Model::perturbed`]), stays within 1e-7 relative L2 of the first. On it
/// a 1e-9 disturbance grows to at most ~1e-7, and DOP853's error, which
/// starts ~1e-12, grows by the same factor.
///
/// Tolerances, for DOP853 at rtol 1e-13: 1e-8 relative L2 on the hammer
/// height and velocity and the contact displacement (measured: <= 1e-9), and
/// 1e-6 samples on contact instants (measured: <= 1e-7). Instants are more
/// sensitive than the traces: a contact entered at a small relative speed
/// `v` moves by `dp / v` (the disturbed run's instants move by up to 2e-5
/// samples inside its horizon while its traces agree to 1e-7). That the
/// remaining difference is DOP853's and not the reference's is checked by
/// convergence: at rtol 1e-12 it must be larger (by ~10x, DOP853 being 8th
/// order: asserted > 2x) wherever it exceeds 1e-8 samples (below that
/// DOP853 reaches its rounding floor on the overdamped cases, whose
/// releases are ill-conditioned: `p` and `p'` are small differences there).
/// A switch located a sub-step off (1e-2 sample), a wrong sign or a missing
/// term in one of the two independent phase descriptions (matrix vs
/// right-hand side) gives 1e-4 or more, and would not converge. Each case must offer a horizon of at least 50
/// samples (the chattering heavy hammer has 101).
#[test]
fn expm_matches_dop853() {
    let cases = [
        (
            "soft strike, no gravity",
            object(0.01, 2e-4, -1.0, 0.0, 0.45, 0.1),
        ),
        (
            "stiff elastic, equal masses",
            object(0.24, 1e-4, -0.5, 0.0, 3.1, 0.0),
        ),
        (
            "stiff damped, light hammer",
            object(0.003, 0.0, -2.0, 0.0, 2.7, 0.3),
        ),
        (
            "critical rattle, gravity",
            object(0.01, 1e-3, 0.0, 9.81, 3.1, 1.0),
        ),
        (
            "elastic rattle, gravity",
            object(0.01, 1e-3, 0.0, 9.81, 3.1, 0.0),
        ),
        (
            "heavy hammer pressing",
            object(1.0, 0.0, -0.1, 0.0, 3.1, 0.0),
        ),
        (
            "heavy hammer, gravity",
            object(1.0, 1e-4, 0.0, 9.81, 2.3, 0.05),
        ),
        (
            "overdamped, heavy hammer",
            object(7.0, 0.0, -0.1, 0.0, 3.1, 5.0),
        ),
        (
            "overdamped rattle, gravity",
            object(0.01, 1e-3, 0.0, 9.81, 3.1, 5.0),
        ),
    ];
    let n = 2205;
    let mut failures = Vec::new();
    for (name, model) in cases {
        let t0 = std::time::Instant::now();
        let a = solve(&model, RATE, n);
        let ta = t0.elapsed().as_secs_f64();
        let hz = horizon(&a, &solve(&model.perturbed(1e-9), RATE, n), 1e-7);
        let w = hz + 1;
        let t_max = hz as f64 / RATE;
        let within = |s: &Solution| s.contacts.iter().filter(|c| c.start_s <= t_max).count();
        let mut dts = [0.0; 2];
        for (r, rtol) in [1e-12, 1e-13].into_iter().enumerate() {
            let t0 = std::time::Instant::now();
            let b = dop853::solve(&model, RATE, n, rtol);
            let tb = t0.elapsed().as_secs_f64();
            let ex = rel_l2(&a.x_hammer()[..w], &b.x_hammer()[..w]);
            let ev = rel_l2(&a.v_hammer()[..w], &b.v_hammer()[..w]);
            let ec = rel_l2(&a.x_contact()[..w], &b.x_contact()[..w]);
            let dt = max_dt(&a, &b, t_max);
            println!(
                "{name:<28} rtol {rtol:.0e}: horizon {hz:>4} samples, contacts {:>3}/{:<3} (in 50 ms {:>3}/{:<3}) \
                 x_h {ex:.1e}  v_h {ev:.1e}  x_c {ec:.1e}  max dt {} samples  \
                 (expm {ta:.2} s, {}/{} sub-steps; dop853 {tb:.2} s, {} steps)",
                within(&a),
                within(&b),
                a.contacts.len(),
                b.contacts.len(),
                dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
                a.stats.substeps_per_sample[0],
                a.stats.substeps_per_sample[1],
                b.stats.steps,
            );
            let Some(dt) = dt else {
                failures.push(format!(
                    "{name}, rtol {rtol:e}: contact counts differ within the horizon: expm {} dop853 {}",
                    within(&a),
                    within(&b)
                ));
                continue;
            };
            dts[r] = dt;
            if rtol == 1e-13 {
                for (what, err, tol) in [
                    ("x_h", ex, 1e-8),
                    ("v_h", ev, 1e-8),
                    ("x_c", ec, 1e-8),
                    ("contact instants [samples]", dt, 1e-6),
                ] {
                    if !(err < tol) {
                        failures.push(format!("{name}: {what} disagree by {err:e} > {tol:e}"));
                    }
                }
            }
        }
        if dts[1] > 1e-8 && !(dts[0] > 2.0 * dts[1]) {
            failures.push(format!(
                "{name}: contact instants do not converge with DOP853's tolerance: {:e} (1e-12) vs {:e} (1e-13) samples",
                dts[0], dts[1]
            ));
        }
        if hz < 50 {
            failures.push(format!("{name}: horizon {hz} < 50 samples"));
        }
        if a.contacts.is_empty() {
            failures.push(format!("{name}: no contact"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A heavy hammer (1000x the object's effective mass) pressed at 0.1 m/s into
/// the 4-mode object through a stiff (101.7x Nyquist), critically damped or
/// overdamped contact, with and without gravity: the object rides on the
/// hammer, the contact's fast decay (`c / m_eff` ~ 3e7..1.4e8 1/s) sits next
/// to the object's modes (2e3..2e5 rad/s), and the contact force is a tiny
/// difference `k (x_c - x_h)` of large terms (`|p| / |x_h|` ~ 1e-8). With the
/// phase matrix rounded to f64 entry by entry the reference solved a slightly
/// different contact (its spring also pulled on `x_h` and the `q_i` with
/// stiffness ~`u k`): hammer height 4e-11 off DOP853 after 10 ms and growing
/// about as `t^2` (1.2e-8 after 50 ms at the plugin's `C3 zeta 1`), while
/// DOP853, which forms `p` first, and the engine agreed to 3e-14. The
/// double-double entries ([`crate::phase::augmented_matrix`]) remove it.
///
/// Tolerances, against DOP853 at rtol 1e-13 over 10 ms: 1e-12 relative L2
/// on hammer height and velocity and contact displacement (measured <=
/// 4e-14; the f64 entries gave 4e-11), 1e-7 samples on contact instants
/// (measured <= 3e-8). DOP853 must itself be converged there: at rtol 1e-12
/// its traces must stay within 2e-12 of its rtol 1e-13 run (measured <=
/// 5e-13, on the contact displacement; its 8th order puts the rtol 1e-13
/// run ~10x closer to the exact solution).
#[test]
fn strongly_damped_heavy_hammer_matches_dop853() {
    let m_eff = 1.0 / 8.5;
    let cases = [
        (
            "heavy hammer, critical, 101.7x",
            object(1000.0 * m_eff, 0.0, -0.1, 0.0, 101.7, 1.0),
        ),
        (
            "heavy hammer, overdamped, 101.7x",
            object(1000.0 * m_eff, 0.0, -0.1, 0.0, 101.7, 5.0),
        ),
        (
            "heavy hammer, critical, gravity",
            object(1000.0 * m_eff, 0.0, -0.1, 9.81, 101.7, 1.0),
        ),
    ];
    let n = 441;
    let traces = |s: &Solution| [s.x_hammer(), s.v_hammer(), s.x_contact()];
    let mut failures = Vec::new();
    for (name, model) in cases {
        let a = solve(&model, RATE, n);
        let b = dop853::solve(&model, RATE, n, 1e-13);
        let b12 = dop853::solve(&model, RATE, n, 1e-12);
        let (ta, tb, tb12) = (traces(&a), traces(&b), traces(&b12));
        let err: Vec<f64> = (0..3).map(|k| rel_l2(&ta[k], &tb[k])).collect();
        let conv: Vec<f64> = (0..3).map(|k| rel_l2(&tb12[k], &tb[k])).collect();
        let dt = max_dt(&a, &b, f64::INFINITY);
        println!(
            "{name:<34} contacts {:>2}/{:<2} sub-steps {:?}: x_h {:.1e}  v_h {:.1e}  x_c {:.1e}  max dt {} samples \
             (DOP853 1e-12 vs 1e-13: x_h {:.1e}  v_h {:.1e}  x_c {:.1e})",
            a.contacts.len(),
            b.contacts.len(),
            a.stats.substeps_per_sample,
            err[0],
            err[1],
            err[2],
            dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
            conv[0],
            conv[1],
            conv[2],
        );
        if a.contacts.len() < 2 {
            failures.push(format!("{name}: {} contact(s)", a.contacts.len()));
        }
        for (k, what) in ["x_h", "v_h", "x_c"].iter().enumerate() {
            if !(conv[k] < 2e-12) {
                failures.push(format!(
                    "{name}: DOP853 not converged on {what}: {:e}",
                    conv[k]
                ));
            }
            if !(err[k] < 1e-12) {
                failures.push(format!("{name}: {what} disagrees by {:e} > 1e-12", err[k]));
            }
        }
        match dt {
            Some(dt) if dt < 1e-7 => {}
            Some(dt) => failures.push(format!(
                "{name}: contact instants disagree by {dt:e} > 1e-7 samples"
            )),
            None => failures.push(format!(
                "{name}: contact counts differ: expm {} dop853 {}",
                a.contacts.len(),
                b.contacts.len()
            )),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The flows are exact, so the sub-step length must not matter beyond
/// rounding: the reference with sub-steps 4x shorter (`|B|_1 h_sub <=
/// 0.125`) on non-chaotic stiff cases (one contact at 101.7x and 1013.7x
/// Nyquist, a damped bounce, an overdamped heavy hammer; in a chaotic
/// rattle any rounding difference grows without bound).
///
/// Tolerance 1e-9 relative L2 and 1e-8 samples: the exact states are
/// double-double, so the two runs differ only where their time units fall
/// (up to 1e-15 sample apart: 1e-12 of a contact at 1000x Nyquist) and in
/// the final rounding (measured <= 1e-13 and 1e-10 samples; in f64 the
/// overdamped case moved by 3e-10 and 1e-9 samples).
#[test]
fn reference_does_not_depend_on_its_substeps() {
    let cases = [
        (
            "one contact, 101.7x",
            object(1e-7, 0.0, -1.0, 0.0, 101.7, 0.0),
        ),
        (
            "one contact, 1013.7x",
            object(1e-7, 0.0, -1.0, 0.0, 1013.7, 0.1),
        ),
        (
            "damped bounce, 31.3x",
            object(0.001, 1e-3, 0.0, 9.81, 31.3, 0.3),
        ),
        (
            "overdamped, heavy hammer",
            object(7.0, 0.0, -0.1, 0.0, 3.1, 5.0),
        ),
    ];
    let n = 2205;
    for (name, model) in cases {
        let a = solve(&model, RATE, n);
        let b = crate::solve_with_substeps(&model, RATE, n, 0.125);
        let ex = rel_l2(&a.x_hammer(), &b.x_hammer());
        let ev = rel_l2(&a.v_hammer(), &b.v_hammer());
        let ec = rel_l2(&a.x_contact(), &b.x_contact());
        let dt = max_dt(&a, &b, f64::INFINITY);
        println!(
            "{name:<26} contacts {:>3}, sub-steps {:?} vs {:?}: x_h {ex:.1e}  v_h {ev:.1e}  x_c {ec:.1e}  max dt {} samples",
            a.contacts.len(),
            a.stats.substeps_per_sample,
            b.stats.substeps_per_sample,
            dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
        );
        let dt = dt.unwrap_or_else(|| {
            panic!(
                "{name}: contact counts differ: {} vs {}",
                a.contacts.len(),
                b.contacts.len()
            )
        });
        for (what, err, tol) in [
            ("x_h", ex, 1e-9),
            ("v_h", ev, 1e-9),
            ("x_c", ec, 1e-9),
            ("contact instants [samples]", dt, 1e-8),
        ] {
            assert!(
                err < tol,
                "{name}: {what} changes by {err:e} > {tol:e} with shorter sub-steps"
            );
        }
    }
}

/// A lossless run keeps its energy (the flows and the switches add none):
/// the per-sample energy of an undamped object struck elastically drifts by
/// rounding only (< 1e-10 relative over 2205 samples and every contact).
#[test]
fn lossless_energy_is_kept() {
    let mut model = object(0.05, 1e-3, 0.0, 9.81, 31.3, 0.0);
    for m in &mut model.modes {
        m.t60_s = None;
    }
    let sol = solve(&model, RATE, 2205);
    let e0 = sol.samples[0].energy;
    let drift = sol
        .samples
        .iter()
        .map(|s| (s.energy - e0).abs() / e0.abs())
        .fold(0.0, f64::max);
    println!(
        "lossless rattle at 31.3x Nyquist: {} contacts, max |E/E0 - 1| = {drift:.1e}",
        sol.contacts.len()
    );
    assert!(sol.contacts.len() > 1);
    assert!(drift < 1e-10, "energy drift {drift:e}");
}

/// A mallet of two masses (face and a back mass on a spring-damper, the
/// lumped model of a head on a flexible shaft) against the 4-mode object:
/// the expm reference (the back mass in its double-double phase matrix)
/// against DOP853 (the back mass in its right-hand side), and energy kept
/// when nothing is damped. Same tolerances as [`expm_matches_dop853`] on
/// the same kind of horizon, plus the back mass's own height.
#[test]
fn back_mass_expm_matches_dop853() {
    let with_back = |mut m: Model, m_b: f64, f_b: f64, zeta_b: f64| {
        // the mallet's own mode: omega^2 = k_s (1/m_h + 1/m_b)
        let inv = 1.0 / m.hammer.mass_kg + 1.0 / m_b;
        let w = 2.0 * PI * f_b;
        let k_s = w * w / inv;
        m.back = Some(BackMass {
            mass_kg: m_b,
            spring_n_per_m: k_s,
            damping_n_s_per_m: 2.0 * zeta_b * (k_s / inv).sqrt(),
        });
        m
    };
    let cases = [
        (
            "soft face, ringing shaft",
            with_back(object(0.005, 2e-4, -1.0, 0.0, 0.45, 0.1), 0.02, 900.0, 0.02),
        ),
        (
            "stiff face, heavy back, gravity",
            with_back(object(0.01, 1e-3, 0.0, 9.81, 3.1, 0.3), 0.1, 450.0, 0.05),
        ),
        (
            "elastic, undamped shaft",
            with_back(object(0.02, 1e-4, -0.5, 0.0, 2.2, 0.0), 0.01, 2500.0, 0.0),
        ),
    ];
    let n = 2205;
    let mut failures = Vec::new();
    for (name, model) in cases {
        let a = solve(&model, RATE, n);
        let hz = horizon(&a, &solve(&model.perturbed(1e-9), RATE, n), 1e-7);
        let w = hz + 1;
        let b = dop853::solve(&model, RATE, n, 1e-13);
        let back = |s: &Solution| s.samples[..w].iter().map(|x| x.x_back).collect::<Vec<_>>();
        let errs = [
            ("x_h", rel_l2(&a.x_hammer()[..w], &b.x_hammer()[..w])),
            ("v_h", rel_l2(&a.v_hammer()[..w], &b.v_hammer()[..w])),
            ("x_c", rel_l2(&a.x_contact()[..w], &b.x_contact()[..w])),
            ("x_b", rel_l2(&back(&a), &back(&b))),
        ];
        let dt = max_dt(&a, &b, hz as f64 / RATE);
        println!(
            "{name:<32} horizon {hz:>4}, contacts {}/{}, {}, max dt {} samples",
            a.contacts.len(),
            b.contacts.len(),
            errs.map(|(w, e)| format!("{w} {e:.1e}")).join(", "),
            dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
        );
        for (what, e) in errs {
            if !(e < 1e-8) {
                failures.push(format!("{name}: {what} disagree by {e:e}"));
            }
        }
        match dt {
            Some(dt) if dt < 1e-6 => {}
            _ => failures.push(format!("{name}: contact instants {dt:?}")),
        }
        if hz < 50 || a.contacts.is_empty() {
            failures.push(format!(
                "{name}: horizon {hz}, {} contacts",
                a.contacts.len()
            ));
        }
        // the back mass moves on its own: it is a mallet, not a rigid one
        let rel = a.samples[..w]
            .iter()
            .map(|s| (s.x_back - s.x_hammer).abs())
            .fold(0.0, f64::max);
        if !(rel > 0.0) {
            failures.push(format!(
                "{name}: the back mass never moved relative to the face"
            ));
        }
        if name.starts_with("elastic") {
            let e0 = a.samples[0].energy;
            // the object's modes are damped (all but one): energy never rises
            let rise = a
                .samples
                .windows(2)
                .map(|p| (p[1].energy - p[0].energy) / e0)
                .fold(f64::NEG_INFINITY, f64::max);
            if !(rise < 1e-12) {
                failures.push(format!("{name}: energy rose by {rise:e} of E0"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Several contacts: two hammers, each on its own object, the two objects'
/// modes in one model (each mode weighs 0 at the other hammer's point). The
/// contacts never interact, so the run must be the two single-contact runs
/// side by side: hammer heights, contact points and contact instants of
/// each within rounding of its own run, and the energy their sum.
#[test]
fn two_contacts_that_never_interact_are_two_runs() {
    use crate::ExtraHammer;
    // soft contacts (0.05x and 0.07x Nyquist, about 0.3 ms long) that
    // start about together, so the two are in contact at once
    let a = object(0.01, 2e-4, -1.0, 0.0, 0.05, 0.1);
    let mut b = object(0.03, 1.5e-4, -0.7, 9.81, 0.07, 0.3);
    for m in &mut b.modes {
        m.freq_hz *= 1.37;
        m.weight *= 0.8;
    }
    let (na, nb) = (a.modes.len(), b.modes.len());
    let mut modes = a.modes.clone();
    for m in &b.modes {
        modes.push(Mode { weight: 0.0, ..*m });
    }
    let mut extra_weights = vec![0.0; na];
    extra_weights.extend(b.modes.iter().map(|m| m.weight));
    let both = Model {
        modes,
        hammer: a.hammer,
        contact: a.contact,
        back: None,
        extra: vec![ExtraHammer {
            hammer: b.hammer,
            weights: extra_weights,
            contact: b.contact,
        }],
    };
    let n = 2205;
    let (sa, sb, s2) = (
        solve(&a, RATE, n),
        solve(&b, RATE, n),
        solve(&both, RATE, n),
    );
    let rel = |x: &[f64], y: &[f64]| rel_l2(x, y);
    let col = |s: &Solution, f: &dyn Fn(&crate::Sample) -> f64| {
        s.samples.iter().map(f).collect::<Vec<f64>>()
    };
    let errs = [
        rel(&col(&s2, &|x| x.x_hammer), &col(&sa, &|x| x.x_hammer)),
        rel(&col(&s2, &|x| x.x_contact), &col(&sa, &|x| x.x_contact)),
        rel(&col(&s2, &|x| x.extra[0][0]), &col(&sb, &|x| x.x_hammer)),
        rel(&col(&s2, &|x| x.extra[0][2]), &col(&sb, &|x| x.x_contact)),
        rel(
            &col(&s2, &|x| x.energy),
            &sa.samples
                .iter()
                .zip(&sb.samples)
                .map(|(x, y)| x.energy + y.energy)
                .collect::<Vec<_>>(),
        ),
    ];
    let of = |s: &Solution, c: usize| {
        s.contacts
            .iter()
            .filter(|x| x.contact == c)
            .copied()
            .collect::<Vec<_>>()
    };
    let (ca, cb) = (of(&s2, 0), of(&s2, 1));
    assert_eq!(ca.len(), sa.contacts.len());
    assert_eq!(cb.len(), sb.contacts.len());
    let mut dt: f64 = 0.0;
    for (x, y) in ca
        .iter()
        .zip(&sa.contacts)
        .chain(cb.iter().zip(&sb.contacts))
    {
        dt = dt.max((x.start_s - y.start_s).abs());
        if let (Some(ex), Some(ey)) = (x.end_s, y.end_s) {
            dt = dt.max((ex - ey).abs());
        }
    }
    let both_at_once = s2.samples.iter().filter(|x| x.active == 3).count();
    println!(
        "two separate contacts ({na} + {nb} modes): traces {:.1e}, contacts {}+{}, instants {:.1e} samples, {both_at_once} samples with both in contact",
        errs.iter().fold(0.0f64, |m, e| m.max(*e)),
        ca.len(),
        cb.len(),
        dt * RATE
    );
    for e in errs {
        assert!(e < 1e-10, "{errs:?}");
    }
    assert!(dt * RATE < 1e-8, "instants {dt:e} s");
    assert!(!ca.is_empty() && !cb.is_empty() && both_at_once > 0);
}

/// Two hammers on one undamped object, struck elastically so that their
/// contacts overlap: the energy (object, both hammers, both springs) is
/// kept to rounding through every switch of either contact, and two equal
/// hammers struck symmetrically on a one-mode object (equal weights) move
/// alike.
#[test]
fn two_hammers_on_one_object_keep_the_energy() {
    use crate::ExtraHammer;
    // soft contacts (0.08x Nyquist) arriving 0.1 and 0.16 ms after the start
    let mut model = object(0.02, 1e-4, -1.0, 0.0, 0.08, 0.0);
    for m in &mut model.modes {
        m.t60_s = None;
    }
    let weights: Vec<f64> = model.modes.iter().map(|m| -0.6 * m.weight + 0.3).collect();
    model.extra.push(ExtraHammer {
        hammer: Hammer {
            mass_kg: 0.015,
            height_m: 1.3e-4,
            velocity_m_per_s: -0.8,
            gravity_m_per_s2: 0.0,
        },
        weights,
        contact: model.contact,
    });
    let sol = solve(&model, RATE, 2205);
    let e0 = sol.samples[0].energy;
    let drift = sol
        .samples
        .iter()
        .map(|s| (s.energy - e0).abs() / e0)
        .fold(0.0, f64::max);
    let overlap = sol.samples.iter().filter(|s| s.active == 3).count();
    let per = |c: usize| sol.contacts.iter().filter(|x| x.contact == c).count();
    println!(
        "two hammers on one lossless object: contacts {} + {}, {overlap} samples both in contact, max |E/E0 - 1| = {drift:.1e}",
        per(0),
        per(1)
    );
    assert!(per(0) > 0 && per(1) > 0 && overlap > 0);
    assert!(drift < 1e-10, "energy drift {drift:e}");

    // symmetric: one mode, both hammers alike on equal weights
    let one = Mode {
        freq_hz: 311.0,
        t60_s: None,
        weight: 2.0,
    };
    let mut sym = object(0.01, 1e-4, -1.0, 0.0, 0.3, 0.2);
    sym.modes = vec![one];
    sym.extra.push(ExtraHammer {
        hammer: sym.hammer,
        weights: vec![2.0],
        contact: sym.contact,
    });
    let s = solve(&sym, RATE, 1000);
    let diff = s
        .samples
        .iter()
        .map(|x| (x.x_hammer - x.extra[0][0]).abs())
        .fold(0.0, f64::max);
    let scale = s
        .samples
        .iter()
        .map(|x| x.x_hammer.abs())
        .fold(0.0, f64::max);
    println!(
        "symmetric hammers: max height difference {:.1e} of {scale:.1e} m",
        diff
    );
    assert!(diff <= 1e-12 * scale, "{diff:e}");
    assert!(
        s.contacts.iter().filter(|x| x.contact == 0).count()
            == s.contacts.iter().filter(|x| x.contact == 1).count()
    );
}
