//! Objects from geometry and material in scene files (docs/design.md,
//! "Objects from geometry and material"): each kind against its modal
//! equivalent written out here from the closed forms (not through the
//! shapes module), the instrument's parameters on them, and bad input.

use modal_contact::instrument::{damped_scene, scene_for, InstrumentParams};
use modal_contact::render::{render, RenderOptions};
use modal_contact::scene::{ObjectSpec, Scene};
use std::f64::consts::PI;

const RATE: f64 = 48000.0;
const LN_1000: f64 = 6.907_755_278_982_137;

/// A scene around one object table (TOML), struck at `contact`, heard at
/// `pickup`.
fn scene_with(object: &str) -> String {
    format!(
        r#"
version = 1
name = "physical"
duration_s = 0.25

[[object]]
{object}

[hammer]
mass_kg = 0.02
height_m = 0.0
velocity_m_per_s = -1.0

[contact]
object = "o"
point = "contact"
stiffness_n_per_m = 2e6
damping_n_s_per_m = 10.0

[[pickup]]
object = "o"
point = "pickup"
"#
    )
}

fn parse(object: &str) -> Scene {
    Scene::from_toml_str(&scene_with(object)).unwrap_or_else(|e| panic!("{e}"))
}

fn err(object: &str) -> String {
    match Scene::from_toml_str(&scene_with(object)) {
        Err(e) => e.to_string(),
        Ok(s) => match s.expanded(RATE) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted: {object}"),
        },
    }
}

/// The modal object a scene's physical object expands to.
fn modal_of(scene: &Scene) -> modal_contact::scene::ModalSpec {
    let ex = scene.expanded(RATE).unwrap_or_else(|e| panic!("{e}"));
    match &ex.object[0] {
        ObjectSpec::Modal(m) => m.clone(),
        o => panic!("not expanded: {}", o.kind()),
    }
}

/// `scene` with its object replaced by a modal object of these modes
/// (frequency, T60, weights at contact and pickup).
fn hand_expanded(scene: &Scene, modes: &[(f64, Option<f64>, f64, f64)]) -> Scene {
    let mut text =
        String::from("name = \"o\"\nkind = \"modal\"\npoints = [\"contact\", \"pickup\"]\n");
    for (f, t60, wc, wp) in modes {
        text.push_str(&format!("[[object.mode]]\nfreq_hz = {f:e}\n"));
        if let Some(t) = t60 {
            text.push_str(&format!("t60_s = {t:e}\n"));
        }
        text.push_str(&format!("weights = [{wc:e}, {wp:e}]\n"));
    }
    let hand = parse(&text);
    let mut out = scene.clone();
    out.object = hand.object;
    out
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let d = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let peak = b.iter().map(|x| x.abs()).fold(0.0, f64::max);
    (d, peak)
}

/// The ends of the chain: the scene file in the new kind and its modal
/// equivalent written out from the closed form render the same to
/// rounding (both through the whole compiler and engine).
fn renders_like(scene: &Scene, modes: &[(f64, Option<f64>, f64, f64)], what: &str) {
    let hand = hand_expanded(scene, modes);
    let opts = RenderOptions {
        rate_hz: RATE,
        ..RenderOptions::default()
    };
    let a = render(scene, &opts).unwrap_or_else(|e| panic!("{e}"));
    let b = render(&hand, &opts).unwrap_or_else(|e| panic!("{e}"));
    let (d, peak) = max_abs_diff(&a.left, &b.left);
    println!(
        "{what}: {} modes, max |difference| {d:.3e} of peak {peak:.3e}",
        modes.len()
    );
    assert!(peak > 0.0, "{what}: silent");
    assert!(d <= 1e-12 * peak, "{what}: {d:e} vs peak {peak:e}");
}

/// Simply supported steel plate: `omega_mn = pi^2 (m^2/a^2 + n^2/b^2)
/// sqrt(D / (rho h))`, `Phi = 2 / sqrt(rho h a b) sin sin`, T60 from the
/// loss factor and a constant rate; every mode up to the Nyquist frequency.
#[test]
fn plate_is_its_closed_form() {
    let (a, b, h, rho, e, nu, eta, s0): (f64, f64, f64, f64, f64, f64, f64, f64) =
        (0.4, 0.28, 0.008, 7850.0, 2.0e11, 0.29, 2e-4, 0.3);
    let scene = parse(&format!(
        r#"name = "o"
kind = "plate"
material = {{ name = "steel", density_kg_per_m3 = {rho}, youngs_modulus_pa = {e}, poisson_ratio = {nu}, loss_factor = {eta} }}
length_x_m = {a}
length_y_m = {b}
thickness_m = {h}
loss = {{ decay_rate_per_s = {s0} }}
points = {{ contact = [0.13, 0.09], pickup = [0.31, 0.2] }}"#
    ));
    let d = e * h * h * h / (12.0 * (1.0 - nu * nu));
    let mut modes = Vec::new();
    for m in 1..200 {
        for n in 1..200 {
            let w = PI
                * PI
                * ((m * m) as f64 / (a * a) + (n * n) as f64 / (b * b))
                * (d / (rho * h)).sqrt();
            let f = w / (2.0 * PI);
            if f <= RATE / 2.0 {
                let phi = |x: f64, y: f64| {
                    2.0 / (rho * h * a * b).sqrt()
                        * (m as f64 * PI * x / a).sin()
                        * (n as f64 * PI * y / b).sin()
                };
                let t60 = LN_1000 / (s0 + eta * PI * f);
                modes.push((f, Some(t60), phi(0.13, 0.09), phi(0.31, 0.2)));
            }
        }
    }
    modes.sort_by(|x, y| x.0.total_cmp(&y.0));
    let got = modal_of(&scene);
    assert_eq!(got.mode.len(), modes.len(), "modes below Nyquist");
    let mut worst = 0.0f64;
    for (g, w) in got.mode.iter().zip(&modes) {
        worst = worst.max((g.freq_hz / w.0 - 1.0).abs());
        assert!((g.t60_s.unwrap() / w.1.unwrap() - 1.0).abs() < 1e-13);
    }
    println!(
        "plate: {} modes, worst relative frequency error {worst:.2e}",
        modes.len()
    );
    assert!(worst < 1e-13);
    renders_like(&scene, &modes, "plate");
}

/// A stiff steel wire: `f_n = n f_0 sqrt(1 + B n^2)`, `B = pi^2 E I / (T
/// L^2)`, `Phi = sqrt(2 / (mu L)) sin(n pi x / L)`, damping `sigma_0 +
/// sigma_r (f / f_r)^2` (the usual frequency-dependent string loss).
#[test]
fn stiff_string_is_its_closed_form() {
    let (l, t, dia, rho, e): (f64, f64, f64, f64, f64) = (0.65, 700.0, 1.0e-3, 7850.0, 2.0e11);
    let scene = parse(&format!(
        r#"name = "o"
kind = "stiff_string"
material = {{ name = "steel", density_kg_per_m3 = {rho}, youngs_modulus_pa = {e}, loss_factor = 0.0 }}
length_m = {l}
tension_n = {t}
diameter_m = {dia}
max_freq_hz = 12000.0
loss = {{ decay_rate_per_s = 0.4, radiation_per_s = 2.0, radiation_ref_hz = 1000.0 }}
points = {{ contact = 0.08, pickup = 0.5 }}"#
    ));
    let mu = rho * PI * dia * dia / 4.0;
    let ei = e * PI * dia.powi(4) / 64.0;
    let f0 = (t / mu).sqrt() / (2.0 * l);
    let bb = PI * PI * ei / (t * l * l);
    let mut modes = Vec::new();
    for n in 1.. {
        let f = n as f64 * f0 * (1.0 + bb * (n * n) as f64).sqrt();
        if f > 12000.0 {
            break;
        }
        let phi = |x: f64| (2.0 / (mu * l)).sqrt() * (n as f64 * PI * x / l).sin();
        let t60 = LN_1000 / (0.4 + 2.0 * (f / 1000.0).powi(2));
        modes.push((f, Some(t60), phi(0.08), phi(0.5)));
    }
    println!("stiff string: B = {bb:.3e}, f0 = {f0:.3} Hz");
    let got = modal_of(&scene);
    assert_eq!(got.mode.len(), modes.len());
    for (g, w) in got.mode.iter().zip(&modes) {
        assert!(
            (g.freq_hz / w.0 - 1.0).abs() < 1e-13,
            "{} vs {}",
            g.freq_hz,
            w.0
        );
    }
    renders_like(&scene, &modes, "stiff string");
}

/// Circular membrane: `f_mn = j_mn c / (2 pi a)` with the published Bessel
/// zeros; a point at `(r, theta)` weighs the `cos` and `sin` partners by
/// `cos(m theta)` and `sin(m theta)`.
#[test]
fn membrane_frequencies_and_angles() {
    let scene = parse(
        r#"name = "o"
kind = "membrane"
radius_m = 0.2
tension_n_per_m = 3000.0
areal_density_kg_per_m2 = 0.25
max_modes = 12
loss = { loss_factor = 0.01 }
points = { contact = [0.1, 30.0], pickup = 0.05 }"#,
    );
    let got = modal_of(&scene);
    let c = (3000.0f64 / 0.25).sqrt();
    // j_01, j_11 (x2), j_21 (x2), j_02, j_31 (x2) (Abramowitz & Stegun 9.5)
    let zeros = [
        2.404825557695773,
        3.831705970207512,
        5.135622301840683,
        5.520078110286311,
        6.380161895923984,
    ];
    let f = |j: f64| j * c / (2.0 * PI * 0.2);
    let want = [
        zeros[0], zeros[1], zeros[1], zeros[2], zeros[2], zeros[3], zeros[4], zeros[4],
    ];
    for (g, j) in got.mode.iter().zip(want) {
        assert!(
            (g.freq_hz / f(j) - 1.0).abs() < 1e-12,
            "{} vs {}",
            g.freq_hz,
            f(j)
        );
    }
    // the (1,1) pair at theta = 30 degrees: weights in ratio cos 30 : sin 30
    let (wc, ws) = (got.mode[1].weights[0], got.mode[2].weights[0]);
    assert!(
        (ws / wc - (30f64.to_radians()).tan()).abs() < 1e-12,
        "{ws} / {wc}"
    );
    // the pickup at theta = 0 hears no sin partner
    assert_eq!(got.mode[2].weights[1], 0.0);
    let _ = render(
        &scene,
        &RenderOptions {
            rate_hz: RATE,
            ..RenderOptions::default()
        },
    )
    .unwrap();
}

/// Material values: a scene may override the table's; the frequencies of
/// a bar scale as `sqrt(E / rho)`.
#[test]
fn material_overrides_scale_a_bar() {
    let bar = |extra: &str| {
        parse(&format!(
            r#"name = "o"
kind = "bar"
material = {{ name = "aluminium"{extra} }}
length_m = 0.3
width_m = 0.04
thickness_m = 0.008
timoshenko = false
points = {{ contact = 0.15, pickup = 0.02 }}"#
        ))
    };
    let base = modal_of(&bar(""));
    let stiffer = modal_of(&bar(", youngs_modulus_pa = 1.38e11"));
    let al = modal_contact::bodies::materials::material("aluminium").unwrap();
    let ratio = (1.38e11 / al.youngs_modulus_pa).sqrt();
    for (a, b) in base.mode.iter().zip(&stiffer.mode) {
        assert!((b.freq_hz / a.freq_hz / ratio - 1.0).abs() < 1e-12);
    }
    // free-free Euler-Bernoulli: f_1 = 4.730040744862704^2 / (2 pi L^2) sqrt(E I / (rho A))
    let f1 = 4.730040744862704f64.powi(2) / (2.0 * PI * 0.09)
        * (al.youngs_modulus_pa * 0.008 * 0.008 / (12.0 * al.density_kg_m3)).sqrt();
    println!(
        "aluminium bar f1 = {:.4} Hz (closed form {f1:.4})",
        base.mode[0].freq_hz
    );
    assert!((base.mode[0].freq_hz / f1 - 1.0).abs() < 1e-12);
    // the default Timoshenko correction lowers every mode, the higher ones more
    let timo = modal_of(&parse(
        r#"name = "o"
kind = "bar"
material = "aluminium"
length_m = 0.3
width_m = 0.04
thickness_m = 0.008
points = { contact = 0.15, pickup = 0.02 }"#,
    ));
    let low: Vec<f64> = timo
        .mode
        .iter()
        .zip(&base.mode)
        .map(|(t, e)| t.freq_hz / e.freq_hz)
        .collect();
    assert!(
        low.iter().all(|r| *r < 1.0) && low.windows(2).all(|w| w[1] < w[0]),
        "{low:?}"
    );
}

/// The instrument's strike position moves the contact point along the
/// object and its weights come from the mode shapes there; the decay scale
/// and the damper scale every T60 exactly (radiation damping included).
#[test]
fn instrument_parameters_on_physical_objects() {
    let scene = parse(
        r#"name = "o"
kind = "stiff_string"
linear_density_kg_per_m = 0.006
bending_stiffness_n_m2 = 1e-4
length_m = 0.65
tension_n = 700.0
max_modes = 20
loss = { decay_rate_per_s = 0.5, loss_factor = 1e-4, radiation_damping = 1.0 }
points = { contact = 0.1, pickup = 0.3 }"#,
    );
    let mut p = InstrumentParams::default();
    for pos in [0.0, 0.137, 0.5, 1.0] {
        p.scene.strike_pos_norm = Some(pos);
        let m = modal_of(&scene_for(&scene, &p));
        let ci = m.points.iter().position(|x| x == "contact").unwrap();
        for (n, mode) in m.mode.iter().enumerate() {
            let want = (2.0f64 / (0.006 * 0.65)).sqrt() * ((n + 1) as f64 * PI * pos).sin();
            assert!(
                (mode.weights[ci] - want).abs() < 1e-12 * (1.0 + want.abs()),
                "pos {pos}"
            );
        }
    }
    let base = modal_of(&scene);
    p.scene.strike_pos_norm = None;
    p.scene.decay_scale = 2.5;
    let longer = modal_of(&scene_for(&scene, &p));
    let damped = modal_of(&damped_scene(&scene, 0.4));
    let f = 1.0 + modal_contact::instrument::DAMPER_T60_DIVISOR * 0.4;
    for ((a, b), c) in base.mode.iter().zip(&longer.mode).zip(&damped.mode) {
        assert_eq!(a.freq_hz, b.freq_hz);
        assert!((b.t60_s.unwrap() / a.t60_s.unwrap() / 2.5 - 1.0).abs() < 1e-13);
        assert!((a.t60_s.unwrap() / c.t60_s.unwrap() / f - 1.0).abs() < 1e-13);
    }
    // a lossless object released gets the documented release decay
    let lossless = parse(
        r#"name = "o"
kind = "membrane"
radius_m = 0.2
tension_n_per_m = 3000.0
areal_density_kg_per_m2 = 0.25
max_modes = 4
points = { contact = 0.1, pickup = 0.05 }"#,
    );
    assert!(modal_of(&lossless).mode.iter().all(|m| m.t60_s.is_none()));
    let released = modal_of(&damped_scene(&lossless, 0.0));
    for m in &released.mode {
        let t = m.t60_s.expect("damped");
        assert!((t / modal_contact::instrument::UNDAMPED_RELEASE_T60_S - 1.0).abs() < 1e-13);
    }
}

/// Bad input: each a clear error naming the field, never a panic.
#[test]
fn bad_physical_objects_are_refused_with_the_field() {
    let bar = |geom: &str| {
        format!(
            "name = \"o\"\nkind = \"bar\"\nmaterial = \"rosewood\"\n{geom}\npoints = {{ contact = 0.1, pickup = 0.02 }}"
        )
    };
    let cases = [
        (bar("length_m = -0.3\nwidth_m = 0.05\nthickness_m = 0.02"), "object[0].length_m"),
        (bar("length_m = 0.3\nwidth_m = 0.0\nthickness_m = 0.02"), "object[0].width_m"),
        (
            "name = \"o\"\nkind = \"tube\"\nmaterial = \"brass\"\nlength_m = 1.0\nouter_diameter_m = 0.03\ninner_diameter_m = 0.03\npoints = { contact = 0.1, pickup = 0.2 }".into(),
            "object[0].inner_diameter_m",
        ),
        (
            "name = \"o\"\nkind = \"plate\"\nmaterial = { name = \"steel\", poisson_ratio = 0.6 }\nlength_x_m = 0.3\nlength_y_m = 0.2\nthickness_m = 0.002\npoints = { contact = [0.1, 0.1], pickup = [0.2, 0.1] }".into(),
            "object[0].material.poisson_ratio",
        ),
        (bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\npoints_extra = 1"), "unknown field"),
        (
            "name = \"o\"\nkind = \"bar\"\nmaterial = \"rosewood\"\nlength_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\npoints = { contact = 0.4, pickup = 0.02 }".into(),
            "object[0].points.contact",
        ),
        (
            "name = \"o\"\nkind = \"plate\"\nmaterial = \"steel\"\nlength_x_m = 0.3\nlength_y_m = 0.2\nthickness_m = 0.002\npoints = { contact = 0.1, pickup = [0.2, 0.1] }".into(),
            "object[0].points.contact",
        ),
        (
            "name = \"o\"\nkind = \"membrane\"\nradius_m = 0.2\ntension_n_per_m = 3000.0\nareal_density_kg_per_m2 = 0.25\npoints = { contact = [0.3, 0.0], pickup = 0.05 }".into(),
            "object[0].points.contact",
        ),
        (bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\nmax_freq_hz = 10.0"), "object[0].max_freq_hz"),
        (
            "name = \"o\"\nkind = \"bar\"\nmaterial = \"unobtainium\"\nlength_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\npoints = { contact = 0.1, pickup = 0.02 }".into(),
            "object[0].material.name",
        ),
        (
            "name = \"o\"\nkind = \"stiff_string\"\nlength_m = 0.6\ntension_n = 500.0\npoints = { contact = 0.1, pickup = 0.2 }".into(),
            "object[0]: give either",
        ),
        (
            bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\nloss = { dashpots = [{ point = \"cord\", n_s_per_m = 1.0 }] }"),
            "object[0].loss.dashpots[0].point",
        ),
        (
            bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\nloss = { dashpots = [{ point = \"contact\", n_s_per_m = -1.0 }] }"),
            "object[0].loss.dashpots[0].n_s_per_m",
        ),
        (
            bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\nloss = { dashpots = [{ point = \"contact\", n_s_per_m = 1e300 }] }"),
            "object[0].loss.dashpots[0].n_s_per_m",
        ),
        (
            bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\nloss = { radiation_damping = -1.0 }"),
            "object[0].loss.radiation_damping: must be",
        ),
        (
            bar("length_m = 0.3\nwidth_m = 0.05\nthickness_m = 0.02\nloss = { radiation_damping = inf }"),
            "object[0].loss.radiation_damping: must be",
        ),
        (
            "name = \"o\"\nkind = \"plate\"\nmaterial = \"steel\"\nlength_x_m = 0.3\nlength_y_m = 0.2\nthickness_m = 0.002\nloss = { radiation_damping = 1.0 }\npoints = { contact = [0.1, 0.1], pickup = [0.2, 0.1] }".into(),
            "object[0].loss.radiation_damping: a plate's radiation is loss.plate_radiation",
        ),
        // very fine geometry: a huge thin plate has far too many modes
        (
            "name = \"o\"\nkind = \"plate\"\nmaterial = \"steel\"\nlength_x_m = 3.0\nlength_y_m = 2.0\nthickness_m = 0.0005\npoints = { contact = [0.1, 0.1], pickup = [0.2, 0.1] }".into(),
            "more than the limit",
        ),
    ];
    for (object, want) in cases {
        let e = err(&object);
        println!("{want}: {e}");
        assert!(e.contains(want), "expected {want:?} in {e:?}");
    }
}

/// The strike position on a bar (keeping the contact's offset from the
/// centre line, so torsion still sounds), a plate (its diagonal) and a
/// membrane (the radius at the contact's angle): the contact weights are
/// the closed-form shapes there.
#[test]
fn strike_position_on_bars_plates_and_membranes() {
    let mut p = InstrumentParams::default();
    // a simply supported plate: Phi = 2 / sqrt(rho h a b) sin(m pi x / a) sin(n pi y / b)
    let plate = parse(
        r#"name = "o"
kind = "plate"
material = { name = "steel", density_kg_per_m3 = 7800.0 }
length_x_m = 0.5
length_y_m = 0.3
thickness_m = 0.004
max_modes = 30
points = { contact = [0.1, 0.1], pickup = [0.3, 0.2] }"#,
    );
    let pos = 0.37;
    p.scene.strike_pos_norm = Some(pos);
    let m = modal_of(&scene_for(&plate, &p));
    let norm = 2.0 / (7800.0f64 * 0.004 * 0.5 * 0.3).sqrt();
    // every (m, n) with the frequency order of the closed form
    let mut want: Vec<(f64, f64)> = Vec::new();
    for i in 1..20 {
        for j in 1..20 {
            let f = (i * i) as f64 / 0.25 + (j * j) as f64 / 0.09;
            let w = norm * (i as f64 * PI * pos).sin() * (j as f64 * PI * pos).sin();
            want.push((f, w));
        }
    }
    want.sort_by(|a, b| a.0.total_cmp(&b.0));
    let ci = m.points.iter().position(|x| x == "contact").unwrap();
    for (mode, (_, w)) in m.mode.iter().zip(&want) {
        assert!(
            (mode.weights[ci] - w).abs() < 1e-12,
            "{} vs {w}",
            mode.weights[ci]
        );
    }
    // a membrane: the radius moves, the angle stays (the (1,1) pair keeps
    // its cos : sin ratio at 40 degrees)
    let drum = parse(
        r#"name = "o"
kind = "membrane"
radius_m = 0.2
tension_n_per_m = 3000.0
areal_density_kg_per_m2 = 0.25
max_modes = 6
points = { contact = [0.05, 40.0], pickup = 0.1 }"#,
    );
    p.scene.strike_pos_norm = Some(0.6);
    let m = modal_of(&scene_for(&drum, &p));
    let ci = m.points.iter().position(|x| x == "contact").unwrap();
    let (wc, ws) = (m.mode[1].weights[ci], m.mode[2].weights[ci]);
    assert!((ws / wc - 40f64.to_radians().tan()).abs() < 1e-12);
    // (0,1) mode at r = 0.6 a: N J_0(j_01 0.6), N = 1 / (sqrt(pi sigma) a |J_1(j_01)|)
    let j01 = 2.404825557695773f64;
    // J_0 and J_1 by their power series (converges fast for these arguments)
    let bessel = |n: i32, x: f64| {
        (0..30)
            .map(|k| {
                let fact = |m: i32| (1..=m).map(f64::from).product::<f64>();
                (-1f64).powi(k) * (x / 2.0).powi(2 * k + n) / (fact(k) * fact(k + n))
            })
            .sum::<f64>()
    };
    let n = 1.0 / ((PI * 0.25).sqrt() * 0.2 * bessel(1, j01).abs());
    let want = n * bessel(0, j01 * 0.6);
    println!(
        "membrane (0,1) at r = 0.6 a: {} (closed form {want})",
        m.mode[0].weights[ci]
    );
    assert!((m.mode[0].weights[ci] - want).abs() < 1e-10 * want.abs());
    // a bar with torsion: the contact moves along, stays 10 mm off the
    // centre line, so its torsional weights are y times the twist shape
    let bar = parse(
        r#"name = "o"
kind = "bar"
material = "aluminium"
length_m = 0.3
width_m = 0.04
thickness_m = 0.008
torsion = true
max_modes = 12
points = { contact = [0.05, 0.01], pickup = [0.02, -0.01] }"#,
    );
    p.scene.strike_pos_norm = Some(0.25);
    let moved = scene_for(&bar, &p);
    let ObjectSpec::Bar(b) = &moved.object[0] else {
        panic!("bar")
    };
    assert_eq!(
        b.points["contact"],
        modal_contact::scene::PointSpec::Pair([0.075, 0.01])
    );
    let m = modal_of(&moved);
    assert!(m.mode.iter().any(|x| x.weights[0] != 0.0), "struck");
}

/// Dashpots where a bar is held (docs/design.md, "Dashpots at points"):
/// each mode's added decay rate is `sum_p c w_p^2 / 2` with `w_p` the
/// closed-form free-free Euler-Bernoulli shape, mass-normalised, written
/// out here; and that first-order rate is what the exact eigenvalues of the
/// full system (modal masses, stiffnesses and decay, plus the dashpots'
/// rank-two damping matrix, which couples the modes) give, to the order
/// the neglected coupling leaves. A dashpot at a mode's node does not damp
/// it, and the instrument's decay parameter scales the dashpots as it does
/// every other rate.
#[test]
fn dashpots_at_points_damp_each_mode_to_first_order() {
    // an aluminium bar on two cords at its fundamental's nodes
    let (len, b, h, rho, e) = (0.35, 0.057, 0.0127, 2700.0, 70e9);
    let c = 2.0;
    let bar = |dashpots: &str| {
        parse(&format!(
            "name = \"o\"\nkind = \"bar\"\n\
             material = {{ name = \"aluminium\", density_kg_per_m3 = {rho}, youngs_modulus_pa = {e}, shear_modulus_pa = 26e9, loss_factor = 0.0 }}\n\
             length_m = {len}\nwidth_m = {b}\nthickness_m = {h}\ntimoshenko = false\n\
             max_freq_hz = 20000.0\n\
             loss = {{ decay_rate_per_s = 1.0{dashpots} }}\n\
             points = {{ contact = 0.17, pickup = 0.02, cord_a = {a:.6}, cord_b = {z:.6} }}",
            a = 0.224_2 * len,
            z = 0.775_8 * len,
        ))
    };
    let plain = modal_of(&bar(""));
    let held_scene = bar(&format!(
        ", dashpots = [{{ point = \"cord_a\", n_s_per_m = {c} }}, {{ point = \"cord_b\", n_s_per_m = {c} }}]"
    ));
    let held = modal_of(&held_scene);
    assert_eq!(plain.mode.len(), held.mode.len());
    let n = held.mode.len();
    assert!(n >= 5, "{n} modes");
    let mass = rho * b * h * len;
    let shape = |k: usize, x: f64| free_free_shape(k, x / len) / mass.sqrt();
    let row = |name: &str| held.points.iter().position(|p| p == name).expect(name);
    let (ia, ib) = (row("cord_a"), row("cord_b"));
    let sigma = |t60: Option<f64>| LN_1000 / t60.expect("damped");
    let mut worst_first = 0.0_f64;
    for k in 0..n.min(6) {
        let added = sigma(held.mode[k].t60_s) - sigma(plain.mode[k].t60_s);
        let want = 0.5 * c * (shape(k, 0.224_2 * len).powi(2) + shape(k, 0.775_8 * len).powi(2));
        let rel = (added - want).abs() / want.max(1e-3);
        println!(
            "mode {k} ({:.1} Hz): added decay {added:.6e} 1/s, closed form {want:.6e} (relative error {rel:.1e})",
            held.mode[k].freq_hz
        );
        worst_first = worst_first.max(rel);
    }
    assert!(
        worst_first < 1e-4,
        "first-order rates against the closed form: {worst_first:e}"
    );
    // the fundamental sits still at its nodes: under 1e-3 of the next mode's added rate
    let added = |k: usize| sigma(held.mode[k].t60_s) - sigma(plain.mode[k].t60_s);
    assert!(added(0) < 1e-3 * added(1), "{} vs {}", added(0), added(1));

    let plain_rates: Vec<f64> = plain.mode.iter().map(|m| sigma(m.t60_s)).collect();
    let eig = exact_eigenvalues(&held, &plain_rates, &[(ia, c), (ib, c)]);
    let mut worst_exact = 0.0_f64;
    for (k, m) in held.mode.iter().enumerate() {
        let om = 2.0 * PI * m.freq_hz;
        let lam = eig
            .iter()
            .filter(|l| l.im > 0.0)
            .min_by(|x, y| (x.im - om).abs().total_cmp(&(y.im - om).abs()))
            .expect("an eigenvalue");
        let exact = -lam.re;
        let first = sigma(m.t60_s);
        let rel = (first - exact).abs() / exact;
        println!(
            "mode {k} ({:.1} Hz): decay rate first order {first:.6e}, exact {exact:.6e} 1/s (relative {rel:.1e}); frequency shift {:.1e} relative",
            m.freq_hz,
            (lam.im - om) / om
        );
        worst_exact = worst_exact.max(rel);
    }
    assert!(
        worst_exact < 1e-6,
        "first order against the exact eigenvalues: {worst_exact:e}"
    );

    // the instrument's decay parameter and the damper scale the dashpots
    // with every other rate: every mode's T60 alike
    let mut p = InstrumentParams::default();
    p.scene.decay_scale = 2.5;
    let longer = modal_of(&scene_for(&held_scene, &p));
    let damped = modal_of(&damped_scene(&held_scene, 0.4));
    let f = 1.0 + modal_contact::instrument::DAMPER_T60_DIVISOR * 0.4;
    for ((a, b), d) in held.mode.iter().zip(&longer.mode).zip(&damped.mode) {
        assert!((b.t60_s.unwrap() / a.t60_s.unwrap() / 2.5 - 1.0).abs() < 1e-13);
        assert!((a.t60_s.unwrap() / d.t60_s.unwrap() / f - 1.0).abs() < 1e-13);
    }
}

/// Mode `k` (from 0) of a free-free Euler-Bernoulli beam at `u = x / L`,
/// `cosh + cos - s (sinh + sin)` of `beta_k x`, normalised numerically to a
/// mean square of 1 over the length (times `1 / sqrt(mass)`: the
/// mass-normalised shape).
fn free_free_shape(k: usize, u: f64) -> f64 {
    let bl = match k {
        0 => 4.730_040_745,
        1 => 7.853_204_624,
        2 => 10.995_607_838,
        3 => 14.137_165_491,
        _ => (2 * k + 3) as f64 * PI / 2.0,
    };
    let s = (bl.cosh() - bl.cos()) / (bl.sinh() - bl.sin());
    let f = |u: f64| {
        let y = bl * u;
        y.cosh() + y.cos() - s * (y.sinh() + y.sin())
    };
    let steps = 4000;
    let mean_sq = (0..steps)
        .map(|i| f((i as f64 + 0.5) / steps as f64).powi(2))
        .sum::<f64>()
        / steps as f64;
    f(u) / mean_sq.sqrt()
}

/// The eigenvalues of `x'' + C x' + K x = 0` for the modes of `m`: `K =
/// diag(omega^2)`, `C = diag(2 rates) + sum c w_p w_p^T` over the
/// dashpots `(row, c)` (`w_p` the modes' weights in that row), in the
/// balanced state `(omega x, x')`, whose matrix's norm is the highest
/// `omega` rather than its square, so the eigenvalues come out to rounding
/// of `omega`.
fn exact_eigenvalues(
    m: &modal_contact::scene::ModalSpec,
    rates: &[f64],
    dashpots: &[(usize, f64)],
) -> Vec<nalgebra::Complex<f64>> {
    let n = m.mode.len();
    let mut a = nalgebra::DMatrix::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        let om = 2.0 * PI * m.mode[i].freq_hz;
        a[(i, n + i)] = om;
        a[(n + i, i)] = -om;
        a[(n + i, n + i)] = -2.0 * rates[i];
        for j in 0..n {
            for &(row, c) in dashpots {
                a[(n + i, n + j)] -= c * m.mode[i].weights[row] * m.mode[j].weights[row];
            }
        }
    }
    a.complex_eigenvalues().iter().copied().collect()
}

/// A steel tube's ovalling modes (docs/design.md, "Objects from geometry
/// and material"): Rayleigh's inextensional ring modes written out here,
/// `omega_n^2 = E_h h^2 n^2 (n^2 - 1)^2 / (12 rho (1 - nu^2) R^4 (n^2 +
/// 1))` with the hoop modulus `E_h` the scene gives (not the material's
/// `E`), each `n` a `cos` and a `sin` partner of mass `rho h R L pi (1 + 1 /
/// n^2)`; a point `[x, y]` weighs the motion across the axis at `phi =
/// asin(y / (D / 2))`: `w cos phi - v sin phi`.
#[test]
fn tube_ovalling_modes_are_rayleighs_ring() {
    let (l, d_out, d_in, rho, e, e_h, nu) = (0.5, 0.1, 0.096, 7850.0, 2.0e11, 1.5e11, 0.3);
    let scene = parse(&format!(
        r#"name = "o"
kind = "tube"
material = {{ name = "steel", density_kg_per_m3 = {rho}, youngs_modulus_pa = {e}, poisson_ratio = {nu} }}
length_m = {l}
outer_diameter_m = {d_out}
inner_diameter_m = {d_in}
timoshenko = false
ovalling = true
hoop_modulus_pa = {e_h}
max_freq_hz = 5000.0
points = {{ contact = [0.1, 0.0], pickup = [0.3, 0.02] }}"#
    ));
    let got = modal_of(&scene);
    let (h, r) = ((d_out - d_in) / 2.0, (d_out + d_in) / 4.0);
    let phi = (0.02f64 / (d_out / 2.0)).asin();
    let mut rings = 0;
    let mut worst = 0.0f64;
    for n in 2..10 {
        let nf = n as f64;
        let w2 = e_h * h * h * nf * nf * (nf * nf - 1.0).powi(2)
            / (12.0 * rho * (1.0 - nu * nu) * r.powi(4) * (nf * nf + 1.0));
        let f = w2.sqrt() / (2.0 * PI);
        let found: Vec<_> = got
            .mode
            .iter()
            .filter(|m| (m.freq_hz / f - 1.0).abs() < 1e-9)
            .collect();
        if f > 5000.0 {
            assert!(found.is_empty());
            continue;
        }
        assert_eq!(found.len(), 2, "n = {n}: cos and sin at {f} Hz");
        let scale = 1.0 / (rho * h * r * l * PI * (1.0 + 1.0 / (nf * nf))).sqrt();
        let (s, c) = phi.sin_cos();
        let (sn, cn) = (nf * phi).sin_cos();
        let want = [
            [scale, scale * (cn * c + sn / nf * s)],
            [0.0, scale * (sn * c - cn / nf * s)],
        ];
        for (m, w) in found.iter().zip(want) {
            worst = worst.max((m.freq_hz / f - 1.0).abs());
            for (g, x) in m.weights.iter().zip(w) {
                assert!((g - x).abs() <= 1e-12 * scale, "n = {n}: {g} vs {x}");
            }
        }
        rings += 2;
    }
    println!("ovalling: {rings} ring modes to 5 kHz, worst relative frequency error {worst:.1e}");
    assert_eq!(rings, 8);
    // the modulus round the wall is the scene's, not the material's
    assert!(got.mode.iter().all(|m| {
        let w2 = e * h * h * 36.0 / (12.0 * rho * (1.0 - nu * nu) * r.powi(4) * 5.0);
        (m.freq_hz / (w2.sqrt() / (2.0 * PI)) - 1.0).abs() > 1e-3
    }));
    // Refused, each naming its field.
    let tube = |extra: &str| {
        format!(
            "name = \"o\"\nkind = \"tube\"\nmaterial = \"steel\"\nlength_m = 0.5\n\
             outer_diameter_m = 0.1\ninner_diameter_m = 0.096\n{extra}\n\
             points = {{ contact = 0.1, pickup = 0.3 }}"
        )
    };
    let e1 = err(&tube("hoop_modulus_pa = 1e9"));
    assert!(
        e1.contains("object[0].hoop_modulus_pa") && e1.contains("ovalling = true"),
        "{e1}"
    );
    let e2 = err(&tube("ovalling = true\nhoop_modulus_pa = -1.0"));
    assert!(e2.contains("object[0].hoop_modulus_pa"), "{e2}");
    let e3 = err(&tube("ovalling = true\nsupport = \"clamped-clamped\""));
    assert!(
        e3.contains("object[0].ovalling") && e3.contains("free ends"),
        "{e3}"
    );
    let e4 =
        err(&tube("ovalling = true").replace("inner_diameter_m = 0.096", "inner_diameter_m = 0.0"));
    assert!(e4.contains("object[0].ovalling"), "{e4}");
    // heard as radiated pressure, or damped by its radiation: not modelled
    let e5 = err(&format!(
        "{}\n\n[[listener]]\nname = \"front\"\ndistance_m = 1.0\npolar_deg = 0.0\n\
         azimuth_deg = 0.0\n\n[[pickup]]\nobject = \"o\"\npoint = \"front\"\nquantity = \"pressure\"",
        tube("ovalling = true")
    ));
    assert!(e5.contains("ovalling"), "{e5}");
    let e6 = err(&tube("ovalling = true\nloss = { radiation_damping = 1.0 }"));
    assert!(e6.contains("ovalling"), "{e6}");
    println!(
        "refused: {e1}\n         {e2}\n         {e3}\n         {e4}\n         {e5}\n         {e6}"
    );
}
