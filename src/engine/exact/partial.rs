//! The state within a sample: the event function and its derivatives
//! through the state stepped by a partial step, the partial propagators
//! `exp(G tau)` (one vectorised exp/sin/cos sweep per distinct step), and
//! the partial steps themselves, block by block or, for a dense phase, by
//! a Taylor series.

use super::{TAYLOR_MAX_NORM, TAYLOR_TERMS};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::engine::dot::dot;
use crate::engine::kernel::{self, BlockProps};
use crate::engine::vmath::{self, SimdPath};
use crate::engine::{current_phase, EngineState, Phase};
use crate::physics::block::{exp2, OscBlocks};

impl EngineState {
    /// `[phi, phi', phi'']` at `tau` into the step from the current state,
    /// through the state itself (a sweep of partial propagators). `full`
    /// means `tau` is the whole step (precomputed propagators).
    pub(super) fn eval_event3(&mut self, scene: &CompiledScene, tau: f64, full: bool) -> [f64; 3] {
        let [mut f, mut d, mut dd] = self.event_sums(scene, tau, full);
        if self.in_contact() {
            f += self.offsets(scene).pi / scene.sk;
        } else {
            f += self.x_h + self.v_h * tau - 0.5 * self.g * tau * tau;
            d += self.v_h - self.g * tau;
            dd -= self.g;
        }
        [f, d, dd]
    }

    /// The object's part of [`eval_event3`](Self::eval_event3): the event
    /// rows `ev`, `ev'`, `ev''` times the state stepped by `tau`.
    pub(in crate::engine) fn event_sums(
        &mut self,
        scene: &CompiledScene,
        tau: f64,
        full: bool,
    ) -> [f64; 3] {
        let full = full || tau == self.step_s;
        let ph: &CompiledPhase = current_phase(self, scene);
        if ph.dense.is_some() {
            let s = &self.phases[self.phase.index()].s;
            let n = ph.dim;
            if tau == 0.0 {
                return [
                    dot(&ph.ev, &s[..n]),
                    dot(&ph.ev_d, &s[..n]),
                    dot(&ph.ev_dd, &s[..n]),
                ];
            }
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, full, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            [
                dot(&ph.ev, &t0[..n]),
                dot(&ph.ev_d, &t0[..n]),
                dot(&ph.ev_dd, &t0[..n]),
            ]
        } else {
            if tau != 0.0 && !full {
                self.ensure_partial(scene, tau);
            }
            let ps = &self.phases[self.phase.index()];
            let s = &ps.s;
            let props = match (tau == 0.0, full) {
                (true, _) => None,
                (false, false) => Some(&self.p_part),
                (false, true) => Some(&ps.props),
            };
            kernel::event_rows(self.simd, props, s, [&ph.ev, &ph.ev_d, &ph.ev_dd])
        }
    }

    /// Fill `p_part` with the current phase's block propagators over `tau`,
    /// unless it already holds them: one sweep of exp/sin/cos per distinct
    /// `(phase, tau)`.
    pub(in crate::engine) fn ensure_partial(&mut self, scene: &CompiledScene, tau: f64) {
        let contact = self.in_contact();
        if self.part_ok && self.part_tau == tau && self.part_contact == contact {
            return;
        }
        let ph = current_phase(self, scene);
        let gens = ph.gens.as_ref().expect("block phase");
        let nb = gens.len();
        let o = &ph.osc;
        let p = &mut self.p_part;
        osc_propagators(self.simd, o, tau, &mut self.part_args, p, nb);
        for &k in &o.other {
            p.set(k, &exp2(&gens[k], tau));
        }
        self.part_ok = true;
        self.part_tau = tau;
        self.part_contact = contact;
        self.exact_stats.partial_sweeps += 1;
    }

    /// Advance the current phase by `tau` (no switching).
    pub(super) fn advance_by(&mut self, scene: &CompiledScene, tau: f64, full: bool) {
        if tau <= 0.0 {
            return;
        }
        let full = full || tau == self.step_s;
        let ph: &CompiledPhase = current_phase(self, scene);
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        if ph.dense.is_some() {
            let n = ph.dim;
            let s = &mut self.phases[phase.index()].s;
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, full, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            s[..n].copy_from_slice(&t0[..n]);
        } else {
            if !full {
                self.ensure_partial(scene, tau);
            }
            let ps = &mut self.phases[phase.index()];
            let (s, props) = if full {
                (&mut ps.s, &ps.props)
            } else {
                (&mut ps.s, &self.p_part)
            };
            kernel::step_blocks(self.simd, props, &mut s[..ph.dim / 2 * 2]);
        }
        if !in_contact {
            self.x_h += self.v_h * tau - 0.5 * self.g * tau * tau;
            self.v_h -= self.g * tau;
        }
    }
}

/// The first `nb` blocks' propagators over `tau` into `p`, for the
/// oscillatory blocks of `o` (the others are left to the caller): `exp`,
/// `sin` and `cos` of every block in one vectorised batch
/// ([`vmath::exp_sincos`], whose two paths differ by their fused
/// multiply-adds), then `exp(G tau)` from them as in `OscForm::exp_from`:
/// the same products and sums as the scalar loop, without fused
/// multiply-adds, compiled for AVX2 where the CPU has it. O(N).
/// \[audio-thread\]
fn osc_propagators(
    simd: SimdPath,
    o: &OscBlocks,
    tau: f64,
    args: &mut [Vec<f64>; 5],
    p: &mut BlockProps,
    nb: usize,
) {
    #[inline(always)]
    fn body(
        simd: SimdPath,
        o: &OscBlocks,
        tau: f64,
        args: &mut [Vec<f64>; 5],
        p: &mut BlockProps,
        nb: usize,
    ) {
        let [mt, wt, e, sn, cs] = args;
        let (mt, wt) = (&mut mt[..nb], &mut wt[..nb]);
        let (m, w) = (&o.m[..nb], &o.w[..nb]);
        for k in 0..nb {
            mt[k] = m[k] * tau;
            wt[k] = w[k] * tau;
        }
        let (e, sn, cs) = (&mut e[..nb], &mut sn[..nb], &mut cs[..nb]);
        vmath::exp_sincos(simd, mt, wt, e, sn, cs);
        let (p00, p01) = (&mut p.p00[..nb], &mut p.p01[..nb]);
        let (p10, p11) = (&mut p.p10[..nb], &mut p.p11[..nb]);
        let [n0, n1, n2, n3] = &o.n_w;
        let (n0, n1, n2, n3) = (&n0[..nb], &n1[..nb], &n2[..nb], &n3[..nb]);
        for k in 0..nb {
            let (es, ec) = (e[k] * sn[k], e[k] * cs[k]);
            p00[k] = ec + es * n0[k];
            p01[k] = es * n1[k];
            p10[k] = es * n2[k];
            p11[k] = ec + es * n3[k];
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn body_avx2(
        simd: SimdPath,
        o: &OscBlocks,
        tau: f64,
        args: &mut [Vec<f64>; 5],
        p: &mut BlockProps,
        nb: usize,
    ) {
        body(simd, o, tau, args, p, nb)
    }
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `detect()` makes, after
        // checking AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { body_avx2(simd, o, tau, args, p, nb) },
        _ => body(simd, o, tau, args, p, nb),
    }
}

/// `out = exp(A tau) s` for a dense phase: the precomputed propagator for a
/// full step, else a Taylor series in sub-steps with `|A| tau_sub <= 0.5`.
pub(super) fn dense_apply(
    ph: &CompiledPhase,
    s: &[f64],
    tau: f64,
    full: bool,
    out: &mut [f64],
    term: &mut [f64],
    next: &mut [f64],
) {
    let n = ph.dim;
    let (a, phi) = ph.dense.as_ref().expect("dense phase");
    if full {
        for i in 0..n {
            out[i] = dot(&phi[i * n..(i + 1) * n], &s[..n]);
        }
        return;
    }
    let norm = a.norm(); // Frobenius >= spectral
    let subs = ((norm * tau / TAYLOR_MAX_NORM).ceil() as usize).clamp(1, 1 << 20);
    let dt = tau / subs as f64;
    out[..n].copy_from_slice(&s[..n]);
    for _ in 0..subs {
        term[..n].copy_from_slice(&out[..n]);
        for k in 1..=TAYLOR_TERMS {
            for i in 0..n {
                let mut acc = 0.0;
                for j in 0..n {
                    acc += a[(i, j)] * term[j];
                }
                next[i] = acc * dt / k as f64;
            }
            term[..n].copy_from_slice(&next[..n]);
            for i in 0..n {
                out[i] += term[i];
            }
        }
    }
}
