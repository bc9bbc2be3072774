//! Saved state against the BUILT (release) plugin: exact round trip, a state
//! from an older version (parameters missing) loads with defaults for what
//! it lacks, invalid values are replaced by defaults, and truncated, empty,
//! random and huge states are refused (the host is told) with the instance's
//! parameters left as they were, and the instance still plays.
//!
//! A CLAP state of this plugin is nice-plug's: an 8-byte little-endian
//! length, then JSON `{"version": .., "params": {id: value}, "fields": {}}`.

use modal_contact::plugin::params::ids;
use modal_contact::presets;
use modal_testkit::rng::TestRng;
use plugin_tests::*;

fn values(p: &mut LoadedPlugin) -> Vec<f64> {
    ids::ALL
        .iter()
        .map(|id| p.param_value(param_id(id)))
        .collect()
}

/// Set non-default values through process (as automation).
fn set_non_defaults(p: &mut LoadedPlugin) {
    let set = [
        (ids::SCENE, presets::index_of("wood-block").unwrap() as f64),
        (ids::HARDNESS, 0.2),
        (ids::GAIN, 0.3),
        (ids::SWITCHING, 0.0),
        (ids::DECAY, 0.7),
    ];
    let events = set
        .iter()
        .enumerate()
        .map(|(i, (id, v))| HostEvent::Param {
            at: i,
            id: param_id(id),
            value: *v,
        })
        .collect();
    p.render(&RenderSpec::new(48_000.0, 64, 64, events));
}

fn plays(p: &mut LoadedPlugin) -> f64 {
    let out = p.render(&RenderSpec::new(
        44_100.0,
        512,
        22_050,
        vec![HostEvent::NoteOn {
            at: 10,
            key: 60,
            velocity: 0.8,
        }],
    ));
    assert!(out.iter().flatten().all(|v| v.is_finite()));
    rms(&out[0])
}

#[test]
fn round_trip_is_exact_and_older_states_get_defaults() {
    let bundle = clap_bundle(Variant::Release);
    let defaults = values(&mut LoadedPlugin::load(&bundle));
    let mut a = LoadedPlugin::load(&bundle);
    set_non_defaults(&mut a);
    let saved = a.save_state();
    let before = values(&mut a);
    let mut b = LoadedPlugin::load(&bundle);
    b.load_state(&saved);
    assert_eq!(values(&mut b), before, "round trip");
    // saving the restored instance gives the same bytes
    assert_eq!(b.save_state(), saved);

    // An "older version": no switching, gain or decay entries (added later),
    // loaded into an instance whose values for them are not the defaults.
    let json = json_of(&saved);
    println!("saved state: {json}");
    let mut v: serde_like::Obj = serde_like::parse(&json);
    for id in [ids::SWITCHING, ids::GAIN, ids::DECAY] {
        v.remove_param(id);
    }
    v.set_version("0.0.1");
    let older = state_of(&v.to_json());
    println!("older state: {}", v.to_json());
    let mut c = LoadedPlugin::load(&bundle);
    set_non_defaults(&mut c);
    assert!(c.try_load_state(&older), "an older state must load");
    let got = values(&mut c);
    for (i, id) in ids::ALL.iter().enumerate() {
        let want = if [ids::SWITCHING, ids::GAIN, ids::DECAY].contains(id) {
            defaults[i]
        } else {
            before[i]
        };
        assert!(
            (got[i] - want).abs() < 1e-6,
            "{id}: {} (want {want})",
            got[i]
        );
    }
    // invalid values in a well-formed state: replaced by defaults
    let bad = json
        .replace(
            &format!("\"{}\":", ids::SCENE),
            &format!(
                "\"{}\":{{\"string\":\"no-such-preset\"}},\"x_{}\":",
                ids::SCENE,
                ids::SCENE
            ),
        )
        .replacen(
            "\"hardness\":",
            "\"hardness\":{\"f32\":1e30},\"x_hardness\":",
            1,
        );
    println!("state with invalid values: {bad}");
    let mut d = LoadedPlugin::load(&bundle);
    assert!(d.try_load_state(&state_of(&bad)), "{bad}");
    let got = values(&mut d);
    let idx = |id: &str| ids::ALL.iter().position(|x| *x == id).unwrap();
    assert_eq!(got[idx(ids::SCENE)], defaults[idx(ids::SCENE)]);
    assert_eq!(got[idx(ids::HARDNESS)], defaults[idx(ids::HARDNESS)]);
    assert_eq!(got[idx(ids::GAIN)], before[idx(ids::GAIN)]);
    assert!(plays(&mut d) > 1e-6);
}

#[test]
fn broken_states_are_refused_and_change_nothing() {
    let bundle = clap_bundle(Variant::Release);
    let mut a = LoadedPlugin::load(&bundle);
    set_non_defaults(&mut a);
    let saved = a.save_state();
    let mut rng = TestRng(0x9e37_79b9_7f4a_7c15);
    let mut random = |n: usize| -> Vec<u8> { (0..n).map(|_| rng.next_u64() as u8).collect() };
    let json = json_of(&saved);
    let mut cases: Vec<(String, Vec<u8>)> = vec![
        ("empty".into(), Vec::new()),
        ("length only".into(), saved[..8].to_vec()),
        ("truncated header".into(), saved[..5].to_vec()),
        ("truncated JSON".into(), saved[..saved.len() / 2].to_vec()),
        (
            "truncated JSON, length fixed".into(),
            state_of(&json[..json.len() / 2]),
        ),
        ("random 1000 bytes".into(), random(1000)),
        ("random JSON-length prefix".into(), {
            let mut s = 900u64.to_le_bytes().to_vec();
            s.extend(random(900));
            s
        }),
        ("claims 1 TB".into(), {
            let mut s = (1u64 << 40).to_le_bytes().to_vec();
            s.extend_from_slice(&saved[8..]);
            s
        }),
        ("claims u64::MAX".into(), {
            let mut s = u64::MAX.to_le_bytes().to_vec();
            s.extend_from_slice(&saved[8..]);
            s
        }),
        ("huge: 64 MB of junk".into(), {
            let n = 64 << 20;
            let mut s = (n as u64).to_le_bytes().to_vec();
            s.resize(8 + n, b'[');
            s
        }),
        ("not an object".into(), state_of("[1, 2, 3]")),
        (
            "params of the wrong type".into(),
            state_of("{\"params\": 7, \"fields\": {}}"),
        ),
    ];
    for i in 0..40 {
        let n = 1 + (i * 37) % 300;
        cases.push((format!("random {n} bytes"), random(n)));
    }
    let mut b = LoadedPlugin::load(&bundle);
    set_non_defaults(&mut b);
    let before = values(&mut b);
    for (what, bytes) in &cases {
        let t = std::time::Instant::now();
        let ok = b.try_load_state(bytes);
        println!(
            "{what:>32}: {} bytes -> {} in {:.1} ms",
            bytes.len(),
            if ok { "LOADED" } else { "refused" },
            t.elapsed().as_secs_f64() * 1e3
        );
        assert!(!ok, "{what}: a broken state was accepted");
        assert_eq!(values(&mut b), before, "{what}: parameters changed");
    }
    assert!(plays(&mut b) > 1e-6, "the instance no longer plays");
}

/// Minimal JSON surgery on nice-plug's state object (no JSON dependency in
/// the tests: the state's layout is flat and known).
mod serde_like {
    pub(super) struct Obj(String);

    pub(super) fn parse(json: &str) -> Obj {
        assert!(
            json.starts_with('{') && json.contains("\"params\":{"),
            "{json}"
        );
        Obj(json.to_string())
    }

    impl Obj {
        /// Remove `"id":value,` (or `,"id":value`) from the params object.
        pub(super) fn remove_param(&mut self, id: &str) {
            let key = format!("\"{id}\":");
            let start = self
                .0
                .find(&key)
                .unwrap_or_else(|| panic!("{id} in {}", self.0));
            let rest = &self.0[start + key.len()..];
            // values are flat objects like {"f32":1.0}
            let end_rel = rest.find('}').expect("end of value") + 1;
            let mut end = start + key.len() + end_rel;
            let mut begin = start;
            if self.0.as_bytes()[end] == b',' {
                end += 1;
            } else if self.0.as_bytes()[start - 1] == b',' {
                begin -= 1;
            }
            self.0.replace_range(begin..end, "");
        }

        pub(super) fn set_version(&mut self, v: &str) {
            let key = "\"version\":\"";
            if let Some(s) = self.0.find(key) {
                let e = self.0[s + key.len()..].find('"').unwrap() + s + key.len();
                self.0.replace_range(s + key.len()..e, v);
            }
        }

        pub(super) fn to_json(&self) -> String {
            self.0.clone()
        }
    }
}

/// A scene of the user's own (not a preset): the one docs/plugin.md's
/// "Write your first scene" shows (the guide's text is checked against the
/// file below, so the guide's example is one that loads and plays).
const USER_SCENE: &str = include_str!("../../docs/first-scene.toml");

fn strike(p: &mut LoadedPlugin) -> [Vec<f32>; 2] {
    p.render(&RenderSpec::new(
        48_000.0,
        256,
        24_000,
        vec![on(100, 60, 0.8), on(9000, 67, 0.5)],
    ))
}

/// The user's scene is stored in the project: a fresh instance on a
/// machine without the file plays it bit for bit, equal to the library's
/// render of the same scene; a saved scene that no longer validates plays
/// the preset and keeps its text.
#[test]
fn a_user_scene_travels_in_the_project_and_plays_without_its_file() {
    let guide = std::fs::read_to_string(workspace_root().join("docs/plugin.md")).unwrap();
    assert!(
        guide.contains(USER_SCENE),
        "docs/plugin.md shows docs/first-scene.toml as it is"
    );
    let bundle = clap_bundle(Variant::Release);
    let dir = out_dir().join("user-scene-state");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("my-bar.toml");
    std::fs::write(&file, USER_SCENE).unwrap();

    let mut a = LoadedPlugin::load(&bundle);
    let fresh = a.save_state();
    let preset = strike(&mut LoadedPlugin::load(&bundle));
    a.load_state(&with_user_scene(&fresh, "my-bar", USER_SCENE, &file));
    let heard_a = strike(&mut a);
    let saved = a.save_state();
    println!(
        "saved fields: {}",
        serde_json::from_str::<serde_json::Value>(&json_of(&saved)).unwrap()["fields"]
    );
    std::fs::remove_file(&file).unwrap();

    let mut b = LoadedPlugin::load(&bundle);
    b.load_state(&saved);
    let heard_b = strike(&mut b);
    assert_eq!(
        heard_a, heard_b,
        "the same sound without the file, bit for bit"
    );
    assert!(
        max_abs_diff(&heard_a[0], &preset[0]) > 0.01,
        "the user scene, not the preset"
    );
    assert_eq!(b.save_state(), saved, "saved back unchanged");

    // the library's render of the scene at the default parameters
    let scene = modal_contact::scene::Scene::from_toml_str(USER_SCENE).unwrap();
    let ip = modal_contact::instrument::InstrumentParams::default();
    let prepared =
        modal_contact::instrument::prepare_scene(&scene, &ip.scene, 48_000.0, 0).unwrap();
    let lib = library_render_prepared(
        prepared,
        &ip,
        24_000,
        &[on(100, 60, 0.8), on(9000, 67, 0.5)],
    );
    let d = max_abs_diff(&lib[0], &heard_b[0]).max(max_abs_diff(&lib[1], &heard_b[1]));
    println!(
        "plugin vs library: max |diff| {d:.2e}, peak {:.3}",
        peak(&lib[0])
    );
    assert!(d < 1e-6, "{d}");

    // a saved scene that no longer validates: the preset plays, the text stays
    let broken = USER_SCENE.replace("t60_s = 0.5", "t60_s = -0.5");
    let mut c = LoadedPlugin::load(&bundle);
    c.load_state(&with_user_scene(&fresh, "my-bar", &broken, &file));
    assert_eq!(strike(&mut c), preset, "the preset plays");
    let kept: serde_json::Value = serde_json::from_str(&json_of(&c.save_state())).unwrap();
    let kept_scene: serde_json::Value =
        serde_json::from_str(kept["fields"]["user_scene"].as_str().unwrap()).unwrap();
    assert_eq!(kept_scene["text"], broken, "the user's text is not lost");
}
