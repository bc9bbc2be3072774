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
mod plots;
mod report;
pub mod sf2;
mod stroke;
mod velocity;

use crate::benchmarks::{rustc_version, today};
use analysis::{Peak, Spectrum, T60};
use anyhow::{bail, Context, Result};
use clap::Args;
use gm::GmSound;
use modal_contact::instrument::root_note;
use modal_contact::scene::Scene;
use rayon::prelude::*;
use report::{
    method_text, report_header, write_confusion, write_other_recordings, write_preset_plots,
    write_preset_table, write_scale_pairs, write_strokes, write_summary,
};
use sf2::{KeyRegion, SoundFont, VELOCITY};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

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

/// The keys nearest `key` first (`key`, then one below, one above, ...).
fn keys_around(key: u8) -> impl Iterator<Item = u8> {
    let k = i32::from(key);
    std::iter::once(k)
        .chain((1..128).flat_map(move |d| [k - d, k + d]))
        .filter(|k| (0..128).contains(k))
        .map(|k| k as u8)
}

/// Whether `s` played at `key` is transposed at most
/// [`MAX_TRANSPOSE_CENTS`] (a percussion key always is: it plays at its
/// own key).
fn near_recorded(sf: &SoundFont, s: GmSound, key: u8) -> bool {
    let (bank, program) = s.bank_program();
    sf.transposition(bank, program, s.key_for(key), VELOCITY)
        .is_some_and(|c| c <= MAX_TRANSPOSE_CENTS + 1e-9)
}

/// The key `s` is played at to stand for `key`: its percussion key; else
/// `key` itself when that is within an octave of the recording, otherwise
/// the nearest key that is ([`MAX_TRANSPOSE_CENTS`]); `key` when none is.
fn playable_key(sf: &SoundFont, s: GmSound, key: u8) -> u8 {
    if s.is_drum() {
        return s.key_for(key);
    }
    keys_around(key)
        .find(|&k| near_recorded(sf, s, k))
        .unwrap_or(key)
}

/// The common key of two recordings compared with each other: the
/// nearest key to `key` at which both are within an octave of their
/// recordings ([`MAX_TRANSPOSE_CENTS`]), `key` when there is none.
fn common_key(sf: &SoundFont, a: GmSound, b: GmSound, key: u8) -> u8 {
    keys_around(key)
        .find(|&k| near_recorded(sf, a, k) && near_recorded(sf, b, k))
        .unwrap_or(key)
}

/// The General MIDI kits (bank 128 programs) searched, in this order, for
/// another recording of a percussion key: Room, Power, Jazz, Brush,
/// Orchestra (the General Standard 2 kit numbers).
pub const OTHER_KITS: [u16; 5] = [8, 16, 32, 40, 48];

/// Another recording of `s` at `key`, for the scale of "close": for a
/// pitched instrument the samples of the nearest other key range of the
/// same preset, played at `key` (transposed at most an octave,
/// [`MAX_TRANSPOSE_CENTS`]); for a percussion key the same key of the
/// first other kit ([`OTHER_KITS`]) whose samples differ (a brush kit's
/// own sounds have no other kit). `None` when the soundfont has no such
/// recording.
fn another_recording(sf: &SoundFont, s: GmSound, key: u8) -> Option<KeyRegion> {
    let (bank, program) = s.bank_program();
    let key = s.key_for(key);
    let own = sf.key_region(bank, program, key, VELOCITY).ok()?;
    let names = |r: &KeyRegion| -> Vec<String> { r.zones.iter().map(|z| z.name.clone()).collect() };
    let own_names = names(&own);
    let differs = |r: &KeyRegion| names(r).iter().all(|n| !own_names.contains(n));
    if let GmSound::Brush(_) = s {
        return None;
    }
    if s.is_drum() {
        return OTHER_KITS.iter().find_map(|&kit| {
            sf.key_region(bank, kit, key, VELOCITY)
                .ok()
                .filter(|r| differs(r))
        });
    }
    keys_around(key)
        .skip(1)
        .take_while(|&k| k.abs_diff(key) <= 12)
        .find_map(|k| {
            sf.key_region_played_at(bank, program, k, key, VELOCITY)
                .ok()
                .filter(|r| {
                    differs(r)
                        && r.zones
                            .iter()
                            .all(|z| z.cents.abs() <= MAX_TRANSPOSE_CENTS + 1e-9)
                })
        })
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

/// The partials of a sound: the strongest peaks of its long spectrum.
fn partials(s: &Sound, range_db: f64) -> Vec<Peak> {
    let (spec, n) = analysis::long_spectrum(&s.x, RATE_HZ, PARTIAL_WINDOW_S);
    let hi = (0.95 * s.band_limit_hz).min(20000.0);
    analysis::peaks(&spec, n, 30.0, hi, range_db)
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

/// The 1/3-octave distance between two sounds over the first
/// [`WINDOW_S`] (or the shorter one's length).
fn distance(a: &Sound, b: &Sound) -> f64 {
    let t = WINDOW_S.min(a.seconds()).min(b.seconds());
    let la = analysis::band_levels(&analysis::welch(&a.x, RATE_HZ, t));
    let lb = analysis::band_levels(&analysis::welch(&b.x, RATE_HZ, t));
    analysis::third_octave_distance(&la, &lb)
}

/// The decays of a sound's partials.
fn decays(s: &Sound, frames: &[Vec<f64>], peaks: &[Peak]) -> Decays {
    peaks
        .iter()
        .map(|p| {
            (
                p.freq_hz,
                analysis::fit_t60(&analysis::track(frames, RATE_HZ, p.freq_hz)),
            )
        })
        .filter(|_| !s.x.is_empty())
        .collect()
}

type RecordingKey = (GmSound, u8);
/// A recording played, or why it could not be.
type Played = std::result::Result<Recording, String>;

/// Measure a preset against its recording and the confusion set.
fn compare(
    p: &PresetFile,
    sound: GmSound,
    render: &Sound,
    recs: &BTreeMap<RecordingKey, std::result::Result<Recording, String>>,
    keys: &BTreeMap<RecordingKey, u8>,
    set: &[GmSound],
) -> Result<Comparison> {
    let own_key = keys[&(sound, p.key)];
    let own = match &recs[&(sound, own_key)] {
        Ok(r) => r,
        Err(e) => bail!("{e}"),
    };
    let real = &own.played;
    let window_s = WINDOW_S.min(real.seconds()).min(render.seconds());

    // partials
    let real_peaks = partials(real, PEAK_RANGE_DB);
    let render_peaks = partials(render, RENDER_RANGE_DB);
    let real_frames = analysis::stft(&real.x);
    let render_frames = analysis::stft(&render.x);
    let rows = partial_rows(&real_peaks, &render_peaks, &real_frames, &render_frames);

    // attack
    let ra = analysis::attack_spectrum(&real.x, RATE_HZ, ATTACK_S);
    let ga = analysis::attack_spectrum(&render.x, RATE_HZ, ATTACK_S);
    let centroid = (analysis::centroid(&ra), analysis::centroid(&ga));
    let hf_db = (
        analysis::fraction_above_db(&ra, HF_HZ),
        analysis::fraction_above_db(&ga, HF_HZ),
    );

    // bands
    let spectra = (
        analysis::welch(&real.x, RATE_HZ, window_s),
        analysis::welch(&render.x, RATE_HZ, window_s),
    );
    let dist = analysis::third_octave_distance(
        &analysis::band_levels(&spectra.0),
        &analysis::band_levels(&spectra.1),
    );
    let confusion = confusion_distances(render, p.key, recs, keys, set);

    let real_top: Vec<Peak> = real_peaks.iter().copied().take(PLOT_PARTIALS).collect();
    let render_top: Vec<Peak> = render_peaks.iter().copied().take(PLOT_PARTIALS).collect();
    let mut c = Comparison {
        stem: p.stem.clone(),
        sound,
        key: p.key,
        recording: if own_key == sound.key_for(p.key) {
            own.describe()
        } else {
            format!(
                "{}. Played at key {own_key}, not at the preset's key {}: there the recording would be \
                 transposed by more than an octave (see the method)",
                own.describe(),
                p.key
            )
        },
        render_onset_s: render.onset_s,
        window_s,
        rows,
        centroid,
        hf_db,
        distance: dist,
        confusion,
        targets: Vec::new(),
        decays: (
            decays(real, &real_frames, &real_top),
            decays(render, &render_frames, &render_top),
        ),
        spectra,
        signals: (real.x.clone(), render.x.clone()),
        strokes: p.scene.drive.is_some().then(|| {
            (
                stroke::stroke(&real.x, RATE_HZ),
                stroke::stroke(&render.x, RATE_HZ),
            )
        }),
    };
    c.targets = targets(&c, real.band_limit_hz, own_key);
    Ok(c)
}

/// The recording's strongest [`PARTIALS`] partials, each with the
/// render's nearest partial and both decays (`*_frames`: the two STFTs).
fn partial_rows(
    real_peaks: &[Peak],
    render_peaks: &[Peak],
    real_frames: &[Vec<f64>],
    render_frames: &[Vec<f64>],
) -> Vec<PartialRow> {
    let strongest: Vec<Peak> = real_peaks.iter().copied().take(PARTIALS).collect();
    let lowest = strongest
        .iter()
        .map(|p| p.freq_hz)
        .fold(f64::INFINITY, f64::min);
    strongest
        .iter()
        .map(|&rp| {
            let near = render_peaks
                .iter()
                .map(|q| (*q, analysis::cents(rp.freq_hz, q.freq_hz)))
                .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
            let t60_render = near
                .filter(|(_, c)| c.abs() <= T60_MATCH_CENTS)
                .map(|(q, _)| {
                    analysis::fit_t60(&analysis::track(render_frames, RATE_HZ, q.freq_hz))
                });
            PartialRow {
                real: rp,
                ratio: rp.freq_hz / lowest,
                render: near,
                t60_real: analysis::fit_t60(&analysis::track(real_frames, RATE_HZ, rp.freq_hz)),
                t60_render,
            }
        })
        .collect::<Vec<_>>()
}

/// The render's distance to the recording of every sound of the set
/// `set` at `key` (`None`: no zone), and the key each was played at.
fn confusion_distances(
    render: &Sound,
    key: u8,
    recs: &BTreeMap<RecordingKey, std::result::Result<Recording, String>>,
    keys: &BTreeMap<RecordingKey, u8>,
    set: &[GmSound],
) -> Vec<(GmSound, Option<f64>, u8)> {
    set.iter()
        .map(|&s| {
            let k = keys[&(s, key)];
            let d = recs[&(s, k)]
                .as_ref()
                .ok()
                .map(|r| distance(render, &r.played));
            (s, d, k)
        })
        .collect()
}

/// The targets of the comparison `c` (its `targets` not yet set), the
/// recording's band limit \[Hz\] and the key it was played at.
fn targets(c: &Comparison, band_limit_hz: f64, own_key: u8) -> Vec<Target> {
    let (dist, centroid, hf_db, rows, sound) = (c.distance, c.centroid, c.hf_db, &c.rows, c.sound);
    let mut targets = Vec::new();
    targets.push(Target {
        name: "1/3-octave distance <= 6 dB",
        verdict: Verdict::of(dist <= TARGET_DISTANCE_DB),
        detail: format!("{dist:.1} dB"),
    });
    let cr = centroid.1 / centroid.0;
    targets.push(Target {
        name: "attack centroid 0.75-1.33x",
        verdict: Verdict::of((TARGET_CENTROID.0..=TARGET_CENTROID.1).contains(&cr)),
        detail: format!("{cr:.2}x"),
    });
    let hd = hf_db.1 - hf_db.0;
    let (hf_verdict, hf_detail) = if band_limit_hz < HF_HZ * 1.1 {
        (
            Verdict::NotApplicable,
            format!(
                "{hd:+.1} dB, but the recording stops at {:.1} kHz",
                band_limit_hz / 1000.0
            ),
        )
    } else {
        (
            Verdict::of(hd.abs() <= TARGET_HF_DB),
            format!("{hd:+.1} dB"),
        )
    };
    targets.push(Target {
        name: "energy > 5 kHz within +-6 dB",
        verdict: hf_verdict,
        detail: hf_detail,
    });
    let present = rows.iter().filter(|r| r.present()).count();
    let elsewhere = if own_key == sound.key_for(c.key) {
        String::new()
    } else {
        format!(", the recording at key {own_key}")
    };
    if c.strokes.is_some() {
        // a stroke's spectrum is its clicks' on the object, not partials
        // ringing down from one strike ("Strokes" says how it moves)
        for name in ["4 strongest partials within 15 cents", "T60 within 1.5x"] {
            targets.push(Target {
                name,
                verdict: Verdict::NotApplicable,
                detail: "a stroke, not a strike".into(),
            });
        }
    } else {
        targets.push(Target {
            name: "4 strongest partials within 15 cents",
            verdict: Verdict::of(present == rows.len() && rows.len() == PARTIALS),
            detail: format!("{present} of {}{elsewhere}", rows.len()),
        });
        targets.push(t60_target(rows));
    }
    let nearest = c
        .confusion
        .iter()
        .filter_map(|(s, d, _)| d.map(|d| (*s, d)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    targets.push(Target {
        name: "nearest recording is its own",
        verdict: Verdict::of(nearest.is_some_and(|(s, _)| s == sound)),
        detail: nearest.map_or("none".into(), |(s, d)| format!("{} ({d:.1} dB)", s.name())),
    });
    targets
}

/// The decay target: every partial fitted on both within
/// [`TARGET_T60_FACTOR`].
fn t60_target(rows: &[PartialRow]) -> Target {
    let ratios: Vec<f64> = rows.iter().filter_map(PartialRow::t60_ratio).collect();
    if ratios.is_empty() {
        return Target {
            name: "T60 within 1.5x",
            verdict: Verdict::NotApplicable,
            detail: "no partial with a fit on both".into(),
        };
    }
    let ok = ratios
        .iter()
        .filter(|r| (1.0 / TARGET_T60_FACTOR..=TARGET_T60_FACTOR).contains(*r))
        .count();
    Target {
        name: "T60 within 1.5x",
        verdict: Verdict::of(ok == ratios.len()),
        detail: format!("{ok} of {} fitted", ratios.len()),
    }
}

/// What FluidR3 offers for the presets that name no recording: preset
/// headers whose names say bell, chime, gong, plate, cymbal, triangle,
/// agogo or steel (not the steel-string guitar), each with the samples its zones play at key 72, and the
/// standard kit's metal keys with theirs.
fn bells_and_plates(sf: &SoundFont) -> String {
    const WORDS: [&str; 8] = [
        "bell", "chime", "gong", "plate", "cymbal", "triangle", "agogo", "steel",
    ];
    let samples = |bank: u16, program: u16, key: u8| -> String {
        match sf.key_region(bank, program, key, VELOCITY) {
            Ok(r) => {
                let mut names: Vec<String> = Vec::new();
                for z in &r.zones {
                    let n = format!("\"{}\"", z.name);
                    if !names.contains(&n) {
                        names.push(n);
                    }
                }
                names.join(", ")
            }
            Err(_) => "no zone".into(),
        }
    };
    let mut s = String::new();
    for h in sf.presets() {
        let low = h.name.to_lowercase();
        if h.bank < 128 && WORDS.iter().any(|w| low.contains(w)) && !low.contains("guitar") {
            let _ = writeln!(
                s,
                "- bank {} program {} \"{}\": key 72 plays {}",
                h.bank,
                h.program,
                h.name,
                samples(h.bank, h.program, 72)
            );
        }
    }
    for key in [49u8, 51, 52, 53, 55, 56, 57, 59, 80, 81] {
        let _ = writeln!(
            s,
            "- kit (bank 128 program 0) key {key} {}: plays {}",
            GmSound::Drum(key).name(),
            samples(128, 0, key)
        );
    }
    s
}

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

/// The confusion set: every instrument a preset names, then
/// [`CONFUSION_EXTRA`], each once.
fn confusion_set(all: &[PresetFile]) -> Vec<GmSound> {
    let mut set: Vec<GmSound> = Vec::new();
    for p in all {
        if let Ok(Some(s)) = p.real {
            if !set.contains(&s) {
                set.push(s);
            }
        }
    }
    for n in CONFUSION_EXTRA {
        let s = GmSound::parse(n).expect("a GM name");
        if !set.contains(&s) {
            set.push(s);
        }
    }
    set
}

/// The key each recording of the set is played at, for each compared
/// preset's key; and the recordings that takes, each once.
fn recording_keys(
    sf: &SoundFont,
    compared: &[(&PresetFile, GmSound)],
    set: &[GmSound],
) -> (BTreeMap<RecordingKey, u8>, Vec<RecordingKey>) {
    let mut keys: BTreeMap<RecordingKey, u8> = BTreeMap::new();
    let mut wanted: Vec<RecordingKey> = Vec::new();
    for (p, _) in compared {
        for &o in set {
            let k = playable_key(sf, o, p.key);
            keys.insert((o, p.key), k);
            if !wanted.contains(&(o, k)) {
                wanted.push((o, k));
            }
        }
    }
    (keys, wanted)
}

/// The [`SCALE_PAIRS`] with the key both are played at (the first's
/// preset's key, or middle C), their recordings added to `wanted`.
fn scale_pairs(
    sf: &SoundFont,
    all: &[PresetFile],
    wanted: &mut Vec<RecordingKey>,
) -> Vec<(GmSound, GmSound, u8)> {
    let key_of = |s: GmSound| -> u8 {
        all.iter()
            .find(|p| matches!(p.real, Ok(Some(x)) if x == s))
            .map_or(60, |p| p.key)
    };
    let pairs: Vec<(GmSound, GmSound, u8)> = SCALE_PAIRS
        .iter()
        .map(|(x, y)| {
            let (x, y) = (
                GmSound::parse(x).expect("GM"),
                GmSound::parse(y).expect("GM"),
            );
            (x, y, common_key(sf, x, y, key_of(x)))
        })
        .collect();
    for &(x, y, k) in &pairs {
        for s in [x, y] {
            if !wanted.contains(&(s, s.key_for(k))) {
                wanted.push((s, s.key_for(k)));
            }
        }
    }
    pairs
}

/// The same instruments, another recording each, at the first preset's
/// key.
fn other_recordings(
    sf: &SoundFont,
    compared: &[(&PresetFile, GmSound)],
) -> Vec<(GmSound, u8, Option<Played>)> {
    let mut own_sounds: Vec<(GmSound, u8)> = Vec::new();
    for (p, s) in compared {
        if !own_sounds.iter().any(|(x, _)| x == s) {
            own_sounds.push((*s, playable_key(sf, *s, p.key)));
        }
    }
    own_sounds
        .par_iter()
        .map(|&(s, k)| (s, k, another_recording(sf, s, k).map(Recording::new)))
        .collect()
}

/// Every recording of `wanted`, played.
fn play_recordings(
    sf: &SoundFont,
    wanted: &[RecordingKey],
) -> BTreeMap<RecordingKey, std::result::Result<Recording, String>> {
    wanted
        .par_iter()
        .map(|&(s, key)| {
            let (bank, program) = s.bank_program();
            let r = sf
                .key_region(bank, program, key, VELOCITY)
                .map_err(|e| format!("{e:#}"))
                .and_then(Recording::new);
            ((s, key), r)
        })
        .collect()
}

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
fn write_pair(dir: &Path, stem: &str, real: &[f64], render: &[f64]) -> Result<()> {
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

#[cfg(test)]
mod tests {
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
