//! A physical object as the modal object the compiler runs on: its modes
//! up to the limits, each mode's decay and its weights at the named points
//! and toward the listeners.

use super::loss::plate_radiation_rate;
use super::shape::shape_error;
use super::PhysicalSpec;
use crate::bodies::radiated_power::radiation_decay_rate;
use crate::bodies::radiation::{far_field, Direction, SOUND_SPEED_M_PER_S};
use crate::bodies::resonator::{ModeEffect, Resonator, MAX_MIXING};
use crate::bodies::shapes::{Point, Shape, ShapeMode};
use crate::scene::error::{check_max, check_non_negative, check_positive, SceneError};
use crate::scene::limits::{
    MAX_DAMPING_N_S_PER_M, MAX_FREQ_HZ, MAX_MODES_PER_OBJECT, MAX_WEIGHT, MIN_FREQ_HZ, MIN_T60_S,
};
use crate::scene::{
    pressure_point, ListenerSpec, ModalSpec, ModeSpec, PRESSURE_REF_AREA_M2, PRESSURE_REF_OMEGA,
};
use std::f64::consts::PI;

/// Which modes are listed: up to `max_freq_hz` (default: the Nyquist
/// frequency of the rate the scene is compiled for), at most `max_modes`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ModeLimits {
    pub(super) max_freq_hz: Option<f64>,
    pub(super) max_modes: Option<usize>,
}
impl PhysicalSpec<'_> {
    /// The modal object this describes at `rate_hz`: modes up to the
    /// limits, each mode's T60 from the loss model and its weight at every
    /// point from the mass-normalised shape. Errors name the field.
    pub fn to_modal(&self, base: &str, rate_hz: f64) -> Result<ModalSpec, SceneError> {
        self.to_modal_heard(base, rate_hz, &[])
    }

    /// [`Self::to_modal`] with two more points per listener, `{l}~q` and
    /// `{l}~v` ([`crate::scene::pressure_point`]): each mode's weights for
    /// the pressure it radiates toward the listener (docs/design.md,
    /// "Radiation to a listener"; `crate::bodies::radiation`).
    pub fn to_modal_heard(
        &self,
        base: &str,
        rate_hz: f64,
        listeners: &[&ListenerSpec],
    ) -> Result<ModalSpec, SceneError> {
        let (shape, eta) = self.shape(base)?;
        let loss = self.loss().model(eta);
        loss.validate().map_err(|e| shape_error(base, e))?;
        let limits = self.limits();
        let (max_freq, max_count) = mode_limits(base, &limits, rate_hz)?;
        let points = self.named_points(base)?;
        let dashpots = self.dashpots(base, &points)?;
        let modes = listed_modes(
            base,
            &shape,
            max_freq,
            max_count,
            limits.max_modes.is_none(),
        )?;
        let weight_scale = self.weight_scale(base, &shape)?;
        let mut mode = Vec::with_capacity(modes.len());
        let radiation = self.plate_radiation(base, &shape)?;
        let radiated = self.radiation_damping(base)?;
        let lowest = modes
            .iter()
            .map(|m| m.freq_hz)
            .fold(f64::INFINITY, f64::min);
        let resonator = self.resonator(base, &shape, lowest)?;
        let weighing = Weighing {
            base,
            shape: &shape,
            weight_scale,
            points: &points,
            listeners,
        };
        for (k, m) in modes.iter().enumerate() {
            // what the tube does to this mode ringing at its frequency
            let tube = match &resonator {
                Some((r, at)) => {
                    let phi = weight_scale
                        * m.shape_at(*at).map_err(|e| {
                            SceneError::new(format!("{base}.resonator.point"), e.to_string())
                        })?;
                    Some(r.on_mode(m.freq_hz, phi))
                }
                None => None,
            };
            let mut weights = weighing.at_points(k, m)?;
            let sigma = loss
                .decay_rate(m.freq_hz)
                .map_err(|e| shape_error(base, e))?
                + radiation.as_ref().map_or(0.0, |r| r(m.freq_hz))
                + radiated_decay_rate(base, radiated, &shape, m, weight_scale)?
                + tube.map_or(0.0, |t| t.decay_rate_per_s)
                + dashpot_decay_rate(&dashpots, &weights);
            let t60_s = (sigma > 0.0).then(|| (1000f64.ln() / sigma).max(MIN_T60_S));
            // the tube's frequency shift (under 0.1 cent on the presets) is
            // not applied: the bar keeps the tuning its maker gave it
            let freq_hz = m.freq_hz;
            weighing.toward_listeners(k, m, tube, &mut weights)?;
            mode.push(ModeSpec {
                freq_hz,
                t60_s,
                weights,
            });
        }
        if let Some((r, at)) = &resonator {
            let bars = modes
                .iter()
                .zip(&mode)
                .map(|(m, spec)| Ok((m.omega(), weight_scale * m.shape_at(*at)?, spec)))
                .collect::<Result<Vec<_>, String>>()
                .map_err(|e| SceneError::new(format!("{base}.resonator.point"), e))?;
            let own = tube_modes(base, r, &bars, max_freq, points.len(), listeners.len())?;
            if mode.len() + own.len() > MAX_MODES_PER_OBJECT {
                return Err(SceneError::new(
                    format!("{base}.resonator"),
                    format!(
                        "the bar's {} modes and the tube's {} exceed {MAX_MODES_PER_OBJECT}: \
                         lower max_modes",
                        mode.len(),
                        own.len()
                    ),
                ));
            }
            mode.extend(own);
        }
        let mut names: Vec<String> = points.into_iter().map(|(n, _)| n).collect();
        for l in listeners {
            names.push(pressure_point(&l.name, false));
            names.push(pressure_point(&l.name, true));
        }
        Ok(ModalSpec {
            name: self.name().to_string(),
            points: names,
            mode,
        })
    }

    /// The object's named points as points of its shape (at least one).
    fn named_points(&self, base: &str) -> Result<Vec<(String, Point)>, SceneError> {
        let points: Vec<(String, Point)> = self
            .points()
            .iter()
            .map(|(n, p)| Ok((n.clone(), self.point(base, n, *p)?)))
            .collect::<Result<_, SceneError>>()?;
        if points.is_empty() {
            return Err(SceneError::new(
                format!("{base}.points"),
                "name at least one point (the struck one)",
            ));
        }
        Ok(points)
    }

    /// The dashpots: the index of each one's point among the named points
    /// and its damping, within `0 ..= MAX_DAMPING_N_S_PER_M`.
    fn dashpots(
        &self,
        base: &str,
        points: &[(String, Point)],
    ) -> Result<Vec<(usize, f64)>, SceneError> {
        self.loss()
            .dashpots
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let path = format!("{base}.loss.dashpots[{i}]");
                let Some(at) = points.iter().position(|(n, _)| *n == d.point) else {
                    return Err(SceneError::new(
                        format!("{path}.point"),
                        format!("names no point of the object: {:?}", d.point),
                    ));
                };
                let c = d.n_s_per_m;
                check_non_negative(&format!("{path}.n_s_per_m"), c)?;
                check_max(&format!("{path}.n_s_per_m"), c, MAX_DAMPING_N_S_PER_M)?;
                Ok((at, c))
            })
            .collect()
    }

    /// A bar's resonator tube and the point over its axis; `lowest_hz`
    /// (the bar's lowest mode) is its default tuning. The bar covers the
    /// mouth across its width: `S_c = min(pi a^2, 2 a b)`.
    pub(super) fn resonator(
        &self,
        base: &str,
        shape: &Shape,
        lowest_hz: f64,
    ) -> Result<Option<(Resonator, Point)>, SceneError> {
        let (PhysicalSpec::Bar(spec), Shape::Bar(bar)) = (self, shape) else {
            return Ok(None);
        };
        let Some(r) = &spec.resonator else {
            return Ok(None);
        };
        let path = format!("{base}.resonator");
        let Some(p) = spec.points.get(&r.point) else {
            return Err(SceneError::new(
                format!("{path}.point"),
                format!("names no point of the bar: {:?}", r.point),
            ));
        };
        let at = self.point(base, &r.point, *p)?;
        check_positive(&format!("{path}.radius_m"), r.radius_m)?;
        let tuned = r.tuned_hz.unwrap_or(lowest_hz);
        check_positive(&format!("{path}.tuned_hz"), tuned)?;
        let a = r.radius_m;
        let covered = (PI * a * a).min(2.0 * a * bar.width_m);
        let tube =
            Resonator::tuned(a, tuned, covered).map_err(|e| SceneError::new(path.clone(), e))?;
        Ok(Some((tube, at)))
    }

    /// `sqrt(m_uniform / mass_kg)` of an undercut bar whose mass is given
    /// (1 otherwise).
    pub(super) fn weight_scale(&self, base: &str, shape: &Shape) -> Result<f64, SceneError> {
        let (PhysicalSpec::Bar(spec), Shape::Bar(bar)) = (self, shape) else {
            return Ok(1.0);
        };
        let Some(m) = spec.mass_kg else {
            return Ok(1.0);
        };
        let path = format!("{base}.mass_kg");
        check_positive(&path, m)?;
        let uniform = bar.mass_kg();
        if spec.tuning.is_empty() || m > uniform {
            return Err(SceneError::new(
                path,
                format!(
                    "only a tuned (undercut) bar takes a mass, at most the uniform bar's {uniform} kg; got {m}"
                ),
            ));
        }
        Ok((uniform / m).sqrt())
    }

    /// The factor of the radiation damping (`loss.radiation_damping`),
    /// checked: finite and not negative.
    pub(super) fn radiation_damping(&self, base: &str) -> Result<f64, SceneError> {
        let scale = self.loss().radiation_damping;
        check_non_negative(&format!("{base}.loss.radiation_damping"), scale)?;
        Ok(scale)
    }

    /// The plate radiation term of the loss, when asked for (plates only).
    #[allow(clippy::type_complexity)]
    pub(super) fn plate_radiation(
        &self,
        base: &str,
        shape: &Shape,
    ) -> Result<Option<Box<dyn Fn(f64) -> f64>>, SceneError> {
        let scale = self.loss().plate_radiation;
        check_non_negative(&format!("{base}.loss.plate_radiation"), scale)?;
        if scale == 0.0 {
            return Ok(None);
        }
        let Shape::Plate(p) = shape else {
            return Err(SceneError::new(
                format!("{base}.loss.plate_radiation"),
                format!("only a plate radiates as a plate, not a {}", self.kind()),
            ));
        };
        let (a, b, rho_h, d) = (
            p.length_x_m,
            p.length_y_m,
            p.density_kg_m3 * p.thickness_m,
            p.flexural_rigidity(),
        );
        Ok(Some(Box::new(move |f| {
            scale * plate_radiation_rate(f, a, b, rho_h, d)
        })))
    }
}
/// The decay rate radiating costs mode `m` (`scale` times both faces'
/// power, docs/design.md "Radiation damping"), its shape scaled by
/// `weight_scale` (an undercut bar's shapes renormalised to its mass).
fn radiated_decay_rate(
    base: &str,
    scale: f64,
    shape: &Shape,
    m: &ShapeMode,
    weight_scale: f64,
) -> Result<f64, SceneError> {
    if scale == 0.0 {
        return Ok(0.0);
    }
    let one_face = radiation_decay_rate(shape, m)
        .map_err(|e| SceneError::new(format!("{base}.loss.radiation_damping"), e))?;
    Ok(scale * 2.0 * weight_scale * weight_scale * one_face)
}

/// The highest frequency and the most modes `limits` let an object list:
/// `max_freq_hz` (at most [`MAX_FREQ_HZ`]) or the Nyquist frequency of
/// `rate_hz`, and `max_modes` (1 ..= [`MAX_MODES_PER_OBJECT`]) or that
/// limit. Errors name the field.
fn mode_limits(base: &str, limits: &ModeLimits, rate_hz: f64) -> Result<(f64, usize), SceneError> {
    let max_freq = match limits.max_freq_hz {
        Some(f) => {
            check_positive(&format!("{base}.max_freq_hz"), f)?;
            f.min(MAX_FREQ_HZ)
        }
        None => 0.5 * rate_hz,
    };
    let max_count = limits.max_modes.unwrap_or(MAX_MODES_PER_OBJECT);
    if max_count == 0 || max_count > MAX_MODES_PER_OBJECT {
        return Err(SceneError::new(
            format!("{base}.max_modes"),
            format!("must be in 1..={MAX_MODES_PER_OBJECT}, got {max_count}"),
        ));
    }
    Ok((max_freq, max_count))
}

/// The modes of `shape` up to `max_freq` Hz, at most `max_count`, without
/// those below [`MIN_FREQ_HZ`]; `unlimited` (no `max_modes` given): an
/// error before any work when the estimate is far above the limit, and
/// when more than `max_count` modes lie below `max_freq`.
fn listed_modes(
    base: &str,
    shape: &Shape,
    max_freq: f64,
    max_count: usize,
    unlimited: bool,
) -> Result<Vec<ShapeMode>, SceneError> {
    // refuse before any work when the limits would list too many modes
    if unlimited {
        let estimate = mode_count_estimate(shape, max_freq);
        if estimate > 2.0 * MAX_MODES_PER_OBJECT as f64 {
            return Err(SceneError::new(
                base.to_string(),
                format!(
                    "about {estimate:.0} modes below {max_freq:.0} Hz, more than the limit of \
                     {MAX_MODES_PER_OBJECT}: set `max_freq_hz` or `max_modes`"
                ),
            ));
        }
    }
    let modes = shape
        .modes(max_freq, max_count + 1)
        .map_err(|e| shape_error(base, e))?;
    if modes.len() > max_count && unlimited {
        return Err(SceneError::new(
            base.to_string(),
            format!(
                "more than {MAX_MODES_PER_OBJECT} modes below {max_freq:.0} Hz (about {:.0}): \
                 set `max_freq_hz` or `max_modes`",
                mode_count_estimate(shape, max_freq)
            ),
        ));
    }
    let modes: Vec<ShapeMode> = modes
        .into_iter()
        .take(max_count)
        .filter(|m| m.freq_hz >= MIN_FREQ_HZ)
        .collect();
    if modes.is_empty() {
        return Err(SceneError::new(
            format!("{base}.max_freq_hz"),
            format!(
                "no mode at or below {max_freq} Hz (the lowest is at {:.6e} Hz)",
                shape
                    .modes(f64::INFINITY, 1)
                    .ok()
                    .and_then(|m| m.first().map(|m| m.freq_hz))
                    .unwrap_or(f64::NAN)
            ),
        ));
    }
    Ok(modes)
}

/// The decay rate \[1/s\] the dashpots `(point index, c)` add to a mode
/// of these weights at the named points: `sum_p c_p w_p^2 / 2`, to first
/// order in the dampings (docs/design.md, "Dashpots at points").
fn dashpot_decay_rate(dashpots: &[(usize, f64)], weights: &[f64]) -> f64 {
    dashpots
        .iter()
        .map(|&(at, c)| 0.5 * c * weights[at] * weights[at])
        .sum()
}

/// What each mode of one object is weighed at: its named points, and the
/// listeners its pressure pickups name.
struct Weighing<'a> {
    /// The object's path in the scene, for errors.
    base: &'a str,
    /// The object's kind and geometry.
    shape: &'a Shape,
    /// What multiplies every mass-normalised shape (a tuned bar's
    /// renormalisation, else 1).
    weight_scale: f64,
    /// The named points.
    points: &'a [(String, Point)],
    /// The listeners heard.
    listeners: &'a [&'a ListenerSpec],
}

impl Weighing<'_> {
    /// Mode `k`'s weight at each point, each within [`MAX_WEIGHT`].
    fn at_points(&self, k: usize, m: &ShapeMode) -> Result<Vec<f64>, SceneError> {
        let mut weights = Vec::with_capacity(self.points.len());
        for (name, p) in self.points {
            let w = self.weight_scale
                * m.shape_at(*p).map_err(|e| {
                    SceneError::new(format!("{}.points.{name}", self.base), e.to_string())
                })?;
            if !(w.abs() <= MAX_WEIGHT) {
                return Err(SceneError::new(
                    self.base.to_string(),
                    format!(
                        "mode {k} ({}) has weight {w:e} at point {name:?}: the object is too \
                         light (an effective mass below 1e-12 kg)",
                        m.label
                    ),
                ));
            }
            weights.push(w);
        }
        Ok(weights)
    }

    /// Mode `k`'s two weights toward each listener (its far field and the
    /// tube's monopole, `tube`), appended to `weights`, each within
    /// [`MAX_WEIGHT`].
    fn toward_listeners(
        &self,
        k: usize,
        m: &ShapeMode,
        tube: Option<ModeEffect>,
        weights: &mut Vec<f64>,
    ) -> Result<(), SceneError> {
        for l in self.listeners {
            let dir = Direction {
                polar_deg: l.polar_deg,
                azimuth_deg: l.azimuth_deg,
            };
            let (re, im) = far_field(self.shape, m, dir, SOUND_SPEED_M_PER_S).map_err(|e| {
                SceneError::new(
                    format!("{}: listener {:?}", self.base, l.name),
                    e.to_string(),
                )
            })?;
            // the tube's monopole beside the bar's own far field (the
            // tube's is already per unit of the mass-normalised mode)
            let (re, im) = (self.weight_scale * re, self.weight_scale * im);
            let (re, im) = tube.map_or((re, im), |t| (re + t.far_field.0, im + t.far_field.1));
            for w in pressure_weights(m.omega(), (re, im)) {
                if !(w.abs() <= MAX_WEIGHT) {
                    return Err(SceneError::new(
                        self.base.to_string(),
                        format!(
                            "mode {k} ({}) radiates with weight {w:e} toward listener {:?}, \
                             beyond {MAX_WEIGHT:e}",
                            m.label, l.name
                        ),
                    ));
                }
                weights.push(w);
            }
        }
        Ok(())
    }
}

/// The two pseudo-point weights (`{l}~q`, `{l}~v`) of a mode at `omega`
/// radiating `W = (re, im)` toward a listener: `(omega /
/// PRESSURE_REF_OMEGA)^k W / PRESSURE_REF_AREA_M2`, `k` = 2 and 1
/// ([`crate::scene::PRESSURE_REF_OMEGA`]).
fn pressure_weights(omega: f64, (re, im): (f64, f64)) -> [f64; 2] {
    let r = omega / PRESSURE_REF_OMEGA;
    [
        r * r * re / PRESSURE_REF_AREA_M2,
        r * im / PRESSURE_REF_AREA_M2,
    ]
}

/// The tube's own resonances above its tuned one as modes of the bar and
/// tube together (docs/design.md, "Resonator tubes"), to first order in
/// their coupling: tube mode `j`'s eigenvector has the component `c_ij`
/// ([`Resonator::mixing`]) on bar mode `i`, so its weight at each point is
/// `sum_i c_ij` times bar mode `i`'s there, and toward each listener it
/// radiates the tube's monopole ([`crate::bodies::resonator::TubeMode::far_field`]). `bars`: each
/// bar mode's `omega`, its weight at the tube's axis and its spec (the
/// first `points` weights are at the named points). A tube mode whose
/// mixing with some bar mode exceeds [`MAX_MIXING`] (the two nearly in
/// tune) is left out, as the tuned resonance is: the bar mode carries the
/// tube's response at its own frequency.
fn tube_modes(
    base: &str,
    r: &Resonator,
    bars: &[(f64, f64, &ModeSpec)],
    max_freq_hz: f64,
    points: usize,
    listeners: usize,
) -> Result<Vec<ModeSpec>, SceneError> {
    let path = format!("{base}.resonator");
    let own = r.own_modes(max_freq_hz).ok_or_else(|| {
        SceneError::new(
            path.clone(),
            "no lossy resonance of the tube found (a defect)",
        )
    })?;
    let mut out = Vec::new();
    for t in &own {
        let c: Vec<f64> = bars
            .iter()
            .map(|(omega, phi, _)| r.mixing(t, *omega, *phi))
            .collect();
        if c.iter().any(|x| !(x.abs() <= MAX_MIXING)) {
            continue;
        }
        let mut weights = vec![0.0; points];
        for (ci, (_, _, spec)) in c.iter().zip(bars) {
            for (w, b) in weights.iter_mut().zip(&spec.weights[..points]) {
                *w += ci * b;
            }
        }
        let heard = pressure_weights(2.0 * PI * t.freq_hz, t.far_field);
        for _ in 0..listeners {
            weights.extend(heard);
        }
        if let Some(w) = weights.iter().find(|w| !(w.abs() <= MAX_WEIGHT)) {
            return Err(SceneError::new(
                path,
                format!(
                    "the tube's mode at {:.1} Hz has weight {w:e}, beyond {MAX_WEIGHT:e}",
                    t.freq_hz
                ),
            ));
        }
        out.push(ModeSpec {
            freq_hz: t.freq_hz,
            t60_s: Some((1000f64.ln() / t.decay_rate_per_s).max(MIN_T60_S)),
            weights,
        });
    }
    Ok(out)
}

/// Modes below `f` by the asymptotic mode count of each kind (Weyl's law
/// for the plate and membrane; the beam and string dispersion relations),
/// for refusing runaway geometry before listing anything.
fn mode_count_estimate(shape: &Shape, f: f64) -> f64 {
    let w = 2.0 * PI * f;
    match shape {
        // bending (omega = (n pi / L)^2 sqrt(E I / (rho A))) plus torsion
        // (f = n c_t / (2 L))
        Shape::Bar(b) => {
            let ei_ra = b.youngs_modulus_pa * b.thickness_m.powi(2) / (12.0 * b.density_kg_m3);
            let torsion = b.torsion.map_or(0.0, |g| {
                let c_t =
                    (g * b.torsion_constant_m4() / (b.density_kg_m3 * b.polar_moment_m4())).sqrt();
                2.0 * b.length_m * f / c_t
            });
            b.length_m * (w * w / ei_ra).powf(0.25) / PI + torsion
        }
        Shape::Tube(t) => {
            let r2 = (t.outer_diameter_m.powi(2) + t.inner_diameter_m.powi(2)) / 16.0;
            let ei_ra = t.youngs_modulus_pa * r2 / t.density_kg_m3;
            let torsion = t
                .torsion
                .map_or(0.0, |g| 2.0 * t.length_m * f / (g / t.density_kg_m3).sqrt());
            // two partners per ovalling mode `n` (a few dozen at most
            // below any audio rate)
            let ovalling = (2..10_000)
                .take_while(|&n| t.ovalling_freq_hz(n).is_some_and(|fo| fo <= f))
                .count() as f64
                * 2.0;
            t.length_m * (w * w / ei_ra).powf(0.25) / PI + torsion + ovalling
        }
        Shape::Plate(p) => {
            let area = p.length_x_m * p.length_y_m;
            area * w * (p.density_kg_m3 * p.thickness_m / p.flexural_rigidity()).sqrt() / (4.0 * PI)
        }
        Shape::Membrane(m) => {
            let k = w * (m.areal_density_kg_m2 / m.tension_n_per_m).sqrt();
            (m.radius_m * k).powi(2) / 4.0
        }
        Shape::StiffString(s) => f / s.ideal_fundamental_hz(),
    }
}
