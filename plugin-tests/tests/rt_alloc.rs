//! The allocation check really covers the plugin's `process`, and a panic in
//! `process` is caught at its boundary.
//!
//! The `rt-checks` bundles are built with debug assertions and nice-plug's
//! `assert_process_allocs`: any allocation inside `process` aborts the host
//! process. A stress render (many note-ons, voice stealing, releases on the
//! damped scene, pressure (note expressions, aftertouch, mod wheel, MPE),
//! brightness (note expressions, MPE timbre: voices moved between hardness
//! levels),
//! parameter swaps including a preset change with its fade-out,
//! a switching change and a strike-position change, and bad input: all 128
//! keys at velocity 127 in one block at 64 voices, then a note on every
//! sample for 256 samples, stealing voices mid-contact; notes ended at once by
//! All Notes Off, Reset All Controllers, All Sound Off and a lowered
//! Polyphony) runs in a child process
//! (this test binary re-executed with `MODAL_CONTACT_CHILD_BUNDLE` set), so an
//! abort is observed rather than killing the test run. In the `rt-checks`
//! build note 2 at velocity 0.123 (test-only `alloc-bug` trigger) allocates in `process` on purpose: the child must die; the
//! clean build must not. In the `panic-bug` build (no allocation checker:
//! the unwinder's own (de)allocations would trip it) note 1 panics inside
//! `process`: the child must live, the block is silenced, a line is logged,
//! and the notes after it play.

use modal_contact::plugin::params::ids;
use modal_contact::presets;
use plugin_tests::*;
use std::path::Path;
use std::process::{Command, Output};

const CHILD_ENV: &str = "MODAL_CONTACT_CHILD_BUNDLE";
const SCRIPT_ENV: &str = "MODAL_CONTACT_CHILD_SCRIPT";

/// Renders the stress script; returns (output, the same notes without the
/// parameter changes).
fn stress(bundle: &Path, fault_note: Option<u8>) -> ([Vec<f32>; 2], [Vec<f32>; 2], usize) {
    let rate = 44_100.0;
    let total = (rate * 3.0) as usize;
    let notes = stress_notes();
    let first_change = 30_000;
    let mut events = notes.clone();
    // the largest polyphony for the bad-input chords (CLAP value: the step)
    events.push(param(9_000, ids::POLYPHONY, 63.0));
    if let Some(key) = fault_note {
        events.push(HostEvent::NoteOn {
            at: 25_000,
            key,
            velocity: 0.123,
        });
    }
    push_bends_and_mpe(&mut events);
    push_brightness_and_modulation(&mut events);
    push_pressure(&mut events);
    push_notes_ended_at_once(&mut events);
    events.push(param(first_change, ids::HARDNESS, 0.6));
    events.push(param(first_change, ids::DECAY, 0.4));
    events.push(param(45_000, ids::STRIKE_CUSTOM, 1.0));
    events.push(param(45_000, ids::STRIKE_POS, 0.8));
    events.push(param(60_000, ids::SWITCHING, 0.0));
    events.push(param(75_000, ids::DAMPER, 1.0));
    events.push(param(
        90_000,
        ids::SCENE,
        presets::index_of("paper-string").unwrap() as f64,
    ));
    events.push(param(
        105_000,
        ids::SCENE,
        presets::index_of("steel-plate").unwrap() as f64,
    ));
    let mut spec = RenderSpec::new(rate, 256, total, events);
    spec.settle_after = vec![first_change, 45_000, 60_000, 75_000, 90_000, 105_000];
    spec.settle_ms = 300;
    let with = LoadedPlugin::load(bundle).render(&spec);
    let without = LoadedPlugin::load(bundle).render(&RenderSpec::new(rate, 256, total, notes));
    (with, without, first_change)
}

/// A raw MIDI message at sample `at`.
fn midi(at: usize, data: [u8; 3]) -> HostEvent {
    HostEvent::Midi { at, data }
}

/// The script's notes: 48 notes (a third released), then bad input (all
/// 128 keys at once, a note on every sample for a block) and repeated
/// notes on one key.
fn stress_notes() -> Vec<HostEvent> {
    let mut notes = Vec::new();
    for i in 0..48usize {
        let at = 50 + i * 1500;
        let key = 40 + (i * 7 % 36) as u8;
        notes.push(HostEvent::NoteOn {
            at,
            key,
            velocity: 0.1 + 0.018 * i as f64,
        });
        if i % 3 == 0 {
            notes.push(HostEvent::NoteOff { at: at + 700, key });
        }
    }
    // bad input: all 128 keys at velocity 127 in one block, then a note on
    // every sample for a block, stealing voices in the middle of their
    // contacts
    for key in 0..128u8 {
        notes.push(HostEvent::NoteOn {
            at: 10_000,
            key,
            velocity: 1.0,
        });
    }
    for i in 0..256usize {
        notes.push(HostEvent::NoteOn {
            at: 12_000 + i,
            key: (i * 37 % 128) as u8,
            velocity: 1.0,
        });
    }
    // repeated notes on one key
    for i in 0..10usize {
        notes.push(HostEvent::NoteOn {
            at: 20_000 + 211 * i,
            key: 57,
            velocity: 0.7,
        });
    }
    notes
}

/// The pitch-bend wheel over the repeated notes; an MPE zone with notes,
/// bends, pressure and timbre on every member channel.
fn push_bends_and_mpe(events: &mut Vec<HostEvent>) {
    // the pitch-bend wheel over the repeated notes: full up, full down
    // within a glide, back to the centre
    events.push(plugin_tests::pitch_bend(20_100, 16383));
    events.push(plugin_tests::pitch_bend(20_500, 0));
    events.push(plugin_tests::pitch_bend(23_000, 8192));
    // MPE: the zone's configuration message, then notes on every member
    // channel (two per channel) and a bend on each, which retunes every
    // note of its channel; then the zone is turned off again
    events.extend([
        midi(24_000, [0xB0, 101, 0]),
        midi(24_000, [0xB0, 100, 6]),
        midi(24_000, [0xB0, 6, 15]),
    ]);
    for ch in 1..16u8 {
        let at = 24_010 + 10 * ch as usize;
        events.push(midi(at, [0x90 | ch, 30 + ch, 100]));
        events.push(midi(at, [0x90 | ch, 80 + ch, 90]));
        events.push(midi(24_300, [0xE0 | ch, 0, (ch * 8) & 0x7f]));
        // and its pressure, pressing every note of the channel, and its
        // timbre, moving them to another hardness level
        events.push(midi(24_400, [0xD0 | ch, 8 * ch, 0]));
        events.push(midi(24_450, [0xB0 | ch, 74, (ch * 9) & 0x7f]));
    }
}

/// Brightness per note, and CLAP polyphonic modulation of every modulated
/// parameter.
fn push_brightness_and_modulation(events: &mut Vec<HostEvent>) {
    // brightness: per note (CLAP note expressions), at the onset (a new
    // level for the strike), during contacts and while ringing, NaN-free
    // extremes
    for (k, key) in [57u8, 60, 64, 67].into_iter().enumerate() {
        events.push(plugin_tests::note_brightness(20_000 + 100 * k, key, 1.0));
        events.push(plugin_tests::note_brightness(20_003 + 100 * k, key, 0.0));
        events.push(plugin_tests::note_brightness(22_800 + 100 * k, key, 0.6));
    }
    // CLAP polyphonic modulation: notes with ids, every modulated
    // parameter at the onset, during the contact and after the release,
    // beyond the ranges, and an id that is not sounding; the first
    // modulation of position and damper makes the worker compile their
    // levels, installed by a swap while the checker watches
    for (k, key) in [40u8, 44, 47].into_iter().enumerate() {
        let id = 500 + k as u32;
        let at = 26_000 + 50 * k;
        events.push(plugin_tests::on_id(at, key, 0.9, id));
        events.push(poly_mod(at, id, PolyTarget::Hardness, 0.3));
        events.push(poly_mod(at, id, PolyTarget::StrikePosition, -1.0));
        events.push(poly_mod(at + 2, id, PolyTarget::Damper, 1.0));
        events.push(poly_mod(at + 2, id, PolyTarget::Hardness, -1.0));
        events.push(plugin_tests::off(at + 2_000, key));
        events.push(poly_mod(at + 2_500, id, PolyTarget::Damper, -1.0));
    }
    events.push(poly_mod(26_100, 12_345, PolyTarget::StrikePosition, 0.5));
    for target in [
        PolyTarget::Hardness,
        PolyTarget::StrikePosition,
        PolyTarget::Damper,
    ] {
        events.push(poly_mod(26_200, 501, target, f64::NAN));
        events.push(poly_mod(26_210, 502, target, f64::INFINITY));
    }
}

/// Pressure per note, channel aftertouch and the mod wheel; the MPE zone
/// turned off.
fn push_pressure(events: &mut Vec<HostEvent>) {
    // pressure: per note (CLAP note expressions, polyphonic aftertouch),
    // channel aftertouch and the mod wheel, up and back to 0
    for (k, key) in [60u8, 64, 67].into_iter().enumerate() {
        events.push(plugin_tests::note_pressure(21_000 + 100 * k, key, 0.9));
        events.push(midi(21_500 + 100 * k, [0xA0, key, 127]));
    }
    events.extend([
        midi(22_000, [0xD0, 100, 0]),
        midi(22_400, [0xB0, 1, 127]),
        midi(23_500, [0xD0, 0, 0]),
        midi(23_600, [0xB0, 1, 0]),
    ]);
    events.push(midi(24_600, [0xB0, 6, 0]));
}

/// Notes ended at once by the channel-mode messages and by a lower
/// polyphony.
fn push_notes_ended_at_once(events: &mut Vec<HostEvent>) {
    // notes ended at once: All Notes Off under the sustain pedal, Reset
    // All Controllers (the pedal up, the wheel back), All Sound Off fading
    // every voice, then 24 notes and the Polyphony lowered to 4 under them
    // (the 20 quietest end: 16 fade, the rest are cut), and All Sound Off
    // again while those fade
    events.extend([
        midi(27_000, [0xB0, 64, 127]),
        midi(27_100, [0xB0, 123, 0]),
        plugin_tests::pitch_bend(27_150, 12_000),
        midi(27_200, [0xB1, 121, 0]),
        midi(27_300, [0xB0, 120, 0]),
    ]);
    for i in 0..24usize {
        events.push(HostEvent::NoteOn {
            at: 27_400 + 10 * i,
            key: 40 + i as u8,
            velocity: 0.3 + 0.02 * i as f64,
        });
    }
    events.push(param(28_000, ids::POLYPHONY, 3.0));
    events.push(midi(28_100, [0xB0, 120, 0]));
}

/// The panic script: a note, note 1 (panics in the `panic-bug` build) in the
/// block starting at 19_968, a note after it. Returns a summary line.
fn panic_script(bundle: &Path) -> String {
    let (rate, block, total) = (44_100.0, 256, 44_100);
    let (panic_at, after) = (20_000, 30_000);
    let clean = vec![
        HostEvent::NoteOn {
            at: 100,
            key: 57,
            velocity: 0.8,
        },
        HostEvent::NoteOn {
            at: after,
            key: 60,
            velocity: 0.8,
        },
    ];
    let mut with = clean.clone();
    with.push(HostEvent::NoteOn {
        at: panic_at,
        key: 1,
        velocity: 0.5,
    });
    let out = LoadedPlugin::load(bundle).render(&RenderSpec::new(rate, block, total, with));
    let reference = LoadedPlugin::load(bundle).render(&RenderSpec::new(rate, block, total, clean));
    let block_start = panic_at / block * block;
    let finite = out.iter().flatten().all(|v| v.is_finite());
    let same_before = out[0][..block_start] == reference[0][..block_start];
    let silent = out[0][block_start..after]
        .iter()
        .chain(&out[1][block_start..after])
        .all(|&v| v == 0.0);
    let later = rms(&out[0][after..]);
    let sounding_before = rms(&reference[0][block_start..after]);
    write_wav(&out_dir().join("panic-caught.wav"), rate, &out);
    format!(
        "CHILD_PANIC_OK finite={finite} same_before={same_before} silent_after_panic={silent} \
         rms_before_panic={sounding_before:.3e} rms_of_the_next_note={later:.3e}"
    )
}

/// A user scene of `n` modes (200 Hz .. 15 kHz), large enough that the
/// compiler stores its changes of basis in hierarchical form.
fn large_scene(n: usize) -> String {
    let mut t = String::from(
        "version = 1\nname = \"large\"\nduration_s = 1.0\n\n[[object]]\nname = \"bar\"\n\
         kind = \"modal\"\npoints = [\"contact\", \"pickup\"]\n",
    );
    for i in 0..n {
        let f = 200.0 * (75.0f64).powf(i as f64 / (n - 1) as f64);
        let w = 1.0 / (1.0 + 0.02 * i as f64).sqrt();
        let wp = if i % 2 == 0 { 0.8 * w } else { -0.6 * w };
        t += &format!(
            "\n[[object.mode]]\nfreq_hz = {f}\nt60_s = {}\nweights = [{w}, {wp}]\n",
            2.5 / (1.0 + f / 1500.0)
        );
    }
    t + "\n[hammer]\nmass_kg = 0.03\nheight_m = 0.001\nvelocity_m_per_s = -1.0\n\n\
         [contact]\nobject = \"bar\"\npoint = \"contact\"\nstiffness_n_per_m = 2e6\n\
         damping_n_s_per_m = 20.0\n\n[[pickup]]\nobject = \"bar\"\npoint = \"pickup\"\n\
         quantity = \"velocity\"\ngain = 0.5\n"
}

/// The large scene as a user scene: repeated notes and chords on ringing
/// voices, so strikes switch through the hierarchical changes of basis.
fn large_script(bundle: &Path) -> String {
    let text = large_scene(150);
    let path = out_dir().join("rt-checks-large.toml");
    std::fs::write(&path, &text).unwrap();
    let mut p = LoadedPlugin::load(bundle);
    let fresh = p.save_state();
    p.load_state(&with_user_scene(&fresh, "large", &text, &path));
    let mut events = Vec::new();
    for i in 0..24usize {
        for k in 0..(1 + i % 4) {
            events.push(on(100 + 1000 * i, 57 + 3 * k as u8, 0.5 + 0.02 * i as f64));
        }
    }
    let out = p.render(&RenderSpec::new(48_000.0, 64, 28_000, events));
    let finite = out.iter().flatten().all(|v| v.is_finite());
    write_wav(&out_dir().join("rt-checks-large.wav"), 48_000.0, &out);
    format!(
        "CHILD_LARGE_OK finite={finite} peak={:.4} rms_late={:.3e}",
        peak(&out[0]),
        rms(&out[0][20_000..])
    )
}

/// Scenes of several contacts as user scenes, each played as a kit
/// (docs/design.md, "Played as a kit"): a roll on one key, notes on
/// every sample, every key at velocity 127 in one block, the bend, the
/// pressure, note-offs and pedals (a released kit voice goes on the
/// scene's damped compile: the two mallets once more with a damper), and a
/// Hardness change whose swap fades the ringing kit out. Returns a
/// summary line.
fn kit_script(bundle: &Path) -> String {
    let rate = 48_000.0;
    let mut lines = Vec::new();
    let two = include_str!("../../presets/marimba-two-mallets.toml");
    let damped = two.replace("\ndamper = 0.0", "\ndamper = 0.5");
    assert_ne!(damped, two, "the preset says its damper");
    for (name, text) in [
        ("two-mallets", two),
        ("two-mallets-damped", damped.as_str()),
        (
            "ball",
            include_str!("../../presets/ball-between-plates.toml"),
        ),
        ("chimes", include_str!("../../presets/wind-chimes.toml")),
        ("snare", include_str!("../../presets/snare-pair.toml")),
    ] {
        let path = out_dir().join(format!("rt-checks-kit-{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let mut p = LoadedPlugin::load(bundle);
        let fresh = p.save_state();
        p.load_state(&with_user_scene(&fresh, name, text, &path));
        let mut events = Vec::new();
        for i in 0..16usize {
            events.push(on(100 + 1500 * i, 60, 0.4 + 0.03 * i as f64));
        }
        for key in 0..128u8 {
            events.push(on(26_000, key, 1.0));
        }
        for i in 0..256usize {
            events.push(on(28_000 + i, (i * 37 % 128) as u8, 1.0));
        }
        let midi = |at: usize, data: [u8; 3]| HostEvent::Midi { at, data };
        events.extend([
            plugin_tests::pitch_bend(30_000, 16383),
            midi(30_100, [0xD0, 100, 0]),
            midi(30_200, [0xB0, 64, 127]),
            plugin_tests::off(30_300, 60),
            midi(30_400, [0xB0, 64, 0]),
            plugin_tests::note_brightness(30_500, 60, 1.0),
            param(34_000, ids::HARDNESS, 0.7),
        ]);
        // kit voices ended at once: the Polyphony lowered under the roll's
        // and the chords' voices, then the channel mode messages
        events.extend([
            param(29_000, ids::POLYPHONY, 1.0),
            midi(31_000, [0xB0, 123, 0]),
            midi(31_100, [0xB0, 121, 0]),
            on(31_200, 60, 0.8),
            on(31_210, 67, 0.8),
            midi(31_300, [0xB0, 120, 0]),
        ]);
        events.push(on(40_000, 62, 0.8));
        let mut spec = RenderSpec::new(rate, 64, 48_000, events);
        spec.settle_after = vec![34_000];
        spec.settle_ms = 500;
        let out = p.render(&spec);
        let finite = out.iter().flatten().all(|v| v.is_finite());
        let bounded = out
            .iter()
            .flatten()
            .all(|v| f64::from(v.abs()) <= modal_contact::instrument::OUTPUT_CEILING);
        write_wav(
            &out_dir().join(format!("rt-checks-kit-{name}.wav")),
            rate,
            &out,
        );
        lines.push(format!(
            "{name}: finite={finite} bounded={bounded} rms_roll={:.3e} rms_after_swap={:.3e}",
            rms(&out[0][..24_000]),
            rms(&out[0][40_000..])
        ));
    }
    format!("CHILD_KIT_OK {}", lines.join("; "))
}

/// Does nothing unless spawned by `run_child`.
#[test]
fn child_render() {
    let Ok(bundle) = std::env::var(CHILD_ENV) else {
        return;
    };
    let bundle = Path::new(&bundle);
    match std::env::var(SCRIPT_ENV).as_deref() {
        Ok("panic") => println!("{}", panic_script(bundle)),
        Ok("large") => println!("{}", large_script(bundle)),
        Ok("kit") => println!("{}", kit_script(bundle)),
        script => {
            let fault = (script == Ok("alloc")).then_some(2);
            let (with, without, change) = stress(bundle, fault);
            let finite = with.iter().flatten().all(|v| v.is_finite());
            let bounded = with
                .iter()
                .chain(&without)
                .flatten()
                .all(|v| f64::from(v.abs()) <= modal_contact::instrument::OUTPUT_CEILING);
            let swapped = with[0][change..] != without[0][change..];
            write_wav(&out_dir().join("rt-checks-stress.wav"), 44_100.0, &with);
            println!(
                "CHILD_RENDER_OK finite={finite} bounded={bounded} swapped={swapped} peak={:.4}",
                peak(&with[0])
            );
        }
    }
}

fn run_child(bundle: &Path, script: &str) -> Output {
    Command::new(std::env::current_exe().expect("test exe"))
        .args(["--exact", "child_render", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, bundle)
        .env(SCRIPT_ENV, script)
        .output()
        .expect("spawn child test process")
}

#[test]
fn rt_checks_build_runs_the_stress_render_without_allocating() {
    let out = run_child(&clap_bundle(Variant::RtChecks), "stress");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stdout
        .lines()
        .find(|l| l.contains("CHILD_RENDER_OK"))
        .unwrap_or_else(|| panic!("child failed: {:?}\n{stdout}\n{stderr}", out.status));
    println!("{line}");
    assert!(out.status.success(), "{:?}\n{stderr}", out.status);
    assert!(line.contains("finite=true"), "{line}");
    assert!(line.contains("bounded=true"), "{line}");
    assert!(line.contains("swapped=true"), "{line}");
}

/// Strikes on ringing voices of a 150-mode user scene switch through the
/// structured changes of basis (the library compiles the same text with
/// both in hierarchical form) without allocating in the checked build.
#[test]
fn rt_checks_build_switches_a_large_scene_without_allocating() {
    let scene = modal_contact::scene::Scene::from_toml_str(&large_scene(150)).expect("valid scene");
    let sc = modal_contact::compile::compile_one(&scene, 48_000.0).unwrap();
    assert!(sc.w_cf_h.is_some() && sc.w_fc_h.is_some(), "{}", sc.summary);
    let out = run_child(&clap_bundle(Variant::RtChecks), "large");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stdout
        .lines()
        .find(|l| l.contains("CHILD_LARGE_OK"))
        .unwrap_or_else(|| panic!("child failed: {:?}\n{stdout}\n{stderr}", out.status));
    println!("{line}");
    assert!(out.status.success(), "{:?}\n{stderr}", out.status);
    assert!(line.contains("finite=true"), "{line}");
    let peak: f64 = line
        .split("peak=")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(peak > 1e-3, "the large scene sounds: {line}");
}

/// Scenes of several contacts play as kits in the checked build without
/// allocating: strikes that open contacts, every key at once, a swap.
#[test]
fn rt_checks_build_plays_kits_without_allocating() {
    let out = run_child(&clap_bundle(Variant::RtChecks), "kit");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stdout
        .lines()
        .find(|l| l.contains("CHILD_KIT_OK"))
        .unwrap_or_else(|| panic!("child failed: {:?}\n{stdout}\n{stderr}", out.status));
    println!("{line}");
    assert!(out.status.success(), "{:?}\n{stderr}", out.status);
    assert!(!line.contains("=false"), "{line}");
    for part in line.trim_start_matches("CHILD_KIT_OK ").split("; ") {
        let num = |key: &str| -> f64 {
            let v = part.split(key).nth(1).expect(key);
            v.split_whitespace().next().unwrap().parse().expect(key)
        };
        assert!(num("rms_roll=") > 1e-4, "the roll sounds: {part}");
        assert!(num("rms_after_swap=") > 1e-5, "the new kit plays: {part}");
    }
}

#[test]
fn allocation_in_process_aborts_the_checked_build() {
    let out = run_child(&clap_bundle(Variant::AllocBug), "alloc");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        !out.status.success(),
        "child should die; stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(
            out.status.signal(),
            Some(6),
            "expected SIGABRT, got {:?}",
            out.status
        );
    }
    assert!(!stdout.contains("CHILD_RENDER_OK"));
    assert!(
        stderr.contains("memory allocation of"),
        "missing the allocation-check message; stderr:\n{stderr}"
    );
    println!(
        "alloc-bug build, note 2 (allocates): aborted as expected: {:?}; {}",
        out.status,
        stderr
            .lines()
            .find(|l| l.contains("memory allocation of"))
            .unwrap_or("")
    );
}

#[test]
fn a_panic_in_process_is_caught_silenced_and_logged() {
    let out = run_child(&clap_bundle(Variant::PanicBug), "panic");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stdout
        .lines()
        .find(|l| l.contains("CHILD_PANIC_OK"))
        .unwrap_or_else(|| panic!("child failed: {:?}\n{stdout}\n{stderr}", out.status));
    println!("{line}");
    let logged = stderr
        .lines()
        .find(|l| l.contains("caught a panic"))
        .unwrap_or_else(|| panic!("no log line; stderr:\n{stderr}"));
    println!("log: {logged}");
    assert!(out.status.success(), "{:?}\n{stderr}", out.status);
    assert!(
        logged.contains("panic-bug: deliberate panic on note 1"),
        "{logged}"
    );
    for want in ["finite=true", "same_before=true", "silent_after_panic=true"] {
        assert!(line.contains(want), "{want}: {line}");
    }
    let num = |key: &str| -> f64 {
        let v = line.split(key).nth(1).expect(key);
        v.split_whitespace().next().unwrap().parse().expect(key)
    };
    // sounding: the presets play at -45 LUFS (docs/levels.md)
    assert!(num("rms_before_panic=") > 1e-4, "{line}");
    assert!(num("rms_of_the_next_note=") > 1e-4, "{line}");
}
