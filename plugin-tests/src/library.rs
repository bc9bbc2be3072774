//! The same notes through the instrument library, no plugin: a render of
//! host events as the plugin would hear them, for sample-by-sample
//! comparison.

use crate::HostEvent;
use modal_contact::instrument::{
    prepare, Event, Instrument, InstrumentParams, TimedEvent as LibEvent,
};

/// Render `events` (notes and the pedals' controllers) with the instrument library directly,
/// at the plugin's parameter defaults `params`. Velocities are rounded to f32
/// as nice-plug does. Returns `[left, right]`.
pub fn library_render(
    params: &InstrumentParams,
    rate_hz: f64,
    total: usize,
    events: &[HostEvent],
) -> [Vec<f32>; 2] {
    let prepared = prepare(&params.scene, rate_hz, 0).expect("compile");
    library_render_prepared(prepared, params, total, events)
}

/// [`library_render`] of an already prepared scene (a user's scene file,
/// `modal_contact::instrument::prepare_scene`).
pub fn library_render_prepared(
    prepared: Box<modal_contact::instrument::Prepared>,
    params: &InstrumentParams,
    total: usize,
    events: &[HostEvent],
) -> [Vec<f32>; 2] {
    let mut inst = Instrument::new(prepared, params.play);
    let mut sorted: Vec<LibEvent> = events
        .iter()
        .filter_map(|e| library_event(e, events, params))
        .collect();
    sorted.sort_by_key(|e| e.offset);
    let mut l = vec![0.0; total];
    let mut r = vec![0.0; total];
    inst.process(&sorted, &mut l, &mut r);
    [l, r]
}

/// The instrument library's event for the host event `e` of `events`, as
/// the plugin turns it into one (`None`: the plugin hears it otherwise, or
/// not at all).
fn library_event(
    e: &HostEvent,
    events: &[HostEvent],
    params: &InstrumentParams,
) -> Option<LibEvent> {
    match *e {
        HostEvent::NoteOn { at, key, velocity } => Some(LibEvent {
            offset: at,
            event: Event::NoteOn {
                key,
                velocity_norm: velocity as f32 as f64,
            },
        }),
        HostEvent::NoteOff { at, key } => Some(LibEvent {
            offset: at,
            event: Event::NoteOff { key },
        }),
        HostEvent::Midi { at, data } => library_midi_event(at, data),
        HostEvent::Tuning { at, key, semitones } => Some(LibEvent {
            offset: at,
            event: Event::NoteTuning {
                key: Some(key),
                semitones,
            },
        }),
        HostEvent::Pressure { at, key, value } => Some(LibEvent {
            offset: at,
            event: Event::NotePressure {
                key: Some(key),
                value: f64::from(value as f32),
            },
        }),
        HostEvent::Brightness { at, key, value } => Some(LibEvent {
            offset: at,
            event: Event::NoteBrightness {
                key: Some(key),
                value: f64::from(value as f32),
            },
        }),
        HostEvent::NoteOnId {
            at, key, velocity, ..
        } => Some(LibEvent {
            offset: at,
            event: Event::NoteOn {
                key,
                velocity_norm: velocity as f32 as f64,
            },
        }),
        HostEvent::PolyMod {
            at,
            id,
            target,
            amount,
        } => {
            // the key of the note id (the last note-on with it before)
            let key = events.iter().rev().find_map(|e| match *e {
                HostEvent::NoteOnId {
                    at: a, key, id: i, ..
                } if i == id && a <= at => Some(key),
                _ => None,
            })?;
            Some(LibEvent {
                offset: at,
                event: target.event(&params.scene, key, amount),
            })
        }
        HostEvent::Param { .. } => None,
    }
}

/// The instrument library's event for the MIDI message `data` at sample
/// `at`, as the plugin turns it into one (`None`: the plugin hears it
/// otherwise, or not at all).
fn library_midi_event(at: usize, data: [u8; 3]) -> Option<LibEvent> {
    match data {
        [0xB0, c @ (64 | 66), v] => Some(LibEvent {
            offset: at,
            event: if c == 64 {
                Event::Sustain { down: v >= 64 }
            } else {
                Event::Sostenuto { down: v >= 64 }
            },
        }),
        [0xE0, lsb, msb] => {
            // the 14-bit wheel, centre 8192 (the plugin's own mapping)
            let m = f64::from(u16::from(lsb & 0x7f) | (u16::from(msb & 0x7f) << 7)) - 8192.0;
            Some(LibEvent {
                offset: at,
                event: Event::PitchBend {
                    value: if m >= 0.0 { m / 8191.0 } else { m / 8192.0 },
                },
            })
        }
        // the mod wheel and channel aftertouch as nice-plug gives them
        // (value / 127 in f32)
        [0xB0, 1, v] => Some(LibEvent {
            offset: at,
            event: Event::ModWheel {
                value: f64::from(f32::from(v) / 127.0),
            },
        }),
        [0xD0, v, _] => Some(LibEvent {
            offset: at,
            event: Event::ChannelPressure {
                value: f64::from(f32::from(v) / 127.0),
            },
        }),
        _ => None,
    }
}
