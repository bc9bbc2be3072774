//! Tests of the mappings from the parameters and the keyboard to the
//! played scene: velocity, hardness, strike position, decay, damper,
//! gravity, root notes and pitch, a chain mallet under the hammer mass.

use super::*;

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
        "../../../tests/data/modal-presets/steel-plate.toml"
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

    // two points: ignored (the wood block as a table of modes, before it
    // became a physical description: its preset, heard by a listener,
    // expands into four points)
    let b = Scene::from_toml_str(include_str!(
        "../../../tests/data/modal-presets/wood-block.toml"
    ))
    .unwrap();
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
                                                       // A5, not its hum (A4, its lowest mode); the chime's strike note C#5,
                                                       // not its lowest mode (126 Hz, B2)
    assert_eq!(root_note(&base("bell")), 81.0);
    assert_eq!(root_note(&base("tubular-chime")), 73.0);
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
