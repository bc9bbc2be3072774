//! Fuzzing the scene parser and the compiler (docs/design.md, "Scene files").
//!
//! Thousands of generated scene files, structured ones with extreme and
//! degenerate values (0, -1, -0.0, NaN, +-inf, 1e300, 1e-300, subnormals,
//! empty lists, 10^5 modes or masses) and byte/line mutations of the presets,
//! go through `Scene::from_toml_str` and `compile`. Each must either
//! - be refused with an error that names the field or the reason, or
//! - compile into a scene whose engine run (a few thousand samples of the
//!   scene's own hammer, then a strike, at 44.1 kHz and at 8 or 192 kHz, with
//!   both switching methods) is finite at every sample and never gains energy
//!   from one sample to the next beyond a rounding bound.
//!
//! No step may panic: each one runs under `catch_unwind`, and a panic fails the
//! test with the offending TOML; a case that runs longer than a minute (a hang)
//! ends the process with its TOML printed. Counts of accepted and refused
//! cases, by reason, are printed (`-- --nocapture`; `FUZZ_SCENES_SHOW=1` adds
//! one example scene per compile refusal). `FUZZ_SCENES_CASES=N` sets the
//! structured case count (default [`STRUCTURED_CASES`]) for longer local runs;
//! the mutation count scales with it. The cases come from a fixed seed
//! ([`DEFAULT_SEED`]) so that a red run is a regression, not a new draw;
//! `FUZZ_SCENES_SEED=N` picks another seed and `FUZZ_SCENES_SEED=random` a
//! fresh one (printed), for longer local exploration. A failure prints the
//! seed and the shrunk scene, which then belongs in
//! `regressions_found_by_the_fuzzer`.

use modal_contact::compile::{
    compile_opts, CompileBudget, CompileCost, CompileOptions, CompiledPhase, CompiledScene,
};
use modal_contact::engine::EngineState;
use modal_contact::scene::*;
use modal_testkit::rng::TestRng;
use modal_testkit::scenes::preset_path;
use proptest::prelude::*;
use proptest::sample::select;
use proptest::test_runner::{Config, RngSeed, TestCaseError, TestRunner};
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Mutex, Once};
use std::time::Instant;

/// f64 unit roundoff.
const U: f64 = f64::EPSILON / 2.0;
/// Structured scenes per run (each compiled at two rates, run in two modes).
const STRUCTURED_CASES: u32 = 1500;
/// Preset mutations per run.
const MUTATION_CASES: u32 = 700;
/// Samples of the scene's own hammer, then samples after a strike, at 44.1 kHz
/// (half of each at the other rate).
const PRE_SAMPLES: usize = 1000;
const POST_SAMPLES: usize = 2000;
/// The strike after the first segment: 1 mm above the surface, 0.5 m/s down.
const STRIKE_HEIGHT_M: f64 = 1e-3;
const STRIKE_V_M_PER_S: f64 = -0.5;

/// The seed the tests use unless `FUZZ_SCENES_SEED` says otherwise.
const DEFAULT_SEED: u64 = 0x6d6f_6461_6c5f_6374;

/// The seed of this run (see the module documentation).
fn seed() -> u64 {
    match std::env::var("FUZZ_SCENES_SEED").ok().as_deref() {
        None | Some("") => DEFAULT_SEED,
        Some("random") => {
            let t = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos() as u64);
            // the clock through the test generator, so that close clocks
            // give far seeds
            TestRng(t).next_u64()
        }
        Some(s) => s
            .parse()
            .unwrap_or_else(|_| panic!("FUZZ_SCENES_SEED must be a u64 or `random`, got {s:?}")),
    }
}

fn cases(default: u32) -> u32 {
    std::env::var("FUZZ_SCENES_CASES")
        .ok()
        .and_then(|s| s.parse::<u32>().ok())
        .map_or(default, |n| {
            (n as u64 * default as u64 / STRUCTURED_CASES as u64) as u32
        })
        .max(1)
}

// ---------------------------------------------------------------- statistics

#[derive(Default)]
struct Stats {
    cases: usize,
    parse_refused: BTreeMap<String, usize>,
    compile_refused: BTreeMap<String, usize>,
    /// One scene per compile-refusal category (printed with FUZZ_SCENES_SHOW=1).
    compile_examples: BTreeMap<String, String>,
    accepted_scenes: usize,
    compiled: usize,
    runs: usize,
    samples: u64,
    contacts: u64,
    dense_phases: usize,
    /// Largest (energy rise / rounding bound) seen in any accepted run.
    worst_rise_over_bound: f64,
}

impl Stats {
    fn print(&self, label: &str, secs: f64) {
        let refused_parse: usize = self.parse_refused.values().sum();
        let refused_compile: usize = self.compile_refused.values().sum();
        println!(
            "{label}: {} cases in {secs:.1} s: {refused_parse} refused by the parser/validation, \
             {} parsed; {} compiles accepted, {refused_compile} refused by the compiler; \
             {} engine runs, {} samples, {} contacts, {} dense-fallback phases; \
             worst energy rise {:.2} x the rounding bound",
            self.cases,
            self.accepted_scenes,
            self.compiled,
            self.runs,
            self.samples,
            self.contacts,
            self.dense_phases,
            self.worst_rise_over_bound
        );
        for (what, map) in [
            ("refused (scene)", &self.parse_refused),
            ("refused (compile)", &self.compile_refused),
        ] {
            let mut v: Vec<_> = map.iter().collect();
            v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
            for (k, n) in v {
                println!("   {what:<18} {n:>5}  {k}");
            }
        }
        if std::env::var("FUZZ_SCENES_SHOW").is_ok() {
            for (k, ex) in &self.compile_examples {
                println!("--- example of {k}:\n{ex}");
            }
        }
    }
}

/// Strip indices and numbers so that errors group by field and reason.
fn category(s: &str) -> String {
    let mut out = String::new();
    let mut in_idx = false;
    for ch in s.chars() {
        match ch {
            '[' => {
                in_idx = true;
                out.push('[');
            }
            ']' => {
                in_idx = false;
                out.push(']');
            }
            _ if in_idx => {}
            _ => out.push(ch),
        }
    }
    let out = out.split(", got").next().unwrap_or("").to_string();
    let out = out.split(" (line").next().unwrap_or("").to_string();
    let mut short: String = out.chars().take(90).collect();
    if out.chars().count() > 90 {
        short.push_str("...");
    }
    short
}

// ------------------------------------------------------------ the watchdog

/// A case that runs longer than this is a hang: the watchdog prints its scene
/// and ends the process (a hung engine loop cannot be unwound).
const CASE_TIME_LIMIT_S: f64 = 60.0;

/// The case each fuzz test is running now, and since when.
static CURRENT: Mutex<BTreeMap<&'static str, (Instant, String)>> = Mutex::new(BTreeMap::new());

fn set_current(test: &'static str, text: Option<&str>) {
    static WATCHDOG: Once = Once::new();
    WATCHDOG.call_once(|| {
        std::thread::spawn(|| loop {
            std::thread::sleep(std::time::Duration::from_millis(500));
            let map = CURRENT.lock().unwrap_or_else(|e| e.into_inner());
            for (test, (t0, text)) in map.iter() {
                let dt = t0.elapsed().as_secs_f64();
                if dt > CASE_TIME_LIMIT_S {
                    eprintln!(
                        "{test}: one case has run for {dt:.0} s (hang?); its scene:\n{}",
                        show(text)
                    );
                    std::process::exit(101);
                }
            }
        });
    });
    let mut map = CURRENT.lock().unwrap_or_else(|e| e.into_inner());
    match text {
        Some(t) => {
            map.insert(test, (Instant::now(), t.to_string()));
        }
        None => {
            map.remove(test);
        }
    }
}

// ------------------------------------------------------------ the pipeline

fn show(text: &str) -> String {
    if text.len() > 20_000 {
        let mut cut = 20_000;
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        format!("{}\n... ({} bytes in all)", &text[..cut], text.len())
    } else {
        text.to_string()
    }
}

fn panic_msg(p: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "(non-string panic payload)".into()
    }
}

/// Run `f`, turning a panic into a test failure that prints the scene.
fn guard<T>(what: &str, text: &str, f: impl FnOnce() -> T) -> Result<T, TestCaseError> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
        TestCaseError::fail(format!(
            "{what} panicked: {}\n--- scene ---\n{}",
            panic_msg(p),
            show(text)
        ))
    })
}

fn fail(text: &str, msg: String) -> TestCaseError {
    TestCaseError::fail(format!("{msg}\n--- scene ---\n{}", show(text)))
}

/// The rounding bound per step, relative to the energy scale (as in
/// tests/stability.rs: a row of `dim` terms each rounded once, amplified by
/// the condition of the change of basis, with a safety factor of 64; a dense
/// phase steps in energy coordinates themselves, kappa 1).
fn kappa_eff(ph: &CompiledPhase) -> f64 {
    if ph.dense.is_some() || !ph.diag.kappa.is_finite() {
        1.0
    } else {
        ph.diag.kappa.max(1.0)
    }
}

struct RunOut {
    samples: u64,
    contacts: u64,
    worst: f64,
}

/// Run the scene's own hammer for `pre` samples, strike, run `post` more;
/// every output and energy must be finite and the energy must never rise by
/// more than the rounding bound relative to the running maximum of its scale
/// (|E| plus the magnitude of the gravity term, as in tests/energy.rs, and
/// at least the scale of the static equilibrium under gravity).
/// The observation of a run's state with its energy in the lab frame:
/// for a driven scene the voice's energy is the hammer's relative to the
/// moving surface (docs/numerics.md, "A driven contact").
struct LabObs {
    energy: f64,
    x_hammer: f64,
    in_contact: bool,
    /// The hammer's lab velocity and the surface's rate over the coming
    /// sample (0 when not driven).
    v: f64,
    rate: f64,
    /// The size of the terms the lab energy is summed from.
    terms: f64,
}

impl LabObs {
    /// The moving surface's work from this instant to `next`'s, one sample
    /// later: its rate times the contact force's impulse.
    fn work_to(&self, next: &LabObs, c: &CompiledScene) -> f64 {
        self.rate * c.m_h * (next.v - self.v + c.g * c.h)
    }
}

fn lab_energy(st: &mut EngineState, c: &CompiledScene) -> LabObs {
    let o = st.observe(c);
    let at = st.surface_at(c).unwrap_or_default();
    let (m, v_r) = (c.m_h, o.v_hammer);
    let v = v_r + at.frame_rate_m_per_s;
    LabObs {
        energy: o.energy + m * v * v / 2.0 - m * v_r * v_r / 2.0 + m * c.g * at.height_m,
        x_hammer: o.x_hammer + at.height_m,
        in_contact: o.in_contact,
        v,
        rate: at.rate_m_per_s,
        terms: m * (v * v + v_r * v_r) + (m * c.g * at.height_m).abs(),
    }
}

fn run_engine(c: &CompiledScene, pre: usize, post: usize) -> Result<RunOut, String> {
    let mut st = EngineState::new(c);
    let kappa = kappa_eff(&c.free).max(kappa_eff(&c.contact));
    let bound = 64.0 * c.contact.dim.max(2) as f64 * kappa * U;
    let mg = c.m_h * c.g;
    let mut worst: f64 = 0.0;
    let mut samples = 0;
    let mut contacts = 0;
    for segment in 0..2 {
        let n = if segment == 0 {
            pre
        } else {
            contacts += st.contacts_started;
            st.strike(c, STRIKE_HEIGHT_M, STRIKE_V_M_PER_S);
            post
        };
        let mut prev = lab_energy(&mut st, c);
        if !prev.energy.is_finite() {
            return Err(format!(
                "segment {segment}: initial energy is {:e}",
                prev.energy
            ));
        }
        let scale_of = |o: &LabObs| o.energy.abs() + 2.0 * (mg * o.x_hammer).abs();
        // Under gravity the contact phase steps around its static equilibrium
        // y* (`s_star`), and the hammer height is rebuilt from offsets of that
        // size: round-off scales with the equilibrium's energy too (it is
        // large when a heavy hammer sinks deep into a compliant object).
        let x_eq = c.offsets.x_c - c.offsets.pi / c.sk;
        let e_eq = 0.5 * c.s_star.iter().map(|x| x * x).sum::<f64>() + 2.0 * (mg * x_eq).abs();
        let mut scale_max = scale_of(&prev).max(e_eq);
        for i in 0..n {
            let out = st.tick(c);
            samples += 1;
            if !(out[0].is_finite() && out[1].is_finite()) {
                return Err(format!(
                    "segment {segment}: non-finite output {out:?} at sample {i}"
                ));
            }
            // a driven contact: the lab-frame energy less the moving
            // surface's work over the sample (docs/numerics.md, "A driven
            // contact"), which only the dissipation lowers
            let obs = lab_energy(&mut st, c);
            let work = prev.work_to(&obs, c);
            let proxy = st.energy_proxy(c);
            if !(obs.energy.is_finite() && proxy.is_finite()) {
                return Err(format!(
                    "segment {segment}: non-finite energy {:e} (proxy {proxy:e}) at sample {i}",
                    obs.energy
                ));
            }
            // The energy of each state is a sum of terms that cancel (a
            // falling hammer's kinetic and gravity terms): its rounding scales
            // with the terms of the new state as well as the old ones.
            scale_max = scale_max.max(scale_of(&obs)).max(obs.terms);
            let rel = (obs.energy - prev.energy - work) / (scale_max + 1e-300);
            worst = worst.max(rel / bound);
            if rel > bound {
                return Err(format!(
                    "segment {segment}: energy rose at sample {i}: {:e} -> {:e}, the surface's \
                     work {work:e} (rel. to running max {scale_max:e}: {rel:e} > bound \
                     {bound:e}); in contact {} -> {}",
                    prev.energy, obs.energy, prev.in_contact, obs.in_contact
                ));
            }
            prev = obs;
        }
    }
    contacts += st.contacts_started;
    Ok(RunOut {
        samples,
        contacts,
        worst,
    })
}

/// Parse, validate, round-trip, compile at 44.1 kHz and `other_rate`, run.
fn check_scene_text(
    text: &str,
    other_rate: f64,
    samples_scale: f64,
    stats: &RefCell<Stats>,
) -> Result<(), TestCaseError> {
    stats.borrow_mut().cases += 1;
    let Some(scene) = parse_scene_text(text, stats)? else {
        return Ok(());
    };
    stats.borrow_mut().accepted_scenes += 1;
    check_round_trip(text, &scene)?;
    for (rate, scale) in [(44100.0, 1.0), (other_rate, 0.5)] {
        let Some(compiled) = compile_scene_text(text, &scene, rate, stats)? else {
            continue;
        };
        run_compiled(text, &compiled, rate, scale, samples_scale, stats)?;
    }
    Ok(())
}

/// Parse `text`: the scene, or `None` when it is refused with a message
/// that names its field and gives a reason (counted in `stats`).
fn parse_scene_text(text: &str, stats: &RefCell<Stats>) -> Result<Option<Scene>, TestCaseError> {
    let parsed = guard("Scene::from_toml_str", text, || Scene::from_toml_str(text))?;
    match parsed {
        Err(e) => {
            let shown = e.to_string();
            if e.reason.trim().is_empty() || shown.trim().is_empty() {
                return Err(fail(text, format!("empty error message: {e:?}")));
            }
            if e.reason.trim_start().starts_with("(line") || e.reason.trim().len() < 8 {
                return Err(fail(text, format!("error without a reason: {e:?}")));
            }
            if !e.path.is_empty() && !shown.starts_with(&format!("{}: ", e.path)) {
                return Err(fail(
                    text,
                    format!("error does not name its field: {shown}"),
                ));
            }
            let key = if e.path.is_empty() {
                format!("toml: {}", category(&e.reason))
            } else {
                category(&shown)
            };
            *stats.borrow_mut().parse_refused.entry(key).or_default() += 1;
            Ok(None)
        }
        Ok(s) => Ok(Some(s)),
    }
}

/// A validated scene serialises and reads back as the same scene.
fn check_round_trip(text: &str, scene: &Scene) -> Result<(), TestCaseError> {
    let back = guard("Scene::to_toml_string", text, || scene.to_toml_string())?;
    match guard("re-parse", &back, || Scene::from_toml_str(&back))? {
        Ok(s2) if s2 == *scene => Ok(()),
        Ok(_) => Err(fail(text, format!("round trip changed the scene:\n{back}"))),
        Err(e) => Err(fail(text, format!("round trip refused: {e}\n{back}"))),
    }
}

/// Compile `scene` at `rate` \[Hz\]: the compiled scene, or `None` when it
/// is refused quickly with a reason (counted in `stats`, with an example).
fn compile_scene_text(
    text: &str,
    scene: &Scene,
    rate: f64,
    stats: &RefCell<Stats>,
) -> Result<Option<CompiledScene>, TestCaseError> {
    let t0 = Instant::now();
    let compiled = guard(&format!("compile at {rate} Hz"), text, || {
        compile_opts(
            scene,
            rate,
            Some(Switching::Exact),
            &CompileOptions::default(),
        )
    })?;
    let compiled = match compiled {
        Err(e) => {
            let msg = e.to_string();
            let reason = msg.trim_start_matches("cannot compile scene: ");
            if reason.trim().len() < 8 {
                return Err(fail(
                    text,
                    format!("compile error without a reason: {msg:?}"),
                ));
            }
            let elapsed = t0.elapsed().as_secs_f64();
            if elapsed > 5.0 {
                return Err(fail(
                    text,
                    format!("refusing took {elapsed:.1} s (must be quick): {msg}"),
                ));
            }
            let mut st = stats.borrow_mut();
            let cat = format!("{} ({})", category(reason), e.kind());
            *st.compile_refused.entry(cat.clone()).or_default() += 1;
            st.compile_examples
                .entry(cat)
                .or_insert_with(|| format!("{msg}\n{}", show(text)));
            return Ok(None);
        }
        Ok(c) => c,
    };
    let mut s = stats.borrow_mut();
    s.compiled += 1;
    s.dense_phases +=
        compiled.free.dense.is_some() as usize + compiled.contact.dense.is_some() as usize;
    Ok(Some(compiled))
}

/// Run `compiled` (at `rate` \[Hz\]) with each switching method it allows,
/// for the run lengths scaled by `scale` and `samples_scale`.
fn run_compiled(
    text: &str,
    compiled: &CompiledScene,
    rate: f64,
    scale: f64,
    samples_scale: f64,
    stats: &RefCell<Stats>,
) -> Result<(), TestCaseError> {
    let switchings = if compiled.switching == Switching::Exact {
        vec![Switching::Exact, Switching::OffsetRod]
    } else {
        // the compiler chose the rod (large dense fallback phase)
        vec![Switching::OffsetRod]
    };
    for sw in switchings {
        let mut c = compiled.clone();
        c.switching = sw;
        let pre = (PRE_SAMPLES as f64 * scale * samples_scale) as usize;
        let post = (POST_SAMPLES as f64 * scale * samples_scale) as usize;
        let r = guard(
            &format!("engine at {rate} Hz, {}", sw.as_str()),
            text,
            || run_engine(&c, pre, post),
        )?
        .map_err(|e| {
            fail(
                text,
                format!(
                    "engine run at {rate} Hz, switching {}: {e}\n--- compile summary ---\n{}",
                    sw.as_str(),
                    c.summary
                ),
            )
        })?;
        let mut s = stats.borrow_mut();
        s.runs += 1;
        s.samples += r.samples;
        s.contacts += r.contacts;
        s.worst_rise_over_bound = s.worst_rise_over_bound.max(r.worst);
    }
    Ok(())
}

// ------------------------------------------------------- value generators

/// TOML spelling of a float (`nan`, `inf`, `-inf` are TOML floats).
fn tf(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x == f64::INFINITY {
        "inf".into()
    } else if x == f64::NEG_INFINITY {
        "-inf".into()
    } else {
        format!("{x:e}")
    }
}

/// The degenerate values every numeric field is sometimes given.
const EXTREMES: &[f64] = &[
    0.0,
    -0.0,
    -1.0,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e300,
    -1e300,
    1e-300,
    5e-324,                  // smallest subnormal
    1.1125369292536007e-308, // a subnormal near the normal range
    f64::MAX,
    f64::MIN_POSITIVE,
];

/// A field value: mostly `normal`, sometimes an extreme, sometimes one of
/// the field's own edge values (limits and just past them).
fn num(normal: BoxedStrategy<f64>, edges: &'static [f64]) -> BoxedStrategy<f64> {
    num_w(normal, edges, 24)
}

/// [`num`] with `w_normal` normal draws per extreme and per edge draw.
fn num_w(normal: BoxedStrategy<f64>, edges: &'static [f64], w_normal: u32) -> BoxedStrategy<f64> {
    prop_oneof![
        w_normal => normal,
        1 => select(EXTREMES),
        1 => select(edges),
    ]
    .boxed()
}

fn logu(lo: f64, hi: f64) -> BoxedStrategy<f64> {
    (lo.ln()..hi.ln()).prop_map(f64::exp).boxed()
}

fn uni(lo: f64, hi: f64) -> BoxedStrategy<f64> {
    (lo..hi).boxed()
}

/// `Some` (key written) most of the time, `None` (key omitted: its default).
fn opt<T: std::fmt::Debug + Clone + 'static>(
    s: BoxedStrategy<T>,
    p_some: u32,
) -> BoxedStrategy<Option<T>> {
    prop_oneof![p_some => s.prop_map(Some), (100 - p_some) => Just(None)].boxed()
}

// ------------------------------------------------------- structured scenes

#[derive(Debug, Clone)]
struct GenMode {
    freq: f64,
    t60: Option<f64>,
    weights: Vec<f64>,
}

#[derive(Debug, Clone)]
enum GenObj {
    Modal {
        n_points: usize,
        /// weights per mode: `n_points + weight_len_delta` (usually 0).
        weight_len_delta: i64,
        modes: Vec<GenMode>,
    },
    Str {
        masses: i64,
        mass_kg: f64,
        spring: f64,
        alpha: Option<f64>,
        beta: Option<f64>,
        dashpots: Vec<(i64, f64)>,
        points: Vec<i64>,
    },
    Wall,
    /// A modal object with this many (ordinary) modes: far too many.
    HugeModal(usize),
}

#[derive(Debug, Clone)]
struct GenScene {
    version: i64,
    duration: Option<f64>,
    objects: Vec<GenObj>,
    /// 0: distinct names; 1: a duplicate; 2: an empty name.
    name_fault: u8,
    hammer: (f64, f64, Option<f64>, Option<f64>),
    /// object index, point index, fault (0 none, 1 unknown object,
    /// 2 missing point, 3 unknown point), k, c, switching.
    contact: GenContact,
    /// object index, point index, quantity, gain, pan.
    pickups: Vec<GenPickup>,
    approx: Option<GenApprox>,
    other_rate: f64,
    extra_key: bool,
    /// The scene's `level_db` (omitted: 0 dB).
    level_db: Option<f64>,
}

/// The contact: object index, point index, fault (0 none, 1 unknown
/// object, 2 missing point, 3 unknown point), k, c, switching.
type GenContact = (usize, usize, u8, f64, Option<f64>, Option<&'static str>);

/// The `[approximate]` table: max_freq_hz, nyquist_fraction,
/// quiet_below_db.
type GenApprox = (Option<f64>, Option<f64>, Option<f64>);

/// A pickup: object index, point index, quantity, gain, pan.
type GenPickup = (usize, usize, Option<&'static str>, Option<f64>, Option<f64>);

const POINT_NAMES: [&str; 3] = ["c", "p", "q"];
/// Stands for `c = 2 sqrt(k m_h)`: exactly critical damping, whose contact
/// with a wall is a Jordan block (the dense fallback path).
const CRITICAL_DAMPING: f64 = -1234.5;

fn mode_strategy() -> BoxedStrategy<GenMode> {
    (
        num_w(
            prop_oneof![8 => logu(20.0, 20_000.0), 1 => logu(20_000.0, 300_000.0)].boxed(),
            &[
                MAX_FREQ_HZ,
                1.0000001e7,
                MIN_FREQ_HZ,
                0.999e-3,
                22050.0,
                96000.0,
            ],
            80,
        ),
        opt(
            num_w(logu(0.005, 20.0), &[MIN_T60_S, 0.99e-6, 1e-5, 1e9], 80),
            80,
        ),
        prop::collection::vec(
            num_w(
                prop_oneof![6 => uni(-3.0, 3.0), 1 => Just(0.0)].boxed(),
                &[1e6, -1e6, 1.000001e6, 1e-6],
                80,
            ),
            4,
        ),
    )
        .prop_map(|(freq, t60, weights)| GenMode { freq, t60, weights })
        .boxed()
}

fn object_strategy() -> BoxedStrategy<GenObj> {
    let modes = prop_oneof![
        24 => prop::collection::vec(mode_strategy(), 1..=6),
        12 => prop::collection::vec(mode_strategy(), 7..=24),
        4 => prop::collection::vec(mode_strategy(), 25..=60),
        1 => Just(Vec::new()),
    ];
    let modal = (
        prop_oneof![40 => 1usize..=3, 1 => Just(0usize)],
        prop_oneof![60 => Just(0i64), 1 => Just(-1i64), 1 => Just(1i64)],
        modes,
    )
        .prop_map(|(n_points, weight_len_delta, modes)| GenObj::Modal {
            n_points,
            weight_len_delta,
            modes,
        });
    let masses = prop_oneof![
        // all of these are refused, by validation or by the compile budget,
        // before any expensive work
        30 => 1i64..=40,
        1 => select(&[0i64, -1, 1600, 2000, 2001, 100_000, i64::MAX][..]),
    ];
    let string = (
        masses,
        num(logu(1e-5, 1e-2), &[MIN_MASS_KG, MAX_MASS_KG]),
        num(logu(1e3, 1e6), &[1e-3, 1e12, MAX_STIFFNESS_N_PER_M]),
        opt(num(uni(0.0, 5.0), &[MAX_RAYLEIGH_ALPHA_PER_S]), 70),
        opt(num(uni(0.0, 1e-7), &[MAX_RAYLEIGH_BETA_S, 1e-3]), 70),
        prop::collection::vec(
            (
                prop_oneof![40 => 0i64..40, 1 => Just(-1i64)],
                num(uni(0.0, 1.0), &[MAX_DAMPING_N_S_PER_M, 1e3]),
            ),
            0..=2,
        ),
        prop::collection::vec(prop_oneof![40 => 0i64..40, 1 => Just(-1i64)], 1..=3),
    )
        .prop_map(
            |(masses, mass_kg, spring, alpha, beta, dashpots, points)| GenObj::Str {
                masses,
                mass_kg,
                spring,
                alpha,
                beta,
                dashpots,
                points,
            },
        );
    prop_oneof![
        60 => modal,
        25 => string,
        15 => Just(GenObj::Wall),
        1 => select(&[100_000usize, 4001, 3000, 1700][..]).prop_map(GenObj::HugeModal),
    ]
    .boxed()
}

/// The hammer: mass \[kg\], height \[m\], velocity [m/s], gravity [m/s^2].
fn hammer_strategy() -> impl Strategy<Value = (f64, f64, Option<f64>, Option<f64>)> {
    (
        num(
            logu(1e-4, 1.0),
            &[MIN_MASS_KG, MAX_MASS_KG, 0.5e-12, 1e-9, 1e4],
        ),
        num(
            prop_oneof![4 => uni(0.0, 0.05), 1 => Just(0.0)].boxed(),
            &[MAX_HEIGHT_M, 1e-12],
        ),
        opt(
            num(
                uni(-3.0, 1.0),
                &[MAX_SPEED_M_PER_S, -MAX_SPEED_M_PER_S, 1e-9],
            ),
            80,
        ),
        opt(
            num(
                prop_oneof![2 => Just(9.81), 1 => uni(0.0, 20.0)].boxed(),
                &[MAX_GRAVITY_M_PER_S2, 1e-9],
            ),
            60,
        ),
    )
}

/// The contact, as [`GenScene::contact`].
fn contact_strategy() -> impl Strategy<Value = GenContact> {
    (
        0usize..3,
        0usize..3,
        prop_oneof![40 => Just(0u8), 1 => Just(1u8), 1 => Just(2u8), 1 => Just(3u8)],
        num(
            logu(1e3, 1e8),
            &[1e12, MAX_STIFFNESS_N_PER_M, MIN_STIFFNESS_N_PER_M, 0.99e-3],
        ),
        opt(
            prop_oneof![
                15 => num(uni(0.0, 20.0), &[MAX_DAMPING_N_S_PER_M, 1e6, 1e-9]),
                1 => Just(CRITICAL_DAMPING),
            ]
            .boxed(),
            80,
        ),
        opt(
            prop_oneof![20 => Just("exact"), 20 => Just("offset-rod"), 1 => Just("bogus")].boxed(),
            50,
        ),
    )
}

/// A pickup, as [`GenPickup`].
fn pickup_strategy() -> impl Strategy<Value = GenPickup> {
    (
        0usize..3,
        0usize..3,
        opt(
            prop_oneof![20 => Just("velocity"), 20 => Just("displacement"), 1 => Just("loud")]
                .boxed(),
            70,
        ),
        opt(num(uni(-2.0, 2.0), &[MAX_GAIN, -MAX_GAIN]), 70),
        opt(num(uni(-1.0, 1.0), &[1.0, -1.0, 1.0000001]), 50),
    )
}

/// The `[approximate]` table, as [`GenScene::approx`].
fn approx_strategy() -> BoxedStrategy<Option<GenApprox>> {
    opt(
        (
            opt(num(logu(100.0, 20_000.0), &[1e-9]), 50),
            opt(num(uni(0.1, 1.5), &[1e-9, 1e9]), 50),
            opt(num(uni(-120.0, -10.0), &[0.0, -1e-9, -1e9]), 50),
        )
            .boxed(),
        12,
    )
}

/// Version, duration, objects and name fault of a [`GenScene`].
fn head_strategy() -> impl Strategy<Value = (i64, Option<f64>, Vec<GenObj>, u8)> {
    (
        prop_oneof![60 => Just(1i64), 1 => select(&[0i64, 2, -1][..])],
        opt(num(uni(0.1, 3.0), &[1e-9, MAX_DURATION_S]), 30),
        prop_oneof![
            1 => Just(Vec::new()),
            60 => prop::collection::vec(object_strategy(), 1..=3),
        ],
        prop_oneof![40 => Just(0u8), 1 => Just(1u8), 1 => Just(2u8)],
    )
}

fn scene_strategy() -> BoxedStrategy<GenScene> {
    (
        head_strategy(),
        hammer_strategy(),
        contact_strategy(),
        prop::collection::vec(pickup_strategy(), 0..=3),
        approx_strategy(),
        select(&[8000.0, 192_000.0][..]),
        prop_oneof![100 => Just(false), 1 => Just(true)],
        opt(
            num(
                uni(MIN_LEVEL_DB, MAX_LEVEL_DB),
                &[MIN_LEVEL_DB - 1e-9, MAX_LEVEL_DB + 1.0, -1e300],
            ),
            30,
        ),
    )
        .prop_map(
            |(
                (version, duration, objects, name_fault),
                hammer,
                contact,
                pickups,
                approx,
                other_rate,
                extra_key,
                level_db,
            )| GenScene {
                version,
                duration,
                objects,
                name_fault,
                hammer,
                contact,
                pickups,
                approx,
                other_rate,
                extra_key,
                level_db,
            },
        )
        .boxed()
}

/// Names of an object's points, in file order.
fn points_of(o: &GenObj) -> Vec<&'static str> {
    match o {
        GenObj::Modal { n_points, .. } => POINT_NAMES[..*n_points].to_vec(),
        GenObj::Str { points, .. } => POINT_NAMES[..points.len()].to_vec(),
        GenObj::Wall => Vec::new(),
        GenObj::HugeModal(_) => vec!["c", "p"],
    }
}

/// The name of object `i` (with the scene's name fault).
fn object_name(g: &GenScene, i: usize) -> String {
    match (g.name_fault, i) {
        (1, 1) => "o0".into(),
        (2, 0) => String::new(),
        _ => format!("o{i}"),
    }
}

fn render(g: &GenScene) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let _ = writeln!(t, "version = {}\nname = \"fuzz\"", g.version);
    if let Some(d) = g.duration {
        let _ = writeln!(t, "duration_s = {}", tf(d));
    }
    if let Some(l) = g.level_db {
        let _ = writeln!(t, "level_db = {}", tf(l));
    }
    for (i, o) in g.objects.iter().enumerate() {
        let _ = writeln!(t, "\n[[object]]\nname = {:?}", object_name(g, i));
        render_object(&mut t, o);
    }
    render_hammer(&mut t, g);
    render_contact(&mut t, g);
    render_pickups(&mut t, g);
    render_approx(&mut t, g);
    t
}

/// The `[[object]]` table's lines after its name.
fn render_object(t: &mut String, o: &GenObj) {
    use std::fmt::Write;
    match o {
        GenObj::Wall => {
            let _ = writeln!(t, "kind = \"wall\"");
        }
        GenObj::Modal {
            n_points,
            weight_len_delta,
            modes,
        } => {
            let pts: Vec<String> = POINT_NAMES[..*n_points]
                .iter()
                .map(|p| format!("{p:?}"))
                .collect();
            let _ = writeln!(t, "kind = \"modal\"\npoints = [{}]", pts.join(", "));
            let nw = (*n_points as i64 + weight_len_delta).clamp(0, 4) as usize;
            for m in modes {
                let _ = writeln!(t, "[[object.mode]]\nfreq_hz = {}", tf(m.freq));
                if let Some(x) = m.t60 {
                    let _ = writeln!(t, "t60_s = {}", tf(x));
                }
                let w: Vec<String> = m.weights[..nw].iter().map(|x| tf(*x)).collect();
                let _ = writeln!(t, "weights = [{}]", w.join(", "));
            }
        }
        GenObj::HugeModal(n) => {
            let _ = writeln!(t, "kind = \"modal\"\npoints = [\"c\", \"p\"]");
            for k in 0..*n {
                let f = 100.0 * (1.0 + (k % 997) as f64);
                let _ = writeln!(
                    t,
                    "[[object.mode]]\nfreq_hz = {f}\nt60_s = 1.0\nweights = [1.0, -0.5]"
                );
            }
        }
        GenObj::Str {
            masses,
            mass_kg,
            spring,
            alpha,
            beta,
            dashpots,
            points,
        } => {
            let _ = writeln!(
                t,
                "kind = \"string\"\nmasses = {masses}\nmass_kg = {}\nspring_n_per_m = {}",
                tf(*mass_kg),
                tf(*spring)
            );
            if let Some(a) = alpha {
                let _ = writeln!(t, "rayleigh_alpha_per_s = {}", tf(*a));
            }
            if let Some(b) = beta {
                let _ = writeln!(t, "rayleigh_beta_s = {}", tf(*b));
            }
            // indices are drawn in 0..40; fold them into the string
            // (-1 and the occasional too-large index stay faults)
            let fold = |j: i64| -> i64 {
                if j < 0 || *masses <= 0 {
                    j
                } else if j >= 38 {
                    *masses // one past the end
                } else {
                    j % *masses
                }
            };
            let d: Vec<String> = dashpots
                .iter()
                .map(|(m, c)| format!("{{ mass = {}, n_s_per_m = {} }}", fold(*m), tf(*c)))
                .collect();
            let _ = writeln!(t, "dashpots = [{}]", d.join(", "));
            let p: Vec<String> = points
                .iter()
                .enumerate()
                .map(|(k, j)| format!("{} = {}", POINT_NAMES[k], fold(*j)))
                .collect();
            let _ = writeln!(t, "points = {{ {} }}", p.join(", "));
        }
    }
}

/// The `[hammer]` table.
fn render_hammer(t: &mut String, g: &GenScene) {
    use std::fmt::Write;
    let (m, h, v, gr) = g.hammer;
    let _ = writeln!(t, "\n[hammer]\nmass_kg = {}\nheight_m = {}", tf(m), tf(h));
    if let Some(v) = v {
        let _ = writeln!(t, "velocity_m_per_s = {}", tf(v));
    }
    if let Some(gr) = gr {
        let _ = writeln!(t, "gravity_m_per_s2 = {}", tf(gr));
    }
    if g.extra_key {
        let _ = writeln!(t, "colour = \"red\"");
    }
}

/// The `[contact]` table.
fn render_contact(t: &mut String, g: &GenScene) {
    use std::fmt::Write;
    let m = g.hammer.0;
    let (oi, pi, fault, k, c, sw) = g.contact;
    let n_obj = g.objects.len().max(1);
    let cobj = g.objects.get(oi % n_obj);
    let _ = writeln!(
        t,
        "\n[contact]\nobject = {:?}",
        if fault == 1 || cobj.is_none() {
            "nowhere".to_string()
        } else {
            object_name(g, oi % n_obj)
        }
    );
    let cpts = cobj.map(points_of).unwrap_or_default();
    match fault {
        2 => {}
        3 => {
            let _ = writeln!(t, "point = \"elsewhere\"");
        }
        _ => {
            if !cpts.is_empty() {
                let _ = writeln!(t, "point = {:?}", cpts[pi % cpts.len()]);
            }
        }
    }
    let _ = writeln!(t, "stiffness_n_per_m = {}", tf(k));
    if let Some(c) = c {
        let c = if c == CRITICAL_DAMPING {
            2.0 * (k * m).sqrt()
        } else {
            c
        };
        let _ = writeln!(t, "damping_n_s_per_m = {}", tf(c));
    }
    if let Some(sw) = sw {
        let _ = writeln!(t, "switching = {sw:?}");
    }
}

/// The `[[pickup]]` tables.
fn render_pickups(t: &mut String, g: &GenScene) {
    use std::fmt::Write;
    let n_obj = g.objects.len().max(1);
    for (oi, pi, q, gain, pan) in &g.pickups {
        let Some(o) = g.objects.get(oi % n_obj) else {
            continue;
        };
        let pts = points_of(o);
        let point = if pts.is_empty() {
            "none"
        } else {
            pts[pi % pts.len()]
        };
        let _ = writeln!(
            t,
            "\n[[pickup]]\nobject = {:?}\npoint = {point:?}",
            object_name(g, oi % n_obj)
        );
        if let Some(q) = q {
            let _ = writeln!(t, "quantity = {q:?}");
        }
        if let Some(x) = gain {
            let _ = writeln!(t, "gain = {}", tf(*x));
        }
        if let Some(x) = pan {
            let _ = writeln!(t, "pan = {}", tf(*x));
        }
    }
}

/// The `[approximate]` table, if any.
fn render_approx(t: &mut String, g: &GenScene) {
    use std::fmt::Write;
    let huge = g.objects.iter().any(|o| matches!(o, GenObj::HugeModal(_)));
    // (no approximations next to a huge object: they could prune it down to
    // a size that compiles, for a long time)
    if let (Some((f, nf, q)), false) = (g.approx, huge) {
        let _ = writeln!(t, "\n[approximate]");
        if let Some(x) = f {
            let _ = writeln!(t, "max_freq_hz = {}", tf(x));
        }
        if let Some(x) = nf {
            let _ = writeln!(t, "nyquist_fraction = {}", tf(x));
        }
        if let Some(x) = q {
            let _ = writeln!(t, "quiet_below_db = {}", tf(x));
        }
    }
}

fn runner(cases: u32, seed: u64) -> TestRunner {
    TestRunner::new(Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 4096,
        ..Config::default()
    })
}

#[test]
fn structured_scenes_compile_and_run_stably_or_are_refused_clearly() {
    let stats = RefCell::new(Stats::default());
    let t0 = Instant::now();
    let n = cases(STRUCTURED_CASES);
    let seed = seed();
    let result = runner(n, seed).run(&scene_strategy(), |g| {
        let text = render(&g);
        set_current("structured", Some(&text));
        check_scene_text(&text, g.other_rate, 1.0, &stats)
    });
    set_current("structured", None);
    stats.borrow().print(
        &format!("structured scenes (seed {seed})"),
        t0.elapsed().as_secs_f64(),
    );
    if let Err(e) = result {
        panic!("seed {seed} (FUZZ_SCENES_SEED={seed} reruns it): {e}");
    }
    let s = stats.borrow();
    // the generator must exercise both outcomes substantially
    assert!(s.compiled >= s.cases / 10, "too few accepted scenes");
    assert!(s.parse_refused.values().sum::<usize>() >= s.cases / 10);
}

// ------------------------------------------------------ preset mutations

#[derive(Debug, Clone)]
enum Mutation {
    DeleteLine(usize),
    DuplicateLine(usize),
    SwapLines(usize, usize),
    /// Replace the value of the n-th `key = value` line.
    ReplaceValue(usize, &'static str),
    /// Cut the file at this fraction of its length.
    Truncate(f64),
    /// Put this character at this fraction of the file (replacing one).
    Garble(f64, char),
}

const VALUES: &[&str] = &[
    "nan",
    "+nan",
    "-nan",
    "inf",
    "-inf",
    "0",
    "0.0",
    "-0.0",
    "-1",
    "-1e300",
    "1e300",
    "1e-300",
    "5e-324",
    "1e5",
    "100000",
    "2001",
    "4001",
    "\"\"",
    "\"x\"",
    "[]",
    "[1.0]",
    "{}",
    "true",
    "99999999999999999999",
    "-9223372036854775808",
    "1.7976931348623157e308",
    "\"exact\"",
    "\"offset-rod\"",
];

fn mutation_strategy() -> BoxedStrategy<Mutation> {
    prop_oneof![
        3 => any::<usize>().prop_map(Mutation::DeleteLine),
        2 => any::<usize>().prop_map(Mutation::DuplicateLine),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        6 => (any::<usize>(), select(VALUES)).prop_map(|(i, v)| Mutation::ReplaceValue(i, v)),
        1 => (0.0..1.0f64).prop_map(Mutation::Truncate),
        1 => (0.0..1.0f64, select(&['=', '[', ']', '"', '\n', '#', '{', ',', '\0', 'x', '1'][..]))
            .prop_map(|(f, c)| Mutation::Garble(f, c)),
    ]
    .boxed()
}

fn char_floor(s: &str, f: f64) -> usize {
    let mut i = ((s.len() as f64 * f) as usize).min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn mutate(text: &str, muts: &[Mutation]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for m in muts {
        if lines.is_empty() {
            break;
        }
        let n = lines.len();
        match m {
            Mutation::DeleteLine(i) => {
                lines.remove(i % n);
            }
            Mutation::DuplicateLine(i) => {
                let l = lines[i % n].clone();
                lines.insert(i % n, l);
            }
            Mutation::SwapLines(a, b) => lines.swap(a % n, b % n),
            Mutation::ReplaceValue(i, v) => {
                let kv: Vec<usize> = (0..n)
                    .filter(|&j| {
                        let l = lines[j].trim_start();
                        !l.starts_with('#') && l.contains('=')
                    })
                    .collect();
                if !kv.is_empty() {
                    let j = kv[i % kv.len()];
                    let l = &lines[j];
                    // inline tables: replace the first value inside them
                    let eq = l.find('=').unwrap();
                    let rest = &l[eq + 1..];
                    let end = rest.find([',', '}']).map_or(l.len(), |k| eq + 1 + k);
                    lines[j] = format!("{}= {v}{}", &l[..eq], &l[end..]);
                }
            }
            Mutation::Truncate(f) => {
                let mut s = lines.join("\n");
                s.truncate(char_floor(&s, *f));
                lines = s.lines().map(str::to_string).collect();
            }
            Mutation::Garble(f, c) => {
                let mut s = lines.join("\n");
                let i = char_floor(&s, *f);
                if i < s.len() {
                    let next = s[i..].chars().next().map_or(0, char::len_utf8);
                    s.replace_range(i..i + next, &c.to_string());
                } else {
                    s.push(*c);
                }
                lines = s.lines().map(str::to_string).collect();
            }
        }
    }
    lines.join("\n")
}

fn presets() -> Vec<(String, String)> {
    let dir = preset_path("x").parent().unwrap().to_path_buf();
    let mut v: Vec<(String, String)> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| {
            (
                p.file_stem().unwrap().to_string_lossy().to_string(),
                std::fs::read_to_string(&p).unwrap(),
            )
        })
        // the presets of several contacts are the several-contact engine's
        // (mutated in tests/multi_bodies.rs)
        .filter(|(_, text)| {
            modal_contact::scene::Scene::from_toml_str(text).is_ok_and(|s| !s.several_contacts())
        })
        .collect();
    v.sort();
    assert!(v.len() >= 5, "presets not found in {}", dir.display());
    v
}

#[test]
fn mutated_presets_compile_and_run_stably_or_are_refused_clearly() {
    let presets = presets();
    let stats = RefCell::new(Stats::default());
    let t0 = Instant::now();
    let n = cases(MUTATION_CASES);
    let strategy = (
        0..presets.len(),
        prop::collection::vec(mutation_strategy(), 0..=3),
        select(&[8000.0, 192_000.0][..]),
    );
    let seed = seed();
    let result = runner(n, seed).run(&strategy, |(pi, muts, other_rate)| {
        let text = mutate(&presets[pi].1, &muts);
        set_current("mutations", Some(&text));
        check_scene_text(&text, other_rate, 0.5, &stats)
    });
    set_current("mutations", None);
    stats.borrow().print(
        &format!("mutated presets (seed {seed})"),
        t0.elapsed().as_secs_f64(),
    );
    if let Err(e) = result {
        panic!("seed {seed} (FUZZ_SCENES_SEED={seed} reruns it): {e}");
    }
    let s = stats.borrow();
    assert!(s.compiled >= s.cases / 10, "too few accepted mutations");
}

// ------------------------------------------------------------ the budget

fn modal_text(n: usize, coupled_every: usize) -> String {
    let mut t = String::from(
        "version = 1\nname = \"big\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\", \"p\"]\n",
    );
    for i in 0..n {
        let f = 100.0 * 180f64.powf(i as f64 / n as f64);
        let w = if i % coupled_every == 0 { 1.0 } else { 0.0 };
        t += &format!("[[object.mode]]\nfreq_hz = {f:e}\nt60_s = 1.0\nweights = [{w:e}, 0.5]\n");
    }
    t += "[hammer]\nmass_kg = 0.03\nheight_m = 0.0\nvelocity_m_per_s = -1\n\
          [contact]\nobject = \"o\"\npoint = \"c\"\nstiffness_n_per_m = 1e6\n\
          [[pickup]]\nobject = \"o\"\npoint = \"p\"\n";
    t
}

fn string_text(masses: usize) -> String {
    format!(
        "version = 1\nname = \"big\"\n[[object]]\nname = \"s\"\nkind = \"string\"\nmasses = {masses}\n\
         mass_kg = 1e-4\nspring_n_per_m = 1e5\npoints = {{ c = 0, p = 1 }}\n\
         [hammer]\nmass_kg = 0.002\nheight_m = 0.001\nvelocity_m_per_s = -1\n\
         [contact]\nobject = \"s\"\npoint = \"c\"\nstiffness_n_per_m = 2e4\n\
         [[pickup]]\nobject = \"s\"\npoint = \"p\"\n"
    )
}

/// Scenes too big to compile are refused at once with a message that says
/// what the estimate is, what the limit is, and what to do; scenes over the
/// scene-file limits are refused by validation.
#[test]
fn too_big_scenes_are_refused_fast_with_a_message() {
    over_the_file_limits_is_refused_by_validation();
    over_the_compile_budget_is_refused_before_any_work();
    the_budget_is_an_option();
    equal_modes_over_the_general_budget_are_refused_saying_both();
}

/// Over the scene-file limits: validation refuses (after parsing the text).
fn over_the_file_limits_is_refused_by_validation() {
    for (label, text, want) in [
        (
            "1e5 modes",
            modal_text(100_000, 1),
            "object[0].mode: 100000 modes is more than the limit of 4000",
        ),
        (
            "1e5 string masses",
            string_text(100_000),
            "object[0].masses: must be in 1..=2000, got 100000",
        ),
    ] {
        let t0 = Instant::now();
        let e = Scene::from_toml_str(&text).unwrap_err().to_string();
        let dt = t0.elapsed().as_secs_f64();
        println!(
            "{label}: refused in {dt:.3} s ({} bytes of TOML): {e}",
            text.len()
        );
        assert_eq!(e, want);
        assert!(dt < 5.0, "{label}: refusing took {dt} s");
    }
}

/// Valid scene files, over the compile budget: refused before any O(d^3)
/// work (each of these would take minutes and gigabytes).
fn over_the_compile_budget_is_refused_before_any_work() {
    for (label, text, want) in [
        (
            "2000-mass string",
            string_text(2000),
            "use fewer masses (object[0].masses)",
        ),
        (
            "1600-mass string",
            string_text(1600),
            "use fewer masses (object[0].masses)",
        ),
        (
            "1700 coupled modes",
            modal_text(1700, 1),
            "[approximate] nyquist_fraction",
        ),
        (
            "4000 modes, 1 in 10 coupled",
            modal_text(4000, 10),
            "exceeds the limit 4002",
        ),
        (
            "2000 modes, 1 in 10 coupled",
            modal_text(2000, 10),
            "estimated memory",
        ),
    ] {
        let scene = Scene::from_toml_str(&text).unwrap();
        let t0 = Instant::now();
        let e = compile_opts(&scene, 44100.0, None, &CompileOptions::default())
            .unwrap_err()
            .to_string();
        let dt = t0.elapsed().as_secs_f64();
        println!("{label}: refused in {dt:.4} s: {e}");
        assert!(e.contains(want), "{label}: {e}");
        assert!(dt < 5.0, "{label}: refusing took {dt} s");
    }
}

/// The budget is an option: a tiny one refuses a small scene, which the
/// default compiles, and the message says how to raise it.
fn the_budget_is_an_option() {
    let small = Scene::from_toml_str(&modal_text(20, 1)).unwrap();
    let tiny = CompileOptions {
        budget: CompileBudget {
            max_flops: 1e5,
            max_bytes: f64::INFINITY,
        },
        ..CompileOptions::default()
    };
    let e = compile_opts(&small, 44100.0, None, &tiny)
        .unwrap_err()
        .to_string();
    println!("20 modes under a 1e5-flop budget: {e}");
    assert!(
        e.contains("estimated work") && e.contains("limit 1.0e5"),
        "{e}"
    );
    assert!(e.contains("CompileOptions::budget"), "{e}");
    compile_opts(&small, 44100.0, None, &CompileOptions::default()).unwrap();
}

/// The budget admits a modal object for the rank-one secular route. If
/// that route fails (two equal modes), the general eigensolver takes over
/// only if it fits the budget too; otherwise the scene is refused, saying
/// both.
fn equal_modes_over_the_general_budget_are_refused_saying_both() {
    let mut freq_lines = 0;
    let twins: String = modal_text(20, 1)
        .lines()
        .map(|l| {
            if l.starts_with("freq_hz") {
                freq_lines += 1;
                if freq_lines == 2 {
                    return "freq_hz = 1e2\n".to_string(); // as the first mode
                }
            }
            format!("{l}\n")
        })
        .collect();
    let scene = Scene::from_toml_str(&twins).unwrap();
    let cost = CompileCost::estimate(&scene.object[0], Some("c"), false, true);
    let between = CompileOptions {
        budget: CompileBudget {
            max_flops: 0.5 * (cost.flops + cost.general().flops),
            max_bytes: f64::INFINITY,
        },
        ..CompileOptions::default()
    };
    assert!(cost.flops < between.budget.max_flops && !cost.general_fits(&between.budget));
    let e = compile_opts(&scene, 44100.0, None, &between)
        .unwrap_err()
        .to_string();
    println!("equal modes, budget for the secular route only: {e}");
    assert!(
        e.contains("degenerate") && e.contains("over the compile budget"),
        "{e}"
    );
    let c = compile_opts(&scene, 44100.0, None, &CompileOptions::default()).unwrap();
    assert!(
        c.contact
            .diag
            .method
            .contains("faer; rank-one secular eigenvectors refused"),
        "{}",
        c.summary
    );
}

// ----------------------------------------------- regressions the fuzzer found

fn one_mode_scene(freq: f64, w: f64, k: f64, c: f64, m: f64, g: f64, extra: &str) -> String {
    format!(
        "version = 1\nname = \"r\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\"]\n\
         [[object.mode]]\nfreq_hz = {freq:e}\nt60_s = 1.0\nweights = [{w:e}]\n\
         [hammer]\nmass_kg = {m:e}\nheight_m = 0.0\nvelocity_m_per_s = -0.5\ngravity_m_per_s2 = {g:e}\n\
         [contact]\nobject = \"o\"\npoint = \"c\"\nstiffness_n_per_m = {k:e}\ndamping_n_s_per_m = {c:e}\n\
         [[pickup]]\nobject = \"o\"\npoint = \"c\"\n{extra}"
    )
}

fn wall_text(m: f64, k: f64, c: f64) -> String {
    format!(
        "version = 1\nname = \"w\"\n[[object]]\nname = \"floor\"\nkind = \"wall\"\n\
         [hammer]\nmass_kg = {m:e}\nheight_m = 0.0\nvelocity_m_per_s = -1.0\n\
         [contact]\nobject = \"floor\"\nstiffness_n_per_m = {k:e}\ndamping_n_s_per_m = {c:e}\n"
    )
}

fn compile_at(text: &str, rate: f64) -> Result<CompiledScene, String> {
    let scene = Scene::from_toml_str(text).map_err(|e| e.to_string())?;
    compile_opts(&scene, rate, None, &CompileOptions::default()).map_err(|e| e.to_string())
}

/// Each scene here once broke a rule; each now compiles into a stable run
/// or is refused with a message that says why.
#[test]
fn regressions_found_by_the_fuzzer() {
    let stats = RefCell::new(Stats::default());
    let check = |text: &str, rate: f64| {
        check_scene_text(text, rate, 1.0, &stats).unwrap_or_else(|e| panic!("{e}"));
    };
    stiff_undamped_wall_keeps_its_exact_blocks(&check);
    object_pruned_to_a_wall_compiles(&check);
    stiff_damper_on_a_tiny_mass(&check);
    stiff_critical_wall_avoids_slow_partial_steps(&check);
    hammer_at_rest_on_a_stiff_wall_under_gravity(&check);
    presets_pass_the_compile_checks_at_common_rates();
    overflowing_products_are_refused_by_validation();
}

/// Runs a scene text through [`check_scene_text`] at a rate \[Hz\], panicking
/// on a failure.
type Check<'a> = dyn Fn(&str, f64) + 'a;

fn stiff_undamped_wall_keeps_its_exact_blocks(check: &Check) {
    // 1. A stiff undamped hammer on a wall (|A| h = 4.7e3 at 192 kHz): the
    // decomposition's cross-check against the Pade exp (itself off by ~|A h| u)
    // rejected the exact closed-form blocks and took a non-passive dense
    // propagator. Now the blocks are kept.
    let t = wall_text(1.2248e-3, 1e15, 0.0);
    let c = compile_at(&t, 192_000.0).unwrap();
    println!(
        "stiff wall at 192 kHz: {}",
        c.summary.lines().nth(3).unwrap()
    );
    assert!(c.contact.dense.is_none(), "{}", c.summary);
    check(&t, 192_000.0);
}

fn object_pruned_to_a_wall_compiles(check: &Check) {
    // 2. `[approximate] max_freq_hz` below every mode prunes the object to a
    // rigid wall; compiling then failed with "no point c".
    let t = one_mode_scene(
        958.0,
        1.2,
        1.5e3,
        14.6,
        0.32,
        9.81,
        "[approximate]\nmax_freq_hz = 850.0\n",
    );
    let c = compile_at(&t, 44100.0).unwrap();
    assert!(
        c.summary.contains("(wall, 0 degrees of freedom)"),
        "{}",
        c.summary
    );
    check(&t, 8000.0);
}

fn stiff_damper_on_a_tiny_mass(check: &Check) {
    // 3. A non-passive dense propagator (effective mass 1e-12 kg at the
    // contact with a 13 N s/m damper at 8 kHz: |A| h = 1.6e9, sigma_max - 1 =
    // 4.5e-8) was accepted and gained energy. Then refused as not passive
    // (the general eigensolver's blocks gave sigma_max - 1 = 1.7e-13); the
    // rank-one secular route now decomposes it passively (eigenvalues
    // -c / m_eff = -1.3e13, -k / c = -77, and the hammer swinging on the
    // mode's 1.6e-8 N/m at 1.3e-4 rad/s), and it runs stably.
    let t = one_mode_scene(20.0, 1e6, 1e3, 12.95, 1.0, 0.0, "");
    let c = compile_at(&t, 8000.0).unwrap();
    let d = &c.contact.diag;
    println!(
        "stiff damper on a 1e-12 kg point: {}",
        c.summary.lines().nth(3).unwrap()
    );
    assert!(d.method.contains("secular"), "{}", c.summary);
    assert!(
        d.sigma_max - 1.0 <= 16.0 * 4.0 * d.kappa * U,
        "{}",
        c.summary
    );
    check(&t, 8000.0);

    // 7. Still refused as not passive, saying why: a 1e-12 kg contact point
    // with a 2e3 N s/m damper (|A| h = 2.5e11 at 8 kHz), where neither
    // route's blocks are accurate enough to be passive in f64.
    let t = "version = 1\nname = \"fuzz\"\n[[object]]\nname = \"o0\"\nkind = \"modal\"\n\
             points = [\"c\", \"p\", \"q\"]\n\
             [[object.mode]]\nfreq_hz = 1.635220668045858e2\nweights = [4.829829869729381e-1, 9.538949415789817e-1, 0e0]\n\
             [[object.mode]]\nfreq_hz = 1.7849759385500585e2\nt60_s = 5.270258998123533e0\n\
             weights = [-2.791380621140284e0, 6.146409419843188e-1, 2.677033643378004e0]\n\
             [[object.mode]]\nfreq_hz = 4.545888511119805e1\nt60_s = 1.452973641070041e-1\n\
             weights = [-1.1488949249545708e0, -1e6, 0e0]\n\
             [[object.mode]]\nfreq_hz = 1.0223013063120637e3\nt60_s = 8.423388844601357e-2\n\
             weights = [1.5086467177698417e0, 2.862583060139188e0, -1.4175779382694346e-2]\n\
             [hammer]\nmass_kg = 1.0665131572074324e-1\nheight_m = 2.626874853153423e-2\n\
             velocity_m_per_s = 8.850335853218309e-1\ngravity_m_per_s2 = 9.81e0\n\
             [contact]\nobject = \"o0\"\npoint = \"p\"\nstiffness_n_per_m = 9.105092367774893e6\n\
             damping_n_s_per_m = 1.9708577632920035e3\n\
             [[pickup]]\nobject = \"o0\"\npoint = \"q\"\n";
    let e = compile_at(t, 8000.0).unwrap_err();
    println!("non-passive contact phase: {e}");
    assert!(
        e.contains("contact phase") && e.contains("could create energy"),
        "{e}"
    );
    check(t, 8000.0);
}

fn stiff_critical_wall_avoids_slow_partial_steps(check: &Check) {
    // 4. A dense-fallback phase (critically damped stiff wall contact) with
    // |A| h in the hundreds: exact switching's Taylor partial steps made a
    // sample take minutes. Now the compiler either uses the offset rod for it
    // or refuses the phase as not passive.
    let (m, k) = (0.01f64, 1e12f64);
    let t = wall_text(m, k, 2.0 * (k * m).sqrt());
    match compile_at(&t, 44100.0) {
        Ok(c) => {
            println!("stiff critical wall: {}", c.summary.lines().nth(3).unwrap());
            if c.contact.dense.is_some() {
                assert_eq!(c.switching, Switching::OffsetRod, "{}", c.summary);
            }
        }
        Err(e) => {
            println!("stiff critical wall: {e}");
            assert!(e.contains("not passive"), "{e}");
        }
    }
    check(&t, 192_000.0);
}

fn hammer_at_rest_on_a_stiff_wall_under_gravity(check: &Check) {
    // 6. A 1 kg hammer released at rest on the surface of a stiff wall (8e11
    // N/m, static sag 1.2e-11 m) under gravity: its energy starts at exactly
    // 0 and after one free-fall sample is 0.5 v^2 + g x, two terms of 7.5e-7 J
    // that cancel to round-off (1e-22 J). The check measured that rise
    // against the old state's scale only (the sag's 2.4e-10 J) and failed;
    // it now counts the new state's terms too.
    let t = wall_text(1.0, 8e11, 0.0).replace(
        "velocity_m_per_s = -1.0",
        "velocity_m_per_s = 0.0\ngravity_m_per_s2 = 9.81",
    );
    check(&t, 8000.0);
}

/// The new compile checks (budget, passivity) refuse no preset at any
/// common host rate.
fn presets_pass_the_compile_checks_at_common_rates() {
    for (name, text) in presets() {
        for rate in [8000.0, 22050.0, 44100.0, 48000.0, 96000.0, 192_000.0] {
            compile_at(&text, rate).unwrap_or_else(|e| panic!("{name} at {rate} Hz: {e}"));
        }
    }
}

fn overflowing_products_are_refused_by_validation() {
    // 5. Values whose products overflow are refused by validation, naming
    // the field: a subnormal contact stiffness under gravity (static
    // equilibrium m g / k = inf), a 1e-300 kg hammer (c / m = inf), gravity
    // 1e300 (energy m g x = inf).
    for (text, want) in [
        (
            one_mode_scene(20.0, 1.0, 5e-324, 0.0, 1.0, 9.81, ""),
            "contact.stiffness_n_per_m: must be >= 1e-3, got 5e-324",
        ),
        (
            one_mode_scene(200.0, 1.0, 8e5, 1e6, 1e-300, 9.81, ""),
            "hammer.mass_kg: must be >= 1e-12, got 1e-300",
        ),
        (
            one_mode_scene(200.0, 1.0, 1e3, 0.0, 1.0, 1e300, ""),
            "hammer.gravity_m_per_s2: must be <= 1e4, got 1e300",
        ),
    ] {
        assert_eq!(Scene::from_toml_str(&text).unwrap_err().to_string(), want);
    }
}
