//! The offline tools behind `cargo xtask`, as a library so that tests and
//! benchmarks run the same code as the commands:
//!
//! - [`offline`]: one job (a scene, or a note of a scene played through the
//!   instrument), WAV writing, note and velocity lists;
//! - [`render`]: `cargo xtask render`, one scene or a batch;
//! - [`plot`]: the render plot and the report's diagrams;
//! - [`report`]: `cargo xtask report` (error against run time, stability);
//! - [`benchmarks`]: `cargo xtask benchmarks` (the measurement benches'
//!   tables, written to docs/benchmarks.md);
//! - [`multisample`]: every note x velocity layer of a scene as WAVs plus
//!   an SFZ file;
//! - [`compare_real`]: `cargo xtask compare-real` (the presets against real
//!   recordings from the FluidR3 General MIDI soundfont);
//! - [`levels`]: `cargo xtask levels` (each preset's loudness at one
//!   velocity, and the `level_db` that evens them out);
//! - [`analyze`]: `cargo xtask analyze` (a struck object's modes from a
//!   recording, as a scene file);
//! - [`analyze_real`]: `cargo xtask analyze-real` (that analysis of the
//!   FluidR3 soundfont's mallet percussion, against the 3 dB target).

pub mod analyze;
pub mod analyze_real;
pub mod benchmarks;
pub mod compare_real;
pub mod levels;
pub mod multisample;
pub mod offline;
pub mod plot;
pub mod render;
pub mod report;
