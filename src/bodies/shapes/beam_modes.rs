//! The modes of a bar or tube: bending modes (Euler-Bernoulli, with the
//! optional Timoshenko correction and the tuning of undercut bars) and
//! torsional modes, merged by frequency. The section's quantities come
//! from [`Bar`](super::Bar) and [`Tube`](super::Tube), the beam functions
//! from `beam.rs`.
//!
//! # Bars and tubes (Euler-Bernoulli, optional Timoshenko correction)
//!
//! Points are [`Point::Bar`](super::Point::Bar)`{ x, y }`: `x` along the
//! axis in `[0, L]`, `y` across the width from the centre line (`|y| <= b /
//! 2` for a bar, `<= D / 2` for a tube);
//! [`Point::Line`](super::Point::Line)`(x)` is the point `(x, 0)`. Bending
//! modes do not depend on `y`; torsional modes (below) do.
//!
//! Length `L`, density `rho`, Young's modulus `E`, cross-section area `A`,
//! second moment `I` about the bending axis (rectangle of width `b` and
//! thickness `h` in the direction of vibration: `A = b h`, `I = b h^3 / 12`;
//! tube of outer and inner diameters `D`, `d`: `A = pi (D^2 - d^2) / 4`,
//! `I = pi (D^4 - d^4) / 64`). Radius of gyration `r^2 = I / A`.
//!
//! `omega_n = (beta_n L)^2 / L^2 * sqrt(E I / (rho A))`, with `u_n = beta_n
//! L` the `n`-th root of the frequency equation of the supports, and shapes
//! `Phi = phi / sqrt(rho A L)`, `phi` the beam function normalised to
//! `integral_0^L phi^2 dx = L` (both in `beam.rs`).
//!
//! The free-free bar's two rigid-body modes are left out (a bar rests on
//! soft supports; their frequencies are the supports', not the bar's).
//!
//! **Timoshenko correction** (shear deformation and rotary inertia, shear
//! modulus `G`, shear coefficient `kappa`: 5/6 for a rectangle; Cowper's
//! `kappa = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu)
//! m^2)`, `m = d / D`, for a tube). The Timoshenko equations `rho A w_tt =
//! kappa G A (w_xx - psi_x)`, `rho I psi_tt = E I psi_xx + kappa G A (w_x -
//! psi)` give for a wave of wavenumber `k` the dispersion relation
//!
//! `(rho r^2 / (kappa G)) omega^4 - (1 + (k r)^2 (1 + E / (kappa G)))
//! omega^2 + omega_EB^2 = 0`, `omega_EB^2 = E I k^4 / (rho A)`.
//!
//! Each mode takes its Euler-Bernoulli wavenumber `k = beta_n` and the lower
//! (bending) root: with `s = (k r)^2`, `e = E / (kappa G)`, `B = 1 + s (1 +
//! e)`,
//!
//! `omega_T / omega_EB = sqrt(2 / (B + sqrt(B^2 - 4 e s^2)))  ~  1 - s (1 +
//! e) / 2` (first order).
//!
//! This is exact for simply supported ends; for free and clamped ends it
//! ignores the end correction of the Timoshenko boundary conditions
//! (approximate). Measured against ASTM E1876's correction factor `T1`
//! for the first free-free mode (Spinner-Tefft/Pickett), it overestimates the
//! frequency lowering by about 6.5 % of the lowering (isotropic, `nu =
//! 0.3`, `h / L` from 0.01 to 0.1, tested below): for a bar with `h / L =
//! 0.1` the lowering is 3.59 % instead of 3.38 %. Shapes stay the
//! Euler-Bernoulli ones. Clamped-clamped modes use the same wavenumber
//! `k = u_n / L` as the others.
//!
//! **Tuned (undercut) bars**: target ratios `t_1 : t_2 : ... : t_k` for the
//! first `k` bending modes, and optionally the frequency `F` the maker tunes
//! the fundamental to (the undercut lowers it below the uniform bar's).
//! Mode `i <= k` gets `F t_i / t_1` (`F` defaults to the uniform bar's
//! `f_1`); write `q_i = f_i^tuned / f_i^uniform` for its tuning factor. An
//! untuned mode `i > k` gets `q_i f_i^uniform` with
//! - with `F` given, `k >= 2` and `0 < r = (1 - q_k) / (1 - q_{k-1}) < 1`
//!   (the undercut lowers the lower modes more, as it does): `q_i = 1 - (1 -
//!   q_k) r^(i - k)`, the factor extrapolated geometrically towards 1 (an
//!   undercut at the centre changes the short waves of high modes less);
//! - otherwise `q_i = q_k`: the uniform bar's ratio to the last tuned mode.
//!
//! Shapes (and so weights) stay those of the uniform bar, and torsional
//! modes keep the uniform bar's frequencies. All of this is an estimate: a
//! real undercut moves nodes toward the centre, removes mass and changes the
//! weights.
//!
//! **Torsional modes** (off by default;
//! [`Bar::with_torsion`](super::Bar::with_torsion),
//! [`Tube::with_torsion`](super::Tube::with_torsion) with the shear modulus
//! `G`). Saint-Venant torsion of the twist angle `theta(x, t)`: `rho J_p
//! theta_tt = G K_t theta_xx`, with `J_p` the polar moment of the section
//! about the axis (rotary inertia per length `rho J_p`) and `K_t` the
//! torsion constant; wave speed `c_t = sqrt(G K_t / (rho J_p))`.
//!
//! The section's `K_t` and `J_p`:
//! [`Bar::torsion_constant_m4`](super::Bar::torsion_constant_m4) (a
//! rectangle, see `bar.rs`) and
//! [`Tube::polar_moment_m4`](super::Tube::polar_moment_m4) (`K_t = J_p`,
//! see `tube.rs`).
//!
//! Modes `n >= 1`, with `A = sqrt(2 / (rho J_p L))` so that `integral_0^L
//! rho J_p theta^2 dx = 1`:
//! - free-free: `f_n = n c_t / (2 L)`, `theta = A cos(n pi x / L)` (the rigid
//!   rotation is left out, like the rigid bending modes);
//! - clamped-free: `f_n = (2n - 1) c_t / (4 L)`, `theta = A sin((2n - 1) pi
//!   x / (2 L))`;
//! - clamped-clamped: `f_n = n c_t / (2 L)`, `theta = A sin(n pi x / L)`.
//!
//! A point at `(x, y)` moves in the direction of vibration (across the
//! thickness) by `Phi = y theta(x)`, the weight of the mode there; `y = 0`
//! (and so [`Point::Line`](super::Point::Line)) does not move. The sideways
//! motion `-z theta` of points off the mid-plane is not a weight. Over the
//! whole section `integral rho (y^2 + z^2) theta^2 dA dx = integral rho J_p
//! theta^2 dx = 1`, and a torsional mode is orthogonal to every bending mode
//! (its motion is odd in `y`, theirs even).
//!
//! Approximations: Saint-Venant theory lets the section warp freely and
//! uniformly. That is exact for a round tube, which does not warp; for a
//! rectangle it leaves out the warping stiffness (which raises the
//! frequencies, more for higher modes, short bars and woods with a large
//! `E / G`) and the warping inertia (which lowers them); neither is
//! quantified here. A wooden bar twists with both `G_LR` and `G_LT`; one `G`
//! is used. The Timoshenko correction does not apply to torsion. For a tuned
//! bar the torsional modes keep the uniform bar's frequencies (a real
//! undercut lowers them too). Bending and torsional modes are merged by
//! frequency (bending first on a tie) and `max_freq_hz` and `max_count`
//! apply to the merged list.

use std::f64::consts::PI;

use super::beam::{BeamFn, BeamSupport};
use super::check::{check_limits, positive};
use super::mode::{ModeLabel, ModeShape, ShapeMode};

/// Shear data for the Timoshenko correction of a bar or tube.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShearCorrection {
    /// Shear modulus `G` \[Pa\] (woods: `G_LR` or `G_LT`, by how the bar is cut).
    pub shear_modulus_pa: f64,
    /// Shear coefficient `kappa` (5/6 for a rectangle).
    pub shear_coefficient: f64,
}

impl ShearCorrection {
    /// Rectangular cross-section: `kappa = 5/6`.
    pub fn rectangle(shear_modulus_pa: f64) -> Self {
        ShearCorrection {
            shear_modulus_pa,
            shear_coefficient: 5.0 / 6.0,
        }
    }

    /// Hollow circular cross-section, Cowper's (1966) coefficient
    /// `kappa = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12
    /// nu) m^2)`, `m = d / D` (solid rod: `6 (1 + nu) / (7 + 6 nu)`).
    pub fn tube(
        shear_modulus_pa: f64,
        poisson_ratio: f64,
        outer_diameter_m: f64,
        inner_diameter_m: f64,
    ) -> Self {
        let m = inner_diameter_m / outer_diameter_m;
        let nu = poisson_ratio;
        let p = (1.0 + m * m).powi(2);
        ShearCorrection {
            shear_modulus_pa,
            shear_coefficient: 6.0 * (1.0 + nu) * p
                / ((7.0 + 6.0 * nu) * p + (20.0 + 12.0 * nu) * m * m),
        }
    }

    pub(super) fn validate(&self, owner: &str) -> Result<(), String> {
        positive(
            &format!("{owner}.shear.shear_modulus_pa"),
            self.shear_modulus_pa,
        )?;
        let k = self.shear_coefficient;
        if !(k.is_finite() && k > 0.0 && k <= 1.0) {
            return Err(format!(
                "{owner}.shear.shear_coefficient: must be in (0, 1], got {k}"
            ));
        }
        Ok(())
    }
}

/// `omega_T / omega_EB` for wavenumber `k`, radius of gyration squared `r2`
/// and `e = E / (kappa G)` (lower root of the Timoshenko dispersion relation).
pub fn timoshenko_ratio(k: f64, r2: f64, e: f64) -> f64 {
    let s = k * k * r2;
    let b = 1.0 + s * (1.0 + e);
    (2.0 / (b + (b * b - 4.0 * e * s * s).max(0.0).sqrt())).sqrt()
}

/// Torsion data of a bar or tube.
#[derive(Debug, Clone, Copy)]
pub(super) struct TorsionData {
    /// Wave speed `c_t = sqrt(G K_t / (rho J_p))` \[m/s\].
    pub(super) speed: f64,
    /// Rotary inertia per length `rho J_p` \[kg m\].
    pub(super) rho_jp: f64,
}

/// What bars and tubes share.
pub(super) struct BeamData<'a> {
    pub(super) owner: &'a str,
    pub(super) length: f64,
    /// Largest `|y|` of a point: `b / 2` or `D / 2`.
    pub(super) half_width: f64,
    pub(super) torsion: Option<TorsionData>,
    pub(super) rho_a: f64,
    pub(super) ei: f64,
    pub(super) r2: f64,
    pub(super) support: BeamSupport,
    /// `E / (kappa G)` when the Timoshenko correction is on.
    pub(super) shear_e: Option<f64>,
    pub(super) tuning: &'a [f64],
    pub(super) fundamental: Option<f64>,
}

pub(super) fn check_tuning(owner: &str, tuning: &[f64]) -> Result<(), String> {
    for (i, &t) in tuning.iter().enumerate() {
        positive(&format!("{owner}.tuning[{i}]"), t)?;
        if i > 0 && !(t > tuning[i - 1]) {
            return Err(format!(
                "{owner}.tuning[{i}]: ratios must increase strictly, got {t} after {}",
                tuning[i - 1]
            ));
        }
    }
    Ok(())
}

/// Bending and (when on) torsional modes, merged by frequency, then limited.
pub(super) fn beam_modes(
    d: &BeamData<'_>,
    max_freq_hz: f64,
    max_count: usize,
) -> Result<Vec<ShapeMode>, String> {
    check_limits(max_freq_hz, max_count)?;
    let mut out = bending_modes(d, max_freq_hz, max_count)?;
    if let Some(t) = d.torsion {
        // Each list holds its family's lowest `max_count` modes, so the
        // lowest `max_count` of the union are among them.
        out.extend(torsion_modes(d, t, max_freq_hz, max_count)?);
        // Stable: bending before torsion on a tie.
        out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
        out.truncate(max_count);
    }
    Ok(out)
}

/// Frequency \[Hz\] of torsional mode `n` for wave speed `c_t` and length `L`.
fn torsion_freq(support: BeamSupport, n: usize, speed: f64, length: f64) -> f64 {
    let n = n as f64;
    match support {
        BeamSupport::FreeFree | BeamSupport::ClampedClamped => n * speed / (2.0 * length),
        BeamSupport::ClampedFree => (2.0 * n - 1.0) * speed / (4.0 * length),
    }
}

fn torsion_modes(
    d: &BeamData<'_>,
    t: TorsionData,
    max_freq_hz: f64,
    max_count: usize,
) -> Result<Vec<ShapeMode>, String> {
    let scale = (2.0 / (t.rho_jp * d.length)).sqrt();
    let mut out = Vec::new();
    for n in 1..=max_count {
        let freq = torsion_freq(d.support, n, t.speed, d.length);
        if !(freq.is_finite() && scale.is_finite()) {
            return Err(format!(
                "{}: torsional mode {n} has a non-finite frequency ({freq}) or scale ({scale})",
                d.owner
            ));
        }
        if freq > max_freq_hz {
            break;
        }
        out.push(ShapeMode {
            freq_hz: freq,
            label: ModeLabel::Torsion { n },
            shape: ModeShape::Torsion {
                support: d.support,
                n,
                length: d.length,
                half_width: d.half_width,
                scale,
            },
        });
    }
    Ok(out)
}

fn bending_modes(
    d: &BeamData<'_>,
    max_freq_hz: f64,
    max_count: usize,
) -> Result<Vec<ShapeMode>, String> {
    let c = (d.ei / d.rho_a).sqrt();
    let scale = 1.0 / (d.rho_a * d.length).sqrt();
    let uniform = |f: &BeamFn| -> f64 {
        let u = match *f {
            BeamFn::Elastic { u, .. } => u,
            _ => 0.0,
        };
        let k = u / d.length;
        let ratio = d.shear_e.map_or(1.0, |e| timoshenko_ratio(k, d.r2, e));
        k * k * c * ratio / (2.0 * PI)
    };
    let k_tuned = d.tuning.len();
    let mut f1 = f64::NAN;
    // tuning factors q_i = f_i^tuned / f_i^uniform of the last two tuned modes
    let (mut q_prev, mut q_k) = (f64::NAN, f64::NAN);
    let mut out = Vec::new();
    for n in 1..=max_count {
        let f = BeamFn::elastic(d.support, n);
        let fu = uniform(&f);
        let freq = if k_tuned == 0 {
            fu
        } else if n <= k_tuned {
            if n == 1 {
                f1 = d.fundamental.unwrap_or(fu);
            }
            let t = f1 * d.tuning[n - 1] / d.tuning[0];
            q_prev = q_k;
            q_k = t / fu;
            t
        } else {
            let r = (1.0 - q_k) / (1.0 - q_prev);
            let q = if d.fundamental.is_some() && k_tuned >= 2 && r > 0.0 && r < 1.0 {
                1.0 - (1.0 - q_k) * r.powi((n - k_tuned) as i32)
            } else {
                q_k
            };
            q * fu
        };
        if !freq.is_finite() {
            return Err(format!(
                "{}: mode {n} has a non-finite frequency ({freq})",
                d.owner
            ));
        }
        if freq > max_freq_hz {
            break;
        }
        out.push(ShapeMode {
            freq_hz: freq,
            label: ModeLabel::Bending { n },
            shape: ModeShape::Beam {
                f,
                length: d.length,
                half_width: d.half_width,
                scale,
            },
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::{material, Material};
    use crate::bodies::shapes::test_support::{
        composite, gram, identity_residual, rosewood_bar, torsion_bar, torsion_only,
    };
    use crate::bodies::shapes::{
        beam_root, rectangle_torsion_coefficient, Bar, Point, Shape, Tube,
    };

    #[test]
    fn timoshenko_lowers_frequencies_by_the_expected_amount() {
        let al = material("aluminium").unwrap();
        let iso_g = |e: f64, nu: f64| e / (2.0 * (1.0 + nu));
        let nu = 0.3;
        let e = al.youngs_modulus_pa;
        for h_over_l in [0.01, 0.05, 0.1] {
            let l = 0.5;
            let bar = Bar {
                length_m: l,
                width_m: 0.03,
                thickness_m: h_over_l * l,
                density_kg_m3: al.density_kg_m3,
                youngs_modulus_pa: e,
                support: BeamSupport::FreeFree,
                shear: None,
                tuning: Vec::new(),
                fundamental_hz: None,
                torsion: None,
            };
            let eb = bar.modes(f64::INFINITY, 6).unwrap();
            let ti = bar
                .clone()
                .with_timoshenko(iso_g(e, nu))
                .modes(f64::INFINITY, 6)
                .unwrap();
            let mut last = 0.0;
            for (a, b) in eb.iter().zip(&ti) {
                let low = 1.0 - b.freq_hz / a.freq_hz;
                assert!(low > last, "lowering must grow with mode number");
                last = low;
                // First order: s (1 + E / (kappa G)) / 2.
                let u = beam_root(
                    BeamSupport::FreeFree,
                    match a.label {
                        ModeLabel::Bending { n } => n,
                        _ => unreachable!(),
                    },
                );
                let s = (u * h_over_l).powi(2) / 12.0;
                let first = 0.5 * s * (1.0 + 2.0 * (1.0 + nu) / (5.0 / 6.0));
                if h_over_l == 0.01 {
                    let rel = low / first - 1.0;
                    println!(
                        "h/L 0.01 {}: lowering {low:.4e}, first order {first:.4e}, rel {rel:.1e}",
                        a.label
                    );
                    assert!(rel.abs() < 0.02, "{rel}");
                }
            }
            // ASTM E1876 (Spinner & Tefft 1961): f_T = f_EB / sqrt(T1),
            // T1 = 1 + 6.585 (1 + 0.0752 nu + 0.8109 nu^2) t^2 - 0.868 t^4
            //   - 8.340 (1 + 0.2023 nu + 2.173 nu^2) t^4
            //     / (1 + 6.338 (1 + 0.1408 nu + 1.536 nu^2) t^2), t = h / L.
            let t = h_over_l;
            let t1 = 1.0 + 6.585 * (1.0 + 0.0752 * nu + 0.8109 * nu * nu) * t * t
                - 0.868 * t.powi(4)
                - 8.340 * (1.0 + 0.2023 * nu + 2.173 * nu * nu) * t.powi(4)
                    / (1.0 + 6.338 * (1.0 + 0.1408 * nu + 1.536 * nu * nu) * t * t);
            let astm = 1.0 - 1.0 / t1.sqrt();
            let ours = 1.0 - ti[0].freq_hz / eb[0].freq_hz;
            let rel = ours / astm - 1.0;
            println!(
                "h/L {h_over_l}: mode 1 lowered by {ours:.4e}, ASTM E1876 {astm:.4e}, rel {rel:+.3}"
            );
            assert!(rel.abs() < 0.1, "{rel}");
        }
        // A thick wooden bar (E / G ~ 14): a large correction, still lower.
        let rw = material("rosewood").unwrap();
        let bar = rosewood_bar();
        let eb = bar.modes(f64::INFINITY, 4).unwrap();
        let ti = bar
            .with_timoshenko(rw.shear_modulus_pa)
            .modes(f64::INFINITY, 4)
            .unwrap();
        let lows: Vec<f64> = eb
            .iter()
            .zip(&ti)
            .map(|(a, b)| 1.0 - b.freq_hz / a.freq_hz)
            .collect();
        println!("rosewood bar 0.4 x 0.02: Timoshenko lowering {lows:.4?}");
        assert!(lows[0] > 0.01 && lows[3] > lows[0]);
    }

    #[test]
    fn tuned_bar_reproduces_its_target_ratios() {
        let bar = rosewood_bar();
        let uniform = bar.modes(f64::INFINITY, 6).unwrap();
        let tuned = bar
            .clone()
            .with_tuning(&[1.0, 4.0, 10.0])
            .modes(f64::INFINITY, 6)
            .unwrap();
        let f1 = tuned[0].freq_hz;
        assert_eq!(f1, uniform[0].freq_hz, "fundamental kept");
        for (i, t) in [1.0, 4.0, 10.0].iter().enumerate() {
            let r = tuned[i].freq_hz / f1;
            println!("tuned mode {}: ratio {r:.12}, target {t}", i + 1);
            assert!((r - t).abs() < 1e-12);
        }
        for i in 3..6 {
            let want = tuned[2].freq_hz * uniform[i].freq_hz / uniform[2].freq_hz;
            assert!((tuned[i].freq_hz / want - 1.0).abs() < 1e-14);
            assert_eq!(
                tuned[i].shape_at(Point::Line(0.1)),
                uniform[i].shape_at(Point::Line(0.1))
            );
        }
        // Ratios relative to the first entry; the frequency limit applies to
        // the tuned frequencies.
        let limited = bar
            .clone()
            .with_tuning(&[2.0, 8.0])
            .modes(3.5 * f1, 10)
            .unwrap();
        assert_eq!(limited.len(), 1);
        let err = bar.with_tuning(&[1.0, 4.0, 3.0]).modes(1e4, 5).unwrap_err();
        assert!(err.contains("bar.tuning[2]"), "{err}");
    }

    /// A tuned fundamental: the tuned modes at `F t_i / t_1`, the untuned
    /// ones' factors extrapolated geometrically towards 1, checked against
    /// the hand computation for an A3 marimba bar (rosewood 1050 kg/m^3, 20
    /// GPa, 400 x 58 x 22 mm, Euler-Bernoulli: uniform 617, 1700, 3333, 5510,
    /// 8231, 11497 Hz; factors 0.357, 0.518, 0.660; `r` = 0.705; modes 4-6
    /// at 4190, 6841, 10129 Hz).
    #[test]
    fn tuned_fundamental_extrapolates_the_factors() {
        let m = Material {
            density_kg_m3: 1050.0,
            youngs_modulus_pa: 20e9,
            ..material("rosewood").unwrap()
        };
        let bar = Bar::new(0.4, 0.058, 0.022, &m, BeamSupport::FreeFree);
        let uniform = bar.modes(f64::INFINITY, 6).unwrap();
        let tuned = bar
            .clone()
            .with_tuning(&[1.0, 4.0, 10.0])
            .with_fundamental(220.0)
            .modes(f64::INFINITY, 6)
            .unwrap();
        let f: Vec<f64> = tuned.iter().map(|m| m.freq_hz).collect();
        println!("tuned A3 bar: {f:.1?}");
        for (i, want) in [220.0, 880.0, 2200.0].iter().enumerate() {
            assert!((f[i] / want - 1.0).abs() < 1e-14);
        }
        let q: Vec<f64> = (0..3).map(|i| f[i] / uniform[i].freq_hz).collect();
        let r = (1.0 - q[2]) / (1.0 - q[1]);
        for i in 3..6 {
            let want = (1.0 - (1.0 - q[2]) * r.powi(i as i32 - 2)) * uniform[i].freq_hz;
            assert!((f[i] / want - 1.0).abs() < 1e-14);
        }
        for (got, hand) in f[3..].iter().zip([4190.0, 6841.0, 10129.0]) {
            assert!((got / hand - 1.0).abs() < 1e-3, "{got} vs {hand}");
        }
        let err = bar
            .clone()
            .with_fundamental(220.0)
            .modes(1e4, 5)
            .unwrap_err();
        assert!(err.contains("bar.fundamental_hz"), "{err}");
    }

    /// One bar or tube with torsional modes and its closed-form values:
    /// name, object, `rho J_p`, `G K_t`, wave speed `c_t`, length `L` and
    /// half-width (the `y` of the points measured).
    type TorsionCase = (&'static str, Shape, f64, f64, f64, f64, f64);

    /// The torsional modes of `case` with ends `support` against the closed
    /// form: frequencies, shapes, the wave equation, the end conditions,
    /// and `integral rho J_p theta_i theta_j dx = delta_ij` by quadrature.
    fn check_torsion_modes(
        support: BeamSupport,
        (name, shape, rho_jp, gkt, ct, l, hw): TorsionCase,
    ) {
        let modes = torsion_only(&shape.modes(f64::INFINITY, 80).unwrap());
        assert!(modes.len() >= 20, "{name}: {} torsional modes", modes.len());
        let amp = (2.0 / (rho_jp * l)).sqrt();
        let mut freq_res: f64 = 0.0;
        let mut shape_res: f64 = 0.0;
        let mut pde: f64 = 0.0;
        let mut ends: f64 = 0.0;
        for (i, m) in modes.iter().enumerate() {
            let n = i + 1;
            assert_eq!(m.label, ModeLabel::Torsion { n });
            let nf = n as f64;
            let (want, k) = match support {
                BeamSupport::ClampedFree => (
                    (2.0 * nf - 1.0) * ct / (4.0 * l),
                    (2.0 * nf - 1.0) * PI / (2.0 * l),
                ),
                _ => (nf * ct / (2.0 * l), nf * PI / l),
            };
            freq_res = freq_res.max((m.freq_hz / want - 1.0).abs());
            let theta = |x: f64| m.shape_at(Point::Bar { x, y: hw }).unwrap() / hw;
            for x in [0.0, 0.123 * l, 0.5 * l, 0.77 * l, l] {
                let closed = amp
                    * match support {
                        BeamSupport::FreeFree => (k * x).cos(),
                        _ => (k * x).sin(),
                    };
                shape_res = shape_res.max((theta(x) - closed).abs() / amp);
            }
            // G K_t theta'' + rho J_p omega^2 theta = 0.
            let x = 0.3137 * l;
            let dx = 1e-3 / k;
            let d2 = (theta(x + dx) - 2.0 * theta(x) + theta(x - dx)) / (dx * dx);
            let r = gkt * d2 + rho_jp * m.omega().powi(2) * theta(x);
            pde = pde.max(r.abs() / (rho_jp * m.omega().powi(2) * amp));
            // Ends: a clamp does not turn, a free end has no torque
            // (zero slope, second-order one-sided difference).
            let dx = 1e-6 * l;
            let slope0 = (-3.0 * theta(0.0) + 4.0 * theta(dx) - theta(2.0 * dx)) / (2.0 * dx);
            let slope1 = (3.0 * theta(l) - 4.0 * theta(l - dx) + theta(l - 2.0 * dx)) / (2.0 * dx);
            let (at0, at1) = match support {
                BeamSupport::FreeFree => (slope0 / k, slope1 / k),
                BeamSupport::ClampedFree => (theta(0.0), slope1 / k),
                BeamSupport::ClampedClamped => (theta(0.0), theta(l)),
            };
            ends = ends.max(at0.abs() / amp).max(at1.abs() / amp);
        }
        println!(
            "torsion {name} {support:?}: f1 {:.3} Hz, {} modes, rel freq residual \
             {freq_res:.1e}, shape {shape_res:.1e}, wave equation {pde:.1e}, \
             end conditions {ends:.1e}",
            modes[0].freq_hz,
            modes.len()
        );
        assert!(freq_res < 1e-14, "{freq_res}");
        assert!(shape_res < 1e-13, "{shape_res}");
        assert!(pde < 1e-6, "{pde}");
        assert!(ends < 1e-8, "{ends}");
        // integral rho J_p theta_i theta_j dx = delta_ij by quadrature.
        let q = composite(0.0, l, 64);
        let vals: Vec<Vec<f64>> = modes[..20]
            .iter()
            .map(|m| {
                q.iter()
                    .map(|&(x, _)| m.shape_at(Point::Bar { x, y: hw }).unwrap() / hw)
                    .collect()
            })
            .collect();
        let w: Vec<f64> = q.iter().map(|&(_, w)| rho_jp * w).collect();
        let res = identity_residual(&format!("torsion {name} {support:?}"), &gram(&vals, &w));
        assert!(res < 1e-12, "{res}");
    }

    #[test]
    fn torsion_frequencies_shapes_and_normalisation_against_the_closed_form() {
        let rw = material("rosewood").unwrap();
        let al = material("aluminium").unwrap();
        // Rosewood bar 0.4 x 0.06 x 0.02, G = 1.4 GPa: b/h = 3, beta =
        // 0.26332, K_t = beta b h^3 = 1.2639e-7 m^4, J_p = b h (b^2 + h^2) /
        // 12 = 4.0e-7 m^4, c_t = sqrt(G K_t / (rho J_p)) = 665.11 m/s.
        let (b, h) = (0.06f64, 0.02f64);
        let jp_bar = b * h * (b * b + h * h) / 12.0;
        let beta = rectangle_torsion_coefficient(b, h);
        assert!((beta - 0.263_316_931).abs() < 1e-9, "{beta}");
        let kt_bar = beta * b * h.powi(3);
        let ct_bar = (rw.shear_modulus_pa * kt_bar / (rw.density_kg_m3 * jp_bar)).sqrt();
        let bar = torsion_bar();
        println!(
            "torsion bar: K_t {:.5e} m^4, J_p {:.5e} m^4, c_t {ct_bar:.3} m/s",
            bar.torsion_constant_m4(),
            bar.polar_moment_m4()
        );
        assert!((bar.torsion_constant_m4() / kt_bar - 1.0).abs() < 1e-8);
        assert!((bar.polar_moment_m4() / jp_bar - 1.0).abs() < 1e-15);
        assert!((ct_bar / 665.11 - 1.0).abs() < 1e-5);
        // Aluminium chime with torsion: K_t = J_p, c_t = sqrt(G / rho).
        let tube = Tube::new(1.0, 0.0254, 0.0224, &al).with_torsion(al.shear_modulus_pa);
        let jp_tube = PI * (0.0254f64.powi(4) - 0.0224f64.powi(4)) / 32.0;
        let ct_tube = (al.shear_modulus_pa / al.density_kg_m3).sqrt();
        assert!((tube.polar_moment_m4() / jp_tube - 1.0).abs() < 1e-14);
        for support in [
            BeamSupport::FreeFree,
            BeamSupport::ClampedFree,
            BeamSupport::ClampedClamped,
        ] {
            let cases = [
                (
                    "bar",
                    Shape::Bar(Bar {
                        support,
                        ..bar.clone()
                    }),
                    rw.density_kg_m3 * jp_bar,
                    rw.shear_modulus_pa * kt_bar,
                    ct_bar,
                    0.4,
                    b / 2.0,
                ),
                (
                    "tube",
                    Shape::Tube(Tube {
                        support,
                        ..tube.clone()
                    }),
                    al.density_kg_m3 * jp_tube,
                    al.shear_modulus_pa * jp_tube,
                    ct_tube,
                    1.0,
                    0.0127,
                ),
            ];
            for case in cases {
                check_torsion_modes(support, case);
            }
        }
        // Hand values: the free-free bar's first torsional mode, c_t / (2 L)
        // = 665.11 / 0.8 = 831.39 Hz; the chime's, sqrt(26e9 / 2700) / 2.
        let f1 = torsion_only(&bar.modes(1e4, 100).unwrap())[0].freq_hz;
        println!("rosewood bar: torsion 1 at {f1:.2} Hz (hand: 831.39 Hz)");
        assert!((f1 / 831.39 - 1.0).abs() < 1e-5);
    }

    #[test]
    fn bar_with_torsion_is_mass_normalised_over_the_whole_section() {
        // M_ij = integral rho (w_i w_j + v_i v_j) dV over the 3-D bar: w (in
        // the direction of vibration) is shape_at(x, y); the sideways motion
        // v is -z theta for a torsional mode, 0 for a bending mode. Bending
        // and torsional modes must come out orthogonal and each normalised.
        let bar = torsion_bar();
        let (l, b, h) = (bar.length_m, bar.width_m, bar.thickness_m);
        let rho = bar.density_kg_m3;
        let modes = bar.modes(f64::INFINITY, 12).unwrap();
        let qx = composite(0.0, l, 24);
        let qy = composite(-b / 2.0, b / 2.0, 1);
        let qz = composite(-h / 2.0, h / 2.0, 1);
        let mut vals = vec![Vec::new(); modes.len()];
        let mut w = Vec::new();
        for &(x, wx) in &qx {
            for &(y, wy) in &qy {
                for &(z, wz) in &qz {
                    let wt = rho * wx * wy * wz;
                    w.push(wt);
                    w.push(wt);
                    for (m, v) in modes.iter().zip(vals.iter_mut()) {
                        let up = m.shape_at(Point::Bar { x, y }).unwrap();
                        let side = match m.label {
                            ModeLabel::Torsion { .. } => {
                                -z * m.shape_at(Point::Bar { x, y: b / 2.0 }).unwrap() / (b / 2.0)
                            }
                            _ => 0.0,
                        };
                        v.push(up);
                        v.push(side);
                    }
                }
            }
        }
        let kinds: Vec<String> = modes.iter().map(|m| m.label.to_string()).collect();
        println!("bar with torsion, 12 lowest: {kinds:?}");
        assert!(modes
            .iter()
            .any(|m| matches!(m.label, ModeLabel::Torsion { .. })));
        let res = identity_residual("bar bending + torsion, 3-D", &gram(&vals, &w));
        assert!(res < 1e-10, "{res}");
    }

    #[test]
    fn torsion_merges_with_bending_by_frequency_under_both_limits() {
        let bar = torsion_bar();
        let all = bar.modes(6000.0, 100).unwrap();
        let labels: Vec<String> = all.iter().map(|m| m.label.to_string()).collect();
        println!("bar with torsion up to 6 kHz: {labels:?}");
        // By hand: bending 574.6, 1584.0, 3105.2, 5133.1 Hz; torsion 831.4 n
        // Hz.
        let want = [
            "bending 1",
            "torsion 1",
            "bending 2",
            "torsion 2",
            "torsion 3",
            "bending 3",
            "torsion 4",
            "torsion 5",
            "torsion 6",
            "bending 4",
            "torsion 7",
        ];
        assert_eq!(labels, want);
        // The bending modes are exactly those of the bar without torsion.
        let bending: Vec<f64> = rosewood_bar()
            .modes(6000.0, 100)
            .unwrap()
            .iter()
            .map(|m| m.freq_hz)
            .collect();
        let merged_bending: Vec<f64> = all
            .iter()
            .filter(|m| matches!(m.label, ModeLabel::Bending { .. }))
            .map(|m| m.freq_hz)
            .collect();
        assert_eq!(bending, merged_bending);
        // Both limits apply to the merged list.
        for k in 0..=all.len() {
            let few = bar.modes(f64::INFINITY, k).unwrap();
            assert_eq!(few.len(), k);
            assert!(few.iter().zip(&all).all(|(a, b)| a == b));
        }
        assert_eq!(bar.modes(all[4].freq_hz, 100).unwrap().len(), 5);
        assert_eq!(bar.modes(all[4].freq_hz * 0.999_999, 100).unwrap().len(), 4);
        // A tuned bar: bending retuned, torsion kept, still in order.
        let tuned = bar
            .clone()
            .with_tuning(&[1.0, 4.0, 10.0])
            .modes(6000.0, 100)
            .unwrap();
        assert!(tuned.windows(2).all(|w| w[0].freq_hz <= w[1].freq_hz));
        let tf: Vec<f64> = torsion_only(&tuned).iter().map(|m| m.freq_hz).collect();
        let uf: Vec<f64> = torsion_only(&all).iter().map(|m| m.freq_hz).collect();
        assert_eq!(tf, uf);
        let tl: Vec<String> = tuned.iter().map(|m| m.label.to_string()).collect();
        println!("tuned 1 : 4 : 10 with torsion: {tl:?}");
        assert_eq!(
            &tl[..4],
            ["bending 1", "torsion 1", "torsion 2", "bending 2"]
        );
        // Invalid shear moduli are errors naming the field.
        let err = rosewood_bar().with_torsion(0.0).modes(1e4, 5).unwrap_err();
        assert!(err.contains("bar.torsion"), "{err}");
        let al = material("aluminium").unwrap();
        let err = Tube::new(1.0, 0.02, 0.01, &al)
            .with_torsion(f64::NAN)
            .modes(1e4, 5)
            .unwrap_err();
        assert!(err.contains("tube.torsion"), "{err}");
    }
}
