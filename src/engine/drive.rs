//! A contact driven over a moving surface (docs/numerics.md, "A driven
//! contact"): the surface's height `s(t)` under the contact point is read
//! from the compiled profile at every sample instant and is linear
//! between them, and the penetration is `p = x_contact + s(t) - x_hammer`.
//!
//! The voice keeps the hammer relative to the surface, `x_r = x_hammer -
//! s`. Within a sample `s'' = 0`, so `x_r'' = x_hammer''`: in `x_r` the
//! phases are exactly the undriven ones (the same propagators, the same
//! event function `p = x_contact - x_r`, the same search). Only at a
//! sample instant, where the profile's slope changes from `v_{n-1}` to
//! `v_n`, the relative velocity jumps by `-(v_n - v_{n-1})` while the
//! relative position is continuous: one update of the hammer's velocity
//! in flight, or of the contact phase's state along its momentum column
//! in contact ([`EngineState::kick_hammer`]). That is exact for the
//! first-order hold of the profile, and it adds no step of its own.

use super::{EngineState, Phase, CONTACT, NO_EPOCH};
use crate::compile::CompiledScene;

/// Where the surface is at a sample instant (physical units), for traces
/// and energy ledgers.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SurfaceAt {
    /// Path position \[m\].
    pub path_m: f64,
    /// Height of the surface under the contact \[m\] (from its height at
    /// the start).
    pub height_m: f64,
    /// Its rate over the coming sample \[m/s\].
    pub rate_m_per_s: f64,
    /// The rate the voice's hammer velocity is measured against now \[m/s\]:
    /// the last sample's that has begun (`rate_m_per_s` once the coming
    /// sample has begun; 0 before the first). The hammer's lab velocity
    /// is its voice velocity plus this.
    pub frame_rate_m_per_s: f64,
}

impl EngineState {
    /// Change the hammer's velocity relative to the surface by
    /// `dv_m_per_s` (physical) at the current instant: in flight its
    /// velocity, in contact the contact phase's state along the hammer's
    /// momentum (`CompiledScene::col_eta`, the column a contact's entry
    /// puts the momentum into). The hammer's position, the object and
    /// the phase do not change. O(N) in contact, O(1) in flight.
    /// \[audio-thread\]
    pub fn kick_hammer(&mut self, scene: &CompiledScene, dv_m_per_s: f64) {
        if dv_m_per_s == 0.0 || !dv_m_per_s.is_finite() {
            return;
        }
        self.settle(scene);
        let dv = dv_m_per_s / self.time_scale;
        if self.phase == Phase::Contact {
            let d_eta = scene.sm * dv;
            for (s, &c) in self.phases[CONTACT].s.iter_mut().zip(&scene.col_eta) {
                *s += c * d_eta;
            }
        } else {
            self.v_h += dv;
        }
        // a strike from rest no longer follows its stored switches; the
        // hammer is still where it was, so a strike on the surface keeps
        // its decision from the coming sample's slope
        self.rest_run = None;
        let on_surface = self.struck_on_surface;
        self.discontinuity();
        self.struck_on_surface = on_surface;
    }

    /// The surface at the voice's current sample instant (`None`: the
    /// scene is not driven): once the sample has begun, the segment it
    /// follows; before, the one it will follow at the current speed.
    pub fn surface_at(&self, scene: &CompiledScene) -> Option<SurfaceAt> {
        let d = scene.drive.as_ref()?;
        let path = if self.drive_clock == self.clock {
            self.drive_path
        } else if self.drive_clock == NO_EPOCH {
            d.start_m
        } else {
            self.drive_path + self.drive_step
        };
        let step = if self.drive_clock == self.clock {
            self.drive_step
        } else {
            self.drive_speed * scene.h
        };
        let (s0, s1) = (
            d.profile.at(path) - d.base_m,
            d.profile.at(path + step) - d.base_m,
        );
        let frame = if self.drive_clock == NO_EPOCH {
            0.0
        } else {
            self.drive_rate
        };
        Some(SurfaceAt {
            path_m: path,
            height_m: s0,
            rate_m_per_s: (s1 - s0) * scene.rate_hz,
            frame_rate_m_per_s: frame,
        })
    }

    /// The speed along the path \[m/s\] from the coming sample on (the
    /// scene's `drive.speed_m_per_s` after a reset; 0 stops the surface,
    /// a negative speed runs the path backwards). The surface's height is
    /// continuous; its slope changes at that sample instant, as it does
    /// at every instant of a profile. Ignored (false) when the scene is
    /// not driven or the speed is not finite. \[audio-thread\]
    pub fn set_drive_speed(&mut self, scene: &CompiledScene, m_per_s: f64) -> bool {
        if scene.drive.is_none() || !m_per_s.is_finite() {
            return false;
        }
        self.drive_speed = m_per_s;
        true
    }

    /// The speed along the path \[m/s\] the coming samples follow.
    pub fn drive_speed(&self) -> f64 {
        self.drive_speed
    }

    /// Before the sample at the current clock of a driven scene: the
    /// path advanced by the last sample's step, the profile's slope over
    /// the coming sample, and the hammer's relative velocity changed by
    /// the slope's change (once per sample, however many entry points
    /// look at it). No-op for a scene that is not driven. O(N) in
    /// contact. \[audio-thread\]
    pub(super) fn drive_sample(&mut self, scene: &CompiledScene) {
        if self.drive_clock == self.clock {
            return;
        }
        let Some(now) = self.surface_at(scene) else {
            return;
        };
        let prev = if self.drive_clock == NO_EPOCH {
            0.0
        } else {
            self.drive_rate
        };
        self.drive_clock = self.clock;
        self.drive_path = now.path_m;
        self.drive_step = self.drive_speed * scene.h;
        self.drive_rate = now.rate_m_per_s;
        self.kick_hammer(scene, -(now.rate_m_per_s - prev));
    }
}
