//! What a careless or hostile host can do to the BUILT plugin, through
//! clack-host. Renders run on the `rt-checks` build: any allocation inside
//! `process` aborts this test binary (nice-plug's `assert_process_allocs`),
//! so "no allocation" is checked on every block of every test here. Every
//! sample must be finite and within the documented ceiling
//! ([`OUTPUT_CEILING`]); the output buffers are poisoned with NaN before each
//! block, so a sample the plugin forgets to write fails the test too.

use modal_contact::instrument::{InstrumentParams, OUTPUT_CEILING};
use modal_contact::plugin::params::ids;
use modal_contact::presets;
use modal_testkit::rng::TestRng;
use plugin_tests::*;

/// Every sample finite and within the ceiling; returns the peak.
fn check_block(x: &[f32], what: &str) -> f64 {
    let mut p = 0.0f64;
    for (i, v) in x.iter().enumerate() {
        assert!(v.is_finite(), "{what}: sample {i} is {v}");
        p = p.max(v.abs() as f64);
    }
    assert!(p <= OUTPUT_CEILING, "{what}: peak {p} above the ceiling");
    p
}

/// Process `events` (absolute times) in blocks of the given sizes.
fn play(
    session: &mut Session<'_>,
    sizes: &[usize],
    events: &[HostEvent],
    what: &str,
) -> [Vec<f32>; 2] {
    let mut sorted = events.to_vec();
    sorted.sort_by_key(|e| e.at());
    let mut out = [Vec::new(), Vec::new()];
    let (mut pos, mut next) = (0usize, 0usize);
    for &len in sizes {
        let first = next;
        while next < sorted.len() && sorted[next].at() < pos + len {
            next += 1;
        }
        // events at the end of a zero-length block wait for the next one
        let block = session.process(len, pos, &sorted[first..next]);
        check_block(block[0], what);
        check_block(block[1], what);
        out[0].extend_from_slice(block[0]);
        out[1].extend_from_slice(block[1]);
        pos += len;
    }
    out
}

/// A phrase with repeated notes, releases and a chord.
fn phrase(rate: f64) -> Vec<HostEvent> {
    let s = |t: f64| (t * rate) as usize;
    vec![
        on(s(0.01) + 5, 57, 0.8),
        on(s(0.01) + 5, 64, 0.6),
        on(s(0.2), 57, 1.0),
        on(s(0.21), 57, 0.3),
        off(s(0.4), 64),
        on(s(0.5), 69, 0.7),
        off(s(0.9), 57),
        on(s(1.1), 45, 0.9),
    ]
}

/// Block sizes 0, 1, 7, 64 and 4097, then a different size every block: the
/// output is the same, sample for sample, as with steady 512-sample blocks
/// (everything is on the instrument's own sample clock).
#[test]
fn any_block_size_gives_the_same_output() {
    let rate = 44_100.0;
    let total = (1.5 * rate) as usize;
    let events = phrase(rate);
    let bundle = clap_bundle(Variant::RtChecks);
    let mut rng = TestRng(0x5eed);
    let mut sizes = Vec::new();
    for s in [0usize, 1, 7, 64, 4097] {
        for _ in 0..5 {
            sizes.push(s);
        }
    }
    let mut sum: usize = sizes.iter().sum();
    while sum < total {
        let s = match rng.below(6) {
            0 => 0,
            1 => 1,
            2 => rng.below(16),
            3 => 4097,
            _ => rng.below(4098),
        }
        .min(total - sum);
        sizes.push(s);
        sum += s;
    }
    let mut p = LoadedPlugin::load(&bundle);
    let mut session = p.activate(rate, 1, 4097);
    let odd = play(&mut session, &sizes, &events, "changing blocks");
    session.deactivate();
    let steady = LoadedPlugin::load(&bundle).render(&RenderSpec::new(rate, 512, total, events));
    let d = max_abs_diff(&odd[0], &steady[0]).max(max_abs_diff(&odd[1], &steady[1]));
    println!(
        "{} blocks (sizes 0..=4097, {} empty): peak {:.3}, max |changing - steady 512| = {d:.1e}",
        sizes.len(),
        sizes.iter().filter(|&&s| s == 0).count(),
        peak(&odd[0])
    );
    assert!(peak(&odd[0]) > 0.01);
    assert_eq!(d, 0.0, "the output depends on the block sizes");
}

/// 8 kHz to 384 kHz on one instance, re-activated at each rate: the plugin
/// equals the instrument library compiled at that rate (so the new rate is
/// really used), and notes at pitches 0 and 127 are finite and bounded.
#[test]
fn sample_rates_from_8k_to_384k_and_changes_between_activations() {
    let bundle = clap_bundle(Variant::RtChecks);
    let mut p = LoadedPlugin::load(&bundle);
    let rates = [
        8_000.0, 11_025.0, 22_050.0, 44_100.0, 48_000.0, 88_200.0, 96_000.0, 176_400.0, 192_000.0,
        352_800.0, 384_000.0, 8_000.0,
    ];
    for rate in rates {
        let total = (0.4 * rate) as usize;
        let s = |t: f64| (t * rate) as usize;
        let events = vec![
            on(s(0.01), 57, 0.8),
            on(s(0.05), 0, 1.0),
            on(s(0.1), 127, 1.0),
            on(s(0.15), 127, 0.5),
            on(s(0.2), 0, 0.2),
        ];
        let block = 1024;
        let sizes: Vec<usize> = (0..total.div_ceil(block))
            .map(|i| block.min(total - i * block))
            .collect();
        let mut session = p.activate(rate, 1, block);
        let out = play(&mut session, &sizes, &events, &format!("{rate} Hz"));
        session.deactivate();
        let lib = library_render(&InstrumentParams::default(), rate, total, &events);
        let d = max_abs_diff(&out[0], &lib[0]).max(max_abs_diff(&out[1], &lib[1]));
        let key127 = rms(&out[0][s(0.1)..s(0.15)]);
        println!(
            "{rate:>8} Hz: peak {:.3}, rms of the key-127 note {key127:.2e}, \
             max |plugin - library| {d:.1e}",
            peak(&out[0])
        );
        assert!(d <= 1e-6, "{rate} Hz: plugin and library differ by {d}");
        assert!(rms(&out[0][..s(0.05)]) > 1e-3, "{rate} Hz: no sound");
    }
}

/// Activate/deactivate/reset many times, process before any note and long
/// after all voices died: silence exactly where nothing sounds.
#[test]
fn activation_cycles_resets_and_silence() {
    let bundle = clap_bundle(Variant::RtChecks);
    let mut p = LoadedPlugin::load(&bundle);
    let mut rng = TestRng(42);
    let rates = [44_100.0, 48_000.0, 96_000.0, 22_050.0];
    for cycle in 0..60 {
        let rate = rates[cycle % rates.len()];
        let max = [1, 64, 333, 4096][rng.below(4)];
        let mut session = p.activate(rate, 1, max);
        // before any note: exact silence
        let pre = play(&mut session, &[max.min(64); 3], &[], "before notes");
        assert!(
            pre[0].iter().chain(&pre[1]).all(|&v| v == 0.0),
            "cycle {cycle}"
        );
        // a note, then a reset in the middle of it
        let t0 = 3 * max.min(64);
        let notes = [on(t0, 40 + rng.below(40) as u8, 0.9)];
        let n_blocks = 2000 / max + 2;
        let sizes = vec![max; n_blocks];
        let sounding = play(&mut session, &sizes, &notes, "note");
        assert!(peak(&sounding[0]) > 0.0, "cycle {cycle}: no sound");
        if cycle % 2 == 0 {
            session.reset();
            let after = play(&mut session, &[max.min(256); 2], &[], "after reset");
            assert!(
                after[0].iter().chain(&after[1]).all(|&v| v == 0.0),
                "cycle {cycle}: sound after reset"
            );
        }
        if cycle % 3 == 0 {
            session.deactivate();
        } else {
            drop(session); // deactivated by the session's drop
        }
    }
    // all voices die on their own: a short scene, then exact silence
    let mut session = p.activate(48_000.0, 1, 512);
    let rate = 48_000.0;
    let total = (12.0 * rate) as usize;
    let out = play(
        &mut session,
        &vec![512; total / 512],
        &[on(10, 60, 1.0), off(100, 60)],
        "decay",
    );
    let tail = &out[0][out[0].len() - 48_000..];
    println!(
        "after 12 s the voice has stopped: last second peak {:.1e}",
        peak(tail)
    );
    assert!(tail.iter().all(|&v| v == 0.0), "a dead voice still outputs");
}

/// 1000 note-ons in one block (keys 0..127 with repeats, random
/// velocities including 0), note-offs without note-ons, all-notes-off
/// storms: finite, bounded, no allocation; a note after the storm sounds.
#[test]
fn a_thousand_notes_in_one_block() {
    let bundle = clap_bundle(Variant::RtChecks);
    let mut p = LoadedPlugin::load(&bundle);
    let rate = 48_000.0;
    let mut session = p.activate(rate, 1, 4096);
    let mut rng = TestRng(7);
    let mut events = Vec::new();
    for i in 0..1000 {
        let key = if i % 10 == 0 {
            57
        } else {
            rng.below(128) as u8
        };
        let velocity = if i % 17 == 0 { 0.0 } else { rng.unit() };
        events.push(on(rng.below(4096), key, velocity));
    }
    for _ in 0..300 {
        events.push(off(rng.below(4096), rng.below(128) as u8));
    }
    let sizes = vec![4096; 24];
    let out = play(&mut session, &sizes, &events, "1000 notes");
    println!(
        "1000 notes + 300 stray note-offs in one 4096 block: peak {:.3} (ceiling {OUTPUT_CEILING})",
        peak(&out[0]).max(peak(&out[1]))
    );
    // note-offs for notes that never played, before anything else
    let strays: Vec<HostEvent> = (0..128u8).map(|k| off(k as usize, k)).collect();
    let quiet = play(&mut session, &[4096], &[], "after");
    assert!(quiet[0].iter().all(|v| v.is_finite()));
    session.deactivate();
    let mut fresh = p.activate(rate, 1, 512);
    let out = play(&mut fresh, &[512; 4], &strays, "stray note-offs");
    assert!(out[0].iter().chain(&out[1]).all(|&v| v == 0.0));
    let out = play(
        &mut fresh,
        &[512; 40],
        &[on(2048 + 7, 60, 0.8)],
        "then a note",
    );
    assert!(rms(&out[0]) > 1e-3);
}

/// A velocity-0 note-on releases the key, as in MIDI: the same output as a
/// note-off; alone it plays nothing.
#[test]
fn velocity_zero_note_on_is_a_note_off() {
    let bundle = clap_bundle(Variant::RtChecks);
    let rate = 44_100.0;
    let total = 44_100;
    // the default damper is on: a release is audible
    let render = |events: Vec<HostEvent>| {
        LoadedPlugin::load(&bundle).render(&RenderSpec::new(rate, 256, total, events))
    };
    let with_off = render(vec![on(300, 60, 0.9), off(5000, 60)]);
    let with_zero = render(vec![on(300, 60, 0.9), on(5000, 60, 0.0)]);
    let alone = render(vec![on(300, 62, 0.0)]);
    println!(
        "note-off vs velocity-0 note-on: max diff {:.1e}; velocity 0 alone: peak {:.1e}",
        max_abs_diff(&with_off[0], &with_zero[0]),
        peak(&alone[0])
    );
    assert_eq!(with_off, with_zero);
    assert!(alone[0].iter().chain(&alone[1]).all(|&v| v == 0.0));
}

/// Every parameter automated with random values every block, several at
/// random sample positions inside the block (some outside the range, some
/// NaN or infinite), with notes, for 20 s of audio at 48 kHz in blocks of
/// random size.
#[test]
fn random_sample_accurate_automation_of_every_parameter() {
    let bundle = clap_bundle(Variant::RtChecks);
    // a live host's instance: an offline render would wait for the scene
    // of every one of these thousands of changes
    let mut p = LoadedPlugin::load_realtime(&bundle);
    let rate = 48_000.0;
    let total = (20.0 * rate) as usize;
    let mut rng = TestRng(2024);
    let n_presets = presets::PRESETS.len();
    let mut sizes = Vec::new();
    let mut events = Vec::new();
    let mut pos = 0;
    let mut hostile = 0;
    while pos < total {
        let len = (1 + rng.below(1024)).min(total - pos);
        for id in ids::ALL {
            let v = match rng.below(40) {
                0 => f64::NAN,
                1 => f64::INFINITY,
                2 => -1e9,
                3 => 1e9,
                _ if id == ids::SCENE => rng.below(n_presets) as f64,
                _ if id == ids::SWITCHING || id == ids::STRIKE_CUSTOM => rng.below(2) as f64,
                _ if id == ids::PITCH_TRACKING => rng.below(2) as f64,
                _ => rng.unit(),
            };
            if !(v.is_finite() && (0.0..=n_presets as f64).contains(&v)) {
                hostile += 1;
            }
            // the scene changes less often (each change fades and recompiles)
            if id == ids::SCENE && rng.below(20) != 0 {
                continue;
            }
            events.push(HostEvent::Param {
                at: pos + rng.below(len),
                id: param_id(id),
                value: v,
            });
        }
        if rng.below(3) == 0 {
            events.push(on(
                pos + rng.below(len),
                30 + rng.below(70) as u8,
                rng.unit(),
            ));
        }
        if rng.below(5) == 0 {
            events.push(off(pos + rng.below(len), 30 + rng.below(70) as u8));
        }
        sizes.push(len);
        pos += len;
    }
    let mut session = p.activate(rate, 1, 1024);
    let t = std::time::Instant::now();
    let out = play(&mut session, &sizes, &events, "automation");
    session.deactivate();
    let secs = t.elapsed().as_secs_f64();
    let at_ceiling = out
        .iter()
        .flatten()
        .filter(|v| v.abs() as f64 >= OUTPUT_CEILING)
        .count();
    println!(
        "{} blocks, {} events ({hostile} hostile values: NaN, inf, +-1e9): peak {:.3}, \
         rms {:.3e}, {at_ceiling} of {} samples at the ceiling; rendered in {secs:.1} s",
        sizes.len(),
        events.len(),
        2 * total,
        peak(&out[0]).max(peak(&out[1])),
        rms(&out[0])
    );
    assert!(rms(&out[0]) > 1e-4, "the automation silenced everything");
    // the plugin still plays normally afterwards
    // (the automation left the parameters anywhere: bring the gain up;
    // rendered offline, so the note waits for the scene of those values)
    assert!(p.set_render_mode(true));
    let mut session = p.activate(rate, 1, 512);
    let gain = HostEvent::Param {
        at: 0,
        id: param_id(ids::GAIN),
        value: 0.9,
    };
    let after = play(&mut session, &[512; 40], &[gain, on(100, 57, 0.8)], "after");
    println!("a note after the automation: rms {:.3e}", rms(&after[0]));
    assert!(rms(&after[0]) > 1e-4);
}

/// The audio-thread code paths name no lock, no blocking channel, no I/O
/// and no sleeping (they only use atomics and lock-free queues).
#[test]
fn audio_thread_sources_use_no_locks_or_io() {
    // Every source file with code that runs on the audio thread: the ones
    // whose functions say so in their docs ("[audio-thread]", the project's
    // convention) and, whatever their docs say, every file of the engine,
    // the instrument and the block operations the engine calls. Found by walking src/, not listed by hand, so a
    // new audio-thread file is scanned without anyone remembering to add it.
    // The waits for a scene and the locks the worker shares with the main
    // thread live in plugin/waits.rs, which carries no audio-thread tag: a
    // real-time block never reaches it (an offline render's does, where the
    // host allows a block to wait).
    let root = workspace_root().join("src");
    let mut files = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).expect("read src") {
            let path = e.expect("entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|x| x == "rs") {
                let text = std::fs::read_to_string(&path).expect("read source");
                let rel = path
                    .strip_prefix(&root)
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                let tagged = text.contains("[audio-thread]") || text.contains("\\[audio-thread\\]");
                let hot = rel.starts_with("engine")
                    || rel.starts_with("instrument")
                    || rel == "physics/block.rs";
                if tagged || hot {
                    files.push((rel, text));
                }
            }
        }
    }
    files.sort();
    let names: Vec<&str> = files.iter().map(|(f, _)| f.as_str()).collect();
    println!("audio-thread sources scanned: {names:?}");
    for must in [
        "engine/mod.rs",
        "engine/exact.rs",
        "engine/kernel.rs",
        "engine/vmath.rs",
        "engine/denormal.rs",
        "engine/replay.rs",
        "plugin/mod.rs",
        "physics/block.rs",
    ] {
        assert!(names.contains(&must), "{must} is not scanned");
    }
    let banned = [
        "Mutex",
        "RwLock",
        "Condvar",
        "mpsc",
        "std::fs",
        "File::",
        "println!",
        "eprintln!",
        "sleep(",
        ".lock()",
        "Barrier",
    ];
    for (f, text) in &files {
        // test modules may print and lock (a file that is a test module
        // itself is left out whole)
        if f.ends_with("tests.rs") || f.contains("tests/") {
            continue;
        }
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        for b in banned {
            assert!(!code.contains(b), "{f} uses {b}");
        }
    }
}
