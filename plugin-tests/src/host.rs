//! The minimal clack host: its handlers (what the plugin asked for and
//! told the host), its info, and the plugin entry loaded once per process
//! with its factory's descriptors.

use clack_extensions::latency::{HostLatency, HostLatencyImpl};
use clack_extensions::preset_discovery::prelude::{HostPresetLoad, Location};
use clack_extensions::preset_discovery::HostPresetLoadImpl;
use clack_host::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Mutex;

/// Host callbacks callable from any thread: they only record what the
/// plugin asked for; the test's main loop decides when to act on it
/// ([`Session::restart_pending`](crate::Session::restart_pending),
/// [`LoadedPlugin::run_callbacks`](crate::LoadedPlugin::run_callbacks)).
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
