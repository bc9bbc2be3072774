//! `cargo xtask render`: one scene to a WAV (with its trace and plot if
//! asked), or a batch (several scene files, directories, lists of notes and
//! velocities) rendered on all cores with a JSON sidecar per WAV
//! (docs/design.md, "Offline rendering").

use crate::offline::{self, check_writable, parse_midi_list, play_note, prepare_for, WavFormat};
use crate::plot;
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use modal_contact::compile::CompiledScene;
use modal_contact::instrument::InstrumentParams;
use modal_contact::multi::CompiledMulti;
use modal_contact::render::{
    render_length, render_stream, CsvTrace, NpyTrace, StreamStats, TraceEnvelope, TraceSink,
};
use modal_contact::scene::{Scene, Switching};
use modal_contact::Compiled;
use rayon::prelude::*;
use serde_json::json;
use std::io::{BufWriter, IsTerminal};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The trace file's format (docs/design.md, "The render command and the
/// trace CSV").
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TraceFormat {
    /// Text, one row per sample, shortest round-trip digits.
    #[default]
    Csv,
    /// NumPy `.npy`: the same columns as named f64 fields, the numbers'
    /// own bits (no text: several times cheaper to write and read).
    Npy,
}

impl TraceFormat {
    /// The format of a trace path: `.npy` is NumPy, anything else CSV.
    pub fn of(path: &Path) -> Self {
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
        {
            TraceFormat::Npy
        } else {
            TraceFormat::Csv
        }
    }

    fn extension(self) -> &'static str {
        match self {
            TraceFormat::Csv => "csv",
            TraceFormat::Npy => "npy",
        }
    }
}

/// The switching method, as the command line spells it.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchingArg {
    /// Every crossing located inside the sample on the exact solution.
    Exact,
    /// The paper's method: contact starts at a sample instant.
    OffsetRod,
}

impl From<SwitchingArg> for Switching {
    fn from(s: SwitchingArg) -> Self {
        match s {
            SwitchingArg::Exact => Switching::Exact,
            SwitchingArg::OffsetRod => Switching::OffsetRod,
        }
    }
}

/// `cargo xtask render`.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Scene files (TOML) and directories of scene files. One file and no
    /// --notes/--velocities: --out is the WAV. Otherwise a batch: --out is
    /// a directory.
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// Output WAV (one scene) or directory (batch).
    #[arg(long)]
    pub out: PathBuf,
    /// Trace, one row per sample: CSV, or NumPy if the path ends in .npy.
    /// In a batch, give it without a path: each scene's trace goes next to
    /// its WAV (in --trace-format).
    #[arg(long, num_args = 0..=1)]
    pub trace: Option<Option<PathBuf>>,
    /// The format of a trace written next to its WAV (--trace without a
    /// path).
    #[arg(long, value_enum, default_value_t = TraceFormat::Csv)]
    pub trace_format: TraceFormat,
    /// Plot of hammer height, contact-point displacement and energy (SVG).
    /// Without a path: next to the WAV.
    #[arg(long, num_args = 0..=1)]
    pub plot: Option<Option<PathBuf>>,
    /// Length in seconds (default: each scene's duration_s).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Sample rate in Hz.
    #[arg(long, default_value_t = 44100.0)]
    pub rate: f64,
    /// Switching method (default: the scene's, else the project default).
    #[arg(long, value_enum)]
    pub switching: Option<SwitchingArg>,
    /// MIDI notes to strike, played through the instrument as the plugin
    /// plays them (e.g. `60`, `48,55,60`, `36..96:3`). Default with
    /// --velocities: the note that plays each scene as written.
    #[arg(long)]
    pub notes: Option<String>,
    /// MIDI velocities 1-127 (same syntax). Default with --notes: 100.
    #[arg(long)]
    pub velocities: Option<String>,
    /// Worker threads (default: every core).
    #[arg(long)]
    pub jobs: Option<usize>,
}

/// What a job plays.
#[derive(Debug, Clone, PartialEq)]
pub enum JobKind {
    /// The scene as written (its hammer, its initial state), engine only.
    Scene,
    /// One strike through the instrument.
    Note {
        /// MIDI note.
        note: u8,
        /// MIDI velocity.
        velocity: u8,
    },
}

/// One render: a pure function of its scene file and these parameters.
#[derive(Debug, Clone)]
pub struct Job {
    /// The scene file.
    pub scene_path: PathBuf,
    /// What is played.
    pub kind: JobKind,
    /// The WAV written.
    pub wav: PathBuf,
    /// The trace CSV, if any.
    pub trace: Option<PathBuf>,
    /// The plot, if any.
    pub plot: Option<PathBuf>,
    /// The JSON sidecar, if any (batches).
    pub sidecar: Option<PathBuf>,
    /// Samples it renders, as planned (for the progress bar; 0 when the
    /// scene file could not be read: the job then fails with the reason).
    pub samples: u64,
}

impl Job {
    /// The job's name in messages.
    pub fn name(&self) -> String {
        match self.kind {
            JobKind::Scene => self.scene_path.display().to_string(),
            JobKind::Note { note, velocity } => format!(
                "{} note {note} velocity {velocity}",
                self.scene_path.display()
            ),
        }
    }

    fn outputs(&self) -> impl Iterator<Item = &PathBuf> {
        std::iter::once(&self.wav)
            .chain(&self.trace)
            .chain(&self.plot)
            .chain(&self.sidecar)
    }
}

/// Scene files named on the command line: files as given, directories
/// expanded to their `*.toml` files (sorted; not recursive).
pub fn scene_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("cannot read directory {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.is_file() && f.extension().is_some_and(|x| x == "toml"))
                .collect();
            if found.is_empty() {
                bail!("{}: no .toml scene files in this directory", p.display());
            }
            found.sort();
            out.extend(found);
        } else if p.is_file() {
            out.push(p.clone());
        } else {
            bail!("{}: no such scene file or directory", p.display());
        }
    }
    Ok(out)
}

/// Resolve an optional path argument: given without a path, next to the
/// WAV with extension `ext`.
fn beside(arg: &Option<Option<PathBuf>>, wav: &Path, ext: &str) -> Option<PathBuf> {
    arg.as_ref()
        .map(|p| p.clone().unwrap_or_else(|| wav.with_extension(ext)))
}

/// The jobs of a command line, every output path decided (nothing is
/// rendered or written).
pub fn plan(a: &RenderArgs) -> Result<Vec<Job>> {
    let files = scene_files(&a.scenes)?;
    let length = |scene: Option<&Scene>| -> u64 {
        scene
            .and_then(|sc| render_length(a.seconds.unwrap_or(sc.duration_s), a.rate).ok())
            .unwrap_or(0) as u64
    };
    let by_note = a.notes.is_some() || a.velocities.is_some();
    let batch = by_note || files.len() > 1 || a.scenes.iter().any(|p| p.is_dir());
    if !batch {
        let wav = a.out.clone();
        return Ok(vec![Job {
            scene_path: files[0].clone(),
            kind: JobKind::Scene,
            trace: beside(&a.trace, &wav, a.trace_format.extension()),
            plot: beside(&a.plot, &wav, "svg"),
            sidecar: None,
            samples: length(load_scene(&files[0]).ok().as_ref()),
            wav,
        }]);
    }
    for (what, arg) in [("--trace", &a.trace), ("--plot", &a.plot)] {
        if matches!(arg, Some(Some(_))) {
            bail!("in a batch, give {what} without a path: each goes next to its WAV");
        }
    }
    if by_note && (a.trace.is_some() || a.plot.is_some()) {
        bail!("--trace and --plot follow one engine voice: they are for scene renders, not --notes/--velocities");
    }
    let notes = a
        .notes
        .as_deref()
        .map(|s| parse_midi_list(s, "note", 0, 127))
        .transpose()?;
    let vels = match a.velocities.as_deref() {
        Some(s) => parse_midi_list(s, "velocity", 1, 127)?,
        None => vec![100],
    };
    let mut jobs = Vec::new();
    for f in &files {
        let stem = f
            .file_stem()
            .ok_or_else(|| anyhow!("{}: no file name", f.display()))?
            .to_string_lossy()
            .into_owned();
        let scene = load_scene(f).ok();
        let samples = length(scene.as_ref());
        if !by_note {
            let wav = a.out.join(format!("{stem}.wav"));
            jobs.push(Job {
                scene_path: f.clone(),
                kind: JobKind::Scene,
                trace: beside(&a.trace, &wav, a.trace_format.extension()),
                plot: beside(&a.plot, &wav, "svg"),
                sidecar: Some(wav.with_extension("json")),
                samples,
                wav,
            });
            continue;
        }
        let notes = match (&notes, &scene) {
            (Some(n), _) => n.clone(),
            (None, Some(sc)) => vec![offline::root_key(sc)],
            // The job fails with the scene file's error when it runs.
            (None, None) => vec![60],
        };
        for &note in &notes {
            for &velocity in &vels {
                let wav = a.out.join(format!("{stem}_n{note:03}_v{velocity:03}.wav"));
                jobs.push(Job {
                    scene_path: f.clone(),
                    kind: JobKind::Note { note, velocity },
                    trace: None,
                    plot: None,
                    sidecar: Some(wav.with_extension("json")),
                    samples,
                    wav,
                });
            }
        }
    }
    Ok(jobs)
}

/// Every output path is writable and no two jobs write the same file:
/// checked before any work starts (a batch's directory is created).
pub fn check_outputs(jobs: &[Job]) -> Result<()> {
    let mut seen = std::collections::HashSet::new();
    for j in jobs {
        for p in j.outputs() {
            if !seen.insert(p.clone()) {
                bail!(
                    "{} would be written twice (two scene files with the same name?)",
                    p.display()
                );
            }
            check_writable(p, j.sidecar.is_some())?;
        }
    }
    Ok(())
}

fn load_scene(path: &Path) -> Result<Scene> {
    Scene::from_file(path).with_context(|| path.display().to_string())
}

/// What one job did (printed, and written to its sidecar).
#[derive(Debug, Clone)]
pub struct JobReport {
    /// Sidecar contents.
    pub json: serde_json::Value,
    /// One line for the terminal.
    pub line: String,
    /// Exact switching's counters line (scene jobs).
    pub switching_line: Option<String>,
    /// The compile summary.
    pub summary: String,
}

/// A 32-bit float stereo WAV of a known length written in bulk: the header
/// is hound's (made for zero samples, its two sizes set for `n`), the
/// samples little-endian f32 interleaved, so the file is byte for byte what
/// hound writes sample by sample, at a fraction of the cost.
pub struct FloatWav {
    out: BufWriter<std::fs::File>,
    buf: Vec<u8>,
    left: u64,
}

impl FloatWav {
    /// Create `path` for `n` stereo samples at `rate_hz`.
    pub fn create(path: &Path, rate_hz: f64, n: usize) -> Result<Self> {
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: rate_hz.round() as u32,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut header = std::io::Cursor::new(Vec::new());
        hound::WavWriter::new(&mut header, spec)?.finalize()?;
        let mut header = header.into_inner();
        let data = u32::try_from(8 * n as u64)
            .map_err(|_| anyhow!("{}: too long for a WAV file", path.display()))?;
        let h = header.len();
        let riff = (h as u32 - 8)
            .checked_add(data)
            .ok_or_else(|| anyhow!("{}: too long for a WAV file", path.display()))?;
        header[4..8].copy_from_slice(&riff.to_le_bytes());
        header[h - 4..].copy_from_slice(&data.to_le_bytes());
        let f = std::fs::File::create(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut out = BufWriter::with_capacity(1 << 20, f);
        std::io::Write::write_all(&mut out, &header)?;
        Ok(Self {
            out,
            buf: Vec::with_capacity(8 * modal_contact::render::STREAM_CHUNK),
            left: n as u64,
        })
    }

    /// Append samples (f64, written as f32).
    pub fn write(&mut self, l: &[f64], r: &[f64]) -> std::io::Result<()> {
        if l.len() as u64 > self.left {
            return Err(std::io::Error::other(
                "more samples than the WAV was made for",
            ));
        }
        self.left -= l.len() as u64;
        self.buf.resize(8 * l.len(), 0);
        for ((frame, a), b) in self.buf.chunks_exact_mut(8).zip(l).zip(r) {
            frame[..4].copy_from_slice(&(*a as f32).to_le_bytes());
            frame[4..].copy_from_slice(&(*b as f32).to_le_bytes());
        }
        std::io::Write::write_all(&mut self.out, &self.buf)
    }

    /// Flush; fails if fewer samples came than announced.
    pub fn finish(mut self) -> Result<()> {
        if self.left != 0 {
            bail!("{} samples missing from the WAV", self.left);
        }
        std::io::Write::flush(&mut self.out)?;
        Ok(())
    }
}

/// The outputs of a scene render.
#[derive(Debug, Clone, Default)]
pub struct SceneOutputs<'a> {
    /// The WAV (32-bit float stereo).
    pub wav: Option<&'a Path>,
    /// The trace: CSV, or NumPy if the path ends in `.npy`
    /// ([`TraceFormat::of`]).
    pub trace: Option<&'a Path>,
    /// The plot (SVG) and its title.
    pub plot: Option<(&'a Path, &'a str)>,
}

/// Create the trace file `p`. The traces write chunks of 64 KiB and more:
/// a buffer no larger passes them to the file without copying them (it
/// holds the header and the last, shorter chunk).
fn create_trace_file(p: &Path) -> Result<BufWriter<std::fs::File>> {
    let f = std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))?;
    Ok(BufWriter::with_capacity(1 << 16, f))
}

/// Render `n` samples of a compiled scene into its outputs, streaming: the
/// WAV and the CSV are written as the render goes, the plot is drawn from
/// the envelope ([`TraceEnvelope`]). Without a trace or a plot the engine
/// runs its block path and nothing is observed.
/// `progress` hears how many samples each chunk added.
pub fn render_scene_to(
    compiled: &CompiledScene,
    n: usize,
    out: &SceneOutputs,
    progress: &dyn Fn(u64),
) -> Result<StreamStats> {
    let driven = compiled.drive.is_some();
    render_outputs(
        compiled.rate_hz,
        1,
        driven,
        n,
        out,
        progress,
        |audio, trace| render_stream(compiled, n, audio, trace),
    )
}

/// [`render_scene_to`] for a scene of any number of contacts: the trace
/// gains a group of columns per further contact
/// ([`modal_contact::render::trace_header`]), the plot shows contact 0's
/// hammer and point with the total energy, shaded where any contact is
/// closed.
pub fn render_compiled_to(
    compiled: &Compiled,
    n: usize,
    out: &SceneOutputs,
    progress: &dyn Fn(u64),
) -> Result<StreamStats> {
    render_outputs(
        compiled.rate_hz(),
        compiled.contacts(),
        compiled.driven(),
        n,
        out,
        progress,
        |audio, trace| compiled.stream(n, audio, trace),
    )
}

/// The outputs of a render of `contacts` contacts that `stream` runs (a
/// driven scene's trace with the surface's columns).
#[allow(clippy::too_many_arguments)]
fn render_outputs(
    rate_hz: f64,
    contacts: usize,
    driven: bool,
    n: usize,
    out: &SceneOutputs,
    progress: &dyn Fn(u64),
    stream: impl FnOnce(
        &mut dyn FnMut(&[f64], &[f64]) -> std::io::Result<()>,
        Option<&mut dyn TraceSink>,
    ) -> std::io::Result<StreamStats>,
) -> Result<StreamStats> {
    let mut wav = match out.wav {
        Some(p) => Some(FloatWav::create(p, rate_hz, n)?),
        None => None,
    };
    let mut audio = |l: &[f64], r: &[f64]| -> std::io::Result<()> {
        progress(l.len() as u64);
        match wav.as_mut() {
            Some(w) => w.write(l, r),
            None => Ok(()),
        }
    };
    let trace = match out.trace {
        Some(p) => {
            let f = create_trace_file(p)?;
            Some(match TraceFormat::of(p) {
                TraceFormat::Csv if driven => TraceFile::Csv(CsvTrace::driven(rate_hz, f)?),
                TraceFormat::Csv if contacts == 1 => TraceFile::Csv(CsvTrace::new(rate_hz, f)?),
                TraceFormat::Csv => TraceFile::Csv(CsvTrace::with_contacts(rate_hz, f, contacts)?),
                TraceFormat::Npy if driven => TraceFile::Npy(NpyTrace::driven(rate_hz, n, f)?),
                TraceFormat::Npy => {
                    TraceFile::Npy(NpyTrace::with_contacts(rate_hz, n, contacts, f)?)
                }
            })
        }
        None => None,
    };
    let env = out.plot.map(|_| TraceEnvelope::new(rate_hz, n));
    let (stats, env) = match (trace, env) {
        (None, None) => (stream(&mut audio, None)?, None),
        (Some(mut c), None) => {
            let s = stream(&mut audio, Some(&mut c as &mut dyn TraceSink))?;
            c.finish()?;
            (s, None)
        }
        (None, Some(mut e)) => {
            let s = stream(&mut audio, Some(&mut e as &mut dyn TraceSink))?;
            (s, Some(e))
        }
        (Some(c), Some(e)) => {
            let mut both = (c, e);
            let s = stream(&mut audio, Some(&mut both as &mut dyn TraceSink))?;
            both.0.finish()?;
            (s, Some(both.1))
        }
    };
    if let Some(w) = wav {
        w.finish()?;
    }
    if let (Some(e), Some((path, title))) = (env, out.plot) {
        plot::plot_envelope(&e, title, path)?;
    }
    Ok(stats)
}

/// A trace file being written.
enum TraceFile {
    Csv(CsvTrace<BufWriter<std::fs::File>>),
    Npy(NpyTrace<BufWriter<std::fs::File>>),
}

impl TraceFile {
    fn finish(self) -> std::io::Result<()> {
        match self {
            TraceFile::Csv(c) => c.finish().map(drop),
            TraceFile::Npy(c) => c.finish().map(drop),
        }
    }

    fn sink(&self) -> &dyn TraceSink {
        match self {
            TraceFile::Csv(c) => c,
            TraceFile::Npy(c) => c,
        }
    }

    fn sink_mut(&mut self) -> &mut dyn TraceSink {
        match self {
            TraceFile::Csv(c) => c,
            TraceFile::Npy(c) => c,
        }
    }
}

impl TraceSink for TraceFile {
    fn wants_energy(&self, i: usize) -> bool {
        self.sink().wants_energy(i)
    }
    fn every_energy(&self) -> bool {
        self.sink().every_energy()
    }
    fn needs_ticks(&self) -> bool {
        self.sink().needs_ticks()
    }
    fn record(
        &mut self,
        i: usize,
        m: &modal_contact::engine::Motion,
        e: Option<f64>,
    ) -> std::io::Result<()> {
        self.sink_mut().record(i, m, e)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[modal_contact::engine::Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        self.sink_mut().record_several(i, motions, e)
    }
    fn record_driven(
        &mut self,
        i: usize,
        m: &modal_contact::engine::Motion,
        e: Option<f64>,
        surface: [f64; 2],
    ) -> std::io::Result<()> {
        self.sink_mut().record_driven(i, m, e, surface)
    }
}

fn scene_job(job: &Job, a: &RenderArgs, progress: &dyn Fn(u64)) -> Result<JobReport> {
    let scene = load_scene(&job.scene_path)?;
    let n = render_length(a.seconds.unwrap_or(scene.duration_s), a.rate)?;
    let t0 = Instant::now();
    let compiled = Compiled::new(&scene, a.rate, a.switching.map(Switching::from))?;
    let compile_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let stats = render_compiled_to(
        &compiled,
        n,
        &SceneOutputs {
            wav: Some(&job.wav),
            trace: job.trace.as_deref(),
            plot: job.plot.as_deref().map(|p| (p, scene.name.as_str())),
        },
        progress,
    )?;
    let render_s = t1.elapsed().as_secs_f64();
    if stats.nonfinite > 0 {
        bail!("{} samples were not finite", stats.nonfinite);
    }
    let run = Run {
        n,
        seconds: n as f64 / a.rate,
        compile_s,
        render_s,
    };
    Ok(match &compiled {
        Compiled::One(c) => one_contact_report(job, a, &scene, c, &stats, &run),
        Compiled::Several(c) => several_contacts_report(job, a, &scene, c, &stats, &run),
    })
}

/// How long a scene job's compile and render took, and what it rendered.
struct Run {
    n: usize,
    seconds: f64,
    compile_s: f64,
    render_s: f64,
}

/// The sidecar, the line and the summary of a one-contact render.
fn one_contact_report(
    job: &Job,
    a: &RenderArgs,
    scene: &Scene,
    compiled: &CompiledScene,
    stats: &StreamStats,
    run: &Run,
) -> JobReport {
    let Run {
        n,
        seconds,
        compile_s,
        render_s,
    } = *run;
    let x = &stats.exact_stats;
    let json = scene_json(
        job,
        a,
        scene,
        compiled.switching,
        stats,
        run,
        json!({
            "compile": compile_json(compiled, compile_s),
            "contacts": stats.contacts,
            "exact_switching": {
                "located": x.located, "grazing": x.grazing, "capped": x.capped,
                "rod_fallbacks": x.rod_fallbacks, "uncertified": x.uncertified,
            },
        }),
    );
    let line = format!(
        "rendered {n} samples ({seconds:.3} s) in {render_s:.3} s ({:.0}x real time), compiled in {compile_s:.3} s; {} contacts; peak {:.3e}",
        seconds / render_s.max(1e-12),
        stats.contacts,
        stats.peak
    );
    let switching_line = (stats.exact_stats != Default::default())
        .then(|| modal_contact::render::switching_line(&stats.exact_stats));
    JobReport {
        json,
        line,
        switching_line,
        summary: compiled.summary.clone(),
    }
}

/// The sidecar (each contact's count), the line and the summary of a
/// several-contact render (docs/design.md "Several contacts").
fn several_contacts_report(
    job: &Job,
    a: &RenderArgs,
    scene: &Scene,
    compiled: &CompiledMulti,
    stats: &StreamStats,
    run: &Run,
) -> JobReport {
    let Run {
        n,
        seconds,
        compile_s,
        render_s,
    } = *run;
    let k = compiled.contacts();
    let model = &compiled.model;
    let x = &stats.several.expect("a several-contact render");

    let starts = &x.contacts_started[..k];
    let json = scene_json(
        job,
        a,
        scene,
        compiled.switching,
        stats,
        run,
        json!({
            "compile": {
                "seconds": compile_s,
                "contacts": k,
                "phases": compiled.phases.len(),
                "largest_dim": compiled.max_dim(),
                "kappa": compiled.kappa(),
                "structured_products": compiled.structured_products().0,
            },
            "contacts": starts.iter().sum::<u64>(),
            "contacts_per_contact": starts,
            "exact_switching": {
                "switches": x.switches, "grazing": x.grazing, "capped": x.capped, "uncertified": x.uncertified,
                "evaluations": x.evaluations,
                "kernel_samples": x.kernel_samples, "kernel_discarded": x.kernel_discarded,
                "shadowed": x.shadowed,
            },
        }),
    );
    let line = format!(
        "rendered {n} samples ({seconds:.3} s) in {render_s:.3} s ({:.0}x real time), compiled in {compile_s:.3} s; contacts {starts:?} (per contact); peak {:.3e}",
        seconds / render_s.max(1e-12),
        stats.peak
    );
    let mut summary = format!(
        "several contacts: {k} contacts ({} strikers, {} touches, {} law pieces) between {} modes \
         and {} masses, {} phases compiled up front (the sets in contact that can be reached), largest {} \
         coordinates, condition of the bases at most {:.1}; switch products in hierarchical \
         low-rank form: {} of {}\n",
        scene.striker.len(),
        scene.touch.len(),
        scene.all_contacts() - scene.striker.len() - scene.touch.len(),
        model.freq_hz.len(),
        model.masses.len(),
        compiled.phases.len(),
        compiled.max_dim(),
        compiled.kappa(),
        compiled.structured_products().0,
        compiled.structured_products().1
    );
    summary.push_str(&law_line(scene));
    JobReport {
        json,
        line,
        switching_line: Some(format!(
            "several-contact switching: {} switches, {} grazing touches, {} event evaluations; capped {}, uncertified {}; \
             {} samples on the block path ({} stepped past a failed certificate and discarded); \
             {} searches of a law's pieces in flight behind an open piece left out",
            x.switches, x.grazing, x.evaluations, x.capped, x.uncertified, x.kernel_samples, x.kernel_discarded,
            x.shadowed
        )),
        summary,
    }
}

/// The contact law's pieces and, for a fitted power law, its largest
/// relative force error (empty without a law).
fn law_line(scene: &Scene) -> String {
    let mut laws: Vec<(String, &modal_contact::scene::LawSpec, f64)> = Vec::new();
    if let Some(law) = &scene.contact.law {
        laws.push(("contact".into(), law, scene.contact.damping_n_s_per_m));
    }
    for (i, st) in scene.striker.iter().enumerate() {
        if let Some(law) = &st.law {
            laws.push((format!("striker[{i}]"), law, st.damping_n_s_per_m));
        }
    }
    for (i, t) in scene.touch.iter().enumerate() {
        if let Some(law) = &t.law {
            laws.push((format!("touch[{i}]"), law, t.damping_n_s_per_m));
        }
    }
    let mut out = String::new();
    for (name, law, c1) in laws {
        let Ok(p) = law.pieces(&format!("{name}.law")) else {
            continue;
        };
        let fit = match (law.power, law.up_to_m) {
            (Some(power), Some(up_to)) => format!(
                ", fitted to F ~ p^{power}: largest force error {:.2} % from {:.3e} to {up_to:.3e} m",
                100.0 * p.fit_error,
                law.from_m.unwrap_or(0.1 * up_to)
            ),
            _ => String::new(),
        };
        // each piece's damper in proportion to the stiffness it adds
        // (docs/design.md, "Stiffening contacts"): one relaxation time c / k
        let relax = c1 / p.stiffness[0];
        out.push_str(&format!(
            "{name} law: {} pieces, breakpoints {:.3e} m, stiffness {:.3e} N/m{fit}; damping {c1:.3e} N s/m on the first piece, relaxation time c / k = {relax:.3e} s on every piece\n",
            p.stiffness.len(),
            DisplayList(&p.breakpoints),
            DisplayList(&p.stiffness)
        ));
    }
    out
}

/// A list of numbers in scientific notation, `[a, b, ...]`.
struct DisplayList<'a>(&'a [f64]);

impl std::fmt::LowerExp for DisplayList<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("[")?;
        for (i, x) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            std::fmt::LowerExp::fmt(x, f)?;
        }
        f.write_str("]")
    }
}

/// A scene job's sidecar: what every scene render reports, and the
/// engine's own fields (`engine`, an object) merged in.
fn scene_json(
    job: &Job,
    a: &RenderArgs,
    scene: &Scene,
    switching: Switching,
    stats: &StreamStats,
    run: &Run,
    engine: serde_json::Value,
) -> serde_json::Value {
    let mut json = json!({
        "scene": job.scene_path.display().to_string(),
        "scene_name": scene.name,
        "kind": "scene",
        "rate_hz": a.rate,
        "seconds": run.seconds,
        "samples": run.n,
        "switching": format!("{switching:?}"),
        "peak": stats.peak,
        "render_s": run.render_s,
        "realtime_factor": run.seconds / run.render_s.max(1e-12),
        "files": files_json(job),
    });
    if let (Some(all), serde_json::Value::Object(own)) = (json.as_object_mut(), engine) {
        all.extend(own);
    }
    json
}

fn compile_json(c: &CompiledScene, seconds: f64) -> serde_json::Value {
    json!({
        "seconds": seconds,
        "free": {"dim": c.free.dim, "route": c.free.diag.method},
        "contact": {"dim": c.contact.dim, "route": c.contact.diag.method},
        "summary": c.summary,
    })
}

fn files_json(job: &Job) -> serde_json::Value {
    json!({
        "wav": job.wav.display().to_string(),
        "trace": job.trace.as_ref().map(|p| p.display().to_string()),
        "plot": job.plot.as_ref().map(|p| p.display().to_string()),
    })
}

/// The jobs of one scene file that strike notes: the scene is prepared
/// (mapped and compiled) once, its notes render in parallel.
fn note_jobs(jobs: &[&Job], a: &RenderArgs, done: &(dyn Fn(u64) + Sync)) -> Vec<Result<JobReport>> {
    let prep = (|| -> Result<_> {
        let scene = load_scene(&jobs[0].scene_path)?;
        let params = InstrumentParams::default();
        let (prepared, compile_s) = prepare_for(&scene, &params, a.rate)?;
        Ok((scene, params, prepared, compile_s))
    })();
    let (scene, params, prepared, compile_s) = match prep {
        Ok(p) => p,
        Err(e) => {
            let msg = format!("{e:#}");
            return jobs
                .iter()
                .map(|j| {
                    done(j.samples);
                    Err(anyhow!("{msg}"))
                })
                .collect();
        }
    };
    jobs.par_iter()
        .map(|job| {
            let r = (|| {
                let JobKind::Note { note, velocity } = job.kind else {
                    unreachable!("note jobs only")
                };
                let n = render_length(a.seconds.unwrap_or(scene.duration_s), a.rate)?;
                let r = play_note(&prepared, &params, note, velocity, n);
                offline::write_wav(&job.wav, a.rate, &r.left, &r.right, WavFormat::Float32)?;
                let peak = r
                    .left
                    .iter()
                    .chain(&r.right)
                    .fold(0.0f64, |m, x| m.max(f64::from(x.abs())));
                let seconds = n as f64 / a.rate;
                let json = json!({
                    "scene": job.scene_path.display().to_string(),
                    "scene_name": scene.name,
                    "kind": "note",
                    "note": note,
                    "velocity": velocity,
                    "velocity_norm": offline::velocity_norm(velocity),
                    "rate_hz": a.rate,
                    "seconds": seconds,
                    "samples": n,
                    "switching": format!("{:?}", prepared.switching_used),
                    "fallback_note": r.fallback_note,
                    "compile": match &prepared.kit {
                        Some(k) => json!({
                            "seconds": compile_s,
                            "kit": true,
                            "contacts": k.sc.contacts(),
                            "mallets": k.mallets,
                            "phases": k.sc.phases.len(),
                            "largest_dim": k.max_dim(),
                            "summary": k.summary(),
                        }),
                        None => compile_json(&prepared.scenes.scene, compile_s),
                    },
                    "contacts": r.contacts,
                    "peak": peak,
                    "render_s": r.render_s,
                    "realtime_factor": seconds / r.render_s.max(1e-12),
                    "files": files_json(job),
                });
                let line = format!(
                    "note {note} velocity {velocity}: {} contacts, peak {peak:.3e}, {:.0}x real time",
                    r.contacts,
                    seconds / r.render_s.max(1e-12)
                );
                Ok(JobReport {
                    json,
                    line,
                    switching_line: None,
                    summary: r.summary,
                })
            })();
            done(job.samples);
            r
        })
        .collect()
}

/// Run a planned list of jobs on the rayon pool; the results in job order.
/// `progress` is drawn (if `show_after_1s`) once the jobs have run for a
/// second.
pub fn run_jobs(
    jobs: &[Job],
    a: &RenderArgs,
    progress: &ProgressBar,
    show_after_1s: bool,
) -> Vec<Result<JobReport>> {
    let t0 = Instant::now();
    let shown = AtomicBool::new(!show_after_1s);
    let done = |k: u64| {
        progress.inc(k);
        if t0.elapsed().as_secs_f64() > 1.0 && !shown.swap(true, Ordering::Relaxed) {
            progress.set_draw_target(ProgressDrawTarget::stderr());
        }
    };
    // Group note jobs by scene file (one compile each), keep scene jobs alone.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, j) in jobs.iter().enumerate() {
        match (&j.kind, groups.last_mut()) {
            (JobKind::Note { .. }, Some(g))
                if matches!(jobs[g[0]].kind, JobKind::Note { .. })
                    && jobs[g[0]].scene_path == j.scene_path =>
            {
                g.push(i)
            }
            _ => groups.push(vec![i]),
        }
    }
    let results: Vec<Vec<(usize, Result<JobReport>)>> = groups
        .par_iter()
        .map(|g| {
            let first = &jobs[g[0]];
            let rs = if first.kind == JobKind::Scene {
                let r = scene_job(first, a, &done);
                vec![r]
            } else {
                let js: Vec<&Job> = g.iter().map(|&i| &jobs[i]).collect();
                note_jobs(&js, a, &done)
            };
            g.iter().copied().zip(rs).collect()
        })
        .collect();
    let mut flat: Vec<(usize, Result<JobReport>)> = results.into_iter().flatten().collect();
    flat.sort_by_key(|(i, _)| *i);
    flat.into_iter().map(|(_, r)| r).collect()
}

/// `cargo xtask render`: plan, check every output, render, report. Fails
/// (after every job has run) if any job failed.
pub fn run(a: &RenderArgs) -> Result<()> {
    let jobs = plan(a)?;
    check_outputs(&jobs)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    let total: u64 = jobs.iter().map(|j| j.samples).sum();
    let progress = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
    let tty = std::io::stderr().is_terminal();
    if tty {
        progress.set_style(
            ProgressStyle::with_template(&format!(
                "{{bar:40}} {{percent}}% of {} jobs, {{elapsed}} (eta {{eta}})",
                jobs.len()
            ))
            .expect("template"),
        );
    }
    let single = jobs.len() == 1 && jobs[0].sidecar.is_none();
    let results = pool.install(|| run_jobs(&jobs, a, &progress, tty));
    progress.finish_and_clear();
    let mut failed = 0;
    for (job, r) in jobs.iter().zip(results) {
        match r {
            Ok(rep) => {
                if single {
                    eprint!("{}", rep.summary);
                }
                eprintln!("{}: {}", job.name(), rep.line);
                if let Some(s) = &rep.switching_line {
                    eprintln!("{s}");
                }
                if let Some(p) = &job.sidecar {
                    let text = serde_json::to_string_pretty(&rep.json)?;
                    std::fs::write(p, text + "\n")
                        .with_context(|| format!("cannot write {}", p.display()))?;
                }
                for p in job.outputs() {
                    eprintln!("wrote {}", p.display());
                }
            }
            Err(e) => {
                failed += 1;
                eprintln!("FAILED {}: {e:#}", job.name());
            }
        }
    }
    if failed > 0 {
        bail!("{failed} of {} jobs failed", jobs.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bulk WAV writer writes hound's bytes, and refuses a wrong length.
    #[test]
    fn bulk_wav_is_hounds_wav() {
        let dir = std::env::temp_dir().join(format!("xtask-wav-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let n = 10_007;
        let l: Vec<f64> = (0..n).map(|i| (i as f64 * 0.01).sin() * 0.7).collect();
        let r: Vec<f64> = (0..n).map(|i| -1e-30 * i as f64 + 0.25).collect();
        let (a, b) = (dir.join("a.wav"), dir.join("b.wav"));
        let mut w = FloatWav::create(&a, 48000.0, n).unwrap();
        w.write(&l[..5000], &r[..5000]).unwrap();
        w.write(&l[5000..], &r[5000..]).unwrap();
        w.finish().unwrap();
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 48000,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut h = hound::WavWriter::create(&b, spec).unwrap();
        for (x, y) in l.iter().zip(&r) {
            h.write_sample(*x as f32).unwrap();
            h.write_sample(*y as f32).unwrap();
        }
        h.finalize().unwrap();
        assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
        let mut short = FloatWav::create(&a, 48000.0, 3).unwrap();
        short.write(&l[..2], &r[..2]).unwrap();
        assert!(short.finish().is_err());
        let mut long = FloatWav::create(&a, 48000.0, 1).unwrap();
        assert!(long.write(&l[..2], &r[..2]).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
