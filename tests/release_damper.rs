//! The damper follows the instrument (docs/plugin.md, "Velocity, pitch,
//! voices"): a scene's `[play] damper` says how strongly a released note
//! is damped, the presets without dampers (marimba, bells, chimes, drums)
//! ring on after a staccato release, the damped ones (piano string,
//! vibraphone, tubular chime) are damped as before and held by the sustain
//! pedal, a user scene's value is honoured, and Custom damper puts the
//! Damper parameter in its place.

use modal_contact::instrument::{
    prepare, prepare_scene, Event, Instrument, InstrumentParams, SceneParams, TimedEvent,
    VariantSet,
};
use modal_contact::presets;
use modal_contact::scene::{Scene, DEFAULT_RELEASE_DAMPER};

const RATE: f64 = 44_100.0;
/// A staccato touch: the key is up 50 ms after it went down.
const STACCATO: usize = 2_205;

fn on(offset: usize, key: u8) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteOn {
            key,
            velocity_norm: 0.8,
        },
    }
}

fn off(offset: usize, key: u8) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteOff { key },
    }
}

fn sustain(offset: usize, down: bool) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::Sustain { down },
    }
}

fn params(preset: &str) -> SceneParams {
    SceneParams {
        preset: presets::index_of(preset).unwrap(),
        ..SceneParams::default()
    }
}

/// The preset with the Damper parameter at `damper` (Custom damper on).
fn custom(preset: &str, damper: f64) -> SceneParams {
    SceneParams {
        damper_norm: damper,
        damper_custom: true,
        ..params(preset)
    }
}

/// The left channel of `n` samples of `events` on `sp`.
fn play(sp: &SceneParams, events: &[TimedEvent], n: usize) -> Vec<f32> {
    play_prepared(prepare(sp, RATE, 0).unwrap(), events, n)
}

fn play_prepared(
    p: Box<modal_contact::instrument::Prepared>,
    events: &[TimedEvent],
    n: usize,
) -> Vec<f32> {
    let mut inst = Instrument::new(p, InstrumentParams::default().play);
    let mut l = vec![0.0; n];
    let mut r = vec![0.0; n];
    inst.process(events, &mut l, &mut r);
    l
}

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

/// The root key of a preset.
fn root(preset: &str) -> u8 {
    prepare(&params(preset), RATE, 0).unwrap().root_note.round() as u8
}

/// Level of a note released after 50 ms against the same note held, in the
/// 100 ms from 1 s after the note: (released, held) RMS.
fn staccato_against_held(sp: &SceneParams, key: u8) -> (f64, f64) {
    let n = (1.1 * RATE) as usize;
    let window = RATE as usize..n;
    let released = play(sp, &[on(0, key), off(STACCATO, key)], n);
    let held = play(sp, &[on(0, key)], n);
    (rms(&released[window.clone()]), rms(&held[window]))
}

fn db(x: f64) -> f64 {
    20.0 * x.log10()
}

/// Every preset's damper, as its `[play]` table says (the choices are
/// explained in the preset files): no damper on bars, bells, plates,
/// drums, kits, driven scenes and the scenes made from recordings; the piano string, the paper string, the vibraphone
/// and the tubular chime are damped on release, as every scene was
/// before scenes said it.
const DAMPERS: [(&str, f64); 24] = [
    ("bell", 0.0),
    ("glockenspiel-bar", 0.0),
    ("marimba-bar", 0.0),
    ("paper-bounce", 0.0),
    ("paper-string", 0.5),
    ("steel-plate", 0.0),
    ("wood-block", 0.0),
    ("vibraphone-bar", 0.5),
    ("tubular-chime", 0.5),
    ("frame-drum", 0.0),
    ("piano-string", 0.5),
    ("marimba-rubber-mallet", 0.0),
    ("marimba-two-mallets", 0.0),
    ("ball-between-plates", 0.0),
    ("wind-chimes", 0.0),
    ("snare-pair", 0.0),
    ("guiro", 0.0),
    ("ball-on-plate", 0.0),
    ("marble-on-board", 0.0),
    ("glockenspiel-recorded", 0.0),
    ("marimba-recorded", 0.0),
    ("timpani-recorded", 0.0),
    ("guiro-recorded", 0.0),
    ("snare-brush", 0.0),
];

#[test]
fn every_preset_says_its_damper_and_plays_it() {
    assert_eq!(DAMPERS.len(), presets::COUNT);
    for (name, want) in DAMPERS {
        let i = presets::index_of(name).unwrap();
        let scene = presets::scene(i).unwrap();
        assert!(scene.play.is_some(), "{name}: no [play] table");
        assert_eq!(scene.release_damper(), want, "{name}");
        let p = prepare(&params(name), RATE, 0).unwrap();
        // what the prepared scene says it plays (polyphonic damper
        // modulation is taken around it)
        assert!(!p.params.damper_custom);
        assert_eq!(p.params.damper_norm, want, "{name}");
        if !presets::is_kit(i) {
            assert_eq!(
                p.scenes.damped.is_some(),
                want > 0.0,
                "{name}: damped scene"
            );
        }
        // with Custom damper on, the parameter's damper plays
        let q = prepare(&custom(name, 0.8), RATE, 0).unwrap();
        assert_eq!(q.params.damper_norm, 0.8, "{name}");
    }
}

/// A staccato touch must not silence a bar that has no damper: 1 s after
/// the note the released note is the held note (the same samples), where
/// the Damper of 0.5 every preset once had leaves it 100 dB and more
/// below (or silent: the voice stops at -90 dB).
#[test]
fn undamped_presets_ring_on_after_a_staccato_release() {
    for name in [
        "marimba-bar",
        "glockenspiel-bar",
        "bell",
        "steel-plate",
        "frame-drum",
        "marimba-rubber-mallet",
    ] {
        let key = root(name);
        let (released, held) = staccato_against_held(&params(name), key);
        let (before, _) = staccato_against_held(&custom(name, DEFAULT_RELEASE_DAMPER), key);
        println!(
            "{name}: 1 s after a 50 ms note: released {:.1} dB, held {:.1} dB; \
             with the old Damper 0.5 {:.1} dB",
            db(released),
            db(held),
            db(before)
        );
        // -100 dB at the preset's own output level (`level_db`)
        let level = presets::scene(presets::index_of(name).unwrap())
            .unwrap()
            .level_db;
        assert!(
            held > 1e-5 * 10f64.powf(level / 20.0),
            "{name}: the held note is silent at 1 s"
        );
        assert!(
            (released - held).abs() <= 1e-3 * held,
            "{name}: released {released:e}, held {held:e}"
        );
        assert!(before < 1e-3 * held, "{name}: the old damper did not damp");
    }
}

/// The damped presets are damped on release as before: the same samples
/// as the Damper parameter at 0.5, and far below the held note 1 s on.
#[test]
fn damped_presets_are_damped_on_release_as_before() {
    for name in [
        "piano-string",
        "vibraphone-bar",
        "tubular-chime",
        "paper-string",
    ] {
        let key = root(name);
        let (released, held) = staccato_against_held(&params(name), key);
        println!(
            "{name}: 1 s after a 50 ms note: released {:.1} dB, held {:.1} dB",
            db(released),
            db(held)
        );
        assert!(held > 1e-5, "{name}");
        assert!(released < 1e-2 * held, "{name}: {released:e} vs {held:e}");
        let n = (0.5 * RATE) as usize;
        let ev = [on(0, key), off(STACCATO, key)];
        assert!(
            play(&params(name), &ev, n) == play(&custom(name, 0.5), &ev, n),
            "{name}: not the release of Damper 0.5"
        );
    }
}

/// The sustain pedal holds a damped preset's released note undamped (bit
/// for bit the note never released) until it comes up, and then damps it
/// as a note-off at that instant would; under an undamped preset the pedal
/// changes nothing.
#[test]
fn the_sustain_pedal_holds_a_damped_presets_note() {
    let n = 30_000;
    let (release, up) = (4_000, 16_000);
    for name in ["vibraphone-bar", "piano-string"] {
        let sp = params(name);
        let key = root(name);
        let held = play(&sp, &[sustain(0, true), on(10, key), off(release, key)], n);
        let never = play(&sp, &[on(10, key)], n);
        assert!(held == never, "{name}: released under the pedal");
        let lifted = play(
            &sp,
            &[
                sustain(0, true),
                on(10, key),
                off(release, key),
                sustain(up, false),
            ],
            n,
        );
        let released_then = play(&sp, &[on(10, key), off(up, key)], n);
        assert!(lifted == released_then, "{name}: pedal up is the note-off");
        let (tail, ringing) = (rms(&lifted[n - 4000..]), rms(&never[n - 4000..]));
        println!(
            "{name}: after the pedal, {:.1} dB below the held note",
            db(ringing / tail)
        );
        assert!(tail < 0.05 * ringing, "{name}: {tail:e} vs {ringing:e}");
    }
    let sp = params("marimba-bar");
    let pedalled = play(
        &sp,
        &[
            sustain(0, true),
            on(10, 57),
            off(release, 57),
            sustain(up, false),
        ],
        n,
    );
    assert!(
        pedalled == play(&sp, &[on(10, 57)], n),
        "marimba: nothing to hold"
    );
}

/// A user scene's `[play] damper` is the damper its notes are released
/// with (and absent, 0.5, as before scenes said it); Custom damper puts the
/// parameter's in its place.
#[test]
fn a_user_scenes_damper_is_honoured() {
    let text = presets::PRESETS[presets::index_of("marimba-bar").unwrap()].toml;
    let (head, _) = text.split_once("[play]").unwrap();
    let scene = |damper: Option<f64>| {
        let extra = damper.map_or(String::new(), |d| format!("[play]\ndamper = {d:?}\n"));
        Scene::from_toml_str(&format!("{head}{extra}")).unwrap()
    };
    let n = 20_000;
    let ev = [on(0, 57), off(STACCATO, 57)];
    let run = |s: &Scene, sp: &SceneParams| {
        let p = prepare_scene(s, sp, RATE, 0).unwrap();
        let d = p.params.damper_norm;
        (d, play_prepared(p, &ev, n))
    };
    let sp = SceneParams::default();
    let mut tails = Vec::new();
    for (d, want) in [
        (None, 0.5),
        (Some(0.0), 0.0),
        (Some(0.25), 0.25),
        (Some(1.0), 1.0),
    ] {
        let (played, out) = run(&scene(d), &sp);
        assert_eq!(played, want, "{d:?}");
        // the same samples as the parameter at that damper
        let (_, by_param) = run(&scene(None), &custom("marimba-bar", want));
        assert!(out == by_param, "{d:?}: not the release of Damper {want}");
        tails.push(rms(&out[STACCATO + 2_000..STACCATO + 6_000]));
    }
    println!("release tails, scene dampers absent, 0, 0.25, 1: {tails:?}");
    assert!(
        tails[1] > tails[2] && tails[2] > tails[0] && tails[0] > tails[3],
        "{tails:?}"
    );
    // Custom damper: the scene's 1.0 gives way to the parameter's 0
    let (played, out) = run(&scene(Some(1.0)), &custom("marimba-bar", 0.0));
    assert_eq!(played, 0.0);
    assert!(out == run(&scene(Some(0.0)), &sp).1);
}

/// Polyphonic modulation of Damper is taken around the damper that plays:
/// on the marimba (no damper) a note's offset of +0.25 releases it at
/// 0.25, as the parameter at 0.25 would; -0.25 leaves it ringing.
#[test]
fn damper_levels_are_around_the_scenes_damper() {
    let sp = SceneParams {
        variants: VariantSet {
            position: false,
            damper: true,
        },
        ..params("marimba-bar")
    };
    let n = 12_000;
    let with = |by: f64| {
        play(
            &sp,
            &[
                on(10, 57),
                TimedEvent {
                    offset: 10,
                    event: Event::NoteDamper {
                        key: Some(57),
                        offset: by,
                    },
                },
                off(3_000, 57),
            ],
            n,
        )
    };
    let plain = [on(10, 57), off(3_000, 57)];
    assert!(with(0.25) == play(&custom("marimba-bar", 0.25), &plain, n));
    assert!(with(-0.25) == play(&sp, &plain, n), "below 0: rings on");
    assert!(with(-0.25) == play(&sp, &[on(10, 57)], n));
}
