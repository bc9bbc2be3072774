//! The scene file of an analysed recording: one modal object with the
//! modes found, a mallet whose contact lasts as long as the recording's
//! attack suggests, and a velocity pickup, scaled so an offline render
//! of the scene plays the recording's modes at the recording's level.
//!
//! # Weights
//!
//! A recording gives, per mode, the product of the mode's shape at the
//! strike point and at the microphone, times the force pulse's spectrum
//! at the mode's frequency, times unknown gains (the microphone's, the
//! strike's strength): never the shapes alone. The scene therefore gives
//! the contact and the pickup weights of one magnitude `|w_i|` for mode
//! `i`, which is the one choice that needs nothing the recording does not
//! say: the engine's velocity pickup then plays mode `i` at
//! `gain J w_c,i w_p,i |F(f_i)|` (`J` the impulse of the contact, `F` its
//! normalised force spectrum), so `|w_i|^2` is taken proportional to the
//! recorded amplitude over `|F(f_i)|`.
//!
//! The sign of the product is in the recording: after a short pulse a
//! mode's velocity starts as `+-cos(omega (t - t_c) + atan(alpha /
//! omega))`, `t_c` the pulse's centre, so its phase at the onset is 0 or pi
//! once the common delay `t_c` is taken out. The delay is the one (within
//! 3 ms of the onset, in steps of 1 us) that brings the phases nearest 0
//! or pi, weighted by amplitude (`sum A_i cos(2 (phase_i - expected_i))`
//! largest); a mode whose phase is then nearer pi gets a negative product.
//! The contact weights are positive (a mode's shape is signed so at the
//! strike point, as the presets do) and the pickup weights carry the
//! signs: at the strike point itself every product would be positive, and
//! the onset's click (the jump of the modes' sum at the strike) would be
//! wrong. With every sign positive the two points would be one.
//!
//! The weights are known up to one common scale, set by stating the
//! object's mass at the contact point: `1 / sum w_i^2` (the mass an
//! impulse sees there) is ten times the mallet's, so the mallet is light
//! against the object, as a mallet on a bowl, a bell or a pot lid is, and
//! the contact lasts `pi sqrt(m_eff / k)` with `m_eff` the mallet's mass
//! in series with that point mass (`m / 1.1`). The pickup's gain then
//! brings the render to the recording's level.
//!
//! # The mallet
//!
//! The mass is a stated default, [`DEFAULT_MALLET_KG`]. The contact time
//! `tau` is fitted against renders: the scene is written and rendered for
//! contact times around a first estimate, and the one whose render's
//! 1/3-octave distance to the recording over the first half second
//! ([`super::distance`], from each one's onset) is least is kept. The
//! first estimate comes from the onset's steepest slope
//! (during a half-sine force pulse the velocity rises by its jump `j` as
//! `(1 - cos(pi t / tau)) / 2`, whose largest first difference at the
//! sampling step `h` is `d = j sin(pi h / (2 tau))`; `d` is the largest
//! first difference within 1 ms of the onset and `j` first the largest
//! magnitude there, then the rise across the pulse that first estimate
//! gives, centred on the steepest step; `tau = pi h / (2 asin(d / j))`);
//! without a slope (a silent onset), `1 / f_top`, with `f_top` the highest
//! mode within 40 dB of the strongest. The search tries the estimate times
//! `2^(k/2)` over the whole range allowed, then halves the step twice
//! around the best (up to 21 renders); `tau` is kept within 5 ms and three sampling steps
//! (at least 20 us): a shorter pulse differs only at the top of the band
//! and stiffens the contact. The slope alone
//! misreads a recording whose onset is not the contact's force (a
//! microphone's distance, a room, a trimmed sample) and a soft mallet,
//! whose slow pulse the modes' own swing hides. The weights divide by
//! `|F(f_i)|` down to -40 dB, no further. The stiffness is
//! `m_eff (pi / tau)^2`. The contact's damping ratio is then fitted the
//! same way ([`DAMPING_RATIOS`], then finer steps around the best), and
//! the weights are corrected by the amplitudes the written scene's
//! render plays (`corrected_weights`), while that brings the render
//! nearer the recording.

use super::distance::{band_levels, third_octave_distance, welch};
use super::{Analysis, RecordingError};
use crate::compile::compile_one;
use crate::render::{render, RenderOptions};
use crate::scene::Scene;
use std::f64::consts::PI;
use std::fmt::Write as _;

/// The mallet's mass when nothing says otherwise \[kg\]: a 50 g head.
pub const DEFAULT_MALLET_KG: f64 = 0.05;

/// The object's mass at the contact point over the mallet's.
const POINT_MASS_RATIO: f64 = 10.0;

/// The contact time's bounds \[s\]; the shortest is also at least
/// [`MIN_CONTACT_SAMPLES`] sampling steps.
const CONTACT_S: (f64, f64) = (20e-6, 5e-3);

/// The shortest contact in sampling steps: a half-sine pulse of three
/// steps has its first spectral zero at the Nyquist frequency, so a
/// shorter one changes only the top of the band, and it stiffens the
/// contact beyond what the exact event search resolves within its node
/// budget at real time (docs/numerics.md, "Why it terminates, and what it
/// costs").
const MIN_CONTACT_SAMPLES: f64 = 3.0;

/// The contact time's bounds at `rate_hz` \[s\].
fn contact_bounds(rate_hz: f64) -> (f64, f64) {
    (CONTACT_S.0.max(MIN_CONTACT_SAMPLES / rate_hz), CONTACT_S.1)
}

/// The strike's speed in the scene \[m/s\] (offline renders).
const STRIKE_M_PER_S: f64 = 1.0;

/// The stretch the contact time is fitted over, from the onset \[s\] (the
/// distance `cargo xtask analyze` reports is over the same).
pub const FIT_S: f64 = 0.5;

/// The contact times the fit tries first: the estimate times `2^(k/2)`
/// for `k` in `-FIT_SPAN..=FIT_SPAN`, those within the bounds (which
/// they span: at least 20 us and 5 ms are 8 octaves apart).
const FIT_SPAN: i32 = 16;

/// Halvings of the step around the best contact time after the first
/// grid (two on each side each: 2^(1/4), 2^(1/8)).
const FIT_REFINE: i32 = 2;

/// The least normalised force spectrum a weight is divided by (-40 dB),
/// so a mode near a zero of the pulse's spectrum is not blown up.
const MIN_SPECTRUM: f64 = 0.01;

/// The mallet estimated from the recording's attack.
#[derive(Debug, Clone, PartialEq)]
pub struct MalletEstimate {
    /// The mallet's mass \[kg\] ([`DEFAULT_MALLET_KG`]).
    pub mass_kg: f64,
    /// The contact time the onset's steepest slope gives \[s\].
    pub rise_s: f64,
    /// The highest mode within 40 dB of the strongest \[Hz\].
    pub top_mode_hz: f64,
    /// The contact time the fit started from: the slope's, else
    /// `1 / top_mode_hz`, within the bounds \[s\].
    pub first_s: f64,
    /// The contact time chosen: the fitted one \[s\].
    pub contact_s: f64,
    /// The contact stiffness \[N/m\].
    pub stiffness_n_per_m: f64,
    /// The contact's damping ratio (of the mallet in series with the
    /// point mass on the stiffness), fitted against renders after the
    /// contact time: none, or from 0.02 to 0.5 and between.
    pub damping_ratio: f64,
    /// The chosen scene's render: its 1/3-octave distance to the recording
    /// over the first [`FIT_S`] \[dB\].
    pub render_db: f64,
    /// The render with the first contact time: its distance likewise
    /// \[dB\].
    pub first_db: f64,
    /// The renders the fit compared.
    pub renders: usize,
    /// Rounds of the weights' correction by the amplitudes a render
    /// plays (kept only while each brought the render nearer the
    /// recording); 0: the weights of the half-sine pulse.
    pub weight_rounds: usize,
}

/// The normalised spectrum `|F(f)| / J` of a half-sine force pulse of
/// duration `tau`: `|cos(pi f tau) / (1 - (2 f tau)^2)|` (1 at 0 Hz).
fn half_sine_spectrum(f: f64, tau: f64) -> f64 {
    let x = 2.0 * f * tau;
    if (x - 1.0).abs() < 1e-9 {
        return PI / 4.0;
    }
    ((PI * f * tau).cos() / (1.0 - x * x)).abs()
}

/// The mallet from the attack of `recording` and the modes found.
fn mallet(a: &Analysis, recording: &[f64], mass_kg: f64) -> MalletEstimate {
    let onset = a.onset.min(recording.len());
    let guard = (0.001 * a.rate_hz).ceil() as usize;
    let window = &recording[onset.saturating_sub(guard)..(onset + guard).min(recording.len())];
    let jump = window.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let (at, step) = window
        .windows(2)
        .enumerate()
        .fold((0, 0.0_f64), |(i, m), (j, w)| {
            let d = (w[1] - w[0]).abs();
            if d > m {
                (j, d)
            } else {
                (i, m)
            }
        });
    // A half-sine pulse of duration tau raises the velocity by `jump` as
    // (1 - cos(pi t / tau)) / 2; sampled at h, its largest first difference
    // is `jump sin(pi h / (2 tau))`. The jump is first the largest
    // magnitude near the onset, then the rise across the pulse that
    // estimate gives, centred on the steepest step (so the modes' own
    // swing after the pulse does not count).
    let tau = |jump: f64| {
        if step > 0.0 && jump > 0.0 {
            0.5 * PI / (a.rate_hz * (step / jump).min(1.0).asin())
        } else {
            0.0
        }
    };
    let half = (0.5 * tau(jump) * a.rate_hz).round() as usize;
    let across =
        (window[(at + 1 + half).min(window.len() - 1)] - window[at.saturating_sub(half)]).abs();
    let rise_s = tau(across.max(step));
    let loudest = a.modes.iter().fold(0.0_f64, |m, x| m.max(x.amplitude));
    let top_mode_hz = a
        .modes
        .iter()
        .filter(|m| m.amplitude >= 0.01 * loudest)
        .fold(0.0_f64, |f, m| f.max(m.freq_hz));
    let by_rise = if rise_s > 0.0 { rise_s } else { CONTACT_S.1 };
    let by_top = if top_mode_hz > 0.0 {
        1.0 / top_mode_hz
    } else {
        CONTACT_S.1
    };
    let (lo, hi) = contact_bounds(a.rate_hz);
    let first_s = if rise_s > 0.0 { by_rise } else { by_top }.clamp(lo, hi);
    let mut m = MalletEstimate {
        mass_kg,
        rise_s,
        top_mode_hz,
        first_s,
        contact_s: first_s,
        stiffness_n_per_m: 0.0,
        damping_ratio: 0.0,
        render_db: f64::NAN,
        first_db: f64::NAN,
        renders: 0,
        weight_rounds: 0,
    };
    m.set_contact(first_s);
    m
}

impl MalletEstimate {
    /// The contact's damping \[N s/m\]: `2 zeta sqrt(k m_eff)`.
    pub fn damping_n_s_per_m(&self) -> f64 {
        let m_eff = self.mass_kg * POINT_MASS_RATIO / (1.0 + POINT_MASS_RATIO);
        2.0 * self.damping_ratio * (self.stiffness_n_per_m * m_eff).sqrt()
    }

    /// Contact for `tau` seconds: the stiffness of a half-sine pulse of
    /// that duration on the mallet in series with the point mass.
    fn set_contact(&mut self, tau: f64) {
        let m_eff = self.mass_kg * POINT_MASS_RATIO / (1.0 + POINT_MASS_RATIO);
        self.contact_s = tau;
        self.stiffness_n_per_m = m_eff * (PI / tau).powi(2);
    }
}

/// `seconds` of the render of the scene `text` at `rate_hz`, from its
/// onset (its first sample at a tenth of its peak, as the analysis's onset
/// of a recording is).
pub fn render_from_onset(
    text: &str,
    rate_hz: f64,
    seconds: f64,
) -> Result<Vec<f64>, RecordingError> {
    let scene = Scene::from_toml_str(text)
        .map_err(|e| RecordingError::Scene(format!("the scene written does not load: {e}")))?;
    let out = render(
        &scene,
        &RenderOptions {
            rate_hz,
            seconds: Some(seconds),
            ..RenderOptions::default()
        },
    )
    .map_err(|e| RecordingError::Scene(format!("the scene written does not render: {e}")))?;
    let peak = out.left.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let start = out
        .left
        .iter()
        .position(|v| v.abs() >= 0.1 * peak)
        .unwrap_or(0);
    Ok(out.left[start..].to_vec())
}

/// The 1/3-octave distance of `a` and `b` (both from their onsets) over
/// the first [`FIT_S`], or over the shorter one's length (a recording
/// shorter than that is compared with as much of the other) \[dB\].
pub fn fit_distance(a: &[f64], b: &[f64], rate_hz: f64) -> f64 {
    let n = a.len().min(b.len());
    third_octave_distance(
        &band_levels(&welch(&a[..n], rate_hz, FIT_S)),
        &band_levels(&welch(&b[..n], rate_hz, FIT_S)),
    )
}

/// The 1/3-octave distance of `text`'s render to `recording` from
/// `onset` ([`fit_distance`]).
fn render_distance(
    text: &str,
    recording: &[f64],
    onset: usize,
    rate_hz: f64,
) -> Result<f64, RecordingError> {
    let copy = render_from_onset(text, rate_hz, FIT_S + 0.1)?;
    Ok(fit_distance(
        &recording[onset.min(recording.len())..],
        &copy,
        rate_hz,
    ))
}

/// The contact's damping ratios tried after the contact time (besides
/// none): a felt or yarn head, a soft rubber one, is lossy.
pub(super) const DAMPING_RATIOS: [f64; 6] = [0.02, 0.05, 0.1, 0.2, 0.3, 0.5];

/// The most rounds of the weights' correction.
const WEIGHT_ROUNDS: usize = 4;

/// The largest factor one round changes a weight's square by (either
/// way): a mode the render barely plays (near a zero of the contact's
/// spectrum) is raised step by step, each step kept only if the render
/// comes nearer the recording.
const WEIGHT_STEP: f64 = 10.0;

/// The longest stretch of a render the amplitudes are fitted on \[s\].
const WEIGHT_FIT_S: f64 = 2.0;

/// The weights corrected by what the contact really does: the render of
/// the scene with `raw` is measured ([`super::refine::amplitudes`], over
/// the span the analysis fitted, from the same offset after the onset),
/// each `raw_i` is multiplied by the recording's amplitude of mode `i`
/// over the render's, and the scene is kept while its render's distance
/// to the recording falls (`m.render_db`, updated). A render plays mode
/// `i` at `(sqrt 2 / J) raw_i |F(f_i)|` whatever the other weights (the
/// normalisation to the point mass cancels in the gain), so one round
/// corrects the pulse's spectrum up to the change the new weights make to
/// the contact; the rounds stop at [`WEIGHT_ROUNDS`].
fn corrected_weights(
    a: &Analysis,
    recording: &[f64],
    name: &str,
    m: &mut MalletEstimate,
    signs: &[f64],
    mut raw: Vec<f64>,
) -> Result<Vec<f64>, RecordingError> {
    let settle = a.span.0.saturating_sub(a.onset);
    let fit_len = (a.span.1.saturating_sub(a.span.0)).min((WEIGHT_FIT_S * a.rate_hz) as usize);
    let seconds = ((settle + fit_len) as f64 / a.rate_hz).max(FIT_S) + 0.1;
    let text = scene_for(a, recording.len(), name, m, (&raw, signs))?;
    // one render per scene: its amplitudes set the next round's weights,
    // its first FIT_S its distance
    let mut copy = render_from_onset(&text, a.rate_hz, seconds)?;
    m.renders += 1;
    let mut best = (raw.clone(), m.render_db, 0);
    for round in 1..=WEIGHT_ROUNDS {
        let Some(played) =
            super::refine::amplitudes(&copy, a.rate_hz, &a.modes, (settle, settle + fit_len))
        else {
            break;
        };
        raw = raw
            .iter()
            .zip(&played)
            .zip(&a.modes)
            .map(|((r, p), md)| {
                let ratio = if *p > 0.0 {
                    md.amplitude / p
                } else {
                    WEIGHT_STEP
                };
                r * ratio.clamp(1.0 / WEIGHT_STEP, WEIGHT_STEP)
            })
            .collect();
        let text = scene_for(a, recording.len(), name, m, (&raw, signs))?;
        copy = render_from_onset(&text, a.rate_hz, seconds)?;
        m.renders += 1;
        let d = fit_distance(&recording[a.onset.min(recording.len())..], &copy, a.rate_hz);
        if d < best.1 {
            best = (raw.clone(), d, round);
        }
    }
    m.render_db = best.1;
    m.weight_rounds = best.2;
    Ok(best.0)
}

/// The scene file (TOML) of the object in `a`, analysed from `recording`,
/// named `name`, struck by a mallet of `mass_kg`; checked by parsing it
/// and compiling it at the recording's rate. Returns the text and the
/// mallet estimate.
pub fn object_scene(
    a: &Analysis,
    recording: &[f64],
    name: &str,
    mass_kg: f64,
) -> Result<(String, MalletEstimate), RecordingError> {
    if !(mass_kg.is_finite() && mass_kg > 0.0) {
        return Err(RecordingError::Option(format!(
            "mallet mass {mass_kg} kg: need a positive mass"
        )));
    }
    let mut m = mallet(a, recording, mass_kg);
    let signs = product_signs(a);
    let mut tried: Vec<(f64, f64)> = Vec::new();
    let (lo, hi) = contact_bounds(a.rate_hz);
    let mut try_tau = |m: &mut MalletEstimate, tau: f64| -> Result<f64, RecordingError> {
        let tau = tau.clamp(lo, hi);
        if let Some(&(_, d)) = tried.iter().find(|(t, _)| *t == tau) {
            return Ok(d);
        }
        m.set_contact(tau);
        let text = scene_for(a, recording.len(), name, m, (&pulse_raw(a, m), &signs))?;
        let d = render_distance(&text, recording, a.onset, a.rate_hz)?;
        tried.push((tau, d));
        Ok(d)
    };
    // the grid, then halved steps around its best
    let mut best = (m.first_s, f64::INFINITY);
    for k in -FIT_SPAN..=FIT_SPAN {
        let tau = m.first_s * 2f64.powf(f64::from(k) / 2.0);
        if !(lo..=hi).contains(&tau) {
            continue;
        }
        let d = try_tau(&mut m, tau)?;
        if k == 0 {
            m.first_db = d;
        }
        if d < best.1 {
            best = (tau.clamp(lo, hi), d);
        }
    }
    for r in 1..=FIT_REFINE {
        let step = 2f64.powf(0.5 / f64::from(1 << r));
        let centre = best.0;
        for tau in [centre / step, centre * step] {
            let d = try_tau(&mut m, tau)?;
            if d < best.1 {
                best = (tau.clamp(lo, hi), d);
            }
        }
    }
    let mut renders = tried.len();
    m.set_contact(best.0);
    m.render_db = best.1;
    // the damping ratio: the grid, then a quarter and an eighth octave
    // either side of its best (none stays if nothing beats it)
    let mut try_zeta = |m: &mut MalletEstimate, zeta: f64| -> Result<(), RecordingError> {
        let mut c = m.clone();
        c.damping_ratio = zeta;
        let text = scene_for(a, recording.len(), name, &c, (&pulse_raw(a, &c), &signs))?;
        let d = render_distance(&text, recording, a.onset, a.rate_hz)?;
        renders += 1;
        if d < m.render_db {
            m.damping_ratio = zeta;
            m.render_db = d;
        }
        Ok(())
    };
    for zeta in DAMPING_RATIOS {
        try_zeta(&mut m, zeta)?;
    }
    for step in [2f64.powf(0.25), 2f64.powf(0.125)] {
        let centre = m.damping_ratio;
        if centre > 0.0 {
            try_zeta(&mut m, centre / step)?;
            try_zeta(&mut m, centre * step)?;
        }
    }
    m.renders = renders;
    let first_raw = pulse_raw(a, &m);
    let raw = corrected_weights(a, recording, name, &mut m, &signs, first_raw)?;
    let text = scene_for(a, recording.len(), name, &m, (&raw, &signs))?;
    let scene = Scene::from_toml_str(&text)
        .map_err(|e| RecordingError::Scene(format!("the scene written does not load: {e}")))?;
    compile_one(&scene, a.rate_hz)
        .map_err(|e| RecordingError::Scene(format!("the scene written does not compile: {e}")))?;
    Ok((text, m))
}

/// The weights' squares up to a common scale for `m`'s pulse: each
/// mode's amplitude over the half-sine pulse's spectrum at its frequency.
fn pulse_raw(a: &Analysis, m: &MalletEstimate) -> Vec<f64> {
    a.modes
        .iter()
        .map(|x| x.amplitude / half_sine_spectrum(x.freq_hz, m.contact_s).max(MIN_SPECTRUM))
        .collect()
}

/// The scene text for the mallet `m` and the weights' squares `raw` (up
/// to a common scale): scaled to the point mass, and the gain that plays
/// the modes at the recording's level.
fn scene_for(
    a: &Analysis,
    len: usize,
    name: &str,
    m: &MalletEstimate,
    (raw, signs): (&[f64], &[f64]),
) -> Result<String, RecordingError> {
    // w_i^2 = s raw_i, with sum w_i^2 = 1 / (POINT_MASS_RATIO m).
    let total: f64 = raw.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err(RecordingError::NoModes("no mode has an amplitude".into()));
    }
    let s = 1.0 / (POINT_MASS_RATIO * m.mass_kg * total);
    let m_eff = m.mass_kg * POINT_MASS_RATIO / (1.0 + POINT_MASS_RATIO);
    // Render amplitude of mode i: gain * J * w_i^2 * |F_i| * pan, with the
    // impulse J = 2 m_eff v of an undamped contact and the centre pan's
    // 1/sqrt(2) per channel; w_i^2 |F_i| = s A_i (above MIN_SPECTRUM).
    let impulse = 2.0 * m_eff * STRIKE_M_PER_S;
    let gain = std::f64::consts::SQRT_2 / (impulse * s);
    Ok(scene_text(a, name, m, (raw, signs), s, gain, len))
}

/// The sign of each mode's product of weights (contact times pickup),
/// from its phase at the onset and the common delay that brings the
/// phases nearest 0 or pi.
fn product_signs(a: &Analysis) -> Vec<f64> {
    // The phase a mode would have at the onset with a positive product and
    // a pulse centred `delay` after the onset.
    let expected = |m: &super::Mode, delay: f64| {
        let omega = 2.0 * PI * m.freq_hz;
        (m.alpha() / omega).atan() - omega * delay
    };
    let score = |delay: f64| -> f64 {
        a.modes
            .iter()
            .map(|m| m.amplitude * (2.0 * (m.phase_rad - expected(m, delay))).cos())
            .sum()
    };
    let best = (-3000..=3000)
        .map(|i| f64::from(i) * 1e-6)
        .fold((0.0, f64::NEG_INFINITY), |(d, s), delay| {
            let v = score(delay);
            if v > s {
                (delay, v)
            } else {
                (d, s)
            }
        })
        .0;
    a.modes
        .iter()
        .map(|m| {
            if (m.phase_rad - expected(m, best)).cos() >= 0.0 {
                1.0
            } else {
                -1.0
            }
        })
        .collect()
}

/// The TOML text of the scene.
fn scene_text(
    a: &Analysis,
    name: &str,
    m: &MalletEstimate,
    (raw, signs): (&[f64], &[f64]),
    s: f64,
    gain: f64,
    len: usize,
) -> String {
    let name = name.replace(['"', '\\', '\n'], "_");
    let duration = ((len.saturating_sub(a.onset)) as f64 / a.rate_hz).clamp(0.5, 60.0);
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# An object analysed from a recording: {} modes (ESPRIT on sub-bands).\n\
         # Contact and pickup at one point: the weights are sqrt(amplitude / pulse spectrum){},\n\
         # scaled so the object's mass at that point is {POINT_MASS_RATIO} times the mallet's.\n\
         # Mallet: {:.0} g, contact {:.3} ms (fitted against renders from {:.3} ms; the onset's slope gives {:.3} ms, highest strong mode {:.0} Hz){}.\n\
         version = 1\nname = \"{name}\"\nduration_s = {duration:.3}\n\n\
         [[object]]\nname = \"object\"\nkind = \"modal\"\npoints = [\"contact\", \"pickup\"]\n",
        a.modes.len(),
        if m.weight_rounds > 0 {
            format!(
                " corrected by {} round(s) of the amplitudes renders play",
                m.weight_rounds
            )
        } else {
            String::new()
        },
        1e3 * m.mass_kg,
        1e3 * m.contact_s,
        1e3 * m.first_s,
        1e3 * m.rise_s,
        m.top_mode_hz,
        if m.damping_ratio > 0.0 {
            format!(", damping ratio {:.3}", m.damping_ratio)
        } else {
            String::new()
        }
    );
    for ((x, r), sign) in a.modes.iter().zip(raw).zip(signs) {
        let w = (s * r).sqrt();
        let _ = writeln!(
            t,
            "[[object.mode]]\nfreq_hz = {}\nt60_s = {}\nweights = [{w}, {}]\n",
            x.natural_freq_hz(),
            x.t60_s,
            sign * w
        );
    }
    let _ = writeln!(
        t,
        "[hammer]\nmass_kg = {}\nheight_m = 0.0001\nvelocity_m_per_s = {}\n\n\
         [contact]\nobject = \"object\"\npoint = \"contact\"\nstiffness_n_per_m = {}\n\
         damping_n_s_per_m = {:?}\n\n\
         [[pickup]]\nobject = \"object\"\npoint = \"pickup\"\nquantity = \"velocity\"\ngain = {gain}",
        m.mass_kg,
        -STRIKE_M_PER_S,
        m.stiffness_n_per_m,
        m.damping_n_s_per_m()
    );
    t
}
