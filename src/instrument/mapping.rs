//! Parameters to scenes: what each instrument parameter does to the scene
//! it plays (pure functions of the parameters; they allocate and run off
//! the audio thread), and the velocity and pitch mappings.

use super::{
    DAMPER_T60_DIVISOR, DEFAULT_BEND_RANGE_SEMITONES, DEFAULT_POLYPHONY, DEFAULT_ROOT_NOTE,
    IMPACT_SPEED_RANGE_M_PER_S, MIN_IMPACT_SPEED_M_PER_S, UNDAMPED_RELEASE_T60_S,
    WHEEL_SPEED_RANGE,
};
use crate::presets;
use crate::scene::{ObjectSpec, Scene, Switching, DEFAULT_RELEASE_DAMPER};

/// Velocity (0..1) to the hammer's impact speed \[m/s\]: `0.05 + 2.95 vel^2`.
/// \[any-thread\]
pub fn impact_speed_m_per_s(velocity_norm: f64) -> f64 {
    let v = if velocity_norm.is_finite() {
        velocity_norm.clamp(0.0, 1.0)
    } else {
        0.0
    };
    MIN_IMPACT_SPEED_M_PER_S + IMPACT_SPEED_RANGE_M_PER_S * v * v
}

/// A driven scene's speed along its path \[m/s\] for a note of impact
/// speed `impact_m_per_s` ([`impact_speed_m_per_s`]; docs/design.md,
/// "Rolling and scraping"): the scene's own `drive.speed_m_per_s` times
/// the impact speed's ratio to velocity 100's, so velocity 100 plays the
/// scene as written, a softer note a slower stroke and a harder one a
/// faster one (0.03 to 1.6 times it). \[any-thread\]
pub fn drive_speed_m_per_s(scene_speed_m_per_s: f64, impact_m_per_s: f64) -> f64 {
    scene_speed_m_per_s * impact_m_per_s / impact_speed_m_per_s(100.0 / 127.0)
}

/// The mod wheel's factor on a driven scene's speed along its path
/// (docs/design.md, "Rolling and scraping"): `WHEEL_SPEED_RANGE^wheel`,
/// 1 at rest (the note's velocity alone sets the speed) to
/// [`WHEEL_SPEED_RANGE`] at full; a wheel that is not a number counts as
/// at rest. \[any-thread\]
pub fn wheel_speed_factor(mod_wheel: f64) -> f64 {
    let w = if mod_wheel.is_finite() {
        mod_wheel.clamp(0.0, 1.0)
    } else {
        0.0
    };
    WHEEL_SPEED_RANGE.powf(w)
}

/// A note's brightness as its factor on a driven scene's speed along its
/// path (MPE's slide, CC 74 on the note's channel; docs/design.md,
/// "Rolling and scraping"): `WHEEL_SPEED_RANGE^(2 b - 1)`, 1 at MPE's
/// centre 0.5, from `1 / WHEEL_SPEED_RANGE` at 0 to [`WHEEL_SPEED_RANGE`]
/// at 1; a brightness that is not a number counts as the centre.
/// \[any-thread\]
pub fn slide_speed_factor(brightness: f64) -> f64 {
    let b = if brightness.is_nan() {
        0.5
    } else {
        brightness.clamp(0.0, 1.0)
    };
    WHEEL_SPEED_RANGE.powf(2.0 * b - 1.0)
}

/// Which per-voice variants beyond the hardness levels to compile (the
/// plugin asks for them when a host first modulates that parameter per
/// voice: docs/plugin.md, "Polyphonic modulation").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VariantSet {
    /// The strike-position levels, at every hardness level (20 scenes).
    pub position: bool,
    /// The damper levels (4 damped scenes).
    pub damper: bool,
}

/// Parameters that change the compiled scene (a change needs a recompile on
/// the worker).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneParams {
    /// Index into [`presets::PRESETS`].
    pub preset: usize,
    /// Hammer mass multiplier.
    pub hammer_mass_factor: f64,
    /// Contact stiffness multiplier (hardness).
    pub stiffness_factor: f64,
    /// Contact damping multiplier.
    pub damping_factor: f64,
    /// Strike position along the object, 0..1; `None` = the scene's contact point.
    pub strike_pos_norm: Option<f64>,
    /// Decay time multiplier (T60 times it; Rayleigh damping over it).
    pub decay_scale: f64,
    /// Damper strength after note-off, 0..1 (decay times after note-off
    /// divided by `1 + 50 * damper`): the Damper parameter's when
    /// `damper_custom`, else unused until [`SceneParams::resolved_for`]
    /// puts the scene's own there (a [`Prepared`](super::Prepared)'s
    /// `params` carry the value it plays).
    pub damper_norm: f64,
    /// Damper strength from `damper_norm` (the Damper parameter); off: the
    /// scene's own (`[play] damper`, [`Scene::release_damper`]).
    pub damper_custom: bool,
    /// Gravity for bouncing scenes (scenes whose hammer has gravity) \[m/s^2\].
    pub gravity_m_per_s2: f64,
    /// Switching method (exact falls back to offset-rod if the compiler refuses it).
    pub switching: Switching,
    /// The user's own scene plays instead of the preset when not 0: its
    /// generation number (the plugin's scene library keeps the text; each
    /// loaded scene gets a new number).
    pub user_scene: u64,
    /// Which per-voice variants to compile besides the hardness levels.
    pub variants: VariantSet,
}

impl Default for SceneParams {
    fn default() -> Self {
        Self {
            preset: presets::index_of("marimba-bar").unwrap_or(0),
            hammer_mass_factor: 1.0,
            stiffness_factor: 1.0,
            damping_factor: 1.0,
            strike_pos_norm: None,
            decay_scale: 1.0,
            damper_norm: DEFAULT_RELEASE_DAMPER,
            damper_custom: false,
            gravity_m_per_s2: 9.81,
            switching: Switching::Exact,
            user_scene: 0,
            variants: VariantSet::default(),
        }
    }
}

impl SceneParams {
    /// These parameters as `base` plays them: without `damper_custom`,
    /// `damper_norm` is the scene's own damper ([`Scene::release_damper`]:
    /// `[play] damper`, else [`DEFAULT_RELEASE_DAMPER`]). \[any-thread\]
    pub fn resolved_for(&self, base: &Scene) -> SceneParams {
        let mut p = *self;
        if !p.damper_custom {
            p.damper_norm = base.release_damper();
        }
        p
    }
}

/// Parameters read at note-on or per sample (no recompile).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlayParams {
    /// Notes scale the time axis (pitch); off = every note plays the root.
    pub pitch_tracking: bool,
    /// Drop height for bouncing scenes \[m\].
    pub drop_height_m: f64,
    /// Output gain \[dB\].
    pub gain_db: f64,
    /// Voices that may sound at once, 1..=[`MAX_VOICES`](super::MAX_VOICES).
    pub polyphony: usize,
    /// Pitch bend at full wheel \[semitones\], 0..=[`MAX_BEND_RANGE_SEMITONES`](super::MAX_BEND_RANGE_SEMITONES).
    pub bend_range_semitones: f64,
    /// How far the voices may run behind the output \[s\]: the output's
    /// latency (docs/plugin.md, "Lookahead"; at most
    /// [`MAX_LOOKAHEAD_SAMPLES`](super::MAX_LOOKAHEAD_SAMPLES)).
    pub lookahead_s: f64,
}

impl Default for PlayParams {
    fn default() -> Self {
        Self {
            pitch_tracking: true,
            drop_height_m: 0.02,
            gain_db: -6.0,
            polyphony: DEFAULT_POLYPHONY,
            bend_range_semitones: DEFAULT_BEND_RANGE_SEMITONES,
            lookahead_s: 0.0,
        }
    }
}

/// All instrument parameters.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InstrumentParams {
    /// What needs a compile.
    pub scene: SceneParams,
    /// What does not.
    pub play: PlayParams,
}

/// Change every damping of the scene's objects: each modal T60 (`None` =
/// undamped) by `t60`, each damping rate of a string (Rayleigh `alpha`,
/// `beta`, dashpots) by `rate`. Longer decay times are smaller rates, so a
/// caller scales the two inversely.
fn scale_damping(
    s: &mut Scene,
    t60: impl Fn(Option<f64>) -> Option<f64>,
    rate: impl Fn(f64) -> f64,
) {
    // a modal mallet keeps its own ring: decay and damper act on what it strikes
    let mallet = s.hammer.object.clone();
    for obj in &mut s.object {
        if mallet.as_deref() == Some(obj.name()) {
            continue;
        }
        if let Some(p) = obj.physical() {
            // sigma of every mode is linear in the loss model's rates
            let eta = p.shape("").map_or(0.0, |(_, eta)| eta);
            let undamped = t60(None).map_or(0.0, |t| crate::physics::model::LN_1000 / t);
            if let Some((loss, _)) = obj.physical_mut() {
                *loss = loss.scaled(eta, undamped, &rate);
            }
            continue;
        }
        match obj {
            ObjectSpec::Modal(m) => {
                for mode in &mut m.mode {
                    mode.t60_s = t60(mode.t60_s);
                }
            }
            ObjectSpec::String(st) => {
                st.rayleigh_alpha_per_s = rate(st.rayleigh_alpha_per_s);
                st.rayleigh_beta_s = rate(st.rayleigh_beta_s);
                for d in &mut st.dashpots {
                    d.n_s_per_m = rate(d.n_s_per_m);
                }
            }
            ObjectSpec::Chain(c) => {
                c.rayleigh_alpha_per_s = rate(c.rayleigh_alpha_per_s);
                c.rayleigh_beta_s = rate(c.rayleigh_beta_s);
            }
            _ => {}
        }
    }
}

fn positive_or(v: f64, fallback: f64) -> f64 {
    if v.is_finite() && v > 0.0 {
        v
    } else {
        fallback
    }
}

/// The scene a parameter set describes (pure; allocates).
///
/// - hammer mass, contact stiffness and contact damping are multiplied by
///   their factors (a chain mallet's masses with the hammer's);
/// - decay scale: every T60 is multiplied by it, a string's Rayleigh
///   `alpha`, `beta` and dashpots are divided by it;
/// - strike position (when `Some`): on a string, the contact point moves to
///   mass `round(pos * (masses - 1))`; on a modal object with at least 3
///   points, the points in their listed order are taken as evenly spaced
///   samples of the striking line and each mode's contact weight becomes the
///   linear interpolation of its weights at `pos * (points - 1)`; objects
///   with fewer points (and walls) ignore it; on an object from geometry
///   and material (bar, tube, plate, membrane, stiff string) the contact
///   point moves to [`crate::scene::PhysicalSpec::strike_point`] and its
///   weights come from the mode shapes there;
/// - gravity: scenes whose hammer has gravity (bouncing scenes) get the
///   parameter's value; others stay without gravity;
/// - switching is set in the scene's contact section.
///
/// \[any-thread\]
pub fn scene_for(base: &Scene, p: &InstrumentParams) -> Scene {
    let sp = &p.scene;
    let mut s = base.clone();
    let mass_factor = positive_or(sp.hammer_mass_factor, 1.0);
    s.hammer.mass_kg *= mass_factor;
    // a chain mallet's rigid motion is its masses' sum: heavier together
    // (the hammer's mallet and each striker's)
    let mallets: Vec<String> = s
        .hammer
        .object
        .iter()
        .cloned()
        .chain(
            s.striker
                .iter()
                .filter_map(|st| st.mallet.as_ref().map(|m| m.object.clone())),
        )
        .collect();
    for name in &mallets {
        if let Some(mi) = s.object_index(name) {
            if let ObjectSpec::Chain(c) = &mut s.object[mi] {
                c.masses_kg.iter_mut().for_each(|m| *m *= mass_factor);
            }
        }
    }
    s.contact.stiffness_n_per_m *= positive_or(sp.stiffness_factor, 1.0);
    if let Some(law) = &mut s.contact.law {
        law.scale_force(positive_or(sp.stiffness_factor, 1.0));
    }
    let cf = if sp.damping_factor.is_finite() && sp.damping_factor >= 0.0 {
        sp.damping_factor
    } else {
        1.0
    };
    s.contact.damping_n_s_per_m *= cf;
    // a kit's other mallets are mallets too (its touches are not)
    for st in &mut s.striker {
        st.mass_kg *= mass_factor;
        st.stiffness_n_per_m *= positive_or(sp.stiffness_factor, 1.0);
        if let Some(law) = &mut st.law {
            law.scale_force(positive_or(sp.stiffness_factor, 1.0));
        }
        st.damping_n_s_per_m *= cf;
    }
    let ds = positive_or(sp.decay_scale, 1.0);
    scale_damping(&mut s, |t| t.map(|t| t * ds), |r| r / ds);
    if let Some(pos) = sp.strike_pos_norm {
        let pos = if pos.is_finite() {
            pos.clamp(0.0, 1.0)
        } else {
            0.5
        };
        set_strike_position(&mut s, pos);
    }
    if base.hammer.gravity_m_per_s2 > 0.0 {
        s.hammer.gravity_m_per_s2 = positive_or(sp.gravity_m_per_s2, base.hammer.gravity_m_per_s2);
    }
    s.contact.switching = Some(sp.switching);
    s
}

fn set_strike_position(s: &mut Scene, pos: f64) {
    let Some(point) = s.contact.point.clone() else {
        return;
    };
    let Some(ci) = s.object_index(&s.contact.object) else {
        return;
    };
    if let Some(p) = s.object[ci].physical() {
        let Some(&current) = p.points().get(&point) else {
            return;
        };
        let new = p.strike_point(pos, current);
        if let Some((_, points)) = s.object[ci].physical_mut() {
            points.insert(point, new);
        }
        return;
    }
    match &mut s.object[ci] {
        ObjectSpec::String(st) => {
            if st.masses == 0 {
                return;
            }
            let idx = (pos * (st.masses - 1) as f64).round() as usize;
            st.points.insert(point, idx.min(st.masses - 1));
        }
        ObjectSpec::Modal(m) => {
            let n_pts = m.points.len();
            if n_pts < 3 {
                return;
            }
            let Some(pi) = m.points.iter().position(|p| *p == point) else {
                return;
            };
            let x = pos * (n_pts - 1) as f64;
            let i0 = (x.floor() as usize).min(n_pts - 2);
            let frac = x - i0 as f64;
            for mode in &mut m.mode {
                if mode.weights.len() != n_pts {
                    continue;
                }
                let w = mode.weights[i0] * (1.0 - frac) + mode.weights[i0 + 1] * frac;
                mode.weights[pi] = w;
            }
        }
        _ => {}
    }
}

/// The scene a released voice continues on: every decay time divided by
/// `1 + 50 * damper` (T60s of modal objects; a string's Rayleigh damping and
/// dashpots multiplied by the same factor; undamped modes get
/// [`UNDAMPED_RELEASE_T60_S`] first). Same objects, same dimensions, so
/// \[`EngineState::rebind`\] carries a voice onto it. \[any-thread\]
pub fn damped_scene(scene: &Scene, damper_norm: f64) -> Scene {
    let f = 1.0 + DAMPER_T60_DIVISOR * damper_norm.clamp(0.0, 1.0);
    let mut s = scene.clone();
    scale_damping(
        &mut s,
        |t| Some(t.unwrap_or(UNDAMPED_RELEASE_T60_S) / f),
        |r| r * f,
    );
    s
}

/// Lowest modal frequency of the struck object \[Hz\], if it has one (a
/// string's lowest mode from [`crate::scene::StringSpec::mode_freq_hz`], damping
/// neglected). \[any-thread\]
pub fn lowest_frequency_hz(scene: &Scene) -> Option<f64> {
    let ci = scene.object_index(&scene.contact.object)?;
    match &scene.object[ci] {
        ObjectSpec::Modal(m) => m
            .mode
            .iter()
            .map(|x| x.freq_hz)
            .filter(|f| f.is_finite() && *f > 0.0)
            .min_by(|a, b| a.total_cmp(b)),
        ObjectSpec::String(st) => {
            let f = st.mode_freq_hz(1);
            (f.is_finite() && f > 0.0).then_some(f)
        }
        ObjectSpec::Wall(_) | ObjectSpec::Chain(_) => None,
        obj => obj.physical()?.lowest_frequency_hz(),
    }
}

/// The MIDI note nearest the scene's pitch: `[play] pitch_hz` where the
/// scene names it, else its lowest modal frequency (60 when unknown).
/// \[any-thread\]
pub fn root_note(scene: &Scene) -> f64 {
    let named = scene.play.as_ref().and_then(|p| p.pitch_hz);
    match named.or_else(|| lowest_frequency_hz(scene)) {
        Some(f) => (69.0 + 12.0 * (f / 440.0).log2()).round().clamp(0.0, 127.0),
        None => DEFAULT_ROOT_NOTE,
    }
}

/// The time scale of MIDI `key` with pitch tracking, the scene's root at
/// `root` (what a note-on plays before any bend). \[any-thread\]
pub(super) fn key_scale(key: u8, root: f64) -> f64 {
    2f64.powf((key as f64 - root) / 12.0)
}
