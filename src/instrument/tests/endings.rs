//! Tests of the messages that end or release notes from outside: a choke,
//! All Sound Off, All Notes Off, and Reset All Controllers (the pedals
//! up).

use super::*;

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
