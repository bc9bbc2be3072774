//! Energy-stable modal contact instrument (after Rath, "Energy-stable modelling
//! of contacting modal objects with piece-wise linear interaction force").
//!
//! Layers (DESIGN.md section 4): [`scene`] (parse, validate) -> [`compile`]
//! (off the audio thread: decompositions, propagators) -> [`compile::CompiledScene`]
//! -> [`engine`] (per sample, allocation-free) ; [`render`] drives it offline.

pub mod compile;
pub mod engine;
pub mod instrument;
pub mod physics;
pub mod plugin;
pub mod presets;
pub mod render;
pub mod scene;
#[cfg(test)]
mod test_rng;
