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

use super::vmath::{madd, SimdPath};
use crate::compile::EnergyQuad;
use crate::physics::hodlr::Hodlr;

/// Most samples one [`run_block_with`] call advances (the engine's epoch: the
/// curvature bound of exact switching is refreshed at least this often).
pub const EPOCH: usize = 64;
/// Blocks (modes) processed together in registers: two 4-lane vectors.
pub const GROUP: usize = 8;
const LANES: usize = 4;

/// Clear the upper halves of the vector registers (`vzeroupper`) on the
/// AVX2 path. Code elsewhere in the process (e.g. a linear-algebra library
/// run by the compile worker, or the host) may leave them dirty, which makes
/// every non-VEX SSE instruction that follows pay a merge penalty on some
/// CPUs; the engine calls this once per block. \[audio-thread\]
#[inline]
pub fn clean_upper_state(path: SimdPath) {
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
pub struct BlockProps {
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
    pub fn new(nb: usize) -> Self {
        Self {
            p00: vec![0.0; nb],
            p01: vec![0.0; nb],
            p10: vec![0.0; nb],
            p11: vec![0.0; nb],
        }
    }
    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.p00.len()
    }
    /// Blocks `0..src.len()` from `src` (the rest, if any, as they are).
    /// Panics if `src` has more blocks; callers check the counts.
    /// \[audio-thread\]
    pub fn copy_from(&mut self, src: &BlockProps) {
        let n = src.len();
        self.p00[..n].copy_from_slice(&src.p00);
        self.p01[..n].copy_from_slice(&src.p01);
        self.p10[..n].copy_from_slice(&src.p10);
        self.p11[..n].copy_from_slice(&src.p11);
    }
    /// Store block `k`.
    #[inline]
    pub fn set(&mut self, k: usize, p: &[f64; 4]) {
        self.p00[k] = p[0];
        self.p01[k] = p[1];
        self.p10[k] = p[2];
        self.p11[k] = p[3];
    }
    /// Block `k` (the engine steps whole arrays with [`step_blocks`]).
    #[inline]
    pub fn get(&self, k: usize) -> [f64; 4] {
        [self.p00[k], self.p01[k], self.p10[k], self.p11[k]]
    }
}

/// Rows evaluated on the stepped state: the event row and the two outputs.
pub struct Rows<'a> {
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
pub type BlockAcc = [[[f64; LANES]; 3]; EPOCH];

/// What [`run_block_with`] returns per sample `j`: the rows of the state after
/// step `j` (the state at the start of sample `j + 1`).
#[derive(Debug, Clone)]
pub struct BlockRows {
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

/// One group of [`GROUP`] blocks held in registers: state, propagators and
/// rows. Lanes past the end of the phase are zero (they add exactly 0).
struct Group {
    a: [f64; GROUP],
    b: [f64; GROUP],
    p: [[f64; GROUP]; 4],
    row: [[f64; GROUP]; 6],
    /// Quadratic-form weights `aa, ab, bb` (only read by the `Q` kernels).
    q: [[f64; GROUP]; 3],
    /// The slope row's two halves (only read by the `D` kernels).
    d: [[f64; GROUP]; 2],
    /// The observation's three rows, halves as `row` (only read by the `O`
    /// kernels).
    o: [[f64; GROUP]; 6],
}

/// `lanes[..width] = v[at..at + width]`: a constant-size copy (vector moves)
/// for a full group.
#[inline(always)]
fn put(lanes: &mut [f64; GROUP], v: &[f64], at: usize, width: usize) {
    if width == GROUP {
        lanes.copy_from_slice(&v[at..at + GROUP]);
    } else {
        lanes[..width].copy_from_slice(&v[at..at + width]);
    }
}

impl Group {
    /// A group with every lane zero, made once per kernel run and reloaded
    /// for each group (zeroing ~1.5 KB per group of eight blocks cost more
    /// than a one-sample run's arithmetic).
    #[inline(always)]
    fn zeroed() -> Self {
        Group {
            a: [0.0; GROUP],
            b: [0.0; GROUP],
            p: [[0.0; GROUP]; 4],
            row: [[0.0; GROUP]; 6],
            q: [[0.0; GROUP]; 3],
            d: [[0.0; GROUP]; 2],
            o: [[0.0; GROUP]; 6],
        }
    }

    /// Load the group's state, propagators and rows. A group narrower than
    /// [`GROUP`] (the last one) also zeroes its lanes past the end, in
    /// every field (earlier groups of the run filled them).
    #[inline(always)]
    fn load(
        &mut self,
        p: &BlockProps,
        s: &[f64],
        rows: &Rows,
        nb: usize,
        base: usize,
        width: usize,
    ) {
        let g = self;
        if width < GROUP {
            for lanes in [&mut g.a, &mut g.b]
                .into_iter()
                .chain(g.p.iter_mut())
                .chain(g.row.iter_mut())
                .chain(g.q.iter_mut())
                .chain(g.d.iter_mut())
                .chain(g.o.iter_mut())
            {
                lanes[width..].fill(0.0);
            }
        }
        let srcs: [&[f64]; 4] = [&p.p00, &p.p01, &p.p10, &p.p11];
        let rsrc: [&[f64]; 3] = [rows.ev, rows.l, rows.r];
        put(&mut g.a, s, base, width);
        put(&mut g.b, s, nb + base, width);
        for (q, src) in srcs.iter().enumerate() {
            put(&mut g.p[q], src, base, width);
        }
        for (q, src) in rsrc.iter().enumerate() {
            put(&mut g.row[2 * q], src, base, width);
            put(&mut g.row[2 * q + 1], src, nb + base, width);
        }
    }

    /// Load the quadratic-form weights of the group's blocks.
    #[inline(always)]
    fn load_quad(&mut self, quad: &EnergyQuad, base: usize, width: usize) {
        put(&mut self.q[0], &quad.aa, base, width);
        put(&mut self.q[1], &quad.ab, base, width);
        put(&mut self.q[2], &quad.bb, base, width);
    }

    /// Load the observation's first `n` rows of the group's blocks.
    #[inline(always)]
    fn load_obs(&mut self, rows: &Rows, n: usize, nb: usize, base: usize, width: usize) {
        let rsrc: [&[f64]; 3] = [rows.ev, rows.l, rows.r];
        for (q, src) in rsrc.iter().enumerate().take(n) {
            put(&mut self.o[2 * q], src, base, width);
            put(&mut self.o[2 * q + 1], src, nb + base, width);
        }
    }

    /// Load the slope row of the group's blocks.
    #[inline(always)]
    fn load_slope(&mut self, row: &[f64], nb: usize, base: usize, width: usize) {
        put(&mut self.d[0], row, base, width);
        put(&mut self.d[1], row, nb + base, width);
    }

    /// Step the group `k` samples, adding its share of each sample's rows
    /// into `acc[j]`, in the `Q` copy of each sample's quadratic form into
    /// `qacc[j]`, in the `D` copy of each sample's slope row into `dacc[j]`
    /// and in the `O` copy of each sample's observation rows into
    /// `oacc[j]` (each sum in the same order as `acc`'s). The `first`
    /// group starts every sum at 0 instead of reading the accumulators
    /// (the same values: the callers' sums need no zeroed scratch).
    #[inline(always)]
    fn run<const FMA: bool, const Q: bool, const D: bool, const O: usize>(
        &mut self,
        first: bool,
        k: usize,
        acc: &mut [[[f64; LANES]; 3]],
        qacc: &mut [[f64; LANES]],
        dacc: &mut [[f64; LANES]],
        oacc: &mut [[[f64; LANES]; 3]],
    ) {
        let (mut a, mut b) = (self.a, self.b);
        let [p00, p01, p10, p11] = self.p;
        let row = self.row;
        let orow = self.o;
        let [qaa, qab, qbb] = self.q;
        let [da, db] = self.d;
        for (j_s, acc_j) in acc[..k].iter_mut().enumerate() {
            let mut x0 = [0.0; GROUP];
            let mut x1 = [0.0; GROUP];
            for j in 0..GROUP {
                x0[j] = madd::<FMA>(p00[j], a[j], p01[j] * b[j]);
                x1[j] = madd::<FMA>(p10[j], a[j], p11[j] * b[j]);
            }
            rows_into::<FMA, 3>(first, acc_j, &row, &x0, &x1);
            if O > 0 {
                rows_into::<FMA, O>(first, &mut oacc[j_s], &orow, &x0, &x1);
            }
            if Q {
                let qa = &mut qacc[j_s];
                let start = if first { [0.0; LANES] } else { *qa };
                for j in 0..LANES {
                    let h = j + LANES;
                    let mut v = start[j];
                    v = madd::<FMA>(qaa[j] * x0[j], x0[j], v);
                    v = madd::<FMA>(qab[j] * x0[j], x1[j], v);
                    v = madd::<FMA>(qbb[j] * x1[j], x1[j], v);
                    v = madd::<FMA>(qaa[h] * x0[h], x0[h], v);
                    v = madd::<FMA>(qab[h] * x0[h], x1[h], v);
                    v = madd::<FMA>(qbb[h] * x1[h], x1[h], v);
                    qa[j] = v;
                }
            }
            if D {
                let d = &mut dacc[j_s];
                let start = if first { [0.0; LANES] } else { *d };
                for j in 0..LANES {
                    let h = j + LANES;
                    let mut v = start[j];
                    v = madd::<FMA>(da[j], x0[j], v);
                    v = madd::<FMA>(db[j], x1[j], v);
                    v = madd::<FMA>(da[h], x0[h], v);
                    v = madd::<FMA>(db[h], x1[h], v);
                    d[j] = v;
                }
            }
            a = x0;
            b = x1;
        }
        self.a = a;
        self.b = b;
    }
}

/// Add the first `N` rows' share of one stepped group (`x0`, `x1`) into
/// the lane accumulators `acc` (the one order every row is summed in), or
/// into 0 for the `first` group.
#[inline(always)]
fn rows_into<const FMA: bool, const N: usize>(
    first: bool,
    acc: &mut [[f64; LANES]; 3],
    row: &[[f64; GROUP]; 6],
    x0: &[f64; GROUP],
    x1: &[f64; GROUP],
) {
    for (q, acc_q) in acc.iter_mut().enumerate().take(N) {
        let (ra, rb) = (&row[2 * q], &row[2 * q + 1]);
        let start = if first { [0.0; LANES] } else { *acc_q };
        for j in 0..LANES {
            let h = j + LANES;
            let mut v = start[j];
            v = madd::<FMA>(ra[j], x0[j], v);
            v = madd::<FMA>(rb[j], x1[j], v);
            v = madd::<FMA>(ra[h], x0[h], v);
            v = madd::<FMA>(rb[h], x1[h], v);
            acc_q[j] = v;
        }
    }
}

/// The operands of one [`run_block_with`] call.
pub struct BlockIo<'a> {
    /// Block propagators of the phase.
    pub p: &'a BlockProps,
    /// State at the start (read only).
    pub s: &'a [f64],
    /// State after the last sample (written).
    pub next: &'a mut [f64],
    /// Event and output rows.
    pub rows: Rows<'a>,
    /// Scratch for the per-sample lane sums.
    pub acc: &'a mut BlockAcc,
    /// Rows of every stepped state (written).
    pub out: &'a mut BlockRows,
}

/// The quadratic form of [`run_block_with`]: its weights, the caller's lane
/// scratch and the per-sample values it writes.
pub struct QuadIo<'a> {
    /// The weights.
    pub quad: &'a EnergyQuad,
    /// Scratch for the per-sample lane sums.
    pub acc: &'a mut [[f64; LANES]; EPOCH],
    /// The form of every stepped state (written).
    pub out: &'a mut [f64; EPOCH],
}

/// Lane scratch of a [`QuadIo`].
pub type QuadAcc = [[f64; LANES]; EPOCH];

/// The slope row of [`run_block_with`]: the row, the caller's lane
/// scratch and the per-sample values it writes.
pub struct SlopeIo<'a> {
    /// The row (`ev G`, over the phase's block coordinates).
    pub row: &'a [f64],
    /// Scratch for the per-sample lane sums.
    pub acc: &'a mut QuadAcc,
    /// The row on every stepped state (written).
    pub out: &'a mut [f64; EPOCH],
}

/// The observation rows of [`run_block_with`]: the rows (`x_c, v_c, eta`
/// in the fields `ev, l, r`; only `ev` unless `all`), the caller's lane
/// scratch and the per-sample values it writes.
pub struct ObsIo<'a> {
    /// The rows.
    pub rows: Rows<'a>,
    /// All three rows, or only `rows.ev` (`out.l`, `out.r` not written).
    pub all: bool,
    /// Scratch for the per-sample lane sums.
    pub acc: &'a mut BlockAcc,
    /// The rows on every stepped state (written).
    pub out: &'a mut BlockRows,
}

/// What a kernel run sums beside the state's rows: each `None` costs
/// nothing.
#[derive(Default)]
pub struct Extras<'a> {
    /// A block-diagonal quadratic form (the trace's energy).
    pub quad: Option<QuadIo<'a>>,
    /// The slope row (the Hermite certificate).
    pub slope: Option<SlopeIo<'a>>,
    /// One or three more rows (the trace's motion).
    pub obs: Option<ObsIo<'a>>,
}

#[inline(always)]
fn block_body<const FMA: bool, const Q: bool, const D: bool, const O: usize>(
    io: BlockIo,
    extras: Extras,
    k: usize,
) {
    let Extras { quad, slope, obs } = extras;
    let BlockIo {
        p,
        s,
        next,
        rows,
        acc,
        out,
    } = io;
    let nb = p.len();
    let k = k.min(EPOCH);
    let mut no_qacc = [[0.0; LANES]; 0];
    let (qw, qacc, qout) = match quad {
        Some(QuadIo { quad, acc, out }) if Q => (Some(quad), &mut acc[..], Some(out)),
        _ => (None, &mut no_qacc[..], None),
    };
    let mut no_dacc = [[0.0; LANES]; 0];
    let (drow, dacc, dout) = match slope {
        Some(SlopeIo { row, acc, out }) if D => (Some(row), &mut acc[..], Some(out)),
        _ => (None, &mut no_dacc[..], None),
    };
    let mut no_oacc = [[[0.0; LANES]; 3]; 0];
    let (orows, oacc, oout) = match obs {
        Some(ObsIo { rows, acc, out, .. }) if O > 0 => (Some(rows), &mut acc[..], Some(out)),
        _ => (None, &mut no_oacc[..], None),
    };
    if nb == 0 {
        // no group runs (the first one starts every sum at 0 itself)
        acc[..k].fill([[0.0; LANES]; 3]);
        qacc.iter_mut().take(k).for_each(|a| *a = [0.0; LANES]);
        dacc.iter_mut().take(k).for_each(|a| *a = [0.0; LANES]);
        oacc.iter_mut().take(k).for_each(|a| *a = [[0.0; LANES]; 3]);
    }
    let mut base = 0;
    let mut g = Group::zeroed();
    while base < nb {
        let width = GROUP.min(nb - base);
        g.load(p, s, &rows, nb, base, width);
        if let Some(qw) = qw {
            g.load_quad(qw, base, width);
        }
        if let Some(drow) = drow {
            g.load_slope(drow, nb, base, width);
        }
        if let Some(orows) = &orows {
            g.load_obs(orows, O, nb, base, width);
        }
        g.run::<FMA, Q, D, O>(base == 0, k, &mut acc[..k], qacc, dacc, oacc);
        next[base..base + width].copy_from_slice(&g.a[..width]);
        next[nb + base..nb + base + width].copy_from_slice(&g.b[..width]);
        base += width;
    }
    for j in 0..k {
        out.ev[j] = lane_sum(acc[j][0]);
        out.l[j] = lane_sum(acc[j][1]);
        out.r[j] = lane_sum(acc[j][2]);
    }
    if let Some(qout) = qout {
        for j in 0..k {
            qout[j] = lane_sum(qacc[j]);
        }
    }
    if let Some(dout) = dout {
        for j in 0..k {
            dout[j] = lane_sum(dacc[j]);
        }
    }
    if let Some(oout) = oout {
        for j in 0..k {
            oout.ev[j] = lane_sum(oacc[j][0]);
            if O == 3 {
                oout.l[j] = lane_sum(oacc[j][1]);
                oout.r[j] = lane_sum(oacc[j][2]);
            }
        }
    }
}

/// The kernel for each choice of extras, in an AVX2+FMA copy and a
/// baseline copy: `block_avx2_QDO` and `block_generic_QDO` (`Q`, `D`: `1`
/// where the extra is summed; `O`: the number of observation rows).
macro_rules! kernels {
    ($(($avx:ident, $gen:ident, $q:literal, $d:literal, $o:literal)),* $(,)?) => {
        $(
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            fn $avx(io: BlockIo, extras: Extras, k: usize) {
                block_body::<true, $q, $d, $o>(io, extras, k)
            }
            fn $gen(io: BlockIo, extras: Extras, k: usize) {
                block_body::<false, $q, $d, $o>(io, extras, k)
            }
        )*
    };
}

kernels!(
    (block_avx2_000, block_generic_000, false, false, 0),
    (block_avx2_100, block_generic_100, true, false, 0),
    (block_avx2_010, block_generic_010, false, true, 0),
    (block_avx2_110, block_generic_110, true, true, 0),
    (block_avx2_001, block_generic_001, false, false, 1),
    (block_avx2_101, block_generic_101, true, false, 1),
    (block_avx2_011, block_generic_011, false, true, 1),
    (block_avx2_111, block_generic_111, true, true, 1),
    (block_avx2_003, block_generic_003, false, false, 3),
    (block_avx2_103, block_generic_103, true, false, 3),
    (block_avx2_013, block_generic_013, false, true, 3),
    (block_avx2_113, block_generic_113, true, true, 3),
);

fn check_io(io: &BlockIo) {
    let n = 2 * io.p.len();
    assert!(
        io.s.len() == n
            && io.next.len() == n
            && io.rows.ev.len() == n
            && io.rows.l.len() == n
            && io.rows.r.len() == n,
        "run_block: mismatched lengths"
    );
}

/// Advance the blocks `k <= EPOCH` samples from `io.s` into `io.next`
/// (`s` is left untouched, so a caller can re-run fewer samples), write
/// the rows of every stepped state into `io.out`, and sum the `extras` on
/// every stepped state: the block-diagonal quadratic form `quad` (the
/// trace's energy, O(N) per sample), the slope row (the Hermite
/// certificate of the fast path), one or three more rows `obs` (the trace's
/// motion). The state and rows are bit-identical whatever the extras, and
/// each extra row is summed in the same order as the rows. O(N k),
/// allocation-free. \[audio-thread\]
pub fn run_block_with(path: SimdPath, io: BlockIo, extras: Extras, k: usize) {
    check_io(&io);
    let n = io.s.len();
    if let Some(q) = &extras.quad {
        let nb = io.p.len();
        assert!(
            q.quad.aa.len() == nb && q.quad.ab.len() == nb && q.quad.bb.len() == nb,
            "run_block_with: mismatched quadratic form"
        );
    }
    if let Some(d) = &extras.slope {
        assert!(d.row.len() == n, "run_block_with: mismatched slope row");
    }
    if let Some(o) = &extras.obs {
        assert!(
            o.rows.ev.len() == n && (!o.all || o.rows.l.len() == n && o.rows.r.len() == n),
            "run_block_with: mismatched observation rows"
        );
    }
    let which = (
        extras.quad.is_some(),
        extras.slope.is_some(),
        extras.obs.as_ref().map_or(0, |o| if o.all { 3 } else { 1 }),
    );
    macro_rules! dispatch {
        ($(($q:literal, $d:literal, $o:literal, $avx:ident, $gen:ident)),* $(,)?) => {
            match which {
                $(
                    ($q, $d, $o) => match path {
                        #[cfg(target_arch = "x86_64")]
                        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only
                        // `detect()` makes, after `is_x86_feature_detected!` confirmed AVX2 and
                        // FMA on this CPU.
                        SimdPath::Avx2Fma(_) => unsafe { $avx(io, extras, k) },
                        _ => $gen(io, extras, k),
                    },
                )*
                _ => unreachable!("0, 1 or 3 observation rows"),
            }
        };
    }
    dispatch!(
        (false, false, 0, block_avx2_000, block_generic_000),
        (true, false, 0, block_avx2_100, block_generic_100),
        (false, true, 0, block_avx2_010, block_generic_010),
        (true, true, 0, block_avx2_110, block_generic_110),
        (false, false, 1, block_avx2_001, block_generic_001),
        (true, false, 1, block_avx2_101, block_generic_101),
        (false, true, 1, block_avx2_011, block_generic_011),
        (true, true, 1, block_avx2_111, block_generic_111),
        (false, false, 3, block_avx2_003, block_generic_003),
        (true, false, 3, block_avx2_103, block_generic_103),
        (false, true, 3, block_avx2_013, block_generic_013),
        (true, true, 3, block_avx2_113, block_generic_113),
    );
}

/// [`run_block_with`] without extras: the engine's hot kernel.
/// \[audio-thread\]
#[cfg(test)]
#[inline]
pub fn run_block(path: SimdPath, io: BlockIo, k: usize) {
    run_block_with(path, io, Extras::default(), k);
}

/// `[ev . s, l . s, r . s]` (no step), summed in the same order as
/// [`run_block_with`]'s generic path (bit-identical to it, on either
/// `path`: the AVX2 copy vectorises the same lane sums, without fused
/// multiply-adds). O(N). \[audio-thread\]
#[inline]
pub fn rows_of(path: SimdPath, s: &[f64], rows: &Rows) -> [f64; 3] {
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { rows_of_avx2(s, rows) },
        _ => rows_of_body(s, rows),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rows_of_avx2(s: &[f64], rows: &Rows) -> [f64; 3] {
    rows_of_body(s, rows)
}

/// Block `k` adds into lane `k % LANES`, `LANES` blocks at a time.
#[inline(always)]
fn rows_of_body(s: &[f64], rows: &Rows) -> [f64; 3] {
    let nb = s.len() / 2;
    let (sa, sb) = s.split_at(nb);
    let sb = &sb[..nb];
    let r = [rows.ev, rows.l, rows.r].map(|r| {
        let (a, b) = r.split_at(nb);
        (&a[..nb], &b[..nb])
    });
    let mut acc = [[0.0f64; LANES]; 3];
    let full = nb - nb % LANES;
    let mut k = 0;
    while k < full {
        let (a, b) = (lanes(sa, k), lanes(sb, k));
        for q in 0..3 {
            let (ra, rb) = (lanes(r[q].0, k), lanes(r[q].1, k));
            for l in 0..LANES {
                acc[q][l] += ra[l] * a[l];
                acc[q][l] += rb[l] * b[l];
            }
        }
        k += LANES;
    }
    for k in full..nb {
        for q in 0..3 {
            acc[q][k - full] += r[q].0[k] * sa[k];
            acc[q][k - full] += r[q].1[k] * sb[k];
        }
    }
    [lane_sum(acc[0]), lane_sum(acc[1]), lane_sum(acc[2])]
}

/// `LANES` consecutive values from `k`.
#[inline(always)]
fn lanes(v: &[f64], k: usize) -> [f64; LANES] {
    v[k..k + LANES].try_into().expect("LANES values")
}

/// The two energy measures of a block state that bound the event function's
/// curvature: `(sum_k |s_k|^2, sum_k c_k |s_k|^2)` with `s_k` the 2-vector of
/// block `k` and `c` per-block weights. O(N). The fast path takes them from
/// [`margin_sums`] (the same sums); this scalar loop is the tests'
/// reference.
#[cfg(test)]
pub fn block_measures(s: &[f64], c: &[f64]) -> (f64, f64) {
    let nb = c.len();
    let (sa, sb) = s.split_at(nb);
    let sb = &sb[..nb];
    let mut e = [0.0f64; LANES];
    let mut w = [0.0f64; LANES];
    for k in 0..nb {
        let ek = sa[k] * sa[k] + sb[k] * sb[k];
        e[k % LANES] += ek;
        w[k % LANES] += c[k] * ek;
    }
    (lane_sum(e), lane_sum(w))
}

/// The fast path's interpolation margin of a block state:
/// `sum_k min(c_k h, 2 e_k) |s_k|` with `s_k` the 2-vector of block `k`
/// (`c`: curvature weights, `e`: the event row's block norms, `h = dt^2 / 8`).
/// O(N). The fast path takes it from [`margin_sums`] (the same sum); this
/// scalar loop is the tests' reference.
#[cfg(test)]
pub fn block_margin(s: &[f64], c: &[f64], e: &[f64], h: f64) -> f64 {
    let nb = c.len();
    let (sa, sb) = s.split_at(nb);
    let (sb, e) = (&sb[..nb], &e[..nb]);
    let mut m = [0.0f64; LANES];
    for k in 0..nb {
        let norm = (sa[k] * sa[k] + sb[k] * sb[k]).sqrt();
        m[k % LANES] += (c[k] * h).min(2.0 * e[k]) * norm;
    }
    lane_sum(m)
}

/// `block_measures` and `block_margin` (the tests' scalar references) in
/// one pass over the state, bit for bit the same three sums on either
/// `path` (the same lanes, no fused multiply-adds): `(e, w, margin)`. O(N),
/// about a third of the two scalar passes' time at 1000 modes (1.7 against
/// 5.0 us). \[audio-thread\]
#[inline]
pub fn margin_sums(path: SimdPath, s: &[f64], c: &[f64], e: &[f64], h: f64) -> (f64, f64, f64) {
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { margin_sums_avx2(s, c, e, h) },
        _ => margin_sums_body(s, c, e, h),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn margin_sums_avx2(s: &[f64], c: &[f64], e: &[f64], h: f64) -> (f64, f64, f64) {
    margin_sums_body(s, c, e, h)
}

#[inline(always)]
fn margin_sums_body(s: &[f64], c: &[f64], e: &[f64], h: f64) -> (f64, f64, f64) {
    let nb = c.len();
    let (sa, sb) = s.split_at(nb);
    let (sb, e) = (&sb[..nb], &e[..nb]);
    let (mut ee, mut w, mut m) = ([0.0f64; LANES], [0.0f64; LANES], [0.0f64; LANES]);
    let one = |ee: &mut f64, w: &mut f64, m: &mut f64, a: f64, b: f64, c: f64, e: f64| {
        let ek = a * a + b * b;
        *ee += ek;
        *w += c * ek;
        *m += (c * h).min(2.0 * e) * ek.sqrt();
    };
    let full = nb - nb % LANES;
    let mut k = 0;
    while k < full {
        let (a, b, cc, en) = (lanes(sa, k), lanes(sb, k), lanes(c, k), lanes(e, k));
        for l in 0..LANES {
            one(&mut ee[l], &mut w[l], &mut m[l], a[l], b[l], cc[l], en[l]);
        }
        k += LANES;
    }
    for k in full..nb {
        let l = k - full;
        one(&mut ee[l], &mut w[l], &mut m[l], sa[k], sb[k], c[k], e[k]);
    }
    (lane_sum(ee), lane_sum(w), lane_sum(m))
}

/// Step every block of `s` (`2 nb` entries, block `k` at `k` and `nb + k`)
/// by its propagator in `p`, in place: `(a, b) <- P_k (a, b)` with the
/// scalar step's arithmetic (two products and a sum per entry, no fused
/// multiply-add), so bit for bit the same on either `path`. O(N).
/// \[audio-thread\]
#[inline]
pub fn step_blocks(path: SimdPath, p: &BlockProps, s: &mut [f64]) {
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { step_blocks_avx2(p, s) },
        _ => step_blocks_body(p, s),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn step_blocks_avx2(p: &BlockProps, s: &mut [f64]) {
    step_blocks_body(p, s)
}

#[inline(always)]
fn step_blocks_body(p: &BlockProps, s: &mut [f64]) {
    let nb = s.len() / 2;
    let (sa, sb) = s.split_at_mut(nb);
    let sb = &mut sb[..nb];
    let (p00, p01, p10, p11) = (&p.p00[..nb], &p.p01[..nb], &p.p10[..nb], &p.p11[..nb]);
    for k in 0..nb {
        let (a, b) = (sa[k], sb[k]);
        sa[k] = p00[k] * a + p01[k] * b;
        sb[k] = p10[k] * a + p11[k] * b;
    }
}

/// The rows a Hermite step reads, each per block (`ev`, `ev_d`: `2 nb`
/// entries; the bound weights `c1, c2, c4, e`: `nb`).
pub struct HermiteRows<'a> {
    /// The event row.
    pub ev: &'a [f64],
    /// Its slope row.
    pub ev_d: &'a [f64],
    /// Per block: the bounds of the first, second and fourth derivative
    /// and of the value, per unit of `|s_k|`.
    pub c1: &'a [f64],
    /// See `c1`.
    pub c2: &'a [f64],
    /// See `c1`.
    pub c4: &'a [f64],
    /// See `c1`.
    pub e: &'a [f64],
}

/// One Hermite step over the blocks: `next = P s` (each block as
/// [`step_blocks`] steps it, bit for bit) and the sums the certificates
/// need, `[f0, d0, f1, d1, rem, m4, m2, mag, mag_d]`: the event row and its
/// slope row on `s` and on `next`, `sum_k hermite_block(..) |s_k|`, `sum_k
/// c4_k |s_k|`, `sum_k c2_k |s_k|`, `sum_k (e_k + tau c1_k) |s_k|` and `sum_k
/// c1_k |s_k|`. Block `k` adds into lane `k mod 4` (the last `nb mod 4`
/// blocks into lanes 0.. after the whole groups), the lanes reduced in a
/// fixed order: the same bits on either `path`. `k = [dt4, tail, tau]`.
/// O(N). \[audio-thread\]
#[inline]
pub fn hermite_step_sums(
    path: SimdPath,
    p: &BlockProps,
    s: &[f64],
    next: &mut [f64],
    rows: &HermiteRows<'_>,
    k: [f64; 3],
) -> [f64; 9] {
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { hermite_step_avx2(p, s, next, rows, k) },
        _ => hermite_step_body(p, s, next, rows, k),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn hermite_step_avx2(
    p: &BlockProps,
    s: &[f64],
    next: &mut [f64],
    rows: &HermiteRows<'_>,
    k: [f64; 3],
) -> [f64; 9] {
    hermite_step_body(p, s, next, rows, k)
}

#[inline(always)]
fn hermite_step_body(
    p: &BlockProps,
    s: &[f64],
    next: &mut [f64],
    rows: &HermiteRows<'_>,
    [dt4, tail, tau]: [f64; 3],
) -> [f64; 9] {
    let nb = s.len() / 2;
    let (sa, sb) = s.split_at(nb);
    let sb = &sb[..nb];
    let (na, nbk) = next[..2 * nb].split_at_mut(nb);
    let (p00, p01, p10, p11) = (&p.p00[..nb], &p.p01[..nb], &p.p10[..nb], &p.p11[..nb]);
    let (r0, r1) = rows.ev[..2 * nb].split_at(nb);
    let (q0, q1) = rows.ev_d[..2 * nb].split_at(nb);
    let (c1, c2, c4, e) = (
        &rows.c1[..nb],
        &rows.c2[..nb],
        &rows.c4[..nb],
        &rows.e[..nb],
    );
    let mut acc = [[0.0f64; LANES]; 9];
    // one block's step and terms
    let terms = |[a, b, p00, p01, p10, p11, r0, r1, q0, q1, c1, c2, c4, e]: [f64; 14]| {
        let (a1, b1) = (p00 * a + p01 * b, p10 * a + p11 * b);
        let norm = (a * a + b * b).sqrt();
        (
            (a1, b1),
            [
                r0 * a + r1 * b,
                q0 * a + q1 * b,
                r0 * a1 + r1 * b1,
                q0 * a1 + q1 * b1,
                hermite_block(c1, c4, e, dt4, tail) * norm,
                c4 * norm,
                c2 * norm,
                (e + tau * c1) * norm,
                c1 * norm,
            ],
        )
    };
    let full = nb - nb % LANES;
    for k0 in (0..full).step_by(LANES) {
        let (a, b) = (lanes(sa, k0), lanes(sb, k0));
        let (x00, x01, x10, x11) = (
            lanes(p00, k0),
            lanes(p01, k0),
            lanes(p10, k0),
            lanes(p11, k0),
        );
        let (xr0, xr1, xq0, xq1) = (lanes(r0, k0), lanes(r1, k0), lanes(q0, k0), lanes(q1, k0));
        let (xc1, xc2, xc4, xe) = (lanes(c1, k0), lanes(c2, k0), lanes(c4, k0), lanes(e, k0));
        let (mut a1, mut b1) = ([0.0f64; LANES], [0.0f64; LANES]);
        for l in 0..LANES {
            let ((a1l, b1l), t) = terms([
                a[l], b[l], x00[l], x01[l], x10[l], x11[l], xr0[l], xr1[l], xq0[l], xq1[l], xc1[l],
                xc2[l], xc4[l], xe[l],
            ]);
            (a1[l], b1[l]) = (a1l, b1l);
            for i in 0..9 {
                acc[i][l] += t[i];
            }
        }
        na[k0..k0 + LANES].copy_from_slice(&a1);
        nbk[k0..k0 + LANES].copy_from_slice(&b1);
    }
    for k in full..nb {
        let ((a1, b1), t) = terms([
            sa[k], sb[k], p00[k], p01[k], p10[k], p11[k], r0[k], r1[k], q0[k], q1[k], c1[k], c2[k],
            c4[k], e[k],
        ]);
        (na[k], nbk[k]) = (a1, b1);
        for i in 0..9 {
            acc[i][k - full] += t[i];
        }
    }
    acc.map(lane_sum)
}

/// The Hermite certificate's sums of a block state (`EngineState`'s
/// `hermite_margin`) for `[dt4, tail, dt]`: `(sum_k min(c4_k dt4, 2 e_k +
/// tail c1_k) |s_k|, sum_k (e_k + dt c1_k) |s_k|)`, each summed block after
/// block in order (the terms are computed `LANES` blocks at a time; the sums
/// are the sequential ones, bit for bit on either `path`). O(N).
/// \[audio-thread\]
#[inline]
pub fn hermite_sums(path: SimdPath, s: &[f64], w: [&[f64]; 3], k: [f64; 3]) -> (f64, f64) {
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { hermite_sums_avx2(s, w, k) },
        _ => hermite_sums_body(s, w, k),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn hermite_sums_avx2(s: &[f64], w: [&[f64]; 3], k: [f64; 3]) -> (f64, f64) {
    hermite_sums_body(s, w, k)
}

#[inline(always)]
fn hermite_sums_body(s: &[f64], [c1, c4, e]: [&[f64]; 3], [dt4, tail, dt]: [f64; 3]) -> (f64, f64) {
    let nb = c1.len();
    let (sa, sb) = s.split_at(nb);
    let (sb, c4, e) = (&sb[..nb], &c4[..nb], &e[..nb]);
    let terms = |a: f64, b: f64, c1: f64, c4: f64, e: f64| {
        let norm = (a * a + b * b).sqrt();
        (
            hermite_block(c1, c4, e, dt4, tail) * norm,
            (e + dt * c1) * norm,
        )
    };
    let (mut rem, mut mag) = (0.0, 0.0);
    let full = nb - nb % LANES;
    let mut k = 0;
    while k < full {
        let (a, b) = (lanes(sa, k), lanes(sb, k));
        let (x1, x4, xe) = (lanes(c1, k), lanes(c4, k), lanes(e, k));
        let (mut tr, mut tm) = ([0.0f64; LANES], [0.0f64; LANES]);
        for l in 0..LANES {
            (tr[l], tm[l]) = terms(a[l], b[l], x1[l], x4[l], xe[l]);
        }
        for l in 0..LANES {
            rem += tr[l];
            mag += tm[l];
        }
        k += LANES;
    }
    for k in full..nb {
        let (r, m) = terms(sa[k], sb[k], c1[k], c4[k], e[k]);
        rem += r;
        mag += m;
    }
    (rem, mag)
}

#[inline(always)]
fn event_body<const FMA: bool>(p: Option<&BlockProps>, s: &[f64], rows: [&[f64]; 3]) -> [f64; 3] {
    let nb = s.len() / 2;
    match p {
        Some(p) => event_sum::<FMA, true>(
            [&p.p00[..nb], &p.p01[..nb], &p.p10[..nb], &p.p11[..nb]],
            s,
            rows,
        ),
        None => event_sum::<FMA, false>([&[]; 4], s, rows),
    }
}

/// The sum of [`event_rows`]: block `k` adds into lane `k % LANES`, in a
/// fixed order (no closure: it must inline into the AVX2 copy).
#[inline(always)]
fn event_sum<const FMA: bool, const STEP: bool>(
    p: [&[f64]; 4],
    s: &[f64],
    rows: [&[f64]; 3],
) -> [f64; 3] {
    let nb = s.len() / 2;
    let (sa, sb) = s.split_at(nb);
    let sb = &sb[..nb];
    let r = rows.map(|r| {
        let (a, b) = r.split_at(nb);
        (&a[..nb], &b[..nb])
    });
    let mut acc = [[0.0f64; LANES]; 3];
    let full = nb / LANES * LANES;
    // Whole groups of LANES blocks as fixed-size arrays (the shape the
    // vectoriser takes), then the tail, block `full + j` in lane `j`.
    let group = |x: &[f64], k0: usize| -> [f64; LANES] {
        x[k0..k0 + LANES].try_into().expect("LANES entries")
    };
    for k0 in (0..full).step_by(LANES) {
        let (a, b) = (group(sa, k0), group(sb, k0));
        let (mut x0, mut x1) = (a, b);
        if STEP {
            let pk = p.map(|pq| group(pq, k0));
            for l in 0..LANES {
                x0[l] = madd::<FMA>(pk[0][l], a[l], pk[1][l] * b[l]);
                x1[l] = madd::<FMA>(pk[2][l], a[l], pk[3][l] * b[l]);
            }
        }
        for q in 0..3 {
            let (ra, rb) = (group(r[q].0, k0), group(r[q].1, k0));
            for l in 0..LANES {
                acc[q][l] = madd::<FMA>(ra[l], x0[l], madd::<FMA>(rb[l], x1[l], acc[q][l]));
            }
        }
    }
    for k in full..nb {
        let (x0, x1) = if STEP {
            (
                madd::<FMA>(p[0][k], sa[k], p[1][k] * sb[k]),
                madd::<FMA>(p[2][k], sa[k], p[3][k] * sb[k]),
            )
        } else {
            (sa[k], sb[k])
        };
        for q in 0..3 {
            let l = k - full;
            acc[q][l] = madd::<FMA>(r[q].0[k], x0, madd::<FMA>(r[q].1[k], x1, acc[q][l]));
        }
    }
    [lane_sum(acc[0]), lane_sum(acc[1]), lane_sum(acc[2])]
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn event_avx2(p: Option<&BlockProps>, s: &[f64], rows: [&[f64]; 3]) -> [f64; 3] {
    event_body::<true>(p, s, rows)
}

/// `[r_0 . P s, r_1 . P s, r_2 . P s]` for three rows (the event function
/// and its two derivatives) of a block state `s` stepped by the block
/// propagators `p` (a partial step of exact switching; `None`: no step),
/// without writing the stepped state. Lane sums in a fixed order.
/// O(N), allocation-free. \[audio-thread\]
#[inline]
pub fn event_rows(
    path: SimdPath,
    p: Option<&BlockProps>,
    s: &[f64],
    rows: [&[f64]; 3],
) -> [f64; 3] {
    let n = s.len();
    assert!(
        n.is_multiple_of(2)
            && rows.iter().all(|r| r.len() == n)
            && p.is_none_or(|p| p.len() >= n / 2),
        "event_rows: mismatched lengths"
    );
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { event_avx2(p, s, rows) },
        _ => event_body::<false>(p, s, rows),
    }
}

#[inline(always)]
fn mat_vec_body<const FMA: bool>(m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    let y = &mut y[..nrows];
    let ncols = x.len();
    // Four columns per pass over y: a quarter of the loads and stores of y.
    let mut j = 0;
    while j + 4 <= ncols {
        let xs = [x[j], x[j + 1], x[j + 2], x[j + 3]];
        if xs != [0.0; 4] {
            let c0 = &m[j * nrows..(j + 1) * nrows];
            let c1 = &m[(j + 1) * nrows..(j + 2) * nrows];
            let c2 = &m[(j + 2) * nrows..(j + 3) * nrows];
            let c3 = &m[(j + 3) * nrows..(j + 4) * nrows];
            for i in 0..nrows {
                let mut v = y[i];
                v = madd::<FMA>(c0[i], xs[0], v);
                v = madd::<FMA>(c1[i], xs[1], v);
                v = madd::<FMA>(c2[i], xs[2], v);
                v = madd::<FMA>(c3[i], xs[3], v);
                y[i] = v;
            }
        }
        j += 4;
    }
    for j in j..ncols {
        let xj = x[j];
        if xj == 0.0 {
            continue;
        }
        let col = &m[j * nrows..(j + 1) * nrows];
        for (yi, &mij) in y.iter_mut().zip(col) {
            *yi = madd::<FMA>(mij, xj, *yi);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn mat_vec_avx2(m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    mat_vec_body::<true>(m, nrows, x, y)
}

/// `y += M x` for a column-major `nrows x x.len()` matrix `m` (contiguous
/// columns, vectorised axpys four columns at a time; all-zero groups of `x`
/// skipped).
/// The change of basis at a phase switch. O(rows cols), allocation-free.
/// \[audio-thread\]
pub fn mat_vec_add(path: SimdPath, m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    assert!(
        m.len() == nrows * x.len() && y.len() >= nrows,
        "mat_vec_add: shapes"
    );
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { mat_vec_avx2(m, nrows, x, y) },
        _ => mat_vec_body::<false>(m, nrows, x, y),
    }
}

/// `y += W x` for a change of basis at a switch: through its hierarchical
/// form `h` when there is one (and `structured`), else through the dense
/// row-major `w` of `nrows` rows. `tmp`: scratch for [`hodlr_mat_vec_add`].
/// \[audio-thread\]
pub fn change_of_basis_add(
    path: SimdPath,
    structured: Option<&Hodlr>,
    w: &[f64],
    nrows: usize,
    x: &[f64],
    y: &mut [f64],
    tmp: &mut [Vec<f64>; 3],
) {
    match structured {
        Some(h) => {
            let [a, b, c] = tmp;
            hodlr_mat_vec_add(path, h, x, y, [a, b, c]);
        }
        None => mat_vec_add(path, w, nrows, x, y),
    }
}

/// `y += W x` for `W` in hierarchical low-rank form (the structured change
/// of basis at a switch): the permutations, then each piece through
/// [`mat_vec_add`] (a dense leaf, or `V^T` then `U` of a low-rank block).
/// O(stored entries), allocation-free: `xp`, `yp` and `t` are scratch of at
/// least `cols`, `rows` and `max_rank` entries. \[audio-thread\]
pub fn hodlr_mat_vec_add(
    path: SimdPath,
    h: &Hodlr,
    x: &[f64],
    y: &mut [f64],
    [xp, yp, t]: [&mut [f64]; 3],
) {
    let (xp, yp, t) = (&mut xp[..h.cols], &mut yp[..h.rows], &mut t[..h.max_rank]);
    for (v, &j) in xp.iter_mut().zip(&h.col_perm) {
        *v = x[j];
    }
    yp.fill(0.0);
    for p in &h.pieces {
        let xs = &xp[p.c0..p.c0 + p.nc];
        let ys = &mut yp[p.r0..p.r0 + p.nr];
        match p.rank {
            None => mat_vec_add(path, &h.data[p.off..p.off + p.nr * p.nc], p.nr, xs, ys),
            Some(r) => {
                let t = &mut t[..r];
                t.fill(0.0);
                mat_vec_add(path, &h.data[p.off..p.off + r * p.nc], r, xs, t);
                let u0 = p.off + r * p.nc;
                mat_vec_add(path, &h.data[u0..u0 + p.nr * r], p.nr, t, ys);
            }
        }
    }
    for (v, &i) in yp.iter().zip(&h.row_perm) {
        y[i] += v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A phase of `nb` damped rotation blocks with arbitrary rows and state.
    fn setup(nb: usize) -> (BlockProps, Vec<f64>, [Vec<f64>; 3]) {
        let mut p = BlockProps::new(nb);
        let mut s = vec![0.0; 2 * nb];
        for k in 0..nb {
            let th = 0.1 * k as f64 + 0.05;
            let r = 0.999 - 1e-4 * k as f64;
            p.set(
                k,
                &[r * th.cos(), r * th.sin(), -r * th.sin(), r * th.cos()],
            );
            s[k] = (k as f64).sin();
            s[nb + k] = (k as f64 * 0.7).cos();
        }
        let rows = [0, 1, 2].map(|i| {
            (0..2 * nb)
                .map(|k| ((i + 1) * k) as f64 * 1e-2 - 0.3)
                .collect::<Vec<f64>>()
        });
        (p, s, rows)
    }

    /// Plain per-sample reference: step, then the three rows.
    /// The operands of a test pass.
    fn io<'a>(
        p: &'a BlockProps,
        s: &'a [f64],
        next: &'a mut [f64],
        rows: &'a [Vec<f64>; 3],
        acc: &'a mut BlockAcc,
        out: &'a mut BlockRows,
    ) -> BlockIo<'a> {
        BlockIo {
            p,
            s,
            next,
            rows: Rows {
                ev: &rows[0],
                l: &rows[1],
                r: &rows[2],
            },
            acc,
            out,
        }
    }

    /// One step of every block, plainly (no FMA, no lanes).
    fn plain_step(p: &BlockProps, s: &[f64]) -> Vec<f64> {
        let nb = p.len();
        let mut x = vec![0.0; 2 * nb];
        for b in 0..nb {
            let m = p.get(b);
            x[b] = m[0] * s[b] + m[1] * s[nb + b];
            x[nb + b] = m[2] * s[b] + m[3] * s[nb + b];
        }
        x
    }

    /// The state and rows of a pass with extra sums are `run_block`'s.
    fn assert_plain_rows(
        path: SimdPath,
        p: &BlockProps,
        s: &[f64],
        rows: &[Vec<f64>; 3],
        next: &[f64],
        out: &BlockRows,
    ) {
        let (next_plain, out_plain) = run(path, p, s, rows, EPOCH);
        assert_eq!(next, &next_plain[..]);
        assert_eq!(out.ev, out_plain.ev);
        assert_eq!(out.l, out_plain.l);
        assert_eq!(out.r, out_plain.r);
    }

    fn reference(p: &BlockProps, s: &[f64], rows: &[Vec<f64>; 3], k: usize) -> Vec<[f64; 3]> {
        let mut s = s.to_vec();
        let mut out = Vec::new();
        for _ in 0..k {
            let x = plain_step(p, &s);
            out.push([0, 1, 2].map(|q| rows[q].iter().zip(&x).map(|(a, b)| a * b).sum()));
            s = x;
        }
        out
    }

    fn run(
        path: SimdPath,
        p: &BlockProps,
        s: &[f64],
        rows: &[Vec<f64>; 3],
        k: usize,
    ) -> (Vec<f64>, BlockRows) {
        let mut next = vec![0.0; s.len()];
        let mut acc = Box::new([[[0.0; LANES]; 3]; EPOCH]);
        let mut out = BlockRows::default();
        let io = BlockIo {
            p,
            s,
            next: &mut next,
            rows: Rows {
                ev: &rows[0],
                l: &rows[1],
                r: &rows[2],
            },
            acc: &mut acc,
            out: &mut out,
        };
        run_block(path, io, k);
        (next, out)
    }

    #[test]
    fn both_paths_match_a_plain_reference() {
        println!("path {}", SimdPath::detect().name());
        for nb in [1, 3, 8, 37, 100] {
            let (p, s, rows) = setup(nb);
            let want = reference(&p, &s, &rows, EPOCH);
            for path in [SimdPath::detect(), SimdPath::Generic] {
                let (_, out) = run(path, &p, &s, &rows, EPOCH);
                let mut worst = 0.0f64;
                for (j, w) in want.iter().enumerate() {
                    for (q, got) in [out.ev[j], out.l[j], out.r[j]].iter().enumerate() {
                        let scale = rows[q].iter().map(|x| x.abs()).sum::<f64>() * 2.0;
                        worst = worst.max((got - w[q]).abs() / scale);
                    }
                }
                println!(
                    "{nb} blocks, {path:?}: worst rel. deviation {worst:.1e} over {EPOCH} samples"
                );
                assert!(worst < 1e-13, "{nb} blocks {path:?}: {worst}");
            }
        }
    }

    /// Every choice of extras (quadratic form, slope row, 0, 1 or 3
    /// observation rows; each of the 12 kernels on both paths): the same
    /// state and rows as `run_block` bit for bit, each observation row
    /// bit for bit what the same row gives as a row of `run_block` (the
    /// one summation order), the rows not asked for left alone, and per
    /// sample the quadratic form and the slope row of a plain reference to
    /// rounding, whatever the number of blocks (partial groups included).
    #[test]
    fn extras_match_a_plain_reference_and_leave_the_rows_alone() {
        for nb in [1, 3, 8, 37, 100] {
            let (p, s, rows) = setup(nb);
            let quad = EnergyQuad {
                aa: (0..nb).map(|k| 1.0 + 0.1 * k as f64).collect(),
                ab: (0..nb).map(|k| 0.3 - 0.01 * k as f64).collect(),
                bb: (0..nb).map(|k| 2.0 - 0.005 * k as f64).collect(),
            };
            let drow: Vec<f64> = (0..2 * nb)
                .map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.7)
                .collect();
            let orows = [0, 1, 2].map(|i| {
                (0..2 * nb)
                    .map(|k| ((k * (i + 3)) % 7) as f64 * 0.21 - 0.5)
                    .collect::<Vec<f64>>()
            });
            for path in [SimdPath::detect(), SimdPath::Generic] {
                let (_, as_rows) = run(path, &p, &s, &orows, EPOCH);
                let (mut worst_q, mut worst_d) = (0.0f64, 0.0f64);
                for (with_q, with_d, n_obs) in
                    (0..12).map(|c| (c % 2 == 1, c / 2 % 2 == 1, [0, 1, 3][c / 4]))
                {
                    let mut next = vec![0.0; s.len()];
                    let mut acc = Box::new([[[0.0; LANES]; 3]; EPOCH]);
                    let mut out = BlockRows::default();
                    let mut qacc = Box::new([[0.0; LANES]; EPOCH]);
                    let mut qout = Box::new([f64::NAN; EPOCH]);
                    let mut dacc = Box::new([[0.0; LANES]; EPOCH]);
                    let mut dout = Box::new([f64::NAN; EPOCH]);
                    let mut oacc = Box::new([[[0.0; LANES]; 3]; EPOCH]);
                    let mut oout = BlockRows {
                        ev: [f64::NAN; EPOCH],
                        l: [f64::NAN; EPOCH],
                        r: [f64::NAN; EPOCH],
                    };
                    let extras = Extras {
                        quad: with_q.then_some(QuadIo {
                            quad: &quad,
                            acc: &mut qacc,
                            out: &mut qout,
                        }),
                        slope: with_d.then_some(SlopeIo {
                            row: &drow,
                            acc: &mut dacc,
                            out: &mut dout,
                        }),
                        obs: (n_obs > 0).then_some(ObsIo {
                            rows: Rows {
                                ev: &orows[0],
                                l: &orows[1],
                                r: &orows[2],
                            },
                            all: n_obs == 3,
                            acc: &mut oacc,
                            out: &mut oout,
                        }),
                    };
                    let io = io(&p, &s, &mut next, &rows, &mut acc, &mut out);
                    run_block_with(path, io, extras, EPOCH);
                    assert_plain_rows(path, &p, &s, &rows, &next, &out);
                    let case =
                        format!("{nb} blocks {path:?} quad {with_q} slope {with_d} obs {n_obs}");
                    let bits = |x: &[f64; EPOCH]| x.map(f64::to_bits);
                    match n_obs {
                        0 => assert!(oout.ev.iter().all(|x| x.is_nan()), "{case}"),
                        1 => {
                            assert_eq!(bits(&oout.ev), bits(&as_rows.ev), "{case}");
                            assert!(oout.l.iter().chain(&oout.r).all(|x| x.is_nan()), "{case}");
                        }
                        _ => {
                            assert_eq!(bits(&oout.ev), bits(&as_rows.ev), "{case}");
                            assert_eq!(bits(&oout.l), bits(&as_rows.l), "{case}");
                            assert_eq!(bits(&oout.r), bits(&as_rows.r), "{case}");
                        }
                    }
                    assert_eq!(qout.iter().all(|x| x.is_nan()), !with_q, "{case}");
                    assert_eq!(dout.iter().all(|x| x.is_nan()), !with_d, "{case}");
                    let mut st = s.clone();
                    for j in 0..EPOCH {
                        let x = plain_step(&p, &st);
                        if with_q {
                            let (mut want, mut scale) = (0.0, 0.0);
                            for b in 0..nb {
                                let (a, c) = (x[b], x[nb + b]);
                                want +=
                                    quad.aa[b] * a * a + quad.ab[b] * a * c + quad.bb[b] * c * c;
                                scale += quad.aa[b] * a * a
                                    + quad.ab[b].abs() * (a * c).abs()
                                    + quad.bb[b] * c * c;
                            }
                            worst_q = worst_q.max((qout[j] - want).abs() / scale);
                        }
                        if with_d {
                            let want: f64 = drow.iter().zip(&x).map(|(a, b)| a * b).sum();
                            let scale: f64 = drow.iter().zip(&x).map(|(a, b)| (a * b).abs()).sum();
                            worst_d = worst_d.max((dout[j] - want).abs() / scale);
                        }
                        st = x;
                    }
                }
                println!(
                    "{nb} blocks, {path:?}: quadratic form worst rel. deviation {worst_q:.1e}, slope row {worst_d:.1e}"
                );
                assert!(worst_q < 1e-14, "{nb} blocks {path:?}: {worst_q}");
                assert!(worst_d < 1e-13, "{nb} blocks {path:?}: {worst_d}");
            }
        }
    }

    /// One call of `k` samples is bit-identical to `k` calls of one sample
    /// (the engine's output must not depend on how blocks are split).
    #[test]
    fn k_samples_at_once_equal_k_single_samples_bit_for_bit() {
        for nb in [1, 5, 8, 13, 64] {
            let (p, s, rows) = setup(nb);
            for path in [SimdPath::detect(), SimdPath::Generic] {
                let (next_all, out_all) = run(path, &p, &s, &rows, 23);
                let mut st = s.clone();
                for j in 0..23 {
                    let (next, out) = run(path, &p, &st, &rows, 1);
                    assert_eq!(out.ev[0].to_bits(), out_all.ev[j].to_bits());
                    assert_eq!(out.l[0].to_bits(), out_all.l[j].to_bits());
                    assert_eq!(out.r[0].to_bits(), out_all.r[j].to_bits());
                    st = next;
                }
                assert!(st
                    .iter()
                    .zip(&next_all)
                    .all(|(a, b)| a.to_bits() == b.to_bits()));
                // and the input state is left untouched
                assert_eq!(s, setup(nb).1);
            }
        }
    }

    #[test]
    fn rows_of_uses_the_kernel_order() {
        // rows_of(s) equals the sums the kernel makes for a state stepped by
        // the identity, bit for bit.
        let nb = 21;
        let (mut p, s, rows) = setup(nb);
        for k in 0..nb {
            p.set(k, &[1.0, 0.0, 0.0, 1.0]);
        }
        let (_, out) = run(SimdPath::Generic, &p, &s, &rows, 1);
        let r = Rows {
            ev: &rows[0],
            l: &rows[1],
            r: &rows[2],
        };
        let direct = rows_of(SimdPath::Generic, &s, &r);
        assert_eq!(direct[0].to_bits(), out.ev[0].to_bits());
        assert_eq!(direct[1].to_bits(), out.l[0].to_bits());
        assert_eq!(direct[2].to_bits(), out.r[0].to_bits());
    }

    #[test]
    fn event_rows_match_one_step_of_the_kernel_and_no_step() {
        // With the propagators: the rows of the state after one step (as the
        // kernel computes them); without: the rows of the state itself.
        for nb in [1, 3, 4, 8, 37, 100] {
            let (p, s, rows) = setup(nb);
            let stepped = reference(&p, &s, &rows, 1)[0];
            let unstepped =
                [0, 1, 2].map(|q| rows[q].iter().zip(&s).map(|(a, b)| a * b).sum::<f64>());
            let rr = [&rows[0][..], &rows[1][..], &rows[2][..]];
            for path in [SimdPath::detect(), SimdPath::Generic] {
                for (props, want) in [(Some(&p), stepped), (None, unstepped)] {
                    let got = event_rows(path, props, &s, rr);
                    for q in 0..3 {
                        let scale = rows[q].iter().map(|x| x.abs()).sum::<f64>() * 2.0;
                        let e = (got[q] - want[q]).abs() / scale;
                        assert!(e < 1e-15, "{nb} blocks {path:?} row {q}: {e:e}");
                    }
                }
            }
        }
    }

    #[test]
    fn mat_vec_add_matches_a_plain_product() {
        let (nr, nc) = (37, 29);
        let m: Vec<f64> = (0..nr * nc).map(|i| ((i * 31) % 17) as f64 - 8.0).collect();
        let mut x: Vec<f64> = (0..nc).map(|j| (j as f64).cos()).collect();
        x[3] = 0.0;
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let mut y = vec![1.0; nr];
            mat_vec_add(path, &m, nr, &x, &mut y);
            for i in 0..nr {
                let want = 1.0 + (0..nc).map(|j| m[j * nr + i] * x[j]).sum::<f64>();
                assert!((y[i] - want).abs() < 1e-12, "{path:?} row {i}");
            }
        }
    }

    #[test]
    fn vectorised_margins_and_rows_are_the_scalar_sums_bit_for_bit() {
        // every tail length, both paths, against the scalar loops the
        // engine used before (the same lanes, the same order)
        for nb in [1, 2, 3, 4, 5, 7, 8, 9, 37, 100, 1003] {
            let (_, s, rows) = setup(nb);
            let c: Vec<f64> = (0..nb)
                .map(|k| 0.3 + (k as f64 * 0.7).sin().abs())
                .collect();
            let e: Vec<f64> = (0..nb).map(|k| 1e-3 * (1.0 + (k % 5) as f64)).collect();
            let c4: Vec<f64> = (0..nb).map(|k| 10.0 + (k * k % 13) as f64).collect();
            let h = 0.37;
            let (want_e, want_w) = block_measures(&s, &c);
            let want_m = block_margin(&s, &c, &e, h);
            let r = Rows {
                ev: &rows[0],
                l: &rows[1],
                r: &rows[2],
            };
            let want_rows = [0, 1, 2].map(|q| {
                let mut acc = [0.0f64; LANES];
                for k in 0..nb {
                    acc[k % LANES] += rows[q][k] * s[k];
                    acc[k % LANES] += rows[q][nb + k] * s[nb + k];
                }
                lane_sum(acc)
            });
            let (dt4, tail, dt) = (1e-3, 0.2, 0.5);
            let (mut want_rem, mut want_mag) = (0.0, 0.0);
            for k in 0..nb {
                let norm = (s[k] * s[k] + s[nb + k] * s[nb + k]).sqrt();
                want_rem += super::hermite_block(c[k], c4[k], e[k], dt4, tail) * norm;
                want_mag += (e[k] + dt * c[k]) * norm;
            }
            for path in [SimdPath::detect(), SimdPath::Generic] {
                let (ge, gw, gm) = margin_sums(path, &s, &c, &e, h);
                let bits = |a: f64, b: f64| a.to_bits() == b.to_bits();
                assert!(
                    bits(ge, want_e) && bits(gw, want_w) && bits(gm, want_m),
                    "{nb} blocks {path:?}: margins"
                );
                let got = rows_of(path, &s, &r);
                assert!(
                    (0..3).all(|q| bits(got[q], want_rows[q])),
                    "{nb} blocks {path:?}: rows"
                );
                let (rem, mag) = hermite_sums(path, &s, [&c, &c4, &e], [dt4, tail, dt]);
                assert!(
                    bits(rem, want_rem) && bits(mag, want_mag),
                    "{nb} blocks {path:?}: Hermite sums"
                );
            }
        }
    }

    #[test]
    fn hermite_step_is_the_scalar_step_with_lane_sums_bit_for_bit() {
        // every tail length, both paths: the stepped state is the scalar
        // step's (what `advance_by` did block by block), the sums are the
        // lanes' (block `k` into lane `k mod 4`); and the lanes' sums are
        // within the certificates' rounding allowance `(2 nb + 16) u mag`
        // of the sequential sums the engine took before
        for nb in [1, 2, 3, 4, 5, 7, 8, 9, 37, 100, 1003] {
            let (p, s, rows) = setup(nb);
            let w = |f: &dyn Fn(usize) -> f64| (0..nb).map(f).collect::<Vec<f64>>();
            let c1 = w(&|k| 0.3 + (k as f64 * 0.7).sin().abs());
            let c2 = w(&|k| 2.0 + (k as f64 * 0.3).cos());
            let c4 = w(&|k| 10.0 + (k * k % 13) as f64);
            let e = w(&|k| 1e-3 * (1.0 + (k % 5) as f64));
            let hr = HermiteRows {
                ev: &rows[0],
                ev_d: &rows[1],
                c1: &c1,
                c2: &c2,
                c4: &c4,
                e: &e,
            };
            let (dt4, tail, tau) = (1e-3, 0.2, 0.5);
            let mut want_next = s.clone();
            for k in 0..nb {
                let (a, b) = (s[k], s[nb + k]);
                let q = p.get(k);
                want_next[k] = q[0] * a + q[1] * b;
                want_next[nb + k] = q[2] * a + q[3] * b;
            }
            let (mut lanes_acc, mut seq) = ([[0.0f64; LANES]; 9], [0.0f64; 9]);
            let mut abs = [0.0f64; 9];
            for k in 0..nb {
                let (a, b) = (s[k], s[nb + k]);
                let (a1, b1) = (want_next[k], want_next[nb + k]);
                let norm = (a * a + b * b).sqrt();
                let (r, q) = (&rows[0], &rows[1]);
                let t = [
                    r[k] * a + r[nb + k] * b,
                    q[k] * a + q[nb + k] * b,
                    r[k] * a1 + r[nb + k] * b1,
                    q[k] * a1 + q[nb + k] * b1,
                    super::hermite_block(c1[k], c4[k], e[k], dt4, tail) * norm,
                    c4[k] * norm,
                    c2[k] * norm,
                    (e[k] + tau * c1[k]) * norm,
                    c1[k] * norm,
                ];
                for i in 0..9 {
                    lanes_acc[i][k % LANES] += t[i];
                    seq[i] += t[i];
                    abs[i] += t[i].abs();
                }
            }
            let want = lanes_acc.map(lane_sum);
            for i in 0..9 {
                // each order rounds within `nb u` of the magnitudes summed
                let allowance = (2 * nb + 16) as f64 * f64::EPSILON * abs[i];
                assert!(
                    (want[i] - seq[i]).abs() <= allowance,
                    "{nb} blocks: sum {i} reordered by {:e}, allowance {allowance:e}",
                    (want[i] - seq[i]).abs()
                );
            }
            for path in [SimdPath::detect(), SimdPath::Generic] {
                let mut next = vec![f64::NAN; 2 * nb];
                let got = hermite_step_sums(path, &p, &s, &mut next, &hr, [dt4, tail, tau]);
                let bits =
                    |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(
                    bits(&next, &want_next),
                    "{nb} blocks {path:?}: stepped state"
                );
                assert!(
                    bits(&got, &want),
                    "{nb} blocks {path:?}: sums {got:?} against {want:?}"
                );
                let mut stepped = s.clone();
                step_blocks(path, &p, &mut stepped);
                assert!(
                    bits(&stepped, &want_next),
                    "{nb} blocks {path:?}: step_blocks"
                );
            }
        }
    }

    #[test]
    fn block_measures_are_block_energies() {
        let (_, s, _) = setup(9);
        let c: Vec<f64> = (0..9).map(|k| k as f64).collect();
        let (e, w) = block_measures(&s, &c);
        let e_want: f64 = s.iter().map(|x| x * x).sum();
        let w_want: f64 = (0..9)
            .map(|k| c[k] * (s[k] * s[k] + s[9 + k] * s[9 + k]))
            .sum();
        assert!((e - e_want).abs() < 1e-14 * e_want && (w - w_want).abs() < 1e-14 * w_want);
    }
}
