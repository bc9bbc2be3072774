//! Criterion benchmarks of the per-sample engine (issue: "make the per-sample
//! engine fast"). Every group measures this engine next to a naive baseline in
//! the same run: multiplying the dense transition matrix every sample (the
//! paper's transition matrix used literally), and a summary at the end
//! prints the ratios, ns per mode per sample and the SIMD path that ran.
//! Timing is reported here, never asserted in tests.
//!
//! The engine is driven the way the plugin drives it: `process_block` on
//! blocks of samples. The phase cases hold one phase for the whole run (free:
//! the hammer flies away from a ringing object; contact: a weight rests on a
//! vibrating object at its static equilibrium, with a vibration too small to
//! lift it), so they measure that phase and nothing else; switches are
//! measured on their own (the change of basis, and a whole sample with a
//! located impact), and the preset renders show everything together.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use modal_contact::compile::{compile_with, CompiledScene};
use modal_contact::engine::EngineState;
use modal_contact::physics::decomp::dense_exp;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::scenes::{preset, Contact, Hammer, Modal, Pickup, SceneBuilder};
use nalgebra::{DMatrix, DVector};
use std::hint::black_box;
use std::time::Instant;

const RATE: f64 = 44100.0;
const BLOCK: usize = 441; // 10 ms per iteration

fn modal_scene(n: usize, gravity: bool) -> Scene {
    let mut object = Modal::new("o", &["c", "p"]);
    for i in 0..n {
        let f = 80.0 * (18000.0f64 / 80.0).powf(i as f64 / (n.max(2) - 1) as f64);
        let w = 1.0 / (1.0 + 0.01 * i as f64).sqrt();
        let wp = if i % 2 == 0 { 0.7 * w } else { -0.5 * w };
        object = object.mode(f, 1000.0 / (1.0 + f / 1000.0), &[w, wp]);
    }
    let hammer = if gravity {
        // a heavy weight resting on the object: continuous contact
        Hammer::new(0.5).velocity(-0.1).gravity(9.81)
    } else {
        // hammer flying away: the free phase only
        Hammer::new(0.02).height(1.0).velocity(1.0)
    };
    SceneBuilder::new("bench")
        .object(object)
        .hammer(hammer)
        .contact(Contact::new("o", 1e6).point("c").damping(50.0))
        .pickup(Pickup::new("o", "p"))
        .build()
}

/// The naive baseline: dense transition matrices of the free object (plus a
/// ballistic hammer) and of the contact system, multiplied every sample in
/// physical energy coordinates, offset-rod switching.
struct NaiveDense {
    phi_f: DMatrix<f64>,
    phi_c: DMatrix<f64>,
    y: DVector<f64>,
    tmp: DVector<f64>,
    out: DVector<f64>,
}

impl NaiveDense {
    fn new(sc: &CompiledScene, contact: bool) -> Self {
        let ph = if contact { &sc.contact } else { &sc.free };
        let dim = ph.dim;
        // the same generator as the engine's phase, in energy coordinates
        let a = match (&ph.gens, &ph.dense) {
            (_, Some((a, _))) => a.clone(),
            (Some(g), None) => {
                let nb = g.len();
                let mut gm = DMatrix::zeros(dim, dim);
                for (k, b) in g.iter().enumerate() {
                    gm[(k, k)] = b[0];
                    gm[(k, nb + k)] = b[1];
                    gm[(nb + k, k)] = b[2];
                    gm[(nb + k, nb + k)] = b[3];
                }
                let vinv = &ph.vinv;
                &ph.v * gm * vinv
            }
            _ => unreachable!(),
        };
        let phi = dense_exp(&a, sc.h).unwrap();
        let out = &ph.v.transpose() * DVector::from_vec(ph.rows.vel_l.clone());
        Self {
            phi_f: phi.clone(),
            phi_c: phi,
            y: DVector::from_fn(dim, |i, _| 1e-3 * ((i % 7) as f64 - 3.0)),
            tmp: DVector::zeros(dim),
            out,
        }
    }
    fn run(&mut self, n: usize, contact: bool) -> f64 {
        let phi = if contact { &self.phi_c } else { &self.phi_f };
        let mut acc = 0.0;
        for _ in 0..n {
            phi.mul_to(&self.y, &mut self.tmp);
            std::mem::swap(&mut self.y, &mut self.tmp);
            acc += self.out.dot(&self.y);
        }
        acc
    }
}

/// A state in the requested phase: free (a ringing object, the hammer flying
/// away) or contact (resting at the static equilibrium under gravity with a
/// vibration of half the size that could lift the weight).
fn engine_in(sc: &CompiledScene, contact: bool) -> EngineState {
    let mut st = EngineState::new(sc);
    if !contact {
        let n = sc.free.dim / 2;
        let s = st.free_state_mut();
        for k in 0..n {
            s[n + k] = 1e-3;
        }
    } else {
        let dim = sc.contact.dim;
        let pattern: Vec<f64> = (0..dim).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let y = &sc.contact.v * DVector::from_vec(pattern.clone());
        let p_static = sc.offsets.pi / sc.sk;
        let scale = 0.5 * sc.sk * p_static / y.norm();
        let s = st.rest_in_contact();
        for (x, p) in s.iter_mut().zip(&pattern) {
            *x = p * scale;
        }
    }
    st
}

/// `n` samples in host-like blocks of [`BLOCK`]; returns a checksum.
fn run_engine(st: &mut EngineState, sc: &CompiledScene, n: usize) -> f64 {
    let mut l = [0.0; BLOCK];
    let mut r = [0.0; BLOCK];
    let mut acc = 0.0;
    let mut left = n;
    while left > 0 {
        let m = left.min(BLOCK);
        st.process_block(sc, &mut l[..m], &mut r[..m]);
        acc += l[0] + r[m - 1];
        left -= m;
    }
    acc
}

/// A 100-mode object and a hammer one sample before it hits: the next
/// sample holds a located impact (event search, root, partial steps, change
/// of basis).
fn before_impact() -> (CompiledScene, EngineState) {
    let sc = compile_with(&modal_scene(100, false), RATE, Some(Switching::Exact)).unwrap();
    let mut st = engine_in(&sc, false);
    // hammer 2 mm above the surface, coming down at 1 m/s
    st.strike(&sc, 2e-3, -1.0);
    loop {
        let mut probe = st.clone();
        probe.tick(&sc);
        if probe.contacts_started > 0 {
            return (sc, st);
        }
        st.tick(&sc);
    }
}

fn phases(c: &mut Criterion) {
    for contact in [false, true] {
        let name = if contact {
            "contact_phase"
        } else {
            "free_phase"
        };
        let mut g = c.benchmark_group(name);
        g.sample_size(10);
        for n in [10usize, 100, 1000] {
            let sc = compile_with(&modal_scene(n, contact), RATE, Some(Switching::Exact)).unwrap();
            g.throughput(Throughput::Elements((BLOCK * n) as u64));
            let mut st = engine_in(&sc, contact);
            g.bench_with_input(BenchmarkId::new("engine", n), &n, |b, _| {
                b.iter(|| black_box(run_engine(&mut st, &sc, BLOCK)))
            });
            assert_eq!(st.in_contact(), contact, "the phase must not change");
            let mut naive = NaiveDense::new(&sc, contact);
            g.bench_with_input(BenchmarkId::new("naive_dense", n), &n, |b, _| {
                b.iter(|| black_box(naive.run(BLOCK, contact)))
            });
        }
        g.finish();
    }
}

fn switch(c: &mut Criterion) {
    let sc = compile_with(&modal_scene(100, false), RATE, Some(Switching::Exact)).unwrap();
    let mut st = engine_in(&sc, false);
    let mut g = c.benchmark_group("switch_100_modes");
    g.bench_function("change_of_basis_enter_and_leave", |b| {
        b.iter(|| st.bench_switch_pair(black_box(&sc)))
    });
    let (sc, before) = before_impact();
    g.bench_function("located_impact_sample", |b| {
        b.iter_batched(
            || before.clone(),
            |mut st| black_box(st.tick(&sc)),
            criterion::BatchSize::SmallInput,
        )
    });
    g.finish();
}

/// An `n`-mode object (200 Hz to 1.5x Nyquist, undamped) with a 10 g
/// hammer dropped from 1 mm under gravity onto it through a critically
/// damped contact at `ratio` times Nyquist: it rattles (hundreds of short
/// contacts), the hardest work of the exact event search.
fn rattle_scene(n: usize, ratio: f64) -> Scene {
    let mut object = Modal::new("o", &["c", "p"]);
    let top = 1.5 * RATE / 2.0;
    for i in 0..n {
        let f = if n == 1 {
            200.0
        } else {
            200.0 * (top / 200.0).powf(i as f64 / (n - 1) as f64)
        };
        let w = 0.7 / (1.0 + 0.05 * i as f64).sqrt();
        object = object.mode(f, None, &[w, 0.5 * w]);
    }
    let m_h = 0.01f64;
    let k = m_h * (2.0 * std::f64::consts::PI * ratio * RATE / 2.0).powi(2);
    let c = 2.0 * (k * m_h).sqrt();
    SceneBuilder::new("rattle")
        .object(object)
        .hammer(Hammer::new(m_h).height(0.001).gravity(9.81))
        .contact(Contact::new("o", k).point("c").damping(c))
        .pickup(Pickup::new("o", "p"))
        .build()
}

/// The most expensive sample of the first `n` samples of a run from `st`
/// (the fastest of three timings per sample, so a preemption does not
/// pick it): the state just before it, its index, and the search nodes
/// and switches it holds.
fn worst_sample(sc: &CompiledScene, st: &EngineState, n: usize) -> (EngineState, usize, u64, u64) {
    let mut best = vec![f64::INFINITY; n];
    for _ in 0..3 {
        let mut s = st.clone();
        for b in best.iter_mut() {
            let t0 = Instant::now();
            black_box(s.tick(sc));
            *b = b.min(t0.elapsed().as_secs_f64());
        }
    }
    let i = (0..n).max_by(|&a, &b| best[a].total_cmp(&best[b])).unwrap();
    let mut s = st.clone();
    for _ in 0..i {
        s.tick(sc);
    }
    let before = s.clone();
    let (n0, l0) = (s.exact_stats.search_nodes, s.exact_stats.located);
    s.tick(sc);
    (
        before,
        i,
        s.exact_stats.search_nodes - n0,
        s.exact_stats.located - l0,
    )
}

/// The exact event search at its hardest: the worst sample of 50 ms of
/// rattling on 10 and 100 modes with the contact at 10x, 100x and 1000x
/// Nyquist (criterion times that one sample, from a copy of the state).
fn event_search(c: &mut Criterion) {
    let mut g = c.benchmark_group("event_search_worst_sample");
    g.sample_size(20);
    for n in [10usize, 100] {
        for ratio in [10.0, 100.0, 1000.0] {
            let sc = compile_with(&rattle_scene(n, ratio), RATE, Some(Switching::Exact)).unwrap();
            let (before, ..) = worst_sample(&sc, &EngineState::new(&sc), 2205);
            g.bench_function(
                BenchmarkId::new(format!("{n}_modes"), format!("{ratio}x_nyquist")),
                |b| {
                    b.iter_batched(
                        || before.clone(),
                        |mut st| black_box(st.tick(&sc)),
                        criterion::BatchSize::SmallInput,
                    )
                },
            );
        }
    }
    g.finish();
}

/// The worst sample of each preset, struck at full velocity, at Hardness
/// (contact stiffness factor) 0.01 .. 100, over the first 100 ms:
/// microseconds and fraction of the 44.1 kHz sample period.
fn presets_at_every_hardness() {
    use modal_contact::instrument::{impact_speed_m_per_s, scene_for, InstrumentParams};
    let period_us = 1e6 / RATE;
    println!("worst sample of a full-velocity strike, first 100 ms, per Hardness (us; sample period {period_us:.1} us):");
    let hardness = [0.01, 0.1, 1.0, 10.0, 100.0];
    println!(
        "  {:<18} {}",
        "preset",
        hardness.map(|h| format!("{h:>14}")).join("")
    );
    let mut worst_all: f64 = 0.0;
    // the kits' switches are the several-contact benchmark's
    for i in modal_contact::presets::one_contact() {
        let preset = &modal_contact::presets::PRESETS[i];
        let base = modal_contact::presets::scene(i).unwrap();
        let mut cells = String::new();
        for &hf in &hardness {
            let mut p = InstrumentParams::default();
            p.scene.preset = i;
            p.scene.stiffness_factor = hf;
            let sc = compile_with(&scene_for(&base, &p), RATE, None).unwrap();
            let mut st = EngineState::new(&sc);
            let speed = impact_speed_m_per_s(1.0);
            if base.hammer.gravity_m_per_s2 > 0.0 {
                st.strike(&sc, p.play.drop_height_m, -speed);
            } else {
                st.strike(&sc, 0.0, -speed);
            }
            let (before, ..) = worst_sample(&sc, &st, 4410);
            let t = median_time(31, || {
                let mut s = before.clone();
                black_box(s.tick(&sc));
            });
            worst_all = worst_all.max(t * 1e6);
            cells += &format!("{:>8.1} ({:>3.0}%)", t * 1e6, 100.0 * t * 1e6 / period_us);
        }
        println!("  {:<18} {cells}", preset.name);
    }
    println!(
        "  worst over all presets and Hardness settings: {worst_all:.1} us = {:.0} % of a sample period",
        100.0 * worst_all / period_us
    );
}

fn renders(c: &mut Criterion) {
    let mut g = c.benchmark_group("render_1s");
    g.sample_size(10);
    for name in ["paper-bounce", "paper-string"] {
        let scene = preset(name);
        let sc = compile_with(&scene, RATE, None).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut st = EngineState::new(&sc);
                black_box(run_engine(&mut st, &sc, 44100))
            })
        });
    }
    g.finish();
}

fn voices(c: &mut Criterion) {
    let sc = compile_with(&modal_scene(200, false), RATE, Some(Switching::Exact)).unwrap();
    let mut g = c.benchmark_group("voices_16x200_modes_1s");
    g.sample_size(10);
    let mut vs = sixteen_voices(&sc);
    g.bench_function("engine", |b| {
        b.iter(|| black_box(run_voices(&mut vs, &sc, 44100)))
    });
    g.finish();
}

/// A 200-mode object whose modes have decayed into the subnormal range of
/// f64 (1e-310, as fast modes reach about 10 s after a strike while a slow
/// one keeps the voice alive), with the engine's flush of subnormals on or
/// off.
fn subnormal_tail(sc: &CompiledScene, flush: bool) -> EngineState {
    let mut st = engine_in(sc, false);
    st.set_flush_denormals(flush);
    let n = sc.free.dim / 2;
    let s = st.free_state_mut();
    for k in 0..n {
        s[k] = 1e-310;
        s[n + k] = -1e-310;
    }
    st
}

fn tail(c: &mut Criterion) {
    let sc = compile_with(&modal_scene(200, false), RATE, Some(Switching::Exact)).unwrap();
    let mut g = c.benchmark_group("subnormal_tail_200_modes");
    g.sample_size(10);
    g.throughput(Throughput::Elements((BLOCK * 200) as u64));
    for flush in [true, false] {
        let mut st = subnormal_tail(&sc, flush);
        let name = if flush { "flushed" } else { "not_flushed" };
        g.bench_function(name, |b| {
            b.iter(|| black_box(run_engine(&mut st, &sc, BLOCK)))
        });
    }
    g.finish();
}

/// Median wall time of `f` over `runs` runs [s].
fn median_time(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(|a, b| a.total_cmp(b));
    t[runs / 2]
}

/// 16 voices at different pitches, rendered like the instrument does: in
/// chunks of 64 samples, voice after voice.
fn run_voices(vs: &mut [EngineState], sc: &CompiledScene, n: usize) -> f64 {
    let mut l = [0.0; 64];
    let mut r = [0.0; 64];
    let mut acc = 0.0;
    let mut left = n;
    while left > 0 {
        let m = left.min(64);
        for st in vs.iter_mut() {
            st.process_block(sc, &mut l[..m], &mut r[..m]);
            acc += l[0];
        }
        left -= m;
    }
    acc
}

fn sixteen_voices(sc: &CompiledScene) -> Vec<EngineState> {
    (0..16)
        .map(|i| {
            let mut st = engine_in(sc, false);
            st.set_time_scale(sc, 2f64.powf(i as f64 / 12.0 - 0.5))
                .unwrap();
            st
        })
        .collect()
}

/// Ratios against the naive baseline, measured in this run.
fn summary(_c: &mut Criterion) {
    let path = modal_contact::engine::fastest_kernels();
    println!(
        "\n=== summary (median of 5, this run; SIMD path: {}) ===",
        path
    );
    let n_samp = 44100;
    summary_kernels(n_samp);
    summary_switch();
    summary_event_search();
    presets_at_every_hardness();
    summary_renders();
    let sc = compile_with(&modal_scene(200, false), RATE, Some(Switching::Exact)).unwrap();
    summary_voices(&sc);
    summary_compile();
    summary_subnormal(&sc, n_samp);
}

/// The engine's time per mode and sample against the naive dense
/// baseline's, in flight and in contact, over `n_samp` samples.
fn summary_kernels(n_samp: usize) {
    for contact in [false, true] {
        for n in [10usize, 100, 1000] {
            let sc = compile_with(&modal_scene(n, contact), RATE, Some(Switching::Exact)).unwrap();
            let mut st = engine_in(&sc, contact);
            let te = median_time(5, || {
                black_box(run_engine(&mut st, &sc, n_samp));
            });
            assert_eq!(st.in_contact(), contact, "the phase must not change");
            let mut generic = engine_in(&sc, contact);
            generic.set_portable_kernels(true);
            let tg = median_time(5, || {
                black_box(run_engine(&mut generic, &sc, n_samp));
            });
            let mut naive = NaiveDense::new(&sc, contact);
            let samples_naive = if n >= 1000 { 441 } else { n_samp };
            let tn = median_time(3, || {
                black_box(naive.run(samples_naive, contact));
            }) * (n_samp / samples_naive) as f64;
            let per = |t: f64| t / (n_samp * n) as f64 * 1e9;
            println!(
                "{:<8} {n:>5} modes: engine {:.3} ns/mode/sample (generic path {:.3}), naive dense {:.2} ns/mode/sample, ratio {:.0}x",
                if contact { "contact" } else { "free" },
                per(te),
                per(tg),
                per(tn),
                tn / te
            );
        }
    }
}

/// The cost of a switch at 100 modes: the change of basis alone, and a
/// whole sample with a located impact.
fn summary_switch() {
    let sc = compile_with(&modal_scene(100, false), RATE, Some(Switching::Exact)).unwrap();
    let mut st = engine_in(&sc, false);
    let ts = median_time(5, || {
        for _ in 0..1000 {
            st.bench_switch_pair(&sc);
        }
    }) / 2000.0;
    println!(
        "switch at 100 modes: change of basis {:.2} us per switch",
        ts * 1e6
    );
    let (sc, before) = before_impact();
    let mut plain = before.clone();
    let t_plain = median_time(5, || {
        black_box(run_engine(&mut plain, &sc, 1));
    });
    let mut sweeps = 0;
    let mut times: Vec<f64> = (0..2001)
        .map(|_| {
            let mut st = before.clone();
            let t0 = Instant::now();
            black_box(st.tick(&sc));
            let t = t0.elapsed().as_secs_f64();
            assert_eq!(st.contacts_started, 1);
            sweeps = st.exact_stats.partial_sweeps;
            t
        })
        .collect();
    times.sort_by(|a, b| a.total_cmp(b));
    println!(
        "switch at 100 modes: a sample with a located impact (search, root, partial steps, change of basis) {:.2} us (median of 2001; {sweeps} sweeps of exp(G tau); a plain sample {:.2} us)",
        times[1000] * 1e6,
        t_plain * 1e6
    );
}

/// The exact event search's worst sample in 50 ms of rattling, at 10 and
/// 100 modes and three contact stiffnesses.
fn summary_event_search() {
    println!("exact event search, worst sample of 50 ms of rattling (a 10 g hammer dropped 1 mm, critically damped contact):");
    for n in [10usize, 100] {
        for ratio in [10.0, 100.0, 1000.0] {
            let sc = compile_with(&rattle_scene(n, ratio), RATE, Some(Switching::Exact)).unwrap();
            let st0 = EngineState::new(&sc);
            let (before, i, nodes, switches) = worst_sample(&sc, &st0, 2205);
            let t = median_time(101, || {
                let mut s = before.clone();
                black_box(s.tick(&sc));
            });
            let mut all = st0.clone();
            let t_all = median_time(3, || {
                let mut s = all.clone();
                black_box(run_engine(&mut s, &sc, 2205));
            });
            all = st0;
            black_box(run_engine(&mut all, &sc, 2205));
            println!(
                "  {n:>3} modes, contact at {ratio:>6}x Nyquist: worst sample {:.1} us (sample {i}: {nodes} nodes, {switches} switches; {:.1}x the 22.7 us period); 50 ms in {:.2} ms, {} contacts, at most {} nodes in a sample",
                t * 1e6,
                t * RATE,
                t_all * 1e3,
                all.contacts_started,
                all.exact_stats.max_nodes_in_sample
            );
        }
    }
}

/// The paper's two presets and every driven one (a ball rolling, a
/// guiro scraped, a brush drawn: the surface read and its affine input
/// every sample) rendered whole, against real time, and per sample.
fn summary_renders() {
    let driven = modal_testkit::scenes::driven_presets();
    for name in ["paper-bounce", "paper-string"].into_iter().chain(driven) {
        let scene = preset(name);
        let sc = compile_with(&scene, RATE, None).unwrap();
        let secs = scene.duration_s;
        let n = (secs * RATE) as usize;
        let t = median_time(5, || {
            let mut st = EngineState::new(&sc);
            black_box(run_engine(&mut st, &sc, n));
        });
        println!(
            "render {name} ({secs} s): {:.2} ms, {:.0}x faster than real time, {:.0} ns per sample",
            t * 1e3,
            secs / t,
            t * 1e9 / n as f64
        );
    }
}

/// Sixteen voices of the 200-mode scene `sc`: the share of one core they
/// take in real time.
fn summary_voices(sc: &CompiledScene) {
    let mut vs = sixteen_voices(sc);
    let t = median_time(5, || {
        black_box(run_voices(&mut vs, sc, 44100));
    });
    println!(
        "16 voices x 200 modes: {:.1} % of one core for real time",
        t * 100.0
    );
}

/// The compile time of a modal object and its contact system, at 100, 400
/// and 1000 modes.
fn summary_compile() {
    for (n, runs) in [(100usize, 5usize), (400, 3), (1000, 1)] {
        let scene = modal_scene(n, false);
        let t = median_time(runs, || {
            black_box(compile_with(&scene, RATE, Some(Switching::Exact)).unwrap());
        });
        println!(
            "compile (off the audio thread) of a {n}-mode object and its contact system: {t:.2} s{}",
            if runs == 1 { " (one run)" } else { "" }
        );
    }
}

/// The 200-mode scene `sc` decaying in the subnormal range, with and
/// without the flush, over `n_samp` samples.
fn summary_subnormal(sc: &CompiledScene, n_samp: usize) {
    let per_mode = |flush: bool| {
        let mut st = subnormal_tail(sc, flush);
        median_time(5, || {
            black_box(run_engine(&mut st, sc, n_samp));
        }) / (n_samp * 200) as f64
            * 1e9
    };
    let (on, off) = (per_mode(true), per_mode(false));
    println!(
        "200 modes in the subnormal range: {on:.3} ns/mode/sample with the flush (the default), \
         {off:.3} without ({:.1}x)",
        off / on
    );
}

criterion_group!(
    benches,
    phases,
    switch,
    event_search,
    renders,
    voices,
    tail,
    summary
);
criterion_main!(benches);
