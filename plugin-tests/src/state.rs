//! Plugin state helpers: the JSON of a saved state, a state of a JSON,
//! and a state with a user scene loaded.

use std::path::Path;

/// The JSON of a saved plugin state (nice-plug's: a little-endian length,
/// then the JSON).
pub fn json_of(state: &[u8]) -> String {
    let n = u64::from_le_bytes(state[..8].try_into().unwrap()) as usize;
    String::from_utf8(state[8..8 + n].to_vec()).expect("utf-8 JSON")
}

/// A plugin state holding `json` (see [`json_of`]).
pub fn state_of(json: &str) -> Vec<u8> {
    let mut out = (json.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(json.as_bytes());
    out
}

/// `state` (nice-plug's JSON) with the user scene field set to `text`
/// loaded from `path`, as the editor's scene browser leaves it.
pub fn with_user_scene(state: &[u8], name: &str, text: &str, path: &Path) -> Vec<u8> {
    let mut v: serde_json::Value = serde_json::from_str(&json_of(state)).unwrap();
    let scene = serde_json::json!({ "name": name, "text": text, "path": path });
    v["fields"]["user_scene"] = serde_json::Value::String(scene.to_string());
    state_of(&v.to_string())
}
