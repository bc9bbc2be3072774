//! Streaming a render (docs/design.md, "Offline rendering"): the audio in
//! chunks, the trace (if any) sample by sample, for one contact on the
//! engine and for several on the several-contact engine.

use super::trace::TraceSink;
use crate::compile::CompiledScene;
use crate::engine::{EngineState, ExactStats, Motion};
use crate::multi::{CompiledMulti, MultiObservation, MultiState, MultiStats};
use crate::scene::MAX_SPRINGS;

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
            Some(sink) if compiled.drive.is_some() => {
                // a driven scene: each row with the surface at its instant
                for k in 0..len {
                    let i = done + k;
                    let want = sink.wants_energy(i);
                    let (out, (m, e, at)) = st.tick_with(compiled, |s| {
                        (
                            s.motion(compiled),
                            want.then(|| s.energy(compiled)),
                            s.surface_at(compiled).unwrap_or_default(),
                        )
                    });
                    sink.record_driven(i, &m, e, [at.path_m, at.height_m])?;
                    lc[k] = out[0];
                    rc[k] = out[1];
                }
            }
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
    audio: impl FnMut(&[f64], &[f64]) -> std::io::Result<()>,
    trace: Option<&mut dyn TraceSink>,
) -> std::io::Result<StreamStats> {
    render_stream_several_on(compiled, n, audio, trace, false)
}

/// [`render_stream_several`] on the portable kernels (`portable`) or this
/// CPU's fastest ([`MultiState::set_portable_kernels`]).
pub fn render_stream_several_on(
    compiled: &CompiledMulti,
    n: usize,
    mut audio: impl FnMut(&[f64], &[f64]) -> std::io::Result<()>,
    mut trace: Option<&mut dyn TraceSink>,
    portable: bool,
) -> std::io::Result<StreamStats> {
    let mut st = MultiState::new(compiled);
    st.set_portable_kernels(portable);
    let k = compiled.contacts();
    let (mut l, mut r) = (
        vec![0.0; STREAM_CHUNK.min(n)],
        vec![0.0; STREAM_CHUNK.min(n)],
    );
    let mut motions = [Motion::default(); MAX_SPRINGS];
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
pub(super) fn contact_motion(o: &MultiObservation, j: usize) -> Motion {
    Motion {
        x_hammer: o.x_hammer[j],
        v_hammer: o.v_hammer[j],
        x_contact: o.x_contact[j],
        v_contact: o.v_contact[j],
        in_contact: o.active & (1 << j) != 0,
    }
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
