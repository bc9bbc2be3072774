//! Exact exponential of a real 2x2 generator: the per-block propagator.
//!
//! Every phase of the engine is advanced in a real block-diagonal form with
//! 2x2 blocks `G_k` (a complex pair `a +- ib` gives `[[a, b], [-b, a]]`, two real
//! eigenvalues give `diag(l1, l2)`, a modal object's mode gives
//! `[[0, w], [-w, -2 sigma]]`). The propagator over a time `t` is `exp(G t)`,
//! computed here in closed form:
//!
//! `exp(M) = e^m (cosh(r) I + sinh(r)/r N)`, with `m = tr(M)/2`, `N = M - m I`,
//! `N^2 = delta I`, `delta = ((a - d)/2)^2 + b c`, `r = sqrt(delta)`
//! (Putzer / Cayley-Hamilton for 2x2; for `delta < 0` cosh and sinh become
//! cos and sin). The expression is an entire function of `delta`, so it stays
//! exact through critical damping (`delta = 0`, a Jordan block), where the
//! eigenvector route breaks down (NUMERICS.md section 2, P-E1).

/// A real 2x2 matrix stored row-major `[m11, m12, m21, m22]`.
pub type Mat2 = [f64; 4];

/// Below this |delta| the series of cosh(r) and sinh(r)/r is used: the
/// truncation error of three terms is below |delta|^4/8! ~ 2.5e-17 there.
const SERIES_DELTA: f64 = 1e-3;

/// `exp(g * t)` for a real 2x2 generator `g`, exact to rounding.
///
/// Overflow-safe for strongly overdamped blocks: with real eigenvalues it uses
/// `e^{m+r}` and `e^{m-r}` (each <= 1 for a passive block) rather than the
/// product of `e^m` and `cosh(r)` (which overflows to inf * 0 = NaN).
pub fn exp2(g: &Mat2, t: f64) -> Mat2 {
    let a = g[0] * t;
    let b = g[1] * t;
    let c = g[2] * t;
    let d = g[3] * t;
    // Diagonal blocks (pairs of real eigenvalues) are the common overdamped case.
    if b == 0.0 && c == 0.0 {
        return [a.exp(), 0.0, 0.0, d.exp()];
    }
    let m = 0.5 * (a + d);
    let n11 = 0.5 * (a - d);
    let delta = n11 * n11 + b * c;
    // f0 = e^m cosh(r), f1 = e^m sinh(r)/r  (r = sqrt(delta), maybe imaginary)
    let (f0, f1) = if delta.abs() < SERIES_DELTA {
        let em = m.exp();
        let c0 = 1.0 + delta / 2.0 + delta * delta / 24.0 + delta * delta * delta / 720.0;
        let c1 = 1.0 + delta / 6.0 + delta * delta / 120.0 + delta * delta * delta / 5040.0;
        (em * c0, em * c1)
    } else if delta > 0.0 {
        // Real eigenvalues m +- r. Both are computed without cancellation
        // (the slow one from det / (m -+ r)), and so are the diagonal entries
        // (r -+ |n11| = b c / (r +- |n11|)): this keeps strongly overdamped
        // blocks (zeta = 1e3, X5) accurate, not only finite.
        let r = delta.sqrt();
        let det = a * d - b * c;
        let lam_hi = if m < 0.0 { det / (m - r) } else { m + r };
        let lam_lo = if m > 0.0 { det / (m + r) } else { m - r };
        let ep = lam_hi.exp();
        let en = lam_lo.exp();
        let rp = r + n11.abs();
        let rm = b * c / rp;
        let (d11, d22) = if n11 >= 0.0 {
            (ep * rp + en * rm, ep * rm + en * rp)
        } else {
            (ep * rm + en * rp, ep * rp + en * rm)
        };
        let f1 = (ep - en) / (2.0 * r);
        return [d11 / (2.0 * r), f1 * b, f1 * c, d22 / (2.0 * r)];
    } else {
        let r = (-delta).sqrt();
        let em = m.exp();
        let (s, co) = r.sin_cos();
        (em * co, em * s / r)
    };
    [f0 + f1 * n11, f1 * b, f1 * c, f0 - f1 * n11]
}

/// `p * x` for a 2x2 matrix and a 2-vector.
#[inline]
pub fn mul2(p: &Mat2, x0: f64, x1: f64) -> (f64, f64) {
    (p[0] * x0 + p[1] * x1, p[2] * x0 + p[3] * x1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix2;

    fn dense(g: &Mat2, t: f64) -> Mat2 {
        let m = Matrix2::new(g[0], g[1], g[2], g[3]) * t;
        let e = m.exp();
        [e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]]
    }

    fn rel_err(a: &Mat2, b: &Mat2) -> f64 {
        let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
        let den: f64 = b.iter().map(|y| y * y).sum::<f64>();
        (num / den).sqrt()
    }

    #[test]
    fn matches_pade_exp_across_damping_regimes() {
        let h = 1.0 / 44100.0;
        let w = 2.0 * std::f64::consts::PI * 5000.0;
        // zeta from undamped through critical (exactly 1) to strongly overdamped;
        // the eigenvector route fails at zeta = 1 (NUMERICS.md P-E1).
        for zeta in [0.0, 0.01, 0.5, 1.0 - 1e-9, 1.0, 1.0 + 1e-9, 2.0, 50.0] {
            let g = [0.0, w, -w, -2.0 * zeta * w];
            let e = rel_err(&exp2(&g, h), &dense(&g, h));
            println!("zeta {zeta:e}: rel err vs nalgebra exp {e:.2e}");
            assert!(e < 1e-13, "zeta {zeta}: {e}");
        }
    }

    #[test]
    fn rotation_block_is_a_damped_rotation() {
        // [[a, b], [-b, a]] -> e^{at} [[cos bt, sin bt], [-sin bt, cos bt]]
        let (a, b, t) = (-3.0, 1234.5, 1e-3);
        let p = exp2(&[a, b, -b, a], t);
        let e = (a * t).exp();
        let want = [
            e * (b * t).cos(),
            e * (b * t).sin(),
            -e * (b * t).sin(),
            e * (b * t).cos(),
        ];
        assert!(rel_err(&p, &want) < 1e-14);
    }

    #[test]
    fn jordan_block_is_exact() {
        // [[l, 1], [0, l]] -> e^{lt} [[1, t], [0, 1]]
        let (l, t) = (-7.0, 0.3);
        let p = exp2(&[l, 1.0, 0.0, l], t);
        let e = (l * t).exp();
        let want = [e, e * t, 0.0, e];
        assert!(rel_err(&p, &want) < 1e-15);
    }

    #[test]
    fn huge_overdamping_does_not_overflow() {
        let p = exp2(&[0.0, 1e9, -1e9, -1e14], 1e-4);
        assert!(p.iter().all(|x| x.is_finite()), "{p:?}");
        let p = exp2(&[-1e12, 0.0, 0.0, -1.0], 1e-3);
        assert_eq!(p[0], 0.0);
    }
}
