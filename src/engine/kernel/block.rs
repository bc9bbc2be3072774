//! The block kernel: a phase advanced by up to [`EPOCH`] samples in one
//! call, mode-major (a group of [`GROUP`] blocks held in registers through
//! all the samples), with the extras a run may sum beside its rows (the
//! trace's energy and motion, the Hermite certificate's slope row); one
//! copy per choice of extras, each compiled for AVX2+FMA and for the
//! baseline target.

use super::{lane_sum, BlockAcc, BlockProps, BlockRows, Rows, EPOCH, GROUP, LANES};
use crate::compile::EnergyQuad;
use crate::engine::vmath::{madd, SimdPath};

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
pub(super) fn rows_into<const FMA: bool, const N: usize>(
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
pub(crate) struct BlockIo<'a> {
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
pub(crate) struct QuadIo<'a> {
    /// The weights.
    pub quad: &'a EnergyQuad,
    /// Scratch for the per-sample lane sums.
    pub acc: &'a mut [[f64; LANES]; EPOCH],
    /// The form of every stepped state (written).
    pub out: &'a mut [f64; EPOCH],
}

/// Lane scratch of a [`QuadIo`].
pub(crate) type QuadAcc = [[f64; LANES]; EPOCH];

/// The slope row of [`run_block_with`]: the row, the caller's lane
/// scratch and the per-sample values it writes.
pub(crate) struct SlopeIo<'a> {
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
pub(crate) struct ObsIo<'a> {
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
pub(crate) struct Extras<'a> {
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
pub(crate) fn run_block_with(path: SimdPath, io: BlockIo, extras: Extras, k: usize) {
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
pub(crate) fn run_block(path: SimdPath, io: BlockIo, k: usize) {
    run_block_with(path, io, Extras::default(), k);
}
