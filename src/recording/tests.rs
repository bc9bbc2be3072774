//! Bad input, each refused with its own error (never a panic), and the
//! formats and rates of WAV files read and analysed; the files are written
//! into the system's temporary directory by the tests themselves.

use super::*;
use crate::test_rng::TestRng;
use std::path::{Path, PathBuf};

/// A sum of damped sinusoids `(f, T60, amplitude)`, phase 0.3 rad each.
fn decay(modes: &[(f64, f64, f64)], rate: f64, seconds: f64) -> Vec<f64> {
    let n = (rate * seconds) as usize;
    (0..n)
        .map(|i| {
            let t = i as f64 / rate;
            modes
                .iter()
                .map(|(f, t60, a)| a * (-LN_1000 / t60 * t).exp() * (2.0 * PI * f * t + 0.3).cos())
                .sum()
        })
        .collect()
}

/// Three modes, the test's object.
const MODES: [(f64, f64, f64); 3] = [(523.0, 2.0, 0.4), (1187.0, 1.0, 0.25), (2011.0, 0.5, 0.15)];

/// Options for a test's short analyses: the range of [`MODES`].
fn opts() -> AnalysisOptions {
    AnalysisOptions {
        freq_range_hz: (300.0, 2500.0),
        ..AnalysisOptions::default()
    }
}

/// A unique path in the temporary directory.
fn temp(name: &str) -> PathBuf {
    let mut rng = TestRng(std::process::id() as u64 ^ name.len() as u64);
    std::env::temp_dir().join(format!(
        "modal-contact-recording-{}-{:x}-{name}",
        std::process::id(),
        rng.next_u64()
    ))
}

/// Each mode of [`MODES`] found within `rel` in frequency and 2 % in T60.
fn assert_modes(a: &Analysis, rel: f64) {
    for (f, t60, _) in MODES {
        let m = a
            .modes
            .iter()
            .min_by(|x, y| (x.freq_hz - f).abs().total_cmp(&(y.freq_hz - f).abs()))
            .expect("a mode");
        eprintln!(
            "{f} Hz: found {:.6} Hz ({:.2e} rel), T60 {:.4} s ({:+.3} %)",
            m.freq_hz,
            (m.freq_hz - f).abs() / f,
            m.t60_s,
            100.0 * (m.t60_s / t60 - 1.0)
        );
        assert!(
            (m.freq_hz - f).abs() < rel * f,
            "{f} Hz found at {}",
            m.freq_hz
        );
        assert!(
            (m.t60_s / t60 - 1.0).abs() < 0.02,
            "{t60} s found as {}",
            m.t60_s
        );
    }
}

#[test]
fn silence_is_refused() {
    let e = analyze(&vec![0.0; 48_000], 48_000.0, &opts()).unwrap_err();
    eprintln!("{e}");
    assert!(matches!(e, RecordingError::Silent(_)), "{e:?}");
    assert!(e.to_string().contains("silent"));
}

#[test]
fn nan_and_infinite_samples_are_refused() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut x = decay(&MODES, 48_000.0, 0.5);
        x[1234] = bad;
        let e = analyze(&x, 48_000.0, &opts()).unwrap_err();
        eprintln!("{e}");
        assert_eq!(e, RecordingError::NonFinite(1234));
    }
}

#[test]
fn a_short_recording_is_refused() {
    let x = decay(&MODES, 48_000.0, 0.04);
    let e = analyze(&x, 48_000.0, &opts()).unwrap_err();
    eprintln!("{e}");
    assert!(matches!(e, RecordingError::TooShort { .. }), "{e:?}");
    // A time range that leaves too little of the decay.
    let x = decay(&MODES, 48_000.0, 0.5);
    let o = AnalysisOptions {
        start_s: Some(0.49),
        ..opts()
    };
    let e = analyze(&x, 48_000.0, &o).unwrap_err();
    assert!(matches!(e, RecordingError::TooShort { .. }), "{e:?}");
}

#[test]
fn a_recording_just_over_the_shortest_is_analysed() {
    // 60 ms: the bands widen so each still has its samples.
    let x = decay(&[(1000.0, 0.3, 0.5)], 48_000.0, 0.06);
    let a = analyze(&x, 48_000.0, &AnalysisOptions::default()).unwrap();
    let m = &a.modes[0];
    eprintln!(
        "60 ms: {} Hz, T60 {} s, bands {:?}",
        m.freq_hz, m.t60_s, a.bands
    );
    assert!((m.freq_hz - 1000.0).abs() < 1e-6 * 1000.0);
    assert!((m.t60_s / 0.3 - 1.0).abs() < 1e-3);
}

#[test]
fn white_noise_has_no_modes() {
    let mut rng = TestRng(7);
    let x: Vec<f64> = (0..48_000).map(|_| rng.uniform(-0.5, 0.5)).collect();
    let e = analyze(&x, 48_000.0, &AnalysisOptions::default()).unwrap_err();
    eprintln!("{e}");
    assert!(matches!(e, RecordingError::NoModes(_)), "{e:?}");
}

#[test]
fn a_steady_tone_is_not_a_strike() {
    let x = decay(&[(700.0, 1e6, 0.5)], 48_000.0, 0.5);
    let e = analyze(&x, 48_000.0, &opts()).unwrap_err();
    eprintln!("{e}");
    assert!(matches!(e, RecordingError::NoModes(_)), "{e:?}");
}

#[test]
fn a_clipped_attack_is_reported_and_the_rest_fitted() {
    let x: Vec<f64> = decay(&MODES, 48_000.0, 1.0)
        .into_iter()
        .map(|v| (4.0 * v).clamp(-1.0, 1.0))
        .collect();
    let a = analyze(&x, 48_000.0, &opts()).unwrap();
    let c = a.clipping.clone().expect("clipping found");
    eprintln!("clipping: {c:?}, span from {}", a.span.0);
    assert!(c.runs >= 1 && c.samples >= 3);
    assert!(a.span.0 > c.end);
    // The model's amplitudes are those of the unclipped signal, times 4.
    assert_modes(&a, 1e-6);
    let top = a
        .modes
        .iter()
        .find(|m| (m.freq_hz - 523.0).abs() < 1.0)
        .unwrap();
    assert!(
        (top.amplitude / 1.6 - 1.0).abs() < 1e-3,
        "{}",
        top.amplitude
    );
}

#[test]
fn bad_options_are_refused() {
    let x = decay(&MODES, 48_000.0, 0.5);
    let bad = [
        AnalysisOptions {
            freq_range_hz: (3000.0, 100.0),
            ..opts()
        },
        AnalysisOptions {
            freq_range_hz: (30_000.0, 40_000.0),
            ..opts()
        },
        AnalysisOptions {
            start_s: Some(f64::NAN),
            ..opts()
        },
        AnalysisOptions {
            start_s: Some(0.3),
            end_s: Some(0.2),
            ..opts()
        },
        AnalysisOptions {
            max_modes: Some(0),
            ..opts()
        },
        AnalysisOptions {
            band_hz: -1.0,
            ..opts()
        },
    ];
    for o in bad {
        let e = analyze(&x, 48_000.0, &o).unwrap_err();
        eprintln!("{e}");
        assert!(matches!(e, RecordingError::Option(_)), "{e:?}");
    }
    let e = analyze(&x, 1000.0, &opts()).unwrap_err();
    assert!(matches!(e, RecordingError::SampleRate(_)), "{e:?}");
}

/// Write `frames` (one `Vec` per channel) to a WAV file of `bits` bits
/// (32 float when `float`).
fn write_wav(path: &Path, rate: u32, bits: u16, float: bool, channels: &[Vec<f64>]) {
    let spec = hound::WavSpec {
        channels: channels.len() as u16,
        sample_rate: rate,
        bits_per_sample: bits,
        sample_format: if float {
            hound::SampleFormat::Float
        } else {
            hound::SampleFormat::Int
        },
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    let full = f64::from(1u32 << (bits - 1)) - 1.0;
    for i in 0..channels[0].len() {
        for c in channels {
            if float {
                w.write_sample(c[i] as f32).unwrap();
            } else {
                w.write_sample((c[i] * full).round() as i32).unwrap();
            }
        }
    }
    w.finalize().unwrap();
}

#[test]
fn wav_formats_and_rates_are_read_and_analysed() {
    for rate in [22_050u32, 44_100, 96_000, 192_000] {
        for (bits, float) in [(16, false), (24, false), (32, false), (32, true)] {
            let path = temp(&format!("{rate}-{bits}-{float}.wav"));
            let x = decay(&MODES, f64::from(rate), 0.6);
            write_wav(&path, rate, bits, float, &[x]);
            let r = read_wav(&path, Channel::Mix).unwrap();
            std::fs::remove_file(&path).ok();
            eprintln!("{rate} Hz, {}: {} samples", r.format, r.samples.len());
            assert_eq!(r.rate_hz, f64::from(rate));
            let a = analyze(&r.samples, r.rate_hz, &opts()).unwrap();
            // 16-bit quantisation is noise 90 dB under the peak.
            assert_modes(&a, if bits == 16 { 1e-5 } else { 1e-6 });
        }
    }
}

#[test]
fn stereo_channels_are_chosen_or_mixed() {
    let path = temp("stereo.wav");
    let left = decay(&MODES, 44_100.0, 0.6);
    let right = vec![0.0; left.len()];
    write_wav(&path, 44_100, 24, false, &[left, right]);
    let l = read_wav(&path, Channel::Index(0)).unwrap();
    let r = read_wav(&path, Channel::Index(1)).unwrap();
    let m = read_wav(&path, Channel::Mix).unwrap();
    let e = read_wav(&path, Channel::Index(2)).unwrap_err();
    std::fs::remove_file(&path).ok();
    eprintln!("{e}");
    assert_eq!(
        e,
        RecordingError::Channel {
            asked: 2,
            channels: 2
        }
    );
    assert_eq!(l.channels, 2);
    assert_modes(&analyze(&l.samples, 44_100.0, &opts()).unwrap(), 1e-6);
    let silent = analyze(&r.samples, 44_100.0, &opts()).unwrap_err();
    assert!(matches!(silent, RecordingError::Silent(_)), "{silent:?}");
    let mixed = analyze(&m.samples, 44_100.0, &opts()).unwrap();
    assert_modes(&mixed, 1e-6);
    let top = mixed
        .modes
        .iter()
        .find(|x| (x.freq_hz - 523.0).abs() < 1.0)
        .unwrap();
    assert!(
        (top.amplitude / 0.2 - 1.0).abs() < 1e-3,
        "mix halves: {}",
        top.amplitude
    );
}

#[test]
fn files_that_are_not_audio_are_refused() {
    let text = temp("notes.wav");
    std::fs::write(&text, "these are not samples\n".repeat(100)).unwrap();
    let e = read_wav(&text, Channel::Mix).unwrap_err();
    std::fs::remove_file(&text).ok();
    eprintln!("{e}");
    assert!(matches!(e, RecordingError::NotAudio(_)), "{e:?}");

    let missing = temp("missing.wav");
    let e = read_wav(&missing, Channel::Mix).unwrap_err();
    eprintln!("{e}");
    assert!(matches!(e, RecordingError::Io(_)), "{e:?}");

    // A WAV file cut in the middle of its samples.
    let cut = temp("cut.wav");
    write_wav(&cut, 44_100, 16, false, &[decay(&MODES, 44_100.0, 0.2)]);
    let bytes = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() / 2 + 1]).unwrap();
    let e = read_wav(&cut, Channel::Mix);
    std::fs::remove_file(&cut).ok();
    eprintln!("{e:?}");
    assert!(matches!(e, Err(RecordingError::NotAudio(_))), "{e:?}");

    // 8-bit files read; 64-bit float is not a format the reader takes.
    let f64path = temp("f64.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 64,
        sample_format: hound::SampleFormat::Float,
    };
    if let Ok(mut w) = hound::WavWriter::create(&f64path, spec) {
        let _ = w.write_sample(0.5f32);
        let _ = w.finalize();
    }
    let e = read_wav(&f64path, Channel::Mix);
    std::fs::remove_file(&f64path).ok();
    eprintln!("{e:?}");
    assert!(e.is_err());
}

#[test]
fn nan_in_a_float_file_is_refused() {
    let path = temp("nan.wav");
    let mut x = decay(&MODES, 44_100.0, 0.3);
    x[100] = f64::NAN;
    write_wav(&path, 44_100, 32, true, &[x]);
    let r = read_wav(&path, Channel::Mix).unwrap();
    std::fs::remove_file(&path).ok();
    let e = analyze(&r.samples, r.rate_hz, &opts()).unwrap_err();
    eprintln!("{e}");
    assert_eq!(e, RecordingError::NonFinite(100));
}

/// A partial whose envelope is no exponential (a power law, as a room's
/// or a processed sample's tail decays) splits into a cluster of unstable
/// poles; the cluster is kept as one mode near the partial's frequency
/// that carries its energy (within 2 dB over the first 0.5 s), where
/// dropping every unstable pole would drop the partial. The exact modes
/// beside it are still found to 1e-6.
#[test]
fn a_partial_that_is_no_exponential_is_kept_as_one_mode() {
    let rate = 48_000.0;
    let mut x = decay(&MODES[..1], rate, 1.0);
    let f = 1500.0;
    let partial: Vec<f64> = (0..x.len())
        .map(|i| {
            let t = i as f64 / rate;
            0.3 * (1.0 + t / 0.05).powi(-3) * (2.0 * PI * f * t).cos()
        })
        .collect();
    for (v, p) in x.iter_mut().zip(&partial) {
        *v += p;
    }
    let a = analyze(&x, rate, &opts()).unwrap();
    let near: Vec<&Mode> = a
        .modes
        .iter()
        .filter(|m| (m.freq_hz - f).abs() < 20.0)
        .collect();
    let merged = a
        .dropped
        .iter()
        .filter(|d| d.reason == DropReason::Merged)
        .count();
    eprintln!(
        "{} modes near {f} Hz ({merged} poles merged): {:?}",
        near.len(),
        near.iter()
            .map(|m| (m.freq_hz, m.t60_s, m.level_db()))
            .collect::<Vec<_>>()
    );
    assert!(merged >= 2, "no cluster merged");
    // The energy of the modes near the partial against the partial's own,
    // over the first 0.5 s after the span's start.
    let model = Analysis {
        modes: near.into_iter().cloned().collect(),
        ..a.clone()
    }
    .resynthesize(x.len());
    let (from, to) = (a.span.0, a.span.0 + (0.5 * rate) as usize);
    let energy = |s: &[f64]| s[from..to].iter().map(|v| v * v).sum::<f64>();
    let db = 10.0 * (energy(&model) / energy(&partial)).log10();
    eprintln!("the partial's modes carry {db:+.2} dB of its energy");
    assert!(db.abs() < 2.0, "{db} dB");
    let top = a
        .modes
        .iter()
        .find(|m| (m.freq_hz - MODES[0].0).abs() < 1.0)
        .expect("the exact mode");
    assert!(
        (top.freq_hz / MODES[0].0 - 1.0).abs() < 1e-6,
        "{}",
        top.freq_hz
    );
}
