//! Tests of the parameters: ids, names, ranges and defaults as declared,
//! saved states and their migration, the persisted fields.

use super::*;
use crate::plugin::user_scene::UserScene;
use crate::presets;
use nice_plug::plugin::{ParamValue, PluginState};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// `ParamValue` has no `PartialEq`: compare the debug forms.
macro_rules! same {
    ($a:expr, $b:expr $(, $m:expr)?) => {
        assert_eq!(format!("{:?}", $a), format!("{:?}", $b) $(, $m)?)
    };
}

fn full_state() -> PluginState {
    let mut state = PluginState {
        version: "0.0.1".into(),
        params: BTreeMap::new(),
        fields: BTreeMap::new(),
    };
    assert_eq!(
        migrate_state(&mut state).len(),
        PARAMS.len(),
        "all filled in"
    );
    state
}

/// The parameter `id` as nice-plug's wrappers see it.
fn ptr(p: &ModalContactParams, id: &str) -> ParamPtr {
    p.param_map()
        .into_iter()
        .find(|(i, _, _)| i == id)
        .unwrap_or_else(|| panic!("{id} not in the param map"))
        .1
}

#[test]
fn ids_never_change() {
    // The ids of the first release, in its order: saved projects and
    // automation refer to them.
    let shipped = [
        "scene",
        "hammer_mass",
        "hardness",
        "contact_damping",
        "strike_custom",
        "strike_pos",
        "decay",
        "damper",
        "pitch_tracking",
        "gravity",
        "drop_height",
        "gain",
        "switching",
    ];
    // later ids are appended, never inserted or renamed
    let added = ["polyphony", "bend_range", "lookahead", "damper_custom"];
    let all: Vec<&str> = shipped.iter().chain(&added).copied().collect();
    assert_eq!(ids::ALL.as_slice(), all.as_slice());
    let listed: Vec<&str> = PARAMS.iter().map(|s| s.id).collect();
    assert_eq!(listed, all);
    let p = ModalContactParams::default();
    let mapped: Vec<String> = p
        .param_map()
        .into_iter()
        .map(|(id, _, g)| id + &g)
        .collect();
    assert_eq!(
        mapped, all,
        "the param map is the list, in order, ungrouped"
    );
}

#[test]
fn every_parameter_is_built_from_its_entry() {
    let p = ModalContactParams::default();
    for s in PARAMS {
        let q = ptr(&p, s.id);
        // SAFETY: `q` points at a parameter of `p`, which lives to the
        // end of the loop body and is not moved meanwhile.
        unsafe {
            assert_eq!(q.name(), s.name);
            match s.kind {
                Kind::Float {
                    min,
                    max,
                    default,
                    unit,
                    ..
                } => {
                    assert_eq!(q.unit(), unit, "{}", s.id);
                    assert_eq!(q.step_count(), None, "{}", s.id);
                    let ends = (q.preview_plain(0.0), q.preview_plain(1.0));
                    let tol = 1e-6 * max.abs().max(min.abs()).max(1.0);
                    assert!(
                        (ends.0 - min).abs() <= tol && (ends.1 - max).abs() <= tol,
                        "{}: {ends:?}",
                        s.id
                    );
                    assert_eq!(q.default_plain_value(), default, "{}", s.id);
                    assert_eq!(q.unmodulated_plain_value(), default, "{}", s.id);
                }
                Kind::Int {
                    min,
                    max,
                    default,
                    unit,
                } => {
                    assert_eq!(q.unit(), unit, "{}", s.id);
                    assert_eq!(q.step_count(), Some((max - min) as usize), "{}", s.id);
                    assert_eq!(q.preview_plain(0.0), min as f32, "{}", s.id);
                    assert_eq!(q.preview_plain(1.0), max as f32, "{}", s.id);
                    assert_eq!(q.default_plain_value(), default as f32, "{}", s.id);
                }
                Kind::Bool { default } => {
                    assert_eq!(q.step_count(), Some(1), "{}", s.id);
                    assert_eq!(q.default_plain_value(), default as u8 as f32, "{}", s.id);
                }
                Kind::Choice {
                    ids,
                    names,
                    default,
                } => {
                    assert_eq!(ids.len(), names.len(), "{}", s.id);
                    assert_eq!(q.step_count(), Some(ids.len() - 1), "{}", s.id);
                    assert_eq!(q.default_plain_value(), default as f32, "{}", s.id);
                }
            }
        }
    }
}

#[test]
fn enumerated_values_show_names_and_parse_them() {
    let p = ModalContactParams::default();
    let mut choices = 0;
    for s in PARAMS {
        let Kind::Choice { names, .. } = s.kind else {
            continue;
        };
        choices += 1;
        let q = ptr(&p, s.id);
        let last = (names.len() - 1) as f32;
        for (i, name) in names.iter().enumerate() {
            let norm = i as f32 / last;
            // SAFETY: `q` points at a parameter of `p`, which outlives
            // the loop and is not moved.
            unsafe {
                assert_eq!(q.normalized_value_to_string(norm, true), *name);
                assert_eq!(q.string_to_normalized_value(name), Some(norm), "{name}");
            }
        }
    }
    assert_eq!(choices, 2, "scene and switching");
    // what the host shows for the scene: the preset titles
    let q = ptr(&p, ids::SCENE);
    let last = (presets::PRESETS.len() - 1) as f32;
    for (i, (_, title)) in presets::SHIPPED.iter().enumerate() {
        // SAFETY: `q` points at the scene parameter of `p`, which
        // outlives the loop and is not moved.
        unsafe {
            assert_eq!(q.normalized_value_to_string(i as f32 / last, false), *title);
        }
    }
}

#[test]
fn switching_ids_are_the_scene_file_spellings() {
    for (i, id) in SwitchingMethods::IDS.iter().enumerate() {
        assert_eq!(SWITCHING_METHOD[i].as_str(), *id);
    }
    assert_eq!(SwitchingMethods::IDS.len(), SwitchingMethods::NAMES.len());
}

/// A project saved before the parameters came from one list stores the
/// scene as nice-plug's `{"string": "<preset id>"}` (the derived enum had
/// `#[id]`s, the file stems). It must load as the same preset, at the
/// same index, shown under the same name; an unknown id loads the
/// default (with a note for the log).
#[test]
fn saved_scenes_load_as_the_same_preset() {
    for (index, (id, title)) in presets::SHIPPED.iter().enumerate() {
        let mut state = full_state();
        state
            .params
            .insert(ids::SCENE.into(), ParamValue::String(id.to_string()));
        assert!(migrate_state(&mut state).is_empty(), "{id} kept");
        let p = ModalContactParams::default();
        let ParamPtr::EnumParam(e) = ptr(&p, ids::SCENE) else {
            panic!("scene is an enum parameter");
        };
        // what nice-plug's state loading does with a stored string
        let ParamValue::String(stored) = &state.params[ids::SCENE] else {
            panic!("stored as a string");
        };
        // SAFETY: `e` points at the scene parameter of `p`, alive and
        // not moved until the end of this iteration.
        assert!(unsafe { (*e).set_from_id(stored) }, "{id}");
        assert_eq!(p.scene_params().preset, index, "{id}");
        assert_eq!(presets::PRESETS[index].name, *id);
        assert_eq!(p.scene.to_string(), *title);
        // and saving it again stores the same string
        // SAFETY: as above, `e` points into `p`, still alive.
        assert_eq!(unsafe { (*e).unmodulated_plain_id() }, Some(*id));
    }
    let mut state = full_state();
    state.params.insert(
        ids::SCENE.into(),
        ParamValue::String("no-such-preset".into()),
    );
    let notes = migrate_state(&mut state);
    assert_eq!(notes.len(), 1);
    assert!(notes[0].starts_with("scene: invalid value"), "{notes:?}");
    same!(
        state.params[ids::SCENE],
        ParamValue::String("marimba-bar".into())
    );
}

#[test]
fn an_empty_older_state_gets_every_default() {
    let state = full_state();
    let d = ModalContactParams::default();
    same!(
        state.params[ids::HARDNESS],
        ParamValue::F32(d.hardness.default_plain_value())
    );
    same!(
        state.params[ids::SCENE],
        ParamValue::String("marimba-bar".into())
    );
    same!(
        state.params[ids::SWITCHING],
        ParamValue::String("exact".into())
    );
    same!(state.params[ids::PITCH_TRACKING], ParamValue::Bool(true));
    for s in PARAMS {
        same!(state.params[s.id], s.default_value());
    }
    // a filled-in state is left as it is
    let mut again = state.clone();
    assert!(migrate_state(&mut again).is_empty());
    same!(again.params, state.params);
}

#[test]
fn bad_values_are_replaced_and_good_ones_kept() {
    let mut state = full_state();
    let p = &mut state.params;
    p.insert(ids::HARDNESS.into(), ParamValue::F32(f32::NAN));
    p.insert(ids::DECAY.into(), ParamValue::F32(1e30));
    p.insert(ids::GAIN.into(), ParamValue::F32(-3.0));
    p.insert(ids::DAMPER.into(), ParamValue::Bool(true));
    p.insert(
        ids::SCENE.into(),
        ParamValue::String("no-such-preset".into()),
    );
    p.insert(ids::SWITCHING.into(), ParamValue::I32(0));
    p.insert(ids::STRIKE_CUSTOM.into(), ParamValue::F32(1.0));
    p.insert("from_the_future".into(), ParamValue::F32(3.0));
    let notes = migrate_state(&mut state);
    println!("{notes:#?}");
    assert_eq!(notes.len(), 5, "{notes:?}");
    let d = ModalContactParams::default();
    let p = &state.params;
    same!(
        p[ids::HARDNESS],
        ParamValue::F32(d.hardness.default_plain_value())
    );
    same!(p[ids::DECAY], ParamValue::F32(1.0));
    same!(p[ids::GAIN], ParamValue::F32(-3.0), "in range: kept");
    same!(p[ids::SWITCHING], ParamValue::I32(0), "a valid index: kept");
    same!(p[ids::SCENE], ParamValue::String("marimba-bar".into()));
    same!(p[ids::STRIKE_CUSTOM], ParamValue::Bool(false));
    same!(p["from_the_future"], ParamValue::F32(3.0));
    // an index past the last choice is refused
    let mut state = full_state();
    state
        .params
        .insert(ids::SCENE.into(), ParamValue::I32(presets::COUNT as i32));
    assert_eq!(migrate_state(&mut state).len(), 1);
}

#[test]
fn defaults_are_the_instrument_defaults() {
    let p = ModalContactParams::default();
    let d = InstrumentParams::default();
    let got = p.instrument_params();
    assert_eq!(got.scene.preset, d.scene.preset);
    assert_eq!(got.scene.strike_pos_norm, d.scene.strike_pos_norm);
    assert_eq!(got.scene.switching, d.scene.switching);
    assert_eq!(got.scene.damper_custom, d.scene.damper_custom);
    assert_eq!(got.play.pitch_tracking, d.play.pitch_tracking);
    // the list's f32 literals, read back as f64
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.abs().max(1.0);
    for (what, a, b) in [
        (
            "hammer mass",
            got.scene.hammer_mass_factor,
            d.scene.hammer_mass_factor,
        ),
        (
            "hardness",
            got.scene.stiffness_factor,
            d.scene.stiffness_factor,
        ),
        (
            "contact damping",
            got.scene.damping_factor,
            d.scene.damping_factor,
        ),
        ("decay", got.scene.decay_scale, d.scene.decay_scale),
        ("damper", got.scene.damper_norm, d.scene.damper_norm),
        (
            "gravity",
            got.scene.gravity_m_per_s2,
            d.scene.gravity_m_per_s2,
        ),
        ("drop height", got.play.drop_height_m, d.play.drop_height_m),
        ("gain", got.play.gain_db, d.play.gain_db),
    ] {
        assert!(close(a, b), "{what}: {a} vs the instrument's {b}");
    }
}

/// Each entry's `applies` says what the instrument does with it: moving a
/// `Recompile` parameter changes the compile request and nothing else,
/// moving any other one changes only what is read without a compile.
#[test]
fn applies_matches_the_instrument() {
    let base = || {
        let p = ModalContactParams::default();
        // with a custom strike position and damper, so that Strike
        // position and Damper count
        // SAFETY: both pointers point at parameters of `p`, alive and
        // not moved while they are used.
        unsafe {
            ptr(&p, ids::STRIKE_CUSTOM)._internal_set_normalized_value(1.0);
            ptr(&p, ids::DAMPER_CUSTOM)._internal_set_normalized_value(1.0);
        }
        p
    };
    let b = base();
    for s in PARAMS {
        let p = base();
        let q = ptr(&p, s.id);
        // SAFETY: `q` points at a parameter of `p`, which lives to the
        // end of the loop body and is not moved meanwhile.
        unsafe {
            let now = q.unmodulated_normalized_value();
            q._internal_set_normalized_value(if now < 0.5 { 1.0 } else { 0.0 });
        }
        let scene_moved = p.scene_params() != b.scene_params();
        let play_moved = p.play_params() != b.play_params();
        assert_eq!(
            (scene_moved, play_moved),
            (
                s.applies == Applies::Recompile,
                s.applies != Applies::Recompile
            ),
            "{}: {:?}",
            s.id,
            s.applies
        );
    }
}

/// Custom damper off (a new instance): the knob is not used and moving
/// it asks for no compile; on: the knob is the damper.
#[test]
fn the_damper_knob_counts_only_with_custom_damper() {
    let p = ModalContactParams::default();
    assert!(!p.damper_custom.value(), "a new instance plays the scene's");
    let before = p.scene_params();
    assert!(!before.damper_custom);
    // SAFETY: the pointer points at a parameter of `p`, which outlives
    // this statement.
    unsafe { ptr(&p, ids::DAMPER)._internal_set_normalized_value(0.9) };
    assert_eq!(
        p.scene_params(),
        before,
        "the knob moved, nothing to compile"
    );
    // SAFETY: as above, a parameter of the living `p`.
    unsafe { ptr(&p, ids::DAMPER_CUSTOM)._internal_set_normalized_value(1.0) };
    let on = p.scene_params();
    assert!(on.damper_custom);
    assert!((on.damper_norm - 0.9).abs() < 1e-6, "{}", on.damper_norm);
}

/// A state saved before Custom damper existed stores Damper and not
/// Custom damper: it loads with Custom damper on, so its Damper keeps
/// applying (the project sounds as it did). A state that stores both
/// keeps both; an empty one gets the defaults (off).
#[test]
fn states_saved_before_custom_damper_keep_their_damper() {
    let mut old = full_state();
    old.params.remove(ids::DAMPER_CUSTOM);
    old.params.insert(ids::DAMPER.into(), ParamValue::F32(0.25));
    let notes = migrate_state(&mut old);
    println!("{notes:?}");
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].starts_with("damper_custom: missing"), "{notes:?}");
    same!(old.params[ids::DAMPER_CUSTOM], ParamValue::Bool(true));
    same!(old.params[ids::DAMPER], ParamValue::F32(0.25));
    // what the plugin then plays: the saved damper
    let p = ModalContactParams::default();
    // SAFETY: both pointers point at parameters of `p`, alive and not
    // moved while they are used.
    unsafe {
        ptr(&p, ids::DAMPER)._internal_set_normalized_value(0.25);
        ptr(&p, ids::DAMPER_CUSTOM)._internal_set_normalized_value(1.0);
    }
    let sp = p.scene_params();
    assert!(sp.damper_custom && (sp.damper_norm - 0.25).abs() < 1e-6);
    // even with its Damper refused (then the default, 0.5, as then)
    let mut bad = full_state();
    bad.params.remove(ids::DAMPER_CUSTOM);
    bad.params
        .insert(ids::DAMPER.into(), ParamValue::F32(f32::NAN));
    assert_eq!(migrate_state(&mut bad).len(), 2);
    same!(bad.params[ids::DAMPER_CUSTOM], ParamValue::Bool(true));
    same!(bad.params[ids::DAMPER], ParamValue::F32(0.5));
    // saved with this version: kept as saved, either way
    for custom in [false, true] {
        let mut new = full_state();
        new.params
            .insert(ids::DAMPER_CUSTOM.into(), ParamValue::Bool(custom));
        assert!(migrate_state(&mut new).is_empty());
        same!(new.params[ids::DAMPER_CUSTOM], ParamValue::Bool(custom));
    }
    // nothing stored: the defaults
    let empty = full_state();
    same!(empty.params[ids::DAMPER_CUSTOM], ParamValue::Bool(false));
}

#[test]
fn spec_finds_every_entry() {
    for s in PARAMS {
        assert_eq!(spec(s.id), Some(s));
    }
    assert_eq!(spec("no_such_parameter"), None);
}

/// The user scene, the editor's size and the scene folder round-trip
/// through a saved state's fields; a project without them (older, or
/// saved with a preset) gets the defaults; unreadable values are
/// reported and replaced by defaults.
#[test]
fn persisted_fields_round_trip_and_bad_ones_get_defaults() {
    let a = Persisted::default();
    a.library.load(UserScene {
        name: "mine".into(),
        text: "version = 1".into(),
        path: Some(PathBuf::from("/somewhere/mine.toml")),
    });
    a.editor_size.store((1200, 800));
    *a.scene_folder.lock().unwrap() = Some(PathBuf::from("/my/scenes"));
    let saved = a.serialize();
    println!("{saved:?}");
    let b = Persisted::default();
    assert!(b.deserialize(&saved).is_empty());
    assert_eq!(b.serialize(), saved);
    assert_eq!(b.library.requested().unwrap().name, "mine");
    assert_ne!(b.library.active(), 0);
    assert_eq!(b.editor_size.load(), (1200, 800));

    // an older project: no fields at all
    let notes = b.deserialize(&BTreeMap::new());
    assert!(notes.is_empty());
    assert_eq!(b.library.active(), 0, "the preset plays");
    assert_eq!(b.editor_size.load(), EDITOR_SIZE);
    assert!(b.scene_folder.lock().unwrap().is_none());

    // garbage
    let mut bad = saved.clone();
    bad.insert(keys::USER_SCENE.into(), "{not json".into());
    bad.insert(keys::EDITOR_SIZE.into(), "[5, 99999]".into());
    let notes = b.deserialize(&bad);
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert_eq!(b.library.active(), 0);
    assert_eq!(b.editor_size.load(), EDITOR_SIZE);
}
