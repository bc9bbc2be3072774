//! What a several-contact state shows: each contact's sides and the
//! energy ([`MultiState::observe`]), and the physical state a switch goes
//! through.

use super::*;

impl MultiState {
    /// The state now: each contact's sides (a row each, O(dim)) and the
    /// energy (every mode, every mass's motion and weight, every closed
    /// spring), O(N) for the modes no closed contact touches (all of them
    /// in flight) and O(d^2) for the `d` coordinates of the coupled part.
    pub fn observe(&self, sc: &CompiledMulti) -> MultiObservation {
        let m = &sc.model;
        let ph = &sc.phases[self.slot];
        let g = m.gravity_m_per_s2;
        let s = &self.s;
        let nb = ph.gens.len();
        let nbc = ph.coupled.len() / 2;
        // a row of a switch product on the coupled entries of s
        let row = |a: &DMatrix<f64>, r: usize| -> f64 {
            ph.coupled.iter().map(|&c| a[(r, c)] * self.s_own(c)).sum()
        };
        // the free modes: their blocks are (omega q, q')
        let mut energy = 0.0;
        for k in nbc..nb {
            energy += 0.5 * (s[k] * s[k] + s[nb + k] * s[nb + k]);
        }
        // the coupled modes, the held masses, the closed springs, each
        // from its own value (no expansion about the equilibrium, whose
        // terms could be far larger than the energy)
        for &i in &ph.coupled_modes {
            let (a, b) = (row(&ph.qv, i) + ph.qv0[i], row(&ph.pv, i) + ph.pv0[i]);
            energy += 0.5 * (a * a + b * b);
        }
        for (j, ms) in m.masses.iter().enumerate() {
            let (x, v) = self.mass_at(sc, j);
            energy += 0.5 * ms.mass_kg * v * v + ms.mass_kg * g * x;
        }
        for &c in &ph.members {
            let p = dot(&ph.ev[c], s) + ph.ev0[c] + self.off_ev[c] - self.rod[c];
            energy += 0.5 * m.contacts[c].stiffness_n_per_m * p * p;
        }
        let mut o = MultiObservation {
            active: self.mask,
            energy,
            ..Default::default()
        };
        for j in 0..ph.sides.len() {
            let ((xl, vl), (xu, vu)) = (self.side_at(ph, j, 0), self.side_at(ph, j, 1));
            o.x_hammer[j] = xu;
            o.v_hammer[j] = vu;
            o.x_contact[j] = xl;
            o.v_contact[j] = vl;
        }
        o
    }

    /// [`observe`](Self::observe) the long way, through the physical state
    /// (every `q, q'`, every mass's `x, v`) and the energy summed from it
    /// (a closed spring's from the difference of its sides): O(dim^2) a
    /// sample, for checks.
    pub fn observe_physical(&self, sc: &CompiledMulti) -> MultiObservation {
        let m = &sc.model;
        let ph = &sc.phases[self.slot];
        let nz = m.n() + m.masses.len();
        let (mut zq, mut zv) = (vec![0.0; nz + MAX_SPRINGS], vec![0.0; nz]);
        let mut phys = Physical::new(m);
        let s_own: Vec<f64> = (0..self.s.len()).map(|c| self.s_own(c)).collect();
        ph.physical_of(
            m,
            &s_own,
            (&self.x_f, &self.v_f),
            (&mut zq, &mut zv),
            &mut phys,
            None,
        );
        let mut o = MultiObservation {
            active: self.mask,
            energy: phys.energy(m),
            ..Default::default()
        };
        for (j, ct) in m.contacts.iter().enumerate() {
            let (xl, vl) = phys.side(&ct.lower);
            let (xu, vu) = phys.side(&ct.upper);
            if self.mask & (1 << j) != 0 {
                let p = xl - xu - ct.gap_m - self.rod[j];
                o.energy += 0.5 * ct.stiffness_n_per_m * p * p;
            }
            o.x_hammer[j] = xu;
            o.v_hammer[j] = vu;
            o.x_contact[j] = xl;
            o.v_contact[j] = vl;
        }
        o
    }
}

impl Physical {
    pub(super) fn new(m: &MultiModel) -> Self {
        let (n, nm) = (m.n(), m.masses.len());
        Self {
            q: vec![0.0; n],
            qv: vec![0.0; n],
            x: vec![0.0; nm],
            v: vec![0.0; nm],
        }
    }

    /// A side's position and velocity.
    fn side(&self, e: &MultiEnd) -> (f64, f64) {
        match e {
            MultiEnd::Point(w) => (dot(w, &self.q), dot(w, &self.qv)),
            MultiEnd::Mass(k) => (self.x[k.to_owned()], self.v[*k]),
            MultiEnd::Wall(h) => (*h, 0.0),
        }
    }

    /// Every mode's and every mass's energy, gravity's included (the
    /// closed springs' are the caller's).
    fn energy(&self, m: &MultiModel) -> f64 {
        let mut e = 0.0;
        for i in 0..m.n() {
            let w = two_pi() * m.freq_hz[i];
            let a = w * self.q[i];
            e += 0.5 * (a * a + self.qv[i] * self.qv[i]);
        }
        for (j, ms) in m.masses.iter().enumerate() {
            e += 0.5 * ms.mass_kg * self.v[j] * self.v[j]
                + ms.mass_kg * m.gravity_m_per_s2 * self.x[j];
        }
        e
    }
}
