//! How kit voices end: a choke, All Sound Off, a lowered Polyphony and a
//! steal fade them as voices of one contact fade; a released kit voice
//! rings on its damped compile; pressure damps a kit voice clear of its
//! mallets (docs/plugin.md, "Velocity, pitch, voices" and "Pressure and
//! the mod wheel").

use super::*;

/// Kit voices end as voices do (docs/plugin.md, "Velocity, pitch,
/// voices"): a choke of a pitched kit's key, All Sound Off and a lowered
/// Polyphony (the quietest kit voice) fade them out exactly as a stolen
/// kit voice fades (the output is the others plus the ended ones times
/// the steal's fade gain, where a release, on this kit without a damper, would
/// leave them ringing); a kit of listed notes, one voice for every key,
/// fades in a spare kit state of its own when its last note's key or
/// every note is choked, and a choke of another key leaves it; a stolen
/// kit voice follows the wheel and its note's tuning while it fades.
#[test]
fn kit_voices_end_and_bend_as_voices_do() {
    let scene = two_mallets();
    let notes = [on(0, 57, 0.9), on(500, 64, 0.3)];
    let (both, _) = run_ending(&scene, 4, &notes);
    let (a, _) = run_ending(&scene, 4, &notes[..1]);
    let (b, _) = run_ending(&scene, 4, &notes[1..]);
    kit_choke_and_all_sound_off_fade(&scene, &notes, [&a, &b, &both]);
    kit_lowered_polyphony_fades(&scene, &notes, [&a, &b]);
    stolen_kit_voice_bends(&scene, &notes, &a);
    listed_kit_ends_by_choke_and_all_sound_off();
}

/// The samples rendered in [`kit_voices_end_and_bend_as_voices_do`].
const ENDING_N: usize = 16_800;

/// A kit voice's steal fade, in samples.
fn ending_fade() -> usize {
    (FADE_S * RATE).round() as usize
}

/// The moment the notes of the two-mallet kit are ended.
const ENDING_T0: usize = 14_400;

/// Sample `k` of channel `ch` of `x`.
fn sample(x: &[Vec<f32>; 2], ch: usize, k: usize) -> f64 {
    f64::from(x[ch][k])
}

/// `scene` played with Polyphony `poly` through `events` for
/// [`ENDING_N`] samples: its output and the instrument.
fn run_ending(scene: &Scene, poly: usize, events: &[TimedEvent]) -> ([Vec<f32>; 2], Instrument) {
    let p = prepare_scene(scene, &SceneParams::default(), RATE, 0).unwrap();
    let play = PlayParams {
        gain_db: 0.0,
        polyphony: poly,
        ..PlayParams::default()
    };
    let mut inst = Instrument::new(p, play);
    let mut ev = events.to_vec();
    ev.sort_by_key(|e| e.offset);
    let out = render(&mut inst, &ev, ENDING_N);
    (out, inst)
}

/// `y` is `expect` within its tolerance, and without the fade it would
/// miss by `miss`, far more.
fn check_faded(what: &str, y: &[Vec<f32>; 2], expect: &dyn Fn(usize, usize) -> f64, miss: f64) {
    let (worst, tol) = worst_and_tol(y, expect);
    println!("{what}: {worst:.2e} from the faded sum (tolerance {tol:.1e}), without the fade it would miss by {miss:.2e}");
    assert!(
        worst <= tol && miss > 100.0 * tol,
        "{what}: {worst:e}, {miss:e}"
    );
}

/// How loud `x` still is after `t0` and a fade.
fn ringing_after(x: &[Vec<f32>; 2], t0: usize) -> f64 {
    largest(x, t0 + ending_fade()..ENDING_N, |_| 1.0)
}

/// A choke of a pitched kit's key fades that key's voice, All Sound Off
/// fades both (`[a, b, both]`: the first note alone, the second alone,
/// both).
fn kit_choke_and_all_sound_off_fade(
    scene: &Scene,
    notes: &[TimedEvent; 2],
    [a, b, both]: [&[Vec<f32>; 2]; 3],
) {
    let t0 = ENDING_T0;
    let gain = |k: usize| steal_fade_gain(k, t0, ending_fade());
    let (y, inst) = run_ending(
        scene,
        4,
        &[&notes[..], &[at(t0, Event::Choke { key: Some(57) })]].concat(),
    );
    assert_eq!(inst.voice_keys()[..2], [None, Some(64)]);
    assert_eq!(inst.stats.voices_ended_faded, 1);
    let expect = |ch, k| sample(b, ch, k) + gain(k) * sample(a, ch, k);
    check_faded("kit choke", &y, &expect, ringing_after(a, t0));

    let (y, inst) = run_ending(
        scene,
        4,
        &[&notes[..], &[at(t0, Event::AllSoundOff)]].concat(),
    );
    assert_eq!(
        (inst.active_voices(), inst.stats.voices_ended_faded),
        (0, 2)
    );
    check_faded(
        "kit all sound off",
        &y,
        &|ch, k| gain(k) * sample(both, ch, k),
        ringing_after(both, t0),
    );
}

/// Polyphony 4 -> 1: the quieter key (64) fades (`[a, b]`: each note
/// alone).
fn kit_lowered_polyphony_fades(
    scene: &Scene,
    notes: &[TimedEvent; 2],
    [a, b]: [&[Vec<f32>; 2]; 2],
) {
    let t0 = ENDING_T0;
    let gain = |k: usize| steal_fade_gain(k, t0, ending_fade());
    let p = prepare_scene(scene, &SceneParams::default(), RATE, 0).unwrap();
    let play = PlayParams {
        gain_db: 0.0,
        polyphony: 4,
        ..PlayParams::default()
    };
    let mut inst = Instrument::new(p, play);
    let [l0, r0] = render(&mut inst, notes, t0);
    inst.set_play(PlayParams {
        polyphony: 1,
        ..play
    });
    let [l1, r1] = render(&mut inst, &[], ENDING_N - t0);
    let y = [[l0, l1].concat(), [r0, r1].concat()];
    assert_eq!(inst.voice_keys()[..2], [Some(57), None]);
    let expect = |ch, k| sample(a, ch, k) + gain(k) * sample(b, ch, k);
    check_faded("kit polyphony lowered", &y, &expect, ringing_after(b, t0));
}

/// A stolen kit voice bends and glides with its note's tuning (`a`: the
/// first note alone).
fn stolen_kit_voice_bends(scene: &Scene, notes: &[TimedEvent; 2], a: &[Vec<f32>; 2]) {
    let t0 = ENDING_T0;
    let fade = ending_fade();
    let gain = |k: usize| steal_fade_gain(k, t0, fade);
    let moves = [
        at(t0, Event::PitchBend { value: -1.0 }),
        at(
            t0 + 30,
            Event::NoteTuning {
                key: Some(57),
                semitones: 2.0,
            },
        ),
    ];
    let (y, _) = run_ending(
        scene,
        1,
        &[&notes[..1], &[on(t0, 64, 0.3)], &moves[..]].concat(),
    );
    let (a_moved, _) = run_ending(scene, 1, &[&notes[..1], &moves[..]].concat());
    let (b_moved, _) = run_ending(scene, 1, &[&[on(t0, 64, 0.3)], &moves[..]].concat());
    let deaf = (0..2)
        .flat_map(|ch| (t0..t0 + fade).map(move |k| (ch, k)))
        .map(|(ch, k)| (gain(k) * (sample(&a_moved, ch, k) - sample(a, ch, k))).abs())
        .fold(0.0, f64::max);
    let expect = |ch, k| gain(k) * sample(&a_moved, ch, k) + sample(&b_moved, ch, k);
    check_faded("stolen kit voice bent", &y, &expect, deaf);
}

/// A kit of listed notes (its modes die in 0.15 s: end it early) fades
/// when its last note's key or every note is choked; a choke of another
/// key leaves it.
fn listed_kit_ends_by_choke_and_all_sound_off() {
    let listed = small_kit("notes = [60]", "notes = [62, 60]");
    let t0 = 2_400;
    let gain = |k: usize| steal_fade_gain(k, t0, ending_fade());
    let (a, _) = run_ending(&listed, 16, &[on(0, 62, 0.8), on(100, 60, 0.8)]);
    for key in [Some(60), None] {
        let ev = [
            on(0, 62, 0.8),
            on(100, 60, 0.8),
            at(t0, Event::Choke { key }),
        ];
        let (y, inst) = run_ending(&listed, 16, &ev);
        assert_eq!(inst.active_voices(), 0);
        let what = format!("listed kit, choke of {key:?}");
        check_faded(
            &what,
            &y,
            &|ch, k| gain(k) * sample(&a, ch, k),
            ringing_after(&a, t0),
        );
    }
    let ev = [
        on(0, 62, 0.8),
        on(100, 60, 0.8),
        at(t0, Event::Choke { key: Some(62) }),
    ];
    let (y, _) = run_ending(&listed, 16, &ev);
    assert!(y == a, "a choke of a key that is not its last note's");
    let ev = [on(0, 62, 0.8), on(100, 60, 0.8), at(t0, Event::AllSoundOff)];
    let (y, _) = run_ending(&listed, 16, &ev);
    check_faded(
        "listed kit, all sound off",
        &y,
        &|ch, k| gain(k) * sample(&a, ch, k),
        ringing_after(&a, t0),
    );
}

/// `small_kit`'s modes ringing long (T60 2, 1 and 0.5 s) with the damper
/// `damper` in its `[play]`.
pub(super) fn ringing_kit(damper: f64) -> Scene {
    let mut scene = small_kit("", "");
    if let crate::scene::ObjectSpec::Modal(m) = &mut scene.object[0] {
        for (mode, t60) in m.mode.iter_mut().zip([2.0, 1.0, 0.5]) {
            mode.t60_s = Some(t60);
        }
    }
    scene.play = Some(crate::scene::PlaySpec {
        damper: Some(damper),
        ..Default::default()
    });
    scene
}

/// The decay of `x` in dB/s: a least-squares line through the levels of
/// its 5 ms windows from `from` to `to` seconds.
fn decay_db_per_s(x: &[f32], from: f64, to: f64) -> f64 {
    let w = (0.005 * RATE) as usize;
    let (mut pts, mut t) = (Vec::new(), from);
    while t + 0.005 <= to {
        let k = (t * RATE) as usize;
        let ms = x[k..k + w]
            .iter()
            .map(|&v| f64::from(v).powi(2))
            .sum::<f64>()
            / w as f64;
        pts.push((t + 0.0025, 10.0 * ms.log10()));
        t += 0.005;
    }
    let n = pts.len() as f64;
    let (mt, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, y)| (a + t / n, b + y / n));
    let sxy: f64 = pts.iter().map(|(t, y)| (t - mt) * (y - my)).sum();
    let sxx: f64 = pts.iter().map(|(t, _)| (t - mt) * (t - mt)).sum();
    -sxy / sxx
}

/// A released kit voice continues on the kit's damped compile
/// (docs/design.md, "Played as a kit"), as a voice of one contact
/// continues on its damped scene: until the note-off it plays as the same
/// kit without a damper, sample for sample; the note-off (no contact
/// closed) carries it there with its energy unchanged to rounding; from
/// there its output falls as fast as the damped scene's slowest mode (T60
/// divided by 1 + 50 damper), against the undamped kit's slow decay; a
/// new note on its key carries it back to the played compile.
#[test]
fn a_released_kit_voice_continues_on_the_damped_compile() {
    let mut a = kit_instrument(&ringing_kit(0.5), 0.0);
    let mut b = kit_instrument(&ringing_kit(0.0), 0.0);
    assert!(kit(&a).damped.is_some() && kit(&b).damped.is_none());
    let key = a.cur.root_note as u8;
    let n = (0.3 * RATE) as usize;
    let ra = render(&mut a, &[on(0, key, 0.8)], n);
    let rb = render(&mut b, &[on(0, key, 0.8)], n);
    assert!(ra == rb, "the same kit until the note-off");
    let i = a.voices.iter().position(|v| v.active).unwrap();
    let energy = |inst: &Instrument| {
        let k = kit(inst);
        let st = &k.voices[i].st;
        st.observe(k.sc_for(kit::kit_at(&inst.voices[i]))).energy
    };
    let e0 = energy(&a);
    a.note_off(Some(key));
    b.note_off(Some(key));
    assert!(
        a.voices[i].released && a.voices[i].on_damped,
        "carried at once"
    );
    assert!(b.voices[i].released && !b.voices[i].on_damped);
    let e1 = energy(&a);
    println!(
        "energy at the carry {e0:.6e} -> {e1:.6e} J (model), relative {:.1e}",
        (e1 - e0) / e0
    );
    assert!(((e1 - e0) / e0).abs() < 1e-12);
    let m = (0.05 * RATE) as usize;
    let [da, _] = render(&mut a, &[], m);
    let [db, _] = render(&mut b, &[], m);
    let (rate_a, rate_b) = (
        decay_db_per_s(&da, 0.005, 0.045),
        decay_db_per_s(&db, 0.005, 0.045),
    );
    // the slowest mode's decay [dB/s]: 8.686 sigma, the damped compile's
    // and the played one's
    let slowest = |sc: &CompiledMulti| {
        let s = sc.model.sigma.iter().copied().fold(f64::INFINITY, f64::min);
        20.0 * std::f64::consts::E.log10() * s
    };
    let (want_a, want_b) = (
        slowest(kit(&a).damped.as_ref().unwrap()),
        slowest(&kit(&b).sc),
    );
    println!("decay after the release: damped {rate_a:.0} dB/s (slowest mode {want_a:.0}), undamped {rate_b:.1} dB/s (slowest mode {want_b:.1})");
    assert!(
        (rate_a / want_a - 1.0).abs() < 0.03,
        "{rate_a} against {want_a}"
    );
    assert!(
        (rate_b / want_b - 1.0).abs() < 0.1,
        "{rate_b} against {want_b}"
    );
    // struck again on its key: back on the played compile
    render(&mut a, &[on(0, key, 0.8)], 1);
    assert!(!a.voices[i].released && !a.voices[i].on_damped);
    // released while its mallet is on the object: it waits for the
    // contact to open, then goes on the damped compile at a grid step
    let mut t = 0;
    while kit(&a).voices[i].st.observe(&kit(&a).sc).active == 0 {
        render(&mut a, &[], 1);
        t += 1;
        assert!(t < 4800, "the mallet lands");
    }
    a.note_off(Some(key));
    assert!(a.voices[i].released && !a.voices[i].on_damped, "waits");
    let mut waited = 0;
    while !a.voices[i].on_damped {
        render(&mut a, &[], 64);
        waited += 64;
        assert!(waited < 4800, "carried once the contact opens");
    }
    let damped = kit::KitAt {
        damped: true,
        ..kit::KitAt::default()
    };
    assert_eq!(
        kit(&a).voices[i].st.observe(kit(&a).sc_for(damped)).active,
        0
    );
    println!("released in contact: carried {waited} samples later");
}

/// One mode of a kit voice, played at its own pitch, under pressure `p`
/// from its note-on: once its mallet has left and no contact of it can
/// close, its free decay has the closed form of a damped mode, `y_(n+1) =
/// 2 r cos(w dt) y_n - r^2 y_(n-1)` with `w = sqrt(omega^2 - sigma^2)` and
/// `r = exp(-sigma dt)`, where pressure adds `p MAX_PRESSURE_DECAY_PER_S`
/// to `sigma` and keeps `w` (as on a voice of one contact:
/// `src/instrument/tests/pressure.rs`). The worst residual over the peak
/// of the free and of the pressed recurrence, and the samples pressed.
fn kit_one_mode_residuals(p: f64) -> (f64, f64, u64) {
    let mut scene = ringing_kit(0.0);
    let crate::scene::ObjectSpec::Modal(m) = &mut scene.object[0] else {
        panic!("modal")
    };
    m.mode.truncate(1);
    let (f, t60) = (m.mode[0].freq_hz, m.mode[0].t60_s.unwrap());
    let mut inst = kit_instrument(&scene, 0.0);
    let key = inst.cur.root_note as u8;
    let press = TimedEvent {
        offset: 0,
        event: Event::ChannelPressure { value: p },
    };
    let n = 20_000;
    let [y, _] = render(&mut inst, &[on(0, key, 0.8), press], n);
    let (free, pressed) = one_mode_residuals(&y, RATE, (f, t60), p * MAX_PRESSURE_DECAY_PER_S);
    (free, pressed, inst.stats.pressed_samples)
}

/// Pressure damps a kit voice as it damps a voice of one contact
/// (docs/plugin.md, "Pressure and the mod wheel"): one more decay rate on
/// every mode once no contact of the voice can close
/// (`MultiState::contacts_clear`), its frequency kept, and nothing while
/// it is not pressed.
#[test]
fn pressure_adds_one_decay_rate_to_a_kit_voice_clear_of_its_mallets() {
    let (plain, _, none) = kit_one_mode_residuals(0.0);
    let (wrong, right, pressed) = kit_one_mode_residuals(0.6);
    println!(
        "kit, one mode, closed-form recurrence residual / peak: no pressure {plain:.1e}; \
         pressure 0.6: with the pressed decay {right:.1e}, with the free decay {wrong:.1e} \
         ({pressed} samples pressed)"
    );
    assert_eq!(none, 0);
    assert!(pressed > 10_000, "{pressed}");
    // f32 output: residuals of a few 1e-8 of the peak
    assert!(plain < 1e-6 && right < 1e-6, "{plain:e} {right:e}");
    assert!(wrong > 30.0 * right, "the pressure did nothing: {wrong:e}");
}
