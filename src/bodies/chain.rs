//! A free lumped chain: masses in a line joined by springs, free at both
//! ends (a mallet's head and shaft, lumped; docs/design.md, "Modal
//! mallets").
//!
//! With `M = diag(m)` and the chain's stiffness `K` (each spring `s_i`
//! between masses `i` and `i + 1`), the modes solve `K phi = omega^2 M
//! phi`. Written symmetric, `A = M^-1/2 K M^-1/2 = V Lambda V^T`, the
//! mass-normalised shapes are `phi_j = M^-1/2 v_j` (`phi^T M phi = 1`). A
//! free chain has exactly one zero eigenvalue (it is connected): the rigid
//! translation `phi_0 = 1 / sqrt(sum m)` at every mass, which is left out;
//! the elastic modes are orthogonal to it (`sum m_i phi_ij = 0`).

use nalgebra::{DMatrix, DVector};

/// One elastic mode of a free chain.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainMode {
    /// Angular frequency `omega` \[rad/s\].
    pub omega: f64,
    /// Mass-normalised shape at each mass \[1/sqrt(kg)\], the sign chosen so
    /// that the first mass's entry is `>= 0`.
    pub shape: Vec<f64>,
}

/// The elastic modes of the free chain `masses` (kg) joined by `springs`
/// (N/m; one fewer), in increasing frequency; the rigid translation left
/// out. Every value must be positive and finite and `springs.len() + 1 ==
/// masses.len() >= 2` (the scene validates that first).
pub fn free_chain_modes(masses: &[f64], springs: &[f64]) -> Vec<ChainMode> {
    let n = masses.len();
    debug_assert!(n >= 2 && springs.len() + 1 == n);
    let inv_sqrt_m = DVector::from_iterator(n, masses.iter().map(|m| 1.0 / m.sqrt()));
    let mut a = DMatrix::<f64>::zeros(n, n);
    for (i, s) in springs.iter().enumerate() {
        let (p, q) = (inv_sqrt_m[i], inv_sqrt_m[i + 1]);
        a[(i, i)] += s * p * p;
        a[(i + 1, i + 1)] += s * q * q;
        a[(i, i + 1)] -= s * p * q;
        a[(i + 1, i)] -= s * p * q;
    }
    let eig = a.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    // the smallest is the rigid translation (zero up to rounding)
    order
        .into_iter()
        .skip(1)
        .map(|j| {
            let mut shape: Vec<f64> = (0..n)
                .map(|i| eig.eigenvectors[(i, j)] * inv_sqrt_m[i])
                .collect();
            if shape[0] < 0.0 {
                shape.iter_mut().for_each(|x| *x = -*x);
            }
            ChainMode {
                omega: eig.eigenvalues[j].max(0.0).sqrt(),
                shape,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two masses: one mode, `omega^2 = s (1/m1 + 1/m2)`, shape
    /// `(sqrt(m2 / (m1 M)), -sqrt(m1 / (m2 M)))` (closed form).
    #[test]
    fn two_masses_closed_form() {
        let (m1, m2, s) = (0.005, 0.02, 3.2e4);
        let modes = free_chain_modes(&[m1, m2], &[s]);
        assert_eq!(modes.len(), 1);
        let m = m1 + m2;
        let w = (s * (1.0 / m1 + 1.0 / m2)).sqrt();
        assert!((modes[0].omega - w).abs() < 1e-13 * w);
        assert!((modes[0].shape[0] - (m2 / (m1 * m)).sqrt()).abs() < 1e-12);
        assert!((modes[0].shape[1] + (m1 / (m2 * m)).sqrt()).abs() < 1e-12);
    }

    /// A uniform free chain of `n` masses `m` and springs `s`: `omega_j = 2
    /// sqrt(s/m) sin(j pi / (2 n))`, `j = 1..n-1` (closed form); the shapes
    /// are mass-orthonormal and orthogonal to the rigid translation.
    #[test]
    fn uniform_chain_closed_form_and_orthogonality() {
        let (n, m, s) = (7, 0.003, 1.7e4);
        let masses = vec![m; n];
        let modes = free_chain_modes(&masses, &vec![s; n - 1]);
        assert_eq!(modes.len(), n - 1);
        for (k, md) in modes.iter().enumerate() {
            let j = (k + 1) as f64;
            let w = 2.0 * (s / m).sqrt() * (j * std::f64::consts::PI / (2.0 * n as f64)).sin();
            assert!(
                (md.omega - w).abs() < 1e-12 * w,
                "mode {j}: {} vs {w}",
                md.omega
            );
            let rigid: f64 = md.shape.iter().map(|x| m * x).sum();
            assert!(
                rigid.abs() < 1e-12,
                "mode {j} moves the centre of mass: {rigid}"
            );
            for other in &modes {
                let dot: f64 = md
                    .shape
                    .iter()
                    .zip(&other.shape)
                    .map(|(a, b)| m * a * b)
                    .sum();
                let want = if std::ptr::eq(md, other) { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-12, "{dot} vs {want}");
            }
        }
    }
}
