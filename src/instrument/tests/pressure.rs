//! Tests of pressure (channel and per-note aftertouch, the mod wheel):
//! one more decay rate on every mode, never energy added.

use super::*;

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
    one_mode_residuals(&y, RATE, (f, t60), p * MAX_PRESSURE_DECAY_PER_S)
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
