//! `cargo xtask compare-real`: every preset that names a real instrument
//! (its `real_instrument` key, a General MIDI name) against real recorded
//! samples of that instrument, the raw sample data of the FluidR3 General
//! MIDI soundfont (Debian package `fluid-soundfont-gm`).
//!
//! For each such preset: the scene's strike is rendered (as `cargo xtask
//! render` renders it, mixed to mono), the soundfont's zones for the
//! preset's key are played as a sampler plays them (transposed to that
//! key and resampled to the render's rate; no envelope, filter or loop),
//! and both are measured from their onsets ([`analysis`]): the
//! recording's strongest partials and whether the render has them, decay
//! times per partial, the attack's centroid and energy above 5 kHz, and
//! the 1/3-octave distance; then the same distance between recordings of
//! related instruments and between two recordings of each named
//! instrument (the scale of what "close" means), a confusion
//! table, and the targets of issue 49 per preset. Writes
//! `DIR/compare-real.md` and `DIR/compare-real/*.svg` (default `docs`),
//! and WAV pairs (recording, render) into `target/compare-real/`.

pub use modal_testkit::analysis;
pub mod gm;
mod measure;
mod plots;
mod recordings;
mod report;
pub mod sf2;
mod stroke;
mod targets;
mod velocity;
mod wavs;

use crate::benchmarks::{rustc_version, today};
use analysis::{Peak, Spectrum, T60};
use anyhow::{bail, Context, Result};
use clap::Args;
use gm::GmSound;
use measure::compare;
use modal_contact::instrument::root_note;
use modal_contact::scene::Scene;
use rayon::prelude::*;
use recordings::{
    bells_and_plates, confusion_set, other_recordings, play_recordings, recording_keys, scale_pairs,
};
use report::{
    method_text, report_header, write_confusion, write_other_recordings, write_preset_plots,
    write_preset_table, write_scale_pairs, write_strokes, write_summary,
};
use sf2::{KeyRegion, SoundFont, VELOCITY};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
pub use wavs::demo_recordings;

/// Where Debian's `fluid-soundfont-gm` installs the soundfont.
pub const DEFAULT_SF2: &str = "/usr/share/sounds/sf2/FluidR3_GM.sf2";
/// The Debian package that holds it.
pub const SF2_PACKAGE: &str = "fluid-soundfont-gm";

/// Sample rate of the renders and of the played recordings \[Hz\]: the
/// render command's default.
pub const RATE_HZ: f64 = 44100.0;
/// The stretch whose spectra are compared (band levels, plots) \[s\]
/// from the onset, shortened to the shorter signal when one is shorter.
pub const WINDOW_S: f64 = 0.5;
/// The window of the long spectrum whose peaks are the partials \[s\].
pub const PARTIAL_WINDOW_S: f64 = 1.0;
/// The attack \[s\] from the onset.
pub const ATTACK_S: f64 = 0.05;
/// The frequency above which the attack's energy is counted \[Hz\].
pub const HF_HZ: f64 = 5000.0;
/// The recording's partials compared.
pub const PARTIALS: usize = 4;
/// Peaks further below the strongest are not taken as partials \[dB\].
pub const PEAK_RANGE_DB: f64 = 60.0;
/// A render peak counts as a partial within this many dB of the render's
/// strongest peak.
pub const RENDER_RANGE_DB: f64 = 60.0;
/// Partials on the T60 plots, per signal.
pub const PLOT_PARTIALS: usize = 8;

/// Target: 1/3-octave distance at most this \[dB\].
pub const TARGET_DISTANCE_DB: f64 = 6.0;
/// Target: attack centroid ratio (render / real) within this range.
pub const TARGET_CENTROID: (f64, f64) = (0.75, 1.33);
/// Target: energy above 5 kHz within +- this of the real's \[dB\].
pub const TARGET_HF_DB: f64 = 6.0;
/// Target: the recording's strongest partials present within this \[cents\].
pub const TARGET_CENTS: f64 = 15.0;
/// Target: T60 per partial within this factor.
pub const TARGET_T60_FACTOR: f64 = 1.5;
/// A render partial this near a real one (cents) is the one whose decay is
/// compared with it.
pub const T60_MATCH_CENTS: f64 = 50.0;

/// The furthest a recording is transposed \[cents\]: an octave. A
/// sample played further from its recorded pitch no longer sounds like
/// the instrument (its timbre and band limit move with it), so a pitched
/// recording is played at the nearest key within an octave of its zones'
/// root keys instead, and the report says so.
pub const MAX_TRANSPOSE_CENTS: f64 = 1200.0;

/// The recordings every preset is compared with in the confusion table,
/// besides the instruments the presets name.
pub const CONFUSION_EXTRA: [&str; 5] = [
    "Xylophone",
    "Celesta",
    "Steel Drums",
    "Timpani",
    "Hi Wood Block",
];

/// The pairs of recordings of related instruments whose distance is the
/// scale of "close"; a pitched pair is played at a common key: the key of
/// the first preset that names its first instrument, or the nearest key
/// at which both are within an octave of their recordings
/// (`common_key`).
pub const SCALE_PAIRS: [(&str, &str); 7] = [
    ("Marimba", "Xylophone"),
    ("Marimba", "Vibraphone"),
    ("Glockenspiel", "Celesta"),
    ("Tubular Bells", "Glockenspiel"),
    ("Low Floor Tom", "High Floor Tom"),
    ("Acoustic Snare", "Electric Snare"),
    ("Woodblock", "Hi Wood Block"),
];

/// Presets that name no instrument because FluidR3 has no fitting
/// recording, and what it has instead (found by listing its preset
/// headers and the kit's zones: see the report's last section).
pub const NO_RECORDING: [(&str, &str); 2] = [
    (
        "bell",
        "FluidR3's bells are Tubular Bells (program 14), whose sample also plays bank 8's \
         Church Bell, Tinkle Bell (program 112, a toy bell), Agogo and the kit's Cowbell and \
         Ride Bell: no church bell",
    ),
    (
        "steel-plate",
        "no struck plate: the nearest are the kit's cymbals (domed bronze)",
    ),
];

/// The General MIDI kits (bank 128 programs) searched, in this order, for
/// another recording of a percussion key: Room, Power, Jazz, Brush,
/// Orchestra (the General Standard 2 kit numbers).
pub const OTHER_KITS: [u16; 5] = [8, 16, 32, 40, 48];

/// `cargo xtask compare-real [--preset NAME]... [--out DIR] [--sf2 PATH]
/// [--check] [--seconds S]`.
#[derive(Args, Debug)]
pub struct CompareRealArgs {
    /// Where compare-real.md goes (the plots into its compare-real/).
    #[arg(long, default_value = "docs")]
    pub out: PathBuf,
    /// Compare only this preset (file name without .toml; repeatable).
    #[arg(long = "preset", value_name = "NAME")]
    pub presets: Vec<String>,
    /// The General MIDI soundfont (Debian package fluid-soundfont-gm).
    #[arg(long, default_value = DEFAULT_SF2)]
    pub sf2: PathBuf,
    /// Exit non-zero when any target fails (else always 0 after the
    /// report).
    #[arg(long)]
    pub check: bool,
    /// Length of each render \[s\].
    #[arg(long, default_value_t = 4.0)]
    pub seconds: f64,
}

/// The workspace root (the presets and `target/` are found from it).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A preset file and what it names.
struct PresetFile {
    /// File name without `.toml`.
    stem: String,
    scene: Scene,
    /// The key the scene sounds at ([`root_note`], rounded).
    key: u8,
    /// The instrument it names: none, or an unknown name.
    real: Result<Option<GmSound>, String>,
}

fn load_presets(dir: &Path) -> Result<Vec<PresetFile>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| {
            let scene = Scene::from_file(p).with_context(|| format!("presets/{}", file_name(p)))?;
            let stem = p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let real = match &scene.real_instrument {
                None => Ok(None),
                Some(n) => GmSound::parse(n).map(Some).ok_or_else(|| {
                    format!("{n:?} is not a General MIDI program or percussion key name")
                }),
            };
            Ok(PresetFile {
                stem,
                key: root_note(&scene).round().clamp(0.0, 127.0) as u8,
                scene,
                real,
            })
        })
        .collect()
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The scene's strike rendered as `cargo xtask render` renders it (the
/// scene as written, one or several contacts), the two channels mixed to
/// mono.
fn render_mono(scene: &Scene, seconds: f64) -> Result<Vec<f64>> {
    use modal_contact::render::render_length;
    use modal_contact::Compiled;
    let n = render_length(seconds, RATE_HZ)?;
    let out = Compiled::new(scene, RATE_HZ, None)?.render(n, false);
    let (l, r) = (out.left, out.right);
    let mono: Vec<f64> = l.iter().zip(&r).map(|(a, b)| 0.5 * (a + b)).collect();
    if mono.iter().any(|x| !x.is_finite()) {
        bail!("the render is not finite");
    }
    if mono.iter().all(|x| *x == 0.0) {
        bail!("the render is silent");
    }
    Ok(mono)
}

/// A sound ready to measure: from its onset, at [`RATE_HZ`].
struct Sound {
    /// The samples from the onset.
    x: Vec<f64>,
    /// Where the onset was in the played or rendered signal \[s\].
    onset_s: f64,
    /// Its band limit \[Hz\] (a recording's sample rate and transposition).
    band_limit_hz: f64,
}

impl Sound {
    fn new(full: &[f64], band_limit_hz: f64) -> Self {
        let o = analysis::onset(full, RATE_HZ);
        Self {
            x: full[o..].to_vec(),
            onset_s: o as f64 / RATE_HZ,
            band_limit_hz,
        }
    }

    fn seconds(&self) -> f64 {
        self.x.len() as f64 / RATE_HZ
    }
}

/// A recording: a soundfont key region played at a key.
struct Recording {
    region: KeyRegion,
    played: Sound,
}

impl Recording {
    /// The region played at [`RATE_HZ`].
    fn new(region: KeyRegion) -> std::result::Result<Self, String> {
        let full = region.play(RATE_HZ)?;
        let limit = region.band_limit_hz().min(0.5 * RATE_HZ);
        Ok(Self {
            played: Sound::new(&full, limit),
            region,
        })
    }

    /// One line on the samples and their transposition.
    fn describe(&self) -> String {
        let r = &self.region;
        let zones: Vec<String> = r
            .zones
            .iter()
            .map(|z| {
                let looped = match z.looped {
                    Some((a, b)) => format!(
                        ", looped {:.3}-{:.3} s in the soundfont (the loop is not played)",
                        a as f64 / z.rate_hz,
                        b as f64 / z.rate_hz
                    ),
                    None => String::new(),
                };
                format!(
                    "\"{}\" ({}, {} Hz, {:.2} s{looped})",
                    z.name,
                    z.channel(),
                    z.rate_hz,
                    z.seconds()
                )
            })
            .collect();
        let z0 = &r.zones[0];
        let transposed = r.zones.iter().map(|z| z.cents / 100.0).collect::<Vec<_>>();
        let same = transposed.iter().all(|t| (t - transposed[0]).abs() < 1e-9);
        let semis = if same {
            format!("{:+.2}", transposed[0])
        } else {
            transposed
                .iter()
                .map(|t| format!("{t:+.2}"))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        let far = r.zones.iter().map(|z| z.cents.abs()).fold(0.0, f64::max) > 1200.0;
        let caution = if far {
            ". **Caution**: transposed by more than an octave, far from where it was recorded \
             (its timbre and band limit moved with it): this comparison says little"
        } else {
            ""
        };
        format!(
            "FluidR3 \"{}\" (bank {} program {}) key {} velocity {}: {} zone{} {}{}; root key {}; \
             played at key {} as a sampler plays it: transposed {semis} semitones, resampled to {} Hz; \
             {:.2} s from the onset, band limit {:.1} kHz{caution}",
            r.preset_name,
            r.bank,
            r.program,
            r.key,
            r.velocity,
            r.zones.len(),
            if r.zones.len() == 1 { "" } else { "s" },
            zones.join(" + "),
            if r.zones.len() > 1 { " mixed to mono" } else { "" },
            z0.root_key,
            r.key,
            RATE_HZ,
            self.played.seconds(),
            self.played.band_limit_hz / 1000.0
        )
    }
}

/// One of the recording's strongest partials against the render.
struct PartialRow {
    real: Peak,
    /// Frequency over the lowest of the compared partials.
    ratio: f64,
    /// The render's nearest partial and its distance in cents.
    render: Option<(Peak, f64)>,
    t60_real: T60,
    /// The render's decay at its partial within [`T60_MATCH_CENTS`].
    t60_render: Option<T60>,
}

impl PartialRow {
    fn present(&self) -> bool {
        self.render.is_some_and(|(_, c)| c.abs() <= TARGET_CENTS)
    }

    /// Render T60 / real T60 when both have a fit.
    fn t60_ratio(&self) -> Option<f64> {
        let r = self.t60_real.seconds()?;
        let g = self.t60_render.as_ref()?.seconds()?;
        Some(g / r)
    }
}

/// A target's outcome.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Verdict {
    Pass,
    Fail,
    /// Not measurable here (said why).
    NotApplicable,
}

impl Verdict {
    fn of(ok: bool) -> Self {
        if ok {
            Self::Pass
        } else {
            Self::Fail
        }
    }

    fn word(self) -> &'static str {
        match self {
            Self::Pass => "PASS",
            Self::Fail => "FAIL",
            Self::NotApplicable => "n/a",
        }
    }
}

/// One target of issue 49 for one preset.
struct Target {
    name: &'static str,
    verdict: Verdict,
    detail: String,
}

/// The partials plotted on the T60 plot: frequency and fit.
type Decays = Vec<(f64, T60)>;

/// A preset measured against its recording.
struct Comparison {
    stem: String,
    sound: GmSound,
    key: u8,
    recording: String,
    render_onset_s: f64,
    window_s: f64,
    rows: Vec<PartialRow>,
    centroid: (f64, f64),
    hf_db: (f64, f64),
    distance: f64,
    /// Distance to every recording of the confusion set (`None`: no zone)
    /// and the key it was played at.
    confusion: Vec<(GmSound, Option<f64>, u8)>,
    targets: Vec<Target>,
    /// For the plots: the two energy spectra (real, render).
    spectra: (Spectrum, Spectrum),
    /// For the plots: decays of the strongest partials (real, render).
    decays: (Decays, Decays),
    /// For the WAVs: the two signals from their onsets.
    signals: (Vec<f64>, Vec<f64>),
    /// A scraped or rolled preset's stroke and its recording's (real,
    /// render); `None` for a struck preset.
    strokes: Option<(stroke::Stroke, stroke::Stroke)>,
}

type RecordingKey = (GmSound, u8);
/// A recording played, or why it could not be.
type Played = std::result::Result<Recording, String>;

/// An error naming the Debian package when the soundfont `path` is not a
/// file (`compare-real` and `analyze-real` read it).
pub fn require_sf2(path: &std::path::Path) -> Result<()> {
    if !path.is_file() {
        bail!(
            "soundfont {} not found: install the Debian package {SF2_PACKAGE} \
             (apt-get install {SF2_PACKAGE}), or give another with --sf2 PATH",
            path.display()
        );
    }
    Ok(())
}

/// `cargo xtask compare-real`.
pub fn run(a: &CompareRealArgs) -> Result<()> {
    let t0 = Instant::now();
    require_sf2(&a.sf2)?;
    if !(a.seconds > 0.0 && a.seconds <= 60.0) {
        bail!("--seconds must be in (0, 60], got {}", a.seconds);
    }
    let root = workspace_root();
    let all = load_presets(&root.join("presets"))?;
    for name in &a.presets {
        if !all.iter().any(|p| &p.stem == name) {
            bail!("no preset presets/{name}.toml");
        }
    }
    let chosen: Vec<&PresetFile> = all
        .iter()
        .filter(|p| a.presets.is_empty() || a.presets.contains(&p.stem))
        .collect();
    let compared: Vec<(&PresetFile, GmSound)> = chosen
        .iter()
        .filter_map(|p| match p.real {
            Ok(Some(s)) => Some((*p, s)),
            _ => None,
        })
        .collect();

    // the soundfont and the renders, side by side
    let (sf, renders) = rayon::join(
        || SoundFont::open(&a.sf2),
        || {
            compared
                .par_iter()
                .map(|(p, _)| {
                    render_mono(&p.scene, a.seconds)
                        .with_context(|| format!("rendering presets/{}.toml", p.stem))
                })
                .collect::<Vec<_>>()
        },
    );
    let sf = sf?;
    let renders: Vec<Sound> = renders
        .into_iter()
        .map(|r| r.map(|x| Sound::new(&x, 0.5 * RATE_HZ)))
        .collect::<Result<_>>()?;

    // every recording needed, once: own, confusion set, scale pairs
    let set = confusion_set(&all);
    let (keys, mut wanted) = recording_keys(&sf, &compared, &set);
    let pairs = scale_pairs(&sf, &all, &mut wanted);
    let others = other_recordings(&sf, &compared);
    let recs = play_recordings(&sf, &wanted);

    let comparisons: Vec<Result<Comparison>> = compared
        .par_iter()
        .zip(&renders)
        .map(|((p, s), render)| {
            compare(p, *s, render, &recs, &keys, &set)
                .with_context(|| format!("comparing presets/{}.toml", p.stem))
        })
        .collect();

    // the report
    let mut md = report_header(a);
    let mut body = String::new();
    let _ = writeln!(body, "## Method\n\n{}\n", method_text(a.seconds));
    let tally = write_summary(&mut body, &comparisons, &chosen);
    write_scale_pairs(&mut body, &pairs, &recs);
    write_other_recordings(&mut body, &others, &recs);
    write_confusion(&mut body, &set, &comparisons);
    write_strokes(&mut body, &comparisons);
    let rows = velocity::rows(&sf, &compared, |p, s| {
        keys.get(&(s, p.key)).copied().unwrap_or(p.key)
    });
    velocity::write(&mut body, &rows);

    // per preset
    let plot_dir = a.out.join("compare-real");
    let wav_dir = root.join("target/compare-real");
    std::fs::create_dir_all(&plot_dir)
        .with_context(|| format!("cannot create {}", plot_dir.display()))?;
    std::fs::create_dir_all(&wav_dir).context("cannot create target/compare-real")?;
    for c in comparisons.iter().flatten() {
        write_preset_table(&mut body, c, a.seconds);
        write_preset_plots(&mut body, c, &plot_dir, &wav_dir)?;
    }

    let _ = writeln!(
        body,
        "## What FluidR3 offers for bells and plates\n\nPreset headers whose names say bell, chime, gong, plate, \
         cymbal, triangle, agogo or steel (the samples they play at key 72), and the standard kit's metal keys:\n\n{}",
        bells_and_plates(&sf)
    );
    md.push_str(&body);
    let md_path = a.out.join("compare-real.md");
    std::fs::write(&md_path, &md).with_context(|| format!("cannot write {}", md_path.display()))?;
    print!("{body}");
    println!("{}", tally.summary);
    eprintln!(
        "wrote {} and {}/*.svg; WAV pairs in target/compare-real/ ({:.1} s)",
        md_path.display(),
        plot_dir.display(),
        t0.elapsed().as_secs_f64()
    );
    if a.check && tally.failed > 0 {
        bail!(
            "{} targets failed ({})",
            tally.failed,
            tally.failures.join(", ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::recordings::another_recording;
    use super::*;

    /// Another recording of a pitched instrument is the nearest other key
    /// range's sample heard at the key; a kit key with no other kit has none.
    #[test]
    fn another_recording_is_the_next_key_ranges_sample_at_the_same_key() {
        let sf = SoundFont::read(&mut std::io::Cursor::new(sf2::tests::tiny_sf2())).unwrap();
        let marimba = GmSound::parse("Marimba").unwrap();
        let own = sf.key_region(0, 12, 57, VELOCITY).unwrap();
        let other = another_recording(&sf, marimba, 57).expect("the high range");
        assert_eq!(own.zones[0].name, "low");
        assert_eq!((other.key, other.zones[0].name.as_str()), (57, "high"));
        assert_eq!(other.zones[0].cents, 50.0 * (57.0 - 60.0));
        // from the high range, the other is the low range's sample
        let back = another_recording(&sf, marimba, 64).unwrap();
        assert_eq!((back.key, back.zones[0].name.as_str()), (64, "low"));
        let snare = GmSound::parse("Acoustic Snare").unwrap();
        assert!(another_recording(&sf, snare, 38).is_none());
    }

    #[test]
    fn the_date_is_a_calendar_date() {
        let d = today();
        assert_eq!(d.len(), 10);
        assert!(d.starts_with("20"));
    }

    #[test]
    fn every_preset_names_a_known_instrument_or_none() {
        let all = load_presets(&workspace_root().join("presets")).unwrap();
        assert!(all.len() >= 10);
        for p in &all {
            assert!(p.real.is_ok(), "{}: {:?}", p.stem, p.real.as_ref().err());
        }
        let named = all.iter().filter(|p| matches!(p.real, Ok(Some(_)))).count();
        assert!(named >= 1);
    }

    #[test]
    fn the_tables_names_are_general_midi_names() {
        for n in CONFUSION_EXTRA
            .iter()
            .chain(SCALE_PAIRS.iter().flat_map(|(a, b)| [a, b]))
        {
            assert!(GmSound::parse(n).is_some(), "{n}");
        }
    }

    /// The demo does not need the soundfont: without it, one line naming
    /// the package and no file.
    #[test]
    fn the_demo_without_the_soundfont_says_which_package_holds_it() {
        let dir = std::env::temp_dir().join(format!("xtask-demo-real-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let lines = demo_recordings(&dir, Path::new("/nonexistent/FluidR3_GM.sf2")).unwrap();
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(lines[0].contains(SF2_PACKAGE), "{}", lines[0]);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_soundfont_names_the_package() {
        let a = CompareRealArgs {
            out: std::env::temp_dir(),
            presets: vec![],
            sf2: PathBuf::from("/nonexistent/FluidR3_GM.sf2"),
            check: false,
            seconds: 1.0,
        };
        let e = run(&a).unwrap_err().to_string();
        assert!(e.contains(SF2_PACKAGE), "{e}");
    }
}
