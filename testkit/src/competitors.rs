//! The usual numerical integrators, as competitors for the "error against run
//! time" report (`cargo xtask report`, docs/report.md): symplectic Euler, Stormer-Verlet,
//! classic RK4 and the trapezoidal rule with active-set re-solve, all on the
//! same piecewise-linear (PWL) contact model and the same scenes as the exact
//! engine.
//!
//! # Model
//!
//! The struck object is taken from [`ObjectModel::from_spec`] in energy
//! coordinates `z = [xi; u]` (`n` positions `xi`, `n` velocities `u`, energy
//! `0.5 |z|^2`) with generator `A = [[0, B], [-B^T, -D]]`. The hammer adds its
//! height `x_h` and velocity `v_h`. The state used here is
//! `s = [xi (n); u (n); x_h; v_h]` (dimension `2 n + 2`). With
//! `p = d . xi - x_h` (`d` = contact point's displacement row) and
//! `p' = f . u - v_h` (`f` = contact point's velocity row = force input):
//!
//! ```text
//! F   = k p + c p'  if p > 0,  else 0        (force on the hammer, up)
//! xi' = B u
//! u'  = -B^T xi - D u - f F
//! x_h' = v_h,   v_h' = F / m_h - g
//! E   = 0.5 |z|^2 + 0.5 m_h v_h^2 + m_h g x_h + (0.5 k p^2 if p > 0)
//! ```
//!
//! Every method steps at `h = 1 / (rate_hz * oversample)` and the outputs are
//! the fine states *sampled* (not filtered) every `oversample`-th step, so all
//! methods land on the same output grid as the exact engine.
//!
//! # Methods
//!
//! - [`Method::SymplecticEuler`]: kick then drift. All forces (object
//!   stiffness `-B^T xi`, object damping `-D u`, contact `k p^+ + c p' [p > 0]`)
//!   are evaluated at the old state `(xi_n, u_n, x_h, v_h)`; then the positions
//!   advance with the new velocities. First order (damping and the position
//!   offset both give O(h)); for an undamped mode stable iff `omega h <= 2`.
//! - [`Method::StormerVerlet`]: velocity Verlet (kick-drift-kick). The first
//!   half-kick uses the full acceleration at `(x_n, v_n)`. In the second
//!   half-kick the position-dependent forces (stiffness, contact spring, contact
//!   test `p(x_{n+1}) > 0`) are taken at `x_{n+1}`, and the velocity-dependent
//!   ones (object damping `-D u`, contact damper `c p'`) at the explicit Euler
//!   prediction `v_hat = v_n + h a_n = 2 v_{n+1/2} - v_n`. That keeps the step
//!   explicit and second order with damping (using `v_{n+1/2}` there instead
//!   would make the damping first order); without damping it is exactly the
//!   textbook velocity Verlet (symplectic, stable iff `omega h <= 2`). The
//!   position-dependent part at `x_{n+1}` is cached for the next step.
//! - [`Method::Rk4`]: classic four-stage Runge-Kutta on the first-order PWL
//!   system, the contact test `p > 0` evaluated at every stage. Fourth order
//!   away from switches; for an undamped mode stable iff `omega h <= 2 sqrt 2`.
//! - [`Method::Trapezoid`]: in each step one contact state `sigma` (free or
//!   contact) holds on the whole step, and the step is the trapezoidal rule
//!   (bilinear transform, Cayley map) of that linear phase:
//!   `(I - h/2 A_sigma) s1 = (I + h/2 A_sigma) s0 + h b`, precomputed per phase
//!   as `s1 = M_sigma s0 + c_sigma` (one dense, or sparse when that is cheaper,
//!   mat-vec per solve; no factorisation in the loop). **Consistency rule:**
//!   `sigma = contact` is accepted iff the step's *average* penetration is
//!   positive, `(p(s0) + p(s1)) / 2 > 0`, and `sigma = free` iff it is `<= 0`
//!   (the trapezoid's own estimate of the step-mean penetration, so switches
//!   are not biased towards either end of the step; the end-of-step rule would
//!   start and end every contact half a step early on average). The first
//!   guess is the predicted average penetration `p0 + h/2 p0' > 0`; if the
//!   solution is inconsistent the other phase is solved (2 tries at most). If
//!   neither is consistent (free penetrates on average, contact already pushes
//!   out within the step: a contact shorter than a step) the contact solution is
//!   taken, so an impact is never skipped; such steps are counted in
//!   [`SimOutput::ambiguous_steps`]. Each phase step conserves that phase's
//!   energy to round-off (undamped) or dissipates it; a switch adds or removes
//!   the spring energy `0.5 k p^2` at the switching state (O((h v)^2 k)).
//!   A-stable: bounded for every `omega h`.
//!
//! Allocation happens only in [`PwlSystem::from_scene`] and at the start of
//! [`simulate`]; the step loops are allocation-free. The object's blocks are
//! stored sparse (CSR), so SE, Verlet and RK4 cost O(nnz) per step (O(n) for
//! modal objects and strings); the trapezoid costs one O(N^2) mat-vec per
//! solve (O(N) for a free modal object, whose step matrix is block-diagonal).

use modal_contact::physics::model::ObjectModel;
use modal_contact::scene::{Quantity, Scene};
use nalgebra::{DMatrix, DVector};

/// Compressed sparse row matrix; exact zeros are dropped.
#[derive(Debug, Clone)]
struct Csr {
    ptr: Vec<usize>,
    col: Vec<usize>,
    val: Vec<f64>,
}

impl Csr {
    fn from_dense(m: &DMatrix<f64>) -> Self {
        let mut ptr = Vec::with_capacity(m.nrows() + 1);
        let mut col = Vec::new();
        let mut val = Vec::new();
        ptr.push(0);
        for i in 0..m.nrows() {
            for j in 0..m.ncols() {
                let v = m[(i, j)];
                if v != 0.0 {
                    col.push(j);
                    val.push(v);
                }
            }
            ptr.push(col.len());
        }
        Self { ptr, col, val }
    }

    /// Row `i` dotted with `x`.
    #[inline]
    fn row_dot(&self, i: usize, x: &[f64]) -> f64 {
        let (a, b) = (self.ptr[i], self.ptr[i + 1]);
        let mut acc = 0.0;
        for (c, v) in self.col[a..b].iter().zip(&self.val[a..b]) {
            acc += v * x[*c];
        }
        acc
    }

    /// `y = M x`.
    #[inline]
    fn mul_into(&self, x: &[f64], y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate() {
            *yi = self.row_dot(i, x);
        }
    }

    /// `y += M x`.
    #[inline]
    fn mul_add_into(&self, x: &[f64], y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate() {
            *yi += self.row_dot(i, x);
        }
    }
}

/// A linear map stored dense (row-major) or sparse, whichever is cheaper.
#[derive(Debug, Clone)]
enum LinOp {
    Dense { ncols: usize, val: Vec<f64> },
    Sparse(Csr),
}

impl LinOp {
    fn from_dense(m: &DMatrix<f64>) -> Self {
        let nnz = m.iter().filter(|v| **v != 0.0).count();
        if 3 * nnz < m.nrows() * m.ncols() {
            LinOp::Sparse(Csr::from_dense(m))
        } else {
            let mut val = Vec::with_capacity(m.nrows() * m.ncols());
            for i in 0..m.nrows() {
                for j in 0..m.ncols() {
                    val.push(m[(i, j)]);
                }
            }
            LinOp::Dense {
                ncols: m.ncols(),
                val,
            }
        }
    }

    /// `y = M x + c`.
    #[inline]
    fn affine_into(&self, x: &[f64], c: &[f64], y: &mut [f64]) {
        match self {
            LinOp::Dense { ncols, val } => {
                for (i, yi) in y.iter_mut().enumerate() {
                    let row = &val[i * ncols..(i + 1) * ncols];
                    // four accumulators: the loop is bound by add latency otherwise
                    let mut acc = [0.0f64; 4];
                    let (rc, rr) = row.split_at(ncols - ncols % 4);
                    let (xc, xr) = x[..*ncols].split_at(ncols - ncols % 4);
                    for (a, b) in rc.chunks_exact(4).zip(xc.chunks_exact(4)) {
                        for l in 0..4 {
                            acc[l] += a[l] * b[l];
                        }
                    }
                    let mut tail = c[i];
                    for (a, b) in rr.iter().zip(xr) {
                        tail += a * b;
                    }
                    *yi = tail + ((acc[0] + acc[1]) + (acc[2] + acc[3]));
                }
            }
            LinOp::Sparse(m) => {
                y.copy_from_slice(c);
                m.mul_add_into(x, y);
            }
        }
    }
}

/// Sparse vector: (index, value) of the non-zeros.
type SpVec = Vec<(usize, f64)>;

#[inline]
fn sp_dot(v: &SpVec, x: &[f64]) -> f64 {
    v.iter().map(|&(i, a)| a * x[i]).sum()
}

/// The struck object, the hammer and the PWL contact of one scene, with the
/// matrices the competitors need precomputed.
#[derive(Debug, Clone)]
pub struct PwlSystem {
    /// Object degrees of freedom (`z` has `2 n` entries; 0 for a wall).
    n: usize,
    /// Object generator over `z` (2n x 2n).
    a_obj: DMatrix<f64>,
    /// `B` (xi' = B u), `-B^T`, `-D` as sparse blocks.
    a_xiu: Csr,
    a_uxi: Csr,
    a_uu: Csr,
    /// Contact point displacement row over `xi` (sparse).
    d_xi: SpVec,
    /// Contact point velocity row over `u` = force input (sparse).
    f_u: SpVec,
    /// Gain-weighted sum of the pickup rows over `z` (dense, 2n).
    pick: Vec<f64>,
    /// Contact stiffness [N/m].
    pub k: f64,
    /// Contact damping [N s/m].
    pub c: f64,
    /// Hammer mass \[kg\].
    pub m_h: f64,
    /// Gravity on the hammer [m/s^2] (pulls down).
    pub g: f64,
    /// Initial object state `z0 = [xi; u]` (zeros from a scene: at rest).
    /// Tests may set it to start the object vibrating.
    pub z0: Vec<f64>,
    /// Initial hammer height \[m\].
    pub x_h0: f64,
    /// Initial hammer velocity [m/s] (positive up).
    pub v_h0: f64,
}

impl PwlSystem {
    /// Build the system of `scene`'s contact object, hammer and contact.
    /// Pickups on other objects are silent (those objects are never excited);
    /// pan is ignored (mono, gain-weighted sum).
    pub fn from_scene(scene: &Scene) -> Result<Self, String> {
        let oi = scene
            .object_index(&scene.contact.object)
            .ok_or_else(|| format!("contact.object: no object {:?}", scene.contact.object))?;
        let obj = ObjectModel::from_spec(&scene.object[oi]).map_err(|e| e.to_string())?;
        let n = obj.n;
        let (disp, vel) = match &scene.contact.point {
            Some(name) if n > 0 => {
                let pr = obj
                    .point(name)
                    .ok_or_else(|| format!("contact.point: no point {name:?}"))?;
                (pr.disp.clone(), pr.vel.clone())
            }
            _ => (DVector::zeros(2 * n), DVector::zeros(2 * n)),
        };
        // The position/velocity split needs A = [[0, B], [-B^T, -D]], a
        // displacement row over xi only and a velocity row over u only.
        for i in 0..n {
            for j in 0..n {
                if obj.a[(i, j)] != 0.0 {
                    return Err(format!(
                        "object generator has a non-zero xi-xi entry ({i}, {j})"
                    ));
                }
            }
            if disp[n + i] != 0.0 || vel[i] != 0.0 {
                return Err("contact rows are not of position/velocity form".into());
            }
        }
        let block = |r0: usize, c0: usize| -> Csr {
            Csr::from_dense(&obj.a.view((r0, c0), (n, n)).into_owned())
        };
        let sp = |v: &[f64]| -> SpVec {
            v.iter()
                .enumerate()
                .filter(|(_, a)| **a != 0.0)
                .map(|(i, a)| (i, *a))
                .collect()
        };
        let d_xi = sp(&disp.as_slice()[..n]);
        let f_u = sp(&vel.as_slice()[n..]);
        let mut pick = vec![0.0; 2 * n];
        for p in &scene.pickup {
            if p.object != scene.contact.object || n == 0 {
                continue;
            }
            let pr = obj
                .point(&p.point)
                .ok_or_else(|| format!("pickup: no point {:?}", p.point))?;
            let row = match p.quantity {
                Quantity::Displacement => &pr.disp,
                Quantity::Velocity => &pr.vel,
                // none in an expanded scene (`Scene::expanded`)
                Quantity::Pressure => continue,
            };
            for (acc, r) in pick.iter_mut().zip(row.iter()) {
                *acc += p.gain * r;
            }
        }
        Ok(Self {
            n,
            a_xiu: block(0, n),
            a_uxi: block(n, 0),
            a_uu: block(n, n),
            a_obj: obj.a,
            d_xi,
            f_u,
            pick,
            k: scene.contact.stiffness_n_per_m,
            c: scene.contact.damping_n_s_per_m,
            m_h: scene.hammer.mass_kg,
            g: scene.hammer.gravity_m_per_s2,
            z0: vec![0.0; 2 * n],
            x_h0: scene.hammer.height_m,
            v_h0: scene.hammer.velocity_m_per_s,
        })
    }

    /// Object degrees of freedom (`z` has `2 n` entries).
    pub fn n(&self) -> usize {
        self.n
    }

    /// Non-zeros of the sparse blocks `(B, -B^T, -D)` and of the contact rows
    /// `(d, f)`: the per-step cost of the explicit methods.
    pub fn nnz(&self) -> (usize, usize, usize, usize, usize) {
        (
            self.a_xiu.val.len(),
            self.a_uxi.val.len(),
            self.a_uu.val.len(),
            self.d_xi.len(),
            self.f_u.len(),
        )
    }

    /// Dimension of the full state `s = [xi; u; x_h; v_h]`.
    pub fn dim(&self) -> usize {
        2 * self.n + 2
    }

    /// Initial full state `[z0; x_h0; v_h0]`.
    pub fn initial_state(&self) -> Vec<f64> {
        let mut s = self.z0.clone();
        s.push(self.x_h0);
        s.push(self.v_h0);
        s
    }

    /// Penetration `p = x_c - x_h` of a full state.
    #[inline]
    pub fn penetration(&self, s: &[f64]) -> f64 {
        sp_dot(&self.d_xi, s) - s[2 * self.n]
    }

    /// Penetration rate `p' = v_c - v_h` of a full state.
    #[inline]
    pub fn penetration_rate(&self, s: &[f64]) -> f64 {
        sp_dot(&self.f_u, &s[self.n..]) - s[2 * self.n + 1]
    }

    /// Mixed pickup signal of a full state.
    #[inline]
    pub fn pickup(&self, s: &[f64]) -> f64 {
        self.pick.iter().zip(s).map(|(a, b)| a * b).sum()
    }

    /// Energy and penetration of a full state (docs/design.md, "Conventions
    /// and units"; gravity potential zero at `x_h = 0`).
    #[inline]
    pub fn energy_and_penetration(&self, s: &[f64]) -> (f64, f64) {
        let n2 = 2 * self.n;
        let obj: f64 = s[..n2].iter().map(|v| v * v).sum();
        let (xh, vh) = (s[n2], s[n2 + 1]);
        let p = self.penetration(s);
        let spring = if p > 0.0 { 0.5 * self.k * p * p } else { 0.0 };
        (
            0.5 * obj + 0.5 * self.m_h * vh * vh + self.m_h * self.g * xh + spring,
            p,
        )
    }

    /// Contact force on the hammer (up) for penetration `p` and rate `pd`.
    #[inline]
    fn force(&self, p: f64, pd: f64) -> f64 {
        if p > 0.0 {
            self.k * p + self.c * pd
        } else {
            0.0
        }
    }

    /// Dense first-order generator and forcing of one phase over
    /// `s = [xi; u; x_h; v_h]`: `s' = A s + b`.
    pub fn phase_system(&self, contact: bool) -> (DMatrix<f64>, DVector<f64>) {
        let n = self.n;
        let dim = self.dim();
        let (ih, iv) = (2 * n, 2 * n + 1);
        let mut a = DMatrix::zeros(dim, dim);
        a.view_mut((0, 0), (2 * n, 2 * n)).copy_from(&self.a_obj);
        a[(ih, iv)] = 1.0;
        if contact {
            let (k, c, m) = (self.k, self.c, self.m_h);
            // F = k (d . xi - x_h) + c (f . u - v_h)
            let mut frow = vec![0.0; dim];
            for &(j, dj) in &self.d_xi {
                frow[j] += k * dj;
            }
            for &(j, fj) in &self.f_u {
                frow[n + j] += c * fj;
            }
            frow[ih] -= k;
            frow[iv] -= c;
            for &(i, fi) in &self.f_u {
                for (j, fr) in frow.iter().enumerate() {
                    a[(n + i, j)] -= fi * fr;
                }
            }
            for (j, fr) in frow.iter().enumerate() {
                a[(iv, j)] += fr / m;
            }
        }
        let mut b = DVector::zeros(dim);
        b[iv] = -self.g;
        (a, b)
    }
}

/// The competitor integrators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Symplectic (semi-implicit) Euler, kick then drift, forces explicit.
    SymplecticEuler,
    /// Velocity Verlet with explicit, second-order damping.
    StormerVerlet,
    /// Classic RK4 with the contact test at every stage.
    Rk4,
    /// Trapezoidal rule per linear phase with active-set re-solve.
    Trapezoid,
}

impl Method {
    /// All methods, in report order.
    pub const ALL: [Method; 4] = [
        Method::SymplecticEuler,
        Method::StormerVerlet,
        Method::Rk4,
        Method::Trapezoid,
    ];

    /// Short name for tables and plots.
    pub fn name(self) -> &'static str {
        match self {
            Method::SymplecticEuler => "symplectic-euler",
            Method::StormerVerlet => "stormer-verlet",
            Method::Rk4 => "rk4",
            Method::Trapezoid => "trapezoid",
        }
    }
}

/// What [`simulate`] returns; all series are on the output grid (`rate_hz`),
/// row 0 the initial state.
#[derive(Debug, Clone, Default)]
pub struct SimOutput {
    /// Mono pickup mix (gain-weighted sum).
    pub pickup: Vec<f64>,
    /// Hammer height \[m\].
    pub x_hammer: Vec<f64>,
    /// Energy \[J\] (docs/design.md, "Conventions and units").
    pub energy: Vec<f64>,
    /// Contacts as (start, end) times \[s\] on the fine grid: start = first fine
    /// state with `p > 0`, end = first later fine state with `p <= 0`. A contact
    /// still open at the end (or at divergence) is closed at that time.
    pub contacts: Vec<(f64, f64)>,
    /// Max over fine steps of `(E_{n+1} - E_n) / E0`,
    /// `E0 = |E(0)| + m_h g |x_h(0)|` (can be negative if energy always falls).
    pub max_energy_increase: f64,
    /// A non-finite state or energy above `1e6 E0` was met; the run stopped
    /// there and the remaining outputs are NaN.
    pub diverged: bool,
    /// Fine steps taken.
    pub fine_steps: usize,
    /// Trapezoid only: steps that needed the second phase solve.
    pub resolves: usize,
    /// Trapezoid only: steps where neither phase was consistent (the contact
    /// solution was taken).
    pub ambiguous_steps: usize,
}

/// One fine step of a method, in place on `s = [xi; u; x_h; v_h]`.
trait Stepper {
    fn step(&mut self, sys: &PwlSystem, s: &mut [f64]);
    fn counters(&self) -> (usize, usize) {
        (0, 0)
    }
}

struct SymplecticEuler {
    h: f64,
    acc: Vec<f64>,
    vel: Vec<f64>,
}

impl Stepper for SymplecticEuler {
    fn step(&mut self, sys: &PwlSystem, s: &mut [f64]) {
        let n = sys.n;
        let h = self.h;
        let (z, hv) = s.split_at_mut(2 * n);
        let (xi, u) = z.split_at_mut(n);
        let p = sp_dot(&sys.d_xi, xi) - hv[0];
        let pd = sp_dot(&sys.f_u, u) - hv[1];
        let f = sys.force(p, pd);
        // kick: u_{n+1} = u_n + h (-B^T xi_n - D u_n - f F_n)
        sys.a_uxi.mul_into(xi, &mut self.acc);
        sys.a_uu.mul_add_into(u, &mut self.acc);
        for &(i, fi) in &sys.f_u {
            self.acc[i] -= fi * f;
        }
        for (ui, ai) in u.iter_mut().zip(&self.acc) {
            *ui += h * ai;
        }
        hv[1] += h * (f / sys.m_h - sys.g);
        // drift with the new velocities
        sys.a_xiu.mul_into(u, &mut self.vel);
        for (x, v) in xi.iter_mut().zip(&self.vel) {
            *x += h * v;
        }
        hv[0] += h * hv[1];
    }
}

struct Verlet {
    h: f64,
    /// Cached `-B^T xi` and `p` at the current positions.
    pos_acc: Vec<f64>,
    p: f64,
    cached: bool,
    acc: Vec<f64>,
    u_hat: Vec<f64>,
    tmp: Vec<f64>,
}

impl Stepper for Verlet {
    fn step(&mut self, sys: &PwlSystem, s: &mut [f64]) {
        let n = sys.n;
        let h = self.h;
        let hh = 0.5 * h;
        let (z, hv) = s.split_at_mut(2 * n);
        let (xi, u) = z.split_at_mut(n);
        if !self.cached {
            sys.a_uxi.mul_into(xi, &mut self.pos_acc);
            self.p = sp_dot(&sys.d_xi, xi) - hv[0];
            self.cached = true;
        }
        // full acceleration at (x_n, v_n)
        let f = sys.force(self.p, sp_dot(&sys.f_u, u) - hv[1]);
        sys.a_uu.mul_into(u, &mut self.acc);
        for (a, pa) in self.acc.iter_mut().zip(&self.pos_acc) {
            *a += pa;
        }
        for &(i, fi) in &sys.f_u {
            self.acc[i] -= fi * f;
        }
        let ah = f / sys.m_h - sys.g;
        // Euler prediction (for the velocity-dependent forces of the second
        // half-kick) and first half-kick
        for ((uh, ui), a) in self.u_hat.iter_mut().zip(u.iter_mut()).zip(&self.acc) {
            *uh = *ui + h * a;
            *ui += hh * a;
        }
        let vh_hat = hv[1] + h * ah;
        hv[1] += hh * ah;
        // drift
        sys.a_xiu.mul_into(u, &mut self.tmp);
        for (x, v) in xi.iter_mut().zip(&self.tmp) {
            *x += h * v;
        }
        hv[0] += h * hv[1];
        // position-dependent forces at x_{n+1} (cached for the next step)
        sys.a_uxi.mul_into(xi, &mut self.pos_acc);
        self.p = sp_dot(&sys.d_xi, xi) - hv[0];
        // second half-kick: velocity-dependent forces at the prediction
        let f1 = sys.force(self.p, sp_dot(&sys.f_u, &self.u_hat) - vh_hat);
        sys.a_uu.mul_into(&self.u_hat, &mut self.tmp);
        for ((ui, t), pa) in u.iter_mut().zip(&self.tmp).zip(&self.pos_acc) {
            *ui += hh * (t + pa);
        }
        for &(i, fi) in &sys.f_u {
            u[i] -= hh * fi * f1;
        }
        hv[1] += hh * (f1 / sys.m_h - sys.g);
    }
}

struct Rk4 {
    h: f64,
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
}

/// `out = f(s)`, the PWL vector field.
#[inline]
fn rhs(sys: &PwlSystem, s: &[f64], out: &mut [f64]) {
    let n = sys.n;
    let (xi, rest) = s.split_at(n);
    let (u, hv) = rest.split_at(n);
    let (oxi, orest) = out.split_at_mut(n);
    let (ou, ohv) = orest.split_at_mut(n);
    sys.a_xiu.mul_into(u, oxi);
    sys.a_uxi.mul_into(xi, ou);
    sys.a_uu.mul_add_into(u, ou);
    let p = sp_dot(&sys.d_xi, xi) - hv[0];
    let f = if p > 0.0 {
        let f = sys.k * p + sys.c * (sp_dot(&sys.f_u, u) - hv[1]);
        for &(i, fi) in &sys.f_u {
            ou[i] -= fi * f;
        }
        f
    } else {
        0.0
    };
    ohv[0] = hv[1];
    ohv[1] = f / sys.m_h - sys.g;
}

impl Stepper for Rk4 {
    fn step(&mut self, sys: &PwlSystem, s: &mut [f64]) {
        let h = self.h;
        let [k1, k2, k3, k4] = &mut self.k;
        let tmp = &mut self.tmp;
        rhs(sys, s, k1);
        for ((t, x), k) in tmp.iter_mut().zip(s.iter()).zip(k1.iter()) {
            *t = x + 0.5 * h * k;
        }
        rhs(sys, tmp, k2);
        for ((t, x), k) in tmp.iter_mut().zip(s.iter()).zip(k2.iter()) {
            *t = x + 0.5 * h * k;
        }
        rhs(sys, tmp, k3);
        for ((t, x), k) in tmp.iter_mut().zip(s.iter()).zip(k3.iter()) {
            *t = x + h * k;
        }
        rhs(sys, tmp, k4);
        let h6 = h / 6.0;
        for i in 0..s.len() {
            s[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        }
    }
}

struct Trapezoid {
    h: f64,
    /// `[free, contact]`: `s1 = M s0 + c`.
    m: [LinOp; 2],
    c: [Vec<f64>; 2],
    buf: [Vec<f64>; 2],
    resolves: usize,
    ambiguous: usize,
}

impl Trapezoid {
    fn new(sys: &PwlSystem, h: f64) -> Self {
        let dim = sys.dim();
        let mk = |contact: bool| -> (LinOp, Vec<f64>) {
            let (a, b) = sys.phase_system(contact);
            let id = DMatrix::<f64>::identity(dim, dim);
            let lhs = &id - &a * (0.5 * h);
            let rhs = &id + &a * (0.5 * h);
            let lu = lhs.lu();
            let m = lu
                .solve(&rhs)
                .expect("I - h/2 A is singular (A has an eigenvalue 2/h)");
            let c = lu.solve(&(b * h)).expect("I - h/2 A is singular");
            (LinOp::from_dense(&m), c.as_slice().to_vec())
        };
        let (mf, cf) = mk(false);
        let (mc, cc) = mk(true);
        Self {
            h,
            m: [mf, mc],
            c: [cf, cc],
            buf: [vec![0.0; dim], vec![0.0; dim]],
            resolves: 0,
            ambiguous: 0,
        }
    }
}

impl Stepper for Trapezoid {
    fn step(&mut self, sys: &PwlSystem, s: &mut [f64]) {
        let p0 = sys.penetration(s);
        let guess = p0 + 0.5 * self.h * sys.penetration_rate(s) > 0.0;
        let first = usize::from(guess);
        self.m[first].affine_into(s, &self.c[first], &mut self.buf[first]);
        let consistent = |p1: f64, contact: bool| (p0 + p1 > 0.0) == contact;
        if consistent(sys.penetration(&self.buf[first]), guess) {
            s.copy_from_slice(&self.buf[first]);
            return;
        }
        self.resolves += 1;
        let second = 1 - first;
        self.m[second].affine_into(s, &self.c[second], &mut self.buf[second]);
        if consistent(sys.penetration(&self.buf[second]), !guess) {
            s.copy_from_slice(&self.buf[second]);
        } else {
            // neither phase is consistent: take the contact solution
            self.ambiguous += 1;
            s.copy_from_slice(&self.buf[1]);
        }
    }

    fn counters(&self) -> (usize, usize) {
        (self.resolves, self.ambiguous)
    }
}

/// Simulate `sys` with `method` at `rate_hz * oversample` steps per second and
/// return `n_out` output rows on the `rate_hz` grid (row 0 = initial state,
/// row `j` = state after `j * oversample` fine steps, sampled, not filtered).
pub fn simulate(
    sys: &PwlSystem,
    method: Method,
    rate_hz: f64,
    oversample: usize,
    n_out: usize,
) -> SimOutput {
    assert!(rate_hz > 0.0 && rate_hz.is_finite(), "rate_hz must be > 0");
    assert!(oversample >= 1, "oversample must be >= 1");
    let h = 1.0 / (rate_hz * oversample as f64);
    let n = sys.n;
    match method {
        Method::SymplecticEuler => run(
            sys,
            SymplecticEuler {
                h,
                acc: vec![0.0; n],
                vel: vec![0.0; n],
            },
            h,
            oversample,
            n_out,
        ),
        Method::StormerVerlet => run(
            sys,
            Verlet {
                h,
                pos_acc: vec![0.0; n],
                p: 0.0,
                cached: false,
                acc: vec![0.0; n],
                u_hat: vec![0.0; n],
                tmp: vec![0.0; n],
            },
            h,
            oversample,
            n_out,
        ),
        Method::Rk4 => {
            let d = sys.dim();
            run(
                sys,
                Rk4 {
                    h,
                    k: [vec![0.0; d], vec![0.0; d], vec![0.0; d], vec![0.0; d]],
                    tmp: vec![0.0; d],
                },
                h,
                oversample,
                n_out,
            )
        }
        Method::Trapezoid => run(sys, Trapezoid::new(sys, h), h, oversample, n_out),
    }
}

fn run<S: Stepper>(
    sys: &PwlSystem,
    mut stepper: S,
    h: f64,
    oversample: usize,
    n_out: usize,
) -> SimOutput {
    let mut out = SimOutput {
        pickup: Vec::with_capacity(n_out),
        x_hammer: Vec::with_capacity(n_out),
        energy: Vec::with_capacity(n_out),
        contacts: Vec::new(),
        max_energy_increase: f64::NEG_INFINITY,
        ..Default::default()
    };
    if n_out == 0 {
        out.max_energy_increase = 0.0;
        return out;
    }
    let ih = 2 * sys.n;
    let mut s = sys.initial_state();
    let (e0, p0) = sys.energy_and_penetration(&s);
    let mut e_scale = e0.abs() + sys.m_h * sys.g * sys.x_h0.abs();
    if !(e_scale > 0.0) || !e_scale.is_finite() {
        e_scale = 1.0;
    }
    let limit = 1e6 * e_scale;
    out.pickup.push(sys.pickup(&s));
    out.x_hammer.push(s[ih]);
    out.energy.push(e0);
    let mut open: Option<f64> = if p0 > 0.0 { Some(0.0) } else { None };
    let mut e_prev = e0;
    let mut fine = 0usize;
    let mut diverged = !e0.is_finite();
    'outer: for _ in 1..n_out {
        if diverged {
            break;
        }
        for _ in 0..oversample {
            stepper.step(sys, &mut s);
            fine += 1;
            let (e, p) = sys.energy_and_penetration(&s);
            if !e.is_finite() || e > limit || !p.is_finite() {
                diverged = true;
                break 'outer;
            }
            let de = (e - e_prev) / e_scale;
            if de > out.max_energy_increase {
                out.max_energy_increase = de;
            }
            e_prev = e;
            let t = fine as f64 * h;
            match open {
                None if p > 0.0 => open = Some(t),
                Some(t0) if !(p > 0.0) => {
                    out.contacts.push((t0, t));
                    open = None;
                }
                _ => {}
            }
        }
        out.pickup.push(sys.pickup(&s));
        out.x_hammer.push(s[ih]);
        out.energy.push(e_prev);
    }
    if let Some(t0) = open {
        out.contacts.push((t0, fine as f64 * h));
    }
    out.diverged = diverged;
    out.fine_steps = fine;
    for v in [&mut out.pickup, &mut out.x_hammer, &mut out.energy] {
        v.resize(n_out, f64::NAN);
    }
    if out.max_energy_increase == f64::NEG_INFINITY {
        out.max_energy_increase = 0.0;
    }
    let (r, a) = stepper.counters();
    out.resolves = r;
    out.ambiguous_steps = a;
    out
}
