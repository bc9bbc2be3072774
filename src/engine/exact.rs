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

use super::dot::dot;
use super::kernel::BlockProps;
use super::{current_phase, EngineState, Phase};
use super::{kernel, vmath, SimdPath};
use crate::compile::event::{THETA_RESOLVED, THETA_SLOW};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::physics::block::{exp2, mul2, OscBlocks};

/// Highest degree of the slow blocks' polynomial (`2^25 / 25! = 2e-18`).
pub const MAX_DEGREE: usize = 24;
/// Resolution of a located switch instant, in ulps of the sample period
/// (3.6e-15 of a sample): below it the rounding of `phi` itself (`u |x_h| /
/// |phi'|`, ~1e-14 of a sample for a hammer at millimetres and 1 m/s)
/// decides, so resolving further only costs evaluations. It is also the
/// least time between two switches.
pub const ROOT_ULPS: f64 = 16.0;
/// Most switches located within one sample (every engine, one or several
/// contacts); beyond, the rest of the sample runs in its phase without a
/// search ([`ExactStats::capped`]). Real contacts switch a few times per
/// sample at most (a brass mallet's 3-sample contact: 2).
pub const MAX_SWITCHES_PER_SAMPLE: u64 = 64;
/// A node is neutral when `|phi| <= NEUTRAL_TOL` roundings on all of it.
const NEUTRAL_TOL: f64 = 4.0;
/// Rounding allowance of the model, in units of `u` times the magnitude of
/// what is summed (each product and sum rounds once, with a margin).
const ROUND_UNITS: f64 = 4.0;
/// Deepest bisection: nodes never get narrower than the root resolution,
/// `2^-48` of a sample; the stack holds one pending node per level.
const STACK: usize = 64;
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

impl SearchScratch {
    /// Raise the slow terms' powers `z = C mu^j` up to `j = upto`,
    /// summing the coefficients `poly[j]` (`j <= deg`) and taking the
    /// magnitudes of the third derivative (`j = 3`) and of the Lagrange
    /// remainder (`j = deg + 1`). O(N_slow) per power. \[audio-thread\]
    fn raise_poly(&mut self, simd: SimdPath, upto: usize) {
        if self.next_j > upto {
            return;
        }
        let (ns, deg, j0) = (self.ns, self.deg, self.next_j);
        let mut sums = [0.0; MAX_DEGREE + 2];
        let mut mags = [0.0; 2];
        raise_powers(
            simd,
            Powers {
                zr: &mut self.z_r[..ns],
                zi: &mut self.z_i[..ns],
                mr: &self.mu_r[..ns],
                mi: &self.mu_i[..ns],
                cw: &self.cw[..ns],
            },
            (j0, upto),
            [3, deg + 1],
            &mut sums,
            &mut mags,
        );
        for (j, &sum) in sums.iter().enumerate().take(upto + 1).skip(j0) {
            if j == 3 && ns > 0 {
                self.slow_c3 = mags[0] * self.growth;
            }
            if j == deg + 1 && ns > 0 {
                // Lagrange remainders of the q-th derivative of the
                // degree-`deg` Taylor polynomial: |f^(deg+1)| rem^(deg+1-q)
                // / (deg+1-q)!.
                let rem_mag = mags[1] * self.growth;
                for (q, eq) in self.slow_err.iter_mut().enumerate() {
                    let mut v = rem_mag;
                    for i in 1..=(deg + 1).saturating_sub(q) {
                        v *= self.rem / i as f64;
                    }
                    *eq = v;
                }
            }
            if j <= deg {
                self.poly[j] = sum * self.inv_fact;
                self.inv_fact /= (j + 1) as f64;
            }
        }
        self.next_j = upto + 1;
    }

    /// The fast terms' amplitudes `C = Re + i Im` from the state, gathered
    /// with the data their node bounds need; their rounding and growth go
    /// to `al`.
    #[inline]
    fn gather_fast(
        &mut self,
        ph: &CompiledPhase,
        split: &TermSplit,
        s: &[f64],
        rem: f64,
        al: &mut Allowance,
    ) {
        let nb = ph.dim / 2;
        let terms = &ph.search.terms;
        for (i, &j) in split.fast.iter().enumerate() {
            let t = &terms[j as usize];
            let k = t.block as usize;
            let (x0, x1) = (s[k], s[nb + k]);
            let (cr, ci) = (t.re[0] * x0 + t.re[1] * x1, -(t.im[0] * x0 + t.im[1] * x1));
            let sk = x0.abs() + x1.abs();
            let r = (t.re[0].abs() + t.re[1].abs()) * sk
                + (t.im[0].abs() + t.im[1].abs()) * sk * (t.w * rem).min(1.0);
            al.round += r;
            al.round_d += r * t.mu;
            self.f_cr[i] = cr;
            self.f_ci[i] = ci;
            self.f_m[i] = t.m;
            self.f_w[i] = t.w;
            self.f_mu[i] = t.mu;
            let p = powers(cr, ci, t.m, t.w);
            let mut fb = FastBounds::default();
            for (q, (re, im)) in p.iter().enumerate() {
                fb.ab[q] = [re.abs(), im.abs()];
            }
            // peak of e^{m tau} min(1, w tau) (decaying terms)
            if t.m < 0.0 && t.w > 0.0 {
                let t_star = -1.0 / t.m;
                if t_star * t.w < 1.0 {
                    (fb.peak, fb.peak_val) = (t_star, t.w * t_star * (-1.0f64).exp());
                } else {
                    (fb.peak, fb.peak_val) = (1.0 / t.w, (t.m / t.w).exp());
                }
            }
            self.f_b[i] = fb;
            al.gamma = al.gamma.max(t.m);
        }
        self.nf = split.fast.len();
    }

    /// The slow terms' amplitudes and exponents from the state; their
    /// rounding and growth go to `al`. Returns the largest `|mu|`.
    #[inline]
    fn gather_slow(
        &mut self,
        ph: &CompiledPhase,
        split: &TermSplit,
        s: &[f64],
        rem: f64,
        al: &mut Allowance,
    ) -> f64 {
        let nb = ph.dim / 2;
        let terms = &ph.search.terms;
        let mut mu_max: f64 = 0.0;
        for (i, &j) in split.slow.iter().enumerate() {
            let t = &terms[j as usize];
            let k = t.block as usize;
            let (x0, x1) = (s[k], s[nb + k]);
            self.z_r[i] = t.re[0] * x0 + t.re[1] * x1;
            self.z_i[i] = -(t.im[0] * x0 + t.im[1] * x1);
            self.mu_r[i] = t.m;
            self.mu_i[i] = t.w;
            let cw = (t.w * rem).min(1.0);
            self.cw[i] = cw;
            let sk = x0.abs() + x1.abs();
            let r =
                (t.re[0].abs() + t.re[1].abs()) * sk + (t.im[0].abs() + t.im[1].abs()) * sk * cw;
            al.round += r;
            al.round_d += r * t.mu;
            mu_max = mu_max.max(t.mu);
            al.gamma = al.gamma.max(t.m);
        }
        mu_max
    }

    /// Start the slow Taylor polynomial of `ns` terms with `theta = mu_max
    /// rem`: its degree (`theta^(d+1) / (d+1)! <= 2^-60`, at least
    /// quadratic so the remainders of value, slope and curvature all come
    /// from the (d+1)-th derivative) and its coefficients `poly[j] = sum_k
    /// Re[C_k mu_k^j] / j!` up to `j = 3` (and the magnitude of the third
    /// derivative); the rest only when a node away from the origin needs
    /// them (`complete_poly`): a search that certifies its first node never
    /// pays for them. Returns the degree.
    fn start_poly(&mut self, simd: SimdPath, ns: usize, theta: f64, rem: f64) -> usize {
        let mut deg = 0;
        let mut term = theta; // theta^(deg+1) / (deg+1)!
        while deg < MAX_DEGREE && term > f64::EPSILON / 256.0 {
            deg += 1;
            term *= theta / (deg + 1) as f64;
        }
        deg = if ns == 0 { 0 } else { deg.max(2) };
        self.deg = deg;
        self.ns = ns;
        self.theta = theta;
        self.rem = rem;
        self.next_j = 0;
        self.inv_fact = 1.0;
        self.poly = [0.0; MAX_DEGREE + 1];
        self.slow_c3 = 0.0;
        self.slow_err = [0.0; 3];
        self.raise_poly(simd, 3);
        deg
    }

    /// The slow polynomial's part of a node's bounds: value, slope and
    /// curvature by Horner (at the origin: its first coefficients, which
    /// are exact sums), its remainder, and its third-derivative bound.
    #[inline]
    fn slow_bounds(&mut self, simd: SimdPath, tau: f64, w: f64, nb: &mut NodeBounds) {
        if tau == 0.0 {
            nb.q[0] += self.poly[0];
            nb.q[1] += self.poly[1];
            nb.q[2] += 2.0 * self.poly[2];
        } else {
            self.complete_poly(simd);
            let deg = self.deg;
            let (mut p0, mut p1, mut p2) = (0.0, 0.0, 0.0);
            for j in (0..=deg).rev() {
                p2 = p2 * tau + 2.0 * p1;
                p1 = p1 * tau + p0;
                p0 = p0 * tau + self.poly[j];
            }
            nb.q[0] += p0;
            nb.q[1] += p1;
            nb.q[2] += p2;
            let [e0, e1, e2] = self.slow_err;
            nb.u += e0 + w * (e1 + 0.5 * e2 * w);
            nb.l += e1 + e2 * w;
        }
        nb.c3 += self.slow_c3;
    }

    /// The fast terms' part of a node's bounds: exact, in one vectorised
    /// exp/sin/cos batch; a term the node resolves adds its value, slope and
    /// curvature (and its envelope to `c3`), one it does not adds its
    /// envelope to `u` and `l`.
    #[inline]
    fn fast_bounds(&mut self, simd: SimdPath, tau: f64, w: f64, all: bool, nb: &mut NodeBounds) {
        let nf = self.nf;
        if nf == 0 {
            return;
        }
        for i in 0..nf {
            self.f_mt[i] = self.f_m[i] * tau;
            self.f_wt[i] = self.f_w[i] * tau;
        }
        if all {
            vmath::exp_sincos(
                simd,
                &self.f_mt[..nf],
                &self.f_wt[..nf],
                &mut self.f_e[..nf],
                &mut self.f_s[..nf],
                &mut self.f_c[..nf],
            );
        } else {
            // a term the node does not resolve enters through its envelope
            // alone, which needs no sine or cosine: those of the resolved
            // terms only, gathered (each lane the same bits either way)
            vmath::exp_only(simd, &self.f_mt[..nf], &mut self.f_e[..nf]);
            let mut k = 0;
            for i in 0..nf {
                if self.f_mu[i] * w <= THETA_RESOLVED {
                    self.f_at[k] = i as u32;
                    self.f_rt[k] = self.f_wt[i];
                    k += 1;
                }
            }
            if k > 0 {
                vmath::sincos_only(
                    simd,
                    &self.f_rt[..k],
                    &mut self.f_rs[..k],
                    &mut self.f_rc[..k],
                );
                for j in 0..k {
                    let i = self.f_at[j] as usize;
                    self.f_s[i] = self.f_rs[j];
                    self.f_c[i] = self.f_rc[j];
                }
            }
        }
        let growth = self.growth;
        for i in 0..nf {
            let e = self.f_e[i];
            let (sn, cs) = (self.f_s[i], self.f_c[i]);
            let (cr, ci) = (self.f_cr[i], self.f_ci[i]);
            let (m, wv, mu) = (self.f_m[i], self.f_w[i], self.f_mu[i]);
            let resolved = all || mu * w <= THETA_RESOLVED;
            if resolved {
                let er = e * (cr * cs - ci * sn);
                let ei = e * (cr * sn + ci * cs);
                nb.q[0] += er;
                nb.q[1] += er * m - ei * wv;
                nb.q[2] += er * (m * m - wv * wv) - ei * (2.0 * m * wv);
                if all {
                    continue;
                }
            }
            // sup over the node (tau >= `tau`) of e^{m t} and of
            // e^{m t} min(1, w t)
            let fb = &self.f_b[i];
            let (e_sup, f_sup) = if m < 0.0 {
                let f = if tau >= fb.peak {
                    e * (wv * tau).min(1.0)
                } else {
                    fb.peak_val
                };
                (e, f)
            } else {
                (growth, growth * (wv * (tau + w)).min(1.0))
            };
            let env = |q: usize| fb.ab[q][0] * e_sup + fb.ab[q][1] * f_sup;
            if resolved {
                nb.c3 += env(2);
            } else {
                nb.u += env(0);
                nb.l += env(1);
            }
        }
    }

    /// The whole polynomial and its truncation errors.
    fn complete_poly(&mut self, simd: SimdPath) {
        if self.next_j <= self.deg + 1 {
            self.raise_poly(simd, self.deg + 1);
        }
    }
}

/// The slow terms' powers `z = C mu^j` (structure of arrays) and what
/// their sums need: `cw` weighs `|Im z|` in the magnitudes.
struct Powers<'a> {
    zr: &'a mut [f64],
    zi: &'a mut [f64],
    mr: &'a [f64],
    mi: &'a [f64],
    cw: &'a [f64],
}

/// For `j` in `js.0..=js.1`: `sums[j] = sum_i Re(z_i)`, then `z *= mu`
/// elementwise (complex), and at `j = marks[m]` the magnitude `mags[m] =
/// sum_i |Re z_i| + cw_i |Im z_i|` before the product. The terms are taken
/// eight at a time through all the powers (held in registers, eight
/// independent products in flight) rather than one power at a time through
/// all the terms, so `z` is read and written once, not once per power. The
/// sums run in four lanes (`i mod 4`, reduced in a fixed order, the last
/// `n mod 4` terms apart) and the magnitudes in order of `i`: the same
/// additions in the same order whatever the chunking (deterministic). On the
/// AVX2 path when the CPU has it. \[audio-thread\]
fn raise_powers(
    simd: SimdPath,
    p: Powers<'_>,
    js: (usize, usize),
    marks: [usize; 2],
    sums: &mut [f64; MAX_DEGREE + 2],
    mags: &mut [f64; 2],
) {
    /// Terms `i0..i0 + W` through the powers `js`.
    #[inline(always)]
    fn chunk<const W: usize>(
        p: &mut Powers<'_>,
        i0: usize,
        js: (usize, usize),
        marks: [usize; 2],
        acc: &mut [[f64; 4]; MAX_DEGREE + 2],
        mags: &mut [f64; 2],
    ) {
        let mut a = [0.0; W];
        let mut b = [0.0; W];
        let mut mr = [0.0; W];
        let mut mi = [0.0; W];
        a.copy_from_slice(&p.zr[i0..i0 + W]);
        b.copy_from_slice(&p.zi[i0..i0 + W]);
        mr.copy_from_slice(&p.mr[i0..i0 + W]);
        mi.copy_from_slice(&p.mi[i0..i0 + W]);
        for j in js.0..=js.1 {
            for (m, &mark) in marks.iter().enumerate() {
                if j == mark {
                    for l in 0..W {
                        mags[m] += a[l].abs() + b[l].abs() * p.cw[i0 + l];
                    }
                }
            }
            let acc_j = &mut acc[j];
            for l in 0..W {
                acc_j[l % 4] += a[l];
                let (x, y) = (a[l], b[l]);
                a[l] = x * mr[l] - y * mi[l];
                b[l] = x * mi[l] + y * mr[l];
            }
        }
        p.zr[i0..i0 + W].copy_from_slice(&a);
        p.zi[i0..i0 + W].copy_from_slice(&b);
    }
    #[inline(always)]
    fn body(
        mut p: Powers<'_>,
        js: (usize, usize),
        marks: [usize; 2],
        sums: &mut [f64; MAX_DEGREE + 2],
        mags: &mut [f64; 2],
    ) {
        let n = p.zr.len();
        let full = n - n % 4;
        let mut acc = [[0.0; 4]; MAX_DEGREE + 2];
        let mut i = 0;
        while i + 8 <= full {
            chunk::<8>(&mut p, i, js, marks, &mut acc, mags);
            i += 8;
        }
        if i < full {
            chunk::<4>(&mut p, i, js, marks, &mut acc, mags);
        }
        let mut tail = [0.0; MAX_DEGREE + 2];
        for i in full..n {
            let (mut a, mut b) = (p.zr[i], p.zi[i]);
            let (mr, mi) = (p.mr[i], p.mi[i]);
            for j in js.0..=js.1 {
                for (m, &mark) in marks.iter().enumerate() {
                    if j == mark {
                        mags[m] += a.abs() + b.abs() * p.cw[i];
                    }
                }
                tail[j] += a;
                (a, b) = (a * mr - b * mi, a * mi + b * mr);
            }
            p.zr[i] = a;
            p.zi[i] = b;
        }
        for j in js.0..=js.1 {
            let a = &acc[j];
            sums[j] = ((a[0] + a[1]) + (a[2] + a[3])) + tail[j];
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn body_avx2(
        p: Powers<'_>,
        js: (usize, usize),
        marks: [usize; 2],
        sums: &mut [f64; MAX_DEGREE + 2],
        mags: &mut [f64; 2],
    ) {
        body(p, js, marks, sums, mags)
    }
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `detect()` makes, after
        // checking AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(p, js, marks, sums, mags) },
        _ => body(p, js, marks, sums, mags),
    }
}

/// `C mu^j` for `j = 0, 1, 3` as `(Re, Im)`.
fn powers(cr: f64, ci: f64, m: f64, w: f64) -> [(f64, f64); 3] {
    let mul = |(a, b): (f64, f64)| (a * m - b * w, a * w + b * m);
    let c1 = mul((cr, ci));
    let c3 = mul(mul(c1));
    [(cr, ci), c1, c3]
}

/// Bounds of `phi` on a node `[a, a + w]`: the resolved part's value, slope
/// and curvature at `a` (`q`), the bound `c3` on its third derivative, and
/// bounds on the unresolved part's value (`u`) and slope (`l`).
#[derive(Debug, Clone, Copy)]
struct NodeBounds {
    q: [f64; 3],
    u: f64,
    l: f64,
    c3: f64,
}

/// What the search found.
enum Found {
    /// No crossing before the end of the range.
    None,
    /// Switch at this time after the search origin (`phi <= 0` there, to
    /// rounding).
    At(f64),
}

/// `(min, max)` of `q0 + q1 t + q2 t^2 / 2` on `[0, w]`.
fn quad_range(q: [f64; 3], w: f64) -> (f64, f64) {
    let end = q[0] + w * (q[1] + 0.5 * q[2] * w);
    let (mut lo, mut hi) = (q[0].min(end), q[0].max(end));
    if q[2] != 0.0 {
        let t = -q[1] / q[2];
        if t > 0.0 && t < w {
            let v = q[0] + t * (q[1] + 0.5 * q[2] * t);
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    (lo, hi)
}

impl EngineState {
    /// `[phi, phi', phi'']` at `tau` into the step from the current state,
    /// through the state itself (a sweep of partial propagators). `full`
    /// means `tau` is the whole step (precomputed propagators).
    pub(super) fn eval_event3(&mut self, scene: &CompiledScene, tau: f64, full: bool) -> [f64; 3] {
        let [mut f, mut d, mut dd] = self.event_sums(scene, tau, full);
        if self.in_contact() {
            f += scene.offsets.pi / scene.sk;
        } else {
            f += self.x_h + self.v_h * tau - 0.5 * self.g * tau * tau;
            d += self.v_h - self.g * tau;
            dd -= self.g;
        }
        [f, d, dd]
    }

    /// The object's part of [`eval_event3`](Self::eval_event3): the event
    /// rows `ev`, `ev'`, `ev''` times the state stepped by `tau`.
    pub(super) fn event_sums(&mut self, scene: &CompiledScene, tau: f64, full: bool) -> [f64; 3] {
        let full = full || tau == self.step_s;
        let ph: &CompiledPhase = current_phase(self, scene);
        if ph.dense.is_some() {
            let s = &self.phases[self.phase.index()].s;
            let n = ph.dim;
            if tau == 0.0 {
                return [
                    dot(&ph.ev, &s[..n]),
                    dot(&ph.ev_d, &s[..n]),
                    dot(&ph.ev_dd, &s[..n]),
                ];
            }
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, full, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            [
                dot(&ph.ev, &t0[..n]),
                dot(&ph.ev_d, &t0[..n]),
                dot(&ph.ev_dd, &t0[..n]),
            ]
        } else {
            if tau != 0.0 && !full {
                self.ensure_partial(scene, tau);
            }
            let ps = &self.phases[self.phase.index()];
            let s = &ps.s;
            let props = match (tau == 0.0, full) {
                (true, _) => None,
                (false, false) => Some(&self.p_part),
                (false, true) => Some(&ps.props),
            };
            kernel::event_rows(self.simd, props, s, [&ph.ev, &ph.ev_d, &ph.ev_dd])
        }
    }

    /// Fill `p_part` with the current phase's block propagators over `tau`,
    /// unless it already holds them: one sweep of exp/sin/cos per distinct
    /// `(phase, tau)`.
    pub(super) fn ensure_partial(&mut self, scene: &CompiledScene, tau: f64) {
        let contact = self.in_contact();
        if self.part_ok && self.part_tau == tau && self.part_contact == contact {
            return;
        }
        let ph = current_phase(self, scene);
        let gens = ph.gens.as_ref().expect("block phase");
        let nb = gens.len();
        let o = &ph.osc;
        let p = &mut self.p_part;
        osc_propagators(self.simd, o, tau, &mut self.part_args, p, nb);
        for &k in &o.other {
            p.set(k, &exp2(&gens[k], tau));
        }
        self.part_ok = true;
        self.part_tau = tau;
        self.part_contact = contact;
        self.exact_stats.partial_sweeps += 1;
    }

    /// Advance the current phase by `tau` (no switching).
    pub(super) fn advance_by(&mut self, scene: &CompiledScene, tau: f64, full: bool) {
        if tau <= 0.0 {
            return;
        }
        let full = full || tau == self.step_s;
        let ph: &CompiledPhase = current_phase(self, scene);
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        if ph.dense.is_some() {
            let n = ph.dim;
            let s = &mut self.phases[phase.index()].s;
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, full, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            s[..n].copy_from_slice(&t0[..n]);
        } else {
            if !full {
                self.ensure_partial(scene, tau);
            }
            let ps = &mut self.phases[phase.index()];
            let (s, props) = if full {
                (&mut ps.s, &ps.props)
            } else {
                (&mut ps.s, &self.p_part)
            };
            kernel::step_blocks(self.simd, props, &mut s[..ph.dim / 2 * 2]);
        }
        if !in_contact {
            self.x_h += self.v_h * tau - 0.5 * self.g * tau * tau;
            self.v_h -= self.g * tau;
        }
    }

    /// Build the model of `phi` from the current state over the next `rem`
    /// (reference time): amplitudes of every term, the slow polynomial, the
    /// fast terms gathered with their bound data, the rounding allowances.
    /// O(N + N_slow deg). Stages: the flight or offset part, then (dense
    /// phase: one norm bound and done) the fast terms, the whole blocks and
    /// the slow terms, each adding its rounding to the allowance.
    fn build_model(&mut self, scene: &CompiledScene, rem: f64) {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph = current_phase(self, scene);
        let sc = &mut self.search;
        sc.c = if in_contact {
            [scene.offsets.pi / scene.sk, 0.0, 0.0]
        } else {
            [self.x_h, self.v_h, -self.g]
        };
        let c_scale = sc.c[0].abs() + sc.c[1].abs() * rem + sc.c[2].abs() * rem * rem;
        let c_scale_d = sc.c[1].abs() + sc.c[2].abs() * rem;
        let s = &self.phases[phase.index()].s;
        let units = ROUND_UNITS * f64::EPSILON;
        if let Some((_, _)) = &ph.dense {
            let n = ph.dim;
            sc.y_norm = s[..n].iter().map(|x| x * x).sum::<f64>().sqrt();
            sc.nf = 0;
            sc.deg = 0;
            sc.growth = 1.0;
            let ev_norm = ph.ev.iter().map(|x| x * x).sum::<f64>().sqrt();
            let evd_norm = ph.ev_d.iter().map(|x| x * x).sum::<f64>().sqrt();
            // dense partial steps: a Taylor series of mat-vecs per sub-step
            let k = n as f64 + TAYLOR_TERMS as f64;
            sc.tol = k * units * (c_scale + ev_norm * sc.y_norm);
            sc.tol_d = k * units * (c_scale_d + evd_norm * sc.y_norm);
            return;
        }
        let split = &self.phases[phase.index()].split;
        let mut fast = Allowance::default();
        sc.gather_fast(ph, split, s, rem, &mut fast);
        whole_allowance(ph, s, &mut fast);
        let mut slow = Allowance {
            gamma: fast.gamma,
            ..Allowance::default()
        };
        let mu_max = sc.gather_slow(ph, split, s, rem, &mut slow);
        let growth = (slow.gamma * rem).exp();
        sc.growth = growth;
        let theta = mu_max * rem;
        let deg = sc.start_poly(self.simd, split.slow.len(), theta, rem);
        // Horner's evaluation of the polynomial rounds ~2 deg times terms
        // that add up to at most e^theta times the slow amplitudes.
        let k = (2 * deg + 2) as f64 * theta.exp();
        sc.tol = units * (c_scale + fast.round + k * slow.round) * growth;
        sc.tol_d = units * (c_scale_d + fast.round_d + k * slow.round_d) * growth;
    }

    /// Bounds of `phi` on the node `[tau, tau + w]` of the current model
    /// (`all`: every block resolved, for an exact value of the model): the
    /// flight or offset part, then the slow polynomial, the fast terms and
    /// the whole blocks, each adding to the same [`NodeBounds`] in that
    /// order.
    fn node_bounds(&mut self, scene: &CompiledScene, tau: f64, w: f64, all: bool) -> NodeBounds {
        let phase = self.phase;
        let ph = current_phase(self, scene);
        let sc = &mut self.search;
        let [c0, c1, c2] = sc.c;
        let mut nb = NodeBounds {
            q: [c0 + tau * (c1 + 0.5 * c2 * tau), c1 + c2 * tau, c2],
            u: 0.0,
            l: 0.0,
            c3: 0.0,
        };
        let s = &self.phases[phase.index()].s;
        if ph.dense.is_some() {
            let n = ph.dim;
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, false, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            nb.q[0] += dot(&ph.ev, &t0[..n]);
            nb.q[1] += dot(&ph.ev_d, &t0[..n]);
            nb.q[2] += dot(&ph.ev_dd, &t0[..n]);
            nb.c3 = ph.search.dense_ddd_norm * sc.y_norm;
            return nb;
        }
        sc.slow_bounds(self.simd, tau, w, &mut nb);
        sc.fast_bounds(self.simd, tau, w, all, &mut nb);
        whole_bounds(ph, s, tau, w, all, &mut nb);
        nb
    }

    /// `[phi, phi', phi'']` of the model at `tau` (exact to rounding).
    fn model_eval(&mut self, scene: &CompiledScene, tau: f64) -> [f64; 3] {
        self.node_bounds(scene, tau, 0.0, true).q
    }

    /// The first crossing of the model in `(0, rem]` (`open`: the origin is
    /// a switch instant, where `phi` is zero to rounding and rising).
    fn first_root(
        &mut self,
        scene: &CompiledScene,
        rem: f64,
        open: bool,
        nodes: &mut u64,
    ) -> Found {
        let resolution = ROOT_ULPS * f64::EPSILON * self.step_s;
        let mut top = 0; // pending nodes on the stack
        let mut cur = (0.0, rem);
        loop {
            let (a, w) = cur;
            *nodes += 1;
            let nbd = self.node_bounds(scene, a, w, false);
            let (tol, tol_d) = (self.search.tol, self.search.tol_d);
            let NodeBounds { q, u, l, c3 } = nbd;
            let r3 = c3 * w * w * w / 6.0;
            let r2 = 0.5 * c3 * w * w;
            let (qmin, qmax) = quad_range(q, w);
            let slope_lb = q[1].min(q[1] + q[2] * w) - l - r2 - tol_d;
            let slope_ub = q[1].max(q[1] + q[2] * w) + l + r2 + tol_d;
            let start_open = open && a == 0.0;
            let mut root_free = if start_open {
                // phi(0) = 0 to rounding: no crossing while it rises
                slope_lb > 0.0
            } else {
                qmin - u - r3 - tol > 0.0 || (slope_lb > 0.0 && q[0] - u - tol > 0.0)
            };
            if !root_free && !start_open && slope_ub < 0.0 {
                let end = q[0] + w * (q[1] + 0.5 * q[2] * w);
                if end + u + r3 + tol < 0.0 {
                    // phi(a) >= 0, strictly decreasing, negative at the end
                    let b = self.refine(scene, a, a + w);
                    return Found::At(if open { b.max(resolution) } else { b });
                }
                root_free = end - u - r3 - tol > 0.0;
            }
            if !root_free {
                let neutral = qmin.abs().max(qmax.abs()) + u + r3 <= NEUTRAL_TOL * tol;
                if neutral || w <= resolution {
                    // decided by the sign at the node's end
                    let end = a + w;
                    let fe = self.model_eval(scene, end)[0];
                    if fe <= 0.0 && !(open && end < resolution && fe > -tol) {
                        return Found::At(if open { end.max(resolution) } else { end });
                    }
                    self.exact_stats.grazing += 1;
                    root_free = true;
                } else if top < STACK {
                    let h = 0.5 * w;
                    self.search.stack[top] = (a + h, w - h);
                    top += 1;
                    cur = (a, h);
                    continue;
                } else {
                    // cannot happen: w halves per level and stops at the
                    // resolution, 2^-48 of a sample
                    self.exact_stats.uncertified += 1;
                    root_free = true;
                }
            }
            debug_assert!(root_free);
            if top == 0 {
                return Found::None;
            }
            top -= 1;
            cur = self.search.stack[top];
        }
    }

    /// Refine a certified bracket (`phi(a) >= 0 > phi(b)`, `phi` strictly
    /// decreasing on it) to the root, on the model: safeguarded Halley.
    /// Each step aims a quarter of the resolution past its root estimate,
    /// towards the end of the bracket that did not move (from a point
    /// where `phi > 0` just after the estimate, from one where `phi <= 0`
    /// just before it), so two steps near the root bracket it within the
    /// resolution; a step that would leave the bracket tries half the
    /// resolution inside the far end instead, and the bracket is bisected
    /// whenever neither two steps halved it nor one step halved the step.
    /// Returns a point at most [`ROOT_ULPS`] ulps of the sample after the
    /// root, on its `phi <= 0` side. docs/numerics.md section 6.4.
    /// \[audio-thread\]
    fn refine(&mut self, scene: &CompiledScene, a: f64, b: f64) -> f64 {
        let resolution = ROOT_ULPS * f64::EPSILON * self.step_s;
        let halley = |f: f64, d: f64, dd: f64| 2.0 * f * d / (2.0 * d * d - f * dd);
        let (mut a, mut b) = (a, b);
        let [fb, db, ddb] = self.model_eval(scene, b);
        let mut evals = 1;
        let mut x = b - halley(fb, db, ddb);
        // the bracket's width one and two steps ago (the first step is
        // free to move one end only)
        let mut widths = [b - a, 2.0 * (b - a)];
        let mut last_step = f64::INFINITY;
        // ~2 x 60 halvings reach the resolution from a whole sample; Halley
        // steps only make it faster
        for _ in 0..200 {
            if b - a <= resolution {
                break;
            }
            if !(x > a && x < b) {
                x = 0.5 * (a + b);
            }
            let [fx, dx, ddx] = self.model_eval(scene, x);
            evals += 1;
            let step = halley(fx, dx, ddx);
            let before = fx > 0.0;
            if before {
                a = x;
            } else {
                b = x;
                if fx == 0.0 || step.abs() <= 0.25 * resolution {
                    break;
                }
            }
            let est = x - step;
            x = if !step.is_finite() {
                0.5 * (a + b)
            } else if before {
                (est + 0.25 * resolution).min(b - 0.5 * resolution)
            } else {
                (est - 0.25 * resolution).max(a + 0.5 * resolution)
            };
            // progress: the bracket halved in two steps, or the step did
            // in one (Halley converging from one side)
            if b - a > 0.5 * widths[1] && !(step.abs() <= 0.5 * last_step) {
                x = 0.5 * (a + b);
            }
            widths = [b - a, widths[0]];
            last_step = step.abs();
        }
        self.exact_stats.roots_refined += 1;
        self.exact_stats.root_evals += evals;
        b
    }

    /// Switch phase at the current instant (exact switching): cut the
    /// spring, or start it unstretched (the rod offset takes up the
    /// rounding residual of `phi` at the root, so no energy is added).
    fn switch_now(&mut self, scene: &CompiledScene) {
        if self.in_contact() {
            self.leave_contact(scene);
        } else {
            let p = -self.eval_event3(scene, 0.0, false)[0];
            self.enter_contact(scene, p);
        }
    }

    /// Step the current block phase by `tau` into the spare buffer (the
    /// one-sample propagators when `full`, else the partial ones, with the
    /// same arithmetic as [`advance_by`](Self::advance_by)) and sum what
    /// the Hermite certificates need: `phi` and `phi'` at both ends, the
    /// capped remainder, the fourth-derivative bound `sum_k c4_k |s_k|`
    /// and the magnitude of the sums. `None` for a phase without blocks.
    fn hermite_step(&mut self, scene: &CompiledScene, tau: f64, full: bool) -> Option<HermiteSums> {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph: &CompiledPhase = current_phase(self, scene);
        let nb = ph.dim / 2;
        if ph.dense.is_some() || ph.gens.is_none() || ph.ev_d4_block.len() != nb {
            return None;
        }
        if !full {
            self.ensure_partial(scene, tau);
        }
        let dt4 = tau * tau * tau * tau / 384.0;
        let tail = 8.0 / 27.0 * tau;
        let ps = &mut self.phases[phase.index()];
        let props = if full { &ps.props } else { &self.p_part };
        let (s, next) = (&ps.s, &mut ps.next);
        let rows = kernel::HermiteRows {
            ev: &ph.ev,
            ev_d: &ph.ev_d,
            c1: &ph.ev_d_block,
            c2: &ph.ev_dd_block,
            c4: &ph.ev_d4_block,
            e: &ph.ev_block,
        };
        let [f0, d0, f1, d1, rem, m4, m2, mag, mag_d] = kernel::hermite_step_sums(
            self.simd,
            props,
            &s[..2 * nb],
            next,
            &rows,
            [dt4, tail, tau],
        );
        let mut h = HermiteSums {
            f0,
            d0,
            f1,
            d1,
            rem,
            m4,
            m2,
            mag,
            mag_d,
            ..HermiteSums::default()
        };
        if in_contact {
            let off = scene.offsets.pi / scene.sk;
            h.f0 += off;
            h.f1 += off;
            h.mag += off.abs();
            (h.x_h1, h.v_h1) = (self.x_h, self.v_h);
        } else {
            // exactly `advance_by`'s parabola
            h.x_h1 = self.x_h + (self.v_h * tau - 0.5 * self.g * tau * tau);
            h.v_h1 = self.v_h - self.g * tau;
            h.f0 += self.x_h;
            h.d0 += self.v_h;
            h.f1 += h.x_h1;
            h.d1 += h.v_h1;
            h.mag += self.x_h.abs() + h.x_h1.abs() + tau * (self.v_h.abs() + h.v_h1.abs());
            h.mag_d += self.v_h.abs() + h.v_h1.abs() + self.g.abs() * tau;
        }
        // each sum of 2 nb + 2 products rounds within (2 nb + 2) u of the
        // magnitudes summed; the Bernstein coefficients and the comparison
        // a few u more
        h.units = (2 * nb + 16) as f64 * f64::EPSILON;
        h.allowance = h.units * h.mag;
        Some(h)
    }

    /// Take the state [`hermite_step`](Self::hermite_step) left in the
    /// spare buffer.
    fn hermite_commit(&mut self, h: &HermiteSums) {
        let ps = &mut self.phases[self.phase.index()];
        std::mem::swap(&mut ps.s, &mut ps.next);
        if !self.in_contact() {
            self.x_h = h.x_h1;
            self.v_h = h.v_h1;
        }
    }

    /// Try to clear the whole coming sample without a search: `phi` and
    /// `phi'` at both of its ends (the end state stepped by the one-sample
    /// propagators, with the same arithmetic as
    /// [`advance_by`](Self::advance_by)), their cubic Hermite interpolant
    /// bounded below by its Bernstein coefficients (the convex hull of a
    /// cubic on an interval), less the interpolation remainder `sum_k
    /// min(c4_k dt^4 / 384, 2 e_k + 8/27 dt c1_k) |s_k|` (each block is a
    /// contraction, so `|d^4/dt^4 phi_k| <= c4_k |s_k|`, and a block's own
    /// interpolant stays within `e_k |s_k| + 8/27 dt c1_k |s_k|` of zero)
    /// and a rounding allowance. Above zero, `phi` has no root in the
    /// sample: the state advances by one full step, bit for bit what the
    /// search's "no root" would have left, and `true` is returned. Else
    /// nothing changes. O(N), no transcendental function.
    /// docs/numerics.md section 6.2. \[audio-thread\]
    fn hermite_clear(&mut self, scene: &CompiledScene) -> bool {
        let dt = self.step_s;
        let Some(h) = self.hermite_step(scene, dt, true) else {
            return false;
        };
        // the remainder's contraction (1 + 1e-12) as the fast path's margin
        let low =
            h.f0.min(h.f1)
                .min(h.f0 + h.d0 * dt / 3.0)
                .min(h.f1 - h.d1 * dt / 3.0);
        if !(low - h.rem * (1.0 + 1e-12) - h.allowance > 0.0) {
            return false;
        }
        self.hermite_commit(&h);
        self.exact_stats.hermite_cleared += 1;
        true
    }

    /// What the coming sample's start is when a strike just put the
    /// hammer on the surface (`phi = 0` exactly, [`EngineState::strike`])
    /// and nothing changed since, in flight: the contact's start if the
    /// hammer moves into the surface (`phi' < 0`), else an instant that is
    /// no crossing (the surface moves away at least as fast: the search
    /// looks past it). The search alone decided this through its model's
    /// sums, which put `phi(0)` a rounding above or below zero: it located
    /// the entry up to a few 1e-14 of a sample late for about half of the
    /// strikes on a moving object (a partial step and a search for it), and
    /// where the surface moved away, a rounding below zero made a contact
    /// that ended a rounding later. docs/numerics.md section 6.9.
    /// \[audio-thread\]
    fn strike_start(&mut self, scene: &CompiledScene) -> StrikeStart {
        if !std::mem::take(&mut self.struck_on_surface) || self.in_contact() {
            return StrikeStart::Search;
        }
        let [f, d, _] = self.eval_event3(scene, 0.0, false);
        if f != 0.0 {
            StrikeStart::Search
        } else if d < 0.0 {
            StrikeStart::Enter
        } else {
            StrikeStart::Open
        }
    }

    /// Try to clear the rest `w` of a sample right after a switch: no
    /// crossing downwards in it. The new phase's `phi` starts at zero to
    /// rounding (an entry, the spring starting unstretched) or below it (a
    /// damped release: the penetration is still positive where the force
    /// ends) and must not come down through zero. With `u = t / w` the
    /// interpolant is `H = phi_0 h00(u) + u K(u)`, `K` the quadratic `w
    /// phi'_0 B0 + (1.5 phi_1 - 0.5 w phi'_1) B1 + phi_1 B2` in the
    /// Bernstein basis, and `|phi - H| <= M4 w^4 u^2 (1 - u)^2 / 24 <= u M4
    /// w^4 / 162` (the largest `u (1 - u)^2` is 4/27). So with `k` the least
    /// of `K`'s coefficients less that and the rounding allowance, `phi >=
    /// phi_0 + u k`: where `phi_0 >= 0` (less its rounding) `phi > 0` on
    /// `(0, w]`; else `phi > 0` from `u_1 = 2 |phi_0| / k` on, and before it
    /// `phi' >= phi'_0 - t M2 > 0` (`M2 = sum_k c2_k |s_k|` bounds `phi''`)
    /// keeps `phi` rising. The search decides the same: a switch needs a
    /// crossing downwards. The state advances by the partial step (by the
    /// one-sample step where the switch was at the sample's start), bit for
    /// bit what the search's "no root" would have left.
    /// docs/numerics.md section 6.2. \[audio-thread\]
    fn hermite_clear_rest(&mut self, scene: &CompiledScene, w: f64) -> bool {
        // a whole sample (a switch at its start) steps as `advance_by` does
        // then: by the one-sample propagators
        let Some(h) = self.hermite_step(scene, w, w == self.step_s) else {
            return false;
        };
        let w4 = w * w * w * w;
        let k_low = (w * h.d0).min(1.5 * h.f1 - 0.5 * w * h.d1).min(h.f1);
        let k = k_low - h.m4 * w4 / 162.0 * (1.0 + 1e-12) - 2.0 * h.allowance;
        if !(k > 0.0) {
            return false;
        }
        let f0_low = h.f0 - h.allowance;
        if !(f0_low >= 0.0) {
            let u1 = 2.0 * -f0_low / k;
            let d_allow = 2.0 * h.units * h.mag_d;
            if !(u1 < 1.0 && h.d0 - u1 * w * h.m2 * (1.0 + 1e-12) - d_allow > 0.0) {
                return false;
            }
        }
        self.hermite_commit(&h);
        self.exact_stats.hermite_after_switch += 1;
        true
    }

    /// Exact-switching step of one sample (reference duration `step_s`).
    /// O(N) plus the slow polynomial without events; per switch one change
    /// of basis, O(N^2), and a number of node evaluations bounded by the
    /// phase's time scales. Allocation-free. \[audio-thread\]
    pub(super) fn advance_exact(&mut self, scene: &CompiledScene) {
        let step = self.step_s;
        let max_switches = MAX_SWITCHES_PER_SAMPLE;
        let mut t = 0.0; // time consumed in this sample
        let mut switches: u64 = 0;
        let mut nodes: u64 = 0;
        let mut open = false;
        match self.strike_start(scene) {
            StrikeStart::Enter => {
                // the crossing is this instant: the strike put the hammer
                // on the surface, moving into it
                self.switch_now(scene);
                self.exact_stats.located += 1;
                self.exact_stats.strike_entries += 1;
                switches = 1;
                open = true;
            }
            // on the surface, not moving into it: this instant is no
            // crossing, the search looks past it
            StrikeStart::Open => open = true,
            StrikeStart::Search => {
                // A sample that holds a strike from rest's next stored
                // switch holds a crossing: the certificate would fail (and
                // where it would not, the search's "no root" leaves the
                // same bits).
                if self.rest_due_in(scene) != Some(0) && self.hermite_clear(scene) {
                    return;
                }
            }
        }
        loop {
            let rem = step - t;
            if rem <= 0.0 {
                break;
            }
            let full = t == 0.0;
            let found = if let Some(w) = self.rest_trusted_switch(scene, t) {
                // a strike from rest's switch where the engine's
                // certifying run located it: no search
                self.exact_stats.rest_trusted += 1;
                Found::At(w)
            } else {
                if open
                    && switches > 0
                    && self.hermite_after_switch
                    && self.hermite_clear_rest(scene, rem)
                {
                    break;
                }
                self.build_model(scene, rem);
                if !(self.search.tol.is_finite() && self.search.tol_d.is_finite()) {
                    self.exact_stats.nonfinite += 1;
                    self.advance_by(scene, rem, full);
                    break;
                }
                let mut at_origin = false;
                if !open {
                    // a sample that starts on (or within rounding beyond) the
                    // surface: the crossing is at this instant
                    let [f0, d0, _] = self.model_eval(scene, 0.0);
                    if f0 < 0.0 || (f0 == 0.0 && d0 < 0.0) {
                        if f0 < -NEUTRAL_TOL * self.search.tol {
                            self.exact_stats.rod_fallbacks += 1;
                        }
                        at_origin = true;
                    } else if f0 == 0.0 {
                        open = true;
                    }
                }
                if at_origin {
                    Found::At(0.0)
                } else {
                    self.first_root(scene, rem, open, &mut nodes)
                }
            };
            match found {
                Found::None => {
                    self.advance_by(scene, rem, full);
                    break;
                }
                Found::At(tau) => {
                    let tau = tau.min(rem);
                    self.advance_by(scene, tau, full && tau == rem);
                    t += tau;
                    self.t_in_step = t;
                    self.switch_now(scene);
                    self.exact_stats.located += 1;
                    switches += 1;
                    open = true;
                    if switches >= max_switches {
                        self.exact_stats.capped += 1;
                        self.advance_by(scene, step - t, false);
                        break;
                    }
                }
            }
        }
        let st = &mut self.exact_stats;
        st.search_nodes += nodes;
        st.max_nodes_in_sample = st.max_nodes_in_sample.max(nodes);
        st.max_switches_in_sample = st.max_switches_in_sample.max(switches);
    }
}

/// A sample's start after a strike that put the hammer on the surface
/// ([`EngineState::strike_start`]).
enum StrikeStart {
    /// Not such a sample: the search decides.
    Search,
    /// The contact begins now.
    Enter,
    /// This instant is no crossing.
    Open,
}

/// What [`EngineState::hermite_step`] sums over a step.
#[derive(Debug, Default)]
struct HermiteSums {
    f0: f64,
    d0: f64,
    f1: f64,
    d1: f64,
    /// The capped remainder of the whole-sample certificate.
    rem: f64,
    /// `sum_k c4_k |s_k|`: a bound on the fourth derivative of `phi` over
    /// the step.
    m4: f64,
    /// `sum_k c2_k |s_k|`: a bound on the second derivative.
    m2: f64,
    mag: f64,
    /// The magnitude the slope sums round with.
    mag_d: f64,
    /// `(2 nb + 16) u`: the rounding of a sum per unit of its magnitude.
    units: f64,
    allowance: f64,
    /// The hammer after the step (in flight).
    x_h1: f64,
    v_h1: f64,
}

/// Rounding allowance being summed while a model is built: computing each
/// amplitude `C` from the state rounds each product once (`|re| |s_k|`, and
/// `|im| |s_k|` of which at most `min(1, w rem)` shows), for the value
/// (`round`) and the slope (`round_d`); `gamma` is the largest real part
/// (envelopes can only shrink unless rounding left a lossless eigenvalue's
/// real part a hair above 0).
#[derive(Default)]
struct Allowance {
    round: f64,
    round_d: f64,
    gamma: f64,
}

/// The first `nb` blocks' propagators over `tau` into `p`, for the
/// oscillatory blocks of `o` (the others are left to the caller): `exp`,
/// `sin` and `cos` of every block in one vectorised batch
/// ([`vmath::exp_sincos`], whose two paths differ by their fused
/// multiply-adds), then `exp(G tau)` from them as in `OscForm::exp_from`:
/// the same products and sums as the scalar loop, without fused
/// multiply-adds, compiled for AVX2 where the CPU has it. O(N).
/// \[audio-thread\]
fn osc_propagators(
    simd: SimdPath,
    o: &OscBlocks,
    tau: f64,
    args: &mut [Vec<f64>; 5],
    p: &mut BlockProps,
    nb: usize,
) {
    #[inline(always)]
    fn body(
        simd: SimdPath,
        o: &OscBlocks,
        tau: f64,
        args: &mut [Vec<f64>; 5],
        p: &mut BlockProps,
        nb: usize,
    ) {
        let [mt, wt, e, sn, cs] = args;
        let (mt, wt) = (&mut mt[..nb], &mut wt[..nb]);
        let (m, w) = (&o.m[..nb], &o.w[..nb]);
        for k in 0..nb {
            mt[k] = m[k] * tau;
            wt[k] = w[k] * tau;
        }
        let (e, sn, cs) = (&mut e[..nb], &mut sn[..nb], &mut cs[..nb]);
        vmath::exp_sincos(simd, mt, wt, e, sn, cs);
        let (p00, p01) = (&mut p.p00[..nb], &mut p.p01[..nb]);
        let (p10, p11) = (&mut p.p10[..nb], &mut p.p11[..nb]);
        let [n0, n1, n2, n3] = &o.n_w;
        let (n0, n1, n2, n3) = (&n0[..nb], &n1[..nb], &n2[..nb], &n3[..nb]);
        for k in 0..nb {
            let (es, ec) = (e[k] * sn[k], e[k] * cs[k]);
            p00[k] = ec + es * n0[k];
            p01[k] = es * n1[k];
            p10[k] = es * n2[k];
            p11[k] = ec + es * n3[k];
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn body_avx2(
        simd: SimdPath,
        o: &OscBlocks,
        tau: f64,
        args: &mut [Vec<f64>; 5],
        p: &mut BlockProps,
        nb: usize,
    ) {
        body(simd, o, tau, args, p, nb)
    }
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `detect()` makes, after
        // checking AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(simd, o, tau, args, p, nb) },
        _ => body(simd, o, tau, args, p, nb),
    }
}

/// The whole blocks' rounding (their bounds come from their own state, per
/// node).
#[inline]
fn whole_allowance(ph: &CompiledPhase, s: &[f64], al: &mut Allowance) {
    let nb = ph.dim / 2;
    for (j, &k) in ph.search.whole.iter().enumerate() {
        let k = k as usize;
        let rows = &ph.search.whole_rows[j];
        let sk = s[k].abs() + s[nb + k].abs();
        al.round += (rows[0][0].abs() + rows[0][1].abs()) * sk;
        al.round_d += (rows[2][0].abs() + rows[2][1].abs()) * sk;
        al.gamma = al.gamma.max(ph.search.whole_info[j][0]);
    }
}

/// The whole blocks' part of a node's bounds (nearly equal real
/// eigenvalues): from their own state `x` at the node's start, `|R exp(G t)
/// x| <= e^{lambda_max t} (|R x| + |R N x| t)`.
#[inline]
fn whole_bounds(ph: &CompiledPhase, s: &[f64], tau: f64, w: f64, all: bool, nb: &mut NodeBounds) {
    let gens = ph.gens.as_ref().expect("block phase");
    let n_blocks = gens.len();
    for (j, &k) in ph.search.whole.iter().enumerate() {
        let k = k as usize;
        let (x0, x1) = mul2(&exp2(&gens[k], tau), s[k], s[n_blocks + k]);
        let rows = &ph.search.whole_rows[j];
        let [lmax, rho] = ph.search.whole_info[j];
        let dot2 = |r: [f64; 2]| (r[0] * x0 + r[1] * x1).abs();
        let grow = (lmax.max(0.0) * w).exp();
        let b = |q: usize| (dot2(rows[2 * q]) + dot2(rows[2 * q + 1]) * w) * grow;
        if all || rho * w <= THETA_RESOLVED {
            nb.q[0] += ph.ev[k] * x0 + ph.ev[n_blocks + k] * x1;
            nb.q[1] += ph.ev_d[k] * x0 + ph.ev_d[n_blocks + k] * x1;
            nb.q[2] += ph.ev_dd[k] * x0 + ph.ev_dd[n_blocks + k] * x1;
            if !all {
                nb.c3 += b(2);
            }
        } else {
            nb.u += b(0);
            nb.l += b(1);
        }
    }
}

/// `out = exp(A tau) s` for a dense phase: the precomputed propagator for a
/// full step, else a Taylor series in sub-steps with `|A| tau_sub <= 0.5`.
fn dense_apply(
    ph: &CompiledPhase,
    s: &[f64],
    tau: f64,
    full: bool,
    out: &mut [f64],
    term: &mut [f64],
    next: &mut [f64],
) {
    let n = ph.dim;
    let (a, phi) = ph.dense.as_ref().expect("dense phase");
    if full {
        for i in 0..n {
            out[i] = dot(&phi[i * n..(i + 1) * n], &s[..n]);
        }
        return;
    }
    let norm = a.norm(); // Frobenius >= spectral
    let subs = ((norm * tau / TAYLOR_MAX_NORM).ceil() as usize).clamp(1, 1 << 20);
    let dt = tau / subs as f64;
    out[..n].copy_from_slice(&s[..n]);
    for _ in 0..subs {
        term[..n].copy_from_slice(&out[..n]);
        for k in 1..=TAYLOR_TERMS {
            for i in 0..n {
                let mut acc = 0.0;
                for j in 0..n {
                    acc += a[(i, j)] * term[j];
                }
                next[i] = acc * dt / k as f64;
            }
            term[..n].copy_from_slice(&next[..n]);
            for i in 0..n {
                out[i] += term[i];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compile::compile;
    use crate::engine::ScaleProps;
    use crate::presets;

    /// The contact output rows and offsets at time scale `s` with the modes
    /// above `band_hz` left out, written the plain way: each left-out
    /// free-row entry carried through `W_fc` entry by entry, one channel
    /// at a time.
    fn band_reference(sc: &CompiledScene, s: f64, band_hz: f64) -> ([Vec<f64>; 2], [f64; 2]) {
        let mix = |ph: &crate::compile::CompiledPhase, ch: usize| -> Vec<f64> {
            let (d, v) = if ch == 0 {
                (&ph.rows.disp_l, &ph.rows.vel_l)
            } else {
                (&ph.rows.disp_r, &ph.rows.vel_r)
            };
            d.iter().zip(v).map(|(a, b)| a + b * s).collect()
        };
        let mut free = [mix(&sc.free, 0), mix(&sc.free, 1)];
        let mut contact = [mix(&sc.contact, 0), mix(&sc.contact, 1)];
        let mut offset = [sc.offsets.disp_l, sc.offsets.disp_r];
        let gens = sc.free.gens.as_ref().unwrap();
        let nb = gens.len();
        let limit = 2.0 * std::f64::consts::PI * band_hz / s;
        for (k, g) in gens.iter().enumerate() {
            let half_tr = 0.5 * (g[0] + g[3]);
            let w2 = g[0] * g[3] - g[1] * g[2] - half_tr * half_tr;
            if !(w2 > limit * limit) {
                continue;
            }
            for ch in 0..2 {
                for i in [k, nb + k] {
                    let r = free[ch][i];
                    if r == 0.0 {
                        continue;
                    }
                    free[ch][i] = 0.0;
                    for j in 0..sc.contact.dim {
                        contact[ch][j] -= r * sc.w_fc[(i, j)];
                    }
                    offset[ch] -= r * sc.s_f_star[i];
                }
            }
        }
        (contact, offset)
    }

    #[test]
    fn propagators_made_ahead_are_the_computed_ones_bit_for_bit() {
        // every one-contact preset at three scales, with every mode heard
        // and with an output band that leaves the top modes out: the
        // propagators and output rows copied from a `ScaleProps` are
        // `set_time_scale`'s bit for bit; one made for another scene
        // (other block counts or step) is not used, nor are band rows
        // made for another band
        let other = compile(
            &presets::scene(presets::one_contact().next().unwrap()).unwrap(),
            48000.0,
        )
        .unwrap();
        let bits = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
        };
        let mut band_rows_used = 0;
        for i in presets::one_contact() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            if sc.free.gens.is_none() || sc.contact.gens.is_none() {
                continue;
            }
            for s in [0.5, 1.0, 2f64.powf(7.0 / 12.0)] {
                for band in [f64::INFINITY, 3000.0] {
                    let mut want = EngineState::new(&sc);
                    want.set_output_band(&sc, band);
                    want.set_time_scale(&sc, s).unwrap();
                    for (k, pre) in [
                        ScaleProps::new(&sc, s, band),
                        ScaleProps::new(&sc, s, 1234.5),
                        ScaleProps::new(&other, s, band),
                    ]
                    .iter()
                    .enumerate()
                    {
                        let mut got = EngineState::new(&sc);
                        got.set_output_band(&sc, band);
                        got.set_time_scale_from(&sc, pre).unwrap();
                        assert_eq!(got.step_s.to_bits(), want.step_s.to_bits());
                        for ph in [Phase::Free, Phase::Contact] {
                            let (g, w) = (&got.phases[ph.index()], &want.phases[ph.index()]);
                            for (a, b) in [
                                (&g.props.p00, &w.props.p00),
                                (&g.props.p01, &w.props.p01),
                                (&g.props.p10, &w.props.p10),
                                (&g.props.p11, &w.props.p11),
                            ] {
                                assert!(bits(a, b), "preset {i} at {s}: {ph:?} propagators");
                            }
                            for ch in 0..2 {
                                assert!(
                                    bits(&g.out[ch], &w.out[ch]),
                                    "preset {i} at {s}, band {band}: {ph:?} output row {ch}"
                                );
                            }
                        }
                        assert!(bits(&got.out_c_offset, &want.out_c_offset));
                        let (rows, offset) = band_reference(&sc, s, band);
                        for ch in 0..2 {
                            assert!(
                                bits(&want.phases[Phase::Contact.index()].out[ch], &rows[ch]),
                                "preset {i} at {s}, band {band}: contact row {ch} against the reference"
                            );
                        }
                        assert!(bits(&want.out_c_offset, &offset));
                        assert_eq!(got.band_muted_modes(), want.band_muted_modes());
                        if k == 0 && pre.band.is_some() {
                            assert!(want.band_muted_modes() > 0);
                            band_rows_used += 1;
                        }
                    }
                }
            }
        }
        println!("band rows copied in {band_rows_used} cases");
        assert!(band_rows_used >= 10, "{band_rows_used}");
    }

    #[test]
    fn dot3_is_three_dots_bit_for_bit() {
        use super::super::dot::dot3;
        for n in [0usize, 1, 2, 7, 400, 2002] {
            let row = |m: f64| -> Vec<f64> {
                (0..n)
                    .map(|k| (m * k as f64 + 0.3).sin() * 1e3f64.powf((k % 7) as f64 - 3.0))
                    .collect()
            };
            let s: Vec<f64> = (0..n).map(|k| (k as f64 * 0.77).cos()).collect();
            let (a, b, c) = (row(1.3), row(-0.4), row(2.9));
            // a row of negative zeros: the sums' starting value shows
            let z = vec![-0.0; n];
            let pos = vec![1.0; n];
            for rows in [[&a[..], &b[..], &c[..]], [&z[..], &a[..], &z[..]]] {
                for s in [&s[..], &pos[..]] {
                    let got = dot3(rows, s);
                    for q in 0..3 {
                        assert_eq!(got[q].to_bits(), dot(rows[q], s).to_bits(), "n {n} row {q}");
                    }
                }
            }
        }
    }

    /// The batched partial propagators (vectorised exp/sin/cos, split form)
    /// against `exp2` (libm) block by block, in both phases of every preset.
    #[test]
    fn batched_partial_propagators_match_exp2() {
        let mut worst: f64 = 0.0;
        for i in presets::one_contact() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            let mut st = EngineState::new(&sc);
            for contact in [false, true] {
                st.phase = if contact { Phase::Contact } else { Phase::Free };
                let ph = current_phase(&st, &sc);
                let Some(gens) = ph.gens.clone() else {
                    continue;
                };
                for frac in [1e-9, 0.013, 0.5, 0.999, 3.0] {
                    let tau = frac * sc.h;
                    st.part_ok = false;
                    st.ensure_partial(&sc, tau);
                    for (k, g) in gens.iter().enumerate() {
                        let want = exp2(g, tau);
                        let got = st.p_part.get(k);
                        let norm = want.iter().map(|x| x * x).sum::<f64>().sqrt();
                        let e = got
                            .iter()
                            .zip(&want)
                            .map(|(a, b)| (a - b).abs())
                            .fold(0.0, f64::max)
                            / norm;
                        worst = worst.max(e);
                        assert!(
                            e < 1e-15,
                            "preset {i} contact {contact} tau {tau:e} block {k}: {e:e}"
                        );
                    }
                }
            }
        }
        println!("batched partial propagators vs exp2: worst {worst:.1e} of the block norm");
    }

    /// A voice of `sc` in the free or the contact phase, at time scale
    /// `scale`, its block state filled with a fixed pattern of size `size`
    /// (every block ringing), the hammer at 0.1 mm falling at 0.3 m/s;
    /// `None` where that phase is not in blocks.
    fn ringing_state(
        sc: &CompiledScene,
        contact: bool,
        seed: usize,
        scale: f64,
        size: f64,
    ) -> Option<EngineState> {
        let mut st = EngineState::new(sc);
        st.set_time_scale(sc, scale).unwrap();
        st.phase = if contact { Phase::Contact } else { Phase::Free };
        current_phase(&st, sc).gens.as_ref()?;
        st.x_h = 1e-4;
        st.v_h = -0.3;
        let dim = current_phase(&st, sc).dim;
        for j in 0..dim {
            let v = size * ((j * seed % 101) as f64 / 101.0 - 0.5);
            st.phases[st.phase.index()].s[j] = v;
        }
        Some(st)
    }

    /// The fast path's margin bounds how far `phi` strays from the chord
    /// between a step's end values, checked against `phi` through the state
    /// (exact partial propagators) at 64 instants of each of 6 later steps,
    /// in both phases of every preset, for steps of half, one and three
    /// samples (a note pitched an octave and more up), with the margin
    /// taken once at the start; and it is never above the curvature bound's.
    #[test]
    fn fast_margin_bounds_the_chord_error() {
        let (mut tightest, mut used) = (f64::INFINITY, 0.0f64);
        for i in presets::one_contact() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            for contact in [false, true] {
                for (seed, mult) in [(7919usize, 0.5), (104_729, 1.0), (1299, 3.0)] {
                    let Some(mut st) = ringing_state(&sc, contact, seed, 1.0, 1e-3) else {
                        continue;
                    };
                    let dt = mult * st.step_s;
                    let margin = st.fast_margin(&sc, dt);
                    let ph = current_phase(&st, &sc);
                    let (e, w) =
                        kernel::block_measures(&st.phases[st.phase.index()].s, &ph.ev_dd_block);
                    let curv = (ph.ev_dd_norm * ph.ev_dd_norm * e)
                        .min(ph.ev_dd_block_sum * w)
                        .sqrt();
                    let g = if contact { 0.0 } else { st.g };
                    let old = (g + curv) * dt * dt / 8.0 * (1.0 + 1e-12);
                    assert!(margin <= old, "preset {i}: {margin:e} > {old:e}");
                    tightest = tightest.min(margin / old);
                    for _ in 0..6 {
                        let f0 = st.eval_event3(&sc, 0.0, false)[0];
                        let f1 = st.eval_event3(&sc, dt, false)[0];
                        for j in 1..64 {
                            let t = dt * j as f64 / 64.0;
                            st.part_ok = false;
                            let f = st.eval_event3(&sc, t, false)[0];
                            let chord = f0 + (f1 - f0) * (j as f64 / 64.0);
                            let dev = (f - chord).abs();
                            used = used.max(dev / margin);
                            assert!(
                                dev <= margin,
                                "preset {i} contact {contact} step x{mult}: |phi - chord| = {dev:e} > {margin:e}"
                            );
                        }
                        st.part_ok = false;
                        st.advance_by(&sc, dt, false);
                        st.part_ok = false;
                    }
                }
            }
        }
        println!(
            "fast margin: at most {used:.3} of it used; down to {tightest:.3} of the curvature bound's"
        );
    }

    /// The Hermite certificate's remainder bounds what the cubic Hermite
    /// interpolant of `phi` (value and slope at both ends, evaluated
    /// through the state) misses of `phi` at 64 instants of each of 6
    /// later steps, in both phases of every preset, for steps of half, one
    /// and three samples, the remainder taken from the state at each
    /// step's start.
    #[test]
    fn hermite_remainder_bounds_the_interpolation_error() {
        let mut used = 0.0f64;
        for i in presets::one_contact() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            for contact in [false, true] {
                for (seed, mult) in [(7919usize, 0.5), (104_729, 1.0), (1299, 3.0)] {
                    let Some(mut st) = ringing_state(&sc, contact, seed, 1.0, 1e-3) else {
                        continue;
                    };
                    let dt = mult * st.step_s;
                    let (dt4, tail) = (dt.powi(4) / 384.0, 8.0 / 27.0 * dt);
                    for _ in 0..6 {
                        let ph = current_phase(&st, &sc);
                        let s = &st.phases[st.phase.index()].s;
                        let nb = ph.dim / 2;
                        let rem: f64 = (0..nb)
                            .map(|k| {
                                kernel::hermite_block(
                                    ph.ev_d_block[k],
                                    ph.ev_d4_block[k],
                                    ph.ev_block[k],
                                    dt4,
                                    tail,
                                ) * s[k].hypot(s[nb + k])
                            })
                            .sum();
                        st.part_ok = false;
                        let [f0, d0, _] = st.eval_event3(&sc, 0.0, false);
                        st.part_ok = false;
                        let [f1, d1, _] = st.eval_event3(&sc, dt, false);
                        for j in 1..64 {
                            let u = j as f64 / 64.0;
                            st.part_ok = false;
                            let f = st.eval_event3(&sc, u * dt, false)[0];
                            let h = f0 * (2.0 * u * u * u - 3.0 * u * u + 1.0)
                                + dt * d0 * (u * u * u - 2.0 * u * u + u)
                                + f1 * (-2.0 * u * u * u + 3.0 * u * u)
                                + dt * d1 * (u * u * u - u * u);
                            let dev = (f - h).abs();
                            used = used.max(dev / rem);
                            assert!(
                                dev <= rem,
                                "preset {i} contact {contact} step x{mult}: |phi - H| = {dev:e} > {rem:e}"
                            );
                        }
                        st.part_ok = false;
                        st.advance_by(&sc, dt, false);
                        st.part_ok = false;
                    }
                }
            }
        }
        println!("Hermite remainder: at most {used:.3} of it used");
        assert!(used > 1e-3, "the test should come near its bound somewhere");
    }

    /// Where the Hermite certificate clears a sample, the search finds no
    /// crossing in it and the state is bit for bit the search's: states of
    /// every preset in both phases, scaled so that `phi` starts from a
    /// margin of 1e-3 down to 1e-12 of the motion (clears and refusals
    /// both happen), at one and 2.7 samples' steps.
    #[test]
    fn hermite_clear_agrees_with_the_search() {
        let (mut cleared, mut refused) = (0usize, 0usize);
        for i in presets::one_contact() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            for contact in [false, true] {
                for (seed, scale) in [(7919usize, 1.0), (1299, 2.7)] {
                    for gap in [1e-3, 1e-5, 1e-7, 1e-9, 1e-12, -1e-9] {
                        let Some(mut st) = ringing_state(&sc, contact, seed, scale, 1e-4) else {
                            continue;
                        };
                        // put phi(0) at `gap` (times the motion's size)
                        st.part_ok = false;
                        let f = st.eval_event3(&sc, 0.0, false)[0];
                        let size = 1e-4;
                        if contact {
                            // scale the state: phi = ev.s + off
                            let off = sc.offsets.pi / sc.sk;
                            let evs = f - off;
                            if evs.abs() < 1e-300 {
                                continue;
                            }
                            let want = gap * size - off;
                            let k = want / evs;
                            for x in st.phases[st.phase.index()].s.iter_mut() {
                                *x *= k;
                            }
                        } else {
                            st.x_h += gap * size - f;
                        }
                        let mut a = st.clone();
                        let mut b = st.clone();
                        if a.hermite_clear(&sc) {
                            cleared += 1;
                            let step = b.step_s;
                            b.build_model(&sc, step);
                            let mut nodes = 0;
                            let found = b.first_root(&sc, step, false, &mut nodes);
                            assert!(
                                matches!(found, Found::None),
                                "preset {i} contact {contact} gap {gap:e}: cleared, but the search finds a crossing"
                            );
                            b.advance_by(&sc, step, true);
                            let (sa, sb) =
                                (&a.phases[a.phase.index()].s, &b.phases[b.phase.index()].s);
                            assert!(
                                sa.iter().zip(sb).all(|(x, y)| x.to_bits() == y.to_bits())
                                    && a.x_h.to_bits() == b.x_h.to_bits()
                                    && a.v_h.to_bits() == b.v_h.to_bits(),
                                "preset {i} contact {contact} gap {gap:e}: not the search's state"
                            );
                        } else {
                            refused += 1;
                            let (sa, sb) =
                                (&a.phases[a.phase.index()].s, &st.phases[st.phase.index()].s);
                            assert!(
                                sa.iter().zip(sb).all(|(x, y)| x.to_bits() == y.to_bits()),
                                "a refusal changed the state"
                            );
                        }
                    }
                }
            }
        }
        println!("Hermite certificate: {cleared} samples cleared, {refused} left to the search");
        assert!(cleared > 20 && refused > 20);
    }

    /// The search's model of `phi` (slow polynomial + fast blocks + other
    /// blocks + polynomial part) against `phi` through the state (a sweep
    /// of exact partial propagators), in both phases of every preset, at
    /// several instants of a sample, with the state of a ringing object.
    #[test]
    fn model_matches_the_state_evaluation() {
        let mut worst = [0.0f64; 3];
        for i in presets::one_contact() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            let mut st = EngineState::new(&sc);
            // ring the object: one strike's worth of state in every block
            for contact in [false, true] {
                st.phase = if contact { Phase::Contact } else { Phase::Free };
                st.x_h = 1e-4;
                st.v_h = -0.3;
                let dim = current_phase(&st, &sc).dim;
                for j in 0..dim {
                    let v = 1e-3 * ((j * 7919 % 101) as f64 / 101.0 - 0.5);
                    st.phases[st.phase.index()].s[j] = v;
                }
                st.part_ok = false;
                let step = st.step_s;
                st.build_model(&sc, step);
                for frac in [0.0, 1e-9, 0.013, 0.5, 0.999, 1.0] {
                    let tau = frac * step;
                    let want = st.eval_event3(&sc, tau, false);
                    let got = st.model_eval(&sc, tau);
                    // value and slope within the model's rounding
                    // allowances; curvature to 1e-12 of its scale
                    let curv_scale = st.search.tol_d / (ROUND_UNITS * f64::EPSILON) / step;
                    let tols = [st.search.tol, st.search.tol_d, 1e-12 * curv_scale];
                    for d in 0..3 {
                        let e = (got[d] - want[d]).abs();
                        worst[d] = worst[d].max(e / tols[d]);
                        assert!(
                            e <= tols[d],
                            "preset {i} contact {contact} tau {tau:e} deriv {d}: model {} state {} (allowance {:e})",
                            got[d],
                            want[d],
                            tols[d]
                        );
                    }
                }
            }
        }
        println!(
            "model vs state evaluation: worst {:.3} / {:.3} / {:.3} of the allowance (value / slope / curvature)",
            worst[0], worst[1], worst[2]
        );
    }
}
