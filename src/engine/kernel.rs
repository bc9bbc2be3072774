//! The per-sample kernels, laid out for the machine.
//!
//! Block propagators and state are stored as structure of arrays (block `k`
//! is `(s[k], s[nb + k])`). The hot kernel, [`run_block_with`], advances a phase
//! by up to [`EPOCH`] samples in one call, **mode-major**: a group of
//! [`GROUP`] blocks is loaded into registers (state, 2x2 propagators and the
//! three rows), stepped through all the samples, and adds its share of every
//! sample's event row and outputs into small per-sample accumulators; then
//! the next group. So per sample and mode the work is one 2x2 multiply and
//! three 2-term dot products with everything in registers or L1, instead of
//! streaming the whole state, propagators and rows through the cache once
//! per sample.
//!
//! Determinism: each sample's sums are accumulated in a fixed order (group
//! by group, four lanes, then a fixed tree), whatever the number of samples
//! per call, so running `k` samples in one call gives bit-identical results
//! to `k` calls of one sample. The engine relies on that: its output does
//! not depend on how a host splits its blocks.
//!
//! A plugin binary must run on any x86-64, so AVX2+FMA is chosen at run time
//! (`is_x86_feature_detected!`), never assumed at compile time: the same body
//! is compiled twice, once inside a `#[target_feature(enable = "avx2,fma")]`
//! function (with fused multiply-adds) and once for the baseline target. The
//! two paths round differently (FMA), each deterministically.
//!
//! The kernels' files: `block` (the block kernel, [`run_block_with`]),
//! `sums` (single-pass sums over a block state: its rows, the fast path's
//! margins, the Hermite certificates' sums, the event rows of a partial
//! step, and a plain step) and `matvec` (the change of basis at a switch,
//! dense or hierarchical).

mod block;
mod matvec;
mod sums;

pub(crate) use block::{run_block_with, BlockIo, Extras, ObsIo, QuadAcc, QuadIo, SlopeIo};
pub(crate) use matvec::{change_of_basis_add, hodlr_mat_vec_add};
pub(crate) use sums::{
    event_rows, hermite_step_sums, hermite_sums, margin_sums, rows_as_kernel, rows_of, step_blocks,
    HermiteRows,
};

use super::vmath::SimdPath;

/// Most samples one [`run_block_with`] call advances (the engine's epoch: the
/// curvature bound of exact switching is refreshed at least this often).
pub(crate) const EPOCH: usize = 64;
/// Event rows one [`run_block_with`] call can sum per sample: the row in
/// [`Rows::ev`] beside the outputs and up to three observation rows
/// ([`ObsIo`]).
pub(crate) const EVENT_ROWS: usize = 4;
/// Blocks (modes) processed together in registers: two 4-lane vectors.
pub(crate) const GROUP: usize = 8;
const LANES: usize = 4;

/// Clear the upper halves of the vector registers (`vzeroupper`) on the
/// AVX2 path. Code elsewhere in the process (e.g. a linear-algebra library
/// run by the compile worker, or the host) may leave them dirty, which makes
/// every non-VEX SSE instruction that follows pay a merge penalty on some
/// CPUs; the engine calls this once per block. \[audio-thread\]
#[inline]
pub(crate) fn clean_upper_state(path: SimdPath) {
    #[cfg(target_arch = "x86_64")]
    if matches!(path, SimdPath::Avx2Fma(_)) {
        // SAFETY: `Avx2Fma` is only produced by `detect()` after checking AVX2.
        unsafe { zeroupper() }
    }
    let _ = path;
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn zeroupper() {
    std::arch::x86_64::_mm256_zeroupper();
}

/// Block propagators of one phase for one time step, structure of arrays.
#[derive(Debug, Clone, Default)]
pub(crate) struct BlockProps {
    /// `P[0][0]` of each block.
    pub p00: Vec<f64>,
    /// `P[0][1]`.
    pub p01: Vec<f64>,
    /// `P[1][0]`.
    pub p10: Vec<f64>,
    /// `P[1][1]`.
    pub p11: Vec<f64>,
}

impl BlockProps {
    /// Zeroed storage for `nb` blocks.
    pub(crate) fn new(nb: usize) -> Self {
        Self {
            p00: vec![0.0; nb],
            p01: vec![0.0; nb],
            p10: vec![0.0; nb],
            p11: vec![0.0; nb],
        }
    }
    /// Number of blocks.
    pub(crate) fn len(&self) -> usize {
        self.p00.len()
    }
    /// Blocks `0..src.len()` from `src` (the rest, if any, as they are).
    /// Panics if `src` has more blocks; callers check the counts.
    /// \[audio-thread\]
    pub(crate) fn copy_from(&mut self, src: &BlockProps) {
        let n = src.len();
        self.p00[..n].copy_from_slice(&src.p00);
        self.p01[..n].copy_from_slice(&src.p01);
        self.p10[..n].copy_from_slice(&src.p10);
        self.p11[..n].copy_from_slice(&src.p11);
    }
    /// Store block `k`.
    #[inline]
    pub(crate) fn set(&mut self, k: usize, p: &[f64; 4]) {
        self.p00[k] = p[0];
        self.p01[k] = p[1];
        self.p10[k] = p[2];
        self.p11[k] = p[3];
    }
    /// Block `k` (the engine steps whole arrays with [`step_blocks`]).
    #[inline]
    pub(crate) fn get(&self, k: usize) -> [f64; 4] {
        [self.p00[k], self.p01[k], self.p10[k], self.p11[k]]
    }
}

/// Rows evaluated on the stepped state: the event row and the two outputs.
pub(crate) struct Rows<'a> {
    /// Event row (penetration-like).
    pub ev: &'a [f64],
    /// Left output row.
    pub l: &'a [f64],
    /// Right output row.
    pub r: &'a [f64],
}

/// Per-sample lane accumulators of [`run_block_with`] (`[sample][row][lane]`):
/// 6 KiB of scratch kept by the caller so a call neither allocates nor
/// zeroes it (the first group of blocks writes each sample's sums).
pub(crate) type BlockAcc = [[[f64; LANES]; 3]; EPOCH];

/// What [`run_block_with`] returns per sample `j`: the rows of the state after
/// step `j` (the state at the start of sample `j + 1`).
#[derive(Debug, Clone)]
pub(crate) struct BlockRows {
    /// Event row.
    pub ev: [f64; EPOCH],
    /// Left output row.
    pub l: [f64; EPOCH],
    /// Right output row.
    pub r: [f64; EPOCH],
}

impl Default for BlockRows {
    fn default() -> Self {
        Self {
            ev: [0.0; EPOCH],
            l: [0.0; EPOCH],
            r: [0.0; EPOCH],
        }
    }
}

/// Block `k`'s share of the Hermite remainder per unit of `|s_k|`: the
/// smaller of `c4_k dt^4 / 384` (`dt4`) and `2 e_k + 8/27 dt c1_k`
/// (`tail = 8/27 dt`). `EngineState::hermite_clear`.
#[inline(always)]
pub(super) fn hermite_block(c1: f64, c4: f64, e: f64, dt4: f64, tail: f64) -> f64 {
    (c4 * dt4).min(2.0 * e + tail * c1)
}

/// The fixed reduction of four lanes (the same everywhere, for determinism).
#[inline(always)]
fn lane_sum(v: [f64; LANES]) -> f64 {
    (v[0] + v[1]) + (v[2] + v[3])
}

#[cfg(test)]
pub(crate) use sums::block_measures;

#[cfg(test)]
mod tests;
