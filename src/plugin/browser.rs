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

/// What the user folder holds.
#[derive(Debug, Clone, PartialEq)]
pub enum Folder {
    /// The folder does not exist yet (a first start, before anyone made
    /// it): nothing to list and nothing wrong; the browser offers to
    /// create it.
    Missing,
    /// Its scene files.
    Listed(Vec<Entry>),
}

/// Every `.toml` file directly in `dir`, sorted by name, each parsed and
/// validated; [`Folder::Missing`] if `dir` does not exist. A folder that
/// cannot be read (no permission, a file where the folder should be) is an
/// error with the reason (the browser shows it); a file that cannot be read
/// is an entry with its error.
pub fn list_folder(dir: &Path) -> Result<Folder, String> {
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Folder::Missing),
        Err(e) => return Err(format!("cannot read {}: {e}", dir.display())),
    };
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
    Ok(Folder::Listed(entries))
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
        let Folder::Listed(list) = list_folder(&dir).unwrap() else {
            panic!("the folder exists")
        };
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

    /// A first start: the folder (and its parents) not made yet lists as
    /// missing, without an error; once made, it lists as empty.
    #[test]
    fn a_folder_not_made_yet_is_missing_not_an_error() {
        let dir = std::env::temp_dir().join(format!("mc-browser-missing-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let scenes = dir.join("modalcontact/scenes");
        assert_eq!(list_folder(&scenes), Ok(Folder::Missing));
        std::fs::create_dir_all(&scenes).unwrap();
        assert_eq!(list_folder(&scenes), Ok(Folder::Listed(Vec::new())));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A folder that is there but cannot be read is an error with the
    /// reason: a file where the folder should be (or in its path), a folder
    /// without read permission.
    #[test]
    fn an_unreadable_folder_is_an_error_with_the_reason() {
        let dir =
            std::env::temp_dir().join(format!("mc-browser-unreadable-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("scenes");
        std::fs::write(&file, "not a folder").unwrap();
        let e = list_folder(&file).unwrap_err();
        assert!(
            e.starts_with(&format!("cannot read {}: ", file.display())),
            "{e}"
        );
        assert!(e.to_lowercase().contains("not a directory"), "{e}");
        let e = list_folder(&file.join("inside")).unwrap_err();
        assert!(e.to_lowercase().contains("not a directory"), "{e}");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let locked = dir.join("locked");
            std::fs::create_dir(&locked).unwrap();
            std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o000)).unwrap();
            if std::fs::read_dir(&locked).is_ok() {
                // a privileged user reads it anyway: nothing to refuse
                println!("permissions are not enforced for this user: that case is not checked");
            } else {
                let e = list_folder(&locked).unwrap_err();
                assert!(e.to_lowercase().contains("permission denied"), "{e}");
            }
            std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_default_folder_is_in_the_users_data_directory() {
        if let Some(d) = default_folder() {
            assert!(d.ends_with("scenes"), "{}", d.display());
        }
    }
}
