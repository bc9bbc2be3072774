//! The power each mode of an object from geometry radiates into air, as the
//! decay rate it costs the mode: the far field of
//! [`radiation`](crate::bodies::radiation) integrated over the half space in
//! front of a face. A pure function of plain numbers.
//!
//! # Physics
//!
//! A mode ringing as `q = Q cos(omega t)` radiates toward the direction `s`
//! the pressure amplitude `|p| = rho0 omega^2 |W(s)| Q / (2 pi r)` (the
//! radiation module's `W`, a face in a baffle). The intensity `|p|^2 / (2
//! rho0 c)` over the half sphere of radius `r` carries the power
//!
//! `P = rho0 omega^4 Q^2 / (8 pi^2 c) J`, `J = integral |W(s)|^2 dOmega`,
//!
//! and the mode holds the energy `E = omega^2 Q^2 / 2` (mass-normalised
//! shapes: modal mass 1), so radiating costs it the amplitude decay rate
//!
//! `sigma = P / (2 E) = rho0 omega^2 J / (8 pi^2 c)` \[1/s\].
//!
//! Two closed forms check it (the tests): a compact face of net volume `V`
//! per unit `q` has `J -> 2 pi V^2`, the baffled monopole's `P = rho0 omega^2
//! U^2 / (4 pi c)` (Kinsler, Frey, Coppens & Sanders, *Fundamentals of
//! Acoustics*, 4th ed., 2000, chapter 7); a wide face far above its
//! coincidence frequency `f_c` has `sigma -> rho0 c / (2 rho h) / sqrt(1 -
//! f_c / f)` (Maidanik 1962, [`crate::scene::plate_radiation_rate`]).
//!
//! # Quadrature
//!
//! Directions `s = (u, v, sqrt(1 - u^2 - v^2))` over the unit disk, `dOmega =
//! du dv / sqrt(1 - u^2 - v^2)`.
//!
//! - Strip (a bar's, tube's or string's, as the radiation module takes
//!   them): `W = Y(k v) I(k u)`, `I(kappa) = integral_0^L phi(x) exp(i kappa
//!   (x - L/2)) dx` (a torsional mode's `theta(x)` in place of `phi`), `Y`
//!   the width's factor (`b sinc(k v b / 2)` bending, `2 g(k v)` torsion).
//!   With `v = sqrt(1 - u^2) sin(psi)` the singular weight goes: `J =
//!   integral_(-1)^1 |I(k u)|^2 G(u) du`, `G(u) = integral_(-pi/2)^(pi/2)
//!   |Y(k sqrt(1 - u^2) sin psi)|^2 dpsi`. A string's `scale sin(p x)` has
//!   the closed form `I = scale p (exp(-i kappa L/2) - (-1)^n exp(i kappa
//!   L/2)) / (p^2 - kappa^2)`, taken where `kappa` is more than about 1e-3
//!   from `p`; a bar's or tube's shape, and a string's near `p`, the
//!   radiation module's quadrature.
//! - Membrane: `W = 2 pi i^m a(phi) R(k sin theta)` with the angular factor
//!   `a` (`cos m phi` or `sin m phi`), so `J = A_m integral_0^(pi/2) |W(theta,
//!   antinode)|^2 sin theta dtheta`, `A_m = integral a^2 dphi` (`2 pi` for `m
//!   = 0`, else `pi`). The radial transform of an ideal membrane's `scale
//!   J_m(alpha r)` (`J_m(alpha a) = 0`) is Lommel's closed form, `integral_0^a
//!   J_m(alpha r) J_m(beta r) r dr = a alpha J_(m+1)(alpha a) J_m(beta a) /
//!   (alpha^2 - beta^2)` (Watson, *A Treatise on the Theory of Bessel
//!   Functions*, section 5.11), taken where `beta = k sin theta` is more than
//!   1e-3 from `alpha`; nearer, where it cancels, the radiation module's
//!   quadrature.
//!
//! Each integral is Gauss-Legendre from the rule its phase asks for, doubled
//! until two results agree to [`POWER_TOLERANCE`]. Plates are not computed
//! here (a plate's product shape would need the two-dimensional integral at
//! every direction); a scene gives them Maidanik's efficiency instead.

use std::f64::consts::PI;

use super::radiation::{
    along_strip, membrane, odd_moment, rule, sinc, start_nodes, string_diameter,
    AIR_DENSITY_KG_PER_M3, LEVELS, SOUND_SPEED_M_PER_S,
};
use crate::bodies::shapes::{bessel_j, ModeLabel, Shape, ShapeMode};

/// Relative agreement of two successive rules of a power integral.
pub const POWER_TOLERANCE: f64 = 1e-6;

/// The decay rate \[1/s\] that radiating from one face into the half space in
/// front of it (a face in a baffle, in air at 20 C) costs `mode` of `shape`
/// (see the module docs). Bars, tubes, stiff strings and membranes; errors
/// for a plate, a mode of another kind of object or a quadrature that does
/// not converge (naming the mode).
pub fn radiation_decay_rate(shape: &Shape, mode: &ShapeMode) -> Result<f64, String> {
    shape.validate()?;
    let omega = mode.omega();
    if !(omega.is_finite() && omega > 0.0) {
        return Err(format!(
            "radiation_decay_rate: mode {}: frequency must be finite and > 0, got {} Hz",
            mode.label, mode.freq_hz
        ));
    }
    let k = omega / SOUND_SPEED_M_PER_S;
    let named = |e: String| {
        format!(
            "radiation_decay_rate: mode {} ({} Hz): {e}",
            mode.label, mode.freq_hz
        )
    };
    let mismatch = |kind: &str| {
        Err(format!(
            "radiation_decay_rate: mode {} is not a mode of a {kind}",
            mode.label
        ))
    };
    let j = match (shape, mode.label) {
        (Shape::Bar(b), ModeLabel::Bending { n }) => strip_power(
            mode,
            b.length_m,
            k,
            n as f64 + 1.0,
            Width::Bending(b.width_m),
        ),
        (Shape::Bar(b), ModeLabel::Torsion { n }) => {
            strip_power(mode, b.length_m, k, n as f64, Width::Torsion(b.width_m))
        }
        (Shape::Bar(_), _) => return mismatch("bar"),
        (Shape::Tube(t), ModeLabel::Bending { n }) => strip_power(
            mode,
            t.length_m,
            k,
            n as f64 + 1.0,
            Width::Bending(t.outer_diameter_m),
        ),
        // a tube's torsion moves no surface along its normal
        (Shape::Tube(_), ModeLabel::Torsion { .. }) => Ok(0.0),
        (Shape::Tube(_), ModeLabel::Ring { .. }) => Err(
            "the radiation of a tube's ovalling modes is not modelled (loss.radiation_damping \
             takes bending alone)"
                .to_string(),
        ),
        (Shape::Tube(_), _) => return mismatch("tube"),
        (Shape::StiffString(s), ModeLabel::String { n }) => strip_power(
            mode,
            s.length_m,
            k,
            n as f64,
            Width::Bending(string_diameter(s.linear_density_kg_m)?),
        ),
        (Shape::StiffString(_), _) => return mismatch("stiff string"),
        (Shape::Membrane(mb), ModeLabel::Membrane { m, n, sine }) => {
            membrane_power(mode, mb.radius_m, (m, n, sine), k)
        }
        (Shape::Membrane(_), _) => return mismatch("membrane"),
        (Shape::Plate(_), _) => {
            return Err(
                "radiation_decay_rate: plates are not computed from the far field \
                 (Maidanik's efficiency gives their radiation)"
                    .to_string(),
            )
        }
    }
    .map_err(named)?;
    Ok(AIR_DENSITY_KG_PER_M3 * omega * omega * j / (8.0 * PI * PI * SOUND_SPEED_M_PER_S))
}

/// The width's factor of a strip's far field.
#[derive(Clone, Copy)]
enum Width {
    /// A bending (or string) mode on a strip this wide: `Y = b sinc(kv b/2)`.
    Bending(f64),
    /// A torsional mode `phi = y theta(x)` of a bar this wide: `Y = 2 g(kv)`.
    Torsion(f64),
}

impl Width {
    /// `|Y(kappa_v)|^2`.
    fn squared(self, kappa_v: f64) -> f64 {
        match self {
            Width::Bending(b) => (b * sinc(0.5 * kappa_v * b)).powi(2),
            Width::Torsion(b) => (2.0 * odd_moment(kappa_v, 0.5 * b)).powi(2),
        }
    }

    fn width(self) -> f64 {
        match self {
            Width::Bending(b) | Width::Torsion(b) => b,
        }
    }
}

/// `integral f` over `[lo, hi]` by Gauss-Legendre, from the rule `phase`
/// asks for, doubling until two results agree to [`POWER_TOLERANCE`] of
/// the larger (`f >= 0`).
fn converge(
    (lo, hi): (f64, f64),
    phase: f64,
    mut f: impl FnMut(f64) -> Result<f64, String>,
) -> Result<f64, String> {
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let mut apply = |level: usize| -> Result<f64, String> {
        let mut s = 0.0;
        for &(t, w) in rule(level) {
            s += w * f(mid + half * t)?;
        }
        Ok(s * half)
    };
    let start = start_nodes(phase);
    let mut prev = apply(start)?;
    for level in start + 1..LEVELS {
        let cur = apply(level)?;
        if (cur - prev).abs() <= POWER_TOLERANCE * cur.abs().max(prev.abs()) {
            return Ok(cur);
        }
        prev = cur;
    }
    Err(format!(
        "the power integral did not converge to {POWER_TOLERANCE:e}"
    ))
}

/// `J` of a strip mode (see the module docs).
fn strip_power(
    mode: &ShapeMode,
    length: f64,
    k: f64,
    half_waves: f64,
    width: Width,
) -> Result<f64, String> {
    let sine = mode.string_sine();
    let along = |kappa: f64| -> Result<f64, String> {
        // a string's scale sin(p x), p = n pi / L: integral_0^L sin(p x)
        // exp(i kappa (x - L/2)) dx = p (exp(-i kappa L/2) - (-1)^n
        // exp(i kappa L/2)) / (p^2 - kappa^2), where it does not cancel
        if let Some((scale, n, l)) = sine {
            let p = n as f64 * PI / l;
            let d = (p - kappa) * (p + kappa);
            if d.abs() > 1e-3 * p * p {
                let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
                let (s, c) = (0.5 * kappa * l).sin_cos();
                let (re, im) = ((1.0 - sign) * c, -(1.0 + sign) * s);
                let f = scale * p / d;
                return Ok(f * f * (re * re + im * im));
            }
        }
        let half_width = match width {
            Width::Bending(_) => None,
            Width::Torsion(b) => Some(0.5 * b),
        };
        let (re, im) = along_strip(mode, length, half_width, kappa, half_waves)?;
        Ok(re * re + im * im)
    };
    let across = |u: f64| -> Result<f64, String> {
        let kv = k * (1.0 - u * u).max(0.0).sqrt();
        // |Y|^2 is even in psi
        let g = converge((0.0, 0.5 * PI), 4.0 * kv * width.width(), |psi| {
            Ok(width.squared(kv * psi.sin()))
        })?;
        Ok(2.0 * g)
    };
    // |I(k u)|^2 over u in [-1, 1]: the shape's half-waves and the phase
    // k u (x - L/2) twice over (a square)
    converge((-1.0, 1.0), 2.0 * PI * half_waves + 4.0 * k * length, |u| {
        Ok(along(k * u)? * across(u)?)
    })
}

/// `J` of a membrane mode (see the module docs).
fn membrane_power(
    mode: &ShapeMode,
    radius: f64,
    (m, n, sine): (usize, usize, bool),
    k: f64,
) -> Result<f64, String> {
    let antinode = if sine {
        PI / (2 * m.max(1)) as f64
    } else {
        0.0
    };
    let angular = if m == 0 { 2.0 * PI } else { PI };
    let phase = 2.0 * PI * (n as f64 + 0.5 * m as f64 + 1.0) + 2.0 * k * radius;
    // an ideal membrane's radial factor scale J_m(alpha r), J_m(alpha a) =
    // 0, has Lommel's closed form (the module docs); the quadrature of the
    // radiation module where it cancels (beta within 1e-3 of alpha)
    let closed = mode.membrane_radial().map(|(scale, j, a)| {
        let alpha = j / a;
        (scale, alpha, a, bessel_j(m + 1, j))
    });
    let j = converge((0.0, 0.5 * PI), phase, |theta| {
        let beta = k * theta.sin();
        let w2 = match closed {
            Some((scale, alpha, a, j_next)) if (alpha - beta).abs() > 1e-3 * alpha => {
                let w = 2.0 * PI * scale * a * alpha * j_next * bessel_j(m, beta * a)
                    / ((alpha - beta) * (alpha + beta));
                w * w
            }
            _ => {
                let (re, im) = membrane(mode, radius, (m, n, sine), beta, antinode)?;
                re * re + im * im
            }
        };
        Ok(w2 * theta.sin())
    })?;
    Ok(angular * j)
}

#[cfg(test)]
mod tests;
