//! Double-double arithmetic (a value is the unevaluated sum `hi + lo` of two
//! f64, ~106 bits) for the reference's propagators and exact states.
//!
//! Why: in physical coordinates a stiff contact phase has `|B|` far above
//! the slow motions' rates (up to 1e9 1/s against 1e3), and any product of
//! f64 propagators carries an error ~`u |B| t`: 1e-11 per sample at 1000x
//! Nyquist, which ill-conditioned releases (an overdamped contact lets go
//! when `p = x_c - x_h`, a small difference, returns to zero at a small
//! `p'`) turn into 1e-6 samples after a few dozen contacts. In double-double
//! that error is ~1e-27, and what remains is the final rounding to f64.
//! The phase matrices' entries are double-double too (see
//! [`crate::phase::augmented_matrix`]): rounded to f64 they change the
//! contact force, a small difference of their products with the state.
//!
//! The error-free transformations are the classical ones (Knuth's two-sum,
//! the product's rounding error by a fused multiply-add).

use std::ops::{Add, Mul, Neg, Sub};

/// `hi + lo` with `|lo| <= ulp(hi) / 2`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Dd {
    pub(crate) hi: f64,
    pub(crate) lo: f64,
}

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

#[inline]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

#[inline]
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

impl Dd {
    pub(crate) const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };
    pub(crate) const ONE: Dd = Dd { hi: 1.0, lo: 0.0 };

    #[inline]
    pub(crate) fn from_f64(x: f64) -> Dd {
        Dd { hi: x, lo: 0.0 }
    }

    /// Nearest f64.
    #[inline]
    pub(crate) fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    /// `self * b` for an f64 `b`.
    #[inline]
    pub(crate) fn mul_f64(self, b: f64) -> Dd {
        let (p, e) = two_prod(self.hi, b);
        let (hi, lo) = quick_two_sum(p, e + self.lo * b);
        Dd { hi, lo }
    }

    /// `self / b` for an f64 `b`.
    #[inline]
    pub(crate) fn div_f64(self, b: f64) -> Dd {
        let q1 = self.hi / b;
        let (p, e) = two_prod(q1, b);
        let (s, f) = two_sum(self.hi, -p);
        let q2 = (s + (f - e + self.lo)) / b;
        let (hi, lo) = quick_two_sum(q1, q2);
        Dd { hi, lo }
    }

    #[inline]
    pub(crate) fn abs(self) -> f64 {
        self.to_f64().abs()
    }
}

impl Add for Dd {
    type Output = Dd;
    #[inline]
    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, o.hi);
        let (t, f) = two_sum(self.lo, o.lo);
        let (s, e) = quick_two_sum(s, e + t);
        let (hi, lo) = quick_two_sum(s, e + f);
        Dd { hi, lo }
    }
}

impl Neg for Dd {
    type Output = Dd;
    #[inline]
    fn neg(self) -> Dd {
        Dd {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Sub for Dd {
    type Output = Dd;
    #[inline]
    fn sub(self, o: Dd) -> Dd {
        self + (-o)
    }
}

impl Mul for Dd {
    type Output = Dd;
    #[inline]
    fn mul(self, o: Dd) -> Dd {
        let (p, e) = two_prod(self.hi, o.hi);
        let (hi, lo) = quick_two_sum(p, e + (self.hi * o.lo + self.lo * o.hi));
        Dd { hi, lo }
    }
}

/// A square matrix of [`Dd`], row-major.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DdMat {
    pub(crate) n: usize,
    pub(crate) a: Vec<Dd>,
}

impl DdMat {
    pub(crate) fn identity(n: usize) -> DdMat {
        let mut a = vec![Dd::ZERO; n * n];
        for i in 0..n {
            a[i * n + i] = Dd::ONE;
        }
        DdMat { n, a }
    }

    /// `self * o`.
    pub(crate) fn mul(&self, o: &DdMat) -> DdMat {
        let n = self.n;
        let mut a = vec![Dd::ZERO; n * n];
        for i in 0..n {
            for k in 0..n {
                let x = self.a[i * n + k];
                if x.hi == 0.0 {
                    continue;
                }
                for j in 0..n {
                    a[i * n + j] = a[i * n + j] + x * o.a[k * n + j];
                }
            }
        }
        DdMat { n, a }
    }

    /// `self * y`.
    pub(crate) fn apply(&self, y: &[Dd]) -> Vec<Dd> {
        let n = self.n;
        (0..n)
            .map(|i| {
                let row = &self.a[i * n..(i + 1) * n];
                row.iter().zip(y).fold(
                    Dd::ZERO,
                    |acc, (m, v)| if m.hi == 0.0 { acc } else { acc + *m * *v },
                )
            })
            .collect()
    }

    /// Largest entry magnitude.
    pub(crate) fn max_abs(&self) -> f64 {
        self.a.iter().map(|x| x.abs()).fold(0.0, f64::max)
    }

    /// Nearest f64 matrix, row-major.
    pub(crate) fn to_f64(&self) -> Vec<f64> {
        self.a.iter().map(|x| x.to_f64()).collect()
    }
}

/// Terms of a Taylor series below this fraction of the sum are dropped
/// (below the double-double rounding, 2^-106 = 1.2e-32).
const TAYLOR_TOL: f64 = 1e-34;

/// `exp(B tau)` by its Taylor series in double-double, for `|B tau|_1 <=
/// ~0.5` (then 25 terms reach 1e-34). `b` is double-double, row-major, `n x
/// n` (the phase matrices' entries are exact sums and products of the
/// model's numbers, see [`crate::phase::augmented_matrix`]).
pub(crate) fn exp_taylor(b: &[Dd], n: usize, tau: f64) -> DdMat {
    let x = DdMat {
        n,
        a: b.iter().map(|v| v.mul_f64(tau)).collect(),
    };
    let mut sum = DdMat::identity(n);
    let mut term = DdMat::identity(n);
    for k in 1..200 {
        term = term.mul(&x);
        for t in &mut term.a {
            *t = t.div_f64(k as f64);
        }
        for (s, t) in sum.a.iter_mut().zip(&term.a) {
            *s = *s + *t;
        }
        if term.max_abs() <= TAYLOR_TOL * sum.max_abs() {
            break;
        }
    }
    sum
}

/// `exp(B tau) y` by the Taylor series applied to the vector (no matrix
/// products: for one-off partial steps), same range as [`exp_taylor`].
pub(crate) fn exp_taylor_apply(b: &[Dd], tau: f64, y: &[Dd]) -> Vec<Dd> {
    let n = y.len();
    let mut sum = y.to_vec();
    let mut term = y.to_vec();
    for k in 1..200 {
        let next: Vec<Dd> =
            (0..n)
                .map(|i| {
                    let row = &b[i * n..(i + 1) * n];
                    row.iter().zip(&term).fold(Dd::ZERO, |acc, (m, v)| {
                        if m.hi == 0.0 {
                            acc
                        } else {
                            acc + *m * *v
                        }
                    })
                })
                .map(|v| v.mul_f64(tau).div_f64(k as f64))
                .collect();
        term = next;
        let mut tmax: f64 = 0.0;
        for (s, t) in sum.iter_mut().zip(&term) {
            *s = *s + *t;
            tmax = tmax.max(t.abs());
        }
        let smax = sum.iter().map(|x| x.abs()).fold(0.0, f64::max);
        if tmax <= TAYLOR_TOL * smax {
            break;
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dd(v: &[f64]) -> Vec<Dd> {
        v.iter().map(|&x| Dd::from_f64(x)).collect()
    }

    /// The double-double basics and the Taylor exponential of a rotation
    /// (exact: cos, sin) and of a decay (exact: e^-t), to ~1e-31.
    #[test]
    fn double_double_exp_is_exact() {
        let third = Dd::ONE.div_f64(3.0);
        let err = (third.mul_f64(3.0) - Dd::ONE).to_f64().abs();
        assert!(err < 1e-31, "1/3 * 3 - 1 = {err:e}");
        // rotation by 0.5 rad: exp([[0, w], [-w, 0]] t)
        let e = exp_taylor(&dd(&[0.0, 1.0, -1.0, 0.0]), 2, 0.5);
        let c_err = (e.a[0].hi - 0.5f64.cos()).abs();
        let s_err = (e.a[1].hi - 0.5f64.sin()).abs();
        assert!(c_err < 2e-16 && s_err < 2e-16, "{c_err:e} {s_err:e}");
        // cos^2 + sin^2 = 1 in double-double
        let one = e.a[0] * e.a[0] + e.a[1] * e.a[1];
        let err = (one - Dd::ONE).to_f64().abs();
        println!("double-double rotation: |cos^2 + sin^2 - 1| = {err:.1e}");
        assert!(err < 1e-30, "{err:e}");
        // the vector form agrees with the matrix form
        let v = exp_taylor_apply(&dd(&[0.0, 1.0, -1.0, 0.0]), 0.5, &[Dd::ONE, Dd::ZERO]);
        let err = (v[0] - e.a[0])
            .to_f64()
            .abs()
            .max((v[1] - e.a[2]).to_f64().abs());
        assert!(err < 1e-31, "{err:e}");
        // e^-0.5 * e^0.5 = 1
        let d = exp_taylor(&dd(&[-1.0]), 1, 0.5).a[0] * exp_taylor(&dd(&[1.0]), 1, 0.5).a[0];
        let err = (d - Dd::ONE).to_f64().abs();
        println!("double-double decay: |e^-t e^t - 1| = {err:.1e}");
        assert!(err < 1e-30, "{err:e}");
    }
}
