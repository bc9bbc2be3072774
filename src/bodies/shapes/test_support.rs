//! What the kinds' unit tests share: Gauss-Legendre quadrature, the mass
//! (Gram) matrix of modes and its distance from the identity, and the
//! objects several tests measure.

use std::f64::consts::PI;

use super::{Bar, BeamSupport, Membrane, ModeLabel, Point, ShapeMode};
use crate::bodies::materials::material;

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// Composite 16-point Gauss-Legendre on [lo, hi] with `panels` panels:
/// the nodes and weights.
pub(super) fn composite(lo: f64, hi: f64, panels: usize) -> Vec<(f64, f64)> {
    let gl = gauss_legendre(16);
    let h = (hi - lo) / panels as f64;
    let mut out = Vec::with_capacity(panels * 16);
    for p in 0..panels {
        let c = lo + (p as f64 + 0.5) * h;
        for &(x, w) in &gl {
            out.push((c + 0.5 * h * x, 0.5 * h * w));
        }
    }
    out
}

/// The mass matrix `integral rho Phi_i Phi_j dV` of `modes` on a line
/// of mass per length `rho_a` and length `l`.
pub(super) fn line_gram(modes: &[ShapeMode], rho_a: f64, l: f64, panels: usize) -> Vec<Vec<f64>> {
    let q = composite(0.0, l, panels);
    let vals: Vec<Vec<f64>> = modes
        .iter()
        .map(|m| {
            q.iter()
                .map(|&(x, _)| m.shape_at(Point::Line(x)).unwrap())
                .collect()
        })
        .collect();
    gram(
        &vals,
        &q.iter().map(|&(_, w)| rho_a * w).collect::<Vec<_>>(),
    )
}

pub(super) fn gram(vals: &[Vec<f64>], w: &[f64]) -> Vec<Vec<f64>> {
    let n = vals.len();
    let mut g = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = (0..w.len()).map(|k| w[k] * vals[i][k] * vals[j][k]).sum();
            g[i][j] = s;
            g[j][i] = s;
        }
    }
    g
}

/// Largest `|G - I|` entry, printed with the kind's name.
pub(super) fn identity_residual(name: &str, g: &[Vec<f64>]) -> f64 {
    let mut diag: f64 = 0.0;
    let mut off: f64 = 0.0;
    for (i, row) in g.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            if i == j {
                diag = diag.max((v - 1.0).abs());
            } else {
                off = off.max(v.abs());
            }
        }
    }
    println!(
        "{name}: {} modes, max |M_ii - 1| = {diag:.2e}, max |M_ij| = {off:.2e}",
        g.len()
    );
    diag.max(off)
}

pub(super) fn rosewood_bar() -> Bar {
    let m = material("rosewood").unwrap();
    Bar::new(0.4, 0.06, 0.02, &m, BeamSupport::FreeFree)
}

pub(super) fn torsion_bar() -> Bar {
    rosewood_bar().with_torsion(material("rosewood").unwrap().shear_modulus_pa)
}

pub(super) fn torsion_only(modes: &[ShapeMode]) -> Vec<ShapeMode> {
    modes
        .iter()
        .filter(|m| matches!(m.label, ModeLabel::Torsion { .. }))
        .cloned()
        .collect()
}

pub(super) fn drum() -> Membrane {
    Membrane {
        radius_m: 0.18,
        tension_n_per_m: 3000.0,
        areal_density_kg_m2: 0.26,
    }
}
