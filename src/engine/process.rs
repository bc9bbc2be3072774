//! The entry points that run samples: [`EngineState::tick`] and its
//! observed forms, [`EngineState::process_block`] and the observed block
//! paths. Each runs the fast path (`fast_path`) where it can and one
//! sample on the slow path where it cannot: a sample that may hold a
//! switch (the exact search, or the offset rod's decision) or a sample of
//! a dense-fallback phase.

use super::denormal::FlushDenormals;
use super::dot::dot;
use super::kernel;
use super::observe::ObsOut;
use super::{current_phase, EngineState, Motion, Observation, Phase};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::scene::Switching;

impl EngineState {
    /// One sample: decide the phase at the current instant, return the output
    /// `[left, right]` of the current state, and advance one step. Same
    /// result as one sample of [`process_block`](Self::process_block).
    /// Allocation-free, O(N) (O(N^2) on a switch). \[audio-thread\]
    #[inline]
    pub fn tick(&mut self, scene: &CompiledScene) -> [f64; 2] {
        let (mut l, mut r) = ([0.0], [0.0]);
        self.process_block(scene, &mut l, &mut r);
        [l[0], r[0]]
    }

    /// Like [`tick`](Self::tick) but also returns the trace observation taken
    /// after the switching decision (docs/design.md, "The render command and
    /// the trace CSV"). O(N) plus the energy's cost ([`energy`](Self::energy)):
    /// offline only.
    pub fn tick_observed(&mut self, scene: &CompiledScene) -> ([f64; 2], Observation) {
        self.tick_with(scene, |st| st.observe(scene))
    }

    /// Like [`tick`](Self::tick), calling `look` on the state at the instant
    /// the trace records (after the switching decision, before the step):
    /// a caller that needs only part of the observation (e.g.
    /// [`motion`](Self::motion), and the energy now and then) pays only for
    /// that. Same samples as [`tick`](Self::tick). \[offline\]
    pub fn tick_with<R>(
        &mut self,
        scene: &CompiledScene,
        look: impl FnOnce(&mut Self) -> R,
    ) -> ([f64; 2], R) {
        self.settle(scene);
        self.drive_sample(scene);
        let _flush = FlushDenormals::new(self.flush_denormals);
        self.n_events = 0;
        self.t_in_step = 0.0;
        let rod = scene.switching == Switching::OffsetRod;
        if rod {
            self.decide(scene);
        }
        let seen = look(self);
        let (mut l, mut r) = ([0.0], [0.0]);
        let (done, _) = self.run_fast(scene, &mut l, &mut r, rod, None);
        let out = if done == 1 {
            [l[0], r[0]]
        } else {
            self.slow_sample(scene, rod)
        };
        (out, seen)
    }

    /// Fill `left`/`right` with consecutive samples (f64): the block form of
    /// [`tick`](Self::tick), and what the instrument runs. The result does
    /// not depend on how a run is split into blocks (bit for bit).
    ///
    /// Samples in which no switch can happen (certified in exact mode by the
    /// curvature bound, decided by the sign test with the offset rod) run in
    /// the block kernel, up to `EPOCH` at a time; a sample that may hold a
    /// switch, and every sample of a dense-fallback phase, takes the slow
    /// path (event location, change of basis). Subnormal numbers are
    /// flushed to zero meanwhile ([`denormal`](super::denormal)), so a fading voice does not
    /// get slower. Allocation-free, no system call, O(N) per sample plus
    /// O(N^2) per switch. \[audio-thread\]
    pub fn process_block(&mut self, scene: &CompiledScene, left: &mut [f64], right: &mut [f64]) {
        let n = left.len().min(right.len());
        let mut i = self.replay_block(&mut left[..n], &mut right[..n]);
        if i == n {
            return;
        }
        let _flush = FlushDenormals::new(self.flush_denormals);
        kernel::clean_upper_state(self.simd);
        // a driven scene runs one sample at a time: its hammer is given
        // the surface's slope at every sample instant
        let driven = scene.drive.is_some();
        while i < n {
            let end = if driven { i + 1 } else { n };
            self.drive_sample(scene);
            let (done, slow) =
                self.run_fast(scene, &mut left[i..end], &mut right[i..end], false, None);
            i += done;
            if slow && i < n {
                self.drive_sample(scene);
                let o = self.slow_sample(scene, false);
                left[i] = o[0];
                right[i] = o[1];
                i += 1;
            }
        }
    }

    /// [`process_block`](Self::process_block) that also writes each
    /// sample's [`Motion`] into `motion` (as [`tick_with`](Self::tick_with)
    /// would see it, after the switching decision): fast samples get it from
    /// the contact point's rows, summed in the block path's own kernel pass
    /// (about 1.3-1.6x the block path's cost at 100-1000 modes, instead of a
    /// tick per sample). Same
    /// samples as `process_block` bit for bit; the motion equals
    /// [`motion`](Self::motion)'s up to the order of the sums (rounding).
    /// Allocates its scratch on the first call unless
    /// [`reserve_observation`](Self::reserve_observation) did.
    /// \[offline\] \[audio-thread after `reserve_observation`\]
    pub fn process_block_observed(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
    ) {
        self.observed(scene, left, right, motion, None);
    }

    /// [`process_block_observed`](Self::process_block_observed) that also
    /// writes each sample's [`energy`](Self::energy) into `energy`. In a
    /// phase whose energy coordinates do not mix blocks
    /// ([`CompiledPhase::energy_quad`]: a modal object in flight, its
    /// uncoupled modes) the energy comes from the same kernel pass as the
    /// motion, O(N) per sample; elsewhere (a coupled contact phase, a
    /// string, gravity's equilibrium offset) each sample takes
    /// [`energy`](Self::energy), O(dim^2). Same samples as `process_block`
    /// bit for bit; motion and energy equal [`motion`](Self::motion)'s and
    /// [`energy`](Self::energy)'s up to the order of the sums. Allocates its
    /// scratch on the first call. \[offline\]
    pub fn process_block_traced(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
        energy: &mut [f64],
    ) {
        self.observed(scene, left, right, motion, Some(energy));
    }

    fn observed(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
        mut energy: Option<&mut [f64]>,
    ) {
        if energy.is_some() {
            // the energy is not stored with a strike from rest
            self.settle(scene);
        }
        self.reserve_observation();
        let mut n = left.len().min(right.len()).min(motion.len());
        if let Some(e) = energy.as_deref() {
            n = n.min(e.len());
        }
        let mut i = self.replay_observed(&mut left[..n], &mut right[..n], &mut motion[..n]);
        if scene.drive.is_some() {
            // a driven scene: sample by sample on the tick path, which runs
            // the samples the block path runs (the observing kernel tries
            // the fast path's certificates differently, and a sample it
            // leaves to the slow path rounds otherwise)
            let want = energy.is_some();
            for k in i..n {
                let (o, (m, e)) = self.tick_with(scene, |st| {
                    (st.motion(scene), want.then(|| st.energy_observed(scene)))
                });
                [left[k], right[k]] = o;
                motion[k] = m;
                if let (Some(es), Some(e)) = (energy.as_deref_mut(), e) {
                    es[k] = e;
                }
            }
            return;
        }
        let _flush = FlushDenormals::new(self.flush_denormals);
        kernel::clean_upper_state(self.simd);
        while i < n {
            let (done, slow) = self.run_fast(
                scene,
                &mut left[i..n],
                &mut right[i..n],
                false,
                Some(ObsOut {
                    m: &mut motion[i..n],
                    e: energy.as_deref_mut().map(|e| &mut e[i..n]),
                }),
            );
            i += done;
            if slow && i < n {
                let want = energy.is_some();
                let (o, (m, e)) = self.tick_with(scene, |st| {
                    (st.motion(scene), want.then(|| st.energy_observed(scene)))
                });
                left[i] = o[0];
                right[i] = o[1];
                motion[i] = m;
                if let (Some(es), Some(e)) = (energy.as_deref_mut(), e) {
                    es[i] = e;
                }
                i += 1;
            }
        }
    }

    /// One sample on the slow path: a possible switch (located exactly, or
    /// the offset rod's decision) or a dense-fallback phase. `decided`: the
    /// offset-rod decision for this instant was already taken. \[audio-thread\]
    fn slow_sample(&mut self, scene: &CompiledScene, decided: bool) -> [f64; 2] {
        if !decided {
            self.n_events = 0;
            self.t_in_step = 0.0;
        }
        let out = if scene.switching == Switching::Exact {
            let out = self.output(scene);
            self.advance_exact(scene);
            self.discontinuity();
            out
        } else {
            if !decided {
                self.decide(scene);
            }
            let out = self.output(scene);
            self.step_plain(scene);
            out
        };
        self.clock += 1;
        out
    }

    /// One step of the current phase, no switching (offset rod after its
    /// decision): the block kernel, or the dense propagator.
    fn step_plain(&mut self, scene: &CompiledScene) {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph = current_phase(self, scene);
        if ph.dense.is_some() || ph.gens.is_none() {
            let s = &mut self.phases[phase.index()].s;
            step_phase(ph, s, &mut self.scratch);
            self.cache_ok = false;
        } else {
            self.run_kernel(scene, 1);
            self.commit_kernel(1);
        }
        if !in_contact {
            // Hammer in flight: exact parabola (never diagonalised), in
            // reference time (step s h, the scene's gravity).
            let dt = self.step_s;
            self.x_h += self.v_h * dt - 0.5 * self.g * dt * dt;
            self.v_h -= self.g * dt;
        }
    }

    #[inline]
    fn output(&mut self, scene: &CompiledScene) -> [f64; 2] {
        if !self.cache_ok {
            self.refresh_cache(scene);
        }
        if self.in_contact() {
            [
                self.cache[1] + self.out_c_offset()[0],
                self.cache[2] + self.out_c_offset()[1],
            ]
        } else {
            [self.cache[1], self.cache[2]]
        }
    }
}

/// One step of a dense-fallback phase: `s = exp(A h) s`.
#[inline]
fn step_phase(ph: &CompiledPhase, s: &mut [f64], scratch: &mut [f64]) {
    let (_, phi) = ph.dense.as_ref().expect("dense phase");
    let n = ph.dim;
    for i in 0..n {
        let row = &phi[i * n..(i + 1) * n];
        scratch[i] = dot(row, s);
    }
    s[..n].copy_from_slice(&scratch[..n]);
}
