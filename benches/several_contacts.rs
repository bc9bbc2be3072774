//! Criterion benchmark of the several-contact engine (`src/multi/`,
//! docs/numerics.md section 14): the cost of one switch with 2, 3 and 4
//! contacts on a 100-mode object, as the difference between a sample in
//! which a hammer meets the object (the event search and the change of
//! basis) and the same sample with that hammer far away (the plain step and
//! every contact's check), both measured in the same run; and, printed
//! once, the time to compile every phase. Beside it, the worst block of
//! the instrument playing each kit preset (docs/design.md, "Played as a
//! kit"), and each several-contact preset's render in blocks on the block
//! path against the same engine searching every sample (docs/numerics.md
//! section 14, "The block path"), in the same run; and strikes on a
//! ringing 200-mode object through a law in four pieces with the switches'
//! products structured and dense (docs/numerics.md section 14,
//! "Structured switches"). Timing is reported, never asserted.

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use modal_contact::multi::{CompiledMulti, MultiHammer, MultiModel, MultiState};
use std::hint::black_box;
use std::time::Instant;

const RATE: f64 = 48_000.0;
const MODES: usize = 100;

/// Runs of the same work timed block by block: each block's time is the
/// least of these many runs (a pause of the machine's in one run does not
/// stand for the work's cost; the worst-block bench's rule).
const RUNS: usize = 3;

/// `run()`'s per-block times, each the least of [`RUNS`] runs.
fn least_of_runs(mut run: impl FnMut() -> Vec<f64>) -> Vec<f64> {
    let mut times = run();
    for _ in 1..RUNS {
        for (t, a) in times.iter_mut().zip(run()) {
            *t = t.min(a);
        }
    }
    times
}

/// `k` hammers on a 100-mode object; hammer 0 `height` above it at 1 m/s
/// down, the others 1 m above it.
fn model(k: usize, height: f64) -> MultiModel {
    let n = MODES;
    let freq: Vec<f64> = (0..n)
        .map(|i| 80.0 * (18000.0f64 / 80.0).powf(i as f64 / (n - 1) as f64))
        .collect();
    let hammers = (0..k)
        .map(|j| MultiHammer {
            mass_kg: 0.02,
            height_m: if j == 0 { height } else { 1.0 },
            velocity_m_per_s: -1.0,
            weights: (0..n)
                .map(|i| {
                    (1.0 + 0.3 * j as f64) * ((i * (j + 2)) as f64 * 0.37).cos()
                        / (1.0 + 0.01 * i as f64).sqrt()
                })
                .collect(),
            stiffness_n_per_m: 1e6,
            damping_n_s_per_m: 20.0,
        })
        .collect::<Vec<_>>();
    MultiModel::struck(
        freq.clone(),
        freq.iter().map(|f| 0.5 + f * 1e-3).collect(),
        &hammers,
        0.0,
        [(vec![0.0; n], vec![1.0; n]), (vec![0.0; n], vec![0.5; n])],
    )
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("several_contacts");
    let mut lines = Vec::new();
    for k in [2, 3, 4] {
        let t0 = Instant::now();
        let meet = CompiledMulti::new(&model(k, 5e-6), RATE).unwrap();
        let compile_s = t0.elapsed().as_secs_f64();
        let far = CompiledMulti::new(&model(k, 1.0), RATE).unwrap();
        // the state one sample before the meeting (5 um at 1 m/s: 0.24
        // samples into the next one)
        let at_meet = MultiState::new(&meet);
        {
            let mut probe = at_meet.clone();
            probe.step(&meet);
            assert_eq!(
                probe.stats.switches, 1,
                "{k} contacts: one switch in the sample"
            );
        }
        let at_far = MultiState::new(&far);
        g.bench_with_input(BenchmarkId::new("sample_with_a_switch", k), &k, |b, _| {
            b.iter_batched(
                || at_meet.clone(),
                |mut st| {
                    st.step(black_box(&meet));
                    st
                },
                BatchSize::SmallInput,
            )
        });
        g.bench_with_input(BenchmarkId::new("plain_sample", k), &k, |b, _| {
            b.iter_batched(
                || at_far.clone(),
                |mut st| {
                    st.step(black_box(&far));
                    st
                },
                BatchSize::SmallInput,
            )
        });
        lines.push(format!(
            "{k} contacts, {MODES} modes: {} phases of up to {} coordinates compiled in {:.2} s",
            meet.phases.len(),
            meet.max_dim(),
            compile_s
        ));
    }
    g.finish();
    println!("\n{}", lines.join("\n"));
    println!("per switch: sample_with_a_switch minus plain_sample, same run (criterion's estimates above)");
}

/// The kit presets through the instrument (`Instrument::process`, what the
/// plugin calls per host block) at 48 kHz for 4 s: notes every 125 ms
/// (one at a time, or 4 or 16 keys at one instant: as many kit voices at
/// their pitches, each throwing its next mallet; an unpitched kit's one
/// voice throws the mallets the keys list), in blocks of 32, 64, 128 and 512 samples. Printed:
/// the largest and the 99.9th percentile block, % of the block's real-time
/// budget, and the kit's whole render against real time.
fn kits(_: &mut Criterion) {
    use modal_contact::instrument::{
        prepare, Event, Instrument, InstrumentParams, SceneParams, TimedEvent,
    };
    use modal_contact::presets;
    let seconds = 4.0;
    let total = (seconds * RATE) as usize;
    println!("\nkits: worst block at 48 kHz, % of the block's budget (max / 99.9th percentile), notes every 125 ms, each block the least of {RUNS} runs:");
    println!("| kit | keys at once | 32 samples | 64 samples | 128 samples | 512 samples | render vs real time (64) |");
    println!("|---|---|---|---|---|---|---|");
    for i in (0..presets::COUNT).filter(|&i| presets::is_kit(i)) {
        let sp = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        let prepared = prepare(&sp, RATE, 0).expect("a kit");
        for chord in [1usize, 4, 16] {
            let mut cells = Vec::new();
            let mut realtime = 0.0;
            for block in [32usize, 64, 128, 512] {
                // each block the least of RUNS runs of the same work: a
                // pause of the machine's does not stand for the kit's cost
                let mut times = least_of_runs(|| {
                    let mut inst =
                        Instrument::new(prepared.clone(), InstrumentParams::default().play);
                    let every = (0.125 * RATE) as usize;
                    let (mut l, mut r) = (vec![0.0f32; block], vec![0.0f32; block]);
                    let mut times = Vec::with_capacity(total / block + 1);
                    let mut start = 0;
                    let mut evs: Vec<TimedEvent> = Vec::with_capacity(8);
                    let mut k = 0;
                    while start < total {
                        let len = block.min(total - start);
                        evs.clear();
                        let next = start.div_ceil(every) * every;
                        if next < start + len {
                            for j in 0..chord {
                                evs.push(TimedEvent {
                                    offset: next - start,
                                    event: Event::NoteOn {
                                        key: (48 + 2 * j + k % 3) as u8,
                                        velocity_norm: 0.5 + 0.4 * ((k * 7 + j) % 5) as f64 / 4.0,
                                    },
                                });
                            }
                            k += 1;
                        }
                        let t0 = Instant::now();
                        inst.process(&evs, &mut l[..len], &mut r[..len]);
                        times.push(t0.elapsed().as_secs_f64());
                        black_box(&l);
                        start += len;
                    }
                    times
                });
                if block == 64 {
                    realtime = seconds / times.iter().sum::<f64>();
                }
                times.sort_by(f64::total_cmp);
                let budget = block as f64 / RATE;
                let p999 = times[((times.len() - 1) as f64 * 0.999).round() as usize];
                cells.push(format!(
                    "{:.0} / {:.0}",
                    100.0 * times[times.len() - 1] / budget,
                    100.0 * p999 / budget
                ));
            }
            println!(
                "| {} | {chord} | {} | {realtime:.0}x |",
                presets::NAMES[i],
                cells.join(" | ")
            );
        }
    }
}

/// Each several-contact preset as written, 2 s at 48 kHz in blocks of 64
/// (`MultiState::process_block`), on the block path and with every sample
/// searched (`set_block_path(false)`), alternated five times; printed: the
/// median time per sample of each and their ratio.
fn block_path(_: &mut Criterion) {
    use modal_contact::scene::Scene;
    println!("\nblock path: several-contact presets, 2 s at 48 kHz in blocks of 64 (median of 5, alternated):");
    println!("| preset | block path [ns/sample] | every sample searched [ns/sample] | ratio |");
    println!("|---|---|---|---|");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in [
        "ball-between-plates",
        "marimba-two-mallets",
        "snare-pair",
        "wind-chimes",
    ] {
        let scene = Scene::from_file(&root.join(format!("presets/{name}.toml"))).unwrap();
        let model = MultiModel::from_scene(&scene, RATE).unwrap();
        let sw = scene.contact.switching.unwrap_or_default();
        let sc = CompiledMulti::with_switching(&model, RATE, sw).unwrap();
        let n = (2.0 * RATE) as usize;
        let run = |block_path: bool| {
            let mut st = MultiState::new(&sc);
            st.set_block_path(block_path);
            let (mut l, mut r) = ([0.0; 64], [0.0; 64]);
            let t0 = Instant::now();
            for _ in 0..n / 64 {
                st.process_block(&sc, &mut l, &mut r);
                black_box(&l);
            }
            t0.elapsed().as_secs_f64() * 1e9 / n as f64
        };
        let (mut on, mut off) = (Vec::new(), Vec::new());
        for _ in 0..5 {
            on.push(run(true));
            off.push(run(false));
        }
        on.sort_by(f64::total_cmp);
        off.sort_by(f64::total_cmp);
        println!(
            "| {name} | {:.0} | {:.0} | {:.2} |",
            on[2],
            off[2],
            off[2] / on[2]
        );
    }
}

/// Strikes on the ringing 200-mode object of the worst-block bench
/// (`modal_testkit::scenes::struck_bar`) through `F = K p^2.5` in four
/// and in eight pieces, K through its spring's force at the deepest of a 2 m/s strike,
/// the pieces over the penetrations of 0.12 to 3 m/s (the worst-block
/// bench's table of laws, its last row): 40 strikes at 1 to 1.8 m/s, each
/// timed with its next eight 64-sample blocks, with the switches' products
/// in hierarchical form (`CompiledMulti` as compiled) and dense
/// (`forget_structured`), alternated; printed: the median per strike.
fn structured(_: &mut Criterion) {
    use modal_testkit::scenes::{law_k_through_spring, power_law_travel, with_power_law};
    let spring = modal_testkit::scenes::struck_bar(200, 2.0);
    let power = 2.5;
    let k = law_k_through_spring(&spring);
    let travel = |v| power_law_travel(spring.hammer.mass_kg, k, power, v);
    let mut rows = Vec::new();
    let (mut notes, mut dim) = (Vec::new(), 0);
    for pieces in [4, 8] {
        let scene = with_power_law(&spring, (power, k), pieces, (travel(0.12), travel(3.0)));
        let model = MultiModel::from_scene(&scene, RATE).unwrap();
        let t0 = Instant::now();
        let sc = CompiledMulti::new(&model, RATE).unwrap();
        let compile_s = t0.elapsed().as_secs_f64();
        dim = dim.max(sc.max_dim());
        let mut dense = sc.clone();
        dense.forget_structured();
        let (n, all) = sc.structured_products();
        if pieces == 4 {
            // the same law with every combination of its pieces compiled,
            // the ones never reached too
            let t0 = Instant::now();
            let every = CompiledMulti::with_every_phase(&model, RATE).unwrap();
            let every_s = t0.elapsed().as_secs_f64();
            notes.push(format!(
                "4 pieces: {every_s:.2} s for all {} combinations of the pieces",
                every.phases.len()
            ));
        }
        let (mut a, mut b, mut per) = (Vec::new(), Vec::new(), 0.0);
        for _ in 0..3 {
            let (t, sw) = strikes_on_ringing(&sc);
            a.push(t);
            per = sw;
            b.push(strikes_on_ringing(&dense).0);
        }
        a.sort_by(f64::total_cmp);
        b.sort_by(f64::total_cmp);
        rows.push(format!(
            "| {pieces} | {} | {compile_s:.2} | {n} of {all} | {per:.1} | {:.0} | {:.0} | {:.2} |",
            sc.phases.len(),
            a[1] * 1e6,
            b[1] * 1e6,
            b[1] / a[1]
        ));
    }
    println!("\nstrikes through a law on a ringing 200-mode object (phases: those that can be reached, of up to {dim} coordinates; {}): a strike and its next eight 64-sample blocks at 48 kHz, median of 40 strikes, the middle of 3 alternated runs:", notes.join("; "));
    println!("| pieces | phases | compile s | switch products in hierarchical form | switches per strike | structured products us | dense products us | ratio |");
    println!("|---|---|---|---|---|---|---|---|");
    for r in rows {
        println!("{r}");
    }
}

/// 40 strikes on the ringing object of `sc` at 1 to 1.8 m/s, each timed
/// with its next eight 64-sample blocks: the median time \[s\] and the
/// switches per strike.
fn strikes_on_ringing(sc: &CompiledMulti) -> (f64, f64) {
    let mut st = MultiState::new(sc);
    let (mut l, mut r) = ([0.0; 64], [0.0; 64]);
    st.strike(sc, 0, 0.0, -2.0).unwrap();
    for _ in 0..200 {
        st.process_block(sc, &mut l, &mut r);
    }
    let sw0 = st.stats.switches;
    let mut times = Vec::new();
    for i in 0..40 {
        let t = Instant::now();
        st.strike(sc, 0, 0.0, -(1.0 + 0.02 * f64::from(i))).unwrap();
        for _ in 0..8 {
            st.process_block(sc, &mut l, &mut r);
            black_box(&l);
        }
        times.push(t.elapsed().as_secs_f64());
        for _ in 0..40 {
            st.process_block(sc, &mut l, &mut r);
        }
    }
    times.sort_by(f64::total_cmp);
    (times[20], (st.stats.switches - sw0) as f64 / 40.0)
}

criterion_group!(benches, bench, kits, block_path, structured);
criterion_main!(benches);
