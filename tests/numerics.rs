//! The one-contact engine's numerics in one test binary: against closed
//! forms, the independent reference solver and the competitor integrators;
//! energy and stability; and each of its paths (block processing, the output
//! band, exact savings, the Hermite fast path, structured changes of basis,
//! strikes from rest, played-back strikes) against the path it replaces.
//!
//! Each module is one file of `tests/`, as it was when each was a test
//! binary of its own; a test is named `file::test` (`cargo test --test
//! numerics stability::`). Cargo.toml lists the test binaries and
//! `tests/doc_references.rs` checks that every file of `tests/` is in
//! exactly one of them.

#[path = "band.rs"]
mod band;
#[path = "blocks.rs"]
mod blocks;
#[path = "closed_forms.rs"]
mod closed_forms;
#[path = "competitors.rs"]
mod competitors;
#[path = "drive.rs"]
mod drive;
#[path = "energy.rs"]
mod energy;
#[path = "hermite_fast_path.rs"]
mod hermite_fast_path;
#[path = "reference.rs"]
mod reference;
#[path = "rest_strike.rs"]
mod rest_strike;
#[path = "savings.rs"]
mod savings;
#[path = "stability.rs"]
mod stability;
#[path = "stiff_switching.rs"]
mod stiff_switching;
#[path = "stored_strike.rs"]
mod stored_strike;
#[path = "structured_switch.rs"]
mod structured_switch;
