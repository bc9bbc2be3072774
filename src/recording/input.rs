//! The recording before the fit: every sample finite, not silent, long
//! enough; where the strike starts (the onset), where the flat tops of a
//! clipped attack end, where the free decay analysed starts and ends, and
//! the noise floor around the strike.

use super::{AnalysisOptions, Clipping, RecordingError, MIN_SECONDS, RATE_RANGE_HZ};

/// A peak below this (relative to full scale 1) is silence: -120 dB, under
/// the dither of a 16-bit file and far under any microphone's noise.
pub(crate) const SILENCE: f64 = 1e-6;

/// The onset is the first sample at this fraction of the peak (-20 dB):
/// ten times the noise of a recording whose noise is 40 dB under its peak,
/// so the noise does not trigger it.
const ONSET_FRACTION: f64 = 0.1;

/// A clipped run is at least this many consecutive samples at the peak
/// magnitude with one sign (a clean recording's peak is one sample).
const CLIP_RUN: usize = 3;

/// Samples within this fraction of the peak magnitude count as at full
/// scale for the clipping check.
const CLIP_TOLERANCE: f64 = 1e-6;

/// The recording, checked and located.
#[derive(Debug, Clone)]
pub(crate) struct Located {
    /// The largest magnitude of the recording.
    pub peak: f64,
    /// The onset (first sample at a tenth of the peak).
    pub onset: usize,
    /// The first sample of the free decay analysed.
    pub start: usize,
    /// One past the last sample analysed.
    pub end: usize,
    /// The clipped runs, if any.
    pub clipping: Option<Clipping>,
    /// The RMS of the noise: before the onset when there are 20 ms of it,
    /// else over the last tenth of the recording (an upper bound when the
    /// object still rings there).
    pub noise_rms: f64,
}

/// Check the samples and locate the strike's free decay.
pub(crate) fn locate(
    x: &[f64],
    rate_hz: f64,
    opts: &AnalysisOptions,
) -> Result<Located, RecordingError> {
    if !(rate_hz.is_finite() && (RATE_RANGE_HZ.0..=RATE_RANGE_HZ.1).contains(&rate_hz)) {
        return Err(RecordingError::SampleRate(rate_hz));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(RecordingError::NonFinite(i));
    }
    let seconds = x.len() as f64 / rate_hz;
    if seconds < MIN_SECONDS {
        return Err(RecordingError::TooShort {
            seconds,
            needed: MIN_SECONDS,
        });
    }
    let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if !(peak >= SILENCE) {
        return Err(RecordingError::Silent(peak));
    }
    let onset = x
        .iter()
        .position(|v| v.abs() >= ONSET_FRACTION * peak)
        .unwrap_or(0);
    let clipping = clipped_runs(x, peak);
    let (start, end) = analysed_span(x.len(), rate_hz, onset, clipping.as_ref(), opts)?;
    Ok(Located {
        peak,
        onset,
        start,
        end,
        clipping,
        noise_rms: noise_rms(x, rate_hz, onset),
    })
}

/// The runs of at least [`CLIP_RUN`] samples at the peak magnitude with
/// one sign.
fn clipped_runs(x: &[f64], peak: f64) -> Option<Clipping> {
    let level = peak * (1.0 - CLIP_TOLERANCE);
    let (mut runs, mut samples, mut last_end) = (0, 0, 0);
    let mut i = 0;
    while i < x.len() {
        if x[i].abs() < level {
            i += 1;
            continue;
        }
        let sign = x[i] > 0.0;
        let mut j = i;
        while j < x.len() && x[j].abs() >= level && (x[j] > 0.0) == sign {
            j += 1;
        }
        if j - i >= CLIP_RUN {
            runs += 1;
            samples += j - i;
            last_end = j;
        }
        i = j;
    }
    (runs > 0).then_some(Clipping {
        runs,
        samples,
        end: last_end,
        level: peak,
    })
}

/// The free decay analysed: from the time range's start, or else from
/// `settle_s` after the onset and after the last clipped sample; to the
/// time range's end or the recording's.
fn analysed_span(
    len: usize,
    rate_hz: f64,
    onset: usize,
    clipping: Option<&Clipping>,
    opts: &AnalysisOptions,
) -> Result<(usize, usize), RecordingError> {
    let at = |s: f64| ((s * rate_hz).round().max(0.0) as usize).min(len);
    let clip_end = clipping.map_or(0, |c| c.end);
    let start = match opts.start_s {
        Some(s) => at(s).max(clip_end),
        None => (onset.max(clip_end) + at(opts.settle_s)).min(len),
    };
    let end = opts.end_s.map_or(len, at);
    let needed = super::MIN_DECAY_S;
    let seconds = end.saturating_sub(start) as f64 / rate_hz;
    if seconds < needed {
        return Err(RecordingError::TooShort { seconds, needed });
    }
    Ok((start, end))
}

/// The RMS of the 20 ms or more before the onset (less 5 ms, the pre-echo
/// of a mallet's approach), or else of the last tenth of the recording.
fn noise_rms(x: &[f64], rate_hz: f64, onset: usize) -> f64 {
    let guard = (0.005 * rate_hz) as usize;
    let before = onset.saturating_sub(guard);
    let part = if before as f64 >= 0.02 * rate_hz {
        &x[..before]
    } else {
        &x[x.len() - (x.len() / 10).max(1)..]
    };
    (part.iter().map(|v| v * v).sum::<f64>() / part.len().max(1) as f64).sqrt()
}
