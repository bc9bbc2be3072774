//! The scene files of `presets/`, embedded into the plugin at build time.
//!
//! The list is sorted by file name; its order is the order of the plugin's
//! "Scene" parameter (`plugin::params::PresetChoice`), so it must only grow at
//! the end if saved projects are to keep their scene. A test below checks that
//! the embedded list matches the folder exactly.

use crate::scene::{Scene, SceneError};

/// One embedded preset: its name (the file stem) and the TOML text.
#[derive(Debug, Clone, Copy)]
pub struct Preset {
    /// File stem, e.g. `marimba-bar`.
    pub name: &'static str,
    /// The scene file's text.
    pub toml: &'static str,
}

macro_rules! preset {
    ($name:literal) => {
        Preset {
            name: $name,
            toml: include_str!(concat!("../presets/", $name, ".toml")),
        }
    };
}

/// Every file of `presets/*.toml`, sorted by name.
pub const PRESETS: &[Preset] = &[
    preset!("bell"),
    preset!("glockenspiel-bar"),
    preset!("marimba-bar"),
    preset!("paper-bounce"),
    preset!("paper-string"),
    preset!("steel-plate"),
    preset!("wood-block"),
];

/// Index of the preset called `name`. \[any-thread\]
pub fn index_of(name: &str) -> Option<usize> {
    PRESETS.iter().position(|p| p.name == name)
}

/// Parse and validate preset `index` (allocates). [main-thread / worker]
pub fn scene(index: usize) -> Result<Scene, SceneError> {
    let p = PRESETS.get(index).ok_or_else(|| SceneError {
        path: String::new(),
        reason: format!("no preset with index {index}"),
    })?;
    Scene::from_toml_str(p.toml)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_list_matches_the_presets_folder() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("presets");
        let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| {
                let p = e.unwrap().path();
                (p.extension().and_then(|x| x.to_str()) == Some("toml"))
                    .then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
            })
            .collect();
        on_disk.sort();
        let embedded: Vec<String> = PRESETS.iter().map(|p| p.name.to_string()).collect();
        assert_eq!(embedded, on_disk, "presets/ and PRESETS differ");
        for p in PRESETS {
            let text = std::fs::read_to_string(dir.join(format!("{}.toml", p.name))).unwrap();
            assert_eq!(text, p.toml, "{} embedded text is stale", p.name);
        }
    }

    #[test]
    fn every_preset_parses_and_is_named_after_its_file() {
        for (i, p) in PRESETS.iter().enumerate() {
            let s = scene(i).unwrap_or_else(|e| panic!("{}: {e}", p.name));
            assert_eq!(s.name, p.name);
            assert_eq!(index_of(p.name), Some(i));
        }
    }
}
