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
//! eigenvector route breaks down (docs/numerics.md, "Stepping a phase: 2x2 blocks").

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
    // A complex pair: the split form, whose discriminant is computed before
    // scaling by t and without cancellation (accurate near critical damping).
    if let Some(o) = OscForm::of(g) {
        return o.exp(t);
    }
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

/// An oscillatory block generator (`delta < 0`: a complex eigenpair
/// `m +- i w`) split so that `exp(G t)` needs only `exp(m t)`, `sin(w t)` and
/// `cos(w t)`: `exp(G t) = e^{m t} (cos(w t) I + sin(w t) N / w)` with
/// `N = G - m I` (the formula of [`exp2`] with the `t`-independent parts
/// taken out). The engine evaluates the three functions for all blocks at
/// once (the engine's vectorised exp/sin/cos) when it needs `exp(G tau)` at a new
/// `tau` (located switches).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OscForm {
    /// Real part of the eigenvalues (decay rate, <= 0 for a passive block).
    pub m: f64,
    /// Imaginary part `w > 0` (angular frequency).
    pub w: f64,
    /// `N / w`, row-major.
    pub n_w: Mat2,
}

impl OscForm {
    /// The split of `g`, or `None` when `g` has real eigenvalues (or a
    /// double one: critical damping, a Jordan block), which [`exp2`] handles.
    pub fn of(g: &Mat2) -> Option<Self> {
        let m = 0.5 * (g[0] + g[3]);
        let n11 = 0.5 * (g[0] - g[3]);
        // n11^2 + g1 g2 cancels near critical damping: both products exactly
        // (Dekker), so the discriminant keeps full relative precision.
        let (p, pe) = two_prod(n11, n11);
        let (q, qe) = two_prod(g[1], g[2]);
        let delta = (p + q) + (pe + qe);
        if !(delta < 0.0) {
            return None;
        }
        let w = (-delta).sqrt();
        let n_w = [n11 / w, g[1] / w, g[2] / w, -n11 / w];
        (m.is_finite() && w.is_finite() && n_w.iter().all(|x| x.is_finite())).then_some(Self {
            m,
            w,
            n_w,
        })
    }

    /// `exp(G t)` (what [`exp2`] returns for this block).
    #[inline]
    pub fn exp(&self, t: f64) -> Mat2 {
        let (s, c) = (self.w * t).sin_cos();
        self.exp_from((self.m * t).exp(), s, c)
    }

    /// `exp(G t)` from `e = exp(m t)`, `s = sin(w t)`, `c = cos(w t)`.
    #[inline]
    pub fn exp_from(&self, e: f64, s: f64, c: f64) -> Mat2 {
        let (es, ec) = (e * s, e * c);
        [
            ec + es * self.n_w[0],
            es * self.n_w[1],
            es * self.n_w[2],
            ec + es * self.n_w[3],
        ]
    }
}

/// The oscillatory splits of a phase's blocks as structure of arrays, for
/// the engine's batched partial steps: block `k` is oscillatory unless it is
/// listed in `other` (real eigenvalues: [`exp2`]), where its entries are 0.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OscBlocks {
    /// [`OscForm::m`] per block.
    pub m: Vec<f64>,
    /// [`OscForm::w`] per block.
    pub w: Vec<f64>,
    /// [`OscForm::n_w`] per block, entry by entry.
    pub n_w: [Vec<f64>; 4],
    /// The blocks that are not oscillatory, ascending.
    pub other: Vec<usize>,
}

impl OscBlocks {
    /// The splits of `gens`.
    pub fn of(gens: &[Mat2]) -> Self {
        let nb = gens.len();
        let mut o = Self {
            m: vec![0.0; nb],
            w: vec![0.0; nb],
            n_w: std::array::from_fn(|_| vec![0.0; nb]),
            other: Vec::new(),
        };
        for (k, g) in gens.iter().enumerate() {
            match OscForm::of(g) {
                Some(f) => {
                    o.m[k] = f.m;
                    o.w[k] = f.w;
                    for q in 0..4 {
                        o.n_w[q][k] = f.n_w[q];
                    }
                }
                None => o.other.push(k),
            }
        }
        o
    }

    /// The split of block `k`, if it is oscillatory.
    #[inline]
    pub fn get(&self, k: usize) -> Option<OscForm> {
        (self.other.binary_search(&k).is_err()).then(|| OscForm {
            m: self.m[k],
            w: self.w[k],
            n_w: [
                self.n_w[0][k],
                self.n_w[1][k],
                self.n_w[2][k],
                self.n_w[3][k],
            ],
        })
    }
}

/// The largest eigenvalue of `(G + G^T) / 2`, or 0 if it is negative:
/// `|exp(G t)|_2 <= e^{gamma t}`.
pub fn sym_growth(g: &Mat2) -> f64 {
    let (a, d) = (g[0], g[3]);
    let b = 0.5 * (g[1] + g[2]);
    let top = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt();
    top.max(0.0)
}

/// Whether `G + G^T` is negative semidefinite (then `|exp(G t)|_2 <= 1` for
/// every `t >= 0`), with a relative rounding allowance.
pub fn is_contraction(g: &Mat2) -> bool {
    let (a, d) = (g[0], g[3]);
    let b = 0.5 * (g[1] + g[2]);
    let scale = g.iter().map(|x| x.abs()).fold(0.0, f64::max);
    let tol = 64.0 * f64::EPSILON * scale;
    // 2x2 symmetric [[a, b], [b, d]] <= 0  <=>  a <= 0, d <= 0, ad >= b^2
    a <= tol && d <= tol && a * d - b * b >= -tol * scale
}

/// `a * b = p + e` exactly (Dekker's product with Veltkamp's split: no FMA
/// needed, so the baseline build computes the same; valid while `|a|, |b|`
/// stay below ~1e300).
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    const SPLIT: f64 = 134_217_729.0; // 2^27 + 1
    let split = |x: f64| {
        let c = SPLIT * x;
        let hi = c - (c - x);
        (hi, x - hi)
    };
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    (p, e)
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
        // the eigenvector route fails at zeta = 1 (docs/numerics.md, "Stepping a phase: 2x2 blocks").
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
    fn oscillatory_split_is_accurate_through_near_critical_damping() {
        // Against nalgebra's Pade exp (accurate to ~|G t| u, independent of
        // the discriminant's cancellation), where |G t| is moderate.
        let h = 1.0 / 44100.0;
        let mut worst: f64 = 0.0;
        for f in [20.0, 440.0, 5000.0, 20000.0, 441_000.0] {
            let w = 2.0 * std::f64::consts::PI * f;
            for zeta in [0.0, 1e-4, 0.1, 0.9, 1.0 - 1e-6, 1.0 - 1e-12] {
                for g in [[0.0, w, -w, -2.0 * zeta * w], [-zeta * w, w, -w, -zeta * w]] {
                    let o = OscForm::of(&g).expect("oscillatory");
                    for t in [h, 0.3 * h, 1e-3 * h, 1e-9 * h] {
                        let norm_t = g.iter().map(|x| x * x).sum::<f64>().sqrt() * t;
                        let (s, c) = (o.w * t).sin_cos();
                        let got = o.exp_from((o.m * t).exp(), s, c);
                        // exp2 takes this route for every complex pair
                        assert_eq!(got, exp2(&g, t));
                        if norm_t > 20.0 {
                            continue;
                        }
                        let e = rel_err(&got, &dense(&g, t)) / norm_t.max(1.0);
                        worst = worst.max(e);
                        assert!(e < 2e-15, "f {f} zeta {zeta} t {t:e}: {e:e}");
                    }
                }
            }
        }
        println!(
            "oscillatory split vs Pade exp: worst rel. difference / max(1, |G t|) {worst:.1e}"
        );
        // Where |G t| is large the Pade reference loses accuracy itself: a
        // near-critical mode at 10x Nyquist over one sample (|G t| = 140),
        // against mpmath.expm at 60 digits (the entries below, rounded to
        // f64, for exactly these f64 inputs). Scaling by t before forming the discriminant
        // (the previous formula) was off by 1.2e-13 here.
        let g = [
            0.0,
            2770884.7204661975,
            -2770884.7204661975,
            -5541763.899162954,
        ];
        let t = 2.2675736961451248e-05;
        let want = [
            3.28812001155796e-26,
            3.2367445112430576e-26,
            -3.2367445112430576e-26,
            -3.1853625374391323e-26,
        ];
        let e = rel_err(&exp2(&g, t), &want);
        println!(
            "near-critical mode at 441 kHz over one sample: rel. error {e:.1e} (|m t| u = 7e-15)"
        );
        assert!(e < 1e-14, "{e:e}");
        // real eigenvalues and Jordan blocks are left to the other branches
        assert!(OscForm::of(&[0.0, 1.0, -1.0, -2.0]).is_none());
        assert!(OscForm::of(&[-3.0, 0.0, 0.0, -5.0]).is_none());
        assert!(OscForm::of(&[-7.0, 1.0, 0.0, -7.0]).is_none());
    }

    #[test]
    fn huge_overdamping_does_not_overflow() {
        let p = exp2(&[0.0, 1e9, -1e9, -1e14], 1e-4);
        assert!(p.iter().all(|x| x.is_finite()), "{p:?}");
        let p = exp2(&[-1e12, 0.0, 0.0, -1.0], 1e-3);
        assert_eq!(p[0], 0.0);
    }
}
