//! One sample of the several-contact engine: each contact's first crossing
//! in the step (`multi/search.rs`), the earliest taken, and the switch
//! through the physical state (docs/numerics.md section 14).

use super::*;
use crate::engine::ROOT_ULPS;

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
        let mut starts = [Start::Value; MAX_SPRINGS];
        let mut taken: u64 = 0;
        while t < h {
            let ph = &sc.phases[self.slot];
            let rem = h - t;
            let nb = ph.gens.len();
            if t == 0.0 {
                let props = &self.tables[self.slot].props;
                step_blocks(self.simd, props, &self.s, &mut self.end[..ph.dim], nb);
            } else {
                step_to(
                    ph,
                    (self.simd, &mut self.trig),
                    rem,
                    &self.s,
                    &mut self.end[..ph.dim],
                );
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
                if self.shadows && ph.shadow[j].is_some() {
                    // a stage in flight behind its open stage below: it
                    // cannot cross first (MultiPhase::shadow)
                    self.stats.shadowed += 1;
                    continue;
                }
                let Some(tj) = self.first_crossing(sc, j, rem, starts[j]) else {
                    continue;
                };
                // crossings within the search's resolution are one instant
                let tol = ROOT_ULPS * f64::EPSILON * h;
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
                step_to(
                    ph,
                    (self.simd, &mut self.trig),
                    tau,
                    &self.s,
                    &mut self.end[..ph.dim],
                );
            }
            self.s.copy_from_slice(&self.end[..ph.dim]);
            self.fly(sc, tau);
            t = if tau < rem { t + tau } else { h };
            starts = self.switch(sc, who, self.clock as f64 * h + t, &[0.0; MAX_SPRINGS]);
            taken += 1;
        }
        self.clock += 1;
    }

    /// One whole sample in the current phase with its rods (the state is
    /// held about the equilibrium they shift). O(dim).
    fn step_rod(&mut self, sc: &CompiledMulti) {
        let m = self.slot;
        let ph = &sc.phases[m];
        let dim = ph.dim;
        let props = &self.tables[m].props;
        step_blocks(
            self.simd,
            props,
            &self.s,
            &mut self.end[..dim],
            ph.gens.len(),
        );
        self.s.copy_from_slice(&self.end[..dim]);
        self.fly(sc, self.step_h);
        self.clock += 1;
    }

    /// The current phase's equilibrium shift of the rods, and the rows'
    /// constants it makes. O(K dim).
    pub(super) fn set_shift(&mut self, sc: &CompiledMulti) {
        let ph = &sc.phases[self.slot];
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
            self.off_ev = [0.0; MAX_SPRINGS];
            self.off_sides = [[(0.0, 0.0); 2]; MAX_SPRINGS];
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
        let tb = &self.tables[self.slot];
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

    /// `who` as [`CompiledMulti::staged`] takes it from the current mask,
    /// counted in [`MultiStats::staged`] when it changed.
    fn staged(&mut self, sc: &CompiledMulti, who: u32) -> u32 {
        let staged = sc.staged(self.mask, who);
        if staged != who {
            self.stats.staged += 1;
        }
        staged
    }

    /// The flights (free masses, centres of free groups) go `dt` on.
    pub(super) fn fly(&mut self, sc: &CompiledMulti, dt: f64) {
        let g = sc.model.gravity_m_per_s2;
        for &j in &sc.phases[self.slot].flyers {
            self.x_f[j] += self.v_f[j] * dt - 0.5 * g * dt * dt;
            self.v_f[j] -= g * dt;
        }
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
        enter: &[f64; MAX_SPRINGS],
    ) -> [Start; MAX_SPRINGS] {
        let who = self.staged(sc, who);
        let m = &sc.model;
        let old = &sc.phases[self.slot];
        self.unshift(1.0);
        // every q, q', x, v
        old.physical_of(
            m,
            &self.s,
            (&self.x_f, &self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.phys,
            Some((&mut self.sw, self.simd)),
        );
        // each closed contact's penetration from its own coordinate
        // (exact); an entering one starts unstretched (its crossing, 0 to
        // the search's resolution), so entering adds nothing
        let mut pen = *enter;
        for (j, p) in pen.iter_mut().enumerate().take(sc.contacts()) {
            if self.mask & (1 << j) != 0 {
                *p = dot(&old.ev[j], &self.s) + old.ev0[j];
            }
        }
        let p_left = pen;
        let new_mask = self.mask ^ who;
        let new_slot = sc.slot(new_mask);
        let new = &sc.phases[new_slot];
        self.tables[new_slot].make(new, m, self.scale, self.step_h, self.band_hz);
        self.s.resize(new.dim, 0.0);
        new.state_of(
            m,
            (&self.phys, &pen),
            (&mut self.x_f, &mut self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.s,
            Some((&mut self.sw, self.simd)),
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
        self.slot = new_slot;
        self.set_shift(sc);
        self.unshift(-1.0);
        self.cached = [(u64::MAX, 0.0); MAX_SPRINGS];
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
