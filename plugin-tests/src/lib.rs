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

mod bundles;
mod events;
mod host;
mod library;
mod plugin;
mod signal;
mod state;

pub use bundles::{clap_bundle, out_dir, vst3_bundle, workspace_root, Variant};
pub use events::{
    cc, hardness_factor, note_brightness, note_pressure, note_tuning, off, on, on_id, param,
    param_id, pitch_bend, poly_mod, HostEvent, PolyTarget,
};
pub use host::{
    descriptors, host_info, load_entry, DescriptorInfo, TestHost, TestMainThread, TestShared,
};
pub use library::{library_render, library_render_prepared};
pub use plugin::{Audio, LoadedPlugin, NoteEnd, RenderSpec, Session};
pub use signal::{first_above, max_abs_diff, max_step, peak, rms, write_wav};
pub use state::{json_of, state_of, with_user_scene};

use modal_contact::plugin::ModalContact;
use nice_plug::prelude::ClapPlugin;

/// The plugin's CLAP id, as the plugin declares it: the tests check that
/// the built bundle exports exactly this.
pub const PLUGIN_ID: &str = <ModalContact as ClapPlugin>::CLAP_ID;
/// Bundle file stem.
pub use modal_testkit::bundles::BUNDLE_NAME;
