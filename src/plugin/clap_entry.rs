//! The CLAP entry point: nice-plug's plugin factory plus a preset-discovery
//! factory and the `preset-load` extension, so CLAP hosts can list the
//! built-in scenes and the user's scene files in their own browser and load
//! one (docs/plugin.md, "Preset browsing in hosts").
//!
//! nice-plug's `nice_export_clap!` offers only the plugin factory, so this
//! module writes the entry itself, with nice-plug's own pieces: the plugin
//! factory creates nice-plug's [`Wrapper`] exactly as the macro does, and
//! hands the host a copy of the wrapper's `clap_plugin` whose
//! `get_extension` also answers `clap.preset-load` (every other call goes to
//! the wrapper unchanged: the copy keeps its `plugin_data`, which is how the
//! wrapper finds itself).
//!
//! - **Provider** `dev.modal-contact.scenes`: one location of kind
//!   "plugin" holding every built-in scene (load key: the preset's id, e.g.
//!   `marimba-bar`; flag "factory content"), and, when it exists, the user
//!   scene folder (`browser::default_folder`) as a file location with the
//!   file type `.toml` (flag "user content"). A user file is parsed and
//!   validated when the host asks for its metadata: a file that does not
//!   validate is reported to the host with the field's path and the reason.
//! - **Loading** (`preset-load`, main thread): a built-in scene sets the
//!   Scene parameter and drops any user scene; a file becomes the user scene
//!   (saved in the project like one loaded in the editor). Both go through
//!   nice-plug's state restore, so the host is told that the parameters
//!   changed, and the load happens between two process calls if the plugin
//!   is running. A key that is not a preset, or a file that cannot be read
//!   or does not validate, returns false, tells the host why, and changes
//!   nothing.

use super::params::{ids, keys};
use super::user_scene::UserScene;
use super::{browser, ModalContact};
use crate::presets::PRESETS;
use crate::scene::Scene;
use clap_sys::entry::clap_plugin_entry;
use clap_sys::ext::preset_load::{
    clap_host_preset_load, clap_plugin_preset_load, CLAP_EXT_PRESET_LOAD,
    CLAP_EXT_PRESET_LOAD_COMPAT,
};
use clap_sys::factory::plugin_factory::{clap_plugin_factory, CLAP_PLUGIN_FACTORY_ID};
use clap_sys::factory::preset_discovery::*;
use clap_sys::host::clap_host;
use clap_sys::plugin::{clap_plugin, clap_plugin_descriptor};
use clap_sys::universal_plugin_id::clap_universal_plugin_id;
use clap_sys::version::CLAP_VERSION;
use nice_plug::plugin::ParamValue;
use nice_plug::prelude::ClapPlugin;
use nice_plug::wrapper::clap::{PluginDescriptor, Wrapper};
use std::ffi::{c_char, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// The preset provider's id (stable: hosts index presets by it).
pub const PROVIDER_ID: &CStr = c"dev.modal-contact.scenes";
/// What the provider's location of built-in scenes is called in hosts.
pub const BUILT_IN_LOCATION: &CStr = c"Modal Contact scenes";
/// What the user scene folder is called in hosts.
pub const USER_LOCATION: &CStr = c"My scenes";

/// The plugin's CLAP entry point.
#[unsafe(no_mangle)]
#[used]
pub static clap_entry: clap_plugin_entry = clap_plugin_entry {
    clap_version: CLAP_VERSION,
    init: Some(entry_init),
    deinit: Some(entry_deinit),
    get_factory: Some(entry_get_factory),
};

extern "C" fn entry_init(_plugin_path: *const c_char) -> bool {
    nice_plug::wrapper::setup_logger::<ModalContact>();
    true
}

extern "C" fn entry_deinit() {}

extern "C" fn entry_get_factory(factory_id: *const c_char) -> *const c_void {
    if factory_id.is_null() {
        return std::ptr::null();
    }
    // SAFETY: the host passes a NUL-terminated id.
    let id = unsafe { CStr::from_ptr(factory_id) };
    if id == CLAP_PLUGIN_FACTORY_ID {
        &PLUGIN_FACTORY as *const _ as *const c_void
    } else if id == CLAP_PRESET_DISCOVERY_FACTORY_ID
        || id == CLAP_PRESET_DISCOVERY_FACTORY_ID_COMPAT
    {
        &PRESET_FACTORY as *const _ as *const c_void
    } else {
        std::ptr::null()
    }
}

// ---------------------------------------------------------------------------
// Plugin factory (what `nice_export_clap!` writes, for one plugin type)

static PLUGIN_FACTORY: clap_plugin_factory = clap_plugin_factory {
    get_plugin_count: Some(get_plugin_count),
    get_plugin_descriptor: Some(get_plugin_descriptor),
    create_plugin: Some(create_plugin),
};

fn descriptor() -> &'static PluginDescriptor {
    static DESCRIPTOR: OnceLock<PluginDescriptor> = OnceLock::new();
    DESCRIPTOR.get_or_init(PluginDescriptor::for_plugin::<ModalContact>)
}

unsafe extern "C" fn get_plugin_count(_factory: *const clap_plugin_factory) -> u32 {
    1
}

unsafe extern "C" fn get_plugin_descriptor(
    _factory: *const clap_plugin_factory,
    index: u32,
) -> *const clap_plugin_descriptor {
    if index == 0 {
        descriptor().clap_plugin_descriptor()
    } else {
        std::ptr::null()
    }
}

/// What the host holds: nice-plug's `clap_plugin` with two entries replaced.
/// `repr(C)` with the `clap_plugin` first, so the host's pointer is this.
#[repr(C)]
struct PluginShim {
    plugin: clap_plugin,
    host: *const clap_host,
    inner_get_extension: unsafe extern "C" fn(*const clap_plugin, *const c_char) -> *const c_void,
    inner_destroy: unsafe extern "C" fn(*const clap_plugin),
}

unsafe extern "C" fn create_plugin(
    _factory: *const clap_plugin_factory,
    host: *const clap_host,
    plugin_id: *const c_char,
) -> *const clap_plugin {
    if plugin_id.is_null() || host.is_null() {
        return std::ptr::null();
    }
    // SAFETY: NUL-terminated per the CLAP contract.
    if unsafe { CStr::from_ptr(plugin_id) } != descriptor().clap_id() {
        return std::ptr::null();
    }
    // SAFETY: as in nice_export_clap!: the wrapper reads the host pointer.
    let wrapper = unsafe { Wrapper::<ModalContact>::new(host) };
    let inner = *wrapper.clap_plugin.borrow();
    // The wrapper's `destroy` turns `plugin_data` back into this Arc.
    let _ = Arc::into_raw(wrapper);
    let (Some(get_extension), Some(destroy)) = (inner.get_extension, inner.destroy) else {
        return std::ptr::null();
    };
    let shim = Box::new(PluginShim {
        plugin: clap_plugin {
            get_extension: Some(shim_get_extension),
            destroy: Some(shim_destroy),
            ..inner
        },
        host,
        inner_get_extension: get_extension,
        inner_destroy: destroy,
    });
    Box::into_raw(shim) as *const clap_plugin
}

unsafe extern "C" fn shim_get_extension(
    plugin: *const clap_plugin,
    id: *const c_char,
) -> *const c_void {
    if plugin.is_null() || id.is_null() {
        return std::ptr::null();
    }
    // SAFETY: `plugin` is a PluginShim made by create_plugin; id is a C string.
    let (shim, id_c) = unsafe { (&*(plugin as *const PluginShim), CStr::from_ptr(id)) };
    if id_c == CLAP_EXT_PRESET_LOAD || id_c == CLAP_EXT_PRESET_LOAD_COMPAT {
        return &PRESET_LOAD as *const _ as *const c_void;
    }
    // SAFETY: the wrapper's own function, with the pointer it expects.
    unsafe { (shim.inner_get_extension)(plugin, id) }
}

unsafe extern "C" fn shim_destroy(plugin: *const clap_plugin) {
    if plugin.is_null() {
        return;
    }
    // SAFETY: made by Box::into_raw in create_plugin; destroyed once (CLAP).
    let shim = unsafe { Box::from_raw(plugin as *mut PluginShim) };
    // SAFETY: the wrapper's destroy, while the struct it reads is alive.
    unsafe { (shim.inner_destroy)(plugin) };
}

// ---------------------------------------------------------------------------
// preset-load

static PRESET_LOAD: clap_plugin_preset_load = clap_plugin_preset_load {
    from_location: Some(from_location),
};

/// Where a preset comes from, as a host names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PresetLocation {
    /// A built-in scene, by its id (`presets::PRESETS[i].name`).
    BuiltIn(String),
    /// A scene file.
    File(PathBuf),
}

/// Change `state` so that restoring it plays `location` (the other
/// parameters stay as they are). Errors say why, for the host.
/// \[main-thread\]
pub fn apply_preset(
    state: &mut nice_plug::plugin::PluginState,
    location: &PresetLocation,
) -> Result<(), String> {
    match location {
        PresetLocation::BuiltIn(key) => {
            let p = PRESETS
                .iter()
                .find(|p| p.name == key)
                .ok_or_else(|| format!("no built-in scene {key:?}"))?;
            state
                .params
                .insert(ids::SCENE.into(), ParamValue::String(p.name.into()));
            state.fields.remove(keys::USER_SCENE);
        }
        PresetLocation::File(path) => {
            let scene = UserScene::from_file(path)?;
            Scene::from_toml_str(&scene.text).map_err(|e| format!("{}: {e}", path.display()))?;
            let json = serde_json::to_string(&scene).map_err(|e| e.to_string())?;
            state.fields.insert(keys::USER_SCENE.into(), json);
        }
    }
    Ok(())
}

/// Read what a host passes to `from_location` / `get_metadata`.
///
/// # Safety
/// `location` and `load_key` are null or NUL-terminated strings.
unsafe fn location_of(
    kind: clap_preset_discovery_location_kind,
    location: *const c_char,
    load_key: *const c_char,
) -> Result<PresetLocation, String> {
    let text = |p: *const c_char| {
        // SAFETY: per this function's contract.
        (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    };
    match kind {
        CLAP_PRESET_DISCOVERY_LOCATION_PLUGIN => text(load_key)
            .map(PresetLocation::BuiltIn)
            .ok_or_else(|| "a built-in scene needs a load key".into()),
        CLAP_PRESET_DISCOVERY_LOCATION_FILE => text(location)
            .map(|p| PresetLocation::File(PathBuf::from(p)))
            .ok_or_else(|| "a scene file needs a path".into()),
        k => Err(format!("unknown location kind {k}")),
    }
}

unsafe extern "C" fn from_location(
    plugin: *const clap_plugin,
    kind: clap_preset_discovery_location_kind,
    location: *const c_char,
    load_key: *const c_char,
) -> bool {
    if plugin.is_null() {
        return false;
    }
    // SAFETY: `plugin` is not null and is the `clap_plugin` of a shim made
    // by `create_plugin` (the host passes back the plugin it was given),
    // alive until `shim_destroy`.
    let shim = unsafe { &*(plugin as *const PluginShim) };
    // SAFETY: the shim's `plugin_data` is the wrapper `create_plugin`
    // stored there, which lives as long as the shim.
    let wrapper = unsafe { &*(shim.plugin.plugin_data as *const Wrapper<ModalContact>) };
    // SAFETY: C strings or null, per the CLAP contract.
    let result = unsafe { location_of(kind, location, load_key) }.and_then(|loc| {
        let mut state = wrapper.get_state_object();
        apply_preset(&mut state, &loc)?;
        wrapper.set_state_object_from_gui(state);
        Ok(())
    });
    // Tell the host (when it has the extension) what happened.
    // SAFETY: the host pointer given at creation lives as long as the plugin.
    let host_ext = unsafe {
        let host = &*shim.host;
        host.get_extension
            .map(|f| f(shim.host, CLAP_EXT_PRESET_LOAD.as_ptr()))
            .filter(|p| !p.is_null())
            .map(|p| &*(p as *const clap_host_preset_load))
    };
    match result {
        Ok(()) => {
            if let Some(f) = host_ext.and_then(|e| e.loaded) {
                // SAFETY: main thread, the host's own strings passed back.
                unsafe { f(shim.host, kind, location, load_key) };
            }
            true
        }
        Err(msg) => {
            nice_plug::nice_log!("modal_contact: preset load: {msg}");
            if let Some(f) = host_ext.and_then(|e| e.on_error) {
                let msg = CString::new(msg.replace('\0', " ")).unwrap_or_default();
                // SAFETY: as above.
                unsafe { f(shim.host, kind, location, load_key, 0, msg.as_ptr()) };
            }
            false
        }
    }
}

// ---------------------------------------------------------------------------
// Preset-discovery factory and provider

static PRESET_FACTORY: clap_preset_discovery_factory = clap_preset_discovery_factory {
    count: Some(provider_count),
    get_descriptor: Some(provider_descriptor),
    create: Some(create_provider),
};

static PROVIDER_DESCRIPTOR: clap_preset_discovery_provider_descriptor =
    clap_preset_discovery_provider_descriptor {
        clap_version: CLAP_VERSION,
        id: PROVIDER_ID.as_ptr(),
        name: c"Modal Contact scenes".as_ptr(),
        vendor: c"Modal Contact".as_ptr(),
    };

unsafe extern "C" fn provider_count(_factory: *const clap_preset_discovery_factory) -> u32 {
    1
}

unsafe extern "C" fn provider_descriptor(
    _factory: *const clap_preset_discovery_factory,
    index: u32,
) -> *const clap_preset_discovery_provider_descriptor {
    if index == 0 {
        &PROVIDER_DESCRIPTOR
    } else {
        std::ptr::null()
    }
}

/// The provider the host holds (`repr(C)`, the CLAP struct first).
#[repr(C)]
struct Provider {
    provider: clap_preset_discovery_provider,
    indexer: *const clap_preset_discovery_indexer,
}

unsafe extern "C" fn create_provider(
    _factory: *const clap_preset_discovery_factory,
    indexer: *const clap_preset_discovery_indexer,
    provider_id: *const c_char,
) -> *const clap_preset_discovery_provider {
    if indexer.is_null()
        || provider_id.is_null()
        // SAFETY: not null (checked just above) and NUL-terminated per the
        // CLAP contract.
        || unsafe { CStr::from_ptr(provider_id) } != PROVIDER_ID
    {
        return std::ptr::null();
    }
    let p = Box::new(Provider {
        provider: clap_preset_discovery_provider {
            desc: &PROVIDER_DESCRIPTOR,
            provider_data: std::ptr::null_mut(),
            init: Some(provider_init),
            destroy: Some(provider_destroy),
            get_metadata: Some(provider_get_metadata),
            get_extension: Some(provider_get_extension),
        },
        indexer,
    });
    Box::into_raw(p) as *const clap_preset_discovery_provider
}

/// The user scene folder the provider declares, if it exists.
pub fn user_folder() -> Option<PathBuf> {
    browser::default_folder().filter(|d| d.is_dir())
}

unsafe extern "C" fn provider_init(provider: *const clap_preset_discovery_provider) -> bool {
    // SAFETY: made by create_provider; the indexer outlives the provider.
    let indexer = unsafe { &*(*(provider as *const Provider)).indexer };
    let (Some(declare_location), Some(declare_filetype)) =
        (indexer.declare_location, indexer.declare_filetype)
    else {
        return false;
    };
    let built_in = clap_preset_discovery_location {
        flags: CLAP_PRESET_DISCOVERY_IS_FACTORY_CONTENT,
        name: BUILT_IN_LOCATION.as_ptr(),
        kind: CLAP_PRESET_DISCOVERY_LOCATION_PLUGIN,
        location: std::ptr::null(),
    };
    // SAFETY: the host's callbacks with structs alive for the call.
    if !unsafe { declare_location(indexer, &built_in) } {
        return false;
    }
    let Some(folder) =
        user_folder().and_then(|d| CString::new(d.to_string_lossy().as_bytes()).ok())
    else {
        return true;
    };
    let file_type = clap_preset_discovery_filetype {
        name: c"Modal Contact scene".as_ptr(),
        description: c"A scene file (TOML): objects, contact and hammer".as_ptr(),
        file_extension: c"toml".as_ptr(),
    };
    let user = clap_preset_discovery_location {
        flags: CLAP_PRESET_DISCOVERY_IS_USER_CONTENT,
        name: USER_LOCATION.as_ptr(),
        kind: CLAP_PRESET_DISCOVERY_LOCATION_FILE,
        location: folder.as_ptr(),
    };
    // SAFETY: as above.
    unsafe { declare_filetype(indexer, &file_type) && declare_location(indexer, &user) }
}

unsafe extern "C" fn provider_destroy(provider: *const clap_preset_discovery_provider) {
    if !provider.is_null() {
        // SAFETY: made by Box::into_raw in create_provider; destroyed once.
        drop(unsafe { Box::from_raw(provider as *mut Provider) });
    }
}

unsafe extern "C" fn provider_get_extension(
    _provider: *const clap_preset_discovery_provider,
    _id: *const c_char,
) -> *const c_void {
    std::ptr::null()
}

/// One preset as the provider describes it to a host.
#[derive(Debug, Clone, PartialEq)]
pub struct PresetInfo {
    /// Shown name.
    pub name: String,
    /// Load key (`None` for a file: the file is the preset).
    pub load_key: Option<String>,
    /// The scene's description.
    pub description: String,
    /// Factory (built-in) or user content.
    pub factory: bool,
}

/// The presets at a location (the built-in list, or one scene file), or why
/// not. \[main-thread\]
pub fn presets_at(location: &PresetLocation) -> Result<Vec<PresetInfo>, String> {
    match location {
        PresetLocation::BuiltIn(_) => Ok(PRESETS
            .iter()
            .map(|p| PresetInfo {
                name: p.title.into(),
                load_key: Some(p.name.into()),
                description: Scene::from_toml_str(p.toml)
                    .map(|s| s.description)
                    .unwrap_or_default(),
                factory: true,
            })
            .collect()),
        PresetLocation::File(path) => {
            let scene = Scene::from_file(path).map_err(|e| format!("{}: {e}", path.display()))?;
            Ok(vec![PresetInfo {
                name: file_stem(path),
                load_key: None,
                description: scene.description,
                factory: false,
            }])
        }
    }
}

fn file_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into())
}

fn c_string(s: &str) -> CString {
    CString::new(s.replace('\0', " ")).unwrap_or_default()
}

unsafe extern "C" fn provider_get_metadata(
    _provider: *const clap_preset_discovery_provider,
    kind: clap_preset_discovery_location_kind,
    location: *const c_char,
    receiver: *const clap_preset_discovery_metadata_receiver,
) -> bool {
    if receiver.is_null() {
        return false;
    }
    // SAFETY: the host's receiver, valid for this call.
    let r = unsafe { &*receiver };
    // The built-in location has no load key here: any key selects the list.
    let loc = match kind {
        CLAP_PRESET_DISCOVERY_LOCATION_PLUGIN => Ok(PresetLocation::BuiltIn(String::new())),
        // SAFETY: a C string or null, per the CLAP contract.
        _ => unsafe { location_of(kind, location, std::ptr::null()) },
    };
    let presets = loc.and_then(|l| presets_at(&l));
    let presets = match presets {
        Ok(p) => p,
        Err(msg) => {
            if let Some(on_error) = r.on_error {
                let msg = c_string(&msg);
                // SAFETY: the host's callback.
                unsafe { on_error(receiver, 0, msg.as_ptr()) };
            }
            return false;
        }
    };
    let clap_id = c_string(ModalContact::CLAP_ID);
    let plugin_id = clap_universal_plugin_id {
        abi: c"clap".as_ptr(),
        id: clap_id.as_ptr(),
    };
    let (Some(begin), Some(add_id), Some(flags)) = (r.begin_preset, r.add_plugin_id, r.set_flags)
    else {
        return false;
    };
    for p in &presets {
        let name = c_string(&p.name);
        let key = p.load_key.as_deref().map(c_string);
        let description = c_string(&p.description);
        // SAFETY: the host's callbacks with strings alive for each call.
        unsafe {
            if !begin(
                receiver,
                name.as_ptr(),
                key.as_ref().map_or(std::ptr::null(), |k| k.as_ptr()),
            ) {
                break;
            }
            add_id(receiver, &plugin_id);
            flags(
                receiver,
                if p.factory {
                    CLAP_PRESET_DISCOVERY_IS_FACTORY_CONTENT
                } else {
                    CLAP_PRESET_DISCOVERY_IS_USER_CONTENT
                },
            );
            if let Some(set_description) = r.set_description {
                set_description(receiver, description.as_ptr());
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use nice_plug::plugin::PluginState;
    use std::collections::BTreeMap;

    fn state() -> PluginState {
        PluginState {
            version: String::new(),
            params: BTreeMap::new(),
            fields: BTreeMap::new(),
        }
    }

    #[test]
    fn a_built_in_scene_sets_the_scene_and_drops_a_user_scene() {
        let mut s = state();
        s.fields.insert(keys::USER_SCENE.into(), "{}".into());
        s.fields
            .insert(keys::EDITOR_SIZE.into(), "[800,600]".into());
        apply_preset(&mut s, &PresetLocation::BuiltIn("bell".into())).unwrap();
        assert!(matches!(&s.params[ids::SCENE], ParamValue::String(v) if v == "bell"));
        assert!(!s.fields.contains_key(keys::USER_SCENE));
        assert!(s.fields.contains_key(keys::EDITOR_SIZE), "the rest is kept");
        let before = s.clone();
        let err = apply_preset(&mut s, &PresetLocation::BuiltIn("no-such".into())).unwrap_err();
        assert!(err.contains("no-such"), "{err}");
        assert_eq!(s.params.len(), before.params.len());
    }

    #[test]
    fn a_file_that_does_not_validate_changes_nothing_and_says_where() {
        let dir = std::env::temp_dir().join(format!("mc-preset-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = dir.join("good.toml");
        std::fs::write(&good, PRESETS[0].toml).unwrap();
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, PRESETS[0].toml.replacen("t60_s = ", "t60_s = -", 1)).unwrap();
        let mut s = state();
        let err = apply_preset(&mut s, &PresetLocation::File(bad.clone())).unwrap_err();
        assert!(err.contains("bad.toml") && err.contains("t60"), "{err}");
        assert!(s.fields.is_empty());
        assert!(presets_at(&PresetLocation::File(bad)).is_err());
        apply_preset(&mut s, &PresetLocation::File(good.clone())).unwrap();
        let saved: UserScene = serde_json::from_str(&s.fields[keys::USER_SCENE]).unwrap();
        assert_eq!(saved.text, PRESETS[0].toml);
        assert_eq!(saved.name, "good");
        let listed = presets_at(&PresetLocation::File(good)).unwrap();
        assert_eq!(listed.len(), 1);
        assert_eq!(listed[0].name, "good");
        assert!(!listed[0].factory && listed[0].load_key.is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
