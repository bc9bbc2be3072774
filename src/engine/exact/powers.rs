//! The slow terms' powers `C mu^j`, raised eight terms at a time through
//! every power the slow polynomial needs, in one vectorised pass (on the
//! AVX2 path when the CPU has it), and the first powers of one fast term.

use super::MAX_DEGREE;
use crate::engine::vmath::SimdPath;

/// The slow terms' powers `z = C mu^j` (structure of arrays) and what
/// their sums need: `cw` weighs `|Im z|` in the magnitudes.
pub(super) struct Powers<'a> {
    pub(super) zr: &'a mut [f64],
    pub(super) zi: &'a mut [f64],
    pub(super) mr: &'a [f64],
    pub(super) mi: &'a [f64],
    pub(super) cw: &'a [f64],
}

/// For `j` in `js.0..=js.1`: `sums[j] = sum_i Re(z_i)`, then `z *= mu`
/// elementwise (complex), and at `j = marks[m]` the magnitude `mags[m] =
/// sum_i |Re z_i| + cw_i |Im z_i|` before the product. The terms are taken
/// eight at a time through all the powers (held in registers, eight
/// independent products in flight) rather than one power at a time through
/// all the terms, so `z` is read and written once, not once per power. The
/// sums run in four lanes (`i mod 4`, reduced in a fixed order, the last
/// `n mod 4` terms apart) and the magnitudes in order of `i`: the same
/// additions in the same order whatever the chunking (deterministic). On the
/// AVX2 path when the CPU has it. \[audio-thread\]
pub(super) fn raise_powers(
    simd: SimdPath,
    p: Powers<'_>,
    js: (usize, usize),
    marks: [usize; 2],
    sums: &mut [f64; MAX_DEGREE + 2],
    mags: &mut [f64; 2],
) {
    /// Terms `i0..i0 + W` through the powers `js`.
    #[inline(always)]
    fn chunk<const W: usize>(
        p: &mut Powers<'_>,
        i0: usize,
        js: (usize, usize),
        marks: [usize; 2],
        acc: &mut [[f64; 4]; MAX_DEGREE + 2],
        mags: &mut [f64; 2],
    ) {
        let mut a = [0.0; W];
        let mut b = [0.0; W];
        let mut mr = [0.0; W];
        let mut mi = [0.0; W];
        a.copy_from_slice(&p.zr[i0..i0 + W]);
        b.copy_from_slice(&p.zi[i0..i0 + W]);
        mr.copy_from_slice(&p.mr[i0..i0 + W]);
        mi.copy_from_slice(&p.mi[i0..i0 + W]);
        for j in js.0..=js.1 {
            for (m, &mark) in marks.iter().enumerate() {
                if j == mark {
                    for l in 0..W {
                        mags[m] += a[l].abs() + b[l].abs() * p.cw[i0 + l];
                    }
                }
            }
            let acc_j = &mut acc[j];
            for l in 0..W {
                acc_j[l % 4] += a[l];
                let (x, y) = (a[l], b[l]);
                a[l] = x * mr[l] - y * mi[l];
                b[l] = x * mi[l] + y * mr[l];
            }
        }
        p.zr[i0..i0 + W].copy_from_slice(&a);
        p.zi[i0..i0 + W].copy_from_slice(&b);
    }
    #[inline(always)]
    fn body(
        mut p: Powers<'_>,
        js: (usize, usize),
        marks: [usize; 2],
        sums: &mut [f64; MAX_DEGREE + 2],
        mags: &mut [f64; 2],
    ) {
        let n = p.zr.len();
        let full = n - n % 4;
        let mut acc = [[0.0; 4]; MAX_DEGREE + 2];
        let mut i = 0;
        while i + 8 <= full {
            chunk::<8>(&mut p, i, js, marks, &mut acc, mags);
            i += 8;
        }
        if i < full {
            chunk::<4>(&mut p, i, js, marks, &mut acc, mags);
        }
        let mut tail = [0.0; MAX_DEGREE + 2];
        for i in full..n {
            let (mut a, mut b) = (p.zr[i], p.zi[i]);
            let (mr, mi) = (p.mr[i], p.mi[i]);
            for j in js.0..=js.1 {
                for (m, &mark) in marks.iter().enumerate() {
                    if j == mark {
                        mags[m] += a.abs() + b.abs() * p.cw[i];
                    }
                }
                tail[j] += a;
                (a, b) = (a * mr - b * mi, a * mi + b * mr);
            }
            p.zr[i] = a;
            p.zi[i] = b;
        }
        for j in js.0..=js.1 {
            let a = &acc[j];
            sums[j] = ((a[0] + a[1]) + (a[2] + a[3])) + tail[j];
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn body_avx2(
        p: Powers<'_>,
        js: (usize, usize),
        marks: [usize; 2],
        sums: &mut [f64; MAX_DEGREE + 2],
        mags: &mut [f64; 2],
    ) {
        body(p, js, marks, sums, mags)
    }
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `detect()` makes, after
        // checking AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(p, js, marks, sums, mags) },
        _ => body(p, js, marks, sums, mags),
    }
}

/// `C mu^j` for `j = 0, 1, 3` as `(Re, Im)`.
pub(super) fn powers(cr: f64, ci: f64, m: f64, w: f64) -> [(f64, f64); 3] {
    let mul = |(a, b): (f64, f64)| (a * m - b * w, a * w + b * m);
    let c1 = mul((cr, ci));
    let c3 = mul(mul(c1));
    [(cr, ci), c1, c3]
}
