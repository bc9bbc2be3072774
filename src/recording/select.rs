//! Which poles of the bands' fits are modes: each band's poles mapped back
//! to the recording's rate (frequency, T60, amplitude at the onset),
//! checked one by one, then merged across bands (the same mode found at
//! the common edge of two bands kept once) and limited in number.

use super::band::{band_signal, BandSignal, Lowpass, Plan};
use super::esprit::{self, Fit, Status};
use super::input::Located;
use super::{
    AnalysisOptions, DropReason, DroppedPole, Mode, RecordingError, LN_1000, MAX_EXTRAPOLATION_DB,
};
use std::f64::consts::PI;

/// A band with fewer decimated samples than this is not fitted.
const MIN_BAND_SAMPLES: usize = 24;

/// A pole counts as in its band's valid centre up to this fraction of
/// the half width beyond it (so a mode at a common edge is not lost to
/// both bands; the merge keeps one).
const EDGE_SLACK: f64 = 0.05;

/// The analysis's own noise floor, an amplitude relative to the
/// recording's peak: the band filter's stop band is 120 dB down, so a
/// strong mode's alias sits up to 1e-6 of its amplitude in every band;
/// the floor is 20 dB above that. (A recording's noise is far higher.)
const ALIAS_FLOOR: f64 = 1e-5;

/// A T60 beyond this many times the band's span is beyond the reach of
/// the recording.
const REACH: f64 = 30.0;

/// A T60 whose relative standard deviation is beyond this is not measured.
const MAX_T60_REL_SD: f64 = 0.5;

/// A mode kept by its band, before the merge.
#[derive(Debug, Clone)]
pub(crate) struct Candidate {
    mode: Mode,
    /// The band's index, plus `pass` times a million.
    band: usize,
    /// `|f - f_c|` over the valid half width.
    offset: f64,
}

/// The poles of every band, kept or dropped.
#[derive(Debug, Clone, Default)]
pub(crate) struct Found {
    kept: Vec<Candidate>,
    dropped: Vec<DroppedPole>,
}

/// Where a band is and how its poles map back to the recording.
struct BandCtx<'a> {
    /// The band's index, plus the pass's number times a million.
    index: usize,
    centre: f64,
    rate_hz: f64,
    lp: &'a Lowpass,
    plan: &'a Plan,
    onset: usize,
    /// The samples from the onset the extrapolation rule counts: the
    /// band filter's run-in from the span's start, plus the settling time
    /// (not a later start the user or a clipped attack asks for: what a
    /// mode lost there is measured, not guessed).
    unseen: f64,
    range: (f64, f64),
    min_snr_db: f64,
}

/// Fit every band of `plan` on `x` (scaled to peak 1) and sort the
/// poles; `pass` numbers the band plan (the merge keeps one of a mode
/// found in two bands, never two of the same band).
pub(crate) fn fit_bands(
    x: &[f64],
    rate_hz: f64,
    at: &Located,
    (plan, pass): (&Plan, usize),
    opts: &AnalysisOptions,
) -> Result<Found, RecordingError> {
    let lp = Lowpass::new(plan.decim);
    let mut found = Found::default();
    let mut fitted = 0;
    let range = (
        opts.freq_range_hz.0,
        opts.freq_range_hz.1.min(0.5 * rate_hz),
    );
    for (index, &centre) in plan.centres.iter().enumerate() {
        let sig = band_signal(
            x,
            &lp,
            centre,
            rate_hz,
            at.onset,
            (at.start, at.end),
            opts.window,
        );
        if sig.y.len() < MIN_BAND_SAMPLES {
            continue;
        }
        fitted += 1;
        let fit = esprit::fit(&sig.y, usize::MAX, ALIAS_FLOOR * ALIAS_FLOOR)?;
        let ctx = BandCtx {
            index: index + 1_000_000 * pass,
            centre,
            rate_hz,
            lp: &lp,
            plan,
            onset: at.onset,
            unseen: (lp.half() as f64)
                + (at.start - at.onset.min(at.start)).min((opts.settle_s * rate_hz) as usize)
                    as f64,
            range,
            min_snr_db: opts.min_snr_db,
        };
        classify(&ctx, &fit, &sig, at.peak, &mut found);
    }
    if fitted == 0 {
        let p = 2 * lp.half();
        return Err(RecordingError::TooShort {
            seconds: (at.end - at.start) as f64 / rate_hz,
            needed: (p + MIN_BAND_SAMPLES * plan.decim) as f64 / rate_hz,
        });
    }
    Ok(found)
}

/// Map a band's poles back to the recording and keep or drop each.
fn classify(ctx: &BandCtx<'_>, fit: &Fit, sig: &BandSignal, peak: f64, found: &mut Found) {
    let d = ctx.plan.decim as f64;
    let span_s = sig.y.len() as f64 * d / ctx.rate_hz;
    for k in 0..fit.poles.len() {
        let ln_w = esprit::log(fit.poles[k]) / d;
        let offset = ln_w.im * ctx.rate_hz / (2.0 * PI);
        let alpha = -ln_w.re * ctx.rate_hz;
        let lag = sig.first as f64 - ctx.onset as f64;
        let gain = ctx.lp.response(ln_w) * (ln_w * lag).exp();
        let a = fit.amps[k] / gain;
        let amplitude = 2.0 * a.norm() * peak;
        let sd = fit.sd[k];
        let mode = Mode {
            freq_hz: ctx.centre + offset,
            t60_s: LN_1000 / alpha,
            amplitude: if amplitude.is_finite() {
                amplitude
            } else {
                0.0
            },
            phase_rad: a.im.atan2(a.re),
            snr_db: 10.0 * fit.snr[k].max(1e-30).log10(),
            freq_sd_hz: sd * ctx.rate_hz / (2.0 * PI * d),
            t60_rel_sd: sd * ctx.rate_hz / d / alpha.abs().max(1e-300),
        };
        let lag_db = 20.0 * alpha * ctx.unseen / ctx.rate_hz / std::f64::consts::LN_10;
        let why = reason(ctx, &mode, offset, alpha, fit.status[k], span_s)
            .or_else(|| (lag_db > MAX_EXTRAPOLATION_DB).then_some(DropReason::TooFast(lag_db)));
        match why {
            Some(reason) => found.dropped.push(DroppedPole {
                freq_hz: mode.freq_hz,
                t60_s: mode.t60_s,
                level_db: mode.level_db(),
                reason,
            }),
            None => found.kept.push(Candidate {
                mode,
                band: ctx.index,
                offset: offset.abs() / (0.5 * ctx.plan.width_hz),
            }),
        }
    }
}

/// Why a pole is not a mode, or `None` when it is.
fn reason(
    ctx: &BandCtx<'_>,
    mode: &Mode,
    offset: f64,
    alpha: f64,
    status: Status,
    span_s: f64,
) -> Option<DropReason> {
    if status == Status::Merged {
        Some(DropReason::Merged)
    } else if !(alpha > 0.0) {
        Some(DropReason::Growing)
    } else if offset.abs() > 0.5 * ctx.plan.width_hz * (1.0 + EDGE_SLACK) {
        Some(DropReason::OutsideBandCentre)
    } else if !(mode.freq_hz >= ctx.range.0 && mode.freq_hz <= ctx.range.1) {
        Some(DropReason::OutsideRange)
    } else if status == Status::Unstable {
        Some(DropReason::Unstable)
    } else if !(mode.snr_db >= ctx.min_snr_db) {
        Some(DropReason::BelowNoise(mode.snr_db))
    } else if mode.t60_s > REACH * span_s || !(mode.t60_rel_sd <= MAX_T60_REL_SD) {
        Some(DropReason::BeyondReach)
    } else {
        None
    }
}

/// Put the fast pass's modes (wide bands, short filters) into the fine
/// pass's: a fast mode of T60 under `t60_max` replaces the fine mode it
/// matches when its uncertainty is lower, and joins the modes when no fine
/// mode matches it (the fine pass's long filter saw too little of it).
pub(crate) fn combine(fine: Found, fast: Found, t60_max: f64) -> Found {
    let Found { mut kept, dropped } = fine;
    for c in fast.kept {
        if !(c.mode.t60_s < t60_max) {
            continue;
        }
        let near = kept.iter_mut().find(|k| {
            (k.mode.freq_hz - c.mode.freq_hz).abs()
                < 10.0 * (k.mode.freq_sd_hz + c.mode.freq_sd_hz) + 1e-6 * c.mode.freq_hz
        });
        match near {
            Some(k) if c.mode.freq_sd_hz < k.mode.freq_sd_hz => *k = c,
            Some(_) => {}
            None => kept.push(c),
        }
    }
    Found { kept, dropped }
}

/// Merge the bands' modes: one of each pair found by two neighbouring
/// bands (the one nearer its band's centre), then the strongest
/// `max_modes`; the modes by frequency, and every dropped pole.
pub(crate) fn merge(found: Found, max_modes: Option<usize>) -> (Vec<Mode>, Vec<DroppedPole>) {
    let Found {
        mut kept,
        mut dropped,
    } = found;
    kept.sort_by(|a, b| a.mode.freq_hz.total_cmp(&b.mode.freq_hz));
    let mut merged: Vec<Candidate> = Vec::with_capacity(kept.len());
    for c in kept {
        if let Some(last) = merged.last_mut() {
            let tol = 10.0 * (last.mode.freq_sd_hz + c.mode.freq_sd_hz) + 1e-6 * c.mode.freq_hz;
            if last.band != c.band && (c.mode.freq_hz - last.mode.freq_hz).abs() < tol {
                let loser = if c.offset < last.offset {
                    std::mem::replace(last, c)
                } else {
                    c
                };
                dropped.push(dropped_as(&loser.mode, DropReason::Duplicate));
                continue;
            }
        }
        merged.push(c);
    }
    let mut modes: Vec<Mode> = merged.into_iter().map(|c| c.mode).collect();
    if let Some(n) = max_modes {
        modes.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
        for m in modes.iter().skip(n) {
            dropped.push(dropped_as(m, DropReason::OverLimit));
        }
        modes.truncate(n);
        modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    }
    dropped.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    (modes, dropped)
}

fn dropped_as(m: &Mode, reason: DropReason) -> DroppedPole {
    DroppedPole {
        freq_hz: m.freq_hz,
        t60_s: m.t60_s,
        level_db: m.level_db(),
        reason,
    }
}

/// The dropped poles counted by reason, as one line.
pub(crate) fn summary(dropped: &[DroppedPole]) -> String {
    if dropped.is_empty() {
        return "no singular value above the noise's in any band".into();
    }
    let mut counts: Vec<(String, usize)> = Vec::new();
    for d in dropped {
        let name = match d.reason {
            DropReason::BelowNoise(_) => "below the noise".to_string(),
            DropReason::TooFast(_) => "decaying before their band's first sample".to_string(),
            r => r.to_string(),
        };
        match counts.iter_mut().find(|(n, _)| *n == name) {
            Some((_, c)) => *c += 1,
            None => counts.push((name, 1)),
        }
    }
    let parts: Vec<String> = counts.iter().map(|(n, c)| format!("{c} {n}")).collect();
    format!("poles dropped: {}", parts.join(", "))
}
