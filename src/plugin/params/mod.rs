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
//!
//! This file holds the list and what the macro makes of it; the rest of the
//! room: `metadata.rs` (an entry's [`ParamSpec`], [`Kind`], [`Taper`] and
//! [`Applies`]), `choices.rs` (the [`Choice`]s and their lists),
//! `from_spec.rs` (each nice-plug parameter built from its entry, the
//! polyphonic modulation ids), `persisted.rs` (what is saved besides the
//! parameters) and `migrate.rs` ([`migrate_state`]).

pub use super::poly::{VariantsWanted, POLY_DAMPER, POLY_HARDNESS, POLY_POSITION};
use crate::instrument::{
    InstrumentParams, PlayParams, SceneParams, DEFAULT_BEND_RANGE_SEMITONES,
    MAX_BEND_RANGE_SEMITONES, MAX_LOOKAHEAD_S, MAX_VOICES,
};
use crate::scene::DEFAULT_RELEASE_DAMPER;
use choices::{choice, SWITCHING_METHOD};
use from_spec::FromSpec;
use metadata::{factor, linear};
use nice_plug::prelude::*;
use std::collections::BTreeMap;

mod choices;
mod from_spec;
mod metadata;
mod migrate;
mod persisted;
#[cfg(test)]
mod tests;

pub use choices::{Choice, ChoiceList, PresetChoice, Scenes, SwitchingChoice, SwitchingMethods};
pub use from_spec::{poly_modulation_id, POLY_MODULATED};
pub use metadata::{spec, Applies, Kind, ParamSpec, Taper};
pub use migrate::migrate_state;
pub use persisted::{keys, Persisted, EDITOR_SIZE};

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
