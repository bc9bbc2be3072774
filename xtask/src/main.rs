//! `cargo xtask`: bundle the plugin (nice-plug-xtask) and render scenes offline.
//!
//! - `cargo xtask bundle modal_contact --release` -> `target/bundled/*.clap, *.vst3`
//! - `cargo xtask render SCENE.toml --out OUT.wav [--trace OUT.csv] [--plot OUT.svg]
//!   [--seconds S] [--rate HZ] [--switching offset-rod|exact]` (DESIGN.md section 5)
//! - `cargo xtask test [CARGO TEST ARGS]`: every test, including the plugin
//!   tests on the built bundles and the VST3 test through pedalboard
//! - `cargo xtask demo`: bundle (release) and render a demo through the built
//!   CLAP plugin into `target/demo/*.wav`

mod golden;
mod paramdocs;
mod plot;
mod report;

use anyhow::{bail, Context, Result};
use clap::Parser;
use modal_contact::render::{render, write_trace_csv, RenderOptions};
use modal_contact::scene::{Scene, Switching};
use std::path::PathBuf;

/// Offline render of a scene file.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask render")]
struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output WAV (32-bit float, stereo).
    #[arg(long)]
    out: PathBuf,
    /// Trace CSV (one row per sample).
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Plot of hammer height, contact-point displacement and energy (SVG).
    /// Default: next to the WAV with the extension .svg.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Length in seconds (default: the scene's duration_s).
    #[arg(long)]
    seconds: Option<f64>,
    /// Sample rate in Hz.
    #[arg(long, default_value_t = 44100.0)]
    rate: f64,
    /// Switching method (default: the scene's, else the project default).
    #[arg(long)]
    switching: Option<String>,
}

fn main() -> Result<()> {
    let mut args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("render") => {
            args.remove(1);
            run_render(RenderArgs::parse_from(args))
        }
        Some("report") => report::run(&args[2..]),
        Some("test") => run_tests(&args[2..]),
        Some("demo") => run_demo(),
        Some("golden") => golden::run(args.get(2).is_some_and(|a| a == "--write")),
        Some("param-docs") => paramdocs::run(args.get(2).is_some_and(|a| a == "--check")),
        _ => nice_plug_xtask::main(),
    }
}

/// Run a command, failing with its exit status.
fn run(cmd: &mut std::process::Command) -> Result<()> {
    eprintln!("+ {cmd:?}");
    let status = cmd
        .status()
        .with_context(|| format!("cannot run {cmd:?}"))?;
    if !status.success() {
        bail!("{cmd:?} failed: {status}");
    }
    Ok(())
}

/// The plugin bundles the plugin tests use: (directory under
/// `target/plugin-tests/`, `cargo xtask bundle` arguments). The checked
/// builds use the `test-release` profile (optimised, debug assertions on, so
/// nice-plug's `assert_process_allocs` is active) and share its dependencies
/// with the test build. Release comes last so `target/bundled/` ends up with
/// the release bundle users install.
const TEST_BUNDLES: [(&str, &[&str]); 3] = [
    // The checked build also carries the test-only alloc-bug trigger (note 2
    // at velocity 0.123, played by no other test): one build instead of two.
    (
        "rt-checks",
        &[
            "--profile",
            "test-release",
            "--features",
            "rt-checks,alloc-bug",
        ],
    ),
    // Without rt-checks: the allocation checker aborts on the unwinder's own
    // (de)allocations, so a caught panic can only be shown in a build
    // without it (as users run it).
    (
        "panic-bug",
        &["--profile", "test-release", "--features", "panic-bug"],
    ),
    ("release", &["--release"]),
];

/// `cargo xtask bundle modal_contact ARGS` in-process, then copy the result
/// out of the shared `target/bundled/` to `target/plugin-tests/NAME/`.
fn bundle_to(name: &str, args: &[&str]) -> Result<PathBuf> {
    let mut all = vec!["bundle".to_string(), "modal_contact".to_string()];
    all.extend(args.iter().map(|a| a.to_string()));
    eprintln!("+ cargo xtask {}", all.join(" "));
    nice_plug_xtask::main_with_args("cargo xtask", all)?;
    let out = PathBuf::from("target/plugin-tests").join(name);
    let _ = std::fs::remove_dir_all(&out);
    copy_tree(
        std::path::Path::new("target/bundled/modal_contact.vst3"),
        &out.join("modal_contact.vst3"),
    )?;
    std::fs::copy(
        "target/bundled/modal_contact.clap",
        out.join("modal_contact.clap"),
    )?;
    Ok(std::fs::canonicalize(&out)?)
}

fn copy_tree(from: &std::path::Path, to: &std::path::Path) -> Result<()> {
    std::fs::create_dir_all(to)?;
    for entry in std::fs::read_dir(from).with_context(|| format!("{}", from.display()))? {
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

/// The Python venv for the VST3 test (pedalboard, mido, numpy).
fn ensure_venv() -> Result<PathBuf> {
    let python = PathBuf::from("target/venv/bin/python");
    let ok = python.exists()
        && std::process::Command::new(&python)
            .args(["-c", "import pedalboard, mido, numpy"])
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
    if !ok {
        run(std::process::Command::new("python3").args(["-m", "venv", "target/venv"]))?;
        run(std::process::Command::new("target/venv/bin/pip").args([
            "install",
            "--quiet",
            "pedalboard",
            "mido",
            "numpy",
        ]))?;
    }
    Ok(python)
}

/// `cargo xtask test`: every test of the project (the README's test command):
/// bundles the plugin three ways (release; rt-checks with the test-only
/// alloc-bug trigger; the test-only panic-bug),
/// runs the workspace tests (plugin-tests load those bundles), then renders
/// the VST3 with pedalboard.
fn run_tests(extra: &[String]) -> Result<()> {
    nice_plug_xtask::chdir_workspace_root()?;
    let python = ensure_venv()?;
    let mut dirs = Vec::new();
    for (name, args) in TEST_BUNDLES {
        dirs.push((name, bundle_to(name, args)?));
    }
    // The numerical tests run long loops (1e6 samples with per-sample energy
    // checks): release mode keeps them fast; debug assertions stay on.
    // --no-fail-fast: a failure in one test binary still runs the others
    // (the plugin tests included); the VST3 test runs either way.
    let mut cmd = std::process::Command::new("cargo");
    cmd.args([
        "test",
        "--workspace",
        "--profile",
        "test-release",
        "--no-fail-fast",
    ])
    .args(extra);
    for (name, dir) in &dirs {
        cmd.env(
            format!(
                "MODAL_CONTACT_CLAP_{}",
                name.to_uppercase().replace('-', "_")
            ),
            dir.join("modal_contact.clap"),
        );
    }
    let cargo_tests = run(&mut cmd);
    // The VST3 test compares with the library through this binary.
    run(std::process::Command::new("cargo").args([
        "build",
        "--package",
        "plugin-tests",
        "--profile",
        "test-release",
        "--bin",
        "render-reference",
    ]))?;
    let release = &dirs
        .iter()
        .find(|(n, _)| *n == "release")
        .expect("release")
        .1;
    let vst3_test = run(std::process::Command::new(&python)
        .arg("plugin-tests/vst3/test_vst3.py")
        .env("MODAL_CONTACT_VST3", release.join("modal_contact.vst3"))
        .env(
            "MODAL_CONTACT_REFERENCE",
            "target/test-release/render-reference",
        ));
    cargo_tests?;
    vst3_test
}

/// `cargo xtask demo`: bundle the release plugin and render the demo through
/// the built CLAP plugin (plugin-tests' host) into `target/demo/`.
fn run_demo() -> Result<()> {
    nice_plug_xtask::chdir_workspace_root()?;
    nice_plug_xtask::main_with_args(
        "cargo xtask",
        ["bundle", "modal_contact", "--release"].map(String::from),
    )?;
    run(std::process::Command::new("cargo").args([
        "run",
        "--package",
        "plugin-tests",
        "--release",
        "--bin",
        "render-demo",
        "--",
        "target/bundled/modal_contact.clap",
        "target/demo",
    ]))
}

fn run_render(a: RenderArgs) -> Result<()> {
    let scene = Scene::from_file(&a.scene).with_context(|| format!("{}", a.scene.display()))?;
    let switching = match a.switching.as_deref() {
        None => None,
        Some(s) => match Switching::parse(s) {
            Some(sw) => Some(sw),
            None => bail!("--switching must be offset-rod or exact, got {s:?}"),
        },
    };
    let opts = RenderOptions {
        rate_hz: a.rate,
        seconds: a.seconds,
        switching,
        trace: true,
    };
    let t0 = std::time::Instant::now();
    let out = render(&scene, &opts)?;
    let elapsed = t0.elapsed().as_secs_f64();
    eprint!("{}", out.summary);
    let n = out.left.len();
    let peak = out
        .left
        .iter()
        .chain(&out.right)
        .fold(0.0f64, |m, x| m.max(x.abs()));
    eprintln!(
        "rendered {n} samples ({:.3} s) in {elapsed:.3} s with trace; {} contacts; peak {peak:.3e}",
        n as f64 / a.rate,
        out.contacts
    );
    if out.exact_stats != Default::default() {
        eprintln!("{}", out.switching_line());
    }
    if !out.left.iter().chain(&out.right).all(|x| x.is_finite()) {
        bail!("render produced non-finite samples");
    }
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: a.rate.round() as u32,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(&a.out, spec)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    for (l, r) in out.left.iter().zip(&out.right) {
        w.write_sample(*l as f32)?;
        w.write_sample(*r as f32)?;
    }
    w.finalize()?;
    eprintln!("wrote {}", a.out.display());
    let rows = out.trace.as_ref().expect("trace requested");
    if let Some(path) = &a.trace {
        let f = std::fs::File::create(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        write_trace_csv(rows, std::io::BufWriter::new(f))?;
        eprintln!("wrote {}", path.display());
    }
    let plot_path = a
        .plot
        .clone()
        .unwrap_or_else(|| a.out.with_extension("svg"));
    plot::plot_trace(rows, &scene.name, &plot_path)?;
    eprintln!("wrote {}", plot_path.display());
    Ok(())
}
