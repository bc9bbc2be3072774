//! Carrying a running voice over to a recompiled scene (the same object,
//! other parameters), so that a parameter change neither resets nor clicks.

use super::dot::dot;
use super::{EngineState, CONTACT, FREE};
use crate::compile::CompiledScene;

impl EngineState {
    /// Whether this state can be carried from `old` to `new`: the same
    /// layout (dimensions of both phases, and of this state), and no dense
    /// phase away from `s = 1` (a dense propagator cannot scale time).
    fn can_rebind(&self, old: &CompiledScene, new: &CompiledScene) -> bool {
        old.free.dim == new.free.dim
            && old.contact.dim == new.contact.dim
            && self.phases[FREE].s.len() == new.free.dim
            && self.phases[CONTACT].s.len() == new.contact.dim
            && !((new.free.dense.is_some() || new.contact.dense.is_some())
                && self.time_scale != 1.0)
    }

    /// Carry the running state over to a recompiled scene `new` (same object,
    /// other parameters), so a parameter change neither resets nor clicks.
    ///
    /// The state is taken to energy coordinates with `old` and back to phase
    /// coordinates with `new`; the energy coordinates themselves are kept, so
    /// the stored energy `0.5 |y|^2` is unchanged by the swap. In contact this
    /// keeps the spring coordinate `pi = sqrt(k) p_eff`: with a new stiffness
    /// `k'` the rod is re-chosen so that `0.5 k' p_eff'^2 = 0.5 k p_eff^2`
    /// (docs/numerics.md, "The stability cases": parameters changed during
    /// contact), and the hammer keeps its momentum coordinate.
    /// Returns `false` (state untouched) when the layouts differ (another
    /// object or another mode count): the caller then resets the voice.
    /// O(N^2), allocation-free. \[audio-thread\]
    pub fn rebind(&mut self, old: &CompiledScene, new: &CompiledScene) -> bool {
        self.settle(old);
        if !self.can_rebind(old, new) {
            return false;
        }
        let load = self.load;
        let (ph_old, ph_new, s, star_old, star_new) = if self.in_contact() {
            (
                &old.contact,
                &new.contact,
                &mut self.phases[CONTACT].s,
                &old.s_star[..],
                &new.s_star[..],
            )
        } else {
            (
                &old.free,
                &new.free,
                &mut self.phases[FREE].s,
                &[][..],
                &[][..],
            )
        };
        let dim = ph_old.dim;
        // y = V_old (s + s*_old)
        for i in 0..dim {
            let mut acc = 0.0;
            for j in 0..dim {
                acc += ph_old.v[(i, j)] * (s[j] + star_old.get(j).map_or(0.0, |x| x * load));
            }
            self.scratch[i] = acc;
        }
        // s = V_new^{-1} y - s*_new
        for i in 0..dim {
            let mut acc = 0.0;
            for j in 0..dim {
                acc += ph_new.vinv[(i, j)] * self.scratch[j];
            }
            s[i] = acc - star_new.get(i).map_or(0.0, |x| x * load);
        }
        if self.in_contact() {
            // keep the true penetration p = p_eff + rod: x_h is unchanged
            // only if the spring length is; choose the rod so p_eff' = pi/sk'.
            let pi = dot(&new.contact.rows.pi, &self.phases[CONTACT].s) + new.offsets.pi * load;
            let p_true = self.rod_m + old_p_eff(old, pi);
            self.rod_m = p_true - pi / new.sk;
        }
        let scale = self.time_scale;
        // re-derive propagators and output rows for the new scene
        self.set_time_scale_inner(new, scale);
        true
    }

    /// [`rebind`](Self::rebind) for a state out of contact whose new scene
    /// steps the free phase in the same coordinates as the old one (the
    /// same `V` and free propagators: the same object, only the contact
    /// differs, as for the brightness levels of
    /// [`crate::instrument::Scenes`], which the worker compares): the state
    /// stays as it is, bit for bit, the free phase's propagators too, and
    /// the contact phase's propagators and the rows are derived again for
    /// `new`. O(N) instead of O(N^2). Returns `false` (state untouched) in contact, when the
    /// layouts differ, or for a dense phase away from `s = 1`.
    /// \[audio-thread\]
    pub fn rebind_same_free(&mut self, old: &CompiledScene, new: &CompiledScene) -> bool {
        self.settle(old);
        if self.in_contact() || !self.can_rebind(old, new) {
            return false;
        }
        debug_assert!(
            old.free.v == new.free.v && old.free.gens == new.free.gens && old.h == new.h,
            "rebind_same_free: the free phases differ"
        );
        let scale = self.time_scale;
        self.derive_for(new, scale, true, None);
        true
    }
}

/// Effective penetration in `old` for the spring coordinate `pi` (which the
/// rebind keeps): `p_eff = pi / sqrt(k_old)`.
fn old_p_eff(old: &CompiledScene, pi: f64) -> f64 {
    pi / old.sk
}
