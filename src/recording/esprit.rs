//! ESPRIT on one band's decimated signal: the signal subspace from the SVD
//! of a Hankel matrix of the samples, the model order from the singular
//! values against the noise's, the poles from the subspace's shift
//! invariance, checked at a second, higher order; the amplitudes by least
//! squares on the samples; each pole's uncertainty from the Cramer-Rao
//! bound of one damped exponential in white noise.

use super::RecordingError;
use faer::linalg::solvers::SolveLstsq;
use faer::{c64, Mat, MatRef};

/// The Hankel matrix's rows: a third of the samples (the usual choice for
/// the variance of ESPRIT's poles), at most this many (the SVD's cost grows
/// with the square of the rows).
const MAX_ROWS: usize = 256;

/// A singular value counts as signal when it exceeds the largest a
/// noise-only Hankel matrix would show (the Marchenko-Pastur edge
/// `sigma (sqrt(N) + sqrt(L))`) by this factor (3.5 dB).
const EDGE_MARGIN: f64 = 1.5;

/// A pole is stable when the fit at the higher order has one within this
/// distance, in `ln p` per decimated sample, divided by the number of
/// samples `M` (1 / M is 16 % of the frequency resolution `2 pi / M`: a
/// real partial, not exactly one damped exponential, moves that much
/// between orders), or within 10 of its own standard deviations when that
/// is more.
const STABLE_TOLERANCE: f64 = 1.0;

/// Unstable poles closer than this many frequency resolutions (`2 pi /
/// M` in `arg p`) to one another are one cluster: a partial whose
/// envelope is not one exponential (a beat, a room, a fade) that the fit
/// spreads over neighbouring poles with partly cancelling amplitudes.
const CLUSTER_CELLS: f64 = 30.0;

/// What became of a pole of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Status {
    /// The fit at the higher order has it too, or it stands for a
    /// cluster.
    Stable,
    /// No partner at the higher order and no unstable neighbour to form a
    /// cluster with: a fit of the noise.
    Unstable,
    /// A member of a cluster, replaced by the cluster's one pole.
    Merged,
}

/// A band's fit.
#[derive(Debug, Clone, Default)]
pub(crate) struct Fit {
    /// Poles of the decimated signal: the fit's, then one per cluster.
    pub poles: Vec<c64>,
    /// Complex amplitude of each pole at the first decimated sample: a
    /// kept pole's by least squares on the samples with the kept poles
    /// alone, a dropped one's from the fit with every pole.
    pub amps: Vec<c64>,
    /// What became of each pole.
    pub status: Vec<Status>,
    /// The Cramer-Rao standard deviation of `ln p` (its real and its
    /// imaginary part each) per decimated sample.
    pub sd: Vec<f64>,
    /// The energy of each pole's component over the samples, over the
    /// noise's variance per sample (the matched-filter signal-to-noise ratio).
    pub snr: Vec<f64>,
}

/// Fit damped exponentials to `y`, at most `max_order` of them; the
/// noise's variance is taken as at least `floor_var`.
pub(crate) fn fit(y: &[c64], max_order: usize, floor_var: f64) -> Result<Fit, RecordingError> {
    let m = y.len();
    let rows = (m / 3).min(MAX_ROWS);
    if rows < 4 {
        return Ok(Fit::default());
    }
    let cols = m - rows + 1;
    let h = Mat::<c64>::from_fn(rows, cols, |i, j| y[i + j]);
    let svd = h
        .thin_svd()
        .map_err(|e| RecordingError::Numerics(format!("SVD of a band's Hankel matrix: {e:?}")))?;
    let s: Vec<f64> = svd.S().column_vector().iter().map(|v| v.re).collect();
    // The floor of the arithmetic: 1e-12 of the strongest singular value
    // (a noiseless signal's noise is its rounding, not a median of zeros).
    let floor = s.first().map_or(0.0, |v| (1e-12 * v).powi(2) / cols as f64);
    let noise_var = noise_variance(&s, cols).max(floor).max(floor_var);
    let edge = EDGE_MARGIN * (noise_var.sqrt()) * ((cols as f64).sqrt() + (rows as f64).sqrt());
    let cap = max_order.min(rows / 2 - 1);
    let order = s.iter().take_while(|v| **v > edge).count().min(cap);
    if order == 0 {
        return Ok(Fit::default());
    }
    let u = svd.U();
    let mut poles = esprit(u, order)?;
    let higher = esprit(u, (order + (order / 4).max(2)).min(rows / 2))?;
    let fitted = amplitudes(y, &poles)?;
    // A pole moves between orders by about its own uncertainty: the
    // tolerance is the larger of 16 % of the resolution and 10 of them.
    let mut status: Vec<Status> = poles
        .iter()
        .zip(&fitted)
        .map(|(p, c)| {
            let sd = bound(*p, *c, m, noise_var).0;
            let tol = (STABLE_TOLERANCE / m as f64).max(10.0 * sd);
            if higher.iter().any(|q| (log(*p) - log(*q)).norm() < tol) {
                Status::Stable
            } else {
                Status::Unstable
            }
        })
        .collect();
    for members in clusters(&poles, &status, m) {
        let sum: Vec<c64> = (0..m)
            .map(|j| {
                members
                    .iter()
                    .map(|&k| fitted[k] * (log(poles[k]) * j as f64).exp())
                    .sum()
            })
            .collect();
        if let Some(p) = one_pole(&sum) {
            for &k in &members {
                status[k] = Status::Merged;
            }
            poles.push(p);
            status.push(Status::Stable);
        }
    }
    // The kept poles' amplitudes by least squares with the kept poles
    // alone: what a dropped pole carried goes to its neighbours.
    let kept: Vec<usize> = (0..poles.len())
        .filter(|&k| status[k] == Status::Stable)
        .collect();
    let kept_poles: Vec<c64> = kept.iter().map(|&k| poles[k]).collect();
    let mut amps = fitted;
    amps.resize(poles.len(), c64::new(0.0, 0.0));
    for (a, &k) in amplitudes(y, &kept_poles)?.into_iter().zip(&kept) {
        amps[k] = a;
    }
    let (sd, snr): (Vec<f64>, Vec<f64>) = poles
        .iter()
        .zip(&amps)
        .map(|(p, c)| bound(*p, *c, m, noise_var))
        .unzip();
    Ok(Fit {
        poles,
        amps,
        status,
        sd,
        snr,
    })
}

/// The clusters among the unstable poles: runs of two or more, each
/// closer than [`CLUSTER_CELLS`] resolutions (in frequency) to the next,
/// as lists of indices.
fn clusters(poles: &[c64], status: &[Status], m: usize) -> Vec<Vec<usize>> {
    let gap = CLUSTER_CELLS * 2.0 * std::f64::consts::PI / m as f64;
    let arg = |k: usize| log(poles[k]).im;
    let mut loose: Vec<usize> = (0..poles.len())
        .filter(|&k| status[k] == Status::Unstable)
        .collect();
    loose.sort_by(|&a, &b| arg(a).total_cmp(&arg(b)));
    let mut runs: Vec<Vec<usize>> = Vec::new();
    for k in loose {
        match runs.last_mut() {
            Some(run) if run.last().is_some_and(|&j| arg(k) - arg(j) <= gap) => run.push(k),
            _ => runs.push(vec![k]),
        }
    }
    runs.retain(|run| run.len() > 1);
    runs
}

/// The one pole that best continues `s` by one sample (the least-squares
/// linear predictor of order one, `p = sum s[j+1] s[j]* / sum |s[j]|^2`):
/// a cluster's frequency and decay, weighted by its energy. `None` when
/// `s` has no energy.
fn one_pole(s: &[c64]) -> Option<c64> {
    let (mut num, mut den) = (c64::new(0.0, 0.0), 0.0);
    for w in s.windows(2) {
        num += w[1] * w[0].conj();
        den += w[0].norm_sqr();
    }
    let p = num / den;
    (den > 0.0 && p.re.is_finite() && p.im.is_finite() && p.norm() > 0.0).then_some(p)
}

/// The complex logarithm of a pole, `ln|p| + i arg p` (arg in `(-pi, pi]`).
pub(crate) fn log(p: c64) -> c64 {
    c64::new(p.norm().ln(), p.im.atan2(p.re))
}

/// The noise's variance per sample from the singular values: the median
/// of their squares over the columns (the noise's singular values spread
/// around `sigma sqrt(N)`; the signal's are few, so the median is noise's).
fn noise_variance(s: &[f64], cols: usize) -> f64 {
    let mut sq: Vec<f64> = s.iter().map(|v| v * v).collect();
    sq.sort_by(f64::total_cmp);
    let med = if sq.is_empty() { 0.0 } else { sq[sq.len() / 2] };
    med / cols as f64
}

/// The `order` poles of the signal subspace `u[:, ..order]`: `Phi` solves
/// `U1 Phi = U2` (U without its last, its first row) in least squares, and
/// its eigenvalues are the poles.
fn esprit(u: MatRef<'_, c64>, order: usize) -> Result<Vec<c64>, RecordingError> {
    let rows = u.nrows();
    let u1 = u.submatrix(0, 0, rows - 1, order);
    let u2 = u.submatrix(1, 0, rows - 1, order);
    let phi = u1.qr().solve_lstsq(u2);
    if phi
        .col_iter()
        .any(|c| c.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())))
    {
        return Err(RecordingError::Numerics(
            "ESPRIT's shift matrix is not finite".into(),
        ));
    }
    phi.eigenvalues().map_err(|e| {
        RecordingError::Numerics(format!("eigenvalues of ESPRIT's shift matrix: {e:?}"))
    })
}

/// Least-squares amplitudes of the poles on the samples (a Vandermonde
/// system). Poles that grow beyond `1e6` over the samples get no column
/// (their amplitude is 0): they are dropped as growing anyway.
fn amplitudes(y: &[c64], poles: &[c64]) -> Result<Vec<c64>, RecordingError> {
    let m = y.len();
    let usable: Vec<usize> = (0..poles.len())
        .filter(|&k| poles[k].norm().ln() * (m as f64) < 1e6_f64.ln())
        .collect();
    let mut out = vec![c64::new(0.0, 0.0); poles.len()];
    if usable.is_empty() {
        return Ok(out);
    }
    let v = Mat::<c64>::from_fn(m, usable.len(), |j, k| {
        (log(poles[usable[k]]) * j as f64).exp()
    });
    let rhs = Mat::<c64>::from_fn(m, 1, |j, _| y[j]);
    let c = v.qr().solve_lstsq(&rhs);
    for (i, &k) in usable.iter().enumerate() {
        let a = c[(i, 0)];
        if !(a.re.is_finite() && a.im.is_finite()) {
            return Err(RecordingError::Numerics("amplitudes are not finite".into()));
        }
        out[k] = a;
    }
    Ok(out)
}

/// The Cramer-Rao standard deviation of `ln p` (each part) for one damped
/// exponential `c p^j`, `j < m`, in complex white noise of variance
/// `noise_var`, its amplitude and phase unknown too; and the component's
/// energy over the noise's variance.
fn bound(p: c64, c: c64, m: usize, noise_var: f64) -> (f64, f64) {
    let r2 = p.norm_sqr().min(1.0);
    let (mut s0, mut s1, mut s2, mut w) = (0.0, 0.0, 0.0, 1.0);
    for j in 0..m {
        let jf = j as f64;
        s0 += w;
        s1 += jf * w;
        s2 += jf * jf * w;
        w *= r2;
        if w < 1e-30 {
            break;
        }
    }
    let energy = c.norm_sqr() * s0;
    let noise = noise_var.max(f64::MIN_POSITIVE);
    let info = 2.0 * c.norm_sqr() / noise * (s2 - s1 * s1 / s0);
    let sd = if info > 0.0 {
        1.0 / info.sqrt()
    } else {
        f64::INFINITY
    };
    (sd, energy / noise)
}
