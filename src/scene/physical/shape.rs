//! A physical object's shape: its geometry with the material's values,
//! and its named points as points of the shape.

use super::kinds::{EdgesSpec, PointSpec, TubeSpec};
use super::PhysicalSpec;
use crate::bodies::shapes::{Bar, Membrane, Plate, PlateEdges, Point, Shape, StiffString, Tube};
use crate::scene::error::{check_positive, SceneError};

/// A shape-module message `kind.field: reason` as an error at `base.field`.
pub(super) fn shape_error(base: &str, msg: String) -> SceneError {
    match msg.split_once(": ") {
        Some((field, reason)) if !field.contains(' ') => {
            let field = field.split_once('.').map_or(field, |(_, f)| f);
            SceneError::new(format!("{base}.{field}"), reason.to_string())
        }
        _ => SceneError::new(base.to_string(), msg),
    }
}
/// A tube's shape (with its torsional and ovalling modes when asked) and
/// its material's loss factor.
fn tube_shape(s: &TubeSpec, base: &str) -> Result<(Shape, f64), SceneError> {
    let m = s.material.resolve(base)?;
    let mut tube = Tube::new(s.length_m, s.outer_diameter_m, s.inner_diameter_m, &m);
    tube.support = s.support.support();
    if s.timoshenko {
        tube = tube.with_timoshenko(m.shear_modulus_pa, m.poisson_ratio);
    }
    if s.torsion {
        tube = tube.with_torsion(m.shear_modulus_pa);
    }
    match (s.ovalling, s.hoop_modulus_pa) {
        (true, e) => {
            let e = e.unwrap_or(m.youngs_modulus_pa);
            check_positive(&format!("{base}.hoop_modulus_pa"), e)?;
            tube = tube.with_ovalling(e, m.poisson_ratio);
        }
        (false, Some(_)) => {
            return Err(SceneError::new(
                format!("{base}.hoop_modulus_pa"),
                "sets the ovalling modes' modulus: give `ovalling = true` too",
            ))
        }
        (false, None) => {}
    }
    Ok((Shape::Tube(tube), m.loss_factor))
}

impl PhysicalSpec<'_> {
    /// The shape (geometry with the material's values) and the loss factor
    /// the material gives.
    pub fn shape(&self, base: &str) -> Result<(Shape, f64), SceneError> {
        let err = |e: String| shape_error(base, e);
        let out = match self {
            PhysicalSpec::Bar(s) => {
                let m = s.material.resolve(base)?;
                let mut bar = Bar::new(
                    s.length_m,
                    s.width_m,
                    s.thickness_m,
                    &m,
                    s.support.support(),
                );
                if s.timoshenko {
                    bar = bar.with_timoshenko(m.shear_modulus_pa);
                }
                if !s.tuning.is_empty() {
                    bar = bar.with_tuning(&s.tuning);
                }
                bar.fundamental_hz = s.fundamental_hz;
                if s.torsion {
                    bar = bar.with_torsion(m.shear_modulus_pa);
                }
                (Shape::Bar(bar), m.loss_factor)
            }
            PhysicalSpec::Tube(s) => tube_shape(s, base)?,
            PhysicalSpec::Plate(s) => {
                let m = s.material.resolve(base)?;
                let edges = match s.edges {
                    EdgesSpec::SimplySupported => PlateEdges::SimplySupported,
                    EdgesSpec::Free => PlateEdges::Free,
                };
                let plate = Plate::new(s.length_x_m, s.length_y_m, s.thickness_m, &m, edges);
                (Shape::Plate(plate), m.loss_factor)
            }
            PhysicalSpec::Membrane(s) => (
                Shape::Membrane(Membrane {
                    radius_m: s.radius_m,
                    tension_n_per_m: s.tension_n_per_m,
                    areal_density_kg_m2: s.areal_density_kg_per_m2,
                }),
                0.0,
            ),
            PhysicalSpec::StiffString(s) => {
                let (string, eta) = match (
                    &s.material,
                    s.diameter_m,
                    s.linear_density_kg_per_m,
                    s.bending_stiffness_n_m2,
                ) {
                    (Some(mat), Some(d), None, None) => {
                        let m = mat.resolve(base)?;
                        check_positive(&format!("{base}.diameter_m"), d)?;
                        (
                            StiffString::round_wire(s.length_m, s.tension_n, d, &m),
                            m.loss_factor,
                        )
                    }
                    (None, None, Some(mu), Some(ei)) => (
                        StiffString {
                            length_m: s.length_m,
                            tension_n: s.tension_n,
                            linear_density_kg_m: mu,
                            bending_stiffness_n_m2: ei,
                        },
                        0.0,
                    ),
                    _ => {
                        return Err(SceneError::new(
                            base.to_string(),
                            "give either `material` and `diameter_m` (a round wire) or \
                             `linear_density_kg_per_m` and `bending_stiffness_n_m2`",
                        ))
                    }
                };
                (Shape::StiffString(string), eta)
            }
        };
        out.0.validate().map_err(err)?;
        Ok(out)
    }

    /// The shape-module point of a scene point.
    pub(super) fn point(&self, base: &str, name: &str, p: PointSpec) -> Result<Point, SceneError> {
        let path = format!("{base}.points.{name}");
        let bad = |what: &str| SceneError::new(path.clone(), what.to_string());
        match (self, p) {
            (
                PhysicalSpec::Bar(_) | PhysicalSpec::Tube(_) | PhysicalSpec::StiffString(_),
                PointSpec::Along(x),
            ) => Ok(Point::Line(x)),
            (PhysicalSpec::Plate(_), PointSpec::Pair([x, y])) => Ok(Point::Plane { x, y }),
            (PhysicalSpec::Bar(_) | PhysicalSpec::Tube(_), PointSpec::Pair([x, y])) => {
                Ok(Point::Bar { x, y })
            }
            (PhysicalSpec::Membrane(_), PointSpec::Along(r)) => Ok(Point::Polar { r, theta: 0.0 }),
            (PhysicalSpec::Membrane(_), PointSpec::Pair([r, deg])) => Ok(Point::Polar {
                r,
                theta: deg.to_radians(),
            }),
            (PhysicalSpec::Plate(_), PointSpec::Along(_)) => {
                Err(bad("a point on a plate is [x, y] in metres"))
            }
            (_, PointSpec::Pair(_)) => Err(bad(
                "a point on a string is one position along it, in metres",
            )),
        }
    }
}
