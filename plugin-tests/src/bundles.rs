//! Where the plugin bundles are: the build variants, the workspace and
//! output folders, and the `.clap` / `.vst3` of a variant (bundled once
//! per process when no prebuilt one is given).

use crate::BUNDLE_NAME;
use modal_testkit::bundles::{self, Bundle};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

/// Which build of the plugin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// `--release`, default features (what users install).
    Release,
    /// `--profile test-release --features standalone,rt-checks,alloc-bug`: optimised, debug
    /// assertions on, so nice-plug's `assert_process_allocs` is active.
    RtChecks,
    /// The same build as `RtChecks` (which carries the test-only
    /// `alloc-bug` trigger): note 2 at velocity 0.123 allocates in `process`.
    AllocBug,
    /// `--profile test-release --features standalone,panic-bug` (no allocation
    /// checker): note 1 panics inside `process`.
    PanicBug,
}

impl Variant {
    /// The build of the bundle matrix (`modal_testkit::bundles::BUNDLES`,
    /// which `cargo xtask test` builds too) this variant runs on.
    pub fn bundle(self) -> &'static Bundle {
        bundles::bundle(match self {
            Variant::Release => "release",
            Variant::RtChecks | Variant::AllocBug => "rt-checks",
            Variant::PanicBug => "panic-bug",
        })
    }

    /// Directory / env name.
    pub fn name(self) -> &'static str {
        self.bundle().name
    }

    /// Arguments for `cargo xtask bundle modal_contact ...`.
    pub fn bundle_args(self) -> &'static [&'static str] {
        self.bundle().cargo_args
    }

    /// The environment variable that points at a prebuilt `.clap`.
    pub fn env_var(self) -> String {
        self.bundle().env_var()
    }
}

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("plugin-tests has a parent")
        .to_path_buf()
}

/// Where test outputs (WAVs) go.
pub fn out_dir() -> PathBuf {
    let d = workspace_root()
        .join("target")
        .join("plugin-tests")
        .join("wav");
    std::fs::create_dir_all(&d).expect("mkdir target/plugin-tests/wav");
    d
}

static BUILT: Mutex<Vec<Variant>> = Mutex::new(Vec::new());

/// Path of the `.clap` of `variant` (built first if needed).
pub fn clap_bundle(variant: Variant) -> PathBuf {
    if let Ok(p) = std::env::var(variant.env_var()) {
        return PathBuf::from(p);
    }
    bundle_dir(variant).join(format!("{BUNDLE_NAME}.clap"))
}

/// Path of the `.vst3` bundle directory of `variant` (built first if needed).
pub fn vst3_bundle(variant: Variant) -> PathBuf {
    clap_bundle(variant).with_extension("vst3")
}

fn bundle_dir(variant: Variant) -> PathBuf {
    let root = workspace_root();
    let base = root.join("target").join("plugin-tests");
    let out = base.join(variant.name());
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    let reuse = std::env::var_os("MODAL_CONTACT_SKIP_BUNDLE").is_some()
        && out.join(format!("{BUNDLE_NAME}.clap")).exists();
    if built.contains(&variant) || reuse {
        return out;
    }
    let target_dir = base.join("cargo");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let run = |cmd: &mut Command, what: &str| {
        let status = cmd
            .current_dir(&root)
            .env_remove("CARGO_MANIFEST_DIR")
            .env("CARGO_TARGET_DIR", &target_dir)
            .status()
            .unwrap_or_else(|e| panic!("spawn {what}: {e}"));
        assert!(status.success(), "{what} failed");
    };
    run(
        Command::new(&cargo).args(["build", "--quiet", "--package", "xtask", "--release"]),
        "building xtask",
    );
    run(
        Command::new(target_dir.join("release").join("xtask"))
            .args(["bundle", BUNDLE_NAME])
            .args(variant.bundle_args()),
        "cargo xtask bundle",
    );
    bundles::copy_bundles(&target_dir.join("bundled"), &out)
        .unwrap_or_else(|e| panic!("copying the bundles to {}: {e}", out.display()));
    built.push(variant);
    out
}
