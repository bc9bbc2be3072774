//! What a host sends the instrument: notes and pedals at sample offsets.

/// What a host sends: notes. Times are sample offsets within the block
/// passed to \[`Instrument::process`\] (or the caller renders up to the event
/// with \[`Instrument::render`\] and then calls \[`Instrument::handle`\]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// Strike `key` with `velocity_norm` in 0..1.
    NoteOn {
        /// MIDI key.
        key: u8,
        /// Velocity 0..1 (MIDI velocity / 127).
        velocity_norm: f64,
    },
    /// Release `key` (the damper falls).
    NoteOff {
        /// MIDI key.
        key: u8,
    },
    /// Release every voice (the pedals do not hold it).
    AllNotesOff,
    /// Sustain (damper) pedal, MIDI CC 64: while down, released notes are
    /// not damped; when it comes up, every note no longer held is.
    Sustain {
        /// Pedal down.
        down: bool,
    },
    /// Sostenuto pedal, MIDI CC 66: pressed, it holds the notes that are
    /// down at that moment (only those) until it comes up.
    Sostenuto {
        /// Pedal down.
        down: bool,
    },
    /// The pitch-bend wheel, -1 (down) .. 0 (centre) .. 1 (up): every voice
    /// bends by `value` times [`PlayParams::bend_range_semitones`](super::PlayParams::bend_range_semitones),
    /// smoothly (docs/plugin.md, "Pitch bend"). Out of range is clamped, not
    /// a number is 0.
    PitchBend {
        /// Wheel position, -1 .. 1.
        value: f64,
    },
    /// Per-note tuning (the CLAP and VST3 "tuning" note expression): the
    /// voice of `key` (every voice when `None`, CLAP's wildcard) moves to
    /// its note's pitch plus `semitones`, on top of the wheel, like a bend of
    /// that note alone (docs/plugin.md, "Per-note tuning"). Sent at the
    /// note's onset (before the voice has rendered a sample) it applies at
    /// once, so the note starts at its tuned pitch; later, it glides like
    /// the wheel. Clamped to
    /// ±[`MAX_NOTE_TUNING_SEMITONES`](super::MAX_NOTE_TUNING_SEMITONES); not
    /// a number is 0. A new note on the key starts untuned.
    NoteTuning {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
        /// Offset from the note's pitch \[semitones\].
        semitones: f64,
    },
}

/// An event at a sample offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedEvent {
    /// Sample offset within the rendered span.
    pub offset: usize,
    /// The event.
    pub event: Event,
}
