//! The stability table: every case of the catalogue
//! (`modal_testkit::stability`, docs/numerics.md's "The stability cases")
//! through both engine modes and every competitor at 1x and 8x.

use super::accuracy::fmt_opt;
use super::runs::{from_sim, run_engine, time_engine, TimingPlan, Trajectory};
use anyhow::{anyhow, Result};
use modal_contact::compile::compile_with;
use modal_contact::scene::Switching;
use modal_testkit::competitors::{simulate, Method, PwlSystem};
use modal_testkit::metrics::rel_l2_window;
use modal_testkit::scenes::RATE;
use modal_testkit::stability::Case;
use std::time::Instant;

/// Oversampling factors of the competitors in the stability table.
pub(crate) const STAB_OS: [usize; 2] = [1, 8];
/// Per-step energy increase (relative to E0) above which a run "gains energy".
pub(crate) const GAIN_TOL: f64 = 1e-9;
/// Final-energy deficit against the exact run (relative to E0) above which a
/// run "loses energy".
pub(crate) const LOSS_TOL: f64 = 1e-3;

/// One cell of the table.
#[derive(Debug, Clone)]
pub(crate) struct Cell {
    pub label: String,
    pub text: String,
}

/// Results of one case.
pub(crate) struct StabResult {
    /// The case's name and its numerics label.
    pub name: String,
    pub label: String,
    pub what: String,
    pub samples: usize,
    pub cells: Vec<Cell>,
    pub compile_s: f64,
    pub ref_contacts: usize,
    /// Exact switching diagnostics and its `tick` cost.
    pub engine_note: String,
}

/// Column labels, in table order.
pub(crate) fn labels() -> Vec<String> {
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
            rel_l2_window(&tr.pickup, &r.pickup, 0..r.pickup.len())
        } else {
            rel_l2_window(&tr.x_hammer, &r.x_hammer, 0..r.x_hammer.len())
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
pub(crate) fn run_case(case: &Case) -> Result<StabResult> {
    let t0 = Instant::now();
    let exact = compile_with(&case.scene, RATE, Some(Switching::Exact))
        .map_err(|e| anyhow!("{}: {e}", case.name))?;
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
    let sys = PwlSystem::from_scene(&case.scene).map_err(|e| anyhow!("{}: {e}", case.name))?;
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
        name: case.name.clone(),
        label: case.label.clone(),
        what: case.description.clone(),
        samples: n,
        cells,
        compile_s,
        ref_contacts: reference.contacts.len(),
        engine_note,
    })
}

/// Markdown: one row per case, one column per method.
pub(crate) fn markdown(results: &[StabResult]) -> String {
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
        s += &format!(
            "| {} ({}) | {} | {} |",
            r.name, r.label, r.samples, r.ref_contacts
        );
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
            "- **{}** ({}): {}. Compile {:.2} s; {}\n",
            r.name, r.label, r.what, r.compile_s, r.engine_note
        );
    }
    s
}
