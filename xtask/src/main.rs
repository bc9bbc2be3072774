//! `cargo xtask`: bundle the plugin (nice-plug-xtask), render scenes
//! offline, run every test, the report and the golden renders.
//!
//! - `cargo xtask bundle modal_contact --release` -> `target/bundled/*.clap, *.vst3`
//!   (any command not below goes to nice-plug's xtask)
//! - `cargo xtask render SCENE.toml --out OUT.wav [--trace OUT.csv] [--plot [OUT.svg]]
//!   [--seconds S] [--rate HZ] [--switching offset-rod|exact]`; a batch:
//!   `cargo xtask render SCENES_OR_DIRS... --out DIR [--notes LIST]
//!   [--velocities LIST] [--jobs N]`
//! - `cargo xtask multisample SCENE.toml --notes 36..96 --step 3
//!   --velocities 4 --out DIR`: WAVs and an SFZ file for any sampler`
//! - `cargo xtask test [CARGO TEST ARGS]`: every test, including the plugin
//!   tests on the built bundles, the core built without the plugin
//!   (`examples/embed.rs`) and the VST3 tests through pedalboard and in
//!   Ardour
//! - `cargo xtask demo`: bundle (release) and render a demo through the built
//!   CLAP plugin into `target/demo/*.wav`, and each preset that names a real
//!   instrument into `target/demo/real/NAME.wav` beside its recording
//!   (`NAME-real.wav`, from the FluidR3 soundfont when it is installed)
//! - `cargo xtask report [--quick] [--out DIR] [--only SECTION] [--scene NAME]`
//! - `cargo xtask benchmarks [--out docs/benchmarks.md] [--quick] [--only
//!   NAME]...`: runs the measurement benches and writes the tables they
//!   print to `docs/benchmarks.md`, stamped with machine, OS, compiler and
//!   date
//! - `cargo xtask golden [--write]`: bit-identical renders against
//!   `tests/golden-hashes.txt`
//! - `cargo xtask param-docs [--check]`: the parameter and scene tables of
//!   `docs/plugin.md`, from the plugin's own lists
//! - `cargo xtask compare-real [--preset NAME]... [--out DIR] [--sf2 PATH]
//!   [--check] [--seconds S]`: the presets that name a real instrument
//!   against its recorded samples in the FluidR3 General MIDI soundfont
//!   (`docs/compare-real.md`, plots in `docs/compare-real/`, WAV pairs in
//!   `target/compare-real/`)
//! - `cargo xtask analyze STRIKE.wav --out OBJECT.toml [--channel N]
//!   [--start S] [--end S] [--modes N] [--min-freq HZ] [--max-freq HZ]
//!   [--mallet-kg KG] [--name NAME]`: the modes of a struck object from a
//!   recording of one strike, as a scene file, with a report (modes, poles
//!   dropped, the resynthesis's distance and residual)
//! - `cargo xtask analyze-real [--instrument NAME]... [--out
//!   docs/analyze-real.md] [--sf2 PATH] [--scenes DIR] [--check]` and
//!   `analyze`'s options: that analysis of FluidR3's recorded samples of
//!   nine struck instruments, each scene's render against its recording
//!   (target: 3 dB on the 1/3-octave distance; `docs/analyze-real.md`,
//!   the scenes and recordings in `target/analyze-real/`)
//! - `cargo xtask levels [--check] [--write] [--out docs/levels.md]
//!   [--presets DIR]`: each preset's loudness and peaks at velocity 100,
//!   and the `level_db` that puts it at the common target
//!   (`docs/levels.md`; `--write` sets the presets' levels)

mod golden;
mod paramdocs;

use xtask::{analyze, analyze_real, benchmarks, compare_real, levels, multisample, render, report};

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use modal_testkit::bundles::{copy_bundles, BUNDLES, BUNDLE_NAME};
use std::path::{Path, PathBuf};

/// The project's tasks.
#[derive(Parser, Debug)]
#[command(
    name = "cargo xtask",
    bin_name = "cargo xtask",
    after_help = "Any other command goes to nice-plug's xtask, e.g. `cargo xtask bundle modal_contact --release`."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Offline render: one scene file to a WAV (trace CSV and plot if
    /// asked), or a batch of scene files, directories, notes and
    /// velocities on all cores with a JSON sidecar per WAV.
    Render(render::RenderArgs),
    /// Every note x velocity layer of a scene through the instrument, as
    /// 24-bit WAVs and an SFZ file for any sampler.
    Multisample(multisample::MultisampleArgs),
    /// Error against run time of the engine and the usual integrators, the
    /// stability table and the f32 study (writes report/report.md).
    Report(report::ReportArgs),
    /// Run the measurement benches (engine, worst block, several contacts,
    /// render command, activation, the stiff cases) and write the tables
    /// they print to docs/benchmarks.md, each section stamped with the
    /// machine, OS, compiler and date of its run. Relative paths are from
    /// the workspace root.
    Benchmarks(benchmarks::BenchmarksArgs),
    /// Every test: checks the core without the plugin, bundles the plugin
    /// three ways, runs the allocation tests and examples/embed.rs, the
    /// workspace tests (the plugin tests load those bundles), then the VST3
    /// tests (pedalboard, Ardour).
    Test(TestArgs),
    /// Bundle the release plugin and render a demo through the built CLAP
    /// plugin into target/demo/; each preset that names a real instrument
    /// into target/demo/real/NAME.wav beside its recording, NAME-real.wav
    /// (FluidR3 soundfont, Debian package fluid-soundfont-gm, if installed).
    Demo,
    /// Check that every preset and stability case renders bit-identically
    /// to tests/golden-hashes.txt.
    Golden(golden::GoldenArgs),
    /// Write the parameter and scene tables of docs/plugin.md from the
    /// plugin's own lists.
    ParamDocs(ParamDocsArgs),
    /// Compare every preset that names a real instrument with its recorded
    /// samples in the FluidR3 General MIDI soundfont (Debian package
    /// fluid-soundfont-gm): partials, decay times, attack brightness,
    /// 1/3-octave distance, a confusion table and the targets of issue 49
    /// (writes docs/compare-real.md and its plots).
    CompareReal(compare_real::CompareRealArgs),
    /// Each preset's loudness (EBU R128) and peaks struck at velocity 100,
    /// a 16-note chord's peak, and the level_db that puts it at the
    /// common target (writes docs/levels.md; --write sets the presets'
    /// level_db, --check fails on a preset off its level or a clipping
    /// chord).
    Levels(levels::LevelsArgs),
    /// The modes of a struck object from a recording of one strike (WAV),
    /// written as a scene file with that object, a mallet and a pickup;
    /// prints the modes, the poles dropped and why, and how near the
    /// resynthesis and the scene's render come to the recording.
    Analyze(analyze::AnalyzeArgs),
    /// The analysis of `analyze` on FluidR3's recorded samples of nine
    /// struck instruments (marimba to timpani), each analysed scene's
    /// render against its recording on the 1/3-octave distance (target
    /// 3 dB); writes docs/analyze-real.md, and the scenes and recordings
    /// into target/analyze-real/.
    AnalyzeReal(analyze_real::AnalyzeRealArgs),
    /// Anything else: nice-plug's xtask (`bundle`, `bundle-universal`, ...).
    #[command(external_subcommand)]
    NicePlug(Vec<String>),
}

/// `cargo xtask param-docs [--check]`.
#[derive(Args, Debug)]
struct ParamDocsArgs {
    /// Fail (showing the first differing line) instead of writing when
    /// docs/plugin.md is not what the lists generate.
    #[arg(long)]
    check: bool,
}

/// `cargo xtask test [CARGO TEST ARGS]`.
#[derive(Args, Debug)]
struct TestArgs {
    /// Passed to `cargo test --workspace --profile test-release
    /// --no-fail-fast` as written (e.g. `--test numerics stability:: --
    /// --nocapture`); without them, that run leaves xtask's own tests to
    /// `cargo test --release -p xtask`.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    cargo_test_args: Vec<String>,
}

fn main() -> Result<()> {
    let argv: Vec<String> = std::env::args().collect();
    match Cli::parse_from(&argv).command {
        Some(Command::Render(a)) => render::run(&a),
        Some(Command::Multisample(a)) => multisample::run(&a),
        Some(Command::Report(a)) => report::run(a),
        Some(Command::Benchmarks(a)) => {
            nice_plug_xtask::chdir_workspace_root()?;
            benchmarks::run(&a)
        }
        // The arguments go to cargo test verbatim: clap drops the `--` of
        // `cargo xtask test -- --nocapture`, which cargo test needs.
        Some(Command::Test(_)) => run_tests(&argv[2..]),
        Some(Command::Demo) => run_demo(),
        Some(Command::Golden(a)) => golden::run(a),
        Some(Command::ParamDocs(a)) => paramdocs::run(a.check),
        Some(Command::CompareReal(a)) => compare_real::run(&a),
        Some(Command::Levels(a)) => levels::run(&a),
        Some(Command::Analyze(a)) => analyze::run(&a),
        Some(Command::AnalyzeReal(a)) => analyze_real::run(&a),
        Some(Command::NicePlug(args)) => nice_plug_xtask::main_with_args("cargo xtask", args),
        None => nice_plug_xtask::main(),
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

/// `cargo xtask bundle modal_contact ARGS` in-process, then copy the result
/// out of the shared `target/bundled/` to `target/plugin-tests/NAME/`.
fn bundle_to(name: &str, args: &[&str]) -> Result<PathBuf> {
    let mut all = vec!["bundle".to_string(), BUNDLE_NAME.to_string()];
    all.extend(args.iter().map(|a| a.to_string()));
    eprintln!("+ cargo xtask {}", all.join(" "));
    nice_plug_xtask::main_with_args("cargo xtask", all)?;
    let out = PathBuf::from("target/plugin-tests").join(name);
    copy_bundles(Path::new("target/bundled"), &out)
        .with_context(|| format!("copying target/bundled to {}", out.display()))?;
    Ok(std::fs::canonicalize(&out)?)
}

/// The Python venv for the VST3 test (pedalboard, mido, numpy) and the
/// NPY trace's test (numpy).
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
/// checks the core without the plugin and bundles the plugin three ways
/// (the test-only panic-bug; rt-checks with the test-only alloc-bug
/// trigger; release), runs the allocation tests and the embedding example
/// on the first of them ([`run_alloc_tests`], [`run_embed`]), builds the
/// allocation-checked standalone application for the editor test and the
/// reference renderer for the VST3 test, runs the workspace tests
/// (plugin-tests load those bundles), then renders the VST3 with
/// pedalboard and in Ardour.
fn run_tests(extra: &[String]) -> Result<()> {
    nice_plug_xtask::chdir_workspace_root()?;
    let python = ensure_venv()?;
    check_core()?;
    let mut dirs = Vec::new();
    let mut unchecked = Vec::new();
    for b in &BUNDLES {
        dirs.push((b, bundle_to(b.name, b.cargo_args)?));
        if b.name == "panic-bug" {
            // the tests that need a build without the allocation checker,
            // on this bundle's compilation of the crate before the next
            // bundle's features overwrite its library (`BUNDLES`)
            unchecked.push(run_alloc_tests(b.cargo_args));
            unchecked.push(run_embed(b.cargo_args));
        }
    }
    // The editor test runs the standalone application with the allocation
    // checker (plugin-tests/tests/editor_gui.rs); the VST3 test compares
    // with the library through `render-reference`. Both reuse the checked
    // bundle's compilation of the plugin crate, the last of the
    // test-release builds of the crate's library (`BUNDLES`).
    run(std::process::Command::new("cargo").args(modal_testkit::bundles::STANDALONE_BUILD_ARGS))?;
    run(std::process::Command::new("cargo").args([
        "build",
        "--package",
        "plugin-tests",
        "--profile",
        "test-release",
        "--bin",
        "render-reference",
        "--features",
        modal_testkit::bundles::TEST_FEATURES_ARG,
    ]))?;
    // The numerical tests run long loops (1e6 samples with per-sample energy
    // checks): release mode keeps them fast; debug assertions stay on.
    // --no-fail-fast: a failure in one test binary still runs the others
    // (the plugin tests included); the VST3 test runs either way.
    // The whole suite runs xtask's own tests apart, in the release profile
    // that `cargo xtask` itself was built in ([`xtask_tests`]); tests named
    // in `extra` run as written, xtask's among them.
    let whole = extra.is_empty();
    let mut cmd = std::process::Command::new("cargo");
    cmd.args([
        "test",
        "--workspace",
        "--profile",
        "test-release",
        "--no-fail-fast",
        "--features",
        modal_testkit::bundles::TEST_FEATURES_ARG,
    ])
    .args(if whole {
        &["--exclude", "xtask"][..]
    } else {
        &[]
    })
    .args(extra);
    for (b, dir) in &dirs {
        cmd.env(b.env_var(), dir.join(format!("{BUNDLE_NAME}.clap")));
    }
    // NumPy reads the NPY trace (xtask/tests/trace_npy.rs); the path is
    // absolute but not canonical (the venv is found through its symlink).
    cmd.env(
        "MODAL_CONTACT_PYTHON",
        std::env::current_dir()?.join(&python),
    );
    cmd.env(
        "MODAL_CONTACT_STANDALONE",
        std::env::current_dir()?
            .join("target/test-release")
            .join(modal_testkit::bundles::STANDALONE_BIN),
    );
    let cargo_tests = run(&mut cmd);
    let xtask_tests = if whole { xtask_tests(&python) } else { Ok(()) };
    let release = &dirs
        .iter()
        .find(|(b, _)| b.name == "release")
        .expect("release")
        .1;
    // The VST3 in pedalboard, then the same bundle in a real DAW: Ardour 7,
    // headless (Debian's `ardour`); both compare with the library.
    let host_test = |script: &str| {
        run(std::process::Command::new(&python)
            .arg(script)
            .env(
                "MODAL_CONTACT_VST3",
                release.join(format!("{BUNDLE_NAME}.vst3")),
            )
            .env(
                "MODAL_CONTACT_REFERENCE",
                "target/test-release/render-reference",
            ))
    };
    let vst3_test = host_test("plugin-tests/vst3/test_vst3.py");
    let ardour_test = host_test("plugin-tests/ardour/test_ardour.py");
    cargo_tests?;
    xtask_tests?;
    for r in unchecked {
        r?;
    }
    vst3_test?;
    ardour_test
}

/// xtask's own tests (the commands' arguments, batch renders, levels, the
/// NPY trace read by NumPy from `python`'s venv) in the release profile:
/// they test the commands as `cargo xtask` builds them and reuse that
/// build's compilation of the plugin crate and its dependencies instead of
/// compiling xtask's own (the soundfont parser, plots, cargo's metadata)
/// once more in `test-release` (docs/design.md, "Tests, checks and measurements").
fn xtask_tests(python: &Path) -> Result<()> {
    run(std::process::Command::new("cargo")
        .args(["test", "--release", "-p", "xtask", "--no-fail-fast"])
        .env(
            "MODAL_CONTACT_PYTHON",
            std::env::current_dir()?.join(python),
        ))
}

/// The core without the plugin (README, "Embedding"; docs/design.md,
/// "Layers"): the library and `examples/embed.rs` checked with
/// `--no-default-features`, so nothing of the core names nice-plug, egui,
/// rfd, directories or clap-sys (`-p`, since the workspace's other crates
/// turn the plugin on). A check, not a build: it shares the clippy step's
/// checked dependencies (feature-union/Cargo.toml) instead of compiling the
/// crate once more; the example and the doctest run in the builds with the
/// plugin ([`run_embed`], the workspace's tests), the same code.
fn check_core() -> Result<()> {
    run(std::process::Command::new("cargo").args([
        "check",
        "-p",
        "modal_contact",
        "--no-default-features",
        "--lib",
        "--example",
        "embed",
    ]))
}

/// The allocation tests (`tests/kit_alloc.rs`, `tests/multi_alloc.rs`):
/// each installs a counting global allocator, so both are empty in the
/// workspace's build with `rt-checks` (whose allocation checker is that
/// build's global allocator) and run here, with `bundle_args`, a bundle's
/// arguments without the checker (its compilation of the crate reused).
fn run_alloc_tests(bundle_args: &[&str]) -> Result<()> {
    run(std::process::Command::new("cargo")
        .args(["test", "-p", "modal_contact"])
        .args(bundle_args)
        .args(["--test", "kit_alloc", "--test", "multi_alloc"]))
}

/// `examples/embed.rs` (the README's embedding path) built with
/// `bundle_args` (a bundle's arguments: its compilation of the crate
/// reused) writing a WAV file that is read back (stereo, 48 kHz, 2 s,
/// finite, not silent) for a scene of one contact and one of several, and
/// refusing a missing scene file with exit code 1 and a message.
fn run_embed(bundle_args: &[&str]) -> Result<()> {
    let dir = Path::new("target/embed");
    std::fs::create_dir_all(dir)?;
    let example = |args: &[&Path]| {
        let mut cmd = std::process::Command::new("cargo");
        cmd.args(["run", "-p", "modal_contact"])
            .args(bundle_args)
            .args(["--example", "embed", "--"])
            .args(args);
        cmd
    };
    // one contact, and several (the several-contact route)
    for name in ["marimba-bar", "wind-chimes"] {
        let wav = dir.join(format!("{name}.wav"));
        if wav.exists() {
            std::fs::remove_file(&wav)?;
        }
        let scene = PathBuf::from(format!("presets/{name}.toml"));
        run(&mut example(&[&scene, &wav]))?;
        check_embed_wav(&wav)?;
    }
    let missing = dir.join("no-such-scene.toml");
    let mut cmd = example(&[&missing, &dir.join("missing.wav")]);
    eprintln!("+ {cmd:?}");
    let out = cmd
        .output()
        .with_context(|| format!("cannot run {cmd:?}"))?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() != Some(1) || !stderr.contains("embed: cannot read") {
        bail!(
            "the example should refuse a missing scene with exit code 1 and a message; {}:\n{stderr}",
            out.status
        );
    }
    Ok(())
}

/// The WAV file `examples/embed.rs` wrote: stereo, 48 kHz, 2 s, finite,
/// not silent.
fn check_embed_wav(wav: &Path) -> Result<()> {
    let mut reader =
        hound::WavReader::open(wav).with_context(|| format!("reading {}", wav.display()))?;
    let spec = reader.spec();
    let samples: Vec<f32> = reader.samples::<f32>().collect::<Result<_, _>>()?;
    let peak = samples.iter().fold(0.0_f32, |m, x| m.max(x.abs()));
    println!(
        "{}: {} channels, {} Hz, {} samples, peak {peak:.3e}",
        wav.display(),
        spec.channels,
        spec.sample_rate,
        samples.len()
    );
    if spec.channels != 2 || spec.sample_rate != 48_000 || samples.len() != 2 * 2 * 48_000 {
        bail!("{}: not 2 s of stereo at 48 kHz: {spec:?}", wav.display());
    }
    if samples.iter().any(|x| !x.is_finite()) || !(peak > 1e-4) {
        bail!("{}: silent or not finite (peak {peak:e})", wav.display());
    }
    Ok(())
}

/// `cargo xtask demo`: bundle the release plugin and render the demo through
/// the built CLAP plugin (plugin-tests' host) into `target/demo/`, the
/// presets that name a real instrument into `target/demo/real/`, and beside
/// each the recording `cargo xtask compare-real` compares it with
/// ([`compare_real::demo_recordings`]; without the soundfont, one line
/// says which package holds it).
fn run_demo() -> Result<()> {
    nice_plug_xtask::chdir_workspace_root()?;
    nice_plug_xtask::main_with_args(
        "cargo xtask",
        ["bundle", BUNDLE_NAME, "--release"].map(String::from),
    )?;
    run(std::process::Command::new("cargo").args([
        "run",
        "--package",
        "plugin-tests",
        "--release",
        "--bin",
        "render-demo",
        "--",
        &format!("target/bundled/{BUNDLE_NAME}.clap"),
        "target/demo",
    ]))?;
    let lines = compare_real::demo_recordings(
        Path::new("target/demo/real"),
        Path::new(compare_real::DEFAULT_SF2),
    )?;
    for l in lines {
        println!("{l}");
    }
    Ok(())
}
