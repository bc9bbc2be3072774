//! Tests of the instrument: mappings, voices, swaps, fades.

use super::*;
use crate::compile::{compile_with, CompiledScene};
use crate::physics::model::LN_1000;
use crate::presets;
use crate::scene::{ObjectSpec, Scene, Switching};

const RATE: f64 = 44_100.0;

fn params(preset: &str) -> InstrumentParams {
    let mut p = InstrumentParams::default();
    p.scene.preset = presets::index_of(preset).unwrap();
    p
}

fn base(preset: &str) -> Scene {
    presets::scene(presets::index_of(preset).unwrap()).unwrap()
}

/// A preset with its physical objects expanded to their modes at `RATE`
/// (docs/design.md, "Objects from geometry and material"): for the tests
/// of what the instrument does to a modal object.
fn modal_base(preset: &str) -> Scene {
    base(preset).expanded(RATE).unwrap()
}

fn instrument(p: &InstrumentParams) -> Instrument {
    Instrument::new(prepare(&p.scene, RATE, 0).unwrap(), p.play)
}

pub(super) fn render(inst: &mut Instrument, events: &[TimedEvent], n: usize) -> [Vec<f32>; 2] {
    let mut l = vec![0.0; n];
    let mut r = vec![0.0; n];
    inst.process(events, &mut l, &mut r);
    [l, r]
}

/// The gain of a voice stolen at sample `t0` at sample `k`: 1 before the
/// steal, then a linear ramp to 0 over `fade` samples (docs/plugin.md,
/// "Velocity, pitch, voices"), written out here, not taken from the mixer.
pub(super) fn steal_fade_gain(k: usize, t0: usize, fade: usize) -> f64 {
    if k < t0 {
        1.0
    } else {
        (fade.saturating_sub(k - t0)) as f64 / fade as f64
    }
}

pub(super) fn on(offset: usize, key: u8, vel: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteOn {
            key,
            velocity_norm: vel,
        },
    }
}

fn off(offset: usize, key: u8) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteOff { key },
    }
}

/// The left channel of `n` samples rendered in blocks of the lengths
/// `lens` (cycled), each block given the events that fall in it.
fn render_split(
    inst: &mut Instrument,
    events: &[TimedEvent],
    n: usize,
    lens: &[usize],
) -> Vec<f32> {
    let (mut left, mut right) = (vec![0.0f32; n], vec![0.0f32; n]);
    let (mut pos, mut ev) = (0, 0);
    for len in lens.iter().cycle() {
        if pos >= n {
            break;
        }
        let end = (pos + len).min(n);
        let mut evs = Vec::new();
        while ev < events.len() && events[ev].offset < end {
            evs.push(TimedEvent {
                offset: events[ev].offset - pos,
                ..events[ev]
            });
            ev += 1;
        }
        inst.process(&evs, &mut left[pos..end], &mut right[pos..end]);
        pos = end;
    }
    left
}

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

#[test]
fn velocity_mapping_endpoints_and_monotone() {
    assert_eq!(impact_speed_m_per_s(0.0), 0.05);
    assert!((impact_speed_m_per_s(1.0) - 3.0).abs() < 1e-12);
    assert!((impact_speed_m_per_s(0.5) - (0.05 + 2.95 * 0.25)).abs() < 1e-12);
    assert_eq!(impact_speed_m_per_s(f64::NAN), 0.05);
    assert_eq!(impact_speed_m_per_s(7.0), impact_speed_m_per_s(1.0));
}

#[test]
fn scene_for_defaults_keep_the_scene() {
    for (i, _) in presets::PRESETS.iter().enumerate() {
        let b = presets::scene(i).unwrap();
        let mut p = InstrumentParams::default();
        p.scene.switching = Switching::OffsetRod;
        let mut expect = b.clone();
        expect.contact.switching = Some(Switching::OffsetRod);
        assert_eq!(scene_for(&b, &p), expect, "{}", b.name);
    }
}

#[test]
fn scene_for_scales_hammer_contact_and_decay() {
    let b = modal_base("marimba-bar");
    let mut p = params("marimba-bar");
    p.scene.hammer_mass_factor = 2.0;
    p.scene.stiffness_factor = 3.0;
    p.scene.damping_factor = 0.5;
    p.scene.decay_scale = 4.0;
    let s = scene_for(&b, &p);
    assert_eq!(s.hammer.mass_kg, b.hammer.mass_kg * 2.0);
    assert_eq!(
        s.contact.stiffness_n_per_m,
        b.contact.stiffness_n_per_m * 3.0
    );
    assert_eq!(
        s.contact.damping_n_s_per_m,
        b.contact.damping_n_s_per_m * 0.5
    );
    let (ObjectSpec::Modal(m0), ObjectSpec::Modal(m1)) = (&b.object[0], &s.object[0]) else {
        panic!("modal");
    };
    for (a, c) in m0.mode.iter().zip(&m1.mode) {
        assert_eq!(c.t60_s.unwrap(), a.t60_s.unwrap() * 4.0);
        assert_eq!(c.freq_hz, a.freq_hz);
    }
    // string: Rayleigh and dashpots over the decay scale
    let b = base("paper-string");
    let mut p = params("paper-string");
    p.scene.decay_scale = 2.0;
    let s = scene_for(&b, &p);
    let (ObjectSpec::String(s0), ObjectSpec::String(s1)) = (&b.object[0], &s.object[0]) else {
        panic!("string");
    };
    assert_eq!(s1.rayleigh_alpha_per_s, s0.rayleigh_alpha_per_s / 2.0);
    assert_eq!(s1.rayleigh_beta_s, s0.rayleigh_beta_s / 2.0);
    assert_eq!(s1.dashpots[0].n_s_per_m, s0.dashpots[0].n_s_per_m / 2.0);
}

#[test]
fn strike_position_moves_the_string_contact_and_interpolates_modal_weights() {
    let b = base("paper-string");
    let mut p = params("paper-string");
    p.scene.strike_pos_norm = Some(0.5);
    let s = scene_for(&b, &p);
    let ObjectSpec::String(st) = &s.object[0] else {
        panic!()
    };
    assert_eq!(st.points["contact"], 25); // round(0.5 * 49)
    p.scene.strike_pos_norm = Some(1.0);
    let ObjectSpec::String(st) = &scene_for(&b, &p).object[0] else {
        panic!()
    };
    assert_eq!(st.points["contact"], 49);

    // a modal object with 3 points: contact, pickup, pickup2 (samples at 0,
    // 0.5, 1): the steel plate as a table of modes, before it became a
    // physical description
    let b = Scene::from_toml_str(include_str!(
        "../../tests/data/modal-presets/steel-plate.toml"
    ))
    .unwrap();
    let mut p = params("steel-plate");
    p.scene.strike_pos_norm = Some(0.75);
    let s = scene_for(&b, &p);
    let (ObjectSpec::Modal(m0), ObjectSpec::Modal(m1)) = (&b.object[0], &s.object[0]) else {
        panic!()
    };
    for (a, c) in m0.mode.iter().zip(&m1.mode) {
        let want = 0.5 * a.weights[1] + 0.5 * a.weights[2];
        assert!((c.weights[0] - want).abs() < 1e-12);
        assert_eq!(&c.weights[1..], &a.weights[1..]);
    }
    p.scene.strike_pos_norm = Some(0.0);
    assert_eq!(
        scene_for(&b, &p).object,
        b.object,
        "position 0 = first point"
    );

    // two points: ignored
    let b = modal_base("wood-block");
    let mut p = params("wood-block");
    p.scene.strike_pos_norm = Some(0.3);
    assert_eq!(scene_for(&b, &p).object, b.object);
}

#[test]
fn gravity_only_for_bouncing_scenes() {
    let mut p = params("paper-bounce");
    p.scene.gravity_m_per_s2 = 3.0;
    assert_eq!(
        scene_for(&base("paper-bounce"), &p).hammer.gravity_m_per_s2,
        3.0
    );
    let mut p = params("bell");
    p.scene.gravity_m_per_s2 = 3.0;
    assert_eq!(scene_for(&base("bell"), &p).hammer.gravity_m_per_s2, 0.0);
}

#[test]
fn damped_scene_divides_decay_times() {
    let b = modal_base("marimba-bar");
    let d = damped_scene(&b, 1.0);
    let (ObjectSpec::Modal(m0), ObjectSpec::Modal(m1)) = (&b.object[0], &d.object[0]) else {
        panic!()
    };
    for (a, c) in m0.mode.iter().zip(&m1.mode) {
        assert!((c.t60_s.unwrap() - a.t60_s.unwrap() / 51.0).abs() < 1e-12);
    }
    assert_eq!(damped_scene(&b, 0.0).object, b.object);
}

#[test]
fn root_notes() {
    assert_eq!(root_note(&base("marimba-bar")), 57.0); // 220 Hz = A3
                                                       // scenes that name their pitch (`[play] pitch_hz`): the bell's prime
                                                       // A5, not its hum (A4, its lowest mode); the chime's strike note B4,
                                                       // not its lowest mode (117 Hz, A#2)
    assert_eq!(root_note(&base("bell")), 81.0);
    assert_eq!(root_note(&base("tubular-chime")), 71.0);
    let mut unnamed = base("bell");
    unnamed.play = None;
    assert_eq!(root_note(&unnamed), 69.0); // the hum, 440 Hz
    assert_eq!(root_note(&base("paper-string")), 65.0); // ~350 Hz = F4
    let mut wall = base("paper-bounce");
    wall.object = vec![ObjectSpec::Wall(crate::scene::WallSpec {
        name: "plate".into(),
    })];
    assert_eq!(root_note(&wall), DEFAULT_ROOT_NOTE);
}

#[test]
fn note_sounds_from_its_offset_and_root_plays_the_scene_as_written() {
    let p = params("marimba-bar");
    let mut inst = instrument(&p);
    let at = 1000;
    let [l, r] = render(&mut inst, &[on(at, 57, 0.8)], 20_000);
    assert!(l[..=at].iter().chain(&r[..=at]).all(|x| *x == 0.0));
    assert!(l[at + 1..at + 64].iter().any(|x| *x != 0.0));
    assert!(l.iter().chain(&r).all(|x| x.is_finite()));
    // the root note at the scene's own strike speed is the scene rendered
    // directly (up to the output gain)
    let mut sc = scene_for(&base("marimba-bar"), &p);
    sc.contact.switching = Some(inst.prepared().switching_used);
    let c = compile_with(&sc, RATE, None).unwrap();
    let mut st = EngineState::new(&c);
    let v = impact_speed_m_per_s(0.8);
    st.strike(&c, 0.0, -v);
    let g = 10f64.powf(p.play.gain_db / 20.0);
    for k in 0..5000 {
        let o = st.tick(&c);
        assert!(((o[0] * g) as f32 - l[at + k]).abs() <= 1e-6 * (1.0 + l[at + k].abs()));
    }
}

#[test]
fn pitch_is_the_same_system_played_faster() {
    // One octave up at 44.1 kHz is the root at 22.05 kHz, sample for
    // sample, up to one constant factor (velocity pickups scale with s,
    // the reference strike speed with 1/s).
    let p = params("bell");
    let mut hi = instrument(&p);
    let [h, _] = render(&mut hi, &[on(0, 81, 0.7)], 4000);
    let mut lo = Instrument::new(prepare(&p.scene, RATE / 2.0, 0).unwrap(), p.play);
    let [l, _] = render(&mut lo, &[on(0, 69, 0.7)], 4000);
    let c = h.iter().zip(&l).map(|(a, b)| (a * b) as f64).sum::<f64>()
        / l.iter().map(|b| (b * b) as f64).sum::<f64>();
    let peak = h.iter().fold(0.0f32, |m, x| m.max(x.abs())) as f64;
    let err = h
        .iter()
        .zip(&l)
        .map(|(a, b)| (*a as f64 - c * *b as f64).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-4 * peak, "err {err} peak {peak} c {c}");
    // the bell's root is its prime, A5 = 81 (`[play] pitch_hz`)
    let mut p = params("bell");
    p.play.pitch_tracking = false;
    let mut inst = instrument(&p);
    let [l1, _] = render(&mut inst, &[on(0, 69, 0.7)], 4000);
    let mut inst = instrument(&params("bell"));
    let [l2, _] = render(&mut inst, &[on(0, 81, 0.7)], 4000);
    assert_eq!(l1, l2, "pitch tracking off: every key plays the root");
}

/// A host that times a note past the block's end (against the CLAP and
/// VST3 rules) has it taken at the block's end: the same samples as the
/// note at the next block's first sample, never a panic or an index out of
/// range.
#[test]
fn a_note_timed_past_the_block_end_is_taken_at_its_end() {
    let p = params("marimba-bar");
    let (n, total) = (256, 4096);
    let play = |offset: usize| {
        let mut inst = instrument(&p);
        let (mut l, mut r) = (vec![0.0f32; total], vec![0.0f32; total]);
        inst.process(&[on(offset, 57, 0.8)], &mut l[..n], &mut r[..n]);
        inst.process(&[], &mut l[n..], &mut r[n..]);
        l
    };
    let late = play(n + 1000);
    let at_end = play(n);
    assert!(late[..n].iter().all(|x| *x == 0.0));
    assert!(late[n..].iter().any(|x| *x != 0.0));
    assert_eq!(late, at_end);
    assert_eq!(play(usize::MAX), at_end);
}

#[test]
fn louder_velocity_is_louder_and_block_splitting_does_not_matter() {
    let level = |vel| {
        let mut inst = instrument(&params("wood-block"));
        rms(&render(&mut inst, &[on(0, 70, vel)], 10_000)[0])
    };
    assert!(level(0.9) > 3.0 * level(0.3));
    let events = [
        on(10, 60, 0.5),
        on(300, 64, 0.9),
        off(5000, 60),
        on(7000, 60, 0.4),
    ];
    let mut a = instrument(&params("marimba-bar"));
    let [whole, _] = render(&mut a, &events, 20_000);
    let mut b = instrument(&params("marimba-bar"));
    let split = render_split(&mut b, &events, 20_000, &[1, 7, 64, 100, 333, 512]);
    assert_eq!(whole, split);
}

#[test]
fn repeated_note_restrikes_its_ringing_voice() {
    let mut inst = instrument(&params("marimba-bar"));
    let [l, _] = render(&mut inst, &[on(0, 57, 0.8), on(4410, 57, 0.8)], 8820);
    assert_eq!(inst.active_voices(), 1);
    assert_eq!(inst.stats.notes, 2);
    // the second strike hits a moving bar: not a copy of the first
    let a = &l[..2000];
    let b = &l[4410..6410];
    assert!(a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-4));
    assert!(b.iter().all(|x| x.is_finite()));
}

#[test]
fn voice_stealing_takes_the_quietest_voice() {
    let p = params("marimba-bar");
    let poly = p.play.polyphony;
    let mut inst = instrument(&p);
    let mut events: Vec<TimedEvent> = (0..poly as u8)
        .map(|i| on(10 * i as usize, 40 + i, if i == 5 { 0.05 } else { 0.9 }))
        .collect();
    events.push(on(1000, 100, 0.9));
    render(&mut inst, &events, 1100);
    let keys = inst.voice_keys();
    assert_eq!(inst.stats.steals, 1);
    assert!(
        !keys.contains(&Some(45)),
        "the soft note was stolen: {keys:?}"
    );
    assert!(keys.contains(&Some(100)));
    assert_eq!(inst.active_voices(), poly);
}

#[test]
fn damper_shortens_the_release_and_silent_voices_stop() {
    let tail = |damper: f64| {
        let mut p = params("marimba-bar");
        p.scene.damper_norm = damper;
        p.scene.damper_custom = true;
        let mut inst = instrument(&p);
        let [l, _] = render(&mut inst, &[on(0, 57, 0.8), off(4410, 57)], 44_100);
        (rms(&l[22_050..]), inst)
    };
    let (free, _) = tail(0.0);
    let (damped, _) = tail(1.0);
    assert!(damped < 0.01 * free, "damped {damped} free {free}");
    let mut p = params("wood-block");
    p.scene.damper_norm = 1.0;
    p.scene.damper_custom = true;
    let mut inst = instrument(&p);
    render(&mut inst, &[on(0, 70, 1.0), off(100, 70)], 44_100);
    assert_eq!(
        inst.active_voices(),
        0,
        "a damped wood block is silent after 1 s"
    );
    assert_eq!(inst.stats.silent_stops, 1);
}

#[test]
fn non_finite_voice_is_reset_and_counted() {
    let mut inst = instrument(&params("marimba-bar"));
    let [_, _] = render(&mut inst, &[on(0, 57, 0.8)], 4410);
    inst.voice_state_mut(0).free_state_mut()[0] = f64::NAN;
    let [l, r] = render(&mut inst, &[], 4410);
    assert!(l.iter().chain(&r).all(|x| x.is_finite()));
    assert_eq!(inst.stats.nonfinite_resets, 1);
    assert_eq!(inst.active_voices(), 0);
}

#[test]
fn swap_carries_voices_without_a_jump_and_preset_change_fades() {
    let p = params("marimba-bar");
    let mut inst = instrument(&p);
    let [l0, _] = render(&mut inst, &[on(0, 57, 0.8), on(5, 64, 0.8)], 4410);
    let mut q = p;
    q.scene.stiffness_factor = 1.5;
    q.scene.decay_scale = 0.7;
    let new = prepare(&q.scene, RATE, 1).unwrap();
    assert!(inst.can_install());
    inst.install(new).unwrap();
    assert_eq!(inst.stats.voices_carried, 2);
    assert_eq!(inst.active_voices(), 2);
    let [l1, _] = render(&mut inst, &[], 4410);
    let max_step = l0
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f32::max);
    assert!((l1[0] - l0[4409]).abs() <= max_step, "jump at the swap");
    // the old box is waiting to be handed back, not dropped
    assert_eq!(
        inst.retired_slots_mut()
            .iter()
            .filter(|s| s.is_some())
            .count(),
        1
    );

    let mut r = p;
    r.scene.preset = presets::index_of("bell").unwrap();
    inst.install(prepare(&r.scene, RATE, 2).unwrap()).unwrap();
    assert_eq!(inst.stats.voices_faded, 2);
    assert_eq!(inst.active_voices(), 0);
    assert!(!inst.can_install(), "fading");
    let [l2, _] = render(&mut inst, &[], 4410);
    assert!(
        (l2[0] - l1[4409]).abs() <= max_step,
        "fade starts where it was"
    );
    let fade = (FADE_S * RATE) as usize;
    assert!(l2[fade + 1..].iter().all(|x| *x == 0.0));
    assert!(inst.can_install());
    assert_eq!(
        inst.retired_slots_mut()
            .iter()
            .filter(|s| s.is_some())
            .count(),
        2
    );
}

/// The real-time warning of a stiff scene's event search: no shipped
/// preset needs it at any Hardness (its estimate stays a few nodes per
/// sample), so users only see it for their own stiff scenes.
#[test]
fn presets_need_no_realtime_warning_at_any_hardness() {
    for i in 0..presets::PRESETS.len() {
        for hf in [0.01, 1.0, 100.0] {
            let p = SceneParams {
                preset: i,
                stiffness_factor: hf,
                ..SceneParams::default()
            };
            let pr = prepare(&p, RATE, 1).unwrap();
            assert!(
                pr.realtime_warning().is_none(),
                "{} x{hf}: {:?}",
                pr.scenes.scene.name,
                pr.realtime_warning()
            );
            // a few nodes per sample near a switch; the glockenspiel's
            // brass mallet (a contact of three samples at 44.1 kHz) takes
            // about ten
            assert!(
                pr.scenes.scene.search_nodes_estimate <= 12.0,
                "{}",
                pr.scenes.scene.summary
            );
        }
    }
}

/// The f32 conversion never writes a subnormal, even with the CPU's
/// flush-to-zero off (this test thread does not turn it on), and leaves
/// every normal value as `as f32` does.
#[test]
fn output_conversion_flushes_f32_subnormals() {
    assert!(!crate::engine::denormal::FlushDenormals::active());
    let mut hits = 0;
    for x in [1e-38, -1e-39, 3e-44, 1.4e-45, 1e-300, -5e-324] {
        assert!(
            (x as f32) == 0.0 || !(x as f32).is_normal(),
            "{x} converts to a normal f32"
        );
        assert_eq!(
            super::mix::guarded(x, &mut hits).to_bits(),
            0.0f32.to_bits(),
            "{x}"
        );
    }
    for x in [1.2e-38, -1.5e-38, 1e-20, 0.3, -3.9] {
        assert_eq!(super::mix::guarded(x, &mut hits), x as f32);
        assert!(super::mix::guarded(x, &mut hits).is_normal());
    }
    assert_eq!(hits, 0);
}

fn pedal(offset: usize, sustain: bool, down: bool) -> TimedEvent {
    TimedEvent {
        offset,
        event: if sustain {
            Event::Sustain { down }
        } else {
            Event::Sostenuto { down }
        },
    }
}

/// Render `events` (sorted) and return the left channel.
fn play(events: &[TimedEvent], n: usize) -> Vec<f32> {
    // the bar damped on release (the Damper parameter's 0.5; the preset has
    // no damper of its own), so that there is something for the pedals to hold
    let mut p = params("marimba-bar");
    p.scene.damper_custom = true;
    let mut inst = instrument(&p);
    render(&mut inst, events, n)[0].clone()
}

/// The sustain pedal: a note released while it is down rings exactly as a
/// note never released (bit for bit) until the pedal comes up, and from then
/// exactly as a note released at that instant.
#[test]
fn sustain_pedal_holds_released_notes_until_it_comes_up() {
    let n = 30_000;
    let (release, pedal_up) = (4_000, 16_000);
    let held = play(
        &[pedal(0, true, true), on(10, 60, 0.8), off(release, 60)],
        n,
    );
    let never_released = play(&[on(10, 60, 0.8)], n);
    assert_eq!(held, never_released, "released under the pedal: no damper");
    let up = play(
        &[
            pedal(0, true, true),
            on(10, 60, 0.8),
            off(release, 60),
            pedal(pedal_up, true, false),
        ],
        n,
    );
    let released_then = play(&[on(10, 60, 0.8), off(pedal_up, 60)], n);
    assert_eq!(up, released_then, "pedal up = note-off then");
    // and the damper really acts: the tail is quieter than the held note's
    assert!(rms(&up[n - 4000..]) < 0.5 * rms(&never_released[n - 4000..]));
    // a key still down when the pedal comes up keeps sounding undamped
    let still_down = play(
        &[
            pedal(0, true, true),
            on(10, 60, 0.8),
            pedal(pedal_up, true, false),
        ],
        n,
    );
    assert_eq!(still_down, never_released);
}

/// The sostenuto pedal holds only the notes down when it was pressed: a
/// note struck after it is damped at its note-off as usual; the held one
/// is damped when the pedal comes up.
#[test]
fn sostenuto_holds_only_the_notes_down_when_pressed() {
    let n = 30_000;
    let events = [
        on(10, 60, 0.8),
        pedal(100, false, true),
        on(200, 67, 0.8),
        off(4_000, 60),
        off(4_000, 67),
        pedal(16_000, false, false),
    ];
    let with = play(&events, n);
    let expect = play(
        &[
            on(10, 60, 0.8),
            on(200, 67, 0.8),
            off(4_000, 67),
            off(16_000, 60),
        ],
        n,
    );
    assert_eq!(with, expect);
    // pedal down before any note holds nothing
    let early = play(&[pedal(0, false, true), on(10, 60, 0.8), off(4_000, 60)], n);
    assert_eq!(early, play(&[on(10, 60, 0.8), off(4_000, 60)], n));
}

/// Both pedals: a note held by sostenuto stays undamped when the sustain
/// pedal comes up, and the other way round.
#[test]
fn each_pedal_keeps_what_the_other_holds() {
    let n = 24_000;
    let both = play(
        &[
            on(10, 60, 0.8),
            pedal(50, false, true),
            pedal(60, true, true),
            off(2_000, 60),
            pedal(8_000, true, false),
        ],
        n,
    );
    assert_eq!(
        both,
        play(&[on(10, 60, 0.8)], n),
        "sostenuto still holds it"
    );
    let other = play(
        &[
            on(10, 60, 0.8),
            pedal(50, false, true),
            pedal(60, true, true),
            off(2_000, 60),
            pedal(8_000, false, false),
            pedal(12_000, true, false),
        ],
        n,
    );
    assert_eq!(other, play(&[on(10, 60, 0.8), off(12_000, 60)], n));
}

/// The strike-cost warning: no shipped preset needs it at 64-sample
/// blocks, and at 32 samples only the 50-mass paper string and the frame
/// drum (37 coupled membrane modes) do (a 16-note
/// chord on a 50-mode object takes about 70 % of such a block, measured by
/// `cargo bench --bench worst_block`); a 400-mode object warns at 64-sample
/// blocks (a 16-note chord would take several blocks' worth of CPU), and a
/// large buffer fits it.
#[test]
fn strike_warning_names_what_fits_at_the_hosts_block_size() {
    let mut warned_at_32 = Vec::new();
    for i in 0..presets::PRESETS.len() {
        let p = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        let pr = prepare(&p, RATE, 1).unwrap();
        assert!(
            pr.strike_warning(64, DEFAULT_POLYPHONY, 0).is_none(),
            "{:?}",
            pr.strike_warning(64, DEFAULT_POLYPHONY, 0)
        );
        if pr.strike_warning(32, DEFAULT_POLYPHONY, 0).is_some() {
            warned_at_32.push(pr.scenes.scene.name.clone());
        }
        // a kit's strike switches its largest phase (the snare's head and
        // wires: 110 states); the snare lists its notes, so its one kit
        // voice throws its one mallet at most once an instant
        let limit = if pr.kit.is_some() { 100e-6 } else { 40e-6 };
        assert!(
            pr.strike_cost_estimate_s() < limit,
            "{}",
            pr.scenes.scene.name
        );
    }
    assert_eq!(warned_at_32, ["paper-string", "frame-drum"]);
    let mut big = modal_base("marimba-bar");
    let ObjectSpec::Modal(m) = &mut big.object[0] else {
        panic!("marimba-bar is modal")
    };
    let first = m.mode[0].clone();
    m.mode = (0..400)
        .map(|k| {
            let mut md = first.clone();
            md.freq_hz = first.freq_hz * (1.0 + 0.37 * k as f64);
            md
        })
        .collect();
    let pr = prepare_scene(&big, &SceneParams::default(), 48_000.0, 1).unwrap();
    let est = pr.strike_cost_estimate_s();
    let w = pr
        .strike_warning(64, DEFAULT_POLYPHONY, 0)
        .expect("400 modes at 64 samples");
    println!("{w}");
    assert!(
        w.contains("even one strike takes more than half the block") && w.contains("64 samples"),
        "{w}"
    );
    assert!(est > 200e-6 && est < 5e-3, "{est}");
    assert!(pr.strike_warning(8192, DEFAULT_POLYPHONY, 0).is_none());
    let mid = pr
        .strike_warning(1024, DEFAULT_POLYPHONY, 0)
        .expect("a chord still overruns 1024 samples");
    assert!(mid.contains("simultaneous strikes fit"), "{mid}");
    // the lookahead it names spreads the chord: with it, no warning; with
    // a millisecond less, the same warning
    let ms: f64 = w
        .split("a Lookahead of ")
        .nth(1)
        .and_then(|r| r.split(" ms").next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no lookahead named: {w}"));
    let samples = |ms: f64| lookahead_samples(ms * 1e-3, 48_000.0);
    println!(
        "64-sample blocks: a lookahead of {ms} ms ({} samples)",
        samples(ms)
    );
    assert!(pr
        .strike_warning(64, DEFAULT_POLYPHONY, samples(ms))
        .is_none());
    assert!(pr
        .strike_warning(64, DEFAULT_POLYPHONY, samples(ms - 1.0))
        .is_some());
    // 64 voices at once need more than the longest lookahead
    let all = pr
        .strike_warning(64, MAX_VOICES, lookahead_samples(MAX_LOOKAHEAD_S, 48_000.0))
        .expect("64 strikes");
    assert!(all.contains("even the largest Lookahead"), "{all}");
}

/// Polyphony: at most that many voices sound, the next note steals the
/// quietest; 64 overlapping notes of the heaviest preset all sound at the
/// largest setting; lowering it releases the voices above the new limit.
#[test]
fn polyphony_limits_the_voices_and_64_notes_sound_together() {
    let mut p = params("steel-plate");
    p.play.polyphony = 4;
    let mut inst = instrument(&p);
    let notes: Vec<TimedEvent> = (0..5).map(|k| on(100 * k, 50 + k as u8, 0.8)).collect();
    render(&mut inst, &notes, 2_000);
    assert_eq!(inst.active_voices(), 4);
    assert_eq!(inst.stats.steals, 1);
    assert!(inst.voice_keys()[4..].iter().all(|k| k.is_none()));

    p.play.polyphony = MAX_VOICES;
    let mut inst = instrument(&p);
    let notes: Vec<TimedEvent> = (0..64).map(|k| on(10 * k, 30 + k as u8, 0.7)).collect();
    let [l, r] = render(&mut inst, &notes, 8_000);
    assert_eq!(inst.active_voices(), 64);
    assert_eq!(inst.stats.steals, 0);
    assert!(l.iter().chain(&r).all(|x| x.is_finite()));
    assert!(rms(&l[7_000..]) > 0.0);

    // lowering the limit ends the quietest voices beyond it: the 16
    // loudest of them fade (every spare state), the 40 quietest are cut
    let mut lower = p.play;
    lower.polyphony = 8;
    inst.set_play(lower);
    assert_eq!(inst.active_voices(), 8);
    let s = inst.stats;
    assert_eq!(
        (s.voices_ended, s.voices_ended_faded),
        (56, STEAL_FADES as u64)
    );
    assert_eq!(s.steal_fades_cut, 56 - STEAL_FADES as u64);
    let [l, r] = render(&mut inst, &[on(0, 100, 0.7)], 2_000);
    assert!(l.iter().chain(&r).all(|x| x.is_finite()));
    assert_eq!(inst.active_voices(), 8, "a new note steals");
    let mut bad = p.play;
    bad.polyphony = 0;
    inst.set_play(bad);
    assert_eq!(inst.play.polyphony, 1, "clamped to at least one voice");
}

fn bend(offset: usize, value: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::PitchBend { value },
    }
}

/// A bend glides to the wheel's pitch (2 semitones in 20 ms), ends at
/// exactly the note's time scale times `2^(2/12)`, never raises the
/// voice's physical energy (checked after every sample), and no update
/// makes a step in the output larger than the output's own sample-to-sample
/// change around it.
#[test]
fn pitch_bend_glides_keeps_energy_and_makes_no_step() {
    let p = params("marimba-bar");
    let mut inst = instrument(&p);
    let _ = render(&mut inst, &[on(0, 64, 0.8)], 3000);
    let base = inst.voice_state_mut(0).time_scale();
    assert!(!inst.voice_state_mut(0).in_contact());
    let scene = inst.cur.scenes.scene.clone();
    let energy = |inst: &mut Instrument| inst.voice_state_mut(0).energy(&scene);
    let n = 1500;
    let (mut y, mut e) = (vec![0.0f64], vec![energy(&mut inst)]);
    let mut ticks = Vec::new();
    for k in 0..n {
        let evs = if k == 0 { vec![bend(0, 1.0)] } else { vec![] };
        let before = inst.bend_semitones();
        let [l, _] = render(&mut inst, &evs, 1);
        if inst.bend_semitones() != before {
            ticks.push(y.len()); // the update happened after this sample
        }
        y.push(f64::from(l[0]));
        e.push(energy(&mut inst));
    }
    assert_eq!(inst.bend_semitones(), 2.0);
    let want = base * 2f64.powf(2.0 / 12.0);
    let got = inst.voice_state_mut(0).time_scale();
    assert!((got - want).abs() <= 1e-15 * want, "{got} vs {want}");
    // 2 semitones at 100 semitones/s: 20 ms, in 16-sample updates
    let glide = ticks.len();
    let expect = (0.02 * RATE / BEND_TICK_SAMPLES as f64).ceil() as usize;
    assert!((expect..=expect + 1).contains(&glide), "{glide} updates");
    let rise = e
        .windows(2)
        .map(|w| (w[1] - w[0]) / w[0])
        .fold(f64::MIN, f64::max);
    println!("bend: {glide} updates, largest relative energy change per sample {rise:.1e}");
    assert!(rise <= 1e-13, "energy rose by {rise:e}");
    // the step an update makes is at most the change of slope it causes
    let mut worst = 0.0f64;
    for &t in &ticks {
        if t + 1 >= y.len() || t < 40 {
            continue;
        }
        let jump = ((y[t + 1] - y[t]) - (y[t] - y[t - 1])).abs();
        let mut d: Vec<f64> = (t - 32..t + 32)
            .filter(|&m| m + 1 < y.len())
            .map(|m| (y[m + 1] - y[m]).abs())
            .collect();
        d.sort_by(f64::total_cmp);
        let typical = d[d.len() / 2];
        worst = worst.max(jump / typical);
    }
    println!(
        "bend: largest change of slope at an update / median sample-to-sample change {worst:.3}"
    );
    assert!(worst < 1.0, "{worst}");
}

/// Bends are applied on the instrument's own clock: the output does not
/// depend on how the host splits blocks; a bouncing scene is not bent; a
/// voice struck while the wheel is up starts at the bent pitch.
#[test]
fn pitch_bend_is_independent_of_blocks_and_spares_bouncing_scenes() {
    let events = [
        on(10, 60, 0.7),
        bend(700, 0.5),
        on(900, 67, 0.6),
        bend(2300, -1.0),
        bend(2310, 0.25),
        off(5000, 60),
        bend(6000, 0.0),
    ];
    let n = 9000;
    let mut a = instrument(&params("steel-plate"));
    let [whole, _] = render(&mut a, &events, n);
    let mut b = instrument(&params("steel-plate"));
    let split = render_split(&mut b, &events, n, &[1, 7, 64, 100, 333, 15]);
    assert_eq!(whole, split);
    // the note struck at +1 semitone (wheel 0.5 of 2) plays at that pitch
    let mut c = instrument(&params("steel-plate"));
    let _ = render(&mut c, &[bend(0, 0.5), on(2000, 67, 0.6)], 2001);
    let mut d = instrument(&params("steel-plate"));
    let _ = render(&mut d, &[on(0, 67, 0.6)], 1);
    let (sc, sd) = (
        c.voice_state_mut(0).time_scale(),
        d.voice_state_mut(0).time_scale(),
    );
    assert!((sc / sd - 2f64.powf(1.0 / 12.0)).abs() < 1e-15, "{sc} {sd}");
    // bouncing: the bend changes nothing
    let mut e = instrument(&params("paper-bounce"));
    let [bent, _] = render(&mut e, &[on(0, 60, 0.7), bend(500, 1.0)], 6000);
    let mut f = instrument(&params("paper-bounce"));
    let [plain, _] = render(&mut f, &[on(0, 60, 0.7)], 6000);
    assert_eq!(bent, plain);
}

/// What a test probe keeps of each chunk.
type Seen = std::sync::Arc<std::sync::Mutex<Vec<(usize, u8, u64, Vec<Motion>, Option<f64>)>>>;

struct Recorder(Seen);

impl VoiceProbe for Recorder {
    fn voice_chunk(&mut self, c: &VoiceChunk) {
        self.0
            .lock()
            .unwrap()
            .push((c.voice, c.key, c.start, c.motion.to_vec(), c.energy_j));
    }
}

/// The live view's probe changes no output sample (bit for bit, on every
/// preset, with a chord, a restrike and a release), sees every sample of
/// every sounding voice exactly once, sees each strike's contact, and its
/// energies equal the engine's own `energy` bit for bit; switched off, it
/// sees nothing.
#[test]
fn a_probe_changes_no_sample_and_sees_every_voice_sample() {
    for preset in presets::PRESETS {
        let p = params(preset.name);
        let events = [
            on(10, 60, 0.8),
            on(10, 64, 0.5),
            on(700, 67, 0.6),
            on(3000, 60, 0.9),
            off(5000, 64),
        ];
        let n = 8000;
        let plain = render(&mut instrument(&p), &events, n);
        let seen: Seen = Default::default();
        let mut probed = instrument(&p);
        assert!(probed
            .set_probe(Some(Box::new(Recorder(seen.clone()))))
            .is_none());
        probed.set_probe_on(true);
        let got = render(&mut probed, &events, n);
        assert!(
            plain == got,
            "{}: the probe changed the output",
            preset.name
        );
        let seen = seen.lock().unwrap();
        assert!(!seen.is_empty());
        // per voice: chunks follow each other without gap or overlap
        let mut next: [Option<u64>; MAX_VOICES] = [None; MAX_VOICES];
        let mut contact_keys = std::collections::BTreeSet::new();
        for (v, key, start, m, e) in seen.iter() {
            if let Some(want) = next[*v] {
                assert_eq!(
                    *start, want,
                    "{}: voice {v} skipped or repeated samples",
                    preset.name
                );
            }
            next[*v] = Some(start + m.len() as u64);
            // (none while a strike is played back)
            assert!(
                e.is_none_or(|e| e.is_finite() && e >= 0.0),
                "{}: energy {e:?}",
                preset.name
            );
            if m.iter().any(|x| x.in_contact) {
                contact_keys.insert(*key);
            }
        }
        // a new note's first chunks are played back (no energy), the later
        // ones have one
        if !probed.cur.key_props.is_empty() && !probed.cur.bouncing {
            assert!(seen.iter().any(|c| c.4.is_none()), "{}", preset.name);
        }
        assert!(seen.iter().any(|c| c.4.is_some()), "{}", preset.name);
        assert!(
            [60, 64, 67].iter().all(|k| contact_keys.contains(k)),
            "{}: a strike's contact was not seen ({contact_keys:?})",
            preset.name
        );
        drop(seen);
        // off: nothing more is recorded
        let before = probed.probe.is_some();
        probed.set_probe_on(false);
        let more: Seen = Default::default();
        probed.set_probe(Some(Box::new(Recorder(more.clone()))));
        render(&mut probed, &[on(0, 72, 0.7)], 2000);
        assert!(before && more.lock().unwrap().is_empty());
    }
}

/// `energy_rt` (the probe's, allocation-free) is `energy` bit for bit, in
/// flight and in a coupled (dense) contact phase.
#[test]
fn energy_rt_equals_energy() {
    for preset in presets::PRESETS {
        let pr = prepare(&params(preset.name).scene, RATE, 0).unwrap();
        let sc = &pr.scenes.scene;
        let mut st = EngineState::new(sc);
        st.reserve_observation();
        let mut checked_contact = false;
        let mut left = 400;
        for _ in 0..2 * RATE as usize {
            st.tick(sc);
            let e = st.energy(sc);
            assert_eq!(e.to_bits(), st.energy_rt(sc).to_bits(), "{}", preset.name);
            checked_contact |= st.in_contact();
            left -= usize::from(checked_contact);
            if left == 0 {
                break;
            }
        }
        assert!(checked_contact, "{}: never in contact", preset.name);
    }
}

fn tuning(offset: usize, key: Option<u8>, semitones: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteTuning { key, semitones },
    }
}

/// A per-note tuning sent with the note-on (as a host sends a microtonal
/// note's expression) starts the note at the tuned pitch: note 60 tuned
/// +12 semitones sounds like note 72, to rounding; sent one sample later it
/// glides instead (and so differs).
#[test]
fn a_tuning_at_the_onset_starts_the_note_at_its_pitch() {
    let p = params("marimba-bar");
    let n = 6000;
    let tuned = render(
        &mut instrument(&p),
        &[on(5, 60, 0.8), tuning(5, Some(60), 12.0)],
        n,
    );
    let played = render(&mut instrument(&p), &[on(5, 72, 0.8)], n);
    let peak = played[0].iter().fold(0f32, |m, x| m.max(x.abs())) as f64;
    let d = tuned[0]
        .iter()
        .zip(&played[0])
        .map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs())
        .fold(0.0, f64::max);
    println!("note 60 tuned +12 at its onset vs note 72: max diff {d:.2e} (peak {peak:.3})");
    assert!(peak > 0.01 && d <= 1e-6 * peak, "{d} vs peak {peak}");
    let late = render(
        &mut instrument(&p),
        &[on(5, 60, 0.8), tuning(6, Some(60), 12.0)],
        n,
    );
    let d_late = late[0]
        .iter()
        .zip(&played[0])
        .map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs())
        .fold(0.0, f64::max);
    assert!(d_late > 1e-3 * peak, "a later tuning glides: {d_late}");
}

/// A tuning moves only its note's voice, glides like the wheel (2 semitones
/// in 20 ms, in 16-sample updates), ends at exactly the note's time scale
/// times `2^(2/12)`, adds to the wheel, and never raises the voice's
/// physical energy; the wildcard moves every voice; a new note on the key
/// starts untuned; bad values are clamped (NaN is 0).
#[test]
fn a_note_tuning_glides_one_voice_without_adding_energy() {
    let p = params("marimba-bar");
    let mut inst = instrument(&p);
    let _ = render(&mut inst, &[on(0, 60, 0.8), on(0, 67, 0.6)], 3000);
    let (i60, i67) = (0, 1);
    assert_eq!((inst.voices[i60].key, inst.voices[i67].key), (60, 67));
    let base60 = inst.voice_state_mut(i60).time_scale();
    let base67 = inst.voice_state_mut(i67).time_scale();
    let scene = inst.cur.scenes.scene.clone();
    let mut e_prev = inst.voice_state_mut(i60).energy(&scene);
    let mut rise = f64::MIN;
    let mut updates = 0;
    for k in 0..1500 {
        let evs = if k == 0 {
            vec![tuning(0, Some(60), 2.0)]
        } else {
            vec![]
        };
        let before = inst.voice_state_mut(i60).time_scale();
        let _ = render(&mut inst, &evs, 1);
        let st = inst.voice_state_mut(i60);
        updates += usize::from(st.time_scale() != before);
        let e = st.energy(&scene);
        rise = rise.max((e - e_prev) / e_prev);
        e_prev = e;
    }
    let want = base60 * 2f64.powf(2.0 / 12.0);
    let got = inst.voice_state_mut(i60).time_scale();
    println!("tuning +2: {updates} updates, largest relative energy change per sample {rise:.1e}");
    assert!((got - want).abs() <= 1e-15 * want, "{got} vs {want}");
    assert_eq!(
        inst.voice_state_mut(i67).time_scale(),
        base67,
        "the other note stays"
    );
    let expect = (0.02 * RATE / BEND_TICK_SAMPLES as f64).ceil() as usize;
    assert!(
        (expect..=expect + 1).contains(&updates),
        "{updates} updates"
    );
    assert!(rise <= 1e-13, "energy rose by {rise:e}");

    // adds to the wheel; the wildcard moves both; clamps; NaN is 0
    let _ = render(&mut inst, &[bend(0, 1.0), tuning(0, None, -1.0)], 3000);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b;
    assert!(close(
        inst.voice_state_mut(i60).time_scale(),
        base60 * 2f64.powf(1.0 / 12.0)
    ));
    assert!(close(
        inst.voice_state_mut(i67).time_scale(),
        base67 * 2f64.powf(1.0 / 12.0)
    ));
    // (the targets: a glide of 48 semitones outlasts the quickened decay)
    let _ = render(
        &mut inst,
        &[
            bend(0, 0.0),
            tuning(0, Some(60), 1e9),
            tuning(0, Some(67), f64::NAN),
        ],
        16,
    );
    assert_eq!(inst.voices[i60].tuning_target, MAX_NOTE_TUNING_SEMITONES);
    assert_eq!(inst.voices[i67].tuning_target, 0.0);
    // a new note on the key glides back to the note's own pitch
    let _ = render(&mut inst, &[on(0, 60, 0.5)], 30_000);
    assert!(close(inst.voice_state_mut(i60).time_scale(), base60));
    let y = render(&mut inst, &[], 100);
    assert!(y[0].iter().all(|x| x.is_finite()));
}

fn pressure(offset: usize, key: Option<u8>, value: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NotePressure { key, value },
    }
}

/// One mode of the marimba bar, played at its own pitch: its free decay
/// after the hammer has left has the closed form `y_n = A r^n cos(w n dt +
/// phi)`, i.e. `y_(n+1) = 2 r cos(w dt) y_n - r^2 y_(n-1)`, with
/// `w = sqrt(omega^2 - sigma^2)` and `r = exp(-sigma dt)` from the scene's
/// frequency and T60. Under pressure `p` the same recurrence holds with
/// `sigma + p MAX_PRESSURE_DECAY_PER_S` and the same `w` (a damper that
/// takes energy from every mode alike), across the 64-sample chunks the
/// decay is applied in. Returns the worst residual of each recurrence over
/// the peak.
fn one_mode_recurrence_residuals(p: f64) -> (f64, f64) {
    let mut sc = modal_base("marimba-bar");
    let ObjectSpec::Modal(m) = &mut sc.object[0] else {
        panic!("modal")
    };
    m.mode.truncate(1);
    let (f, t60) = (m.mode[0].freq_hz, m.mode[0].t60_s.unwrap());
    let pr = prepare_scene(&sc, &SceneParams::default(), RATE, 1).unwrap();
    let play = PlayParams {
        pitch_tracking: false,
        ..PlayParams::default()
    };
    let mut inst = Instrument::new(pr, play);
    let n = 20_000;
    let [y, _] = render(&mut inst, &[on(0, 60, 0.8), pressure(0, None, p)], n);
    let y: Vec<f64> = y.iter().map(|&v| f64::from(v)).collect();
    let dt = 1.0 / RATE;
    let omega = 2.0 * std::f64::consts::PI * f;
    let sigma = LN_1000 / t60;
    let w = (omega * omega - sigma * sigma).sqrt();
    let peak = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    // until the voice stops (-90 dB: the silence test)
    let end = y.iter().rposition(|&v| v != 0.0).unwrap() - 1;
    assert!(end > 5000, "{end}");
    let worst = |rate: f64| {
        let r = (-rate * dt).exp();
        (2000..end)
            .map(|i| (y[i + 1] - 2.0 * r * (w * dt).cos() * y[i] + r * r * y[i - 1]).abs())
            .fold(0.0f64, f64::max)
            / peak
    };
    (worst(sigma), worst(sigma + p * MAX_PRESSURE_DECAY_PER_S))
}

#[test]
fn pressure_adds_one_decay_rate_to_every_mode_and_keeps_its_frequency() {
    let (plain, _) = one_mode_recurrence_residuals(0.0);
    let (wrong, right) = one_mode_recurrence_residuals(0.6);
    println!(
        "one mode, closed-form recurrence residual / peak: no pressure {plain:.1e}; \
         pressure 0.6: with the pressed decay {right:.1e}, with the free decay {wrong:.1e}"
    );
    // f32 output: residuals of a few 1e-8 of the peak
    assert!(plain < 1e-6 && right < 1e-6, "{plain:e} {right:e}");
    assert!(wrong > 30.0 * right, "the pressure did nothing: {wrong:e}");
}

/// The energy of voice `i`'s object (the total less the flying hammer's
/// kinetic energy) \[J\].
fn object_energy(inst: &mut Instrument, i: usize, scene: &CompiledScene) -> f64 {
    let st = inst.voice_state_mut(i);
    let (_, v) = st.hammer_in_flight().expect("the hammer has left");
    st.energy(scene) - 0.5 * scene.m_h * v * v
}

/// Pressure on a ringing note: never adds energy, takes it faster than the
/// free decay, leaves the strike itself alone (it acts once the hammer has
/// left), acts on its own key only, and out-of-range or NaN values are
/// clamped or ignored; on a bouncing scene (gravity may bring the hammer
/// back) it does nothing.
#[test]
fn pressure_only_takes_energy_and_spares_strikes_and_bouncing_scenes() {
    let p = params("marimba-bar");
    let mut pressed = instrument(&p);
    let mut free = instrument(&p);
    let notes = [on(0, 60, 0.8), on(0, 64, 0.8)];
    let _ = render(&mut pressed, &notes, 1);
    let _ = render(&mut free, &notes, 1);
    let _ = render(&mut pressed, &[pressure(0, Some(60), f64::NAN)], 1);
    assert_eq!(pressed.voices[0].pressure, 0.0, "NaN is 0");
    let _ = render(&mut pressed, &[pressure(0, Some(60), 7.0)], 1);
    let _ = render(&mut free, &[], 2);
    assert_eq!(pressed.voices[0].pressure, 1.0, "clamped");
    assert_eq!(pressed.voices[1].pressure, 0.0, "its own key only");
    let compiled = pressed.cur.scenes.scene.clone();
    let (mut ep, mut ef) = (Vec::new(), Vec::new());
    let (mut yp, mut yf) = (Vec::new(), Vec::new());
    for _ in 0..400 {
        yp.extend(render(&mut pressed, &[], 64)[0].iter().copied());
        yf.extend(render(&mut free, &[], 64)[0].iter().copied());
        ep.push(object_energy(&mut pressed, 0, &compiled));
        ef.push(object_energy(&mut free, 0, &compiled));
    }
    let rise = ep
        .windows(2)
        .map(|w| (w[1] - w[0]) / w[0])
        .fold(f64::MIN, f64::max);
    println!(
        "pressure 1 on note 60: largest relative change of the object's energy per chunk \
         {rise:.1e}; after 0.58 s {:.2e} J (free {:.2e} J)",
        ep[399], ef[399]
    );
    assert!(rise <= 0.0, "{rise:e}");
    // pressed, it fell to the silence test's -90 dB and stopped; the free
    // note (its energy also going into the marimba's resonator) holds a
    // thousand times more
    assert!(ep[399] < 1e-3 * ef[399]);
    assert!(!pressed.voices[0].active && free.voices[0].active);
    // note 64 unpressed: the same energy either way
    assert_eq!(
        object_energy(&mut pressed, 1, &compiled),
        object_energy(&mut free, 1, &compiled)
    );
    // the strike: pressed from the note's onset, the samples while the
    // hammer is on its way and in contact are the free ones
    let mut a = instrument(&p);
    let mut b = instrument(&p);
    let ya = render(&mut a, &[on(0, 60, 0.8), pressure(0, Some(60), 1.0)], 4000)[0].clone();
    let yb = render(&mut b, &[on(0, 60, 0.8)], 4000)[0].clone();
    let first = ya.iter().zip(&yb).position(|(x, y)| x != y).unwrap();
    assert!(b.voice_state_mut(0).contacts_started >= 1);
    println!("pressed from the onset: the first sample that differs is {first}");
    assert!((10..4000).contains(&first), "{first}");
    // on every preset that does not bounce: the damper waits until the
    // hammer is clear (on the 64-sample grid), so a note pressed from its
    // onset has the same contacts as an unpressed one and the same samples
    // until the first pressed one
    for preset in presets::PRESETS {
        let p = params(preset.name);
        let (mut a, mut b) = (instrument(&p), instrument(&p));
        if a.cur.bouncing || a.cur.kit.is_some() {
            // a kit: pressure changes nothing (a_kit_stops_when_silent_...)
            continue;
        }
        let n = 6000;
        let ya = render(&mut a, &[on(0, 60, 0.9), pressure(0, Some(60), 1.0)], n)[0].clone();
        let yb = render(&mut b, &[on(0, 60, 0.9)], n)[0].clone();
        let first = ya.iter().zip(&yb).position(|(x, y)| x != y);
        assert!(a.voices[0].active, "{}", preset.name);
        let (ca, cb) = (
            a.voice_state_mut(0).contacts_started,
            b.voice_state_mut(0).contacts_started,
        );
        println!(
            "{}: pressed from the onset, {ca} contacts (unpressed {cb}), the first pressed sample {:?} ({:.1} ms), {} pressed",
            preset.name,
            first,
            first.map_or(f64::NAN, |f| f as f64 / RATE * 1e3),
            a.stats.pressed_samples
        );
        let first = first.expect("pressed");
        assert!(first % 64 == 0 || first % 64 == 1, "{first}: on the grid");
        assert!(a.stats.pressed_samples > 0);
        assert_eq!(ca, cb, "{}: the strike is never changed", preset.name);
    }
    // a new note on the key starts unpressed
    let _ = render(&mut a, &[on(0, 60, 0.8)], 1);
    assert_eq!(a.voices[0].pressure, 0.0);
    // bouncing: nothing
    let pb = params("paper-bounce");
    let mut c = instrument(&pb);
    let mut d = instrument(&pb);
    let yc = render(&mut c, &[on(0, 60, 0.8), pressure(0, None, 1.0)], 30_000)[0].clone();
    let yd = render(&mut d, &[on(0, 60, 0.8)], 30_000)[0].clone();
    assert_eq!(yc, yd);
}

/// A chain mallet follows the hammer-mass parameter (its masses with the
/// hammer's, so the played scene stays valid) and keeps its own ring under
/// the decay and damper parameters, which act on the struck bar.
#[test]
fn a_chain_mallet_scales_with_the_hammer_and_keeps_its_ring() {
    let b = base("marimba-rubber-mallet");
    let mi = b.object_index("mallet").unwrap();
    let mut p = params("marimba-rubber-mallet");
    p.scene.hammer_mass_factor = 2.5;
    p.scene.decay_scale = 0.25;
    let s = scene_for(&b, &p);
    s.validate().expect("the played scene is valid");
    let (ObjectSpec::Chain(c0), ObjectSpec::Chain(c1)) = (&b.object[mi], &s.object[mi]) else {
        panic!("chain mallet")
    };
    for (m0, m1) in c0.masses_kg.iter().zip(&c1.masses_kg) {
        assert_eq!(*m1, m0 * 2.5);
    }
    assert_eq!(c1.rayleigh_alpha_per_s, c0.rayleigh_alpha_per_s);
    assert_eq!(c1.rayleigh_beta_s, c0.rayleigh_beta_s);
    let d = damped_scene(&s, 1.0);
    assert_eq!(
        d.object[mi], s.object[mi],
        "the damper leaves the mallet alone"
    );
    assert_ne!(d.object[0], s.object[0], "the damper presses the bar");
    compile_with(&d, RATE, None).expect("compiles");
}

fn brightness(offset: usize, key: Option<u8>, value: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteBrightness { key, value },
    }
}

/// High-frequency share of a signal: energy of its first difference over
/// its energy (larger for a harder, shorter contact).
fn brightness_ratio(x: &[f32]) -> f64 {
    let d: f64 = x.windows(2).map(|w| f64::from(w[1] - w[0]).powi(2)).sum();
    d / x.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>()
}

/// A note's brightness at its onset plays its strike at the hardness of
/// its level: bit for bit the note of an instrument whose Hardness
/// parameter is the level's stiffness (at the root pitch; within rounding
/// at another pitch, where the voice's time scale is re-derived), brighter
/// levels brighter, 0.5 the parameter's own.
///
/// Brighter is checked on the steel plate: a linear contact's force is
/// close to a half sine, whose spectrum has nulls that move down as the
/// contact softens, so on an object heard mostly through a few partials
/// one of them can fall into a null at one level and come back at the
/// next (the marimba's 10:1 partial is 2 dB weaker at level -1 than at
/// -2; the piano string's high share likewise); the plate's many modes
/// average the nulls out.
#[test]
fn brightness_at_the_onset_strikes_at_its_hardness_level() {
    let p = params("steel-plate");
    let root = instrument(&p).prepared().root_note.round() as u8;
    let n = 6000;
    let mut ratios = Vec::new();
    for (b, level) in [(0.0, -2), (0.25, -1), (0.5, 0), (0.75, 1), (1.0, 2)] {
        assert_eq!(timbre_level(b), level);
        for key in [root, root + 7] {
            let mut inst = instrument(&p);
            let got = render(
                &mut inst,
                &[on(10, key, 0.8), brightness(10, Some(key), b)],
                n,
            );
            let mut q = p;
            q.scene.stiffness_factor *= TIMBRE_STIFFNESS_STEP.powi(i32::from(level));
            let want = render(&mut instrument(&q), &[on(10, key, 0.8)], n);
            if key == root {
                assert!(got == want, "brightness {b}: not the level's strike");
            } else {
                let peak = want[0].iter().fold(0.0f32, |a, v| a.max(v.abs()));
                let worst = got[0]
                    .iter()
                    .zip(&want[0])
                    .fold(0.0f32, |a, (x, y)| a.max((x - y).abs()));
                println!(
                    "brightness {b}, key {key}: worst {:.1e} of the peak",
                    worst / peak
                );
                assert!(worst <= 1e-5 * peak, "brightness {b} key {key}: {worst}");
            }
            if key == root {
                ratios.push(brightness_ratio(&got[0][..2000]));
            }
        }
    }
    println!("high-frequency share by level: {ratios:?}");
    assert!(ratios.windows(2).all(|w| w[1] > w[0]), "{ratios:?}");
}

/// A brightness that comes while the hammer is in contact leaves that
/// contact alone and takes the voice to its level after it, on the
/// instrument's own grid (the same samples however the host splits its
/// blocks); the next note on the key starts at level 0 again; not a
/// number is the neutral 0.5, out of range is clamped.
#[test]
fn brightness_during_a_contact_waits_for_its_end() {
    let p = params("marimba-bar");
    let n = 4000;
    let events = [on(0, 60, 1.0), brightness(3, Some(60), 1.0)];
    let mut whole = instrument(&p);
    let a = render(&mut whole, &events, n)[0].clone();
    assert_eq!(whole.voices[0].at.hard, 2, "at its level after the contact");
    let b = render_split(&mut instrument(&p), &events, n, &[7, 64, 33, 1, 128]);
    assert!(a == b, "block splitting changed the samples");
    let plain = render(&mut instrument(&p), &[on(0, 60, 1.0)], n)[0].clone();
    // the first contact (a few samples from sample 1) is the plain one's
    assert_eq!(a[..40], plain[..40]);
    // a new note on the key starts at level 0
    let mut inst = instrument(&p);
    render(&mut inst, &events, n);
    render(&mut inst, &[on(0, 60, 1.0)], 10);
    assert_eq!(inst.voices[0].at.hard, 0);
    assert_eq!(timbre_level(f64::NAN), 0);
    assert_eq!(timbre_level(7.0), TIMBRE_LEVEL_MAX);
    assert_eq!(timbre_level(-3.0), -TIMBRE_LEVEL_MAX);
}

/// The variant at hardness level `level` (parameter position and damper).
fn hard(level: i8) -> Variant {
    Variant {
        hard: level,
        ..Variant::default()
    }
}

fn hardness(offset: usize, key: Option<u8>, factor: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteHardness { key, factor },
    }
}

/// A note's hardness (a host's polyphonic modulation of Hardness) is
/// rounded to the nearest level and added to its brightness's: at the
/// onset, the strike is bit for bit that of an instrument whose Hardness is
/// the sum's level; beyond the compiled levels it stays at the outermost;
/// factors that are not positive numbers are 1; other voices keep their
/// level; a new note on the key starts without it.
#[test]
fn hardness_modulation_adds_its_level_to_the_brightness() {
    let p = params("marimba-bar");
    let n = 4000;
    let step = TIMBRE_STIFFNESS_STEP;
    let cases = [
        // (brightness, factor, level)
        (0.5, step, 1),
        (0.5, 1.0 / step, -1),
        (0.5, step.sqrt() * 0.99, 0),
        (0.5, step.sqrt() * 1.01, 1),
        (0.75, step, 2),
        (0.25, step * step, 1),
        (1.0, step, 2),
        (0.0, 1e9, 0),
        (0.5, 1e-12, -2),
        (0.75, f64::NAN, 1),
        (0.5, -2.0, 0),
        (0.5, 0.0, 0),
        (0.5, f64::INFINITY, 0),
    ];
    for (b, factor, level) in cases {
        let mut inst = instrument(&p);
        let got = render(
            &mut inst,
            &[
                on(10, 60, 0.8),
                on(10, 67, 0.8),
                brightness(10, Some(60), b),
                hardness(10, Some(60), factor),
            ],
            n,
        );
        assert_eq!(inst.voices[0].at.hard, level, "b {b} factor {factor}");
        assert_eq!(inst.voices[1].at.hard, 0, "the other voice keeps its level");
        let mut q = p;
        q.scene.stiffness_factor *= step.powi(i32::from(level));
        let mut want_inst = instrument(&q);
        let want = render(&mut want_inst, &[on(10, 60, 0.8)], n);
        let other = render(&mut instrument(&p), &[on(10, 67, 0.8)], n);
        let sum: Vec<f32> = want[0].iter().zip(&other[0]).map(|(a, b)| a + b).collect();
        // the two voices mix in order: compare the modulated voice alone
        let mut alone = instrument(&p);
        let got_alone = render(
            &mut alone,
            &[
                on(10, 60, 0.8),
                brightness(10, Some(60), b),
                hardness(10, Some(60), factor),
            ],
            n,
        );
        assert!(
            got_alone == want,
            "b {b} factor {factor}: not the level-{level} strike"
        );
        let worst = got[0]
            .iter()
            .zip(&sum)
            .fold(0.0f32, |a, (x, y)| a.max((x - y).abs()));
        assert!(worst <= 1e-6, "b {b} factor {factor}: mix {worst}");
    }
    assert_eq!(hardness_level(step.powi(5)), TIMBRE_LEVEL_MAX);
    assert_eq!(hardness_level(f64::NAN), 0);
    // a new note on the key starts without the modulation
    let mut inst = instrument(&p);
    render(
        &mut inst,
        &[on(0, 60, 0.8), hardness(0, Some(60), 4.0)],
        2000,
    );
    assert_eq!(inst.voices[0].at.hard, 2);
    render(&mut inst, &[on(0, 60, 0.8)], 10);
    assert_eq!(inst.voices[0].at.hard, 0);
    assert_eq!(inst.voices[0].hard_level, 0);
}

fn position(offset: usize, key: Option<u8>, by: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NotePosition { key, offset: by },
    }
}

fn damper(offset: usize, key: Option<u8>, by: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteDamper { key, offset: by },
    }
}

/// A note's strike position (a host's polyphonic modulation of Strike
/// position), once the position levels are compiled, plays bit for bit
/// the strike of an instrument whose Strike position is the level's it
/// rounds to, and with a hardness the (hardness, position) pair's; every
/// variant of a preset steps the same free phase. Without the levels (not
/// asked for, or Custom strike position off) the note plays at the
/// parameter's position.
#[test]
fn position_modulation_strikes_at_its_level() {
    let mut p = params("marimba-bar");
    p.scene.strike_pos_norm = Some(0.4);
    p.scene.variants.position = true;
    let pr = prepare(&p.scene, RATE, 0).unwrap();
    assert_eq!(
        pr.scenes.variant_count(),
        24,
        "every (hardness, position) pair"
    );
    assert!(pr.scenes.variants_same_free());
    let root = pr.root_note.round() as u8;
    let n = 4000;
    let mut sounds: Vec<Vec<f32>> = Vec::new();
    for (by, pos, factor, hl) in [
        (0.1, 1, 1.0, 0),
        (-0.2, -2, 1.0, 0),
        (0.04, 0, 1.0, 0),
        (0.16, 2, 1.0, 0),
        (-0.07, -1, 1.0, 0),
        (0.1, 1, 2.0, 1),
        (-0.1, -1, 0.25, -2),
        (f64::NAN, 0, 1.0, 0),
        (9.0, 2, 1.0, 0),
    ] {
        let mut inst = instrument(&p);
        let got = render(
            &mut inst,
            &[
                on(10, root, 0.8),
                position(10, Some(root), by),
                hardness(10, Some(root), factor),
            ],
            n,
        );
        let at = inst.voices[0].at;
        assert_eq!((at.hard, at.pos), (hl, pos), "offset {by}");
        let mut q = p;
        q.scene.variants = VariantSet::default();
        q.scene.strike_pos_norm = Some((0.4 + f64::from(pos) * POSITION_STEP).clamp(0.0, 1.0));
        q.scene.stiffness_factor *= TIMBRE_STIFFNESS_STEP.powi(i32::from(hl));
        let want = render(&mut instrument(&q), &[on(10, root, 0.8)], n);
        assert!(
            got == want,
            "offset {by} factor {factor}: not the level's strike"
        );
        if hl == 0 {
            sounds.push(got[0].clone());
        }
    }
    // the levels sound different from each other
    for (a, b) in [(0, 1), (0, 2), (1, 3), (2, 4)] {
        assert!(sounds[a] != sounds[b], "levels {a} and {b} sound the same");
    }
    // not compiled (not asked for; or Custom strike position off): the
    // parameter's position
    for q in [
        {
            let mut q = p;
            q.scene.variants.position = false;
            q
        },
        {
            let mut q = p;
            q.scene.strike_pos_norm = None;
            q
        },
    ] {
        let pr = prepare(&q.scene, RATE, 0).unwrap();
        assert_eq!(pr.scenes.variant_count(), 4, "the hardness levels only");
        let got = render(
            &mut instrument(&q),
            &[on(10, root, 0.8), position(10, Some(root), 0.2)],
            n,
        );
        let want = render(&mut instrument(&q), &[on(10, root, 0.8)], n);
        assert!(got == want);
    }
}

/// A note's damper (a host's polyphonic modulation of Damper), once the
/// damper levels are compiled, damps its release bit for bit as an
/// instrument whose Damper is the level's it rounds to (a level at damper 0
/// rings on); a change after the release moves the released voice to the
/// new level's damped scene; the strike itself is never changed.
#[test]
fn damper_modulation_damps_the_release_at_its_level() {
    let mut p = params("marimba-bar");
    p.scene.damper_norm = 0.5;
    p.scene.damper_custom = true;
    p.scene.variants.damper = true;
    let pr = prepare(&p.scene, RATE, 0).unwrap();
    assert_eq!(
        pr.scenes.variant_count(),
        4 + 3,
        "hardness levels, three damped"
    );
    let root = pr.root_note.round() as u8;
    let n = 16_000;
    let mut tails = Vec::new();
    for (by, level) in [
        (-0.5, -2),
        (-0.3, -1),
        (0.1, 0),
        (0.25, 1),
        (0.5, 2),
        (f64::NAN, 0),
    ] {
        let mut inst = instrument(&p);
        let got = render(
            &mut inst,
            &[
                on(10, root, 0.8),
                damper(10, Some(root), by),
                off(3000, root),
            ],
            n,
        );
        assert_eq!(inst.voices[0].at.damper, level);
        let mut q = p;
        q.scene.variants = VariantSet::default();
        q.scene.damper_norm = (0.5 + f64::from(level) * DAMPER_STEP).clamp(0.0, 1.0);
        let want = render(
            &mut instrument(&q),
            &[on(10, root, 0.8), off(3000, root)],
            n,
        );
        assert!(got == want, "offset {by}: not the level's release");
        if !by.is_nan() {
            tails.push(rms(&got[0][3200..3700]));
        }
    }
    println!("release tails by damper level: {tails:?}");
    assert!(tails.windows(2).all(|w| w[1] < w[0]), "{tails:?}");
    // after the release: the released voice moves to the new level
    let plain = render(
        &mut instrument(&p),
        &[on(10, root, 0.8), off(3000, root)],
        n,
    );
    let later = render(
        &mut instrument(&p),
        &[
            on(10, root, 0.8),
            off(3000, root),
            damper(3100, Some(root), 0.5),
        ],
        n,
    );
    assert_eq!(plain[0][..3100], later[0][..3100]);
    let (a, b) = (rms(&plain[0][3300..3800]), rms(&later[0][3300..3800]));
    println!("damper raised after the release: tail {a:.3e} -> {b:.3e}");
    assert!(b < 0.5 * a, "{a} {b}");
}

/// Every preset has its four brightness levels; a scene larger than
/// `TIMBRE_MAX_STATES` has none and plays every brightness at the Hardness
/// parameter's level (the same samples as without brightness).
#[test]
fn presets_have_every_brightness_level_and_large_scenes_none() {
    for (i, preset) in presets::PRESETS.iter().enumerate() {
        let name = preset.name;
        let sp = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        let pr = prepare(&sp, RATE, 0).unwrap();
        if pr.kit.is_some() {
            // a kit plays every note at the parameters' values: no levels
            assert_eq!(pr.scenes.variant_count(), 0, "{name}");
            continue;
        }
        assert!(
            pr.timbre_note().is_none()
                && (-TIMBRE_LEVEL_MAX..=TIMBRE_LEVEL_MAX).all(|l| pr.scenes.has_played(hard(l)))
                && pr.scenes.variants_same_free()
                && pr.scenes.variant_count() == 4,
            "{name}: {} states",
            pr.scenes.scene.contact.dim
        );
    }
    let mut sc = modal_base("marimba-bar");
    let ObjectSpec::Modal(m) = &mut sc.object[0] else {
        panic!("modal")
    };
    let first = m.mode[0].clone();
    m.mode = (0..70)
        .map(|k| {
            let mut md = first.clone();
            md.freq_hz = first.freq_hz * (1.0 + 0.37 * k as f64);
            md
        })
        .collect();
    // (every variant asked for: none is compiled)
    let sp = SceneParams {
        strike_pos_norm: Some(0.5),
        variants: VariantSet {
            position: true,
            damper: true,
        },
        ..SceneParams::default()
    };
    let pr = prepare_scene(&sc, &sp, RATE, 0).unwrap();
    assert!(pr.scenes.scene.contact.dim > TIMBRE_MAX_STATES);
    assert!(!pr.scenes.has_played(hard(1)) && pr.scenes.has_played(hard(0)));
    assert_eq!(pr.scenes.variant_count(), 0);
    let note = pr.timbre_note().expect("a note for the user");
    assert!(note.contains("142 states in contact"), "{note}");
    let play = PlayParams::default();
    let mut bright = Instrument::new(pr.clone(), play);
    let got = render(
        &mut bright,
        &[
            on(0, 60, 0.8),
            brightness(0, None, 1.0),
            hardness(0, None, 4.0),
            position(0, None, 0.2),
            damper(0, None, 0.5),
            off(1500, 60),
        ],
        3000,
    );
    let want = render(
        &mut Instrument::new(pr, play),
        &[on(0, 60, 0.8), off(1500, 60)],
        3000,
    );
    assert!(got == want);
}

/// A `Prepared` is built on whichever thread compiles it, a host's thread at
/// activation (Ardour's crashed on a frame of about 280 KB when the variant
/// scenes were held inline): its bulk (voice states, variant scenes) lives
/// on the heap, and every preset prepares, every variant asked for, on a
/// thread of 256 KB of stack.
#[test]
fn prepare_fits_a_small_host_thread_stack() {
    let size = std::mem::size_of::<Prepared>();
    println!("size of Prepared: {size} bytes");
    assert!(size < 16 * 1024, "{size}");
    std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(|| {
            for i in 0..presets::COUNT {
                let sp = SceneParams {
                    preset: i,
                    strike_pos_norm: Some(0.5),
                    variants: VariantSet {
                        position: true,
                        damper: true,
                    },
                    ..SceneParams::default()
                };
                let p = prepare(&sp, RATE, 0).unwrap();
                assert!(
                    p.scenes.variant_count() >= 24 || p.kit.is_some(),
                    "preset {i}"
                );
            }
        })
        .unwrap()
        .join()
        .unwrap();
}

/// A note on a silent voice is a strike from rest: through the instrument
/// (its velocity and pitch mapping, block splitting), the voice takes the
/// strike's later contacts from the compiler's store, with no miss, on the
/// presets whose hammer meets the object again (`compile::rest`,
/// docs/numerics.md "A strike on an object at rest"), at the root and off
/// it.
#[test]
fn new_notes_take_their_later_contacts_from_the_store() {
    for preset in ["tubular-chime", "piano-string", "marimba-rubber-mallet"] {
        let p = params(preset);
        let mut inst = instrument(&p);
        let root = root_note(&base(preset)).round() as u8;
        let keys = [root, root.saturating_add(5), root.saturating_sub(7)];
        let events: Vec<TimedEvent> = keys
            .iter()
            .enumerate()
            .map(|(j, &k)| on(100 * j, k, 0.8))
            .collect();
        render_split(&mut inst, &events, 4410, &[64, 37, 512]);
        let (mut later, mut misses, mut voices) = (0, 0, 0);
        for (v, st) in inst.voices.iter().zip(inst.cur.states.iter()) {
            if v.active {
                voices += 1;
                later += st.exact_stats.rest_later;
                misses += st.exact_stats.rest_misses;
            }
        }
        println!("{preset}: {voices} voices, {later} later switches stored, {misses} misses");
        assert_eq!(voices, keys.len(), "{preset}");
        assert!(later >= keys.len() as u64, "{preset}: {later}");
        assert_eq!(misses, 0, "{preset}");
    }
}

/// A new note copies its key's propagators, made ahead with the scene
/// (`Prepared::key_props`), instead of computing an exponential and a sine
/// per block: the output is the same bit for bit as with them computed at
/// the note-on, for notes across the keyboard, chords, a retriggered key
/// and notes under a bend (which compute theirs: the bent scale is no key's).
#[test]
fn key_propagators_made_ahead_play_the_same_bits() {
    for preset in ["marimba-bar", "steel-plate", "paper-string"] {
        let p = params(preset);
        let mut ahead = prepare(&p.scene, RATE, 0).unwrap();
        // the propagators alone (the stored strikes from rest made with them
        // play the same to rounding: tests/stored_strike.rs)
        ahead.forget_stored_strikes();
        assert_eq!(ahead.key_props.len(), 128, "{preset}");
        let root = ahead.root_note;
        for key in [0u8, 60, 127] {
            assert_eq!(
                ahead.key_props[usize::from(key)].scale().to_bits(),
                mapping::key_scale(key, root).to_bits()
            );
        }
        let mut computed = prepare(&p.scene, RATE, 0).unwrap();
        computed.key_props.clear();
        let events = [
            on(0, 36, 0.8),
            on(10, 60, 0.5),
            on(10, 67, 0.5),
            on(20, 61, 1.0),
            on(2000, 96, 0.7),
            on(2500, 60, 0.9),
            bend(3000, 0.5),
            on(4000, 50, 0.6),
            bend(5000, 0.0),
            on(7000, 72, 0.6),
        ];
        let mut a = Instrument::new(ahead, p.play);
        let mut b = Instrument::new(computed, p.play);
        let ra = render(&mut a, &events, 9000);
        let rb = render(&mut b, &events, 9000);
        let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
        assert!(ra[0].iter().any(|&v| v != 0.0), "{preset}: silent");
        assert_eq!(bits(&ra[0]), bits(&rb[0]), "{preset}: left");
        assert_eq!(bits(&ra[1]), bits(&rb[1]), "{preset}: right");
        // six new notes at their keys' scales (the retriggered 60 strikes
        // its ringing voice; the note under the bend computes its own)
        assert_eq!(a.stats.key_props_copied, 6, "{preset}");
        assert_eq!(b.stats.key_props_copied, 0, "{preset}");
        // without pitch tracking every note plays at scale 1: the root's
        let mut flat = p.play;
        flat.pitch_tracking = false;
        let mut ahead = prepare(&p.scene, RATE, 0).unwrap();
        ahead.forget_stored_strikes();
        let mut c = Instrument::new(ahead, flat);
        let mut computed = prepare(&p.scene, RATE, 0).unwrap();
        computed.key_props.clear();
        let mut d = Instrument::new(computed, flat);
        let rc = render(&mut c, &events, 9000);
        let rd = render(&mut d, &events, 9000);
        assert_eq!(bits(&rc[0]), bits(&rd[0]), "{preset}: untracked");
        assert_eq!(c.stats.key_props_copied, 6, "{preset}: untracked");
    }
}

/// A stolen voice fades out over [`FADE_S`] while the new note starts at
/// once (docs/plugin.md, "Velocity, pitch, voices"): the case, the marimba at
/// polyphony 1, A3 then E4 300 ms later, at 48 kHz. The output is the old
/// note times the fade's gain (1 up to the steal, then `(L - j) / L` at the
/// `j`-th sample after it, `L` the fade's length) plus the new note
/// rendered alone, sample by sample; so the step at the steal is the
/// ringing note's own plus at most its amplitude over `L`, where a cut
/// makes a step of its whole amplitude.
#[test]
fn a_stolen_voice_fades_out_while_the_new_note_starts_at_once() {
    const RATE_48K: f64 = 48_000.0;
    let mut p = params("marimba-bar");
    p.play.polyphony = 1;
    let t0 = (0.3 * RATE_48K) as usize;
    let n = t0 + 4_800;
    let fade = ((FADE_S * RATE_48K).round()) as usize;
    let mut fails = Vec::new();
    for vel in [100.0 / 127.0, 1.0] {
        let run = |events: &[TimedEvent]| {
            let mut inst = Instrument::new(prepare(&p.scene, RATE_48K, 0).unwrap(), p.play);
            let out = render(&mut inst, events, n);
            (out, inst.stats)
        };
        let (y, stats) = run(&[on(0, 57, vel), on(t0, 64, vel)]);
        let (a, _) = run(&[on(0, 57, vel)]);
        let (b, _) = run(&[on(t0, 64, vel)]);
        assert_eq!(stats.steals, 1);
        let gain = |k: usize| steal_fade_gain(k, t0, fade);
        for ch in 0..2 {
            let ring_step = (t0 - 4_800..t0)
                .map(|k| step_at(&a[ch], k))
                .fold(0.0, f64::max);
            let ring_peak = (t0 - 4_800..t0)
                .map(|k| (a[ch][k] as f64).abs())
                .fold(0.0, f64::max);
            let jump = step_at(&y[ch], t0);
            // the last 10 ms before the steal, and the output and the new
            // note alone over the fade
            let ring_step_10ms = (t0 - 480..t0)
                .map(|k| step_at(&a[ch], k))
                .fold(0.0, f64::max);
            let out_step = (t0..t0 + fade)
                .map(|k| step_at(&y[ch], k))
                .fold(0.0, f64::max);
            let new_step = (t0..t0 + fade)
                .map(|k| step_at(&b[ch], k))
                .fold(0.0, f64::max);
            // the output less the new note: the old note as it fades
            let rest: Vec<f32> = (0..n).map(|k| y[ch][k] - b[ch][k]).collect();
            let rest_step = (t0..t0 + fade + 2)
                .map(|k| step_at(&rest, k))
                .fold(0.0, f64::max);
            let worst = (0..n)
                .map(|k| (y[ch][k] as f64 - (gain(k) * a[ch][k] as f64 + b[ch][k] as f64)).abs())
                .fold(0.0, f64::max);
            println!(
                "velocity {:.0}, channel {ch}: step at the steal {jump:.3e}, the ringing note's \
                 largest step {ring_step:.3e} over 100 ms ({ring_step_10ms:.3e} over 10 ms), \
                 its peak {ring_peak:.3e}; largest step over the fade of the output \
                 {out_step:.3e}, of the new note alone {new_step:.3e}, of the output less the \
                 new note {rest_step:.3e}; farthest from the faded old note plus the new one \
                 {worst:.1e}",
                vel * 127.0,
            );
            if worst > 1e-6 {
                fails.push(format!("the old note faded plus the new note: {worst:e}"));
            }
            if rest_step > ring_step + ring_peak / fade as f64 + 1e-7 {
                fails.push(format!("step {rest_step:e}, the note's own {ring_step:e}"));
            }
        }
    }
    assert!(fails.is_empty(), "{fails:?}");
}

/// The step of `x` into sample `k`.
fn step_at(x: &[f32], k: usize) -> f64 {
    (x[k] as f64 - x[k - 1] as f64).abs()
}

/// Steals at every polyphony (1 ..= [`MAX_VOICES`], every value of the
/// Polyphony parameter): `poly` notes ringing, then a new one steals the
/// quietest. The output is, sample by sample, the old notes without the
/// new one, less the stolen note, plus the stolen note times the fade's
/// gain, plus the new note rendered alone (so it starts at once): each
/// rendered on an instrument of its own. The stolen note's part of the
/// output steps at most by its own largest step plus its amplitude over
/// the fade's length; cutting it would miss the first check by the stolen
/// note's amplitude, which each case checks is far above the tolerance.
#[test]
fn steals_at_every_polyphony_fade_the_stolen_voice_without_a_jump() {
    let fade = ((FADE_S * RATE).round()) as usize;
    let key = |j: usize| 30 + ((j * 37) % 64) as u8;
    let vel = |j: usize| 0.4 + 0.06 * ((j * 13) % 10) as f64;
    let mut worst_ratio = 0.0f64;
    for poly in 1..=MAX_VOICES {
        let mut p = params("marimba-bar");
        p.play.polyphony = poly;
        let notes: Vec<TimedEvent> = (0..poly).map(|j| on(100 * j, key(j), vel(j))).collect();
        let t_s = 100 * poly + 2_205;
        let n = t_s + fade + 500;
        let steal = on(t_s, 100, 0.8);
        let render_all = |events: &[TimedEvent]| {
            let mut inst = instrument(&p);
            let out = render(&mut inst, events, n);
            (out, inst)
        };
        // the steal, in two blocks to see which voice it takes
        let mut inst = instrument(&p);
        let [l0, r0] = render(&mut inst, &notes, t_s);
        let before = inst.voice_keys();
        let [l1, r1] = render(&mut inst, &[on(0, 100, 0.8)], n - t_s);
        let after = inst.voice_keys();
        assert_eq!(inst.stats.steals, 1, "polyphony {poly}");
        assert_eq!(inst.stats.steals_faded, 1, "polyphony {poly}");
        // the new note is on the voice it stole (another may have stopped
        // since, silent)
        let i = after.iter().position(|k| *k == Some(100)).unwrap();
        let j = (0..poly).find(|&j| before[i] == Some(key(j))).unwrap();
        let y = [[l0, l1].concat(), [r0, r1].concat()];
        let (rest, _) = render_all(&notes);
        let (a, _) = render_all(&[notes[j]]);
        let (b, _) = render_all(&[steal]);
        let gain = |k: usize| steal_fade_gain(k, t_s, fade);
        for ch in 0..2 {
            let f = |x: &[Vec<f32>; 2], k: usize| x[ch][k] as f64;
            let peak = (0..n).map(|k| f(&rest, k).abs()).fold(0.0, f64::max);
            let tol = 1e-6 * (1e-2 + peak);
            let mut worst = 0.0f64;
            for k in 0..n {
                let expect = f(&rest, k) - f(&a, k) + gain(k) * f(&a, k) + f(&b, k);
                worst = worst.max((f(&y, k) - expect).abs());
            }
            // what a cut would have missed by
            let cut = (t_s..t_s + fade / 2)
                .map(|k| gain(k) * f(&a, k).abs())
                .fold(0.0, f64::max);
            assert!(
                worst <= tol && cut > 100.0 * tol,
                "polyphony {poly}, channel {ch}: {worst:e} from the faded sum (tolerance \
                 {tol:e}, a cut would miss by {cut:e})"
            );
            // the stolen note as it fades: the output less the others and
            // the new note
            let faded: Vec<f32> = (0..n)
                .map(|k| (f(&y, k) - f(&rest, k) + f(&a, k) - f(&b, k)) as f32)
                .collect();
            let own = (t_s - 441..t_s)
                .map(|k| step_at(&a[ch], k))
                .fold(0.0, f64::max);
            let amp = (t_s - 441..t_s + fade)
                .map(|k| f(&a, k).abs())
                .fold(0.0, f64::max);
            let at_steal = (t_s..t_s + fade + 2)
                .map(|k| step_at(&faded, k))
                .fold(0.0, f64::max);
            assert!(
                at_steal <= own + amp / fade as f64 + 4.0 * tol,
                "polyphony {poly}, channel {ch}: step {at_steal:e}, the stolen note's own \
                 {own:e}, amplitude {amp:e}"
            );
            worst_ratio = worst_ratio.max(at_steal / own);
        }
    }
    println!("largest step of a fading stolen note over its own largest step: {worst_ratio:.3}");
}

/// Only a voice that has sounded fades: a chord of more notes than the
/// polyphony on one sample takes its own notes back without a fade (they
/// have not sounded yet), as it always did; a chord on ringing voices
/// fades them all, and more steals at once than there are spare states
/// cut the fades nearest their end, counted, never a sample that is not a
/// number.
#[test]
fn only_sounding_voices_fade_and_too_many_at_once_cut_the_oldest_fade() {
    let mut p = params("marimba-bar");
    p.play.polyphony = 2;
    let mut inst = instrument(&p);
    let chord: Vec<TimedEvent> = (0..5).map(|k| on(0, 50 + k, 0.8)).collect();
    let [l, _] = render(&mut inst, &chord, 4_410);
    assert_eq!((inst.stats.steals, inst.stats.steals_faded), (3, 0));
    assert!(l.iter().all(|x| x.is_finite()) && rms(&l) > 0.0);
    let again: Vec<TimedEvent> = (0..2).map(|k| on(0, 70 + k, 0.8)).collect();
    render(&mut inst, &again, 4_410);
    assert_eq!((inst.stats.steals, inst.stats.steals_faded), (5, 2));
    assert_eq!(inst.stats.steal_fades_cut, 0);

    p.play.polyphony = MAX_VOICES;
    let mut inst = instrument(&p);
    let notes: Vec<TimedEvent> = (0..64).map(|k| on(10 * k, 30 + k as u8, 0.7)).collect();
    render(&mut inst, &notes, 4_410);
    let burst = STEAL_FADES + 4;
    let chord: Vec<TimedEvent> = (0..burst).map(|k| on(0, 100 + k as u8, 0.7)).collect();
    render(&mut inst, &chord, 1);
    assert_eq!(inst.stats.steals, burst as u64);
    assert_eq!(inst.stats.steals_faded, burst as u64);
    assert_eq!(inst.stats.steal_fades_cut, 4);
    let new = inst
        .voice_keys()
        .iter()
        .flatten()
        .filter(|&&k| k >= 100)
        .count();
    assert_eq!(new, burst, "every note of the chord sounds");
    let [l, r] = render(&mut inst, &[], 4_410);
    assert!(l.iter().chain(&r).all(|x| x.is_finite()));
}

/// A swap while a stolen voice fades: the fade goes on in the old box's
/// spare state (the box is handed back when it ends), so the output is
/// the one without the swap (the same scene compiled again: the carried
/// voice plays on, to the last bits); the new box's spares take the next
/// steal.
#[test]
fn a_swap_during_a_steal_fade_lets_it_finish() {
    let mut p = params("marimba-bar");
    p.play.polyphony = 1;
    let t0 = 13_230;
    let n = 4_410;
    let run = |swap: bool| {
        let mut inst = instrument(&p);
        let [mut l, _] = render(&mut inst, &[on(0, 57, 0.8), on(t0 - 64, 64, 0.8)], t0);
        if swap {
            assert!(inst.can_install());
            inst.install(prepare(&p.scene, RATE, 1).unwrap()).unwrap();
            assert!(!inst.can_install(), "the old box waits for its fade");
            assert_eq!(inst.stats.voices_carried, 1);
        }
        let [l1, _] = render(&mut inst, &[on(n / 2, 69, 0.8)], n);
        l.extend(l1);
        assert!(inst.can_install());
        (l, inst.stats)
    };
    let (plain, s0) = run(false);
    let (swapped, s1) = run(true);
    assert_eq!((s0.steals_faded, s1.steals_faded), (2, 2));
    let peak = plain.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let worst = plain
        .iter()
        .zip(&swapped)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-5 * peak, "{worst:e} (peak {peak:e})");
}

pub(super) fn at(offset: usize, event: Event) -> TimedEvent {
    TimedEvent { offset, event }
}

/// The largest distance of `y` from `expect` over both channels and every
/// sample, and a tolerance: `1e-6` of (`1e-2` plus) the largest `|y|`.
pub(super) fn worst_and_tol(y: &[Vec<f32>; 2], expect: impl Fn(usize, usize) -> f64) -> (f64, f64) {
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for (ch, x) in y.iter().enumerate() {
        for (k, &v) in x.iter().enumerate() {
            worst = worst.max((f64::from(v) - expect(ch, k)).abs());
            peak = peak.max(f64::from(v).abs());
        }
    }
    (worst, 1e-6 * (1e-2 + peak))
}

/// The largest `|x|` over both channels at the samples of `ks`, each
/// times `w(k)`.
pub(super) fn largest(
    x: &[Vec<f32>; 2],
    ks: std::ops::Range<usize>,
    w: impl Fn(usize) -> f64,
) -> f64 {
    ks.flat_map(|k| x.iter().map(move |c| (k, c[k])))
        .map(|(k, v)| (w(k) * f64::from(v)).abs())
        .fold(0.0, f64::max)
}

/// A choke (CLAP's note choke) ends its note at once as a stolen note
/// ends: whatever the pedals, the output is the other notes plus the
/// choked note times the steal's fade gain (`steal_fade_gain`), sample by
/// sample, and the voice is free; a release (what a choke was before)
/// would miss that by the note's whole ringing amplitude, a cut by its
/// amplitude at the choke. A choke at the note's own onset sample ends it
/// before it sounds (the output is the one without that note, bit for
/// bit); a choke of every note fades them all.
#[test]
fn a_choke_fades_its_note_as_a_steal_does_whatever_the_pedals() {
    let p = params("marimba-bar");
    let fade = ((FADE_S * RATE).round()) as usize;
    let (t0, n) = (13_230, 15_400);
    let run = |events: &[TimedEvent]| {
        let mut inst = instrument(&p);
        let out = render(&mut inst, events, n);
        (out, inst)
    };
    let notes = [
        pedal(0, true, true),
        on(10, 57, 0.8),
        on(300, 64, 0.7),
        off(500, 57),
    ];
    let gain = |k: usize| steal_fade_gain(k, t0, fade);
    let (both, _) = run(&notes);
    let (a, _) = run(&[on(10, 57, 0.8)]);

    let mut ev = notes.to_vec();
    ev.push(at(t0, Event::Choke { key: Some(57) }));
    let (y, inst) = run(&ev);
    let sounding: Vec<u8> = inst.voice_keys().iter().flatten().copied().collect();
    assert_eq!(sounding, [64]);
    let s = inst.stats;
    assert_eq!((s.voices_ended, s.voices_ended_faded, s.steals), (1, 1, 0));
    let f = |x: &[Vec<f32>; 2], ch: usize, k: usize| f64::from(x[ch][k]);
    let (worst, tol) = worst_and_tol(&y, |ch, k| {
        f(&both, ch, k) - f(&a, ch, k) + gain(k) * f(&a, ch, k)
    });
    let cut = largest(&a, t0..t0 + fade / 2, gain);
    let released = largest(&a, t0 + fade..n, |_| 1.0);
    println!("choke: {worst:.2e} from the faded sum (tolerance {tol:.1e}); a cut would miss by {cut:.2e}, a release by {released:.2e}");
    assert!(worst <= tol, "{worst:e} > {tol:e}");
    assert!(cut > 100.0 * tol && released > 100.0 * tol);

    // at its onset sample: never sounds
    let mut ev = notes.to_vec();
    ev.extend([on(t0, 69, 0.9), at(t0, Event::Choke { key: Some(69) })]);
    let (y, inst) = run(&ev);
    assert!(y == both, "a note choked at its onset sounds");
    assert_eq!(inst.stats.voices_ended_faded, 0);

    // every note
    let mut ev = notes.to_vec();
    ev.push(at(t0, Event::Choke { key: None }));
    let (y, inst) = run(&ev);
    assert_eq!(inst.active_voices(), 0);
    let (worst, tol) = worst_and_tol(&y, |ch, k| gain(k) * f(&both, ch, k));
    assert!(worst <= tol, "{worst:e} > {tol:e}");
    assert!(y.iter().all(|c| c[t0 + fade..].iter().all(|&v| v == 0.0)));
}

/// All Sound Off (MIDI CC 120) fades every voice as a steal does, the
/// pedals notwithstanding: the output is the notes times the fade's gain,
/// then exact silence. With more voices than spare states the loudest fade
/// and the quietest are cut: 16 loud notes and 4 quiet ones give exactly
/// the 16 loud notes times the gain.
#[test]
fn all_sound_off_fades_every_voice_the_loudest_first() {
    let mut p = params("marimba-bar");
    let fade = ((FADE_S * RATE).round()) as usize;
    let (t0, n) = (8_820, 10_000);
    let gain = |k: usize| steal_fade_gain(k, t0, fade);
    let f = |x: &[Vec<f32>; 2], ch: usize, k: usize| f64::from(x[ch][k]);
    let notes = [
        pedal(0, true, true),
        on(10, 57, 0.8),
        on(300, 64, 0.7),
        on(700, 69, 0.6),
    ];
    let mut inst = instrument(&p);
    let rest = render(&mut inst, &notes, n);
    let mut ev = notes.to_vec();
    ev.push(at(t0, Event::AllSoundOff));
    let mut inst = instrument(&p);
    let y = render(&mut inst, &ev, n);
    let (worst, tol) = worst_and_tol(&y, |ch, k| gain(k) * f(&rest, ch, k));
    let cut = largest(&rest, t0..t0 + fade / 2, gain);
    println!("all sound off: {worst:.2e} from the faded notes (tolerance {tol:.1e}), a cut would miss by {cut:.2e}");
    assert!(worst <= tol && cut > 100.0 * tol, "{worst:e}, {cut:e}");
    assert!(y.iter().all(|c| c[t0 + fade..].iter().all(|&v| v == 0.0)));
    assert_eq!(inst.active_voices(), 0);
    assert_eq!(inst.stats.voices_ended_faded, 3);

    // 20 voices: the 4 quiet ones are cut
    p.play.polyphony = 20;
    let loud: Vec<TimedEvent> = (0..16)
        .map(|j| on(100 * j, 40 + 2 * j as u8, 0.9))
        .collect();
    let quiet: Vec<TimedEvent> = (0..4)
        .map(|j| on(50 + 200 * j, 41 + 4 * j as u8, 0.1))
        .collect();
    let mut all = [loud.clone(), quiet.clone()].concat();
    all.sort_by_key(|e| e.offset);
    let mut inst = instrument(&p);
    let rest = render(&mut inst, &all, n);
    let mut inst = instrument(&p);
    let loud_alone = render(&mut inst, &loud, n);
    all.push(at(t0, Event::AllSoundOff));
    let mut inst = instrument(&p);
    let y = render(&mut inst, &all, n);
    let s = inst.stats;
    assert_eq!(
        (s.voices_ended, s.voices_ended_faded, s.steal_fades_cut),
        (20, 16, 4)
    );
    let (worst, tol) = worst_and_tol(&y, |ch, k| {
        if k < t0 {
            f(&rest, ch, k)
        } else {
            gain(k) * f(&loud_alone, ch, k)
        }
    });
    println!(
        "all sound off of 20 voices: {worst:.2e} from the 16 loud ones faded (tolerance {tol:.1e})"
    );
    assert!(worst <= tol, "{worst:e} > {tol:e}");
}

/// All Notes Off (MIDI CC 123; a CLAP note-off of every key) is a note-off
/// of every key, bit for bit: without pedals every note is released
/// there; what the sustain pedal holds rings on until it comes up, and
/// what the sostenuto pedal holds until it comes up.
#[test]
fn all_notes_off_is_every_key_up_and_the_pedals_hold() {
    let n = 30_000;
    let (t1, t2) = (6_000, 16_000);
    let notes = [on(10, 60, 0.8), on(20, 64, 0.7)];
    let with = |extra: &[TimedEvent]| {
        let mut ev = [&notes[..], extra].concat();
        ev.sort_by_key(|e| e.offset);
        play(&ev, n)
    };
    let all_off = with(&[at(t1, Event::AllNotesOff)]);
    assert!(all_off == with(&[off(t1, 60), off(t1, 64)]));
    assert!(all_off != with(&[]), "released");
    let sustained = with(&[
        pedal(0, true, true),
        at(t1, Event::AllNotesOff),
        pedal(t2, true, false),
    ]);
    assert!(
        sustained == with(&[off(t2, 60), off(t2, 64)]),
        "held by the sustain pedal"
    );
    let sostenuto = with(&[
        pedal(100, false, true),
        on(200, 67, 0.8),
        at(t1, Event::AllNotesOff),
        pedal(t2, false, false),
    ]);
    assert!(
        sostenuto == with(&[on(200, 67, 0.8), off(t1, 67), off(t2, 60), off(t2, 64)]),
        "the sostenuto pedal holds the keys that were down"
    );
}

/// Reset All Controllers (MIDI CC 121): the pedals come up (what they
/// held is damped there), the wheel goes back to the centre, channel
/// aftertouch, the mod wheel and every note's pressure to 0: bit for bit
/// the render with each of those sent at that sample.
#[test]
fn reset_all_controllers_lifts_the_pedals_centres_the_wheel_and_drops_pressure() {
    let n = 30_000;
    let t = 12_000;
    let with = |events: &[TimedEvent]| {
        let mut ev = events.to_vec();
        ev.sort_by_key(|e| e.offset);
        play(&ev, n)
    };
    let held = [
        pedal(0, true, true),
        on(10, 60, 0.8),
        pedal(50, false, true),
        on(100, 64, 0.7),
        off(2_000, 60),
        off(2_000, 64),
    ];
    let reset = with(&[&held[..], &[at(t, Event::ResetControllers)]].concat());
    let up = with(&[&held[..], &[pedal(t, true, false), pedal(t, false, false)]].concat());
    assert!(reset == up, "the pedals come up");
    assert!(reset != with(&held), "something was held");

    let moved = [
        on(10, 60, 0.8),
        on(20, 64, 0.7),
        bend(3_000, 1.0),
        at(3_000, Event::ChannelPressure { value: 0.6 }),
        at(3_000, Event::ModWheel { value: 0.3 }),
        pressure(3_000, Some(64), 0.9),
    ];
    let reset = with(&[&moved[..], &[at(t, Event::ResetControllers)]].concat());
    let back = with(
        &[
            &moved[..],
            &[
                bend(t, 0.0),
                at(t, Event::ChannelPressure { value: 0.0 }),
                at(t, Event::ModWheel { value: 0.0 }),
                pressure(t, None, 0.0),
            ],
        ]
        .concat(),
    );
    assert!(reset == back, "the wheel, aftertouch and pressure at rest");
    assert!(reset != with(&moved));
}

/// Lowering the Polyphony below the voices that sound ends the quietest of
/// them (the rule of a steal) as stolen voices end: the output is the
/// loud notes plus the quiet ones times the steal's fade gain, where a
/// release (what it was before) would miss by the quiet notes' whole
/// ringing amplitude on this undamped bar; then a new note steals.
#[test]
fn a_lowered_polyphony_fades_the_quietest_voices_as_steals_do() {
    let mut p = params("marimba-bar");
    p.play.polyphony = 8;
    let fade = ((FADE_S * RATE).round()) as usize;
    let (t0, n) = (8_832, 11_000);
    let gain = |k: usize| steal_fade_gain(k, t0, fade);
    let f = |x: &[Vec<f32>; 2], ch: usize, k: usize| f64::from(x[ch][k]);
    // loud and quiet notes interleaved over the voices
    let keys = [45u8, 50, 52, 55, 57, 60, 62, 67];
    let loud = |j: usize| j % 3 == 1;
    let note = |j: usize| on(100 * j, keys[j], if loud(j) { 0.9 } else { 0.2 });
    let all: Vec<TimedEvent> = (0..8).map(note).collect();
    let quiet: Vec<TimedEvent> = (0..8).filter(|&j| !loud(j)).map(note).collect();
    let mut inst = instrument(&p);
    let rest = render(&mut inst, &all, n);
    let mut inst = instrument(&p);
    let quiet_alone = render(&mut inst, &quiet, n);
    let mut inst = instrument(&p);
    let [l0, r0] = render(&mut inst, &all, t0);
    let mut lower = p.play;
    lower.polyphony = 3;
    inst.set_play(lower);
    let [l1, r1] = render(&mut inst, &[], n - t0);
    let y = [[l0, l1].concat(), [r0, r1].concat()];
    let mut sounding: Vec<u8> = inst.voice_keys().iter().flatten().copied().collect();
    sounding.sort();
    assert_eq!(sounding, [50, 57, 67], "the loud notes sound on");
    let s = inst.stats;
    assert_eq!((s.voices_ended, s.voices_ended_faded), (5, 5));
    let (worst, tol) = worst_and_tol(&y, |ch, k| {
        f(&rest, ch, k) - f(&quiet_alone, ch, k) + gain(k) * f(&quiet_alone, ch, k)
    });
    let released = largest(&quiet_alone, t0 + fade..n, |_| 1.0);
    println!("lowered polyphony: {worst:.2e} from the faded sum (tolerance {tol:.1e}), a release would miss by {released:.2e}");
    assert!(
        worst <= tol && released > 100.0 * tol,
        "{worst:e}, {released:e}"
    );
    render(&mut inst, &[on(0, 72, 0.8)], 100);
    assert_eq!((inst.stats.steals, inst.active_voices()), (1, 3));
}

/// A stolen voice follows the wheel, its note's tuning and the pressure
/// (channel aftertouch and its key's) while it fades, as a sounding voice
/// does: the output is, sample by sample, the stolen note played on with
/// the same controllers times the steal's fade gain plus the new note with
/// them; a fade deaf to them would miss that by far more than the
/// tolerance.
#[test]
fn a_stolen_voice_follows_the_bend_tuning_and_pressure_while_it_fades() {
    let mut p = params("marimba-bar");
    p.play.polyphony = 1;
    let fade = ((FADE_S * RATE).round()) as usize;
    let (t0, n) = (13_230, 14_400);
    let gain = |k: usize| steal_fade_gain(k, t0, fade);
    let f = |x: &[Vec<f32>; 2], ch: usize, k: usize| f64::from(x[ch][k]);
    let moves = [
        bend(t0, 1.0),
        tuning(t0 + 40, Some(57), 1.0),
        at(t0 + 70, Event::ChannelPressure { value: 0.8 }),
        pressure(t0 + 100, Some(57), 1.0),
    ];
    let run = |notes: &[TimedEvent], moves: &[TimedEvent]| {
        let mut ev = [notes, moves].concat();
        ev.sort_by_key(|e| e.offset);
        let mut inst = instrument(&p);
        render(&mut inst, &ev, n)
    };
    let y = run(&[on(0, 57, 0.8), on(t0, 64, 0.8)], &moves);
    let a_moved = run(&[on(0, 57, 0.8)], &moves);
    let a = run(&[on(0, 57, 0.8)], &[]);
    let b_moved = run(&[on(t0, 64, 0.8)], &moves);
    let (worst, tol) = worst_and_tol(&y, |ch, k| {
        gain(k) * f(&a_moved, ch, k) + f(&b_moved, ch, k)
    });
    let deaf = (0..2)
        .flat_map(|ch| (t0..t0 + fade).map(move |k| (ch, k)))
        .map(|(ch, k)| (gain(k) * (f(&a_moved, ch, k) - f(&a, ch, k))).abs())
        .fold(0.0, f64::max);
    println!("stolen and moved: {worst:.2e} from the faded sum (tolerance {tol:.1e}); a fade deaf to the controllers would miss by {deaf:.2e}");
    assert!(worst <= tol && deaf > 100.0 * tol, "{worst:e}, {deaf:e}");
}
