//! The amplitudes a render of the written scene plays each mode at,
//! measured on the render itself, so that the weights can be corrected
//! by what the contact really did (docs/design.md, "Your own object from
//! a recording").
//!
//! The weights are first divided by a half-sine pulse's spectrum; the
//! contact of a mallet on the object is not quite one (the object gives
//! way, a soft mallet touches again). After the contact the render is
//! exactly a sum of damped sinusoids whose poles are the scene's modes,
//! the modes the analysis found, so their amplitudes are linear least
//! squares on known poles: `x[n] = sum_k d_k u_k^n` over the span after
//! the contact, `u_k` each mode's pole `exp((-alpha + i omega) h)` and
//! its conjugate. The normal equations' Gram matrix is a sum of
//! geometric series, `G_kl = sum_n (conj(u_k) u_l)^n = expm1(M L) /
//! expm1(L)` with `L` the sum of the two poles' logarithms, so only the
//! right-hand side `b_k = sum_n conj(u_k)^n x[n]` runs over the samples:
//! O(N M) for `N` modes and `M` samples, and an O(N^3) solve.

use super::Mode;
use faer::linalg::solvers::Solve;
use faer::{c64, Mat};
use std::f64::consts::PI;

/// The most modes whose amplitudes are measured (a Gram matrix of `2 N`
/// complex rows: 1200 of them are 23 MB and a solve of a fraction of a
/// second); a scene of more modes keeps its first weights.
pub(crate) const MAX_MODES: usize = 600;

/// `expm1(z)` for a complex `z = a + i b`, accurate near 0 (where
/// `exp(z) - 1` loses the digits a geometric sum of a pole near the unit
/// circle needs): `expm1(a) cos b - 2 sin^2(b / 2) + i exp(a) sin b`.
fn expm1(z: c64) -> c64 {
    let (a, b) = (z.re, z.im);
    c64::new(
        a.exp_m1() * b.cos() - 2.0 * (0.5 * b).sin().powi(2),
        a.exp() * b.sin(),
    )
}

/// `sum_{n < m} exp(l n)`, the geometric sum of ratio `exp(l)`.
fn geometric(l: c64, m: usize) -> c64 {
    let den = expm1(l);
    if den.norm() < 1e-300 {
        return c64::new(m as f64, 0.0);
    }
    expm1(l * m as f64) / den
}

/// The peak amplitude at sample 0 of `x` (`rate_hz`) of each of `modes`'
/// damped sinusoids (frequency `freq_hz`, decay `alpha`), fitted by least
/// squares over `x[from..to]`: the analysis's own measure of a mode, so
/// that the two compare. `None` for more than [`MAX_MODES`] modes, an
/// empty span, or a fit that is not finite.
pub(crate) fn amplitudes(
    x: &[f64],
    rate_hz: f64,
    modes: &[Mode],
    (from, to): (usize, usize),
) -> Option<Vec<f64>> {
    let to = to.min(x.len());
    if modes.is_empty() || modes.len() > MAX_MODES || from >= to {
        return None;
    }
    let h = 1.0 / rate_hz;
    // the poles' logarithms: each mode's, then their conjugates
    let logs: Vec<c64> = modes
        .iter()
        .map(|m| c64::new(-m.alpha() * h, 2.0 * PI * m.freq_hz * h))
        .chain(
            modes
                .iter()
                .map(|m| c64::new(-m.alpha() * h, -2.0 * PI * m.freq_hz * h)),
        )
        .collect();
    let k = logs.len();
    let span = to - from;
    let gram = Mat::<c64>::from_fn(k, k, |r, c| geometric(logs[r].conj() + logs[c], span));
    let mut rhs = Mat::<c64>::zeros(k, 1);
    for (r, l) in logs.iter().enumerate() {
        let step = (l.conj()).exp();
        let mut z = c64::new(1.0, 0.0);
        let mut acc = c64::new(0.0, 0.0);
        for &v in &x[from..to] {
            acc += z * v;
            z *= step;
            if z.norm() < 1e-300 {
                break;
            }
        }
        rhs[(r, 0)] = acc;
    }
    let e = gram.partial_piv_lu().solve(&rhs);
    let n = modes.len();
    let out: Vec<f64> = (0..n)
        .map(|i| {
            // back from the span's first sample to sample 0
            let back = |j: usize| (-logs[j] * from as f64).exp();
            (e[(i, 0)] * back(i)).norm() + (e[(i + n, 0)] * back(i + n)).norm()
        })
        .collect();
    out.iter().all(|v| v.is_finite()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(freq_hz: f64, t60_s: f64) -> Mode {
        Mode {
            freq_hz,
            t60_s,
            amplitude: 0.0,
            phase_rad: 0.0,
            snr_db: 0.0,
            freq_sd_hz: 0.0,
            t60_rel_sd: 0.0,
        }
    }

    /// Known damped sinusoids (a pair 1 Hz apart, a fast one near the top
    /// of the band) come back at their amplitudes, fitted after a stretch
    /// the fit does not see and referred back to sample 0.
    #[test]
    fn amplitudes_of_known_sinusoids_come_back() {
        let rate = 48_000.0;
        let modes = [
            mode(220.0, 8.0),
            mode(221.0, 6.0),
            mode(1234.5, 0.4),
            mode(15_000.0, 0.03),
        ];
        let amp = [0.3, 0.7, 0.05, 0.2];
        let phase = [0.1, 2.0, -1.0, 3.0];
        let n = 48_000;
        let x: Vec<f64> = (0..n)
            .map(|j| {
                let t = j as f64 / rate;
                modes
                    .iter()
                    .zip(amp.iter().zip(&phase))
                    .map(|(m, (a, p))| {
                        a * (-m.alpha() * t).exp() * (2.0 * PI * m.freq_hz * t + p).cos()
                    })
                    .sum()
            })
            .collect();
        let got = amplitudes(&x, rate, &modes, (240, n)).unwrap();
        for (g, a) in got.iter().zip(&amp) {
            println!("amplitude {g:.15} against {a}");
            assert!((g - a).abs() < 1e-9 * a, "{g} against {a}");
        }
        assert!(amplitudes(&x, rate, &modes, (n, n)).is_none());
        assert!(amplitudes(&x, rate, &[], (0, n)).is_none());
    }

    /// Against `2 exp(z / 2) sinh(z / 2)`, which has no cancellation near
    /// 0 (`sinh` of the real part from the standard library).
    #[test]
    fn expm1_is_accurate_near_zero() {
        for z in [
            c64::new(1e-9, 2e-9),
            c64::new(-3e-4, 5e-4),
            c64::new(2e-3, -1e-3),
            c64::new(0.5, -2.0),
        ] {
            let w = z * 0.5;
            let sinh = c64::new(w.re.sinh() * w.im.cos(), w.re.cosh() * w.im.sin());
            let reference = w.exp() * sinh * 2.0;
            let err = (expm1(z) - reference).norm() / reference.norm();
            println!("expm1({z}): relative error {err:.1e}");
            assert!(err < 1e-15, "{z}: {err:e}");
        }
    }
}
