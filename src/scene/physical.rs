//! Objects described physically in a scene file: bars, tubes, plates,
//! membranes and stiff strings from geometry and material
//! (docs/design.md, "Objects from geometry and material").
//!
//! Each kind is plain data parsed from TOML. The compiler turns it into an
//! abstract modal object ([`ModalSpec`]) for the rate it compiles for
//! ([`PhysicalSpec::to_modal`]): frequencies and mass-normalised shapes from
//! [`crate::bodies::shapes`], decay times from the loss model, values from
//! the material table [`crate::bodies::materials`] with the scene's
//! overrides. Everything after that (pruning, budget, decompositions) sees
//! only the modal object, so a physical object and its hand-expanded modal
//! equivalent compile to the same thing.

use super::error::{check_finite, check_non_negative, check_positive, SceneError};
use super::limits::{MAX_FREQ_HZ, MAX_MODES_PER_OBJECT, MAX_WEIGHT, MIN_FREQ_HZ, MIN_T60_S};
use super::{
    pressure_point, ListenerSpec, ModalSpec, ModeSpec, PRESSURE_REF_AREA_M2, PRESSURE_REF_OMEGA,
};
use crate::bodies::materials::{self, Material};
use crate::bodies::radiation::{far_field, Direction, SOUND_SPEED_M_PER_S};
use crate::bodies::resonator::{ModeEffect, Resonator};
use crate::bodies::shapes::{
    Bar, BeamSupport, LossModel, Membrane, Plate, PlateEdges, Point, Shape, ShapeMode, StiffString,
    Tube,
};
use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::fmt;

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

/// Values of a material: a table entry by `name`, any value overridden.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Entry of the material table (`steel`, `rosewood`, ...); may be
    /// omitted when every value the kind needs is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Density \[kg/m^3\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_kg_per_m3: Option<f64>,
    /// Young's modulus \[Pa\] (woods: along the grain).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_modulus_pa: Option<f64>,
    /// Shear modulus \[Pa\] (Timoshenko correction, torsion).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear_modulus_pa: Option<f64>,
    /// Poisson's ratio, in (-1, 0.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<f64>,
    /// Material loss factor `eta` (`sigma = eta omega / 2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss_factor: Option<f64>,
}

/// `material = "steel"` is short for `material = { name = "steel" }`.
fn material_spec<'de, D: Deserializer<'de>>(d: D) -> Result<MaterialSpec, D::Error> {
    struct V;
    impl<'de> Visitor<'de> for V {
        type Value = MaterialSpec;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("a material name or a table of material values")
        }
        fn visit_str<E: de::Error>(self, s: &str) -> Result<MaterialSpec, E> {
            Ok(MaterialSpec {
                name: Some(s.to_string()),
                ..MaterialSpec::default()
            })
        }
        fn visit_map<M: MapAccess<'de>>(self, m: M) -> Result<MaterialSpec, M::Error> {
            MaterialSpec::deserialize(de::value::MapAccessDeserializer::new(m))
        }
    }
    d.deserialize_any(V)
}

/// The decay of every mode: `sigma(f) = decay_rate_per_s + eta pi f +
/// radiation_per_s (f / radiation_ref_hz)^radiation_exponent` \[1/s\],
/// `T60 = ln(1000) / sigma` (`eta`: the material's loss factor unless
/// given here).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LossSpec {
    /// Overrides the material's loss factor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss_factor: Option<f64>,
    /// Frequency-independent decay rate (supports, air) \[1/s\].
    #[serde(default)]
    pub decay_rate_per_s: f64,
    /// Radiation-like decay rate at `radiation_ref_hz` \[1/s\].
    #[serde(default)]
    pub radiation_per_s: f64,
    /// Reference frequency of the radiation term \[Hz\].
    #[serde(default = "default_radiation_ref_hz")]
    pub radiation_ref_hz: f64,
    /// Exponent of the radiation term.
    #[serde(default = "default_radiation_exponent")]
    pub radiation_exponent: f64,
    /// Plates only: the sound radiation of a baffled plate into air
    /// ([`plate_radiation_rate`]) times this factor (1: the plate in air at
    /// 20 C; 0, the default: none), beside the power law above.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub plate_radiation: f64,
}

/// Density of air \[kg/m^3\] (20 C) for [`plate_radiation_rate`].
const RHO_AIR: f64 = 1.204;
/// Speed of sound in air \[m/s\] (20 C) for [`plate_radiation_rate`].
const C_AIR: f64 = 343.0;

/// Decay rate \[1/s\] of a mode at `f` of a thin rectangular plate (sides
/// `a`, `b`, areal density `rho_h`, flexural rigidity `d`) radiating into
/// air from a baffle: `rho_0 c / (2 rho h) sigma(f)` with the radiation
/// efficiency `sigma` of a baffled simply supported plate by Maidanik
/// (1962), as given in Beranek & Ver, *Noise and Vibration Control
/// Engineering* (1992). Below the coincidence frequency
/// `f_c = c^2 / (2 pi) sqrt(rho h / D)`, edge and corner radiation:
///
/// `sigma = lambda_c P / S g_2 + 2 lambda_c^2 / S g_1`, `alpha = sqrt(f / f_c)`,
///
/// `g_2 = ((1 - alpha^2) ln((1 + alpha) / (1 - alpha)) + 2 alpha) / (4 pi^2 (1 - alpha^2)^1.5)`,
///
/// `g_1 = 4 / pi^4 (1 - 2 alpha^2) / (alpha sqrt(1 - alpha^2))` below `f_c / 2`, else 0;
///
/// above it `1 / sqrt(1 - f_c / f)`; both capped at `sqrt(a / lambda_c) +
/// sqrt(b / lambda_c)`. Used for free plates too (an estimate: Maidanik's
/// result is for simple supports).
pub fn plate_radiation_rate(f: f64, a: f64, b: f64, rho_h: f64, d: f64) -> f64 {
    let f_co = C_AIR * C_AIR / (2.0 * PI) * (rho_h / d).sqrt();
    let lam_c = C_AIR / f_co;
    let (p, s) = (2.0 * (a + b), a * b);
    let cap = (a / lam_c).sqrt() + (b / lam_c).sqrt();
    let sigma = if f >= f_co {
        if f > f_co {
            1.0 / (1.0 - f_co / f).sqrt()
        } else {
            f64::INFINITY
        }
    } else {
        let al = (f / f_co).sqrt();
        let g2 = ((1.0 - al * al) * ((1.0 + al) / (1.0 - al)).ln() + 2.0 * al)
            / (4.0 * PI * PI * (1.0 - al * al).powf(1.5));
        let g1 = if f < f_co / 2.0 {
            4.0 / PI.powi(4) * (1.0 - 2.0 * al * al) / (al * (1.0 - al * al).sqrt())
        } else {
            0.0
        };
        lam_c * p / s * g2 + 2.0 * lam_c * lam_c / s * g1
    };
    RHO_AIR * C_AIR / (2.0 * rho_h) * sigma.min(cap)
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn default_radiation_ref_hz() -> f64 {
    1000.0
}

fn default_radiation_exponent() -> f64 {
    2.0
}

impl Default for LossSpec {
    fn default() -> Self {
        LossSpec {
            loss_factor: None,
            decay_rate_per_s: 0.0,
            radiation_per_s: 0.0,
            radiation_ref_hz: default_radiation_ref_hz(),
            radiation_exponent: default_radiation_exponent(),
            plate_radiation: 0.0,
        }
    }
}

/// Which modes are listed: up to `max_freq_hz` (default: the Nyquist
/// frequency of the rate the scene is compiled for), at most `max_modes`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ModeLimits {
    max_freq_hz: Option<f64>,
    max_modes: Option<usize>,
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
    fn support(self) -> BeamSupport {
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
    /// Named points: position along the tube \[m\].
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

fn optional_material_spec<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<MaterialSpec>, D::Error> {
    material_spec(d).map(Some)
}

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

/// A shape-module message `kind.field: reason` as an error at `base.field`.
fn shape_error(base: &str, msg: String) -> SceneError {
    match msg.split_once(": ") {
        Some((field, reason)) if !field.contains(' ') => {
            let field = field.split_once('.').map_or(field, |(_, f)| f);
            SceneError::new(format!("{base}.{field}"), reason.to_string())
        }
        _ => SceneError::new(base.to_string(), msg),
    }
}

impl MaterialSpec {
    /// The table entry with the overrides applied; each needed value must
    /// come from one of them.
    fn resolve(&self, base: &str) -> Result<Material, SceneError> {
        let mut m = match &self.name {
            Some(n) => materials::material(n)
                .map_err(|e| SceneError::new(format!("{base}.material.name"), e))?,
            None => Material {
                name: "custom",
                description: "values given in the scene",
                density_kg_m3: f64::NAN,
                youngs_modulus_pa: f64::NAN,
                shear_modulus_pa: f64::NAN,
                poisson_ratio: 0.3,
                loss_factor: 0.0,
            },
        };
        let fields = [
            (
                &mut m.density_kg_m3,
                self.density_kg_per_m3,
                "density_kg_per_m3",
            ),
            (
                &mut m.youngs_modulus_pa,
                self.youngs_modulus_pa,
                "youngs_modulus_pa",
            ),
            (
                &mut m.shear_modulus_pa,
                self.shear_modulus_pa,
                "shear_modulus_pa",
            ),
            (&mut m.poisson_ratio, self.poisson_ratio, "poisson_ratio"),
            (&mut m.loss_factor, self.loss_factor, "loss_factor"),
        ];
        for (slot, given, field) in fields {
            if let Some(v) = given {
                check_finite(&format!("{base}.material.{field}"), v)?;
                *slot = v;
            }
        }
        if self.name.is_none() {
            for (v, field) in [
                (m.density_kg_m3, "density_kg_per_m3"),
                (m.youngs_modulus_pa, "youngs_modulus_pa"),
            ] {
                if v.is_nan() {
                    return Err(SceneError::new(
                        format!("{base}.material"),
                        format!("needs a table `name` or `{field}`"),
                    ));
                }
            }
            if m.shear_modulus_pa.is_nan() {
                // isotropic: G = E / (2 (1 + nu))
                m.shear_modulus_pa = m.youngs_modulus_pa / (2.0 * (1.0 + m.poisson_ratio));
            }
        }
        m.validate().map_err(|e| {
            let reason = e
                .split_once(": ")
                .map_or(e.as_str(), |(_, r)| r)
                .to_string();
            let field = reason
                .split_once(':')
                .map_or("", |(f, _)| f)
                .replace("density_kg_m3", "density_kg_per_m3");
            let reason = reason.split_once(": ").map_or(reason.as_str(), |(_, r)| r);
            SceneError::new(format!("{base}.material.{field}"), reason.to_string())
        })?;
        Ok(m)
    }
}

impl LossSpec {
    fn model(&self, material_eta: f64) -> LossModel {
        LossModel {
            loss_factor: self.loss_factor.unwrap_or(material_eta),
            decay_rate_per_s: self.decay_rate_per_s,
            radiation_per_s: self.radiation_per_s,
            radiation_ref_hz: self.radiation_ref_hz,
            radiation_exponent: self.radiation_exponent,
        }
    }

    /// Every decay rate changed by `rate` (a caller scales decay times
    /// through it, as the instrument does for its decay and damper
    /// parameters: each mode's `sigma` is linear in the three rates, so
    /// scaling them scales every mode's T60 alike), `material_eta` the loss
    /// factor the object takes when none is given here. An object without
    /// any loss gets the constant rate `undamped_rate` instead.
    pub fn scaled(&self, material_eta: f64, undamped_rate: f64, rate: impl Fn(f64) -> f64) -> Self {
        let eta = self.loss_factor.unwrap_or(material_eta);
        if eta == 0.0
            && self.decay_rate_per_s == 0.0
            && self.radiation_per_s == 0.0
            && self.plate_radiation == 0.0
        {
            if undamped_rate == 0.0 {
                return self.clone();
            }
            return LossSpec {
                loss_factor: Some(0.0),
                decay_rate_per_s: undamped_rate,
                ..self.clone()
            };
        }
        let scaled_eta = rate(eta);
        LossSpec {
            // unchanged stays as written (a unit scale keeps the scene)
            loss_factor: if self.loss_factor.is_none() && scaled_eta == eta {
                None
            } else {
                Some(scaled_eta)
            },
            decay_rate_per_s: rate(self.decay_rate_per_s),
            radiation_per_s: rate(self.radiation_per_s),
            plate_radiation: rate(self.plate_radiation),
            ..self.clone()
        }
    }
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
            PhysicalSpec::Tube(s) => {
                let m = s.material.resolve(base)?;
                let mut tube = Tube::new(s.length_m, s.outer_diameter_m, s.inner_diameter_m, &m);
                tube.support = s.support.support();
                if s.timoshenko {
                    tube = tube.with_timoshenko(m.shear_modulus_pa, m.poisson_ratio);
                }
                if s.torsion {
                    tube = tube.with_torsion(m.shear_modulus_pa);
                }
                (Shape::Tube(tube), m.loss_factor)
            }
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
    fn point(&self, base: &str, name: &str, p: PointSpec) -> Result<Point, SceneError> {
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

    /// The modal object this describes at `rate_hz`: modes up to the
    /// limits, each mode's T60 from the loss model and its weight at every
    /// point from the mass-normalised shape. Errors name the field.
    pub fn to_modal(&self, base: &str, rate_hz: f64) -> Result<ModalSpec, SceneError> {
        self.to_modal_heard(base, rate_hz, &[])
    }

    /// [`Self::to_modal`] with two more points per listener, `{l}~q` and
    /// `{l}~v` ([`crate::scene::pressure_point`]): each mode's weights for
    /// the pressure it radiates toward the listener (docs/design.md,
    /// "Radiation to a listener"; `crate::bodies::radiation`).
    pub fn to_modal_heard(
        &self,
        base: &str,
        rate_hz: f64,
        listeners: &[&ListenerSpec],
    ) -> Result<ModalSpec, SceneError> {
        let (shape, eta) = self.shape(base)?;
        let loss = self.loss().model(eta);
        loss.validate().map_err(|e| shape_error(base, e))?;
        let limits = self.limits();
        let (max_freq, max_count) = mode_limits(base, &limits, rate_hz)?;
        let points = self.named_points(base)?;
        let modes = listed_modes(
            base,
            &shape,
            max_freq,
            max_count,
            limits.max_modes.is_none(),
        )?;
        let weight_scale = self.weight_scale(base, &shape)?;
        let mut mode = Vec::with_capacity(modes.len());
        let radiation = self.plate_radiation(base, &shape)?;
        let lowest = modes
            .iter()
            .map(|m| m.freq_hz)
            .fold(f64::INFINITY, f64::min);
        let resonator = self.resonator(base, &shape, lowest)?;
        let weighing = Weighing {
            base,
            shape: &shape,
            weight_scale,
            points: &points,
            listeners,
        };
        for (k, m) in modes.iter().enumerate() {
            // what the tube does to this mode ringing at its frequency
            let tube = match &resonator {
                Some((r, at)) => {
                    let phi = weight_scale
                        * m.shape_at(*at).map_err(|e| {
                            SceneError::new(format!("{base}.resonator.point"), e.to_string())
                        })?;
                    Some(r.on_mode(m.freq_hz, phi))
                }
                None => None,
            };
            let sigma = loss
                .decay_rate(m.freq_hz)
                .map_err(|e| shape_error(base, e))?
                + radiation.as_ref().map_or(0.0, |r| r(m.freq_hz))
                + tube.map_or(0.0, |t| t.decay_rate_per_s);
            let t60_s = (sigma > 0.0).then(|| (1000f64.ln() / sigma).max(MIN_T60_S));
            // the tube's frequency shift (under 0.1 cent on the presets) is
            // not applied: the bar keeps the tuning its maker gave it
            let freq_hz = m.freq_hz;
            let mut weights = weighing.at_points(k, m)?;
            weighing.toward_listeners(k, m, tube, &mut weights)?;
            mode.push(ModeSpec {
                freq_hz,
                t60_s,
                weights,
            });
        }
        let mut names: Vec<String> = points.into_iter().map(|(n, _)| n).collect();
        for l in listeners {
            names.push(pressure_point(&l.name, false));
            names.push(pressure_point(&l.name, true));
        }
        Ok(ModalSpec {
            name: self.name().to_string(),
            points: names,
            mode,
        })
    }

    /// The object's named points as points of its shape (at least one).
    fn named_points(&self, base: &str) -> Result<Vec<(String, Point)>, SceneError> {
        let points: Vec<(String, Point)> = self
            .points()
            .iter()
            .map(|(n, p)| Ok((n.clone(), self.point(base, n, *p)?)))
            .collect::<Result<_, SceneError>>()?;
        if points.is_empty() {
            return Err(SceneError::new(
                format!("{base}.points"),
                "name at least one point (the struck one)",
            ));
        }
        Ok(points)
    }

    /// A bar's resonator tube and the point over its axis; `lowest_hz`
    /// (the bar's lowest mode) is its default tuning. The bar covers the
    /// mouth across its width: `S_c = min(pi a^2, 2 a b)`.
    fn resonator(
        &self,
        base: &str,
        shape: &Shape,
        lowest_hz: f64,
    ) -> Result<Option<(Resonator, Point)>, SceneError> {
        let (PhysicalSpec::Bar(spec), Shape::Bar(bar)) = (self, shape) else {
            return Ok(None);
        };
        let Some(r) = &spec.resonator else {
            return Ok(None);
        };
        let path = format!("{base}.resonator");
        let Some(p) = spec.points.get(&r.point) else {
            return Err(SceneError::new(
                format!("{path}.point"),
                format!("names no point of the bar: {:?}", r.point),
            ));
        };
        let at = self.point(base, &r.point, *p)?;
        check_positive(&format!("{path}.radius_m"), r.radius_m)?;
        let tuned = r.tuned_hz.unwrap_or(lowest_hz);
        check_positive(&format!("{path}.tuned_hz"), tuned)?;
        let a = r.radius_m;
        let covered = (PI * a * a).min(2.0 * a * bar.width_m);
        let tube =
            Resonator::tuned(a, tuned, covered).map_err(|e| SceneError::new(path.clone(), e))?;
        Ok(Some((tube, at)))
    }

    /// `sqrt(m_uniform / mass_kg)` of an undercut bar whose mass is given
    /// (1 otherwise).
    fn weight_scale(&self, base: &str, shape: &Shape) -> Result<f64, SceneError> {
        let (PhysicalSpec::Bar(spec), Shape::Bar(bar)) = (self, shape) else {
            return Ok(1.0);
        };
        let Some(m) = spec.mass_kg else {
            return Ok(1.0);
        };
        let path = format!("{base}.mass_kg");
        check_positive(&path, m)?;
        let uniform = bar.mass_kg();
        if spec.tuning.is_empty() || m > uniform {
            return Err(SceneError::new(
                path,
                format!(
                    "only a tuned (undercut) bar takes a mass, at most the uniform bar's {uniform} kg; got {m}"
                ),
            ));
        }
        Ok((uniform / m).sqrt())
    }

    /// The plate radiation term of the loss, when asked for (plates only).
    #[allow(clippy::type_complexity)]
    fn plate_radiation(
        &self,
        base: &str,
        shape: &Shape,
    ) -> Result<Option<Box<dyn Fn(f64) -> f64>>, SceneError> {
        let scale = self.loss().plate_radiation;
        check_non_negative(&format!("{base}.loss.plate_radiation"), scale)?;
        if scale == 0.0 {
            return Ok(None);
        }
        let Shape::Plate(p) = shape else {
            return Err(SceneError::new(
                format!("{base}.loss.plate_radiation"),
                format!("only a plate radiates as a plate, not a {}", self.kind()),
            ));
        };
        let (a, b, rho_h, d) = (
            p.length_x_m,
            p.length_y_m,
            p.density_kg_m3 * p.thickness_m,
            p.flexural_rigidity(),
        );
        Ok(Some(Box::new(move |f| {
            scale * plate_radiation_rate(f, a, b, rho_h, d)
        })))
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

/// The highest frequency and the most modes `limits` let an object list:
/// `max_freq_hz` (at most [`MAX_FREQ_HZ`]) or the Nyquist frequency of
/// `rate_hz`, and `max_modes` (1 ..= [`MAX_MODES_PER_OBJECT`]) or that
/// limit. Errors name the field.
fn mode_limits(base: &str, limits: &ModeLimits, rate_hz: f64) -> Result<(f64, usize), SceneError> {
    let max_freq = match limits.max_freq_hz {
        Some(f) => {
            check_positive(&format!("{base}.max_freq_hz"), f)?;
            f.min(MAX_FREQ_HZ)
        }
        None => 0.5 * rate_hz,
    };
    let max_count = limits.max_modes.unwrap_or(MAX_MODES_PER_OBJECT);
    if max_count == 0 || max_count > MAX_MODES_PER_OBJECT {
        return Err(SceneError::new(
            format!("{base}.max_modes"),
            format!("must be in 1..={MAX_MODES_PER_OBJECT}, got {max_count}"),
        ));
    }
    Ok((max_freq, max_count))
}

/// The modes of `shape` up to `max_freq` Hz, at most `max_count`, without
/// those below [`MIN_FREQ_HZ`]; `unlimited` (no `max_modes` given): an
/// error before any work when the estimate is far above the limit, and
/// when more than `max_count` modes lie below `max_freq`.
fn listed_modes(
    base: &str,
    shape: &Shape,
    max_freq: f64,
    max_count: usize,
    unlimited: bool,
) -> Result<Vec<ShapeMode>, SceneError> {
    // refuse before any work when the limits would list too many modes
    if unlimited {
        let estimate = mode_count_estimate(shape, max_freq);
        if estimate > 2.0 * MAX_MODES_PER_OBJECT as f64 {
            return Err(SceneError::new(
                base.to_string(),
                format!(
                    "about {estimate:.0} modes below {max_freq:.0} Hz, more than the limit of \
                     {MAX_MODES_PER_OBJECT}: set `max_freq_hz` or `max_modes`"
                ),
            ));
        }
    }
    let modes = shape
        .modes(max_freq, max_count + 1)
        .map_err(|e| shape_error(base, e))?;
    if modes.len() > max_count && unlimited {
        return Err(SceneError::new(
            base.to_string(),
            format!(
                "more than {MAX_MODES_PER_OBJECT} modes below {max_freq:.0} Hz (about {:.0}): \
                 set `max_freq_hz` or `max_modes`",
                mode_count_estimate(shape, max_freq)
            ),
        ));
    }
    let modes: Vec<ShapeMode> = modes
        .into_iter()
        .take(max_count)
        .filter(|m| m.freq_hz >= MIN_FREQ_HZ)
        .collect();
    if modes.is_empty() {
        return Err(SceneError::new(
            format!("{base}.max_freq_hz"),
            format!(
                "no mode at or below {max_freq} Hz (the lowest is at {:.6e} Hz)",
                shape
                    .modes(f64::INFINITY, 1)
                    .ok()
                    .and_then(|m| m.first().map(|m| m.freq_hz))
                    .unwrap_or(f64::NAN)
            ),
        ));
    }
    Ok(modes)
}

/// What each mode of one object is weighed at: its named points, and the
/// listeners its pressure pickups name.
struct Weighing<'a> {
    /// The object's path in the scene, for errors.
    base: &'a str,
    /// The object's kind and geometry.
    shape: &'a Shape,
    /// What multiplies every mass-normalised shape (a tuned bar's
    /// renormalisation, else 1).
    weight_scale: f64,
    /// The named points.
    points: &'a [(String, Point)],
    /// The listeners heard.
    listeners: &'a [&'a ListenerSpec],
}

impl Weighing<'_> {
    /// Mode `k`'s weight at each point, each within [`MAX_WEIGHT`].
    fn at_points(&self, k: usize, m: &ShapeMode) -> Result<Vec<f64>, SceneError> {
        let mut weights = Vec::with_capacity(self.points.len());
        for (name, p) in self.points {
            let w = self.weight_scale
                * m.shape_at(*p).map_err(|e| {
                    SceneError::new(format!("{}.points.{name}", self.base), e.to_string())
                })?;
            if !(w.abs() <= MAX_WEIGHT) {
                return Err(SceneError::new(
                    self.base.to_string(),
                    format!(
                        "mode {k} ({}) has weight {w:e} at point {name:?}: the object is too \
                         light (an effective mass below 1e-12 kg)",
                        m.label
                    ),
                ));
            }
            weights.push(w);
        }
        Ok(weights)
    }

    /// Mode `k`'s two weights toward each listener (its far field and the
    /// tube's monopole, `tube`), appended to `weights`, each within
    /// [`MAX_WEIGHT`].
    fn toward_listeners(
        &self,
        k: usize,
        m: &ShapeMode,
        tube: Option<ModeEffect>,
        weights: &mut Vec<f64>,
    ) -> Result<(), SceneError> {
        for l in self.listeners {
            let dir = Direction {
                polar_deg: l.polar_deg,
                azimuth_deg: l.azimuth_deg,
            };
            let (re, im) = far_field(self.shape, m, dir, SOUND_SPEED_M_PER_S).map_err(|e| {
                SceneError::new(
                    format!("{}: listener {:?}", self.base, l.name),
                    e.to_string(),
                )
            })?;
            // the tube's monopole beside the bar's own far field
            let (re, im) = tube.map_or((re, im), |t| (re + t.far_field.0, im + t.far_field.1));
            let r = m.omega() / PRESSURE_REF_OMEGA;
            for w in [
                self.weight_scale * r * r * re / PRESSURE_REF_AREA_M2,
                self.weight_scale * r * im / PRESSURE_REF_AREA_M2,
            ] {
                if !(w.abs() <= MAX_WEIGHT) {
                    return Err(SceneError::new(
                        self.base.to_string(),
                        format!(
                            "mode {k} ({}) radiates with weight {w:e} toward listener {:?}, \
                             beyond {MAX_WEIGHT:e}",
                            m.label, l.name
                        ),
                    ));
                }
                weights.push(w);
            }
        }
        Ok(())
    }
}

/// Modes below `f` by the asymptotic mode count of each kind (Weyl's law
/// for the plate and membrane; the beam and string dispersion relations),
/// for refusing runaway geometry before listing anything.
fn mode_count_estimate(shape: &Shape, f: f64) -> f64 {
    let w = 2.0 * PI * f;
    match shape {
        // bending (omega = (n pi / L)^2 sqrt(E I / (rho A))) plus torsion
        // (f = n c_t / (2 L))
        Shape::Bar(b) => {
            let ei_ra = b.youngs_modulus_pa * b.thickness_m.powi(2) / (12.0 * b.density_kg_m3);
            let torsion = b.torsion.map_or(0.0, |g| {
                let c_t =
                    (g * b.torsion_constant_m4() / (b.density_kg_m3 * b.polar_moment_m4())).sqrt();
                2.0 * b.length_m * f / c_t
            });
            b.length_m * (w * w / ei_ra).powf(0.25) / PI + torsion
        }
        Shape::Tube(t) => {
            let r2 = (t.outer_diameter_m.powi(2) + t.inner_diameter_m.powi(2)) / 16.0;
            let ei_ra = t.youngs_modulus_pa * r2 / t.density_kg_m3;
            let torsion = t
                .torsion
                .map_or(0.0, |g| 2.0 * t.length_m * f / (g / t.density_kg_m3).sqrt());
            t.length_m * (w * w / ei_ra).powf(0.25) / PI + torsion
        }
        Shape::Plate(p) => {
            let area = p.length_x_m * p.length_y_m;
            area * w * (p.density_kg_m3 * p.thickness_m / p.flexural_rigidity()).sqrt() / (4.0 * PI)
        }
        Shape::Membrane(m) => {
            let k = w * (m.areal_density_kg_m2 / m.tension_n_per_m).sqrt();
            (m.radius_m * k).powi(2) / 4.0
        }
        Shape::StiffString(s) => f / s.ideal_fundamental_hz(),
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
