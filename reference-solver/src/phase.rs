//! One phase (flight or contact) as an affine linear system in physical
//! coordinates, balanced, with the dense exponentials the solver steps with.
//!
//! The augmented state is `[z; 1]`, `z = [q; q'; x_h; v_h]` (then `x_b;
//! v_b` with a back mass, then each extra hammer's and each mass's `x, v`),
//! and the phase matrix `[[A, b], [0, 0]]` carries gravity, and the force
//! `k (h_lower - h_upper - gap)` of an active link's gap and walls, as the
//! affine term `b`, so that `exp` of the augmented matrix gives the affine
//! part of the flow exactly. The event rows take the same constants in the
//! constant coordinate. On a moving surface the state is `[z; s; v; I; 1]`
//! (the surface's height and rate, and the impulse of the hammer's contact
//! force; see [`augmented_matrix`]).
//!
//! Physical coordinates are badly scaled (entries from 1 to `k / m_h`, up to
//! 1e17): a Pade exponential's error is relative to the matrix norm, so the
//! entries `~ sin(omega t) / omega` would lose everything. The matrix is
//! therefore balanced by a diagonal similarity `B = D^-1 A D` with powers of
//! two (Parlett-Reinsch, as LAPACK's `gebal` and MATLAB's `expm` do): exact
//! in floating point, it only changes units, and brings `|B|` within a small
//! factor of the spectral radius. The solver steps `y = D^-1 z`.
//!
//! The matrix itself is double-double ([`augmented_matrix`]): in physical
//! coordinates the contact force is a small difference of large terms, and
//! entries rounded to f64 one by one describe a slightly different contact
//! (a heavy hammer pressed through a stiff contact moved by 1e-8). The
//! balancing is decided on its f64 rounding and applied to it exactly.
//!
//! The propagators the exact states go through are double-double (see
//! [`crate::dd`]): the Taylor series of `exp(B tau)` for `|B tau| <= 0.5`,
//! checked against nalgebra's Pade `exp` of the same sub-step (of the f64
//! matrix) when the phase is built, and whole numbers of sub-steps by
//! repeated squaring. The f64 Pade sub-step propagator marches the state
//! between exact anchors, for the event search only.

use crate::dd::{exp_taylor, exp_taylor_apply, Dd, DdMat};
use crate::{End, Model};
use nalgebra::DMatrix;

/// Largest `|B|_1 h_sub` of a sub-step: over a sub-step the fastest component
/// turns by at most half a radian, so the penetration has at most one
/// interior extremum (the event search relies on it).
pub(crate) const MAX_NORM_STEP: f64 = 0.5;

/// Whole sub-steps between two re-anchorings of the f64 marched state on the
/// exact one (it only decides where to look for switches; 256 f64 products
/// drift by ~1e-14).
pub(crate) const RESYNC: usize = 256;

/// Coordinates a driven phase adds between `z` and the constant: the
/// surface's height `s`, its rate `v` and the impulse `I` of the hammer's
/// contact force since the sample's start.
pub(crate) const DRIVE: usize = 3;

/// A phase ready to step.
#[derive(Debug, Clone)]
pub(crate) struct Phase {
    /// The contacts in contact (bit `c` for contact `c`; flight: 0).
    pub(crate) active: u32,
    /// Augmented dimension: [`Model::state_dim`] `+ 1` (`2 N + 3` for the
    /// paper's scene).
    pub(crate) dim: usize,
    /// Balancing scales: `z_i = d_i y_i` (the last entry scales the constant
    /// coordinate: `y_last = 1 / d_last`).
    pub(crate) d: Vec<f64>,
    /// `|B|_1` [1/s].
    pub(crate) norm: f64,
    /// Sub-steps per sample and their length `h / m` [s].
    pub(crate) m: usize,
    pub(crate) h_sub: f64,
    /// Dyadic levels: a sub-step is `2^levels` time units, each unit at most
    /// [`crate::TIME_RESOLUTION`] of a sample.
    pub(crate) levels: u32,
    /// `exp(B h_sub)` in f64 (nalgebra's Pade), row-major: marches the
    /// state that decides where to search.
    pub(crate) e1: Vec<f64>,
    /// `fine[j] = exp(B h_sub 2^-j)`, `j = 0..=levels`, double-double: the
    /// bisection reaches `k` time units after a point with one product per
    /// set bit of `k`.
    pub(crate) fine: Vec<DdMat>,
    /// `big[l] = exp(B h_sub 2^l)`, `2^l <= m`, double-double: a grid point
    /// `j` sub-steps after an exact anchor is reached with one product per
    /// set bit of `j`, not `j` chained products.
    pub(crate) big: Vec<DdMat>,
    /// Balanced augmented matrix `B = D^-1 [[A, b], [0, 0]] D`, row-major,
    /// double-double (see [`augmented_matrix`]; `e1` and the balancing use
    /// its rounding to f64).
    pub(crate) b_dd: Vec<Dd>,
    /// Rows giving each contact's `p` and `p'` from the balanced state `y`
    /// (`row_p`'s last entry: the constant of `p`, gap and walls, rounded to
    /// f64 and scaled to the constant coordinate).
    pub(crate) row_p: Vec<Vec<f64>>,
    pub(crate) row_v: Vec<Vec<f64>>,
    /// Each contact's constant of `p` (`-gap`, plus the lower wall's
    /// height, less the upper wall's) in double-double, as the phase
    /// matrices' force rows have it: [`Phase::event_dd`] takes it instead of
    /// `row_p`'s rounded last entry, so that the exact states switch where
    /// the exact force vanishes.
    pub(crate) p_const: Vec<Dd>,
}

impl Phase {
    /// Build the phase of `model` with the contacts `active` (bit `c` for
    /// contact `c`) for sample period `h`, with sub-steps of `|B|_1 h_sub
    /// <= max_norm_step`.
    ///
    /// `driven`: the state carries the moving surface under the hammer's
    /// contact, `[z; s; v; I; 1]` (see [`augmented_matrix`]).
    pub(crate) fn new(
        model: &Model,
        active: u32,
        h: f64,
        max_norm_step: f64,
        driven: bool,
    ) -> Self {
        let n = model.n_modes();
        let nz = model.state_dim();
        let dim = nz + 1 + if driven { DRIVE } else { 0 };
        let a_dd = augmented_matrix(model, active, driven);
        let a = DMatrix::from_row_iterator(dim, dim, a_dd.iter().map(|v| v.to_f64()));
        let hammer = (model.mass_index(0), model.mass_index(0) + 1);
        let (b, d) = balance(&a, driven.then_some(hammer));
        // the same similarity on the exact entries (powers of two: exact)
        let b_dd: Vec<Dd> = a_dd
            .iter()
            .enumerate()
            .map(|(ij, v)| v.mul_f64(d[ij % dim] / d[ij / dim]))
            .collect();
        debug_assert!(b_dd.iter().zip(flat(&b)).all(|(x, y)| x.to_f64() == y));
        let norm = norm1(&b);
        let m = ((norm * h / max_norm_step).ceil() as usize).max(1);
        let h_sub = h / m as f64;
        // units of h_sub 2^-levels <= TIME_RESOLUTION h
        let levels =
            ((1.0 / (crate::TIME_RESOLUTION * m as f64)).log2().ceil() as u32).clamp(1, 62);
        let fine: Vec<DdMat> = (0..=levels)
            .map(|j| exp_taylor(&b_dd, dim, h_sub * 0.5f64.powi(j as i32)))
            .collect();
        let e1 = flat(&(&b * h_sub).exp());
        // two independent computations of the same sub-step exponential
        let scale = fine[0].max_abs();
        let diff = e1
            .iter()
            .zip(fine[0].to_f64())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            diff <= 1e-13 * scale,
            "sub-step exponential: Pade and Taylor disagree by {diff:e} (scale {scale:e})"
        );
        let mut big = vec![fine[0].clone()];
        for _ in 1..usize::BITS - m.leading_zeros() {
            let g = big.last().expect("level 0");
            big.push(g.mul(g));
        }
        // p = x_lower - x_upper - gap, p' = v_lower - v_upper, in y = D^-1
        // z, per contact (for a hammer's: sum w_i q_i - x_h); the constant
        // (gap, walls' heights) on the constant coordinate, `z_last = d_last
        // y_last = 1`
        let one = dim - 1;
        let (mut row_p, mut row_v, mut p_const) = (Vec::new(), Vec::new(), Vec::new());
        for c in 0..model.n_contacts() {
            let l = model.link(c);
            let mut rp = vec![0.0; dim];
            let mut rv = vec![0.0; dim];
            let mut p0 = Dd::from_f64(-l.gap_m);
            for (end, s) in [(&l.lower, 1.0), (&l.upper, -1.0)] {
                match end {
                    // a mode weighing on both sides (two points of one
                    // object) gets `w_l - w_u` rounded once: `u |x|` of
                    // `p`, as rounding `x` itself would
                    End::Point(w) => {
                        for i in 0..n {
                            rp[i] += s * w[i] * d[i];
                            rv[n + i] += s * w[i] * d[n + i];
                        }
                    }
                    End::Mass(i) => {
                        let k = model.mass_index(*i);
                        rp[k] += s * d[k];
                        rv[k + 1] += s * d[k + 1];
                    }
                    End::Wall(h) => p0 = p0 + Dd::from_f64(s * h),
                }
            }
            if driven && c == 0 {
                // the hammer's contact sees the surface: p += s, p' += v
                rp[nz] += d[nz];
                rv[nz + 1] += d[nz + 1];
            }
            rp[one] = p0.to_f64() * d[one];
            row_p.push(rp);
            row_v.push(rv);
            p_const.push(p0);
        }
        Phase {
            active,
            dim,
            d,
            norm,
            m,
            h_sub,
            levels,
            e1,
            fine,
            big,
            b_dd,
            row_p,
            row_v,
            p_const,
        }
    }

    /// `exp(B tau) y` in double-double (Taylor series on the vector; `|B
    /// tau| <= 0.5`).
    pub(crate) fn exp_apply(&self, tau: f64, y: &[Dd]) -> Vec<Dd> {
        exp_taylor_apply(&self.b_dd, tau, y)
    }

    /// The state `count` whole sub-steps after `y` (dyadic products).
    pub(crate) fn advance_grid(&self, y: &[Dd], count: usize) -> Vec<Dd> {
        assert!(count >> self.big.len() == 0, "advance_grid: {count} > m");
        let mut cur = y.to_vec();
        for (l, g) in self.big.iter().enumerate() {
            if count & (1 << l) != 0 {
                cur = g.apply(&cur);
            }
        }
        cur
    }

    /// The state `units` time units (`h_sub 2^-levels`) after `y`, `units
    /// <= 2^levels`.
    pub(crate) fn advance_fine(&self, y: &[Dd], units: u64) -> Vec<Dd> {
        let mut cur = y.to_vec();
        for l in 0..=self.levels {
            if units & (1u64 << l) != 0 {
                cur = self.fine[(self.levels - l) as usize].apply(&cur);
            }
        }
        cur
    }

    /// Contact `c`'s `(p, p')` of the exact state `y` (the constant of `p`
    /// in double-double, times the constant coordinate `d_last y_last = 1`).
    pub(crate) fn event_dd(&self, c: usize, y: &[Dd]) -> (f64, f64) {
        let one = self.dim - 1;
        let dot = |row: &[f64], c0: Dd| {
            row[..one]
                .iter()
                .zip(y)
                .fold(
                    c0,
                    |acc, (&r, v)| if r == 0.0 { acc } else { acc + v.mul_f64(r) },
                )
                .to_f64()
        };
        let c0 = if self.p_const[c].hi == 0.0 {
            Dd::ZERO
        } else {
            self.p_const[c] * y[one].mul_f64(self.d[one])
        };
        (dot(&self.row_p[c], c0), dot(&self.row_v[c], Dd::ZERO))
    }

    /// Balanced state of the physical state `z` (exact: the scales are
    /// powers of two).
    pub(crate) fn to_balanced(&self, z: &[Dd]) -> Vec<Dd> {
        let mut y: Vec<Dd> = z
            .iter()
            .zip(&self.d)
            .map(|(z, d)| z.mul_f64(1.0 / d))
            .collect();
        y.push(Dd::from_f64(1.0 / self.d[self.dim - 1]));
        y
    }

    /// Physical state of the balanced state `y` (without the constant).
    pub(crate) fn to_physical(&self, y: &[Dd]) -> Vec<Dd> {
        y[..self.dim - 1]
            .iter()
            .zip(&self.d)
            .map(|(y, d)| y.mul_f64(*d))
            .collect()
    }

    /// Contact `c`'s `(p, p')` of the balanced state `y`.
    #[inline]
    pub(crate) fn event(&self, c: usize, y: &[f64]) -> (f64, f64) {
        (dot(&self.row_p[c], y), dot(&self.row_v[c], y))
    }

    /// Whether contact `c` is in contact in this phase.
    #[inline]
    pub(crate) fn in_contact(&self, c: usize) -> bool {
        self.active & (1 << c) != 0
    }
}

/// The augmented phase matrix `[[A, b], [0, 0]]` in physical coordinates
/// `[z; 1]`, row-major, in double-double: gravity, and with links the
/// gaps' and walls' forces `k (h_lower - h_upper - gap)`, are the affine
/// column `b`.
///
/// `driven`: the coordinates `[z; s; v; I; 1]` of a moving surface under
/// the hammer's contact. Inside a sample the surface moves at a constant
/// rate, `s' = v`, `v' = 0`; the hammer's contact force `F = k (x_c + s -
/// x_h) + c (v_c + v - v_h)` takes the columns of `s` (`k`) and `v` (`c`)
/// beside those of `z`, wherever it acts (the hammer's and the modes'
/// rows), and its impulse `I' = F` is the row of `I` (no column: nothing
/// depends on it).
///
/// Why double-double and not f64 entries: in physical coordinates the contact
/// force `F = k (sum w_j q_j - x_h) + c (...)` is a difference of terms far
/// larger than itself (a heavy hammer pressed on the object through a stiff
/// contact: `|p| / |x_h|` ~ 1e-8 and less), and its row `k w_j, -k, ...`
/// rounded entry by entry is the force of a slightly different contact,
/// whose spring also pulls on `x_h` and `q` themselves (stiffness `u k`, and
/// `u w_i^2 k` on mode `i` where `-omega_i^2 - w_i^2 k` is rounded): a
/// systematic error of the model, not of its integration, that no sub-step
/// length reduces. On a 327 kg hammer pressed on the 0.327 kg object at k =
/// 6.5e13 N/m it moved the hammer height by 1.2e-8 (relative L2 over 50 ms)
/// and contact instants by 7e-5 samples from DOP853, whose right-hand side
/// forms `p` first; a one-ulp change of three entries moved them by 9e-9.
/// Here each entry is the exact sum and product of the model's f64 numbers
/// to ~1e-32 relative, so `F` keeps `~1e-32 |k x|` of error.
pub(crate) fn augmented_matrix(model: &Model, active: u32, driven: bool) -> Vec<Dd> {
    let n = model.n_modes();
    let nz = model.state_dim();
    let dim = nz + 1 + if driven { DRIVE } else { 0 };
    let (xh, vh, one) = (2 * n, 2 * n + 1, dim - 1);
    let mut a = vec![Dd::ZERO; dim * dim];
    let at = |i: usize, j: usize| i * dim + j;
    if driven {
        a[at(nz, nz + 1)] = Dd::ONE;
    }
    for (i, md) in model.modes.iter().enumerate() {
        let w = md.omega();
        a[at(i, n + i)] = Dd::ONE;
        a[at(n + i, i)] = -Dd::from_f64(w).mul_f64(w);
        a[at(n + i, n + i)] = Dd::from_f64(-2.0 * md.sigma());
    }
    a[at(xh, vh)] = Dd::ONE;
    a[at(vh, one)] = Dd::from_f64(-model.hammer.gravity_m_per_s2);
    if let Some(b) = model.back {
        // G = k_s (x_b - x_h) + c_s (v_b - v_h): +G / m_h on the face,
        // -G / m_b on the back mass
        let (xb, vb) = (2 * n + 2, 2 * n + 3);
        let (ks, cs) = (
            Dd::from_f64(b.spring_n_per_m),
            Dd::from_f64(b.damping_n_s_per_m),
        );
        let (mh, mb) = (model.hammer.mass_kg, b.mass_kg);
        a[at(xb, vb)] = Dd::ONE;
        a[at(vb, one)] = Dd::from_f64(-model.hammer.gravity_m_per_s2);
        for (col, g) in [(xb, ks), (xh, -ks), (vb, cs), (vh, -cs)] {
            a[at(vh, col)] = a[at(vh, col)] + g.div_f64(mh);
            a[at(vb, col)] = a[at(vb, col)] - g.div_f64(mb);
        }
    }
    // the other point masses (extra hammers, masses): free under gravity
    for i in 1..model.n_masses() {
        let j = model.mass_index(i);
        a[at(j, j + 1)] = Dd::ONE;
        a[at(j + 1, one)] = Dd::from_f64(-model.mass_of(i).gravity_m_per_s2);
    }
    for cc in (0..model.n_contacts()).filter(|c| active & (1 << c) != 0) {
        let l = model.link(cc);
        let k = Dd::from_f64(l.contact.stiffness_n_per_m);
        let c = Dd::from_f64(l.contact.damping_n_s_per_m);
        // F = k p + c p' with p = x_lower - x_upper - gap: row of F in z
        // (for a hammer's contact: k (sum w_j q_j - x_h) + c (...)); the
        // gap and the walls' heights on the constant column
        let mut f = vec![Dd::ZERO; dim];
        f[one] = -k.mul_f64(l.gap_m);
        let surface = driven && cc == 0;
        if surface {
            f[nz] = k;
            f[nz + 1] = c;
        }
        for (end, s) in [(&l.lower, 1.0), (&l.upper, -1.0)] {
            match end {
                End::Point(w) => {
                    for j in 0..n {
                        f[j] = f[j] + k.mul_f64(s * w[j]);
                        f[n + j] = f[n + j] + c.mul_f64(s * w[j]);
                    }
                }
                End::Mass(i) => {
                    let j = model.mass_index(*i);
                    f[j] = f[j] + k.mul_f64(s);
                    f[j + 1] = f[j + 1] + c.mul_f64(s);
                }
                End::Wall(h) => f[one] = f[one] + k.mul_f64(s * h),
            }
        }
        // lower: -F (an object's q_i'' += -w_i F, a mass's v' += -F / m);
        // upper: +F; a wall takes nothing
        for (end, s) in [(&l.lower, -1.0), (&l.upper, 1.0)] {
            match end {
                End::Point(w) => {
                    for i in 0..n {
                        if w[i] == 0.0 {
                            continue;
                        }
                        for (col, fc) in f.iter().enumerate() {
                            a[at(n + i, col)] = a[at(n + i, col)] + fc.mul_f64(s * w[i]);
                        }
                    }
                }
                End::Mass(i) => {
                    let (v, m) = (model.mass_index(*i) + 1, model.mass_of(*i).mass_kg);
                    for (col, fc) in f.iter().enumerate() {
                        a[at(v, col)] = a[at(v, col)] + fc.div_f64(s * m);
                    }
                }
                End::Wall(_) => {}
            }
        }
        if surface {
            // the impulse's row: I' = F
            a[(nz + 2) * dim..(nz + 3) * dim].copy_from_slice(&f);
        }
    }
    a
}

/// Parlett-Reinsch balancing by powers of two: `B = D^-1 A D`, returned with
/// the diagonal of `D`. Rows or columns without off-diagonal entries keep
/// scale 1. The constant coordinate (last) is then scaled so that the affine
/// column adds nothing to `|B|_1` (its scale is free: it only fixes the value
/// `1 / d` the constant coordinate carries).
///
/// `drive`: the hammer's height and velocity indices in a driven matrix
/// (coordinates `[z; s; v; I; 1]`, see [`augmented_matrix`]). The surface's
/// coordinates are inputs (`v` has no row, `I` no column), which the
/// iteration cannot scale: `z` is balanced alone, then `s` and `v` take
/// the scales of the hammer's height and velocity (their columns are parts
/// of those columns: the contact force's), and `I` a scale that leaves its
/// row (the force) at most 1/16 of the largest column sum.
pub(crate) fn balance(a: &DMatrix<f64>, drive: Option<(usize, usize)>) -> (DMatrix<f64>, Vec<f64>) {
    let dim = a.nrows();
    let mut core = dim - 1;
    if drive.is_some() {
        core -= DRIVE;
    }
    let mut b = a.clone();
    let mut d = vec![1.0; dim];
    for _sweep in 0..200 {
        let mut done = true;
        for i in 0..core {
            let mut c = 0.0;
            let mut r = 0.0;
            for j in 0..core {
                if j != i {
                    c += b[(j, i)].abs();
                    r += b[(i, j)].abs();
                }
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let mut cc = c;
            while cc < r / 2.0 {
                f *= 2.0;
                cc *= 4.0;
            }
            while cc >= r * 2.0 {
                f /= 2.0;
                cc /= 4.0;
            }
            if (cc + r) / f < 0.95 * s {
                done = false;
                d[i] *= f;
                for j in 0..dim {
                    b[(i, j)] /= f;
                    b[(j, i)] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
    if let Some((xh, vh)) = drive {
        let hammer = (d[xh], d[vh]);
        balance_drive(&mut b, &mut d, core, hammer);
        core += DRIVE;
    }
    let core_norm = (0..core)
        .map(|j| (0..core).map(|i| b[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let affine: f64 = (0..core).map(|i| b[(i, core)].abs()).sum();
    if affine > 0.0 && core_norm > 0.0 {
        // power of two f with affine * f <= core_norm
        let f = 2f64.powi((core_norm / affine).log2().floor() as i32);
        d[core] = f;
        for i in 0..core {
            b[(i, core)] *= f;
        }
    }
    (b, d)
}

/// The drive's part of [`balance`]: coordinates `s, v, I` at `nz, nz + 1,
/// nz + 2`, `s` and `v` scaled as the hammer's height and velocity
/// (`hammer`), `I` so that its row sums to at most 1/16 of the largest
/// column sum of the rest.
fn balance_drive(b: &mut DMatrix<f64>, d: &mut [f64], nz: usize, hammer: (f64, f64)) {
    let one = b.nrows() - 1;
    let mut scale = |i: usize, f: f64| {
        d[i] *= f;
        for j in 0..=one {
            b[(i, j)] /= f;
            b[(j, i)] *= f;
        }
    };
    scale(nz, hammer.0);
    scale(nz + 1, hammer.1);
    let ii = nz + 2;
    let rest = (0..one)
        .map(|j| {
            (0..one)
                .filter(|&i| i != ii)
                .map(|i| b[(i, j)].abs())
                .sum::<f64>()
        })
        .fold(0.0, f64::max);
    let row: f64 = (0..one).map(|j| b[(ii, j)].abs()).sum();
    if row > 0.0 && rest > 0.0 {
        // power of two f with row / f <= rest / 16
        let f = 2f64.powi((16.0 * row / rest).log2().ceil() as i32);
        d[ii] *= f;
        for j in 0..=one {
            b[(ii, j)] /= f;
        }
    }
}

/// Induced 1-norm (largest column sum).
pub(crate) fn norm1(b: &DMatrix<f64>) -> f64 {
    (0..b.ncols())
        .map(|j| b.column(j).iter().map(|x| x.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// Row-major copy.
fn flat(m: &DMatrix<f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(m.len());
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            out.push(m[(i, j)]);
        }
    }
    out
}

#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `out = M y` for a row-major square `M`.
#[inline]
pub(crate) fn matvec(m: &[f64], y: &[f64], out: &mut [f64]) {
    let n = y.len();
    for (i, o) in out.iter_mut().enumerate() {
        *o = dot(&m[i * n..(i + 1) * n], y);
    }
}
