//! Compiling a phase (the contacts of a mask closed): its coordinates, its
//! block decomposition and every row the engine reads ([`MultiPhase`]);
//! the compiled model ([`CompiledMulti`]) and the per-state tables.

use super::*;

impl Layout {
    fn new(m: &MultiModel, members: &[usize]) -> Self {
        let nm = m.masses.len();
        let mut parent: Vec<usize> = (0..nm).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        let mut in_contact = vec![false; nm];
        let mut held = vec![false; nm];
        for &c in members {
            let ct = &m.contacts[c];
            match (&ct.lower, &ct.upper) {
                (MultiEnd::Mass(a), MultiEnd::Mass(b)) => {
                    in_contact[*a] = true;
                    in_contact[*b] = true;
                    let (ra, rb) = (root(&mut parent, *a), root(&mut parent, *b));
                    parent[ra] = rb;
                }
                (MultiEnd::Mass(a), _) | (_, MultiEnd::Mass(a)) => {
                    in_contact[*a] = true;
                    held[*a] = true;
                }
                _ => {}
            }
        }
        let mut root_held = vec![false; nm];
        for j in 0..nm {
            if held[j] {
                let r = root(&mut parent, j);
                root_held[r] = true;
            }
        }
        let mut bound = vec![];
        let mut place = vec![None; nm];
        let mut group_of_root: Vec<Option<usize>> = vec![None; nm];
        let mut groups: Vec<Vec<usize>> = vec![];
        let mut fly_of = vec![None; nm];
        for j in 0..nm {
            if !in_contact[j] {
                fly_of[j] = Some(j);
                continue;
            }
            place[j] = Some(bound.len());
            bound.push(j);
            let r = root(&mut parent, j);
            if !root_held[r] {
                let g = *group_of_root[r].get_or_insert_with(|| {
                    groups.push(vec![]);
                    groups.len() - 1
                });
                groups[g].push(j);
                fly_of[j] = Some(groups[g][0]);
            }
        }
        Self {
            bound,
            place,
            groups,
            fly_of,
        }
    }
}

impl MultiPhase {
    fn new(m: &MultiModel, mask: u32, h: f64) -> Result<Self, MultiError> {
        let members: Vec<usize> = (0..m.contacts.len())
            .filter(|j| mask & (1 << j) != 0)
            .collect();
        let lay = Layout::new(m, &members);
        let rows = contact_rows_z(m, &lay, &members);
        let p0: Vec<f64> = rows.iter().map(|r| r.1).collect();
        let cp = CoupledPart::new(m, &lay, &rows);
        let cf = CoupledForces::new(m, &lay, &members, &rows, &p0, &cp);
        let cs = CoupledSystem::new(&cp, &cf, mask)?;
        let blocks = CoupledBlocks::new(&cs.a, h, mask)?;
        let kappa = blocks.kappa;
        let eq = cs.equilibrium(&cp, &cf.rod_force, mask)?;
        let w = WholePhase::new(m, &lay, &members, &cp, &cs, blocks, &eq);
        let growth: Vec<f64> = w.gens.iter().map(|g| (sym_growth(g) * h).exp()).collect();
        let growth_max = growth.iter().copied().fold(1.0, f64::max);
        let phase_rows = PhaseRows {
            m,
            lay: &lay,
            w: &w,
        };
        let er = phase_rows.events(&members, &p0);
        let sides = phase_rows.sides();
        let out = phase_rows.outputs();
        // the entries of s the coupled part moves (the free modes' blocks
        // are their own (omega q, q'))
        let coupled: Vec<usize> = (0..cs.dimc).map(|c| w.smap(c)).collect();
        let sp = SwitchProducts::new(m.n(), &lay, &members, &cp.cm, &w, &coupled);
        let mut flyers: Vec<usize> = (0..m.masses.len())
            .filter(|&j| lay.place[j].is_none())
            .collect();
        flyers.extend(lay.groups.iter().map(|grp| grp[0]));
        let free_blocks: Vec<(usize, usize, usize)> = cp
            .fm
            .iter()
            .enumerate()
            .map(|(j, &i)| (i, w.nbc + j, w.nb + w.nbc + j))
            .collect();
        let forms = w.gens.iter().map(OscForm::of).collect();
        Ok(Self {
            members,
            dim: w.dim,
            forms,
            ev_blocks: er.ev_blocks,
            ev_nz: er.ev_nz,
            evd_nz: er.evd_nz,
            gens: w.gens,
            qv0: sp.qv0,
            pv0: sp.pv0,
            zv0: sp.zv0,
            qv: sp.qv,
            pv: sp.pv,
            zv: sp.zv,
            qv_c: sp.qv_c,
            qv_rows: sp.qv_rows,
            pv_c: sp.pv_c,
            pv_rows: sp.pv_rows,
            zv_c: sp.zv_c,
            bound_rows: (0..lay.bound.len()).collect(),
            vq_c: sp.vq_c,
            vp_c: sp.vp_c,
            free_blocks,
            s_star: sp.s_star,
            bound: lay.bound,
            place: lay.place,
            groups: lay.groups,
            fly_of: lay.fly_of,
            flyers,
            p0,
            rod_s: w.rod_s,
            ev: er.ev,
            ev0: er.ev0,
            ev_d: er.ev_d,
            ev_c2: er.ev_c2,
            ev_e: er.ev_e,
            ev_fly: er.ev_fly,
            search: er.search,
            sides,
            coupled,
            coupled_modes: cp.cm,
            out_d: out.out_d,
            out_d0: out.out_d0,
            out_v: out.out_v,
            out_v0: out.out_v0,
            kappa,
            growth: growth_max,
        })
    }
}

/// A phase that cannot be compiled, and why.
fn phase_error(mask: u32, why: String) -> MultiError {
    MultiError::Phase { mask, why }
}

/// Each closed contact's row over z and constant: `p = g . z + p0`.
fn contact_rows_z(m: &MultiModel, lay: &Layout, members: &[usize]) -> Vec<(Vec<f64>, f64)> {
    let n = m.n();
    let nz = n + lay.bound.len();
    let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
    let row_z = |e: &MultiEnd| -> (Vec<f64>, f64) {
        let mut r = vec![0.0; nz];
        match e {
            MultiEnd::Point(w) => {
                r[..n].copy_from_slice(w);
                (r, 0.0)
            }
            MultiEnd::Mass(j) => {
                if let Some(b) = lay.place[*j] {
                    r[n + b] = 1.0 / sqm(*j);
                }
                (r, 0.0)
            }
            MultiEnd::Wall(hw) => (r, *hw),
        }
    };
    let contact_z = |c: usize| {
        let ct = &m.contacts[c];
        let (rl, cl) = row_z(&ct.lower);
        let (ru, cu) = row_z(&ct.upper);
        let r: Vec<f64> = rl.iter().zip(&ru).map(|(a, b)| a - b).collect();
        (r, cl - cu - ct.gap_m)
    };
    members.iter().map(|&c| contact_z(c)).collect()
}

/// The coupled part of a phase, `zc`: the modes a closed contact touches
/// and the held masses; the modes no closed contact touches keep their
/// free 2x2 blocks (exactly, and degenerate modes need no eigenvectors).
struct CoupledPart {
    /// The coupled modes.
    cm: Vec<usize>,
    /// The free modes.
    fm: Vec<usize>,
    /// Each coordinate of `zc` as a coordinate of z.
    zc_of: Vec<usize>,
    /// `zc`'s dimension.
    nzc: usize,
    /// The coupled part's dimension once each free group's centre is
    /// taken out (P_c's columns).
    nrc: usize,
    /// P_c (`nzc` x `nrc`).
    pc: DMatrix<f64>,
}

impl CoupledPart {
    fn new(m: &MultiModel, lay: &Layout, rows: &[(Vec<f64>, f64)]) -> Self {
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
struct CoupledForces {
    /// F_c.
    fc: DMatrix<f64>,
    /// The damping on zc.
    damping: DMatrix<f64>,
    /// The constant forces on zc (the closed contacts' offsets, gravity).
    force: Vec<f64>,
    /// Per closed contact: the force per metre of a rod in it (on zc).
    rod_force: Vec<Vec<f64>>,
}

impl CoupledForces {
    fn new(
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
struct CoupledSystem {
    /// Q of the QR of `F_c P_c`.
    qc: DMatrix<f64>,
    /// `P_c R_c^-1`: zc per `u_c`.
    zc: DMatrix<f64>,
    /// A.
    a: DMatrix<f64>,
    /// f_y.
    fy: Vec<f64>,
    /// `y_c`'s dimension, `2 nrc`.
    dimc: usize,
}

impl CoupledSystem {
    fn new(cp: &CoupledPart, cf: &CoupledForces, mask: u32) -> Result<Self, MultiError> {
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
    fn equilibrium(
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
struct Equilibrium {
    /// y_c* (`A y_c* + f_y = 0`).
    yc_star: Vec<f64>,
    /// Per closed contact: y_c*'s move per metre of a rod in it.
    rod_yc: Vec<Vec<f64>>,
}

/// The coupled part's block decomposition `A = V blocks V^-1`.
struct CoupledBlocks {
    /// The blocks' generators.
    gens: Vec<Mat2>,
    /// V.
    v: DMatrix<f64>,
    /// V^-1.
    vinv: DMatrix<f64>,
    /// V's condition number.
    kappa: f64,
}

impl CoupledBlocks {
    fn new(a: &DMatrix<f64>, h: f64, mask: u32) -> Result<Self, MultiError> {
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

/// The whole phase: `y = [u_c, u_free; w_c, w_free]`, the free modes'
/// `u = omega q` and `w = q'`; `s = [first components of the coupled
/// blocks, of the free blocks; second components of each]`.
struct WholePhase {
    /// `u`'s dimension.
    nr: usize,
    /// The state's dimension, `2 nr`.
    dim: usize,
    /// The coupled part's `u` dimension.
    nrc: usize,
    /// The coupled blocks.
    nbc: usize,
    /// All blocks.
    nb: usize,
    /// Every block's generator, the coupled ones first.
    gens: Vec<Mat2>,
    /// V.
    v: DMatrix<f64>,
    /// V^-1.
    vinv: DMatrix<f64>,
    /// The equilibrium y*.
    y_star: Vec<f64>,
    /// Per closed contact: the equilibrium's move per metre of a rod, in s.
    rod_s: Vec<Vec<f64>>,
    /// z per `w` (z' = P w).
    p: DMatrix<f64>,
    /// z per `u`.
    z_of_u: DMatrix<f64>,
    /// The modes' and closed contacts' rows per `u` (Q).
    q: DMatrix<f64>,
}

impl WholePhase {
    fn new(
        m: &MultiModel,
        lay: &Layout,
        members: &[usize],
        cp: &CoupledPart,
        cs: &CoupledSystem,
        blocks: CoupledBlocks,
        eq: &Equilibrium,
    ) -> Self {
        let (nrc, dimc) = (cp.nrc, cs.dimc);
        let nr = nrc + cp.fm.len();
        let dim = 2 * nr;
        let nbc = blocks.gens.len();
        let nb = nbc + cp.fm.len();
        let mut w = Self {
            nr,
            dim,
            nrc,
            nbc,
            nb,
            gens: blocks.gens,
            v: DMatrix::zeros(dim, dim),
            vinv: DMatrix::zeros(dim, dim),
            y_star: vec![0.0; dim],
            rod_s: vec![],
            p: DMatrix::zeros(0, 0),
            z_of_u: DMatrix::zeros(0, 0),
            q: DMatrix::zeros(0, 0),
        };
        for r in 0..dimc {
            for c in 0..dimc {
                let (yr, sc) = (w.ymap(r), w.smap(c));
                let (sr, yc) = (w.smap(r), w.ymap(c));
                w.v[(yr, sc)] = blocks.v[(r, c)];
                w.vinv[(sr, yc)] = blocks.vinv[(r, c)];
            }
        }
        for (r, y) in eq.yc_star.iter().enumerate() {
            let yr = w.ymap(r);
            w.y_star[yr] = *y;
        }
        // V^-1 on the coupled part only (a constant force leaves the free
        // modes alone)
        w.rod_s = eq
            .rod_yc
            .iter()
            .map(|yc| {
                let mut rs = vec![0.0; dim];
                for r in 0..dimc {
                    rs[w.smap(r)] = (0..dimc).map(|c| blocks.vinv[(r, c)] * yc[c]).sum();
                }
                rs
            })
            .collect();
        w.place_coordinates(m, lay, members, cp, cs);
        w.add_free_blocks(m, cp);
        w
    }

    /// `y`'s index of the coupled part's `y_c[r]`.
    fn ymap(&self, r: usize) -> usize {
        if r < self.nrc {
            r
        } else {
            self.nr + r - self.nrc
        }
    }

    /// `s`'s index of the coupled part's `s_c[c]`.
    fn smap(&self, c: usize) -> usize {
        if c < self.nbc {
            c
        } else {
            self.nb + c - self.nbc
        }
    }

    /// P, z per `u` and Q: the coupled part's, and the free modes' own.
    fn place_coordinates(
        &mut self,
        m: &MultiModel,
        lay: &Layout,
        members: &[usize],
        cp: &CoupledPart,
        cs: &CoupledSystem,
    ) {
        let (n, nr, nrc) = (m.n(), self.nr, cp.nrc);
        let nz = n + lay.bound.len();
        let ncm = cp.cm.len();
        let mut p = DMatrix::zeros(nz, nr);
        let mut z_of_u = DMatrix::zeros(nz, nr);
        let mut q = DMatrix::zeros(n + members.len(), nr);
        for (r, &zi) in cp.zc_of.iter().enumerate() {
            for c in 0..nrc {
                p[(zi, c)] = cp.pc[(r, c)];
                z_of_u[(zi, c)] = cs.zc[(r, c)];
            }
        }
        for r in 0..cs.qc.nrows() {
            let row = if r < ncm { cp.cm[r] } else { n + r - ncm };
            for c in 0..nrc {
                q[(row, c)] = cs.qc[(r, c)];
            }
        }
        for (j, &i) in cp.fm.iter().enumerate() {
            let w = two_pi() * m.freq_hz[i];
            p[(i, nrc + j)] = 1.0;
            z_of_u[(i, nrc + j)] = 1.0 / w;
            q[(i, nrc + j)] = 1.0;
        }
        (self.p, self.z_of_u, self.q) = (p, z_of_u, q);
    }

    /// The free modes' blocks, generators and (unit) columns of V and
    /// V^-1.
    fn add_free_blocks(&mut self, m: &MultiModel, cp: &CoupledPart) {
        let (nr, nrc, nbc, nb) = (self.nr, self.nrc, self.nbc, self.nb);
        for (j, &i) in cp.fm.iter().enumerate() {
            let w = two_pi() * m.freq_hz[i];
            self.gens.push([0.0, w, -w, -2.0 * m.sigma[i]]);
            self.v[(nrc + j, nbc + j)] = 1.0;
            self.v[(nr + nrc + j, nb + nbc + j)] = 1.0;
            self.vinv[(nbc + j, nrc + j)] = 1.0;
            self.vinv[(nb + nbc + j, nr + nrc + j)] = 1.0;
        }
    }
}

/// The event rows of a phase's contacts (every contact, closed or open).
struct EventRows {
    ev: Vec<Vec<f64>>,
    ev0: Vec<f64>,
    ev_d: Vec<Vec<f64>>,
    ev_c2: Vec<Vec<f64>>,
    ev_e: Vec<Vec<f64>>,
    ev_fly: Vec<(Option<usize>, Option<usize>)>,
    ev_blocks: Vec<Vec<usize>>,
    ev_nz: Vec<Vec<usize>>,
    evd_nz: Vec<Vec<usize>>,
    search: SearchRows,
}

/// The two channels' output rows over s and constants.
struct OutputRows {
    out_d: [Vec<f64>; 2],
    out_d0: [f64; 2],
    out_v: [Vec<f64>; 2],
    out_v0: [f64; 2],
}

/// What a phase's rows over s are made from: the model, the phase's
/// layout and its whole coordinates.
struct PhaseRows<'a> {
    m: &'a MultiModel,
    lay: &'a Layout,
    w: &'a WholePhase,
}

impl PhaseRows<'_> {
    /// A side's position: a row over y, a constant and a flight; a point's
    /// modes through Q's rows (`q_i = (Q u)_i / omega_i`, an orthonormal
    /// basis), a held mass through `Z`.
    fn side_y(&self, e: &MultiEnd) -> (Vec<f64>, f64, Option<usize>) {
        let (m, lay, n, nr) = (self.m, self.lay, self.m.n(), self.w.nr);
        let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
        let (q, z_of_u) = (&self.w.q, &self.w.z_of_u);
        let mut pos = vec![0.0; self.w.dim];
        match e {
            MultiEnd::Point(w) => {
                for (c, x) in pos.iter_mut().enumerate().take(nr) {
                    *x = (0..n)
                        .map(|i| w[i] * q[(i, c)] / (two_pi() * m.freq_hz[i]))
                        .sum();
                }
                (pos, 0.0, None)
            }
            MultiEnd::Mass(j) => match lay.place[*j] {
                Some(b) => {
                    for (c, x) in pos.iter_mut().enumerate().take(nr) {
                        *x = z_of_u[(n + b, c)] / sqm(*j);
                    }
                    (pos, 0.0, lay.fly_of[*j])
                }
                None => (pos, 0.0, Some(*j)),
            },
            MultiEnd::Wall(hw) => (pos, *hw, None),
        }
    }

    /// A side's velocity straight from s (the trace): a row over y and a
    /// flight.
    fn side_v(&self, e: &MultiEnd) -> (Vec<f64>, Option<usize>) {
        let (m, lay, n, nr) = (self.m, self.lay, self.m.n(), self.w.nr);
        let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
        let p = &self.w.p;
        let mut vel = vec![0.0; self.w.dim];
        match e {
            MultiEnd::Point(w) => {
                for c in 0..nr {
                    vel[nr + c] = (0..n).map(|i| w[i] * p[(i, c)]).sum();
                }
                (vel, None)
            }
            MultiEnd::Mass(j) => match lay.place[*j] {
                Some(b) => {
                    for c in 0..nr {
                        vel[nr + c] = p[(n + b, c)] / sqm(*j);
                    }
                    (vel, lay.fly_of[*j])
                }
                None => (vel, Some(*j)),
            },
            MultiEnd::Wall(_) => (vel, None),
        }
    }

    /// Contact `ct`'s penetration as a row over y, a constant and the
    /// flights of its sides (when they differ); `closed`: its place among
    /// the phase's members, with `p0` their constants.
    fn contact_y(
        &self,
        ct: &MultiContact,
        closed: Option<usize>,
        p0: &[f64],
    ) -> (Vec<f64>, f64, (Option<usize>, Option<usize>)) {
        let (n, nr, q) = (self.m.n(), self.w.nr, &self.w.q);
        match closed {
            // closed: its penetration is a coordinate of Q u, exactly
            // (`sqrt(k) (p - p0)`), not a difference of two sides
            Some(pos) => {
                let mut row = vec![0.0; self.w.dim];
                let sk = ct.stiffness_n_per_m.sqrt();
                for (c, x) in row.iter_mut().enumerate().take(nr) {
                    *x = q[(n + pos, c)] / sk;
                }
                (row, p0[pos], (None, None))
            }
            None => {
                let (lo, lo0, lo_fly) = self.side_y(&ct.lower);
                let (up, up0, up_fly) = self.side_y(&ct.upper);
                let row: Vec<f64> = lo.iter().zip(&up).map(|(a, b)| a - b).collect();
                let fly = if lo_fly == up_fly {
                    (None, None)
                } else {
                    (lo_fly, up_fly)
                };
                (row, lo0 - up0 - ct.gap_m, fly)
            }
        }
    }

    /// Every contact's event rows over s: its penetration, its rate and
    /// the bounds on them, and which blocks and entries they touch.
    fn events(&self, members: &[usize], p0: &[f64]) -> EventRows {
        let (v, y_star, gens) = (&self.w.v, &self.w.y_star, &self.w.gens);
        let nb = gens.len();
        let (mut ev, mut ev0, mut ev_d, mut ev_c2, mut ev_e, mut ev_fly) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        let mut search = SearchRows {
            rho: gens.iter().map(spectral_radius).collect(),
            ..SearchRows::default()
        };
        let norms =
            |row: &[f64]| -> Vec<f64> { (0..nb).map(|k| row[k].hypot(row[nb + k])).collect() };
        for (j, ct) in self.m.contacts.iter().enumerate() {
            let closed = members.iter().position(|&c| c == j);
            let (row_y, c0, fly) = self.contact_y(ct, closed, p0);
            let (r, r0) = in_phase(&row_y, v, y_star);
            let r0 = r0 + c0;
            let rd = row_times_gens(&r, gens);
            let rdd = row_times_gens(&rd, gens);
            let rddd = row_times_gens(&rdd, gens);
            ev_c2.push(norms(&rdd));
            ev_e.push(norms(&r));
            search.c1.push(norms(&rd));
            search.c3.push(norms(&rddd));
            search.ev_dd.push(rdd);
            ev.push(r);
            ev0.push(r0);
            ev_d.push(rd);
            ev_fly.push(fly);
        }
        let ev_blocks = ev
            .iter()
            .zip(&ev_d)
            .map(|(r, d): (&Vec<f64>, &Vec<f64>)| {
                (0..nb)
                    .filter(|&k| r[k] != 0.0 || r[nb + k] != 0.0 || d[k] != 0.0 || d[nb + k] != 0.0)
                    .collect()
            })
            .collect();
        let nz_of = |rows: &[Vec<f64>]| -> Vec<Vec<usize>> {
            rows.iter()
                .map(|r| (0..r.len()).filter(|&i| r[i] != 0.0).collect())
                .collect()
        };
        let (ev_nz, evd_nz) = (nz_of(&ev), nz_of(&ev_d));
        EventRows {
            ev,
            ev0,
            ev_d,
            ev_c2,
            ev_e,
            ev_fly,
            ev_blocks,
            ev_nz,
            evd_nz,
            search,
        }
    }

    /// Each contact's two sides' position and velocity rows over s.
    fn sides(&self) -> Vec<[SideRows; 2]> {
        let (v, y_star) = (&self.w.v, &self.w.y_star);
        self.m
            .contacts
            .iter()
            .map(|ct| {
                [&ct.lower, &ct.upper].map(|e| {
                    let (pos_y, c0, fly) = self.side_y(e);
                    let (vel_y, _) = self.side_v(e);
                    let (pos, pos0) = in_phase(&pos_y, v, y_star);
                    let (vel, vel0) = in_phase(&vel_y, v, y_star);
                    SideRows {
                        pos,
                        pos0: pos0 + c0,
                        vel,
                        vel0,
                        fly,
                    }
                })
            })
            .collect()
    }

    /// The two channels' pickup rows over s.
    fn outputs(&self) -> OutputRows {
        let (m, n, nr, dim) = (self.m, self.m.n(), self.w.nr, self.w.dim);
        let (v, y_star, p, q) = (&self.w.v, &self.w.y_star, &self.w.p, &self.w.q);
        let (mut out_d, mut out_v): ([Vec<f64>; 2], [Vec<f64>; 2]) = Default::default();
        let (mut out_d0, mut out_v0) = ([0.0; 2], [0.0; 2]);
        for c in 0..2 {
            let (disp, velo) = &m.pickups[c];
            let (mut row_d, mut row_v) = (vec![0.0; dim], vec![0.0; dim]);
            for col in 0..nr {
                row_d[col] = (0..n)
                    .map(|i| disp[i] * q[(i, col)] / (two_pi() * m.freq_hz[i]))
                    .sum();
                row_v[nr + col] = (0..n).map(|i| velo[i] * p[(i, col)]).sum();
            }
            (out_d[c], out_d0[c]) = in_phase(&row_d, v, y_star);
            (out_v[c], out_v0[c]) = in_phase(&row_v, v, y_star);
        }
        OutputRows {
            out_d,
            out_d0,
            out_v,
            out_v0,
        }
    }
}

/// The products a switch of phase reads: the modes' and closed
/// contacts' rows (Q), the velocities (P) and the bound masses' positions
/// (Z) per s, V^-1 back, and their coupled parts.
struct SwitchProducts {
    s_star: Vec<f64>,
    qv: DMatrix<f64>,
    pv: DMatrix<f64>,
    zv: DMatrix<f64>,
    qv0: Vec<f64>,
    pv0: Vec<f64>,
    zv0: Vec<f64>,
    qv_c: DMatrix<f64>,
    qv_rows: Vec<usize>,
    pv_c: DMatrix<f64>,
    pv_rows: Vec<usize>,
    zv_c: DMatrix<f64>,
    vq_c: DMatrix<f64>,
    vp_c: DMatrix<f64>,
}

impl SwitchProducts {
    fn new(
        n: usize,
        lay: &Layout,
        members: &[usize],
        cm: &[usize],
        w: &WholePhase,
        coupled: &[usize],
    ) -> Self {
        let (nr, dim) = (w.nr, w.dim);
        let (v, vinv, y_star) = (&w.v, &w.vinv, &w.y_star);
        let (p, q) = (&w.p, &w.q);
        let (v_u, v_w) = (v.rows(0, nr), v.rows(nr, nr));
        let (u_star, w_star) = (
            DMatrix::from_column_slice(nr, 1, &y_star[..nr]),
            DMatrix::from_column_slice(nr, 1, &y_star[nr..]),
        );
        let z_m = w.z_of_u.rows(n, lay.bound.len());
        let col = |x: DMatrix<f64>| x.as_slice().to_vec();
        let s_star = col(vinv * DMatrix::from_column_slice(dim, 1, y_star));
        let (qv, pv, zv) = (q * v_u, p * v_w, z_m * v_u);
        let vq = vinv.columns(0, nr) * q.transpose();
        let vp = vinv.columns(nr, nr) * p.transpose();
        let qv_rows: Vec<usize> = cm.iter().copied().chain(n..n + members.len()).collect();
        let pv_rows: Vec<usize> = cm.iter().copied().chain(n..n + lay.bound.len()).collect();
        let nbnd = lay.bound.len();
        let qv_c = DMatrix::from_fn(qv_rows.len(), coupled.len(), |r, c| {
            qv[(qv_rows[r], coupled[c])]
        });
        let pv_c = DMatrix::from_fn(pv_rows.len(), coupled.len(), |r, c| {
            pv[(pv_rows[r], coupled[c])]
        });
        let zv_c = DMatrix::from_fn(nbnd, coupled.len(), |r, c| zv[(r, coupled[c])]);
        let vq_c = DMatrix::from_fn(coupled.len(), qv_rows.len(), |r, c| {
            vq[(coupled[r], qv_rows[c])]
        });
        let vp_c = DMatrix::from_fn(coupled.len(), pv_rows.len(), |r, c| {
            vp[(coupled[r], pv_rows[c])]
        });
        Self {
            s_star,
            qv0: col(q * &u_star),
            pv0: col(p * &w_star),
            zv0: col(z_m * &u_star),
            qv,
            pv,
            zv,
            qv_c,
            qv_rows,
            pv_c,
            pv_rows,
            zv_c,
            vq_c,
            vp_c,
        }
    }
}

impl MultiPhase {
    /// Block `k`'s `exp(G_k t)` (what [`exp2`] gives, its split made once).
    #[inline]
    pub(super) fn exp_block(&self, k: usize, t: f64) -> Mat2 {
        match &self.forms[k] {
            Some(f) => f.exp(t),
            None => exp2(&self.gens[k], t),
        }
    }
}

impl CompiledMulti {
    /// Compile every phase (`2^K` of them) at `rate_hz`.
    pub fn new(model: &MultiModel, rate_hz: f64) -> Result<Self, MultiError> {
        model.validate()?;
        check_value("rate_hz", rate_hz, rate_hz > 0.0)?;
        model.within_budget()?;
        let k = model.contacts.len();
        let h = 1.0 / rate_hz;
        let phases = (0..1u32 << k)
            .map(|mask| MultiPhase::new(model, mask, h))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            model: model.clone(),
            h,
            rate_hz,
            phases,
            switching: Switching::Exact,
        })
    }

    /// [`new`](Self::new) with the given switching method (the scene's
    /// `contact.switching`).
    pub fn with_switching(
        model: &MultiModel,
        rate_hz: f64,
        switching: Switching,
    ) -> Result<Self, MultiError> {
        let mut sc = Self::new(model, rate_hz)?;
        sc.switching = switching;
        Ok(sc)
    }

    /// Number of contacts.
    pub fn contacts(&self) -> usize {
        self.model.contacts.len()
    }

    /// The largest condition number of the phases' `V`.
    pub fn kappa(&self) -> f64 {
        self.phases.iter().map(|p| p.kappa).fold(1.0, f64::max)
    }

    /// The largest block growth over one sample of any phase
    /// ([`MultiPhase::growth`]).
    pub fn growth(&self) -> f64 {
        self.phases.iter().map(|p| p.growth).fold(1.0, f64::max)
    }

    /// The largest phase dimension.
    pub fn max_dim(&self) -> usize {
        self.phases.iter().map(|p| p.dim).max().unwrap_or(0)
    }
}

impl PhaseTables {
    pub(super) fn new(ph: &MultiPhase) -> Self {
        Self {
            props: vec![[0.0; 4]; ph.gens.len()],
            soa: BlockProps::new(ph.gens.len()),
            growth: vec![1.0; ph.gens.len()],
            growth_max: 1.0,
            ev_c2: ph.ev_c2.clone(),
            ev_e: ph.ev_e.clone(),
            ev_c1: ph.search.c1.clone(),
            ev_c3: ph.search.c3.clone(),
            out: [vec![0.0; ph.dim], vec![0.0; ph.dim]],
            out0: [0.0; 2],
            at: f64::NAN,
            limit: f64::INFINITY,
            muted: 0,
        }
    }

    /// Bring them to `scale` (step `h` of the model's time) and the output
    /// band `band_hz` (physical; infinite: every mode heard). O(dim), plus
    /// O(dim) per mode left out, allocation-free.
    pub(super) fn make(
        &mut self,
        ph: &MultiPhase,
        m: &MultiModel,
        scale: f64,
        h: f64,
        band_hz: f64,
    ) {
        let limit = two_pi() * band_hz / scale;
        if self.at == scale && self.limit == limit {
            return;
        }
        self.growth_max = 1.0;
        for (k, g) in ph.gens.iter().enumerate() {
            self.props[k] = exp2(g, h);
            self.soa.set(k, &self.props[k]);
            self.growth[k] = (sym_growth(g) * h).exp();
            self.growth_max = self.growth_max.max(self.growth[k]);
        }
        for j in 0..self.ev_e.len() {
            for k in 0..ph.gens.len() {
                let g = self.growth[k];
                self.ev_c2[j][k] = ph.ev_c2[j][k] * g;
                self.ev_e[j][k] = ph.ev_e[j][k] * g;
                self.ev_c1[j][k] = ph.search.c1[j][k] * g;
                self.ev_c3[j][k] = ph.search.c3[j][k] * g;
            }
        }
        for c in 0..2 {
            for (o, (d, v)) in self.out[c]
                .iter_mut()
                .zip(ph.out_d[c].iter().zip(&ph.out_v[c]))
            {
                *o = d + scale * v;
            }
            self.out0[c] = ph.out_d0[c] + scale * ph.out_v0[c];
        }
        // a mode above the band leaves the outputs: its share of each row
        // (`q_i = (Q u)_i / omega_i`, `q'_i = (P w)_i`, the rows a switch
        // takes the physical state through) is taken out, in every phase
        // alike, so the output stays a continuous function of the
        // physical state across switches; its dynamics stay
        self.muted = 0;
        for i in 0..m.n() {
            let w = two_pi() * m.freq_hz[i];
            if !(w > limit) {
                continue;
            }
            self.muted += 1;
            for c in 0..2 {
                let (a, b) = (m.pickups[c].0[i] / w, scale * m.pickups[c].1[i]);
                if a == 0.0 && b == 0.0 {
                    continue;
                }
                for (col, o) in self.out[c].iter_mut().enumerate() {
                    *o -= a * ph.qv[(i, col)] + b * ph.pv[(i, col)];
                }
                self.out0[c] -= a * ph.qv0[i] + b * ph.pv0[i];
            }
        }
        self.at = scale;
        self.limit = limit;
    }
}

impl MultiPhase {
    /// The physical state of the phase's `y` (the flights from `fly`).
    pub(super) fn physical_of(
        &self,
        m: &MultiModel,
        s: &[f64],
        (x_f, v_f): (&[f64], &[f64]),
        (zq, zv): (&mut [f64], &mut [f64]),
        out: &mut Physical,
    ) {
        let n = m.n();
        // a free mode's block is its own (omega q, q')
        for &(i, k1, k2) in &self.free_blocks {
            out.q[i] = s[k1] / (two_pi() * m.freq_hz[i]);
            out.qv[i] = s[k2];
        }
        // the coupled modes' q from Q u = (omega q, ...), z' = P w, the
        // held masses' x from Z u (the part off the free groups' centres)
        for &r in &self.qv_rows {
            zq[r] = self.qv0[r];
        }
        mat_vec_idx(&self.qv_c, (&self.coupled, s), &self.qv_rows, zq);
        for &i in &self.coupled_modes {
            out.q[i] = zq[i] / (two_pi() * m.freq_hz[i]);
        }
        for &r in &self.pv_rows {
            zv[r] = self.pv0[r];
        }
        mat_vec_idx(&self.pv_c, (&self.coupled, s), &self.pv_rows, zv);
        for &i in &self.coupled_modes {
            out.qv[i] = zv[i];
        }
        let nb = self.bound.len();
        zq[..nb].copy_from_slice(&self.zv0);
        mat_vec_idx(&self.zv_c, (&self.coupled, s), &self.bound_rows, zq);
        for (j, ms) in m.masses.iter().enumerate() {
            match self.place[j] {
                Some(b) => {
                    let s = ms.mass_kg.sqrt();
                    let (mut x, mut v) = (zq[b] / s, zv[n + b] / s);
                    if let Some(k) = self.fly_of[j] {
                        x += x_f[k];
                        v += v_f[k];
                    }
                    out.x[j] = x;
                    out.v[j] = v;
                }
                None => {
                    out.x[j] = x_f[j];
                    out.v[j] = v_f[j];
                }
            }
        }
    }

    /// The phase's block state `s` of a physical state whose closed
    /// contacts' penetrations are `pen` (by contact), and its flights: `u =
    /// Q^T (omega q, sqrt(k_c) (p_c - p0_c))`, `w = P^T z'`, `s = V^-1 (y -
    /// y*)`.
    /// The penetrations come apart from the positions: as a difference of
    /// two sides a heavy hammer's would keep `u |x|` of error.
    pub(super) fn state_of(
        &self,
        m: &MultiModel,
        (ph, pen): (&Physical, &[f64; MAX_CONTACTS]),
        (x_f, v_f): (&mut [f64], &mut [f64]),
        (zq, zv): (&mut [f64], &mut [f64]),
        s: &mut [f64],
    ) {
        let n = m.n();
        for i in 0..n {
            zq[i] = two_pi() * m.freq_hz[i] * ph.q[i];
        }
        for (pos, &c) in self.members.iter().enumerate() {
            zq[n + pos] = m.contacts[c].stiffness_n_per_m.sqrt() * (pen[c] - self.p0[pos]);
        }
        zv[..n].copy_from_slice(&ph.qv);
        for (b, &j) in self.bound.iter().enumerate() {
            zv[n + b] = m.masses[j].mass_kg.sqrt() * ph.v[j];
        }
        for (j, place) in self.place.iter().enumerate() {
            if place.is_none() {
                x_f[j] = ph.x[j];
                v_f[j] = ph.v[j];
            }
        }
        for grp in &self.groups {
            let total: f64 = grp.iter().map(|&j| m.masses[j].mass_kg).sum();
            let (mut x, mut v) = (0.0, 0.0);
            for &j in grp {
                x += m.masses[j].mass_kg * ph.x[j];
                v += m.masses[j].mass_kg * ph.v[j];
            }
            x_f[grp[0]] = x / total;
            v_f[grp[0]] = v / total;
        }
        for (o, x) in s.iter_mut().zip(&self.s_star) {
            *o = -x;
        }
        // a free mode's block is its own (omega q, q') (its `s*` is 0);
        // the coupled entries through the coupled part's products
        for &(i, k1, k2) in &self.free_blocks {
            s[k1] += zq[i];
            s[k2] += zv[i];
        }
        mat_vec_idx(&self.vq_c, (&self.qv_rows, zq), &self.coupled, s);
        mat_vec_idx(&self.vp_c, (&self.pv_rows, zv), &self.coupled, s);
    }
}
