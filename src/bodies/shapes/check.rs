//! Argument checks the kinds share: each returns the value or an error
//! naming the field, so a bad geometry is reported where it was given.

use super::MAX_MODE_COUNT;

pub(super) fn positive(field: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{field}: must be finite and > 0, got {v}"))
    }
}

pub(super) fn non_negative(field: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{field}: must be finite and >= 0, got {v}"))
    }
}

pub(super) fn check_limits(max_freq_hz: f64, max_count: usize) -> Result<(), String> {
    if !(max_freq_hz > 0.0) {
        return Err(format!("max_freq_hz: must be > 0, got {max_freq_hz}"));
    }
    if max_count > MAX_MODE_COUNT {
        return Err(format!(
            "max_count: must be <= {MAX_MODE_COUNT}, got {max_count}"
        ));
    }
    Ok(())
}

pub(super) fn in_range(field: &str, v: f64, hi: f64) -> Result<f64, String> {
    if v.is_finite() && (0.0..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{field}: must be in [0, {hi}], got {v}"))
    }
}

pub(super) fn in_symmetric_range(field: &str, v: f64, half: f64) -> Result<f64, String> {
    if v.is_finite() && v.abs() <= half {
        Ok(v)
    } else {
        Err(format!("{field}: must be in [-{half}, {half}], got {v}"))
    }
}
