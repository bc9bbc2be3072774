//! Scene files: bad input gives the documented error (naming the field), and
//! the compiled contact propagator agrees with an independent dense exp(A h).

use modal_contact::compile::compile_one;
use modal_contact::physics::block::exp2;
use modal_contact::physics::model::{contact_system, ContactParams, ObjectModel};
use modal_contact::scene::Scene;
use modal_testkit::scenes::{preset, preset_path};
use nalgebra::DMatrix;

const GOOD: &str = r#"
version = 1
name = "t"
[[object]]
name = "plate"
kind = "modal"
points = ["contact", "pickup"]
[[object.mode]]
freq_hz = 220.0
t60_s = 0.8
weights = [2.0, 1.0]
[hammer]
mass_kg = 0.01
height_m = 0.02
gravity_m_per_s2 = 9.81
[contact]
object = "plate"
point = "contact"
stiffness_n_per_m = 2e5
damping_n_s_per_m = 2.0
[[pickup]]
object = "plate"
point = "pickup"
"#;

fn err_of(text: &str) -> String {
    match Scene::from_toml_str(text) {
        Ok(_) => panic!("accepted a bad scene:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn good_scene_parses() {
    Scene::from_toml_str(GOOD).unwrap();
}

#[test]
fn bad_scenes_give_errors_that_name_the_field() {
    let cases: &[(&str, &str, &str)] = &[
        (
            "mass_kg = 0.01",
            "mass_kg = -0.01",
            "hammer.mass_kg: must be > 0, got -0.01",
        ),
        (
            "t60_s = 0.8",
            "t60_s = -1.0",
            "object[0].mode[0].t60_s: must be > 0, got -1",
        ),
        (
            "freq_hz = 220.0",
            "freq_hz = nan",
            "object[0].mode[0].freq_hz: must be finite, got NaN",
        ),
        (
            "weights = [2.0, 1.0]",
            "weights = [2.0, inf]",
            "object[0].mode[0].weights[1]: must be finite, got inf",
        ),
        (
            "weights = [2.0, 1.0]",
            "weights = [2.0]",
            "object[0].mode[0].weights: needs one weight per point (2), got 1",
        ),
        (
            "stiffness_n_per_m = 2e5",
            "stiffness_n_per_m = 0.0",
            "contact.stiffness_n_per_m: must be > 0, got 0",
        ),
        (
            "point = \"pickup\"",
            "point = \"nowhere\"",
            "pickup[0].point: object \"plate\" has no point \"nowhere\"",
        ),
        (
            "object = \"plate\"\npoint = \"contact\"",
            "object = \"bowl\"\npoint = \"contact\"",
            "contact.object: no object named \"bowl\"",
        ),
        (
            "height_m = 0.02",
            "height_m = 0.02\ncolour = \"red\"",
            "unknown field `colour`",
        ),
        ("version = 1", "version = 2", "version: must be 1, got 2"),
    ];
    for (from, to, want) in cases {
        assert!(GOOD.contains(from), "test case does not apply: {from}");
        let text = GOOD.replacen(from, to, 1);
        let got = err_of(&text);
        println!("{to:?} -> {got}");
        assert!(got.contains(want), "for {to:?}: got {got:?}, want {want:?}");
    }
}

#[test]
fn zero_modes_is_an_error() {
    let text = r#"
version = 1
name = "t"
[[object]]
name = "plate"
kind = "modal"
points = ["contact"]
[hammer]
mass_kg = 0.01
height_m = 0.02
[contact]
object = "plate"
point = "contact"
stiffness_n_per_m = 2e5
"#;
    let got = err_of(text);
    assert_eq!(
        got,
        "object[0].mode: a modal object needs at least one mode"
    );
}

#[test]
fn string_with_bad_point_index_is_an_error() {
    let text = std::fs::read_to_string(preset_path("paper-string")).unwrap();
    let text = text.replace("pickup = 40", "pickup = 50");
    let got = err_of(&text);
    assert_eq!(
        got,
        "object[0].points.pickup: must be < masses (50), got 50"
    );
    let text2 = std::fs::read_to_string(preset_path("paper-string"))
        .unwrap()
        .replace("mass_kg = 1e-4", "mass_kg = -1e-4");
    assert_eq!(
        err_of(&text2),
        "object[0].mass_kg: must be > 0, got -0.0001"
    );
}

#[test]
fn syntax_errors_are_reported_not_panicked() {
    for text in [
        "",
        "version = ",
        "[[object]\n",
        "\u{0}\u{1}garbage",
        "version = 1\nname = 3",
    ] {
        let e = Scene::from_toml_str(text).unwrap_err();
        println!("{text:?} -> {e}");
        assert!(!e.reason.trim().starts_with("(line"), "no message: {e}");
        assert!(e.reason.len() > 10);
    }
}

/// Independent check of the compiled contact propagator: rebuild the contact
/// generator from the model, exponentiate it with nalgebra's Pade `exp`, and
/// compare with `V blockdiag(exp(G_k h)) V^-1` built from the compiled scene.
#[test]
fn compiled_contact_propagator_matches_dense_expm() {
    for name in [
        "paper-bounce",
        "paper-string",
        "marimba-bar",
        "steel-plate",
        "bell",
    ] {
        let rate = 44100.0;
        // physical objects as the modes the compiler computes at this rate
        let sc = preset(name).expanded(rate).unwrap();
        let compiled = compile_one(&sc, rate).unwrap();
        let obj_idx = sc.object_index(&sc.contact.object).unwrap();
        let obj = ObjectModel::from_spec(&sc.object[obj_idx]).unwrap();
        let vel = obj
            .point(sc.contact.point.as_deref().unwrap())
            .unwrap()
            .vel
            .clone();
        let (a, _f, _lay) = contact_system(
            &obj,
            Some(&vel),
            &ContactParams {
                k: sc.contact.stiffness_n_per_m,
                c: sc.contact.damping_n_s_per_m,
                m_h: sc.hammer.mass_kg,
                g: sc.hammer.gravity_m_per_s2,
            },
        );
        let dense = (&a / rate).exp();
        let ph = &compiled.contact;
        let gens = ph.gens.as_ref().expect("presets use the eigen blocks");
        let dim = ph.dim;
        let mut p = DMatrix::zeros(dim, dim);
        for (k, g) in gens.iter().enumerate() {
            let e = exp2(g, 1.0 / rate);
            // block k acts on (s[k], s[nb + k]) (structure of arrays)
            let nb = gens.len();
            p[(k, k)] = e[0];
            p[(k, nb + k)] = e[1];
            p[(nb + k, k)] = e[2];
            p[(nb + k, nb + k)] = e[3];
        }
        let vinv = ph.v.clone().try_inverse().unwrap();
        let ours = &ph.v * p * vinv;
        let err = (&ours - &dense).norm() / dense.norm();
        println!(
            "{name}: dim {dim}, |V exp(G h) V^-1 - expm(A h)| / |expm| = {err:.2e}, kappa {:.2}",
            ph.diag.kappa
        );
        assert!(err < 1e-10, "{name}: {err:e}");
    }
}
