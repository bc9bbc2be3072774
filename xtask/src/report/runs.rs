//! Running the engine and the competitors on the output grid and timing
//! their stepping loops (the metrics are `modal_testkit::metrics`, shared
//! with the tests).

use modal_contact::compile::CompiledScene;
use modal_contact::engine::EngineState;
use modal_testkit::competitors::{simulate, Method, PwlSystem, SimOutput};
use modal_testkit::metrics::{ContactLog, Interval};
use std::hint::black_box;
use std::time::Instant;

/// Everything a run produces on the output grid (row `j` = time `j / rate`).
#[derive(Debug, Clone, Default)]
pub(crate) struct Trajectory {
    /// Pickup signal (engine: left channel; competitors: gain-weighted sum).
    pub pickup: Vec<f64>,
    /// Hammer contact-face height \[m\].
    pub x_hammer: Vec<f64>,
    /// Total energy \[J\].
    pub energy: Vec<f64>,
    /// Contacts (start, end) \[s\]; one still open at the end of the run
    /// ends there.
    pub contacts: Vec<Interval>,
    /// Non-finite state or energy above 1e6 E0 (the rest is NaN).
    pub diverged: bool,
    /// Energy scale `E0 = |E(0)| + m_h g |x_h(0)|` \[J\].
    pub e0: f64,
    /// Largest per-step energy increase / E0 (engine: per sample;
    /// competitors: per fine step).
    pub max_step_gain: f64,
    /// Engine only: what exact switching did, and the wall time per sample
    /// of the observed run.
    pub engine_note: String,
}

impl Trajectory {
    /// Largest increase of the energy between two output samples / E0.
    pub(crate) fn max_sample_gain(&self) -> f64 {
        self.energy
            .windows(2)
            .map(|w| (w[1] - w[0]) / self.e0)
            .filter(|x| x.is_finite())
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Last finite energy.
    pub(crate) fn e_end(&self) -> f64 {
        self.energy
            .iter()
            .rev()
            .find(|e| e.is_finite())
            .copied()
            .unwrap_or(f64::NAN)
    }
}

/// Energy scale used by every run: `|E(0)| + m_h g |x_h(0)|`.
fn e_scale(e0: f64, m_h: f64, g: f64, x_h0: f64) -> f64 {
    let s = e0.abs() + m_h * g * x_h0.abs();
    if s > 0.0 && s.is_finite() {
        s
    } else {
        1.0
    }
}

/// Run the engine for `n` samples with per-sample observation (O(N^2) per
/// sample: offline only). Contact times come from the switch log after each
/// tick (`t_n + after_s`).
pub(crate) fn run_engine(sc: &CompiledScene, n: usize) -> Trajectory {
    let t_run = Instant::now();
    let mut st = EngineState::new(sc);
    let first = st.observe(sc);
    let e0 = e_scale(first.energy, sc.m_h, sc.g, sc.hammer_x0);
    let limit = 1e6 * e0;
    let mut tr = Trajectory {
        pickup: Vec::with_capacity(n),
        x_hammer: Vec::with_capacity(n),
        energy: Vec::with_capacity(n),
        e0,
        max_step_gain: f64::NEG_INFINITY,
        ..Default::default()
    };
    let mut log = ContactLog::default();
    let mut prev_e = first.energy;
    for i in 0..n {
        let t_n = i as f64 / sc.rate_hz;
        let (out, obs) = st.tick_observed(sc);
        if !(out[0].is_finite() && obs.energy.is_finite() && obs.energy <= limit) {
            tr.diverged = true;
            break;
        }
        if i > 0 {
            tr.max_step_gain = tr.max_step_gain.max((obs.energy - prev_e) / e0);
        }
        prev_e = obs.energy;
        tr.pickup.push(out[0]);
        tr.x_hammer.push(obs.x_hammer);
        tr.energy.push(obs.energy);
        for ev in st.switch_events() {
            // an inconsistent log is the engine's counters' business
            let _ = log.record(t_n + ev.after_s, ev.entered);
        }
    }
    // the energy after the last step
    if !tr.diverged {
        let obs = st.observe(sc);
        if obs.energy.is_finite() {
            tr.max_step_gain = tr.max_step_gain.max((obs.energy - prev_e) / e0);
        }
    }
    tr.contacts = log.finish(Some(n as f64 / sc.rate_hz));
    for v in [&mut tr.pickup, &mut tr.x_hammer, &mut tr.energy] {
        v.resize(n, f64::NAN);
    }
    if tr.max_step_gain == f64::NEG_INFINITY {
        tr.max_step_gain = 0.0;
    }
    let x = &st.exact_stats;
    tr.engine_note = format!(
        "{:.1} us/sample observed; located {}, capped {}, rod fallbacks {}, grazing {}, uncertified {}",
        t_run.elapsed().as_secs_f64() / n.max(1) as f64 * 1e6,
        x.located,
        x.capped,
        x.rod_fallbacks,
        x.grazing,
        x.uncertified
    );
    tr
}

/// The engine at `factor` times the rate, sampled every `factor`-th output
/// (contacts keep their located times).
pub(crate) fn run_engine_subsampled(
    sc_fine: &CompiledScene,
    n: usize,
    factor: usize,
) -> Trajectory {
    let mut tr = run_engine(sc_fine, n * factor);
    for v in [&mut tr.pickup, &mut tr.x_hammer, &mut tr.energy] {
        *v = v.iter().step_by(factor).copied().collect();
    }
    tr
}

/// A competitor's output as a [`Trajectory`].
pub(crate) fn from_sim(sys: &PwlSystem, out: SimOutput) -> Trajectory {
    let e_first = out.energy.first().copied().unwrap_or(f64::NAN);
    Trajectory {
        e0: e_scale(e_first, sys.m_h, sys.g, sys.x_h0),
        max_step_gain: out.max_energy_increase,
        diverged: out.diverged,
        pickup: out.pickup,
        x_hammer: out.x_hammer,
        energy: out.energy,
        contacts: out
            .contacts
            .into_iter()
            .map(|(a, b)| (a, Some(b)))
            .collect(),
        engine_note: String::new(),
    }
}

/// Median of a small sample.
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Clear the upper halves of the AVX registers (`vzeroupper`) before a timed
/// loop. Everything in the report runs on one thread, and compiling a small
/// scene (measured: <= 15 modes, contact system <= 32 states) returns with
/// the upper halves dirty; until the next `vzeroupper` every legacy-SSE
/// instruction (the engine's scalar code) then runs ~4x slower (0.42 against
/// 0.10 us per sample for 10 modes, and the next scene's run as well). The
/// plugin compiles on a worker thread, so its audio thread never sees this.
fn clear_avx_upper() {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx")]
        unsafe fn zeroupper() {
            std::arch::x86_64::_mm256_zeroupper();
        }
        if std::is_x86_feature_detected!("avx") {
            // SAFETY: AVX was detected on this CPU just above.
            unsafe { zeroupper() }
        }
    }
}

/// Repetitions for timing: `reps` unless one run already took longer than
/// `slow_s`, then 3.
pub struct TimingPlan {
    pub reps: usize,
    pub slow_s: f64,
}

/// Seconds of one run of the engine's stepping loop over `n` samples (`tick`
/// only: no observation, no allocation; state built outside the timed
/// region).
fn time_engine_once(sc: &CompiledScene, n: usize) -> f64 {
    let mut st = EngineState::new(sc);
    clear_avx_upper();
    let t0 = Instant::now();
    let mut acc = 0.0;
    for _ in 0..n {
        let o = st.tick(sc);
        acc += o[0];
    }
    black_box(acc);
    t0.elapsed().as_secs_f64()
}

/// Median seconds of the engine's stepping loop ([`time_engine_once`]) and
/// the repetitions.
pub(crate) fn time_engine(sc: &CompiledScene, n: usize, plan: &TimingPlan) -> (f64, usize) {
    let mut times = Vec::new();
    while times.len() < plan.reps {
        times.push(time_engine_once(sc, n));
        if times.len() >= 3 && times[0] > plan.slow_s {
            break;
        }
    }
    let k = times.len();
    (median(times), k)
}

/// Two scenes timed in alternation (a, b, a, b, ...; same repetitions as
/// [`time_engine`]), so both see the same load of a shared machine: (median
/// seconds of `a`, of `b`, median of the per-pair ratios `a / b`,
/// repetitions).
pub(crate) fn time_engine_pair(
    a: &CompiledScene,
    b: &CompiledScene,
    n: usize,
    plan: &TimingPlan,
) -> (f64, f64, f64, usize) {
    let (mut ta, mut tb, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    while ta.len() < plan.reps {
        let (x, y) = (time_engine_once(a, n), time_engine_once(b, n));
        ta.push(x);
        tb.push(y);
        ratio.push(x / y);
        if ta.len() >= 3 && ta[0].max(tb[0]) > plan.slow_s {
            break;
        }
    }
    let k = ta.len();
    (median(ta), median(tb), median(ratio), k)
}

/// Simulate a competitor, timing the whole `simulate` call minus its setup
/// (the same call with one output row: allocations and, for the trapezoid,
/// the two LU solves). Returns (output of the first run, median seconds,
/// repetitions). The timed loop still includes `simulate`'s per-fine-step
/// energy evaluation and contact bookkeeping (O(nnz) like a step; there is no
/// public step-only API).
pub(crate) fn time_competitor(
    sys: &PwlSystem,
    m: Method,
    rate: f64,
    os: usize,
    n: usize,
    plan: &TimingPlan,
) -> (SimOutput, f64, usize) {
    let mut setups = Vec::new();
    for _ in 0..3 {
        clear_avx_upper();
        let t0 = Instant::now();
        black_box(simulate(sys, m, rate, os, 1));
        setups.push(t0.elapsed().as_secs_f64());
    }
    let setup = median(setups);
    let mut times = Vec::new();
    let mut first = None;
    while times.len() < plan.reps {
        clear_avx_upper();
        let t0 = Instant::now();
        let out = black_box(simulate(sys, m, rate, os, n));
        times.push((t0.elapsed().as_secs_f64() - setup).max(0.0));
        if first.is_none() {
            first = Some(out);
        }
        if times.len() >= 3 && times[0] > plan.slow_s {
            break;
        }
        // a diverged run stops early: its time is not a cost
        if first.as_ref().is_some_and(|o| o.diverged) && times.len() >= 3 {
            break;
        }
    }
    let k = times.len();
    (first.expect("at least one run"), median(times), k)
}
