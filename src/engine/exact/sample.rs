//! One sample of exact switching: the sample's start after a strike that
//! put the hammer on the surface, the Hermite certificate, the model and
//! the search for the first crossing in the rest of the sample, the switch
//! there, and again until the sample is consumed.

use super::{MAX_SWITCHES_PER_SAMPLE, NEUTRAL_TOL};
use crate::compile::CompiledScene;
use crate::engine::search::Found;
use crate::engine::EngineState;

impl EngineState {
    /// Switch phase at the current instant (exact switching): cut the
    /// spring, or start it unstretched (the rod offset takes up the
    /// rounding residual of `phi` at the root, so no energy is added).
    fn switch_now(&mut self, scene: &CompiledScene) {
        if self.in_contact() {
            self.leave_contact(scene);
        } else {
            let p = -self.eval_event3(scene, 0.0, false)[0];
            self.enter_contact(scene, p);
        }
    }

    /// What the coming sample's start is when a strike just put the
    /// hammer on the surface (`phi = 0` exactly, [`EngineState::strike`])
    /// and nothing changed since, in flight: the contact's start if the
    /// hammer moves into the surface (`phi' < 0`), else an instant that is
    /// no crossing (the surface moves away at least as fast: the search
    /// looks past it). The search alone decided this through its model's
    /// sums, which put `phi(0)` a rounding above or below zero: it located
    /// the entry up to a few 1e-14 of a sample late for about half of the
    /// strikes on a moving object (a partial step and a search for it), and
    /// where the surface moved away, a rounding below zero made a contact
    /// that ended a rounding later. docs/numerics.md section 6.9.
    /// \[audio-thread\]
    fn strike_start(&mut self, scene: &CompiledScene) -> StrikeStart {
        if !std::mem::take(&mut self.struck_on_surface) || self.in_contact() {
            return StrikeStart::Search;
        }
        let [f, d, _] = self.eval_event3(scene, 0.0, false);
        if f != 0.0 {
            StrikeStart::Search
        } else if d < 0.0 {
            StrikeStart::Enter
        } else {
            StrikeStart::Open
        }
    }

    /// Exact-switching step of one sample (reference duration `step_s`).
    /// O(N) plus the slow polynomial without events; per switch one change
    /// of basis, O(N^2), and a number of node evaluations bounded by the
    /// phase's time scales. Allocation-free. \[audio-thread\]
    pub(in crate::engine) fn advance_exact(&mut self, scene: &CompiledScene) {
        let step = self.step_s;
        let max_switches = MAX_SWITCHES_PER_SAMPLE;
        let mut t = 0.0; // time consumed in this sample
        let mut switches: u64 = 0;
        let mut nodes: u64 = 0;
        let mut open = false;
        match self.strike_start(scene) {
            StrikeStart::Enter => {
                // the crossing is this instant: the strike put the hammer
                // on the surface, moving into it
                self.switch_now(scene);
                self.exact_stats.located += 1;
                self.exact_stats.strike_entries += 1;
                switches = 1;
                open = true;
            }
            // on the surface, not moving into it: this instant is no
            // crossing, the search looks past it
            StrikeStart::Open => open = true,
            StrikeStart::Search => {
                // A sample that holds a strike from rest's next stored
                // switch holds a crossing: the certificate would fail (and
                // where it would not, the search's "no root" leaves the
                // same bits).
                if self.rest_due_in(scene) != Some(0) && self.hermite_clear(scene) {
                    return;
                }
            }
        }
        loop {
            let rem = step - t;
            if rem <= 0.0 {
                break;
            }
            let full = t == 0.0;
            let found = if let Some(w) = self.rest_trusted_switch(scene, t) {
                // a strike from rest's switch where the engine's
                // certifying run located it: no search
                self.exact_stats.rest_trusted += 1;
                Found::At(w)
            } else {
                if open
                    && switches > 0
                    && self.hermite_after_switch
                    && self.hermite_clear_rest(scene, rem)
                {
                    break;
                }
                self.build_model(scene, rem);
                if !(self.search.tol.is_finite() && self.search.tol_d.is_finite()) {
                    self.exact_stats.nonfinite += 1;
                    self.advance_by(scene, rem, full);
                    break;
                }
                let mut at_origin = false;
                if !open {
                    // a sample that starts on (or within rounding beyond) the
                    // surface: the crossing is at this instant
                    let [f0, d0, _] = self.model_eval(scene, 0.0);
                    if f0 < 0.0 || (f0 == 0.0 && d0 < 0.0) {
                        if f0 < -NEUTRAL_TOL * self.search.tol {
                            self.exact_stats.rod_fallbacks += 1;
                        }
                        at_origin = true;
                    } else if f0 == 0.0 {
                        open = true;
                    }
                }
                if at_origin {
                    Found::At(0.0)
                } else {
                    self.first_root(scene, rem, open, &mut nodes)
                }
            };
            match found {
                Found::None => {
                    self.advance_by(scene, rem, full);
                    break;
                }
                Found::At(tau) => {
                    let tau = tau.min(rem);
                    self.advance_by(scene, tau, full && tau == rem);
                    t += tau;
                    self.t_in_step = t;
                    self.switch_now(scene);
                    self.exact_stats.located += 1;
                    switches += 1;
                    open = true;
                    if switches >= max_switches {
                        self.exact_stats.capped += 1;
                        self.advance_by(scene, step - t, false);
                        break;
                    }
                }
            }
        }
        let st = &mut self.exact_stats;
        st.search_nodes += nodes;
        st.max_nodes_in_sample = st.max_nodes_in_sample.max(nodes);
        st.max_switches_in_sample = st.max_switches_in_sample.max(switches);
    }
}

/// A sample's start after a strike that put the hammer on the surface
/// ([`EngineState::strike_start`]).
enum StrikeStart {
    /// Not such a sample: the search decides.
    Search,
    /// The contact begins now.
    Enter,
    /// This instant is no crossing.
    Open,
}
