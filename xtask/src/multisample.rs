//! `cargo xtask multisample`: every sampled note x velocity layer of a scene,
//! played through the instrument as the plugin plays it, as 24-bit WAVs
//! plus an SFZ file that maps them (key ranges, velocity layers, root keys,
//! no release trigger, no loop), so the instrument can be played in any SFZ
//! sampler where the plugin cannot run (docs/design.md, "Multisample
//! export").

use crate::offline::{
    check_writable, parse_midi_list, play_note, prepare_for, velocity_layers, write_wav, WavFormat,
};
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget};
use modal_contact::instrument::{InstrumentParams, Prepared};
use modal_contact::render::render_length;
use modal_contact::scene::Scene;
use rayon::prelude::*;
use serde_json::json;
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::time::Instant;

/// `cargo xtask multisample`.
#[derive(Args, Debug, Clone)]
pub struct MultisampleArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Keys the SFZ covers (a list or range, e.g. `36..96`).
    #[arg(long, default_value = "36..96")]
    pub notes: String,
    /// Sample every `step`-th key of the list (the last key is always
    /// sampled); the keys between play the nearest sample, pitch-shifted.
    #[arg(long, default_value_t = 1)]
    pub step: usize,
    /// Velocity layers over 1..127 (each rendered at its top velocity).
    #[arg(long, default_value_t = 4)]
    pub velocities: usize,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Sample rate in Hz.
    #[arg(long, default_value_t = 44100.0)]
    pub rate: f64,
    /// Longest sample in seconds (default: the scene's duration_s); each
    /// sample's silent tail is trimmed.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Name of the SFZ file and prefix of the samples (default: the scene
    /// file's stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Overwrite files of an earlier export.
    #[arg(long)]
    pub force: bool,
    /// Worker threads (default: every core).
    #[arg(long)]
    pub jobs: Option<usize>,
}

/// One SFZ region: a sampled note and velocity layer, and what it covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// The note rendered (the region's `pitch_keycenter`).
    pub note: u8,
    /// Lowest key played from it.
    pub lokey: u8,
    /// Highest key played from it.
    pub hikey: u8,
    /// Lowest velocity of the layer.
    pub lovel: u8,
    /// Highest velocity of the layer (the velocity rendered).
    pub hivel: u8,
}

impl Region {
    /// The sample's file name.
    pub fn file(&self, name: &str) -> String {
        format!("{name}_n{:03}_v{:03}.wav", self.note, self.hivel)
    }
}

/// The regions for `keys` (sorted, unique), sampling every `step`-th key
/// and the last one, and `layers` velocity layers: each sampled note covers
/// the keys nearer to it than to its neighbours (a key halfway goes to the
/// lower note), the first and last reach the ends of `keys`, no key is
/// covered twice or missed.
pub fn layout(keys: &[u8], step: usize, layers: usize) -> Result<Vec<Region>> {
    if keys.is_empty() {
        bail!("no keys to sample");
    }
    if step == 0 {
        bail!("--step must be at least 1");
    }
    let mut sampled: Vec<u8> = keys.iter().copied().step_by(step).collect();
    let last = *keys.last().expect("not empty");
    if sampled.last() != Some(&last) {
        sampled.push(last);
    }
    let vels = velocity_layers(layers)?;
    let mut out = Vec::new();
    for (i, &note) in sampled.iter().enumerate() {
        let lokey = match i {
            0 => keys[0],
            _ => (u16::from(sampled[i - 1]) + u16::from(note)) as u8 / 2 + 1,
        };
        let hikey = match sampled.get(i + 1) {
            Some(&next) => ((u16::from(note) + u16::from(next)) / 2) as u8,
            None => last,
        };
        for &(lovel, hivel) in &vels {
            out.push(Region {
                note,
                lokey,
                hikey,
                lovel,
                hivel,
            });
        }
    }
    Ok(out)
}

/// A rendered sample: both channels trimmed, its peak and what it did.
struct Sample {
    left: Vec<f32>,
    right: Vec<f32>,
    peak: f32,
    contacts: u64,
    render_s: f64,
}

/// Samples kept at least (10 ms at 48 kHz) and the fade over a trimmed end.
const MIN_KEEP: usize = 480;
const FADE: usize = 64;
/// The tail is cut where both channels stay below this fraction of the
/// sample's peak (-120 dB), with a short linear fade.
const TAIL_FLOOR: f32 = 1e-6;

fn trim(left: &mut Vec<f32>, right: &mut Vec<f32>) -> f32 {
    let peak = left
        .iter()
        .chain(right.iter())
        .fold(0.0f32, |m, x| m.max(x.abs()));
    let floor = peak * TAIL_FLOOR;
    let last = (0..left.len())
        .rev()
        .find(|&i| left[i].abs() > floor || right[i].abs() > floor)
        .map_or(0, |i| i + 1);
    let keep = (last + FADE).max(MIN_KEEP).min(left.len());
    let cut = keep < left.len();
    left.truncate(keep);
    right.truncate(keep);
    if cut && keep > FADE {
        for k in 0..FADE {
            let g = (FADE - k) as f32 / FADE as f32;
            left[keep - FADE + k] *= g;
            right[keep - FADE + k] *= g;
        }
    }
    peak
}

/// The SFZ text for `regions` (samples named by [`Region::file`]).
/// `fixed_pitch`: a kit whose mallets list notes (docs/design.md, "Played
/// as a kit"), every note at the scene's pitch: no region is transposed
/// (`pitch_keytrack=0`).
pub fn sfz_text(
    name: &str,
    header: &str,
    regions: &[Region],
    volume_db: f64,
    fixed_pitch: bool,
) -> String {
    let mut s = String::new();
    for line in header.lines() {
        let _ = writeln!(s, "// {line}");
    }
    let _ = writeln!(s, "\n<control>\ndefault_path=./\n");
    let _ = writeln!(
        s,
        "<global>\n// each layer was recorded at its own level: no velocity scaling\n\
         amp_veltrack=0\n// percussion: the whole sample plays, note-off does not cut it\n\
         loop_mode=one_shot\ntrigger=attack"
    );
    if volume_db != 0.0 {
        let _ = writeln!(s, "volume={volume_db:.3}");
    }
    if fixed_pitch {
        let _ = writeln!(
            s,
            "// a kit: every note sounds at the scene's pitch\npitch_keytrack=0"
        );
    }
    for r in regions {
        let _ = writeln!(
            s,
            "\n<region> sample={} pitch_keycenter={} lokey={} hikey={} lovel={} hivel={}",
            r.file(name),
            r.note,
            r.lokey,
            r.hikey,
            r.lovel,
            r.hivel
        );
    }
    s
}

/// A kit whose mallets list notes (docs/design.md, "Played as a kit"):
/// every key sounds at the scene's pitch, and keys throw different mallets.
/// (A kit without lists is pitched per key like a scene of one contact.)
fn fixed_pitch(scene: &Scene) -> bool {
    scene.several_contacts()
        && (!scene.hammer.notes.is_empty() || scene.striker.iter().any(|s| !s.notes.is_empty()))
}

/// What an export writes, decided and checked before anything renders.
struct Plan {
    scene: Scene,
    keys: Vec<u8>,
    regions: Vec<Region>,
    name: String,
    /// Samples rendered per note (before the tail is trimmed).
    samples: usize,
    sfz: PathBuf,
    manifest: PathBuf,
}

/// Parse the arguments and check every output path (refusing files of an
/// earlier export unless `--force`).
fn plan(a: &MultisampleArgs) -> Result<Plan> {
    let scene = Scene::from_file(&a.scene).with_context(|| a.scene.display().to_string())?;
    let mut keys = parse_midi_list(&a.notes, "note", 0, 127)?;
    keys.sort_unstable();
    let regions = layout(&keys, a.step, a.velocities)?;
    if fixed_pitch(&scene) && a.step > 1 {
        bail!(
            "--step {}: scene {:?} is a kit whose notes throw different mallets (docs/design.md, \
             \"Played as a kit\"): a region cannot stand for its neighbours; export it with \
             --step 1",
            a.step,
            scene.name
        );
    }
    let name = match &a.name {
        Some(n) => n.clone(),
        None => a
            .scene
            .file_stem()
            .context("scene file name")?
            .to_string_lossy()
            .into_owned(),
    };
    let samples = render_length(a.seconds.unwrap_or(scene.duration_s), a.rate)?;
    let sfz = a.out.join(format!("{name}.sfz"));
    let manifest = a.out.join(format!("{name}.json"));
    let mut outputs: Vec<PathBuf> = regions.iter().map(|r| a.out.join(r.file(&name))).collect();
    outputs.extend([sfz.clone(), manifest.clone()]);
    for p in &outputs {
        if p.exists() && !a.force {
            bail!(
                "{} exists (an earlier export?): give --force to overwrite",
                p.display()
            );
        }
        check_writable(p, true)?;
    }
    Ok(Plan {
        scene,
        keys,
        regions,
        name,
        samples,
        sfz,
        manifest,
    })
}

/// Render every region on the pool, each at its top velocity; a note that
/// panics is returned as its message, the others still render. The
/// progress bar appears on a terminal once the job has run for 1 s.
fn render_all(
    pool: &rayon::ThreadPool,
    prepared: &Prepared,
    params: &InstrumentParams,
    plan: &Plan,
) -> Vec<std::result::Result<Sample, String>> {
    let progress = ProgressBar::with_draw_target(
        Some(plan.regions.len() as u64),
        ProgressDrawTarget::hidden(),
    );
    let t0 = Instant::now();
    let tty = std::io::stderr().is_terminal();
    let out = pool.install(|| {
        plan.regions
            .par_iter()
            .map(|r| {
                let played = std::panic::catch_unwind(AssertUnwindSafe(|| {
                    play_note(prepared, params, r.note, r.hivel, plan.samples)
                }));
                progress.inc(1);
                if tty && t0.elapsed().as_secs_f64() > 1.0 && progress.is_hidden() {
                    progress.set_draw_target(ProgressDrawTarget::stderr());
                }
                let mut nr = played.map_err(|e| {
                    e.downcast_ref::<String>()
                        .cloned()
                        .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_else(|| "panicked".into())
                })?;
                let peak = trim(&mut nr.left, &mut nr.right);
                Ok(Sample {
                    left: nr.left,
                    right: nr.right,
                    peak,
                    contacts: nr.contacts,
                    render_s: nr.render_s,
                })
            })
            .collect()
    });
    progress.finish_and_clear();
    out
}

/// The common factor that keeps the loudest sample within 24-bit full
/// scale (1 when nothing would clip), and the `volume` in dB that undoes it.
fn level_scale(global_peak: f32) -> (f32, f64) {
    if global_peak <= 1.0 {
        return (1.0, 0.0);
    }
    let scale = 0.999 / global_peak;
    (scale, -20.0 * f64::from(scale).log10())
}

/// The command line that reproduces the export (for the SFZ header).
pub fn command_line(a: &MultisampleArgs) -> String {
    let q = |s: String| {
        if s.is_empty() || s.contains(|c: char| c.is_whitespace() || "'\"\\$`".contains(c)) {
            format!("'{}'", s.replace('\'', r"'\''"))
        } else {
            s
        }
    };
    let mut c = format!(
        "cargo xtask multisample {} --notes {} --step {} --velocities {} --out {} --rate {}",
        q(a.scene.display().to_string()),
        q(a.notes.clone()),
        a.step,
        a.velocities,
        q(a.out.display().to_string()),
        a.rate
    );
    if let Some(s) = a.seconds {
        let _ = write!(c, " --seconds {s}");
    }
    if let Some(n) = &a.name {
        let _ = write!(c, " --name {}", q(n.clone()));
    }
    c
}

/// The SFZ's comment header: what was rendered, how, and how the levels
/// were kept.
fn header(a: &MultisampleArgs, plan: &Plan, volume_db: f64, failed: usize) -> String {
    let (keys, n) = (&plan.keys, plan.samples);
    let mut h = format!(
        "{}: multisample of {} (scene {:?}), rendered by\n  {}\n\
         {} regions: keys {}..{} sampled every {} key(s), {} velocity layer(s), \
         each rendered at its top velocity\n\
         {} Hz, at most {:.3} s per sample (tails below -120 dB of the sample's peak trimmed), \
         24-bit PCM\n\
         levels are the instrument's own across notes and layers (no sample normalised){}\n\
         note-off does not damp here: the plugin's damper after note-off is not sampled, \
         each sample plays out (one_shot)",
        plan.name,
        a.scene.display(),
        plan.scene.name,
        command_line(a),
        plan.regions.len(),
        keys[0],
        keys[keys.len() - 1],
        a.step,
        a.velocities,
        a.rate,
        n as f64 / a.rate,
        if volume_db > 0.0 {
            format!(";\nall scaled by -{volume_db:.2} dB to fit 24-bit full scale, `volume` restores it")
        } else {
            String::new()
        }
    );
    if failed > 0 {
        let _ = write!(h, "\n{failed} sample(s) FAILED to render and are left out");
    }
    h
}

/// Export the multisample. Every output path is checked first; a note that
/// fails is reported with its name and the others are still written (the
/// command then fails).
pub fn run(a: &MultisampleArgs) -> Result<()> {
    let plan = plan(a)?;
    let params = InstrumentParams::default();
    let (prepared, compile_s) = prepare_for(&plan.scene, &params, a.rate)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    let t0 = Instant::now();
    let rendered = render_all(&pool, &prepared, &params, &plan);
    let global_peak = rendered.iter().flatten().fold(0.0f32, |m, s| m.max(s.peak));
    // Levels are kept across notes and layers; only if something would clip
    // in 24-bit PCM is everything scaled by one factor, undone by `volume`.
    let (scale, volume_db) = level_scale(global_peak);
    if volume_db > 0.0 {
        eprintln!(
            "the loudest sample peaks at {global_peak:.3}: every sample scaled by -{volume_db:.2} dB, \
             restored by volume={volume_db:.3} in <global>"
        );
    }
    if volume_db > 6.0 {
        eprintln!(
            "warning: SFZ 1 players may limit volume to +6 dB; this export will play quieter there"
        );
    }
    let (mut written, mut files, mut failed) = (Vec::new(), Vec::new(), Vec::new());
    for (r, s) in plan.regions.iter().zip(&rendered) {
        let path = a.out.join(r.file(&plan.name));
        let scaled = |x: &[f32]| -> Vec<f32> { x.iter().map(|v| v * scale).collect() };
        let result = s
            .as_ref()
            .map_err(|e| anyhow::anyhow!("panicked: {e}"))
            .and_then(|s| {
                let (l, rr) = (scaled(&s.left), scaled(&s.right));
                write_wav(&path, a.rate, &l, &rr, WavFormat::Pcm24).map(|()| (s, l.len()))
            });
        match result {
            Ok((s, len)) => {
                written.push(*r);
                files.push(json!({
                    "file": r.file(&plan.name),
                    "note": r.note,
                    "keys": [r.lokey, r.hikey],
                    "velocities": [r.lovel, r.hivel],
                    "rendered_velocity": r.hivel,
                    "samples": len,
                    "peak": s.peak,
                    "contacts": s.contacts,
                    "render_s": s.render_s,
                }));
            }
            Err(e) => {
                eprintln!(
                    "FAILED note {} velocity {} ({}): {e:#}",
                    r.note,
                    r.hivel,
                    r.file(&plan.name)
                );
                failed
                    .push(json!({"note": r.note, "velocity": r.hivel, "error": format!("{e:#}")}));
            }
        }
    }
    let text = sfz_text(
        &plan.name,
        &header(a, &plan, volume_db, failed.len()),
        &written,
        volume_db,
        fixed_pitch(&plan.scene),
    );
    std::fs::write(&plan.sfz, text)
        .with_context(|| format!("cannot write {}", plan.sfz.display()))?;
    let m = json!({
        "scene": a.scene.display().to_string(),
        "scene_name": plan.scene.name,
        "command": command_line(a),
        "rate_hz": a.rate,
        "max_seconds": plan.samples as f64 / a.rate,
        "compile_s": compile_s,
        "render_s": t0.elapsed().as_secs_f64(),
        "scale": scale,
        "volume_db": volume_db,
        "files": files,
        "failed": failed,
    });
    std::fs::write(&plan.manifest, serde_json::to_string_pretty(&m)? + "\n")
        .with_context(|| format!("cannot write {}", plan.manifest.display()))?;
    eprintln!(
        "wrote {} samples, {} and {} in {:.2} s (compile {compile_s:.2} s)",
        written.len(),
        plan.sfz.display(),
        plan.manifest.display(),
        t0.elapsed().as_secs_f64()
    );
    if !failed.is_empty() {
        bail!("{} of {} samples failed", failed.len(), plan.regions.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn covered(regions: &[Region]) -> Vec<(u8, u8)> {
        let mut v: Vec<(u8, u8)> = regions
            .iter()
            .flat_map(|r| {
                (r.lokey..=r.hikey).flat_map(move |k| (r.lovel..=r.hivel).map(move |v| (k, v)))
            })
            .collect();
        v.sort_unstable();
        v
    }

    /// Every key of the range and every velocity 1..127 is covered exactly
    /// once, by the nearest sampled note, whose own key is in its range.
    #[test]
    fn layout_covers_every_key_and_velocity_once() {
        for (spec, step, layers) in [
            ("36..96", 3, 4),
            ("60", 1, 1),
            ("21..108", 5, 3),
            ("40..47", 2, 127),
        ] {
            let keys = parse_midi_list(spec, "note", 0, 127).unwrap();
            let regions = layout(&keys, step, layers).unwrap();
            let want: Vec<(u8, u8)> = keys
                .iter()
                .flat_map(|&k| (1..=127u8).map(move |v| (k, v)))
                .collect();
            assert_eq!(covered(&regions), want, "{spec} step {step}");
            for r in &regions {
                assert!(r.lokey <= r.note && r.note <= r.hikey, "{r:?}");
                for k in r.lokey..=r.hikey {
                    let d = (i16::from(k) - i16::from(r.note)).abs();
                    assert!(regions
                        .iter()
                        .all(|o| (i16::from(k) - i16::from(o.note)).abs() >= d));
                }
            }
        }
        let r = layout(&parse_midi_list("36..96", "note", 0, 127).unwrap(), 3, 4).unwrap();
        assert_eq!(r.len(), 21 * 4);
        assert_eq!((r[0].note, r[0].lokey, r[0].hikey), (36, 36, 37));
        assert_eq!((r[4].note, r[4].lokey, r[4].hikey), (39, 38, 40));
        // the last key is sampled even off the step
        let r = layout(&[60, 61, 62, 63], 3, 1).unwrap();
        assert_eq!(r.iter().map(|r| r.note).collect::<Vec<_>>(), [60, 63]);
        assert!(layout(&[], 1, 1).is_err() && layout(&[60], 0, 1).is_err());
    }

    #[test]
    fn sfz_names_every_region_with_its_opcodes() {
        let regions = layout(&[60, 61, 62], 2, 2).unwrap();
        let text = sfz_text("bar", "made here\nline two", &regions, 0.0, false);
        assert!(!text.contains("pitch_keytrack"));
        assert!(sfz_text("bar", "", &regions, 0.0, true).contains("\npitch_keytrack=0\n"));
        assert!(text.starts_with("// made here\n// line two\n"));
        for must in [
            "amp_veltrack=0",
            "loop_mode=one_shot",
            "trigger=attack",
            "default_path=./",
        ] {
            assert!(text.contains(must), "{must}");
        }
        assert!(!text.contains("volume="));
        assert!(text.contains(
            "<region> sample=bar_n060_v063.wav pitch_keycenter=60 lokey=60 hikey=61 lovel=1 hivel=63"
        ));
        assert!(text.contains(
            "<region> sample=bar_n062_v127.wav pitch_keycenter=62 lokey=62 hikey=62 lovel=64 hivel=127"
        ));
        assert_eq!(text.matches("<region>").count(), 4);
        assert!(sfz_text("bar", "", &regions, 3.5, false).contains("volume=3.500"));
    }

    #[test]
    fn levels_are_scaled_only_when_they_would_clip() {
        assert_eq!(level_scale(0.0), (1.0, 0.0));
        assert_eq!(level_scale(1.0), (1.0, 0.0));
        let (scale, db) = level_scale(2.0);
        assert!((scale * 2.0 - 0.999).abs() < 1e-6);
        assert!((db - 20.0 * (2.0f64 / 0.999).log10()).abs() < 1e-4, "{db}");
    }

    #[test]
    fn the_command_line_reproduces_the_export() {
        let mut a = MultisampleArgs {
            scene: "presets/marimba-bar.toml".into(),
            notes: "36..96".into(),
            step: 3,
            velocities: 4,
            out: "my dir".into(),
            rate: 44100.0,
            seconds: None,
            name: None,
            force: true,
            jobs: Some(2),
        };
        assert_eq!(
            command_line(&a),
            "cargo xtask multisample presets/marimba-bar.toml --notes 36..96 --step 3 \
             --velocities 4 --out 'my dir' --rate 44100"
        );
        (a.seconds, a.name) = (Some(1.5), Some("it's".into()));
        assert!(command_line(&a).ends_with(r"--seconds 1.5 --name 'it'\''s'"));
    }

    /// A kit whose notes throw different mallets is exported a key per
    /// region, untransposed: `--step 3` is refused by name before anything
    /// renders; a kit without note lists (pitched per key, as a scene of
    /// one contact) takes it and is transposed as one.
    #[test]
    fn a_kit_with_note_lists_is_exported_a_key_per_region() {
        let dir = std::env::temp_dir().join(format!("kit-sfz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let text = std::fs::read_to_string(root.join("presets/marimba-two-mallets.toml"))
            .unwrap()
            .replace("[contact]", "notes = [60]\n\n[contact]");
        let listed = dir.join("listed.toml");
        std::fs::write(&listed, text).unwrap();
        let args = |scene: PathBuf| MultisampleArgs {
            scene,
            notes: "58..62".into(),
            step: 3,
            velocities: 1,
            out: dir.join("out"),
            rate: 44100.0,
            seconds: Some(0.05),
            name: None,
            force: true,
            jobs: Some(1),
        };
        let e = plan(&args(listed)).err().expect("refused");
        assert!(format!("{e:#}").contains("--step 3"), "{e:#}");
        assert!(fixed_pitch(
            &Scene::from_file(&dir.join("listed.toml")).unwrap()
        ));
        let chimes = root.join("presets/wind-chimes.toml");
        assert!(plan(&args(chimes.clone())).is_ok());
        assert!(!fixed_pitch(&Scene::from_file(&chimes).unwrap()));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn trimming_keeps_the_sound_and_cuts_the_silence() {
        let mut l: Vec<f32> = (0..10_000)
            .map(|i| {
                if i < 3000 {
                    0.5 * (i as f32 * 0.1).sin()
                } else {
                    0.0
                }
            })
            .collect();
        let mut r = l.clone();
        let peak = trim(&mut l, &mut r);
        assert!((peak - 0.5).abs() < 1e-3);
        assert!(l.len() >= 3000 && l.len() <= 3000 + FADE, "{}", l.len());
        let mut quiet = vec![0.0f32; 5000];
        let mut q2 = quiet.clone();
        trim(&mut quiet, &mut q2);
        assert_eq!(quiet.len(), MIN_KEEP);
    }
}
