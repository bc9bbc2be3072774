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
        let n = m.n();
        let g = m.gravity_m_per_s2;
        let members: Vec<usize> = (0..m.contacts.len())
            .filter(|j| mask & (1 << j) != 0)
            .collect();
        let bad = |why: String| MultiError::Phase { mask, why };
        let lay = Layout::new(m, &members);
        let nz = n + lay.bound.len();
        let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
        // each closed contact's row over z and constant: p = g . z + p0
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
        let rows: Vec<(Vec<f64>, f64)> = members.iter().map(|&c| contact_z(c)).collect();
        let p0: Vec<f64> = rows.iter().map(|r| r.1).collect();
        // the modes no closed contact touches keep their free 2x2 blocks
        // (exactly, and degenerate modes need no eigenvectors); the others
        // and the held masses are the coupled part, `zc`
        let (cm, fm): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| rows.iter().any(|r| r.0[i] != 0.0));
        let zc_of: Vec<usize> = cm
            .iter()
            .copied()
            .chain((0..lay.bound.len()).map(|b| n + b))
            .collect();
        let nzc = zc_of.len();
        // P_c: the identity but on each free group, where it is an
        // orthonormal basis of the complement of the group's centre
        // direction e (sqrt(m_j) / sqrt(M)): the columns of the Householder
        // reflection that takes e to the group's first axis, but the first
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
        // F_c P_c with F_c = [diag(omega); sqrt(k_c) g_c^T] on zc, its QR;
        // the damping and the constant forces on zc
        let ncm = cm.len();
        let mut fc = DMatrix::zeros(ncm + members.len(), nzc);
        let mut damping = DMatrix::zeros(nzc, nzc);
        for (a, &i) in cm.iter().enumerate() {
            fc[(a, a)] = two_pi() * m.freq_hz[i];
            damping[(a, a)] = 2.0 * m.sigma[i];
        }
        let mut force = vec![0.0; nzc];
        // per closed contact: the force per metre of a rod in it (on zc)
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
        let (qc, rc) = if nrc == 0 {
            (DMatrix::zeros(fc.nrows(), 0), DMatrix::zeros(0, 0))
        } else {
            let qr = (&fc * &pc).qr();
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
        let zc = &pc * &rinv;
        let dt = pc.transpose() * &damping * &pc;
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
            fy[nrc + i] = (0..nzc).map(|a| pc[(a, i)] * force[a]).sum();
        }
        let (gens_c, vc, vinvc, kappa) = if dimc == 0 {
            (vec![], DMatrix::zeros(0, 0), DMatrix::zeros(0, 0), 1.0)
        } else {
            let d = decompose_via(&a, h, None, true).map_err(|e| bad(e.to_string()))?;
            let Form::Blocks { gens } = d.form else {
                return Err(bad(format!(
                    "no block form ({})",
                    d.diag.fallback_reason.unwrap_or_default()
                )));
            };
            (gens, d.v, d.vinv, d.diag.kappa)
        };
        // the equilibrium `A y* + f = 0`, and per closed contact its move
        // per metre of a rod
        let lu = (dimc > 0).then(|| a.clone().lu());
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
        let yc_star = solve(&fy, "no equilibrium under gravity")?;
        let mut rod_yc = Vec::with_capacity(members.len());
        for rf in &rod_force {
            let mut f = vec![0.0; dimc];
            for i in 0..nrc {
                f[nrc + i] = (0..nzc).map(|a| pc[(a, i)] * rf[a]).sum();
            }
            rod_yc.push(solve(&f, "no equilibrium with an offset rod")?);
        }
        // the whole phase: y = [u_c, u_free; w_c, w_free], the free modes'
        // u = omega q and w = q'; s = [first components of the coupled
        // blocks, of the free blocks; second components of each]
        let nr = nrc + fm.len();
        let dim = 2 * nr;
        let nbc = gens_c.len();
        let nb = nbc + fm.len();
        let ymap = |r: usize| if r < nrc { r } else { nr + r - nrc };
        let smap = |c: usize| if c < nbc { c } else { nb + c - nbc };
        let mut gens = gens_c;
        let (mut v, mut vinv) = (DMatrix::zeros(dim, dim), DMatrix::zeros(dim, dim));
        for r in 0..dimc {
            for c in 0..dimc {
                v[(ymap(r), smap(c))] = vc[(r, c)];
                vinv[(smap(r), ymap(c))] = vinvc[(r, c)];
            }
        }
        let mut y_star = vec![0.0; dim];
        for (r, y) in yc_star.iter().enumerate() {
            y_star[ymap(r)] = *y;
        }
        // V^-1 on the coupled part only (a constant force leaves the free
        // modes alone)
        let rod_s: Vec<Vec<f64>> = rod_yc
            .iter()
            .map(|yc| {
                let mut rs = vec![0.0; dim];
                for r in 0..dimc {
                    rs[smap(r)] = (0..dimc).map(|c| vinvc[(r, c)] * yc[c]).sum();
                }
                rs
            })
            .collect();
        let mut p = DMatrix::zeros(nz, nr);
        let mut z_of_u = DMatrix::zeros(nz, nr);
        let mut q = DMatrix::zeros(n + members.len(), nr);
        for (r, &zi) in zc_of.iter().enumerate() {
            for c in 0..nrc {
                p[(zi, c)] = pc[(r, c)];
                z_of_u[(zi, c)] = zc[(r, c)];
            }
        }
        for r in 0..qc.nrows() {
            let row = if r < ncm { cm[r] } else { n + r - ncm };
            for c in 0..nrc {
                q[(row, c)] = qc[(r, c)];
            }
        }
        for (j, &i) in fm.iter().enumerate() {
            let w = two_pi() * m.freq_hz[i];
            gens.push([0.0, w, -w, -2.0 * m.sigma[i]]);
            v[(nrc + j, nbc + j)] = 1.0;
            v[(nr + nrc + j, nb + nbc + j)] = 1.0;
            vinv[(nbc + j, nrc + j)] = 1.0;
            vinv[(nb + nbc + j, nr + nrc + j)] = 1.0;
            p[(i, nrc + j)] = 1.0;
            z_of_u[(i, nrc + j)] = 1.0 / w;
            q[(i, nrc + j)] = 1.0;
        }
        let growth: Vec<f64> = gens.iter().map(|g| (sym_growth(g) * h).exp()).collect();
        let growth_max = growth.iter().copied().fold(1.0, f64::max);
        let nb = gens.len();
        // a side's position: a row over y, a constant and a flight; a
        // point's modes through Q's rows (`q_i = (Q u)_i / omega_i`, an
        // orthonormal basis), a held mass through `Z`
        let side_y = |e: &MultiEnd| -> (Vec<f64>, f64, Option<usize>) {
            let mut pos = vec![0.0; dim];
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
        };
        let (mut ev, mut ev0, mut ev_d, mut ev_c2, mut ev_e, mut ev_fly) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        for (j, ct) in m.contacts.iter().enumerate() {
            let (row_y, c0, fly) = match members.iter().position(|&c| c == j) {
                // closed: its penetration is a coordinate of Q u, exactly
                // (`sqrt(k) (p - p0)`), not a difference of two sides
                Some(pos) => {
                    let mut row = vec![0.0; dim];
                    let sk = ct.stiffness_n_per_m.sqrt();
                    for (c, x) in row.iter_mut().enumerate().take(nr) {
                        *x = q[(n + pos, c)] / sk;
                    }
                    (row, p0[pos], (None, None))
                }
                None => {
                    let (lo, lo0, lo_fly) = side_y(&ct.lower);
                    let (up, up0, up_fly) = side_y(&ct.upper);
                    let row: Vec<f64> = lo.iter().zip(&up).map(|(a, b)| a - b).collect();
                    let fly = if lo_fly == up_fly {
                        (None, None)
                    } else {
                        (lo_fly, up_fly)
                    };
                    (row, lo0 - up0 - ct.gap_m, fly)
                }
            };
            let (r, r0) = in_phase(&row_y, &v, &y_star);
            let r0 = r0 + c0;
            let rd = row_times_gens(&r, &gens);
            let rdd = row_times_gens(&rd, &gens);
            ev_c2.push((0..nb).map(|k| rdd[k].hypot(rdd[nb + k])).collect());
            ev_e.push((0..nb).map(|k| r[k].hypot(r[nb + k])).collect());
            ev.push(r);
            ev0.push(r0);
            ev_d.push(rd);
            ev_fly.push(fly);
        }
        // each side's position and velocity straight from s (the trace)
        let side_v = |e: &MultiEnd| -> (Vec<f64>, Option<usize>) {
            let mut vel = vec![0.0; dim];
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
        };
        let sides: Vec<[SideRows; 2]> = m
            .contacts
            .iter()
            .map(|ct| {
                [&ct.lower, &ct.upper].map(|e| {
                    let (pos_y, c0, fly) = side_y(e);
                    let (vel_y, _) = side_v(e);
                    let (pos, pos0) = in_phase(&pos_y, &v, &y_star);
                    let (vel, vel0) = in_phase(&vel_y, &v, &y_star);
                    SideRows {
                        pos,
                        pos0: pos0 + c0,
                        vel,
                        vel0,
                        fly,
                    }
                })
            })
            .collect();
        // the entries of s the coupled part moves (the free modes' blocks
        // are their own (omega q, q'))
        let coupled: Vec<usize> = (0..dimc).map(smap).collect();
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
            (out_d[c], out_d0[c]) = in_phase(&row_d, &v, &y_star);
            (out_v[c], out_v0[c]) = in_phase(&row_v, &v, &y_star);
        }
        let mut flyers: Vec<usize> = (0..m.masses.len())
            .filter(|&j| lay.place[j].is_none())
            .collect();
        flyers.extend(lay.groups.iter().map(|grp| grp[0]));
        let (v_u, v_w) = (v.rows(0, nr), v.rows(nr, nr));
        let (u_star, w_star) = (
            DMatrix::from_column_slice(nr, 1, &y_star[..nr]),
            DMatrix::from_column_slice(nr, 1, &y_star[nr..]),
        );
        let z_m = z_of_u.rows(n, lay.bound.len());
        let col = |x: DMatrix<f64>| x.as_slice().to_vec();
        let s_star = col(&vinv * DMatrix::from_column_slice(dim, 1, &y_star));
        let (qv, pv, zv) = (&q * v_u, &p * v_w, z_m * v_u);
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
        let free_blocks: Vec<(usize, usize, usize)> = fm
            .iter()
            .enumerate()
            .map(|(j, &i)| (i, nbc + j, nb + nbc + j))
            .collect();
        let forms = gens.iter().map(OscForm::of).collect();
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
        Ok(Self {
            members,
            dim,
            forms,
            ev_blocks,
            ev_nz,
            evd_nz,
            gens,
            qv0: col(&q * &u_star),
            pv0: col(&p * &w_star),
            zv0: col(z_m * &u_star),
            qv,
            pv,
            zv,
            qv_c,
            qv_rows,
            pv_c,
            pv_rows,
            zv_c,
            bound_rows: (0..nbnd).collect(),
            vq_c,
            vp_c,
            free_blocks,
            s_star,
            bound: lay.bound,
            place: lay.place,
            groups: lay.groups,
            fly_of: lay.fly_of,
            flyers,
            p0,
            rod_s,
            ev,
            ev0,
            ev_d,
            ev_c2,
            ev_e,
            ev_fly,
            sides,
            coupled,
            coupled_modes: cm,
            out_d,
            out_d0,
            out_v,
            out_v0,
            kappa,
            growth: growth_max,
        })
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
            growth: vec![1.0; ph.gens.len()],
            growth_max: 1.0,
            ev_c2: ph.ev_c2.clone(),
            ev_e: ph.ev_e.clone(),
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
            self.growth[k] = (sym_growth(g) * h).exp();
            self.growth_max = self.growth_max.max(self.growth[k]);
        }
        for (j, (c2, e)) in self.ev_c2.iter_mut().zip(&mut self.ev_e).enumerate() {
            for k in 0..ph.gens.len() {
                c2[k] = ph.ev_c2[j][k] * self.growth[k];
                e[k] = ph.ev_e[j][k] * self.growth[k];
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
