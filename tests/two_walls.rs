//! Two walls on one side (docs/design.md, "Several contacts"): a wall is
//! told by where it is, not by its kind, so a mass between a floor
//! (`[contact]` on a wall) and a ceiling (a `[[touch]]` on another wall)
//! compiles, and runs as the closed form; a genuinely duplicate pair (one
//! spring-damper twice) is still refused, and every refusal of a scene of
//! several contacts names the scene's field.
//!
//! The closed form of a point mass `m` between a floor at 0 and a ceiling
//! at `H` (the touch's `gap_m`), each a linear spring-damper `k, c`:
//!
//! - flight: `x = x0 + v0 t - g t^2 / 2`, to the floor (`x = 0`) or the
//!   ceiling (`x = H`), the root of a quadratic;
//! - contact: the penetration (`p = -x` under the floor, `x - H` over the
//!   ceiling) obeys `p'' + 2 zeta omega p' + omega^2 p = +-g` (`+g` on the
//!   floor, `-g` on the ceiling; `omega^2 = k / m`, `zeta = c / (2
//!   sqrt(k m))`), so with `p(0) = 0`, `p'(0) = u` (the speed coming in),
//!   `p = d + e^(-a t) (-d cos(omega_d t) + (u - a d) / omega_d
//!   sin(omega_d t))`, `d = +-g / omega^2`, `a = zeta omega`, `omega_d =
//!   omega sqrt(1 - zeta^2)`; the contact ends at its next zero. Without
//!   gravity that is `pi / omega_d`, leaving at `exp(-zeta pi / sqrt(1 -
//!   zeta^2))` of the speed it came with; with gravity the zero is found
//!   by bisection of the closed form to the last bit.
//!
//! Checked: every switch (which wall, in or out) in the closed form's
//! order; each instant against the closed form's; each speed at an impact
//! and at a release (the engine's flight state at the sample beside it,
//! carried to its own switch instant by the exact flight law) against the
//! closed form's; without gravity, each contact's duration against `pi /
//! omega_d` and its restitution against `exp(-zeta pi / sqrt(1 - zeta^2))`
//! directly; and the height and velocity at every sample against the
//! closed form. Tolerances: both sides solve the same piecewise-linear
//! equations exactly up to rounding. The engine advances each sample by a
//! closed-form block exponential (a few ulps of the state per sample) and
//! locates each switch to about an ulp of the sample (docs/numerics.md
//! section 14); the rounding grows at most linearly with the samples run
//! (up to 2.4e4 here, so a few 1e-12 of the state) and moves a
//! switch instant by the state's error over the speed there, and a height
//! or velocity near a switch by that shift times the slope (a stiff
//! contact's acceleration). Measured worst: instants 3.9e-10 samples,
//! speeds at switches 4.7e-14, contact times 1.2e-12, restitutions 5e-14,
//! heights 4.1e-13 of the ceiling, velocities 6.3e-11 of the start speed
//! (the stiffest contacts). The bounds, about 100 times those: instants
//! 1e-7 samples, speeds 1e-11, contact times and restitutions 1e-10,
//! heights 1e-10, velocities 1e-8; an instant off by a thousandth of a
//! sample, or a restitution off in its twelfth digit, fails.

use modal_contact::multi::{CompiledMulti, MultiEnd, MultiError, MultiModel, MultiState};
use modal_contact::scene::Scene;
use std::f64::consts::PI;

const RATE: f64 = 48_000.0;
const H_S: f64 = 1.0 / RATE;
const TOL_INSTANT_SAMPLES: f64 = 1e-7;
const TOL_SPEED: f64 = 1e-11;
const TOL_CONTACT: f64 = 1e-10;
const TOL_HEIGHT: f64 = 1e-10;
const TOL_VELOCITY: f64 = 1e-8;

/// A wall's spring-damper: stiffness [N/m] and damping ratio against the
/// mass.
#[derive(Debug, Clone, Copy)]
struct Wall {
    k: f64,
    zeta: f64,
}

#[derive(Debug, Clone, Copy)]
struct Case {
    name: &'static str,
    /// Mass [kg], start height [m] and velocity [m/s], gravity [m/s^2].
    m: f64,
    x0: f64,
    v0: f64,
    g: f64,
    /// The ceiling's height [m] (the touch's `gap_m`).
    ceiling_m: f64,
    floor: Wall,
    ceiling: Wall,
    /// Samples run.
    samples: usize,
}

impl Case {
    fn c(&self, w: Wall) -> f64 {
        2.0 * w.zeta * (w.k * self.m).sqrt()
    }

    /// The scene: two walls, the hammer between them.
    fn scene_text(&self) -> String {
        format!(
            r#"
version = 1
name = "two-walls"
duration_s = 1.0

[[object]]
name = "floor"
kind = "wall"

[[object]]
name = "ceiling"
kind = "wall"

[hammer]
mass_kg = {m:?}
height_m = {x0:?}
velocity_m_per_s = {v0:?}
gravity_m_per_s2 = {g:?}

[contact]
object = "floor"
stiffness_n_per_m = {k1:?}
damping_n_s_per_m = {c1:?}

[[touch]]
lower = {{ object = "hammer" }}
upper = {{ object = "ceiling" }}
gap_m = {h:?}
stiffness_n_per_m = {k2:?}
damping_n_s_per_m = {c2:?}
"#,
            m = self.m,
            x0 = self.x0,
            v0 = self.v0,
            g = self.g,
            k1 = self.floor.k,
            c1 = self.c(self.floor),
            h = self.ceiling_m,
            k2 = self.ceiling.k,
            c2 = self.c(self.ceiling),
        )
    }
}

/// A switch: contact 0 (the floor) or 1 (the ceiling) entered or left at
/// `t`, the mass's velocity `v` then.
#[derive(Debug, Clone, Copy)]
struct Event {
    contact: usize,
    entered: bool,
    t: f64,
    v: f64,
}

/// A piece of the closed-form motion from `t0`.
#[derive(Debug, Clone, Copy)]
enum Piece {
    Flight {
        t0: f64,
        x0: f64,
        v0: f64,
    },
    Contact {
        t0: f64,
        /// 0 the floor, 1 the ceiling.
        wall: usize,
        a: f64,
        wd: f64,
        d: f64,
        b: f64,
    },
}

/// `(p, p')` of a contact piece `t` after it began.
fn penetration(a: f64, wd: f64, d: f64, b: f64, t: f64) -> (f64, f64) {
    let (e, (s, c)) = ((-a * t).exp(), (wd * t).sin_cos());
    let aa = -d;
    (
        d + e * (aa * c + b * s),
        e * ((-a * aa + wd * b) * c + (-a * b - wd * aa) * s),
    )
}

/// The closed-form motion until `t_end`: its pieces and its switches.
fn closed_form(case: &Case, t_end: f64) -> (Vec<Piece>, Vec<Event>) {
    let (g, h) = (case.g, case.ceiling_m);
    let (mut t, mut x, mut v) = (0.0f64, case.x0, case.v0);
    let (mut pieces, mut events) = (vec![], vec![]);
    loop {
        pieces.push(Piece::Flight {
            t0: t,
            x0: x,
            v0: v,
        });
        // the next wall: the ceiling if the flight reaches it, else the
        // floor (each root in its form without cancellation)
        let up = h - x;
        let to_ceiling = if v > 0.0 && v * v >= 2.0 * g * up {
            Some(2.0 * up / (v + (v * v - 2.0 * g * up).sqrt()))
        } else {
            None
        };
        let (wall, tau) = match to_ceiling {
            Some(tau) => (1, tau),
            None if g == 0.0 && v >= 0.0 => break,
            None if v > 0.0 => (0, (v + (v * v + 2.0 * g * x).sqrt()) / g),
            None => (0, 2.0 * x / ((v * v + 2.0 * g * x).sqrt() - v)),
        };
        if t + tau > t_end {
            break;
        }
        t += tau;
        v -= g * tau;
        events.push(Event {
            contact: wall,
            entered: true,
            t,
            v,
        });
        let w = if wall == 0 { case.floor } else { case.ceiling };
        let w0 = (w.k / case.m).sqrt();
        let (a, wd) = (w.zeta * w0, w0 * (1.0 - w.zeta * w.zeta).sqrt());
        let (d, u) = if wall == 0 {
            (g / (w0 * w0), -v)
        } else {
            (-g / (w0 * w0), v)
        };
        let b = (u - a * d) / wd;
        pieces.push(Piece::Contact {
            t0: t,
            wall,
            a,
            wd,
            d,
            b,
        });
        let tau_c = if g == 0.0 {
            PI / wd
        } else {
            // the first sign change on a fine grid over two half periods,
            // then bisection to the last bit
            let p = |s: f64| penetration(a, wd, d, b, s).0;
            let steps = 4000;
            let span = 2.0 * PI / wd;
            let Some(i) = (1..=steps).find(|&i| p(span * i as f64 / steps as f64) <= 0.0) else {
                break; // it rests on the wall
            };
            let (mut lo, mut hi) = (
                span * (i - 1) as f64 / steps as f64,
                span * i as f64 / steps as f64,
            );
            while hi - lo > 0.0 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if p(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            hi
        };
        if t + tau_c > t_end {
            break;
        }
        let dp = penetration(a, wd, d, b, tau_c).1;
        t += tau_c;
        (x, v) = if wall == 0 { (0.0, -dp) } else { (h, dp) };
        events.push(Event {
            contact: wall,
            entered: false,
            t,
            v,
        });
    }
    (pieces, events)
}

/// Height and velocity of the closed form at `t`.
fn state_at(pieces: &[Piece], g: f64, h: f64, t: f64) -> (f64, f64) {
    let start = |p: &Piece| match p {
        Piece::Flight { t0, .. } | Piece::Contact { t0, .. } => *t0,
    };
    let k = pieces.partition_point(|p| start(p) <= t).max(1) - 1;
    match pieces[k] {
        Piece::Flight { t0, x0, v0 } => {
            let s = t - t0;
            (x0 + v0 * s - 0.5 * g * s * s, v0 - g * s)
        }
        Piece::Contact {
            t0,
            wall,
            a,
            wd,
            d,
            b,
        } => {
            let (p, dp) = penetration(a, wd, d, b, t - t0);
            if wall == 0 {
                (-p, -dp)
            } else {
                (h + p, dp)
            }
        }
    }
}

/// What the engine did against the closed form.
#[derive(Debug, Default)]
struct Agreement {
    switches: usize,
    /// Worst instant [samples], speed at a switch (relative), height
    /// (relative to the ceiling) and velocity (relative to the start
    /// speed) at a sample.
    instant: f64,
    speed: f64,
    speeds_checked: usize,
    x: f64,
    v: f64,
    /// Without gravity: worst contact duration against `pi / omega_d` and
    /// restitution against `exp(-zeta pi / sqrt(1 - zeta^2))`, relative.
    duration: f64,
    restitution: f64,
}

fn run(case: &Case) -> Agreement {
    let scene = Scene::from_toml_str(&case.scene_text()).unwrap();
    let model = MultiModel::from_scene(&scene, RATE).unwrap();
    assert_eq!(
        (model.masses.len(), model.contacts.len()),
        (1, 2),
        "{}",
        case.name
    );
    let sc = CompiledMulti::new(&model, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    st.record(true);
    let mut xs = vec![st.observe(&sc)];
    for _ in 0..case.samples {
        st.tick(&sc);
        xs.push(st.observe(&sc));
    }
    assert_eq!(st.stats.capped, 0, "{}", case.name);
    assert_eq!(st.stats.uncertified, 0, "{}", case.name);
    let t_end = case.samples as f64 * H_S;
    let (pieces, want) = closed_form(case, t_end);
    let got = st.switches.clone();
    assert_eq!(
        got.len(),
        want.len(),
        "{}: {} switches, the closed form {}",
        case.name,
        got.len(),
        want.len()
    );
    for wall in 0..2 {
        let hits = got.iter().filter(|s| s.contact == wall).count();
        assert!(
            hits >= 4,
            "{}: wall {wall} switched {hits} times",
            case.name
        );
    }
    let mut ag = Agreement {
        switches: got.len(),
        ..Agreement::default()
    };
    let (g, h) = (case.g, case.ceiling_m);
    for (i, (s, e)) in got.iter().zip(&want).enumerate() {
        assert_eq!(
            (s.contact, s.entered),
            (e.contact, e.entered),
            "{}: switch {i}",
            case.name
        );
        ag.instant = ag.instant.max((s.time_s - e.t).abs() / H_S);
        // the engine's speed at its switch: the flight beside it (before an
        // impact, after a release) at a sample within that flight, carried
        // to the switch by the exact flight law
        let (flight_from, flight_to) = if e.entered {
            (i.checked_sub(1).map_or(0.0, |j| got[j].time_s), s.time_s)
        } else {
            (s.time_s, got.get(i + 1).map_or(t_end, |n| n.time_s))
        };
        let k = if e.entered {
            (s.time_s / H_S).floor()
        } else {
            (s.time_s / H_S).ceil()
        };
        let tk = k * H_S;
        if tk > flight_from && tk < flight_to && (k as usize) < xs.len() {
            let vk = xs[k as usize].v_hammer[0];
            let v = vk - g * (s.time_s - tk);
            ag.speed = ag.speed.max((v - e.v).abs() / e.v.abs());
            ag.speeds_checked += 1;
        }
    }
    // without gravity the contact and the restitution in closed form
    if g == 0.0 {
        let mut v_in = case.v0.abs();
        for (i, pair) in got.chunks_exact(2).enumerate() {
            let w = if pair[0].contact == 0 {
                case.floor
            } else {
                case.ceiling
            };
            let wd = (w.k / case.m).sqrt() * (1.0 - w.zeta * w.zeta).sqrt();
            let e = (-w.zeta * PI / (1.0 - w.zeta * w.zeta).sqrt()).exp();
            let dur = pair[1].time_s - pair[0].time_s;
            ag.duration = ag.duration.max((dur * wd / PI - 1.0).abs());
            // the flight after it runs at the speed it left with
            if let Some(next) = got.get(2 * i + 2) {
                let v_out = h / (next.time_s - pair[1].time_s);
                ag.restitution = ag.restitution.max((v_out / v_in / e - 1.0).abs());
                v_in = v_out;
            }
        }
    }
    let v_scale = case.v0.abs();
    for (i, o) in xs.iter().enumerate() {
        let (x, v) = state_at(&pieces, g, h, i as f64 * H_S);
        ag.x = ag.x.max((o.x_hammer[0] - x).abs() / h);
        ag.v = ag.v.max((o.v_hammer[0] - v).abs() / v_scale);
    }
    ag
}

/// A mass between a floor and a ceiling, with gravity and without, damped
/// and elastic, contacts of many samples and of less than one: every
/// switch, speed and sample as the closed form.
#[test]
fn a_mass_between_two_walls_bounces_as_the_closed_form() {
    let cases = [
        Case {
            name: "no gravity, damped, floor 4e6 N/m zeta 0.05, ceiling 1e6 N/m zeta 0.1",
            m: 0.05,
            x0: 0.004,
            v0: -3.0,
            g: 0.0,
            ceiling_m: 0.01,
            floor: Wall { k: 4e6, zeta: 0.05 },
            ceiling: Wall { k: 1e6, zeta: 0.1 },
            samples: 24_000,
        },
        Case {
            name: "no gravity, contacts shorter than a sample (4e9 N/m, 11 us)",
            m: 0.05,
            x0: 0.004,
            v0: -3.0,
            g: 0.0,
            ceiling_m: 0.01,
            floor: Wall { k: 4e9, zeta: 0.2 },
            ceiling: Wall { k: 4e9, zeta: 0.0 },
            samples: 12_000,
        },
        Case {
            name: "gravity, damped, a steel ball between walls 5 mm apart",
            m: 0.016,
            x0: 0.001,
            v0: -2.5,
            g: 9.81,
            ceiling_m: 0.005,
            floor: Wall {
                k: 2e6,
                zeta: 0.0224,
            },
            ceiling: Wall { k: 2e6, zeta: 0.05 },
            samples: 6_000,
        },
        Case {
            name: "gravity, elastic",
            m: 0.02,
            x0: 0.002,
            v0: 1.0,
            g: 9.81,
            ceiling_m: 0.02,
            floor: Wall { k: 5e5, zeta: 0.0 },
            ceiling: Wall { k: 2e6, zeta: 0.0 },
            samples: 24_000,
        },
    ];
    for case in &cases {
        let ag = run(case);
        let closed = if case.g == 0.0 {
            format!(
                "; contact time {:.1e} off pi / omega_d, restitution {:.1e} off \
                 exp(-zeta pi / sqrt(1 - zeta^2))",
                ag.duration, ag.restitution
            )
        } else {
            String::new()
        };
        println!(
            "{}: {} switches; instants {:.1e} samples, speeds {:.1e} ({} checked), height \
             {:.1e}, velocity {:.1e}{closed}",
            case.name, ag.switches, ag.instant, ag.speed, ag.speeds_checked, ag.x, ag.v,
        );
        assert!(ag.switches >= 12, "{}: {ag:?}", case.name);
        assert!(ag.instant < TOL_INSTANT_SAMPLES, "{}: {ag:?}", case.name);
        assert!(ag.speeds_checked >= 6, "{}: {ag:?}", case.name);
        assert!(ag.speed < TOL_SPEED, "{}: {ag:?}", case.name);
        assert!(ag.x < TOL_HEIGHT, "{}: {ag:?}", case.name);
        assert!(ag.v < TOL_VELOCITY, "{}: {ag:?}", case.name);
        assert!(
            ag.duration < TOL_CONTACT && ag.restitution < TOL_CONTACT,
            "{}: {ag:?}",
            case.name
        );
    }
}

/// The scene's error of `text`: from the validator, or else from the
/// several-contact model (what compiling it refuses).
fn refusal(text: &str) -> String {
    let scene = match Scene::from_toml_str(text) {
        Ok(s) => s,
        Err(e) => return e.to_string(),
    };
    match MultiModel::from_scene(&scene, RATE) {
        Err(e) => e.to_string(),
        Ok(m) => match CompiledMulti::new(&m, RATE) {
            Err(e) => e.in_scene(&scene).to_string(),
            Ok(_) => "compiled".into(),
        },
    }
}

const BELL: &str = r#"
version = 1
name = "bell-between-walls"
duration_s = 1.0

[[object]]
name = "floor"
kind = "wall"

[[object]]
name = "ceiling"
kind = "wall"

[[object]]
name = "bell"
kind = "modal"
points = ["rim", "pickup"]
[[object.mode]]
freq_hz = 180.0
t60_s = 2.0
weights = [3.0, 1.0]
[[object.mode]]
freq_hz = 730.0
t60_s = 1.0
weights = [2.0, -1.5]

[hammer]
mass_kg = 0.05
height_m = 0.001
velocity_m_per_s = -4.0

[contact]
object = "bell"
point = "rim"
stiffness_n_per_m = 1.0e6

[[touch]]
lower = { object = "floor" }
upper = { object = "bell", point = "rim" }
gap_m = 0.0005
stiffness_n_per_m = 1.0e7

[[touch]]
lower = { object = "bell", point = "rim" }
upper = { object = "ceiling" }
gap_m = 0.0005
stiffness_n_per_m = 1.0e7
"#;

/// Two walls on an object's point (a floor under it, a ceiling over it)
/// and on a modal mallet (`hammer.object`: its face between a floor and
/// a ceiling) compile, and the run reaches both walls; two walls at one
/// height on opposite faces of a mass compile too.
#[test]
fn two_different_walls_on_one_side_compile() {
    // the struck rim swings down into the floor and up into the ceiling
    let scene = Scene::from_toml_str(BELL).unwrap();
    let m = MultiModel::from_scene(&scene, RATE).unwrap();
    assert_eq!(m.contacts.len(), 3);
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    for _ in 0..4800 {
        st.tick(&sc);
    }
    let started = st.stats.contacts_started;
    println!("bell between walls: contacts started {started:?}");
    assert!(started[1] >= 1 && started[2] >= 1, "{started:?}");

    // a modal mallet between a floor and a ceiling
    let mallet = r#"
version = 1
name = "mallet-between-walls"
duration_s = 1.0

[[object]]
name = "floor"
kind = "wall"

[[object]]
name = "ceiling"
kind = "wall"

[[object]]
name = "mallet"
kind = "modal"
points = ["face", "grip"]
[[object.mode]]
freq_hz = 900.0
t60_s = 0.2
weights = [4.0, -2.0]

[hammer]
object = "mallet"
point = "face"
mass_kg = 0.03
height_m = 0.002
velocity_m_per_s = -2.0

[contact]
object = "floor"
stiffness_n_per_m = 2.0e6

[[touch]]
lower = { object = "hammer" }
upper = { object = "ceiling" }
gap_m = 0.004
stiffness_n_per_m = 2.0e6
"#;
    let scene = Scene::from_toml_str(mallet).unwrap();
    let m = MultiModel::from_scene(&scene, RATE).unwrap();
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    for _ in 0..9600 {
        st.tick(&sc);
    }
    let started = st.stats.contacts_started;
    println!("modal mallet between walls: contacts started {started:?}");
    assert!(started[0] >= 1 && started[1] >= 1, "{started:?}");

    // the model: a floor and a ceiling are told by where they are
    let c = |lower, upper, gap_m| modal_contact::multi::MultiContact {
        lower,
        upper,
        gap_m,
        stiffness_n_per_m: 1e6,
        damping_n_s_per_m: 0.0,
    };
    let mut model = m.clone();
    model.contacts = vec![
        c(MultiEnd::Wall(0.0), MultiEnd::Mass(0), 0.0),
        c(MultiEnd::Mass(0), MultiEnd::Wall(0.0), 0.004),
    ];
    assert_eq!(model.validate(), Ok(()));
    // two floors, the second 1 mm deeper: two stages of one contact
    model.contacts[1] = c(MultiEnd::Wall(0.0), MultiEnd::Mass(0), 0.001);
    assert_eq!(model.validate(), Ok(()));
    // the same floor twice, once as a wall 1 cm up with a gap of 1 cm
    model.contacts[1] = c(MultiEnd::Wall(0.01), MultiEnd::Mass(0), 0.01);
    assert_eq!(model.validate(), Err(MultiError::SamePoint(0, 1)));
}

/// A genuinely duplicate pair: two walls of different names at one
/// height under the hammer are one surface twice, refused with the touch's
/// field path; the same wall named twice is the validator's refusal, with
/// its path.
#[test]
fn a_duplicate_pair_is_refused_with_its_field_path() {
    let case = Case {
        name: "",
        m: 0.05,
        x0: 0.004,
        v0: -3.0,
        g: 0.0,
        ceiling_m: 0.01,
        floor: Wall { k: 4e6, zeta: 0.05 },
        ceiling: Wall { k: 1e6, zeta: 0.1 },
        samples: 0,
    };
    let text = case.scene_text();
    assert_eq!(refusal(&text), "compiled");
    let two_floors = text.replace(
        "lower = { object = \"hammer\" }\nupper = { object = \"ceiling\" }\ngap_m = 0.01",
        "lower = { object = \"ceiling\" }\nupper = { object = \"hammer\" }\ngap_m = 0.0",
    );
    assert_ne!(two_floors, text);
    let e = refusal(&two_floors);
    println!("refused: {e}");
    assert!(
        e.starts_with("touch[0]: the same pair as contact (") && e.contains("one point pair"),
        "{e}"
    );
    // 1 mm deeper it is a second stage, not a duplicate
    let deeper = two_floors.replace("gap_m = 0.0", "gap_m = 0.001");
    assert_eq!(refusal(&deeper), "compiled");
    // the same wall twice: the validator's refusal
    let same = two_floors.replace(
        "lower = { object = \"ceiling\" }",
        "lower = { object = \"floor\" }",
    );
    let e = refusal(&same);
    println!("refused: {e}");
    assert!(
        e.starts_with("touch[0].upper: another contact already joins these two sides"),
        "{e}"
    );
}

/// Every refusal of a several-contact model made from a scene names the
/// scene's field: `contact`, `striker[i]`, `touch[i]` and their keys, the
/// hammer, an object's mode; over the compile budget, the largest object.
#[test]
fn compile_refusals_name_the_scene_field() {
    // one striker and the two touches of BELL: contacts 0 `contact`, 1
    // `striker[0]`, 2 and 3 `touch[0]` and `touch[1]`; masses 0 `hammer`, 1
    // `striker[0]`
    let text = BELL.replacen(
        "[[touch]]",
        "[[striker]]\nmass_kg = 0.02\nheight_m = 0.002\npoint = \"pickup\"\n\
         stiffness_n_per_m = 1.0e6\n\n[[touch]]",
        1,
    );
    let scene = Scene::from_toml_str(&text).unwrap();
    let m = MultiModel::from_scene(&scene, RATE).unwrap();
    assert_eq!((m.masses.len(), m.contacts.len()), (2, 4));
    let path = |e: MultiError| e.in_scene(&scene).path;
    let value = |field: &str| MultiError::Value {
        field: field.into(),
        value: f64::NAN,
    };
    let sides = |contact, part| MultiError::Sides {
        contact,
        part,
        why: String::new(),
    };
    for (e, want) in [
        (
            value("contacts[0].stiffness_n_per_m"),
            "contact.stiffness_n_per_m",
        ),
        (
            value("contacts[1].damping_n_s_per_m"),
            "striker[0].damping_n_s_per_m",
        ),
        (value("contacts[2].gap_m"), "touch[0].gap_m"),
        (value("contacts[3].upper.wall"), "touch[1].upper"),
        (value("contacts[1].lower.weights[1]"), "striker[0].point"),
        (value("contacts[0].lower.weights[0]"), "contact.point"),
        (value("masses[0].mass_kg"), "hammer.mass_kg"),
        (
            value("masses[1].velocity_m_per_s"),
            "striker[0].velocity_m_per_s",
        ),
        (value("gravity_m_per_s2"), "hammer.gravity_m_per_s2"),
        (value("pickups[1][0]"), "pickup"),
        (sides(2, "lower"), "touch[0].lower"),
        (sides(3, "upper"), "touch[1].upper"),
        (sides(3, "gap_m"), "touch[1].gap_m"),
        (sides(0, "gap_m"), "hammer.height_m"),
        (sides(1, "gap_m"), "striker[0].height_m"),
        (MultiError::SamePoint(1, 3), "touch[1]"),
        (
            MultiError::Phase {
                mask: 0b1010,
                why: "no block form".into(),
            },
            "striker[0]",
        ),
        (MultiError::ContactCount(5), "touch"),
    ] {
        let s = e.in_scene(&scene).to_string();
        println!("{s}");
        assert_eq!(path(e), want, "{s}");
    }
    let e = MultiError::Phase {
        mask: 0b1010,
        why: "no block form".into(),
    }
    .in_scene(&scene)
    .to_string();
    assert!(e.contains("striker[0], touch[1] in contact"), "{e}");

    // a mode's value (never out of range in a valid scene): its objects
    let mut bad = m.clone();
    bad.sigma[1] = -1.0;
    let e = CompiledMulti::new(&bad, RATE).unwrap_err();
    assert_eq!(path(e), "object");

    // over the compile budget, from the scene: the object with the most
    // modes, before any compiling
    let modes: String = (0..1000)
        .map(|i| {
            format!(
                "[[object.mode]]\nfreq_hz = {}.0\nweights = [1.0, 0.5]\n",
                100 + 10 * i
            )
        })
        .collect();
    let big = BELL.replace(
        "[[object.mode]]\nfreq_hz = 180.0",
        &format!("{modes}[[object.mode]]\nfreq_hz = 180.0"),
    );
    let t0 = std::time::Instant::now();
    let e = refusal(&big);
    println!("refused: {e}");
    assert!(e.starts_with("object[2]: 8 phases"), "{e}");
    assert!(t0.elapsed().as_secs_f64() < 5.0);
}
