//! `cargo xtask analyze-real`: the analysis of `cargo xtask analyze`
//! ([`crate::analyze::fit`]: the modes, the scene written, the distances)
//! run on real recordings, the raw sample data of the FluidR3 General MIDI
//! soundfont (Debian package `fluid-soundfont-gm`), read as `cargo xtask
//! compare-real` reads it ([`crate::compare_real::sf2`]).
//!
//! For each of nine struck instruments ([`INSTRUMENTS`]): the zones that
//! sound at the instrument's reference key, at velocity 100, played at
//! their sample's own root key (no transposition but the zones' fine
//! tuning and the samples' pitch correction, a few cents) and resampled
//! to 44.1 kHz, the stereo pair mixed to mono; analysed with `analyze`'s
//! options; the written scene rendered; and the render's 1/3-octave
//! distance to the recording over the first 0.5 s after each one's onset,
//! against the target of 3 dB ([`TARGET_DB`]). Writes the table and each
//! sample's strongest modes to `docs/analyze-real.md`, and each scene and
//! recording (`NAME.toml`, `NAME.wav`) into `target/analyze-real/`, so
//! `cargo xtask analyze target/analyze-real/NAME.wav` can be run on it.

use crate::analyze::{fit, Fit, DISTANCE_S};
use crate::benchmarks::Stamp;
use crate::compare_real::gm::GmSound;
use crate::compare_real::sf2::{KeyRegion, SoundFont, VELOCITY};
use crate::compare_real::{DEFAULT_SF2, RATE_HZ, SF2_PACKAGE};
use anyhow::{bail, Context, Result};
use clap::Args;
use modal_contact::recording::{AnalysisOptions, DropReason, DEFAULT_MALLET_KG};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// The target: the analysed scene's render within this of the recording
/// on the 1/3-octave distance over the first 0.5 s \[dB\] (issue 52).
pub const TARGET_DB: f64 = 3.0;

/// The strongest modes listed per sample.
pub const LISTED_MODES: usize = 12;

/// The instruments analysed (General MIDI names, all bank 0 programs), and
/// the reference key whose zones are taken, in the middle of each
/// instrument's range: C4 for marimba, vibraphone, tubular bells, steel
/// drums and woodblock, C5 for xylophone and celesta, C6 for the
/// glockenspiel, A2 for the timpani.
pub const INSTRUMENTS: [(&str, u8); 9] = [
    ("Marimba", 60),
    ("Vibraphone", 60),
    ("Glockenspiel", 84),
    ("Tubular Bells", 60),
    ("Xylophone", 72),
    ("Celesta", 72),
    ("Steel Drums", 60),
    ("Woodblock", 60),
    ("Timpani", 45),
];

/// `cargo xtask analyze-real [--instrument NAME]... [--out FILE] [--sf2
/// PATH] [--scenes DIR] [--check]` and `analyze`'s options.
#[derive(Args, Debug)]
pub struct AnalyzeRealArgs {
    /// The report to write.
    #[arg(long, default_value = "docs/analyze-real.md")]
    pub out: PathBuf,
    /// The General MIDI soundfont (Debian package fluid-soundfont-gm).
    #[arg(long, default_value = DEFAULT_SF2)]
    pub sf2: PathBuf,
    /// Analyse only this instrument (a General MIDI name of the nine,
    /// e.g. "Xylophone"; repeatable).
    #[arg(long = "instrument", value_name = "NAME")]
    pub instruments: Vec<String>,
    /// Where each analysed scene and its recording are written
    /// (NAME.toml, NAME.wav).
    #[arg(long, default_value = "target/analyze-real")]
    pub scenes: PathBuf,
    /// Exit non-zero when a sample misses the 3 dB target.
    #[arg(long)]
    pub check: bool,
    /// Start of the span fitted, from the recording's start (s); default:
    /// 5 ms after the onset.
    #[arg(long)]
    pub start: Option<f64>,
    /// End of the span fitted (s); default: the recording's end.
    #[arg(long)]
    pub end: Option<f64>,
    /// Keep at most this many modes (the strongest).
    #[arg(long)]
    pub modes: Option<usize>,
    /// Lowest mode frequency (Hz).
    #[arg(long, default_value_t = 20.0)]
    pub min_freq: f64,
    /// Highest mode frequency (Hz).
    #[arg(long, default_value_t = 20_000.0)]
    pub max_freq: f64,
    /// The mallet's mass in the scenes (kg).
    #[arg(long, default_value_t = DEFAULT_MALLET_KG)]
    pub mallet_kg: f64,
}

/// The instruments chosen: all of [`INSTRUMENTS`] for no name, else the
/// ones named (General MIDI names, compared loosely), in the table's
/// order; an error for a name not among them.
pub fn chosen(names: &[String]) -> Result<Vec<(GmSound, u8)>> {
    let all: Vec<(GmSound, u8)> = INSTRUMENTS
        .iter()
        .map(|&(n, k)| (GmSound::parse(n).expect("a General MIDI name"), k))
        .collect();
    for n in names {
        if !GmSound::parse(n).is_some_and(|s| all.iter().any(|(a, _)| *a == s)) {
            bail!(
                "instrument {n:?}: not one of {}",
                INSTRUMENTS.map(|(n, _)| n).join(", ")
            );
        }
    }
    Ok(all
        .into_iter()
        .filter(|(s, _)| names.is_empty() || names.iter().any(|n| GmSound::parse(n) == Some(*s)))
        .collect())
}

/// The zones' sample names, in order.
fn sample_names(r: &KeyRegion) -> Vec<&str> {
    r.zones.iter().map(|z| z.name.as_str()).collect()
}

/// The recording analysed for `sound`: the zones that sound at
/// `reference` (velocity 100), played at the first zone's root key when
/// the same zones sound there (untransposed); else played at `reference`
/// (a zone whose root key lies outside its key range).
pub fn sample_for(sf: &SoundFont, sound: GmSound, reference: u8) -> Result<KeyRegion> {
    let (bank, program) = sound.bank_program();
    let at_ref = sf.key_region(bank, program, reference, VELOCITY)?;
    let root = at_ref.zones[0].root_key;
    if let Ok(key) = u8::try_from(root) {
        if key < 128 {
            if let Ok(r) = sf.key_region(bank, program, key, VELOCITY) {
                if sample_names(&r) == sample_names(&at_ref) {
                    return Ok(r);
                }
            }
        }
    }
    Ok(at_ref)
}

/// A file name for an instrument: its name in lower case, spaces as `-`.
pub fn stem(sound: GmSound) -> String {
    sound.name().to_lowercase().replace(' ', "-")
}

/// One line of the table: what was analysed and what the analysis gave.
#[derive(Debug, Clone)]
pub struct Row {
    /// The General MIDI label (name and program).
    pub instrument: String,
    /// The samples played (a stereo pair's two).
    pub samples: String,
    /// The key played.
    pub key: u8,
    /// The largest transposition of the zones at that key \[cents\].
    pub cents: f64,
    /// The recording's length \[s\].
    pub seconds: f64,
    /// What the analysis gave, or why it failed.
    pub result: std::result::Result<Outcome, String>,
}

/// What the analysis of one sample gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Modes kept.
    pub modes: usize,
    /// Poles dropped, all reasons.
    pub dropped: usize,
    /// Of those, outside their band's centre (the neighbouring band's).
    pub outside: usize,
    /// Residual energy over the span fitted \[dB\].
    pub residual_db: f64,
    /// The resynthesis's distance \[dB\].
    pub resynthesis_db: f64,
    /// The written scene's render's distance \[dB\].
    pub render_db: f64,
    /// The resynthesis's and the render's distances over the free decay
    /// (from the span fitted's start) \[dB\].
    pub decay_db: (f64, f64),
    /// The strongest modes, by frequency: (frequency \[Hz\], T60 \[s\],
    /// level \[dB\]).
    pub strongest: Vec<(f64, f64, f64)>,
}

impl Outcome {
    /// From a fit.
    pub fn of(f: &Fit) -> Self {
        let mut strongest: Vec<(f64, f64, f64)> =
            f.an.modes
                .iter()
                .map(|m| (m.freq_hz, m.t60_s, m.level_db()))
                .collect();
        strongest.sort_by(|a, b| b.2.total_cmp(&a.2));
        strongest.truncate(LISTED_MODES);
        strongest.sort_by(|a, b| a.0.total_cmp(&b.0));
        Self {
            modes: f.an.modes.len(),
            dropped: f.an.dropped.len(),
            outside: f
                .an
                .dropped
                .iter()
                .filter(|d| d.reason == DropReason::OutsideBandCentre)
                .count(),
            residual_db: f.residual_db,
            resynthesis_db: f.resynthesis_db,
            render_db: f.render_db,
            decay_db: f.decay_db,
            strongest,
        }
    }

    /// Whether the render is within [`TARGET_DB`].
    pub fn passes(&self) -> bool {
        self.render_db <= TARGET_DB
    }
}

/// The table: one line per row.
pub fn table(rows: &[Row]) -> String {
    let mut t = String::from(
        "| instrument | sample | key | modes kept | poles dropped | residual energy | \
         resynthesis distance | render distance | 3 dB | free decay: resynthesis, render |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let key = if r.cents.abs() < 50.0 {
            format!("{}", r.key)
        } else {
            format!("{} ({:+.0} cents)", r.key, r.cents)
        };
        let rest = match &r.result {
            Ok(o) => format!(
                "{} | {} ({} outside their band's centre) | {:.1} dB | {:.2} dB | {:.2} dB | {} | \
                 {:.2} dB, {:.2} dB",
                o.modes,
                o.dropped,
                o.outside,
                o.residual_db,
                o.resynthesis_db,
                o.render_db,
                if o.passes() { "PASS" } else { "FAIL" },
                o.decay_db.0,
                o.decay_db.1
            ),
            // a message's `|` would end the cell
            Err(e) => format!("- | - | - | - | - | FAIL ({}) | -", e.replace('|', "\\|")),
        };
        let _ = writeln!(t, "| {} | {} | {key} | {rest} |", r.instrument, r.samples);
    }
    t
}

/// The strongest modes of each sample.
fn modes_text(rows: &[Row]) -> String {
    let mut t = String::new();
    for r in rows {
        let Ok(o) = &r.result else { continue };
        let _ = writeln!(
            t,
            "### {}\n\n{} key {}, {:.2} s: the {} strongest of {} modes.\n\n\
             | freq [Hz] | T60 [s] | level [dB] |\n|---|---|---|",
            r.instrument,
            r.samples,
            r.key,
            r.seconds,
            o.strongest.len(),
            o.modes
        );
        for (f, t60, l) in &o.strongest {
            let _ = writeln!(t, "| {f:.2} | {t60:.3} | {l:.1} |");
        }
        t.push('\n');
    }
    t
}

/// The command line that made the report.
pub fn command_line(a: &AnalyzeRealArgs) -> String {
    let mut c = String::from("cargo xtask analyze-real");
    for n in &a.instruments {
        let _ = write!(c, " --instrument {n:?}");
    }
    if let Some(s) = a.start {
        let _ = write!(c, " --start {s}");
    }
    if let Some(s) = a.end {
        let _ = write!(c, " --end {s}");
    }
    if let Some(m) = a.modes {
        let _ = write!(c, " --modes {m}");
    }
    if a.min_freq != 20.0 {
        let _ = write!(c, " --min-freq {}", a.min_freq);
    }
    if a.max_freq != 20_000.0 {
        let _ = write!(c, " --max-freq {}", a.max_freq);
    }
    if a.mallet_kg != DEFAULT_MALLET_KG {
        let _ = write!(c, " --mallet-kg {}", a.mallet_kg);
    }
    c
}

/// Analyse one instrument's recording; write its scene and WAV.
fn one(sf: &SoundFont, sound: GmSound, reference: u8, a: &AnalyzeRealArgs) -> Result<Row> {
    let region = sample_for(sf, sound, reference)?;
    let x = region
        .play(RATE_HZ)
        .map_err(|e| anyhow::anyhow!("playing {}: {e}", sound.label()))?;
    let cents =
        region
            .zones
            .iter()
            .map(|z| z.cents)
            .fold(0.0, |m: f64, c| if c.abs() > m.abs() { c } else { m });
    let opts = AnalysisOptions {
        freq_range_hz: (a.min_freq, a.max_freq),
        start_s: a.start,
        end_s: a.end,
        max_modes: a.modes,
        ..AnalysisOptions::default()
    };
    let name = stem(sound);
    let result = match fit(&x, RATE_HZ, &opts, &name, a.mallet_kg) {
        Ok(f) => {
            let toml = a.scenes.join(format!("{name}.toml"));
            std::fs::write(&toml, &f.text)
                .with_context(|| format!("cannot write {}", toml.display()))?;
            Ok(Outcome::of(&f))
        }
        Err(e) => Err(format!("{e:#}")),
    };
    let y: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    crate::offline::write_wav(
        &a.scenes.join(format!("{name}.wav")),
        RATE_HZ,
        &y,
        &y,
        crate::offline::WavFormat::Float32,
    )?;
    let samples = sample_names(&region).join(" + ");
    Ok(Row {
        instrument: sound.label(),
        samples: format!(
            "`{samples}` (bank {}, program {})",
            region.bank, region.program
        ),
        key: region.key,
        cents,
        seconds: x.len() as f64 / RATE_HZ,
        result,
    })
}

/// `cargo xtask analyze-real`.
pub fn run(a: &AnalyzeRealArgs) -> Result<()> {
    let t0 = Instant::now();
    crate::compare_real::require_sf2(&a.sf2)?;
    let list = chosen(&a.instruments)?;
    let sf = SoundFont::open(&a.sf2)?;
    std::fs::create_dir_all(&a.scenes)
        .with_context(|| format!("cannot create {}", a.scenes.display()))?;
    let rows: Vec<Row> = list
        .par_iter()
        .map(|&(s, k)| one(&sf, s, k, a).with_context(|| s.label()))
        .collect::<Result<_>>()?;
    let seconds = t0.elapsed().as_secs_f64();
    let md = report(a, &rows, &Stamp::here(), seconds);
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    std::fs::write(&a.out, &md).with_context(|| format!("cannot write {}", a.out.display()))?;
    print!("{}", table(&rows));
    eprintln!(
        "wrote {}, and the scenes and recordings into {} ({seconds:.1} s)",
        a.out.display(),
        a.scenes.display()
    );
    let failed: Vec<&str> = rows
        .iter()
        .filter(|r| !r.result.as_ref().is_ok_and(Outcome::passes))
        .map(|r| r.instrument.as_str())
        .collect();
    if a.check && !failed.is_empty() {
        bail!(
            "{} of {} samples miss {TARGET_DB} dB: {}",
            failed.len(),
            rows.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// The whole page.
pub fn report(a: &AnalyzeRealArgs, rows: &[Row], stamp: &Stamp, seconds: f64) -> String {
    let passed = rows
        .iter()
        .filter(|r| r.result.as_ref().is_ok_and(Outcome::passes))
        .count();
    let sf_name = a
        .sf2
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let mut md = String::from("# Objects analysed from real recordings\n\n");
    let _ = writeln!(
        md,
        "Generated by `{}` on {}, {} ({} cores), {}, {}, soundfont {sf_name} (Debian package \
         `{SF2_PACKAGE}`); the run took {seconds:.0} s; do not edit by hand.\n",
        command_line(a),
        stamp.date,
        stamp.cpu,
        stamp.cores,
        stamp.os,
        stamp.rustc
    );
    let _ = writeln!(
        md,
        "## Method\n\n\
         Each instrument's recording is FluidR3's raw sample data (`cargo xtask compare-real`'s \
         reader): the zones that sound at the instrument's reference key at velocity {VELOCITY}, \
         played at their sample's own root key (the key column; transposed only by the zones' \
         fine tuning and the sample's pitch correction, else the transposition is given), \
         without envelope, filter or loop, resampled to {RATE_HZ} Hz, a stereo pair mixed to \
         mono. `cargo xtask analyze`'s analysis \
         (docs/design.md, \"Your own object from a recording\") \
         finds its modes and writes a scene; the columns are what `analyze` \
         prints: the modes kept, the poles dropped, the residual's energy (recording minus \
         resynthesis, over the span fitted, relative to the recording's), the resynthesis's \
         1/3-octave distance to the recording and the written scene's render's, both over \
         the first {DISTANCE_S} s after the onset. The target (issue 52): the render within \
         {TARGET_DB} dB. The last column gives the same two distances over {DISTANCE_S} s from \
         the start of the span fitted (5 ms after the onset): the free decay the modes were \
         fitted on, without the attack (a recording shorter than that, the vibraphone's looped \
         sample, is compared over its own length). The scenes and recordings are in `target/analyze-real/` \
         (`NAME.toml`, `NAME.wav`).\n"
    );
    let _ = writeln!(
        md,
        "## Table\n\n{passed} of {} within {TARGET_DB} dB.\n\n{}",
        rows.len(),
        table(rows)
    );
    let _ = write!(md, "## The modes\n\n{}", modes_text(rows));
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare_real::sf2::tests::tiny_sf2;

    #[test]
    fn the_instruments_are_general_midi_programs_and_names_choose_them() {
        let all = chosen(&[]).unwrap();
        assert_eq!(all.len(), 9);
        assert!(all.iter().all(|(s, _)| !s.is_drum()));
        let two = chosen(&["timpani".into(), "Steel-Drums".into()]).unwrap();
        // in the table's order, whatever the order asked
        assert_eq!(
            two.iter().map(|(s, _)| s.name()).collect::<Vec<_>>(),
            ["Steel Drums", "Timpani"]
        );
        assert_eq!(stem(two[0].0), "steel-drums");
        let e = chosen(&["Bagpipe".into()]).unwrap_err().to_string();
        assert!(e.contains("Xylophone"), "{e}");
    }

    /// The zones at the reference key, played at their root key when the
    /// same zones sound there; else at the reference key.
    #[test]
    fn the_sample_is_played_at_its_root_key_when_its_zone_holds_it() {
        let sf = SoundFont::read(&mut std::io::Cursor::new(tiny_sf2())).unwrap();
        let marimba = GmSound::parse("Marimba").unwrap();
        // keys 60-127: sample "high", original pitch 60, no override
        let r = sample_for(&sf, marimba, 64).unwrap();
        assert_eq!((r.key, sample_names(&r)), (60, vec!["high"]));
        assert_eq!(r.zones[0].cents, 0.0);
        // keys 0-59: sample "low", root key 69 (outside its range): played
        // at the reference key
        let r = sample_for(&sf, marimba, 57).unwrap();
        assert_eq!((r.key, sample_names(&r)), (57, vec!["low"]));
        assert!(sample_for(&sf, GmSound::parse("Xylophone").unwrap(), 60).is_err());
    }

    #[test]
    fn the_table_says_pass_or_fail_against_3_db() {
        let row = |db: f64, result_ok: bool| Row {
            instrument: "Xylophone (program 13)".into(),
            samples: "`Xylo C5` (bank 0, program 13)".into(),
            key: 72,
            cents: if result_ok { 3.0 } else { -700.0 },
            seconds: 1.0,
            result: if result_ok {
                Ok(Outcome {
                    modes: 12,
                    dropped: 30,
                    outside: 20,
                    residual_db: -25.04,
                    resynthesis_db: 0.5,
                    render_db: db,
                    decay_db: (0.25, 1.5),
                    strongest: vec![(523.25, 0.8, -20.0)],
                })
            } else {
                Err("gain: |value| too big".into())
            },
        };
        let t = table(&[row(2.99, true), row(3.01, true), row(0.0, false)]);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 5);
        assert!(
            lines[2].ends_with("| 2.99 dB | PASS | 0.25 dB, 1.50 dB |"),
            "{}",
            lines[2]
        );
        assert!(
            lines[2].contains("| 72 | 12 | 30 (20 outside"),
            "{}",
            lines[2]
        );
        assert!(lines[2].contains("| -25.0 dB |"), "{}", lines[2]);
        assert!(lines[3].contains("| 3.01 dB | FAIL |"), "{}", lines[3]);
        assert!(lines[4].contains("| 72 (-700 cents) |"), "{}", lines[4]);
        assert!(
            lines[4].ends_with("FAIL (gain: \\|value\\| too big) | - |"),
            "{}",
            lines[4]
        );
    }

    #[test]
    fn a_missing_soundfont_names_the_package() {
        let a = AnalyzeRealArgs {
            out: std::env::temp_dir().join("analyze-real-never-written.md"),
            sf2: PathBuf::from("/nonexistent/FluidR3_GM.sf2"),
            instruments: vec![],
            scenes: std::env::temp_dir(),
            check: false,
            start: None,
            end: None,
            modes: None,
            min_freq: 20.0,
            max_freq: 20_000.0,
            mallet_kg: DEFAULT_MALLET_KG,
        };
        let e = run(&a).unwrap_err().to_string();
        assert!(e.contains(SF2_PACKAGE), "{e}");
        assert!(!a.out.exists());
        assert_eq!(
            command_line(&a),
            "cargo xtask analyze-real",
            "defaults are not repeated"
        );
    }
}
