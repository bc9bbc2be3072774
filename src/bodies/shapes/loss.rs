//! The decay of each mode: a [`LossModel`] of supports and air, material
//! damping and a radiation-like term.
//!
//! # Loss model
//!
//! Each mode decays at `sigma_i = sigma_0 + eta omega_i / 2 + sigma_r
//! (f_i / f_r)^p` \[1/s\] (the `sigma_i` of docs/design.md section 2):
//! constant `sigma_0` (supports, air drag), material loss factor `eta` (a
//! mode alone decays as `T60 = 2 ln(1000) / (eta omega)`), and an optional
//! radiation-like term `sigma_r` at reference frequency `f_r` growing as
//! `f^p` (`p = 2` gives the form `a_0 + a_2 f^2` fitted to xylophone bars by
//! Chaigne & Doutaut, JASA 101, 1997, with `a_0 = sigma_0`). `T60_i =
//! ln(1000) / sigma_i`, none when `sigma_i = 0` (undamped).

use std::f64::consts::PI;

use super::check::{non_negative, positive};

/// Decay of each mode: `sigma(f) = sigma_0 + eta omega / 2 + sigma_r (f /
/// f_r)^p` \[1/s\], `T60 = ln(1000) / sigma`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossModel {
    /// Material loss factor `eta` (`Material::loss_factor`).
    pub loss_factor: f64,
    /// Frequency-independent decay rate `sigma_0` \[1/s\].
    pub decay_rate_per_s: f64,
    /// Radiation-like decay rate `sigma_r` at `radiation_ref_hz` \[1/s\].
    pub radiation_per_s: f64,
    /// Reference frequency `f_r` of the radiation term \[Hz\].
    pub radiation_ref_hz: f64,
    /// Exponent `p` of the radiation term.
    pub radiation_exponent: f64,
}

impl LossModel {
    /// Material damping only.
    pub fn material(loss_factor: f64) -> Self {
        LossModel {
            loss_factor,
            decay_rate_per_s: 0.0,
            radiation_per_s: 0.0,
            radiation_ref_hz: 1000.0,
            radiation_exponent: 2.0,
        }
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        non_negative("loss.loss_factor", self.loss_factor)?;
        non_negative("loss.decay_rate_per_s", self.decay_rate_per_s)?;
        non_negative("loss.radiation_per_s", self.radiation_per_s)?;
        positive("loss.radiation_ref_hz", self.radiation_ref_hz)?;
        non_negative("loss.radiation_exponent", self.radiation_exponent)?;
        Ok(())
    }

    /// Decay rate `sigma` \[1/s\] of a mode at `freq_hz`.
    pub fn decay_rate(&self, freq_hz: f64) -> Result<f64, String> {
        self.validate()?;
        non_negative("freq_hz", freq_hz)?;
        Ok(self.decay_rate_per_s
            + self.loss_factor * PI * freq_hz
            + self.radiation_per_s
                * (freq_hz / self.radiation_ref_hz).powf(self.radiation_exponent))
    }

    /// 60 dB decay time \[s\] of a mode at `freq_hz`; `None` when undamped.
    pub fn t60_s(&self, freq_hz: f64) -> Result<Option<f64>, String> {
        let sigma = self.decay_rate(freq_hz)?;
        Ok(if sigma > 0.0 {
            Some(1000f64.ln() / sigma)
        } else {
            None
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_model_t60() {
        let eta = 0.005;
        let loss = LossModel::material(eta);
        let f = 440.0;
        let t60 = loss.t60_s(f).unwrap().unwrap();
        let want = 2.0 * 1000f64.ln() / (eta * 2.0 * PI * f);
        println!("eta {eta}, {f} Hz: T60 {t60:.6} s (2 ln 1000 / (eta omega) = {want:.6})");
        assert!((t60 / want - 1.0).abs() < 1e-15);
        let full = LossModel {
            loss_factor: eta,
            decay_rate_per_s: 0.5,
            radiation_per_s: 2.0,
            radiation_ref_hz: 1000.0,
            radiation_exponent: 2.0,
        };
        let sigma = full.decay_rate(2000.0).unwrap();
        assert!((sigma - (0.5 + eta * PI * 2000.0 + 8.0)).abs() < 1e-12);
        assert_eq!(LossModel::material(0.0).t60_s(100.0).unwrap(), None);
        let bad = LossModel {
            loss_factor: f64::NAN,
            ..full
        };
        assert!(bad.t60_s(100.0).unwrap_err().contains("loss.loss_factor"));
        let bad = LossModel {
            radiation_ref_hz: 0.0,
            ..full
        };
        assert!(bad
            .t60_s(100.0)
            .unwrap_err()
            .contains("loss.radiation_ref_hz"));
    }
}
