//! Several contacts at once, in one test binary: the several-contact engine
//! against the independent reference solver, closed forms and the
//! one-contact engine; contact laws of several pieces against closed forms; its block path against its search; contacts between any two bodies; strikes into a
//! running state; two walls on one side.
//!
//! Each module is one file of `tests/`; a test is named `file::test`
//! (`cargo test --test multi multi_contact::`). Cargo.toml lists the test
//! binaries and `tests/doc_references.rs` checks that every file of
//! `tests/` is in exactly one of them.

#[path = "contact_law.rs"]
mod contact_law;
#[path = "multi_block.rs"]
mod multi_block;
#[path = "multi_bodies.rs"]
mod multi_bodies;
#[path = "multi_contact.rs"]
mod multi_contact;
#[path = "multi_strike.rs"]
mod multi_strike;
#[path = "two_walls.rs"]
mod two_walls;
