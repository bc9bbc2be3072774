//! The reference checked against what it must reproduce: closed forms for a
//! hammer on a rigid wall (and for masses on walls and on each other
//! through links), and an unrelated integrator (DOP853) on modal objects
//! (and on links between objects and masses). Run with `--nocapture` to see
//! the residuals.

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
        masses: vec![],
        links: vec![],
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
        masses: vec![],
        links: vec![],
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
/// counts differ), matched contact by contact (with several, two instants
/// a rounding apart may come in either order). An end is compared when
/// both runs have it.
fn max_dt(a: &Solution, b: &Solution, t_max: f64) -> Option<f64> {
    let mut dt: f64 = 0.0;
    for k in 0..=crate::MAX_EXTRA {
        let of = |s: &Solution| {
            s.contacts
                .iter()
                .filter(|c| c.contact == k && c.start_s <= t_max)
                .copied()
                .collect::<Vec<_>>()
        };
        let (ca, cb) = (of(a), of(b));
        if ca.len() != cb.len() {
            return None;
        }
        for (x, y) in ca.iter().zip(&cb) {
            dt = dt.max((x.start_s - y.start_s).abs());
            if let (Some(ex), Some(ey)) = (x.end_s, y.end_s) {
                dt = dt.max((ex - ey).abs());
            }
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
        compare_expm_dop853(name, &model, n, &mut failures);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// One case of [`expm_matches_dop853`]: `n` samples of `model` by the
/// reference and by DOP853 at rtol 1e-12 and 1e-13, compared within the
/// reference's horizon; every disagreement is pushed to `failures`.
fn compare_expm_dop853(name: &str, model: &Model, n: usize, failures: &mut Vec<String>) {
    let t0 = std::time::Instant::now();
    let a = solve(model, RATE, n);
    let ta = t0.elapsed().as_secs_f64();
    let hz = horizon(&a, &solve(&model.perturbed(1e-9), RATE, n), 1e-7);
    let w = hz + 1;
    let t_max = hz as f64 / RATE;
    let within = |s: &Solution| s.contacts.iter().filter(|c| c.start_s <= t_max).count();
    let mut dts = [0.0; 2];
    for (r, rtol) in [1e-12, 1e-13].into_iter().enumerate() {
        let t0 = std::time::Instant::now();
        let b = dop853::solve(model, RATE, n, rtol);
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
        masses: vec![],
        links: vec![],
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

/// A point mass at `x` moving at `v`, no gravity.
fn free_mass(m: f64, x: f64, v: f64) -> Hammer {
    Hammer {
        mass_kg: m,
        height_m: x,
        velocity_m_per_s: v,
        gravity_m_per_s2: 0.0,
    }
}

/// A scene without an object (the hammer's contact is the rigid wall at 0)
/// whose hammer is `hammer`, with the contact law `contact` for every
/// contact.
fn bare(hammer: Hammer, contact: Contact) -> Model {
    Model {
        modes: Vec::new(),
        hammer,
        contact,
        back: None,
        extra: Vec::new(),
        masses: vec![],
        links: vec![],
    }
}

/// The contact law of frequency `ratio` x Nyquist and damping ratio `zeta`
/// on a link of inverse mass `inv_m` (`omega^2 = k inv_m`).
fn law(inv_m: f64, ratio: f64, zeta: f64) -> Contact {
    let w = 2.0 * PI * ratio * NYQUIST;
    let k = w * w / inv_m;
    Contact {
        stiffness_n_per_m: k,
        damping_n_s_per_m: 2.0 * zeta * (k / inv_m).sqrt(),
    }
}

/// Two equal free point masses through an undamped link (no gravity): the
/// lower one `A` moving up at 1 m/s, the upper one `B` at rest 0.1 mm
/// above, the link's gap `-2e-5` (`A`'s thickness: its height is its bottom
/// face, so contact starts 80 us in). The relative motion is a hammer of
/// the reduced mass `m / 2` on a wall: the contact lasts `pi / sqrt(2 k /
/// m)`, after which the velocities are exchanged (`A` stops, `B` leaves at 1
/// m/s), and the total momentum `m (v_A + v_B)` is kept at every sample,
/// in contact too. Once with `A` the hammer itself and `B` a mass, once
/// with both masses behind a parked extra hammer (mass numbers 2 and 3,
/// the link contact 2): the state layout and the link's indices.
///
/// Tolerances: instants 1e-9 relative (located to a time unit, 1e-15 of a
/// sample; measured <= 6e-15), velocities and momentum 1e-12 of the 1 m/s
/// (measured <= 2e-16: the exact states are double-double and the
/// positions only cancel in `p`), energy 1e-12 (measured <= 3e-15). A wrong sign on a side or
/// the gap, a force on the wrong mass or a mass at the wrong place in `z`
/// misses by orders.
#[test]
fn two_masses_exchange_their_velocities_through_a_link() {
    use crate::{End, ExtraHammer, Link};
    let m = 0.02;
    let (x_a, x_b, gap) = (1e-3, 1.1e-3, -2e-5);
    let t_in = (x_b - x_a + gap) / 1.0;
    let mut worst: f64 = 0.0;
    let mut in_contact = 0;
    for ratio in [0.03, 0.3, 3.7, 317.3] {
        let contact = law(2.0 / m, ratio, 0.0);
        let dur = PI / (2.0 * contact.stiffness_n_per_m / m).sqrt();
        for parked in [false, true] {
            let (model, c) = if parked {
                // hammer and an extra hammer parked (at rest, above the
                // wall at 0, never touching it)
                let mut mdl = bare(free_mass(0.1, 1.0, 0.0), contact);
                mdl.extra.push(ExtraHammer {
                    hammer: free_mass(0.3, 2.0, 0.0),
                    weights: vec![],
                    contact,
                });
                mdl.masses = vec![free_mass(m, x_a, 1.0), free_mass(m, x_b, 0.0)];
                mdl.links.push(Link {
                    lower: End::Mass(2),
                    upper: End::Mass(3),
                    gap_m: gap,
                    contact,
                });
                (mdl, 2)
            } else {
                let mut mdl = bare(free_mass(m, x_a, 1.0), contact);
                mdl.masses = vec![free_mass(m, x_b, 0.0)];
                mdl.links.push(Link {
                    lower: End::Mass(0),
                    upper: End::Mass(1),
                    gap_m: gap,
                    contact,
                });
                (mdl, 1)
            };
            let n = ((t_in + dur) * RATE).ceil() as usize + 3;
            let sol = solve(&model, RATE, n);
            assert_eq!(sol.contacts.len(), 1, "ratio {ratio}: {:?}", sol.contacts);
            let ci = sol.contacts[0];
            assert_eq!(ci.contact, c);
            let end = ci.end_s.expect("contact ended");
            let err_start = (ci.start_s - t_in).abs() / t_in;
            let err_dur = ((end - ci.start_s) - dur).abs() / dur;
            // link columns: upper (B) height and velocity, lower (A)
            let v = |s: &crate::Sample| (s.extra[c - 1][3], s.extra[c - 1][1]);
            let (v_a, v_b) = v(&sol.samples[n]);
            let err_v = (v_a.abs()).max((v_b - 1.0).abs());
            let mut err_p: f64 = 0.0;
            let mut err_e: f64 = 0.0;
            let e0 = sol.samples[0].energy;
            for s in &sol.samples {
                let (va, vb) = v(s);
                err_p = err_p.max((m * va + m * vb - m).abs() / m);
                err_e = err_e.max((s.energy - e0).abs() / e0);
                in_contact += (s.active & (1 << c) != 0) as usize;
            }
            println!(
                "two masses, link at {ratio:6.2}x Nyquist{}: contact {:.2e} samples; start {err_start:.1e}, \
                 duration {err_dur:.1e}, velocities {err_v:.1e}, momentum {err_p:.1e}, energy {err_e:.1e}",
                if parked { " (parked hammers)" } else { "" },
                dur * RATE
            );
            for (what, err, tol) in [
                ("start", err_start, 1e-9),
                ("duration", err_dur, 1e-9),
                ("velocities", err_v, 1e-12),
                ("momentum", err_p, 1e-12),
                ("energy", err_e, 1e-12),
            ] {
                assert!(
                    err < tol,
                    "ratio {ratio} parked {parked}: {what} off by {err:e}"
                );
                worst = worst.max(err);
            }
            if parked {
                // the parked hammer stays where it is
                assert_eq!(sol.samples[n].x_hammer, model.hammer.height_m);
            }
        }
    }
    println!("two masses: worst {worst:.1e}, {in_contact} samples in contact");
    assert!(in_contact > 10, "{in_contact} samples in contact");
}

/// A hammer on a rigid wall through a link ([`crate::End::Wall`] at 5 cm,
/// gap 3e-5 m: the face touches at `x_h = 0.05 - 3e-5`), and a mass under a
/// ceiling (lower side the mass, upper side a wall at 0.2 m, gap `-2e-5`)
/// while the hammer is parked: both are a mass on a wall, `m p'' = -k p -
/// c p'`, so the contact lasts `pi / w_d` (`w_0 = sqrt(k / m)`, `zeta = c /
/// (2 sqrt(k m))`, `w_d = w_0 sqrt(1 - zeta^2)`) and the mass leaves at
/// `exp(-zeta pi / sqrt(1 - zeta^2))` of its impact speed (1 m/s, the
/// contact starting 0.1 ms in). Same tolerances as
/// [`rigid_wall_closed_forms`] (1e-10 relative; measured <= 3e-12, the
/// start's error being the rounding of the initial heights): the walls'
/// heights and the gaps are in the phase matrices' constant column and in
/// the event rows' constant, both double-double. DOP853 too (up to 31.9x
/// Nyquist, rtol 1e-13) within 1e-8: its error control is relative to the
/// heights (5 and 20 cm), ~2e-8 of the compression at 31.9x (measured <=
/// 9e-10).
#[test]
fn link_to_a_wall_closed_forms() {
    use crate::{End, Link};
    let m = 0.02;
    let t_in = 1e-4;
    let (mut worst, mut worst_dop): (f64, f64) = (0.0, 0.0);
    for zeta in [0.0, 0.1, 0.7] {
        for ratio in [1.0, 31.9, 1000.0] {
            let contact = law(1.0 / m, ratio, zeta);
            let w0 = 2.0 * PI * ratio * NYQUIST;
            let wd = w0 * (1.0 - zeta * zeta).sqrt();
            let dur = PI / wd;
            let e = (-zeta * PI / (1.0 - zeta * zeta).sqrt()).exp();
            let n = ((t_in + dur) * RATE).ceil() as usize + 2;
            for ceiling in [false, true] {
                let (h, gap) = if ceiling { (0.2, -2e-5) } else { (0.05, 3e-5) };
                let model = if ceiling {
                    let mut mdl = bare(free_mass(0.1, 1.0, 0.0), contact);
                    mdl.masses = vec![free_mass(m, h + gap - t_in, 1.0)];
                    mdl.links.push(Link {
                        lower: End::Mass(1),
                        upper: End::Wall(h),
                        gap_m: gap,
                        contact,
                    });
                    mdl
                } else {
                    let mut mdl = bare(free_mass(m, h - gap + t_in, -1.0), contact);
                    mdl.links.push(Link {
                        lower: End::Wall(h),
                        upper: End::Mass(0),
                        gap_m: gap,
                        contact,
                    });
                    mdl
                };
                let mut runs = vec![("expm", solve(&model, RATE, n))];
                if ratio < 100.0 {
                    runs.push(("dop853", dop853::solve(&model, RATE, n, 1e-13)));
                }
                for (solver, sol) in runs {
                    assert_eq!(sol.contacts.len(), 1, "{:?}", sol.contacts);
                    let c = sol.contacts[0];
                    assert_eq!(c.contact, 1);
                    let end = c.end_s.expect("contact ended");
                    let err_start = (c.start_s - t_in).abs() / t_in;
                    let err_dur = ((end - c.start_s) - dur).abs() / dur;
                    let last = &sol.samples[n];
                    // the mass leaves the wall: up from the floor, down from the
                    // ceiling (the link's columns: upper side, then lower side)
                    let v_out = if ceiling {
                        -last.extra[0][3]
                    } else {
                        last.v_hammer
                    };
                    let err_e = (v_out - e).abs() / e;
                    // the wall side is observed at its height, at rest
                    let wall = if ceiling {
                        [last.extra[0][0], last.extra[0][1]]
                    } else {
                        [last.extra[0][2], last.extra[0][3]]
                    };
                    assert_eq!(wall, [h, 0.0]);
                    let e0 = sol.samples[0].energy;
                    let err_energy = if zeta == 0.0 {
                        (last.energy - e0).abs() / (0.5 * m)
                    } else {
                        0.0
                    };
                    println!(
                    "link to a {} zeta {zeta:3} f_c {ratio:6.1}x Nyquist, {solver:<6}: start {err_start:.1e}, duration {err_dur:.1e}, \
                     restitution {err_e:.1e}, energy {err_energy:.1e}",
                    if ceiling { "ceiling" } else { "floor  " }
                );
                    let tol = if solver == "expm" { 1e-10 } else { 1e-8 };
                    for (what, err) in [
                        ("start", err_start),
                        ("duration", err_dur),
                        ("restitution", err_e),
                        ("energy", err_energy),
                    ] {
                        assert!(
                        err < tol,
                        "{solver}: ceiling {ceiling} zeta {zeta} ratio {ratio}: {what} off by {err:e}"
                    );
                        if solver == "expm" {
                            worst = worst.max(err);
                        } else {
                            worst_dop = worst_dop.max(err);
                        }
                    }
                }
            }
        }
    }
    println!("link to a wall: worst relative error {worst:.1e} (expm), {worst_dop:.1e} (DOP853)");
}

/// Every trace of a [`Solution`] the link tests compare: the first
/// contact's three columns and the second contact's four.
fn link_traces(s: &Solution, w: usize) -> Vec<(&'static str, Vec<f64>)> {
    let col = |f: &dyn Fn(&crate::Sample) -> f64| s.samples[..w].iter().map(f).collect();
    vec![
        ("x_h", s.x_hammer()[..w].to_vec()),
        ("v_h", s.v_hammer()[..w].to_vec()),
        ("x_c", s.x_contact()[..w].to_vec()),
        ("link upper x", col(&|x| x.extra[0][0])),
        ("link upper v", col(&|x| x.extra[0][1])),
        ("link lower x", col(&|x| x.extra[0][2])),
        ("link lower v", col(&|x| x.extra[0][3])),
    ]
}

/// The expm reference against DOP853 on a scene with a link, as
/// [`expm_matches_dop853`] compares them: on the predictability horizon
/// (now over the link's columns too), 1e-8 relative L2 on every trace and
/// 1e-6 samples on every contact instant at rtol 1e-13, DOP853's instants
/// converging with its tolerance where they differ by more than 1e-8
/// samples, a horizon of at least 50 samples holding contacts of both
/// kinds. Returns the failures.
fn link_expm_vs_dop853(name: &str, model: &Model, n: usize) -> Vec<String> {
    let mut failures = Vec::new();
    let a = solve(model, RATE, n);
    let hz = horizon(&a, &solve(&model.perturbed(1e-9), RATE, n), 1e-7);
    let w = hz + 1;
    let t_max = hz as f64 / RATE;
    let per = |s: &Solution, c: usize| {
        s.contacts
            .iter()
            .filter(|x| x.contact == c && x.start_s <= t_max)
            .count()
    };
    let mut dts = [0.0; 2];
    for (r, rtol) in [1e-12, 1e-13].into_iter().enumerate() {
        let b = dop853::solve(model, RATE, n, rtol);
        let (ta, tb) = (link_traces(&a, w), link_traces(&b, w));
        let errs: Vec<(&str, f64)> = ta
            .iter()
            .zip(&tb)
            .map(|((what, x), (_, y))| (*what, rel_l2(x, y)))
            .collect();
        let dt = max_dt(&a, &b, t_max);
        println!(
            "{name:<34} rtol {rtol:.0e}: horizon {hz:>4}, contacts {}+{} / {}+{} in it ({} in all), {}, max dt {} samples",
            per(&a, 0),
            per(&a, 1),
            per(&b, 0),
            per(&b, 1),
            a.contacts.len(),
            errs.iter()
                .map(|(w, e)| format!("{w} {e:.1e}"))
                .collect::<Vec<_>>()
                .join(", "),
            dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
        );
        let Some(dt) = dt else {
            failures.push(format!("{name}, rtol {rtol:e}: contact counts differ"));
            continue;
        };
        dts[r] = dt;
        if rtol == 1e-13 {
            for (what, e) in errs {
                if !(e < 1e-8) {
                    failures.push(format!("{name}: {what} disagree by {e:e}"));
                }
            }
            if !(dt < 1e-6) {
                failures.push(format!("{name}: contact instants {dt:e} samples"));
            }
        }
    }
    if dts[1] > 1e-8 && !(dts[0] > 2.0 * dts[1]) {
        failures.push(format!(
            "{name}: contact instants do not converge with DOP853's tolerance: {:e} vs {:e} samples",
            dts[0], dts[1]
        ));
    }
    if hz < 50 || per(&a, 0) == 0 || per(&a, 1) == 0 {
        failures.push(format!(
            "{name}: horizon {hz}, contacts {} + {} in it",
            per(&a, 0),
            per(&a, 1)
        ));
    }
    failures
}

/// Two objects touching through a link: the hammer strikes object `A` (one
/// mode, 150 Hz), whose point facing object `B` (one mode, 230 Hz, `1e-4`
/// m above it at rest) moves up when it is struck (a weight of the other
/// sign), and knocks `B` (an object-object contact, every contact damped:
/// the modes, the hammer's contact at zeta 0.1, the link at 0.2). The modes
/// of the two objects are concatenated: the hammer's point and `A`'s point
/// weigh 0 on `B`'s mode, `B`'s point 0 on `A`'s. The expm reference
/// against DOP853 (whose right-hand side takes the link's force from its
/// two sides) as in [`expm_matches_dop853`]; the same with the link
/// stiffer than Nyquist and the hammer's contact softer (measured at rtol
/// 1e-13: traces <= 6e-12, instants <= 4e-11 samples).
#[test]
fn object_object_link_expm_matches_dop853() {
    use crate::{End, Link};
    let scene = |r_hammer: f64, r_link: f64| {
        let modes = vec![
            Mode {
                freq_hz: 150.0,
                t60_s: Some(0.5),
                weight: 2.0,
            },
            Mode {
                freq_hz: 230.0,
                t60_s: Some(0.4),
                weight: 0.0,
            },
        ];
        let (w_a, w_b) = (-1.5, 1.5);
        Model {
            modes,
            hammer: Hammer {
                mass_kg: 0.05,
                height_m: 1e-4,
                velocity_m_per_s: -2.0,
                gravity_m_per_s2: 0.0,
            },
            contact: law(1.0 / 0.05 + 4.0, r_hammer, 0.1),
            back: None,
            extra: Vec::new(),
            masses: vec![],
            links: vec![Link {
                lower: End::Point(vec![w_a, 0.0]),
                upper: End::Point(vec![0.0, w_b]),
                gap_m: 1e-4,
                contact: law(w_a * w_a + w_b * w_b, r_link, 0.2),
            }],
        }
    };
    let mut failures = Vec::new();
    for (name, model) in [
        ("object-object, link 1.3x", scene(0.5, 1.3)),
        ("object-object, link 3.1x", scene(0.2, 3.1)),
    ] {
        failures.extend(link_expm_vs_dop853(name, &model, 2205));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A ball between two plates: the hammer (10 g) thrown up at 0.5 m/s from
/// 0.5 mm above the lower plate's point (the main contact, two modes),
/// under gravity, hits the upper plate's point (a link: lower side the
/// hammer, upper side the upper plate's point, two modes of their own, gap
/// 1 mm) and rattles between them. Everything is damped: the energy
/// ([`Model::energy_of`]: both plates, the ball's kinetic and gravitational
/// energy, both springs) never rises from one sample to the next by more
/// than rounding (1e-12 of the initial energy; measured <= 1e-15), and the
/// expm reference agrees with DOP853 as in [`expm_matches_dop853`].
#[test]
fn ball_between_two_plates() {
    use crate::{End, Link};
    let plates = |zeta: f64| {
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
                freq_hz: 523.0,
                t60_s: Some(0.5),
                weight: 0.0,
            },
            Mode {
                freq_hz: 2100.0,
                t60_s: Some(0.2),
                weight: 0.0,
            },
        ];
        let upper = vec![0.0, 0.0, 1.8, 1.1];
        let m = 0.01;
        let inv_upper: f64 = upper.iter().map(|w| w * w).sum();
        Model {
            modes,
            hammer: Hammer {
                mass_kg: m,
                height_m: 5e-4,
                velocity_m_per_s: 0.5,
                gravity_m_per_s2: 9.81,
            },
            contact: law(1.0 / m + 4.0 + 2.25, 0.8, zeta),
            back: None,
            extra: Vec::new(),
            masses: vec![],
            links: vec![Link {
                lower: End::Mass(0),
                upper: End::Point(upper),
                gap_m: 1e-3,
                contact: law(1.0 / m + inv_upper, 1.1, 2.0 * zeta),
            }],
        }
    };
    let mut failures = Vec::new();
    for (name, model) in [
        ("ball between plates, zeta 0.1", plates(0.1)),
        ("ball between plates, zeta 0.5", plates(0.5)),
    ] {
        let n = 2205;
        let a = solve(&model, RATE, n);
        let e0 = a.samples[0].energy;
        let rise = a
            .samples
            .windows(2)
            .map(|p| (p[1].energy - p[0].energy) / e0)
            .fold(f64::NEG_INFINITY, f64::max);
        let per = |c: usize| a.contacts.iter().filter(|x| x.contact == c).count();
        println!(
            "{name:<34} contacts {} (lower) + {} (upper) in 50 ms, energy {:.2e} -> {:.2e} J, largest rise {rise:.1e} of E0",
            per(0),
            per(1),
            e0,
            a.samples[n].energy
        );
        if !(rise < 1e-12) {
            failures.push(format!("{name}: energy rose by {rise:e} of E0"));
        }
        if per(0) < 2 || per(1) < 2 {
            failures.push(format!("{name}: contacts {} + {}", per(0), per(1)));
        }
        failures.extend(link_expm_vs_dop853(name, &model, n));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A link that restates the hammer's own contact (lower side its contact
/// point, upper side a mass in the hammer's place, no gap) is that contact:
/// with the hammer parked out of reach, the mass moves as the hammer of the
/// plain run, to rounding (the phase matrices differ by the parked
/// hammer's rows, so their sub-steps may too: same tolerances as
/// [`reference_does_not_depend_on_its_substeps`], 1e-9 relative L2 and 1e-8
/// samples; measured: 0, bit for bit). Non-chaotic cases, as there.
#[test]
fn a_link_restating_the_hammers_contact_is_that_contact() {
    use crate::{End, Link};
    let cases = [
        ("soft strike", object(0.01, 2e-4, -1.0, 0.0, 0.45, 0.1)),
        (
            "damped bounce, 31.3x",
            object(0.001, 1e-3, 0.0, 9.81, 31.3, 0.3),
        ),
    ];
    let n = 2205;
    for (name, plain) in cases {
        let mut linked = plain.clone();
        linked.hammer = free_mass(1.0, 1.0, 0.0);
        linked.masses = vec![plain.hammer];
        linked.links.push(Link {
            lower: End::Point(plain.modes.iter().map(|m| m.weight).collect()),
            upper: End::Mass(1),
            gap_m: 0.0,
            contact: plain.contact,
        });
        let a = solve(&plain, RATE, n);
        let b = solve(&linked, RATE, n);
        let col = |s: &Solution, f: &dyn Fn(&crate::Sample) -> f64| {
            s.samples.iter().map(f).collect::<Vec<f64>>()
        };
        let errs = [
            rel_l2(&col(&b, &|x| x.extra[0][0]), &a.x_hammer()),
            rel_l2(&col(&b, &|x| x.extra[0][1]), &a.v_hammer()),
            rel_l2(&col(&b, &|x| x.extra[0][2]), &a.x_contact()),
            rel_l2(&col(&b, &|x| x.x_contact), &a.x_contact()),
        ];
        // the same intervals, numbered as the link
        assert!(b.contacts.iter().all(|c| c.contact == 1));
        let mut dt: f64 = 0.0;
        assert_eq!(a.contacts.len(), b.contacts.len(), "{name}");
        for (x, y) in a.contacts.iter().zip(&b.contacts) {
            dt = dt.max((x.start_s - y.start_s).abs());
            if let (Some(ex), Some(ey)) = (x.end_s, y.end_s) {
                dt = dt.max((ex - ey).abs());
            }
        }
        println!(
            "{name:<22} as a link: contacts {}, traces {:.1e}, instants {:.1e} samples",
            a.contacts.len(),
            errs.iter().fold(0.0f64, |m, e| m.max(*e)),
            dt * RATE
        );
        assert!(!a.contacts.is_empty());
        for e in errs {
            assert!(e < 1e-9, "{name}: {errs:?}");
        }
        assert!(dt * RATE < 1e-8, "{name}: instants {dt:e} s");
    }
}

/// Heights `f(t)` of a surface at the `n + 1` sample instants of `n`
/// samples.
fn surface(n: usize, f: impl Fn(f64) -> f64) -> Vec<f64> {
    (0..=n).map(|i| f(i as f64 / RATE)).collect()
}

/// Every number of two solutions (samples and contact instants) the same
/// bit for bit: their shortest round-trip spellings, `-0` apart from `0`.
fn same_bits(a: &Solution, b: &Solution) -> bool {
    format!("{:?}", a.samples) == format!("{:?}", b.samples)
        && format!("{:?}", a.contacts) == format!("{:?}", b.contacts)
}

/// A surface of zeros is no surface: the same run bit for bit, by both
/// solvers, as without one (the expm solver takes a sample where the
/// surface rests at 0 with the phases without the surface, whose equations
/// it reduces to; DOP853 integrates `s = 0` through its surface terms, and
/// the impulse it carries is outside its error control).
///
/// The surface's own phases are checked where the surface rests at a
/// height `c != 0` over the whole run: that is the plain run with the
/// hammer `c` lower (the penetration `x_c + c - x_h` of a hammer at `x_h`
/// is that of one at `x_h - c`), heights shifted by `c`, the energy by `m g
/// c`, no work. Non-chaotic cases (as [`reference_does_not_depend_on_its_substeps`]),
/// tolerances as there: 1e-9 relative L2 and 1e-8 samples (measured <=
/// 1.2e-13 and 9e-11 samples); DOP853 on the soft strike within 1e-9 and
/// 1e-7 samples of its own plain run (measured <= 9e-15 and 5e-15 samples;
/// at 31.3x Nyquist its error control, relative to heights that the shift
/// changes, moves the instants by 3e-4 samples).
#[test]
fn a_surface_at_rest_is_no_surface() {
    let cases = [
        ("soft strike", object(0.01, 2e-4, -1.0, 0.0, 0.45, 0.1)),
        (
            "damped bounce, 31.3x",
            object(0.001, 1e-3, 0.0, 9.81, 31.3, 0.3),
        ),
        ("critical rattle", object(0.01, 1e-3, 0.0, 9.81, 3.1, 1.0)),
        ("wall, 31.9x", wall(0.02, 31.9, 0.1)),
    ];
    let n = 2205;
    let zeros = vec![0.0; n + 1];
    for (name, model) in &cases {
        let a = solve(model, RATE, n);
        let b = crate::solve_on_surface(model, &zeros, RATE, n);
        let da = dop853::solve(model, RATE, n, 1e-12);
        let db = dop853::solve_on_surface(model, &zeros, RATE, n, 1e-12);
        println!(
            "{name:<22} on a surface of zeros: expm bit for bit {}, DOP853 bit for bit {} ({} contacts)",
            same_bits(&a, &b),
            same_bits(&da, &db),
            a.contacts.len()
        );
        assert!(same_bits(&a, &b), "{name}: expm differs on a zero surface");
        assert!(
            same_bits(&da, &db),
            "{name}: DOP853 differs on a zero surface"
        );
    }
    let c = 1.7e-4;
    for (name, model) in &cases[..2] {
        let mut lower = model.clone();
        lower.hammer.height_m -= c;
        let flat = vec![c; n + 1];
        let (plain, on) = (
            solve(&lower, RATE, n),
            crate::solve_on_surface(model, &flat, RATE, n),
        );
        surface_at_rest_case(name, "expm", model, c, &plain, &on);
        if name.starts_with("soft") {
            let (plain, on) = (
                dop853::solve(&lower, RATE, n, 1e-13),
                dop853::solve_on_surface(model, &flat, RATE, n, 1e-13),
            );
            surface_at_rest_case(name, "dop853", model, c, &plain, &on);
        }
    }
}

/// One case of [`a_surface_at_rest_is_no_surface`]: the run `on` a surface
/// resting at `c` against the `plain` run of the hammer `c` lower.
fn surface_at_rest_case(
    name: &str,
    solver: &str,
    model: &Model,
    c: f64,
    plain: &Solution,
    on: &Solution,
) {
    let shifted: Vec<f64> = on.x_hammer().iter().map(|x| x - c).collect();
    let mg = model.hammer.mass_kg * model.hammer.gravity_m_per_s2;
    let e_on: Vec<f64> = on.samples.iter().map(|s| s.energy - mg * c).collect();
    let e_plain: Vec<f64> = plain.samples.iter().map(|s| s.energy).collect();
    let errs = [
        rel_l2(&shifted, &plain.x_hammer()),
        rel_l2(&on.v_hammer(), &plain.v_hammer()),
        rel_l2(&on.x_contact(), &plain.x_contact()),
        rel_l2(&e_on, &e_plain),
    ];
    let work = on
        .samples
        .iter()
        .map(|s| s.surface_work_j.abs())
        .fold(0.0, f64::max);
    let dt = max_dt(on, plain, f64::INFINITY);
    println!(
        "{name:<22} {solver:<6} on a surface at rest at {c:e} m vs the hammer {c:e} m lower: \
         x_h {:.1e}  v_h {:.1e}  x_c {:.1e}  energy {:.1e}  instants {} samples, work {work:e} J",
        errs[0],
        errs[1],
        errs[2],
        errs[3],
        dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
    );
    let dt_tol = if solver == "expm" { 1e-8 } else { 1e-7 };
    assert!(errs.iter().all(|e| *e < 1e-9), "{name} {solver}: {errs:?}");
    assert!(
        dt.is_some_and(|d| d < dt_tol),
        "{name} {solver}: instants {dt:?}"
    );
    assert_eq!(work, 0.0, "{name} {solver}: work of a surface at rest");
    assert!(on.samples.iter().all(|s| s.surface_m == c));
}

/// A hammer of mass `m` on a rigid wall through the contact `k, c`, under
/// gravity `g`, in contact all along: the closed form of its motion on a
/// moving surface.
struct WallOnSurface {
    m: f64,
    k: f64,
    c: f64,
    g: f64,
}

impl WallOnSurface {
    /// The exact motion over one sample of length `h` on a surface moving
    /// from `s0` at the rate `v`, from `(x, x')`. The equation `m x'' = -m
    /// g + k (s - x) + c (v - x')` with `s = s0 + v t` has the particular
    /// solution `s - m g / k` (then `x' = v` and the spring holds the
    /// weight), plus the damped oscillation `y` of `m y'' + c y' + k y = 0`
    /// from `y(0) = x - s0 + m g / k`, `y'(0) = x' - v`: underdamped, `y =
    /// e^{-a t} (y0 cos(w_d t) + (y0' + a y0) / w_d sin(w_d t))` with `a =
    /// c / 2m`, `w_d = sqrt(k / m - a^2)`. Returns `(x, x')` at the
    /// sample's end.
    fn step(&self, s0: f64, v: f64, (x, u): (f64, f64), h: f64) -> (f64, f64) {
        let Self { m, k, c, g } = *self;
        let a = c / (2.0 * m);
        let w2 = k / m;
        let wd = (w2 - a * a).sqrt();
        let sag = m * g / k;
        let (y0, dy0) = (x - s0 + sag, u - v);
        let (sn, cs) = (wd * h).sin_cos();
        let e = (-a * h).exp();
        let y = e * (y0 * cs + (dy0 + a * y0) / wd * sn);
        let dy = e * (dy0 * cs - (a * dy0 + w2 * y0) / wd * sn);
        (s0 + v * h - sag + y, v + dy)
    }
}

/// A hammer resting under gravity on a rigid wall at its static
/// equilibrium (`x = -m g / k`), contact at 0.07x Nyquist with damping
/// ratio 0.3, carried by the surface: a ramp at 0.2 mm/s for 1000 samples,
/// then a 50 Hz sinusoid of 20 um starting at rest (2 m/s^2 at most: the
/// hammer never lifts off), 4410 samples in all. The reference against the closed form of
/// [`WallOnSurface::step`] chained sample by sample from the same surface
/// heights, relative to the largest value of each trace: height, velocity,
/// and the compression `s - x` (a small difference, ~1e-7 m under
/// heights ~1e-4 m).
///
/// Tolerance 1e-12 (measured: height 3e-16, velocity 2e-14, compression
/// 1e-13): the closed form itself is f64 over 4410 chained samples. A surface rate off by one sample, a
/// missing `c v` in the force or `s` missing from the penetration misses by
/// orders (the ramp's `c v` alone moves the compression by `c v / k`, a
/// tenth of it).
#[test]
fn hammer_carried_by_a_surface_on_a_wall_closed_form() {
    let m = 0.02;
    let (ratio, zeta, g) = (0.07, 0.3, 9.81);
    let w0 = 2.0 * PI * ratio * NYQUIST;
    let k = m * w0 * w0;
    let c = 2.0 * zeta * m * w0;
    let n = 4410;
    let (n_ramp, v_ramp, amp, f) = (1000, 2e-4, 2e-5, 50.0);
    let t_ramp = n_ramp as f64 / RATE;
    let heights = surface(n, |t| {
        if t <= t_ramp {
            v_ramp * t
        } else {
            v_ramp * t_ramp + amp * (1.0 - (2.0 * PI * f * (t - t_ramp)).cos())
        }
    });
    let mut model = wall(m, ratio, zeta);
    model.hammer.height_m = -m * g / k;
    model.hammer.velocity_m_per_s = 0.0;
    model.hammer.gravity_m_per_s2 = g;
    let sol = crate::solve_on_surface(&model, &heights, RATE, n);
    let exact = WallOnSurface { m, k, c, g };
    let h = 1.0 / RATE;
    let mut x = (model.hammer.height_m, 0.0);
    let mut traces = [
        (vec![x.0], vec![]),
        (vec![x.1], vec![]),
        (vec![0.0], vec![]),
    ];
    traces[2].0[0] = heights[0] - x.0;
    for i in 0..n {
        x = exact.step(heights[i], (heights[i + 1] - heights[i]) / h, x, h);
        traces[0].0.push(x.0);
        traces[1].0.push(x.1);
        traces[2].0.push(heights[i + 1] - x.0);
    }
    for s in &sol.samples {
        traces[0].1.push(s.x_hammer);
        traces[1].1.push(s.v_hammer);
        traces[2].1.push(s.surface_m - s.x_hammer);
    }
    let mut errs = [0.0; 3];
    for (e, (ex, re)) in errs.iter_mut().zip(&traces) {
        let scale = ex.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        *e = ex
            .iter()
            .zip(re)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale;
    }
    let min_p = traces[2].1.iter().fold(f64::INFINITY, |a, p| a.min(*p));
    println!(
        "hammer carried by a surface on a wall: {} contact(s), smallest compression {min_p:.2e} m (m g / k {:.2e}); \
         max error / max value: height {:.1e}, velocity {:.1e}, compression {:.1e}",
        sol.contacts.len(),
        m * g / k,
        errs[0],
        errs[1],
        errs[2]
    );
    assert_eq!(sol.contacts.len(), 1, "{:?}", sol.contacts);
    assert!(sol.contacts[0].end_s.is_none() && min_p > 0.0);
    for (what, e) in ["height", "velocity", "compression"].iter().zip(errs) {
        assert!(e < 1e-12, "{what} off by {e:e} of its largest value");
    }
}

/// A 10 g ball under gravity set on the 4-mode object (contact at `ratio`
/// x Nyquist, damping ratio `zeta`) whose contact point rides on a surface
/// shaking at 600 Hz with 5 um (70 m/s^2, seven times gravity: the ball is
/// thrown off and lands again, over and over), `n` samples.
fn shaken_ball(ratio: f64, zeta: f64, n: usize) -> (Model, Vec<f64>) {
    let model = object(0.01, 0.0, 0.0, 9.81, ratio, zeta);
    let heights = surface(n, |t| 5e-6 * (2.0 * PI * 600.0 * t).sin());
    (model, heights)
}

/// The expm reference against DOP853 on a moving surface that throws the
/// ball off the object and catches it again (see [`shaken_ball`]; contact
/// at 0.45x and 3.1x Nyquist, damped and elastic), as
/// [`expm_matches_dop853`] compares them: on the predictability horizon of
/// a run disturbed by 1e-9 (on the same surface), 1e-8 relative L2 on the
/// hammer's height and velocity and the contact point's displacement, 1e-6
/// samples on the contact instants at rtol 1e-13, DOP853's instants
/// converging with its tolerance where they differ by more than 1e-8
/// samples, at least 50 samples and 4 contacts in the horizon; and the
/// surface's work by the two (each from its own impulse) within 1e-8 of the
/// largest work over the horizon. Measured at rtol 1e-13: horizons of 611
/// to 1792 samples holding 4 or 5 contacts, traces <= 8.5e-11, work <=
/// 7.3e-11, instants <= 5.8e-9 samples (about 8x less than at rtol 1e-12:
/// DOP853's error).
#[test]
fn shaken_ball_expm_matches_dop853() {
    let n = 2205;
    let mut failures = Vec::new();
    for (name, ratio, zeta) in [
        ("shaken ball, soft, damped", 0.45, 0.2),
        ("shaken ball, stiff, elastic", 3.1, 0.0),
        ("shaken ball, stiff, damped", 3.1, 0.3),
    ] {
        let (model, heights) = shaken_ball(ratio, zeta, n);
        let a = crate::solve_on_surface(&model, &heights, RATE, n);
        let p = crate::solve_on_surface(&model.perturbed(1e-9), &heights, RATE, n);
        let hz = horizon(&a, &p, 1e-7);
        let w = hz + 1;
        let t_max = hz as f64 / RATE;
        let within = |s: &Solution| s.contacts.iter().filter(|c| c.start_s <= t_max).count();
        let mut dts = [0.0; 2];
        for (r, rtol) in [1e-12, 1e-13].into_iter().enumerate() {
            let b = dop853::solve_on_surface(&model, &heights, RATE, n, rtol);
            let errs = [
                ("x_h", rel_l2(&a.x_hammer()[..w], &b.x_hammer()[..w])),
                ("v_h", rel_l2(&a.v_hammer()[..w], &b.v_hammer()[..w])),
                ("x_c", rel_l2(&a.x_contact()[..w], &b.x_contact()[..w])),
            ];
            let work = |s: &Solution| {
                s.samples[..w]
                    .iter()
                    .map(|x| x.surface_work_j)
                    .collect::<Vec<_>>()
            };
            let (wa, wb) = (work(&a), work(&b));
            let w_scale = wa.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let ew = wa
                .iter()
                .zip(&wb)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
                / w_scale;
            let dt = max_dt(&a, &b, t_max);
            println!(
                "{name:<28} rtol {rtol:.0e}: horizon {hz:>4}, contacts {}/{} in it ({} in all), {}, work {ew:.1e} (of {w_scale:.1e} J), max dt {} samples",
                within(&a),
                within(&b),
                a.contacts.len(),
                errs.map(|(w, e)| format!("{w} {e:.1e}")).join(", "),
                dt.map_or("n/a".into(), |d| format!("{d:.1e}")),
            );
            let Some(dt) = dt else {
                failures.push(format!("{name}, rtol {rtol:e}: contact counts differ"));
                continue;
            };
            dts[r] = dt;
            if rtol == 1e-13 {
                let checks = [
                    (errs[0].0, errs[0].1, 1e-8),
                    (errs[1].0, errs[1].1, 1e-8),
                    (errs[2].0, errs[2].1, 1e-8),
                    ("work", ew, 1e-8),
                    ("instants [samples]", dt, 1e-6),
                ];
                for (what, e, tol) in checks {
                    if !(e < tol) {
                        failures.push(format!("{name}: {what} disagree by {e:e} > {tol:e}"));
                    }
                }
            }
        }
        if dts[1] > 1e-8 && !(dts[0] > 2.0 * dts[1]) {
            failures.push(format!(
                "{name}: instants do not converge with DOP853's tolerance: {:e} vs {:e} samples",
                dts[0], dts[1]
            ));
        }
        if hz < 50 || within(&a) < 4 {
            failures.push(format!(
                "{name}: horizon {hz}, {} contacts in it",
                within(&a)
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The energy ledger on a moving surface: the energy ([`crate::Sample::energy`],
/// lab frame, the spring's `p` including the surface) changes by the
/// surface's work `W = integral of F v dt` and by what the dampers take. On
/// the shaken ball of [`shaken_ball`] with nothing damped (modes undamped,
/// elastic contact at 3.1x and 31.3x Nyquist): `E(t) - E(0) = W(t)` at
/// every sample, to 1e-10 of the largest `|W|` (measured <= 8e-16); with
/// the modes and the contact damped, `E - E(0) - W` never rises from one
/// sample to the next by more than 1e-12 of it (it falls at every sample:
/// the modes' decay never stops), and the dampers take most of the work.
/// Many lift-offs and landings in either (at least 10 contacts in 0.1 s).
#[test]
fn surface_work_balances_the_energy() {
    let n = 4410;
    let mut failures = Vec::new();
    for (name, ratio, zeta, lossless) in [
        ("lossless, 3.1x", 3.1, 0.0, true),
        ("lossless, 31.3x", 31.3, 0.0, true),
        ("damped, 3.1x", 3.1, 0.3, false),
        ("damped, 31.3x", 31.3, 0.3, false),
    ] {
        let (mut model, heights) = shaken_ball(ratio, zeta, n);
        if lossless {
            for m in &mut model.modes {
                m.t60_s = None;
            }
        }
        let sol = crate::solve_on_surface(&model, &heights, RATE, n);
        let e0 = sol.samples[0].energy;
        let ledger: Vec<f64> = sol
            .samples
            .iter()
            .map(|s| s.energy - e0 - s.surface_work_j)
            .collect();
        let scale = sol
            .samples
            .iter()
            .fold(0.0f64, |m, s| m.max(s.surface_work_j.abs()));
        let (what, err, tol) = if lossless {
            let off = ledger.iter().fold(0.0f64, |m, x| m.max(x.abs())) / scale;
            ("|E - E0 - W|", off, 1e-10)
        } else {
            let rise = ledger
                .windows(2)
                .map(|p| (p[1] - p[0]) / scale)
                .fold(f64::NEG_INFINITY, f64::max);
            ("largest rise of E - E0 - W", rise, 1e-12)
        };
        let lost = -ledger[n] / scale;
        println!(
            "{name:<16} {} contacts, largest |W| {scale:.2e} J, E0 {e0:.2e} J, lost at the end {lost:.1e} of it: {what} {err:.1e} of it",
            sol.contacts.len()
        );
        if !(err < tol) {
            failures.push(format!("{name}: {what} {err:e} > {tol:e}"));
        }
        if sol.contacts.len() < 10 {
            failures.push(format!("{name}: {} contacts", sol.contacts.len()));
        }
        if !lossless && !(lost > 1e-3) {
            failures.push(format!("{name}: the dampers took nothing ({lost:e})"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
