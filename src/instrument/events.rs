//! What a host sends the instrument: notes at sample offsets.

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
    /// Release every voice.
    AllNotesOff,
}

/// An event at a sample offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedEvent {
    /// Sample offset within the rendered span.
    pub offset: usize,
    /// The event.
    pub event: Event,
}
