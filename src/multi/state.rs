//! The several-contact state: a new state, a rest, a state carried to a
//! recompile, a strike, the time scale, the output band and the offset
//! rod's decision ([`MultiState`]).

use super::*;

impl MultiState {
    /// The model's initial state: the objects at rest, the masses in
    /// flight where the model puts them.
    pub fn new(sc: &CompiledMulti) -> Self {
        let dim = sc.max_dim();
        let nz = sc.model.n() + sc.model.masses.len();
        let x_f = sc.model.masses.iter().map(|m| m.height_m).collect();
        let v_f = sc.model.masses.iter().map(|m| m.velocity_m_per_s).collect();
        // every phase's tables at scale 1 up front: a state that keeps its
        // scale never makes them on the way (a switch pays nothing more)
        let mut tables: Vec<PhaseTables> = sc.phases.iter().map(PhaseTables::new).collect();
        for (t, ph) in tables.iter_mut().zip(&sc.phases) {
            t.make(ph, &sc.model, 1.0, sc.h, f64::INFINITY);
        }
        Self {
            mask: 0,
            slot: 0,
            scale: 1.0,
            step_h: sc.h,
            tables,
            s: {
                let mut s = Vec::with_capacity(dim);
                s.resize(sc.phases[0].dim, 0.0);
                s
            },
            end: vec![0.0; dim],
            norms: vec![0.0; dim / 2],
            x_f,
            v_f,
            zq: vec![0.0; nz + MAX_SPRINGS],
            zv: vec![0.0; nz],
            phys: Physical::new(&sc.model),
            sw: Box::new(SwitchScratch::new(&sc.model, &sc.phases)),
            cached: [(u64::MAX, 0.0); MAX_SPRINGS],
            stack: [(0.0, 0.0); STACK],
            trig: Trig::new(dim / 2),
            simd: SimdPath::detect(),
            kern: Box::new(fast::Kern::new(dim)),
            block_path: true,
            hermite: true,
            shadows: true,
            implied: 0,
            spec_len: crate::engine::kernel::EPOCH,
            rod: [0.0; MAX_SPRINGS],
            shift: vec![0.0; dim],
            rods_on: false,
            off_ev: [0.0; MAX_SPRINGS],
            off_sides: [[(0.0, 0.0); 2]; MAX_SPRINGS],
            off_out: [0.0; 2],
            band_hz: f64::INFINITY,
            decided: u64::MAX,
            clock: 0,
            stats: MultiStats::default(),
            switches: Vec::new(),
            record: false,
        }
    }

    /// Back to rest, as an instrument's kit wakes (docs/design.md, "Played
    /// as a kit"): every object still, every mass at its model height
    /// and still, no contact closed. The clock runs on. Allocation-free.
    /// \[audio-thread\]
    pub fn rest(&mut self, sc: &CompiledMulti) {
        self.mask = 0;
        self.slot = 0;
        self.tables[0].make(
            &sc.phases[0],
            &sc.model,
            self.scale,
            self.step_h,
            self.band_hz,
        );
        self.s.clear();
        self.s.resize(sc.phases[0].dim, 0.0);
        for (j, m) in sc.model.masses.iter().enumerate() {
            self.x_f[j] = m.height_m;
            self.v_f[j] = 0.0;
        }
        self.cached = [(u64::MAX, 0.0); MAX_SPRINGS];
        self.rod = [0.0; MAX_SPRINGS];
        self.set_shift(sc);
        self.decided = u64::MAX;
    }

    /// Carry the state from `from` to `to`, another compile of the same
    /// bodies (the same modes' frequencies, masses and contacts; other
    /// stiffnesses, dampings or decays: a parameter change): only while no
    /// contact is closed, through the physical state, which does not
    /// change, so neither does the energy (the objects', the masses' and
    /// gravity's; no spring is stretched). False (nothing changed) when a
    /// contact is closed or the bodies differ. The state must have been
    /// made for a compile with phases as large as `to`'s
    /// ([`MultiState::new`] of either, when both have the same layout).
    /// O(dim^2), allocation-free. \[audio-thread\]
    pub fn carry(&mut self, from: &CompiledMulti, to: &CompiledMulti) -> bool {
        let (a, b) = (&from.model, &to.model);
        let same = a.freq_hz == b.freq_hz
            && a.masses.len() == b.masses.len()
            && a.contacts.len() == b.contacts.len()
            && self.s.capacity() >= to.max_dim()
            && self.tables.len() == to.phases.len()
            && self
                .tables
                .iter()
                .zip(&to.phases)
                .all(|(t, p)| t.props.len() == p.gens.len() && t.out[0].len() == p.dim)
            && self.mask == 0;
        if !same {
            return false;
        }
        from.phases[0].physical_of(
            a,
            &self.s,
            (&self.x_f, &self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.phys,
            None,
        );
        let new = &to.phases[0];
        self.s.resize(new.dim, 0.0);
        new.state_of(
            b,
            (&self.phys, &[0.0; MAX_SPRINGS]),
            (&mut self.x_f, &mut self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.s,
            None,
        );
        // the tables were the old compile's
        self.forget_tables();
        self.tables[0].make(new, b, self.scale, self.step_h, self.band_hz);
        true
    }

    /// Forget every phase's tables: the state is to run on another compile
    /// of the same layout from a rest ([`rest`](Self::rest)) or a new time
    /// scale ([`set_time_scale`](Self::set_time_scale)), which make the
    /// current phase's tables; the others are made when entered, as after a
    /// [`carry`](Self::carry). O(phases), allocation-free. \[audio-thread\]
    pub fn forget_tables(&mut self) {
        for t in &mut self.tables {
            t.at = f64::NAN;
        }
        self.cached = [(u64::MAX, 0.0); MAX_SPRINGS];
    }

    /// A strike between two samples: the mass on the upper side of
    /// contact `c` is thrown from `height_m` above that contact's lower
    /// side (where it is now), or from as high as the sides above it let
    /// it be, at `velocity_m_per_s` (positive up). Its closed contacts
    /// open first, through the physical state as a switch does (their
    /// springs' energy leaves, nothing is added); its other contacts stay
    /// open where it is put (above every side it rests on, below every
    /// side above it); where no such place exists the strike is refused
    /// and nothing changes: `Err(StrikeRefused::Wedged)` (a ball pressed
    /// between two plates). O(dim) to place, O(dim^2) when a contact
    /// opens. Allocation-free. \[audio-thread\]
    pub fn strike(
        &mut self,
        sc: &CompiledMulti,
        c: usize,
        height_m: f64,
        velocity_m_per_s: f64,
    ) -> Result<(), StrikeRefused> {
        let m = &sc.model;
        let Some(MultiEnd::Mass(k)) = m.contacts.get(c).map(|ct| &ct.upper) else {
            return Err(StrikeRefused::NotAMass);
        };
        let k = *k;
        if !(height_m >= 0.0 && height_m.is_finite() && velocity_m_per_s.is_finite()) {
            return Err(StrikeRefused::NotFinite);
        }
        // the bounds its contacts put on its height, from the other sides
        // where they are now (a switch does not move them)
        let ph = &sc.phases[self.slot];
        let (mut lo, mut hi, mut want) = (f64::NEG_INFINITY, f64::INFINITY, 0.0);
        let mut who = 0u32;
        for (j, ct) in m.contacts.iter().enumerate() {
            if ct.upper == MultiEnd::Mass(k) {
                let (x, _) = self.side_at(ph, j, 0);
                lo = lo.max(x - ct.gap_m);
                if j == c {
                    want = x + height_m;
                }
            } else if ct.lower == MultiEnd::Mass(k) {
                hi = hi.min(self.side_at(ph, j, 1).0 + ct.gap_m);
            } else {
                continue;
            }
            who |= 1 << j;
        }
        if !(lo <= hi) {
            return Err(StrikeRefused::Wedged);
        }
        // as high as asked, or as the sides above it let it be
        let x = want.max(lo).min(hi);
        let closed = who & self.mask;
        if closed != 0 {
            let time_s = self.clock as f64 * self.step_h;
            self.switch(sc, closed, time_s, &[0.0; MAX_SPRINGS]);
        }
        // every contact of the mass is open: it flies alone, in its slot
        debug_assert!(sc.phases[self.slot].place[k].is_none());
        self.x_f[k] = x;
        self.v_f[k] = velocity_m_per_s;
        self.cached = [(u64::MAX, 0.0); MAX_SPRINGS];
        Ok(())
    }

    /// The kinetic energy \[J\] of the masses that may still land: each
    /// one in a closed contact, falling under gravity, or closing on a
    /// side of one of its open contacts (its penetration rising). A mass
    /// that flies away from everything in a scene without gravity does
    /// not count: it never comes back (the instrument's silence test).
    /// O(masses dim).
    pub fn masses_to_land(&self, sc: &CompiledMulti) -> f64 {
        let m = &sc.model;
        let ph = &sc.phases[self.slot];
        let mut e = 0.0;
        for (k, ms) in m.masses.iter().enumerate() {
            let v = self.mass_at(sc, k).1;
            let lands = m.gravity_m_per_s2 > 0.0
                || m.contacts.iter().enumerate().any(|(j, ct)| {
                    if self.mask & (1 << j) != 0 {
                        ct.lower == MultiEnd::Mass(k) || ct.upper == MultiEnd::Mass(k)
                    } else if ct.upper == MultiEnd::Mass(k) {
                        self.side_at(ph, j, 0).1 > v
                    } else if ct.lower == MultiEnd::Mass(k) {
                        v > self.side_at(ph, j, 1).1
                    } else {
                        false
                    }
                });
            if lands {
                e += 0.5 * ms.mass_kg * v * v;
            }
        }
        e
    }

    /// Contact `j`'s lower (`which` 0) or upper side's position and
    /// velocity in the current phase `ph` (its rows, the rods' constants
    /// and its flight).
    pub(super) fn side_at(&self, ph: &MultiPhase, j: usize, which: usize) -> (f64, f64) {
        let r = &ph.sides[j][which];
        let (ox, ov) = self.off_sides[j][which];
        let (fx, fv) = r.fly.map_or((0.0, 0.0), |k| (self.x_f[k], self.v_f[k]));
        (
            dot(&r.pos, &self.s) + r.pos0 + ox + fx,
            dot(&r.vel, &self.s) + r.vel0 + ov + fv,
        )
    }

    /// Entry `c` of the block state about the phase's own equilibrium
    /// (with rods, `s + shift`).
    pub(super) fn s_own(&self, c: usize) -> f64 {
        if self.rods_on {
            self.s[c] + self.shift[c]
        } else {
            self.s[c]
        }
    }

    /// Mass `j`'s height and velocity: its flight when free, else its
    /// coordinate's rows (plus its group's flight).
    pub(super) fn mass_at(&self, sc: &CompiledMulti, j: usize) -> (f64, f64) {
        let ph = &sc.phases[self.slot];
        let Some(b) = ph.place[j] else {
            return (self.x_f[j], self.v_f[j]);
        };
        let n = sc.model.n();
        let sq = sc.model.masses[j].mass_kg.sqrt();
        let row = |a: &DMatrix<f64>, r: usize| -> f64 {
            ph.coupled.iter().map(|&c| a[(r, c)] * self.s_own(c)).sum()
        };
        let (mut x, mut v) = (
            (row(&ph.zv, b) + ph.zv0[b]) / sq,
            (row(&ph.pv, n + b) + ph.pv0[n + b]) / sq,
        );
        if let Some(k) = ph.fly_of[j] {
            x += self.x_f[k];
            v += self.v_f[k];
        }
        (x, v)
    }

    /// Keep every switch in [`switches`](Self::switches) (tests).
    pub fn record(&mut self, on: bool) {
        self.record = on;
    }

    /// The contacts in contact (bit `j`).
    pub fn active(&self) -> u32 {
        self.mask
    }

    /// One sample: the output `[left, right]` of the current state (the
    /// one-contact engine's convention: sample `n` is time `n / fs`), then
    /// advance one step.
    pub fn tick(&mut self, sc: &CompiledMulti) -> [f64; 2] {
        let (mut l, mut r) = ([0.0], [0.0]);
        self.process_block(sc, &mut l, &mut r);
        [l[0], r[0]]
    }

    /// `left.len().min(right.len())` samples, the engine's block call for
    /// a several-contact scene: runs of samples in the block kernel, each
    /// certified to hold no crossing, and the search for a sample that is
    /// not (`multi/fast.rs`); the same samples bit for bit however the
    /// caller splits its blocks ([`tick`](Self::tick) is a block of one).
    /// \[audio-thread\]
    pub fn process_block(&mut self, sc: &CompiledMulti, left: &mut [f64], right: &mut [f64]) {
        let n = left.len().min(right.len());
        let mut i = 0;
        while i < n {
            if self.fast_ready(sc) {
                let run = self.run_fast(sc, &mut left[i..n], &mut right[i..n]);
                i += run.done;
                if !run.failed {
                    continue;
                }
            }
            if i < n {
                // a sample the block path could not certify: the search
                self.decide(sc);
                [left[i], right[i]] = self.output(sc);
                self.step(sc);
                i += 1;
            }
        }
    }

    /// The output `[left, right]` of the current state.
    ///
    /// Summed as the block kernel sums a sample's output on this state's
    /// kernel path (`engine/kernel`'s `rows_as_kernel`), so a sample the
    /// search takes and one the block path takes give their output in the
    /// same arithmetic. O(dim).
    pub fn output(&self, sc: &CompiledMulti) -> [f64; 2] {
        let m = self.slot;
        let tb = &self.tables[m];
        let dim = sc.phases[m].dim;
        let rows = crate::engine::kernel::Rows {
            ev: &self.kern.zero[..dim],
            l: &tb.out[0],
            r: &tb.out[1],
        };
        let [_, l, r] = crate::engine::kernel::rows_as_kernel(self.simd, &self.s, &rows);
        [
            l + tb.out0[0] + self.off_out[0],
            r + tb.out0[1] + self.off_out[1],
        ]
    }

    /// Play the model `scale` times faster (a note's pitch: every
    /// frequency and decay rate times `scale`, stiffness times `scale^2`,
    /// damping times `scale`, gravity times `scale^2`, masses kept: each
    /// sample advances the model's time by `scale h`). The state stays in
    /// the model's units, so a mass's physical velocity is `scale` times
    /// its velocity here, and the outputs' velocity pickups take the
    /// factor. O(N) now for the current phase, O(N) for another phase when
    /// it is first entered at this scale; allocation-free. A scale that is
    /// not finite and positive is refused ([`TimeScaleError::Invalid`], as
    /// the one-contact engine's `EngineState::set_time_scale` refuses it)
    /// and nothing changes. \[audio-thread\]
    pub fn set_time_scale(&mut self, sc: &CompiledMulti, scale: f64) -> Result<(), TimeScaleError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(TimeScaleError::Invalid);
        }
        self.scale = scale;
        self.step_h = sc.h * scale;
        self.cached = [(u64::MAX, 0.0); MAX_SPRINGS];
        let m = self.slot;
        self.tables[m].make(&sc.phases[m], &sc.model, scale, self.step_h, self.band_hz);
        self.set_shift(sc);
        Ok(())
    }

    /// Leave the objects' modes whose frequency (at the current time
    /// scale, physical Hz) is above `band_hz` out of the outputs, in every
    /// phase, as the one-contact engine's output band does, so a kit voice
    /// pitched up does not alias its top modes into the audio band. The
    /// dynamics keep every mode. Infinite (the default), not a number or
    /// not positive: every mode heard. Every phase's tables are made at
    /// the band now (a state that keeps its scale makes none on the way),
    /// O(phases dim) plus O(dim) per mode left out; allocation-free.
    /// \[worker\] \[audio-thread\]
    pub fn set_output_band(&mut self, sc: &CompiledMulti, band_hz: f64) {
        self.band_hz = if band_hz > 0.0 {
            band_hz
        } else {
            f64::INFINITY
        };
        for (t, ph) in self.tables.iter_mut().zip(&sc.phases) {
            t.make(ph, &sc.model, self.scale, self.step_h, self.band_hz);
        }
        self.set_shift(sc);
    }

    /// The modes the output band leaves out in the current phase.
    pub fn band_muted_modes(&self) -> usize {
        self.tables[self.slot].muted
    }

    /// Change the time scale to `scale` as a pitch bend does, without
    /// adding or removing energy (the one-contact engine's rule,
    /// `EngineState::bend_time_scale`): with no contact closed every
    /// object is in its free modes and every mass flies, so the modes'
    /// state and the masses' velocities are scaled by `s_old / s` (the
    /// physical energy, `s^2` times the model's, is unchanged: a higher
    /// pitch at the same energy is a smaller displacement; a mass keeps
    /// its physical velocity and its place). `Ok(false)` and nothing done
    /// while a contact is closed (the caller tries again later); refused
    /// with gravity, whose physical value `s^2 g` would change
    /// ([`TimeScaleError::Gravity`]), and for a scale that is not finite
    /// and positive. O(N) plus the phase's tables, allocation-free.
    /// \[audio-thread\]
    pub fn bend_time_scale(
        &mut self,
        sc: &CompiledMulti,
        scale: f64,
    ) -> Result<bool, TimeScaleError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(TimeScaleError::Invalid);
        }
        if sc.model.gravity_m_per_s2 != 0.0 {
            return Err(TimeScaleError::Gravity);
        }
        if self.mask != 0 {
            return Ok(false);
        }
        if scale == self.scale {
            return Ok(true);
        }
        // phase 0: every block is a free mode's (omega q, q'), no
        // equilibrium offset (no closed spring, no gravity)
        let r = self.scale / scale;
        for x in self.s.iter_mut() {
            *x *= r;
        }
        for v in self.v_f.iter_mut() {
            *v *= r;
        }
        self.set_time_scale(sc, scale)?;
        Ok(true)
    }

    /// The time scale ([`set_time_scale`](Self::set_time_scale)).
    pub fn time_scale(&self) -> f64 {
        self.scale
    }

    /// With the offset rod ([`CompiledMulti::switching`]), the switching
    /// decision at this sample instant (once per instant; a no-op with
    /// exact switching): an open contact whose penetration `p` is above 0
    /// closes with a rod of length `p` (its spring starts unstretched), a
    /// closed one whose `p - d` is at or below 0 opens (its spring's `k (p
    /// - d)^2 / 2` leaves). Contacts that switch here switch together,
    /// through the physical state. The trace observes after it
    /// (`crate::render::render_stream_several`). O(K dim), plus a switch. \[audio-thread\]
    pub fn decide(&mut self, sc: &CompiledMulti) {
        if sc.switching != Switching::OffsetRod || self.decided == self.clock {
            return;
        }
        self.decided = self.clock;
        let mut who = 0u32;
        let mut enter = [0.0; MAX_SPRINGS];
        for j in 0..sc.contacts() {
            let p = self.penetration(sc, j);
            if self.mask & (1 << j) != 0 {
                if !(p - self.rod[j] > 0.0) {
                    who |= 1 << j;
                }
            } else if p > 0.0 {
                who |= 1 << j;
                enter[j] = p;
            }
        }
        if who != 0 {
            let time_s = self.clock as f64 * self.step_h;
            self.switch(sc, who, time_s, &enter);
        }
    }

    /// Contact `j`'s penetration now (without its rod) \[m\]: its row,
    /// and the flights of its free sides.
    fn penetration(&self, sc: &CompiledMulti, j: usize) -> f64 {
        let ph = &sc.phases[self.slot];
        let (lo, up) = ph.ev_fly[j];
        let at = |slot: Option<usize>| slot.map_or(0.0, |k| self.x_f[k]);
        dot(&ph.ev[j], &self.s) + ph.ev0[j] + self.off_ev[j] + at(lo) - at(up)
    }

    /// Whether no contact can close for as long as every body flies free:
    /// no contact closed, no gravity, and for each contact the flights in
    /// its penetration moving away (a free lower side not rising, a free
    /// upper side not falling) while the objects' share stays below the
    /// rest of it. In this phase every block is a free mode's own `(omega
    /// q, q')`, whose norm never grows (the mode only loses energy), so
    /// block `k`'s share of contact `j`'s penetration stays within
    /// `|r_k| |s_k|` (`MultiPhase::ev_e`) and the penetration below its
    /// constant part, the flights now and those sums. Also when the
    /// objects are damped more (a pressed kit voice: its objects' state
    /// times a factor below 1), so a kit voice that is clear is pressed
    /// exactly by scaling its samples (docs/plugin.md, "Pressure and the
    /// mod wheel"). The margin `1e-9` of the reach covers the sum's
    /// rounding and the blocks' `1 + 1e-12` per step. O(contacts N).
    /// \[audio-thread\]
    pub fn contacts_clear(&self, sc: &CompiledMulti) -> bool {
        if self.mask != 0 || sc.model.gravity_m_per_s2 != 0.0 {
            return false;
        }
        let ph = &sc.phases[0];
        let nb = ph.gens.len();
        let s = &self.s;
        if s.len() != 2 * nb {
            return false;
        }
        (0..sc.contacts()).all(|j| {
            let e = &ph.ev_e[j];
            if e.len() != nb {
                return false;
            }
            let (lo, up) = ph.ev_fly[j];
            let away =
                lo.is_none_or(|k| self.v_f[k] <= 0.0) && up.is_none_or(|k| self.v_f[k] >= 0.0);
            let reach: f64 = (0..nb)
                .map(|k| e[k] * (s[k] * s[k] + s[nb + k] * s[nb + k]).sqrt())
                .sum();
            let rest = self.penetration(sc, j) - dot(&ph.ev[j], s);
            away && rest + reach * (1.0 + 1e-9) < 0.0
        })
    }

    /// Multiply the objects' state by `factor` (in `(0, 1]`) while no
    /// contact is closed: added mass-proportional damping over the samples
    /// it stands for (a pressed kit voice; the one-contact engine's
    /// `EngineState::scale_free_state`). Every mode keeps its damped
    /// frequency and decays faster; the masses fly on as they were.
    /// Refused (false, nothing changed) with a contact closed or a factor
    /// outside `(0, 1]`. O(N), allocation-free. \[audio-thread\]
    pub fn scale_objects(&mut self, factor: f64) -> bool {
        if self.mask != 0 || !(factor > 0.0 && factor <= 1.0) {
            return false;
        }
        self.s.iter_mut().for_each(|x| *x *= factor);
        self.cached = [(u64::MAX, 0.0); MAX_SPRINGS];
        true
    }

    /// The objects' energy (the model's units) while no contact is
    /// closed: the free phase's state is energy-normalised, so half its
    /// squared norm; `None` while a contact is closed. O(N). \[audio-thread\]
    pub fn objects_energy(&self) -> Option<f64> {
        (self.mask == 0).then(|| 0.5 * self.s.iter().map(|x| x * x).sum::<f64>())
    }

    /// The energy \[J, model units\] were the objects' state times `g`
    /// (a pressed kit voice's, [`scale_objects`](Self::scale_objects) not
    /// yet taken): the objects' part times `g^2`, with no contact closed;
    /// else the energy. O(N). \[audio-thread\]
    pub fn energy_objects_scaled(&self, sc: &CompiledMulti, g: f64) -> f64 {
        let e = self.observe(sc).energy;
        match self.objects_energy() {
            Some(objects) if g != 1.0 => e - (1.0 - g * g) * objects,
            _ => e,
        }
    }

    /// Contact `j`'s offset rod \[m\] (0 when open, and with exact
    /// switching).
    pub fn rod(&self, j: usize) -> f64 {
        self.rod[j]
    }
}
