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
//! The hammer often meets the object again a few samples later (the object
//! it set ringing comes back up to it). Without gravity the whole strike -
//! every flight, contact and switch - is `eta` times one trajectory, so the
//! compiler follows that trajectory on: for each later switch (an entry,
//! then its release, ...) it stores the instant and the state just after
//! it in the new phase's coordinates, with its derivative
//! ([`RestSwitch`]); the engine writes `eta (S + (T - t) S')` there
//! instead of the change of basis (an entry scaled to the energy the flight
//! it ends has, a release with the stored hammer momentum, so that neither
//! adds energy), and a strike from rest costs no product at all within the
//! stored span (docs/numerics.md, "A strike on an object at rest").
//!
//! The compiler finds these instants on a grid and by bisection, which
//! could miss a crossing between two grid points; they become decisions
//! only where the engine's own certified search confirms them. Before a
//! scene is played (the first engine state made for it, or the
//! instrument's worker for each scene it compiles), the engine runs a
//! downward strike from rest on it, every switch located by its search,
//! and counts the stored switches it takes where they are stored
//! ([`RestStrike::certified`], [`crate::engine::certify_rest_strike`]). A voice takes those at their
//! stored instants without a search: its strike is `eta` times the same
//! trajectory, which differs from the certifying run's by rounding only.
//! A stored switch past them stays a hint the voice's search must confirm;
//! one that does not come where it is stored ends the run, and that switch
//! and every later one take the dense product.

use super::CompiledPhase;
use crate::physics::block::{exp2, mul2, Mat2};
use nalgebra::DMatrix;
use std::sync::OnceLock;

/// `|T - t_r| rho` below which the engine uses the stored release: the
/// remainder of the first-order Taylor step is `<= (|T - t_r| rho)^2 / 2`
/// relative, 5e-17 here.
pub const REST_MATCH: f64 = 1e-8;

/// At a later entry of a strike from rest, the largest relative difference
/// between the amplitude of the state the engine has and that of the
/// trajectory the compiler followed (the square root of their energies'
/// ratio) for which the engine takes the stored state: the two differ by
/// rounding (about `1e-13` over a long lossless flight); a state off the
/// trajectory by more takes the change of basis.
pub const REST_ENERGY_MATCH: f64 = 1e-9;

/// Grid points of the search for `t_r` per radian of the fastest block
/// that the event function contains.
const GRID_PER_RADIAN: f64 = 4.0;

/// At most this many grid points (the contact then counts as too long to
/// precompute, and strikes from rest take the dense product).
const MAX_GRID: usize = 200_000;

/// How long after the first entry the compiler follows a strike from rest
/// \[s, reference time\]: the later contacts of a strike (the hammer meeting
/// the object it set ringing) come within a few milliseconds.
pub const REST_SEQ_T_MAX_S: f64 = 0.02;

/// At most this many switches after the first release are stored.
pub const REST_SEQ_MAX: usize = 16;

/// Grid steps between two looks at the compile's cancellation.
const CANCEL_CHECK_STEPS: usize = 4096;

/// Block steps (grid points times excited blocks) the compiler spends
/// following a strike past its first release; where they run out the
/// stored switches end.
const REST_SEQ_WORK: f64 = 4e7;

/// A switch of a strike from rest after its first release, per unit hammer
/// momentum (as [`RestStrike::f`]): an entry (the contact state just after
/// it) or a release (the free state just after it); they alternate,
/// starting with an entry.
#[derive(Debug, Clone)]
pub struct RestSwitch {
    /// Instant since the strike's first entry \[s, reference time\].
    pub t: f64,
    /// The state just after the switch in the new phase's coordinates.
    pub s: Vec<f64>,
    /// Its derivative with respect to the switch instant.
    pub s_d: Vec<f64>,
    /// Largest eigenvalue modulus of the blocks the state before the switch
    /// excites \[1/s\] (the Taylor step's remainder, as [`RestStrike::rho`]).
    pub rho: f64,
    /// An entry's energy per unit momentum squared and its derivative with
    /// respect to the instant (`0.5 |V_c s|^2`): the engine compares it
    /// with the energy the state it replaces has (O(N) in flight) and
    /// writes the stored state scaled to that energy, so an entry neither
    /// adds energy nor follows a trajectory the state is not on. `None`
    /// for a release.
    pub energy: Option<(f64, f64)>,
    /// A release's hammer momentum per unit momentum and its derivative
    /// (the contact phase's `eta` row on the state before it): the hammer
    /// leaves with the stored trajectory's momentum, so the free state
    /// written, hammer included, is that trajectory's and has its energy.
    /// `None` for an entry.
    pub hammer_eta: Option<(f64, f64)>,
}

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
    /// The switches after the first release, in order (entry, release,
    /// entry, ...), as far as the compiler followed the strike
    /// ([`REST_SEQ_T_MAX_S`], [`REST_SEQ_MAX`]); valid for a hammer that
    /// struck downwards (`eta < 0`).
    pub later: Vec<RestSwitch>,
    /// How many of the stored switches (the first release, then `later` in
    /// order) the engine's own certified search located where they are
    /// stored, on a downward strike from rest the engine runs
    /// ([`crate::engine::certify_rest_strike`]; set once, the first time
    /// an engine state is made for the scene or the scene is certified):
    /// a voice takes these at their stored instants without a search; a
    /// stored switch past them, or any while this is unset, stays a hint
    /// the voice's search must confirm.
    pub certified: OnceLock<usize>,
}

/// What the stage reads from the compiled scene.
pub(super) struct RestInputs<'a> {
    pub free: &'a CompiledPhase,
    pub contact: &'a CompiledPhase,
    pub col_eta: &'a [f64],
    pub w_cf: &'a DMatrix<f64>,
    pub w_fc: &'a DMatrix<f64>,
    /// The free phase's equilibrium (zero without gravity).
    pub s_f_star: &'a [f64],
    /// The offsets of the contact rows of `x_c` and `eta` (zero without
    /// gravity).
    pub offsets_x_eta: (f64, f64),
    /// `sqrt(m_h)`.
    pub sm: f64,
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

/// The strike from rest, or `None` when the scene has none to precompute
/// (gravity or a rod offset makes the contact affine, a dense contact phase
/// has no blocks, or the contact lasts longer than `t_max`).
pub(super) fn rest_strike(inp: &RestInputs) -> Option<RestStrike> {
    let ph = inp.contact;
    let contact = Flow::of(ph)?;
    if inp.offset_pi != 0.0 || inp.s_star.iter().any(|&x| x != 0.0) || inp.col_eta.len() != ph.dim {
        return None;
    }
    let rho = contact.rho(inp.col_eta);
    if !(rho > 0.0 && rho.is_finite()) {
        return None;
    }
    // the contact of a downward strike (eta = -1) from its start: its first
    // downward crossing of p_eff
    let start: Vec<f64> = inp.col_eta.iter().map(|x| -x).collect();
    let excited = (0..contact.nb)
        .filter(|&k| contact.excited(&start, k))
        .count();
    let mut work = (MAX_GRID * excited.max(1)) as f64;
    let (t_r, s_r) = contact.first_crossing(&start, (0.0, 0.0), inp.h, inp.t_max, &mut work)?;
    // F(t_r) and F'(t_r) per unit momentum: one dense product each, once
    // per compile
    let y_r: Vec<f64> = s_r.iter().map(|x| -x).collect();
    let f: Vec<f64> = (inp.w_fc * nalgebra::DVector::from_column_slice(&y_r))
        .data
        .into();
    let yd_r = contact.deriv(&y_r);
    let f_d = (inp.w_fc * nalgebra::DVector::from_vec(yd_r)).data.into();
    let later = later_switches(inp, t_r, &y_r, &f);
    Some(RestStrike {
        t_r,
        f,
        f_d,
        rho,
        later,
        certified: OnceLock::new(),
    })
}

/// A phase advanced in 2x2 blocks, for following the strike.
struct Flow<'a> {
    gens: &'a [Mat2],
    ev: &'a [f64],
    nb: usize,
}

impl<'a> Flow<'a> {
    fn of(ph: &'a CompiledPhase) -> Option<Self> {
        let gens = ph.gens.as_deref()?;
        let nb = gens.len();
        (ph.dense.is_none() && ph.dim == 2 * nb && ph.ev.len() == ph.dim).then_some(Self {
            gens,
            ev: &ph.ev,
            nb,
        })
    }

    fn excited(&self, y: &[f64], k: usize) -> bool {
        y[k] != 0.0 || y[self.nb + k] != 0.0
    }

    /// Largest eigenvalue modulus of the blocks `y` excites.
    fn rho(&self, y: &[f64]) -> f64 {
        (0..self.nb)
            .filter(|&k| self.excited(y, k))
            .map(|k| eig_modulus(&self.gens[k]))
            .fold(0.0, f64::max)
    }

    fn phi(&self, y: &[f64]) -> f64 {
        (0..self.nb)
            .map(|k| self.ev[k] * y[k] + self.ev[self.nb + k] * y[self.nb + k])
            .sum()
    }

    /// [`phi`](Self::phi) over the blocks `ex` only (the others are zero).
    fn phi_on(&self, y: &[f64], ex: &[usize]) -> f64 {
        ex.iter()
            .map(|&k| self.ev[k] * y[k] + self.ev[self.nb + k] * y[self.nb + k])
            .sum()
    }

    /// `y` advanced by `t` through the closed-form block exponentials.
    fn advance(&self, y: &[f64], t: f64) -> Vec<f64> {
        let mut out = vec![0.0; y.len()];
        for k in (0..self.nb).filter(|&k| self.excited(y, k)) {
            (out[k], out[self.nb + k]) = mul2(&exp2(&self.gens[k], t), y[k], y[self.nb + k]);
        }
        out
    }

    /// The time derivative `G y`.
    fn deriv(&self, y: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; y.len()];
        for k in 0..self.nb {
            (out[k], out[self.nb + k]) = mul2(&self.gens[k], y[k], y[self.nb + k]);
        }
        out
    }

    /// The first downward crossing after 0 of `phi(y(t)) + a + b t`, which
    /// must start positive at the first grid point: the instant and the
    /// state there, or `None` (no crossing before `t_end`, an ambiguous
    /// start, or the work budget spent). A grid of [`GRID_PER_RADIAN`]
    /// points per radian of the fastest excited block (at most a sample
    /// `h` apart), stepped by the exact one-step propagators, then
    /// bisection on the closed form from the bracket's start.
    fn first_crossing(
        &self,
        y0: &[f64],
        (a, b): (f64, f64),
        h: f64,
        t_end: f64,
        work: &mut f64,
    ) -> Option<(f64, Vec<f64>)> {
        let rho = self.rho(y0);
        let dt = if rho > 0.0 {
            (1.0 / (GRID_PER_RADIAN * rho)).min(h)
        } else {
            h
        };
        let ex: Vec<usize> = (0..self.nb).filter(|&k| self.excited(y0, k)).collect();
        let steps: Vec<Mat2> = ex.iter().map(|&k| exp2(&self.gens[k], dt)).collect();
        let at = |y: &[f64], t: f64| self.phi(y) + a + b * t;
        // a grid step costs the excited blocks only (each step's work is
        // what `work` counts: a scene of many modes with few excited must
        // not pay for all of them per step)
        let mut y = y0.to_vec();
        let mut t = 0.0;
        let mut grid = 0usize;
        let t_a = loop {
            for (&k, p) in ex.iter().zip(&steps) {
                (y[k], y[self.nb + k]) = mul2(p, y[k], y[self.nb + k]);
            }
            grid += 1;
            *work -= ex.len().max(1) as f64;
            let t_next = grid as f64 * dt;
            let phi = self.phi_on(&y, &ex) + a + b * t_next;
            if !phi.is_finite() || *work < 0.0 || t_next > t_end {
                return None;
            }
            if grid.is_multiple_of(CANCEL_CHECK_STEPS) && super::cancel::cancelled() {
                return None;
            }
            if phi <= 0.0 {
                if grid == 1 {
                    // the first grid point is not clear of the surface
                    return None;
                }
                break t;
            }
            t = t_next;
        };
        // the closed form from the segment's start decides; it must agree
        // with the grid on the bracket
        let t_b = t_a + dt;
        let phi_closed = |tau: f64| at(&self.advance(y0, tau), tau);
        if !(phi_closed(t_a) > 0.0 && phi_closed(t_b) <= 0.0) {
            return None;
        }
        let (mut lo, mut hi) = (t_a, t_b);
        loop {
            let m = 0.5 * (lo + hi);
            if m <= lo || m >= hi {
                break;
            }
            if phi_closed(m) > 0.0 {
                lo = m;
            } else {
                hi = m;
            }
        }
        Some((hi, self.advance(y0, hi)))
    }
}

/// Follow a strike from rest past its first release (`t_r`, contact state
/// `y_r` and free state `f` there, per unit momentum): the later switches,
/// per unit momentum, for a hammer that struck downwards. Empty when the
/// scene is affine (gravity), a phase is dense, or the hammer does not
/// come back within [`REST_SEQ_T_MAX_S`].
fn later_switches(inp: &RestInputs, t_r: f64, y_r: &[f64], f: &[f64]) -> Vec<RestSwitch> {
    let mut out = Vec::new();
    let (Some(free), Some(contact)) = (Flow::of(inp.free), Flow::of(inp.contact)) else {
        return out;
    };
    // an entry's energy check needs the flight's energy in O(N)
    if inp.free.energy_quad.is_none()
        || inp.s_f_star.iter().any(|&x| x != 0.0)
        || inp.offsets_x_eta != (0.0, 0.0)
        || !(inp.sm > 0.0)
        || inp.w_cf.shape() != (contact.nb * 2, free.nb * 2)
        || inp.w_fc.shape() != (free.nb * 2, contact.nb * 2)
    {
        return out;
    }
    let rows = &inp.contact.rows;
    let (x_c_row, eta_row) = (&rows.x_c, &rows.eta);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    // the trajectory of a downward strike (eta = -1): the stored vectors
    // are per unit momentum, so they are its negation
    let neg = |v: Vec<f64>| -> Vec<f64> { v.into_iter().map(|x| -x).collect() };
    let mut s_c: Vec<f64> = y_r.iter().map(|x| -x).collect();
    let mut s_f: Vec<f64> = f.iter().map(|x| -x).collect();
    let mut t_now = t_r;
    let mut work = REST_SEQ_WORK;
    let mat = |m: &DMatrix<f64>, v: &[f64]| -> Vec<f64> {
        (m * nalgebra::DVector::from_column_slice(v)).data.into()
    };
    while out.len() + 2 <= REST_SEQ_MAX {
        // the hammer after the release: x_h = x_c - p_eff, v_h = eta / sqrt(m_h)
        let p_eff = contact.phi(&s_c);
        let x_h = dot(x_c_row, &s_c) - p_eff;
        let eta_h = dot(eta_row, &s_c);
        let v_h = eta_h / inp.sm;
        // flight: phi_f = ev_f . s_f + x_h + v_h t
        let left = REST_SEQ_T_MAX_S - t_now;
        let Some((dt_f, s_f_e)) = free.first_crossing(&s_f, (x_h, v_h), inp.h, left, &mut work)
        else {
            break;
        };
        // entry: s_c = W_cf s_f + col_eta eta (the spring unstretched)
        let t_e = t_now + dt_f;
        let mut e = mat(inp.w_cf, &s_f_e);
        for (x, c) in e.iter_mut().zip(inp.col_eta) {
            *x += c * eta_h;
        }
        let e_d = mat(inp.w_cf, &free.deriv(&s_f_e));
        let rho_f = free.rho(&s_f_e);
        let (y, y_d) = (mat(&inp.contact.v, &e), mat(&inp.contact.v, &e_d));
        let energy = (0.5 * dot(&y, &y), dot(&y, &y_d));
        // contact: until p_eff comes down through zero
        let left = REST_SEQ_T_MAX_S - t_e;
        let release = contact.first_crossing(&e, (0.0, 0.0), inp.h, left, &mut work);
        out.push(RestSwitch {
            t: t_e,
            s: neg(e),
            s_d: neg(e_d),
            rho: rho_f,
            energy: Some(energy),
            hammer_eta: None,
        });
        let Some((dt_c, s_c_r)) = release else {
            break;
        };
        let t_l = t_e + dt_c;
        let f_l = mat(inp.w_fc, &s_c_r);
        let s_c_r_d = contact.deriv(&s_c_r);
        let f_l_d = mat(inp.w_fc, &s_c_r_d);
        let hammer_eta = (-dot(eta_row, &s_c_r), -dot(eta_row, &s_c_r_d));
        out.push(RestSwitch {
            t: t_l,
            s: neg(f_l.clone()),
            s_d: neg(f_l_d),
            rho: contact.rho(&s_c_r),
            energy: None,
            hammer_eta: Some(hammer_eta),
        });
        (s_c, s_f, t_now) = (s_c_r, f_l, t_l);
    }
    out
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
