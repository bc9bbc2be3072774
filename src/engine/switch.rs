//! Changing phase: the offset rod's decision at a sample instant, entering
//! contact and leaving it (one change of basis, or the state a strike
//! from rest stored), and the log of the last tick's switches.

use super::dot::dot3;
use super::kernel;
use super::{EngineState, Phase, RestRun, SwitchEvent, CONTACT, FREE};
use crate::compile::CompiledScene;
use crate::scene::Switching;

impl EngineState {
    /// The event function now: flight `x_h - x_c`, contact `p_eff`
    /// (from the cached rows: the same numbers the fast path decides on).
    fn phi_now(&mut self, scene: &CompiledScene) -> f64 {
        if !self.cache_ok {
            self.refresh_cache(scene);
        }
        if self.in_contact() {
            self.cache[0] + self.offsets(scene).pi / scene.sk
        } else {
            self.cache[0] + self.x_h
        }
    }

    /// Offset rod: the decision at a sample instant, on the same numbers
    /// the fast path uses ([`phi_now`](Self::phi_now)).
    pub(super) fn decide(&mut self, scene: &CompiledScene) {
        let phi = self.phi_now(scene);
        if self.in_contact() {
            // Leave at the first sample with p_eff <= 0 (paper 2.2); cutting the
            // spring there can only lose its energy 0.5 k p_eff^2.
            if !(phi > 0.0) {
                self.leave_contact(scene);
            }
        } else if phi < 0.0 {
            // p = x_c - x_h = -phi > 0
            self.enter_contact(scene, -phi);
        }
    }

    /// Offset rod: the spring starts unstretched (p_eff = 0), so entering
    /// contact adds no energy. O(N^2): one change of basis; O(N) when the
    /// object is at rest (its coordinates are all zero).
    pub(super) fn enter_contact(&mut self, scene: &CompiledScene, p: f64) {
        let at_rest = self.phases[FREE].s.iter().all(|&x| x == 0.0);
        let stored = if at_rest {
            None
        } else {
            self.rest_next(scene, true)
        };
        self.rod_m = p;
        let eta = scene.sm * self.v_h;
        let dc = scene.contact.dim;
        let load = self.load;
        let [free, contact] = &mut self.phases;
        if let Some((sw, d, scale)) = stored {
            // a later contact of a strike from rest, where the compiler
            // found it: the state it stored
            for i in 0..dc {
                contact.s[i] = scale * (sw.s[i] + d * sw.s_d[i]) - scene.s_star[i] * load;
            }
        } else {
            for i in 0..dc {
                contact.s[i] = scene.col_eta[i] * eta - scene.s_star[i] * load;
            }
            if !at_rest {
                kernel::change_of_basis_add(
                    self.simd,
                    scene.w_cf_h.as_ref().filter(|_| self.structured),
                    scene.w_cf.as_slice(),
                    dc,
                    &free.s,
                    &mut contact.s,
                    &mut self.dense_tmp,
                );
            }
        }
        if at_rest {
            // a strike from rest begins: follow it
            self.rest_run =
                (self.rest_enabled && scene.rest.is_some() && scene.switching == Switching::Exact)
                    .then_some(RestRun {
                        clock0: self.clock,
                        t0: self.t_in_step,
                        eta,
                        next: 0,
                        lambda: 1.0,
                    });
        }
        self.phase = Phase::Contact;
        self.contacts_started += 1;
        self.discontinuity();
        self.log_event(true);
    }

    /// Cut the spring (can only remove its energy). O(N^2): one change of
    /// basis; O(N) at the end of a strike on the object at rest, whose free
    /// state the compiler stored (docs/numerics.md, "A strike on an object
    /// at rest").
    pub(super) fn leave_contact(&mut self, scene: &CompiledScene) {
        let rows = &scene.contact.rows;
        let [pi, x_c, eta] = dot3([&rows.pi, &rows.x_c, &rows.eta], &self.phases[CONTACT].s);
        // exactly `penetration`'s
        let off = self.offsets(scene);
        let p_eff = (pi + off.pi) / scene.sk;
        let x_c = x_c + off.x_c;
        let mut eta = eta + off.eta;
        let df = scene.free.dim;
        let load = self.load;
        let rest = self.rest_next(scene, false);
        let [free, contact] = &mut self.phases;
        if let Some((sw, d, scale)) = rest {
            for i in 0..df {
                free.s[i] = scene.s_f_star[i] * load + scale * (sw.s[i] + d * sw.s_d[i]);
            }
            if let Some((e, e_d)) = sw.hammer_eta {
                // the hammer leaves on the stored trajectory too
                eta = scale * (e + d * e_d);
            }
        } else {
            for (x, s) in free.s[..df].iter_mut().zip(&scene.s_f_star) {
                *x = s * load;
            }
            kernel::change_of_basis_add(
                self.simd,
                scene.w_fc_h.as_ref().filter(|_| self.structured),
                scene.w_fc.as_slice(),
                df,
                &contact.s,
                &mut free.s,
                &mut self.dense_tmp,
            );
        }
        self.x_h = x_c - p_eff - self.rod_m;
        self.v_h = eta / scene.sm;
        self.rod_m = 0.0;
        self.phase = Phase::Free;
        self.discontinuity();
        self.log_event(false);
    }

    fn log_event(&mut self, entered: bool) {
        if self.n_events < self.events.len() {
            self.events[self.n_events] = SwitchEvent {
                after_s: self.t_in_step / self.time_scale,
                entered,
            };
            self.n_events += 1;
        } else {
            self.events_dropped += 1;
        }
    }

    /// Enter contact (offset rod at the current penetration) and leave it
    /// again: two changes of basis, O(N^2). Only for benchmarks of the switch
    /// cost. \[any-thread\]
    #[doc(hidden)]
    pub fn bench_switch_pair(&mut self, scene: &CompiledScene) {
        let p = self.penetration(scene);
        self.enter_contact(scene, p.max(0.0));
        self.leave_contact(scene);
    }

    /// Phase switches that happened during the last `tick` (offline
    /// diagnostics: contact start/end times). \[any-thread\]
    pub fn switch_events(&self) -> &[SwitchEvent] {
        &self.events[..self.n_events]
    }

    /// Record up to `n` switches per tick (default 64). Allocates: not on
    /// the audio thread. \[main-thread\]
    pub fn set_event_log_capacity(&mut self, n: usize) {
        self.events = vec![SwitchEvent::default(); n];
        self.n_events = 0;
    }
}
