//! Tests of the offline render: the CSV's numbers, the streamed and
//! traced paths against the per-sample rows, the trace files and the
//! several-contact render.

use super::csv::CSV_CHUNK_ROWS;
use super::stream::contact_motion;
use super::*;
use crate::compile::compile_with;
use crate::engine::Observation;
use crate::multi::MultiState;
use crate::test_rng::TestRng;
use std::io::Write;

fn text(x: f64) -> String {
    let mut buf = Vec::new();
    push_numbers(&mut buf, &[x], |_| b"");
    String::from_utf8(buf).unwrap()
}

/// Significant digits of a number's text (`-0.00120e3` -> 3).
fn digits(s: &str) -> usize {
    let mantissa = s.split(['e', 'E']).next().unwrap();
    let d: String = mantissa.chars().filter(char::is_ascii_digit).collect();
    let d = d.trim_start_matches('0').trim_end_matches('0');
    d.len().max(1)
}

/// The CSV's numbers read back bit for bit, with the fewest digits
/// (as many as core's shortest `{:e}`): special values, every power of
/// ten, sample times, numbers with short exact expansions (where two
/// shortest candidates can tie), random bit patterns (every magnitude,
/// subnormals included) and random numbers of audio-like magnitudes;
/// a few spellings pinned; six at a time as a row writes them.
#[test]
fn csv_numbers_read_back_exactly_with_the_fewest_digits() {
    let mut cases = vec![
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.1,
        100.0,
        123.456,
        1e-7,
        1.5e16,
        1e21,
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        2.2675736961451248e-5,
        120.0,
        1234567.0,
        -0.25,
        9.999e-6,
        1e-5,
        1e-4,
        1e15,
        1e16,
        2e-320,
    ];
    cases.extend((-320..=308).map(|k| 10f64.powi(k)));
    cases.extend((0..100_000).map(|i| f64::from(i) / 44100.0));
    cases.extend((0..100_000).map(|i| f64::from(i) / 48000.0));
    cases.extend((1..20_000).map(|i| f64::from(i) / 1024.0 - 7.0));
    cases.extend((1..20_000).map(|i| f64::from(i) * 2f64.powi(60)));
    let mut rng = TestRng(7);
    for _ in 0..300_000 {
        let x = f64::from_bits(rng.next_u64());
        if x.is_finite() {
            cases.push(x);
        }
        let mag = 10f64.powf(rng.uniform(-30.0, 17.0));
        cases.push(rng.uniform(-0.5, 0.5) * mag);
    }
    for &x in &cases {
        let s = text(x);
        let back: f64 = s.parse().unwrap_or_else(|e| panic!("{s:?}: {e}"));
        assert_eq!(back.to_bits(), x.to_bits(), "{s:?} for {x:e}");
        assert_eq!(digits(&s), digits(&format!("{x:e}")), "{s:?} for {x:e}");
    }
    for (x, s) in [
        (0.0, "0.0"),
        (-0.0, "-0.0"),
        (0.00036, "0.00036"),
        (-123.5, "-123.5"),
        (1.5e-7, "1.5e-7"),
        (1e20, "1e+20"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
    ] {
        assert_eq!(text(x), s);
    }
    for six in cases.chunks_exact(6) {
        let mut got = Vec::new();
        push_numbers(&mut got, six, |_| b",");
        let want: String = six.iter().map(|&x| text(x) + ",").collect();
        assert_eq!(String::from_utf8(got).unwrap(), want);
    }
}

/// The left channel of a streamed render into `sink`.
fn stream_left(compiled: &CompiledScene, n: usize, sink: &mut dyn TraceSink) -> Vec<f64> {
    let mut left = Vec::new();
    render_stream(
        compiled,
        n,
        |l, _| {
            left.extend_from_slice(l);
            Ok(())
        },
        Some(sink),
    )
    .unwrap();
    left
}

/// The CSV's rows, parsed back.
fn parse_csv(bytes: &[u8]) -> Vec<TraceRow> {
    let text = std::str::from_utf8(bytes).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(TRACE_HEADER));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let x = |i: usize| f[i].parse::<f64>().unwrap();
            TraceRow {
                t: x(0),
                obs: Observation {
                    x_hammer: x(1),
                    v_hammer: x(2),
                    x_contact: x(3),
                    v_contact: x(4),
                    in_contact: f[5] == "1",
                    energy: x(6),
                },
                surface: [0.0; 2],
            }
        })
        .collect()
}

/// Largest deviation of `got` from `want`, per column relative to the
/// column's range over the render (energy: to its largest value);
/// times and contact flags must be equal.
fn worst_row_deviation(got: &[TraceRow], want: &[TraceRow]) -> [f64; 5] {
    assert_eq!(got.len(), want.len());
    let cols: [fn(&TraceRow) -> f64; 5] = [
        |r| r.obs.x_hammer,
        |r| r.obs.v_hammer,
        |r| r.obs.x_contact,
        |r| r.obs.v_contact,
        |r| r.obs.energy,
    ];
    cols.map(|f| {
        let (lo, hi) = want
            .iter()
            .map(f)
            .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
        let scale = if f(&want[0]) == want[0].obs.energy {
            hi.abs().max(lo.abs())
        } else {
            hi - lo
        }
        .max(1e-300);
        got.iter()
            .zip(want)
            .map(|(g, w)| {
                assert_eq!(g.t, w.t);
                assert_eq!(
                    g.obs.in_contact, w.obs.in_contact,
                    "contact flag at t = {}",
                    w.t
                );
                (f(g) - f(w)).abs() / scale
            })
            .fold(0.0, f64::max)
    })
}

/// The trace CSV comes from the block path with the kernel's motion and
/// energy (O(N) per sample where the phase allows): on presets with one
/// strike, bounces under gravity, a string (dense phases) and a wood
/// block, with both switching methods, it gives the same audio bit for
/// bit as the per-sample path and the same rows up to the order of the
/// sums (1e-12 of each column's range; measured below 1e-15), and its
/// energy never increases by more than the per-sample path's does.
#[test]
fn traced_block_path_matches_the_per_sample_rows() {
    for name in ["steel-plate", "paper-bounce", "paper-string", "wood-block"] {
        for sw in [Switching::Exact, Switching::OffsetRod] {
            let scene = crate::presets::scene(crate::presets::index_of(name).unwrap()).unwrap();
            let compiled = compile_with(&scene, 44100.0, Some(sw)).unwrap();
            let n = 30_000;
            let full = render_compiled(&compiled, n, true);
            let want = full.trace.unwrap();
            let mut csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
            let left = stream_left(&compiled, n, &mut csv);
            assert_eq!(left, full.left, "{name} {sw:?}: audio");
            let got = parse_csv(&csv.finish().unwrap());
            let worst = worst_row_deviation(&got, &want);
            let rise = |rows: &[TraceRow]| {
                rows.windows(2)
                    .map(|w| (w[1].obs.energy - w[0].obs.energy) / w[0].obs.energy.abs())
                    .fold(f64::MIN, f64::max)
            };
            let (rg, rw) = (rise(&got), rise(&want));
            println!(
                "{name} {sw:?}: worst deviation (x_h, v_h, x_c, v_c, E) {:.1e} {:.1e} {:.1e} {:.1e} {:.1e}; \
                 largest energy rise per sample {rg:.1e} (per-sample path {rw:.1e})",
                worst[0], worst[1], worst[2], worst[3], worst[4]
            );
            assert!(
                worst.iter().all(|&w| w <= 1e-12),
                "{name} {sw:?}: {worst:?}"
            );
            assert!(rg <= rw.max(0.0) + 1e-15, "{name} {sw:?}: {rg:e} vs {rw:e}");
        }
    }
}

/// A writer that fails after `left` bytes.
struct FailAfter {
    left: usize,
}

impl Write for FailAfter {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if b.len() > self.left {
            return Err(std::io::Error::other("disk full"));
        }
        self.left -= b.len();
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The render stopped and `finish` said why.
fn check_failed(streamed: std::io::Result<()>, finished: std::io::Result<()>) {
    let msg = format!(
        "{:?} / {:?}",
        streamed.as_ref().err(),
        finished.as_ref().err()
    );
    assert!(streamed.is_err(), "the render went on: {msg}");
    assert!(
        finished
            .err()
            .is_some_and(|e| e.to_string().contains("disk full")),
        "{msg}"
    );
}

/// A failed write of the trace's writer thread (CSV or NumPy) stops the
/// render with that error (not a hang, not a silent short file), and a
/// sink dropped without `finish` leaves no thread behind.
#[test]
fn trace_write_errors_reach_the_render() {
    let scene = crate::presets::scene(crate::presets::index_of("steel-plate").unwrap()).unwrap();
    let compiled = compile_with(&scene, 44100.0, None).unwrap();
    let n = 20 * CSV_CHUNK_ROWS;
    let csv = CsvTrace::new(44100.0, FailAfter { left: 200_000 }).unwrap();
    let npy = NpyTrace::new(44100.0, n, FailAfter { left: 200_000 }).unwrap();
    let mut csv = csv;
    let streamed = render_stream(
        &compiled,
        n,
        |_, _| Ok(()),
        Some(&mut csv as &mut dyn TraceSink),
    );
    let finished = csv.finish().map(drop);
    check_failed(streamed.map(drop), finished);
    let mut npy = npy;
    let streamed = render_stream(
        &compiled,
        n,
        |_, _| Ok(()),
        Some(&mut npy as &mut dyn TraceSink),
    );
    let finished = npy.finish().map(drop);
    check_failed(streamed.map(drop), finished);
    // dropped mid-way: joins its writer
    let mut csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
    for i in 0..3 * CSV_CHUNK_ROWS {
        csv.record(i, &Motion::default(), Some(0.0)).unwrap();
    }
    drop(csv);
    let mut npy = NpyTrace::new(44100.0, n, Vec::new()).unwrap();
    for i in 0..3 * CSV_CHUNK_ROWS {
        npy.record(i, &Motion::default(), Some(0.0)).unwrap();
    }
    drop(npy);
}

/// Streaming gives the in-memory render's samples and rows, whatever
/// the sink: the block path and the observed path agree bit for bit
/// with the per-sample path, and the CSV written as it goes holds the
/// same rows up to the order of the sums.
#[test]
fn streamed_render_matches_in_memory_render() {
    let scene = crate::presets::scene(crate::presets::index_of("steel-plate").unwrap()).unwrap();
    let compiled = compile_with(&scene, 44100.0, None).unwrap();
    let n = 3 * STREAM_CHUNK + 17;
    let full = render_compiled(&compiled, n, true);
    let plain = render_compiled(&compiled, n, false);
    assert_eq!(full.left, plain.left);
    assert_eq!(full.right, plain.right);
    let mut want = Vec::new();
    write_trace_csv(full.trace.as_ref().unwrap(), &mut want).unwrap();
    let mut csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
    let mut env = TraceEnvelope::new(44100.0, n);
    let mut both = (csv, env);
    let left = stream_left(&compiled, n, &mut both);
    (csv, env) = both;
    assert_eq!(left, full.left);
    let got = parse_csv(&csv.finish().unwrap());
    assert!(worst_row_deviation(&got, &full.trace.as_ref().unwrap()[..])
        .iter()
        .all(|&w| w <= 1e-12));
    assert_eq!(parse_csv(&want).len(), n);
    // the envelope saw what the CSV saw (the same block path), bit for
    // bit: every sample in one bucket, min/max and energy right
    let rows = got;
    assert_eq!(env.buckets.iter().map(|b| b.len).sum::<usize>(), n);
    assert!(env.buckets.len() <= ENVELOPE_BUCKETS);
    assert_eq!(env.energy_start, rows[0].obs.energy);
    for b in &env.buckets {
        let span = &rows[b.start..b.start + b.len];
        let lo = span
            .iter()
            .map(|r| r.obs.x_contact)
            .fold(f64::INFINITY, f64::min);
        let hi = span
            .iter()
            .map(|r| r.obs.x_contact)
            .fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(b.x_contact, [lo, hi]);
        assert_eq!(b.in_contact, span.iter().any(|r| r.obs.in_contact));
        assert_eq!(b.energy_end, span.last().unwrap().obs.energy);
    }
    assert!(env.buckets.iter().any(|b| b.in_contact));
}

/// The CSV written by several formatting threads (chunks formatted side
/// by side, written in order) is byte for byte the one written on one
/// thread, for 1, 2 and 5 threads and lengths around the chunk size.
#[test]
fn csv_from_several_formatting_threads_is_the_one_thread_csv() {
    let mut rng = TestRng(11);
    let rows: Vec<TraceRow> = (0..7 * CSV_CHUNK_ROWS + 5)
        .map(|i| TraceRow {
            t: i as f64 / 48000.0,
            obs: Observation {
                x_hammer: rng.uniform(-1e-3, 1e-3),
                v_hammer: rng.uniform(-2.0, 2.0),
                x_contact: rng.uniform(-1e-5, 1e-5),
                v_contact: rng.uniform(-1e-2, 1e-2),
                in_contact: rng.uniform(0.0, 1.0) < 0.1,
                energy: rng.uniform(0.0, 1e-2),
            },
            surface: [0.0; 2],
        })
        .collect();
    for n in [0, 1, CSV_CHUNK_ROWS, CSV_CHUNK_ROWS + 1, rows.len()] {
        let mut want = Vec::new();
        write_trace_csv(&rows[..n], &mut want).unwrap();
        for threads in [1, 2, 5] {
            let mut csv = CsvTrace::with_formatters(48000.0, Vec::new(), threads).unwrap();
            for (i, r) in rows[..n].iter().enumerate() {
                let m = Motion {
                    x_hammer: r.obs.x_hammer,
                    v_hammer: r.obs.v_hammer,
                    x_contact: r.obs.x_contact,
                    v_contact: r.obs.v_contact,
                    in_contact: r.obs.in_contact,
                };
                csv.record(i, &m, Some(r.obs.energy)).unwrap();
            }
            assert!(csv.finish().unwrap() == want, "{n} rows, {threads} threads");
        }
    }
}

/// The envelope built from runs of samples (`record_run`, what the
/// traced render hands it) is the one built sample by sample, for
/// renders shorter and longer than its 1024 buckets and runs that
/// start and end anywhere in a bucket.
#[test]
fn envelope_from_runs_is_the_envelope_from_samples() {
    let mut rng = TestRng(5);
    for samples in [1, 7, 1000, 1024, 1025, 5000, 70_001] {
        let motion: Vec<Motion> = (0..samples)
            .map(|_| Motion {
                x_hammer: rng.uniform(-1.0, 1.0),
                v_hammer: 0.0,
                x_contact: rng.uniform(-1.0, 1.0),
                v_contact: 0.0,
                in_contact: rng.uniform(0.0, 1.0) < 0.01,
            })
            .collect();
        let energy: Vec<f64> = (0..samples).map(|_| rng.uniform(0.0, 1.0)).collect();
        let mut want = TraceEnvelope::new(44100.0, samples);
        for (i, m) in motion.iter().enumerate() {
            let e = want.wants_energy(i).then_some(energy[i]);
            want.record(i, m, e).unwrap();
        }
        let mut got = TraceEnvelope::new(44100.0, samples);
        let mut at = 0;
        while at < samples {
            let len = (1 + (rng.uniform(0.0, 1.0) * 3000.0) as usize).min(samples - at);
            got.record_run(at, &motion[at..at + len], &energy[at..at + len])
                .unwrap();
            at += len;
        }
        assert_eq!(got.energy_start, want.energy_start, "{samples}");
        assert_eq!(got.buckets, want.buckets, "{samples}");
    }
}

/// The NPY trace holds the CSV trace's numbers bit for bit (the CSV's
/// shortest digits read back exactly), under a NumPy v1.0 header that
/// names the CSV's columns, with the row count, padded to 64 bytes; a
/// trace with fewer rows than its header is an error.
#[test]
fn npy_trace_is_the_csv_trace_in_binary() {
    let scene = crate::presets::scene(crate::presets::index_of("paper-bounce").unwrap()).unwrap();
    let compiled = compile_with(&scene, 44100.0, None).unwrap();
    let n = 2 * CSV_CHUNK_ROWS + 123;
    let csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
    let npy = NpyTrace::new(44100.0, n, Vec::new()).unwrap();
    let mut both = (csv, npy);
    stream_left(&compiled, n, &mut both);
    let (csv, npy) = both;
    let rows = parse_csv(&csv.finish().unwrap());
    let bytes = npy.finish().unwrap();
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let hlen = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
    assert_eq!((10 + hlen) % 64, 0);
    let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
    assert!(header.ends_with('\n'), "{header:?}");
    assert_eq!(
        header.trim_end(),
        format!(
            "{{'descr': [('t', '<f8'), ('x_hammer', '<f8'), ('v_hammer', '<f8'), \
             ('x_contact', '<f8'), ('v_contact', '<f8'), ('in_contact', '<f8'), \
             ('energy', '<f8')], 'fortran_order': False, 'shape': ({n},), }}"
        )
    );
    let body = &bytes[10 + hlen..];
    assert_eq!(body.len(), n * NpyTrace::<Vec<u8>>::RECORD);
    assert_eq!(rows.len(), n);
    let mut contacts = 0;
    for (rec, r) in body.chunks_exact(56).zip(&rows) {
        let f = |k: usize| f64::from_le_bytes(rec[8 * k..8 * k + 8].try_into().unwrap());
        let o = &r.obs;
        let want = [r.t, o.x_hammer, o.v_hammer, o.x_contact, o.v_contact];
        for (k, w) in want.into_iter().enumerate() {
            assert_eq!(f(k).to_bits(), w.to_bits(), "column {k} at t = {}", r.t);
        }
        assert_eq!(f(5), if o.in_contact { 1.0 } else { 0.0 });
        assert_eq!(f(6).to_bits(), o.energy.to_bits());
        contacts += usize::from(o.in_contact);
    }
    assert!(contacts > 0, "the render should hold a contact");
    // fewer rows than the header says
    let mut short = NpyTrace::new(44100.0, 3, Vec::new()).unwrap();
    short.record(0, &Motion::default(), Some(0.0)).unwrap();
    let e = short.finish().unwrap_err().to_string();
    assert!(e.contains("3 rows, 1 were recorded"), "{e}");
}

/// The plot's envelope on the block path with the motion equals the one
/// built from every traced row, on presets with one strike, bounces and
/// a string, with both switching methods: the same audio bit for bit,
/// the same contact buckets, and min/max and energies equal up to the
/// order of the sums (relative 1e-12 of the signal's range; measured 3.4e-16).
#[test]
fn envelope_on_the_block_path_matches_the_traced_rows() {
    for name in ["steel-plate", "paper-bounce", "paper-string", "wood-block"] {
        for sw in [Switching::Exact, Switching::OffsetRod] {
            let scene = crate::presets::scene(crate::presets::index_of(name).unwrap()).unwrap();
            let compiled = compile_with(&scene, 44100.0, Some(sw)).unwrap();
            let n = 30_000;
            let full = render_compiled(&compiled, n, true);
            let rows = full.trace.unwrap();
            let mut env = TraceEnvelope::new(44100.0, n);
            let left = stream_left(&compiled, n, &mut env);
            assert_eq!(left, full.left, "{name} {sw:?}: audio");
            let span = |f: fn(&TraceRow) -> f64| {
                let (lo, hi) = rows
                    .iter()
                    .map(f)
                    .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
                (hi - lo).max(1e-300)
            };
            let (sx, sc) = (span(|r| r.obs.x_hammer), span(|r| r.obs.x_contact));
            let se = span(|r| r.obs.energy).max(rows[0].obs.energy.abs());
            let mut worst = 0.0f64;
            assert!((env.energy_start - rows[0].obs.energy).abs() <= 1e-9 * se);
            for b in &env.buckets {
                let part = &rows[b.start..b.start + b.len];
                let mm = |f: fn(&TraceRow) -> f64| {
                    part.iter()
                        .map(f)
                        .fold([f64::MAX, f64::MIN], |[a, c], x| [a.min(x), c.max(x)])
                };
                let (xh, xc) = (mm(|r| r.obs.x_hammer), mm(|r| r.obs.x_contact));
                for q in 0..2 {
                    worst = worst.max((b.x_hammer[q] - xh[q]).abs() / sx);
                    worst = worst.max((b.x_contact[q] - xc[q]).abs() / sc);
                }
                worst = worst.max((b.energy_end - part.last().unwrap().obs.energy).abs() / se);
                assert_eq!(
                    b.in_contact,
                    part.iter().any(|r| r.obs.in_contact),
                    "{name} {sw:?}: contact flags of bucket at {}",
                    b.start
                );
            }
            println!("{name} {sw:?}: worst envelope deviation {worst:.1e} of the range");
            assert!(worst <= 1e-12, "{name} {sw:?}: {worst:e}");
        }
    }
}

/// A sink that keeps one contact (the default `record_several`).
struct OneContactOnly(usize);

impl TraceSink for OneContactOnly {
    fn wants_energy(&self, _: usize) -> bool {
        false
    }
    fn record(&mut self, _: usize, _: &Motion, _: Option<f64>) -> std::io::Result<()> {
        self.0 += 1;
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

/// A several-contact scene renders through [`render()`] as through
/// the several-contact engine's own loop (each sample's decision,
/// observation and tick), bit for bit: the audio, every contact's
/// motion in the rows in memory, and the CSV and NumPy traces, whose
/// header names each contact's columns and whose numbers read back to
/// the rows' exactly. A sink that keeps one contact refuses the
/// render instead of dropping columns.
#[test]
fn a_several_contact_scene_renders_through_the_one_render() {
    let scene =
        crate::presets::scene(crate::presets::index_of("ball-between-plates").unwrap()).unwrap();
    let rate = 44_100.0;
    let n = 3000;
    let opts = RenderOptions {
        rate_hz: rate,
        seconds: Some(n as f64 / rate),
        switching: None,
        trace: true,
    };
    let out = render(&scene, &opts).unwrap();
    let Ok(Compiled::Several(c)) = Compiled::new(&scene, rate, None) else {
        panic!("a several-contact scene compiles for the several-contact engine");
    };
    let k = c.contacts();
    assert_eq!(k, 2);
    // the engine's own loop
    let mut st = MultiState::new(&c);
    let rows = out.trace.as_ref().unwrap();
    assert_eq!(rows.len(), n);
    assert_eq!(out.trace_further.len(), n * (k - 1));
    for i in 0..n {
        st.decide(&c);
        let o = st.observe(&c);
        assert_eq!(
            rows[i].obs,
            contact_motion(&o, 0).with_energy(o.energy),
            "row {i}"
        );
        for j in 1..k {
            assert_eq!(
                out.trace_further[i * (k - 1) + j - 1],
                contact_motion(&o, j)
            );
        }
        let [l, r] = st.tick(&c);
        assert_eq!((out.left[i], out.right[i]), (l, r), "sample {i}");
    }
    // the block path (no trace) makes the same samples
    let plain = Compiled::Several(c.clone()).render(n, false);
    assert!(plain.left == out.left && plain.right == out.right);
    let started: u64 = st.stats.contacts_started[..k].iter().sum();
    assert!(started >= 2, "the ball touches: {started} contacts");
    assert_eq!(out.contacts, started);
    assert_eq!(out.several, Some(st.stats));
    // the CSV: the header, and every number of every row
    let mut csv = CsvTrace::with_contacts(rate, Vec::new(), k).unwrap();
    let stats = render_stream_several(&c, n, |_, _| Ok(()), Some(&mut csv)).unwrap();
    assert_eq!(stats.several, out.several);
    let text = String::from_utf8(csv.finish().unwrap()).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), trace_header(k));
    let flag = |b: bool| f64::from(u8::from(b));
    let mut expect = Vec::new();
    for (i, line) in lines.enumerate() {
        let got: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let mut want = rows[i].columns().to_vec();
        for m in &out.trace_further[i * (k - 1)..(i + 1) * (k - 1)] {
            want.extend([
                m.x_hammer,
                m.v_hammer,
                m.x_contact,
                m.v_contact,
                flag(m.in_contact),
            ]);
        }
        assert_eq!(got.len(), 7 + 5 * (k - 1));
        for (a, b) in got.iter().zip(&want) {
            assert_eq!(a.to_bits(), b.to_bits(), "CSV row {i}: {line}");
        }
        expect.extend(want);
    }
    assert_eq!(expect.len(), n * (7 + 5 * (k - 1)));
    // the NumPy trace: the same numbers' own bits after its header
    let mut npy = NpyTrace::with_contacts(rate, n, k, Vec::new()).unwrap();
    render_stream_several(&c, n, |_, _| Ok(()), Some(&mut npy)).unwrap();
    let bytes = npy.finish().unwrap();
    let body = &bytes[bytes.len() - 8 * expect.len()..];
    for (q, x) in expect.iter().enumerate() {
        let b: [u8; 8] = body[8 * q..8 * q + 8].try_into().unwrap();
        assert_eq!(
            f64::from_le_bytes(b).to_bits(),
            x.to_bits(),
            "NPY field {q}"
        );
    }
    assert!(
        String::from_utf8_lossy(&bytes[..bytes.len() - body.len()]).contains("'x_hammer_1', '<f8'")
    );
    // a one-contact sink refuses
    let mut one = OneContactOnly(0);
    let refused = render_stream_several(&c, n, |_, _| Ok(()), Some(&mut one)).unwrap_err();
    assert!(
        refused.to_string().contains("takes one contact"),
        "{refused}"
    );
    assert_eq!(one.0, 0);
}
