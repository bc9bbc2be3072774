//! Render the demo THROUGH THE BUILT CLAP PLUGIN (clack-host, offline):
//! a few phrases on four scenes, with chords and repeated notes, and a
//! roll on the two-mallet kit (docs/design.md, "Played as a kit"), into
//! `OUT_DIR/*.wav`; and one strike of each preset that names a real
//! instrument (`real_instrument`) at its root key, velocity 100, into
//! `OUT_DIR/real/NAME.wav`, the key and velocity `cargo xtask
//! compare-real` compares it with its recording at (docs/design.md, "How
//! close to the real instruments"; `cargo xtask demo` writes the
//! recording beside it). Used by `cargo xtask demo`.
//!
//! `render-demo PATH/TO/modal_contact.clap OUT_DIR`

use modal_contact::instrument::root_note;
use modal_contact::plugin::params::ids;
use modal_contact::presets;
use plugin_tests::{param_id, peak, write_wav, HostEvent, LoadedPlugin, RenderSpec};
use std::path::{Path, PathBuf};

const RATE: f64 = 48_000.0;
/// Length of a strike of a preset that names a real instrument \[s\].
const REAL_SECONDS: f64 = 4.0;
/// Its MIDI velocity: the recording's (compare-real's).
const REAL_VELOCITY: f64 = 100.0 / 127.0;

/// (seconds, semitones above the root, velocity 0..1, hold seconds)
type Phrase<'a> = &'a [(f64, i32, f64, f64)];

/// Play `phrase` on preset `name` through the plugin for `seconds` and
/// write it to `path`.
fn render(clap: &Path, name: &str, phrase: Phrase, seconds: f64, path: &Path) {
    let idx = presets::index_of(name).expect("preset");
    let root = root_note(&presets::scene(idx).expect("scene")) as i32;
    let s = |t: f64| (t * RATE) as usize;
    let mut events = vec![HostEvent::Param {
        at: 0,
        id: param_id(ids::SCENE),
        value: idx as f64,
    }];
    for &(t, semis, vel, hold) in phrase {
        let key = (root + semis).clamp(0, 127) as u8;
        events.push(HostEvent::NoteOn {
            at: s(t),
            key,
            velocity: vel,
        });
        events.push(HostEvent::NoteOff {
            at: s(t + hold),
            key,
        });
    }
    let mut spec = RenderSpec::new(RATE, 512, s(seconds), events);
    // let the worker compile the chosen scene before the first note
    spec.settle_after = vec![0];
    spec.settle_ms = 500;
    let out = LoadedPlugin::load(clap).render(&spec);
    assert!(
        out.iter().flatten().all(|v| v.is_finite()),
        "non-finite output"
    );
    write_wav(path, RATE, &out);
    println!(
        "wrote {} (root note {root}, peak {:.3})",
        path.display(),
        peak(&out[0]).max(peak(&out[1]))
    );
}

fn main() {
    let mut args = std::env::args().skip(1);
    let clap = PathBuf::from(args.next().expect("path of the .clap"));
    let out_dir = PathBuf::from(args.next().unwrap_or_else(|| "target/demo".into()));
    std::fs::create_dir_all(&out_dir).expect("mkdir out");
    let demos: [(&str, Phrase); 4] = [
        (
            "marimba-bar",
            &[
                (0.30, 0, 0.7, 0.5),
                (0.55, 3, 0.6, 0.5),
                (0.80, 7, 0.7, 0.5),
                (1.05, 12, 0.8, 0.8),
                // repeated note: the mallet hits the ringing bar again
                (1.60, 7, 0.6, 0.1),
                (1.70, 7, 0.6, 0.1),
                (1.80, 7, 0.9, 0.6),
                // chord
                (2.40, 0, 0.8, 1.5),
                (2.40, 4, 0.7, 1.5),
                (2.40, 7, 0.7, 1.5),
                (2.40, 12, 0.6, 1.5),
            ],
        ),
        (
            "bell",
            &[
                (0.30, 0, 0.6, 3.0),
                (1.30, 7, 0.5, 3.0),
                (2.30, 0, 0.9, 3.0), // repeated on the ringing bell
                (3.30, -5, 0.7, 3.0),
                (3.30, 4, 0.5, 3.0),
            ],
        ),
        (
            // a kit plays at its scene's pitch: one key, the two mallets in
            // turn, a crescendo roll then two accents
            "marimba-two-mallets",
            &[
                (0.30, 0, 0.35, 0.1),
                (0.42, 0, 0.40, 0.1),
                (0.54, 0, 0.45, 0.1),
                (0.66, 0, 0.50, 0.1),
                (0.78, 0, 0.55, 0.1),
                (0.90, 0, 0.60, 0.1),
                (1.02, 0, 0.65, 0.1),
                (1.14, 0, 0.70, 0.1),
                (1.26, 0, 0.75, 0.1),
                (1.38, 0, 0.80, 0.1),
                (2.20, 0, 0.95, 0.1),
                (2.50, 0, 0.95, 0.1),
            ],
        ),
        (
            "paper-bounce",
            &[
                (0.30, 0, 0.3, 3.0),
                (1.60, 0, 0.8, 3.0), // dropped again while it still bounces
                (2.80, 5, 0.5, 3.0),
            ],
        ),
    ];
    for (name, phrase) in demos {
        render(
            &clap,
            name,
            phrase,
            5.0,
            &out_dir.join(format!("{name}.wav")),
        );
    }
    // each preset that names a real instrument: one strike at its root,
    // held (a damped preset rings as its recording does)
    let strike: Phrase = &[(0.2, 0, REAL_VELOCITY, REAL_SECONDS - 0.3)];
    for (i, name) in presets::NAMES.iter().enumerate() {
        let named = presets::scene(i).expect("scene").real_instrument.is_some();
        if named {
            let path = out_dir.join("real").join(format!("{name}.wav"));
            render(&clap, name, strike, REAL_SECONDS, &path);
        }
    }
}
