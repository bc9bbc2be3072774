//! Tests of the kit (a scene of several contacts played by the
//! instrument, docs/design.md, "Played as a kit"): a note is the scene
//! struck offline (at its pitch), notes choose mallets as the scene says,
//! blocks and the lookahead do not change a sample, a kit voice stops when
//! silent and wakes at rest, a swap carries or fades it.

use super::tests::{
    at, largest, off, on, one_mode_residuals, render, steal_fade_gain, worst_and_tol,
};
use super::*;
use crate::multi::{CompiledMulti, MultiModel, MultiState};
use crate::scene::{Scene, Switching};

mod ending;
use ending::ringing_kit;

const RATE: f64 = 48_000.0;

fn two_mallets() -> Scene {
    Scene::from_toml_str(include_str!("../../../presets/marimba-two-mallets.toml")).unwrap()
}

/// Three quickly decaying modes struck by two mallets (contacts 0 and 1),
/// the notes of each given.
fn small_kit(hammer_notes: &str, striker_notes: &str) -> Scene {
    Scene::from_toml_str(&format!(
        r#"
version = 1
name = "small-kit"
[[object]]
name = "bar"
kind = "modal"
points = ["a", "b", "pickup"]
mode = [
  {{ freq_hz = 300.0, t60_s = 0.15, weights = [1.0, 0.6, 0.9] }},
  {{ freq_hz = 810.0, t60_s = 0.1, weights = [-0.7, 1.0, 0.5] }},
  {{ freq_hz = 1650.0, t60_s = 0.08, weights = [0.5, -0.8, 0.7] }},
]
[hammer]
mass_kg = 0.02
height_m = 0.002
{hammer_notes}
[contact]
object = "bar"
point = "a"
stiffness_n_per_m = 2e5
damping_n_s_per_m = 5.0
[[striker]]
mass_kg = 0.03
height_m = 0.004
point = "b"
stiffness_n_per_m = 4e5
damping_n_s_per_m = 8.0
{striker_notes}
[[pickup]]
object = "bar"
point = "pickup"
quantity = "velocity"
"#
    ))
    .unwrap()
}

fn kit_instrument(scene: &Scene, lookahead_s: f64) -> Instrument {
    kit_switching(scene, lookahead_s, Switching::Exact)
}

/// A kit with the Switching parameter at `switching`.
fn kit_switching(scene: &Scene, lookahead_s: f64, switching: Switching) -> Instrument {
    let params = SceneParams {
        switching,
        ..SceneParams::default()
    };
    let p = prepare_scene(scene, &params, RATE, 0).unwrap();
    assert_eq!(p.switching_used, switching);
    assert!(p.kit.is_some());
    let play = PlayParams {
        gain_db: 0.0,
        lookahead_s,
        ..PlayParams::default()
    };
    let mut inst = Instrument::new(p, play);
    inst.set_lookahead(lookahead_samples(lookahead_s, RATE));
    inst
}

fn kit(inst: &Instrument) -> &Kit {
    inst.cur.kit.as_deref().unwrap()
}

/// The contacts every kit voice started, per contact.
fn started(inst: &Instrument) -> [u64; crate::multi::MAX_SPRINGS] {
    kit(inst).contacts_started()
}

/// A note on the two-mallet marimba at its root note is the scene
/// rendered offline with its first mallet thrown from the bar's surface at
/// the note's speed and the second parked, still, where the scene puts
/// it: the same samples (to the output's f32 rounding), through the
/// model's own start instead of the kit's rest and throw. A fifth up it is
/// the same model played 2^(7/12) times faster (its own compile at the
/// scaled values, `tests/multi_strike.rs` checks the time scale), and two
/// keys sound together as two kit voices, their sum. With exact
/// switching and with an offset rod per contact (the Switching
/// parameter).
#[test]
fn a_kit_note_is_the_scene_struck_offline() {
    for sw in [Switching::Exact, Switching::OffsetRod] {
        kit_note_offline(sw);
    }
}

fn kit_note_offline(sw: Switching) {
    let scene = two_mallets();
    let kit_instrument = |scene: &Scene, lookahead_s: f64| kit_switching(scene, lookahead_s, sw);
    let mut inst = kit_instrument(&scene, 0.0);
    let root = inst.prepared().root_note as u8;
    assert_eq!(root, 57, "A3");
    let (at, n) = (100, 9600);
    let out = render(&mut inst, &[on(at, root, 0.8)], at + n);
    let speed = impact_speed_m_per_s(0.8);
    let offline = |s: f64| {
        let mut model = MultiModel::from_scene(&scene, RATE).unwrap();
        model.masses[0].height_m = 0.0;
        model.masses[0].velocity_m_per_s = -speed;
        model.masses[1].velocity_m_per_s = 0.0;
        model.freq_hz.iter_mut().for_each(|f| *f *= s);
        model.sigma.iter_mut().for_each(|x| *x *= s);
        for ct in &mut model.contacts {
            ct.stiffness_n_per_m *= s * s;
            ct.damping_n_s_per_m *= s;
        }
        let sc = CompiledMulti::with_switching(&model, RATE, sw).unwrap();
        let mut st = MultiState::new(&sc);
        let y: Vec<[f64; 2]> = (0..n).map(|_| st.tick(&sc)).collect();
        (y, st.stats.contacts_started)
    };
    let compare = |out: &[Vec<f32>; 2], y: &[[f64; 2]]| {
        let (mut peak, mut worst) = (0.0f64, 0.0f64);
        for (k, y) in y.iter().enumerate() {
            for ch in 0..2 {
                peak = peak.max(y[ch].abs());
                worst = worst.max((f64::from(out[ch][at + k]) - y[ch]).abs());
            }
        }
        (worst, peak)
    };
    let (y, started) = offline(1.0);
    let (worst, peak) = compare(&out, &y);
    println!(
        "{}: kit at its root vs offline: {worst:.3e} of peak {peak:.3e}, contacts {started:?}",
        sw.as_str()
    );
    assert!(out[0][..at].iter().all(|&x| x == 0.0), "silent before");
    assert!(peak > 1e-3);
    assert!(worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
    assert_eq!(kit(&inst).state().stats.contacts_started, started);
    assert_eq!(inst.active_voices(), 1);

    let fifth = 2f64.powf(7.0 / 12.0);
    let (y5, _) = offline(fifth);
    let mut up = kit_instrument(&scene, 0.0);
    let out5 = render(&mut up, &[on(at, root + 7, 0.8)], at + n);
    let (worst5, peak5) = compare(&out5, &y5);
    println!(
        "{}: a fifth up vs the scaled model offline: {worst5:.3e} of peak {peak5:.3e}",
        sw.as_str()
    );
    assert!(worst5 <= 1e-6 * peak5, "{worst5:e} of {peak5:e}");

    let mut both = kit_instrument(&scene, 0.0);
    let out2 = render(
        &mut both,
        &[on(at, root, 0.8), on(at, root + 7, 0.8)],
        at + n,
    );
    assert_eq!(both.active_voices(), 2);
    let mut worst2 = 0.0f64;
    for k in 0..n {
        for ch in 0..2 {
            let sum = f64::from(out[ch][at + k]) + f64::from(out5[ch][at + k]);
            worst2 = worst2.max((f64::from(out2[ch][at + k]) - sum).abs());
        }
    }
    assert!(worst2 <= 1e-6 * peak, "two keys: {worst2:e}");
}

/// Three octaves up, a kit voice leaves the modes pitched above Nyquist
/// out of its outputs (the output band, as a voice of one contact does)
/// and keeps them in its dynamics: its samples are those of the scene
/// compiled at the scaled values with those modes' pickups removed.
#[test]
fn a_kit_voice_pitched_up_leaves_its_top_modes_out() {
    let scene = two_mallets();
    let mut inst = kit_instrument(&scene, 0.0);
    let root = inst.prepared().root_note as u8;
    let (at, n, s) = (100, 9600, 8.0);
    let out = render(&mut inst, &[on(at, root + 36, 0.8)], at + n);
    let muted = kit(&inst).voice_state(0).unwrap().band_muted_modes();
    let mut model = MultiModel::from_scene(&scene, RATE).unwrap();
    model.masses[0].height_m = 0.0;
    model.masses[0].velocity_m_per_s = -impact_speed_m_per_s(0.8);
    model.masses[1].velocity_m_per_s = 0.0;
    let mut left_out = 0;
    for i in 0..model.freq_hz.len() {
        model.freq_hz[i] *= s;
        model.sigma[i] *= s;
        if model.freq_hz[i] > 0.5 * RATE {
            left_out += 1;
            for c in 0..2 {
                model.pickups[c].0[i] = 0.0;
                model.pickups[c].1[i] = 0.0;
            }
        }
    }
    for ct in &mut model.contacts {
        ct.stiffness_n_per_m *= s * s;
        ct.damping_n_s_per_m *= s;
    }
    let sc = CompiledMulti::new(&model, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    let y: Vec<[f64; 2]> = (0..n).map(|_| st.tick(&sc)).collect();
    // eight times faster, the note may fall below the silence level within
    // the window: the voice stops there (its samples after it are 0), and
    // is compared up to it
    let stop = (0..n)
        .rev()
        .find(|&k| out[0][at + k] != 0.0 || out[1][at + k] != 0.0)
        .map_or(0, |k| k + 1);
    let (mut peak, mut worst, mut cut) = (0.0f64, 0.0f64, 0.0f64);
    for (k, y) in y.iter().enumerate() {
        for ch in 0..2 {
            peak = peak.max(y[ch].abs());
            if k < stop {
                worst = worst.max((f64::from(out[ch][at + k]) - y[ch]).abs());
            } else {
                cut = cut.max(y[ch].abs());
            }
        }
    }
    println!(
        "three octaves up: {muted} of {} modes left out; against the scaled scene without their pickups {worst:.3e} of peak {peak:.3e} over {stop} samples; after the voice stopped the scene's samples were at most {cut:.3e}",
        model.freq_hz.len()
    );
    assert_eq!(muted, left_out);
    assert!(muted > 0);
    assert!(peak > 1e-3);
    assert!(stop > n / 2, "it sounds for {stop} samples");
    assert!(worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
    // what the stop cut is within a few dB of the silence level (-90 dB,
    // the energy ratio as an amplitude)
    assert!(
        cut <= 3.0 * SILENCE_ENERGY_RATIO.sqrt() * peak,
        "{cut:e} of {peak:e}"
    );
}

/// Notes choose the mallets the scene lists; a note no mallet lists
/// strikes nothing; without lists the mallets take turns.
#[test]
fn notes_strike_the_mallets_the_scene_gives_them() {
    let scene = small_kit("notes = [60]", "notes = [62, 60]");
    let mut inst = kit_instrument(&scene, 0.0);
    render(&mut inst, &[on(0, 61, 0.7)], 4800);
    assert_eq!(started(&inst)[..2], [0, 0], "61 strikes nothing");
    assert_eq!(inst.active_voices(), 0);
    render(&mut inst, &[on(0, 62, 0.7)], 4800);
    assert_eq!(started(&inst)[0], 0, "62: not the hammer");
    assert!(started(&inst)[1] >= 1, "62: the striker");
    let before = started(&inst);
    render(&mut inst, &[on(0, 60, 0.7)], 4800);
    let after = started(&inst);
    assert!(after[0] > before[0] && after[1] > before[1], "60: both");

    // without lists: a kit voice per key, its mallets in turn
    let mut turn = kit_instrument(&small_kit("", ""), 0.0);
    assert!(kit(&turn).pitched && !kit(&inst).pitched);
    let mut seen = Vec::new();
    for _ in 0..4 {
        let before = started(&turn);
        render(&mut turn, &[on(0, 40, 0.7)], 2400);
        let after = started(&turn);
        seen.push([after[0] > before[0], after[1] > before[1]]);
    }
    assert_eq!(
        seen,
        [[true, false], [false, true], [true, false], [false, true]],
        "in turn"
    );
    assert_eq!(turn.active_voices(), 1, "one key, one voice");
    // another key: another voice, at its pitch, its first mallet
    render(&mut turn, &[on(0, 52, 0.7)], 2400);
    assert_eq!(turn.active_voices(), 2);
    let other = kit(&turn).voice_state(1).unwrap();
    let octave = other.time_scale() / kit(&turn).state().time_scale();
    assert!((octave - 2.0).abs() < 1e-15, "an octave up: {octave}");
    assert!(other.stats.contacts_started[0] >= 1 && other.stats.contacts_started[1] == 0);
}

/// However the host splits its blocks, and with a lookahead, the kit's
/// samples are the same (the lookahead's: that many samples later).
#[test]
fn a_kit_renders_the_same_in_any_blocks_and_with_a_lookahead() {
    // with a damper, pressure and note-offs: their decisions are on the
    // grid and at events, not where blocks end
    let mut scene = two_mallets();
    scene.play = Some(crate::scene::PlaySpec {
        damper: Some(0.5),
        ..Default::default()
    });
    let press = |offset, value| TimedEvent {
        offset,
        event: Event::ChannelPressure { value },
    };
    let events = [
        on(10, 60, 0.9),
        on(700, 62, 0.5),
        press(1500, 0.7),
        press(2500, 0.0),
        on(3000, 60, 1.0),
        off(4000, 62),
        off(7000, 60),
    ];
    let n = 12_000;
    let mut first = kit_instrument(&scene, 0.0);
    let whole = render(&mut first, &events, n);
    assert!(first.stats.pressed_samples > 0, "pressed");
    let mut inst = kit_instrument(&scene, 0.0);
    let (mut l, mut r) = (vec![0.0f32; n], vec![0.0f32; n]);
    let (mut pos, mut i) = (0, 0);
    for len in [1usize, 7, 64, 333, 5].iter().cycle() {
        if pos >= n {
            break;
        }
        let end = (pos + len).min(n);
        let evs: Vec<TimedEvent> = events
            .iter()
            .filter(|e| (pos..end).contains(&e.offset))
            .map(|e| TimedEvent {
                offset: e.offset - pos,
                ..*e
            })
            .collect();
        inst.process(&evs, &mut l[pos..end], &mut r[pos..end]);
        pos = end;
        i += 1;
    }
    assert!(i > 100);
    assert_eq!(l, whole[0], "blocks");
    assert_eq!(r, whole[1], "blocks");
    let mut ahead = kit_instrument(&scene, 0.005);
    let la = ahead.lookahead();
    assert!(la > 200);
    let delayed = render(&mut ahead, &events, n + la);
    assert!(delayed[0][..la].iter().all(|&x| x == 0.0));
    assert_eq!(delayed[0][la..], whole[0][..], "lookahead");
}

/// A kit voice stops when it has gone silent, and the next note wakes it
/// at rest: the same samples as the first note's. On a kit without a
/// damper, note-off, the pedals and note expressions change nothing.
#[test]
fn a_kit_stops_when_silent_and_wakes_at_rest() {
    let mut scene = small_kit("", "");
    scene.play = Some(crate::scene::PlaySpec {
        damper: Some(0.0),
        ..Default::default()
    });
    let mut inst = kit_instrument(&scene, 0.0);
    let n = 4800;
    let first = render(&mut inst, &[on(0, 50, 0.6)], n);
    assert_eq!(inst.active_voices(), 1);
    // ringing on: every event that is not a note (nor a bend or a
    // tuning) changes nothing
    let extra = [
        TimedEvent {
            offset: 3,
            event: Event::NoteOff { key: 50 },
        },
        TimedEvent {
            offset: 11,
            event: Event::Sustain { down: true },
        },
        TimedEvent {
            offset: 13,
            event: Event::NoteBrightness {
                key: Some(50),
                value: 1.0,
            },
        },
        TimedEvent {
            offset: 17,
            event: Event::Sustain { down: false },
        },
        TimedEvent {
            offset: 19,
            event: Event::AllNotesOff,
        },
    ];
    let mut quiet = kit_instrument(&scene, 0.0);
    render(&mut quiet, &[on(0, 50, 0.6)], n);
    let a = render(&mut inst, &extra, n);
    let b = render(&mut quiet, &[], n);
    assert!(a == b, "events that are not notes change nothing");
    let t = 2 * n + until_silent(&mut inst);
    println!("silent after {:.3} s", t as f64 / RATE);
    assert_eq!(inst.active_voices(), 0, "stopped");
    assert!(inst.stats.silent_stops >= 1);
    assert!(t < 3 * RATE as usize, "the modes decay in 0.15 s");
    // woken at rest, a key's voice starts its turn again: the same
    // throw, the same samples; a note while it rings throws the other
    // mallet
    let again = render(&mut inst, &[on(0, 50, 0.6)], n);
    assert!(again == first, "woke at rest, the same throw");
    let second = render(&mut inst, &[on(0, 50, 0.6)], n);
    assert!(second != first, "the second mallet");
    until_silent(&mut inst);
    assert!(render(&mut inst, &[on(0, 50, 0.6)], n) == first);
}

/// Render until the kit stops (at most 10 s); the samples it took.
fn until_silent(inst: &mut Instrument) -> usize {
    let mut t = 0;
    while inst.active_voices() > 0 && t < 10 * RATE as usize {
        render(inst, &[], 480);
        t += 480;
    }
    t
}

/// A swap (a recompile: the Hardness knob) while the kit rings with no
/// contact closed carries it to the new kit through the physical state:
/// the energy is the same after as before, the voice rings on and the next
/// throw meets the new stiffness. A swap while a contact is closed fades
/// the old kit out over the fade and starts the new one at rest; nothing
/// is not a number, and the old box is retired.
#[test]
fn a_kit_swap_carries_it_out_of_contact_and_fades_it_in_contact() {
    let scene = two_mallets();
    let harder = || {
        let sp = SceneParams {
            stiffness_factor: 2.0,
            ..SceneParams::default()
        };
        prepare_scene(&scene, &sp, RATE, 1).unwrap()
    };
    // out of contact: carried
    let mut inst = kit_instrument(&scene, 0.0);
    render(&mut inst, &[on(0, 60, 1.0)], 2000);
    while kit(&inst).state().active() != 0 {
        render(&mut inst, &[], 1);
    }
    let before = kit(&inst).state().observe(&kit(&inst).sc).energy;
    assert!(inst.install(harder()).is_ok());
    let after = kit(&inst).state().observe(&kit(&inst).sc).energy;
    let rel = (after - before).abs() / before;
    println!("carried: energy {before:.6e} J before, {after:.6e} J after ({rel:.1e})");
    assert!(rel < 1e-12, "{rel:e}");
    assert_eq!((inst.active_voices(), inst.stats.voices_carried), (1, 1));
    assert_eq!(inst.stats.voices_faded, 0);
    assert_eq!(
        kit(&inst).sc.model.contacts[0].stiffness_n_per_m,
        2.0 * 282102.0
    );
    let fade = (FADE_S * RATE).round() as usize;
    let rings = render(&mut inst, &[], 4 * fade);
    let tail = rings[0][3 * fade..]
        .iter()
        .fold(0.0f32, |a, &x| a.max(x.abs()));
    assert!(tail > 1e-3, "rings on after the fade's length: {tail:e}");
    let started = kit(&inst).state().stats.contacts_started[1];
    render(&mut inst, &[on(0, 60, 1.0)], 2000);
    assert!(
        kit(&inst).state().stats.contacts_started[1] > started,
        "the next throw"
    );

    // a Decay change gives the free modes other blocks: the same energy
    let shorter = SceneParams {
        decay_scale: 0.25,
        ..SceneParams::default()
    };
    while kit(&inst).state().active() != 0 {
        render(&mut inst, &[], 1);
    }
    let before = kit(&inst).state().observe(&kit(&inst).sc).energy;
    assert!(inst
        .install(prepare_scene(&scene, &shorter, RATE, 2).unwrap())
        .is_ok());
    let after = kit(&inst).state().observe(&kit(&inst).sc).energy;
    let rel = (after - before).abs() / before;
    println!("Decay 0.25: energy {before:.6e} J before, {after:.6e} J after ({rel:.1e})");
    assert!(rel < 1e-12, "{rel:e}");
    assert_eq!(inst.stats.voices_carried, 2);

    // in contact: faded
    let mut inst = kit_instrument(&scene, 0.0);
    render(&mut inst, &[on(0, 60, 1.0)], 10);
    assert_ne!(kit(&inst).state().active(), 0, "in contact");
    assert!(inst.install(harder()).is_ok());
    assert_eq!(inst.active_voices(), 0, "the old kit fades");
    let out = render(&mut inst, &[], 2 * fade);
    assert!(out[0][..fade / 4].iter().any(|&x| x != 0.0), "fading");
    assert!(out[0][fade + 1..].iter().all(|&x| x == 0.0), "faded");
    assert_eq!(inst.stats.voices_faded, 1);
    assert!(inst.retired_slots_mut().iter().any(|s| s.is_some()));
    let new = render(&mut inst, &[on(0, 60, 1.0)], 2000);
    assert!(new[0].iter().all(|x| x.is_finite()) && new[0].iter().any(|&x| x != 0.0));
}

/// A pitch bend and a per-note tuning reach a kit's voices, as they reach
/// the voices of one contact: a kit voice with no contact closed takes the
/// bend (its time scale the key's pitch times the bend, the energy kept:
/// `tests/multi_strike.rs`), one in contact waits for the contact to end;
/// a key's tuning moves only that key's kit voice; a new key starts at
/// the bend. A kit whose mallets list notes is one voice for every key: a
/// tuning of one key leaves it, a tuning of every note moves it.
#[test]
fn a_kit_bends_and_takes_per_note_tuning() {
    let ev = |offset: usize, event: Event| TimedEvent { offset, event };
    let range = PlayParams::default().bend_range_semitones;
    // the marimba rings for seconds (the small kit's modes decay in 0.15 s)
    let mut inst = kit_instrument(&two_mallets(), 0.0);
    let root = inst.prepared().root_note as u8;
    let scale = |inst: &Instrument, i: usize| kit(inst).voice_state(i).unwrap().time_scale();
    // the bend arrives with the note: in contact the voice waits
    render(&mut inst, &[on(0, root, 0.8)], 1);
    let mut was_in = false;
    let mut waited = 0;
    let mut last = scale(&inst, 0);
    render(&mut inst, &[ev(0, Event::PitchBend { value: 1.0 })], 1);
    for _ in 0..2400 {
        let inside = kit(&inst).voice_state(0).unwrap().active() != 0;
        let now = scale(&inst, 0);
        if inside && was_in {
            assert_eq!(now, last, "bent in contact");
            waited += 1;
        }
        (was_in, last) = (inside, now);
        render(&mut inst, &[], 1);
    }
    assert!(waited > 10, "{waited} samples in contact");
    render(&mut inst, &[], 4800);
    let bent = 2f64.powf(range / 12.0);
    println!("bend: {:.15} (want {bent:.15})", scale(&inst, 0));
    assert!((scale(&inst, 0) - bent).abs() < 1e-12);
    // a key's tuning moves that key's voice only
    render(&mut inst, &[on(0, root + 12, 0.8)], 4800);
    assert!(
        (scale(&inst, 1) - 2.0 * bent).abs() < 1e-12,
        "{}",
        scale(&inst, 1)
    );
    let tune = Event::NoteTuning {
        key: Some(root),
        semitones: 1.0,
    };
    render(&mut inst, &[ev(0, tune)], 9600);
    assert!((scale(&inst, 0) - 2f64.powf((range + 1.0) / 12.0)).abs() < 1e-12);
    assert!((scale(&inst, 1) - 2.0 * bent).abs() < 1e-12);
    // a kit of listed notes: one voice for every key
    let mut listed = kit_instrument(&small_kit("notes = [60]", "notes = [62, 60]"), 0.0);
    render(&mut listed, &[on(0, 60, 0.8)], 4800);
    let tune = |key| Event::NoteTuning {
        key,
        semitones: 2.0,
    };
    render(&mut listed, &[ev(0, tune(Some(60)))], 4800);
    assert_eq!(scale(&listed, 0), 1.0);
    // struck again, so that it sounds while it glides
    render(&mut listed, &[on(0, 60, 0.8), ev(1, tune(None))], 3000);
    assert!(listed.active_voices() > 0);
    assert!((scale(&listed, 0) - 2f64.powf(2.0 / 12.0)).abs() < 1e-12);
}

/// A kit with gravity (a ball between two plates) drops its ball from the
/// drop height; velocity 127 on all 128 keys in one block and a note on
/// every sample stay finite and within the ceiling, and a ball wedged
/// between the plates is refused rather than pushed into one.
#[test]
fn a_bouncing_kit_takes_every_key_at_once() {
    let scene =
        Scene::from_toml_str(include_str!("../../../presets/ball-between-plates.toml")).unwrap();
    let mut inst = kit_instrument(&scene, 0.0);
    let mut events: Vec<TimedEvent> = (0..128u8).map(|k| on(10, k, 1.0)).collect();
    events.extend((0..256).map(|i| on(1000 + i, (i * 37 % 128) as u8, 1.0)));
    let out = render(&mut inst, &events, 24_000);
    let peak = out[0].iter().fold(0.0f32, |a, &x| a.max(x.abs()));
    println!(
        "ball: peak {peak:.3}, strikes refused {}, contacts {:?}",
        kit(&inst).refused,
        kit(&inst).state().stats.contacts_started
    );
    assert!(out.iter().flatten().all(|x| x.is_finite()));
    assert!(f64::from(peak) <= OUTPUT_CEILING && peak > 0.0);
    assert!(kit(&inst).state().stats.contacts_started[0] > 0);
    assert_eq!(inst.stats.notes, 128 + 256);
    assert_eq!(
        kit(&inst).refused,
        0,
        "the ball always finds room under the lid"
    );
}

/// The live view sees every contact of a kit as a voice of its own: the
/// wind chimes' clapper and both touches between the tubes, each with its
/// sides' motion and its contact intervals, and the motion the probe gets
/// is the kit's own (the same samples as without the view).
#[test]
fn the_live_view_shows_every_contact_of_a_kit() {
    use std::sync::{Arc, Mutex};
    #[derive(Default)]
    struct Seen {
        in_contact: [usize; 4],
        samples: [usize; 4],
        keys: [u8; 4],
        finite: bool,
    }
    struct Probe(Arc<Mutex<Seen>>);
    impl VoiceProbe for Probe {
        fn voice_chunk(&mut self, c: &VoiceChunk) {
            let mut s = self.0.lock().unwrap();
            s.samples[c.voice] += c.motion.len();
            s.in_contact[c.voice] += c.motion.iter().filter(|m| m.in_contact).count();
            s.keys[c.voice] = c.key;
            s.finite = c.motion.iter().all(|m| {
                [m.x_hammer, m.v_hammer, m.x_contact, m.v_contact]
                    .iter()
                    .all(|x| x.is_finite())
            }) && c.energy_j.is_some_and(f64::is_finite);
        }
    }
    let scene = Scene::from_toml_str(include_str!("../../../presets/wind-chimes.toml")).unwrap();
    let seen = Arc::new(Mutex::new(Seen::default()));
    let mut viewed = kit_instrument(&scene, 0.0);
    viewed.set_probe(Some(Box::new(Probe(seen.clone()))));
    viewed.set_probe_on(true);
    let n = 96_000;
    let a = render(&mut viewed, &[on(0, 72, 1.0)], n);
    let b = render(&mut kit_instrument(&scene, 0.0), &[on(0, 72, 1.0)], n);
    assert!(a == b, "the view changes no sample");
    let s = seen.lock().unwrap();
    println!(
        "chimes in the live view: samples {:?}, in contact {:?}",
        s.samples, s.in_contact
    );
    assert!(s.finite);
    assert_eq!(s.samples[..3], [n, n, n]);
    assert_eq!(s.samples[3], 0, "three contacts");
    assert!(
        s.in_contact[..3].iter().all(|&c| c > 0),
        "{:?}",
        s.in_contact
    );
    assert_eq!(s.keys[0], 72, "the clapper's contact under its key");
}

/// Random abuse of kits (a debug build's assertions armed): swaps between
/// every kit preset and a preset of one contact with random parameters,
/// random play parameters (polyphony, lookahead, drop height, pitch
/// tracking), notes with random keys and velocities (not-a-number
/// included), every other event; every sample finite and within the
/// ceiling, no panic.
#[test]
fn kits_take_random_abuse() {
    use crate::test_rng::TestRng;
    let mut rng = TestRng(0x0b1e);
    let kits: Vec<usize> = (0..crate::presets::COUNT)
        .filter(|&i| crate::presets::is_kit(i))
        .collect();
    let bar = crate::presets::index_of("marimba-bar").unwrap();
    let mut sp = SceneParams {
        preset: kits[0],
        ..SceneParams::default()
    };
    let mut inst = Instrument::new(prepare(&sp, RATE, 0).unwrap(), PlayParams::default());
    let mut revision = 1;
    for round in 0..60 {
        if round % 4 == 1 {
            sp.preset = if rng.below(5) == 0 {
                bar
            } else {
                kits[rng.below(kits.len())]
            };
            sp.stiffness_factor = [0.01, 1.0, 10.0, f64::NAN][rng.below(4)];
            sp.hammer_mass_factor = [0.1, 1.0, 4.0][rng.below(3)];
            sp.decay_scale = [0.05, 1.0, 3.0][rng.below(3)];
            sp.strike_pos_norm = [None, Some(0.0), Some(0.7)][rng.below(3)];
            sp.damper_custom = rng.below(2) == 0;
            sp.damper_norm = [0.0, 0.5, 1.0][rng.below(3)];
            sp.variants = crate::instrument::VariantSet {
                position: rng.below(2) == 0,
                damper: rng.below(2) == 0,
            };
            if let Ok(p) = prepare(&sp, RATE, revision) {
                revision += 1;
                if inst.can_install() {
                    let _ = inst.install(p);
                }
            }
            for slot in inst.retired_slots_mut() {
                slot.take();
            }
        }
        if round % 5 == 2 {
            let play = PlayParams {
                polyphony: 1 + rng.below(64),
                pitch_tracking: rng.below(2) == 0,
                drop_height_m: [0.0, 0.02, 0.3, f64::NAN][rng.below(4)],
                lookahead_s: [0.0, 0.005, 0.04][rng.below(3)],
                ..PlayParams::default()
            };
            inst.set_play(play);
            inst.set_lookahead(lookahead_samples(play.lookahead_s, RATE));
        }
        let n = 1 + rng.below(2000);
        let mut events = Vec::new();
        for _ in 0..rng.below(40) {
            let offset = rng.below(n);
            let key = rng.below(128) as u8;
            let key_or_all = [Some(key), None][rng.below(2)];
            let event = match rng.below(10) {
                0..=2 => Event::NoteOn {
                    key,
                    velocity_norm: [rng.unit(), 1.0, f64::NAN, 0.0][rng.below(4)],
                },
                3 => Event::NoteOff { key },
                4 => Event::PitchBend {
                    value: rng.uniform(-1.0, 1.0),
                },
                5 => Event::ChannelPressure {
                    value: [rng.unit(), 1.0, f64::NAN][rng.below(3)],
                },
                6 => Event::NotePosition {
                    key: key_or_all,
                    offset: [rng.uniform(-0.5, 0.5), f64::NAN][rng.below(2)],
                },
                7 => Event::NoteDamper {
                    key: key_or_all,
                    offset: [rng.uniform(-1.0, 1.0), f64::NAN][rng.below(2)],
                },
                8 => Event::NoteHardness {
                    key: key_or_all,
                    factor: [rng.uniform(0.1, 8.0), f64::NAN, 0.0][rng.below(3)],
                },
                _ => Event::Sustain {
                    down: rng.below(2) == 0,
                },
            };
            events.push(TimedEvent { offset, event });
        }
        events.sort_by_key(|e| e.offset);
        let out = render(&mut inst, &events, n);
        assert!(
            out.iter()
                .flatten()
                .all(|x| x.is_finite() && f64::from(x.abs()) <= OUTPUT_CEILING),
            "round {round}"
        );
    }
    println!("kits: {:?}", inst.stats);
}

/// A pitched kit steals as a voice of one contact does: at polyphony 1,
/// a new key takes the ringing kit voice, whose running state fades out
/// over [`FADE_S`] in a spare kit state while the new key starts at once
/// on a state at rest: the output is the old key times the fade's gain
/// plus the new key alone, sample by sample (cutting it would miss that by
/// the old key's amplitude). The contacts the fade's state starts still count.
#[test]
fn a_stolen_kit_voice_fades_out_while_the_new_key_starts() {
    let scene = two_mallets();
    let run = |events: &[TimedEvent], n: usize| {
        let p = prepare_scene(&scene, &SceneParams::default(), RATE, 0).unwrap();
        let play = PlayParams {
            gain_db: 0.0,
            polyphony: 1,
            ..PlayParams::default()
        };
        let mut inst = Instrument::new(p, play);
        let out = render(&mut inst, events, n);
        (out, inst)
    };
    let (t0, n) = (14_400, 19_200);
    let fade = (FADE_S * RATE).round() as usize;
    let (y, inst) = run(&[on(0, 57, 0.8), on(t0, 64, 0.8)], n);
    let (a, alone) = run(&[on(0, 57, 0.8)], n);
    let (b, _) = run(&[on(t0, 64, 0.8)], n);
    assert_eq!((inst.stats.steals, inst.stats.steals_faded), (1, 1));
    assert_eq!(inst.voice_keys()[0], Some(64));
    let gain = |k: usize| steal_fade_gain(k, t0, fade);
    for ch in 0..2 {
        let (mut worst, mut cut) = (0.0f64, 0.0f64);
        for k in 0..n {
            let old = gain(k) * f64::from(a[ch][k]);
            worst = worst.max((f64::from(y[ch][k]) - old - f64::from(b[ch][k])).abs());
            if k >= t0 {
                cut = cut.max(old.abs());
            }
        }
        println!("channel {ch}: {worst:e} from the faded sum, a cut would miss by {cut:e}");
        assert!(
            worst <= 1e-6 && cut > 1e-3,
            "channel {ch}: {worst:e}, {cut:e}"
        );
    }
    // the old key's contacts (up to the steal) are still counted
    let both = started(&inst).iter().sum::<u64>();
    assert!(both >= started(&alone).iter().sum::<u64>(), "{both}");
}

/// A note's brightness plays a kit voice at its hardness level, as it
/// plays a voice of one contact (docs/plugin.md, "Brightness"): the kit
/// compiles its four other levels; brightness 1 at the note's onset throws
/// with every mallet's spring `TIMBRE_STIFFNESS_STEP^2` = 4 times as stiff,
/// the same samples as the kit prepared at Hardness x4 struck alike (the
/// voice carried through the physical state before its mallet lands:
/// rounding); brightness 0.5, level 0, changes nothing.
#[test]
fn brightness_plays_a_kit_voice_at_its_hardness_level() {
    let scene = ringing_kit(0.0);
    let mut a = kit_instrument(&scene, 0.0);
    assert_eq!(kit(&a).hardness_levels(), 4);
    let key = a.cur.root_note as u8;
    let bright = |value| TimedEvent {
        offset: 0,
        event: Event::NoteBrightness {
            key: Some(key),
            value,
        },
    };
    let n = 4800;
    let [ra, _] = render(&mut a, &[on(0, key, 0.8), bright(1.0)], n);
    let harder = SceneParams {
        stiffness_factor: TIMBRE_STIFFNESS_STEP.powi(2),
        ..SceneParams::default()
    };
    let play = PlayParams {
        gain_db: 0.0,
        ..PlayParams::default()
    };
    let mut b = Instrument::new(prepare_scene(&scene, &harder, RATE, 0).unwrap(), play);
    let [rb, _] = render(&mut b, &[on(0, key, 0.8)], n);
    let [rc, _] = render(&mut kit_instrument(&scene, 0.0), &[on(0, key, 0.8)], n);
    let [rd, _] = render(
        &mut kit_instrument(&scene, 0.0),
        &[on(0, key, 0.8), bright(0.5)],
        n,
    );
    let peak = rb.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let diff = |x: &[f32], y: &[f32]| {
        x.iter()
            .zip(y)
            .fold(0.0f32, |m, (p, q)| m.max((p - q).abs()))
    };
    let (same, other) = (diff(&ra, &rb), diff(&ra, &rc));
    println!(
        "brightness 1 against Hardness x4: {same:.2e} of peak {peak:.3e}; against level 0: {other:.2e}"
    );
    assert!(same <= 1e-6 * peak, "{same:e}");
    assert!(other > 1e-2 * peak, "{other:e}");
    assert!(rd == rc, "level 0 is the played compile");
}

/// The several-contact engine and the engine of one contact make the same
/// arithmetic, and a kit voice falls silent by the rule of a voice of one
/// contact: the two-mallet marimba (the marimba-bar preset's bar, pickup
/// and mallet, with a second mallet that a note on a pitched kit does not
/// throw) played as a kit gives the samples of marimba-bar played as
/// voices of one contact, bit for bit, at and away from the root, at
/// several velocities, through a release on the damped compile (Custom
/// damper) and with two keys sounding, and each kit voice stops at the
/// same sample as its voice of one contact.
#[test]
fn a_kit_of_one_thrown_mallet_plays_the_one_contact_voice_bit_for_bit() {
    let play = PlayParams {
        gain_db: 0.0,
        ..PlayParams::default()
    };
    let prepared = |name: &str| {
        let sp = SceneParams {
            preset: crate::presets::index_of(name).unwrap(),
            damper_custom: true,
            damper_norm: 0.5,
            ..SceneParams::default()
        };
        prepare(&sp, RATE, 0).unwrap()
    };
    let root = prepared("marimba-bar").root_note.round() as u8;
    let n = 12_000;
    for events in [
        vec![on(0, root, 0.8), off(4000, root)],
        vec![on(10, root - 12, 0.3), off(6000, root - 12)],
        vec![
            on(0, root + 7, 1.0),
            on(2000, root, 0.5),
            off(5000, root + 7),
        ],
    ] {
        let mut kit = Instrument::new(prepared("marimba-two-mallets"), play);
        assert!(kit.cur.kit.is_some());
        let mut one = Instrument::new(prepared("marimba-bar"), play);
        assert!(one.cur.kit.is_none());
        let a = render(&mut kit, &events, n);
        let b = render(&mut one, &events, n);
        let peak = b[0].iter().fold(0.0f32, |m, x| m.max(x.abs()));
        let diff = a[0]
            .iter()
            .zip(&b[0])
            .fold(0.0f32, |m, (p, q)| m.max((p - q).abs()));
        let last = a[0].iter().rposition(|&x| x != 0.0);
        println!(
            "kit against one contact: {diff:.1e} of peak {peak:.3e}, last sounding sample {last:?}, \
             {} stops",
            one.stats.silent_stops
        );
        assert!(peak > 1e-3);
        assert!(a == b, "differ by {diff:e}");
        assert_eq!(kit.stats.silent_stops, one.stats.silent_stops);
        assert_eq!(kit.active_voices(), one.active_voices());
    }
}

/// Every kit preset's voice falls silent after a note and stops: the
/// ball between two plates comes to rest lying on a plate (a contact
/// closed, so it stops on its output), the others with no contact closed
/// (on their energy, as voices of one contact).
#[test]
fn every_kit_preset_falls_silent_after_a_note() {
    for i in (0..crate::presets::COUNT).filter(|&i| crate::presets::is_kit(i)) {
        let sp = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        let p = prepare(&sp, RATE, 0).unwrap();
        let root = p.root_note.round() as u8;
        let mut inst = Instrument::new(p, PlayParams::default());
        render(&mut inst, &[on(0, root, 0.8)], 4800);
        let t = until_silent(&mut inst);
        let name = crate::presets::PRESETS[i].name;
        println!(
            "{name}: silent {:.2} s after the first 0.1 s",
            t as f64 / RATE
        );
        assert_eq!(inst.active_voices(), 0, "{name}");
        assert_eq!(inst.stats.silent_stops, 1, "{name}");
    }
}
