//! The whole phase: the coupled part's blocks and the free modes' own,
//! with the coordinates that map the state back to the modes and masses.

use super::coupled::{CoupledBlocks, CoupledPart, CoupledSystem, Equilibrium};
use super::*;

/// The whole phase: `y = [u_c, u_free; w_c, w_free]`, the free modes'
/// `u = omega q` and `w = q'`; `s = [first components of the coupled
/// blocks, of the free blocks; second components of each]`.
pub(super) struct WholePhase {
    /// `u`'s dimension.
    pub(super) nr: usize,
    /// The state's dimension, `2 nr`.
    pub(super) dim: usize,
    /// The coupled part's `u` dimension.
    nrc: usize,
    /// The coupled blocks.
    pub(super) nbc: usize,
    /// All blocks.
    pub(super) nb: usize,
    /// Every block's generator, the coupled ones first.
    pub(super) gens: Vec<Mat2>,
    /// V.
    pub(super) v: DMatrix<f64>,
    /// V^-1.
    pub(super) vinv: DMatrix<f64>,
    /// The equilibrium y*.
    pub(super) y_star: Vec<f64>,
    /// Per closed contact: the equilibrium's move per metre of a rod, in s.
    pub(super) rod_s: Vec<Vec<f64>>,
    /// z per `w` (z' = P w).
    pub(super) p: DMatrix<f64>,
    /// z per `u`.
    pub(super) z_of_u: DMatrix<f64>,
    /// The modes' and closed contacts' rows per `u` (Q).
    pub(super) q: DMatrix<f64>,
}

impl WholePhase {
    pub(super) fn new(
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
    pub(super) fn smap(&self, c: usize) -> usize {
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
