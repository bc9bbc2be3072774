//! Drives the BUILT `.clap` bundles through clack-host: descriptor,
//! parameters, note timing at 44.1 and 96 kHz, velocity, equality with the
//! instrument library, a parameter swap in the middle of a render, and state.
//! Renders go to `target/plugin-tests/wav/`.

use modal_contact::instrument::{InstrumentParams, VariantSet};
use modal_contact::plugin::params::ids;
use modal_contact::presets;
use plugin_tests::*;

/// A phrase on the default scene (marimba bar, root A3 = 57): a chord, a
/// repeated note while it rings, a release, more notes than voices.
fn phrase(rate: f64) -> Vec<HostEvent> {
    let s = |t: f64| (t * rate) as usize;
    let mut ev = vec![
        on(s(0.010) + 3, 57, 0.8),
        on(s(0.010) + 3, 61, 0.6),
        on(s(0.010) + 3, 64, 0.7),
        on(s(0.300), 57, 0.9), // repeated: strikes the ringing bar again
        on(s(0.301), 57, 0.4),
        off(s(0.600), 61),
        off(s(0.700), 57),
    ];
    for i in 0..20u8 {
        ev.push(on(
            s(0.8) + 977 * i as usize,
            45 + 2 * i,
            0.2 + 0.04 * i as f64,
        ));
    }
    ev.push(off(s(1.5), 47));
    ev
}

#[test]
fn descriptor_is_an_instrument() {
    let d = descriptors(&clap_bundle(Variant::Release));
    assert_eq!(d.len(), 1);
    assert_eq!(d[0].id, PLUGIN_ID);
    assert_eq!(d[0].name, "Modal Contact");
    assert_eq!(d[0].vendor, "Modal Contact");
    assert!(
        !d[0].url.contains("example.invalid"),
        "no placeholder address: {:?}",
        d[0].url
    );
    for f in ["instrument", "synthesizer", "stereo"] {
        assert!(d[0].features.iter().any(|x| x == f), "{:?}", d[0].features);
    }
}

#[test]
fn every_parameter_is_exposed_under_its_stable_id() {
    let mut p = LoadedPlugin::load(&clap_bundle(Variant::Release));
    let infos = p.param_infos();
    println!("{} parameters: {infos:?}", infos.len());
    assert_eq!(infos.len(), ids::ALL.len());
    for id in ids::ALL {
        assert!(
            infos.iter().any(|(h, _)| *h == param_id(id)),
            "{id} missing: {infos:?}"
        );
    }
    // defaults: marimba bar, pitch tracking on, exact switching requested
    let marimba = presets::index_of("marimba-bar").unwrap() as f64;
    let expect = [
        (ids::SCENE, marimba),
        (ids::PITCH_TRACKING, 1.0),
        (ids::SWITCHING, 1.0),
        (ids::STRIKE_CUSTOM, 0.0),
    ];
    for (id, v) in expect {
        let got = p.param_value(param_id(id));
        assert!((got - v).abs() < 1e-6, "{id}: {got} != {v}");
    }
}

fn check_note_timing(variant: Variant, rate: f64, block: usize) {
    let mut p = LoadedPlugin::load(&clap_bundle(variant));
    let at = 2 * block + 137; // inside the third block, not on a boundary
    let total = (rate * 3.0) as usize;
    let spec = RenderSpec::new(rate, block, total, vec![on(at, 57, 0.8)]);
    let out = p.render(&spec);
    write_wav(
        &out_dir().join(format!("timing-{}-{}.wav", variant.name(), rate as u32)),
        rate,
        &out,
    );
    let [l, r] = &out;
    assert_eq!(l.len(), total);
    assert!(
        l.iter().chain(r).all(|v| v.is_finite()),
        "non-finite output"
    );
    assert!(
        l[..at].iter().chain(&r[..at]).all(|&v| v == 0.0),
        "sound before the note"
    );
    let first = first_above(l, 0.0).expect("sound");
    println!(
        "{} @ {rate} Hz: note at {at}, first non-zero sample {first}, peak {:.3}",
        variant.name(),
        peak(l)
    );
    assert!(first > at && first <= at + 3, "first sound at {first}");
    assert!(rms(&l[at..at + rate as usize]) > 1e-3);
}

#[test]
fn notes_start_at_their_sample_44k1() {
    check_note_timing(Variant::Release, 44_100.0, 512);
}

#[test]
fn notes_start_at_their_sample_96k() {
    check_note_timing(Variant::Release, 96_000.0, 1024);
}

#[test]
fn louder_velocity_is_louder() {
    let bundle = clap_bundle(Variant::Release);
    let level = |velocity| {
        let mut p = LoadedPlugin::load(&bundle);
        let spec = RenderSpec::new(44_100.0, 256, 44_100, vec![on(100, 57, velocity)]);
        let [l, _] = p.render(&spec);
        (rms(&l), peak(&l))
    };
    let levels: Vec<(f64, f64)> = [0.2, 0.5, 0.8, 1.0].into_iter().map(level).collect();
    println!("velocity 0.2/0.5/0.8/1.0 -> (rms, peak) {levels:?}");
    for w in levels.windows(2) {
        assert!(w[1].0 > w[0].0 * 1.2, "{levels:?}");
    }
}

fn check_equals_library(variant: Variant, rate: f64, block: usize) {
    let bundle = clap_bundle(variant);
    let mut p = LoadedPlugin::load(&bundle);
    let events = phrase(rate);
    let total = (rate * 3.0) as usize;
    let plugin = p.render(&RenderSpec::new(rate, block, total, events.clone()));
    let lib = library_render(&InstrumentParams::default(), rate, total, &events);
    write_wav(
        &out_dir().join(format!("phrase-{}-{}.wav", variant.name(), rate as u32)),
        rate,
        &plugin,
    );
    let d = max_abs_diff(&plugin[0], &lib[0]).max(max_abs_diff(&plugin[1], &lib[1]));
    println!(
        "{} @ {rate} Hz, block {block}: peak {:.4}, max |plugin - library| = {d:.3e}",
        variant.name(),
        peak(&plugin[0])
    );
    assert!(plugin[0].iter().chain(&plugin[1]).all(|v| v.is_finite()));
    assert!(peak(&plugin[0]) > 0.05);
    assert!(d <= 1e-6, "plugin and library differ by {d}");
}

#[test]
fn output_equals_the_instrument_library_44k1() {
    check_equals_library(Variant::Release, 44_100.0, 512);
}

#[test]
fn output_equals_the_instrument_library_96k_odd_blocks() {
    check_equals_library(Variant::Release, 96_000.0, 333);
}

/// The rt-checks build (allocation in process aborts) plays the same phrase
/// with the same result.
#[test]
fn rt_checks_build_equals_the_library() {
    check_equals_library(Variant::RtChecks, 44_100.0, 128);
}

/// The Lookahead parameter (docs/plugin.md, "Lookahead") through a real
/// host: 10 ms at 48 kHz is a latency of 480 samples the plugin reports,
/// and the phrase sounds as the library plays it, 480 samples later,
/// after 480 samples of silence. Set by a host's parameter event while the
/// plugin plays: it keeps its latency until the host restarts it, and
/// tells the host the new one from `activate` (CLAP's rule).
fn check_lookahead(variant: Variant) {
    let rate = 48_000.0;
    let block = 64;
    let mut p = LoadedPlugin::load(&clap_bundle(variant));
    let mut s = p.activate(rate, 1, block);
    assert_eq!(s.plugin().latency(), 0, "no latency by default");
    s.render(0, 4096, block, &[param(0, ids::LOOKAHEAD, 10.0)]);
    let before_restart = s.plugin().latency();
    let restarts = s.honour_restarts(4);
    // (the activation's first scene may come after it: docs/plugin.md,
    // "Parameter changes: the swap design"; time for the worker, not a
    // timing assertion)
    std::thread::sleep(std::time::Duration::from_millis(500));
    s.render(0, block, block, &[]);
    let events = phrase(rate);
    let total = (rate * 2.0) as usize;
    let late = s.render(0, total + 480, block, &events);
    let (latency, told) = (s.plugin().latency(), s.plugin().latency_changes());
    let violations = s.plugin().latency_violations();
    s.deactivate();
    assert_eq!(violations, 0, "latency changed outside activate");
    assert_eq!(before_restart, 0, "the latency changed before a restart");
    assert!(restarts >= 1, "the plugin asked for no restart");
    assert_eq!(latency, 480, "the new lookahead is the latency");
    assert!(told >= 1, "the host was not told of the new latency");
    let lib = library_render(&InstrumentParams::default(), rate, total, &events);
    assert!(late[0][..480]
        .iter()
        .chain(&late[1][..480])
        .all(|x| *x == 0.0));
    let d = max_abs_diff(&late[0][480..], &lib[0]).max(max_abs_diff(&late[1][480..], &lib[1]));
    println!(
        "{}: lookahead 10 ms = latency {latency} samples after {restarts} restart(s); peak {:.3}; \
         max |plugin(t + 480) - library(t)| = {d:.3e}",
        variant.name(),
        peak(&lib[0])
    );
    assert!(peak(&lib[0]) > 0.05);
    assert!(d <= 1e-6, "plugin and library differ by {d}");
}

#[test]
fn lookahead_is_a_reported_latency_and_changes_nothing_else() {
    check_lookahead(Variant::Release);
}

/// The same through the rt-checks build: the lookahead's lanes, clocks and
/// latency report allocate nothing on the audio thread.
#[test]
fn lookahead_under_rt_checks() {
    check_lookahead(Variant::RtChecks);
}

/// What a host's main thread does between two chunks of audio: honour a
/// restart the plugin asked for (deactivate, run its callbacks, activate),
/// else run its callbacks. Returns the restarts made (0 or 1).
fn host_step(s: &mut Session) -> u32 {
    if s.restart_pending() {
        s.deactivated(|p| p.run_callbacks());
        1
    } else {
        s.plugin().run_callbacks();
        0
    }
}

/// Frames `start..start + total` of `events`, processed on an audio thread
/// `chunk` blocks at a time, with a [`host_step`] after each chunk.
/// Returns the output and the restarts made.
fn play(
    s: &mut Session,
    start: usize,
    total: usize,
    block: usize,
    chunk: usize,
    events: &[HostEvent],
) -> ([Vec<f32>; 2], u32) {
    let mut out = [Vec::with_capacity(total), Vec::with_capacity(total)];
    let mut restarts = 0;
    let mut pos = start;
    while pos < start + total {
        let len = (block * chunk).min(start + total - pos);
        let part = s.on_audio_thread(|a| a.render(pos, len, block, events));
        out[0].extend_from_slice(&part[0]);
        out[1].extend_from_slice(&part[1]);
        restarts += host_step(s);
        pos += len;
    }
    (out, restarts)
}

/// Silence on the audio thread until a chunk passes with no restart made
/// or asked for (at most 8 chunks). Returns the restarts made.
fn settle(s: &mut Session, block: usize) -> u32 {
    let mut restarts = 0;
    for _ in 0..8 {
        let (out, r) = play(s, 0, 4 * block, block, 4, &[]);
        assert!(out[0].iter().chain(&out[1]).all(|x| *x == 0.0));
        restarts += r;
        if r == 0 && !s.restart_pending() {
            return restarts;
        }
    }
    panic!("the plugin still asks for restarts after 8 chunks");
}

/// The lookahead's latency through a host that follows CLAP's latency
/// rule (docs/plugin.md, "Lookahead"): `clap_host_latency::changed` only
/// inside `clap_plugin::activate` (the test host counts every other call
/// as a violation), a new latency asked for with `request_restart`. Audio
/// runs on its own thread, the host's main thread works between chunks:
/// it restarts the plugin when asked and runs its callbacks. A Lookahead
/// of 10 ms comes as a parameter event in `process`; later one of 15 ms in
/// the last block before the host stops, and while stopped the host
/// flushes 20 ms. After each, the plugin reports the new latency (480,
/// then 960 samples) and plays the phrase that much later, to within
/// 1e-6 of the library; until a restart it keeps the old one. The host
/// renders offline (CLAP `render` extension), so each activation's first
/// scene is in place before its first block whatever the worker's speed
/// (docs/plugin.md, "Parameter changes: the swap design"); the restart is
/// asked for in `process` as in real time.
fn check_latency_protocol(variant: Variant) {
    let rate = 48_000.0;
    let block = 256;
    let total = (rate * 2.0) as usize;
    let events = phrase(rate);
    let lib = library_render(&InstrumentParams::default(), rate, total, &events);
    let mut p = LoadedPlugin::load(&clap_bundle(variant));
    assert!(p.set_render_mode(true), "the offline mode was refused");
    let mut s = p.activate(rate, 1, block);
    assert_eq!(s.plugin().latency(), 0, "no latency by default");
    let mut restarts = settle(&mut s, block);
    // a parameter event in the second block of a chunk
    let change = [param(block + 77, ids::LOOKAHEAD, 10.0)];
    s.on_audio_thread(|a| a.render(0, 4 * block, block, &change));
    let asked = s.plugin().restarts_requested();
    let kept = s.plugin().latency();
    restarts += host_step(&mut s) + settle(&mut s, block);
    let first = s.plugin().latency();
    let (late, during) = play(&mut s, 0, total + 960, block, 32, &events);
    // the event just before the host stops, then a flush while stopped
    let change = [param(3 * block + 5, ids::LOOKAHEAD, 15.0)];
    s.on_audio_thread(|a| a.render(0, 4 * block, block, &change));
    s.deactivated(|p| {
        p.run_callbacks();
        p.flush_params(&[(param_id(ids::LOOKAHEAD), 20.0)]);
        p.run_callbacks();
    });
    restarts += settle(&mut s, block);
    let second = s.plugin().latency();
    let (later, during_2) = play(&mut s, 0, total + 960, block, 32, &events);
    let violations = s.plugin().latency_violations();
    let told = s.plugin().latency_changes();
    let requested = s.plugin().restarts_requested();
    s.deactivate();
    println!(
        "{}: {violations} latency change(s) outside activate, {told} inside or out; \
         {requested} restart(s) asked for, {restarts} made; latency {kept} until the restart, \
         then {first}, then {second}",
        variant.name()
    );
    assert_eq!(
        violations, 0,
        "clap_host_latency::changed outside clap_plugin::activate"
    );
    assert!(
        asked >= 1,
        "no restart asked for after the Lookahead changed"
    );
    assert_eq!(
        kept, 0,
        "the latency changed before the host restarted the plugin"
    );
    assert_eq!(first, 480, "10 ms at 48 kHz");
    assert_eq!(second, 960, "the flushed 20 ms");
    assert!(
        told >= 2,
        "the host was told of {told} latency change(s), not 2"
    );
    assert_eq!(
        (during, during_2),
        (0, 0),
        "restarts asked for while the phrase played"
    );
    for (out, delay) in [(&late, 480), (&later, 960)] {
        assert!(out[0][..delay]
            .iter()
            .chain(&out[1][..delay])
            .all(|x| *x == 0.0));
        let d = max_abs_diff(&out[0][delay..delay + total], &lib[0])
            .max(max_abs_diff(&out[1][delay..delay + total], &lib[1]));
        println!("  delay {delay}: max |plugin(t + {delay}) - library(t)| = {d:.3e}");
        assert!(
            d <= 1e-6,
            "delayed by {delay}: plugin and library differ by {d}"
        );
    }
}

#[test]
fn latency_changes_only_inside_activate() {
    check_latency_protocol(Variant::Release);
}

/// The same through the rt-checks build (a restart asked for from
/// `process` allocates nothing).
#[test]
fn latency_changes_only_inside_activate_under_rt_checks() {
    check_latency_protocol(Variant::RtChecks);
}

/// A decay and hardness change mid-render through the `variant` bundle:
/// nothing changes before it, the recompiled scene is swapped in within
/// 0.3 s without a jump, and its shorter decay is heard.
fn check_param_swap(variant: Variant) {
    let rate = 44_100.0;
    let total = (rate * 2.5) as usize;
    let notes = vec![on(100, 57, 0.9), on(130, 64, 0.7), on(5000, 69, 0.8)];
    let change = 22_050 + 77;
    // Decay scale 1 -> 0.18 x and hardness up: the worker recompiles, the
    // audio thread swaps at a block boundary and rebinds the ringing voices.
    let mut changed = notes.clone();
    changed.push(param(change, ids::DECAY, 0.3));
    changed.push(param(change, ids::HARDNESS, 0.5));
    let mut spec = RenderSpec::new(rate, 256, total, changed);
    spec.settle_after = vec![change];
    spec.settle_ms = 300;
    let bundle = clap_bundle(variant);
    let mut p = LoadedPlugin::load(&bundle);
    let with = p.render(&spec);
    let decay_now = p.param_value(param_id(ids::DECAY));
    assert!((decay_now - 0.3).abs() < 1e-6, "{decay_now}");
    let mut q = LoadedPlugin::load(&bundle);
    let without = q.render(&RenderSpec::new(rate, 256, total, notes));
    write_wav(
        &out_dir().join(format!("param-swap-{}.wav", variant.name())),
        rate,
        &with,
    );
    let l = &with[0];
    assert!(l.iter().chain(&with[1]).all(|v| v.is_finite()));
    assert_eq!(
        &l[..change],
        &without[0][..change],
        "nothing changes before the event"
    );
    let swap = (change..total)
        .find(|&k| l[k] != without[0][k])
        .expect("the new scene was never swapped in");
    let own = max_step(&l[change - 4410..change]);
    let at_swap = max_step(&l[swap - 1..swap + 256]);
    let late = |x: &[f32]| rms(&x[swap + 11_025..swap + 22_050]);
    println!(
        "{}: param change at {change}, swapped in at {swap} (+{} samples); \
         max step around the swap {at_swap:.3e} vs the signal's own {own:.3e}; \
         late rms {:.3e} (unchanged render {:.3e})",
        variant.name(),
        swap - change,
        late(l),
        late(&without[0])
    );
    assert!(
        swap < change + (0.3 * rate) as usize,
        "swap too late to test"
    );
    assert!(at_swap <= own, "jump at the swap: {at_swap} > {own}");
    assert!(late(l) < 0.2 * late(&without[0]), "shorter decay not heard");
}

#[test]
fn parameter_change_mid_render_swaps_without_a_jump() {
    check_param_swap(Variant::Release);
}

#[test]
fn parameter_change_mid_render_under_rt_checks() {
    check_param_swap(Variant::RtChecks);
}

#[test]
fn saved_state_restores_every_parameter() {
    let bundle = clap_bundle(Variant::Release);
    let mut a = LoadedPlugin::load(&bundle);
    // Non-default values for all 13, set through process() as automation.
    let values = [
        (ids::SCENE, presets::index_of("bell").unwrap() as f64),
        (ids::HAMMER_MASS, 0.7),
        (ids::HARDNESS, 0.2),
        (ids::CONTACT_DAMPING, 0.4),
        (ids::STRIKE_CUSTOM, 1.0),
        (ids::STRIKE_POS, 0.25),
        (ids::DECAY, 0.6),
        (ids::DAMPER, 0.9),
        (ids::PITCH_TRACKING, 0.0),
        (ids::GRAVITY, 0.3),
        (ids::DROP_HEIGHT, 0.7),
        (ids::GAIN, 0.8),
        (ids::SWITCHING, 0.0),
    ];
    let events: Vec<HostEvent> = values
        .iter()
        .enumerate()
        .map(|(i, (id, v))| param(i, id, *v))
        .collect();
    a.render(&RenderSpec::new(48_000.0, 64, 64, events));
    let before: Vec<f64> = ids::ALL
        .iter()
        .map(|id| a.param_value(param_id(id)))
        .collect();
    for ((id, v), got) in values.iter().zip(&before) {
        assert!((got - v).abs() < 1e-6, "{id}: set {v}, reads {got}");
    }
    let state = a.save_state();
    println!("state: {} bytes", state.len());

    let mut b = LoadedPlugin::load(&bundle);
    assert_ne!(b.param_value(param_id(ids::SCENE)), before[0]);
    b.load_state(&state);
    let after: Vec<f64> = ids::ALL
        .iter()
        .map(|id| b.param_value(param_id(id)))
        .collect();
    assert_eq!(before, after, "restored parameters differ");

    // and the restored instance sounds like the original one
    let notes = vec![on(10, 69, 0.8), off(2000, 69), on(3000, 72, 0.5)];
    let ra = a.render(&RenderSpec::new(44_100.0, 512, 22_050, notes.clone()));
    let rb = b.render(&RenderSpec::new(44_100.0, 512, 22_050, notes));
    assert!(peak(&ra[0]) > 1e-4);
    assert_eq!(ra, rb);
}

/// `played` through the plugin (release build, default parameters,
/// 256-sample blocks) against the library driven with `meant`, the events
/// `played` should become: prints and bounds the largest difference, and
/// returns the plugin's render.
fn plugin_equals_library(
    what: &str,
    rate: f64,
    total: usize,
    played: Vec<HostEvent>,
    meant: &[HostEvent],
) -> [Vec<f32>; 2] {
    let mut p = LoadedPlugin::load(&clap_bundle(Variant::Release));
    let plugin = p.render(&RenderSpec::new(rate, 256, total, played));
    let lib = library_render(&InstrumentParams::default(), rate, total, meant);
    let d = max_abs_diff(&plugin[0], &lib[0]).max(max_abs_diff(&plugin[1], &lib[1]));
    println!("{what}: max |plugin - library| = {d:.3e}");
    assert!(
        peak(&lib[0]) > 1e-3,
        "{what}: the library's render is silent"
    );
    assert!(d <= 1e-6, "{what}: plugin and library differ by {d}");
    plugin
}

/// The pitch-bend wheel through a real host: MIDI pitch bends reach the
/// instrument at their sample offsets, so the plugin's render equals the
/// library's with the same bends, and a bent note differs from the
/// unbent one.
#[test]
fn pitch_bend_through_the_host_matches_the_library() {
    let rate = 48_000.0;
    let total = 24_000;
    let events = vec![
        on(100, 60, 0.8),
        plugin_tests::pitch_bend(2_000, 16383),
        plugin_tests::pitch_bend(9_000, 0),
        on(9_500, 64, 0.7),
        plugin_tests::pitch_bend(15_000, 8192),
    ];
    let plugin = plugin_equals_library("pitch bend", rate, total, events.clone(), &events);
    let plain_events = vec![on(100, 60, 0.8), on(9_500, 64, 0.7)];
    let plain = library_render(&InstrumentParams::default(), rate, total, &plain_events);
    let moved = max_abs_diff(&plugin[0][3_000..9_000], &plain[0][3_000..9_000]);
    println!("bent against unbent: max difference {moved:.3e}");
    assert!(
        moved > 1e-3 * peak(&plain[0]),
        "the bend did nothing: {moved}"
    );
}

/// Per-note tuning through a real host: CLAP "tuning" note expressions
/// reach the voice of their key at their sample offsets (one at the onset
/// starts the note at its tuned pitch, a later one glides that note only),
/// so the plugin's render equals the library's with the same expressions;
/// note 60 tuned +7 at its onset sounds like note 67.
#[test]
fn note_tuning_expressions_through_the_host_match_the_library() {
    let rate = 48_000.0;
    let total = 24_000;
    let events = vec![
        on(100, 60, 0.8),
        plugin_tests::note_tuning(100, 60, 7.0),
        on(3_000, 64, 0.7),
        plugin_tests::note_tuning(6_000, 64, -0.5),
        plugin_tests::note_tuning(12_000, 60, 0.25),
    ];
    let plugin = plugin_equals_library("note tuning", rate, total, events.clone(), &events);
    let fifth = library_render(
        &InstrumentParams::default(),
        rate,
        2_900,
        &[on(100, 67, 0.8)],
    );
    let d5 = max_abs_diff(&plugin[0][..2_900], &fifth[0]);
    println!("note 60 tuned +7 at its onset vs note 67: max diff {d5:.3e}");
    assert!(peak(&fifth[0]) > 0.01 && d5 <= 1e-6, "{d5}");
    let untuned = library_render(
        &InstrumentParams::default(),
        rate,
        total,
        &[on(100, 60, 0.8), on(3_000, 64, 0.7)],
    );
    let moved = max_abs_diff(&plugin[0][7_000..12_000], &untuned[0][7_000..12_000]);
    assert!(
        moved > 1e-3 * peak(&untuned[0]),
        "the tuning did nothing: {moved}"
    );
}

/// MPE over MIDI 1.0 through a real host: after the MPE Configuration
/// Message (RPN 6 on channel 1), a member channel's pitch bend retunes the
/// notes of that channel only (48 semitones at full bend), a note-on on an
/// already bent channel starts at that pitch, and channel 1 stays the
/// wheel: the plugin's render equals the library's with the per-note
/// tunings and wheel bends those messages mean. Without the configuration
/// message, a bend on channel 2 is the wheel.
#[test]
fn mpe_member_channel_bends_tune_their_notes_through_the_host() {
    let rate = 48_000.0;
    let total = 24_000;
    let midi = |at: usize, data: [u8; 3]| HostEvent::Midi { at, data };
    let bend14 = |m: i32| {
        let v = (m + 8192) as u16;
        [(v & 0x7f) as u8, (v >> 7) as u8]
    };
    // the plugin's own mapping: 14 bits -> -1 .. 1 -> 48 semitones
    let semis = |m: i32| {
        let m = f64::from(m);
        (if m >= 0.0 { m / 8191.0 } else { m / 8192.0 }) * 48.0
    };
    let (b2, b3) = (bend14(1024), bend14(-2048));
    let events = vec![
        midi(0, [0xB0, 101, 0]),
        midi(0, [0xB0, 100, 6]),
        midi(0, [0xB0, 6, 15]),
        midi(50, [0xE1, b2[0], b2[1]]),
        midi(100, [0x91, 60, 100]),
        midi(3_000, [0x92, 64, 90]),
        midi(6_000, [0xE2, b3[0], b3[1]]),
        plugin_tests::pitch_bend(12_000, 16383),
    ];
    let expected = vec![
        on(100, 60, 100.0 / 127.0),
        plugin_tests::note_tuning(100, 60, semis(1024)),
        on(3_000, 64, 90.0 / 127.0),
        plugin_tests::note_tuning(6_000, 64, semis(-2048)),
        plugin_tests::pitch_bend(12_000, 16383),
    ];
    let what = format!(
        "MPE: {:+.3} and {:+.3} semitones on channels 2 and 3",
        semis(1024),
        semis(-2048)
    );
    plugin_equals_library(&what, rate, total, events, &expected);

    // no configuration message: channel 2's bend is the wheel (2 semitones)
    let events = vec![
        midi(100, [0x91, 60, 100]),
        midi(6_000, [0xE1, b2[0], b2[1]]),
    ];
    let v = 1024.0 / 8191.0;
    let wheel_bend = (8192.0 + v * 8191.0) as u16;
    let expected = vec![
        on(100, 60, 100.0 / 127.0),
        plugin_tests::pitch_bend(6_000, wheel_bend),
    ];
    plugin_equals_library(
        "without MPE, channel 2's bend as the wheel",
        rate,
        total,
        events,
        &expected,
    );
}

/// The pedals through a real host: MIDI controllers 64 (sustain) and 66
/// (sostenuto) reach the instrument at their sample offsets, so the
/// plugin's render equals the library's with the same pedal events, and a
/// note released under the sustain pedal rings on (its tail is louder than
/// the same note released without the pedal).
/// The plugin's render of `events` in 256-sample blocks after its Damper
/// is set to Custom (parameter changes at sample 0, then 400 ms for the
/// worker to swap the scene in).
fn render_with_custom_damper(
    bundle: &std::path::Path,
    rate: f64,
    total: usize,
    events: &[HostEvent],
) -> [Vec<f32>; 2] {
    let mut spec = RenderSpec::new(
        rate,
        256,
        total,
        [param(0, ids::DAMPER_CUSTOM, 1.0)]
            .into_iter()
            .chain(events.iter().copied())
            .collect(),
    );
    spec.settle_after = vec![0];
    spec.settle_ms = 400;
    LoadedPlugin::load(bundle).render(&spec)
}

#[test]
fn pedals_through_the_host_match_the_library() {
    let bundle = clap_bundle(Variant::Release);
    let rate = 48_000.0;
    let total = 48_000;
    // the bar damped on release (the Damper parameter's 0.5; the preset
    // has no damper of its own), so that the pedals have something to hold:
    // Custom damper on at sample 0, the notes from the third block on,
    // after its compile
    let t0 = 512;
    let events = vec![
        on(t0 + 100, 60, 0.8),
        cc(t0 + 200, 66, 127),
        cc(t0 + 300, 64, 100),
        on(t0 + 400, 64, 0.7),
        off(t0 + 6_000, 60),
        off(t0 + 6_000, 64),
        cc(t0 + 20_000, 64, 0),
        cc(t0 + 30_000, 66, 10),
    ];
    let render_damped =
        |events: &[HostEvent]| render_with_custom_damper(&bundle, rate, total, events);
    let plugin = render_damped(&events);
    let mut params = InstrumentParams::default();
    params.scene.damper_custom = true;
    let lib = library_render(&params, rate, total, &events);
    let d = max_abs_diff(&plugin[0], &lib[0]).max(max_abs_diff(&plugin[1], &lib[1]));
    println!("pedals: max |plugin - library| = {d:.3e}");
    assert!(d <= 1e-6, "plugin and library differ by {d}");
    let no_pedal: Vec<_> = events
        .iter()
        .copied()
        .filter(|e| !matches!(e, plugin_tests::HostEvent::Midi { .. }))
        .collect();
    let plain = render_damped(&no_pedal);
    let tail = t0 + 10_000..t0 + 19_000;
    let (held, damped) = (rms(&plugin[0][tail.clone()]), rms(&plain[0][tail]));
    println!("tail rms with the pedals {held:.3e}, without {damped:.3e}");
    assert!(
        held > 1.5 * damped,
        "the pedal did not hold: {held} vs {damped}"
    );
}

/// Brightness through a real host: a CLAP "brightness" note expression at
/// one note's onset and, after the MPE configuration message, a member
/// channel's timbre (CC 74) before its note and during another: the
/// plugin's render equals the library's with the brightness those messages
/// mean, and a bright note is brighter than the same note without.
#[test]
fn brightness_and_mpe_timbre_through_the_host_match_the_library() {
    let rate = 48_000.0;
    let total = 12_000;
    let midi = |at: usize, data: [u8; 3]| HostEvent::Midi { at, data };
    let notes = vec![on(100, 60, 0.8)];
    let mut events = notes.clone();
    events.push(plugin_tests::note_brightness(100, 60, 1.0));
    let plugin = plugin_equals_library("brightness", rate, total, events.clone(), &events);
    let plain = library_render(&InstrumentParams::default(), rate, total, &notes);
    let high = |x: &[f32]| {
        let d: f64 = x.windows(2).map(|w| f64::from(w[1] - w[0]).powi(2)).sum();
        d / x.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>()
    };
    let (b, p) = (high(&plugin[0][..3_000]), high(&plain[0][..3_000]));
    println!("high-frequency share, bright vs plain: {b:.3e} vs {p:.3e}");
    assert!(b > 1.2 * p, "{b} vs {p}");

    // MPE: channel 2's timbre before its note, channel 3's during its note
    let mpe = vec![
        midi(0, [0xB0, 101, 0]),
        midi(0, [0xB0, 100, 6]),
        midi(0, [0xB0, 6, 15]),
        midi(50, [0xB1, 74, 127]),
        midi(100, [0x91, 60, 100]),
        midi(200, [0x92, 64, 90]),
        midi(5_000, [0xB2, 74, 0]),
    ];
    let meant = vec![
        on(100, 60, 100.0 / 127.0),
        plugin_tests::note_brightness(100, 60, 1.0),
        on(200, 64, 90.0 / 127.0),
        plugin_tests::note_brightness(5_000, 64, 0.0),
    ];
    plugin_equals_library("MPE timbre", rate, total, mpe, &meant);
}

/// CLAP polyphonic modulation of Hardness through a real host: notes with
/// note ids, a `param_mod` on two of them (one up, one down, one note
/// unmodulated, one modulation of an id that never played): the plugin's
/// render equals the library's with the hardness factors the offsets mean
/// (the parameter's mapping written out in the test), and the plugin
/// tells the host when each voice ends (CLAP note-end with its note id and
/// key): a new note on a key ends the old id at once, a released note ends
/// when it has died away, and a voice that was never given an id ends
/// without one reported.
#[test]
fn hardness_poly_modulation_and_note_ends_through_the_host() {
    let rate = 48_000.0;
    let total = 12_000;
    let up = poly_mod(100, 1, PolyTarget::Hardness, 0.05);
    let down = poly_mod(100, 2, PolyTarget::Hardness, -0.1);
    let stray = poly_mod(150, 99, PolyTarget::Hardness, 0.3);
    let events = vec![
        on_id(100, 60, 0.8, 1),
        up,
        on_id(100, 64, 0.7, 2),
        down,
        on_id(200, 67, 0.8, 3),
        stray,
    ];
    // the factors' levels (log2, rounded): 1 and -2, far from a rounding edge
    let (f_up, f_down) = (hardness_factor(1.0, 0.05), hardness_factor(1.0, -0.1));
    println!("hardness factors: up {f_up:.4}, down {f_down:.4}");
    assert!((f_up.log2() - 1.0).abs() < 0.3 && (f_down.log2() + 2.0).abs() < 0.3);
    let plugin = plugin_equals_library("hardness modulation", rate, total, events.clone(), &events);
    let plain_events = vec![on(100, 60, 0.8), on(100, 64, 0.7), on(200, 67, 0.8)];
    let plain = library_render(&InstrumentParams::default(), rate, total, &plain_events);
    let moved = max_abs_diff(&plugin[0][..3_000], &plain[0][..3_000]);
    println!("modulated against unmodulated: max difference {moved:.3e}");
    assert!(moved > 1e-3 * peak(&plain[0]), "{moved}");

    // note ends: key 60 struck again with id 4 at 3000 ends id 1 there;
    // key 64 released at 1000 ends id 2 when it has died away; key 67 (id
    // 3) rings on; a note without an id ends nothing the host knows
    let mut p = LoadedPlugin::load(&clap_bundle(Variant::Release));
    let mut session = p.activate(rate, 1, 256);
    let script = [
        // the marimba rings on after its release: a damper that follows
        // the key makes the released note die away
        param(0, ids::DAMPER_CUSTOM, 1.0),
        on_id(100, 60, 0.8, 1),
        on_id(100, 64, 0.7, 2),
        on_id(200, 67, 0.8, 3),
        on(300, 72, 0.8),
        off(1_000, 64),
        off(1_000, 72),
        on_id(3_000, 60, 0.8, 4),
    ];
    // 0.33 s: the unreleased notes ring on (the bar alone falls silent
    // after about a second)
    let (block, blocks) = (256, 62);
    for b in 0..blocks {
        let start = b * block;
        let here: Vec<HostEvent> = script
            .iter()
            .copied()
            .filter(|e| e.at() >= start && e.at() < start + block)
            .collect();
        session.process(block, start, &here);
    }
    let ends = session.note_ends().to_vec();
    session.deactivate();
    println!("note ends: {ends:?}");
    let end_of = |id: u32| ends.iter().find(|e| e.id == Some(id)).copied();
    let e1 = end_of(1).expect("id 1 ends when its key is struck again");
    assert_eq!(e1.key, Some(60));
    assert!((3_000..3_256).contains(&e1.at), "{e1:?}");
    let e2 = end_of(2).expect("id 2 ends after its release");
    assert_eq!(e2.key, Some(64));
    assert!(e2.at > 1_000 && e2.at < blocks * block, "{e2:?}");
    assert!(end_of(3).is_none(), "id 3 still rings");
    assert!(end_of(4).is_none(), "id 4 still rings");
    assert!(
        ends.iter().all(|e| e.id.is_some() && e.key != Some(72)),
        "a note without an id: {ends:?}"
    );
    assert_eq!(ends.len(), 2, "each id ends once: {ends:?}");
}

/// CLAP polyphonic modulation of Strike position and Damper through a real
/// host. Their levels are compiled when a host first modulates those
/// parameters: here a modulation of a note id that is not sounding, at the
/// start (with Custom strike position switched on), asks for them, and the
/// render waits for the compile. Then notes with ids and their
/// modulations (a position up, a position down, a damper, one note
/// unmodulated): the plugin's render equals the library's with
/// those levels compiled and the offsets the amounts mean (from the
/// parameters' ranges, written out in the test), and differs from the same
/// notes unmodulated. On the default scene and on a kit (the two-mallet
/// marimba, whose kit voices move between the kit's compiles of those
/// levels).
#[test]
fn position_and_damper_poly_modulation_through_the_host_match_the_library() {
    position_and_damper_through_the_host(None);
    position_and_damper_through_the_host(Some("marimba-two-mallets"));
}

fn position_and_damper_through_the_host(preset: Option<&str>) {
    let rate = 48_000.0;
    let total = 16_000;
    let notes = vec![
        on_id(4_000, 57, 0.8, 1),
        poly_mod(4_000, 1, PolyTarget::StrikePosition, 0.1),
        on_id(4_000, 64, 0.7, 2),
        poly_mod(4_000, 2, PolyTarget::Damper, 0.3),
        on_id(4_100, 60, 0.8, 3),
        poly_mod(4_100, 3, PolyTarget::StrikePosition, -0.2),
        on_id(4_200, 69, 0.8, 4),
        off(9_000, 64),
        off(9_000, 69),
    ];
    let index = preset.map(|name| presets::index_of(name).unwrap());
    let mut events: Vec<HostEvent> = index
        .map(|i| param(0, ids::SCENE, i as f64))
        .into_iter()
        .collect();
    events.extend([
        param(0, ids::STRIKE_CUSTOM, 1.0),
        poly_mod(0, 99, PolyTarget::StrikePosition, 0.1),
        poly_mod(0, 99, PolyTarget::Damper, 0.1),
    ]);
    events.extend(notes.iter().copied());
    let mut spec = RenderSpec::new(rate, 256, total, events);
    spec.settle_after = vec![0, 256, 512];
    spec.settle_ms = 400;
    let plugin = LoadedPlugin::load(&clap_bundle(Variant::Release)).render(&spec);
    let mut params = InstrumentParams::default();
    if let Some(i) = index {
        params.scene.preset = i;
    }
    params.scene.strike_pos_norm = Some(0.5);
    params.scene.variants = VariantSet {
        position: true,
        damper: true,
    };
    let lib = library_render(&params, rate, total, &notes);
    let d = max_abs_diff(&plugin[0], &lib[0]).max(max_abs_diff(&plugin[1], &lib[1]));
    println!("{preset:?}: position and damper modulation: max |plugin - library| = {d:.3e}");
    assert!(peak(&lib[0]) > 1e-3, "the library's render is silent");
    assert!(d <= 1e-6, "plugin and library differ by {d}");
    let plain_notes: Vec<HostEvent> = notes
        .iter()
        .copied()
        .filter(|e| !matches!(e, HostEvent::PolyMod { .. }))
        .collect();
    let plain = library_render(&params, rate, total, &plain_notes);
    // the strikes differ from the first sample (the positions), the
    // damped note only after its release (the damper)
    assert_eq!(plugin[0][..4_000], plain[0][..4_000]);
    let damped_only: Vec<HostEvent> = plain_notes
        .iter()
        .copied()
        .chain([poly_mod(4_000, 2, PolyTarget::Damper, 0.3)])
        .collect();
    let damped = library_render(&params, rate, total, &damped_only);
    assert_eq!(damped[0][..9_000], plain[0][..9_000]);
    let released = max_abs_diff(&damped[0][9_000..], &plain[0][9_000..]);
    println!("damper: released note against unmodulated, max difference {released:.3e}");
    assert!(released > 1e-4, "{released}");
    for (what, range) in [("strikes", 4_000..8_000), ("release", 9_200..12_000)] {
        let moved = max_abs_diff(&plugin[0][range.clone()], &plain[0][range]);
        println!("{what}: modulated against unmodulated, max difference {moved:.3e}");
        assert!(moved > 1e-4, "{what}: {moved}");
    }
}

/// Pressure through a real host: a CLAP "pressure" note expression on one
/// note, channel aftertouch and the mod wheel (MIDI 1.0), and, after the
/// MPE configuration message, a member channel's pressure on that
/// channel's note: the plugin's render equals the library's with the
/// pressures those messages mean, and the pressed notes die away faster
/// than the same notes unpressed.
#[test]
fn pressure_aftertouch_and_mod_wheel_through_the_host_match_the_library() {
    let rate = 48_000.0;
    let total = 30_000;
    let midi = |at: usize, data: [u8; 3]| HostEvent::Midi { at, data };
    let notes = vec![on(100, 60, 0.8), on(4_000, 64, 0.7)];
    let mut events = notes.clone();
    events.extend([
        plugin_tests::note_pressure(3_000, 60, 0.7),
        midi(9_000, [0xD0, 90, 0]),
        midi(14_000, [0xD0, 0, 0]),
        midi(16_000, [0xB0, 1, 127]),
        midi(22_000, [0xB0, 1, 40]),
    ]);
    let plugin = plugin_equals_library("pressure", rate, total, events.clone(), &events);
    let free = library_render(&InstrumentParams::default(), rate, total, &notes);
    let late = |x: &[f32]| plugin_tests::rms(&x[24_000..]);
    println!(
        "pressed vs unpressed, last 6000 samples: rms {:.3e} vs {:.3e}",
        late(&plugin[0]),
        late(&free[0])
    );
    assert!(late(&plugin[0]) < 0.1 * late(&free[0]));
    // the first note's strike is untouched: pressure acts once the hammer
    // has left
    assert_eq!(plugin[0][..3_000], free[0][..3_000]);

    // MPE: member channel 2's pressure presses its note only
    let mpe = vec![
        midi(0, [0xB0, 101, 0]),
        midi(0, [0xB0, 100, 6]),
        midi(0, [0xB0, 6, 15]),
        midi(100, [0x91, 60, 100]),
        midi(200, [0x92, 64, 90]),
        midi(5_000, [0xD2, 127, 0]),
    ];
    let meant = vec![
        on(100, 60, 100.0 / 127.0),
        on(200, 64, 90.0 / 127.0),
        plugin_tests::note_pressure(5_000, 64, 1.0),
    ];
    plugin_equals_library("MPE pressure", rate, total, mpe, &meant);
}

/// MIDI's channel mode messages through a real host (docs/plugin.md,
/// "Pedals"): All Notes Off (controller 123) is a note-off of every key,
/// so the sustain pedal holds the notes until Reset All Controllers (121)
/// lifts it (and brings the bent wheel back to its centre); All Sound Off
/// (120) fades every note out in 5 ms, pedal or not, then the output is
/// exactly silent until the next note. The plugin's render equals the
/// library's driven with the events those messages mean; before, the
/// plugin ignored all three (the notes rang on).
#[test]
fn channel_mode_messages_through_the_host_match_the_library() {
    use modal_contact::instrument::{prepare, Event, Instrument, TimedEvent, FADE_S};
    let bundle = clap_bundle(Variant::Release);
    let rate = 48_000.0;
    let total = 48_000;
    // the bar damped on release (Custom damper on at sample 0, the notes
    // from the third block on, after its compile), so that a release shows
    let t0 = 512;
    let fade = (FADE_S * rate).round() as usize;
    let (sound_off, next) = (t0 + 20_000, t0 + 30_000);
    let host = vec![
        on(t0 + 100, 60, 0.8),
        on(t0 + 200, 64, 0.7),
        cc(t0 + 300, 64, 127),
        cc(t0 + 2_000, 123, 0),
        plugin_tests::pitch_bend(t0 + 3_000, 16383),
        cc(t0 + 8_000, 121, 0),
        on(t0 + 12_000, 67, 0.9),
        cc(t0 + 12_050, 64, 127),
        on(t0 + 12_100, 72, 0.8),
        cc(sound_off, 120, 0),
        on(next, 62, 0.8),
        cc(t0 + 36_000, 64, 0),
        cc(t0 + 40_000, 123, 0),
    ];
    let plugin = render_with_custom_damper(&bundle, rate, total, &host);

    let note = |offset: usize, key: u8, v: f64| TimedEvent {
        offset,
        event: Event::NoteOn {
            key,
            velocity_norm: v as f32 as f64,
        },
    };
    let ev = |offset: usize, event: Event| TimedEvent { offset, event };
    let meant = [
        note(t0 + 100, 60, 0.8),
        note(t0 + 200, 64, 0.7),
        ev(t0 + 300, Event::Sustain { down: true }),
        ev(t0 + 2_000, Event::AllNotesOff),
        ev(t0 + 3_000, Event::PitchBend { value: 1.0 }),
        ev(t0 + 8_000, Event::ResetControllers),
        note(t0 + 12_000, 67, 0.9),
        ev(t0 + 12_050, Event::Sustain { down: true }),
        note(t0 + 12_100, 72, 0.8),
        ev(sound_off, Event::AllSoundOff),
        note(next, 62, 0.8),
        ev(t0 + 36_000, Event::Sustain { down: false }),
        ev(t0 + 40_000, Event::AllNotesOff),
    ];
    let mut params = InstrumentParams::default();
    params.scene.damper_custom = true;
    let mut inst = Instrument::new(prepare(&params.scene, rate, 0).unwrap(), params.play);
    let (mut l, mut r) = (vec![0.0; total], vec![0.0; total]);
    inst.process(&meant, &mut l, &mut r);
    let lib = [l, r];
    let d = max_abs_diff(&plugin[0], &lib[0]).max(max_abs_diff(&plugin[1], &lib[1]));
    println!("channel mode messages: max |plugin - library| = {d:.3e}");
    assert!(peak(&lib[0]) > 1e-3, "the library's render is silent");
    assert!(d <= 1e-6, "plugin and library differ by {d}");
    // silent from the end of All Sound Off's fade to the next note
    let sounding = peak(&plugin[0][sound_off - 500..sound_off]);
    let after = plugin
        .iter()
        .flat_map(|c| &c[sound_off + fade..next])
        .fold(0.0f32, |m, x| m.max(x.abs()));
    println!("before All Sound Off peak {sounding:.3e}, after its fade {after:e}");
    assert!(sounding > 1e-3 && after == 0.0, "{sounding}, {after}");
    // the pedal held the notes All Notes Off released: the same notes
    // without controller 123 ring the same until the reset
    let no_123: Vec<HostEvent> = host
        .iter()
        .copied()
        .filter(|e| {
            !matches!(
                e,
                HostEvent::Midi {
                    data: [0xB0, 123, _],
                    ..
                }
            )
        })
        .collect();
    let held = render_with_custom_damper(&bundle, rate, total, &no_123);
    assert_eq!(plugin[0][..t0 + 8_000], held[0][..t0 + 8_000]);
}
