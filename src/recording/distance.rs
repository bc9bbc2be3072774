//! The 1/3-octave distance between two sounds: the measure `cargo xtask
//! analyze` reports for a recording's resynthesis and render, the one the
//! mallet's contact time is fitted by ([`super::object_scene`]) and the one
//! `cargo xtask compare-real` puts presets against real recordings with.
//! Band energies of the first half second (Welch's summed power spectra),
//! 26 bands from 50 Hz to 16 kHz, each over the total and floored 60 dB
//! under the loudest; the distance is the RMS of two sets' differences.
//! Fourier transforms by the `realfft` crate.

use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// A one-sided power spectrum: bin `k` is frequency `k * df`.
#[derive(Debug, Clone)]
pub struct Spectrum {
    /// Bin spacing \[Hz\].
    pub df: f64,
    /// Power per bin (arbitrary scale).
    pub power: Vec<f64>,
}

impl Spectrum {
    /// Frequency of bin `k` \[Hz\].
    pub fn freq(&self, k: usize) -> f64 {
        k as f64 * self.df
    }

    /// Power between `lo` and `hi` \[Hz\], each bin taken as covering
    /// `[f - df/2, f + df/2)` and counted by the fraction of it inside.
    pub fn band_power(&self, lo: f64, hi: f64) -> f64 {
        let k0 = ((lo / self.df) - 0.5).floor().max(0.0) as usize;
        let k1 = (((hi / self.df) + 0.5).ceil() as usize).min(self.power.len());
        (k0..k1)
            .map(|k| {
                let (a, b) = ((k as f64 - 0.5) * self.df, (k as f64 + 0.5) * self.df);
                let overlap = (b.min(hi) - a.max(lo)).max(0.0) / self.df;
                overlap * self.power[k]
            })
            .sum()
    }
}

/// The symmetric Hann window of `n` points.
pub fn hann(n: usize) -> Vec<f64> {
    if n < 2 {
        return vec![1.0; n];
    }
    (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / (n - 1) as f64).cos())
        .collect()
}

/// `|FFT|^2` of `x * window` zero-padded to `nfft` (`nfft / 2 + 1` bins).
pub fn power_spectrum(
    planner: &mut RealFftPlanner<f64>,
    x: &[f64],
    window: &[f64],
    nfft: usize,
) -> Vec<f64> {
    let fft = planner.plan_fft_forward(nfft);
    let mut buf = fft.make_input_vec();
    for ((b, s), w) in buf.iter_mut().zip(x).zip(window) {
        *b = s * w;
    }
    let mut out = fft.make_output_vec();
    fft.process(&mut buf, &mut out)
        .expect("sizes from the plan");
    out.iter().map(|c| c.norm_sqr()).collect()
}

/// The number of 1/3-octave bands, 50 Hz to 16 kHz.
pub const BANDS: usize = 26;

/// Centre frequency of 1/3-octave band `b` (0 = 50 Hz, 25 = 16 kHz): the
/// exact base-10 centres of IEC 61260-1, 1000 Hz x 10^(n/10), n = -13..=12
/// (nominally 50, 63, 80, ..., 12500, 16000 Hz); the band edges are the
/// centre x 10^(+-1/20).
pub fn band_centre(b: usize) -> f64 {
    1000.0 * 10f64.powf((b as f64 - 13.0) / 10.0)
}

/// The nominal (printed) centre of band `b`.
pub const BAND_NOMINAL: [&str; BANDS] = [
    "50", "63", "80", "100", "125", "160", "200", "250", "315", "400", "500", "630", "800", "1k",
    "1.25k", "1.6k", "2k", "2.5k", "3.15k", "4k", "5k", "6.3k", "8k", "10k", "12.5k", "16k",
];

/// The frames of [`welch`]: 8192-point Hann, hop 2048.
pub const WELCH_LEN: usize = 8192;

/// The energy spectrum of the first `seconds` of `x`: a 10 ms
/// raised-cosine fade-out at the end of the stretch, then the summed
/// power of 8192-point Hann frames at hop 2048 (a quarter frame: the
/// squared windows add up to a constant, so every sample of the stretch
/// weighs the same) over the stretch with zeros around it (Welch's
/// method without the averaging's normalisation).
pub fn welch(x: &[f64], rate_hz: f64, seconds: f64) -> Spectrum {
    let n = ((seconds * rate_hz).round() as usize).min(x.len());
    let fout = ((0.01 * rate_hz) as usize).min(n);
    let hop = WELCH_LEN / 4;
    let mut padded = vec![0.0; WELCH_LEN + n + WELCH_LEN];
    for i in 0..n {
        let j = n - 1 - i;
        let g = if j < fout {
            0.5 - 0.5 * (PI * j as f64 / fout as f64).cos()
        } else {
            1.0
        };
        padded[WELCH_LEN + i] = x[i] * g;
    }
    let w = hann(WELCH_LEN);
    let mut planner = RealFftPlanner::new();
    let mut power = vec![0.0; WELCH_LEN / 2 + 1];
    let mut s = hop;
    while s + WELCH_LEN <= padded.len() {
        let p = power_spectrum(&mut planner, &padded[s..s + WELCH_LEN], &w, WELCH_LEN);
        for (a, b) in power.iter_mut().zip(p) {
            *a += b;
        }
        s += hop;
    }
    Spectrum {
        df: rate_hz / WELCH_LEN as f64,
        power,
    }
}

/// How far below the loudest band a band level is floored \[dB\].
pub const BAND_FLOOR_DB: f64 = 60.0;

/// 1/3-octave band levels of an energy spectrum ([`welch`]), 50 Hz to
/// 16 kHz ([`band_centre`]): each band's energy over the total of the 26
/// bands, in dB (so the levels of any signal add up to 0 dB in power,
/// whatever its loudness), floored at [`BAND_FLOOR_DB`] below the loudest
/// band (so bands empty in one signal and nearly empty in the other count
/// as equal, not as hundreds of dB apart).
pub fn band_levels(spec: &Spectrum) -> [f64; BANDS] {
    let edge = 10f64.powf(0.05);
    let e: Vec<f64> = (0..BANDS)
        .map(|b| spec.band_power(band_centre(b) / edge, band_centre(b) * edge))
        .collect();
    let total: f64 = e.iter().sum::<f64>().max(1e-300);
    let db: Vec<f64> = e
        .iter()
        .map(|v| 10.0 * (v / total + 1e-300).log10())
        .collect();
    let top = db.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut out = [0.0; BANDS];
    for (o, v) in out.iter_mut().zip(db) {
        *o = v.max(top - BAND_FLOOR_DB);
    }
    out
}

/// The 1/3-octave distance between two sounds \[dB\]: the root mean
/// square, over the 26 bands from 50 Hz to 16 kHz, of the difference of
/// their band levels ([`band_levels`]: each normalised to its own total
/// energy, floored 60 dB below its loudest band). 0 for spectra of the
/// same shape; a sound whose every band is off by d dB from the other's
/// (after normalisation) is d dB away. It measures spectral balance
/// (timbre) over the stretch analysed, not loudness, pitch detail within
/// a band, or time structure.
pub fn third_octave_distance(a: &[f64; BANDS], b: &[f64; BANDS]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / BANDS as f64).sqrt()
}
