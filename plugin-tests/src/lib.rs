//! Test harness: locates (or builds) the plugin bundles and drives the BUILT
//! `.clap` through `clack-host` 0.2, offline; also drives the instrument
//! library directly with the same events, for sample-by-sample comparison.
//!
//! Bundles are found like this (first match wins):
//! 1. env `MODAL_CONTACT_CLAP_<VARIANT>` (`..._RELEASE`, `..._RT_CHECKS`,
//!    `..._ALLOC_BUG`, `..._PANIC_BUG`) = path of a `.clap`: used as is (`cargo xtask test`
//!    builds the three bundles first and sets these);
//! 2. otherwise the harness bundles the variant itself, once per process,
//!    with `CARGO_TARGET_DIR=target/plugin-tests/cargo` (so it never waits on
//!    the lock of the outer `cargo test`), and copies the result to
//!    `target/plugin-tests/<variant>/`. `MODAL_CONTACT_SKIP_BUNDLE=1` reuses
//!    what is there.

use clack_extensions::latency::{HostLatency, HostLatencyImpl, PluginLatency};
use clack_extensions::params::{ParamInfoBuffer, PluginParams};
use clack_extensions::preset_discovery::prelude::{HostPresetLoad, Location, PluginPresetLoad};
use clack_extensions::preset_discovery::HostPresetLoadImpl;
use clack_extensions::render::{PluginRender, RenderMode};
use clack_extensions::state::PluginState;
use clack_host::events::event_types::{
    MidiEvent, NoteEndEvent, NoteExpressionEvent, NoteExpressionType, NoteOffEvent, NoteOnEvent,
    ParamModEvent, ParamValueEvent,
};
use clack_host::events::Match;
use clack_host::prelude::*;
use modal_contact::instrument::{
    prepare, Event, Instrument, InstrumentParams, TimedEvent as LibEvent,
};
use modal_contact::plugin::ModalContact;
use modal_testkit::bundles::{self, Bundle};
use nice_plug::prelude::ClapPlugin;
use std::ffi::CString;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Mutex;

/// The plugin's CLAP id, as the plugin declares it: the tests check that
/// the built bundle exports exactly this.
pub const PLUGIN_ID: &str = <ModalContact as ClapPlugin>::CLAP_ID;
/// Bundle file stem.
pub use modal_testkit::bundles::BUNDLE_NAME;

/// Which build of the plugin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// `--release`, default features (what users install).
    Release,
    /// `--profile test-release --features standalone,rt-checks,alloc-bug`: optimised, debug
    /// assertions on, so nice-plug's `assert_process_allocs` is active.
    RtChecks,
    /// The same build as `RtChecks` (which carries the test-only
    /// `alloc-bug` trigger): note 2 at velocity 0.123 allocates in `process`.
    AllocBug,
    /// `--profile test-release --features standalone,panic-bug` (no allocation
    /// checker): note 1 panics inside `process`.
    PanicBug,
}

impl Variant {
    /// The build of the bundle matrix (`modal_testkit::bundles::BUNDLES`,
    /// which `cargo xtask test` builds too) this variant runs on.
    pub fn bundle(self) -> &'static Bundle {
        bundles::bundle(match self {
            Variant::Release => "release",
            Variant::RtChecks | Variant::AllocBug => "rt-checks",
            Variant::PanicBug => "panic-bug",
        })
    }

    /// Directory / env name.
    pub fn name(self) -> &'static str {
        self.bundle().name
    }

    /// Arguments for `cargo xtask bundle modal_contact ...`.
    pub fn bundle_args(self) -> &'static [&'static str] {
        self.bundle().cargo_args
    }

    /// The environment variable that points at a prebuilt `.clap`.
    pub fn env_var(self) -> String {
        self.bundle().env_var()
    }
}

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("plugin-tests has a parent")
        .to_path_buf()
}

/// Where test outputs (WAVs) go.
pub fn out_dir() -> PathBuf {
    let d = workspace_root()
        .join("target")
        .join("plugin-tests")
        .join("wav");
    std::fs::create_dir_all(&d).expect("mkdir target/plugin-tests/wav");
    d
}

static BUILT: Mutex<Vec<Variant>> = Mutex::new(Vec::new());

/// Path of the `.clap` of `variant` (built first if needed).
pub fn clap_bundle(variant: Variant) -> PathBuf {
    if let Ok(p) = std::env::var(variant.env_var()) {
        return PathBuf::from(p);
    }
    bundle_dir(variant).join(format!("{BUNDLE_NAME}.clap"))
}

/// Path of the `.vst3` bundle directory of `variant` (built first if needed).
pub fn vst3_bundle(variant: Variant) -> PathBuf {
    clap_bundle(variant).with_extension("vst3")
}

fn bundle_dir(variant: Variant) -> PathBuf {
    let root = workspace_root();
    let base = root.join("target").join("plugin-tests");
    let out = base.join(variant.name());
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    let reuse = std::env::var_os("MODAL_CONTACT_SKIP_BUNDLE").is_some()
        && out.join(format!("{BUNDLE_NAME}.clap")).exists();
    if built.contains(&variant) || reuse {
        return out;
    }
    let target_dir = base.join("cargo");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let run = |cmd: &mut Command, what: &str| {
        let status = cmd
            .current_dir(&root)
            .env_remove("CARGO_MANIFEST_DIR")
            .env("CARGO_TARGET_DIR", &target_dir)
            .status()
            .unwrap_or_else(|e| panic!("spawn {what}: {e}"));
        assert!(status.success(), "{what} failed");
    };
    run(
        Command::new(&cargo).args(["build", "--quiet", "--package", "xtask", "--release"]),
        "building xtask",
    );
    run(
        Command::new(target_dir.join("release").join("xtask"))
            .args(["bundle", BUNDLE_NAME])
            .args(variant.bundle_args()),
        "cargo xtask bundle",
    );
    bundles::copy_bundles(&target_dir.join("bundled"), &out)
        .unwrap_or_else(|e| panic!("copying the bundles to {}: {e}", out.display()));
    built.push(variant);
    out
}

// ---------------------------------------------------------------------------
// Minimal clack host

/// Host callbacks callable from any thread: they only record what the
/// plugin asked for; the test's main loop decides when to act on it
/// ([`Session::restart_pending`], [`LoadedPlugin::run_callbacks`]).
#[derive(Default)]
pub struct TestShared {
    /// Times the plugin asked to be deactivated and re-activated
    /// (`clap_host::request_restart`, from any thread).
    pub restarts_requested: AtomicU32,
    /// The plugin asked for a call of its `on_main_thread`
    /// (`clap_host::request_callback`) that the host has not made yet.
    pub callback_requested: AtomicBool,
}

impl SharedHandler<'_> for TestShared {
    fn request_restart(&self) {
        self.restarts_requested.fetch_add(1, Ordering::SeqCst);
    }
    fn request_process(&self) {}
    fn request_callback(&self) {
        self.callback_requested.store(true, Ordering::SeqCst);
    }
}

/// Host type.
pub struct TestHost;

impl HostHandlers for TestHost {
    type Shared<'a> = TestShared;
    type MainThread<'a> = TestMainThread;
    type AudioProcessor<'a> = ();

    fn declare_extensions(builder: &mut HostExtensions<Self>, _shared: &Self::Shared<'_>) {
        builder.register::<HostPresetLoad>();
        builder.register::<HostLatency>();
    }
}

/// Main-thread host state: what the plugin told the host through the
/// preset-load extension (`loaded KEY` / `error KEY: MESSAGE`).
#[derive(Default)]
pub struct TestMainThread {
    /// The callbacks received, in order.
    pub preset_events: std::cell::RefCell<Vec<String>>,
    /// Times the plugin said its latency changed (CLAP latency extension).
    pub latency_changes: std::cell::Cell<u32>,
    /// Set while the host is inside `clap_plugin::activate`: the only
    /// place CLAP allows `clap_host_latency::changed`.
    pub in_activate: std::cell::Cell<bool>,
    /// Times the plugin said its latency changed outside
    /// `clap_plugin::activate` (a breach of the latency extension's rule).
    pub latency_violations: std::cell::Cell<u32>,
}

impl MainThreadHandler<'_> for TestMainThread {}

impl HostLatencyImpl for TestMainThread {
    fn changed(&self) {
        self.latency_changes.set(self.latency_changes.get() + 1);
        if !self.in_activate.get() {
            self.latency_violations
                .set(self.latency_violations.get() + 1);
        }
    }
}

fn location_text(location: Location, load_key: Option<&std::ffi::CStr>) -> String {
    let key = load_key.map(|k| k.to_string_lossy().into_owned());
    match location {
        Location::Plugin => key.unwrap_or_default(),
        Location::File { path } => path.to_string_lossy().into_owned(),
    }
}

impl HostPresetLoadImpl for TestMainThread {
    fn on_error(
        &self,
        location: Location,
        load_key: Option<&std::ffi::CStr>,
        _os_error: i32,
        message: Option<&std::ffi::CStr>,
    ) {
        self.preset_events.borrow_mut().push(format!(
            "error {}: {}",
            location_text(location, load_key),
            message.map(|m| m.to_string_lossy()).unwrap_or_default()
        ));
    }

    fn loaded(&self, location: Location, load_key: Option<&std::ffi::CStr>) {
        self.preset_events
            .borrow_mut()
            .push(format!("loaded {}", location_text(location, load_key)));
    }
}

/// Descriptor data read from the plugin factory.
#[derive(Debug, Clone)]
pub struct DescriptorInfo {
    /// CLAP id.
    pub id: String,
    /// Display name.
    pub name: String,
    /// Feature strings.
    pub features: Vec<String>,
    /// Vendor.
    pub vendor: String,
    /// Web page (empty or absent: none).
    pub url: String,
}

/// An event at an absolute sample position of a render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HostEvent {
    /// Note on (velocity 0..1).
    NoteOn {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Velocity 0..1.
        velocity: f64,
    },
    /// Note off.
    NoteOff {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
    },
    /// A raw MIDI 1.0 message (e.g. a controller: `[0xB0, 64, 127]`).
    Midi {
        /// Sample position.
        at: usize,
        /// The three bytes.
        data: [u8; 3],
    },
    /// A CLAP "tuning" note expression for `key` on channel 1 \[semitones\].
    Tuning {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Semitones.
        semitones: f64,
    },
    /// A CLAP "pressure" note expression for `key` on channel 1 (0 .. 1).
    Pressure {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Pressure.
        value: f64,
    },
    /// A CLAP "brightness" note expression for `key` on channel 1 (0 .. 1).
    Brightness {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Brightness.
        value: f64,
    },
    /// Note on with the host's note id (CLAP `note_id`), channel 1.
    NoteOnId {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Velocity 0..1.
        velocity: f64,
        /// The note id.
        id: u32,
    },
    /// A CLAP polyphonic modulation (`param_mod` on one note id) of a
    /// parameter by `amount` (normalized offset).
    PolyMod {
        /// Sample position.
        at: usize,
        /// The note id it modulates.
        id: u32,
        /// The parameter.
        target: PolyTarget,
        /// Normalized offset.
        amount: f64,
    },
    /// Parameter value (CLAP value: normalised for continuous parameters,
    /// step index for enums and bools).
    Param {
        /// Sample position.
        at: usize,
        /// CLAP param id.
        id: u32,
        /// Value.
        value: f64,
    },
}

impl HostEvent {
    /// Sample position.
    pub fn at(&self) -> usize {
        match *self {
            HostEvent::NoteOn { at, .. }
            | HostEvent::NoteOff { at, .. }
            | HostEvent::Midi { at, .. }
            | HostEvent::Tuning { at, .. }
            | HostEvent::Pressure { at, .. }
            | HostEvent::Brightness { at, .. }
            | HostEvent::NoteOnId { at, .. }
            | HostEvent::PolyMod { at, .. }
            | HostEvent::Param { at, .. } => at,
        }
    }
}

/// A note-on event.
pub fn on(at: usize, key: u8, velocity: f64) -> HostEvent {
    HostEvent::NoteOn { at, key, velocity }
}

/// A note-off event.
pub fn off(at: usize, key: u8) -> HostEvent {
    HostEvent::NoteOff { at, key }
}

/// A MIDI controller change on channel 1 (`value` 0..127).
pub fn cc(at: usize, controller: u8, value: u8) -> HostEvent {
    HostEvent::Midi {
        at,
        data: [0xB0, controller, value],
    }
}

/// A MIDI pitch bend on channel 1 (`value` 0..16383, centre 8192).
pub fn pitch_bend(at: usize, value: u16) -> HostEvent {
    HostEvent::Midi {
        at,
        data: [0xE0, (value & 0x7f) as u8, ((value >> 7) & 0x7f) as u8],
    }
}

/// A per-note tuning (CLAP note expression) for `key`.
pub fn note_tuning(at: usize, key: u8, semitones: f64) -> HostEvent {
    HostEvent::Tuning { at, key, semitones }
}

/// A per-note pressure (CLAP note expression) for `key`.
pub fn note_pressure(at: usize, key: u8, value: f64) -> HostEvent {
    HostEvent::Pressure { at, key, value }
}

/// A per-note brightness (CLAP note expression) for `key`.
pub fn note_brightness(at: usize, key: u8, value: f64) -> HostEvent {
    HostEvent::Brightness { at, key, value }
}

/// A parameter event by string id (CLAP value, see [`HostEvent::Param`]).
pub fn param(at: usize, id: &str, value: f64) -> HostEvent {
    HostEvent::Param {
        at,
        id: param_id(id),
        value,
    }
}

/// A parameter a CLAP host may modulate per voice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PolyTarget {
    /// Hardness.
    Hardness,
    /// Strike position.
    StrikePosition,
    /// Damper.
    Damper,
}

impl PolyTarget {
    /// The parameter's string id.
    pub fn param_id(self) -> &'static str {
        match self {
            Self::Hardness => "hardness",
            Self::StrikePosition => "strike_pos",
            Self::Damper => "damper",
        }
    }

    /// The instrument event a modulation by `amount` (normalized) of a
    /// voice of `key` means, at the parameter values `played`, through the
    /// parameters' ranges written out here (Strike position and Damper
    /// are linear 0 .. 1), not through the plugin's code.
    pub fn event(
        self,
        played: &modal_contact::instrument::SceneParams,
        key: u8,
        amount: f64,
    ) -> Event {
        let key = Some(key);
        let linear = |x: f64| (x + amount).clamp(0.0, 1.0) - x;
        match self {
            Self::Hardness => Event::NoteHardness {
                key,
                factor: hardness_factor(played.stiffness_factor, amount),
            },
            Self::StrikePosition => Event::NotePosition {
                key,
                offset: linear(played.strike_pos_norm.unwrap_or(0.5)),
            },
            Self::Damper => Event::NoteDamper {
                key,
                offset: linear(played.damper_norm),
            },
        }
    }
}

/// A polyphonic modulation of `target` on note id `id`.
pub fn poly_mod(at: usize, id: u32, target: PolyTarget, amount: f64) -> HostEvent {
    HostEvent::PolyMod {
        at,
        id,
        target,
        amount,
    }
}

/// A Hardness modulation's factor: the Hardness parameter's value at its
/// knob position plus `offset` (clamped to the knob's range) over
/// `played`, through the parameter's mapping written out here (0.01 ..
/// 100, skewed: `0.01 + 99.99 n^4`), not through the plugin's code.
pub fn hardness_factor(played: f64, offset: f64) -> f64 {
    let (min, max) = (0.01, 100.0);
    let n = ((played - min) / (max - min)).powf(0.25);
    let m = (n + offset).clamp(0.0, 1.0);
    (min + (max - min) * m.powi(4)) / played
}

/// A note-on with a note id.
pub fn on_id(at: usize, key: u8, velocity: f64, id: u32) -> HostEvent {
    HostEvent::NoteOnId {
        at,
        key,
        velocity,
        id,
    }
}

/// nice-plug's string id -> CLAP param id hash.
pub fn param_id(id: &str) -> u32 {
    let mut hash: u32 = 0;
    for b in id.bytes() {
        hash = hash.wrapping_mul(31).wrapping_add(b as u32);
    }
    hash & !(1 << 31)
}

/// A loaded plugin instance.
pub struct LoadedPlugin {
    // Field order matters: the instance is dropped before the entry.
    instance: PluginInstance<TestHost>,
    /// [`TestShared::restarts_requested`] just before the last activation:
    /// requests after it are still to be honoured.
    restarts_at_activate: u32,
    _entry: PluginEntry,
}

/// What the test host says about itself.
pub fn host_info() -> HostInfo {
    HostInfo::new(
        "modal-contact-test-host",
        "modal_contact",
        "https://example.invalid",
        "0.1.0",
    )
    .expect("host info")
}

/// Entries are never unloaded: dlclose'ing the plugin while a thread that
/// called into it is alive makes that thread crash at exit (a TLS destructor
/// registered by the plugin runs after its code was unmapped).
static KEEP_LOADED: Mutex<Vec<(PathBuf, PluginEntry)>> = Mutex::new(Vec::new());

/// The bundle's entry, loaded once per process and never unloaded.
pub fn load_entry(bundle: &Path) -> PluginEntry {
    let mut kept = KEEP_LOADED.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, e)) = kept.iter().find(|(p, _)| p == bundle) {
        return e.clone();
    }
    // SAFETY: loading a dynamic library runs its initialisers; it is our own build.
    let entry = unsafe { PluginEntry::load(bundle) }
        .unwrap_or_else(|e| panic!("load CLAP entry {}: {e:?}", bundle.display()));
    kept.push((bundle.to_path_buf(), entry.clone()));
    entry
}

/// The descriptors of the bundle's factory.
pub fn descriptors(bundle: &Path) -> Vec<DescriptorInfo> {
    let entry = load_entry(bundle);
    let factory = entry.get_plugin_factory().expect("plugin factory");
    factory
        .plugin_descriptors()
        .map(|d| DescriptorInfo {
            id: d.id().expect("id").to_string_lossy().into_owned(),
            name: d.name().expect("name").to_string_lossy().into_owned(),
            features: d
                .features()
                .map(|f| f.to_string_lossy().into_owned())
                .collect(),
            vendor: d
                .vendor()
                .map(|v| v.to_string_lossy().into_owned())
                .unwrap_or_default(),
            url: d
                .url()
                .map(|v| v.to_string_lossy().into_owned())
                .unwrap_or_default(),
        })
        .collect()
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

// ---------------------------------------------------------------------------
// The same notes through the instrument library, no plugin

/// Render `events` (notes and the pedals' controllers) with the instrument library directly,
/// at the plugin's parameter defaults `params`. Velocities are rounded to f32
/// as nice-plug does. Returns `[left, right]`.
pub fn library_render(
    params: &InstrumentParams,
    rate_hz: f64,
    total: usize,
    events: &[HostEvent],
) -> [Vec<f32>; 2] {
    let prepared = prepare(&params.scene, rate_hz, 0).expect("compile");
    library_render_prepared(prepared, params, total, events)
}

/// [`library_render`] of an already prepared scene (a user's scene file,
/// `modal_contact::instrument::prepare_scene`).
pub fn library_render_prepared(
    prepared: Box<modal_contact::instrument::Prepared>,
    params: &InstrumentParams,
    total: usize,
    events: &[HostEvent],
) -> [Vec<f32>; 2] {
    let mut inst = Instrument::new(prepared, params.play);
    let mut sorted: Vec<LibEvent> = events
        .iter()
        .filter_map(|e| library_event(e, events, params))
        .collect();
    sorted.sort_by_key(|e| e.offset);
    let mut l = vec![0.0; total];
    let mut r = vec![0.0; total];
    inst.process(&sorted, &mut l, &mut r);
    [l, r]
}

/// The instrument library's event for the host event `e` of `events`, as
/// the plugin turns it into one (`None`: the plugin hears it otherwise, or
/// not at all).
fn library_event(
    e: &HostEvent,
    events: &[HostEvent],
    params: &InstrumentParams,
) -> Option<LibEvent> {
    match *e {
        HostEvent::NoteOn { at, key, velocity } => Some(LibEvent {
            offset: at,
            event: Event::NoteOn {
                key,
                velocity_norm: velocity as f32 as f64,
            },
        }),
        HostEvent::NoteOff { at, key } => Some(LibEvent {
            offset: at,
            event: Event::NoteOff { key },
        }),
        HostEvent::Midi { at, data } => library_midi_event(at, data),
        HostEvent::Tuning { at, key, semitones } => Some(LibEvent {
            offset: at,
            event: Event::NoteTuning {
                key: Some(key),
                semitones,
            },
        }),
        HostEvent::Pressure { at, key, value } => Some(LibEvent {
            offset: at,
            event: Event::NotePressure {
                key: Some(key),
                value: f64::from(value as f32),
            },
        }),
        HostEvent::Brightness { at, key, value } => Some(LibEvent {
            offset: at,
            event: Event::NoteBrightness {
                key: Some(key),
                value: f64::from(value as f32),
            },
        }),
        HostEvent::NoteOnId {
            at, key, velocity, ..
        } => Some(LibEvent {
            offset: at,
            event: Event::NoteOn {
                key,
                velocity_norm: velocity as f32 as f64,
            },
        }),
        HostEvent::PolyMod {
            at,
            id,
            target,
            amount,
        } => {
            // the key of the note id (the last note-on with it before)
            let key = events.iter().rev().find_map(|e| match *e {
                HostEvent::NoteOnId {
                    at: a, key, id: i, ..
                } if i == id && a <= at => Some(key),
                _ => None,
            })?;
            Some(LibEvent {
                offset: at,
                event: target.event(&params.scene, key, amount),
            })
        }
        HostEvent::Param { .. } => None,
    }
}

/// The instrument library's event for the MIDI message `data` at sample
/// `at`, as the plugin turns it into one (`None`: the plugin hears it
/// otherwise, or not at all).
fn library_midi_event(at: usize, data: [u8; 3]) -> Option<LibEvent> {
    match data {
        [0xB0, c @ (64 | 66), v] => Some(LibEvent {
            offset: at,
            event: if c == 64 {
                Event::Sustain { down: v >= 64 }
            } else {
                Event::Sostenuto { down: v >= 64 }
            },
        }),
        [0xE0, lsb, msb] => {
            // the 14-bit wheel, centre 8192 (the plugin's own mapping)
            let m = f64::from(u16::from(lsb & 0x7f) | (u16::from(msb & 0x7f) << 7)) - 8192.0;
            Some(LibEvent {
                offset: at,
                event: Event::PitchBend {
                    value: if m >= 0.0 { m / 8191.0 } else { m / 8192.0 },
                },
            })
        }
        // the mod wheel and channel aftertouch as nice-plug gives them
        // (value / 127 in f32)
        [0xB0, 1, v] => Some(LibEvent {
            offset: at,
            event: Event::ModWheel {
                value: f64::from(f32::from(v) / 127.0),
            },
        }),
        [0xD0, v, _] => Some(LibEvent {
            offset: at,
            event: Event::ChannelPressure {
                value: f64::from(f32::from(v) / 127.0),
            },
        }),
        _ => None,
    }
}

// ---------------------------------------------------------------------------
// Signal helpers

/// Root mean square (0 for empty).
pub fn rms(x: &[f32]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|&v| (v as f64) * (v as f64)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Peak magnitude.
pub fn peak(x: &[f32]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64))
}

/// Largest sample-to-sample change.
pub fn max_step(x: &[f32]) -> f64 {
    x.windows(2)
        .map(|w| (w[1] as f64 - w[0] as f64).abs())
        .fold(0.0, f64::max)
}

/// Index of the first sample whose magnitude exceeds `threshold`.
pub fn first_above(x: &[f32], threshold: f32) -> Option<usize> {
    x.iter().position(|v| v.abs() > threshold)
}

/// Largest absolute difference.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .fold(0.0, f64::max)
}

/// Write a stereo 32-bit float WAV.
pub fn write_wav(path: &Path, rate_hz: f64, ch: &[Vec<f32>; 2]) {
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d).expect("mkdir");
    }
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: rate_hz.round() as u32,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec)
        .unwrap_or_else(|e| panic!("create {}: {e}", path.display()));
    for (l, r) in ch[0].iter().zip(&ch[1]) {
        w.write_sample(*l).expect("write");
        w.write_sample(*r).expect("write");
    }
    w.finalize().expect("finalize wav");
}

/// The JSON of a saved plugin state (nice-plug's: a little-endian length,
/// then the JSON).
pub fn json_of(state: &[u8]) -> String {
    let n = u64::from_le_bytes(state[..8].try_into().unwrap()) as usize;
    String::from_utf8(state[8..8 + n].to_vec()).expect("utf-8 JSON")
}

/// A plugin state holding `json` (see [`json_of`]).
pub fn state_of(json: &str) -> Vec<u8> {
    let mut out = (json.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(json.as_bytes());
    out
}

/// `state` (nice-plug's JSON) with the user scene field set to `text`
/// loaded from `path`, as the editor's scene browser leaves it.
pub fn with_user_scene(state: &[u8], name: &str, text: &str, path: &Path) -> Vec<u8> {
    let mut v: serde_json::Value = serde_json::from_str(&json_of(state)).unwrap();
    let scene = serde_json::json!({ "name": name, "text": text, "path": path });
    v["fields"]["user_scene"] = serde_json::Value::String(scene.to_string());
    state_of(&v.to_string())
}
