//! Modes of simple objects from geometry and material: frequencies,
//! mass-normalised mode shapes at any point, and decay times from a loss
//! model. Pure functions; nothing here knows about scenes.
//!
//! # Conventions
//!
//! A mode shape `Phi` is **mass normalised**: `integral rho Phi^2 dV = 1`
//! (for a bar `integral rho A Phi^2 dx = 1`, a plate `integral rho h Phi^2
//! dA = 1`, a membrane `integral sigma Phi^2 dA = 1`, a string `integral mu
//! Phi^2 dx = 1`), so `Phi` is in 1/sqrt(kg) and is directly the weight
//! `w_{p,i}` of docs/design.md section 2 (unit modal mass; a single mode of
//! weight `w` looks like a mass `1 / w^2` at that point). Signs of shapes are
//! arbitrary but fixed.
//!
//! Every kind lists its modes with [`Shape::modes`]`(max_freq_hz,
//! max_count)`: the modes of frequency `<= max_freq_hz`, lowest first, at
//! most `max_count` of them (`max_freq_hz` may be `+inf`; `max_count <=`
//! [`MAX_MODE_COUNT`]). Rigid-body modes (zero frequency) are never listed.
//!
//! # Bars and tubes (Euler-Bernoulli, optional Timoshenko correction)
//!
//! Points are [`Point::Bar`]`{ x, y }`: `x` along the axis in `[0, L]`, `y`
//! across the width from the centre line (`|y| <= b / 2` for a bar, `<= D /
//! 2` for a tube); [`Point::Line`]`(x)` is the point `(x, 0)`. Bending modes
//! do not depend on `y`; torsional modes (below) do.
//!
//! Length `L`, density `rho`, Young's modulus `E`, cross-section area `A`,
//! second moment `I` about the bending axis (rectangle of width `b` and
//! thickness `h` in the direction of vibration: `A = b h`, `I = b h^3 / 12`;
//! tube of outer and inner diameters `D`, `d`: `A = pi (D^2 - d^2) / 4`,
//! `I = pi (D^4 - d^4) / 64`). Radius of gyration `r^2 = I / A`.
//!
//! `omega_n = (beta_n L)^2 / L^2 * sqrt(E I / (rho A))`, with `u_n = beta_n
//! L` the `n`-th positive root of
//! - free-free: `cos u cosh u = 1` (`u_n -> (2n+1) pi/2`; 4.7300, 7.8532,
//!   10.9956, ...),
//! - clamped (`x = 0`) - free: `cos u cosh u = -1` (`u_n -> (2n-1) pi/2`;
//!   1.8751, 4.6941, 7.8548, ...),
//! - clamped-clamped (both ends clamped, e.g. a wood block's lips): `cos u
//!   cosh u = 1`, the same roots as free-free.
//!
//! Solved as `cos u -+ sech u = 0` (no overflow) by Newton's method from the
//! asymptote, safeguarded by bisection in the bracket `[n pi, (n+1) pi]`
//! (free-free, clamped-clamped) or `[(n-1) pi, n pi]` (clamped-free).
//!
//! Shapes (`xi = x / L`), normalised to `integral_0^L phi^2 dx = L`:
//! - free-free: `phi = cosh(u xi) + cos(u xi) - s (sinh(u xi) + sin(u xi))`,
//!   `s = (cosh u - cos u) / (sinh u - sin u)`;
//! - clamped-free: `phi = cosh(u xi) - cos(u xi) - s (sinh(u xi) - sin(u
//!   xi))`, `s = (cosh u + cos u) / (sinh u + sin u)`;
//! - clamped-clamped: `phi = cosh(u xi) - cos(u xi) - s (sinh(u xi) - sin(u
//!   xi))`, `s = (cosh u - cos u) / (sinh u - sin u)` (the free-free `s`:
//!   the clamped-clamped shape is `d^2 phi_ff / d xi^2 / u^2`, and is 0 with
//!   zero slope at both ends);
//!
//! and `Phi = phi / sqrt(rho A L)`. Evaluated in the overflow-free form
//! `phi = c_g exp(u (xi - 1)) + c_d exp(-u xi) + t (cos(u xi) - s sin(u
//! xi))`, where `cosh(u xi) - s sinh(u xi) = c_g exp(u (xi - 1)) + c_d
//! exp(-u xi)` with `c_g = (1 - s) e^u / 2`, `c_d = (1 + s) / 2`, and `t =
//! +1` (free-free) or `-1` (clamped-free, clamped-clamped). With `E1 =
//! exp(-u)`, multiplying numerator and denominator of `s` by `2 E1`:
//! - free-free and clamped-clamped: `s = (1 + E1^2 - 2 E1 cos u) / Q`, `c_g =
//!   (cos u - sin u - E1) / Q`, `Q = 1 - E1^2 - 2 E1 sin u` (from `1 - s = 2
//!   E1 (cos u - sin u - E1) / Q`);
//! - clamped-free: `s = (1 + E1^2 + 2 E1 cos u) / Q`, `c_g = (sin u - cos u
//!   - E1) / Q`, `Q = 1 - E1^2 + 2 E1 sin u`.
//!
//! The free-free bar's two rigid-body modes are left out (a bar rests on
//! soft supports; their frequencies are the supports', not the bar's).
//!
//! **Timoshenko correction** (shear deformation and rotary inertia, shear
//! modulus `G`, shear coefficient `kappa`: 5/6 for a rectangle; Cowper's
//! `kappa = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu)
//! m^2)`, `m = d / D`, for a tube). The Timoshenko equations `rho A w_tt =
//! kappa G A (w_xx - psi_x)`, `rho I psi_tt = E I psi_xx + kappa G A (w_x -
//! psi)` give for a wave of wavenumber `k` the dispersion relation
//!
//! `(rho r^2 / (kappa G)) omega^4 - (1 + (k r)^2 (1 + E / (kappa G)))
//! omega^2 + omega_EB^2 = 0`, `omega_EB^2 = E I k^4 / (rho A)`.
//!
//! Each mode takes its Euler-Bernoulli wavenumber `k = beta_n` and the lower
//! (bending) root: with `s = (k r)^2`, `e = E / (kappa G)`, `B = 1 + s (1 +
//! e)`,
//!
//! `omega_T / omega_EB = sqrt(2 / (B + sqrt(B^2 - 4 e s^2)))  ~  1 - s (1 +
//! e) / 2` (first order).
//!
//! This is exact for simply supported ends; for free and clamped ends it
//! ignores the end correction of the Timoshenko boundary conditions
//! (approximate). Measured against ASTM E1876's correction factor `T1`
//! for the first free-free mode (Spinner-Tefft/Pickett), it overestimates the
//! frequency lowering by about 6.5 % of the lowering (isotropic, `nu =
//! 0.3`, `h / L` from 0.01 to 0.1, tested below): for a bar with `h / L =
//! 0.1` the lowering is 3.59 % instead of 3.38 %. Shapes stay the
//! Euler-Bernoulli ones. Clamped-clamped modes use the same wavenumber
//! `k = u_n / L` as the others.
//!
//! **Tuned (undercut) bars**: target ratios `t_1 : t_2 : ... : t_k` for the
//! first `k` bending modes, and optionally the frequency `F` the maker tunes
//! the fundamental to (the undercut lowers it below the uniform bar's).
//! Mode `i <= k` gets `F t_i / t_1` (`F` defaults to the uniform bar's
//! `f_1`); write `q_i = f_i^tuned / f_i^uniform` for its tuning factor. An
//! untuned mode `i > k` gets `q_i f_i^uniform` with
//! - with `F` given, `k >= 2` and `0 < r = (1 - q_k) / (1 - q_{k-1}) < 1`
//!   (the undercut lowers the lower modes more, as it does): `q_i = 1 - (1 -
//!   q_k) r^(i - k)`, the factor extrapolated geometrically towards 1 (an
//!   undercut at the centre changes the short waves of high modes less);
//! - otherwise `q_i = q_k`: the uniform bar's ratio to the last tuned mode.
//!
//! Shapes (and so weights) stay those of the uniform bar, and torsional
//! modes keep the uniform bar's frequencies. All of this is an estimate: a
//! real undercut moves nodes toward the centre, removes mass and changes the
//! weights.
//!
//! **Torsional modes** (off by default; [`Bar::with_torsion`],
//! [`Tube::with_torsion`] with the shear modulus `G`). Saint-Venant torsion
//! of the twist angle `theta(x, t)`: `rho J_p theta_tt = G K_t theta_xx`,
//! with `J_p` the polar moment of the section about the axis (rotary inertia
//! per length `rho J_p`) and `K_t` the torsion constant; wave speed `c_t =
//! sqrt(G K_t / (rho J_p))`.
//! - Rectangle of sides `b >= h` (swap them otherwise): `K_t = beta b h^3`,
//!   `beta = 1/3 (1 - 192 / pi^5 (h / b) S)`, `S = sum_{n odd} tanh(n pi b /
//!   (2 h)) / n^5`, and `J_p = b h (b^2 + h^2) / 12`. `S` is summed as
//!   `lambda(5) - sum_{n odd} (1 - tanh z_n) / n^5`, `z_n = n pi b / (2 h)`,
//!   `lambda(5) = sum_{n odd} n^-5 = (31 / 32) zeta(5)`, `1 - tanh z = 2
//!   exp(-2 z) / (1 + exp(-2 z))`: the terms fall like `exp(-n pi)`, so a
//!   few terms reach full precision. `beta` = 0.1406 (square), 0.229 (`b / h
//!   = 2`), 0.312 (10), `-> 1/3` (thin strip).
//! - Tube: `K_t = J_p = pi (D^4 - d^4) / 32`, so `c_t = sqrt(G / rho)`.
//!
//! Modes `n >= 1`, with `A = sqrt(2 / (rho J_p L))` so that `integral_0^L
//! rho J_p theta^2 dx = 1`:
//! - free-free: `f_n = n c_t / (2 L)`, `theta = A cos(n pi x / L)` (the rigid
//!   rotation is left out, like the rigid bending modes);
//! - clamped-free: `f_n = (2n - 1) c_t / (4 L)`, `theta = A sin((2n - 1) pi
//!   x / (2 L))`;
//! - clamped-clamped: `f_n = n c_t / (2 L)`, `theta = A sin(n pi x / L)`.
//!
//! A point at `(x, y)` moves in the direction of vibration (across the
//! thickness) by `Phi = y theta(x)`, the weight of the mode there; `y = 0`
//! (and so [`Point::Line`]) does not move. The sideways motion `-z theta` of
//! points off the mid-plane is not a weight. Over the whole section `integral
//! rho (y^2 + z^2) theta^2 dA dx = integral rho J_p theta^2 dx = 1`, and a
//! torsional mode is orthogonal to every bending mode (its motion is odd in
//! `y`, theirs even).
//!
//! Approximations: Saint-Venant theory lets the section warp freely and
//! uniformly. That is exact for a round tube, which does not warp; for a
//! rectangle it leaves out the warping stiffness (which raises the
//! frequencies, more for higher modes, short bars and woods with a large
//! `E / G`) and the warping inertia (which lowers them); neither is
//! quantified here. A wooden bar twists with both `G_LR` and `G_LT`; one `G`
//! is used. The Timoshenko correction does not apply to torsion. For a tuned
//! bar the torsional modes keep the uniform bar's frequencies (a real
//! undercut lowers them too). Bending and torsional modes are merged by
//! frequency (bending first on a tie) and `max_freq_hz` and `max_count`
//! apply to the merged list.
//!
//! # Rectangular plates (Kirchhoff)
//!
//! Sides `a` (x), `b` (y), thickness `h`, flexural rigidity `D = E h^3 /
//! (12 (1 - nu^2))`, points `(x, y)` in `[0, a] x [0, b]`.
//!
//! - Simply supported (exact): `omega_mn = pi^2 (m^2 / a^2 + n^2 / b^2)
//!   sqrt(D / (rho h))`, `m, n >= 1`, `Phi = 2 / sqrt(rho h a b) sin(m pi x /
//!   a) sin(n pi y / b)`.
//! - Free edges (**approximate**, Warburton 1954 as given by Leissa,
//!   *Vibration of Plates*, NASA SP-160, 1969): `omega_mn = (pi^2 / a^2)
//!   sqrt(D / (rho h)) sqrt(lambda^2)`, `lambda^2 = G_x^4 + G_y^4 (a/b)^4 + 2
//!   (a/b)^2 (nu H_x H_y + (1 - nu) J_x J_y)`, with for index `m` (number of
//!   nodal lines across x; the same for `n`, y):
//!   `m = 0`: `G = H = J = 0`; `m = 1`: `G = H = 0`, `J = 12 / pi^2`;
//!   `m = 2`: `G = 1.506`, `H = 1.248`, `J = 5.017`; `m >= 3`: `G = m - 1/2`,
//!   `H = (m - 1/2)^2 (1 - 4 / ((2m - 1) pi))`, `J = (m - 1/2)^2 (1 + 12 /
//!   ((2m - 1) pi))`. Modes `(0,0)`, `(0,1)`, `(1,0)` are rigid and left out;
//!   `(1,1)` is the twisting mode. Shapes are products of free-free beam
//!   functions `Phi = X_m(x) Y_n(y) / sqrt(rho h a b)` with `X_0 = 1`, `X_1 =
//!   sqrt(3) (1 - 2 x / a)`, `X_m` (m >= 2) the free-free beam function of
//!   root `m - 1` (each with `integral X^2 = a`): exactly mass normalised and
//!   orthogonal, but not exact plate modes. For a square plate (`nu = 0.3`)
//!   the frequencies are within about 5 % of Leissa's exact values for the
//!   twisting and (1,2) modes, while the (0,2)/(2,0) pair, which the real
//!   plate mixes into two modes of different frequency (19.6 and 24.3 in
//!   units of `sqrt(D / (rho h)) / a^2`), gets one frequency (22.4) between
//!   them. Needs `0 <= nu < 0.5`.
//!
//! # Circular membrane
//!
//! Radius `a`, tension `T` \[N/m\], areal density `sigma` \[kg/m^2\], points
//! `(r, theta)`: `omega_mn = j_mn sqrt(T / sigma) / a`, `j_mn` the `n`-th
//! positive zero of the Bessel function `J_m`. Shapes `Phi = N J_m(j_mn r /
//! a) cos(m theta)` and, for `m > 0`, the degenerate partner with `sin(m
//! theta)` (listed as a second mode of the same frequency; a pair is never
//! split by `max_count`, so the count may fall one short). Using
//! `integral_0^a J_m(j r / a)^2 r dr = a^2 J_{m+1}(j)^2 / 2`: `N = 1 /
//! (sqrt(pi sigma) a |J_1(j_0n)|)` for `m = 0`, `N = sqrt(2) / (sqrt(pi
//! sigma) a |J_{m+1}(j_mn)|)` for `m > 0`.
//!
//! `J_m(x)` (integer `m >= 0`, `x >= 0`): power series `sum_k (-1)^k
//! (x/2)^(2k+m) / (k! (k+m)!)` for `x < 1`; otherwise Miller's backward
//! recurrence `J_{k-1} = (2k / x) J_k - J_{k+1}` from `N = max(m+1, x) +
//! sqrt(160 max(m+1, x)) + 20` (even), normalised by `J_0 + 2 sum J_{2k} =
//! 1` (absolute accuracy ~1e-14). Zeros: the first zero exceeds `m`;
//! consecutive zeros are more than 3 apart, so from `max(m, 1)` (or the
//! previous zero + 3) a scan in steps of 0.5 brackets exactly one sign
//! change, which Newton's method (`J_m' = (m / x) J_m - J_{m+1}`),
//! safeguarded by bisection, polishes to a few ulp.
//!
//! # Stiff string
//!
//! Length `L`, tension `T` \[N\], linear density `mu` \[kg/m\], bending
//! stiffness `E I` \[N m^2\], pinned (simply supported) ends, points `x` in
//! `[0, L]`: `f_n = n f_0 sqrt(1 + B n^2)`, `f_0 = sqrt(T / mu) / (2 L)`,
//! `B = pi^2 E I / (T L^2)` (exact for `mu y_tt = T y_xx - E I y_xxxx`
//! with `y = y_xx = 0` at both ends), `Phi = sqrt(2 / (mu L)) sin(n pi x /
//! L)`.
//!
//! # Loss model
//!
//! Each mode decays at `sigma_i = sigma_0 + eta omega_i / 2 + sigma_r
//! (f_i / f_r)^p` \[1/s\] (the `sigma_i` of docs/design.md section 2):
//! constant `sigma_0` (supports, air drag), material loss factor `eta` (a
//! mode alone decays as `T60 = 2 ln(1000) / (eta omega)`), and an optional
//! radiation-like term `sigma_r` at reference frequency `f_r` growing as
//! `f^p` (`p = 2` gives the form `a_0 + a_2 f^2` fitted to xylophone bars by
//! Chaigne & Doutaut, JASA 101, 1997, with `a_0 = sigma_0`). `T60_i =
//! ln(1000) / sigma_i`, none when `sigma_i = 0` (undamped).

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;
use std::f64::consts::PI;
use std::fmt;

use crate::bodies::materials::Material;

/// The most modes one call lists (a guard against runaway requests).
pub const MAX_MODE_COUNT: usize = 100_000;

// ---------------------------------------------------------------------------
// Validation helpers
// ---------------------------------------------------------------------------

fn positive(field: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{field}: must be finite and > 0, got {v}"))
    }
}

fn non_negative(field: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{field}: must be finite and >= 0, got {v}"))
    }
}

fn check_limits(max_freq_hz: f64, max_count: usize) -> Result<(), String> {
    if !(max_freq_hz > 0.0) {
        return Err(format!("max_freq_hz: must be > 0, got {max_freq_hz}"));
    }
    if max_count > MAX_MODE_COUNT {
        return Err(format!(
            "max_count: must be <= {MAX_MODE_COUNT}, got {max_count}"
        ));
    }
    Ok(())
}

fn in_range(field: &str, v: f64, hi: f64) -> Result<f64, String> {
    if v.is_finite() && (0.0..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{field}: must be in [0, {hi}], got {v}"))
    }
}

fn in_symmetric_range(field: &str, v: f64, half: f64) -> Result<f64, String> {
    if v.is_finite() && v.abs() <= half {
        Ok(v)
    } else {
        Err(format!("{field}: must be in [-{half}, {half}], got {v}"))
    }
}

// ---------------------------------------------------------------------------
// Points, labels, modes
// ---------------------------------------------------------------------------

/// A point on an object, in the coordinates of its kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Point {
    /// Bar, tube, string: position along the axis \[m\], `0..=L`. On a bar
    /// or tube, the point on the centre line (`Point::Bar` with `y = 0`).
    Line(f64),
    /// Bar or tube \[m\]: `x` along the axis, `0..=L`; `y` across the width
    /// from the centre line, `|y| <= b/2` (bar) or `<= D/2` (tube). Only
    /// torsional modes depend on `y`.
    Bar {
        /// Along the axis.
        x: f64,
        /// Across the width, from the centre line.
        y: f64,
    },
    /// Rectangular plate \[m\]: `x` in `0..=a`, `y` in `0..=b`.
    Plane {
        /// Along side `a`.
        x: f64,
        /// Along side `b`.
        y: f64,
    },
    /// Circular membrane: radius \[m\] `0..=a`, angle \[rad\] (any finite).
    Polar {
        /// Distance from the centre.
        r: f64,
        /// Angle from the `cos` modes' antinode line.
        theta: f64,
    },
}

/// Which mode a [`ShapeMode`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ModeLabel {
    /// Bar or tube bending mode `n` (1 = fundamental).
    Bending {
        /// Mode number from 1.
        n: usize,
    },
    /// Plate mode: half-waves (simply supported) or nodal lines (free
    /// edges, Warburton's indices) along x (`m`) and y (`n`).
    Plate {
        /// Index along side `a`.
        m: usize,
        /// Index along side `b`.
        n: usize,
    },
    /// Membrane mode: `m` nodal diameters, `n` nodal circles counting the
    /// rim; `sine` tells the `sin(m theta)` partner of a degenerate pair.
    Membrane {
        /// Nodal diameters.
        m: usize,
        /// Nodal circles (with the rim).
        n: usize,
        /// The `sin(m theta)` partner.
        sine: bool,
    },
    /// String mode `n` (1 = fundamental).
    String {
        /// Mode number from 1.
        n: usize,
    },
    /// Bar or tube torsional mode `n` (1 = lowest).
    Torsion {
        /// Mode number from 1.
        n: usize,
    },
}

impl fmt::Display for ModeLabel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ModeLabel::Bending { n } => write!(f, "bending {n}"),
            ModeLabel::Plate { m, n } => write!(f, "plate ({m},{n})"),
            ModeLabel::Membrane { m, n, sine } => {
                write!(f, "membrane ({m},{n})")?;
                if m > 0 {
                    write!(f, " {}", if sine { "sin" } else { "cos" })?;
                }
                Ok(())
            }
            ModeLabel::String { n } => write!(f, "string {n}"),
            ModeLabel::Torsion { n } => write!(f, "torsion {n}"),
        }
    }
}

/// One mode: frequency, label and its mass-normalised shape.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeMode {
    /// Undamped natural frequency \[Hz\].
    pub freq_hz: f64,
    /// Which mode.
    pub label: ModeLabel,
    shape: ModeShape,
}

impl ShapeMode {
    /// Angular frequency \[rad/s\].
    pub fn omega(&self) -> f64 {
        2.0 * PI * self.freq_hz
    }

    /// The mass-normalised mode shape at `point` \[1/sqrt(kg)\]: the weight
    /// `w_{p,i}` of a modal object. Bars and tubes take [`Point::Bar`] or
    /// [`Point::Line`] (`y = 0`), strings [`Point::Line`], plates
    /// [`Point::Plane`], membranes [`Point::Polar`]. Errors for a point of
    /// another kind, out of the object (naming the coordinate) or not finite.
    pub fn shape_at(&self, point: Point) -> Result<f64, String> {
        self.shape.eval(point)
    }
}

/// A mode shape, evaluable anywhere on its object.
#[derive(Debug, Clone, PartialEq)]
enum ModeShape {
    Beam {
        f: BeamFn,
        length: f64,
        half_width: f64,
        scale: f64,
    },
    /// `Phi = y theta(x)`, `theta = scale * (cos or sin)` by `support`.
    Torsion {
        support: BeamSupport,
        n: usize,
        length: f64,
        half_width: f64,
        scale: f64,
    },
    PlateSs {
        a: f64,
        b: f64,
        m: usize,
        n: usize,
        scale: f64,
    },
    PlateFree {
        fx: BeamFn,
        fy: BeamFn,
        a: f64,
        b: f64,
        scale: f64,
    },
    Membrane {
        radius: f64,
        m: usize,
        j: f64,
        sine: bool,
        scale: f64,
    },
    String {
        length: f64,
        n: usize,
        scale: f64,
    },
}

impl ModeShape {
    fn eval(&self, point: Point) -> Result<f64, String> {
        match (self, point) {
            (
                &ModeShape::Beam {
                    f,
                    length,
                    half_width,
                    scale,
                },
                Point::Line(_) | Point::Bar { .. },
            ) => {
                let (x, _) = bar_point(point, length, half_width)?;
                Ok(scale * f.eval(x / length))
            }
            (
                &ModeShape::Torsion {
                    support,
                    n,
                    length,
                    half_width,
                    scale,
                },
                Point::Line(_) | Point::Bar { .. },
            ) => {
                let (x, y) = bar_point(point, length, half_width)?;
                Ok(y * scale * torsion_fn(support, n, x / length))
            }
            (&ModeShape::String { length, n, scale }, Point::Line(x)) => {
                let x = in_range("point.x", x, length)?;
                Ok(scale * (n as f64 * PI * x / length).sin())
            }
            (&ModeShape::PlateSs { a, b, m, n, scale }, Point::Plane { x, y }) => {
                let x = in_range("point.x", x, a)?;
                let y = in_range("point.y", y, b)?;
                Ok(scale * (m as f64 * PI * x / a).sin() * (n as f64 * PI * y / b).sin())
            }
            (
                &ModeShape::PlateFree {
                    fx,
                    fy,
                    a,
                    b,
                    scale,
                },
                Point::Plane { x, y },
            ) => {
                let x = in_range("point.x", x, a)?;
                let y = in_range("point.y", y, b)?;
                Ok(scale * fx.eval(x / a) * fy.eval(y / b))
            }
            (
                &ModeShape::Membrane {
                    radius,
                    m,
                    j,
                    sine,
                    scale,
                },
                Point::Polar { r, theta },
            ) => {
                let r = in_range("point.r", r, radius)?;
                if !theta.is_finite() {
                    return Err(format!("point.theta: must be finite, got {theta}"));
                }
                let angular = if sine {
                    (m as f64 * theta).sin()
                } else {
                    (m as f64 * theta).cos()
                };
                Ok(scale * bessel_j(m, j * r / radius) * angular)
            }
            (shape, p) => Err(format!(
                "point: {p:?} is not a point of a {}",
                match shape {
                    ModeShape::Beam { .. } | ModeShape::Torsion { .. } =>
                        "bar or tube (use Point::Bar or Point::Line)",
                    ModeShape::String { .. } => "string (use Point::Line)",
                    ModeShape::PlateSs { .. } | ModeShape::PlateFree { .. } =>
                        "plate (use Point::Plane)",
                    ModeShape::Membrane { .. } => "membrane (use Point::Polar)",
                }
            )),
        }
    }
}

/// `(x, y)` of a [`Point::Line`] (`y = 0`) or [`Point::Bar`] on a bar or
/// tube of length `length`, checked.
fn bar_point(point: Point, length: f64, half_width: f64) -> Result<(f64, f64), String> {
    match point {
        Point::Line(x) => Ok((in_range("point.x", x, length)?, 0.0)),
        Point::Bar { x, y } => Ok((
            in_range("point.x", x, length)?,
            in_symmetric_range("point.y", y, half_width)?,
        )),
        p => Err(format!("point: {p:?} is not a point of a bar or tube")),
    }
}

// ---------------------------------------------------------------------------
// Beam functions
// ---------------------------------------------------------------------------

/// Boundary conditions of a bar or tube.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BeamSupport {
    /// Both ends free (xylophone and marimba bars, chimes).
    FreeFree,
    /// Clamped at `x = 0`, free at `x = L` (kalimba tine, tuning-fork prong).
    ClampedFree,
    /// Both ends clamped (the lips of a wood block).
    ClampedClamped,
}

/// `sech x` without overflow (`x >= 0`).
fn sech(x: f64) -> f64 {
    let e = (-x).exp();
    2.0 * e / (1.0 + e * e)
}

/// `u_n = beta_n L`, the `n`-th (from 1) positive root of `cos u cosh u = 1`
/// (free-free, clamped-clamped) or `= -1` (clamped-free).
pub fn beam_root(support: BeamSupport, n: usize) -> f64 {
    let n = n.max(1) as f64;
    // g(u) = cos u - c sech u, c = +1 (free-free, clamped-clamped) or -1
    // (clamped-free).
    let (c, lo, hi, guess) = match support {
        BeamSupport::FreeFree | BeamSupport::ClampedClamped => {
            (1.0, n * PI, (n + 1.0) * PI, (2.0 * n + 1.0) * PI / 2.0)
        }
        BeamSupport::ClampedFree => (-1.0, (n - 1.0) * PI, n * PI, (2.0 * n - 1.0) * PI / 2.0),
    };
    let g = |u: f64| u.cos() - c * sech(u);
    let dg = |u: f64| {
        let s = sech(u);
        let t = (1.0 - (-2.0 * u).exp()) / (1.0 + (-2.0 * u).exp());
        -u.sin() + c * s * t
    };
    safeguarded_newton(g, dg, lo, hi, guess)
}

/// Newton's method kept inside a sign-change bracket `[lo, hi]` (bisection
/// when a step leaves it). Returns the best point found.
fn safeguarded_newton(
    f: impl Fn(f64) -> f64,
    df: impl Fn(f64) -> f64,
    mut lo: f64,
    mut hi: f64,
    guess: f64,
) -> f64 {
    let f_lo = f(lo);
    if f_lo == 0.0 {
        return lo;
    }
    let lo_negative = f_lo < 0.0;
    let mut x = if guess > lo && guess < hi {
        guess
    } else {
        0.5 * (lo + hi)
    };
    for _ in 0..200 {
        let fx = f(x);
        if fx == 0.0 {
            return x;
        }
        if (fx < 0.0) == lo_negative {
            lo = x;
        } else {
            hi = x;
        }
        let d = df(x);
        let newton = x - fx / d;
        let next = if d != 0.0 && newton.is_finite() && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        let step = (next - x).abs();
        x = next;
        if step <= 4.0 * f64::EPSILON * x.abs() || hi - lo <= 4.0 * f64::EPSILON * x.abs() {
            break;
        }
    }
    x
}

/// A 1-D beam function on `xi = x / L` in `[0, 1]`, normalised to
/// `integral_0^1 phi^2 d xi = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum BeamFn {
    /// `phi = 1` (rigid translation).
    Rigid0,
    /// `phi = sqrt(3) (1 - 2 xi)` (rigid rotation).
    Rigid1,
    /// Elastic mode: `phi = c_g e^{u(xi-1)} + c_d e^{-u xi} + t (cos(u xi) -
    /// s sin(u xi))`, `t = +1` free-free, `-1` clamped-free and
    /// clamped-clamped.
    Elastic {
        u: f64,
        c_grow: f64,
        c_decay: f64,
        s: f64,
        trig: f64,
    },
}

impl BeamFn {
    fn elastic(support: BeamSupport, n: usize) -> BeamFn {
        let u = beam_root(support, n);
        let e1 = (-u).exp();
        let (su, cu) = u.sin_cos();
        let (s, c_grow, trig) = match support {
            BeamSupport::FreeFree | BeamSupport::ClampedClamped => {
                // The same hyperbolic part; the trigonometric part changes sign.
                let q = 1.0 - e1 * e1 - 2.0 * e1 * su;
                let trig = if support == BeamSupport::FreeFree {
                    1.0
                } else {
                    -1.0
                };
                (
                    (1.0 + e1 * e1 - 2.0 * e1 * cu) / q,
                    (cu - su - e1) / q,
                    trig,
                )
            }
            BeamSupport::ClampedFree => {
                let q = 1.0 - e1 * e1 + 2.0 * e1 * su;
                (
                    (1.0 + e1 * e1 + 2.0 * e1 * cu) / q,
                    (su - cu - e1) / q,
                    -1.0,
                )
            }
        };
        BeamFn::Elastic {
            u,
            c_grow,
            c_decay: 0.5 * (1.0 + s),
            s,
            trig,
        }
    }

    fn eval(&self, xi: f64) -> f64 {
        match *self {
            BeamFn::Rigid0 => 1.0,
            BeamFn::Rigid1 => 3f64.sqrt() * (1.0 - 2.0 * xi),
            BeamFn::Elastic {
                u,
                c_grow,
                c_decay,
                s,
                trig,
            } => {
                let (sn, cs) = (u * xi).sin_cos();
                c_grow * (u * (xi - 1.0)).exp() + c_decay * (-u * xi).exp() + trig * (cs - s * sn)
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Bars and tubes
// ---------------------------------------------------------------------------

/// Shear data for the Timoshenko correction of a bar or tube.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShearCorrection {
    /// Shear modulus `G` \[Pa\] (woods: `G_LR` or `G_LT`, by how the bar is cut).
    pub shear_modulus_pa: f64,
    /// Shear coefficient `kappa` (5/6 for a rectangle).
    pub shear_coefficient: f64,
}

impl ShearCorrection {
    /// Rectangular cross-section: `kappa = 5/6`.
    pub fn rectangle(shear_modulus_pa: f64) -> Self {
        ShearCorrection {
            shear_modulus_pa,
            shear_coefficient: 5.0 / 6.0,
        }
    }

    /// Hollow circular cross-section, Cowper's (1966) coefficient
    /// `kappa = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12
    /// nu) m^2)`, `m = d / D` (solid rod: `6 (1 + nu) / (7 + 6 nu)`).
    pub fn tube(
        shear_modulus_pa: f64,
        poisson_ratio: f64,
        outer_diameter_m: f64,
        inner_diameter_m: f64,
    ) -> Self {
        let m = inner_diameter_m / outer_diameter_m;
        let nu = poisson_ratio;
        let p = (1.0 + m * m).powi(2);
        ShearCorrection {
            shear_modulus_pa,
            shear_coefficient: 6.0 * (1.0 + nu) * p
                / ((7.0 + 6.0 * nu) * p + (20.0 + 12.0 * nu) * m * m),
        }
    }

    fn validate(&self, owner: &str) -> Result<(), String> {
        positive(
            &format!("{owner}.shear.shear_modulus_pa"),
            self.shear_modulus_pa,
        )?;
        let k = self.shear_coefficient;
        if !(k.is_finite() && k > 0.0 && k <= 1.0) {
            return Err(format!(
                "{owner}.shear.shear_coefficient: must be in (0, 1], got {k}"
            ));
        }
        Ok(())
    }
}

/// `omega_T / omega_EB` for wavenumber `k`, radius of gyration squared `r2`
/// and `e = E / (kappa G)` (lower root of the Timoshenko dispersion relation).
pub fn timoshenko_ratio(k: f64, r2: f64, e: f64) -> f64 {
    let s = k * k * r2;
    let b = 1.0 + s * (1.0 + e);
    (2.0 / (b + (b * b - 4.0 * e * s * s).max(0.0).sqrt())).sqrt()
}

/// Torsion data of a bar or tube.
#[derive(Debug, Clone, Copy)]
struct TorsionData {
    /// Wave speed `c_t = sqrt(G K_t / (rho J_p))` \[m/s\].
    speed: f64,
    /// Rotary inertia per length `rho J_p` \[kg m\].
    rho_jp: f64,
}

/// What bars and tubes share.
struct BeamData<'a> {
    owner: &'a str,
    length: f64,
    /// Largest `|y|` of a point: `b / 2` or `D / 2`.
    half_width: f64,
    torsion: Option<TorsionData>,
    rho_a: f64,
    ei: f64,
    r2: f64,
    support: BeamSupport,
    /// `E / (kappa G)` when the Timoshenko correction is on.
    shear_e: Option<f64>,
    tuning: &'a [f64],
    fundamental: Option<f64>,
}

fn check_tuning(owner: &str, tuning: &[f64]) -> Result<(), String> {
    for (i, &t) in tuning.iter().enumerate() {
        positive(&format!("{owner}.tuning[{i}]"), t)?;
        if i > 0 && !(t > tuning[i - 1]) {
            return Err(format!(
                "{owner}.tuning[{i}]: ratios must increase strictly, got {t} after {}",
                tuning[i - 1]
            ));
        }
    }
    Ok(())
}

/// Bending and (when on) torsional modes, merged by frequency, then limited.
fn beam_modes(
    d: &BeamData<'_>,
    max_freq_hz: f64,
    max_count: usize,
) -> Result<Vec<ShapeMode>, String> {
    check_limits(max_freq_hz, max_count)?;
    let mut out = bending_modes(d, max_freq_hz, max_count)?;
    if let Some(t) = d.torsion {
        // Each list holds its family's lowest `max_count` modes, so the
        // lowest `max_count` of the union are among them.
        out.extend(torsion_modes(d, t, max_freq_hz, max_count)?);
        // Stable: bending before torsion on a tie.
        out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
        out.truncate(max_count);
    }
    Ok(out)
}

/// `theta(xi) / A` of torsional mode `n`, `xi = x / L`.
fn torsion_fn(support: BeamSupport, n: usize, xi: f64) -> f64 {
    let n = n as f64;
    match support {
        BeamSupport::FreeFree => (n * PI * xi).cos(),
        BeamSupport::ClampedFree => ((2.0 * n - 1.0) * PI * xi / 2.0).sin(),
        BeamSupport::ClampedClamped => (n * PI * xi).sin(),
    }
}

/// Frequency \[Hz\] of torsional mode `n` for wave speed `c_t` and length `L`.
fn torsion_freq(support: BeamSupport, n: usize, speed: f64, length: f64) -> f64 {
    let n = n as f64;
    match support {
        BeamSupport::FreeFree | BeamSupport::ClampedClamped => n * speed / (2.0 * length),
        BeamSupport::ClampedFree => (2.0 * n - 1.0) * speed / (4.0 * length),
    }
}

fn torsion_modes(
    d: &BeamData<'_>,
    t: TorsionData,
    max_freq_hz: f64,
    max_count: usize,
) -> Result<Vec<ShapeMode>, String> {
    let scale = (2.0 / (t.rho_jp * d.length)).sqrt();
    let mut out = Vec::new();
    for n in 1..=max_count {
        let freq = torsion_freq(d.support, n, t.speed, d.length);
        if !(freq.is_finite() && scale.is_finite()) {
            return Err(format!(
                "{}: torsional mode {n} has a non-finite frequency ({freq}) or scale ({scale})",
                d.owner
            ));
        }
        if freq > max_freq_hz {
            break;
        }
        out.push(ShapeMode {
            freq_hz: freq,
            label: ModeLabel::Torsion { n },
            shape: ModeShape::Torsion {
                support: d.support,
                n,
                length: d.length,
                half_width: d.half_width,
                scale,
            },
        });
    }
    Ok(out)
}

/// `beta` of the Saint-Venant torsion constant `K_t = beta b h^3` of a
/// rectangle with sides `b >= h` (the sides are swapped when `b < h`):
/// `beta = 1/3 (1 - 192 / pi^5 (h / b) sum_{n odd} tanh(n pi b / (2 h)) /
/// n^5)`. 0.1406 for a square, `-> 1/3` for a thin strip. NaN unless both
/// sides are positive and finite.
pub fn rectangle_torsion_coefficient(b: f64, h: f64) -> f64 {
    if !(b.is_finite() && h.is_finite() && b > 0.0 && h > 0.0) {
        return f64::NAN;
    }
    let (b, h) = if b >= h { (b, h) } else { (h, b) };
    // lambda(5) = sum over odd n of n^-5 = (31/32) zeta(5).
    const ZETA5: f64 = 1.036_927_755_143_37;
    let lambda5 = 31.0 / 32.0 * ZETA5;
    // S = lambda(5) - sum_{n odd} (1 - tanh z_n) / n^5, 1 - tanh z = 2 e / (1
    // + e), e = exp(-2 z), 2 z_n = n pi b / h >= n pi.
    let mut tail = 0.0;
    let mut n = 1.0f64;
    loop {
        let e = (-n * PI * b / h).exp();
        let term = 2.0 * e / (1.0 + e) / n.powi(5);
        tail += term;
        if term <= 1e-18 * lambda5 {
            break;
        }
        n += 2.0;
    }
    let sum = lambda5 - tail;
    (1.0 - 192.0 / PI.powi(5) * (h / b) * sum) / 3.0
}

fn bending_modes(
    d: &BeamData<'_>,
    max_freq_hz: f64,
    max_count: usize,
) -> Result<Vec<ShapeMode>, String> {
    let c = (d.ei / d.rho_a).sqrt();
    let scale = 1.0 / (d.rho_a * d.length).sqrt();
    let uniform = |f: &BeamFn| -> f64 {
        let u = match *f {
            BeamFn::Elastic { u, .. } => u,
            _ => 0.0,
        };
        let k = u / d.length;
        let ratio = d.shear_e.map_or(1.0, |e| timoshenko_ratio(k, d.r2, e));
        k * k * c * ratio / (2.0 * PI)
    };
    let k_tuned = d.tuning.len();
    let mut f1 = f64::NAN;
    // tuning factors q_i = f_i^tuned / f_i^uniform of the last two tuned modes
    let (mut q_prev, mut q_k) = (f64::NAN, f64::NAN);
    let mut out = Vec::new();
    for n in 1..=max_count {
        let f = BeamFn::elastic(d.support, n);
        let fu = uniform(&f);
        let freq = if k_tuned == 0 {
            fu
        } else if n <= k_tuned {
            if n == 1 {
                f1 = d.fundamental.unwrap_or(fu);
            }
            let t = f1 * d.tuning[n - 1] / d.tuning[0];
            q_prev = q_k;
            q_k = t / fu;
            t
        } else {
            let r = (1.0 - q_k) / (1.0 - q_prev);
            let q = if d.fundamental.is_some() && k_tuned >= 2 && r > 0.0 && r < 1.0 {
                1.0 - (1.0 - q_k) * r.powi((n - k_tuned) as i32)
            } else {
                q_k
            };
            q * fu
        };
        if !freq.is_finite() {
            return Err(format!(
                "{}: mode {n} has a non-finite frequency ({freq})",
                d.owner
            ));
        }
        if freq > max_freq_hz {
            break;
        }
        out.push(ShapeMode {
            freq_hz: freq,
            label: ModeLabel::Bending { n },
            shape: ModeShape::Beam {
                f,
                length: d.length,
                half_width: d.half_width,
                scale,
            },
        });
    }
    Ok(out)
}

/// A rectangular bar bending across its thickness.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Width `b` \[m\] (not in the direction of vibration).
    pub width_m: f64,
    /// Thickness `h` \[m\] (in the direction of vibration).
    pub thickness_m: f64,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` along the bar \[Pa\].
    pub youngs_modulus_pa: f64,
    /// Boundary conditions.
    pub support: BeamSupport,
    /// Timoshenko correction (none: Euler-Bernoulli).
    pub shear: Option<ShearCorrection>,
    /// Target frequency ratios of the first bending modes (empty: uniform
    /// bar). See the module docs, "Tuned (undercut) bars".
    pub tuning: Vec<f64>,
    /// With `tuning`: the tuned fundamental \[Hz\] (`None`: the uniform
    /// bar's).
    pub fundamental_hz: Option<f64>,
    /// Shear modulus `G` \[Pa\] of the torsional modes (none: bending
    /// only). See the module docs, "Torsional modes".
    pub torsion: Option<f64>,
}

impl Bar {
    /// A uniform Euler-Bernoulli bar of `material` (density and `E`).
    pub fn new(
        length_m: f64,
        width_m: f64,
        thickness_m: f64,
        material: &Material,
        support: BeamSupport,
    ) -> Self {
        Bar {
            length_m,
            width_m,
            thickness_m,
            density_kg_m3: material.density_kg_m3,
            youngs_modulus_pa: material.youngs_modulus_pa,
            support,
            shear: None,
            tuning: Vec::new(),
            fundamental_hz: None,
            torsion: None,
        }
    }

    /// With the Timoshenko correction, shear modulus `G`, `kappa = 5/6`.
    pub fn with_timoshenko(mut self, shear_modulus_pa: f64) -> Self {
        self.shear = Some(ShearCorrection::rectangle(shear_modulus_pa));
        self
    }

    /// Tuned to the ratios `t_1 : t_2 : ...` of its first bending modes.
    pub fn with_tuning(mut self, ratios: &[f64]) -> Self {
        self.tuning = ratios.to_vec();
        self
    }

    /// A tuned bar's fundamental tuned to `hz` (see "Tuned (undercut) bars").
    pub fn with_fundamental(mut self, hz: f64) -> Self {
        self.fundamental_hz = Some(hz);
        self
    }

    /// With torsional modes (Saint-Venant), shear modulus `G`.
    pub fn with_torsion(mut self, shear_modulus_pa: f64) -> Self {
        self.torsion = Some(shear_modulus_pa);
        self
    }

    /// Polar moment of the section `J_p = b h (b^2 + h^2) / 12` \[m^4\].
    pub fn polar_moment_m4(&self) -> f64 {
        let (b, h) = (self.width_m, self.thickness_m);
        b * h * (b * b + h * h) / 12.0
    }

    /// Saint-Venant torsion constant `K_t = beta b h^3` (`b >= h`, see
    /// [`rectangle_torsion_coefficient`]) \[m^4\].
    pub fn torsion_constant_m4(&self) -> f64 {
        let long = self.width_m.max(self.thickness_m);
        let short = self.width_m.min(self.thickness_m);
        rectangle_torsion_coefficient(long, short) * long * short.powi(3)
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("bar.length_m", self.length_m)?;
        positive("bar.width_m", self.width_m)?;
        positive("bar.thickness_m", self.thickness_m)?;
        positive("bar.density_kg_m3", self.density_kg_m3)?;
        positive("bar.youngs_modulus_pa", self.youngs_modulus_pa)?;
        if let Some(s) = &self.shear {
            s.validate("bar")?;
        }
        if let Some(g) = self.torsion {
            positive("bar.torsion", g)?;
        }
        if let Some(f) = self.fundamental_hz {
            positive("bar.fundamental_hz", f)?;
            if self.tuning.is_empty() {
                return Err(
                    "bar.fundamental_hz: only a tuned bar (tuning) has a fundamental apart from its geometry"
                        .into(),
                );
            }
        }
        check_tuning("bar", &self.tuning)
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.length_m * self.width_m * self.thickness_m
    }

    /// Bending (and, when on, torsional) modes up to `max_freq_hz`, at most
    /// `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        let a = self.width_m * self.thickness_m;
        let i = self.width_m * self.thickness_m.powi(3) / 12.0;
        let rho_jp = self.density_kg_m3 * self.polar_moment_m4();
        beam_modes(
            &BeamData {
                owner: "bar",
                length: self.length_m,
                half_width: 0.5 * self.width_m,
                torsion: self.torsion.map(|g| TorsionData {
                    speed: (g * self.torsion_constant_m4() / rho_jp).sqrt(),
                    rho_jp,
                }),
                rho_a: self.density_kg_m3 * a,
                ei: self.youngs_modulus_pa * i,
                r2: i / a,
                support: self.support,
                shear_e: self
                    .shear
                    .map(|s| self.youngs_modulus_pa / (s.shear_coefficient * s.shear_modulus_pa)),
                tuning: &self.tuning,
                fundamental: self.fundamental_hz,
            },
            max_freq_hz,
            max_count,
        )
    }
}

/// A round tube (chime) or, with inner diameter 0, a solid rod.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Outer diameter `D` \[m\].
    pub outer_diameter_m: f64,
    /// Inner diameter `d` \[m\], `0 <= d < D`.
    pub inner_diameter_m: f64,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` \[Pa\].
    pub youngs_modulus_pa: f64,
    /// Boundary conditions (chimes hang free: free-free).
    pub support: BeamSupport,
    /// Timoshenko correction (none: Euler-Bernoulli).
    pub shear: Option<ShearCorrection>,
    /// Shear modulus `G` \[Pa\] of the torsional modes (none: bending
    /// only). See the module docs, "Torsional modes".
    pub torsion: Option<f64>,
}

impl Tube {
    /// A free-free Euler-Bernoulli tube of `material`.
    pub fn new(
        length_m: f64,
        outer_diameter_m: f64,
        inner_diameter_m: f64,
        material: &Material,
    ) -> Self {
        Tube {
            length_m,
            outer_diameter_m,
            inner_diameter_m,
            density_kg_m3: material.density_kg_m3,
            youngs_modulus_pa: material.youngs_modulus_pa,
            support: BeamSupport::FreeFree,
            shear: None,
            torsion: None,
        }
    }

    /// With the Timoshenko correction (Cowper's shear coefficient).
    pub fn with_timoshenko(mut self, shear_modulus_pa: f64, poisson_ratio: f64) -> Self {
        self.shear = Some(ShearCorrection::tube(
            shear_modulus_pa,
            poisson_ratio,
            self.outer_diameter_m,
            self.inner_diameter_m,
        ));
        self
    }

    /// With torsional modes, shear modulus `G`.
    pub fn with_torsion(mut self, shear_modulus_pa: f64) -> Self {
        self.torsion = Some(shear_modulus_pa);
        self
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("tube.length_m", self.length_m)?;
        positive("tube.outer_diameter_m", self.outer_diameter_m)?;
        non_negative("tube.inner_diameter_m", self.inner_diameter_m)?;
        if !(self.inner_diameter_m < self.outer_diameter_m) {
            return Err(format!(
                "tube.inner_diameter_m: must be < outer_diameter_m ({}), got {}",
                self.outer_diameter_m, self.inner_diameter_m
            ));
        }
        positive("tube.density_kg_m3", self.density_kg_m3)?;
        positive("tube.youngs_modulus_pa", self.youngs_modulus_pa)?;
        if let Some(s) = &self.shear {
            s.validate("tube")?;
        }
        if let Some(g) = self.torsion {
            positive("tube.torsion", g)?;
        }
        Ok(())
    }

    /// Cross-section area `pi (D^2 - d^2) / 4` \[m^2\].
    pub fn area_m2(&self) -> f64 {
        PI * (self.outer_diameter_m.powi(2) - self.inner_diameter_m.powi(2)) / 4.0
    }

    /// Second moment of area `pi (D^4 - d^4) / 64` \[m^4\].
    pub fn second_moment_m4(&self) -> f64 {
        PI * (self.outer_diameter_m.powi(4) - self.inner_diameter_m.powi(4)) / 64.0
    }

    /// Polar moment `J_p = pi (D^4 - d^4) / 32`, also the torsion constant
    /// `K_t` \[m^4\].
    pub fn polar_moment_m4(&self) -> f64 {
        PI * (self.outer_diameter_m.powi(4) - self.inner_diameter_m.powi(4)) / 32.0
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.area_m2() * self.length_m
    }

    /// Bending (and, when on, torsional) modes up to `max_freq_hz`, at most
    /// `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        let a = self.area_m2();
        let i = self.second_moment_m4();
        beam_modes(
            &BeamData {
                owner: "tube",
                length: self.length_m,
                half_width: 0.5 * self.outer_diameter_m,
                // K_t = J_p: c_t = sqrt(G / rho).
                torsion: self.torsion.map(|g| TorsionData {
                    speed: (g / self.density_kg_m3).sqrt(),
                    rho_jp: self.density_kg_m3 * self.polar_moment_m4(),
                }),
                rho_a: self.density_kg_m3 * a,
                ei: self.youngs_modulus_pa * i,
                // (D^2 + d^2) / 16, without the cancellation of I / A.
                r2: (self.outer_diameter_m.powi(2) + self.inner_diameter_m.powi(2)) / 16.0,
                support: self.support,
                shear_e: self
                    .shear
                    .map(|s| self.youngs_modulus_pa / (s.shear_coefficient * s.shear_modulus_pa)),
                tuning: &[],
                fundamental: None,
            },
            max_freq_hz,
            max_count,
        )
    }
}

// ---------------------------------------------------------------------------
// Enumeration of two-index families in ascending order
// ---------------------------------------------------------------------------

/// `f64` with a total order, for the heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Key(f64);
impl Eq for Key {}
impl PartialOrd for Key {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Key {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// Visit the lattice `m >= m0`, `n >= n0` in ascending `value(m, n)`, for a
/// `value` nondecreasing in each index, until `visit` returns false. Only
/// the visited points and their successors are evaluated.
fn lattice_ascending(
    m0: usize,
    n0: usize,
    mut value: impl FnMut(usize, usize) -> Result<f64, String>,
    mut visit: impl FnMut(usize, usize, f64) -> bool,
) -> Result<(), String> {
    let mut heap = BinaryHeap::new();
    heap.push(Reverse((Key(value(m0, n0)?), m0, n0)));
    while let Some(Reverse((Key(v), m, n))) = heap.pop() {
        if !visit(m, n, v) {
            break;
        }
        heap.push(Reverse((Key(value(m, n + 1)?), m, n + 1)));
        if n == n0 {
            heap.push(Reverse((Key(value(m + 1, n0)?), m + 1, n0)));
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Plates
// ---------------------------------------------------------------------------

/// Edge conditions of a rectangular plate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlateEdges {
    /// All four edges simply supported (exact closed form).
    SimplySupported,
    /// All four edges free (Warburton's approximation).
    Free,
}

/// A thin rectangular plate (Kirchhoff), isotropic.
#[derive(Debug, Clone, PartialEq)]
pub struct Plate {
    /// Side `a` along x \[m\].
    pub length_x_m: f64,
    /// Side `b` along y \[m\].
    pub length_y_m: f64,
    /// Thickness `h` \[m\].
    pub thickness_m: f64,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` \[Pa\].
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio `nu`, `-1 < nu < 0.5` (free edges: `0 <= nu < 0.5`).
    pub poisson_ratio: f64,
    /// Edge conditions.
    pub edges: PlateEdges,
}

/// Warburton's `(G, H, J)` of a free-free direction, index `m`.
fn warburton_free(m: usize) -> (f64, f64, f64) {
    match m {
        0 => (0.0, 0.0, 0.0),
        1 => (0.0, 0.0, 12.0 / (PI * PI)),
        2 => (1.506, 1.248, 5.017),
        _ => {
            let g = m as f64 - 0.5;
            let q = (2.0 * m as f64 - 1.0) * PI;
            (g, g * g * (1.0 - 4.0 / q), g * g * (1.0 + 12.0 / q))
        }
    }
}

fn free_beam_fn(m: usize) -> BeamFn {
    match m {
        0 => BeamFn::Rigid0,
        1 => BeamFn::Rigid1,
        _ => BeamFn::elastic(BeamSupport::FreeFree, m - 1),
    }
}

impl Plate {
    /// A plate of `material` (density, `E`, `nu`).
    pub fn new(
        length_x_m: f64,
        length_y_m: f64,
        thickness_m: f64,
        material: &Material,
        edges: PlateEdges,
    ) -> Self {
        Plate {
            length_x_m,
            length_y_m,
            thickness_m,
            density_kg_m3: material.density_kg_m3,
            youngs_modulus_pa: material.youngs_modulus_pa,
            poisson_ratio: material.poisson_ratio,
            edges,
        }
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("plate.length_x_m", self.length_x_m)?;
        positive("plate.length_y_m", self.length_y_m)?;
        positive("plate.thickness_m", self.thickness_m)?;
        positive("plate.density_kg_m3", self.density_kg_m3)?;
        positive("plate.youngs_modulus_pa", self.youngs_modulus_pa)?;
        let nu = self.poisson_ratio;
        let lo = match self.edges {
            PlateEdges::SimplySupported => -1.0,
            PlateEdges::Free => 0.0,
        };
        let ok = match self.edges {
            PlateEdges::SimplySupported => nu > -1.0 && nu < 0.5,
            PlateEdges::Free => (0.0..0.5).contains(&nu),
        };
        if !ok {
            return Err(format!(
                "plate.poisson_ratio: must be in {}{lo}, 0.5) for {:?} edges, got {nu}",
                if lo < 0.0 { "(" } else { "[" },
                self.edges
            ));
        }
        Ok(())
    }

    /// Flexural rigidity `D = E h^3 / (12 (1 - nu^2))` \[N m\].
    pub fn flexural_rigidity(&self) -> f64 {
        self.youngs_modulus_pa * self.thickness_m.powi(3)
            / (12.0 * (1.0 - self.poisson_ratio * self.poisson_ratio))
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.thickness_m * self.length_x_m * self.length_y_m
    }

    /// Modes up to `max_freq_hz`, at most `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        check_limits(max_freq_hz, max_count)?;
        let (a, b) = (self.length_x_m, self.length_y_m);
        let rho_h = self.density_kg_m3 * self.thickness_m;
        let speed = (self.flexural_rigidity() / rho_h).sqrt();
        let scale_ss = 2.0 / (rho_h * a * b).sqrt();
        let scale_free = 1.0 / (rho_h * a * b).sqrt();
        let nu = self.poisson_ratio;
        let edges = self.edges;
        let freq = move |m: usize, n: usize| -> f64 {
            match edges {
                PlateEdges::SimplySupported => {
                    let (m, n) = (m as f64, n as f64);
                    PI * PI * (m * m / (a * a) + n * n / (b * b)) * speed / (2.0 * PI)
                }
                PlateEdges::Free => {
                    let (gx, hx, jx) = warburton_free(m);
                    let (gy, hy, jy) = warburton_free(n);
                    let r = a / b;
                    let l2 = gx.powi(4)
                        + gy.powi(4) * r.powi(4)
                        + 2.0 * r * r * (nu * hx * hy + (1.0 - nu) * jx * jy);
                    PI * PI / (a * a) * speed * l2.sqrt() / (2.0 * PI)
                }
            }
        };
        let start = match edges {
            PlateEdges::SimplySupported => 1,
            PlateEdges::Free => 0,
        };
        let mut out = Vec::new();
        if max_count == 0 {
            return Ok(out);
        }
        lattice_ascending(
            start,
            start,
            |m, n| Ok(freq(m, n)),
            |m, n, f| {
                if f > max_freq_hz {
                    return false;
                }
                let rigid = edges == PlateEdges::Free && m + n < 2;
                if !rigid {
                    let shape = match edges {
                        PlateEdges::SimplySupported => ModeShape::PlateSs {
                            a,
                            b,
                            m,
                            n,
                            scale: scale_ss,
                        },
                        PlateEdges::Free => ModeShape::PlateFree {
                            fx: free_beam_fn(m),
                            fy: free_beam_fn(n),
                            a,
                            b,
                            scale: scale_free,
                        },
                    };
                    out.push(ShapeMode {
                        freq_hz: f,
                        label: ModeLabel::Plate { m, n },
                        shape,
                    });
                }
                out.len() < max_count
            },
        )?;
        Ok(out)
    }
}

// ---------------------------------------------------------------------------
// Bessel functions
// ---------------------------------------------------------------------------

/// Power series of `J_m(x)` (accurate for small `x`).
fn bessel_j_series(m: usize, x: f64) -> f64 {
    let h = 0.5 * x;
    let mut term = 1.0;
    for k in 1..=m {
        term *= h / k as f64;
    }
    let mut sum = term;
    let h2 = h * h;
    for k in 1..200 {
        term *= -h2 / (k as f64 * (k + m) as f64);
        sum += term;
        if term.abs() <= 1e-17 * sum.abs() {
            break;
        }
    }
    sum
}

/// `(J_m(x), J_{m+1}(x))` for `x >= 0`.
fn bessel_j_pair(m: usize, x: f64) -> (f64, f64) {
    if x == 0.0 {
        return (if m == 0 { 1.0 } else { 0.0 }, 0.0);
    }
    if x < 1.0 {
        return (bessel_j_series(m, x), bessel_j_series(m + 1, x));
    }
    // Miller's backward recurrence from an even order well above max(m, x).
    let top = ((m + 1) as f64).max(x);
    let mut start = (top + (160.0 * top).sqrt() + 20.0).ceil() as usize;
    start += start % 2;
    let (mut a, mut b) = (0.0f64, 1.0f64); // J_{k+1}, J_k (unnormalised)
    let (mut jm, mut jm1) = (0.0, 0.0);
    let mut sum = 0.0;
    for k in (1..=start).rev() {
        let c = 2.0 * k as f64 / x * b - a; // J_{k-1}
        a = b;
        b = c;
        let order = k - 1;
        if order == m + 1 {
            jm1 = b;
        }
        if order == m {
            jm = b;
        }
        if order == 0 {
            sum += b;
        } else if order % 2 == 0 {
            sum += 2.0 * b;
        }
        if b.abs() > 1e200 {
            a *= 1e-200;
            b *= 1e-200;
            sum *= 1e-200;
            jm *= 1e-200;
            jm1 *= 1e-200;
        }
    }
    (jm / sum, jm1 / sum)
}

/// Bessel function of the first kind `J_m(x)`, integer `m >= 0`, `x >= 0`
/// (series below 1, Miller's backward recurrence above; absolute error
/// ~1e-14 near the zeros). `x < 0` uses `J_m(-x) = (-1)^m J_m(x)`; NaN
/// gives NaN.
pub fn bessel_j(m: usize, x: f64) -> f64 {
    if x < 0.0 {
        let v = bessel_j_pair(m, -x).0;
        return if m.is_multiple_of(2) { v } else { -v };
    }
    bessel_j_pair(m, x).0
}

/// Successive positive zeros of `J_m`.
struct BesselZeros {
    m: usize,
    next_start: f64,
}

impl BesselZeros {
    fn new(m: usize) -> Self {
        BesselZeros {
            m,
            next_start: (m as f64).max(1.0),
        }
    }

    fn next_zero(&mut self) -> Result<f64, String> {
        let m = self.m;
        let f = |x: f64| bessel_j_pair(m, x).0;
        let df = |x: f64| {
            let (j, j1) = bessel_j_pair(m, x);
            m as f64 / x * j - j1
        };
        let h = 0.5;
        let mut x0 = self.next_start;
        let mut f0 = f(x0);
        for _ in 0..1_000_000 {
            let x1 = x0 + h;
            let f1 = f(x1);
            if f0 == 0.0 || (f0 < 0.0) != (f1 < 0.0) {
                let root = if f0 == 0.0 {
                    x0
                } else {
                    safeguarded_newton(f, df, x0, x1, 0.5 * (x0 + x1))
                };
                self.next_start = root + 3.0;
                return Ok(root);
            }
            x0 = x1;
            f0 = f1;
        }
        Err(format!("bessel zero of J_{m}: no sign change found"))
    }
}

/// `j_mn`, the `n`-th (from 1) positive zero of `J_m`.
pub fn bessel_j_zero(m: usize, n: usize) -> Result<f64, String> {
    if n == 0 {
        return Err("bessel_j_zero: n counts from 1, got 0".to_string());
    }
    let mut z = BesselZeros::new(m);
    let mut x = 0.0;
    for _ in 0..n {
        x = z.next_zero()?;
    }
    Ok(x)
}

// ---------------------------------------------------------------------------
// Membrane
// ---------------------------------------------------------------------------

/// An ideal circular membrane with a fixed rim.
#[derive(Debug, Clone, PartialEq)]
pub struct Membrane {
    /// Radius `a` \[m\].
    pub radius_m: f64,
    /// Tension per unit length `T` \[N/m\].
    pub tension_n_per_m: f64,
    /// Areal density `sigma` \[kg/m^2\].
    pub areal_density_kg_m2: f64,
}

impl Membrane {
    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("membrane.radius_m", self.radius_m)?;
        positive("membrane.tension_n_per_m", self.tension_n_per_m)?;
        positive("membrane.areal_density_kg_m2", self.areal_density_kg_m2)?;
        Ok(())
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.areal_density_kg_m2 * PI * self.radius_m * self.radius_m
    }

    /// Modes up to `max_freq_hz`, at most `max_count` (a degenerate pair is
    /// listed whole or not at all), lowest first; the `cos` partner first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        check_limits(max_freq_hz, max_count)?;
        let a = self.radius_m;
        let sigma = self.areal_density_kg_m2;
        let hz_per_zero = (self.tension_n_per_m / sigma).sqrt() / a / (2.0 * PI);
        let mut out = Vec::new();
        if max_count == 0 {
            return Ok(out);
        }
        // zeros[m]: the zeros of J_m found so far, and the finder.
        let mut zeros: Vec<(Vec<f64>, BesselZeros)> = Vec::new();
        let mut zero = |m: usize, n: usize| -> Result<f64, String> {
            while zeros.len() <= m {
                let k = zeros.len();
                zeros.push((Vec::new(), BesselZeros::new(k)));
            }
            let (found, finder) = &mut zeros[m];
            while found.len() < n {
                found.push(finder.next_zero()?);
            }
            Ok(found[n - 1])
        };
        let mut pending: Option<String> = None;
        lattice_ascending(0, 1, &mut zero, |m, n, j| {
            let f = j * hz_per_zero;
            if f > max_freq_hz {
                return false;
            }
            let partners = if m == 0 { 1 } else { 2 };
            if out.len() + partners > max_count {
                return false;
            }
            let (_, j1) = bessel_j_pair(m, j);
            if !(j1 != 0.0 && j1.is_finite()) {
                pending = Some(format!("membrane: J_{}(j_{m}{n}) = {j1}", m + 1));
                return false;
            }
            let base = if m == 0 { 1.0 } else { 2f64.sqrt() };
            let scale = base / ((PI * sigma).sqrt() * a * j1.abs());
            for sine in [false, true].into_iter().take(partners) {
                out.push(ShapeMode {
                    freq_hz: f,
                    label: ModeLabel::Membrane { m, n, sine },
                    shape: ModeShape::Membrane {
                        radius: a,
                        m,
                        j,
                        sine,
                        scale,
                    },
                });
            }
            out.len() < max_count
        })?;
        match pending {
            Some(e) => Err(e),
            None => Ok(out),
        }
    }
}

// ---------------------------------------------------------------------------
// Stiff string
// ---------------------------------------------------------------------------

/// A string with bending stiffness, pinned ends.
#[derive(Debug, Clone, PartialEq)]
pub struct StiffString {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Tension `T` \[N\].
    pub tension_n: f64,
    /// Linear density `mu` \[kg/m\].
    pub linear_density_kg_m: f64,
    /// Bending stiffness `E I` \[N m^2\] (0: ideal string).
    pub bending_stiffness_n_m2: f64,
}

impl StiffString {
    /// A solid round wire of `material`: `mu = rho pi d^2 / 4`, `E I = E pi
    /// d^4 / 64`.
    pub fn round_wire(length_m: f64, tension_n: f64, diameter_m: f64, material: &Material) -> Self {
        StiffString {
            length_m,
            tension_n,
            linear_density_kg_m: material.density_kg_m3 * PI * diameter_m * diameter_m / 4.0,
            bending_stiffness_n_m2: material.youngs_modulus_pa * PI * diameter_m.powi(4) / 64.0,
        }
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("stiff_string.length_m", self.length_m)?;
        positive("stiff_string.tension_n", self.tension_n)?;
        positive("stiff_string.linear_density_kg_m", self.linear_density_kg_m)?;
        non_negative(
            "stiff_string.bending_stiffness_n_m2",
            self.bending_stiffness_n_m2,
        )?;
        Ok(())
    }

    /// `f_0 = sqrt(T / mu) / (2 L)` \[Hz\] (the ideal string's fundamental).
    pub fn ideal_fundamental_hz(&self) -> f64 {
        (self.tension_n / self.linear_density_kg_m).sqrt() / (2.0 * self.length_m)
    }

    /// Inharmonicity coefficient `B = pi^2 E I / (T L^2)`.
    pub fn inharmonicity(&self) -> f64 {
        PI * PI * self.bending_stiffness_n_m2 / (self.tension_n * self.length_m * self.length_m)
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.linear_density_kg_m * self.length_m
    }

    /// Modes up to `max_freq_hz`, at most `max_count`.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        check_limits(max_freq_hz, max_count)?;
        let f0 = self.ideal_fundamental_hz();
        let b = self.inharmonicity();
        let scale = (2.0 / (self.linear_density_kg_m * self.length_m)).sqrt();
        let mut out = Vec::new();
        for n in 1..=max_count {
            let nf = n as f64;
            let f = nf * f0 * (1.0 + b * nf * nf).sqrt();
            if f > max_freq_hz {
                break;
            }
            out.push(ShapeMode {
                freq_hz: f,
                label: ModeLabel::String { n },
                shape: ModeShape::String {
                    length: self.length_m,
                    n,
                    scale,
                },
            });
        }
        Ok(out)
    }
}

// ---------------------------------------------------------------------------
// All kinds
// ---------------------------------------------------------------------------

/// Any of the kinds above.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Rectangular bar.
    Bar(Bar),
    /// Round tube or rod.
    Tube(Tube),
    /// Rectangular plate.
    Plate(Plate),
    /// Circular membrane.
    Membrane(Membrane),
    /// Stiff string.
    StiffString(StiffString),
}

impl Shape {
    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        match self {
            Shape::Bar(s) => s.validate(),
            Shape::Tube(s) => s.validate(),
            Shape::Plate(s) => s.validate(),
            Shape::Membrane(s) => s.validate(),
            Shape::StiffString(s) => s.validate(),
        }
    }

    /// The modes of frequency `<= max_freq_hz` (`+inf` allowed), lowest
    /// first, at most `max_count` (`<= MAX_MODE_COUNT`).
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        match self {
            Shape::Bar(s) => s.modes(max_freq_hz, max_count),
            Shape::Tube(s) => s.modes(max_freq_hz, max_count),
            Shape::Plate(s) => s.modes(max_freq_hz, max_count),
            Shape::Membrane(s) => s.modes(max_freq_hz, max_count),
            Shape::StiffString(s) => s.modes(max_freq_hz, max_count),
        }
    }

    /// Total mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        match self {
            Shape::Bar(s) => s.mass_kg(),
            Shape::Tube(s) => s.mass_kg(),
            Shape::Plate(s) => s.mass_kg(),
            Shape::Membrane(s) => s.mass_kg(),
            Shape::StiffString(s) => s.mass_kg(),
        }
    }
}

// ---------------------------------------------------------------------------
// Loss model
// ---------------------------------------------------------------------------

/// Decay of each mode: `sigma(f) = sigma_0 + eta omega / 2 + sigma_r (f /
/// f_r)^p` \[1/s\], `T60 = ln(1000) / sigma`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossModel {
    /// Material loss factor `eta` (`Material::loss_factor`).
    pub loss_factor: f64,
    /// Frequency-independent decay rate `sigma_0` \[1/s\].
    pub decay_rate_per_s: f64,
    /// Radiation-like decay rate `sigma_r` at `radiation_ref_hz` \[1/s\].
    pub radiation_per_s: f64,
    /// Reference frequency `f_r` of the radiation term \[Hz\].
    pub radiation_ref_hz: f64,
    /// Exponent `p` of the radiation term.
    pub radiation_exponent: f64,
}

impl LossModel {
    /// Material damping only.
    pub fn material(loss_factor: f64) -> Self {
        LossModel {
            loss_factor,
            decay_rate_per_s: 0.0,
            radiation_per_s: 0.0,
            radiation_ref_hz: 1000.0,
            radiation_exponent: 2.0,
        }
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        non_negative("loss.loss_factor", self.loss_factor)?;
        non_negative("loss.decay_rate_per_s", self.decay_rate_per_s)?;
        non_negative("loss.radiation_per_s", self.radiation_per_s)?;
        positive("loss.radiation_ref_hz", self.radiation_ref_hz)?;
        non_negative("loss.radiation_exponent", self.radiation_exponent)?;
        Ok(())
    }

    /// Decay rate `sigma` \[1/s\] of a mode at `freq_hz`.
    pub fn decay_rate(&self, freq_hz: f64) -> Result<f64, String> {
        self.validate()?;
        non_negative("freq_hz", freq_hz)?;
        Ok(self.decay_rate_per_s
            + self.loss_factor * PI * freq_hz
            + self.radiation_per_s
                * (freq_hz / self.radiation_ref_hz).powf(self.radiation_exponent))
    }

    /// 60 dB decay time \[s\] of a mode at `freq_hz`; `None` when undamped.
    pub fn t60_s(&self, freq_hz: f64) -> Result<Option<f64>, String> {
        let sigma = self.decay_rate(freq_hz)?;
        Ok(if sigma > 0.0 {
            Some(1000f64.ln() / sigma)
        } else {
            None
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;

    /// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n).
    fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
        }
        out
    }

    /// Composite 16-point Gauss-Legendre on [lo, hi] with `panels` panels:
    /// the nodes and weights.
    fn composite(lo: f64, hi: f64, panels: usize) -> Vec<(f64, f64)> {
        let gl = gauss_legendre(16);
        let h = (hi - lo) / panels as f64;
        let mut out = Vec::with_capacity(panels * 16);
        for p in 0..panels {
            let c = lo + (p as f64 + 0.5) * h;
            for &(x, w) in &gl {
                out.push((c + 0.5 * h * x, 0.5 * h * w));
            }
        }
        out
    }

    /// The mass matrix `integral rho Phi_i Phi_j dV` of `modes` on a line
    /// of mass per length `rho_a` and length `l`.
    fn line_gram(modes: &[ShapeMode], rho_a: f64, l: f64, panels: usize) -> Vec<Vec<f64>> {
        let q = composite(0.0, l, panels);
        let vals: Vec<Vec<f64>> = modes
            .iter()
            .map(|m| {
                q.iter()
                    .map(|&(x, _)| m.shape_at(Point::Line(x)).unwrap())
                    .collect()
            })
            .collect();
        gram(
            &vals,
            &q.iter().map(|&(_, w)| rho_a * w).collect::<Vec<_>>(),
        )
    }

    fn gram(vals: &[Vec<f64>], w: &[f64]) -> Vec<Vec<f64>> {
        let n = vals.len();
        let mut g = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in 0..=i {
                let s: f64 = (0..w.len()).map(|k| w[k] * vals[i][k] * vals[j][k]).sum();
                g[i][j] = s;
                g[j][i] = s;
            }
        }
        g
    }

    /// Largest `|G - I|` entry, printed with the kind's name.
    fn identity_residual(name: &str, g: &[Vec<f64>]) -> f64 {
        let mut diag: f64 = 0.0;
        let mut off: f64 = 0.0;
        for (i, row) in g.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                if i == j {
                    diag = diag.max((v - 1.0).abs());
                } else {
                    off = off.max(v.abs());
                }
            }
        }
        println!(
            "{name}: {} modes, max |M_ii - 1| = {diag:.2e}, max |M_ij| = {off:.2e}",
            g.len()
        );
        diag.max(off)
    }

    fn rosewood_bar() -> Bar {
        let m = material("rosewood").unwrap();
        Bar::new(0.4, 0.06, 0.02, &m, BeamSupport::FreeFree)
    }

    // -- beam roots ---------------------------------------------------------

    #[test]
    fn free_free_roots_match_the_published_table() {
        // Blevins, Formulas for Natural Frequency and Mode Shape, table 8-1.
        let table = [
            4.730040745,
            7.853204624,
            10.99560784,
            14.13716549,
            17.27875966,
        ];
        for (i, &t) in table.iter().enumerate() {
            let u = beam_root(BeamSupport::FreeFree, i + 1);
            let res = u - t;
            println!(
                "free-free u_{} = {u:.12}, table {t}, residual {res:.2e}",
                i + 1
            );
            // The table has 10 significant digits: half a unit of the last.
            assert!(res.abs() < 5.01e-9, "{res}");
            assert!(((u.cos() * u.cosh()) - 1.0).abs() < 1e-12 * u.cosh());
        }
        for n in [10, 100, 1000] {
            let u = beam_root(BeamSupport::FreeFree, n);
            let asym = (2 * n + 1) as f64 * PI / 2.0;
            println!("free-free u_{n} - (2n+1) pi/2 = {:.2e}", u - asym);
            assert!((u - asym).abs() < 1e-12 * asym);
        }
    }

    #[test]
    fn clamped_free_roots_match_the_published_table() {
        let table = [
            1.875104069,
            4.694091133,
            7.854757438,
            10.99554073,
            14.13716839,
        ];
        for (i, &t) in table.iter().enumerate() {
            let u = beam_root(BeamSupport::ClampedFree, i + 1);
            let res = u - t;
            println!(
                "clamped-free u_{} = {u:.12}, table {t}, residual {res:.2e}",
                i + 1
            );
            // The table has 10 significant digits: half a unit of the last.
            assert!(res.abs() < 5.01e-9, "{res}");
        }
    }

    #[test]
    fn free_free_frequency_ratios() {
        let modes = rosewood_bar().modes(f64::INFINITY, 4).unwrap();
        let f1 = modes[0].freq_hz;
        for (m, t) in modes[1..].iter().zip([2.756, 5.404, 8.933]) {
            let r = m.freq_hz / f1;
            println!(
                "{}: ratio {r:.5}, table {t}, residual {:.1e}",
                m.label,
                r - t
            );
            assert!((r - t).abs() < 6e-4, "{r}");
        }
    }

    // -- beam shapes --------------------------------------------------------

    #[test]
    fn beam_shapes_are_mass_normalised_and_orthogonal_by_quadrature() {
        let bar = rosewood_bar();
        let rho_a = bar.density_kg_m3 * bar.width_m * bar.thickness_m;
        for support in [BeamSupport::FreeFree, BeamSupport::ClampedFree] {
            let b = Bar {
                support,
                ..bar.clone()
            };
            let modes = b.modes(f64::INFINITY, 12).unwrap();
            let g = line_gram(&modes, rho_a, b.length_m, 64);
            let res = identity_residual(&format!("bar {support:?}"), &g);
            assert!(res < 1e-10, "{res}");
        }
        // A high mode: the overflow-free form stays bounded and normalised
        // (with cosh/sinh written out, cosh(200) alone is 3.6e86).
        let b = bar.clone();
        let modes = b.modes(f64::INFINITY, 64).unwrap();
        let high = &modes[62..64];
        let g = line_gram(high, rho_a, b.length_m, 400);
        let res = identity_residual("bar free-free modes 63-64", &g);
        assert!(res < 1e-9, "{res}");
    }

    #[test]
    fn beam_end_values_match_the_classical_results() {
        // With integral phi^2 = L: a free end has |phi| = 2 (free-free: both
        // ends, clamped-free: the tip), a clamped end phi = 0 with zero slope.
        let bar = rosewood_bar();
        let scale = (bar.mass_kg()).sqrt();
        let l = bar.length_m;
        let ff = bar.modes(f64::INFINITY, 30).unwrap();
        let cf = Bar {
            support: BeamSupport::ClampedFree,
            ..bar.clone()
        }
        .modes(f64::INFINITY, 30)
        .unwrap();
        let mut worst: f64 = 0.0;
        for m in &ff {
            let e0 = m.shape_at(Point::Line(0.0)).unwrap() * scale;
            let el = m.shape_at(Point::Line(l)).unwrap() * scale;
            worst = worst
                .max((e0.abs() - 2.0).abs())
                .max((el.abs() - 2.0).abs());
        }
        for m in &cf {
            let tip = m.shape_at(Point::Line(l)).unwrap() * scale;
            let root = m.shape_at(Point::Line(0.0)).unwrap() * scale;
            let h = 1e-7 * l;
            let slope = (m.shape_at(Point::Line(h)).unwrap() * scale - root) / h * l;
            worst = worst.max((tip.abs() - 2.0).abs()).max(root.abs());
            // phi ~ u^2 xi^2 near the clamp: the one-sided slope is ~u^2 h/L.
            assert!(slope.abs() < 1e-3, "{}: slope {slope}", m.label);
        }
        println!("beam end values: worst residual {worst:.2e}");
        assert!(worst < 1e-9, "{worst}");
    }

    // -- physical sanity ----------------------------------------------------

    #[test]
    fn rosewood_bar_fundamental_is_as_computed_by_hand() {
        // 0.4 x 0.06 x 0.02 m rosewood (rho 1000 kg/m^3, E 20 GPa), uniform,
        // free-free: r = h / sqrt(12) = 5.7735e-3 m, c = sqrt(E / rho) =
        // 4472.1 m/s, f1 = 4.7300^2 r c / (2 pi L^2) = 22.3733 * 5.7735e-3 *
        // 4472.1 / 1.00531 = 574.6 Hz (about D5). Over the published range of
        // Honduras rosewood (E 17-26 GPa, rho 900-1050 kg/m^3) f1 stays in
        // 517-691 Hz.
        let f1 = rosewood_bar().modes(f64::INFINITY, 1).unwrap()[0].freq_hz;
        println!("rosewood bar f1 = {f1:.3} Hz (hand: 574.6 Hz)");
        assert!((f1 / 574.6 - 1.0).abs() < 5e-4, "{f1}");
        assert!(f1 > 517.0 && f1 < 691.0);
    }

    #[test]
    fn aluminium_chime_is_as_computed_by_hand() {
        // 6061 tube, L = 1 m, D = 25.4 mm, wall 1.5 mm (d = 22.4 mm):
        // A = pi (D^2 - d^2) / 4 = 1.1263e-4 m^2, I = pi (D^4 - d^4) / 64 =
        // 8.0735e-9 m^4, r^2 = I / A = (D^2 + d^2) / 16 = 7.1683e-5 m^2,
        // c = sqrt(68.9e9 / 2700) = 5051.5 m/s,
        // f1 = 22.3733 * 8.4666e-3 * 5051.5 / (2 pi) = 152.29 Hz (about D3),
        // then 419.8, 823.0 Hz (ratios 2.756, 5.404).
        let al = material("aluminium").unwrap();
        let tube = Tube::new(1.0, 0.0254, 0.0224, &al);
        println!(
            "chime: A = {:.5e} m^2, I = {:.5e} m^4",
            tube.area_m2(),
            tube.second_moment_m4()
        );
        assert!((tube.area_m2() / 1.1263e-4 - 1.0).abs() < 1e-4);
        assert!((tube.second_moment_m4() / 8.0735e-9 - 1.0).abs() < 1e-4);
        let modes = tube.modes(1000.0, 10).unwrap();
        let f: Vec<f64> = modes.iter().map(|m| m.freq_hz).collect();
        println!("chime modes up to 1 kHz: {f:.2?}");
        assert_eq!(f.len(), 3);
        assert!((f[0] / 152.29 - 1.0).abs() < 3e-4, "{}", f[0]);
        assert!((f[1] / 419.8 - 1.0).abs() < 5e-4 && (f[2] / 823.0 - 1.0).abs() < 5e-4);
        // Mass normalisation of the tube by quadrature.
        let rho_a = al.density_kg_m3 * tube.area_m2();
        let g = line_gram(&modes, rho_a, 1.0, 64);
        assert!(identity_residual("tube", &g) < 1e-10);
        // Thin-walled tube: the Timoshenko correction is tiny for r/L ~ 0.008.
        // Timoshenko: a thin wall has a small Cowper coefficient (~0.53), so
        // E / (kappa G) ~ 5 and the first-order lowering s (1 + e) / 2, s =
        // (u_1 r / L)^2 = 1.60e-3, is ~4.8e-3.
        let timo = tube
            .clone()
            .with_timoshenko(al.shear_modulus_pa, al.poisson_ratio);
        let kappa = timo.shear.map(|s| s.shear_coefficient).unwrap();
        let t = timo.modes(1000.0, 3).unwrap();
        let low = 1.0 - t[0].freq_hz / f[0];
        let s = (beam_root(BeamSupport::FreeFree, 1) * 0.0254f64.hypot(0.0224) / 4.0).powi(2);
        let first = 0.5 * s * (1.0 + al.youngs_modulus_pa / (kappa * al.shear_modulus_pa));
        println!(
            "chime: kappa {kappa:.4}, Timoshenko lowers f1 by {low:.4e} (first order {first:.4e})"
        );
        assert!(kappa > 0.5 && kappa < 0.56);
        assert!(low > 0.0 && (low / first - 1.0).abs() < 0.02);
    }

    // -- Timoshenko ---------------------------------------------------------

    #[test]
    fn timoshenko_lowers_frequencies_by_the_expected_amount() {
        let al = material("aluminium").unwrap();
        let iso_g = |e: f64, nu: f64| e / (2.0 * (1.0 + nu));
        let nu = 0.3;
        let e = al.youngs_modulus_pa;
        for h_over_l in [0.01, 0.05, 0.1] {
            let l = 0.5;
            let bar = Bar {
                length_m: l,
                width_m: 0.03,
                thickness_m: h_over_l * l,
                density_kg_m3: al.density_kg_m3,
                youngs_modulus_pa: e,
                support: BeamSupport::FreeFree,
                shear: None,
                tuning: Vec::new(),
                fundamental_hz: None,
                torsion: None,
            };
            let eb = bar.modes(f64::INFINITY, 6).unwrap();
            let ti = bar
                .clone()
                .with_timoshenko(iso_g(e, nu))
                .modes(f64::INFINITY, 6)
                .unwrap();
            let mut last = 0.0;
            for (a, b) in eb.iter().zip(&ti) {
                let low = 1.0 - b.freq_hz / a.freq_hz;
                assert!(low > last, "lowering must grow with mode number");
                last = low;
                // First order: s (1 + E / (kappa G)) / 2.
                let u = beam_root(
                    BeamSupport::FreeFree,
                    match a.label {
                        ModeLabel::Bending { n } => n,
                        _ => unreachable!(),
                    },
                );
                let s = (u * h_over_l).powi(2) / 12.0;
                let first = 0.5 * s * (1.0 + 2.0 * (1.0 + nu) / (5.0 / 6.0));
                if h_over_l == 0.01 {
                    let rel = low / first - 1.0;
                    println!(
                        "h/L 0.01 {}: lowering {low:.4e}, first order {first:.4e}, rel {rel:.1e}",
                        a.label
                    );
                    assert!(rel.abs() < 0.02, "{rel}");
                }
            }
            // ASTM E1876 (Spinner & Tefft 1961): f_T = f_EB / sqrt(T1),
            // T1 = 1 + 6.585 (1 + 0.0752 nu + 0.8109 nu^2) t^2 - 0.868 t^4
            //   - 8.340 (1 + 0.2023 nu + 2.173 nu^2) t^4
            //     / (1 + 6.338 (1 + 0.1408 nu + 1.536 nu^2) t^2), t = h / L.
            let t = h_over_l;
            let t1 = 1.0 + 6.585 * (1.0 + 0.0752 * nu + 0.8109 * nu * nu) * t * t
                - 0.868 * t.powi(4)
                - 8.340 * (1.0 + 0.2023 * nu + 2.173 * nu * nu) * t.powi(4)
                    / (1.0 + 6.338 * (1.0 + 0.1408 * nu + 1.536 * nu * nu) * t * t);
            let astm = 1.0 - 1.0 / t1.sqrt();
            let ours = 1.0 - ti[0].freq_hz / eb[0].freq_hz;
            let rel = ours / astm - 1.0;
            println!(
                "h/L {h_over_l}: mode 1 lowered by {ours:.4e}, ASTM E1876 {astm:.4e}, rel {rel:+.3}"
            );
            assert!(rel.abs() < 0.1, "{rel}");
        }
        // A thick wooden bar (E / G ~ 14): a large correction, still lower.
        let rw = material("rosewood").unwrap();
        let bar = rosewood_bar();
        let eb = bar.modes(f64::INFINITY, 4).unwrap();
        let ti = bar
            .with_timoshenko(rw.shear_modulus_pa)
            .modes(f64::INFINITY, 4)
            .unwrap();
        let lows: Vec<f64> = eb
            .iter()
            .zip(&ti)
            .map(|(a, b)| 1.0 - b.freq_hz / a.freq_hz)
            .collect();
        println!("rosewood bar 0.4 x 0.02: Timoshenko lowering {lows:.4?}");
        assert!(lows[0] > 0.01 && lows[3] > lows[0]);
    }

    // -- tuned bars ---------------------------------------------------------

    #[test]
    fn tuned_bar_reproduces_its_target_ratios() {
        let bar = rosewood_bar();
        let uniform = bar.modes(f64::INFINITY, 6).unwrap();
        let tuned = bar
            .clone()
            .with_tuning(&[1.0, 4.0, 10.0])
            .modes(f64::INFINITY, 6)
            .unwrap();
        let f1 = tuned[0].freq_hz;
        assert_eq!(f1, uniform[0].freq_hz, "fundamental kept");
        for (i, t) in [1.0, 4.0, 10.0].iter().enumerate() {
            let r = tuned[i].freq_hz / f1;
            println!("tuned mode {}: ratio {r:.12}, target {t}", i + 1);
            assert!((r - t).abs() < 1e-12);
        }
        for i in 3..6 {
            let want = tuned[2].freq_hz * uniform[i].freq_hz / uniform[2].freq_hz;
            assert!((tuned[i].freq_hz / want - 1.0).abs() < 1e-14);
            assert_eq!(
                tuned[i].shape_at(Point::Line(0.1)),
                uniform[i].shape_at(Point::Line(0.1))
            );
        }
        // Ratios relative to the first entry; the frequency limit applies to
        // the tuned frequencies.
        let limited = bar
            .clone()
            .with_tuning(&[2.0, 8.0])
            .modes(3.5 * f1, 10)
            .unwrap();
        assert_eq!(limited.len(), 1);
        let err = bar.with_tuning(&[1.0, 4.0, 3.0]).modes(1e4, 5).unwrap_err();
        assert!(err.contains("bar.tuning[2]"), "{err}");
    }

    /// A tuned fundamental: the tuned modes at `F t_i / t_1`, the untuned
    /// ones' factors extrapolated geometrically towards 1, checked against
    /// the hand computation for an A3 marimba bar (rosewood 1050 kg/m^3, 20
    /// GPa, 400 x 58 x 22 mm, Euler-Bernoulli: uniform 617, 1700, 3333, 5510,
    /// 8231, 11497 Hz; factors 0.357, 0.518, 0.660; `r` = 0.705; modes 4-6
    /// at 4190, 6841, 10129 Hz).
    #[test]
    fn tuned_fundamental_extrapolates_the_factors() {
        let m = Material {
            density_kg_m3: 1050.0,
            youngs_modulus_pa: 20e9,
            ..material("rosewood").unwrap()
        };
        let bar = Bar::new(0.4, 0.058, 0.022, &m, BeamSupport::FreeFree);
        let uniform = bar.modes(f64::INFINITY, 6).unwrap();
        let tuned = bar
            .clone()
            .with_tuning(&[1.0, 4.0, 10.0])
            .with_fundamental(220.0)
            .modes(f64::INFINITY, 6)
            .unwrap();
        let f: Vec<f64> = tuned.iter().map(|m| m.freq_hz).collect();
        println!("tuned A3 bar: {f:.1?}");
        for (i, want) in [220.0, 880.0, 2200.0].iter().enumerate() {
            assert!((f[i] / want - 1.0).abs() < 1e-14);
        }
        let q: Vec<f64> = (0..3).map(|i| f[i] / uniform[i].freq_hz).collect();
        let r = (1.0 - q[2]) / (1.0 - q[1]);
        for i in 3..6 {
            let want = (1.0 - (1.0 - q[2]) * r.powi(i as i32 - 2)) * uniform[i].freq_hz;
            assert!((f[i] / want - 1.0).abs() < 1e-14);
        }
        for (got, hand) in f[3..].iter().zip([4190.0, 6841.0, 10129.0]) {
            assert!((got / hand - 1.0).abs() < 1e-3, "{got} vs {hand}");
        }
        let err = bar
            .clone()
            .with_fundamental(220.0)
            .modes(1e4, 5)
            .unwrap_err();
        assert!(err.contains("bar.fundamental_hz"), "{err}");
    }

    // -- plates -------------------------------------------------------------

    fn plate_gram(p: &Plate, modes: &[ShapeMode], panels: usize) -> Vec<Vec<f64>> {
        let qx = composite(0.0, p.length_x_m, panels);
        let qy = composite(0.0, p.length_y_m, panels);
        let rho_h = p.density_kg_m3 * p.thickness_m;
        let mut w = Vec::new();
        let mut pts = Vec::new();
        for &(x, wx) in &qx {
            for &(y, wy) in &qy {
                pts.push(Point::Plane { x, y });
                w.push(rho_h * wx * wy);
            }
        }
        let vals: Vec<Vec<f64>> = modes
            .iter()
            .map(|m| pts.iter().map(|&p| m.shape_at(p).unwrap()).collect())
            .collect();
        gram(&vals, &w)
    }

    #[test]
    fn simply_supported_plate_matches_the_closed_form() {
        let steel = material("steel").unwrap();
        let p = Plate::new(0.5, 0.3, 0.002, &steel, PlateEdges::SimplySupported);
        let modes = p.modes(f64::INFINITY, 40).unwrap();
        // Closed form, computed independently over a 40 x 40 grid and sorted.
        let d = steel.youngs_modulus_pa * 0.002f64.powi(3) / (12.0 * (1.0 - 0.29f64 * 0.29));
        let c = (d / (steel.density_kg_m3 * 0.002)).sqrt();
        let mut all = Vec::new();
        for m in 1..=40 {
            for n in 1..=40 {
                let (mf, nf) = (m as f64, n as f64);
                all.push(PI / 2.0 * (mf * mf / 0.25 + nf * nf / 0.09) * c);
            }
        }
        all.sort_by(f64::total_cmp);
        let mut worst: f64 = 0.0;
        for (m, want) in modes.iter().zip(&all) {
            worst = worst.max((m.freq_hz / want - 1.0).abs());
        }
        println!(
            "SS plate: f11 = {:.3} Hz, 40 modes, worst rel residual vs closed form {worst:.1e}",
            modes[0].freq_hz
        );
        assert!(worst < 1e-14);
        assert_eq!(modes[0].label, ModeLabel::Plate { m: 1, n: 1 });
        let g = plate_gram(&p, &modes[..12], 8);
        assert!(identity_residual("SS plate", &g) < 1e-10);
        // Limits: by frequency.
        let f_lim = modes[9].freq_hz;
        assert_eq!(p.modes(f_lim, 100).unwrap().len(), 10);
    }

    #[test]
    fn free_plate_warburton_against_leissa_and_quadrature() {
        // Leissa (1969), square FFFF plate, nu = 0.3, omega a^2 sqrt(rho h /
        // D): 13.468 (twist), 19.596, 24.270 (the (2,0) -+ (0,2) pair),
        // 34.801 (double).
        let mut p = Plate::new(
            0.3,
            0.3,
            0.003,
            &material("aluminium").unwrap(),
            PlateEdges::Free,
        );
        p.poisson_ratio = 0.3;
        let unit = (p.flexural_rigidity() / (p.density_kg_m3 * p.thickness_m)).sqrt()
            / (p.length_x_m * p.length_x_m)
            / (2.0 * PI);
        let modes = p.modes(f64::INFINITY, 30).unwrap();
        let lam: Vec<f64> = modes.iter().map(|m| m.freq_hz / unit).collect();
        println!(
            "free plate: {:?}",
            modes
                .iter()
                .zip(&lam)
                .take(6)
                .map(|(m, l)| format!("{} {l:.3}", m.label))
                .collect::<Vec<_>>()
        );
        assert_eq!(modes[0].label, ModeLabel::Plate { m: 1, n: 1 });
        let twist = lam[0] / 13.468 - 1.0;
        assert!(twist.abs() < 0.06, "{twist}");
        assert!(lam[1] > 19.596 && lam[1] < 24.270 && (lam[1] - lam[2]).abs() < 1e-9);
        let l12 = lam[3] / 34.801 - 1.0;
        assert!(l12.abs() < 0.06, "{l12}");
        println!("free plate: twist rel {twist:+.3}, (1,2) rel {l12:+.3}");
        // No rigid modes; all labels distinct.
        assert!(modes
            .iter()
            .all(|m| !matches!(m.label, ModeLabel::Plate { m, n } if m + n < 2)));
        let g = plate_gram(&p, &modes[..12], 8);
        assert!(identity_residual("free plate", &g) < 1e-10);
        // nu < 0 is refused for free edges.
        p.poisson_ratio = -0.1;
        let err = p.modes(1e4, 5).unwrap_err();
        assert!(err.contains("plate.poisson_ratio"), "{err}");
    }

    // -- Bessel and membrane ------------------------------------------------

    #[test]
    fn bessel_values_against_reference_and_series() {
        // Abramowitz & Stegun table 9.1 values.
        for (m, x, want) in [
            (0, 1.0, 0.765_197_686_557_966_6),
            (1, 1.0, 0.440_050_585_744_933_5),
            (0, 10.0, -0.245_935_764_451_348_3),
            (1, 10.0, 0.043_472_746_168_861_44),
            (0, 0.5, 0.938_469_807_240_813),
        ] {
            let v = bessel_j(m, x);
            println!("J_{m}({x}) = {v:.16}, residual {:.1e}", v - want);
            assert!((v - want).abs() < 2e-15, "{v}");
        }
        // Miller against the series (mild cancellation below x = 8).
        let mut worst: f64 = 0.0;
        for m in 0..12 {
            for i in 0..40 {
                let x = 1.0 + 0.175 * i as f64;
                worst = worst.max((bessel_j(m, x) - bessel_j_series(m, x)).abs());
            }
        }
        println!("Miller vs series on [1, 8], m < 12: max |diff| {worst:.1e}");
        assert!(worst < 1e-13);
        // The normalisation identity at large x, and continuity at x = 1.
        let x = 150.0;
        let s: f64 = bessel_j(0, x) + 2.0 * (1..200).map(|k| bessel_j(2 * k, x)).sum::<f64>();
        assert!((s - 1.0).abs() < 1e-13);
        assert!((bessel_j(3, 1.0 - 1e-12) - bessel_j(3, 1.0)).abs() < 1e-13);
    }

    #[test]
    fn bessel_zeros_match_the_published_table() {
        // Abramowitz & Stegun table 9.5.
        let table = [
            (0, 1, 2.404_825_557_695_773),
            (0, 2, 5.520_078_110_286_311),
            (0, 3, 8.653_727_912_911_013),
            (1, 1, 3.831_705_970_207_512),
            (1, 2, 7.015_586_669_815_619),
            (2, 1, 5.135_622_301_840_683),
            (2, 2, 8.417_244_140_399_865),
            (3, 1, 6.380_161_895_923_984),
            (4, 1, 7.588_342_434_503_804),
        ];
        for (m, n, want) in table {
            let z = bessel_j_zero(m, n).unwrap();
            println!("j_{m}{n} = {z:.15}, residual {:.1e}", z - want);
            assert!((z - want).abs() < 1e-13, "{z}");
        }
        // Far zeros against McMahon's expansion (error O(beta^-7) ~ 1e-13).
        for m in [0usize, 1, 2] {
            let n = 30;
            let beta = (n as f64 + m as f64 / 2.0 - 0.25) * PI;
            let mu = 4.0 * (m * m) as f64;
            let b8 = 8.0 * beta;
            let mc = beta
                - (mu - 1.0) / b8
                - 4.0 * (mu - 1.0) * (7.0 * mu - 31.0) / (3.0 * b8.powi(3))
                - 32.0 * (mu - 1.0) * (83.0 * mu * mu - 982.0 * mu + 3779.0) / (15.0 * b8.powi(5));
            let z = bessel_j_zero(m, n).unwrap();
            println!("j_{m},{n} = {z:.13}, McMahon residual {:.1e}", z - mc);
            assert!((z - mc).abs() < 1e-10);
        }
        assert!(bessel_j_zero(0, 0).is_err());
    }

    fn drum() -> Membrane {
        Membrane {
            radius_m: 0.18,
            tension_n_per_m: 3000.0,
            areal_density_kg_m2: 0.26,
        }
    }

    #[test]
    fn membrane_ratios_pairs_and_limits() {
        let m = drum();
        let modes = m.modes(f64::INFINITY, 7).unwrap();
        let labels: Vec<String> = modes.iter().map(|x| x.label.to_string()).collect();
        println!("membrane: {labels:?}");
        // (0,1), (1,1) cos+sin, (2,1) cos+sin, (0,2): 6 modes, the (3,1) pair
        // does not fit in 7.
        assert_eq!(modes.len(), 6);
        let f1 = modes[0].freq_hz;
        let c = (3000.0f64 / 0.26).sqrt() / 0.18 / (2.0 * PI);
        assert!((f1 / (2.404_825_557_695_773 * c) - 1.0).abs() < 1e-14);
        // The quoted ratios 1.594, 2.136, 2.296 are rounded (and the first
        // is 1.5933 to four places): within 1e-3 of them, and exactly the
        // ratios of the tabulated zeros.
        for (i, t, exact) in [
            (1, 1.594, 3.831_705_970_207_512 / 2.404_825_557_695_773),
            (3, 2.136, 5.135_622_301_840_683 / 2.404_825_557_695_773),
            (5, 2.296, 5.520_078_110_286_311 / 2.404_825_557_695_773),
        ] {
            let r = modes[i].freq_hz / f1;
            println!(
                "{}: ratio {r:.6}, quoted {t}, from the zero table {exact:.6}, residual {:.1e}",
                modes[i].label,
                r - exact
            );
            assert!((r - t).abs() < 1e-3);
            assert!((r - exact).abs() < 1e-12);
        }
        assert_eq!(modes[1].freq_hz, modes[2].freq_hz);
        assert_eq!(
            modes[2].label,
            ModeLabel::Membrane {
                m: 1,
                n: 1,
                sine: true
            }
        );
        // The rim is a node; J_m(0) = 0 for m > 0.
        for md in &modes {
            assert!(
                md.shape_at(Point::Polar {
                    r: 0.18,
                    theta: 0.3
                })
                .unwrap()
                .abs()
                    < 1e-13
            );
        }
        assert!(
            modes[1]
                .shape_at(Point::Polar { r: 0.0, theta: 0.0 })
                .unwrap()
                == 0.0
        );
        // Frequency limit.
        assert_eq!(m.modes(modes[3].freq_hz, 100).unwrap().len(), 5);
    }

    #[test]
    fn membrane_is_mass_normalised_and_orthogonal_by_quadrature() {
        let mb = drum();
        let modes = mb.modes(f64::INFINITY, 20).unwrap();
        // r: composite Gauss-Legendre with the r dr weight; theta: the
        // trapezoid rule, exact for these trigonometric polynomials.
        let qr = composite(0.0, mb.radius_m, 12);
        let nt = 64;
        let mut pts = Vec::new();
        let mut w = Vec::new();
        for &(r, wr) in &qr {
            for k in 0..nt {
                let theta = 2.0 * PI * k as f64 / nt as f64;
                pts.push(Point::Polar { r, theta });
                w.push(mb.areal_density_kg_m2 * r * wr * 2.0 * PI / nt as f64);
            }
        }
        let vals: Vec<Vec<f64>> = modes
            .iter()
            .map(|m| pts.iter().map(|&p| m.shape_at(p).unwrap()).collect())
            .collect();
        let g = gram(&vals, &w);
        assert!(identity_residual("membrane", &g) < 1e-10);
    }

    // -- stiff string -------------------------------------------------------

    #[test]
    fn stiff_string_inharmonicity_pde_and_normalisation() {
        // Steel wire d = 1 mm, L = 0.65 m, T = 700 N: mu = 7870 pi (0.5e-3)^2
        // = 6.181e-3 kg/m, f0 = sqrt(700 / mu) / 1.3 = 258.9 Hz, EI = 205e9 pi
        // 1e-12 / 64 = 1.0063e-2 N m^2, B = pi^2 EI / (T L^2) = 3.358e-4 (the
        // order of piano strings' B, 1e-4..1e-3, Fletcher & Rossing ch. 12).
        let s = StiffString::round_wire(0.65, 700.0, 1e-3, &material("steel").unwrap());
        let b = s.inharmonicity();
        println!(
            "string: f0 = {:.2} Hz, B = {b:.4e}",
            s.ideal_fundamental_hz()
        );
        assert!((s.ideal_fundamental_hz() / 258.9 - 1.0).abs() < 5e-4);
        assert!((b / 3.358e-4 - 1.0).abs() < 1e-3);
        let modes = s.modes(f64::INFINITY, 30).unwrap();
        for m in &modes {
            let ModeLabel::String { n } = m.label else {
                unreachable!()
            };
            let nf = n as f64;
            // Inharmonicity: f_n / (n f_1) = sqrt((1 + B n^2) / (1 + B)).
            let r = m.freq_hz / (nf * modes[0].freq_hz);
            assert!((r - ((1.0 + b * nf * nf) / (1.0 + b)).sqrt()).abs() < 1e-14);
            // The PDE mu omega^2 phi = -T phi'' + EI phi'''' by finite
            // differences at an interior point.
            let x = 0.2371;
            let h = 2e-3 / nf;
            let p = |k: f64| m.shape_at(Point::Line(x + k * h)).unwrap();
            let d2 = (p(1.0) - 2.0 * p(0.0) + p(-1.0)) / (h * h);
            let d4 = (p(2.0) - 4.0 * p(1.0) + 6.0 * p(0.0) - 4.0 * p(-1.0) + p(-2.0)) / h.powi(4);
            let lhs = s.linear_density_kg_m * m.omega().powi(2) * p(0.0);
            let rhs = -s.tension_n * d2 + s.bending_stiffness_n_m2 * d4;
            let scale = s.linear_density_kg_m
                * m.omega().powi(2)
                * m.shape_at(Point::Line(0.0))
                    .unwrap()
                    .abs()
                    .max((2.0 / (s.linear_density_kg_m * 0.65)).sqrt());
            if n <= 10 {
                assert!((lhs - rhs).abs() < 1e-4 * scale, "n {n}: {lhs} vs {rhs}");
            }
        }
        let r30 = modes[29].freq_hz / (30.0 * modes[0].freq_hz);
        println!(
            "string: f30 / (30 f1) = {r30:.6} (stretch {:.2} cents)",
            1200.0 * r30.log2()
        );
        let g = line_gram(&modes[..15], s.linear_density_kg_m, 0.65, 32);
        assert!(identity_residual("stiff string", &g) < 1e-10);
        // B = 0: harmonic.
        let ideal = StiffString {
            bending_stiffness_n_m2: 0.0,
            ..s
        };
        let h = ideal.modes(f64::INFINITY, 5).unwrap();
        assert!((h[4].freq_hz / h[0].freq_hz - 5.0).abs() < 1e-14);
    }

    // -- loss model ---------------------------------------------------------

    #[test]
    fn loss_model_t60() {
        let eta = 0.005;
        let loss = LossModel::material(eta);
        let f = 440.0;
        let t60 = loss.t60_s(f).unwrap().unwrap();
        let want = 2.0 * 1000f64.ln() / (eta * 2.0 * PI * f);
        println!("eta {eta}, {f} Hz: T60 {t60:.6} s (2 ln 1000 / (eta omega) = {want:.6})");
        assert!((t60 / want - 1.0).abs() < 1e-15);
        let full = LossModel {
            loss_factor: eta,
            decay_rate_per_s: 0.5,
            radiation_per_s: 2.0,
            radiation_ref_hz: 1000.0,
            radiation_exponent: 2.0,
        };
        let sigma = full.decay_rate(2000.0).unwrap();
        assert!((sigma - (0.5 + eta * PI * 2000.0 + 8.0)).abs() < 1e-12);
        assert_eq!(LossModel::material(0.0).t60_s(100.0).unwrap(), None);
        let bad = LossModel {
            loss_factor: f64::NAN,
            ..full
        };
        assert!(bad.t60_s(100.0).unwrap_err().contains("loss.loss_factor"));
        let bad = LossModel {
            radiation_ref_hz: 0.0,
            ..full
        };
        assert!(bad
            .t60_s(100.0)
            .unwrap_err()
            .contains("loss.radiation_ref_hz"));
    }

    // -- clamped-clamped beams ----------------------------------------------

    #[test]
    fn clamped_clamped_roots_ends_pde_and_quadrature() {
        // The same equation cos u cosh u = 1 as free-free: the same roots.
        for n in 1..=200 {
            assert_eq!(
                beam_root(BeamSupport::ClampedClamped, n),
                beam_root(BeamSupport::FreeFree, n)
            );
        }
        for (n, t) in [(1, 4.730040745), (2, 7.853204624), (3, 10.99560784)] {
            let u = beam_root(BeamSupport::ClampedClamped, n);
            println!(
                "clamped-clamped u_{n} = {u:.12}, table {t}, residual {:.2e}",
                u - t
            );
            assert!((u - t).abs() < 5.01e-9);
        }
        let ff = rosewood_bar();
        let bar = Bar {
            support: BeamSupport::ClampedClamped,
            ..ff.clone()
        };
        let l = bar.length_m;
        let rho_a = bar.density_kg_m3 * bar.width_m * bar.thickness_m;
        // phi (with integral_0^1 phi^2 d xi = 1) = Phi sqrt(rho A L).
        let norm = bar.mass_kg().sqrt();
        let modes = bar.modes(f64::INFINITY, 20).unwrap();
        let ff_modes = ff.modes(f64::INFINITY, 20).unwrap();
        // Same frequencies as free-free, also with the Timoshenko correction.
        for (a, b) in modes.iter().zip(&ff_modes) {
            assert_eq!(a.freq_hz, b.freq_hz);
        }
        let g_rw = material("rosewood").unwrap().shear_modulus_pa;
        let t_cc = bar.clone().with_timoshenko(g_rw).modes(1e5, 8).unwrap();
        let t_ff = ff.clone().with_timoshenko(g_rw).modes(1e5, 8).unwrap();
        assert!(t_cc.iter().zip(&t_ff).all(|(a, b)| a.freq_hz == b.freq_hz));
        assert!(t_cc[0].freq_hz < modes[0].freq_hz);
        let mut end_value: f64 = 0.0;
        let mut end_slope: f64 = 0.0;
        let mut pde: f64 = 0.0;
        let mut second: f64 = 0.0;
        for (m, mf) in modes.iter().zip(&ff_modes) {
            let ModeLabel::Bending { n } = m.label else {
                unreachable!()
            };
            let u = beam_root(BeamSupport::ClampedClamped, n);
            let phi = |xi: f64| m.shape_at(Point::Line(xi * l)).unwrap() * norm;
            let phi_ff = |xi: f64| mf.shape_at(Point::Line(xi * l)).unwrap() * norm;
            end_value = end_value.max(phi(0.0).abs()).max(phi(1.0).abs());
            // Second-order one-sided slopes d phi / d xi at both ends,
            // relative to the interior slope scale u.
            let h = 1e-6;
            let s0 = (-3.0 * phi(0.0) + 4.0 * phi(h) - phi(2.0 * h)) / (2.0 * h);
            let s1 = (3.0 * phi(1.0) - 4.0 * phi(1.0 - h) + phi(1.0 - 2.0 * h)) / (2.0 * h);
            end_slope = end_slope.max(s0.abs() / u).max(s1.abs() / u);
            // The beam equation phi'''' = u^4 phi at interior points, and
            // phi_cc = phi_ff'' / u^2 (both in xi), by central differences.
            for xi in [0.1371, 0.5, 0.8113] {
                let h4 = 0.005 / u;
                let d4 = (phi(xi + 2.0 * h4) - 4.0 * phi(xi + h4) + 6.0 * phi(xi)
                    - 4.0 * phi(xi - h4)
                    + phi(xi - 2.0 * h4))
                    / h4.powi(4);
                pde = pde.max((d4 - u.powi(4) * phi(xi)).abs() / (2.0 * u.powi(4)));
                let h2 = 1e-3 / u;
                let d2 = (phi_ff(xi + h2) - 2.0 * phi_ff(xi) + phi_ff(xi - h2)) / (h2 * h2);
                second = second.max((d2 / (u * u) - phi(xi)).abs() / 2.0);
            }
        }
        println!(
            "clamped-clamped, 20 modes: max |phi| at the ends {end_value:.2e}, \
             max |phi'|/u at the ends {end_slope:.2e}, \
             beam equation rel residual {pde:.2e}, |phi_ff''/u^2 - phi_cc| / 2 {second:.2e}"
        );
        assert!(end_value < 1e-12, "{end_value}");
        assert!(end_slope < 1e-6, "{end_slope}");
        assert!(pde < 1e-4, "{pde}");
        assert!(second < 1e-6, "{second}");
        let g = line_gram(&modes, rho_a, l, 64);
        let res = identity_residual("bar ClampedClamped", &g);
        assert!(res < 1e-10, "{res}");
        // High modes stay bounded and normalised in the overflow-free form.
        let modes = bar.modes(f64::INFINITY, 64).unwrap();
        let g = line_gram(&modes[62..64], rho_a, l, 400);
        let res = identity_residual("bar clamped-clamped modes 63-64", &g);
        assert!(res < 1e-9, "{res}");
        // A clamped-clamped tube.
        let al = material("aluminium").unwrap();
        let tube = Tube {
            support: BeamSupport::ClampedClamped,
            ..Tube::new(1.0, 0.0254, 0.0224, &al)
        };
        let tm = tube.modes(f64::INFINITY, 10).unwrap();
        let g = line_gram(&tm, al.density_kg_m3 * tube.area_m2(), 1.0, 64);
        assert!(identity_residual("tube ClampedClamped", &g) < 1e-10);
    }

    // -- torsion ------------------------------------------------------------

    #[test]
    fn torsion_coefficient_matches_the_published_table() {
        // Timoshenko & Goodier, Theory of Elasticity, sec. 109 (k_1 of the
        // rectangle); 0.1406 for the square to four places.
        for (ratio, want, tol) in [(1.0, 0.1406, 5e-5), (2.0, 0.229, 5e-4), (10.0, 0.312, 5e-4)] {
            let beta = rectangle_torsion_coefficient(ratio * 0.01, 0.01);
            println!(
                "torsion beta(b/h = {ratio}) = {beta:.6}, table {want}, residual {:.1e}",
                beta - want
            );
            assert!((beta - want).abs() < tol, "{beta}");
            // The sides may come in either order.
            assert_eq!(beta, rectangle_torsion_coefficient(0.01, ratio * 0.01));
        }
        // Against the series evaluated in 40-digit arithmetic (offline,
        // rounded to f64), and against the series summed directly here in
        // f64 (smallest terms first; the tail beyond n = 20001 is below
        // 1e-18).
        let reference = [
            (1.0, 0.1405770149551537),
            (1.25, 0.17173254224128393),
            (1.5, 0.19576070887554403),
            (2.0, 0.22868167711957077),
            (3.0, 0.2633169310015001),
            (5.0, 0.29131675418798886),
            (10.0, 0.3123250374572054),
            (100.0, 0.33123250374572044),
            (1000.0, 0.333123250374572),
        ];
        let mut worst_ref: f64 = 0.0;
        let mut worst_direct: f64 = 0.0;
        for (ratio, want) in reference {
            let beta = rectangle_torsion_coefficient(ratio, 1.0);
            worst_ref = worst_ref.max((beta - want).abs());
            let direct: f64 = (0..10_001)
                .rev()
                .map(|k| {
                    let n = (2 * k + 1) as f64;
                    (n * PI * ratio / 2.0).tanh() / n.powi(5)
                })
                .sum();
            let direct = (1.0 - 192.0 / PI.powi(5) / ratio * direct) / 3.0;
            worst_direct = worst_direct.max((beta - direct).abs());
        }
        println!(
            "torsion beta, b/h 1 to 1000: max |beta - 40-digit reference| {worst_ref:.1e}, \
             max |beta - direct f64 series| {worst_direct:.1e}"
        );
        assert!(worst_ref < 3e-16, "{worst_ref}");
        assert!(worst_direct < 1e-15, "{worst_direct}");
        // Thin strip: beta -> 1/3 - 0.21 h / b (192 lambda(5) / (3 pi^5) = 0.2101).
        let thin = rectangle_torsion_coefficient(1000.0, 1.0);
        assert!(
            (thin - (1.0 / 3.0 - 0.2101 / 1000.0)).abs() < 1e-7,
            "{thin}"
        );
        assert!(rectangle_torsion_coefficient(0.0, 1.0).is_nan());
        assert!(rectangle_torsion_coefficient(f64::NAN, 1.0).is_nan());
    }

    fn torsion_bar() -> Bar {
        rosewood_bar().with_torsion(material("rosewood").unwrap().shear_modulus_pa)
    }

    fn torsion_only(modes: &[ShapeMode]) -> Vec<ShapeMode> {
        modes
            .iter()
            .filter(|m| matches!(m.label, ModeLabel::Torsion { .. }))
            .cloned()
            .collect()
    }

    #[test]
    fn torsion_frequencies_shapes_and_normalisation_against_the_closed_form() {
        let rw = material("rosewood").unwrap();
        let al = material("aluminium").unwrap();
        // Rosewood bar 0.4 x 0.06 x 0.02, G = 1.4 GPa: b/h = 3, beta =
        // 0.26332, K_t = beta b h^3 = 1.2639e-7 m^4, J_p = b h (b^2 + h^2) /
        // 12 = 4.0e-7 m^4, c_t = sqrt(G K_t / (rho J_p)) = 665.11 m/s.
        let (b, h) = (0.06f64, 0.02f64);
        let jp_bar = b * h * (b * b + h * h) / 12.0;
        let beta = rectangle_torsion_coefficient(b, h);
        assert!((beta - 0.263_316_931).abs() < 1e-9, "{beta}");
        let kt_bar = beta * b * h.powi(3);
        let ct_bar = (rw.shear_modulus_pa * kt_bar / (rw.density_kg_m3 * jp_bar)).sqrt();
        let bar = torsion_bar();
        println!(
            "torsion bar: K_t {:.5e} m^4, J_p {:.5e} m^4, c_t {ct_bar:.3} m/s",
            bar.torsion_constant_m4(),
            bar.polar_moment_m4()
        );
        assert!((bar.torsion_constant_m4() / kt_bar - 1.0).abs() < 1e-8);
        assert!((bar.polar_moment_m4() / jp_bar - 1.0).abs() < 1e-15);
        assert!((ct_bar / 665.11 - 1.0).abs() < 1e-5);
        // Aluminium chime with torsion: K_t = J_p, c_t = sqrt(G / rho).
        let tube = Tube::new(1.0, 0.0254, 0.0224, &al).with_torsion(al.shear_modulus_pa);
        let jp_tube = PI * (0.0254f64.powi(4) - 0.0224f64.powi(4)) / 32.0;
        let ct_tube = (al.shear_modulus_pa / al.density_kg_m3).sqrt();
        assert!((tube.polar_moment_m4() / jp_tube - 1.0).abs() < 1e-14);
        for support in [
            BeamSupport::FreeFree,
            BeamSupport::ClampedFree,
            BeamSupport::ClampedClamped,
        ] {
            let cases = [
                (
                    "bar",
                    Shape::Bar(Bar {
                        support,
                        ..bar.clone()
                    }),
                    rw.density_kg_m3 * jp_bar,
                    rw.shear_modulus_pa * kt_bar,
                    ct_bar,
                    0.4,
                    b / 2.0,
                ),
                (
                    "tube",
                    Shape::Tube(Tube {
                        support,
                        ..tube.clone()
                    }),
                    al.density_kg_m3 * jp_tube,
                    al.shear_modulus_pa * jp_tube,
                    ct_tube,
                    1.0,
                    0.0127,
                ),
            ];
            for (name, shape, rho_jp, gkt, ct, l, hw) in cases {
                let modes = torsion_only(&shape.modes(f64::INFINITY, 80).unwrap());
                assert!(modes.len() >= 20, "{name}: {} torsional modes", modes.len());
                let amp = (2.0 / (rho_jp * l)).sqrt();
                let mut freq_res: f64 = 0.0;
                let mut shape_res: f64 = 0.0;
                let mut pde: f64 = 0.0;
                let mut ends: f64 = 0.0;
                for (i, m) in modes.iter().enumerate() {
                    let n = i + 1;
                    assert_eq!(m.label, ModeLabel::Torsion { n });
                    let nf = n as f64;
                    let (want, k) = match support {
                        BeamSupport::ClampedFree => (
                            (2.0 * nf - 1.0) * ct / (4.0 * l),
                            (2.0 * nf - 1.0) * PI / (2.0 * l),
                        ),
                        _ => (nf * ct / (2.0 * l), nf * PI / l),
                    };
                    freq_res = freq_res.max((m.freq_hz / want - 1.0).abs());
                    let theta = |x: f64| m.shape_at(Point::Bar { x, y: hw }).unwrap() / hw;
                    for x in [0.0, 0.123 * l, 0.5 * l, 0.77 * l, l] {
                        let closed = amp
                            * match support {
                                BeamSupport::FreeFree => (k * x).cos(),
                                _ => (k * x).sin(),
                            };
                        shape_res = shape_res.max((theta(x) - closed).abs() / amp);
                    }
                    // G K_t theta'' + rho J_p omega^2 theta = 0.
                    let x = 0.3137 * l;
                    let dx = 1e-3 / k;
                    let d2 = (theta(x + dx) - 2.0 * theta(x) + theta(x - dx)) / (dx * dx);
                    let r = gkt * d2 + rho_jp * m.omega().powi(2) * theta(x);
                    pde = pde.max(r.abs() / (rho_jp * m.omega().powi(2) * amp));
                    // Ends: a clamp does not turn, a free end has no torque
                    // (zero slope, second-order one-sided difference).
                    let dx = 1e-6 * l;
                    let slope0 =
                        (-3.0 * theta(0.0) + 4.0 * theta(dx) - theta(2.0 * dx)) / (2.0 * dx);
                    let slope1 =
                        (3.0 * theta(l) - 4.0 * theta(l - dx) + theta(l - 2.0 * dx)) / (2.0 * dx);
                    let (at0, at1) = match support {
                        BeamSupport::FreeFree => (slope0 / k, slope1 / k),
                        BeamSupport::ClampedFree => (theta(0.0), slope1 / k),
                        BeamSupport::ClampedClamped => (theta(0.0), theta(l)),
                    };
                    ends = ends.max(at0.abs() / amp).max(at1.abs() / amp);
                }
                println!(
                    "torsion {name} {support:?}: f1 {:.3} Hz, {} modes, rel freq residual \
                     {freq_res:.1e}, shape {shape_res:.1e}, wave equation {pde:.1e}, \
                     end conditions {ends:.1e}",
                    modes[0].freq_hz,
                    modes.len()
                );
                assert!(freq_res < 1e-14, "{freq_res}");
                assert!(shape_res < 1e-13, "{shape_res}");
                assert!(pde < 1e-6, "{pde}");
                assert!(ends < 1e-8, "{ends}");
                // integral rho J_p theta_i theta_j dx = delta_ij by quadrature.
                let q = composite(0.0, l, 64);
                let vals: Vec<Vec<f64>> = modes[..20]
                    .iter()
                    .map(|m| {
                        q.iter()
                            .map(|&(x, _)| m.shape_at(Point::Bar { x, y: hw }).unwrap() / hw)
                            .collect()
                    })
                    .collect();
                let w: Vec<f64> = q.iter().map(|&(_, w)| rho_jp * w).collect();
                let res =
                    identity_residual(&format!("torsion {name} {support:?}"), &gram(&vals, &w));
                assert!(res < 1e-12, "{res}");
            }
        }
        // Hand values: the free-free bar's first torsional mode, c_t / (2 L)
        // = 665.11 / 0.8 = 831.39 Hz; the chime's, sqrt(26e9 / 2700) / 2.
        let f1 = torsion_only(&bar.modes(1e4, 100).unwrap())[0].freq_hz;
        println!("rosewood bar: torsion 1 at {f1:.2} Hz (hand: 831.39 Hz)");
        assert!((f1 / 831.39 - 1.0).abs() < 1e-5);
    }

    #[test]
    fn bar_with_torsion_is_mass_normalised_over_the_whole_section() {
        // M_ij = integral rho (w_i w_j + v_i v_j) dV over the 3-D bar: w (in
        // the direction of vibration) is shape_at(x, y); the sideways motion
        // v is -z theta for a torsional mode, 0 for a bending mode. Bending
        // and torsional modes must come out orthogonal and each normalised.
        let bar = torsion_bar();
        let (l, b, h) = (bar.length_m, bar.width_m, bar.thickness_m);
        let rho = bar.density_kg_m3;
        let modes = bar.modes(f64::INFINITY, 12).unwrap();
        let qx = composite(0.0, l, 24);
        let qy = composite(-b / 2.0, b / 2.0, 1);
        let qz = composite(-h / 2.0, h / 2.0, 1);
        let mut vals = vec![Vec::new(); modes.len()];
        let mut w = Vec::new();
        for &(x, wx) in &qx {
            for &(y, wy) in &qy {
                for &(z, wz) in &qz {
                    let wt = rho * wx * wy * wz;
                    w.push(wt);
                    w.push(wt);
                    for (m, v) in modes.iter().zip(vals.iter_mut()) {
                        let up = m.shape_at(Point::Bar { x, y }).unwrap();
                        let side = match m.label {
                            ModeLabel::Torsion { .. } => {
                                -z * m.shape_at(Point::Bar { x, y: b / 2.0 }).unwrap() / (b / 2.0)
                            }
                            _ => 0.0,
                        };
                        v.push(up);
                        v.push(side);
                    }
                }
            }
        }
        let kinds: Vec<String> = modes.iter().map(|m| m.label.to_string()).collect();
        println!("bar with torsion, 12 lowest: {kinds:?}");
        assert!(modes
            .iter()
            .any(|m| matches!(m.label, ModeLabel::Torsion { .. })));
        let res = identity_residual("bar bending + torsion, 3-D", &gram(&vals, &w));
        assert!(res < 1e-10, "{res}");
    }

    #[test]
    fn points_across_the_bar_torsion_is_odd_in_y_bending_ignores_y() {
        let bar = torsion_bar();
        let hw = bar.width_m / 2.0;
        let modes = bar.modes(f64::INFINITY, 10).unwrap();
        let mut lin: f64 = 0.0;
        for m in &modes {
            for x in [0.0, 0.0917, 0.2, 0.3333, 0.4] {
                let edge = m.shape_at(Point::Bar { x, y: hw }).unwrap();
                let line = m.shape_at(Point::Line(x)).unwrap();
                for y in [-hw, -0.0123, 0.0, 0.007, hw] {
                    let v = m.shape_at(Point::Bar { x, y }).unwrap();
                    let mirror = m.shape_at(Point::Bar { x, y: -y }).unwrap();
                    match m.label {
                        ModeLabel::Torsion { .. } => {
                            lin = lin.max((v - y / hw * edge).abs());
                            assert_eq!(v, -mirror);
                            assert_eq!(line, 0.0);
                        }
                        _ => assert_eq!(v, line),
                    }
                }
            }
        }
        println!("torsion: max |Phi(x, y) - (y / (b/2)) Phi(x, b/2)| = {lin:.1e} / sqrt(kg)");
        assert!(lin < 1e-13, "{lin}");
        // A torsional mode's weight at the edge of the free-free bar's end:
        // (b/2) sqrt(2 / (rho J_p L)) = 0.03 sqrt(2 / (1000 * 4e-7 * 0.4)).
        let t1 = modes
            .iter()
            .find(|m| m.label == ModeLabel::Torsion { n: 1 })
            .unwrap();
        let edge = t1.shape_at(Point::Bar { x: 0.0, y: hw }).unwrap();
        let want = 0.03 * (2.0f64 / (1000.0 * 4e-7 * 0.4)).sqrt();
        println!("torsion 1 at (0, b/2): {edge:.6} / sqrt(kg), hand {want:.6}");
        assert!((edge / want - 1.0).abs() < 1e-12);
        // Out of range: errors name the coordinate.
        for m in [&modes[0], t1] {
            for y in [
                hw * (1.0 + 1e-9),
                -hw * (1.0 + 1e-9),
                f64::NAN,
                f64::INFINITY,
            ] {
                let err = m.shape_at(Point::Bar { x: 0.1, y }).unwrap_err();
                assert!(err.contains("point.y"), "{err}");
            }
            for x in [-1e-9, 0.4 + 1e-9, f64::NAN] {
                let err = m.shape_at(Point::Bar { x, y: 0.0 }).unwrap_err();
                assert!(err.contains("point.x"), "{err}");
            }
            let err = m.shape_at(Point::Plane { x: 0.1, y: 0.0 }).unwrap_err();
            assert!(err.contains("Point::Bar"), "{err}");
        }
        println!(
            "out of range: {}",
            t1.shape_at(Point::Bar { x: 0.1, y: 0.031 }).unwrap_err()
        );
        // A tube's half-width is D / 2.
        let al = material("aluminium").unwrap();
        let tube = Tube::new(1.0, 0.0254, 0.0224, &al).with_torsion(al.shear_modulus_pa);
        for m in tube.modes(5000.0, 10).unwrap() {
            assert!(m.shape_at(Point::Bar { x: 0.5, y: 0.0127 }).is_ok());
            let err = m.shape_at(Point::Bar { x: 0.5, y: -0.0128 }).unwrap_err();
            assert!(err.contains("point.y"), "{err}");
        }
        // Point::Bar belongs to bars and tubes only.
        let p = Plate::new(0.3, 0.2, 0.002, &al, PlateEdges::SimplySupported);
        let pm = &p.modes(1e4, 1).unwrap()[0];
        let err = pm.shape_at(Point::Bar { x: 0.1, y: 0.0 }).unwrap_err();
        assert!(err.contains("point") && err.contains("plate"), "{err}");
    }

    #[test]
    fn torsion_merges_with_bending_by_frequency_under_both_limits() {
        let bar = torsion_bar();
        let all = bar.modes(6000.0, 100).unwrap();
        let labels: Vec<String> = all.iter().map(|m| m.label.to_string()).collect();
        println!("bar with torsion up to 6 kHz: {labels:?}");
        // By hand: bending 574.6, 1584.0, 3105.2, 5133.1 Hz; torsion 831.4 n
        // Hz.
        let want = [
            "bending 1",
            "torsion 1",
            "bending 2",
            "torsion 2",
            "torsion 3",
            "bending 3",
            "torsion 4",
            "torsion 5",
            "torsion 6",
            "bending 4",
            "torsion 7",
        ];
        assert_eq!(labels, want);
        // The bending modes are exactly those of the bar without torsion.
        let bending: Vec<f64> = rosewood_bar()
            .modes(6000.0, 100)
            .unwrap()
            .iter()
            .map(|m| m.freq_hz)
            .collect();
        let merged_bending: Vec<f64> = all
            .iter()
            .filter(|m| matches!(m.label, ModeLabel::Bending { .. }))
            .map(|m| m.freq_hz)
            .collect();
        assert_eq!(bending, merged_bending);
        // Both limits apply to the merged list.
        for k in 0..=all.len() {
            let few = bar.modes(f64::INFINITY, k).unwrap();
            assert_eq!(few.len(), k);
            assert!(few.iter().zip(&all).all(|(a, b)| a == b));
        }
        assert_eq!(bar.modes(all[4].freq_hz, 100).unwrap().len(), 5);
        assert_eq!(bar.modes(all[4].freq_hz * 0.999_999, 100).unwrap().len(), 4);
        // A tuned bar: bending retuned, torsion kept, still in order.
        let tuned = bar
            .clone()
            .with_tuning(&[1.0, 4.0, 10.0])
            .modes(6000.0, 100)
            .unwrap();
        assert!(tuned.windows(2).all(|w| w[0].freq_hz <= w[1].freq_hz));
        let tf: Vec<f64> = torsion_only(&tuned).iter().map(|m| m.freq_hz).collect();
        let uf: Vec<f64> = torsion_only(&all).iter().map(|m| m.freq_hz).collect();
        assert_eq!(tf, uf);
        let tl: Vec<String> = tuned.iter().map(|m| m.label.to_string()).collect();
        println!("tuned 1 : 4 : 10 with torsion: {tl:?}");
        assert_eq!(
            &tl[..4],
            ["bending 1", "torsion 1", "torsion 2", "bending 2"]
        );
        // Invalid shear moduli are errors naming the field.
        let err = rosewood_bar().with_torsion(0.0).modes(1e4, 5).unwrap_err();
        assert!(err.contains("bar.torsion"), "{err}");
        let al = material("aluminium").unwrap();
        let err = Tube::new(1.0, 0.02, 0.01, &al)
            .with_torsion(f64::NAN)
            .modes(1e4, 5)
            .unwrap_err();
        assert!(err.contains("tube.torsion"), "{err}");
    }

    // -- validation and limits ----------------------------------------------

    #[test]
    fn invalid_geometry_is_an_error_naming_the_field() {
        let mut bar = rosewood_bar();
        bar.thickness_m = -0.01;
        assert!(bar.modes(1e4, 5).unwrap_err().contains("bar.thickness_m"));
        bar.thickness_m = f64::NAN;
        assert!(bar.modes(1e4, 5).unwrap_err().contains("bar.thickness_m"));
        let bar = rosewood_bar().with_timoshenko(0.0);
        assert!(bar
            .modes(1e4, 5)
            .unwrap_err()
            .contains("bar.shear.shear_modulus_pa"));
        let al = material("aluminium").unwrap();
        let tube = Tube::new(1.0, 0.02, 0.02, &al);
        let err = tube.modes(1e4, 5).unwrap_err();
        assert!(err.contains("tube.inner_diameter_m"), "{err}");
        let mut p = Plate::new(0.3, 0.2, 0.001, &al, PlateEdges::SimplySupported);
        p.poisson_ratio = 0.5;
        assert!(p.modes(1e4, 5).unwrap_err().contains("plate.poisson_ratio"));
        p.poisson_ratio = 0.3;
        p.length_y_m = 0.0;
        assert!(p.modes(1e4, 5).unwrap_err().contains("plate.length_y_m"));
        let mb = Membrane {
            tension_n_per_m: f64::INFINITY,
            ..drum()
        };
        assert!(mb
            .modes(1e4, 5)
            .unwrap_err()
            .contains("membrane.tension_n_per_m"));
        let s = StiffString {
            length_m: 1.0,
            tension_n: 100.0,
            linear_density_kg_m: 1e-3,
            bending_stiffness_n_m2: -1.0,
        };
        assert!(s
            .modes(1e4, 5)
            .unwrap_err()
            .contains("stiff_string.bending_stiffness_n_m2"));
        // Limits.
        let bar = rosewood_bar();
        assert!(bar.modes(f64::NAN, 5).unwrap_err().contains("max_freq_hz"));
        assert!(bar.modes(0.0, 5).unwrap_err().contains("max_freq_hz"));
        assert!(bar
            .modes(1e4, MAX_MODE_COUNT + 1)
            .unwrap_err()
            .contains("max_count"));
        // Points.
        let m = &bar.modes(1e4, 1).unwrap()[0];
        assert!(m
            .shape_at(Point::Line(0.41))
            .unwrap_err()
            .contains("point.x"));
        assert!(m
            .shape_at(Point::Polar { r: 0.0, theta: 0.0 })
            .unwrap_err()
            .contains("point"));
    }

    #[test]
    fn every_kind_honours_both_limits_and_sorts_its_modes() {
        let al = material("aluminium").unwrap();
        let names = [
            "bar",
            "bar + torsion",
            "tube",
            "tube clamped-clamped + torsion",
            "SS plate",
            "free plate",
            "membrane",
            "string",
        ];
        let kinds = [
            Shape::Bar(rosewood_bar()),
            Shape::Bar(torsion_bar()),
            Shape::Tube(Tube::new(1.0, 0.0254, 0.0224, &al)),
            Shape::Tube(Tube {
                support: BeamSupport::ClampedClamped,
                ..Tube::new(1.0, 0.0254, 0.0224, &al).with_torsion(al.shear_modulus_pa)
            }),
            Shape::Plate(Plate::new(
                0.4,
                0.3,
                0.002,
                &al,
                PlateEdges::SimplySupported,
            )),
            Shape::Plate(Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::Free)),
            Shape::Membrane(drum()),
            Shape::StiffString(StiffString::round_wire(
                0.65,
                700.0,
                1e-3,
                &material("steel").unwrap(),
            )),
        ];
        for (k, name) in kinds.iter().zip(names) {
            k.validate().unwrap();
            let all = k.modes(20_000.0, 200).unwrap();
            assert!(!all.is_empty());
            assert!(all.windows(2).all(|w| w[0].freq_hz <= w[1].freq_hz));
            assert!(all.iter().all(|m| m.freq_hz > 0.0 && m.freq_hz <= 20_000.0));
            let few = k.modes(f64::INFINITY, 5).unwrap();
            assert!(few.len() == 5 || (few.len() == 4 && matches!(k, Shape::Membrane(_))));
            for (a, b) in few.iter().zip(&all) {
                assert_eq!(a.freq_hz, b.freq_hz);
            }
            assert!(k.modes(1e4, 0).unwrap().is_empty());
            println!(
                "{name}: {} modes <= 20 kHz (cap 200), mass {:.4} kg",
                all.len(),
                k.mass_kg()
            );
        }
    }
}
