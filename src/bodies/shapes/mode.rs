//! What every kind's modes are made of: a [`Point`] on an object, a
//! [`ModeLabel`], and a [`ShapeMode`] (frequency, label, and its
//! mass-normalised shape, evaluable at any point of its object). The
//! conventions are in the `shapes` module docs.

use std::f64::consts::PI;
use std::fmt;

use super::beam::{torsion_fn, BeamFn, BeamSupport};
use super::bessel::bessel_j;
use super::check::{in_range, in_symmetric_range};

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
    /// A tube's ovalling (shell) mode: `n` waves round the wall (`n >= 2`),
    /// the same along the tube; `sine` tells the partner turned by a
    /// quarter wave (`sin(n phi)`).
    Ring {
        /// Waves round the circumference.
        n: usize,
        /// The `sin(n phi)` partner.
        sine: bool,
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
            ModeLabel::Ring { n, sine } => {
                write!(f, "ovalling {n} {}", if sine { "sin" } else { "cos" })
            }
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
    pub(super) shape: ModeShape,
}

impl ShapeMode {
    /// A string mode's `scale sin(n pi x / L)` as `(scale, n, L)`; none
    /// for a mode of another object.
    pub(crate) fn string_sine(&self) -> Option<(f64, usize, f64)> {
        match self.shape {
            ModeShape::String { length, n, scale } => Some((scale, n, length)),
            _ => None,
        }
    }

    /// A membrane mode's radial factor `scale J_m(j r / a)` as `(scale, j,
    /// a)`; none for a mode of another object.
    pub(crate) fn membrane_radial(&self) -> Option<(f64, f64, f64)> {
        match self.shape {
            ModeShape::Membrane {
                radius, j, scale, ..
            } => Some((scale, j, radius)),
            _ => None,
        }
    }

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
pub(super) enum ModeShape {
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
    /// A tube's ovalling mode: the wall's radial motion `scale cos(n phi)`
    /// and tangential `-(scale / n) sin(n phi)` (or the `sine` partner's,
    /// turned by a quarter wave), the same at every `x`; a point's weight
    /// is the motion across the tube's axis at the surface point `phi =
    /// asin(y / (D / 2))` from the top (`tube.rs`, "Ovalling modes").
    Ring {
        length: f64,
        half_width: f64,
        n: usize,
        sine: bool,
        scale: f64,
    },
}

impl ModeShape {
    pub(super) fn eval(&self, point: Point) -> Result<f64, String> {
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
            (
                &ModeShape::Ring {
                    length,
                    half_width,
                    n,
                    sine,
                    scale,
                },
                Point::Line(_) | Point::Bar { .. },
            ) => {
                let (_, y) = bar_point(point, length, half_width)?;
                let phi = (y / half_width).clamp(-1.0, 1.0).asin();
                let (sp, cp) = phi.sin_cos();
                let (sn, cn) = (n as f64 * phi).sin_cos();
                let nf = n as f64;
                // radial w and tangential v (toward +y), projected on the
                // direction across the axis that y = 0 faces: w cos phi -
                // v sin phi
                let (w, v) = if sine { (sn, cn / nf) } else { (cn, -sn / nf) };
                Ok(scale * (w * cp - v * sp))
            }
            (shape, p) => Err(format!(
                "point: {p:?} is not a point of a {}",
                match shape {
                    ModeShape::Beam { .. } | ModeShape::Torsion { .. } | ModeShape::Ring { .. } =>
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;
    use crate::bodies::shapes::test_support::torsion_bar;
    use crate::bodies::shapes::{Plate, PlateEdges, Tube};

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
}
