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
//! # Where each part lives
//!
//! Each file's own docs give its formulas and their sources.
//!
//! - `mode.rs`: [`Point`], [`ModeLabel`], [`ShapeMode`] and the evaluation
//!   of its shape;
//! - `beam.rs`: Euler-Bernoulli roots and shapes ([`beam_root`],
//!   [`BeamSupport`]);
//! - `beam_modes.rs`: the modes of bars and tubes (Timoshenko correction,
//!   tuned bars, torsional modes; [`ShearCorrection`], [`timoshenko_ratio`]);
//! - `bar.rs`: [`Bar`], [`rectangle_torsion_coefficient`]; `tube.rs`: [`Tube`];
//! - `plate.rs`: [`Plate`] (Kirchhoff, Warburton's free edges);
//! - `bessel.rs`: [`bessel_j`], [`bessel_j_zero`]; `membrane.rs`: [`Membrane`];
//! - `string.rs`: [`StiffString`];
//! - `loss.rs`: [`LossModel`], the decay time of each mode;
//! - `check.rs` and `search.rs`: argument checks, a safeguarded Newton
//!   root finder and the ascending walk over two-index mode families.

mod bar;
mod beam;
mod beam_modes;
mod bessel;
mod check;
mod loss;
mod membrane;
mod mode;
mod plate;
mod search;
mod string;
mod tube;

pub use bar::{rectangle_torsion_coefficient, Bar};
pub use beam::{beam_root, BeamSupport};
pub use beam_modes::{timoshenko_ratio, ShearCorrection};
pub use bessel::{bessel_j, bessel_j_zero};
pub use loss::LossModel;
pub use membrane::Membrane;
pub use mode::{ModeLabel, Point, ShapeMode};
pub use plate::{Plate, PlateEdges};
pub use string::StiffString;
pub use tube::Tube;

/// The most modes one call lists (a guard against runaway requests).
pub const MAX_MODE_COUNT: usize = 100_000;

/// Any of the kinds: bar, tube, plate, membrane, stiff string.
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

#[cfg(test)]
mod test_support;

#[cfg(test)]
mod tests {
    use super::test_support::{drum, rosewood_bar, torsion_bar};
    use super::*;
    use crate::bodies::materials::material;

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
