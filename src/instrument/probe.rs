//! What the instrument shows of its voices while a probe is attached: the
//! plugin's live view (docs/plugin.md, "The editor") attaches one that
//! writes into a wait-free ring for the editor window. With no probe, or a
//! probe switched off, the voices run the plain block path and nothing is
//! recorded.

use crate::engine::Motion;

/// One chunk (at most [`super::CHECK_INTERVAL_SAMPLES`] samples) of one
/// sounding voice, as the engine computed it.
#[derive(Debug, Clone, Copy)]
pub struct VoiceChunk<'a> {
    /// Voice index.
    pub voice: usize,
    /// Its MIDI key.
    pub key: u8,
    /// Released (on its damped scene or held by a pedal after note-off).
    pub released: bool,
    /// The instrument's clock at the chunk's first sample.
    pub start: u64,
    /// The motion of each sample of the chunk (hammer and contact point).
    pub motion: &'a [Motion],
    /// The voice's total energy after the chunk's last sample \[J\];
    /// `None` while the voice plays back a stored strike from rest (the
    /// recording holds no energies: docs/numerics.md, "A strike from rest
    /// played back").
    pub energy_j: Option<f64>,
    /// A driven voice's position along its path at the chunk's end \[m\]
    /// (`None`: the scene is not driven; docs/design.md, "Rolling and
    /// scraping").
    pub path_m: Option<f64>,
}

/// Receives the voices' motion; called on the audio thread, so an
/// implementation must not block or allocate. \[audio-thread\]
pub trait VoiceProbe: Send {
    /// One chunk of one sounding voice.
    fn voice_chunk(&mut self, chunk: &VoiceChunk);
}
