//! The driven contact's surface, made ready for the engine (docs/design.md,
//! "Rolling and scraping"): `[drive]`'s profile tabulated
//! (`bodies::surface`), read from its WAV file if it names one, and
//! filtered by the rolling body's radius.

use crate::bodies::surface::{self, Profile};
use crate::scene::{Beyond, DriveSpec, SceneError, SurfaceSpec};

/// Grid points per ridge of a ridged surface.
const POINTS_PER_RIDGE: usize = 64;

/// Grid points per correlation length of a rough surface.
const POINTS_PER_CORRELATION: f64 = 16.0;

/// Most grid points of a profile (a rough surface's grid is coarsened to
/// this; a WAV file longer than this is refused).
pub const MAX_PROFILE_POINTS: usize = 1 << 22;

/// What the engine needs to drive the contact: the profile it follows
/// (already the rolling body's view of the surface), the speed and the
/// start along the path.
#[derive(Debug, Clone, PartialEq)]
pub struct DrivePlan {
    /// The heights the contact follows \[m\] along the path.
    pub profile: Profile,
    /// Speed along the path \[m/s\].
    pub speed_m_per_s: f64,
    /// Path position at the start \[m\].
    pub start_m: f64,
    /// The surface under the start (heights are measured from it, so the
    /// scene's hammer height is its height above the surface there) \[m\].
    pub base_m: f64,
}

/// Build the plan of `spec` (field paths `drive.*` in errors).
pub fn plan(spec: &DriveSpec) -> Result<DrivePlan, SceneError> {
    let periodic = spec.beyond == Beyond::Wrap;
    let raw = match &spec.surface {
        SurfaceSpec::Ridges {
            length_m,
            spacing_m,
            depth_m,
            rise,
        } => surface::ridges(
            *length_m,
            *spacing_m,
            *depth_m,
            *rise,
            POINTS_PER_RIDGE,
            periodic,
        ),
        SurfaceSpec::Fractal {
            length_m,
            rms_m,
            correlation_m,
            exponent,
            seed,
        } => {
            let want = (POINTS_PER_CORRELATION * length_m / correlation_m).ceil();
            let n = if want >= MAX_PROFILE_POINTS as f64 {
                MAX_PROFILE_POINTS
            } else {
                (want as usize).max(16)
            };
            let p = surface::fractal(*length_m, n, *rms_m, *correlation_m, *exponent, *seed);
            if periodic {
                p
            } else {
                // held ends instead of wrapping: the same heights, the last
                // one repeated so the table spans the length
                let mut h = p.heights;
                h.push(h[0]);
                Profile {
                    dx: p.dx,
                    heights: h,
                    periodic: false,
                }
            }
        }
        SurfaceSpec::Wav {
            file,
            length_m,
            depth_m,
        } => {
            let samples = read_wav(file)?;
            surface::scaled(&samples, *length_m, *depth_m, periodic)
        }
    };
    let profile = surface::roll(&raw, spec.radius_m);
    let base_m = profile.at(spec.start_m);
    Ok(DrivePlan {
        profile,
        speed_m_per_s: spec.speed_m_per_s,
        start_m: spec.start_m,
        base_m,
    })
}

/// A WAV file's samples, channels mixed (their mean), as f64.
fn read_wav(file: &str) -> Result<Vec<f64>, SceneError> {
    let field = "drive.surface.file";
    let mut r = hound::WavReader::open(file)
        .map_err(|e| SceneError::new(field, format!("cannot read {file} as a WAV file: {e}")))?;
    let spec = r.spec();
    let ch = usize::from(spec.channels.max(1));
    let frames = r.duration() as usize;
    if frames < 2 {
        return Err(SceneError::new(
            field,
            format!("{file} holds {frames} sample frames; a profile needs at least 2"),
        ));
    }
    if frames > MAX_PROFILE_POINTS {
        return Err(SceneError::new(
            field,
            format!("{file} holds {frames} sample frames; at most {MAX_PROFILE_POINTS}"),
        ));
    }
    let bad = |e: hound::Error| SceneError::new(field, format!("{file}: {e}"));
    let values: Vec<f64> = match spec.sample_format {
        hound::SampleFormat::Float => r
            .samples::<f32>()
            .map(|s| s.map(f64::from))
            .collect::<Result<_, _>>()
            .map_err(bad)?,
        hound::SampleFormat::Int => r
            .samples::<i32>()
            .map(|s| s.map(f64::from))
            .collect::<Result<_, _>>()
            .map_err(bad)?,
    };
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(SceneError::new(
            field,
            format!("{file}: sample {i} is not a finite number"),
        ));
    }
    Ok(values
        .chunks(ch)
        .map(|c| c.iter().sum::<f64>() / c.len() as f64)
        .collect())
}
