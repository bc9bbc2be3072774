//! The coupled part of a phase (the modes a closed contact touches and
//! the held masses): its coordinates, forces, first-order system,
//! equilibrium and block decomposition.

use super::*;

/// The coupled part of a phase, `zc`: the modes a closed contact touches
/// and the held masses; the modes no closed contact touches keep their
/// free 2x2 blocks (exactly, and degenerate modes need no eigenvectors).
pub(super) struct CoupledPart {
    /// The coupled modes.
    pub(super) cm: Vec<usize>,
    /// The free modes.
    pub(super) fm: Vec<usize>,
    /// Each coordinate of `zc` as a coordinate of z.
    pub(super) zc_of: Vec<usize>,
    /// `zc`'s dimension.
    nzc: usize,
    /// The coupled part's dimension once each free group's centre is
    /// taken out (P_c's columns).
    pub(super) nrc: usize,
    /// P_c (`nzc` x `nrc`).
    pub(super) pc: DMatrix<f64>,
}

impl CoupledPart {
    pub(super) fn new(m: &MultiModel, lay: &Layout, rows: &[(Vec<f64>, f64)]) -> Self {
        let n = m.n();
        let (cm, fm): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| rows.iter().any(|r| r.0[i] != 0.0));
        let zc_of: Vec<usize> = cm
            .iter()
            .copied()
            .chain((0..lay.bound.len()).map(|b| n + b))
            .collect();
        let nzc = zc_of.len();
        let nrc = nzc - lay.groups.len();
        let pc = coupled_basis(m, lay, &zc_of);
        Self {
            cm,
            fm,
            zc_of,
            nzc,
            nrc,
            pc,
        }
    }
}

/// P_c: the identity but on each free group, where it is an orthonormal
/// basis of the complement of the group's centre direction e (sqrt(m_j) /
/// sqrt(M)): the columns of the Householder reflection that takes e to
/// the group's first axis, but the first.
fn coupled_basis(m: &MultiModel, lay: &Layout, zc_of: &[usize]) -> DMatrix<f64> {
    let n = m.n();
    let nzc = zc_of.len();
    let nrc = nzc - lay.groups.len();
    let mut pc = DMatrix::zeros(nzc, nrc);
    let mut col = 0;
    let at_zc = |zi: usize| zc_of.iter().position(|&x| x == zi).expect("coupled");
    let mut in_group = vec![false; nzc];
    for grp in &lay.groups {
        for &j in grp {
            in_group[at_zc(n + lay.place[j].expect("grouped masses are bound"))] = true;
        }
    }
    for r in 0..nzc {
        if !in_group[r] {
            pc[(r, col)] = 1.0;
            col += 1;
        }
    }
    for grp in &lay.groups {
        let total: f64 = grp.iter().map(|&j| m.masses[j].mass_kg).sum();
        let idx: Vec<usize> = grp
            .iter()
            .map(|&j| at_zc(n + lay.place[j].expect("bound")))
            .collect();
        let e: Vec<f64> = grp
            .iter()
            .map(|&j| (m.masses[j].mass_kg / total).sqrt())
            .collect();
        // v = e + e_0 (e_0 > 0, no cancellation); H = I - 2 v v^T / |v|^2
        let mut v = e.clone();
        v[0] += 1.0;
        let vv = dot(&v, &v);
        for c in 1..grp.len() {
            for (a, &ra) in idx.iter().enumerate() {
                let delta = if a == c { 1.0 } else { 0.0 };
                pc[(ra, col)] = delta - 2.0 * v[a] * v[c] / vv;
            }
            col += 1;
        }
    }
    pc
}

/// F_c = [diag(omega); sqrt(k_c) g_c^T] on zc, the damping and the
/// constant forces on zc.
pub(super) struct CoupledForces {
    /// F_c.
    fc: DMatrix<f64>,
    /// The damping on zc.
    damping: DMatrix<f64>,
    /// The constant forces on zc (the closed contacts' offsets, gravity).
    force: Vec<f64>,
    /// Per closed contact: the force per metre of a rod in it (on zc).
    pub(super) rod_force: Vec<Vec<f64>>,
}

impl CoupledForces {
    pub(super) fn new(
        m: &MultiModel,
        lay: &Layout,
        members: &[usize],
        rows: &[(Vec<f64>, f64)],
        p0: &[f64],
        cp: &CoupledPart,
    ) -> Self {
        let g = m.gravity_m_per_s2;
        let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
        let (cm, zc_of, nzc) = (&cp.cm, &cp.zc_of, cp.nzc);
        let ncm = cm.len();
        let mut fc = DMatrix::zeros(ncm + members.len(), nzc);
        let mut damping = DMatrix::zeros(nzc, nzc);
        for (a, &i) in cm.iter().enumerate() {
            fc[(a, a)] = two_pi() * m.freq_hz[i];
            damping[(a, a)] = 2.0 * m.sigma[i];
        }
        let mut force = vec![0.0; nzc];
        let mut rod_force = vec![vec![0.0; nzc]; members.len()];
        for (pos, &c) in members.iter().enumerate() {
            let ct = &m.contacts[c];
            let gz: Vec<f64> = zc_of.iter().map(|&zi| rows[pos].0[zi]).collect();
            let sk = ct.stiffness_n_per_m.sqrt();
            for (colz, x) in gz.iter().enumerate() {
                fc[(ncm + pos, colz)] = sk * x;
            }
            for a in 0..nzc {
                force[a] -= ct.stiffness_n_per_m * p0[pos] * gz[a];
                rod_force[pos][a] = ct.stiffness_n_per_m * gz[a];
                for b in 0..nzc {
                    damping[(a, b)] += ct.damping_n_s_per_m * gz[a] * gz[b];
                }
            }
        }
        for (b, &j) in lay.bound.iter().enumerate() {
            force[ncm + b] -= g * sqm(j);
        }
        Self {
            fc,
            damping,
            force,
            rod_force,
        }
    }
}

/// The coupled part's first-order system `y_c' = A y_c + f_y` in
/// `y_c = [u_c; w_c]` (`u_c = R_c P_c^T zc`), from the QR of `F_c P_c`.
pub(super) struct CoupledSystem {
    /// Q of the QR of `F_c P_c`.
    pub(super) qc: DMatrix<f64>,
    /// `P_c R_c^-1`: zc per `u_c`.
    pub(super) zc: DMatrix<f64>,
    /// A.
    pub(super) a: DMatrix<f64>,
    /// f_y.
    fy: Vec<f64>,
    /// `y_c`'s dimension, `2 nrc`.
    pub(super) dimc: usize,
}

impl CoupledSystem {
    pub(super) fn new(cp: &CoupledPart, cf: &CoupledForces, mask: u32) -> Result<Self, MultiError> {
        let bad = |why: String| phase_error(mask, why);
        let (nrc, nzc, pc) = (cp.nrc, cp.nzc, &cp.pc);
        let (qc, rc) = if nrc == 0 {
            (DMatrix::zeros(cf.fc.nrows(), 0), DMatrix::zeros(0, 0))
        } else {
            let qr = (&cf.fc * pc).qr();
            let (q, r) = (qr.q(), qr.r());
            let rmax = (0..nrc).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
            if (0..nrc).any(|i| !(r[(i, i)].abs() > rmax * 1e-15)) {
                return Err(bad("its stiffness is singular".into()));
            }
            (q, r)
        };
        let rinv = rc
            .clone()
            .solve_upper_triangular(&DMatrix::identity(nrc, nrc))
            .ok_or_else(|| bad("its stiffness is singular".into()))?;
        let zc = pc * &rinv;
        let dt = pc.transpose() * &cf.damping * pc;
        let dimc = 2 * nrc;
        let mut a = DMatrix::zeros(dimc, dimc);
        for i in 0..nrc {
            for j in 0..nrc {
                a[(i, nrc + j)] = rc[(i, j)];
                a[(nrc + j, i)] = -rc[(i, j)];
                a[(nrc + i, nrc + j)] = -dt[(i, j)];
            }
        }
        let mut fy = vec![0.0; dimc];
        for i in 0..nrc {
            fy[nrc + i] = (0..nzc).map(|a| pc[(a, i)] * cf.force[a]).sum();
        }
        Ok(Self {
            qc,
            zc,
            a,
            fy,
            dimc,
        })
    }

    /// The equilibrium `A y* + f = 0`, and per closed contact its move
    /// per metre of a rod (`rod_force`).
    pub(super) fn equilibrium(
        &self,
        cp: &CoupledPart,
        rod_force: &[Vec<f64>],
        mask: u32,
    ) -> Result<Equilibrium, MultiError> {
        let bad = |why: String| phase_error(mask, why);
        let (dimc, nrc, nzc, pc) = (self.dimc, cp.nrc, cp.nzc, &cp.pc);
        let lu = (dimc > 0).then(|| self.a.clone().lu());
        let solve = |f: &[f64], why: &str| -> Result<Vec<f64>, MultiError> {
            if f.iter().all(|x| *x == 0.0) {
                return Ok(vec![0.0; dimc]);
            }
            let rhs = nalgebra::DVector::from_iterator(dimc, f.iter().map(|x| -x));
            let y = lu
                .as_ref()
                .and_then(|lu| lu.solve(&rhs))
                .ok_or_else(|| bad(why.into()))?;
            Ok(y.iter().copied().collect())
        };
        let yc_star = solve(&self.fy, "no equilibrium under gravity")?;
        let mut rod_yc = Vec::with_capacity(rod_force.len());
        for rf in rod_force {
            let mut f = vec![0.0; dimc];
            for i in 0..nrc {
                f[nrc + i] = (0..nzc).map(|a| pc[(a, i)] * rf[a]).sum();
            }
            rod_yc.push(solve(&f, "no equilibrium with an offset rod")?);
        }
        Ok(Equilibrium { yc_star, rod_yc })
    }
}

/// The coupled part's equilibrium and its moves.
pub(super) struct Equilibrium {
    /// y_c* (`A y_c* + f_y = 0`).
    pub(super) yc_star: Vec<f64>,
    /// Per closed contact: y_c*'s move per metre of a rod in it.
    pub(super) rod_yc: Vec<Vec<f64>>,
}

/// The coupled part's block decomposition `A = V blocks V^-1`.
pub(super) struct CoupledBlocks {
    /// The blocks' generators.
    pub(super) gens: Vec<Mat2>,
    /// V.
    pub(super) v: DMatrix<f64>,
    /// V^-1.
    pub(super) vinv: DMatrix<f64>,
    /// V's condition number.
    pub(super) kappa: f64,
}

impl CoupledBlocks {
    pub(super) fn new(a: &DMatrix<f64>, h: f64, mask: u32) -> Result<Self, MultiError> {
        let bad = |why: String| phase_error(mask, why);
        if a.nrows() == 0 {
            return Ok(Self {
                gens: vec![],
                v: DMatrix::zeros(0, 0),
                vinv: DMatrix::zeros(0, 0),
                kappa: 1.0,
            });
        }
        let d = decompose_via(a, h, None, true).map_err(|e| bad(e.to_string()))?;
        let Form::Blocks { gens } = d.form else {
            return Err(bad(format!(
                "no block form ({})",
                d.diag.fallback_reason.unwrap_or_default()
            )));
        };
        Ok(Self {
            gens,
            v: d.v,
            vinv: d.vinv,
            kappa: d.diag.kappa,
        })
    }
}
