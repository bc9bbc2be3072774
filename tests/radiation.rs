//! Radiation to a listener (docs/design.md, "Radiation to a listener"): a
//! pressure pickup hears the far-field pressure of the whole surface.
//!
//! The end-to-end check is independent of the radiation module: straight in
//! front of a simply supported plate (polar 0) the far field of Rayleigh's
//! integral is `p = rho0 / (2 pi r) * d^2/dt^2 (integral of the surface
//! displacement)`, and the engine's own point pickups give that integral
//! by the midpoint rule over a grid of points (displacement pickups whose
//! gains are the cells' areas); its second difference at a high sample
//! rate is the volume acceleration. The pressure pickup, which computes
//! each mode's weight by Gauss-Legendre quadrature and writes the pressure
//! of a freely ringing mode as `-(rho0 / (2 pi r)) omega^2 (net volume)
//! q`, must agree after the strike while the plate rings. What separates
//! the two: the midpoint rule's error on the highest mode kept, `(m pi /
//! N)^2 / 24` for `m` half-waves over `N` cells (0.4 % for m = 3 over 30),
//! the second difference's `(omega h)^2 / 12` (under 1e-3 at 2 kHz and
//! 192 kHz), and the damping term a freely ringing mode's pressure leaves
//! out (`2 sigma / omega`, under 1e-3 here): 2 % bounds them all with
//! room; a wrong sign, a missing `omega^2`, a wrong gain or a mode's
//! weight off by a few percent fails.
//!
//! Also: the scene's refusals of listeners and pressure pickups name
//! their fields; the expansion's gains and weights are the ones the
//! design gives.

use modal_contact::bodies::radiation::AIR_DENSITY_KG_PER_M3;
use modal_contact::compile::compile_one;
use modal_contact::engine::EngineState;
use modal_contact::scene::{
    pressure_point, ObjectSpec, Quantity, Scene, PRESSURE_REF_AREA_M2, PRESSURE_REF_OMEGA,
};
use std::f64::consts::PI;

const RATE: f64 = 192_000.0;
const A: f64 = 0.4;
const B: f64 = 0.28;
const NX: usize = 30;
const NY: usize = 21;
const R: f64 = 2.0;
const TOL_REL: f64 = 0.02;

/// The steel plate of the steel-plate preset, modes below `max_hz`, struck
/// off-centre; `pickups` appended as written.
fn plate_scene(max_hz: f64, points: &str, pickups: &str) -> String {
    format!(
        r#"version = 1
name = "radiating-plate"
[[object]]
name = "plate"
kind = "plate"
material = {{ name = "steel", density_kg_per_m3 = 7850.0, youngs_modulus_pa = 200e9, poisson_ratio = 0.3, loss_factor = 1e-4 }}
length_x_m = {A}
length_y_m = {B}
thickness_m = 0.008
edges = "simply-supported"
max_freq_hz = {max_hz}
loss = {{ decay_rate_per_s = 0.3 }}
points = {{ contact = [0.148, 0.1148]{points} }}
[hammer]
mass_kg = 0.04
height_m = 0.001
velocity_m_per_s = -1.5
[contact]
object = "plate"
point = "contact"
stiffness_n_per_m = 2e6
damping_n_s_per_m = 20.0
[[listener]]
name = "front"
distance_m = {R}
polar_deg = 0.0
[[listener]]
name = "side"
distance_m = {R}
polar_deg = 40.0
azimuth_deg = 20.0
{pickups}"#
    )
}

fn render(scene: &Scene, n: usize) -> Vec<f64> {
    let c = compile_one(scene, RATE).unwrap();
    let mut st = EngineState::new(&c);
    (0..n).map(|_| st.tick(&c)[0]).collect()
}

#[test]
fn pressure_in_front_of_a_plate_is_its_volume_acceleration() {
    // the grid of midpoints and their displacement pickups, each weighted
    // by its cell's area
    let (dx, dy) = (A / NX as f64, B / NY as f64);
    let mut points = String::new();
    let mut grid = String::new();
    for i in 0..NX {
        for j in 0..NY {
            let (x, y) = ((i as f64 + 0.5) * dx, (j as f64 + 0.5) * dy);
            points += &format!(", g{i}_{j} = [{x}, {y}]");
            grid += &format!(
                "[[pickup]]\nobject = \"plate\"\npoint = \"g{i}_{j}\"\nquantity = \"displacement\"\ngain = {}\n",
                dx * dy
            );
        }
    }
    let pressure = "[[pickup]]\nobject = \"plate\"\npoint = \"front\"\nquantity = \"pressure\"\n";
    let max_hz = 1500.0;
    let heard = Scene::from_toml_str(&plate_scene(max_hz, &points, pressure)).unwrap();
    let volume = Scene::from_toml_str(&plate_scene(max_hz, &points, &grid)).unwrap();
    let n = (0.06 * RATE) as usize;
    let p = render(&heard, n);
    let v = render(&volume, n);
    let h = 1.0 / RATE;
    // p = rho0 / (2 pi r) * the volume acceleration (toward the listener,
    // the displacement's own sign)
    let c0 = AIR_DENSITY_KG_PER_M3 / (2.0 * PI * R);
    // after the contact (a few ms), while the plate rings
    let from = (0.01 * RATE) as usize;
    let (mut num, mut den) = (0.0, 0.0);
    for t in from..n - 1 {
        let acc = (v[t + 1] - 2.0 * v[t] + v[t - 1]) / (h * h);
        let want = c0 * acc;
        num += (p[t] - want).powi(2);
        den += want.powi(2);
    }
    let rel = (num / den).sqrt();
    println!("pressure vs the grid's volume acceleration: relative RMS {rel:.2e}");
    assert!(den > 0.0 && p.iter().all(|x| x.is_finite()));
    assert!(rel < TOL_REL, "relative RMS {rel:e}");
}

#[test]
fn pressure_pickups_expand_into_the_listeners_rows() {
    let pressure = "[[pickup]]\nobject = \"plate\"\npoint = \"side\"\nquantity = \"pressure\"\ngain = 0.5\npan = 0.3\n";
    let s = Scene::from_toml_str(&plate_scene(3000.0, "", pressure)).unwrap();
    let e = s.expanded(48_000.0).unwrap();
    assert!(e.listener.is_empty());
    assert_eq!(e.pickup.len(), 2);
    let g = -0.5 * AIR_DENSITY_KG_PER_M3 / (2.0 * PI * R) * PRESSURE_REF_AREA_M2;
    let (q, v) = (&e.pickup[0], &e.pickup[1]);
    assert_eq!(q.quantity, Quantity::Displacement);
    assert_eq!(q.point, pressure_point("side", false));
    assert!((q.gain / (g * PRESSURE_REF_OMEGA * PRESSURE_REF_OMEGA) - 1.0).abs() < 1e-14);
    assert_eq!(v.quantity, Quantity::Velocity);
    assert_eq!(v.point, pressure_point("side", true));
    assert!((v.gain / (g * PRESSURE_REF_OMEGA) - 1.0).abs() < 1e-14);
    assert_eq!((q.pan, v.pan), (0.3, 0.3));
    let ObjectSpec::Modal(m) = &e.object[0] else {
        panic!("the plate expands to a modal object");
    };
    let iq = m.points.iter().position(|p| *p == q.point).unwrap();
    let iv = m.points.iter().position(|p| *p == v.point).unwrap();
    // off the normal the modes radiate with both parts, and the (1,1)
    // mode's displacement weight is its net volume's, shifted in phase
    let first = &m.mode[0];
    let w = 2.0 * PI * first.freq_hz / PRESSURE_REF_OMEGA;
    assert!(first.weights[iq].abs() > 0.0);
    assert!(m.mode.iter().any(|md| md.weights[iv].abs() > 0.0));
    // straight in front: the (1,1) mode's net volume, closed form
    // (2 a / pi)(2 b / pi) times the mass-normalised amplitude 2 / sqrt(M)
    let front = "[[pickup]]\nobject = \"plate\"\npoint = \"front\"\nquantity = \"pressure\"\n";
    let s = Scene::from_toml_str(&plate_scene(3000.0, "", front)).unwrap();
    let e = s.expanded(48_000.0).unwrap();
    let ObjectSpec::Modal(m) = &e.object[0] else {
        panic!("modal");
    };
    let iq = m
        .points
        .iter()
        .position(|p| *p == pressure_point("front", false))
        .unwrap();
    let iv = m
        .points
        .iter()
        .position(|p| *p == pressure_point("front", true))
        .unwrap();
    let mass = 7850.0 * A * B * 0.008;
    let net = 2.0 / mass.sqrt() * (2.0 * A / PI) * (2.0 * B / PI);
    let want = w * w * net / PRESSURE_REF_AREA_M2;
    let got = m.mode[0].weights[iq];
    println!("(1,1) weight {got} against the closed form {want}");
    assert!((got / want - 1.0).abs() < 1e-9, "{got} vs {want}");
    assert!(m
        .mode
        .iter()
        .all(|md| md.weights[iv].abs() < 1e-9 * want.abs()));
}

#[test]
fn listeners_and_pressure_pickups_are_checked_with_their_fields() {
    let ok = "[[pickup]]\nobject = \"plate\"\npoint = \"front\"\nquantity = \"pressure\"\n";
    let base = plate_scene(3000.0, "", ok);
    assert!(Scene::from_toml_str(&base).is_ok());
    for (from, to, want) in [
        (
            "distance_m = 2\npolar_deg = 0.0",
            "distance_m = 0.01\npolar_deg = 0.0",
            "listener[0].distance_m",
        ),
        (
            "polar_deg = 40.0",
            "polar_deg = 120.0",
            "listener[1].polar_deg: must be within 0 ..= 90",
        ),
        (
            "azimuth_deg = 20.0",
            "azimuth_deg = nan",
            "listener[1].azimuth_deg: must be finite",
        ),
        ("name = \"side\"", "name = \"front\"", "listener[1].name"),
        (
            "point = \"front\"\nquantity",
            "point = \"back\"\nquantity",
            "pickup[0].point: a pressure pickup names a listener",
        ),
    ] {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let got = Scene::from_toml_str(&text).unwrap_err().to_string();
        assert!(got.contains(want), "{to}: {got}");
    }
    // a modal object has no surface to radiate from
    let modal = r#"version = 1
name = "m"
[[object]]
name = "bar"
kind = "modal"
points = ["contact"]
[[object.mode]]
freq_hz = 220.0
t60_s = 1.0
weights = [1.0]
[hammer]
mass_kg = 0.03
height_m = 0.001
[contact]
object = "bar"
point = "contact"
stiffness_n_per_m = 3e5
[[listener]]
name = "front"
distance_m = 1.0
[[pickup]]
object = "bar"
point = "front"
quantity = "pressure"
"#;
    let got = Scene::from_toml_str(modal).unwrap_err().to_string();
    assert!(
        got.contains("pickup[0].quantity: pressure needs an object from geometry"),
        "{got}"
    );
}

/// A marimba bar (the preset's A3) with a resonator tube, heard straight
/// above, where a free bar's own far field is zero to first order (its
/// modes have no net volume) and the tube's monopole is what is heard.
fn resonated_bar(resonator: &str) -> String {
    format!(
        r#"version = 1
name = "resonated-bar"
[[object]]
name = "bar"
kind = "bar"
material = {{ name = "rosewood", density_kg_per_m3 = 1050.0, youngs_modulus_pa = 20e9, shear_modulus_pa = 1.6e9, loss_factor = 0.0075 }}
length_m = 0.4
width_m = 0.058
thickness_m = 0.022
tuning = [1.0, 4.0, 10.0]
fundamental_hz = 220.0
max_freq_hz = 3000.0
loss = {{ decay_rate_per_s = 0.5 }}
{resonator}
points = {{ contact = 0.18, centre = 0.2 }}
[hammer]
mass_kg = 0.03
height_m = 0.001
velocity_m_per_s = -2.0
[contact]
object = "bar"
point = "contact"
stiffness_n_per_m = 3e5
damping_n_s_per_m = 40.0
[[listener]]
name = "above"
distance_m = 1.0
[[pickup]]
object = "bar"
point = "above"
quantity = "pressure"
"#
    )
}

/// The tube's effect reaches the compiled object as the design says
/// (docs/design.md, "Resonator tubes"): each mode's decay rate grows by
/// the tube's `S_c^2 phi^2 Re(Z_par) / 2`, its frequency moves by the
/// reactance's share, and its listener weights gain the tube's monopole;
/// the fundamental, tuned to the tube, is the one the tube takes most from
/// and radiates loudest; the tube's own resonances above the tuned one
/// follow the bar's modes, heard through the tube's monopole and struck
/// through their first-order components on the bar's modes.
#[test]
fn a_resonator_tube_damps_and_radiates_each_mode_as_the_design_says() {
    use modal_contact::bodies::resonator::{Resonator, MAX_MIXING};
    let with = Scene::from_toml_str(&resonated_bar(
        r#"resonator = { radius_m = 0.031, point = "centre" }"#,
    ))
    .unwrap()
    .expanded(48000.0)
    .unwrap();
    let without = Scene::from_toml_str(&resonated_bar(""))
        .unwrap()
        .expanded(48000.0)
        .unwrap();
    let (ObjectSpec::Modal(a), ObjectSpec::Modal(b)) = (&with.object[0], &without.object[0]) else {
        panic!("not modal");
    };
    let at = |m: &modal_contact::scene::ModalSpec, p: &str| {
        m.points.iter().position(|q| q == p).unwrap()
    };
    let (centre, q) = (at(b, "centre"), at(a, &pressure_point("above", false)));
    let area = PI * 0.031f64.powi(2); // the bar (58 mm) covers the 62 mm mouth's width
    let tube = Resonator::tuned(0.031, b.mode[0].freq_hz, area).unwrap();
    let sigma = |t60: f64| 1000f64.ln() / t60;
    // the bar's modes, then the tube's own resonances above the tuned one
    // that no bar mode is nearly in tune with
    let own: Vec<_> = tube
        .own_modes(f64::INFINITY)
        .unwrap()
        .into_iter()
        .filter(|t| {
            b.mode.iter().all(|m| {
                let omega = 2.0 * PI * m.freq_hz;
                tube.mixing(t, omega, m.weights[centre]).abs() <= MAX_MIXING
            })
        })
        .collect();
    assert!(!own.is_empty());
    assert_eq!(a.mode.len(), b.mode.len() + own.len());
    for (t, m) in own.iter().zip(&a.mode[b.mode.len()..]) {
        let r = 2.0 * PI * t.freq_hz / PRESSURE_REF_OMEGA;
        let want = r * r * t.far_field.0 / PRESSURE_REF_AREA_M2;
        // at the struck point: the bar modes' weights there times the
        // tube mode's components on them
        let contact = at(b, "contact");
        let struck: f64 = b
            .mode
            .iter()
            .map(|mb| {
                tube.mixing(t, 2.0 * PI * mb.freq_hz, mb.weights[centre]) * mb.weights[contact]
            })
            .sum();
        println!(
            "tube mode {:.1} Hz, T60 {:.3} s, ~q weight {:.4e}, at the contact {:.4e}",
            m.freq_hz,
            m.t60_s.unwrap(),
            m.weights[q],
            m.weights[contact]
        );
        assert_eq!(m.freq_hz, t.freq_hz);
        assert!((sigma(m.t60_s.unwrap()) - t.decay_rate_per_s).abs() < 1e-9 * t.decay_rate_per_s);
        assert!((m.weights[q] - want).abs() <= 1e-9 * want.abs());
        assert!((m.weights[contact] - struck).abs() <= 1e-9 * struck.abs());
    }
    let mut loudest = (0.0, 0usize);
    for (k, (ma, mb)) in a.mode.iter().zip(&b.mode).enumerate() {
        let e = tube.on_mode(mb.freq_hz, mb.weights[centre]);
        let added = sigma(ma.t60_s.unwrap()) - sigma(mb.t60_s.unwrap());
        let shift = ma.freq_hz - mb.freq_hz;
        // the bar's own weight straight above is zero to rounding: the
        // listener's `~q` weight is the tube's, in the rows' units
        let r = 2.0 * PI * mb.freq_hz / PRESSURE_REF_OMEGA;
        let want = r * r * e.far_field.0 / PRESSURE_REF_AREA_M2;
        println!(
            "mode {k}: {:.1} Hz, sigma +{added:.4} (tube {:.4}) 1/s, shift {shift:+.5} Hz, ~q weight {:.4e} (tube {want:.4e})",
            mb.freq_hz, e.decay_rate_per_s, ma.weights[q]
        );
        assert!((added - e.decay_rate_per_s).abs() <= 1e-9 * sigma(mb.t60_s.unwrap()));
        // the reactive shift is left out (the bar keeps its tuning); it is
        // under a tenth of a cent
        assert_eq!(shift, 0.0);
        assert!(
            e.freq_shift_hz.abs() < 6e-5 * mb.freq_hz,
            "{}",
            e.freq_shift_hz
        );
        assert!((ma.weights[q] - want).abs() <= 1e-6 * want.abs().max(1e-6));
        if e.far_field.0.hypot(e.far_field.1) > loudest.0 {
            loudest = (e.far_field.0.hypot(e.far_field.1), k);
        }
    }
    assert_eq!(loudest.1, 0, "the tuned fundamental radiates loudest");
    let fundamental = sigma(a.mode[0].t60_s.unwrap()) - sigma(b.mode[0].t60_s.unwrap());
    assert!(
        fundamental > 1.0,
        "the tube takes {fundamental} 1/s from the fundamental"
    );
}

#[test]
fn bad_resonators_are_refused_with_their_field() {
    for (res, field) in [
        (
            r#"resonator = { radius_m = 0.031, point = "nowhere" }"#,
            "object[0].resonator.point",
        ),
        (
            r#"resonator = { radius_m = 0.0, point = "centre" }"#,
            "object[0].resonator.radius_m",
        ),
        (
            r#"resonator = { radius_m = 0.031, point = "centre", tuned_hz = -1.0 }"#,
            "object[0].resonator.tuned_hz",
        ),
        (
            r#"resonator = { radius_m = 3.0, point = "centre" }"#,
            "object[0].resonator",
        ),
    ] {
        let e = Scene::from_toml_str(&resonated_bar(res))
            .unwrap_err()
            .to_string();
        println!("{res}: {e}");
        assert!(e.contains(field), "{res}: {e}");
    }
}
