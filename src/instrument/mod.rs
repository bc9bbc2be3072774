//! The playable instrument: MIDI-like strikes on a compiled scene, with voices,
//! pitch, a damper, voice stealing, silence detection and the realtime swap of
//! recompiled scenes. Pure library code: no plugin types, no threads, no
//! atomics. The plugin (`crate::plugin`) and the tests drive the same
//! [`Instrument`] with the same [`Event`]s, so a test can compare the plugin's
//! output with a direct render sample by sample.
//!
//! # Mappings
//!
//! - **Velocity -> a driven scene's speed** ([`drive_speed_m_per_s`]): the
//!   scene's speed along its path times the impact speed's ratio to velocity
//!   100's; a new note puts the hammer on the surface at rest at the path's
//!   start, a note on a ringing key changes the speed, the mod wheel
//!   multiplies every held note's speed by 1 to [`WHEEL_SPEED_RANGE`]
//!   ([`wheel_speed_factor`]), a note's brightness (MPE's slide) its own
//!   speed by `1 / WHEEL_SPEED_RANGE` to [`WHEEL_SPEED_RANGE`], 1 at the
//!   centre ([`slide_speed_factor`]; in a driven scene it does not change
//!   the hardness), pressure (the note's or the channel's)
//!   presses it with up to [`PRESS_RANGE`] times the scene's force,
//!   continuously ([`press_factor`]; [`EngineState::set_load`] in O(N) at
//!   the sample the pressure changes), note-off stops the surface (docs/design.md,
//!   "Rolling and scraping").
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
//! - **Pitch bend** ([`Event::PitchBend`]): the wheel times
//!   [`PlayParams::bend_range_semitones`] scales every sounding voice's time
//!   axis again, gliding at most [`BEND_SLEW_SEMITONES_PER_S`] and updated
//!   every [`BEND_TICK_SAMPLES`] samples of the instrument's clock, keeping
//!   each voice's physical energy ([`EngineState::bend_time_scale`]);
//!   bouncing scenes are not bent (docs/plugin.md, "Pitch bend").
//! - **Per-note tuning** ([`Event::NoteTuning`]): the same for one voice,
//!   on top of the wheel; at the note's onset it applies at once
//!   (docs/plugin.md, "Per-note tuning").
//! - **Damper**: on note-off the voice is carried ([`EngineState::rebind`],
//!   no energy increase) onto a "damped" compilation of the same scene whose
//!   decay times are divided by `1 + 50 * damper` ([`damped_scene`]). A new
//!   note on the same key carries it back. Damper 0 means no damping on
//!   release (the bar rings on, as a struck bar does).
//! - **Brightness** ([`Event::NoteBrightness`]): a note's brightness picks
//!   the hardness of its strikes, the contact stiffness times
//!   `2^level` for `level = round(4 b) - 2` ([`timbre_level`]), from scenes
//!   compiled with the played one ([`Scenes`]). The voice moves to
//!   its level's scene ([`EngineState::rebind_same_free`]: the object's
//!   free motion is the same in every level's scene, so its state is kept
//!   and nothing changes but the next contact) at once when its hammer is
//!   out of contact, else on the silence-check grid after the contact; a
//!   new note starts at level 0. A note's hardness ([`Event::NoteHardness`],
//!   a host's polyphonic modulation of Hardness) is rounded to the same
//!   levels ([`hardness_level`]) and added to its brightness's; its strike
//!   position and damper ([`Event::NotePosition`], [`Event::NoteDamper`])
//!   to five levels of their own, compiled once a host modulates them
//!   ([`VariantSet`]; docs/plugin.md, "Polyphonic modulation").
//! - **Voices**: one voice per note, up to the polyphony
//!   ([`PlayParams::polyphony`], at most [`MAX_VOICES`], all allocated once). A repeated note
//!   strikes its own voice again while it rings: the hammer hits the moving
//!   surface ([`EngineState::strike`]). A new note takes a free voice, else
//!   steals the quietest one (lowest energy): the new note starts on it at
//!   once, and its running state moves into a spare state
//!   ([`STEAL_FADES`]) and fades out over [`FADE_S`] instead of being cut
//!   (docs/plugin.md, "Velocity, pitch, voices"). A choke
//!   ([`Event::Choke`]), All Sound Off ([`Event::AllSoundOff`]) and a
//!   lowered polyphony (the quietest voices beyond it) end voices the same
//!   way: each fades out in a spare state over [`FADE_S`], and a fading
//!   voice follows the bend, its note's tuning and the pressure as a
//!   sounding one does. A voice whose energy falls below
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
//!   clean on the new one. Stolen voices still fading fade on in the old
//!   box's spare states. Old boxes go to fixed
//!   [`Instrument::retired_slots_mut`] (once their fades have ended) for the
//!   caller to hand back to a non-realtime thread: nothing is dropped here.

mod events;
mod kit;
#[cfg(test)]
mod kit_tests;
mod mapping;
mod mix;
mod prepared;
mod probe;
#[cfg(test)]
mod tests;
mod voices;

pub use events::{Event, TimedEvent};
pub use kit::{Kit, LISTED_KIT_SPARES, MAX_KIT_VOICES, SILENCE_AMPLITUDE_RATIO};
pub use mapping::{
    damped_scene, drive_speed_m_per_s, impact_speed_m_per_s, lowest_frequency_hz, root_note,
    scene_for, slide_speed_factor, wheel_speed_factor, InstrumentParams, PlayParams, SceneParams,
    VariantSet,
};
pub use mix::{WorkMeter, LOOKAHEAD_WORK_FRACTION, MAX_LOOKAHEAD_S, MAX_LOOKAHEAD_SAMPLES};
pub use prepared::{
    damper_level, hardness_level, position_level, prepare, prepare_scene, prepare_scene_staged,
    prepare_staged, press_factor, timbre_level, PrepareError, Prepared, Scenes, Stage, StrikeCost,
    Variant, DAMPER_STEP, POSITION_STEP, PRESS_RANGE, STEP_NS_FIXED, STEP_NS_PER_STATE,
    STRIKE_BUDGET_FRACTION, STRIKE_NS_FIXED, STRIKE_NS_PER_STATE, STRIKE_NS_PER_SWITCH_FLOP,
    TIMBRE_LEVEL_MAX, TIMBRE_MAX_STATES, TIMBRE_STIFFNESS_STEP,
};
pub use probe::{VoiceChunk, VoiceProbe};

use crate::engine::{EngineState, Motion};
use voices::Voice;

/// Number of voices (one per sounding note).
pub const MAX_VOICES: usize = 64;
/// Voices that sound at once unless the Polyphony parameter says otherwise.
pub const DEFAULT_POLYPHONY: usize = 16;
/// Voices are checked for silence on this grid of the instrument's own sample
/// clock (a power of two; 64 samples = 1.5 ms at 44.1 kHz).
pub const CHECK_INTERVAL_SAMPLES: usize = 64;
/// A voice stops when its energy is below this fraction of its strike's
/// energy: -90 dB, far below audibility after a full-scale strike.
pub const SILENCE_ENERGY_RATIO: f64 = 1e-9;
/// Fade-out length for voices that cannot be carried across a swap and for
/// stolen voices \[s\] (5 ms: short enough to feel immediate, long enough
/// not to click: the linear ramp adds at most a voice's amplitude over the
/// fade's length to a sample's step, no more than the voice's own largest
/// step for every mode above `1 / (2 pi FADE_S)` = 32 Hz).
pub const FADE_S: f64 = 0.005;
/// Stolen voices that can fade out at once (each one a spare engine state
/// per [`Prepared`], and per pitched kit a spare kit state): a steal while
/// every one fades cuts the fade nearest its end (counted in
/// [`Stats::steal_fades_cut`]). docs/plugin.md, "Velocity, pitch, voices".
pub const STEAL_FADES: usize = 16;
/// Released decay times are divided by `1 + DAMPER_T60_DIVISOR * damper`
/// (damper 1 = 51 times shorter: a felt damper on a bar).
pub const DAMPER_T60_DIVISOR: f64 = 50.0;
/// Modes without damping get this T60 \[s\] before the damper divides it
/// (they would otherwise ring forever after release).
pub const UNDAMPED_RELEASE_T60_S: f64 = 20.0;
/// Slowest impact speed (velocity 0) \[m/s\].
pub const MIN_IMPACT_SPEED_M_PER_S: f64 = 0.05;
/// A driven scene's speed at full mod wheel, as a multiple of the speed
/// its note's velocity set ([`wheel_speed_factor`]).
pub const WHEEL_SPEED_RANGE: f64 = 4.0;
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
/// Damper pressure at its full value (a note's pressure, channel
/// aftertouch or the mod wheel at 1) adds this decay rate to every mode
/// \[1/s\]: `ln(1000) / 0.25`, 60 dB more in every quarter second
/// (docs/plugin.md, "Pressure and the mod wheel").
pub const MAX_PRESSURE_DECAY_PER_S: f64 = crate::physics::model::LN_1000 / 0.25;
/// Pitch bend at full wheel unless the Bend range parameter says otherwise
/// \[semitones\].
pub const DEFAULT_BEND_RANGE_SEMITONES: f64 = 2.0;
/// Largest bend range \[semitones\] (two octaves).
pub const MAX_BEND_RANGE_SEMITONES: f64 = 24.0;
/// While a bend moves, every sounding voice's time scale is updated on this
/// grid of the instrument's own sample clock (so the result does not depend
/// on how the host splits blocks).
pub const BEND_TICK_SAMPLES: usize = 16;
/// A bend moves towards the wheel at most this fast \[semitones/s\]: a step
/// of the wheel becomes a glide (2 semitones in 20 ms), and each update
/// changes the pitch by at most `100 * 16 / rate` semitones (0.036 at
/// 44.1 kHz: the displacement scales by 0.2 %).
pub const BEND_SLEW_SEMITONES_PER_S: f64 = 100.0;
/// Largest per-note tuning \[semitones\] ([`Event::NoteTuning`]; four
/// octaves, MPE's default per-note bend range).
pub const MAX_NOTE_TUNING_SEMITONES: f64 = 48.0;
/// Root note of scenes without modal frequencies (middle C).
pub const DEFAULT_ROOT_NOTE: f64 = 60.0;
/// Fixed slots for retired compiled scenes waiting to be handed back.
pub const RETIRED_SLOTS: usize = 4;

/// The lookahead of `seconds` at `rate_hz` \[samples\]: rounded, within
/// 0..=[`MAX_LOOKAHEAD_SAMPLES`] (not a number: 0).
pub fn lookahead_samples(seconds: f64, rate_hz: f64) -> usize {
    let n = (seconds * rate_hz).round();
    if n >= 1.0 {
        (n as usize).min(MAX_LOOKAHEAD_SAMPLES)
    } else {
        0
    }
}

/// `now` moved towards `target` by at most `step`.
fn slew(now: f64, target: f64, step: f64) -> f64 {
    let d = target - now;
    if d.abs() <= step {
        target
    } else {
        now + step.copysign(d)
    }
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
    /// Of those, the stolen voices that fade out over [`FADE_S`] (the
    /// others had not sounded yet: struck from rest at that very sample).
    pub steals_faded: u64,
    /// Fades cut because every spare state was fading ([`STEAL_FADES`]):
    /// for a steal or a choke of one note the fade nearest its end was
    /// taken; for voices ended together (All Sound Off, a choke of every
    /// note, a lowered Polyphony; the loudest first) the fade nearest its
    /// end if it began earlier, else the voice ending now (the quietest
    /// left) went without a fade.
    pub steal_fades_cut: u64,
    /// Voices ended by a choke, All Sound Off or a lowered Polyphony
    /// ([`Event::Choke`], [`Event::AllSoundOff`]).
    pub voices_ended: u64,
    /// Of those, the ones that fade out over [`FADE_S`] as a stolen voice
    /// does (the others had not sounded yet, or were cut: counted in
    /// [`Stats::steal_fades_cut`]).
    pub voices_ended_faded: u64,
    /// Voices reset because they produced a non-finite sample.
    pub nonfinite_resets: u64,
    /// Notes played at s = 1 because the scene uses the dense fallback.
    pub dense_pitch_fallbacks: u64,
    /// Voices stopped because they fell silent.
    pub silent_stops: u64,
    /// Note-ons.
    pub notes: u64,
    /// New notes whose propagators were copied from those made ahead for
    /// their key (`Prepared`'s key propagators), not computed.
    pub key_props_copied: u64,
    /// New notes on a voice at rest played back from their key's stored
    /// strike from rest ([`crate::engine::EngineState::strike_stored`]).
    pub strikes_replayed: u64,
    /// Voice samples rendered under a pressed damper (docs/plugin.md,
    /// "Pressure and the mod wheel").
    pub pressed_samples: u64,
    /// Output samples that reached [`OUTPUT_CEILING`] (or were not finite
    /// after mixing, written as 0).
    pub ceiling_hits: u64,
}

/// The instrument (owned by the audio thread). Everything it does after
/// [`Instrument::new`] is allocation-free.
pub struct Instrument {
    cur: Box<Prepared>,
    voices: [Voice; MAX_VOICES],
    /// Previous scene while voices that could not be carried fade out.
    fading: Option<Box<Prepared>>,
    /// Which voices of `fading` sound: each one's variant and whether it
    /// is on its damped scene.
    fade_voices: [Option<(Variant, bool)>; MAX_VOICES],
    fade_left: usize,
    fade_len: usize,
    /// Stolen voices fading out in the spare states of `cur`
    /// (`Prepared::spares`, a pitched kit's `Kit::spares`), by spare.
    steal_fades: [Option<voices::StealFade>; STEAL_FADES],
    /// The same for the spare states of `fading` (fades that were under
    /// way at the swap).
    old_steal_fades: [Option<voices::StealFade>; STEAL_FADES],
    retired: [Option<Box<Prepared>>; RETIRED_SLOTS],
    play: PlayParams,
    gain: f64,
    sample_pos: u64,
    /// The pedals and which keys are down (docs/plugin.md, "Pedals").
    pedals: Pedals,
    /// Pitch-bend wheel, -1 .. 1.
    bend_wheel: f64,
    /// Bend the voices are at (or moving to) now \[semitones\].
    bend_now: f64,
    /// Some voice could not take the last bend (it was in contact).
    bend_pending: bool,
    /// Some voice's per-note tuning is still gliding.
    tuning_moving: bool,
    /// Some voice waits for its brightness level (its hammer was in
    /// contact when the brightness came).
    timbre_pending: bool,
    /// Channel aftertouch, 0 .. 1.
    channel_pressure: f64,
    /// Mod wheel, 0 .. 1.
    mod_wheel: f64,
    acc: [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    vbuf: [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    /// The live view's probe and whether it records now.
    probe: Option<Box<dyn VoiceProbe>>,
    probe_on: bool,
    motion: [Motion; CHECK_INTERVAL_SAMPLES],
    /// A kit's motion per contact for the live view.
    kit_motion: [[Motion; CHECK_INTERVAL_SAMPLES]; crate::multi::MAX_SPRINGS],
    /// Each voice's clock and samples, and the output (`mix`).
    lanes: mix::Lanes,
    /// Counters.
    pub stats: Stats,
}

/// Which keys are down and what the pedals hold (128 keys as bits).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Pedals {
    sustain: bool,
    sostenuto: bool,
    keys_down: [u64; 2],
    /// Keys that were down when the sostenuto pedal went down.
    sostenuto_keys: [u64; 2],
}

impl Pedals {
    fn bit(keys: &[u64; 2], key: u8) -> bool {
        keys[usize::from(key >> 6) & 1] & (1 << (key & 63)) != 0
    }

    fn set_down(&mut self, key: u8, down: bool) {
        let (w, b) = (usize::from(key >> 6) & 1, 1u64 << (key & 63));
        if down {
            self.keys_down[w] |= b;
        } else {
            self.keys_down[w] &= !b;
        }
    }

    /// A released key's note keeps ringing undamped.
    fn holds(&self, key: u8) -> bool {
        self.sustain || (self.sostenuto && Self::bit(&self.sostenuto_keys, key))
    }
}

impl Instrument {
    /// Key `key` came up: damp its note unless a pedal holds it.
    fn key_up(&mut self, key: u8) {
        self.pedals.set_down(key, false);
        if !self.pedals.holds(key) {
            self.note_off(Some(key));
        }
    }

    /// A pedal came up: damp every sounding note whose key is up and that
    /// the other pedal does not hold.
    fn damp_unheld(&mut self) {
        for i in 0..MAX_VOICES {
            let v = self.voices[i];
            if v.active
                && !v.released
                && !Pedals::bit(&self.pedals.keys_down, v.key)
                && !self.pedals.holds(v.key)
            {
                self.note_off(Some(v.key));
            }
        }
    }

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
            steal_fades: [None; STEAL_FADES],
            old_steal_fades: [None; STEAL_FADES],
            retired: Default::default(),
            play,
            gain: 1.0,
            sample_pos: 0,
            pedals: Pedals::default(),
            bend_wheel: 0.0,
            bend_now: 0.0,
            bend_pending: false,
            tuning_moving: false,
            timbre_pending: false,
            channel_pressure: 0.0,
            mod_wheel: 0.0,
            acc: [[0.0; CHECK_INTERVAL_SAMPLES]; 2],
            vbuf: [[0.0; CHECK_INTERVAL_SAMPLES]; 2],
            probe: None,
            probe_on: false,
            motion: [Motion::default(); CHECK_INTERVAL_SAMPLES],
            kit_motion: [[Motion::default(); CHECK_INTERVAL_SAMPLES]; crate::multi::MAX_SPRINGS],
            lanes: mix::Lanes::new(),
            stats: Stats::default(),
        };
        inst.set_play(play);
        inst
    }

    /// Attach (or detach, `None`) a probe that sees every sounding voice's
    /// motion and energy; returns the previous one. It records only while
    /// [`set_probe_on`](Self::set_probe_on) says so. \[main-thread\]
    pub fn set_probe(&mut self, probe: Option<Box<dyn VoiceProbe>>) -> Option<Box<dyn VoiceProbe>> {
        std::mem::replace(&mut self.probe, probe)
    }

    /// Switch the probe on or off (e.g. while the editor window is open).
    /// On, each voice runs the engine's observed block path (the same
    /// samples bit for bit, its kernel pass summing the contact point's rows too) and its
    /// energy is taken once per chunk. Allocation-free. \[audio-thread\]
    pub fn set_probe_on(&mut self, on: bool) {
        self.probe_on = on && self.probe.is_some();
    }

    /// The scene set currently played. \[audio-thread\]
    pub fn prepared(&self) -> &Prepared {
        &self.cur
    }

    /// The scene set it plays, taken back as the instrument ends (a fading
    /// or retired one is dropped): a new instrument may be built around it
    /// ([`Instrument::new`]); its voice states start over at their next
    /// note as a stolen voice's does. \[main-thread\]
    pub fn into_prepared(self) -> Box<Prepared> {
        self.cur
    }

    /// Update the parameters that need no compile (gain and the lookahead
    /// now; pitch tracking and drop height at the next note; a polyphony
    /// below the voices that sound ends the quietest of them now, each
    /// fading out as a stolen voice does). \[audio-thread\]
    pub fn set_play(&mut self, mut play: PlayParams) {
        play.polyphony = play.polyphony.clamp(1, MAX_VOICES);
        play.bend_range_semitones = if play.bend_range_semitones.is_finite() {
            play.bend_range_semitones
                .clamp(0.0, MAX_BEND_RANGE_SEMITONES)
        } else {
            DEFAULT_BEND_RANGE_SEMITONES
        };
        if play.polyphony < self.play.polyphony {
            // the voices beyond a lowered limit, the quietest first, fade
            // out as stolen voices do
            self.end_beyond(play.polyphony);
        }
        self.play = play;
        let g = 10f64.powf(play.gain_db / 20.0);
        self.gain = if g.is_finite() { g } else { 0.0 };
        self.set_lookahead(lookahead_samples(play.lookahead_s, self.cur.rate_hz));
    }

    /// The bend the voices are at now \[semitones\] (it glides towards the
    /// wheel's, see [`BEND_SLEW_SEMITONES_PER_S`]). \[audio-thread\]
    pub fn bend_semitones(&self) -> f64 {
        self.bend_now
    }

    /// The bend the wheel asks for \[semitones\].
    fn bend_target(&self) -> f64 {
        self.bend_wheel * self.play.bend_range_semitones
    }

    /// Whether a bend is still moving (the voices are updated on the
    /// [`BEND_TICK_SAMPLES`] grid).
    fn bend_moving(&self) -> bool {
        self.bend_now != self.bend_target() || self.bend_pending || self.tuning_moving
    }

    /// One update of a moving bend: step towards the wheel (slew-limited)
    /// and give every sounding voice its new time scale without adding or
    /// removing energy ([`EngineState::bend_time_scale`]); a voice in
    /// contact takes it at a later update. Bouncing scenes are not bent
    /// (gravity would change with the time axis). O(voices N),
    /// allocation-free. \[audio-thread\]
    fn bend_tick(&mut self) {
        let target = self.bend_target();
        let step = BEND_SLEW_SEMITONES_PER_S * BEND_TICK_SAMPLES as f64 / self.cur.rate_hz;
        self.bend_now = slew(self.bend_now, target, step);
        // the voices fading out follow the bend too
        let (fades_pending, fades_moving) = self.fades_bend_tick(step);
        if self.cur.kit.is_some() {
            let (pending, moving) = self.kit_bend_tick(step);
            self.bend_pending = pending || fades_pending;
            self.tuning_moving = moving || fades_moving;
            return;
        }
        let mut pending = false;
        let mut tuning_moving = false;
        for i in 0..MAX_VOICES {
            let v = &mut self.voices[i];
            if !v.active {
                continue;
            }
            v.tuning_now = slew(v.tuning_now, v.tuning_target, step);
            if self.cur.bouncing {
                continue;
            }
            tuning_moving |= v.tuning_now != v.tuning_target;
            let s = v.base_scale * 2f64.powf((self.bend_now + v.tuning_now) / 12.0);
            if self.cur.states[i].time_scale() == s {
                continue;
            }
            // a pressed voice takes its damper's decay first, and is
            // decided again at its new pitch
            self.press_flush(i);
            let (p, v) = (&mut *self.cur, &self.voices[i]);
            // Err: a voice that cannot scale time (dense fallback) stays put
            if let Ok(false) = p.states[i].bend_time_scale(p.scenes.bound(v.at, v.on_damped), s) {
                pending = true;
            }
            self.press_decide(i);
        }
        self.bend_pending = pending || fades_pending;
        self.tuning_moving = tuning_moving || fades_moving;
    }

    /// A per-note tuning ([`Event::NoteTuning`]). \[audio-thread\]
    fn note_tuning(&mut self, key: Option<u8>, semitones: f64) {
        let t = if semitones.is_nan() {
            0.0
        } else {
            semitones.clamp(-MAX_NOTE_TUNING_SEMITONES, MAX_NOTE_TUNING_SEMITONES)
        };
        if self.cur.kit.is_some() {
            self.kit_note_tuning(key, t);
            return;
        }
        // the voices of `key` fading out glide to it too
        if !self.cur.bouncing {
            let mut fading = false;
            self.for_fades(key, |f| {
                f.tuning_target = t;
                fading |= f.tuning_now != t;
            });
            self.tuning_moving |= fading;
        }
        for i in 0..MAX_VOICES {
            let v = &mut self.voices[i];
            if !v.active || key.is_some_and(|k| k != v.key) {
                continue;
            }
            v.tuning_target = t;
            if self.cur.bouncing || v.tuning_now == t {
                continue;
            }
            if v.onset_pos == self.sample_pos && !self.cur.states[i].in_contact() {
                // at the onset: the note starts at its tuned pitch (the
                // hammer keeps its physical speed, the object its energy;
                // the silence test's reference follows the units)
                self.press_flush(i);
                let (p, v) = (&mut *self.cur, &mut self.voices[i]);
                let st = &mut p.states[i];
                let s = v.base_scale * 2f64.powf((self.bend_now + t) / 12.0);
                let s_old = st.time_scale();
                let tuned = st.bend_time_scale(p.scenes.bound(v.at, v.on_damped), s);
                if let Ok(true) = tuned {
                    v.tuning_now = t;
                    v.strike_energy *= (s_old / s) * (s_old / s);
                }
                self.press_decide(i);
                if let Ok(true) = tuned {
                    continue;
                }
            }
            self.tuning_moving = true;
        }
    }

    /// The engine state of voice `voice_idx` at the voice's own clock (with
    /// a lookahead it may be behind the instrument's; for tests and tools).
    /// \[audio-thread\]
    pub fn voice_state(&self, voice_idx: usize) -> &EngineState {
        &self.cur.states[voice_idx]
    }

    /// The engine state of voice `voice_idx`, every voice brought up to the
    /// instrument's clock first (for tests and tools, e.g. to inspect or
    /// disturb a voice). \[audio-thread\]
    pub fn voice_state_mut(&mut self, voice_idx: usize) -> &mut EngineState {
        self.sync_all(true);
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
        self.sync_all(true);
        let same_object = new.params.preset == self.cur.params.preset
            && new.params.user_scene == self.cur.params.user_scene
            && new.rate_hz == self.cur.rate_hz;
        let mut any_fade = false;
        for i in 0..MAX_VOICES {
            if !self.voices[i].active {
                continue;
            }
            // a kit: carried to the new kit of the same scene while no
            // contact is closed (`Kit::take_over`), else it fades out and
            // the new one starts at rest
            if self.cur.kit.is_some() || new.kit.is_some() {
                // a pressed kit voice's state takes its damper's decay so far
                self.press_flush(i);
                let at = kit::kit_at(&self.voices[i]);
                let carried = match (self.cur.kit.as_deref_mut(), new.kit.as_deref_mut()) {
                    (Some(old), Some(to)) if same_object => to.take_over(old, (i, at)),
                    _ => None,
                };
                if let Some(at) = carried {
                    let v = &mut self.voices[i];
                    kit::set_kit_at(v, at);
                    // its note's level, where the new kit has it, at the
                    // next grid step
                    self.stats.voices_carried += 1;
                } else {
                    let v = &mut self.voices[i];
                    self.fade_voices[i] = Some((v.at, v.on_damped));
                    v.active = false;
                    any_fade = true;
                    self.stats.voices_faded += 1;
                }
                continue;
            }
            // a pressed voice's state takes its damper's decay so far
            self.press_flush(i);
            let v = &mut self.voices[i];
            // a variant the new scene set lacks plays the nearest it has
            // (`Scenes::bound`)
            let to_damped = v.released && new.scenes.damped_for(v.at.damper).is_some();
            let carried = same_object && {
                let Prepared { states, scenes, .. } = &mut *self.cur;
                let from = scenes.bound(v.at, v.on_damped);
                let ok = states[i].rebind(from, new.scenes.bound(v.at, to_damped));
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
                self.timbre_pending |= v.at != v.want;
            } else {
                self.fade_voices[i] = Some((v.at, v.on_damped));
                v.active = false;
                any_fade = true;
                self.stats.voices_faded += 1;
            }
        }
        let old = std::mem::replace(&mut self.cur, new);
        (0..MAX_VOICES).for_each(|i| self.press_decide(i));
        self.stats.swaps += 1;
        // stolen voices still fading go on in the old box's spare states
        let steals = std::mem::replace(&mut self.steal_fades, [None; STEAL_FADES]);
        let any_steal = steals.iter().any(Option::is_some);
        if any_fade || any_steal {
            self.fading = Some(old);
            self.old_steal_fades = steals;
            self.fade_left = if any_fade { self.fade_len } else { 0 };
            self.lanes.begin(voices::FADE_LANE, self.sample_pos);
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
        self.pedals = Pedals::default();
        self.voices = [Voice::default(); MAX_VOICES];
        self.fade_voices = [None; MAX_VOICES];
        self.fade_left = 0;
        self.steal_fades = [None; STEAL_FADES];
        self.old_steal_fades = [None; STEAL_FADES];
        self.restart_lanes();
    }

    /// Apply one event now, the voices it concerns at the instrument's
    /// clock ([`Instrument::handle`]). \[audio-thread\]
    fn apply(&mut self, event: Event) {
        match event {
            // MIDI's convention: a note-on at velocity 0 is a note-off (and
            // a velocity that is not a number strikes nothing).
            Event::NoteOn { key, velocity_norm } if !(velocity_norm > 0.0) => self.key_up(key),
            Event::NoteOn { key, velocity_norm } => {
                self.pedals.set_down(key, true);
                self.note_on(key, velocity_norm)
            }
            Event::NoteOff { key } => self.key_up(key),
            // every key up: what the pedals hold rings on
            Event::AllNotesOff => {
                self.pedals.keys_down = [0; 2];
                self.damp_unheld();
            }
            Event::Choke { key } => self.choke(key),
            Event::AllSoundOff => self.end_all(),
            Event::ResetControllers => {
                self.pedals.sustain = false;
                self.pedals.sostenuto = false;
                self.pedals.sostenuto_keys = [0; 2];
                self.damp_unheld();
                self.bend_wheel = 0.0;
                self.channel_pressure = 0.0;
                self.mod_wheel = 0.0;
                self.drive_wheel();
                for i in 0..MAX_VOICES {
                    if self.voices[i].active {
                        self.voices[i].pressure = 0.0;
                    }
                    self.repress(i);
                    self.press_drive(i);
                }
                self.for_fades(None, |f| f.pressure = 0.0);
                self.repress_fades();
            }
            Event::Sustain { down } => {
                self.pedals.sustain = down;
                if !down {
                    self.damp_unheld();
                }
            }
            Event::PitchBend { value } => {
                self.bend_wheel = if value.is_nan() {
                    0.0
                } else {
                    value.clamp(-1.0, 1.0)
                };
            }
            Event::NoteTuning { key, semitones } => self.note_tuning(key, semitones),
            Event::NotePressure { key, value } => {
                let value = unit(value);
                for i in 0..MAX_VOICES {
                    let v = &mut self.voices[i];
                    if v.active && key.is_none_or(|k| k == v.key) {
                        v.pressure = value;
                        self.repress(i);
                        self.press_drive(i);
                    }
                }
                // and the voices of `key` fading out
                self.for_fades(key, |f| f.pressure = value);
                self.repress_fades();
            }
            Event::NoteBrightness { key, value } => self.note_brightness(key, value),
            Event::NoteHardness { key, factor } => {
                let level = hardness_level(factor);
                self.want_levels(key, |v| v.hard_level = level);
            }
            Event::NotePosition { key, offset } => {
                let level = position_level(offset);
                self.want_levels(key, |v| v.want.pos = level);
            }
            Event::NoteDamper { key, offset } => {
                let level = damper_level(offset);
                self.want_levels(key, |v| v.want.damper = level);
            }
            Event::ChannelPressure { value } => {
                self.channel_pressure = unit(value);
                for i in 0..MAX_VOICES {
                    self.repress(i);
                    self.press_drive(i);
                }
                self.repress_fades();
            }
            Event::ModWheel { value } => {
                self.mod_wheel = unit(value);
                self.drive_wheel();
                (0..MAX_VOICES).for_each(|i| self.repress(i));
                self.repress_fades();
            }
            Event::Sostenuto { down } => {
                if down && !self.pedals.sostenuto {
                    self.pedals.sostenuto_keys = self.pedals.keys_down;
                }
                self.pedals.sostenuto = down;
                if !down {
                    self.pedals.sostenuto_keys = [0; 2];
                    self.damp_unheld();
                }
            }
        }
    }
}

impl Instrument {
    /// A note's brightness: its hardness level, or in a driven scene its
    /// stroke's speed (MPE's slide, [`slide_speed_factor`]).
    fn note_brightness(&mut self, key: Option<u8>, value: f64) {
        if self.cur.kit.is_none() && self.cur.scenes.scene.drive.is_some() {
            self.drive_slide(key, slide_speed_factor(value));
        } else {
            let level = timbre_level(value);
            self.want_levels(key, |v| v.bright_level = level);
        }
    }

    /// Update the voices of `key` (every voice for `None`) with `set` and
    /// move them to the hardness level their note now asks for.
    fn want_levels(&mut self, key: Option<u8>, set: impl Fn(&mut Voice)) {
        if self.cur.kit.is_some() {
            return self.kit_want_levels(key, set);
        }
        for v in &mut self.voices {
            if v.active && key.is_none_or(|k| k == v.key) {
                set(v);
                v.want.hard = wanted_level(v.bright_level, v.hard_level);
                self.timbre_pending |= v.at != v.want;
            }
        }
        if self.timbre_pending {
            self.apply_timbre();
        }
    }
}

/// Multiply the `len` samples of `buf` (and the probe's contact point) by
/// `g, g q, g q^2, ...` (a pressed voice's damper, continuing from `g`);
/// returns `g q^len`.
fn decay_into(
    buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
    mut g: f64,
    q: f64,
    mut motion: Option<&mut [Motion]>,
) -> f64 {
    for k in 0..len {
        buf[0][k] *= g;
        buf[1][k] *= g;
        if let Some(m) = motion.as_deref_mut() {
            m[k].x_contact *= g;
            m[k].v_contact *= g;
        }
        g *= q;
    }
    g
}

/// The hardness level of a note: its brightness's level plus its hardness
/// modulation's, within the compiled levels (±[`TIMBRE_LEVEL_MAX`]).
fn wanted_level(bright: i8, hard: i8) -> i8 {
    (bright + hard).clamp(-TIMBRE_LEVEL_MAX, TIMBRE_LEVEL_MAX)
}

/// A controller's value in 0 .. 1: clamped, not a number is 0.
fn unit(x: f64) -> f64 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}
