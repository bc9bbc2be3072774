//! Offline rendering: scene -> compile -> engine, with an optional trace
//! (docs/design.md, "The render command and the trace CSV"). Used by `cargo xtask render`, the report and tests.
//!
//! This file holds the render's options, output and errors, the compiled
//! scene of one or several contacts and the in-memory render; the rest of
//! the room: `stream.rs` (the streamed render, audio in chunks and the
//! trace sample by sample), `trace.rs` (the trace's rows and header, the
//! [`TraceSink`] and the rows in memory), `csv.rs` (the CSV trace and its
//! formatting threads), `numbers.rs` (the CSV's shortest round-trip
//! digits), `npy.rs` (the NumPy trace), `writer.rs` (the trace files'
//! writer thread) and `envelope.rs` (the plot's envelope).

use crate::compile::{CompileError, CompiledScene};
use crate::engine::{ExactStats, Motion};
use crate::multi::{CompiledMulti, MultiStats};
use crate::play::Compiled;
use crate::scene::{Scene, Switching, MAX_DURATION_S};

mod csv;
mod envelope;
mod npy;
mod numbers;
mod stream;
#[cfg(test)]
mod tests;
mod trace;
mod writer;

pub use csv::{write_trace_csv, CsvTrace};
pub use envelope::{EnvelopeBucket, TraceEnvelope, ENVELOPE_BUCKETS};
pub use npy::NpyTrace;
pub use numbers::{push_numbers, put_numbers, NUMBER_ROOM};
pub use stream::{
    render_stream, render_stream_several, render_stream_several_on, StreamStats, STREAM_CHUNK,
};
pub use trace::{
    trace_header, trace_header_with, TraceRow, TraceRows, TraceSink, DRIVE_COLUMNS, TRACE_HEADER,
};

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

/// Render a scene of one to [`MAX_SPRINGS`](crate::scene::MAX_SPRINGS)
/// contacts offline (in memory; [`Compiled::stream`] for long renders).
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<RenderOutput, RenderError> {
    let seconds = opts.seconds.unwrap_or(scene.duration_s);
    let n = render_length(seconds, opts.rate_hz)?;
    Ok(Compiled::new(scene, opts.rate_hz, opts.switching)?.render(n, opts.trace))
}

/// The render of a scene of one or several contacts (the type is the
/// embedder's, [`crate::play`]; its offline render is here).
impl Compiled {
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
    render_several_on(compiled, n, trace, false)
}

/// [`render_several`] on the portable kernels (`portable`) or this CPU's
/// fastest ([`MultiState::set_portable_kernels`](crate::multi::MultiState::set_portable_kernels)).
pub fn render_several_on(
    compiled: &CompiledMulti,
    n: usize,
    trace: bool,
    portable: bool,
) -> RenderOutput {
    let k = compiled.contacts();
    render_in_memory(
        compiled.rate_hz,
        k,
        n,
        trace,
        String::new(),
        |audio, sink| render_stream_several_on(compiled, n, audio, sink, portable),
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
