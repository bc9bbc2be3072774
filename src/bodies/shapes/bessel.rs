//! Bessel functions of the first kind `J_m` and their positive zeros
//! `j_mn`, for the circular membrane (`membrane.rs`) and its radiation.
//!
//! `J_m(x)` (integer `m >= 0`, `x >= 0`): power series `sum_k (-1)^k
//! (x/2)^(2k+m) / (k! (k+m)!)` for `x < 1`; otherwise Miller's backward
//! recurrence `J_{k-1} = (2k / x) J_k - J_{k+1}` from `N = max(m+1, x) +
//! sqrt(160 max(m+1, x)) + 20` (even), normalised by `J_0 + 2 sum J_{2k} =
//! 1` (absolute accuracy ~1e-14). Zeros: the first zero exceeds `m`;
//! consecutive zeros are more than 3 apart, so from `max(m, 1)` (or the
//! previous zero + 3) a scan in steps of 0.5 brackets exactly one sign
//! change, which Newton's method (`J_m' = (m / x) J_m - J_{m+1}`),
//! safeguarded by bisection, polishes to a few ulp.

use super::search::safeguarded_newton;

/// Power series of `J_m(x)` (accurate for small `x`).
fn bessel_j_series(m: usize, x: f64) -> f64 {
    let h = 0.5 * x;
    let mut term = 1.0;
    for k in 1..=m {
        term *= h / k as f64;
    }
    let mut sum = term;
    let h2 = h * h;
    for k in 1..200 {
        term *= -h2 / (k as f64 * (k + m) as f64);
        sum += term;
        if term.abs() <= 1e-17 * sum.abs() {
            break;
        }
    }
    sum
}

/// `(J_m(x), J_{m+1}(x))` for `x >= 0`.
pub(super) fn bessel_j_pair(m: usize, x: f64) -> (f64, f64) {
    if x == 0.0 {
        return (if m == 0 { 1.0 } else { 0.0 }, 0.0);
    }
    if x < 1.0 {
        return (bessel_j_series(m, x), bessel_j_series(m + 1, x));
    }
    // Miller's backward recurrence from an even order well above max(m, x).
    let top = ((m + 1) as f64).max(x);
    let mut start = (top + (160.0 * top).sqrt() + 20.0).ceil() as usize;
    start += start % 2;
    let (mut a, mut b) = (0.0f64, 1.0f64); // J_{k+1}, J_k (unnormalised)
    let (mut jm, mut jm1) = (0.0, 0.0);
    let mut sum = 0.0;
    for k in (1..=start).rev() {
        let c = 2.0 * k as f64 / x * b - a; // J_{k-1}
        a = b;
        b = c;
        let order = k - 1;
        if order == m + 1 {
            jm1 = b;
        }
        if order == m {
            jm = b;
        }
        if order == 0 {
            sum += b;
        } else if order % 2 == 0 {
            sum += 2.0 * b;
        }
        if b.abs() > 1e200 {
            a *= 1e-200;
            b *= 1e-200;
            sum *= 1e-200;
            jm *= 1e-200;
            jm1 *= 1e-200;
        }
    }
    (jm / sum, jm1 / sum)
}

/// Bessel function of the first kind `J_m(x)`, integer `m >= 0`, `x >= 0`
/// (series below 1, Miller's backward recurrence above; absolute error
/// ~1e-14 near the zeros). `x < 0` uses `J_m(-x) = (-1)^m J_m(x)`; NaN
/// gives NaN.
pub fn bessel_j(m: usize, x: f64) -> f64 {
    if x < 0.0 {
        let v = bessel_j_pair(m, -x).0;
        return if m.is_multiple_of(2) { v } else { -v };
    }
    bessel_j_pair(m, x).0
}

/// Successive positive zeros of `J_m`.
pub(super) struct BesselZeros {
    m: usize,
    next_start: f64,
}

impl BesselZeros {
    pub(super) fn new(m: usize) -> Self {
        BesselZeros {
            m,
            next_start: (m as f64).max(1.0),
        }
    }

    pub(super) fn next_zero(&mut self) -> Result<f64, String> {
        let m = self.m;
        let f = |x: f64| bessel_j_pair(m, x).0;
        let df = |x: f64| {
            let (j, j1) = bessel_j_pair(m, x);
            m as f64 / x * j - j1
        };
        let h = 0.5;
        let mut x0 = self.next_start;
        let mut f0 = f(x0);
        for _ in 0..1_000_000 {
            let x1 = x0 + h;
            let f1 = f(x1);
            if f0 == 0.0 || (f0 < 0.0) != (f1 < 0.0) {
                let root = if f0 == 0.0 {
                    x0
                } else {
                    safeguarded_newton(f, df, x0, x1, 0.5 * (x0 + x1))
                };
                self.next_start = root + 3.0;
                return Ok(root);
            }
            x0 = x1;
            f0 = f1;
        }
        Err(format!("bessel zero of J_{m}: no sign change found"))
    }
}

/// `j_mn`, the `n`-th (from 1) positive zero of `J_m`.
pub fn bessel_j_zero(m: usize, n: usize) -> Result<f64, String> {
    if n == 0 {
        return Err("bessel_j_zero: n counts from 1, got 0".to_string());
    }
    let mut z = BesselZeros::new(m);
    let mut x = 0.0;
    for _ in 0..n {
        x = z.next_zero()?;
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    #[test]
    fn bessel_values_against_reference_and_series() {
        // Abramowitz & Stegun table 9.1 values.
        for (m, x, want) in [
            (0, 1.0, 0.765_197_686_557_966_6),
            (1, 1.0, 0.440_050_585_744_933_5),
            (0, 10.0, -0.245_935_764_451_348_3),
            (1, 10.0, 0.043_472_746_168_861_44),
            (0, 0.5, 0.938_469_807_240_813),
        ] {
            let v = bessel_j(m, x);
            println!("J_{m}({x}) = {v:.16}, residual {:.1e}", v - want);
            assert!((v - want).abs() < 2e-15, "{v}");
        }
        // Miller against the series (mild cancellation below x = 8).
        let mut worst: f64 = 0.0;
        for m in 0..12 {
            for i in 0..40 {
                let x = 1.0 + 0.175 * i as f64;
                worst = worst.max((bessel_j(m, x) - bessel_j_series(m, x)).abs());
            }
        }
        println!("Miller vs series on [1, 8], m < 12: max |diff| {worst:.1e}");
        assert!(worst < 1e-13);
        // The normalisation identity at large x, and continuity at x = 1.
        let x = 150.0;
        let s: f64 = bessel_j(0, x) + 2.0 * (1..200).map(|k| bessel_j(2 * k, x)).sum::<f64>();
        assert!((s - 1.0).abs() < 1e-13);
        assert!((bessel_j(3, 1.0 - 1e-12) - bessel_j(3, 1.0)).abs() < 1e-13);
    }

    #[test]
    fn bessel_zeros_match_the_published_table() {
        // Abramowitz & Stegun table 9.5.
        let table = [
            (0, 1, 2.404_825_557_695_773),
            (0, 2, 5.520_078_110_286_311),
            (0, 3, 8.653_727_912_911_013),
            (1, 1, 3.831_705_970_207_512),
            (1, 2, 7.015_586_669_815_619),
            (2, 1, 5.135_622_301_840_683),
            (2, 2, 8.417_244_140_399_865),
            (3, 1, 6.380_161_895_923_984),
            (4, 1, 7.588_342_434_503_804),
        ];
        for (m, n, want) in table {
            let z = bessel_j_zero(m, n).unwrap();
            println!("j_{m}{n} = {z:.15}, residual {:.1e}", z - want);
            assert!((z - want).abs() < 1e-13, "{z}");
        }
        // Far zeros against McMahon's expansion (error O(beta^-7) ~ 1e-13).
        for m in [0usize, 1, 2] {
            let n = 30;
            let beta = (n as f64 + m as f64 / 2.0 - 0.25) * PI;
            let mu = 4.0 * (m * m) as f64;
            let b8 = 8.0 * beta;
            let mc = beta
                - (mu - 1.0) / b8
                - 4.0 * (mu - 1.0) * (7.0 * mu - 31.0) / (3.0 * b8.powi(3))
                - 32.0 * (mu - 1.0) * (83.0 * mu * mu - 982.0 * mu + 3779.0) / (15.0 * b8.powi(5));
            let z = bessel_j_zero(m, n).unwrap();
            println!("j_{m},{n} = {z:.13}, McMahon residual {:.1e}", z - mc);
            assert!((z - mc).abs() < 1e-10);
        }
        assert!(bessel_j_zero(0, 0).is_err());
    }
}
