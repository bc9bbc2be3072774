//! The events a render plays: [`HostEvent`] and its constructors (notes,
//! MIDI, note expressions, parameters, polyphonic modulation), and the
//! parameter ids and mappings they are written with.

use modal_contact::instrument::Event;

/// An event at an absolute sample position of a render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HostEvent {
    /// Note on (velocity 0..1).
    NoteOn {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Velocity 0..1.
        velocity: f64,
    },
    /// Note off.
    NoteOff {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
    },
    /// A raw MIDI 1.0 message (e.g. a controller: `[0xB0, 64, 127]`).
    Midi {
        /// Sample position.
        at: usize,
        /// The three bytes.
        data: [u8; 3],
    },
    /// A CLAP "tuning" note expression for `key` on channel 1 \[semitones\].
    Tuning {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Semitones.
        semitones: f64,
    },
    /// A CLAP "pressure" note expression for `key` on channel 1 (0 .. 1).
    Pressure {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Pressure.
        value: f64,
    },
    /// A CLAP "brightness" note expression for `key` on channel 1 (0 .. 1).
    Brightness {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Brightness.
        value: f64,
    },
    /// Note on with the host's note id (CLAP `note_id`), channel 1.
    NoteOnId {
        /// Sample position.
        at: usize,
        /// MIDI key.
        key: u8,
        /// Velocity 0..1.
        velocity: f64,
        /// The note id.
        id: u32,
    },
    /// A CLAP polyphonic modulation (`param_mod` on one note id) of a
    /// parameter by `amount` (normalized offset).
    PolyMod {
        /// Sample position.
        at: usize,
        /// The note id it modulates.
        id: u32,
        /// The parameter.
        target: PolyTarget,
        /// Normalized offset.
        amount: f64,
    },
    /// Parameter value (CLAP value: normalised for continuous parameters,
    /// step index for enums and bools).
    Param {
        /// Sample position.
        at: usize,
        /// CLAP param id.
        id: u32,
        /// Value.
        value: f64,
    },
}

impl HostEvent {
    /// Sample position.
    pub fn at(&self) -> usize {
        match *self {
            HostEvent::NoteOn { at, .. }
            | HostEvent::NoteOff { at, .. }
            | HostEvent::Midi { at, .. }
            | HostEvent::Tuning { at, .. }
            | HostEvent::Pressure { at, .. }
            | HostEvent::Brightness { at, .. }
            | HostEvent::NoteOnId { at, .. }
            | HostEvent::PolyMod { at, .. }
            | HostEvent::Param { at, .. } => at,
        }
    }
}

/// A note-on event.
pub fn on(at: usize, key: u8, velocity: f64) -> HostEvent {
    HostEvent::NoteOn { at, key, velocity }
}

/// A note-off event.
pub fn off(at: usize, key: u8) -> HostEvent {
    HostEvent::NoteOff { at, key }
}

/// A MIDI controller change on channel 1 (`value` 0..127).
pub fn cc(at: usize, controller: u8, value: u8) -> HostEvent {
    HostEvent::Midi {
        at,
        data: [0xB0, controller, value],
    }
}

/// A MIDI pitch bend on channel 1 (`value` 0..16383, centre 8192).
pub fn pitch_bend(at: usize, value: u16) -> HostEvent {
    HostEvent::Midi {
        at,
        data: [0xE0, (value & 0x7f) as u8, ((value >> 7) & 0x7f) as u8],
    }
}

/// A per-note tuning (CLAP note expression) for `key`.
pub fn note_tuning(at: usize, key: u8, semitones: f64) -> HostEvent {
    HostEvent::Tuning { at, key, semitones }
}

/// A per-note pressure (CLAP note expression) for `key`.
pub fn note_pressure(at: usize, key: u8, value: f64) -> HostEvent {
    HostEvent::Pressure { at, key, value }
}

/// A per-note brightness (CLAP note expression) for `key`.
pub fn note_brightness(at: usize, key: u8, value: f64) -> HostEvent {
    HostEvent::Brightness { at, key, value }
}

/// A parameter event by string id (CLAP value, see [`HostEvent::Param`]).
pub fn param(at: usize, id: &str, value: f64) -> HostEvent {
    HostEvent::Param {
        at,
        id: param_id(id),
        value,
    }
}

/// A parameter a CLAP host may modulate per voice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PolyTarget {
    /// Hardness.
    Hardness,
    /// Strike position.
    StrikePosition,
    /// Damper.
    Damper,
}

impl PolyTarget {
    /// The parameter's string id.
    pub fn param_id(self) -> &'static str {
        match self {
            Self::Hardness => "hardness",
            Self::StrikePosition => "strike_pos",
            Self::Damper => "damper",
        }
    }

    /// The instrument event a modulation by `amount` (normalized) of a
    /// voice of `key` means, at the parameter values `played`, through the
    /// parameters' ranges written out here (Strike position and Damper
    /// are linear 0 .. 1), not through the plugin's code.
    pub fn event(
        self,
        played: &modal_contact::instrument::SceneParams,
        key: u8,
        amount: f64,
    ) -> Event {
        let key = Some(key);
        let linear = |x: f64| (x + amount).clamp(0.0, 1.0) - x;
        match self {
            Self::Hardness => Event::NoteHardness {
                key,
                factor: hardness_factor(played.stiffness_factor, amount),
            },
            Self::StrikePosition => Event::NotePosition {
                key,
                offset: linear(played.strike_pos_norm.unwrap_or(0.5)),
            },
            Self::Damper => Event::NoteDamper {
                key,
                offset: linear(played.damper_norm),
            },
        }
    }
}

/// A polyphonic modulation of `target` on note id `id`.
pub fn poly_mod(at: usize, id: u32, target: PolyTarget, amount: f64) -> HostEvent {
    HostEvent::PolyMod {
        at,
        id,
        target,
        amount,
    }
}

/// A Hardness modulation's factor: the Hardness parameter's value at its
/// knob position plus `offset` (clamped to the knob's range) over
/// `played`, through the parameter's mapping written out here (0.01 ..
/// 100, skewed: `0.01 + 99.99 n^4`), not through the plugin's code.
pub fn hardness_factor(played: f64, offset: f64) -> f64 {
    let (min, max) = (0.01, 100.0);
    let n = ((played - min) / (max - min)).powf(0.25);
    let m = (n + offset).clamp(0.0, 1.0);
    (min + (max - min) * m.powi(4)) / played
}

/// A note-on with a note id.
pub fn on_id(at: usize, key: u8, velocity: f64, id: u32) -> HostEvent {
    HostEvent::NoteOnId {
        at,
        key,
        velocity,
        id,
    }
}

/// nice-plug's string id -> CLAP param id hash.
pub fn param_id(id: &str) -> u32 {
    let mut hash: u32 = 0;
    for b in id.bytes() {
        hash = hash.wrapping_mul(31).wrapping_add(b as u32);
    }
    hash & !(1 << 31)
}
