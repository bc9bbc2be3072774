//! The editor's scene browser: the user scene folder and what is in it.
//! Every `.toml` file is parsed and validated when the folder is listed (off
//! the audio thread; the editor lists on a background thread), so an invalid
//! file is shown with its error (the field's path and the reason) before
//! anyone tries to play it. Loading a file hands its text to the worker
//! ([`super::user_scene::SceneLibrary::load`]), which validates it again and
//! compiles it.

use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// The default user scene folder: `scenes` in the platform's data
/// directory for the plugin (Linux: `$XDG_DATA_HOME/modalcontact/scenes`,
/// usually `~/.local/share/modalcontact/scenes`; macOS:
/// `~/Library/Application Support/dev.modal-contact.Modal-Contact/scenes`;
/// Windows: `%APPDATA%\modal-contact\Modal Contact\data\scenes`), or `None`
/// where the platform has no home directory.
pub fn default_folder() -> Option<PathBuf> {
    directories::ProjectDirs::from("dev", "modal-contact", "Modal Contact")
        .map(|d| d.data_dir().join("scenes"))
}

/// One scene file of the folder.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// The file stem.
    pub name: String,
    /// The file.
    pub path: PathBuf,
    /// The scene's description if it validates, else the error.
    pub status: Result<String, String>,
}

/// Every `.toml` file directly in `dir`, sorted by name, each parsed and
/// validated. A folder that does not exist or cannot be read is an error
/// with the reason (the browser shows it); a file that cannot be read is an
/// entry with its error.
pub fn list_folder(dir: &Path) -> Result<Vec<Entry>, String> {
    let rd = std::fs::read_dir(dir).map_err(|e| format!("cannot read {}: {e}", dir.display()))?;
    let mut entries: Vec<Entry> = rd
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("toml"))
                && p.is_file()
        })
        .map(|path| {
            let status = Scene::from_file(&path)
                .map(|s| s.description.clone())
                .map_err(|e| e.to_string());
            Entry {
                name: path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                path,
                status,
            }
        })
        .collect();
    entries.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_folder_lists_valid_and_invalid_scenes_with_their_errors() {
        let dir = std::env::temp_dir().join(format!("mc-browser-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let good = crate::presets::PRESETS
            .iter()
            .find(|p| p.name == "bell")
            .unwrap()
            .toml;
        std::fs::write(dir.join("b-good.toml"), good).unwrap();
        std::fs::write(dir.join("a-broken.toml"), "name = [").unwrap();
        let bad = good.replacen("t60_s = ", "t60_s = -", 1);
        std::fs::write(dir.join("c-invalid.toml"), bad).unwrap();
        std::fs::write(dir.join("notes.txt"), "not a scene").unwrap();
        let list = list_folder(&dir).unwrap();
        let names: Vec<&str> = list.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["a-broken", "b-good", "c-invalid"]);
        assert!(
            list[0].status.as_ref().unwrap_err().contains("line 1"),
            "{:?}",
            list[0]
        );
        assert!(list[1].status.is_ok(), "{:?}", list[1]);
        let e = list[2].status.as_ref().unwrap_err();
        assert!(e.starts_with("object[0].mode[0].t60_s: must be > 0"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_folder_is_an_error_not_a_panic() {
        let e = list_folder(Path::new("/nonexistent/modal-contact/scenes")).unwrap_err();
        assert!(e.contains("cannot read /nonexistent"), "{e}");
    }

    #[test]
    fn the_default_folder_is_in_the_users_data_directory() {
        if let Some(d) = default_folder() {
            assert!(d.ends_with("scenes"), "{}", d.display());
        }
    }
}
