//! A rectangular bar (xylophone, marimba, wood-block lips, kalimba
//! tine): its section (`A = b h`, `I = b h^3 / 12`, the polar moment
//! and Saint-Venant torsion constant) and its modes, listed by
//! `beam_modes.rs`.
//!
//! Torsion constant of a rectangle (`beam_modes.rs`, "Torsional modes"):
//! - Rectangle of sides `b >= h` (swap them otherwise): `K_t = beta b h^3`,
//!   `beta = 1/3 (1 - 192 / pi^5 (h / b) S)`, `S = sum_{n odd} tanh(n pi b /
//!   (2 h)) / n^5`, and `J_p = b h (b^2 + h^2) / 12`. `S` is summed as
//!   `lambda(5) - sum_{n odd} (1 - tanh z_n) / n^5`, `z_n = n pi b / (2 h)`,
//!   `lambda(5) = sum_{n odd} n^-5 = (31 / 32) zeta(5)`, `1 - tanh z = 2
//!   exp(-2 z) / (1 + exp(-2 z))`: the terms fall like `exp(-n pi)`, so a
//!   few terms reach full precision. `beta` = 0.1406 (square), 0.229 (`b / h
//!   = 2`), 0.312 (10), `-> 1/3` (thin strip).

use std::f64::consts::PI;

use super::beam::BeamSupport;
use super::beam_modes::{beam_modes, check_tuning, BeamData, ShearCorrection, TorsionData};
use super::check::positive;
use super::mode::ShapeMode;
use crate::bodies::materials::Material;

/// A rectangular bar bending across its thickness.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Width `b` \[m\] (not in the direction of vibration).
    pub width_m: f64,
    /// Thickness `h` \[m\] (in the direction of vibration).
    pub thickness_m: f64,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` along the bar \[Pa\].
    pub youngs_modulus_pa: f64,
    /// Boundary conditions.
    pub support: BeamSupport,
    /// Timoshenko correction (none: Euler-Bernoulli).
    pub shear: Option<ShearCorrection>,
    /// Target frequency ratios of the first bending modes (empty: uniform
    /// bar). See "Tuned (undercut) bars" in `beam_modes.rs`.
    pub tuning: Vec<f64>,
    /// With `tuning`: the tuned fundamental \[Hz\] (`None`: the uniform
    /// bar's).
    pub fundamental_hz: Option<f64>,
    /// Shear modulus `G` \[Pa\] of the torsional modes (none: bending
    /// only). See "Torsional modes" in `beam_modes.rs`.
    pub torsion: Option<f64>,
}

impl Bar {
    /// A uniform Euler-Bernoulli bar of `material` (density and `E`).
    pub fn new(
        length_m: f64,
        width_m: f64,
        thickness_m: f64,
        material: &Material,
        support: BeamSupport,
    ) -> Self {
        Bar {
            length_m,
            width_m,
            thickness_m,
            density_kg_m3: material.density_kg_m3,
            youngs_modulus_pa: material.youngs_modulus_pa,
            support,
            shear: None,
            tuning: Vec::new(),
            fundamental_hz: None,
            torsion: None,
        }
    }

    /// With the Timoshenko correction, shear modulus `G`, `kappa = 5/6`.
    pub fn with_timoshenko(mut self, shear_modulus_pa: f64) -> Self {
        self.shear = Some(ShearCorrection::rectangle(shear_modulus_pa));
        self
    }

    /// Tuned to the ratios `t_1 : t_2 : ...` of its first bending modes.
    pub fn with_tuning(mut self, ratios: &[f64]) -> Self {
        self.tuning = ratios.to_vec();
        self
    }

    /// A tuned bar's fundamental tuned to `hz` (see "Tuned (undercut) bars").
    pub fn with_fundamental(mut self, hz: f64) -> Self {
        self.fundamental_hz = Some(hz);
        self
    }

    /// With torsional modes (Saint-Venant), shear modulus `G`.
    pub fn with_torsion(mut self, shear_modulus_pa: f64) -> Self {
        self.torsion = Some(shear_modulus_pa);
        self
    }

    /// Polar moment of the section `J_p = b h (b^2 + h^2) / 12` \[m^4\].
    pub fn polar_moment_m4(&self) -> f64 {
        let (b, h) = (self.width_m, self.thickness_m);
        b * h * (b * b + h * h) / 12.0
    }

    /// Saint-Venant torsion constant `K_t = beta b h^3` (`b >= h`, see
    /// [`rectangle_torsion_coefficient`]) \[m^4\].
    pub fn torsion_constant_m4(&self) -> f64 {
        let long = self.width_m.max(self.thickness_m);
        let short = self.width_m.min(self.thickness_m);
        rectangle_torsion_coefficient(long, short) * long * short.powi(3)
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("bar.length_m", self.length_m)?;
        positive("bar.width_m", self.width_m)?;
        positive("bar.thickness_m", self.thickness_m)?;
        positive("bar.density_kg_m3", self.density_kg_m3)?;
        positive("bar.youngs_modulus_pa", self.youngs_modulus_pa)?;
        if let Some(s) = &self.shear {
            s.validate("bar")?;
        }
        if let Some(g) = self.torsion {
            positive("bar.torsion", g)?;
        }
        if let Some(f) = self.fundamental_hz {
            positive("bar.fundamental_hz", f)?;
            if self.tuning.is_empty() {
                return Err(
                    "bar.fundamental_hz: only a tuned bar (tuning) has a fundamental apart from its geometry"
                        .into(),
                );
            }
        }
        check_tuning("bar", &self.tuning)
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.length_m * self.width_m * self.thickness_m
    }

    /// Bending (and, when on, torsional) modes up to `max_freq_hz`, at most
    /// `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        let a = self.width_m * self.thickness_m;
        let i = self.width_m * self.thickness_m.powi(3) / 12.0;
        let rho_jp = self.density_kg_m3 * self.polar_moment_m4();
        beam_modes(
            &BeamData {
                owner: "bar",
                length: self.length_m,
                half_width: 0.5 * self.width_m,
                torsion: self.torsion.map(|g| TorsionData {
                    speed: (g * self.torsion_constant_m4() / rho_jp).sqrt(),
                    rho_jp,
                }),
                rho_a: self.density_kg_m3 * a,
                ei: self.youngs_modulus_pa * i,
                r2: i / a,
                support: self.support,
                shear_e: self
                    .shear
                    .map(|s| self.youngs_modulus_pa / (s.shear_coefficient * s.shear_modulus_pa)),
                tuning: &self.tuning,
                fundamental: self.fundamental_hz,
            },
            max_freq_hz,
            max_count,
        )
    }
}

/// `beta` of the Saint-Venant torsion constant `K_t = beta b h^3` of a
/// rectangle with sides `b >= h` (the sides are swapped when `b < h`):
/// `beta = 1/3 (1 - 192 / pi^5 (h / b) sum_{n odd} tanh(n pi b / (2 h)) /
/// n^5)`. 0.1406 for a square, `-> 1/3` for a thin strip. NaN unless both
/// sides are positive and finite.
pub fn rectangle_torsion_coefficient(b: f64, h: f64) -> f64 {
    if !(b.is_finite() && h.is_finite() && b > 0.0 && h > 0.0) {
        return f64::NAN;
    }
    let (b, h) = if b >= h { (b, h) } else { (h, b) };
    // lambda(5) = sum over odd n of n^-5 = (31/32) zeta(5).
    const ZETA5: f64 = 1.036_927_755_143_37;
    let lambda5 = 31.0 / 32.0 * ZETA5;
    // S = lambda(5) - sum_{n odd} (1 - tanh z_n) / n^5, 1 - tanh z = 2 e / (1
    // + e), e = exp(-2 z), 2 z_n = n pi b / h >= n pi.
    let mut tail = 0.0;
    let mut n = 1.0f64;
    loop {
        let e = (-n * PI * b / h).exp();
        let term = 2.0 * e / (1.0 + e) / n.powi(5);
        tail += term;
        if term <= 1e-18 * lambda5 {
            break;
        }
        n += 2.0;
    }
    let sum = lambda5 - tail;
    (1.0 - 192.0 / PI.powi(5) * (h / b) * sum) / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::shapes::test_support::rosewood_bar;

    #[test]
    fn free_free_frequency_ratios() {
        let modes = rosewood_bar().modes(f64::INFINITY, 4).unwrap();
        let f1 = modes[0].freq_hz;
        for (m, t) in modes[1..].iter().zip([2.756, 5.404, 8.933]) {
            let r = m.freq_hz / f1;
            println!(
                "{}: ratio {r:.5}, table {t}, residual {:.1e}",
                m.label,
                r - t
            );
            assert!((r - t).abs() < 6e-4, "{r}");
        }
    }

    #[test]
    fn rosewood_bar_fundamental_is_as_computed_by_hand() {
        // 0.4 x 0.06 x 0.02 m rosewood (rho 1000 kg/m^3, E 20 GPa), uniform,
        // free-free: r = h / sqrt(12) = 5.7735e-3 m, c = sqrt(E / rho) =
        // 4472.1 m/s, f1 = 4.7300^2 r c / (2 pi L^2) = 22.3733 * 5.7735e-3 *
        // 4472.1 / 1.00531 = 574.6 Hz (about D5). Over the published range of
        // Honduras rosewood (E 17-26 GPa, rho 900-1050 kg/m^3) f1 stays in
        // 517-691 Hz.
        let f1 = rosewood_bar().modes(f64::INFINITY, 1).unwrap()[0].freq_hz;
        println!("rosewood bar f1 = {f1:.3} Hz (hand: 574.6 Hz)");
        assert!((f1 / 574.6 - 1.0).abs() < 5e-4, "{f1}");
        assert!(f1 > 517.0 && f1 < 691.0);
    }

    #[test]
    fn torsion_coefficient_matches_the_published_table() {
        // Timoshenko & Goodier, Theory of Elasticity, sec. 109 (k_1 of the
        // rectangle); 0.1406 for the square to four places.
        for (ratio, want, tol) in [(1.0, 0.1406, 5e-5), (2.0, 0.229, 5e-4), (10.0, 0.312, 5e-4)] {
            let beta = rectangle_torsion_coefficient(ratio * 0.01, 0.01);
            println!(
                "torsion beta(b/h = {ratio}) = {beta:.6}, table {want}, residual {:.1e}",
                beta - want
            );
            assert!((beta - want).abs() < tol, "{beta}");
            // The sides may come in either order.
            assert_eq!(beta, rectangle_torsion_coefficient(0.01, ratio * 0.01));
        }
        // Against the series evaluated in 40-digit arithmetic (offline,
        // rounded to f64), and against the series summed directly here in
        // f64 (smallest terms first; the tail beyond n = 20001 is below
        // 1e-18).
        let reference = [
            (1.0, 0.1405770149551537),
            (1.25, 0.17173254224128393),
            (1.5, 0.19576070887554403),
            (2.0, 0.22868167711957077),
            (3.0, 0.2633169310015001),
            (5.0, 0.29131675418798886),
            (10.0, 0.3123250374572054),
            (100.0, 0.33123250374572044),
            (1000.0, 0.333123250374572),
        ];
        let mut worst_ref: f64 = 0.0;
        let mut worst_direct: f64 = 0.0;
        for (ratio, want) in reference {
            let beta = rectangle_torsion_coefficient(ratio, 1.0);
            worst_ref = worst_ref.max((beta - want).abs());
            let direct: f64 = (0..10_001)
                .rev()
                .map(|k| {
                    let n = (2 * k + 1) as f64;
                    (n * PI * ratio / 2.0).tanh() / n.powi(5)
                })
                .sum();
            let direct = (1.0 - 192.0 / PI.powi(5) / ratio * direct) / 3.0;
            worst_direct = worst_direct.max((beta - direct).abs());
        }
        println!(
            "torsion beta, b/h 1 to 1000: max |beta - 40-digit reference| {worst_ref:.1e}, \
             max |beta - direct f64 series| {worst_direct:.1e}"
        );
        assert!(worst_ref < 3e-16, "{worst_ref}");
        assert!(worst_direct < 1e-15, "{worst_direct}");
        // Thin strip: beta -> 1/3 - 0.21 h / b (192 lambda(5) / (3 pi^5) = 0.2101).
        let thin = rectangle_torsion_coefficient(1000.0, 1.0);
        assert!(
            (thin - (1.0 / 3.0 - 0.2101 / 1000.0)).abs() < 1e-7,
            "{thin}"
        );
        assert!(rectangle_torsion_coefficient(0.0, 1.0).is_nan());
        assert!(rectangle_torsion_coefficient(f64::NAN, 1.0).is_nan());
    }
}
