//! Scene files: the editable description of an instrument (docs/design.md, "Scene files").
//!
//! A scene is parsed from TOML with serde (`deny_unknown_fields` everywhere, so a
//! misspelt key is an error, not silence) and then validated. Every error names
//! the field by its path and gives the reason, e.g.
//! `object[0].mode[2].t60_s: must be > 0, got -1`.
//!
//! Units are SI and carried in the key names (`_hz`, `_s`, `_kg`, `_n_per_m`, ...).
//!
//! This file holds the schema (the [`Scene`] and the tables it is made of)
//! and turns a scene into the one the compiler runs on
//! ([`Scene::expanded`]); the rest of the room: `limits.rs` (the range of
//! every value), `error.rs` ([`SceneError`] and the value checks),
//! `validate.rs` ([`Scene::validate`]), `physical/` (objects from
//! geometry and material) and `mallet.rs` (modal mallets and lumped
//! chains).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod drive;
mod error;
mod law;
mod limits;
mod mallet;
mod physical;
mod validate;

pub use drive::{
    Beyond, DriveSpec, SurfaceSpec, MAX_PRESS_N, MAX_ROLL_RADIUS_M, MAX_SURFACE_DEPTH_M,
    MAX_SURFACE_LENGTH_M,
};
pub use error::SceneError;
pub use law::{fit_power, LawSpec, Pieces, MAX_LAW_PIECES};
pub use limits::{
    MAX_CONTACTS, MAX_DAMPING_N_S_PER_M, MAX_DURATION_S, MAX_FREQ_HZ, MAX_GAIN,
    MAX_GRAVITY_M_PER_S2, MAX_HEIGHT_M, MAX_LEVEL_DB, MAX_LISTENER_DISTANCE_M, MAX_MASS_KG,
    MAX_MODES_PER_OBJECT, MAX_RAYLEIGH_ALPHA_PER_S, MAX_RAYLEIGH_BETA_S, MAX_SPEED_M_PER_S,
    MAX_SPRINGS, MAX_STIFFNESS_N_PER_M, MAX_STRING_MASSES, MAX_WEIGHT, MIN_FREQ_HZ, MIN_LEVEL_DB,
    MIN_LISTENER_DISTANCE_M, MIN_MASS_KG, MIN_STIFFNESS_N_PER_M, MIN_T60_S, SCENE_VERSION,
};
pub use mallet::{mallet_contact_point, ChainSpec, MAX_CHAIN_MASSES};
pub use physical::{
    plate_radiation_rate, BarSpec, EdgesSpec, LossSpec, MaterialSpec, MembraneSpec, PhysicalSpec,
    PlateSpec, PointDashpotSpec, PointSpec, StiffStringSpec, SupportSpec, TubeSpec,
};

/// How the engine switches between the free and the contact phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Switching {
    /// The paper's method (section 2.2): contact starts at the first sample with
    /// penetration > 0, with an offset rod so the spring starts unstretched.
    #[serde(rename = "offset-rod")]
    OffsetRod,
    /// Switch instants located inside the sample on the exact phase solution
    /// (the default: the offset rod is only first-order accurate).
    #[serde(rename = "exact")]
    #[default]
    Exact,
}

impl Switching {
    /// Parse the command-line / scene spelling.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "offset-rod" => Some(Self::OffsetRod),
            "exact" => Some(Self::Exact),
            _ => None,
        }
    }
    /// The scene-file spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::OffsetRod => "offset-rod",
            Self::Exact => "exact",
        }
    }
}

/// A whole scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// File layout version; must be [`SCENE_VERSION`].
    pub version: u32,
    /// Short name (presets use the file stem).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Default render length \[s\].
    #[serde(default = "default_duration_s")]
    pub duration_s: f64,
    /// The real instrument this scene models, by its General MIDI name
    /// (e.g. "marimba"): `cargo xtask compare-real` compares the scene's
    /// strike with recordings of it (docs/design.md, "How close to the real
    /// instruments"); absent: not compared. Rendering ignores it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub real_instrument: Option<String>,
    /// The scene's output level \[dB\]: a gain of `10^(level_db / 20)` on
    /// every pickup, so that scenes of very different physics sound at one
    /// loudness at the same velocity (the presets' values are set by `cargo
    /// xtask levels --write`: docs/design.md, "Scene files" and "Offline
    /// rendering"). [`Scene::expanded`] applies it; 0 (the default) leaves
    /// the pickups as written.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub level_db: f64,
    /// The objects of the scene (at least one).
    #[serde(default)]
    pub object: Vec<ObjectSpec>,
    /// The striking point mass.
    pub hammer: HammerSpec,
    /// Which object and point the hammer hits, and the contact spring-damper.
    pub contact: ContactSpec,
    /// More hammers, each with a contact of its own on the struck object
    /// (docs/design.md, "Several contacts"); empty: the one contact of
    /// `[hammer]` and `[contact]`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub striker: Vec<StrikerSpec>,
    /// Contacts between two objects, an object and the hammer, or either
    /// and a wall (docs/design.md, "Several contacts"); empty: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub touch: Vec<TouchSpec>,
    /// What is heard.
    #[serde(default)]
    pub pickup: Vec<PickupSpec>,
    /// Far listeners the pressure pickups name (empty: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub listener: Vec<ListenerSpec>,
    /// Opt-in approximate savings (none by default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub approximate: Option<ApproxSpec>,
    /// How the instrument plays the scene: what a note's release does
    /// (absent: [`DEFAULT_RELEASE_DAMPER`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub play: Option<PlaySpec>,
    /// The hammer's contact driven over a surface profile (rolling,
    /// scraping: docs/design.md, "Rolling and scraping"); absent: struck.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<DriveSpec>,
}

/// The damper of a scene that does not say (`[play]` or its `damper`
/// absent): decay times after a note's release divided by `1 + 50 * 0.5`,
/// what every scene played before scenes could say it.
pub const DEFAULT_RELEASE_DAMPER: f64 = 0.5;

/// The `[play]` table: how the instrument plays the scene (docs/plugin.md,
/// "Velocity, pitch, voices"). Offline renders have no notes and ignore it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PlaySpec {
    /// How strongly a released note is damped, 0 ..= 1, as the Damper
    /// parameter: decay times after note-off divided by `1 + 50 * damper`;
    /// 0: no damper, the object rings on after the release (a marimba bar,
    /// a bell). Absent: [`DEFAULT_RELEASE_DAMPER`]. The plugin's Damper
    /// replaces it when Custom damper is on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damper: Option<f64>,
    /// The pitch a listener names \[Hz\], where it is not the struck
    /// object's lowest mode: a tubular chime's strike note (about half its
    /// fourth mode's frequency), a bell's prime (an octave above its hum).
    /// The instrument's root note is the MIDI note nearest it (absent: the
    /// lowest mode's, [`crate::instrument::root_note`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_hz: Option<f64>,
}

/// Opt-in approximations: each drops modes and adds a (measured) error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ApproxSpec {
    /// Drop modes above this frequency \[Hz\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_freq_hz: Option<f64>,
    /// Drop modes above this fraction of the Nyquist frequency (e.g. 0.9).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nyquist_fraction: Option<f64>,
    /// Drop modes whose bounded contribution at the pickups is below this
    /// level relative to the loudest mode [dB, negative, e.g. -80].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quiet_below_db: Option<f64>,
}

fn default_duration_s() -> f64 {
    1.0
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// One object; `kind` selects the variant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind")]
pub enum ObjectSpec {
    /// An abstract modal object (paper section 2.3).
    #[serde(rename = "modal")]
    Modal(ModalSpec),
    /// `masses` lumped masses between fixed ends (paper sections 1.2, 2.1).
    #[serde(rename = "string")]
    String(StringSpec),
    /// A rigid, immovable surface at x = 0.
    #[serde(rename = "wall")]
    Wall(WallSpec),
    /// A rectangular bar from geometry and material.
    #[serde(rename = "bar")]
    Bar(BarSpec),
    /// A round tube or rod from geometry and material.
    #[serde(rename = "tube")]
    Tube(TubeSpec),
    /// A rectangular plate from geometry and material.
    #[serde(rename = "plate")]
    Plate(PlateSpec),
    /// A circular membrane from radius, tension and areal density.
    #[serde(rename = "membrane")]
    Membrane(MembraneSpec),
    /// A string with bending stiffness.
    #[serde(rename = "stiff_string")]
    StiffString(StiffStringSpec),
    /// A free lumped chain: a mallet's head and shaft (only as
    /// `hammer.object`).
    #[serde(rename = "chain")]
    Chain(ChainSpec),
}

impl ObjectSpec {
    /// The object's name.
    pub fn name(&self) -> &str {
        match self {
            ObjectSpec::Modal(m) => &m.name,
            ObjectSpec::String(s) => &s.name,
            ObjectSpec::Wall(w) => &w.name,
            ObjectSpec::Chain(c) => &c.name,
            _ => self.physical().map_or("", |p| p.name()),
        }
    }
    /// Names of the object's points, in the order the object defines them.
    pub fn point_names(&self) -> Vec<String> {
        match self {
            ObjectSpec::Modal(m) => m.points.clone(),
            ObjectSpec::String(s) => s.points.keys().cloned().collect(),
            ObjectSpec::Wall(_) => Vec::new(),
            ObjectSpec::Chain(c) => c.points.keys().cloned().collect(),
            _ => self
                .physical()
                .map(|p| p.points().keys().cloned().collect())
                .unwrap_or_default(),
        }
    }
    /// The object as a physical description (bar, tube, plate, membrane,
    /// stiff string), if it is one.
    pub fn physical(&self) -> Option<PhysicalSpec<'_>> {
        match self {
            ObjectSpec::Bar(s) => Some(PhysicalSpec::Bar(s)),
            ObjectSpec::Tube(s) => Some(PhysicalSpec::Tube(s)),
            ObjectSpec::Plate(s) => Some(PhysicalSpec::Plate(s)),
            ObjectSpec::Membrane(s) => Some(PhysicalSpec::Membrane(s)),
            ObjectSpec::StiffString(s) => Some(PhysicalSpec::StiffString(s)),
            ObjectSpec::Modal(_)
            | ObjectSpec::String(_)
            | ObjectSpec::Wall(_)
            | ObjectSpec::Chain(_) => None,
        }
    }
    /// The scene-file spelling of the object's kind.
    pub fn kind(&self) -> &'static str {
        match self {
            ObjectSpec::Modal(_) => "modal",
            ObjectSpec::String(_) => "string",
            ObjectSpec::Wall(_) => "wall",
            ObjectSpec::Chain(_) => "chain",
            _ => self.physical().map_or("", |p| p.kind()),
        }
    }
}

/// An abstract modal object: modes with frequency, T60 and weights at points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModalSpec {
    /// Object name.
    pub name: String,
    /// Named points; each mode has one weight per point, in this order.
    pub points: Vec<String>,
    /// The modes.
    #[serde(default)]
    pub mode: Vec<ModeSpec>,
}

/// One mode of a modal object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeSpec {
    /// Undamped natural frequency \[Hz\].
    pub freq_hz: f64,
    /// 60 dB decay time \[s\]; omitted means undamped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t60_s: Option<f64>,
    /// Mass-normalised mode shape at each point \[1/sqrt(kg)\].
    pub weights: Vec<f64>,
}

/// A string of lumped masses between fixed ends.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StringSpec {
    /// Object name.
    pub name: String,
    /// Number of masses.
    pub masses: usize,
    /// Each mass \[kg\].
    pub mass_kg: f64,
    /// Each of the `masses + 1` springs \[N/m\].
    pub spring_n_per_m: f64,
    /// Rayleigh damping, mass part: `C = alpha M + beta K + dashpots` \[1/s\].
    #[serde(default)]
    pub rayleigh_alpha_per_s: f64,
    /// Rayleigh damping, stiffness part \[s\].
    #[serde(default)]
    pub rayleigh_beta_s: f64,
    /// Extra dashpots to ground at single masses (make C not commute with K).
    #[serde(default)]
    pub dashpots: Vec<DashpotSpec>,
    /// Named points: 0-based mass indices.
    pub points: BTreeMap<String, usize>,
}

impl StringSpec {
    /// Natural frequency of mode `j` (1..=masses) of the undamped
    /// fixed-fixed chain \[Hz\]: `omega_j = 2 sqrt(s/m) sin(j pi / (2 (n + 1)))`
    /// (docs/design.md, "Conventions and units"). The one closed form of the string's
    /// modes: validation, summaries and the instrument's root note use it.
    pub fn mode_freq_hz(&self, j: usize) -> f64 {
        let omega = 2.0
            * (self.spring_n_per_m / self.mass_kg).sqrt()
            * (j as f64 * std::f64::consts::PI / (2.0 * (self.masses as f64 + 1.0))).sin();
        omega / (2.0 * std::f64::consts::PI)
    }
}

/// A dashpot from one mass to ground.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DashpotSpec {
    /// 0-based mass index.
    pub mass: usize,
    /// Damping coefficient \[N s/m\].
    pub n_s_per_m: f64,
}

/// A rigid wall at x = 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallSpec {
    /// Object name.
    pub name: String,
}

/// The hammer: a point mass moving along the vertical axis (positive up).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HammerSpec {
    /// Mass \[kg\].
    pub mass_kg: f64,
    /// Initial height of its contact face \[m\] (>= 0: it starts out of contact).
    pub height_m: f64,
    /// Initial velocity \[m/s\], positive up.
    #[serde(default)]
    pub velocity_m_per_s: f64,
    /// Gravity acting on the hammer \[m/s^2\] (pulls down); 0 = none.
    #[serde(default)]
    pub gravity_m_per_s2: f64,
    /// A modal mallet: the object of the scene whose modes are the
    /// hammer's own (free-free elastic) vibration; `mass_kg` is then the
    /// whole mallet's mass, its rigid-body motion (docs/design.md, "Modal
    /// mallets"). `None`: a point mass.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object: Option<String>,
    /// The mallet's point that touches the struck object (with `object`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
    /// In a scene of several contacts played by the instrument: the MIDI
    /// notes that strike this mallet (docs/design.md, "Played as a kit").
    /// Empty: see [`StrikerSpec::notes`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<u8>,
}

/// Another hammer (a point mass, or a modal mallet: [`StrikerSpec::mallet`])
/// with a contact of its own on the struck object (`[contact].object`), at
/// a point of its own, under the scene's gravity
/// (`[hammer].gravity_m_per_s2`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StrikerSpec {
    /// Mass \[kg\].
    pub mass_kg: f64,
    /// Initial height of its contact face \[m\] (>= 0).
    pub height_m: f64,
    /// Initial velocity \[m/s\], positive up.
    #[serde(default)]
    pub velocity_m_per_s: f64,
    /// The struck object's point it hits.
    pub point: String,
    /// Contact stiffness \[N/m\] (omitted, 0, with a `law`).
    #[serde(default)]
    pub stiffness_n_per_m: f64,
    /// Contact damping \[N s/m\] (with a `law`: the first piece's, as
    /// [`ContactSpec::damping_n_s_per_m`]).
    #[serde(default)]
    pub damping_n_s_per_m: f64,
    /// A law of several pieces instead of one stiffness, as `[contact]`'s
    /// ([`ContactSpec::law`]); not with a modal mallet (`mallet`) yet.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<LawSpec>,
    /// The MIDI notes that strike this mallet when the instrument plays
    /// the scene. When no mallet (`[hammer]` or a striker) lists notes,
    /// every note strikes the next mallet in turn (a roll on one key);
    /// else a note strikes every mallet that lists it, and a note no
    /// mallet lists strikes nothing.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<u8>,
    /// A mallet with modes of its own, as `hammer.object` and
    /// `hammer.point` make one of the hammer (docs/design.md, "Modal
    /// mallets"): the object whose free modes are the mallet's elastic
    /// vibration and its point that touches. `mass_kg` is then the whole
    /// mallet's mass (its rigid motion). None: a point mass.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mallet: Option<End>,
}

/// The name a touch gives the scene's `[hammer]`.
pub const HAMMER_SIDE: &str = "hammer";

/// One side of a touch: an object (and its point, but for a wall) or the
/// hammer ([`HAMMER_SIDE`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct End {
    /// An object's name, or `"hammer"`.
    pub object: String,
    /// The object's point (not for a wall or the hammer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
    /// Set by [`Scene::expanded`] alone, on a side `"hammer"`: the side is
    /// striker `i` (the further pieces of a striker's law); never read
    /// from or written to a scene file.
    #[serde(skip)]
    pub striker: Option<usize>,
}

/// A contact between two sides (docs/design.md, "Several contacts"):
/// penetration `p = x_lower - x_upper - gap_m`, in contact while `p > 0`,
/// the spring-damper `k p + c p'` pushing the upper side up and the lower
/// one down.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TouchSpec {
    /// The side below.
    pub lower: End,
    /// The side above.
    pub upper: End,
    /// How far the upper side rests above the lower one \[m\] (>= 0; the
    /// hammer's height already counts from the struck object's rest, a
    /// wall is at 0).
    #[serde(default)]
    pub gap_m: f64,
    /// Contact stiffness \[N/m\] (omitted, 0, with a `law`).
    #[serde(default)]
    pub stiffness_n_per_m: f64,
    /// Contact damping \[N s/m\] (with a `law`: the first piece's).
    #[serde(default)]
    pub damping_n_s_per_m: f64,
    /// A law of several pieces instead of one stiffness, as `[contact]`'s
    /// ([`ContactSpec::law`]), its breakpoints counted from `gap_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<LawSpec>,
}

/// The contact spring-damper (paper eq. 9).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Name of the struck object.
    pub object: String,
    /// Name of the struck point (omit for a wall).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
    /// Contact stiffness k_c \[N/m\] (omitted, 0, with a `law`).
    #[serde(default)]
    pub stiffness_n_per_m: f64,
    /// Contact damping c_c \[N s/m\] (with a `law`: the first piece's; each
    /// further piece adds damping in proportion to the stiffness it adds).
    #[serde(default)]
    pub damping_n_s_per_m: f64,
    /// Switching method; omitted means the project default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub switching: Option<Switching>,
    /// A law of several pieces that stiffens instead of one stiffness
    /// (docs/design.md, "Stiffening contacts").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<LawSpec>,
}

/// What a pickup measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Quantity {
    /// Velocity of the point \[m/s\] (the default: it weights the highs as the ear does).
    #[default]
    Velocity,
    /// Displacement of the point \[m\].
    Displacement,
    /// Sound pressure radiated by the whole object to a far listener \[Pa\]:
    /// the pickup's `point` names a `[[listener]]`, its object is one from
    /// geometry (docs/design.md, "Radiation to a listener").
    Pressure,
}

/// A listener far from the objects, for pressure pickups: its distance and
/// direction in each object's own frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ListenerSpec {
    /// Name a pressure pickup's `point` refers to.
    pub name: String,
    /// Distance from the object \[m\] (the far field: several times the
    /// object's size).
    pub distance_m: f64,
    /// Angle from the object's radiating face's normal \[deg\], 0 ..= 90.
    #[serde(default)]
    pub polar_deg: f64,
    /// Angle around that normal from the object's x axis (its length, a
    /// plate's first side, a membrane's angle origin) \[deg\].
    #[serde(default)]
    pub azimuth_deg: f64,
}

/// A pickup: a point that is heard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickupSpec {
    /// Object name.
    pub object: String,
    /// Point name.
    pub point: String,
    /// Velocity or displacement.
    #[serde(default)]
    pub quantity: Quantity,
    /// Linear gain applied to the quantity.
    #[serde(default = "default_gain")]
    pub gain: f64,
    /// Stereo position, -1 (left) .. 1 (right); constant-power pan law.
    #[serde(default)]
    pub pan: f64,
}

fn default_gain() -> f64 {
    1.0
}

/// The angular frequency \[rad/s\] (1 kHz) and the area \[m^2\] the
/// pressure rows are written in units of: a mode's weights on a listener's
/// pseudo-points are `(omega_n / PRESSURE_REF_OMEGA)^k W_n /
/// PRESSURE_REF_AREA_M2` (within [`MAX_WEIGHT`] for every audible mode of
/// any object the limits allow), the pickups' gains carry the rest.
pub const PRESSURE_REF_OMEGA: f64 = 2.0 * std::f64::consts::PI * 1000.0;

/// See [`PRESSURE_REF_OMEGA`].
pub const PRESSURE_REF_AREA_M2: f64 = 1.0e-3;

/// The two pickups a pressure pickup becomes in [`Scene::expanded`]: the
/// radiated pressure of mode `n` toward listener `l` at distance `r` is
/// `-(rho0 / (2 pi r)) (omega_n^2 Re W_n q_n + omega_n Im W_n q_n')`
/// (docs/design.md, "Radiation to a listener"), so a displacement pickup
/// on the point `{l}~q` (weights `(omega_n / omega_ref)^2 Re W_n / A_ref`)
/// and a velocity pickup on `{l}~v` (weights `(omega_n / omega_ref) Im W_n
/// / A_ref`), their gains `-g rho0 / (2 pi r)` times `omega_ref^2 A_ref`
/// and `omega_ref A_ref`.
fn pressure_pickups(pk: &PickupSpec, listeners: &[ListenerSpec]) -> Vec<PickupSpec> {
    use crate::bodies::radiation::AIR_DENSITY_KG_PER_M3;
    let Some(l) = listeners.iter().find(|l| l.name == pk.point) else {
        return Vec::new();
    };
    let g = -pk.gain * AIR_DENSITY_KG_PER_M3 / (2.0 * std::f64::consts::PI * l.distance_m)
        * PRESSURE_REF_AREA_M2;
    let w = PRESSURE_REF_OMEGA;
    vec![
        PickupSpec {
            point: pressure_point(&l.name, false),
            quantity: Quantity::Displacement,
            gain: g * w * w,
            ..pk.clone()
        },
        PickupSpec {
            point: pressure_point(&l.name, true),
            quantity: Quantity::Velocity,
            gain: g * w,
            ..pk.clone()
        },
    ]
}

/// The name of a listener's pseudo-point on an expanded object: `{l}~q`
/// (weights on the modal displacements) or `{l}~v` (on the velocities).
pub fn pressure_point(listener: &str, velocity: bool) -> String {
    format!("{listener}~{}", if velocity { 'v' } else { 'q' })
}

impl Scene {
    /// Parse and validate a scene from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Scene, SceneError> {
        let scene: Scene = toml::from_str(text).map_err(|e| {
            let mut msg = e.message().trim().to_string();
            if msg.is_empty() {
                // some syntax errors carry their text only in Display
                msg = e.to_string().replace('\n', " ");
            }
            let loc = e
                .span()
                .map(|s| {
                    let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                    format!(" (line {line})")
                })
                .unwrap_or_default();
            SceneError::new("", format!("{msg}{loc}"))
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// Read, parse and validate a scene file. A file the scene names by
    /// a relative path (`drive.surface.file`) is taken from the scene
    /// file's folder.
    pub fn from_file(path: &std::path::Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new("", format!("cannot read {}: {e}", path.display())))?;
        let mut scene = Self::from_toml_str(&text)?;
        if let Some(DriveSpec {
            surface: SurfaceSpec::Wav { file, .. },
            ..
        }) = scene.drive.as_mut()
        {
            let named = std::path::Path::new(file.as_str());
            if named.is_relative() {
                if let Some(dir) = path.parent() {
                    *file = dir.join(named).to_string_lossy().into_owned();
                }
            }
        }
        Ok(scene)
    }

    /// Serialise back to TOML.
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a validated scene always serialises")
    }

    /// The scene with every physically described object (bar, tube,
    /// plate, membrane, stiff string) replaced by the modal object it
    /// describes at `rate_hz` (docs/design.md, "Objects from geometry and
    /// material"); other objects as they are; a modal mallet's modes joined
    /// to the struck object's (docs/design.md, "Modal mallets"); every
    /// pickup's gain times [`Scene::level_gain`] (the expanded scene's
    /// `level_db` is 0: its pickups carry the level). The compiler runs on
    /// this.
    pub fn expanded(&self, rate_hz: f64) -> Result<Scene, SceneError> {
        let mut out = self.clone();
        for (i, obj) in out.object.iter_mut().enumerate() {
            if let Some(p) = obj.physical() {
                // the listeners its pressure pickups name
                let heard: Vec<&ListenerSpec> = self
                    .listener
                    .iter()
                    .filter(|l| {
                        self.pickup.iter().any(|pk| {
                            pk.quantity == Quantity::Pressure
                                && pk.object == p.name()
                                && pk.point == l.name
                        })
                    })
                    .collect();
                let modal = p.to_modal_heard(&format!("object[{i}]"), rate_hz, &heard)?;
                *obj = ObjectSpec::Modal(modal);
            } else if let ObjectSpec::Chain(c) = obj {
                *obj = ObjectSpec::Modal(c.to_modal());
            }
        }
        out.pickup = self
            .pickup
            .iter()
            .flat_map(|pk| match pk.quantity {
                Quantity::Pressure => pressure_pickups(pk, &self.listener),
                _ => vec![pk.clone()],
            })
            .collect();
        // the scene's level: after the pressure pickups' expansion, so it
        // scales every output row alike (docs/design.md, "Scene files")
        if self.level_db != 0.0 {
            let g = self.level_gain();
            for pk in &mut out.pickup {
                pk.gain *= g;
            }
            out.level_db = 0.0;
        }
        out.listener.clear();
        // a hand pressing a driven hammer: a constant force, as its weight is
        if let Some(d) = &out.drive {
            if d.press_n > 0.0 {
                out.hammer.gravity_m_per_s2 += d.press_n / out.hammer.mass_kg;
            }
        }
        out.merge_mallet()?;
        out.expand_law()?;
        Ok(out)
    }

    /// Every contact's law as springs side by side (src/scene/law.rs):
    /// the contact takes its first piece's stiffness, and each further
    /// piece becomes a `[[touch]]` between the same two sides, after the
    /// scene's own touches (`[contact]`'s, then each striker's, then each
    /// touch's), its gap the piece's breakpoint (a touch's: plus its own
    /// gap), its stiffness and damping what the piece adds (damping in
    /// proportion to stiffness, the first piece's ratio). Each added
    /// spring and damper is positive, so each is passive, and so is their
    /// sum.
    fn expand_law(&mut self) -> Result<(), SceneError> {
        let mut added = Vec::new();
        let hammer = |striker: Option<usize>| End {
            object: HAMMER_SIDE.to_string(),
            point: None,
            striker,
        };
        if let Some(law) = self.contact.law.take() {
            let c = &mut self.contact;
            let lower = End {
                object: c.object.clone(),
                point: c.point.clone(),
                striker: None,
            };
            let (k, d) = (&mut c.stiffness_n_per_m, c.damping_n_s_per_m);
            added.extend(law_touches(
                &law,
                "contact.law",
                (k, d),
                (lower, hammer(None)),
                0.0,
            )?);
        }
        for (i, st) in self.striker.iter_mut().enumerate() {
            if let Some(law) = st.law.take() {
                let lower = End {
                    object: self.contact.object.clone(),
                    point: Some(st.point.clone()),
                    striker: None,
                };
                let (k, d) = (&mut st.stiffness_n_per_m, st.damping_n_s_per_m);
                let path = format!("striker[{i}].law");
                added.extend(law_touches(
                    &law,
                    &path,
                    (k, d),
                    (lower, hammer(Some(i))),
                    0.0,
                )?);
            }
        }
        for (i, t) in self.touch.iter_mut().enumerate() {
            if let Some(law) = t.law.take() {
                let sides = (t.lower.clone(), t.upper.clone());
                let (k, d) = (&mut t.stiffness_n_per_m, t.damping_n_s_per_m);
                let path = format!("touch[{i}].law");
                added.extend(law_touches(&law, &path, (k, d), sides, t.gap_m)?);
            }
        }
        self.touch.extend(added);
        Ok(())
    }

    /// The linear gain of `level_db`, `10^(level_db / 20)` (exactly 1 at
    /// 0 dB).
    pub fn level_gain(&self) -> f64 {
        10f64.powf(self.level_db / 20.0)
    }

    /// Several contacts (`[[striker]]` or `[[touch]]`): the several-contact
    /// engine runs it, the one-contact compiler and the instrument refuse
    /// it.
    pub fn several_contacts(&self) -> bool {
        !self.striker.is_empty() || !self.touch.is_empty() || self.all_contacts() > 1
    }

    /// Contacts the scene makes once every law is springs side by side:
    /// each contact one per piece of its law (one without a law, or with
    /// one that is not valid).
    pub fn all_contacts(&self) -> usize {
        law_count(self.contact.law.as_ref())
            + self
                .striker
                .iter()
                .map(|st| law_count(st.law.as_ref()))
                .sum::<usize>()
            + self
                .touch
                .iter()
                .map(|t| law_count(t.law.as_ref()))
                .sum::<usize>()
    }

    /// Index of the object named `name`.
    pub fn object_index(&self, name: &str) -> Option<usize> {
        self.object.iter().position(|o| o.name() == name)
    }

    /// How strongly a released note is damped: `[play] damper`, or
    /// [`DEFAULT_RELEASE_DAMPER`] when the scene does not say.
    pub fn release_damper(&self) -> f64 {
        self.play
            .as_ref()
            .and_then(|p| p.damper)
            .unwrap_or(DEFAULT_RELEASE_DAMPER)
    }
}

/// Contacts a law makes: one per piece (1 without a law, or with one
/// that is not valid: validation says why).
fn law_count(law: Option<&LawSpec>) -> usize {
    law.and_then(|l| l.pieces("law").ok())
        .map_or(1, |p| p.stiffness.len())
}

/// The touches a contact's `law` adds between `sides` (lower, upper): the
/// contact's stiffness `k` becomes the first piece's, each further piece a
/// touch at `gap + ` its breakpoint with the stiffness it adds and damping
/// in the first piece's ratio `d / k_1` ([`Scene::expand_law`]).
fn law_touches(
    law: &LawSpec,
    path: &str,
    (k, d): (&mut f64, f64),
    (lower, upper): (End, End),
    gap: f64,
) -> Result<Vec<TouchSpec>, SceneError> {
    let pieces = law.pieces(path)?;
    let k1 = pieces.stiffness[0];
    let ratio = d / k1;
    *k = k1;
    Ok(pieces
        .breakpoints
        .iter()
        .enumerate()
        .map(|(i, &q)| {
            let dk = pieces.stiffness[i + 1] - pieces.stiffness[i];
            TouchSpec {
                lower: lower.clone(),
                upper: upper.clone(),
                gap_m: gap + q,
                stiffness_n_per_m: dk,
                damping_n_s_per_m: ratio * dk,
                law: None,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    const BAR: &str = r#"
version = 1
name = "t"
[[object]]
name = "bar"
kind = "modal"
points = ["contact"]
[[object.mode]]
freq_hz = 220.0
t60_s = 1.0
weights = [1.0]
[hammer]
mass_kg = 0.03
height_m = 0.001
[contact]
object = "bar"
point = "contact"
stiffness_n_per_m = 3e5
[[pickup]]
object = "bar"
point = "contact"
"#;

    /// `[contact] law`: read, checked, a round trip through TOML, and
    /// expanded into springs side by side (one `[[touch]]` per further
    /// piece, its gap the breakpoint, its stiffness and damping what the
    /// piece adds); refusals name the field.
    #[test]
    fn a_contact_law_becomes_touches_and_bad_ones_name_their_field() {
        let law = "law = { breakpoints_m = [1e-4, 3e-4], stiffness_n_per_m = [1e5, 3e5, 7e5] }";
        let with = BAR.replace(
            "stiffness_n_per_m = 3e5",
            &format!("damping_n_s_per_m = 10.0\n{law}"),
        );
        let s = Scene::from_toml_str(&with).unwrap();
        assert!(s.several_contacts());
        assert_eq!(s.all_contacts(), 3);
        let back = Scene::from_toml_str(&s.to_toml_string()).unwrap();
        assert_eq!(back, s, "round trip");
        let e = s.expanded(48_000.0).unwrap();
        assert_eq!(e.contact.law, None);
        assert_eq!(e.contact.stiffness_n_per_m, 1e5);
        let touches: Vec<(f64, f64, f64)> = e
            .touch
            .iter()
            .map(|t| (t.gap_m, t.stiffness_n_per_m, t.damping_n_s_per_m))
            .collect();
        assert_eq!(touches, vec![(1e-4, 2e5, 20.0), (3e-4, 4e5, 40.0)]);
        assert!(e.touch.iter().all(|t| t.upper.object == HAMMER_SIDE
            && t.lower.object == "bar"
            && t.lower.point.as_deref() == Some("contact")));
        let bad = |text: String, field: &str| {
            let err = Scene::from_toml_str(&text).unwrap_err();
            assert_eq!(err.path, field, "{err}");
        };
        bad(
            BAR.replace("stiffness_n_per_m = 3e5", ""),
            "contact.stiffness_n_per_m",
        );
        bad(
            BAR.replace(
                "stiffness_n_per_m = 3e5",
                &format!("stiffness_n_per_m = 3e5\n{law}"),
            ),
            "contact.stiffness_n_per_m",
        );
        bad(
            BAR.replace(
                "stiffness_n_per_m = 3e5",
                "law = { breakpoints_m = [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 6e-4, 7e-4, 8e-4], \
                 stiffness_n_per_m = [1e5, 2e5, 3e5, 4e5, 5e5, 6e5, 7e5, 8e5, 9e5] }",
            ),
            // nine pieces, one more than a law may have
            "contact.law.stiffness_n_per_m",
        );
        bad(
            BAR.replace(
                "stiffness_n_per_m = 3e5",
                "law = { power = 2.5, pieces = 3 }",
            ),
            "contact.law.force_n_at",
        );
    }

    /// A striker's and a touch's `law`: read, a round trip through TOML,
    /// expanded into touches after the scene's own (a striker's against
    /// that striker, a touch's between its sides from its own gap), the
    /// contacts counted with every law's pieces; refusals name the field.
    /// The bar with points `contact`, `b` and `c`, a striker at `b` and a
    /// touch from `c` to the hammer, each with a law of two pieces, and
    /// that law's text.
    fn law_bar_striker_touch() -> (String, String, String, &'static str) {
        let law = "law = { breakpoints_m = [1e-4], stiffness_n_per_m = [1e5, 3e5] }";
        let bar = BAR
            .replace(
                "points = [\"contact\"]",
                "points = [\"contact\", \"b\", \"c\"]",
            )
            .replace("weights = [1.0]", "weights = [1.0, 0.5, -0.5]");
        let striker = format!(
            "[[striker]]\nmass_kg = 0.02\nheight_m = 0.001\npoint = \"b\"\ndamping_n_s_per_m = 2.0\n{law}\n"
        );
        let touch = format!(
            "[[touch]]\nlower = {{ object = \"bar\", point = \"c\" }}\nupper = {{ object = \"hammer\" }}\n\
             gap_m = 0.002\ndamping_n_s_per_m = 1.0\n{law}\n"
        );
        (bar, striker, touch, law)
    }

    #[test]
    fn striker_and_touch_laws_become_touches_and_bad_ones_name_their_field() {
        let (bar, striker, touch, law) = law_bar_striker_touch();
        let s = Scene::from_toml_str(&format!("{bar}{striker}"))
            .map_err(|e| e.to_string())
            .unwrap();
        assert_eq!(s.all_contacts(), 3);
        let back = Scene::from_toml_str(&s.to_toml_string()).unwrap();
        assert_eq!(back, s, "round trip");
        let e = s.expanded(48_000.0).unwrap();
        assert_eq!(e.striker[0].law, None);
        assert_eq!(e.striker[0].stiffness_n_per_m, 1e5);
        assert_eq!(e.touch.len(), 1);
        let t = &e.touch[0];
        assert_eq!(
            (t.gap_m, t.stiffness_n_per_m, t.damping_n_s_per_m),
            (1e-4, 2e5, 4.0)
        );
        assert_eq!(
            (t.upper.object.as_str(), t.upper.striker),
            (HAMMER_SIDE, Some(0))
        );
        assert_eq!(t.lower.point.as_deref(), Some("b"));
        let s = Scene::from_toml_str(&format!("{bar}{touch}")).unwrap();
        let e = s.expanded(48_000.0).unwrap();
        assert_eq!(e.touch.len(), 2);
        assert_eq!(e.touch[0].stiffness_n_per_m, 1e5);
        let t = &e.touch[1];
        assert_eq!(
            (t.gap_m, t.stiffness_n_per_m, t.damping_n_s_per_m),
            (0.002 + 1e-4, 2e5, 2.0)
        );
        assert_eq!(
            (t.upper.striker, t.lower.point.as_deref()),
            (None, Some("c"))
        );
        let bad = |text: String, field: &str| {
            let err = Scene::from_toml_str(&text).unwrap_err();
            assert_eq!(err.path, field, "{err}");
            err.to_string()
        };
        bad(
            format!(
                "{bar}{}",
                striker.replace("damping_n_s_per_m = 2.0", "stiffness_n_per_m = 1e5")
            ),
            "striker[0].stiffness_n_per_m",
        );
        bad(
            format!(
                "{bar}{}",
                touch.replace("damping_n_s_per_m = 1.0", "stiffness_n_per_m = 1e5")
            ),
            "touch[0].stiffness_n_per_m",
        );
        bad(
            format!("{bar}{}", striker.replace(&format!("{law}\n"), "")),
            "striker[0].stiffness_n_per_m",
        );
        bad(
            format!("{bar}{}", striker.replace("[1e5, 3e5]", "[3e5, 1e5]")),
            "striker[0].law.stiffness_n_per_m[1]",
        );
        // a striker's law on a modal mallet: its pieces are touches on that
        // striker (the model presses them on the struck point less the
        // mallet's face: tests/contact_law.rs)
        let mallet = "[[object]]\nname = \"m\"\nkind = \"modal\"\npoints = [\"tip\"]\n\
                      [[object.mode]]\nfreq_hz = 2000.0\nt60_s = 0.1\nweights = [1.0]\n";
        let on_mallet = Scene::from_toml_str(&format!(
            "{bar}{mallet}{}",
            striker.replace(
                "point = \"b\"",
                "point = \"b\"\nmallet = { object = \"m\", point = \"tip\" }"
            )
        ))
        .unwrap();
        let e = on_mallet.expanded(48_000.0).unwrap();
        assert_eq!(e.touch.len(), 1);
        assert_eq!(e.touch[0].upper.striker, Some(0));
        assert!(e.striker[0].mallet.is_some());
    }

    /// A law has at most eight pieces and a scene at most twelve springs
    /// with every law's pieces (`MAX_SPRINGS`): five are within it,
    /// thirteen are refused at the first law.
    #[test]
    fn laws_make_at_most_twelve_springs() {
        let (bar, striker, touch, law) = law_bar_striker_touch();
        let bad = |text: String, field: &str| {
            let err = Scene::from_toml_str(&text).unwrap_err();
            assert_eq!(err.path, field, "{err}");
            err.to_string()
        };
        // five springs are within the limit, thirteen are not
        let five = Scene::from_toml_str(&format!("{bar}{striker}{touch}")).unwrap();
        assert_eq!(five.all_contacts(), 5);
        let eight = "law = { breakpoints_m = [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 6e-4, 7e-4], \
                     stiffness_n_per_m = [1e5, 2e5, 3e5, 4e5, 5e5, 6e5, 7e5, 8e5] }";
        let four = "law = { breakpoints_m = [1e-4, 2e-4, 3e-4], \
                    stiffness_n_per_m = [1e5, 2e5, 3e5, 4e5] }";
        let too_many = bad(
            format!(
                "{bar}{}{}",
                striker.replace(law, eight),
                touch.replace(law, four)
            ),
            "striker[0].law",
        );
        assert!(too_many.contains("13 springs"), "{too_many}");
    }

    /// `[play] damper`: absent is today's 0.5, 0 ..= 1 is taken as
    /// written and survives a round trip through TOML; anything else is
    /// refused with its field path.
    #[test]
    fn play_damper_is_read_checked_and_defaults_to_half() {
        let plain = Scene::from_toml_str(BAR).unwrap();
        assert_eq!(plain.play, None);
        assert_eq!(plain.release_damper(), DEFAULT_RELEASE_DAMPER);
        assert!(!plain.to_toml_string().contains("[play]"));
        let empty = Scene::from_toml_str(&format!("{BAR}[play]\n")).unwrap();
        assert_eq!(empty.release_damper(), 0.5);
        for d in [0.0, 0.25, 1.0] {
            let s = Scene::from_toml_str(&format!("{BAR}[play]\ndamper = {d:?}\n")).unwrap();
            assert_eq!(s.release_damper(), d);
            let back = Scene::from_toml_str(&s.to_toml_string()).unwrap();
            assert_eq!(back, s, "round trip");
        }
        for (value, want) in [
            ("-0.1", "play.damper: must be within 0 ..= 1, got -0.1"),
            ("1.5", "play.damper: must be within 0 ..= 1, got 1.5"),
            ("nan", "play.damper: must be finite, got NaN"),
            ("inf", "play.damper: must be finite, got inf"),
            ("\"off\"", "invalid type: string \"off\", expected f64"),
        ] {
            let text = format!("{BAR}[play]\ndamper = {value}\n");
            let got = Scene::from_toml_str(&text).unwrap_err().to_string();
            assert!(got.contains(want), "{value}: {got}");
        }
        let got = Scene::from_toml_str(&format!("{BAR}[play]\ndampr = 0.0\n"))
            .unwrap_err()
            .to_string();
        assert!(got.contains("unknown field `dampr`"), "{got}");
    }

    /// `[play] pitch_hz`: read, written back, checked with its field path;
    /// `real_instrument` likewise read and written back.
    #[test]
    fn play_pitch_and_real_instrument_are_read_and_checked() {
        let text = format!("{BAR}[play]\npitch_hz = 493.0\n");
        let s = Scene::from_toml_str(&text).unwrap();
        assert_eq!(s.play.as_ref().and_then(|p| p.pitch_hz), Some(493.0));
        assert_eq!(Scene::from_toml_str(&s.to_toml_string()).unwrap(), s);
        for (value, want) in [
            ("0.0", "play.pitch_hz: must be > 0, got 0"),
            ("-5.0", "play.pitch_hz: must be > 0, got -5"),
            ("nan", "play.pitch_hz: must be finite, got NaN"),
            ("4.0", "play.pitch_hz"),
            ("20000.0", "play.pitch_hz"),
        ] {
            let text = format!("{BAR}[play]\npitch_hz = {value}\n");
            let got = Scene::from_toml_str(&text).unwrap_err().to_string();
            assert!(got.contains(want), "{value}: {got}");
        }
        let named = BAR.replacen(
            "version = 1\n",
            "version = 1\nreal_instrument = \"Marimba\"\n",
            1,
        );
        let s = Scene::from_toml_str(&named).unwrap();
        assert_eq!(s.real_instrument.as_deref(), Some("Marimba"));
        assert_eq!(Scene::from_toml_str(&s.to_toml_string()).unwrap(), s);
    }

    /// `level_db`: absent is 0 and not written back; a value is read,
    /// written back and multiplies every pickup's gain in the expanded
    /// scene (whose own level is then 0); anything out of range, not a
    /// number, or a level that takes a pickup's gain past [`MAX_GAIN`] is
    /// refused naming `level_db`.
    #[test]
    fn level_db_is_read_checked_and_scales_the_pickups() {
        let plain = Scene::from_toml_str(BAR).unwrap();
        assert_eq!(plain.level_db, 0.0);
        assert_eq!(plain.level_gain(), 1.0);
        assert!(!plain.to_toml_string().contains("level_db"));
        assert_eq!(
            plain.expanded(48000.0).unwrap(),
            plain.expanded(48000.0).unwrap()
        );
        let text = BAR.replacen("version = 1\n", "version = 1\nlevel_db = -6.5\n", 1);
        let s = Scene::from_toml_str(&text).unwrap();
        assert_eq!(s.level_db, -6.5);
        assert!(s.to_toml_string().contains("level_db = -6.5"));
        assert_eq!(Scene::from_toml_str(&s.to_toml_string()).unwrap(), s);
        let (e0, e1) = (
            plain.expanded(48000.0).unwrap(),
            s.expanded(48000.0).unwrap(),
        );
        assert_eq!(e1.level_db, 0.0);
        assert_eq!(e0.pickup.len(), e1.pickup.len());
        for (a, b) in e0.pickup.iter().zip(&e1.pickup) {
            assert_eq!(b.gain, a.gain * 10f64.powf(-6.5 / 20.0));
        }
        e1.validate().unwrap();
        for (value, want) in [
            ("nan", "level_db: must be finite, got NaN"),
            ("inf", "level_db: must be finite, got inf"),
            ("40.5", "level_db: must be within -60 ..= 40 dB, got 40.5"),
            ("-61.0", "level_db: must be within -60 ..= 40 dB, got -61"),
            ("\"loud\"", "invalid type: string \"loud\", expected f64"),
        ] {
            let text = BAR.replacen(
                "version = 1\n",
                &format!("version = 1\nlevel_db = {value}\n"),
                1,
            );
            let got = Scene::from_toml_str(&text).unwrap_err().to_string();
            assert!(got.contains(want), "{value}: {got}");
        }
        // BAR ends in its pickup's table
        let loud =
            BAR.replacen("version = 1\n", "version = 1\nlevel_db = 40.0\n", 1) + "gain = 1e5\n";
        let got = Scene::from_toml_str(&loud).unwrap_err().to_string();
        assert!(got.starts_with("level_db: pickup[0].gain"), "{got}");
    }
}
