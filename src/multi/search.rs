//! A contact's event function as the certified search sees it: the one
//! search of every engine (`engine/search.rs`; docs/numerics.md section
//! 6.4, and section 14 for what is particular to several contacts) on the
//! model this engine has of a contact's penetration over the rest of a
//! step: a row over the phase's 2x2 blocks, each `exp(G_k t) s_k` exactly,
//! plus the exact parabolas of the contact's free sides.

use super::*;
use crate::compile::event::THETA_RESOLVED;
use crate::engine::search::{
    self, hermite_low, hermite_rest_clears, EventModel, Found, NodeBounds, Tally, ROUND_UNITS,
    STACK,
};

/// `|(a, b)|`: the square root of the sum of squares where the sum can
/// neither overflow nor lose digits to underflow (a correctly rounded
/// root of a sum rounded twice: within 2 ulp), `hypot` elsewhere: a node
/// takes one per block it touches, and libm's `hypot` costs several square
/// roots. The bounds it enters carry their rounding allowances
/// (`ROUND_UNITS`), far above these ulps.
#[inline]
fn norm2(a: f64, b: f64) -> f64 {
    let s = a * a + b * b;
    if (1e-290..=1e290).contains(&s) {
        s.sqrt()
    } else {
        a.hypot(b)
    }
}

/// Contact `j`'s event function `psi` in the current phase from the
/// block state `s` at the search's origin.
struct ContactModel<'a> {
    ph: &'a MultiPhase,
    tb: &'a PhaseTables,
    j: usize,
    s: &'a [f64],
    f: EventFn,
    tol: (f64, f64),
    stack: &'a mut [(f64, f64); STACK],
    trig: &'a mut Trig,
    simd: SimdPath,
    evaluations: &'a mut u64,
}

impl ContactModel<'_> {
    /// Bounds on `[a, a + w]` (`all`: every block resolved, the exact
    /// value, slope and curvature at `a`). A block whose generator turns
    /// by at most `THETA_RESOLVED` over the node adds its value, slope and
    /// curvature at `a` and its third derivative's bound; any other, its
    /// envelope and its slope's. O(blocks the row touches).
    fn node(&mut self, a: f64, w: f64, all: bool) -> NodeBounds {
        *self.evaluations += 1;
        let (ph, tb, j) = (self.ph, self.tb, self.j);
        let nb = ph.gens.len();
        let (r, rd, rdd) = (&ph.ev[j], &ph.ev_d[j], &ph.search.ev_dd[j]);
        let EventFn {
            sign, x0, v0, g, ..
        } = self.f;
        let mut out = NodeBounds {
            q: [ph.ev0[j] + x0 + a * (v0 - 0.5 * g * a), v0 - g * a, -g],
            u: 0.0,
            l: 0.0,
            c3: 0.0,
        };
        self.trig
            .at(self.simd, ph, ph.ev_blocks[j].iter().copied(), a);
        for (i, &k) in ph.ev_blocks[j].iter().enumerate() {
            let (y0, y1) = mul2(&self.trig.exp(ph, k, i, a), self.s[k], self.s[nb + k]);
            if all || ph.search.rho[k] * w <= THETA_RESOLVED {
                out.q[0] += r[k] * y0 + r[nb + k] * y1;
                out.q[1] += rd[k] * y0 + rd[nb + k] * y1;
                out.q[2] += rdd[k] * y0 + rdd[nb + k] * y1;
                if !all {
                    out.c3 += tb.ev_c3[j][k] * norm2(y0, y1);
                }
            } else {
                let n = norm2(y0, y1);
                out.u += tb.ev_e[j][k] * n;
                out.l += tb.ev_c1[j][k] * n;
            }
        }
        out.q = out.q.map(|x| sign * x);
        out
    }
}

impl EventModel for ContactModel<'_> {
    fn bounds(&mut self, a: f64, w: f64) -> NodeBounds {
        self.node(a, w, false)
    }

    fn eval(&mut self, t: f64) -> [f64; 3] {
        self.node(t, 0.0, true).q
    }

    fn tolerances(&self) -> (f64, f64) {
        self.tol
    }

    fn stack(&mut self) -> &mut [(f64, f64); STACK] {
        self.stack
    }
}

impl MultiState {
    /// The first crossing of contact `j` in `(0, rem]` of the current step
    /// (the state `s` at its origin, `end` at `rem`), or `None`: a whole
    /// sample that clears its epoch's margin holds none; a contact on the
    /// far side at the origin crosses there; otherwise the certified
    /// search decides, from the origin as a switch instant (`open`) for a
    /// contact that just switched.
    pub(super) fn first_crossing(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        rem: f64,
        start: Start,
    ) -> Option<f64> {
        let ph = &sc.phases[self.slot];
        let f = self.event_fn(sc, j);
        let q0 = dot_at(&ph.ev[j], &self.s, &ph.ev_nz[j]) + ph.ev0[j];
        let q_end = dot_at(&ph.ev[j], &self.end, &ph.ev_nz[j]) + ph.ev0[j];
        let (psi0, psi_end) = (f.psi(q0, 0.0), f.psi(q_end, rem));
        // a whole sample that clears the epoch's margin holds no crossing
        let epoch = self.clock / 64;
        let whole = matches!(start, Start::Value) && rem == self.step_h;
        if whole && self.cached[j].0 == epoch && psi_end.min(psi0) > self.cached[j].1 {
            return None;
        }
        self.take_norms(ph, j);
        if whole && self.cached[j].0 != epoch {
            self.cached[j] = (epoch, self.whole_margin(ph, j, &f));
        }
        let tol = self.tolerances(ph, j, &f, rem);
        let mut open = matches!(start, Start::Boundary);
        if !open && psi0.min(psi_end) - self.margin(ph, j, rem, f.g.abs()) > tol.0 {
            // both ends clear the chord's margin (section 6.2's
            // certificate, before any search)
            return None;
        }
        if !open {
            // a step that starts on the far side (or at 0 moving across):
            // the crossing is at its origin
            let d0 = f.dpsi(dot_at(&ph.ev_d[j], &self.s, &ph.evd_nz[j]), 0.0);
            if psi0 < 0.0 || (psi0 == 0.0 && d0 < 0.0) {
                return Some(0.0);
            }
            open = psi0 == 0.0;
        }
        if self.hermite && self.hermite_clears(ph, j, &f, rem, (psi0, psi_end), open) {
            self.stats.hermite_cleared += 1;
            return None;
        }
        let mut model = ContactModel {
            ph,
            tb: &self.tables[self.slot],
            j,
            s: &self.s,
            f,
            tol,
            stack: &mut self.stack,
            trig: &mut self.trig,
            simd: self.simd,
            evaluations: &mut self.stats.evaluations,
        };
        let mut tally = Tally::default();
        let found = search::first_root(&mut model, self.step_h, rem, open, &mut tally);
        self.stats.grazing += tally.grazing;
        self.stats.uncertified += tally.uncertified;
        match found {
            Found::At(t) => Some(t),
            Found::None => None,
        }
    }

    /// The one-contact engine's Hermite certificates (docs/numerics.md
    /// section 6.2) on contact `j`'s `psi` over the step's `(0, w]`, from
    /// its values `psi` at both ends (the state `s` and `end`), its slopes
    /// there and each block's `|s_k|` (`norms`). Every block is a
    /// contraction up to its growth, so `|d^n/dt^n psi_k| <= c_n,k |s_k|`
    /// over the step.
    ///
    /// - A step that starts with `psi > 0` (`open` false): the cubic
    ///   Hermite interpolant `H` of the two ends is bounded below by its
    ///   Bernstein coefficients; `|psi - H| <= sum_k min(c4_k w^4 / 384,
    ///   2 e_k + 8/27 w c1_k) |s_k|`. The least coefficient less that
    ///   and a rounding allowance above 0: no root.
    /// - The rest of a sample after this contact switched (`open`): `psi`
    ///   starts at 0 to rounding (or below it) and must not come down
    ///   through 0 in it: `psi >= psi_0 + u k` with `u = t / w` and `k`
    ///   the least of the quadratic `K`'s Bernstein coefficients (`w
    ///   psi'_0`, `1.5 psi_1 - 0.5 w psi'_1`, `psi_1`) less `M4 w^4 / 162`
    ///   and the allowance; below 0 at the start, `psi' >= psi'_0 - t M2`
    ///   keeps it rising until `u_1 = 2 |psi_0| / k`.
    ///
    /// The flights' parabolas are interpolated exactly (their fourth
    /// derivative is 0; their curvature `g` joins `M2`). `true`: the
    /// search would find no crossing there, and the step's end state
    /// stands as its "no root" leaves it. O(blocks the row touches), no
    /// transcendental function.
    fn hermite_clears(
        &self,
        ph: &MultiPhase,
        j: usize,
        f: &EventFn,
        w: f64,
        (psi0, psi1): (f64, f64),
        open: bool,
    ) -> bool {
        let tb = &self.tables[self.slot];
        let d0 = f.dpsi(dot_at(&ph.ev_d[j], &self.s, &ph.evd_nz[j]), 0.0);
        let d1 = f.dpsi(dot_at(&ph.ev_d[j], &self.end, &ph.evd_nz[j]), w);
        let (c1, c2, c4, e) = (&tb.ev_c1[j], &tb.ev_c2[j], &tb.ev_c4[j], &tb.ev_e[j]);
        let w4 = w * w * w * w;
        let tail = 8.0 / 27.0 * w;
        let (xs, vs, gs) = f.scale;
        let mut mag = ph.ev0[j].abs() + xs + vs * w + gs * w * w;
        let mut mag_d = vs + gs * w;
        let (mut rem, mut m4, mut m2) = (0.0, 0.0, f.g.abs());
        for &k in &ph.ev_blocks[j] {
            let n = self.norms[k];
            mag += e[k] * n;
            mag_d += c1[k] * n;
            rem += (c4[k] * w4 / 384.0).min(2.0 * e[k] + tail * c1[k]) * n;
            m4 += c4[k] * n;
            m2 += c2[k] * n;
        }
        // each sum of 2 per block plus a few terms rounds within that
        // many u of the magnitudes summed; the coefficients and the
        // comparison a few u more (the slopes enter times w)
        let units = (2 * ph.ev_blocks[j].len() + 16) as f64 * f64::EPSILON;
        let allowance = units * (mag + w * mag_d);
        let ends = [psi0, d0, psi1, d1];
        if !open {
            return hermite_low(ends, w) - rem * (1.0 + 1e-12) - allowance > 0.0;
        }
        hermite_rest_clears(ends, w, (m4, m2), (allowance, 2.0 * units * mag_d))
    }

    /// Contact `j`'s whole-sample margin for `epoch` from the current
    /// state ([`whole_margin`](Self::whole_margin)), kept for the epoch.
    pub(super) fn cache_margin(&mut self, sc: &CompiledMulti, j: usize, epoch: u64) {
        let ph = &sc.phases[self.slot];
        let f = self.event_fn(sc, j);
        self.take_norms(ph, j);
        self.cached[j] = (epoch, self.whole_margin(ph, j, &f));
    }

    /// The margin of a whole sample from the norms taken now, times the
    /// phase's growth over 64 samples: it holds for every later state of
    /// the clock's 64-sample epoch.
    fn whole_margin(&self, ph: &MultiPhase, j: usize, f: &EventFn) -> f64 {
        let later = self.tables[self.slot].growth_max.powi(64);
        self.margin(ph, j, self.step_h, f.g.abs()) * later
    }

    /// Each block's `|s_k|` at the step's origin into `norms`, for the
    /// blocks contact `j`'s rows touch (0 for the others, which weigh 0 in
    /// its bounds). O(blocks the row touches).
    fn take_norms(&mut self, ph: &MultiPhase, j: usize) {
        let nb = ph.gens.len();
        self.norms[..nb].fill(0.0);
        for &k in &ph.ev_blocks[j] {
            self.norms[k] = norm2(self.s[k], self.s[nb + k]);
        }
    }

    /// Contact `j`'s event function in the current phase: its sign and the
    /// flights of its free sides (the lower side's less the upper's).
    pub(super) fn event_fn(&self, sc: &CompiledMulti, j: usize) -> EventFn {
        let ph = &sc.phases[self.slot];
        let inside = self.mask & (1 << j) != 0;
        let g = sc.model.gravity_m_per_s2;
        let (lo, up) = ph.ev_fly[j];
        let flight =
            |slot: Option<usize>| slot.map_or((0.0, 0.0, 0.0), |k| (self.x_f[k], self.v_f[k], g));
        let ((xl, vl, gl), (xu, vu, gu)) = (flight(lo), flight(up));
        EventFn {
            sign: if inside { 1.0 } else { -1.0 },
            x0: xl - xu,
            v0: vl - vu,
            g: gl - gu,
            scale: (xl.abs() + xu.abs(), vl.abs() + vu.abs(), gl + gu),
        }
    }

    /// The rounding allowances of contact `j`'s `psi` and `psi'` over
    /// `rem` (`ROUND_UNITS` of `u` times the magnitudes summed into them:
    /// each block's share bound from its norm at the origin, taken by
    /// [`take_norms`](Self::take_norms), the constant, the flights'
    /// heights, speeds and travel). O(blocks the row touches).
    fn tolerances(&self, ph: &MultiPhase, j: usize, f: &EventFn, rem: f64) -> (f64, f64) {
        let tb = &self.tables[self.slot];
        let (xs, vs, gs) = f.scale;
        let mut mag = ph.ev0[j].abs() + xs + vs * rem + gs * rem * rem;
        let mut mag_d = vs + gs * rem;
        for &k in &ph.ev_blocks[j] {
            mag += tb.ev_e[j][k] * self.norms[k];
            mag_d += tb.ev_c1[j][k] * self.norms[k];
        }
        let units = ROUND_UNITS * f64::EPSILON;
        (units * mag, units * mag_d)
    }

    /// How far contact `j`'s event function may stray from the chord over
    /// a piece of width `w` from the step's origin: per block the smaller
    /// of its curvature's share `c_k |s_k| w^2 / 8` and `2 e_k |s_k|` (its
    /// share of the function and of the chord both stay within `e_k
    /// |s_k|`), plus the falling sides' exact `g w^2 / 8`; the one-contact
    /// engine's margin (docs/numerics.md section 6.2), with `|s_k|` at the
    /// origin (`norms`): every block is a contraction up to its growth
    /// factor, so it bounds the piece.
    fn margin(&self, ph: &MultiPhase, j: usize, w: f64, g_curv: f64) -> f64 {
        let h = w * w / 8.0;
        let mut acc = g_curv * h;
        let tb = &self.tables[self.slot];
        let (c2, e) = (&tb.ev_c2[j], &tb.ev_e[j]);
        for k in 0..ph.gens.len() {
            acc += (c2[k] * h).min(2.0 * e[k]) * self.norms[k];
        }
        acc * (1.0 + 1e-12)
    }
}
