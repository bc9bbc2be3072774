//! The contact system of a modal object struck at one point, decomposed
//! through its rank-one structure (docs/numerics.md, "Decomposing a phase"): O(N^2)
//! instead of a general O(N^3) eigensolver.
//!
//! Modes `q_i'' + 2 sigma_i q_i' + omega_i^2 q_i = -f_i F`, hammer
//! `m x_h'' = F`, contact force `F = k p + c p'` with `p = sum f_i q_i - x_h`.
//! An eigenvalue `z` of the contact phase makes the contact force excite
//! exactly the motion it came from:
//!
//! `s(z) = 1 + (k + c z) R(z) = 0`, `R(z) = sum_i f_i^2 / D_i(z) + 1 / (m z^2)`,
//! `D_i(z) = z^2 + 2 sigma_i z + omega_i^2`,
//!
//! a scalar secular equation whose `2 n + 2` roots are the zeros of the
//! polynomial `P(z) = s(z) m z^2 prod_i D_i(z)`. The eigenvector for a root
//! follows in closed form (force `F = 1`): in the energy coordinates of
//! [`crate::physics::model::contact_system`], `xi_i = -f_i omega_i / D_i`,
//! `u_i = -f_i z / D_i`, `pi = sqrt(k) / (k + c z)`, `eta = 1 / (sqrt(m) z)`.
//! The generator has the form `A = [[0, B], [-B^T, -Dm]]` (positions
//! `xi, pi`; momenta `u, eta`), so `A^T = J A J` with `J = diag(I, -I)`:
//! `J v` is a left eigenvector for the same `z`, and the inverse of the
//! eigenvector matrix is `diag(1 / (v_j^T J v_j)) V^T J`, also O(N^2). (Its
//! rounding grows with each eigenvalue's condition number `1 / |v_j^T J
//! v_j|`; past `ROW_COND_MAX` the inverse is taken by LU instead, one
//! blocked O(N^3) factorisation.)
//!
//! Roots: Aberth-Ehrlich simultaneous iteration on `P`, started from the
//! poles (each mode's two poles; the hammer's double pole at 0 replaced by
//! the rigid-contact frequency `+-i sqrt(k (1/m + sum f_i^2))`). Each root is
//! kept as its offset `delta` from the nearest pole, and `P'/P` is evaluated
//! with that pole's factor multiplied into `s` (`S_j = D_j s`), so a root
//! next to a pole (a weakly coupled mode) keeps full relative precision in
//! `delta`, and so does `D_j = delta (delta + p_j - p_j')`, which the
//! eigenvector divides by (the idea of Gu and Eisenstat's stable secular
//! solvers: never form the difference of a root and a pole from two rounded
//! numbers). O(N) per root and sweep, O(N^2) per sweep, typically 10-30
//! sweeps. On 1000 random scenes (1 to 60 modes, undamped to overdamped,
//! soft to stiff contacts; the test below) the residual is at most 3e-16,
//! `|V^-1 V - I|` 4e-15 and the propagator within 3e-15 of the dense Pade
//! `exp(A h)`, as close as the general eigensolver gets.
//!
//! Failure is reported, not hidden: equal modes (a degenerate pair has a
//! combination that does not couple, whose eigenvector this formula cannot
//! give), roots that do not converge, or an unpaired complex root return an
//! error, and the caller uses the general eigensolver instead. The caller
//! also checks the result (residual, condition, inverse) like any other
//! decomposition.

use crate::physics::block::Mat2;
use crate::physics::error::SecularError;
use nalgebra::{Complex, DMatrix};

type C = Complex<f64>;

/// A modal object struck at one point by the hammer: what the contact
/// phase's eigenproblem depends on. Only modes with a nonzero weight at the
/// contact point belong here (the others are exactly decoupled).
#[derive(Debug, Clone, Copy)]
pub struct ModalContact<'a> {
    /// Undamped angular frequencies `omega_i` \[rad/s\], > 0.
    pub omega: &'a [f64],
    /// Decay rates `sigma_i` \[1/s\], >= 0 (generator entry `-2 sigma_i`).
    pub sigma: &'a [f64],
    /// Mode weights at the contact point `f_i` \[1/sqrt(kg)\], nonzero.
    pub f: &'a [f64],
    /// Contact stiffness \[N/m\], > 0.
    pub k: f64,
    /// Contact damping \[N s/m\], >= 0.
    pub c: f64,
    /// Hammer mass \[kg\], > 0.
    pub m_h: f64,
}

/// Real 2x2 blocks in structure-of-arrays layout (block `k` on coordinates
/// `k` and `nb + k`), the eigenvector matrix `V` (rows in the contact
/// system's order `[xi; pi; u; eta]`) and `V^{-1}`.
pub type BlockEigen = (Vec<Mat2>, DMatrix<f64>, DMatrix<f64>);

/// Most Aberth sweeps before giving up.
pub const MAX_SWEEPS: usize = 200;
/// A root is converged when its last correction is below this fraction of
/// its distance to its pole (or below 8 ulps of the root); corrections at
/// rounding level wander around 1e-15 of it. Two more sweeps follow.
const REL_STEP: f64 = 1e-14;
/// Sweeps after every root has converged.
const POLISH_SWEEPS: usize = 2;
/// Largest eigenvalue condition number `1 / |v^T J v|` (unit `v`) for which
/// `V^-1` is built from the left eigenvectors `J v`; beyond it, by LU.
const ROW_COND_MAX: f64 = 4.0;
/// Roots with `|Im z| <= REAL_TOL |z|` are real.
const REAL_TOL: f64 = 1e-9;

/// One factor of `P`: a mode's `D_i` or the hammer's `z^2`, with its poles
/// and its weight in `R` (`f_i^2`, or `1/m`).
#[derive(Debug, Clone, Copy)]
struct Factor {
    p: [C; 2],
    g: f64,
}

impl Factor {
    /// `D(z)` and `D'(z)` at `z = p[a] + delta`, with both differences
    /// `z - p[.]` formed from `delta` and the pole difference.
    #[inline]
    fn eval_anchored(&self, a: usize, delta: C) -> (C, C) {
        let d0 = delta;
        let d1 = delta + (self.p[a] - self.p[1 - a]);
        (d0 * d1, d0 + d1)
    }

    /// `D(z)` and `D'(z)` at `z = base + delta` (`base` a pole of another
    /// factor).
    #[inline]
    fn eval_at(&self, base: C, delta: C) -> (C, C) {
        let d0 = (base - self.p[0]) + delta;
        let d1 = (base - self.p[1]) + delta;
        (d0 * d1, d0 + d1)
    }
}

/// A root as an offset from an anchor pole.
#[derive(Debug, Clone, Copy)]
struct Root {
    /// Factor and which of its two poles.
    j: usize,
    a: usize,
    delta: C,
}

struct Problem {
    factors: Vec<Factor>,
    k: f64,
    c: f64,
}

impl Problem {
    fn pole(&self, r: &Root) -> C {
        self.factors[r.j].p[r.a]
    }

    fn z(&self, r: &Root) -> C {
        self.pole(r) + r.delta
    }

    /// The Newton correction `P/P'` at the root estimate, with the anchor's
    /// factor multiplied into `s` (no cancellation next to the pole).
    fn newton(&self, r: &Root) -> C {
        let base = self.pole(r);
        let z = base + r.delta;
        let mut rsum = C::new(0.0, 0.0);
        let mut rder = C::new(0.0, 0.0);
        let mut logsum = C::new(0.0, 0.0);
        for (l, fl) in self.factors.iter().enumerate() {
            if l == r.j {
                continue;
            }
            let (d, dd) = fl.eval_at(base, r.delta);
            let inv = d.inv();
            rsum += inv * fl.g;
            rder -= dd * inv * inv * fl.g;
            logsum += dd * inv;
        }
        let fj = &self.factors[r.j];
        let (dj, ddj) = fj.eval_anchored(r.a, r.delta);
        let kz = C::new(self.k, 0.0) + z * self.c;
        let one = C::new(1.0, 0.0) + kz * rsum;
        let s = dj * one + kz * fj.g;
        let sd = ddj * one + dj * (rsum * self.c + kz * rder) + C::new(self.c * fj.g, 0.0);
        // 1 / (S'/S + logsum), with no division by S: an exact root gives 0.
        s / (sd + s * logsum)
    }

    /// Move the root's anchor to the nearest pole.
    fn reanchor(&self, r: &mut Root) {
        let z = self.z(r);
        let mut best = (r.delta.norm_sqr(), r.j, r.a);
        for (l, fl) in self.factors.iter().enumerate() {
            for a in 0..2 {
                let d = (z - fl.p[a]).norm_sqr();
                if d < best.0 {
                    best = (d, l, a);
                }
            }
        }
        if (best.1, best.2) != (r.j, r.a) {
            let old = self.pole(r);
            r.j = best.1;
            r.a = best.2;
            r.delta = (old - self.pole(r)) + r.delta;
        }
    }
}

/// The poles of `z^2 + 2 sigma z + omega^2`, each computed without
/// cancellation.
fn mode_poles(omega: f64, sigma: f64) -> [C; 2] {
    if sigma < omega {
        let wd = ((omega - sigma) * (omega + sigma)).sqrt();
        [C::new(-sigma, wd), C::new(-sigma, -wd)]
    } else {
        let r = ((sigma - omega) * (sigma + omega)).sqrt();
        let big = -sigma - r;
        [C::new(omega * omega / big, 0.0), C::new(big, 0.0)]
    }
}

/// Decompose the contact phase of `mc` (see the module doc). O(N^2) time,
/// O(N^2) memory for `V` and `V^{-1}`. Four stages: the problem's factors,
/// the roots, their eigenvectors sorted into conjugate pairs and real
/// pairs, and the blocks with `V` and `V^{-1}`.
pub fn decompose(mc: &ModalContact) -> Result<BlockEigen, SecularError> {
    let prob = Problem::new(mc)?;
    let roots = solve_roots(&prob, mc)?;
    let (complex, real) = eigenpairs(&prob, mc, &roots)?;
    let mut out = Assembly::new(2 * mc.omega.len() + 2);
    for (z, r, ev) in &complex {
        out.put_conjugate_pair(&prob, mc, r, *z, ev)?;
    }
    for &(i1, i2, crit) in &real_pairs(&real, mc.omega.len()) {
        if crit {
            let (z1, r1, _) = &real[i1];
            let z2 = real[i2].0;
            out.put_near_critical(&prob, mc, r1, C::new(*z1, 0.0), C::new(z2, 0.0))?;
        } else {
            out.put_real_pair(mc.omega.len(), &real[i1], &real[i2])?;
        }
    }
    out.finish()
}

impl Problem {
    /// The factors of `P` for a valid `mc`; refuses out-of-range data and
    /// two modes sharing a pole.
    fn new(mc: &ModalContact) -> Result<Self, SecularError> {
        let n = mc.omega.len();
        if mc.sigma.len() != n || mc.f.len() != n {
            return Err(SecularError::MismatchedData);
        }
        let ok = |x: f64| x.is_finite();
        if !(mc.k > 0.0 && ok(mc.k) && mc.c >= 0.0 && ok(mc.c) && mc.m_h > 0.0 && ok(mc.m_h)) {
            return Err(SecularError::ContactOutOfRange);
        }
        for i in 0..n {
            if !(mc.omega[i] > 0.0 && ok(mc.omega[i]) && mc.sigma[i] >= 0.0 && ok(mc.sigma[i])) {
                return Err(SecularError::ModeOutOfRange(i));
            }
            if !(mc.f[i] != 0.0 && ok(mc.f[i])) {
                return Err(SecularError::ModeNotCoupled(i));
            }
        }
        let mut factors: Vec<Factor> = (0..n)
            .map(|i| Factor {
                p: mode_poles(mc.omega[i], mc.sigma[i]),
                g: mc.f[i] * mc.f[i],
            })
            .collect();
        factors.push(Factor {
            p: [C::new(0.0, 0.0); 2],
            g: 1.0 / mc.m_h,
        });
        // Equal poles of two modes: a combination of them does not couple, and
        // its eigenvector is not of the closed form (deflation would be needed).
        let mut poles: Vec<(f64, f64)> = factors[..n]
            .iter()
            .flat_map(|f| f.p.iter().map(|p| (p.re, p.im)))
            .collect();
        poles.sort_by(|x, y| x.1.total_cmp(&y.1).then(x.0.total_cmp(&y.0)));
        for w in poles.windows(2) {
            let (a, b) = (C::new(w[0].0, w[0].1), C::new(w[1].0, w[1].1));
            if (a - b).norm() <= 1e-12 * a.norm().max(b.norm()) {
                return Err(SecularError::SharedPole);
            }
        }
        Ok(Problem {
            factors,
            k: mc.k,
            c: mc.c,
        })
    }
}

/// The `2 n + 2` roots of `P` by Aberth-Ehrlich iteration (Gauss-Seidel
/// order), started from every mode's poles and the hammer's pair at the
/// rigid contact frequency.
fn solve_roots(prob: &Problem, mc: &ModalContact) -> Result<Vec<Root>, SecularError> {
    let n = mc.omega.len();
    let dim = 2 * n + 2;
    let mut roots: Vec<Root> = Vec::with_capacity(dim);
    for j in 0..n {
        for a in 0..2 {
            roots.push(Root {
                j,
                a,
                delta: C::new(0.0, 0.0),
            });
        }
    }
    let g_sum: f64 = 1.0 / mc.m_h + mc.f.iter().map(|f| f * f).sum::<f64>();
    let w_h = (mc.k * g_sum).sqrt();
    for sign in [1.0, -1.0] {
        let mut r = Root {
            j: n,
            a: 0,
            delta: C::new(-0.5 * mc.c * g_sum, sign * w_h),
        };
        prob.reanchor(&mut r);
        roots.push(r);
    }

    let mut converged = vec![false; dim];
    let mut sweeps = 0;
    let mut polish = 0;
    while sweeps < MAX_SWEEPS && polish < POLISH_SWEEPS {
        if converged.iter().all(|&c| c) {
            polish += 1;
        }
        sweeps += 1;
        for i in 0..dim {
            let ri = roots[i];
            let pi = prob.pole(&ri);
            let mut sum = C::new(0.0, 0.0);
            for (m, rm) in roots.iter().enumerate() {
                if m != i {
                    let diff = (pi - prob.pole(rm)) + (ri.delta - rm.delta);
                    sum += diff.inv();
                }
            }
            let newton = prob.newton(&ri);
            let w = newton / (C::new(1.0, 0.0) - newton * sum);
            if !(w.re.is_finite() && w.im.is_finite()) {
                return Err(SecularError::IterationBrokeDown { sweep: sweeps });
            }
            // converged: the step is tiny against the distance to the pole,
            // or below the root's own rounding (8 ulps)
            let tol = (REL_STEP * ri.delta.norm()).max(8.0 * f64::EPSILON * prob.z(&ri).norm());
            converged[i] |= w.norm() <= tol;
            let r = &mut roots[i];
            r.delta -= w;
            prob.reanchor(r);
        }
    }
    if converged.iter().any(|c| !c) {
        return Err(SecularError::NotConverged {
            count: converged.iter().filter(|c| !**c).count(),
            of: dim,
            sweeps,
        });
    }
    Ok(roots)
}

/// The eigenvector of root `r` in energy coordinates, unnormalised (force
/// 1, times the anchor's factor).
fn eigenvector(prob: &Problem, mc: &ModalContact, r: &Root) -> Vec<C> {
    let n = mc.omega.len();
    let base = prob.pole(r);
    let z = base + r.delta;
    let fj = &prob.factors[r.j];
    let (dj, _) = fj.eval_anchored(r.a, r.delta);
    let mut v = vec![C::new(0.0, 0.0); 2 * n + 2];
    for i in 0..n {
        // D_j / D_i (1 for the anchor)
        let ratio = if i == r.j {
            C::new(1.0, 0.0)
        } else {
            dj / prob.factors[i].eval_at(base, r.delta).0
        };
        v[i] = ratio * (-mc.f[i] * mc.omega[i]);
        v[n + 1 + i] = ratio * z * (-mc.f[i]);
    }
    v[n] = dj * mc.k.sqrt() / (C::new(mc.k, 0.0) + z * mc.c);
    v[2 * n + 1] = dj / (z * mc.m_h.sqrt());
    v
}

/// `v / |v|`.
fn unit(mut v: Vec<C>) -> Vec<C> {
    let norm = v.iter().map(|x| x.norm_sqr()).sum::<f64>().sqrt();
    for x in v.iter_mut() {
        *x /= norm;
    }
    v
}

/// `v^T J v` (bilinear): positions (the first `n + 1` entries) minus
/// momenta.
fn jnorm(v: &[C], n: usize) -> C {
    let mut acc = C::new(0.0, 0.0);
    for (i, x) in v.iter().enumerate() {
        if i <= n {
            acc += x * x;
        } else {
            acc -= x * x;
        }
    }
    acc
}

/// A complex root (upper half plane) and a real root, each with its root
/// and unit eigenvector.
type ComplexPair = (C, Root, Vec<C>);
type RealRoot = (f64, Root, Vec<C>);

/// The roots' unit eigenvectors: one per conjugate pair (its upper
/// member) and one per real root (polished on the real axis), the real ones
/// sorted. Passivity is exact: no eigenvalue of the contact phase has a
/// positive real part, and a lossless one has none at all (A is skew);
/// rounding may leave +-1e-16 |z|, which is removed here.
fn eigenpairs(
    prob: &Problem,
    mc: &ModalContact,
    roots: &[Root],
) -> Result<(Vec<ComplexPair>, Vec<RealRoot>), SecularError> {
    let lossless = mc.c == 0.0 && mc.sigma.iter().all(|&s| s == 0.0);
    let mut complex: Vec<ComplexPair> = Vec::new();
    let mut real: Vec<RealRoot> = Vec::new();
    let mut n_lower = 0;
    for r in roots {
        let mut z = prob.z(r);
        if lossless {
            z.re = 0.0;
        } else {
            z.re = z.re.min(0.0);
        }
        if z.im.abs() <= REAL_TOL * z.norm() {
            // On the real axis: polish there by Newton (no deflation needed
            // this close), keeping the offset from the pole (not the root
            // itself) exact, so that the root and its vector are real.
            let mut rr = *r;
            rr.delta.im = -prob.pole(&rr).im;
            for _ in 0..3 {
                rr.delta.re -= prob.newton(&rr).re;
            }
            real.push((
                prob.z(&rr).re.min(0.0),
                rr,
                unit(eigenvector(prob, mc, &rr)),
            ));
        } else if z.im > 0.0 {
            complex.push((z, *r, unit(eigenvector(prob, mc, r))));
        } else {
            n_lower += 1;
        }
    }
    if n_lower != complex.len() || !real.len().is_multiple_of(2) {
        return Err(SecularError::NotConjugate {
            upper: complex.len(),
            lower: n_lower,
            real: real.len(),
        });
    }
    real.sort_by(|x, y| x.0.total_cmp(&y.0));
    Ok((complex, real))
}

/// The real roots in pairs `(i, j, near_critical)`: adjacent roots within
/// [`NEAR_CRITICAL_GAP`] of each other and ill-conditioned are paired as
/// near critical, the others in order.
fn real_pairs(real: &[RealRoot], n: usize) -> Vec<(usize, usize, bool)> {
    let cond = |v: &[C]| 1.0 / jnorm(v, n).norm();
    let mut pairs = Vec::new();
    let mut used = vec![false; real.len()];
    for i in 0..real.len().saturating_sub(1) {
        if used[i] || used[i + 1] {
            continue;
        }
        let (z1, z2) = (real[i].0, real[i + 1].0);
        let close = (z1 - z2).abs() < NEAR_CRITICAL_GAP * z1.abs().max(z2.abs());
        let ill = cond(&real[i].2).max(cond(&real[i + 1].2)) > NEAR_CRITICAL_COND;
        if close && ill {
            used[i] = true;
            used[i + 1] = true;
            pairs.push((i, i + 1, true));
        }
    }
    let rest: Vec<usize> = (0..real.len()).filter(|&i| !used[i]).collect();
    for ch in rest.chunks(2) {
        pairs.push((ch[0], ch[1], false));
    }
    pairs
}

/// The blocks, `V` and `V^{-1}` as they are filled, block by block.
///
/// Each row of `V^-1` is `J v_j / (v_j^T J v_j)`; with `|v_j| = 1`,
/// `1 / |v_j^T J v_j|` is the condition number of eigenvalue `j`, and the
/// row's rounding error grows with it (the propagator's with its product
/// with `kappa(V)`). Past [`ROW_COND_MAX`] the inverse is taken by LU
/// instead (O(N^3), but one blocked factorisation, far cheaper than the
/// eigensolver).
struct Assembly {
    gens: Vec<Mat2>,
    v: DMatrix<f64>,
    vinv: DMatrix<f64>,
    worst_cond: f64,
    nb: usize,
}

impl Assembly {
    fn new(dim: usize) -> Self {
        Self {
            gens: Vec::with_capacity(dim / 2),
            v: DMatrix::zeros(dim, dim),
            vinv: DMatrix::zeros(dim, dim),
            worst_cond: 1.0,
            nb: dim / 2,
        }
    }

    /// `+1` on positions, `-1` on momenta (the diagonal of `J`).
    fn sign(i: usize, n: usize) -> f64 {
        if i <= n {
            1.0
        } else {
            -1.0
        }
    }

    /// A near-critical pair: the orthonormal basis of its invariant
    /// subspace instead of its (nearly parallel) eigenvectors.
    fn put_near_critical(
        &mut self,
        prob: &Problem,
        mc: &ModalContact,
        r: &Root,
        z1: C,
        z2: C,
    ) -> Result<(), SecularError> {
        let (kb, nb) = (self.gens.len(), self.nb);
        let (g, q, rows) = pair_basis(prob, mc, r, z1, z2)?;
        for i in 0..2 * nb {
            self.v[(i, kb)] = q[0][i];
            self.v[(i, nb + kb)] = q[1][i];
            self.vinv[(kb, i)] = rows[0][i];
            self.vinv[(nb + kb, i)] = rows[1][i];
        }
        self.gens.push(g);
        Ok(())
    }

    /// A conjugate pair `z, conj z` as one real block on `sqrt(2) (Re v,
    /// Im v)` (near critical: [`Assembly::put_near_critical`]).
    fn put_conjugate_pair(
        &mut self,
        prob: &Problem,
        mc: &ModalContact,
        r: &Root,
        z: C,
        ev: &[C],
    ) -> Result<(), SecularError> {
        let n = mc.omega.len();
        let nj = jnorm(ev, n);
        if !(nj.norm() > 0.0) || 1.0 / nj.norm() > NEAR_CRITICAL_COND {
            return self.put_near_critical(prob, mc, r, z, z.conj());
        }
        let (kb, nb) = (self.gens.len(), self.nb);
        let s2 = std::f64::consts::SQRT_2;
        self.worst_cond = self.worst_cond.max(1.0 / nj.norm());
        let inv_n = nj.inv();
        for i in 0..2 * nb {
            self.v[(i, kb)] = s2 * ev[i].re;
            self.v[(i, nb + kb)] = s2 * ev[i].im;
            let w = ev[i] * Self::sign(i, n) * inv_n;
            self.vinv[(kb, i)] = s2 * w.re;
            self.vinv[(nb + kb, i)] = -s2 * w.im;
        }
        self.gens.push([z.re, z.im, -z.im, z.re]);
        Ok(())
    }

    /// Two well-separated real roots as one diagonal block.
    fn put_real_pair(
        &mut self,
        n: usize,
        first: &RealRoot,
        second: &RealRoot,
    ) -> Result<(), SecularError> {
        let (kb, nb) = (self.gens.len(), self.nb);
        for (col, (_, _, ev)) in [(kb, first), (nb + kb, second)] {
            let nj = jnorm(ev, n).re;
            if !(nj.abs() > 0.0) {
                return Err(SecularError::Defective);
            }
            self.worst_cond = self.worst_cond.max(1.0 / nj.abs());
            for i in 0..2 * nb {
                self.v[(i, col)] = ev[i].re;
                self.vinv[(col, i)] = ev[i].re * Self::sign(i, n) / nj;
            }
        }
        self.gens.push([first.0, 0.0, 0.0, second.0]);
        Ok(())
    }

    /// Checks finiteness; `V^{-1}` by LU when a row would be too
    /// ill-conditioned.
    fn finish(mut self) -> Result<BlockEigen, SecularError> {
        if self.v.iter().any(|x| !x.is_finite()) {
            return Err(SecularError::NotFinite("eigenvectors"));
        }
        if self.worst_cond > ROW_COND_MAX {
            self.vinv = crate::physics::linalg::inverse(&self.v).ok_or(SecularError::Singular)?;
        }
        if self.vinv.iter().any(|x| !x.is_finite()) {
            return Err(SecularError::NotFinite("inverse"));
        }
        Ok((self.gens, self.v, self.vinv))
    }
}

/// Eigenvalues whose condition number `1 / |v^T J v|` (unit `v`) exceeds
/// this, in a pair closer than [`NEAR_CRITICAL_GAP`], are near critical
/// damping: their eigenvectors are nearly parallel, so the pair is given
/// the orthonormal basis of its invariant subspace instead.
const NEAR_CRITICAL_COND: f64 = 8.0;
/// Real roots closer than this fraction of their size form one
/// near-critical pair.
const NEAR_CRITICAL_GAP: f64 = 0.5;

/// Coefficients (ascending powers) of a factor's polynomial `D(z)`.
fn factor_poly(f: &Factor) -> [f64; 3] {
    // (z - p0)(z - p1) = z^2 - (p0 + p1) z + p0 p1 (real: conjugate or real poles)
    let s = f.p[0] + f.p[1];
    let p = f.p[0] * f.p[1];
    [p.re, -s.re, 1.0]
}

/// Divided difference `(N(z)/D(z) - N(w)/D(w)) / (z - w)` of a ratio of
/// real polynomials at a pair `z, w` that is either conjugate or real,
/// from `s = z + w` and `p = z w` (both real) and `D(z) D(w)`:
/// `sum n_a d_b sgn(a - b) p^min(a,b) h_(|a-b|-1)(s, p) / (D(z) D(w))` with
/// `h` the complete homogeneous symmetric polynomials. No difference of
/// two nearly equal computed numbers is formed, so the result keeps full
/// relative precision as `w -> z` (critical damping).
fn divided_difference(num: &[f64], den: &[f64], s: f64, p: f64, dz_dw: f64) -> f64 {
    let h = |k: usize| match k {
        0 => 1.0,
        1 => s,
        2 => s * s - p,
        _ => s * (s * s - 2.0 * p),
    };
    let mut acc = 0.0;
    for (a, &na) in num.iter().enumerate() {
        if na == 0.0 {
            continue;
        }
        for (b, &db) in den.iter().enumerate() {
            if db == 0.0 || a == b {
                continue;
            }
            let (lo, gap) = (a.min(b), a.abs_diff(b));
            let sgn = if a > b { 1.0 } else { -1.0 };
            acc += sgn * na * db * p.powi(lo as i32) * h(gap - 1);
        }
    }
    acc / dz_dw
}

/// The orthonormal basis of the invariant subspace of a near-critical pair
/// of roots `z1, z2` (conjugate, or real), its 2x2 block, and the matching
/// rows of `V^-1`.
///
/// With `v(z)` the eigenvector family of [`decompose`] (analytic in `z`,
/// scaled by the anchor factor of `r`), `x = (v(z1) + v(z2)) / 2` and the
/// divided difference `d = (v(z1) - v(z2)) / (z1 - z2)` are real and span
/// the subspace; `A x = a x + e d`, `A d = x + a d` with `a = (z1 + z2) / 2`,
/// `e = ((z1 - z2) / 2)^2` (`-w^2` for a conjugate pair): at exactly
/// critical damping (`e = 0`) a Jordan block, which `exp2` steps exactly.
/// `d` comes entry by entry from [`divided_difference`], so the pair stays
/// accurate however close the roots are. Gram-Schmidt gives `Q = [x d]
/// R^-1` and the block `R G R^-1`; the left subspace is spanned by `J x`,
/// `J d` (`A^T = J A J`), and the rows are `(L Q)^-1 L`.
#[allow(clippy::type_complexity)]
fn pair_basis(
    prob: &Problem,
    mc: &ModalContact,
    r: &Root,
    z1: C,
    z2: C,
) -> Result<(Mat2, [Vec<f64>; 2], [Vec<f64>; 2]), SecularError> {
    let n = mc.omega.len();
    let dim = 2 * n + 2;
    let j = r.j;
    let dj = factor_poly(&prob.factors[j]);
    let (s, p) = ((z1 + z2).re, (z1 * z2).re);
    let eval = |c: &[f64], z: C| -> C {
        let mut acc = C::new(0.0, 0.0);
        for &x in c.iter().rev() {
            acc = acc * z + x;
        }
        acc
    };
    // D(z1) D(z2), real for a conjugate or real pair
    let prod = |c: &[f64]| (eval(c, z1) * eval(c, z2)).re;
    let mut x = vec![0.0; dim];
    let mut d = vec![0.0; dim];
    let sk = mc.k.sqrt();
    let sm = mc.m_h.sqrt();
    // x: the mean of the two eigenvectors (for a conjugate pair, the real
    // part), with the common anchor factor D_j.
    let mean = |num: &[f64], den: &[f64]| -> f64 {
        let a = eval(num, z1) / eval(den, z1);
        let b = eval(num, z2) / eval(den, z2);
        0.5 * (a + b).re
    };
    let zdj = [0.0, dj[0], dj[1], dj[2]];
    for i in 0..n {
        let (fi, wi) = (mc.f[i], mc.omega[i]);
        if i == j {
            // D_j / D_j = 1: xi = -f w, u = -f z
            x[i] = -fi * wi;
            x[n + 1 + i] = -fi * s * 0.5;
            d[i] = 0.0;
            d[n + 1 + i] = -fi;
        } else {
            let di = factor_poly(&prob.factors[i]);
            let dd_w = prod(&di);
            x[i] = -fi * wi * mean(&dj, &di);
            x[n + 1 + i] = -fi * mean(&zdj, &di);
            d[i] = -fi * wi * divided_difference(&dj, &di, s, p, dd_w);
            d[n + 1 + i] = -fi * divided_difference(&zdj, &di, s, p, dd_w);
        }
    }
    let kc = [mc.k, mc.c];
    x[n] = sk * mean(&dj, &kc);
    d[n] = sk * divided_difference(&dj, &kc, s, p, prod(&kc));
    let zz = [0.0, 1.0];
    x[2 * n + 1] = mean(&dj, &zz) / sm;
    d[2 * n + 1] = divided_difference(&dj, &zz, s, p, p) / sm;
    let a = 0.5 * s;
    let e = 0.25 * (z1 - z2).powi(2).re;
    orthonormal_pair(x, d, a, e, n)
}

/// The pair's basis `[x d]` with `A x = a x + e d`, `A d = x + a d`
/// orthonormalised (Gram-Schmidt twice): `Q`, the block `R G R^-1` and the
/// rows `(L Q)^-1 L` of `V^-1` with `L = [J x; J d]` (`J` flips the sign of
/// the momenta, which start at `n + 1`).
#[allow(clippy::type_complexity)]
fn orthonormal_pair(
    x: Vec<f64>,
    d: Vec<f64>,
    a: f64,
    e: f64,
    n: usize,
) -> Result<(Mat2, [Vec<f64>; 2], [Vec<f64>; 2]), SecularError> {
    let dim = x.len();
    // Gram-Schmidt (twice) on [x d]
    let dotv = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, w)| u * w).sum::<f64>();
    let nx = dotv(&x, &x).sqrt();
    let q1: Vec<f64> = x.iter().map(|t| t / nx).collect();
    let mut q2 = d.clone();
    let mut r12 = 0.0;
    for _ in 0..2 {
        let c = dotv(&q1, &q2);
        r12 += c;
        for (a, b) in q2.iter_mut().zip(&q1) {
            *a -= c * b;
        }
    }
    let r22 = dotv(&q2, &q2).sqrt();
    if !(nx > 0.0 && r22 > 1e-8 * dotv(&d, &d).sqrt() && r22.is_finite()) {
        return Err(SecularError::NoIndependentBasis);
    }
    for a in q2.iter_mut() {
        *a /= r22;
    }
    // block: R G R^-1, G = [[a, 1], [e, a]], R = [[nx, r12], [0, r22]]
    let rg = [nx * a + r12 * e, nx + r12 * a, r22 * e, r22 * a];
    let g = [
        rg[0] / nx,
        (rg[1] - rg[0] * r12 / nx) / r22,
        rg[2] / nx,
        (rg[3] - rg[2] * r12 / nx) / r22,
    ];
    // rows: (L Q)^-1 L with L = [J x; J d]
    let jv = |u: &[f64]| -> Vec<f64> {
        u.iter()
            .enumerate()
            .map(|(i, t)| if i <= n { *t } else { -*t })
            .collect()
    };
    let (l1, l2) = (jv(&x), jv(&d));
    let lq = [
        dotv(&l1, &q1),
        dotv(&l1, &q2),
        dotv(&l2, &q1),
        dotv(&l2, &q2),
    ];
    let det = lq[0] * lq[3] - lq[1] * lq[2];
    if !(det.abs() > 0.0 && det.is_finite()) {
        return Err(SecularError::SingularLeftBasis);
    }
    let inv = [lq[3] / det, -lq[1] / det, -lq[2] / det, lq[0] / det];
    let row1: Vec<f64> = (0..dim).map(|i| inv[0] * l1[i] + inv[1] * l2[i]).collect();
    let row2: Vec<f64> = (0..dim).map(|i| inv[2] * l1[i] + inv[3] * l2[i]).collect();
    Ok((g, [q1, q2], [row1, row2]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::decomp::{block_residual, blocks_to_dense, dense_exp};
    use crate::physics::model::{contact_system, ContactParams, ObjectModel};
    use crate::scene::{ModalSpec, ModeSpec, ObjectSpec};

    use crate::test_rng::TestRng as Rng;

    /// Log-uniform in [lo, hi].
    fn log_uniform(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
        lo * (hi / lo).powf(rng.unit())
    }

    struct Case {
        omega: Vec<f64>,
        sigma: Vec<f64>,
        f: Vec<f64>,
        k: f64,
        c: f64,
        m_h: f64,
    }

    impl Case {
        fn mc(&self) -> ModalContact<'_> {
            ModalContact {
                omega: &self.omega,
                sigma: &self.sigma,
                f: &self.f,
                k: self.k,
                c: self.c,
                m_h: self.m_h,
            }
        }
        /// The contact generator as the compiler builds it (from frequency
        /// and T60), and the case with the model's own omega and sigma.
        fn generator(&self) -> (DMatrix<f64>, Case) {
            let spec = ModalSpec {
                name: "o".into(),
                points: vec!["c".into()],
                mode: (0..self.omega.len())
                    .map(|i| ModeSpec {
                        freq_hz: self.omega[i] / (2.0 * std::f64::consts::PI),
                        t60_s: (self.sigma[i] > 0.0)
                            .then(|| crate::physics::model::LN_1000 / self.sigma[i]),
                        weights: vec![self.f[i]],
                    })
                    .collect(),
            };
            let obj = ObjectModel::from_spec(&ObjectSpec::Modal(spec)).unwrap();
            let blocks = obj.modal_blocks.clone().unwrap();
            let row = obj.point("c").unwrap().vel.clone();
            let p = ContactParams {
                k: self.k,
                c: self.c,
                m_h: self.m_h,
                g: 0.0,
            };
            let model = Case {
                omega: blocks.iter().map(|b| b[1]).collect(),
                sigma: blocks.iter().map(|b| -0.5 * b[3]).collect(),
                f: self.f.clone(),
                ..*self
            };
            (contact_system(&obj, Some(&row), &p).0, model)
        }
    }

    fn random_case(rng: &mut Rng, n: usize) -> Case {
        let mut omega: Vec<f64> = (0..n)
            .map(|_| 2.0 * std::f64::consts::PI * log_uniform(rng, 30.0, 20000.0))
            .collect();
        omega.sort_by(|a, b| a.total_cmp(b));
        let damping = rng.unit();
        let sigma = omega
            .iter()
            .map(|w| {
                if damping < 0.2 {
                    0.0
                } else if damping < 0.4 {
                    // some overdamped modes
                    w * log_uniform(rng, 1e-4, 5.0)
                } else {
                    w * log_uniform(rng, 1e-5, 1e-2)
                }
            })
            .collect::<Vec<_>>();
        let f = (0..n)
            .map(|_| {
                let s = if rng.unit() < 0.5 { -1.0 } else { 1.0 };
                s * log_uniform(rng, 1e-3, 5.0)
            })
            .collect();
        let m_h = log_uniform(rng, 1e-3, 3.0);
        let k = log_uniform(rng, 1e3, 1e9);
        let c = if rng.unit() < 0.3 {
            0.0
        } else {
            2.0 * (k * m_h).sqrt() * log_uniform(rng, 1e-3, 3.0)
        };
        Case {
            omega,
            sigma,
            f,
            k,
            c,
            m_h,
        }
    }

    /// Random scenes from 1 to 60 modes (undamped, lightly damped, partly
    /// overdamped; soft to stiff, light to heavy hammers): the secular
    /// decomposition is an eigendecomposition of the compiler's generator,
    /// its inverse is accurate, and its propagator matches the dense Pade
    /// exp(A h).
    #[test]
    fn matches_the_generator_on_random_scenes() {
        let mut rng = Rng(2024);
        let h = 1.0 / 44100.0;
        let (mut worst_res, mut worst_inv, mut worst_exp) = (0.0f64, 0.0f64, 0.0f64);
        let mut refused = Vec::new();
        let cases = 1000;
        for t in 0..cases {
            let n = [1, 2, 3, 5, 8, 20, 60][t % 7];
            let case = random_case(&mut rng, n);
            let (a, exact) = case.generator();
            let dim = a.nrows();
            let (gens, v, vinv) = match decompose(&exact.mc()) {
                Ok(d) => d,
                Err(e) => {
                    refused.push(format!("case {t} ({n} modes): {e}"));
                    continue;
                }
            };
            let res = block_residual(&a, &gens, &v);
            let inv = (&vinv * &v - DMatrix::identity(dim, dim)).norm() / (dim as f64).sqrt();
            let p = blocks_to_dense(&gens, &v, &vinv, h);
            let reference = dense_exp(&a, h).unwrap();
            let ah = (a.norm() * h).max(1.0);
            let exp_diff = (&p - &reference).norm() / reference.norm() / ah;
            worst_res = worst_res.max(res);
            worst_inv = worst_inv.max(inv);
            worst_exp = worst_exp.max(exp_diff);
            assert!(
                res < 1e-13,
                "case {t} ({n} modes): residual {res:e}\n{:?} {:?} {:?} k {} c {} m {}\n{gens:?}",
                exact.omega,
                exact.sigma,
                exact.f,
                exact.k,
                exact.c,
                exact.m_h
            );
            assert!(inv < 1e-11, "case {t} ({n} modes): |V^-1 V - I| {inv:e}");
            assert!(
                exp_diff < 1e-12,
                "case {t} ({n} modes): propagator off by {exp_diff:e}"
            );
        }
        println!(
            "secular route on {cases} random scenes: worst residual {worst_res:.1e}, \
             |V^-1 V - I| {worst_inv:.1e}, |P - exp(A h)| / max(1, |A h|) {worst_exp:.1e}; \
             refused {}: {refused:?}",
            refused.len()
        );
        // refusals go to the general eigensolver; they must stay rare
        assert!(refused.len() <= cases / 50, "{refused:?}");
    }

    #[test]
    fn lossless_contact_has_imaginary_eigenvalues_and_an_orthogonal_basis() {
        let case = Case {
            omega: vec![1000.0, 2500.0, 7000.0],
            sigma: vec![0.0; 3],
            f: vec![1.0, -0.5, 0.8],
            k: 1e6,
            c: 0.0,
            m_h: 0.02,
        };
        let (gens, v, vinv) = decompose(&case.mc()).unwrap();
        assert!(gens.iter().all(|g| g[0] == 0.0 && g[3] == 0.0), "{gens:?}");
        let dev = (&vinv - v.transpose()).norm() / v.norm();
        println!("lossless: |V^-1 - V^T| / |V| = {dev:.1e}");
        assert!(dev < 1e-13);
    }

    #[test]
    fn equal_modes_are_left_to_the_general_solver() {
        let case = Case {
            omega: vec![1000.0, 1000.0],
            sigma: vec![2.0, 2.0],
            f: vec![1.0, 0.7],
            k: 1e6,
            c: 3.0,
            m_h: 0.02,
        };
        let e = decompose(&case.mc()).unwrap_err();
        assert_eq!(e, SecularError::SharedPole, "{e}");
    }
}
