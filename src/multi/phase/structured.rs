//! A switch's products in hierarchical low-rank form
//! ([`StructuredProducts`]): the coupled part's `Q V_u`, `P V_w`,
//! `V^-1_u Q^T` and `V^-1_w P^T` of a phase, ordered by frequency on both
//! sides, are Cauchy-like as the one-contact engine's changes of basis are
//! (a phase's modes are the free modes changed by a few springs), so where
//! the form pays a product costs O(N r log N) instead of O(N^2)
//! (docs/numerics.md section 14, "Structured switches").

use super::rows::SwitchProducts;
use super::*;
use crate::engine::kernel::hodlr_mat_vec_add;
use crate::engine::vmath::SimdPath;
use crate::physics::hodlr::Hodlr;

/// The truncation of the products' off-diagonal blocks, in `u |W|_2`: the
/// products are formed by dense products of the phase's eigenvectors, so
/// their entries carry rounding of about `sqrt(N) u` (measured: a 200-mode
/// object's blocks keep 35 to 42 of 50 singular values above `4 u |W|_2`,
/// the one-contact engine's truncation, and their measured residuals are
/// ten times that); at `TOL_U` they keep a rank near 20.
const TOL_U: f64 = 256.0;

/// The four products of a phase's switch in hierarchical form, each `None`
/// where the dense product stays (too small to pay, or the form failed
/// its check: [`Hodlr::try_build`]).
#[derive(Debug, Clone, Default)]
pub(in crate::multi) struct StructuredProducts {
    pub(in crate::multi) qv: Option<Hodlr>,
    pub(in crate::multi) pv: Option<Hodlr>,
    pub(in crate::multi) vq: Option<Hodlr>,
    pub(in crate::multi) vp: Option<Hodlr>,
}

/// The order that sorts `keys` increasing (ties by index).
fn order_of(keys: &[f64]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..keys.len()).collect();
    idx.sort_by(|&a, &b| keys[a].total_cmp(&keys[b]).then(a.cmp(&b)));
    idx
}

impl StructuredProducts {
    /// The products of `sp` in hierarchical form where it pays. Rows of
    /// the physical side (`qv_rows`, `pv_rows`) in the order of their
    /// modes' frequencies, the closed contacts' and held masses' rows
    /// after them; the coupled entries of `s` in the order of their
    /// blocks' `|det G_k|` (the one-contact engine's `frequency_order`),
    /// each block's two coordinates together. Each form's permutations
    /// are then composed with the rows it reads and writes (`coupled`,
    /// `qv_rows`, `pv_rows`), so a product reads the state's vector and
    /// adds into the physical side's (and back) with one gather and one
    /// scatter.
    pub(super) fn new(
        freq_hz: &[f64],
        cm: &[usize],
        sp: &SwitchProducts,
        coupled: &[usize],
        gens: &[Mat2],
    ) -> Self {
        let nb = gens.len();
        let det = |g: &Mat2| (g[0] * g[3] - g[1] * g[2]).abs();
        let col_keys: Vec<(f64, usize, usize)> = coupled
            .iter()
            .map(|&e| {
                let b = if e < nb { e } else { e - nb };
                (det(&gens[b]), b, e)
            })
            .collect();
        let mut cols: Vec<usize> = (0..coupled.len()).collect();
        cols.sort_by(|&a, &b| {
            let (x, y) = (col_keys[a], col_keys[b]);
            x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2))
        });
        let row_keys = |rows: &[usize]| -> Vec<f64> {
            (0..rows.len())
                .map(|r| cm.get(r).map_or(f64::INFINITY, |&i| freq_hz[i]))
                .collect()
        };
        let (qr, pr) = (
            order_of(&row_keys(&sp.qv_rows)),
            order_of(&row_keys(&sp.pv_rows)),
        );
        let form = |w, rp: &[usize], cp: &[usize], (rows, cols): (&[usize], &[usize])| {
            Hodlr::try_build_at(w, rp, cp, TOL_U).ok().map(|mut h| {
                for r in &mut h.row_perm {
                    *r = rows[*r];
                }
                for c in &mut h.col_perm {
                    *c = cols[*c];
                }
                h
            })
        };
        let (qv, pv) = (&sp.qv_rows[..], &sp.pv_rows[..]);
        Self {
            qv: form(&sp.qv_c, &qr, &cols, (qv, coupled)),
            pv: form(&sp.pv_c, &pr, &cols, (pv, coupled)),
            vq: form(&sp.vq_c, &cols, &qr, (coupled, qv)),
            vp: form(&sp.vp_c, &cols, &pr, (coupled, pv)),
        }
    }

    /// How many of the four are in hierarchical form.
    pub(in crate::multi) fn count(&self) -> usize {
        [&self.qv, &self.pv, &self.vq, &self.vp]
            .iter()
            .filter(|h| h.is_some())
            .count()
    }

    /// The largest rows, columns and rank of the four (the scratch a
    /// product needs).
    pub(in crate::multi) fn sizes(&self) -> (usize, usize, usize) {
        [&self.qv, &self.pv, &self.vq, &self.vp]
            .iter()
            .filter_map(|h| h.as_ref())
            .fold((0, 0, 0), |(r, c, k), h| {
                (r.max(h.rows), c.max(h.cols), k.max(h.max_rank))
            })
    }
}

/// A state's scratch for the structured products (allocated with the
/// state, off the audio thread).
#[derive(Debug, Clone)]
pub(in crate::multi) struct SwitchScratch {
    tmp: [Vec<f64>; 3],
}

impl SwitchScratch {
    /// Room for every phase of `phases` and of any other compile of the
    /// same layout (a state is carried between such compiles: a kit's
    /// hardness levels, a parameter change): a product's rows and columns
    /// are at most the largest phase's dimension or the object's rows
    /// (`n` modes, the contacts, the masses), its rank at most the smaller.
    pub(in crate::multi) fn new(m: &MultiModel, phases: &[MultiPhase]) -> Self {
        let dim = phases.iter().map(|p| p.dim).max().unwrap_or(0);
        let (mut rows, mut cols, mut rank) =
            (dim.max(m.n() + m.masses.len() + MAX_SPRINGS), dim, dim);
        for ph in phases {
            let (r, c, k) = ph.structured.sizes();
            rows = rows.max(r);
            cols = cols.max(c);
            rank = rank.max(k);
        }
        Self {
            tmp: [vec![0.0; cols], vec![0.0; rows], vec![0.0; rank]],
        }
    }
}

/// `out[rows[r]] += sum_c M[r, c] x[cols[c]]`: through `h` with the
/// scratch (on the state's kernel path) when both are there and the
/// scratch has room for `h`, else the dense `m`
/// (`mat_vec_idx`, the dense product's order). O(stored entries) or O(entries),
/// allocation-free. \[audio-thread\]
pub(in crate::multi) fn product(
    h: Option<&Hodlr>,
    m: &DMatrix<f64>,
    (cols, x): (&[usize], &[f64]),
    rows: &[usize],
    out: &mut [f64],
    scratch: Option<(&mut SwitchScratch, SimdPath)>,
) {
    // A state made for another compile of the same layout (a carry to a
    // recompile) may hold less scratch than this compile's forms need:
    // then the dense product, never an index out of its room.
    let fits = |h: &Hodlr, sw: &SwitchScratch| {
        sw.tmp[0].len() >= h.cols && sw.tmp[1].len() >= h.rows && sw.tmp[2].len() >= h.max_rank
    };
    match (h, scratch) {
        // h's permutations are composed with `cols` and `rows` (`new`)
        (Some(h), Some((sw, path))) if fits(h, sw) => {
            let [a, b, c] = &mut sw.tmp;
            hodlr_mat_vec_add(path, h, x, out, [a, b, c]);
        }
        _ => mat_vec_idx(m, (cols, x), rows, out),
    }
}
