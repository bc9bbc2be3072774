//! Pure f64 math: models, closed-form blocks, decompositions. May allocate;
//! never runs on the audio thread.

pub mod block;
pub mod decomp;
pub mod error;
pub mod hodlr;
pub mod linalg;
pub mod model;
pub mod secular;

pub use error::{Check, DecompError, ModelError, SecularError};
