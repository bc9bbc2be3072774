//! Energy-stable modal contact instrument (after Rath, "Energy-stable modelling
//! of contacting modal objects with piece-wise linear interaction force").
//!
//! Layers (docs/design.md, "Layers"): [`bodies`] (modes from geometry and
//! material) -> [`scene`] (parse, validate) -> [`compile`](mod@compile)
//! (off the audio thread: decompositions, propagators) -> [`CompiledScene`]
//! -> [`engine`] (per sample, allocation-free); [`multi`] runs scenes of
//! several contacts and [`play`] is the one way in for both ([`compile()`]
//! -> [`Compiled`] -> [`Voice`]); [`render`](mod@render) drives it offline, [`instrument`] plays notes through it, and `plugin`
//! (feature `plugin`, on by default) puts the instrument in a CLAP or VST3
//! host.
//!
//! # Embedding
//!
//! Without the plugin (`default-features = false`) the crate is the core:
//! scene, compiler, engine and offline render, with none of the plugin's
//! dependencies (nice-plug, egui, rfd, directories, clap-sys). The names
//! below are re-exported here. A scene file of one to four contacts,
//! compiled at 48 kHz, its mallet thrown at the object and played in
//! blocks of 64 samples (`examples/embed.rs` does the same and writes a
//! WAV file):
//!
//! ```
//! use modal_contact::{compile, Scene, Voice};
//! use std::path::Path;
//!
//! let scene = Scene::from_file(Path::new("presets/marimba-bar.toml"))?;
//! let compiled = compile(&scene, 48_000.0)?;
//! let mut voice = Voice::new(&compiled);
//! // contact 0's mallet put on the surface, moving down at 2 m/s
//! voice.strike(&compiled, 0, 0.0, -2.0)?;
//! let (mut left, mut right) = ([0.0; 64], [0.0; 64]);
//! let mut out = Vec::new();
//! for _ in 0..2 * 48_000 / 64 {
//!     voice.process_block(&compiled, &mut left, &mut right);
//!     out.extend(left.iter().zip(&right).flat_map(|(l, r)| [*l, *r]));
//! }
//! assert!(out.iter().any(|x| x.abs() > 1e-6));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`Scene::from_file`] and [`compile()`] refuse a bad scene with an error
//! that names the field ([`SceneError`], [`CompileError`]); [`Voice::strike`]
//! refuses a strike it cannot take ([`StrikeError`]) and changes nothing,
//! and [`Voice::process_block`] neither fails nor allocates. [`render()`]
//! renders a scene offline in one call, with the per-sample trace if asked
//! ([`RenderOptions`]). For what only one contact offers (played-back
//! strikes, the energy and trace of each sample), [`compile_one`] gives the
//! [`CompiledScene`] an [`EngineState`] runs.

pub mod bodies;
pub mod compile;
pub mod engine;
pub mod instrument;
pub mod multi;
pub mod physics;
pub mod play;
#[cfg(feature = "plugin")]
pub mod plugin;
pub mod presets;
/// Modes of a struck object from a recording of its strike (ESPRIT on sub-bands), and its scene.
pub mod recording;
pub mod render;
pub mod scene;
// The one seeded generator of every test. It lives here, not in the dev-only
// testkit crate, because the unit tests inside this crate cannot depend on a
// crate that depends on this one; testkit re-exports it for everything else.
#[doc(hidden)]
pub mod test_rng;

pub use compile::{compile_one, CompileError, CompiledScene};
pub use engine::EngineState;
pub use play::{compile, Compiled, StrikeError, Voice};
pub use render::{render, RenderError, RenderOptions, RenderOutput};
pub use scene::{Scene, SceneError};
