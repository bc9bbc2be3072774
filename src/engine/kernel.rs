//! The per-sample kernels, laid out for the machine: block propagators and
//! state in structure-of-arrays form (block `k` is `(s[k], s[nb + k])`),
//! chunked by 4 so LLVM emits 256-bit vector code, one fused pass that steps
//! the state and evaluates every row the next sample needs.
//!
//! A plugin binary must run on any x86-64, so AVX2+FMA is chosen at run time
//! (`is_x86_feature_detected!`), never assumed at compile time: the same body
//! is compiled twice, once inside a `#[target_feature(enable = "avx2,fma")]`
//! function (with fused multiply-adds) and once for the baseline target.

/// Which kernel variant runs on this machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimdPath {
    /// AVX2 with FMA (x86-64, detected at run time).
    Avx2Fma,
    /// Portable code for the baseline target (SSE2 on x86-64).
    Generic,
}

impl SimdPath {
    /// Detect the best path for this CPU.
    pub fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                return SimdPath::Avx2Fma;
            }
        }
        SimdPath::Generic
    }
    /// Human-readable name (benchmarks print it).
    pub fn name(self) -> &'static str {
        match self {
            SimdPath::Avx2Fma => "avx2+fma (runtime-detected)",
            SimdPath::Generic => "generic (baseline target)",
        }
    }
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
    /// No blocks.
    pub fn is_empty(&self) -> bool {
        self.p00.is_empty()
    }
    /// Store block `k`.
    #[inline]
    pub fn set(&mut self, k: usize, p: &[f64; 4]) {
        self.p00[k] = p[0];
        self.p01[k] = p[1];
        self.p10[k] = p[2];
        self.p11[k] = p[3];
    }
    /// Block `k`.
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

/// Result of a fused step: `[ev . next, l . next, r . next, |s|^2]`.
pub type Fused = [f64; 4];

#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

const LANES: usize = 4;

#[inline(always)]
fn fused_body<const FMA: bool>(p: &BlockProps, s: &[f64], next: &mut [f64], rows: &Rows) -> Fused {
    let nb = p.len();
    // Re-slice every stream to exactly `nb` so the bounds checks vanish and
    // LLVM can keep the four lanes of each accumulator in one vector register.
    let (sa, sb) = s.split_at(nb);
    let sb = &sb[..nb];
    let (na, nbv) = next.split_at_mut(nb);
    let nbv = &mut nbv[..nb];
    let (ea, eb) = rows.ev.split_at(nb);
    let eb = &eb[..nb];
    let (la, lb) = rows.l.split_at(nb);
    let lb = &lb[..nb];
    let (ra, rb) = rows.r.split_at(nb);
    let rb = &rb[..nb];
    let (p00, p01, p10, p11) = (&p.p00[..nb], &p.p01[..nb], &p.p10[..nb], &p.p11[..nb]);
    let mut acc_e = [0.0f64; LANES];
    let mut acc_l = [0.0f64; LANES];
    let mut acc_r = [0.0f64; LANES];
    let mut acc_n = [0.0f64; LANES];
    let chunks = nb / LANES;
    for c in 0..chunks {
        let base = c * LANES;
        for j in 0..LANES {
            let k = base + j;
            let a = sa[k];
            let b = sb[k];
            let x0 = madd::<FMA>(p00[k], a, p01[k] * b);
            let x1 = madd::<FMA>(p10[k], a, p11[k] * b);
            na[k] = x0;
            nbv[k] = x1;
            acc_e[j] = madd::<FMA>(ea[k], x0, madd::<FMA>(eb[k], x1, acc_e[j]));
            acc_l[j] = madd::<FMA>(la[k], x0, madd::<FMA>(lb[k], x1, acc_l[j]));
            acc_r[j] = madd::<FMA>(ra[k], x0, madd::<FMA>(rb[k], x1, acc_r[j]));
            acc_n[j] = madd::<FMA>(a, a, madd::<FMA>(b, b, acc_n[j]));
        }
    }
    let sum = |v: [f64; LANES]| (v[0] + v[1]) + (v[2] + v[3]);
    let mut out = [sum(acc_e), sum(acc_l), sum(acc_r), sum(acc_n)];
    for k in chunks * LANES..nb {
        let a = sa[k];
        let b = sb[k];
        let x0 = p00[k] * a + p01[k] * b;
        let x1 = p10[k] * a + p11[k] * b;
        na[k] = x0;
        nbv[k] = x1;
        out[0] += ea[k] * x0 + eb[k] * x1;
        out[1] += la[k] * x0 + lb[k] * x1;
        out[2] += ra[k] * x0 + rb[k] * x1;
        out[3] += a * a + b * b;
    }
    out
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn fused_avx2(p: &BlockProps, s: &[f64], next: &mut [f64], rows: &Rows) -> Fused {
    fused_body::<true>(p, s, next, rows)
}

fn fused_generic(p: &BlockProps, s: &[f64], next: &mut [f64], rows: &Rows) -> Fused {
    fused_body::<false>(p, s, next, rows)
}

/// `next = P s` for all blocks, and the rows of `next` plus `|s|^2`, in one
/// pass. O(N), allocation-free. [audio-thread]
#[inline]
pub fn fused_step(
    path: SimdPath,
    p: &BlockProps,
    s: &[f64],
    next: &mut [f64],
    rows: &Rows,
) -> Fused {
    debug_assert_eq!(s.len(), 2 * p.len());
    debug_assert_eq!(next.len(), s.len());
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` is only produced by `detect()` after
        // `is_x86_feature_detected!` confirmed AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma => unsafe { fused_avx2(p, s, next, rows) },
        _ => fused_generic(p, s, next, rows),
    }
}

/// `[ev . s, l . s, r . s]` (no step). O(N). [audio-thread]
#[inline]
pub fn rows_of(s: &[f64], rows: &Rows) -> [f64; 3] {
    let mut out = [0.0; 3];
    for k in 0..s.len() {
        out[0] += rows.ev[k] * s[k];
        out[1] += rows.l[k] * s[k];
        out[2] += rows.r[k] * s[k];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn avx2_and_generic_paths_agree() {
        let nb = 37; // not a multiple of the lane count
        let mut p = BlockProps::new(nb);
        let mut s = vec![0.0; 2 * nb];
        let mut rows_v = vec![vec![0.0; 2 * nb]; 3];
        for k in 0..nb {
            let th = 0.1 * k as f64;
            p.set(
                k,
                &[
                    0.99 * th.cos(),
                    0.99 * th.sin(),
                    -0.99 * th.sin(),
                    0.99 * th.cos(),
                ],
            );
            s[k] = (k as f64).sin();
            s[nb + k] = (k as f64 * 0.7).cos();
        }
        for (i, r) in rows_v.iter_mut().enumerate() {
            for (k, x) in r.iter_mut().enumerate() {
                *x = ((i + 1) * k) as f64 * 1e-2 - 0.3;
            }
        }
        let rows = Rows {
            ev: &rows_v[0],
            l: &rows_v[1],
            r: &rows_v[2],
        };
        let mut n1 = vec![0.0; 2 * nb];
        let mut n2 = vec![0.0; 2 * nb];
        let a = fused_step(SimdPath::detect(), &p, &s, &mut n1, &rows);
        let b = fused_step(SimdPath::Generic, &p, &s, &mut n2, &rows);
        println!("path {}", SimdPath::detect().name());
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-13 * y.abs().max(1.0), "{x} vs {y}");
        }
        for (x, y) in n1.iter().zip(&n2) {
            assert!((x - y).abs() <= 1e-15 * y.abs().max(1.0));
        }
        // and against a plain reference
        let mut ev = 0.0;
        for k in 0..nb {
            let x0 = p.p00[k] * s[k] + p.p01[k] * s[nb + k];
            let x1 = p.p10[k] * s[k] + p.p11[k] * s[nb + k];
            ev += rows.ev[k] * x0 + rows.ev[nb + k] * x1;
        }
        assert!((ev - b[0]).abs() < 1e-12);
    }
}
