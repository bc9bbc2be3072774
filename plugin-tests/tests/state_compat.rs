//! Projects saved before the parameters came from one list load unchanged
//! in the BUILT (release) plugin: the same preset for every saved scene id,
//! every other value as saved, and saving again gives the same bytes plus
//! the parameters added since, at their defaults.
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
/// added since that build at their defaults (ids in order).
fn saved_back(saved: &str) -> String {
    saved
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
