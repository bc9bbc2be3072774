//! A loaded plugin instance ([`LoadedPlugin`]) and how it renders: the
//! render settings ([`RenderSpec`]), an activated session ([`Session`])
//! and its audio-thread side ([`Audio`]), block by block.

use crate::{
    host_info, load_entry, param_id, HostEvent, TestHost, TestMainThread, TestShared, PLUGIN_ID,
};
use clack_extensions::latency::PluginLatency;
use clack_extensions::params::{ParamInfoBuffer, PluginParams};
use clack_extensions::preset_discovery::prelude::{Location, PluginPresetLoad};
use clack_extensions::render::{PluginRender, RenderMode};
use clack_extensions::state::PluginState;
use clack_host::events::event_types::{
    MidiEvent, NoteEndEvent, NoteExpressionEvent, NoteExpressionType, NoteOffEvent, NoteOnEvent,
    ParamModEvent, ParamValueEvent,
};
use clack_host::events::Match;
use clack_host::prelude::*;
use std::ffi::CString;
use std::path::Path;
use std::sync::atomic::Ordering;

/// A loaded plugin instance.
pub struct LoadedPlugin {
    // Field order matters: the instance is dropped before the entry.
    instance: PluginInstance<TestHost>,
    /// [`TestShared::restarts_requested`] just before the last activation:
    /// requests after it are still to be honoured.
    restarts_at_activate: u32,
    _entry: PluginEntry,
}

/// How a render is run.
#[derive(Debug, Clone)]
pub struct RenderSpec {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Block size (the last block may be shorter).
    pub max_block: usize,
    /// Frames to render.
    pub total: usize,
    /// Events (any order).
    pub events: Vec<HostEvent>,
    /// After the block containing each of these positions, wait this long
    /// \[ms\] so the plugin's worker can finish a compile (an offline render
    /// runs far faster than real time). Not a timing assertion.
    pub settle_after: Vec<usize>,
    /// See `settle_after`.
    pub settle_ms: u64,
}

impl RenderSpec {
    /// A render with no settling pauses.
    pub fn new(rate_hz: f64, max_block: usize, total: usize, events: Vec<HostEvent>) -> Self {
        Self {
            rate_hz,
            max_block,
            total,
            events,
            settle_after: Vec::new(),
            settle_ms: 0,
        }
    }
}

impl LoadedPlugin {
    /// Load and instantiate the plugin of `bundle`, set to render offline
    /// (CLAP render extension): the harness calls `process` far faster
    /// than real time, as an export does, and an offline render waits for
    /// the scenes it asks for, so a render never depends on how fast the
    /// plugin's worker is (docs/plugin.md, "Parameter changes: the swap
    /// design"). [`LoadedPlugin::load_realtime`] is a live host's
    /// instance.
    pub fn load(bundle: &Path) -> Self {
        let mut p = Self::load_realtime(bundle);
        assert!(
            p.set_render_mode(true),
            "the render extension refused offline"
        );
        p
    }

    /// Load and instantiate the plugin of `bundle` in real-time mode (a
    /// live host's: the first scene may come blocks after the activation,
    /// a parameter's scene when the worker is done).
    pub fn load_realtime(bundle: &Path) -> Self {
        let entry = load_entry(bundle);
        let id = CString::new(PLUGIN_ID).expect("id");
        let instance = PluginInstance::<TestHost>::new(
            |_| TestShared::default(),
            |_| TestMainThread::default(),
            &entry,
            &id,
            &host_info(),
        )
        .expect("instantiate plugin");
        Self {
            instance,
            restarts_at_activate: 0,
            _entry: entry,
        }
    }

    /// (id, name) of every parameter, via the params extension.
    pub fn param_infos(&mut self) -> Vec<(u32, String)> {
        let handle = self.instance.plugin_handle();
        let params: PluginParams = handle.get_extension().expect("params extension");
        let mut out = Vec::new();
        for i in 0..params.count(&handle) {
            let mut buf = ParamInfoBuffer::new();
            if let Some(info) = params.get_info(&handle, i, &mut buf) {
                out.push((
                    info.id.get(),
                    String::from_utf8_lossy(info.name).into_owned(),
                ));
            }
        }
        out
    }

    /// Times the plugin told the host its latency changed.
    pub fn latency_changes(&mut self) -> u32 {
        self.instance.access_handler(|h| h.latency_changes.get())
    }

    /// Times the plugin told the host its latency changed outside
    /// `clap_plugin::activate` (CLAP allows it only inside).
    pub fn latency_violations(&mut self) -> u32 {
        self.instance.access_handler(|h| h.latency_violations.get())
    }

    /// Times the plugin asked the host to restart it (from any thread).
    pub fn restarts_requested(&self) -> u32 {
        self.instance
            .access_shared_handler(|h| h.restarts_requested.load(Ordering::SeqCst))
    }

    /// The host's main loop: call the plugin's `on_main_thread` if it asked
    /// for it since the last call. Returns whether it was called.
    pub fn run_callbacks(&mut self) -> bool {
        let asked = self
            .instance
            .access_shared_handler(|h| h.callback_requested.swap(false, Ordering::SeqCst));
        if asked {
            self.instance.call_on_main_thread_callback();
        }
        asked
    }

    /// Set parameters (CLAP values, see [`HostEvent::Param`]) through the
    /// params extension's `flush`, as a host does while the plugin is not
    /// processing. Only while deactivated (the test host has no active
    /// flush).
    pub fn flush_params(&mut self, values: &[(u32, f64)]) {
        let params: PluginParams = self
            .instance
            .plugin_handle()
            .get_extension()
            .expect("params extension");
        let mut events = EventBuffer::with_capacity(values.len());
        for &(id, value) in values {
            events.push(&ParamValueEvent::new(
                0,
                ClapId::new(id),
                Pckn::match_all(),
                value,
            ));
        }
        let mut out = EventBuffer::with_capacity(16);
        let mut handle = self
            .instance
            .inactive_plugin_handle()
            .expect("flush_params: the plugin is active");
        params.flush(&mut handle, &events.as_input(), &mut out.as_output());
    }

    /// Set the render mode (CLAP render extension): `true` for offline (an
    /// export: no real-time constraint), `false` for real time. Returns
    /// whether the plugin accepted it. Set it while deactivated: the next
    /// activation runs in it.
    pub fn set_render_mode(&mut self, offline: bool) -> bool {
        let handle = self.instance.plugin_handle();
        let ext: PluginRender = handle.get_extension().expect("render extension");
        let mode = if offline {
            RenderMode::Offline
        } else {
            RenderMode::Realtime
        };
        ext.set(&handle, mode).is_ok()
    }

    /// The latency the plugin reports \[samples\] (CLAP latency extension).
    pub fn latency(&mut self) -> u32 {
        let handle = self.instance.plugin_handle();
        let ext: PluginLatency = handle.get_extension().expect("latency extension");
        ext.get(&handle)
    }

    /// A parameter's CLAP value.
    pub fn param_value(&mut self, id: u32) -> f64 {
        let handle = self.instance.plugin_handle();
        let params: PluginParams = handle.get_extension().expect("params extension");
        params
            .get_value(&handle, ClapId::new(id))
            .expect("param value")
    }

    /// Save the plugin state.
    pub fn save_state(&mut self) -> Vec<u8> {
        let handle = self.instance.plugin_handle();
        let state: PluginState = handle.get_extension().expect("state extension");
        let mut bytes = Vec::new();
        state.save(&handle, &mut bytes).expect("save state");
        bytes
    }

    /// Load a saved state.
    pub fn load_state(&mut self, bytes: &[u8]) {
        assert!(self.try_load_state(bytes), "load state refused");
    }

    /// Load a state; false when the plugin refused it (the host is told).
    pub fn try_load_state(&mut self, bytes: &[u8]) -> bool {
        let handle = self.instance.plugin_handle();
        let state: PluginState = handle.get_extension().expect("state extension");
        state.load(&handle, &mut &bytes[..]).is_ok()
    }

    /// Load a preset the way a host's preset browser does (CLAP
    /// preset-load): `Location::Plugin` with a built-in scene's key, or a
    /// scene file. Returns whether the plugin accepted it and the
    /// preset-load callbacks the host received during the call.
    pub fn load_preset(
        &mut self,
        location: Location,
        load_key: Option<&std::ffi::CStr>,
    ) -> (bool, Vec<String>) {
        let handle = self.instance.plugin_handle();
        let ext: PluginPresetLoad = handle.get_extension().expect("preset-load extension");
        let ok = ext.load_from_location(&handle, location, load_key).is_ok();
        let events = self.instance.access_handler(|h| h.preset_events.take());
        (ok, events)
    }

    /// Activate at `rate_hz` for blocks of `min_frames..=max_frames` and
    /// start processing. [main thread, then the "audio thread" is the caller]
    pub fn activate(&mut self, rate_hz: f64, min_frames: usize, max_frames: usize) -> Session<'_> {
        let config = PluginAudioConfiguration {
            sample_rate: rate_hz,
            min_frames_count: min_frames as u32,
            max_frames_count: max_frames as u32,
        };
        let processor = self.start(config);
        Session {
            plugin: self,
            config,
            audio: Audio {
                processor: Some(processor),
                max_frames,
                left: vec![0f32; max_frames],
                right: vec![0f32; max_frames],
                out_ports: AudioPorts::with_capacity(2, 1),
                in_events: EventBuffer::with_capacity(1024),
                out_events: EventBuffer::with_capacity(256),
                steady: 0,
                note_ends: Vec::new(),
            },
        }
    }

    /// `clap_plugin::activate` (flagged for the latency extension's rule,
    /// see [`TestMainThread::in_activate`]), then `start_processing`. A
    /// restart asked for before this call is honoured by it.
    fn start(&mut self, config: PluginAudioConfiguration) -> StartedPluginAudioProcessor<TestHost> {
        self.restarts_at_activate = self.restarts_requested();
        self.instance.access_handler(|h| h.in_activate.set(true));
        let activated = self.instance.activate(|_, _| (), config);
        self.instance.access_handler(|h| h.in_activate.set(false));
        let processor = activated.expect("activate");
        processor.start_processing().expect("start processing")
    }

    /// Activate, render, deactivate. Returns `[left, right]`.
    pub fn render(&mut self, spec: &RenderSpec) -> [Vec<f32>; 2] {
        let mut session = self.activate(spec.rate_hz, 1, spec.max_block);
        let mut sorted = spec.events.clone();
        sorted.sort_by_key(|e| e.at());
        let total = spec.total;
        let mut out = [Vec::with_capacity(total), Vec::with_capacity(total)];
        let mut next = 0usize;
        let mut pos = 0usize;
        while pos < total {
            let len = spec.max_block.min(total - pos);
            let first = next;
            while next < sorted.len() && sorted[next].at() < pos + len {
                next += 1;
            }
            let block = session.process(len, pos, &sorted[first..next]);
            out[0].extend_from_slice(block[0]);
            out[1].extend_from_slice(block[1]);
            if spec.settle_after.iter().any(|&s| s >= pos && s < pos + len) {
                std::thread::sleep(std::time::Duration::from_millis(spec.settle_ms));
            }
            pos += len;
        }
        session.deactivate();
        out
    }
}

/// An activated, processing instance: blocks are processed one at a time,
/// with whatever sizes and events the caller chooses, on the caller's
/// thread or on another one ([`Session::on_audio_thread`]).
pub struct Session<'a> {
    plugin: &'a mut LoadedPlugin,
    config: PluginAudioConfiguration,
    audio: Audio,
}

/// The audio-thread side of a [`Session`]: the started processor and the
/// host's buffers. It can be handed to another thread.
pub struct Audio {
    processor: Option<StartedPluginAudioProcessor<TestHost>>,
    max_frames: usize,
    left: Vec<f32>,
    right: Vec<f32>,
    out_ports: AudioPorts,
    in_events: EventBuffer,
    out_events: EventBuffer,
    steady: u64,
    /// The plugin's note-end events so far (CLAP `NOTE_END`: a voice
    /// ended), in order.
    pub note_ends: Vec<NoteEnd>,
}

/// A note-end event the plugin sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NoteEnd {
    /// Absolute sample position.
    pub at: usize,
    /// Its note id (`None`: the wildcard).
    pub id: Option<u32>,
    /// Its key.
    pub key: Option<u8>,
}

impl Session<'_> {
    /// Process one block on the caller's thread: see [`Audio::process`].
    pub fn process(
        &mut self,
        frames: usize,
        block_start: usize,
        events: &[HostEvent],
    ) -> [&[f32]; 2] {
        self.audio.process(frames, block_start, events)
    }

    /// Process part of a script on the caller's thread: see
    /// [`Audio::render`].
    pub fn render(
        &mut self,
        start: usize,
        total: usize,
        block: usize,
        events: &[HostEvent],
    ) -> [Vec<f32>; 2] {
        self.audio.render(start, total, block, events)
    }

    /// The plugin's note-end events so far, in order.
    pub fn note_ends(&self) -> &[NoteEnd] {
        &self.audio.note_ends
    }

    /// Run `f` with the audio side on another thread (as a host's audio
    /// thread runs `process`), and wait for it. A panic in `f` is the
    /// caller's.
    pub fn on_audio_thread<R: Send>(&mut self, f: impl FnOnce(&mut Audio) -> R + Send) -> R {
        let audio = &mut self.audio;
        std::thread::scope(|s| {
            s.spawn(move || f(audio))
                .join()
                .unwrap_or_else(|e| std::panic::resume_unwind(e))
        })
    }

    /// The instance, for main-thread calls while it is active (its
    /// latency, its callbacks, its parameters' values).
    pub fn plugin(&mut self) -> &mut LoadedPlugin {
        self.plugin
    }

    /// The plugin asked for a restart (`clap_host::request_restart`) after
    /// the last activation began.
    pub fn restart_pending(&self) -> bool {
        self.plugin.restarts_requested() > self.plugin.restarts_at_activate
    }

    /// What a host does between two activations: stop processing,
    /// deactivate, run `f` on the deactivated instance (the host's
    /// main-thread work: callbacks, a parameter flush), activate with the
    /// same configuration and start processing again. The audio side
    /// keeps its buffers and its steady time.
    pub fn deactivated<R>(&mut self, f: impl FnOnce(&mut LoadedPlugin) -> R) -> R {
        self.stop();
        let r = f(self.plugin);
        self.audio.processor = Some(self.plugin.start(self.config));
        r
    }

    /// Honour the plugin's restart requests as a host does (deactivate,
    /// run its callbacks, activate) until it asks for none; at most
    /// `limit` restarts. Returns how many were made.
    pub fn honour_restarts(&mut self, limit: u32) -> u32 {
        let mut n = 0;
        while self.restart_pending() {
            assert!(
                n < limit,
                "the plugin asked for more than {limit} restarts in a row"
            );
            self.deactivated(|p| p.run_callbacks());
            n += 1;
        }
        n
    }

    /// The host's reset (e.g. on transport jumps).
    pub fn reset(&mut self) {
        self.audio.reset();
    }

    /// Stop processing and deactivate.
    pub fn deactivate(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        if let Some(p) = self.audio.processor.take() {
            let stopped = p.stop_processing();
            self.plugin.instance.deactivate(stopped);
        }
    }
}

impl Audio {
    /// Process one block of `frames` (0 allowed, at most the activation's
    /// maximum) with `events` whose `at` is absolute: `block_start` is
    /// subtracted. The output buffers are poisoned with NaN first, so every
    /// sample the plugin fails to write shows. Returns `[left, right]`.
    pub fn process(
        &mut self,
        frames: usize,
        block_start: usize,
        events: &[HostEvent],
    ) -> [&[f32]; 2] {
        assert!(
            frames <= self.max_frames,
            "{frames} > max {}",
            self.max_frames
        );
        self.in_events.clear();
        self.out_events.clear();
        self.queue_events(block_start, events);
        let (left, right) = (&mut self.left[..frames], &mut self.right[..frames]);
        left.fill(f32::NAN);
        right.fill(f32::NAN);
        let input_audio = InputAudioBuffers::empty();
        let mut output_audio = self.out_ports.with_output_buffers([AudioPortBuffer {
            latency: 0,
            channels: AudioPortBufferType::f32_output_only([left, right].into_iter()),
        }]);
        self.processor
            .as_mut()
            .expect("processing")
            .process(
                &input_audio,
                &mut output_audio,
                &self.in_events.as_input(),
                &mut self.out_events.as_output(),
                Some(self.steady),
                None,
            )
            .expect("process");
        self.record_note_ends(block_start);
        self.steady += frames as u64;
        [&self.left[..frames], &self.right[..frames]]
    }

    /// Queue `events` (their `at` absolute, `block_start` subtracted) as
    /// the block's CLAP input events.
    fn queue_events(&mut self, block_start: usize, events: &[HostEvent]) {
        for e in events {
            let t = (e.at() - block_start) as u32;
            match *e {
                HostEvent::NoteOn { key, velocity, .. } => self.in_events.push(&NoteOnEvent::new(
                    t,
                    Pckn::new(0u16, 0u16, key as u16, Match::All),
                    velocity,
                )),
                HostEvent::NoteOff { key, .. } => self.in_events.push(&NoteOffEvent::new(
                    t,
                    Pckn::new(0u16, 0u16, key as u16, Match::All),
                    0.0,
                )),
                HostEvent::Midi { data, .. } => self.in_events.push(&MidiEvent::new(t, 0, data)),
                HostEvent::Tuning { key, semitones, .. } => {
                    self.in_events.push(&NoteExpressionEvent::new(
                        t,
                        Pckn::new(0u16, 0u16, key as u16, Match::All),
                        NoteExpressionType::Tuning,
                        semitones,
                    ))
                }
                HostEvent::Pressure { key, value, .. } => {
                    self.in_events.push(&NoteExpressionEvent::new(
                        t,
                        Pckn::new(0u16, 0u16, key as u16, Match::All),
                        NoteExpressionType::Pressure,
                        value,
                    ))
                }
                HostEvent::Brightness { key, value, .. } => {
                    self.in_events.push(&NoteExpressionEvent::new(
                        t,
                        Pckn::new(0u16, 0u16, key as u16, Match::All),
                        NoteExpressionType::Brightness,
                        value,
                    ))
                }
                HostEvent::NoteOnId {
                    key, velocity, id, ..
                } => self.in_events.push(&NoteOnEvent::new(
                    t,
                    Pckn::new(0u16, 0u16, key as u16, id),
                    velocity,
                )),
                HostEvent::PolyMod {
                    id, target, amount, ..
                } => self.in_events.push(&ParamModEvent::new(
                    t,
                    ClapId::new(param_id(target.param_id())),
                    Pckn::new(Match::All, Match::All, Match::All, id),
                    amount,
                )),
                HostEvent::Param { id, value, .. } => self.in_events.push(&ParamValueEvent::new(
                    t,
                    ClapId::new(id),
                    Pckn::match_all(),
                    value,
                )),
            }
        }
    }

    /// Record the note-end events the plugin sent in this block, their
    /// times made absolute by `block_start`.
    fn record_note_ends(&mut self, block_start: usize) {
        for e in self.out_events.iter() {
            if let Some(end) = e.as_event::<NoteEndEvent>() {
                let id = match end.note_id() {
                    Match::Specific(id) => Some(id),
                    Match::All => None,
                };
                let key = match end.key() {
                    Match::Specific(k) => Some(k as u8),
                    Match::All => None,
                };
                self.note_ends.push(NoteEnd {
                    at: block_start + e.header().time() as usize,
                    id,
                    key,
                });
            }
        }
    }

    /// The host's reset (e.g. on transport jumps).
    pub fn reset(&mut self) {
        self.processor.as_mut().expect("processing").reset();
    }

    /// Process frames `start..start + total` of a script whose events are
    /// at positions from its start, in blocks of `block` counted from
    /// `start` (the last may be shorter); events outside those frames are
    /// left out. Returns `[left, right]`.
    pub fn render(
        &mut self,
        start: usize,
        total: usize,
        block: usize,
        events: &[HostEvent],
    ) -> [Vec<f32>; 2] {
        let end = start + total;
        let mut sorted: Vec<HostEvent> = events
            .iter()
            .filter(|e| (start..end).contains(&e.at()))
            .copied()
            .collect();
        sorted.sort_by_key(|e| e.at());
        let mut out = [Vec::with_capacity(total), Vec::with_capacity(total)];
        let (mut next, mut pos) = (0usize, start);
        while pos < end {
            let len = block.min(end - pos);
            let first = next;
            while next < sorted.len() && sorted[next].at() < pos + len {
                next += 1;
            }
            let b = self.process(len, pos, &sorted[first..next]);
            out[0].extend_from_slice(b[0]);
            out[1].extend_from_slice(b[1]);
            pos += len;
        }
        out
    }
}

impl Drop for Session<'_> {
    fn drop(&mut self) {
        self.stop();
    }
}
