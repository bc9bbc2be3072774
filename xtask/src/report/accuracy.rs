//! "Error against run time": every method on every accuracy scene, against the
//! exact-switching engine (f64, the scene's rate) as the reference.

use super::runs::{
    from_sim, run_engine, run_engine_subsampled, time_competitor, time_engine, time_engine_pair,
    TimingPlan, Trajectory,
};
use anyhow::{anyhow, Result};
use modal_contact::compile::{compile_with, CompiledScene};
use modal_contact::scene::{ApproxSpec, Scene, Switching};
use modal_testkit::competitors::{Method, PwlSystem};
use modal_testkit::metrics::{match_contacts, rel_l2_window, ContactMatch, Ends};
use modal_testkit::scenes::RATE;
use std::time::Instant;

/// Oversampling factors of the competitors.
pub const OVERSAMPLES: [usize; 7] = [1, 2, 4, 8, 16, 32, 64];
/// Rate factor of the reference cross-check.
pub const CHECK_FACTOR: usize = 16;
/// The short error window \[s\].
pub const SHORT_S: f64 = 0.05;

/// One accuracy scene.
pub struct Case {
    /// The scene's name in the report.
    pub name: String,
    /// The scene every method runs.
    pub scene: Scene,
    /// Length of the runs \[s\].
    pub seconds: f64,
    /// What the scene is, in a sentence of the report.
    pub what: String,
    /// Opt-in approximation settings (the scene's `[approximate]` table) to
    /// measure with the exact engine, each against the exact reference.
    pub approx: Vec<ApproxSpec>,
    /// Oversampling factors of the competitors (a prefix of [`OVERSAMPLES`]).
    pub oversamples: &'static [usize],
}

/// Name of the plotted series of the approximation settings.
pub const APPROX_SERIES: &str = "exact + approximations";

/// One method at one oversampling on one scene.
#[derive(Debug, Clone)]
pub struct Row {
    /// The method's name (`exact`, `offset-rod`, a competitor's).
    pub method: String,
    /// Oversampling factor of the method's run.
    pub os: usize,
    /// Median CPU seconds per second of audio (stepping loop only).
    pub cpu_per_s: f64,
    /// Repetitions the timing took its median of.
    pub reps: usize,
    /// Relative L2 of the pickup (velocity) over the 50 ms from the first
    /// reference contact.
    pub pick_short: Option<f64>,
    /// Relative L2 of the pickup (velocity) over the whole window.
    pub pick_full: Option<f64>,
    /// Relative L2 of the hammer height over the window.
    pub hammer: Option<f64>,
    /// Contacts matched by order against the reference (errors in samples).
    pub contacts: ContactMatch,
    /// Largest energy increase between two output samples / E0.
    pub max_gain: f64,
    /// Whether the run diverged (a non-finite state or an energy above 1e6
    /// E0).
    pub diverged: bool,
}

impl Row {
    /// Set the CPU time from a `(median seconds, repetitions)` measurement
    /// over `seconds` of audio.
    fn timed(mut self, (t, k): (f64, usize), seconds: f64) -> Self {
        self.cpu_per_s = t / seconds;
        self.reps = k;
        self
    }
}

/// The exact engine with one approximation setting.
#[derive(Debug, Clone)]
pub struct ApproxRow {
    /// Short label of the setting (plot and table).
    pub label: String,
    /// Modes of the struck object kept (of [`SceneResult::modes`]).
    pub modes: usize,
    /// Compile time \[s\] (off the audio thread; the eigenproblem shrinks too).
    pub compile_s: f64,
    /// The exact scene's CPU seconds per second of audio, timed in
    /// alternation with this setting (the load of the shared machine drifts
    /// over a report run).
    pub exact_cpu_per_s: f64,
    /// Median over the alternating pairs of exact time / this setting's time.
    pub ratio: f64,
    /// Errors against the exact reference, i.e. the error the setting adds.
    pub row: Row,
}

/// Results of one scene.
pub struct SceneResult {
    /// The scene's name, as [`Case::name`].
    pub name: String,
    /// What the scene is, as [`Case::what`].
    pub what: String,
    /// Length of the runs \[s\].
    pub seconds: f64,
    /// Length of the runs \[samples\].
    pub n: usize,
    /// Every method at every oversampling.
    pub rows: Vec<Row>,
    /// Reference contacts.
    pub ref_contacts: usize,
    /// Cross-check of the reference against the engine at 16x the rate:
    /// (pickup short, pickup full, hammer, max |contact time| difference in
    /// samples).
    pub check: (Option<f64>, Option<f64>, Option<f64>, f64),
    /// Whether the pickup is identically zero (wall: no pickup).
    pub has_pickup: bool,
    /// Modes of the struck object in the exact run.
    pub modes: usize,
    /// The exact run's compile time \[s\].
    pub compile_s: f64,
    /// The exact engine with each approximation setting of the case.
    pub approx: Vec<ApproxRow>,
}

/// Modes of the struck object in a compiled scene: half the free phase's
/// state size (0 for a wall).
fn modes_of(sc: &CompiledScene) -> usize {
    sc.free.dim / 2
}

/// Short label of an approximation setting, e.g. `<= 0.5 f_Nyq + quiet < -30 dB`.
pub fn approx_label(a: &ApproxSpec) -> String {
    let mut parts = Vec::new();
    if let Some(f) = a.nyquist_fraction {
        parts.push(format!("<= {f} f_Nyq"));
    }
    if let Some(f) = a.max_freq_hz {
        parts.push(format!("<= {} kHz", f / 1000.0));
    }
    if let Some(db) = a.quiet_below_db {
        parts.push(format!("quiet < {db} dB"));
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join(" + ")
    }
}

/// Contacts of `tr` matched by order against `reference`, errors in
/// samples.
fn contact_errors(tr: &Trajectory, reference: &Trajectory) -> ContactMatch {
    match_contacts(
        &tr.contacts,
        &reference.contacts,
        f64::INFINITY,
        RATE,
        Ends::EitherEnded,
    )
}

fn row_from(method: &str, os: usize, tr: &Trajectory, reference: &Trajectory, n: usize) -> Row {
    // the short window starts at the reference's first contact (a dropped
    // ball is silent before it lands)
    let s0 = reference
        .contacts
        .first()
        .map_or(0, |c| (c.0 * RATE).floor() as usize);
    let s1 = (s0 + (SHORT_S * RATE).round() as usize).min(n);
    Row {
        method: method.to_string(),
        os,
        cpu_per_s: f64::NAN,
        reps: 0,
        pick_short: rel_l2_window(&tr.pickup, &reference.pickup, s0..s1),
        pick_full: rel_l2_window(&tr.pickup, &reference.pickup, 0..n),
        hammer: rel_l2_window(&tr.x_hammer, &reference.x_hammer, 0..n),
        contacts: contact_errors(tr, reference),
        max_gain: tr.max_sample_gain(),
        diverged: tr.diverged,
    }
}

/// Measure one scene.
pub fn run_case(case: &Case, plan: &TimingPlan) -> Result<SceneResult> {
    let n = (case.seconds * RATE).round() as usize;
    let t_compile = Instant::now();
    let exact = compile_with(&case.scene, RATE, Some(Switching::Exact))
        .map_err(|e| anyhow!("{}: {e}", case.name))?;
    let compile_s = t_compile.elapsed().as_secs_f64();
    let rod = compile_with(&case.scene, RATE, Some(Switching::OffsetRod))
        .map_err(|e| anyhow!("{}: {e}", case.name))?;
    let fine = compile_with(
        &case.scene,
        RATE * CHECK_FACTOR as f64,
        Some(Switching::Exact),
    )
    .map_err(|e| anyhow!("{}: {e}", case.name))?;
    let reference = run_engine(&exact, n);
    eprintln!("  exact: {}", reference.engine_note);
    let check = run_engine_subsampled(&fine, n, CHECK_FACTOR);
    let has_pickup = reference.pickup.iter().any(|x| *x != 0.0);

    let mut rows = Vec::new();
    // exact at 1x: its error is its disagreement with the 16x-rate run (it
    // is the reference itself, so against the reference it is 0 by
    // construction)
    let mut r = row_from("exact", 1, &reference, &check, n)
        .timed(time_engine(&exact, n, plan), case.seconds);
    // the energy gain is the reference run's own
    r.max_gain = reference.max_sample_gain();
    let c = contact_errors(&reference, &check);
    let check_tuple = (
        r.pick_short,
        r.pick_full,
        r.hammer,
        c.max_start.max(c.max_end),
    );
    rows.push(r);

    let rod_tr = run_engine(&rod, n);
    rows.push(
        row_from("offset-rod", 1, &rod_tr, &reference, n)
            .timed(time_engine(&rod, n, plan), case.seconds),
    );

    // opt-in approximations: the same engine, run and timed the same way, on
    // the scene with its `[approximate]` table set
    let mut approx = Vec::new();
    for spec in &case.approx {
        let mut scene = case.scene.clone();
        scene.approximate = Some(spec.clone());
        let label = approx_label(spec);
        let t0 = Instant::now();
        let sc = compile_with(&scene, RATE, Some(Switching::Exact))
            .map_err(|e| anyhow!("{} ({label}): {e}", case.name))?;
        let compile_s = t0.elapsed().as_secs_f64();
        let tr = run_engine(&sc, n);
        let (t_exact, t, ratio, k) = time_engine_pair(&exact, &sc, n, plan);
        let row = row_from(APPROX_SERIES, 1, &tr, &reference, n).timed((t, k), case.seconds);
        eprintln!(
            "  {label:<30} {:>3} modes err {:>9} cpu {:.3e} s/s; {}",
            modes_of(&sc),
            fmt_opt(row.pick_full),
            row.cpu_per_s,
            tr.engine_note
        );
        approx.push(ApproxRow {
            label,
            modes: modes_of(&sc),
            compile_s,
            exact_cpu_per_s: t_exact / case.seconds,
            ratio,
            row,
        });
    }

    let sys = PwlSystem::from_scene(&case.scene).map_err(|e| anyhow!("{}: {e}", case.name))?;
    for m in Method::ALL {
        for &os in case.oversamples {
            let (out, t, k) = time_competitor(&sys, m, RATE, os, n, plan);
            let tr = from_sim(&sys, out);
            let r = row_from(m.name(), os, &tr, &reference, n).timed((t, k), case.seconds);
            eprintln!(
                "  {:<18} x{os:<3} err {:>9} cpu {:.3e} s/s",
                m.name(),
                fmt_opt(if has_pickup { r.pick_full } else { r.hammer }),
                r.cpu_per_s
            );
            rows.push(r);
        }
    }
    Ok(SceneResult {
        name: case.name.clone(),
        what: case.what.clone(),
        seconds: case.seconds,
        n,
        rows,
        ref_contacts: reference.contacts.len(),
        check: check_tuple,
        has_pickup,
        modes: modes_of(&exact),
        compile_s,
        approx,
    })
}

/// `1.23e-4`, `n/a` or `inf`.
pub fn fmt_opt(x: Option<f64>) -> String {
    match x {
        None => "n/a".into(),
        Some(v) if v.is_infinite() => "inf".into(),
        Some(v) if v.is_nan() => "NaN".into(),
        Some(v) => format!("{v:.2e}"),
    }
}

/// Markdown table of one scene.
pub fn markdown(res: &SceneResult) -> String {
    let mut s = format!(
        "### {} ({:.2} s, {} samples at 44.1 kHz; reference: {} contacts)\n\n{}\n\n",
        res.name, res.seconds, res.n, res.ref_contacts, res.what
    );
    s += "| method | OS | CPU s per s audio | pickup vel. err 50 ms from 1st contact | pickup vel. err full | hammer err | contacts run/ref (missed, extra) | max abs onset err [smp] | max abs end err [smp] | max dE between samples / E0 |\n";
    s += "|---|---|---|---|---|---|---|---|---|---|\n";
    for r in &res.rows {
        let div = if r.diverged { " **diverged**" } else { "" };
        let gain = if r.max_gain.is_finite() {
            format!("{:.1e}", r.max_gain)
        } else {
            "-".into()
        };
        let c = &r.contacts;
        s += &format!(
            "| {}{} | {} | {:.2e} ({}x) | {} | {} | {} | {}/{} ({}, {}) | {:.2e} | {:.2e} | {} |\n",
            r.method,
            div,
            r.os,
            r.cpu_per_s,
            r.reps,
            fmt_opt(r.pick_short),
            fmt_opt(r.pick_full),
            fmt_opt(r.hammer),
            c.n_run,
            c.n_ref,
            c.missed(),
            c.extra(),
            c.max_start,
            c.max_end,
            gain
        );
    }
    if !res.approx.is_empty() {
        s += &approx_markdown(res);
    }
    s
}

/// The table of the approximation settings of one scene.
fn approx_markdown(res: &SceneResult) -> String {
    let mut s = format!(
        "\n**Exact + approximations** (series `{APPROX_SERIES}` in the plot). Each row: the exact engine on the same scene with \
         an opt-in `[approximate]` setting (`nyquist_fraction` / `max_freq_hz`: drop modes above the limit; `quiet_below_db`: \
         drop modes whose bounded pickup contribution per contact impulse is below that level re the loudest mode; \
         src/compile/prune.rs), run and measured exactly like the rows above. Its errors are against the exact \
         reference, i.e. the error the setting *adds* (the exact row's own error, against the 16x run, is {}). \
         CPU time: the same `tick` loop and repetitions, but the setting and the exact scene ({} modes) are timed \
         in alternation (exact, setting, exact, ...) so both see the same load of the shared machine; time ratio = \
         median over those pairs of exact / setting. Compile = off-thread compile time (exact: {:.3} s).\n\n",
        fmt_opt(res.rows[0].pick_full),
        res.modes,
        res.compile_s
    );
    s += "| setting | modes kept | pickup vel. err 50 ms from 1st contact | pickup vel. err full (added error) | hammer err | contacts run/ref (missed, extra) | max abs onset / end err [smp] | CPU s per s audio | exact, timed alternately | time ratio exact / setting | compile [s] |\n";
    s += "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for a in &res.approx {
        let r = &a.row;
        let c = &r.contacts;
        s += &format!(
            "| {} | {} / {} | {} | {} | {} | {}/{} ({}, {}) | {:.1e} / {:.1e} | {:.2e} ({}x) | {:.2e} | {:.2}x ({:.0} % saved) | {:.3} |\n",
            a.label,
            a.modes,
            res.modes,
            fmt_opt(r.pick_short),
            fmt_opt(r.pick_full),
            fmt_opt(r.hammer),
            c.n_run,
            c.n_ref,
            c.missed(),
            c.extra(),
            c.max_start,
            c.max_end,
            r.cpu_per_s,
            r.reps,
            a.exact_cpu_per_s,
            a.ratio,
            100.0 * (1.0 - 1.0 / a.ratio),
            a.compile_s
        );
    }
    s
}
