//! The stability cases (docs/numerics.md, "The stability cases"): scenes
//! at the edges of what the engine claims, each run through both switching
//! modes. One table, [`cases`], that the report's stability section, its
//! golden renders (`cargo xtask golden`) and `tests/stability.rs` all
//! iterate over, and the scene families it is built from, which the tests'
//! own variants use too.
//!
//! Each case has a descriptive name and keeps its old label (`X3 ...`, the
//! numbering of the numerics notes) as a secondary one: the golden hashes
//! are recorded under it.

use crate::scenes::{c_for, k_for, wall_strike, ModalStrike, NYQ, RATE};
use modal_contact::scene::Scene;

/// One case of the catalogue.
#[derive(Debug, Clone)]
pub struct Case {
    /// What the case is about, e.g. "contact at 100x Nyquist".
    pub name: String,
    /// The case's label in the numerics notes, e.g. `X3 f_c = 100x f_Nyq`
    /// (the key of its golden renders).
    pub label: String,
    /// The scene's parameters in a sentence.
    pub description: String,
    /// Length of a run [samples at [`RATE`]].
    pub samples: usize,
    /// The scene the case runs.
    pub scene: Scene,
}

impl Case {
    fn new(name: String, label: String, description: &str, samples: usize, scene: Scene) -> Case {
        Case {
            name,
            label,
            description: description.to_string(),
            samples,
            scene,
        }
    }
}

/// X3: contact frequency `ratio` times Nyquist on 20 modes (200 Hz .. 0.82
/// f_Nyq), a 20 g hammer at 1 m/s, zeta_c = 0.2.
pub fn contact_at(ratio: f64) -> ModalStrike {
    let m_h = 0.02;
    let k = k_for(m_h, ratio * NYQ);
    ModalStrike::new(20, 200.0, 0.82 * NYQ)
        .damped()
        .hammer(m_h)
        .contact(k, c_for(m_h, k, 0.2))
}

/// X2 (and X6 when not `damped`: every damping 0, modes and contact): a
/// 0.2 kg hammer at 1 m/s, contact at 0.45 f_Nyq, zeta_c 0.3, on 20 modes
/// (200 Hz .. 0.82 f_Nyq); the hammer chatters.
pub fn stiff_chattering(damped: bool) -> ModalStrike {
    let m_h = 0.2;
    let k = k_for(m_h, 0.45 * NYQ);
    let s = ModalStrike::new(20, 200.0, 0.82 * NYQ).hammer(m_h);
    if damped {
        s.damped().contact(k, c_for(m_h, k, 0.3))
    } else {
        s.contact(k, 0.0)
    }
}

/// X4: a 10 g hammer against a rigid wall at 1 m/s, k = 1e6 N/m, zeta_c = 1
/// exactly (the contact block is defective: a Jordan block).
pub fn critical_wall() -> Scene {
    let (m, k) = (0.01, 1e6);
    wall_strike(m, k, c_for(m, k, 1.0), 0.0, -1.0)
}

/// X4 on an object: one undamped 300 Hz mode, a 10 g hammer, k = 1e6 N/m,
/// zeta_c = 1 (the coupling splits the critical pair).
pub fn critical_one_mode() -> ModalStrike {
    let (m, k) = (0.01, 1e6);
    ModalStrike::new(1, 300.0, 300.0)
        .hammer(m)
        .contact(k, c_for(m, k, 1.0))
}

/// X5: an overdamped contact (`zeta` > 1) on 10 modes 200 Hz .. 5 kHz, a
/// 20 g hammer, k = 1e6 N/m.
pub fn overdamped(zeta: f64) -> ModalStrike {
    let (m, k) = (0.02, 1e6);
    ModalStrike::new(10, 200.0, 5000.0)
        .damped()
        .hammer(m)
        .contact(k, c_for(m, k, zeta))
}

/// X8: 40 modes from 150 Hz to 2.7 f_Nyq, a 20 g hammer, k = 1e6 N/m, c =
/// 5 N s/m.
pub fn modes_above_nyquist() -> ModalStrike {
    ModalStrike::new(40, 150.0, 2.7 * NYQ)
        .damped()
        .contact(1e6, 5.0)
}

/// X7: a hammer of `ratio` times mode 0's effective mass (1 kg) on 10
/// modes 200 Hz .. 8 kHz, the contact frequency kept at 2 kHz, zeta_c 0.1.
pub fn mass_ratio(ratio: f64) -> ModalStrike {
    let k = k_for(ratio, 2000.0);
    ModalStrike::new(10, 200.0, 8000.0)
        .damped()
        .hammer(ratio)
        .contact(k, c_for(ratio, k, 0.1))
}

/// X9: `n` modes from 100 Hz to 18 kHz, a 30 g hammer, k = 1e6 N/m, c = 10
/// N s/m.
pub fn many_modes(n: usize) -> ModalStrike {
    ModalStrike::new(n, 100.0, 18_000.0)
        .damped()
        .hammer(0.03)
        .contact(1e6, 10.0)
}

/// X11: a 10 g hammer grazing 5 modes (300 Hz .. 5 kHz) at `speed` m/s
/// from 1e-12 m, k = 1e6 N/m, c = 5 N s/m.
pub fn grazing(speed: f64) -> ModalStrike {
    ModalStrike::new(5, 300.0, 5000.0)
        .damped()
        .hammer(0.01)
        .contact(1e6, 5.0)
        .start(1e-12, -speed)
}

/// X12/X13: a 50 g ball dropped from 1 cm (g = 9.81) on 3 modes 220 ..
/// 3500 Hz, k = 2e5 N/m, c = 5 N s/m: it bounces, then rests in
/// continuous contact for good.
pub fn settling() -> ModalStrike {
    ModalStrike::new(3, 220.0, 3500.0)
        .damped()
        .hammer(0.05)
        .contact(2e5, 5.0)
        .dropped(9.81)
}

/// The catalogue, in the report's order.
pub fn cases() -> Vec<Case> {
    let mut v = Vec::new();
    push_stiffness_cases(&mut v);
    push_damping_cases(&mut v);
    push_size_cases(&mut v);
    push_grazing_and_resting_cases(&mut v);
    v
}

/// X3, X2, X6: the contact's stiffness against the sample rate, and a
/// chattering contact with and without damping.
fn push_stiffness_cases(v: &mut Vec<Case>) {
    let modal = |label: &str, s: ModalStrike| s.scene(label);
    for ratio in [1.0, 10.0, 100.0, 1000.0] {
        let label = format!("X3 f_c = {ratio}x f_Nyq");
        v.push(Case::new(
            format!("contact at {ratio}x Nyquist"),
            label.clone(),
            "20 modes 200 Hz..0.82 f_Nyq, m_h 0.02 kg, zeta_c 0.2, v0 1 m/s",
            20_000,
            modal(&label, contact_at(ratio)),
        ));
    }
    v.push(Case::new(
        "stiff chattering contact".into(),
        "X2 stiff, chattering".into(),
        "f_c = 0.45 f_Nyq, zeta_c 0.3, m_h/m_k 0.2, 20 modes to 0.82 f_Nyq",
        20_000,
        modal("X2 stiff, chattering", stiff_chattering(true)),
    ));
    v.push(Case::new(
        "stiff chattering without any damping".into(),
        "X6 zero damping".into(),
        "X2 with every damping 0 (modes and contact): energy must stay E0",
        20_000,
        modal("X6 zero damping", stiff_chattering(false)),
    ));
}

/// X4, X5: critically damped and overdamped contacts.
fn push_damping_cases(v: &mut Vec<Case>) {
    let modal = |label: &str, s: ModalStrike| s.scene(label);
    v.push(Case::new(
        "critical damping against a wall".into(),
        "X4 critical damping, wall".into(),
        "hammer vs rigid wall, zeta_c = 1 exactly (defective contact block)",
        5000,
        critical_wall(),
    ));
    v.push(Case::new(
        "critical damping on one mode".into(),
        "X4 critical damping, 1 mode".into(),
        "one undamped 300 Hz mode, 10 g hammer, k 1e6, zeta_c = 1",
        20_000,
        modal("X4 critical damping, 1 mode", critical_one_mode()),
    ));
    for zeta in [10.0, 1e3] {
        let label = format!("X5 overdamped zeta = {zeta}");
        let (what, samples) = if zeta > 100.0 {
            ("10 modes 200 Hz..5 kHz, m_h 0.02 kg, k 1e6 (shortened to 4410 samples when the exact engine cost ~0.8 ms per sample here; its cost now: the `tick` time that follows)", 4410)
        } else {
            ("10 modes 200 Hz..5 kHz, m_h 0.02 kg, k 1e6", 20_000)
        };
        v.push(Case::new(
            format!("overdamped contact, zeta {zeta}"),
            label.clone(),
            what,
            samples,
            modal(&label, overdamped(zeta)),
        ));
    }
}

/// X8, X7, X9: modes above Nyquist, the hammer's mass against the
/// object's, and the number of modes.
fn push_size_cases(v: &mut Vec<Case>) {
    let modal = |label: &str, s: ModalStrike| s.scene(label);
    v.push(Case::new(
        "modes up to 2.7x Nyquist".into(),
        "X8 modes above Nyquist".into(),
        "40 modes 150 Hz..2.7 f_Nyq, m_h 0.02 kg, k 1e6, c 5",
        20_000,
        modal("X8 modes above Nyquist", modes_above_nyquist()),
    ));
    for ratio in [1e-6, 1e-3, 1.0, 1e3] {
        let label = format!("X7 m_h/m_k = {ratio:e}");
        let (what, samples) = if ratio > 100.0 {
            ("10 modes 200 Hz..8 kHz (mode 0: 1 kg), f_c 2 kHz, zeta_c 0.1 (shortened to 2000 samples when the exact engine cost ~7 ms per sample here; its cost now: the `tick` time that follows)", 2000)
        } else {
            (
                "10 modes 200 Hz..8 kHz (mode 0: 1 kg), f_c 2 kHz, zeta_c 0.1",
                20_000,
            )
        };
        v.push(Case::new(
            format!("hammer {ratio:e} x the object's mass"),
            label.clone(),
            what,
            samples,
            modal(&label, mass_ratio(ratio)),
        ));
    }
    for n in [1usize, 10, 100, 300] {
        let label = format!("X9 {n} modes");
        v.push(Case::new(
            if n == 1 {
                "one mode".to_string()
            } else {
                format!("{n} modes")
            },
            label.clone(),
            "modes 100 Hz..18 kHz, m_h 0.03 kg, k 1e6, c 10 (capped at 300 modes: at 1000 the dense trapezoid competitor would dominate the runtime)",
            if n >= 300 { 4410 } else { 10_000 },
            modal(&label, many_modes(n)),
        ));
    }
}

/// X11, X12/X13: a grazing impact, and a ball settling into continuous
/// contact.
fn push_grazing_and_resting_cases(v: &mut Vec<Case>) {
    let modal = |label: &str, s: ModalStrike| s.scene(label);
    v.push(Case::new(
        "grazing impact at 1e-9 m/s".into(),
        "X11 grazing v = 1e-9".into(),
        "5 modes 300 Hz..5 kHz, impact speed 1e-9 m/s from 1e-12 m",
        20_000,
        modal("X11 grazing v = 1e-9", grazing(1e-9)),
    ));
    v.push(Case::new(
        "ball settling into continuous contact".into(),
        "X12/X13 long contact".into(),
        "50 g ball dropped from 1 cm (g = 9.81) on 3 modes 220..3500 Hz, k 2e5, c 5: bounces, then rests in continuous contact (3 s)",
        (3.0 * RATE) as usize,
        modal("X12/X13 long contact", settling()),
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_labels_are_unique() {
        let c = cases();
        for (i, a) in c.iter().enumerate() {
            for b in &c[..i] {
                assert_ne!(a.name, b.name);
                assert_ne!(a.label, b.label);
            }
        }
        assert_eq!(c.len(), 21);
    }
}
