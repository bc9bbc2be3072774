//! The render command against the engine alone (docs/design.md, "Offline
//! rendering"): per sample, the command's WAV-only render, its render with
//! the plot, and with the trace CSV and the plot, at 10, 100 and 1000
//! modes, and with the trace as NumPy `.npy` and the plot, against
//! `EngineState::process_block` over the same samples. The
//! compile is left out of both (it is printed by the command separately),
//! and each timed render writes new files (the last ones are deleted first,
//! untimed).
//!
//! `cargo bench -p xtask --bench render_command` prints criterion's
//! timings and, at the end, the ratios measured in one run with the
//! variants interleaved (A B C D E A B C D E ...), median of the repetitions:
//! per sample (the slope between two lengths) and the fixed cost of one
//! render beside it (`-- summary` prints only those), and the CSV's text
//! alone: the same rows through the render's CSV writer with every core
//! free of the engine, into no file (the floor of the CSV render on this
//! machine: shortest round-trip digits of six numbers per row).

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};
use modal_contact::compile::{compile_one, CompiledScene};
use modal_contact::engine::{EngineState, Motion};
use modal_contact::render::{render_stream, CsvTrace, TraceSink};
use modal_contact::scene::Scene;
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;
use xtask::render::{render_scene_to, SceneOutputs};

const RATE: f64 = 44100.0;

/// A modal object of `n` modes struck once by a hammer that falls from
/// 1 mm at 1 m/s, bounces off and flies away.
fn struck(n: usize) -> Scene {
    let mut object = Modal::new("o", &["c", "p"]);
    for i in 0..n {
        let f = 80.0 * (18000.0f64 / 80.0).powf(i as f64 / (n.max(2) - 1) as f64);
        let w = 1.0 / (1.0 + 0.01 * i as f64).sqrt();
        let wp = if i % 2 == 0 { 0.7 * w } else { -0.5 * w };
        object = object.mode(f, 2.0 / (1.0 + f / 2000.0), &[w, wp]);
    }
    SceneBuilder::new("bench")
        .object(object)
        .hammer(Hammer::new(0.02).height(1e-3).velocity(-1.0))
        .contact(Contact::new("o", 1e6).point("c").damping(5.0))
        .pickup(Pickup::new("o", "p"))
        .build()
}

/// Long enough that the per-render costs (creating the files, drawing the
/// plot) do not hide the per-sample ones: 10 s at 10 modes, 4 s at 100,
/// 1 s at 1000.
fn samples(n_modes: usize) -> usize {
    let seconds = match n_modes {
        0..=10 => 10.0,
        11..=100 => 4.0,
        _ => 1.0,
    };
    (seconds * RATE) as usize
}

fn engine_only(sc: &CompiledScene, n: usize) -> f64 {
    let mut st = EngineState::new(sc);
    let (mut l, mut r) = (vec![0.0; 4096], vec![0.0; 4096]);
    let mut done = 0;
    let mut acc = 0.0;
    while done < n {
        let k = 4096.min(n - done);
        st.process_block(sc, &mut l[..k], &mut r[..k]);
        acc += l[k - 1];
        done += k;
    }
    acc
}

#[derive(Clone, Copy, Debug)]
enum Variant {
    Engine,
    Wav,
    WavPlot,
    WavTracePlot,
    WavNpyPlot,
}

const VARIANTS: [Variant; 5] = [
    Variant::Engine,
    Variant::Wav,
    Variant::WavPlot,
    Variant::WavTracePlot,
    Variant::WavNpyPlot,
];

fn run(v: Variant, sc: &CompiledScene, n: usize, dir: &std::path::Path) {
    let wav = dir.join("bench.wav");
    let csv = dir.join("bench.csv");
    let svg = dir.join("bench.svg");
    let npy = dir.join("bench.npy");
    let out = match v {
        Variant::Engine => {
            black_box(engine_only(sc, n));
            return;
        }
        Variant::Wav => SceneOutputs {
            wav: Some(&wav),
            ..Default::default()
        },
        Variant::WavPlot => SceneOutputs {
            wav: Some(&wav),
            plot: Some((&svg, "bench")),
            ..Default::default()
        },
        Variant::WavTracePlot => SceneOutputs {
            wav: Some(&wav),
            trace: Some(&csv),
            plot: Some((&svg, "bench")),
        },
        Variant::WavNpyPlot => SceneOutputs {
            wav: Some(&wav),
            trace: Some(&npy),
            plot: Some((&svg, "bench")),
        },
    };
    black_box(render_scene_to(sc, n, &out, &|_| {}).expect("render"));
}

/// Every sample's motion and energy, kept in memory (the block path's, as
/// the CSV render takes them).
#[derive(Default)]
struct Keep(Vec<(Motion, f64)>);

impl TraceSink for Keep {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, _: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.0.push((*m, e.expect("asked for")));
        Ok(())
    }
    fn record_driven(
        &mut self,
        i: usize,
        m: &Motion,
        e: Option<f64>,
        _: [f64; 2],
    ) -> std::io::Result<()> {
        self.record(i, m, e)
    }
}

/// The CSV's text alone: the first `n` kept rows through the render's CSV
/// writer (its formatting threads on every core, no engine beside them)
/// into `io::sink` (no disk). What the CSV render cannot go below.
fn text_alone(rows: &[(Motion, f64)], n: usize) {
    let mut csv = CsvTrace::new(RATE, std::io::sink()).expect("csv");
    for (i, (m, e)) in rows[..n].iter().enumerate() {
        csv.record(i, m, Some(*e)).expect("record");
    }
    csv.finish().expect("finish");
}

/// Remove the last render's files, so that each timed render writes new
/// ones (overwriting a file first truncates it, which costs the kernel time
/// in proportion to the old file, not to the render: docs/design.md,
/// "Offline rendering").
fn fresh(dir: &std::path::Path) {
    for f in ["bench.wav", "bench.csv", "bench.svg", "bench.npy"] {
        let _ = std::fs::remove_file(dir.join(f));
    }
}

fn scratch() -> PathBuf {
    let d = std::env::temp_dir().join(format!("render-command-bench-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn command(c: &mut Criterion) {
    let dir = scratch();
    let mut g = c.benchmark_group("render_command");
    g.sample_size(10);
    g.measurement_time(std::time::Duration::from_secs(3));
    for n_modes in [10, 100, 1000] {
        let sc = compile_one(&struck(n_modes), RATE).expect("compile");
        let n = samples(n_modes);
        g.throughput(Throughput::Elements(n as u64));
        for v in VARIANTS {
            g.bench_with_input(
                BenchmarkId::new(format!("{v:?}"), n_modes),
                &n_modes,
                |b, _| {
                    b.iter_batched(
                        || fresh(&dir),
                        |_| run(v, &sc, n, &dir),
                        BatchSize::PerIteration,
                    )
                },
            );
        }
    }
    g.finish();
}

/// Per-sample ratios to the engine and each variant's fixed cost per
/// render, the variants interleaved, median of 7 rounds. Each variant runs
/// at two lengths, `L` and `3 L`: its cost per sample is the difference of
/// the two times over `2 L` samples (what one more sample costs, whatever
/// the render's length), its fixed cost what is left of the `L` render
/// (creating the files, starting the trace threads, drawing the plot's
/// 1024 buckets).
fn summary(_: &mut Criterion) {
    let dir = scratch();
    println!(
        "\nrender command per sample (marginal: lengths L and 3 L), ratio to the engine alone, median of 7 interleaved rounds:"
    );
    println!("| modes | engine ns/sample | WAV only | WAV + plot | WAV + trace CSV + plot | CSV text alone | WAV + trace NPY + plot | engine x real time | fixed ms per render (WAV / plot / CSV + plot / NPY + plot) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for n_modes in [10, 100, 1000] {
        let sc = compile_one(&struck(n_modes), RATE).expect("compile");
        let n = samples(n_modes);
        // [variant][round] of (time at L, time at 3 L)
        let mut short = [[0.0f64; 7]; 5];
        let mut slope = [[0.0f64; 7]; 5];
        let mut kept = Keep::default();
        render_stream(&sc, 3 * n, |_, _| Ok(()), Some(&mut kept)).expect("rows");
        let mut text = [0.0f64; 7];
        for round in 0..7 {
            let t0 = Instant::now();
            text_alone(&kept.0, n);
            let t1 = t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            text_alone(&kept.0, 3 * n);
            text[round] = (t0.elapsed().as_secs_f64() - t1) / (2 * n) as f64;
            for (k, v) in VARIANTS.iter().enumerate() {
                fresh(&dir);
                let t0 = Instant::now();
                run(*v, &sc, n, &dir);
                let t1 = t0.elapsed().as_secs_f64();
                fresh(&dir);
                let t0 = Instant::now();
                run(*v, &sc, 3 * n, &dir);
                let t3 = t0.elapsed().as_secs_f64();
                short[k][round] = t1;
                slope[k][round] = (t3 - t1) / (2 * n) as f64;
            }
        }
        let med = |xs: &[f64; 7]| {
            let mut xs = *xs;
            xs.sort_by(f64::total_cmp);
            xs[3]
        };
        let per: Vec<f64> = slope.iter().map(med).collect();
        // what is left of the L render beyond its per-sample cost, beyond
        // the engine's own (a few allocations)
        let intercept = |k: usize| {
            let mut f = [0.0; 7];
            for (r, fr) in f.iter_mut().enumerate() {
                *fr = short[k][r] - slope[k][r] * n as f64;
            }
            med(&f)
        };
        let fixed: Vec<f64> = (0..5)
            .map(|k| (intercept(k) - intercept(0)) * 1e3)
            .collect();
        println!(
            "| {n_modes} | {:.1} | {:.2}x | {:.2}x | {:.2}x | {:.2}x | {:.2}x | {:.0}x | {:.1} / {:.1} / {:.1} / {:.1} |",
            per[0] * 1e9,
            per[1] / per[0],
            per[2] / per[0],
            per[3] / per[0],
            med(&text) / per[0],
            per[4] / per[0],
            1.0 / (RATE * per[0]),
            fixed[1],
            fixed[2],
            fixed[3],
            fixed[4],
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, command, summary);
criterion_main!(benches);
