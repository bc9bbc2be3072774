//! What the trace records: a voice's [`Motion`] and [`Observation`] at an
//! instant, and the observed block paths' share of a fast run (the contact
//! point's rows and the energy's form, summed in the kernel's own pass).

use super::dot::dot;
use super::kernel::{rows_of, Rows, EPOCH};
use super::{EngineState, Motion, ObsScratch, Observation, CONTACT, FREE};
use crate::compile::{CompiledPhase, CompiledScene};

/// What an observed run writes per sample: the motion, and the energy when
/// asked.
pub(super) struct ObsOut<'a> {
    pub(super) m: &'a mut [Motion],
    pub(super) e: Option<&'a mut [f64]>,
}

/// The trace's rows of phase `ph`: `x_c, v_c` and, in contact, `eta`
/// (zeros in flight, `zeros` at least the phase's dimension).
pub(super) fn obs_rows<'a>(ph: &'a CompiledPhase, zeros: &'a [f64], in_contact: bool) -> Rows<'a> {
    Rows {
        ev: &ph.rows.x_c,
        l: &ph.rows.v_c,
        r: if in_contact {
            &ph.rows.eta
        } else {
            &zeros[..ph.dim]
        },
    }
}

impl EngineState {
    /// Allocate the scratch of [`process_block_observed`](Self::process_block_observed)
    /// and [`process_block_traced`](Self::process_block_traced) now, so that
    /// their calls allocate nothing (the instrument's live view observes
    /// voices on the audio thread). Idempotent. \[main-thread / worker\]
    pub fn reserve_observation(&mut self) {
        let dim = self.phases[FREE].s.len().max(self.phases[CONTACT].s.len());
        if self.obs.as_ref().is_none_or(|o| o.zeros.len() < dim) {
            self.obs = Some(Box::new(ObsScratch {
                zeros: vec![0.0; dim],
                rows: Box::default(),
                oacc: Box::new([[[0.0; 4]; 3]; EPOCH]),
                qacc: Box::new([[0.0; 4]; EPOCH]),
                qout: Box::new([0.0; EPOCH]),
                e_next: None,
                y: vec![0.0; dim],
            }));
        }
    }

    /// Whether the current phase's energy can come from the kernel pass
    /// (see [`process_block_traced`](Self::process_block_traced)).
    pub(super) fn quad_energy_ok(&self, scene: &CompiledScene) -> bool {
        let ph = scene.phase(self.phase);
        ph.energy_quad.is_some()
            && ph.gens.is_some()
            && ph.dense.is_none()
            && (!self.in_contact() || scene.s_star.iter().all(|&x| x == 0.0))
    }

    /// The motion of the `k` samples the fast path is about to commit
    /// (before [`commit_kernel`](Self::commit_kernel)): state 0 is the
    /// current one, states `1..k` come from the rows `x_c, v_c, eta` (and
    /// the energy's form) the fast path's kernel pass summed beside its own
    /// (`Observe`); the hammer in flight follows the same parabola as
    /// the fast path, in contact its height is `x_c - p_eff - rod` with
    /// `p_eff` the event row the engine's own pass computed.
    pub(super) fn observe_run(&mut self, scene: &CompiledScene, k: usize, out: ObsOut) {
        let ObsOut { m, e } = out;
        // energy of state 0: the last run's, or the state's own
        let e0 = match (&e, self.obs.as_ref().and_then(|o| o.e_next)) {
            (None, _) => None,
            (Some(_), Some((c, v))) if c == self.clock => Some(v),
            (Some(_), _) => Some(self.energy_observed(scene)),
        };
        let quad = if e.is_some() && self.quad_energy_ok(scene) {
            scene.phase(self.phase).energy_quad.as_ref()
        } else {
            None
        };
        let in_contact = self.in_contact();
        let ph = scene.phase(self.phase);
        let off = self.offsets(scene);
        let obs = self
            .obs
            .as_mut()
            .expect("allocated by process_block_observed");
        let ps = &self.phases[self.phase.index()];
        let r0 = rows_of(self.simd, &ps.s, &obs_rows(ph, &obs.zeros, in_contact));
        // states 1..k: the rows (and the energy's form) the engine's own
        // kernel pass summed beside its rows (`run_kernel_rows`)
        let (sc, dt, g) = (self.time_scale, self.step_s, self.g);
        let (mut x_h, mut v_h) = (self.x_h, self.v_h);
        for (j, mj) in m.iter_mut().enumerate().take(k) {
            let [xc, vc, eta] = if j == 0 {
                r0
            } else if in_contact {
                [obs.rows.ev[j - 1], obs.rows.l[j - 1], obs.rows.r[j - 1]]
            } else {
                // `x_c = -ev` bit for bit (the same products and sums,
                // negated), `0 - ev` so that a zero stays +0
                [0.0 - self.brows.ev[j - 1], obs.rows.ev[j - 1], 0.0]
            };
            *mj = if in_contact {
                let ev = if j == 0 {
                    self.cache[0]
                } else {
                    self.brows.ev[j - 1]
                };
                let x_c = xc + off.x_c;
                Motion {
                    x_hammer: x_c - (ev + off.pi / scene.sk) - self.rod_m,
                    v_hammer: (eta + off.eta) / scene.sm * sc,
                    x_contact: x_c,
                    v_contact: (vc + off.v_c) * sc,
                    in_contact: true,
                }
            } else {
                let here = Motion {
                    x_hammer: x_h,
                    v_hammer: v_h * sc,
                    x_contact: xc,
                    v_contact: vc * sc,
                    in_contact: false,
                };
                x_h += v_h * dt - 0.5 * g * dt * dt;
                v_h -= g * dt;
                here
            };
        }
        if let (Some(es), Some(e0)) = (e, e0) {
            // the affine terms of `energy`, from the motion just written
            let q = &obs.qout;
            let e_at = |j: usize, mj: &Motion| {
                let stored = 0.5 * q[j - 1];
                let x_h = mj.x_hammer;
                let v_h = mj.v_hammer / sc;
                let affine = if in_contact {
                    scene.m_h * g * x_h
                } else {
                    0.5 * scene.m_h * v_h * v_h + scene.m_h * g * x_h
                };
                sc * sc * (stored + affine)
            };
            es[0] = e0;
            if quad.is_some() {
                for j in 1..k {
                    es[j] = e_at(j, &m[j]);
                }
                // the state after the run: hammer in flight after k steps
                let (x_k, v_k) = if in_contact { (0.0, 0.0) } else { (x_h, v_h) };
                let last = Motion {
                    x_hammer: x_k,
                    v_hammer: v_k * sc,
                    ..m[k - 1]
                };
                obs.e_next = (!in_contact).then(|| (self.clock + k as u64, e_at(k, &last)));
            } else {
                obs.e_next = None;
            }
        }
    }

    /// Physical observation of the current state: [`motion`](Self::motion)
    /// and [`energy`](Self::energy). \[offline\]
    pub fn observe(&self, scene: &CompiledScene) -> Observation {
        self.motion(scene).with_energy(self.energy(scene))
    }

    /// The trace's columns but the energy: O(N) (dot products with the
    /// compiled rows). \[offline\]
    pub fn motion(&self, scene: &CompiledScene) -> Motion {
        let s = self.time_scale;
        if self.in_contact() {
            let ph = &scene.contact;
            let st = &self.phases[CONTACT].s;
            let off = self.offsets(scene);
            let x_c = dot(&ph.rows.x_c, st) + off.x_c;
            let v_c = dot(&ph.rows.v_c, st) + off.v_c;
            let eta = dot(&ph.rows.eta, st) + off.eta;
            Motion {
                x_hammer: self.contact_hammer_height(scene, x_c),
                v_hammer: eta / scene.sm * s,
                x_contact: x_c,
                v_contact: v_c * s,
                in_contact: true,
            }
        } else {
            let ph = &scene.free;
            let st = &self.phases[FREE].s;
            Motion {
                x_hammer: self.x_h,
                v_hammer: self.v_h * s,
                x_contact: dot(&ph.rows.x_c, st),
                v_contact: dot(&ph.rows.v_c, st) * s,
                in_contact: false,
            }
        }
    }

    /// Hammer height in contact: the contact point less the effective
    /// penetration and the rod.
    pub(super) fn contact_hammer_height(&self, scene: &CompiledScene, x_c: f64) -> f64 {
        x_c - self.penetration(scene) - self.rod_m
    }

    /// Effective penetration now (`p_eff`, with the rod) \[m\].
    pub fn penetration(&self, scene: &CompiledScene) -> f64 {
        if let Some(p) = self.replay_penetration() {
            return p;
        }
        if self.in_contact() {
            (dot(&scene.contact.rows.pi, &self.phases[CONTACT].s) + self.offsets(scene).pi)
                / scene.sk
        } else {
            dot(&scene.free.rows.x_c, &self.phases[FREE].s) - self.x_h
        }
    }
}
