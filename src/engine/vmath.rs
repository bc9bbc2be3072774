//! Batch `exp`, `sin` and `cos` for the audio thread: branch-free lanes that
//! LLVM vectorises, compiled twice like the kernels in [`kernel`] (a
//! `#[target_feature(enable = "avx2,fma")]` copy with fused multiply-adds and
//! a baseline copy), chosen at run time by [`SimdPath`].
//!
//! Method (per lane, no branches; the two paths differ only in FMA rounding):
//!
//! * `exp(m)`: `m` is clamped to `[-746, 710]` (outside it the result is 0 or
//!   +inf anyway; NaN passes through), `n = round(m / ln 2)` by the
//!   `1.5 * 2^52` magic-number trick, and `m - n ln 2` is reduced with
//!   fdlibm's two-part (Cody-Waite) `ln2_hi + ln2_lo`: `m - n ln2_hi` is
//!   exact, and the rounding error of subtracting `n ln2_lo` is kept as a
//!   correction term. `exp(x)` on `|x| <= ln2/2` is the Taylor polynomial of
//!   degree 13 (truncation < 5e-18 relative), summed as
//!   `(1 + x) + (x^2 Q(x) + err(1 + x) + corr)` with `1 + x` split exactly.
//!   The result is scaled by `2^n` in two exact steps `2^n1 * 2^n2`
//!   (`n1 = round(n/2)`), built from exponent bits with shifts only, so
//!   subnormal results are rounded once (correct, not flushed) and `exp` of
//!   values near 709.78 does not overflow early.
//! * `sin(r)`, `cos(r)`: quadrant `q = round(r * 2/pi)` by the magic trick,
//!   then the reduced argument `r - q pi/2` as a double-double `(y0, y1)`
//!   with fdlibm's 33-bit split of `pi/2` (`pio2_1 + pio2_2 + pio2_3 +
//!   pio2_3t`, as in `__ieee754_rem_pio2`): `q pio2_{1,2,3}` are exact for
//!   `q < 2^20`, so is `r - q pio2_1`, and the two further subtractions
//!   keep their rounding errors (Fast2Sum), so the reduced argument is
//!   accurate to better than 2^-70 relative, even next to a multiple of
//!   `pi/2` (the nearest doubles to `k pi/2` below [`R_FAST`] leave
//!   remainders of ~1e-17 at worst), and `sin(k pi)` keeps full relative
//!   precision.
//!   fdlibm's `__kernel_sin(x, y, 1)` / `__kernel_cos(x, y)` minimax
//!   polynomials (FreeBSD `k_sin.c`, `k_cos.c`; Sun Microsystems 1993) give
//!   both on `[-pi/4, pi/4]`, and the quadrant swaps and negates them with
//!   bit masks. Arguments above [`R_FAST`] (rare; +inf too) are recomputed
//!   by `f64::sin_cos` in a scalar pass after the vector loop, which only
//!   runs when some lane needs it.
//!
//! Measured accuracy, both paths: against glibc's `exp` and `sin_cos` (tests
//! below: ~1e6 random arguments, ~2.5e6 arguments next to multiples of
//! `pi/4` and `pi/2`, edge cases) every result is within 1 ulp of glibc's,
//! in ulps of the reference value (no floor, so `sin` next to a root of
//! it is held to its own relative precision); 1-3% of the results differ
//! from glibc at all. Against 200-bit references (mpmath, offline, on 1e5
//! arguments per path weighted towards the hard cases: arguments next to
//! multiples of `pi/2`, odd multiples of `pi/4` and subnormal `exp`): `exp`
//! <= 0.64 ulp (normal results; <= 0.75 ulp of the subnormal spacing for
//! subnormal ones), `sin` <= 0.80 ulp, `cos` <= 0.75 ulp (glibc: 0.51).
//!
//! [`kernel`]: super::kernel

/// Proof that this CPU has AVX2 and FMA. Only [`SimdPath::detect`] makes
/// one (its field is private to this module), so no code, not even in this
/// crate, can ask for the AVX2 kernels on a CPU that lacks them: the
/// `unsafe` calls into `#[target_feature]` functions here and in
/// [`kernel`](super::kernel) rely on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Avx2Fma(());

/// Which kernel variant runs on this machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SimdPath {
    /// AVX2 with FMA (x86-64, detected at run time).
    Avx2Fma(Avx2Fma),
    /// Portable code for the baseline target (SSE2 on x86-64).
    Generic,
}

impl SimdPath {
    /// Detect the best path for this CPU.
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                return SimdPath::Avx2Fma(Avx2Fma(()));
            }
        }
        SimdPath::Generic
    }
    /// Human-readable name (benchmarks print it).
    pub(crate) fn name(self) -> &'static str {
        match self {
            SimdPath::Avx2Fma(_) => "avx2+fma (runtime-detected)",
            SimdPath::Generic => "generic (baseline target)",
        }
    }
}

/// `a b + c`: fused (one rounding) in the FMA copy of a kernel, two
/// roundings in the baseline copy. Only call it from `#[inline(always)]`
/// bodies, so that it is compiled inside the `target_feature` function
/// (elsewhere `mul_add` would be a call into libm's software fma).
#[inline(always)]
pub(crate) fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Largest `r` the vector path reduces itself (`q = round(r 2/pi) < 2^20`
/// keeps the products `q pio2_k` exact); larger arguments fall back to
/// `f64::sin_cos`.
pub(crate) const R_FAST: f64 = 1.0e6;

/// Lanes per chunk: two AVX2 vectors (or four SSE2 ones) per step.
const LANES: usize = 8;

/// `1.5 * 2^52`: adding it rounds a double of magnitude < 2^51 to an
/// integer, which then sits in the low bits of the sum.
const MAGIC: f64 = 6_755_399_441_055_744.0;
/// `MAGIC + 1023`: the sum's low 12 bits are then a biased exponent.
const MAGIC_BIAS: f64 = 6_755_399_441_056_767.0;

const LOG2E: f64 = std::f64::consts::LOG2_E;
/// fdlibm `e_exp.c`: `ln2_hi` (32 significant bits) and `ln2_lo`.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
/// Clamp of the exponent argument: `exp(-746) = 0`, `exp(710) = inf`.
const M_MIN: f64 = -746.0;
const M_MAX: f64 = 710.0;

/// Taylor coefficients `1/k!`, `k = 2..=13`.
const E2: f64 = 1.0 / 2.0;
const E3: f64 = 1.0 / 6.0;
const E4: f64 = 1.0 / 24.0;
const E5: f64 = 1.0 / 120.0;
const E6: f64 = 1.0 / 720.0;
const E7: f64 = 1.0 / 5_040.0;
const E8: f64 = 1.0 / 40_320.0;
const E9: f64 = 1.0 / 362_880.0;
const E10: f64 = 1.0 / 3_628_800.0;
const E11: f64 = 1.0 / 39_916_800.0;
const E12: f64 = 1.0 / 479_001_600.0;
const E13: f64 = 1.0 / 6_227_020_800.0;

/// fdlibm `e_rem_pio2.c`: `2/pi` and `pi/2` in 33-bit pieces.
const INV_PIO2: f64 = f64::from_bits(0x3fe4_5f30_6dc9_c883);
const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5440_0000);
const PIO2_2: f64 = f64::from_bits(0x3dd0_b461_1a60_0000);
const PIO2_3: f64 = f64::from_bits(0x3ba3_198a_2e00_0000);
const PIO2_3T: f64 = f64::from_bits(0x397b_839a_2520_49c1);

/// fdlibm `k_sin.c`.
const S1: f64 = f64::from_bits(0xbfc5_5555_5555_5549);
const S2: f64 = f64::from_bits(0x3f81_1111_1110_f8a6);
const S3: f64 = f64::from_bits(0xbf2a_01a0_19c1_61d5);
const S4: f64 = f64::from_bits(0x3ec7_1de3_57b1_fe7d);
const S5: f64 = f64::from_bits(0xbe5a_e5e6_8a2b_9ceb);
const S6: f64 = f64::from_bits(0x3de5_d93a_5acf_d57c);
/// fdlibm `k_cos.c`.
const C1: f64 = f64::from_bits(0x3fa5_5555_5555_554c);
const C2: f64 = f64::from_bits(0xbf56_c16c_16c1_5177);
const C3: f64 = f64::from_bits(0x3efa_01a0_19cb_1590);
const C4: f64 = f64::from_bits(0xbe92_7e4f_809c_52ad);
const C5: f64 = f64::from_bits(0x3e21_ee9e_bdb4_b1c4);
const C6: f64 = f64::from_bits(0xbda8_fae9_be88_38d4);

/// `2^k` for an integer-valued `k` in `[-1022, 1023]` given as
/// `t = k + MAGIC_BIAS` (the biased exponent is in the low bits of `t`).
#[inline(always)]
fn pow2_from_magic(t: f64) -> f64 {
    f64::from_bits(t.to_bits() << 52)
}

/// `exp(m)` of one lane (see the module doc).
#[inline(always)]
fn exp_lane<const FMA: bool>(m: f64) -> f64 {
    // Selects, not branches; NaN compares false and passes through.
    let x = if m < M_MIN { M_MIN } else { m };
    let x = if x > M_MAX { M_MAX } else { x };
    let n = madd::<FMA>(x, LOG2E, MAGIC) - MAGIC;
    // x - n ln2_hi is exact (n ln2_hi has <= 43 bits, Sterbenz).
    let hi = madd::<FMA>(-n, LN2_HI, x);
    let lo = n * LN2_LO;
    let r = hi - lo;
    let corr = (hi - r) - lo;
    // Q(r) = sum_{k=2}^{13} r^(k-2) / k!, Estrin's scheme (short latency).
    let r2 = r * r;
    let r4 = r2 * r2;
    let p0 = madd::<FMA>(r, E3, E2);
    let p1 = madd::<FMA>(r, E5, E4);
    let p2 = madd::<FMA>(r, E7, E6);
    let p3 = madd::<FMA>(r, E9, E8);
    let p4 = madd::<FMA>(r, E11, E10);
    let p5 = madd::<FMA>(r, E13, E12);
    let q01 = madd::<FMA>(r2, p1, p0);
    let q23 = madd::<FMA>(r2, p3, p2);
    let q45 = madd::<FMA>(r2, p5, p4);
    let q = madd::<FMA>(r4, madd::<FMA>(r4, q45, q23), q01);
    // exp(r + corr) = (1 + r) + r^2 Q(r) + corr (1 + r), with 1 + r split.
    let one_r = 1.0 + r;
    let one_r_err = (1.0 - one_r) + r;
    let tail = madd::<FMA>(r2, q, madd::<FMA>(corr, one_r, one_r_err));
    let p = one_r + tail;
    // 2^n = 2^n1 2^n2, both factors normal for n in [-1077, 1025].
    let t1 = madd::<FMA>(n, 0.5, MAGIC_BIAS);
    let n1 = t1 - MAGIC_BIAS;
    let t2 = (n - n1) + MAGIC_BIAS;
    p * pow2_from_magic(t1) * pow2_from_magic(t2)
}

/// `(sin r, cos r)` of one lane for `0 <= r <= R_FAST` (see the module doc).
#[inline(always)]
fn sincos_lane<const FMA: bool>(r: f64) -> (f64, f64) {
    let t = madd::<FMA>(r, INV_PIO2, MAGIC);
    let q = t - MAGIC;
    // r - q pi/2 as y0 + y1. The three products are exact for q < 2^20,
    // and so is a = r - q pio2_1 (Sterbenz). The two further subtractions
    // keep their rounding errors e1, e2 (Fast2Sum): where |a| < |b| (or
    // |s1| < |c|) the difference is exact, as a, b are multiples of 2^-65
    // and |a - b| < 2^-13 (s1, c: multiples of 2^-96, |s1 - c| < 2^-48), so
    // the error term comes out 0, as it should.
    let a = madd::<FMA>(-q, PIO2_1, r);
    let b = q * PIO2_2;
    let c = q * PIO2_3;
    let d = q * PIO2_3T;
    let s1 = a - b;
    let e1 = (a - s1) - b;
    let s2 = s1 - c;
    let e2 = (s1 - s2) - c;
    let tail = (e1 + e2) - d;
    let y0 = s2 + tail;
    let y1 = tail - (y0 - s2);
    // fdlibm __kernel_sin(y0, y1, 1) and __kernel_cos(y0, y1).
    let z = y0 * y0;
    let w = z * z;
    let v = z * y0;
    let rs = madd::<FMA>(
        z * w,
        madd::<FMA>(z, S6, S5),
        madd::<FMA>(z, madd::<FMA>(z, S4, S3), S2),
    );
    let ks = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * S1);
    let rc = madd::<FMA>(
        w * w,
        madd::<FMA>(z, madd::<FMA>(z, C6, C5), C4),
        z * madd::<FMA>(z, madd::<FMA>(z, C3, C2), C1),
    );
    let hz = 0.5 * z;
    let wc = 1.0 - hz;
    let kc = wc + (((1.0 - wc) - hz) + (z * rc - y0 * y1));
    // Quadrant: odd q swaps sin and cos; sin is negated for q mod 4 in
    // {2, 3}, cos for {1, 2}. Bit masks, no branches.
    let qb = t.to_bits();
    let swap = (qb & 1).wrapping_neg();
    let sin_sign = (qb & 2) << 62;
    let cos_sign = (qb.wrapping_add(1) & 2) << 62;
    let (ks, kc) = (ks.to_bits(), kc.to_bits());
    let sin = ((ks & !swap) | (kc & swap)) ^ sin_sign;
    let cos = ((kc & !swap) | (ks & swap)) ^ cos_sign;
    (f64::from_bits(sin), f64::from_bits(cos))
}

/// One chunk of [`LANES`] lanes; returns whether some `r` exceeded
/// [`R_FAST`] (its sine and cosine must be recomputed).
#[inline(always)]
fn chunk<const FMA: bool>(
    m: &[f64; LANES],
    r: &[f64; LANES],
    e: &mut [f64; LANES],
    s: &mut [f64; LANES],
    c: &mut [f64; LANES],
) -> bool {
    let mut big = 0u64;
    for j in 0..LANES {
        e[j] = exp_lane::<FMA>(m[j]);
        let (sj, cj) = sincos_lane::<FMA>(r[j]);
        s[j] = sj;
        c[j] = cj;
        big |= (r[j] > R_FAST) as u64;
    }
    big != 0
}

#[inline(always)]
fn body<const FMA: bool>(
    m: &[f64],
    r: &[f64],
    e: &mut [f64],
    s: &mut [f64],
    c: &mut [f64],
) -> bool {
    let (mc, mt) = m.as_chunks::<LANES>();
    let (rc, rt) = r.as_chunks::<LANES>();
    let (ec, et) = e.as_chunks_mut::<LANES>();
    let (sc, st) = s.as_chunks_mut::<LANES>();
    let (cc, ct) = c.as_chunks_mut::<LANES>();
    let mut big = false;
    for ((((mk, rk), ek), sk), ck) in mc.iter().zip(rc).zip(ec).zip(sc).zip(cc) {
        big |= chunk::<FMA>(mk, rk, ek, sk, ck);
    }
    let rest = mt.len();
    if rest > 0 {
        // The tail, padded with (m, r) = (0, 0): the same code per lane.
        let mut mk = [0.0; LANES];
        let mut rk = [0.0; LANES];
        mk[..rest].copy_from_slice(mt);
        rk[..rest].copy_from_slice(rt);
        let (mut ek, mut sk, mut ck) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        big |= chunk::<FMA>(&mk, &rk, &mut ek, &mut sk, &mut ck);
        et.copy_from_slice(&ek[..rest]);
        st.copy_from_slice(&sk[..rest]);
        ct.copy_from_slice(&ck[..rest]);
    }
    big
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn body_avx2(m: &[f64], r: &[f64], e: &mut [f64], s: &mut [f64], c: &mut [f64]) -> bool {
    body::<true>(m, r, e, s, c)
}

/// `e[k] = exp(m[k])`, `s[k] = sin(r[k])`, `c[k] = cos(r[k])` for slices of
/// equal length (panics otherwise, once, at entry).
///
/// Domain: any `m` (performance matters for `m <= 0`): `m <= -745.14` and
/// `-inf` give 0, subnormal results are rounded correctly (or flushed to 0
/// when the caller runs with FTZ), `m >= 709.79` gives +inf, NaN gives NaN.
/// `r >= 0`: up to [`R_FAST`] on the vector path, larger (and +inf) by
/// `f64::sin_cos` in a scalar pass after it; `r = 0` gives exactly
/// `(0, 1)`.
///
/// Accuracy (both paths, see the module doc for how it was measured):
/// within 1 ulp of glibc's `exp` / `sin_cos` in ulps of the reference,
/// including `sin`/`cos` next to multiples of `pi/2`; against exact values
/// <= 0.64 ulp (`exp`, normal results), <= 0.80 ulp (`sin`), <= 0.75 ulp
/// (`cos`). The two paths round differently (FMA), each deterministically
/// and within 1 ulp of each other.
///
/// No allocation, no locks, no I/O. \[audio-thread\]
#[inline]
pub(crate) fn exp_sincos(
    path: SimdPath,
    m: &[f64],
    r: &[f64],
    e: &mut [f64],
    s: &mut [f64],
    c: &mut [f64],
) {
    let n = m.len();
    assert!(
        r.len() == n && e.len() == n && s.len() == n && c.len() == n,
        "exp_sincos: mismatched lengths"
    );
    let big = match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `detect()` makes, after
        // `is_x86_feature_detected!` confirmed AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(m, r, e, s, c) },
        _ => body::<false>(m, r, e, s, c),
    };
    if big {
        sincos_beyond_fast(r, s, c);
    }
}

/// The arguments above [`R_FAST`] (rare; +inf too), which the vector path
/// does not reduce: `f64::sin_cos` in a scalar pass.
fn sincos_beyond_fast(r: &[f64], s: &mut [f64], c: &mut [f64]) {
    for k in 0..r.len() {
        if r[k] > R_FAST {
            let (sk, ck) = r[k].sin_cos();
            s[k] = sk;
            c[k] = ck;
        }
    }
}

/// `e[k] = exp(m[k])`: [`exp_sincos`]'s exponentials alone, bit for bit
/// (the same lanes on the same path). Panics on unequal lengths.
/// \[audio-thread\]
#[inline]
pub(crate) fn exp_only(path: SimdPath, m: &[f64], e: &mut [f64]) {
    assert!(m.len() == e.len(), "exp_only: mismatched lengths");
    #[inline(always)]
    fn body<const FMA: bool>(m: &[f64], e: &mut [f64]) {
        let (mc, mt) = m.as_chunks::<LANES>();
        let (ec, et) = e.as_chunks_mut::<LANES>();
        for (mk, ek) in mc.iter().zip(ec) {
            for j in 0..LANES {
                ek[j] = exp_lane::<FMA>(mk[j]);
            }
        }
        for (x, y) in mt.iter().zip(et) {
            *y = exp_lane::<FMA>(*x);
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn body_avx2(m: &[f64], e: &mut [f64]) {
        body::<true>(m, e)
    }
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `detect()` makes, after
        // `is_x86_feature_detected!` confirmed AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(m, e) },
        _ => body::<false>(m, e),
    }
}

/// `s[k] = sin(r[k])`, `c[k] = cos(r[k])`: [`exp_sincos`]'s sines and
/// cosines alone, bit for bit (the same lanes on the same path, the same
/// scalar pass above [`R_FAST`]). Panics on unequal lengths.
/// \[audio-thread\]
#[inline]
pub(crate) fn sincos_only(path: SimdPath, r: &[f64], s: &mut [f64], c: &mut [f64]) {
    let n = r.len();
    assert!(
        s.len() == n && c.len() == n,
        "sincos_only: mismatched lengths"
    );
    #[inline(always)]
    fn body<const FMA: bool>(r: &[f64], s: &mut [f64], c: &mut [f64]) -> bool {
        // whole chunks of lanes without bounds checks, as `exp_sincos`'s
        let (rc, rt) = r.as_chunks::<LANES>();
        let (sc, st) = s.as_chunks_mut::<LANES>();
        let (cc, ct) = c.as_chunks_mut::<LANES>();
        let mut big = 0u64;
        for ((rk, sk), ck) in rc.iter().zip(sc).zip(cc) {
            for j in 0..LANES {
                (sk[j], ck[j]) = sincos_lane::<FMA>(rk[j]);
                big |= (rk[j] > R_FAST) as u64;
            }
        }
        for ((x, y), z) in rt.iter().zip(st).zip(ct) {
            (*y, *z) = sincos_lane::<FMA>(*x);
            big |= (*x > R_FAST) as u64;
        }
        big != 0
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn body_avx2(r: &[f64], s: &mut [f64], c: &mut [f64]) -> bool {
        body::<true>(r, s, c)
    }
    let big = match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `exp_only`.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(r, s, c) },
        _ => body::<false>(r, s, c),
    };
    if big {
        sincos_beyond_fast(r, s, c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_rng::TestRng as Rng;

    /// Log-uniform magnitude in [10^lo, 10^hi].
    fn log_uniform(g: &mut Rng, lo: f64, hi: f64) -> f64 {
        10f64.powf(g.uniform(lo, hi))
    }

    /// `|got - want|` in ulps of `want`: the spacing of doubles at `|want|`
    /// (`2^(e - 52)` for `want` in `[2^e, 2^(e+1))`, `2^-1074` for subnormal
    /// and zero `want`). This is the strict relative metric, with no floor:
    /// `sin` next to a multiple of `pi` is measured relative to its own tiny
    /// value, not to the argument's scale. Equal values (including infinities
    /// and signed zeros) are 0; NaN against non-NaN is infinite.
    fn ulp_err(got: f64, want: f64) -> f64 {
        if got == want || (got.is_nan() && want.is_nan()) {
            return 0.0;
        }
        if !got.is_finite() || !want.is_finite() {
            return f64::INFINITY;
        }
        let a = want.abs();
        let ulp = if a < f64::MIN_POSITIVE {
            f64::from_bits(1)
        } else {
            f64::from_bits(a.to_bits() & 0x7ff0_0000_0000_0000) * f64::EPSILON
        };
        (got - want).abs() / ulp
    }

    fn paths() -> Vec<SimdPath> {
        let mut p = vec![SimdPath::Generic];
        if let avx @ SimdPath::Avx2Fma(_) = SimdPath::detect() {
            p.push(avx);
        } else {
            println!("AVX2+FMA not available: only the generic path is tested");
        }
        p
    }

    /// Largest errors over a batch and the arguments where they occur, and
    /// how many results differ from the reference at all.
    #[derive(Default, Debug)]
    struct MaxErr {
        exp: (f64, f64),
        sin: (f64, f64),
        cos: (f64, f64),
        differ: [usize; 3],
    }

    fn run(path: SimdPath, m: &[f64], r: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = m.len();
        let (mut e, mut s, mut c) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        exp_sincos(path, m, r, &mut e, &mut s, &mut c);
        (e, s, c)
    }

    fn measure(path: SimdPath, m: &[f64], r: &[f64]) -> MaxErr {
        let (e, s, c) = run(path, m, r);
        let mut mx = MaxErr::default();
        for k in 0..m.len() {
            let ee = ulp_err(e[k], m[k].exp());
            mx.differ[0] += (ee != 0.0) as usize;
            if ee > mx.exp.0 || ee.is_nan() {
                mx.exp = (ee, m[k]);
            }
            let (rs, rc) = r[k].sin_cos();
            let es = ulp_err(s[k], rs);
            mx.differ[1] += (es != 0.0) as usize;
            if es > mx.sin.0 || es.is_nan() {
                mx.sin = (es, r[k]);
            }
            let ec = ulp_err(c[k], rc);
            mx.differ[2] += (ec != 0.0) as usize;
            if ec > mx.cos.0 || ec.is_nan() {
                mx.cos = (ec, r[k]);
            }
        }
        mx
    }

    fn check(label: &str, path: SimdPath, m: &[f64], r: &[f64]) {
        let mx = measure(path, m, r);
        println!(
            "{label} [{}], {} args: max ulp exp {:.3} (m = {:e}), sin {:.3} (r = {:e}), cos {:.3} (r = {:e})",
            path.name(),
            m.len(),
            mx.exp.0,
            mx.exp.1,
            mx.sin.0,
            mx.sin.1,
            mx.cos.0,
            mx.cos.1
        );
        let pct = |d: usize| 100.0 * d as f64 / m.len().max(1) as f64;
        println!(
            "    results differing from glibc: exp {:.3}%, sin {:.3}%, cos {:.3}%",
            pct(mx.differ[0]),
            pct(mx.differ[1]),
            pct(mx.differ[2])
        );
        assert!(mx.exp.0 <= 2.0, "{label} {path:?}: exp error {mx:?}");
        assert!(mx.sin.0 <= 2.0, "{label} {path:?}: sin error {mx:?}");
        assert!(mx.cos.0 <= 2.0, "{label} {path:?}: cos error {mx:?}");
    }

    /// ~1e6 random arguments (an odd count: the padded tail runs too).
    fn random_args(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut g = Rng(seed);
        let mut m = Vec::with_capacity(n);
        let mut r = Vec::with_capacity(n);
        for _ in 0..n {
            let u = g.unit();
            m.push(if u < 0.3 {
                -g.uniform(0.0, 800.0)
            } else if u < 0.6 {
                -log_uniform(&mut g, -300.0, 800f64.log10())
            } else if u < 0.85 {
                -g.uniform(0.0, 20.0)
            } else if u < 0.9 {
                // results around and below f64::MIN_POSITIVE
                g.uniform(-745.3, -707.0)
            } else {
                g.uniform(0.0, 709.0)
            });
            let u = g.unit();
            r.push(if u < 0.5 {
                g.uniform(0.0, 20.0)
            } else if u < 0.7 {
                log_uniform(&mut g, -300.0, 5.0)
            } else if u < 0.85 {
                g.uniform(0.0, 1e5)
            } else if u < 0.97 {
                g.uniform(0.0, R_FAST)
            } else {
                // the scalar fall-back
                log_uniform(&mut g, R_FAST.log10(), 9.0)
            });
        }
        (m, r)
    }

    /// The exponentials alone and the sines and cosines alone are
    /// `exp_sincos`'s bit for bit, on both paths, at every length (tails
    /// included) and above `R_FAST`.
    #[test]
    fn exp_only_and_sincos_only_are_exp_sincos_bit_for_bit() {
        let (mut m, mut r) = random_args(4099, 0x5eed_0007);
        r[17] = 3.0 * R_FAST;
        r[4000] = f64::INFINITY;
        m[5] = -800.0;
        for path in paths() {
            for n in (0..=20).chain([1000, 4099]) {
                let (mut e, mut sn, mut cs) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                exp_sincos(path, &m[..n], &r[..n], &mut e, &mut sn, &mut cs);
                let mut e1 = vec![0.0; n];
                exp_only(path, &m[..n], &mut e1);
                let (mut s1, mut c1) = (vec![0.0; n], vec![0.0; n]);
                sincos_only(path, &r[..n], &mut s1, &mut c1);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&e), bits(&e1), "exp, n = {n}");
                assert_eq!(bits(&sn), bits(&s1), "sin, n = {n}");
                assert_eq!(bits(&cs), bits(&c1), "cos, n = {n}");
            }
        }
    }

    #[test]
    fn random_arguments_within_2_ulp() {
        let (m, r) = random_args((1 << 20) + 5, 0x5eed_0001);
        for path in paths() {
            check("random", path, &m, &r);
        }
    }

    /// The double nearest to `k pi/2 * scale` (`scale` a power of two), from
    /// the exact products `k pio2_i`.
    fn near_multiple(k: f64, scale: f64) -> f64 {
        let hi = k * PIO2_1 * scale;
        let lo = (k * PIO2_2 + (k * PIO2_3 + k * PIO2_3T)) * scale;
        hi + lo
    }

    #[test]
    fn near_multiples_of_pi_within_2_ulp() {
        // Multiples of pi/4 up to 1e5 with neighbours +-2 ulp (the sin roots
        // are the multiples of pi, the cos roots the odd multiples of pi/2).
        let mut r = Vec::new();
        let kmax = (1e5 / std::f64::consts::FRAC_PI_4) as u64;
        for k in 0..=kmax {
            let x = near_multiple(k as f64, 0.5);
            r.extend([
                x.next_down().next_down(),
                x.next_down(),
                x,
                x.next_up(),
                x.next_up().next_up(),
            ]);
        }
        // Every multiple of pi/2 up to R_FAST (the hardest reductions of all
        // doubles below R_FAST are among these) with neighbours +-1 ulp.
        let kmax = (R_FAST / std::f64::consts::FRAC_PI_2) as u64;
        for k in 1..=kmax {
            let x = near_multiple(k as f64, 1.0);
            r.extend([x.next_down(), x, x.next_up()]);
        }
        let r: Vec<f64> = r
            .into_iter()
            .filter(|x| (0.0..=R_FAST).contains(x))
            .collect();
        let mut g = Rng(7);
        let m: Vec<f64> = r.iter().map(|_| -g.uniform(0.0, 30.0)).collect();
        for path in paths() {
            check("multiples of pi/4", path, &m, &r);
        }
    }

    #[test]
    fn edge_cases_within_2_ulp() {
        use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, LN_2, PI};
        let mut m = vec![
            0.0,
            -0.0,
            -1e-300,
            -5e-324,
            1e-300,
            5e-324,
            -1e-17,
            -745.2,
            -745.1332191019411,
            -745.1332191019412,
            -745.0,
            -744.4,
            -708.4,
            -708.3964185322641,
            -708.0,
            -1e308,
            -f64::MAX,
            f64::NEG_INFINITY,
            -0.5 * LN_2,
            0.5 * LN_2,
            709.0,
            709.782712893384,
            709.7827128933841,
            1e308,
            f64::INFINITY,
        ];
        // Multiples and half-multiples of ln 2 (reduction boundaries), with
        // neighbours.
        for k in -2200..=2048 {
            let x = k as f64 * 0.5 * LN_2;
            if x > -746.0 && x < 709.7 {
                m.extend([x.next_down(), x, x.next_up()]);
            }
        }
        let mut r = vec![
            0.0,
            -0.0,
            1e-300,
            5e-324,
            1e-17,
            1e-8,
            FRAC_PI_4,
            FRAC_PI_4.next_up(),
            FRAC_PI_4.next_down(),
            FRAC_PI_2,
            PI,
            1.0,
            10.0,
            1e5,
            R_FAST,
            R_FAST.next_up(),
            1e20,
            f64::MAX,
        ];
        // Odd multiples of pi/4 (reduced argument +-pi/4: the kernel's edge).
        for k in 0..2000 {
            let x = near_multiple((2 * k + 1) as f64, 0.5);
            r.extend([x.next_down(), x, x.next_up()]);
        }
        let n = m.len().max(r.len());
        let m: Vec<f64> = m.iter().cycle().take(n).copied().collect();
        let r: Vec<f64> = r.iter().cycle().take(n).copied().collect();
        for path in paths() {
            check("edge cases", path, &m, &r);
            let (e, s, c) = run(path, &[0.0, f64::NEG_INFINITY, -745.2, -1e308], &[0.0; 4]);
            assert_eq!(e, [1.0, 0.0, 0.0, 0.0]);
            assert_eq!(s, [0.0; 4]);
            assert_eq!(c, [1.0; 4]);
            let (e, s, c) = run(path, &[f64::NAN, 710.0], &[f64::INFINITY, f64::NAN]);
            assert!(e[0].is_nan() && e[1] == f64::INFINITY);
            assert!(s.iter().chain(&c).all(|x| x.is_nan()));
        }
    }

    #[test]
    fn generic_and_avx2_agree_closely() {
        let SimdPath::Avx2Fma(avx) = SimdPath::detect() else {
            println!("AVX2+FMA not available: nothing to compare");
            return;
        };
        let (m, r) = random_args(1 << 18, 0x5eed_0002);
        let (e0, s0, c0) = run(SimdPath::Generic, &m, &r);
        let (e1, s1, c1) = run(SimdPath::Avx2Fma(avx), &m, &r);
        let mut worst = [0.0f64; 3];
        for k in 0..m.len() {
            worst[0] = worst[0].max(ulp_err(e1[k], e0[k]));
            worst[1] = worst[1].max(ulp_err(s1[k], s0[k]));
            worst[2] = worst[2].max(ulp_err(c1[k], c0[k]));
        }
        println!(
            "avx2 vs generic: max ulp exp {:.3}, sin {:.3}, cos {:.3}",
            worst[0], worst[1], worst[2]
        );
        assert!(worst.iter().all(|&w| w <= 2.0), "{worst:?}");
    }

    #[test]
    fn any_length_matches_elementwise() {
        let (m, r) = random_args(40, 0x5eed_0003);
        for path in paths() {
            for n in 0..=m.len() {
                let (e, s, c) = run(path, &m[..n], &r[..n]);
                for k in 0..n {
                    let (e1, s1, c1) = run(path, &m[k..k + 1], &r[k..k + 1]);
                    assert_eq!(e[k].to_bits(), e1[0].to_bits());
                    assert_eq!(s[k].to_bits(), s1[0].to_bits());
                    assert_eq!(c[k].to_bits(), c1[0].to_bits());
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "mismatched lengths")]
    fn mismatched_lengths_panic() {
        let mut out = [0.0; 2];
        let (mut s, mut c) = ([0.0; 3], [0.0; 3]);
        exp_sincos(
            SimdPath::Generic,
            &[0.0; 3],
            &[0.0; 3],
            &mut out,
            &mut s,
            &mut c,
        );
    }
}
