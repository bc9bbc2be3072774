//! Linear models of the objects and of the contact system, in energy coordinates.
//!
//! Every object with `n` degrees of freedom is written as a first-order system in
//! the coordinates `z = [xi; u] = [L^T q; M^{1/2} q']` with `K = L L^T`, so that its
//! energy is `0.5 |z|^2` (docs/numerics.md, "Energy coordinates and passivity"). Its generator is
//! `A = [[0, B], [-B^T, -D]]` with `B = L^T M^{-1/2}` and
//! `D = M^{-1/2} C M^{-1/2}`: a skew part plus a negative semidefinite part, so
//! `|exp(A t)| <= 1` holds by construction.
//!
//! The contact system (paper eq. 12-15 and 20) adds the hammer and the contact
//! spring. Its coordinates are `y = [xi (n); pi; u (n); eta]` with
//! `pi = sqrt(k_c) p_eff` (the spring's energy coordinate, `p_eff` the effective
//! penetration) and `eta = sqrt(m_h) v_h` (the hammer's momentum coordinate).
//! Energy is again `0.5 |y|^2` (plus gravity's potential, which is affine).
//! Because the offset rod only shifts `p_eff`, the rod adds no term at all in
//! these coordinates; gravity adds a constant forcing on `eta`.

use crate::physics::block::Mat2;
use crate::physics::error::ModelError;
use crate::scene::{ModalSpec, ObjectSpec, StringSpec};
use nalgebra::{DMatrix, DVector};

/// `ln(1000)`: a mode decaying by 60 dB in T60 has amplitude rate
/// `sigma = ln(1000) / T60` (docs/design.md, "Conventions and units").
pub const LN_1000: f64 = 6.907_755_278_982_137;

/// Displacement and velocity rows of one named point, over `z = [xi; u]`.
#[derive(Debug, Clone)]
pub struct PointRows {
    /// Point name.
    pub name: String,
    /// `x_p = disp . z`.
    pub disp: DVector<f64>,
    /// `x_p' = vel . z`; for the contact point this is also the force input
    /// (reciprocity: `M^{-1/2} w = (w^T M^{-1/2})^T`).
    pub vel: DVector<f64>,
}

/// An object's free dynamics in energy coordinates.
#[derive(Debug, Clone)]
pub struct ObjectModel {
    /// Object name.
    pub name: String,
    /// Degrees of freedom (`z` has `2 n` entries).
    pub n: usize,
    /// Generator `A` (2n x 2n).
    pub a: DMatrix<f64>,
    /// For modal objects: the exact 2x2 generator of mode `i` acting on
    /// `(xi_i, u_i)`, so the free phase needs no eigensolver.
    pub modal_blocks: Option<Vec<Mat2>>,
    /// Named points.
    pub points: Vec<PointRows>,
    /// Undamped natural frequencies \[Hz\], for summaries.
    pub freqs_hz: Vec<f64>,
}

impl ObjectModel {
    /// Rows of the point named `name`.
    pub fn point(&self, name: &str) -> Option<&PointRows> {
        self.points.iter().find(|p| p.name == name)
    }

    /// Build the model of one scene object.
    pub fn from_spec(spec: &ObjectSpec) -> Result<Self, ModelError> {
        match spec {
            ObjectSpec::Modal(m) => Ok(modal_model(m)),
            ObjectSpec::String(s) => string_model(s),
            ObjectSpec::Bar(_)
            | ObjectSpec::Tube(_)
            | ObjectSpec::Plate(_)
            | ObjectSpec::Membrane(_)
            | ObjectSpec::StiffString(_)
            | ObjectSpec::Chain(_) => Err(ModelError::NotExpanded),
            ObjectSpec::Wall(w) => Ok(ObjectModel {
                name: w.name.clone(),
                n: 0,
                a: DMatrix::zeros(0, 0),
                modal_blocks: Some(Vec::new()),
                points: Vec::new(),
                freqs_hz: Vec::new(),
            }),
        }
    }
}

impl ObjectModel {
    /// This object and a modal mallet as one object (docs/design.md, "Modal
    /// mallets"): the free dynamics side by side, `z = [xi; xi_m; u; u_m]`,
    /// the mallet's points as `"<mallet>.<point>"`, and the contact point
    /// `contact_name`, whose rows are this object's point `point` minus the
    /// mallet's point `tip` (the penetration `x_c - (x_h + x_tip)`). The
    /// route for objects whose contact is not a rank-one update of modes
    /// (a lumped string): the general eigensolver takes the joined model.
    /// `None` if a point is missing.
    pub fn joined_with_mallet(
        &self,
        mallet: &ObjectModel,
        point: &str,
        tip: &str,
        contact_name: &str,
    ) -> Option<ObjectModel> {
        let (n1, n2) = (self.n, mallet.n);
        let n = n1 + n2;
        // where entry j of each part's z goes in the joined z
        let at1 = |j: usize| if j < n1 { j } else { n2 + j };
        let at2 = |j: usize| if j < n2 { n1 + j } else { n1 + n + (j - n2) };
        let mut a = DMatrix::zeros(2 * n, 2 * n);
        for i in 0..2 * n1 {
            for j in 0..2 * n1 {
                a[(at1(i), at1(j))] = self.a[(i, j)];
            }
        }
        for i in 0..2 * n2 {
            for j in 0..2 * n2 {
                a[(at2(i), at2(j))] = mallet.a[(i, j)];
            }
        }
        let embed = |row: &DVector<f64>, at: &dyn Fn(usize) -> usize| {
            let mut out = DVector::zeros(2 * n);
            for (j, v) in row.iter().enumerate() {
                out[at(j)] = *v;
            }
            out
        };
        let mut points: Vec<PointRows> = self
            .points
            .iter()
            .map(|p| PointRows {
                name: p.name.clone(),
                disp: embed(&p.disp, &at1),
                vel: embed(&p.vel, &at1),
            })
            .collect();
        points.extend(mallet.points.iter().map(|p| PointRows {
            name: format!("{}.{}", mallet.name, p.name),
            disp: embed(&p.disp, &at2),
            vel: embed(&p.vel, &at2),
        }));
        let (c, t) = (self.point(point)?, mallet.point(tip)?);
        points.push(PointRows {
            name: contact_name.to_string(),
            disp: embed(&c.disp, &at1) - embed(&t.disp, &at2),
            vel: embed(&c.vel, &at1) - embed(&t.vel, &at2),
        });
        let mut freqs_hz = self.freqs_hz.clone();
        freqs_hz.extend_from_slice(&mallet.freqs_hz);
        Some(ObjectModel {
            name: self.name.clone(),
            n,
            a,
            modal_blocks: None,
            points,
            freqs_hz,
        })
    }
}

/// Abstract modal object (paper eq. 16-18): `xi_i = omega_i q_i`, `u_i = q_i'`.
fn modal_model(m: &ModalSpec) -> ObjectModel {
    let n = m.mode.len();
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    let mut blocks = Vec::with_capacity(n);
    let mut freqs = Vec::with_capacity(n);
    for (i, mode) in m.mode.iter().enumerate() {
        let omega = 2.0 * std::f64::consts::PI * mode.freq_hz;
        let sigma = mode.t60_s.map_or(0.0, |t| LN_1000 / t);
        a[(i, n + i)] = omega;
        a[(n + i, i)] = -omega;
        a[(n + i, n + i)] = -2.0 * sigma;
        blocks.push([0.0, omega, -omega, -2.0 * sigma]);
        freqs.push(mode.freq_hz);
    }
    let points = m
        .points
        .iter()
        .enumerate()
        .map(|(pi, name)| {
            let mut disp = DVector::zeros(2 * n);
            let mut vel = DVector::zeros(2 * n);
            for (i, mode) in m.mode.iter().enumerate() {
                let omega = 2.0 * std::f64::consts::PI * mode.freq_hz;
                disp[i] = mode.weights[pi] / omega;
                vel[n + i] = mode.weights[pi];
            }
            PointRows {
                name: name.clone(),
                disp,
                vel,
            }
        })
        .collect();
    ObjectModel {
        name: m.name.clone(),
        n,
        a,
        modal_blocks: Some(blocks),
        points,
        freqs_hz: freqs,
    }
}

/// String of `n` equal masses between fixed ends with `n + 1` equal springs
/// (paper section 2.1, figure 1). `C = alpha M + beta K + dashpots`, which does
/// not commute with `K` as soon as there is a dashpot.
fn string_model(s: &StringSpec) -> Result<ObjectModel, ModelError> {
    let n = s.masses;
    let m = s.mass_kg;
    let kk = s.spring_n_per_m;
    let mut k = DMatrix::zeros(n, n);
    for i in 0..n {
        k[(i, i)] = 2.0 * kk;
        if i + 1 < n {
            k[(i, i + 1)] = -kk;
            k[(i + 1, i)] = -kk;
        }
    }
    let mut c = &k * s.rayleigh_beta_s;
    for i in 0..n {
        c[(i, i)] += s.rayleigh_alpha_per_s * m;
    }
    for d in &s.dashpots {
        c[(d.mass, d.mass)] += d.n_s_per_m;
    }
    let chol =
        nalgebra::Cholesky::new(k.clone()).ok_or(ModelError::StiffnessNotPositiveDefinite)?;
    let l = chol.l();
    let inv_sqrt_m = 1.0 / m.sqrt();
    // B = L^T M^{-1/2}; D = M^{-1/2} C M^{-1/2}
    let b = l.transpose() * inv_sqrt_m;
    let d = &c / m;
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).copy_from(&b);
    a.view_mut((n, 0), (n, n)).copy_from(&(-b.transpose()));
    a.view_mut((n, n), (n, n)).copy_from(&(-d));
    // x_j = (L^{-T} xi)_j  =>  row_j = (L^{-1} e_j)^T
    let l_inv =
        crate::physics::linalg::inverse(&l).ok_or(ModelError::StiffnessNotPositiveDefinite)?;
    let points = s
        .points
        .iter()
        .map(|(name, &j)| {
            let mut disp = DVector::zeros(2 * n);
            let mut vel = DVector::zeros(2 * n);
            for i in 0..n {
                disp[i] = l_inv[(i, j)];
            }
            vel[n + j] = inv_sqrt_m;
            PointRows {
                name: name.clone(),
                disp,
                vel,
            }
        })
        .collect();
    // Natural frequencies of the fixed-fixed chain (for the summary).
    let freqs = (1..=n).map(|j| s.mode_freq_hz(j)).collect();
    Ok(ObjectModel {
        name: s.name.clone(),
        n,
        a,
        modal_blocks: None,
        points,
        freqs_hz: freqs,
    })
}

/// Indices into the contact state `y = [xi (n); pi; u (n); eta]`.
#[derive(Debug, Clone, Copy)]
pub struct ContactLayout {
    /// Object degrees of freedom.
    pub n: usize,
}

impl ContactLayout {
    /// Dimension of `y`.
    pub fn dim(&self) -> usize {
        2 * self.n + 2
    }
    /// Index of the spring coordinate `pi`.
    pub fn pi(&self) -> usize {
        self.n
    }
    /// Index of the hammer momentum coordinate `eta`.
    pub fn eta(&self) -> usize {
        2 * self.n + 1
    }
    /// Where entry `j` of the object's `z = [xi; u]` goes in `y`.
    pub fn embed(&self, j: usize) -> usize {
        if j < self.n {
            j
        } else {
            j + 1
        }
    }
    /// Embed an object row (over `z`) into a row over `y`.
    pub fn embed_row(&self, row: &DVector<f64>) -> DVector<f64> {
        let mut out = DVector::zeros(self.dim());
        for (j, v) in row.iter().enumerate() {
            out[self.embed(j)] = *v;
        }
        out
    }
}

/// Physical parameters of the contact and hammer.
#[derive(Debug, Clone, Copy)]
pub struct ContactParams {
    /// Contact stiffness \[N/m\].
    pub k: f64,
    /// Contact damping \[N s/m\].
    pub c: f64,
    /// Hammer mass \[kg\].
    pub m_h: f64,
    /// Gravity \[m/s^2\] (pulls down).
    pub g: f64,
}

/// Generator and constant forcing of the contact phase (paper eq. 15 with the
/// point contact of eq. 9/10/11, or eq. 20 for abstract modal objects):
/// `y' = A y + f`.
///
/// Derivation, with `f_c` the contact point's velocity row (= force input),
/// `sk = sqrt(k)`, `sm = sqrt(m_h)`:
/// `pi' = sk (f_c . u - eta / sm)`,
/// `u' = -B^T xi - D u - f_c (sk pi + c (f_c . u - eta / sm))`,
/// `eta' = (sk pi + c (f_c . u - eta / sm)) / sm - g sm`.
/// The skew-symmetric pairs `(pi, u)`, `(pi, eta)` carry the spring; the
/// damper is `-c a a^T` with `a = (f_c, -1/sm)`.
pub fn contact_system(
    obj: &ObjectModel,
    contact_vel_row: Option<&DVector<f64>>,
    p: &ContactParams,
) -> (DMatrix<f64>, DVector<f64>, ContactLayout) {
    let lay = ContactLayout { n: obj.n };
    let n = obj.n;
    let dim = lay.dim();
    let mut a = DMatrix::zeros(dim, dim);
    for i in 0..2 * n {
        for j in 0..2 * n {
            a[(lay.embed(i), lay.embed(j))] = obj.a[(i, j)];
        }
    }
    let sk = p.k.sqrt();
    let sm = p.m_h.sqrt();
    let (pi, eta) = (lay.pi(), lay.eta());
    // force/velocity column of the contact point over u (zero for a wall)
    let fvec: Vec<f64> = match contact_vel_row {
        Some(row) => (0..n).map(|i| row[n + i]).collect(),
        None => vec![0.0; n],
    };
    for i in 0..n {
        let ui = n + 1 + i;
        a[(pi, ui)] += sk * fvec[i];
        a[(ui, pi)] -= sk * fvec[i];
        for j in 0..n {
            a[(ui, n + 1 + j)] -= p.c * fvec[i] * fvec[j];
        }
        a[(ui, eta)] += p.c * fvec[i] / sm;
        a[(eta, ui)] += p.c * fvec[i] / sm;
    }
    a[(pi, eta)] -= sk / sm;
    a[(eta, pi)] += sk / sm;
    a[(eta, eta)] -= p.c / p.m_h;
    let mut f = DVector::zeros(dim);
    f[eta] = -p.g * sm;
    (a, f, lay)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_mode(f_hz: f64, t60: Option<f64>, w: f64) -> ObjectModel {
        modal_model(&ModalSpec {
            name: "o".into(),
            points: vec!["c".into()],
            mode: vec![crate::scene::ModeSpec {
                freq_hz: f_hz,
                t60_s: t60,
                weights: vec![w],
            }],
        })
    }

    #[test]
    fn contact_generator_is_skew_plus_dissipative() {
        let obj = one_mode(300.0, Some(0.5), 2.0);
        let row = obj.point("c").unwrap().vel.clone();
        let p = ContactParams {
            k: 1e5,
            c: 3.0,
            m_h: 0.02,
            g: 9.81,
        };
        let (a, _f, _lay) = contact_system(&obj, Some(&row), &p);
        let sym = &a + a.transpose();
        let eig = nalgebra::SymmetricEigen::new(sym);
        let max = eig.eigenvalues.iter().cloned().fold(f64::MIN, f64::max);
        // A + A^T must be negative semidefinite: energy 0.5|y|^2 never grows.
        assert!(max <= 1e-9 * a.norm(), "max eig of A+A^T = {max}");
    }

    #[test]
    fn string_rows_reproduce_positions() {
        // Build a tiny string and check x_j = disp_j . [L^T q; ...] for a random q.
        let spec = StringSpec {
            name: "s".into(),
            masses: 5,
            mass_kg: 0.01,
            spring_n_per_m: 1000.0,
            rayleigh_alpha_per_s: 0.0,
            rayleigh_beta_s: 0.0,
            dashpots: vec![],
            points: [("p".to_string(), 3usize)].into_iter().collect(),
        };
        let obj = string_model(&spec).unwrap();
        let q = DVector::from_vec(vec![0.1, -0.2, 0.3, 0.05, -0.01]);
        let mut k = DMatrix::zeros(5, 5);
        for i in 0..5 {
            k[(i, i)] = 2000.0;
            if i + 1 < 5 {
                k[(i, i + 1)] = -1000.0;
                k[(i + 1, i)] = -1000.0;
            }
        }
        let l = nalgebra::Cholesky::new(k).unwrap().l();
        let xi = l.transpose() * &q;
        let mut z = DVector::zeros(10);
        z.rows_mut(0, 5).copy_from(&xi);
        let x3 = obj.point("p").unwrap().disp.dot(&z);
        assert!((x3 - q[3]).abs() < 1e-14, "{x3} vs {}", q[3]);
    }
}
