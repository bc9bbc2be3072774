//! Far-field radiation of each mode of an object from geometry
//! ([`shapes`](crate::bodies::shapes)) toward a listener: the Rayleigh
//! integral of a baffled plane radiator in the far field. A pure function of
//! plain numbers.
//!
//! # Physics
//!
//! A plane face `S` in an infinite rigid baffle, moving along its normal with
//! acceleration `a(x, t)`, radiates into the half space in front of it the
//! pressure (Rayleigh's integral; Kinsler, Frey, Coppens & Sanders,
//! *Fundamentals of Acoustics*, 4th ed., 2000, chapter 7, the baffled
//! piston; Pierce, *Acoustics*, 1989, pp. 214-215)
//!
//! `p(y, t) = rho0 / (2 pi) integral_S a(x, t - |y - x| / c) / |y - x| dA`.
//!
//! Mode `n` moves the face by `phi_n(x) q_n(t)` (`phi_n` the mass-normalised
//! shape of [`ShapeMode::shape_at`] \[1/sqrt(kg)\], `q_n` its modal
//! coordinate \[sqrt(kg) m\]). A listener at distance `r` in direction `s` (a
//! unit vector) from the face's centre `x0` is in the far field when `r` is
//! large against the face and against `k extent^2`: there `|y - x| = r - s .
//! (x - x0)` in the phase and `r` in the amplitude. With `Q_n` the analytic
//! signal of `q_n` (`q_n = Re Q_n`) and a single frequency `omega_n`, a delay
//! `tau` multiplies `Q_n` by `exp(-i omega_n tau)`, so
//!
//! `p_n(t) = rho0 / (2 pi r) Re[W_n Qddot_n(t - r / c)]`,
//!
//! `W_n = integral_S phi_n(x) exp(i k s . (x - x0)) dA`, `k = omega_n / c`.
//!
//! [`far_field`] returns `W_n` \[m^2/sqrt(kg)\]; the caller applies `rho0 /
//! (2 pi r)` and `omega_n` and drops the delay `r / c` common to all modes.
//!
//! **A freely ringing mode.** `q = cos(omega t)` has the analytic signal
//! `Q = exp(i omega t)` and `Qddot = -omega^2 Q`, so `Re[W Qddot] = -omega^2
//! (Re W cos(omega t) - Im W sin(omega t))`; with `sin(omega t) = -qdot /
//! omega`,
//!
//! `p_n = -(rho0 / (2 pi r)) (omega_n^2 Re W_n q_n + omega_n Im W_n qdot_n)`,
//!
//! and by linearity for any amplitude and phase. For a decaying mode this
//! holds to first order in `sigma_n / omega_n`.
//!
//! # Faces and directions
//!
//! The direction is a polar angle from the face's normal (0 to 90 degrees:
//! the half space in front of the face, the side toward which a positive
//! shape value moves) and an azimuth around it from the object's `x` axis.
//! With `u = sin(polar) cos(azimuth)`, `v = sin(polar) sin(azimuth)` the
//! phase is `k (u (x - x0) + v (y - y0))`.
//!
//! - Bar: `x` in `[0, L]`, `y` in `[-b/2, b/2]` (`b` the width,
//!   [`Point::Bar`]), centre `(L/2, 0)`. Bending modes do not depend on `y`:
//!   `W = b sinc(k v b / 2) integral_0^L phi(x) exp(i k u (x - L/2)) dx`,
//!   `sinc z = sin z / z`. Torsional modes move by `phi = y theta(x)`: `W =
//!   2 i g integral_0^L theta(x) exp(i k u (x - L/2)) dx`, `g = integral_0^(b/2)
//!   y sin(k v y) dy = (b/2)^2 (sin z - z cos z) / z^2`, `z = k v b / 2`
//!   (for `|z| < 1/2`, where the difference cancels, `sin z - z cos z` is
//!   summed as its power series `sum_(j >= 1) (-1)^(j+1) 2 j z^(2j+1) /
//!   (2j+1)!`).
//! - Tube: the same strip with the outer diameter `D` as its width (the
//!   projection of the cylinder; an approximation: the real surface is
//!   curved and its normal velocity varies around it). Its torsional modes
//!   move no surface along its normal: `W = 0`.
//! - Stiff string: the same strip with the diameter `d` as its width. A
//!   [`StiffString`](crate::bodies::shapes::StiffString) stores its linear
//!   density `mu`, not its diameter, so `d` is that of a round steel wire of
//!   the same `mu`: `d = sqrt(4 mu / (pi rho_steel))`, `rho_steel` from the
//!   materials table (an estimate: a wire of another material or a wound
//!   string has another diameter; `W` scales with `d`).
//! - Plate: `[0, a] x [0, b]`, centre `(a/2, b/2)`. Both plate models are
//!   products `phi = X(x) Y(y)`, so `W = W_x W_y / phi(x*, y*)` with `W_x =
//!   integral_0^a phi(x, y*) exp(i k u (x - a/2)) dx`, `W_y = integral_0^b
//!   phi(x*, y) exp(i k v (y - b/2)) dy` and `(x*, y*)` an antinode
//!   (`(a/(2m), b/(2n))` simply supported, the corner `(0, 0)` with free
//!   edges). The product form is checked at two points; a shape that fails
//!   the check is integrated in two dimensions instead.
//! - Membrane: the disk of radius `a` centred on 0, `x = r cos(theta)`, `y =
//!   r sin(theta)`, `theta` the angle of [`Point::Polar`] (0 on an antinode
//!   line of the `cos(m theta)` modes). With `phi = R(r) cos(m theta)` (or
//!   `sin`), `beta = k sin(polar)`, and the Jacobi-Anger expansion
//!   `integral_0^(2 pi) cos(m theta) exp(i z cos(theta - psi)) d theta = 2
//!   pi i^m J_m(z) cos(m psi)` (the same with `sin`), `W = 2 pi i^m
//!   cos(m azimuth) integral_0^a R(r) J_m(beta r) r dr`. The radial integral
//!   is checked against Lommel's integral `integral_0^a J_m(alpha r) J_m(beta
//!   r) r dr = a alpha J_(m+1)(alpha a) J_m(beta a) / (alpha^2 - beta^2)` for
//!   `J_m(alpha a) = 0` (Watson, *A Treatise on the Theory of Bessel
//!   Functions*, section 5.11) in the tests.
//!
//! Approximations of the model, not of the numbers: the baffle (a bar, plate
//! or drum head without one radiates less at low frequencies, where the air
//! flows around its edge from one face to the other), one face only, and the
//! strip in place of a tube's or string's round surface.
//!
//! # Quadrature
//!
//! Gauss-Legendre rules of `32 * 2^j` nodes (`j = 0..=7`, up to 4096),
//! computed once by Newton's method on the Legendre recurrence. An `N`-node
//! rule is exact for polynomials of degree `2N - 1`, and `exp(i w t)` on
//! `[-1, 1]` needs a polynomial of degree about `w` plus a few dozen to reach
//! rounding error, so an integrand whose total phase over the interval is
//! `Phi = pi * half-waves of the shape + |kappa| * length` needs a little
//! more than `Phi / 4` nodes (the excess grows like `Phi^(1/3)`, the width of
//! the Bessel functions' turning region). Each integral starts at the first
//! rule of at least `Phi / 4 + 16` nodes and doubles until two successive
//! results differ by less than `1e-10` times `integral |phi| dA` (estimated
//! on the same nodes), else an error names the mode. A whole object of 200
//! modes takes a few milliseconds.

use std::f64::consts::PI;
use std::sync::OnceLock;

use crate::bodies::materials::material;
use crate::bodies::shapes::{ModeLabel, PlateEdges, Point, Shape, ShapeMode};

/// Direction of a far-field listener in an object's own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Direction {
    /// Angle from the radiating face's normal \[deg\], 0 ..= 90 (0: straight in front).
    pub polar_deg: f64,
    /// Angle around the normal from the object's x axis (a bar's, tube's or
    /// string's length, a plate's first side, a membrane's angle origin)
    /// \[deg\].
    pub azimuth_deg: f64,
}

/// Speed of sound in air at 20 C \[m/s\]: Kinsler, Frey, Coppens & Sanders,
/// *Fundamentals of Acoustics*, 4th ed. (2000), the appendix table of gases
/// (air at 20 C and 1 atm: 343 m/s); the ideal gas value `sqrt(gamma R T /
/// M)` with `gamma = 1.4`, `R = 8.314462 J/(mol K)`, `T = 293.15 K`, `M =
/// 0.028965 kg/mol` is 343.2 m/s.
pub const SOUND_SPEED_M_PER_S: f64 = 343.0;

/// Density of air at 20 C \[kg/m^3\]: dry air at 101.325 kPa by the ideal gas
/// law, `p M / (R T) = 101325 * 0.028965 / (8.314462 * 293.15) = 1.204`.
pub const AIR_DENSITY_KG_PER_M3: f64 = 1.204;

/// Convergence tolerance, relative to `integral |phi| dA`.
pub(super) const TOLERANCE: f64 = 1e-10;
/// Nodes of the smallest rule.
const MIN_NODES: usize = 32;
/// Rules of `MIN_NODES << j`, `j < LEVELS` (the largest has 4096 nodes).
pub(super) const LEVELS: usize = 8;
/// Nodes of the largest rule.
const MAX_NODES: usize = MIN_NODES << (LEVELS - 1);

/// `W_n` of `mode` of `shape` toward `dir` at `k = omega_n / c`: `(re, im)`
/// \[m^2/sqrt(kg)\] (see the module docs). `mode` must be one of
/// `shape.modes(..)`. Errors for an invalid shape, direction or sound speed,
/// a mode of another kind of object, or a quadrature that does not converge
/// (naming the mode).
pub fn far_field(
    shape: &Shape,
    mode: &ShapeMode,
    dir: Direction,
    sound_speed_m_per_s: f64,
) -> Result<(f64, f64), String> {
    shape.validate()?;
    let polar = dir.polar_deg;
    if !(polar.is_finite() && (0.0..=90.0).contains(&polar)) {
        return Err(format!(
            "far_field: dir.polar_deg: must be in [0, 90], got {polar}"
        ));
    }
    if !dir.azimuth_deg.is_finite() {
        return Err(format!(
            "far_field: dir.azimuth_deg: must be finite, got {}",
            dir.azimuth_deg
        ));
    }
    let c = sound_speed_m_per_s;
    if !(c.is_finite() && c > 0.0) {
        return Err(format!(
            "far_field: sound_speed_m_per_s: must be finite and > 0, got {c}"
        ));
    }
    let omega = mode.omega();
    if !(omega.is_finite() && omega > 0.0) {
        return Err(format!(
            "far_field: mode {}: frequency must be finite and > 0, got {} Hz",
            mode.label, mode.freq_hz
        ));
    }
    let k = omega / c;
    let sin_polar = polar.to_radians().sin();
    let (sin_az, cos_az) = dir.azimuth_deg.to_radians().sin_cos();
    let (kx, ky) = (k * sin_polar * cos_az, k * sin_polar * sin_az);
    let mismatch = |kind: &str| {
        Err(format!(
            "far_field: mode {} is not a mode of a {kind}",
            mode.label
        ))
    };
    let named = |e: String| format!("far_field: mode {} ({} Hz): {e}", mode.label, mode.freq_hz);
    match shape {
        Shape::Bar(bar) => match mode.label {
            ModeLabel::Bending { n } => {
                strip(mode, bar.length_m, bar.width_m, kx, ky, n as f64 + 1.0).map_err(named)
            }
            ModeLabel::Torsion { n } => {
                torsion_strip(mode, bar.length_m, bar.width_m, kx, ky, n as f64).map_err(named)
            }
            _ => mismatch("bar"),
        },
        Shape::Tube(tube) => match mode.label {
            ModeLabel::Bending { n } => strip(
                mode,
                tube.length_m,
                tube.outer_diameter_m,
                kx,
                ky,
                n as f64 + 1.0,
            )
            .map_err(named),
            ModeLabel::Torsion { .. } => Ok((0.0, 0.0)),
            _ => mismatch("tube"),
        },
        Shape::StiffString(s) => match mode.label {
            ModeLabel::String { n } => strip(
                mode,
                s.length_m,
                string_diameter(s.linear_density_kg_m)?,
                kx,
                ky,
                n as f64,
            )
            .map_err(named),
            _ => mismatch("stiff string"),
        },
        Shape::Plate(p) => match mode.label {
            ModeLabel::Plate { m, n } => {
                plate(mode, p.length_x_m, p.length_y_m, p.edges, (m, n), kx, ky).map_err(named)
            }
            _ => mismatch("plate"),
        },
        Shape::Membrane(mb) => match mode.label {
            ModeLabel::Membrane { m, n, sine } => membrane(
                mode,
                mb.radius_m,
                (m, n, sine),
                k * sin_polar,
                dir.azimuth_deg.to_radians(),
            )
            .map_err(named),
            _ => mismatch("membrane"),
        },
    }
}

/// Diameter \[m\] of a round steel wire of linear density `mu` \[kg/m\].
pub(super) fn string_diameter(mu: f64) -> Result<f64, String> {
    let steel = material("steel")?;
    Ok((4.0 * mu / (PI * steel.density_kg_m3)).sqrt())
}

// ---------------------------------------------------------------------------
// Faces
// ---------------------------------------------------------------------------

/// A bending or string mode on the strip `[0, L] x [-w/2, w/2]`.
fn strip(
    mode: &ShapeMode,
    length: f64,
    width: f64,
    kx: f64,
    ky: f64,
    half_waves: f64,
) -> Result<(f64, f64), String> {
    let (re, im, _) = oscillatory_1d(
        |x| mode.shape_at(Point::Line(x)),
        (0.0, length),
        0.5 * length,
        kx,
        half_waves,
        TOLERANCE,
    )?;
    let y = width * sinc(0.5 * ky * width);
    Ok((re * y, im * y))
}

/// A torsional mode `phi = y theta(x)` of a bar of width `w`.
fn torsion_strip(
    mode: &ShapeMode,
    length: f64,
    width: f64,
    kx: f64,
    ky: f64,
    half_waves: f64,
) -> Result<(f64, f64), String> {
    let hw = 0.5 * width;
    let (re, im, _) = oscillatory_1d(
        |x| Ok(mode.shape_at(Point::Bar { x, y: hw })? / hw),
        (0.0, length),
        0.5 * length,
        kx,
        half_waves,
        TOLERANCE,
    )?;
    // integral_{-h}^{h} y exp(i ky y) dy = 2 i g.
    let g2 = 2.0 * odd_moment(ky, hw);
    Ok((-im * g2, re * g2))
}

/// `sin z / z`.
pub(super) fn sinc(z: f64) -> f64 {
    if z == 0.0 {
        1.0
    } else {
        z.sin() / z
    }
}

/// `g = integral_0^h y sin(alpha y) dy = h^2 (sin z - z cos z) / z^2`, `z =
/// alpha h`; the power series for `|z| < 1/2`, where the closed form
/// cancels.
pub(super) fn odd_moment(alpha: f64, h: f64) -> f64 {
    let z = alpha * h;
    if z.abs() >= 0.5 {
        return h * h * (z.sin() - z * z.cos()) / (z * z);
    }
    // sin z - z cos z = sum_{j>=1} (-1)^(j+1) 2 j z^(2j+1) / (2j+1)!.
    let z2 = z * z;
    let mut power = z; // z^(2j+1) / (2j+1)!, from j = 0
    let mut sum = 0.0;
    for j in 1..20 {
        power *= z2 / ((2 * j) as f64 * (2 * j + 1) as f64);
        let term = 2.0 * j as f64 * power;
        sum += if j % 2 == 1 { term } else { -term };
        if term.abs() <= 1e-18 * sum.abs() {
            break;
        }
    }
    h * h * sum / z2.max(f64::MIN_POSITIVE)
}

/// A plate mode `(m, n)` on `[0, a] x [0, b]`.
fn plate(
    mode: &ShapeMode,
    a: f64,
    b: f64,
    edges: PlateEdges,
    (m, n): (usize, usize),
    kx: f64,
    ky: f64,
) -> Result<(f64, f64), String> {
    let at = |x: f64, y: f64| mode.shape_at(Point::Plane { x, y });
    let (xs, ys) = match edges {
        PlateEdges::SimplySupported => (a / (2 * m.max(1)) as f64, b / (2 * n.max(1)) as f64),
        PlateEdges::Free => (0.0, 0.0),
    };
    let (hx, hy) = (m as f64 + 1.0, n as f64 + 1.0);
    let c = at(xs, ys)?;
    let mut separable = c.is_finite() && c != 0.0;
    if separable {
        for (px, py) in [(0.287_1, 0.643_7), (0.812_3, 0.137_9)] {
            let (x, y) = (px * a, py * b);
            let product = at(x, ys)? * at(xs, y)?;
            if (at(x, y)? * c - product).abs() > 1e-9 * c * c {
                separable = false;
            }
        }
    }
    if !separable {
        let (re, im, _) = oscillatory_2d(
            at,
            ((0.0, a), (0.0, b)),
            (0.5 * a, 0.5 * b),
            (kx, ky),
            (hx, hy),
            TOLERANCE,
        )?;
        return Ok((re, im));
    }
    // Each factor to half the tolerance: the product's error is at most
    // tol/2 (A_x |W_y| + |W_x| A_y) / |c| <= tol A_x A_y / |c|.
    let (xr, xi, _) = oscillatory_1d(|x| at(x, ys), (0.0, a), 0.5 * a, kx, hx, 0.5 * TOLERANCE)?;
    let (yr, yi, _) = oscillatory_1d(|y| at(xs, y), (0.0, b), 0.5 * b, ky, hy, 0.5 * TOLERANCE)?;
    Ok(((xr * yr - xi * yi) / c, (xr * yi + xi * yr) / c))
}

/// A membrane mode `(m, n)` (`sine`: the `sin(m theta)` partner) of radius
/// `a`, `beta = k sin(polar)`, azimuth `psi` \[rad\].
pub(super) fn membrane(
    mode: &ShapeMode,
    a: f64,
    (m, n, sine): (usize, usize, bool),
    beta: f64,
    psi: f64,
) -> Result<(f64, f64), String> {
    let angular = |t: f64| {
        if sine {
            (m as f64 * t).sin()
        } else {
            (m as f64 * t).cos()
        }
    };
    // An antinode line of the angular factor.
    let theta = if sine {
        PI / (2 * m.max(1)) as f64
    } else {
        0.0
    };
    let on_line = angular(theta);
    if m > 0 && beta == 0.0 {
        // J_m(0) = 0: check the point kind, then nothing radiates.
        mode.shape_at(Point::Polar { r: 0.0, theta })?;
        return Ok((0.0, 0.0));
    }
    let radial = |r: f64| -> Result<(f64, f64, f64), String> {
        let rr = mode.shape_at(Point::Polar { r, theta })? / on_line;
        Ok((
            rr * crate::bodies::shapes::bessel_j(m, beta * r) * r,
            0.0,
            (rr * r).abs(),
        ))
    };
    let phase = PI * (n as f64 + 0.5 * m as f64 + 1.0) + beta.abs() * a;
    // integral |phi| dA = (2 pi or 4) integral |R| r dr, and W = 2 pi
    // integral R J_m r dr (times at most 1): half the tolerance suffices.
    let (int, _, _) = converge_1d((0.0, a), start_nodes(phase), 0.5 * TOLERANCE, radial)?;
    let w = 2.0 * PI * angular(psi) * int;
    // times i^m
    Ok(match m % 4 {
        0 => (w, 0.0),
        1 => (0.0, w),
        2 => (-w, 0.0),
        _ => (0.0, -w),
    })
}

// ---------------------------------------------------------------------------
// Quadrature
// ---------------------------------------------------------------------------

/// Nodes and weights of the `n`-point Gauss-Legendre rule on `[-1, 1]`
/// (`n >= 1`): the roots of `P_n` by Newton's method from Tricomi's
/// approximation `(1 - (n - 1) / (8 n^3)) cos(pi (i - 1/4) / (n + 1/2))`,
/// `i = 1..=n`, weights `2 / ((1 - x^2) P_n'(x)^2)` (Abramowitz & Stegun
/// 25.4.29; the roots are symmetric, so half of them are computed).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    // P_j = a_j x P_(j-1) - b_j P_(j-2), a_j = (2j - 1) / j, b_j = (j - 1) / j.
    let coef: Vec<(f64, f64)> = (0..=n)
        .map(|j| {
            let jf = (j.max(1)) as f64;
            ((2.0 * jf - 1.0) / jf, (jf - 1.0) / jf)
        })
        .collect();
    // (P_n(x), P_n'(x)) for |x| < 1.
    let legendre = |x: f64| {
        let (mut p0, mut p1) = (1.0, x);
        for &(a, b) in &coef[2..] {
            let p2 = a * x * p1 - b * p0;
            p0 = p1;
            p1 = p2;
        }
        (p1, n as f64 * (x * p1 - p0) / (x * x - 1.0))
    };
    let mut out = vec![(0.0, 0.0); n];
    let nf = n as f64;
    let shrink = 1.0 - (nf - 1.0) / (8.0 * nf * nf * nf);
    for i in 0..n.div_ceil(2) {
        let mut x = shrink * (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        for _ in 0..50 {
            let (p, dp) = legendre(x);
            let dx = p / dp;
            x -= dx;
            if dx.abs() <= 1e-15 {
                break;
            }
        }
        let (_, dp) = legendre(x);
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out[i] = (x, w);
        out[n - 1 - i] = (-x, w);
    }
    if n % 2 == 1 {
        out[n / 2].0 = 0.0;
    }
    out
}

/// The rule of `MIN_NODES << level` nodes, computed once.
pub(super) fn rule(level: usize) -> &'static [(f64, f64)] {
    static RULES: [OnceLock<Vec<(f64, f64)>>; LEVELS] = [const { OnceLock::new() }; LEVELS];
    RULES[level].get_or_init(|| gauss_legendre(MIN_NODES << level))
}

/// The first rule level for an integrand of total phase `phase` \[rad\]
/// over its interval: at least `phase / 4 + 16` nodes (the doubled rule that
/// checks it has `phase / 2 + 32`, well past the `phase / 4` where
/// Gauss-Legendre starts to converge).
pub(super) fn start_nodes(phase: f64) -> usize {
    let want = 0.25 * phase.abs() + 16.0;
    let mut level = 0;
    while level + 1 < LEVELS && ((MIN_NODES << level) as f64) < want {
        level += 1;
    }
    level
}

/// `sum w g(x)` over the rule of `level` mapped to `[lo, hi]`, for `g =
/// (re, im, abs)`.
fn apply_rule(
    level: usize,
    (lo, hi): (f64, f64),
    g: &mut impl FnMut(f64) -> Result<(f64, f64, f64), String>,
) -> Result<(f64, f64, f64), String> {
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let (mut re, mut im, mut abs) = (0.0, 0.0, 0.0);
    for &(t, w) in rule(level) {
        let (a, b, c) = g(mid + half * t)?;
        re += w * a;
        im += w * b;
        abs += w * c;
    }
    Ok((re * half, im * half, abs * half))
}

/// `integral g` over `[lo, hi]` for `g = (re, im, abs)`, from rule level
/// `start`, doubling the nodes until two results differ by at most `tol`
/// times the integral of `abs`.
fn converge_1d(
    interval: (f64, f64),
    start: usize,
    tol: f64,
    mut g: impl FnMut(f64) -> Result<(f64, f64, f64), String>,
) -> Result<(f64, f64, f64), String> {
    let mut prev = apply_rule(start, interval, &mut g)?;
    for level in start + 1..LEVELS {
        let cur = apply_rule(level, interval, &mut g)?;
        if (cur.0 - prev.0).hypot(cur.1 - prev.1) <= tol * cur.2 {
            return Ok(cur);
        }
        prev = cur;
    }
    Err(format!(
        "quadrature did not converge to {tol:e} of integral |phi| with {MAX_NODES} nodes"
    ))
}

/// `integral f(x) exp(i kappa (x - centre)) dx` over `interval` and
/// `integral |f| dx`: `(re, im, abs)`. `half_waves` of `f` set the first
/// rule with the phase.
pub(super) fn oscillatory_1d(
    mut f: impl FnMut(f64) -> Result<f64, String>,
    interval: (f64, f64),
    centre: f64,
    kappa: f64,
    half_waves: f64,
    tol: f64,
) -> Result<(f64, f64, f64), String> {
    let phase = PI * half_waves + kappa.abs() * (interval.1 - interval.0);
    converge_1d(interval, start_nodes(phase), tol, |x| {
        let v = f(x)?;
        let (s, c) = (kappa * (x - centre)).sin_cos();
        Ok((v * c, v * s, v.abs()))
    })
}

/// The two-dimensional form of [`oscillatory_1d`] on a rectangle (tensor
/// product rules, both sides doubled together): `integral f(x, y) exp(i
/// (kx (x - cx) + ky (y - cy))) dx dy` and `integral |f|`.
fn oscillatory_2d(
    mut f: impl FnMut(f64, f64) -> Result<f64, String>,
    ((x0, x1), (y0, y1)): ((f64, f64), (f64, f64)),
    (cx, cy): (f64, f64),
    (kx, ky): (f64, f64),
    (hx, hy): (f64, f64),
    tol: f64,
) -> Result<(f64, f64, f64), String> {
    let sx = start_nodes(PI * hx + kx.abs() * (x1 - x0));
    let sy = start_nodes(PI * hy + ky.abs() * (y1 - y0));
    let mut eval = |lx: usize, ly: usize| -> Result<(f64, f64, f64), String> {
        let (mx, hx) = (0.5 * (x0 + x1), 0.5 * (x1 - x0));
        let (my, hy) = (0.5 * (y0 + y1), 0.5 * (y1 - y0));
        let (mut re, mut im, mut abs) = (0.0, 0.0, 0.0);
        for &(tx, wx) in rule(lx) {
            let x = mx + hx * tx;
            for &(ty, wy) in rule(ly) {
                let y = my + hy * ty;
                let v = f(x, y)?;
                let w = wx * wy;
                let (s, c) = (kx * (x - cx) + ky * (y - cy)).sin_cos();
                re += w * v * c;
                im += w * v * s;
                abs += w * v.abs();
            }
        }
        let j = hx * hy;
        Ok((re * j, im * j, abs * j))
    };
    let mut prev = eval(sx, sy)?;
    for step in 1..LEVELS - sx.min(sy) {
        let (lx, ly) = ((sx + step).min(LEVELS - 1), (sy + step).min(LEVELS - 1));
        let cur = eval(lx, ly)?;
        if (cur.0 - prev.0).hypot(cur.1 - prev.1) <= tol * cur.2 {
            return Ok(cur);
        }
        prev = cur;
    }
    Err(format!(
        "quadrature did not converge to {tol:e} of integral |phi| with {MAX_NODES} nodes a side"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::shapes::{bessel_j, Bar, BeamSupport, Membrane, Plate, StiffString, Tube};

    fn dir(polar_deg: f64, azimuth_deg: f64) -> Direction {
        Direction {
            polar_deg,
            azimuth_deg,
        }
    }

    fn plate_ss() -> Plate {
        let al = material("aluminium").unwrap();
        Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::SimplySupported)
    }

    fn drum() -> Membrane {
        Membrane {
            radius_m: 0.18,
            tension_n_per_m: 3000.0,
            areal_density_kg_m2: 0.26,
        }
    }

    fn rosewood_bar() -> Bar {
        Bar::new(
            0.4,
            0.06,
            0.02,
            &material("rosewood").unwrap(),
            BeamSupport::FreeFree,
        )
    }

    fn wavenumbers(mode: &ShapeMode, d: Direction, c: f64) -> (f64, f64, f64) {
        let k = mode.omega() / c;
        let sp = d.polar_deg.to_radians().sin();
        let (sa, ca) = d.azimuth_deg.to_radians().sin_cos();
        (k, k * sp * ca, k * sp * sa)
    }

    /// `integral_0^a sin(m pi x / a) exp(i kappa (x - a/2)) dx = p (exp(-i
    /// kappa a / 2) - (-1)^m exp(i kappa a / 2)) / (p^2 - kappa^2)`, `p = m
    /// pi / a` (from `sin = (e^(ipx) - e^(-ipx)) / (2i)` and `e^(ipa) =
    /// (-1)^m`).
    fn sine_transform(m: usize, a: f64, kappa: f64) -> (f64, f64) {
        let p = m as f64 * PI / a;
        let sign = if m.is_multiple_of(2) { 1.0 } else { -1.0 };
        let (s, c) = (0.5 * kappa * a).sin_cos();
        let d = p * p - kappa * kappa;
        assert!(
            d.abs() > 1e-3 * p * p,
            "too close to the removable singularity"
        );
        // exp(-i h) - sign exp(i h) = (c - sign c) + i (-s - sign s)
        (p * (c - sign * c) / d, p * (-s - sign * s) / d)
    }

    fn cmul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
        (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
    }

    fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
        (a.0 - b.0).hypot(a.1 - b.1)
    }

    #[test]
    fn gauss_legendre_rules_are_exact_for_their_degree() {
        for n in [1usize, 2, 5, 32, 33, 4096] {
            let r = gauss_legendre(n);
            let sum: f64 = r.iter().map(|p| p.1).sum();
            assert!((sum - 2.0).abs() < 1e-13, "n {n}: sum of weights {sum}");
            // integral x^(2n-2) = 2 / (2n - 1), the highest even degree < 2n.
            let deg = 2 * n - 2;
            // x^deg near x = 1 turns a node's rounding error d into a
            // relative error deg * d: up to ~1e-12 for n = 4096.
            let q: f64 = r.iter().map(|&(x, w)| w * x.powi(deg as i32)).sum();
            let want = 2.0 / (deg as f64 + 1.0);
            let tol = 1e-14 * (deg as f64 + 10.0);
            assert!((q / want - 1.0).abs() < tol, "n {n}: {q} vs {want}");
        }
        // A 4096-node rule integrates cos(1000 x) to its closed form.
        let q: f64 = gauss_legendre(4096)
            .iter()
            .map(|&(x, w)| w * (1000.0 * x).cos())
            .sum();
        let want = 2.0 * 1000f64.sin() / 1000.0;
        println!("GL 4096: cos(1000 x) error {:.1e}", (q - want).abs());
        assert!((q - want).abs() < 1e-13);
    }

    #[test]
    fn simply_supported_plate_matches_the_closed_form() {
        let p = plate_ss();
        let (a, b) = (p.length_x_m, p.length_y_m);
        let scale = 2.0 / (p.density_kg_m3 * p.thickness_m * a * b).sqrt();
        let modes = p.modes(f64::INFINITY, 40).unwrap();
        let shape = Shape::Plate(p);
        // integral |phi| dA = scale (2a / pi) (2b / pi) for every (m, n).
        let abs = scale * (2.0 * a / PI) * (2.0 * b / PI);
        let mut worst: f64 = 0.0;
        for (mm, nn) in [(1, 1), (2, 1), (3, 2)] {
            let mode = modes
                .iter()
                .find(|x| x.label == ModeLabel::Plate { m: mm, n: nn })
                .unwrap();
            // scale: shape_at at the antinode.
            let at = mode
                .shape_at(Point::Plane {
                    x: a / (2.0 * mm as f64),
                    y: b / (2.0 * nn as f64),
                })
                .unwrap();
            assert!((at / scale - 1.0).abs() < 1e-14);
            for c in [SOUND_SPEED_M_PER_S, 20.0, 2.3] {
                for d in [
                    dir(0.0, 0.0),
                    dir(60.0, 0.0),
                    dir(60.0, 37.0),
                    dir(30.0, 90.0),
                    dir(85.0, 200.0),
                ] {
                    let (_, kx, ky) = wavenumbers(mode, d, c);
                    let want = cmul(sine_transform(mm, a, kx), sine_transform(nn, b, ky));
                    let want = (scale * want.0, scale * want.1);
                    let got = far_field(&shape, mode, d, c).unwrap();
                    // Relative to |W|, or to integral |phi| where W is 0
                    // (even modes straight ahead).
                    let size = want.0.hypot(want.1);
                    let err = dist(got, want) / if size > 1e-6 * abs { size } else { abs };
                    worst = worst.max(err);
                    assert!(
                        err < 1e-9,
                        "{} c {c} {d:?}: {got:?} vs {want:?}",
                        mode.label
                    );
                }
            }
        }
        println!("SS plate vs closed form: worst relative error {worst:.1e}");
    }

    #[test]
    fn plate_fundamental_straight_ahead_is_its_net_volume() {
        let p = plate_ss();
        let (a, b) = (p.length_x_m, p.length_y_m);
        let scale = 2.0 / (p.density_kg_m3 * p.thickness_m * a * b).sqrt();
        let mode = p.modes(f64::INFINITY, 1).unwrap().remove(0);
        let got = far_field(&Shape::Plate(p), &mode, dir(0.0, 0.0), SOUND_SPEED_M_PER_S).unwrap();
        let want = (2.0 * a / PI) * (2.0 * b / PI) * scale;
        let err = dist(got, (want, 0.0)) / want;
        println!(
            "plate (1,1) at polar 0: W = {:.9e}, net volume {want:.9e}, rel error {err:.1e}",
            got.0
        );
        assert!(err < 1e-12, "{got:?} vs {want}");
    }

    #[test]
    fn free_plate_separable_path_matches_two_dimensional_quadrature() {
        let al = material("aluminium").unwrap();
        let p = Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::Free);
        let (a, b) = (p.length_x_m, p.length_y_m);
        let modes = p.modes(f64::INFINITY, 12).unwrap();
        let shape = Shape::Plate(p);
        let mut worst: f64 = 0.0;
        for mode in &modes {
            let ModeLabel::Plate { m, n } = mode.label else {
                panic!()
            };
            for c in [SOUND_SPEED_M_PER_S, 5.0] {
                for d in [dir(0.0, 0.0), dir(45.0, 30.0), dir(80.0, 250.0)] {
                    let (_, kx, ky) = wavenumbers(mode, d, c);
                    let (re, im, abs) = oscillatory_2d(
                        |x, y| mode.shape_at(Point::Plane { x, y }),
                        ((0.0, a), (0.0, b)),
                        (a / 2.0, b / 2.0),
                        (kx, ky),
                        (m as f64 + 1.0, n as f64 + 1.0),
                        1e-12,
                    )
                    .unwrap();
                    let got = far_field(&shape, mode, d, c).unwrap();
                    let err = dist(got, (re, im)) / abs;
                    worst = worst.max(err);
                    assert!(err < 1e-9, "{} {d:?}: {got:?} vs {re} {im}", mode.label);
                }
            }
        }
        println!("free plate, separable vs 2-D: worst error {worst:.1e} of integral |phi|");
    }

    /// Lommel: `integral_0^a J_m(alpha r) J_m(beta r) r dr = a alpha
    /// J_(m+1)(alpha a) J_m(beta a) / (alpha^2 - beta^2)` when `J_m(alpha a)
    /// = 0`.
    fn lommel(m: usize, j: f64, a: f64, beta: f64) -> f64 {
        let alpha = j / a;
        let d = alpha * alpha - beta * beta;
        assert!(d.abs() > 1e-3 * alpha * alpha);
        a * alpha * bessel_j(m + 1, j) * bessel_j(m, beta * a) / d
    }

    #[test]
    fn membrane_axisymmetric_modes_match_lommels_integral() {
        let mb = drum();
        let a = mb.radius_m;
        let modes = mb.modes(f64::INFINITY, 60).unwrap();
        let shape = Shape::Membrane(mb.clone());
        let mut worst: f64 = 0.0;
        let mut checked = 0;
        for mode in &modes {
            let ModeLabel::Membrane { m, n, .. } = mode.label else {
                panic!()
            };
            if m != 0 || n > 4 {
                continue;
            }
            let j = crate::bodies::shapes::bessel_j_zero(0, n).unwrap();
            // Scale and sign: Phi(0) = scale J0(0) = scale.
            let scale = mode.shape_at(Point::Polar { r: 0.0, theta: 0.0 }).unwrap();
            for c in [SOUND_SPEED_M_PER_S, 30.0, 3.0] {
                for d in [
                    dir(0.0, 0.0),
                    dir(30.0, 10.0),
                    dir(60.0, 0.0),
                    dir(89.0, 123.0),
                ] {
                    let (k, _, _) = wavenumbers(mode, d, c);
                    let beta = k * d.polar_deg.to_radians().sin();
                    let want = 2.0 * PI * scale * lommel(0, j, a, beta);
                    let got = far_field(&shape, mode, d, c).unwrap();
                    let err = dist(got, (want, 0.0)) / want.abs();
                    worst = worst.max(err);
                    assert!(err < 1e-9, "{} c {c} {d:?}: {got:?} vs {want}", mode.label);
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 4 * 3 * 4);
        println!("membrane (0,n) vs Lommel: worst relative error {worst:.1e}");
        // m >= 1: nothing straight ahead; at an angle, Lommel times 2 pi i^m
        // cos(m psi) (or sin).
        let mut worst_m: f64 = 0.0;
        for mode in &modes {
            let ModeLabel::Membrane { m, n, sine } = mode.label else {
                panic!()
            };
            if m == 0 {
                continue;
            }
            let j = crate::bodies::shapes::bessel_j_zero(m, n).unwrap();
            let theta = if sine { PI / (2.0 * m as f64) } else { 0.0 };
            let r0 = 0.37 * a;
            let scale =
                mode.shape_at(Point::Polar { r: r0, theta }).unwrap() / bessel_j(m, j * r0 / a);
            // |J_m| <= 1: an upper bound of integral |phi| dA.
            let abs = scale.abs() * PI * a * a;
            let w0 = far_field(&shape, mode, dir(0.0, 17.0), SOUND_SPEED_M_PER_S).unwrap();
            assert!(w0.0.hypot(w0.1) < 1e-12 * abs, "{}: {w0:?}", mode.label);
            for (c, d) in [
                (SOUND_SPEED_M_PER_S, dir(50.0, 20.0)),
                (4.0, dir(70.0, 200.0)),
            ] {
                let (k, _, _) = wavenumbers(mode, d, c);
                let beta = k * d.polar_deg.to_radians().sin();
                let psi = d.azimuth_deg.to_radians();
                let ang = if sine {
                    (m as f64 * psi).sin()
                } else {
                    (m as f64 * psi).cos()
                };
                let w = 2.0 * PI * scale * ang * lommel(m, j, a, beta);
                let want = match m % 4 {
                    0 => (w, 0.0),
                    1 => (0.0, w),
                    2 => (-w, 0.0),
                    _ => (0.0, -w),
                };
                let got = far_field(&shape, mode, d, c).unwrap();
                let err = dist(got, want) / w.abs().max(1e-300);
                worst_m = worst_m.max(err);
                assert!(
                    err < 1e-9,
                    "{} c {c} {d:?}: {got:?} vs {want:?}",
                    mode.label
                );
            }
        }
        println!("membrane m >= 1 vs Lommel: worst relative error {worst_m:.1e}");
    }

    #[test]
    fn membrane_matches_quadrature_over_the_disk() {
        // Independent of the Jacobi-Anger reduction: Gauss-Legendre in r,
        // the trapezoidal rule (spectrally exact for periodic integrands) in
        // theta, Phi from shape_at at each point.
        let mb = drum();
        let a = mb.radius_m;
        let modes = mb.modes(f64::INFINITY, 12).unwrap();
        let shape = Shape::Membrane(mb);
        let rs = gauss_legendre(256);
        let nt = 512;
        let mut worst: f64 = 0.0;
        for mode in &modes {
            for (c, d) in [
                (SOUND_SPEED_M_PER_S, dir(0.0, 0.0)),
                (SOUND_SPEED_M_PER_S, dir(60.0, 25.0)),
                (10.0, dir(40.0, 110.0)),
                (6.0, dir(75.0, 300.0)),
            ] {
                let (_, kx, ky) = wavenumbers(mode, d, c);
                let (mut re, mut im, mut abs) = (0.0, 0.0, 0.0);
                for &(t, w) in &rs {
                    let r = 0.5 * a * (1.0 + t);
                    for i in 0..nt {
                        let th = 2.0 * PI * i as f64 / nt as f64;
                        let v = mode.shape_at(Point::Polar { r, theta: th }).unwrap();
                        let wt = 0.5 * a * w * r * 2.0 * PI / nt as f64;
                        let (s, co) = (kx * r * th.cos() + ky * r * th.sin()).sin_cos();
                        re += wt * v * co;
                        im += wt * v * s;
                        abs += wt * v.abs();
                    }
                }
                let got = far_field(&shape, mode, d, c).unwrap();
                let err = dist(got, (re, im)) / abs;
                worst = worst.max(err);
                assert!(
                    err < 1e-9,
                    "{} c {c} {d:?}: {got:?} vs ({re}, {im})",
                    mode.label
                );
            }
        }
        println!("membrane vs 2-D disk quadrature: worst error {worst:.1e} of integral |phi|");
    }

    /// `integral |phi| dA` of a bar mode by 2-D quadrature.
    fn bar_abs(mode: &ShapeMode, l: f64, hw: f64) -> f64 {
        oscillatory_2d(
            |x, y| mode.shape_at(Point::Bar { x, y }),
            ((0.0, l), (-hw, hw)),
            (l / 2.0, 0.0),
            (0.0, 0.0),
            (10.0, 1.0),
            1e-12,
        )
        .unwrap()
        .2
    }

    #[test]
    fn free_free_bar_bending_modes_are_silent_ahead_and_real_or_imaginary_by_symmetry() {
        let bar = rosewood_bar();
        let (l, hw) = (bar.length_m, bar.width_m / 2.0);
        let modes = bar.modes(f64::INFINITY, 8).unwrap();
        let shape = Shape::Bar(bar);
        let (mut ahead, mut off_axis): (f64, f64) = (0.0, 0.0);
        for mode in &modes {
            let ModeLabel::Bending { n } = mode.label else {
                panic!()
            };
            let abs = bar_abs(mode, l, hw);
            let w0 = far_field(&shape, mode, dir(0.0, 0.0), SOUND_SPEED_M_PER_S).unwrap();
            let r0 = w0.0.hypot(w0.1) / abs;
            ahead = ahead.max(r0);
            assert!(r0 < 1e-9, "{}: {w0:?}, integral |phi| {abs}", mode.label);
            let w = far_field(&shape, mode, dir(60.0, 0.0), SOUND_SPEED_M_PER_S).unwrap();
            // Mode n = 1, 3, ... is even about the centre: W real; n = 2, 4,
            // ... odd: W imaginary.
            let (big, small) = if n % 2 == 1 { (w.0, w.1) } else { (w.1, w.0) };
            println!(
                "{} ({:.1} Hz): |W(0)| / int|phi| = {r0:.1e}; W(60 deg) = ({:.4e}, {:.4e}), int|phi| {abs:.4e}",
                mode.label, mode.freq_hz, w.0, w.1
            );
            assert!(big.abs() > 1e-3 * abs, "{}: {w:?}", mode.label);
            off_axis = off_axis.max(small.abs() / abs);
            assert!(small.abs() < 1e-9 * abs, "{}: {w:?}", mode.label);
        }
        println!("bar: worst |W(0)| {ahead:.1e}, worst wrong part at 60 deg {off_axis:.1e} (of int |phi|)");
    }

    #[test]
    fn strip_closed_forms_match_two_dimensional_quadrature() {
        let rw = material("rosewood").unwrap();
        let al = material("aluminium").unwrap();
        let bars = [
            Shape::Bar(rosewood_bar().with_torsion(rw.shear_modulus_pa)),
            Shape::Bar(Bar::new(0.3, 0.05, 0.01, &al, BeamSupport::ClampedFree)),
            Shape::Tube(Tube::new(1.0, 0.0254, 0.0224, &al).with_torsion(al.shear_modulus_pa)),
        ];
        let mut worst: f64 = 0.0;
        for shape in &bars {
            let (l, width) = match shape {
                Shape::Bar(b) => (b.length_m, b.width_m),
                Shape::Tube(t) => (t.length_m, t.outer_diameter_m),
                _ => unreachable!(),
            };
            let hw = width / 2.0;
            let modes = shape.modes(f64::INFINITY, 10).unwrap();
            for mode in &modes {
                let torsion = matches!(mode.label, ModeLabel::Torsion { .. });
                for (c, d) in [
                    (SOUND_SPEED_M_PER_S, dir(0.0, 0.0)),
                    (SOUND_SPEED_M_PER_S, dir(60.0, 0.0)),
                    (SOUND_SPEED_M_PER_S, dir(45.0, 30.0)),
                    (3.0, dir(60.0, 90.0)),
                    (5.0, dir(80.0, 70.0)),
                    (4.0, dir(20.0, 160.0)),
                ] {
                    let got = far_field(shape, mode, d, c).unwrap();
                    if torsion && matches!(shape, Shape::Tube(_)) {
                        assert_eq!(got, (0.0, 0.0));
                        continue;
                    }
                    let (_, kx, ky) = wavenumbers(mode, d, c);
                    let (re, im, abs) = oscillatory_2d(
                        |x, y| mode.shape_at(Point::Bar { x, y }),
                        ((0.0, l), (-hw, hw)),
                        (l / 2.0, 0.0),
                        (kx, ky),
                        (12.0, 1.0),
                        1e-12,
                    )
                    .unwrap();
                    let err = dist(got, (re, im)) / abs;
                    worst = worst.max(err);
                    assert!(
                        err < 1e-9,
                        "{} c {c} {d:?}: {got:?} vs ({re}, {im})",
                        mode.label
                    );
                    if torsion && d == dir(45.0, 30.0) {
                        assert!(re.hypot(im) > 1e-6 * abs, "{}", mode.label);
                    }
                }
            }
        }
        println!("bars and tube, 1-D + closed form in y vs 2-D: worst error {worst:.1e} of integral |phi|");
        // The small-argument series of the odd moment joins the closed form.
        for z in [0.499_999_999, 0.5] {
            let g = odd_moment(z, 1.0);
            let closed = (z.sin() - z * z.cos()) / (z * z);
            assert!((g / closed - 1.0).abs() < 1e-14, "{g} vs {closed}");
        }
        assert_eq!(odd_moment(0.0, 0.03), 0.0);
        let g = odd_moment(1e-3, 1.0);
        assert!((g / (1e-3 / 3.0 - 1e-9 / 30.0) - 1.0).abs() < 1e-14);
    }

    #[test]
    fn string_is_a_strip_of_its_wire_diameter() {
        let steel = material("steel").unwrap();
        let d = 1e-3;
        let s = StiffString::round_wire(0.65, 700.0, d, &steel);
        let modes = s.modes(f64::INFINITY, 6).unwrap();
        let scale = (2.0 / (s.linear_density_kg_m * s.length_m)).sqrt();
        let l = s.length_m;
        // integral |phi| dA = scale (2 L / pi) d
        let abs = scale * 2.0 * l / PI * d;
        let shape = Shape::StiffString(s);
        let mut worst: f64 = 0.0;
        for mode in &modes {
            let ModeLabel::String { n } = mode.label else {
                panic!()
            };
            for (c, dr) in [
                (SOUND_SPEED_M_PER_S, dir(0.0, 0.0)),
                (SOUND_SPEED_M_PER_S, dir(60.0, 0.0)),
                (2.0, dir(70.0, 50.0)),
            ] {
                let (_, kx, ky) = wavenumbers(mode, dr, c);
                let sx = sine_transform(n, l, kx);
                let y = d * sinc(ky * d / 2.0);
                let want = (scale * sx.0 * y, scale * sx.1 * y);
                let got = far_field(&shape, mode, dr, c).unwrap();
                // Relative to |W|, or to integral |phi| where W is 0 (even
                // modes straight ahead).
                let size = want.0.hypot(want.1);
                let err = dist(got, want) / if size > 1e-6 * abs { size } else { abs };
                worst = worst.max(err);
                assert!(err < 1e-9, "{} {dr:?}: {got:?} vs {want:?}", mode.label);
            }
        }
        println!("string vs closed form: worst relative error {worst:.1e}");
    }

    #[test]
    fn invalid_input_is_an_error() {
        let p = plate_ss();
        let mode = p.modes(f64::INFINITY, 1).unwrap().remove(0);
        let shape = Shape::Plate(p);
        for d in [dir(-1.0, 0.0), dir(90.5, 0.0), dir(f64::NAN, 0.0)] {
            let e = far_field(&shape, &mode, d, SOUND_SPEED_M_PER_S).unwrap_err();
            assert!(e.contains("polar_deg"), "{e}");
        }
        let e = far_field(&shape, &mode, dir(0.0, f64::INFINITY), 343.0).unwrap_err();
        assert!(e.contains("azimuth_deg"), "{e}");
        for c in [0.0, -1.0, f64::NAN] {
            let e = far_field(&shape, &mode, dir(0.0, 0.0), c).unwrap_err();
            assert!(e.contains("sound_speed"), "{e}");
        }
        let bar_mode = rosewood_bar().modes(f64::INFINITY, 1).unwrap().remove(0);
        let e = far_field(&shape, &bar_mode, dir(0.0, 0.0), 343.0).unwrap_err();
        assert!(e.contains("bending 1") && e.contains("plate"), "{e}");
        let e = far_field(&Shape::Membrane(drum()), &mode, dir(0.0, 0.0), 343.0).unwrap_err();
        assert!(e.contains("membrane"), "{e}");
        // A phase too fast for the largest rule: an error naming the mode.
        let e = far_field(&shape, &mode, dir(90.0, 0.0), 1e-4).unwrap_err();
        assert!(e.contains("plate (1,1)") && e.contains("converge"), "{e}");
    }

    #[test]
    fn two_hundred_modes_are_fast() {
        let al = material("aluminium").unwrap();
        let shapes = [
            ("SS plate", Shape::Plate(plate_ss())),
            (
                "free plate",
                Shape::Plate(Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::Free)),
            ),
            ("membrane", Shape::Membrane(drum())),
            ("bar", Shape::Bar(rosewood_bar())),
        ];
        // The rules are computed once per process: time the largest afresh.
        let t = std::time::Instant::now();
        let largest = gauss_legendre(MAX_NODES);
        println!(
            "the {}-node rule: {:.1} ms (once per process)",
            largest.len(),
            t.elapsed().as_secs_f64() * 1e3
        );
        for level in 0..LEVELS {
            rule(level);
        }
        for (name, shape) in &shapes {
            // The 200 lowest, or those in the audio band (a bar's 200th
            // bending mode is at several MHz).
            let modes = shape.modes(20_000.0, 200).unwrap();
            for d in [dir(30.0, 20.0), dir(90.0, 45.0)] {
                let t = std::time::Instant::now();
                let mut sum = 0.0;
                for mode in &modes {
                    let w = far_field(shape, mode, d, SOUND_SPEED_M_PER_S).unwrap();
                    sum += w.0.abs() + w.1.abs();
                }
                let ms = t.elapsed().as_secs_f64() * 1e3;
                println!(
                    "{name}: {} modes up to {:.0} Hz toward {d:?} in {ms:.2} ms (sum |W| {sum:.3e})",
                    modes.len(),
                    modes.last().unwrap().freq_hz
                );
                assert!(sum.is_finite());
            }
        }
    }
}
