//! Exact switching (beyond the paper): every instant inside a sample where
//! the event function crosses zero is found, in time order, on the exact
//! phase solution, and the sample is consumed piecewise: `exp(A_1 tau)`,
//! switch, `exp(A_2 (tau' - tau))`, switch, ... (docs/numerics.md, "Exact
//! switching" and "Finding every crossing").
//!
//! Event function `phi(tau)`: in flight `phi = x_h - x_c` (contact starts
//! when it crosses 0 downwards), in contact `phi = p_eff` (contact ends when
//! it crosses 0 downwards). A contact never continues past its first release
//! crossing, so a tensile spring force never acts outside the exact contact
//! intervals.
//!
//! # The model
//!
//! From the instant `t0` where a search starts, `phi(t0 + tau)` is a known
//! finite sum ([`crate::compile::event`]): the exactly polynomial part `c`
//! (the hammer's parabola in flight, a constant in contact), one damped
//! oscillation `Re[C_k e^{mu_k tau}]` per oscillatory block with complex
//! amplitude `C_k` taken from the state in O(1), and `r_k exp(G_k tau) s_k`
//! for the few blocks with real eigenvalues. The oscillatory blocks are
//! split by how far they turn over a sample:
//!
//! - *slow* (`|mu| h <= THETA_SLOW`): summed into one Taylor polynomial about
//!   `t0` whose truncation error is below rounding (degree chosen for it),
//!   so their sum and its derivatives cost O(degree) anywhere in the sample;
//! - *fast*: evaluated exactly (one exp and one sin/cos each) wherever the
//!   search looks.
//!
//! # Certified isolation
//!
//! The search bisects `[t0, t_end]`, left to right. On a node `[a, a + w]`
//! every fast block with `|mu| w <= THETA_RESOLVED`, every slow block and the
//! polynomial part are *resolved*: their exact value, slope and curvature at
//! `a` give a quadratic `Q` with the cubic remainder `|mu|^3 |C| e^{m a}
//! w^3 / 6`; every other block is *unresolved* and enters only through its
//! exact envelope `|C| e^{m a}` (slope `|mu| |C| e^{m a}`). From these bounds
//! a node is
//!
//! - root-free: `phi > 0` on the whole node (or `phi` increases from a
//!   positive value);
//! - a certain, unique first root: `phi' < 0` on the node and `phi(a + w) < 0`
//!   (with `phi(a) >= 0` known from the nodes before it); the root is then
//!   refined on the model to [`ROOT_ULPS`] ulps of the sample;
//! - neutral: `|phi|` is within rounding of zero on the whole node (a
//!   grazing touch: both phases give the same motion to rounding), or the
//!   node is below the root resolution: decided by the sign of `phi` at its
//!   end;
//! - or split in two.
//!
//! So the work per sample is bounded by the phase's own time scales: nodes
//! shrink only until the fast blocks whose amplitude can still change the
//! sign are resolved (`w ~ 1 / |mu|`), and below that only next to a root
//! or a tangency, where the bisection descends along one path to the root
//! resolution (at most ~50 levels). There is no depth limit. The switches of
//! a sample are capped at [`MAX_SWITCHES_PER_SAMPLE`]: in exact arithmetic a
//! switch hands the new phase a `phi` that rises, but when the two phases'
//! decompositions disagree on the relative velocity by more than it is (a
//! hammer riding on the object with no force, stiff phases), each phase sees
//! the other's start as an immediate crossing and the switches would follow
//! one another at the root resolution, up to `1 / (ROOT_ULPS eps)` of them
//! (docs/numerics.md, "Why it terminates, and what it costs"). At the cap the
//! rest of the sample runs in its phase without a search (counted in
//! `capped`); both phases are passive, and a penetration left by the free
//! phase is taken up by the offset rod at the next entry, so the cap adds no
//! energy.
//!
//! A switch happens on a crossing with `phi` going down (a touch with zero
//! relative speed that does not cross carries no impulse and is not a
//! contact); right after a switch the new phase's `phi` starts at zero
//! (the spring starts unstretched: the residual of rounding at the root is
//! taken up by the rod offset, which adds no energy) and rises.
//!
//! # Files
//!
//! This file holds the counters, the named tolerances and the search's
//! scratch; the search itself is in
//!
//! - `sample`: one sample of exact switching, the search's driver;
//! - `partial`: the state within a sample (partial propagators and steps);
//! - `model`: the model of `phi` and its bounds on a node;
//! - `powers`: the slow terms' powers, raised in one vectorised pass;
//! - `roots`: the certified bisection and the root's refinement;
//! - `hermite`: the Hermite certificates that clear a sample without a
//!   search.

mod hermite;
mod model;
mod partial;
mod powers;
mod roots;
mod sample;

use crate::compile::event::THETA_SLOW;
use crate::compile::CompiledPhase;
pub use crate::engine::search::ROOT_ULPS;
use crate::engine::search::{NEUTRAL_TOL, ROUND_UNITS, STACK};

/// Highest degree of the slow blocks' polynomial (`2^25 / 25! = 2e-18`).
const MAX_DEGREE: usize = 24;
/// Most switches located within one sample (every engine, one or several
/// contacts); beyond, the rest of the sample runs in its phase without a
/// search ([`ExactStats::capped`]). Real contacts switch a few times per
/// sample at most (a brass mallet's 3-sample contact: 2).
pub const MAX_SWITCHES_PER_SAMPLE: u64 = 64;
/// Largest |A tau| per Taylor sub-step for dense partial steps, and the
/// number of terms: 0.5^20 / 20! ~ 4e-25.
const TAYLOR_MAX_NORM: f64 = 0.5;
const TAYLOR_TERMS: usize = 20;

/// Counters of what the exact switching did (diagnostics for reports,
/// tests and the render summary).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ExactStats {
    /// Switches located inside samples.
    pub located: u64,
    /// Samples that reached [`MAX_SWITCHES_PER_SAMPLE`] (switches at the
    /// root resolution, one after another: a contact at zero force that
    /// the phases' rounding cannot decide); the rest of such a sample runs
    /// in its phase without a search.
    pub capped: u64,
    /// Samples that started on the wrong side of the surface by more than
    /// rounding (a crossing missed in the sample before: never expected).
    /// The contact then starts with the paper's offset rod.
    pub rod_fallbacks: u64,
    /// Neutral nodes and resolution-sized nodes that ended with `phi > 0`:
    /// touches of zero within rounding that are not crossings.
    pub grazing: u64,
    /// Nodes left undecided (none: every node is decided at the latest at
    /// the root resolution; kept as a diagnostic the tests assert is 0).
    pub uncertified: u64,
    /// Partial-step propagators `exp(G tau)` computed for every block (one
    /// exponential and one sine/cosine per block).
    pub partial_sweeps: u64,
    /// Nodes the event search examined.
    pub search_nodes: u64,
    /// Most nodes examined in one sample.
    pub max_nodes_in_sample: u64,
    /// Most switches in one sample.
    pub max_switches_in_sample: u64,
    /// Samples whose state was not finite (no search: the rest of the
    /// sample is stepped in the current phase, and the caller sees a
    /// non-finite output; the instrument resets such a voice).
    pub nonfinite: u64,
    /// Contacts that began on the object at rest and ended where the
    /// compiler found their release: both switches O(N)
    /// ([`crate::compile::rest`]).
    pub rest_releases: u64,
    /// Switches after the first release of a strike from rest (its later
    /// contacts) that came where the compiler found them: O(N), the state
    /// stored.
    pub rest_later: u64,
    /// Stored switches of a strike from rest taken at their stored
    /// instants without a search (the engine's certifying run had
    /// confirmed them: [`crate::compile::rest::RestStrike::certified`]);
    /// also counted in `located` and in `rest_releases` / `rest_later`.
    pub rest_trusted: u64,
    /// Switches of a strike from rest that did not come where the compiler
    /// found them (the first release ended elsewhere: another strike, a
    /// change of pitch, a grazing release; or a later switch did): the
    /// dense change of basis, for it and the rest of the strike.
    pub rest_misses: u64,
    /// Samples the fast path could not certify that the Hermite
    /// certificate cleared before any search (value and slope at both
    /// ends, fourth-derivative remainder; docs/numerics.md section 6.2).
    pub hermite_cleared: u64,
    /// Rests of samples after a located switch that the Hermite
    /// certificate cleared without a second model and search.
    pub hermite_after_switch: u64,
    /// Contacts that began at a strike's instant, the hammer put on the
    /// surface moving into it: entered without a search.
    pub strike_entries: u64,
    /// Roots refined on the model (docs/numerics.md section 6.4).
    pub roots_refined: u64,
    /// The model evaluations those refinements took (about five a root).
    pub root_evals: u64,
    /// Samples the block kernel stepped past one that failed its test,
    /// thrown away (the run is stepped again up to that sample): the fast
    /// path's speculation that did not pay.
    pub kernel_discarded: u64,
    /// Strikes from rest played back from their recording
    /// ([`crate::engine::EngineState::strike_stored`]; the replays a
    /// voice settled are not counted here).
    pub replayed: u64,
    /// Replays settled: the strike run for real up to where its replay
    /// was, because something changed the voice before its end.
    pub settled: u64,
}

impl ExactStats {
    /// Add `o`'s counts to these (the largest of the per-sample maxima).
    pub fn add(&mut self, o: &ExactStats) {
        let ExactStats {
            located,
            capped,
            rod_fallbacks,
            grazing,
            uncertified,
            partial_sweeps,
            search_nodes,
            max_nodes_in_sample,
            max_switches_in_sample,
            nonfinite,
            rest_releases,
            rest_later,
            rest_trusted,
            rest_misses,
            hermite_cleared,
            hermite_after_switch,
            strike_entries,
            roots_refined,
            root_evals,
            kernel_discarded,
            replayed,
            settled,
        } = *o;
        self.located += located;
        self.capped += capped;
        self.rod_fallbacks += rod_fallbacks;
        self.grazing += grazing;
        self.uncertified += uncertified;
        self.partial_sweeps += partial_sweeps;
        self.search_nodes += search_nodes;
        self.max_nodes_in_sample = self.max_nodes_in_sample.max(max_nodes_in_sample);
        self.max_switches_in_sample = self.max_switches_in_sample.max(max_switches_in_sample);
        self.nonfinite += nonfinite;
        self.rest_releases += rest_releases;
        self.rest_later += rest_later;
        self.rest_trusted += rest_trusted;
        self.rest_misses += rest_misses;
        self.hermite_cleared += hermite_cleared;
        self.hermite_after_switch += hermite_after_switch;
        self.strike_entries += strike_entries;
        self.roots_refined += roots_refined;
        self.root_evals += root_evals;
        self.kernel_discarded += kernel_discarded;
        self.replayed += replayed;
        self.settled += settled;
    }
}

/// Which terms of a phase's event function ([`crate::compile::event`])
/// are slow (one polynomial) and which are fast (evaluated exactly), for the
/// current step length. Recomputed when the time scale changes.
#[derive(Debug, Default)]
pub(super) struct TermSplit {
    slow: Vec<u32>,
    fast: Vec<u32>,
}

impl Clone for TermSplit {
    /// Keeps the room, not only the length: a derived clone (a cloned
    /// voice state) would make the next [`update`](Self::update) at
    /// another step grow the lists on the audio thread.
    fn clone(&self) -> Self {
        let mut c = Self::with_capacity(self.slow.capacity().max(self.fast.capacity()));
        c.slow.extend_from_slice(&self.slow);
        c.fast.extend_from_slice(&self.fast);
        c
    }
}

impl TermSplit {
    /// Room for `n` terms (two per block at most).
    pub(super) fn with_capacity(n: usize) -> Self {
        Self {
            slow: Vec::with_capacity(n),
            fast: Vec::with_capacity(n),
        }
    }

    /// Split the terms of `ph` for steps of `step` (reference time).
    /// O(N), allocation-free within the capacity. \[audio-thread\]
    pub(super) fn update(&mut self, ph: &CompiledPhase, step: f64) {
        self.slow.clear();
        self.fast.clear();
        for (i, t) in ph.search.terms.iter().enumerate() {
            if t.mu * step <= THETA_SLOW {
                self.slow.push(i as u32);
            } else {
                self.fast.push(i as u32);
            }
        }
    }
}

/// Per fast term, what the node bounds need besides its amplitude: for
/// `j = 0, 1, 3` the magnitudes of `alpha_j = Re(C mu^j)` and `beta_j =
/// -Im(C mu^j)` (`|alpha cos + beta sin| <= |alpha| + |beta| |sin|`, within
/// a factor sqrt(2) of the envelope `|C|` and far below it near critical
/// damping), and the peak of `e^{m tau} min(1, w tau)` (its instant and
/// value) for decaying terms.
#[derive(Debug, Clone, Copy, Default)]
struct FastBounds {
    ab: [[f64; 2]; 3],
    peak: f64,
    peak_val: f64,
}

/// Scratch of the event search (sized once per voice, never reallocated).
#[derive(Debug, Clone)]
pub(super) struct SearchScratch {
    /// Fast terms gathered for the current model: complex amplitude
    /// `C = cr + i ci`, `mu = m + i w`, `|mu|`, and their bound data.
    nf: usize,
    f_cr: Vec<f64>,
    f_ci: Vec<f64>,
    f_m: Vec<f64>,
    f_w: Vec<f64>,
    f_mu: Vec<f64>,
    f_b: Vec<FastBounds>,
    /// exp/sin/cos arguments and results for the fast terms.
    f_mt: Vec<f64>,
    f_wt: Vec<f64>,
    f_e: Vec<f64>,
    f_s: Vec<f64>,
    f_c: Vec<f64>,
    /// The terms a node resolves (indices into the fast terms), their
    /// arguments and their sines and cosines.
    f_at: Vec<u32>,
    f_rt: Vec<f64>,
    f_rs: Vec<f64>,
    f_rc: Vec<f64>,
    /// Slow terms' polynomial `sum_j poly[j] tau^j`, its degree, the bound
    /// on the slow part's third derivative, and the truncation errors of the
    /// polynomial's value, slope and curvature.
    poly: [f64; MAX_DEGREE + 1],
    deg: usize,
    slow_c3: f64,
    slow_err: [f64; 3],
    /// Slow terms: how many, `|mu|max rem`, the model's range, and the next
    /// power `j` of the raising (`z = C mu^j`, `inv_fact = 1 / j!`).
    ns: usize,
    theta: f64,
    rem: f64,
    next_j: usize,
    inv_fact: f64,
    /// Slow terms gathered: `C mu^j` as it is raised, `mu`, and
    /// `min(1, w rem)` (how much of `Im(C mu^j)` can show).
    z_r: Vec<f64>,
    z_i: Vec<f64>,
    mu_r: Vec<f64>,
    mu_i: Vec<f64>,
    cw: Vec<f64>,
    /// Exactly polynomial part `c0 + c1 tau + c2 tau^2 / 2`.
    c: [f64; 3],
    /// Growth allowance `e^{gamma rem}` of envelopes (rounding of lossless
    /// eigenvalues may leave `m` a hair above 0).
    growth: f64,
    /// Rounding allowances of the value and of the slope.
    tol: f64,
    tol_d: f64,
    /// Dense phases: the state norm at the origin.
    y_norm: f64,
    /// Pending right halves of the bisection, `(a, w)`.
    stack: [(f64, f64); STACK],
}

impl SearchScratch {
    /// Room for `n` terms.
    pub(super) fn new(n: usize) -> Self {
        let v = || vec![0.0; n];
        Self {
            nf: 0,
            f_cr: v(),
            f_ci: v(),
            f_m: v(),
            f_w: v(),
            f_mu: v(),
            f_b: vec![FastBounds::default(); n],
            f_mt: v(),
            f_wt: v(),
            f_e: v(),
            f_s: v(),
            f_c: v(),
            f_at: vec![0; n],
            f_rt: v(),
            f_rs: v(),
            f_rc: v(),
            poly: [0.0; MAX_DEGREE + 1],
            ns: 0,
            theta: 0.0,
            rem: 0.0,
            next_j: 0,
            inv_fact: 1.0,
            deg: 0,
            slow_c3: 0.0,
            slow_err: [0.0; 3],
            z_r: v(),
            z_i: v(),
            mu_r: v(),
            mu_i: v(),
            cw: v(),
            c: [0.0; 3],
            growth: 1.0,
            tol: 0.0,
            tol_d: 0.0,
            y_norm: 0.0,
            stack: [(0.0, 0.0); STACK],
        }
    }
}

#[cfg(test)]
mod tests;
