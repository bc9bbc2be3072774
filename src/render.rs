//! Offline rendering: scene -> compile -> engine, with an optional trace
//! (docs/design.md, "The render command and the trace CSV"). Used by `cargo xtask render`, the report and tests.

use crate::compile::{compile_with, CompileError, CompiledScene, RATE_RANGE_HZ};
use crate::engine::{EngineState, ExactStats, Motion, Observation};
use crate::multi::{CompiledMulti, MultiModel, MultiObservation, MultiState, MultiStats};
use crate::scene::{Scene, Switching, MAX_CONTACTS, MAX_DURATION_S};
use std::io::Write;

/// Options of an offline render.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Length \[s\]; `None` = the scene's `duration_s`.
    pub seconds: Option<f64>,
    /// Override of the scene's switching method.
    pub switching: Option<Switching>,
    /// Record the per-sample trace.
    pub trace: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            rate_hz: 44100.0,
            seconds: None,
            switching: None,
            trace: false,
        }
    }
}

/// One trace row (docs/design.md, "The render command and the trace CSV"): row `n` is time `n / fs`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    /// Time \[s\].
    pub t: f64,
    /// The observation at that time, after the switching decision.
    pub obs: Observation,
}

impl TraceRow {
    /// The row's numbers in the order of [`TRACE_HEADER`] (`in_contact` 0
    /// or 1).
    pub fn columns(&self) -> [f64; 7] {
        let o = &self.obs;
        [
            self.t,
            o.x_hammer,
            o.v_hammer,
            o.x_contact,
            o.v_contact,
            f64::from(u8::from(o.in_contact)),
            o.energy,
        ]
    }
}

/// Result of a render.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Left and right pickup signals (f64, physical units times pickup gains).
    pub left: Vec<f64>,
    /// See `left`.
    pub right: Vec<f64>,
    /// Trace rows, if requested (of a several-contact scene: contact 0's
    /// motion and the total energy; the further contacts in
    /// `trace_further`).
    pub trace: Option<Vec<TraceRow>>,
    /// The further contacts' motion of a several-contact scene's trace:
    /// `contacts - 1` per trace row, contact 1 first (empty for one
    /// contact, or without a trace).
    pub trace_further: Vec<Motion>,
    /// The compiler's summary (one contact; empty for several).
    pub summary: String,
    /// Number of contacts that started (of every contact).
    pub contacts: u64,
    /// What exact switching did (one contact; all zero with the offset
    /// rod).
    pub exact_stats: ExactStats,
    /// What the several-contact engine did (`None` for one contact).
    pub several: Option<MultiStats>,
}

impl RenderOutput {
    /// One line on the exact switching's work and its diagnostics (the
    /// counters that must stay 0: `capped`, `rod_fallbacks`,
    /// `uncertified`).
    pub fn switching_line(&self) -> String {
        switching_line(&self.exact_stats)
    }
}

/// One line on what exact switching did ([`RenderOutput::switching_line`]).
pub fn switching_line(x: &ExactStats) -> String {
    format!(
        "exact switching: {} located switches, {} grazing touches; capped {}, rod fallbacks {}, uncertified {}; \
         event search: {} nodes, at most {} nodes and {} switches in one sample; \
         {} samples and {} rests after a switch cleared by the Hermite certificate; \
         strikes from rest: {} stored switches taken ({} without a search), {} not where stored",
        x.located,
        x.grazing,
        x.capped,
        x.rod_fallbacks,
        x.uncertified,
        x.search_nodes,
        x.max_nodes_in_sample,
        x.max_switches_in_sample,
        x.hermite_cleared,
        x.hermite_after_switch,
        x.rest_releases + x.rest_later,
        x.rest_trusted,
        x.rest_misses
    )
}

/// Why an offline render could not run.
#[derive(Debug, Clone, PartialEq)]
pub enum RenderError {
    /// The scene did not compile.
    Compile(CompileError),
    /// The length is not in `(0, MAX_DURATION_S]` seconds.
    Length(f64),
}

impl std::fmt::Display for RenderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Compile(e) => write!(f, "{e}"),
            Self::Length(s) => write!(
                f,
                "render length must be in (0, {MAX_DURATION_S}] s, got {s}"
            ),
        }
    }
}

impl std::error::Error for RenderError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Compile(e) => Some(e),
            Self::Length(_) => None,
        }
    }
}

impl From<CompileError> for RenderError {
    fn from(e: CompileError) -> Self {
        Self::Compile(e)
    }
}

/// Render a scene of one to [`MAX_CONTACTS`] contacts offline (in
/// memory; [`Compiled::stream`] for long renders).
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<RenderOutput, RenderError> {
    let seconds = opts.seconds.unwrap_or(scene.duration_s);
    let n = render_length(seconds, opts.rate_hz)?;
    Ok(Compiled::new(scene, opts.rate_hz, opts.switching)?.render(n, opts.trace))
}

/// A scene compiled for a render: one contact runs on the engine
/// ([`crate::engine`]), several on the several-contact engine
/// ([`crate::multi`]); the render, its trace and its sinks are the same
/// for both (docs/design.md, "Offline rendering").
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)]
pub enum Compiled {
    /// A scene of one contact.
    One(CompiledScene),
    /// A scene of several contacts (`[[striker]]`, `[[touch]]`).
    Several(CompiledMulti),
}

impl Compiled {
    /// Compile `scene` at `rate_hz`, with `switching` overriding the
    /// scene's switching method: through [`compile_with`] for one contact,
    /// through [`MultiModel::from_scene`] and [`CompiledMulti`] for
    /// several (their refusals name the scene's field).
    pub fn new(
        scene: &Scene,
        rate_hz: f64,
        switching: Option<Switching>,
    ) -> Result<Self, CompileError> {
        if !scene.several_contacts() {
            return compile_with(scene, rate_hz, switching).map(Self::One);
        }
        if !(rate_hz.is_finite() && (RATE_RANGE_HZ.0..=RATE_RANGE_HZ.1).contains(&rate_hz)) {
            return Err(CompileError::SampleRate(rate_hz));
        }
        let model = MultiModel::from_scene(scene, rate_hz)?;
        let switching = switching.or(scene.contact.switching).unwrap_or_default();
        CompiledMulti::with_switching(&model, rate_hz, switching)
            .map(Self::Several)
            .map_err(|e| CompileError::Scene(e.in_scene(scene)))
    }

    /// Sample rate \[Hz\].
    pub fn rate_hz(&self) -> f64 {
        match self {
            Self::One(c) => c.rate_hz,
            Self::Several(c) => c.rate_hz,
        }
    }

    /// Number of contacts.
    pub fn contacts(&self) -> usize {
        match self {
            Self::One(_) => 1,
            Self::Several(c) => c.contacts(),
        }
    }

    /// The switching method it runs with.
    pub fn switching(&self) -> Switching {
        match self {
            Self::One(c) => c.switching,
            Self::Several(c) => c.switching,
        }
    }

    /// Render `n` samples from the initial state in memory, with the
    /// trace if asked ([`render_compiled`], [`render_several`]).
    pub fn render(&self, n: usize, trace: bool) -> RenderOutput {
        match self {
            Self::One(c) => render_compiled(c, n, trace),
            Self::Several(c) => render_several(c, n, trace),
        }
    }

    /// Stream a render of `n` samples from the initial state
    /// ([`render_stream`], [`render_stream_several`]).
    pub fn stream(
        &self,
        n: usize,
        audio: impl FnMut(&[f64], &[f64]) -> std::io::Result<()>,
        trace: Option<&mut dyn TraceSink>,
    ) -> std::io::Result<StreamStats> {
        match self {
            Self::One(c) => render_stream(c, n, audio, trace),
            Self::Several(c) => render_stream_several(c, n, audio, trace),
        }
    }
}

/// Samples in `seconds` at `rate_hz`, or why that is not a render length.
pub fn render_length(seconds: f64, rate_hz: f64) -> Result<usize, RenderError> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= MAX_DURATION_S) {
        return Err(RenderError::Length(seconds));
    }
    Ok((seconds * rate_hz).round() as usize)
}

/// Render `n` samples of a compiled scene from its initial state, in memory.
pub fn render_compiled(compiled: &CompiledScene, n: usize, trace: bool) -> RenderOutput {
    let summary = compiled.summary.clone();
    render_in_memory(compiled.rate_hz, 1, n, trace, summary, |audio, sink| {
        render_stream(compiled, n, audio, sink)
    })
}

/// Render `n` samples of a compiled several-contact scene from its initial
/// state, in memory.
pub fn render_several(compiled: &CompiledMulti, n: usize, trace: bool) -> RenderOutput {
    let k = compiled.contacts();
    render_in_memory(
        compiled.rate_hz,
        k,
        n,
        trace,
        String::new(),
        |audio, sink| render_stream_several(compiled, n, audio, sink),
    )
}

/// The audio and (if asked) the rows of a render of `contacts` contacts
/// that `stream` runs, in memory.
fn render_in_memory(
    rate_hz: f64,
    contacts: usize,
    n: usize,
    trace: bool,
    summary: String,
    stream: impl FnOnce(
        &mut dyn FnMut(&[f64], &[f64]) -> std::io::Result<()>,
        Option<&mut dyn TraceSink>,
    ) -> std::io::Result<StreamStats>,
) -> RenderOutput {
    let (mut left, mut right) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let rows_kept = if trace { n } else { 0 };
    let mut rows = TraceRows {
        rate_hz,
        rows: Vec::with_capacity(rows_kept),
        further: Vec::with_capacity(rows_kept * (contacts - 1)),
        contacts,
    };
    let mut audio = |l: &[f64], r: &[f64]| {
        left.extend_from_slice(l);
        right.extend_from_slice(r);
        Ok(())
    };
    let sink: Option<&mut dyn TraceSink> = if trace { Some(&mut rows) } else { None };
    let stats = stream(&mut audio, sink).expect("in-memory sinks do not fail");
    RenderOutput {
        rate_hz,
        left,
        right,
        trace: trace.then_some(rows.rows),
        trace_further: rows.further,
        summary,
        contacts: stats.contacts,
        exact_stats: stats.exact_stats,
        several: stats.several,
    }
}

/// Samples per call of the audio callback of [`render_stream`].
pub const STREAM_CHUNK: usize = 4096;

/// What a streamed render leaves besides what its sinks received.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StreamStats {
    /// Samples rendered.
    pub samples: usize,
    /// Number of contacts that started.
    pub contacts: u64,
    /// What exact switching did.
    pub exact_stats: ExactStats,
    /// Largest `|sample|` over both channels.
    pub peak: f64,
    /// Samples (left or right) that were not finite.
    pub nonfinite: usize,
    /// What the several-contact engine did (`None` for one contact).
    pub several: Option<MultiStats>,
}

/// Where a render's trace goes, sample by sample (docs/design.md, "Offline
/// rendering"): the full rows, a CSV file, the plot's envelope, or several.
pub trait TraceSink {
    /// Whether sample `i` needs the energy (it costs more than the motion,
    /// see [`EngineState::energy`]).
    fn wants_energy(&self, i: usize) -> bool;
    /// Record sample `i` (time `i / fs`): its motion, and its energy when
    /// [`wants_energy`](Self::wants_energy) said so.
    fn record(&mut self, i: usize, motion: &Motion, energy: Option<f64>) -> std::io::Result<()>;
    /// Record sample `i` of a several-contact render: each contact's motion
    /// (contact 0 first) and the total energy. A sink that keeps one
    /// contact's motion takes a single motion and refuses more (an error,
    /// not a dropped column); the trace files, the rows in memory and the
    /// plot's envelope take every contact.
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        energy: Option<f64>,
    ) -> std::io::Result<()> {
        match motions {
            [m] => self.record(i, m, energy),
            _ => Err(std::io::Error::other(format!(
                "this trace takes one contact, the render has {}",
                motions.len()
            ))),
        }
    }
    /// Whether the sink wants the energy of (nearly) every sample. When it
    /// does not, the render runs the engine's block path with the motion
    /// ([`EngineState::process_block_observed`], one kernel pass summing
    /// the contact point's rows too) and takes the energy only where asked.
    fn every_energy(&self) -> bool {
        true
    }
    /// Whether the sink needs the values of the engine's per-sample path
    /// ([`EngineState::tick_with`]) bit for bit (the in-memory rows the
    /// tests compare against). When it does not, a sink that wants every
    /// energy gets the block path's motion and energy
    /// ([`EngineState::process_block_traced`]), equal up to the order of
    /// the sums and O(N) per sample wherever the phase allows.
    fn needs_ticks(&self) -> bool {
        true
    }
    /// Record the consecutive samples `first..first + motion.len()`, each
    /// with its energy (`energy[k]` for sample `first + k`; the sink keeps
    /// it where [`wants_energy`](Self::wants_energy) says): what the
    /// render hands a sink that wants every energy, one call per chunk.
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        for (k, (m, &e)) in motion.iter().zip(energy).enumerate() {
            let i = first + k;
            let e = self.wants_energy(i).then_some(e);
            self.record(i, m, e)?;
        }
        Ok(())
    }
}

/// Stream a render: `audio` receives consecutive chunks of at most
/// [`STREAM_CHUNK`] samples (left, right), `trace` (if any) every sample.
/// Memory stays O(chunk) whatever the length. Without a trace the engine
/// runs its block path ([`EngineState::process_block`]), with one it ticks
/// sample by sample and observes only what the sink asks for; the samples
/// are the same bit for bit either way.
pub fn render_stream(
    compiled: &CompiledScene,
    n: usize,
    mut audio: impl FnMut(&[f64], &[f64]) -> std::io::Result<()>,
    mut trace: Option<&mut dyn TraceSink>,
) -> std::io::Result<StreamStats> {
    let mut st = EngineState::new(compiled);
    let mut l = vec![0.0; STREAM_CHUNK.min(n)];
    let mut r = vec![0.0; STREAM_CHUNK.min(n)];
    let still = Motion {
        x_hammer: 0.0,
        v_hammer: 0.0,
        x_contact: 0.0,
        v_contact: 0.0,
        in_contact: false,
    };
    let mut motion = vec![
        still;
        if trace.is_some() {
            STREAM_CHUNK.min(n)
        } else {
            0
        }
    ];
    let mut energy = vec![0.0; motion.len()];
    let mut stats = StreamStats::default();
    let mut done = 0;
    while done < n {
        let len = STREAM_CHUNK.min(n - done);
        let (lc, rc) = (&mut l[..len], &mut r[..len]);
        match trace.as_deref_mut() {
            None => st.process_block(compiled, lc, rc),
            Some(sink) if !sink.every_energy() => {
                observe_block(compiled, &mut st, sink, done, lc, rc, &mut motion[..len])?
            }
            Some(sink) if !sink.needs_ticks() => {
                let (m, e) = (&mut motion[..len], &mut energy[..len]);
                st.process_block_traced(compiled, lc, rc, m, e);
                sink.record_run(done, m, e)?;
            }
            Some(sink) => {
                for k in 0..len {
                    let i = done + k;
                    let want = sink.wants_energy(i);
                    let (out, (m, e)) = st.tick_with(compiled, |s| {
                        (s.motion(compiled), want.then(|| s.energy(compiled)))
                    });
                    sink.record(i, &m, e)?;
                    lc[k] = out[0];
                    rc[k] = out[1];
                }
            }
        }
        // branch-free scans (a NaN never wins `max`; infinities are counted)
        let finite_peak = |xs: &[f64]| {
            xs.iter()
                .map(|x| if x.is_finite() { x.abs() } else { 0.0 })
                .fold(0.0, f64::max)
        };
        stats.peak = stats.peak.max(finite_peak(lc)).max(finite_peak(rc));
        stats.nonfinite += lc
            .iter()
            .chain(rc.iter())
            .filter(|x| !x.is_finite())
            .count();
        audio(lc, rc)?;
        done += len;
    }
    stats.samples = n;
    stats.contacts = st.contacts_started;
    stats.exact_stats = st.exact_stats;
    Ok(stats)
}

/// [`render_stream`] for a several-contact scene: `audio` receives
/// consecutive chunks of at most [`STREAM_CHUNK`] samples, `trace` (if any)
/// every sample's motion of each contact and the total energy through
/// [`TraceSink::record_several`] (after the switching decision at that
/// instant, as the one-contact trace). O(N) per sample and O(N^2) per
/// switch; a trace adds O(N^2) per sample (the energy through the change of
/// basis).
pub fn render_stream_several(
    compiled: &CompiledMulti,
    n: usize,
    mut audio: impl FnMut(&[f64], &[f64]) -> std::io::Result<()>,
    mut trace: Option<&mut dyn TraceSink>,
) -> std::io::Result<StreamStats> {
    let mut st = MultiState::new(compiled);
    let k = compiled.contacts();
    let (mut l, mut r) = (
        vec![0.0; STREAM_CHUNK.min(n)],
        vec![0.0; STREAM_CHUNK.min(n)],
    );
    let mut motions = [Motion::default(); MAX_CONTACTS];
    let mut stats = StreamStats::default();
    let mut done = 0;
    while done < n {
        let len = STREAM_CHUNK.min(n - done);
        match trace.as_deref_mut() {
            None => st.process_block(compiled, &mut l[..len], &mut r[..len]),
            Some(sink) => {
                for q in 0..len {
                    st.decide(compiled);
                    let o = st.observe(compiled);
                    for (j, m) in motions[..k].iter_mut().enumerate() {
                        *m = contact_motion(&o, j);
                    }
                    sink.record_several(done + q, &motions[..k], Some(o.energy))?;
                    [l[q], r[q]] = st.tick(compiled);
                }
            }
        }
        for x in l[..len].iter().chain(&r[..len]) {
            if x.is_finite() {
                stats.peak = stats.peak.max(x.abs());
            } else {
                stats.nonfinite += 1;
            }
        }
        audio(&l[..len], &r[..len])?;
        done += len;
    }
    stats.samples = n;
    stats.contacts = st.stats.contacts_started[..k].iter().sum();
    stats.several = Some(st.stats);
    Ok(stats)
}

/// Contact `j`'s motion in a several-contact observation.
fn contact_motion(o: &MultiObservation, j: usize) -> Motion {
    Motion {
        x_hammer: o.x_hammer[j],
        v_hammer: o.v_hammer[j],
        x_contact: o.x_contact[j],
        v_contact: o.v_contact[j],
        in_contact: o.active & (1 << j) != 0,
    }
}

/// Every trace row in memory (tests, the report).
#[derive(Debug, Clone, Default)]
pub struct TraceRows {
    /// Sample rate \[Hz\] (row `i` is time `i / rate_hz`).
    pub rate_hz: f64,
    /// The rows (of a several-contact render: contact 0's motion and the
    /// total energy).
    pub rows: Vec<TraceRow>,
    /// The further contacts' motion of a several-contact render,
    /// `contacts - 1` per row (contact 1 first).
    pub further: Vec<Motion>,
    /// Contacts per row (1 for one contact).
    pub contacts: usize,
}

/// One chunk on the block path with the motion, the energy taken where
/// the sink asks (from the state at that instant, before its sample: the
/// same value as after the switching decision up to rounding, the offset
/// rod's spring starting at zero length).
fn observe_block(
    compiled: &CompiledScene,
    st: &mut EngineState,
    sink: &mut dyn TraceSink,
    first: usize,
    lc: &mut [f64],
    rc: &mut [f64],
    motion: &mut [Motion],
) -> std::io::Result<()> {
    let len = lc.len();
    let mut k = 0;
    while k < len {
        let e = sink.wants_energy(first + k).then(|| st.energy(compiled));
        let mut end = k + 1;
        while end < len && !sink.wants_energy(first + end) {
            end += 1;
        }
        st.process_block_observed(
            compiled,
            &mut lc[k..end],
            &mut rc[k..end],
            &mut motion[k..end],
        );
        for (q, m) in motion[k..end].iter().enumerate() {
            sink.record(first + k + q, m, if q == 0 { e } else { None })?;
        }
        k = end;
    }
    Ok(())
}

impl TraceSink for TraceRows {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.rows.push(TraceRow {
            t: i as f64 / self.rate_hz,
            obs: m.with_energy(e.expect("every energy was asked for")),
        });
        Ok(())
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        check_contacts(motions, self.contacts)?;
        self.further.extend_from_slice(&motions[1..]);
        self.record(i, &motions[0], e)
    }
}

/// An error unless a sample holds the `contacts` motions a sink was made
/// for.
fn check_contacts(motions: &[Motion], contacts: usize) -> std::io::Result<()> {
    if motions.len() == contacts {
        Ok(())
    } else {
        Err(std::io::Error::other(format!(
            "a trace of {contacts} contacts was handed {} motions",
            motions.len()
        )))
    }
}

/// Two sinks fed the same samples (e.g. the CSV file and the plot).
impl<A: TraceSink, B: TraceSink> TraceSink for (A, B) {
    fn wants_energy(&self, i: usize) -> bool {
        self.0.wants_energy(i) || self.1.wants_energy(i)
    }
    fn every_energy(&self) -> bool {
        self.0.every_energy() || self.1.every_energy()
    }
    fn needs_ticks(&self) -> bool {
        self.0.needs_ticks() || self.1.needs_ticks()
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        let e0 = if self.0.wants_energy(i) { e } else { None };
        let e1 = if self.1.wants_energy(i) { e } else { None };
        self.0.record(i, m, e0)?;
        self.1.record(i, m, e1)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        let e0 = if self.0.wants_energy(i) { e } else { None };
        let e1 = if self.1.wants_energy(i) { e } else { None };
        self.0.record_several(i, motions, e0)?;
        self.1.record_several(i, motions, e1)
    }
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        self.0.record_run(first, motion, energy)?;
        self.1.record_run(first, motion, energy)
    }
}

/// Rows per chunk a [`CsvTrace`] hands to its formatting threads.
const CSV_CHUNK_ROWS: usize = 4096;
/// Chunks waiting for a formatting thread (memory stays O(chunk) for any
/// length: at most this many, plus one per formatting thread, plus as many
/// formatted ones waiting for their turn to be written).
const CSV_CHUNKS_IN_FLIGHT: usize = 4;
/// Most formatting threads of one [`CsvTrace`].
const CSV_MAX_FORMATTERS: usize = 4;

/// A thread that writes numbered chunks of bytes to `out` in their order
/// (they may arrive in any order), handing each written buffer back on
/// `give` for reuse; it returns `out` after a flush, or the first write
/// error, when `chunks` closes.
fn spawn_ordered_writer<W: Write + Send + 'static>(
    name: &str,
    mut out: W,
    chunks: crossbeam::channel::Receiver<(u64, Vec<u8>)>,
    give: crossbeam::channel::Sender<Vec<u8>>,
) -> std::io::Result<std::thread::JoinHandle<std::io::Result<W>>> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let mut waiting = std::collections::BTreeMap::new();
            let mut next = 0u64;
            for (seq, bytes) in chunks {
                waiting.insert(seq, bytes);
                while let Some(bytes) = waiting.remove(&next) {
                    out.write_all(&bytes)?;
                    let _ = give.try_send(bytes);
                    next += 1;
                }
            }
            out.flush()?;
            Ok(out)
        })
}

/// Wait for a writer thread (once): its result, or an error if it panicked.
fn join_writer<W>(
    writer: &mut Option<std::thread::JoinHandle<std::io::Result<W>>>,
) -> std::io::Result<W> {
    writer
        .take()
        .expect("joined once")
        .join()
        .map_err(|_| std::io::Error::other("the trace writer panicked"))?
}

/// A chunk of rows and its place in the file.
type Chunk = (u64, Vec<TraceRow>);

/// The sending end of a trace's threads: hands numbered chunks on (the
/// next thread puts them back in order) and takes spent buffers back for
/// reuse.
struct ChunkQueue<T> {
    seq: u64,
    to: Option<crossbeam::channel::Sender<(u64, Vec<T>)>>,
    spare: crossbeam::channel::Receiver<Vec<T>>,
}

impl<T> ChunkQueue<T> {
    /// Hand `buf` on as the next chunk, leaving an empty buffer of
    /// `capacity` (a spare one if any) in its place; an error if the
    /// threads have stopped (a failed write: the sink's `finish` returns
    /// it).
    fn send(&mut self, buf: &mut Vec<T>, capacity: usize) -> std::io::Result<()> {
        let mut fresh = self
            .spare
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(capacity));
        fresh.clear();
        let chunk = std::mem::replace(buf, fresh);
        let stopped = || std::io::Error::other("the trace writer stopped");
        self.to
            .as_ref()
            .ok_or_else(stopped)?
            .send((self.seq, chunk))
            .map_err(|_| stopped())?;
        self.seq += 1;
        Ok(())
    }

    /// No more chunks: the threads finish what they have and end.
    fn close(&mut self) {
        self.to = None;
    }
}

/// Writes the trace CSV as it goes (docs/design.md, "The render command and
/// the trace CSV"): the render hands rows in chunks of `CSV_CHUNK_ROWS`
/// (4096) to formatting threads (one per core, at most
/// `CSV_MAX_FORMATTERS`), which turn them into text side by side, and a
/// writer thread writes the texts in the chunks' order. The text is the
/// CSV's largest cost, so it runs beside the engine on every core; O(1)
/// memory for any length, the bytes those of writing the rows in order on
/// one thread.
pub struct CsvTrace<W: Write + Send + 'static> {
    rate_hz: f64,
    /// Contacts per sample: a sample is this many consecutive entries of
    /// `rows` (contact 0's with the energy, then the further contacts').
    contacts: usize,
    rows: Vec<TraceRow>,
    queue: ChunkQueue<TraceRow>,
    formatters: Vec<std::thread::JoinHandle<()>>,
    writer: Option<std::thread::JoinHandle<std::io::Result<W>>>,
}

impl<W: Write + Send + 'static> CsvTrace<W> {
    /// Write the header to `out` and return the sink (its threads started:
    /// one formatting thread per core, at most `CSV_MAX_FORMATTERS`).
    pub fn new(rate_hz: f64, out: W) -> std::io::Result<Self> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self::with_formatters(rate_hz, out, cores.min(CSV_MAX_FORMATTERS))
    }

    /// [`new`](Self::new) with `formatters` formatting threads (at least 1).
    pub fn with_formatters(rate_hz: f64, out: W, formatters: usize) -> std::io::Result<Self> {
        Self::start(rate_hz, out, formatters, 1)
    }

    /// The trace of a render of `contacts` contacts (columns
    /// [`trace_header`]), fed by [`TraceSink::record_several`].
    pub fn with_contacts(rate_hz: f64, out: W, contacts: usize) -> std::io::Result<Self> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self::start(rate_hz, out, cores.min(CSV_MAX_FORMATTERS), contacts)
    }

    fn start(
        rate_hz: f64,
        mut out: W,
        formatters: usize,
        contacts: usize,
    ) -> std::io::Result<Self> {
        use crossbeam::channel::bounded;
        let contacts = contacts.clamp(1, MAX_CONTACTS);
        writeln!(out, "{}", trace_header(contacts))?;
        let formatters = formatters.max(1);
        let (to_format, chunks) = bounded::<Chunk>(CSV_CHUNKS_IN_FLIGHT);
        let (to_writer, texts) = bounded::<(u64, Vec<u8>)>(CSV_CHUNKS_IN_FLIGHT);
        let (give_rows, spare) = bounded(CSV_CHUNKS_IN_FLIGHT + formatters + 1);
        let (give_text, spare_text) = bounded::<Vec<u8>>(2 * CSV_CHUNKS_IN_FLIGHT + formatters + 1);
        let mut threads = Vec::with_capacity(formatters);
        for k in 0..formatters {
            let (chunks, to_writer) = (chunks.clone(), to_writer.clone());
            let (give_rows, spare_text) = (give_rows.clone(), spare_text.clone());
            threads.push(
                std::thread::Builder::new()
                    .name(format!("trace-csv-format-{k}"))
                    .spawn(move || {
                        for (seq, mut rows) in chunks {
                            // a spare text keeps its length: only what
                            // this chunk may need beyond it is zeroed
                            let mut text = spare_text.try_recv().unwrap_or_default();
                            text.resize(rows.len() * ROW_ROOM, 0);
                            let mut end = 0;
                            if contacts == 1 {
                                for r in &rows {
                                    end = put_row(&mut text, end, r);
                                }
                            } else {
                                for sample in rows.chunks(contacts) {
                                    end = put_sample(&mut text, end, sample);
                                }
                            }
                            text.truncate(end);
                            rows.clear();
                            let _ = give_rows.try_send(rows);
                            if to_writer.send((seq, text)).is_err() {
                                // the writer stopped (a failed write)
                                return;
                            }
                        }
                    })?,
            );
        }
        drop((to_writer, chunks, give_rows, spare_text));
        // texts arrive in any order: the writer takes each at its turn
        let writer = spawn_ordered_writer("trace-csv-write", out, texts, give_text)?;
        Ok(Self {
            rate_hz,
            contacts,
            rows: Vec::with_capacity(CSV_CHUNK_ROWS * contacts),
            queue: ChunkQueue {
                seq: 0,
                to: Some(to_format),
                spare,
            },
            formatters: threads,
            writer: Some(writer),
        })
    }

    /// Hand the rows so far to the formatting threads; an error if the
    /// writer has stopped (a failed write: [`finish`](Self::finish) returns
    /// it).
    fn send(&mut self) -> std::io::Result<()> {
        self.queue
            .send(&mut self.rows, CSV_CHUNK_ROWS * self.contacts)
    }

    /// Stop the threads and wait for them: the writer's result, or an error
    /// if a thread panicked.
    fn join(&mut self) -> std::io::Result<W> {
        self.queue.close();
        let mut panicked = false;
        for t in self.formatters.drain(..) {
            panicked |= t.join().is_err();
        }
        let written = join_writer(&mut self.writer);
        if panicked {
            return Err(std::io::Error::other("a trace formatting thread panicked"));
        }
        written
    }

    /// Write the remaining rows, wait for the threads, flush and hand back
    /// the writer (or the first write error).
    pub fn finish(mut self) -> std::io::Result<W> {
        let sent = if self.rows.is_empty() {
            Ok(())
        } else {
            self.send()
        };
        let out = self.join()?;
        sent.map(|_| out)
    }
}

impl<W: Write + Send + 'static> Drop for CsvTrace<W> {
    fn drop(&mut self) {
        // a sink dropped without `finish` (an error elsewhere): stop the
        // threads and wait for them, so none outlives the render
        if self.writer.is_some() {
            let _ = self.join();
        }
    }
}

impl<W: Write + Send + 'static> TraceSink for CsvTrace<W> {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.record_several(i, std::slice::from_ref(m), e)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        check_contacts(motions, self.contacts)?;
        let t = i as f64 / self.rate_hz;
        let e = e.expect("every energy was asked for");
        // the further contacts ride in rows of their own (their energy
        // unused): a sample is `contacts` consecutive rows
        self.rows.extend(motions.iter().map(|m| TraceRow {
            t,
            obs: m.with_energy(e),
        }));
        if self.rows.len() >= CSV_CHUNK_ROWS * self.contacts {
            self.send()?;
        }
        Ok(())
    }
}

/// The NPY header (format 1.0) of `rows` records whose fields are the
/// comma-separated `columns` (the CSV's header), each a little-endian f64
/// (`in_contact` 0 or 1).
fn npy_header_with(columns: &str, rows: usize) -> Vec<u8> {
    let fields: Vec<String> = columns
        .split(',')
        .map(|name| format!("('{name}', '<f8')"))
        .collect();
    let dict = format!(
        "{{'descr': [{}], 'fortran_order': False, 'shape': ({rows},), }}",
        fields.join(", ")
    );
    // magic, version 1.0, header length; the whole header padded with
    // spaces to a multiple of 64 bytes and ended by a newline
    let unpadded = 10 + dict.len() + 1;
    let pad = unpadded.next_multiple_of(64) - unpadded;
    let len = u16::try_from(dict.len() + pad + 1).expect("a short header");
    let mut h = b"\x93NUMPY\x01\x00".to_vec();
    h.extend_from_slice(&len.to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h.extend(std::iter::repeat_n(b' ', pad));
    h.push(b'\n');
    h
}

/// Bytes of one NPY trace record (7 f64 fields).
const NPY_RECORD: usize = 56;
/// Bytes a further contact adds to a record (5 f64 fields).
const NPY_FURTHER: usize = 40;

/// Writes the trace as a NumPy `.npy` file (docs/design.md, "The render
/// command and the trace CSV"): one record per sample with the CSV's
/// columns as named f64 fields, the numbers' own bits (no text), so
/// `numpy.load(path)["energy"]` reads a column exactly. The row count is
/// in the header, so the render's length is given up front;
/// [`finish`](Self::finish) checks that every row came. The records are
/// written by a writer thread in chunks of `CSV_CHUNK_ROWS` (the file
/// system's copy runs beside the engine).
pub struct NpyTrace<W: Write + Send + 'static> {
    rate_hz: f64,
    /// Contacts per record ([`trace_header`]).
    contacts: usize,
    /// Bytes handed to the writer at a time (whole records).
    chunk: usize,
    rows: usize,
    written: usize,
    buf: Vec<u8>,
    queue: ChunkQueue<u8>,
    writer: Option<std::thread::JoinHandle<std::io::Result<W>>>,
}

impl<W: Write + Send + 'static> NpyTrace<W> {
    /// Bytes per record of one contact (7 f64 fields).
    pub const RECORD: usize = NPY_RECORD;

    /// Write the header for `rows` records to `out` and start the writer.
    pub fn new(rate_hz: f64, rows: usize, out: W) -> std::io::Result<Self> {
        Self::with_contacts(rate_hz, rows, 1, out)
    }

    /// The trace of a render of `contacts` contacts: the fields of
    /// [`trace_header`], [`Self::RECORD`] bytes for contact 0 and 40 more
    /// per further contact; fed by [`TraceSink::record_several`].
    pub fn with_contacts(
        rate_hz: f64,
        rows: usize,
        contacts: usize,
        mut out: W,
    ) -> std::io::Result<Self> {
        use crossbeam::channel::bounded;
        let contacts = contacts.clamp(1, MAX_CONTACTS);
        out.write_all(&npy_header_with(&trace_header(contacts), rows))?;
        let chunk = CSV_CHUNK_ROWS * (NPY_RECORD + NPY_FURTHER * (contacts - 1));
        let (to_writer, chunks) = bounded(CSV_CHUNKS_IN_FLIGHT);
        let (give, spare) = bounded(CSV_CHUNKS_IN_FLIGHT + 1);
        let writer = spawn_ordered_writer("trace-npy-write", out, chunks, give)?;
        Ok(Self {
            rate_hz,
            contacts,
            chunk,
            rows,
            written: 0,
            buf: Vec::with_capacity(chunk),
            queue: ChunkQueue {
                seq: 0,
                to: Some(to_writer),
                spare,
            },
            writer: Some(writer),
        })
    }

    /// Hand the records so far to the writer; an error if it has stopped
    /// (a failed write: [`finish`](Self::finish) returns it).
    fn send(&mut self) -> std::io::Result<()> {
        self.queue.send(&mut self.buf, self.chunk)
    }

    /// Stop the writer and wait for it: its result, or an error if it
    /// panicked.
    fn join(&mut self) -> std::io::Result<W> {
        self.queue.close();
        join_writer(&mut self.writer)
    }

    /// Write the remaining records, wait for the writer, flush and hand
    /// back the output; an error if a write failed, or if fewer or more
    /// records came than the header says.
    pub fn finish(mut self) -> std::io::Result<W> {
        let sent = if self.buf.is_empty() {
            Ok(())
        } else {
            self.send()
        };
        let out = self.join()?;
        sent?;
        if self.written != self.rows {
            return Err(std::io::Error::other(format!(
                "the trace's header says {} rows, {} were recorded",
                self.rows, self.written
            )));
        }
        Ok(out)
    }

    fn push(&mut self, i: usize, m: &Motion, e: f64) {
        let row = TraceRow {
            t: i as f64 / self.rate_hz,
            obs: m.with_energy(e),
        };
        let mut rec = [0u8; NPY_RECORD];
        for (k, x) in row.columns().into_iter().enumerate() {
            rec[8 * k..8 * k + 8].copy_from_slice(&x.to_le_bytes());
        }
        self.buf.extend_from_slice(&rec);
    }
}

impl<W: Write + Send + 'static> Drop for NpyTrace<W> {
    fn drop(&mut self) {
        // dropped without `finish` (an error elsewhere): stop the writer
        // and wait for it, so it does not outlive the render
        if self.writer.is_some() {
            let _ = self.join();
        }
    }
}

impl<W: Write + Send + 'static> TraceSink for NpyTrace<W> {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.record_several(i, std::slice::from_ref(m), e)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        check_contacts(motions, self.contacts)?;
        self.push(i, &motions[0], e.expect("every energy was asked for"));
        for m in &motions[1..] {
            let flag = f64::from(u8::from(m.in_contact));
            for x in [m.x_hammer, m.v_hammer, m.x_contact, m.v_contact, flag] {
                self.buf.extend_from_slice(&x.to_le_bytes());
            }
        }
        self.written += 1;
        if self.buf.len() >= self.chunk {
            self.send()?;
        }
        Ok(())
    }
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        check_contacts(&[Motion::default()], self.contacts)?;
        for (k, (m, &e)) in motion.iter().zip(energy).enumerate() {
            self.push(first + k, m, e);
            if self.buf.len() >= self.chunk {
                self.send()?;
            }
        }
        self.written += motion.len().min(energy.len());
        Ok(())
    }
}

/// Largest number of buckets of a [`TraceEnvelope`].
pub const ENVELOPE_BUCKETS: usize = 1024;

/// One bucket of consecutive samples of a [`TraceEnvelope`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvelopeBucket {
    /// First sample.
    pub start: usize,
    /// Samples in the bucket.
    pub len: usize,
    /// Smallest and largest hammer height \[m\].
    pub x_hammer: [f64; 2],
    /// Smallest and largest contact-point displacement \[m\].
    pub x_contact: [f64; 2],
    /// Some sample of the bucket is in contact.
    pub in_contact: bool,
    /// Energy at the bucket's last sample \[J\] (total energy does not
    /// increase, so it is the bucket's smallest and the next one's start).
    pub energy_end: f64,
}

/// The plot's input: min/max per bucket of at most [`ENVELOPE_BUCKETS`]
/// buckets, whatever the length, and the energy at the bucket ends only,
/// so a 10-minute render costs the plot what a 1-second one does.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceEnvelope {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Samples per bucket (the last may be shorter).
    pub bucket_len: usize,
    /// Samples the render will have.
    pub samples: usize,
    /// Energy at sample 0 \[J\].
    pub energy_start: f64,
    /// The buckets so far.
    pub buckets: Vec<EnvelopeBucket>,
}

impl TraceEnvelope {
    /// An empty envelope for a render of `samples` samples.
    pub fn new(rate_hz: f64, samples: usize) -> Self {
        Self {
            rate_hz,
            bucket_len: samples.div_ceil(ENVELOPE_BUCKETS).max(1),
            samples,
            energy_start: f64::NAN,
            buckets: Vec::with_capacity(ENVELOPE_BUCKETS),
        }
    }

    fn is_bucket_end(&self, i: usize) -> bool {
        (i + 1).is_multiple_of(self.bucket_len) || i + 1 == self.samples
    }
}

impl TraceSink for TraceEnvelope {
    fn wants_energy(&self, i: usize) -> bool {
        i == 0 || self.is_bucket_end(i)
    }
    fn every_energy(&self) -> bool {
        false
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        if i == 0 {
            self.energy_start = e.expect("asked for");
        }
        if i.is_multiple_of(self.bucket_len) {
            self.buckets.push(EnvelopeBucket {
                start: i,
                len: 0,
                x_hammer: [m.x_hammer; 2],
                x_contact: [m.x_contact; 2],
                in_contact: false,
                energy_end: f64::NAN,
            });
        }
        let end = self.is_bucket_end(i);
        let b = self
            .buckets
            .last_mut()
            .expect("a bucket starts at sample 0");
        b.len += 1;
        b.x_hammer = [b.x_hammer[0].min(m.x_hammer), b.x_hammer[1].max(m.x_hammer)];
        b.x_contact = [
            b.x_contact[0].min(m.x_contact),
            b.x_contact[1].max(m.x_contact),
        ];
        b.in_contact |= m.in_contact;
        if end {
            b.energy_end = e.expect("asked for");
        }
        Ok(())
    }
    /// Contact 0's hammer and point, shaded where any contact is closed.
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        let m = Motion {
            in_contact: motions.iter().any(|m| m.in_contact),
            ..motions[0]
        };
        self.record(i, &m, e)
    }
    /// [`record`](Self::record) for a run of samples, a bucket's share at
    /// a time (the same min/max in the same order).
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        let n = motion.len().min(energy.len());
        let mut k = 0;
        while k < n {
            let i = first + k;
            if i.is_multiple_of(self.bucket_len) {
                // a bucket starts (and may end, or be the render's first)
                let e = self.wants_energy(i).then_some(energy[k]);
                self.record(i, &motion[k], e)?;
                k += 1;
                continue;
            }
            // the rest of this bucket within the run
            let span = (self.bucket_len - i % self.bucket_len).min(n - k);
            let end = self.is_bucket_end(i + span - 1);
            let b = self
                .buckets
                .last_mut()
                .expect("a bucket starts at sample 0");
            for m in &motion[k..k + span] {
                b.x_hammer = [b.x_hammer[0].min(m.x_hammer), b.x_hammer[1].max(m.x_hammer)];
                b.x_contact = [
                    b.x_contact[0].min(m.x_contact),
                    b.x_contact[1].max(m.x_contact),
                ];
                b.in_contact |= m.in_contact;
            }
            b.len += span;
            if end {
                b.energy_end = energy[k + span - 1];
            }
            k += span;
        }
        Ok(())
    }
}

/// The trace CSV header (docs/design.md, "The render command and the trace CSV").
pub const TRACE_HEADER: &str = "t,x_hammer,v_hammer,x_contact,v_contact,in_contact,energy";

/// The trace's header for `contacts` contacts (docs/design.md, "Several
/// contacts"): [`TRACE_HEADER`] for contact 0 (`energy` the total), then
/// `x_hammer_j, v_hammer_j, x_contact_j, v_contact_j, in_contact_j` for
/// each further contact `j`.
pub fn trace_header(contacts: usize) -> String {
    let mut h = String::from(TRACE_HEADER);
    for j in 1..contacts {
        h.push_str(&format!(
            ",x_hammer_{j},v_hammer_{j},x_contact_{j},v_contact_{j},in_contact_{j}"
        ));
    }
    h
}

/// Write trace rows as CSV (each number's shortest round-trip digits,
/// [`put_numbers`]).
pub fn write_trace_csv<W: Write>(rows: &[TraceRow], mut w: W) -> std::io::Result<()> {
    writeln!(w, "{TRACE_HEADER}")?;
    let mut buf = Vec::with_capacity(ROW_ROOM);
    for r in rows {
        buf.clear();
        push_row(&mut buf, r);
        w.write_all(&buf)?;
    }
    Ok(())
}

/// Room for one row in [`put_row`]: 6 numbers, each with its separator
/// (the `in_contact` flag is part of one).
const ROW_ROOM: usize = 6 * NUMBER_ROOM;

/// Append one CSV row to `buf` (numbers as [`put_numbers`] writes them).
fn push_row(buf: &mut Vec<u8>, r: &TraceRow) {
    let at = buf.len();
    buf.resize(at + ROW_ROOM, 0);
    let end = put_row(buf, at, r);
    buf.truncate(end);
}

/// Write one CSV row to `out[at..]` (room for [`ROW_ROOM`] bytes); the end.
fn put_row(out: &mut [u8], at: usize, r: &TraceRow) -> usize {
    let o = &r.obs;
    let xs = [
        r.t,
        o.x_hammer,
        o.v_hammer,
        o.x_contact,
        o.v_contact,
        o.energy,
    ];
    put_numbers(out, at, &xs, |k| match k {
        4 if o.in_contact => b",1,",
        4 => b",0,",
        5 => b"\n",
        _ => b",",
    })
}

/// Write one sample of a several-contact trace to `out[at..]` (room for
/// [`ROW_ROOM`] bytes per entry of `sample`): contact 0's row as
/// [`put_row`] writes it (its `energy` the total), then each further
/// contact's `x_hammer, v_hammer, x_contact, v_contact, in_contact`
/// ([`trace_header`]); the end.
fn put_sample(out: &mut [u8], at: usize, sample: &[TraceRow]) -> usize {
    let (r, further) = (&sample[0], &sample[1..]);
    let o = &r.obs;
    let xs = [
        r.t,
        o.x_hammer,
        o.v_hammer,
        o.x_contact,
        o.v_contact,
        o.energy,
    ];
    let mut at = put_numbers(out, at, &xs, |k| match k {
        4 if o.in_contact => b",1,",
        4 => b",0,",
        _ => b",",
    });
    for (j, f) in further.iter().enumerate() {
        let (m, last) = (&f.obs, j + 1 == further.len());
        let xs = [m.x_hammer, m.v_hammer, m.x_contact, m.v_contact];
        at = put_numbers(out, at, &xs, |k| match (k, m.in_contact, last) {
            (3, true, true) => b",1\n",
            (3, false, true) => b",0\n",
            (3, true, false) => b",1,",
            (3, false, false) => b",0,",
            _ => b",",
        });
    }
    at
}

/// Room for one number and its separator in [`put_numbers`]: a number is
/// at most 24 bytes (`-2.2250738585072014e-308`), a separator at most 8.
pub const NUMBER_ROOM: usize = 32;

/// Write `xs` to `out[at..]`, each as the shortest decimal text that reads
/// back to it exactly, as zmij (Schubfach) spells it: a decimal fraction
/// for exponents -5 to 15 (`0.00036`, `-123.5`, `0.0`), else scientific
/// (`1.5e-7`, `1e+20`); `NaN`, `inf`, `-inf` (which a trace never holds).
/// After number `k` comes `sep(k)` (at most 8 bytes: a separator).
/// `out[at..]` must have room for [`NUMBER_ROOM`] bytes per number; returns
/// the end of what was written.
///
/// Every CSV reader reads these (Rust's `parse`, Python's `float`, NumPy);
/// tested to read back bit for bit, with as many digits as core's shortest,
/// on numbers of every magnitude. The digits are not moved into core's
/// `{:e}` spelling: that move costs as much again as finding them.
///
/// Up to 8 numbers are formatted first and then moved with fixed-size
/// copies straight into `out`: a copy call per number took a fifth of the
/// text's time, and a load that spans several stores made just before it
/// (zmij writes its digits in pieces of several sizes) waits for them,
/// which the other numbers' work hides (docs/design.md, "Offline
/// rendering").
pub fn put_numbers(
    out: &mut [u8],
    mut at: usize,
    xs: &[f64],
    sep: impl Fn(usize) -> &'static [u8],
) -> usize {
    const BATCH: usize = 8;
    let mut fmts = [(); BATCH].map(|_| zmij::Buffer::new());
    for (c, batch) in xs.chunks(BATCH).enumerate() {
        let mut texts: [&[u8]; BATCH] = [&[]; BATCH];
        for ((f, &x), t) in fmts.iter_mut().zip(batch).zip(&mut texts) {
            *t = f.format(x).as_bytes();
        }
        for (j, s) in texts[..batch.len()].iter().enumerate() {
            copy_short(out, at, s);
            at += s.len();
            let p = sep(c * BATCH + j);
            copy_short(out, at, p);
            at += p.len();
        }
    }
    at
}

/// Append `xs` to `buf` as [`put_numbers`] writes them.
pub fn push_numbers(buf: &mut Vec<u8>, xs: &[f64], sep: impl Fn(usize) -> &'static [u8]) {
    let at = buf.len();
    buf.resize(at + xs.len() * NUMBER_ROOM, 0);
    let end = put_numbers(buf, at, xs, sep);
    buf.truncate(end);
}

/// Copy `s` (at most 32 bytes) to `o[at..]` in at most two fixed-size,
/// overlapping copies (no call, no per-byte loop beyond 3 bytes).
#[inline(always)]
fn copy_short(o: &mut [u8], at: usize, s: &[u8]) {
    let n = s.len();
    if n >= 16 {
        o[at..at + 16].copy_from_slice(&s[..16]);
        o[at + n - 16..at + n].copy_from_slice(&s[n - 16..]);
    } else if n >= 8 {
        o[at..at + 8].copy_from_slice(&s[..8]);
        o[at + n - 8..at + n].copy_from_slice(&s[n - 8..]);
    } else if n >= 4 {
        o[at..at + 4].copy_from_slice(&s[..4]);
        o[at + n - 4..at + n].copy_from_slice(&s[n - 4..]);
    } else {
        for (d, &c) in o[at..at + n].iter_mut().zip(s) {
            *d = c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::TestRng;

    fn text(x: f64) -> String {
        let mut buf = Vec::new();
        push_numbers(&mut buf, &[x], |_| b"");
        String::from_utf8(buf).unwrap()
    }

    /// Significant digits of a number's text (`-0.00120e3` -> 3).
    fn digits(s: &str) -> usize {
        let mantissa = s.split(['e', 'E']).next().unwrap();
        let d: String = mantissa.chars().filter(char::is_ascii_digit).collect();
        let d = d.trim_start_matches('0').trim_end_matches('0');
        d.len().max(1)
    }

    /// The CSV's numbers read back bit for bit, with the fewest digits
    /// (as many as core's shortest `{:e}`): special values, every power of
    /// ten, sample times, numbers with short exact expansions (where two
    /// shortest candidates can tie), random bit patterns (every magnitude,
    /// subnormals included) and random numbers of audio-like magnitudes;
    /// a few spellings pinned; six at a time as a row writes them.
    #[test]
    fn csv_numbers_read_back_exactly_with_the_fewest_digits() {
        let mut cases = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            100.0,
            123.456,
            1e-7,
            1.5e16,
            1e21,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            2.2675736961451248e-5,
            120.0,
            1234567.0,
            -0.25,
            9.999e-6,
            1e-5,
            1e-4,
            1e15,
            1e16,
            2e-320,
        ];
        cases.extend((-320..=308).map(|k| 10f64.powi(k)));
        cases.extend((0..100_000).map(|i| f64::from(i) / 44100.0));
        cases.extend((0..100_000).map(|i| f64::from(i) / 48000.0));
        cases.extend((1..20_000).map(|i| f64::from(i) / 1024.0 - 7.0));
        cases.extend((1..20_000).map(|i| f64::from(i) * 2f64.powi(60)));
        let mut rng = TestRng(7);
        for _ in 0..300_000 {
            let x = f64::from_bits(rng.next_u64());
            if x.is_finite() {
                cases.push(x);
            }
            let mag = 10f64.powf(rng.uniform(-30.0, 17.0));
            cases.push(rng.uniform(-0.5, 0.5) * mag);
        }
        for &x in &cases {
            let s = text(x);
            let back: f64 = s.parse().unwrap_or_else(|e| panic!("{s:?}: {e}"));
            assert_eq!(back.to_bits(), x.to_bits(), "{s:?} for {x:e}");
            assert_eq!(digits(&s), digits(&format!("{x:e}")), "{s:?} for {x:e}");
        }
        for (x, s) in [
            (0.0, "0.0"),
            (-0.0, "-0.0"),
            (0.00036, "0.00036"),
            (-123.5, "-123.5"),
            (1.5e-7, "1.5e-7"),
            (1e20, "1e+20"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
        ] {
            assert_eq!(text(x), s);
        }
        for six in cases.chunks_exact(6) {
            let mut got = Vec::new();
            push_numbers(&mut got, six, |_| b",");
            let want: String = six.iter().map(|&x| text(x) + ",").collect();
            assert_eq!(String::from_utf8(got).unwrap(), want);
        }
    }

    /// The left channel of a streamed render into `sink`.
    fn stream_left(compiled: &CompiledScene, n: usize, sink: &mut dyn TraceSink) -> Vec<f64> {
        let mut left = Vec::new();
        render_stream(
            compiled,
            n,
            |l, _| {
                left.extend_from_slice(l);
                Ok(())
            },
            Some(sink),
        )
        .unwrap();
        left
    }

    /// The CSV's rows, parsed back.
    fn parse_csv(bytes: &[u8]) -> Vec<TraceRow> {
        let text = std::str::from_utf8(bytes).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some(TRACE_HEADER));
        lines
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                let x = |i: usize| f[i].parse::<f64>().unwrap();
                TraceRow {
                    t: x(0),
                    obs: Observation {
                        x_hammer: x(1),
                        v_hammer: x(2),
                        x_contact: x(3),
                        v_contact: x(4),
                        in_contact: f[5] == "1",
                        energy: x(6),
                    },
                }
            })
            .collect()
    }

    /// Largest deviation of `got` from `want`, per column relative to the
    /// column's range over the render (energy: to its largest value);
    /// times and contact flags must be equal.
    fn worst_row_deviation(got: &[TraceRow], want: &[TraceRow]) -> [f64; 5] {
        assert_eq!(got.len(), want.len());
        let cols: [fn(&TraceRow) -> f64; 5] = [
            |r| r.obs.x_hammer,
            |r| r.obs.v_hammer,
            |r| r.obs.x_contact,
            |r| r.obs.v_contact,
            |r| r.obs.energy,
        ];
        cols.map(|f| {
            let (lo, hi) = want
                .iter()
                .map(f)
                .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
            let scale = if f(&want[0]) == want[0].obs.energy {
                hi.abs().max(lo.abs())
            } else {
                hi - lo
            }
            .max(1e-300);
            got.iter()
                .zip(want)
                .map(|(g, w)| {
                    assert_eq!(g.t, w.t);
                    assert_eq!(
                        g.obs.in_contact, w.obs.in_contact,
                        "contact flag at t = {}",
                        w.t
                    );
                    (f(g) - f(w)).abs() / scale
                })
                .fold(0.0, f64::max)
        })
    }

    /// The trace CSV comes from the block path with the kernel's motion and
    /// energy (O(N) per sample where the phase allows): on presets with one
    /// strike, bounces under gravity, a string (dense phases) and a wood
    /// block, with both switching methods, it gives the same audio bit for
    /// bit as the per-sample path and the same rows up to the order of the
    /// sums (1e-12 of each column's range; measured below 1e-15), and its
    /// energy never increases by more than the per-sample path's does.
    #[test]
    fn traced_block_path_matches_the_per_sample_rows() {
        for name in ["steel-plate", "paper-bounce", "paper-string", "wood-block"] {
            for sw in [Switching::Exact, Switching::OffsetRod] {
                let scene = crate::presets::scene(crate::presets::index_of(name).unwrap()).unwrap();
                let compiled = compile_with(&scene, 44100.0, Some(sw)).unwrap();
                let n = 30_000;
                let full = render_compiled(&compiled, n, true);
                let want = full.trace.unwrap();
                let mut csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
                let left = stream_left(&compiled, n, &mut csv);
                assert_eq!(left, full.left, "{name} {sw:?}: audio");
                let got = parse_csv(&csv.finish().unwrap());
                let worst = worst_row_deviation(&got, &want);
                let rise = |rows: &[TraceRow]| {
                    rows.windows(2)
                        .map(|w| (w[1].obs.energy - w[0].obs.energy) / w[0].obs.energy.abs())
                        .fold(f64::MIN, f64::max)
                };
                let (rg, rw) = (rise(&got), rise(&want));
                println!(
                    "{name} {sw:?}: worst deviation (x_h, v_h, x_c, v_c, E) {:.1e} {:.1e} {:.1e} {:.1e} {:.1e}; \
                     largest energy rise per sample {rg:.1e} (per-sample path {rw:.1e})",
                    worst[0], worst[1], worst[2], worst[3], worst[4]
                );
                assert!(
                    worst.iter().all(|&w| w <= 1e-12),
                    "{name} {sw:?}: {worst:?}"
                );
                assert!(rg <= rw.max(0.0) + 1e-15, "{name} {sw:?}: {rg:e} vs {rw:e}");
            }
        }
    }

    /// A writer that fails after `left` bytes.
    struct FailAfter {
        left: usize,
    }

    impl Write for FailAfter {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            if b.len() > self.left {
                return Err(std::io::Error::other("disk full"));
            }
            self.left -= b.len();
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// The render stopped and `finish` said why.
    fn check_failed(streamed: std::io::Result<()>, finished: std::io::Result<()>) {
        let msg = format!(
            "{:?} / {:?}",
            streamed.as_ref().err(),
            finished.as_ref().err()
        );
        assert!(streamed.is_err(), "the render went on: {msg}");
        assert!(
            finished
                .err()
                .is_some_and(|e| e.to_string().contains("disk full")),
            "{msg}"
        );
    }

    /// A failed write of the trace's writer thread (CSV or NumPy) stops the
    /// render with that error (not a hang, not a silent short file), and a
    /// sink dropped without `finish` leaves no thread behind.
    #[test]
    fn trace_write_errors_reach_the_render() {
        let scene =
            crate::presets::scene(crate::presets::index_of("steel-plate").unwrap()).unwrap();
        let compiled = compile_with(&scene, 44100.0, None).unwrap();
        let n = 20 * CSV_CHUNK_ROWS;
        let csv = CsvTrace::new(44100.0, FailAfter { left: 200_000 }).unwrap();
        let npy = NpyTrace::new(44100.0, n, FailAfter { left: 200_000 }).unwrap();
        let mut csv = csv;
        let streamed = render_stream(
            &compiled,
            n,
            |_, _| Ok(()),
            Some(&mut csv as &mut dyn TraceSink),
        );
        let finished = csv.finish().map(drop);
        check_failed(streamed.map(drop), finished);
        let mut npy = npy;
        let streamed = render_stream(
            &compiled,
            n,
            |_, _| Ok(()),
            Some(&mut npy as &mut dyn TraceSink),
        );
        let finished = npy.finish().map(drop);
        check_failed(streamed.map(drop), finished);
        // dropped mid-way: joins its writer
        let mut csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
        for i in 0..3 * CSV_CHUNK_ROWS {
            csv.record(i, &Motion::default(), Some(0.0)).unwrap();
        }
        drop(csv);
        let mut npy = NpyTrace::new(44100.0, n, Vec::new()).unwrap();
        for i in 0..3 * CSV_CHUNK_ROWS {
            npy.record(i, &Motion::default(), Some(0.0)).unwrap();
        }
        drop(npy);
    }

    /// Streaming gives the in-memory render's samples and rows, whatever
    /// the sink: the block path and the observed path agree bit for bit
    /// with the per-sample path, and the CSV written as it goes holds the
    /// same rows up to the order of the sums.
    #[test]
    fn streamed_render_matches_in_memory_render() {
        let scene =
            crate::presets::scene(crate::presets::index_of("steel-plate").unwrap()).unwrap();
        let compiled = compile_with(&scene, 44100.0, None).unwrap();
        let n = 3 * STREAM_CHUNK + 17;
        let full = render_compiled(&compiled, n, true);
        let plain = render_compiled(&compiled, n, false);
        assert_eq!(full.left, plain.left);
        assert_eq!(full.right, plain.right);
        let mut want = Vec::new();
        write_trace_csv(full.trace.as_ref().unwrap(), &mut want).unwrap();
        let mut csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
        let mut env = TraceEnvelope::new(44100.0, n);
        let mut both = (csv, env);
        let left = stream_left(&compiled, n, &mut both);
        (csv, env) = both;
        assert_eq!(left, full.left);
        let got = parse_csv(&csv.finish().unwrap());
        assert!(worst_row_deviation(&got, &full.trace.as_ref().unwrap()[..])
            .iter()
            .all(|&w| w <= 1e-12));
        assert_eq!(parse_csv(&want).len(), n);
        // the envelope saw what the CSV saw (the same block path), bit for
        // bit: every sample in one bucket, min/max and energy right
        let rows = got;
        assert_eq!(env.buckets.iter().map(|b| b.len).sum::<usize>(), n);
        assert!(env.buckets.len() <= ENVELOPE_BUCKETS);
        assert_eq!(env.energy_start, rows[0].obs.energy);
        for b in &env.buckets {
            let span = &rows[b.start..b.start + b.len];
            let lo = span
                .iter()
                .map(|r| r.obs.x_contact)
                .fold(f64::INFINITY, f64::min);
            let hi = span
                .iter()
                .map(|r| r.obs.x_contact)
                .fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(b.x_contact, [lo, hi]);
            assert_eq!(b.in_contact, span.iter().any(|r| r.obs.in_contact));
            assert_eq!(b.energy_end, span.last().unwrap().obs.energy);
        }
        assert!(env.buckets.iter().any(|b| b.in_contact));
    }

    /// The CSV written by several formatting threads (chunks formatted side
    /// by side, written in order) is byte for byte the one written on one
    /// thread, for 1, 2 and 5 threads and lengths around the chunk size.
    #[test]
    fn csv_from_several_formatting_threads_is_the_one_thread_csv() {
        let mut rng = TestRng(11);
        let rows: Vec<TraceRow> = (0..7 * CSV_CHUNK_ROWS + 5)
            .map(|i| TraceRow {
                t: i as f64 / 48000.0,
                obs: Observation {
                    x_hammer: rng.uniform(-1e-3, 1e-3),
                    v_hammer: rng.uniform(-2.0, 2.0),
                    x_contact: rng.uniform(-1e-5, 1e-5),
                    v_contact: rng.uniform(-1e-2, 1e-2),
                    in_contact: rng.uniform(0.0, 1.0) < 0.1,
                    energy: rng.uniform(0.0, 1e-2),
                },
            })
            .collect();
        for n in [0, 1, CSV_CHUNK_ROWS, CSV_CHUNK_ROWS + 1, rows.len()] {
            let mut want = Vec::new();
            write_trace_csv(&rows[..n], &mut want).unwrap();
            for threads in [1, 2, 5] {
                let mut csv = CsvTrace::with_formatters(48000.0, Vec::new(), threads).unwrap();
                for (i, r) in rows[..n].iter().enumerate() {
                    let m = Motion {
                        x_hammer: r.obs.x_hammer,
                        v_hammer: r.obs.v_hammer,
                        x_contact: r.obs.x_contact,
                        v_contact: r.obs.v_contact,
                        in_contact: r.obs.in_contact,
                    };
                    csv.record(i, &m, Some(r.obs.energy)).unwrap();
                }
                assert!(csv.finish().unwrap() == want, "{n} rows, {threads} threads");
            }
        }
    }

    /// The envelope built from runs of samples (`record_run`, what the
    /// traced render hands it) is the one built sample by sample, for
    /// renders shorter and longer than its 1024 buckets and runs that
    /// start and end anywhere in a bucket.
    #[test]
    fn envelope_from_runs_is_the_envelope_from_samples() {
        let mut rng = TestRng(5);
        for samples in [1, 7, 1000, 1024, 1025, 5000, 70_001] {
            let motion: Vec<Motion> = (0..samples)
                .map(|_| Motion {
                    x_hammer: rng.uniform(-1.0, 1.0),
                    v_hammer: 0.0,
                    x_contact: rng.uniform(-1.0, 1.0),
                    v_contact: 0.0,
                    in_contact: rng.uniform(0.0, 1.0) < 0.01,
                })
                .collect();
            let energy: Vec<f64> = (0..samples).map(|_| rng.uniform(0.0, 1.0)).collect();
            let mut want = TraceEnvelope::new(44100.0, samples);
            for (i, m) in motion.iter().enumerate() {
                let e = want.wants_energy(i).then_some(energy[i]);
                want.record(i, m, e).unwrap();
            }
            let mut got = TraceEnvelope::new(44100.0, samples);
            let mut at = 0;
            while at < samples {
                let len = (1 + (rng.uniform(0.0, 1.0) * 3000.0) as usize).min(samples - at);
                got.record_run(at, &motion[at..at + len], &energy[at..at + len])
                    .unwrap();
                at += len;
            }
            assert_eq!(got.energy_start, want.energy_start, "{samples}");
            assert_eq!(got.buckets, want.buckets, "{samples}");
        }
    }

    /// The NPY trace holds the CSV trace's numbers bit for bit (the CSV's
    /// shortest digits read back exactly), under a NumPy v1.0 header that
    /// names the CSV's columns, with the row count, padded to 64 bytes; a
    /// trace with fewer rows than its header is an error.
    #[test]
    fn npy_trace_is_the_csv_trace_in_binary() {
        let scene =
            crate::presets::scene(crate::presets::index_of("paper-bounce").unwrap()).unwrap();
        let compiled = compile_with(&scene, 44100.0, None).unwrap();
        let n = 2 * CSV_CHUNK_ROWS + 123;
        let csv = CsvTrace::new(44100.0, Vec::new()).unwrap();
        let npy = NpyTrace::new(44100.0, n, Vec::new()).unwrap();
        let mut both = (csv, npy);
        stream_left(&compiled, n, &mut both);
        let (csv, npy) = both;
        let rows = parse_csv(&csv.finish().unwrap());
        let bytes = npy.finish().unwrap();
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        let hlen = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
        assert_eq!((10 + hlen) % 64, 0);
        let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
        assert!(header.ends_with('\n'), "{header:?}");
        assert_eq!(
            header.trim_end(),
            format!(
                "{{'descr': [('t', '<f8'), ('x_hammer', '<f8'), ('v_hammer', '<f8'), \
                 ('x_contact', '<f8'), ('v_contact', '<f8'), ('in_contact', '<f8'), \
                 ('energy', '<f8')], 'fortran_order': False, 'shape': ({n},), }}"
            )
        );
        let body = &bytes[10 + hlen..];
        assert_eq!(body.len(), n * NpyTrace::<Vec<u8>>::RECORD);
        assert_eq!(rows.len(), n);
        let mut contacts = 0;
        for (rec, r) in body.chunks_exact(56).zip(&rows) {
            let f = |k: usize| f64::from_le_bytes(rec[8 * k..8 * k + 8].try_into().unwrap());
            let o = &r.obs;
            let want = [r.t, o.x_hammer, o.v_hammer, o.x_contact, o.v_contact];
            for (k, w) in want.into_iter().enumerate() {
                assert_eq!(f(k).to_bits(), w.to_bits(), "column {k} at t = {}", r.t);
            }
            assert_eq!(f(5), if o.in_contact { 1.0 } else { 0.0 });
            assert_eq!(f(6).to_bits(), o.energy.to_bits());
            contacts += usize::from(o.in_contact);
        }
        assert!(contacts > 0, "the render should hold a contact");
        // fewer rows than the header says
        let mut short = NpyTrace::new(44100.0, 3, Vec::new()).unwrap();
        short.record(0, &Motion::default(), Some(0.0)).unwrap();
        let e = short.finish().unwrap_err().to_string();
        assert!(e.contains("3 rows, 1 were recorded"), "{e}");
    }

    /// The plot's envelope on the block path with the motion equals the one
    /// built from every traced row, on presets with one strike, bounces and
    /// a string, with both switching methods: the same audio bit for bit,
    /// the same contact buckets, and min/max and energies equal up to the
    /// order of the sums (relative 1e-12 of the signal's range; measured 3.4e-16).
    #[test]
    fn envelope_on_the_block_path_matches_the_traced_rows() {
        for name in ["steel-plate", "paper-bounce", "paper-string", "wood-block"] {
            for sw in [Switching::Exact, Switching::OffsetRod] {
                let scene = crate::presets::scene(crate::presets::index_of(name).unwrap()).unwrap();
                let compiled = compile_with(&scene, 44100.0, Some(sw)).unwrap();
                let n = 30_000;
                let full = render_compiled(&compiled, n, true);
                let rows = full.trace.unwrap();
                let mut env = TraceEnvelope::new(44100.0, n);
                let left = stream_left(&compiled, n, &mut env);
                assert_eq!(left, full.left, "{name} {sw:?}: audio");
                let span = |f: fn(&TraceRow) -> f64| {
                    let (lo, hi) = rows
                        .iter()
                        .map(f)
                        .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
                    (hi - lo).max(1e-300)
                };
                let (sx, sc) = (span(|r| r.obs.x_hammer), span(|r| r.obs.x_contact));
                let se = span(|r| r.obs.energy).max(rows[0].obs.energy.abs());
                let mut worst = 0.0f64;
                assert!((env.energy_start - rows[0].obs.energy).abs() <= 1e-9 * se);
                for b in &env.buckets {
                    let part = &rows[b.start..b.start + b.len];
                    let mm = |f: fn(&TraceRow) -> f64| {
                        part.iter()
                            .map(f)
                            .fold([f64::MAX, f64::MIN], |[a, c], x| [a.min(x), c.max(x)])
                    };
                    let (xh, xc) = (mm(|r| r.obs.x_hammer), mm(|r| r.obs.x_contact));
                    for q in 0..2 {
                        worst = worst.max((b.x_hammer[q] - xh[q]).abs() / sx);
                        worst = worst.max((b.x_contact[q] - xc[q]).abs() / sc);
                    }
                    worst = worst.max((b.energy_end - part.last().unwrap().obs.energy).abs() / se);
                    assert_eq!(
                        b.in_contact,
                        part.iter().any(|r| r.obs.in_contact),
                        "{name} {sw:?}: contact flags of bucket at {}",
                        b.start
                    );
                }
                println!("{name} {sw:?}: worst envelope deviation {worst:.1e} of the range");
                assert!(worst <= 1e-12, "{name} {sw:?}: {worst:e}");
            }
        }
    }

    /// A sink that keeps one contact (the default `record_several`).
    struct OneContactOnly(usize);

    impl TraceSink for OneContactOnly {
        fn wants_energy(&self, _: usize) -> bool {
            false
        }
        fn record(&mut self, _: usize, _: &Motion, _: Option<f64>) -> std::io::Result<()> {
            self.0 += 1;
            Ok(())
        }
    }

    /// A several-contact scene renders through [`render()`] as through
    /// the several-contact engine's own loop (each sample's decision,
    /// observation and tick), bit for bit: the audio, every contact's
    /// motion in the rows in memory, and the CSV and NumPy traces, whose
    /// header names each contact's columns and whose numbers read back to
    /// the rows' exactly. A sink that keeps one contact refuses the
    /// render instead of dropping columns.
    #[test]
    fn a_several_contact_scene_renders_through_the_one_render() {
        let scene = crate::presets::scene(crate::presets::index_of("ball-between-plates").unwrap())
            .unwrap();
        let rate = 44_100.0;
        let n = 3000;
        let opts = RenderOptions {
            rate_hz: rate,
            seconds: Some(n as f64 / rate),
            switching: None,
            trace: true,
        };
        let out = render(&scene, &opts).unwrap();
        let Ok(Compiled::Several(c)) = Compiled::new(&scene, rate, None) else {
            panic!("a several-contact scene compiles for the several-contact engine");
        };
        let k = c.contacts();
        assert_eq!(k, 2);
        // the engine's own loop
        let mut st = MultiState::new(&c);
        let rows = out.trace.as_ref().unwrap();
        assert_eq!(rows.len(), n);
        assert_eq!(out.trace_further.len(), n * (k - 1));
        for i in 0..n {
            st.decide(&c);
            let o = st.observe(&c);
            assert_eq!(
                rows[i].obs,
                contact_motion(&o, 0).with_energy(o.energy),
                "row {i}"
            );
            for j in 1..k {
                assert_eq!(
                    out.trace_further[i * (k - 1) + j - 1],
                    contact_motion(&o, j)
                );
            }
            let [l, r] = st.tick(&c);
            assert_eq!((out.left[i], out.right[i]), (l, r), "sample {i}");
        }
        // the block path (no trace) makes the same samples
        let plain = Compiled::Several(c.clone()).render(n, false);
        assert!(plain.left == out.left && plain.right == out.right);
        let started: u64 = st.stats.contacts_started[..k].iter().sum();
        assert!(started >= 2, "the ball touches: {started} contacts");
        assert_eq!(out.contacts, started);
        assert_eq!(out.several, Some(st.stats));
        // the CSV: the header, and every number of every row
        let mut csv = CsvTrace::with_contacts(rate, Vec::new(), k).unwrap();
        let stats = render_stream_several(&c, n, |_, _| Ok(()), Some(&mut csv)).unwrap();
        assert_eq!(stats.several, out.several);
        let text = String::from_utf8(csv.finish().unwrap()).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next().unwrap(), trace_header(k));
        let flag = |b: bool| f64::from(u8::from(b));
        let mut expect = Vec::new();
        for (i, line) in lines.enumerate() {
            let got: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            let mut want = rows[i].columns().to_vec();
            for m in &out.trace_further[i * (k - 1)..(i + 1) * (k - 1)] {
                want.extend([
                    m.x_hammer,
                    m.v_hammer,
                    m.x_contact,
                    m.v_contact,
                    flag(m.in_contact),
                ]);
            }
            assert_eq!(got.len(), 7 + 5 * (k - 1));
            for (a, b) in got.iter().zip(&want) {
                assert_eq!(a.to_bits(), b.to_bits(), "CSV row {i}: {line}");
            }
            expect.extend(want);
        }
        assert_eq!(expect.len(), n * (7 + 5 * (k - 1)));
        // the NumPy trace: the same numbers' own bits after its header
        let mut npy = NpyTrace::with_contacts(rate, n, k, Vec::new()).unwrap();
        render_stream_several(&c, n, |_, _| Ok(()), Some(&mut npy)).unwrap();
        let bytes = npy.finish().unwrap();
        let body = &bytes[bytes.len() - 8 * expect.len()..];
        for (q, x) in expect.iter().enumerate() {
            let b: [u8; 8] = body[8 * q..8 * q + 8].try_into().unwrap();
            assert_eq!(
                f64::from_le_bytes(b).to_bits(),
                x.to_bits(),
                "NPY field {q}"
            );
        }
        assert!(String::from_utf8_lossy(&bytes[..bytes.len() - body.len()])
            .contains("'x_hammer_1', '<f8'"));
        // a one-contact sink refuses
        let mut one = OneContactOnly(0);
        let refused = render_stream_several(&c, n, |_, _| Ok(()), Some(&mut one)).unwrap_err();
        assert!(
            refused.to_string().contains("takes one contact"),
            "{refused}"
        );
        assert_eq!(one.0, 0);
    }
}
