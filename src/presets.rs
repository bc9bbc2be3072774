//! The scene files of `presets/`, embedded into the plugin at build time.
//!
//! [`PRESETS`] is the one list of presets: the plugin's "Scene" parameter
//! takes its choices, their ids and the names hosts show from it
//! (`plugin::params`, with the feature `plugin`), `cargo xtask param-docs`
//! writes the scenes table of docs/plugin.md from it, and the tests iterate
//! over it. Adding a preset means adding its TOML file and one line at the
//! END of the list (then `cargo xtask param-docs`).
//!
//! Why a written list and not a build script that scans `presets/*.toml`: the
//! order is part of the plugin's interface, and a folder has no order. nice-plug
//! saves the scene in a project by its string id (the file stem), so saved
//! projects find their preset whatever the order; but a host's automation of
//! the parameter stores its position (a CLAP host the index, a VST3 host
//! `index / (count - 1)`), so a shipped preset must never move. A scan could
//! only sort the names, which puts a new preset in the middle and shifts
//! every one after it. So the list is append-only: `saved_indices_never_move`
//! pins the order of the shipped presets, and
//! `embedded_list_matches_the_presets_folder` fails when a file of the folder
//! is missing from the list (or the other way round). Appending still changes
//! the VST3 normalised values of the existing presets (the count changes);
//! only reserving slots in advance would avoid that, which would show hosts
//! choices that do not exist.

use crate::scene::{Scene, SceneError};

/// One embedded preset.
#[derive(Debug, Clone, Copy)]
pub struct Preset {
    /// File stem, e.g. `marimba-bar`: the scene's `name`, and the id a saved
    /// project stores for the "Scene" parameter (never rename one).
    pub name: &'static str,
    /// What hosts show as the "Scene" parameter's value, e.g. `Marimba bar`.
    pub title: &'static str,
    /// The scene file's text.
    pub toml: &'static str,
}

macro_rules! preset {
    ($name:literal, $title:literal) => {
        Preset {
            name: $name,
            title: $title,
            toml: include_str!(concat!("../presets/", $name, ".toml")),
        }
    };
}

/// Every file of `presets/*.toml`, in the order of the "Scene" parameter.
/// Append only (see the module documentation).
pub const PRESETS: &[Preset] = &[
    preset!("bell", "Bell"),
    preset!("glockenspiel-bar", "Glockenspiel bar"),
    preset!("marimba-bar", "Marimba bar"),
    preset!("paper-bounce", "Paper bounce"),
    preset!("paper-string", "Paper string"),
    preset!("steel-plate", "Steel plate"),
    preset!("wood-block", "Wood block"),
    preset!("vibraphone-bar", "Vibraphone bar"),
    preset!("tubular-chime", "Tubular chime"),
    preset!("frame-drum", "Frame drum"),
    preset!("piano-string", "Piano string"),
    preset!("marimba-rubber-mallet", "Marimba, rubber mallet"),
    preset!("marimba-two-mallets", "Marimba, two mallets (kit)"),
    preset!("ball-between-plates", "Ball between plates (kit)"),
    preset!("wind-chimes", "Wind chimes (kit)"),
    preset!("snare-pair", "Snare pair (kit)"),
    preset!("guiro", "Guiro (scraped)"),
    preset!("ball-on-plate", "Ball rolling on a plate"),
    preset!("marble-on-board", "Marble rolling on a board"),
    preset!("glockenspiel-recorded", "Glockenspiel (from a recording)"),
    preset!("marimba-recorded", "Marimba (from a recording)"),
    preset!("timpani-recorded", "Timpani (from a recording)"),
    preset!("guiro-recorded", "Guiro (from a recording)"),
    preset!("snare-brush", "Snare head, brushed"),
];

/// How many presets there are.
pub const COUNT: usize = PRESETS.len();

/// Whether preset `i` is a scene of several contacts, which the instrument
/// plays as a kit (docs/design.md, "Played as a kit"); false
/// for an index out of range or a scene that does not parse.
pub fn is_kit(i: usize) -> bool {
    scene(i).is_ok_and(|s| s.several_contacts())
}

/// The indices of the presets of one contact (what the one-contact
/// compiler and engine take), in list order.
pub fn one_contact() -> impl Iterator<Item = usize> {
    (0..COUNT).filter(|&i| !is_kit(i))
}

/// The presets' names (file stems), in list order: the "Scene" parameter's
/// stable ids. Built from [`PRESETS`] at compile time, because nice-plug's
/// `Enum` trait wants `&'static` slices of them.
pub const NAMES: [&str; COUNT] = {
    let mut out = [""; COUNT];
    let mut i = 0;
    while i < COUNT {
        out[i] = PRESETS[i].name;
        i += 1;
    }
    out
};

/// The presets' titles, in list order (what hosts show).
pub const TITLES: [&str; COUNT] = {
    let mut out = [""; COUNT];
    let mut i = 0;
    while i < COUNT {
        out[i] = PRESETS[i].title;
        i += 1;
    }
    out
};

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

/// The presets this plugin shipped with before the list became the single
/// source, at the index hosts have automated them under and with the title
/// hosts have shown: what `saved_indices_never_move` and the parameter tests
/// hold the list to.
#[cfg(test)]
pub(crate) const SHIPPED: [(&str, &str); 7] = [
    ("bell", "Bell"),
    ("glockenspiel-bar", "Glockenspiel bar"),
    ("marimba-bar", "Marimba bar"),
    ("paper-bounce", "Paper bounce"),
    ("paper-string", "Paper string"),
    ("steel-plate", "Steel plate"),
    ("wood-block", "Wood block"),
];

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
        let mut embedded: Vec<String> = PRESETS.iter().map(|p| p.name.to_string()).collect();
        embedded.sort();
        assert_eq!(
            embedded, on_disk,
            "presets/ and PRESETS differ: append a new preset at the end of PRESETS"
        );
        for p in PRESETS {
            let text = std::fs::read_to_string(dir.join(format!("{}.toml", p.name))).unwrap();
            assert_eq!(text, p.toml, "{} embedded text is stale", p.name);
        }
    }

    #[test]
    fn saved_indices_never_move() {
        assert!(
            PRESETS.len() >= SHIPPED.len(),
            "a shipped preset was removed"
        );
        for (i, (name, title)) in SHIPPED.iter().enumerate() {
            assert_eq!(
                (PRESETS[i].name, PRESETS[i].title),
                (*name, *title),
                "preset {i} moved or was renamed: hosts automate the Scene parameter by index"
            );
        }
    }

    #[test]
    fn names_and_titles_are_unique_and_follow_the_list() {
        assert_eq!(NAMES.len(), PRESETS.len());
        for (i, p) in PRESETS.iter().enumerate() {
            assert_eq!((NAMES[i], TITLES[i]), (p.name, p.title));
            assert!(!p.title.is_empty());
            assert_eq!(PRESETS.iter().filter(|q| q.name == p.name).count(), 1);
            assert_eq!(PRESETS.iter().filter(|q| q.title == p.title).count(), 1);
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
