//! Scenes for tests, benches and the report, built as typed values instead
//! of formatted TOML text, and the scene families they share.
//!
//! [`SceneBuilder`] fills [`Scene`] with the scene file's defaults (what
//! the scene contract, docs/design.md, "Scene files", says an omitted key
//! means: velocity, gravity and damping 0, pickups measuring velocity at
//! gain 1, centred, switching and approximations unset, `duration_s = 1`)
//! and validates the result exactly as a scene file is validated. Numbers
//! go in as `f64`s, so nothing depends on how a number would have been
//! printed (the TOML texts these builders replace wrote every number so
//! that it read back exactly; the values are the same).
//!
//! The families ([`ModalStrike`], [`chattering`], [`plate`],
//! [`wall_strike`]) are the synthetic scenes of the report and the
//! stability cases; the tests that check the report's reference build
//! them from here too, so both measure the same scene.

use modal_contact::scene::{
    ApproxSpec, ContactSpec, DashpotSpec, HammerSpec, LawSpec, ModalSpec, ModeSpec, ObjectSpec,
    PickupSpec, Quantity, Scene, SceneError, StrikerSpec, StringSpec, Switching, WallSpec,
    SCENE_VERSION,
};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::PathBuf;

/// The output rate every shared scene family is designed for \[Hz\].
pub const RATE: f64 = 44_100.0;
/// The Nyquist frequency at [`RATE`] \[Hz\].
pub const NYQ: f64 = RATE / 2.0;

// ----------------------------------------------------------------- builder

/// A [`Scene`] under construction: objects, hammer, contact, pickups.
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    name: String,
    description: String,
    duration_s: f64,
    objects: Vec<ObjectSpec>,
    hammer: Option<HammerSpec>,
    contact: Option<ContactSpec>,
    strikers: Vec<StrikerSpec>,
    pickups: Vec<PickupSpec>,
    approximate: Option<ApproxSpec>,
}

impl SceneBuilder {
    /// An empty scene named `name` (the file layout version of this build).
    pub fn new(name: &str) -> Self {
        SceneBuilder {
            name: name.to_string(),
            description: String::new(),
            duration_s: 1.0,
            objects: Vec::new(),
            hammer: None,
            contact: None,
            strikers: Vec::new(),
            pickups: Vec::new(),
            approximate: None,
        }
    }

    /// Free text.
    pub fn description(mut self, text: &str) -> Self {
        self.description = text.to_string();
        self
    }

    /// Default render length \[s\].
    pub fn duration(mut self, seconds: f64) -> Self {
        self.duration_s = seconds;
        self
    }

    /// Add a striker: another hammer with a contact of its own.
    pub fn striker(mut self, striker: StrikerSpec) -> Self {
        self.strikers.push(striker);
        self
    }

    /// Add an object ([`Modal`], [`Wall`] or [`Chain`]).
    pub fn object(mut self, object: impl Into<ObjectSpec>) -> Self {
        self.objects.push(object.into());
        self
    }

    /// The hammer.
    pub fn hammer(mut self, hammer: Hammer) -> Self {
        self.hammer = Some(hammer.0);
        self
    }

    /// The contact.
    pub fn contact(mut self, contact: Contact) -> Self {
        self.contact = Some(contact.0);
        self
    }

    /// Add a pickup.
    pub fn pickup(mut self, pickup: Pickup) -> Self {
        self.pickups.push(pickup.0);
        self
    }

    /// The `[approximate]` table.
    pub fn approximate(mut self, approx: ApproxSpec) -> Self {
        self.approximate = Some(approx);
        self
    }

    /// The scene as given (not validated). Without a hammer or a contact
    /// the scene file would not even parse: that panics.
    fn assemble(self) -> Scene {
        Scene {
            version: SCENE_VERSION,
            name: self.name,
            description: self.description,
            duration_s: self.duration_s,
            object: self.objects,
            hammer: self.hammer.expect("SceneBuilder: no hammer"),
            contact: self.contact.expect("SceneBuilder: no contact"),
            striker: self.strikers,
            touch: Vec::new(),
            pickup: self.pickups,
            approximate: self.approximate,
            play: None,
            drive: None,
            real_instrument: None,
            level_db: 0.0,
            listener: Vec::new(),
        }
    }

    /// The scene, validated as a scene file is.
    pub fn try_build(self) -> Result<Scene, SceneError> {
        let scene = self.assemble();
        scene.validate()?;
        Ok(scene)
    }

    /// The scene; panics with the validation error and the scene (a test's
    /// scene that does not validate is a bug in the test).
    pub fn build(self) -> Scene {
        let scene = self.assemble();
        if let Err(e) = scene.validate() {
            panic!("invalid test scene: {e}\n{scene:#?}");
        }
        scene
    }
}

/// A modal object: named points and modes with a weight at each point.
#[derive(Debug, Clone)]
pub struct Modal(ModalSpec);

impl Modal {
    /// No modes yet; `points` in the order every mode's weights follow.
    pub fn new(name: &str, points: &[&str]) -> Self {
        Modal(ModalSpec {
            name: name.to_string(),
            points: points.iter().map(|p| p.to_string()).collect(),
            mode: Vec::new(),
        })
    }

    /// Add a mode: frequency \[Hz\], 60 dB decay time \[s\] (`None`:
    /// undamped) and its mass-normalised weight at each point [1/sqrt(kg)].
    pub fn mode(mut self, freq_hz: f64, t60_s: impl Into<Option<f64>>, weights: &[f64]) -> Self {
        self.0.mode.push(ModeSpec {
            freq_hz,
            t60_s: t60_s.into(),
            weights: weights.to_vec(),
        });
        self
    }
}

impl From<Modal> for ObjectSpec {
    fn from(m: Modal) -> Self {
        ObjectSpec::Modal(m.0)
    }
}

/// A rigid wall at x = 0.
#[derive(Debug, Clone)]
pub struct Wall(WallSpec);

impl Wall {
    /// A wall named `name`.
    pub fn new(name: &str) -> Self {
        Wall(WallSpec {
            name: name.to_string(),
        })
    }
}

impl From<Wall> for ObjectSpec {
    fn from(w: Wall) -> Self {
        ObjectSpec::Wall(w.0)
    }
}

/// A string of lumped masses between fixed ends (`kind = "string"`).
#[derive(Debug, Clone)]
pub struct Chain(StringSpec);

impl Chain {
    /// `masses` masses of `mass_kg` joined by `masses + 1` springs of
    /// `spring_n_per_m`, undamped, no points yet.
    pub fn new(name: &str, masses: usize, mass_kg: f64, spring_n_per_m: f64) -> Self {
        Chain(StringSpec {
            name: name.to_string(),
            masses,
            mass_kg,
            spring_n_per_m,
            rayleigh_alpha_per_s: 0.0,
            rayleigh_beta_s: 0.0,
            dashpots: Vec::new(),
            points: BTreeMap::new(),
        })
    }

    /// Rayleigh damping `C = alpha M + beta K` ([1/s], \[s\]).
    pub fn rayleigh(mut self, alpha_per_s: f64, beta_s: f64) -> Self {
        self.0.rayleigh_alpha_per_s = alpha_per_s;
        self.0.rayleigh_beta_s = beta_s;
        self
    }

    /// A dashpot to ground at mass `mass` (0-based) [N s/m].
    pub fn dashpot(mut self, mass: usize, n_s_per_m: f64) -> Self {
        self.0.dashpots.push(DashpotSpec { mass, n_s_per_m });
        self
    }

    /// Name mass `mass` (0-based) as a point.
    pub fn point(mut self, name: &str, mass: usize) -> Self {
        self.0.points.insert(name.to_string(), mass);
        self
    }
}

impl From<Chain> for ObjectSpec {
    fn from(c: Chain) -> Self {
        ObjectSpec::String(c.0)
    }
}

/// The hammer: at rest at height 0, no gravity, until told otherwise.
#[derive(Debug, Clone)]
pub struct Hammer(HammerSpec);

impl Hammer {
    /// A hammer of `mass_kg`.
    pub fn new(mass_kg: f64) -> Self {
        Hammer(HammerSpec {
            mass_kg,
            height_m: 0.0,
            velocity_m_per_s: 0.0,
            gravity_m_per_s2: 0.0,
            object: None,
            point: None,
            notes: Vec::new(),
        })
    }

    /// A modal mallet: `object`'s modes are the hammer's own, touching at
    /// its `point`.
    pub fn mallet(mut self, object: &str, point: &str) -> Self {
        self.0.object = Some(object.to_string());
        self.0.point = Some(point.to_string());
        self
    }

    /// Initial height of the contact face above the surface \[m\].
    pub fn height(mut self, m: f64) -> Self {
        self.0.height_m = m;
        self
    }

    /// Initial velocity [m/s], positive up.
    pub fn velocity(mut self, m_per_s: f64) -> Self {
        self.0.velocity_m_per_s = m_per_s;
        self
    }

    /// Gravity on the hammer [m/s^2].
    pub fn gravity(mut self, m_per_s2: f64) -> Self {
        self.0.gravity_m_per_s2 = m_per_s2;
        self
    }
}

/// The contact spring-damper: undamped, the project's default switching.
#[derive(Debug, Clone)]
pub struct Contact(ContactSpec);

impl Contact {
    /// A contact with `object` (a wall: no point) of stiffness [N/m].
    pub fn new(object: &str, stiffness_n_per_m: f64) -> Self {
        Contact(ContactSpec {
            object: object.to_string(),
            point: None,
            stiffness_n_per_m,
            damping_n_s_per_m: 0.0,
            switching: None,
            law: None,
        })
    }

    /// The struck point of a modal object or string.
    pub fn point(mut self, point: &str) -> Self {
        self.0.point = Some(point.to_string());
        self
    }

    /// Contact damping [N s/m].
    pub fn damping(mut self, n_s_per_m: f64) -> Self {
        self.0.damping_n_s_per_m = n_s_per_m;
        self
    }

    /// The scene's switching method.
    pub fn switching(mut self, switching: Switching) -> Self {
        self.0.switching = Some(switching);
        self
    }
}

/// A pickup: velocity at gain 1, centred, until told otherwise.
#[derive(Debug, Clone)]
pub struct Pickup(PickupSpec);

impl Pickup {
    /// A pickup at `point` of `object`.
    pub fn new(object: &str, point: &str) -> Self {
        Pickup(PickupSpec {
            object: object.to_string(),
            point: point.to_string(),
            quantity: Quantity::Velocity,
            gain: 1.0,
            pan: 0.0,
        })
    }

    /// Measure displacement instead of velocity.
    pub fn displacement(mut self) -> Self {
        self.0.quantity = Quantity::Displacement;
        self
    }

    /// Linear gain.
    pub fn gain(mut self, gain: f64) -> Self {
        self.0.gain = gain;
        self
    }

    /// Stereo position, -1 (left) .. 1 (right).
    pub fn pan(mut self, pan: f64) -> Self {
        self.0.pan = pan;
        self
    }
}

// ----------------------------------------------------------------- presets

/// Path of `presets/<name>.toml`.
pub fn preset_path(name: &str) -> PathBuf {
    crate::workspace_root()
        .join("presets")
        .join(format!("{name}.toml"))
}

/// A preset scene (panics with the error: the presets are tested to load).
pub fn preset(name: &str) -> Scene {
    Scene::from_file(&preset_path(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The presets driven over a surface (a `[drive]` table), in the
/// preset list's order: the tests and benches of rolling and scraping
/// take each of them, a new one included.
pub fn driven_presets() -> Vec<&'static str> {
    modal_contact::presets::PRESETS
        .iter()
        .map(|p| p.name)
        .filter(|&n| preset(n).drive.is_some())
        .collect()
}

/// A scene with only its first pickup, panned hard left: the engine's left
/// channel is then that pickup times its gain (`cos(0) = 1`), the same
/// signal the competitors produce (they ignore the pan), so the report and
/// its reference tests compare like with like.
pub fn single_pickup(mut scene: Scene) -> Scene {
    // the scene's output level is a gain on every pickup (tests/level.rs):
    // the references compare the physics at unit gain
    scene.level_db = 0.0;
    scene.pickup.truncate(1);
    let p = scene
        .pickup
        .first_mut()
        .unwrap_or_else(|| panic!("{}: no pickup", scene.name));
    p.pan = -1.0;
    scene
}

/// Parse a scene from TOML text, panicking with the error and the text
/// (for tests whose subject is the text itself).
pub fn parse(text: &str) -> Scene {
    Scene::from_toml_str(text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

// --------------------------------------------------------------- families

/// Contact stiffness [N/m] that makes a hammer of mass `m` on a rigid point
/// ring at `fc` \[Hz\].
pub fn k_for(m: f64, fc: f64) -> f64 {
    m * (2.0 * PI * fc).powi(2)
}

/// Contact damping [N s/m] of damping ratio `zeta` for a hammer of mass `m`
/// on a rigid point with stiffness `k`.
pub fn c_for(m: f64, k: f64, zeta: f64) -> f64 {
    zeta * 2.0 * (k * m).sqrt()
}

/// How the modes of a [`ModalStrike`] decay when it is damped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum T60Law {
    /// 2 s at the lowest mode down to 0.1 s at the highest, geometric in
    /// the mode index (the report's scenes).
    Geometric,
    /// `2 s / (1 + f / 1 kHz)`: the law `tests/stability.rs` was written
    /// with (its printed numbers are for it).
    FallingWithFrequency,
}

/// The synthetic scene of the report and the stability cases: a modal
/// object `o` with `modes` modes geometric from `f_lo` to `f_hi` \[Hz\] and
/// weights `1 / sqrt(1 + 0.1 i)` at the contact point `c` (mode 0 has unit
/// effective mass there; the others are somewhat heavier), alternating in
/// sign at the pickup point `p`; a point-mass hammer; one velocity pickup
/// at `p`, panned hard left (see [`single_pickup`]).
///
/// Set fields directly or through the methods; [`ModalStrike::scene`]
/// builds it.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalStrike {
    /// Number of modes, geometric from `f_lo` to `f_hi`.
    pub modes: usize,
    /// Frequency of the lowest mode \[Hz\].
    pub f_lo: f64,
    /// Frequency of the highest mode \[Hz\].
    pub f_hi: f64,
    /// Whether the modes decay.
    pub damped: bool,
    /// How the modes decay, when they do.
    pub t60_law: T60Law,
    /// Hammer mass \[kg\].
    pub m_h: f64,
    /// Contact stiffness [N/m].
    pub k: f64,
    /// Contact damping [N s/m].
    pub c: f64,
    /// Gravity on the hammer [m/s^2].
    pub gravity: f64,
    /// Initial height of the hammer's contact face above the surface \[m\].
    pub height: f64,
    /// Initial velocity of the hammer [m/s], positive up.
    pub velocity: f64,
}

impl ModalStrike {
    /// `modes` undamped modes from `f_lo` to `f_hi`, a 20 g hammer touching
    /// the surface at 1 m/s down without gravity, a rigid undamped contact
    /// of 1e6 N/m: change what the case is about.
    pub fn new(modes: usize, f_lo: f64, f_hi: f64) -> Self {
        ModalStrike {
            modes,
            f_lo,
            f_hi,
            damped: false,
            t60_law: T60Law::Geometric,
            m_h: 0.02,
            k: 1e6,
            c: 0.0,
            gravity: 0.0,
            height: 0.0,
            velocity: -1.0,
        }
    }

    /// Modes decaying by [`T60Law::Geometric`] (see [`ModalStrike::t60_law`]).
    pub fn damped(mut self) -> Self {
        self.damped = true;
        self
    }

    /// How the modes decay when they are damped.
    pub fn t60_law(mut self, law: T60Law) -> Self {
        self.t60_law = law;
        self
    }

    /// Hammer mass \[kg\].
    pub fn hammer(mut self, m_h: f64) -> Self {
        self.m_h = m_h;
        self
    }

    /// Contact stiffness [N/m] and damping [N s/m].
    pub fn contact(mut self, k: f64, c: f64) -> Self {
        self.k = k;
        self.c = c;
        self
    }

    /// Dropped from rest 1 cm above the surface under gravity `g`.
    pub fn dropped(mut self, g: f64) -> Self {
        self.gravity = g;
        self.height = 0.01;
        self.velocity = 0.0;
        self
    }

    /// Initial height \[m\] and velocity [m/s] of the hammer.
    pub fn start(mut self, height: f64, velocity: f64) -> Self {
        self.height = height;
        self.velocity = velocity;
        self
    }

    /// Frequency \[Hz\] of mode `i`.
    pub fn freq(&self, i: usize) -> f64 {
        if self.modes == 1 {
            self.f_lo
        } else {
            self.f_lo * (self.f_hi / self.f_lo).powf(i as f64 / (self.modes - 1) as f64)
        }
    }

    /// The scene, named `name`.
    pub fn scene(&self, name: &str) -> Scene {
        let n = self.modes;
        let mut object = Modal::new("o", &["c", "p"]);
        for i in 0..n {
            let f = self.freq(i);
            let w = 1.0 / (1.0 + 0.1 * i as f64).sqrt();
            let wp = if i % 2 == 0 { 0.7 * w } else { -0.5 * w };
            let t60 = self.damped.then(|| match self.t60_law {
                T60Law::Geometric => {
                    let x = if n == 1 {
                        0.0
                    } else {
                        i as f64 / (n - 1) as f64
                    };
                    2.0 * (0.05f64).powf(x)
                }
                T60Law::FallingWithFrequency => 2.0 / (1.0 + f / 1000.0),
            });
            object = object.mode(f, t60, &[w, wp]);
        }
        SceneBuilder::new(name)
            .object(object)
            .hammer(
                Hammer::new(self.m_h)
                    .height(self.height)
                    .velocity(self.velocity)
                    .gravity(self.gravity),
            )
            .contact(Contact::new("o", self.k).point("c").damping(self.c))
            .pickup(Pickup::new("o", "p").pan(-1.0))
            .build()
    }
}

/// Stiff strikes on many modes (docs/numerics.md's S1/X1 at `fc_ratio` =
/// 0.09 and S2/X2 at 0.45): 20 modes from 200 Hz to 0.82 f_Nyq, T60 2 s ..
/// 0.1 s, a 0.2 kg hammer, contact frequency `fc_ratio` f_Nyq, zeta_c =
/// 0.3, 1 m/s down from 1e-5 m (the first crossing falls 0.44 of a sample
/// into the first sample).
pub fn chattering(name: &str, fc_ratio: f64) -> Scene {
    let m_h = 0.2;
    let k = k_for(m_h, fc_ratio * NYQ);
    ModalStrike::new(20, 200.0, 0.82 * NYQ)
        .damped()
        .hammer(m_h)
        .contact(k, c_for(m_h, k, 0.3))
        .start(1e-5, -1.0)
        .scene(name)
}

/// The plate of `presets/steel-plate.toml` (simply supported 400 x 280 x 8 mm
/// steel, Kirchhoff: `f_mn = (pi/2) sqrt(D/(rho h)) ((m/a)^2 + (n/b)^2)`,
/// mass-normalised shapes `2/sqrt(M) sin(m pi x/a) sin(n pi y/b)`, contact at
/// (0.37, 0.41), pickup at (0.72, 0.64) of (a, b), hard beater 0.04 kg with
/// k = 9.796e6 N/m, c = 124.1 N s/m, -1.5 m/s), but with every mode up to
/// `f_max_hz` instead of 8 kHz and a simpler loss model:
/// `T60 = ln(1000) / (1 + pi f eta)`, `eta = 1e-4` (no radiation term). The
/// beater starts 0.1 mm above the plate. Modes sorted by frequency; one
/// velocity pickup panned hard left.
pub fn plate(name: &str, f_max_hz: f64) -> Scene {
    let (e, nu, rho, thick, a, b): (f64, f64, f64, f64, f64, f64) =
        (200e9, 0.3, 7850.0, 0.008, 0.4, 0.28);
    let d = e * thick.powi(3) / (12.0 * (1.0 - nu * nu));
    let rho_h = rho * thick;
    let s = (d / rho_h).sqrt();
    let mass = rho_h * a * b;
    let f_of =
        |m: usize, n: usize| PI / 2.0 * s * ((m as f64 / a).powi(2) + (n as f64 / b).powi(2));
    let shape = |m: usize, n: usize, x: f64, y: f64| {
        2.0 / mass.sqrt() * (m as f64 * PI * x).sin() * (n as f64 * PI * y).sin()
    };
    let mut modes = Vec::new();
    for m in 1.. {
        if f_of(m, 1) > f_max_hz {
            break;
        }
        for n in 1.. {
            let f = f_of(m, n);
            if f > f_max_hz {
                break;
            }
            modes.push((f, m, n));
        }
    }
    modes.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut object = Modal::new("o", &["c", "p"]);
    for (f, m, n) in modes {
        let t60 = 1000f64.ln() / (1.0 + PI * f * 1e-4);
        object = object.mode(f, t60, &[shape(m, n, 0.37, 0.41), shape(m, n, 0.72, 0.64)]);
    }
    SceneBuilder::new(name)
        .object(object)
        .hammer(Hammer::new(0.04).height(1e-4).velocity(-1.5))
        .contact(Contact::new("o", 9.79621e6).point("c").damping(124.104))
        .pickup(Pickup::new("o", "p").pan(-1.0))
        .build()
}

/// A hammer of mass `m` against a rigid wall (`floor`), no gravity, no
/// pickup, starting `height` above it at `v0` (negative: down), contact
/// stiffness `k` and damping `c`.
pub fn wall_strike(m: f64, k: f64, c: f64, height: f64, v0: f64) -> Scene {
    SceneBuilder::new("wall")
        .object(Wall::new("floor"))
        .hammer(Hammer::new(m).height(height).velocity(v0))
        .contact(Contact::new("floor", k).damping(c))
        .build()
}

/// The worst-block bench's struck bar of `n` modes (`benches/worst_block.rs`,
/// `tests/lookahead.rs`): a bar-like spectrum from 220 Hz to 18 kHz,
/// weights that fall slowly with frequency, a 30 g hammer 1 mm above at
/// 1 m/s on a 2e6 N/m contact, `seconds` long.
pub fn struck_bar(n: usize, seconds: f64) -> Scene {
    let mut object = Modal::new("bar", &["c", "p"]);
    for i in 0..n {
        let f = 220.0 * (18000.0f64 / 220.0).powf(i as f64 / (n.max(2) - 1) as f64);
        let w = 1.0 / (1.0 + 0.02 * i as f64).sqrt();
        let wp = if i % 2 == 0 { 0.8 * w } else { -0.6 * w };
        object = object.mode(f, 2.5 / (1.0 + f / 1500.0), &[w, wp]);
    }
    SceneBuilder::new("worst-block")
        .duration(seconds)
        .object(object)
        .hammer(Hammer::new(0.03).height(1e-3).velocity(-1.0))
        .contact(Contact::new("bar", 2e6).point("c").damping(20.0))
        .pickup(Pickup::new("bar", "p"))
        .build()
}

/// The law `F = k p^power` through `spring`'s linear contact force at the
/// deepest of a 2 m/s strike of its hammer, `k_s / (2 sqrt(m / k_s))`
/// \[N/m^power\] (the same force there, whatever the power).
pub fn law_k_through_spring(spring: &Scene) -> f64 {
    let (m, ks) = (spring.hammer.mass_kg, spring.contact.stiffness_n_per_m);
    ks / (2.0 * (m / ks).sqrt())
}

/// The deepest penetration \[m\] of a mass `m` arriving at `v` on the
/// contact force `F = k p^power` alone (its kinetic energy all stored).
pub fn power_law_travel(m: f64, k: f64, power: f64, v: f64) -> f64 {
    ((power + 1.0) * m * v * v / (2.0 * k)).powf(1.0 / (power + 1.0))
}

/// `spring` with its contact's linear spring replaced by `F = k p^power`
/// fitted in `pieces` pieces over the penetrations `from` to `up_to`
/// \[m\], keeping the spring's relaxation time `c / k` (the first piece's
/// damper is that time its stiffness, as a spring made a law keeps it:
/// docs/design.md, "Stiffening contacts"). Panics if the law is not valid
/// (a test's or bench's own numbers).
pub fn with_power_law(
    spring: &Scene,
    (power, k): (f64, f64),
    pieces: usize,
    (from, up_to): (f64, f64),
) -> Scene {
    let law = LawSpec {
        power: Some(power),
        force_n_at: Some([up_to, k * up_to.powf(power)]),
        pieces: Some(pieces),
        from_m: Some(from),
        up_to_m: Some(up_to),
        ..LawSpec::default()
    };
    let first = law.pieces("contact.law").expect("a valid law").stiffness[0];
    let tau = spring.contact.damping_n_s_per_m / spring.contact.stiffness_n_per_m;
    let mut scene = spring.clone();
    scene.contact.stiffness_n_per_m = 0.0;
    scene.contact.damping_n_s_per_m = tau * first;
    scene.contact.law = Some(law);
    scene.validate().expect("a valid scene with its law");
    scene
}

/// The report's rigid-wall accuracy case: 10 g hammer, f_c = 1.59 kHz (k =
/// 1e6 N/m), zeta = 0.1, starting 0.1 mm above the wall at 1 m/s down
/// (contact starts 4.41 samples in).
pub fn wall_accuracy() -> Scene {
    let (m, k) = (0.01, 1e6);
    wall_strike(m, k, c_for(m, k, 0.1), 1e-4, -1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The builder's defaults are the scene file's: a scene that sets
    /// only what the TOML sets is the parsed TOML, field for field.
    #[test]
    fn built_scenes_equal_their_scene_files() {
        let text = r#"
version = 1
name = "all"
[[object]]
name = "bar"
kind = "modal"
points = ["c", "p"]
[[object.mode]]
freq_hz = 220.0
t60_s = 0.8
weights = [2.0, -1.0]
[[object.mode]]
freq_hz = 950.0
weights = [1.5, 0.5]
[[object]]
name = "s"
kind = "string"
masses = 5
mass_kg = 1e-3
spring_n_per_m = 1e4
rayleigh_alpha_per_s = 0.5
dashpots = [{ mass = 2, n_s_per_m = 0.01 }]
points = { a = 0, b = 4 }
[[object]]
name = "floor"
kind = "wall"
[hammer]
mass_kg = 0.01
height_m = 0.02
gravity_m_per_s2 = 9.81
[contact]
object = "bar"
point = "c"
stiffness_n_per_m = 2e5
switching = "offset-rod"
[[pickup]]
object = "bar"
point = "p"
[[pickup]]
object = "s"
point = "b"
quantity = "displacement"
gain = 1000.0
pan = 0.5
[approximate]
quiet_below_db = -60.0
"#;
        let built = SceneBuilder::new("all")
            .object(
                Modal::new("bar", &["c", "p"])
                    .mode(220.0, 0.8, &[2.0, -1.0])
                    .mode(950.0, None, &[1.5, 0.5]),
            )
            .object(
                Chain::new("s", 5, 1e-3, 1e4)
                    .rayleigh(0.5, 0.0)
                    .dashpot(2, 0.01)
                    .point("a", 0)
                    .point("b", 4),
            )
            .object(Wall::new("floor"))
            .hammer(Hammer::new(0.01).height(0.02).gravity(9.81))
            .contact(
                Contact::new("bar", 2e5)
                    .point("c")
                    .switching(Switching::OffsetRod),
            )
            .pickup(Pickup::new("bar", "p"))
            .pickup(Pickup::new("s", "b").displacement().gain(1000.0).pan(0.5))
            .approximate(ApproxSpec {
                quiet_below_db: Some(-60.0),
                ..Default::default()
            })
            .build();
        assert_eq!(built, parse(text));
    }

    #[test]
    #[should_panic(expected = "hammer.mass_kg")]
    fn an_invalid_scene_is_refused_with_the_field() {
        SceneBuilder::new("bad")
            .object(Wall::new("floor"))
            .hammer(Hammer::new(-1.0))
            .contact(Contact::new("floor", 1e6))
            .build();
    }

    #[test]
    fn the_families_validate() {
        assert_eq!(chattering("s", 0.45).object.len(), 1);
        assert!(plate("p", NYQ).pickup[0].pan == -1.0);
        assert!(wall_accuracy().pickup.is_empty());
        let s = ModalStrike::new(3, 220.0, 3500.0).damped().dropped(9.81);
        assert_eq!(s.scene("x").hammer.height_m, 0.01);
        assert_eq!(single_pickup(preset("paper-string")).pickup.len(), 1);
    }
}
