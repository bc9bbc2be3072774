//! The voice's energy: exact (offline, and on the audio thread without
//! allocating once the observation scratch is reserved), for the traced
//! block path, for a pressed voice, and the cheap proxy that stops decayed
//! voices and picks the one to steal.

use super::dot::dot;
use super::kernel;
use super::{EngineState, Phase, CONTACT, FREE};
use crate::compile::{CompiledPhase, CompiledScene};

impl EngineState {
    /// [`energy_rt`](Self::energy_rt) of this state with the object's
    /// free state times `factor` (a pressed voice between two updates of
    /// its state, [`scale_free_state`](Self::scale_free_state)): the
    /// object's energy times `factor^2`, the hammer's as it is. In contact
    /// (never pressed) `energy_rt`. \[audio-thread after `reserve_observation`\]
    pub fn energy_rt_scaled(&mut self, scene: &CompiledScene, factor: f64) -> f64 {
        self.settle(scene);
        let e = self.energy_rt(scene);
        if factor == 1.0 || self.in_contact() {
            return e;
        }
        let s = self.time_scale;
        let hammer =
            s * s * (0.5 * scene.m_h * self.v_h * self.v_h + scene.m_h * self.g * self.x_h);
        (e - hammer) * factor * factor + hammer
    }

    /// Cheap O(N) energy proxy in reference units: `0.5 |s|^2` of the current
    /// phase plus the hammer's kinetic energy. Exact for modal objects in
    /// flight (orthonormal blocks); within a factor kappa(V)^2 otherwise.
    /// Used to stop voices that have decayed and to pick the quietest
    /// voice to steal (for each note-on of a chord that steals: the sum
    /// runs in four lanes, `x[i]` into lane `i % 4`, which the compiler
    /// vectorises; a single chain of additions waited for each one).
    /// \[audio-thread\]
    pub fn energy_proxy(&self, scene: &CompiledScene) -> f64 {
        if let Some(e) = self.replay_proxy() {
            return e;
        }
        let s = &self.phases[self.phase.index()].s;
        let (quads, tail) = s.as_chunks::<4>();
        let mut acc = [0.0; 4];
        for q in quads {
            for l in 0..4 {
                acc[l] += q[l] * q[l];
            }
        }
        let tail: f64 = tail.iter().map(|x| x * x).sum();
        let state = 0.5 * (((acc[0] + acc[1]) + (acc[2] + acc[3])) + tail);
        match self.phase {
            Phase::Contact => state,
            Phase::Free => state + 0.5 * scene.m_h * self.v_h * self.v_h,
        }
    }

    /// Total energy \[J\]: object + hammer (kinetic and gravity) + contact
    /// spring, from the state in energy coordinates `y = V (s + s*)` as
    /// `0.5 |y|^2` plus the affine terms. O(nonzeros of V): O(N) where `V`
    /// is sparse (a modal object in flight), O(dim^2) for a dense `V` (a
    /// coupled contact phase, a string). \[offline\]
    pub fn energy(&self, scene: &CompiledScene) -> f64 {
        let mut y = Vec::new();
        self.energy_using(scene, &mut y)
    }

    /// [`energy`](Self::energy) without allocating once
    /// [`reserve_observation`](Self::reserve_observation) ran (a dense `V`
    /// takes its product vector from the observation scratch): the
    /// instrument's live view reads it on the audio thread. Same value bit
    /// for bit. \[audio-thread after `reserve_observation`\]
    pub fn energy_rt(&mut self, scene: &CompiledScene) -> f64 {
        self.settle(scene);
        let mut y = self
            .obs
            .as_mut()
            .map(|o| std::mem::take(&mut o.y))
            .unwrap_or_default();
        let e = self.energy_using(scene, &mut y);
        if let Some(o) = self.obs.as_mut() {
            o.y = y;
        }
        e
    }

    /// [`energy`](Self::energy) for the traced block path: in a coupled
    /// contact phase whose change of basis back to the free phase has a
    /// hierarchical form (a large modal object), through the free
    /// coordinates: `s_f = W_fc (s + s*)` in O(N r log N), the object's
    /// energy from the free phase's sparse `V` in O(N), plus the spring's
    /// `pi^2 / 2` and the hammer's `eta^2 / 2` from their rows. The same
    /// energy as the dense `0.5 |V (s + s*)|^2` to within the hierarchical
    /// form's tolerance (docs/numerics.md, "Structured changes of basis");
    /// elsewhere exactly [`energy_rt`](Self::energy_rt). \[offline\]
    pub(super) fn energy_observed(&mut self, scene: &CompiledScene) -> f64 {
        let structured = scene.w_fc_h.as_ref().filter(|_| self.structured);
        let (Some(h), true, true) = (structured, self.in_contact(), scene.free.v_sparse.is_some())
        else {
            return self.energy_rt(scene);
        };
        self.reserve_observation();
        let obs = self.obs.as_mut().expect("reserved");
        let df = scene.free.dim;
        if obs.y.len() < df {
            obs.y.resize(df, 0.0);
        }
        let st = &self.phases[CONTACT].s;
        let s_f = &mut obs.y[..df];
        for (x, s) in s_f.iter_mut().zip(&scene.s_f_star) {
            *x = s * self.load;
        }
        let [a, b, c] = &mut self.dense_tmp;
        kernel::hodlr_mat_vec_add(self.simd, h, st, s_f, [a, b, c]);
        let e_obj = half_norm_sq_energy_coords(&scene.free, s_f, (&[], 0.0), &mut Vec::new());
        let rows = &scene.contact.rows;
        let off = self.offsets(scene);
        let pi = dot(&rows.pi, st) + off.pi;
        let eta = dot(&rows.eta, st) + off.eta;
        let x_c = dot(&rows.x_c, st) + off.x_c;
        let x_h = self.contact_hammer_height(scene, x_c);
        let s = self.time_scale;
        s * s * (e_obj + 0.5 * (pi * pi + eta * eta) + scene.m_h * self.g * x_h)
    }

    /// See [`energy`](Self::energy); `y` is grown to the phase's dimension
    /// when `V` is dense (no allocation when it is already that long).
    fn energy_using(&self, scene: &CompiledScene, y: &mut Vec<f64>) -> f64 {
        let s = self.time_scale;
        if self.in_contact() {
            let ph = &scene.contact;
            let st = &self.phases[CONTACT].s;
            let e_ref = half_norm_sq_energy_coords(ph, st, (&scene.s_star, self.load), y);
            let x_c = dot(&ph.rows.x_c, st) + self.offsets(scene).x_c;
            let x_h = self.contact_hammer_height(scene, x_c);
            s * s * (e_ref + scene.m_h * self.g * x_h)
        } else {
            let e_obj =
                half_norm_sq_energy_coords(&scene.free, &self.phases[FREE].s, (&[], 0.0), y);
            let v = self.v_h;
            s * s * (e_obj + 0.5 * scene.m_h * v * v + scene.m_h * self.g * self.x_h)
        }
    }
}

/// `0.5 |y|^2` for `y = V (s + load s_star)` (physical energy
/// coordinates; `star` is `(s_star, load)`).
/// Each `y_i` is summed over `j` in ascending order, so the sparse and the
/// dense products give the same value bit for bit. A sparse `V` costs its
/// nonzeros; a dense one is applied by columns (contiguous in memory).
fn half_norm_sq_energy_coords(
    ph: &CompiledPhase,
    s: &[f64],
    star: (&[f64], f64),
    y: &mut Vec<f64>,
) -> f64 {
    let (s_star, load) = star;
    let sj = |j: usize| s[j] + s_star.get(j).map_or(0.0, |x| x * load);
    if let Some(sp) = &ph.v_sparse {
        let mut e = 0.0;
        for i in 0..ph.dim {
            let y = sp.row_dot(i, sj);
            e += y * y;
        }
        return 0.5 * e;
    }
    if y.len() < ph.dim {
        y.resize(ph.dim, 0.0);
    }
    let y = &mut y[..ph.dim];
    y.iter_mut().for_each(|v| *v = 0.0);
    // nalgebra stores by columns: column j is one contiguous slice
    for (j, col) in ph.v.as_slice().chunks_exact(ph.dim.max(1)).enumerate() {
        let x = sj(j);
        for (yi, v) in y.iter_mut().zip(col) {
            *yi += v * x;
        }
    }
    0.5 * y.iter().map(|v| v * v).sum::<f64>()
}
