//! What the exact event search needs to know about a phase's event function
//! beyond its rows (docs/numerics.md, "Certified isolation
//! of the first crossing").
//!
//! In a block phase the event function is a sum over blocks,
//! `phi(t0 + tau) = c(tau) + sum_k r_k . exp(G_k tau) s_k`, with `r_k` the
//! block's two entries of the event row and `c` the exactly polynomial part
//! (the hammer's parabola in flight, a constant in contact). Almost every
//! block's share is a sum of *terms* `Re[C e^{mu tau}]` whose complex
//! amplitude `C` is a linear function of the block's state:
//!
//! - an oscillatory block (`G = m I + N`, eigenvalues `m +- i w`):
//!   `r . exp(G tau) s = e^{m tau} (alpha cos(w tau) + beta sin(w tau))
//!   = Re[(alpha - i beta) e^{mu tau}]`, `mu = m + i w`, with
//!   `alpha = r . s` and `beta = (r N / w) . s`: one term;
//! - a block with two well separated real eigenvalues `l1`, `l2` (an
//!   overdamped mode, a pair of real contact eigenvalues): by Sylvester's
//!   formula `exp(G tau) = (e^{l1 tau} (G - l2 I) - e^{l2 tau} (G - l1 I)) /
//!   (l1 - l2)`, two real terms with amplitudes `r (G - l2 I) s / (l1 - l2)`
//!   and `-r (G - l1 I) s / (l1 - l2)`.
//!
//! So two rows per term give every amplitude from the state in O(1), and
//! from it the exact envelope `|C| e^{Re(mu) tau}` and every derivative
//! `Re[C mu^j e^{mu tau}]`, `|.| <= |mu|^j |C| e^{Re(mu) tau}`. The rare
//! blocks with nearly equal real eigenvalues (within a factor 2: one time
//! scale, but Sylvester's amplitudes would cancel) stay whole: with
//! `G = m I + N`, `N^2 = rho^2 I`, `exp(G tau) = e^{m tau} (cosh(rho tau) I +
//! sinh(rho tau) / rho N)`, so a row `R` applied to the block's state `x`
//! at a node's start is at most `e^{(m + rho) tau} (|R x| + |R N x| tau)`
//! later: the search keeps the rows `r G^j` and `r G^j N`.
//!
//! Near critical damping an oscillatory term has `w << |m|` and an
//! ill-conditioned eigenbasis: `alpha` is of the size of the motion but
//! `beta ~ 1 / w` is huge, and its envelope `|C|` says nothing. Its sine
//! is small for as long as it matters, so the search bounds such a term by
//! `e^{m tau} (|alpha| + |beta| min(1, w tau))`, which stays of the size of
//! the motion (the same for every derivative, with `C mu^j`).

use crate::physics::block::{Mat2, OscBlocks};
use nalgebra::DMatrix;

/// The engine's event search resolves a term on a node of width `w` when
/// `|mu| w <=` this: then its cubic remainder `|mu|^3 w^3 / 6` (0.46 of its
/// amplitude) and slope remainder `|mu|^3 w^2 / 2` beat the bare envelope
/// and slope bound.
pub const THETA_RESOLVED: f64 = 1.4;
/// A term is slow when `|mu| h <=` this: the engine sums the slow terms
/// into one Taylor polynomial per search, whose series converges fast over
/// a whole sample (every term at most `2^j / j!` of its amplitude).
pub const THETA_SLOW: f64 = 2.0;
/// Nodes a search examines on its way down to the root resolution next to
/// one root or tangency (`2^-48` of a sample).
pub const NODES_PER_ROOT: f64 = 50.0;

/// Real eigenvalues closer than this ratio (`|l1 - l2| < SPLIT_GAP max|l|`)
/// are not split into two terms: their Sylvester amplitudes cancel by up to
/// `1 / SPLIT_GAP`, while one time scale covers both.
pub const SPLIT_GAP: f64 = 0.5;

/// One term `Re[C e^{mu tau}]` of the event function: its block, the rows
/// that give `C = (re . s_k) - i (im . s_k)` from the block's state
/// `s_k = (s[k], s[nb + k])`, and `mu = m + i w`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    /// Block index.
    pub block: u32,
    /// Row of the real part of `C` over the block's two coordinates.
    pub re: [f64; 2],
    /// Row of minus the imaginary part of `C`.
    pub im: [f64; 2],
    /// `Re(mu)` (decay rate, <= 0 up to rounding).
    pub m: f64,
    /// `Im(mu) >= 0` (angular frequency; 0 for a real term).
    pub w: f64,
    /// `|mu|`: how far the term turns or decays per unit of time.
    pub mu: f64,
}

/// Per-phase data of the event search.
#[derive(Debug, Clone, Default)]
pub struct EventSearch {
    /// The terms of the event function, block by block.
    pub terms: Vec<Term>,
    /// Blocks that are not written as terms (nearly equal real
    /// eigenvalues), ascending.
    pub whole: Vec<u32>,
    /// Per whole block: the rows `[r, r N, r G, r G N, r G^3, r G^3 N]`.
    pub whole_rows: Vec<[[f64; 2]; 6]>,
    /// Per whole block: `[lambda_max, rho_spec]`: the larger real
    /// eigenvalue (`|exp(G tau) x|`-type bounds grow at most like
    /// `e^{lambda_max tau}`, <= 1 up to rounding) and the spectral radius.
    pub whole_info: Vec<[f64; 2]>,
    /// Dense phases: `|ev A^3|` (the event function's third derivative is
    /// at most this times the state norm, `|exp(A tau)| <= 1`).
    pub dense_ddd_norm: f64,
}

/// `row G` for one 2x2 block (row vector times matrix).
fn row_g(r: [f64; 2], g: &Mat2) -> [f64; 2] {
    [r[0] * g[0] + r[1] * g[2], r[0] * g[1] + r[1] * g[3]]
}

/// The real eigenvalues `(l1, l2)` of a 2x2 block with a non-negative
/// discriminant, each computed without cancellation.
fn real_eigenvalues(g: &Mat2) -> (f64, f64) {
    let m = 0.5 * (g[0] + g[3]);
    let n11 = 0.5 * (g[0] - g[3]);
    let r = (n11 * n11 + g[1] * g[2]).max(0.0).sqrt();
    let det = g[0] * g[3] - g[1] * g[2];
    if m < 0.0 {
        let lo = m - r;
        (if lo != 0.0 { det / lo } else { m + r }, lo)
    } else {
        let hi = m + r;
        (hi, if hi != 0.0 { det / hi } else { m - r })
    }
}

impl EventSearch {
    /// `(slow terms, fast terms, largest |mu| h of a fast term)` at step
    /// `h`.
    pub fn split_at(&self, h: f64) -> (usize, usize, f64) {
        let fast: Vec<f64> = self
            .terms
            .iter()
            .map(|t| t.mu * h)
            .filter(|&x| x > THETA_SLOW)
            .collect();
        let top = fast.iter().copied().fold(0.0, f64::max);
        (self.terms.len() - fast.len(), fast.len(), top)
    }

    /// The search data of a block phase with event row `ev`.
    pub fn of_blocks(gens: &[Mat2], osc: &OscBlocks, ev: &[f64]) -> Self {
        let nb = gens.len();
        let mut terms = Vec::with_capacity(nb);
        let mut whole = Vec::new();
        let mut whole_rows = Vec::new();
        let mut whole_info = Vec::new();
        for (k, g) in gens.iter().enumerate() {
            let r = [ev[k], ev[nb + k]];
            if let Some(o) = osc.get(k) {
                let n = o.n_w;
                terms.push(Term {
                    block: k as u32,
                    re: r,
                    im: [r[0] * n[0] + r[1] * n[2], r[0] * n[1] + r[1] * n[3]],
                    m: o.m,
                    w: o.w,
                    mu: o.m.hypot(o.w),
                });
                continue;
            }
            let (l1, l2) = real_eigenvalues(g);
            let rho = l1.abs().max(l2.abs());
            let gap = l1 - l2;
            if gap.abs() >= SPLIT_GAP * rho && gap != 0.0 {
                // Sylvester: r (G - l I) / (l1 - l2)
                let shifted = |l: f64| -> [f64; 2] {
                    let gs = [g[0] - l, g[1], g[2], g[3] - l];
                    let x = row_g(r, &gs);
                    [x[0] / gap, x[1] / gap]
                };
                let a1 = shifted(l2);
                let a2 = shifted(l1);
                for (re, l) in [(a1, l1), ([-a2[0], -a2[1]], l2)] {
                    terms.push(Term {
                        block: k as u32,
                        re,
                        im: [0.0; 2],
                        m: l,
                        w: 0.0,
                        mu: l.abs(),
                    });
                }
            } else {
                let m = 0.5 * (g[0] + g[3]);
                let n = [g[0] - m, g[1], g[2], g[3] - m];
                let r1 = row_g(r, g);
                let r3 = row_g(row_g(r1, g), g);
                whole.push(k as u32);
                whole_rows.push([r, row_g(r, &n), r1, row_g(r1, &n), r3, row_g(r3, &n)]);
                whole_info.push([l1.max(l2), rho]);
            }
        }
        Self {
            terms,
            whole,
            whole_rows,
            whole_info,
            dense_ddd_norm: 0.0,
        }
    }

    /// The search data of a dense phase with generator `a` and event row
    /// `ev`.
    pub fn of_dense(a: &DMatrix<f64>, ev: &[f64]) -> Self {
        let mut row = nalgebra::DVector::from_column_slice(ev).transpose();
        for _ in 0..3 {
            row *= a;
        }
        Self {
            dense_ddd_norm: row.norm(),
            ..Self::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::block::{exp2, is_contraction, mul2};

    /// The terms of every block add up to `r . exp(G tau) s` (exp2) for
    /// blocks of every shape the compiler makes: modal blocks in energy
    /// coordinates (lightly damped, near-critical, overdamped), rotation
    /// and diagonal blocks of an eigendecomposition; a block with nearly
    /// equal real eigenvalues stays whole.
    #[test]
    fn terms_add_up_to_the_block_exponential() {
        let gens: Vec<Mat2> = vec![
            [0.0, 2000.0, -2000.0, -3.0],
            [-40.0, 9000.0, -9000.0, -40.0],
            [0.0, 1e6, -1e6, -1.9e6],  // near-critical modal block
            [-5.0, 0.0, 0.0, -7e4],    // diagonal real pair
            [0.0, 1e3, -1e3, -2e5],    // overdamped modal block
            [0.0, 1e3, -1e3, -2.05e3], // barely overdamped: stays whole
        ];
        let osc = OscBlocks::of(&gens);
        let nb = gens.len();
        let ev: Vec<f64> = (0..2 * nb).map(|i| 0.3 + 0.1 * i as f64).collect();
        let sr = EventSearch::of_blocks(&gens, &osc, &ev);
        assert_eq!(sr.whole, vec![5]);
        assert_eq!(sr.terms.len(), 3 + 2 * 2);
        let s: Vec<f64> = (0..2 * nb)
            .map(|i| (-1.0f64).powi(i as i32) / (1.0 + i as f64))
            .collect();
        let mut worst: f64 = 0.0;
        for (k, g) in gens.iter().enumerate() {
            assert!(is_contraction(g), "block {k}");
            if sr.whole.contains(&(k as u32)) {
                continue;
            }
            for tau in [0.0, 1e-7, 3e-5, 1e-3] {
                let (x0, x1) = mul2(&exp2(g, tau), s[k], s[nb + k]);
                let want = ev[k] * x0 + ev[nb + k] * x1;
                let mut got = 0.0;
                let mut scale = 0.0;
                for t in sr.terms.iter().filter(|t| t.block == k as u32) {
                    let cr = t.re[0] * s[k] + t.re[1] * s[nb + k];
                    let ci = -(t.im[0] * s[k] + t.im[1] * s[nb + k]);
                    let e = (t.m * tau).exp();
                    got += e * (cr * (t.w * tau).cos() - ci * (t.w * tau).sin());
                    scale += cr.hypot(ci);
                }
                worst = worst.max((got - want).abs() / scale);
            }
        }
        println!("terms vs exp2: worst {worst:.1e} of the amplitudes");
        assert!(worst < 1e-14, "{worst:e}");
        assert!(!is_contraction(&[0.1, 0.0, 0.0, -1.0]));
        assert!(!is_contraction(&[-1.0, 10.0, 0.0, -1.0]));
    }
}
