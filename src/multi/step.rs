//! One sample of the several-contact engine: the certified search for
//! each contact's first crossing in the step and the switch through the
//! physical state (docs/numerics.md section 14).

use super::*;

impl MultiState {
    /// Advance one sample: with exact switching, switching wherever a
    /// contact crosses; with the offset rod, in the phase its decision at
    /// the sample's start chose ([`decide`](Self::decide)).
    pub fn step(&mut self, sc: &CompiledMulti) {
        if sc.switching == Switching::OffsetRod {
            self.decide(sc);
            self.step_rod(sc);
            return;
        }
        let h = self.step_h;
        let mut t = 0.0;
        let mut starts = [Start::Value; MAX_CONTACTS];
        let mut taken: u64 = 0;
        while t < h {
            let ph = &sc.phases[self.mask as usize];
            let rem = h - t;
            let nb = ph.gens.len();
            if t == 0.0 {
                let props = &self.tables[self.mask as usize].props;
                step_blocks(props, &self.s, &mut self.end[..ph.dim], nb);
            } else {
                step_to(ph, rem, &self.s, &mut self.end[..ph.dim]);
            }
            if taken >= MAX_SWITCHES_PER_SAMPLE {
                self.stats.capped += 1;
                self.s.copy_from_slice(&self.end[..ph.dim]);
                self.fly(sc, rem);
                break;
            }
            // the first crossing of any contact, and every contact that
            // crosses then
            let mut first: Option<f64> = None;
            let mut who = 0u32;
            for j in 0..sc.contacts() {
                let Some(tj) = self.first_crossing(sc, j, rem, starts[j]) else {
                    continue;
                };
                let tol = LEAF * h * 4.0;
                match first {
                    Some(f) if tj > f + tol => {}
                    Some(f) if tj >= f - tol => who |= 1 << j,
                    _ => {
                        first = Some(tj);
                        who = 1 << j;
                    }
                }
            }
            let Some(tau) = first else {
                self.s.copy_from_slice(&self.end[..ph.dim]);
                self.fly(sc, rem);
                break;
            };
            let tau = tau.min(rem);
            if tau < rem {
                step_to(ph, tau, &self.s, &mut self.end[..ph.dim]);
            }
            self.s.copy_from_slice(&self.end[..ph.dim]);
            self.fly(sc, tau);
            t = if tau < rem { t + tau } else { h };
            starts = self.switch(sc, who, self.clock as f64 * h + t, &[0.0; MAX_CONTACTS]);
            taken += 1;
        }
        self.clock += 1;
    }

    /// One whole sample in the current phase with its rods (the state is
    /// held about the equilibrium they shift). O(dim).
    fn step_rod(&mut self, sc: &CompiledMulti) {
        let m = self.mask as usize;
        let ph = &sc.phases[m];
        let dim = ph.dim;
        let props = &self.tables[m].props;
        step_blocks(props, &self.s, &mut self.end[..dim], ph.gens.len());
        self.s.copy_from_slice(&self.end[..dim]);
        self.fly(sc, self.step_h);
        self.clock += 1;
    }

    /// The current phase's equilibrium shift of the rods, and the rows'
    /// constants it makes. O(K dim).
    pub(super) fn set_shift(&mut self, sc: &CompiledMulti) {
        let ph = &sc.phases[self.mask as usize];
        let shift = &mut self.shift[..ph.dim];
        shift.fill(0.0);
        self.rods_on = false;
        for (pos, &c) in ph.members.iter().enumerate() {
            let d = self.rod[c];
            if d != 0.0 {
                self.rods_on = true;
                for (x, r) in shift.iter_mut().zip(&ph.rod_s[pos]) {
                    *x += d * r;
                }
            }
        }
        if !self.rods_on {
            // exact switching, or no rod: nothing to add (and no products)
            self.off_ev = [0.0; MAX_CONTACTS];
            self.off_sides = [[(0.0, 0.0); 2]; MAX_CONTACTS];
            self.off_out = [0.0; 2];
            return;
        }
        let shift = &self.shift[..ph.dim];
        for j in 0..sc.contacts() {
            self.off_ev[j] = dot(&ph.ev[j], shift);
            for (o, r) in self.off_sides[j].iter_mut().zip(&ph.sides[j]) {
                *o = (dot(&r.pos, shift), dot(&r.vel, shift));
            }
        }
        let tb = &self.tables[self.mask as usize];
        for (o, row) in self.off_out.iter_mut().zip(&tb.out) {
            *o = dot(&row[..ph.dim], shift);
        }
    }

    /// With rods, `s` from the shifted equilibrium to the phase's own
    /// (`sign` 1) and back (-1): the form a switch's products take.
    fn unshift(&mut self, sign: f64) {
        if self.rods_on {
            let dim = self.s.len();
            for (x, d) in self.s.iter_mut().zip(&self.shift[..dim]) {
                *x += sign * d;
            }
        }
    }

    /// The flights (free masses, centres of free groups) go `dt` on.
    fn fly(&mut self, sc: &CompiledMulti, dt: f64) {
        let g = sc.model.gravity_m_per_s2;
        for &j in &sc.phases[self.mask as usize].flyers {
            self.x_f[j] += self.v_f[j] * dt - 0.5 * g * dt * dt;
            self.v_f[j] -= g * dt;
        }
    }

    /// Contact `j`'s event function over `[0, rem]` of the current phase
    /// from the state `s` (its end state in `end`): its first crossing, if
    /// any (docs: the module's).
    fn first_crossing(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        rem: f64,
        start: Start,
    ) -> Option<f64> {
        let ph = &sc.phases[self.mask as usize];
        let nb = ph.gens.len();
        let inside = self.mask & (1 << j) != 0;
        let g = sc.model.gravity_m_per_s2;
        // the flights in the penetration: the lower side's less the upper's
        let (lo, up) = ph.ev_fly[j];
        let flight =
            |slot: Option<usize>| slot.map_or((0.0, 0.0, 0.0), |k| (self.x_f[k], self.v_f[k], g));
        let ((xl, vl, gl), (xu, vu, gu)) = (flight(lo), flight(up));
        let mut f = EventFn {
            sign: if inside { 1.0 } else { -1.0 },
            x0: xl - xu,
            v0: vl - vu,
            g: gl - gu,
            allow: 0.0,
            neutral: 0.0,
        };
        let (row, nz) = (&ph.ev[j], &ph.ev_nz[j]);
        let q0 = dot_at(row, &self.s, nz) + ph.ev0[j];
        let q_end = dot_at(row, &self.end, nz) + ph.ev0[j];
        let psi_end = f.psi(q_end, rem);
        // a whole sample that clears the epoch's margin holds no crossing
        let epoch = self.clock / 64;
        let whole = matches!(start, Start::Value) && rem == self.step_h;
        if whole && self.cached[j].0 == epoch {
            let p0 = f.psi(q0, 0.0);
            if psi_end.min(p0) > self.cached[j].1 {
                return None;
            }
        }
        let d0 = f.dpsi(dot_at(&ph.ev_d[j], &self.s, &ph.evd_nz[j]), 0.0);
        let mut mag = ph.ev0[j].abs();
        let ev_e = &self.tables[self.mask as usize].ev_e[j];
        // the blocks the rows touch (the others weigh 0 in every bound)
        self.norms[0][..nb].fill(0.0);
        for &k in &ph.ev_blocks[j] {
            self.norms[0][k] = (self.s[k] * self.s[k] + self.s[nb + k] * self.s[nb + k]).sqrt();
            mag += ev_e[k] * self.norms[0][k];
        }
        mag += xl.abs() + xu.abs() + (vl.abs() + vu.abs()) * rem + (gl + gu) * rem * rem;
        f.neutral = 4.0 * f64::EPSILON / 2.0 * mag;
        // only for a contact that just left: its flight starts at 0 and a
        // rounding-level value of the wrong sign is no new contact
        if matches!(start, Start::Boundary) && !inside {
            f.allow = f.neutral;
        }
        self.budget = SEARCH_BUDGET;
        let g_curv = f.g.abs();
        let m = self.curvature(ph, j, g_curv, 0);
        if whole && self.cached[j].0 != epoch {
            // for the rest of the epoch: at most 64 samples of growth
            let later = self.tables[self.mask as usize].growth_max.powi(64);
            self.cached[j] = (epoch, self.margin(ph, j, rem, g_curv, 0) * later);
        }
        let (a, psi_a, da) = match start {
            Start::Value => (0.0, f.psi(q0, 0.0), d0),
            // a contact that just switched, moving back towards the side it
            // left (a touch at rounding level): from 0, searched as any
            // piece, crossing back only where psi is across beyond rounding
            Start::Boundary if !(d0 > 0.0) => (0.0, 0.0, d0),
            Start::Boundary => {
                // psi >= d0 t - m t^2 / 2 > 0 on (0, 2 d0 / m)
                let clear = if m > 0.0 { 2.0 * d0 / m } else { f64::INFINITY };
                if clear >= rem {
                    if f.crossed(psi_end) {
                        self.stats.uncertified += 1;
                    }
                    return None;
                }
                let a = clear * (1.0 - 1e-9);
                let (q, dq) = self.eval(ph, j, a, Some(1));
                (a, f.psi(q, a), f.dpsi(dq, a))
            }
        };
        if f.crossed(psi_a) {
            return Some(a);
        }
        let slot = if a > 0.0 { 1 } else { 0 };
        let piece = Piece {
            g_curv,
            left: slot,
            free: slot + 1,
        };
        self.search(sc, j, &f, (a, psi_a, da), (rem, psi_end), piece)
    }

    /// How far contact `j`'s event function may stray from the chord over
    /// a piece of width `w` of the current step: per block the smaller of
    /// its curvature's share `c_k |s_k| w^2 / 8` and `2 e_k |s_k|` (its
    /// share of the function and of the chord both stay within `e_k
    /// |s_k|`), plus the falling hammer's exact `g w^2 / 8`; the one-contact
    /// engine's margin (docs/numerics.md section 6.2), with `|s_k|` taken at
    /// the piece's left end (in slot `slot`): every block is a contraction
    /// (up to its growth factor), so it bounds the piece.
    fn margin(&self, ph: &MultiPhase, j: usize, w: f64, g_curv: f64, slot: usize) -> f64 {
        let h = w * w / 8.0;
        let mut acc = g_curv * h;
        let norms = &self.norms[slot];
        let tb = &self.tables[self.mask as usize];
        let (c2, e) = (&tb.ev_c2[j], &tb.ev_e[j]);
        for k in 0..ph.gens.len() {
            acc += (c2[k] * h).min(2.0 * e[k]) * norms[k];
        }
        acc * (1.0 + 1e-12)
    }

    /// A bound on `|psi''|` over a piece from the norms at its left end (in
    /// slot `slot`): `sum_k c_k |s_k| + g`.
    fn curvature(&self, ph: &MultiPhase, j: usize, g_curv: f64, slot: usize) -> f64 {
        let norms = &self.norms[slot];
        let c2 = &self.tables[self.mask as usize].ev_c2[j];
        let mut m = g_curv;
        for k in 0..ph.gens.len() {
            m += c2[k] * norms[k];
        }
        m * (1.0 + 1e-12)
    }

    /// The event quantity of contact `j` and its slope at `t` into the
    /// current step, and each block's `|s_k(t)|` into slot `slot`.
    fn eval(&mut self, ph: &MultiPhase, j: usize, t: f64, slot: Option<usize>) -> (f64, f64) {
        self.stats.evaluations += 1;
        let nb = ph.gens.len();
        if let Some(slot) = slot {
            while self.norms.len() <= slot {
                self.norms.push(Vec::new());
            }
            self.norms[slot].resize(nb, 0.0);
        }
        let (row, row_d) = (&ph.ev[j], &ph.ev_d[j]);
        let (mut q, mut dq) = (ph.ev0[j], 0.0);
        // only the blocks the rows touch: the others add 0 here and weigh
        // 0 in the bounds (their norms set to 0)
        if let Some(slot) = slot {
            self.norms[slot].fill(0.0);
        }
        for &k in &ph.ev_blocks[j] {
            let p = ph.exp_block(k, t);
            let (x0, x1) = mul2(&p, self.s[k], self.s[nb + k]);
            if let Some(slot) = slot {
                self.norms[slot][k] = (x0 * x0 + x1 * x1).sqrt();
            }
            q += row[k] * x0 + row[nb + k] * x1;
            dq += row_d[k] * x0 + row_d[nb + k] * x1;
        }
        (q, dq)
    }

    /// The first crossing in `(a, b]` (none before `a`; `da` the slope at
    /// `a`), halving left first; a piece that crosses and on which `psi`
    /// certainly falls all the way (`psi'(a) + M (b - a) < 0`) holds one
    /// crossing, found by [`refine`](Self::refine).
    fn search(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        f: &EventFn,
        (a, pa, da): (f64, f64, f64),
        (b, pb): (f64, f64),
        piece: Piece,
    ) -> Option<f64> {
        let w = b - a;
        let ph = &sc.phases[self.mask as usize];
        if !f.crossed(pb)
            && pa.min(pb) - self.margin(ph, j, w, piece.g_curv, piece.left) > -f.neutral
        {
            return None;
        }
        if f.crossed(pb) && da + self.curvature(ph, j, piece.g_curv, piece.left) * w < 0.0 {
            return Some(self.refine(sc, j, f, (a, pa), (b, pb)));
        }
        let mid = a + 0.5 * w;
        if w <= LEAF * self.step_h || mid <= a || mid >= b {
            if f.crossed(pb) {
                return Some(b);
            }
            self.stats.grazing += 1;
            return None;
        }
        if self.budget == 0 {
            // a piece left undecided (counted; never on the tests' cases
            // but the dwelling ones, docs/numerics.md section 14)
            if f.crossed(pb) {
                return Some(b);
            }
            self.stats.uncertified += 1;
            return None;
        }
        self.budget -= 1;
        // the midpoint's norms in `free`: the left half keeps `left` and
        // stacks above `free`, the right half starts from `free`
        let (q, dq) = self.eval(ph, j, mid, Some(piece.free));
        let (pm, dm) = (f.psi(q, mid), f.dpsi(dq, mid));
        let left_half = Piece {
            free: piece.free + 1,
            ..piece
        };
        if let Some(t) = self.search(sc, j, f, (a, pa, da), (mid, pm), left_half) {
            return Some(t);
        }
        let right_half = Piece {
            left: piece.free,
            free: piece.free + 1,
            ..piece
        };
        self.search(sc, j, f, (mid, pm, dm), (b, pb), right_half)
    }

    /// The one crossing of a piece on which `psi` falls all the way,
    /// `psi(a)` on this side and `psi(b)` across: regula falsi with the
    /// Illinois halving, a halving step whenever the bracket shrinks by
    /// less than half, until it is a leaf wide; its right end.
    fn refine(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        f: &EventFn,
        (mut a, mut pa): (f64, f64),
        (mut b, mut pb): (f64, f64),
    ) -> f64 {
        let ph = &sc.phases[self.mask as usize];
        let mut side = 0i8;
        let mut bisect = false;
        // no point nearer an end than half a leaf: a secant that lands on
        // the root from this side is followed by one just across it
        let tol = 0.5 * LEAF * self.step_h;
        while b - a > LEAF * self.step_h {
            let w = b - a;
            let t = if bisect {
                a + 0.5 * w
            } else {
                let t = a + pa / (pa - pb) * w;
                if t.is_finite() {
                    t.clamp(a + tol, b - tol)
                } else {
                    a + 0.5 * w
                }
            };
            if t <= a || t >= b {
                break;
            }
            let (q, _) = self.eval(ph, j, t, None);
            let pt = f.psi(q, t);
            if f.crossed(pt) {
                b = t;
                pb = pt;
                if side == 1 {
                    pa *= 0.5;
                }
                side = 1;
            } else {
                a = t;
                pa = pt;
                if side == -1 {
                    pb *= 0.5;
                }
                side = -1;
            }
            bisect = b - a > 0.5 * w;
        }
        b
    }

    /// Switch the contacts of `who` at the state's time `time_s`: each
    /// enters or leaves, through the physical state (which does not jump),
    /// two changes of basis, O(dim^2). Returns where each contact's next
    /// search starts.
    /// Contacts `who` change side at `time_s`; an entering contact `j`
    /// starts at the penetration `enter[j]` (0 at an exact crossing; with
    /// the offset rod, its rod), a leaving one's rod goes.
    pub(super) fn switch(
        &mut self,
        sc: &CompiledMulti,
        who: u32,
        time_s: f64,
        enter: &[f64; MAX_CONTACTS],
    ) -> [Start; MAX_CONTACTS] {
        let m = &sc.model;
        let old = &sc.phases[self.mask as usize];
        self.unshift(1.0);
        // every q, q', x, v
        old.physical_of(
            m,
            &self.s,
            (&self.x_f, &self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.phys,
        );
        // each closed contact's penetration from its own coordinate
        // (exact); an entering one starts unstretched (its crossing, 0 to
        // the search's leaf), so entering adds nothing
        let mut pen = *enter;
        for (j, p) in pen.iter_mut().enumerate().take(sc.contacts()) {
            if self.mask & (1 << j) != 0 {
                *p = dot(&old.ev[j], &self.s) + old.ev0[j];
            }
        }
        let p_left = pen;
        let new_mask = self.mask ^ who;
        let new = &sc.phases[new_mask as usize];
        self.tables[new_mask as usize].make(new, m, self.scale, self.step_h, self.band_hz);
        self.s.resize(new.dim, 0.0);
        new.state_of(
            m,
            (&self.phys, &pen),
            (&mut self.x_f, &mut self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.s,
        );
        // a mass a leaving contact sets free starts its flight exactly at the
        // penetration the contact left with, the rest of it as the new
        // phase computes it (its row), without the change of basis's
        // rounding between the two bases' views of the other side
        let mut placed = 0u64;
        for j in 0..sc.contacts() {
            if who & (1 << j) == 0 || new_mask & (1 << j) != 0 {
                continue;
            }
            let ct = &m.contacts[j];
            let freed = |e: &MultiEnd| match e {
                MultiEnd::Mass(k)
                    if new.place[*k].is_none()
                        && old.place[*k].is_some()
                        && placed & (1 << k) == 0 =>
                {
                    Some(*k)
                }
                _ => None,
            };
            let q = dot(&new.ev[j], &self.s) + new.ev0[j];
            let (lo, up) = new.ev_fly[j];
            let at = |slot: Option<usize>, x: &[f64]| slot.map_or(0.0, |k| x[k]);
            // p = q + x_lower - x_upper (flights only)
            if let Some(k) = freed(&ct.upper) {
                let x_lo = if lo == Some(k) {
                    0.0
                } else {
                    at(lo, &self.x_f)
                };
                self.x_f[k] = q + x_lo - p_left[j];
                placed |= 1 << k;
            } else if let Some(k) = freed(&ct.lower) {
                let x_up = if up == Some(k) {
                    0.0
                } else {
                    at(up, &self.x_f)
                };
                self.x_f[k] = p_left[j] - q + x_up;
                placed |= 1 << k;
            }
        }
        for j in 0..sc.contacts() {
            if who & (1 << j) != 0 {
                let entered = new_mask & (1 << j) != 0;
                self.rod[j] = if entered { enter[j] } else { 0.0 };
                if entered {
                    self.stats.contacts_started[j] += 1;
                }
                if self.record {
                    self.switches.push(MultiSwitch {
                        contact: j,
                        entered,
                        time_s,
                    });
                }
            }
        }
        self.mask = new_mask;
        self.set_shift(sc);
        self.unshift(-1.0);
        self.cached = [(u64::MAX, 0.0); MAX_CONTACTS];
        self.stats.switches += 1;
        std::array::from_fn(|j| {
            if who & (1 << j) != 0 {
                Start::Boundary
            } else {
                Start::Value
            }
        })
    }
}
