//! The core embedded in an application, without the plugin: load a scene
//! file (one to four contacts), compile it at 48 kHz, throw each of its
//! mallets at the object, process 2 s in blocks of 64 samples and write a
//! 32-bit float stereo WAV file.
//!
//! ```sh
//! cargo run -p modal_contact --release --no-default-features --example embed -- [SCENE.toml] [OUT.wav]
//! ```
//!
//! The scene defaults to `presets/marimba-bar.toml`, the output to
//! `embed.wav`. A scene that cannot be read, parsed or compiled is
//! reported with its error (naming the field) and exit code 1.

use modal_contact::{compile, Scene, StrikeError, Voice};
use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const RATE_HZ: u32 = 48_000;
const BLOCK: usize = 64;
const SECONDS: usize = 2;
/// The hammer's speed at the strike \[m/s\], downwards.
const STRIKE_M_PER_S: f64 = 2.0;

fn main() -> ExitCode {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    if args.len() > 2 || args.iter().any(|a| a.to_string_lossy().starts_with('-')) {
        eprintln!("usage: embed [SCENE.toml] [OUT.wav]");
        return ExitCode::FAILURE;
    }
    let scene = args
        .first()
        .cloned()
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("presets/marimba-bar.toml"));
    let out = args.get(1).cloned().unwrap_or_else(|| "embed.wav".into());
    match run(&scene, &out) {
        Ok(peak) => {
            println!(
                "{}: {SECONDS} s at {RATE_HZ} Hz, peak {peak:.3e} -> {}",
                scene.display(),
                out.display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("embed: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Render `scene` into the WAV file `out`; the peak of both channels.
fn run(scene: &Path, out: &Path) -> Result<f64, Box<dyn Error>> {
    let text = std::fs::read_to_string(scene)
        .map_err(|e| format!("cannot read {}: {e}", scene.display()))?;
    let parsed = Scene::from_toml_str(&text).map_err(|e| format!("{}: {e}", scene.display()))?;
    let compiled = compile(&parsed, f64::from(RATE_HZ))
        .map_err(|e| format!("{} does not compile: {e}", scene.display()))?;
    let mut voice = Voice::new(&compiled);
    // every mallet put on the surface it strikes, moving down (a contact
    // between two objects has no mallet to throw)
    for contact in 0..compiled.contacts() {
        match voice.strike(&compiled, contact, 0.0, -STRIKE_M_PER_S) {
            Ok(()) | Err(StrikeError::NoMallet) => {}
            Err(e) => return Err(format!("contact {contact}: {e}").into()),
        }
    }

    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: RATE_HZ,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let cannot_write = |e: hound::Error| format!("cannot write {}: {e}", out.display());
    let mut wav = hound::WavWriter::create(out, spec).map_err(cannot_write)?;
    let (mut left, mut right) = ([0.0; BLOCK], [0.0; BLOCK]);
    let mut peak = 0.0_f64;
    for _ in 0..SECONDS * RATE_HZ as usize / BLOCK {
        voice.process_block(&compiled, &mut left, &mut right);
        for (&l, &r) in left.iter().zip(&right) {
            peak = peak.max(l.abs()).max(r.abs());
            wav.write_sample(l as f32).map_err(cannot_write)?;
            wav.write_sample(r as f32).map_err(cannot_write)?;
        }
    }
    wav.finalize().map_err(cannot_write)?;
    Ok(peak)
}
