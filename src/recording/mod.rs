//! Modes of a struck object from a recording of its strike: frequency,
//! T60 and complex amplitude of each mode, from the free decay after the
//! contact, and a scene file with that object.
//!
//! # The method
//!
//! After the mallet has left, a struck object rings freely: its sound is a
//! sum of damped sinusoids `A_k exp(-alpha_k t) cos(2 pi f_k t + phi_k)`,
//! one per mode (what the engine's modal object plays, docs/design.md,
//! "Conventions and units"). Fitting that model directly gives what a
//! spectrum's peaks cannot: two modes closer than the analysis window's
//! resolution are still two poles, and each pole's radius is its damping,
//! with no decay curve to fit. The fit is ESPRIT (Roy and Kailath 1989):
//! the samples' Hankel matrix has the rank of the number of poles; its
//! leading left singular vectors span the signal subspace, and that
//! subspace shifted by one sample is itself times a matrix whose
//! eigenvalues are the poles.
//!
//! A recording holds tens to hundreds of modes over 20 kHz, and the SVD's
//! cost grows with the cube of the model order; so the range is cut into
//! sub-bands (`band.rs`): each is shifted to baseband, low-pass filtered
//! and decimated (by `D`, to a rate of twice the band's width), and fitted
//! alone. Filtering and decimation keep damped exponentials damped
//! exponentials with the same poles (raised to the power `D`), so the fit
//! is still exact; each band keeps only the poles inside its valid centre
//! (the middle half of the decimated band: what aliases there comes from
//! the filter's stop band, 120 dB down), and the bands tile the range.
//! Decimation also lengthens the time a Hankel matrix of a given size
//! spans: at 500 Hz decimated rate, 1024 samples are 2 s, which is what
//! resolves modes 1 Hz apart and measures a T60 of 20 s.
//!
//! The price of narrow bands is a long filter: its half length (16 ms for
//! 250 Hz bands) passes before the first decimated sample, and a mode of
//! T60 50 ms has lost 20 dB by then. So a second, fast pass fits bands
//! four times wider (filters four times shorter, 0.5 s spans): a mode it
//! finds with a T60 under ten of the fine filter's half lengths replaces
//! the fine pass's estimate of it when its uncertainty is lower, and joins
//! the modes when the fine pass has none there. Slow modes and close pairs
//! come from the fine pass.
//!
//! The model order of a band (`esprit.rs`) is the number of singular values
//! above the largest a noise-only matrix would have (the Marchenko-Pastur
//! edge `sigma (sqrt(N) + sqrt(L))` for an `L x N` matrix of noise of
//! standard deviation `sigma`, times 1.5), with `sigma` from the median of
//! the singular values (the signal's are few, so the median is noise's).
//! Each band is fitted at that order and at a higher one (a quarter more,
//! at least 2 more); a pole without a partner at the higher order (within
//! 16 % of the frequency resolution, or 10 of its standard deviations when
//! that is more) is unstable. A lone unstable pole is a fit of the noise
//! and is dropped. Unstable poles that come in runs, each within 30
//! resolutions of the next, are a *cluster*: a real partial whose envelope
//! is not one exponential (a beat, a room, a sample's processing), which
//! the fit spreads over neighbouring poles with partly cancelling
//! amplitudes, so that no one of them is the partial and dropping them
//! all would drop it. A cluster is replaced by one pole: the least-squares
//! one-step predictor of its members' summed component (its frequency and
//! decay weighted by its energy); the members are listed as merged. The
//! poles kept are dropped when they grow (no passive object does), lie
//! outside the band's centre (the neighbouring band has them), lie outside
//! the frequency range asked for, carry less energy than 20 dB over the
//! noise (matched-filter signal-to-noise ratio: the component's energy
//! over the band's noise variance per sample), decay too slowly for the
//! recording to measure (T60 beyond 30 times the span analysed, or its
//! uncertainty over 50 %), or so fast that their level at the onset would
//! be extrapolated by more than 20 dB over what the band cannot see (the
//! settling time and the band filter's run-in): such a pole's amplitude
//! at the onset is a guess, and on real recordings it came out 40 to 140
//! dB above the recording's peak. Every dropped pole is listed with its
//! reason. A mode found by two neighbouring bands (at their common edge)
//! is kept once, from the band whose centre is nearer.
//!
//! Amplitudes: each band's complex amplitudes come from least squares on
//! its samples with the poles it keeps (a Vandermonde system; a dropped
//! pole's share goes to its neighbours instead of leaving a partner that
//! cancelled it alone); the filter scales a
//! component by its transfer function at the pole, `H(w) = sum h[m] w^-m`,
//! which is known exactly, so the amplitude in the recording is recovered
//! exactly, referred to the onset (time 0 of the model, the first sample
//! at a tenth of the peak). Uncertainties are the Cramer-Rao bounds of a
//! single damped exponential in white noise of the band's variance (close
//! modes raise them; they are a floor, not a guarantee).
//!
//! The span analysed starts `settle_s` (5 ms) after the onset, past the
//! contact of any mallet but the softest (a contact lasts about
//! `pi sqrt(m / k)`: 1 ms for 30 g on 3e5 N/m), and after the last clipped
//! sample of a clipped attack.
//!
//! The analysis's own floor is 100 dB under the recording's peak: the band
//! filter passes a strong mode's alias into every band 120 dB down, and
//! ESPRIT would fit it; a band's noise variance is taken as at least that
//! floor's.
//!
//! Limits (tests/recording.rs measures them): a mode's frequency error is
//! bounded below by its Cramer-Rao bound, which grows with its damping, so
//! a mode of T60 50 ms at 1 kHz needs a per-sample signal-to-noise ratio
//! near 60 dB for a relative error of 1e-5; crowded fast-decaying modes
//! (bandwidths overlapping) come out with errors of 1e-4 and several
//! percent, or are missed; and a recording that is not a sum of damped
//! sinusoids after the strike (a pitch glide, a rattle, a room's
//! reverberation) splits its partials into clusters of unstable poles,
//! each then one mode of the cluster's energy and mean decay.
//!
//! Files: `input.rs` (checks, onset, clipping, span, noise), `band.rs` (the
//! band split), `esprit.rs` (one band's fit), `select.rs` (which poles are
//! kept and the merge), `wav.rs` (reading WAV files), `scene.rs` (the
//! scene file).

mod band;
pub mod distance;
mod error;
mod esprit;
mod input;
mod refine;
mod scene;
mod select;
#[cfg(test)]
mod tests;
mod wav;

pub use error::RecordingError;
pub use scene::{
    fit_distance, object_scene, render_from_onset, MalletEstimate, DEFAULT_MALLET_KG, FIT_S,
};
pub use wav::{read_wav, Channel, Recording};

use std::f64::consts::PI;

/// The sample rates the analysis takes \[Hz\].
pub const RATE_RANGE_HZ: (f64, f64) = (8_000.0, 384_000.0);

/// A mode's amplitude at the onset is extrapolated back from its band's
/// first sample, past the settling time and the band filter's half
/// length; a mode that would lose more than this many dB over that lag is
/// dropped (its onset amplitude is not measured; the fast pass's shorter
/// filter sees it when it is there to see) \[dB\].
pub const MAX_EXTRAPOLATION_DB: f64 = 20.0;

/// The shortest recording the analysis takes \[s\].
pub const MIN_SECONDS: f64 = 0.05;

/// The shortest free decay (after onset, clipping and time range) the
/// analysis fits \[s\].
pub const MIN_DECAY_S: f64 = 0.02;

/// The fast pass's bands are this many times wider than the fine pass's
/// (`band_hz`): its filters are as many times shorter, so it sees more of
/// a mode that decays within tens of milliseconds.
const FAST_BAND_FACTOR: f64 = 4.0;

/// `ln(1000)`: amplitude decay rate `alpha` to T60, `T60 = ln(1000) / alpha`.
const LN_1000: f64 = 6.907_755_278_982_137;

/// What to analyse and how.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalysisOptions {
    /// The frequency range of the modes \[Hz\] (capped at Nyquist).
    pub freq_range_hz: (f64, f64),
    /// Start of the span analysed, from the recording's start \[s\]; `None`:
    /// `settle_s` after the onset and after any clipping.
    pub start_s: Option<f64>,
    /// End of the span analysed \[s\]; `None`: the recording's end.
    pub end_s: Option<f64>,
    /// Time from the onset to the start of the span analysed \[s\].
    pub settle_s: f64,
    /// Keep at most this many modes (the strongest).
    pub max_modes: Option<usize>,
    /// Width of a band's valid centre \[Hz\] (widened for short recordings
    /// so a band has at least 64 decimated samples).
    pub band_hz: f64,
    /// Most decimated samples fitted per band.
    pub window: usize,
    /// A pole's least matched-filter signal-to-noise ratio \[dB\].
    pub min_snr_db: f64,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self {
            freq_range_hz: (20.0, 20_000.0),
            start_s: None,
            end_s: None,
            settle_s: 0.005,
            max_modes: None,
            band_hz: 250.0,
            window: 1024,
            min_snr_db: 20.0,
        }
    }
}

/// One mode found: `amplitude exp(-alpha t) cos(2 pi freq_hz t + phase_rad)`
/// with `alpha = ln(1000) / t60_s` and `t` from the onset.
#[derive(Debug, Clone, PartialEq)]
pub struct Mode {
    /// The damped (observed) frequency \[Hz\].
    pub freq_hz: f64,
    /// The time to decay by 60 dB \[s\].
    pub t60_s: f64,
    /// Peak amplitude at the onset, in the recording's units (full scale 1
    /// for a WAV file).
    pub amplitude: f64,
    /// Phase at the onset \[rad\].
    pub phase_rad: f64,
    /// Matched-filter signal-to-noise ratio in its band \[dB\].
    pub snr_db: f64,
    /// Standard deviation of `freq_hz` (Cramer-Rao, one mode) \[Hz\].
    pub freq_sd_hz: f64,
    /// Relative standard deviation of `t60_s` (Cramer-Rao, one mode).
    pub t60_rel_sd: f64,
}

impl Mode {
    /// Amplitude decay rate `ln(1000) / T60` \[1/s\].
    pub fn alpha(&self) -> f64 {
        LN_1000 / self.t60_s
    }

    /// The undamped natural frequency `sqrt(f_d^2 + (alpha / 2 pi)^2)`
    /// \[Hz\]: a scene's `freq_hz` (the engine's mode `x'' + 2 alpha x' +
    /// (2 pi f)^2 x` rings at the damped frequency).
    pub fn natural_freq_hz(&self) -> f64 {
        self.freq_hz.hypot(self.alpha() / (2.0 * PI))
    }

    /// Level of the amplitude \[dB re full scale\].
    pub fn level_db(&self) -> f64 {
        20.0 * self.amplitude.max(1e-300).log10()
    }
}

/// Why a pole was dropped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DropReason {
    /// It grows (`T60 <= 0`): no passive object does.
    Growing,
    /// Outside its band's valid centre: the neighbouring band fits it.
    OutsideBandCentre,
    /// Outside the frequency range asked for.
    OutsideRange,
    /// No partner in the fit at the higher model order: a fit of noise.
    Unstable,
    /// One of a cluster of unstable poles, replaced by the cluster's one
    /// pole.
    Merged,
    /// Its matched-filter signal-to-noise ratio \[dB\] is under the least.
    BelowNoise(f64),
    /// It decays too slowly for the span analysed to measure its T60.
    BeyondReach,
    /// It decays so fast that its amplitude at the onset would be
    /// extrapolated by this many dB from the band's first sample
    /// (more than [`MAX_EXTRAPOLATION_DB`]).
    TooFast(f64),
    /// The same mode from the neighbouring band, kept from there.
    Duplicate,
    /// More modes than the most asked for; the weakest go.
    OverLimit,
}

impl std::fmt::Display for DropReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Growing => write!(f, "growing"),
            Self::OutsideBandCentre => write!(f, "outside its band's centre"),
            Self::OutsideRange => write!(f, "outside the frequency range"),
            Self::Unstable => write!(f, "unstable across model orders"),
            Self::Merged => write!(f, "merged into its cluster's mode"),
            Self::BelowNoise(snr) => write!(f, "below the noise (SNR {snr:.1} dB)"),
            Self::BeyondReach => write!(f, "T60 beyond the recording's reach"),
            Self::TooFast(db) => write!(
                f,
                "decays before its band's first sample (onset level extrapolated by {db:.0} dB)"
            ),
            Self::Duplicate => write!(f, "duplicate of the neighbouring band's"),
            Self::OverLimit => write!(f, "over the mode limit"),
        }
    }
}

/// A pole the analysis dropped.
#[derive(Debug, Clone, PartialEq)]
pub struct DroppedPole {
    /// Its frequency \[Hz\].
    pub freq_hz: f64,
    /// Its T60 \[s\] (negative when it grows).
    pub t60_s: f64,
    /// Its level at the onset \[dB re full scale\].
    pub level_db: f64,
    /// Why.
    pub reason: DropReason,
}

/// Flat tops of a clipped recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Clipping {
    /// Number of runs of at least 3 samples at full scale.
    pub runs: usize,
    /// Samples in those runs.
    pub samples: usize,
    /// One past the last clipped sample (the fit starts after it).
    pub end: usize,
    /// The level clipped at (the recording's peak magnitude).
    pub level: f64,
}

/// What the analysis found.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// The modes kept, by frequency.
    pub modes: Vec<Mode>,
    /// The poles dropped, with their reasons.
    pub dropped: Vec<DroppedPole>,
    /// The onset (time 0 of the modes) \[samples\].
    pub onset: usize,
    /// The span analysed \[samples\], `start..end`.
    pub span: (usize, usize),
    /// The flat tops of a clipped attack, if any.
    pub clipping: Option<Clipping>,
    /// The recording's peak magnitude.
    pub peak: f64,
    /// The noise's RMS before the onset (or in the recording's last tenth)
    /// \[dB re the peak\].
    pub noise_db: f64,
    /// Number of bands, their valid width \[Hz\] and decimation.
    pub bands: (usize, f64, usize),
}

impl Analysis {
    /// The modes' sound over `len` samples of the recording's timeline:
    /// zero before the onset, the sum of the modes after.
    pub fn resynthesize(&self, len: usize) -> Vec<f64> {
        let mut out = vec![0.0; len];
        for m in &self.modes {
            let dt = 1.0 / self.rate_hz;
            let step = faer::c64::new(-m.alpha() * dt, 2.0 * PI * m.freq_hz * dt).exp();
            let mut z = faer::c64::new(m.phase_rad.cos(), m.phase_rad.sin()) * m.amplitude;
            for v in out.iter_mut().skip(self.onset) {
                *v += z.re;
                z *= step;
                if z.norm() < 1e-30 {
                    break;
                }
            }
        }
        out
    }

    /// The energy of `recording - resynthesis` over the span analysed,
    /// relative to the recording's energy there \[dB\].
    pub fn residual_db(&self, recording: &[f64]) -> f64 {
        let (start, end) = (self.span.0, self.span.1.min(recording.len()));
        let model = self.resynthesize(end);
        let (mut e, mut r) = (0.0, 0.0);
        for i in start..end {
            e += recording[i] * recording[i];
            r += (recording[i] - model[i]).powi(2);
        }
        10.0 * (r.max(1e-300) / e.max(1e-300)).log10()
    }
}

/// Estimate the modes of the struck object in the mono `recording` at
/// `rate_hz` (the module's documentation has the method). Refuses bad
/// input with a [`RecordingError`]; never panics.
pub fn analyze(
    recording: &[f64],
    rate_hz: f64,
    opts: &AnalysisOptions,
) -> Result<Analysis, RecordingError> {
    check_options(opts, rate_hz)?;
    let at = input::locate(recording, rate_hz, opts)?;
    let span_s = (at.end - at.start) as f64 / rate_hz;
    let lo = opts.freq_range_hz.0.max(0.0);
    let hi = opts.freq_range_hz.1.min(0.5 * rate_hz);
    // At least 64 decimated samples past the filter (16 D samples) per band.
    let band_hz = opts.band_hz.max(40.0 / span_s);
    let plan = band::Plan::new(lo, hi, rate_hz, band_hz);
    let scaled: Vec<f64> = recording.iter().map(|v| v / at.peak).collect();
    let mut found = select::fit_bands(&scaled, rate_hz, &at, (&plan, 0), opts)?;
    let wide = band::Plan::new(lo, hi, rate_hz, FAST_BAND_FACTOR * band_hz);
    if wide.decim < plan.decim {
        let fast = select::fit_bands(&scaled, rate_hz, &at, (&wide, 1), opts)?;
        // The fine filter's half length: a mode whose T60 is under ten of
        // them has lost more than 6 dB before the fine pass's first sample.
        let t60_max = 10.0 * band::half_length_s(plan.decim, rate_hz);
        found = select::combine(found, fast, t60_max);
    }
    let (modes, dropped) = select::merge(found, opts.max_modes);
    if modes.is_empty() {
        return Err(RecordingError::NoModes(select::summary(&dropped)));
    }
    Ok(Analysis {
        rate_hz,
        modes,
        dropped,
        onset: at.onset,
        span: (at.start, at.end),
        clipping: at.clipping,
        peak: at.peak,
        noise_db: 20.0 * (at.noise_rms / at.peak).max(1e-15).log10(),
        bands: (plan.centres.len(), plan.width_hz, plan.decim),
    })
}

/// Refuse options no analysis can honour.
fn check_options(opts: &AnalysisOptions, rate_hz: f64) -> Result<(), RecordingError> {
    let (lo, hi) = opts.freq_range_hz;
    if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo < hi) {
        return Err(RecordingError::Option(format!(
            "frequency range {lo}..{hi} Hz: need 0 <= low < high"
        )));
    }
    if rate_hz.is_finite() && lo >= 0.5 * rate_hz {
        return Err(RecordingError::Option(format!(
            "frequency range starts at {lo} Hz, at or above Nyquist ({} Hz)",
            0.5 * rate_hz
        )));
    }
    for (name, v) in [("start", opts.start_s), ("end", opts.end_s)] {
        if v.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
            return Err(RecordingError::Option(format!(
                "{name} time {v:?} s: need a finite time >= 0"
            )));
        }
    }
    if let (Some(s), Some(e)) = (opts.start_s, opts.end_s) {
        if !(s < e) {
            return Err(RecordingError::Option(format!(
                "time range {s}..{e} s is empty"
            )));
        }
    }
    let ok = opts.settle_s.is_finite()
        && opts.settle_s >= 0.0
        && opts.band_hz.is_finite()
        && opts.band_hz > 0.0
        && opts.window >= 64
        && opts.min_snr_db.is_finite()
        && opts.max_modes != Some(0);
    if !ok {
        return Err(RecordingError::Option(format!(
            "settle {} s (>= 0), band {} Hz (> 0), window {} (>= 64), least SNR {} dB (finite), \
             most modes {:?} (>= 1)",
            opts.settle_s, opts.band_hz, opts.window, opts.min_snr_db, opts.max_modes
        )));
    }
    Ok(())
}
