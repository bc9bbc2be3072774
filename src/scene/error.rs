//! [`SceneError`], the error of a scene file that names the offending
//! field and the reason, and the checks of single values that build it.

use std::fmt;

/// A validation or parse error that names the field and the reason.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// Path of the offending field, e.g. `object[0].mode[2].t60_s` (empty for
    /// TOML syntax errors, whose message carries the line).
    pub path: String,
    /// Why the value is refused.
    pub reason: String,
}

impl SceneError {
    pub(crate) fn new(path: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            reason: reason.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            write!(f, "{}", self.reason)
        } else {
            write!(f, "{}: {}", self.path, self.reason)
        }
    }
}

impl std::error::Error for SceneError {}

pub(super) fn check_finite(path: &str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SceneError::new(path, format!("must be finite, got {v}")))
    }
}

pub(super) fn check_positive(path: &str, v: f64) -> Result<(), SceneError> {
    check_finite(path, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(SceneError::new(path, format!("must be > 0, got {v}")))
    }
}

pub(super) fn check_non_negative(path: &str, v: f64) -> Result<(), SceneError> {
    check_finite(path, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(SceneError::new(path, format!("must be >= 0, got {v}")))
    }
}

/// `v` (already known finite) must be at most `hi`.
pub(super) fn check_max(path: &str, v: f64, hi: f64) -> Result<(), SceneError> {
    if v <= hi {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("must be <= {hi:e}, got {v:e}"),
        ))
    }
}

/// `v` (already known finite) must be at least `lo`.
pub(super) fn check_min(path: &str, v: f64, lo: f64) -> Result<(), SceneError> {
    if v >= lo {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("must be >= {lo:e}, got {v:e}"),
        ))
    }
}

/// `|v|` (already known finite) must be at most `hi`.
pub(super) fn check_abs_max(path: &str, v: f64, hi: f64) -> Result<(), SceneError> {
    if v.abs() <= hi {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("|value| must be <= {hi:e}, got {v:e}"),
        ))
    }
}
