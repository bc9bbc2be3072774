//! A scene of several contacts played by the instrument (docs/design.md,
//! "Played as a kit"): its objects are one physical system, so a voice
//! plays the whole scene, a *kit voice*. A note throws mallets at the
//! note's impact speed from the surface of the point each strikes (from
//! the drop height in a scene with gravity); a mallet still in contact
//! leaves it first ([`MultiState::strike`]).
//!
//! - A scene whose mallets list no notes is *pitched*: one kit voice per
//!   key at the key's pitch ([`MultiState::set_time_scale`], as a voice of
//!   one contact), up to [`MAX_KIT_VOICES`]; a note throws the next mallet
//!   of its key's voice in turn (a repeated key rolls), a new key takes a
//!   free voice or steals the quietest, whose running state fades out in
//!   a spare kit state over [`super::FADE_S`] as a stolen voice of one
//!   contact does (the new key starts at once on a state at rest).
//! - A scene whose mallets list notes (`notes` of `[hammer]` and each
//!   `[[striker]]`) is one kit voice at the scene's pitch: a note throws
//!   every mallet that lists it (a drum kit).
//!
//! A released kit voice (its note's key up, the pedals too; a kit of
//! listed notes: its last note's key) continues on the scene's damped
//! compile when the scene has a damper (`[play] damper`, or Custom damper),
//! as a voice of one contact continues on its damped scene: the same
//! physical state carried while no contact is closed ([`Kit::damped`],
//! [`MultiState::carry`]; with one closed, at a later step of the
//! silence-check grid), and back to the played compile when its key
//! strikes again. Without a damper it rings on. A note's brightness (and
//! a host's polyphonic modulation of Hardness) moves its kit voice to the
//! kit's compile at that hardness level ([`Kit::settle`], the same way),
//! and pressure damps it once none of its contacts can close
//! ([`MultiState::contacts_clear`]), as they do a voice of one contact. A
//! kit voice stops when it is silent, as a voice of one contact does: no
//! contact closed, and its objects' energy and the masses that may still
//! land ([`MultiState::masses_to_land`]) below [`SILENCE_ENERGY_RATIO`] of
//! its last throw's energy (a mass lying on an object: its output below
//! [`SILENCE_AMPLITUDE_RATIO`] of its loudest for a check interval).
//!
//! Kit voice `i` renders in voice `i`'s lane, so the lookahead, the gain,
//! the output guard and the fades of a swap and of a steal are the
//! voices' own.

use super::{
    impact_speed_m_per_s, Instrument, CHECK_INTERVAL_SAMPLES, SILENCE_ENERGY_RATIO, STEAL_FADES,
    TIMBRE_LEVEL_MAX,
};
use crate::engine::TimeScaleError;
use crate::multi::{CompiledMulti, MultiEnd, MultiModel, MultiState, MAX_SPRINGS};
use crate::scene::{Scene, SceneError};

/// A kit voice resting with a contact closed (a mass lying on an object
/// under gravity) stops when its output stays below this fraction of its
/// loudest since the last throw for a whole check interval (-90 dB, the
/// voices' energy ratio [`SILENCE_ENERGY_RATIO`] as an amplitude).
pub const SILENCE_AMPLITUDE_RATIO: f64 = 3.1622776601683795e-5;

/// Kit voices of a pitched kit: as many as voices of one contact (the
/// Polyphony parameter's range), each holding every phase's tables at its
/// pitch (about 170 KB for four contacts on 100 modes).
pub const MAX_KIT_VOICES: usize = super::MAX_VOICES;

/// Spare kit states of a kit whose mallets list notes (one kit voice,
/// never stolen): its voice fades out in one when choked or silenced by
/// All Sound Off, as a stolen voice does; two, so that a choke, a new
/// note and a second choke within [`super::FADE_S`] cut no fade.
pub const LISTED_KIT_SPARES: usize = 2;

/// One kit voice: the scene's running state at its pitch, its turn and its
/// silence test.
#[derive(Clone)]
pub(super) struct KitVoice {
    pub(super) st: MultiState,
    /// The mallet its next note throws when in turn.
    next: usize,
    /// The last note that threw each mallet (the live view).
    last_key: [u8; MAX_SPRINGS],
    /// The loudest output since the last throw, the loudest of the
    /// current check interval, and the throw's energy (the model's units).
    peak: f64,
    interval_peak: f64,
    strike_energy: f64,
}

/// The compiled scene of several contacts, its kit voices and which note
/// throws which mallet. Built off the audio thread; everything the
/// instrument does with it is allocation-free.
#[derive(Clone)]
pub struct Kit {
    /// Every phase of the scene's contacts.
    pub sc: CompiledMulti,
    /// The same scene under the damper (every object's decay times
    /// divided as [`super::mapping::damped_scene`] does), which released
    /// kit voices continue on; `None` when the damper is 0.
    pub damped: Option<CompiledMulti>,
    /// The scene at the other levels of a note's hardness, strike
    /// position and damper (a note's brightness, a host's polyphonic
    /// modulation), where compiled.
    pub(super) levels: KitLevels,
    /// The kit voices ([`MAX_KIT_VOICES`] when pitched, else 1).
    pub(super) voices: Vec<KitVoice>,
    /// Spare states for kit voices to fade out in when stolen, choked or
    /// ended by All Sound Off or a lowered Polyphony ([`STEAL_FADES`]
    /// when pitched; [`LISTED_KIT_SPARES`] for the one voice of a kit of
    /// listed notes, which is never stolen).
    pub(super) spares: Vec<MultiState>,
    /// Per MIDI note: the mallets it throws (bit `i`: mallet `i`, whose
    /// contact is contact `i`; `[hammer]` is mallet 0, striker `i` mallet
    /// `i + 1`).
    keys: [u8; 128],
    /// No mallet lists notes: a voice per key at its pitch, each note the
    /// next mallet of its voice in turn.
    pub pitched: bool,
    /// How many mallets.
    pub mallets: usize,
    /// The masses fall (the scene has gravity).
    pub bouncing: bool,
    /// Throws refused (a mallet wedged, [`MultiState::strike`]).
    pub refused: u64,
}

impl Kit {
    /// The kit of a scene of several contacts (as played: the parameters
    /// already applied) at `rate_hz`, with its damped compile when
    /// `damper_norm` (0 .. 1) is above 0. \[worker\] \[main-thread\]
    pub fn new(scene: &Scene, rate_hz: f64, damper_norm: f64) -> Result<Self, SceneError> {
        let switching = scene.contact.switching.unwrap_or_default();
        let compile = |scene: &Scene| Self::compile_scene(scene, rate_hz, switching);
        let sc = compile(scene)?;
        let damped = if damper_norm > 0.0 {
            let d = compile(&super::mapping::damped_scene(scene, damper_norm))?;
            // the same bodies and phases, other decays: a state carries
            // between the two ([`MultiState::carry`])
            let mut probe = MultiState::new(&sc);
            probe.rest(&sc);
            if !probe.carry(&sc, &d) {
                return Err(SceneError::new(
                    "play.damper",
                    "the damped scene's phases differ from the played scene's",
                ));
            }
            Some(d)
        } else {
            None
        };
        let lists: Vec<&Vec<u8>> = std::iter::once(&scene.hammer.notes)
            .chain(scene.striker.iter().map(|s| &s.notes))
            .collect();
        let mut keys = [0u8; 128];
        for (i, notes) in lists.iter().enumerate() {
            for &n in notes.iter() {
                keys[usize::from(n.min(127))] |= 1 << i;
            }
        }
        let pitched = lists.iter().all(|l| l.is_empty());
        let mut st = MultiState::new(&sc);
        st.rest(&sc);
        // a voice pitched up leaves its modes above Nyquist out of its
        // outputs, as a voice of one contact does
        st.set_output_band(&sc, super::OUTPUT_BAND_FRACTION * 0.5 * rate_hz);
        let spares = vec![
            st.clone();
            if pitched {
                STEAL_FADES
            } else {
                LISTED_KIT_SPARES
            }
        ];
        let voice = KitVoice {
            st,
            next: 0,
            last_key: [0; MAX_SPRINGS],
            peak: 0.0,
            interval_peak: 0.0,
            strike_energy: 0.0,
        };
        Ok(Self {
            voices: vec![voice; if pitched { MAX_KIT_VOICES } else { 1 }],
            spares,
            mallets: lists.len(),
            pitched,
            keys,
            bouncing: scene.hammer.gravity_m_per_s2 > 0.0,
            refused: 0,
            sc,
            damped,
            levels: KitLevels::none(),
        })
    }

    /// One compile of a kit's scene (`scene`, a variant of the played one:
    /// another hardness, the damper) at `rate_hz` with `switching`.
    /// \[worker\] \[main-thread\]
    pub fn compile_scene(
        scene: &Scene,
        rate_hz: f64,
        switching: crate::scene::Switching,
    ) -> Result<CompiledMulti, SceneError> {
        let model = MultiModel::from_scene(scene, rate_hz)?;
        CompiledMulti::with_switching(&model, rate_hz, switching).map_err(|e| e.in_scene(scene))
    }

    /// Which note throws which mallet, in words (the summary).
    pub fn notes_rule(&self) -> &'static str {
        match (self.pitched, self.mallets) {
            (true, 1) => "a voice per key at its pitch, each note throwing the mallet",
            (true, _) => "a voice per key at its pitch, each note throwing its next mallet in turn",
            (false, _) => {
                "one voice at the scene's pitch, notes throwing the mallets that list them"
            }
        }
    }

    /// What was compiled, in words (the plugin's compile summary, the
    /// offline render's).
    pub fn summary(&self) -> String {
        let m = &self.sc.model;
        format!(
            "several contacts, played as a kit: {} modes, {} mallets, {} masses, {} contacts \
             ({} phases, all compiled), largest phase {} states (per sample O(states)), {}, \
             {} switching",
            m.freq_hz.len(),
            self.mallets,
            m.masses.len(),
            m.contacts.len(),
            self.sc.phases.len(),
            self.max_dim(),
            self.notes_rule(),
            self.sc.switching.as_str(),
        )
    }

    /// The largest state dimension of its phases.
    pub fn max_dim(&self) -> usize {
        self.sc.max_dim()
    }

    /// The compile a kit voice runs on (`at`, or the nearest level the kit
    /// has compiled: a missing position level at the same hardness, a
    /// missing damper level on the parameter's damped compile).
    pub fn sc_for(&self, at: KitAt) -> &CompiledMulti {
        compile_for(&self.sc, &self.damped, &self.levels, at)
    }

    /// The compile `at` names as the kit has it: once damped, the damped
    /// compile of its damper level if compiled (a level whose damper is 0:
    /// not damped, it rings on), else the parameter's damped compile if
    /// any (a released voice throws nothing: at hardness and position 0);
    /// else its (hardness, position) level if compiled, else its hardness
    /// level at the parameter's position, else the played compile.
    pub(super) fn resolve(&self, at: KitAt) -> KitAt {
        lookup(&self.sc, &self.damped, &self.levels, at).0
    }

    /// Install the compiles of the other levels: `played` at (hardness,
    /// position) levels, `damped` at damper levels (`None`: that level's
    /// damper is 0). Each must carry a state of the played compile both
    /// ways ([`MultiState::carry`]), else it is left out. \[worker\]
    pub(super) fn set_levels(
        &mut self,
        played: Vec<((i8, i8), CompiledMulti)>,
        damped: Vec<(i8, Option<CompiledMulti>)>,
    ) {
        let mut probe = MultiState::new(&self.sc);
        probe.rest(&self.sc);
        let mut fits = |c: &CompiledMulti| probe.carry(&self.sc, c) && probe.carry(c, &self.sc);
        for ((h, p), c) in played {
            if (h, p) != (0, 0) && fits(&c) {
                self.levels.played[cell(h, p)] = Some(c);
            }
        }
        for (d, c) in damped {
            if d == 0 {
                continue;
            }
            match c {
                Some(c) if fits(&c) => self.levels.damped[slot(d)] = Some(Some(c)),
                Some(_) => {}
                None => self.levels.damped[slot(d)] = Some(None),
            }
        }
    }

    /// How many hardness levels are compiled besides the played one (at
    /// the parameter's strike position).
    pub fn hardness_levels(&self) -> usize {
        (-TIMBRE_LEVEL_MAX..=TIMBRE_LEVEL_MAX)
            .filter(|&h| h != 0 && self.levels.played[cell(h, 0)].is_some())
            .count()
    }

    /// How many (hardness, position) levels off the parameter's position
    /// are compiled.
    pub fn position_levels(&self) -> usize {
        let all = self.levels.played.iter().filter(|c| c.is_some()).count();
        all - self.hardness_levels()
    }

    /// How many damper levels besides the parameter's are known (compiled,
    /// or of damper 0).
    pub fn damper_levels(&self) -> usize {
        self.levels.damped.iter().filter(|c| c.is_some()).count()
    }

    /// How many compiles of other levels it holds (hardness, position,
    /// damper).
    pub fn level_count(&self) -> usize {
        self.levels.played.iter().filter(|c| c.is_some()).count()
            + self
                .levels
                .damped
                .iter()
                .filter(|d| matches!(d, Some(Some(_))))
                .count()
    }

    /// Whether any compile besides the played one exists (a voice may run
    /// on another).
    pub(super) fn has_other_compiles(&self) -> bool {
        self.damped.is_some()
            || self.levels.played.iter().any(Option::is_some)
            || self
                .levels
                .damped
                .iter()
                .any(|d| matches!(d, Some(Some(_))))
    }

    /// Most throws that can start at one instant: a voice each when
    /// pitched, else every mallet.
    pub fn most_at_once(&self) -> usize {
        if self.pitched {
            MAX_KIT_VOICES
        } else {
            self.mallets
        }
    }

    /// Tick kit voice `i`'s `len` samples into `buf` with a linear gain
    /// ramp `g0 - k dg`, calling `look` (if any: the live view) on the
    /// state before each sample, else as one block; false if a sample was
    /// not a number (the voice then rests). \[audio-thread\]
    pub(super) fn tick_into(
        &mut self,
        (i, at): (usize, KitAt),
        buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
        len: usize,
        (g0, dg): (f64, f64),
        look: Option<impl FnMut(usize, &MultiState, &CompiledMulti)>,
    ) -> bool {
        let sc = compile_for(&self.sc, &self.damped, &self.levels, at);
        tick_state(&mut self.voices[i].st, sc, buf, len, (g0, dg), look)
    }

    /// Tick spare state `f` (a stolen kit voice fading out) `len` samples
    /// into `buf`, without a gain (the fade's is the caller's); false if a
    /// sample was not a number (the state then rests). \[audio-thread\]
    pub(super) fn tick_spare_into(
        &mut self,
        (f, at): (usize, KitAt),
        buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
        len: usize,
    ) -> bool {
        let sc = compile_for(&self.sc, &self.damped, &self.levels, at);
        tick_state(
            &mut self.spares[f],
            sc,
            buf,
            len,
            (1.0, 0.0),
            None::<fn(usize, &MultiState, &CompiledMulti)>,
        )
    }

    /// Take over the running state of kit voice `i` of `old`, a kit of
    /// the same scene compiled with other parameters, while none of its
    /// contacts is closed ([`MultiState::carry`]: the physical state and
    /// so the energy unchanged), with its pitch, its turn, its keys and
    /// its silence test's references; `old` keeps this kit's fresh state
    /// (to be retired). `at`: the compile of `old` the voice runs on; it
    /// goes on the same one of this kit (the nearest it has: [`resolve`]).
    /// The compile it now runs on, or `None` (nothing changed) when a
    /// contact is closed, the bodies differ or the new kit has no such
    /// voice. Allocation-free. \[audio-thread\]
    ///
    /// [`resolve`]: Kit::resolve
    pub(super) fn take_over(&mut self, old: &mut Kit, (i, at): (usize, KitAt)) -> Option<KitAt> {
        if self.mallets != old.mallets || i >= self.voices.len() || i >= old.voices.len() {
            return None;
        }
        let to_at = self.resolve(at);
        let from_sc = compile_for(&old.sc, &old.damped, &old.levels, at);
        let to_sc = compile_for(&self.sc, &self.damped, &self.levels, to_at);
        let (to, from) = (&mut self.voices[i], &mut old.voices[i]);
        if !from.st.carry(from_sc, to_sc) {
            return None;
        }
        std::mem::swap(&mut to.st, &mut from.st);
        to.next = from.next;
        to.last_key = from.last_key;
        to.peak = from.peak;
        to.interval_peak = from.interval_peak;
        to.strike_energy = from.strike_energy;
        Some(to_at)
    }

    /// Carry kit voice `i` from the compile it runs on (`at`) to the one it
    /// wants (`want`, the nearest the kit has: [`Kit::resolve`]; the damped
    /// one for a released voice, else its note's hardness level), while no
    /// contact is closed ([`MultiState::carry`]: the physical state, so the
    /// energy, unchanged). The compile it runs on afterwards; unchanged
    /// when a contact is closed (a later grid step tries again). O(dim^2)
    /// when it moves, allocation-free. \[audio-thread\]
    pub(super) fn settle(&mut self, i: usize, at: KitAt, want: KitAt) -> KitAt {
        let want = self.resolve(want);
        if want == at || i >= self.voices.len() {
            return at;
        }
        let from = compile_for(&self.sc, &self.damped, &self.levels, at);
        let to = compile_for(&self.sc, &self.damped, &self.levels, want);
        // the same compile under another name (a level not compiled, a
        // damper level that only matters once released): nothing to carry
        if std::ptr::eq(from, to) || self.voices[i].st.carry(from, to) {
            want
        } else {
            at
        }
    }

    /// How loud kit voice `i` is, as a steal compares kit voices: its
    /// output's peak since its last throw (0 for no such voice).
    pub(super) fn loudness(&self, i: usize) -> f64 {
        self.voices
            .get(i)
            .map_or(0.0, |kv| kv.interval_peak.max(kv.peak))
    }

    /// The running state of kit voice 0 (tests, tools). \[audio-thread\]
    pub fn state(&self) -> &MultiState {
        &self.voices[0].st
    }

    /// The running state of kit voice `i` (tests, tools). \[audio-thread\]
    pub fn voice_state(&self, i: usize) -> Option<&MultiState> {
        self.voices.get(i).map(|v| &v.st)
    }

    /// The contacts started by every kit voice (and by the stolen ones
    /// fading out in its spare states), per contact.
    pub fn contacts_started(&self) -> [u64; MAX_SPRINGS] {
        let mut out = [0; MAX_SPRINGS];
        for st in self.voices.iter().map(|v| &v.st).chain(&self.spares) {
            for (o, c) in out.iter_mut().zip(st.stats.contacts_started) {
                *o += c;
            }
        }
        out
    }
}

impl Kit {
    /// The mallets a note on `key` throws on kit voice `idx`, one bit
    /// each: on a pitched kit the voice's next mallet in turn (from the
    /// first unless `same`, the voice already sounding this key), else the
    /// key's mallets. \[audio-thread\]
    fn mallets_for(&mut self, idx: usize, key: u8, same: bool) -> u8 {
        if self.pitched {
            let kv = &mut self.voices[idx];
            if !same {
                kv.next = 0;
            }
            let i = kv.next;
            kv.next = (kv.next + 1) % self.mallets;
            1u8 << i
        } else {
            self.keys[usize::from(key.min(127))]
        }
    }

    /// Kit voice `idx`'s mallets in `which` thrown down at `speed` (m/s)
    /// from `height` (m) for a note on `key`; a throw the state refuses is
    /// counted. A throw restarts the silence test's references.
    /// \[audio-thread\]
    fn throw(&mut self, (idx, at): (usize, KitAt), which: u8, key: u8, speed: f64, height: f64) {
        let sc = compile_for(&self.sc, &self.damped, &self.levels, at);
        let kv = &mut self.voices[idx];
        let g = sc.model.gravity_m_per_s2;
        // the model's units: a physical speed is `scale` times the model's
        let v_model = speed / kv.st.time_scale();
        let mut energy = 0.0;
        for i in 0..self.mallets {
            if which & (1 << i) == 0 {
                continue;
            }
            if kv.st.strike(sc, i, height, -v_model).is_ok() {
                let m = sc.model.masses[i].mass_kg;
                energy += 0.5 * m * v_model * v_model + m * g * height;
                kv.last_key[i] = key;
            } else {
                self.refused += 1;
            }
        }
        if energy > 0.0 {
            // a new throw: the silence test's references start again
            kv.strike_energy = energy;
            kv.peak = 0.0;
        }
    }
}

/// The compile voice `v` (a kit voice's slot) runs on.
pub(super) fn kit_at(v: &super::Voice) -> KitAt {
    KitAt::of(v.at, v.on_damped)
}

/// The compile voice `v` wants: the damped one (of its damper level) once
/// released, else its note's hardness and position levels.
fn kit_want(v: &super::Voice) -> KitAt {
    KitAt::of(v.want, v.released)
}

/// Voice `v` now runs on `at`.
pub(super) fn set_kit_at(v: &mut super::Voice, at: KitAt) {
    v.at.hard = at.hard;
    v.at.pos = at.pos;
    v.at.damper = at.damper;
    v.on_damped = at.damped;
}

/// Which of a kit's compiles a kit voice runs on: its hardness and
/// strike-position levels (0: the parameters' own), its damper level, and
/// whether it runs on a damped compile (a released voice's; then at
/// hardness and position 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KitAt {
    /// The hardness level, `-TIMBRE_LEVEL_MAX ..= TIMBRE_LEVEL_MAX`.
    pub hard: i8,
    /// The strike-position level, `-TIMBRE_LEVEL_MAX ..= TIMBRE_LEVEL_MAX`.
    pub pos: i8,
    /// The damper level, `-TIMBRE_LEVEL_MAX ..= TIMBRE_LEVEL_MAX` (what a
    /// release damps with).
    pub damper: i8,
    /// A damped compile.
    pub damped: bool,
}

impl KitAt {
    /// The compile a voice's levels `at` name, damped or not.
    pub(super) fn of(at: super::Variant, damped: bool) -> Self {
        Self {
            hard: at.hard,
            pos: at.pos,
            damper: at.damper,
            damped,
        }
    }
}

/// A kit's compiles at other levels than the parameters' (docs/plugin.md,
/// "Polyphonic modulation").
#[derive(Clone)]
pub(super) struct KitLevels {
    /// By [`cell`]`(hardness, position)`: the scene with every mallet's
    /// spring (or law) times [`super::TIMBRE_STIFFNESS_STEP`]`^hardness`
    /// and the strike point moved by `position` times
    /// [`super::POSITION_STEP`]; `None` at (0, 0) (that is [`Kit::sc`])
    /// and where not compiled.
    played: Vec<Option<CompiledMulti>>,
    /// By [`slot`]`(damper)`: the damped compile with the damper plus
    /// `damper` times [`super::DAMPER_STEP`]; `Some(None)` where that
    /// damper is 0 (a released voice rings on); `None` at 0 (that is
    /// [`Kit::damped`]) and where not compiled.
    damped: Vec<Option<Option<CompiledMulti>>>,
}

impl KitLevels {
    /// No level compiled.
    fn none() -> Self {
        Self {
            played: (0..LEVELS * LEVELS).map(|_| None).collect(),
            damped: (0..LEVELS).map(|_| None).collect(),
        }
    }
}

/// Levels of each axis.
const LEVELS: usize = 2 * TIMBRE_LEVEL_MAX as usize + 1;

/// The index of `level` on an axis (clamped to the levels).
fn slot(level: i8) -> usize {
    (level.clamp(-TIMBRE_LEVEL_MAX, TIMBRE_LEVEL_MAX) + TIMBRE_LEVEL_MAX) as usize
}

/// The index of (hardness, position) levels in [`KitLevels::played`].
fn cell(hard: i8, pos: i8) -> usize {
    slot(hard) * LEVELS + slot(pos)
}

/// The compile `at` names among a kit's fields, the nearest compiled
/// ([`Kit::resolve`]), and its name.
fn lookup<'a>(
    sc: &'a CompiledMulti,
    damped: &'a Option<CompiledMulti>,
    levels: &'a KitLevels,
    at: KitAt,
) -> (KitAt, &'a CompiledMulti) {
    let (h, p, d) = (at.hard, at.pos, at.damper);
    if at.damped {
        let released = |damper| KitAt {
            hard: 0,
            pos: 0,
            damper,
            damped: true,
        };
        match levels.damped.get(slot(d)) {
            Some(Some(Some(c))) if d != 0 => return (released(d), c),
            // that level's damper is 0: the voice rings on, undamped
            Some(Some(None)) if d != 0 => {}
            _ => {
                if let Some(c) = damped {
                    return (released(0), c);
                }
            }
        }
    }
    let played = |h, p| levels.played.get(cell(h, p)).and_then(Option::as_ref);
    let name = |hard, pos| KitAt {
        hard,
        pos,
        damper: d,
        damped: false,
    };
    if (h, p) == (0, 0) {
        return (name(0, 0), sc);
    }
    if let Some(c) = played(h, p) {
        return (name(h, p), c);
    }
    match played(h, 0) {
        Some(c) if h != 0 => (name(h, 0), c),
        _ => (name(0, 0), sc),
    }
}

/// The compile `at` names among a kit's fields (the nearest compiled:
/// [`Kit::sc_for`] on the fields, so the voices can be borrowed beside
/// them).
pub(super) fn compile_for<'a>(
    sc: &'a CompiledMulti,
    damped: &'a Option<CompiledMulti>,
    levels: &'a KitLevels,
    at: KitAt,
) -> &'a CompiledMulti {
    lookup(sc, damped, levels, at).1
}

/// Tick `st` `len` samples into `buf` with a linear gain ramp
/// `g0 - k dg`, calling `look` (if any) on the state before each sample;
/// without one, the samples run as one block on the engine's block path
/// (the same samples bit for bit). False if a sample was not a number (the
/// state then rests). \[audio-thread\]
fn tick_state(
    st: &mut MultiState,
    sc: &CompiledMulti,
    buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
    (g0, dg): (f64, f64),
    look: Option<impl FnMut(usize, &MultiState, &CompiledMulti)>,
) -> bool {
    let [b0, b1] = buf;
    match look {
        Some(mut look) => {
            for k in 0..len {
                look(k, st, sc);
                [b0[k], b1[k]] = st.tick(sc);
            }
        }
        None => st.process_block(sc, &mut b0[..len], &mut b1[..len]),
    }
    let mut finite = true;
    for k in 0..len {
        finite &= b0[k].is_finite() && b1[k].is_finite();
        let g = (g0 - k as f64 * dg).max(0.0);
        b0[k] *= g;
        b1[k] *= g;
    }
    if !finite {
        st.rest(sc);
    }
    finite
}

impl KitVoice {
    /// Its time scale to `s` as a bend does
    /// ([`MultiState::bend_time_scale`]); the silence test's throw energy
    /// follows the model's units. `Ok(false)`: a contact is closed, later.
    fn retune(&mut self, sc: &CompiledMulti, s: f64) -> Result<bool, TimeScaleError> {
        let s_old = self.st.time_scale();
        if s == s_old {
            return Ok(true);
        }
        let done = self.st.bend_time_scale(sc, s)?;
        if done {
            let r = s_old / s;
            self.strike_energy *= r * r;
        }
        Ok(done)
    }
}

impl Instrument {
    /// A note on a kit: the kit voice it plays (its key's, a free one, or
    /// the quietest, woken at rest at the key's pitch; the only one of an
    /// unpitched kit), then its mallets thrown. \[audio-thread\]
    pub(super) fn kit_note_on(&mut self, key: u8, velocity_norm: f64) {
        let speed = impact_speed_m_per_s(velocity_norm);
        let drop = self.play.drop_height_m.max(0.0);
        let tracking = self.play.pitch_tracking;
        let poly = self.play.polyphony.clamp(1, super::MAX_VOICES);
        let root = self.cur.root_note;
        let Some(kit) = self.cur.kit.as_deref() else {
            return;
        };
        self.stats.notes += 1;
        let (pitched, kits) = (kit.pitched, kit.voices.len().min(super::MAX_VOICES));
        let idx = if !pitched {
            0
        } else {
            self.pitched_kit_voice(key, kits, poly)
        };
        let v = self.voices[idx];
        let wake = !v.active || v.key != key && pitched;
        // stolen while it sounds: its running state fades out in a spare
        // (docs/plugin.md, "Velocity, pitch, voices")
        if wake && v.active && self.fade_voice(idx, false) {
            self.stats.steals_faded += 1;
        }
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        let same = self.voices[idx].active && self.voices[idx].key == key;
        let which = kit.mallets_for(idx, key, same);
        if which == 0 {
            return;
        }
        if wake {
            self.wake_kit_voice(idx, key, tracking, root);
        } else {
            self.renote_kit_voice(idx);
        }
        let v = &mut self.voices[idx];
        v.key = key;
        v.onset_pos = self.sample_pos;
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        let height = if kit.bouncing { drop } else { 0.0 };
        kit.throw((idx, kit_at(v)), which, key, speed, height);
        self.press_decide(idx);
    }

    /// The kit voice a note on `key` plays on a pitched kit of `kits`
    /// voices: its key's voice, a free one while fewer than `poly` sound,
    /// else the quietest (a steal, counted). \[audio-thread\]
    fn pitched_kit_voice(&mut self, key: u8, kits: usize, poly: usize) -> usize {
        // its key's voice, a free one while fewer than the limit
        // sound, else the quietest (the voices that sound may be any:
        // a lowered Polyphony ends the quietest, wherever they are)
        let voices = &self.voices[..kits];
        let own = voices.iter().position(|v| v.active && v.key == key);
        let sounding = voices.iter().filter(|v| v.active).count();
        let free = voices.iter().position(|v| !v.active);
        match own.or(free.filter(|_| sounding < kits.min(poly))) {
            Some(i) => i,
            None => {
                self.stats.steals += 1;
                let mut among = [false; super::MAX_VOICES];
                (0..kits).for_each(|i| among[i] = self.voices[i].active);
                self.quietest(&among).unwrap_or(0)
            }
        }
    }

    /// Kit voice `idx` woken (or stolen) at rest for a note on `key`, at
    /// the key's pitch (with `tracking`, about `root`) and the bend.
    /// \[audio-thread\]
    fn wake_kit_voice(&mut self, idx: usize, key: u8, tracking: bool, root: f64) {
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        let v = &mut self.voices[idx];
        let others = kit.has_other_compiles();
        let kv = &mut kit.voices[idx];
        if others {
            // its state may have run on another compile (its own, or a
            // fade's it was swapped with): the played one's tables from here
            kv.st.forget_tables();
        }
        // a new note: the played compile, its note's levels, pressure and
        // tuning reset (a sounding voice's damper was taken when it faded)
        v.on_damped = false;
        v.released = false;
        v.at = super::Variant::default();
        v.want = super::Variant::default();
        v.bright_level = 0;
        v.hard_level = 0;
        v.pressure = 0.0;
        v.pressing = None;
        // woken (or stolen) at rest, at the key's pitch and the bend
        let base = if kit.pitched && tracking {
            super::mapping::key_scale(key, root)
        } else {
            1.0
        };
        let scale = if kit.bouncing {
            base
        } else {
            base * 2f64.powf(self.bend_now / 12.0)
        };
        if kv.st.set_time_scale(&kit.sc, scale).is_err() {
            // (a key's scale and the bend are finite and positive; were
            // they not, the voice would play at the scene's pitch)
            let _ = kv.st.set_time_scale(&kit.sc, 1.0);
        }
        kv.st.rest(&kit.sc);
        kv.peak = 0.0;
        kv.interval_peak = 0.0;
        if !v.active {
            self.lanes.begin(idx, self.sample_pos);
        }
        v.active = true;
        v.fresh = true;
        v.base_scale = base;
        v.tuning_now = 0.0;
        v.tuning_target = 0.0;
    }

    /// A new note on kit voice `idx` while it rings: it starts untuned,
    /// without its note's pressure, back on the played compile at level 0
    /// (while a contact is closed it stays where it is until a later grid
    /// step carries it).
    fn renote_kit_voice(&mut self, idx: usize) {
        self.press_flush(idx);
        let v = &mut self.voices[idx];
        // a new note on its ringing voice
        v.released = false;
        v.want = super::Variant::default();
        v.bright_level = 0;
        v.hard_level = 0;
        v.pressure = 0.0;
        if let Some(kit) = self.cur.kit.as_deref_mut() {
            set_kit_at(v, kit.settle(idx, kit_at(v), kit_want(v)));
        }
        v.fresh = false;
        if v.tuning_target != 0.0 || v.tuning_now != 0.0 {
            // a new note starts untuned (from where it is, gliding)
            v.tuning_target = 0.0;
            self.tuning_moving = true;
        }
    }

    /// One update of a moving bend or tuning on a kit (the voices' rule,
    /// [`Instrument::bend_tick`]): every sounding kit voice steps its
    /// tuning and takes its new time scale without adding or removing
    /// energy ([`MultiState::bend_time_scale`]); one with a contact closed
    /// takes it at a later update. Bouncing kits are not bent (gravity
    /// would change with the time axis). Whether a voice waits, and
    /// whether a tuning still moves. O(voices N), allocation-free.
    /// \[audio-thread\]
    pub(super) fn kit_bend_tick(&mut self, step: f64) -> (bool, bool) {
        let (mut pending, mut moving) = (false, false);
        let Some(kit) = self.cur.kit.as_deref() else {
            return (false, false);
        };
        let (n, bouncing) = (kit.voices.len().min(super::MAX_VOICES), kit.bouncing);
        for i in 0..n {
            let v = &mut self.voices[i];
            if !v.active {
                continue;
            }
            v.tuning_now = super::slew(v.tuning_now, v.tuning_target, step);
            if bouncing {
                continue;
            }
            moving |= v.tuning_now != v.tuning_target;
            let s = v.base_scale * 2f64.powf((self.bend_now + v.tuning_now) / 12.0);
            if self.retune_kit_voice(i, s) == Ok(false) {
                pending = true;
            }
        }
        (pending, moving)
    }

    /// Kit voice `i` to the time scale `s` ([`KitVoice::retune`]); a
    /// pressed one takes its damper's decay first and is decided again at
    /// its new pitch. \[audio-thread\]
    fn retune_kit_voice(&mut self, i: usize, s: f64) -> Result<bool, TimeScaleError> {
        let Some(kit) = self.cur.kit.as_deref() else {
            return Ok(true);
        };
        if kit.voices[i].st.time_scale() == s {
            return Ok(true);
        }
        self.press_flush(i);
        let at = kit_at(&self.voices[i]);
        let Some(Kit {
            voices,
            sc,
            damped,
            levels,
            ..
        }) = self.cur.kit.as_deref_mut()
        else {
            return Ok(true);
        };
        let done = voices[i].retune(compile_for(sc, damped, levels, at), s);
        self.press_decide(i);
        done
    }

    /// A per-note tuning on a kit: a pitched kit's voice of that key (or
    /// every voice) glides to it, or at its note's onset, with no contact
    /// closed, starts there; a kit whose mallets list notes is one voice
    /// for every key, so only a tuning of every note (`key` none) moves
    /// it. \[audio-thread\]
    pub(super) fn kit_note_tuning(&mut self, key: Option<u8>, t: f64) {
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        if kit.bouncing || !kit.pitched && key.is_some() {
            return;
        }
        // the voices of `key` fading out glide to it too
        let mut fading = false;
        for fades in [&mut self.steal_fades, &mut self.old_steal_fades] {
            for fade in fades.iter_mut().flatten() {
                if key.is_none_or(|k| k == fade.key) {
                    fade.tuning_target = t;
                    fading |= fade.tuning_now != t;
                }
            }
        }
        self.tuning_moving |= fading;
        for i in 0..kit.voices.len().min(super::MAX_VOICES) {
            let v = &mut self.voices[i];
            if !v.active || key.is_some_and(|k| k != v.key) {
                continue;
            }
            v.tuning_target = t;
            if v.tuning_now == t {
                continue;
            }
            if v.onset_pos == self.sample_pos {
                let s = v.base_scale * 2f64.powf((self.bend_now + t) / 12.0);
                if let Ok(true) = self.retune_kit_voice(i, s) {
                    self.voices[i].tuning_now = t;
                    continue;
                }
            }
            self.tuning_moving = true;
        }
    }

    /// Render kit voice `i`'s chunk of `len` samples starting at time `t0`
    /// into `vbuf` (voice `i`'s lane takes it); the contacts it started,
    /// or `None` when a sample was not a number (the voice rests and
    /// stops: nothing of that chunk sounds). With the live view on, every
    /// contact is shown as a voice of its own (voice `4 i + j` for contact
    /// `j`: its upper side as the hammer, its lower side as the contact
    /// point; a mallet's contact under the key that last threw it).
    /// \[audio-thread\]
    pub(super) fn kit_render(&mut self, i: usize, t0: u64, len: usize) -> Option<u64> {
        let kit = self.cur.kit.as_deref_mut()?;
        if i >= kit.voices.len() {
            self.voices[i].active = false;
            return None;
        }
        let started: u64 = kit.voices[i].st.stats.contacts_started.iter().sum();
        let observe = self.probe_on && self.probe.is_some();
        let contacts = kit.sc.contacts();
        let motion = &mut self.kit_motion;
        let look = |k: usize, st: &MultiState, sc: &CompiledMulti| {
            let o = st.observe(sc);
            let s = st.time_scale();
            for (j, m) in motion.iter_mut().enumerate().take(contacts) {
                m[k] = crate::engine::Motion {
                    x_hammer: o.x_hammer[j],
                    v_hammer: o.v_hammer[j] * s,
                    x_contact: o.x_contact[j],
                    v_contact: o.v_contact[j] * s,
                    in_contact: o.active & (1 << j) != 0,
                };
            }
        };
        let at = kit_at(&self.voices[i]);
        let finite = kit.tick_into(
            (i, at),
            &mut self.vbuf,
            len,
            (1.0, 0.0),
            observe.then_some(look),
        );
        if !finite {
            self.voices[i].active = false;
            self.stats.nonfinite_resets += 1;
            return None;
        }
        // damper pressure (docs/plugin.md, "Pressure and the mod wheel"):
        // no contact of the voice could close when it was last decided, so
        // its pressed motion is the free motion with the objects' part
        // times the damper's decay, sample by sample
        let mut pressed = 1.0;
        if let Some(pr) = self.voices[i].pressing.as_mut() {
            if observe {
                for (ct, m) in kit.sc.model.contacts.iter().zip(&mut self.kit_motion) {
                    let mut g = pr.g;
                    for mk in &mut m[..len] {
                        if matches!(ct.lower, MultiEnd::Point(_)) {
                            mk.x_contact *= g;
                            mk.v_contact *= g;
                        }
                        if matches!(ct.upper, MultiEnd::Point(_)) {
                            mk.x_hammer *= g;
                            mk.v_hammer *= g;
                        }
                        g *= pr.q;
                    }
                }
            }
            pr.g = super::decay_into(&mut self.vbuf, len, pr.g, pr.q, None);
            pressed = pr.g;
            self.stats.pressed_samples += len as u64;
        }
        let kv = &mut kit.voices[i];
        let mut peak = kv.interval_peak;
        for k in 0..len {
            peak = peak.max(self.vbuf[0][k].abs()).max(self.vbuf[1][k].abs());
        }
        kv.interval_peak = peak;
        kv.peak = kv.peak.max(peak);
        if observe {
            // physical energy: the model's times the scale squared
            let s = kv.st.time_scale();
            let sc = compile_for(&kit.sc, &kit.damped, &kit.levels, at);
            let energy_j = kv.st.energy_objects_scaled(sc, pressed) * s * s;
            if let Some(probe) = self.probe.as_deref_mut() {
                // a law's further pieces move as its first does: one lane
                for j in (0..contacts).filter(|&j| !sc.is_stage(j)) {
                    probe.voice_chunk(&super::VoiceChunk {
                        voice: i * MAX_SPRINGS + j,
                        key: kv.last_key[j],
                        released: self.voices[i].released,
                        start: t0,
                        motion: &self.kit_motion[j][..len],
                        energy_j: Some(energy_j),
                        path_m: None,
                    });
                }
            }
        }
        let now: u64 = kv.st.stats.contacts_started.iter().sum();
        Some(now - started)
    }

    /// A note's brightness or hardness modulation on a kit (`set` on the
    /// voices of `key`, every voice for `None`; a kit of listed notes is
    /// its last note's): each kit voice goes on its note's hardness level
    /// now, or while a contact of it is closed at a later grid step
    /// ([`Kit::settle`]); a released one stays on the damped compile.
    /// \[audio-thread\]
    pub(super) fn kit_want_levels(&mut self, key: Option<u8>, set: impl Fn(&mut super::Voice)) {
        let Some(kit) = self.cur.kit.as_deref() else {
            return;
        };
        for i in 0..kit.voices.len().min(super::MAX_VOICES) {
            let v = &mut self.voices[i];
            if !v.active || key.is_some_and(|k| k != v.key) {
                continue;
            }
            set(v);
            v.want.hard = super::wanted_level(v.bright_level, v.hard_level);
            if kit_at(v) == kit_want(v) {
                continue;
            }
            self.press_flush(i);
            let Some(kit) = self.cur.kit.as_deref_mut() else {
                return;
            };
            let v = &mut self.voices[i];
            set_kit_at(v, kit.settle(i, kit_at(v), kit_want(v)));
            self.press_decide(i);
        }
    }

    /// A note-off on a kit (after the pedals): every sounding kit voice of
    /// `key` (every one for `None`; a kit of listed notes is its last
    /// note's) is released and carried to the damped compile, if the kit
    /// has one, now or, while a contact is closed, at a later step of the
    /// silence-check grid ([`Kit::settle`]). O(dim^2) per voice
    /// carried, allocation-free. \[audio-thread\]
    pub(super) fn kit_note_off(&mut self, key: Option<u8>) {
        let Some(kit) = self.cur.kit.as_deref() else {
            return;
        };
        for i in 0..kit.voices.len().min(super::MAX_VOICES) {
            let v = self.voices[i];
            if !v.active || v.released || key.is_some_and(|k| k != v.key) {
                continue;
            }
            self.press_flush(i);
            let Some(kit) = self.cur.kit.as_deref_mut() else {
                return;
            };
            let v = &mut self.voices[i];
            v.released = true;
            set_kit_at(v, kit.settle(i, kit_at(v), kit_want(v)));
            self.press_decide(i);
        }
    }

    /// Kit voice `i`'s silence check (on the silence-check grid): it stops,
    /// as a voice of one contact does, when no contact of it is closed and
    /// its objects' energy ([`MultiState::objects_energy`]) and the masses
    /// that may still land hold less than [`SILENCE_ENERGY_RATIO`] of its
    /// last throw's energy; with a contact closed (a mass lying on an
    /// object), when its last interval's output stayed below
    /// [`SILENCE_AMPLITUDE_RATIO`] of its loudest since the throw and the
    /// masses that may land hardly move. \[audio-thread\]
    pub(super) fn kit_silence(&mut self, i: usize) {
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        if !self.voices[i].active || i >= kit.voices.len() {
            return;
        }
        // a voice that waited for its contacts to open goes on the
        // compile it wants now: the damped one when released, else its
        // note's hardness level
        let v = &mut self.voices[i];
        set_kit_at(v, kit.settle(i, kit_at(v), kit_want(v)));
        let sc = compile_for(&kit.sc, &kit.damped, &kit.levels, kit_at(v));
        let kv = &mut kit.voices[i];
        let quiet = kv.interval_peak < SILENCE_AMPLITUDE_RATIO * kv.peak;
        kv.interval_peak = 0.0;
        let floor = SILENCE_ENERGY_RATIO * kv.strike_energy;
        let landing = kv.st.masses_to_land(sc);
        let silent = match kv.st.objects_energy() {
            // no contact closed: the rule of a voice of one contact
            Some(objects) => objects + landing < floor,
            // a contact closed at rest (a mass lying on an object under
            // gravity holds its spring's and its objects' static energy):
            // its output, and the masses that may land hardly moving
            None => quiet && landing < floor,
        };
        if silent {
            self.voices[i].active = false;
            self.stats.silent_stops += 1;
        }
    }
}
