//! Plugin glue (nice-plug, CLAP + VST3): parameters, MIDI -> [`Event`], the
//! worker handoff, and the export macros. All voice logic is in
//! [`crate::instrument`]; this file only moves data between the host and it.
//!
//! Threads: `activate`/`deactivate` run on the main thread and may allocate,
//! but never wait long: `activate` asks the worker for the first scene and
//! waits at most [`worker::ACTIVATE_WAIT_MS`] for it (a scene that takes
//! longer is installed by the first block after it is ready: until then
//! the instance is silent, and an offline render waits for it);
//! `deactivate` cancels the worker's compile and never joins it (the worker
//! lives as long as the instance: docs/design.md, "The plugin
//! and its threads"). `process` runs on the audio thread: it only does atomic
//! loads of the parameters, lock-free queue operations and the
//! instrument's allocation-free rendering.
//!
//! Latency (the Lookahead parameter): CLAP allows a new latency only from
//! `activate`, so a CLAP instance keeps the lookahead it was activated with
//! and asks the host to restart it when the parameter moves; the VST3 and
//! standalone wrappers report a new latency from `process` as their APIs
//! allow (docs/plugin.md, "Lookahead").

pub mod browser;
pub mod clap_entry;
pub mod editor;
pub mod import;
pub mod live;
pub mod mpe;
pub mod params;
pub mod poly;
pub mod user_scene;
pub mod voice_ids;
pub mod waits;
pub mod worker;

use crate::instrument::{
    lookahead_samples, Event, Instrument, PlayParams, SceneParams, Stage, TimedEvent, VoiceProbe,
    MAX_VOICES,
};
use crossbeam::queue::ArrayQueue;
use live::{LiveProbe, LiveRing, RING_FRAMES};
use nice_plug::midi::{Channel, Key, VoiceID};
use nice_plug::prelude::*;
use nice_plug::util::permit_alloc;
use params::ModalContactParams;
use std::sync::Arc;
use worker::{CompileRequest, Handoff, Worker};

/// The plugin.
pub struct ModalContact {
    params: Arc<ModalContactParams>,
    /// Audio thread owns it between activate and deactivate (built on the
    /// worker around the activation's first scene).
    instrument: Option<Box<Instrument>>,
    /// Shared with the worker (queues, counters).
    handoff: Arc<Handoff>,
    /// Main thread: spawned at the first activation, joined when the
    /// instance is dropped.
    worker: Option<Worker>,
    /// Audio thread: the last parameter set requested (or compiled in activate).
    requested: SceneParams,
    /// Request revision counter: increases across activations (a scene of
    /// an older activation is never installed).
    revision: u64,
    /// The revision of this activation's first scene.
    first_revision: u64,
    /// The revision of the scene the instrument should play now (the last
    /// request posted, or the kept scene's).
    latest_request: u64,
    /// The live view's probe, until the first instrument takes it.
    probe: Option<Box<dyn VoiceProbe>>,
    /// The host renders offline: `process` waits for the scenes it asked
    /// for (an offline render never depends on the worker's timing).
    offline: bool,
    /// The lookahead this activation reports as its latency \[s\] (CLAP:
    /// fixed until the host restarts the instance).
    active_lookahead_s: f64,
    /// A CLAP restart was asked for the Lookahead's new value.
    restart_requested: bool,
    /// The last activation's scene set, kept for the next one when it
    /// asks for the same parameters at the same rate (a host's restart
    /// for a new latency or block size then compiles nothing): the rate,
    /// the parameters it was requested for, the scenes.
    parked: Option<(f64, SceneParams, Box<crate::instrument::Prepared>)>,
    /// Audio thread: a scene taken from the queue that could not be installed yet.
    pending: Option<Box<crate::instrument::Prepared>>,
    /// An older activation's instrument taken by mistake, freed on the
    /// main thread.
    pending_first: Option<Box<Instrument>>,
    rate_hz: f64,
    /// The host's largest block \[samples\], from activation.
    max_block: usize,
    /// Panics caught at the process boundary since activation.
    panics: u64,
    /// The live view's ring (the instrument's probe writes, the editor reads).
    ring: Arc<LiveRing>,
    /// Audition pad strikes from the editor.
    pads: Arc<ArrayQueue<Event>>,
    /// Audio thread: MIDI 1.0 MPE (docs/plugin.md, "Per-note tuning").
    mpe: mpe::Mpe,
    /// Audio thread: what the last host event became (MPE may make many).
    translated: mpe::Out,
    /// Audio thread: the host's voice ids and their polyphonic modulation.
    voice_ids: voice_ids::VoiceIds,
    #[cfg(feature = "alloc-bug")]
    leak: Vec<f32>,
}

impl Default for ModalContact {
    fn default() -> Self {
        let params = Arc::new(ModalContactParams::default());
        let requested = params.scene_params();
        Self {
            params,
            instrument: None,
            handoff: Handoff::new(),
            worker: None,
            requested,
            revision: 0,
            first_revision: 0,
            latest_request: 0,
            probe: None,
            offline: false,
            active_lookahead_s: 0.0,
            restart_requested: false,
            parked: None,
            pending: None,
            pending_first: None,
            rate_hz: 0.0,
            max_block: 0,
            panics: 0,
            ring: LiveRing::new(RING_FRAMES),
            pads: Arc::new(ArrayQueue::new(editor::PAD_QUEUE)),
            mpe: mpe::Mpe::default(),
            translated: mpe::Out::new(),
            voice_ids: voice_ids::VoiceIds::default(),
            #[cfg(feature = "alloc-bug")]
            leak: Vec::new(),
        }
    }
}

impl ModalContact {
    /// Hand retired scenes back, swap in a ready one, and post a request if
    /// the matrix parameters moved. Lock-free, allocation-free. \[audio-thread\]
    fn maybe_swap_and_request(&mut self, play: PlayParams) {
        if self.instrument.is_none() {
            self.take_first();
        }
        let Some(inst) = self.instrument.as_mut() else {
            return;
        };
        if self.offline {
            // an offline render takes every scene it asked for at the
            // block it asked for it (allowed to wait: not real time)
            wait_while(&self.handoff, |h| h.compiling());
        }
        for slot in inst.retired_slots_mut() {
            if let Some(b) = slot.take() {
                if let Err(b) = self.handoff.give_back(b) {
                    *slot = Some(b);
                }
            }
        }
        if inst.can_install() {
            let next = self.pending.take().or_else(|| self.handoff.take_ready());
            if let Some(p) = next {
                if p.revision < self.first_revision {
                    // an older activation's (cannot happen: deactivation
                    // drains them); freed on the worker
                    if let Err(p) = self.handoff.give_back(p) {
                        self.pending = Some(p);
                    }
                } else if let Err(p) = inst.install(p) {
                    self.pending = Some(p);
                }
            }
        }
        let wanted = self.params.scene_params();
        if wanted != self.requested {
            let req = CompileRequest {
                revision: self.revision + 1,
                rate_hz: self.rate_hz,
                max_block: self.max_block,
                polyphony: play.polyphony,
                lookahead: inst.lookahead(),
                params: wanted,
                first: None,
                stage: Stage::Full,
                upgrade: false,
            };
            if self.handoff.request(req) {
                self.revision += 1;
                self.latest_request = self.revision;
                self.requested = wanted;
                if self.offline {
                    wait_while(&self.handoff, |h| h.compiling());
                }
            }
        }
        inst.set_play(play);
    }

    /// Take the activation's first instrument if the worker has built it
    /// (an offline render waits for it). Lock-free, allocation-free.
    /// \[audio-thread\] \[main-thread\]
    fn take_first(&mut self) {
        let rev = self.first_revision;
        if self.offline {
            wait_while(&self.handoff, |h| h.compiling() && !h.failed(rev));
        }
        while let Some(inst) = self.handoff.take_first() {
            if inst.prepared().revision < rev {
                // an older activation's (cannot happen: deactivation
                // drains them); kept until the main thread frees it
                self.pending_first = Some(inst);
                continue;
            }
            let mut inst = inst;
            // the probe moves in (no allocation); it records while the
            // editor holds the ring's reading end
            inst.set_probe(self.probe.take());
            self.instrument = Some(inst);
            return;
        }
    }

    /// Cancel the worker's compiles of this activation and free the
    /// instrument; never waits for the worker. \[main-thread\]
    fn shut_down(&mut self) {
        self.handoff.cancel_through(self.revision);
        self.parked = self
            .instrument
            .take()
            // it plays the last request's scene: nothing newer was asked for
            .filter(|inst| inst.prepared().revision == self.latest_request)
            .map(|inst| (self.rate_hz, self.requested, inst.into_prepared()));
        self.pending = None;
        self.pending_first = None;
        self.probe = None;
        self.voice_ids = voice_ids::VoiceIds::default();
    }
}

/// Wait (sleeping, not spinning) while `busy` says so: offline renders only,
/// where the host allows a block to take its time. Bounded by the worker
/// answering every request (a scene, an error, or its cancellation).
fn wait_while(h: &Handoff, busy: impl Fn(&Handoff) -> bool) {
    waits::while_busy(|| busy(h) && !h.stopped(), None);
}

impl Drop for ModalContact {
    fn drop(&mut self) {
        self.shut_down();
        if let Some(mut w) = self.worker.take() {
            w.stop();
        }
        self.handoff.drain();
    }
}

/// The value nice-plug's VST3 wrapper reports for its hidden MIDI
/// controller parameters (not a 7-bit MIDI value).
const VST3_CC_PLACEHOLDER: f32 = 0.5;
/// MIDI controller of the mod wheel.
const MOD_WHEEL_CC: u8 = 1;
/// MIDI controller of MPE's timbre (an MPE member channel's brightness).
const TIMBRE_CC: u8 = 74;
/// MIDI controller of the sustain (damper) pedal.
const SUSTAIN_CC: u8 = 64;
/// MIDI controller of the sostenuto pedal.
const SOSTENUTO_CC: u8 = 66;
/// MIDI channel mode message All Sound Off (controller 120).
const ALL_SOUND_OFF_CC: u8 = 120;
/// MIDI channel mode message Reset All Controllers (controller 121).
const RESET_CONTROLLERS_CC: u8 = 121;
/// MIDI channel mode message All Notes Off (controller 123).
const ALL_NOTES_OFF_CC: u8 = 123;
/// A pedal is down from controller value 64 of 127 (nice-plug gives the
/// value divided by 127).
const PEDAL_DOWN: f32 = 64.0 / 127.0;

fn note_event(event: &NoteEvent<()>) -> Option<Event> {
    match *event {
        NoteEvent::NoteOn { key, velocity, .. } => key.number().map(|key| Event::NoteOn {
            key,
            velocity_norm: velocity as f64,
        }),
        // (a CLAP wildcard key with a note id is that note's:
        // `for_note_id`)
        NoteEvent::NoteOff { key, .. } => Some(match key.number() {
            Some(key) => Event::NoteOff { key },
            None => Event::AllNotesOff,
        }),
        // A CLAP choke: the note stops at once, in the steal's fade
        // (docs/plugin.md, "Velocity, pitch, voices").
        NoteEvent::Choke { key, .. } => Some(Event::Choke { key: key.number() }),
        // MIDI's channel mode messages (docs/plugin.md, "Pedals"); not the
        // VST3 wrapper's placeholder a host restoring a session sends back
        // (see `MidiChannelPressure` below).
        NoteEvent::MidiCC { cc, value, .. }
            if value != VST3_CC_PLACEHOLDER
                && matches!(
                    cc,
                    ALL_SOUND_OFF_CC | RESET_CONTROLLERS_CC | ALL_NOTES_OFF_CC
                ) =>
        {
            Some(match cc {
                ALL_SOUND_OFF_CC => Event::AllSoundOff,
                RESET_CONTROLLERS_CC => Event::ResetControllers,
                _ => Event::AllNotesOff,
            })
        }
        // The pedals (docs/plugin.md, "Pedals"): down from 64 of 127 on,
        // MIDI's convention for switch controllers.
        NoteEvent::MidiCC { cc, value, .. } if cc == SUSTAIN_CC || cc == SOSTENUTO_CC => {
            let down = value >= PEDAL_DOWN;
            Some(if cc == SUSTAIN_CC {
                Event::Sustain { down }
            } else {
                Event::Sostenuto { down }
            })
        }
        // The wheel: nice-plug gives 0 .. 1 with the centre at 0.5.
        // The centre is 8192 of 0..16383, so 0.5 exactly is not on the
        // grid: go back to the 14-bit value, centre 0, ends -1 and 1.
        NoteEvent::MidiPitchBend { value, .. } => {
            let v = if value.is_nan() {
                0.5
            } else {
                f64::from(value)
            };
            let m = (v.clamp(0.0, 1.0) * 16383.0).round() - 8192.0;
            Some(Event::PitchBend {
                value: if m >= 0.0 { m / 8191.0 } else { m / 8192.0 },
            })
        }
        // Per-note tuning (CLAP and VST3 note expressions; nice-plug gives
        // semitones). Voices are one per key, so the key finds the voice.
        NoteEvent::PolyTuning { key, tuning, .. } => Some(Event::NoteTuning {
            key: key.number(),
            semitones: f64::from(tuning),
        }),
        // Pressure (docs/plugin.md, "Pressure and the mod wheel"): per note
        // (CLAP/VST3 note expression, polyphonic aftertouch), the channel's
        // aftertouch, the mod wheel; nice-plug gives 0 .. 1.
        NoteEvent::PolyPressure { key, pressure, .. } => Some(Event::NotePressure {
            key: key.number(),
            value: f64::from(pressure),
        }),
        // Brightness (docs/plugin.md, "Brightness"): per note (CLAP/VST3
        // note expression); nice-plug gives 0 .. 1.
        NoteEvent::PolyBrightness {
            key, brightness, ..
        } => Some(Event::NoteBrightness {
            key: key.number(),
            value: f64::from(brightness),
        }),
        // A value of exactly 0.5 is not a 7-bit MIDI value (v / 127): it is
        // what nice-plug's VST3 wrapper answers when a host reads one of its
        // hidden MIDI controller parameters, which a host restoring a
        // session (Ardour) sends back: every voice would be pressed halfway
        // after a reload (docs/plugin.md, "Pressure and the mod wheel").
        NoteEvent::MidiChannelPressure { pressure, .. } if pressure != VST3_CC_PLACEHOLDER => {
            Some(Event::ChannelPressure {
                value: f64::from(pressure),
            })
        }
        NoteEvent::MidiCC { cc, value, .. }
            if cc == MOD_WHEEL_CC && value != VST3_CC_PLACEHOLDER =>
        {
            Some(Event::ModWheel {
                value: f64::from(value),
            })
        }
        _ => None,
    }
}

/// A CLAP note-off or choke of any key but one note id (CLAP matches a
/// wildcard key with a note id as that note) ends only that note: the
/// event for the key of the id, or none when the id is not sounding. Any
/// other event: `e` as it is.
fn for_note_id(event: &NoteEvent<()>, e: Event, ids: &voice_ids::VoiceIds) -> Option<Event> {
    let (NoteEvent::NoteOff {
        voice_id: VoiceID::ID(id),
        key: Key::Wildcard,
        ..
    }
    | NoteEvent::Choke {
        voice_id: VoiceID::ID(id),
        key: Key::Wildcard,
        ..
    }) = *event
    else {
        return Some(e);
    };
    let key = ids.key_of(id)?;
    Some(match e {
        Event::Choke { .. } => Event::Choke { key: Some(key) },
        _ => Event::NoteOff { key },
    })
}

/// The host's note event `event`, as the instrument's `e`, into `out`: its
/// voice id kept for polyphonic modulation, an MPE member channel's
/// bend, pressure and controllers made its notes'. \[audio-thread\]
fn translate(
    event: NoteEvent<()>,
    e: Event,
    ids: &mut voice_ids::VoiceIds,
    mpe: &mut mpe::Mpe,
    out: &mut mpe::Out,
) {
    match (event, e) {
        (
            NoteEvent::NoteOn {
                channel, voice_id, ..
            },
            Event::NoteOn { key, .. },
        ) => {
            let channel = channel.number().unwrap_or(0);
            ids.note_on(key, voice_id.id(), channel);
            mpe.note_on(channel, e, out)
        }
        (NoteEvent::NoteOn { channel, .. }, _) => {
            mpe.note_on(channel.number().unwrap_or(0), e, out)
        }
        (NoteEvent::MidiPitchBend { channel, .. }, Event::PitchBend { value })
            if mpe.pitch_bend(channel, value, out) => {}
        (NoteEvent::MidiChannelPressure { channel, .. }, Event::ChannelPressure { value })
            if mpe.pressure(channel, value, out) => {}
        // Reset All Controllers on an MPE member channel: its
        // notes' bend and pressure (the channel's controllers)
        (NoteEvent::MidiCC { channel, .. }, Event::ResetControllers)
            if mpe.reset_controllers(channel, out) => {}
        _ => out.set_one(e),
    }
}

/// The parameter of polyphonic modulation id `poly`.
fn poly_param(params: &ModalContactParams, poly: u32) -> &FloatParam {
    match poly {
        params::POLY_HARDNESS => &params.hardness,
        params::POLY_POSITION => &params.strike_pos,
        _ => &params.damper,
    }
}

/// The parameters a host modulates per voice, and the values the played
/// scene was compiled for.
struct Modulated<'a> {
    params: &'a ModalContactParams,
    played: SceneParams,
}

impl Modulated<'_> {
    /// A host event that is no note's (`event`): polyphonic modulation
    /// (docs/plugin.md, "Polyphonic modulation": a voice's offset, or the
    /// parameter moved under every modulated voice), an MPE member
    /// channel's timbre (the brightness of its notes) or another
    /// controller. Whether it put events in `out` to play at its time.
    /// \[audio-thread\]
    fn control(
        &self,
        event: NoteEvent<()>,
        ids: &mut voice_ids::VoiceIds,
        mpe: &mut mpe::Mpe,
        out: &mut mpe::Out,
    ) -> bool {
        // polyphonic modulation (docs/plugin.md, "Polyphonic
        // modulation"): a voice's offset, or the parameter moved
        // under every modulated voice
        match event {
            NoteEvent::PolyModulation {
                voice_id,
                poly_modulation_id: poly,
                normalized_offset,
                ..
            } => {
                self.params.variants_wanted.want(poly);
                if let Some(key) = ids.modulate(voice_id, poly, normalized_offset) {
                    let base = poly_param(self.params, poly).unmodulated_normalized_value();
                    out.set_one(self.event(poly, key, base, normalized_offset));
                    return true;
                }
                return false;
            }
            NoteEvent::MonoAutomation {
                poly_modulation_id: poly,
                normalized_value,
                ..
            } => {
                out.clear();
                for (key, off) in ids.modulated(poly) {
                    out.push(self.event(poly, key, normalized_value, off));
                }
                return true;
            }
            _ => {}
        }
        if let NoteEvent::MidiCC {
            channel, cc, value, ..
        } = event
        {
            let placeholder = value == VST3_CC_PLACEHOLDER;
            let value = (value.clamp(0.0, 1.0) * 127.0).round() as u8;
            // (exactly 0.5 is the VST3 wrapper's placeholder, see
            // `note_event`: a restored session's, not a timbre)
            if cc == TIMBRE_CC && !placeholder && mpe.timbre(channel, f64::from(value) / 127.0, out)
            {
                // the brightness of the member channel's notes
                return true;
            }
            mpe.controller(channel, cc, value);
        }
        false
    }

    /// The instrument's event for a voice's modulation of parameter `poly`:
    /// the parameter at knob position `base + offset` against the played
    /// scene's value (docs/plugin.md, "Polyphonic modulation"). With Custom
    /// damper off the Damper knob is not used: a damper offset is taken
    /// around the scene's damper, the one that plays.
    fn event(&self, poly: u32, key: u8, base: f32, offset: f32) -> Event {
        let p = poly_param(self.params, poly);
        let base = if poly == params::POLY_DAMPER && !self.played.damper_custom {
            p.preview_normalized(self.played.damper_norm as f32)
        } else {
            base
        };
        let value = f64::from(p.preview_plain(base + offset));
        let key = Some(key);
        match poly {
            params::POLY_HARDNESS => Event::NoteHardness {
                key,
                factor: value / self.played.stiffness_factor,
            },
            params::POLY_POSITION => Event::NotePosition {
                key,
                offset: value
                    - self
                        .played
                        .strike_pos_norm
                        .unwrap_or(f64::from(p.preview_plain(base))),
            },
            _ => Event::NoteDamper {
                key,
                offset: value - self.played.damper_norm,
            },
        }
    }
}

impl Plugin for ModalContact {
    const NAME: &'static str = "Modal Contact";
    const VENDOR: &'static str = "Modal Contact";
    // The project has no public web page or support address yet: hosts get
    // none (an empty field) rather than a made-up one. Fill both in when it
    // has them (CLAP and VST3 descriptors, and the preset provider's vendor).
    const URL: &'static str = "";
    const EMAIL: &'static str = "";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    const AUDIO_IO_LAYOUTS: &'static [AudioIOLayout] = &[AudioIOLayout {
        main_input_channels: None,
        main_output_channels: NonZeroU32::new(2),
        aux_input_ports: &[],
        aux_output_ports: &[],
        names: PortNames::const_default(),
    }];

    // Notes and controllers (the pedals, CC 64 and 66).
    const MIDI_INPUT: MidiConfig = MidiConfig::MidiCCs;
    // Room for every event one process call can bring without the wrapper
    // growing its queues on the audio thread: MIDI CCs make the VST3
    // wrapper expose 16 x 130 hidden controller parameters, and a host
    // restoring a session (Ardour does) sends all of them, with ours, in one
    // call: 2095 changes. nice-plug's default is 1024 (docs/plugin.md,
    // "How the tests show it").
    const INPUT_EVENT_CAPACITY: usize = 4096;
    // The wrapper splits blocks at parameter changes: a change is requested
    // at its sample (the swap itself follows when the worker is done).
    const SAMPLE_ACCURATE_AUTOMATION: bool = true;

    type Editor = editor::ModalEditor;
    type SysExMessage = ();
    type BackgroundTask = ();

    fn params(&self) -> Arc<dyn Params> {
        self.params.clone()
    }

    /// The editor window (docs/plugin.md, "The editor"). \[main-thread\]
    fn editor(&mut self, _async_executor: AsyncExecutor<Self>) -> Option<Self::Editor> {
        editor::create(editor::EditorLink {
            params: self.params.clone(),
            ring: self.ring.clone(),
            pads: self.pads.clone(),
            handoff: self.handoff.clone(),
        })
    }

    /// States from older versions get defaults for parameters they lack;
    /// invalid values are replaced by defaults (see [`params::migrate_state`]).
    /// \[main-thread\]
    fn filter_state(state: &mut nice_plug::plugin::PluginState) {
        let notes = params::migrate_state(state);
        if !notes.is_empty() {
            nice_log!("modal_contact: state: {}", notes.join("; "));
        }
    }

    /// Ask the worker for the current parameters' scene at the host's
    /// sample rate and take it if it is ready within
    /// [`worker::ACTIVATE_WAIT_MS`] (else the first block after it is
    /// ready does). \[main-thread\]
    fn activate(
        &mut self,
        _audio_io_layout: &AudioIOLayout,
        buffer_config: &BufferConfig,
        context: &mut impl ActivateContext<Self>,
    ) -> bool {
        let t0 = std::time::Instant::now();
        self.shut_down();
        let rate_hz = buffer_config.sample_rate as f64;
        if self.worker.is_none() {
            match Worker::spawn(self.handoff.clone(), self.params.persisted.library.clone()) {
                Ok(w) => self.worker = Some(w),
                Err(e) => {
                    nice_log!("modal_contact: cannot start the compile worker: {e}");
                    return false;
                }
            }
        }
        let ip = self.params.instrument_params();
        let max_block = buffer_config.max_buffer_size as usize;
        self.max_block = max_block;
        self.rate_hz = rate_hz;
        self.offline = buffer_config.process_mode == ProcessMode::Offline;
        self.active_lookahead_s = ip.play.lookahead_s;
        self.restart_requested = false;
        self.revision += 1;
        self.first_revision = self.revision;
        self.requested = ip.scene;
        // the last activation's scenes, if they are what is asked for now
        let reuse = self
            .parked
            .take()
            .filter(|(rate, params, p)| *rate == rate_hz && *params == ip.scene && p.complete);
        if let Some((_, _, prepared)) = reuse {
            self.latest_request = prepared.revision;
            self.instrument = Some(Box::new(Instrument::new(prepared, ip.play)));
        } else {
            self.latest_request = self.revision;
            let req = CompileRequest {
                revision: self.revision,
                rate_hz,
                max_block,
                polyphony: ip.play.polyphony,
                lookahead: lookahead_samples(ip.play.lookahead_s, rate_hz),
                params: ip.scene,
                first: Some(ip.play),
                // a live host gets a playable scene first (within the
                // activation's wait), then the whole one; an offline render
                // waits for the whole one (its output never depends on the
                // worker's timing)
                stage: if self.offline {
                    Stage::Full
                } else {
                    Stage::Playable
                },
                upgrade: false,
            };
            // the queues were drained by shut_down: this cannot fail
            if !self.handoff.request(req) {
                nice_log!("modal_contact: the compile queue is full at activation");
                return false;
            }
        }
        // the lookahead is the plugin's latency (docs/plugin.md, "Lookahead")
        context.set_latency_samples(lookahead_samples(ip.play.lookahead_s, rate_hz) as u32);
        // the previous instrument (and its probe) was dropped in shut_down
        self.ring.set_rate_hz(rate_hz);
        self.probe = self
            .ring
            .producer()
            .map(|p| Box::new(LiveProbe(p)) as Box<dyn VoiceProbe>);
        #[cfg(feature = "alloc-bug")]
        {
            self.leak = Vec::new();
        }
        if let Some(inst) = self.instrument.as_mut() {
            // a kept scene: its instrument is ready now
            inst.set_probe(self.probe.take());
            return true;
        }
        let deadline = t0 + std::time::Duration::from_millis(worker::ACTIVATE_WAIT_MS);
        let rev = self.first_revision;
        let h = &self.handoff;
        waits::while_busy(|| h.compiling() && !h.failed(rev), Some(deadline));
        self.take_first();
        if self.instrument.is_none() {
            if self.handoff.failed(rev) {
                nice_log!("modal_contact: cannot compile any scene");
                return false;
            }
            nice_log!(
                "modal_contact: the scene is still compiling after {} ms; the instance is \
                 silent until it is ready",
                worker::ACTIVATE_WAIT_MS
            );
        }
        true
    }

    /// Cancel the worker's compile and free the scenes; never waits for
    /// the worker. \[main-thread\]
    fn deactivate(&mut self) {
        self.shut_down();
    }

    /// Silence every voice (no allocation: states are reset in place by
    /// restarting the instrument's voices). \[audio-thread\]
    fn reset(&mut self) {
        if let Some(inst) = self.instrument.as_mut() {
            inst.silence();
        }
    }

    /// Render with sample-accurate note events, behind the panic boundary:
    /// a panic anywhere below (instrument, engine, swap) is caught here, the
    /// block is written as silence, every voice is stopped (their state may
    /// be half-updated), a line is logged, and the next block plays on. A
    /// panic must never unwind into the host (through `extern "C"` it would
    /// abort the whole DAW). \[audio-thread\]
    fn process(
        &mut self,
        buffer: &mut Buffer,
        _aux: &mut AuxiliaryBuffers,
        context: &mut impl ProcessContext<Self>,
    ) -> ProcessStatus {
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            self.process_guarded(&mut *buffer, &mut *context)
        }));
        match caught {
            Ok(status) => status,
            Err(payload) => {
                self.panics += 1;
                let n = self.panics;
                // The panic already allocated its payload; freeing it and
                // logging may allocate too. A panic is the one exception to
                // the no-allocation rule (the alternative is the host's death).
                // (In builds with the allocation checker, the unwinder's own
                // deallocation already aborted before this point.)
                permit_alloc(|| {
                    let what = payload
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| payload.downcast_ref::<String>().cloned())
                        .unwrap_or_default();
                    nice_log!(
                        "modal_contact: caught a panic in process ({what}); \
                         block silenced, voices stopped (panic {n} since activation)"
                    );
                    drop(payload);
                });
                if let Some(inst) = self.instrument.as_mut() {
                    inst.silence();
                }
                for ch in buffer.as_slice().iter_mut() {
                    ch.fill(0.0);
                }
                ProcessStatus::Normal
            }
        }
    }
}

impl ModalContact {
    /// The Lookahead parameter's latency: with CLAP the instance plays
    /// (in `play`) the lookahead it was activated with and asks the host
    /// for a restart when the knob moved; else it reports the new latency.
    /// \[audio-thread\]
    fn follow_lookahead(&mut self, play: &mut PlayParams, context: &mut impl ProcessContext<Self>) {
        let wanted_lookahead = lookahead_samples(play.lookahead_s, self.rate_hz);
        if context.plugin_api() == PluginApi::Clap {
            // CLAP: the latency changes only in activate; the instance
            // plays the lookahead it was activated with and asks the host
            // for a restart (docs/plugin.md, "Lookahead")
            play.lookahead_s = self.active_lookahead_s;
            if wanted_lookahead != lookahead_samples(self.active_lookahead_s, self.rate_hz)
                && !self.restart_requested
            {
                self.restart_requested = true;
                context.request_restart();
            }
        } else {
            // a new Lookahead is a new latency (the wrapper tells the
            // host only when it changed)
            context.set_latency_samples(wanted_lookahead as u32);
        }
    }

    /// The body of `process` (see there). \[audio-thread\]
    fn process_guarded(
        &mut self,
        buffer: &mut Buffer,
        context: &mut impl ProcessContext<Self>,
    ) -> ProcessStatus {
        let mut play = self.params.play_params();
        self.follow_lookahead(&mut play, context);
        self.maybe_swap_and_request(play);
        let out = buffer.as_slice();
        let Some(inst) = self.instrument.as_mut() else {
            for ch in out.iter_mut() {
                ch.fill(0.0);
            }
            return ProcessStatus::Normal;
        };
        if out.len() < 2 {
            // No stereo output to write to (a host that ignored the layout).
            for ch in out.iter_mut() {
                ch.fill(0.0);
            }
            return ProcessStatus::Normal;
        }
        let (left, right) = out.split_at_mut(1);
        let (left, right) = (&mut *left[0], &mut *right[0]);
        // the probe records while the editor holds the ring's reading end
        inst.set_probe_on(self.ring.has_consumer());
        // audition pads first, at the block's start, then the host's events
        let pads = &self.pads;
        let pad_events =
            std::iter::from_fn(|| pads.pop()).map(|event| TimedEvent { offset: 0, event });
        #[cfg(feature = "alloc-bug")]
        let leak = &mut self.leak;
        // The host's events as the instrument's, read as the block is
        // rendered (no buffer): the instrument applies each at its offset.
        // One host event may become several (an MPE member channel's bend
        // retunes each of its notes): they wait in `translated`.
        let (mpe, out) = (&mut self.mpe, &mut self.translated);
        let ids = &mut self.voice_ids;
        let params = &*self.params;
        let modulated = Modulated {
            params,
            played: inst.prepared().params,
        };
        out.clear();
        let (mut next, mut at) = (0usize, 0usize);
        let events = std::iter::from_fn(|| loop {
            if let Some(&event) = out.as_slice().get(next) {
                next += 1;
                return Some(TimedEvent { offset: at, event });
            }
            let event = context.next_event()?;
            let Some(e) = note_event(&event).and_then(|e| for_note_id(&event, e, ids)) else {
                if modulated.control(event, ids, mpe, out) {
                    (next, at) = (0, event.timing() as usize);
                }
                continue;
            };
            // TEST ONLY fault injection (test bundles; never in a shipped
            // build): note 2 at velocity 0.123 allocates in process, note 1
            // panics.
            #[cfg(feature = "alloc-bug")]
            if matches!(e, Event::NoteOn { key: 2, velocity_norm }
                if (velocity_norm - 0.123).abs() < 1e-6)
            {
                leak.push(0.0);
            }
            #[cfg(feature = "panic-bug")]
            if matches!(e, Event::NoteOn { key: 1, .. }) {
                panic!("panic-bug: deliberate panic on note 1");
            }
            translate(event, e, ids, mpe, out);
            (next, at) = (0, event.timing() as usize);
        });
        inst.process_events(pad_events.chain(events), left, right);
        // the voices that ended (silence, stealing, a new note on their
        // key, a fade) end the host's modulation of them
        self.voice_ids.block_done(&inst.voice_keys());
        let last = left.len().saturating_sub(1) as u32;
        for v in self.voice_ids.take_ended() {
            let _ = context.try_send_event(NoteEvent::VoiceTerminated {
                timing: last,
                voice_id: VoiceID::ID(v.id),
                channel: Channel::Number(v.channel),
                key: Key::Number(v.key),
            });
        }
        ProcessStatus::KeepAlive
    }
}

impl ClapPlugin for ModalContact {
    const CLAP_ID: &'static str = "dev.modal-contact.modal-contact";
    const CLAP_DESCRIPTION: Option<&'static str> =
        Some("Energy-stable modal contact percussion (exact piecewise-linear contact)");
    const CLAP_MANUAL_URL: Option<&'static str> = None;
    const CLAP_SUPPORT_URL: Option<&'static str> = None;
    // Hardness, strike position and damper per voice (docs/plugin.md,
    // "Polyphonic modulation"); one voice per key: a second note on a key
    // strikes its ringing voice.
    const CLAP_POLY_MODULATION_CONFIG: Option<PolyModulationConfig> = Some(PolyModulationConfig {
        max_voice_capacity: MAX_VOICES as u32,
        supports_overlapping_voices: false,
    });
    const CLAP_FEATURES: &'static [ClapFeature] = &[
        ClapFeature::Instrument,
        ClapFeature::Synthesizer,
        ClapFeature::Stereo,
    ];
}

impl Vst3Plugin for ModalContact {
    const VST3_CLASS_ID: [u8; 16] = *b"ModalContactRath";
    const VST3_SUBCATEGORIES: &'static [Vst3SubCategory] =
        &[Vst3SubCategory::Instrument, Vst3SubCategory::Synth];
}

// The CLAP entry point is `clap_entry` (the plugin factory plus preset
// discovery); nice_export_clap! would offer the plugin factory only.
nice_export_vst3!(ModalContact);

#[cfg(test)]
mod tests {
    use super::*;

    fn wheel(value: f32) -> f64 {
        let ev = NoteEvent::MidiPitchBend {
            timing: 0,
            channel: 0,
            value,
        };
        match note_event(&ev) {
            Some(Event::PitchBend { value }) => value,
            other => panic!("{other:?}"),
        }
    }

    /// The wheel's 14-bit values map to -1 .. 1 with the centre (8192 of
    /// 0..16383, which nice-plug gives as 8192 / 16383) exactly at 0.
    /// Aftertouch and the mod wheel pass every 7-bit value, and not the
    /// VST3 wrapper's 0.5 that hosts echo back when restoring a session.
    #[test]
    fn pressure_controllers_skip_the_vst3_placeholder() {
        let pressure = |v: f32| {
            note_event(&NoteEvent::MidiChannelPressure {
                timing: 0,
                channel: 0,
                pressure: v,
            })
        };
        let wheel = |v: f32| {
            note_event(&NoteEvent::MidiCC {
                timing: 0,
                channel: 0,
                cc: MOD_WHEEL_CC,
                value: v,
            })
        };
        for k in 0..=127u8 {
            let v = f32::from(k) / 127.0;
            assert_eq!(
                pressure(v),
                Some(Event::ChannelPressure {
                    value: f64::from(v)
                })
            );
            assert_eq!(
                wheel(v),
                Some(Event::ModWheel {
                    value: f64::from(v)
                })
            );
        }
        assert_eq!(pressure(0.5), None);
        assert_eq!(wheel(0.5), None);
    }

    /// What note ends become: a CLAP choke is a choke of its key (every
    /// key for the wildcard), not a note-off; a note-off of the wildcard
    /// key is every key up; MIDI's channel mode messages 120 (All Sound
    /// Off), 121 (Reset All Controllers) and 123 (All Notes Off) are
    /// theirs, on any channel and at any value but the VST3 wrapper's
    /// placeholder; a note-off or choke of the wildcard key with a note id
    /// is that note's (nothing when the id is not sounding).
    #[test]
    fn note_ends_and_channel_mode_messages_map_to_their_events() {
        let choke = |key: Key, voice_id: VoiceID| NoteEvent::Choke {
            timing: 0,
            voice_id,
            channel: Channel::Number(0),
            key,
        };
        let note_off = |key: Key, voice_id: VoiceID| NoteEvent::NoteOff {
            timing: 0,
            voice_id,
            channel: Channel::Number(0),
            key,
            velocity: 0.0,
        };
        let any = VoiceID::Wildcard;
        assert_eq!(
            note_event(&choke(Key::Number(60), any)),
            Some(Event::Choke { key: Some(60) })
        );
        assert_eq!(
            note_event(&choke(Key::Wildcard, any)),
            Some(Event::Choke { key: None })
        );
        assert_eq!(
            note_event(&note_off(Key::Number(60), any)),
            Some(Event::NoteOff { key: 60 })
        );
        assert_eq!(
            note_event(&note_off(Key::Wildcard, any)),
            Some(Event::AllNotesOff)
        );
        let cc = |channel: u8, cc: u8, value: f32| {
            note_event(&NoteEvent::MidiCC {
                timing: 0,
                channel,
                cc,
                value,
            })
        };
        for channel in [0, 9, 15] {
            for value in [0.0, 1.0 / 127.0, 1.0] {
                assert_eq!(cc(channel, 120, value), Some(Event::AllSoundOff));
                assert_eq!(cc(channel, 121, value), Some(Event::ResetControllers));
                assert_eq!(cc(channel, 123, value), Some(Event::AllNotesOff));
            }
        }
        for c in [120, 121, 123] {
            assert_eq!(cc(0, c, VST3_CC_PLACEHOLDER), None, "controller {c}");
        }
        assert_eq!(cc(0, 122, 0.0), None, "local control: not ours");

        // a note id with the wildcard key
        let mut ids = voice_ids::VoiceIds::default();
        ids.note_on(64, Some(7), 0);
        let by_id = |event: NoteEvent<()>| {
            let e = note_event(&event)?;
            for_note_id(&event, e, &ids)
        };
        let (id7, id8) = (VoiceID::ID(7), VoiceID::ID(8));
        assert_eq!(
            by_id(choke(Key::Wildcard, id7)),
            Some(Event::Choke { key: Some(64) })
        );
        assert_eq!(by_id(choke(Key::Wildcard, id8)), None);
        assert_eq!(
            by_id(note_off(Key::Wildcard, id7)),
            Some(Event::NoteOff { key: 64 })
        );
        assert_eq!(by_id(note_off(Key::Wildcard, id8)), None);
        // a key given: the key's
        assert_eq!(
            by_id(choke(Key::Number(60), id8)),
            Some(Event::Choke { key: Some(60) })
        );
        assert_eq!(
            by_id(note_off(Key::Wildcard, any)),
            Some(Event::AllNotesOff)
        );
    }

    #[test]
    fn pitch_bend_wheel_maps_its_centre_to_zero() {
        assert_eq!(wheel(8192.0 / 16383.0), 0.0);
        assert_eq!(wheel(0.0), -1.0);
        assert_eq!(wheel(1.0), 1.0);
        assert_eq!(wheel(4096.0 / 16383.0), -0.5);
        assert_eq!(wheel(f32::NAN), 0.0, "not a number: the centre");
        assert!(wheel(0.75) > 0.49 && wheel(0.75) < 0.51);
    }
}
