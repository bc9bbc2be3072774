//! MIDI Polyphonic Expression (MPE) over MIDI 1.0: per-note pitch from the
//! pitch bend of each note's own channel (docs/plugin.md, "Per-note tuning").
//!
//! MPE is off until the controller or host sends an MPE Configuration
//! Message (RPN 6: CC 101 = 0, CC 100 = 6, CC 6 = the number of member
//! channels, 0 to 15; 0 turns the zone off): on channel 1 for the lower
//! zone (members: channels 2 ..= members + 1), on channel 16 for the upper
//! zone (members: channels 15 - members + 1 ..= 15, counting down from 15).
//! Both zones may be on; a zone configured over the other's channels
//! shrinks the other (MPE's rule), and each message resets the bend
//! ranges, bends, pressures and notes of the channels it touches. On a
//! member channel a pitch bend retunes the notes sounding from that
//! channel (an [`Event::NoteTuning`] per key, at the bend's sample), by the
//! channel's bend range (48 semitones unless RPN 0 on that channel says
//! otherwise), its channel pressure presses them
//! ([`Event::NotePressure`]) and its timbre (CC 74) sets their brightness
//! ([`Event::NoteBrightness`]); a note-on on a member channel whose bend is
//! off centre, whose pressure is up or that has had a timbre starts that
//! way (its tuning, pressure and brightness follow the note-on at the same
//! sample). The manager channels
//! (1 and 16) and channels outside both zones stay the wheel and the
//! channel aftertouch for every voice.
//!
//! Plain data, fixed size: the audio thread owns it; no allocation.

use crate::instrument::{Event, MAX_NOTE_TUNING_SEMITONES};

/// Per-note bend range of member channels after the configuration message
/// \[semitones\] (MPE's default).
pub const MEMBER_BEND_RANGE_SEMITONES: f64 = 48.0;

/// No channel (a key not sounding from any member channel).
const NONE: u8 = u8::MAX;

/// What one MIDI message becomes: at most two events per key, plus one.
#[derive(Debug, Clone)]
pub struct Out {
    events: [Event; 257],
    len: usize,
}

impl Default for Out {
    fn default() -> Self {
        Self::new()
    }
}

impl Out {
    /// No events.
    pub fn new() -> Self {
        Self {
            events: [Event::AllNotesOff; 257],
            len: 0,
        }
    }

    /// Only `e`.
    pub fn set_one(&mut self, e: Event) {
        self.len = 0;
        self.push(e);
    }

    /// Add `e` (beyond the room: dropped).
    pub fn push(&mut self, e: Event) {
        if self.len < self.events.len() {
            self.events[self.len] = e;
            self.len += 1;
        }
    }

    /// Forget the events.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// The events, in order.
    pub fn as_slice(&self) -> &[Event] {
        &self.events[..self.len]
    }
}

/// The MPE state of one plugin instance.
#[derive(Debug, Clone)]
pub struct Mpe {
    /// Member channels of the lower zone (0: off).
    lower: u8,
    /// Member channels of the upper zone (0: off).
    upper: u8,
    /// Per channel: the RPN selected by CC 101 / CC 100 (MSB, LSB).
    rpn: [(u8, u8); 16],
    /// Per channel: pitch-bend range \[semitones\] (RPN 0).
    range: [f64; 16],
    /// Per channel: the bend now, -1 .. 1.
    bend: [f64; 16],
    /// Per channel: the pressure now, 0 .. 1.
    pressure: [f64; 16],
    /// Per channel: the timbre (CC 74) now, 0 .. 1, or not a number
    /// before the channel's first.
    timbre: [f64; 16],
    /// Per key: the member channel its last note-on came from.
    key_channel: [u8; 128],
}

impl Default for Mpe {
    fn default() -> Self {
        Self {
            lower: 0,
            upper: 0,
            rpn: [(127, 127); 16],
            range: [MEMBER_BEND_RANGE_SEMITONES; 16],
            bend: [0.0; 16],
            pressure: [0.0; 16],
            timbre: [f64::NAN; 16],
            key_channel: [NONE; 128],
        }
    }
}

impl Mpe {
    /// Whether a zone is configured.
    pub fn enabled(&self) -> bool {
        self.lower > 0 || self.upper > 0
    }

    fn is_member(&self, channel: u8) -> bool {
        member_of(self.lower, self.upper, channel)
    }

    /// Configure the lower (`upper == false`) or upper zone with `members`
    /// member channels: the other zone shrinks off the channels taken, and
    /// every channel whose role changes or that is in the configured zone
    /// starts afresh.
    fn configure(&mut self, upper: bool, members: u8) {
        let (lower0, upper0) = (self.lower, self.upper);
        let members = members.min(15);
        if upper {
            self.upper = members;
            if members > 0 && self.lower + members > 14 {
                self.lower = 14u8.saturating_sub(members);
            }
        } else {
            self.lower = members;
            if members > 0 && self.upper + members > 14 {
                self.upper = 14u8.saturating_sub(members);
            }
        }
        for c in 0..16u8 {
            let in_zone = if upper {
                member_of(0, self.upper, c) || c == 15
            } else {
                member_of(self.lower, 0, c) || c == 0
            };
            if in_zone || member_of(lower0, upper0, c) != self.is_member(c) {
                let i = c as usize;
                self.range[i] = MEMBER_BEND_RANGE_SEMITONES;
                self.bend[i] = 0.0;
                self.pressure[i] = 0.0;
                self.timbre[i] = f64::NAN;
                self.key_channel
                    .iter_mut()
                    .filter(|k| **k == c)
                    .for_each(|k| *k = NONE);
            }
        }
    }

    /// A note-on `event` (already translated) from `channel`, into `out`:
    /// remembers the key's channel and adds the channel's tuning after it.
    pub fn note_on(&mut self, channel: u8, event: Event, out: &mut Out) {
        out.set_one(event);
        if let Event::NoteOn { key, velocity_norm } = event {
            let member = self.is_member(channel);
            self.key_channel[key as usize & 127] = if member { channel } else { NONE };
            if velocity_norm > 0.0 && member {
                let c = channel as usize;
                if self.bend[c] != 0.0 {
                    out.push(Event::NoteTuning {
                        key: Some(key),
                        semitones: self.semitones(c),
                    });
                }
                if self.pressure[c] != 0.0 {
                    out.push(Event::NotePressure {
                        key: Some(key),
                        value: self.pressure[c],
                    });
                }
                if !self.timbre[c].is_nan() {
                    out.push(Event::NoteBrightness {
                        key: Some(key),
                        value: self.timbre[c],
                    });
                }
            }
        }
    }

    fn semitones(&self, c: usize) -> f64 {
        (self.bend[c] * self.range[c]).clamp(-MAX_NOTE_TUNING_SEMITONES, MAX_NOTE_TUNING_SEMITONES)
    }

    /// A pitch bend (`value` -1 .. 1, already mapped from the 14 bits) on
    /// `channel`: `false` (and `out` untouched) when it is the wheel (MPE
    /// off, the manager channel or a channel outside the zone), else `true`
    /// with the tunings of the keys sounding from that member channel in
    /// `out`.
    pub fn pitch_bend(&mut self, channel: u8, value: f64, out: &mut Out) -> bool {
        if !self.is_member(channel) {
            return false;
        }
        let c = channel as usize;
        self.bend[c] = value;
        let semitones = self.semitones(c);
        self.for_keys_of(channel, out, |key| Event::NoteTuning {
            key: Some(key),
            semitones,
        });
        true
    }

    /// `out` = one event per key sounding from `channel`.
    fn for_keys_of(&self, channel: u8, out: &mut Out, event: impl Fn(u8) -> Event) {
        out.clear();
        for (key, &ch) in self.key_channel.iter().enumerate() {
            if ch == channel {
                out.push(event(key as u8));
            }
        }
    }

    /// Channel pressure (`value` 0 .. 1) on `channel`: `false` (and `out`
    /// untouched) when it is the channel's aftertouch for every voice (MPE
    /// off, the manager channel or a channel outside the zone), else `true`
    /// with the pressures of the keys sounding from that member channel in
    /// `out`.
    pub fn pressure(&mut self, channel: u8, value: f64, out: &mut Out) -> bool {
        if !self.is_member(channel) {
            return false;
        }
        self.pressure[channel as usize] = value;
        self.for_keys_of(channel, out, |key| Event::NotePressure {
            key: Some(key),
            value,
        });
        true
    }

    /// MPE's timbre, CC 74 (`value` 0 .. 1) on `channel`: `false` (and
    /// `out` untouched) off the member channels (MPE off, the manager
    /// channel, a channel outside the zone), else `true` with the
    /// brightness of the keys sounding from that member channel in `out`;
    /// a later note-on on the channel starts with it.
    pub fn timbre(&mut self, channel: u8, value: f64, out: &mut Out) -> bool {
        if !self.is_member(channel) {
            return false;
        }
        self.timbre[channel as usize] = value;
        self.for_keys_of(channel, out, |key| Event::NoteBrightness {
            key: Some(key),
            value,
        });
        true
    }

    /// Reset All Controllers (CC 121) on `channel`: its RPN selection is
    /// forgotten (MIDI's recommended practice RP-015); `false` (and `out`
    /// untouched) off the member channels (MPE off, the manager channel, a
    /// channel outside the zone: the reset of every voice's controllers),
    /// else `true` with the member channel's bend and pressure at rest and
    /// the keys sounding from it back at their pitch and without pressure
    /// in `out` (a tuning and a pressure per key).
    pub fn reset_controllers(&mut self, channel: u8, out: &mut Out) -> bool {
        let c = channel as usize & 15;
        self.rpn[c] = (127, 127);
        if !self.is_member(channel) {
            return false;
        }
        self.bend[c] = 0.0;
        self.pressure[c] = 0.0;
        out.clear();
        for (key, &ch) in self.key_channel.iter().enumerate() {
            if ch == channel {
                let key = Some(key as u8);
                out.push(Event::NoteTuning {
                    key,
                    semitones: 0.0,
                });
                out.push(Event::NotePressure { key, value: 0.0 });
            }
        }
        true
    }

    /// A controller (`value` 0 ..= 127): follows RPN selection and data
    /// entry for RPN 6 (the zone) on channel 1 and RPN 0 (bend range) on
    /// member channels. Returns whether it was one of those controllers.
    pub fn controller(&mut self, channel: u8, cc: u8, value: u8) -> bool {
        let c = channel as usize & 15;
        match cc {
            101 => self.rpn[c].0 = value,
            100 => self.rpn[c].1 = value,
            6 => match self.rpn[c] {
                (0, 6) if c == 0 || c == 15 => self.configure(c == 15, value),
                (0, 0) => self.range[c] = f64::from(value),
                _ => return false,
            },
            _ => return false,
        }
        true
    }
}

/// Whether `channel` is a member channel of a lower zone of `lower` and an
/// upper zone of `upper` member channels.
fn member_of(lower: u8, upper: u8, channel: u8) -> bool {
    (lower > 0 && (1..=lower).contains(&channel))
        || (upper > 0 && (15 - upper.min(15)..15).contains(&channel))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn configure(m: &mut Mpe, members: u8) {
        assert!(m.controller(0, 101, 0));
        assert!(m.controller(0, 100, 6));
        assert!(m.controller(0, 6, members));
    }

    fn on(key: u8) -> Event {
        Event::NoteOn {
            key,
            velocity_norm: 0.5,
        }
    }

    fn tune(key: u8, semitones: f64) -> Event {
        Event::NoteTuning {
            key: Some(key),
            semitones,
        }
    }

    fn note_on(m: &mut Mpe, channel: u8, e: Event) -> Vec<Event> {
        let mut out = Out::new();
        m.note_on(channel, e, &mut out);
        out.as_slice().to_vec()
    }

    fn press(m: &mut Mpe, channel: u8, value: f64) -> Option<Vec<Event>> {
        let mut out = Out::new();
        m.pressure(channel, value, &mut out)
            .then(|| out.as_slice().to_vec())
    }

    fn pressed(key: u8, value: f64) -> Event {
        Event::NotePressure {
            key: Some(key),
            value,
        }
    }

    fn configure_upper(m: &mut Mpe, members: u8) {
        assert!(m.controller(15, 101, 0));
        assert!(m.controller(15, 100, 6));
        assert!(m.controller(15, 6, members));
    }

    /// The upper zone (RPN 6 on channel 16) counts its members down from
    /// channel 15; both zones at once; a zone configured over the other's
    /// channels shrinks it; channel 16 stays the wheel.
    #[test]
    fn upper_zone_and_both_zones() {
        let mut m = Mpe::default();
        configure_upper(&mut m, 3);
        assert!(m.enabled());
        // 0-based channels 12, 13, 14 are members; 11 and 15 are not
        note_on(&mut m, 14, on(60));
        note_on(&mut m, 11, on(62));
        assert_eq!(bend(&mut m, 14, 0.25).unwrap(), [tune(60, 12.0)]);
        assert!(bend(&mut m, 11, 0.5).is_none(), "outside the zone");
        assert!(bend(&mut m, 15, 0.5).is_none(), "the manager is the wheel");
        // the lower zone beside it
        configure(&mut m, 5);
        note_on(&mut m, 3, on(64));
        assert_eq!(bend(&mut m, 3, -0.5).unwrap(), [tune(64, -24.0)]);
        assert_eq!(
            bend(&mut m, 14, 0.5).unwrap(),
            [tune(60, 24.0)],
            "the upper zone stays"
        );
        // a lower zone of 13 takes channels 1..=13: the upper zone keeps 1
        configure(&mut m, 13);
        assert!(m.is_member(13) && m.is_member(14));
        assert_eq!(m.upper, 1);
        assert_eq!(
            bend(&mut m, 14, 0.5).unwrap(),
            [tune(60, 24.0)],
            "channel 14 kept its note"
        );
        assert!(
            bend(&mut m, 12, 0.5).unwrap().is_empty(),
            "channel 12 changed zones: afresh"
        );
        configure(&mut m, 0);
        configure_upper(&mut m, 0);
        assert!(!m.enabled());
    }

    /// A member channel's pressure presses its notes (and a later note on
    /// that channel starts pressed); off, on the manager channel or outside
    /// the zone it is the channel's aftertouch.
    #[test]
    fn member_channel_pressure_presses_its_notes_only() {
        let mut m = Mpe::default();
        assert!(press(&mut m, 2, 0.5).is_none(), "off: aftertouch");
        configure(&mut m, 3);
        note_on(&mut m, 2, on(60));
        note_on(&mut m, 3, on(64));
        assert_eq!(press(&mut m, 2, 0.5).unwrap(), [pressed(60, 0.5)]);
        assert!(press(&mut m, 0, 0.5).is_none(), "manager channel");
        assert!(press(&mut m, 9, 0.5).is_none(), "outside the zone");
        assert_eq!(note_on(&mut m, 2, on(67)), [on(67), pressed(67, 0.5)]);
        configure(&mut m, 3);
        assert_eq!(
            note_on(&mut m, 2, on(69)),
            [on(69)],
            "the zone message resets"
        );
    }

    /// Reset All Controllers on a member channel brings its notes back to
    /// their pitch and out of pressure (a tuning and a pressure of 0 per
    /// key, every key of a crowded channel) and a later note on it starts
    /// plain; off, on the manager channel or outside the zone it is the
    /// reset of every voice's controllers. It forgets the channel's RPN
    /// selection either way.
    #[test]
    fn reset_all_controllers_rests_a_member_channel() {
        let reset = |m: &mut Mpe, channel: u8| {
            let mut out = Out::new();
            m.reset_controllers(channel, &mut out)
                .then(|| out.as_slice().to_vec())
        };
        let mut m = Mpe::default();
        assert!(reset(&mut m, 1).is_none(), "off");
        configure(&mut m, 3);
        note_on(&mut m, 2, on(60));
        note_on(&mut m, 3, on(64));
        assert!(press(&mut m, 2, 0.5).is_some());
        let mut out = Out::new();
        assert!(m.pitch_bend(2, 0.25, &mut out));
        let rest = |key: u8| {
            [
                tune(key, 0.0),
                Event::NotePressure {
                    key: Some(key),
                    value: 0.0,
                },
            ]
        };
        assert_eq!(reset(&mut m, 2).unwrap(), rest(60));
        assert_eq!(note_on(&mut m, 2, on(67)), [on(67)], "starts plain");
        assert!(reset(&mut m, 0).is_none(), "manager channel");
        assert!(reset(&mut m, 9).is_none(), "outside the zone");
        // every key of a channel that holds all 128
        for key in 0..128 {
            note_on(&mut m, 3, on(key));
        }
        let all = reset(&mut m, 3).unwrap();
        assert_eq!(all.len(), 256);
        assert_eq!(all[254..], rest(127));
        // the RPN selection is forgotten: a data entry after it is no one's
        assert!(m.controller(0, 101, 0));
        assert!(m.controller(0, 100, 0));
        assert!(reset(&mut m, 0).is_none());
        assert!(!m.controller(0, 6, 12), "no RPN selected");
    }

    fn brighten(m: &mut Mpe, channel: u8, value: f64) -> Option<Vec<Event>> {
        let mut out = Out::new();
        m.timbre(channel, value, &mut out)
            .then(|| out.as_slice().to_vec())
    }

    fn bright(key: u8, value: f64) -> Event {
        Event::NoteBrightness {
            key: Some(key),
            value,
        }
    }

    /// A member channel's timbre (CC 74) sets its notes' brightness, and a
    /// note-on on a channel that has had one starts with it (MPE sends the
    /// timbre before the note); off, on the manager channel or outside the
    /// zone it is no one's.
    #[test]
    fn member_channel_timbre_sets_its_notes_brightness() {
        let mut m = Mpe::default();
        assert!(brighten(&mut m, 2, 0.8).is_none(), "off");
        configure(&mut m, 3);
        assert_eq!(note_on(&mut m, 2, on(60)), [on(60)], "no timbre yet");
        note_on(&mut m, 3, on(64));
        assert_eq!(brighten(&mut m, 2, 0.8).unwrap(), [bright(60, 0.8)]);
        assert!(brighten(&mut m, 0, 0.8).is_none(), "manager channel");
        assert!(brighten(&mut m, 9, 0.8).is_none(), "outside the zone");
        assert_eq!(brighten(&mut m, 3, 0.1).unwrap(), [bright(64, 0.1)]);
        assert_eq!(note_on(&mut m, 3, on(67)), [on(67), bright(67, 0.1)]);
        configure(&mut m, 3);
        assert_eq!(
            note_on(&mut m, 3, on(69)),
            [on(69)],
            "the zone message resets"
        );
    }

    fn bend(m: &mut Mpe, channel: u8, value: f64) -> Option<Vec<Event>> {
        let mut out = Out::new();
        m.pitch_bend(channel, value, &mut out)
            .then(|| out.as_slice().to_vec())
    }

    #[test]
    fn off_until_configured_then_member_bends_retune_their_notes_only() {
        let mut m = Mpe::default();
        assert!(
            bend(&mut m, 1, 0.5).is_none(),
            "off: every bend is the wheel"
        );
        configure(&mut m, 3);
        assert!(m.enabled());
        assert_eq!(note_on(&mut m, 1, on(60)), [on(60)]);
        assert_eq!(note_on(&mut m, 2, on(64)), [on(64)]);
        assert_eq!(bend(&mut m, 1, 0.25).unwrap(), [tune(60, 12.0)]);
        assert!(
            bend(&mut m, 0, 0.5).is_none(),
            "the manager channel is the wheel"
        );
        assert!(
            bend(&mut m, 5, 0.5).is_none(),
            "outside the zone: the wheel"
        );
        // a note-on on a bent channel starts at the channel's pitch
        assert_eq!(note_on(&mut m, 1, on(67)), [on(67), tune(67, 12.0)]);
        // RPN 0 sets a member channel's range; the zone message resets it
        assert!(m.controller(2, 101, 0) && m.controller(2, 100, 0) && m.controller(2, 6, 2));
        assert_eq!(bend(&mut m, 2, -1.0).unwrap(), [tune(64, -2.0)]);
        configure(&mut m, 0);
        assert!(!m.enabled() && bend(&mut m, 1, 1.0).is_none());
        assert!(!m.controller(0, 7, 100), "other controllers are not MPE's");
    }
}
