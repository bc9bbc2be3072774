//! The instrument, in one test binary: a driven scene's notes, the
//! lookahead, the damper on release, a stiffening mallet's brightness, and
//! no subnormal f32 output.
//!
//! Each module is one file of `tests/`; a test is named `file::test`
//! (`cargo test --test instrument lookahead::`). Cargo.toml lists the test
//! binaries and `tests/doc_references.rs` checks that every file of
//! `tests/` is in exactly one of them.

#[path = "driven_notes.rs"]
mod driven_notes;
#[path = "lookahead.rs"]
mod lookahead;
#[path = "release_damper.rs"]
mod release_damper;
#[path = "stiffening.rs"]
mod stiffening;
#[path = "subnormal_output.rs"]
mod subnormal_output;
