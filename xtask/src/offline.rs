//! One offline job and what every offline command shares: note and
//! velocity lists, a note played through the instrument exactly as the
//! plugin plays it, and WAV writing.
//!
//! Every job is a pure function of its scene file and its parameters: the
//! engine and the instrument are deterministic (no clock, no thread, no
//! random number enters a render), so the same job gives the same bytes on
//! the same build and CPU (docs/design.md, "Offline rendering").

use anyhow::{bail, Context, Result};
use modal_contact::instrument::{
    prepare_scene, Event, Instrument, InstrumentParams, Prepared, TimedEvent,
};
use modal_contact::scene::Scene;
use std::path::Path;
use std::time::Instant;

/// A list of MIDI numbers as the command line writes it: comma-separated
/// items, each a number `60` or an inclusive range `36..96`, optionally
/// every `step`-th (`36..96:3`). `lo..=hi` bounds every value (notes 0-127,
/// velocities 1-127). Order is kept; duplicates are refused.
pub fn parse_midi_list(spec: &str, what: &str, lo: u8, hi: u8) -> Result<Vec<u8>> {
    let mut out: Vec<u8> = Vec::new();
    let num = |s: &str| -> Result<u8> {
        let v: i64 = s
            .trim()
            .parse()
            .with_context(|| format!("{what} list {spec:?}: {s:?} is not a number"))?;
        if v < i64::from(lo) || v > i64::from(hi) {
            bail!("{what} list {spec:?}: {v} is outside {lo}..={hi}");
        }
        Ok(v as u8)
    };
    for item in spec.split(',').map(str::trim) {
        if item.is_empty() {
            bail!("{what} list {spec:?}: empty item");
        }
        let (range, step) = match item.split_once(':') {
            Some((r, s)) => {
                let step: usize = s
                    .trim()
                    .parse()
                    .with_context(|| format!("{what} list {spec:?}: step {s:?}"))?;
                if step == 0 {
                    bail!("{what} list {spec:?}: step must be at least 1");
                }
                (r, step)
            }
            None => (item, 1),
        };
        match range.split_once("..") {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b.trim_start_matches('='))?);
                if a > b {
                    bail!("{what} list {spec:?}: range {a}..{b} is empty");
                }
                out.extend((a..=b).step_by(step));
            }
            None if step == 1 => out.push(num(range)?),
            None => bail!("{what} list {spec:?}: a step needs a range (a..b:step)"),
        }
    }
    let mut seen = [false; 256];
    for &v in &out {
        if std::mem::replace(&mut seen[v as usize], true) {
            bail!("{what} list {spec:?}: {v} appears twice");
        }
    }
    Ok(out)
}

/// `n` velocity layers over MIDI velocities 1..=127: the inclusive range of
/// each, lowest first, as equal as integer bounds allow (the top layer
/// ends at 127).
pub fn velocity_layers(n: usize) -> Result<Vec<(u8, u8)>> {
    if !(1..=127).contains(&n) {
        bail!("velocity layers must be 1..=127, got {n}");
    }
    Ok((0..n)
        .map(|i| {
            let lo = 1 + (127 * i) / n;
            let hi = (127 * (i + 1)) / n;
            (lo as u8, hi as u8)
        })
        .collect())
}

/// The normalised velocity the plugin receives for MIDI velocity `v`
/// (nice-plug divides the 7-bit velocity by 127 in f32).
pub fn velocity_norm(v: u8) -> f64 {
    (f32::from(v) / 127.0) as f64
}

/// A note played through the instrument.
#[derive(Debug, Clone)]
pub struct NoteRender {
    /// Output channels, as the plugin writes them (f32, after the gain).
    pub left: Vec<f32>,
    /// See `left`.
    pub right: Vec<f32>,
    /// Contacts that started, over every voice.
    pub contacts: u64,
    /// The compile summary of the scene played.
    pub summary: String,
    /// Routes of the free and contact phases' decompositions.
    pub routes: [String; 2],
    /// A note when the scene fell back to the offset rod.
    pub fallback_note: Option<String>,
    /// Seconds spent rendering.
    pub render_s: f64,
}

/// Prepare `base` as the plugin would with the parameters `params`
/// (mapping, compile fallback, damped scene).
pub fn prepare_for(
    base: &Scene,
    params: &InstrumentParams,
    rate_hz: f64,
) -> Result<(Box<Prepared>, f64)> {
    let t0 = Instant::now();
    let prepared = prepare_scene(base, &params.scene, rate_hz, 0).map_err(anyhow::Error::msg)?;
    Ok((prepared, t0.elapsed().as_secs_f64()))
}

/// Strike `note` at MIDI velocity `velocity` at sample 0 and render
/// `samples` samples (no note-off: the note rings as a one-shot), through
/// the same instrument code, velocity and pitch mapping and voices as the
/// plugin.
pub fn play_note(
    prepared: &Prepared,
    params: &InstrumentParams,
    note: u8,
    velocity: u8,
    samples: usize,
) -> NoteRender {
    play_notes(prepared, params, &[note], velocity, samples)
}

/// Strike every note of `notes` at MIDI velocity `velocity` together at
/// sample 0 (a chord; in this order, on the same sample) and render
/// `samples` samples, as [`play_note`] does one.
pub fn play_notes(
    prepared: &Prepared,
    params: &InstrumentParams,
    notes: &[u8],
    velocity: u8,
    samples: usize,
) -> NoteRender {
    // a kit (docs/design.md, "Played as a kit"): its own summary
    let summary = prepared
        .kit
        .as_ref()
        .map_or_else(|| prepared.scenes.scene.summary.clone(), |k| k.summary());
    let routes = [
        prepared.scenes.scene.free.diag.method.clone(),
        prepared.scenes.scene.contact.diag.method.clone(),
    ];
    let fallback_note = prepared.fallback_note.clone();
    let mut inst = Instrument::new(Box::new(prepared.clone()), params.play);
    let mut left = vec![0.0f32; samples];
    let mut right = vec![0.0f32; samples];
    let t0 = Instant::now();
    let on: Vec<TimedEvent> = notes
        .iter()
        .map(|&key| TimedEvent {
            offset: 0,
            event: Event::NoteOn {
                key,
                velocity_norm: velocity_norm(velocity),
            },
        })
        .collect();
    inst.process(&on, &mut left, &mut right);
    let render_s = t0.elapsed().as_secs_f64();
    let contacts = match &inst.prepared().kit {
        Some(k) => k.contacts_started().iter().sum(),
        None => (0..modal_contact::instrument::MAX_VOICES)
            .map(|v| inst.voice_state_mut(v).contacts_started)
            .sum(),
    };
    NoteRender {
        left,
        right,
        contacts,
        summary,
        routes,
        fallback_note,
        render_s,
    }
}

/// The note that plays a scene as written: its root
/// ([`modal_contact::instrument::root_note`], rounded), what `cargo xtask
/// render --velocities` strikes when no notes are given.
pub fn root_key(scene: &Scene) -> u8 {
    modal_contact::instrument::root_note(scene)
        .round()
        .clamp(0.0, 127.0) as u8
}

/// The sample format of a written WAV.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WavFormat {
    /// 32-bit float (the render command's format).
    Float32,
    /// 24-bit integer PCM (what hardware and most software samplers read).
    Pcm24,
}

/// Write a stereo WAV. Refuses non-finite samples; 24-bit PCM refuses
/// samples beyond full scale (the caller scales first) instead of clipping.
pub fn write_wav(
    path: &Path,
    rate_hz: f64,
    left: &[f32],
    right: &[f32],
    format: WavFormat,
) -> Result<()> {
    if let Some(i) = left.iter().chain(right).position(|x| !x.is_finite()) {
        bail!("{}: sample {i} is not finite", path.display());
    }
    let (bits, sample_format) = match format {
        WavFormat::Float32 => (32, hound::SampleFormat::Float),
        WavFormat::Pcm24 => (24, hound::SampleFormat::Int),
    };
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: rate_hz.round() as u32,
        bits_per_sample: bits,
        sample_format,
    };
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut w = hound::WavWriter::new(std::io::BufWriter::new(file), spec)?;
    const FULL: f64 = 8_388_607.0;
    for (l, r) in left.iter().zip(right) {
        for x in [*l, *r] {
            match format {
                WavFormat::Float32 => w.write_sample(x)?,
                WavFormat::Pcm24 => {
                    if x.abs() > 1.0 {
                        bail!(
                            "{}: sample {x} beyond full scale for 24-bit PCM",
                            path.display()
                        );
                    }
                    w.write_sample((f64::from(x) * FULL).round() as i32)?;
                }
            }
        }
    }
    w.finalize()?;
    Ok(())
}

/// Fail early when `path` cannot be written: its directory must exist (or
/// be creatable when `create_dirs`) and the file must be creatable. Leaves
/// no file behind that was not there.
pub fn check_writable(path: &Path, create_dirs: bool) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        if create_dirs {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create directory {}", dir.display()))?;
        } else {
            bail!(
                "{}: directory {} does not exist",
                path.display(),
                dir.display()
            );
        }
    }
    if path.is_dir() {
        bail!("{} is a directory", path.display());
    }
    let existed = path.exists();
    std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    if !existed {
        let _ = std::fs::remove_file(path);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_parse_items_ranges_and_steps() {
        assert_eq!(parse_midi_list("60", "note", 0, 127).unwrap(), [60]);
        assert_eq!(
            parse_midi_list("60, 64,67", "note", 0, 127).unwrap(),
            [60, 64, 67]
        );
        assert_eq!(
            parse_midi_list("36..45:3", "note", 0, 127).unwrap(),
            [36, 39, 42, 45]
        );
        assert_eq!(
            parse_midi_list("1..3,100", "velocity", 1, 127).unwrap(),
            [1, 2, 3, 100]
        );
        for bad in ["", "a", "0", "128", "5..3", "60,60", "60:2", "1..4:0"] {
            assert!(
                parse_midi_list(bad, "velocity", 1, 127).is_err(),
                "{bad:?} accepted"
            );
        }
    }

    #[test]
    fn velocity_layers_cover_1_to_127_without_gaps() {
        for n in 1..=127 {
            let l = velocity_layers(n).unwrap();
            assert_eq!(l.len(), n);
            assert_eq!(l[0].0, 1);
            assert_eq!(l[n - 1].1, 127);
            for w in l.windows(2) {
                assert_eq!(w[0].1 + 1, w[1].0);
            }
            assert!(l.iter().all(|(a, b)| a <= b));
        }
        assert_eq!(
            velocity_layers(4).unwrap(),
            [(1, 31), (32, 63), (64, 95), (96, 127)]
        );
        assert!(velocity_layers(0).is_err() && velocity_layers(128).is_err());
    }

    #[test]
    fn velocity_norm_is_what_the_plugin_receives() {
        assert_eq!(velocity_norm(127), 1.0);
        assert_eq!(velocity_norm(0), 0.0);
        assert_eq!(velocity_norm(64), (64.0f32 / 127.0) as f64);
    }

    #[test]
    fn unwritable_paths_are_refused_before_work() {
        let dir = std::env::temp_dir().join(format!("xtask-offline-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert!(check_writable(&dir.join("missing/x.wav"), false).is_err());
        assert!(check_writable(&dir, false).is_err());
        let ok = dir.join("x.wav");
        check_writable(&ok, false).unwrap();
        assert!(!ok.exists(), "the check left a file behind");
        check_writable(&dir.join("made/y.wav"), true).unwrap();
        assert!(dir.join("made").is_dir());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
