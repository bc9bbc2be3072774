//! A strike from rest played back (`EngineState::strike_stored`,
//! docs/numerics.md "A strike from rest played back") against the engine
//! running the same strike: on every preset and stability case that
//! records one, at several pitches and speeds, block by block the same
//! samples to rounding, the same answers to what a caller asks meanwhile
//! (contact, energy, hammer, penetration), the same state where the replay
//! ends; a replay interrupted anywhere (a second strike, a bend, a new
//! band, a rebind) goes on as the strike would (a bend in contact waits,
//! as it does for the engine); what cannot be replayed is
//! refused and plays as before. Through the instrument: the same output
//! with the stored strikes and without them, events in the middle of
//! strikes included. The engine's own strikes are checked against the
//! independent solver in `tests/stiff_switching.rs`.

use modal_contact::compile::{compile_one, CompiledScene};
use modal_contact::engine::{EngineState, ScaleProps, LINEAR_TOL};
use modal_contact::instrument::{prepare_scene, Event, Instrument, InstrumentParams, TimedEvent};
use modal_contact::presets;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::scenes::{struck_bar, RATE};
use modal_testkit::stability;

/// The band the instrument's voices hear at 48 kHz (0.45 of the rate:
/// above it modes are left out of the outputs at high pitches).
const BAND: f64 = 0.45 * RATE;
/// The slowest and fastest impacts the recordings are checked at.
const SPEEDS: [f64; 2] = [0.05, 3.0];

fn scenes() -> Vec<(String, Scene)> {
    let mut v: Vec<(String, Scene)> = presets::one_contact()
        .map(|i| {
            let s = presets::scene(i).unwrap();
            (format!("preset {}", presets::NAMES[i]), s)
        })
        .collect();
    for c in stability::cases() {
        v.push((format!("stability {}", c.label), c.scene));
    }
    v.push(("bar 200 modes".into(), struck_bar(200, 1.0)));
    v
}

/// A voice at scale `s` with the band, reset, as the instrument makes one.
fn voice(sc: &CompiledScene, pre: &ScaleProps) -> EngineState {
    let mut st = EngineState::new(sc);
    st.set_output_band(sc, BAND);
    st.set_time_scale_from(sc, pre).unwrap();
    st.reset(sc);
    st
}

/// The largest |a - b| relative to `scale`.
fn rel(a: f64, b: f64, scale: f64) -> f64 {
    (a - b).abs() / scale.max(f64::MIN_POSITIVE)
}

/// Run `a` (replaying) and `b` (the engine) side by side for `n` samples
/// in blocks of varying length, comparing outputs and, at every block
/// boundary, what a caller can ask. Returns the largest output difference
/// relative to the peak and the largest difference of the answers.
fn side_by_side(
    sc: &CompiledScene,
    a: &mut EngineState,
    b: &mut EngineState,
    n: usize,
) -> (f64, f64) {
    let (mut out_a, mut out_b) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut asked = Vec::new();
    let sizes = [1usize, 7, 64, 3, 33, 128, 2];
    let (mut done, mut j) = (0, 0);
    while done < n {
        let len = sizes[j % sizes.len()].min(n - done);
        j += 1;
        let (mut la, mut ra, mut lb, mut rb) = (
            vec![0.0; len],
            vec![0.0; len],
            vec![0.0; len],
            vec![0.0; len],
        );
        a.process_block(sc, &mut la, &mut ra);
        b.process_block(sc, &mut lb, &mut rb);
        out_a.extend(la.iter().zip(&ra).map(|(l, r)| [*l, *r]));
        out_b.extend(lb.iter().zip(&rb).map(|(l, r)| [*l, *r]));
        done += len;
        assert_eq!(a.in_contact(), b.in_contact(), "contact at sample {done}");
        // (a replaying voice is never clear: nor is the engine's before its
        // last stored switch)
        assert_eq!(
            a.hammer_clear(sc),
            b.hammer_clear(sc),
            "clear at sample {done}"
        );
        assert_eq!(
            a.hammer_in_flight().is_some(),
            b.hammer_in_flight().is_some(),
            "flight at sample {done}"
        );
        asked.push((
            a.energy_proxy(sc),
            b.energy_proxy(sc),
            a.penetration(sc),
            b.penetration(sc),
            a.hammer_in_flight(),
            b.hammer_in_flight(),
        ));
    }
    let peak = out_b.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    let out = out_a
        .iter()
        .zip(&out_b)
        .flat_map(|(x, y)| [rel(x[0], y[0], peak), rel(x[1], y[1], peak)])
        .fold(0.0, f64::max);
    let e_top = asked.iter().fold(0.0f64, |m, q| m.max(q.1.abs()));
    let p_top = asked.iter().fold(0.0f64, |m, q| m.max(q.3.abs()));
    let h_top = asked.iter().fold(0.0f64, |m, q| {
        q.5.map_or(m, |(x, v)| m.max(x.abs()).max(v.abs()))
    });
    let mut ask = 0.0f64;
    for (ea, eb, pa, pb, ha, hb) in &asked {
        ask = ask.max(rel(*ea, *eb, e_top)).max(rel(*pa, *pb, p_top));
        if let (Some(x), Some(y)) = (ha, hb) {
            ask = ask.max(rel(x.0, y.0, h_top)).max(rel(x.1, y.1, h_top));
        }
    }
    (out, ask)
}

#[test]
fn a_replayed_strike_is_the_engine_strike_times_its_speed() {
    let mut recorded = 0;
    let mut worst: (f64, f64) = (0.0, 0.0);
    for (name, scene) in scenes() {
        let sc = compile_one(&scene, RATE).unwrap();
        let linear = sc.switching == Switching::Exact && sc.g == 0.0;
        for s in [0.5, 1.0, 1.37, 3.0] {
            let mut pre = ScaleProps::new(&sc, s, BAND);
            let kept = pre.store_strike(&sc, BAND, &SPEEDS);
            if !linear {
                assert!(
                    !kept,
                    "{name}: a recording without exact switching or with gravity"
                );
                continue;
            }
            let Some(rec) = pre.stored_strike() else {
                println!("{name} s {s}: not recorded");
                continue;
            };
            recorded += 1;
            for v in [0.05, 0.7, 1.88, 3.0] {
                let (mut a, mut b) = (voice(&sc, &pre), voice(&sc, &pre));
                assert!(a.strike_stored(&sc, v, &pre), "{name} s {s} v {v}");
                b.strike(&sc, 0.0, -v);
                let n = rec.len() + 600;
                let (out, ask) = side_by_side(&sc, &mut a, &mut b, n);
                assert!(!a.replaying());
                // where the replay ended the state is the engine's
                let top = b.phase_state().iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let state = a
                    .phase_state()
                    .iter()
                    .zip(b.phase_state())
                    .fold(0.0f64, |m, (x, y)| m.max(rel(*x, *y, top)));
                assert_eq!(a.contacts_started, b.contacts_started, "{name}");
                assert_eq!(a.exact_stats.replayed, 1);
                assert!(
                    out <= LINEAR_TOL && ask <= LINEAR_TOL && state <= LINEAR_TOL,
                    "{name} s {s} v {v}: outputs {out:.1e}, answers {ask:.1e}, state {state:.1e}"
                );
                worst = (worst.0.max(out), worst.1.max(ask.max(state)));
            }
            if s == 1.0 {
                println!(
                    "{name}: {} samples replayed, check at other speeds {:.1e}",
                    rec.len(),
                    rec.linear_err()
                );
            }
        }
    }
    println!("{recorded} recordings; largest differences: outputs {:.1e} of the peak, answers and states {:.1e}", worst.0, worst.1);
    assert!(recorded >= 40, "{recorded}");
}

#[test]
fn a_replay_interrupted_anywhere_goes_on_as_the_strike() {
    let sc = compile_one(&struck_bar(200, 1.0), RATE).unwrap();
    let mut pre = ScaleProps::new(&sc, 1.0, BAND);
    assert!(pre.store_strike(&sc, BAND, &SPEEDS));
    let len = pre.stored_strike().unwrap().len();
    let mut worst = 0.0f64;
    for k in [0, 1, 2, len / 3, len / 2, len - 1] {
        for action in 0..4 {
            let (mut a, mut b) = (voice(&sc, &pre), voice(&sc, &pre));
            assert!(a.strike_stored(&sc, 1.3, &pre));
            b.strike(&sc, 0.0, -1.3);
            let (mut l, mut r) = (vec![0.0; k], vec![0.0; k]);
            a.process_block(&sc, &mut l, &mut r);
            b.process_block(&sc, &mut l, &mut r);
            assert!(a.replaying());
            let touching = a.in_contact();
            let mut bent = Vec::new();
            for st in [&mut a, &mut b] {
                match action {
                    0 => st.strike(&sc, 0.0, -0.4),
                    1 => bent.push(st.bend_time_scale(&sc, 1.06).unwrap()),
                    2 => st.set_output_band(&sc, 5000.0),
                    _ => assert!(st.rebind(&sc, &sc)),
                }
            }
            if action == 1 && touching {
                // a bend waits for the release, a replaying voice's too
                // (unsettled)
                assert_eq!(bent, [false, false], "k {k}");
                assert!(a.replaying() && a.exact_stats.settled == 0);
            } else {
                assert_eq!(bent.first(), bent.last(), "k {k}");
                assert!(!a.replaying(), "k {k} action {action}");
                assert_eq!(a.exact_stats.settled, 1);
            }
            let (out, ask) = side_by_side(&sc, &mut a, &mut b, len + 400);
            println!("settled at {k}, action {action}: outputs {out:.1e}, answers {ask:.1e}");
            assert!(
                out <= LINEAR_TOL && ask <= LINEAR_TOL,
                "k {k} action {action}: {out:.1e} {ask:.1e}"
            );
            worst = worst.max(out);
        }
    }
    println!("largest output difference after a settle: {worst:.1e} of the peak");
}

#[test]
fn what_cannot_be_replayed_is_an_ordinary_strike() {
    let sc = compile_one(&struck_bar(50, 1.0), RATE).unwrap();
    let mut pre = ScaleProps::new(&sc, 1.0, BAND);
    assert!(pre.store_strike(&sc, BAND, &SPEEDS));
    let other = ScaleProps::new(&sc, 1.5, BAND);
    let mut cases: Vec<(&str, EngineState, &ScaleProps)> = Vec::new();
    // a ringing voice
    let mut ringing = voice(&sc, &pre);
    ringing.strike(&sc, 0.0, -1.0);
    let (mut l, mut r) = (vec![0.0; 300], vec![0.0; 300]);
    ringing.process_block(&sc, &mut l, &mut r);
    cases.push(("ringing", ringing, &pre));
    // propagators without a recording, and at another scale than the voice's
    cases.push(("unrecorded", voice(&sc, &pre), &other));
    let mut portable = voice(&sc, &pre);
    portable.set_portable_kernels(!portable.portable_kernels());
    cases.push(("other kernels", portable, &pre));
    for (name, st, props) in cases {
        let (mut a, mut b) = (st.clone(), st);
        assert!(!a.strike_stored(&sc, 1.0, props), "{name}");
        b.strike(&sc, 0.0, -1.0);
        let (mut la, mut ra, mut lb, mut rb) = (
            vec![0.0; 500],
            vec![0.0; 500],
            vec![0.0; 500],
            vec![0.0; 500],
        );
        a.process_block(&sc, &mut la, &mut ra);
        b.process_block(&sc, &mut lb, &mut rb);
        assert_eq!(
            (la, ra),
            (lb, rb),
            "{name}: bit for bit the engine's strike"
        );
    }
    // gravity: nothing recorded
    let mut dropped = struck_bar(50, 1.0);
    dropped.hammer.gravity_m_per_s2 = 9.81;
    let sc = compile_one(&dropped, RATE).unwrap();
    let mut pre = ScaleProps::new(&sc, 1.0, BAND);
    assert!(!pre.store_strike(&sc, BAND, &SPEEDS));
}

/// Notes, chords and events landing inside strikes (releases, repeated
/// notes, bends, pressure, brightness) through the instrument, with the
/// stored strikes and without them.
#[test]
fn the_instrument_sounds_the_same_with_its_stored_strikes() {
    let params = InstrumentParams::default();
    for (name, scene) in [
        ("bar 200 modes", struck_bar(200, 1.0)),
        (
            "paper-string",
            presets::scene(presets::index_of("paper-string").unwrap()).unwrap(),
        ),
        (
            "marimba-bar",
            presets::scene(presets::index_of("marimba-bar").unwrap()).unwrap(),
        ),
    ] {
        let with = prepare_scene(&scene, &params.scene, RATE, 0).unwrap();
        let mut without = with.clone();
        without.forget_stored_strikes();
        let evs = strike_events();
        let render = |p| render_events(p, params.play, &evs);
        let (la, ra, sa) = render(with);
        let (lb, rb, sb) = render(without);
        let peak = lb.iter().chain(&rb).fold(0.0f32, |m, x| m.max(x.abs()));
        let diff = la
            .iter()
            .zip(&lb)
            .chain(ra.iter().zip(&rb))
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        println!(
            "{name}: {} of {} notes replayed ({} without), largest difference {:.1e} of the peak {peak:.2e}",
            sa.strikes_replayed, sa.notes, sb.strikes_replayed, diff / peak
        );
        assert!(sa.strikes_replayed > 0 && sb.strikes_replayed == 0);
        assert!(peak > 0.0);
        // f32 output: one rounding of the output apart at most
        assert!(
            diff <= 2.0 * f32::EPSILON * peak,
            "{name}: {diff:e} of {peak:e}"
        );
    }
}

/// Six chords of twelve notes, 3000 samples apart, each with a release,
/// pressure, brightness, a repeated note and a bend landing inside its
/// strikes.
fn strike_events() -> Vec<TimedEvent> {
    let on = |key: u8, at: usize, vel: f64| TimedEvent {
        offset: at,
        event: Event::NoteOn {
            key,
            velocity_norm: vel,
        },
    };
    let mut evs = Vec::new();
    for c in 0..6usize {
        let at = c * 3000 + 5;
        for j in 0..12u8 {
            evs.push(on(
                40 + (j * 7 + c as u8 * 3) % 40,
                at,
                0.2 + 0.06 * f64::from(j),
            ));
        }
        // inside the strikes just made
        evs.push(TimedEvent {
            offset: at + 9,
            event: Event::NoteOff {
                key: 40 + (c as u8 * 3) % 40,
            },
        });
        evs.push(TimedEvent {
            offset: at + 11,
            event: Event::NotePressure {
                key: Some(40 + (14 + c as u8 * 3) % 40),
                value: 0.7,
            },
        });
        evs.push(TimedEvent {
            offset: at + 13,
            event: Event::NoteBrightness {
                key: Some(40 + (21 + c as u8 * 3) % 40),
                value: 0.9,
            },
        });
        evs.push(on(40 + (7 + c as u8 * 3) % 40, at + 17, 0.9));
        evs.push(TimedEvent {
            offset: at + 23,
            event: Event::PitchBend {
                value: 0.1 * c as f64 - 0.2,
            },
        });
    }
    evs
}

/// 20000 samples of the instrument `p` plays with `play`, in blocks of 64
/// with the events `evs`: left, right and the instrument's statistics.
fn render_events(
    p: Box<modal_contact::instrument::Prepared>,
    play: modal_contact::instrument::PlayParams,
    evs: &[TimedEvent],
) -> (Vec<f32>, Vec<f32>, modal_contact::instrument::Stats) {
    let mut inst = Instrument::new(p, play);
    let total = 20000;
    let (mut l, mut r) = (vec![0.0f32; total], vec![0.0f32; total]);
    let mut start = 0;
    while start < total {
        let len = 64.min(total - start);
        let local: Vec<TimedEvent> = evs
            .iter()
            .filter(|e| e.offset >= start && e.offset < start + len)
            .map(|e| TimedEvent {
                offset: e.offset - start,
                event: e.event,
            })
            .collect();
        inst.process(
            &local,
            &mut l[start..start + len],
            &mut r[start..start + len],
        );
        start += len;
    }
    (l, r, inst.stats)
}
