//! A resonator tube under a bar (marimba, vibraphone, xylophone): a round
//! tube closed at the bottom, open under the bar, its air column tuned to
//! a frequency (docs/design.md, "Resonator tubes").
//!
//! The bar's face over the tube's mouth pushes a volume velocity `U_s =
//! S_c w'` into the air at the mouth (`S_c` the part of the mouth the bar
//! covers, `w` the bar's displacement over the tube's axis). That air
//! flows two ways: down the tube, whose input impedance is `Z_t = -i Z0
//! cot(k L)` (closed at the far end; `Z0 = rho0 c / S`, `S = pi a^2`, `k`
//! complex with the wall losses), and out into the room through the mouth's
//! radiation impedance `Z_r`. With `e^{i omega t}` time dependence:
//!
//! - the mouth pressure is `p_m = Z_par U_s`, `Z_par = Z_t Z_r / (Z_t +
//!   Z_r)`; it pushes back on the bar with the force `-S_c p_m`, so a mass-
//!   normalised mode of weight `phi` at the tube's axis gains the decay
//!   rate `sigma = S_c^2 phi^2 Re(Z_par) / 2`, and the reactive part would
//!   move its frequency by `-S_c^2 phi^2 Im(Z_par) / (4 pi)` \[Hz\] (a
//!   scene leaves that out: docs/design.md, "Resonator tubes");
//! - the room receives the flow out of the mouth, `U_r = p_m / Z_r`, and
//!   the bar's top face draws `U_s` from above: together, within a small
//!   fraction of a wavelength, a monopole of strength `U_r - U_s = -U_s
//!   Z_r / (Z_t + Z_r)`. Far from a tuned resonance `|Z_t| >> |Z_r|` and it
//!   vanishes (the bar's two faces cancel, as they do without a tube);
//!   at the resonance, where `Z_t + Z_r` is only the losses, it is the
//!   tube's quality factor times `U_s`: the resonator is what makes a
//!   marimba's fundamental loud.
//!
//! The lumped picture needs a compact mouth: modes above `ka = 1` are
//! left to the bar alone ([`MAX_COMPACT_KA`]); a marimba's or a
//! vibraphone's tube matters at the fundamental, a tenth of that.
//!
//! Each mode is taken as it rings freely (a steady state at its own
//! frequency), as the radiation to a listener is (docs/design.md,
//! "Radiation to a listener"): this holds while the tube answers faster
//! than the mode decays (the tube's bandwidth, a few hertz, against the
//! mode's decay rate); the tube's own ringing after the strike, and the
//! coupling of two bar modes through the tube, are left out.
//!
//! Sources: the closed tube's impedance and the wall-loss attenuation
//! `alpha = 3e-5 sqrt(f) / a` \[1/m\] (air at room temperature), Fletcher
//! & Rossing, *The Physics of Musical Instruments*, 2nd ed. (1998), 8.2-8.3;
//! the unflanged open end's radiation impedance at low `ka`, `Z0 ((ka)^2 /
//! 4 + 0.61 i ka)` (Levine & Schwinger, Phys. Rev. 73, 1948), here
//! divided by `1 + (ka)^2 / 4` so that it tends to the plane wave's `Z0`
//! (and no reactance) at large `ka`, where the tube no longer matters.

use nalgebra::Complex;
use std::f64::consts::PI;

use crate::bodies::radiation::{AIR_DENSITY_KG_PER_M3, SOUND_SPEED_M_PER_S};

type C = Complex<f64>;

/// Largest tube radius \[m\].
pub const MAX_RADIUS_M: f64 = 0.5;

/// Largest `ka` (the mouth's radius in wavenumbers) at which the mouth
/// is a compact source: the model's bar face over a point-like junction of
/// tube and room holds while the mouth is small against the wavelength. A
/// mode above it (1.76 kHz for a 62 mm tube) is left as the bar alone
/// makes it: neither damped nor radiated by the tube.
pub const MAX_COMPACT_KA: f64 = 1.0;

/// Wall-loss coefficient of air at room temperature: `alpha = WALL_LOSS
/// sqrt(f) / a` \[1/m\] (Fletcher & Rossing 8.2).
pub const WALL_LOSS: f64 = 3e-5;

/// End correction of an unflanged open end, in radii (Levine & Schwinger).
pub const END_CORRECTION: f64 = 0.6133;

/// A tuned resonator tube.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resonator {
    /// Inner radius \[m\].
    pub radius_m: f64,
    /// Length of the air column from the closed end to the mouth \[m\].
    pub length_m: f64,
    /// The part of the mouth the bar covers \[m^2\].
    pub coupling_area_m2: f64,
}

/// What a resonator does to one mode ringing at its frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModeEffect {
    /// Decay rate added \[1/s\].
    pub decay_rate_per_s: f64,
    /// Frequency change the reactive load would make \[Hz\] (scenes do
    /// not apply it: the bar keeps its tuning).
    pub freq_shift_hz: f64,
    /// The monopole the mode radiates through the tube, in the units of
    /// `bodies::radiation::far_field`'s `W_n` (`(re, im)`, m^2/sqrt(kg)):
    /// its pressure at distance `r` is `-(rho0 / (2 pi r)) omega^2 W q` for
    /// the mode's analytic displacement `q`.
    pub far_field: (f64, f64),
}

impl Resonator {
    /// The tube of radius `radius_m` whose air column, loaded by its open
    /// end's reactance and without losses, resonates at `tuned_hz`: `cot(k
    /// L) = X_r / Z0` at that frequency. The bar covers `coupling_area_m2`
    /// of the mouth (at most its area).
    pub fn tuned(radius_m: f64, tuned_hz: f64, coupling_area_m2: f64) -> Result<Self, String> {
        if !(radius_m.is_finite() && radius_m > 0.0 && radius_m <= MAX_RADIUS_M) {
            return Err(format!(
                "radius_m: must be in (0, {MAX_RADIUS_M}], got {radius_m}"
            ));
        }
        if !(tuned_hz.is_finite() && tuned_hz > 0.0) {
            return Err(format!("tuned_hz: must be finite and > 0, got {tuned_hz}"));
        }
        let area = PI * radius_m * radius_m;
        if !(coupling_area_m2.is_finite() && coupling_area_m2 > 0.0 && coupling_area_m2 <= area) {
            return Err(format!(
                "coupling area: must be in (0, {area}] (the mouth), got {coupling_area_m2}"
            ));
        }
        let k = 2.0 * PI * tuned_hz / SOUND_SPEED_M_PER_S;
        let x = reactance_ratio(k * radius_m);
        // cot(k L) = x, the first root: k L in (0, pi / 2)
        let length_m = (1.0 / x).atan() / k;
        Ok(Self {
            radius_m,
            length_m,
            coupling_area_m2,
        })
    }

    /// Characteristic impedance of the air column `rho0 c / S` \[Pa s/m^3\].
    pub fn z0(&self) -> f64 {
        AIR_DENSITY_KG_PER_M3 * SOUND_SPEED_M_PER_S / (PI * self.radius_m * self.radius_m)
    }

    /// The tube's input impedance at its mouth, `-i Z0 cot(k L)` with the
    /// wall losses in `k` \[Pa s/m^3\].
    pub fn tube_impedance(&self, freq_hz: f64) -> C {
        let k = 2.0 * PI * freq_hz / SOUND_SPEED_M_PER_S;
        let alpha = WALL_LOSS * freq_hz.sqrt() / self.radius_m;
        let kl = C::new(k, -alpha) * self.length_m;
        C::new(0.0, -self.z0()) * kl.cos() / kl.sin()
    }

    /// The open end's radiation impedance \[Pa s/m^3\] (module docs).
    pub fn radiation_impedance(&self, freq_hz: f64) -> C {
        let ka = 2.0 * PI * freq_hz / SOUND_SPEED_M_PER_S * self.radius_m;
        let d = 1.0 + ka * ka / 4.0;
        C::new(ka * ka / 4.0 / d, END_CORRECTION * ka / d) * self.z0()
    }

    /// The effect on a mode at `freq_hz` whose mass-normalised weight at
    /// the tube's axis is `phi` \[1/sqrt(kg)\]; none above
    /// [`MAX_COMPACT_KA`] (module docs).
    pub fn on_mode(&self, freq_hz: f64, phi: f64) -> ModeEffect {
        let ka = 2.0 * PI * freq_hz / SOUND_SPEED_M_PER_S * self.radius_m;
        if ka > MAX_COMPACT_KA {
            return ModeEffect {
                decay_rate_per_s: 0.0,
                freq_shift_hz: 0.0,
                far_field: (0.0, 0.0),
            };
        }
        let zt = self.tube_impedance(freq_hz);
        let zr = self.radiation_impedance(freq_hz);
        let zpar = zt * zr / (zt + zr);
        let g = self.coupling_area_m2 * self.coupling_area_m2 * phi * phi;
        // U_r - U_s = -U_s Z_r / (Z_t + Z_r), U_s = S_c phi i omega q, into
        // free space p = i omega rho0 Q / (4 pi r) = -(rho0 / (2 pi r))
        // omega^2 W q with W = -S_c phi Z_r / (2 (Z_t + Z_r))
        let w = -(zr / (zt + zr)) * (0.5 * self.coupling_area_m2 * phi);
        ModeEffect {
            decay_rate_per_s: 0.5 * g * zpar.re,
            freq_shift_hz: -g * zpar.im / (4.0 * PI),
            far_field: (w.re, w.im),
        }
    }
}

/// `X_r / Z0` of the open end at `ka`.
fn reactance_ratio(ka: f64) -> f64 {
    END_CORRECTION * ka / (1.0 + ka * ka / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn marimba_a3() -> Resonator {
        let a = 0.033;
        Resonator::tuned(a, 220.0, PI * a * a).unwrap()
    }

    /// Without losses the parallel resonance (zero admittance of tube and
    /// open end together) sits at the tuned frequency; the length is the
    /// quarter wave less about the end correction.
    #[test]
    fn the_air_column_resonates_where_it_is_tuned() {
        let r = marimba_a3();
        let k = 2.0 * PI * 220.0 / SOUND_SPEED_M_PER_S;
        let tube = -r.z0() / (k * r.length_m).tan(); // lossless: -i Z0 cot, imaginary part
        let end = reactance_ratio(k * r.radius_m) * r.z0();
        // 1 / (i X_t) + 1 / (i X_r) = 0  <=>  X_t = -X_r
        let residual = (tube + end).abs() / end.abs();
        println!("length {} m, residual {residual:e}", r.length_m);
        assert!(residual < 1e-12);
        let quarter = SOUND_SPEED_M_PER_S / (4.0 * 220.0);
        let correction = (quarter - r.length_m) / r.radius_m;
        assert!((correction - END_CORRECTION).abs() < 0.01, "{correction}");
    }

    /// The input impedance of the closed tube in closed form against a
    /// chain of short lossy segments (each a transfer matrix of a uniform
    /// line), built from the closed end.
    #[test]
    fn the_tube_impedance_matches_a_chain_of_segments() {
        let r = marimba_a3();
        for f in [110.0, 219.0, 660.0, 1500.0] {
            let exact = r.tube_impedance(f);
            let k = C::new(
                2.0 * PI * f / SOUND_SPEED_M_PER_S,
                -WALL_LOSS * f64::sqrt(f) / r.radius_m,
            );
            let n = 4000;
            let dl = r.length_m / n as f64;
            // from the closed end: (p, U) = (1, 0); each segment
            // p' = cos(k dl) p - i Z0 sin(k dl) U, U' = -i sin(k dl) p / Z0 + cos(k dl) U
            // (U toward the mouth; i omega rho0 u = -dp/dx)
            let (mut p, mut u) = (C::new(1.0, 0.0), C::new(0.0, 0.0));
            let (cs, sn) = ((k * dl).cos(), (k * dl).sin());
            let i = C::new(0.0, 1.0);
            for _ in 0..n {
                let p2 = cs * p - i * sn * u * r.z0();
                let u2 = -i * sn * p / r.z0() + cs * u;
                p = p2;
                u = u2;
            }
            // the volume velocity into the tube is -U (U flows toward the mouth)
            let chain = -p / u;
            let rel = (chain - exact).norm() / exact.norm();
            println!("{f} Hz: closed form {exact}, chain {chain}, rel {rel:e}");
            assert!(rel < 1e-9, "{f} Hz: {rel:e}");
        }
    }

    /// The power the mode loses, `2 sigma E` with `E = omega^2 |q|^2 / 2`,
    /// is what the tube's walls dissipate plus what its mouth radiates
    /// (the circuit's branches), and the monopole is the tube's quality
    /// factor times the bar's flow at the resonance.
    #[test]
    fn the_mode_loses_what_the_tube_dissipates_and_radiates() {
        let r = marimba_a3();
        let phi = 2.0;
        for f in [150.0, 219.8, 220.0, 660.0, 880.0] {
            let e = r.on_mode(f, phi);
            let omega = 2.0 * PI * f;
            let us = r.coupling_area_m2 * phi * omega; // |U_s| for |q| = 1
            let zt = r.tube_impedance(f);
            let zr = r.radiation_impedance(f);
            let pm = us * zt * zr / (zt + zr);
            let (ut, ur) = (pm / zt, pm / zr);
            let branches = 0.5 * (ut.norm_sqr() * zt.re + ur.norm_sqr() * zr.re);
            let lost = 2.0 * e.decay_rate_per_s * 0.5 * omega * omega;
            println!(
                "{f} Hz: sigma {:.4} 1/s, shift {:+.4} Hz, |W| {:.3e}; lost {lost:.6e} W, branches {branches:.6e} W",
                e.decay_rate_per_s,
                e.freq_shift_hz,
                e.far_field.0.hypot(e.far_field.1)
            );
            assert!(((lost - branches) / branches).abs() < 1e-12);
            assert!(e.decay_rate_per_s > 0.0);
        }
        // the monopole is largest near the tuned frequency and far above
        // the bar's own flow there
        let gain = |f: f64| {
            let w = r.on_mode(f, phi).far_field;
            w.0.hypot(w.1) / (0.5 * r.coupling_area_m2 * phi)
        };
        println!(
            "gain: 200 Hz {:.2}, 220 Hz {:.2}, 880 Hz {:.3}",
            gain(200.0),
            gain(220.0),
            gain(880.0)
        );
        assert!(gain(220.0) > 5.0 && gain(220.0) > 4.0 * gain(200.0));
        assert!(gain(880.0) < 0.2);
        // above ka = 1 the tube is left out
        let above = MAX_COMPACT_KA * SOUND_SPEED_M_PER_S / (2.0 * PI * r.radius_m) * 1.001;
        let e = r.on_mode(above, phi);
        assert_eq!((e.decay_rate_per_s, e.far_field), (0.0, (0.0, 0.0)));
    }

    #[test]
    fn bad_values_are_refused_with_their_name() {
        assert!(Resonator::tuned(0.0, 220.0, 1e-3)
            .unwrap_err()
            .contains("radius_m"));
        assert!(Resonator::tuned(0.03, f64::NAN, 1e-3)
            .unwrap_err()
            .contains("tuned_hz"));
        assert!(Resonator::tuned(0.03, 220.0, 1.0)
            .unwrap_err()
            .contains("coupling area"));
    }
}
