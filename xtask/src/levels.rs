//! `cargo xtask levels [--check] [--write] [--out docs/levels.md]
//! [--presets DIR]`: how loud each preset is at the same velocity, and the
//! `level_db` that puts it at the common target (docs/design.md, "Offline
//! rendering", "Even levels").
//!
//! Each preset is struck once at velocity [`VELOCITY`] through the
//! instrument exactly as `cargo xtask render presets --velocities 100
//! --seconds 2` strikes it ([`crate::offline::play_note`] at the scene's
//! root, the plugin's parameter defaults), and measured over its first
//! [`LOUDNESS_S`]: the EBU R128 integrated loudness (ITU-R BS.1770:
//! K-weighting, 400 ms blocks, the absolute and the relative gate; the
//! `ebur128` crate) and the sample peak; then [`CHORD_KEYS`] keys around
//! the root are struck together at the same velocity and the chord's
//! sample peak is measured. `--write` rewrites each file's top-level
//! `level_db` line ([`set_level_line`]: every other byte stays), so that
//! its loudness meets [`TARGET_LUFS`]; `--check` fails naming every
//! preset outside [`TOLERANCE_LU`] of it or whose chord peaks above
//! [`CLIP_DBFS`].

use crate::benchmarks::{rustc_version, today};
use crate::offline::{play_notes, prepare_for, root_key};
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use modal_contact::instrument::{InstrumentParams, OUTPUT_CEILING};
use modal_contact::render::render_length;
use modal_contact::scene::{Scene, MAX_LEVEL_DB, MIN_LEVEL_DB};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Sample rate of the renders \[Hz\]: the render command's default.
pub const RATE_HZ: f64 = 44100.0;
/// The MIDI velocity every preset is measured at.
pub const VELOCITY: u8 = 100;
/// The stretch whose loudness and peaks are measured \[s\], from the
/// strike.
pub const LOUDNESS_S: f64 = 2.0;
/// The loudness every preset is set to at [`VELOCITY`] \[LUFS\]. It is
/// chosen for the chord's headroom, not for broadcast: a chord of
/// [`CHORD_KEYS`] keys struck on one sample adds its notes' attacks
/// almost in phase (up to 24 dB above one strike's peak), so the largest
/// chord crest of the presets ([`Measured::chord_crest_db`],
/// docs/levels.md) decides how loud they may be; at EBU R128's programme
/// level, -23 LUFS, most chords would clip (docs/design.md, "Even
/// levels"). Output gain is the player's.
pub const TARGET_LUFS: f64 = -45.0;
/// How far from [`TARGET_LUFS`] a preset may be \[LU\] before `--check`
/// fails: a step a listener barely notices when switching presets.
pub const TOLERANCE_LU: f64 = 2.0;
/// Keys of the chord.
pub const CHORD_KEYS: usize = 16;
/// The chord's span \[semitones\]: two octaves, the root in the middle.
pub const CHORD_SPAN: u8 = 24;
/// A chord peaking above this clips \[dBFS\] (one dB of margin for a
/// converter's inter-sample peaks).
pub const CLIP_DBFS: f64 = -1.0;
/// How far below [`CLIP_DBFS`] `--write` puts a chord that would clip at
/// the target \[dB\]: more than the 0.05 dB a level written to 0.1 dB may
/// round up.
pub const CHORD_MARGIN_DB: f64 = 0.1;
/// How often `--write` measures and writes again at most: a second pass
/// is needed only where a strike reached the instrument's output ceiling
/// (+12 dBFS) at its old level, so that its loudness was measured
/// clipped.
pub const MAX_WRITE_PASSES: usize = 3;
/// The comment of a `level_db` line `--write` adds.
pub const WRITTEN_BY: &str =
    "# output level, set by cargo xtask levels --write (docs/levels.md has the method)";

/// `cargo xtask levels [--check] [--write] [--out docs/levels.md]
/// [--presets DIR]`.
#[derive(Args, Debug, Clone)]
pub struct LevelsArgs {
    /// The scene files measured: every `*.toml` of this directory
    /// (default: the workspace's presets/).
    #[arg(long, value_name = "DIR")]
    pub presets: Option<PathBuf>,
    /// The generated page, Markdown (default: the workspace's
    /// docs/levels.md).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Exit non-zero naming every preset whose loudness is more than the
    /// tolerance from the target, or whose chord clips.
    #[arg(long)]
    pub check: bool,
    /// Rewrite each file's `level_db = ...` line (or add one) with the
    /// level that meets the target, then measure again: the page and
    /// `--check` see the written levels.
    #[arg(long)]
    pub write: bool,
}

/// How a scene plays a chord.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// One contact: a voice per key.
    Pitched,
    /// Several contacts whose mallets list no notes: a kit voice per key
    /// at the key's pitch (docs/design.md, "Played as a kit").
    PitchedKit,
    /// Several contacts whose mallets list notes: one kit voice at the
    /// scene's pitch, every note throws its mallets; it plays no chord,
    /// so its chord is its single strike.
    Drum,
}

impl Kind {
    fn word(self) -> &'static str {
        match self {
            Kind::Pitched => "pitched",
            Kind::PitchedKit => "kit, a voice per key",
            Kind::Drum => "kit, one voice (no chord)",
        }
    }
}

/// One preset measured.
#[derive(Debug, Clone)]
pub struct Measured {
    /// File name without `.toml`.
    pub stem: String,
    /// Its `level_db` as measured.
    pub level_db: f64,
    /// The key struck (its root).
    pub key: u8,
    /// How it plays a chord.
    pub kind: Kind,
    /// The chord's keys (the root alone for a drum).
    pub chord: Vec<u8>,
    /// Integrated loudness of the strike's first [`LOUDNESS_S`] \[LUFS\].
    pub lufs: f64,
    /// The strike's sample peak \[dBFS\].
    pub peak_dbfs: f64,
    /// The chord's sample peak \[dBFS\].
    pub chord_peak_dbfs: f64,
    /// The `level_db` that puts the strike at [`TARGET_LUFS`]
    /// ([`gain_for_loudness`] on the strike as rendered).
    pub target_level_db: f64,
}

impl Measured {
    /// The `level_db` `--write` writes: the one that puts the strike at
    /// [`TARGET_LUFS`], or, where the chord would peak above [`CLIP_DBFS`]
    /// there, the one that puts the chord's peak [`CHORD_MARGIN_DB`] below
    /// it, as long as the strike stays within [`TOLERANCE_LU`] of the
    /// target (further down, the target's lowest level: `--check` then
    /// names the clipping chord).
    pub fn level_for_target(&self) -> f64 {
        if self.chord_peak_at(self.target_level_db) <= CLIP_DBFS - CHORD_MARGIN_DB {
            return self.target_level_db;
        }
        let headroom = self.level_db + (CLIP_DBFS - CHORD_MARGIN_DB) - self.chord_peak_dbfs;
        headroom.max(self.target_level_db - TOLERANCE_LU)
    }

    /// The chord's peak over the strike's loudness \[dB\]: what decides
    /// how loud a preset may be before its chord clips.
    pub fn chord_crest_db(&self) -> f64 {
        self.chord_peak_dbfs - self.lufs
    }

    /// The chord's peak at [`Measured::level_for_target`] \[dBFS\].
    pub fn chord_peak_at_target(&self) -> f64 {
        self.chord_peak_at(self.level_for_target())
    }

    /// The chord's peak at `level_db` \[dBFS\] (peaks move dB for dB with
    /// the level).
    pub fn chord_peak_at(&self, level_db: f64) -> f64 {
        self.chord_peak_dbfs + level_db - self.level_db
    }

    /// What `--check` refuses, as phrases (empty: none).
    pub fn problems(&self) -> Vec<String> {
        let mut p = Vec::new();
        let off = self.lufs - TARGET_LUFS;
        if !(off.abs() <= TOLERANCE_LU) {
            p.push(format!(
                "loudness {:.1} LUFS, {off:+.1} LU from the target {TARGET_LUFS} +-{TOLERANCE_LU}",
                self.lufs
            ));
        }
        if !(self.chord_peak_dbfs <= CLIP_DBFS) {
            p.push(format!(
                "the chord peaks at {:.1} dBFS, above {CLIP_DBFS}",
                self.chord_peak_dbfs
            ));
        }
        p
    }
}

/// The EBU R128 integrated loudness of planar channels at `rate_hz`
/// \[LUFS\] (ITU-R BS.1770-4: K-weighted, mean square per 400 ms block
/// overlapping by 75 %, channels summed with weight 1 (left, right, or a
/// mono channel), gated at -70 LUFS and 10 LU below the ungated mean).
/// Silence is `-inf`.
pub fn loudness_lufs(channels: &[&[f32]], rate_hz: f64) -> Result<f64> {
    let n = u32::try_from(channels.len()).map_err(|_| anyhow!("too many channels"))?;
    let mut m = ebur128::EbuR128::new(n, rate_hz.round() as u32, ebur128::Mode::I)
        .map_err(|e| anyhow!("loudness meter: {e}"))?;
    m.add_frames_planar_f32(channels)
        .map_err(|e| anyhow!("loudness meter: {e}"))?;
    m.loudness_global()
        .map_err(|e| anyhow!("loudness meter: {e}"))
}

/// The gain \[dB\] that brings `channels` to the integrated loudness
/// `target` \[LUFS\], to 0.01 LU. A scene's level scales its output by
/// exactly its gain (tests/level.rs), so the loudness of the output at
/// another level is that of these samples times the gain; but the gain is
/// not the target minus the loudness: the absolute gate (-70 LUFS) does
/// not move with the signal, so a quiet tail's blocks join or leave the
/// measure as the level moves, and the relative gate with them. So the
/// gain is found on the gated measure itself: each step moves it by what
/// is still missing.
pub fn gain_for_loudness(channels: &[&[f32]], rate_hz: f64, target: f64) -> Result<f64> {
    let at = |db: f64| -> Result<f64> {
        let g = 10f64.powf(db / 20.0);
        let scaled: Vec<Vec<f32>> = channels
            .iter()
            .map(|c| c.iter().map(|&x| (f64::from(x) * g) as f32).collect())
            .collect();
        let refs: Vec<&[f32]> = scaled.iter().map(Vec::as_slice).collect();
        loudness_lufs(&refs, rate_hz)
    };
    let mut db = target - loudness_lufs(channels, rate_hz)?;
    if !db.is_finite() {
        bail!("silence has no loudness to set");
    }
    let mut best = (f64::INFINITY, db);
    for _ in 0..12 {
        let miss = target - at(db)?;
        if miss.abs() < best.0 {
            best = (miss.abs(), db);
        }
        if miss.abs() < 0.01 {
            break;
        }
        db += miss;
    }
    Ok(best.1)
}

/// Whether a peak \[dBFS\] is the instrument's output ceiling
/// ([`OUTPUT_CEILING`], +12 dBFS): the signal was held there.
pub fn at_ceiling(peak_dbfs: f64) -> bool {
    peak_dbfs >= 20.0 * OUTPUT_CEILING.log10() - 0.01
}

/// The largest sample magnitude of the channels \[dBFS\] (`-inf` for
/// silence).
pub fn sample_peak_dbfs(channels: &[&[f32]]) -> f64 {
    let peak = channels
        .iter()
        .flat_map(|c| c.iter())
        .fold(0.0f64, |m, x| m.max(f64::from(x.abs())));
    20.0 * peak.log10()
}

/// [`CHORD_KEYS`] keys over [`CHORD_SPAN`] semitones, as evenly as
/// semitones allow, the root in the middle (moved inside 0..=127 near
/// the keyboard's ends).
pub fn chord_keys(root: u8) -> Vec<u8> {
    let span = i32::from(CHORD_SPAN);
    let lo = (i32::from(root) - span / 2).clamp(0, 127 - span);
    (0..CHORD_KEYS)
        .map(|i| {
            let step = (i as f64 * f64::from(span) / (CHORD_KEYS - 1) as f64).round() as i32;
            (lo + step) as u8
        })
        .collect()
}

/// Measure one scene file.
pub fn measure(path: &Path) -> Result<Measured> {
    let scene = Scene::from_file(path).with_context(|| path.display().to_string())?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let params = InstrumentParams::default();
    let (prepared, _) = prepare_for(&scene, &params, RATE_HZ)?;
    let kind = match &prepared.kit {
        None => Kind::Pitched,
        Some(k) if k.pitched => Kind::PitchedKit,
        Some(_) => Kind::Drum,
    };
    let n = render_length(LOUDNESS_S, RATE_HZ)?;
    let key = root_key(&scene);
    let one = play_notes(&prepared, &params, &[key], VELOCITY, n);
    let single = [one.left.as_slice(), one.right.as_slice()];
    let lufs = loudness_lufs(&single, RATE_HZ)?;
    let target_level_db = scene.level_db + gain_for_loudness(&single, RATE_HZ, TARGET_LUFS)?;
    let peak_dbfs = sample_peak_dbfs(&single);
    let (chord, chord_peak_dbfs) = if kind == Kind::Drum {
        (vec![key], peak_dbfs)
    } else {
        let keys = chord_keys(key);
        let c = play_notes(&prepared, &params, &keys, VELOCITY, n);
        let p = sample_peak_dbfs(&[c.left.as_slice(), c.right.as_slice()]);
        (keys, p)
    };
    if !lufs.is_finite() || !peak_dbfs.is_finite() {
        bail!("{}: the strike is silent", path.display());
    }
    Ok(Measured {
        stem,
        level_db: scene.level_db,
        key,
        kind,
        chord,
        lufs,
        peak_dbfs,
        chord_peak_dbfs,
        target_level_db,
    })
}

/// `level_db` as `--write` spells it: 0.1 dB, no negative zero.
pub fn format_level(level_db: f64) -> String {
    let r = (level_db * 10.0).round() / 10.0;
    format!("{:.1}", if r == 0.0 { 0.0 } else { r })
}

/// Whether `line` sets the top-level key `key` (`key = ...`).
fn sets_key(line: &str, key: &str) -> bool {
    line.trim_start()
        .strip_prefix(key)
        .is_some_and(|rest| rest.trim_start().starts_with('='))
}

/// `text` (a scene file) with its top-level `level_db` set to `level_db`
/// ([`format_level`]): the value of an existing `level_db = ...` line is
/// replaced (its indentation, spacing and comment kept); without one, a
/// line `level_db = V  # ...` ([`WRITTEN_BY`]) goes after the last
/// top-level `real_instrument` or `duration_s` line, else right before
/// the first table, else at the end. Every other byte is kept (line
/// endings included). Top level: the lines before the first table header
/// that is not inside a multi-line string.
pub fn set_level_line(text: &str, level_db: f64) -> String {
    let value = format_level(level_db);
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    // the top level: lines before the first table header; a line that
    // starts inside a multi-line string sets no key
    let mut open: Option<&str> = None;
    let mut top_end = lines.len();
    let mut key_line = vec![false; lines.len()];
    for (i, l) in lines.iter().enumerate() {
        if open.is_none() {
            if l.trim_start().starts_with('[') {
                top_end = i;
                break;
            }
            key_line[i] = true;
        }
        for delim in ["\"\"\"", "'''"] {
            if open.is_none_or(|d| d == delim) && l.matches(delim).count() % 2 == 1 {
                open = if open.is_some() { None } else { Some(delim) };
            }
        }
    }
    let top_key = |keys: &[&str]| {
        (0..top_end)
            .filter(|&i| key_line[i] && keys.iter().any(|k| sets_key(lines[i], k)))
            .collect::<Vec<usize>>()
    };
    let mut out = String::with_capacity(text.len() + 80);
    if let Some(&at) = top_key(&["level_db"]).first() {
        let l = lines[at];
        let eq = l.find('=').expect("a key line") + 1;
        let after = &l[eq..];
        let ws = after.len() - after.trim_start().len();
        let start = eq + ws;
        let end = start
            + l[start..]
                .find(|c: char| c.is_whitespace() || c == '#')
                .unwrap_or(l.len() - start);
        for (i, line) in lines.iter().enumerate() {
            if i == at {
                out.push_str(&l[..start]);
                out.push_str(&value);
                out.push_str(&l[end..]);
            } else {
                out.push_str(line);
            }
        }
        return out;
    }
    let new_line = |eol: &str| format!("level_db = {value}  {WRITTEN_BY}{eol}");
    let after = top_key(&["real_instrument", "duration_s"]).last().copied();
    let eol_of = |l: &str| if l.ends_with("\r\n") { "\r\n" } else { "\n" };
    match after {
        Some(at) => {
            for (i, line) in lines.iter().enumerate() {
                out.push_str(line);
                if i == at {
                    if !line.ends_with('\n') {
                        out.push('\n');
                    }
                    out.push_str(&new_line(eol_of(line)));
                }
            }
        }
        None if top_end < lines.len() => {
            for (i, line) in lines.iter().enumerate() {
                if i == top_end {
                    out.push_str(&new_line(eol_of(line)));
                }
                out.push_str(line);
            }
        }
        None => {
            out.push_str(text);
            if !text.is_empty() && !text.ends_with('\n') {
                out.push('\n');
            }
            let eol = lines.first().map_or("\n", |l| eol_of(l));
            out.push_str(&new_line(eol));
        }
    }
    out
}

/// Rewrite `path`'s `level_db` to `level_db`, checking that the new text
/// is the same scene with that level (and nothing else changed).
pub fn write_level(path: &Path, level_db: f64) -> Result<()> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let new = set_level_line(&text, level_db);
    let before = Scene::from_toml_str(&text).with_context(|| path.display().to_string())?;
    let after = Scene::from_toml_str(&new)
        .with_context(|| format!("{}: the rewritten file", path.display()))?;
    let want: f64 = format_level(level_db).parse().expect("a number");
    if after.level_db != want
        || (Scene {
            level_db: want,
            ..before
        }) != after
    {
        bail!(
            "{}: rewriting its level_db line would change more than the level (is level_db set \
             inside a table or a multi-line string?)",
            path.display()
        );
    }
    if new != text {
        std::fs::write(path, new).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}

/// The scene files of `dir` (`*.toml`, sorted).
fn scene_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "toml"))
        .collect();
    if files.is_empty() {
        bail!("{}: no .toml scene files", dir.display());
    }
    files.sort();
    Ok(files)
}

/// The CPU model and its cores (the benchmarks page's stamp).
fn machine() -> String {
    let st = crate::benchmarks::Stamp::here();
    format!("{}, {} cores", st.cpu, st.cores)
}

/// The page's method section.
fn method_text() -> String {
    format!(
        "Each preset is struck once at MIDI velocity {VELOCITY} through the instrument, exactly as `cargo xtask render \
presets --velocities {VELOCITY} --seconds {LOUDNESS_S}` strikes it (its root key, the plugin's parameter defaults: Output \
gain -6 dB, {RATE_HZ} Hz), and its first {LOUDNESS_S} s are measured:

- **Loudness**: EBU R128 integrated loudness (ITU-R BS.1770-4: K-weighting, 400 ms blocks overlapping by 75 %, \
left and right summed, the absolute gate at -70 LUFS and the relative gate 10 LU below; the `ebur128` crate), in LUFS.
- **Peak**: the largest sample of either channel, in dBFS.
- **Chord peak**: {CHORD_KEYS} keys over two octaves, the root in the middle (root - 12 to root + 12, as evenly as \
semitones allow), struck together at velocity {VELOCITY}: the largest sample of either channel. A kit whose mallets \
list no notes plays it with a kit voice per key; a kit whose mallets list notes (a drum: one kit voice, every note \
throws its mallets) plays no chord, and its chord peak is its single strike's.
- **Chord crest**: the chord's peak over the single strike's loudness, in dB. Struck on one sample, the notes' \
attacks add almost in phase (up to 24 dB above one strike's peak); the largest crest decides how loud the presets \
may be before a chord clips.
- **Target**: {TARGET_LUFS} LUFS +-{TOLERANCE_LU} LU, and no chord above {CLIP_DBFS} dBFS. The target is set by the \
chords' headroom: with crests up to about 42 dB, a louder target (EBU R128's programme level, -23 LUFS, would be the \
usual one) would make most chords clip; Output gain is the player's. \"level_db for target\" is the \
level that puts the strike at {TARGET_LUFS} LUFS, or, where the chord would peak above {CLIP_DBFS} dBFS there, the \
level that puts the chord {CHORD_MARGIN_DB} dB below it, as long as the strike stays within {TOLERANCE_LU} LU of the \
target: a scene's level is a gain on every pickup, so the output scales by \
exactly that gain: its peaks move dB for dB with it, and its loudness nearly so (the absolute gate at -70 LUFS \
does not move with the signal, so a quiet tail's blocks join or leave the measure as the level moves: up to about \
1 LU here). So the level is found on these samples scaled to it, measured again until within 0.01 LU, and one \
`cargo xtask levels --write` lands on the target to the 0.1 dB it writes; \"chord peak at target\" says where each \
chord then peaks (\">=\": the chord reached the instrument's output ceiling, +12 dBFS, and was held there; a \
strike that reached it was measured clipped, so `--write` measures and writes again, up to {MAX_WRITE_PASSES} passes, \
until no level moves)."
    )
}

/// The table of measured presets (Markdown).
fn table(rows: &[Result<Measured>], files: &[PathBuf]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| preset | plays | key | level_db | loudness [LUFS] | peak [dBFS] | chord peak [dBFS] | chord crest [dB] | level_db for target | chord peak at target [dBFS] | check |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for (r, f) in rows.iter().zip(files) {
        match r {
            Ok(m) => {
                let problems = m.problems();
                // a chord the output ceiling held peaks higher at any level
                let at_target = if at_ceiling(m.chord_peak_dbfs) {
                    format!(">= {:.1}", m.chord_peak_at_target())
                } else {
                    format!("{:.1}", m.chord_peak_at_target())
                };
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {} |",
                    m.stem,
                    m.kind.word(),
                    m.key,
                    format_level(m.level_db),
                    m.lufs,
                    m.peak_dbfs,
                    m.chord_peak_dbfs,
                    m.chord_crest_db(),
                    format_level(m.level_for_target()),
                    at_target,
                    if problems.is_empty() {
                        "ok".to_string()
                    } else {
                        problems.join("; ")
                    }
                );
            }
            Err(e) => {
                let _ = writeln!(
                    s,
                    "| {} | error: {e:#} | | | | | | | | | |",
                    f.file_stem().unwrap_or_default().to_string_lossy()
                );
            }
        }
    }
    s
}

/// Measure every scene file, on a pool of its own, one job per core (as
/// `cargo xtask render` runs its jobs: the instrument's preparation runs
/// compiles on threads of its own whose linear algebra waits on rayon's
/// global pool, so the jobs must not occupy that pool).
fn measure_all(files: &[PathBuf]) -> Result<Vec<Result<Measured>>> {
    let pool = rayon::ThreadPoolBuilder::new().build()?;
    Ok(pool.install(|| files.par_iter().map(|f| measure(f)).collect()))
}

/// `cargo xtask levels`.
pub fn run(a: &LevelsArgs) -> Result<()> {
    let t0 = std::time::Instant::now();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let presets = a.presets.clone().unwrap_or_else(|| root.join("presets"));
    let out = a.out.clone().unwrap_or_else(|| root.join("docs/levels.md"));
    let files = scene_files(&presets)?;
    let mut rows = measure_all(&files)?;
    let written = if a.write {
        write_levels(&files, &mut rows)?
    } else {
        String::new()
    };
    let mut md = String::new();
    let _ = writeln!(md, "# Preset levels\n");
    let _ = writeln!(
        md,
        "Generated by `cargo xtask levels{}` on {} with {} on {}; do not edit by hand.\n",
        if a.write { " --write" } else { "" },
        today(),
        rustc_version(),
        machine()
    );
    let body = table(&rows, &files);
    let summary = summary_line(&rows);
    let _ = writeln!(md, "## Method\n\n{}\n", method_text());
    let _ = writeln!(md, "## Levels\n\n{written}{body}\n{summary}");
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    std::fs::write(&out, &md).with_context(|| format!("cannot write {}", out.display()))?;
    print!("{body}");
    println!("{summary}");
    eprintln!(
        "wrote {} ({:.1} s)",
        out.display(),
        t0.elapsed().as_secs_f64()
    );
    if a.check {
        check_levels(&rows, &files)?;
    }
    Ok(())
}

/// `--write`: set each scene file's level to its target's and measure
/// `rows` again, until none moves (at most [`MAX_WRITE_PASSES`] passes).
/// Returns the line the report says it with.
fn write_levels(files: &[PathBuf], rows: &mut Vec<Result<Measured>>) -> Result<String> {
    let mut written = String::new();
    let mut passes = 0;
    let mut files_written = 0;
    while passes < MAX_WRITE_PASSES {
        // every level first, so that a refusal writes no file
        let mut levels = Vec::new();
        for (r, f) in rows.iter().zip(files) {
            let Ok(m) = r else { continue };
            let level = m.level_for_target();
            if format_level(level) == format_level(m.level_db) {
                continue;
            }
            if !(MIN_LEVEL_DB..=MAX_LEVEL_DB).contains(&level) {
                bail!(
                    "{}: the level for the target, {level:.1} dB, is outside {MIN_LEVEL_DB} ..= \
                     {MAX_LEVEL_DB}: not written",
                    f.display()
                );
            }
            levels.push((f, m, level));
        }
        if levels.is_empty() {
            break;
        }
        passes += 1;
        let mut moved = Vec::new();
        for (f, m, level) in levels {
            write_level(f, level)?;
            moved.push(format!(
                "{}: level_db {} -> {}",
                m.stem,
                format_level(m.level_db),
                format_level(level)
            ));
        }
        files_written += moved.len();
        eprintln!(
            "pass {passes}: wrote {} files:\n  {}",
            moved.len(),
            moved.join("\n  ")
        );
        *rows = measure_all(files)?;
    }
    let _ = writeln!(
        written,
        "`--write` wrote {files_written} levels in {passes} pass{} and measured again (this table).\n",
        if passes == 1 { "" } else { "es" }
    );
    Ok(written)
}

/// The table's last line: the loudness and peak spreads, and the presets
/// off their level.
fn summary_line(rows: &[Result<Measured>]) -> String {
    let finite: Vec<&Measured> = rows.iter().flatten().collect();
    let spread = |f: &dyn Fn(&Measured) -> f64| {
        let lo = finite.iter().map(|m| f(m)).fold(f64::INFINITY, f64::min);
        let hi = finite
            .iter()
            .map(|m| f(m))
            .fold(f64::NEG_INFINITY, f64::max);
        hi - lo
    };
    format!(
        "Over {} presets: loudness spread {:.1} LU, peak spread {:.1} dB; {} outside {TARGET_LUFS} +-{TOLERANCE_LU} \
         LUFS or clipping a chord.",
        finite.len(),
        spread(&|m| m.lufs),
        spread(&|m| m.peak_dbfs),
        rows.iter()
            .filter(|r| !r.as_ref().is_ok_and(|m| m.problems().is_empty()))
            .count()
    )
}

/// `--check`: every preset at its level, or an error listing those that
/// are not.
fn check_levels(rows: &[Result<Measured>], files: &[PathBuf]) -> Result<()> {
    let failures: Vec<String> = rows
        .iter()
        .zip(files)
        .filter_map(|(r, f)| match r {
            Ok(m) => {
                let p = m.problems();
                (!p.is_empty()).then(|| format!("{}: {}", m.stem, p.join("; ")))
            }
            Err(e) => Some(format!("{}: {e:#}", f.display())),
        })
        .collect();
    if !failures.is_empty() {
        bail!(
            "{} presets off their level (`cargo xtask levels --write` sets them):\n  {}",
            failures.len(),
            failures.join("\n  ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1 kHz sine at -20 dBFS (amplitude 0.1) on one channel reads -23.0
    /// LUFS (BS.1770's calibration: K-weighting is +0.69 dB at 1 kHz, and
    /// -0.691 + 10 log10(0.1^2 / 2) + 0.69 = -23.0); on both channels of a
    /// stereo pair, 3 dB more (the channels' powers add); a gain of one
    /// half, 6.02 dB less; silence is -inf.
    #[test]
    fn a_full_scale_sine_reads_its_closed_form_loudness() {
        let rate = 48_000.0;
        let sine: Vec<f32> = (0..(5.0 * rate) as usize)
            .map(|i| (0.1 * (2.0 * std::f64::consts::PI * 1000.0 * i as f64 / rate).sin()) as f32)
            .collect();
        let mono = loudness_lufs(&[&sine], rate).unwrap();
        assert!((mono + 23.0).abs() <= 0.1, "{mono}");
        let stereo = loudness_lufs(&[&sine, &sine], rate).unwrap();
        assert!(
            (stereo - mono - 10.0 * 2f64.log10()).abs() <= 1e-3,
            "{stereo}"
        );
        let half: Vec<f32> = sine.iter().map(|x| 0.5 * x).collect();
        let quieter = loudness_lufs(&[&half], rate).unwrap();
        assert!(
            (mono - quieter - 20.0 * 2f64.log10()).abs() <= 1e-3,
            "{quieter}"
        );
        let at_44k: Vec<f32> = (0..(5.0 * RATE_HZ) as usize)
            .map(|i| {
                (0.1 * (2.0 * std::f64::consts::PI * 1000.0 * i as f64 / RATE_HZ).sin()) as f32
            })
            .collect();
        let m44 = loudness_lufs(&[&at_44k], RATE_HZ).unwrap();
        assert!((m44 + 23.0).abs() <= 0.1, "{m44}");
        assert_eq!(
            loudness_lufs(&[&vec![0.0f32; 48_000]], rate).unwrap(),
            f64::NEG_INFINITY
        );
        assert!((sample_peak_dbfs(&[&sine]) + 20.0).abs() < 1e-3);
    }

    /// A chord that would clip at the target lowers the written level, by
    /// no more than the tolerance; one that does not leaves it at the
    /// target.
    #[test]
    fn a_chord_that_would_clip_lowers_the_level_within_the_tolerance() {
        let m = |chord_peak_dbfs: f64| Measured {
            stem: "x".into(),
            level_db: -10.0,
            key: 60,
            kind: Kind::Pitched,
            chord: vec![60],
            lufs: -44.0,
            peak_dbfs: -20.0,
            chord_peak_dbfs,
            target_level_db: -11.0,
        };
        // at the target the chord peaks 1 dB lower than measured
        assert_eq!(m(-3.0).level_for_target(), -11.0);
        let lowered = m(0.0).level_for_target();
        assert!((lowered - (-10.0 - 1.1)).abs() < 1e-12, "{lowered}");
        let l = m(1.5).level_for_target();
        assert!((l - (-12.6)).abs() < 1e-12, "{l}");
        assert!((l + 10.0 + 1.5 - (CLIP_DBFS - CHORD_MARGIN_DB)).abs() < 1e-12);
        // further than the tolerance: the target's lowest level
        assert_eq!(m(5.0).level_for_target(), -11.0 - TOLERANCE_LU);
    }

    #[test]
    fn the_chord_spans_two_octaves_around_the_root() {
        let c = chord_keys(57);
        assert_eq!(c.len(), CHORD_KEYS);
        assert_eq!((c[0], c[CHORD_KEYS - 1]), (45, 69));
        assert!(c.windows(2).all(|w| w[1] > w[0] && w[1] - w[0] <= 2));
        assert_eq!(chord_keys(2)[0], 0);
        assert_eq!(*chord_keys(126).last().unwrap(), 127);
    }

    const SCENE: &str = "# a comment\n#\nversion = 1\nname = \"x\"\ndescription = \"d\"\nduration_s = 1.5\n\
real_instrument = \"Marimba\"  # compared\n\n[[object]]  # the bar\nname = \"bar\"\nduration_s = 9.0\n";

    #[test]
    fn a_level_line_is_inserted_after_the_top_level_keys() {
        let out = set_level_line(SCENE, -7.26);
        let want = SCENE.replace(
            "# compared\n",
            &format!("# compared\nlevel_db = -7.3  {WRITTEN_BY}\n"),
        );
        assert_eq!(out, want);
        // without real_instrument: after duration_s (the top level's, not
        // the table's)
        let plain = SCENE.replace("real_instrument = \"Marimba\"  # compared\n", "");
        let out = set_level_line(&plain, 3.0);
        assert_eq!(
            out,
            plain.replace(
                "duration_s = 1.5\n",
                &format!("duration_s = 1.5\nlevel_db = 3.0  {WRITTEN_BY}\n")
            )
        );
        // neither: right before the first table
        let bare = "version = 1\nname = \"x\"\n\n[hammer]\nmass_kg = 1.0\n";
        assert_eq!(
            set_level_line(bare, -0.04),
            format!("version = 1\nname = \"x\"\n\nlevel_db = 0.0  {WRITTEN_BY}\n[hammer]\nmass_kg = 1.0\n")
        );
        // no table, no final newline
        assert_eq!(
            set_level_line("version = 1", 1.0),
            format!("version = 1\nlevel_db = 1.0  {WRITTEN_BY}\n")
        );
        // CRLF files get a CRLF line
        let crlf = SCENE.replace('\n', "\r\n");
        let out = set_level_line(&crlf, -1.0);
        assert_eq!(
            out,
            crlf.replace(
                "# compared\r\n",
                &format!("# compared\r\nlevel_db = -1.0  {WRITTEN_BY}\r\n")
            )
        );
    }

    #[test]
    fn an_existing_level_line_keeps_everything_but_its_value() {
        let once = set_level_line(SCENE, -7.26);
        let twice = set_level_line(&once, 12.0);
        assert_eq!(twice, once.replace("level_db = -7.3", "level_db = 12.0"));
        let hand = SCENE.replace(
            "duration_s = 1.5\n",
            "duration_s = 1.5\n  level_db=4   # by ear\n",
        );
        assert_eq!(
            set_level_line(&hand, -2.0),
            hand.replace("level_db=4   # by ear", "level_db=-2.0   # by ear")
        );
        // a level_db inside a table or a multi-line string is not the
        // top level's
        let in_string = "version = 1\ndescription = \"\"\"\nlevel_db = 3\n[x]\n\"\"\"\nduration_s = 1.0\n[hammer]\n";
        assert_eq!(
            set_level_line(in_string, 1.0),
            in_string.replace(
                "duration_s = 1.0\n",
                &format!("duration_s = 1.0\nlevel_db = 1.0  {WRITTEN_BY}\n")
            )
        );
    }

    #[test]
    fn levels_are_written_to_a_tenth_of_a_db() {
        assert_eq!(format_level(-7.26), "-7.3");
        assert_eq!(format_level(-0.04), "0.0");
        assert_eq!(format_level(0.06), "0.1");
        assert_eq!(format_level(12.0), "12.0");
    }
}
