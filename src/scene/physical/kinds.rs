//! The kinds of physical object as a scene file writes them: bars (with
//! their resonator tubes), tubes, plates, membranes and stiff strings,
//! their points, supports and edges.

use super::loss::LossSpec;
use super::material::{material_spec, optional_material_spec, MaterialSpec};
use crate::bodies::shapes::BeamSupport;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A point on a physical object: a position along a bar, tube or string
/// \[m\] (`0.12`), or a pair: `[x, y]` on a plate \[m\] (or along and
/// across a bar \[m\]), `[r, theta]` on a membrane (radius \[m\], angle
/// \[degrees\] from the line of the `cos` modes' antinodes).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PointSpec {
    /// One coordinate.
    Along(f64),
    /// Two coordinates.
    Pair([f64; 2]),
}

/// Boundary conditions of a bar or tube in a scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum SupportSpec {
    /// Both ends free (bars on soft supports, hanging chimes).
    #[default]
    #[serde(rename = "free-free")]
    FreeFree,
    /// Clamped at `x = 0`, free at the other end (tines, reeds).
    #[serde(rename = "clamped-free")]
    ClampedFree,
    /// Clamped at both ends (the lip of a slit drum or wood block).
    #[serde(rename = "clamped-clamped")]
    ClampedClamped,
}

impl SupportSpec {
    pub(super) fn support(self) -> BeamSupport {
        match self {
            SupportSpec::FreeFree => BeamSupport::FreeFree,
            SupportSpec::ClampedFree => BeamSupport::ClampedFree,
            SupportSpec::ClampedClamped => BeamSupport::ClampedClamped,
        }
    }
}

/// Edges of a plate in a scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum EdgesSpec {
    /// All edges simply supported (exact closed form).
    #[default]
    #[serde(rename = "simply-supported")]
    SimplySupported,
    /// All edges free (Warburton's approximation).
    #[serde(rename = "free")]
    Free,
}

fn yes() -> bool {
    true
}

/// `kind = "bar"`: a rectangular bar bending across its thickness.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BarSpec {
    /// Object name.
    pub name: String,
    /// Material (density, Young's and shear moduli, loss factor).
    #[serde(deserialize_with = "material_spec")]
    pub material: MaterialSpec,
    /// Length \[m\].
    pub length_m: f64,
    /// Width \[m\] (across, not in the direction of vibration).
    pub width_m: f64,
    /// Thickness \[m\] (in the direction of vibration).
    pub thickness_m: f64,
    /// Ends.
    #[serde(default)]
    pub support: SupportSpec,
    /// Timoshenko correction (shear and rotary inertia); default on.
    #[serde(default = "yes")]
    pub timoshenko: bool,
    /// Torsional modes (Saint-Venant, the material's shear modulus);
    /// default off. They move points off the centre line (`[x, y]`).
    #[serde(default)]
    pub torsion: bool,
    /// Target ratios of the first bending modes (an undercut bar, e.g.
    /// `[1, 4, 10]`); empty: a uniform bar.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tuning: Vec<f64>,
    /// With `tuning`: the frequency the maker tunes the fundamental to
    /// \[Hz\] (the undercut lowers it below the uniform bar's). Default: the
    /// uniform bar's fundamental.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fundamental_hz: Option<f64>,
    /// With `tuning`: the bar's mass after the undercut \[kg\] (at most the
    /// uniform bar's); the uniform bar's mass-normalised shapes are scaled
    /// by `sqrt(m_uniform / mass_kg)` (an estimate: the undercut removes
    /// mass where the shapes do not change). Default: the uniform bar's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f64>,
    /// Decay.
    #[serde(default)]
    pub loss: LossSpec,
    /// Highest mode frequency listed \[Hz\]; default the Nyquist frequency
    /// of the rate the scene is compiled for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_freq_hz: Option<f64>,
    /// Most modes listed (default and limit `MAX_MODES_PER_OBJECT`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_modes: Option<usize>,
    /// A resonator tube under the bar (docs/design.md, "Resonator tubes").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resonator: Option<ResonatorSpec>,
    /// Named points: position along the bar from one end \[m\].
    pub points: BTreeMap<String, PointSpec>,
}

/// `resonator = { radius_m, point, tuned_hz }` on a bar: a round tube,
/// closed at the bottom, open under the bar's `point` (docs/design.md,
/// "Resonator tubes").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResonatorSpec {
    /// Inner radius of the tube \[m\].
    pub radius_m: f64,
    /// The bar's named point over the tube's axis.
    pub point: String,
    /// The frequency its air column is tuned to \[Hz\]; default the bar's
    /// lowest mode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tuned_hz: Option<f64>,
}

/// `kind = "tube"`: a round tube (chime) or rod.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TubeSpec {
    /// Object name.
    pub name: String,
    /// Material.
    #[serde(deserialize_with = "material_spec")]
    pub material: MaterialSpec,
    /// Length \[m\].
    pub length_m: f64,
    /// Outer diameter \[m\].
    pub outer_diameter_m: f64,
    /// Inner diameter \[m\] (0: a solid rod).
    #[serde(default)]
    pub inner_diameter_m: f64,
    /// Ends.
    #[serde(default)]
    pub support: SupportSpec,
    /// Timoshenko correction; default on.
    #[serde(default = "yes")]
    pub timoshenko: bool,
    /// Torsional modes (Saint-Venant); default off.
    #[serde(default)]
    pub torsion: bool,
    /// Ovalling modes of the wall (Rayleigh's inextensional shell modes,
    /// free ends); default off.
    #[serde(default)]
    pub ovalling: bool,
    /// The wall's modulus round the circumference for the ovalling modes
    /// \[Pa\] (a wooden tube's is across the grain); default the
    /// material's Young's modulus.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hoop_modulus_pa: Option<f64>,
    /// Decay.
    #[serde(default)]
    pub loss: LossSpec,
    /// Highest mode frequency listed \[Hz\]; default the Nyquist frequency
    /// of the rate the scene is compiled for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_freq_hz: Option<f64>,
    /// Most modes listed (default and limit `MAX_MODES_PER_OBJECT`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_modes: Option<usize>,
    /// Named points: position along the tube \[m\], or `[along, across]`
    /// (across from the line the contact faces, `|across| <= D / 2`).
    pub points: BTreeMap<String, PointSpec>,
}

/// `kind = "plate"`: a thin rectangular isotropic plate (Kirchhoff).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlateSpec {
    /// Object name.
    pub name: String,
    /// Material (density, Young's modulus, Poisson's ratio, loss factor).
    #[serde(deserialize_with = "material_spec")]
    pub material: MaterialSpec,
    /// Side along x \[m\].
    pub length_x_m: f64,
    /// Side along y \[m\].
    pub length_y_m: f64,
    /// Thickness \[m\].
    pub thickness_m: f64,
    /// Edges.
    #[serde(default)]
    pub edges: EdgesSpec,
    /// Decay.
    #[serde(default)]
    pub loss: LossSpec,
    /// Highest mode frequency listed \[Hz\]; default the Nyquist frequency
    /// of the rate the scene is compiled for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_freq_hz: Option<f64>,
    /// Most modes listed (default and limit `MAX_MODES_PER_OBJECT`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_modes: Option<usize>,
    /// Named points: `[x, y]` \[m\].
    pub points: BTreeMap<String, PointSpec>,
}

/// `kind = "membrane"`: an ideal circular membrane with a fixed rim.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MembraneSpec {
    /// Object name.
    pub name: String,
    /// Radius \[m\].
    pub radius_m: f64,
    /// Tension per unit length of the rim \[N/m\].
    pub tension_n_per_m: f64,
    /// Mass per unit area \[kg/m^2\].
    pub areal_density_kg_per_m2: f64,
    /// Decay (no material: the loss factor is 0 unless given here).
    #[serde(default)]
    pub loss: LossSpec,
    /// Highest mode frequency listed \[Hz\]; default the Nyquist frequency
    /// of the rate the scene is compiled for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_freq_hz: Option<f64>,
    /// Most modes listed (default and limit `MAX_MODES_PER_OBJECT`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_modes: Option<usize>,
    /// Named points: `[r, theta]` (radius \[m\], angle \[degrees\]), or a
    /// radius alone (angle 0).
    pub points: BTreeMap<String, PointSpec>,
}

/// `kind = "stiff_string"`: a string with bending stiffness, pinned ends.
/// Either a round wire (`material` and `diameter_m`) or the linear density
/// and bending stiffness directly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StiffStringSpec {
    /// Object name.
    pub name: String,
    /// Speaking length \[m\].
    pub length_m: f64,
    /// Tension \[N\].
    pub tension_n: f64,
    /// Material of a round wire.
    #[serde(
        default,
        deserialize_with = "optional_material_spec",
        skip_serializing_if = "Option::is_none"
    )]
    pub material: Option<MaterialSpec>,
    /// Diameter of a round wire \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diameter_m: Option<f64>,
    /// Mass per unit length \[kg/m\] (instead of material and diameter).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub linear_density_kg_per_m: Option<f64>,
    /// Bending stiffness `E I` \[N m^2\] (instead of material and
    /// diameter; 0 is an ideal string).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bending_stiffness_n_m2: Option<f64>,
    /// Decay.
    #[serde(default)]
    pub loss: LossSpec,
    /// Highest mode frequency listed \[Hz\]; default the Nyquist frequency
    /// of the rate the scene is compiled for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_freq_hz: Option<f64>,
    /// Most modes listed (default and limit `MAX_MODES_PER_OBJECT`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_modes: Option<usize>,
    /// Named points: position along the string \[m\].
    pub points: BTreeMap<String, PointSpec>,
}
