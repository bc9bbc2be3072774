//! A dense matrix in hierarchical off-diagonal low-rank (HODLR) form, so a
//! matrix-vector product costs O(N r log N) instead of O(N^2)
//! (docs/numerics.md, "Structured changes of basis").
//!
//! The changes of basis between a modal object's free modes and its contact
//! modes are Cauchy-like: entry `(j, i)` is a smooth function of the free
//! pole `d_i` and the contact eigenvalue `z_j` divided by `z_j - d_i`
//! (docs/numerics.md, "Decomposing a phase"). With both bases ordered by
//! frequency, a block that couples one band of frequencies to a disjoint
//! band is numerically of low rank: at 200 and 1000 modes every off-diagonal
//! block of the bisection has rank 26-48 at the working precision. This
//! module finds those ranks and stores the factors; the engine applies them
//! with its SIMD kernels (`src/engine/kernel/matvec.rs`, `hodlr_mat_vec_add`).
//!
//! Built on the compile worker (allocates); the truncation is controlled
//! and measured: each block's discarded singular values are within
//! [`HODLR_TOL_U`] `u |W|_2` (Frobenius), the residual of every stored
//! factor pair is computed, and the whole product is checked against the
//! dense one before use ([`HODLR_CHECK_U`]).

use faer::{Mat, MatRef};
use nalgebra::DMatrix;

/// Blocks with at most this many rows or columns are stored dense.
pub const HODLR_LEAF: usize = 64;
/// Each off-diagonal block is truncated so that its discarded singular
/// values are within `HODLR_TOL_U u |W|_2` (Frobenius; `u = 2^-53`): about
/// the rounding of its decomposition, and below that of the dense product
/// itself (up to `N u |W| |x|`, typically `sqrt(N) u |W| |x|`).
pub const HODLR_TOL_U: f64 = 4.0;
/// Allowance for rounding in a block's measured residual, in `u
/// sqrt(min(m, n)) |A|_F` (a backward-stable SVD and the residual's own
/// evaluation; measured up to 3 on the changes of basis of 200-1000 modes).
pub const HODLR_ROUNDING_U: f64 = 4.0;
/// The hierarchical form is used only when it stores at most this fraction
/// of the dense matrix's entries (below that it is not worth its
/// indirection).
pub const HODLR_MAX_FILL: f64 = 0.75;
/// The checked product may differ from the dense one by at most this many
/// `u |W|_2 |x|` (the truncations of the `log2(N / leaf)` levels a row
/// crosses, plus both products' rounding).
pub const HODLR_CHECK_U: f64 = 64.0;

/// Unit roundoff of f64, `u = 2^-53`.
const UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;

/// One stored piece: a dense leaf or a low-rank off-diagonal block, both in
/// the permuted order (rows `r0..r0 + nr`, columns `c0..c0 + nc`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Piece {
    /// First row of the piece (permuted order).
    pub r0: usize,
    /// Number of rows.
    pub nr: usize,
    /// First column of the piece (permuted order).
    pub c0: usize,
    /// Number of columns.
    pub nc: usize,
    /// `None`: a dense `nr x nc` block at `off` (column-major). `Some(r)`:
    /// `V^T` (`r x nc`, column-major) at `off`, then `U` (`nr x r`,
    /// column-major) at `off + r nc`.
    pub rank: Option<usize>,
    /// Where the piece's numbers start in [`Hodlr::data`].
    pub off: usize,
}

/// A matrix `W` as `P_r^T H P_c`: the permutations put rows and columns in
/// frequency order, `H` is the hierarchy of pieces.
#[derive(Debug, Clone, PartialEq)]
pub struct Hodlr {
    /// Number of rows of `W`.
    pub rows: usize,
    /// Number of columns of `W`.
    pub cols: usize,
    /// Permuted row `i` is row `row_perm[i]` of `W`.
    pub row_perm: Vec<usize>,
    /// Permuted column `j` is column `col_perm[j]` of `W`.
    pub col_perm: Vec<usize>,
    /// The dense leaves and low-rank blocks that tile `H`.
    pub pieces: Vec<Piece>,
    /// Every piece's numbers, one after the other (see [`Piece::off`]).
    pub data: Vec<f64>,
    /// Largest rank of an off-diagonal block.
    pub max_rank: usize,
    /// `|W|_2` (power iteration).
    pub norm2: f64,
    /// Largest measured `|A - U V^T|_F` over the off-diagonal blocks.
    pub max_block_error: f64,
    /// Measured `max |H x - W x| / (|W|_2 |x|)` of the build's check, in
    /// units of `u`.
    pub check_u: f64,
}

/// The coordinate order that sorts a block phase's 2x2 blocks by the
/// modulus of their eigenvalues (`|det G_k|`), each block's two coordinates
/// (`k` and `nb + k` in the engine's layout) kept together.
pub fn frequency_order(gens: &[[f64; 4]]) -> Vec<usize> {
    let nb = gens.len();
    let key = |g: &[f64; 4]| (g[0] * g[3] - g[1] * g[2]).abs();
    let mut idx: Vec<usize> = (0..nb).collect();
    idx.sort_by(|&a, &b| key(&gens[a]).total_cmp(&key(&gens[b])).then(a.cmp(&b)));
    idx.iter().flat_map(|&k| [k, nb + k]).collect()
}

impl Hodlr {
    /// The hierarchical form of `w` in the order `row_perm` x `col_perm`,
    /// or `None` when it would not store at most [`HODLR_MAX_FILL`] of the
    /// entries, or fails its check (the caller keeps the dense product).
    pub fn build(w: &DMatrix<f64>, row_perm: &[usize], col_perm: &[usize]) -> Option<Hodlr> {
        Self::try_build(w, row_perm, col_perm).ok()
    }

    /// [`Hodlr::build`], saying why the dense product stays.
    pub fn try_build(
        w: &DMatrix<f64>,
        row_perm: &[usize],
        col_perm: &[usize],
    ) -> Result<Hodlr, String> {
        Self::try_build_at(w, row_perm, col_perm, HODLR_TOL_U)
    }

    /// [`Hodlr::try_build`] truncating at `tol_u u |W|_2` instead of
    /// [`HODLR_TOL_U`] (a matrix whose entries carry more rounding than
    /// that, formed by dense products, cannot be truncated below its own
    /// noise); the check then allows the larger of [`HODLR_CHECK_U`] and
    /// `16 tol_u` (the truncations of the levels a row crosses).
    pub fn try_build_at(
        w: &DMatrix<f64>,
        row_perm: &[usize],
        col_perm: &[usize],
        tol_u: f64,
    ) -> Result<Hodlr, String> {
        let (rows, cols) = (w.nrows(), w.ncols());
        assert!(row_perm.len() == rows && col_perm.len() == cols);
        if rows <= 2 * HODLR_LEAF || cols <= 2 * HODLR_LEAF {
            return Err(format!("{rows}x{cols} is small"));
        }
        if w.iter().any(|x| !x.is_finite()) {
            return Err("non-finite entries".into());
        }
        let a = Mat::from_fn(rows, cols, |i, j| w[(row_perm[i], col_perm[j])]);
        let norm2 = norm2(a.as_ref());
        if !(norm2 > 0.0) {
            return Err("zero matrix".into());
        }
        let mut h = Hodlr {
            rows,
            cols,
            row_perm: row_perm.to_vec(),
            col_perm: col_perm.to_vec(),
            pieces: Vec::new(),
            data: Vec::new(),
            max_rank: 0,
            norm2,
            max_block_error: 0.0,
            check_u: 0.0,
        };
        let tol = tol_u * UNIT_ROUNDOFF * norm2;
        h.split(a.as_ref(), 0, rows, 0, cols, tol)
            .ok_or("a block failed to compress")?;
        let fill = h.data.len() as f64 / (rows * cols) as f64;
        if fill > HODLR_MAX_FILL {
            return Err(format!(
                "it would store {:.0} % of the entries",
                100.0 * fill
            ));
        }
        // The check: the product against the dense one on a few vectors.
        let mut worst: f64 = 0.0;
        for seed in 0..3u64 {
            let x: Vec<f64> = (0..cols).map(|j| uniform(0xC0FFEE + seed, j, 0)).collect();
            let mut y = vec![0.0; rows];
            h.apply_add_reference(&x, &mut y);
            let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
            for i in 0..rows {
                let d: f64 = (0..cols).map(|j| w[(i, j)] * x[j]).sum();
                worst = worst.max((y[i] - d).abs() / (norm2 * xn * UNIT_ROUNDOFF));
            }
        }
        h.check_u = worst;
        if worst <= HODLR_CHECK_U.max(16.0 * tol_u) {
            Ok(h)
        } else {
            Err(format!(
                "its product is {worst:.1} u |W| |x| off the dense one"
            ))
        }
    }

    /// Entries stored (also the multiply-adds of one product).
    pub fn stored(&self) -> usize {
        self.data.len()
    }

    /// `y += W x`, plain loops (the compiler's check and tests; the engine
    /// has its own SIMD version).
    pub fn apply_add_reference(&self, x: &[f64], y: &mut [f64]) {
        let xp: Vec<f64> = self.col_perm.iter().map(|&j| x[j]).collect();
        let mut yp = vec![0.0; self.rows];
        let mut t = vec![0.0; self.max_rank];
        for p in &self.pieces {
            let xs = &xp[p.c0..p.c0 + p.nc];
            let ys = &mut yp[p.r0..p.r0 + p.nr];
            match p.rank {
                None => mat_vec(&self.data[p.off..p.off + p.nr * p.nc], p.nr, xs, ys),
                Some(r) => {
                    let t = &mut t[..r];
                    t.iter_mut().for_each(|v| *v = 0.0);
                    mat_vec(&self.data[p.off..p.off + r * p.nc], r, xs, t);
                    let u0 = p.off + r * p.nc;
                    mat_vec(&self.data[u0..u0 + p.nr * r], p.nr, t, ys);
                }
            }
        }
        for (i, v) in yp.iter().enumerate() {
            y[self.row_perm[i]] += v;
        }
    }

    fn split(
        &mut self,
        a: MatRef<'_, f64>,
        r0: usize,
        nr: usize,
        c0: usize,
        nc: usize,
        tol: f64,
    ) -> Option<()> {
        if nr <= HODLR_LEAF || nc <= HODLR_LEAF {
            let off = self.data.len();
            for j in 0..nc {
                for i in 0..nr {
                    self.data.push(a[(r0 + i, c0 + j)]);
                }
            }
            self.pieces.push(Piece {
                r0,
                nr,
                c0,
                nc,
                rank: None,
                off,
            });
            return Some(());
        }
        let (rm, cm) = (nr / 2, nc / 2);
        self.split(a, r0, rm, c0, cm, tol)?;
        self.split(a, r0 + rm, nr - rm, c0 + cm, nc - cm, tol)?;
        for (br, bnr, bc, bnc) in [(r0, rm, c0 + cm, nc - cm), (r0 + rm, nr - rm, c0, cm)] {
            let block = a.submatrix(br, bc, bnr, bnc);
            let seed = ((br as u64) << 32) ^ bc as u64;
            let (u, vt, err) = compress(block, tol, seed)?;
            let r = u.ncols();
            self.max_rank = self.max_rank.max(r);
            self.max_block_error = self.max_block_error.max(err);
            let off = self.data.len();
            for j in 0..bnc {
                for k in 0..r {
                    self.data.push(vt[(k, j)]);
                }
            }
            for k in 0..r {
                for i in 0..bnr {
                    self.data.push(u[(i, k)]);
                }
            }
            self.pieces.push(Piece {
                r0: br,
                nr: bnr,
                c0: bc,
                nc: bnc,
                rank: Some(r),
                off,
            });
        }
        Some(())
    }
}

/// `y += M x`, `M` column-major with `nrows` rows.
fn mat_vec(m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    for (j, &xj) in x.iter().enumerate() {
        let col = &m[j * nrows..(j + 1) * nrows];
        for i in 0..nrows {
            y[i] += col[i] * xj;
        }
    }
}

/// Truncated factors `U` (`m x r`) and `V^T` (`r x n`) of `a`: the
/// smallest rank whose discarded singular values are within `tol`
/// (Frobenius). A randomized range finder first ([`range`]: `O(m n k)` for
/// a range of `k` columns) for blocks of at least `4 RANGE_SAMPLES` rows and
/// columns, the full singular value decomposition when that does not meet
/// the check or the block is smaller. Returns the measured
/// residual `|a - U V^T|_F`, or `None` when even the full decomposition
/// exceeds `2 tol + HODLR_ROUNDING_U u sqrt(min(m, n)) |a|_F` (what a
/// backward-stable decomposition and the residual's own evaluation round
/// by). Deterministic (fixed seeds).
fn compress(a: MatRef<'_, f64>, tol: f64, seed: u64) -> Option<(Mat<f64>, Mat<f64>, f64)> {
    let (m, n) = (a.nrows(), a.ncols());
    let allowed =
        2.0 * tol + HODLR_ROUNDING_U * UNIT_ROUNDOFF * (m.min(n) as f64).sqrt() * a.norm_l2();
    let full = m.min(n);
    if full >= 4 * RANGE_SAMPLES {
        if let Some(q) = range(a, allowed / 4.0, seed) {
            let (ub, vt) = truncate((q.transpose() * a).as_ref(), tol)?;
            let u = &q * &ub;
            let resid = (a - &u * &vt).norm_l2();
            if resid <= allowed {
                return Some((u, vt, resid));
            }
        }
    }
    let (u, vt) = truncate(a, tol)?;
    let resid = (a - &u * &vt).norm_l2();
    (resid <= allowed).then_some((u, vt, resid))
}

/// Samples per pass of [`range`].
const RANGE_SAMPLES: usize = 32;

/// An orthonormal basis `Q` of `a`'s numerical range, with `|a - Q Q^T
/// a|_F <= tol` measured on the explicitly formed residual: each pass
/// samples the residual `R` (not `a`), so directions far below `|a|` are
/// resolved relative to `|R|` instead of being lost in the rounding of `a
/// Omega`. `None` when it needs more than half the columns (then the full
/// decomposition is cheaper).
fn range(a: MatRef<'_, f64>, tol: f64, seed: u64) -> Option<Mat<f64>> {
    let (m, n) = (a.nrows(), a.ncols());
    let mut q = Mat::<f64>::zeros(m, 0);
    let mut r = a.to_owned();
    let mut pass = 0u64;
    while r.norm_l2() > tol {
        if q.ncols() + RANGE_SAMPLES > m.min(n) / 2 {
            return None;
        }
        let omega = Mat::from_fn(n, RANGE_SAMPLES, |i, j| uniform(seed ^ (pass << 48), i, j));
        let y = &r * &omega;
        // Directions of `y` far below its largest are the rounding of `r
        // Omega`, not range: keep the rest, then orthogonalize them against
        // the basis so far (twice: one pass loses orthogonality).
        let svd = y.thin_svd().ok()?;
        let sv = svd.S().column_vector();
        let keep = (0..sv.nrows())
            .take_while(|&j| sv[j] > 1e-6 * sv[0])
            .count();
        if keep == 0 {
            return None;
        }
        let mut qn = svd.U().subcols(0, keep).to_owned();
        for _ in 0..2 {
            qn = &qn - &q * (q.transpose() * &qn);
            qn = qn.qr().compute_thin_Q();
        }
        r = &r - &qn * (qn.transpose() * &r);
        let mut both = Mat::<f64>::zeros(m, q.ncols() + qn.ncols());
        both.as_mut()
            .submatrix_mut(0, 0, m, q.ncols())
            .copy_from(&q);
        both.as_mut()
            .submatrix_mut(0, q.ncols(), m, qn.ncols())
            .copy_from(&qn);
        q = both;
        pass += 1;
    }
    Some(q)
}

/// `U Sigma` and `V^T` of `a`'s singular value decomposition, cut at the
/// smallest rank whose discarded singular values are within `tol`
/// (Frobenius).
fn truncate(a: MatRef<'_, f64>, tol: f64) -> Option<(Mat<f64>, Mat<f64>)> {
    let svd = a.thin_svd().ok()?;
    let s = svd.S().column_vector();
    let mut r = s.nrows();
    let mut tail = 0.0;
    while r > 0 {
        let t = tail + s[r - 1] * s[r - 1];
        if t.sqrt() > tol {
            break;
        }
        tail = t;
        r -= 1;
    }
    let (ub, vb) = (svd.U(), svd.V());
    Some((
        Mat::from_fn(a.nrows(), r, |i, j| ub[(i, j)] * s[j]),
        Mat::from_fn(r, a.ncols(), |i, j| vb[(j, i)]),
    ))
}

/// `|a|_2` by power iteration on `a^T a` (a lower bound that converges
/// from below; 30 steps from a fixed start).
fn norm2(a: MatRef<'_, f64>) -> f64 {
    let n = a.ncols();
    let mut x = Mat::from_fn(n, 1, |i, _| 1.0 + uniform(7, i, 0) * 0.5);
    let mut est = 0.0;
    for _ in 0..30 {
        let nx = x.norm_l2();
        if !(nx > 0.0) {
            return 0.0;
        }
        x *= faer::Scale(1.0 / nx);
        let y = a * &x;
        est = y.norm_l2();
        x = a.transpose() * &y;
    }
    est
}

/// A deterministic number in `[-1, 1)` from a seed and two indices
/// (splitmix64).
fn uniform(seed: u64, i: usize, j: usize) -> f64 {
    let mut z = seed
        .wrapping_add((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add((j as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Cauchy matrix with interlaced points (the structure of the
    /// changes of basis) is stored in a fraction of its entries and
    /// multiplies to within a few `u |W| |x|` of the dense product.
    #[test]
    fn cauchy_matrix_compresses_and_multiplies_exactly() {
        let n = 600;
        let d: Vec<f64> = (0..n).map(|i| (i as f64 + 1.0).powf(1.3)).collect();
        let z: Vec<f64> = (0..n).map(|i| (i as f64 + 1.5).powf(1.3)).collect();
        let w = DMatrix::from_fn(n, n, |j, i| 1.0 / (z[j] - d[i]));
        let id: Vec<usize> = (0..n).collect();
        let h = Hodlr::build(&w, &id, &id).expect("compresses");
        let fill = h.stored() as f64 / (n * n) as f64;
        println!(
            "n {n}: max rank {}, fill {fill:.3}, block error {:.1e} (|W| {:.2e}), check {:.2} u",
            h.max_rank, h.max_block_error, h.norm2, h.check_u
        );
        assert!(fill < 0.5, "fill {fill}");
        assert!(
            h.max_block_error
                <= (2.0 * HODLR_TOL_U + HODLR_ROUNDING_U * 30.0 * 18.0) * UNIT_ROUNDOFF * h.norm2
        );
        assert!(h.check_u <= HODLR_CHECK_U);
        // a permuted copy gives the same product through the permutations
        let perm: Vec<usize> = (0..n).map(|i| (i * 7) % n).collect();
        let wp = DMatrix::from_fn(n, n, |i, j| {
            w[(perm.iter().position(|&p| p == i).unwrap(), j)]
        });
        let hp = Hodlr::build(&wp, &perm, &id).expect("compresses");
        let x: Vec<f64> = (0..n).map(|j| (j as f64 * 0.37).sin()).collect();
        let (mut y1, mut y2) = (vec![0.0; n], vec![0.0; n]);
        h.apply_add_reference(&x, &mut y1);
        hp.apply_add_reference(&x, &mut y2);
        for i in 0..n {
            assert_eq!(y1[i], y2[perm[i]]);
        }
    }

    /// A matrix without low-rank structure is refused (the caller keeps
    /// the dense product).
    #[test]
    fn random_matrix_is_not_compressed() {
        let n = 300;
        let w = DMatrix::from_fn(n, n, |i, j| uniform(3, i, j));
        let id: Vec<usize> = (0..n).collect();
        assert!(Hodlr::build(&w, &id, &id).is_none());
    }
}
