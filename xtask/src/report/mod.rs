//! `cargo xtask report [--quick] [--out DIR]`: the "error against run time"
//! report, the stability table and the f32 study (docs/report.md; the cases
//! are docs/numerics.md's "The stability cases").
//!
//! Writes `DIR/report.md` (default `report/`), one work-precision diagram per
//! accuracy scene (`DIR/pareto-<scene>.svg`) and prints the tables. Timing is
//! reported, never asserted. `--quick` shortens every render (for smoke runs;
//! its numbers are not the report's).
//! `--only accuracy|stability|f32` runs one section, `--scene NAME` one
//! accuracy scene (development); `REPORT_DEBUG=1` prints
//! per-run times and exact-switching counters of the stability runs.

pub mod accuracy;
mod runs;
mod stability;
mod sustain;

use accuracy::{Case, SceneResult};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use modal_contact::scene::{ApproxSpec, ObjectSpec, Scene};
use modal_testkit::scenes::{self, NYQ};
use runs::TimingPlan;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// `cargo xtask report [--quick] [--out DIR] [--only SECTION] [--scene NAME]`.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Shorten every render (smoke runs; its numbers are not the report's).
    #[arg(long)]
    quick: bool,
    /// Where report.md and the plots go.
    #[arg(long, default_value = "report")]
    out: PathBuf,
    /// Run one section only (development).
    #[arg(long, value_enum)]
    only: Option<Section>,
    /// Run only the accuracy scene of this name (development).
    #[arg(long)]
    scene: Option<String>,
}

/// A section of the report.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum Section {
    /// Error against run time.
    Accuracy,
    /// The stability table.
    Stability,
    /// f32 against f64 state on a long sustain.
    F32,
}

impl ReportArgs {
    fn wants(&self, section: Section) -> bool {
        self.only.is_none_or(|o| o == section)
    }
}

fn accuracy_cases(quick: bool) -> Result<Vec<Case>> {
    let len = |s: f64| if quick { s.min(0.06) } else { s };
    Ok(vec![
        Case {
            name: "paper-bounce".into(),
            scene: scenes::single_pickup(scenes::preset("paper-bounce")),
            seconds: len(0.5),
            what: "presets/paper-bounce.toml (10 g ball dropped from 2 cm onto 3 modes, gravity; many bounces), pickup panned hard left.".into(),
            approx: Vec::new(),
            oversamples: &accuracy::OVERSAMPLES,
        },
        Case {
            name: "paper-string".into(),
            scene: scenes::single_pickup(scenes::preset("paper-string")),
            seconds: len(0.2),
            what: "presets/paper-string.toml (50-mass string, non-proportional damping, hammer 1 m/s), only the first pickup (mass 40), panned hard left.".into(),
            approx: Vec::new(),
            oversamples: &accuracy::OVERSAMPLES,
        },
        Case {
            name: "wall".into(),
            scene: scenes::wall_accuracy(),
            seconds: len(0.1),
            what: "Rigid wall, no gravity: 10 g hammer, k = 1e6 N/m (f_c = 1.59 kHz), zeta_c = 0.1, 0.1 mm above the wall at 1 m/s (contact from 4.41 samples). No pickup: the error is the hammer trajectory's.".into(),
            approx: Vec::new(),
            oversamples: &accuracy::OVERSAMPLES,
        },
        Case {
            name: "X2-chattering".into(),
            scene: scenes::chattering("X2-chattering", 0.45),
            seconds: len(0.2),
            what: "the stiff chattering contact of docs/numerics.md, \"The stability cases\" (X2): f_c = 0.45 f_Nyq, zeta_c = 0.3, m_h/m_k = 0.2, 20 modes 200 Hz..0.82 f_Nyq (T60 2 s..0.1 s), v0 = 1 m/s from 1e-5 m.".into(),
            approx: Vec::new(),
            oversamples: &accuracy::OVERSAMPLES,
        },
        Case {
            name: "S1-soft".into(),
            scene: scenes::chattering("S1-soft", 0.09),
            seconds: len(0.2),
            what: "the soft contact (X1) of docs/numerics.md, \"The stability cases\": as the stiff chattering contact with f_c = 0.09 f_Nyq.".into(),
            approx: Vec::new(),
            oversamples: &accuracy::OVERSAMPLES,
        },
        plate_case(quick)?,
    ])
}

/// The accuracy scene with many modes, some above Nyquist, measured also
/// with the opt-in approximations.
fn plate_case(quick: bool) -> Result<Case> {
    let scene = scenes::plate("plate-full", 1.5 * NYQ);
    Ok(Case {
        name: "plate-full".into(),
        what: format!(
            "The plate of presets/steel-plate.toml (simply supported 400 x 280 x 8 mm steel; hard beater 0.04 kg, \
             -1.5 m/s, here from 0.1 mm; contact designed for 0.2 ms) with every mode up to 1.5 f_Nyq instead of \
             8 kHz and T60 = ln(1000)/(1 + pi f 1e-4): {}. One velocity pickup at (0.72, 0.64). Competitors only up \
             to 16x (cost: O(N) per fine step with N = 280 states). Also measured with the opt-in approximations \
             (second table).",
            modal_summary(&scene)
        ),
        scene,
        // short: the 16x reference check observes O(N^2) per sample
        seconds: if quick { 0.06 } else { 0.1 },
        approx: plate_approximations(),
        oversamples: &accuracy::OVERSAMPLES[..5],
    })
}

/// The approximation settings measured on `plate-full`: frequency limits
/// (relative to Nyquist and absolute), quiet-mode levels, and one combination.
fn plate_approximations() -> Vec<ApproxSpec> {
    let nyq = |f: f64| ApproxSpec {
        nyquist_fraction: Some(f),
        ..Default::default()
    };
    let max = |hz: f64| ApproxSpec {
        max_freq_hz: Some(hz),
        ..Default::default()
    };
    let quiet = |db: f64| ApproxSpec {
        quiet_below_db: Some(db),
        ..Default::default()
    };
    vec![
        nyq(1.0),
        nyq(0.8),
        nyq(0.5),
        nyq(0.25),
        max(8000.0),
        max(3000.0),
        quiet(-40.0),
        quiet(-30.0),
        quiet(-20.0),
        ApproxSpec {
            nyquist_fraction: Some(1.0),
            quiet_below_db: Some(-30.0),
            ..Default::default()
        },
    ]
}

/// Methods on the Pareto front (no other point is both cheaper and more
/// accurate) of a scene, by the plotted metric.
fn pareto(res: &SceneResult) -> Vec<String> {
    let methods = res
        .rows
        .iter()
        .map(|r| (format!("{} x{}", r.method, r.os), r));
    let approx = res
        .approx
        .iter()
        .map(|a| (format!("exact + {}", a.label), &a.row));
    let pts: Vec<(String, f64, f64)> = methods
        .chain(approx)
        .filter(|(_, r)| !r.diverged)
        .filter_map(|(name, r)| {
            let y = if res.has_pickup {
                r.pick_full
            } else {
                r.hammer
            }?;
            (y.is_finite() && r.cpu_per_s.is_finite()).then_some((name, r.cpu_per_s, y))
        })
        .collect();
    let mut front: Vec<(String, f64, f64)> = pts
        .iter()
        .filter(|(_, x, y)| {
            !pts.iter()
                .any(|(_, x2, y2)| x2 <= x && y2 <= y && (x2 < x || y2 < y))
        })
        .cloned()
        .collect();
    front.sort_by(|a, b| a.1.total_cmp(&b.1));
    front
        .into_iter()
        .map(|(n, x, y)| format!("{n} ({x:.1e} s/s, {y:.1e})"))
        .collect()
}

/// Run the report.
pub fn run(a: ReportArgs) -> Result<()> {
    nice_plug_xtask::chdir_workspace_root()?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    let t_start = Instant::now();
    let plan = TimingPlan {
        reps: 5,
        slow_s: 0.5,
    };
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Error against run time, and stability\n\nGenerated by `cargo xtask report{}` (xtask/src/report/). \
         All signals are compared on the 44.1 kHz output grid; oversampled methods are sampled, not filtered. \
         Reference: the exact-switching engine in f64 at 44.1 kHz (cross-checked against the same engine at \
         {}x the rate, below). Errors are relative L2 norms against the reference. CPU time: median of up to \
         {} runs in this process (3 when one run takes over {} s), stepping loop only (engine: `tick` in a \
         loop; competitors: `simulate` minus the same call with one output row, i.e. minus setup; the competitor \
         loop still includes its per-fine-step energy and contact bookkeeping, O(state) per step). Every timed \
         run starts with `vzeroupper`: compiling a small scene on the same thread leaves the upper AVX register \
         halves dirty, which slowed the engine's next runs ~4x (xtask/src/report/runs.rs). One core of \
         a shared 2-core machine; other jobs may have run at the same time, so treat times as +-30 %.\n",
        if a.quick { " --quick" } else { "" },
        accuracy::CHECK_FACTOR,
        plan.reps,
        plan.slow_s
    );
    if a.quick {
        md += "\n**Quick mode: shortened renders; not the report's numbers.**\n";
    }

    let results = accuracy_section(&a, &plan, &mut md)?;
    stability_section(&a, &mut md)?;
    sustain_section(&a, &mut md);

    let _ = writeln!(
        md,
        "\nTotal report time: {:.0} s.",
        t_start.elapsed().as_secs_f64()
    );
    let path = a.out.join("report.md");
    std::fs::write(&path, &md).with_context(|| format!("{}", path.display()))?;
    eprintln!(
        "wrote {} and {} plots in {:.0} s",
        path.display(),
        results.len(),
        t_start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Section 1, error against run time: every accuracy scene (its table and
/// plot), then the reference's cross-check. Returns the scenes' results.
fn accuracy_section(
    a: &ReportArgs,
    plan: &TimingPlan,
    md: &mut String,
) -> Result<Vec<SceneResult>> {
    // --- accuracy
    *md += "\n## 1. Error against run time\n\n";
    *md += "Columns: CPU seconds per second of audio (repetitions); relative L2 error of the pickup velocity over the 50 ms from the reference's first contact onset (a dropped ball is silent before it lands) and over the whole window; relative L2 of the hammer height; contacts matched by order (missed = reference contacts without a partner, extra = the opposite); largest onset/end time error over matched contacts in samples; largest energy increase between two output samples relative to E0 = |E(0)| + m_h g |x_h(0)|. \
           The `exact` row is the reference itself: its errors are against the engine at 16x the rate (its own error is 0 by construction).\n\n";
    let mut results = Vec::new();
    let mut acc_cases = if a.wants(Section::Accuracy) {
        accuracy_cases(a.quick)?
    } else {
        Vec::new()
    };
    if let Some(name) = &a.scene {
        acc_cases.retain(|c| &c.name == name);
    }
    for case in acc_cases {
        eprintln!("accuracy: {} ({} s)", case.name, case.seconds);
        let t0 = Instant::now();
        let res = accuracy::run_case(&case, plan)?;
        let table = accuracy::markdown(&res);
        println!("{table}");
        let svg = a.out.join(format!("pareto-{}.svg", res.name));
        crate::plot::plot_work_precision(&res, &svg)?;
        *md += &table;
        let _ = writeln!(
            md,
            "\nPlot: [`{0}`]({0}). Pareto front (cheapest first): {1}.\n\n(measured in {2:.1} s)\n",
            svg.file_name().unwrap_or_default().to_string_lossy(),
            pareto(&res).join("; "),
            t0.elapsed().as_secs_f64()
        );
        results.push(res);
    }
    *md += "### Reference cross-check (exact engine at 44.1 kHz vs at 705.6 kHz, every 16th sample)\n\n";
    *md += "| scene | pickup 50 ms from 1st contact | pickup full | hammer | max contact time diff [samples] |\n|---|---|---|---|---|\n";
    for r in &results {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.1e} |",
            r.name,
            accuracy::fmt_opt(r.check.0),
            accuracy::fmt_opt(r.check.1),
            accuracy::fmt_opt(r.check.2),
            r.check.3
        );
    }

    Ok(results)
}

/// Section 2, stability: the stability catalogue's table.
fn stability_section(a: &ReportArgs, md: &mut String) -> Result<()> {
    // --- stability
    eprintln!("stability table");
    *md += "\n## 2. Stability (docs/numerics.md, \"The stability cases\")\n\n";
    let _ = writeln!(
        md,
        "Each cell: **diverges** (non-finite or energy > 1e6 E0; time of the first bad sample), \
         **gains energy** (largest per-step increase > {:.0e} E0; engine: per sample, competitors: per fine step; value printed), \
         loses energy (final energy more than {:.0e} E0 below the exact run's), else ok. \
         `gain` is the largest per-step increase / E0 (rounding level ~1e-16); `err` the relative L2 error of the pickup \
         (hammer height when there is no pickup) against the exact run over the whole run.\n",
        stability::GAIN_TOL,
        stability::LOSS_TOL
    );
    let mut stab = Vec::new();
    let stab_cases = if a.wants(Section::Stability) {
        modal_testkit::stability::cases()
    } else {
        Vec::new()
    };
    for case in stab_cases {
        let case = if a.quick {
            modal_testkit::stability::Case {
                samples: case.samples.min(2000),
                ..case
            }
        } else {
            case
        };
        let t0 = Instant::now();
        stab.push(stability::run_case(&case)?);
        eprintln!("  {} ({:.1} s)", case.name, t0.elapsed().as_secs_f64());
    }
    let stab_md = stability::markdown(&stab);
    println!("{stab_md}");
    *md += &stab_md;

    Ok(())
}

/// Section 3, f32 against f64 state on a long sustain.
fn sustain_section(a: &ReportArgs, md: &mut String) {
    // --- f32
    eprintln!("f32 vs f64 sustain");
    *md += "\n## 3. f32 versus f64 state on a long sustain\n\n";
    let _ = writeln!(
        md,
        "One free mode advanced by the engine's exact 2x2 block propagator (`physics::block::exp2` in f64; \
         the f32 run casts the coefficients and keeps the state in f32), free decay from the unit state, \
         {} samples (22.7 s). Compared with the f64 run at t_eval = min(22.7 s, 2 T60) (the f64 amplitude is \
         1e-6 at 2 T60). Pitch error from the phase difference at t_eval; in brackets the pitch error of the \
         rounded coefficients alone (eigenvalue angle). `pole -4u`: f32 coefficients rounded from the f64 \
         propagator times (1 - 2u), u = 2^-24, so |pole|^2 <= r^2 (1 - 4u) (docs/numerics.md, \"f32 or f64\").\n",
        sustain::SUSTAIN_N
    );
    let sus = if a.wants(Section::F32) {
        sustain::run_all()
    } else {
        Vec::new()
    };
    let sus_md = sustain::markdown(&sus);
    println!("{sus_md}");
    *md += &sus_md;
    if !sus.is_empty() {
        *md += &sustain_summary(&sus);
    }
}

/// `"139 modes 365 Hz .. 33.1 kHz (48 above f_Nyq), T60 6.2 s .. 0.61 s"` for
/// the first object of a scene when it is modal (measured from the scene).
fn modal_summary(scene: &Scene) -> String {
    let Some(ObjectSpec::Modal(m)) = scene.object.first() else {
        return "not a modal object".into();
    };
    let fs = m.mode.iter().map(|x| x.freq_hz);
    let (f_lo, f_hi) = fs.fold((f64::INFINITY, 0.0f64), |(a, b), f| (a.min(f), b.max(f)));
    let above = m.mode.iter().filter(|x| x.freq_hz > NYQ).count();
    let t60s: Vec<f64> = m.mode.iter().filter_map(|x| x.t60_s).collect();
    let t_hi = t60s.iter().copied().fold(0.0f64, f64::max);
    let t_lo = t60s.iter().copied().fold(f64::INFINITY, f64::min);
    format!(
        "{} modes {f_lo:.0} Hz .. {:.1} kHz ({above} above f_Nyq), T60 {t_hi:.2} s .. {t_lo:.2} s",
        m.mode.len(),
        f_hi / 1000.0
    )
}

fn sustain_summary(rows: &[sustain::SustainRow]) -> String {
    let max_of = |f: &dyn Fn(&sustain::SustainRow) -> Option<f64>| {
        rows.iter()
            .filter_map(f)
            .fold(0.0f64, |m, x| m.max(x.abs()))
    };
    let min_of = |f: &dyn Fn(&sustain::SustainRow) -> Option<f64>| {
        rows.iter().filter_map(f).fold(f64::INFINITY, f64::min)
    };
    let amp = max_of(&|r| Some(r.amp_err));
    let pitch = max_of(&|r| Some(r.pitch_cent));
    let damped = |r: &sustain::SustainRow| r.t60.is_finite() && r.t60 >= 10.0;
    let up_damped = max_of(&|r| damped(r).then_some(r.frac_up_f32));
    let up_t1_normal = max_of(&|r| (r.t60 <= 1.0).then_some(r.frac_up_f32_normal));
    let up_t1_all = max_of(&|r| (r.t60 <= 1.0).then_some(r.frac_up_f32));
    let sub_t1 = min_of(&|r| if r.t60 <= 1.0 { r.subnormal_at } else { None });
    let up_undamped_lo = min_of(&|r| (!r.t60.is_finite()).then_some(r.frac_up_f32));
    let up_undamped_hi = max_of(&|r| (!r.t60.is_finite()).then_some(r.frac_up_f32));
    let up_shrunk = max_of(&|r| Some(r.frac_up_f32_shrunk));
    let shrunk_loss = -max_of(&|r| (!r.t60.is_finite()).then_some(r.energy_err_shrunk));
    format!(
        "\nSummary (measured here): f32 amplitude error up to {:.1}% and pitch error up to {:.1e} cent. \
         Steps with an f32 energy increase: up to {:.1}% of steps for 10 s <= T60 <= 100 s (the 2x2 block works in \
         (omega q, q') coordinates, where the per-step dissipation vanishes when q' = 0, so rounding wins on those \
         steps; the prototype's diagonal complex-pole form showed none, docs/numerics.md, \"f32 or f64\"), {:.0}..{:.0}% undamped; at T60 = 1 s up to {:.1}% \
         before the state turns subnormal (from {:.1} s on; {:.0}% over the whole run). With the f32 pole rounded \
         down (|p|^2 <= r^2 (1 - 4u)) at most {:.2}% of the steps before subnormals, at the price of {:.0}% less energy \
         after 22.7 s undamped. f64 state: no increase in any damped run; undamped, increases of at most \
         ~1e-15 relative (rounding).\n",
        100.0 * amp,
        pitch,
        100.0 * up_damped,
        100.0 * up_undamped_lo,
        100.0 * up_undamped_hi,
        100.0 * up_t1_normal,
        sub_t1,
        100.0 * up_t1_all,
        100.0 * up_shrunk,
        -100.0 * shrunk_loss
    )
}
