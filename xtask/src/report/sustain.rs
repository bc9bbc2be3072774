//! f32 against f64 state on a long sustain (docs/numerics.md, "f32 or f64"): the
//! engine's exact 2x2 block propagator of one free mode, `exp2` in f64, run in
//! f64 and (coefficients and state cast) in f32, free decay from the unit
//! state over 1e6 samples.

use super::scenes::RATE;
use modal_contact::physics::block::{exp2, Mat2};
use modal_contact::physics::model::LN_1000;
use std::f64::consts::PI;

/// Samples of every sustain run (22.7 s at 44.1 kHz).
pub(crate) const SUSTAIN_N: usize = 1_000_000;
/// Mode frequencies \[Hz\].
pub(crate) const FREQS: [f64; 5] = [20.0, 200.0, 1000.0, 5000.0, 15_000.0];
/// T60 \[s\] (infinity: undamped).
pub(crate) const T60S: [f64; 4] = [1.0, 10.0, 100.0, f64::INFINITY];
/// f32 unit roundoff.
const U32: f64 = 5.960_464_477_539_063e-8;

/// Results of one mode.
#[derive(Debug, Clone)]
pub(crate) struct SustainRow {
    pub f: f64,
    pub t60: f64,
    /// Instant the comparison is taken at \[s\]: the end, or when the f64
    /// amplitude has fallen to 1e-6 (-120 dB), whichever is first.
    pub t_eval: f64,
    /// f32 amplitude / f64 amplitude - 1 at `t_eval`.
    pub amp_err: f64,
    /// Phase difference f32 - f64 at `t_eval` \[rad\] and the pitch error it
    /// means \[cent\].
    pub phase_err: f64,
    pub pitch_cent: f64,
    /// Pitch error of the rounded propagator's eigenvalue \[cent\] (the
    /// coefficient-quantisation part alone).
    pub pitch_cent_coeff: f64,
    /// Fraction of steps whose energy increases: f32, f32 with the pole
    /// rounded down by 4u, f64; and the largest relative increase of f32.
    pub frac_up_f32: f64,
    /// Fraction of the steps before the first subnormal f32 state whose
    /// energy increases.
    pub frac_up_f32_normal: f64,
    /// (Shrunk run: counted before its first subnormal state.)
    pub frac_up_f32_shrunk: f64,
    pub frac_up_f64: f64,
    pub max_up_f32: f64,
    pub max_up_f64: f64,
    /// f32 energy / f64 energy - 1 at `t_eval`, plain and shrunk.
    pub energy_err: f64,
    pub energy_err_shrunk: f64,
    /// First time the f32 state is subnormal \[s\].
    pub subnormal_at: Option<f64>,
}

struct Run {
    /// Per-step energies are not kept; the counters are.
    ups: usize,
    /// Increases before the first subnormal state.
    ups_normal: usize,
    max_up: f64,
    state_at_eval: (f64, f64),
    subnormal_at: Option<usize>,
}

fn run_f64(p: &Mat2, n: usize, eval: usize) -> Run {
    let (mut x, mut y) = (1.0f64, 0.0f64);
    let mut e = 1.0;
    let mut r = Run {
        ups: 0,
        ups_normal: 0,
        max_up: 0.0,
        state_at_eval: (x, y),
        subnormal_at: None,
    };
    for i in 1..=n {
        let nx = p[0] * x + p[1] * y;
        let ny = p[2] * x + p[3] * y;
        x = nx;
        y = ny;
        let en = x * x + y * y;
        if en > e {
            r.ups += 1;
            r.max_up = r.max_up.max((en - e) / e);
        }
        e = en;
        if i == eval {
            r.state_at_eval = (x, y);
        }
    }
    r
}

fn run_f32(p: &[f32; 4], n: usize, eval: usize) -> Run {
    let (mut x, mut y) = (1.0f32, 0.0f32);
    let mut e = 1.0f64;
    let mut r = Run {
        ups: 0,
        ups_normal: 0,
        max_up: 0.0,
        state_at_eval: (1.0, 0.0),
        subnormal_at: None,
    };
    for i in 1..=n {
        let nx = p[0] * x + p[1] * y;
        let ny = p[2] * x + p[3] * y;
        x = nx;
        y = ny;
        let (xd, yd) = (x as f64, y as f64);
        let en = xd * xd + yd * yd;
        if r.subnormal_at.is_none() && (x.is_subnormal() || y.is_subnormal()) {
            r.subnormal_at = Some(i);
        }
        if en > e {
            r.ups += 1;
            if r.subnormal_at.is_none() {
                r.ups_normal += 1;
            }
            if e > 0.0 {
                r.max_up = r.max_up.max((en - e) / e);
            }
        }
        e = en;
        if i == eval {
            r.state_at_eval = (xd, yd);
        }
    }
    r
}

/// Angle of the upper-half-plane eigenvalue of a real 2x2 with complex
/// eigenvalues (NaN otherwise).
fn eig_angle(p: &[f64; 4]) -> f64 {
    let tr = p[0] + p[3];
    let det = p[0] * p[3] - p[1] * p[2];
    let disc = det - 0.25 * tr * tr;
    if disc > 0.0 {
        disc.sqrt().atan2(0.5 * tr)
    } else {
        f64::NAN
    }
}

/// One mode.
pub(crate) fn run_mode(f: f64, t60: f64) -> SustainRow {
    let h = 1.0 / RATE;
    let w = 2.0 * PI * f;
    let sigma = if t60.is_finite() { LN_1000 / t60 } else { 0.0 };
    // modal block over (omega q, q'), as in the engine's free phase
    let g: Mat2 = [0.0, w, -w, -2.0 * sigma];
    let p64 = exp2(&g, h);
    let p32 = p64.map(|v| v as f32);
    // |p|^2 <= r^2 (1 - 4u) (docs/numerics.md, "f32 or f64"): entries times (1 - 2u)
    let shrink = 1.0 - 2.0 * U32;
    let p32s = p64.map(|v| (v * shrink) as f32);
    // evaluation instant: amplitude e^{-sigma t} = 1e-6 at t = 2 T60
    let n = SUSTAIN_N;
    let eval = if t60.is_finite() {
        ((2.0 * t60 * RATE) as usize).clamp(1, n)
    } else {
        n
    };
    let r64 = run_f64(&p64, n, eval);
    let r32 = run_f32(&p32, n, eval);
    let r32s = run_f32(&p32s, n, eval);
    let t_eval = eval as f64 * h;
    let (x64, y64) = r64.state_at_eval;
    let (x32, y32) = r32.state_at_eval;
    let (xs, ys) = r32s.state_at_eval;
    let a64 = x64.hypot(y64);
    let a32 = x32.hypot(y32);
    let mut dphi = y32.atan2(x32) - y64.atan2(x64);
    while dphi > PI {
        dphi -= 2.0 * PI;
    }
    while dphi < -PI {
        dphi += 2.0 * PI;
    }
    let wd = (w * w - sigma * sigma).max(0.0).sqrt();
    let cents = |ratio: f64| 1200.0 * ratio.log2();
    // phase runs clockwise in (omega q, q') for this block: a faster f32
    // oscillator has a more negative phase
    let pitch_cent = cents(1.0 - dphi / (wd * t_eval));
    let p32d: [f64; 4] = p32.map(|v| v as f64);
    let pitch_cent_coeff = cents(eig_angle(&p32d) / eig_angle(&p64));
    let e64 = x64 * x64 + y64 * y64;
    SustainRow {
        f,
        t60,
        t_eval,
        amp_err: a32 / a64 - 1.0,
        phase_err: dphi,
        pitch_cent,
        pitch_cent_coeff,
        frac_up_f32: r32.ups as f64 / n as f64,
        frac_up_f32_normal: r32.ups_normal as f64 / r32.subnormal_at.map_or(n, |i| i.max(1)) as f64,
        frac_up_f32_shrunk: r32s.ups_normal as f64
            / r32s.subnormal_at.map_or(n, |i| i.max(1)) as f64,
        frac_up_f64: r64.ups as f64 / n as f64,
        max_up_f32: r32.max_up,
        max_up_f64: r64.max_up,
        energy_err: (x32 * x32 + y32 * y32) / e64 - 1.0,
        energy_err_shrunk: (xs * xs + ys * ys) / e64 - 1.0,
        subnormal_at: r32.subnormal_at.map(|i| i as f64 * h),
    }
}

/// Every mode and T60.
pub(crate) fn run_all() -> Vec<SustainRow> {
    let mut v = Vec::new();
    for t60 in T60S {
        for f in FREQS {
            v.push(run_mode(f, t60));
        }
    }
    v
}

/// Markdown table.
pub(crate) fn markdown(rows: &[SustainRow]) -> String {
    let mut s = String::from(
        "| f [Hz] | T60 [s] | t_eval [s] | f32 amplitude err | f32 energy err | f32 phase err [rad] | f32 pitch err [cent] (coeff. only) | steps with E up: f32 all (before subnormals) / f32 pole -4u before subnormals / f64 | max rel. step gain f32 / f64 | f32 energy err, pole -4u | f32 subnormal from |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let t60 = if r.t60.is_finite() {
            format!("{}", r.t60)
        } else {
            "inf".into()
        };
        s += &format!(
            "| {} | {t60} | {:.2} | {:+.2e} | {:+.2e} | {:+.2e} | {:+.1e} ({:+.1e}) | {:.1}% ({:.1}%) / {:.1}% / {:.1}% | {:.1e} / {:.1e} | {:+.2e} | {} |\n",
            r.f,
            r.t_eval,
            r.amp_err,
            r.energy_err,
            r.phase_err,
            r.pitch_cent,
            r.pitch_cent_coeff,
            100.0 * r.frac_up_f32,
            100.0 * r.frac_up_f32_normal,
            100.0 * r.frac_up_f32_shrunk,
            100.0 * r.frac_up_f64,
            r.max_up_f32,
            r.max_up_f64,
            r.energy_err_shrunk,
            r.subnormal_at
                .map_or("never".into(), |t| format!("{t:.1} s")),
        );
    }
    s
}
