//! The search's model of `phi` from the current state (docs/numerics.md,
//! "The search: slow and fast terms"): the polynomial part, the slow
//! terms' Taylor polynomial, the fast terms gathered with their bound
//! data, the whole blocks, and the rounding allowances; and the bounds of
//! `phi` on a node that the certified bisection decides on.

use super::partial::dense_apply;
use super::powers::{powers, raise_powers, Powers};
use super::{FastBounds, SearchScratch, TermSplit, MAX_DEGREE, ROUND_UNITS, TAYLOR_TERMS};
use crate::compile::event::THETA_RESOLVED;
use crate::compile::{CompiledPhase, CompiledScene};
use crate::engine::dot::dot;
use crate::engine::search::NodeBounds;
use crate::engine::vmath::{self, SimdPath};
use crate::engine::{current_phase, EngineState, Phase};
use crate::physics::block::{exp2, mul2};

impl SearchScratch {
    /// Raise the slow terms' powers `z = C mu^j` up to `j = upto`,
    /// summing the coefficients `poly[j]` (`j <= deg`) and taking the
    /// magnitudes of the third derivative (`j = 3`) and of the Lagrange
    /// remainder (`j = deg + 1`). O(N_slow) per power. \[audio-thread\]
    fn raise_poly(&mut self, simd: SimdPath, upto: usize) {
        if self.next_j > upto {
            return;
        }
        let (ns, deg, j0) = (self.ns, self.deg, self.next_j);
        let mut sums = [0.0; MAX_DEGREE + 2];
        let mut mags = [0.0; 2];
        raise_powers(
            simd,
            Powers {
                zr: &mut self.z_r[..ns],
                zi: &mut self.z_i[..ns],
                mr: &self.mu_r[..ns],
                mi: &self.mu_i[..ns],
                cw: &self.cw[..ns],
            },
            (j0, upto),
            [3, deg + 1],
            &mut sums,
            &mut mags,
        );
        for (j, &sum) in sums.iter().enumerate().take(upto + 1).skip(j0) {
            if j == 3 && ns > 0 {
                self.slow_c3 = mags[0] * self.growth;
            }
            if j == deg + 1 && ns > 0 {
                // Lagrange remainders of the q-th derivative of the
                // degree-`deg` Taylor polynomial: |f^(deg+1)| rem^(deg+1-q)
                // / (deg+1-q)!.
                let rem_mag = mags[1] * self.growth;
                for (q, eq) in self.slow_err.iter_mut().enumerate() {
                    let mut v = rem_mag;
                    for i in 1..=(deg + 1).saturating_sub(q) {
                        v *= self.rem / i as f64;
                    }
                    *eq = v;
                }
            }
            if j <= deg {
                self.poly[j] = sum * self.inv_fact;
                self.inv_fact /= (j + 1) as f64;
            }
        }
        self.next_j = upto + 1;
    }

    /// The fast terms' amplitudes `C = Re + i Im` from the state, gathered
    /// with the data their node bounds need; their rounding and growth go
    /// to `al`.
    #[inline]
    fn gather_fast(
        &mut self,
        ph: &CompiledPhase,
        split: &TermSplit,
        s: &[f64],
        rem: f64,
        al: &mut Allowance,
    ) {
        let nb = ph.dim / 2;
        let terms = &ph.search.terms;
        for (i, &j) in split.fast.iter().enumerate() {
            let t = &terms[j as usize];
            let k = t.block as usize;
            let (x0, x1) = (s[k], s[nb + k]);
            let (cr, ci) = (t.re[0] * x0 + t.re[1] * x1, -(t.im[0] * x0 + t.im[1] * x1));
            let sk = x0.abs() + x1.abs();
            let r = (t.re[0].abs() + t.re[1].abs()) * sk
                + (t.im[0].abs() + t.im[1].abs()) * sk * (t.w * rem).min(1.0);
            al.round += r;
            al.round_d += r * t.mu;
            self.f_cr[i] = cr;
            self.f_ci[i] = ci;
            self.f_m[i] = t.m;
            self.f_w[i] = t.w;
            self.f_mu[i] = t.mu;
            let p = powers(cr, ci, t.m, t.w);
            let mut fb = FastBounds::default();
            for (q, (re, im)) in p.iter().enumerate() {
                fb.ab[q] = [re.abs(), im.abs()];
            }
            // peak of e^{m tau} min(1, w tau) (decaying terms)
            if t.m < 0.0 && t.w > 0.0 {
                let t_star = -1.0 / t.m;
                if t_star * t.w < 1.0 {
                    (fb.peak, fb.peak_val) = (t_star, t.w * t_star * (-1.0f64).exp());
                } else {
                    (fb.peak, fb.peak_val) = (1.0 / t.w, (t.m / t.w).exp());
                }
            }
            self.f_b[i] = fb;
            al.gamma = al.gamma.max(t.m);
        }
        self.nf = split.fast.len();
    }

    /// The slow terms' amplitudes and exponents from the state; their
    /// rounding and growth go to `al`. Returns the largest `|mu|`.
    #[inline]
    fn gather_slow(
        &mut self,
        ph: &CompiledPhase,
        split: &TermSplit,
        s: &[f64],
        rem: f64,
        al: &mut Allowance,
    ) -> f64 {
        let nb = ph.dim / 2;
        let terms = &ph.search.terms;
        let mut mu_max: f64 = 0.0;
        for (i, &j) in split.slow.iter().enumerate() {
            let t = &terms[j as usize];
            let k = t.block as usize;
            let (x0, x1) = (s[k], s[nb + k]);
            self.z_r[i] = t.re[0] * x0 + t.re[1] * x1;
            self.z_i[i] = -(t.im[0] * x0 + t.im[1] * x1);
            self.mu_r[i] = t.m;
            self.mu_i[i] = t.w;
            let cw = (t.w * rem).min(1.0);
            self.cw[i] = cw;
            let sk = x0.abs() + x1.abs();
            let r =
                (t.re[0].abs() + t.re[1].abs()) * sk + (t.im[0].abs() + t.im[1].abs()) * sk * cw;
            al.round += r;
            al.round_d += r * t.mu;
            mu_max = mu_max.max(t.mu);
            al.gamma = al.gamma.max(t.m);
        }
        mu_max
    }

    /// Start the slow Taylor polynomial of `ns` terms with `theta = mu_max
    /// rem`: its degree (`theta^(d+1) / (d+1)! <= 2^-60`, at least
    /// quadratic so the remainders of value, slope and curvature all come
    /// from the (d+1)-th derivative) and its coefficients `poly[j] = sum_k
    /// Re[C_k mu_k^j] / j!` up to `j = 3` (and the magnitude of the third
    /// derivative); the rest only when a node away from the origin needs
    /// them (`complete_poly`): a search that certifies its first node never
    /// pays for them. Returns the degree.
    fn start_poly(&mut self, simd: SimdPath, ns: usize, theta: f64, rem: f64) -> usize {
        let mut deg = 0;
        let mut term = theta; // theta^(deg+1) / (deg+1)!
        while deg < MAX_DEGREE && term > f64::EPSILON / 256.0 {
            deg += 1;
            term *= theta / (deg + 1) as f64;
        }
        deg = if ns == 0 { 0 } else { deg.max(2) };
        self.deg = deg;
        self.ns = ns;
        self.theta = theta;
        self.rem = rem;
        self.next_j = 0;
        self.inv_fact = 1.0;
        self.poly = [0.0; MAX_DEGREE + 1];
        self.slow_c3 = 0.0;
        self.slow_err = [0.0; 3];
        self.raise_poly(simd, 3);
        deg
    }

    /// The slow polynomial's part of a node's bounds: value, slope and
    /// curvature by Horner (at the origin: its first coefficients, which
    /// are exact sums), its remainder, and its third-derivative bound.
    #[inline]
    fn slow_bounds(&mut self, simd: SimdPath, tau: f64, w: f64, nb: &mut NodeBounds) {
        if tau == 0.0 {
            nb.q[0] += self.poly[0];
            nb.q[1] += self.poly[1];
            nb.q[2] += 2.0 * self.poly[2];
        } else {
            self.complete_poly(simd);
            let deg = self.deg;
            let (mut p0, mut p1, mut p2) = (0.0, 0.0, 0.0);
            for j in (0..=deg).rev() {
                p2 = p2 * tau + 2.0 * p1;
                p1 = p1 * tau + p0;
                p0 = p0 * tau + self.poly[j];
            }
            nb.q[0] += p0;
            nb.q[1] += p1;
            nb.q[2] += p2;
            let [e0, e1, e2] = self.slow_err;
            nb.u += e0 + w * (e1 + 0.5 * e2 * w);
            nb.l += e1 + e2 * w;
        }
        nb.c3 += self.slow_c3;
    }

    /// The fast terms' part of a node's bounds: exact, in one vectorised
    /// exp/sin/cos batch; a term the node resolves adds its value, slope and
    /// curvature (and its envelope to `c3`), one it does not adds its
    /// envelope to `u` and `l`.
    #[inline]
    fn fast_bounds(&mut self, simd: SimdPath, tau: f64, w: f64, all: bool, nb: &mut NodeBounds) {
        let nf = self.nf;
        if nf == 0 {
            return;
        }
        for i in 0..nf {
            self.f_mt[i] = self.f_m[i] * tau;
            self.f_wt[i] = self.f_w[i] * tau;
        }
        if all {
            vmath::exp_sincos(
                simd,
                &self.f_mt[..nf],
                &self.f_wt[..nf],
                &mut self.f_e[..nf],
                &mut self.f_s[..nf],
                &mut self.f_c[..nf],
            );
        } else {
            // a term the node does not resolve enters through its envelope
            // alone, which needs no sine or cosine: those of the resolved
            // terms only, gathered (each lane the same bits either way)
            vmath::exp_only(simd, &self.f_mt[..nf], &mut self.f_e[..nf]);
            let mut k = 0;
            for i in 0..nf {
                if self.f_mu[i] * w <= THETA_RESOLVED {
                    self.f_at[k] = i as u32;
                    self.f_rt[k] = self.f_wt[i];
                    k += 1;
                }
            }
            if k > 0 {
                vmath::sincos_only(
                    simd,
                    &self.f_rt[..k],
                    &mut self.f_rs[..k],
                    &mut self.f_rc[..k],
                );
                for j in 0..k {
                    let i = self.f_at[j] as usize;
                    self.f_s[i] = self.f_rs[j];
                    self.f_c[i] = self.f_rc[j];
                }
            }
        }
        let growth = self.growth;
        for i in 0..nf {
            let e = self.f_e[i];
            let (sn, cs) = (self.f_s[i], self.f_c[i]);
            let (cr, ci) = (self.f_cr[i], self.f_ci[i]);
            let (m, wv, mu) = (self.f_m[i], self.f_w[i], self.f_mu[i]);
            let resolved = all || mu * w <= THETA_RESOLVED;
            if resolved {
                let er = e * (cr * cs - ci * sn);
                let ei = e * (cr * sn + ci * cs);
                nb.q[0] += er;
                nb.q[1] += er * m - ei * wv;
                nb.q[2] += er * (m * m - wv * wv) - ei * (2.0 * m * wv);
                if all {
                    continue;
                }
            }
            // sup over the node (tau >= `tau`) of e^{m t} and of
            // e^{m t} min(1, w t)
            let fb = &self.f_b[i];
            let (e_sup, f_sup) = if m < 0.0 {
                let f = if tau >= fb.peak {
                    e * (wv * tau).min(1.0)
                } else {
                    fb.peak_val
                };
                (e, f)
            } else {
                (growth, growth * (wv * (tau + w)).min(1.0))
            };
            let env = |q: usize| fb.ab[q][0] * e_sup + fb.ab[q][1] * f_sup;
            if resolved {
                nb.c3 += env(2);
            } else {
                nb.u += env(0);
                nb.l += env(1);
            }
        }
    }

    /// The whole polynomial and its truncation errors.
    fn complete_poly(&mut self, simd: SimdPath) {
        if self.next_j <= self.deg + 1 {
            self.raise_poly(simd, self.deg + 1);
        }
    }
}

/// Rounding allowance being summed while a model is built: computing each
/// amplitude `C` from the state rounds each product once (`|re| |s_k|`, and
/// `|im| |s_k|` of which at most `min(1, w rem)` shows), for the value
/// (`round`) and the slope (`round_d`); `gamma` is the largest real part
/// (envelopes can only shrink unless rounding left a lossless eigenvalue's
/// real part a hair above 0).
#[derive(Default)]
struct Allowance {
    round: f64,
    round_d: f64,
    gamma: f64,
}

impl EngineState {
    /// Build the model of `phi` from the current state over the next `rem`
    /// (reference time): amplitudes of every term, the slow polynomial, the
    /// fast terms gathered with their bound data, the rounding allowances.
    /// O(N + N_slow deg). Stages: the flight or offset part, then (dense
    /// phase: one norm bound and done) the fast terms, the whole blocks and
    /// the slow terms, each adding its rounding to the allowance.
    pub(super) fn build_model(&mut self, scene: &CompiledScene, rem: f64) {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph = current_phase(self, scene);
        let off_pi = self.offsets(scene).pi;
        let sc = &mut self.search;
        sc.c = if in_contact {
            [off_pi / scene.sk, 0.0, 0.0]
        } else {
            [self.x_h, self.v_h, -self.g]
        };
        let c_scale = sc.c[0].abs() + sc.c[1].abs() * rem + sc.c[2].abs() * rem * rem;
        let c_scale_d = sc.c[1].abs() + sc.c[2].abs() * rem;
        let s = &self.phases[phase.index()].s;
        let units = ROUND_UNITS * f64::EPSILON;
        if let Some((_, _)) = &ph.dense {
            let n = ph.dim;
            sc.y_norm = s[..n].iter().map(|x| x * x).sum::<f64>().sqrt();
            sc.nf = 0;
            sc.deg = 0;
            sc.growth = 1.0;
            let ev_norm = ph.ev.iter().map(|x| x * x).sum::<f64>().sqrt();
            let evd_norm = ph.ev_d.iter().map(|x| x * x).sum::<f64>().sqrt();
            // dense partial steps: a Taylor series of mat-vecs per sub-step
            let k = n as f64 + TAYLOR_TERMS as f64;
            sc.tol = k * units * (c_scale + ev_norm * sc.y_norm);
            sc.tol_d = k * units * (c_scale_d + evd_norm * sc.y_norm);
            return;
        }
        let split = &self.phases[phase.index()].split;
        let mut fast = Allowance::default();
        sc.gather_fast(ph, split, s, rem, &mut fast);
        whole_allowance(ph, s, &mut fast);
        let mut slow = Allowance {
            gamma: fast.gamma,
            ..Allowance::default()
        };
        let mu_max = sc.gather_slow(ph, split, s, rem, &mut slow);
        let growth = (slow.gamma * rem).exp();
        sc.growth = growth;
        let theta = mu_max * rem;
        let deg = sc.start_poly(self.simd, split.slow.len(), theta, rem);
        // Horner's evaluation of the polynomial rounds ~2 deg times terms
        // that add up to at most e^theta times the slow amplitudes.
        let k = (2 * deg + 2) as f64 * theta.exp();
        sc.tol = units * (c_scale + fast.round + k * slow.round) * growth;
        sc.tol_d = units * (c_scale_d + fast.round_d + k * slow.round_d) * growth;
    }

    /// Bounds of `phi` on the node `[tau, tau + w]` of the current model
    /// (`all`: every block resolved, for an exact value of the model): the
    /// flight or offset part, then the slow polynomial, the fast terms and
    /// the whole blocks, each adding to the same [`NodeBounds`] in that
    /// order.
    pub(super) fn node_bounds(
        &mut self,
        scene: &CompiledScene,
        tau: f64,
        w: f64,
        all: bool,
    ) -> NodeBounds {
        let phase = self.phase;
        let ph = current_phase(self, scene);
        let sc = &mut self.search;
        let [c0, c1, c2] = sc.c;
        let mut nb = NodeBounds {
            q: [c0 + tau * (c1 + 0.5 * c2 * tau), c1 + c2 * tau, c2],
            u: 0.0,
            l: 0.0,
            c3: 0.0,
        };
        let s = &self.phases[phase.index()].s;
        if ph.dense.is_some() {
            let n = ph.dim;
            let [t0, t1, t2] = &mut self.dense_tmp;
            dense_apply(ph, s, tau, false, &mut t0[..n], &mut t1[..n], &mut t2[..n]);
            nb.q[0] += dot(&ph.ev, &t0[..n]);
            nb.q[1] += dot(&ph.ev_d, &t0[..n]);
            nb.q[2] += dot(&ph.ev_dd, &t0[..n]);
            nb.c3 = ph.search.dense_ddd_norm * sc.y_norm;
            return nb;
        }
        sc.slow_bounds(self.simd, tau, w, &mut nb);
        sc.fast_bounds(self.simd, tau, w, all, &mut nb);
        whole_bounds(ph, s, tau, w, all, &mut nb);
        nb
    }

    /// `[phi, phi', phi'']` of the model at `tau` (exact to rounding).
    pub(super) fn model_eval(&mut self, scene: &CompiledScene, tau: f64) -> [f64; 3] {
        self.node_bounds(scene, tau, 0.0, true).q
    }
}

/// The whole blocks' rounding (their bounds come from their own state, per
/// node).
#[inline]
fn whole_allowance(ph: &CompiledPhase, s: &[f64], al: &mut Allowance) {
    let nb = ph.dim / 2;
    for (j, &k) in ph.search.whole.iter().enumerate() {
        let k = k as usize;
        let rows = &ph.search.whole_rows[j];
        let sk = s[k].abs() + s[nb + k].abs();
        al.round += (rows[0][0].abs() + rows[0][1].abs()) * sk;
        al.round_d += (rows[2][0].abs() + rows[2][1].abs()) * sk;
        al.gamma = al.gamma.max(ph.search.whole_info[j][0]);
    }
}

/// The whole blocks' part of a node's bounds (nearly equal real
/// eigenvalues): from their own state `x` at the node's start, `|R exp(G t)
/// x| <= e^{lambda_max t} (|R x| + |R N x| t)`.
#[inline]
fn whole_bounds(ph: &CompiledPhase, s: &[f64], tau: f64, w: f64, all: bool, nb: &mut NodeBounds) {
    let gens = ph.gens.as_ref().expect("block phase");
    let n_blocks = gens.len();
    for (j, &k) in ph.search.whole.iter().enumerate() {
        let k = k as usize;
        let (x0, x1) = mul2(&exp2(&gens[k], tau), s[k], s[n_blocks + k]);
        let rows = &ph.search.whole_rows[j];
        let [lmax, rho] = ph.search.whole_info[j];
        let dot2 = |r: [f64; 2]| (r[0] * x0 + r[1] * x1).abs();
        let grow = (lmax.max(0.0) * w).exp();
        let b = |q: usize| (dot2(rows[2 * q]) + dot2(rows[2 * q + 1]) * w) * grow;
        if all || rho * w <= THETA_RESOLVED {
            nb.q[0] += ph.ev[k] * x0 + ph.ev[n_blocks + k] * x1;
            nb.q[1] += ph.ev_d[k] * x0 + ph.ev_d[n_blocks + k] * x1;
            nb.q[2] += ph.ev_dd[k] * x0 + ph.ev_dd[n_blocks + k] * x1;
            if !all {
                nb.c3 += b(2);
            }
        } else {
            nb.u += b(0);
            nb.l += b(1);
        }
    }
}
