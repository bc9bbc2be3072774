//! Energy-stable modal contact instrument (after Rath, "Energy-stable modelling
//! of contacting modal objects with piece-wise linear interaction force").
//!
//! Layers (docs/design.md, "Layers"): [`bodies`] (modes from geometry and
//! material) -> [`scene`] (parse, validate) -> [`compile`]
//! (off the audio thread: decompositions, propagators) -> [`compile::CompiledScene`]
//! -> [`engine`] (per sample, allocation-free) ; [`render`] drives it offline.

pub mod bodies;
pub mod compile;
pub mod engine;
pub mod instrument;
pub mod multi;
pub mod physics;
pub mod plugin;
pub mod presets;
pub mod render;
pub mod scene;
// The one seeded generator of every test. It lives here, not in the dev-only
// testkit crate, because the unit tests inside this crate cannot depend on a
// crate that depends on this one; testkit re-exports it for everything else.
#[doc(hidden)]
pub mod test_rng;
