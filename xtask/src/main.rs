//! `cargo xtask`: bundle the plugin (nice-plug-xtask) and render scenes offline.
//!
//! - `cargo xtask bundle modal_contact --release` -> `target/bundled/*.clap, *.vst3`
//! - `cargo xtask render SCENE.toml --out OUT.wav [--trace OUT.csv] [--plot OUT.svg]
//!   [--seconds S] [--rate HZ] [--switching offset-rod|exact]` (DESIGN.md section 5)

mod plot;

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
        Some("test") => run_tests(&args[2..]),
        _ => nice_plug_xtask::main(),
    }
}

/// Run a command, failing with its exit status.
fn run(cmd: &mut std::process::Command) -> Result<()> {
    eprintln!("+ {cmd:?}");
    let status = cmd.status().with_context(|| format!("cannot run {cmd:?}"))?;
    if !status.success() {
        bail!("{cmd:?} failed: {status}");
    }
    Ok(())
}

/// `cargo xtask test`: every test of the project (the README's test command).
fn run_tests(extra: &[String]) -> Result<()> {
    nice_plug_xtask::chdir_workspace_root()?;
    // The numerical tests run long loops (1e6 samples with per-sample energy
    // checks): release mode keeps them fast; debug assertions stay on.
    run(std::process::Command::new("cargo")
        .args(["test", "--workspace", "--profile", "test-release"])
        .args(extra))?;
    Ok(())
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
