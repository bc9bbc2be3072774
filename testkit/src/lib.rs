//! Test scaffolding of `modal_contact`, shared by its tests, benches, the
//! plugin tests and `cargo xtask` (the report and the golden renders), so
//! that every list, scene family and metric they have in common is written
//! once. A dev-only crate: the plugin library never depends on it.
//!
//! - [`competitors`]: the textbook integrators the report measures the
//!   engine against (and `tests/competitors.rs` checks).
//! - [`rng`]: the one seeded generator of the tests.
//! - [`scenes`]: a typed scene builder and the scene families shared by the
//!   report and the tests.
//! - [`stability`]: the catalogue of stability cases (docs/numerics.md, "The
//!   stability cases"), run by the report and by `tests/stability.rs`.
//! - [`metrics`]: relative L2 errors, contact-interval matching and the
//!   rounding bound of the energy checks.
//! - [`bundles`]: the plugin bundles the plugin tests load, and how they are
//!   copied out of `target/bundled/`.
//! - [`analysis`]: the measurements of `cargo xtask compare-real` (spectra,
//!   partials, T60, attack, 1/3-octave bands and their distance), also the
//!   recording tests' distance.

pub mod analysis;
pub mod bundles;
pub mod competitors;
pub mod metrics;
pub mod parallel;
pub mod rng;
pub mod scenes;
pub mod stability;

use std::path::PathBuf;

/// The workspace root (the directory of the plugin crate): `presets/`,
/// `target/` and `tests/` are found from here whatever the current
/// directory of the test or tool.
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("testkit/ lies inside the workspace")
        .to_path_buf()
}
