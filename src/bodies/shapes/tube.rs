//! A round tube (chime) or solid rod: its section (`A = pi (D^2 - d^2) /
//! 4`, `I = pi (D^4 - d^4) / 64`) and its modes, listed by
//! `beam_modes.rs`. Free-free by default; Cowper's shear coefficient for
//! the Timoshenko correction.
//!
//! Torsion (`beam_modes.rs`, "Torsional modes"):
//! - Tube: `K_t = J_p = pi (D^4 - d^4) / 32`, so `c_t = sqrt(G / rho)`.
//!
//! # Ovalling modes
//!
//! A tube's wall also bends round its circumference: the shell's
//! inextensional modes (Rayleigh, *The Theory of Sound*, 1877, section
//! 235; Soedel, *Vibrations of Shells and Plates*, ch. 5). With `n >= 2`
//! waves round the wall, radial motion `w = cos(n phi)` and tangential `v =
//! -sin(n phi) / n` (so the mid-surface does not stretch: `dv/dphi + w =
//! 0`), the same at every `x`, which free ends allow (a ring's in-plane
//! flexural modes, for a tube long against its radius with the wall in
//! plane strain):
//!
//! ```text
//! omega_n^2 = E h^2 n^2 (n^2 - 1)^2 / (12 rho (1 - nu^2) R^4 (n^2 + 1))
//! ```
//!
//! `h = (D - d) / 2` the wall, `R = (D + d) / 4` its mid-surface radius, `E`
//! the wall's modulus round the circumference (a wooden tube's is across
//! the grain). Mass normalised: the kinetic energy's `integral rho h (w^2
//! + v^2) R dphi dx = rho h R L pi (1 + 1 / n^2)` is 1. Each `n` has two
//! modes, `cos(n phi)` and its partner turned by a quarter wave. Thin-wall
//! theory: a wall thick against the radius (shear, rotary inertia) lowers
//! them, by a few per cent at `h / R = 0.2` (an estimate, not computed).
//! Free ends only; the modes with axial variation (Rayleigh's second
//! family, `w` linear in `x`) are not listed.

use std::f64::consts::PI;

use super::beam::BeamSupport;
use super::beam_modes::{beam_modes, BeamData, ShearCorrection, TorsionData};
use super::check::{non_negative, positive};
use super::mode::{ModeLabel, ModeShape, ShapeMode};
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
    /// The wall's modulus round the circumference \[Pa\] and Poisson's
    /// ratio of the ovalling modes (none: no ovalling modes). See
    /// "Ovalling modes" above.
    pub ovalling: Option<(f64, f64)>,
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
            ovalling: None,
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

    /// With ovalling modes: the wall's modulus `E` round the
    /// circumference and Poisson's ratio `nu`.
    pub fn with_ovalling(mut self, hoop_modulus_pa: f64, poisson_ratio: f64) -> Self {
        self.ovalling = Some((hoop_modulus_pa, poisson_ratio));
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
        if let Some((e, nu)) = self.ovalling {
            positive("tube.hoop_modulus_pa", e)?;
            if !(nu.is_finite() && (0.0..0.5).contains(&nu)) {
                return Err(format!("tube.poisson_ratio: must be in [0, 0.5), got {nu}"));
            }
            if self.inner_diameter_m <= 0.0 {
                return Err("tube.ovalling: a solid rod has no wall to oval".to_string());
            }
            if self.support != BeamSupport::FreeFree {
                return Err(
                    "tube.ovalling: ovalling modes are listed for free ends only".to_string(),
                );
            }
        }
        Ok(())
    }

    /// Frequency of ovalling mode `n` (`n >= 2`) \[Hz\], "Ovalling modes".
    pub fn ovalling_freq_hz(&self, n: usize) -> Option<f64> {
        let (e, nu) = self.ovalling?;
        let h = 0.5 * (self.outer_diameter_m - self.inner_diameter_m);
        let r = 0.25 * (self.outer_diameter_m + self.inner_diameter_m);
        let nf = n as f64;
        let w2 = e * h * h * nf * nf * (nf * nf - 1.0).powi(2)
            / (12.0 * self.density_kg_m3 * (1.0 - nu * nu) * r.powi(4) * (nf * nf + 1.0));
        Some(w2.sqrt() / (2.0 * PI))
    }

    /// Ovalling modes up to `max_freq_hz`, each `n` a `cos` and a `sin`
    /// partner, at most `max_count`.
    fn ring_modes(&self, max_freq_hz: f64, max_count: usize) -> Vec<ShapeMode> {
        let mut out = Vec::new();
        let h = 0.5 * (self.outer_diameter_m - self.inner_diameter_m);
        let r = 0.25 * (self.outer_diameter_m + self.inner_diameter_m);
        for n in 2.. {
            let Some(f) = self.ovalling_freq_hz(n) else {
                break;
            };
            if f > max_freq_hz || out.len() >= max_count {
                break;
            }
            let nf = n as f64;
            let mass = self.density_kg_m3 * h * r * self.length_m * PI * (1.0 + 1.0 / (nf * nf));
            for sine in [false, true] {
                out.push(ShapeMode {
                    freq_hz: f,
                    label: ModeLabel::Ring { n, sine },
                    shape: ModeShape::Ring {
                        length: self.length_m,
                        half_width: 0.5 * self.outer_diameter_m,
                        n,
                        sine,
                        scale: 1.0 / mass.sqrt(),
                    },
                });
            }
        }
        out
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

    /// Bending (and, when on, torsional and ovalling) modes up to
    /// `max_freq_hz`, at most `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        let a = self.area_m2();
        let i = self.second_moment_m4();
        let mut out = beam_modes(
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
        )?;
        if self.ovalling.is_some() {
            // each list holds its family's lowest `max_count`; stable: the
            // beam's modes first on a tie
            out.extend(self.ring_modes(max_freq_hz, max_count));
            out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
            out.truncate(max_count);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;
    use crate::bodies::shapes::beam_root;
    use crate::bodies::shapes::test_support::{identity_residual, line_gram};
    use crate::bodies::shapes::Point;

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

    /// The ring's strain and kinetic energies of a displacement `(w, v)`
    /// (radial, tangential) of the mid-line, from the deformed curve's
    /// geometry: its curvature and stretch by central differences over
    /// `n_pts` points, `U = (1/2) integral (D dkappa^2 + (E h / (1 - nu^2))
    /// eps^2) R dphi` and `T / omega^2 = (1/2) integral rho h (w^2 + v^2) R
    /// dphi`, per metre of tube.
    fn ring_energies(
        r: f64,
        (e, nu, rho, h): (f64, f64, f64, f64),
        wv: impl Fn(f64) -> (f64, f64),
        n_pts: usize,
    ) -> (f64, f64) {
        let delta = 1e-5 * r;
        let dphi = 2.0 * PI / n_pts as f64;
        // the curve at amplitude `a` of the displacement
        let at = |phi: f64, a: f64| {
            let (w, v) = wv(phi);
            let (s, c) = phi.sin_cos();
            // radial (sin, cos), tangential (cos, -sin) in (y, z)
            ((r + a * w) * s + a * v * c, (r + a * w) * c - a * v * s)
        };
        // curvature and stretch at `phi` by central differences
        let geometry = |phi: f64, a: f64| {
            let (p0, p1, p2) = (at(phi - dphi, a), at(phi, a), at(phi + dphi, a));
            let d1 = ((p2.0 - p0.0) / (2.0 * dphi), (p2.1 - p0.1) / (2.0 * dphi));
            let d2 = (
                (p2.0 - 2.0 * p1.0 + p0.0) / (dphi * dphi),
                (p2.1 - 2.0 * p1.1 + p0.1) / (dphi * dphi),
            );
            let speed = d1.0.hypot(d1.1);
            // the curve runs clockwise in (y, z): its curvature is -(y'z'' - z'y'') / |P'|^3
            (
                -(d1.0 * d2.1 - d1.1 * d2.0) / speed.powi(3),
                speed / r - 1.0,
            )
        };
        let bend = e * h.powi(3) / (12.0 * (1.0 - nu * nu));
        let (mut u, mut t) = (0.0, 0.0);
        for i in 0..n_pts {
            let phi = i as f64 * dphi;
            // the changes against the undeformed circle differenced alike
            // (its own truncation error cancels)
            let (k1, e1) = geometry(phi, delta);
            let (k0, e0) = geometry(phi, 0.0);
            let (dk, eps) = (k1 - k0, e1 - e0);
            u += 0.5 * (bend * dk * dk + e * h / (1.0 - nu * nu) * eps * eps) * r * dphi;
            let (w, v) = wv(phi);
            t += 0.5 * rho * h * (w * w + v * v) * delta * delta * r * dphi;
        }
        (u, t)
    }

    #[test]
    fn ovalling_modes_are_rayleighs_and_the_rings_geometry_agrees() {
        // Steel tube, D = 100 mm, d = 96 mm: h = 2 mm, R = (D + d) / 4 = 49 mm, L = 0.5
        // m, E = 200 GPa, rho = 7850, nu = 0.3. Rayleigh's omega_n^2 = E h^2
        // n^2 (n^2 - 1)^2 / (12 rho (1 - nu^2) R^4 (n^2 + 1)) by hand: 543.3668,
        // 1536.8733, 2946.8200, 4765.6417 Hz for n = 2..5; the ring's
        // published coefficients n (n^2 - 1) / sqrt(n^2 + 1) = 2.6833,
        // 7.5895, 14.552, 23.534 (Blevins, Formulas for Natural Frequency and
        // Mode Shape, ring in-plane flexure) give the same ratios. Mass of
        // mode 2: rho h R L pi (1 + 1/4) = 1.510517 kg.
        let tube = Tube {
            length_m: 0.5,
            outer_diameter_m: 0.1,
            inner_diameter_m: 0.096,
            density_kg_m3: 7850.0,
            youngs_modulus_pa: 200e9,
            support: BeamSupport::FreeFree,
            shear: None,
            torsion: None,
            ovalling: None,
        }
        .with_ovalling(200e9, 0.3);
        let hand = [543.3668, 1536.8733, 2946.8200, 4765.6417];
        let coef = [2.6833, 7.5895, 14.552, 23.534];
        for (k, (f, c)) in hand.iter().zip(coef).enumerate() {
            let got = tube.ovalling_freq_hz(k + 2).unwrap();
            println!("ovalling {}: {got:.3} Hz (hand {f:.3})", k + 2);
            assert!((got / f - 1.0).abs() < 1e-6);
            assert!((got / hand[0] / (c / coef[0]) - 1.0).abs() < 1e-4);
        }
        let modes = tube.modes(5000.0, 200).unwrap();
        let rings: Vec<&ShapeMode> = modes
            .iter()
            .filter(|m| matches!(m.label, ModeLabel::Ring { .. }))
            .collect();
        assert_eq!(rings.len(), 8, "n = 2..5, cos and sin");
        assert!(modes.windows(2).all(|w| w[0].freq_hz <= w[1].freq_hz));
        // Weights: on top (y = 0) the cos partner moves radially with its
        // whole scale, the same all along; the sin partner not at all.
        let scale2 = 1.0 / 1.510_517_f64.sqrt();
        for x in [0.0, 0.13, 0.5] {
            let c = rings[0].shape_at(Point::Line(x)).unwrap();
            let s = rings[1].shape_at(Point::Bar { x, y: 0.0 }).unwrap();
            assert!((c / scale2 - 1.0).abs() < 1e-5, "{c}");
            assert!(s.abs() < 1e-15);
        }
        // At the side (y = D/2, phi = 90 degrees) the motion across the
        // axis is the tangential part: -v = sin(n pi / 2) / n (cos partner).
        let side = rings[2].shape_at(Point::Bar { x: 0.2, y: 0.05 }).unwrap();
        let scale3 = 1.0 / (7850.0 * 0.002 * 0.049 * 0.5 * PI * (1.0 + 1.0 / 9.0)).sqrt();
        assert!((side / (scale3 * (1.5 * PI).sin() / 3.0) - 1.0).abs() < 1e-12);
        // The frequency again from the deformed ring's geometry (its change
        // of curvature and stretch, by differences), not from the formula.
        let (e, nu, rho, h, r) = (200e9, 0.3, 7850.0, 0.002, 0.049);
        let mut worst: f64 = 0.0;
        for n in 2..=5 {
            let nf = n as f64;
            for sine in [false, true] {
                let wv = |phi: f64| {
                    let (sn, cn) = (nf * phi).sin_cos();
                    if sine {
                        (sn, cn / nf)
                    } else {
                        (cn, -sn / nf)
                    }
                };
                let (u, t) = ring_energies(r, (e, nu, rho, h), wv, 8192);
                let f = (u / t).sqrt() / (2.0 * PI);
                let rel = f / tube.ovalling_freq_hz(n).unwrap() - 1.0;
                worst = worst.max(rel.abs());
            }
        }
        println!("ovalling from the ring's geometry: largest relative error {worst:.1e}");
        assert!(worst < 1e-5, "{worst}");
        // A stretching shape costs more: w = cos(n phi) with v = 0 (the mid-line
        // stretches) is far stiffer than Rayleigh's.
        let (u, t) = ring_energies(r, (e, nu, rho, h), |p| ((2.0 * p).cos(), 0.0), 8192);
        assert!((u / t).sqrt() / (2.0 * PI) > 5.0 * hand[0]);
        // Refused: a solid rod, ends that are not free, a bad modulus.
        let mut rod = tube.clone();
        rod.inner_diameter_m = 0.0;
        assert!(rod.modes(1e4, 10).unwrap_err().contains("tube.ovalling"));
        let mut held = tube.clone();
        held.support = BeamSupport::ClampedClamped;
        assert!(held.modes(1e4, 10).unwrap_err().contains("free ends"));
        let bad = tube.clone().with_ovalling(f64::NAN, 0.3);
        assert!(bad
            .modes(1e4, 10)
            .unwrap_err()
            .contains("tube.hoop_modulus_pa"));
    }
}
