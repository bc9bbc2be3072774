//! Tests of voice stealing: a stolen voice fades while the new note starts
//! at once, at every polyphony, only voices that sounded fade, a lowered
//! Polyphony ends voices as steals do, and a fading voice follows the
//! controllers.

use super::*;

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
