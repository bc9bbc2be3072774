//! Contact laws of several linear pieces: a contact that stiffens as it
//! is pressed (docs/design.md, "Stiffening contacts").
//!
//! A law of `P` pieces has breakpoints `0 < q_1 < ... < q_{P-1}` in
//! penetration and a stiffness `k_1 < k_2 < ... < k_P` per piece; its
//! elastic force is continuous, `F(p) = F(q_{i-1}) + k_i (p - q_{i-1})` on
//! piece `i`. That is exactly `P` springs side by side, spring `i` of
//! stiffness `k_i - k_{i-1}` touching once the penetration passes
//! `q_{i-1}`: the scene's `[contact]` takes piece 1 and each further piece
//! becomes a contact of its own between the same two sides with a gap of
//! its breakpoint ([`Scene::expanded`](super::Scene::expanded)), so the
//! several-contact engine finds and takes every breakpoint crossing as it
//! does any contact's, exactly and in order.

use super::error::{check_max, check_min, check_positive, SceneError};
use super::limits::{MAX_STIFFNESS_N_PER_M, MIN_STIFFNESS_N_PER_M};
use serde::{Deserialize, Serialize};

/// Most pieces of one law (every piece is a spring; a scene holds at most
/// [`MAX_SPRINGS`](super::MAX_SPRINGS)).
pub const MAX_LAW_PIECES: usize = 8;

/// `[contact] law`: either the pieces (`breakpoints_m` and
/// `stiffness_n_per_m`) or a power law fitted by pieces (`power`,
/// `force_n_at`, `pieces`, `up_to_m`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LawSpec {
    /// Breakpoints \[m\] of penetration, increasing, above 0 (pieces given
    /// directly).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub breakpoints_m: Option<Vec<f64>>,
    /// Stiffness of each piece \[N/m\], one more than the breakpoints,
    /// increasing (pieces given directly).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_n_per_m: Option<Vec<f64>>,
    /// Exponent of the power law `F = F_ref (p / p_ref)^power`, at least 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub power: Option<f64>,
    /// `[p_ref, F_ref]`: a penetration \[m\] and the force \[N\] there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_n_at: Option<[f64; 2]>,
    /// How many pieces the power law is fitted with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pieces: Option<usize>,
    /// The fit follows the power law up to this penetration \[m\]; beyond
    /// it the last piece goes on straight (softer than the power law).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up_to_m: Option<f64>,
    /// ... and from this one \[m\] (default a tenth of `up_to_m`): below
    /// it the first piece is a line from 0, stiffer than the power law.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_m: Option<f64>,
}

/// A law's pieces, checked: `stiffness.len() == breakpoints.len() + 1`.
#[derive(Debug, Clone, PartialEq)]
pub struct Pieces {
    /// Breakpoints \[m\], increasing, above 0.
    pub breakpoints: Vec<f64>,
    /// Stiffness per piece \[N/m\], increasing.
    pub stiffness: Vec<f64>,
    /// A fitted power law's largest relative force error over `[from_m,
    /// up_to_m]` (0 for pieces given directly).
    pub fit_error: f64,
}

impl Pieces {
    /// The elastic force at penetration `p` \[N\] (0 for `p <= 0`).
    pub fn force(&self, p: f64) -> f64 {
        if !(p > 0.0) {
            return 0.0;
        }
        let (mut f, mut at) = (0.0, 0.0);
        for (i, &k) in self.stiffness.iter().enumerate() {
            let end = self.breakpoints.get(i).copied().unwrap_or(f64::INFINITY);
            if p <= end {
                return f + k * (p - at);
            }
            f += k * (end - at);
            at = end;
        }
        f
    }

    /// The potential energy at penetration `p` \[J\]: the integral of the
    /// elastic force from 0, piece-wise quadratic.
    pub fn potential(&self, p: f64) -> f64 {
        if !(p > 0.0) {
            return 0.0;
        }
        let (mut e, mut f, mut at) = (0.0, 0.0, 0.0);
        for (i, &k) in self.stiffness.iter().enumerate() {
            let end = self
                .breakpoints
                .get(i)
                .copied()
                .unwrap_or(f64::INFINITY)
                .min(p);
            let d = end - at;
            e += f * d + 0.5 * k * d * d;
            f += k * d;
            at = end;
            if at >= p {
                break;
            }
        }
        e
    }
}

impl LawSpec {
    /// The law's pieces, or why they are not a law (errors name the field
    /// under `path`, e.g. `contact.law`).
    pub fn pieces(&self, path: &str) -> Result<Pieces, SceneError> {
        let f = |k: &str| format!("{path}.{k}");
        let direct = self.breakpoints_m.is_some() || self.stiffness_n_per_m.is_some();
        let power = self.power.is_some()
            || self.force_n_at.is_some()
            || self.pieces.is_some()
            || self.up_to_m.is_some()
            || self.from_m.is_some();
        match (direct, power) {
            (true, true) => Err(SceneError::new(
                path,
                "give either breakpoints_m and stiffness_n_per_m, or power, force_n_at, pieces \
                 and up_to_m",
            )),
            (false, false) => Err(SceneError::new(
                path,
                "empty: give breakpoints_m and stiffness_n_per_m, or power, force_n_at, pieces \
                 and up_to_m",
            )),
            (true, false) => {
                let q = self.breakpoints_m.clone().ok_or_else(|| {
                    SceneError::new(f("breakpoints_m"), "missing (with stiffness_n_per_m)")
                })?;
                let k = self.stiffness_n_per_m.clone().ok_or_else(|| {
                    SceneError::new(f("stiffness_n_per_m"), "missing (with breakpoints_m)")
                })?;
                checked(path, q, k, 0.0)
            }
            (false, true) => self.fitted(path),
        }
    }

    /// The same law with every force `factor` times larger (every piece's
    /// stiffness, or the power law's reference force): the breakpoints
    /// stay, so the law keeps its shape (the instrument's Hardness).
    pub fn scale_force(&mut self, factor: f64) {
        if let Some(k) = &mut self.stiffness_n_per_m {
            k.iter_mut().for_each(|k| *k *= factor);
        }
        if let Some(at) = &mut self.force_n_at {
            at[1] *= factor;
        }
    }

    /// The power law fitted by pieces ([`fit_power`]).
    fn fitted(&self, path: &str) -> Result<Pieces, SceneError> {
        let f = |k: &str| format!("{path}.{k}");
        let missing = |k: &str| {
            SceneError::new(
                f(k),
                "missing (a power law needs power, force_n_at, pieces and up_to_m)",
            )
        };
        let power = self.power.ok_or_else(|| missing("power"))?;
        let [p_ref, f_ref] = self.force_n_at.ok_or_else(|| missing("force_n_at"))?;
        let pieces = self.pieces.ok_or_else(|| missing("pieces"))?;
        let up_to = self.up_to_m.ok_or_else(|| missing("up_to_m"))?;
        let from = self.from_m.unwrap_or(0.1 * up_to);
        if !(power.is_finite() && (1.0..=6.0).contains(&power)) {
            return Err(SceneError::new(
                f("power"),
                format!("{power}: from 1 to 6 (a law that stiffens; Hertz 1.5, felt 2-4)"),
            ));
        }
        check_positive(&f("force_n_at[0]"), p_ref)?;
        check_positive(&f("force_n_at[1]"), f_ref)?;
        check_positive(&f("up_to_m"), up_to)?;
        check_positive(&f("from_m"), from)?;
        if !(from < up_to) {
            return Err(SceneError::new(
                f("from_m"),
                format!("{from}: below up_to_m"),
            ));
        }
        if !(1..=MAX_LAW_PIECES).contains(&pieces) {
            return Err(SceneError::new(
                f("pieces"),
                format!("{pieces}: from 1 to {MAX_LAW_PIECES}"),
            ));
        }
        let a = f_ref / p_ref.powf(power);
        let (q, k, err) = fit_power(a, power, from, up_to, pieces);
        checked(path, q, k, err)
    }
}

/// Check pieces given directly or fitted: breakpoints increasing and above
/// 0, one stiffness more, each in range and above the one before.
fn checked(path: &str, q: Vec<f64>, k: Vec<f64>, fit_error: f64) -> Result<Pieces, SceneError> {
    let f = |k: &str| format!("{path}.{k}");
    if k.len() != q.len() + 1 {
        return Err(SceneError::new(
            f("stiffness_n_per_m"),
            format!(
                "{} stiffnesses for {} breakpoints: one piece more than breakpoints",
                k.len(),
                q.len()
            ),
        ));
    }
    if k.len() > MAX_LAW_PIECES {
        return Err(SceneError::new(
            f("stiffness_n_per_m"),
            format!("{} pieces, at most {MAX_LAW_PIECES}", k.len()),
        ));
    }
    let mut last = 0.0;
    for (i, &x) in q.iter().enumerate() {
        let at = f(&format!("breakpoints_m[{i}]"));
        check_positive(&at, x)?;
        if !(x > last) {
            return Err(SceneError::new(at, format!("{x}: above the one before")));
        }
        last = x;
    }
    let mut last = 0.0;
    for (i, &x) in k.iter().enumerate() {
        let at = f(&format!("stiffness_n_per_m[{i}]"));
        check_positive(&at, x)?;
        check_min(&at, x, MIN_STIFFNESS_N_PER_M)?;
        check_max(&at, x, MAX_STIFFNESS_N_PER_M)?;
        if !(x > last) {
            return Err(SceneError::new(
                at,
                format!("{x}: above the piece before (a law that stiffens)"),
            ));
        }
        last = x;
    }
    Ok(Pieces {
        breakpoints: q,
        stiffness: k,
        fit_error,
    })
}

/// The largest relative error `chord / curve - 1` of the chord of
/// `p^alpha` over `[x0, rho x0]` (the same for every `x0`: a power law
/// looks the same at every scale). The chord lies above a convex curve;
/// `chord(u) / u^alpha` is largest where `u = alpha (s - 1) / (s (alpha -
/// 1))`, `s` the chord's slope in units of `x0`.
fn chord_error(alpha: f64, rho: f64) -> f64 {
    if !(alpha > 1.0) || !(rho > 1.0) {
        return 0.0;
    }
    let s = (rho.powf(alpha) - 1.0) / (rho - 1.0);
    let u = (alpha * (s - 1.0) / (s * (alpha - 1.0))).clamp(1.0, rho);
    (1.0 + s * (u - 1.0)) / u.powf(alpha) - 1.0
}

/// The ratio `rho` whose chord error is `e` (at most `cap`).
fn ratio_for(alpha: f64, e: f64, cap: f64) -> f64 {
    if chord_error(alpha, cap) <= e {
        return cap;
    }
    let (mut lo, mut hi) = (1.0_f64, cap);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if chord_error(alpha, mid) <= e {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The pieces' ends when each piece's relative error over `[from, up_to]`
/// is at most `e`: the first piece, a line from 0, ends where it is `1 +
/// e` times the curve at `from`; each next one where its chord's error
/// reaches `e`. At most `most + 1` of them (more means `e` is too small).
fn ends_for(alpha: f64, from: f64, up_to: f64, e: f64, most: usize) -> Vec<f64> {
    let first = (from * (1.0 + e).powf(1.0 / (alpha - 1.0))).min(up_to);
    let mut ends = vec![first];
    let mut x = first;
    while x < up_to && ends.len() <= most {
        let next = (x * ratio_for(alpha, e, up_to / x)).min(up_to);
        if !(next > x) {
            ends.push(up_to);
            break;
        }
        ends.push(next);
        x = next;
    }
    ends
}

/// Fit `F = a p^alpha` (`alpha > 1`) with `pieces` linear pieces through
/// its values at their ends (the force is 0 at 0, continuous, exact at
/// every breakpoint, and above the curve between them), the breakpoints
/// placed so that the largest relative force error over `[from, up_to]`
/// is the least such interpolants have: every piece there has the same.
/// Below `from` the first piece is a line from 0, stiffer than the curve
/// (no line from 0 follows `p^alpha` there); above `up_to` the last piece
/// goes on straight. Returns the breakpoints, the stiffnesses and that
/// largest relative error.
pub fn fit_power(
    a: f64,
    alpha: f64,
    from: f64,
    up_to: f64,
    pieces: usize,
) -> (Vec<f64>, Vec<f64>, f64) {
    let force = |p: f64| a * p.powf(alpha);
    if !(alpha > 1.0) {
        return (Vec::new(), vec![force(up_to) / up_to], 0.0);
    }
    // the least error whose pieces reach `up_to` within `pieces`
    let one = (up_to / from).powf(alpha - 1.0) - 1.0;
    let (mut lo, mut hi) = (0.0, one * (1.0 + 1e-12));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if ends_for(alpha, from, up_to, mid, pieces).len() <= pieces {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let mut ends = ends_for(alpha, from, up_to, hi, pieces);
    ends.truncate(pieces);
    if let Some(last) = ends.last_mut() {
        *last = up_to;
    }
    let mut k = Vec::with_capacity(ends.len());
    let mut x0: f64 = 0.0;
    for &x1 in &ends {
        k.push((force(x1) - force(x0)) / (x1 - x0));
        x0 = x1;
    }
    let err = relative_error(&ends, alpha, from);
    ends.pop();
    (ends, k, err)
}

/// The largest relative error over `[from, ends.last]` of the
/// interpolant of `p^alpha` with pieces ending at `ends`.
fn relative_error(ends: &[f64], alpha: f64, from: f64) -> f64 {
    let mut err: f64 = 0.0;
    let mut x0: f64 = 0.0;
    for &x1 in ends {
        let e = if x0 > 0.0 {
            chord_error(alpha, x1 / x0)
        } else if from < x1 {
            (x1 / from).powf(alpha - 1.0) - 1.0
        } else {
            0.0
        };
        err = err.max(e);
        x0 = x1;
    }
    err
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law(power: f64, pieces: usize) -> LawSpec {
        LawSpec {
            power: Some(power),
            force_n_at: Some([1e-3, 50.0]),
            pieces: Some(pieces),
            up_to_m: Some(2e-3),
            ..LawSpec::default()
        }
    }

    /// Largest `|F_pieces / F - 1|` over a fine geometric grid of `[from,
    /// up_to]` (a tenth of 2 mm to 2 mm).
    fn sampled_error(p: &Pieces, power: f64) -> f64 {
        let a = 50.0 / 1e-3_f64.powf(power);
        (0..=20_000)
            .map(|i| {
                let x = 2e-4 * 10f64.powf(f64::from(i) / 20_000.0);
                (p.force(x) / (a * x.powf(power)) - 1.0).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_fitted_power_law_is_exact_at_its_breakpoints_and_its_error_falls_with_pieces() {
        for power in [1.5, 2.5, 3.5] {
            let a = 50.0 / 1e-3_f64.powf(power);
            let mut before = f64::INFINITY;
            for n in 1..=MAX_LAW_PIECES {
                let p = law(power, n).pieces("contact.law").unwrap();
                assert_eq!(p.stiffness.len(), n);
                for &q in &p.breakpoints {
                    let rel = (p.force(q) - a * q.powf(power)).abs() / (a * q.powf(power));
                    assert!(rel < 1e-12, "power {power}, {n} pieces: {rel:e} at {q}");
                }
                let sampled = sampled_error(&p, power);
                eprintln!(
                    "power {power}, {n} pieces: error {:.4} (sampled {sampled:.4}), k {:?}",
                    p.fit_error, p.stiffness
                );
                // the stated error is the largest (to the grid's resolution)
                assert!((sampled - p.fit_error).abs() < 1e-3 * p.fit_error.max(1e-9));
                assert!(p.fit_error < before, "power {power}: {n} pieces no better");
                before = p.fit_error;
            }
        }
    }

    #[test]
    fn a_linear_power_law_is_one_piece_without_error() {
        let p = law(1.0, 3).pieces("contact.law").unwrap();
        assert!(p.fit_error < 1e-12);
        let k = 50.0 / 1e-3;
        for x in [1e-4, 1e-3, 3e-3] {
            assert!((p.force(x) - k * x).abs() < 1e-9 * k * x);
        }
    }

    #[test]
    fn the_potential_is_the_integral_of_the_force() {
        let p = law(2.5, 4).pieces("contact.law").unwrap();
        let n = 100_000;
        let h = 3e-3 / f64::from(n);
        let mut e = 0.0;
        for i in 0..n {
            let x = (f64::from(i) + 0.5) * h;
            e += p.force(x) * h;
        }
        let want = p.potential(3e-3);
        assert!((e - want).abs() < 1e-8 * want, "{e} vs {want}");
    }

    #[test]
    fn bad_laws_name_their_field() {
        let cases: Vec<(LawSpec, &str)> = vec![
            (LawSpec::default(), "contact.law"),
            (law(0.5, 3), "contact.law.power"),
            (law(2.5, 9), "contact.law.pieces"),
            (
                LawSpec {
                    breakpoints_m: Some(vec![1e-3, 5e-4]),
                    stiffness_n_per_m: Some(vec![1e5, 2e5, 3e5]),
                    ..LawSpec::default()
                },
                "contact.law.breakpoints_m[1]",
            ),
            (
                LawSpec {
                    breakpoints_m: Some(vec![1e-3]),
                    stiffness_n_per_m: Some(vec![2e5, 1e5]),
                    ..LawSpec::default()
                },
                "contact.law.stiffness_n_per_m[1]",
            ),
            (
                LawSpec {
                    breakpoints_m: Some(vec![1e-3]),
                    stiffness_n_per_m: Some(vec![1e5]),
                    ..LawSpec::default()
                },
                "contact.law.stiffness_n_per_m",
            ),
            (
                LawSpec {
                    breakpoints_m: Some(vec![1e-3]),
                    power: Some(2.0),
                    ..LawSpec::default()
                },
                "contact.law",
            ),
        ];
        for (spec, field) in cases {
            let e = spec.pieces("contact.law").unwrap_err();
            assert_eq!(e.path, field, "{e}");
        }
    }
}
