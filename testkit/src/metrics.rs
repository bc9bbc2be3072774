//! The measures the tests, the stiff test and the report compare runs with:
//! relative L2 errors, contacts collected from the engine's switch log and
//! matched by order, and the rounding allowance of the energy checks.
//!
//! Written once so that "agrees to 1e-9" or "the same contacts" means the
//! same thing in a test's assertion as in the report's table.

use modal_contact::compile::CompiledScene;
use modal_contact::engine::Observation;
use modal_contact::multi::{MultiModel, MultiState};
use std::ops::Range;

/// f64 unit roundoff, `2^-53`.
pub const U: f64 = f64::EPSILON / 2.0;

// ------------------------------------------------------------- relative L2

/// Relative L2 difference `|a - reference| / |reference|` of two signals of
/// the same length (a length mismatch is a bug in the test: it panics).
///
/// Identical signals give 0 even when both are silent (they agree
/// perfectly); otherwise a silent reference gives infinity and a
/// non-finite value anywhere gives NaN, so `err <= tol` fails on both.
pub fn rel_l2(a: &[f64], reference: &[f64]) -> f64 {
    assert_eq!(a.len(), reference.len(), "rel_l2 of different lengths");
    let num: f64 = a
        .iter()
        .zip(reference)
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    if num == 0.0 {
        return 0.0;
    }
    let den: f64 = reference.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

/// The report's form of [`rel_l2`]: over `window` (clipped to both
/// signals), `None` when the reference is silent there (no error to
/// speak of: the wall scene has no pickup), infinity when `a` holds a
/// non-finite value in the window (a diverged run is infinitely wrong,
/// not "NaN").
pub fn rel_l2_window(a: &[f64], reference: &[f64], window: Range<usize>) -> Option<f64> {
    let end = window.end.min(a.len()).min(reference.len());
    let start = window.start.min(end);
    let den: f64 = reference[start..end].iter().map(|y| y * y).sum();
    if !(den > 0.0) {
        return None;
    }
    let mut num = 0.0;
    for (x, y) in a[start..end].iter().zip(&reference[start..end]) {
        if !x.is_finite() {
            return Some(f64::INFINITY);
        }
        num += (x - y) * (x - y);
    }
    Some((num / den).sqrt())
}

// ---------------------------------------------------------------- contacts

/// One contact: start and end in the caller's unit (seconds or samples);
/// `end` is `None` when the run ended in contact and the caller did not
/// close it.
pub type Interval = (f64, Option<f64>);

/// What is wrong with a switch log: two entries in a row, or an exit
/// without an entry. Either means the engine lost track of its phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LogAnomaly {
    /// Entered again while in contact since `since`.
    EnteredWhileInContact {
        /// When the open contact started (the caller's unit).
        since: f64,
    },
    /// Left contact without having entered.
    LeftWithoutEntering,
}

/// Contacts collected from a run's switch log, one event at a time
/// (`EngineState::switch_events` after each tick, at `t_n + after_s`).
#[derive(Debug, Default, Clone)]
pub struct ContactLog {
    intervals: Vec<Interval>,
    open: Option<f64>,
}

impl ContactLog {
    /// Record a switch at `t`: entering contact (`entered`) or leaving it.
    /// An inconsistent event is reported, and handled as the engine's
    /// phase says: a second entry restarts the open contact, an exit
    /// without entry is dropped.
    pub fn record(&mut self, t: f64, entered: bool) -> Result<(), LogAnomaly> {
        if entered {
            match self.open.replace(t) {
                Some(since) => Err(LogAnomaly::EnteredWhileInContact { since }),
                None => Ok(()),
            }
        } else if let Some(t0) = self.open.take() {
            self.intervals.push((t0, Some(t)));
            Ok(())
        } else {
            Err(LogAnomaly::LeftWithoutEntering)
        }
    }

    /// The contacts; one still open ends at `end` (`None`: left open).
    pub fn finish(mut self, end: Option<f64>) -> Vec<Interval> {
        if let Some(t0) = self.open {
            self.intervals.push((t0, end));
        }
        self.intervals
    }
}

/// Two runs' contacts matched by order (the k-th contact of one with the
/// k-th of the other), on the contacts that start by a time limit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContactMatch {
    /// Contacts of the run that start by the limit.
    pub n_run: usize,
    /// Contacts of the reference that start by the limit.
    pub n_ref: usize,
    /// Largest start difference over the matched pairs.
    pub max_start: f64,
    /// Largest end difference over the matched pairs (infinite when only
    /// one of the two ended by the limit).
    pub max_end: f64,
    /// Mean start difference over the matched pairs.
    pub mean_start: f64,
    /// Per matched pair, the larger of its start and end differences.
    pub pair_errors: Vec<f64>,
}

impl ContactMatch {
    /// Reference contacts without a partner.
    pub fn missed(&self) -> usize {
        self.n_ref.saturating_sub(self.n_run)
    }

    /// Run contacts without a partner.
    pub fn extra(&self) -> usize {
        self.n_run.saturating_sub(self.n_ref)
    }

    /// The largest instant difference of any matched pair.
    pub fn worst(&self) -> f64 {
        self.max_start.max(self.max_end)
    }

    /// The first matched pair that differs by more than `tol`.
    pub fn first_beyond(&self, tol: f64) -> Option<usize> {
        self.pair_errors.iter().position(|&d| d > tol)
    }
}

/// Which contact ends [`match_contacts`] compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ends {
    /// An end is compared when both runs ended the contact before the
    /// limit; a contact still open there in either run is compared by its
    /// start only. For runs that part by chaos after a while: their late
    /// contacts are compared for what is determined.
    BothEnded,
    /// An end is compared when either run ended the contact by the limit,
    /// and one that only one run has by then is infinitely far: before the
    /// limit nothing is forgiven.
    EitherEnded,
}

/// Match `run` against `reference` on the contacts starting at or before
/// `until` (`f64::INFINITY`: all), comparing the ends `ends` says.
/// Differences are `|a - b| * scale` (e.g. the rate, for intervals in
/// seconds and errors in samples).
pub fn match_contacts(
    run: &[Interval],
    reference: &[Interval],
    until: f64,
    scale: f64,
    ends: Ends,
) -> ContactMatch {
    let within = |c: &&Interval| c.0 <= until;
    let a: Vec<&Interval> = run.iter().filter(within).collect();
    let b: Vec<&Interval> = reference.iter().filter(within).collect();
    let mut m = ContactMatch {
        n_run: a.len(),
        n_ref: b.len(),
        ..ContactMatch::default()
    };
    let mut sum = 0.0;
    for (x, y) in a.iter().zip(&b) {
        let ds = (x.0 - y.0).abs() * scale;
        let de = match (ends, x.1, y.1) {
            (Ends::BothEnded, Some(ex), Some(ey)) if ex < until && ey < until => {
                (ex - ey).abs() * scale
            }
            (Ends::EitherEnded, Some(ex), Some(ey)) if ex.min(ey) <= until => {
                (ex - ey).abs() * scale
            }
            (Ends::EitherEnded, Some(e), None) | (Ends::EitherEnded, None, Some(e))
                if e <= until =>
            {
                f64::INFINITY
            }
            _ => 0.0,
        };
        m.max_start = m.max_start.max(ds);
        m.max_end = m.max_end.max(de);
        m.pair_errors.push(ds.max(de));
        sum += ds;
    }
    let pairs = m.pair_errors.len();
    m.mean_start = if pairs > 0 { sum / pairs as f64 } else { 0.0 };
    m
}

/// How far two runs' contacts stay determined (intervals in samples): the
/// last sample before the first contact that the two place more than `tol`
/// apart (start or end), or that only one of them has; `n` when they agree
/// on every contact. Used with a reference and its slightly disturbed twin,
/// it says where the inputs stop determining the instants.
pub fn instant_horizon(a: &[Interval], b: &[Interval], tol: f64, n: usize) -> usize {
    let before = |s: f64| (s.ceil() as usize).saturating_sub(1);
    for (i, x) in a.iter().enumerate() {
        let Some(y) = b.get(i) else {
            return before(x.0);
        };
        let ends_differ = match (x.1, y.1) {
            (Some(e), Some(f)) => (e - f).abs() > tol,
            (None, None) => false,
            _ => true,
        };
        if (x.0 - y.0).abs() > tol || ends_differ {
            return before(x.0.min(y.0));
        }
    }
    match b.get(a.len()) {
        Some(y) => before(y.0),
        None => n,
    }
}

// ------------------------------------------------------------------ energy

/// How much the observed energy may rise from one sample to the next by
/// rounding alone, relative to [`energy_scale`]: `64 dim kappa u`. The
/// energy is observed through the compiled change of basis, a row of `dim`
/// terms each rounded once and amplified by the condition number `kappa`
/// of the phases' eigenvector matrices (1 when it is not finite, e.g. for
/// a phase without a basis), with a safety factor. The stability suite, the
/// stiff test hold every run to it (the fuzzer and `tests/energy.rs` use their own variants).
pub fn energy_rounding_bound(sc: &CompiledScene) -> f64 {
    let kappa = sc.free.diag.kappa.max(sc.contact.diag.kappa);
    let kappa = if kappa.is_finite() { kappa } else { 1.0 };
    64.0 * sc.contact.dim as f64 * kappa * U
}

/// The energy scale of an observation, `|E| + 2 m_h g |x_h|`: with gravity
/// the total energy can be near zero while its parts (the hammer's
/// potential energy among them) are large, and rounding follows the parts.
pub fn energy_scale(obs: &Observation, m_g: f64) -> f64 {
    obs.energy.abs() + 2.0 * m_g * obs.x_hammer.abs()
}

/// What the offset rods of a several-contact state add to its energy's
/// rounding scale: a rod `d_j` shifts the equilibrium the state is held
/// about by `sqrt(k_j) d_j` in energy coordinates, so its rounding moves
/// an energy `E` by up to `sqrt(2 E k_j) d_j` (docs/numerics.md section
/// 14, "The offset rod per contact"); 0 with exact switching.
pub fn rod_energy_scale(m: &MultiModel, st: &MultiState, energy: f64) -> f64 {
    m.contacts
        .iter()
        .enumerate()
        .map(|(j, c)| (2.0 * energy.abs() * c.stiffness_n_per_m).sqrt() * st.rod(j).abs())
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rel_l2_of_identical_signals_is_zero_even_when_silent() {
        assert_eq!(rel_l2(&[0.0, 0.0], &[0.0, 0.0]), 0.0);
        assert_eq!(rel_l2(&[1.0, 2.0], &[1.0, 2.0]), 0.0);
        assert!((rel_l2(&[1.0, 0.0], &[2.0, 0.0]) - 0.5).abs() < 1e-16);
        assert!(rel_l2(&[f64::NAN, 0.0], &[1.0, 0.0]).is_nan());
        assert_eq!(rel_l2_window(&[1.0], &[0.0], 0..1), None);
        assert_eq!(
            rel_l2_window(&[f64::NAN], &[1.0], 0..1),
            Some(f64::INFINITY)
        );
    }

    #[test]
    fn contacts_are_logged_and_matched_by_order() {
        let mut log = ContactLog::default();
        log.record(1.0, true).unwrap();
        log.record(2.0, false).unwrap();
        assert_eq!(log.record(3.0, false), Err(LogAnomaly::LeftWithoutEntering));
        log.record(4.0, true).unwrap();
        assert_eq!(
            log.record(4.5, true),
            Err(LogAnomaly::EnteredWhileInContact { since: 4.0 })
        );
        let run = log.clone().finish(Some(6.0));
        assert_eq!(run, vec![(1.0, Some(2.0)), (4.5, Some(6.0))]);
        assert_eq!(log.finish(None), vec![(1.0, Some(2.0)), (4.5, None)]);

        let reference = vec![(1.0, Some(2.5)), (4.0, None), (7.0, Some(8.0))];
        let m = match_contacts(&run, &reference, f64::INFINITY, 10.0, Ends::EitherEnded);
        assert_eq!((m.n_run, m.n_ref, m.missed(), m.extra()), (2, 3, 1, 0));
        assert_eq!(m.max_start, 5.0);
        assert_eq!(m.max_end, f64::INFINITY);
        assert_eq!(m.first_beyond(4.0), Some(0));
        // before the end of the open contact, nothing beyond the limit counts
        let m = match_contacts(&run, &reference, 5.0, 1.0, Ends::EitherEnded);
        assert_eq!((m.n_run, m.n_ref), (2, 2));
        assert_eq!((m.max_start, m.max_end), (0.5, 0.5));
        assert_eq!(m.mean_start, 0.25);
        // an end only one run has by the limit
        let m = match_contacts(&run, &reference, 6.5, 1.0, Ends::EitherEnded);
        assert_eq!(m.max_end, f64::INFINITY);
        let m = match_contacts(&run, &reference, 6.5, 1.0, Ends::BothEnded);
        assert_eq!((m.max_start, m.max_end), (0.5, 0.5));
    }

    #[test]
    fn the_instant_horizon_stops_before_the_first_disagreement() {
        let a = vec![(10.2, Some(11.5)), (20.5, Some(21.0))];
        let b = vec![(10.2, Some(11.5)), (20.5, Some(21.1))];
        assert_eq!(instant_horizon(&a, &a, 1e-6, 100), 100);
        assert_eq!(instant_horizon(&a, &b, 1e-6, 100), 20);
        assert_eq!(instant_horizon(&a[..1], &b, 1e-6, 100), 20);
    }
}
