//! A stiffening contact through the instrument (docs/design.md,
//! "Stiffening contacts"): struck harder, a law that stiffens makes the
//! attack brighter, where a linear spring's attack has the same spectrum
//! at every velocity.

use modal_contact::instrument::{
    impact_speed_m_per_s, prepare_scene, Event, Instrument, InstrumentParams, SceneParams,
    TimedEvent,
};
use modal_contact::presets;
use modal_contact::scene::{LawSpec, Scene};
use modal_testkit::analysis;

const RATE: f64 = 44_100.0;
/// The attack: the first 50 ms.
const ATTACK: usize = 2_205;

/// The attack's spectral centroid \[Hz\] over the first 50 ms, as `cargo
/// xtask compare-real` measures it.
fn centroid(x: &[f32]) -> f64 {
    let x: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
    analysis::centroid(&analysis::attack_spectrum(&x, RATE, 0.05))
}

/// The attack of one note of `scene` at `velocity` (0 to 1).
fn attack(scene: &Scene, velocity: f64) -> Vec<f32> {
    let p = prepare_scene(scene, &SceneParams::default(), RATE, 0).unwrap();
    let mut inst = Instrument::new(p, InstrumentParams::default().play);
    let key = modal_contact::instrument::root_note(scene).round() as u8;
    let events = [TimedEvent {
        offset: 0,
        event: Event::NoteOn {
            key,
            velocity_norm: velocity,
        },
    }];
    let n = ATTACK + 4096;
    let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
    inst.process(&events, &mut l, &mut r);
    // from the onset (the instrument's lookahead delays it)
    let start = l.iter().position(|v| v.abs() > 1e-6).expect("a sound");
    l[start..start + ATTACK].to_vec()
}

/// marimba-bar's yarn mallet as a law that stiffens: `F ~ p^2` through the
/// linear spring's force at its deepest for a 2 m/s strike (the same
/// contact there), fitted over the penetrations of the softest to the
/// hardest note.
fn stiffening_marimba() -> Scene {
    let mut s = presets::scene(presets::index_of("marimba-bar").unwrap()).unwrap();
    let (m, k) = (s.hammer.mass_kg, s.contact.stiffness_n_per_m);
    let p2 = 2.0 * (m / k).sqrt();
    let top = impact_speed_m_per_s(1.0) * (m / k).sqrt();
    let low = impact_speed_m_per_s(0.1) * (m / k).sqrt();
    s.contact.stiffness_n_per_m = 0.0;
    s.contact.law = Some(LawSpec {
        power: Some(2.0),
        force_n_at: Some([p2, k * p2]),
        pieces: Some(4),
        up_to_m: Some(1.5 * top),
        from_m: Some(0.5 * low),
        ..LawSpec::default()
    });
    s.validate().unwrap();
    s
}

#[test]
fn a_stiffening_mallet_is_brighter_struck_harder_and_a_linear_one_is_not() {
    let linear = presets::scene(presets::index_of("marimba-bar").unwrap()).unwrap();
    let law = stiffening_marimba();
    let (lp, lf) = (
        centroid(&attack(&linear, 0.16)),
        centroid(&attack(&linear, 1.0)),
    );
    let (sp, sf) = (centroid(&attack(&law, 0.16)), centroid(&attack(&law, 1.0)));
    eprintln!(
        "attack centroid pp -> ff: linear {lp:.1} -> {lf:.1} Hz, stiffening {sp:.1} -> {sf:.1} Hz"
    );
    assert!((lf / lp - 1.0).abs() < 0.02, "linear: {lp} vs {lf}");
    assert!(sf > 1.2 * sp, "stiffening: {sp} vs {sf}");
}
