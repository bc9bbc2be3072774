//! Stage 5b of the compiler: what a strike on the object *at rest* needs, so
//! that such a strike costs O(N) instead of two dense changes of basis
//! (docs/numerics.md, "A strike on an object at rest").
//!
//! Without gravity the contact phase is linear and homogeneous. A hammer that
//! meets the object at rest starts the contact phase in the state `s_c(0) =
//! col_eta eta` (the object's coordinates are zero, the spring unstretched),
//! so the whole contact is `s_c(t) = eta exp(G t) col_eta`: its release
//! instant `t_r` (the first downward crossing of `p_eff`) does not depend on
//! the speed `eta`, and the free state at the release is `eta F(t_r)` with
//! `F(t) = W_fc exp(G t) col_eta`. The compiler finds `t_r` and stores
//! `F(t_r)` and `F'(t_r)`; the engine, when it releases a contact that began
//! on the object at rest at the instant `T` it located itself, writes `eta
//! (F(t_r) + (T - t_r) F'(t_r))` instead of the dense product `W_fc s_c` -
//! both equal the exact state to rounding (the engine checks `|T - t_r|
//! rho <= REST_MATCH` so the Taylor remainder is below rounding).
//!
//! `t_r` is only a hint: the instant of the release is always the one the
//! engine's certified search locates. A `t_r` that missed the true first
//! crossing would simply never match, and every release would take the
//! dense product.

use super::CompiledPhase;
use crate::physics::block::{exp2, mul2, Mat2};
use nalgebra::DMatrix;

/// `|T - t_r| rho` below which the engine uses the stored release: the
/// remainder of the first-order Taylor step is `<= (|T - t_r| rho)^2 / 2`
/// relative, 5e-17 here.
pub const REST_MATCH: f64 = 1e-8;

/// Grid points of the search for `t_r` per radian of the fastest block
/// that the event function contains.
const GRID_PER_RADIAN: f64 = 4.0;

/// At most this many grid points (the contact then counts as too long to
/// precompute, and strikes from rest take the dense product).
const MAX_GRID: usize = 200_000;

/// A strike on the object at rest, per unit hammer momentum `eta` (energy
/// coordinates, `eta = sqrt(m_h) v`).
#[derive(Debug, Clone)]
pub struct RestStrike {
    /// Contact duration \[s, reference time\]: the first downward crossing of
    /// `p_eff` after a strike on the object at rest.
    pub t_r: f64,
    /// `F(t_r) = W_fc exp(G t_r) col_eta`: the free state at the release.
    pub f: Vec<f64>,
    /// `F'(t_r) = W_fc G exp(G t_r) col_eta`.
    pub f_d: Vec<f64>,
    /// Largest eigenvalue modulus of the contact blocks that the strike
    /// excites \[1/s\].
    pub rho: f64,
}

/// What the stage reads from the compiled scene.
pub(super) struct RestInputs<'a> {
    pub contact: &'a CompiledPhase,
    pub col_eta: &'a [f64],
    pub w_fc: &'a DMatrix<f64>,
    pub s_star: &'a [f64],
    pub offset_pi: f64,
    /// Sample period \[s\].
    pub h: f64,
    /// The longest contact precomputed \[s\].
    pub t_max: f64,
}

/// Largest eigenvalue modulus of a real 2x2 generator.
fn eig_modulus(g: &Mat2) -> f64 {
    let m = 0.5 * (g[0] + g[3]);
    let det = g[0] * g[3] - g[1] * g[2];
    let disc = m * m - det;
    if disc >= 0.0 {
        m.abs() + disc.sqrt()
    } else {
        det.abs().sqrt()
    }
}

/// The excited blocks: index, generator and `col_eta` part.
struct Excited {
    k: usize,
    g: Mat2,
    c: (f64, f64),
    ev: (f64, f64),
}

/// The event function `p_eff` of a unit strike (`eta = -1`: the hammer
/// moving down) at `t`, from the closed-form block exponentials.
fn phi_at(ex: &[Excited], t: f64) -> f64 {
    ex.iter()
        .map(|e| {
            let (y0, y1) = mul2(&exp2(&e.g, t), e.c.0, e.c.1);
            -(e.ev.0 * y0 + e.ev.1 * y1)
        })
        .sum()
}

/// The strike from rest, or `None` when the scene has none to precompute
/// (gravity or a rod offset makes the contact affine, a dense contact phase
/// has no blocks, or the contact lasts longer than `t_max`).
pub(super) fn rest_strike(inp: &RestInputs) -> Option<RestStrike> {
    let ph = inp.contact;
    let gens = ph.gens.as_ref()?;
    let nb = gens.len();
    if ph.dense.is_some()
        || ph.dim != 2 * nb
        || inp.offset_pi != 0.0
        || inp.s_star.iter().any(|&x| x != 0.0)
        || inp.col_eta.len() != ph.dim
    {
        return None;
    }
    let ex: Vec<Excited> = (0..nb)
        .filter(|&k| inp.col_eta[k] != 0.0 || inp.col_eta[nb + k] != 0.0)
        .map(|k| Excited {
            k,
            g: gens[k],
            c: (inp.col_eta[k], inp.col_eta[nb + k]),
            ev: (ph.ev[k], ph.ev[nb + k]),
        })
        .collect();
    let rho = ex.iter().map(|e| eig_modulus(&e.g)).fold(0.0, f64::max);
    if !(rho > 0.0 && rho.is_finite()) {
        return None;
    }
    // Bracket the first downward crossing on a grid stepped by the exact
    // one-step propagators (O(N) per point), then bisect on the closed form.
    let dt = (1.0 / (GRID_PER_RADIAN * rho)).min(inp.h);
    let steps: Vec<Mat2> = ex.iter().map(|e| exp2(&e.g, dt)).collect();
    let mut y: Vec<(f64, f64)> = ex.iter().map(|e| e.c).collect();
    let (mut t, mut phi_prev) = (0.0, 0.0);
    let mut grid = 0usize;
    let (a, b) = loop {
        grid += 1;
        if grid > MAX_GRID || t > inp.t_max {
            return None;
        }
        let mut phi = 0.0;
        for ((e, p), yk) in ex.iter().zip(&steps).zip(y.iter_mut()) {
            *yk = mul2(p, yk.0, yk.1);
            phi -= e.ev.0 * yk.0 + e.ev.1 * yk.1;
        }
        let t_next = grid as f64 * dt;
        // a crossing: from positive to <= 0 (phi rises from 0 first)
        if phi_prev > 0.0 && phi <= 0.0 {
            break (t, t_next);
        }
        if !phi.is_finite() {
            return None;
        }
        phi_prev = phi;
        t = t_next;
    };
    let (mut a, mut b) = (a, b);
    // the closed form decides; it must agree with the grid on the bracket
    if !(phi_at(&ex, a) > 0.0 && phi_at(&ex, b) <= 0.0) {
        return None;
    }
    loop {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            break;
        }
        if phi_at(&ex, m) > 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    let t_r = b;
    // F(t_r) and F'(t_r): one dense product each, once per compile
    let dim = ph.dim;
    let (mut y_r, mut yd_r) = (vec![0.0; dim], vec![0.0; dim]);
    for e in &ex {
        let (y0, y1) = mul2(&exp2(&e.g, t_r), e.c.0, e.c.1);
        let (d0, d1) = mul2(&e.g, y0, y1);
        (y_r[e.k], y_r[nb + e.k]) = (y0, y1);
        (yd_r[e.k], yd_r[nb + e.k]) = (d0, d1);
    }
    let f = (inp.w_fc * nalgebra::DVector::from_vec(y_r)).data.into();
    let f_d = (inp.w_fc * nalgebra::DVector::from_vec(yd_r)).data.into();
    Some(RestStrike { t_r, f, f_d, rho })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvalue_moduli_of_2x2_generators() {
        // rotation with decay: -s +- i w
        let (s, w) = (3.0, 40.0);
        let g = [-s, w, -w, -s];
        assert!((eig_modulus(&g) - (s * s + w * w).sqrt()).abs() < 1e-12);
        // real pair -1, -100
        let g = [-1.0, 0.0, 0.0, -100.0];
        assert!((eig_modulus(&g) - 100.0).abs() < 1e-12);
    }
}
