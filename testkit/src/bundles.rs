//! The plugin bundles the plugin tests load: which builds, with which
//! `cargo xtask bundle` arguments, and how a build is copied out of the
//! shared `target/bundled/` (each `cargo xtask bundle` overwrites it).
//! `cargo xtask test` builds every bundle of [`BUNDLES`] up front and
//! hands the paths to the tests; the plugin-tests harness builds a missing
//! one itself. Both read this table.

use std::io;
use std::path::Path;

/// The bundle file stem (the plugin crate's library name).
pub const BUNDLE_NAME: &str = "modal_contact";

/// One build of the plugin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bundle {
    /// Directory under `target/plugin-tests/`, and the environment
    /// variable's suffix (see [`Bundle::env_var`]).
    pub name: &'static str,
    /// Arguments after `cargo xtask bundle modal_contact`.
    pub cargo_args: &'static [&'static str],
}

impl Bundle {
    /// The environment variable that points the plugin tests at a prebuilt
    /// `.clap` of this build: `MODAL_CONTACT_CLAP_<NAME>` (upper case, `-`
    /// as `_`).
    pub fn env_var(&self) -> String {
        format!(
            "MODAL_CONTACT_CLAP_{}",
            self.name.to_uppercase().replace('-', "_")
        )
    }
}

/// The features of every `test-release` build `cargo xtask test` makes (the
/// checked bundle, the standalone, the workspace's tests): one feature set
/// of the plugin crate, so they share one compilation of nice-plug and of
/// everything built on it (`feature-union/Cargo.toml` aligns the rest). The
/// panic-bug bundle differs only in nice-plug's allocation checker.
pub const TEST_FEATURES: &str = "standalone,rt-checks,alloc-bug";

/// `cargo build` arguments of the standalone application the editor test
/// runs (with the allocation checker); the binary lands in
/// `target/test-release/`. `-p` keeps the other workspace members' features
/// out of the build (they would make it a different one).
pub const STANDALONE_BUILD_ARGS: [&str; 9] = [
    "build",
    "-p",
    "modal_contact",
    "--profile",
    "test-release",
    "--features",
    TEST_FEATURES,
    "--bin",
    STANDALONE_BIN,
];

/// `cargo test --workspace` / `cargo build --package plugin-tests` feature
/// argument that gives the plugin crate [`TEST_FEATURES`].
pub const TEST_FEATURES_ARG: &str =
    "modal_contact/standalone,modal_contact/rt-checks,modal_contact/alloc-bug";

/// The standalone application's binary name.
pub const STANDALONE_BIN: &str = "modal-contact-standalone";

/// Every build the plugin tests use. The checked builds use the
/// `test-release` profile (optimised, debug assertions on, so nice-plug's
/// `assert_process_allocs` is active) and the features of the test build
/// ([`TEST_FEATURES`]; the standalone code compiled in is not used by the
/// bundles), so the dependency tree is compiled once for all of them.
///
/// The order saves two compilations of the plugin crate. A library with a
/// `cdylib` crate type is written to a file name without cargo's hash of
/// its features, so a build with other features overwrites it and makes
/// the earlier build stale: the panic-bug bundle comes first, and the
/// checked bundle after it, whose compilation the standalone application,
/// the workspace's tests and the reference renderer that `cargo xtask test`
/// builds next reuse. Release comes last so that after `cargo xtask test`,
/// `target/bundled/` holds the release bundle users install.
pub const BUNDLES: [Bundle; 3] = [
    // Without rt-checks: the allocation checker aborts on the unwinder's own
    // (de)allocations, so a caught panic can only be shown in a build
    // without it (as users run it).
    Bundle {
        name: "panic-bug",
        cargo_args: &[
            "--profile",
            "test-release",
            "--features",
            "standalone,panic-bug",
        ],
    },
    // The checked build also carries the test-only alloc-bug trigger (note 2
    // at velocity 0.123, played by no other test): one build instead of two.
    Bundle {
        name: "rt-checks",
        cargo_args: &["--profile", "test-release", "--features", TEST_FEATURES],
    },
    Bundle {
        name: "release",
        cargo_args: &["--release"],
    },
];

/// The bundle named `name` (one of [`BUNDLES`]; anything else is a bug).
pub fn bundle(name: &str) -> &'static Bundle {
    BUNDLES
        .iter()
        .find(|b| b.name == name)
        .unwrap_or_else(|| panic!("no plugin bundle named {name:?}"))
}

/// Copy the directory tree `from` to `to` (created as needed).
pub fn copy_tree(from: &Path, to: &Path) -> io::Result<()> {
    std::fs::create_dir_all(to)?;
    let entries = std::fs::read_dir(from)
        .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", from.display())))?;
    for entry in entries {
        let entry = entry?;
        let dest = to.join(entry.file_name());
        if entry.file_type()?.is_dir() {
            copy_tree(&entry.path(), &dest)?;
        } else {
            std::fs::copy(entry.path(), &dest)?;
        }
    }
    Ok(())
}

/// Replace `out` with a copy of the `.clap` and the `.vst3` bundle in
/// `bundled` (a `target/bundled/` directory).
pub fn copy_bundles(bundled: &Path, out: &Path) -> io::Result<()> {
    let _ = std::fs::remove_dir_all(out);
    copy_tree(
        &bundled.join(format!("{BUNDLE_NAME}.vst3")),
        &out.join(format!("{BUNDLE_NAME}.vst3")),
    )?;
    std::fs::copy(
        bundled.join(format!("{BUNDLE_NAME}.clap")),
        out.join(format!("{BUNDLE_NAME}.clap")),
    )?;
    Ok(())
}
