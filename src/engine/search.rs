//! The certified search for the first crossing of an event function in the
//! rest of a sample, and the refinement of a certified bracket to the root
//! (docs/numerics.md, "Certified isolation of the first crossing"). One
//! search, with one set of tolerances, for every contact of every engine:
//! the event function is seen only through an [`EventModel`] (its bounds on
//! a node and its exact value, slope and curvature at a point), which the
//! one-contact engine builds from its slow and fast terms
//! (`engine/exact/model.rs`) and the several-contact engine from its phase's
//! blocks (`multi/search.rs`).

/// Resolution of a located switch instant, in ulps of the sample period
/// (3.6e-15 of a sample): below it the rounding of `phi` itself (`u |x_h| /
/// |phi'|`, ~1e-14 of a sample for a hammer at millimetres and 1 m/s)
/// decides, so resolving further only costs evaluations. It is also the
/// least time between two switches.
pub const ROOT_ULPS: f64 = 16.0;
/// A node is neutral when `|phi| <= NEUTRAL_TOL` roundings on all of it.
pub(crate) const NEUTRAL_TOL: f64 = 4.0;
/// Rounding allowance of a model, in units of `u` times the magnitude of
/// what is summed (each product and sum rounds once, with a margin).
pub(crate) const ROUND_UNITS: f64 = 4.0;
/// Deepest bisection: nodes never get narrower than the root resolution,
/// `2^-48` of a sample; the stack holds one pending node per level.
pub(crate) const STACK: usize = 64;

/// Bounds of `phi` on a node `[a, a + w]`: the resolved part's value, slope
/// and curvature at `a` (`q`), the bound `c3` on its third derivative, and
/// bounds on the unresolved part's value (`u`) and slope (`l`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct NodeBounds {
    pub(crate) q: [f64; 3],
    pub(crate) u: f64,
    pub(crate) l: f64,
    pub(crate) c3: f64,
}

/// An event function `phi` over the rest of a sample, as the search sees
/// it. Times count from the search's origin. \[audio-thread\]
pub(crate) trait EventModel {
    /// Bounds of `phi` on the node `[a, a + w]`.
    fn bounds(&mut self, a: f64, w: f64) -> NodeBounds;
    /// `[phi, phi', phi'']` at `t`, exact to rounding.
    fn eval(&mut self, t: f64) -> [f64; 3];
    /// The rounding allowances of `phi`'s value and of its slope.
    fn tolerances(&self) -> (f64, f64);
    /// The search's stack of pending nodes.
    fn stack(&mut self) -> &mut [(f64, f64); STACK];
}

/// What the search found.
pub(crate) enum Found {
    /// No crossing before the end of the range.
    None,
    /// Switch at this time after the search origin (`phi <= 0` there, to
    /// rounding).
    At(f64),
}

/// What a search did (its caller adds them to its counters).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Tally {
    /// Nodes examined.
    pub(crate) nodes: u64,
    /// Neutral and resolution-sized nodes that ended with `phi > 0`.
    pub(crate) grazing: u64,
    /// Nodes left undecided (none: the stack is as deep as the resolution).
    pub(crate) uncertified: u64,
    /// Roots refined, and the evaluations they took.
    pub(crate) refined: u64,
    pub(crate) root_evals: u64,
}

/// The least Bernstein coefficient of the cubic Hermite interpolant of an
/// event function's values `f0`, `f1` and slopes `d0`, `d1` at the two ends
/// of a step of `w`: a lower bound of the interpolant on the step (a cubic
/// lies in the convex hull of its control points). Both engines' Hermite
/// certificates of a whole step take it (docs/numerics.md section 6.2).
#[inline]
pub(crate) fn hermite_low([f0, d0, f1, d1]: [f64; 4], w: f64) -> f64 {
    f0.min(f1).min(f0 + d0 * w / 3.0).min(f1 - d1 * w / 3.0)
}

/// The Hermite certificate of the rest `w` of a step right after its
/// contact switched (docs/numerics.md section 6.2, "After a switch"), from
/// the event function's values and slopes at both ends, the bounds `m4` on
/// its fourth derivative and `m2` on its second over the rest, and the
/// rounding allowances of the values (`allow`) and of the slope (`allow_d`):
/// with `u = t / w`, `phi >= phi_0 + u k` where `k` is the least of the
/// quadratic `K`'s Bernstein coefficients (`w phi'_0`, `1.5 phi_1 - 0.5 w
/// phi'_1`, `phi_1`) less `m4 w^4 / 162` and twice the allowance; where
/// `phi_0` is below 0, `phi' >= phi'_0 - t m2` keeps it rising until `u_1 =
/// 2 |phi_0| / k`. `true`: no crossing downwards in the rest. Both engines
/// take it.
#[inline]
pub(crate) fn hermite_rest_clears(
    [f0, d0, f1, d1]: [f64; 4],
    w: f64,
    (m4, m2): (f64, f64),
    (allow, allow_d): (f64, f64),
) -> bool {
    let w4 = w * w * w * w;
    let k_low = (w * d0).min(1.5 * f1 - 0.5 * w * d1).min(f1);
    let k = k_low - m4 * w4 / 162.0 * (1.0 + 1e-12) - 2.0 * allow;
    if !(k > 0.0) {
        return false;
    }
    let f0_low = f0 - allow;
    if f0_low >= 0.0 {
        return true;
    }
    let u1 = 2.0 * -f0_low / k;
    u1 < 1.0 && d0 - u1 * w * m2 * (1.0 + 1e-12) - allow_d > 0.0
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

/// How one node was decided.
enum Node {
    /// No crossing on it.
    Free,
    /// The first crossing, at this time.
    Root(f64),
    /// Split in two.
    Split,
}

/// The first crossing of `phi` in `(0, rem]` of a sample of `step_s`
/// (`open`: the origin is a switch instant, where `phi` is zero to
/// rounding and rising). \[audio-thread\]
pub(crate) fn first_root<M: EventModel>(
    m: &mut M,
    step_s: f64,
    rem: f64,
    open: bool,
    tally: &mut Tally,
) -> Found {
    let resolution = ROOT_ULPS * f64::EPSILON * step_s;
    let mut top = 0; // pending nodes on the stack
    let mut cur = (0.0, rem);
    loop {
        let (a, w) = cur;
        tally.nodes += 1;
        match decide(m, (a, w), resolution, open, tally) {
            Node::Root(t) => return Found::At(t),
            Node::Split if top < STACK => {
                let h = 0.5 * w;
                m.stack()[top] = (a + h, w - h);
                top += 1;
                cur = (a, h);
                continue;
            }
            // cannot happen: w halves per level and stops at the
            // resolution, 2^-48 of a sample
            Node::Split => tally.uncertified += 1,
            Node::Free => {}
        }
        if top == 0 {
            return Found::None;
        }
        top -= 1;
        cur = m.stack()[top];
    }
}

/// Decide the node `[a, a + w]` from its bounds (`phi(a) >= 0` known from
/// the nodes before it).
fn decide<M: EventModel>(
    m: &mut M,
    (a, w): (f64, f64),
    resolution: f64,
    open: bool,
    tally: &mut Tally,
) -> Node {
    let NodeBounds { q, u, l, c3 } = m.bounds(a, w);
    let (tol, tol_d) = m.tolerances();
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
            let b = refine(m, resolution, a, a + w, tally);
            return Node::Root(if open { b.max(resolution) } else { b });
        }
        root_free = end - u - r3 - tol > 0.0;
    }
    if root_free {
        return Node::Free;
    }
    let neutral = qmin.abs().max(qmax.abs()) + u + r3 <= NEUTRAL_TOL * tol;
    if !(neutral || w <= resolution) {
        return Node::Split;
    }
    // decided by the sign at the node's end
    let end = a + w;
    let fe = m.eval(end)[0];
    if fe <= 0.0 && !(open && end < resolution && fe > -tol) {
        return Node::Root(if open { end.max(resolution) } else { end });
    }
    tally.grazing += 1;
    Node::Free
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
fn refine<M: EventModel>(m: &mut M, resolution: f64, a: f64, b: f64, tally: &mut Tally) -> f64 {
    let halley = |f: f64, d: f64, dd: f64| 2.0 * f * d / (2.0 * d * d - f * dd);
    let (mut a, mut b) = (a, b);
    let [fb, db, ddb] = m.eval(b);
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
        let [fx, dx, ddx] = m.eval(x);
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
    tally.refined += 1;
    tally.root_evals += evals;
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::TestRng;

    /// `phi(t) = A cos(w t + p) + c`: exact bounds (its value, slope and
    /// curvature at a node's start, `A w^3` on its third derivative).
    struct Cosine {
        amp: f64,
        w: f64,
        p: f64,
        c: f64,
        stack: [(f64, f64); STACK],
    }

    impl Cosine {
        fn at(&self, t: f64) -> [f64; 3] {
            let (s, co) = (self.w * t + self.p).sin_cos();
            let a = self.amp;
            [a * co + self.c, -a * self.w * s, -a * self.w * self.w * co]
        }

        /// The first root in `(0, rem]` in closed form: the first `t` where
        /// `cos(w t + p) = -c / A` with `cos` falling there.
        fn first_root(&self, rem: f64) -> Option<f64> {
            let x = -self.c / self.amp;
            if x < -1.0 {
                return None; // phi stays above c - A > 0
            }
            let theta = x.min(1.0).acos(); // cos falls through x at theta + 2 pi k
            let tau = std::f64::consts::TAU;
            let k = ((self.p - theta) / tau).ceil();
            let mut t = (theta + k * tau - self.p) / self.w;
            if t <= 0.0 {
                t += tau / self.w;
            }
            (t <= rem).then_some(t)
        }
    }

    impl EventModel for Cosine {
        fn bounds(&mut self, a: f64, _w: f64) -> NodeBounds {
            NodeBounds {
                q: self.at(a),
                u: 0.0,
                l: 0.0,
                c3: self.amp * self.w.powi(3),
            }
        }
        fn eval(&mut self, t: f64) -> [f64; 3] {
            self.at(t)
        }
        fn tolerances(&self) -> (f64, f64) {
            let units = ROUND_UNITS * f64::EPSILON;
            (units * (self.amp + self.c.abs()), units * self.amp * self.w)
        }
        fn stack(&mut self) -> &mut [(f64, f64); STACK] {
            &mut self.stack
        }
    }

    /// The search finds the closed form's first root to its resolution
    /// (16 ulps of the sample, on the `phi <= 0` side) or none where there
    /// is none, over random cosines of 0.01 to 30 turns per sample crossing
    /// or missing their offset.
    #[test]
    fn finds_a_cosines_first_root_to_the_resolution() {
        let mut rng = TestRng(0x5ea7c4);
        let step = 1.0 / 48_000.0;
        let resolution = ROOT_ULPS * f64::EPSILON * step;
        let (mut found, mut none, mut worst) = (0, 0, 0.0f64);
        for _ in 0..2000 {
            let amp = 10f64.powf(rng.uniform(-6.0, 0.0));
            let w = 10f64.powf(rng.uniform(-2.0, 1.5)) * std::f64::consts::TAU / step;
            let p = rng.uniform(0.0, std::f64::consts::TAU);
            let mut m = Cosine {
                amp,
                w,
                p,
                c: amp * rng.uniform(-1.2, 1.2),
                stack: [(0.0, 0.0); STACK],
            };
            // phi(0) >= 0 (the search's precondition, else a switch at 0)
            if m.at(0.0)[0] < 0.0 {
                continue;
            }
            let mut tally = Tally::default();
            let got = first_root(&mut m, step, step, false, &mut tally);
            match (got, m.first_root(step)) {
                (Found::At(t), Some(want)) => {
                    // the closed form's own rounding: acos near +-1 is
                    // ill-conditioned, so compare in phi too
                    let err = t - want;
                    worst = worst.max(err.abs() / resolution);
                    assert!(
                        m.at(t)[0] <= m.tolerances().0,
                        "phi({t}) = {:e} > 0",
                        m.at(t)[0]
                    );
                    assert!(err > -resolution || m.at(want)[0].abs() < 1e3 * m.tolerances().0);
                    found += 1;
                }
                (Found::None, None) => none += 1,
                (Found::At(t), None) => {
                    panic!(
                        "root at {t:e} where the closed form has none (phi {:e})",
                        m.at(t)[0]
                    )
                }
                (Found::None, Some(want)) => {
                    // a tangency within rounding is a graze, not a miss
                    let dip = (m.c - m.amp).abs();
                    assert!(
                        dip <= NEUTRAL_TOL * 4.0 * m.tolerances().0,
                        "missed the root at {want:e} (dip {dip:e})"
                    );
                }
            }
            assert_eq!(tally.uncertified, 0);
        }
        println!("{found} roots, {none} without; worst error {worst:.2} resolutions");
        assert!(found > 400 && none > 300);
        assert!(worst <= 2.0, "worst error {worst} resolutions");
    }

    /// From a switch instant (`open`), a rising `phi` holds no crossing and
    /// one that falls crosses after the resolution, within `phi`'s own
    /// rounding of it (`phi` is a difference of two equal terms at 0, so
    /// its sign near 0 is rounding's).
    #[test]
    fn an_open_origin_is_left_only_by_a_falling_phi() {
        let step = 1.0 / 48_000.0;
        let resolution = ROOT_ULPS * f64::EPSILON * step;
        let half_pi = std::f64::consts::FRAC_PI_2;
        for (p, want) in [(0.5 - half_pi, None), (half_pi - 0.5, Some(resolution))] {
            // phi(0) = 0, phi'(0) = -A w sin p: rising for the first p,
            // falling for the second
            let mut m = Cosine {
                amp: 1e-3,
                w: 1000.0,
                p,
                c: 0.0,
                stack: [(0.0, 0.0); STACK],
            };
            m.c = -m.amp * m.p.cos();
            let got = first_root(&mut m, step, step, true, &mut Tally::default());
            match (got, want) {
                (Found::None, None) => {}
                (Found::At(t), Some(w)) => {
                    let rounding = m.tolerances().0 / m.at(0.0)[1].abs();
                    assert!(
                        t >= w && t <= w + 5.0 * rounding,
                        "{t:e}, rounding {rounding:e}"
                    );
                }
                (Found::At(t), None) => panic!("crossing at {t:e} of a rising phi"),
                (Found::None, Some(_)) => panic!("no crossing of a falling phi"),
            }
        }
    }
}
