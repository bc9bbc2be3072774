//! A thin rectangular plate (Kirchhoff), isotropic, with simply supported
//! or free edges: its modes in ascending frequency.
//!
//! # Rectangular plates (Kirchhoff)
//!
//! Sides `a` (x), `b` (y), thickness `h`, flexural rigidity `D = E h^3 /
//! (12 (1 - nu^2))`, points `(x, y)` in `[0, a] x [0, b]`.
//!
//! - Simply supported (exact): `omega_mn = pi^2 (m^2 / a^2 + n^2 / b^2)
//!   sqrt(D / (rho h))`, `m, n >= 1`, `Phi = 2 / sqrt(rho h a b) sin(m pi x /
//!   a) sin(n pi y / b)`.
//! - Free edges (**approximate**, Warburton 1954 as given by Leissa,
//!   *Vibration of Plates*, NASA SP-160, 1969): `omega_mn = (pi^2 / a^2)
//!   sqrt(D / (rho h)) sqrt(lambda^2)`, `lambda^2 = G_x^4 + G_y^4 (a/b)^4 + 2
//!   (a/b)^2 (nu H_x H_y + (1 - nu) J_x J_y)`, with for index `m` (number of
//!   nodal lines across x; the same for `n`, y):
//!   `m = 0`: `G = H = J = 0`; `m = 1`: `G = H = 0`, `J = 12 / pi^2`;
//!   `m = 2`: `G = 1.506`, `H = 1.248`, `J = 5.017`; `m >= 3`: `G = m - 1/2`,
//!   `H = (m - 1/2)^2 (1 - 4 / ((2m - 1) pi))`, `J = (m - 1/2)^2 (1 + 12 /
//!   ((2m - 1) pi))`. Modes `(0,0)`, `(0,1)`, `(1,0)` are rigid and left out;
//!   `(1,1)` is the twisting mode. Shapes are products of free-free beam
//!   functions `Phi = X_m(x) Y_n(y) / sqrt(rho h a b)` with `X_0 = 1`, `X_1 =
//!   sqrt(3) (1 - 2 x / a)`, `X_m` (m >= 2) the free-free beam function of
//!   root `m - 1` (each with `integral X^2 = a`): exactly mass normalised and
//!   orthogonal, but not exact plate modes. For a square plate (`nu = 0.3`)
//!   the frequencies are within about 5 % of Leissa's exact values for the
//!   twisting and (1,2) modes, while the (0,2)/(2,0) pair, which the real
//!   plate mixes into two modes of different frequency (19.6 and 24.3 in
//!   units of `sqrt(D / (rho h)) / a^2`), gets one frequency (22.4) between
//!   them. Needs `0 <= nu < 0.5`.

use std::f64::consts::PI;

use super::beam::{BeamFn, BeamSupport};
use super::check::{check_limits, positive};
use super::mode::{ModeLabel, ModeShape, ShapeMode};
use super::search::lattice_ascending;
use crate::bodies::materials::Material;

/// Edge conditions of a rectangular plate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlateEdges {
    /// All four edges simply supported (exact closed form).
    SimplySupported,
    /// All four edges free (Warburton's approximation).
    Free,
}

/// A thin rectangular plate (Kirchhoff), isotropic.
#[derive(Debug, Clone, PartialEq)]
pub struct Plate {
    /// Side `a` along x \[m\].
    pub length_x_m: f64,
    /// Side `b` along y \[m\].
    pub length_y_m: f64,
    /// Thickness `h` \[m\].
    pub thickness_m: f64,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` \[Pa\].
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio `nu`, `-1 < nu < 0.5` (free edges: `0 <= nu < 0.5`).
    pub poisson_ratio: f64,
    /// Edge conditions.
    pub edges: PlateEdges,
}

/// Warburton's `(G, H, J)` of a free-free direction, index `m`.
fn warburton_free(m: usize) -> (f64, f64, f64) {
    match m {
        0 => (0.0, 0.0, 0.0),
        1 => (0.0, 0.0, 12.0 / (PI * PI)),
        2 => (1.506, 1.248, 5.017),
        _ => {
            let g = m as f64 - 0.5;
            let q = (2.0 * m as f64 - 1.0) * PI;
            (g, g * g * (1.0 - 4.0 / q), g * g * (1.0 + 12.0 / q))
        }
    }
}

fn free_beam_fn(m: usize) -> BeamFn {
    match m {
        0 => BeamFn::Rigid0,
        1 => BeamFn::Rigid1,
        _ => BeamFn::elastic(BeamSupport::FreeFree, m - 1),
    }
}

impl Plate {
    /// A plate of `material` (density, `E`, `nu`).
    pub fn new(
        length_x_m: f64,
        length_y_m: f64,
        thickness_m: f64,
        material: &Material,
        edges: PlateEdges,
    ) -> Self {
        Plate {
            length_x_m,
            length_y_m,
            thickness_m,
            density_kg_m3: material.density_kg_m3,
            youngs_modulus_pa: material.youngs_modulus_pa,
            poisson_ratio: material.poisson_ratio,
            edges,
        }
    }

    /// Check every field; errors name it.
    pub fn validate(&self) -> Result<(), String> {
        positive("plate.length_x_m", self.length_x_m)?;
        positive("plate.length_y_m", self.length_y_m)?;
        positive("plate.thickness_m", self.thickness_m)?;
        positive("plate.density_kg_m3", self.density_kg_m3)?;
        positive("plate.youngs_modulus_pa", self.youngs_modulus_pa)?;
        let nu = self.poisson_ratio;
        let lo = match self.edges {
            PlateEdges::SimplySupported => -1.0,
            PlateEdges::Free => 0.0,
        };
        let ok = match self.edges {
            PlateEdges::SimplySupported => nu > -1.0 && nu < 0.5,
            PlateEdges::Free => (0.0..0.5).contains(&nu),
        };
        if !ok {
            return Err(format!(
                "plate.poisson_ratio: must be in {}{lo}, 0.5) for {:?} edges, got {nu}",
                if lo < 0.0 { "(" } else { "[" },
                self.edges
            ));
        }
        Ok(())
    }

    /// Flexural rigidity `D = E h^3 / (12 (1 - nu^2))` \[N m\].
    pub fn flexural_rigidity(&self) -> f64 {
        self.youngs_modulus_pa * self.thickness_m.powi(3)
            / (12.0 * (1.0 - self.poisson_ratio * self.poisson_ratio))
    }

    /// Mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.thickness_m * self.length_x_m * self.length_y_m
    }

    /// Modes up to `max_freq_hz`, at most `max_count`, lowest first.
    pub fn modes(&self, max_freq_hz: f64, max_count: usize) -> Result<Vec<ShapeMode>, String> {
        self.validate()?;
        check_limits(max_freq_hz, max_count)?;
        let (a, b) = (self.length_x_m, self.length_y_m);
        let rho_h = self.density_kg_m3 * self.thickness_m;
        let speed = (self.flexural_rigidity() / rho_h).sqrt();
        let scale_ss = 2.0 / (rho_h * a * b).sqrt();
        let scale_free = 1.0 / (rho_h * a * b).sqrt();
        let nu = self.poisson_ratio;
        let edges = self.edges;
        let freq = move |m: usize, n: usize| -> f64 {
            match edges {
                PlateEdges::SimplySupported => {
                    let (m, n) = (m as f64, n as f64);
                    PI * PI * (m * m / (a * a) + n * n / (b * b)) * speed / (2.0 * PI)
                }
                PlateEdges::Free => {
                    let (gx, hx, jx) = warburton_free(m);
                    let (gy, hy, jy) = warburton_free(n);
                    let r = a / b;
                    let l2 = gx.powi(4)
                        + gy.powi(4) * r.powi(4)
                        + 2.0 * r * r * (nu * hx * hy + (1.0 - nu) * jx * jy);
                    PI * PI / (a * a) * speed * l2.sqrt() / (2.0 * PI)
                }
            }
        };
        let start = match edges {
            PlateEdges::SimplySupported => 1,
            PlateEdges::Free => 0,
        };
        let mut out = Vec::new();
        if max_count == 0 {
            return Ok(out);
        }
        lattice_ascending(
            start,
            start,
            |m, n| Ok(freq(m, n)),
            |m, n, f| {
                if f > max_freq_hz {
                    return false;
                }
                let rigid = edges == PlateEdges::Free && m + n < 2;
                if !rigid {
                    let shape = match edges {
                        PlateEdges::SimplySupported => ModeShape::PlateSs {
                            a,
                            b,
                            m,
                            n,
                            scale: scale_ss,
                        },
                        PlateEdges::Free => ModeShape::PlateFree {
                            fx: free_beam_fn(m),
                            fy: free_beam_fn(n),
                            a,
                            b,
                            scale: scale_free,
                        },
                    };
                    out.push(ShapeMode {
                        freq_hz: f,
                        label: ModeLabel::Plate { m, n },
                        shape,
                    });
                }
                out.len() < max_count
            },
        )?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;
    use crate::bodies::shapes::test_support::{composite, gram, identity_residual};
    use crate::bodies::shapes::Point;

    fn plate_gram(p: &Plate, modes: &[ShapeMode], panels: usize) -> Vec<Vec<f64>> {
        let qx = composite(0.0, p.length_x_m, panels);
        let qy = composite(0.0, p.length_y_m, panels);
        let rho_h = p.density_kg_m3 * p.thickness_m;
        let mut w = Vec::new();
        let mut pts = Vec::new();
        for &(x, wx) in &qx {
            for &(y, wy) in &qy {
                pts.push(Point::Plane { x, y });
                w.push(rho_h * wx * wy);
            }
        }
        let vals: Vec<Vec<f64>> = modes
            .iter()
            .map(|m| pts.iter().map(|&p| m.shape_at(p).unwrap()).collect())
            .collect();
        gram(&vals, &w)
    }

    #[test]
    fn simply_supported_plate_matches_the_closed_form() {
        let steel = material("steel").unwrap();
        let p = Plate::new(0.5, 0.3, 0.002, &steel, PlateEdges::SimplySupported);
        let modes = p.modes(f64::INFINITY, 40).unwrap();
        // Closed form, computed independently over a 40 x 40 grid and sorted.
        let d = steel.youngs_modulus_pa * 0.002f64.powi(3) / (12.0 * (1.0 - 0.29f64 * 0.29));
        let c = (d / (steel.density_kg_m3 * 0.002)).sqrt();
        let mut all = Vec::new();
        for m in 1..=40 {
            for n in 1..=40 {
                let (mf, nf) = (m as f64, n as f64);
                all.push(PI / 2.0 * (mf * mf / 0.25 + nf * nf / 0.09) * c);
            }
        }
        all.sort_by(f64::total_cmp);
        let mut worst: f64 = 0.0;
        for (m, want) in modes.iter().zip(&all) {
            worst = worst.max((m.freq_hz / want - 1.0).abs());
        }
        println!(
            "SS plate: f11 = {:.3} Hz, 40 modes, worst rel residual vs closed form {worst:.1e}",
            modes[0].freq_hz
        );
        assert!(worst < 1e-14);
        assert_eq!(modes[0].label, ModeLabel::Plate { m: 1, n: 1 });
        let g = plate_gram(&p, &modes[..12], 8);
        assert!(identity_residual("SS plate", &g) < 1e-10);
        // Limits: by frequency.
        let f_lim = modes[9].freq_hz;
        assert_eq!(p.modes(f_lim, 100).unwrap().len(), 10);
    }

    #[test]
    fn free_plate_warburton_against_leissa_and_quadrature() {
        // Leissa (1969), square FFFF plate, nu = 0.3, omega a^2 sqrt(rho h /
        // D): 13.468 (twist), 19.596, 24.270 (the (2,0) -+ (0,2) pair),
        // 34.801 (double).
        let mut p = Plate::new(
            0.3,
            0.3,
            0.003,
            &material("aluminium").unwrap(),
            PlateEdges::Free,
        );
        p.poisson_ratio = 0.3;
        let unit = (p.flexural_rigidity() / (p.density_kg_m3 * p.thickness_m)).sqrt()
            / (p.length_x_m * p.length_x_m)
            / (2.0 * PI);
        let modes = p.modes(f64::INFINITY, 30).unwrap();
        let lam: Vec<f64> = modes.iter().map(|m| m.freq_hz / unit).collect();
        println!(
            "free plate: {:?}",
            modes
                .iter()
                .zip(&lam)
                .take(6)
                .map(|(m, l)| format!("{} {l:.3}", m.label))
                .collect::<Vec<_>>()
        );
        assert_eq!(modes[0].label, ModeLabel::Plate { m: 1, n: 1 });
        let twist = lam[0] / 13.468 - 1.0;
        assert!(twist.abs() < 0.06, "{twist}");
        assert!(lam[1] > 19.596 && lam[1] < 24.270 && (lam[1] - lam[2]).abs() < 1e-9);
        let l12 = lam[3] / 34.801 - 1.0;
        assert!(l12.abs() < 0.06, "{l12}");
        println!("free plate: twist rel {twist:+.3}, (1,2) rel {l12:+.3}");
        // No rigid modes; all labels distinct.
        assert!(modes
            .iter()
            .all(|m| !matches!(m.label, ModeLabel::Plate { m, n } if m + n < 2)));
        let g = plate_gram(&p, &modes[..12], 8);
        assert!(identity_residual("free plate", &g) < 1e-10);
        // nu < 0 is refused for free edges.
        p.poisson_ratio = -0.1;
        let err = p.modes(1e4, 5).unwrap_err();
        assert!(err.contains("plate.poisson_ratio"), "{err}");
    }
}
