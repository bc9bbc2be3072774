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
//! mode's decay rate); the coupling of two bar modes through the tube is
//! left out.
//!
//! The tube's own ringing after the strike: its resonances above the
//! tuned one ([`Resonator::own_modes`], a closed tube's odd harmonics)
//! are modes of their own, each an air mass and a compliance from the
//! pole of `Z_par` (its Foster term), coupled to the bar modes to first
//! order ([`Resonator::mixing`]) and radiating from the open end
//! ([`TubeMode`]). The tuned resonance itself stays in the bar mode it is
//! tuned to (the two are too close for the first-order picture).
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

/// `d (X_r / Z0) / d(ka)`.
fn reactance_ratio_slope(ka: f64) -> f64 {
    let d = 1.0 + ka * ka / 4.0;
    END_CORRECTION * (1.0 - ka * ka / 4.0) / (d * d)
}

/// Largest mixing of a tube mode with a bar mode (the first-order
/// eigenvector component, dimensionless) for which the tube mode is
/// added as a mode of its own ([`Resonator::mixing`]): beyond, the two are
/// too close in frequency for the first-order picture, and the tube mode
/// is left out (docs/design.md, "Resonator tubes").
pub const MAX_MIXING: f64 = 0.1;

/// One of the tube's own resonances above the tuned one, as an oscillator
/// of the air (docs/design.md, "Resonator tubes"): near its resonance the
/// mouth's impedance `Z_par` is the Foster term `(1 / C) s / (s^2 +
/// Omega^2)` of an air mass `L` and a compliance `C` (`Omega^2 = 1 / (L
/// C)`), so the mouth's pressure is `(X - xi) / C` with `X` the volume the
/// bar pushes into the mouth and `xi` the volume the air mass has moved
/// (`L xi'' = (X - xi) / C`). With `eta = sqrt(L) xi` the tube mode is a
/// unit-mass oscillator coupled to a bar mode of weight `phi` at the
/// tube's axis through the potential `(S_c phi q - eta / sqrt(L))^2 / (2
/// C)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TubeMode {
    /// The lossless resonance `Omega / (2 pi)` \[Hz\] (a root of `Z_t + Z_r`
    /// without losses or radiation resistance).
    pub lossless_hz: f64,
    /// The resonance with the walls' and the mouth's losses \[Hz\].
    pub freq_hz: f64,
    /// Its decay rate \[1/s\] (the wall losses and the radiation
    /// resistance of the open end).
    pub decay_rate_per_s: f64,
    /// `1 / C` \[Pa/m^3\]: the Foster residue of `Z_par` at `Omega`.
    pub stiffness: f64,
    /// `L = 1 / (C Omega^2)` \[kg/m^4\].
    pub inertance: f64,
    /// The monopole it radiates per unit of its coordinate `eta`, in the
    /// units of [`ModeEffect::far_field`].
    pub far_field: (f64, f64),
}

impl Resonator {
    /// The tube's own resonances above the tuned one (the roots of `Z_t +
    /// Z_r` with `k L` in `((j - 1) pi, (j - 1) pi + pi / 2)`, `j >= 2`: a
    /// closed tube's odd harmonics, each lowered by the end correction) up
    /// to `max_hz` and [`MAX_COMPACT_KA`]. `None` when a lossy root is not
    /// found (it always is for a valid tube: a defect, not bad input).
    pub fn own_modes(&self, max_hz: f64) -> Option<Vec<TubeMode>> {
        let (a, len, c) = (self.radius_m, self.length_m, SOUND_SPEED_M_PER_S);
        let z0 = self.z0();
        let mut out = Vec::new();
        for j in 2.. {
            // cot(theta) - x(theta a / L), decreasing from +inf to -x
            let g = |th: f64| 1.0 / th.tan() - reactance_ratio(th * a / len);
            let lo0 = (j - 1) as f64 * PI;
            let (mut lo, mut hi) = (lo0 + 1e-12, lo0 + PI / 2.0);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if g(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let th = 0.5 * (lo + hi);
            let omega = th * c / len;
            let ka = omega * a / c;
            let f = omega / (2.0 * PI);
            if ka > MAX_COMPACT_KA || f > max_hz {
                break;
            }
            let x = reactance_ratio(ka);
            // Z_par = Z_t Z_r / (Z_t + Z_r) near the root: Z_t Z_r = X_r^2,
            // Z_t + Z_r = i D'(Omega) (omega - Omega), D = X_r - Z0 cot(k L);
            // the Foster term is (1 / C) / (2 i (omega - Omega)) there
            let sin = th.sin();
            let d_slope = z0 * (reactance_ratio_slope(ka) * a / c + len / (c * sin * sin));
            let stiffness = 2.0 * (z0 * x) * (z0 * x) / d_slope;
            let inertance = stiffness / (omega * omega);
            let (root, slope) = self.lossy_root(omega)?;
            // the mouth's pressure -eta / (C sqrt(L)) per unit eta; the room
            // receives the monopole -p / Z_t (module docs), which at the
            // mode's own complex frequency, where Z_t = -Z_r, is the flow
            // p / Z_r through the open end; W = -i Q / (2 omega)
            let w_hz = root.re / (2.0 * PI);
            let q = C::new(-stiffness / inertance.sqrt(), 0.0) / self.radiation_at(root);
            // The losses are spread along the tube and over its open end,
            // not a damper on one air mass: the lossy Z_par's residue at the
            // root, Z_t Z_r / (Z_t + Z_r)' = -Z_r^2 / (Z_t + Z_r)', differs
            // from the damped oscillator's, (1 / C) omega* / (2 i
            // Omega_d), by a few per cent and a fraction of a radian; the
            // monopole takes their ratio, so the mode's sound is the exact
            // resonance's
            let zr = self.radiation_at(root);
            let exact = -(zr * zr) / slope;
            let lumped = C::new(stiffness, 0.0) * root / C::new(0.0, 2.0 * root.re);
            let w = C::new(0.0, -1.0) * q / (2.0 * root.re) * (exact / lumped);
            out.push(TubeMode {
                lossless_hz: f,
                freq_hz: w_hz,
                decay_rate_per_s: root.im,
                stiffness,
                inertance,
                far_field: (w.re, w.im),
            });
        }
        Some(out)
    }

    /// The open end's radiation impedance at a complex angular frequency
    /// (the continuation of [`Self::radiation_impedance`]).
    fn radiation_at(&self, w: C) -> C {
        let ka = w * (self.radius_m / SOUND_SPEED_M_PER_S);
        let d = C::new(1.0, 0.0) + ka * ka / 4.0;
        (ka * ka / 4.0 + C::new(0.0, END_CORRECTION) * ka) / d * self.z0()
    }

    /// The complex root `omega = Omega' + i sigma` of `Z_t + Z_r` near the
    /// lossless `omega0` (`e^{i omega t}`: `sigma > 0` decays), by Newton's
    /// method on the analytic continuation (the wall loss's `sqrt(f)`
    /// too), and the slope of `Z_t + Z_r` there.
    fn lossy_root(&self, omega0: f64) -> Option<(C, C)> {
        let (a, len, c) = (self.radius_m, self.length_m, SOUND_SPEED_M_PER_S);
        let z0 = self.z0();
        let f = |w: C| {
            // the wall loss at the complex frequency: sqrt(f) continued
            let alpha = (w / (2.0 * PI)).sqrt() * (WALL_LOSS / a);
            let kl = (w / c - C::new(0.0, 1.0) * alpha) * len;
            C::new(0.0, -z0) * kl.cos() / kl.sin() + self.radiation_at(w)
        };
        let mut w = C::new(omega0, 0.0);
        let h = 1e-6 * omega0;
        for _ in 0..50 {
            let fw = f(w);
            let df = (f(w + h) - f(w - h)) / (2.0 * h);
            let step = fw / df;
            w -= step;
            if !(w.re.is_finite() && w.im.is_finite()) {
                return None;
            }
            if step.norm() < 1e-13 * omega0 {
                let df = (f(w + h) - f(w - h)) / (2.0 * h);
                return (w.im > 0.0 && df.norm() > 0.0).then_some((w, df));
            }
        }
        None
    }

    /// The coupling `K = -S_c phi / (C sqrt(L))` of tube mode `m` and a
    /// mass-normalised bar mode of weight `phi` \[1/sqrt(kg)\] at the
    /// tube's axis, an entry of the joint stiffness matrix \[1/s^2\].
    pub fn coupling(&self, m: &TubeMode, phi: f64) -> f64 {
        -self.coupling_area_m2 * phi * m.stiffness / m.inertance.sqrt()
    }

    /// The first-order component of bar mode `(omega_bar, phi)` in tube
    /// mode `m`'s eigenvector, `K / (Omega^2 - omega_bar^2)`
    /// (dimensionless; each coordinate of unit mass).
    pub fn mixing(&self, m: &TubeMode, omega_bar: f64, phi: f64) -> f64 {
        let om = 2.0 * PI * m.lossless_hz;
        self.coupling(m, phi) / (om * om - omega_bar * omega_bar)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::model::LN_1000;

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

    /// `Z_par = Z_t Z_r / (Z_t + Z_r)` in closed form, `lossless` without
    /// the wall losses and the radiation resistance.
    fn z_par(r: &Resonator, f: f64, lossless: bool) -> C {
        let (zt, zr) = if lossless {
            let k = 2.0 * PI * f / SOUND_SPEED_M_PER_S;
            (
                C::new(0.0, -r.z0() / (k * r.length_m).tan()),
                C::new(0.0, reactance_ratio(k * r.radius_m) * r.z0()),
            )
        } else {
            (r.tube_impedance(f), r.radiation_impedance(f))
        };
        zt * zr / (zt + zr)
    }

    /// The tube's own modes against the closed form of the mouth's
    /// impedance: each lies at a pole of the lossless `Z_par`, near a
    /// closed tube's odd harmonic; its residue is the Foster term's `1 /
    /// (2 C)` (the limit of `i (omega - Omega) Z_par`); its decay rate is
    /// half the -3 dB width of the lossy `|Z_par|^2` along the real axis.
    #[test]
    fn the_tubes_own_modes_are_the_poles_of_the_mouths_impedance() {
        let r = marimba_a3();
        let modes = r.own_modes(20_000.0).unwrap();
        let top = MAX_COMPACT_KA * SOUND_SPEED_M_PER_S / (2.0 * PI * r.radius_m);
        println!("{} modes below ka = 1 ({top:.0} Hz)", modes.len());
        assert_eq!(modes.len(), 3, "660, 1100, 1540 Hz, not 1980");
        for (j, m) in modes.iter().enumerate() {
            let odd = (2 * j + 3) as f64;
            assert!(m.lossless_hz < odd * 220.0 * 1.02 && m.lossless_hz > odd * 220.0 * 0.9);
            // the residue, from both sides of the pole
            for eps in [1e-7, -1e-7] {
                let f = m.lossless_hz * (1.0 + eps);
                let res = C::new(0.0, 2.0 * PI * (f - m.lossless_hz)) * z_par(&r, f, true);
                let rel = (res.re - 0.5 * m.stiffness).abs() / (0.5 * m.stiffness);
                println!(
                    "mode {}: {:.3} Hz (odd harmonic {odd}: {:.4} x 220), 1/C {:.4e} Pa/m^3, \
                     residue rel. error {rel:.2e} (side {eps:+})",
                    j + 2,
                    m.lossless_hz,
                    m.lossless_hz / 220.0,
                    m.stiffness
                );
                assert!(rel < 1e-5, "{rel:e}");
                assert!(res.im.abs() < 1e-5 * m.stiffness);
            }
            // the lossy resonance from the closed form on the real axis
            // alone (the wall loss at each frequency, not frozen at the
            // mode's): `Z_t + Z_r` through three frequencies a quarter
            // half-width apart as a quadratic in omega, and its root near
            // them
            let d = 0.25 * m.decay_rate_per_s;
            let w0 = 2.0 * PI * m.freq_hz;
            let g = |w: f64| {
                let f = w / (2.0 * PI);
                r.tube_impedance(f) + r.radiation_impedance(f)
            };
            let (ga, gb, gc) = (g(w0 - d), g(w0), g(w0 + d));
            // g(w0 + t d) = gb + t (gc - ga) / 2 + t^2 (gc - 2 gb + ga) / 2
            let (c1, c2) = ((gc - ga) * 0.5, (gc - gb * 2.0 + ga) * 0.5);
            let disc = (c1 * c1 - c2 * gb * 4.0).sqrt();
            let t = [(-c1 + disc) / (c2 * 2.0), (-c1 - disc) / (c2 * 2.0)];
            let t = if t[0].norm() < t[1].norm() {
                t[0]
            } else {
                t[1]
            };
            let root = C::new(w0, 0.0) + t * d;
            println!(
                "   lossy {:.3} Hz, sigma {:.4} 1/s (T60 {:.3} s); from the real axis {:.3} Hz, {:.4} 1/s",
                m.freq_hz,
                m.decay_rate_per_s,
                LN_1000 / m.decay_rate_per_s,
                root.re / (2.0 * PI),
                root.im
            );
            // (the quadratic's own error, extrapolating a decay rate's
            // distance off the axis from a quarter of it, is a few parts in
            // 10^3)
            assert!((root.re - w0).abs() < 3e-5 * w0);
            assert!((root.im - m.decay_rate_per_s).abs() < 2e-2 * m.decay_rate_per_s);
            assert!(m.inertance > 0.0 && m.decay_rate_per_s > 0.0);
        }
    }

    /// Each tube mode's monopole is the exact lossy resonance's (the
    /// residue of the closed form's `Z_par` at its complex frequency), and
    /// its first-order eigenvector components are those of the joint
    /// stiffness matrix's eigenvector.
    #[test]
    fn a_tube_mode_radiates_and_couples_as_the_closed_form() {
        let r = marimba_a3();
        let modes = r.own_modes(20_000.0).unwrap();
        for m in &modes {
            // the residue of the lossy Z_par at the mode's complex frequency
            // (Z_t Z_r / (Z_t + Z_r)', the derivative by central
            // differences on the real axis beside it) against the lossy
            // Foster term's, (1 / C) omega* / (2 i Omega_d)
            let w0 = 2.0 * PI * m.freq_hz;
            let sigma = m.decay_rate_per_s;
            let root = C::new(w0, sigma);
            let zt = |w: C| {
                let alpha = (w / (2.0 * PI)).sqrt() * (WALL_LOSS / r.radius_m);
                let kl = (w / SOUND_SPEED_M_PER_S - C::new(0.0, 1.0) * alpha) * r.length_m;
                C::new(0.0, -r.z0()) * kl.cos() / kl.sin()
            };
            let h = 1e-4 * w0;
            let sum = |w: C| zt(w) + r.radiation_at(w);
            let slope = (sum(root + h) - sum(root - h)) / (2.0 * h);
            let res = zt(root) * r.radiation_at(root) / slope;
            let foster = C::new(m.stiffness, 0.0) * root / C::new(0.0, 2.0 * (w0 * w0).sqrt());
            let rel = (res - foster).norm() / foster.norm();
            println!(
                "{:.1} Hz: residue of Z_par {res:.5e}, Foster term {foster:.5e}, rel {rel:.2e}; \
                 W per unit eta {:.4e} {:+.4e}i",
                m.freq_hz, m.far_field.0, m.far_field.1
            );
            // the tube's losses are spread along it and over its open end,
            // not a damper on one air mass: against the lumped oscillator's
            // they turn the residue by 0.3 to 0.6 radian and scale it by 3
            // to 15 per cent
            // (the monopole takes the ratio: the tube mode's sound is the
            // exact resonance's)
            let ratio = res / foster;
            let q = C::new(-m.stiffness / m.inertance.sqrt(), 0.0) / r.radiation_at(root);
            let lumped_w = C::new(0.0, -1.0) * q / (2.0 * w0);
            let w = C::new(m.far_field.0, m.far_field.1);
            println!(
                "   exact / lumped residue {:.4} at {:+.3} rad; W / lumped W {:.4} at {:+.3} rad",
                ratio.norm(),
                ratio.arg(),
                (w / lumped_w).norm(),
                (w / lumped_w).arg()
            );
            assert!((w / lumped_w - ratio).norm() < 1e-6);
            assert!(
                (ratio.norm() - 1.0).abs() < 0.2 && ratio.arg().abs() < 1.0,
                "{ratio}"
            );
            // the flow out of the open end at the root is -p / Z_t
            assert!((zt(root) + r.radiation_at(root)).norm() < 1e-9 * r.z0());
        }
        // first-order eigenvectors against the joint stiffness matrix of a
        // bar tuned 1:4:10 (weights 2, -1.5, 1 at the axis) and the tube modes
        let bar = [(220.0, 2.0), (880.0, -1.5), (2200.0, 1.0)];
        let n = bar.len() + modes.len();
        let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
        for (i, (f, phi)) in bar.iter().enumerate() {
            k[(i, i)] += (2.0 * PI * f).powi(2);
            for (j, m) in modes.iter().enumerate() {
                let jj = bar.len() + j;
                let c = r.coupling(m, *phi);
                k[(i, jj)] = c;
                k[(jj, i)] = c;
                for (i2, (_, phi2)) in bar.iter().enumerate() {
                    // the compression term (S_c phi)(S_c phi2) / C
                    k[(i, i2)] += r.coupling_area_m2.powi(2) * phi * phi2 * m.stiffness;
                }
                k[(jj, jj)] = (2.0 * PI * m.lossless_hz).powi(2);
            }
        }
        let eig = nalgebra::SymmetricEigen::new(k);
        for (j, m) in modes.iter().enumerate() {
            let jj = bar.len() + j;
            let col = (0..n)
                .max_by(|&a, &b| {
                    eig.eigenvectors[(jj, a)]
                        .abs()
                        .total_cmp(&eig.eigenvectors[(jj, b)].abs())
                })
                .unwrap();
            let v = eig.eigenvectors.column(col);
            let v = v / v[jj];
            for (i, (f, phi)) in bar.iter().enumerate() {
                let first = r.mixing(m, 2.0 * PI * f, *phi);
                let err = (v[i] - first).abs();
                println!(
                    "tube mode {:.0} Hz on bar mode {f} Hz: first order {first:+.4e}, exact {:+.4e}",
                    m.lossless_hz, v[i]
                );
                assert!(first.abs() < MAX_MIXING);
                assert!(err < 0.05 * first.abs() + 1e-9, "{err:e}");
            }
        }
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
