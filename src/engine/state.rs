//! What a caller reads and sets of a voice between blocks: its coordinates
//! (tests and tools set a vibration, benchmarks a steady contact), the
//! hammer in flight and whether it is clear of the object, the pressure
//! that damps the free state, and a new strike.

use super::{EngineState, Phase, CONTACT, FREE};
use crate::compile::CompiledScene;

impl EngineState {
    /// Free-phase coordinates of the struck object (for tests and tools that
    /// set an initial vibration). Structure of arrays: block `k` is
    /// `(s[k], s[nb + k])`; for a modal object block `k` is mode `k`, i.e.
    /// `s[k] = omega_k q_k` and `s[n + k] = q_k'` (reference time).
    /// A replaying voice ([`strike_stored`](Self::strike_stored)) stops
    /// replaying and is at the instant of its strike: settle it
    /// ([`settle`](Self::settle)) first to change it where it is.
    pub fn free_state_mut(&mut self) -> &mut [f64] {
        self.replay = None;
        self.rest_run = None;
        self.discontinuity();
        &mut self.phases[FREE].s
    }

    /// Put the hammer in contact at the contact phase's static equilibrium
    /// (with gravity: resting on the object under its weight; without: just
    /// touching), the object following it, and return the contact-phase
    /// coordinates relative to that equilibrium (all zero now) for the caller
    /// to add a vibration. Structure of arrays like
    /// [`free_state_mut`](Self::free_state_mut); energy coordinates are
    /// `y = V (s + s_star)`, so the penetration cannot reach 0 while
    /// `|V s| < sqrt(k) p_static` in a passive phase. For benchmarks and
    /// tests of the steady contact phase. \[any-thread\]
    pub fn rest_in_contact(&mut self) -> &mut [f64] {
        self.replay = None;
        self.phases[CONTACT].s.iter_mut().for_each(|x| *x = 0.0);
        self.rest_run = None;
        self.rod_m = 0.0;
        self.phase = Phase::Contact;
        self.discontinuity();
        &mut self.phases[CONTACT].s
    }

    /// The current phase's state in its block coordinates (read only; the
    /// layout of [`free_state_mut`](Self::free_state_mut)). For tests and
    /// diagnostics; a replaying voice's is the one its strike left until
    /// it is settled ([`settle`](Self::settle)). \[any-thread\]
    pub fn phase_state(&self) -> &[f64] {
        &self.phases[self.phase.index()].s
    }

    /// Hammer height \[m\] and physical velocity \[m/s\] while in flight.
    pub fn hammer_in_flight(&self) -> Option<(f64, f64)> {
        let (x_h, v_h) = self.replay_hammer().unwrap_or((self.x_h, self.v_h));
        (!self.in_contact()).then_some((x_h, v_h * self.time_scale))
    }

    /// Whether the hammer is clear of the object for as long as both fly
    /// free: in flight, not falling back (no gravity, not moving down) and
    /// higher than the object's contact point can reach from its present
    /// state. Every block of the free phase is a contraction, so block
    /// `k`'s share of the contact point's displacement stays within `e_k
    /// |s_k|` (`CompiledPhase::ev_block`) and the point below their sum,
    /// while the hammer only rises. Also when that motion is damped more (a
    /// pressed voice: the object's state times a factor below 1), so a
    /// voice that is clear is pressed exactly by scaling its samples
    /// (docs/plugin.md, "Pressure and the mod wheel"). False for a dense
    /// free phase (no blocks to bound). The margin `1e-9` covers the sum's
    /// rounding and each step's `1 + 1e-12` of the blocks' contraction over
    /// far more steps than the 64 a decision stands for. O(N). \[audio-thread\]
    pub fn hammer_clear(&self, scene: &CompiledScene) -> bool {
        let ph = &scene.free;
        let nb = ph.dim / 2;
        // a replaying voice is never clear: its last stored switch is to come
        if self.replay.is_some()
            || self.in_contact()
            || self.g != 0.0
            || !(self.v_h >= 0.0)
            || ph.ev_block.len() != nb
        {
            return false;
        }
        let s = &self.phases[FREE].s;
        let reach: f64 = (0..nb)
            .map(|k| ph.ev_block[k] * (s[k] * s[k] + s[nb + k] * s[nb + k]).sqrt())
            .sum();
        self.x_h > reach * (1.0 + 1e-9)
    }

    /// Change the constant force on the hammer (its weight and a hand's
    /// press, `[hammer] gravity_m_per_s2` and `drive.press_n`) to `load`
    /// times the scene's, from this sample instant on: the instrument's
    /// pressure on a driven scene (docs/design.md, "Rolling and scraping").
    /// The physical state does not move: in flight only the hammer's
    /// acceleration changes; in contact the state is held about the
    /// contact phase's equilibrium under the force, `y = V (s + load
    /// s_star)`, and that equilibrium is linear in the force, so `s` takes
    /// `(load_old - load) s_star` and every row keeps its value (the
    /// penetration, the rod, the outputs). A step of the force at an
    /// instant is as exact as any other sample's motion; what it does to
    /// the energy is the hand's work. Refused (false, nothing changed) for
    /// a load that is not finite or is negative. O(N). \[audio-thread\]
    pub fn set_load(&mut self, scene: &CompiledScene, load: f64) -> bool {
        if !(load.is_finite() && load >= 0.0) {
            return false;
        }
        self.settle(scene);
        if load == self.load {
            return true;
        }
        if self.in_contact() {
            let d = self.load - load;
            for (x, star) in self.phases[CONTACT].s.iter_mut().zip(&scene.s_star) {
                *x += d * star;
            }
        }
        self.load = load;
        self.g = scene.g * load;
        self.discontinuity();
        true
    }

    /// The constant force on the hammer as a multiple of the scene's
    /// ([`set_load`](Self::set_load); 1 after a reset).
    pub fn load(&self) -> f64 {
        self.load
    }

    /// Multiply the free phase's state by `factor` (in `(0, 1]`): added
    /// mass-proportional damping over the samples it stands for (the
    /// instrument's pressure, docs/plugin.md, "Pressure and the mod
    /// wheel"). With `z(t) = e^(-a t) x(t)` every mode keeps its damped
    /// frequency and decays `a` faster; the free state has no affine part,
    /// so its energy is multiplied by `factor^2`. Refused (false, nothing
    /// changed) in contact, while replaying a stored strike, or for a
    /// factor outside `(0, 1]`. O(N). \[audio-thread\]
    pub fn scale_free_state(&mut self, factor: f64) -> bool {
        if self.replay.is_some() || self.in_contact() || !(factor > 0.0 && factor <= 1.0) {
            return false;
        }
        self.phases[FREE].s.iter_mut().for_each(|x| *x *= factor);
        self.rest_run = None;
        self.discontinuity();
        true
    }

    /// Whether the hammer is in contact (for the coming step; a replaying
    /// voice's as its stored strike has it).
    pub fn in_contact(&self) -> bool {
        self.replay_in_contact()
            .unwrap_or(self.phase == Phase::Contact)
    }

    /// Launch the hammer again from `height_m` with `velocity_m_per_s`
    /// (physical, positive up) while the object keeps its motion: a repeated
    /// strike hits a moving surface. If the old hammer is still in contact it is
    /// lifted off first (its spring is cut: that can only remove energy).
    /// Put on the surface (`height_m` 0), the coming sample decides at its
    /// start whether the contact begins there, without a search
    /// (docs/numerics.md section 6.9). O(N^2) when in contact, else O(N).
    /// \[audio-thread\]
    pub fn strike(&mut self, scene: &CompiledScene, height_m: f64, velocity_m_per_s: f64) {
        self.settle(scene);
        if self.in_contact() {
            // between samples: at the start of the coming one
            self.t_in_step = 0.0;
            self.leave_contact(scene);
        }
        // the surface's height as the event function sums it (its row is
        // `-x_c`, and a negated sum is the sum of the negated terms): a
        // hammer put on the surface then has `phi = 0` exactly
        let [ev_s, _, _] = self.event_sums(scene, 0.0, false);
        let height = height_m.max(0.0);
        self.x_h = -ev_s + height;
        self.v_h = velocity_m_per_s / self.time_scale;
        // a strike from rest still under way is not followed any further
        self.rest_run = None;
        self.discontinuity();
        // on the surface: whether the contact begins at this instant is
        // decided by the coming sample, from `phi' (0)`
        self.struck_on_surface = self.strike_entry && height == 0.0;
    }
}
