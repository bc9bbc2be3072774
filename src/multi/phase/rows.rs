//! The rows a phase's engine reads over its block state: every contact's
//! event rows, its sides' positions and velocities, the outputs, and the
//! products a switch of phase reads.

use super::whole::WholePhase;
use super::*;

/// The event rows of a phase's contacts (every contact, closed or open).
pub(super) struct EventRows {
    pub(super) ev: Vec<Vec<f64>>,
    pub(super) ev0: Vec<f64>,
    pub(super) ev_d: Vec<Vec<f64>>,
    pub(super) ev_c2: Vec<Vec<f64>>,
    pub(super) ev_e: Vec<Vec<f64>>,
    pub(super) ev_fly: Vec<(Option<usize>, Option<usize>)>,
    pub(super) ev_blocks: Vec<Vec<usize>>,
    pub(super) ev_nz: Vec<Vec<usize>>,
    pub(super) evd_nz: Vec<Vec<usize>>,
    pub(super) search: SearchRows,
}

/// The two channels' output rows over s and constants.
pub(super) struct OutputRows {
    pub(super) out_d: [Vec<f64>; 2],
    pub(super) out_d0: [f64; 2],
    pub(super) out_v: [Vec<f64>; 2],
    pub(super) out_v0: [f64; 2],
}

/// What a phase's rows over s are made from: the model, the phase's
/// layout and its whole coordinates.
pub(super) struct PhaseRows<'a> {
    pub(super) m: &'a MultiModel,
    pub(super) lay: &'a Layout,
    pub(super) w: &'a WholePhase,
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
    pub(super) fn events(&self, members: &[usize], p0: &[f64]) -> EventRows {
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
            search.c4.push(norms(&row_times_gens(&rddd, gens)));
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
    pub(super) fn sides(&self) -> Vec<[SideRows; 2]> {
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
    pub(super) fn outputs(&self) -> OutputRows {
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
pub(super) struct SwitchProducts {
    pub(super) s_star: Vec<f64>,
    pub(super) qv: DMatrix<f64>,
    pub(super) pv: DMatrix<f64>,
    pub(super) zv: DMatrix<f64>,
    pub(super) qv0: Vec<f64>,
    pub(super) pv0: Vec<f64>,
    pub(super) zv0: Vec<f64>,
    pub(super) qv_c: DMatrix<f64>,
    pub(super) qv_rows: Vec<usize>,
    pub(super) pv_c: DMatrix<f64>,
    pub(super) pv_rows: Vec<usize>,
    pub(super) zv_c: DMatrix<f64>,
    pub(super) vq_c: DMatrix<f64>,
    pub(super) vp_c: DMatrix<f64>,
}

impl SwitchProducts {
    pub(super) fn new(
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
