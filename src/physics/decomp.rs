//! Decomposition of a phase generator into real 2x2 blocks, with checks, and
//! the dense fallback (docs/numerics.md, "Decomposing a phase").
//!
//! `A = V G V^{-1}` with `G` block diagonal: a complex eigenpair `a +- ib` with
//! eigenvector `x + iy` contributes the columns `sqrt(2) x, sqrt(2) y` of `V`
//! and the block `[[a, b], [-b, a]]`; real eigenvalues are paired into
//! diagonal blocks. The eigenvectors come from faer's real non-symmetric EVD
//! (nalgebra has none). Each decomposition is checked: the residual
//! `|A V - V G| / (|A| |V|)`, the condition number of `V`, and the agreement of
//! `V exp(G h) V^{-1}` with nalgebra's dense Pade `exp(A h)`. When a check
//! fails (near-defective `A`: exactly critical damping, coalescing
//! eigenvalues), the phase falls back to the dense propagator `exp(A h)`.

use crate::physics::block::{exp2, is_contraction, Mat2};
use crate::physics::error::{Check, DecompError, SecularError};
use crate::physics::linalg::{mat_vec, to_faer};
pub use crate::physics::secular::BlockEigen;
use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{evd_real, evd_scratch, ComputeEigenvectors};
use faer::{Mat, Par};
use nalgebra::{DMatrix, DVector};

/// Largest accepted condition number of `V` (energy coordinates give 1-25 on
/// the presets, docs/numerics.md, "Tolerances"; 1e6 leaves room but stops the
/// near-defective cases, whose kappa grows like delta^{-1/2}).
pub const MAX_KAPPA: f64 = 1e6;
/// Largest accepted relative residual `|A V - V G| / (|A| |V|)`.
pub const MAX_RESIDUAL: f64 = 1e-11;
/// Largest accepted relative difference between the block propagator and
/// nalgebra's dense `exp(A h)`, per unit of `kappa(V)` (rounding in the change
/// of basis is amplified by kappa).
pub const MAX_EXPM_DIFF_PER_KAPPA: f64 = 1e-12;

/// How a phase is advanced.
#[derive(Debug, Clone)]
pub enum Form {
    /// Real 2x2 blocks: state `s` with `y = V s`, one `exp2` per block. Block
    /// `k` acts on `(s[k], s[nb + k])` (structure of arrays).
    Blocks {
        /// Block generators `G_k`.
        gens: Vec<Mat2>,
    },
    /// Dense fallback: state is `y` itself (`V = I`), stepped by `exp(A h)`.
    Dense {
        /// The generator, for partial steps and recompiles.
        a: DMatrix<f64>,
    },
}

/// A decomposed phase generator and the numbers that justify it.
#[derive(Debug, Clone)]
pub struct PhaseDecomp {
    /// Blocks or dense.
    pub form: Form,
    /// Columns: the phase coordinates in energy coordinates (`y = V s`).
    pub v: DMatrix<f64>,
    /// `V^{-1}`.
    pub vinv: DMatrix<f64>,
    /// Checks.
    pub diag: DecompDiagnostics,
}

/// What the checks measured.
#[derive(Debug, Clone, Default)]
pub struct DecompDiagnostics {
    /// State dimension.
    pub dim: usize,
    /// "closed-form modal blocks", "eigen blocks (faer)" or "dense exp(A h)".
    pub method: String,
    /// Relative residual of the eigen decomposition (NaN when not computed).
    pub residual: f64,
    /// Condition number of `V` (1 for closed forms and dense).
    pub kappa: f64,
    /// Relative Frobenius difference between the propagator used and
    /// nalgebra's `exp(A h)` (NaN when not computed).
    pub expm_rel_diff: f64,
    /// Largest singular value of the propagator over one sample in energy
    /// coordinates (<= 1 for a passive phase, up to rounding).
    pub sigma_max: f64,
    /// Why the eigen route was refused, if it was.
    pub fallback_reason: Option<String>,
    /// `kappa` and `sigma_max` are power-iteration estimates (lower bounds),
    /// not SVDs (systems above [`MAX_DENSE_CHECK_DIM`]).
    pub estimated: bool,
}

/// Largest singular value.
pub fn sigma_max(m: &DMatrix<f64>) -> f64 {
    if m.nrows() == 0 {
        return 0.0;
    }
    match crate::physics::linalg::singular_values(m) {
        Some(s) => s.first().copied().unwrap_or(0.0),
        None => f64::NAN,
    }
}

/// Dense `exp(A t)` with a finiteness guard (nalgebra's `exp` unwraps an LU
/// solve internally and would panic on NaN input).
pub fn dense_exp(a: &DMatrix<f64>, t: f64) -> Result<DMatrix<f64>, DecompError> {
    if a.iter().any(|x| !x.is_finite()) || !t.is_finite() {
        return Err(DecompError::NonFinite);
    }
    if a.nrows() == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    let e = (a * t).exp();
    if e.iter().any(|x| !x.is_finite()) {
        return Err(DecompError::ExpNotFinite);
    }
    Ok(e)
}

/// `V blockdiag(exp(G_k t)) V^{-1}` as a dense matrix (for checks).
pub fn blocks_to_dense(
    gens: &[Mat2],
    v: &DMatrix<f64>,
    vinv: &DMatrix<f64>,
    t: f64,
) -> DMatrix<f64> {
    let dim = v.nrows();
    let nb = gens.len();
    let mut p = DMatrix::zeros(dim, dim);
    for (k, g) in gens.iter().enumerate() {
        let e = exp2(g, t);
        p[(k, k)] = e[0];
        p[(k, nb + k)] = e[1];
        p[(nb + k, k)] = e[2];
        p[(nb + k, nb + k)] = e[3];
    }
    use crate::physics::linalg::matmul;
    matmul(&matmul(v, &p), vinv)
}

/// Phase from closed-form 2x2 blocks acting on coordinate pairs given by
/// `pairs[k] = (i, j)` of the energy vector (modal objects: `(xi_k, u_k)`).
pub fn from_blocks(gens: Vec<Mat2>, pairs: &[(usize, usize)], dim: usize, h: f64) -> PhaseDecomp {
    let nb = pairs.len();
    let mut v = DMatrix::zeros(dim, dim);
    for (k, &(i, j)) in pairs.iter().enumerate() {
        v[(i, k)] = 1.0;
        v[(j, nb + k)] = 1.0;
    }
    let vinv = v.transpose();
    let sig = if dim <= 400 {
        sigma_max(&blocks_to_dense(&gens, &v, &vinv, h))
    } else {
        // A permutation of 2x2 blocks: the norm is the largest block norm.
        gens.iter()
            .map(|g| {
                let e = exp2(g, h);
                sigma_max(&DMatrix::from_row_slice(2, 2, &e))
            })
            .fold(0.0, f64::max)
    };
    PhaseDecomp {
        form: Form::Blocks { gens },
        v,
        vinv,
        diag: DecompDiagnostics {
            dim,
            method: "closed-form modal blocks".into(),
            residual: 0.0,
            kappa: 1.0,
            expm_rel_diff: f64::NAN,
            sigma_max: sig,
            fallback_reason: None,
            estimated: false,
        },
    }
}

/// Decompose a general phase generator; falls back to dense when the eigen
/// route fails its checks. `h` is the sample period used for the checks.
pub fn decompose(a: &DMatrix<f64>, h: f64) -> Result<PhaseDecomp, DecompError> {
    decompose_via(a, h, None, true)
}

/// Like [`decompose`], trying first a decomposition that the caller got from
/// the system's structure (`(method name, result)`, e.g. the rank-one
/// secular route of [`crate::physics::secular`]). It is checked like any
/// other; if it failed or fails the checks, faer's general eigensolver is
/// used (the summary says why) when `allow_general`, else the error says
/// why the structured route was refused.
pub fn decompose_via(
    a: &DMatrix<f64>,
    h: f64,
    structured: Option<(&str, Result<BlockEigen, SecularError>)>,
    allow_general: bool,
) -> Result<PhaseDecomp, DecompError> {
    if a.iter().any(|x| !x.is_finite()) {
        return Err(DecompError::NonFinite);
    }
    // A 2x2 generator (a hammer against a wall, or the hammer-spring pair
    // of a contact whose coupled modes all sit at a node) is its own block:
    // exp2 is exact for every 2x2 matrix, Jordan blocks (exactly critical
    // damping) included, so it needs no eigenvectors and no dense fallback.
    let g2 = [a[(0, 0)], a[(0, 1)], a[(1, 0)], a[(1, 1)]];
    if a.nrows() == 2 && is_contraction(&g2) {
        let mut d = from_blocks(vec![g2], &[(0, 1)], 2, h);
        d.diag.method = "one 2x2 block in closed form (exact at any damping)".into();
        let p = blocks_to_dense(&[g2], &d.v, &d.vinv, h);
        let reference = dense_exp(a, h)?;
        d.diag.expm_rel_diff = (&p - &reference).norm() / reference.norm().max(f64::MIN_POSITIVE);
        return Ok(d);
    }
    let mut refused: Option<(String, DecompError)> = None;
    if let Some((name, eig)) = structured {
        match eig
            .map_err(|e| Refusal::plain(e.into()))
            .and_then(|e| checked(a, h, e, name))
        {
            Ok(d) => return Ok(d),
            Err(r) => refused = Some((name.to_string(), r.error)),
        }
    }
    if let (Some((_, e)), false) = (&refused, allow_general) {
        return Err(DecompError::GeneralOverBudget {
            refused: Box::new(e.clone()),
        });
    }
    let refused_text = refused
        .as_ref()
        .map(|(name, e)| format!("{name} refused: {e}"));
    let method = match &refused_text {
        Some(r) => format!("eigen blocks (faer; {r})"),
        None => "eigen blocks (faer)".to_string(),
    };
    match eigen_blocks(a)
        .map_err(Refusal::plain)
        .and_then(|e| checked(a, h, e, &method))
    {
        Ok(d) => Ok(d),
        Err(r) => Ok(dense_phase(
            a,
            dense_exp(a, h)?,
            r.residual,
            r.kappa,
            Some(match &refused_text {
                Some(s) => format!("{}; {s}", r.error),
                None => r.error.to_string(),
            }),
        )),
    }
}

/// Why a block decomposition was not accepted, with what was measured.
struct Refusal {
    error: DecompError,
    residual: f64,
    kappa: f64,
}

impl Refusal {
    fn plain(error: DecompError) -> Self {
        Self {
            error,
            residual: f64::NAN,
            kappa: f64::NAN,
        }
    }
}

/// Largest accepted `|V^-1 V - I|` (relative, per unit of `kappa(V)`): the
/// structured route builds `V^-1` from left eigenvectors, not by inversion.
pub const MAX_INVERSE_DEFECT_PER_KAPPA: f64 = 1e-11;

/// Check a block decomposition `(gens, V, V^-1)` of `a` (residual,
/// condition, inverse, and for small systems the propagator against the
/// dense Pade `exp(A h)`) and make it a phase, or say why not.
fn checked(
    a: &DMatrix<f64>,
    h: f64,
    (gens, v, vinv): BlockEigen,
    method: &str,
) -> Result<PhaseDecomp, Refusal> {
    let dim = a.nrows();
    let small = dim <= MAX_DENSE_CHECK_DIM;
    let (residual, kappa, inv_defect) = measure(a, &gens, &v, &vinv).map_err(Refusal::plain)?;
    let refuse = |error: DecompError| Refusal {
        error,
        residual,
        kappa,
    };
    let failed = |check: Check, value: f64, limit: f64| {
        refuse(DecompError::Failed {
            check,
            value,
            limit,
        })
    };
    if !(residual <= MAX_RESIDUAL) {
        return Err(failed(Check::Residual, residual, MAX_RESIDUAL));
    }
    if !(kappa <= MAX_KAPPA) {
        return Err(failed(Check::Kappa, kappa, MAX_KAPPA));
    }
    let inv_limit = MAX_INVERSE_DEFECT_PER_KAPPA * kappa.max(1.0);
    if !(inv_defect <= inv_limit) {
        return Err(failed(Check::Inverse, inv_defect, inv_limit));
    }
    // Dense cross-check against nalgebra's Pade exp (O(dim^3), only for
    // small systems; large ones rely on residual, inverse and kappa, which
    // bound the propagator error by ~ kappa * residual * |A h|).
    let (diff, sig) = if small {
        let reference = dense_exp(a, h).map_err(&refuse)?;
        let p = blocks_to_dense(&gens, &v, &vinv, h);
        let diff = (&p - &reference).norm() / reference.norm().max(f64::MIN_POSITIVE);
        (diff, sigma_max(&p))
    } else {
        (f64::NAN, sigma_max_blocks_est(&gens, &v, &vinv, h))
    };
    // (The reference is itself only accurate to ~ |A h| u: each of the
    // ~log2 |A h| squarings of the Pade exp doubles its error.
    // tests/fuzz_scenes.rs found a stiff hammer-on-wall rotation, |A h| =
    // 4.7e3, whose closed-form blocks were exact but differed from the
    // reference by 1e-12: the dense fallback taken then was the non-passive
    // one.)
    let diff_limit =
        MAX_EXPM_DIFF_PER_KAPPA * kappa.max(1.0) * (dim as f64).sqrt() * (a.norm() * h).max(1.0);
    if small && !(diff <= diff_limit) {
        return Err(failed(Check::Propagator, diff, diff_limit));
    }
    Ok(PhaseDecomp {
        form: Form::Blocks { gens },
        diag: DecompDiagnostics {
            dim,
            method: method.to_string(),
            residual,
            kappa,
            expm_rel_diff: diff,
            sigma_max: sig,
            fallback_reason: None,
            estimated: !small,
        },
        v,
        vinv,
    })
}

/// `|A V - V G| / (|A| |V|)` for block generators `G` in structure-of-arrays
/// layout (block `k` on columns `k` and `nb + k` of `V`).
pub fn block_residual(a: &DMatrix<f64>, gens: &[Mat2], v: &DMatrix<f64>) -> f64 {
    let n = v.nrows();
    let nb = gens.len();
    let mut vg = DMatrix::zeros(n, n);
    for (k, g) in gens.iter().enumerate() {
        for i in 0..n {
            let (x0, x1) = (v[(i, k)], v[(i, nb + k)]);
            vg[(i, k)] = x0 * g[0] + x1 * g[2];
            vg[(i, nb + k)] = x0 * g[1] + x1 * g[3];
        }
    }
    (crate::physics::linalg::matmul(a, v) - vg).norm()
        / (a.norm() * v.norm()).max(f64::MIN_POSITIVE)
}

/// `(|A V - V G| / (|A| |V|), kappa(V), |V^-1 V - I|)` of a block
/// decomposition in structure-of-arrays layout. `kappa` is exact (SVD) up to
/// dimension [`MAX_DENSE_CHECK_DIM`], above it `|V| |V^-1|` by power
/// iteration (O(n^2) per step; each factor converges from below). The
/// inverse defect is exact (Frobenius, relative to `sqrt(n)`) for small
/// systems, else measured on three fixed probe vectors.
fn measure(
    a: &DMatrix<f64>,
    gens: &[Mat2],
    v: &DMatrix<f64>,
    vinv: &DMatrix<f64>,
) -> Result<(f64, f64, f64), DecompError> {
    let n = a.nrows();
    if n == 0 {
        return Ok((0.0, 1.0, 0.0));
    }
    let nb = gens.len();
    if 2 * nb != n || v.shape() != (n, n) || vinv.shape() != (n, n) {
        return Err(DecompError::WrongShape);
    }
    if v.iter().chain(vinv.iter()).any(|x| !x.is_finite()) {
        return Err(DecompError::EigenvectorsNotFinite);
    }
    let residual = block_residual(a, gens, v);
    let (kappa, inv_defect) = if n <= MAX_DENSE_CHECK_DIM {
        let sv = crate::physics::linalg::singular_values(v).ok_or(DecompError::SvdFailed)?;
        let smax = sv.first().copied().unwrap_or(0.0);
        let smin = sv.last().copied().unwrap_or(0.0);
        let kappa = if smin > 0.0 {
            smax / smin
        } else {
            f64::INFINITY
        };
        let defect = (crate::physics::linalg::matmul(vinv, v) - DMatrix::identity(n, n)).norm()
            / (n as f64).sqrt();
        (kappa, defect)
    } else {
        let (fv, fvinv) = (to_faer(v), to_faer(vinv));
        let norm = |m: &Mat<f64>| power_sigma(n, 30, |x, transpose| mat_vec(m, x, transpose));
        let mut defect: f64 = 0.0;
        for seed in 0..3usize {
            let x = DVector::from_fn(n, |i, _| {
                (((i + 1) * (7919 + 104_729 * seed)) % 1009) as f64 / 1009.0 - 0.5
            });
            let back = mat_vec(&fvinv, &mat_vec(&fv, &x, false), false);
            defect = defect.max((back - &x).norm() / x.norm());
        }
        (norm(&fv) * norm(&fvinv), defect)
    };
    if !kappa.is_finite() {
        return Err(DecompError::EigenvectorsSingular);
    }
    Ok((residual, kappa, inv_defect))
}

/// Decompose a generator that is block diagonal after a permutation: the
/// `coupled` indices form one general system (decomposed and checked as in
/// [`decompose`]); each pair in `free_pairs` (with its closed-form 2x2
/// generator) is an exactly decoupled mode, e.g. a mode with zero weight at
/// the contact point during contact (docs/numerics.md, "Leaving out what a scene does not need":
/// those modes are bit-identical with and without contact). Returns `None` when the coupled
/// part needs the dense fallback (the caller then decomposes the whole).
pub fn decompose_split(
    a: &DMatrix<f64>,
    coupled: &[usize],
    free_pairs: &[(usize, usize)],
    free_gens: &[Mat2],
    h: f64,
    structured: Option<(&str, Result<BlockEigen, SecularError>)>,
    allow_general: bool,
) -> Result<Option<PhaseDecomp>, DecompError> {
    let dim = a.nrows();
    let nc = coupled.len();
    let sub = DMatrix::from_fn(nc, nc, |i, j| a[(coupled[i], coupled[j])]);
    let d = decompose_via(&sub, h, structured, allow_general)?;
    let Form::Blocks { gens: cg } = d.form else {
        return Ok(None);
    };
    let nbc = cg.len();
    let nb = nbc + free_pairs.len();
    let mut v = DMatrix::zeros(dim, dim);
    let mut vinv = DMatrix::zeros(dim, dim);
    // coupled blocks: SoA columns k and nbc + k of the sub-decomposition go
    // to columns k and nb + k of the whole
    for k in 0..nbc {
        for (ri, &r) in coupled.iter().enumerate() {
            v[(r, k)] = d.v[(ri, k)];
            v[(r, nb + k)] = d.v[(ri, nbc + k)];
            vinv[(k, r)] = d.vinv[(k, ri)];
            vinv[(nb + k, r)] = d.vinv[(nbc + k, ri)];
        }
    }
    let mut gens = cg;
    for (j, (&(i0, i1), g)) in free_pairs.iter().zip(free_gens).enumerate() {
        let k = nbc + j;
        v[(i0, k)] = 1.0;
        v[(i1, nb + k)] = 1.0;
        vinv[(k, i0)] = 1.0;
        vinv[(nb + k, i1)] = 1.0;
        gens.push(*g);
    }
    let mut diag = d.diag;
    diag.dim = dim;
    diag.method = format!(
        "{} on the coupled {nc}-dim part + {} decoupled closed-form modes",
        diag.method,
        free_pairs.len()
    );
    Ok(Some(PhaseDecomp {
        form: Form::Blocks { gens },
        v,
        vinv,
        diag,
    }))
}

/// Largest dimension for which the dense `exp(A h)` cross-check and exact
/// SVDs are computed at compile time (O(dim^3) with nalgebra's Pade `exp`).
pub const MAX_DENSE_CHECK_DIM: usize = 400;

/// Power-iteration estimate of the largest singular value of
/// `P = V blockdiag(exp(G h)) V^-1`, O(dim^2) per iteration.
fn sigma_max_blocks_est(gens: &[Mat2], v: &DMatrix<f64>, vinv: &DMatrix<f64>, h: f64) -> f64 {
    let props: Vec<Mat2> = gens.iter().map(|g| exp2(g, h)).collect();
    let nb = props.len();
    let apply_blocks = |x: &mut DVector<f64>, transpose: bool| {
        for (k, p) in props.iter().enumerate() {
            let (a, b) = (x[k], x[nb + k]);
            if transpose {
                x[k] = p[0] * a + p[2] * b;
                x[nb + k] = p[1] * a + p[3] * b;
            } else {
                x[k] = p[0] * a + p[1] * b;
                x[nb + k] = p[2] * a + p[3] * b;
            }
        }
    };
    let (fv, fvinv) = (to_faer(v), to_faer(vinv));
    power_sigma(v.nrows(), 30, |x, transpose| {
        if transpose {
            let mut z = mat_vec(&fv, x, true);
            apply_blocks(&mut z, true);
            mat_vec(&fvinv, &z, true)
        } else {
            let mut y = mat_vec(&fvinv, x, false);
            apply_blocks(&mut y, false);
            mat_vec(&fv, &y, false)
        }
    })
}

/// Largest singular value of the operator `x -> apply(x, false)` (with
/// `apply(y, true)` its transpose) by power iteration on `M^T M` from a
/// fixed start vector: a lower bound that converges to `sigma_max`, stopped
/// after `iters` steps or when it changes by less than 1e-15 relative.
fn power_sigma(
    dim: usize,
    iters: usize,
    mut apply: impl FnMut(&DVector<f64>, bool) -> DVector<f64>,
) -> f64 {
    let mut x = DVector::from_fn(dim, |i, _| 1.0 + ((i * 7919) % 13) as f64 / 13.0);
    x /= x.norm();
    let mut sigma: f64 = 0.0;
    for _ in 0..iters {
        let y = apply(&x, false);
        let z = apply(&y, true);
        let n = z.norm();
        if !(n > 0.0) {
            return 0.0;
        }
        let next = n.sqrt();
        let done = (next - sigma).abs() <= 1e-15 * next;
        sigma = next;
        x = z / n;
        if done {
            break;
        }
    }
    sigma
}

fn dense_phase(
    a: &DMatrix<f64>,
    reference: DMatrix<f64>,
    residual: f64,
    kappa: f64,
    reason: Option<String>,
) -> PhaseDecomp {
    let dim = a.nrows();
    PhaseDecomp {
        form: Form::Dense { a: a.clone() },
        v: DMatrix::identity(dim, dim),
        vinv: DMatrix::identity(dim, dim),
        diag: DecompDiagnostics {
            dim,
            method: "dense exp(A h)".into(),
            residual,
            kappa,
            expm_rel_diff: 0.0,
            sigma_max: sigma_max(&reference),
            fallback_reason: reason,
            estimated: false,
        },
    }
}

/// Real block form from faer's real EVD (structure of arrays): `(gens, V,
/// V^{-1})`, unchecked ([`checked`] measures it).
fn eigen_blocks(a: &DMatrix<f64>) -> Result<BlockEigen, DecompError> {
    let n = a.nrows();
    if n == 0 {
        return Ok((Vec::new(), DMatrix::zeros(0, 0), DMatrix::zeros(0, 0)));
    }
    let fa = Mat::<f64>::from_fn(n, n, |i, j| a[(i, j)]);
    let mut s_re = Diag::<f64>::zeros(n);
    let mut s_im = Diag::<f64>::zeros(n);
    let mut u = Mat::<f64>::zeros(n, n);
    let scratch = evd_scratch::<f64>(
        n,
        ComputeEigenvectors::No,
        ComputeEigenvectors::Yes,
        Par::Seq,
        Default::default(),
    );
    let mut mem = MemBuffer::new(scratch);
    evd_real(
        fa.as_ref(),
        s_re.as_mut(),
        s_im.as_mut(),
        None,
        Some(u.as_mut()),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|e| DecompError::NoConvergence(format!("{e:?}")))?;

    let mut v = DMatrix::zeros(n, n);
    let mut gens: Vec<Mat2> = Vec::with_capacity(n / 2);
    let mut reals: Vec<(f64, usize)> = Vec::new();
    let mut col = 0;
    let mut j = 0;
    while j < n {
        let im = s_im[j];
        if im == 0.0 {
            reals.push((s_re[j], j));
            j += 1;
        } else {
            if j + 1 >= n {
                return Err(DecompError::UnpairedComplex);
            }
            // v = x + i y, normalised so |v| = 1; columns sqrt(2) x, sqrt(2) y.
            let norm: f64 = (0..n)
                .map(|i| u[(i, j)].powi(2) + u[(i, j + 1)].powi(2))
                .sum::<f64>()
                .sqrt();
            let s = std::f64::consts::SQRT_2 / norm;
            for i in 0..n {
                v[(i, col)] = u[(i, j)] * s;
                v[(i, col + 1)] = u[(i, j + 1)] * s;
            }
            let re = s_re[j];
            gens.push([re, im, -im, re]);
            col += 2;
            j += 2;
        }
    }
    if !reals.len().is_multiple_of(2) {
        return Err(DecompError::OddReal);
    }
    reals.sort_by(|x, y| x.0.total_cmp(&y.0));
    for pair in reals.chunks(2) {
        for (off, &(_, jj)) in pair.iter().enumerate() {
            let norm: f64 = (0..n).map(|i| u[(i, jj)].powi(2)).sum::<f64>().sqrt();
            for i in 0..n {
                v[(i, col + off)] = u[(i, jj)] / norm;
            }
        }
        gens.push([pair[0].0, 0.0, 0.0, pair[1].0]);
        col += 2;
    }
    debug_assert_eq!(col, n);
    if v.iter().any(|x| !x.is_finite()) {
        return Err(DecompError::EigenvectorsNotFinite);
    }
    // faer's blocked LU (nalgebra's unblocked one took most of a
    // 2002-dimensional compile)
    let vinv = crate::physics::linalg::inverse(&v).ok_or(DecompError::EigenvectorsSingular)?;
    // Structure of arrays: block k's coordinates go to k and nb + k, so the
    // engine's kernels stream contiguous arrays (docs/numerics.md, "Stepping a phase: 2x2 blocks").
    let nb = gens.len();
    let perm = |c: usize| {
        if c.is_multiple_of(2) {
            c / 2
        } else {
            nb + c / 2
        }
    };
    let mut v_soa = DMatrix::zeros(n, n);
    let mut vinv_soa = DMatrix::zeros(n, n);
    for c in 0..n {
        v_soa.set_column(perm(c), &v.column(c));
        vinv_soa.set_row(perm(c), &vinv.row(c));
    }
    Ok((gens, v_soa, vinv_soa))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn critically_damped_two_by_two_is_one_exact_block() {
        // Hammer against a rigid wall with exactly critical contact damping:
        // A = [[0, -w], [w, -2 w]] is a Jordan block (NUMERICS X4). As a
        // single 2x2 block exp2 is exact: e^{-w t} [[1 + w t, -w t], [w t,
        // 1 - w t]] in closed form.
        let w = 2.0 * std::f64::consts::PI * 3000.0;
        let a = DMatrix::from_row_slice(2, 2, &[0.0, -w, w, -2.0 * w]);
        let h = 1.0 / 44100.0;
        let d = decompose(&a, h).unwrap();
        println!("{:?}", d.diag);
        let Form::Blocks { gens } = &d.form else {
            panic!("not a block: {:?}", d.diag)
        };
        assert!(d.diag.fallback_reason.is_none());
        for t in [h * 1e-6, h * 0.37, h, 10.0 * h] {
            let p = exp2(&gens[0], t);
            let e = (-w * t).exp();
            let want = [e * (1.0 + w * t), -e * w * t, e * w * t, e * (1.0 - w * t)];
            let err = p
                .iter()
                .zip(&want)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(err < 4e-16, "t {t:e}: {p:?} vs {want:?}");
        }
    }

    #[test]
    fn near_defective_larger_system_falls_back_to_dense() {
        // Two identical critically damped pairs: a double Jordan structure
        // of dimension 4 (no 2x2 shortcut).
        let w = 2.0 * std::f64::consts::PI * 3000.0;
        let mut a = DMatrix::zeros(4, 4);
        for b in [0, 2] {
            a[(b, b + 1)] = -w;
            a[(b + 1, b)] = w;
            a[(b + 1, b + 1)] = -2.0 * w;
        }
        let d = decompose(&a, 1.0 / 44100.0).unwrap();
        println!("{:?}", d.diag);
        assert!(matches!(d.form, Form::Dense { .. }), "{:?}", d.diag);
        assert!(d.diag.fallback_reason.is_some());
    }

    #[test]
    fn underdamped_system_uses_blocks_and_matches_expm() {
        let w = 2.0 * std::f64::consts::PI * 3000.0;
        let a = DMatrix::from_row_slice(2, 2, &[0.0, -w, w, -0.2 * w]);
        let d = decompose(&a, 1.0 / 44100.0).unwrap();
        println!("{:?}", d.diag);
        assert!(matches!(d.form, Form::Blocks { .. }));
        assert!(d.diag.expm_rel_diff < 1e-13);
        assert!(d.diag.kappa < 2.0);
    }
}
