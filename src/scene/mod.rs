//! Scene files: the editable description of an instrument (docs/design.md, "Scene files").
//!
//! A scene is parsed from TOML with serde (`deny_unknown_fields` everywhere, so a
//! misspelt key is an error, not silence) and then validated. Every error names
//! the field by its path and gives the reason, e.g.
//! `object[0].mode[2].t60_s: must be > 0, got -1`.
//!
//! Units are SI and carried in the key names (`_hz`, `_s`, `_kg`, `_n_per_m`, ...).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

mod mallet;
mod physical;
pub use mallet::{mallet_contact_point, ChainSpec, MAX_CHAIN_MASSES};
pub use physical::{
    plate_radiation_rate, BarSpec, EdgesSpec, LossSpec, MaterialSpec, MembraneSpec, PhysicalSpec,
    PlateSpec, PointSpec, StiffStringSpec, SupportSpec, TubeSpec,
};

/// The only scene file layout version this build reads.
pub const SCENE_VERSION: u32 = 1;
/// Largest number of lumped masses in a `kind = "string"` object. The contact
/// system has `2 * masses + 2` states and is diagonalised off the audio thread;
/// 2000 masses already take seconds (docs/numerics.md, "Decomposing a phase").
pub const MAX_STRING_MASSES: usize = 2000;
/// Largest number of modes in one modal object (same reason as above).
pub const MAX_MODES_PER_OBJECT: usize = 4000;
/// Frequencies above this are refused as nonsense (10 MHz is far above any
/// audio rate this plugin runs at; above-Nyquist modes below it are legal).
pub const MAX_FREQ_HZ: f64 = 1.0e7;

// Ranges of the other physical values. Outside them the compiled matrices
// overflow or lose all precision (tests/fuzz_scenes.rs found each case: a
// 1e-300 kg hammer or a 5e-324 s T60 gives non-finite generators, gravity
// 1e300 non-finite energies, a gain of 1e300 non-finite output), so a scene
// file is refused with the field's name instead. Each range is far wider than
// any instrument needs.

/// Lowest mode frequency \[Hz\]: a period of 1000 s, longer than any render; a
/// 0 Hz mode would be a free rigid body, which is not a mode.
pub const MIN_FREQ_HZ: f64 = 1.0e-3;
/// Shortest T60 \[s\]: 60 dB of decay in a microsecond (damping rate
/// `ln(1000) / T60` up to 6.9e6 1/s) is far beyond any audible damping.
pub const MIN_T60_S: f64 = 1.0e-6;
/// Largest mode weight magnitude \[1/sqrt(kg)\]: a mode that looks like a mass
/// of `1 / w^2 = 1e-12` kg at that point ([`MIN_MASS_KG`]).
pub const MAX_WEIGHT: f64 = 1.0e6;
/// Lightest and heaviest mass \[kg\] (hammer, string masses): the lower limit
/// is the effective mass of the largest allowed weight, `1 / MAX_WEIGHT^2`.
pub const MIN_MASS_KG: f64 = 1.0e-12;
/// See [`MIN_MASS_KG`] (a thousand tonnes).
pub const MAX_MASS_KG: f64 = 1.0e6;
/// Smallest contact stiffness \[N/m\]: a spring that pushes with 1 uN per mm
/// of compression. Softer ones overflow the static equilibrium under
/// gravity (`m g / k`; tests/fuzz_scenes.rs found `5e-324`).
pub const MIN_STIFFNESS_N_PER_M: f64 = 1.0e-3;
/// Largest contact or string spring stiffness \[N/m\] (a contact frequency of
/// 1000x the Nyquist frequency of 44.1 kHz with a 20 g hammer needs 3.8e14).
pub const MAX_STIFFNESS_N_PER_M: f64 = 1.0e16;
/// Largest contact or dashpot damping \[N s/m\] (an overdamped contact with
/// zeta = 1e3 for a 20 g hammer on 1e6 N/m needs 2.8e5).
pub const MAX_DAMPING_N_S_PER_M: f64 = 1.0e9;
/// Largest Rayleigh mass-proportional damping \[1/s\] (the rate of a T60 of
/// [`MIN_T60_S`]: `2 ln(1000) / 1e-6`).
pub const MAX_RAYLEIGH_ALPHA_PER_S: f64 = 1.4e7;
/// Largest Rayleigh stiffness-proportional damping \[s\] (1 s damps every
/// mode above 1 Hz critically).
pub const MAX_RAYLEIGH_BETA_S: f64 = 1.0;
/// Largest hammer height \[m\] and speed \[m/s\] (three times the speed of
/// sound in air).
pub const MAX_HEIGHT_M: f64 = 1.0e3;
/// See [`MAX_HEIGHT_M`].
pub const MAX_SPEED_M_PER_S: f64 = 1.0e3;
/// Largest gravity \[m/s^2\] (a thousand g).
pub const MAX_GRAVITY_M_PER_S2: f64 = 1.0e4;
/// Largest pickup gain magnitude (+120 dB).
pub const MAX_GAIN: f64 = 1.0e6;
/// Longest `duration_s` \[s\] (the renderer's limit).
pub const MAX_DURATION_S: f64 = 3600.0;
/// Quietest and loudest `level_db` \[dB\], the output level a scene states
/// (docs/design.md, "Scene files"): far wider than the spread of the
/// presets' loudness, which it evens out.
pub const MIN_LEVEL_DB: f64 = -60.0;
/// See [`MIN_LEVEL_DB`].
pub const MAX_LEVEL_DB: f64 = 40.0;

/// A validation or parse error that names the field and the reason.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// Path of the offending field, e.g. `object[0].mode[2].t60_s` (empty for
    /// TOML syntax errors, whose message carries the line).
    pub path: String,
    /// Why the value is refused.
    pub reason: String,
}

impl SceneError {
    pub(crate) fn new(path: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            reason: reason.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            write!(f, "{}", self.reason)
        } else {
            write!(f, "{}: {}", self.path, self.reason)
        }
    }
}

impl std::error::Error for SceneError {}

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
    /// Contact stiffness \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Contact damping \[N s/m\].
    #[serde(default)]
    pub damping_n_s_per_m: f64,
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

/// Most contacts of one scene: `[contact]` and up to `MAX_CONTACTS - 1`
/// strikers and touches.
pub const MAX_CONTACTS: usize = 4;

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
    /// Contact stiffness \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Contact damping \[N s/m\].
    #[serde(default)]
    pub damping_n_s_per_m: f64,
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
    /// Contact stiffness k_c \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Contact damping c_c \[N s/m\].
    #[serde(default)]
    pub damping_n_s_per_m: f64,
    /// Switching method; omitted means the project default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub switching: Option<Switching>,
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

/// Farthest listener \[m\].
pub const MAX_LISTENER_DISTANCE_M: f64 = 1000.0;
/// Nearest listener \[m\] (closer is not the far field of any object;
/// it also keeps the pressure pickups' gains within [`MAX_GAIN`]).
pub const MIN_LISTENER_DISTANCE_M: f64 = 0.1;

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

fn check_finite(path: &str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SceneError::new(path, format!("must be finite, got {v}")))
    }
}

fn check_positive(path: &str, v: f64) -> Result<(), SceneError> {
    check_finite(path, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(SceneError::new(path, format!("must be > 0, got {v}")))
    }
}

fn check_non_negative(path: &str, v: f64) -> Result<(), SceneError> {
    check_finite(path, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(SceneError::new(path, format!("must be >= 0, got {v}")))
    }
}

/// `v` (already known finite) must be at most `hi`.
fn check_max(path: &str, v: f64, hi: f64) -> Result<(), SceneError> {
    if v <= hi {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("must be <= {hi:e}, got {v:e}"),
        ))
    }
}

/// `v` (already known finite) must be at least `lo`.
fn check_min(path: &str, v: f64, lo: f64) -> Result<(), SceneError> {
    if v >= lo {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("must be >= {lo:e}, got {v:e}"),
        ))
    }
}

/// `|v|` (already known finite) must be at most `hi`.
fn check_abs_max(path: &str, v: f64, hi: f64) -> Result<(), SceneError> {
    if v.abs() <= hi {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("|value| must be <= {hi:e}, got {v:e}"),
        ))
    }
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

    /// Read, parse and validate a scene file.
    pub fn from_file(path: &std::path::Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new("", format!("cannot read {}: {e}", path.display())))?;
        Self::from_toml_str(&text)
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
        out.merge_mallet()?;
        Ok(out)
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
        !self.striker.is_empty() || !self.touch.is_empty()
    }

    /// Index of the object named `name`.
    pub fn object_index(&self, name: &str) -> Option<usize> {
        self.object.iter().position(|o| o.name() == name)
    }

    /// Check every value; the first problem found is returned.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.version != SCENE_VERSION {
            return Err(SceneError::new(
                "version",
                format!("must be {SCENE_VERSION}, got {}", self.version),
            ));
        }
        check_positive("duration_s", self.duration_s)?;
        check_max("duration_s", self.duration_s, MAX_DURATION_S)?;
        check_finite("level_db", self.level_db)?;
        if !(MIN_LEVEL_DB..=MAX_LEVEL_DB).contains(&self.level_db) {
            return Err(SceneError::new(
                "level_db",
                format!(
                    "must be within {MIN_LEVEL_DB} ..= {MAX_LEVEL_DB} dB, got {}",
                    self.level_db
                ),
            ));
        }
        if self.object.is_empty() {
            return Err(SceneError::new("object", "at least one object is needed"));
        }
        self.validate_objects()?;
        if let Some(a) = &self.approximate {
            a.validate()?;
        }
        self.hammer.validate()?;
        self.validate_contact()?;
        self.validate_mallet()?;
        self.validate_strikers()?;
        self.validate_touches()?;
        self.validate_notes()?;
        self.validate_listeners()?;
        self.validate_pickups()?;
        if let Some(p) = &self.play {
            p.validate()?;
        }
        Ok(())
    }

    /// How strongly a released note is damped: `[play] damper`, or
    /// [`DEFAULT_RELEASE_DAMPER`] when the scene does not say.
    pub fn release_damper(&self) -> f64 {
        self.play
            .as_ref()
            .and_then(|p| p.damper)
            .unwrap_or(DEFAULT_RELEASE_DAMPER)
    }

    /// Notes: MIDI notes (0..=127), and only where there are several
    /// contacts (they choose among the mallets the instrument strikes).
    fn validate_notes(&self) -> Result<(), SceneError> {
        let lists = std::iter::once(("hammer.notes".to_string(), &self.hammer.notes)).chain(
            self.striker
                .iter()
                .enumerate()
                .map(|(i, st)| (format!("striker[{i}].notes"), &st.notes)),
        );
        for (field, notes) in lists {
            if let Some(&n) = notes.iter().find(|&&n| n > 127) {
                return Err(SceneError::new(
                    field,
                    format!("{n} is not a MIDI note (0 ..= 127)"),
                ));
            }
            if !notes.is_empty() && !self.several_contacts() {
                return Err(SceneError::new(
                    field,
                    "notes choose among the mallets of a scene of several contacts ([[striker]] \
                     or [[touch]]); with one contact every note strikes the hammer: remove it",
                ));
            }
        }
        Ok(())
    }

    /// Strikers: at most `MAX_CONTACTS - 1`; each hits a point of the
    /// struck object that no other contact hits, with the values of a
    /// hammer and a contact, and a mallet of its own if it names one;
    /// strikers need an object with points (not a wall).
    fn validate_strikers(&self) -> Result<(), SceneError> {
        if self.striker.is_empty() {
            return Ok(());
        }
        if self.striker.len() >= MAX_CONTACTS {
            return Err(SceneError::new(
                "striker",
                format!(
                    "{} strikers and [contact] make {} contacts, at most {MAX_CONTACTS}",
                    self.striker.len(),
                    self.striker.len() + 1
                ),
            ));
        }
        let obj = self
            .object_index(&self.contact.object)
            .map(|i| &self.object[i])
            .expect("validate_contact ran first");
        if matches!(obj, ObjectSpec::Wall(_)) {
            return Err(SceneError::new(
                "striker",
                "several contacts strike an object with points, not a wall",
            ));
        }
        let names = obj.point_names();
        for (i, st) in self.striker.iter().enumerate() {
            let base = format!("striker[{i}]");
            let f = |k: &str| format!("{base}.{k}");
            if !names.contains(&st.point) {
                return Err(SceneError::new(
                    f("point"),
                    format!(
                        "object {:?} has no point {:?}",
                        self.contact.object, st.point
                    ),
                ));
            }
            let taken = self.contact.point.as_ref() == Some(&st.point)
                || self.striker[..i].iter().any(|o| o.point == st.point);
            if taken {
                return Err(SceneError::new(
                    f("point"),
                    format!(
                        "another contact already hits {:?}: two contacts on one point pair",
                        st.point
                    ),
                ));
            }
            check_positive(&f("mass_kg"), st.mass_kg)?;
            check_min(&f("mass_kg"), st.mass_kg, MIN_MASS_KG)?;
            check_max(&f("mass_kg"), st.mass_kg, MAX_MASS_KG)?;
            check_non_negative(&f("height_m"), st.height_m)?;
            check_max(&f("height_m"), st.height_m, MAX_HEIGHT_M)?;
            check_finite(&f("velocity_m_per_s"), st.velocity_m_per_s)?;
            check_abs_max(
                &f("velocity_m_per_s"),
                st.velocity_m_per_s,
                MAX_SPEED_M_PER_S,
            )?;
            check_positive(&f("stiffness_n_per_m"), st.stiffness_n_per_m)?;
            check_min(
                &f("stiffness_n_per_m"),
                st.stiffness_n_per_m,
                MIN_STIFFNESS_N_PER_M,
            )?;
            check_max(
                &f("stiffness_n_per_m"),
                st.stiffness_n_per_m,
                MAX_STIFFNESS_N_PER_M,
            )?;
            check_non_negative(&f("damping_n_s_per_m"), st.damping_n_s_per_m)?;
            check_max(
                &f("damping_n_s_per_m"),
                st.damping_n_s_per_m,
                MAX_DAMPING_N_S_PER_M,
            )?;
            if let Some(m) = &st.mallet {
                let used = self.hammer.object.as_ref() == Some(&m.object)
                    || self.striker[..i]
                        .iter()
                        .any(|o| o.mallet.as_ref().is_some_and(|x| x.object == m.object));
                if used {
                    return Err(SceneError::new(
                        f("mallet.object"),
                        format!(
                            "{:?} is another mallet already: each mallet is an object of its own",
                            m.object
                        ),
                    ));
                }
                let touched = self
                    .touch
                    .iter()
                    .any(|t| t.lower.object == m.object || t.upper.object == m.object);
                if touched {
                    return Err(SceneError::new(
                        f("mallet.object"),
                        format!(
                            "a touch names {:?}: a striker's mallet is struck only through its striker",
                            m.object
                        ),
                    ));
                }
                self.check_mallet(
                    [&f("mallet.object"), &f("mallet.point"), &f("mass_kg")],
                    &m.object,
                    m.point.as_ref(),
                    st.mass_kg,
                )?;
            }
        }
        Ok(())
    }

    /// Touches: at most `MAX_CONTACTS` contacts in all; each side names
    /// the hammer, a wall or an object's point, the two sides differ, no
    /// two contacts join the same pair, values in their ranges.
    fn validate_touches(&self) -> Result<(), SceneError> {
        if self.touch.is_empty() {
            return Ok(());
        }
        let total = 1 + self.striker.len() + self.touch.len();
        if total > MAX_CONTACTS {
            return Err(SceneError::new(
                "touch",
                format!(
                    "[contact], {} strikers and {} touches make {total} contacts, at most \
                     {MAX_CONTACTS}",
                    self.striker.len(),
                    self.touch.len()
                ),
            ));
        }
        // every contact's pair of sides, as (object, point) both ways
        let side_key = |e: &End| (e.object.clone(), e.point.clone());
        let mut pairs = vec![(
            (self.contact.object.clone(), self.contact.point.clone()),
            (HAMMER_SIDE.to_string(), None),
        )];
        for st in &self.striker {
            pairs.push((
                (self.contact.object.clone(), Some(st.point.clone())),
                (HAMMER_SIDE.to_string(), None),
            ));
        }
        for (i, t) in self.touch.iter().enumerate() {
            let f = |k: &str| format!("touch[{i}].{k}");
            let mut walls = 0;
            for (name, e) in [("lower", &t.lower), ("upper", &t.upper)] {
                if e.object == HAMMER_SIDE {
                    if self.object_index(HAMMER_SIDE).is_some() {
                        return Err(SceneError::new(
                            f(&format!("{name}.object")),
                            "\"hammer\" names both an object and the hammer: rename the object",
                        ));
                    }
                    // a point of the hammer's modal mallet (its face when
                    // none is named)
                    if let Some(p) = &e.point {
                        let Some(m) = &self.hammer.object else {
                            return Err(SceneError::new(
                                f(&format!("{name}.point")),
                                "a point-mass hammer has no points; omit the key",
                            ));
                        };
                        let points = self
                            .object_index(m)
                            .map(|o| self.object[o].point_names())
                            .unwrap_or_default();
                        if !points.contains(p) {
                            return Err(SceneError::new(
                                f(&format!("{name}.point")),
                                format!(
                                    "the hammer's mallet {m:?} has no point {p:?}: one of {points:?}"
                                ),
                            ));
                        }
                    }
                    continue;
                }
                let Some(o) = self.object_index(&e.object) else {
                    return Err(SceneError::new(
                        f(&format!("{name}.object")),
                        format!("no object named {:?}", e.object),
                    ));
                };
                if self.hammer.object.as_ref() == Some(&e.object) {
                    return Err(SceneError::new(
                        f(&format!("{name}.object")),
                        format!(
                            "{:?} is the modal mallet: its face (hammer.point) is the side \
                             \"hammer\"",
                            e.object
                        ),
                    ));
                }
                let obj = &self.object[o];
                match (obj, &e.point) {
                    (ObjectSpec::Wall(_), None) => walls += 1,
                    (ObjectSpec::Wall(_), Some(_)) => {
                        return Err(SceneError::new(
                            f(&format!("{name}.point")),
                            "a wall has no points; omit the key",
                        ))
                    }
                    (ObjectSpec::String(_) | ObjectSpec::Chain(_), _) => {
                        return Err(SceneError::new(
                            f(&format!("{name}.object")),
                            format!(
                                "{:?} is a lumped {}: several contacts touch objects with modes \
                                 (kind \"modal\" or one from geometry and material) and walls",
                                e.object,
                                obj.kind()
                            ),
                        ))
                    }
                    (_, None) => {
                        return Err(SceneError::new(
                            f(&format!("{name}.point")),
                            format!(
                                "missing: name one of {:?}'s points {:?}",
                                e.object,
                                obj.point_names()
                            ),
                        ))
                    }
                    (_, Some(p)) if !obj.point_names().contains(p) => {
                        return Err(SceneError::new(
                            f(&format!("{name}.point")),
                            format!("object {:?} has no point {p:?}", e.object),
                        ))
                    }
                    _ => {}
                }
            }
            if walls == 2 {
                return Err(SceneError::new(f("upper"), "two walls cannot touch"));
            }
            if t.lower.object == t.upper.object {
                return Err(SceneError::new(
                    f("upper.object"),
                    format!("{:?} in contact with itself", t.lower.object),
                ));
            }
            let (a, b) = (side_key(&t.lower), side_key(&t.upper));
            if pairs
                .iter()
                .any(|(x, y)| (*x == a && *y == b) || (*x == b && *y == a))
            {
                return Err(SceneError::new(
                    f("upper"),
                    "another contact already joins these two sides: two contacts on one point pair",
                ));
            }
            pairs.push((a, b));
            check_non_negative(&f("gap_m"), t.gap_m)?;
            check_max(&f("gap_m"), t.gap_m, MAX_HEIGHT_M)?;
            check_positive(&f("stiffness_n_per_m"), t.stiffness_n_per_m)?;
            check_min(
                &f("stiffness_n_per_m"),
                t.stiffness_n_per_m,
                MIN_STIFFNESS_N_PER_M,
            )?;
            check_max(
                &f("stiffness_n_per_m"),
                t.stiffness_n_per_m,
                MAX_STIFFNESS_N_PER_M,
            )?;
            check_non_negative(&f("damping_n_s_per_m"), t.damping_n_s_per_m)?;
            check_max(
                &f("damping_n_s_per_m"),
                t.damping_n_s_per_m,
                MAX_DAMPING_N_S_PER_M,
            )?;
            // the hammer starts at its height: below an upper side resting
            // `gap` above the struck object's rest, it must not start inside
            let hammer_side = |e: &End| e.object == HAMMER_SIDE;
            if hammer_side(&t.lower) && self.hammer.height_m > t.gap_m {
                return Err(SceneError::new(
                    f("gap_m"),
                    format!(
                        "the hammer starts at {} m, inside {:?} resting {} m up: raise gap_m or \
                         lower hammer.height_m",
                        self.hammer.height_m, t.upper.object, t.gap_m
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Names unique and non-empty, each object's own values.
    fn validate_objects(&self) -> Result<(), SceneError> {
        for (i, obj) in self.object.iter().enumerate() {
            let base = format!("object[{i}]");
            if obj.name().is_empty() {
                return Err(SceneError::new(format!("{base}.name"), "must not be empty"));
            }
            if self.object[..i].iter().any(|o| o.name() == obj.name()) {
                return Err(SceneError::new(
                    format!("{base}.name"),
                    format!("duplicate object name {:?}", obj.name()),
                ));
            }
            match obj {
                ObjectSpec::Modal(m) => validate_modal(&base, m)?,
                ObjectSpec::String(s) => validate_string(&base, s)?,
                ObjectSpec::Wall(_) => {}
                ObjectSpec::Chain(c) => c.validate(&base)?,
                _ => {
                    if let Some(p) = obj.physical() {
                        p.validate(&base)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// The struck object and point exist (a wall has none), and the
    /// spring-damper's values.
    fn validate_contact(&self) -> Result<(), SceneError> {
        let c = &self.contact;
        let Some(obj_idx) = self.object_index(&c.object) else {
            return Err(SceneError::new(
                "contact.object",
                format!("no object named {:?}", c.object),
            ));
        };
        match (&self.object[obj_idx], &c.point) {
            (ObjectSpec::Wall(_), Some(_)) => {
                return Err(SceneError::new(
                    "contact.point",
                    "a wall has no points; omit the key",
                ))
            }
            (ObjectSpec::Wall(_), None) => {}
            (obj, None) => {
                return Err(SceneError::new(
                    "contact.point",
                    format!(
                        "missing: object {:?} is not a wall, name one of its points {:?}",
                        c.object,
                        obj.point_names()
                    ),
                ))
            }
            (obj, Some(p)) => {
                if !obj.point_names().contains(p) {
                    return Err(SceneError::new(
                        "contact.point",
                        format!("object {:?} has no point {:?}", c.object, p),
                    ));
                }
            }
        }
        check_positive("contact.stiffness_n_per_m", c.stiffness_n_per_m)?;
        check_min(
            "contact.stiffness_n_per_m",
            c.stiffness_n_per_m,
            MIN_STIFFNESS_N_PER_M,
        )?;
        check_max(
            "contact.stiffness_n_per_m",
            c.stiffness_n_per_m,
            MAX_STIFFNESS_N_PER_M,
        )?;
        check_non_negative("contact.damping_n_s_per_m", c.damping_n_s_per_m)?;
        check_max(
            "contact.damping_n_s_per_m",
            c.damping_n_s_per_m,
            MAX_DAMPING_N_S_PER_M,
        )?;
        Ok(())
    }

    /// The listeners: unique names, distance and angles in range.
    fn validate_listeners(&self) -> Result<(), SceneError> {
        for (i, l) in self.listener.iter().enumerate() {
            let base = format!("listener[{i}]");
            if l.name.is_empty() || self.listener[..i].iter().any(|o| o.name == l.name) {
                return Err(SceneError::new(
                    format!("{base}.name"),
                    format!("must be a name no other listener has, got {:?}", l.name),
                ));
            }
            let d = format!("{base}.distance_m");
            check_positive(&d, l.distance_m)?;
            check_min(&d, l.distance_m, MIN_LISTENER_DISTANCE_M)?;
            check_max(&d, l.distance_m, MAX_LISTENER_DISTANCE_M)?;
            let p = format!("{base}.polar_deg");
            check_finite(&p, l.polar_deg)?;
            if !(0.0..=90.0).contains(&l.polar_deg) {
                return Err(SceneError::new(
                    p,
                    format!("must be within 0 ..= 90, got {}", l.polar_deg),
                ));
            }
            let a = format!("{base}.azimuth_deg");
            check_finite(&a, l.azimuth_deg)?;
            check_abs_max(&a, l.azimuth_deg, 360.0)?;
        }
        Ok(())
    }

    /// Each pickup's object and point exist; gain and pan.
    fn validate_pickups(&self) -> Result<(), SceneError> {
        for (i, p) in self.pickup.iter().enumerate() {
            let base = format!("pickup[{i}]");
            let Some(oi) = self.object_index(&p.object) else {
                return Err(SceneError::new(
                    format!("{base}.object"),
                    format!("no object named {:?}", p.object),
                ));
            };
            if p.quantity == Quantity::Pressure {
                if self.object[oi].physical().is_none() {
                    return Err(SceneError::new(
                        format!("{base}.quantity"),
                        format!(
                            "pressure needs an object from geometry (bar, tube, plate, membrane, \
                             stiff_string); {:?} is a {}",
                            p.object,
                            self.object[oi].kind()
                        ),
                    ));
                }
                if !self.listener.iter().any(|l| l.name == p.point) {
                    return Err(SceneError::new(
                        format!("{base}.point"),
                        format!(
                            "a pressure pickup names a listener: no [[listener]] {:?}",
                            p.point
                        ),
                    ));
                }
            } else if !self.object[oi].point_names().contains(&p.point) {
                return Err(SceneError::new(
                    format!("{base}.point"),
                    format!("object {:?} has no point {:?}", p.object, p.point),
                ));
            }
            check_finite(&format!("{base}.gain"), p.gain)?;
            check_abs_max(&format!("{base}.gain"), p.gain, MAX_GAIN)?;
            // the gain the engine gets: times the scene's level
            let heard = p.gain * self.level_gain();
            if heard.abs() > MAX_GAIN {
                return Err(SceneError::new(
                    "level_db",
                    format!(
                        "{base}.gain {:e} at level_db {} makes {heard:e}; |gain x level| must be <= {MAX_GAIN:e}",
                        p.gain, self.level_db
                    ),
                ));
            }
            check_finite(&format!("{base}.pan"), p.pan)?;
            if !(-1.0..=1.0).contains(&p.pan) {
                return Err(SceneError::new(
                    format!("{base}.pan"),
                    format!("must be in [-1, 1], got {}", p.pan),
                ));
            }
        }
        Ok(())
    }
}

impl ApproxSpec {
    fn validate(&self) -> Result<(), SceneError> {
        if let Some(f) = self.max_freq_hz {
            check_positive("approximate.max_freq_hz", f)?;
        }
        if let Some(f) = self.nyquist_fraction {
            check_positive("approximate.nyquist_fraction", f)?;
        }
        if let Some(db) = self.quiet_below_db {
            check_finite("approximate.quiet_below_db", db)?;
            if db >= 0.0 {
                return Err(SceneError::new(
                    "approximate.quiet_below_db",
                    format!("must be < 0 dB, got {db}"),
                ));
            }
        }
        Ok(())
    }
}

impl PlaySpec {
    fn validate(&self) -> Result<(), SceneError> {
        if let Some(d) = self.damper {
            check_finite("play.damper", d)?;
            if !(0.0..=1.0).contains(&d) {
                return Err(SceneError::new(
                    "play.damper",
                    format!("must be within 0 ..= 1, got {d}"),
                ));
            }
        }
        if let Some(f) = self.pitch_hz {
            check_positive("play.pitch_hz", f)?;
            // MIDI notes 0 ..= 127 (8.2 Hz ..= 12.5 kHz)
            check_min("play.pitch_hz", f, 8.0)?;
            check_max("play.pitch_hz", f, 13_000.0)?;
        }
        Ok(())
    }
}

impl HammerSpec {
    fn validate(&self) -> Result<(), SceneError> {
        let h = self;
        check_positive("hammer.mass_kg", h.mass_kg)?;
        check_min("hammer.mass_kg", h.mass_kg, MIN_MASS_KG)?;
        check_max("hammer.mass_kg", h.mass_kg, MAX_MASS_KG)?;
        check_non_negative("hammer.height_m", h.height_m)?;
        check_max("hammer.height_m", h.height_m, MAX_HEIGHT_M)?;
        check_finite("hammer.velocity_m_per_s", h.velocity_m_per_s)?;
        check_abs_max(
            "hammer.velocity_m_per_s",
            h.velocity_m_per_s,
            MAX_SPEED_M_PER_S,
        )?;
        check_non_negative("hammer.gravity_m_per_s2", h.gravity_m_per_s2)?;
        check_max(
            "hammer.gravity_m_per_s2",
            h.gravity_m_per_s2,
            MAX_GRAVITY_M_PER_S2,
        )?;

        Ok(())
    }
}

fn validate_modal(base: &str, m: &ModalSpec) -> Result<(), SceneError> {
    if m.mode.is_empty() {
        return Err(SceneError::new(
            format!("{base}.mode"),
            "a modal object needs at least one mode",
        ));
    }
    if m.mode.len() > MAX_MODES_PER_OBJECT {
        return Err(SceneError::new(
            format!("{base}.mode"),
            format!(
                "{} modes is more than the limit of {MAX_MODES_PER_OBJECT}",
                m.mode.len()
            ),
        ));
    }
    for (j, p) in m.points.iter().enumerate() {
        if p.is_empty() {
            return Err(SceneError::new(
                format!("{base}.points[{j}]"),
                "must not be empty",
            ));
        }
        if m.points[..j].contains(p) {
            return Err(SceneError::new(
                format!("{base}.points[{j}]"),
                format!("duplicate point name {p:?}"),
            ));
        }
    }
    for (k, mode) in m.mode.iter().enumerate() {
        let mb = format!("{base}.mode[{k}]");
        check_positive(&format!("{mb}.freq_hz"), mode.freq_hz)?;
        if mode.freq_hz > MAX_FREQ_HZ {
            return Err(SceneError::new(
                format!("{mb}.freq_hz"),
                format!("must be <= {MAX_FREQ_HZ}, got {}", mode.freq_hz),
            ));
        }
        check_min(&format!("{mb}.freq_hz"), mode.freq_hz, MIN_FREQ_HZ)?;
        if let Some(t60) = mode.t60_s {
            check_positive(&format!("{mb}.t60_s"), t60)?;
            check_min(&format!("{mb}.t60_s"), t60, MIN_T60_S)?;
        }
        if mode.weights.len() != m.points.len() {
            return Err(SceneError::new(
                format!("{mb}.weights"),
                format!(
                    "needs one weight per point ({}), got {}",
                    m.points.len(),
                    mode.weights.len()
                ),
            ));
        }
        for (j, w) in mode.weights.iter().enumerate() {
            check_finite(&format!("{mb}.weights[{j}]"), *w)?;
            if w.abs() > MAX_WEIGHT {
                return Err(SceneError::new(
                    format!("{mb}.weights[{j}]"),
                    format!(
                        "|w| must be <= {MAX_WEIGHT:e} 1/sqrt(kg) (an effective mass >= {MIN_MASS_KG:e} kg), got {w}"
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn validate_string(base: &str, s: &StringSpec) -> Result<(), SceneError> {
    if s.masses == 0 || s.masses > MAX_STRING_MASSES {
        return Err(SceneError::new(
            format!("{base}.masses"),
            format!("must be in 1..={MAX_STRING_MASSES}, got {}", s.masses),
        ));
    }
    check_positive(&format!("{base}.mass_kg"), s.mass_kg)?;
    check_min(&format!("{base}.mass_kg"), s.mass_kg, MIN_MASS_KG)?;
    check_max(&format!("{base}.mass_kg"), s.mass_kg, MAX_MASS_KG)?;
    check_positive(&format!("{base}.spring_n_per_m"), s.spring_n_per_m)?;
    check_max(
        &format!("{base}.spring_n_per_m"),
        s.spring_n_per_m,
        MAX_STIFFNESS_N_PER_M,
    )?;
    // The chain's modes must lie in the same frequency range as a modal
    // object's modes.
    let f_lo = s.mode_freq_hz(1);
    let f_hi = s.mode_freq_hz(s.masses);
    if f_hi > MAX_FREQ_HZ {
        return Err(SceneError::new(
            format!("{base}.spring_n_per_m"),
            format!(
                "with mass_kg = {:e} the highest mode is at {f_hi:.3e} Hz, above {MAX_FREQ_HZ:e} Hz (spring too stiff or masses too light)",
                s.mass_kg
            ),
        ));
    }
    if f_lo < MIN_FREQ_HZ {
        return Err(SceneError::new(
            format!("{base}.spring_n_per_m"),
            format!(
                "with mass_kg = {:e} the lowest mode is at {f_lo:.3e} Hz, below {MIN_FREQ_HZ:e} Hz (spring too soft or masses too heavy)",
                s.mass_kg
            ),
        ));
    }
    check_non_negative(
        &format!("{base}.rayleigh_alpha_per_s"),
        s.rayleigh_alpha_per_s,
    )?;
    check_max(
        &format!("{base}.rayleigh_alpha_per_s"),
        s.rayleigh_alpha_per_s,
        MAX_RAYLEIGH_ALPHA_PER_S,
    )?;
    check_non_negative(&format!("{base}.rayleigh_beta_s"), s.rayleigh_beta_s)?;
    check_max(
        &format!("{base}.rayleigh_beta_s"),
        s.rayleigh_beta_s,
        MAX_RAYLEIGH_BETA_S,
    )?;
    for (j, d) in s.dashpots.iter().enumerate() {
        if d.mass >= s.masses {
            return Err(SceneError::new(
                format!("{base}.dashpots[{j}].mass"),
                format!("must be < masses ({}), got {}", s.masses, d.mass),
            ));
        }
        check_non_negative(&format!("{base}.dashpots[{j}].n_s_per_m"), d.n_s_per_m)?;
        check_max(
            &format!("{base}.dashpots[{j}].n_s_per_m"),
            d.n_s_per_m,
            MAX_DAMPING_N_S_PER_M,
        )?;
    }
    for (name, &idx) in &s.points {
        if idx >= s.masses {
            return Err(SceneError::new(
                format!("{base}.points.{name}"),
                format!("must be < masses ({}), got {idx}", s.masses),
            ));
        }
    }
    Ok(())
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
