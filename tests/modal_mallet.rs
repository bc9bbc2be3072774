//! Modal mallets (issue 17, item 1; docs/design.md, "Modal mallets"): a
//! hammer with modes of its own, joined to the struck object's modes by the
//! compiler.
//!
//! The independent check: a mallet of two lumped masses (the face `m1`
//! that touches, a back mass `m2` behind it on a spring-damper `k_s`,
//! `c_s`: a head on a flexible shaft) is solved by the reference solver
//! (`pwl_reference`, its `BackMass`) in *physical* coordinates, the two
//! masses as they are. The engine is given the same mallet the way a scene
//! describes one: a hammer of the whole mass `M = m1 + m2` (the rigid-body
//! motion) and a modal object with its one free-free elastic mode, written
//! here from the closed form of a two-mass chain:
//!
//! - `omega^2 = k_s (1/m1 + 1/m2)`, decay rate `sigma = c_s (1/m1 +
//!   1/m2) / 2` (the dashpot is proportional to the spring, so the mode is
//!   classically damped), `T60 = ln(1000) / sigma`;
//! - mass-normalised shape `psi_face = sqrt(m2 / (m1 M))`, `psi_back =
//!   -sqrt(m1 / (m2 M))` (unit modal mass, orthogonal to the rigid motion).
//!
//! What is compared, on the 44.1 kHz grid and on the window where a 1e-9
//! disturbance of the reference does not yet change its traces by 1e-7 or
//! its contact instants by 1e-6 samples (as in tests/stiff_switching.rs):
//! the engine's hammer height and velocity (the rigid motion) against the
//! reference's centre of mass `(m1 x_face + m2 x_back) / M`; the engine's
//! penetration `x_contact - x_hammer` (its contact point carries minus the
//! mallet's deflection) against the reference's `x_c - x_face`; the energy;
//! the contact instants. Relative L2 within 1e-6 and instants within 1e-6
//! samples, the tolerances of the stiff-switching family, which these
//! cases extend: contact at 3.17x..317.3x Nyquist, a mallet mode from 300 Hz
//! to above the Nyquist frequency, damped and undamped shafts, gravity.

use modal_contact::compile::{compile_with, CompileError};
use modal_contact::engine::{EngineState, Observation};
use modal_contact::render::{render, RenderOptions};
use modal_contact::scene::{Scene, Switching};
use modal_testkit::metrics::{
    energy_rounding_bound, energy_scale, instant_horizon, match_contacts, rel_l2, ContactLog, Ends,
    Interval,
};
use modal_testkit::scenes::{Chain, Contact, Hammer, Modal, Pickup, SceneBuilder, Wall};
use pwl_reference as reference;
use std::f64::consts::PI;

const RATE: f64 = 44_100.0;
const NYQUIST: f64 = RATE / 2.0;
const SAMPLES: usize = 2205;
const LN_1000: f64 = 6.907_755_278_982_137;

/// The struck object of the reference solver's own tests: four modes, one
/// above the Nyquist frequency, one undamped: `(f, T60, weight at the
/// contact, weight at the pickup)`.
const OBJECT: [(f64, Option<f64>, f64, f64); 4] = [
    (311.0, Some(0.6), 2.0, 1.1),
    (1303.0, Some(0.3), -1.5, 0.7),
    (7411.0, None, 1.2, -0.4),
    (1.2 * NYQUIST, Some(0.02), 0.9, 0.2),
];

/// A two-mass mallet against [`OBJECT`].
#[derive(Debug, Clone, Copy)]
struct Case {
    name: &'static str,
    /// Face and back mass [kg].
    m1: f64,
    m2: f64,
    /// The mallet's own frequency [Hz] and damping ratio.
    f_b: f64,
    zeta_b: f64,
    /// Contact frequency (face against the object's effective mass) as a
    /// multiple of Nyquist, and its damping ratio.
    fc_ratio: f64,
    zeta_c: f64,
    /// Initial height [m], velocity [m/s], gravity [m/s^2].
    x0: f64,
    v0: f64,
    g: f64,
    /// Strike a rigid wall instead of [`OBJECT`].
    wall: bool,
}

impl Case {
    fn m(&self) -> f64 {
        self.m1 + self.m2
    }

    /// `(k_s, c_s)` of the shaft.
    fn shaft(&self) -> (f64, f64) {
        let inv = 1.0 / self.m1 + 1.0 / self.m2;
        let w = 2.0 * PI * self.f_b;
        let k = w * w / inv;
        (k, 2.0 * self.zeta_b * (k / inv).sqrt())
    }

    /// `(k, c)` of the contact: the face against the object.
    fn contact(&self) -> (f64, f64) {
        let inv_eff: f64 = self.object().iter().map(|m| m.2 * m.2).sum();
        let inv = 1.0 / self.m1 + inv_eff;
        let w = 2.0 * PI * self.fc_ratio * NYQUIST;
        let k = w * w / inv;
        (k, 2.0 * self.zeta_c * (k / inv).sqrt())
    }

    /// The mallet's mode, from the closed form of the two-mass chain:
    /// `(f, T60, psi_face, psi_back)`.
    fn mallet_mode(&self) -> (f64, Option<f64>, f64, f64) {
        let (m1, m2, m) = (self.m1, self.m2, self.m());
        let (_, c_s) = self.shaft();
        let sigma = 0.5 * c_s * (1.0 / m1 + 1.0 / m2);
        let t60 = (sigma > 0.0).then(|| LN_1000 / sigma);
        (
            self.f_b,
            t60,
            (m2 / (m1 * m)).sqrt(),
            -(m1 / (m2 * m)).sqrt(),
        )
    }

    /// The struck object's modes (none for a wall).
    fn object(&self) -> &'static [(f64, Option<f64>, f64, f64)] {
        if self.wall {
            &[]
        } else {
            &OBJECT
        }
    }

    fn scene(&self) -> Scene {
        let (f, t60, face, back) = self.mallet_mode();
        let mallet = Modal::new("mallet", &["face", "back"]).mode(f, t60, &[face, back]);
        let (k, c) = self.contact();
        if self.wall {
            return SceneBuilder::new(self.name)
                .object(Wall::new("o"))
                .object(mallet)
                .hammer(
                    Hammer::new(self.m())
                        .height(self.x0)
                        .velocity(self.v0)
                        .gravity(self.g)
                        .mallet("mallet", "face"),
                )
                .contact(Contact::new("o", k).damping(c).switching(Switching::Exact))
                .pickup(Pickup::new("mallet", "back").pan(1.0))
                .try_build()
                .expect("valid scene");
        }
        let mut object = Modal::new("o", &["c", "p"]);
        for &(f, t60, w, wp) in &OBJECT {
            object = object.mode(f, t60, &[w, wp]);
        }
        SceneBuilder::new(self.name)
            .object(object)
            .object(mallet)
            .hammer(
                Hammer::new(self.m())
                    .height(self.x0)
                    .velocity(self.v0)
                    .gravity(self.g)
                    .mallet("mallet", "face"),
            )
            .contact(
                Contact::new("o", k)
                    .point("c")
                    .damping(c)
                    .switching(Switching::Exact),
            )
            .pickup(Pickup::new("o", "p").pan(-1.0))
            .pickup(Pickup::new("mallet", "back").pan(1.0))
            .try_build()
            .expect("valid scene")
    }

    fn model(&self) -> reference::Model {
        let modes = self
            .object()
            .iter()
            .map(|&(freq_hz, t60_s, weight, _)| reference::Mode {
                freq_hz,
                t60_s,
                weight,
            })
            .collect();
        let (k, c) = self.contact();
        self.model_with(modes, k, c)
    }

    /// The reference's model of this mallet striking `modes` through the
    /// contact `(k, c)`.
    fn model_with(&self, modes: Vec<reference::Mode>, k: f64, c: f64) -> reference::Model {
        let (k_s, c_s) = self.shaft();
        reference::Model {
            modes,
            hammer: reference::Hammer {
                mass_kg: self.m1,
                height_m: self.x0,
                velocity_m_per_s: self.v0,
                gravity_m_per_s2: self.g,
            },
            contact: reference::Contact {
                stiffness_n_per_m: k,
                damping_n_s_per_m: c,
            },
            back: Some(reference::BackMass {
                mass_kg: self.m2,
                spring_n_per_m: k_s,
                damping_n_s_per_m: c_s,
            }),
            extra: Vec::new(),
            masses: vec![],
            links: vec![],
        }
    }
}

fn cases() -> Vec<Case> {
    let base = Case {
        name: "rubber head 5+20 g, shaft 900 Hz, 3.17x",
        m1: 0.005,
        m2: 0.02,
        f_b: 900.0,
        zeta_b: 0.02,
        fc_ratio: 3.17,
        zeta_c: 0.1,
        x0: 2e-4,
        v0: -1.0,
        g: 0.0,
        wall: false,
    };
    vec![
        base,
        Case {
            name: "hard head, 31.3x, undamped shaft",
            fc_ratio: 31.3,
            zeta_b: 0.0,
            zeta_c: 0.0,
            ..base
        },
        Case {
            name: "stiff critical contact 317.3x, heavy back",
            m2: 0.2,
            f_b: 300.0,
            fc_ratio: 317.3,
            zeta_c: 1.0,
            ..base
        },
        Case {
            name: "mallet mode above Nyquist (1.4x)",
            f_b: 1.4 * NYQUIST,
            zeta_b: 0.05,
            fc_ratio: 31.3,
            ..base
        },
        Case {
            name: "dropped under gravity, 31.3x",
            m1: 0.01,
            m2: 0.1,
            f_b: 450.0,
            zeta_b: 0.05,
            fc_ratio: 31.3,
            zeta_c: 0.3,
            x0: 1e-3,
            v0: 0.0,
            g: 9.81,
            wall: false,
        },
        Case {
            name: "on a wall, 31.3x, gravity",
            m1: 0.01,
            m2: 0.1,
            f_b: 450.0,
            zeta_b: 0.05,
            fc_ratio: 31.3,
            zeta_c: 0.3,
            x0: 1e-3,
            v0: 0.0,
            g: 9.81,
            wall: true,
        },
    ]
}

fn intervals(sol: &reference::Solution) -> Vec<Interval> {
    sol.contacts
        .iter()
        .map(|c| (c.start_s * RATE, c.end_s.map(|e| e * RATE)))
        .collect()
}

/// The engine's observations and contact intervals over `SAMPLES`.
fn run_engine(scene: &Scene) -> (Vec<Observation>, Vec<Interval>, f64, EngineState) {
    let sc = compile_with(scene, RATE, Some(Switching::Exact)).expect("compiles");
    let mut st = EngineState::new(&sc);
    let mut obs = vec![st.observe(&sc)];
    let mut log = ContactLog::default();
    for i in 0..SAMPLES {
        st.tick(&sc);
        for ev in st.switch_events() {
            log.record(i as f64 + ev.after_s * RATE, ev.entered)
                .expect("contacts alternate");
        }
        obs.push(st.observe(&sc));
    }
    (obs, log.finish(None), energy_rounding_bound(&sc), st)
}

/// Compare the engine's run of `scene` with the reference's of `model` (a
/// two-mass mallet: face `m1`, back `m2`, gravity `g`) as the module
/// documentation says; prints one line, returns the failures.
fn against_reference(
    name: &str,
    scene: &Scene,
    model: &reference::Model,
    m1: f64,
    m2: f64,
    g: f64,
) -> Vec<String> {
    let mut failures = Vec::new();
    let sol = reference::solve(model, RATE, SAMPLES);
    let twin = reference::solve(&model.perturbed(1e-9), RATE, SAMPLES);
    let ref_c = intervals(&sol);
    let hz = reference::horizon(&sol, &twin, 1e-7).min(instant_horizon(
        &ref_c,
        &intervals(&twin),
        1e-6,
        SAMPLES,
    ));
    let w = hz + 1;
    let (obs, eng_c, bound, st) = run_engine(scene);
    let m = m1 + m2;
    let reference_of = |f: &dyn Fn(&reference::Sample) -> f64| -> Vec<f64> {
        sol.samples[..w].iter().map(f).collect()
    };
    let engine_of =
        |f: &dyn Fn(&Observation) -> f64| -> Vec<f64> { obs[..w].iter().map(f).collect() };
    let errors = [
        (
            "centre-of-mass height",
            rel_l2(
                &engine_of(&|o| o.x_hammer),
                &reference_of(&|s| (m1 * s.x_hammer + m2 * s.x_back) / m),
            ),
        ),
        (
            "centre-of-mass velocity",
            rel_l2(
                &engine_of(&|o| o.v_hammer),
                &reference_of(&|s| (m1 * s.v_hammer + m2 * s.v_back) / m),
            ),
        ),
        (
            "penetration",
            rel_l2(
                &engine_of(&|o| o.x_contact - o.x_hammer),
                &reference_of(&|s| s.x_contact - s.x_hammer),
            ),
        ),
        (
            "energy",
            rel_l2(&engine_of(&|o| o.energy), &reference_of(&|s| s.energy)),
        ),
    ];
    let mc = match_contacts(&eng_c, &ref_c, hz as f64, 1.0, Ends::EitherEnded);
    // the mallet really rings: its face moves relative to the centre
    let deflection = sol.samples[..w]
        .iter()
        .map(|s| (s.x_hammer - s.x_back).abs())
        .fold(0.0, f64::max);
    let mg = m * g;
    let rise = obs
        .windows(2)
        .map(|p| (p[1].energy - p[0].energy) / energy_scale(&p[0], mg).max(energy_scale(&p[1], mg)))
        .fold(f64::NEG_INFINITY, f64::max);
    println!(
        "{name:<44} window {hz:>4}, contacts {}/{}, x_cm {:.1e}, v_cm {:.1e}, penetration {:.1e}, \
         energy {:.1e}, instants {:.1e} samples, max dE/E {rise:.1e} (bound {bound:.1e}), deflection {deflection:.1e} m",
        mc.n_ref,
        mc.n_run,
        errors[0].1,
        errors[1].1,
        errors[2].1,
        errors[3].1,
        mc.worst()
    );
    for (what, e) in errors {
        if !(e <= 1e-6) {
            failures.push(format!("{name}: {what} relative L2 {e:e}"));
        }
    }
    if mc.n_ref != mc.n_run || mc.n_ref == 0 || !(mc.worst() <= 1e-6) {
        failures.push(format!(
            "{name}: contacts {} vs {}, worst instant {:e} samples",
            mc.n_ref,
            mc.n_run,
            mc.worst()
        ));
    }
    if hz < 200 {
        failures.push(format!("{name}: window {hz} samples < 200"));
    }
    if !(rise <= bound) {
        failures.push(format!("{name}: energy rose by {rise:e} > {bound:e}"));
    }
    let s = &st.exact_stats;
    if s.capped + s.rod_fallbacks + s.uncertified != 0 {
        failures.push(format!("{name}: exact switching counters {s:?}"));
    }
    if !(deflection > 1e-9) {
        failures.push(format!(
            "{name}: the mallet never deformed ({deflection:e} m)"
        ));
    }
    failures
}

#[test]
fn two_mass_mallet_matches_the_reference_in_physical_coordinates() {
    let mut failures = Vec::new();
    for case in cases() {
        failures.extend(against_reference(
            case.name,
            &case.scene(),
            &case.model(),
            case.m1,
            case.m2,
            case.g,
        ));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The mallet is heard: a pickup on its back point (moved onto the joined
/// object by the compiler) rings at the mallet's own frequency, the struck
/// object's pickup hears a different strike than from a rigid hammer of
/// the same mass, and a mallet with a very stiff shaft strikes like that
/// rigid hammer.
#[test]
fn the_mallet_rings_and_a_stiff_one_is_a_point_mass() {
    let case = cases()[1];
    let opts = RenderOptions {
        rate_hz: RATE,
        seconds: Some(0.1),
        ..RenderOptions::default()
    };
    let out = render(&case.scene(), &opts).expect("renders");
    // the right channel is the mallet's back point alone
    let right = &out.right;
    let peak = right.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(peak > 0.0, "the mallet's pickup is silent");
    // its frequency: zero crossings after the last contact (one mode only)
    let (_, contacts, _, _) = run_engine(&case.scene());
    let last = contacts
        .last()
        .and_then(|c| c.1)
        .expect("the mallet leaves");
    let tail = &right[last.ceil() as usize + 1..SAMPLES];
    let crossings: Vec<f64> = tail
        .windows(2)
        .enumerate()
        .filter(|(_, p)| p[0] < 0.0 && p[1] >= 0.0)
        .map(|(i, p)| i as f64 + p[0] / (p[0] - p[1]))
        .collect();
    let periods = crossings.len() - 1;
    let f = periods as f64 * RATE / (crossings[periods] - crossings[0]);
    // damped frequency of the mode: f sqrt(1 - zeta^2)
    let fd = case.f_b * (1.0 - case.zeta_b * case.zeta_b).sqrt();
    println!(
        "mallet pickup: peak {peak:.3e} m/s, {} contacts, after the last one {periods} periods at {f:.2} Hz (damped mode {fd:.2} Hz)",
        contacts.len()
    );
    assert!(
        periods >= 10 && (f - fd).abs() < 1e-3 * fd,
        "mallet rings at {f} Hz"
    );

    // the same strike with a rigid hammer of the whole mass
    let rigid = |scene: &Scene| {
        let mut s = scene.clone();
        s.hammer.object = None;
        s.hammer.point = None;
        s.pickup.truncate(1);
        s.object.truncate(1);
        s
    };
    let left_of = |scene: &Scene| render(scene, &opts).expect("renders").left;
    let mallet_left = &out.left;
    let rigid_left = left_of(&rigid(&case.scene()));
    let d = rel_l2(mallet_left, &rigid_left);
    println!("object pickup, mallet vs rigid hammer: relative L2 {d:.3}");
    assert!(d > 0.05, "the mallet changes the strike by only {d}");

    // a shaft whose mode is at 2 MHz, far above the contact: nearly rigid
    let stiff = Case {
        f_b: 2.0e6,
        zeta_b: 0.0,
        ..case
    };
    let stiff_left = left_of(&stiff.scene());
    let d_stiff = rel_l2(&stiff_left, &rigid_left);
    println!("object pickup, 2 MHz shaft vs rigid hammer: relative L2 {d_stiff:.2e}");
    assert!(d_stiff < d / 50.0, "{d_stiff} vs {d}");
}

/// Bad mallet keys: each a clear error naming the field.
#[test]
fn bad_mallets_are_refused_by_name() {
    let good = cases()[0].scene();
    bad_hammer_keys_are_refused(&good);
    bad_chain_mallets_are_refused(&good);

    // the scene file keys
    let text = good.to_toml_string();
    assert!(
        text.contains("object = \"mallet\"") && text.contains("point = \"face\""),
        "{text}"
    );
    assert_eq!(Scene::from_toml_str(&text).unwrap(), good);
}

/// The hammer's object and point keys of the mallet scene `good`, a
/// string as mallet, and a point name the join would produce.
fn bad_hammer_keys_are_refused(good: &Scene) {
    let check = |f: &dyn Fn(&mut Scene), path: &str, words: &str| {
        let mut s = good.clone();
        f(&mut s);
        let e = s.validate().expect_err(path);
        let msg = e.to_string();
        assert!(
            msg.starts_with(path) && msg.contains(words),
            "{path}: got {msg:?}"
        );
    };
    check(
        &|s| s.hammer.object = Some("nope".into()),
        "hammer.object",
        "no object named",
    );
    check(
        &|s| s.hammer.object = Some("o".into()),
        "hammer.object",
        "struck object",
    );
    check(&|s| s.hammer.point = None, "hammer.point", "missing");
    check(
        &|s| s.hammer.point = Some("tip".into()),
        "hammer.point",
        "no point",
    );
    check(
        &|s| {
            s.hammer.object = None;
        },
        "hammer.point",
        "point-mass hammer has no points",
    );
    // a lumped string (fixed ends) as mallet
    let mut with_chain = good.clone();
    with_chain
        .object
        .push(Chain::new("chain", 3, 0.01, 1e4).point("end", 0).into());
    with_chain.hammer.object = Some("chain".into());
    with_chain.hammer.point = Some("end".into());
    let e = with_chain.validate().unwrap_err().to_string();
    assert!(
        e.starts_with("hammer.object") && e.contains("string"),
        "{e}"
    );
    // a point name the join would produce already on the struck object
    let mut clash = good.clone();
    if let modal_contact::scene::ObjectSpec::Modal(m) = &mut clash.object[0] {
        m.points[1] = "mallet.back".into();
    }
    clash.pickup[0].point = "mallet.back".into();
    let e = compile_with(&clash, RATE, None).unwrap_err();
    assert!(
        matches!(&e, CompileError::Scene(s) if s.to_string().starts_with("hammer.point")),
        "{e}"
    );
}

/// A chain as the mallet of the scene `good`: the hammer's mass must be the
/// chain's; springs between the masses; points on masses; never struck.
fn bad_chain_mallets_are_refused(good: &Scene) {
    let chain = |masses: Vec<f64>, springs: Vec<f64>, point: usize| {
        let mut s = good.clone();
        let mi = s.object_index("mallet").unwrap();
        s.object[mi] = modal_contact::scene::ObjectSpec::Chain(modal_contact::scene::ChainSpec {
            name: "mallet".into(),
            masses_kg: masses,
            springs_n_per_m: springs,
            rayleigh_alpha_per_s: 0.0,
            rayleigh_beta_s: 0.0,
            points: [("face".to_string(), 0), ("back".to_string(), point)]
                .into_iter()
                .collect(),
        });
        s
    };
    let m = good.hammer.mass_kg;
    assert!(chain(vec![m / 2.0, m / 2.0], vec![1e4], 1)
        .validate()
        .is_ok());
    for (bad, path, words) in [
        (chain(vec![m, m], vec![1e4], 1), "hammer.mass_kg", "sum of"),
        (
            chain(vec![m / 2.0, m / 2.0], vec![1e4, 1e4], 1),
            "object[1].springs_n_per_m",
            "need 1 springs",
        ),
        (
            chain(vec![m / 2.0, m / 2.0], vec![-1.0], 1),
            "object[1].springs_n_per_m[0]",
            "> 0",
        ),
        (
            chain(vec![m / 2.0, m / 2.0], vec![1e4], 2),
            "object[1].points.back",
            "mass index",
        ),
        (chain(vec![m], vec![], 0), "object[1].masses_kg", "2..="),
    ] {
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.starts_with(path) && e.contains(words), "{path}: {e}");
    }
    let mut struck_chain = chain(vec![m / 2.0, m / 2.0], vec![1e4], 1);
    struck_chain.hammer.object = None;
    struck_chain.hammer.point = None;
    struck_chain.contact.object = "mallet".into();
    struck_chain.contact.point = Some("face".into());
    let e = struck_chain.validate().unwrap_err().to_string();
    assert!(
        e.starts_with("contact.object") && e.contains("free chain"),
        "{e}"
    );
}

/// The rubber-mallet preset's chain (`kind = "chain"`: cap 6 g, head 14 g,
/// shaft 6 + 8 g; springs 5.4e5, 4.0e3, 3.0e3 N/m) expands to the modes its
/// file states, each checked without an eigensolver: `det(K - omega^2 M)`
/// of the tridiagonal chain (its continuant recurrence) changes sign across
/// each frequency (within 1e-9 relative), the shapes leave `(K - omega^2
/// M) phi` at rounding, are mass-normalised and keep the centre of mass
/// still; the T60s are the Rayleigh ones the file designs (0.12, 0.115,
/// 0.02 s within 1 %), and the hammer's mass is the chain's.
#[test]
fn rubber_mallet_preset_is_the_chain_it_describes() {
    use modal_contact::scene::ObjectSpec;
    let index = modal_contact::presets::index_of("marimba-rubber-mallet").expect("preset");
    let scene = modal_contact::presets::scene(index).expect("parses");
    let mi = scene.object_index("mallet").unwrap();
    let ObjectSpec::Chain(chain) = &scene.object[mi] else {
        panic!("the mallet is a chain")
    };
    let (m, s) = (&chain.masses_kg, &chain.springs_n_per_m);
    assert_eq!(m, &[0.006, 0.014, 0.006, 0.008]);
    assert!((scene.hammer.mass_kg - chain.mass_kg()).abs() < 1e-15);
    let n = m.len();
    // K - lambda M of the free chain, tridiagonal
    let diag = |i: usize, lam: f64| {
        let k = if i > 0 { s[i - 1] } else { 0.0 } + if i + 1 < n { s[i] } else { 0.0 };
        k - lam * m[i]
    };
    let det = |lam: f64| {
        // continuant: d_i = a_i d_{i-1} - s_{i-1}^2 d_{i-2}
        let (mut d2, mut d1) = (1.0, diag(0, lam));
        for i in 1..n {
            let d = diag(i, lam) * d1 - s[i - 1] * s[i - 1] * d2;
            d2 = d1;
            d1 = d;
        }
        d1
    };
    let modal = chain.to_modal();
    assert_eq!(modal.mode.len(), n - 1);
    let pts: Vec<usize> = modal.points.iter().map(|p| chain.points[p]).collect();
    let mut freqs = Vec::new();
    for md in &modal.mode {
        let w = 2.0 * PI * md.freq_hz;
        let (lo, hi) = ((w * (1.0 - 1e-9)).powi(2), (w * (1.0 + 1e-9)).powi(2));
        assert!(det(lo) * det(hi) < 0.0, "{} Hz is not a root", md.freq_hz);
        let mut phi = vec![0.0; n];
        for (k, &j) in pts.iter().enumerate() {
            phi[j] = md.weights[k];
        }
        let lam = w * w;
        let mut res: f64 = 0.0;
        for i in 0..n {
            let mut r = diag(i, lam) * phi[i];
            if i > 0 {
                r -= s[i - 1] * phi[i - 1];
            }
            if i + 1 < n {
                r -= s[i] * phi[i + 1];
            }
            res = res.max(r.abs() / (5.4e5 * phi.iter().fold(0.0f64, |a, x| a.max(x.abs()))));
        }
        let norm: f64 = (0..n).map(|i| m[i] * phi[i] * phi[i]).sum();
        let centre: f64 = (0..n).map(|i| m[i] * phi[i]).sum();
        println!(
            "mallet mode {:.3} Hz, T60 {:.4} s: residual {res:.1e}, phi^T M phi - 1 = {:.1e}, sum m phi = {centre:.1e}",
            md.freq_hz,
            md.t60_s.unwrap(),
            norm - 1.0
        );
        assert!(res < 1e-12 && (norm - 1.0).abs() < 1e-12 && centre.abs() < 1e-12);
        freqs.push((md.freq_hz, md.t60_s.unwrap()));
    }
    for ((f, t60), (want_f, want_t60)) in
        freqs
            .iter()
            .zip([(86.2, 0.12), (191.5, 0.115), (1805.3, 0.02)])
    {
        assert!(
            (f - want_f).abs() < 0.05 && (t60 / want_t60 - 1.0).abs() < 0.01,
            "{f} Hz, {t60} s"
        );
    }
}

/// A free point mass as a scene object: one undamped mode at the lowest
/// frequency a scene allows (1e-3 Hz, a period of 1000 s) with weight `1 /
/// sqrt(m)`. Over the milliseconds of these runs its spring pulls with
/// `omega^2 x ~ 4e-5 x` [m/s^2]: a free mass to ~1e-10 of the velocities.
fn free_mass(name: &str, m: f64) -> Modal {
    Modal::new(name, &["c"]).mode(1e-3, None, &[1.0 / m.sqrt()])
}

/// Two point masses in elastic contact: the hammer `m1` at `v` hits a free
/// mass `m2` at rest. Closed form (conservation of momentum and energy):
/// after the contact `v1 = (m1 - m2) / (m1 + m2) v`, `v2 = 2 m1 / (m1 + m2) v`;
/// one contact lasting half a period of the two-mass spring, `pi sqrt(m_r /
/// k)`, `m_r = m1 m2 / (m1 + m2)`; the momentum `m1 v_h + m2 v_c` constant
/// at every sample, in contact too. Mass ratios 1e-3..1e3, contact at 0.5x
/// to 1013.7x Nyquist, exact switching. Tolerances: 1e-9 of `|v|` on the
/// velocities and the momentum (the 1e-3 Hz spring and rounding are far
/// below), 1e-6 samples on the duration (the instants are located to
/// ~1e-12 samples).
#[test]
fn free_point_masses_exchange_velocities() {
    let v = -1.0;
    let mut worst = [0.0f64; 3];
    for ratio in [1e-3, 1.0, 1e3] {
        for fc in [0.5, 31.3, 1013.7] {
            let m2 = 0.01;
            let m1 = ratio * m2;
            let mr = m1 * m2 / (m1 + m2);
            let w = 2.0 * PI * fc * NYQUIST;
            let k = w * w * mr;
            let scene = SceneBuilder::new("two masses")
                .object(free_mass("m2", m2))
                .hammer(Hammer::new(m1).height(1e-5).velocity(v))
                .contact(Contact::new("m2", k).point("c").switching(Switching::Exact))
                .pickup(Pickup::new("m2", "c"))
                .try_build()
                .expect("valid");
            let (obs, contacts, _, _) = run_engine(&scene);
            // just after the contact (the 1e-3 Hz spring has not yet
            // acted measurably)
            let after = contacts[0].1.expect("contact ended").ceil() as usize + 1;
            let last = &obs[after];
            let v1 = (m1 - m2) / (m1 + m2) * v;
            let v2 = 2.0 * m1 / (m1 + m2) * v;
            let e_v = ((last.v_hammer - v1).abs()).max((last.v_contact - v2).abs()) / v.abs();
            // momentum, less the impulse of the free mass's 1e-3 Hz spring
            // (`-m2 omega^2 x_c`, trapezoid rule)
            let w0 = 2.0 * PI * 1e-3;
            let (mut impulse, mut e_p) = (0.0, 0.0f64);
            for (i, o) in obs.iter().enumerate() {
                if i > 0 {
                    impulse -= m2 * w0 * w0 * 0.5 * (o.x_contact + obs[i - 1].x_contact) / RATE;
                }
                let p = m1 * o.v_hammer + m2 * o.v_contact - impulse;
                e_p = e_p.max((p - m1 * v).abs() / (m1 * v.abs()).max(m2 * v2.abs()));
            }
            assert_eq!(contacts.len(), 1, "ratio {ratio}, {fc}x: {contacts:?}");
            let (t0, t1) = (contacts[0].0, contacts[0].1.expect("contact ended"));
            let e_t = ((t1 - t0) - PI * (mr / k).sqrt() * RATE).abs();
            println!(
                "m1/m2 {ratio:>6}, contact {fc:>6}x Nyquist: velocities {e_v:.1e}, momentum {e_p:.1e}, duration {e_t:.1e} samples"
            );
            assert!(
                e_v < 1e-9 && e_p < 1e-9 && e_t < 1e-6,
                "ratio {ratio}, {fc}x"
            );
            for (w, e) in worst.iter_mut().zip([e_v, e_p, e_t]) {
                *w = w.max(e);
            }
        }
    }
    println!(
        "worst: velocities {:.1e}, momentum {:.1e}, duration {:.1e} samples",
        worst[0], worst[1], worst[2]
    );
}

/// A modal mallet (the two-mass one of the reference cases, undamped) hits a
/// free mass: the momentum of the whole mallet (its rigid motion) plus the
/// struck mass's is constant at every sample, through the contact and the
/// mallet's ring, and with nothing damped the energy stays (to rounding).
#[test]
fn a_modal_mallet_conserves_momentum() {
    let case = Case {
        zeta_b: 0.0,
        ..cases()[0]
    };
    let (f, _, face, back) = case.mallet_mode();
    let m_obj = 0.05;
    let k = {
        let inv = 1.0 / case.m1 + 1.0 / m_obj;
        let w = 2.0 * PI * 3.17 * NYQUIST;
        w * w / inv
    };
    let scene = SceneBuilder::new("mallet on a free mass")
        .object(free_mass("m", m_obj))
        .object(Modal::new("mallet", &["face", "back"]).mode(f, None, &[face, back]))
        .hammer(
            Hammer::new(case.m())
                .height(1e-4)
                .velocity(-1.0)
                .mallet("mallet", "face"),
        )
        .contact(Contact::new("m", k).point("c").switching(Switching::Exact))
        .pickup(Pickup::new("m", "c").pan(-1.0))
        .pickup(Pickup::new("m", "c").displacement().pan(1.0))
        .try_build()
        .expect("valid");
    // the struck mass's own velocity and displacement are its pickups'
    // (left and right; the engine's contact point moves with it minus the
    // mallet face's ring); its 1e-3 Hz spring's impulse is taken out as in
    // `free_point_masses_exchange_velocities`
    let sc = compile_with(&scene, RATE, Some(Switching::Exact)).unwrap();
    let mut st = EngineState::new(&sc);
    let p0 = -case.m();
    let e0 = st.observe(&sc).energy;
    let (mut e_p, mut e_e, mut contacts) = (0.0f64, 0.0f64, 0);
    let mut before = st.observe(&sc);
    let w0 = 2.0 * PI * 1e-3;
    let (mut impulse, mut x_prev) = (0.0, 0.0);
    for _ in 0..SAMPLES {
        // a tick's output is the pickups at its start instant
        let [v_obj, x_obj] = st.tick(&sc);
        impulse -= m_obj * w0 * w0 * 0.5 * (x_obj + x_prev) / RATE;
        x_prev = x_obj;
        contacts += st.switch_events().iter().filter(|e| e.entered).count();
        let p = case.m() * before.v_hammer + m_obj * v_obj - impulse;
        e_p = e_p.max((p - p0).abs() / p0.abs());
        before = st.observe(&sc);
        e_e = e_e.max((before.energy - e0).abs() / e0);
    }
    println!("mallet on a free mass: {contacts} contacts, momentum {e_p:.1e}, energy {e_e:.1e} (relative)");
    assert!(contacts >= 1);
    assert!(e_p < 1e-9, "momentum {e_p:e}");
    assert!(e_e < 1e-12, "energy {e_e:e}");
}

/// A mallet given as `kind = "chain"` (the two masses and the shaft's
/// spring, Rayleigh `beta = c_s / k_s` so that `C = beta K` is the shaft's
/// dashpot) expands to the closed-form mode of every case above
/// (frequency, T60, both weights within 1e-12 relative), and renders
/// against the reference solver as the hand-written mode does.
#[test]
fn a_chain_mallet_is_the_two_mass_closed_form() {
    use modal_contact::scene::{ChainSpec, ObjectSpec};
    let chain_of = |c: &Case| {
        let (k_s, c_s) = c.shaft();
        ChainSpec {
            name: "mallet".into(),
            masses_kg: vec![c.m1, c.m2],
            springs_n_per_m: vec![k_s],
            rayleigh_alpha_per_s: 0.0,
            rayleigh_beta_s: c_s / k_s,
            points: [("face".to_string(), 0), ("back".to_string(), 1)]
                .into_iter()
                .collect(),
        }
    };
    let mut worst: f64 = 0.0;
    for case in cases() {
        let modal = chain_of(&case).to_modal();
        assert_eq!(modal.mode.len(), 1);
        let md = &modal.mode[0];
        let (f, t60, face, back) = case.mallet_mode();
        let at = |p: &str| md.weights[modal.points.iter().position(|x| x == p).unwrap()];
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
        let mut e = rel(md.freq_hz, f)
            .max(rel(at("face"), face))
            .max(rel(at("back"), back));
        match (md.t60_s, t60) {
            (Some(a), Some(b)) => e = e.max(rel(a, b)),
            (None, None) => {}
            other => panic!("{}: T60 {other:?}", case.name),
        }
        worst = worst.max(e);
    }
    println!("chain mallets vs the two-mass closed form: worst relative difference {worst:.1e}");
    assert!(worst < 1e-12, "{worst:e}");

    // end to end: the chain in a scene file, against the reference
    let case = cases()[4];
    let mut scene = case.scene();
    let mi = scene.object_index("mallet").unwrap();
    scene.object[mi] = ObjectSpec::Chain(chain_of(&case));
    let scene = Scene::from_toml_str(&scene.to_toml_string()).expect("a valid scene file");
    let sol = reference::solve(&case.model(), RATE, SAMPLES);
    let (obs, contacts, _, _) = run_engine(&scene);
    let w = 1000;
    let (m1, m2, m) = (case.m1, case.m2, case.m());
    let cm: Vec<f64> = sol.samples[..w]
        .iter()
        .map(|s| (m1 * s.x_hammer + m2 * s.x_back) / m)
        .collect();
    let e = rel_l2(
        &obs[..w].iter().map(|o| o.x_hammer).collect::<Vec<_>>(),
        &cm,
    );
    println!(
        "chain mallet dropped under gravity vs the reference: centre of mass {e:.1e}, {} contacts",
        contacts.len()
    );
    assert!(e < 1e-9 && !contacts.is_empty(), "{e:e}");
}

/// A modal mallet on a lumped string (`kind = "string"`): the string's
/// contact is not a rank-one update of modes, so the compiler joins the two
/// models and the general eigensolver takes them together. Checked against
/// the reference solver given the string by its closed-form modes (a
/// uniform fixed-fixed chain of `n` masses `m`, springs `s`: `omega_j = 2
/// sqrt(s/m) sin(j pi / (2 (n+1)))`, mass-normalised shapes `sqrt(2 / (m
/// (n+1))) sin(i j pi / (n+1))`, Rayleigh damping `sigma_j = (alpha + beta
/// omega_j^2) / 2`) and the two-mass mallet in physical coordinates; same
/// comparison and tolerances as the modal cases.
#[test]
fn a_mallet_on_a_lumped_string_takes_the_general_route() {
    let (n, m, s, alpha, beta) = (12usize, 2e-3, 4e4, 2.0, 1e-6);
    let (c_idx, p_idx) = (3usize, 8usize);
    let mallet = Case {
        name: "mallet on a string",
        m1: 0.004,
        m2: 0.012,
        f_b: 700.0,
        zeta_b: 0.03,
        fc_ratio: 31.3,
        zeta_c: 0.2,
        x0: 1e-4,
        v0: -1.0,
        g: 0.0,
        wall: false,
    };
    // the contact against the face and the string's mass at the point
    let inv = 1.0 / mallet.m1 + 1.0 / m;
    let w = 2.0 * PI * mallet.fc_ratio * NYQUIST;
    let k = w * w / inv;
    let c = 2.0 * mallet.zeta_c * (k / inv).sqrt();
    let (f, t60, face, back) = mallet.mallet_mode();
    let scene = SceneBuilder::new("string and mallet")
        .object(
            Chain::new("o", n, m, s)
                .rayleigh(alpha, beta)
                .point("c", c_idx)
                .point("p", p_idx),
        )
        .object(Modal::new("mallet", &["face", "back"]).mode(f, t60, &[face, back]))
        .hammer(
            Hammer::new(mallet.m())
                .height(mallet.x0)
                .velocity(mallet.v0)
                .mallet("mallet", "face"),
        )
        .contact(
            Contact::new("o", k)
                .point("c")
                .damping(c)
                .switching(Switching::Exact),
        )
        .try_build()
        .expect("valid");
    let scene = Scene::from_toml_str(&scene.to_toml_string()).expect("a valid scene file");
    let sc = compile_with(&scene, RATE, Some(Switching::Exact)).expect("compiles");
    println!("{}", sc.summary.lines().next().unwrap_or(""));
    assert_eq!(sc.free.dim, 2 * (n + 1), "string and mallet joined");

    let modes: Vec<reference::Mode> = (1..=n)
        .map(|j| {
            let omega = 2.0 * (s / m).sqrt() * (j as f64 * PI / (2.0 * (n as f64 + 1.0))).sin();
            let sigma = 0.5 * (alpha + beta * omega * omega);
            let shape = |i: usize| {
                (2.0 / (m * (n as f64 + 1.0))).sqrt()
                    * ((i + 1) as f64 * j as f64 * PI / (n as f64 + 1.0)).sin()
            };
            reference::Mode {
                freq_hz: omega / (2.0 * PI),
                t60_s: Some(LN_1000 / sigma),
                weight: shape(c_idx),
            }
        })
        .collect();
    let model = mallet.model_with(modes, k, c);
    let failures = against_reference(
        "mallet on a 12-mass string",
        &scene,
        &model,
        mallet.m1,
        mallet.m2,
        0.0,
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
