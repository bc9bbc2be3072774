//! Criterion benchmark of the several-contact engine (`src/multi.rs`,
//! docs/numerics.md section 14): the cost of one switch with 2, 3 and 4
//! contacts on a 100-mode object, as the difference between a sample in
//! which a hammer meets the object (the event search and the change of
//! basis) and the same sample with that hammer far away (the plain step and
//! every contact's check), both measured in the same run; and, printed
//! once, the time to compile every phase. Timing is reported, never
//! asserted.

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use modal_contact::multi::{CompiledMulti, MultiHammer, MultiModel, MultiState};
use std::hint::black_box;
use std::time::Instant;

const RATE: f64 = 48_000.0;
const MODES: usize = 100;

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

criterion_group!(benches, bench);
criterion_main!(benches);
