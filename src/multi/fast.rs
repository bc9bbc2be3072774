//! The several-contact engine's block path: runs of samples stepped by the
//! one-contact engine's block kernel (`engine/kernel`: mode-major, every
//! contact's event row and both outputs summed per sample in registers),
//! each sample then certified to hold no crossing by the epoch's margins
//! (the same test the step's search starts with); the first sample that
//! fails it, and the run's samples after it, are stepped again by the
//! search (docs/numerics.md section 14, "The block path").
//!
//! The kernel runs on the state's kernel path (this CPU's fastest or the
//! portable one), and a whole sample the search's way is stepped in the
//! kernel's arithmetic on that path (`step_blocks`: the same fused or
//! unfused products), its rows summed by [`rows_as_kernel`] as the kernel
//! sums them: so a run of `k` samples, `k` runs of one and the traced render give
//! the same samples on each path (the portable one the same on every CPU).

use super::*;
use crate::engine::kernel::{
    rows_as_kernel, run_block_with, BlockIo, BlockRows, Extras, ObsIo, Rows,
};
use crate::engine::kernel::{BlockAcc, EPOCH};

/// The samples a run tries after a sample failed its certificate, doubled
/// after each run that passes whole (up to [`EPOCH`]): a run that fails
/// costs its samples past the failure and a re-run of those before it, so
/// near a crossing (a contact's every sample while a law's breakpoint or
/// another contact is close) short runs waste less. Speed only: which
/// samples the block path takes and their sums do not depend on a run's
/// length, so the output is the same bit for bit (the one-contact engine's
/// speculation, `engine/fast_path.rs`).
pub(super) const SPEC_RESTART: usize = 16;

/// The kernel's scratch, one per state (about 30 KB: kept off the state's
/// own size by a box).
#[derive(Debug, Clone)]
pub(super) struct Kern {
    acc: BlockAcc,
    acc_obs: BlockAcc,
    rows: BlockRows,
    obs: BlockRows,
    next: Vec<f64>,
    /// A row of zeros (a contact the scene does not have).
    pub(super) zero: Vec<f64>,
}

impl Kern {
    /// Room for phases of `dim` coordinates.
    pub(super) fn new(dim: usize) -> Self {
        Self {
            acc: [[[0.0; 4]; 3]; EPOCH],
            acc_obs: [[[0.0; 4]; 3]; EPOCH],
            rows: BlockRows::default(),
            obs: BlockRows::default(),
            next: vec![0.0; dim],
            zero: vec![0.0; dim],
        }
    }
}

/// The rows the block path sums: contact 0's event row and the two
/// outputs, then contacts 1 to 3's event rows (`zero` for a contact the
/// scene does not have).
fn kernel_rows_of<'a>(ph: &'a MultiPhase, tb: &'a PhaseTables, zero: &'a [f64]) -> [Rows<'a>; 2] {
    let row = |j: usize| ph.ev.get(j).map_or(zero, |r| &r[..]);
    [
        Rows {
            ev: row(0),
            l: &tb.out[0],
            r: &tb.out[1],
        },
        Rows {
            ev: row(1),
            l: row(2),
            r: row(3),
        },
    ]
}

/// How a run ended.
pub(super) struct Run {
    /// Samples stepped and certified.
    pub(super) done: usize,
    /// A sample failed the certificate (it is the next one).
    pub(super) failed: bool,
}

impl MultiState {
    /// Whether the block path may run: exact switching (the offset rod
    /// decides at every sample instant) and a kernel row for every contact
    /// (the kernel sums up to `EVENT_ROWS` event rows beside the outputs;
    /// an open contact whose open stage below has the same row, a law's
    /// later piece, is read from that stage's row: `MultiPhase::kernel_row`;
    /// otherwise every sample takes the search's way).
    pub(super) fn fast_ready(&self, sc: &CompiledMulti) -> bool {
        self.block_path
            && sc.switching == Switching::Exact
            && !self.rods_on
            && sc.phases[self.slot].kernel_ready
    }

    /// TEST ONLY: turn the block path off (`false`: every sample takes the
    /// search's way, as a check of the block path against it) or on.
    #[doc(hidden)]
    pub fn set_block_path(&mut self, on: bool) {
        self.block_path = on;
    }

    /// TEST ONLY: search and certify every contact (`false`), the stages
    /// in flight behind their open stage below too, as a check that
    /// leaving them out (`MultiPhase::shadow`) changes nothing; or leave
    /// them out (`true`, the default).
    #[doc(hidden)]
    pub fn set_shadows(&mut self, on: bool) {
        self.shadows = on;
    }

    /// TEST ONLY: turn the Hermite certificates off (`false`: every sample
    /// the chord's margin leaves goes to the search, as a check of the
    /// certificates against it) or on.
    #[doc(hidden)]
    pub fn set_hermite(&mut self, on: bool) {
        self.hermite = on;
    }

    /// Run the portable kernels (`true`, the baseline target: the block
    /// kernel, the whole-sample step in its arithmetic, the batched `exp`,
    /// `sin` and `cos` of the search's nodes and partial steps, the
    /// switches' structured products) or this
    /// CPU's fastest (`false`, the default). The two round differently
    /// (fused multiply-adds), each deterministically, as the one-contact
    /// engine's (`EngineState::set_portable_kernels`); on each, the block
    /// path is the per-sample step bit for bit (docs/numerics.md section
    /// 14). \[any-thread\]
    pub fn set_portable_kernels(&mut self, portable: bool) {
        self.simd = if portable {
            SimdPath::Generic
        } else {
            SimdPath::detect()
        };
    }

    /// Up to `left.len()` samples (at most to the end of the clock's
    /// epoch, and [`EPOCH`]) in the block kernel, each certified to hold
    /// no crossing of any contact; the outputs of the certified samples
    /// into `left` and `right`. \[audio-thread\]
    pub(super) fn run_fast(
        &mut self,
        sc: &CompiledMulti,
        left: &mut [f64],
        right: &mut [f64],
    ) -> Run {
        let left_in_epoch = (64 - self.clock % 64) as usize;
        let k = left
            .len()
            .min(right.len())
            .min(EPOCH)
            .min(left_in_epoch)
            .min(self.spec_len);
        self.ensure_margins(sc);
        let start = self.rows_now(sc);
        let m = self.slot;
        let (out0, nc) = (self.tables[m].out0, sc.contacts());
        if !self.may_pass(sc, &start, nc) {
            // the first sample fails whatever its end: no run to throw away
            self.spec_len = SPEC_RESTART;
            return Run {
                done: 0,
                failed: true,
            };
        }
        self.kernel(sc, k, true);
        let mut done = 0;
        while done < k {
            let i = done;
            let end = self.kernel_rows(i);
            let beg = if i == 0 {
                start
            } else {
                self.kernel_rows(i - 1)
            };
            if !self.certified(sc, &beg, &end, nc) {
                break;
            }
            left[i] = beg[4] + out0[0] + self.off_out[0];
            right[i] = beg[5] + out0[1] + self.off_out[1];
            self.fly(sc, self.step_h);
            self.clock += 1;
            done += 1;
        }
        if done < k {
            self.spec_len = SPEC_RESTART;
        } else {
            self.spec_len = (2 * self.spec_len).min(EPOCH);
        }
        if done < k && done > 0 {
            // the run went past a sample that failed: step again to it
            self.stats.kernel_discarded += (k - done) as u64;
            self.kernel(sc, done, false);
        }
        if done > 0 {
            let dim = self.s.len();
            self.s.copy_from_slice(&self.kern.next[..dim]);
            self.stats.kernel_samples += done as u64;
        }
        Run {
            done,
            failed: done < k,
        }
    }

    /// Step `k` samples from `s` into the scratch's `next`, with every
    /// contact's event row (`all`) or only the outputs.
    fn kernel(&mut self, sc: &CompiledMulti, k: usize, all: bool) {
        let m = self.slot;
        let ph = &sc.phases[m];
        let tb = &self.tables[m];
        let dim = ph.dim;
        let kern = &mut *self.kern;
        let [rows, obs_rows] = kernel_rows_of(ph, tb, &kern.zero[..dim]);
        let obs = (all && ph.kernel_obs > 0).then_some(ObsIo {
            rows: obs_rows,
            all: ph.kernel_obs > 1,
            acc: &mut kern.acc_obs,
            out: &mut kern.obs,
        });
        let io = BlockIo {
            p: &tb.soa,
            s: &self.s,
            next: &mut kern.next[..dim],
            rows,
            acc: &mut kern.acc,
            out: &mut kern.rows,
        };
        let extras = Extras {
            obs,
            ..Extras::default()
        };
        run_block_with(self.simd, io, extras, k);
    }

    /// The rows of the state after the run's step `i`: the kernel's event
    /// rows (without their constants; the observation rows the phase's
    /// `kernel_obs` leaves out hold stale numbers that no contact reads),
    /// then the two outputs.
    fn kernel_rows(&self, i: usize) -> [f64; 6] {
        let (r, o) = (&self.kern.rows, &self.kern.obs);
        [r.ev[i], o.ev[i], o.l[i], o.r[i], r.l[i], r.r[i]]
    }

    /// The same rows of the current state ([`rows_as_kernel`]: the
    /// kernel's sums on this path).
    fn rows_now(&self, sc: &CompiledMulti) -> [f64; 6] {
        let m = self.slot;
        let ph = &sc.phases[m];
        let tb = &self.tables[m];
        let [rows, obs_rows] = kernel_rows_of(ph, tb, &self.kern.zero[..ph.dim]);
        let [e0, l, r] = rows_as_kernel(self.simd, &self.s, &rows);
        let [e1, e2, e3] = if ph.kernel_obs > 0 {
            rows_as_kernel(self.simd, &self.s, &obs_rows)
        } else {
            [0.0; 3]
        };
        [e0, e1, e2, e3, l, r]
    }

    /// Whether the sample from rows `beg` may pass
    /// [`certified`](Self::certified): every contact's `psi` at its start
    /// clears its epoch's margin (the test's half that needs no run).
    fn may_pass(&self, sc: &CompiledMulti, beg: &[f64; 6], nc: usize) -> bool {
        let ph = &sc.phases[self.slot];
        (0..nc).all(|j| {
            if self.implied(j) {
                return true;
            }
            let f = self.event_fn(sc, j);
            let q = ph.kernel_row[j].map_or(f64::NAN, |r| beg[r]);
            f.psi(q + ph.ev0[j], 0.0) > self.cached[j].1
        })
    }

    /// Whether no contact crosses in the sample from rows `beg` to rows
    /// `end`: each contact's `psi` at both ends clears its epoch's margin
    /// (the test [`first_crossing`](Self::first_crossing) starts with).
    fn certified(&self, sc: &CompiledMulti, beg: &[f64; 6], end: &[f64; 6], nc: usize) -> bool {
        let ph = &sc.phases[self.slot];
        (0..nc).all(|j| {
            if self.implied(j) {
                return true;
            }
            let f = self.event_fn(sc, j);
            // no row: NaN, which no certificate passes
            let r = ph.kernel_row[j];
            let (q0, q1) = (
                r.map_or(f64::NAN, |r| beg[r]) + ph.ev0[j],
                r.map_or(f64::NAN, |r| end[r]) + ph.ev0[j],
            );
            let margin = self.cached[j].1;
            f.psi(q0, 0.0).min(f.psi(q1, self.step_h)) > margin
        })
    }

    /// Whether contact `j`'s certificate follows from its shadowing
    /// stage's ([`MultiPhase::shadow`]), which the same test checks: its
    /// `psi` is the stage's plus `d` (up to rounding far below `d`), so it
    /// clears its own margin wherever the stage clears the stage's and
    /// its margin is within `d / 2` of the stage's. Then the test's
    /// outcome is the same with or without it. Taken once per run, with
    /// the margins (`ensure_margins`: a run stays in its phase and epoch).
    fn implied(&self, j: usize) -> bool {
        self.implied & (1 << j) != 0
    }

    /// Every contact's margin for the clock's epoch, taken now where it
    /// is not yet ([`first_crossing`](Self::first_crossing) takes it the
    /// same way).
    /// Then the contacts whose certificate follows from their shadowing
    /// stage's at these margins ([`implied`](Self::implied)), once per run.
    fn ensure_margins(&mut self, sc: &CompiledMulti) {
        let epoch = self.clock / 64;
        for j in 0..sc.contacts() {
            if self.cached[j].0 != epoch {
                self.cache_margin(sc, j, epoch);
            }
        }
        let ph = &sc.phases[self.slot];
        self.implied = 0;
        if self.shadows {
            for (j, sh) in ph.shadow.iter().enumerate() {
                if sh.is_some_and(|(i, d)| self.cached[j].1 <= self.cached[i].1 + 0.5 * d) {
                    self.implied |= 1 << j;
                }
            }
        }
    }
}
