//! Exact switching at any contact stiffness (issue 11): the engine in exact
//! mode against an independent reference solver (`pwl_reference`: physical
//! coordinates, dense matrix exponentials per sub-step with double-double
//! exact states, bisection on the exact flow; checked in its own tests
//! against closed forms, DOP853 and its own sub-step length), on a family
//! of stiff cases at 44.1 kHz, 50 ms each.
//!
//! Each case is written once as plain numbers ([`Case`] -> [`Numbers`]); the
//! engine's scene and the reference model are both derived from them, so the
//! two solvers share the scene and nothing else.
//!
//! Definitions used to place the cases:
//! - The object's effective mass at the contact point is `m_eff = 1 / sum
//!   w_i^2` (all modes' contact weights): what a contact much shorter than
//!   every mode's period feels (each mode is a mass `1 / w_i^2` there, and
//!   at high frequency their admittances add). A wall has `1 / m_eff = 0`.
//! - The mass ratio is `m_h / m_eff`.
//! - The contact frequency is the two-mass one, `f_c = sqrt(k (1/m_h +
//!   1/m_eff)) / 2 pi`, given as a multiple of the Nyquist frequency
//!   (22.05 kHz), always a non-integer one (3.17x, 31.3x, 101.7x, 317.3x,
//!   1013.7x) so no contact lasts a whole number of samples.
//! - The damping ratio is `zeta = c / (2 sqrt(k m_r))`, `m_r = 1 / (1/m_h +
//!   1/m_eff)`: 0, 0.05 (light), 1 (critical), 5 (overdamped).
//!
//! The three cases of the issue are `C1`, `C2`, `C3`; the others vary one
//! factor around them (`C1 f_c 3.17x`, ...) plus a few combinations (`X*`).
//! The object (`O4`) is the paper-bounce object's modes (220, 950, 3500 Hz)
//! at 0.6x its weights plus a mode at 28.9 kHz (1.31x Nyquist), undamped:
//! `m_eff` = 0.327 kg. Variants: `O4d` damped (T60 0.4 / 0.25 / 0.1 /
//! 0.02 s), `O4w` top mode at 1.497x Nyquist, `O1` the 220 Hz mode alone,
//! `wall`.
//!
//! Comparison, per case, on the 44.1 kHz grid, on a window `[0, N]`:
//! - Predictability horizon (twin): the reference runs again with the hammer
//!   disturbed by 1e-9 (relative): its initial height under gravity (when
//!   the height is non-zero), otherwise its mass. Not the initial velocity:
//!   without gravity the system is homogeneous and autonomous, so a scaled
//!   velocity scales the whole motion and a changed height only shifts it in
//!   time, and neither ever grows (`pwl_reference::Model::perturbed`). The
//!   twin horizon is the largest sample `N` such that on `[0, N]` the two
//!   runs agree to 1e-7 relative L2 on hammer height, hammer velocity and
//!   contact displacement (`pwl_reference::horizon`).
//! - Instant horizon: contact instants are far more sensitive than the
//!   traces (an instant moves by `dp / p'`, a lot when a contact begins or
//!   ends at a small relative speed): in the chattering cases the twin
//!   moves instants by up to 1e-4 samples while its traces still agree to
//!   1e-7. So the window also ends before the first contact whose start or
//!   end the twin places more than 1e-6 samples (the tolerance) from the
//!   reference's: beyond it the instants are not determined to the
//!   tolerance by inputs known to 1e-9. That leaves the engine a margin of
//!   10 over its own worst noise: it keeps its state in f64, so
//!   a hammer and a surface at `|x|` carry `u |x|` of rounding per step,
//!   which a slow entry after a long flight turns into an instant error
//!   `u |x| / |v_rel|` (C3's fourth switch: 2e-11 samples against the
//!   reference, 3.6e-12 between the engine at 44.1 kHz and at 16x that
//!   rate), the size a 1e-10 disturbance of the inputs gives; chattering
//!   then amplifies it about tenfold per contact, as it does the twin's.
//!   (The reference itself is double-double inside: its own error is far
//!   below this.)
//! - `N` is the smaller of the two and must be at least [`MIN_HORIZON`]
//!   samples.
//! - On `[0, N]`: relative L2 error of hammer height, hammer velocity and
//!   contact displacement <= 1e-6; the same number of contacts starting in
//!   the window, each start and end within 1e-6 samples of the reference's.
//!   Why these tolerances: both solvers solve the same piecewise-linear ODE
//!   exactly up to rounding and locate switches to ~1e-15 of a sample; the
//!   reference agrees with closed forms to ~1e-11 and with DOP853 to ~1e-9
//!   (its double-double flows do not depend on its sub-steps to 1e-13), and
//!   on the window a 1e-9 change of the inputs moves nothing by more than
//!   a tenth of each tolerance. A release one sub-sample late (the issue's
//!   1.3 us at 1 m/s) is a 1e-2..1e-1 sample error and 1e-3 or more on the
//!   traces.
//! - Over the whole run: energy never increases from one sample to the next
//!   beyond `64 dim kappa u` relative to `max(|E| + 2 m_h g |x_h|)` of the
//!   two samples (`dim` = contact-phase dimension, `kappa` = the larger
//!   condition number of the compiled phases' eigenvector matrices, through
//!   which the observed energy is computed, `u` = 2^-53; the stability
//!   suite's bound), and the exact switching counters `capped`,
//!   `rod_fallbacks`, `uncertified` stay 0.
//! - Speed: the engine runs three times; each tick is timed
//!   (`Instant` around `tick`), the fastest of the three kept per sample (so
//!   a preemption by the OS, 4 ms here, does not count), and the slowest
//!   sample printed. Never asserted.
//!
//! The table (one row per case) is printed and written to
//! `target/stiff_switching.md`. Run with
//! `cargo test --profile test-release --test numerics stiff_switching:: --
//! --nocapture`;
//! the cases run on all cores.

use modal_contact::compile::{compile_with, CompiledScene};
use modal_contact::engine::{EngineState, Observation};
use modal_contact::scene::{Scene, SceneError, Switching};
use modal_testkit::metrics::{
    energy_rounding_bound, energy_scale, instant_horizon, match_contacts, rel_l2, ContactLog, Ends,
    Interval, LogAnomaly,
};
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder, Wall};
use pwl_reference as reference;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::time::Instant;

const RATE: f64 = 44_100.0;
const NYQUIST: f64 = RATE / 2.0;
/// 50 ms.
const SAMPLES: usize = 2205;
/// Relative L2 tolerance on the traces within the horizon.
const TOL_TRACE: f64 = 1e-6;
/// Contact-instant tolerance [samples].
const TOL_INSTANT: f64 = 1e-6;
/// Relative disturbance of the twin reference run.
const DISTURBANCE: f64 = 1e-9;
/// Agreement that defines the horizon (relative L2).
const HORIZON_TOL: f64 = 1e-7;
/// Largest difference between the reference's and its twin's contact
/// instants on the window [samples].
const INSTANT_HORIZON_TOL: f64 = TOL_INSTANT;
/// Shortest acceptable window [samples]: the chattering cases still cover
/// several contacts.
const MIN_HORIZON: usize = 20;
/// Engine runs timed (the fastest per sample is kept).
const TIMING_RUNS: usize = 3;
/// Gravity of the rattling cases [m/s^2].
const G: f64 = 9.81;

/// The struck object.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Object {
    /// Paper-bounce modes at 0.6x weights plus one at 1.31x Nyquist, undamped.
    O4,
    /// `O4` with decay times.
    O4d,
    /// `O4` with its top mode at 1.497x Nyquist.
    O4w,
    /// The 220 Hz mode of `O4` alone.
    O1,
    /// A rigid wall.
    Wall,
}

impl Object {
    /// `(freq_hz, t60_s, contact weight, pickup weight)` per mode.
    fn modes(self) -> Vec<(f64, Option<f64>, f64, f64)> {
        let o4 = vec![
            (220.0, None, 1.2, 1.0),
            (950.0, None, 0.9, -1.2),
            (3500.0, None, 0.72, 0.9),
            (28_912.3, None, 0.54, 0.5),
        ];
        match self {
            Object::O4 => o4,
            Object::O4d => o4
                .into_iter()
                .zip([0.4, 0.25, 0.1, 0.02])
                .map(|((f, _, w, p), t)| (f, Some(t), w, p))
                .collect(),
            Object::O4w => {
                let mut m = o4;
                m[3].0 = 1.497 * NYQUIST;
                m
            }
            Object::O1 => vec![o4[0]],
            Object::Wall => Vec::new(),
        }
    }

    fn label(self) -> &'static str {
        match self {
            Object::O4 => "O4",
            Object::O4d => "O4d",
            Object::O4w => "O4w",
            Object::O1 => "O1",
            Object::Wall => "wall",
        }
    }
}

/// How heavy the hammer is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mass {
    /// `m_h / m_eff`.
    Ratio(f64),
    /// Absolute [kg].
    Kg(f64),
}

/// How the hammer starts.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Launch {
    /// At the object's surface (height 0), moving down at this speed [m/s],
    /// no gravity.
    Strike(f64),
    /// Dropped from rest at this height [m] under gravity.
    Drop(f64),
    /// At the surface moving down at this speed [m/s], under gravity.
    StrikeUnderGravity(f64),
}

/// One case of the family.
#[derive(Debug, Clone)]
struct Case {
    name: String,
    object: Object,
    mass: Mass,
    launch: Launch,
    /// Contact frequency over the Nyquist frequency.
    fc_ratio: f64,
    /// Contact damping ratio.
    zeta: f64,
}

impl Case {
    fn new(
        name: &str,
        object: Object,
        mass: Mass,
        launch: Launch,
        fc_ratio: f64,
        zeta: f64,
    ) -> Self {
        Case {
            name: name.to_string(),
            object,
            mass,
            launch,
            fc_ratio,
            zeta,
        }
    }

    /// A variant of this case named `name`.
    fn with(&self, name: &str, f: impl FnOnce(&mut Case)) -> Case {
        let mut c = self.clone();
        c.name = name.to_string();
        f(&mut c);
        c
    }
}

/// A case as the numbers both solvers are given.
#[derive(Debug, Clone)]
struct Numbers {
    modes: Vec<(f64, Option<f64>, f64, f64)>,
    m_h: f64,
    x0: f64,
    v0: f64,
    g: f64,
    k: f64,
    c: f64,
}

impl Numbers {
    fn of(case: &Case) -> Numbers {
        let modes = case.object.modes();
        let inv_eff: f64 = modes.iter().map(|m| m.2 * m.2).sum();
        let m_h = match case.mass {
            Mass::Kg(m) => m,
            Mass::Ratio(r) => {
                assert!(
                    inv_eff > 0.0,
                    "{}: a mass ratio needs a modal object",
                    case.name
                );
                r / inv_eff
            }
        };
        let inv_m = 1.0 / m_h + inv_eff;
        let w_c = 2.0 * PI * case.fc_ratio * NYQUIST;
        let k = w_c * w_c / inv_m;
        let c = 2.0 * case.zeta * (k / inv_m).sqrt();
        let (x0, v0, g) = match case.launch {
            Launch::Strike(v) => (0.0, -v, 0.0),
            Launch::Drop(h) => (h, 0.0, G),
            Launch::StrikeUnderGravity(v) => (0.0, -v, G),
        };
        Numbers {
            modes,
            m_h,
            x0,
            v0,
            g,
            k,
            c,
        }
    }

    /// The engine's scene (exact switching).
    fn scene(&self) -> Result<Scene, SceneError> {
        let hammer = Hammer::new(self.m_h)
            .height(self.x0)
            .velocity(self.v0)
            .gravity(self.g);
        let contact = Contact::new("o", self.k)
            .damping(self.c)
            .switching(Switching::Exact);
        if self.modes.is_empty() {
            return SceneBuilder::new("stiff")
                .object(Wall::new("o"))
                .hammer(hammer)
                .contact(contact)
                .try_build();
        }
        let mut object = Modal::new("o", &["c", "p"]);
        for &(f, t60, w, wp) in &self.modes {
            object = object.mode(f, t60, &[w, wp]);
        }
        SceneBuilder::new("stiff")
            .object(object)
            .hammer(hammer)
            .contact(contact.point("c"))
            .pickup(Pickup::new("o", "p"))
            .try_build()
    }

    /// The reference solver's model.
    fn model(&self) -> reference::Model {
        reference::Model {
            modes: self
                .modes
                .iter()
                .map(|&(freq_hz, t60_s, weight, _)| reference::Mode {
                    freq_hz,
                    t60_s,
                    weight,
                })
                .collect(),
            hammer: reference::Hammer {
                mass_kg: self.m_h,
                height_m: self.x0,
                velocity_m_per_s: self.v0,
                gravity_m_per_s2: self.g,
            },
            contact: reference::Contact {
                stiffness_n_per_m: self.k,
                damping_n_s_per_m: self.c,
            },
            back: None,
            extra: Vec::new(),
            masses: vec![],
            links: vec![],
        }
    }
}

/// The family: the three cases, one-factor sweeps around each, and
/// a few combinations.
fn cases() -> Vec<Case> {
    use Launch::*;
    use Object::*;
    let fcs = [
        ("3.17x", 3.17),
        ("31.3x", 31.3),
        ("317.3x", 317.3),
        ("1013.7x", 1013.7),
    ];
    // (1) light hammer, 1 m/s down, no gravity, elastic, 101.7x Nyquist
    let c1 = Case::new("C1", O4, Mass::Ratio(1e-6), Strike(1.0), 101.7, 0.0);
    // (2) 10 g dropped from 1 mm, critically damped, 101.7x Nyquist
    let c2 = Case::new("C2", O4, Mass::Kg(0.01), Drop(1e-3), 101.7, 1.0);
    // (3) heavy hammer pressing slowly, elastic, 101.7x Nyquist
    let c3 = Case::new("C3", O4, Mass::Ratio(1e3), Strike(0.1), 101.7, 0.0);
    let mut v = vec![c1.clone(), c2.clone(), c3.clone()];
    for (base, zetas) in [
        (&c1, [0.05, 1.0, 5.0]),
        (&c2, [0.0, 0.05, 5.0]),
        (&c3, [0.05, 1.0, 5.0]),
    ] {
        for (label, r) in fcs {
            v.push(base.with(&format!("{} f_c {label}", base.name), |c| c.fc_ratio = r));
        }
        for z in zetas {
            v.push(base.with(&format!("{} zeta {z}", base.name), |c| c.zeta = z));
        }
    }
    for r in [1e-3, 1.0, 1e3] {
        v.push(c1.with(&format!("C1 mass {r:e}"), |c| c.mass = Mass::Ratio(r)));
    }
    for r in [1e-6, 1e-3, 1.0, 1e3] {
        v.push(c2.with(&format!("C2 mass {r:e}"), |c| c.mass = Mass::Ratio(r)));
    }
    for o in [O4d, O4w, O1] {
        v.push(c1.with(&format!("C1 {}", o.label()), |c| c.object = o));
    }
    v.push(c1.with("C1 wall", |c| {
        c.object = Wall;
        c.mass = Mass::Kg(0.01);
    }));
    v.push(c1.with("C1 gravity", |c| c.launch = Drop(1e-3)));
    for o in [O4d, O4w] {
        v.push(c2.with(&format!("C2 {}", o.label()), |c| c.object = o));
    }
    v.push(c2.with("C2 wall", |c| c.object = Wall));
    v.push(c3.with("C3 O4d", |c| c.object = O4d));
    v.push(c3.with("C3 gravity", |c| c.launch = StrikeUnderGravity(0.1)));
    // combinations
    v.push(Case::new(
        "X1 O4d mass 1 drop zeta 5 1013.7x",
        O4d,
        Mass::Ratio(1.0),
        Drop(1e-3),
        1013.7,
        5.0,
    ));
    v.push(Case::new(
        "X2 O4w mass 1e-3 zeta 0.05 3.17x",
        O4w,
        Mass::Ratio(1e-3),
        Strike(1.0),
        3.17,
        0.05,
    ));
    v.push(Case::new(
        "X3 O4w mass 1e3 drop zeta 1 317.3x",
        O4w,
        Mass::Ratio(1e3),
        Drop(1e-3),
        317.3,
        1.0,
    ));
    v.push(Case::new(
        "X4 wall drop zeta 0.05 31.3x",
        Wall,
        Mass::Kg(0.01),
        Drop(1e-3),
        31.3,
        0.05,
    ));
    v.push(Case::new(
        "X5 O1 mass 1e-6 drop 1013.7x",
        O1,
        Mass::Ratio(1e-6),
        Drop(1e-3),
        1013.7,
        0.0,
    ));
    v
}

/// What one case measured.
#[derive(Debug, Default)]
struct Outcome {
    name: String,
    contacts_ref: usize,
    contacts_eng: usize,
    /// Window `[0, horizon]`: the smaller of the trace and instant horizons.
    horizon: usize,
    horizon_twin: usize,
    horizon_instants: usize,
    err_x: f64,
    err_v: f64,
    err_c: f64,
    /// Worst contact-instant error within the horizon [samples].
    dt: f64,
    /// The same for the disturbed reference run (sensitivity).
    twin_dt: f64,
    /// Largest relative energy increase between samples (engine).
    de: f64,
    /// Worst tick [us] (fastest of the timed runs, per sample).
    worst_us: f64,
    /// Switches of a strike from rest after its first release that the
    /// engine took from the compiler's store (`compile::rest`), and the
    /// switches that did not come where it said.
    rest_later: u64,
    rest_misses: u64,
    failures: Vec<String>,
    /// Short names of the failed checks, for the table.
    failed: Vec<&'static str>,
    summary: String,
}

fn fmt_interval(c: &Interval) -> String {
    match c.1 {
        Some(e) => format!("[{:.9}, {:.9}]", c.0, e),
        None => format!("[{:.9}, open]", c.0),
    }
}

fn reference_intervals(sol: &reference::Solution) -> Vec<Interval> {
    sol.contacts
        .iter()
        .map(|c| (c.start_s * RATE, c.end_s.map(|e| e * RATE)))
        .collect()
}

/// Run one case: both reference runs, the engine, every comparison.
fn run_case(case: &Case) -> Outcome {
    let num = Numbers::of(case);
    let mut out = Outcome {
        name: case.name.clone(),
        ..Outcome::default()
    };
    let model = num.model();
    let (sol, ref_contacts) = reference_runs(&model, &mut out);
    let hz = out.horizon;
    let Some(compiled) = compile_case(&num, &mut out) else {
        return out;
    };
    out.summary = compiled.summary.clone();
    let (obs, eng_contacts, st) = run_engine(&compiled, &mut out);
    check_traces(&obs, &sol, hz, &mut out);
    check_instants(&eng_contacts, &ref_contacts, hz, &mut out);
    check_energy(&obs, &compiled, &num, &mut out);
    check_counters(&st, &mut out);
    out
}

/// The reference's run of `model` and its twin's (inputs moved by
/// [`DISTURBANCE`]): the horizons of `out` and the reference's contacts
/// \[samples\], a failure if the comparison window is too short.
fn reference_runs(
    model: &reference::Model,
    out: &mut Outcome,
) -> (reference::Solution, Vec<Interval>) {
    let sol = reference::solve(model, RATE, SAMPLES);
    let twin = reference::solve(&model.perturbed(DISTURBANCE), RATE, SAMPLES);
    let ref_contacts = reference_intervals(&sol);
    out.horizon_twin = reference::horizon(&sol, &twin, HORIZON_TOL);
    out.horizon_instants = instant_horizon(
        &ref_contacts,
        &reference_intervals(&twin),
        INSTANT_HORIZON_TOL,
        SAMPLES,
    );
    let hz = out.horizon_twin.min(out.horizon_instants);
    out.horizon = hz;
    out.contacts_ref = sol.contacts.len();
    out.twin_dt = match_contacts(
        &reference_intervals(&twin),
        &ref_contacts,
        hz as f64,
        1.0,
        Ends::EitherEnded,
    )
    .worst();
    if hz < MIN_HORIZON {
        out.failed.push("window");
        out.failures.push(format!(
            "comparison window {hz} samples < {MIN_HORIZON} (trace horizon {}, instant horizon {}): \
             the case is too chaotic to compare",
            out.horizon_twin, out.horizon_instants
        ));
    }
    (sol, ref_contacts)
}

/// The case's scene compiled, or `None` with the failure in `out`.
fn compile_case(num: &Numbers, out: &mut Outcome) -> Option<CompiledScene> {
    let scene = match num.scene() {
        Ok(s) => s,
        Err(e) => {
            out.failed.push("scene");
            out.failures.push(format!("scene refused: {e}\n{num:?}"));
            return None;
        }
    };
    let compiled = match compile_with(&scene, RATE, Some(Switching::Exact)) {
        Ok(c) => c,
        Err(e) => {
            out.failed.push("compile");
            out.failures.push(format!("compile failed: {e}\n{num:?}"));
            return None;
        }
    };
    Some(compiled)
}

/// Run the engine [`TIMING_RUNS`] times: the first run's observations and
/// contacts \[samples\], the last run's state; the worst tick's time and
/// the switch log's anomalies in `out`.
fn run_engine(
    compiled: &CompiledScene,
    out: &mut Outcome,
) -> (Vec<Observation>, Vec<Interval>, EngineState) {
    let mut obs = Vec::with_capacity(SAMPLES + 1);
    let mut eng_contacts: Vec<Interval> = Vec::new();
    let mut tick_s = vec![f64::INFINITY; SAMPLES];
    let mut st = EngineState::new(compiled);
    for run in 0..TIMING_RUNS {
        // the first run records, the others only time
        let record = run == 0;
        if !record {
            st = EngineState::new(compiled);
        }
        if record {
            obs.push(st.observe(compiled));
        }
        let mut log = ContactLog::default();
        for (i, best) in tick_s.iter_mut().enumerate() {
            let t0 = Instant::now();
            st.tick(compiled);
            *best = best.min(t0.elapsed().as_secs_f64());
            if !record {
                continue;
            }
            for ev in st.switch_events() {
                let t = i as f64 + ev.after_s * RATE;
                match log.record(t, ev.entered) {
                    Ok(()) => {}
                    Err(LogAnomaly::EnteredWhileInContact { since }) => out.failures.push(format!(
                        "engine entered contact at {t:.9} samples while in contact since {since:.9}"
                    )),
                    Err(LogAnomaly::LeftWithoutEntering) => out.failures.push(format!(
                        "engine left contact at {t:.9} samples without entering"
                    )),
                }
            }
            obs.push(st.observe(compiled));
        }
        if record {
            eng_contacts = log.finish(None);
            if !out.failures.is_empty() {
                out.failed.push("events");
            }
        }
    }
    let worst = tick_s.iter().copied().fold(0.0, f64::max);
    out.worst_us = worst * 1e6;
    out.contacts_eng = eng_contacts.len();
    (obs, eng_contacts, st)
}

/// The engine's traces against the reference's on the horizon `hz`.
fn check_traces(obs: &[Observation], sol: &reference::Solution, hz: usize, out: &mut Outcome) {
    // traces on the horizon
    let w = hz + 1;
    let eng_x: Vec<f64> = obs[..w].iter().map(|o| o.x_hammer).collect();
    let eng_v: Vec<f64> = obs[..w].iter().map(|o| o.v_hammer).collect();
    let eng_c: Vec<f64> = obs[..w].iter().map(|o| o.x_contact).collect();
    out.err_x = rel_l2(&eng_x, &sol.x_hammer()[..w]);
    out.err_v = rel_l2(&eng_v, &sol.v_hammer()[..w]);
    out.err_c = rel_l2(&eng_c, &sol.x_contact()[..w]);
    for (what, e) in [
        ("hammer height", out.err_x),
        ("hammer velocity", out.err_v),
        ("contact displacement", out.err_c),
    ] {
        if !(e <= TOL_TRACE) {
            if !out.failed.contains(&"traces") {
                out.failed.push("traces");
            }
            out.failures.push(format!(
                "{what}: relative L2 error {e:.3e} > {TOL_TRACE:e} over samples [0, {hz}]"
            ));
        }
    }
}

/// The engine's contact instants against the reference's on the horizon
/// `hz` \[samples\].
fn check_instants(
    eng_contacts: &[Interval],
    ref_contacts: &[Interval],
    hz: usize,
    out: &mut Outcome,
) {
    // contact instants on the horizon
    let m = match_contacts(
        eng_contacts,
        ref_contacts,
        hz as f64,
        1.0,
        Ends::EitherEnded,
    );
    let (n_ref, n_eng, dt) = (m.n_ref, m.n_run, m.worst());
    out.dt = dt;
    if n_ref != n_eng {
        out.failed.push("count");
        out.failures.push(format!(
            "{n_ref} reference vs {n_eng} engine contacts start within the horizon ({hz} samples)"
        ));
    }
    if let Some(i) = m.first_beyond(TOL_INSTANT) {
        out.failed.push("instants");
        out.failures.push(format!(
            "contact #{i}: reference {} vs engine {} samples (worst instant error {dt:.3e} > {TOL_INSTANT:e} samples)",
            fmt_interval(&ref_contacts[i]),
            fmt_interval(&eng_contacts[i])
        ));
    }
}

/// The energy never rises beyond rounding over the whole run.
fn check_energy(obs: &[Observation], compiled: &CompiledScene, num: &Numbers, out: &mut Outcome) {
    // energy over the whole run
    let bound = energy_rounding_bound(compiled);
    let mg = num.m_h * num.g;
    let mut de = f64::NEG_INFINITY;
    let mut first_rise = None;
    for i in 1..obs.len() {
        let (a, b) = (&obs[i - 1], &obs[i]);
        let scale = energy_scale(a, mg)
            .max(energy_scale(b, mg))
            .max(f64::MIN_POSITIVE);
        let rel = (b.energy - a.energy) / scale;
        if rel > de {
            de = rel;
        }
        if !(rel <= bound) && first_rise.is_none() {
            first_rise = Some((i, a.energy, b.energy, rel));
        }
    }
    out.de = de;
    if let Some((i, a, b, rel)) = first_rise {
        out.failed.push("energy");
        out.failures.push(format!(
            "energy rose at sample {i}: {a:.12e} -> {b:.12e} J (relative {rel:.3e} > {bound:.3e}; worst {de:.3e})"
        ));
    }
}

/// The exact switching's failure counters are 0.
fn check_counters(st: &EngineState, out: &mut Outcome) {
    let s = &st.exact_stats;
    (out.rest_later, out.rest_misses) = (s.rest_later, s.rest_misses);
    if s.capped != 0 || s.rod_fallbacks != 0 || s.uncertified != 0 {
        out.failed.push("counters");
        out.failures.push(format!(
            "exact switching counters must be 0: capped {}, rod_fallbacks {}, uncertified {} (located {}, grazing {})",
            s.capped, s.rod_fallbacks, s.uncertified, s.located, s.grazing
        ));
    }
}

/// Run a case, turning a panic into a failure (so the table still prints).
fn run_caught(case: &Case) -> Outcome {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run_case(case))) {
        Ok(o) => o,
        Err(e) => {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Outcome {
                name: case.name.clone(),
                failures: vec![format!("panicked: {msg}")],
                failed: vec!["panic"],
                ..Outcome::default()
            }
        }
    }
}

/// The table, as markdown.
fn table(outcomes: &[Outcome]) -> String {
    let mut t = String::from(
        "| case | contacts ref/engine (50 ms) | window [samples] (traces / instants) | hammer x err | hammer v err \
         | contact x err | worst instant err [samples] | twin dt [samples] | max dE/E | worst us/sample | result |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in outcomes {
        let _ = writeln!(
            t,
            "| {} | {}/{} | {} ({} / {}) | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.1} | {} |",
            o.name,
            o.contacts_ref,
            o.contacts_eng,
            o.horizon,
            o.horizon_twin,
            o.horizon_instants,
            o.err_x,
            o.err_v,
            o.err_c,
            o.dt,
            o.twin_dt,
            o.de,
            o.worst_us,
            if o.failures.is_empty() {
                "ok".to_string()
            } else {
                format!("FAIL: {}", o.failed.join(", "))
            }
        );
    }
    t
}

#[test]
fn stiff_exact_switching_matches_the_reference() {
    let cases = cases();
    let t0 = Instant::now();
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let outcomes: Vec<Outcome> = modal_testkit::parallel::map(&cases, run_caught);
    let md = table(&outcomes);
    println!("{md}");
    println!(
        "{} cases in {:.1} s on {threads} threads (worst us/sample: the slowest sample of the fastest of {TIMING_RUNS} runs, \
         other cases running on the other cores: indicative only)",
        outcomes.len(),
        t0.elapsed().as_secs_f64()
    );
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target");
    let _ = std::fs::create_dir_all(&dir);
    if let Err(e) = std::fs::write(dir.join("stiff_switching.md"), &md) {
        println!("could not write target/stiff_switching.md: {e}");
    }
    let mut report = String::new();
    for (case, o) in cases.iter().zip(&outcomes) {
        if o.failures.is_empty() {
            continue;
        }
        let _ = writeln!(report, "{}: {:?}", o.name, Numbers::of(case));
        for f in &o.failures {
            let _ = writeln!(report, "  - {f}");
        }
        if !o.summary.is_empty() {
            println!("--- {} compile summary:\n{}", o.name, o.summary);
        }
    }
    // the later switches of strikes from rest (the stored states) are
    // checked here against the reference too
    let later: u64 = outcomes.iter().map(|o| o.rest_later).sum();
    let with_later = outcomes.iter().filter(|o| o.rest_later > 0).count();
    let misses: u64 = outcomes.iter().map(|o| o.rest_misses).sum();
    println!(
        "strikes from rest: {later} later switches taken from the store in {with_later} cases, {misses} switches elsewhere"
    );
    assert!(
        with_later >= 5,
        "only {with_later} cases took a stored later switch"
    );
    let failed = outcomes.iter().filter(|o| !o.failures.is_empty()).count();
    assert!(
        failed == 0,
        "{failed} of {} stiff cases fail (table above and in target/stiff_switching.md):\n{report}",
        outcomes.len()
    );
}
