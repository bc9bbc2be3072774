//! Leaving out modes a scene does not need (docs/numerics.md, "Leaving out what
//! a scene does not need").
//!
//! Exact (always on): a mode of the struck modal object that is zero at the
//! contact point and at every heard pickup is never excited (the object
//! starts at rest and is only forced at the contact point) and never heard:
//! it is dropped. (Modes with zero contact weight that are heard are kept,
//! but outside the contact eigenproblem: see `compile`.)
//!
//! Approximate (opt-in per scene, `[approximate]`): modes above a frequency
//! limit or a fraction of the Nyquist frequency, and modes whose contribution
//! at the pickups is bounded below a level relative to the loudest mode. The
//! bound for an impulse `J` at the contact: mode `i`'s pickup velocity is at
//! most `|w_c,i| J sum_p |g_p w_p,i|` (displacement: divided by `omega_i`),
//! so the ratio of these sums between modes bounds the relative level.

use super::CompileOptions;
use crate::scene::{ObjectSpec, Quantity, Scene};

/// The struck object with the unneeded modes removed, and why each went.
pub fn prune_object(
    scene: &Scene,
    ci: usize,
    rate_hz: f64,
    opts: &CompileOptions,
) -> (ObjectSpec, Vec<String>) {
    let spec = scene.object[ci].clone();
    let ObjectSpec::Modal(mut m) = spec else {
        return (spec, Vec::new());
    };
    let Some(cp) = scene
        .contact
        .point
        .as_ref()
        .and_then(|p| m.points.iter().position(|x| x == p))
    else {
        return (ObjectSpec::Modal(m), Vec::new());
    };
    // heard pickups on this object: (point index, gain, displacement?)
    let pickups: Vec<(usize, f64, bool)> = scene
        .pickup
        .iter()
        .filter(|p| p.object == m.name && p.gain != 0.0)
        .filter_map(|p| {
            m.points
                .iter()
                .position(|x| *x == p.point)
                .map(|i| (i, p.gain, p.quantity == Quantity::Displacement))
        })
        .collect();
    let approx = scene.approximate.as_ref().filter(|_| opts.approximations);
    let nyquist = rate_hz / 2.0;
    let mut limit_hz = f64::INFINITY;
    if let Some(a) = approx {
        if let Some(f) = a.max_freq_hz {
            limit_hz = limit_hz.min(f);
        }
        if let Some(fr) = a.nyquist_fraction {
            limit_hz = limit_hz.min(fr * nyquist);
        }
    }
    let contribution = |mode: &crate::scene::ModeSpec| -> f64 {
        let omega = 2.0 * std::f64::consts::PI * mode.freq_hz;
        let heard: f64 = pickups
            .iter()
            .map(|&(pi, g, disp)| {
                let w = (g * mode.weights[pi]).abs();
                if disp {
                    w / omega
                } else {
                    w
                }
            })
            .sum();
        mode.weights[cp].abs() * heard
    };
    let loudest = m.mode.iter().map(contribution).fold(0.0, f64::max);
    let mut dropped = Vec::new();
    let mut kept = Vec::with_capacity(m.mode.len());
    for (i, mode) in m.mode.drain(..).enumerate() {
        let silent_everywhere =
            mode.weights[cp] == 0.0 && pickups.iter().all(|&(pi, _, _)| mode.weights[pi] == 0.0);
        if opts.exact_savings && silent_everywhere {
            dropped.push(format!(
                "mode {i} ({} Hz): zero at the contact point and every pickup (exact)",
                mode.freq_hz
            ));
            continue;
        }
        if mode.freq_hz > limit_hz {
            dropped.push(format!(
                "mode {i} ({} Hz): above the {limit_hz:.0} Hz limit (approximate)",
                mode.freq_hz
            ));
            continue;
        }
        if let Some(db) = approx.and_then(|a| a.quiet_below_db) {
            let c = contribution(&mode);
            let level = 20.0 * (c / loudest).log10();
            if loudest > 0.0 && level < db {
                dropped.push(format!(
                    "mode {i} ({} Hz): bounded at {level:.1} dB re the loudest, below {db} dB (approximate)",
                    mode.freq_hz
                ));
                continue;
            }
        }
        kept.push(mode);
    }
    m.mode = kept;
    if m.mode.is_empty() {
        // an object with no modes behaves as a rigid wall at the contact point
        return (
            ObjectSpec::Wall(crate::scene::WallSpec { name: m.name }),
            dropped,
        );
    }
    (ObjectSpec::Modal(m), dropped)
}
