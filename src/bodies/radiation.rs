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
const TOLERANCE: f64 = 1e-10;
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
            ModeLabel::Ring { .. } => Err(named(
                "the far field of a tube's ovalling modes is not modelled (hear the tube \
                 through a velocity or displacement pickup)"
                    .to_string(),
            )),
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
    let (re, im) = along_strip(mode, length, None, kx, half_waves)?;
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
    let (re, im) = along_strip(mode, length, Some(hw), kx, half_waves)?;
    // integral_{-h}^{h} y exp(i ky y) dy = 2 i g.
    let g2 = 2.0 * odd_moment(ky, hw);
    Ok((-im * g2, re * g2))
}

/// `integral_0^L f(x) exp(i kappa (x - L/2)) dx` of a strip mode: `f` its
/// shape along the centre line (bending, string), or with `half_width`
/// a torsional mode's twist `theta(x) = phi(x, w/2) / (w/2)`.
pub(super) fn along_strip(
    mode: &ShapeMode,
    length: f64,
    half_width: Option<f64>,
    kappa: f64,
    half_waves: f64,
) -> Result<(f64, f64), String> {
    let (re, im, _) = oscillatory_1d(
        |x| match half_width {
            None => mode.shape_at(Point::Line(x)),
            Some(hw) => Ok(mode.shape_at(Point::Bar { x, y: hw })? / hw),
        },
        (0.0, length),
        0.5 * length,
        kappa,
        half_waves,
        TOLERANCE,
    )?;
    Ok((re, im))
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
fn oscillatory_1d(
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
mod tests;
