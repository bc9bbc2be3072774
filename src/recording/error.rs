//! Why an analysis of a recording could not run: one variant per kind of
//! bad input, each with a message that says what was wrong and, where
//! there is one, what to do about it.

/// An analysis refused its input (or its options).
#[derive(Debug, Clone, PartialEq)]
pub enum RecordingError {
    /// The file could not be opened or read.
    Io(String),
    /// The file is not a WAV file hound can read (not audio, or damaged).
    NotAudio(String),
    /// A WAV sample format other than 8/16/24/32-bit integer or 32-bit float.
    UnsupportedFormat(String),
    /// The sample rate \[Hz\] is outside [`RATE_RANGE_HZ`](super::RATE_RANGE_HZ).
    SampleRate(f64),
    /// The recording (or the part of it after the onset, the clipping and
    /// the time range) is too short: its length and the least the
    /// analysis needs \[s\].
    TooShort {
        /// What is there \[s\].
        seconds: f64,
        /// The least the analysis needs \[s\].
        needed: f64,
    },
    /// A sample is NaN or infinite: its index (in frames).
    NonFinite(usize),
    /// Every sample is (near) zero: the peak, relative to full scale.
    Silent(f64),
    /// The channel asked for is not in the file.
    Channel {
        /// The channel asked for (0 = first).
        asked: usize,
        /// How many the file has.
        channels: usize,
    },
    /// An option is out of range: what and why.
    Option(String),
    /// No pole survived: the sound is not the free decay of a struck
    /// object (or its modes are all below the noise). The counts of
    /// dropped poles by reason, as text.
    NoModes(String),
    /// The scene written from the analysis does not load or compile.
    Scene(String),
    /// A decomposition did not converge (should not happen on finite data).
    Numerics(String),
}

impl std::fmt::Display for RecordingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "cannot read the recording: {e}"),
            Self::NotAudio(e) => write!(f, "not a WAV audio file: {e}"),
            Self::UnsupportedFormat(e) => write!(
                f,
                "unsupported WAV sample format ({e}); use 16/24/32-bit integer or 32-bit float PCM"
            ),
            Self::SampleRate(r) => write!(
                f,
                "sample rate {r} Hz is outside the analysis's range {} to {} Hz",
                super::RATE_RANGE_HZ.0,
                super::RATE_RANGE_HZ.1
            ),
            Self::TooShort { seconds, needed } => write!(
                f,
                "the recording's free decay is too short: {:.1} ms, at least {:.1} ms needed \
                 (record the whole decay, or widen the time range)",
                seconds * 1e3,
                needed * 1e3
            ),
            Self::NonFinite(i) => write!(
                f,
                "sample {i} is NaN or infinite: the file is damaged or not a recording"
            ),
            Self::Silent(peak) => write!(
                f,
                "the recording is silent (peak {:.1} dB re full scale)",
                20.0 * peak.max(1e-300).log10()
            ),
            Self::Channel { asked, channels } => write!(
                f,
                "channel {asked} asked for, but the file has {channels} channel(s) (0 is the first)"
            ),
            Self::Option(e) => write!(f, "bad analysis option: {e}"),
            Self::NoModes(why) => write!(
                f,
                "no stable decaying modes found: this does not sound like the free decay of a struck object ({why})"
            ),
            Self::Scene(e) => write!(f, "{e}"),
            Self::Numerics(e) => write!(f, "a decomposition failed: {e}"),
        }
    }
}

impl std::error::Error for RecordingError {}
