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
use crate::scene::{ObjectSpec, Quantity, Scene, SceneError};

/// What the compiler does with one mode of the struck modal object.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeFate {
    /// Index in the scene's list.
    pub index: usize,
    /// Frequency \[Hz\].
    pub freq_hz: f64,
    /// T60 \[s\] (`None`: undamped).
    pub t60_s: Option<f64>,
    /// The bound on its pickup level for an impulse at the contact, relative
    /// to the loudest mode's (1 = the loudest; 0 = silent).
    pub level: f64,
    /// Why it is left out, if it is.
    pub dropped: Option<String>,
}

/// Every mode of the struck object (object `ci`, a modal object with the
/// contact point among its points) and what the compiler does with it;
/// `None` for any other object. The editor draws this as the object's
/// spectrum. \[worker\]
pub fn mode_fates(
    scene: &Scene,
    ci: usize,
    rate_hz: f64,
    opts: &CompileOptions,
) -> Option<Vec<ModeFate>> {
    let ObjectSpec::Modal(m) = &scene.object[ci] else {
        return None;
    };
    let cp = scene
        .contact
        .point
        .as_ref()
        .and_then(|p| m.points.iter().position(|x| x == p))?;
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
    let fate = |i: usize, mode: &crate::scene::ModeSpec| -> ModeFate {
        let c = contribution(mode);
        let silent_everywhere =
            mode.weights[cp] == 0.0 && pickups.iter().all(|&(pi, _, _)| mode.weights[pi] == 0.0);
        let dropped = if opts.exact_savings && silent_everywhere {
            Some(format!(
                "mode {i} ({} Hz): zero at the contact point and every pickup (exact)",
                mode.freq_hz
            ))
        } else if mode.freq_hz > limit_hz {
            Some(format!(
                "mode {i} ({} Hz): above the {limit_hz:.0} Hz limit (approximate)",
                mode.freq_hz
            ))
        } else {
            approx.and_then(|a| a.quiet_below_db).and_then(|db| {
                let level = 20.0 * (c / loudest).log10();
                (loudest > 0.0 && level < db).then(|| {
                    format!(
                        "mode {i} ({} Hz): bounded at {level:.1} dB re the loudest, below {db} dB (approximate)",
                        mode.freq_hz
                    )
                })
            })
        };
        ModeFate {
            index: i,
            freq_hz: mode.freq_hz,
            t60_s: mode.t60_s,
            level: if loudest > 0.0 { c / loudest } else { 0.0 },
            dropped,
        }
    };
    Some(
        m.mode
            .iter()
            .enumerate()
            .map(|(i, mode)| fate(i, mode))
            .collect(),
    )
}

/// The struck object's modes as the compiler resolves them (see
/// [`struck_mode_fates`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StruckModes {
    /// Every mode and its fate: the struck object's own first, then a
    /// modal mallet's, which the compiler joins to the struck object
    /// (docs/design.md, "Modal mallets").
    pub fates: Vec<ModeFate>,
    /// How many of `fates` are the struck object's own.
    pub own: usize,
}

/// The struck object of `scene` turned into its modes the way the compiler
/// does before it leaves any out (stage 0 of `compile`: [`Scene::expanded`]
/// at `rate_hz`, so an object from geometry and material becomes its modes
/// and a modal mallet's modes join the struck object's), and what the
/// compiler does with each ([`mode_fates`]). `Ok(None)`: the struck object
/// has no modes to list (a lumped string, a wall). An error names the field
/// the expansion refused. \[worker\]
pub fn struck_mode_fates(
    scene: &Scene,
    rate_hz: f64,
    opts: &CompileOptions,
) -> Result<Option<StruckModes>, SceneError> {
    let expanded = scene.expanded(rate_hz)?;
    let ci = expanded
        .object_index(&expanded.contact.object)
        .ok_or_else(|| {
            SceneError::new(
                "contact.object",
                format!("no object named {:?}", expanded.contact.object),
            )
        })?;
    let Some(fates) = mode_fates(&expanded, ci, rate_hz, opts) else {
        return Ok(None);
    };
    // a joined mallet's modes come last (the expansion clears
    // `hammer.object` when it joins one)
    let joined = scene
        .hammer
        .object
        .as_deref()
        .filter(|_| expanded.hammer.object.is_none())
        .and_then(|m| expanded.object_index(m))
        .map_or(0, |mi| match &expanded.object[mi] {
            ObjectSpec::Modal(m) => m.mode.len(),
            _ => 0,
        });
    Ok(Some(StruckModes {
        own: fates.len().saturating_sub(joined),
        fates,
    }))
}

/// The struck object with the unneeded modes removed, and why each went.
pub fn prune_object(
    scene: &Scene,
    ci: usize,
    rate_hz: f64,
    opts: &CompileOptions,
) -> (ObjectSpec, Vec<String>) {
    let spec = scene.object[ci].clone();
    let (ObjectSpec::Modal(mut m), Some(fates)) =
        (spec.clone(), mode_fates(scene, ci, rate_hz, opts))
    else {
        return (spec, Vec::new());
    };
    let mut dropped = Vec::new();
    let mut kept = Vec::with_capacity(m.mode.len());
    for (mode, fate) in m.mode.drain(..).zip(fates) {
        match fate.dropped {
            Some(why) => dropped.push(why),
            None => kept.push(mode),
        }
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
