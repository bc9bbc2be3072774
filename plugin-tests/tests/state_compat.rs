//! Projects saved before the parameters came from one list load unchanged
//! in the BUILT (release) plugin: the same preset for every saved scene id,
//! every other value as saved, and saving again gives the same bytes plus
//! the parameters added since, at their defaults (Custom damper on: that
//! build's Damper always applied, and keeps applying).
//!
//! The state below is what that build saved (nice-plug's CLAP state: an
//! 8-byte little-endian length, then the JSON; parameters in id order, the
//! scene and the switching method stored by their string ids): both tests
//! were run against a bundle of that build too, where saving it back gave
//! these bytes. The table of
//! scene ids is the order that build gave them: hosts that automated the
//! Scene parameter stored these positions.

use modal_contact::plugin::params::ids;
use plugin_tests::*;

/// Every parameter off its default, the scene and switching by string id.
const SAVED: &str = concat!(
    r#"{"version":"0.1.0","params":{"#,
    r#""contact_damping":{"f32":0.5},"damper":{"f32":0.25},"decay":{"f32":2.0},"#,
    r#""drop_height":{"f32":35.0},"gain":{"f32":-12.0},"gravity":{"f32":4.5},"#,
    r#""hammer_mass":{"f32":0.75},"hardness":{"f32":3.0},"pitch_tracking":{"bool":false},"#,
    r#""scene":{"string":"wood-block"},"strike_custom":{"bool":true},"strike_pos":{"f32":0.25},"#,
    r#""switching":{"string":"offset-rod"}},"fields":{}}"#
);

/// The scene ids of that build, at their positions.
const SHIPPED_SCENES: [&str; 7] = [
    "bell",
    "glockenspiel-bar",
    "marimba-bar",
    "paper-bounce",
    "paper-string",
    "steel-plate",
    "wood-block",
];

/// What saving [`SAVED`] back writes: the same entries, and the parameters
/// added since that build at their defaults (ids in order), but Custom
/// damper on (the saved Damper plays, as it did).
fn saved_back(saved: &str) -> String {
    saved
        .replace(
            r#""damper":{"f32":0.25},"#,
            r#""damper":{"f32":0.25},"damper_custom":{"bool":true},"#,
        )
        .replace(
            r#""pitch_tracking":{"bool":false},"#,
            r#""lookahead":{"i32":0},"pitch_tracking":{"bool":false},"polyphony":{"i32":16},"#,
        )
        .replace(
            r#""params":{"contact_damping""#,
            r#""params":{"bend_range":{"f32":2.0},"contact_damping""#,
        )
}

fn state_of(json: &str) -> Vec<u8> {
    let mut out = (json.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(json.as_bytes());
    out
}

#[test]
fn a_state_saved_before_the_single_list_loads_unchanged() {
    let bundle = clap_bundle(Variant::Release);
    let mut p = LoadedPlugin::load(&bundle);
    let saved = state_of(SAVED);
    assert!(p.try_load_state(&saved), "the saved state must load");
    // the stepped parameters as the host reads them (their step)
    for (id, want) in [
        (ids::SCENE, 6.0),
        (ids::SWITCHING, 0.0),
        (ids::PITCH_TRACKING, 0.0),
        (ids::STRIKE_CUSTOM, 1.0),
        // new since, and on: the saved Damper keeps applying
        (ids::DAMPER_CUSTOM, 1.0),
    ] {
        let got = p.param_value(param_id(id));
        assert!((got - want).abs() < 1e-6, "{id}: {got} (saved {want})");
    }
    // new since: its default, 16 voices (CLAP value: the step from 1)
    let poly = p.param_value(param_id(ids::POLYPHONY));
    assert!((poly - 15.0).abs() < 1e-6, "polyphony step {poly}");
    // and no lookahead (no latency)
    let lookahead = p.param_value(param_id(ids::LOOKAHEAD));
    assert_eq!(lookahead, 0.0, "lookahead step {lookahead}");
    assert_eq!(p.latency(), 0);
    // Saving again gives the same bytes: every value was taken as saved (a
    // refused one would have been replaced by its default) and the format
    // is the same; the parameters added since come at their defaults.
    assert_eq!(
        String::from_utf8(p.save_state()[8..].to_vec()).unwrap(),
        saved_back(SAVED),
        "saving again gives the same state"
    );
}

#[test]
fn every_saved_scene_id_loads_as_the_same_preset() {
    let bundle = clap_bundle(Variant::Release);
    let mut p = LoadedPlugin::load(&bundle);
    for (index, id) in SHIPPED_SCENES.iter().enumerate() {
        let json = SAVED.replace(
            r#""scene":{"string":"wood-block"}"#,
            &format!(r#""scene":{{"string":"{id}"}}"#),
        );
        assert!(p.try_load_state(&state_of(&json)), "{id}");
        let got = p.param_value(param_id(ids::SCENE));
        assert!(
            (got - index as f64).abs() < 1e-6,
            "{id}: at {got}, saved at {index}"
        );
        let again = String::from_utf8(p.save_state()[8..].to_vec()).unwrap();
        assert_eq!(
            again,
            saved_back(&json),
            "{id}: saved back under the same id"
        );
    }
}

/// A project saved before Custom damper existed plays the Damper it was
/// saved with: on the marimba bar (whose own damper is 0: it rings on), a
/// note released after 50 ms sounds exactly as with a state that says
/// Custom damper on, and is damped far below the one of a state that says
/// off.
#[test]
fn a_state_saved_before_custom_damper_plays_its_damper() {
    let bundle = clap_bundle(Variant::Release);
    let old = SAVED.replace(
        r#""scene":{"string":"wood-block"}"#,
        r#""scene":{"string":"marimba-bar"}"#,
    );
    let saying = |custom: bool| {
        old.replace(
            r#""damper":{"f32":0.25},"#,
            &format!(r#""damper":{{"f32":0.25}},"damper_custom":{{"bool":{custom}}},"#),
        )
    };
    let play = |json: &str| {
        let mut p = LoadedPlugin::load(&bundle);
        assert!(p.try_load_state(&state_of(json)), "{json}");
        let rate = 44_100.0;
        let t0 = 1_024;
        let mut spec = RenderSpec::new(
            rate,
            256,
            22_050,
            vec![on(t0, 57, 0.8), off(t0 + 2_205, 57)],
        );
        // (time for the worker's compile before the note; not a timing
        // assertion)
        spec.settle_after = vec![0];
        spec.settle_ms = 400;
        let out = p.render(&spec);
        assert!(peak(&out[0]) > 1e-3, "silent");
        rms(&out[0][t0 + 2_205 + 4_410..])
    };
    let (old_tail, on_tail, off_tail) = (play(&old), play(&saying(true)), play(&saying(false)));
    println!("release tails: old state {old_tail:.3e}, Custom damper on {on_tail:.3e}, off {off_tail:.3e}");
    assert_eq!(old_tail, on_tail, "the old state plays its Damper");
    assert!(old_tail < 0.01 * off_tail, "{old_tail} vs {off_tail}");
}
