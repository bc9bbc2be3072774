//! Render notes with the instrument library directly (no plugin) to a raw
//! file, the reference the VST3 test compares pedalboard's render with.
//!
//! `render-reference --rate HZ --samples N --out FILE [--preset NAME]
//!  [--gain-db DB] EVENT...` where EVENT is `on:SAMPLE:KEY:VELOCITY127` or
//! `off:SAMPLE:KEY`. Output: f32 little-endian, all left samples then all
//! right samples. Velocities are converted like a host does (`vel / 127` as
//! f32). Other parameters are the plugin's defaults.

use modal_contact::instrument::InstrumentParams;
use modal_contact::presets;
use plugin_tests::{library_render, HostEvent};
use std::io::Write;

fn main() {
    let mut args = std::env::args().skip(1);
    let mut rate = 44_100.0;
    let mut samples = 0usize;
    let mut out = None;
    let mut params = InstrumentParams::default();
    let mut events = Vec::new();
    while let Some(a) = args.next() {
        let mut val = || args.next().unwrap_or_else(|| panic!("{a} needs a value"));
        match a.as_str() {
            "--rate" => rate = val().parse().expect("--rate"),
            "--samples" => samples = val().parse().expect("--samples"),
            "--out" => out = Some(val()),
            "--gain-db" => params.play.gain_db = val().parse().expect("--gain-db"),
            // the Damper knob applies (Custom damper on) instead of the
            // scene's own damper
            "--damper-custom" => params.scene.damper_custom = true,
            "--preset" => {
                let name = val();
                params.scene.preset =
                    presets::index_of(&name).unwrap_or_else(|| panic!("no preset {name}"));
            }
            ev => {
                let f: Vec<&str> = ev.split(':').collect();
                let num = |i: usize| -> usize { f[i].parse().expect("event field") };
                match f[0] {
                    "on" if f.len() == 4 => events.push(HostEvent::NoteOn {
                        at: num(1),
                        key: num(2) as u8,
                        velocity: (num(3) as f32 / 127.0) as f64,
                    }),
                    "off" if f.len() == 3 => events.push(HostEvent::NoteOff {
                        at: num(1),
                        key: num(2) as u8,
                    }),
                    _ => panic!("bad argument {ev}"),
                }
            }
        }
    }
    let out = out.expect("--out FILE");
    let [l, r] = library_render(&params, rate, samples, &events);
    let mut w = std::io::BufWriter::new(std::fs::File::create(&out).expect("create output"));
    for x in l.iter().chain(&r) {
        w.write_all(&x.to_le_bytes()).expect("write");
    }
    w.flush().expect("flush");
}
