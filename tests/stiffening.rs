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
    let key = modal_contact::instrument::root_note(scene).round() as u8;
    attack_of(scene, key, velocity)
}

/// The attack of note `key` of `scene` at `velocity` (0 to 1).
fn attack_of(scene: &Scene, key: u8, velocity: f64) -> Vec<f32> {
    let p = prepare_scene(scene, &SceneParams::default(), RATE, 0).unwrap();
    let mut inst = Instrument::new(p, InstrumentParams::default().play);
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

/// A yarn mallet of mass `m` on spring `k` as a law that stiffens: `F ~
/// p^2` through the linear spring's force at its deepest for a 2 m/s
/// strike (the same contact there), fitted over the penetrations of the
/// softest to the hardest note, in `pieces` pieces.
fn yarn_law(m: f64, k: f64, pieces: usize) -> LawSpec {
    let p2 = 2.0 * (m / k).sqrt();
    let top = impact_speed_m_per_s(1.0) * (m / k).sqrt();
    let low = impact_speed_m_per_s(0.1) * (m / k).sqrt();
    LawSpec {
        power: Some(2.0),
        force_n_at: Some([p2, k * p2]),
        pieces: Some(pieces),
        up_to_m: Some(1.5 * top),
        from_m: Some(0.5 * low),
        ..LawSpec::default()
    }
}

/// marimba-bar's yarn mallet as a law that stiffens ([`yarn_law`], four
/// pieces).
fn stiffening_marimba() -> Scene {
    let mut s = presets::scene(presets::index_of("marimba-bar").unwrap()).unwrap();
    let (m, k) = (s.hammer.mass_kg, s.contact.stiffness_n_per_m);
    s.contact.stiffness_n_per_m = 0.0;
    s.contact.law = Some(yarn_law(m, k, 4));
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

/// A kit's second mallet (`[[striker]]`) with a law that stiffens: in
/// marimba-two-mallets with each mallet on a key of its own (a kit of
/// listed notes), the striker's key brightens with velocity when its
/// yarn is a law of three pieces and does not with its linear spring.
#[test]
fn a_strikers_stiffening_law_brightens_its_key_through_the_instrument() {
    let mut linear = presets::scene(presets::index_of("marimba-two-mallets").unwrap()).unwrap();
    linear.hammer.notes = vec![61];
    linear.striker[0].notes = vec![60];
    // the striker thrown from just over the bar, as the hammer is
    linear.striker[0].height_m = linear.hammer.height_m;
    linear.validate().unwrap();
    let mut law = linear.clone();
    let st = &mut law.striker[0];
    let (m, k) = (st.mass_kg, st.stiffness_n_per_m);
    st.stiffness_n_per_m = 0.0;
    st.law = Some(yarn_law(m, k, 3));
    law.validate().unwrap();
    let (lp, lf) = (
        centroid(&attack_of(&linear, 60, 0.16)),
        centroid(&attack_of(&linear, 60, 1.0)),
    );
    let (sp, sf) = (
        centroid(&attack_of(&law, 60, 0.16)),
        centroid(&attack_of(&law, 60, 1.0)),
    );
    eprintln!(
        "striker's attack centroid pp -> ff: linear {lp:.1} -> {lf:.1} Hz, stiffening {sp:.1} -> {sf:.1} Hz"
    );
    assert!((lf / lp - 1.0).abs() < 0.02, "linear: {lp} vs {lf}");
    assert!(sf > 1.2 * sp, "stiffening: {sp} vs {sf}");
}
