//! What a scraped or rolled preset is compared by besides its spectrum:
//! how long its stroke sounds and how often its contact clicks
//! (docs/design.md, "Rolling and scraping"). A stroke has no partials that
//! decay freely, so the partial and decay targets of a struck preset do
//! not apply to it; these two numbers say whether the stroke moves as the
//! recorded one does.

/// RMS frames of the sounding-time measure \[s\].
const FRAME_S: f64 = 0.005;
/// A frame sounds when its RMS is within this of the loudest frame's \[dB\].
const SOUNDING_DB: f64 = 20.0;
/// RMS frames of the click-rate envelope \[s\].
const ENVELOPE_S: f64 = 0.0005;
/// The click periods looked for \[s\]: 1.5 ms to 40 ms (25 to 667 clicks a
/// second, from a slow roll to a fast scrape over fine ridges).
const PERIODS_S: (f64, f64) = (0.0015, 0.040);

/// The stroke of one sound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Stroke {
    /// How long it sounds: from the first to the end of the last
    /// [`FRAME_S`] frame within [`SOUNDING_DB`] of the loudest \[s\].
    pub sounding_s: f64,
    /// Clicks a second: the inverse of the strongest period of its
    /// envelope's autocorrelation over the sounding frames (its largest
    /// peak), with that correlation (`None`: no peak in [`PERIODS_S`]
    /// correlates above 0).
    pub clicks: Option<(f64, f64)>,
}

/// The RMS of `x` in frames of `len` samples (the last partial frame left
/// out).
fn rms_frames(x: &[f64], len: usize) -> Vec<f64> {
    x.chunks_exact(len.max(1))
        .map(|c| (c.iter().map(|v| v * v).sum::<f64>() / c.len() as f64).sqrt())
        .collect()
}

/// Measure the stroke of `x` sampled at `rate_hz`: its sounding time, and
/// its click rate from the autocorrelation of its RMS envelope (frames of
/// [`ENVELOPE_S`], the mean removed) from the first to the last sounding
/// frame, the lag of the largest correlation in [`PERIODS_S`] refined by
/// a parabola through its neighbours.
pub(super) fn stroke(x: &[f64], rate_hz: f64) -> Stroke {
    let frames = rms_frames(x, (FRAME_S * rate_hz).round() as usize);
    let loudest = frames.iter().copied().fold(0.0, f64::max);
    let floor = loudest * 10f64.powf(-SOUNDING_DB / 20.0);
    let on: Vec<usize> = (0..frames.len())
        .filter(|&i| loudest > 0.0 && frames[i] >= floor)
        .collect();
    let (Some(&first), Some(&last)) = (on.first(), on.last()) else {
        return Stroke {
            sounding_s: 0.0,
            clicks: None,
        };
    };
    let hop = (ENVELOPE_S * rate_hz).round() as usize;
    let per = (FRAME_S / ENVELOPE_S).round() as usize;
    let mut env = rms_frames(x, hop);
    env.truncate((last + 1) * per);
    let start = (first * per).min(env.len());
    Stroke {
        sounding_s: (last + 1 - first) as f64 * FRAME_S,
        clicks: click_rate(&mut env[start..], hop as f64 / rate_hz),
    }
}

/// Clicks a second and their correlation from an RMS envelope in frames
/// of `frame_s` (see [`Stroke::clicks`]); the envelope's mean is removed
/// in place.
fn click_rate(env: &mut [f64], frame_s: f64) -> Option<(f64, f64)> {
    let mean = env.iter().sum::<f64>() / env.len().max(1) as f64;
    env.iter_mut().for_each(|e| *e -= mean);
    let (lo, hi) = (
        (PERIODS_S.0 / ENVELOPE_S).floor() as usize,
        (PERIODS_S.1 / ENVELOPE_S).ceil() as usize,
    );
    if env.len() < 2 * hi {
        return None;
    }
    let ac: Vec<f64> = (0..=hi + 1)
        .map(|lag| env.iter().zip(&env[lag..]).map(|(a, b)| a * b).sum())
        .collect();
    if ac[0] <= 0.0 {
        return None;
    }
    // the largest peak (a lag whose correlation exceeds both neighbours'),
    // not the slope down from lag 0 that a smooth envelope has
    let best = (lo..=hi)
        .filter(|&l| ac[l] > ac[l - 1] && ac[l] >= ac[l + 1])
        .max_by(|&a, &b| ac[a].total_cmp(&ac[b]))?;
    let r = ac[best] / ac[0];
    if r <= 0.0 {
        return None;
    }
    let (ym, y0, yp) = (ac[best - 1], ac[best], ac[best + 1]);
    let den = ym - 2.0 * y0 + yp;
    let shift = if den < 0.0 {
        (0.5 * (ym - yp) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    Some((1.0 / ((best as f64 + shift) * frame_s), r))
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: f64 = 44100.0;

    /// A click train: a decaying 2.5 kHz burst every `period_s` for
    /// `seconds`, silence after.
    fn clicks(period_s: f64, seconds: f64) -> Vec<f64> {
        let n = (seconds * RATE) as usize;
        let mut x = vec![0.0; n + (0.3 * RATE) as usize];
        let mut t0 = 0.0;
        while t0 < seconds {
            let i0 = (t0 * RATE).round() as usize;
            for k in 0..(0.002 * RATE) as usize {
                let t = k as f64 / RATE;
                x[i0 + k] += (-t / 3e-4).exp() * (2.0 * std::f64::consts::PI * 2500.0 * t).sin();
            }
            t0 += period_s;
        }
        x
    }

    /// The click rate and sounding time of click trains of known period
    /// and length, from a slow roll to a fast scrape.
    #[test]
    fn a_click_train_gives_its_rate_and_length() {
        for (period, seconds) in [(0.003, 0.25), (0.009, 0.4), (0.020, 0.5)] {
            let s = stroke(&clicks(period, seconds), RATE);
            let (rate, r) = s.clicks.expect("clicks");
            println!(
                "period {period} s for {seconds} s: {rate:.1} clicks/s (correlation {r:.2}), \
                 sounding {:.3} s",
                s.sounding_s
            );
            assert!(
                (rate * period - 1.0).abs() < 0.01,
                "{rate} against {}",
                1.0 / period
            );
            // the last click starts within a period of the end
            let last = ((seconds / period).ceil() - 1.0) * period;
            assert!(
                (s.sounding_s - last).abs() <= 0.01,
                "{} against {last}",
                s.sounding_s
            );
        }
    }

    /// Silence has no stroke; steady noise sounds throughout and its
    /// envelope barely correlates at any click period.
    #[test]
    fn silence_and_noise_have_no_clicks() {
        let silent = stroke(&vec![0.0; 22050], RATE);
        assert_eq!(silent.sounding_s, 0.0);
        assert!(silent.clicks.is_none());
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let noise: Vec<f64> = (0..22050)
            .map(|_| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let s = stroke(&noise, RATE);
        println!("noise: {s:?}");
        assert!((s.sounding_s - 0.5).abs() < 0.01, "{}", s.sounding_s);
        assert!(s.clicks.is_none_or(|(_, r)| r < 0.2), "{:?}", s.clicks);
    }
}
