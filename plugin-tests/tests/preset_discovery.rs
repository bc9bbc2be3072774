//! CLAP preset discovery and preset-load on the BUILT bundle, driven the way
//! a host's preset browser drives them (clack-host's provider, indexer and
//! metadata receiver; the plugin's `clap.preset-load` extension):
//! the provider lists every built-in scene and the scene files of the user
//! folder, a listed preset loads and then sounds exactly like the scene it
//! names (compared with the instrument library's own render of that scene),
//! and a bad key or a file that does not validate is refused, reported to
//! the host with the reason, and changes nothing.
//!
//! One test function: the user folder comes from `XDG_DATA_HOME`, set before
//! the plugin reads it and never while another thread could.

use clack_extensions::preset_discovery::prelude::*;
use clack_host::prelude::HostError;
use clack_host::prelude::PluginEntry;
use modal_contact::instrument::InstrumentParams;
use modal_contact::plugin::clap_entry::{BUILT_IN_LOCATION, PROVIDER_ID, USER_LOCATION};
use modal_contact::plugin::params::{ids, keys};
use modal_contact::presets::{self, PRESETS};
use modal_contact::scene::Scene;
use plugin_tests::*;
use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};

#[derive(Default)]
struct Indexer {
    file_types: Vec<String>,
    /// (name, flags, path of a file location)
    locations: Vec<(String, Flags, Option<PathBuf>)>,
}

impl IndexerImpl for Indexer {
    fn declare_filetype(&mut self, file_type: FileType) -> Result<(), HostError> {
        self.file_types.push(
            file_type
                .file_extension
                .map(|e| e.to_string_lossy().into_owned())
                .unwrap_or_default(),
        );
        Ok(())
    }

    fn declare_location(&mut self, location: LocationInfo) -> Result<(), HostError> {
        let path = match location.location {
            Location::Plugin => None,
            Location::File { path } => Some(PathBuf::from(path.to_string_lossy().into_owned())),
        };
        self.locations.push((
            location.name.to_string_lossy().into_owned(),
            location.flags,
            path,
        ));
        Ok(())
    }

    fn declare_soundpack(&mut self, _soundpack: Soundpack) -> Result<(), HostError> {
        Ok(())
    }
}

#[derive(Debug, Default, Clone, PartialEq)]
struct Found {
    name: String,
    key: Option<String>,
    plugin_ids: Vec<(String, String)>,
    flags: Option<Flags>,
    description: String,
}

#[derive(Default)]
struct Receiver {
    presets: Vec<Found>,
    errors: Vec<String>,
}

fn text(s: &CStr) -> String {
    s.to_string_lossy().into_owned()
}

impl MetadataReceiverImpl for Receiver {
    fn on_error(&mut self, _error_code: i32, error_message: Option<&CStr>) {
        self.errors
            .push(error_message.map(text).unwrap_or_default());
    }

    fn begin_preset(
        &mut self,
        name: Option<&CStr>,
        load_key: Option<&CStr>,
    ) -> Result<(), HostError> {
        self.presets.push(Found {
            name: name.map(text).unwrap_or_default(),
            key: load_key.map(text),
            ..Found::default()
        });
        Ok(())
    }

    fn add_plugin_id(&mut self, plugin_id: UniversalPluginId) {
        if let Some(p) = self.presets.last_mut() {
            p.plugin_ids.push((text(plugin_id.abi), text(plugin_id.id)));
        }
    }

    fn set_soundpack_id(&mut self, _soundpack_id: &CStr) {}

    fn set_flags(&mut self, flags: Flags) {
        if let Some(p) = self.presets.last_mut() {
            p.flags = Some(flags);
        }
    }

    fn add_creator(&mut self, _creator: &CStr) {}

    fn set_description(&mut self, description: &CStr) {
        if let Some(p) = self.presets.last_mut() {
            p.description = text(description);
        }
    }

    fn set_timestamps(
        &mut self,
        _creation_time: Option<Timestamp>,
        _modification_time: Option<Timestamp>,
    ) {
    }

    fn add_feature(&mut self, _feature: &CStr) {}

    fn add_extra_info(&mut self, _key: &CStr, _value: &CStr) {}
}

fn metadata(provider: &mut Provider<Indexer>, location: Location) -> Receiver {
    let mut r = Receiver::default();
    provider.get_metadata(location, &mut r);
    r
}

fn c_path(p: &std::path::Path) -> CString {
    CString::new(p.to_string_lossy().into_owned()).unwrap()
}

const EVENTS: fn() -> Vec<HostEvent> = || vec![on(100, 60, 0.8), on(9000, 67, 0.5)];
const RATE: f64 = 48_000.0;
const TOTAL: usize = 24_000;

fn strike(p: &mut LoadedPlugin) -> [Vec<f32>; 2] {
    p.render(&RenderSpec::new(RATE, 256, TOTAL, EVENTS()))
}

/// The library's render of built-in scene `name` at default parameters.
fn library_strike(name: &str) -> [Vec<f32>; 2] {
    let mut ip = InstrumentParams::default();
    ip.scene.preset = presets::index_of(name).unwrap();
    library_render(&ip, RATE, TOTAL, &EVENTS())
}

fn saved_fields(p: &mut LoadedPlugin) -> serde_json::Value {
    let v: serde_json::Value = serde_json::from_str(&json_of(&p.save_state())).unwrap();
    v["fields"].clone()
}

#[test]
fn hosts_list_the_built_in_and_user_scenes_and_load_them() {
    // The user folder, with one good and one broken scene file, before the
    // plugin is loaded into this process.
    let data = out_dir().join("preset-discovery-data");
    let _ = std::fs::remove_dir_all(&data);
    let folder = data.join("modalcontact/scenes");
    std::fs::create_dir_all(&folder).unwrap();
    std::env::set_var("XDG_DATA_HOME", &data);
    let bell = PRESETS.iter().find(|p| p.name == "bell").unwrap();
    let good = folder.join("my-bell.toml");
    std::fs::write(&good, bell.toml).unwrap();
    let broken = folder.join("broken.toml");
    std::fs::write(&broken, bell.toml.replacen("t60_s = ", "t60_s = -", 1)).unwrap();

    let bundle = clap_bundle(Variant::Release);
    let entry = load_entry(&bundle);
    discovery_lists_the_scenes(&entry, &folder, &good, &broken);

    // --- loading
    let mut p = LoadedPlugin::load(&bundle);
    let default_sound = strike(&mut p);
    let bell_lib = library_strike("bell");
    assert!(
        max_abs_diff(&default_sound[0], &bell_lib[0]) > 0.01,
        "bell is not the default"
    );

    built_in_and_user_scenes_load(&mut p, &good, &bell_lib, &default_sound);
    refused_presets_change_nothing(&mut p, &folder, &broken, &default_sound);
}

/// The preset-discovery factory of `entry` lists one provider, the plugin
/// vendor's, with the built-in scenes and the user folder `folder`: every
/// built-in scene, the good user file `good` and the broken one `broken`
/// with an error naming it and its field.
fn discovery_lists_the_scenes(entry: &PluginEntry, folder: &Path, good: &Path, broken: &Path) {
    // --- discovery
    let factory: PresetDiscoveryFactory = entry.get_factory().expect("preset-discovery factory");
    assert_eq!(factory.provider_count(), 1);
    let desc = factory.get_provider_descriptor(0).expect("descriptor");
    assert_eq!(desc.id(), Some(PROVIDER_ID));
    println!(
        "provider {:?} {:?} by {:?}",
        desc.id(),
        desc.name(),
        desc.vendor()
    );
    let vendor = <modal_contact::plugin::ModalContact as nice_plug::prelude::Plugin>::VENDOR;
    assert_eq!(
        desc.vendor().map(text).as_deref(),
        Some(vendor),
        "the plugin's vendor"
    );
    let mut provider = Provider::instantiate(Indexer::default(), entry, PROVIDER_ID, &host_info())
        .expect("provider");
    let idx = provider.indexer();
    println!(
        "locations {:?}, file types {:?}",
        idx.locations, idx.file_types
    );
    assert_eq!(
        idx.locations,
        vec![
            (text(BUILT_IN_LOCATION), Flags::IS_FACTORY_CONTENT, None),
            (
                text(USER_LOCATION),
                Flags::IS_USER_CONTENT,
                Some(folder.to_path_buf())
            ),
        ]
    );
    assert_eq!(idx.file_types, vec!["toml".to_string()]);

    let built_in = metadata(&mut provider, Location::Plugin);
    assert!(built_in.errors.is_empty(), "{:?}", built_in.errors);
    let expected: Vec<Found> = PRESETS
        .iter()
        .map(|p| Found {
            name: p.title.into(),
            key: Some(p.name.into()),
            plugin_ids: vec![("clap".into(), PLUGIN_ID.into())],
            flags: Some(Flags::IS_FACTORY_CONTENT),
            description: Scene::from_toml_str(p.toml).unwrap().description,
        })
        .collect();
    assert_eq!(built_in.presets, expected);
    assert!(expected.iter().all(|p| !p.description.is_empty()));

    let mine = metadata(
        &mut provider,
        Location::File {
            path: &c_path(good),
        },
    );
    assert!(mine.errors.is_empty(), "{:?}", mine.errors);
    assert_eq!(mine.presets.len(), 1);
    assert_eq!(mine.presets[0].name, "my-bell");
    assert_eq!(mine.presets[0].key, None);
    assert_eq!(mine.presets[0].flags, Some(Flags::IS_USER_CONTENT));
    assert_eq!(mine.presets[0].plugin_ids, expected[0].plugin_ids);

    let bad = metadata(
        &mut provider,
        Location::File {
            path: &c_path(broken),
        },
    );
    println!("broken file: {:?}", bad.errors);
    assert!(bad.presets.is_empty());
    assert_eq!(bad.errors.len(), 1);
    assert!(
        bad.errors[0].contains("broken.toml") && bad.errors[0].contains("t60"),
        "the file and the field: {:?}",
        bad.errors
    );
    drop(provider);
}

/// The built-in bell, then the user file `good` (the bell's text), load and
/// play as the library's bell `bell_lib`; a built-in scene then replaces
/// the user scene (the marimba bar, `default_sound` bit for bit).
fn built_in_and_user_scenes_load(
    p: &mut LoadedPlugin,
    good: &Path,
    bell_lib: &[Vec<f32>; 2],
    default_sound: &[Vec<f32>; 2],
) {
    let scene_id = param_id(ids::SCENE);
    let (ok, events) = p.load_preset(Location::Plugin, Some(c"bell"));
    assert!(ok);
    assert_eq!(events, vec!["loaded bell".to_string()]);
    assert_eq!(
        p.param_value(scene_id),
        presets::index_of("bell").unwrap() as f64
    );
    let heard = strike(p);
    let d = max_abs_diff(&heard[0], &bell_lib[0]).max(max_abs_diff(&heard[1], &bell_lib[1]));
    println!("built-in bell after preset-load vs the library's bell: max diff {d:.3e}");
    assert!(d < 1e-6, "{d}");

    let (ok, events) = p.load_preset(
        Location::File {
            path: &c_path(good),
        },
        None,
    );
    assert!(ok);
    assert_eq!(events, vec![format!("loaded {}", good.display())]);
    let user: serde_json::Value =
        serde_json::from_str(saved_fields(p)[keys::USER_SCENE].as_str().unwrap()).unwrap();
    assert_eq!(user["name"], "my-bell");
    let heard_file = strike(p);
    let d =
        max_abs_diff(&heard_file[0], &bell_lib[0]).max(max_abs_diff(&heard_file[1], &bell_lib[1]));
    println!(
        "my-bell.toml (the bell's text) after preset-load vs the library's bell: max diff {d:.3e}"
    );
    assert!(d < 1e-6, "{d}");

    // a built-in scene replaces the user scene
    let (ok, _) = p.load_preset(Location::Plugin, Some(c"marimba-bar"));
    assert!(ok);
    assert!(saved_fields(p).get(keys::USER_SCENE).is_none());
    assert_eq!(
        strike(p),
        *default_sound,
        "the marimba bar again, bit for bit"
    );
}

/// Refused loads (an unknown built-in key, the broken file `broken`, a
/// missing file in `folder`) change nothing and tell the host why.
fn refused_presets_change_nothing(
    p: &mut LoadedPlugin,
    folder: &Path,
    broken: &Path,
    default_sound: &[Vec<f32>; 2],
) {
    // refused: nothing changes, the host hears why
    let before = p.save_state();
    let (ok, events) = p.load_preset(Location::Plugin, Some(c"no-such-scene"));
    assert!(!ok);
    println!("bad key: {events:?}");
    assert_eq!(events.len(), 1);
    assert!(
        events[0].starts_with("error no-such-scene:") && events[0].contains("no built-in scene")
    );
    let (ok, events) = p.load_preset(
        Location::File {
            path: &c_path(broken),
        },
        None,
    );
    assert!(!ok);
    println!("broken file: {events:?}");
    assert!(events.len() == 1 && events[0].contains("t60"), "{events:?}");
    let missing = folder.join("missing.toml");
    let (ok, events) = p.load_preset(
        Location::File {
            path: &c_path(&missing),
        },
        None,
    );
    assert!(
        !ok && events.len() == 1 && events[0].contains("cannot read"),
        "{events:?}"
    );
    assert_eq!(p.save_state(), before, "a refused preset changes nothing");
    assert_eq!(strike(p), *default_sound);
}
