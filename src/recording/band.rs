//! The band split: the analysed range cut into sub-bands of equal width,
//! each shifted to baseband (multiplied by `exp(-i 2 pi f_c t)`), low-pass
//! filtered by a linear-phase FIR and decimated.
//!
//! A filter keeps a damped exponential a damped exponential: the FIR `h`
//! applied to `a w^n` gives `a H(w) w^n` with `H(w) = sum_m h[m] w^-m`, the
//! filter's transfer function at the pole itself (not on the unit circle),
//! once the filter has only free-decay samples under it. So the decimated
//! band signal is again an exact sum of damped exponentials, with poles
//! `w^D` and amplitudes `a H(w) w^(n1 - n_ref)`, and the amplitudes are
//! recovered exactly from the band's fit.
//!
//! With decimation `D` the decimated rate is `fs / D`; the band kept (the
//! valid centre) is its middle half, `|f - f_c| < fs / (4 D)`, and the
//! bands tile the range with that width. The filter is a Kaiser-windowed
//! sinc with its cut-off at `fs / (2 D)`, its transition from `fs / (4 D)`
//! to `3 fs / (4 D)` and 120 dB in its stop band: what aliases into a
//! band's valid centre comes from the stop band, 120 dB down; what lies in
//! the transition shows as poles outside the centre, which the band drops
//! (its neighbour keeps them).

use faer::c64;
use std::f64::consts::PI;

/// The filter's half length in decimated samples: `P = 8 D` taps each
/// side, the Kaiser estimate `(A - 7.95) / (2.285 dw)` for A = 120 dB and
/// a transition `dw = pi / D`, rounded up.
const HALF_TAPS_PER_DECIMATION: usize = 8;

/// Kaiser's beta for 120 dB of stop band: `0.1102 (A - 8.7)`.
const KAISER_BETA: f64 = 12.27;

/// The low-pass FIR of one decimation, symmetric: `h[m]` for `m` in
/// `-P..=P`, stored at `m + P`.
#[derive(Debug, Clone)]
pub(crate) struct Lowpass {
    taps: Vec<f64>,
    half: usize,
    decim: usize,
}

/// The zeroth-order modified Bessel function of the first kind (its
/// series; converges for the window's arguments, at most `KAISER_BETA`).
fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term, q) = (1.0, 1.0, 0.25 * x * x);
    for k in 1..200 {
        term *= q / (k * k) as f64;
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    sum
}

impl Lowpass {
    /// The filter for decimation `decim` (at least 1), unity gain at 0 Hz.
    pub(crate) fn new(decim: usize) -> Self {
        let decim = decim.max(1);
        let half = HALF_TAPS_PER_DECIMATION * decim;
        let cut = 0.5 / decim as f64; // cycles per sample
        let norm = bessel_i0(KAISER_BETA);
        let mut taps: Vec<f64> = (0..=2 * half)
            .map(|i| {
                let m = i as f64 - half as f64;
                let r = m / half as f64;
                let window = bessel_i0(KAISER_BETA * (1.0 - r * r).max(0.0).sqrt()) / norm;
                let sinc = if m == 0.0 {
                    2.0 * cut
                } else {
                    (2.0 * PI * cut * m).sin() / (PI * m)
                };
                sinc * window
            })
            .collect();
        let sum: f64 = taps.iter().sum();
        for t in &mut taps {
            *t /= sum;
        }
        Self { taps, half, decim }
    }

    /// The half length `P` \[samples\].
    pub(crate) fn half(&self) -> usize {
        self.half
    }

    /// `H(w) = sum_m h[m] w^-m` at a pole `w` of the full-rate baseband
    /// signal, given as its logarithm `ln w` (so no power overflows).
    pub(crate) fn response(&self, ln_w: c64) -> c64 {
        self.taps
            .iter()
            .enumerate()
            .map(|(i, h)| {
                let m = i as f64 - self.half as f64;
                (ln_w * (-m)).exp() * *h
            })
            .sum()
    }
}

/// The filter's half length for decimation `decim` at `rate_hz` \[s\]: the
/// time from the start of the span analysed to the first decimated sample.
pub(crate) fn half_length_s(decim: usize, rate_hz: f64) -> f64 {
    (HALF_TAPS_PER_DECIMATION * decim.max(1)) as f64 / rate_hz
}

/// The bands: decimation, valid width and centres.
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    /// Decimation `D`.
    pub decim: usize,
    /// Width of each band's valid centre \[Hz\]: `fs / (2 D)`.
    pub width_hz: f64,
    /// The bands' centre frequencies \[Hz\], ascending.
    pub centres: Vec<f64>,
}

impl Plan {
    /// Bands of about `band_hz` valid width covering `lo..hi` \[Hz\]: the
    /// centres are `(i + 1/2) fs / (2 D)`, so the bands tile `0..fs/2`
    /// exactly and the lowest and highest (whose images from negative
    /// frequencies and from above Nyquist fall outside their valid centre)
    /// need no special case.
    pub(crate) fn new(lo: f64, hi: f64, rate_hz: f64, band_hz: f64) -> Self {
        let decim = ((rate_hz / (2.0 * band_hz)).round() as usize).max(1);
        let width_hz = rate_hz / (2.0 * decim as f64);
        let first = (lo / width_hz).floor().max(0.0) as usize;
        let last = ((hi / width_hz).ceil() as usize).min(decim);
        let centres = (first..last).map(|i| (i as f64 + 0.5) * width_hz).collect();
        Self {
            decim,
            width_hz,
            centres,
        }
    }
}

/// One band's decimated baseband signal.
#[derive(Debug, Clone)]
pub(crate) struct BandSignal {
    /// The decimated samples.
    pub y: Vec<c64>,
    /// The full-rate index of `y[0]`.
    pub first: usize,
}

/// Shift `x[start..end]` by `-centre_hz` (phase zero at sample `reference`),
/// filter and keep every `D`-th sample where the whole filter lies on the
/// span, at most `max_len` of them.
pub(crate) fn band_signal(
    x: &[f64],
    lp: &Lowpass,
    centre_hz: f64,
    rate_hz: f64,
    reference: usize,
    span: (usize, usize),
    max_len: usize,
) -> BandSignal {
    let (start, end) = (span.0, span.1.min(x.len()));
    let (p, d) = (lp.half, lp.decim);
    let first = start + p;
    let count = if end > first + p {
        ((end - 1 - p - first) / d + 1).min(max_len)
    } else {
        0
    };
    if count == 0 {
        return BandSignal {
            y: Vec::new(),
            first,
        };
    }
    let stop = first + (count - 1) * d + p + 1;
    let cycles = centre_hz / rate_hz;
    let u: Vec<c64> = (start..stop)
        .map(|k| {
            let t = k as f64 - reference as f64;
            let phase = -2.0 * PI * (cycles * t).rem_euclid(1.0);
            c64::new(phase.cos(), phase.sin()) * x[k]
        })
        .collect();
    let y = (0..count)
        .map(|j| {
            // u index of n - m for m = -P..=P is (first + j d - start) - m
            let centre = first + j * d - start;
            let window = &u[centre - p..=centre + p];
            // h is symmetric, so h[m] u[n - m] summed over m is h[i] * window[i]
            lp.taps
                .iter()
                .zip(window.iter())
                .map(|(h, v)| *v * *h)
                .sum()
        })
        .collect();
    BandSignal { y, first }
}
