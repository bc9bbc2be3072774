//! The Hermite certificates (docs/numerics.md section 6.2): a sample, or
//! the rest of one after a switch, cleared without a model and a search
//! where the cubic Hermite interpolant of `phi` less its remainder stays
//! above zero; the state then steps as the search's "no root" would.

use crate::compile::{CompiledPhase, CompiledScene};
use crate::engine::kernel;
use crate::engine::search::{hermite_low, hermite_rest_clears};
use crate::engine::{current_phase, EngineState, Phase};

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

impl EngineState {
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
            let off = self.offsets(scene).pi / scene.sk;
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
    pub(super) fn hermite_clear(&mut self, scene: &CompiledScene) -> bool {
        let dt = self.step_s;
        let Some(h) = self.hermite_step(scene, dt, true) else {
            return false;
        };
        // the remainder's contraction (1 + 1e-12) as the fast path's margin
        let low = hermite_low([h.f0, h.d0, h.f1, h.d1], dt);
        if !(low - h.rem * (1.0 + 1e-12) - h.allowance > 0.0) {
            return false;
        }
        self.hermite_commit(&h);
        self.exact_stats.hermite_cleared += 1;
        true
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
    pub(super) fn hermite_clear_rest(&mut self, scene: &CompiledScene, w: f64) -> bool {
        // a whole sample (a switch at its start) steps as `advance_by` does
        // then: by the one-sample propagators
        let Some(h) = self.hermite_step(scene, w, w == self.step_s) else {
            return false;
        };
        let ends = [h.f0, h.d0, h.f1, h.d1];
        let allow = (h.allowance, 2.0 * h.units * h.mag_d);
        if !hermite_rest_clears(ends, w, (h.m4, h.m2), allow) {
            return false;
        }
        self.hermite_commit(&h);
        self.exact_stats.hermite_after_switch += 1;
        true
    }
}
