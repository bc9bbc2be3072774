//! The worst block, not the average: per-block CPU time of the instrument
//! (`Instrument::process`, exactly what the plugin calls per host block)
//! over a long render at 48 kHz with chords of 1, 4 and 16 notes struck
//! together every 125 ms on voices that still ring (so strikes land on
//! sounding voices and steal them), on modal objects of 10, 50, 200 and 1000
//! modes, in blocks of 32, 64, 128 and 512 samples. Printed: the largest
//! and the 99.9th percentile block, as a fraction of the block's real-time
//! budget (`block / 48000` s). Above 100 % a block is late: a dropout.
//!
//! Beside it: the strike cost per voice, one note through the instrument
//! at three pitches, 64 voices, bad input, a pitch bend, and a 16-note
//! chord with a brightness on every note.
//!
//! `cargo bench --bench worst_block` (a criterion target; the table is
//! printed, nothing is asserted: timings are never test conditions).

use criterion::{criterion_group, criterion_main, Criterion};
use modal_contact::instrument::{
    prepare_scene, Event, Instrument, InstrumentParams, Prepared, TimedEvent, VoiceChunk,
    VoiceProbe,
};
use modal_contact::scene::Scene;
use modal_testkit::scenes::struck_bar;
use std::time::Instant;

const RATE: f64 = 48000.0;
/// Seconds rendered per configuration.
const SECONDS: f64 = 2.0;
/// Chords repeat this often.
const CHORD_EVERY_S: f64 = 0.125;
/// Runs of each cell; a block's time is its least over them.
const RUNS: usize = 3;

/// A struck modal object of `n` modes (a bar-like spectrum up to 18 kHz,
/// weights that fall slowly with frequency), hammer as the presets'.
fn object(n: usize) -> Scene {
    struck_bar(n, SECONDS)
}

/// Chords of `chord` notes (a spread of keys around the root) at velocity
/// 100/127 every `CHORD_EVERY_S`, each chord shifted by a semitone so the
/// same keys retrigger ringing voices or steal others.
fn events(chord: usize, total: usize) -> Vec<TimedEvent> {
    let every = (CHORD_EVERY_S * RATE) as usize;
    let mut out = Vec::new();
    let mut k = 0;
    let mut at = 0;
    while at < total {
        for j in 0..chord {
            out.push(TimedEvent {
                offset: at,
                event: Event::NoteOn {
                    key: (48 + (j * 5 + k) % 36) as u8,
                    velocity_norm: 100.0 / 127.0,
                },
            });
        }
        k += 1;
        at += every;
    }
    out
}

/// Per-block seconds of one render.
fn block_times(prepared: &Prepared, chord: usize, block: usize) -> Vec<f64> {
    block_times_ahead(prepared, chord, block, 0)
}

/// Per-block seconds of one render with a lookahead of `lookahead` samples,
/// each block's the least of [`RUNS`] runs (see [`least_of_runs`]).
fn block_times_ahead(
    prepared: &Prepared,
    chord: usize,
    block: usize,
    lookahead: usize,
) -> Vec<f64> {
    let total = (SECONDS * RATE) as usize;
    let evs = events(chord, total);
    least_of_runs(|| run_blocks(prepared, &evs, total, block, lookahead))
}

/// Each block's least time over [`RUNS`] runs of the same
/// deterministic work: a block the machine interrupted in one run (a
/// pause of a few milliseconds, the same in every cell whatever the block
/// size, when anything else runs beside the bench) does not stand for
/// the instrument's cost.
fn least_of_runs(mut run: impl FnMut() -> Vec<f64>) -> Vec<f64> {
    let mut times = run();
    for _ in 1..RUNS {
        for (t, a) in times.iter_mut().zip(run()) {
            *t = t.min(a);
        }
    }
    times
}

/// Per-block seconds of playing `evs` for `total` samples in blocks of
/// `block` with a lookahead of `lookahead` samples.
fn run_blocks(
    prepared: &Prepared,
    evs: &[TimedEvent],
    total: usize,
    block: usize,
    lookahead: usize,
) -> Vec<f64> {
    let mut inst = Instrument::new(Box::new(prepared.clone()), InstrumentParams::default().play);
    inst.set_lookahead(lookahead);
    let (mut l, mut r) = (vec![0.0f32; block], vec![0.0f32; block]);
    let mut times = Vec::with_capacity(total / block + 1);
    let mut e = 0;
    let mut start = 0;
    let mut local: Vec<TimedEvent> = Vec::with_capacity(64);
    while start < total {
        let len = block.min(total - start);
        local.clear();
        while e < evs.len() && evs[e].offset < start + len {
            local.push(TimedEvent {
                offset: evs[e].offset - start,
                event: evs[e].event,
            });
            e += 1;
        }
        let t0 = Instant::now();
        inst.process(&local, &mut l[..len], &mut r[..len]);
        times.push(t0.elapsed().as_secs_f64());
        std::hint::black_box(&l);
        start += len;
    }
    times
}

/// A table cell: the largest and the 99.9th percentile of the block
/// times `t`, % of the budget of `block` samples.
fn cell(mut t: Vec<f64>, block: usize) -> String {
    t.sort_by(f64::total_cmp);
    let budget = block as f64 / RATE;
    format!(
        "{:.0} / {:.0}",
        100.0 * t[t.len() - 1] / budget,
        100.0 * percentile(&t, 0.999) / budget
    )
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn worst_block(_: &mut Criterion) {
    println!("\nworst block at 48 kHz, % of the block's real-time budget (max / 99.9th percentile), {SECONDS} s per cell, each block the least of {RUNS} runs, chords every {CHORD_EVERY_S} s:");
    println!("| modes | chord | 32 samples | 64 samples | 128 samples | 512 samples |");
    println!("|---|---|---|---|---|---|");
    for n in [10, 50, 200, 1000] {
        let params = InstrumentParams::default();
        let prepared = prepare_scene(&object(n), &params.scene, RATE, 0).expect("compile");
        // the same scene switching through its dense matrices, for the
        // ratio in the same run
        let mut dense = prepared.clone();
        let structured = dense.scenes.scene.w_cf_h.take().is_some();
        dense.scenes.scene.w_fc_h = None;
        if let Some(d) = dense.scenes.damped.as_mut() {
            d.w_cf_h = None;
            d.w_fc_h = None;
        }
        // and without the strikes from rest played back (every new note
        // then runs its strike)
        let mut unstored = prepared.clone();
        unstored.forget_stored_strikes();
        let mut variants: Vec<(&Prepared, String)> = vec![(&prepared, n.to_string())];
        if structured {
            variants.push((&dense, format!("{n}, dense switches")));
        }
        if n >= 200 {
            variants.push((&unstored, format!("{n}, strikes not played back")));
        }
        for chord in [1, 4, 16] {
            for (prepared, label) in &variants {
                if label.contains("back") && chord != 16 {
                    continue;
                }
                let mut cells = Vec::new();
                for block in [32, 64, 128, 512] {
                    cells.push(cell(block_times(prepared, chord, block), block));
                }
                println!("| {label} | {chord} | {} |", cells.join(" | "));
            }
        }
    }
}

/// The same renders with a lookahead (docs/plugin.md, "Lookahead"): the
/// voices run up to that many samples behind the instrument's clock and
/// work ahead only while a block's estimated work fits in 40 % of its
/// budget, so a chord's strikes spread over the blocks after it; the
/// output is the same, the lookahead later. Max / 99.9th percentile, % of
/// the budget, as the table above.
fn lookahead(_: &mut Criterion) {
    println!("\nwith a lookahead, 48 kHz, % of the block's real-time budget (max / 99.9th percentile), {SECONDS} s per cell, each block the least of {RUNS} runs, chords every {CHORD_EVERY_S} s:");
    println!("| modes | chord | lookahead | 32 samples | 64 samples | 128 samples | 512 samples |");
    println!("|---|---|---|---|---|---|---|");
    for (n, chords) in [(50, &[16][..]), (200, &[4, 16][..]), (1000, &[1, 4][..])] {
        let params = InstrumentParams::default();
        let prepared = prepare_scene(&object(n), &params.scene, RATE, 0).expect("compile");
        for &chord in chords {
            for l in [0, 256, 512, 1024, 2048] {
                let mut cells = Vec::new();
                for block in [32, 64, 128, 512] {
                    cells.push(cell(block_times_ahead(&prepared, chord, block, l), block));
                }
                let ms = l as f64 / RATE * 1e3;
                println!(
                    "| {n} | {chord} | {l} ({ms:.1} ms) | {} |",
                    cells.join(" | ")
                );
            }
        }
    }
}

/// The slowest of the 8 blocks after `st.strike`, less one plain block of
/// `plain` (64-sample blocks).
fn strike_block(
    sc: &modal_contact::compile::CompiledScene,
    st: &mut modal_contact::engine::EngineState,
    plain: &mut modal_contact::engine::EngineState,
) -> f64 {
    struck_block(sc, st, plain, |st| st.strike(sc, 0.0, -1.0))
}

/// [`strike_block`] of a strike from rest played back
/// (`EngineState::strike_stored`) on `st`, reset.
fn replay_block(
    sc: &modal_contact::compile::CompiledScene,
    st: &mut modal_contact::engine::EngineState,
    pre: &modal_contact::engine::ScaleProps,
    plain: &mut modal_contact::engine::EngineState,
) -> f64 {
    struck_block(sc, st, plain, |st| assert!(st.strike_stored(sc, 1.0, pre)))
}

/// The slowest of the 8 blocks after `strike(st)`, less one plain block
/// of `plain`.
fn struck_block(
    sc: &modal_contact::compile::CompiledScene,
    st: &mut modal_contact::engine::EngineState,
    plain: &mut modal_contact::engine::EngineState,
    strike: impl FnOnce(&mut modal_contact::engine::EngineState),
) -> f64 {
    let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
    let t0 = Instant::now();
    plain.process_block(sc, &mut l, &mut r);
    let base = t0.elapsed().as_secs_f64();
    strike(st);
    let mut worst = 0.0f64;
    for _ in 0..8 {
        let t0 = Instant::now();
        st.process_block(sc, &mut l, &mut r);
        worst = worst.max(t0.elapsed().as_secs_f64());
    }
    (worst - base).max(0.0)
}

/// The block holding one strike, beyond a plain block, measured on one
/// voice (`EngineState`, 64-sample blocks at 48 kHz, the slowest of the
/// blocks the strike touches, median of 41 strikes): on a ringing voice
/// (two changes of basis: hierarchical where the scene has them, and the
/// same strike through the dense matrices, with their ratio), next to the
/// estimate the plugin logs its warning from
/// (`Prepared::strike_cost_estimate_s`), and on the object at
/// rest (a new note on a voice state reset as the instrument resets its
/// voices: the stored release, docs/numerics.md "A strike on an object at
/// rest"), with the ratio to the same strike through the dense
/// products in the same run, and played back from its recording
/// (`EngineState::strike_stored`, what a new note at a key's pitch does:
/// docs/numerics.md "A strike from rest played back").
fn strike_cost(_: &mut Criterion) {
    use modal_contact::engine::{EngineState, ScaleProps};
    println!("\nstrike cost, one voice, 64-sample blocks at 48 kHz (measured: slowest block of the strike less a plain block; median of 41):");
    println!("| modes | switch multiply-adds (dense) | ringing: measured us | ringing: estimated us | ringing, dense products us | ratio | at rest us | at rest, dense products us | ratio | at rest, played back us |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for n in [10, 50, 100, 200, 400, 1000] {
        let params = InstrumentParams::default();
        let prepared = prepare_scene(&object(n), &params.scene, RATE, 0).expect("compile");
        let sc = &prepared.scenes.scene;
        let mut ringing = EngineState::new(sc);
        ringing.strike(sc, 0.0, -1.0);
        let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
        for _ in 0..200 {
            ringing.process_block(sc, &mut l, &mut r);
        }
        let mut silent = EngineState::new(sc);
        silent.strike(sc, 1.0, 0.0);
        // a new note's voice is one the instrument made ahead and resets
        // (as here), not new memory: a state allocated per strike would pay
        // its first writes' page faults inside the timed block
        let mut at_rest = [true, false].map(|rest| {
            let mut st = EngineState::new(sc);
            st.set_rest_strike(rest);
            st
        });
        // a new note's strike played back from its key's recording (the
        // instrument's path for a voice at rest at a key's pitch)
        let band = 0.45 * RATE;
        let mut pre = ScaleProps::new(sc, 1.0, band);
        let played = pre.store_strike(sc, band, &[0.05, 2.2]);
        let mut replaying = EngineState::new(sc);
        replaying.set_output_band(sc, band);
        let mut extra = [Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new()];
        for _ in 0..41 {
            extra[0].push(strike_block(sc, &mut ringing.clone(), &mut ringing.clone()));
            let mut dense = ringing.clone();
            dense.set_structured_switch(false);
            extra[3].push(strike_block(sc, &mut dense, &mut ringing.clone()));
            for (j, st) in [1, 2].into_iter().zip(at_rest.iter_mut()) {
                st.reset(sc);
                extra[j].push(strike_block(sc, st, &mut silent.clone()));
            }
            if played {
                replaying.reset(sc);
                extra[4].push(replay_block(sc, &mut replaying, &pre, &mut silent.clone()));
            }
        }
        let med = extra.map(|mut e| {
            e.sort_by(f64::total_cmp);
            e.get(20).copied().unwrap_or(f64::NAN)
        });
        println!(
            "| {n} | {} ({}) | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            sc.switch_multiply_adds(),
            2 * sc.free.dim * sc.contact.dim,
            med[0] * 1e6,
            prepared.strike_cost_estimate_s() * 1e6,
            med[3] * 1e6,
            med[3] / med[0],
            med[1] * 1e6,
            med[2] * 1e6,
            med[2] / med[1],
            med[4] * 1e6
        );
    }
}

/// 64 overlapping notes of the heaviest preset (the most states in contact) at
/// the largest polyphony: CPU time per second of audio, as a fraction of
/// one core (median of 5 renders of 2 s, the notes struck in the first
/// 64 ms), without and with the editor's live view (a probe attached and
/// on: the observed block path and each chunk's energy), alternating.
fn polyphony_64(_: &mut Criterion) {
    let mut params = InstrumentParams::default();
    params.play.polyphony = modal_contact::instrument::MAX_VOICES;
    // the heaviest preset: the most coupled states in contact
    let (prepared, name, modes) = modal_contact::presets::one_contact()
        .map(|i| {
            params.scene.preset = i;
            let p = modal_contact::instrument::prepare(&params.scene, RATE, 0).expect("compile");
            let modes = p.scenes.scene.free.dim / 2;
            (p, modal_contact::presets::PRESETS[i].name, modes)
        })
        .max_by_key(|(p, _, _)| p.scenes.scene.contact.dim)
        .expect("presets");
    let total = (2.0 * RATE) as usize;
    let events: Vec<TimedEvent> = (0..64)
        .map(|k| TimedEvent {
            offset: 48 * k,
            event: Event::NoteOn {
                key: 30 + k as u8,
                velocity_norm: 0.8,
            },
        })
        .collect();
    // with the editor's live view open, the voices run the observed block
    // path and hand each chunk's motion to the probe (here one that only
    // reads it: the view's own decimation is left out)
    struct Reader(f64);
    impl VoiceProbe for Reader {
        fn voice_chunk(&mut self, chunk: &VoiceChunk) {
            self.0 +=
                chunk.energy_j.unwrap_or(0.0) + chunk.motion.last().map_or(0.0, |m| m.x_contact);
        }
    }
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..5 {
        for (probe, times) in times.iter_mut().enumerate() {
            let mut inst = Instrument::new(prepared.clone(), params.play);
            if probe == 1 {
                inst.set_probe(Some(Box::new(Reader(0.0))));
                inst.set_probe_on(true);
            }
            let (mut l, mut r) = (vec![0.0f32; 512], vec![0.0f32; 512]);
            let t0 = Instant::now();
            let mut start = 0;
            while start < total {
                let evs: Vec<TimedEvent> = events
                    .iter()
                    .filter(|e| e.offset >= start && e.offset < start + 512)
                    .map(|e| TimedEvent {
                        offset: e.offset - start,
                        event: e.event,
                    })
                    .collect();
                inst.process(&evs, &mut l, &mut r);
                start += 512;
            }
            assert_eq!(inst.stats.steals, 0, "all 64 notes got their own voice");
            times.push(t0.elapsed().as_secs_f64());
        }
    }
    let [plain, probed] = times.map(|mut t| {
        t.sort_by(f64::total_cmp);
        t[2]
    });
    println!(
        "\n64 voices of {name} ({modes} modes, the heaviest preset) at 48 kHz, 512-sample blocks: {:.1} % of one core; with the live view's probe on: {:.1} % (median of 5, alternating)",
        100.0 * plain / 2.0,
        100.0 * probed / 2.0
    );
}

/// Bad input at 64 voices, 64-sample blocks at 48 kHz: all 128 keys at
/// velocity 127 in one block, and a note on every sample of a block
/// (stealing voices mid-contact); the worst block over 1 s (over the 40
/// blocks after the notes for the object at the compile budget's memory
/// limit, 1500 coupled modes: 64 voices of it cost more per sample than a
/// second of audio).
fn bad_input(_: &mut Criterion) {
    println!("\nbad input at 64 voices, 64-sample blocks at 48 kHz, worst block over 1 s (% of the budget):");
    println!(
        "| object | 128 keys at velocity 127 in one block | a note on every sample of a block |"
    );
    println!("|---|---|---|");
    let mut plate = InstrumentParams::default();
    plate.scene.preset = modal_contact::presets::index_of("steel-plate").expect("preset");
    let objects = [
        (
            "steel-plate (29 modes)",
            modal_contact::presets::scene(plate.scene.preset).expect("preset"),
        ),
        ("200 modes", object(200)),
        (
            "1500 modes (the compile budget's memory limit)",
            object(1500),
        ),
    ];
    for (name, scene) in objects {
        let blocks = if name.starts_with("1500") {
            50
        } else {
            RATE as usize / 64
        };
        let mut params = InstrumentParams::default();
        params.play.polyphony = modal_contact::instrument::MAX_VOICES;
        let prepared = prepare_scene(&scene, &params.scene, RATE, 0).expect("compile");
        let chord: Vec<TimedEvent> = (0..128u8)
            .map(|key| TimedEvent {
                offset: 0,
                event: Event::NoteOn {
                    key,
                    velocity_norm: 1.0,
                },
            })
            .collect();
        let run: Vec<TimedEvent> = (0..64usize)
            .map(|i| TimedEvent {
                offset: i,
                event: Event::NoteOn {
                    key: (i * 37 % 128) as u8,
                    velocity_norm: 1.0,
                },
            })
            .collect();
        let mut cells = Vec::new();
        for first in [&chord, &run] {
            let mut inst = Instrument::new(prepared.clone(), params.play);
            let (mut l, mut r) = (vec![0.0f32; 64], vec![0.0f32; 64]);
            let mut worst = 0.0f64;
            for b in 0..blocks {
                let evs: &[TimedEvent] = if b == 10 { first } else { &[] };
                worst = worst.max(timed_process(&mut inst, evs, &mut l, &mut r));
            }
            cells.push(format!("{:.0} %", 100.0 * worst / (64.0 / RATE)));
        }
        println!("| {name} | {} | {} |", cells[0], cells[1]);
    }
}

/// A pitch bend while 16 voices ring: the worst 64-sample block of a
/// 2-semitone glide up and down (every voice gets a new time scale every
/// 16 samples), against the worst block of the same render without the
/// bend, at 48 kHz.
fn pitch_bend(_: &mut Criterion) {
    println!("\npitch bend, 16 voices ringing, 64-sample blocks at 48 kHz, worst block of 0.5 s (% of the budget):");
    println!("| object | without a bend | bending 2 semitones up and back |");
    println!("|---|---|---|");
    let mut plate = InstrumentParams::default();
    plate.scene.preset = modal_contact::presets::index_of("steel-plate").expect("preset");
    let objects = [
        (
            "steel-plate (29 modes)",
            modal_contact::presets::scene(plate.scene.preset).expect("preset"),
        ),
        ("200 modes", object(200)),
    ];
    for (name, scene) in objects {
        let params = InstrumentParams::default();
        let prepared = prepare_scene(&scene, &params.scene, RATE, 0).expect("compile");
        let mut cells = Vec::new();
        for bend in [false, true] {
            let mut best = f64::INFINITY;
            for _ in 0..5 {
                let mut inst = Instrument::new(prepared.clone(), params.play);
                let (mut l, mut r) = (vec![0.0f32; 64], vec![0.0f32; 64]);
                let chord: Vec<TimedEvent> = (0..16u8)
                    .map(|k| TimedEvent {
                        offset: 0,
                        event: Event::NoteOn {
                            key: 48 + 2 * k,
                            velocity_norm: 0.8,
                        },
                    })
                    .collect();
                inst.process(&chord, &mut l, &mut r);
                // let the contacts end
                for _ in 0..40 {
                    inst.process(&[], &mut l, &mut r);
                }
                let mut worst = 0.0f64;
                for b in 0..(RATE as usize / 2 / 64) {
                    let value = match b {
                        0 => 1.0,
                        150 => 0.0,
                        _ => f64::NAN,
                    };
                    let evs = [TimedEvent {
                        offset: 0,
                        event: Event::PitchBend { value },
                    }];
                    let evs: &[TimedEvent] = if bend && !value.is_nan() { &evs } else { &[] };
                    worst = worst.max(timed_process(&mut inst, evs, &mut l, &mut r));
                }
                best = best.min(worst);
            }
            cells.push(format!("{:.0} %", 100.0 * best / (64.0 / RATE)));
        }
        println!("| {name} | {} | {} |", cells[0], cells[1]);
    }
}

/// Every preset as the plugin plays it: the same 16 keys (every other
/// semitone from C3) struck again every [`CHORD_EVERY_S`] on their own
/// voices, still ringing (a strike on a ringing object locates every
/// switch: none is played back; a driven preset's notes are 16 strokes
/// at once), 64-sample blocks at 48 kHz; the worst block and the 99.9th
/// percentile, % of the budget. Each block's time is the least of
/// [`RUNS`] runs of the same deterministic work, so a block the
/// machine interrupted in one run (a pause of about 10 ms spans two
/// 64-sample blocks, which lifts the percentile too) does not stand for
/// the preset's cost.
fn preset_chords(_: &mut Criterion) {
    use modal_contact::instrument::{prepare, SceneParams};
    println!("\npresets, the same 16-note chord struck again every {CHORD_EVERY_S} s on its ringing voices (a driven preset: 16 strokes), 64-sample blocks at 48 kHz, {SECONDS} s, each block the least of {RUNS} runs: worst block, % of the budget (max / 99.9th percentile):");
    println!("| preset | 64 samples |");
    println!("|---|---|");
    let total = (SECONDS * RATE) as usize;
    let evs = chord_events(total);
    for (i, p) in modal_contact::presets::PRESETS.iter().enumerate() {
        let sp = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        let prepared = prepare(&sp, RATE, 0).expect("compile");
        let times = least_of_runs(|| run_blocks(&prepared, &evs, total, 64, 0));
        println!("| {} | {} |", p.name, cell(times, 64));
    }
}

/// The 16-note chord of [`preset_chords`] on presets whose mallet is a
/// stiffening law beside its linear spring (docs/design.md, "Stiffening
/// contacts"): the glockenspiel's brass head (the preset's own law, beside
/// the spring of the same duration at its impact speed that its header
/// derives) and the wood block's hickory tip (made a law here) by Hertz's
/// contact, `F = (4/3) E* sqrt(R) p^1.5`
/// (E* and R as the presets' headers derive them), in three pieces over
/// the penetrations of MIDI velocities 20 to 127 (`((1 + power) m v^2 /
/// (2 K))^(1 / (1 + power))`, the hammer's mass); the piano's felt by
/// Chaigne and Askenfelt's C4 hammer, `F = 4.5e9 p^2.5`, four pieces from
/// 0.05 to 1 mm; marimba-bar's yarn by `F = K p^2` through its spring's
/// force at the deepest of a 2 m/s strike (`K = k / (2 sqrt(m / k))`), four
/// pieces over the penetrations of velocities 20 to 127; and the 200-mode
/// object of [`worst_block`] (issue 51's chord target) with a felt-like
/// `F = K p^2.5` through its spring the same way, four pieces; every piece
/// with the spring's relaxation time `c / k`.
/// A law makes a scene of several contacts, played as a kit: the table
/// says what that costs beside the spring, with no lookahead and with the
/// lookahead that spreads a chord's strikes over the blocks after it
/// (docs/plugin.md, "Lookahead"). The preset rows' method.
fn law_chords(_: &mut Criterion) {
    /// A row's label, its scene and preset index (`None`: a scene that is
    /// no preset), its law's `K` \[N/m^power\] (`None`: through its
    /// spring's force at the deepest of a 2 m/s strike), power and pieces,
    /// and the range of penetrations it follows \[m\] (`None`:
    /// velocities 20 to 127).
    type LawCase = (
        String,
        Scene,
        Option<usize>,
        Option<f64>,
        f64,
        usize,
        Option<(f64, f64)>,
    );
    use modal_contact::instrument::SceneParams;
    println!("\npresets with a stiffening law in place of their spring, the same 16-note chord struck again every {CHORD_EVERY_S} s on its ringing voices, 64-sample blocks at 48 kHz, {SECONDS} s, each block the least of {RUNS} runs: worst block, % of the budget (max / 99.9th percentile), with no lookahead and with a lookahead of 256 and 512 samples (5.3 and 10.7 ms):");
    println!("| preset | law | with the law | with the law, lookahead 256 | with the law, lookahead 512 | with its spring | with its spring, lookahead 256 |");
    println!("|---|---|---|---|---|---|---|");
    let total = (SECONDS * RATE) as usize;
    let evs = chord_events(total);
    let preset = |name: &str, k: Option<f64>, power: f64, pieces: usize, range| -> LawCase {
        let index = modal_contact::presets::index_of(name).expect("preset");
        let scene = modal_contact::presets::scene(index).expect("preset");
        (
            name.to_string(),
            scene,
            Some(index),
            k,
            power,
            pieces,
            range,
        )
    };
    let cases: [LawCase; 5] = [
        preset(
            "glockenspiel-bar",
            Some(4.0 / 3.0 * 74.7e9 * 7.5e-3f64.sqrt()),
            1.5,
            3,
            None,
        ),
        preset(
            "wood-block",
            Some(4.0 / 3.0 * 6.6e9 * 5e-3f64.sqrt()),
            1.5,
            3,
            None,
        ),
        preset("piano-string", Some(4.5e9), 2.5, 4, Some((5e-5, 1e-3))),
        preset("marimba-bar", None, 2.0, 4, None),
        (
            "200 modes".to_string(),
            object(200),
            None,
            None,
            2.5,
            4,
            None,
        ),
    ];
    for (name, spring, index, k, power, pieces, range) in cases {
        let m = spring.hammer.mass_kg;
        let k = k.unwrap_or_else(|| modal_testkit::scenes::law_k_through_spring(&spring));
        let travel = |v| modal_testkit::scenes::power_law_travel(m, k, power, v);
        let (from, up_to) = range.unwrap_or((travel(0.12), travel(3.0)));
        // a preset that has its law already (glockenspiel-bar) plays it as
        // written, beside the linear spring of the same duration at its
        // impact speed that its header derives (and it had before)
        let (scene, spring) = match (&spring.contact.law, name.as_str()) {
            (Some(_), "glockenspiel-bar") => {
                let mut linear = spring.clone();
                linear.contact.law = None;
                (
                    linear.contact.stiffness_n_per_m,
                    linear.contact.damping_n_s_per_m,
                ) = (4.25e7, 77.1);
                (spring, linear)
            }
            (Some(_), _) => panic!("{name}: a preset with a law needs its header's spring here"),
            (None, _) => (
                modal_testkit::scenes::with_power_law(&spring, (power, k), pieces, (from, up_to)),
                spring,
            ),
        };
        let sp = SceneParams {
            preset: index.unwrap_or(SceneParams::default().preset),
            ..SceneParams::default()
        };
        let with_law = prepare_scene(&scene, &sp, RATE, 0).expect("compile");
        let with_spring = prepare_scene(&spring, &sp, RATE, 0).expect("compile");
        let mut cells = Vec::new();
        for (prepared, ahead) in [
            (&with_law, 0),
            (&with_law, 256),
            (&with_law, 512),
            (&with_spring, 0),
            (&with_spring, 256),
        ] {
            let times = least_of_runs(|| run_blocks(prepared, &evs, total, 64, ahead));
            cells.push(cell(times, 64));
        }
        println!(
            "| {name} | F ~ p^{power}, {pieces} pieces, {from:.2e} to {up_to:.2e} m | {} |",
            cells.join(" | ")
        );
    }
}

/// The same 16-note chord (keys 48 to 78, every other key, velocity 100)
/// every [`CHORD_EVERY_S`] over `total` samples.
fn chord_events(total: usize) -> Vec<TimedEvent> {
    let every = (CHORD_EVERY_S * RATE) as usize;
    (0..total)
        .step_by(every)
        .flat_map(|at| {
            (0..16u8).map(move |k| TimedEvent {
                offset: at,
                event: Event::NoteOn {
                    key: 48 + 2 * k,
                    velocity_norm: 100.0 / 127.0,
                },
            })
        })
        .collect()
}

/// A 16-note chord struck in one 64-sample block at 48 kHz on presets,
/// without and with a brightness on every note at its onset (each voice
/// moved to another hardness level's scene before its first contact,
/// docs/plugin.md "Brightness"): the chord's block in microseconds, median
/// of 41.
fn brightness_chord(_: &mut Criterion) {
    use modal_contact::instrument::{prepare, SceneParams};
    println!("\n16-note chord in one 64-sample block at 48 kHz (budget 1333 us), median of 41:");
    println!("| preset | chord us | chord with a brightness on every note us |");
    println!("|---|---|---|");
    for name in ["marimba-bar", "steel-plate", "frame-drum", "paper-string"] {
        let sp = SceneParams {
            preset: modal_contact::presets::index_of(name).expect("preset"),
            ..SceneParams::default()
        };
        let prepared = prepare(&sp, RATE, 0).expect("compile");
        let mut cells = Vec::new();
        for bright in [false, true] {
            let mut times = Vec::new();
            for _ in 0..41 {
                let mut inst = Instrument::new(prepared.clone(), InstrumentParams::default().play);
                let mut evs = Vec::new();
                for k in 0..16u8 {
                    let key = 48 + 2 * k;
                    evs.push(TimedEvent {
                        offset: 0,
                        event: Event::NoteOn {
                            key,
                            velocity_norm: 0.8,
                        },
                    });
                    if bright {
                        evs.push(TimedEvent {
                            offset: 0,
                            event: Event::NoteBrightness {
                                key: Some(key),
                                value: 0.9,
                            },
                        });
                    }
                }
                let (mut l, mut r) = (vec![0.0f32; 64], vec![0.0f32; 64]);
                times.push(timed_process(&mut inst, &evs, &mut l, &mut r));
            }
            times.sort_by(f64::total_cmp);
            cells.push(format!("{:.0}", times[20] * 1e6));
        }
        println!("| {name} | {} | {} |", cells[0], cells[1]);
    }
}

/// The time of one `inst.process(evs, l, r)` call \[s\]; its output
/// checked finite after the clock stops.
fn timed_process(inst: &mut Instrument, evs: &[TimedEvent], l: &mut [f32], r: &mut [f32]) -> f64 {
    let t0 = Instant::now();
    inst.process(evs, l, r);
    let t = t0.elapsed().as_secs_f64();
    assert!(l.iter().chain(r.iter()).all(|x| x.is_finite()));
    t
}

/// One note through the instrument, as a player plays it: the first
/// 64-sample block of a fresh instrument's note (note-on, the strike from
/// rest, the block's stepping) at the object's root and higher, where the
/// output band leaves the top modes out (docs/design.md, "The
/// instrument": what the worker made ahead for each key). Median of 21,
/// microseconds; the budget is 1333 us.
fn note_block(_: &mut Criterion) {
    println!("\none note through the instrument, its first 64-sample block at 48 kHz (us, median of 21; budget 1333 us):");
    println!("| modes | at the root | 15 semitones up | 27 semitones up |");
    println!("|---|---|---|---|");
    for n in [200, 1000] {
        let params = InstrumentParams::default();
        let prepared = prepare_scene(&object(n), &params.scene, RATE, 0).expect("compile");
        let root = prepared.root_note.round() as i32;
        let mut cells = Vec::new();
        for up in [0, 15, 27] {
            let key = (root + up).clamp(0, 127) as u8;
            let evs = [TimedEvent {
                offset: 0,
                event: Event::NoteOn {
                    key,
                    velocity_norm: 100.0 / 127.0,
                },
            }];
            let mut times = Vec::new();
            for _ in 0..21 {
                let mut inst = Instrument::new(prepared.clone(), params.play);
                let (mut l, mut r) = (vec![0.0f32; 64], vec![0.0f32; 64]);
                inst.process(&[], &mut l, &mut r);
                times.push(timed_process(&mut inst, &evs, &mut l, &mut r));
            }
            times.sort_by(f64::total_cmp);
            cells.push(format!("{:.0}", times[10] * 1e6));
        }
        println!("| {n} | {} | {} | {} |", cells[0], cells[1], cells[2]);
    }
}

criterion_group!(
    benches,
    strike_cost,
    note_block,
    polyphony_64,
    bad_input,
    pitch_bend,
    brightness_chord,
    preset_chords,
    law_chords,
    worst_block,
    lookahead
);
criterion_main!(benches);
