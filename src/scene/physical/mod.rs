//! Objects described physically in a scene file: bars, tubes, plates,
//! membranes and stiff strings from geometry and material
//! (docs/design.md, "Objects from geometry and material").
//!
//! Each kind is plain data parsed from TOML. The compiler turns it into an
//! abstract modal object ([`ModalSpec`](crate::scene::ModalSpec)) for the rate it compiles for
//! ([`PhysicalSpec::to_modal`]): frequencies and mass-normalised shapes from
//! [`crate::bodies::shapes`], decay times from the loss model, values from
//! the material table [`crate::bodies::materials`] with the scene's
//! overrides. Everything after that (pruning, budget, decompositions) sees
//! only the modal object, so a physical object and its hand-expanded modal
//! equivalent compile to the same thing.
//!
//! This file holds [`PhysicalSpec`] (any of the kinds, what the rest of the
//! crate asks of it) and the checks of a scene's physical object; the rest
//! of the room: `kinds.rs` (each kind as a scene file writes it),
//! `material.rs` (the material and its overrides), `loss.rs` (the decay
//! model and a plate's radiation), `shape.rs` (the shape and its points)
//! and `modal.rs` (the modal object the compiler runs on).

use super::error::{check_positive, SceneError};
use super::limits::MAX_MODES_PER_OBJECT;
use modal::ModeLimits;
use shape::shape_error;
use std::collections::BTreeMap;

mod kinds;
mod loss;
mod material;
mod modal;
mod shape;

pub use kinds::{
    BarSpec, EdgesSpec, MembraneSpec, PlateSpec, PointSpec, StiffStringSpec, SupportSpec, TubeSpec,
};
pub use loss::{plate_radiation_rate, LossSpec, PointDashpotSpec};
pub use material::MaterialSpec;

/// Any physically described object.
#[derive(Debug, Clone, Copy)]
pub enum PhysicalSpec<'a> {
    /// A bar.
    Bar(&'a BarSpec),
    /// A tube.
    Tube(&'a TubeSpec),
    /// A plate.
    Plate(&'a PlateSpec),
    /// A membrane.
    Membrane(&'a MembraneSpec),
    /// A stiff string.
    StiffString(&'a StiffStringSpec),
}

impl<'a> PhysicalSpec<'a> {
    /// Object name.
    pub fn name(&self) -> &'a str {
        match self {
            PhysicalSpec::Bar(s) => &s.name,
            PhysicalSpec::Tube(s) => &s.name,
            PhysicalSpec::Plate(s) => &s.name,
            PhysicalSpec::Membrane(s) => &s.name,
            PhysicalSpec::StiffString(s) => &s.name,
        }
    }

    /// The scene-file spelling of the kind.
    pub fn kind(&self) -> &'static str {
        match self {
            PhysicalSpec::Bar(_) => "bar",
            PhysicalSpec::Tube(_) => "tube",
            PhysicalSpec::Plate(_) => "plate",
            PhysicalSpec::Membrane(_) => "membrane",
            PhysicalSpec::StiffString(_) => "stiff_string",
        }
    }

    /// Named points.
    pub fn points(&self) -> &'a BTreeMap<String, PointSpec> {
        match self {
            PhysicalSpec::Bar(s) => &s.points,
            PhysicalSpec::Tube(s) => &s.points,
            PhysicalSpec::Plate(s) => &s.points,
            PhysicalSpec::Membrane(s) => &s.points,
            PhysicalSpec::StiffString(s) => &s.points,
        }
    }

    fn loss(&self) -> &'a LossSpec {
        match self {
            PhysicalSpec::Bar(s) => &s.loss,
            PhysicalSpec::Tube(s) => &s.loss,
            PhysicalSpec::Plate(s) => &s.loss,
            PhysicalSpec::Membrane(s) => &s.loss,
            PhysicalSpec::StiffString(s) => &s.loss,
        }
    }

    fn limits(&self) -> ModeLimits {
        let (max_freq_hz, max_modes) = match self {
            PhysicalSpec::Bar(s) => (s.max_freq_hz, s.max_modes),
            PhysicalSpec::Tube(s) => (s.max_freq_hz, s.max_modes),
            PhysicalSpec::Plate(s) => (s.max_freq_hz, s.max_modes),
            PhysicalSpec::Membrane(s) => (s.max_freq_hz, s.max_modes),
            PhysicalSpec::StiffString(s) => (s.max_freq_hz, s.max_modes),
        };
        ModeLimits {
            max_freq_hz,
            max_modes,
        }
    }

    /// Check the values that do not depend on the sample rate (geometry,
    /// material, loss, points on the object).
    pub fn validate(&self, base: &str) -> Result<(), SceneError> {
        let (shape, eta) = self.shape(base)?;
        self.loss()
            .model(eta)
            .validate()
            .map_err(|e| shape_error(&format!("{base}.loss"), e))?;
        self.plate_radiation(base, &shape)?;
        if self.radiation_damping(base)? > 0.0
            && matches!(shape, crate::bodies::shapes::Shape::Plate(_))
        {
            return Err(SceneError::new(
                format!("{base}.loss.radiation_damping"),
                "a plate's radiation is loss.plate_radiation (Maidanik's efficiency); \
                 radiation_damping is computed for bars, tubes, stiff strings and membranes",
            ));
        }
        self.weight_scale(base, &shape)?;
        if let Some(f) = self.lowest_frequency_hz() {
            self.resonator(base, &shape, f)?;
        }
        if let Some(f) = self.limits().max_freq_hz {
            check_positive(&format!("{base}.max_freq_hz"), f)?;
        }
        if let Some(n) = self.limits().max_modes {
            if n == 0 || n > MAX_MODES_PER_OBJECT {
                return Err(SceneError::new(
                    format!("{base}.max_modes"),
                    format!("must be in 1..={MAX_MODES_PER_OBJECT}, got {n}"),
                ));
            }
        }
        if self.points().is_empty() {
            return Err(SceneError::new(
                format!("{base}.points"),
                "name at least one point (the struck one)",
            ));
        }
        // each point on the object: evaluate the first mode's shape there
        let first = shape
            .modes(f64::INFINITY, 1)
            .map_err(|e| shape_error(base, e))?;
        for (name, p) in self.points() {
            if name.is_empty() {
                return Err(SceneError::new(
                    format!("{base}.points"),
                    "a point name must not be empty",
                ));
            }
            let point = self.point(base, name, *p)?;
            if let Some(m) = first.first() {
                m.shape_at(point)
                    .map_err(|e| SceneError::new(format!("{base}.points.{name}"), e.to_string()))?;
            }
        }
        Ok(())
    }

    /// Lowest mode frequency \[Hz\] (whatever the limits).
    pub fn lowest_frequency_hz(&self) -> Option<f64> {
        let (shape, _) = self.shape("").ok()?;
        shape
            .modes(f64::INFINITY, 1)
            .ok()?
            .first()
            .map(|m| m.freq_hz)
    }
}

impl PhysicalSpec<'_> {
    /// The point at `pos` (0..1) of the object's striking line, for the
    /// instrument's strike-position parameter: along a bar, tube or string
    /// `pos` times its length; on a plate the diagonal from `(0, 0)` to
    /// `(a, b)`; on a membrane the radius `pos` times the rim's, at the
    /// angle of `current` (the scene's contact point).
    pub fn strike_point(&self, pos: f64, current: PointSpec) -> PointSpec {
        match self {
            PhysicalSpec::Bar(s) => along_keeping_y(pos * s.length_m, current),
            PhysicalSpec::Tube(s) => along_keeping_y(pos * s.length_m, current),
            PhysicalSpec::StiffString(s) => PointSpec::Along(pos * s.length_m),
            PhysicalSpec::Plate(s) => PointSpec::Pair([pos * s.length_x_m, pos * s.length_y_m]),
            PhysicalSpec::Membrane(s) => {
                let theta = match current {
                    PointSpec::Pair([_, t]) => t,
                    PointSpec::Along(_) => 0.0,
                };
                PointSpec::Pair([pos * s.radius_m, theta])
            }
        }
    }
}

/// A point at `x` along a bar or tube, as far off the centre line as
/// `current` (torsion).
fn along_keeping_y(x: f64, current: PointSpec) -> PointSpec {
    match current {
        PointSpec::Pair([_, y]) => PointSpec::Pair([x, y]),
        PointSpec::Along(_) => PointSpec::Along(x),
    }
}

impl super::ObjectSpec {
    /// A physical object's loss and named points, to change (the
    /// instrument's decay, damper and strike-position parameters).
    pub fn physical_mut(&mut self) -> Option<(&mut LossSpec, &mut BTreeMap<String, PointSpec>)> {
        use super::ObjectSpec as O;
        match self {
            O::Bar(s) => Some((&mut s.loss, &mut s.points)),
            O::Tube(s) => Some((&mut s.loss, &mut s.points)),
            O::Plate(s) => Some((&mut s.loss, &mut s.points)),
            O::Membrane(s) => Some((&mut s.loss, &mut s.points)),
            O::StiffString(s) => Some((&mut s.loss, &mut s.points)),
            O::Modal(_) | O::String(_) | O::Wall(_) | O::Chain(_) => None,
        }
    }
}
