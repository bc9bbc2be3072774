//! Offline rendering: scene -> compile -> engine, with an optional trace
//! (docs/design.md, "The render command and the trace CSV"). Used by `cargo xtask render`, the report and tests.

use crate::compile::{compile_with, CompileError, CompiledScene};
use crate::engine::{EngineState, ExactStats, Observation};
use crate::scene::{Scene, Switching, MAX_DURATION_S};
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

/// Result of a render.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Left and right pickup signals (f64, physical units times pickup gains).
    pub left: Vec<f64>,
    /// See `left`.
    pub right: Vec<f64>,
    /// Trace rows, if requested.
    pub trace: Option<Vec<TraceRow>>,
    /// The compiler's summary.
    pub summary: String,
    /// Number of contacts that started.
    pub contacts: u64,
    /// What exact switching did (all zero with the offset rod).
    pub exact_stats: ExactStats,
}

impl RenderOutput {
    /// One line on the exact switching's work and its diagnostics (the
    /// counters that must stay 0: `capped`, `rod_fallbacks`,
    /// `uncertified`).
    pub fn switching_line(&self) -> String {
        let x = &self.exact_stats;
        format!(
            "exact switching: {} located switches, {} grazing touches; capped {}, rod fallbacks {}, uncertified {}; \
             event search: {} nodes, at most {} nodes and {} switches in one sample",
            x.located,
            x.grazing,
            x.capped,
            x.rod_fallbacks,
            x.uncertified,
            x.search_nodes,
            x.max_nodes_in_sample,
            x.max_switches_in_sample
        )
    }
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

/// Render a scene offline.
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<RenderOutput, RenderError> {
    let seconds = opts.seconds.unwrap_or(scene.duration_s);
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= MAX_DURATION_S) {
        return Err(RenderError::Length(seconds));
    }
    let compiled = compile_with(scene, opts.rate_hz, opts.switching)?;
    let n = (seconds * opts.rate_hz).round() as usize;
    Ok(render_compiled(&compiled, n, opts.trace))
}

/// Render `n` samples of a compiled scene from its initial state.
pub fn render_compiled(compiled: &CompiledScene, n: usize, trace: bool) -> RenderOutput {
    let mut st = EngineState::new(compiled);
    let mut left = Vec::with_capacity(n);
    let mut right = Vec::with_capacity(n);
    let mut rows = if trace {
        Some(Vec::with_capacity(n))
    } else {
        None
    };
    for i in 0..n {
        let out = if let Some(rows) = rows.as_mut() {
            let (out, obs) = st.tick_observed(compiled);
            rows.push(TraceRow {
                t: i as f64 / compiled.rate_hz,
                obs,
            });
            out
        } else {
            st.tick(compiled)
        };
        left.push(out[0]);
        right.push(out[1]);
    }
    RenderOutput {
        rate_hz: compiled.rate_hz,
        left,
        right,
        trace: rows,
        summary: compiled.summary.clone(),
        contacts: st.contacts_started,
        exact_stats: st.exact_stats,
    }
}

/// The trace CSV header (docs/design.md, "The render command and the trace CSV").
pub const TRACE_HEADER: &str = "t,x_hammer,v_hammer,x_contact,v_contact,in_contact,energy";

/// Write trace rows as CSV (full f64 precision, round-trip exact).
pub fn write_trace_csv<W: Write>(rows: &[TraceRow], mut w: W) -> std::io::Result<()> {
    writeln!(w, "{TRACE_HEADER}")?;
    for r in rows {
        let o = &r.obs;
        writeln!(
            w,
            "{:e},{:e},{:e},{:e},{:e},{},{:e}",
            r.t,
            o.x_hammer,
            o.v_hammer,
            o.x_contact,
            o.v_contact,
            u8::from(o.in_contact),
            o.energy
        )?;
    }
    Ok(())
}
