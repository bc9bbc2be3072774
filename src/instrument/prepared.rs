//! Prepared scenes: everything the audio thread needs for one parameter set,
//! compiled off the audio thread, and the compile fallback that keeps a
//! scene playing when exact switching is refused.

use super::mapping::{
    damped_scene, root_note, scene_for, InstrumentParams, PlayParams, SceneParams,
};
use super::{MAX_VOICES, OUTPUT_BAND_FRACTION};
use crate::compile::{compile_with, CompileError, CompiledScene};
use crate::engine::EngineState;
use crate::presets;
use crate::scene::{Scene, Switching};

/// Everything the audio thread needs for one parameter set, built off the
/// audio thread: the compiled scene, its damped variant, and a fresh engine
/// state per voice (so a swap to new dimensions allocates nothing). A clone
/// (offline tools play many notes of one compile) allocates.
#[derive(Clone)]
pub struct Prepared {
    /// Request revision this was built for.
    pub revision: u64,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// The parameters it was built from.
    pub params: SceneParams,
    /// The compiled scenes.
    pub scenes: Scenes,
    /// MIDI note that plays the scene as written.
    pub root_note: f64,
    /// The hammer has gravity (it is dropped, it bounces).
    pub bouncing: bool,
    /// The switching method actually compiled.
    pub switching_used: Switching,
    /// Set when the requested switching was refused and the fallback used.
    pub fallback_note: Option<String>,
    /// One engine state per voice, sized for `scenes` (the running state of
    /// a carried voice moves in here at a swap).
    pub(super) states: [EngineState; MAX_VOICES],
}

/// The scene as played, the one released voices continue on, and the
/// scene at the other hardness levels a note's brightness selects. Kept
/// apart from the voice states so a voice's scene can be read while its
/// state is being stepped.
#[derive(Clone)]
pub struct Scenes {
    /// The scene as played.
    pub scene: CompiledScene,
    /// Released voices continue on this (`None` when the damper is 0).
    pub damped: Option<CompiledScene>,
    /// The played scene at the hardness levels -2, -1, +1, +2 (contact
    /// stiffness times `TIMBRE_STIFFNESS_STEP^level`), for a note's
    /// brightness (docs/plugin.md, "Brightness"); `None` where the scene is
    /// too large ([`TIMBRE_MAX_STATES`]) or the level did not compile.
    pub timbre: [Option<CompiledScene>; 4],
    /// Whether each level's scene has the played scene's free phase (the
    /// same `V`, `V^-1`, blocks and step, compared exactly when it is
    /// prepared): a voice out of contact then moves between levels in O(N)
    /// ([`EngineState::rebind_same_free`]).
    pub timbre_same_free: [bool; 4],
}

/// The slot of hardness `level` in [`Scenes::timbre`] (`None` for the
/// played scene's level 0).
fn timbre_slot(level: i8) -> Option<usize> {
    match level {
        -2 => Some(0),
        -1 => Some(1),
        1 => Some(2),
        2 => Some(3),
        _ => None,
    }
}

impl Scenes {
    /// The scene a voice is bound to: the damped one when it is released
    /// onto it, else the played one at hardness `level` (the played one
    /// where that level has no scene).
    #[inline]
    pub fn bound(&self, level: i8, on_damped: bool) -> &CompiledScene {
        match (&self.damped, on_damped) {
            (Some(d), true) => d,
            _ => timbre_slot(level)
                .and_then(|k| self.timbre[k].as_ref())
                .unwrap_or(&self.scene),
        }
    }

    /// Whether the scenes of levels `a` and `b` step the free phase in the
    /// same coordinates (see [`Scenes::timbre_same_free`]).
    pub fn same_free(&self, a: i8, b: i8) -> bool {
        let same = |l: i8| {
            timbre_slot(l).is_none_or(|k| self.timbre[k].is_none() || self.timbre_same_free[k])
        };
        same(a) && same(b)
    }

    /// Whether hardness `level` has a scene of its own (level 0 always:
    /// the played scene).
    pub fn has_level(&self, level: i8) -> bool {
        timbre_slot(level).is_none_or(|k| self.timbre[k].is_some())
    }
}

/// Brightness levels on each side of the played hardness: a note's
/// brightness `b` in 0 .. 1 selects level `round(4 b) - 2`, -2 ..= 2, and
/// the contact stiffness of its strikes is the Hardness parameter's times
/// `TIMBRE_STIFFNESS_STEP^level` (docs/plugin.md, "Brightness").
pub const TIMBRE_LEVEL_MAX: i8 = 2;
/// Contact stiffness ratio between neighbouring brightness levels (2: the
/// contact's own frequency `sqrt(k / m)` moves by half an octave a level,
/// an octave either way in all).
pub const TIMBRE_STIFFNESS_STEP: f64 = 2.0;
/// Largest contact-phase dimension for which the brightness levels are
/// compiled (each level is a compile of its own, four more per parameter
/// change: every preset has fewer states (tested); a larger user scene plays
/// every note at the Hardness parameter's level, and the plugin says so
/// in its log and the editor: [`Prepared::timbre_note`]).
pub const TIMBRE_MAX_STATES: usize = 128;

/// The hardness level of brightness `b` (0 .. 1; not a number is the
/// neutral 0.5, MPE's centre).
pub fn timbre_level(b: f64) -> i8 {
    let b = if b.is_nan() { 0.5 } else { b.clamp(0.0, 1.0) };
    let max = f64::from(TIMBRE_LEVEL_MAX);
    ((2.0 * max * b).round() - max) as i8
}

/// The hardness level of a note's hardness `factor` (its contact
/// stiffness over the Hardness parameter's, e.g. from a host's polyphonic
/// modulation of Hardness): the nearest level, `round(log2 factor /
/// log2 TIMBRE_STIFFNESS_STEP)`, within ±[`TIMBRE_LEVEL_MAX`]; a factor
/// that is not a finite positive number is level 0 (docs/plugin.md, "Polyphonic
/// modulation").
pub fn hardness_level(factor: f64) -> i8 {
    if !(factor > 0.0 && factor.is_finite()) {
        return 0;
    }
    let max = f64::from(TIMBRE_LEVEL_MAX);
    (factor.ln() / TIMBRE_STIFFNESS_STEP.ln())
        .round()
        .clamp(-max, max) as i8
}

/// Cost model of the block that holds a strike, beyond a plain block
/// (`benches/worst_block.rs` prints it next to the measurement): per
/// multiply-add of the two changes of basis
/// ([`CompiledScene::switch_multiply_adds`](crate::compile::CompiledScene::switch_multiply_adds):
/// the hierarchical forms' stored entries, or the dense matrices'), per
/// state of the contact phase (the located switch's partial steps and
/// event search), and a fixed part. A strike usually makes two or three
/// contacts (the hammer meets the ringing object again), so the per
/// multiply-add figure covers them. Fitted on this project's development
/// machine (2-core AMD EPYC, AVX2), where it is within 0.6x-1.9x of the
/// measured cost from 10 to 1000 modes; a slower CPU takes longer, so the
/// warning below leaves a margin.
pub const STRIKE_NS_PER_SWITCH_FLOP: f64 = 1.6;
/// See [`STRIKE_NS_PER_SWITCH_FLOP`].
pub const STRIKE_NS_PER_STATE: f64 = 20.0;
/// See [`STRIKE_NS_PER_SWITCH_FLOP`].
pub const STRIKE_NS_FIXED: f64 = 4_000.0;
/// The strike warning fires when a chord of as many strikes as the
/// polyphony allows, in one block, is estimated to need more than this fraction of the block's
/// real-time budget (the rest is the voices' own running cost, the host
/// and a slower CPU).
pub const STRIKE_BUDGET_FRACTION: f64 = 0.5;

impl Prepared {
    /// Estimated CPU time of the block that holds one strike, beyond a plain
    /// block (seconds; see [`STRIKE_NS_PER_SWITCH_FLOP`]). \[any-thread\]
    pub fn strike_cost_estimate_s(&self) -> f64 {
        let sc = &self.scenes.scene;
        let flops = sc.switch_multiply_adds() as f64;
        (flops * STRIKE_NS_PER_SWITCH_FLOP
            + sc.contact.dim as f64 * STRIKE_NS_PER_STATE
            + STRIKE_NS_FIXED)
            * 1e-9
    }

    /// A warning when a chord of `polyphony` notes struck in one block of
    /// `block_len` samples is estimated to take more than
    /// [`STRIKE_BUDGET_FRACTION`] of the block's real-time budget: how many
    /// simultaneous strikes fit, and what helps. `None` when it fits.
    /// \[worker\] \[main-thread\]
    pub fn strike_warning(&self, block_len: usize, polyphony: usize) -> Option<String> {
        let budget = block_len as f64 / self.rate_hz;
        let strike = self.strike_cost_estimate_s();
        let chord = polyphony.clamp(1, MAX_VOICES) as f64 * strike;
        (chord > STRIKE_BUDGET_FRACTION * budget).then(|| {
            let fit = (STRIKE_BUDGET_FRACTION * budget / strike).floor() as usize;
            let fits = match fit {
                0 => "even one strike takes more than half the block".to_string(),
                1 => "one strike at a time fits in half the block".to_string(),
                k => format!("about {k} simultaneous strikes fit in half the block"),
            };
            format!(
                "scene {:?}: a strike costs about {:.0} us of CPU in the block that holds it \
                 (estimate; {} states in contact); at {block_len} samples per block \
                 ({:.2} ms) {fits}, and a {polyphony}-note chord needs about {:.0} % of \
                 the block: expect dropouts on chords unless the host's buffer is larger \
                 (or the object has fewer modes)",
                self.scenes.scene.name,
                strike * 1e6,
                self.scenes.scene.contact.dim,
                budget * 1e3,
                100.0 * chord / budget
            )
        })
    }

    /// A note when the scene is too large for the brightness levels
    /// ([`TIMBRE_MAX_STATES`]): every note plays at the Hardness
    /// parameter's level. \[any-thread\]
    pub fn timbre_note(&self) -> Option<String> {
        let dim = self.scenes.scene.contact.dim;
        (dim > TIMBRE_MAX_STATES).then(|| {
            format!(
                "scene {:?}: {dim} states in contact, more than {TIMBRE_MAX_STATES}: the \
                 brightness levels are not compiled, so note brightness (the note \
                 expression, MPE timbre) plays every note at the Hardness parameter's level",
                self.scenes.scene.name
            )
        })
    }

    /// A warning when the scene's exact event search may cost more than a
    /// sample period in a sample that holds a switch (the compile summary's
    /// estimate, at the root pitch: higher notes step further per sample and
    /// cost more). The engine keeps the physics exact whatever it costs; the
    /// warning tells the user where CPU spikes come from. \[worker\]
    pub fn realtime_warning(&self) -> Option<String> {
        let n = self.scenes.scene.search_nodes_estimate;
        (n > crate::compile::REALTIME_SEARCH_NODES).then(|| {
            let line = self
                .scenes
                .scene
                .summary
                .lines()
                .find(|l| l.starts_with("event search"))
                .unwrap_or("");
            format!(
                "scene {:?}: the contact is stiff enough that a sample holding a switch may take longer than a sample period (about {n:.0} event-search nodes per sample; exact switching stays exact, expect CPU spikes at small buffer sizes; lower Hardness or raise Hammer mass to reduce it). {line}",
                self.scenes.scene.name
            )
        })
    }
}

impl std::fmt::Debug for Prepared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prepared")
            .field("revision", &self.revision)
            .field("rate_hz", &self.rate_hz)
            .field("scene", &self.scenes.scene.name)
            .field("switching_used", &self.switching_used)
            .finish_non_exhaustive()
    }
}

fn compile_with_fallback(
    scene: &Scene,
    rate_hz: f64,
    switching: Switching,
) -> Result<(CompiledScene, Switching, Option<String>), CompileError> {
    match compile_with(scene, rate_hz, Some(switching)) {
        Ok(c) => Ok((c, switching, None)),
        Err(e) if switching == Switching::Exact => {
            let c = compile_with(scene, rate_hz, Some(Switching::OffsetRod))?;
            Ok((
                c,
                Switching::OffsetRod,
                Some(format!(
                    "exact switching refused ({e}); falling back to offset-rod"
                )),
            ))
        }
        Err(e) => Err(e),
    }
}

/// Why a parameter set could not be prepared.
#[derive(Debug, Clone, PartialEq)]
pub enum PrepareError {
    /// A scene (the played one or its damped variant) did not compile.
    Compile(CompileError),
    /// The damped scene compiled to other dimensions than the played one
    /// (released voices could not carry their state over).
    DampedLayoutDiffers,
}

impl std::fmt::Display for PrepareError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Compile(e) => write!(f, "{e}"),
            Self::DampedLayoutDiffers => {
                write!(f, "damped scene has other dimensions than the scene")
            }
        }
    }
}

impl std::error::Error for PrepareError {}

impl From<CompileError> for PrepareError {
    fn from(e: CompileError) -> Self {
        Self::Compile(e)
    }
}

/// Compile everything for `params` at `rate_hz` (eigendecompositions: never
/// call this on the audio thread). \[worker\] \[main-thread\]
pub fn prepare(
    params: &SceneParams,
    rate_hz: f64,
    revision: u64,
) -> Result<Box<Prepared>, PrepareError> {
    let base = presets::scene(params.preset).map_err(CompileError::Scene)?;
    prepare_scene(&base, params, rate_hz, revision)
}

/// [`prepare`] for a scene given as a value (a user's scene file, an
/// offline batch job) instead of the preset `params.preset` names: the same
/// parameter mapping, compile fallback and damped scene. `params.preset` is
/// only carried along. \[worker\] \[main-thread\]
pub fn prepare_scene(
    base: &Scene,
    params: &SceneParams,
    rate_hz: f64,
    revision: u64,
) -> Result<Box<Prepared>, PrepareError> {
    let ip = InstrumentParams {
        scene: *params,
        play: PlayParams::default(),
    };
    let played = scene_for(base, &ip);
    let (scene, switching_used, fallback_note) =
        compile_with_fallback(&played, rate_hz, params.switching)?;
    let damped = if params.damper_norm > 0.0 {
        let d = damped_scene(&played, params.damper_norm);
        Some(compile_with(&d, rate_hz, Some(switching_used))?)
    } else {
        None
    };
    if let Some(d) = &damped {
        if d.free.dim != scene.free.dim || d.contact.dim != scene.contact.dim {
            return Err(PrepareError::DampedLayoutDiffers);
        }
    }
    let timbre = if scene.contact.dim <= TIMBRE_MAX_STATES {
        [-2i8, -1, 1, 2].map(|level| {
            let mut p = *params;
            p.stiffness_factor *= TIMBRE_STIFFNESS_STEP.powi(i32::from(level));
            let ip = InstrumentParams {
                scene: p,
                play: PlayParams::default(),
            };
            // a level that does not compile (a stiffness beyond the
            // scene's limits) or lays its states out otherwise plays at
            // the Hardness parameter's level
            compile_with(&scene_for(base, &ip), rate_hz, Some(switching_used))
                .ok()
                .filter(|t| t.free.dim == scene.free.dim && t.contact.dim == scene.contact.dim)
        })
    } else {
        [None, None, None, None]
    };
    let timbre_same_free = std::array::from_fn(|k| {
        timbre[k].as_ref().is_some_and(|t| {
            t.free.v == scene.free.v
                && t.free.vinv == scene.free.vinv
                && t.free.gens == scene.free.gens
                && t.free.dense == scene.free.dense
                && t.h == scene.h
        })
    });
    let band_hz = OUTPUT_BAND_FRACTION * 0.5 * rate_hz;
    let states = std::array::from_fn(|_| {
        let mut st = EngineState::new(&scene);
        st.set_output_band(&scene, band_hz);
        // the live view observes voices on the audio thread: no allocation there
        st.reserve_observation();
        st
    });
    Ok(Box::new(Prepared {
        revision,
        rate_hz,
        params: *params,
        root_note: root_note(base),
        bouncing: base.hammer.gravity_m_per_s2 > 0.0,
        switching_used,
        fallback_note,
        scenes: Scenes {
            scene,
            damped,
            timbre,
            timbre_same_free,
        },
        states,
    }))
}
