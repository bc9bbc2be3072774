//! Build-time only: see this crate's Cargo.toml. Intentionally empty.
