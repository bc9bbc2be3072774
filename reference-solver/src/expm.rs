//! The reference solver: exact phase flows by dense matrix exponentials,
//! switches located by bisection on the exact flow.
//!
//! Each sample period `h` is cut into `m` equal sub-steps of the current phase
//! (`|B|_1 h / m <= 0.5`, see [`crate::phase`]). On every sub-step the
//! penetration `p` and `p'` are checked at both ends: a change of the
//! "switched" side brackets a crossing; otherwise, if `p` moves toward
//! switching at the start and away at the end, its interior extremum is
//! located (bisection on `p'`) and, if `p` has switched there, the crossing
//! lies between the start and the extremum. Brackets are refined by
//! bisection on the exact flow `exp(B tau) y` down to one time unit (`<=
//! 1e-15` of a sample). Time inside a sub-step is an integer count of units,
//! a power of two per sub-step, so every bisection midpoint is reached from
//! the bracket's left end with the precomputed `exp(B h/m 2^-j)` (one
//! product per bit of the offset).
//!
//! Exact states (double-double, see [`crate::dd`]) are kept at anchors: the
//! sample's start, the state after each switch and at the end of the partial
//! step that follows it. A grid point `j` sub-steps after an anchor is
//! reached exactly by one product per set bit of `j`. Between anchors an
//! f64 copy is marched one sub-step at a time with nalgebra's Pade `exp(B
//! h/m)`; it only decides where to search: any sub-step it flags is
//! re-derived exactly from the anchor and searched exactly, and it is
//! re-anchored every [`RESYNC`] sub-steps and at the sample's end.
//!
//! At a switch the state carries over unchanged (positions and velocities
//! are continuous) and the new phase runs a partial step to the next point
//! of its own sub-step grid (Taylor series `exp(B tau) y` for the odd
//! length, searched the same way), then whole sub-steps to the sample
//! instant. Any number of switches may happen inside a sub-step or a sample.

use crate::dd::Dd;
use crate::phase::{matvec, Phase, MAX_NORM_STEP, RESYNC};
use crate::{record_switch, switched, toward, ContactInterval, Model, Solution, Stats};

/// Switches per sample beyond which the run is declared a loop (a physical
/// run at these stiffnesses has a handful).
const MAX_SWITCHES_PER_SAMPLE: usize = 100_000;

/// How the states inside one step are reached from its start.
enum Flow<'a> {
    /// A whole sub-step: units of `h_sub 2^-levels`, precomputed powers.
    Grid(&'a Phase),
    /// A partial step of `2^levels` units of `unit` seconds (Taylor series
    /// per point).
    Partial {
        phase: &'a Phase,
        unit: f64,
        levels: u32,
    },
}

impl Flow<'_> {
    fn phase(&self) -> &Phase {
        match self {
            Flow::Grid(p) => p,
            Flow::Partial { phase, .. } => phase,
        }
    }

    fn levels(&self) -> u32 {
        match self {
            Flow::Grid(p) => p.levels,
            Flow::Partial { levels, .. } => *levels,
        }
    }

    /// Step length [s].
    fn length(&self) -> f64 {
        match self {
            Flow::Grid(p) => p.h_sub,
            Flow::Partial { unit, levels, .. } => unit * 2f64.powi(*levels as i32),
        }
    }

    /// The exact state `units` time units after `y`.
    fn advance(&self, y: &[Dd], units: u64) -> Vec<Dd> {
        match self {
            Flow::Grid(p) => p.advance_fine(y, units),
            Flow::Partial { phase, unit, .. } => phase.exp_apply(unit * units as f64, y),
        }
    }
}

/// Search one step for the first switch of any contact. `y0`, `y1`: exact
/// states at its start and end (`y0` not switched). Returns the unit count
/// and the exact state of the earliest switched point found, or `None`.
fn search(flow: &Flow, y0: &[Dd], y1: &[Dd], stats: &mut Stats) -> Option<(u64, Vec<Dd>)> {
    let mut best: Option<(u64, Vec<Dd>)> = None;
    for c in 0..flow.phase().row_p.len() {
        if let Some((u, y)) = search_contact(flow, c, y0, y1, stats) {
            if best.as_ref().is_none_or(|(b, _)| u < *b) {
                best = Some((u, y));
            }
        }
    }
    best
}

/// [`search`] for contact `c` alone.
fn search_contact(
    flow: &Flow,
    c: usize,
    y0: &[Dd],
    y1: &[Dd],
    stats: &mut Stats,
) -> Option<(u64, Vec<Dd>)> {
    let ph = flow.phase();
    let inc = ph.in_contact(c);
    let total = 1u64 << flow.levels();
    let (p1, d1) = ph.event_dd(c, y1);
    if switched(inc, p1) {
        return Some(refine(flow, c, 0, y0.to_vec(), total, y1.to_vec()));
    }
    let (_, d0) = ph.event_dd(c, y0);
    if !(toward(inc, d0) > 0.0 && toward(inc, d1) <= 0.0) {
        return None;
    }
    // an interior extremum of p toward switching: bisection on p'
    stats.extremum_searches += 1;
    let (mut lo, mut ylo, mut hi) = (0u64, y0.to_vec(), total);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        let ym = flow.advance(&ylo, mid - lo);
        let (pm, dm) = ph.event_dd(c, &ym);
        if switched(inc, pm) {
            return Some(refine(flow, c, 0, y0.to_vec(), mid, ym));
        }
        if toward(inc, dm) > 0.0 {
            lo = mid;
            ylo = ym;
        } else {
            hi = mid;
        }
    }
    let yh = flow.advance(&ylo, 1);
    if switched(inc, ph.event_dd(c, &yh).0) {
        return Some(refine(flow, c, 0, y0.to_vec(), hi, yh));
    }
    None
}

/// Bisection on `[a, b]` (unit counts) with `a` not switched and `b`
/// switched (contact `c`), down to one unit. Returns `b` and the state
/// there, as evaluated when `b` was found switched (so the new phase starts
/// exactly on its side).
fn refine(
    flow: &Flow,
    c: usize,
    mut a: u64,
    mut ya: Vec<Dd>,
    mut b: u64,
    mut yb: Vec<Dd>,
) -> (u64, Vec<Dd>) {
    let ph = flow.phase();
    while b - a > 1 {
        let mid = a + (b - a) / 2;
        let ym = flow.advance(&ya, mid - a);
        if switched(ph.in_contact(c), ph.event_dd(c, &ym).0) {
            b = mid;
            yb = ym;
        } else {
            a = mid;
            ya = ym;
        }
    }
    (b, yb)
}

/// Whether the marched f64 step `y0 -> y1` may hold a switch of any
/// contact (the tests [`search`] makes first, with a margin: a point within
/// 1e-12 of the largest term of `p` from the switching side counts, so the
/// marched copy's drift, ~`RESYNC u` = 3e-14, cannot hide a crossing the
/// exact states have; a wider margin would flag every sub-step of a hammer
/// resting under gravity on a stiff contact, compressed by `m g / k` ~
/// 1e-10 of its height at 1000x Nyquist).
fn may_switch(ph: &Phase, y0: &[f64], y1: &[f64]) -> bool {
    (0..ph.row_p.len()).any(|c| {
        let (p0, d0) = ph.event(c, y0);
        let (p1, d1) = ph.event(c, y1);
        let scale = ph.row_p[c]
            .iter()
            .zip(y1)
            .map(|(r, y)| (r * y).abs())
            .fold(0.0, f64::max);
        let margin = 1e-12 * scale;
        let inc = ph.in_contact(c);
        let near = |p: f64| if inc { p <= margin } else { p > -margin };
        near(p0) || near(p1) || (toward(inc, d0) > 0.0 && toward(inc, d1) <= 0.0)
    })
}

fn to_f64(y: &[Dd]) -> Vec<f64> {
    y.iter().map(|v| v.to_f64()).collect()
}

/// Solve `model` for `n` samples at `rate_hz` (the reference solution).
pub fn solve(model: &Model, rate_hz: f64, n: usize) -> Solution {
    solve_with_substeps(model, rate_hz, n, MAX_NORM_STEP)
}

/// [`solve`] with sub-steps of `|B|_1 h_sub <= max_norm_step` instead of
/// 0.5: the flows are exact, so the result must not depend on it beyond
/// rounding (a convergence check of the reference itself).
pub fn solve_with_substeps(model: &Model, rate_hz: f64, n: usize, max_norm_step: f64) -> Solution {
    solve_driven(model, None, rate_hz, n, max_norm_step)
}

/// [`solve`] with the hammer's contact on a moving surface: `surface_m[i]`
/// is its height \[m\] at the sample instant `i / rate_hz`, linear in
/// between (at least `n + 1` heights for `n` samples; see the crate's
/// documentation). [`Sample::surface_m`] and [`Sample::surface_work_j`]
/// report it.
///
/// [`Sample::surface_m`]: crate::Sample::surface_m
/// [`Sample::surface_work_j`]: crate::Sample::surface_work_j
pub fn solve_on_surface(model: &Model, surface_m: &[f64], rate_hz: f64, n: usize) -> Solution {
    solve_driven(model, Some(surface_m), rate_hz, n, MAX_NORM_STEP)
}

/// The surface over sample `i` of period `h`: its height at the sample's
/// start and its rate, exact in double-double (the rate is the heights'
/// difference over `h`, so that the flow reaches the next height at the
/// sample's end), or `None` where it rests at 0 over the whole sample.
fn drive_of(surface_m: &[f64], i: usize, h: f64) -> Option<(Dd, Dd)> {
    let (s0, s1) = (surface_m[i], surface_m[i + 1]);
    if s0 == 0.0 && s1 == 0.0 {
        return None;
    }
    Some((
        Dd::from_f64(s0),
        (Dd::from_f64(s1) - Dd::from_f64(s0)).div_f64(h),
    ))
}

/// [`solve_with_substeps`], on the moving surface `surface_m` if any (see
/// [`solve_on_surface`]).
pub(crate) fn solve_driven(
    model: &Model,
    surface_m: Option<&[f64]>,
    rate_hz: f64,
    n: usize,
    max_norm_step: f64,
) -> Solution {
    let h = 1.0 / rate_hz;
    model.check();
    if let Some(s) = surface_m {
        assert!(
            s.len() > n,
            "surface: {} heights for {n} samples (n + 1 needed)",
            s.len()
        );
        assert!(s[..=n].iter().all(|x| x.is_finite()), "surface: not finite");
    }
    // every subset of contacts in contact, by its bit set; the same on the
    // surface
    let build = |driven: bool| -> Vec<Phase> {
        (0..1u32 << model.n_contacts())
            .map(|active| Phase::new(model, active, h, max_norm_step, driven))
            .collect()
    };
    let phases = build(false);
    let driven_phases = if surface_m.is_some() {
        build(true)
    } else {
        Vec::new()
    };
    let stats = Stats {
        substeps_per_sample: [phases[0].m, phases[1].m],
        norms: [phases[0].norm, phases[1].norm],
        ..Stats::default()
    };
    let z0: Vec<Dd> = model
        .initial_state()
        .into_iter()
        .map(Dd::from_f64)
        .collect();
    // the exact state at the current sample instant
    let mut y = phases[0].to_balanced(&z0);
    let mut run = Run {
        model,
        phases: [phases, driven_phases],
        driven: false,
        h,
        active: 0,
        stats,
        contacts: Vec::new(),
    };
    let mut work = Dd::ZERO;
    let mut samples = Vec::with_capacity(n + 1);
    let mut first = run.observe(&y, work);
    // (not in contact yet: the surface is in no energy)
    first.surface_m = surface_m.map_or(0.0, |s| s[0]);
    samples.push(first);
    for i in 0..n {
        let drive = surface_m.and_then(|s| drive_of(s, i, h));
        y = run.enter(y, drive);
        y = run.sample(y, i);
        if let Some((_, v)) = drive {
            // the work of the surface over the sample: v times the impulse
            work = work + v * run.impulse(&y);
        }
        samples.push(run.observe(&y, work));
    }
    Solution {
        rate_hz,
        samples,
        contacts: run.contacts,
        stats: run.stats,
    }
}

/// A run in progress: the model's phases and what the run has recorded.
struct Run<'a> {
    model: &'a Model,
    /// Every subset of contacts in contact, by its bit set: without the
    /// surface, and on it (empty without one).
    phases: [Vec<Phase>; 2],
    /// Whether the current sample is on the surface (`phases[1]`).
    driven: bool,
    /// Sample period \[s\].
    h: f64,
    /// The contacts in contact (bit `c` for contact `c`).
    active: u32,
    stats: Stats,
    contacts: Vec<ContactInterval>,
}

impl Run<'_> {
    /// The phase the run is in.
    fn phase(&self) -> &Phase {
        &self.phases[self.driven as usize][self.active as usize]
    }

    /// The exact state `y` at a sample's start (balanced coordinates of
    /// the current phase) in the phase of the sample to come: on the
    /// surface with `drive = Some((s, v))`, its height and rate set (and
    /// the impulse to 0), off it without.
    fn enter(&mut self, y: Vec<Dd>, drive: Option<(Dd, Dd)>) -> Vec<Dd> {
        if !self.driven && drive.is_none() {
            return y;
        }
        let mut z = self.phase().to_physical(&y);
        z.truncate(self.model.state_dim());
        if let Some((s, v)) = drive {
            z.extend([s, v, Dd::ZERO]);
        }
        self.driven = drive.is_some();
        self.phase().to_balanced(&z)
    }

    /// The impulse of the hammer's contact force since the sample's start
    /// in the exact driven state `y`.
    fn impulse(&self, y: &[Dd]) -> Dd {
        self.phase().to_physical(y)[self.model.state_dim() + 2]
    }

    /// The observation of the exact state `y`, the surface's work so far
    /// `work`.
    fn observe(&self, y: &[Dd], work: Dd) -> crate::Sample {
        let z = to_f64(&self.phase().to_physical(y));
        let nz = self.model.state_dim();
        let s = if self.driven { z[nz] } else { 0.0 };
        let mut sample = self.model.observe_on(&z[..nz], self.active, s);
        sample.surface_work_j = work.to_f64();
        sample
    }

    /// Advance the exact state `y` (balanced coordinates of the current
    /// phase) over sample `i`, switching phase at every switch inside it.
    /// Returns the exact state at the sample's end.
    fn sample(&mut self, y: Vec<Dd>, i: usize) -> Vec<Dd> {
        let h = self.h;
        let t_n = i as f64 * h;
        let mut march = March::new(y);
        let set = &self.phases[self.driven as usize];
        loop {
            let ph = &set[self.active as usize];
            let next = if march.on_grid {
                march.grid_step(ph, &mut self.stats)
            } else {
                march.partial_step(ph, h, &mut self.stats)
            };
            let (flow, t_start, units, ys) = match next {
                Next::SampleEnd => return march.anchor,
                Next::NoSwitch => continue,
                Next::Switch {
                    flow,
                    t_start,
                    units,
                    ys,
                } => (flow, t_start, units, ys),
            };
            // a switch inside the step
            let frac = units as f64 / 2f64.powi(flow.levels() as i32);
            march.t = (t_start + frac * flow.length()).min(h);
            let z = ph.to_physical(&ys);
            // every contact switched at this point changes side (the one
            // found first, and any that switched at the same instant)
            for c in 0..self.model.n_contacts() {
                if !switched(ph.in_contact(c), ph.event_dd(c, &ys).0) {
                    continue;
                }
                self.active ^= 1 << c;
                let inc = self.active & (1 << c) != 0;
                record_switch(&mut self.contacts, c, inc, t_n + march.t);
            }
            let ph_new = &set[self.active as usize];
            march.y = ph_new.to_balanced(&z);
            self.stats.switches += 1;
            march.switches += 1;
            assert!(
                march.switches <= MAX_SWITCHES_PER_SAMPLE,
                "reference solver: more than {MAX_SWITCHES_PER_SAMPLE} switches in sample {i}"
            );
            if march.t >= h {
                march.on_grid = true;
                march.j = ph_new.m;
                march.anchor = march.y.clone();
                march.anchor_j = march.j;
            } else {
                march.on_grid = false;
            }
        }
    }
}

/// The march through one sample. On the grid: at sub-step `j` of the
/// current phase, exact anchor `(anchor_j, anchor)` and marched copy `yf`.
/// Off the grid: exact state `y` at `t` seconds into the sample, after a
/// switch.
struct March {
    on_grid: bool,
    j: usize,
    anchor_j: usize,
    anchor: Vec<Dd>,
    yf: Vec<f64>,
    /// The marched copy's next sub-step (a buffer).
    yf1: Vec<f64>,
    y: Vec<Dd>,
    t: f64,
    /// Switches so far in this sample.
    switches: usize,
}

/// What one step of a [`March`] came to.
enum Next<'p> {
    /// The sample instant is reached: the state is the anchor.
    SampleEnd,
    /// The step held no switch; the march moved past it.
    NoSwitch,
    /// A switch inside the step `flow` starting `t_start` seconds into the
    /// sample: `units` time units into it, exact state `ys` there.
    Switch {
        flow: Flow<'p>,
        t_start: f64,
        units: u64,
        ys: Vec<Dd>,
    },
}

impl March {
    /// On the grid at sub-step 0, anchored at the exact state `y`.
    fn new(y: Vec<Dd>) -> Self {
        let yf = to_f64(&y);
        March {
            on_grid: true,
            j: 0,
            anchor_j: 0,
            anchor: y.clone(),
            yf1: vec![0.0; yf.len()],
            yf,
            y,
            t: 0.0,
            switches: 0,
        }
    }

    /// On the grid at sub-step `j`, anchored there at the exact state
    /// `anchor`.
    fn reanchor(&mut self, j: usize, anchor: Vec<Dd>) {
        self.j = j;
        self.anchor_j = j;
        self.yf = to_f64(&anchor);
        self.anchor = anchor;
    }

    /// One whole sub-step of the phase `ph` on its grid: marched in f64,
    /// and searched on exact states when the marched step may hold a
    /// switch.
    fn grid_step<'p>(&mut self, ph: &'p Phase, stats: &mut Stats) -> Next<'p> {
        if self.j == ph.m {
            debug_assert_eq!(self.anchor_j, self.j);
            return Next::SampleEnd;
        }
        matvec(&ph.e1, &self.yf, &mut self.yf1);
        stats.steps += 1;
        if !may_switch(ph, &self.yf, &self.yf1) {
            std::mem::swap(&mut self.yf, &mut self.yf1);
            self.j += 1;
            if self.j == ph.m || (self.j - self.anchor_j).is_multiple_of(RESYNC) {
                let anchor = ph.advance_grid(&self.anchor, self.j - self.anchor_j);
                self.reanchor(self.j, anchor);
            }
            return Next::NoSwitch;
        }
        // search this sub-step on exact states
        let y0 = ph.advance_grid(&self.anchor, self.j - self.anchor_j);
        let y1 = ph.advance_grid(&y0, 1);
        let flow = Flow::Grid(ph);
        let t_start = self.j as f64 * ph.h_sub;
        match search(&flow, &y0, &y1, stats) {
            None => {
                self.reanchor(self.j + 1, y1);
                Next::NoSwitch
            }
            Some((units, ys)) => Next::Switch {
                flow,
                t_start,
                units,
                ys,
            },
        }
    }

    /// The partial step of the phase `ph` from `t` to its next grid point
    /// (or the sample's end, `h` seconds), searched on exact states.
    fn partial_step<'p>(&mut self, ph: &'p Phase, h: f64, stats: &mut Stats) -> Next<'p> {
        let mut jn = (self.t / ph.h_sub).floor() as usize + 1;
        while jn < ph.m && jn as f64 * ph.h_sub <= self.t {
            jn += 1;
        }
        let end = if jn >= ph.m { h } else { jn as f64 * ph.h_sub };
        let tau = end - self.t;
        let levels = ((tau / (crate::TIME_RESOLUTION * h)).log2().ceil() as u32).clamp(1, 62);
        let y1 = ph.exp_apply(tau, &self.y);
        stats.steps += 1;
        let flow = Flow::Partial {
            phase: ph,
            unit: tau / 2f64.powi(levels as i32),
            levels,
        };
        match search(&flow, &self.y, &y1, stats) {
            None => {
                self.on_grid = true;
                self.reanchor(jn.min(ph.m), y1);
                Next::NoSwitch
            }
            Some((units, ys)) => Next::Switch {
                flow,
                t_start: self.t,
                units,
                ys,
            },
        }
    }
}
