//! The CLAP polyphonic modulation ids and the per-voice variants a host's
//! modulation asks for (docs/plugin.md, "Polyphonic modulation"): shared
//! by the parameters (which name them) and the audio thread (which asks
//! for the variants), so neither imports the other for them.

use crate::instrument::VariantSet;
use std::sync::atomic::{AtomicBool, Ordering};

/// The CLAP polyphonic modulation id of Hardness (docs/plugin.md,
/// "Polyphonic modulation").
pub const POLY_HARDNESS: u32 = 0;
/// The CLAP polyphonic modulation id of Strike position.
pub const POLY_POSITION: u32 = 1;
/// The CLAP polyphonic modulation id of Damper.
pub const POLY_DAMPER: u32 = 2;

/// Which per-voice variants a host's polyphonic modulation has asked for
/// since the plugin was created: the audio thread sets them when the first
/// modulation of Strike position or Damper arrives, and the next compile
/// includes them (docs/plugin.md, "Polyphonic modulation"). Atomics: the
/// audio thread stores, any thread loads.
#[derive(Debug, Default)]
pub struct VariantsWanted {
    position: AtomicBool,
    damper: AtomicBool,
}

impl VariantsWanted {
    /// The variants asked for. \[any-thread\]
    pub fn get(&self) -> VariantSet {
        VariantSet {
            position: self.position.load(Ordering::Relaxed),
            damper: self.damper.load(Ordering::Relaxed),
        }
    }

    /// Ask for the variants of polyphonic modulation id `poly` (Hardness
    /// needs none: its levels are always there). \[audio-thread\]
    pub fn want(&self, poly: u32) {
        match poly {
            POLY_POSITION => self.position.store(true, Ordering::Relaxed),
            POLY_DAMPER => self.damper.store(true, Ordering::Relaxed),
            _ => {}
        }
    }
}
