//! What a host sends the instrument: notes and pedals at sample offsets.

/// What a host sends: notes. Times are sample offsets within the block
/// passed to \[`Instrument::process`\] (or \[`Instrument::process_events`\],
/// which takes them one at a time).
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
    /// Every key up (MIDI CC 123, All Notes Off; a CLAP note-off of every
    /// key): a note-off for every sounding note, so the pedals hold what
    /// they hold (MIDI 1.0: the notes a pedal sustains sound on until it
    /// comes up) and a scene without damper rings on (docs/plugin.md,
    /// "Pedals").
    AllNotesOff,
    /// Stop the note of `key` (every note for `None`) at once (a CLAP
    /// note choke): its voice fades out over [`FADE_S`](super::FADE_S)
    /// exactly as a stolen voice does, whatever the pedals, and is free
    /// for the next note (docs/plugin.md, "Velocity, pitch, voices").
    Choke {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
    },
    /// MIDI CC 120, All Sound Off: every sounding voice fades out over
    /// [`FADE_S`](super::FADE_S) as a stolen voice does, whatever the
    /// pedals; the pedals and the controllers stay as they are.
    AllSoundOff,
    /// MIDI CC 121, Reset All Controllers (MIDI's recommended practice
    /// RP-015): the sustain and sostenuto pedals up (the notes they held
    /// whose keys are up are damped, as when a pedal comes up), the wheel
    /// at its centre (the voices glide back), channel aftertouch, the mod
    /// wheel and every note's pressure at 0. Notes, brightness and
    /// per-note tuning stay.
    ResetControllers,
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
    /// Pressure on a note, 0 .. 1 (the CLAP and VST3 "pressure" note
    /// expression, MIDI polyphonic aftertouch, an MPE member channel's
    /// pressure): a damper pressed on that note's object, every mode
    /// decaying faster by up to [`MAX_PRESSURE_DECAY_PER_S`](super::MAX_PRESSURE_DECAY_PER_S)
    /// (docs/plugin.md, "Pressure and the mod wheel"). `key: None`: every
    /// voice. Out of range is clamped, not a number is 0; a new note on
    /// the key starts without pressure.
    NotePressure {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
        /// Pressure, 0 .. 1.
        value: f64,
    },
    /// Brightness of a note, 0 .. 1 (the CLAP and VST3 "brightness" note
    /// expression, an MPE member channel's timbre, CC 74): the hardness of
    /// that note's strikes, in five levels around the Hardness parameter
    /// (0.5 is the parameter's own; 0 a quarter of its contact stiffness, 1
    /// four times it; docs/plugin.md, "Brightness"). It applies to the
    /// note's next contact: at once when its hammer is not touching the
    /// object (a brightness at the note's onset shapes its first strike),
    /// else after that contact. `key: None`: every voice. Out of range is
    /// clamped, not a number is 0.5; a new note on the key starts at 0.5.
    NoteBrightness {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
        /// Brightness, 0 .. 1.
        value: f64,
    },
    /// Hardness of a note, as a factor of the Hardness parameter's contact
    /// stiffness (what a host's polyphonic modulation of Hardness asks of
    /// that note's voice): rounded to the brightness levels (stiffness
    /// steps of [`TIMBRE_STIFFNESS_STEP`](super::TIMBRE_STIFFNESS_STEP),
    /// [`hardness_level`](super::hardness_level)) and added to the note's
    /// brightness level, within the compiled levels; it applies as a
    /// brightness does (the next contact; at the note's onset, its first).
    /// `key: None`: every voice. Not a finite positive number is 1; a new note on
    /// the key starts at 1 (docs/plugin.md, "Polyphonic modulation").
    NoteHardness {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
        /// Contact stiffness over the Hardness parameter's.
        factor: f64,
    },
    /// Strike position of a note, as an offset from the Strike position
    /// parameter (what a host's polyphonic modulation of Strike position
    /// asks of that note's voice, in the parameter's units): rounded to
    /// levels of [`POSITION_STEP`](super::POSITION_STEP), within two on
    /// each side ([`position_level`](super::position_level)); it applies as
    /// a brightness does. Only with Custom strike position on, and once the
    /// position levels are compiled
    /// ([`VariantSet::position`](super::VariantSet)); before, the voice
    /// plays at the parameter's position. Not a number is 0; a new note on
    /// the key starts at 0 (docs/plugin.md, "Polyphonic modulation").
    NotePosition {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
        /// Offset from the parameter's position (0 .. 1 units).
        offset: f64,
    },
    /// Damper of a note, as an offset from the Damper parameter (a host's
    /// polyphonic modulation of Damper, in the parameter's units): rounded
    /// to levels of [`DAMPER_STEP`](super::DAMPER_STEP), within two on
    /// each side ([`damper_level`](super::damper_level)); it takes effect
    /// when the note is released (a released note moves to its new level's
    /// damped scene after any contact under way). Once the damper levels
    /// are compiled ([`VariantSet::damper`](super::VariantSet)); before,
    /// the voice is damped as the parameter says. Not a number is 0; a new
    /// note on the key starts at 0 (docs/plugin.md, "Polyphonic
    /// modulation").
    NoteDamper {
        /// MIDI key, or `None` for every voice.
        key: Option<u8>,
        /// Offset from the parameter's damper (0 .. 1 units).
        offset: f64,
    },
    /// Channel aftertouch, 0 .. 1: the same damper on every voice (a voice
    /// takes the largest of its note's pressure, this and the mod wheel).
    ChannelPressure {
        /// Pressure, 0 .. 1.
        value: f64,
    },
    /// The mod wheel (MIDI CC 1), 0 .. 1: the damper of
    /// [`ChannelPressure`](Self::ChannelPressure), for keyboards without
    /// aftertouch.
    ModWheel {
        /// Wheel position, 0 .. 1.
        value: f64,
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
