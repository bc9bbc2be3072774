//! The reference solver: exact phase flows by dense matrix exponentials,
//! switches located by bisection on the exact flow.
//!
//! Each sample period `h` is cut into `m` equal sub-steps of the current phase
//! (`|B|_1 h / m <= 0.5`, see [`crate::phase`]); a sub-step is one product
//! with `exp(B h/m)`. On every sub-step the penetration `p` and `p'` are
//! checked at both ends: a change of the "switched" side brackets a crossing;
//! otherwise, if `p` moves toward switching at the start and away at the end,
//! its interior extremum is located (bisection on `p'`) and, if `p` has
//! switched there, the crossing lies between the start and the extremum.
//! Brackets are refined by bisection on the exact flow `exp(B tau) y` down to
//! one time unit (`<= 1e-15` of a sample). Time inside a sub-step is an
//! integer count of units, a power of two per sub-step, so every bisection
//! midpoint is reached from the bracket's left end with the precomputed
//! `exp(B h/m 2^-j)` (one product per bit of the offset).
//!
//! At a switch the state carries over unchanged (positions and velocities
//! are continuous) and the new phase runs a partial step to the next point of
//! its own sub-step grid (Pade `exp(B tau)` for the odd lengths, searched the
//! same way), then whole sub-steps to the sample instant. Any number of
//! switches may happen inside a sub-step or a sample.

use crate::phase::{matvec, Phase, MAX_NORM_STEP, RESYNC};
use crate::{switched, toward, ContactInterval, Model, Solution, Stats};
use std::cell::RefCell;

/// Switches per sample beyond which the run is declared a loop (a physical
/// run at these stiffnesses has a handful).
const MAX_SWITCHES_PER_SAMPLE: usize = 100_000;

/// How the states inside one step are reached from its start.
enum Flow<'a> {
    /// A whole sub-step: units of `h_sub 2^-levels`, precomputed powers.
    Grid(&'a Phase),
    /// A partial step of `2^levels` units of `unit` seconds; `exp(B unit
    /// 2^l)` computed on first use.
    Partial {
        phase: &'a Phase,
        unit: f64,
        levels: u32,
        cache: RefCell<Vec<Option<Vec<f64>>>>,
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

    /// The state `units` time units after `y` (one product per set bit).
    fn advance(&self, y: &[f64], units: u64) -> Vec<f64> {
        let mut cur = y.to_vec();
        let mut tmp = vec![0.0; y.len()];
        let levels = self.levels();
        for l in 0..=levels {
            if units & (1u64 << l) == 0 {
                continue;
            }
            match self {
                Flow::Grid(p) => matvec(&p.e[(levels - l) as usize], &cur, &mut tmp),
                Flow::Partial {
                    phase, unit, cache, ..
                } => {
                    let mut c = cache.borrow_mut();
                    let e = c[l as usize]
                        .get_or_insert_with(|| phase.exp_flat(unit * 2f64.powi(l as i32)));
                    matvec(e, &cur, &mut tmp);
                }
            }
            std::mem::swap(&mut cur, &mut tmp);
        }
        cur
    }
}

/// Search one step for the first switch. `y0`, `y1`: states at its start and
/// end (`y0` not switched). Returns the unit count and the state of the first
/// switched point found, or `None`.
fn search(flow: &Flow, y0: &[f64], y1: &[f64], stats: &mut Stats) -> Option<(u64, Vec<f64>)> {
    let ph = flow.phase();
    let c = ph.contact;
    let total = 1u64 << flow.levels();
    let (p1, d1) = ph.event(y1);
    if switched(c, p1) {
        return Some(refine(flow, 0, y0.to_vec(), total, y1.to_vec()));
    }
    let (_, d0) = ph.event(y0);
    if !(toward(c, d0) > 0.0 && toward(c, d1) <= 0.0) {
        return None;
    }
    // an interior extremum of p toward switching: bisection on p'
    stats.extremum_searches += 1;
    let (mut lo, mut ylo, mut hi) = (0u64, y0.to_vec(), total);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        let ym = flow.advance(&ylo, mid - lo);
        let (pm, dm) = ph.event(&ym);
        if switched(c, pm) {
            return Some(refine(flow, 0, y0.to_vec(), mid, ym));
        }
        if toward(c, dm) > 0.0 {
            lo = mid;
            ylo = ym;
        } else {
            hi = mid;
        }
    }
    let yh = flow.advance(&ylo, 1);
    if switched(c, ph.event(&yh).0) {
        return Some(refine(flow, 0, y0.to_vec(), hi, yh));
    }
    None
}

/// Bisection on `[a, b]` (unit counts) with `a` not switched and `b`
/// switched, down to one unit. Returns `b` and the state there, as evaluated
/// when `b` was found switched (so the new phase starts exactly on its side).
fn refine(
    flow: &Flow,
    mut a: u64,
    mut ya: Vec<f64>,
    mut b: u64,
    mut yb: Vec<f64>,
) -> (u64, Vec<f64>) {
    let ph = flow.phase();
    while b - a > 1 {
        let mid = a + (b - a) / 2;
        let ym = flow.advance(&ya, mid - a);
        if switched(ph.contact, ph.event(&ym).0) {
            b = mid;
            yb = ym;
        } else {
            a = mid;
            ya = ym;
        }
    }
    (b, yb)
}

/// Solve `model` for `n` samples at `rate_hz` (the reference solution).
pub fn solve(model: &Model, rate_hz: f64, n: usize) -> Solution {
    solve_with_substeps(model, rate_hz, n, MAX_NORM_STEP)
}

/// [`solve`] with sub-steps of `|B|_1 h_sub <= max_norm_step` instead of
/// 0.5: the flows are exact, so the result must not depend on it beyond
/// rounding (a convergence check of the reference itself).
pub fn solve_with_substeps(model: &Model, rate_hz: f64, n: usize, max_norm_step: f64) -> Solution {
    let h = 1.0 / rate_hz;
    let phases = [
        Phase::new(model, false, h, max_norm_step),
        Phase::new(model, true, h, max_norm_step),
    ];
    let mut stats = Stats {
        substeps_per_sample: [phases[0].m, phases[1].m],
        norms: [phases[0].norm, phases[1].norm],
        ..Stats::default()
    };
    let mut in_contact = false;
    let mut y = phases[0].to_balanced(&model.initial_state());
    let mut samples = Vec::with_capacity(n + 1);
    samples.push(model.observe(&phases[0].to_physical(&y), false));
    let mut contacts: Vec<ContactInterval> = Vec::new();
    let mut y1 = vec![0.0; y.len()];
    for i in 0..n {
        let t_n = i as f64 * h;
        // Position in the sample: on the current phase's grid point j, or
        // `t` seconds into the sample, off the grid, after a switch. The
        // marched state `y` is re-derived from the anchor (the last grid
        // point reached exactly: the sample start, or the end of the
        // partial step after a switch) every RESYNC sub-steps, before any
        // search and at the sample's end.
        let mut on_grid: Option<usize> = Some(0);
        let mut anchor = (0usize, y.clone());
        let mut t = 0.0;
        let mut switches = 0usize;
        loop {
            let ph = &phases[in_contact as usize];
            let (flow, t_start, next) = match on_grid {
                Some(j) if j == ph.m => break,
                Some(j) => {
                    matvec(&ph.e[0], &y, &mut y1);
                    if j > anchor.0 && may_switch(ph, &y, &y1) {
                        // search from exact states, not marched ones
                        y = ph.advance_grid(&anchor.1, j - anchor.0);
                        y1 = ph.advance_grid(&anchor.1, j + 1 - anchor.0);
                    }
                    (Flow::Grid(ph), j as f64 * ph.h_sub, j + 1)
                }
                None => {
                    // partial step to the next grid point of this phase
                    let mut j = (t / ph.h_sub).floor() as usize + 1;
                    while j < ph.m && j as f64 * ph.h_sub <= t {
                        j += 1;
                    }
                    let end = if j >= ph.m { h } else { j as f64 * ph.h_sub };
                    let tau = end - t;
                    let levels =
                        ((tau / (crate::TIME_RESOLUTION * h)).log2().ceil() as u32).clamp(1, 62);
                    let unit = tau / 2f64.powi(levels as i32);
                    let e = ph.exp_flat(tau);
                    matvec(&e, &y, &mut y1);
                    let mut cache = vec![None; levels as usize + 1];
                    cache[levels as usize] = Some(e);
                    (
                        Flow::Partial {
                            phase: ph,
                            unit,
                            levels,
                            cache: RefCell::new(cache),
                        },
                        t,
                        j.min(ph.m),
                    )
                }
            };
            stats.steps += 1;
            match search(&flow, &y, &y1, &mut stats) {
                None => {
                    std::mem::swap(&mut y, &mut y1);
                    let exact_end = match flow {
                        // a partial step ends exactly on the grid: new anchor
                        Flow::Partial { .. } => true,
                        Flow::Grid(_) => next == ph.m || (next - anchor.0).is_multiple_of(RESYNC),
                    };
                    if exact_end {
                        if matches!(flow, Flow::Grid(_)) {
                            y = ph.advance_grid(&anchor.1, next - anchor.0);
                        }
                        anchor = (next, y.clone());
                    }
                    on_grid = Some(next);
                }
                Some((units, ys)) => {
                    let frac = units as f64 / 2f64.powi(flow.levels() as i32);
                    t = (t_start + frac * flow.length()).min(h);
                    let z = ph.to_physical(&ys);
                    in_contact = !in_contact;
                    y = phases[in_contact as usize].to_balanced(&z);
                    if in_contact {
                        contacts.push(ContactInterval {
                            start_s: t_n + t,
                            end_s: None,
                        });
                    } else if let Some(last) = contacts.last_mut() {
                        last.end_s = Some(t_n + t);
                    }
                    stats.switches += 1;
                    switches += 1;
                    assert!(
                        switches <= MAX_SWITCHES_PER_SAMPLE,
                        "reference solver: more than {MAX_SWITCHES_PER_SAMPLE} switches in sample {i}"
                    );
                    on_grid = if t >= h {
                        let m = phases[in_contact as usize].m;
                        anchor = (m, y.clone());
                        Some(m)
                    } else {
                        None
                    };
                }
            }
        }
        let ph = &phases[in_contact as usize];
        samples.push(model.observe(&ph.to_physical(&y), in_contact));
    }
    Solution {
        rate_hz,
        samples,
        contacts,
        stats,
    }
}

/// Whether the marched step `y0 -> y1` may hold a switch (the same tests as
/// [`search`] makes first).
fn may_switch(ph: &Phase, y0: &[f64], y1: &[f64]) -> bool {
    let (p1, d1) = ph.event(y1);
    let (_, d0) = ph.event(y0);
    switched(ph.contact, p1) || (toward(ph.contact, d0) > 0.0 && toward(ph.contact, d1) <= 0.0)
}
