//! The certified bisection that finds the first crossing of the model in
//! the rest of a sample, and the refinement of a certified bracket to the
//! root (docs/numerics.md, "Certified isolation of the first crossing").

use super::model::NodeBounds;
use super::{NEUTRAL_TOL, ROOT_ULPS, STACK};
use crate::compile::CompiledScene;
use crate::engine::EngineState;

/// What the search found.
pub(super) enum Found {
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
    /// The first crossing of the model in `(0, rem]` (`open`: the origin is
    /// a switch instant, where `phi` is zero to rounding and rising).
    pub(super) fn first_root(
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
}
