//! Prepared scenes: everything the audio thread needs for one parameter set,
//! compiled off the audio thread, and the compile fallback that keeps a
//! scene playing when exact switching is refused.

use super::kit::Kit;
use super::mapping::{
    damped_scene, impact_speed_m_per_s, key_scale, root_note, scene_for, InstrumentParams,
    PlayParams, SceneParams,
};
use super::{
    lookahead_samples, LOOKAHEAD_WORK_FRACTION, MAX_LOOKAHEAD_S, MAX_VOICES, OUTPUT_BAND_FRACTION,
    STEAL_FADES,
};
use crate::compile::{cancel, compile_with, CompileError, CompiledScene};
use crate::engine::{certify_rest_strike, EngineState, ScaleProps};
use crate::presets;
use crate::scene::{Scene, SceneError, Switching};

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
    /// The parameters it was built from, resolved for its scene (the
    /// damper it plays: [`SceneParams::resolved_for`]).
    pub params: SceneParams,
    /// The compiled scenes.
    pub scenes: Scenes,
    /// MIDI note that plays the scene as written.
    pub root_note: f64,
    /// The hammer has gravity or a hand presses it (it is dropped, it
    /// bounces, it rests on the object under a constant force).
    pub bouncing: bool,
    /// The switching method actually compiled.
    pub switching_used: Switching,
    /// Set when the requested switching was refused and the fallback used.
    pub fallback_note: Option<String>,
    /// One engine state per voice, sized for `scenes` (the running state of
    /// a carried voice moves in here at a swap).
    /// On the heap, as the variants (a `Prepared` is built on whichever
    /// thread compiles it, a host's thread at activation).
    pub(super) states: Box<[EngineState; MAX_VOICES]>,
    /// [`STEAL_FADES`] more, sized as `states`: a stolen voice's running
    /// state moves into one to fade out (docs/plugin.md, "Velocity, pitch, voices"); none
    /// for a kit (its own spares, [`Kit`]).
    pub(super) spares: Box<[EngineState]>,
    /// A scene of several contacts, played as a kit (docs/design.md,
    /// "Played as a kit"); then `scenes` holds the first
    /// mallet on its object alone (what the instrument reads of a scene:
    /// its spectrum, its costs), which no voice plays.
    pub kit: Option<Box<Kit>>,
    /// The played scene's propagators at each MIDI key's pitch (`[key]`,
    /// the scale a note-on computes with pitch tracking and no bend), so a
    /// new note copies them instead of computing an exponential and a sine
    /// per block on the audio thread; empty for a kit and for a scene with
    /// a dense phase (which plays at its root pitch only). \[worker\]
    pub(super) key_props: Vec<ScaleProps>,
    /// Everything [`Stage::Full`] compiles is here: false for a
    /// [`Stage::Playable`] scene that left variants or the keys' stored
    /// strikes out (the worker follows it with the full one).
    pub complete: bool,
}

/// How much of a scene [`prepare_staged`] compiles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Stage {
    /// The played scene and its damped scene only: no variants, no stored
    /// strikes (new notes compute their propagators and strike on the
    /// audio thread, as after a bend). An activation's first scene on a
    /// live host, so the instance sounds within the activation's wait
    /// (docs/design.md, "The plugin and its threads").
    Playable,
    /// Everything: the variants and every key's stored strike.
    #[default]
    Full,
}

/// The scene as played, the one released voices continue on, and the
/// variants a voice may play on instead (docs/plugin.md, "Brightness" and
/// "Polyphonic modulation"): the played scene at other hardness levels
/// (always, for scenes of at most [`TIMBRE_MAX_STATES`] states in contact)
/// and strike-position levels, and the damped scene at other damper levels
/// (when asked for: [`SceneParams::variants`]). Kept apart from the voice
/// states so a voice's scene can be read while its state is being stepped.
#[derive(Clone)]
pub struct Scenes {
    /// The scene as played.
    pub scene: CompiledScene,
    /// Released voices continue on this (`None` when the damper is 0).
    pub damped: Option<CompiledScene>,
    /// The played scene at (hardness level, position level), `(0, 0)`
    /// excluded (that is `scene`), at `cell(hard, pos)`. On the heap:
    /// a `Prepared` is built on the stack of whichever thread compiles it
    /// (a host's thread at activation), and 25 scenes inline would be a
    /// large frame there.
    played: Vec<Option<VariantScene>>,
    /// The damped scene at damper level `d` at `[d + 2]` (level 0 excluded:
    /// that is `damped`): `None` where not compiled (the voice uses
    /// `damped`), `Some(None)` where that level's damper is 0 (a released
    /// voice rings on its played scene). On the heap, as `played`.
    damped_at: Vec<Option<Option<CompiledScene>>>,
}

/// A variant of the played scene and whether it steps the free phase in
/// the played scene's coordinates (the same `V`, `V^-1`, blocks and step,
/// compared exactly when it is prepared): a voice out of contact then moves
/// between such variants in O(N) ([`EngineState::rebind_same_free`]).
#[derive(Clone)]
struct VariantScene {
    scene: CompiledScene,
    same_free: bool,
}

/// Levels of each variant axis: `-TIMBRE_LEVEL_MAX ..= TIMBRE_LEVEL_MAX`.
const LEVELS: usize = 2 * TIMBRE_LEVEL_MAX as usize + 1;

/// The index of `level` on a variant axis (clamped to the levels).
fn slot(level: i8) -> usize {
    (level.clamp(-TIMBRE_LEVEL_MAX, TIMBRE_LEVEL_MAX) + TIMBRE_LEVEL_MAX) as usize
}

/// The index of (hardness level, position level) in [`Scenes`]' played
/// variants.
fn cell(hard: i8, pos: i8) -> usize {
    slot(hard) * LEVELS + slot(pos)
}

/// Which of the compiled scenes a voice plays on: its levels on each
/// variant axis (0: the parameter's own value).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Variant {
    /// Hardness level: contact stiffness times `TIMBRE_STIFFNESS_STEP^hard`.
    pub hard: i8,
    /// Strike-position level: the position plus `pos * POSITION_STEP`.
    pub pos: i8,
    /// Damper level (once released): the damper plus `damper * DAMPER_STEP`.
    pub damper: i8,
}

impl Prepared {
    /// Drop every key's stored strike from rest
    /// ([`ScaleProps::forget_strike`]): new notes then strike as the
    /// engine runs them (a comparison for tests and benchmarks).
    #[doc(hidden)]
    pub fn forget_stored_strikes(&mut self) {
        self.key_props
            .iter_mut()
            .for_each(ScaleProps::forget_strike);
    }
}

impl Scenes {
    /// The played scene at hardness level `hard` and position level `pos`,
    /// and whether it steps the free phase as `scene` does. A variant that
    /// was not compiled resolves to the same hardness at the parameter's
    /// position, then to `scene`.
    fn played_at(&self, hard: i8, pos: i8) -> (&CompiledScene, bool) {
        let at = |h: i8, p: i8| self.played[cell(h, p)].as_ref();
        match at(hard, pos).or_else(|| at(hard, 0)) {
            Some(v) => (&v.scene, v.same_free),
            None => (&self.scene, true),
        }
    }

    /// The scene a voice released at damper level `level` continues on
    /// (`None`: it rings on its played scene, the damper being 0).
    pub fn damped_for(&self, level: i8) -> Option<&CompiledScene> {
        match (level, &self.damped_at[slot(level)]) {
            (0, _) | (_, None) => self.damped.as_ref(),
            (_, Some(d)) => d.as_ref(),
        }
    }

    /// The scene a voice at `v` is bound to: the damped one of its damper
    /// level when it is released onto it, else the played one at its
    /// hardness and position levels.
    #[inline]
    pub fn bound(&self, v: Variant, on_damped: bool) -> &CompiledScene {
        if on_damped {
            if let Some(d) = self.damped_for(v.damper) {
                return d;
            }
        }
        self.played_at(v.hard, v.pos).0
    }

    /// Whether the played scenes of `a` and `b` step the free phase in the
    /// same coordinates (so a voice moves between them in O(N)).
    pub fn same_free(&self, a: Variant, b: Variant) -> bool {
        self.played_at(a.hard, a.pos).1 && self.played_at(b.hard, b.pos).1
    }

    /// Whether `v`'s hardness and position levels have a played scene of
    /// their own (`(0, 0)` always: the played scene).
    pub fn has_played(&self, v: Variant) -> bool {
        (v.hard == 0 && v.pos == 0) || self.played[cell(v.hard, v.pos)].is_some()
    }

    /// Whether every played variant steps the free phase as the played
    /// scene does.
    pub fn variants_same_free(&self) -> bool {
        self.played.iter().flatten().all(|v| v.same_free)
    }

    /// Every compiled scene: the played one, the damped one, the variants.
    fn all(&self) -> impl Iterator<Item = &CompiledScene> {
        let played = self.played.iter().flatten().map(|v| &v.scene);
        let damped_at = self.damped_at.iter().flatten().flatten();
        std::iter::once(&self.scene)
            .chain(&self.damped)
            .chain(played)
            .chain(damped_at)
    }

    /// How many variants (played and damped) are compiled.
    pub fn variant_count(&self) -> usize {
        self.played.iter().flatten().count() + self.damped_at.iter().flatten().flatten().count()
    }
}

/// Strike position between neighbouring position levels (of the striking
/// line, 0 .. 1).
pub const POSITION_STEP: f64 = 0.1;
/// Damper between neighbouring damper levels (of its 0 .. 1).
pub const DAMPER_STEP: f64 = 0.25;

/// The level of an offset `x` on an axis of step `step`: the nearest,
/// within ±[`TIMBRE_LEVEL_MAX`]; not a number is 0.
fn level_of(x: f64, step: f64) -> i8 {
    if x.is_nan() {
        return 0;
    }
    let max = f64::from(TIMBRE_LEVEL_MAX);
    (x / step).round().clamp(-max, max) as i8
}

/// The strike-position level of a note's position offset (a host's
/// polyphonic modulation of Strike position, in its units).
pub fn position_level(offset: f64) -> i8 {
    level_of(offset, POSITION_STEP)
}

/// The damper level of a note's damper offset (a host's polyphonic
/// modulation of Damper, in its units).
pub fn damper_level(offset: f64) -> i8 {
    level_of(offset, DAMPER_STEP)
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

/// The constant force on a driven hammer at full pressure, as a multiple
/// of the scene's own ([`press_factor`]).
pub const PRESS_RANGE: f64 = 4.0;

/// The factor on a driven scene's constant force at pressure `p` (0 .. 1;
/// not a number is 0): `1 + (PRESS_RANGE - 1) p`, 1 unpressed (the scene as
/// written) to [`PRESS_RANGE`] at full pressure, continuous (docs/design.md,
/// "Rolling and scraping"; [`EngineState::set_load`]). \[any-thread\]
pub fn press_factor(p: f64) -> f64 {
    let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) };
    1.0 + (PRESS_RANGE - 1.0) * p
}

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
    level_of(factor.ln(), TIMBRE_STIFFNESS_STEP.ln())
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

/// Cost model of a voice's plain stepping, free or in contact, per sample:
/// nanoseconds per state of the contact phase, and a fixed part (fitted on
/// the same machine as [`STRIKE_NS_PER_SWITCH_FLOP`]: 14, 67 and 600 ns
/// per sample at 10, 100 and 1000 modes). Only the lookahead's scheduling
/// reads it (docs/plugin.md, "Lookahead"): it decides when work is done,
/// never what is computed.
pub const STEP_NS_PER_STATE: f64 = 0.3;
/// See [`STEP_NS_PER_STATE`].
pub const STEP_NS_FIXED: f64 = 8.0;

/// A compiled scene's estimated strike cost, and the warning it gives at a
/// host's block size, polyphony and lookahead.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StrikeCost {
    /// The scene's name.
    pub scene: String,
    /// [`Prepared::strike_cost_estimate_s`] \[s\].
    pub strike_s: f64,
    /// States of the contact phase.
    pub contact_states: usize,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Most strikes that can start in one sample: the polyphony's notes,
    /// a pitched kit's voices, or a listed kit's mallets (its one voice
    /// throws each at most once an instant).
    pub most_at_once: usize,
}

impl StrikeCost {
    /// See [`Prepared::strike_warning`]. \[any-thread\]
    pub fn warning(&self, block_len: usize, polyphony: usize, lookahead: usize) -> Option<String> {
        let budget = block_len as f64 / self.rate_hz;
        let strike = self.strike_s;
        let polyphony = polyphony.clamp(1, MAX_VOICES).min(self.most_at_once.max(1));
        let chord = polyphony as f64 * strike;
        // with a lookahead, the voices work through a chord's strikes in
        // the blocks after it, a share of each
        let ahead = LOOKAHEAD_WORK_FRACTION * lookahead as f64 / self.rate_hz;
        (chord > STRIKE_BUDGET_FRACTION * budget + ahead).then(|| {
            let need_s = (chord - STRIKE_BUDGET_FRACTION * budget) / LOOKAHEAD_WORK_FRACTION;
            let longest = lookahead_samples(MAX_LOOKAHEAD_S, self.rate_hz);
            let spread = if need_s * self.rate_hz <= longest as f64 {
                format!(
                    "a Lookahead of {:.0} ms or more spreads such a chord over the blocks \
                     after it (docs/plugin.md, \"Lookahead\")",
                    (need_s * 1e3).ceil()
                )
            } else {
                format!(
                    "even the largest Lookahead ({:.0} ms) is too short to spread it",
                    longest as f64 / self.rate_hz * 1e3
                )
            };
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
                 ({spread}; or the object has fewer modes)",
                self.scene,
                strike * 1e6,
                self.contact_states,
                budget * 1e3,
                100.0 * chord / budget
            )
        })
    }
}

impl Prepared {
    /// Estimated CPU time of one voice's sample, free or in contact \[ns\]
    /// ([`STEP_NS_PER_STATE`]). \[any-thread\]
    pub fn step_cost_ns(&self) -> f64 {
        STEP_NS_FIXED + STEP_NS_PER_STATE * self.contact_states() as f64
    }

    /// The states a voice steps in contact: the played scene's, or a
    /// kit's largest phase. \[any-thread\]
    fn contact_states(&self) -> usize {
        self.kit
            .as_ref()
            .map_or(self.scenes.scene.contact.dim, |k| k.max_dim())
    }

    /// Estimated CPU time of one contact beyond its samples' stepping \[ns\]:
    /// half of [`Prepared::strike_cost_estimate_s`] (a strike makes two or
    /// three contacts). \[any-thread\]
    pub fn contact_cost_ns(&self) -> f64 {
        0.5e9 * self.strike_cost_estimate_s()
    }

    /// Estimated CPU time of the block that holds one strike, beyond a plain
    /// block (seconds; see [`STRIKE_NS_PER_SWITCH_FLOP`]). \[any-thread\]
    pub fn strike_cost_estimate_s(&self) -> f64 {
        let sc = &self.scenes.scene;
        // a kit's switch: four products of about dim^2 / 2 (docs/numerics.md
        // section 14), a strike two switches
        let flops = self.kit.as_ref().map_or(sc.switch_multiply_adds(), |k| {
            let d = k.max_dim();
            4 * d * d
        }) as f64;
        (flops * STRIKE_NS_PER_SWITCH_FLOP
            + self.contact_states() as f64 * STRIKE_NS_PER_STATE
            + STRIKE_NS_FIXED)
            * 1e-9
    }

    /// A warning when a chord of `polyphony` notes struck in one block of
    /// `block_len` samples is estimated to take more than
    /// [`STRIKE_BUDGET_FRACTION`] of the block's real-time budget, beyond
    /// what a lookahead of `lookahead` samples spreads: how many
    /// simultaneous strikes fit, and what helps. `None` when it fits
    /// ([`StrikeCost::warning`]). \[worker\] \[main-thread\]
    pub fn strike_warning(
        &self,
        block_len: usize,
        polyphony: usize,
        lookahead: usize,
    ) -> Option<String> {
        self.strike_cost().warning(block_len, polyphony, lookahead)
    }

    /// What the strike warning is computed from (kept by the plugin's
    /// compile report, so the editor can say it again for the parameters
    /// of the moment). \[any-thread\]
    pub fn strike_cost(&self) -> StrikeCost {
        StrikeCost {
            scene: self.scenes.scene.name.clone(),
            strike_s: self.strike_cost_estimate_s(),
            contact_states: self.contact_states(),
            most_at_once: self.kit.as_ref().map_or(MAX_VOICES, |k| k.most_at_once()),
            rate_hz: self.rate_hz,
        }
    }

    /// A note when the scene is too large for the brightness and
    /// modulation levels ([`TIMBRE_MAX_STATES`]): every note plays at the
    /// parameters' values. \[any-thread\]
    pub fn timbre_note(&self) -> Option<String> {
        if let Some(kit) = self.kit.as_deref() {
            let dim = kit.max_dim();
            return (dim > TIMBRE_MAX_STATES).then(|| {
                format!(
                    "scene {:?}: a kit whose largest phase has {dim} states, more than \
                     {TIMBRE_MAX_STATES}: its brightness and modulation levels are not \
                     compiled, so note brightness (the note expression, MPE timbre) and \
                     polyphonic modulation of Hardness, Strike position and Damper play every \
                     note at the parameters' values",
                    self.scenes.scene.name
                )
            });
        }
        let dim = self.scenes.scene.contact.dim;
        (dim > TIMBRE_MAX_STATES).then(|| {
            format!(
                "scene {:?}: {dim} states in contact, more than {TIMBRE_MAX_STATES}: the \
                 brightness and modulation levels are not compiled, so note brightness (the \
                 note expression, MPE timbre) and polyphonic modulation of Hardness, Strike \
                 position and Damper play every note at the parameters' values",
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
    /// A scene of several contacts that does not make a kit (the field
    /// and why).
    Kit(SceneError),
    /// The compile was cancelled (the instance was deactivated or ended:
    /// [`crate::compile::cancel`]).
    Cancelled,
}

impl std::fmt::Display for PrepareError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Compile(e) => write!(f, "{e}"),
            Self::DampedLayoutDiffers => {
                write!(f, "damped scene has other dimensions than the scene")
            }
            Self::Kit(e) => write!(f, "{e}"),
            Self::Cancelled => write!(f, "{}", cancel::Cancelled),
        }
    }
}

impl std::error::Error for PrepareError {}

impl From<cancel::Cancelled> for PrepareError {
    fn from(_: cancel::Cancelled) -> Self {
        Self::Cancelled
    }
}

impl From<CompileError> for PrepareError {
    fn from(e: CompileError) -> Self {
        Self::Compile(e)
    }
}

/// `f` of every item, in order, computed on up to as many scoped threads as
/// the machine has cores. The threads are joined before this returns: none
/// outlives the call (a host may unload the plugin's library right after a
/// compile, and a thread still running its code would crash the host; a
/// global thread pool would keep its threads). A panic in `f` is passed on.
/// \[worker\] \[main-thread\]
fn side_by_side<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = cores.min(items.len());
    if threads <= 1 {
        return items.iter().map(f).collect();
    }
    let per = items.len().div_ceil(threads);
    let f = &f;
    // the compile's cancellation goes along (crate::compile::cancel)
    let cancel = cancel::current();
    let cancel = cancel.as_ref();
    std::thread::scope(|scope| {
        let running: Vec<_> = items
            .chunks(per)
            .map(|chunk| {
                scope.spawn(move || {
                    cancel::within(cancel, || chunk.iter().map(f).collect::<Vec<R>>())
                })
            })
            .collect();
        running
            .into_iter()
            .flat_map(|t| t.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    })
}

/// Compile everything for `params` at `rate_hz` (eigendecompositions: never
/// call this on the audio thread). \[worker\] \[main-thread\]
pub fn prepare(
    params: &SceneParams,
    rate_hz: f64,
    revision: u64,
) -> Result<Box<Prepared>, PrepareError> {
    prepare_staged(params, rate_hz, revision, Stage::Full)
}

/// [`prepare`] of `stage`. \[worker\] \[main-thread\]
pub fn prepare_staged(
    params: &SceneParams,
    rate_hz: f64,
    revision: u64,
    stage: Stage,
) -> Result<Box<Prepared>, PrepareError> {
    let base = presets::scene(params.preset).map_err(CompileError::Scene)?;
    prepare_scene_staged(&base, params, rate_hz, revision, stage)
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
    prepare_scene_staged(base, params, rate_hz, revision, Stage::Full)
}

/// [`prepare_scene`] of `stage`. \[worker\] \[main-thread\]
pub fn prepare_scene_staged(
    base: &Scene,
    params: &SceneParams,
    rate_hz: f64,
    revision: u64,
    stage: Stage,
) -> Result<Box<Prepared>, PrepareError> {
    // the scene's own damper unless Custom damper is on: what is compiled,
    // and what the prepared params say is played
    let params = &params.resolved_for(base);
    let ip = InstrumentParams {
        scene: *params,
        play: PlayParams::default(),
    };
    let played_scene = scene_for(base, &ip);
    if played_scene.several_contacts() {
        return prepare_kit(base, &played_scene, params, (rate_hz, revision), stage);
    }
    let (scene, switching_used, fallback_note) =
        compile_with_fallback(&played_scene, rate_hz, params.switching)?;
    cancel::check()?;
    let damped = if params.damper_norm > 0.0 {
        let d = damped_scene(&played_scene, params.damper_norm);
        Some(compile_with(&d, rate_hz, Some(switching_used))?)
    } else {
        None
    };
    if let Some(d) = &damped {
        if d.free.dim != scene.free.dim || d.contact.dim != scene.contact.dim {
            return Err(PrepareError::DampedLayoutDiffers);
        }
    }
    let variants = Variants {
        base,
        played_scene: &played_scene,
        params,
        rate_hz,
        switching_used,
        scene: &scene,
        small: scene.contact.dim <= TIMBRE_MAX_STATES,
        stage,
    };
    let (played, played_left_out) = variants.played()?;
    let (damped_at, dampers_left_out) = variants.damped_at();
    let left_out = played_left_out | dampers_left_out;
    cancel::check()?;
    let scenes = Scenes {
        scene,
        damped,
        played,
        damped_at,
    };
    assemble(
        (base, params, rate_hz, revision),
        (switching_used, fallback_note),
        scenes,
        None,
        (stage, left_out),
    )
}

/// What the variants of one prepared scene are compiled from: the scene
/// as the instrument plays it, its parameters, and the played scene they
/// must lay their states out as.
struct Variants<'a> {
    /// The scene given (a preset or a user's file).
    base: &'a Scene,
    /// `base` with the parameters applied.
    played_scene: &'a Scene,
    /// The resolved parameters.
    params: &'a SceneParams,
    /// Sample rate \[Hz\].
    rate_hz: f64,
    /// The switching method the played scene compiled with.
    switching_used: Switching,
    /// The played scene, compiled.
    scene: &'a CompiledScene,
    /// Its contact system is small enough for variants
    /// ([`TIMBRE_MAX_STATES`]).
    small: bool,
    /// What is compiled now.
    stage: Stage,
}

impl Variants<'_> {
    /// Whether `t` lays its states out as the played scene does.
    fn same_layout(&self, t: &CompiledScene) -> bool {
        t.free.dim == self.scene.free.dim && t.contact.dim == self.scene.contact.dim
    }

    /// The played variants: every hardness level, and with the position
    /// levels every (hardness, position) pair; a variant that does not
    /// compile (a stiffness beyond the scene's limits) or lays its states
    /// out otherwise is left out (its voices play the nearest that
    /// exists). By [`cell`], and whether a playable stage left them out.
    /// \[worker\] \[main-thread\]
    fn played(&self) -> Result<(Vec<Option<VariantScene>>, bool), PrepareError> {
        let (params, scene) = (self.params, self.scene);
        let positions = params.variants.position && params.strike_pos_norm.is_some();
        let levels = -TIMBRE_LEVEL_MAX..=TIMBRE_LEVEL_MAX;
        let small = self.small;
        let mut pairs: Vec<(i8, i8)> = levels
            .clone()
            .flat_map(|h| levels.clone().map(move |pl| (h, pl)))
            .filter(|&(h, pl)| small && (h, pl) != (0, 0) && (pl == 0 || positions))
            .collect();
        // what a playable stage leaves out
        let mut left_out = false;
        if self.stage == Stage::Playable {
            left_out |= !pairs.is_empty();
            pairs.clear();
        }
        // compiled side by side (each is a compile of its own)
        let compiled: Vec<Option<VariantScene>> = side_by_side(&pairs, |&(h, pl)| {
            let mut p = *params;
            p.stiffness_factor *= TIMBRE_STIFFNESS_STEP.powi(i32::from(h));
            p.strike_pos_norm = p
                .strike_pos_norm
                .map(|x| (x + f64::from(pl) * POSITION_STEP).clamp(0.0, 1.0));
            let ip = InstrumentParams {
                scene: p,
                play: PlayParams::default(),
            };
            compile_with(
                &scene_for(self.base, &ip),
                self.rate_hz,
                Some(self.switching_used),
            )
            .ok()
            .filter(|t| self.same_layout(t))
            .map(|t| VariantScene {
                same_free: t.free.v == scene.free.v
                    && t.free.vinv == scene.free.vinv
                    && t.free.gens == scene.free.gens
                    && t.free.dense == scene.free.dense
                    && t.h == scene.h,
                scene: t,
            })
        });
        cancel::check()?;
        let mut played: Vec<Option<VariantScene>> = (0..LEVELS * LEVELS).map(|_| None).collect();
        for (&(h, pl), v) in pairs.iter().zip(compiled) {
            played[cell(h, pl)] = v;
        }
        Ok((played, left_out))
    }

    /// The damped scene at the other damper levels: `Some(None)` where the
    /// level's damper is 0. By [`slot`], and whether a playable stage left
    /// them out. \[worker\] \[main-thread\]
    fn damped_at(&self) -> (Vec<Option<Option<CompiledScene>>>, bool) {
        let params = self.params;
        let levels = -TIMBRE_LEVEL_MAX..=TIMBRE_LEVEL_MAX;
        let mut left_out = false;
        let mut dampers: Vec<i8> = if self.small && params.variants.damper {
            levels.filter(|&d| d != 0).collect()
        } else {
            Vec::new()
        };
        if self.stage == Stage::Playable {
            left_out |= !dampers.is_empty();
            dampers.clear();
        }
        let compiled: Vec<Option<Option<CompiledScene>>> = side_by_side(&dampers, |&d| {
            let value = (params.damper_norm + f64::from(d) * DAMPER_STEP).clamp(0.0, 1.0);
            if value > 0.0 {
                compile_with(
                    &damped_scene(self.played_scene, value),
                    self.rate_hz,
                    Some(self.switching_used),
                )
                .ok()
                .filter(|t| self.same_layout(t))
                .map(Some)
            } else {
                Some(None)
            }
        });
        let mut damped_at: Vec<Option<Option<CompiledScene>>> = (0..LEVELS).map(|_| None).collect();
        for (&d, v) in dampers.iter().zip(compiled) {
            damped_at[slot(d)] = v;
        }
        (damped_at, left_out)
    }
}

/// A [`Prepared`] of compiled scenes (and a kit), with a fresh engine
/// state per voice. \[worker\] \[main-thread\]
fn assemble(
    (base, params, rate_hz, revision): (&Scene, &SceneParams, f64, u64),
    (switching_used, fallback_note): (Switching, Option<String>),
    scenes: Scenes,
    kit: Option<Box<Kit>>,
    (stage, mut left_out): (Stage, bool),
) -> Result<Box<Prepared>, PrepareError> {
    // here, not on the audio thread: a voice rebound to a scene takes its
    // certified stored switches without a search (docs/numerics.md 6.9)
    for sc in scenes.all() {
        certify_rest_strike(sc);
    }
    let states = voice_states(&scenes.scene, rate_hz);
    let spares: Box<[EngineState]> = if kit.is_some() {
        Box::new([])
    } else {
        voice_states::<STEAL_FADES>(&scenes.scene, rate_hz)
    };
    let root = root_note(base);
    let sc = &scenes.scene;
    // a constant force on the hammer: its weight, or a hand pressing a
    // driven hammer (docs/design.md, "Rolling and scraping")
    let bouncing =
        base.hammer.gravity_m_per_s2 > 0.0 || base.drive.as_ref().is_some_and(|d| d.press_n > 0.0);
    let no_keys = kit.is_some() || sc.free.dense.is_some() || sc.contact.dense.is_some();
    let key_props = if no_keys {
        Vec::new()
    } else if stage == Stage::Playable {
        left_out = true;
        Vec::new()
    } else {
        // each key's strike from rest recorded with its propagators, checked
        // at the slowest and the fastest impact a note plays
        let speeds = [impact_speed_m_per_s(0.0), impact_speed_m_per_s(1.0)];
        let band = output_band_hz(rate_hz);
        (0..=127u8)
            .map(|key| {
                cancel::check()?;
                let mut k = ScaleProps::new(sc, key_scale(key, root), band);
                if !bouncing {
                    k.store_strike(sc, band, &speeds);
                }
                Ok(k)
            })
            .collect::<Result<_, cancel::Cancelled>>()?
    };
    cancel::check()?;
    Ok(Box::new(Prepared {
        revision,
        rate_hz,
        params: *params,
        root_note: root,
        bouncing,
        switching_used,
        fallback_note,
        scenes,
        states,
        spares,
        kit,
        key_props,
        complete: !left_out,
    }))
}

/// The voices' output band at `rate_hz` (modes above it are left out of
/// the outputs: [`EngineState::set_output_band`]). \[any-thread\]
fn output_band_hz(rate_hz: f64) -> f64 {
    OUTPUT_BAND_FRACTION * 0.5 * rate_hz
}

/// `N` fresh engine states for `scene` (one per voice, or the spares).
/// \[worker\] \[main-thread\]
fn voice_states<const N: usize>(scene: &CompiledScene, rate_hz: f64) -> Box<[EngineState; N]> {
    let band_hz = output_band_hz(rate_hz);
    let states: Vec<EngineState> = (0..N)
        .map(|_| {
            let mut st = EngineState::new(scene);
            st.set_output_band(scene, band_hz);
            // the live view observes voices on the audio thread: no
            // allocation there
            st.reserve_observation();
            st
        })
        .collect();
    let Ok(states) = <Box<[EngineState; N]>>::try_from(states.into_boxed_slice()) else {
        unreachable!("N states were made");
    };
    states
}

/// [`prepare_scene`] for a scene of several contacts (`played`, the
/// parameters applied): its kit, and the first mallet on its object alone
/// compiled for what the instrument reads of every scene (no voice plays
/// it). The kit switches as the Switching parameter says (an offset rod
/// per contact, or exactly). \[worker\] \[main-thread\]
/// A compile of a kit at other levels ([`prepare_kit`]).
#[derive(Clone, Copy)]
enum KitJob {
    /// At (hardness, position) levels.
    Played(i8, i8),
    /// Damped, at a damper level.
    Damped(i8),
}

fn prepare_kit(
    base: &Scene,
    played: &Scene,
    params: &SceneParams,
    (rate_hz, revision): (f64, u64),
    stage: Stage,
) -> Result<Box<Prepared>, PrepareError> {
    let mut kit = Kit::new(played, rate_hz, params.damper_norm).map_err(PrepareError::Kit)?;
    cancel::check()?;
    // the levels a note's brightness and a host's polyphonic modulation
    // play, as a scene of one contact has them (`Variants::played`,
    // `Variants::damped_at`): every mallet's spring (or law) times
    // TIMBRE_STIFFNESS_STEP^level, with the position levels at each when
    // asked for, and the damped compile at each damper level when asked
    // for; for phases of at most TIMBRE_MAX_STATES states; a playable
    // stage leaves them to the full one
    let small = kit.max_dim() <= TIMBRE_MAX_STATES;
    let positions = params.variants.position && params.strike_pos_norm.is_some();
    let levels = -TIMBRE_LEVEL_MAX..=TIMBRE_LEVEL_MAX;
    let mut jobs: Vec<KitJob> = levels
        .clone()
        .flat_map(|h| levels.clone().map(move |pl| KitJob::Played(h, pl)))
        .filter(
            |j| matches!(*j, KitJob::Played(h, pl) if (h, pl) != (0, 0) && (pl == 0 || positions)),
        )
        .collect();
    if params.variants.damper {
        jobs.extend(levels.filter(|&d| d != 0).map(KitJob::Damped));
    }
    if !small {
        jobs.clear();
    }
    let left_out = !jobs.is_empty() && stage == Stage::Playable;
    if stage == Stage::Playable {
        jobs.clear();
    }
    let switching = kit.sc.switching;
    let compiled = side_by_side(&jobs, |job| match *job {
        KitJob::Played(h, pl) => {
            let mut p = *params;
            p.stiffness_factor *= TIMBRE_STIFFNESS_STEP.powi(i32::from(h));
            p.strike_pos_norm = p
                .strike_pos_norm
                .map(|x| (x + f64::from(pl) * POSITION_STEP).clamp(0.0, 1.0));
            let ip = InstrumentParams {
                scene: p,
                play: PlayParams::default(),
            };
            Kit::compile_scene(&scene_for(base, &ip), rate_hz, switching)
                .ok()
                .map(Some)
        }
        KitJob::Damped(d) => {
            let value = (params.damper_norm + f64::from(d) * DAMPER_STEP).clamp(0.0, 1.0);
            if value > 0.0 {
                Kit::compile_scene(&damped_scene(played, value), rate_hz, switching)
                    .ok()
                    .map(Some)
            } else {
                Some(None)
            }
        }
    });
    cancel::check()?;
    let (mut at_levels, mut at_dampers) = (Vec::new(), Vec::new());
    for (job, c) in jobs.into_iter().zip(compiled) {
        match (job, c) {
            (KitJob::Played(h, pl), Some(Some(c))) => at_levels.push(((h, pl), c)),
            (KitJob::Damped(d), Some(c)) => at_dampers.push((d, c)),
            _ => {}
        }
    }
    kit.set_levels(at_levels, at_dampers);
    let mut alone = played.clone();
    alone.striker.clear();
    alone.touch.clear();
    alone.hammer.notes.clear();
    // a law's first piece: the contact as it touches
    if let Some(law) = alone.contact.law.take() {
        let pieces = law.pieces("contact.law").map_err(PrepareError::Kit)?;
        alone.contact.stiffness_n_per_m = pieces.stiffness[0];
    }
    let used = kit.sc.switching;
    let scene = compile_with(&alone, rate_hz, Some(used))?;
    let scenes = Scenes {
        scene,
        damped: None,
        played: (0..LEVELS * LEVELS).map(|_| None).collect(),
        damped_at: (0..LEVELS).map(|_| None).collect(),
    };
    assemble(
        (base, params, rate_hz, revision),
        (used, None),
        scenes,
        Some(Box::new(kit)),
        (Stage::Full, left_out),
    )
}
