//! Tests of the compiled levels a note is played at: brightness, and the
//! hosts' per-note hardness, strike position and damper; every preset's
//! levels, and a prepare that fits a small host thread's stack.

use super::*;

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

/// The largest difference between two renders' samples.
fn max_diff(x: &[f32], y: &[f32]) -> f32 {
    x.iter()
        .zip(y)
        .fold(0.0f32, |m, (p, q)| m.max((p - q).abs()))
}

/// On a kit (the two-mallet marimba), a note's strike position once the
/// position levels are compiled plays the strike of a kit prepared at the
/// level's position (and with a hardness, the pair's): the voice is carried
/// onto the level's compile through the physical state before its mallet
/// lands, so the same samples to rounding; without the levels the
/// parameter's position.
#[test]
fn position_modulation_strikes_a_kit_voice_at_its_level() {
    let mut p = params("marimba-two-mallets");
    p.scene.strike_pos_norm = Some(0.4);
    p.scene.variants.position = true;
    let pr = prepare(&p.scene, RATE, 0).unwrap();
    let kit = pr.kit.as_deref().unwrap();
    assert_eq!((kit.hardness_levels(), kit.position_levels()), (4, 20));
    let root = pr.root_note.round() as u8;
    let n = 4800;
    let mut sounds = Vec::new();
    for (by, pos, factor, hl) in [
        (0.1, 1, 1.0, 0),
        (-0.2, -2, 1.0, 0),
        (0.1, 1, 2.0, 1),
        (f64::NAN, 0, 1.0, 0),
    ] {
        let mut inst = instrument(&p);
        let [got, _] = render(
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
        q.scene.strike_pos_norm = Some(0.4 + f64::from(pos) * POSITION_STEP);
        q.scene.stiffness_factor *= TIMBRE_STIFFNESS_STEP.powi(i32::from(hl));
        let [want, _] = render(&mut instrument(&q), &[on(10, root, 0.8)], n);
        let peak = want.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        let d = max_diff(&got, &want);
        println!("kit, position offset {by}, hardness x{factor}: {d:.2e} of peak {peak:.3e}");
        assert!(d <= 1e-6 * peak, "offset {by}: {d:e}");
        sounds.push(got);
    }
    assert!(sounds[3] == render(&mut instrument(&p), &[on(10, root, 0.8)], n)[0]);
    let peak = sounds[3].iter().fold(0.0f32, |m, x| m.max(x.abs()));
    for (a, b) in [(0, 1), (0, 3), (1, 3)] {
        let d = max_diff(&sounds[a], &sounds[b]);
        assert!(d > 1e-2 * peak, "levels {a} and {b}: {d:e}");
    }
    // not asked for: the parameter's position, no levels but hardness's
    let mut q = p;
    q.scene.variants.position = false;
    let pr = prepare(&q.scene, RATE, 0).unwrap();
    assert_eq!(pr.kit.as_deref().unwrap().position_levels(), 0);
    let got = render(
        &mut instrument(&q),
        &[on(10, root, 0.8), position(10, Some(root), 0.2)],
        n,
    );
    assert!(got == render(&mut instrument(&q), &[on(10, root, 0.8)], n));
}

/// On a kit (the two-mallet marimba), a note's damper once the damper
/// levels are compiled damps its release as a kit prepared with the
/// level's Damper, bit for bit (the same compiles, the same carry; a level
/// at damper 0 rings on); a change after the release carries the released
/// voice to the new level's damped compile.
#[test]
fn damper_modulation_damps_a_released_kit_voice_at_its_level() {
    let mut p = params("marimba-two-mallets");
    p.scene.damper_norm = 0.5;
    p.scene.damper_custom = true;
    p.scene.variants.damper = true;
    let pr = prepare(&p.scene, RATE, 0).unwrap();
    assert_eq!(pr.kit.as_deref().unwrap().damper_levels(), 4);
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
        assert_eq!(inst.voices[0].at.damper, level, "offset {by}");
        assert_eq!(inst.voices[0].on_damped, level != -2, "offset {by}");
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
    println!("kit release tails by damper level: {tails:?}");
    assert!(tails.windows(2).all(|w| w[1] < w[0]), "{tails:?}");
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
    println!("kit damper raised after the release: tail {a:.3e} -> {b:.3e}");
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
        if let Some(kit) = pr.kit.as_deref() {
            // a kit's levels are its own compiles
            assert_eq!(pr.scenes.variant_count(), 0, "{name}");
            assert!(
                pr.timbre_note().is_none() && kit.hardness_levels() == 4,
                "{name}: {} states",
                kit.max_dim()
            );
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
