//! Test scaffolding of `modal_contact`, shared by its tests, benches, the
//! plugin tests and `cargo xtask` (the report and the golden renders), so
//! that every list, scene family and metric they have in common is written
//! once. A dev-only crate: the plugin library never depends on it.
//!
//! - [`competitors`]: the textbook integrators the report measures the
//!   engine against (and `tests/competitors.rs` checks).
//! - [`rng`]: the one seeded generator of the tests.
//! - [`bundles`]: the plugin bundles the plugin tests load, and how they are
//!   copied out of `target/bundled/`.

pub mod bundles;
pub mod competitors;
pub mod rng;
