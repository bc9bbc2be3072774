//! Shared helpers for the integration tests.
#![allow(dead_code)]

use modal_contact::scene::Scene;
use std::path::PathBuf;

/// Path of a preset file.
pub fn preset_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("presets")
        .join(format!("{name}.toml"))
}

/// Load a preset.
pub fn preset(name: &str) -> Scene {
    Scene::from_file(&preset_path(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Parse a scene from TOML text, panicking with the error.
pub fn scene(text: &str) -> Scene {
    Scene::from_toml_str(text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// A hammer against a rigid wall (no gravity), moving down at `v0`.
pub fn wall_scene(m: f64, k: f64, c: f64, v0: f64) -> Scene {
    scene(&format!(
        r#"
version = 1
name = "wall"
[[object]]
name = "floor"
kind = "wall"
[hammer]
mass_kg = {m:e}
height_m = 0.0
velocity_m_per_s = {v0:e}
[contact]
object = "floor"
stiffness_n_per_m = {k:e}
damping_n_s_per_m = {c:e}
"#
    ))
}

/// Relative L2 difference.
pub fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}
