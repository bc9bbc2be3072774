//! The decay of a physical object's modes: the loss model of a scene file
//! and the sound radiation of a baffled plate.

use crate::bodies::shapes::LossModel;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The decay of every mode: `sigma(f) = decay_rate_per_s + eta pi f +
/// radiation_per_s (f / radiation_ref_hz)^radiation_exponent` \[1/s\],
/// `T60 = ln(1000) / sigma` (`eta`: the material's loss factor unless
/// given here).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LossSpec {
    /// Overrides the material's loss factor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss_factor: Option<f64>,
    /// Frequency-independent decay rate (supports, air) \[1/s\].
    #[serde(default)]
    pub decay_rate_per_s: f64,
    /// Radiation-like decay rate at `radiation_ref_hz` \[1/s\].
    #[serde(default)]
    pub radiation_per_s: f64,
    /// Reference frequency of the radiation term \[Hz\].
    #[serde(default = "default_radiation_ref_hz")]
    pub radiation_ref_hz: f64,
    /// Exponent of the radiation term.
    #[serde(default = "default_radiation_exponent")]
    pub radiation_exponent: f64,
    /// Plates only: the sound radiation of a baffled plate into air
    /// ([`plate_radiation_rate`]) times this factor (1: the plate in air at
    /// 20 C; 0, the default: none), beside the power law above.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub plate_radiation: f64,
    /// Bars, tubes, stiff strings and membranes: the power each mode
    /// radiates into air from both faces, each face as the far field the
    /// listeners hear gives it (a face in a baffle,
    /// [`radiation_decay_rate`](crate::bodies::radiated_power::radiation_decay_rate)),
    /// times this factor (1: both faces radiate freely; 0, the default:
    /// none), beside the power law above. A tube's is its projected
    /// strip's, which overstates a round tube's (docs/design.md,
    /// "Radiation damping").
    #[serde(default, skip_serializing_if = "is_zero")]
    pub radiation_damping: f64,
    /// Dashpots where the object is held (the cords through a bar, the
    /// felt under it): each adds `n_s_per_m w^2 / 2` \[1/s\] to a mode of
    /// weight `w` there (docs/design.md, "Dashpots at points").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dashpots: Vec<PointDashpotSpec>,
}

/// A dashpot between one of a physical object's named points and the
/// (still) frame: where the object is held.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointDashpotSpec {
    /// The object's named point.
    pub point: String,
    /// Damping coefficient \[N s/m\].
    pub n_s_per_m: f64,
}

/// Density of air \[kg/m^3\] (20 C) for [`plate_radiation_rate`].
const RHO_AIR: f64 = 1.204;
/// Speed of sound in air \[m/s\] (20 C) for [`plate_radiation_rate`].
const C_AIR: f64 = 343.0;

/// Decay rate \[1/s\] of a mode at `f` of a thin rectangular plate (sides
/// `a`, `b`, areal density `rho_h`, flexural rigidity `d`) radiating into
/// air from a baffle: `rho_0 c / (2 rho h) sigma(f)` with the radiation
/// efficiency `sigma` of a baffled simply supported plate by Maidanik
/// (1962), as given in Beranek & Ver, *Noise and Vibration Control
/// Engineering* (1992). Below the coincidence frequency
/// `f_c = c^2 / (2 pi) sqrt(rho h / D)`, edge and corner radiation:
///
/// `sigma = lambda_c P / S g_2 + 2 lambda_c^2 / S g_1`, `alpha = sqrt(f / f_c)`,
///
/// `g_2 = ((1 - alpha^2) ln((1 + alpha) / (1 - alpha)) + 2 alpha) / (4 pi^2 (1 - alpha^2)^1.5)`,
///
/// `g_1 = 4 / pi^4 (1 - 2 alpha^2) / (alpha sqrt(1 - alpha^2))` below `f_c / 2`, else 0;
///
/// above it `1 / sqrt(1 - f_c / f)`; both capped at `sqrt(a / lambda_c) +
/// sqrt(b / lambda_c)`. Used for free plates too (an estimate: Maidanik's
/// result is for simple supports).
pub fn plate_radiation_rate(f: f64, a: f64, b: f64, rho_h: f64, d: f64) -> f64 {
    let f_co = C_AIR * C_AIR / (2.0 * PI) * (rho_h / d).sqrt();
    let lam_c = C_AIR / f_co;
    let (p, s) = (2.0 * (a + b), a * b);
    let cap = (a / lam_c).sqrt() + (b / lam_c).sqrt();
    let sigma = if f >= f_co {
        if f > f_co {
            1.0 / (1.0 - f_co / f).sqrt()
        } else {
            f64::INFINITY
        }
    } else {
        let al = (f / f_co).sqrt();
        let g2 = ((1.0 - al * al) * ((1.0 + al) / (1.0 - al)).ln() + 2.0 * al)
            / (4.0 * PI * PI * (1.0 - al * al).powf(1.5));
        let g1 = if f < f_co / 2.0 {
            4.0 / PI.powi(4) * (1.0 - 2.0 * al * al) / (al * (1.0 - al * al).sqrt())
        } else {
            0.0
        };
        lam_c * p / s * g2 + 2.0 * lam_c * lam_c / s * g1
    };
    RHO_AIR * C_AIR / (2.0 * rho_h) * sigma.min(cap)
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn default_radiation_ref_hz() -> f64 {
    1000.0
}

fn default_radiation_exponent() -> f64 {
    2.0
}

impl Default for LossSpec {
    fn default() -> Self {
        LossSpec {
            loss_factor: None,
            decay_rate_per_s: 0.0,
            radiation_per_s: 0.0,
            radiation_ref_hz: default_radiation_ref_hz(),
            radiation_exponent: default_radiation_exponent(),
            plate_radiation: 0.0,
            radiation_damping: 0.0,
            dashpots: Vec::new(),
        }
    }
}

impl LossSpec {
    pub(super) fn model(&self, material_eta: f64) -> LossModel {
        LossModel {
            loss_factor: self.loss_factor.unwrap_or(material_eta),
            decay_rate_per_s: self.decay_rate_per_s,
            radiation_per_s: self.radiation_per_s,
            radiation_ref_hz: self.radiation_ref_hz,
            radiation_exponent: self.radiation_exponent,
        }
    }

    /// Every decay rate (and every dashpot's damping) changed by `rate` (a
    /// caller scales decay times through it, as the instrument does for its
    /// decay and damper parameters: each mode's `sigma` is linear in them,
    /// so scaling them scales every mode's T60 alike), `material_eta` the loss
    /// factor the object takes when none is given here. An object without
    /// any loss gets the constant rate `undamped_rate` instead.
    pub fn scaled(&self, material_eta: f64, undamped_rate: f64, rate: impl Fn(f64) -> f64) -> Self {
        let eta = self.loss_factor.unwrap_or(material_eta);
        if eta == 0.0
            && self.decay_rate_per_s == 0.0
            && self.radiation_per_s == 0.0
            && self.plate_radiation == 0.0
            && self.radiation_damping == 0.0
            && self.dashpots.iter().all(|d| d.n_s_per_m == 0.0)
        {
            if undamped_rate == 0.0 {
                return self.clone();
            }
            return LossSpec {
                loss_factor: Some(0.0),
                decay_rate_per_s: undamped_rate,
                ..self.clone()
            };
        }
        let scaled_eta = rate(eta);
        LossSpec {
            // unchanged stays as written (a unit scale keeps the scene)
            loss_factor: if self.loss_factor.is_none() && scaled_eta == eta {
                None
            } else {
                Some(scaled_eta)
            },
            decay_rate_per_s: rate(self.decay_rate_per_s),
            radiation_per_s: rate(self.radiation_per_s),
            plate_radiation: rate(self.plate_radiation),
            radiation_damping: rate(self.radiation_damping),
            // a dashpot's decay rate is linear in its damping
            dashpots: self
                .dashpots
                .iter()
                .map(|d| PointDashpotSpec {
                    n_s_per_m: rate(d.n_s_per_m),
                    ..d.clone()
                })
                .collect(),
            ..self.clone()
        }
    }
}
