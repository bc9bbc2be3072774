//! Tests of a swap of the compiled scene under sounding voices: carried
//! without a jump, faded on a preset change, a steal's fade let finish.

use super::*;

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
