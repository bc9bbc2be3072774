//! Tests of notes and voices: a note's timing and loudness, restrikes,
//! the quietest voice taken, releases, Polyphony, the f32 output, and the
//! strikes from rest and key propagators a new note takes.

use super::*;

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
