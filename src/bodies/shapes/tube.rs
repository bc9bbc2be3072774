//! A round tube (chime) or solid rod: its section (`A = pi (D^2 - d^2) /
//! 4`, `I = pi (D^4 - d^4) / 64`) and its modes, listed by
//! `beam_modes.rs`. Free-free by default; Cowper's shear coefficient for
//! the Timoshenko correction.
//!
//! Torsion (`beam_modes.rs`, "Torsional modes"):
//! - Tube: `K_t = J_p = pi (D^4 - d^4) / 32`, so `c_t = sqrt(G / rho)`.

use std::f64::consts::PI;

use super::beam::BeamSupport;
use super::beam_modes::{beam_modes, BeamData, ShearCorrection, TorsionData};
use super::check::{non_negative, positive};
use super::mode::ShapeMode;
use crate::bodies::materials::Material;

/// A round tube (chime) or, with inner diameter 0, a solid rod.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Outer diameter `D` \[m\].
    pub outer_diameter_m: f64,
    /// Inner diameter `d` \[m\], `0 <= d < D`.
    pub inner_diameter_m: f64,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` \[Pa\].
    pub youngs_modulus_pa: f64,
    /// Boundary conditions (chimes hang free: free-free).
    pub support: BeamSupport,
    /// Timoshenko correction (none: Euler-Bernoulli).
    pub shear: Option<ShearCorrection>,
    /// Shear modulus `G` \[Pa\] of the torsional modes (none: bending
    /// only). See "Torsional modes" in `beam_modes.rs`.
    pub torsion: Option<f64>,
}

impl Tube {
    /// A free-free Euler-Bernoulli tube of `material`.
    pub fn new(
        length_m: f64,
        outer_diameter_m: f64,
        inner_diameter_m: f64,
        material: &Material,
    ) -> Self {
        Tube {
            length_m,
            outer_diameter_m,
            inner_diameter_m,
            density_kg_m3: material.density_kg_m3,
            youngs_modulus_pa: material.youngs_modulus_pa,
            support: BeamSupport::FreeFree,
            shear: None,
            torsion: None,
        }
    }

    /// With the Timoshenko correction (Cowper's shear coefficient).
    pub fn with_timoshenko(mut self, shear_modulus_pa: f64, poisson_ratio: f64) -> Self {
        self.shear = Some(ShearCorrection::tube(
            shear_modulus_pa,
            poisson_ratio,
            self.outer_diameter_m,
            self.inner_diameter_m,
        ));
        self
    }

    /// With torsional modes, shear modulus `G`.
    pub fn with_torsion(mut self, shear_modulus_pa: f64) -> Self {
        self.torsion = Some(shear_modulus_pa);
        self
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("tube.length_m", self.length_m)?;
        positive("tube.outer_diameter_m", self.outer_diameter_m)?;
        non_negative("tube.inner_diameter_m", self.inner_diameter_m)?;
        if !(self.inner_diameter_m < self.outer_diameter_m) {
            return Err(format!(
                "tube.inner_diameter_m: must be < outer_diameter_m ({}), got {}",
                self.outer_diameter_m, self.inner_diameter_m
            ));
        }
        positive("tube.density_kg_m3", self.density_kg_m3)?;
        positive("tube.youngs_modulus_pa", self.youngs_modulus_pa)?;
        if let Some(s) = &self.shear {
            s.validate("tube")?;
        }
        if let Some(g) = self.torsion {
            positive("tube.torsion", g)?;
        }
        Ok(())
    }

    /// Cross-section area `pi (D^2 - d^2) / 4` \[m^2\].
    pub fn area_m2(&self) -> f64 {
        PI * (self.outer_diameter_m.powi(2) - self.inner_diameter_m.powi(2)) / 4.0
    }

    /// Second moment of area `pi (D^4 - d^4) / 64` \[m^4\].
    pub fn second_moment_m4(&self) -> f64 {
        PI * (self.outer_diameter_m.powi(4) - self.inner_diameter_m.powi(4)) / 64.0
    }

    /// Polar moment `J_p = pi (D^4 - d^4) / 32`, also the torsion constant
    /// `K_t` \[m^4\].
    pub fn polar_moment_m4(&self) -> f64 {
        PI * (self.outer_diameter_m.powi(4) - self.inner_diameter_m.powi(4)) / 32.0
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.area_m2() * self.length_m
    }

    /// Bending (and, when on, torsional) modes up to `max_freq_hz`, at most
    /// `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        let a = self.area_m2();
        let i = self.second_moment_m4();
        beam_modes(
            &BeamData {
                owner: "tube",
                length: self.length_m,
                half_width: 0.5 * self.outer_diameter_m,
                // K_t = J_p: c_t = sqrt(G / rho).
                torsion: self.torsion.map(|g| TorsionData {
                    speed: (g / self.density_kg_m3).sqrt(),
                    rho_jp: self.density_kg_m3 * self.polar_moment_m4(),
                }),
                rho_a: self.density_kg_m3 * a,
                ei: self.youngs_modulus_pa * i,
                // (D^2 + d^2) / 16, without the cancellation of I / A.
                r2: (self.outer_diameter_m.powi(2) + self.inner_diameter_m.powi(2)) / 16.0,
                support: self.support,
                shear_e: self
                    .shear
                    .map(|s| self.youngs_modulus_pa / (s.shear_coefficient * s.shear_modulus_pa)),
                tuning: &[],
                fundamental: None,
            },
            max_freq_hz,
            max_count,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;
    use crate::bodies::shapes::beam_root;
    use crate::bodies::shapes::test_support::{identity_residual, line_gram};

    #[test]
    fn aluminium_chime_is_as_computed_by_hand() {
        // 6061 tube, L = 1 m, D = 25.4 mm, wall 1.5 mm (d = 22.4 mm):
        // A = pi (D^2 - d^2) / 4 = 1.1263e-4 m^2, I = pi (D^4 - d^4) / 64 =
        // 8.0735e-9 m^4, r^2 = I / A = (D^2 + d^2) / 16 = 7.1683e-5 m^2,
        // c = sqrt(68.9e9 / 2700) = 5051.5 m/s,
        // f1 = 22.3733 * 8.4666e-3 * 5051.5 / (2 pi) = 152.29 Hz (about D3),
        // then 419.8, 823.0 Hz (ratios 2.756, 5.404).
        let al = material("aluminium").unwrap();
        let tube = Tube::new(1.0, 0.0254, 0.0224, &al);
        println!(
            "chime: A = {:.5e} m^2, I = {:.5e} m^4",
            tube.area_m2(),
            tube.second_moment_m4()
        );
        assert!((tube.area_m2() / 1.1263e-4 - 1.0).abs() < 1e-4);
        assert!((tube.second_moment_m4() / 8.0735e-9 - 1.0).abs() < 1e-4);
        let modes = tube.modes(1000.0, 10).unwrap();
        let f: Vec<f64> = modes.iter().map(|m| m.freq_hz).collect();
        println!("chime modes up to 1 kHz: {f:.2?}");
        assert_eq!(f.len(), 3);
        assert!((f[0] / 152.29 - 1.0).abs() < 3e-4, "{}", f[0]);
        assert!((f[1] / 419.8 - 1.0).abs() < 5e-4 && (f[2] / 823.0 - 1.0).abs() < 5e-4);
        // Mass normalisation of the tube by quadrature.
        let rho_a = al.density_kg_m3 * tube.area_m2();
        let g = line_gram(&modes, rho_a, 1.0, 64);
        assert!(identity_residual("tube", &g) < 1e-10);
        // Thin-walled tube: the Timoshenko correction is tiny for r/L ~ 0.008.
        // Timoshenko: a thin wall has a small Cowper coefficient (~0.53), so
        // E / (kappa G) ~ 5 and the first-order lowering s (1 + e) / 2, s =
        // (u_1 r / L)^2 = 1.60e-3, is ~4.8e-3.
        let timo = tube
            .clone()
            .with_timoshenko(al.shear_modulus_pa, al.poisson_ratio);
        let kappa = timo.shear.map(|s| s.shear_coefficient).unwrap();
        let t = timo.modes(1000.0, 3).unwrap();
        let low = 1.0 - t[0].freq_hz / f[0];
        let s = (beam_root(BeamSupport::FreeFree, 1) * 0.0254f64.hypot(0.0224) / 4.0).powi(2);
        let first = 0.5 * s * (1.0 + al.youngs_modulus_pa / (kappa * al.shear_modulus_pa));
        println!(
            "chime: kappa {kappa:.4}, Timoshenko lowers f1 by {low:.4e} (first order {first:.4e})"
        );
        assert!(kappa > 0.5 && kappa < 0.56);
        assert!(low > 0.0 && (low / first - 1.0).abs() < 0.02);
    }
}
