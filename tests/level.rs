//! A scene's `level_db` (docs/design.md, "Scene files"): a gain on every
//! pickup, so a scene at -6.02 dB (a gain of one half) sounds exactly half
//! as loud, sample for sample, on the one-contact engine, on the
//! several-contact engine and through the instrument; out of range it is
//! refused naming the field.

use modal_contact::instrument::{
    prepare_scene, root_note, Event, Instrument, InstrumentParams, TimedEvent,
};
use modal_contact::scene::Scene;
use modal_contact::Compiled;
use modal_testkit::scenes::preset;

const RATE: f64 = 48_000.0;

/// The level of a gain of one half \[dB\].
fn half_db() -> f64 {
    20.0 * 0.5f64.log10()
}

fn at_level(name: &str, level_db: f64) -> Scene {
    let mut s = preset(name);
    s.level_db = level_db;
    s.validate().unwrap();
    s
}

/// Both channels of the scene as written, on the engine that runs it.
fn engine_output(s: &Scene, n: usize) -> Vec<f64> {
    let r = Compiled::new(s, RATE, None).unwrap().render(n, false);
    r.left.into_iter().chain(r.right).collect()
}

/// Both channels of one note at the scene's root through the instrument.
fn instrument_output(s: &Scene, n: usize) -> Vec<f64> {
    let params = InstrumentParams::default();
    let p = prepare_scene(s, &params.scene, RATE, 0).unwrap();
    let mut inst = Instrument::new(p, params.play);
    let (mut l, mut r) = (vec![0.0f32; n], vec![0.0f32; n]);
    let on = TimedEvent {
        offset: 0,
        event: Event::NoteOn {
            key: root_note(s) as u8,
            velocity_norm: 100.0 / 127.0,
        },
    };
    inst.process(&[on], &mut l, &mut r);
    l.iter().chain(&r).map(|&x| f64::from(x)).collect()
}

/// `b / a` is `ratio` within `tol` of `a`'s peak; `a` is not silent.
fn assert_scaled(what: &str, a: &[f64], b: &[f64], ratio: f64, tol: f64) {
    assert_eq!(a.len(), b.len());
    let peak = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(peak > 1e-6, "{what}: silent (peak {peak:e})");
    let worst = a
        .iter()
        .zip(b)
        .map(|(x, y)| (y - ratio * x).abs())
        .fold(0.0f64, f64::max);
    println!("{what}: peak {peak:.3e}, |b - {ratio} a| <= {worst:.2e}");
    assert!(
        worst <= tol * peak,
        "{what}: {worst:e} of peak {peak:e} off the ratio {ratio}"
    );
}

#[test]
fn level_db_scales_the_output_exactly() {
    let g = 10f64.powf(half_db() / 20.0);
    assert!((g - 0.5).abs() <= 2.0 * f64::EPSILON, "{g}");
    let n = (0.5 * RATE) as usize;
    // one contact (a bar from geometry), one contact with a modal mallet,
    // several contacts (a kit with touches), each on its engine
    for name in ["marimba-bar", "marimba-rubber-mallet", "snare-pair"] {
        let a = engine_output(&at_level(name, 0.0), n);
        let b = engine_output(&at_level(name, half_db()), n);
        assert_scaled(&format!("{name}, engine"), &a, &b, 0.5, 1e-13);
        // +20 dB: ten times
        let c = engine_output(&at_level(name, 20.0), n);
        assert_scaled(&format!("{name}, engine, +20 dB"), &a, &c, 10.0, 1e-12);
    }
    // through the instrument (f32 output): a pitched scene and a kit
    for name in ["marimba-bar", "marimba-two-mallets"] {
        let a = instrument_output(&at_level(name, 0.0), n);
        let b = instrument_output(&at_level(name, half_db()), n);
        assert_scaled(&format!("{name}, instrument"), &a, &b, 0.5, 1e-6);
    }
}

#[test]
fn a_bad_level_db_is_refused_naming_the_field() {
    for bad in [f64::NAN, f64::INFINITY, 40.5, -60.5, 1e300] {
        let mut s = preset("marimba-bar");
        s.level_db = bad;
        let e = s.validate().unwrap_err();
        assert_eq!(e.path, "level_db", "{bad}: {e}");
        // and in a file, with the message naming the field
        let text = format!("level_db = {bad:?}\n{}", preset_text("marimba-bar"));
        let text = text.replace("level_db = NaN", "level_db = nan");
        let e = Scene::from_toml_str(&text).unwrap_err().to_string();
        assert!(e.starts_with("level_db: "), "{bad}: {e}");
    }
    for ok in [-60.0, -12.5, 0.0, 40.0] {
        let mut s = preset("marimba-bar");
        s.level_db = ok;
        s.validate().unwrap();
    }
}

/// A preset's text without its own `level_db` line, if any.
fn preset_text(name: &str) -> String {
    std::fs::read_to_string(modal_testkit::scenes::preset_path(name))
        .unwrap()
        .lines()
        .filter(|l| !l.trim_start().starts_with("level_db"))
        .map(|l| format!("{l}\n"))
        .collect()
}
