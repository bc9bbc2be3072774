//! A stiff string with pinned ends: its modes, stretched by bending
//! stiffness.
//!
//! # Stiff string
//!
//! Length `L`, tension `T` \[N\], linear density `mu` \[kg/m\], bending
//! stiffness `E I` \[N m^2\], pinned (simply supported) ends, points `x` in
//! `[0, L]`: `f_n = n f_0 sqrt(1 + B n^2)`, `f_0 = sqrt(T / mu) / (2 L)`,
//! `B = pi^2 E I / (T L^2)` (exact for `mu y_tt = T y_xx - E I y_xxxx`
//! with `y = y_xx = 0` at both ends), `Phi = sqrt(2 / (mu L)) sin(n pi x /
//! L)`.

use std::f64::consts::PI;

use super::check::{check_limits, non_negative, positive};
use super::mode::{ModeLabel, ModeShape, ShapeMode};
use crate::bodies::materials::Material;

/// A string with bending stiffness, pinned ends.
#[derive(Debug, Clone, PartialEq)]
pub struct StiffString {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Tension `T` \[N\].
    pub tension_n: f64,
    /// Linear density `mu` \[kg/m\].
    pub linear_density_kg_m: f64,
    /// Bending stiffness `E I` \[N m^2\] (0: ideal string).
    pub bending_stiffness_n_m2: f64,
}

impl StiffString {
    /// A solid round wire of `material`: `mu = rho pi d^2 / 4`, `E I = E pi
    /// d^4 / 64`.
    pub fn round_wire(length_m: f64, tension_n: f64, diameter_m: f64, material: &Material) -> Self {
        StiffString {
            length_m,
            tension_n,
            linear_density_kg_m: material.density_kg_m3 * PI * diameter_m * diameter_m / 4.0,
            bending_stiffness_n_m2: material.youngs_modulus_pa * PI * diameter_m.powi(4) / 64.0,
        }
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("stiff_string.length_m", self.length_m)?;
        positive("stiff_string.tension_n", self.tension_n)?;
        positive("stiff_string.linear_density_kg_m", self.linear_density_kg_m)?;
        non_negative(
            "stiff_string.bending_stiffness_n_m2",
            self.bending_stiffness_n_m2,
        )?;
        Ok(())
    }

    /// `f_0 = sqrt(T / mu) / (2 L)` \[Hz\] (the ideal string's fundamental).
    pub fn ideal_fundamental_hz(&self) -> f64 {
        (self.tension_n / self.linear_density_kg_m).sqrt() / (2.0 * self.length_m)
    }

    /// Inharmonicity coefficient `B = pi^2 E I / (T L^2)`.
    pub fn inharmonicity(&self) -> f64 {
        PI * PI * self.bending_stiffness_n_m2 / (self.tension_n * self.length_m * self.length_m)
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.linear_density_kg_m * self.length_m
    }

    /// Modes up to `max_freq_hz`, at most `max_count`.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        check_limits(max_freq_hz, max_count)?;
        let f0 = self.ideal_fundamental_hz();
        let b = self.inharmonicity();
        let scale = (2.0 / (self.linear_density_kg_m * self.length_m)).sqrt();
        let mut out = Vec::new();
        for n in 1..=max_count {
            let nf = n as f64;
            let f = nf * f0 * (1.0 + b * nf * nf).sqrt();
            if f > max_freq_hz {
                break;
            }
            out.push(ShapeMode {
                freq_hz: f,
                label: ModeLabel::String { n },
                shape: ModeShape::String {
                    length: self.length_m,
                    n,
                    scale,
                },
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;
    use crate::bodies::shapes::test_support::{identity_residual, line_gram};
    use crate::bodies::shapes::Point;

    #[test]
    fn stiff_string_inharmonicity_pde_and_normalisation() {
        // Steel wire d = 1 mm, L = 0.65 m, T = 700 N: mu = 7870 pi (0.5e-3)^2
        // = 6.181e-3 kg/m, f0 = sqrt(700 / mu) / 1.3 = 258.9 Hz, EI = 205e9 pi
        // 1e-12 / 64 = 1.0063e-2 N m^2, B = pi^2 EI / (T L^2) = 3.358e-4 (the
        // order of piano strings' B, 1e-4..1e-3, Fletcher & Rossing ch. 12).
        let s = StiffString::round_wire(0.65, 700.0, 1e-3, &material("steel").unwrap());
        let b = s.inharmonicity();
        println!(
            "string: f0 = {:.2} Hz, B = {b:.4e}",
            s.ideal_fundamental_hz()
        );
        assert!((s.ideal_fundamental_hz() / 258.9 - 1.0).abs() < 5e-4);
        assert!((b / 3.358e-4 - 1.0).abs() < 1e-3);
        let modes = s.modes(f64::INFINITY, 30).unwrap();
        for m in &modes {
            let ModeLabel::String { n } = m.label else {
                unreachable!()
            };
            let nf = n as f64;
            // Inharmonicity: f_n / (n f_1) = sqrt((1 + B n^2) / (1 + B)).
            let r = m.freq_hz / (nf * modes[0].freq_hz);
            assert!((r - ((1.0 + b * nf * nf) / (1.0 + b)).sqrt()).abs() < 1e-14);
            // The PDE mu omega^2 phi = -T phi'' + EI phi'''' by finite
            // differences at an interior point.
            let x = 0.2371;
            let h = 2e-3 / nf;
            let p = |k: f64| m.shape_at(Point::Line(x + k * h)).unwrap();
            let d2 = (p(1.0) - 2.0 * p(0.0) + p(-1.0)) / (h * h);
            let d4 = (p(2.0) - 4.0 * p(1.0) + 6.0 * p(0.0) - 4.0 * p(-1.0) + p(-2.0)) / h.powi(4);
            let lhs = s.linear_density_kg_m * m.omega().powi(2) * p(0.0);
            let rhs = -s.tension_n * d2 + s.bending_stiffness_n_m2 * d4;
            let scale = s.linear_density_kg_m
                * m.omega().powi(2)
                * m.shape_at(Point::Line(0.0))
                    .unwrap()
                    .abs()
                    .max((2.0 / (s.linear_density_kg_m * 0.65)).sqrt());
            if n <= 10 {
                assert!((lhs - rhs).abs() < 1e-4 * scale, "n {n}: {lhs} vs {rhs}");
            }
        }
        let r30 = modes[29].freq_hz / (30.0 * modes[0].freq_hz);
        println!(
            "string: f30 / (30 f1) = {r30:.6} (stretch {:.2} cents)",
            1200.0 * r30.log2()
        );
        let g = line_gram(&modes[..15], s.linear_density_kg_m, 0.65, 32);
        assert!(identity_residual("stiff string", &g) < 1e-10);
        // B = 0: harmonic.
        let ideal = StiffString {
            bending_stiffness_n_m2: 0.0,
            ..s
        };
        let h = ideal.modes(f64::INFINITY, 5).unwrap();
        assert!((h[4].freq_hz / h[0].freq_hz - 5.0).abs() < 1e-14);
    }
}
