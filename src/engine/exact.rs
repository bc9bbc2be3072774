//! Exact switching (beyond the paper): the instants where the penetration
//! crosses zero are located inside the sample on the exact phase solution, and
//! the sample is consumed piecewise: `exp(A_1 tau)`, switch, `exp(A_2 (h - tau))`
//! (NUMERICS.md sections 0 and 4).
//!
//! Event function `phi(tau)`: in flight `phi = x_h - x_c` (contact starts when it
//! reaches 0 from above), in contact `phi = p_eff` (contact ends when it reaches
//! 0 from above). Between samples `phi` is a known sum of exponentials plus the
//! hammer's parabola, evaluated in O(N) at any `tau` from the block generators.
//!
//! Detection without missing short excursions: with `|exp(G tau)| <= 1` (every
//! block is passive in its coordinates), `|phi''| <= B = g + |ev_dd| |s|` over
//! the whole step, so `phi >= min(phi_a, phi_b) - B w^2 / 8` on an interval of
//! width `w` (chord bound), and `phi >= phi_a + phi_a' t - B t^2 / 2` (tangent
//! bound, used right after a switch where `phi_a = 0`). An interval that
//! neither bound certifies is bisected, up to [`MAX_DEPTH`] levels; a sign
//! change is refined by safeguarded Newton to a few ulps.
//!
//! Robustness: at most [`MAX_SWITCHES_PER_SAMPLE`] switches per sample (then
//! the sample is finished in the current phase); a switch happens only on a
//! transversal crossing (`phi' < 0`; a grazing touch with zero relative speed
//! carries no impulse); and if a sample nevertheless starts inside the object
//! in flight (an excursion below the bisection resolution), contact begins
//! with the paper's offset rod, which adds no energy.

use super::{dot, EngineState};
use super::{kernel, vmath};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::physics::block::exp2;

/// Cap on switches inside one sample (X2 saw 2; X11 grazing must not loop).
pub const MAX_SWITCHES_PER_SAMPLE: u32 = 8;
/// Bisection depth of the event search: intervals down to h / 2^10.
pub const MAX_DEPTH: u32 = 10;
/// Newton/bisection iterations for a root (converges in ~5-8; the cap only
/// bounds the worst case).
const MAX_ROOT_ITERS: u32 = 100;
/// Resolution of a located switch instant, in ulps of the instant (3.5e-15
/// of a sample): below it the rounding of `phi` itself (`u |x_h| / |phi'|`,
/// ~1e-14 of a sample for a hammer at millimetres and 1 m/s) decides, so
/// iterating further only costs sweeps.
const ROOT_ULPS: f64 = 16.0;
/// Largest |A tau| per Taylor sub-step for dense partial steps, and the
/// number of terms: 0.5^20 / 20! ~ 4e-25.
const TAYLOR_MAX_NORM: f64 = 0.5;
const TAYLOR_TERMS: usize = 20;

/// Counters of what the exact switching did (diagnostics for reports/tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ExactStats {
    /// Switches located inside samples.
    pub located: u64,
    /// Samples that hit the per-sample switch cap.
    pub capped: u64,
    /// Contacts started by the offset-rod safety net.
    pub rod_fallbacks: u64,
    /// Grazing zeros that were not switched (no impulse).
    pub grazing: u64,
    /// Intervals left uncertified at the bisection depth limit.
    pub uncertified: u64,
    /// Partial-step propagators `exp(G tau)` computed for every block (one
    /// exponential and one sine/cosine per block: the main cost of a
    /// located switch).
    pub partial_sweeps: u64,
}

enum Search {
    None,
    /// `phi(a) > 0 >= phi(b)` on `[a, b]`.
    Bracket(f64, f64),
}

impl EngineState {
    /// `(phi, phi')` at `tau` into the step from the current state (reference
    /// time). `full` means `tau` is the whole step (precomputed propagators).
    fn eval_event(&mut self, scene: &CompiledScene, tau: f64, full: bool) -> (f64, f64) {
        let [f, d, _] = self.eval_event3(scene, tau, full);
        (f, d)
    }

    /// `[phi, phi', phi'']` at `tau` (see [`eval_event`](Self::eval_event)).
    /// A partial step of exactly one sample period uses the precomputed
    /// propagators (they are `exp(G h)` whatever the starting instant).
    fn eval_event3(&mut self, scene: &CompiledScene, tau: f64, full: bool) -> [f64; 3] {
        let full = full || tau == self.step_s;
        let ph: &CompiledPhase = current_phase(self, scene);
        let s = if self.in_contact {
            &self.s_c
        } else {
            &self.s_f
        };
        let (mut f, mut d, mut dd) = if ph.dense.is_some() {
            let n = ph.dim;
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, full, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            (
                dot(&ph.ev, &t0[..n]),
                dot(&ph.ev_d, &t0[..n]),
                dot(&ph.ev_dd, &t0[..n]),
            )
        } else {
            if tau != 0.0 && !full {
                self.ensure_partial(scene, tau);
            }
            let s = if self.in_contact {
                &self.s_c
            } else {
                &self.s_f
            };
            let props = match (tau == 0.0, full, self.in_contact) {
                (true, _, _) => None,
                (false, false, _) => Some(&self.p_part),
                (false, true, true) => Some(&self.p_c),
                (false, true, false) => Some(&self.p_f),
            };
            let [f, d, dd] = kernel::event_rows(self.simd, props, s, [&ph.ev, &ph.ev_d, &ph.ev_dd]);
            (f, d, dd)
        };
        if self.in_contact {
            f += scene.offsets.pi / scene.sk;
        } else {
            f += self.x_h + self.v_h * tau - 0.5 * self.g * tau * tau;
            d += self.v_h - self.g * tau;
            dd -= self.g;
        }
        [f, d, dd]
    }

    /// Fill `p_part` with the current phase's block propagators over `tau`,
    /// unless it already holds them (the event search evaluates a point and
    /// then advances to it; the remainder of a sample is checked and then
    /// stepped): one sweep of `exp2` per distinct `(phase, tau)`.
    fn ensure_partial(&mut self, scene: &CompiledScene, tau: f64) {
        let contact = self.in_contact;
        if self.part_ok && self.part_tau == tau && self.part_contact == contact {
            return;
        }
        let ph = current_phase(self, scene);
        let gens = ph.gens.as_ref().expect("block phase");
        let nb = gens.len();
        // Oscillatory blocks (all of a modal object's free phase, the
        // complex pairs of a contact phase): exp, sin and cos of every
        // block in one vectorised batch, then `exp(G tau)` from them as in
        // `OscForm::exp_from`. Blocks with real eigenvalues: exp2.
        let o = &ph.osc;
        let [mt, wt, e, sn, cs] = &mut self.part_args;
        let (mt, wt) = (&mut mt[..nb], &mut wt[..nb]);
        for k in 0..nb {
            mt[k] = o.m[k] * tau;
            wt[k] = o.w[k] * tau;
        }
        let (e, sn, cs) = (&mut e[..nb], &mut sn[..nb], &mut cs[..nb]);
        vmath::exp_sincos(self.simd, mt, wt, e, sn, cs);
        let p = &mut self.p_part;
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
        for &k in &o.other {
            p.set(k, &exp2(&gens[k], tau));
        }
        self.part_ok = true;
        self.part_tau = tau;
        self.part_contact = contact;
        self.exact_stats.partial_sweeps += 1;
    }

    /// Curvature bound `B >= |phi''|` over any sub-step from the current state.
    fn curvature_bound(&self, scene: &CompiledScene) -> f64 {
        let ph = current_phase(self, scene);
        let s = if self.in_contact {
            &self.s_c
        } else {
            &self.s_f
        };
        let g = if self.in_contact { 0.0 } else { self.g };
        let global = ph.ev_dd_norm * s.iter().map(|x| x * x).sum::<f64>().sqrt();
        // Per-block bound: each 2x2 block is a contraction on its own, so
        // |phi''| <= sum_k |ev_dd_k| |s_k|. Much tighter than the global
        // Cauchy-Schwarz bound when the energy sits in blocks that barely move
        // phi (a heavy hammer's slow mode, NUMERICS X7). Dense phases: global.
        let bound = match &ph.gens {
            Some(gens) => {
                let nb = gens.len();
                let mut acc = 0.0;
                for k in 0..nb {
                    acc += ph.ev_dd_block[k] * (s[k] * s[k] + s[nb + k] * s[nb + k]).sqrt();
                }
                acc.min(global)
            }
            None => global,
        };
        // 1 + 1e-12: the blocks are contractions up to rounding of exp2
        g + bound * (1.0 + 1e-12)
    }

    /// Advance the current phase by `tau` (no switching).
    fn advance_by(&mut self, scene: &CompiledScene, tau: f64, full: bool) {
        if tau <= 0.0 {
            return;
        }
        let full = full || tau == self.step_s;
        let ph: &CompiledPhase = current_phase(self, scene);
        let in_contact = self.in_contact;
        if ph.dense.is_some() {
            let n = ph.dim;
            let s = if in_contact {
                &mut self.s_c
            } else {
                &mut self.s_f
            };
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, full, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            s[..n].copy_from_slice(&t0[..n]);
        } else {
            if !full {
                self.ensure_partial(scene, tau);
            }
            let (s, props) = match (full, in_contact) {
                (false, true) => (&mut self.s_c, &self.p_part),
                (false, false) => (&mut self.s_f, &self.p_part),
                (true, true) => (&mut self.s_c, &self.p_c),
                (true, false) => (&mut self.s_f, &self.p_f),
            };
            let nb = ph.dim / 2;
            for k in 0..nb {
                let p = props.get(k);
                let (a, b) = (s[k], s[nb + k]);
                s[k] = p[0] * a + p[1] * b;
                s[nb + k] = p[2] * a + p[3] * b;
            }
        }
        if !in_contact {
            self.x_h += self.v_h * tau - 0.5 * self.g * tau * tau;
            self.v_h -= self.g * tau;
        }
    }

    fn certified(fa: f64, da: f64, fb: f64, w: f64, b: f64) -> bool {
        let chord = fa.min(fb) - b * w * w / 8.0 > 0.0;
        let tangent = fa >= 0.0 && da > 0.0 && fb > 0.0 && fa + da * w - b * w * w / 2.0 > 0.0;
        chord || tangent
    }

    #[allow(clippy::too_many_arguments)]
    fn search(
        &mut self,
        scene: &CompiledScene,
        bound: f64,
        a: f64,
        fa: f64,
        da: f64,
        b: f64,
        fb: f64,
        depth: u32,
    ) -> Search {
        if fb <= 0.0 {
            return Search::Bracket(a, b);
        }
        if Self::certified(fa, da, fb, b - a, bound) {
            return Search::None;
        }
        if depth >= MAX_DEPTH {
            self.exact_stats.uncertified += 1;
            return Search::None;
        }
        let m = 0.5 * (a + b);
        let (fm, dm) = self.eval_event(scene, m, false);
        if fm <= 0.0 {
            return Search::Bracket(a, m);
        }
        match self.search(scene, bound, a, fa, da, m, fm, depth + 1) {
            Search::None => self.search(scene, bound, m, fm, dm, b, fb, depth + 1),
            br => br,
        }
    }

    /// Refine a bracket `phi(a) > 0 >= phi(b)` to the switch instant: the
    /// returned point `b` has `phi(b) <= 0` (the switch happens there, the
    /// rod takes up the few-ulp residual) and lies at most ~[`ROOT_ULPS`]
    /// ulps after the root; also returns `phi'(b)`.
    ///
    /// Safeguarded Halley iteration (`phi''` costs one more dot per
    /// evaluation; convergence is cubic). It starts from the Halley point of
    /// a bracket end (`tau = 0` and whole samples cost no sweep of `exp2`),
    /// aims every step a few ulps past its root estimate, and stops at the
    /// first point with `phi <= 0` whose own Halley correction is a few
    /// ulps: typically three evaluations, and the advance to `b` reuses the
    /// propagators of the last one.
    fn refine(&mut self, scene: &CompiledScene, a: f64, b: f64) -> (f64, f64) {
        let (mut a, mut b) = (a, b);
        let halley = |f: f64, d: f64, dd: f64| 2.0 * f * d / (2.0 * d * d - f * dd);
        let ends = [b, a].map(|t| (t, self.eval_event3(scene, t, false)));
        let mut db = ends[0].1[1];
        let mut x = f64::NAN;
        for (t, [f, d, dd]) in ends {
            let guess = t - halley(f, d, dd);
            if guess > a && guess < b {
                x = guess;
                break;
            }
        }
        if x.is_nan() {
            let (fa, fb) = (ends[1].1[0], ends[0].1[0]);
            x = a - fa * (b - a) / (fb - fa);
        }
        for _ in 0..MAX_ROOT_ITERS {
            if b - a <= ROOT_ULPS * f64::EPSILON * b {
                break;
            }
            if !(x > a && x < b) {
                x = 0.5 * (a + b);
                if !(x > a && x < b) {
                    break;
                }
            }
            let [fx, dx, ddx] = self.eval_event3(scene, x, false);
            let step = halley(fx, dx, ddx);
            if fx > 0.0 {
                a = x;
            } else {
                b = x;
                db = dx;
                if fx == 0.0 || step.abs() <= ROOT_ULPS * f64::EPSILON * x {
                    break;
                }
            }
            // aim just past the root estimate, onto the phi <= 0 side
            let est = x - step;
            x = if step.is_finite() {
                est + 4.0 * f64::EPSILON * est.abs()
            } else {
                0.5 * (a + b)
            };
        }
        (b, db)
    }

    /// Exact-switching step of one sample (reference duration `step_s`).
    /// O(N) without events; O(N) trig per evaluation and O(N^2) per switch
    /// when a switch is near. Allocation-free. [audio-thread]
    pub(super) fn advance_exact(&mut self, scene: &CompiledScene) {
        // Safety net: a sample that starts on the wrong side of the surface.
        let (phi0, dphi0) = self.eval_event(scene, 0.0, false);
        if phi0 < 0.0 && dphi0 <= 0.0 {
            if self.in_contact {
                self.leave_contact(scene);
            } else {
                self.exact_stats.rod_fallbacks += 1;
                self.enter_contact(scene, -phi0);
            }
        }
        let step = self.step_s;
        let mut t = 0.0; // time consumed in this sample
        let mut switches = 0;
        loop {
            let rem = step - t;
            if rem <= 0.0 {
                break;
            }
            let full = t == 0.0;
            let (fa, da) = self.eval_event(scene, 0.0, false);
            // one-sided start: right after a switch phi = 0 and phi' > 0
            let fa = if switches > 0 { fa.max(0.0) } else { fa };
            let (fb, _) = self.eval_event(scene, rem, full);
            let bound = self.curvature_bound(scene);
            match self.search(scene, bound, 0.0, fa, da, rem, fb, 0) {
                Search::None => {
                    self.advance_by(scene, rem, full);
                    break;
                }
                Search::Bracket(a, b) => {
                    let (tau, dtau) = self.refine(scene, a, b);
                    self.advance_by(scene, tau, full && tau == rem);
                    t += tau;
                    self.t_in_step = t;
                    if dtau < 0.0 {
                        if self.in_contact {
                            self.leave_contact(scene);
                        } else {
                            // phi = x_h - x_c <= 0 (a few ulps): the rod
                            // takes up that residual, the spring starts at 0.
                            let p = (-self.eval_event(scene, 0.0, false).0).max(0.0);
                            self.enter_contact(scene, p);
                        }
                        self.exact_stats.located += 1;
                        switches += 1;
                    } else {
                        // A zero touched with phi' >= 0: no impulse, both
                        // phases agree here. Finish the sample in the current
                        // phase; the start-of-sample check settles the rest.
                        self.exact_stats.grazing += 1;
                        let rem = step - t;
                        self.advance_by(scene, rem, false);
                        break;
                    }
                    if switches >= MAX_SWITCHES_PER_SAMPLE {
                        self.exact_stats.capped += 1;
                        let rem = step - t;
                        self.advance_by(scene, rem, false);
                        break;
                    }
                }
            }
        }
    }
}

/// The current phase of `st` in `scene` (a plain shared borrow; split out so
/// the borrow checker sees it does not alias the state vectors).
pub(super) fn current_phase<'a>(st: &EngineState, scene: &'a CompiledScene) -> &'a CompiledPhase {
    if st.in_contact {
        &scene.contact
    } else {
        &scene.free
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
    use crate::presets;

    /// The batched partial propagators (vectorised exp/sin/cos, split form)
    /// against `exp2` (libm) block by block, in both phases of every preset.
    #[test]
    fn batched_partial_propagators_match_exp2() {
        let mut worst: f64 = 0.0;
        for i in 0..presets::PRESETS.len() {
            let sc = compile(&presets::scene(i).unwrap(), 44100.0).unwrap();
            let mut st = EngineState::new(&sc);
            for contact in [false, true] {
                st.in_contact = contact;
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
}
