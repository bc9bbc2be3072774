//! Tests of the pitch bend and the per-note tuning: glides that add no
//! energy and make no step, independent of the host's blocks.

use super::*;

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
