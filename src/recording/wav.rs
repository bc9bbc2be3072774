//! Reading a recording from a WAV file: 8/16/24/32-bit integer or 32-bit
//! float PCM at any rate, one channel of it or the mean of all, as `f64`
//! with full scale 1.

use super::RecordingError;
use std::path::Path;

/// Which channel of a multi-channel file is analysed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Channel {
    /// The mean of every channel.
    #[default]
    Mix,
    /// One channel (0 = the first, the left of a stereo file).
    Index(usize),
}

/// A recording read from a file.
#[derive(Debug, Clone)]
pub struct Recording {
    /// The samples of the channel asked for (full scale 1).
    pub samples: Vec<f64>,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// The file's number of channels.
    pub channels: usize,
    /// The file's sample format, e.g. "24-bit int".
    pub format: String,
}

/// Read `channel` of the WAV file at `path`.
pub fn read_wav(path: &Path, channel: Channel) -> Result<Recording, RecordingError> {
    let reader = hound::WavReader::open(path).map_err(|e| match e {
        hound::Error::IoError(io) => RecordingError::Io(format!("{}: {io}", path.display())),
        hound::Error::Unsupported => {
            RecordingError::UnsupportedFormat(format!("{}: hound cannot read it", path.display()))
        }
        other => RecordingError::NotAudio(format!("{}: {other}", path.display())),
    })?;
    let spec = reader.spec();
    let channels = usize::from(spec.channels);
    if channels == 0 {
        return Err(RecordingError::NotAudio("the file has no channels".into()));
    }
    if let Channel::Index(asked) = channel {
        if asked >= channels {
            return Err(RecordingError::Channel { asked, channels });
        }
    }
    let (interleaved, format) = match (spec.sample_format, spec.bits_per_sample) {
        (hound::SampleFormat::Float, 32) => (
            collect(reader.into_samples::<f32>().map(|s| s.map(f64::from)))?,
            "32-bit float".to_string(),
        ),
        (hound::SampleFormat::Int, bits @ (8 | 16 | 24 | 32)) => {
            let scale = 1.0 / f64::from(1u32 << (bits - 1));
            (
                collect(
                    reader
                        .into_samples::<i32>()
                        .map(|s| s.map(|v| f64::from(v) * scale)),
                )?,
                format!("{bits}-bit int"),
            )
        }
        (f, bits) => {
            return Err(RecordingError::UnsupportedFormat(format!(
                "{bits}-bit {}",
                if f == hound::SampleFormat::Float {
                    "float"
                } else {
                    "int"
                }
            )))
        }
    };
    let samples = match channel {
        Channel::Index(c) => interleaved
            .iter()
            .skip(c)
            .step_by(channels)
            .copied()
            .collect(),
        Channel::Mix => interleaved
            .chunks_exact(channels)
            .map(|f| f.iter().sum::<f64>() / channels as f64)
            .collect(),
    };
    Ok(Recording {
        samples,
        rate_hz: f64::from(spec.sample_rate),
        channels,
        format,
    })
}

/// The samples, or the error of a damaged (truncated) file.
fn collect(it: impl Iterator<Item = hound::Result<f64>>) -> Result<Vec<f64>, RecordingError> {
    it.collect::<Result<Vec<f64>, _>>()
        .map_err(|e| RecordingError::NotAudio(format!("damaged sample data: {e}")))
}
