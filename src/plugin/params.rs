//! The plugin's parameters, declared once.
//!
//! The `parameters!` invocation below is the single list of parameters: each
//! entry gives the stable id, the name hosts show, the kind with its range,
//! default and unit, when a change takes effect, and what the parameter does.
//! From it the macro makes
//! - [`PARAMS`], the metadata as data: `cargo xtask param-docs` writes the
//!   parameter table of docs/plugin.md from it, [`migrate_state`] checks
//!   saved states against it, and the tests iterate over it;
//! - [`ids`], the id constants the host tests address parameters by;
//! - [`ModalContactParams`], the typed nice-plug parameters, each built from
//!   its entry (so the audio thread reads fields with atomic loads, no
//!   look-up), and its `Params` implementation. nice-plug's
//!   `#[derive(Params)]` wants every id again as an attribute literal, a
//!   second copy of the list; the implementation here does what the derive
//!   generates (one `(id, pointer, "")` per field, in declaration order, no
//!   persisted fields) with the ids taken from the list.
//!
//! Enumerated parameters are [`Choice`]s of a [`ChoiceList`] whose ids and
//! names are the list's own (the scene's come from [`crate::presets::PRESETS`]),
//! so no Rust enum repeats them. Hosts show their names, and nice-plug saves
//! them by id: a project saved with any earlier version finds the same preset.
//!
//! Never change an id (saved projects and automation refer to them; the test
//! `ids_never_change` holds them), and only append choices at the end (CLAP
//! automation stores a choice's index).

pub use super::poly::{VariantsWanted, POLY_DAMPER, POLY_HARDNESS, POLY_POSITION};
use super::user_scene::{lock, SceneLibrary, UserScene};
use crate::instrument::{
    InstrumentParams, PlayParams, SceneParams, DEFAULT_BEND_RANGE_SEMITONES,
    MAX_BEND_RANGE_SEMITONES, MAX_LOOKAHEAD_S, MAX_VOICES,
};
use crate::presets;
use crate::scene::{Switching, DEFAULT_RELEASE_DAMPER};
use crossbeam::atomic::AtomicCell;
use nice_plug::plugin::{ParamValue, PluginState};
use nice_plug::prelude::*;
use std::collections::BTreeMap;
use std::marker::PhantomData;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// One parameter's metadata: an entry of [`PARAMS`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Stable id (what saved projects and automation refer to).
    pub id: &'static str,
    /// Name hosts show.
    pub name: &'static str,
    /// Value type, range, default and unit.
    pub kind: Kind,
    /// When a change is heard.
    pub applies: Applies,
    /// What the parameter does (Markdown, for docs/plugin.md).
    pub doc: &'static str,
}

/// A parameter's value type, with its range, default and display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A continuous value.
    Float {
        /// Smallest value.
        min: f32,
        /// Largest value.
        max: f32,
        /// Default value.
        default: f32,
        /// How the host's knob maps onto the range.
        taper: Taper,
        /// Unit appended to the value, with its leading space (`" dB"`), or `""`.
        unit: &'static str,
        /// Decimal places hosts show.
        digits: usize,
    },
    /// A whole number (hosts show and step it as one).
    Int {
        /// Smallest value.
        min: i32,
        /// Largest value.
        max: i32,
        /// Default value.
        default: i32,
        /// Unit appended to the value, with its leading space, or `""`.
        unit: &'static str,
    },
    /// Off or on.
    Bool {
        /// Default value.
        default: bool,
    },
    /// One of a list of named choices.
    Choice {
        /// Stable ids, saved in projects.
        ids: &'static [&'static str],
        /// Names hosts show, in the order of `ids`.
        names: &'static [&'static str],
        /// Index of the default choice.
        default: usize,
    },
}

/// How a float parameter's normalised (knob) position maps to its value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Taper {
    /// Evenly spread.
    Linear,
    /// nice-plug's `FloatRange::Skewed` with `factor = skew_factor(exponent)`:
    /// a negative exponent gives the low end more of the knob.
    Skewed {
        /// Power-of-two exponent of the skew factor.
        exponent: f32,
    },
}

/// When a parameter change is heard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applies {
    /// It changes the matrices: the worker recompiles the scene off the
    /// audio thread and the result is swapped in (docs/plugin.md,
    /// "Parameter changes: the swap design"). Part of [`SceneParams`].
    Recompile,
    /// Read when a note starts. Part of [`PlayParams`].
    NextNote,
    /// Read at every block. Part of [`PlayParams`].
    NextBlock,
}

impl ParamSpec {
    /// The default as nice-plug stores it in a saved state.
    pub fn default_value(&self) -> ParamValue {
        match self.kind {
            Kind::Float { default, .. } => ParamValue::F32(default),
            Kind::Int { default, .. } => ParamValue::I32(default),
            Kind::Bool { default } => ParamValue::Bool(default),
            Kind::Choice { ids, default, .. } => ParamValue::String(ids[default].to_string()),
        }
    }
}

/// The metadata of the parameter `id`.
pub fn spec(id: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|s| s.id == id)
}

/// A list of named choices for an enumerated parameter.
pub trait ChoiceList: 'static {
    /// Stable ids, saved in projects (never change one).
    const IDS: &'static [&'static str];
    /// Names hosts show, in the order of `IDS`.
    const NAMES: &'static [&'static str];
}

/// One choice of the list `L`. nice-plug's [`Enum`] is implemented from the
/// list's ids and names, so an enumerated parameter needs no Rust enum that
/// would repeat them.
pub struct Choice<L> {
    index: usize,
    list: PhantomData<L>,
}

// Written out: derives would demand the same traits of the marker type `L`.
impl<L> Clone for Choice<L> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<L> Copy for Choice<L> {}
impl<L> PartialEq for Choice<L> {
    fn eq(&self, other: &Self) -> bool {
        self.index == other.index
    }
}
impl<L> Eq for Choice<L> {}
impl<L: ChoiceList> std::fmt::Debug for Choice<L> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Choice({:?})", self.id())
    }
}

impl<L: ChoiceList> Choice<L> {
    /// Position in the list.
    pub fn index(self) -> usize {
        self.index
    }
    /// Stable id.
    pub fn id(self) -> &'static str {
        L::IDS[self.index]
    }
}

impl<L: ChoiceList> Enum for Choice<L> {
    fn variants() -> &'static [&'static str] {
        L::NAMES
    }
    fn ids() -> Option<&'static [&'static str]> {
        Some(L::IDS)
    }
    fn to_index(self) -> usize {
        self.index
    }
    /// Out of range gives the first choice, as the trait asks.
    fn from_index(index: usize) -> Self {
        Self {
            index: if index < L::IDS.len() { index } else { 0 },
            list: PhantomData,
        }
    }
}

/// The embedded presets ([`crate::presets::PRESETS`], in its order).
pub struct Scenes;
impl ChoiceList for Scenes {
    const IDS: &'static [&'static str] = &presets::NAMES;
    const NAMES: &'static [&'static str] = &presets::TITLES;
}

/// The switching methods; the ids are the scene files' spellings.
pub struct SwitchingMethods;
impl ChoiceList for SwitchingMethods {
    const IDS: &'static [&'static str] = &["offset-rod", "exact"];
    const NAMES: &'static [&'static str] = &["Offset rod", "Exact"];
}
/// The method of each [`SwitchingMethods`] choice.
const SWITCHING_METHOD: [Switching; 2] = [Switching::OffsetRod, Switching::Exact];

/// The "Scene" parameter's value.
pub type PresetChoice = Choice<Scenes>;
/// The "Switching" parameter's value.
pub type SwitchingChoice = Choice<SwitchingMethods>;

/// A multiplier of a scene quantity, skewed so that 1 x sits near the middle
/// of the knob.
const fn factor(min: f32, max: f32, digits: usize) -> Kind {
    Kind::Float {
        min,
        max,
        default: 1.0,
        taper: Taper::Skewed { exponent: -2.0 },
        unit: " x",
        digits,
    }
}

/// A linear float parameter.
const fn linear(min: f32, max: f32, default: f32, unit: &'static str, digits: usize) -> Kind {
    Kind::Float {
        min,
        max,
        default,
        taper: Taper::Linear,
        unit,
        digits,
    }
}

/// The choices of `L`, defaulting to the one with id `default` (a missing id
/// stops the build: this runs at compile time).
const fn choice<L: ChoiceList>(default: &str) -> Kind {
    let mut i = 0;
    while i < L::IDS.len() {
        if str_eq(L::IDS[i], default) {
            return Kind::Choice {
                ids: L::IDS,
                names: L::NAMES,
                default: i,
            };
        }
        i += 1;
    }
    panic!("the default is not one of the choices");
}

const fn str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Builds a nice-plug parameter from its entry of [`PARAMS`].
trait FromSpec {
    fn from_spec(s: &ParamSpec) -> Self;
}

impl FromSpec for FloatParam {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Float {
            min,
            max,
            default,
            taper,
            unit,
            digits,
        } = s.kind
        else {
            panic!(
                "{}: declared {:?}, but its field is a FloatParam",
                s.id, s.kind
            );
        };
        let range = match taper {
            Taper::Linear => FloatRange::Linear { min, max },
            Taper::Skewed { exponent } => FloatRange::Skewed {
                min,
                max,
                factor: FloatRange::skew_factor(exponent),
            },
        };
        let p = FloatParam::new(s.name, default, range)
            .with_unit(unit)
            .with_value_to_string(formatters::v2s_f32_rounded(digits));
        match poly_modulation_id(s.id) {
            Some(id) => p.with_poly_modulation_id(id),
            None => p,
        }
    }
}

/// The parameters a CLAP host may modulate per voice, with their
/// polyphonic modulation ids.
pub const POLY_MODULATED: &[(&str, u32)] = &[
    (ids::HARDNESS, POLY_HARDNESS),
    (ids::STRIKE_POS, POLY_POSITION),
    (ids::DAMPER, POLY_DAMPER),
];

/// The polyphonic modulation id of parameter `id`, if it has one.
pub fn poly_modulation_id(id: &str) -> Option<u32> {
    POLY_MODULATED
        .iter()
        .find(|(p, _)| *p == id)
        .map(|&(_, poly)| poly)
}

impl FromSpec for IntParam {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Int {
            min,
            max,
            default,
            unit,
        } = s.kind
        else {
            panic!(
                "{}: declared {:?}, but its field is an IntParam",
                s.id, s.kind
            );
        };
        IntParam::new(s.name, default, IntRange::Linear { min, max }).with_unit(unit)
    }
}

impl FromSpec for BoolParam {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Bool { default } = s.kind else {
            panic!(
                "{}: declared {:?}, but its field is a BoolParam",
                s.id, s.kind
            );
        };
        BoolParam::new(s.name, default)
    }
}

impl<L: ChoiceList> FromSpec for EnumParam<Choice<L>> {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Choice { ids, default, .. } = s.kind else {
            panic!(
                "{}: declared {:?}, but its field is an EnumParam",
                s.id, s.kind
            );
        };
        assert!(
            ids == L::IDS,
            "{}: the entry's choices are not its field's",
            s.id
        );
        EnumParam::new(s.name, Choice::from_index(default))
    }
}

/// Declares the parameters: see the module documentation for what it makes.
macro_rules! parameters {
    ($(
        $field:ident: $ty:ty = $ID:ident {
            id: $id:literal,
            name: $name:literal,
            kind: $kind:expr,
            applies: $applies:expr,
            doc: $doc:expr $(,)?
        }
    ),* $(,)?) => {
        /// Parameter ids (stable: saved projects and automation refer to them).
        pub mod ids {
            $(
                #[doc = $doc]
                pub const $ID: &str = $id;
            )*
            /// Every id, in the order of [`super::PARAMS`].
            pub const ALL: [&str; [$($id),*].len()] = [$($ID),*];
        }

        /// Every parameter, in the order hosts list them.
        pub const PARAMS: &[ParamSpec] = &[$(
            ParamSpec {
                id: ids::$ID,
                name: $name,
                kind: $kind,
                applies: $applies,
                doc: $doc,
            }
        ),*];

        /// The plugin's parameters: every entry of [`PARAMS`], automatable and
        /// saved with the host's project by nice-plug.
        pub struct ModalContactParams {
            $(
                #[doc = $doc]
                pub $field: $ty,
            )*
            /// What is saved besides the parameters (the user's scene, the
            /// editor's size and scene folder).
            pub persisted: Persisted,
            /// The per-voice variants a host's polyphonic modulation asked
            /// for (set by the audio thread, read with the parameters).
            pub variants_wanted: VariantsWanted,
        }

        impl Default for ModalContactParams {
            fn default() -> Self {
                Self {
                    $($field: FromSpec::from_spec(
                        spec(ids::$ID).expect("declared above"),
                    ),)*
                    persisted: Persisted::default(),
                    variants_wanted: VariantsWanted::default(),
                }
            }
        }

        // SAFETY: as for nice-plug's derive: the pointers point into `self`'s
        // fields, and nice-plug only dereferences them while it holds the
        // `Arc` the plugin hands out in `Plugin::params`.
        unsafe impl Params for ModalContactParams {
            fn param_map(&self) -> Vec<(String, ParamPtr, String)> {
                vec![$(
                    (String::from(ids::$ID), self.$field.as_ptr(), String::new()),
                )*]
            }

            fn serialize_fields(&self) -> BTreeMap<String, String> {
                self.persisted.serialize()
            }

            fn deserialize_fields(&self, serialized: &BTreeMap<String, String>) {
                for note in self.persisted.deserialize(serialized) {
                    nice_log!("modal_contact: state: {note}");
                }
            }
        }
    };
}

parameters! {
    scene: EnumParam<PresetChoice> = SCENE {
        id: "scene",
        name: "Scene",
        kind: choice::<Scenes>("marimba-bar"),
        applies: Applies::Recompile,
        doc: "Which scene of `presets/` is struck (the scenes are listed below).",
    },
    hammer_mass: FloatParam = HAMMER_MASS {
        id: "hammer_mass",
        name: "Hammer mass",
        kind: factor(0.1, 10.0, 3),
        applies: Applies::Recompile,
        doc: "Multiplies the scene's hammer mass. Heavier: longer contact, darker, louder.",
    },
    hardness: FloatParam = HARDNESS {
        id: "hardness",
        name: "Hardness",
        kind: factor(0.01, 100.0, 3),
        applies: Applies::Recompile,
        doc: "Multiplies the contact stiffness. Harder: shorter contact, brighter. \
              Per voice in CLAP hosts (polyphonic modulation, in levels).",
    },
    contact_damping: FloatParam = CONTACT_DAMPING {
        id: "contact_damping",
        name: "Contact damping",
        kind: factor(0.0, 10.0, 3),
        applies: Applies::Recompile,
        doc: "Multiplies the contact damping (a lossy felt vs a hard mallet).",
    },
    strike_custom: BoolParam = STRIKE_CUSTOM {
        id: "strike_custom",
        name: "Custom strike position",
        kind: Kind::Bool { default: false },
        applies: Applies::Recompile,
        doc: "Off: strike where the scene says. On: use Strike position.",
    },
    strike_pos: FloatParam = STRIKE_POS {
        id: "strike_pos",
        name: "Strike position",
        kind: linear(0.0, 1.0, 0.5, "", 3),
        applies: Applies::Recompile,
        doc: "Where along the object the hammer hits, 0 .. 1 (see below; \
              the scenes table says which scenes it moves). Per voice in CLAP \
              hosts (polyphonic modulation, in levels).",
    },
    decay: FloatParam = DECAY {
        id: "decay",
        name: "Decay",
        kind: factor(0.1, 10.0, 3),
        applies: Applies::Recompile,
        doc: "Multiplies every decay time (modal T60s; a string's Rayleigh damping \
              and dashpots are divided by it).",
    },
    damper: FloatParam = DAMPER {
        id: "damper",
        name: "Damper",
        kind: linear(0.0, 1.0, 0.5, "", 3),
        applies: Applies::Recompile,
        doc: "How strongly a released note is damped, with Custom damper on: decay \
              times after note-off are divided by `1 + 50 * damper`. 0 = the object \
              rings on after release. Per voice in CLAP hosts (polyphonic modulation, \
              in levels, around the damper that plays).",
    },
    pitch_tracking: BoolParam = PITCH_TRACKING {
        id: "pitch_tracking",
        name: "Pitch tracking",
        kind: Kind::Bool { default: true },
        applies: Applies::NextNote,
        doc: "On: the note sets the pitch. Off: every note plays the scene as written.",
    },
    gravity: FloatParam = GRAVITY {
        id: "gravity",
        name: "Gravity",
        kind: linear(0.5, 30.0, 9.81, " m/s2", 2),
        applies: Applies::Recompile,
        doc: "Gravity on the hammer, for bouncing scenes only (scenes whose hammer \
              has gravity; the scenes table says which).",
    },
    drop_height_mm: FloatParam = DROP_HEIGHT {
        id: "drop_height",
        name: "Drop height",
        kind: Kind::Float {
            min: 1.0,
            max: 100.0,
            default: 20.0,
            taper: Taper::Skewed { exponent: -1.0 },
            unit: " mm",
            digits: 1,
        },
        applies: Applies::NextNote,
        doc: "Height the hammer is dropped from in bouncing scenes.",
    },
    gain_db: FloatParam = GAIN {
        id: "gain",
        name: "Output gain",
        kind: linear(-60.0, 12.0, -6.0, " dB", 1),
        applies: Applies::NextBlock,
        doc: "Output level, after the scene's own level (`level_db`, a gain on \
              its pickups): the presets' levels put a strike at velocity 100 at \
              one loudness, low enough that a 16-note chord stays below full \
              scale at this gain's default (docs/levels.md).",
    },
    switching: EnumParam<SwitchingChoice> = SWITCHING {
        id: "switching",
        name: "Switching",
        kind: choice::<SwitchingMethods>("exact"),
        applies: Applies::Recompile,
        doc: "Contact switching method: Exact finds every contact start and end \
              inside the sample, in order, on the exact solution (located to \
              3.6e-15 of a sample; no switching error beyond f64 rounding, \
              docs/numerics.md, \"Exact switching\"); Offset rod is the paper's method (first \
              order, contacts start up to a sample late). A kit takes it too: each of its \
              contacts with a rod of its own. If a scene's compile \
              refuses exact switching (a dense-fallback phase larger than 16 states \
              or too stiff for partial dense steps), it is compiled with the offset \
              rod and the worker logs `exact switching refused (...); falling back \
              to offset-rod`.",
    },
    polyphony: IntParam = POLYPHONY {
        id: "polyphony",
        name: "Polyphony",
        kind: Kind::Int {
            min: 1,
            max: MAX_VOICES as i32,
            default: 16,
            unit: " voices",
        },
        applies: Applies::NextNote,
        doc: "How many notes sound at once. A note beyond it steals the quietest \
              voice; lowering it below the voices that sound ends the quietest of \
              them, each fading out in 5 ms as a stolen voice does. The voices \
              are allocated once: changing it allocates nothing.",
    },
    bend_range: FloatParam = BEND_RANGE {
        id: "bend_range",
        name: "Bend range",
        kind: linear(0.0, MAX_BEND_RANGE_SEMITONES as f32, DEFAULT_BEND_RANGE_SEMITONES as f32, " st", 1),
        applies: Applies::NextBlock,
        doc: "Pitch bend at full wheel, in semitones. A bend glides at most 100 \
              semitones per second and keeps each voice's energy: the object's \
              displacement scales by the inverse of the pitch ratio \
              (docs/plugin.md, \"Pitch bend\"). Bouncing scenes are not bent.",
    },
    lookahead: IntParam = LOOKAHEAD {
        id: "lookahead",
        name: "Lookahead",
        kind: Kind::Int {
            min: 0,
            max: (MAX_LOOKAHEAD_S * 1000.0) as i32,
            default: 0,
            unit: " ms",
        },
        applies: Applies::NextBlock,
        doc: "Latency the plugin reports so that a chord's strikes need not all be \
              computed in the block that holds them: the voices may run up to this \
              far behind and work through the strikes in the blocks after it, a \
              share of each (docs/plugin.md, \"Lookahead\"). The sound is the same, \
              this much later (hosts compensate it on playback). 0: no latency, every \
              strike computed in its own block. At most 4096 samples (21 ms at \
              192 kHz). A change restarts the output (the host restarts its audio \
              for the new latency).",
    },
    damper_custom: BoolParam = DAMPER_CUSTOM {
        id: "damper_custom",
        name: "Custom damper",
        kind: Kind::Bool { default: false },
        applies: Applies::Recompile,
        doc: "Off: a released note is damped as the scene says (its `[play] damper`; \
              the scenes table gives each preset's, 0.5 for a scene that does not say). \
              On: use Damper. A project saved before this parameter existed loads \
              with it on, so it keeps the Damper it was saved with.",
    },
}

impl ModalContactParams {
    /// Snapshot of the parameters that need a compile (atomic loads only).
    /// \[any-thread\]
    pub fn scene_params(&self) -> SceneParams {
        SceneParams {
            preset: self.scene.value().index(),
            hammer_mass_factor: self.hammer_mass.value() as f64,
            stiffness_factor: self.hardness.value() as f64,
            damping_factor: self.contact_damping.value() as f64,
            strike_pos_norm: self
                .strike_custom
                .value()
                .then(|| self.strike_pos.value() as f64),
            decay_scale: self.decay.value() as f64,
            // the knob only counts when it is used: moving it with Custom
            // damper off asks for no compile
            damper_norm: if self.damper_custom.value() {
                self.damper.value() as f64
            } else {
                DEFAULT_RELEASE_DAMPER
            },
            damper_custom: self.damper_custom.value(),
            gravity_m_per_s2: self.gravity.value() as f64,
            switching: SWITCHING_METHOD[self.switching.value().index()],
            user_scene: self.persisted.library.active(),
            variants: self.variants_wanted.get(),
        }
    }

    /// Snapshot of the parameters read without a compile. \[any-thread\]
    pub fn play_params(&self) -> PlayParams {
        PlayParams {
            pitch_tracking: self.pitch_tracking.value(),
            drop_height_m: self.drop_height_mm.value() as f64 / 1000.0,
            gain_db: self.gain_db.value() as f64,
            polyphony: self.polyphony.value().clamp(1, MAX_VOICES as i32) as usize,
            bend_range_semitones: self.bend_range.value() as f64,
            lookahead_s: self.lookahead.value() as f64 / 1000.0,
        }
    }

    /// Both snapshots. \[any-thread\]
    pub fn instrument_params(&self) -> InstrumentParams {
        InstrumentParams {
            scene: self.scene_params(),
            play: self.play_params(),
        }
    }
}

/// Default editor window size \[logical pixels\].
pub const EDITOR_SIZE: (u32, u32) = (1000, 700);
/// Saved-state keys of [`Persisted`] (never change them).
pub mod keys {
    /// The user's scene (JSON of [`super::UserScene`]; absent: the preset).
    pub const USER_SCENE: &str = "user_scene";
    /// The editor's size, `[width, height]` in logical pixels.
    pub const EDITOR_SIZE: &str = "editor_size";
    /// The scene browser's folder (absent: the default folder).
    pub const SCENE_FOLDER: &str = "scene_folder";
}

/// What the plugin saves with a project besides the parameters. The
/// audio thread reads only the library's atomic generation.
pub struct Persisted {
    /// The user's scene and the compile reports.
    pub library: Arc<SceneLibrary>,
    /// The editor's size \[logical pixels\].
    pub editor_size: AtomicCell<(u32, u32)>,
    /// The scene browser's folder (`None`: the default).
    pub scene_folder: Mutex<Option<PathBuf>>,
}

impl Default for Persisted {
    fn default() -> Self {
        Self {
            library: Arc::new(SceneLibrary::default()),
            editor_size: AtomicCell::new(EDITOR_SIZE),
            scene_folder: Mutex::new(None),
        }
    }
}

impl Persisted {
    /// The fields as a saved state stores them. \[main-thread\]
    pub fn serialize(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        if let Some(s) = self.library.to_saved() {
            if let Ok(j) = serde_json::to_string(&s) {
                m.insert(keys::USER_SCENE.into(), j);
            }
        }
        // only what differs from the defaults: a project that never opened
        // the editor saves exactly what it saved before the editor existed
        let (w, h) = self.editor_size.load();
        if (w, h) != EDITOR_SIZE {
            m.insert(keys::EDITOR_SIZE.into(), format!("[{w},{h}]"));
        }
        if let Some(f) = lock(&self.scene_folder).as_ref() {
            if let Ok(j) = serde_json::to_string(f) {
                m.insert(keys::SCENE_FOLDER.into(), j);
            }
        }
        m
    }

    /// Restore from a saved state: a missing field (an older project) gets
    /// its default, an unreadable one too, with a note for the log (a user
    /// scene that no longer validates is reported by its compile, and its
    /// text kept). \[main-thread\]
    pub fn deserialize(&self, m: &BTreeMap<String, String>) -> Vec<String> {
        let mut notes = Vec::new();
        let scene = m.get(keys::USER_SCENE).and_then(|j| {
            serde_json::from_str::<UserScene>(j)
                .map_err(|e| {
                    notes.push(format!(
                        "the saved user scene is unreadable ({e}); playing the preset"
                    ))
                })
                .ok()
        });
        self.library.restore(scene);
        let size = m.get(keys::EDITOR_SIZE).and_then(|j| {
            serde_json::from_str::<(u32, u32)>(j)
                .ok()
                .filter(|&(w, h)| (200..=8192).contains(&w) && (150..=8192).contains(&h))
                .or_else(|| {
                    notes.push(format!("editor size {j:?} ignored"));
                    None
                })
        });
        self.editor_size.store(size.unwrap_or(EDITOR_SIZE));
        let folder = m
            .get(keys::SCENE_FOLDER)
            .and_then(|j| serde_json::from_str::<PathBuf>(j).ok());
        *lock(&self.scene_folder) = folder;
        notes
    }
}

/// Make a state safe to load, before nice-plug applies it
/// ([`Plugin::filter_state`]): every parameter of [`PARAMS`] that the state
/// lacks (a project saved by an older version) gets its default, and every
/// value that is of the wrong type, not finite, outside its range, or an
/// unknown choice id (a preset this version does not have) is replaced by
/// the default too (without this, a missing or refused value would silently
/// keep whatever the instance had before the load). One exception: a state
/// that stores Damper but not Custom damper (saved before Custom damper
/// existed) gets Custom damper on, so its Damper keeps applying. Entries for
/// ids this version does not know are left alone (nice-plug skips them).
/// Returns one note per replaced value, for the log. \[main-thread\]
pub fn migrate_state(state: &mut PluginState) -> Vec<String> {
    let mut notes = Vec::new();
    // A state that stores the Damper but not Custom damper was saved when
    // the Damper always applied: it keeps applying (the project sounds as
    // it did), where a new instance plays the scene's own damper.
    if state.params.contains_key(ids::DAMPER) && !state.params.contains_key(ids::DAMPER_CUSTOM) {
        notes.push(format!(
            "{}: missing in a state that stores {}, using on (the saved Damper applies, as \
             when it was saved)",
            ids::DAMPER_CUSTOM,
            ids::DAMPER
        ));
        state
            .params
            .insert(ids::DAMPER_CUSTOM.to_string(), ParamValue::Bool(true));
    }
    for spec in PARAMS {
        let stored = state.params.get(spec.id);
        let ok = match (spec.kind, stored) {
            (Kind::Float { .. }, Some(ParamValue::F32(v))) => {
                float_in_range(&FloatParam::from_spec(spec), *v)
            }
            (Kind::Int { min, max, .. }, Some(ParamValue::I32(v))) => (min..=max).contains(v),
            (Kind::Bool { .. }, Some(ParamValue::Bool(_))) => true,
            (Kind::Choice { ids, .. }, Some(ParamValue::String(s))) => ids.contains(&s.as_str()),
            // nice-plug stores an index for enums without ids; accept one
            // that names a choice.
            (Kind::Choice { ids, .. }, Some(ParamValue::I32(i))) => {
                usize::try_from(*i).is_ok_and(|i| i < ids.len())
            }
            _ => false,
        };
        if !ok {
            let what = match stored {
                None => "missing".to_string(),
                Some(v) => format!("invalid value {v:?}"),
            };
            let default = spec.default_value();
            notes.push(format!(
                "{}: {what}, using the default {default:?}",
                spec.id
            ));
            state.params.insert(spec.id.to_string(), default);
        }
    }
    notes
}

/// Finite and inside the parameter's range (a round trip through the
/// normalised value changes nothing but rounding).
fn float_in_range(p: &FloatParam, v: f32) -> bool {
    if !v.is_finite() {
        return false;
    }
    let back = p.preview_plain(p.preview_normalized(v));
    (back - v).abs() <= 1e-4 * v.abs().max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// `ParamValue` has no `PartialEq`: compare the debug forms.
    macro_rules! same {
        ($a:expr, $b:expr $(, $m:expr)?) => {
            assert_eq!(format!("{:?}", $a), format!("{:?}", $b) $(, $m)?)
        };
    }

    fn full_state() -> PluginState {
        let mut state = PluginState {
            version: "0.0.1".into(),
            params: BTreeMap::new(),
            fields: BTreeMap::new(),
        };
        assert_eq!(
            migrate_state(&mut state).len(),
            PARAMS.len(),
            "all filled in"
        );
        state
    }

    /// The parameter `id` as nice-plug's wrappers see it.
    fn ptr(p: &ModalContactParams, id: &str) -> ParamPtr {
        p.param_map()
            .into_iter()
            .find(|(i, _, _)| i == id)
            .unwrap_or_else(|| panic!("{id} not in the param map"))
            .1
    }

    #[test]
    fn ids_never_change() {
        // The ids of the first release, in its order: saved projects and
        // automation refer to them.
        let shipped = [
            "scene",
            "hammer_mass",
            "hardness",
            "contact_damping",
            "strike_custom",
            "strike_pos",
            "decay",
            "damper",
            "pitch_tracking",
            "gravity",
            "drop_height",
            "gain",
            "switching",
        ];
        // later ids are appended, never inserted or renamed
        let added = ["polyphony", "bend_range", "lookahead", "damper_custom"];
        let all: Vec<&str> = shipped.iter().chain(&added).copied().collect();
        assert_eq!(ids::ALL.as_slice(), all.as_slice());
        let listed: Vec<&str> = PARAMS.iter().map(|s| s.id).collect();
        assert_eq!(listed, all);
        let p = ModalContactParams::default();
        let mapped: Vec<String> = p
            .param_map()
            .into_iter()
            .map(|(id, _, g)| id + &g)
            .collect();
        assert_eq!(
            mapped, all,
            "the param map is the list, in order, ungrouped"
        );
    }

    #[test]
    fn every_parameter_is_built_from_its_entry() {
        let p = ModalContactParams::default();
        for s in PARAMS {
            let q = ptr(&p, s.id);
            // SAFETY: `q` points at a parameter of `p`, which lives to the
            // end of the loop body and is not moved meanwhile.
            unsafe {
                assert_eq!(q.name(), s.name);
                match s.kind {
                    Kind::Float {
                        min,
                        max,
                        default,
                        unit,
                        ..
                    } => {
                        assert_eq!(q.unit(), unit, "{}", s.id);
                        assert_eq!(q.step_count(), None, "{}", s.id);
                        let ends = (q.preview_plain(0.0), q.preview_plain(1.0));
                        let tol = 1e-6 * max.abs().max(min.abs()).max(1.0);
                        assert!(
                            (ends.0 - min).abs() <= tol && (ends.1 - max).abs() <= tol,
                            "{}: {ends:?}",
                            s.id
                        );
                        assert_eq!(q.default_plain_value(), default, "{}", s.id);
                        assert_eq!(q.unmodulated_plain_value(), default, "{}", s.id);
                    }
                    Kind::Int {
                        min,
                        max,
                        default,
                        unit,
                    } => {
                        assert_eq!(q.unit(), unit, "{}", s.id);
                        assert_eq!(q.step_count(), Some((max - min) as usize), "{}", s.id);
                        assert_eq!(q.preview_plain(0.0), min as f32, "{}", s.id);
                        assert_eq!(q.preview_plain(1.0), max as f32, "{}", s.id);
                        assert_eq!(q.default_plain_value(), default as f32, "{}", s.id);
                    }
                    Kind::Bool { default } => {
                        assert_eq!(q.step_count(), Some(1), "{}", s.id);
                        assert_eq!(q.default_plain_value(), default as u8 as f32, "{}", s.id);
                    }
                    Kind::Choice {
                        ids,
                        names,
                        default,
                    } => {
                        assert_eq!(ids.len(), names.len(), "{}", s.id);
                        assert_eq!(q.step_count(), Some(ids.len() - 1), "{}", s.id);
                        assert_eq!(q.default_plain_value(), default as f32, "{}", s.id);
                    }
                }
            }
        }
    }

    #[test]
    fn enumerated_values_show_names_and_parse_them() {
        let p = ModalContactParams::default();
        let mut choices = 0;
        for s in PARAMS {
            let Kind::Choice { names, .. } = s.kind else {
                continue;
            };
            choices += 1;
            let q = ptr(&p, s.id);
            let last = (names.len() - 1) as f32;
            for (i, name) in names.iter().enumerate() {
                let norm = i as f32 / last;
                // SAFETY: `q` points at a parameter of `p`, which outlives
                // the loop and is not moved.
                unsafe {
                    assert_eq!(q.normalized_value_to_string(norm, true), *name);
                    assert_eq!(q.string_to_normalized_value(name), Some(norm), "{name}");
                }
            }
        }
        assert_eq!(choices, 2, "scene and switching");
        // what the host shows for the scene: the preset titles
        let q = ptr(&p, ids::SCENE);
        let last = (presets::PRESETS.len() - 1) as f32;
        for (i, (_, title)) in presets::SHIPPED.iter().enumerate() {
            // SAFETY: `q` points at the scene parameter of `p`, which
            // outlives the loop and is not moved.
            unsafe {
                assert_eq!(q.normalized_value_to_string(i as f32 / last, false), *title);
            }
        }
    }

    #[test]
    fn switching_ids_are_the_scene_file_spellings() {
        for (i, id) in SwitchingMethods::IDS.iter().enumerate() {
            assert_eq!(SWITCHING_METHOD[i].as_str(), *id);
        }
        assert_eq!(SwitchingMethods::IDS.len(), SwitchingMethods::NAMES.len());
    }

    /// A project saved before the parameters came from one list stores the
    /// scene as nice-plug's `{"string": "<preset id>"}` (the derived enum had
    /// `#[id]`s, the file stems). It must load as the same preset, at the
    /// same index, shown under the same name; an unknown id loads the
    /// default (with a note for the log).
    #[test]
    fn saved_scenes_load_as_the_same_preset() {
        for (index, (id, title)) in presets::SHIPPED.iter().enumerate() {
            let mut state = full_state();
            state
                .params
                .insert(ids::SCENE.into(), ParamValue::String(id.to_string()));
            assert!(migrate_state(&mut state).is_empty(), "{id} kept");
            let p = ModalContactParams::default();
            let ParamPtr::EnumParam(e) = ptr(&p, ids::SCENE) else {
                panic!("scene is an enum parameter");
            };
            // what nice-plug's state loading does with a stored string
            let ParamValue::String(stored) = &state.params[ids::SCENE] else {
                panic!("stored as a string");
            };
            // SAFETY: `e` points at the scene parameter of `p`, alive and
            // not moved until the end of this iteration.
            assert!(unsafe { (*e).set_from_id(stored) }, "{id}");
            assert_eq!(p.scene_params().preset, index, "{id}");
            assert_eq!(presets::PRESETS[index].name, *id);
            assert_eq!(p.scene.to_string(), *title);
            // and saving it again stores the same string
            // SAFETY: as above, `e` points into `p`, still alive.
            assert_eq!(unsafe { (*e).unmodulated_plain_id() }, Some(*id));
        }
        let mut state = full_state();
        state.params.insert(
            ids::SCENE.into(),
            ParamValue::String("no-such-preset".into()),
        );
        let notes = migrate_state(&mut state);
        assert_eq!(notes.len(), 1);
        assert!(notes[0].starts_with("scene: invalid value"), "{notes:?}");
        same!(
            state.params[ids::SCENE],
            ParamValue::String("marimba-bar".into())
        );
    }

    #[test]
    fn an_empty_older_state_gets_every_default() {
        let state = full_state();
        let d = ModalContactParams::default();
        same!(
            state.params[ids::HARDNESS],
            ParamValue::F32(d.hardness.default_plain_value())
        );
        same!(
            state.params[ids::SCENE],
            ParamValue::String("marimba-bar".into())
        );
        same!(
            state.params[ids::SWITCHING],
            ParamValue::String("exact".into())
        );
        same!(state.params[ids::PITCH_TRACKING], ParamValue::Bool(true));
        for s in PARAMS {
            same!(state.params[s.id], s.default_value());
        }
        // a filled-in state is left as it is
        let mut again = state.clone();
        assert!(migrate_state(&mut again).is_empty());
        same!(again.params, state.params);
    }

    #[test]
    fn bad_values_are_replaced_and_good_ones_kept() {
        let mut state = full_state();
        let p = &mut state.params;
        p.insert(ids::HARDNESS.into(), ParamValue::F32(f32::NAN));
        p.insert(ids::DECAY.into(), ParamValue::F32(1e30));
        p.insert(ids::GAIN.into(), ParamValue::F32(-3.0));
        p.insert(ids::DAMPER.into(), ParamValue::Bool(true));
        p.insert(
            ids::SCENE.into(),
            ParamValue::String("no-such-preset".into()),
        );
        p.insert(ids::SWITCHING.into(), ParamValue::I32(0));
        p.insert(ids::STRIKE_CUSTOM.into(), ParamValue::F32(1.0));
        p.insert("from_the_future".into(), ParamValue::F32(3.0));
        let notes = migrate_state(&mut state);
        println!("{notes:#?}");
        assert_eq!(notes.len(), 5, "{notes:?}");
        let d = ModalContactParams::default();
        let p = &state.params;
        same!(
            p[ids::HARDNESS],
            ParamValue::F32(d.hardness.default_plain_value())
        );
        same!(p[ids::DECAY], ParamValue::F32(1.0));
        same!(p[ids::GAIN], ParamValue::F32(-3.0), "in range: kept");
        same!(p[ids::SWITCHING], ParamValue::I32(0), "a valid index: kept");
        same!(p[ids::SCENE], ParamValue::String("marimba-bar".into()));
        same!(p[ids::STRIKE_CUSTOM], ParamValue::Bool(false));
        same!(p["from_the_future"], ParamValue::F32(3.0));
        // an index past the last choice is refused
        let mut state = full_state();
        state
            .params
            .insert(ids::SCENE.into(), ParamValue::I32(presets::COUNT as i32));
        assert_eq!(migrate_state(&mut state).len(), 1);
    }

    #[test]
    fn defaults_are_the_instrument_defaults() {
        let p = ModalContactParams::default();
        let d = InstrumentParams::default();
        let got = p.instrument_params();
        assert_eq!(got.scene.preset, d.scene.preset);
        assert_eq!(got.scene.strike_pos_norm, d.scene.strike_pos_norm);
        assert_eq!(got.scene.switching, d.scene.switching);
        assert_eq!(got.scene.damper_custom, d.scene.damper_custom);
        assert_eq!(got.play.pitch_tracking, d.play.pitch_tracking);
        // the list's f32 literals, read back as f64
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.abs().max(1.0);
        for (what, a, b) in [
            (
                "hammer mass",
                got.scene.hammer_mass_factor,
                d.scene.hammer_mass_factor,
            ),
            (
                "hardness",
                got.scene.stiffness_factor,
                d.scene.stiffness_factor,
            ),
            (
                "contact damping",
                got.scene.damping_factor,
                d.scene.damping_factor,
            ),
            ("decay", got.scene.decay_scale, d.scene.decay_scale),
            ("damper", got.scene.damper_norm, d.scene.damper_norm),
            (
                "gravity",
                got.scene.gravity_m_per_s2,
                d.scene.gravity_m_per_s2,
            ),
            ("drop height", got.play.drop_height_m, d.play.drop_height_m),
            ("gain", got.play.gain_db, d.play.gain_db),
        ] {
            assert!(close(a, b), "{what}: {a} vs the instrument's {b}");
        }
    }

    /// Each entry's `applies` says what the instrument does with it: moving a
    /// `Recompile` parameter changes the compile request and nothing else,
    /// moving any other one changes only what is read without a compile.
    #[test]
    fn applies_matches_the_instrument() {
        let base = || {
            let p = ModalContactParams::default();
            // with a custom strike position and damper, so that Strike
            // position and Damper count
            // SAFETY: both pointers point at parameters of `p`, alive and
            // not moved while they are used.
            unsafe {
                ptr(&p, ids::STRIKE_CUSTOM)._internal_set_normalized_value(1.0);
                ptr(&p, ids::DAMPER_CUSTOM)._internal_set_normalized_value(1.0);
            }
            p
        };
        let b = base();
        for s in PARAMS {
            let p = base();
            let q = ptr(&p, s.id);
            // SAFETY: `q` points at a parameter of `p`, which lives to the
            // end of the loop body and is not moved meanwhile.
            unsafe {
                let now = q.unmodulated_normalized_value();
                q._internal_set_normalized_value(if now < 0.5 { 1.0 } else { 0.0 });
            }
            let scene_moved = p.scene_params() != b.scene_params();
            let play_moved = p.play_params() != b.play_params();
            assert_eq!(
                (scene_moved, play_moved),
                (
                    s.applies == Applies::Recompile,
                    s.applies != Applies::Recompile
                ),
                "{}: {:?}",
                s.id,
                s.applies
            );
        }
    }

    /// Custom damper off (a new instance): the knob is not used and moving
    /// it asks for no compile; on: the knob is the damper.
    #[test]
    fn the_damper_knob_counts_only_with_custom_damper() {
        let p = ModalContactParams::default();
        assert!(!p.damper_custom.value(), "a new instance plays the scene's");
        let before = p.scene_params();
        assert!(!before.damper_custom);
        // SAFETY: the pointer points at a parameter of `p`, which outlives
        // this statement.
        unsafe { ptr(&p, ids::DAMPER)._internal_set_normalized_value(0.9) };
        assert_eq!(
            p.scene_params(),
            before,
            "the knob moved, nothing to compile"
        );
        // SAFETY: as above, a parameter of the living `p`.
        unsafe { ptr(&p, ids::DAMPER_CUSTOM)._internal_set_normalized_value(1.0) };
        let on = p.scene_params();
        assert!(on.damper_custom);
        assert!((on.damper_norm - 0.9).abs() < 1e-6, "{}", on.damper_norm);
    }

    /// A state saved before Custom damper existed stores Damper and not
    /// Custom damper: it loads with Custom damper on, so its Damper keeps
    /// applying (the project sounds as it did). A state that stores both
    /// keeps both; an empty one gets the defaults (off).
    #[test]
    fn states_saved_before_custom_damper_keep_their_damper() {
        let mut old = full_state();
        old.params.remove(ids::DAMPER_CUSTOM);
        old.params.insert(ids::DAMPER.into(), ParamValue::F32(0.25));
        let notes = migrate_state(&mut old);
        println!("{notes:?}");
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].starts_with("damper_custom: missing"), "{notes:?}");
        same!(old.params[ids::DAMPER_CUSTOM], ParamValue::Bool(true));
        same!(old.params[ids::DAMPER], ParamValue::F32(0.25));
        // what the plugin then plays: the saved damper
        let p = ModalContactParams::default();
        // SAFETY: both pointers point at parameters of `p`, alive and not
        // moved while they are used.
        unsafe {
            ptr(&p, ids::DAMPER)._internal_set_normalized_value(0.25);
            ptr(&p, ids::DAMPER_CUSTOM)._internal_set_normalized_value(1.0);
        }
        let sp = p.scene_params();
        assert!(sp.damper_custom && (sp.damper_norm - 0.25).abs() < 1e-6);
        // even with its Damper refused (then the default, 0.5, as then)
        let mut bad = full_state();
        bad.params.remove(ids::DAMPER_CUSTOM);
        bad.params
            .insert(ids::DAMPER.into(), ParamValue::F32(f32::NAN));
        assert_eq!(migrate_state(&mut bad).len(), 2);
        same!(bad.params[ids::DAMPER_CUSTOM], ParamValue::Bool(true));
        same!(bad.params[ids::DAMPER], ParamValue::F32(0.5));
        // saved with this version: kept as saved, either way
        for custom in [false, true] {
            let mut new = full_state();
            new.params
                .insert(ids::DAMPER_CUSTOM.into(), ParamValue::Bool(custom));
            assert!(migrate_state(&mut new).is_empty());
            same!(new.params[ids::DAMPER_CUSTOM], ParamValue::Bool(custom));
        }
        // nothing stored: the defaults
        let empty = full_state();
        same!(empty.params[ids::DAMPER_CUSTOM], ParamValue::Bool(false));
    }

    #[test]
    fn spec_finds_every_entry() {
        for s in PARAMS {
            assert_eq!(spec(s.id), Some(s));
        }
        assert_eq!(spec("no_such_parameter"), None);
    }

    /// The user scene, the editor's size and the scene folder round-trip
    /// through a saved state's fields; a project without them (older, or
    /// saved with a preset) gets the defaults; unreadable values are
    /// reported and replaced by defaults.
    #[test]
    fn persisted_fields_round_trip_and_bad_ones_get_defaults() {
        let a = Persisted::default();
        a.library.load(UserScene {
            name: "mine".into(),
            text: "version = 1".into(),
            path: Some(PathBuf::from("/somewhere/mine.toml")),
        });
        a.editor_size.store((1200, 800));
        *a.scene_folder.lock().unwrap() = Some(PathBuf::from("/my/scenes"));
        let saved = a.serialize();
        println!("{saved:?}");
        let b = Persisted::default();
        assert!(b.deserialize(&saved).is_empty());
        assert_eq!(b.serialize(), saved);
        assert_eq!(b.library.requested().unwrap().name, "mine");
        assert_ne!(b.library.active(), 0);
        assert_eq!(b.editor_size.load(), (1200, 800));

        // an older project: no fields at all
        let notes = b.deserialize(&BTreeMap::new());
        assert!(notes.is_empty());
        assert_eq!(b.library.active(), 0, "the preset plays");
        assert_eq!(b.editor_size.load(), EDITOR_SIZE);
        assert!(b.scene_folder.lock().unwrap().is_none());

        // garbage
        let mut bad = saved.clone();
        bad.insert(keys::USER_SCENE.into(), "{not json".into());
        bad.insert(keys::EDITOR_SIZE.into(), "[5, 99999]".into());
        let notes = b.deserialize(&bad);
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert_eq!(b.library.active(), 0);
        assert_eq!(b.editor_size.load(), EDITOR_SIZE);
    }
}
