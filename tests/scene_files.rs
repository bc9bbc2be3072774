//! Scene files and what they describe, in one test binary: parsing and
//! refusals, the presets, objects from geometry and material, radiation to
//! a listener, modal mallets, a scene's level, an object's scene from a
//! recording; and the project's documents
//! against its code (references, tolerances, the layer picture, the
//! README's example, this list of test binaries).
//!
//! Each module is one file of `tests/`; a test is named `file::test`
//! (`cargo test --test scene_files presets::`). Cargo.toml lists the test
//! binaries and `tests/doc_references.rs` checks that every file of
//! `tests/` is in exactly one of them.

#[path = "doc_references.rs"]
mod doc_references;
#[path = "level.rs"]
mod level;
#[path = "modal_mallet.rs"]
mod modal_mallet;
#[path = "physical_objects.rs"]
mod physical_objects;
#[path = "presets.rs"]
mod presets;
#[path = "radiation.rs"]
mod radiation;
#[path = "recording.rs"]
mod recording;
#[path = "scenes.rs"]
mod scenes;
