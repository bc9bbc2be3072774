//! What the plugin saves with a project besides the parameters: the user's
//! scene, the editor's size and the scene browser's folder.

use crate::plugin::user_scene::{lock, SceneLibrary, UserScene};
use crossbeam::atomic::AtomicCell;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// Default editor window size \[logical pixels\].
pub const EDITOR_SIZE: (u32, u32) = (1000, 700);
/// Saved-state keys of [`Persisted`] (never change them).
pub mod keys {
    /// The user's scene (JSON of [`super::UserScene`]; absent: the preset).
    pub const USER_SCENE: &str = "user_scene";
    /// The editor's size, `[width, height]` in logical pixels.
    pub const EDITOR_SIZE: &str = "editor_size";
    /// The scene browser's folder (absent: the default folder).
    pub const SCENE_FOLDER: &str = "scene_folder";
}

/// What the plugin saves with a project besides the parameters. The
/// audio thread reads only the library's atomic generation.
pub struct Persisted {
    /// The user's scene and the compile reports.
    pub library: Arc<SceneLibrary>,
    /// The editor's size \[logical pixels\].
    pub editor_size: AtomicCell<(u32, u32)>,
    /// The scene browser's folder (`None`: the default).
    pub scene_folder: Mutex<Option<PathBuf>>,
}

impl Default for Persisted {
    fn default() -> Self {
        Self {
            library: Arc::new(SceneLibrary::default()),
            editor_size: AtomicCell::new(EDITOR_SIZE),
            scene_folder: Mutex::new(None),
        }
    }
}

impl Persisted {
    /// The fields as a saved state stores them. \[main-thread\]
    pub fn serialize(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        if let Some(s) = self.library.to_saved() {
            if let Ok(j) = serde_json::to_string(&s) {
                m.insert(keys::USER_SCENE.into(), j);
            }
        }
        // only what differs from the defaults: a project that never opened
        // the editor saves exactly what it saved before the editor existed
        let (w, h) = self.editor_size.load();
        if (w, h) != EDITOR_SIZE {
            m.insert(keys::EDITOR_SIZE.into(), format!("[{w},{h}]"));
        }
        if let Some(f) = lock(&self.scene_folder).as_ref() {
            if let Ok(j) = serde_json::to_string(f) {
                m.insert(keys::SCENE_FOLDER.into(), j);
            }
        }
        m
    }

    /// Restore from a saved state: a missing field (an older project) gets
    /// its default, an unreadable one too, with a note for the log (a user
    /// scene that no longer validates is reported by its compile, and its
    /// text kept). \[main-thread\]
    pub fn deserialize(&self, m: &BTreeMap<String, String>) -> Vec<String> {
        let mut notes = Vec::new();
        let scene = m.get(keys::USER_SCENE).and_then(|j| {
            serde_json::from_str::<UserScene>(j)
                .map_err(|e| {
                    notes.push(format!(
                        "the saved user scene is unreadable ({e}); playing the preset"
                    ))
                })
                .ok()
        });
        self.library.restore(scene);
        let size = m.get(keys::EDITOR_SIZE).and_then(|j| {
            serde_json::from_str::<(u32, u32)>(j)
                .ok()
                .filter(|&(w, h)| (200..=8192).contains(&w) && (150..=8192).contains(&h))
                .or_else(|| {
                    notes.push(format!("editor size {j:?} ignored"));
                    None
                })
        });
        self.editor_size.store(size.unwrap_or(EDITOR_SIZE));
        let folder = m
            .get(keys::SCENE_FOLDER)
            .and_then(|j| serde_json::from_str::<PathBuf>(j).ok());
        *lock(&self.scene_folder) = folder;
        notes
    }
}
