//! `[drive]`: the hammer's contact driven over a surface profile (rolling
//! and scraping, docs/design.md, "Rolling and scraping"). The schema and
//! its checks; the profile itself is made by `bodies::surface` and driven
//! by the engine (`src/engine/drive.rs`).

use serde::{Deserialize, Serialize};

use super::error::{check_finite, check_max, check_non_negative, check_positive};
use super::{SceneError, MAX_SPEED_M_PER_S};

/// Longest surface \[m\] a scene may describe (the profile is tabulated
/// along it).
pub const MAX_SURFACE_LENGTH_M: f64 = 100.0;

/// Deepest surface relief \[m\] (peak height or RMS).
pub const MAX_SURFACE_DEPTH_M: f64 = 0.01;

/// Largest rolling radius \[m\].
pub const MAX_ROLL_RADIUS_M: f64 = 0.5;

/// Largest pressing force \[N\].
pub const MAX_PRESS_N: f64 = 1000.0;

/// The hammer's contact point travels along a path on the struck object
/// at a set speed; the surface's height under it moves the contact's rest
/// position: penetration `p = x_contact + s(t) - x_hammer`, `s` read from
/// the profile at the path position at each sample instant and linear
/// between samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSpec {
    /// Speed along the path \[m/s\] (0: the surface stands still).
    pub speed_m_per_s: f64,
    /// Path position at the start \[m\].
    #[serde(default)]
    pub start_m: f64,
    /// Radius of the rolling body \[m\]: the contact follows the surface
    /// as a ball of this radius does (it cannot reach into hollows
    /// narrower than itself). 0: a point (a scraping tip).
    #[serde(default)]
    pub radius_m: f64,
    /// A constant force pressing the hammer onto the surface \[N\] (a hand
    /// holding a scraper), added to its weight.
    #[serde(default)]
    pub press_n: f64,
    /// What the path does past the profile's end.
    #[serde(default)]
    pub beyond: Beyond,
    /// The surface.
    pub surface: SurfaceSpec,
}

/// What the path does past the profile's end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Beyond {
    /// Start again at the beginning (a closed track: the profile is
    /// periodic, its ends joined).
    #[default]
    Wrap,
    /// Stay at the end: the surface stops moving.
    Stop,
}

/// A surface profile along the path, heights in metres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum SurfaceSpec {
    /// Periodic ridges (a guiro, a ratchet): each a sawtooth rising over
    /// `rise` of the spacing and falling over the rest.
    Ridges {
        /// Path length of the profile \[m\].
        length_m: f64,
        /// Distance between ridges \[m\].
        spacing_m: f64,
        /// Ridge height \[m\].
        depth_m: f64,
        /// Fraction of the spacing over which a ridge rises (0.5: a
        /// symmetric triangle; 1: a ratchet's slow rise and sudden drop).
        #[serde(default = "default_rise")]
        rise: f64,
    },
    /// Random roughness: Gaussian-like heights with a power spectrum
    /// `(1 + (k l)^2)^(-exponent / 2)` (flat below the correlation
    /// length's wavenumber, falling as `k^-exponent` above it), scaled to
    /// the RMS height; periodic over its length; the same for the same
    /// seed.
    Fractal {
        /// Path length of the profile \[m\].
        length_m: f64,
        /// RMS height \[m\].
        rms_m: f64,
        /// Correlation length `l` \[m\].
        correlation_m: f64,
        /// Spectral exponent (2: Brownian-like; 1: rougher, 3: smoother).
        #[serde(default = "default_exponent")]
        exponent: f64,
        /// Seed of the random phases.
        #[serde(default)]
        seed: u64,
    },
    /// A WAV file read as heights along the path: its channels mixed,
    /// spread evenly over the length, scaled so the largest `|height|` is
    /// `depth_m`.
    Wav {
        /// The file (relative paths from the scene file's folder).
        file: String,
        /// Path length the file's samples cover \[m\].
        length_m: f64,
        /// Largest `|height|` \[m\].
        depth_m: f64,
    },
}

fn default_rise() -> f64 {
    0.5
}

fn default_exponent() -> f64 {
    2.0
}

impl SurfaceSpec {
    /// Path length of the profile \[m\].
    pub fn length_m(&self) -> f64 {
        match self {
            Self::Ridges { length_m, .. }
            | Self::Fractal { length_m, .. }
            | Self::Wav { length_m, .. } => *length_m,
        }
    }

    fn validate(&self) -> Result<(), SceneError> {
        let length = self.length_m();
        check_positive("drive.surface.length_m", length)?;
        check_max("drive.surface.length_m", length, MAX_SURFACE_LENGTH_M)?;
        match self {
            Self::Ridges {
                spacing_m,
                depth_m,
                rise,
                ..
            } => {
                check_positive("drive.surface.spacing_m", *spacing_m)?;
                check_max("drive.surface.spacing_m", *spacing_m, length)?;
                check_non_negative("drive.surface.depth_m", *depth_m)?;
                check_max("drive.surface.depth_m", *depth_m, MAX_SURFACE_DEPTH_M)?;
                check_finite("drive.surface.rise", *rise)?;
                if !(*rise > 0.0 && *rise <= 1.0) {
                    return Err(SceneError::new(
                        "drive.surface.rise",
                        format!("must be within (0, 1], got {rise}"),
                    ));
                }
            }
            Self::Fractal {
                rms_m,
                correlation_m,
                exponent,
                ..
            } => {
                check_non_negative("drive.surface.rms_m", *rms_m)?;
                check_max("drive.surface.rms_m", *rms_m, MAX_SURFACE_DEPTH_M)?;
                check_positive("drive.surface.correlation_m", *correlation_m)?;
                check_max("drive.surface.correlation_m", *correlation_m, length)?;
                check_finite("drive.surface.exponent", *exponent)?;
                if !(0.5..=4.0).contains(exponent) {
                    return Err(SceneError::new(
                        "drive.surface.exponent",
                        format!("must be within 0.5 ..= 4, got {exponent}"),
                    ));
                }
            }
            Self::Wav { file, depth_m, .. } => {
                if file.trim().is_empty() {
                    return Err(SceneError::new(
                        "drive.surface.file",
                        "must name a WAV file",
                    ));
                }
                check_non_negative("drive.surface.depth_m", *depth_m)?;
                check_max("drive.surface.depth_m", *depth_m, MAX_SURFACE_DEPTH_M)?;
            }
        }
        Ok(())
    }
}

impl DriveSpec {
    /// Check every value (field paths `drive.*`).
    pub(super) fn validate(&self) -> Result<(), SceneError> {
        check_finite("drive.speed_m_per_s", self.speed_m_per_s)?;
        if self.speed_m_per_s.abs() > MAX_SPEED_M_PER_S {
            return Err(SceneError::new(
                "drive.speed_m_per_s",
                format!(
                    "must be within +-{MAX_SPEED_M_PER_S} m/s, got {}",
                    self.speed_m_per_s
                ),
            ));
        }
        check_finite("drive.start_m", self.start_m)?;
        check_non_negative("drive.radius_m", self.radius_m)?;
        check_max("drive.radius_m", self.radius_m, MAX_ROLL_RADIUS_M)?;
        check_non_negative("drive.press_n", self.press_n)?;
        check_max("drive.press_n", self.press_n, MAX_PRESS_N)?;
        self.surface.validate()
    }
}
