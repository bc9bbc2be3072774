//! The WAV files: the recordings `cargo xtask demo` puts beside its
//! real-instrument renders, and each comparison's (recording, render)
//! pair.

use super::recordings::playable_key;
use super::*;

/// For `cargo xtask demo`: beside each `DIR/NAME.wav` the demo rendered
/// for a preset that names a real instrument (its strike at its root key,
/// velocity [`VELOCITY`], through the built plugin), the recording it is
/// compared with, as the comparison plays it (the soundfont's raw
/// samples for that key and velocity, transposed and resampled as a
/// sampler plays them, the zones mixed to mono, from the onset), as `DIR/NAME-real.wav` at [`RATE_HZ`] on both channels, scaled
/// to the render's EBU R128 integrated loudness so that a listener
/// compares the sounds, not their levels (its peak held at -1 dBFS if
/// that would be higher). Returns one line per preset. Without the
/// soundfont it writes nothing and returns one line naming the Debian
/// package: the demo does not need it.
pub fn demo_recordings(dir: &Path, sf2: &Path) -> Result<Vec<String>> {
    if !sf2.is_file() {
        return Ok(vec![format!(
            "no recordings beside the real-instrument demos: soundfont {} not found (Debian \
             package {SF2_PACKAGE})",
            sf2.display()
        )]);
    }
    let sf = SoundFont::open(sf2)?;
    let mut lines = Vec::new();
    for p in load_presets(&workspace_root().join("presets"))? {
        let Ok(Some(sound)) = p.real else { continue };
        let render_path = dir.join(format!("{}.wav", p.stem));
        let render = read_wav(&render_path)?;
        let key = playable_key(&sf, sound, p.key);
        let (bank, program) = sound.bank_program();
        let rec = match sf
            .key_region(bank, program, key, VELOCITY)
            .map_err(|e| format!("{e:#}"))
            .and_then(Recording::new)
        {
            Ok(r) => r,
            Err(e) => {
                lines.push(format!("{}: no recording ({e})", p.stem));
                continue;
            }
        };
        let x: Vec<f32> = rec.played.x.iter().map(|&v| v as f32).collect();
        let chans = [render.1.as_slice(), render.2.as_slice()];
        let want = crate::levels::loudness_lufs(&chans, render.0)?;
        let have = crate::levels::loudness_lufs(&[&x, &x], RATE_HZ)?;
        let peak = x.iter().fold(0.0f64, |m, v| m.max(f64::from(v.abs())));
        let mut gain = 10f64.powf((want - have) / 20.0);
        let mut held = "";
        if peak * gain > 10f64.powf(-1.0 / 20.0) {
            gain = 10f64.powf(-1.0 / 20.0) / peak;
            held = ", held at -1 dBFS peak";
        }
        if !gain.is_finite() {
            bail!("{}: a silent render or recording", render_path.display());
        }
        let y: Vec<f32> = x.iter().map(|&v| (f64::from(v) * gain) as f32).collect();
        let out = dir.join(format!("{}-real.wav", p.stem));
        crate::offline::write_wav(&out, RATE_HZ, &y, &y, crate::offline::WavFormat::Float32)?;
        let moved = if key == sound.key_for(p.key) {
            String::new()
        } else {
            format!(
                " (played at key {key}: at the preset's key {} it would be transposed by more \
                 than an octave)",
                p.key
            )
        };
        lines.push(format!(
            "wrote {}: {} key {} velocity {VELOCITY}{moved}, at the render's loudness {want:.1} \
             LUFS{held}",
            out.display(),
            sound.label(),
            sound.key_for(key),
        ));
    }
    Ok(lines)
}

/// A WAV's rate and its first two channels (one channel: both), as f32.
fn read_wav(path: &Path) -> Result<(f64, Vec<f32>, Vec<f32>)> {
    let mut r =
        hound::WavReader::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let spec = r.spec();
    let data: Vec<f32> = match spec.sample_format {
        hound::SampleFormat::Float => r.samples::<f32>().collect::<Result<_, _>>()?,
        hound::SampleFormat::Int => {
            let full = 2f32.powi(i32::from(spec.bits_per_sample) - 1);
            r.samples::<i32>()
                .map(|s| s.map(|v| v as f32 / full))
                .collect::<Result<_, _>>()?
        }
    };
    let c = usize::from(spec.channels.max(1));
    let left: Vec<f32> = data.iter().step_by(c).copied().collect();
    let right: Vec<f32> = if c > 1 {
        data.iter().skip(1).step_by(c).copied().collect()
    } else {
        left.clone()
    };
    Ok((f64::from(spec.sample_rate), left, right))
}

/// Write the recording and the render as `NAME-real.wav` and
/// `NAME-render.wav` (32-bit float, both peaks at -6 dBFS, the mono signal
/// on both channels).
pub(super) fn write_pair(dir: &Path, stem: &str, real: &[f64], render: &[f64]) -> Result<()> {
    for (what, x) in [("real", real), ("render", render)] {
        let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        let y: Vec<f32> = x.iter().map(|v| (0.5 * v / peak) as f32).collect();
        crate::offline::write_wav(
            &dir.join(format!("{stem}-{what}.wav")),
            RATE_HZ,
            &y,
            &y,
            crate::offline::WavFormat::Float32,
        )?;
    }
    Ok(())
}
