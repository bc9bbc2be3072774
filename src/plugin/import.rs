//! The editor's "Import recording...": a recorded strike becomes a user
//! scene. The analysis is the library's ([`crate::recording`], whose
//! module documentation has the method; `cargo xtask analyze` runs the same
//! steps from the command line); this module runs it on a file, saves the
//! scene into the user folder without overwriting anything there, and
//! prepares what the editor draws: the recording's spectrum with the
//! fitted modes' over it. Everything here runs on a background thread the
//! editor starts; nothing is shared with the audio thread (docs/plugin.md,
//! "Import a recording").

use crate::recording::{analyze, object_scene, read_wav, AnalysisOptions, Channel};
use crate::recording::{Analysis, DEFAULT_MALLET_KG};
use realfft::RealFftPlanner;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The stretch of the recording the spectra are taken over, from the
/// onset \[s\] (the 1/3-octave distance of `cargo xtask analyze` measures
/// the same first half second).
pub const SPECTRUM_S: f64 = 0.5;

/// Points of the drawn spectra, log-spaced from [`SPECTRUM_LOW_HZ`] to
/// Nyquist (or 20 kHz).
pub const SPECTRUM_POINTS: usize = 256;

/// The lowest frequency drawn \[Hz\].
pub const SPECTRUM_LOW_HZ: f64 = 20.0;

/// Most files named after one recording in one folder (`name.toml`,
/// `name-2.toml`, ...): beyond it the import says so instead of looking
/// further.
const MAX_SAME_NAME: usize = 999;

/// A recording imported: where its scene was saved and what the editor
/// shows of the fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The scene file written (new: nothing was overwritten).
    pub path: PathBuf,
    /// The scene's name (the recording's file name without extension).
    pub name: String,
    /// One line for the editor: modes, their range, the residual, the
    /// mallet, clipping.
    pub summary: String,
    /// The spectra over the first [`SPECTRUM_S`] after the onset.
    pub spectrum: FitSpectrum,
}

/// The recording's and the fit's magnitude spectra at log-spaced
/// frequencies, both in dB re the recording's largest point.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FitSpectrum {
    /// The frequencies \[Hz\].
    pub freqs_hz: Vec<f64>,
    /// The recording's level at each \[dB\].
    pub recording_db: Vec<f64>,
    /// The fitted modes' level (their sum resynthesized) at each \[dB\].
    pub fit_db: Vec<f64>,
    /// The modes found: frequency \[Hz\] and level at the onset \[dB re the
    /// strongest\].
    pub modes: Vec<(f64, f64)>,
}

/// Analyse the strike recorded in `wav` (the mean of its channels; the
/// analysis's defaults: modes from 20 Hz to 20 kHz, the fit from 5 ms after
/// the onset) and save its scene into `folder` (made if missing) as
/// `NAME.toml`, or `NAME-2.toml`, ... when that name is taken. Every
/// failure is a message saying what was wrong (the recording's,
/// [`crate::recording::RecordingError`], or the folder's); nothing is
/// written then. \[worker\]
pub fn import_recording(wav: &Path, folder: &Path) -> Result<Imported, String> {
    // a folder that cannot be made is said before the analysis's seconds
    if folder.exists() && !folder.is_dir() {
        return Err(format!(
            "cannot make the user folder {}: a file is in its place",
            folder.display()
        ));
    }
    let rec = read_wav(wav, Channel::Mix).map_err(|e| format!("{}: {e}", wav.display()))?;
    let x = &rec.samples;
    let an = analyze(x, rec.rate_hz, &AnalysisOptions::default())
        .map_err(|e| format!("{}: {e}", wav.display()))?;
    let name = wav
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.trim().is_empty())
        .unwrap_or_else(|| "recording".into());
    let (text, mallet) = object_scene(&an, x, &name, DEFAULT_MALLET_KG)
        .map_err(|e| format!("{}: {e}", wav.display()))?;
    let path = save_new(folder, &file_stem(&name), &text)?;
    let (lo, hi) = an
        .modes
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), m| {
            (lo.min(m.freq_hz), hi.max(m.freq_hz))
        });
    let clipped = an.clipping.as_ref().map_or(String::new(), |c| {
        format!(
            "; clipped ({} samples at full scale): fitted after {:.1} ms",
            c.samples,
            1e3 * c.end.saturating_sub(an.onset) as f64 / an.rate_hz
        )
    });
    let summary = format!(
        "{} modes, {:.0} Hz .. {:.0} Hz; residual {:.1} dB of the recording over the span fitted; \
         mallet {:.0} g, contact {:.2} ms{clipped}",
        an.modes.len(),
        lo,
        hi,
        an.residual_db(x),
        1e3 * mallet.mass_kg,
        1e3 * mallet.contact_s,
    );
    Ok(Imported {
        spectrum: fit_spectrum(&an, x),
        path,
        name,
        summary,
    })
}

/// A file name from a scene's name: what file systems refuse (path
/// separators, control characters and the characters Windows reserves)
/// becomes `_`.
fn file_stem(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_control() || "/\\:*?\"<>|".contains(c) {
                '_'
            } else {
                c
            }
        })
        .collect();
    let s = s.trim().trim_start_matches('.').to_string();
    if s.is_empty() {
        "recording".into()
    } else {
        s
    }
}

/// Write `text` into a new file `stem.toml` in `folder` (made if missing),
/// or `stem-2.toml`, `stem-3.toml`, ... if that exists: the file is created
/// exclusively, so an existing file (another import, the user's own) is
/// never overwritten, even by two imports at once.
fn save_new(folder: &Path, stem: &str, text: &str) -> Result<PathBuf, String> {
    std::fs::create_dir_all(folder)
        .map_err(|e| format!("cannot make the user folder {}: {e}", folder.display()))?;
    for n in 1..=MAX_SAME_NAME {
        let file = if n == 1 {
            format!("{stem}.toml")
        } else {
            format!("{stem}-{n}.toml")
        };
        let path = folder.join(file);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(mut f) => {
                return f
                    .write_all(text.as_bytes())
                    .and_then(|()| f.sync_all())
                    .map(|()| path.clone())
                    .map_err(|e| {
                        // a partial file would list as a broken scene
                        let _ = std::fs::remove_file(&path);
                        format!("cannot write {}: {e}", path.display())
                    });
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(format!("cannot create {}: {e}", path.display())),
        }
    }
    Err(format!(
        "{} already holds {MAX_SAME_NAME} scenes named {stem}: rename the recording",
        folder.display()
    ))
}

/// The recording's and the resynthesis's spectra over the first
/// [`SPECTRUM_S`] after the onset: each a Hann-windowed FFT (zero-padded
/// to a power of two), reduced to [`SPECTRUM_POINTS`] log-spaced points,
/// each the largest magnitude of the bins from it up to the next point
/// (the nearest bin where no bin falls between).
pub fn fit_spectrum(an: &Analysis, recording: &[f64]) -> FitSpectrum {
    let start = an.onset.min(recording.len());
    let len = ((SPECTRUM_S * an.rate_hz) as usize).min(recording.len() - start);
    if len < 16 {
        return FitSpectrum::default();
    }
    let model = an.resynthesize(start + len);
    let nfft = len.next_power_of_two() * 2;
    let rec = magnitudes(&recording[start..start + len], nfft);
    let fit = magnitudes(&model[start..start + len], nfft);
    let bin_hz = an.rate_hz / nfft as f64;
    let top = (0.5 * an.rate_hz).min(20_000.0);
    let edges: Vec<f64> = (0..=SPECTRUM_POINTS)
        .map(|i| SPECTRUM_LOW_HZ * (top / SPECTRUM_LOW_HZ).powf(i as f64 / SPECTRUM_POINTS as f64))
        .collect();
    let reduce = |mags: &[f64]| -> Vec<f64> {
        edges
            .windows(2)
            .map(|w| {
                let (a, b) = ((w[0] / bin_hz).ceil() as usize, (w[1] / bin_hz) as usize);
                let b = b.min(mags.len() - 1);
                if a <= b {
                    mags[a..=b].iter().fold(0.0_f64, |m, &v| m.max(v))
                } else {
                    mags[((w[0] / bin_hz).round() as usize).min(mags.len() - 1)]
                }
            })
            .collect()
    };
    let (rec, fit) = (reduce(&rec), reduce(&fit));
    let peak = rec.iter().fold(0.0_f64, |m, &v| m.max(v)).max(1e-300);
    let db = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .map(|&m| 20.0 * (m.max(1e-300) / peak).log10())
            .collect()
    };
    let strongest = an
        .modes
        .iter()
        .fold(0.0_f64, |m, x| m.max(x.amplitude))
        .max(1e-300);
    FitSpectrum {
        freqs_hz: edges.windows(2).map(|w| (w[0] * w[1]).sqrt()).collect(),
        recording_db: db(&rec),
        fit_db: db(&fit),
        modes: an
            .modes
            .iter()
            .map(|m| (m.freq_hz, 20.0 * (m.amplitude / strongest).log10()))
            .collect(),
    }
}

/// `|FFT|` of `x` under a Hann window, zero-padded to `nfft` points.
fn magnitudes(x: &[f64], nfft: usize) -> Vec<f64> {
    let n = x.len();
    let mut buf = vec![0.0; nfft];
    for (i, (b, v)) in buf.iter_mut().zip(x).enumerate() {
        let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
        *b = v * w;
    }
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(nfft);
    let mut spec = fft.make_output_vec();
    // the lengths are the plan's own: the transform cannot refuse them
    if fft.process(&mut buf, &mut spec).is_err() {
        return vec![0.0; nfft / 2 + 1];
    }
    spec.iter().map(|c| c.norm()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::model::LN_1000;
    use crate::plugin::browser::{list_folder, Folder};
    use std::f64::consts::PI;

    /// A fresh folder in the temporary directory for test `name`.
    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("mc-import-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// Three modes `(f, T60, amplitude)` (the strike's object).
    const MODES: [(f64, f64, f64); 3] = [(440.0, 1.5, 0.4), (1210.0, 0.8, 0.2), (2950.0, 0.4, 0.1)];

    /// An integer PCM WAV file of `samples` (interleaved).
    fn write_wav(
        path: &Path,
        channels: u16,
        rate: u32,
        bits: u16,
        samples: impl Iterator<Item = i32>,
    ) {
        let spec = hound::WavSpec {
            channels,
            sample_rate: rate,
            bits_per_sample: bits,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(path, spec).expect("wav");
        for v in samples {
            w.write_sample(v).expect("sample");
        }
        w.finalize().expect("wav");
    }

    /// A 16-bit WAV of [`MODES`] ringing from 10 ms into the file (silence
    /// before it), 0.6 s at 44.1 kHz.
    fn strike_wav(path: &Path) {
        let rate = 44_100.0;
        let samples = (0..26_460).map(|i| {
            let t = (i as f64 - 441.0) / rate;
            let v: f64 = if t < 0.0 {
                0.0
            } else {
                MODES
                    .iter()
                    .map(|(f, t60, a)| a * (-LN_1000 / t60 * t).exp() * (2.0 * PI * f * t).sin())
                    .sum()
            };
            (v * 32767.0).round() as i32
        });
        write_wav(path, 1, 44_100, 16, samples);
    }

    #[test]
    fn an_imported_strike_is_a_new_user_scene_with_its_modes() {
        let dir = temp("strike");
        let wav = dir.with_extension("wav");
        strike_wav(&wav);
        let scenes = dir.join("scenes");
        let a = import_recording(&wav, &scenes).expect("import");
        eprintln!("{}: {}", a.path.display(), a.summary);
        assert_eq!(a.path, scenes.join(format!("{}.toml", a.name)));
        // the folder lists it as a valid scene, as the browser shows it
        let Ok(Folder::Listed(entries)) = list_folder(&scenes) else {
            panic!("the folder is not listed")
        };
        assert_eq!(entries.len(), 1);
        assert!(entries[0].status.is_ok(), "{:?}", entries[0].status);
        // its modes are the recording's
        let text = std::fs::read_to_string(&a.path).expect("read");
        let scene = crate::Scene::from_toml_str(&text).expect("scene");
        let found = &a.spectrum.modes;
        for (f, _, _) in MODES {
            let near = found
                .iter()
                .map(|m| (m.0 - f).abs() / f)
                .fold(f64::INFINITY, f64::min);
            eprintln!("{f} Hz: nearest mode {near:.2e} relative");
            assert!(near < 1e-4, "{f} Hz not found: {found:?}");
        }
        assert!(scene.object.len() == 1);
        // the fit's spectrum lies on the recording's at the modes
        let s = &a.spectrum;
        assert_eq!(s.freqs_hz.len(), SPECTRUM_POINTS);
        for (f, _, _) in MODES {
            // the point whose band holds the mode (the nearest on a log axis)
            let i = (0..s.freqs_hz.len())
                .min_by(|&a, &b| {
                    (s.freqs_hz[a] / f)
                        .ln()
                        .abs()
                        .total_cmp(&(s.freqs_hz[b] / f).ln().abs())
                })
                .expect("points");
            let gap = (s.fit_db[i] - s.recording_db[i]).abs();
            eprintln!(
                "{f} Hz: recording {:.3} dB, fit {:.3} dB",
                s.recording_db[i], s.fit_db[i]
            );
            assert!(
                gap < 0.1,
                "{f} Hz: the fit is {gap:.3} dB off the recording"
            );
        }
        let loudest = s.recording_db.iter().fold(f64::MIN, |m, &v| m.max(v));
        assert!(
            loudest.abs() < 1e-9,
            "levels are re the recording's largest"
        );
        let _ = std::fs::remove_dir_all(&dir);
        let _ = std::fs::remove_file(&wav);
    }

    #[test]
    fn a_second_save_never_overwrites() {
        let dir = temp("twice");
        std::fs::create_dir_all(&dir).expect("dir");
        // the user's own file of that name stays as it is
        let own = dir.join("bowl.toml");
        std::fs::write(&own, "# mine\n").expect("write");
        let a = save_new(&dir, "bowl", "# first\n").expect("save");
        let b = save_new(&dir, "bowl", "# second\n").expect("save");
        assert_eq!(a, dir.join("bowl-2.toml"));
        assert_eq!(b, dir.join("bowl-3.toml"));
        assert_eq!(std::fs::read_to_string(&own).unwrap(), "# mine\n");
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "# first\n");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "# second\n");
        // a folder made on the way
        let deeper = dir.join("new").join("scenes");
        assert_eq!(
            save_new(&deeper, "bowl", "x").expect("save"),
            deeper.join("bowl.toml")
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_recordings_and_folders_are_refused_with_their_reason_and_write_nothing() {
        let dir = temp("bad");
        std::fs::create_dir_all(&dir).expect("dir");
        let scenes = dir.join("scenes");
        // not audio
        let text = dir.join("notes.wav");
        std::fs::write(&text, "this is not a recording").expect("write");
        let e = import_recording(&text, &scenes).unwrap_err();
        assert!(e.contains("notes.wav") && e.contains("not a WAV"), "{e}");
        // silence
        let quiet = dir.join("quiet.wav");
        write_wav(&quiet, 2, 48_000, 24, std::iter::repeat_n(0, 2 * 48_000));
        let e = import_recording(&quiet, &scenes).unwrap_err();
        assert!(e.contains("silent"), "{e}");
        // a missing file
        let e = import_recording(&dir.join("gone.wav"), &scenes).unwrap_err();
        assert!(e.contains("gone.wav"), "{e}");
        assert!(!scenes.exists(), "a failed import made the folder");
        // a file where the folder should be
        let wav = dir.join("strike.wav");
        strike_wav(&wav);
        let blocked = dir.join("blocked");
        std::fs::write(&blocked, "").expect("write");
        let e = import_recording(&wav, &blocked).unwrap_err();
        assert!(e.contains("cannot make the user folder"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn file_names_from_scene_names() {
        assert_eq!(file_stem("bowl"), "bowl");
        assert_eq!(file_stem("a/b\\c:d"), "a_b_c_d");
        assert_eq!(file_stem("..hidden"), "hidden");
        assert_eq!(file_stem("   "), "recording");
        assert_eq!(file_stem("x\u{7}y"), "x_y");
    }
}
