//! The stability table: every extreme case of NUMERICS.md section 4 through
//! both engine modes and every competitor at 1x and 8x.

use super::accuracy::fmt_opt;
use super::runs::{from_sim, rel_l2, run_engine, time_engine, TimingPlan, Trajectory};
use super::scenes::{c_for, k_for, modal_scene, wall_scene, ModalOpts, NYQ, RATE};
use anyhow::{anyhow, Result};
use modal_contact::compile::compile_with;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::competitors::{simulate, Method, PwlSystem};
use std::time::Instant;

/// Oversampling factors of the competitors in the stability table.
pub const STAB_OS: [usize; 2] = [1, 8];
/// Per-step energy increase (relative to E0) above which a run "gains energy".
pub const GAIN_TOL: f64 = 1e-9;
/// Final-energy deficit against the exact run (relative to E0) above which a
/// run "loses energy".
pub const LOSS_TOL: f64 = 1e-3;

/// One case.
pub struct StabCase {
    pub id: String,
    pub what: String,
    pub scene: Scene,
    pub samples: usize,
}

/// One cell of the table.
#[derive(Debug, Clone)]
pub struct Cell {
    pub label: String,
    pub text: String,
}

/// Results of one case.
pub struct StabResult {
    pub id: String,
    pub what: String,
    pub samples: usize,
    pub cells: Vec<Cell>,
    pub compile_s: f64,
    pub ref_contacts: usize,
    /// Exact switching diagnostics and its `tick` cost.
    pub engine_note: String,
}

/// Column labels, in table order.
pub fn labels() -> Vec<String> {
    let mut v = vec!["exact".to_string(), "offset-rod".to_string()];
    for m in Method::ALL {
        for os in STAB_OS {
            v.push(format!("{} x{os}", short(m)));
        }
    }
    v
}

fn short(m: Method) -> &'static str {
    match m {
        Method::SymplecticEuler => "SE",
        Method::StormerVerlet => "Verlet",
        Method::Rk4 => "RK4",
        Method::Trapezoid => "trap.",
    }
}

#[allow(clippy::too_many_arguments)]
fn modal(
    id: &str,
    what: &str,
    samples: usize,
    n: usize,
    f_lo: f64,
    f_hi: f64,
    damped: bool,
    m_h: f64,
    k: f64,
    c: f64,
    g: f64,
) -> Result<StabCase> {
    Ok(StabCase {
        id: id.into(),
        what: what.into(),
        samples,
        scene: modal_scene(
            id,
            ModalOpts {
                n,
                f_lo,
                f_hi,
                damped,
                m_h,
                k,
                c,
                g,
                height: 0.0,
            },
        )?,
    })
}

/// The cases (scene parameters as in tests/stability.rs).
pub fn cases() -> Result<Vec<StabCase>> {
    let mut v = Vec::new();
    let m_h = 0.02;
    for ratio in [1.0, 10.0, 100.0, 1000.0] {
        let k = k_for(m_h, ratio * NYQ);
        v.push(modal(
            &format!("X3 f_c = {ratio}x f_Nyq"),
            "20 modes 200 Hz..0.82 f_Nyq, m_h 0.02 kg, zeta_c 0.2, v0 1 m/s",
            20_000,
            20,
            200.0,
            0.82 * NYQ,
            true,
            m_h,
            k,
            c_for(m_h, k, 0.2),
            0.0,
        )?);
    }
    let m2 = 0.2;
    let k2 = k_for(m2, 0.45 * NYQ);
    v.push(modal(
        "X2 stiff, chattering",
        "f_c = 0.45 f_Nyq, zeta_c 0.3, m_h/m_k 0.2, 20 modes to 0.82 f_Nyq",
        20_000,
        20,
        200.0,
        0.82 * NYQ,
        true,
        m2,
        k2,
        c_for(m2, k2, 0.3),
        0.0,
    )?);
    v.push(modal(
        "X6 zero damping",
        "X2 with every damping 0 (modes and contact): energy must stay E0",
        20_000,
        20,
        200.0,
        0.82 * NYQ,
        false,
        m2,
        k2,
        0.0,
        0.0,
    )?);
    let (mw, kw) = (0.01, 1e6);
    v.push(StabCase {
        id: "X4 critical damping, wall".into(),
        what: "hammer vs rigid wall, zeta_c = 1 exactly (defective contact block)".into(),
        samples: 5000,
        scene: wall_scene(mw, kw, c_for(mw, kw, 1.0), 0.0, -1.0)?,
    });
    v.push(modal(
        "X4 critical damping, 1 mode",
        "one undamped 300 Hz mode, 10 g hammer, k 1e6, zeta_c = 1",
        20_000,
        1,
        300.0,
        300.0,
        false,
        mw,
        kw,
        c_for(mw, kw, 1.0),
        0.0,
    )?);
    for zeta in [10.0, 1e3] {
        v.push(modal(
            &format!("X5 overdamped zeta = {zeta}"),
            if zeta > 100.0 {
                "10 modes 200 Hz..5 kHz, m_h 0.02 kg, k 1e6 (shortened to 4410 samples when the exact engine cost ~0.8 ms per sample here; its cost now: the `tick` time that follows)"
            } else {
                "10 modes 200 Hz..5 kHz, m_h 0.02 kg, k 1e6"
            },
            if zeta > 100.0 { 4410 } else { 20_000 },
            10,
            200.0,
            5000.0,
            true,
            0.02,
            1e6,
            c_for(0.02, 1e6, zeta),
            0.0,
        )?);
    }
    v.push(modal(
        "X8 modes above Nyquist",
        "40 modes 150 Hz..2.7 f_Nyq, m_h 0.02 kg, k 1e6, c 5",
        20_000,
        40,
        150.0,
        2.7 * NYQ,
        true,
        0.02,
        1e6,
        5.0,
        0.0,
    )?);
    for ratio in [1e-6, 1e-3, 1.0, 1e3] {
        let k = k_for(ratio, 2000.0);
        v.push(modal(
            &format!("X7 m_h/m_k = {ratio:e}"),
            if ratio > 100.0 {
                "10 modes 200 Hz..8 kHz (mode 0: 1 kg), f_c 2 kHz, zeta_c 0.1 (shortened to 2000 samples when the exact engine cost ~7 ms per sample here; its cost now: the `tick` time that follows)"
            } else {
                "10 modes 200 Hz..8 kHz (mode 0: 1 kg), f_c 2 kHz, zeta_c 0.1"
            },
            if ratio > 100.0 { 2000 } else { 20_000 },
            10,
            200.0,
            8000.0,
            true,
            ratio,
            k,
            c_for(ratio, k, 0.1),
            0.0,
        )?);
    }
    for n in [1usize, 10, 100, 300] {
        let samples = if n >= 300 { 4410 } else { 10_000 };
        v.push(modal(
            &format!("X9 {n} modes"),
            "modes 100 Hz..18 kHz, m_h 0.03 kg, k 1e6, c 10 (capped at 300 modes: at 1000 the dense trapezoid competitor would dominate the runtime)",
            samples,
            n,
            100.0,
            18_000.0,
            true,
            0.03,
            1e6,
            10.0,
            0.0,
        )?);
    }
    let mut graze = modal(
        "X11 grazing v = 1e-9",
        "5 modes 300 Hz..5 kHz, impact speed 1e-9 m/s from 1e-12 m",
        20_000,
        5,
        300.0,
        5000.0,
        true,
        0.01,
        1e6,
        5.0,
        0.0,
    )?;
    graze.scene.hammer.velocity_m_per_s = -1e-9;
    graze.scene.hammer.height_m = 1e-12;
    v.push(graze);
    v.push(modal(
        "X12/X13 long contact",
        "50 g ball dropped from 1 cm (g = 9.81) on 3 modes 220..3500 Hz, k 2e5, c 5: bounces, then rests in continuous contact (3 s)",
        (3.0 * RATE) as usize,
        3,
        220.0,
        3500.0,
        true,
        0.05,
        2e5,
        5.0,
        9.81,
    )?);
    Ok(v)
}

fn first_nan(tr: &Trajectory) -> Option<usize> {
    tr.x_hammer.iter().position(|x| !x.is_finite())
}

fn cell(tr: &Trajectory, reference: Option<&Trajectory>, has_pickup: bool) -> String {
    if tr.diverged {
        return match first_nan(tr) {
            Some(i) => format!("**diverges** ({:.2} ms)", i as f64 / RATE * 1e3),
            None => "**diverges**".into(),
        };
    }
    let err = reference.and_then(|r| {
        if has_pickup {
            rel_l2(&tr.pickup, &r.pickup, r.pickup.len())
        } else {
            rel_l2(&tr.x_hammer, &r.x_hammer, r.x_hammer.len())
        }
    });
    let err_s = match reference {
        Some(_) => format!("; err {}", fmt_opt(err)),
        None => String::new(),
    };
    if tr.max_step_gain > GAIN_TOL {
        return format!("**gains energy** {:.1e}{err_s}", tr.max_step_gain);
    }
    let gain_s = if tr.max_step_gain > 0.0 {
        format!("gain {:.0e}", tr.max_step_gain)
    } else {
        "no gain".into()
    };
    if let Some(r) = reference {
        let d = (tr.e_end() - r.e_end()) / tr.e0;
        if d < -LOSS_TOL {
            return format!("loses energy ({d:+.1e} E0 at end; {gain_s}){err_s}");
        }
    }
    format!("ok ({gain_s}){err_s}")
}

/// Run one case.
pub fn run_case(case: &StabCase) -> Result<StabResult> {
    let t0 = Instant::now();
    let exact = compile_with(&case.scene, RATE, Some(Switching::Exact))
        .map_err(|e| anyhow!("{}: {e}", case.id))?;
    let compile_s = t0.elapsed().as_secs_f64();
    let mut rod = exact.clone();
    rod.switching = Switching::OffsetRod;
    let n = case.samples;
    let t1 = Instant::now();
    let reference = run_engine(&exact, n);
    if std::env::var_os("REPORT_DEBUG").is_some() {
        eprintln!(
            "    exact {:.2} s; {}",
            t1.elapsed().as_secs_f64(),
            reference.engine_note
        );
    }
    let has_pickup = reference.pickup.iter().any(|x| *x != 0.0);
    let n_t = n.min(500);
    let (t_tick, _) = time_engine(
        &exact,
        n_t,
        &TimingPlan {
            reps: 1,
            slow_s: 0.0,
        },
    );
    let engine_note = format!(
        "exact `tick` {:.2} us/sample (first {n_t} samples); {}",
        t_tick / n_t as f64 * 1e6,
        reference.engine_note
    );
    let mut cells = vec![Cell {
        label: "exact".into(),
        text: cell(&reference, None, has_pickup),
    }];
    let rod_tr = run_engine(&rod, n);
    cells.push(Cell {
        label: "offset-rod".into(),
        text: cell(&rod_tr, Some(&reference), has_pickup),
    });
    let sys = PwlSystem::from_scene(&case.scene).map_err(|e| anyhow!("{}: {e}", case.id))?;
    for m in Method::ALL {
        for os in STAB_OS {
            let t1 = Instant::now();
            let tr = from_sim(&sys, simulate(&sys, m, RATE, os, n));
            if std::env::var_os("REPORT_DEBUG").is_some() {
                eprintln!("    {} x{os} {:.2} s", m.name(), t1.elapsed().as_secs_f64());
            }
            cells.push(Cell {
                label: format!("{} x{os}", short(m)),
                text: cell(&tr, Some(&reference), has_pickup),
            });
        }
    }
    Ok(StabResult {
        id: case.id.clone(),
        what: case.what.clone(),
        samples: n,
        cells,
        compile_s,
        ref_contacts: reference.contacts.len(),
        engine_note,
    })
}

/// Markdown: one row per case, one column per method.
pub fn markdown(results: &[StabResult]) -> String {
    let labels = labels();
    let mut s = String::from("| case | samples | contacts (exact) |");
    for l in &labels {
        s += &format!(" {l} |");
    }
    s += "\n|---|---|---|";
    for _ in &labels {
        s += "---|";
    }
    s += "\n";
    for r in results {
        s += &format!("| {} | {} | {} |", r.id, r.samples, r.ref_contacts);
        for l in &labels {
            let t = r
                .cells
                .iter()
                .find(|c| &c.label == l)
                .map_or("-", |c| c.text.as_str());
            s += &format!(" {t} |");
        }
        s += "\n";
    }
    s += "\nCase parameters:\n\n";
    for r in results {
        s += &format!(
            "- **{}**: {}. Compile {:.2} s; {}\n",
            r.id, r.what, r.compile_s, r.engine_note
        );
    }
    s
}
