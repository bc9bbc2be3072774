//! The lookahead (docs/plugin.md, "Lookahead"): voices may run up to the
//! lookahead behind the instrument's clock, so a chord's strikes spread
//! over several blocks, and the output is the plain instrument's, that many
//! samples later, bit for bit. Checked against the plain instrument (the
//! lookahead at 0, the path every other test of the instrument runs) on
//! presets and on a 100-mode object, with scripts that play everything a
//! host can send (chords on one sample and notes a sample apart, note-offs,
//! pedals, the bend wheel, pressures, the mod wheel, brightness, per-note
//! tuning and modulation) in host blocks of random lengths; that the
//! strikes of a chord really leave the block that holds it; and, the base
//! of all of it, that without a lookahead the same scripts give the same
//! samples in any host blocks.

use modal_contact::instrument::{
    prepare, prepare_scene, Event, Instrument, InstrumentParams, Prepared, TimedEvent, VoiceChunk,
    VoiceProbe, WorkMeter, LOOKAHEAD_WORK_FRACTION, MAX_LOOKAHEAD_SAMPLES,
};
use modal_contact::presets;
use modal_testkit::rng::TestRng;
use modal_testkit::scenes::struck_bar;

const RATE: f64 = 48_000.0;

fn preset(name: &str) -> Box<Prepared> {
    let mut p = InstrumentParams::default();
    p.scene.preset = presets::index_of(name).unwrap();
    prepare(&p.scene, RATE, 0).unwrap()
}

fn modal(n: usize) -> Box<Prepared> {
    let p = InstrumentParams::default();
    prepare_scene(&struck_bar(n, 1.0), &p.scene, RATE, 0).unwrap()
}

fn at(offset: usize, event: Event) -> TimedEvent {
    TimedEvent { offset, event }
}

/// A random script of `n` samples: everything a host sends, at random
/// times (sorted).
fn script(seed: u64, n: usize) -> Vec<TimedEvent> {
    let mut rng = TestRng(seed);
    let mut out = Vec::new();
    let key = |rng: &mut TestRng| 48 + rng.below(30) as u8;
    let mut t = 0;
    loop {
        t += rng.below(1500);
        if t >= n {
            break;
        }
        match rng.below(14) {
            0..=3 => {
                // a chord on one sample
                for _ in 0..1 + rng.below(8) {
                    let (key, velocity_norm) = (key(&mut rng), rng.uniform(0.1, 1.0));
                    out.push(at(t, Event::NoteOn { key, velocity_norm }));
                }
            }
            4 => {
                // notes a sample or a few apart
                for j in 0..1 + rng.below(4) {
                    let (key, velocity_norm) = (key(&mut rng), rng.uniform(0.1, 1.0));
                    out.push(at(
                        t + j * rng.below(3),
                        Event::NoteOn { key, velocity_norm },
                    ));
                }
            }
            5 | 6 => out.push(at(t, Event::NoteOff { key: key(&mut rng) })),
            7 => out.push(at(
                t,
                Event::Sustain {
                    down: rng.below(2) == 0,
                },
            )),
            8 => out.push(at(
                t,
                Event::PitchBend {
                    value: rng.uniform(-1.0, 1.0),
                },
            )),
            9 => out.push(at(
                t,
                if rng.below(2) == 0 {
                    Event::ChannelPressure {
                        value: rng.uniform(0.0, 0.6),
                    }
                } else {
                    Event::ModWheel {
                        value: rng.uniform(0.0, 0.6),
                    }
                },
            )),
            10 => out.push(at(
                t,
                Event::NotePressure {
                    key: Some(key(&mut rng)),
                    value: rng.uniform(0.0, 1.0),
                },
            )),
            11 => out.push(at(
                t,
                Event::NoteBrightness {
                    key: Some(key(&mut rng)),
                    value: rng.unit(),
                },
            )),
            12 => out.push(at(
                t,
                Event::NoteTuning {
                    key: Some(key(&mut rng)),
                    semitones: rng.uniform(-2.0, 2.0),
                },
            )),
            _ => out.push(at(
                t,
                Event::Sostenuto {
                    down: rng.below(2) == 0,
                },
            )),
        }
    }
    out.sort_by_key(|e| e.offset);
    out
}

/// Both channels of `n` samples rendered in host blocks of the lengths
/// `blocks` gives (cycled), each block given its events.
fn render(
    inst: &mut Instrument,
    events: &[TimedEvent],
    n: usize,
    blocks: &[usize],
) -> [Vec<f32>; 2] {
    render_lag(inst, events, n, blocks).0
}

/// [`render`], and the largest lag of a voice behind the instrument's
/// clock after a block.
fn render_lag(
    inst: &mut Instrument,
    events: &[TimedEvent],
    n: usize,
    blocks: &[usize],
) -> ([Vec<f32>; 2], usize) {
    let mut lag = 0;
    let (mut l, mut r) = (vec![0.0f32; n], vec![0.0f32; n]);
    let (mut pos, mut e) = (0, 0);
    for len in blocks.iter().cycle() {
        if pos >= n {
            break;
        }
        let end = (pos + len).min(n);
        let mut local = Vec::new();
        while e < events.len() && events[e].offset < end {
            local.push(at(events[e].offset - pos, events[e].event));
            e += 1;
        }
        inst.process(&local, &mut l[pos..end], &mut r[pos..end]);
        lag = lag.max(inst.lag());
        pos = end;
    }
    ([l, r], lag)
}

fn random_blocks(seed: u64) -> Vec<usize> {
    let mut rng = TestRng(seed);
    (0..50)
        .map(|_| match rng.below(3) {
            0 => 1 + rng.below(64),
            1 => 1 + rng.below(700),
            _ => 1 + rng.below(3000),
        })
        .collect()
}

/// The output at lookahead `l` is the plain output `l` samples later, bit
/// for bit (and silence before), with the same notes, steals and resets.
fn assert_delayed(
    make: &dyn Fn() -> Box<Prepared>,
    events: &[TimedEvent],
    n: usize,
    l: usize,
    work: f64,
    seed: u64,
) {
    let mut plain = Instrument::new(make(), InstrumentParams::default().play);
    let [l0, r0] = render(&mut plain, events, n, &random_blocks(seed));
    let mut late = Instrument::new(make(), InstrumentParams::default().play);
    late.set_lookahead(l);
    late.set_lookahead_work(work);
    assert_eq!(late.lookahead(), l);
    let ([l1, r1], lag) = render_lag(&mut late, events, n + l, &random_blocks(seed));
    assert!(lag <= l + 64, "lag {lag}");
    assert!(
        l1[..l].iter().chain(&r1[..l]).all(|x| *x == 0.0),
        "silence first"
    );
    let peak = l0.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    assert!(peak > 1e-3, "the script sounds (peak {peak})");
    let differ = (0..n)
        .filter(|&t| {
            l1[t + l].to_bits() != l0[t].to_bits() || r1[t + l].to_bits() != r0[t].to_bits()
        })
        .count();
    assert_eq!(differ, 0, "lookahead {l}: {differ} of {n} samples differ");
    let (a, b) = (plain.stats, late.stats);
    assert_eq!(
        (
            a.notes,
            a.steals,
            a.nonfinite_resets,
            a.dense_pitch_fallbacks
        ),
        (
            b.notes,
            b.steals,
            b.nonfinite_resets,
            b.dense_pitch_fallbacks
        )
    );
    println!(
        "lookahead {l}, work ahead {work}: {n} samples equal, voices up to {lag} samples behind, peak {peak:.3}, {} notes, {} steals, {} silent stops (plain {})",
        b.notes, b.steals, b.silent_stops, a.silent_stops
    );
}

#[test]
fn the_output_is_the_plain_instruments_later_bit_for_bit() {
    let n = 96_000;
    for (name, make) in [
        (
            "marimba-bar",
            Box::new(|| preset("marimba-bar")) as Box<dyn Fn() -> Box<Prepared>>,
        ),
        ("paper-string", Box::new(|| preset("paper-string"))),
        ("bell", Box::new(|| preset("bell"))),
        ("100 modes", Box::new(|| modal(100))),
    ] {
        // the default share of work ahead, none (every voice the whole
        // lookahead behind), and a little
        for (k, (l, work)) in [
            (1, LOOKAHEAD_WORK_FRACTION),
            (64, 0.0),
            (300, LOOKAHEAD_WORK_FRACTION),
            (300, 0.02),
            (1024, 0.0),
            (MAX_LOOKAHEAD_SAMPLES, 0.0),
            (MAX_LOOKAHEAD_SAMPLES, LOOKAHEAD_WORK_FRACTION),
        ]
        .into_iter()
        .enumerate()
        {
            let seed = 17 + 31 * k as u64 + name.len() as u64;
            println!("{name}:");
            assert_delayed(&*make, &script(seed, n), n, l, work, seed);
        }
    }
}

/// The point of it: with a lookahead, a chord's strikes leave the block
/// that holds it. A 16-note chord on a 100-mode object in 64-sample
/// blocks, struck again while it rings (a new note on a voice at rest is
/// played back from its recording, docs/numerics.md "A strike from rest
/// played back": no work to spread; a strike on a ringing voice switches
/// itself): every strike's contacts start in that block without a
/// lookahead; with one, the voices work ahead only while the block's
/// estimated work fits, and the contacts spread over the blocks after.
#[test]
fn a_chords_strikes_spread_over_the_blocks_of_the_lookahead() {
    let chord: Vec<TimedEvent> = (0..16)
        .map(|j| {
            at(
                10,
                Event::NoteOn {
                    key: 48 + 2 * j as u8,
                    velocity_norm: 0.8,
                },
            )
        })
        .collect();
    let block = 64;
    let contacts_per_block = |l: usize| {
        let mut inst = Instrument::new(modal(100), InstrumentParams::default().play);
        inst.set_lookahead(l);
        // the cost model's schedule: the same on every machine
        inst.set_work_meter(WorkMeter::Estimate);
        let (mut left, mut right) = (vec![0.0f32; block], vec![0.0f32; block]);
        let mut per_block = Vec::new();
        let mut before = 0;
        let mut out = Vec::new();
        for b in 0..70 {
            let evs = if b == 0 || b == 30 { &chord[..] } else { &[] };
            inst.process(evs, &mut left, &mut right);
            out.extend_from_slice(&left);
            // the contacts the voices switched themselves
            let now: u64 = (0..16)
                .map(|i| {
                    let st = inst.voice_state(i);
                    st.contacts_started - st.contacts_replayed
                })
                .sum();
            per_block.push(now - before);
            before = now;
        }
        let replayed: u64 = (0..16).map(|i| inst.voice_state(i).contacts_replayed).sum();
        assert!(replayed >= 16, "the first chord played back");
        (per_block.split_off(30), out)
    };
    let (plain, out0) = contacts_per_block(0);
    let (spread, out1) = contacts_per_block(1024);
    println!("contacts started per 64-sample block, no lookahead: {plain:?}");
    println!("with a lookahead of 1024 samples: {spread:?}");
    assert!(
        plain[0] >= 16,
        "every strike's first contact in the chord's block"
    );
    let most = *spread.iter().max().unwrap();
    assert!(3 * most <= plain[0], "at most {most} contacts in one block");
    assert_eq!(
        plain.iter().sum::<u64>(),
        spread.iter().sum::<u64>(),
        "the same contacts"
    );
    // and the same sound, later
    assert!((0..out0.len() - 1024).all(|t| out1[t + 1024].to_bits() == out0[t].to_bits()));
}

/// A swap (a new scene installed while voices ring, some carried, some
/// faded) under a lookahead: the carried voices' samples are the plain
/// instrument's, later; the fade's sum of several voices may differ in its
/// last bits (it is summed apart from the voices'), never more.
#[test]
fn a_swap_under_a_lookahead_is_the_plain_swap_later() {
    let n = 48_000;
    let l = 500;
    let events = script(5, n);
    let run = |l: usize| {
        let mut inst = Instrument::new(preset("marimba-bar"), InstrumentParams::default().play);
        inst.set_lookahead(l);
        // no work ahead: every voice the whole lookahead behind
        inst.set_lookahead_work(0.0);
        let (mut left, mut right) = (vec![0.0f32; n + l], vec![0.0f32; n + l]);
        let mut e = 0;
        for (b, start) in (0..n + l).step_by(256).enumerate() {
            let end = (start + 256).min(n + l);
            let mut local = Vec::new();
            while e < events.len() && events[e].offset < end {
                local.push(at(events[e].offset - start, events[e].event));
                e += 1;
            }
            if b == 60 {
                // the same object stiffer: carried
                let mut p = InstrumentParams::default();
                p.scene.preset = presets::index_of("marimba-bar").unwrap();
                p.scene.stiffness_factor = 1.5;
                inst.install(prepare(&p.scene, RATE, 1).unwrap()).unwrap();
            }
            if b == 120 {
                // another preset: faded
                inst.install(preset("bell")).unwrap();
            }
            inst.process(&local, &mut left[start..end], &mut right[start..end]);
        }
        (left, inst.stats)
    };
    let (a, sa) = run(0);
    let (b, sb) = run(l);
    assert!(sa.voices_faded > 1 && sa.voices_carried > 0, "{sa:?}");
    assert_eq!(
        (sa.voices_faded, sa.voices_carried),
        (sb.voices_faded, sb.voices_carried)
    );
    let peak = a.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let (mut worst, mut differ) = (0.0f32, 0);
    for t in 0..n {
        let d = (b[t + l] - a[t]).abs();
        worst = worst.max(d);
        differ += usize::from(d > 0.0);
    }
    println!("swap under a lookahead of {l}: {differ} of {n} samples differ, by at most {worst:e} (peak {peak})");
    assert!(worst <= 4.0 * f32::EPSILON * peak, "{worst}");
}

/// A new lookahead brings every voice up to the clock, drops what waited
/// to be read, and plays on: silence for the new lookahead, then the
/// plain output from the change on.
#[test]
fn a_new_lookahead_restarts_the_output_and_keeps_the_voices() {
    let events = [
        at(
            0,
            Event::NoteOn {
                key: 60,
                velocity_norm: 0.7,
            },
        ),
        at(
            3000,
            Event::NoteOn {
                key: 64,
                velocity_norm: 0.9,
            },
        ),
    ];
    let n = 20_000;
    let mut plain = Instrument::new(preset("vibraphone-bar"), InstrumentParams::default().play);
    let [p, _] = render(&mut plain, &events, n, &[512]);
    let mut inst = Instrument::new(preset("vibraphone-bar"), InstrumentParams::default().play);
    inst.set_lookahead(100);
    let (mut l, mut r) = (vec![0.0f32; n], vec![0.0f32; n]);
    inst.process(&events[..1], &mut l[..2048], &mut r[..2048]);
    // the change at the clock's 2048: silence for 700, then time 2048 on
    inst.set_lookahead(700);
    let evs = [at(3000 - 2048, events[1].event)];
    inst.process(&evs, &mut l[2048..], &mut r[2048..]);
    assert!(l[..100].iter().all(|x| *x == 0.0));
    assert!((100..2048).all(|t| l[t].to_bits() == p[t - 100].to_bits()));
    assert!(
        l[2048..2748].iter().all(|x| *x == 0.0),
        "the new lookahead's silence"
    );
    assert!((2748..n).all(|t| l[t].to_bits() == p[t - 700].to_bits()));
}

/// What the probe kept: (voice, first sample, length) of every chunk.
type Chunks = std::sync::Arc<std::sync::Mutex<Vec<(usize, u64, usize)>>>;

struct Recorder(Chunks);

impl VoiceProbe for Recorder {
    fn voice_chunk(&mut self, c: &VoiceChunk) {
        self.0
            .lock()
            .unwrap()
            .push((c.voice, c.start, c.motion.len()));
    }
}

/// The editor's live view under a lookahead: the probe sees the same
/// chunks of the same voices as without one (the voices render in the
/// same chunks, only at other times: ahead of the output), each voice's in
/// order, and the output is still the plain one later, bit for bit.
#[test]
fn the_live_view_sees_the_same_chunks_under_a_lookahead() {
    let n = 48_000;
    let l = 700;
    let events = script(3, n);
    let blocks = random_blocks(3);
    let probed = |lookahead: usize| {
        let seen: Chunks = Default::default();
        let mut inst = Instrument::new(preset("steel-plate"), InstrumentParams::default().play);
        inst.set_probe(Some(Box::new(Recorder(seen.clone()))));
        inst.set_probe_on(true);
        inst.set_lookahead(lookahead);
        inst.set_lookahead_work(0.02);
        let ([out, _], lag) = render_lag(&mut inst, &events, n + lookahead, &blocks);
        let chunks = std::mem::take(&mut *seen.lock().unwrap());
        (out, lag, chunks)
    };
    let (p, _, mut plain) = probed(0);
    let (q, lag, mut late) = probed(l);
    assert!(lag > 64, "the voices ran behind ({lag})");
    assert!((0..n).all(|t| q[t + l].to_bits() == p[t].to_bits()));
    // each voice's chunks in order
    let mut next = [0u64; 64];
    for &(v, start, len) in &late {
        assert!(
            start >= next[v],
            "voice {v}: chunk at {start} before {}",
            next[v]
        );
        next[v] = start + len as u64;
    }
    // the same chunks (those of the first n samples: the late render ran
    // its voices on)
    late.retain(|c| c.1 < n as u64);
    plain.retain(|c| c.1 < n as u64);
    plain.sort();
    late.sort();
    println!(
        "{} chunks seen with and without a lookahead of {l}, voices up to {lag} samples behind",
        plain.len()
    );
    assert_eq!(plain, late);
}

/// Without a lookahead too, the output does not depend on how the host
/// splits its blocks, pressure included (docs/plugin.md, "Pressure and the
/// mod wheel": pressing is decided on the instrument's 64-sample grid and
/// at the events that change a voice, never where a host block ends): the
/// same random scripts in blocks of one sample, of 512 and of random
/// lengths give the same samples bit for bit.
#[test]
fn the_output_does_not_depend_on_the_hosts_blocks() {
    let n = 48_000;
    for (name, make) in [
        (
            "marimba-bar",
            Box::new(|| preset("marimba-bar")) as Box<dyn Fn() -> Box<Prepared>>,
        ),
        ("paper-string", Box::new(|| preset("paper-string"))),
        ("frame-drum", Box::new(|| preset("frame-drum"))),
        ("100 modes", Box::new(|| modal(100))),
    ] {
        for seed in [3u64, 5, 8, 13] {
            let events = script(seed, n);
            let pressed = events.iter().any(|e| {
                matches!(
                    e.event,
                    Event::NotePressure { .. }
                        | Event::ChannelPressure { .. }
                        | Event::ModWheel { .. }
                )
            });
            let mut outs = Vec::new();
            for blocks in [vec![512], vec![1], random_blocks(seed)] {
                let mut inst = Instrument::new(make(), InstrumentParams::default().play);
                outs.push((render(&mut inst, &events, n, &blocks), inst.stats));
            }
            let ([l0, r0], a) = &outs[0];
            let peak = l0.iter().fold(0.0f32, |m, x| m.max(x.abs()));
            assert!(peak > 1e-3, "the script sounds (peak {peak})");
            for ([l1, r1], b) in &outs[1..] {
                let differ = (0..n)
                    .filter(|&t| {
                        l1[t].to_bits() != l0[t].to_bits() || r1[t].to_bits() != r0[t].to_bits()
                    })
                    .count();
                let worst = (0..n).fold(0.0f32, |m, t| m.max((l1[t] - l0[t]).abs()));
                assert_eq!(
                    differ, 0,
                    "{name}, seed {seed}: {differ} of {n} samples differ, by up to {:.2e} of the peak",
                    worst / peak
                );
                assert_eq!(a, b);
            }
            assert!(
                !pressed || a.pressed_samples > 0,
                "{name}, seed {seed}: nothing pressed"
            );
            println!(
                "{name}, seed {seed}: {n} samples equal in blocks of 512, 1 and random lengths, peak {peak:.3}, {} voice samples pressed",
                a.pressed_samples
            );
        }
    }
}
