//! The fast path: runs of up to `EPOCH` samples through the block kernel,
//! certified afterwards sample by sample (exact switching: the chord test
//! against the interpolation margin, or the Hermite certificate; the
//! offset rod: its sign test), and the margins and cached rows they are
//! checked with.

use super::dot::dot;
use super::kernel::{
    self, rows_of, run_block_with, BlockIo, Extras, ObsIo, QuadIo, Rows, SlopeIo, EPOCH,
};
use super::observe::{obs_rows, ObsOut};
use super::search::hermite_low;
use super::{current_phase, EngineState, Phase, SlopeScratch};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::scene::Switching;

/// Samples the fast path tries after a sample failed its check. A kernel
/// run first loads every block's state, propagator and rows (at 200 modes
/// about as long as stepping 10 samples), so short runs cost nearly as
/// much as long ones, while a failure costs the run and a re-run of the
/// samples before it; so restarting at 16 rather than 1 makes a strike on
/// a ringing object cheaper, the more so the fewer its modes (the strike
/// table of `cargo bench --bench worst_block` measures a strike). Speed
/// only: the kernel's per-sample
/// sums do not depend on a run's length, so the output is the same bit for
/// bit.
const SPEC_RESTART: usize = 16;

/// What a fast-path kernel run sums for the trace beside the audio.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Observe {
    /// Nothing (the instrument).
    No,
    /// The rows `x_c, v_c, eta` (in flight `v_c` alone: `x_c` is the
    /// negated event row).
    Motion,
    /// Those and the energy's block-diagonal form.
    MotionEnergy,
}

impl EngineState {
    /// The fast path: run up to `left.len()` samples (within the current
    /// epoch and the speculation length) through the block kernel, then
    /// check them in order; commit every sample before the first one that
    /// may hold a switch. Returns the samples done and whether the next one
    /// needs the slow path. `decided`: the offset-rod decision for the first
    /// sample was already taken (traces). \[audio-thread\]
    pub(super) fn run_fast(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        decided: bool,
        obs: Option<ObsOut>,
    ) -> (usize, bool) {
        let in_contact = self.phase == Phase::Contact;
        let ph = current_phase(self, scene);
        if ph.dense.is_some() || ph.gens.is_none() {
            return (0, true);
        }
        let exact = scene.switching == Switching::Exact;
        let energy = obs.as_ref().is_some_and(|o| o.e.is_some());
        let (k_max, slow) = self.run_length(scene, left.len().min(right.len()), energy, exact);
        if k_max == 0 {
            return (0, slow);
        }
        let hermite = self.refresh_margins(scene, exact);
        if exact && !self.first_sample_may_pass(scene, hermite) {
            self.restart_speculation(self.clock / EPOCH as u64 + 1);
            return (0, true);
        }
        let observe = match &obs {
            None => Observe::No,
            Some(o) if o.e.is_some() && self.quad_energy_ok(scene) => Observe::MotionEnergy,
            Some(_) => Observe::Motion,
        };
        self.run_kernel_rows(scene, k_max, hermite, observe);
        let (k_ok, (x_h, v_h)) = self.check_run(
            scene,
            &mut left[..k_max],
            &mut right[..k_max],
            decided,
            hermite,
        );
        if k_ok < k_max {
            self.exact_stats.kernel_discarded += (k_max - k_ok) as u64;
            self.restart_speculation((self.clock + k_ok as u64) / EPOCH as u64 + 1);
            if k_ok == 0 {
                return (0, true);
            }
            // Re-run only the certified samples (bit-identical: the kernel's
            // per-sample sums do not depend on the number of samples).
            self.run_kernel(scene, k_ok);
        } else {
            self.spec_len = (2 * self.spec_len).min(EPOCH);
        }
        if let Some(ObsOut { m, e }) = obs {
            self.observe_run(
                scene,
                k_ok,
                ObsOut {
                    m: &mut m[..k_ok],
                    e: e.map(|e| &mut e[..k_ok]),
                },
            );
        }
        self.commit_kernel(k_ok);
        if !in_contact {
            self.x_h = x_h;
            self.v_h = v_h;
        }
        self.clock += k_ok as u64;
        // The events of the last sample: none in a fast sample, unless the
        // offset rod's decision for it was already taken (and logged) by
        // `tick_observed`.
        if !(decided && k_ok == 1) {
            self.n_events = 0;
        }
        (k_ok, k_ok < k_max)
    }

    /// How many of the `n` samples asked for the coming run takes: no more
    /// than the rest of the epoch and the speculation length, one where the
    /// trace's `energy` must come from the state itself, and (`exact`) none
    /// past the start of the sample that holds a strike from rest's next
    /// stored switch. With none, whether the next sample needs the slow
    /// path.
    fn run_length(
        &mut self,
        scene: &CompiledScene,
        n: usize,
        energy: bool,
        exact: bool,
    ) -> (usize, bool) {
        let epoch_left = EPOCH - (self.clock % EPOCH as u64) as usize;
        let mut k_max = n.min(epoch_left).min(self.spec_len);
        if energy && !self.quad_energy_ok(scene) {
            // energy from the state itself, one sample at a time
            k_max = k_max.min(1);
        }
        if k_max == 0 {
            return (0, false);
        }
        if exact {
            // A strike from rest knows the sample its next switch falls in
            // (a hint for where the run stops, never a decision): the run
            // ends before it, and that sample goes to the slow path as a
            // failed test would send it, without the run past it that the
            // failed test would throw away. Same samples bit for bit.
            match self.rest_due_in(scene) {
                Some(0) => {
                    self.restart_speculation(self.clock / EPOCH as u64 + 1);
                    return (0, true);
                }
                Some(k) => k_max = k_max.min(k),
                None => {}
            }
        }
        (k_max, false)
    }

    /// A sample failed its test, or will: the next runs start at
    /// `SPEC_RESTART` samples again, and the fast path tries the Hermite
    /// certificate up to the epoch `until` of the clock.
    fn restart_speculation(&mut self, until: u64) {
        self.spec_len = SPEC_RESTART;
        self.herm_until = Some(until);
    }

    /// Make the cached rows and the margins the coming run is checked with
    /// current: the interpolation margin of this epoch (`exact`), and the
    /// Hermite certificate's where the fast path tries it. Returns whether
    /// it does.
    fn refresh_margins(&mut self, scene: &CompiledScene, exact: bool) -> bool {
        if !self.cache_ok {
            self.refresh_cache(scene);
        }
        let epoch = self.clock / EPOCH as u64;
        let dt = self.step_s;
        if exact && (self.bound_epoch != epoch || self.bound_dt != dt) {
            self.bound = self.fast_margin(scene, dt);
            self.bound_epoch = epoch;
            self.bound_dt = dt;
        }
        // In the epoch of a sample that failed its test and the next one,
        // the samples are also tried with the Hermite certificate
        // (docs/numerics.md section 6.2): the kernel then sums the slope
        // row too. Keyed to the voice's clock (runs never cross an epoch),
        // so the output does not depend on how blocks are split.
        let hermite = exact && self.fast_hermite && self.herm_until.is_some_and(|u| epoch <= u);
        if hermite && (self.herm_epoch != epoch || self.herm_dt != dt) {
            (self.herm_rem, self.herm_mag) = self.hermite_margin(scene, dt);
            self.herm_epoch = epoch;
            self.herm_dt = dt;
        }
        hermite
    }

    /// Whether the run's first sample can pass its test (exact switching).
    /// The test needs `phi0 - margin > 0` (or the Hermite certificate,
    /// whose lower bound is at most `phi0`), and `phi0` is known before the
    /// run. Where it fails (the samples before a slow release, the sample a
    /// strike starts in) every sample of the run would be thrown away: the
    /// same decision, without the O(N k) run.
    fn first_sample_may_pass(&self, scene: &CompiledScene, hermite: bool) -> bool {
        let in_contact = self.phase == Phase::Contact;
        let herm_units = herm_units(current_phase(self, scene));
        let phi0 = self.cache[0]
            + if in_contact {
                self.offsets(scene).pi / scene.sk
            } else {
                self.x_h
            };
        let herm_ok = hermite && phi0 - self.herm_rem - herm_units * self.herm_mag > 0.0;
        phi0 - self.bound > 0.0 || herm_ok
    }

    /// Check the `left.len()` samples the kernel just ran, in order, and
    /// write the output of each that passes: exact switching's chord test
    /// against the interpolation margin, or (`hermite`) the Hermite
    /// certificate; the offset rod's sign test (`decided`: the first
    /// sample's decision was already taken). The hammer in flight follows
    /// its exact parabola. Returns how many pass before the first that
    /// fails, and the hammer's height and reference velocity after them.
    fn check_run(
        &self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        decided: bool,
        hermite: bool,
    ) -> (usize, (f64, f64)) {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph = current_phase(self, scene);
        let exact = scene.switching == Switching::Exact;
        let herm_units = herm_units(ph);
        let dt = self.step_s;
        let k_max = left.len();
        // The slope at the run's first state, `phi'`: an O(N) sequential
        // sum, needed only where the first sample's chord test fails (later
        // samples take the kernel's slope row), so it is summed there.
        let mut d_j: Option<f64> = None;
        let g = self.g;
        let margin = self.bound;
        let (off, out_off) = if in_contact {
            (self.offsets(scene).pi / scene.sk, self.out_c_offset())
        } else {
            (0.0, [0.0; 2])
        };
        let (mut x_h, mut v_h) = (self.x_h, self.v_h);
        let mut rows_j = self.cache;
        let mut k_ok = k_max;
        for j in 0..k_max {
            let phi0 = rows_j[0] + if in_contact { off } else { x_h };
            let (x_h1, v_h1) = if in_contact {
                (x_h, v_h)
            } else {
                (x_h + v_h * dt - 0.5 * g * dt * dt, v_h - g * dt)
            };
            let next_rows = [self.brows.ev[j], self.brows.l[j], self.brows.r[j]];
            let ok = if exact {
                let phi1 = next_rows[0] + if in_contact { off } else { x_h1 };
                let chord = phi1 > 0.0 && phi0.min(phi1) - margin > 0.0;
                let d1 = if hermite {
                    self.slope.out[j] + if in_contact { 0.0 } else { v_h1 }
                } else {
                    0.0
                };
                let ok = chord
                    || hermite && {
                        let d0 = *d_j.get_or_insert_with(|| {
                            dot(&ph.ev_d, &self.phases[phase.index()].s)
                                + if in_contact { 0.0 } else { self.v_h }
                        });
                        let low = hermite_low([phi0, d0, phi1, d1], dt);
                        let hammer = if in_contact {
                            off.abs()
                        } else {
                            x_h.abs() + x_h1.abs() + dt * (v_h.abs() + v_h1.abs())
                        };
                        let allow = herm_units * (self.herm_mag + hammer);
                        low - self.herm_rem - allow > 0.0
                    };
                d_j = Some(d1);
                ok
            } else if j == 0 && decided {
                true
            } else if in_contact {
                phi0 > 0.0 // leave at the first sample with p_eff <= 0
            } else {
                !(phi0 < 0.0) // enter at the first sample with p > 0
            };
            if !ok {
                k_ok = j;
                break;
            }
            left[j] = rows_j[1] + out_off[0];
            right[j] = rows_j[2] + out_off[1];
            rows_j = next_rows;
            x_h = x_h1;
            v_h = v_h1;
        }
        (k_ok, (x_h, v_h))
    }

    /// Run the block kernel `k` samples from the current block phase's
    /// state into the spare buffer (the state itself is left untouched) and
    /// leave the rows of every stepped state in `brows`.
    pub(super) fn run_kernel(&mut self, scene: &CompiledScene, k: usize) {
        self.run_kernel_rows(scene, k, false, Observe::No);
    }

    /// The kernel run of [`run_kernel`](Self::run_kernel), with the slope
    /// row when `slope`, and with what `observe` asks summed into the
    /// observation scratch (the trace's rows `x_c, v_c, eta`, and the
    /// energy's form): one pass over the state for the audio and the trace.
    fn run_kernel_rows(&mut self, scene: &CompiledScene, k: usize, slope: bool, observe: Observe) {
        let ph = scene.phase(self.phase);
        let in_contact = self.in_contact();
        let ps = &mut self.phases[self.phase.index()];
        let (s, next, props, out) = (&ps.s, &mut ps.next, &ps.props, &ps.out);
        let io = BlockIo {
            p: props,
            s,
            next,
            rows: Rows {
                ev: &ph.ev,
                l: &out[0],
                r: &out[1],
            },
            acc: &mut self.acc,
            out: &mut self.brows,
        };
        let mut extras = Extras::default();
        if slope {
            let SlopeScratch { acc, out: dout } = &mut *self.slope;
            extras.slope = Some(SlopeIo {
                row: &ph.ev_d,
                acc,
                out: dout,
            });
        }
        if observe != Observe::No {
            let obs = self
                .obs
                .as_deref_mut()
                .expect("allocated by reserve_observation");
            // in flight the event row is `-x_c` (the compiler's), so the
            // kernel's own event sums give `x_c` and only `v_c` is added
            extras.obs = Some(ObsIo {
                rows: if in_contact {
                    obs_rows(ph, &obs.zeros, true)
                } else {
                    Rows {
                        ev: &ph.rows.v_c,
                        l: &ph.rows.v_c,
                        r: &ph.rows.v_c,
                    }
                },
                all: in_contact,
                acc: &mut obs.oacc,
                out: &mut obs.rows,
            });
            if observe == Observe::MotionEnergy {
                extras.quad = ph.energy_quad.as_ref().map(|quad| QuadIo {
                    quad,
                    acc: &mut obs.qacc,
                    out: &mut obs.qout,
                });
            }
        }
        run_block_with(self.simd, io, extras, k);
    }

    /// The Hermite certificate's remainder for steps of `dt` from the
    /// current state, valid for every later state of the phase (each block
    /// is a contraction), and the magnitude its rounding allowance scales
    /// with: `(sum_k min(c4_k dt^4 / 384, 2 e_k + 8/27 dt c1_k) |s_k| (1 +
    /// 1e-12), sum_k (e_k + dt c1_k) |s_k|)`. docs/numerics.md section 6.2.
    fn hermite_margin(&self, scene: &CompiledScene, dt: f64) -> (f64, f64) {
        let (ph, s) = (scene.phase(self.phase), &self.phases[self.phase.index()].s);
        let nb = ph.dim / 2;
        if ph.ev_d4_block.len() != nb {
            return (f64::INFINITY, f64::INFINITY);
        }
        let (dt4, tail) = (dt * dt * dt * dt / 384.0, 8.0 / 27.0 * dt);
        let (rem, mag) = kernel::hermite_sums(
            self.simd,
            &s[..2 * nb],
            [&ph.ev_d_block, &ph.ev_d4_block, &ph.ev_block],
            [dt4, tail, dt],
        );
        (rem * (1.0 + 1e-12), mag)
    }

    /// Adopt the state of the last [`run_kernel`](Self::run_kernel) call,
    /// which ran `k >= 1` samples, and its rows as the cached rows.
    pub(super) fn commit_kernel(&mut self, k: usize) {
        let ps = &mut self.phases[self.phase.index()];
        std::mem::swap(&mut ps.s, &mut ps.next);
        let j = k - 1;
        self.cache = [self.brows.ev[j], self.brows.l[j], self.brows.r[j]];
        self.cache_ok = true;
    }

    /// Interpolation margin for fast steps of `dt` from the current state:
    /// a bound on `|phi(t) - L(t)|` within any later step of the phase,
    /// `L` the chord between the step's end values, so that both end values
    /// above the margin certify no crossing inside. Per block the smaller
    /// of its curvature's share `c_k |s_k| dt^2 / 8` and `2 e_k |s_k|` (the
    /// block's share of `phi` and of the chord both stay within
    /// `e_k |s_k|`); no larger than the curvature bounds `|ev_dd| |s|` and
    /// `sqrt(sum c_k * sum c_k |s_k|^2)` times `dt^2 / 8` (see
    /// `CompiledPhase::ev_dd_block`, `ev_block`; docs/numerics.md section
    /// 6.2); plus gravity's exact `g dt^2 / 8` in flight. Valid for every
    /// later state of the phase. O(N).
    pub(super) fn fast_margin(&self, scene: &CompiledScene, dt: f64) -> f64 {
        let (ph, s) = (scene.phase(self.phase), &self.phases[self.phase.index()].s);
        let h = dt * dt / 8.0;
        let (e, w, blocks) = kernel::margin_sums(self.simd, s, &ph.ev_dd_block, &ph.ev_block, h);
        let global2 = ph.ev_dd_norm * ph.ev_dd_norm * e;
        let weighted2 = ph.ev_dd_block_sum * w;
        let g = if self.in_contact() { 0.0 } else { self.g };
        // 1 + 1e-12: the blocks are contractions up to rounding of exp2,
        // and the sums round
        (g * h + blocks.min(global2.min(weighted2).sqrt() * h)) * (1.0 + 1e-12)
    }

    pub(super) fn refresh_cache(&mut self, scene: &CompiledScene) {
        let ph = scene.phase(self.phase);
        let ps = &self.phases[self.phase.index()];
        let (s, out) = (&ps.s, &ps.out);
        let rows = Rows {
            ev: &ph.ev,
            l: &out[0],
            r: &out[1],
        };
        self.cache = rows_of(self.simd, s, &rows);
        self.cache_ok = true;
    }
}

/// The Hermite certificate's rounding allowance per unit of the magnitudes
/// it sums, for a phase of `nb` blocks: `(2 nb + 16) u` (as the slow
/// path's, `hermite_step`).
fn herm_units(ph: &CompiledPhase) -> f64 {
    let nb = ph.dim / 2;
    (2 * nb + 16) as f64 * f64::EPSILON
}
