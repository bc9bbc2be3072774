//! Single passes over a block state outside the block kernel: its rows
//! ([`rows_of`]), the fast path's interpolation margin ([`margin_sums`]),
//! the Hermite certificates' sums ([`hermite_sums`],
//! [`hermite_step_sums`]), the event rows of a partially stepped state
//! ([`event_rows`]) and a plain step ([`step_blocks`]). Each sums in a
//! fixed order, the same bits on either path; [`rows_as_kernel`] alone
//! sums as the kernel does on each path (fused on the FMA path).

use super::{hermite_block, lane_sum, BlockProps, Rows, LANES};
use crate::engine::vmath::{madd, SimdPath};

/// `[ev . s, l . s, r . s]` (no step), summed in the same order as
/// [`run_block_with`](super::run_block_with)'s generic path (bit-identical to it, on either
/// `path`: the AVX2 copy vectorises the same lane sums, without fused
/// multiply-adds). O(N). \[audio-thread\]
#[inline]
pub(crate) fn rows_of(path: SimdPath, s: &[f64], rows: &Rows) -> [f64; 3] {
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

/// `[ev . s, l . s, r . s]` (no step) summed exactly as
/// [`run_block_with`](super::run_block_with) sums the rows of a state it
/// stepped on `path`: the same groups of [`GROUP`](super::GROUP) blocks,
/// lanes and order as [`rows_of`], and on the FMA path the same fused
/// multiply-adds (which [`rows_of`] never takes). The rows of the state a
/// run starts from, bit for bit what the kernel would give for it: the
/// several-contact engine outputs a sample from the rows before its step,
/// the first of a run from these and the others from the kernel's. O(N).
/// \[audio-thread\]
#[inline]
pub(crate) fn rows_as_kernel(path: SimdPath, s: &[f64], rows: &Rows) -> [f64; 3] {
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { rows_as_kernel_fma(s, rows) },
        _ => rows_as_kernel_body::<false>(s, rows),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rows_as_kernel_fma(s: &[f64], rows: &Rows) -> [f64; 3] {
    rows_as_kernel_body::<true>(s, rows)
}

/// Group by group as the kernel loads them (a short last group padded
/// with zeros, which add exactly nothing), each group's share added by the
/// kernel's own [`rows_into`](super::block::rows_into).
#[inline(always)]
fn rows_as_kernel_body<const FMA: bool>(s: &[f64], rows: &Rows) -> [f64; 3] {
    use super::GROUP;
    let nb = s.len() / 2;
    let (sa, sb) = (&s[..nb], &s[nb..2 * nb]);
    let r = [rows.ev, rows.l, rows.r];
    let mut acc = [[0.0f64; LANES]; 3];
    let mut row = [[0.0f64; GROUP]; 6];
    let mut base = 0;
    while base < nb {
        let width = GROUP.min(nb - base);
        let at = |v: &[f64], i: usize| if i < width { v[base + i] } else { 0.0 };
        let x0: [f64; GROUP] = std::array::from_fn(|i| at(sa, i));
        let x1: [f64; GROUP] = std::array::from_fn(|i| at(sb, i));
        for (q, rq) in r.iter().enumerate() {
            let (ra, rb) = rq.split_at(nb);
            row[2 * q] = std::array::from_fn(|i| at(ra, i));
            row[2 * q + 1] = std::array::from_fn(|i| at(&rb[..nb], i));
        }
        super::block::rows_into::<FMA, 3>(base == 0, &mut acc, &row, &x0, &x1);
        base += width;
    }
    [lane_sum(acc[0]), lane_sum(acc[1]), lane_sum(acc[2])]
}

/// `LANES` consecutive values from `k`.
#[inline(always)]
fn lanes(v: &[f64], k: usize) -> [f64; LANES] {
    v[k..k + LANES].try_into().expect("LANES values")
}

/// `block_measures` and `block_margin` (the tests' scalar references) in
/// one pass over the state, bit for bit the same three sums on either
/// `path` (the same lanes, no fused multiply-adds): `(e, w, margin)`. O(N),
/// about a third of the two scalar passes' time at 1000 modes (1.7 against
/// 5.0 us). \[audio-thread\]
#[inline]
pub(crate) fn margin_sums(
    path: SimdPath,
    s: &[f64],
    c: &[f64],
    e: &[f64],
    h: f64,
) -> (f64, f64, f64) {
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
pub(crate) fn step_blocks(path: SimdPath, p: &BlockProps, s: &mut [f64]) {
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
pub(crate) struct HermiteRows<'a> {
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
pub(crate) fn hermite_step_sums(
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
pub(crate) fn hermite_sums(path: SimdPath, s: &[f64], w: [&[f64]; 3], k: [f64; 3]) -> (f64, f64) {
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
pub(crate) fn event_rows(
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

/// The two energy measures of a block state that bound the event function's
/// curvature: `(sum_k |s_k|^2, sum_k c_k |s_k|^2)` with `s_k` the 2-vector of
/// block `k` and `c` per-block weights. O(N). The fast path takes them from
/// [`margin_sums`] (the same sums); this scalar loop is the tests'
/// reference.
#[cfg(test)]
pub(crate) fn block_measures(s: &[f64], c: &[f64]) -> (f64, f64) {
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
pub(crate) fn block_margin(s: &[f64], c: &[f64], e: &[f64], h: f64) -> f64 {
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
