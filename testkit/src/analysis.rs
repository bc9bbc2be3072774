//! The measurements of `cargo xtask compare-real` (and of the recording
//! analysis's checks), on mono signals at one
//! sample rate: onset, long-window spectrum and its peaks (partials),
//! per-partial decay time (T60), the attack's spectral centroid and its
//! energy above 5 kHz, 1/3-octave band levels and the distance between two
//! sets of them (the core's, `modal_contact::recording::distance`, which
//! the recording analysis fits its mallet by; re-exported here), and the
//! band-limited resampling that plays a recording at another pitch and
//! rate. Fourier transforms by the `realfft` crate.

pub use modal_contact::recording::distance::{
    band_centre, band_levels, hann, power_spectrum, third_octave_distance, welch, Spectrum, BANDS,
    BAND_FLOOR_DB, BAND_NOMINAL, WELCH_LEN,
};
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// The onset of a struck sound: the first sample whose magnitude reaches
/// 1 % (-40 dB) of the signal's peak, moved 1 ms earlier (not before 0),
/// so that the strike's first rise is kept.
pub fn onset(x: &[f64], rate_hz: f64) -> usize {
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let first = x.iter().position(|v| v.abs() >= 0.01 * peak).unwrap_or(0);
    first.saturating_sub((0.001 * rate_hz).round() as usize)
}

/// The long-window spectrum for partials: the first `seconds` of `x`
/// (or all of it), Hann window, zero-padded to 4 times the next power of
/// two for finer peak positions.
pub fn long_spectrum(x: &[f64], rate_hz: f64, seconds: f64) -> (Spectrum, usize) {
    let n = ((seconds * rate_hz).round() as usize).min(x.len()).max(16);
    let nfft = 4 * n.next_power_of_two();
    let mut planner = RealFftPlanner::new();
    let mut seg = x[..n.min(x.len())].to_vec();
    seg.resize(n, 0.0);
    let power = power_spectrum(&mut planner, &seg, &hann(n), nfft);
    (
        Spectrum {
            df: rate_hz / nfft as f64,
            power,
        },
        n,
    )
}

/// A spectral peak.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Frequency \[Hz\], by parabolic interpolation of the dB spectrum
    /// over the peak bin and its neighbours (J. O. Smith, "Spectral Audio
    /// Signal Processing", quadratic interpolation of spectral peaks).
    pub freq_hz: f64,
    /// Level \[dB\] relative to the strongest peak found.
    pub level_db: f64,
}

/// The peaks of a long-window spectrum ([`long_spectrum`] of a window of
/// `window_len` samples) between `f_lo` and `f_hi`, strongest first: the
/// local maxima of the dB spectrum that are also the largest value within
/// +-3 % (about a quarter tone each way) and within +-2 bins of the
/// unpadded window (the Hann main lobe), no more than `range_db` below the
/// strongest. Each is refined by parabolic interpolation.
pub fn peaks(spec: &Spectrum, window_len: usize, f_lo: f64, f_hi: f64, range_db: f64) -> Vec<Peak> {
    let db: Vec<f64> = spec
        .power
        .iter()
        .map(|p| 10.0 * (p + 1e-300).log10())
        .collect();
    let pad = (spec.power.len().saturating_sub(1) * 2) as f64 / window_len as f64;
    let lobe = (2.0 * pad).ceil() as usize;
    let mut found = Vec::new();
    for k in 1..db.len().saturating_sub(1) {
        let f = spec.freq(k);
        if f < f_lo || f > f_hi || !(db[k] > db[k - 1] && db[k] >= db[k + 1]) {
            continue;
        }
        let half = ((0.03 * f / spec.df).ceil() as usize).max(lobe);
        let (a, b) = (k.saturating_sub(half), (k + half).min(db.len() - 1));
        if db[a..=b].iter().any(|&v| v > db[k]) {
            continue;
        }
        let (l, c, r) = (db[k - 1], db[k], db[k + 1]);
        let den = l - 2.0 * c + r;
        let d = if den.abs() > 1e-12 {
            0.5 * (l - r) / den
        } else {
            0.0
        };
        found.push(Peak {
            freq_hz: (k as f64 + d) * spec.df,
            level_db: c - 0.25 * (l - r) * d,
        });
    }
    let top = found
        .iter()
        .map(|p| p.level_db)
        .fold(f64::NEG_INFINITY, f64::max);
    let mut kept: Vec<Peak> = found
        .into_iter()
        .filter(|p| p.level_db >= top - range_db)
        .map(|p| Peak {
            level_db: p.level_db - top,
            ..p
        })
        .collect();
    kept.sort_by(|a, b| b.level_db.total_cmp(&a.level_db));
    kept
}

/// The interval from `a` to `b` in cents.
pub fn cents(a: f64, b: f64) -> f64 {
    1200.0 * (b / a).log2()
}

/// The STFT of the decay fits: 4096-point Hann frames, hop 512.
pub const STFT_LEN: usize = 4096;
/// See [`STFT_LEN`].
pub const STFT_HOP: usize = 512;

/// A partial's level track: one value per STFT frame.
#[derive(Debug, Clone)]
pub struct Track {
    /// Frame centre times \[s\] from the signal's start.
    pub t: Vec<f64>,
    /// Level \[dB\], arbitrary reference.
    pub db: Vec<f64>,
    /// Where the last frame ends \[s\] (about the signal's length).
    pub end_s: f64,
}

/// The STFT power frames of `x` ([`STFT_LEN`], [`STFT_HOP`]): only frames
/// that lie inside the signal.
pub fn stft(x: &[f64]) -> Vec<Vec<f64>> {
    let mut planner = RealFftPlanner::new();
    let w = hann(STFT_LEN);
    let mut frames = Vec::new();
    let mut s = 0;
    while s + STFT_LEN <= x.len() {
        frames.push(power_spectrum(
            &mut planner,
            &x[s..s + STFT_LEN],
            &w,
            STFT_LEN,
        ));
        s += STFT_HOP;
    }
    frames
}

/// The level track of the partial at `freq_hz` in STFT frames: per frame
/// the largest power within +-2 bins (the Hann main lobe) of its bin.
pub fn track(frames: &[Vec<f64>], rate_hz: f64, freq_hz: f64) -> Track {
    let df = rate_hz / STFT_LEN as f64;
    let k = (freq_hz / df).round() as usize;
    let t = (0..frames.len())
        .map(|j| (j * STFT_HOP + STFT_LEN / 2) as f64 / rate_hz)
        .collect();
    let db = frames
        .iter()
        .map(|p| {
            let (a, b) = (k.saturating_sub(2), (k + 2).min(p.len() - 1));
            10.0 * (p[a..=b].iter().fold(0.0f64, |m, &v| m.max(v)) + 1e-300).log10()
        })
        .collect();
    let end_s = ((frames.len().max(1) - 1) * STFT_HOP + STFT_LEN) as f64 / rate_hz;
    Track { t, db, end_s }
}

/// A decay fit, or why there is none.
#[derive(Debug, Clone, PartialEq)]
pub enum T60 {
    /// A fit.
    Fit {
        /// Time for a 60 dB decay \[s\].
        t60_s: f64,
        /// The fitted line's drop over the stretch \[dB\].
        range_db: f64,
        /// The stretch \[s\].
        from_s: f64,
        /// See `from_s`.
        to_s: f64,
        /// The stretch runs to the signal's end (no noise floor reached).
        to_end: bool,
    },
    /// No fit, and why.
    NoFit(String),
}

impl T60 {
    /// The decay time when there is a fit.
    pub fn seconds(&self) -> Option<f64> {
        match self {
            Self::Fit { t60_s, .. } => Some(*t60_s),
            Self::NoFit(_) => None,
        }
    }
}

/// Least-squares slope of `y` against `x`.
fn slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    if sxx > 0.0 {
        sxy / sxx
    } else {
        0.0
    }
}

/// The minimum decay a fit needs \[dB\].
pub const MIN_FIT_DB: f64 = 15.0;
/// The longest stretch a fit takes \[dB below its start\]: a render has no
/// noise floor, and a line over hundreds of dB would weigh the late decay
/// far more than what is heard.
pub const MAX_FIT_DB: f64 = 60.0;

/// T60 of a level track (the line fit of ISO 3382-1 on one partial's
/// envelope): a least-squares line in dB over the stretch from the first
/// frame 3 dB below the track's peak down to the last frame before the
/// track falls to 10 dB above the noise floor or [`MAX_FIT_DB`] below the
/// stretch's start, whichever comes first; T60 = 60 dB / the line's slope. The floor is the median of the last 10 % of the frames (at
/// least 3) when the track has levelled off there (those frames fall at
/// less than a quarter of the rate of the frames between the peak and
/// them); otherwise the partial was still decaying when the signal ended
/// (a short sample) and the stretch runs to the end. The crossings are
/// decided on the track smoothed over 5 frames (beats), the line is
/// fitted to the raw track. No fit when the line drops less than
/// [`MIN_FIT_DB`].
pub fn fit_t60(tr: &Track) -> T60 {
    let n = tr.db.len();
    if n < 8 {
        return T60::NoFit(format!("only {n} analysis frames"));
    }
    let sm: Vec<f64> = (0..n)
        .map(|j| {
            let (a, b) = (j.saturating_sub(2), (j + 2).min(n - 1));
            tr.db[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
        })
        .collect();
    let p = (0..n).max_by(|&a, &b| sm[a].total_cmp(&sm[b])).unwrap_or(0);
    let tail = (n / 10).max(3);
    let tail_slope = slope(&tr.t[n - tail..], &sm[n - tail..]);
    let body_slope = if n - tail >= p + 3 {
        slope(&tr.t[p..n - tail], &sm[p..n - tail])
    } else {
        tail_slope
    };
    let levelled = !(body_slope < 0.0) || tail_slope > 0.25 * body_slope;
    let mut last: Vec<f64> = sm[n - tail..].to_vec();
    last.sort_by(f64::total_cmp);
    let floor = last[tail / 2];
    let end_s = tr.end_s;
    let short = |drop: f64| {
        format!(
            "only {:.0} dB of decay in the {end_s:.2} s signal",
            drop.max(0.0)
        )
    };
    let Some(start) = (p..n).find(|&j| sm[j] <= sm[p] - 3.0) else {
        return T60::NoFit(if levelled {
            format!(
                "only {:.0} dB above the noise floor",
                (sm[p] - floor).max(0.0)
            )
        } else {
            short(sm[p] - sm[n - 1])
        });
    };
    let limit = if levelled {
        floor + 10.0
    } else {
        f64::NEG_INFINITY
    }
    .max(sm[start] - MAX_FIT_DB);
    let end = match (start + 1..n).find(|&j| sm[j] <= limit) {
        Some(j) => j - 1,
        None => n - 1,
    };
    if end < start + 2 {
        return T60::NoFit(format!(
            "only {:.0} dB above the noise floor",
            (sm[p] - floor).max(0.0)
        ));
    }
    let s = slope(&tr.t[start..=end], &tr.db[start..=end]);
    let range = -s * (tr.t[end] - tr.t[start]);
    if !(s < 0.0) || range < MIN_FIT_DB {
        return T60::NoFit(if levelled {
            format!(
                "only {:.0} dB of decay above the noise floor",
                range.max(0.0)
            )
        } else {
            short(range)
        });
    }
    T60::Fit {
        t60_s: -60.0 / s,
        range_db: range,
        from_s: tr.t[start],
        to_s: tr.t[end],
        to_end: !levelled && end == n - 1 && sm[end] > sm[start] - MAX_FIT_DB,
    }
}

/// The attack's spectrum: the first `seconds` of `x` with a 1 ms
/// raised-cosine fade-in and a 5 ms fade-out (so the cut adds no
/// spectrum of its own), zero-padded to at least 8192 points.
pub fn attack_spectrum(x: &[f64], rate_hz: f64, seconds: f64) -> Spectrum {
    let n = ((seconds * rate_hz).round() as usize).max(16);
    let (fin, fout) = ((0.001 * rate_hz) as usize, (0.005 * rate_hz) as usize);
    let w: Vec<f64> = (0..n)
        .map(|i| {
            let rise = if i < fin {
                0.5 - 0.5 * (PI * i as f64 / fin as f64).cos()
            } else {
                1.0
            };
            let j = n - 1 - i;
            let fall = if j < fout {
                0.5 - 0.5 * (PI * j as f64 / fout as f64).cos()
            } else {
                1.0
            };
            rise * fall
        })
        .collect();
    let mut seg = x[..n.min(x.len())].to_vec();
    seg.resize(n, 0.0);
    let nfft = n.next_power_of_two().max(8192);
    let mut planner = RealFftPlanner::new();
    Spectrum {
        df: rate_hz / nfft as f64,
        power: power_spectrum(&mut planner, &seg, &w, nfft),
    }
}

/// The lowest frequency counted in the attack's measures \[Hz\] (below it:
/// offsets and rumble, not the instrument).
pub const ATTACK_LO_HZ: f64 = 20.0;

/// Spectral centroid \[Hz\]: the power-weighted mean frequency of the
/// spectrum above [`ATTACK_LO_HZ`] (the frequency of the energy's centre
/// of mass; G. Peeters, "A large set of audio features", 2004, with power
/// weights).
pub fn centroid(spec: &Spectrum) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (k, p) in spec.power.iter().enumerate() {
        let f = spec.freq(k);
        if f >= ATTACK_LO_HZ {
            num += f * p;
            den += p;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// The lowest level any energy fraction reports \[dB\].
pub const FLOOR_FRACTION_DB: f64 = -120.0;

/// The fraction of the spectrum's power (above [`ATTACK_LO_HZ`]) that
/// lies above `f_hz`, in dB (at least [`FLOOR_FRACTION_DB`]).
pub fn fraction_above_db(spec: &Spectrum, f_hz: f64) -> f64 {
    let total = spec.band_power(ATTACK_LO_HZ, f64::INFINITY);
    let above = spec.band_power(f_hz, f64::INFINITY);
    if total <= 0.0 {
        return FLOOR_FRACTION_DB;
    }
    (10.0 * (above / total).log10()).max(FLOOR_FRACTION_DB)
}

/// Band-limited resampling with `rubato`'s asynchronous sinc resampler
/// (256 taps, Blackman-Harris window; rubato sets the cutoff, relative to
/// the lower of the two Nyquist frequencies, where aliasing stays below the
/// window's side lobes): output sample `j` is the
/// input read at position `j * step`, `step` input samples per output
/// sample (a step above 1 plays faster and higher). The resampler's delay
/// is trimmed off, so both start together. Errors if `step` is not a
/// positive finite ratio rubato accepts.
pub fn resample(x: &[f64], step: f64) -> Result<Vec<f64>, String> {
    use audioadapter_buffers::direct::InterleavedSlice;
    use rubato::{
        Async, FixedAsync, Resampler, SincInterpolationParameters, SincInterpolationType,
        WindowFunction,
    };
    if !(step > 0.0 && step.is_finite()) {
        return Err(format!("resampling step {step}"));
    }
    if x.is_empty() {
        return Ok(Vec::new());
    }
    let sinc_len = 256;
    let window = WindowFunction::BlackmanHarris2;
    let params = SincInterpolationParameters {
        sinc_len,
        f_cutoff: None,
        interpolation: SincInterpolationType::Cubic,
        oversampling_factor: 256,
        window,
    };
    let mut r = Async::<f64>::new_sinc(1.0 / step, 1.0, &params, 1024, 1, FixedAsync::Input)
        .map_err(|e| format!("resampling by {step}: {e}"))?;
    let mut out = vec![0.0; r.process_all_needed_output_len(x.len())];
    let input = InterleavedSlice::new(x, 1, x.len()).map_err(|e| e.to_string())?;
    let frames = out.len();
    let mut output = InterleavedSlice::new_mut(&mut out, 1, frames).map_err(|e| e.to_string())?;
    let (_, n) = r
        .process_all_into_buffer(&input, &mut output, x.len(), None)
        .map_err(|e| format!("resampling by {step}: {e}"))?;
    out.truncate(n);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 44100.0;

    /// A deterministic Gaussian noise (xorshift64* and Box-Muller).
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.max(1);
        let mut u = || {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            ((s.wrapping_mul(0x2545F4914F6CDD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| (-2.0 * u().ln()).sqrt() * (2.0 * PI * u()).cos())
            .collect()
    }

    /// A sum of exponentially decaying sinusoids `(f, T60, amplitude)`.
    fn decays(parts: &[(f64, f64, f64)], seconds: f64) -> Vec<f64> {
        let n = (seconds * FS) as usize;
        let hiss = noise(n, 7);
        (0..n)
            .map(|i| {
                let t = i as f64 / FS;
                parts
                    .iter()
                    .map(|&(f, t60, a)| a * (-6.9078 * t / t60).exp() * (2.0 * PI * f * t).sin())
                    .sum::<f64>()
                    + 1e-5 * hiss[i]
            })
            .collect()
    }

    #[test]
    fn partials_and_t60s_of_decaying_sinusoids_are_recovered() {
        let parts = [
            (220.0, 1.5, 1.0),
            (880.0, 0.4, 0.5),
            (2200.0, 0.15, 0.4),
            (3930.0, 0.8, 0.1),
        ];
        let x = decays(&parts, 3.0);
        let (spec, n) = long_spectrum(&x, FS, 1.0);
        let pk = peaks(&spec, n, 30.0, 20000.0, 60.0);
        assert!(pk.len() >= 4, "{pk:?}");
        let frames = stft(&x);
        for &(f, t60, _) in &parts {
            let p = pk
                .iter()
                .min_by(|a, b| {
                    cents(f, a.freq_hz)
                        .abs()
                        .total_cmp(&cents(f, b.freq_hz).abs())
                })
                .unwrap();
            assert!(
                cents(f, p.freq_hz).abs() < 2.0,
                "{f} Hz found at {}",
                p.freq_hz
            );
            let fit = fit_t60(&track(&frames, FS, f));
            let got = fit.seconds().unwrap_or_else(|| panic!("{f} Hz: {fit:?}"));
            assert!(
                (got / t60 - 1.0).abs() < 0.05,
                "{f} Hz: T60 {got} s, true {t60} s"
            );
        }
        assert_eq!(pk[0].level_db, 0.0);
        assert!((pk[0].freq_hz - 220.0).abs() < 0.5);
    }

    #[test]
    fn a_decay_cut_short_has_no_fit_and_says_why() {
        // 0.3 s of a partial with T60 5 s: about 4 dB of decay in the data
        let x = decays(&[(440.0, 5.0, 1.0)], 0.3);
        match fit_t60(&track(&stft(&x), FS, 440.0)) {
            T60::NoFit(why) => assert!(why.contains("dB"), "{why}"),
            fit => panic!("{fit:?}"),
        }
    }

    #[test]
    fn a_pure_tones_centroid_is_its_frequency() {
        let x: Vec<f64> = (0..FS as usize)
            .map(|i| (2.0 * PI * 1000.0 * i as f64 / FS).sin())
            .collect();
        let spec = attack_spectrum(&x, FS, 0.05);
        assert!(
            (centroid(&spec) / 1000.0 - 1.0).abs() < 0.01,
            "{}",
            centroid(&spec)
        );
        assert!(fraction_above_db(&spec, 5000.0) < -60.0);
    }

    #[test]
    fn white_noise_band_levels_follow_the_bandwidth() {
        // white noise has equal power per hertz: each band's share is its
        // width's share of the 26 bands' span (levels rise 1 dB a band)
        let x = noise((4.0 * FS) as usize, 3);
        let lv = band_levels(&welch(&x, FS, 4.0));
        let edge = 10f64.powf(0.05);
        let width = |b: usize| band_centre(b) * (edge - 1.0 / edge);
        let span: f64 = (0..BANDS).map(width).sum();
        for b in 0..BANDS {
            let expect = 10.0 * (width(b) / span).log10();
            assert!(
                (lv[b] - expect).abs() < 1.0,
                "band {}: {} dB, expected {expect}",
                BAND_NOMINAL[b],
                lv[b]
            );
        }
        let sum: f64 = lv.iter().map(|l| 10f64.powf(l / 10.0)).sum();
        assert!((sum - 1.0).abs() < 1e-9);
    }

    #[test]
    fn distance_is_zero_to_itself_and_the_tilts_rms_to_a_tilted_copy() {
        let x = noise((2.0 * FS) as usize, 11);
        let a = band_levels(&welch(&x, FS, 2.0));
        assert_eq!(third_octave_distance(&a, &a), 0.0);
        // a copy tilted by +3 dB per octave about 1 kHz (power times f/1k),
        // made in the frequency domain
        let n = x.len().next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
        let mut buf = x.clone();
        buf.resize(n, 0.0);
        let mut spec = fwd.make_output_vec();
        fwd.process(&mut buf, &mut spec).unwrap();
        for (k, c) in spec.iter_mut().enumerate() {
            *c *= (k as f64 * FS / n as f64 / 1000.0).sqrt() / n as f64;
        }
        inv.process(&mut spec, &mut buf).unwrap();
        let b = band_levels(&welch(&buf[..x.len()], FS, 2.0));
        // the closed form: band b's level moves by t_b = 10 log10(f_b / 1k)
        // (the tilt at its centre, exact to 0.01 dB over a third octave),
        // less the shift c that renormalises the total; with white noise's
        // band energies E_b ~ width_b ~ f_b
        let t: Vec<f64> = (0..BANDS)
            .map(|i| 10.0 * (band_centre(i) / 1000.0).log10())
            .collect();
        let e: Vec<f64> = (0..BANDS).map(band_centre).collect();
        let c = 10.0
            * (e.iter()
                .zip(&t)
                .map(|(e, t)| e * 10f64.powf(t / 10.0))
                .sum::<f64>()
                / e.iter().sum::<f64>())
            .log10();
        let expect = (t.iter().map(|t| (t - c).powi(2)).sum::<f64>() / BANDS as f64).sqrt();
        let got = third_octave_distance(&a, &b);
        assert!(
            (got - expect).abs() < 0.3,
            "distance {got} dB, closed form {expect} dB"
        );
        assert!(expect > 5.0);
    }

    #[test]
    fn resampling_moves_a_tone_and_keeps_its_level_without_aliasing() {
        let f = 1000.0;
        let x: Vec<f64> = (0..22050)
            .map(|i| (2.0 * PI * f * i as f64 / FS).sin())
            .collect();
        // read 1.5x faster: 1500 Hz at the same rate
        let y = resample(&x, 1.5).unwrap();
        assert_eq!(y.len(), 14700);
        let (spec, n) = long_spectrum(&y[1000..13000], FS, 1.0);
        let p = peaks(&spec, n, 30.0, 20000.0, 60.0);
        assert!(cents(1500.0, p[0].freq_hz).abs() < 0.5, "{:?}", p[0]);
        let rms = (y[1000..13000].iter().map(|v| v * v).sum::<f64>() / 12000.0).sqrt();
        assert!((rms * 2f64.sqrt() - 1.0).abs() < 0.01, "rms {rms}");
        // a 15 kHz tone read 2x faster would alias to 14.1 kHz: filtered out
        let hi: Vec<f64> = (0..22050)
            .map(|i| (2.0 * PI * 15000.0 * i as f64 / FS).sin())
            .collect();
        let z = resample(&hi, 2.0).unwrap();
        let rz = (z[500..10000].iter().map(|v| v * v).sum::<f64>() / 9500.0).sqrt();
        assert!(rz < 1e-3, "alias rms {rz}");
    }

    #[test]
    fn onset_is_a_millisecond_before_the_sound() {
        let mut x = vec![0.0; 1000];
        x.extend((0..1000).map(|i| (i as f64 * 0.1).sin()));
        assert_eq!(onset(&x, FS), 1000 + 1 - 44);
    }
}
