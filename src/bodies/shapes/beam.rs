//! Euler-Bernoulli beam functions: the roots `u_n = beta_n L` of the
//! frequency equation for each [`BeamSupport`], the bending shapes in an
//! overflow-free form, and the torsional shapes. Bars and tubes use them
//! for their modes (`beam_modes.rs`), free plates as the factors of their
//! shapes (`plate.rs`).
//!
//! `u_n = beta_n L` is the `n`-th positive root of
//! - free-free: `cos u cosh u = 1` (`u_n -> (2n+1) pi/2`; 4.7300, 7.8532,
//!   10.9956, ...),
//! - clamped (`x = 0`) - free: `cos u cosh u = -1` (`u_n -> (2n-1) pi/2`;
//!   1.8751, 4.6941, 7.8548, ...),
//! - clamped-clamped (both ends clamped, e.g. a wood block's lips): `cos u
//!   cosh u = 1`, the same roots as free-free.
//!
//! Solved as `cos u -+ sech u = 0` (no overflow) by Newton's method from the
//! asymptote, safeguarded by bisection in the bracket `[n pi, (n+1) pi]`
//! (free-free, clamped-clamped) or `[(n-1) pi, n pi]` (clamped-free).
//!
//! Shapes (`xi = x / L`), normalised to `integral_0^L phi^2 dx = L`:
//! - free-free: `phi = cosh(u xi) + cos(u xi) - s (sinh(u xi) + sin(u xi))`,
//!   `s = (cosh u - cos u) / (sinh u - sin u)`;
//! - clamped-free: `phi = cosh(u xi) - cos(u xi) - s (sinh(u xi) - sin(u
//!   xi))`, `s = (cosh u + cos u) / (sinh u + sin u)`;
//! - clamped-clamped: `phi = cosh(u xi) - cos(u xi) - s (sinh(u xi) - sin(u
//!   xi))`, `s = (cosh u - cos u) / (sinh u - sin u)` (the free-free `s`:
//!   the clamped-clamped shape is `d^2 phi_ff / d xi^2 / u^2`, and is 0 with
//!   zero slope at both ends);
//!
//! and `Phi = phi / sqrt(rho A L)`. Evaluated in the overflow-free form
//! `phi = c_g exp(u (xi - 1)) + c_d exp(-u xi) + t (cos(u xi) - s sin(u
//! xi))`, where `cosh(u xi) - s sinh(u xi) = c_g exp(u (xi - 1)) + c_d
//! exp(-u xi)` with `c_g = (1 - s) e^u / 2`, `c_d = (1 + s) / 2`, and `t =
//! +1` (free-free) or `-1` (clamped-free, clamped-clamped). With `E1 =
//! exp(-u)`, multiplying numerator and denominator of `s` by `2 E1`:
//! - free-free and clamped-clamped: `s = (1 + E1^2 - 2 E1 cos u) / Q`, `c_g =
//!   (cos u - sin u - E1) / Q`, `Q = 1 - E1^2 - 2 E1 sin u` (from `1 - s = 2
//!   E1 (cos u - sin u - E1) / Q`);
//! - clamped-free: `s = (1 + E1^2 + 2 E1 cos u) / Q`, `c_g = (sin u - cos u
//!   - E1) / Q`, `Q = 1 - E1^2 + 2 E1 sin u`.

use std::f64::consts::PI;

use super::search::safeguarded_newton;

/// Boundary conditions of a bar or tube.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BeamSupport {
    /// Both ends free (xylophone and marimba bars, chimes).
    FreeFree,
    /// Clamped at `x = 0`, free at `x = L` (kalimba tine, tuning-fork prong).
    ClampedFree,
    /// Both ends clamped (the lips of a wood block).
    ClampedClamped,
}

/// `sech x` without overflow (`x >= 0`).
fn sech(x: f64) -> f64 {
    let e = (-x).exp();
    2.0 * e / (1.0 + e * e)
}

/// `u_n = beta_n L`, the `n`-th (from 1) positive root of `cos u cosh u = 1`
/// (free-free, clamped-clamped) or `= -1` (clamped-free).
pub fn beam_root(support: BeamSupport, n: usize) -> f64 {
    let n = n.max(1) as f64;
    // g(u) = cos u - c sech u, c = +1 (free-free, clamped-clamped) or -1
    // (clamped-free).
    let (c, lo, hi, guess) = match support {
        BeamSupport::FreeFree | BeamSupport::ClampedClamped => {
            (1.0, n * PI, (n + 1.0) * PI, (2.0 * n + 1.0) * PI / 2.0)
        }
        BeamSupport::ClampedFree => (-1.0, (n - 1.0) * PI, n * PI, (2.0 * n - 1.0) * PI / 2.0),
    };
    let g = |u: f64| u.cos() - c * sech(u);
    let dg = |u: f64| {
        let s = sech(u);
        let t = (1.0 - (-2.0 * u).exp()) / (1.0 + (-2.0 * u).exp());
        -u.sin() + c * s * t
    };
    safeguarded_newton(g, dg, lo, hi, guess)
}

/// A 1-D beam function on `xi = x / L` in `[0, 1]`, normalised to
/// `integral_0^1 phi^2 d xi = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum BeamFn {
    /// `phi = 1` (rigid translation).
    Rigid0,
    /// `phi = sqrt(3) (1 - 2 xi)` (rigid rotation).
    Rigid1,
    /// Elastic mode: `phi = c_g e^{u(xi-1)} + c_d e^{-u xi} + t (cos(u xi) -
    /// s sin(u xi))`, `t = +1` free-free, `-1` clamped-free and
    /// clamped-clamped.
    Elastic {
        u: f64,
        c_grow: f64,
        c_decay: f64,
        s: f64,
        trig: f64,
    },
}

impl BeamFn {
    pub(super) fn elastic(support: BeamSupport, n: usize) -> BeamFn {
        let u = beam_root(support, n);
        let e1 = (-u).exp();
        let (su, cu) = u.sin_cos();
        let (s, c_grow, trig) = match support {
            BeamSupport::FreeFree | BeamSupport::ClampedClamped => {
                // The same hyperbolic part; the trigonometric part changes sign.
                let q = 1.0 - e1 * e1 - 2.0 * e1 * su;
                let trig = if support == BeamSupport::FreeFree {
                    1.0
                } else {
                    -1.0
                };
                (
                    (1.0 + e1 * e1 - 2.0 * e1 * cu) / q,
                    (cu - su - e1) / q,
                    trig,
                )
            }
            BeamSupport::ClampedFree => {
                let q = 1.0 - e1 * e1 + 2.0 * e1 * su;
                (
                    (1.0 + e1 * e1 + 2.0 * e1 * cu) / q,
                    (su - cu - e1) / q,
                    -1.0,
                )
            }
        };
        BeamFn::Elastic {
            u,
            c_grow,
            c_decay: 0.5 * (1.0 + s),
            s,
            trig,
        }
    }

    pub(super) fn eval(&self, xi: f64) -> f64 {
        match *self {
            BeamFn::Rigid0 => 1.0,
            BeamFn::Rigid1 => 3f64.sqrt() * (1.0 - 2.0 * xi),
            BeamFn::Elastic {
                u,
                c_grow,
                c_decay,
                s,
                trig,
            } => {
                let (sn, cs) = (u * xi).sin_cos();
                c_grow * (u * (xi - 1.0)).exp() + c_decay * (-u * xi).exp() + trig * (cs - s * sn)
            }
        }
    }
}

/// `theta(xi) / A` of torsional mode `n`, `xi = x / L`.
pub(super) fn torsion_fn(support: BeamSupport, n: usize, xi: f64) -> f64 {
    let n = n as f64;
    match support {
        BeamSupport::FreeFree => (n * PI * xi).cos(),
        BeamSupport::ClampedFree => ((2.0 * n - 1.0) * PI * xi / 2.0).sin(),
        BeamSupport::ClampedClamped => (n * PI * xi).sin(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bodies::materials::material;
    use crate::bodies::shapes::test_support::{identity_residual, line_gram, rosewood_bar};
    use crate::bodies::shapes::{Bar, ModeLabel, Point, Tube};

    #[test]
    fn free_free_roots_match_the_published_table() {
        // Blevins, Formulas for Natural Frequency and Mode Shape, table 8-1.
        let table = [
            4.730040745,
            7.853204624,
            10.99560784,
            14.13716549,
            17.27875966,
        ];
        for (i, &t) in table.iter().enumerate() {
            let u = beam_root(BeamSupport::FreeFree, i + 1);
            let res = u - t;
            println!(
                "free-free u_{} = {u:.12}, table {t}, residual {res:.2e}",
                i + 1
            );
            // The table has 10 significant digits: half a unit of the last.
            assert!(res.abs() < 5.01e-9, "{res}");
            assert!(((u.cos() * u.cosh()) - 1.0).abs() < 1e-12 * u.cosh());
        }
        for n in [10, 100, 1000] {
            let u = beam_root(BeamSupport::FreeFree, n);
            let asym = (2 * n + 1) as f64 * PI / 2.0;
            println!("free-free u_{n} - (2n+1) pi/2 = {:.2e}", u - asym);
            assert!((u - asym).abs() < 1e-12 * asym);
        }
    }

    #[test]
    fn clamped_free_roots_match_the_published_table() {
        let table = [
            1.875104069,
            4.694091133,
            7.854757438,
            10.99554073,
            14.13716839,
        ];
        for (i, &t) in table.iter().enumerate() {
            let u = beam_root(BeamSupport::ClampedFree, i + 1);
            let res = u - t;
            println!(
                "clamped-free u_{} = {u:.12}, table {t}, residual {res:.2e}",
                i + 1
            );
            // The table has 10 significant digits: half a unit of the last.
            assert!(res.abs() < 5.01e-9, "{res}");
        }
    }

    #[test]
    fn beam_shapes_are_mass_normalised_and_orthogonal_by_quadrature() {
        let bar = rosewood_bar();
        let rho_a = bar.density_kg_m3 * bar.width_m * bar.thickness_m;
        for support in [BeamSupport::FreeFree, BeamSupport::ClampedFree] {
            let b = Bar {
                support,
                ..bar.clone()
            };
            let modes = b.modes(f64::INFINITY, 12).unwrap();
            let g = line_gram(&modes, rho_a, b.length_m, 64);
            let res = identity_residual(&format!("bar {support:?}"), &g);
            assert!(res < 1e-10, "{res}");
        }
        // A high mode: the overflow-free form stays bounded and normalised
        // (with cosh/sinh written out, cosh(200) alone is 3.6e86).
        let b = bar.clone();
        let modes = b.modes(f64::INFINITY, 64).unwrap();
        let high = &modes[62..64];
        let g = line_gram(high, rho_a, b.length_m, 400);
        let res = identity_residual("bar free-free modes 63-64", &g);
        assert!(res < 1e-9, "{res}");
    }

    #[test]
    fn beam_end_values_match_the_classical_results() {
        // With integral phi^2 = L: a free end has |phi| = 2 (free-free: both
        // ends, clamped-free: the tip), a clamped end phi = 0 with zero slope.
        let bar = rosewood_bar();
        let scale = (bar.mass_kg()).sqrt();
        let l = bar.length_m;
        let ff = bar.modes(f64::INFINITY, 30).unwrap();
        let cf = Bar {
            support: BeamSupport::ClampedFree,
            ..bar.clone()
        }
        .modes(f64::INFINITY, 30)
        .unwrap();
        let mut worst: f64 = 0.0;
        for m in &ff {
            let e0 = m.shape_at(Point::Line(0.0)).unwrap() * scale;
            let el = m.shape_at(Point::Line(l)).unwrap() * scale;
            worst = worst
                .max((e0.abs() - 2.0).abs())
                .max((el.abs() - 2.0).abs());
        }
        for m in &cf {
            let tip = m.shape_at(Point::Line(l)).unwrap() * scale;
            let root = m.shape_at(Point::Line(0.0)).unwrap() * scale;
            let h = 1e-7 * l;
            let slope = (m.shape_at(Point::Line(h)).unwrap() * scale - root) / h * l;
            worst = worst.max((tip.abs() - 2.0).abs()).max(root.abs());
            // phi ~ u^2 xi^2 near the clamp: the one-sided slope is ~u^2 h/L.
            assert!(slope.abs() < 1e-3, "{}: slope {slope}", m.label);
        }
        println!("beam end values: worst residual {worst:.2e}");
        assert!(worst < 1e-9, "{worst}");
    }

    #[test]
    fn clamped_clamped_roots_ends_pde_and_quadrature() {
        // The same equation cos u cosh u = 1 as free-free: the same roots.
        for n in 1..=200 {
            assert_eq!(
                beam_root(BeamSupport::ClampedClamped, n),
                beam_root(BeamSupport::FreeFree, n)
            );
        }
        for (n, t) in [(1, 4.730040745), (2, 7.853204624), (3, 10.99560784)] {
            let u = beam_root(BeamSupport::ClampedClamped, n);
            println!(
                "clamped-clamped u_{n} = {u:.12}, table {t}, residual {:.2e}",
                u - t
            );
            assert!((u - t).abs() < 5.01e-9);
        }
        let ff = rosewood_bar();
        let bar = Bar {
            support: BeamSupport::ClampedClamped,
            ..ff.clone()
        };
        let l = bar.length_m;
        let rho_a = bar.density_kg_m3 * bar.width_m * bar.thickness_m;
        // phi (with integral_0^1 phi^2 d xi = 1) = Phi sqrt(rho A L).
        let norm = bar.mass_kg().sqrt();
        let modes = bar.modes(f64::INFINITY, 20).unwrap();
        let ff_modes = ff.modes(f64::INFINITY, 20).unwrap();
        // Same frequencies as free-free, also with the Timoshenko correction.
        for (a, b) in modes.iter().zip(&ff_modes) {
            assert_eq!(a.freq_hz, b.freq_hz);
        }
        let g_rw = material("rosewood").unwrap().shear_modulus_pa;
        let t_cc = bar.clone().with_timoshenko(g_rw).modes(1e5, 8).unwrap();
        let t_ff = ff.clone().with_timoshenko(g_rw).modes(1e5, 8).unwrap();
        assert!(t_cc.iter().zip(&t_ff).all(|(a, b)| a.freq_hz == b.freq_hz));
        assert!(t_cc[0].freq_hz < modes[0].freq_hz);
        let mut end_value: f64 = 0.0;
        let mut end_slope: f64 = 0.0;
        let mut pde: f64 = 0.0;
        let mut second: f64 = 0.0;
        for (m, mf) in modes.iter().zip(&ff_modes) {
            let ModeLabel::Bending { n } = m.label else {
                unreachable!()
            };
            let u = beam_root(BeamSupport::ClampedClamped, n);
            let phi = |xi: f64| m.shape_at(Point::Line(xi * l)).unwrap() * norm;
            let phi_ff = |xi: f64| mf.shape_at(Point::Line(xi * l)).unwrap() * norm;
            end_value = end_value.max(phi(0.0).abs()).max(phi(1.0).abs());
            // Second-order one-sided slopes d phi / d xi at both ends,
            // relative to the interior slope scale u.
            let h = 1e-6;
            let s0 = (-3.0 * phi(0.0) + 4.0 * phi(h) - phi(2.0 * h)) / (2.0 * h);
            let s1 = (3.0 * phi(1.0) - 4.0 * phi(1.0 - h) + phi(1.0 - 2.0 * h)) / (2.0 * h);
            end_slope = end_slope.max(s0.abs() / u).max(s1.abs() / u);
            // The beam equation phi'''' = u^4 phi at interior points, and
            // phi_cc = phi_ff'' / u^2 (both in xi), by central differences.
            for xi in [0.1371, 0.5, 0.8113] {
                let h4 = 0.005 / u;
                let d4 = (phi(xi + 2.0 * h4) - 4.0 * phi(xi + h4) + 6.0 * phi(xi)
                    - 4.0 * phi(xi - h4)
                    + phi(xi - 2.0 * h4))
                    / h4.powi(4);
                pde = pde.max((d4 - u.powi(4) * phi(xi)).abs() / (2.0 * u.powi(4)));
                let h2 = 1e-3 / u;
                let d2 = (phi_ff(xi + h2) - 2.0 * phi_ff(xi) + phi_ff(xi - h2)) / (h2 * h2);
                second = second.max((d2 / (u * u) - phi(xi)).abs() / 2.0);
            }
        }
        println!(
            "clamped-clamped, 20 modes: max |phi| at the ends {end_value:.2e}, \
             max |phi'|/u at the ends {end_slope:.2e}, \
             beam equation rel residual {pde:.2e}, |phi_ff''/u^2 - phi_cc| / 2 {second:.2e}"
        );
        assert!(end_value < 1e-12, "{end_value}");
        assert!(end_slope < 1e-6, "{end_slope}");
        assert!(pde < 1e-4, "{pde}");
        assert!(second < 1e-6, "{second}");
        let g = line_gram(&modes, rho_a, l, 64);
        let res = identity_residual("bar ClampedClamped", &g);
        assert!(res < 1e-10, "{res}");
        // High modes stay bounded and normalised in the overflow-free form.
        let modes = bar.modes(f64::INFINITY, 64).unwrap();
        let g = line_gram(&modes[62..64], rho_a, l, 400);
        let res = identity_residual("bar clamped-clamped modes 63-64", &g);
        assert!(res < 1e-9, "{res}");
        // A clamped-clamped tube.
        let al = material("aluminium").unwrap();
        let tube = Tube {
            support: BeamSupport::ClampedClamped,
            ..Tube::new(1.0, 0.0254, 0.0224, &al)
        };
        let tm = tube.modes(f64::INFINITY, 10).unwrap();
        let g = line_gram(&tm, al.density_kg_m3 * tube.area_m2(), 1.0, 64);
        assert!(identity_residual("tube ClampedClamped", &g) < 1e-10);
    }
}
