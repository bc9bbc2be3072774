//! The playable instrument: MIDI-like strikes on a compiled scene, with voices,
//! pitch, a damper, voice stealing, silence detection and the realtime swap of
//! recompiled scenes. Pure library code: no plugin types, no threads, no
//! atomics. The plugin (`crate::plugin`) and the tests drive the same
//! [`Instrument`] with the same [`Event`]s, so a test can compare the plugin's
//! output with a direct render sample by sample.
//!
//! # Mappings
//!
//! - **Velocity -> impact speed** ([`impact_speed_m_per_s`]):
//!   `v = 0.05 + 2.95 * vel^2` m/s for `vel` in 0..1 (MIDI velocity / 127), so
//!   the softest note hits at 5 cm/s and the hardest at 3 m/s; the square gives
//!   the usual "more range at the top" feel. A note-on at velocity 0 (or not
//!   a number) is a note-off, as in MIDI. The contact is linear, so the
//!   output amplitude is proportional to `v` (up to the hammer's bounce).
//!   The hammer is launched from the surface of the object (height 0 above the
//!   contact point's current displacement) moving down at `v`: contact starts
//!   one sample after the note. In a bouncing scene (gravity > 0) it is dropped
//!   from the drop height instead, with the same downward speed.
//! - **Note -> pitch**: the voice runs the scene with its time axis scaled by
//!   `s = 2^((note - root) / 12)` ([`EngineState::set_time_scale`]): every
//!   modal frequency times `s`, every decay time over `s`, contact stiffness
//!   times `s^2`, contact damping times `s`, gravity times `s^2`, hammer mass
//!   kept. That is exactly the same physical system played back `s` times
//!   faster, so the timbre (the ratio of contact time to period, the decay in
//!   periods, the bounce pattern) is the same at every pitch. It costs O(N) at
//!   note-on and no compile. The root note ([`root_note`]) is the MIDI note
//!   nearest the scene's lowest modal frequency (60 when it has none), so
//!   playing the root gives the scene as written. If the scene uses the
//!   compiler's dense fallback the engine cannot scale time: that voice plays
//!   at `s = 1` (counted in [`Stats::dense_pitch_fallbacks`]).
//! - **Damper**: on note-off the voice is carried ([`EngineState::rebind`],
//!   no energy increase) onto a "damped" compilation of the same scene whose
//!   decay times are divided by `1 + 50 * damper` ([`damped_scene`]). A new
//!   note on the same key carries it back. Damper 0 means no damping on
//!   release (the bar rings on, as a struck bar does).
//! - **Voices**: one voice per note, [`MAX_VOICES`] of them. A repeated note
//!   strikes its own voice again while it rings: the hammer hits the moving
//!   surface ([`EngineState::strike`]). A new note takes a free voice, else
//!   steals the quietest one (lowest energy). A voice whose energy falls below
//!   [`SILENCE_ENERGY_RATIO`] of its strike's energy (checked every
//!   [`CHECK_INTERVAL_SAMPLES`] samples of the instrument's own clock, so the
//!   result does not depend on how the host splits blocks) stops and costs
//!   nothing.
//! - **Swap**: [`Instrument::install`] takes a freshly compiled [`Prepared`]
//!   at a block boundary. Each running voice is carried over with
//!   [`EngineState::rebind`]; the running state is moved into the new box (a
//!   pointer swap per voice, no allocation). If a voice cannot be carried (other
//!   preset, other mode count, dense fallback at s != 1) it is faded out over
//!   [`FADE_S`] on the old scene instead of being cut, and a new note starts
//!   clean on the new one. Old boxes go to fixed [`Instrument::retired_slots_mut`]
//!   for the caller to hand back to a non-realtime thread: nothing is dropped
//!   here.

use crate::compile::{compile_with, CompileError, CompiledScene};
use crate::engine::denormal::FlushDenormals;
use crate::engine::{EngineState, TimeScaleError};
use crate::presets;
use crate::scene::{ObjectSpec, Scene, Switching};

/// Number of voices (one per sounding note).
pub const MAX_VOICES: usize = 16;
/// Voices are checked for silence on this grid of the instrument's own sample
/// clock (a power of two; 64 samples = 1.5 ms at 44.1 kHz).
pub const CHECK_INTERVAL_SAMPLES: usize = 64;
/// A voice stops when its energy is below this fraction of its strike's
/// energy: -90 dB, far below audibility after a full-scale strike.
pub const SILENCE_ENERGY_RATIO: f64 = 1e-9;
/// Fade-out length for voices that cannot be carried across a swap \[s\]
/// (5 ms: short enough to feel immediate, long enough not to click).
pub const FADE_S: f64 = 0.005;
/// Released decay times are divided by `1 + DAMPER_T60_DIVISOR * damper`
/// (damper 1 = 51 times shorter: a felt damper on a bar).
pub const DAMPER_T60_DIVISOR: f64 = 50.0;
/// Modes without damping get this T60 \[s\] before the damper divides it
/// (they would otherwise ring forever after release).
pub const UNDAMPED_RELEASE_T60_S: f64 = 20.0;
/// Slowest impact speed (velocity 0) \[m/s\].
pub const MIN_IMPACT_SPEED_M_PER_S: f64 = 0.05;
/// Impact speed added at full velocity \[m/s\] (velocity 1 gives 3 m/s).
pub const IMPACT_SPEED_RANGE_M_PER_S: f64 = 2.95;
/// Hard output ceiling: no sample the instrument writes exceeds this in
/// magnitude (4.0 = +12 dBFS). It is a last-resort guard against abuse
/// (hundreds of full-velocity strikes piling energy into one ringing object
/// at full gain): playing the presets never reaches it (the plugin tests
/// count the samples it touches). A sample that would be larger is written
/// at the ceiling with its sign and counted in [`Stats::ceiling_hits`].
pub const OUTPUT_CEILING: f64 = 4.0;
/// Each voice hears the modes of its object up to this fraction of the
/// Nyquist frequency, at the voice's pitch ([`EngineState::set_output_band`]):
/// a note pitched up leaves its top modes out of the output instead of
/// aliasing them back into the audio band. The dynamics keep every mode.
pub const OUTPUT_BAND_FRACTION: f64 = 1.0;
/// Root note of scenes without modal frequencies (middle C).
pub const DEFAULT_ROOT_NOTE: f64 = 60.0;
/// Fixed slots for retired compiled scenes waiting to be handed back.
pub const RETIRED_SLOTS: usize = 4;

/// Velocity (0..1) to the hammer's impact speed \[m/s\]: `0.05 + 2.95 vel^2`.
/// \[any-thread\]
pub fn impact_speed_m_per_s(velocity_norm: f64) -> f64 {
    let v = if velocity_norm.is_finite() {
        velocity_norm.clamp(0.0, 1.0)
    } else {
        0.0
    };
    MIN_IMPACT_SPEED_M_PER_S + IMPACT_SPEED_RANGE_M_PER_S * v * v
}

/// Parameters that change the compiled scene (a change needs a recompile on
/// the worker).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneParams {
    /// Index into [`presets::PRESETS`].
    pub preset: usize,
    /// Hammer mass multiplier.
    pub hammer_mass_factor: f64,
    /// Contact stiffness multiplier (hardness).
    pub stiffness_factor: f64,
    /// Contact damping multiplier.
    pub damping_factor: f64,
    /// Strike position along the object, 0..1; `None` = the scene's contact point.
    pub strike_pos_norm: Option<f64>,
    /// Decay time multiplier (T60 times it; Rayleigh damping over it).
    pub decay_scale: f64,
    /// Damper strength after note-off, 0..1.
    pub damper_norm: f64,
    /// Gravity for bouncing scenes (scenes whose hammer has gravity) \[m/s^2\].
    pub gravity_m_per_s2: f64,
    /// Switching method (exact falls back to offset-rod if the compiler refuses it).
    pub switching: Switching,
}

impl Default for SceneParams {
    fn default() -> Self {
        Self {
            preset: presets::index_of("marimba-bar").unwrap_or(0),
            hammer_mass_factor: 1.0,
            stiffness_factor: 1.0,
            damping_factor: 1.0,
            strike_pos_norm: None,
            decay_scale: 1.0,
            damper_norm: 0.5,
            gravity_m_per_s2: 9.81,
            switching: Switching::Exact,
        }
    }
}

/// Parameters read at note-on or per sample (no recompile).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlayParams {
    /// Notes scale the time axis (pitch); off = every note plays the root.
    pub pitch_tracking: bool,
    /// Drop height for bouncing scenes \[m\].
    pub drop_height_m: f64,
    /// Output gain \[dB\].
    pub gain_db: f64,
}

impl Default for PlayParams {
    fn default() -> Self {
        Self {
            pitch_tracking: true,
            drop_height_m: 0.02,
            gain_db: -6.0,
        }
    }
}

/// All instrument parameters.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InstrumentParams {
    /// What needs a compile.
    pub scene: SceneParams,
    /// What does not.
    pub play: PlayParams,
}

fn positive_or(v: f64, fallback: f64) -> f64 {
    if v.is_finite() && v > 0.0 {
        v
    } else {
        fallback
    }
}

/// The scene a parameter set describes (pure; allocates).
///
/// - hammer mass, contact stiffness and contact damping are multiplied by
///   their factors;
/// - decay scale: every T60 is multiplied by it, a string's Rayleigh
///   `alpha`, `beta` and dashpots are divided by it;
/// - strike position (when `Some`): on a string, the contact point moves to
///   mass `round(pos * (masses - 1))`; on a modal object with at least 3
///   points, the points in their listed order are taken as evenly spaced
///   samples of the striking line and each mode's contact weight becomes the
///   linear interpolation of its weights at `pos * (points - 1)`; objects
///   with fewer points (and walls) ignore it;
/// - gravity: scenes whose hammer has gravity (bouncing scenes) get the
///   parameter's value; others stay without gravity;
/// - switching is set in the scene's contact section.
///
/// \[any-thread\]
pub fn scene_for(base: &Scene, p: &InstrumentParams) -> Scene {
    let sp = &p.scene;
    let mut s = base.clone();
    s.hammer.mass_kg *= positive_or(sp.hammer_mass_factor, 1.0);
    s.contact.stiffness_n_per_m *= positive_or(sp.stiffness_factor, 1.0);
    let cf = if sp.damping_factor.is_finite() && sp.damping_factor >= 0.0 {
        sp.damping_factor
    } else {
        1.0
    };
    s.contact.damping_n_s_per_m *= cf;
    let ds = positive_or(sp.decay_scale, 1.0);
    for obj in &mut s.object {
        match obj {
            ObjectSpec::Modal(m) => {
                for mode in &mut m.mode {
                    if let Some(t) = mode.t60_s.as_mut() {
                        *t *= ds;
                    }
                }
            }
            ObjectSpec::String(st) => {
                st.rayleigh_alpha_per_s /= ds;
                st.rayleigh_beta_s /= ds;
                for d in &mut st.dashpots {
                    d.n_s_per_m /= ds;
                }
            }
            ObjectSpec::Wall(_) => {}
        }
    }
    if let Some(pos) = sp.strike_pos_norm {
        let pos = if pos.is_finite() {
            pos.clamp(0.0, 1.0)
        } else {
            0.5
        };
        set_strike_position(&mut s, pos);
    }
    if base.hammer.gravity_m_per_s2 > 0.0 {
        s.hammer.gravity_m_per_s2 = positive_or(sp.gravity_m_per_s2, base.hammer.gravity_m_per_s2);
    }
    s.contact.switching = Some(sp.switching);
    s
}

fn set_strike_position(s: &mut Scene, pos: f64) {
    let Some(point) = s.contact.point.clone() else {
        return;
    };
    let Some(ci) = s.object_index(&s.contact.object) else {
        return;
    };
    match &mut s.object[ci] {
        ObjectSpec::String(st) => {
            if st.masses == 0 {
                return;
            }
            let idx = (pos * (st.masses - 1) as f64).round() as usize;
            st.points.insert(point, idx.min(st.masses - 1));
        }
        ObjectSpec::Modal(m) => {
            let n_pts = m.points.len();
            if n_pts < 3 {
                return;
            }
            let Some(pi) = m.points.iter().position(|p| *p == point) else {
                return;
            };
            let x = pos * (n_pts - 1) as f64;
            let i0 = (x.floor() as usize).min(n_pts - 2);
            let frac = x - i0 as f64;
            for mode in &mut m.mode {
                if mode.weights.len() != n_pts {
                    continue;
                }
                let w = mode.weights[i0] * (1.0 - frac) + mode.weights[i0 + 1] * frac;
                mode.weights[pi] = w;
            }
        }
        ObjectSpec::Wall(_) => {}
    }
}

/// The scene a released voice continues on: every decay time divided by
/// `1 + 50 * damper` (T60s of modal objects; a string's Rayleigh damping and
/// dashpots multiplied by the same factor; undamped modes get
/// [`UNDAMPED_RELEASE_T60_S`] first). Same objects, same dimensions, so
/// [`EngineState::rebind`] carries a voice onto it. \[any-thread\]
pub fn damped_scene(scene: &Scene, damper_norm: f64) -> Scene {
    let f = 1.0 + DAMPER_T60_DIVISOR * damper_norm.clamp(0.0, 1.0);
    let mut s = scene.clone();
    for obj in &mut s.object {
        match obj {
            ObjectSpec::Modal(m) => {
                for mode in &mut m.mode {
                    let t = mode.t60_s.unwrap_or(UNDAMPED_RELEASE_T60_S);
                    mode.t60_s = Some(t / f);
                }
            }
            ObjectSpec::String(st) => {
                st.rayleigh_alpha_per_s *= f;
                st.rayleigh_beta_s *= f;
                for d in &mut st.dashpots {
                    d.n_s_per_m *= f;
                }
            }
            ObjectSpec::Wall(_) => {}
        }
    }
    s
}

/// Lowest modal frequency of the struck object \[Hz\], if it has one (a
/// string's lowest mode from `omega_1 = 2 sqrt(s/m) sin(pi / (2 (n + 1)))`,
/// damping neglected). \[any-thread\]
pub fn lowest_frequency_hz(scene: &Scene) -> Option<f64> {
    let ci = scene.object_index(&scene.contact.object)?;
    match &scene.object[ci] {
        ObjectSpec::Modal(m) => m
            .mode
            .iter()
            .map(|x| x.freq_hz)
            .filter(|f| f.is_finite() && *f > 0.0)
            .min_by(|a, b| a.total_cmp(b)),
        ObjectSpec::String(st) => {
            let w1 = 2.0
                * (st.spring_n_per_m / st.mass_kg).sqrt()
                * (std::f64::consts::PI / (2.0 * (st.masses as f64 + 1.0))).sin();
            let f = w1 / (2.0 * std::f64::consts::PI);
            (f.is_finite() && f > 0.0).then_some(f)
        }
        ObjectSpec::Wall(_) => None,
    }
}

/// The MIDI note nearest the scene's lowest modal frequency (60 when unknown).
/// \[any-thread\]
pub fn root_note(scene: &Scene) -> f64 {
    match lowest_frequency_hz(scene) {
        Some(f) => (69.0 + 12.0 * (f / 440.0).log2()).round().clamp(0.0, 127.0),
        None => DEFAULT_ROOT_NOTE,
    }
}

/// Everything the audio thread needs for one parameter set, built off the
/// audio thread: the compiled scene, its damped variant, and a fresh engine
/// state per voice (so a swap to new dimensions allocates nothing).
pub struct Prepared {
    /// Request revision this was built for.
    pub revision: u64,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// The parameters it was built from.
    pub params: SceneParams,
    /// The scene as played.
    pub scene: CompiledScene,
    /// Released voices continue on this (`None` when the damper is 0).
    pub damped: Option<CompiledScene>,
    /// MIDI note that plays the scene as written.
    pub root_note: f64,
    /// The hammer has gravity (it is dropped, it bounces).
    pub bouncing: bool,
    /// The switching method actually compiled.
    pub switching_used: Switching,
    /// Set when the requested switching was refused and the fallback used.
    pub fallback_note: Option<String>,
    states: [EngineState; MAX_VOICES],
}

impl Prepared {
    /// A warning when the scene's exact event search may cost more than a
    /// sample period in a sample that holds a switch (the compile summary's
    /// estimate, at the root pitch: higher notes step further per sample and
    /// cost more). The engine keeps the physics exact whatever it costs; the
    /// warning tells the user where CPU spikes come from. \[worker\]
    pub fn realtime_warning(&self) -> Option<String> {
        let n = self.scene.search_nodes_estimate;
        (n > crate::compile::REALTIME_SEARCH_NODES).then(|| {
            let line = self
                .scene
                .summary
                .lines()
                .find(|l| l.starts_with("event search"))
                .unwrap_or("");
            format!(
                "scene {:?}: the contact is stiff enough that a sample holding a switch may take longer than a sample period (about {n:.0} event-search nodes per sample; exact switching stays exact, expect CPU spikes at small buffer sizes; lower Hardness or raise Hammer mass to reduce it). {line}",
                self.scene.name
            )
        })
    }
}

impl std::fmt::Debug for Prepared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prepared")
            .field("revision", &self.revision)
            .field("rate_hz", &self.rate_hz)
            .field("scene", &self.scene.name)
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
    let ip = InstrumentParams {
        scene: *params,
        play: PlayParams::default(),
    };
    let played = scene_for(&base, &ip);
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
    let band_hz = OUTPUT_BAND_FRACTION * 0.5 * rate_hz;
    let states = std::array::from_fn(|_| {
        let mut st = EngineState::new(&scene);
        st.set_output_band(&scene, band_hz);
        st
    });
    Ok(Box::new(Prepared {
        revision,
        rate_hz,
        params: *params,
        root_note: root_note(&base),
        bouncing: base.hammer.gravity_m_per_s2 > 0.0,
        switching_used,
        fallback_note,
        scene,
        damped,
        states,
    }))
}

/// What a host sends: notes. Times are sample offsets within the block
/// passed to [`Instrument::process`] (or the caller renders up to the event
/// with [`Instrument::render`] and then calls [`Instrument::handle`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// Strike `key` with `velocity_norm` in 0..1.
    NoteOn {
        /// MIDI key.
        key: u8,
        /// Velocity 0..1 (MIDI velocity / 127).
        velocity_norm: f64,
    },
    /// Release `key` (the damper falls).
    NoteOff {
        /// MIDI key.
        key: u8,
    },
    /// Release every voice.
    AllNotesOff,
}

/// An event at a sample offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedEvent {
    /// Sample offset within the rendered span.
    pub offset: usize,
    /// The event.
    pub event: Event,
}

/// Counters for tests and diagnostics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Scenes installed by [`Instrument::install`].
    pub swaps: u64,
    /// Voices carried across a swap by `rebind`.
    pub voices_carried: u64,
    /// Voices that could not be carried and were faded out.
    pub voices_faded: u64,
    /// Notes that stole a sounding voice.
    pub steals: u64,
    /// Voices reset because they produced a non-finite sample.
    pub nonfinite_resets: u64,
    /// Notes played at s = 1 because the scene uses the dense fallback.
    pub dense_pitch_fallbacks: u64,
    /// Voices stopped because they fell silent.
    pub silent_stops: u64,
    /// Note-ons.
    pub notes: u64,
    /// Output samples that reached [`OUTPUT_CEILING`] (or were not finite
    /// after mixing, written as 0).
    pub ceiling_hits: u64,
}

#[derive(Debug, Clone, Copy, Default)]
struct Voice {
    active: bool,
    key: u8,
    released: bool,
    /// Bound to `Prepared::damped` rather than `Prepared::scene`.
    on_damped: bool,
    /// Energy of the last strike (reference units), for the silence test.
    strike_energy: f64,
}

fn bound(p: &Prepared, on_damped: bool) -> &CompiledScene {
    match (&p.damped, on_damped) {
        (Some(d), true) => d,
        _ => &p.scene,
    }
}

/// The instrument (owned by the audio thread). Everything it does after
/// [`Instrument::new`] is allocation-free.
pub struct Instrument {
    cur: Box<Prepared>,
    voices: [Voice; MAX_VOICES],
    /// Previous scene while voices that could not be carried fade out.
    fading: Option<Box<Prepared>>,
    /// Which voices of `fading` sound, and whether each is on its damped scene.
    fade_voices: [Option<bool>; MAX_VOICES],
    fade_left: usize,
    fade_len: usize,
    retired: [Option<Box<Prepared>>; RETIRED_SLOTS],
    play: PlayParams,
    gain: f64,
    sample_pos: u64,
    acc: [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    vbuf: [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    /// Counters.
    pub stats: Stats,
}

impl Instrument {
    /// Start with a prepared scene. \[main-thread\]
    pub fn new(prepared: Box<Prepared>, play: PlayParams) -> Self {
        let fade_len = ((FADE_S * prepared.rate_hz).round() as usize).max(1);
        let mut inst = Self {
            cur: prepared,
            voices: [Voice::default(); MAX_VOICES],
            fading: None,
            fade_voices: [None; MAX_VOICES],
            fade_left: 0,
            fade_len,
            retired: Default::default(),
            play,
            gain: 1.0,
            sample_pos: 0,
            acc: [[0.0; CHECK_INTERVAL_SAMPLES]; 2],
            vbuf: [[0.0; CHECK_INTERVAL_SAMPLES]; 2],
            stats: Stats::default(),
        };
        inst.set_play(play);
        inst
    }

    /// The scene set currently played. \[audio-thread\]
    pub fn prepared(&self) -> &Prepared {
        &self.cur
    }

    /// Update the parameters that need no compile (gain now; pitch tracking
    /// and drop height at the next note). \[audio-thread\]
    pub fn set_play(&mut self, play: PlayParams) {
        self.play = play;
        let g = 10f64.powf(play.gain_db / 20.0);
        self.gain = if g.is_finite() { g } else { 0.0 };
    }

    /// The engine state of voice `voice_idx` (for tests and tools, e.g. to
    /// inspect or disturb a voice). \[audio-thread\]
    pub fn voice_state_mut(&mut self, voice_idx: usize) -> &mut EngineState {
        &mut self.cur.states[voice_idx]
    }

    /// Number of sounding voices (fading ones not counted). \[audio-thread\]
    pub fn active_voices(&self) -> usize {
        self.voices.iter().filter(|v| v.active).count()
    }

    /// Keys of the sounding voices, by voice index. \[audio-thread\]
    pub fn voice_keys(&self) -> [Option<u8>; MAX_VOICES] {
        std::array::from_fn(|i| self.voices[i].active.then_some(self.voices[i].key))
    }

    /// Whether [`install`](Self::install) would accept a scene now (no fade
    /// in progress and a free retired slot). \[audio-thread\]
    pub fn can_install(&self) -> bool {
        self.fading.is_none() && self.retired.iter().any(|s| s.is_none())
    }

    /// Retired scenes waiting to be handed back: the caller takes them out
    /// (and puts them back if its return queue is full). \[audio-thread\]
    pub fn retired_slots_mut(&mut self) -> &mut [Option<Box<Prepared>>] {
        &mut self.retired
    }

    /// Swap in a recompiled scene at a block boundary, carrying every voice
    /// (see the module doc). Returns the box unused if it cannot be taken now
    /// ([`can_install`](Self::can_install) is false). O(MAX_VOICES N^2),
    /// allocation-free. \[audio-thread\]
    pub fn install(&mut self, mut new: Box<Prepared>) -> Result<(), Box<Prepared>> {
        if !self.can_install() {
            return Err(new);
        }
        let same_object =
            new.params.preset == self.cur.params.preset && new.rate_hz == self.cur.rate_hz;
        let mut any_fade = false;
        for i in 0..MAX_VOICES {
            let v = &mut self.voices[i];
            if !v.active {
                continue;
            }
            let to_damped = v.released && new.damped.is_some();
            let carried = same_object && {
                let Prepared {
                    states,
                    scene,
                    damped,
                    ..
                } = &mut *self.cur;
                let from = match (&*damped, v.on_damped) {
                    (Some(d), true) => d,
                    _ => &*scene,
                };
                let ok = states[i].rebind(from, bound(&new, to_damped));
                if ok {
                    // The running state moves into the new box; the new box's
                    // fresh state goes back with the old one.
                    std::mem::swap(&mut states[i], &mut new.states[i]);
                }
                ok
            };
            let v = &mut self.voices[i];
            if carried {
                v.on_damped = to_damped;
                self.stats.voices_carried += 1;
            } else {
                self.fade_voices[i] = Some(v.on_damped);
                v.active = false;
                any_fade = true;
                self.stats.voices_faded += 1;
            }
        }
        let old = std::mem::replace(&mut self.cur, new);
        self.stats.swaps += 1;
        if any_fade {
            self.fading = Some(old);
            self.fade_left = self.fade_len;
        } else {
            self.retire(old);
        }
        Ok(())
    }

    fn retire(&mut self, b: Box<Prepared>) {
        if let Some(slot) = self.retired.iter_mut().find(|s| s.is_none()) {
            *slot = Some(b);
        } else {
            // Unreachable through `install` (it checks for a free slot); keep
            // it fading (silent) rather than dropping it here.
            self.fading = Some(b);
            self.fade_voices = [None; MAX_VOICES];
            self.fade_left = 0;
        }
    }

    /// Stop every voice at once (host reset). Allocation-free. \[audio-thread\]
    pub fn silence(&mut self) {
        self.voices = [Voice::default(); MAX_VOICES];
        self.fade_voices = [None; MAX_VOICES];
        self.fade_left = 0;
    }

    /// Apply one event now (between two samples). \[audio-thread\]
    pub fn handle(&mut self, event: Event) {
        match event {
            // MIDI's convention: a note-on at velocity 0 is a note-off (and
            // a velocity that is not a number strikes nothing).
            Event::NoteOn { key, velocity_norm } if !(velocity_norm > 0.0) => {
                self.note_off(Some(key))
            }
            Event::NoteOn { key, velocity_norm } => self.note_on(key, velocity_norm),
            Event::NoteOff { key } => self.note_off(Some(key)),
            Event::AllNotesOff => self.note_off(None),
        }
    }

    fn note_on(&mut self, key: u8, velocity_norm: f64) {
        self.stats.notes += 1;
        let speed = impact_speed_m_per_s(velocity_norm);
        let p = &mut *self.cur;
        let idx = if let Some(i) = self.voices.iter().position(|v| v.active && v.key == key) {
            // Same key still ringing: strike the moving object again.
            let v = &mut self.voices[i];
            if v.on_damped {
                let ok = match &p.damped {
                    Some(d) => p.states[i].rebind(d, &p.scene),
                    None => true,
                };
                if !ok {
                    p.states[i].reset(&p.scene);
                }
                v.on_damped = false;
            }
            v.released = false;
            i
        } else {
            let i = match self.voices.iter().position(|v| !v.active) {
                Some(i) => i,
                None => {
                    self.stats.steals += 1;
                    quietest(p, &self.voices)
                }
            };
            let st = &mut p.states[i];
            st.reset(&p.scene);
            let s = if self.play.pitch_tracking {
                2f64.powf((key as f64 - p.root_note) / 12.0)
            } else {
                1.0
            };
            match st.set_time_scale(&p.scene, s) {
                Ok(()) => {}
                Err(TimeScaleError::DenseFallback) | Err(TimeScaleError::Invalid) => {
                    self.stats.dense_pitch_fallbacks += u64::from(s != 1.0);
                    let _ = st.set_time_scale(&p.scene, 1.0);
                }
            }
            st.reset(&p.scene);
            self.voices[i] = Voice {
                active: true,
                key,
                released: false,
                on_damped: false,
                strike_energy: 0.0,
            };
            i
        };
        let st = &mut p.states[idx];
        let s = st.time_scale();
        let v_ref = speed / s;
        let m_h = p.scene.m_h;
        let mut e = 0.5 * m_h * v_ref * v_ref;
        if p.bouncing {
            let h = self.play.drop_height_m.max(0.0);
            st.strike(&p.scene, h, -speed);
            e += m_h * p.scene.g * h;
        } else {
            st.strike(&p.scene, 0.0, -speed);
        }
        self.voices[idx].strike_energy = e;
    }

    fn note_off(&mut self, key: Option<u8>) {
        let p = &mut *self.cur;
        for (i, v) in self.voices.iter_mut().enumerate() {
            if !v.active || v.released || key.is_some_and(|k| k != v.key) {
                continue;
            }
            v.released = true;
            if let Some(d) = &p.damped {
                if p.states[i].rebind(&p.scene, d) {
                    v.on_damped = true;
                }
            }
        }
    }

    /// Render consecutive samples into `left`/`right` (overwritten).
    /// Allocation-free. \[audio-thread\]
    pub fn render(&mut self, left: &mut [f32], right: &mut [f32]) {
        let n = left.len().min(right.len());
        let mut i = 0;
        while i < n {
            let phase = (self.sample_pos % CHECK_INTERVAL_SAMPLES as u64) as usize;
            let len = (CHECK_INTERVAL_SAMPLES - phase).min(n - i);
            self.render_chunk(&mut left[i..i + len], &mut right[i..i + len]);
            i += len;
            self.sample_pos += len as u64;
            if self
                .sample_pos
                .is_multiple_of(CHECK_INTERVAL_SAMPLES as u64)
            {
                self.stop_silent_voices();
            }
        }
    }

    /// Render `left.len()` samples, applying `events` (sorted by offset, offsets
    /// within the span) at their sample offsets. \[audio-thread\]
    pub fn process(&mut self, events: &[TimedEvent], left: &mut [f32], right: &mut [f32]) {
        // Subnormals off for the whole block (each voice's engine would set
        // it too; once here, the voices find it on and leave it).
        let _flush = FlushDenormals::new(true);
        let n = left.len().min(right.len());
        let mut pos = 0;
        for ev in events {
            let at = ev.offset.clamp(pos, n);
            self.render(&mut left[pos..at], &mut right[pos..at]);
            pos = at;
            self.handle(ev.event);
        }
        self.render(&mut left[pos..n], &mut right[pos..n]);
    }

    fn render_chunk(&mut self, left: &mut [f32], right: &mut [f32]) {
        let len = left.len();
        for ch in &mut self.acc {
            ch[..len].iter_mut().for_each(|x| *x = 0.0);
        }
        let p = &mut *self.cur;
        for i in 0..MAX_VOICES {
            let v = &mut self.voices[i];
            if !v.active {
                continue;
            }
            let scene = match (&p.damped, v.on_damped) {
                (Some(d), true) => d,
                _ => &p.scene,
            };
            let st = &mut p.states[i];
            if tick_into(st, scene, &mut self.vbuf, len, 1.0, 0.0) {
                add_into(&mut self.acc, &self.vbuf, len);
            } else {
                st.reset(&p.scene);
                v.active = false;
                self.stats.nonfinite_resets += 1;
            }
        }
        if let Some(f) = self.fading.as_deref_mut() {
            for i in 0..MAX_VOICES {
                let Some(on_damped) = self.fade_voices[i] else {
                    continue;
                };
                if self.fade_left == 0 {
                    break;
                }
                let scene = match (&f.damped, on_damped) {
                    (Some(d), true) => d,
                    _ => &f.scene,
                };
                let g0 = self.fade_left as f64 / self.fade_len as f64;
                let dg = 1.0 / self.fade_len as f64;
                if tick_into(&mut f.states[i], scene, &mut self.vbuf, len, g0, dg) {
                    add_into(&mut self.acc, &self.vbuf, len);
                } else {
                    self.fade_voices[i] = None;
                    self.stats.nonfinite_resets += 1;
                }
            }
            self.fade_left = self.fade_left.saturating_sub(len);
            if self.fade_left == 0 {
                self.fade_voices = [None; MAX_VOICES];
                if let Some(slot) = self.retired.iter_mut().find(|s| s.is_none()) {
                    *slot = self.fading.take();
                }
            }
        }
        let g = self.gain;
        let mut hits = 0u64;
        for k in 0..len {
            left[k] = guarded(self.acc[0][k] * g, &mut hits);
            right[k] = guarded(self.acc[1][k] * g, &mut hits);
        }
        self.stats.ceiling_hits += hits;
    }

    fn stop_silent_voices(&mut self) {
        let p = &*self.cur;
        for (i, v) in self.voices.iter_mut().enumerate() {
            if !v.active {
                continue;
            }
            let scene = bound(p, v.on_damped);
            if let Some(e) = audible_energy(&p.states[i], scene) {
                if e < SILENCE_ENERGY_RATIO * v.strike_energy {
                    v.active = false;
                    self.stats.silent_stops += 1;
                }
            }
        }
    }
}

/// Energy that decides whether a voice still sounds (reference units), or
/// `None` while the hammer is still on its way (the strike is to come).
fn audible_energy(st: &EngineState, scene: &CompiledScene) -> Option<f64> {
    let proxy = st.energy_proxy(scene);
    if st.in_contact() {
        return Some(proxy);
    }
    let (_, v_phys) = st.hammer_in_flight()?;
    let v_ref = v_phys / st.time_scale();
    if scene.g > 0.0 {
        // Falling hammer: its height above the surface is energy to come.
        let above = (-st.penetration(scene)).max(0.0);
        Some(proxy + scene.m_h * scene.g * above)
    } else if v_ref < 0.0 {
        None
    } else {
        // The hammer flies away for good: only the object sounds.
        Some((proxy - 0.5 * scene.m_h * v_ref * v_ref).max(0.0))
    }
}

/// The output guard: `x` when within [`OUTPUT_CEILING`], else the ceiling
/// with `x`'s sign (0 for NaN), counted in `hits`.
#[inline]
fn guarded(x: f64, hits: &mut u64) -> f32 {
    if x.abs() <= OUTPUT_CEILING {
        x as f32
    } else {
        *hits += 1;
        if x.is_nan() {
            0.0
        } else {
            OUTPUT_CEILING.copysign(x) as f32
        }
    }
}

fn quietest(p: &Prepared, voices: &[Voice; MAX_VOICES]) -> usize {
    let mut best = 0;
    let mut best_e = f64::INFINITY;
    for (i, v) in voices.iter().enumerate() {
        let s = p.states[i].time_scale();
        let e = p.states[i].energy_proxy(bound(p, v.on_damped)) * s * s;
        if !(e >= best_e) {
            best = i;
            best_e = e;
        }
    }
    best
}

/// Tick `len` samples of one voice into `buf` with a linear gain ramp
/// `g0 - k dg`; false if a sample was not finite.
fn tick_into(
    st: &mut EngineState,
    scene: &CompiledScene,
    buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
    g0: f64,
    dg: f64,
) -> bool {
    let [l, r] = buf;
    st.process_block(scene, &mut l[..len], &mut r[..len]);
    let mut finite = true;
    for k in 0..len {
        finite &= l[k].is_finite() && r[k].is_finite();
        if dg != 0.0 || g0 != 1.0 {
            let g = (g0 - k as f64 * dg).max(0.0);
            l[k] *= g;
            r[k] *= g;
        }
    }
    finite
}

fn add_into(
    acc: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    buf: &[[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
) {
    for ch in 0..2 {
        for k in 0..len {
            acc[ch][k] += buf[ch][k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: f64 = 44_100.0;

    fn params(preset: &str) -> InstrumentParams {
        let mut p = InstrumentParams::default();
        p.scene.preset = presets::index_of(preset).unwrap();
        p
    }

    fn base(preset: &str) -> Scene {
        presets::scene(presets::index_of(preset).unwrap()).unwrap()
    }

    fn instrument(p: &InstrumentParams) -> Instrument {
        Instrument::new(prepare(&p.scene, RATE, 0).unwrap(), p.play)
    }

    fn render(inst: &mut Instrument, events: &[TimedEvent], n: usize) -> [Vec<f32>; 2] {
        let mut l = vec![0.0; n];
        let mut r = vec![0.0; n];
        inst.process(events, &mut l, &mut r);
        [l, r]
    }

    fn on(offset: usize, key: u8, vel: f64) -> TimedEvent {
        TimedEvent {
            offset,
            event: Event::NoteOn {
                key,
                velocity_norm: vel,
            },
        }
    }

    fn off(offset: usize, key: u8) -> TimedEvent {
        TimedEvent {
            offset,
            event: Event::NoteOff { key },
        }
    }

    fn rms(x: &[f32]) -> f64 {
        (x.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / x.len().max(1) as f64).sqrt()
    }

    #[test]
    fn velocity_mapping_endpoints_and_monotone() {
        assert_eq!(impact_speed_m_per_s(0.0), 0.05);
        assert!((impact_speed_m_per_s(1.0) - 3.0).abs() < 1e-12);
        assert!((impact_speed_m_per_s(0.5) - (0.05 + 2.95 * 0.25)).abs() < 1e-12);
        assert_eq!(impact_speed_m_per_s(f64::NAN), 0.05);
        assert_eq!(impact_speed_m_per_s(7.0), impact_speed_m_per_s(1.0));
    }

    #[test]
    fn scene_for_defaults_keep_the_scene() {
        for (i, _) in presets::PRESETS.iter().enumerate() {
            let b = presets::scene(i).unwrap();
            let mut p = InstrumentParams::default();
            p.scene.switching = Switching::OffsetRod;
            let mut expect = b.clone();
            expect.contact.switching = Some(Switching::OffsetRod);
            assert_eq!(scene_for(&b, &p), expect, "{}", b.name);
        }
    }

    #[test]
    fn scene_for_scales_hammer_contact_and_decay() {
        let b = base("marimba-bar");
        let mut p = params("marimba-bar");
        p.scene.hammer_mass_factor = 2.0;
        p.scene.stiffness_factor = 3.0;
        p.scene.damping_factor = 0.5;
        p.scene.decay_scale = 4.0;
        let s = scene_for(&b, &p);
        assert_eq!(s.hammer.mass_kg, b.hammer.mass_kg * 2.0);
        assert_eq!(
            s.contact.stiffness_n_per_m,
            b.contact.stiffness_n_per_m * 3.0
        );
        assert_eq!(
            s.contact.damping_n_s_per_m,
            b.contact.damping_n_s_per_m * 0.5
        );
        let (ObjectSpec::Modal(m0), ObjectSpec::Modal(m1)) = (&b.object[0], &s.object[0]) else {
            panic!("modal");
        };
        for (a, c) in m0.mode.iter().zip(&m1.mode) {
            assert_eq!(c.t60_s.unwrap(), a.t60_s.unwrap() * 4.0);
            assert_eq!(c.freq_hz, a.freq_hz);
        }
        // string: Rayleigh and dashpots over the decay scale
        let b = base("paper-string");
        let mut p = params("paper-string");
        p.scene.decay_scale = 2.0;
        let s = scene_for(&b, &p);
        let (ObjectSpec::String(s0), ObjectSpec::String(s1)) = (&b.object[0], &s.object[0]) else {
            panic!("string");
        };
        assert_eq!(s1.rayleigh_alpha_per_s, s0.rayleigh_alpha_per_s / 2.0);
        assert_eq!(s1.rayleigh_beta_s, s0.rayleigh_beta_s / 2.0);
        assert_eq!(s1.dashpots[0].n_s_per_m, s0.dashpots[0].n_s_per_m / 2.0);
    }

    #[test]
    fn strike_position_moves_the_string_contact_and_interpolates_modal_weights() {
        let b = base("paper-string");
        let mut p = params("paper-string");
        p.scene.strike_pos_norm = Some(0.5);
        let s = scene_for(&b, &p);
        let ObjectSpec::String(st) = &s.object[0] else {
            panic!()
        };
        assert_eq!(st.points["contact"], 25); // round(0.5 * 49)
        p.scene.strike_pos_norm = Some(1.0);
        let ObjectSpec::String(st) = &scene_for(&b, &p).object[0] else {
            panic!()
        };
        assert_eq!(st.points["contact"], 49);

        // steel-plate has 3 points: contact, pickup, pickup2 (samples at 0, 0.5, 1)
        let b = base("steel-plate");
        let mut p = params("steel-plate");
        p.scene.strike_pos_norm = Some(0.75);
        let s = scene_for(&b, &p);
        let (ObjectSpec::Modal(m0), ObjectSpec::Modal(m1)) = (&b.object[0], &s.object[0]) else {
            panic!()
        };
        for (a, c) in m0.mode.iter().zip(&m1.mode) {
            let want = 0.5 * a.weights[1] + 0.5 * a.weights[2];
            assert!((c.weights[0] - want).abs() < 1e-12);
            assert_eq!(&c.weights[1..], &a.weights[1..]);
        }
        p.scene.strike_pos_norm = Some(0.0);
        assert_eq!(
            scene_for(&b, &p).object,
            b.object,
            "position 0 = first point"
        );

        // two points: ignored
        let b = base("marimba-bar");
        let mut p = params("marimba-bar");
        p.scene.strike_pos_norm = Some(0.3);
        assert_eq!(scene_for(&b, &p).object, b.object);
    }

    #[test]
    fn gravity_only_for_bouncing_scenes() {
        let mut p = params("paper-bounce");
        p.scene.gravity_m_per_s2 = 3.0;
        assert_eq!(
            scene_for(&base("paper-bounce"), &p).hammer.gravity_m_per_s2,
            3.0
        );
        let mut p = params("bell");
        p.scene.gravity_m_per_s2 = 3.0;
        assert_eq!(scene_for(&base("bell"), &p).hammer.gravity_m_per_s2, 0.0);
    }

    #[test]
    fn damped_scene_divides_decay_times() {
        let b = base("marimba-bar");
        let d = damped_scene(&b, 1.0);
        let (ObjectSpec::Modal(m0), ObjectSpec::Modal(m1)) = (&b.object[0], &d.object[0]) else {
            panic!()
        };
        for (a, c) in m0.mode.iter().zip(&m1.mode) {
            assert!((c.t60_s.unwrap() - a.t60_s.unwrap() / 51.0).abs() < 1e-12);
        }
        assert_eq!(damped_scene(&b, 0.0).object, b.object);
    }

    #[test]
    fn root_notes() {
        assert_eq!(root_note(&base("marimba-bar")), 57.0); // 220 Hz = A3
        assert_eq!(root_note(&base("bell")), 69.0); // 440 Hz
        assert_eq!(root_note(&base("paper-string")), 65.0); // ~350 Hz = F4
        let mut wall = base("paper-bounce");
        wall.object = vec![ObjectSpec::Wall(crate::scene::WallSpec {
            name: "plate".into(),
        })];
        assert_eq!(root_note(&wall), DEFAULT_ROOT_NOTE);
    }

    #[test]
    fn note_sounds_from_its_offset_and_root_plays_the_scene_as_written() {
        let p = params("marimba-bar");
        let mut inst = instrument(&p);
        let at = 1000;
        let [l, r] = render(&mut inst, &[on(at, 57, 0.8)], 20_000);
        assert!(l[..=at].iter().chain(&r[..=at]).all(|x| *x == 0.0));
        assert!(l[at + 1..at + 64].iter().any(|x| *x != 0.0));
        assert!(l.iter().chain(&r).all(|x| x.is_finite()));
        // the root note at the scene's own strike speed is the scene rendered
        // directly (up to the output gain)
        let mut sc = scene_for(&base("marimba-bar"), &p);
        sc.contact.switching = Some(inst.prepared().switching_used);
        let c = compile_with(&sc, RATE, None).unwrap();
        let mut st = EngineState::new(&c);
        let v = impact_speed_m_per_s(0.8);
        st.strike(&c, 0.0, -v);
        let g = 10f64.powf(p.play.gain_db / 20.0);
        for k in 0..5000 {
            let o = st.tick(&c);
            assert!(((o[0] * g) as f32 - l[at + k]).abs() <= 1e-6 * (1.0 + l[at + k].abs()));
        }
    }

    #[test]
    fn pitch_is_the_same_system_played_faster() {
        // One octave up at 44.1 kHz is the root at 22.05 kHz, sample for
        // sample, up to one constant factor (velocity pickups scale with s,
        // the reference strike speed with 1/s).
        let p = params("bell");
        let mut hi = instrument(&p);
        let [h, _] = render(&mut hi, &[on(0, 81, 0.7)], 4000);
        let mut lo = Instrument::new(prepare(&p.scene, RATE / 2.0, 0).unwrap(), p.play);
        let [l, _] = render(&mut lo, &[on(0, 69, 0.7)], 4000);
        let c = h.iter().zip(&l).map(|(a, b)| (a * b) as f64).sum::<f64>()
            / l.iter().map(|b| (b * b) as f64).sum::<f64>();
        let peak = h.iter().fold(0.0f32, |m, x| m.max(x.abs())) as f64;
        let err = h
            .iter()
            .zip(&l)
            .map(|(a, b)| (*a as f64 - c * *b as f64).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-4 * peak, "err {err} peak {peak} c {c}");
        let mut p = params("bell");
        p.play.pitch_tracking = false;
        let mut inst = instrument(&p);
        let [l1, _] = render(&mut inst, &[on(0, 81, 0.7)], 4000);
        let mut inst = instrument(&params("bell"));
        let [l2, _] = render(&mut inst, &[on(0, 69, 0.7)], 4000);
        assert_eq!(l1, l2, "pitch tracking off: every key plays the root");
    }

    #[test]
    fn louder_velocity_is_louder_and_block_splitting_does_not_matter() {
        let level = |vel| {
            let mut inst = instrument(&params("wood-block"));
            rms(&render(&mut inst, &[on(0, 70, vel)], 10_000)[0])
        };
        assert!(level(0.9) > 3.0 * level(0.3));
        let events = [
            on(10, 60, 0.5),
            on(300, 64, 0.9),
            off(5000, 60),
            on(7000, 60, 0.4),
        ];
        let mut a = instrument(&params("marimba-bar"));
        let [whole, _] = render(&mut a, &events, 20_000);
        let mut b = instrument(&params("marimba-bar"));
        let mut split = vec![0.0f32; 20_000];
        let mut right = vec![0.0f32; 20_000];
        let mut pos = 0;
        let mut ev = 0;
        for len in [1usize, 7, 64, 100, 333, 512].iter().cycle() {
            if pos >= 20_000 {
                break;
            }
            let end = (pos + len).min(20_000);
            let mut evs = Vec::new();
            while ev < events.len() && events[ev].offset < end {
                evs.push(TimedEvent {
                    offset: events[ev].offset - pos,
                    ..events[ev]
                });
                ev += 1;
            }
            b.process(&evs, &mut split[pos..end], &mut right[pos..end]);
            pos = end;
        }
        assert_eq!(whole, split);
    }

    #[test]
    fn repeated_note_restrikes_its_ringing_voice() {
        let mut inst = instrument(&params("marimba-bar"));
        let [l, _] = render(&mut inst, &[on(0, 57, 0.8), on(4410, 57, 0.8)], 8820);
        assert_eq!(inst.active_voices(), 1);
        assert_eq!(inst.stats.notes, 2);
        // the second strike hits a moving bar: not a copy of the first
        let a = &l[..2000];
        let b = &l[4410..6410];
        assert!(a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-4));
        assert!(b.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn voice_stealing_takes_the_quietest_voice() {
        let mut inst = instrument(&params("marimba-bar"));
        let mut events: Vec<TimedEvent> = (0..MAX_VOICES as u8)
            .map(|i| on(10 * i as usize, 40 + i, if i == 5 { 0.05 } else { 0.9 }))
            .collect();
        events.push(on(1000, 100, 0.9));
        render(&mut inst, &events, 1100);
        let keys = inst.voice_keys();
        assert_eq!(inst.stats.steals, 1);
        assert!(
            !keys.contains(&Some(45)),
            "the soft note was stolen: {keys:?}"
        );
        assert!(keys.contains(&Some(100)));
        assert_eq!(inst.active_voices(), MAX_VOICES);
    }

    #[test]
    fn damper_shortens_the_release_and_silent_voices_stop() {
        let tail = |damper: f64| {
            let mut p = params("marimba-bar");
            p.scene.damper_norm = damper;
            let mut inst = instrument(&p);
            let [l, _] = render(&mut inst, &[on(0, 57, 0.8), off(4410, 57)], 44_100);
            (rms(&l[22_050..]), inst)
        };
        let (free, _) = tail(0.0);
        let (damped, _) = tail(1.0);
        assert!(damped < 0.01 * free, "damped {damped} free {free}");
        let mut p = params("wood-block");
        p.scene.damper_norm = 1.0;
        let mut inst = instrument(&p);
        render(&mut inst, &[on(0, 70, 1.0), off(100, 70)], 44_100);
        assert_eq!(
            inst.active_voices(),
            0,
            "a damped wood block is silent after 1 s"
        );
        assert_eq!(inst.stats.silent_stops, 1);
    }

    #[test]
    fn non_finite_voice_is_reset_and_counted() {
        let mut inst = instrument(&params("marimba-bar"));
        let [_, _] = render(&mut inst, &[on(0, 57, 0.8)], 4410);
        inst.voice_state_mut(0).free_state_mut()[0] = f64::NAN;
        let [l, r] = render(&mut inst, &[], 4410);
        assert!(l.iter().chain(&r).all(|x| x.is_finite()));
        assert_eq!(inst.stats.nonfinite_resets, 1);
        assert_eq!(inst.active_voices(), 0);
    }

    #[test]
    fn swap_carries_voices_without_a_jump_and_preset_change_fades() {
        let p = params("marimba-bar");
        let mut inst = instrument(&p);
        let [l0, _] = render(&mut inst, &[on(0, 57, 0.8), on(5, 64, 0.8)], 4410);
        let mut q = p;
        q.scene.stiffness_factor = 1.5;
        q.scene.decay_scale = 0.7;
        let new = prepare(&q.scene, RATE, 1).unwrap();
        assert!(inst.can_install());
        inst.install(new).unwrap();
        assert_eq!(inst.stats.voices_carried, 2);
        assert_eq!(inst.active_voices(), 2);
        let [l1, _] = render(&mut inst, &[], 4410);
        let max_step = l0
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f32::max);
        assert!((l1[0] - l0[4409]).abs() <= max_step, "jump at the swap");
        // the old box is waiting to be handed back, not dropped
        assert_eq!(
            inst.retired_slots_mut()
                .iter()
                .filter(|s| s.is_some())
                .count(),
            1
        );

        let mut r = p;
        r.scene.preset = presets::index_of("bell").unwrap();
        inst.install(prepare(&r.scene, RATE, 2).unwrap()).unwrap();
        assert_eq!(inst.stats.voices_faded, 2);
        assert_eq!(inst.active_voices(), 0);
        assert!(!inst.can_install(), "fading");
        let [l2, _] = render(&mut inst, &[], 4410);
        assert!(
            (l2[0] - l1[4409]).abs() <= max_step,
            "fade starts where it was"
        );
        let fade = (FADE_S * RATE) as usize;
        assert!(l2[fade + 1..].iter().all(|x| *x == 0.0));
        assert!(inst.can_install());
        assert_eq!(
            inst.retired_slots_mut()
                .iter()
                .filter(|s| s.is_some())
                .count(),
            2
        );
    }

    /// The real-time warning of a stiff scene's event search: no shipped
    /// preset needs it at any Hardness (its estimate stays a few nodes per
    /// sample), so users only see it for their own stiff scenes.
    #[test]
    fn presets_need_no_realtime_warning_at_any_hardness() {
        for i in 0..presets::PRESETS.len() {
            for hf in [0.01, 1.0, 100.0] {
                let p = SceneParams {
                    preset: i,
                    stiffness_factor: hf,
                    ..SceneParams::default()
                };
                let pr = prepare(&p, RATE, 1).unwrap();
                assert!(
                    pr.realtime_warning().is_none(),
                    "{} x{hf}: {:?}",
                    pr.scene.name,
                    pr.realtime_warning()
                );
                assert!(
                    pr.scene.search_nodes_estimate <= 8.0,
                    "{}",
                    pr.scene.summary
                );
            }
        }
    }
}
