//! A driven scene played by the instrument (docs/design.md, "Rolling and
//! scraping"): a note starts the stroke (its velocity the speed along
//! the path), a harder note strokes faster, the mod wheel speeds a held
//! stroke up and so does its note's slide (MPE's brightness), pressure
//! presses it harder, note-off stops the surface, and the voice ends once it is
//! silent.

use modal_contact::instrument::{
    drive_speed_m_per_s, impact_speed_m_per_s, prepare_scene, slide_speed_factor,
    wheel_speed_factor, Event, Instrument, PlayParams, SceneParams, TimedEvent, WHEEL_SPEED_RANGE,
};
use modal_contact::scene::{Beyond, DriveSpec, Scene, SurfaceSpec};
use modal_contact::{compile_one, EngineState};
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder};

const RATE: f64 = 44_100.0;

/// A scraper pressed by 5 N onto ridges 3 mm apart cut into a bar of
/// three modes, drawn at 0.2 m/s at velocity 100: a pulse every 15 ms.
fn scraped_bar() -> Scene {
    let bar = Modal::new("bar", &["c", "p"])
        .mode(300.0, Some(1.2), &[0.9, 0.5])
        .mode(1100.0, Some(0.6), &[-0.6, 0.7])
        .mode(2700.0, Some(0.3), &[0.4, -0.3]);
    let mut scene = SceneBuilder::new("scraped-bar")
        .duration(1.0)
        .object(bar)
        .hammer(Hammer::new(0.01).height(0.0))
        .contact(Contact::new("bar", 2.0e5).point("c").damping(2.0))
        .pickup(Pickup::new("bar", "p"))
        .build();
    scene.drive = Some(DriveSpec {
        speed_m_per_s: 0.2,
        start_m: 0.0,
        radius_m: 0.0,
        press_n: 5.0,
        beyond: Beyond::Wrap,
        surface: SurfaceSpec::Ridges {
            length_m: 0.15,
            spacing_m: 3e-3,
            depth_m: 1e-4,
            rise: 0.9,
        },
    });
    scene
}

/// `seconds` of the instrument (no gain, no lookahead) after a note at
/// `velocity` on the scene's root key, released after `hold` seconds
/// (never if `None`); the left channel and the instrument.
fn play(velocity: f64, hold: Option<f64>, seconds: f64) -> (Vec<f32>, Instrument) {
    play_with(velocity, hold, seconds, &[])
}

/// [`play`] with `more` events after the note-on (and before the
/// note-off).
fn play_with(
    velocity: f64,
    hold: Option<f64>,
    seconds: f64,
    more: &[TimedEvent],
) -> (Vec<f32>, Instrument) {
    let scene = scraped_bar();
    let p = prepare_scene(&scene, &SceneParams::default(), RATE, 0).unwrap();
    let play = PlayParams {
        gain_db: 0.0,
        lookahead_s: 0.0,
        ..PlayParams::default()
    };
    let mut inst = Instrument::new(p, play);
    inst.set_lookahead(0);
    let key = modal_contact::instrument::root_note(&scene).round() as u8;
    let n = (seconds * RATE) as usize;
    let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
    let mut events = vec![TimedEvent {
        offset: 0,
        event: Event::NoteOn {
            key,
            velocity_norm: velocity,
        },
    }];
    events.extend_from_slice(more);
    if let Some(h) = hold {
        events.push(TimedEvent {
            offset: (h * RATE) as usize,
            event: Event::NoteOff { key },
        });
    }
    inst.process(&events, &mut l, &mut r);
    (l, inst)
}

/// RMS of `x`.
fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>() / x.len() as f64).sqrt()
}

/// A held note on the root key is the scene driven offline with the
/// scraper put on the surface at rest and the speed of the note's
/// velocity (velocity 100: the scene's 0.2 m/s), to the output's f32
/// rounding; a harder note scrapes faster and louder.
#[test]
fn a_note_is_the_scene_driven_at_its_velocitys_speed() {
    let scene = scraped_bar();
    let sc = compile_one(&scene, RATE).unwrap();
    let n = (0.5 * RATE) as usize;
    let mut levels = Vec::new();
    for velocity in [64.0 / 127.0, 100.0 / 127.0, 1.0] {
        let (out, inst) = play(velocity, None, 0.5);
        let speed = drive_speed_m_per_s(0.2, impact_speed_m_per_s(velocity));
        let mut st = EngineState::new(&sc);
        st.strike(&sc, 0.0, 0.0);
        st.set_drive_speed(&sc, speed);
        let (mut worst, mut peak) = (0.0f64, 0.0f64);
        for &o in &out[..n] {
            let y = st.tick(&sc)[0];
            peak = peak.max(y.abs());
            worst = worst.max((f64::from(o) - y).abs());
        }
        println!(
            "velocity {:.0}: speed {speed:.3} m/s, instrument vs offline {worst:.1e} of peak \
             {peak:.1e}, {} contacts",
            velocity * 127.0,
            st.contacts_started
        );
        assert!(peak > 1e-5 && worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
        assert_eq!(inst.active_voices(), 1);
        levels.push(rms(&out));
    }
    assert!(levels[0] < levels[1] && levels[1] < levels[2], "{levels:?}");
}

/// Released, the surface stops: the scraping ends, the bar rings out and
/// the voice stops when silent; held, it scrapes on.
#[test]
fn note_off_stops_the_stroke_and_the_voice_ends() {
    let (held, _) = play(100.0 / 127.0, None, 3.0);
    let (released, inst) = play(100.0 / 127.0, Some(0.3), 3.0);
    let late = |x: &[f32]| rms(&x[(2.0 * RATE) as usize..]);
    println!(
        "after 2 s: held {:.2e}, released at 0.3 s {:.2e}; silent stops {}",
        late(&held),
        late(&released),
        inst.stats.silent_stops
    );
    assert!(late(&held) > 0.3 * rms(&held));
    assert!(late(&released) < 1e-4 * late(&held));
    assert_eq!(inst.stats.silent_stops, 1);
    assert_eq!(inst.active_voices(), 0);
}

/// The mod wheel multiplies a held stroke's speed where the wheel moves
/// (`4^wheel`): the instrument is the scene driven offline at the note's
/// speed, then at the wheel's, to the output's f32 rounding; the faster
/// stroke passes more ridges and is louder; the wheel at rest again
/// brings the note's own speed back, and a wheel that is not a number
/// counts as at rest.
#[test]
fn the_mod_wheel_speeds_a_held_stroke_up() {
    assert_eq!(wheel_speed_factor(0.0), 1.0);
    assert_eq!(wheel_speed_factor(1.0), WHEEL_SPEED_RANGE);
    assert_eq!(wheel_speed_factor(f64::NAN), 1.0);
    assert!((wheel_speed_factor(0.5) - 2.0).abs() < 1e-15);
    let scene = scraped_bar();
    let sc = compile_one(&scene, RATE).unwrap();
    let velocity = 100.0 / 127.0;
    let (up, down) = ((0.2 * RATE) as usize, (0.4 * RATE) as usize);
    let n = (0.6 * RATE) as usize;
    let wheel = |offset, value| TimedEvent {
        offset,
        event: Event::ModWheel { value },
    };
    let (out, inst) = play_with(
        velocity,
        None,
        0.6,
        &[wheel(up, 0.75), wheel(down, f64::NAN)],
    );
    let speed = drive_speed_m_per_s(0.2, impact_speed_m_per_s(velocity));
    let mut st = EngineState::new(&sc);
    st.strike(&sc, 0.0, 0.0);
    st.set_drive_speed(&sc, speed);
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    let mut path = [0.0; 3];
    for (k, &o) in out[..n].iter().enumerate() {
        if k == up {
            path[0] = st.surface_at(&sc).unwrap().path_m;
            st.set_drive_speed(&sc, speed * 4f64.powf(0.75));
        }
        if k == down {
            path[1] = st.surface_at(&sc).unwrap().path_m;
            st.set_drive_speed(&sc, speed);
        }
        let y = st.tick(&sc)[0];
        peak = peak.max(y.abs());
        worst = worst.max((f64::from(o) - y).abs());
    }
    path[2] = st.surface_at(&sc).unwrap().path_m;
    let level = |a: usize, b: usize| rms(&out[a..b]);
    let (before, during, after) = (level(0, up), level(up, down), level(down, n));
    println!(
        "path {:.4} / {:.4} / {:.4} m (0.2 s each), rms {before:.2e} / {during:.2e} / \
         {after:.2e}; instrument vs offline {worst:.1e} of peak {peak:.1e}",
        path[0],
        path[1] - path[0],
        path[2] - path[1]
    );
    assert!(peak > 1e-5 && worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
    let ratio = (path[1] - path[0]) / path[0];
    assert!((ratio - 4f64.powf(0.75)).abs() < 1e-6, "{ratio}");
    assert!(((path[2] - path[1]) / path[0] - 1.0).abs() < 1e-6);
    assert!(
        during > 1.5 * before && during > 1.5 * after,
        "{before} {during} {after}"
    );
    assert_eq!(inst.active_voices(), 1);
}

/// A note's brightness (MPE's slide) in a driven scene sets its own speed
/// (docs/design.md, "Rolling and scraping"): `WHEEL_SPEED_RANGE^(2 b -
/// 1)`. Slid to the top it plays exactly what the mod wheel at full plays
/// (bit for bit: both multiply the note's speed by 4, and the slide leaves
/// the hardness alone), back to the centre what the wheel at rest plays;
/// a slide on another key changes nothing.
#[test]
fn the_slide_sets_its_own_notes_speed() {
    assert_eq!(slide_speed_factor(0.5), 1.0);
    assert_eq!(slide_speed_factor(f64::NAN), 1.0);
    assert!((slide_speed_factor(1.0) - WHEEL_SPEED_RANGE).abs() < 1e-15);
    assert!((slide_speed_factor(0.0) - 1.0 / WHEEL_SPEED_RANGE).abs() < 1e-15);
    assert_eq!(slide_speed_factor(7.0), slide_speed_factor(1.0));
    let key = modal_contact::instrument::root_note(&scraped_bar()).round() as u8;
    let velocity = 100.0 / 127.0;
    let (up, down) = ((0.2 * RATE) as usize, (0.4 * RATE) as usize);
    let at = |offset, event| TimedEvent { offset, event };
    let slide = |k: u8, value| Event::NoteBrightness {
        key: Some(k),
        value,
    };
    let wheel = |value| Event::ModWheel { value };
    let (slid, _) = play_with(
        velocity,
        None,
        0.6,
        &[at(up, slide(key, 1.0)), at(down, slide(key, 0.5))],
    );
    let (wheeled, _) = play_with(
        velocity,
        None,
        0.6,
        &[at(up, wheel(1.0)), at(down, wheel(0.0))],
    );
    let (plain, _) = play(velocity, None, 0.6);
    let (other, _) = play_with(velocity, None, 0.6, &[at(up, slide(key + 1, 1.0))]);
    let differ = |a: &[f32], b: &[f32]| a.iter().zip(b).filter(|(x, y)| x != y).count();
    let during = |x: &[f32]| rms(&x[up..down]);
    println!(
        "slid vs wheeled: {} samples differ; slid vs plain: {} differ (rms while slid {:.2e} against {:.2e}); another key's slide: {} differ",
        differ(&slid, &wheeled),
        differ(&slid, &plain),
        during(&slid),
        during(&plain),
        differ(&other, &plain)
    );
    assert_eq!(differ(&slid, &wheeled), 0);
    assert!(differ(&slid[up..down], &plain[up..down]) > 0);
    assert!(during(&slid) > 1.5 * during(&plain));
    assert_eq!(differ(&other, &plain), 0);
}

/// Pressure presses a held stroke harder, continuously (docs/design.md,
/// "Rolling and scraping"): the hand's force times `1 + 3 p` (5 N
/// unpressed, 20 N at full pressure). The instrument is the scene driven
/// offline with its load set where the pressure moves
/// ([`EngineState::set_load`]), to the output's f32 rounding. The load is
/// checked against the scene compiled under 20 N (its own equilibrium and
/// rows, an independent route to the same physics: the offline voice
/// carried there and back, [`EngineState::rebind`]). And independently of
/// the engine, the momentum balance says the contact's mean force over a
/// window is the pressing force (the hammer's velocity is bounded):
/// measured from the motion (`k p + c p'` while in contact), it follows
/// the pressure.
#[test]
fn pressure_presses_a_held_stroke_harder() {
    use modal_contact::instrument::{press_factor, PRESS_RANGE};
    assert_eq!(press_factor(1.0), PRESS_RANGE);
    assert_eq!(press_factor(7.0), PRESS_RANGE);
    assert_eq!(press_factor(f64::NAN), 1.0);
    assert_eq!(press_factor(-1.0), 1.0);
    assert_eq!(press_factor(0.5), 2.5);
    let scene = scraped_bar();
    let mut pressed = scene.clone();
    pressed.drive.as_mut().unwrap().press_n *= 4.0;
    let (sc, sc4) = (
        compile_one(&scene, RATE).unwrap(),
        compile_one(&pressed, RATE).unwrap(),
    );
    let velocity = 100.0 / 127.0;
    let key = modal_contact::instrument::root_note(&scene).round() as u8;
    let (up, down) = ((0.3 * RATE) as usize, (0.6 * RATE) as usize);
    let n = (0.9 * RATE) as usize;
    let press = |offset, value| TimedEvent {
        offset,
        event: Event::NotePressure {
            key: Some(key),
            value,
        },
    };
    let (out, inst) = play_with(velocity, None, 0.9, &[press(up, 1.0), press(down, 0.0)]);
    let speed = drive_speed_m_per_s(0.2, impact_speed_m_per_s(velocity));
    let start = || {
        let mut st = EngineState::new(&sc);
        st.strike(&sc, 0.0, 0.0);
        st.set_drive_speed(&sc, speed);
        st
    };
    let (mut st, mut other) = (start(), start());
    let (mut worst, mut apart, mut peak) = (0.0f64, 0.0f64, 0.0f64);
    let (k, c) = (2.0e5, 2.0);
    let mut force = [0.0f64; 3];
    for (i, &o) in out[..n].iter().enumerate() {
        if i == up {
            assert!(st.set_load(&sc, 4.0));
            assert!(other.rebind(&sc, &sc4));
        }
        if i == down {
            assert!(st.set_load(&sc, 1.0));
            assert!(other.rebind(&sc4, &sc));
        }
        let (y, m) = st.tick_with(&sc, |s| s.motion(&sc));
        let now = if (up..down).contains(&i) { &sc4 } else { &sc };
        let y4 = other.tick(now)[0];
        let (p, dp) = (m.x_contact - m.x_hammer, m.v_contact - m.v_hammer);
        if m.in_contact {
            force[(i >= up) as usize + (i >= down) as usize] += (k * p + c * dp).max(0.0);
        }
        peak = peak.max(y[0].abs());
        worst = worst.max((f64::from(o) - y[0]).abs());
        apart = apart.max((y4 - y[0]).abs());
    }
    // the mean force over each 0.3 s window
    let mean = |sum: f64| sum / (0.3 * RATE);
    println!(
        "mean contact force {:.2} / {:.2} / {:.2} N (press 5 / 20 / 5 N); instrument vs \
         offline {worst:.1e}, load vs the scene compiled under 20 N {apart:.1e}, of peak \
         {peak:.1e}",
        mean(force[0]),
        mean(force[1]),
        mean(force[2])
    );
    assert!(peak > 1e-5 && worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
    assert!(apart <= 1e-9 * peak, "{apart:e} of {peak:e}");
    assert!((mean(force[0]) / 5.0 - 1.0).abs() < 0.15, "{force:?}");
    assert!((mean(force[1]) / 20.0 - 1.0).abs() < 0.15, "{force:?}");
    assert!((mean(force[2]) / 5.0 - 1.0).abs() < 0.15, "{force:?}");
    assert_eq!(inst.active_voices(), 1);
}

/// Pressure swept from none to full over 0.4 s in steps of 1/128 (a
/// controller's stream): the force follows every step, not a few levels.
/// The instrument is the scene driven offline with the load set at each
/// step, to the output's f32 rounding; the mean contact force over each
/// quarter of the sweep (from the motion, as above) is the hand's mean
/// force over it, `5 (1 + 3 p)` N, within 15 %; and the sweep's distinct
/// loads are all 129.
#[test]
fn pressure_moves_the_force_continuously() {
    use modal_contact::instrument::press_factor;
    let scene = scraped_bar();
    let sc = compile_one(&scene, RATE).unwrap();
    let velocity = 100.0 / 127.0;
    let key = modal_contact::instrument::root_note(&scene).round() as u8;
    let (from, len) = ((0.1 * RATE) as usize, (0.4 * RATE) as usize);
    let steps = 128;
    let at = |j: usize| from + j * len / steps;
    let events: Vec<TimedEvent> = (0..=steps)
        .map(|j| TimedEvent {
            offset: at(j),
            event: Event::NotePressure {
                key: Some(key),
                value: j as f64 / steps as f64,
            },
        })
        .collect();
    // a block past the last step
    let n = from + len + 64;
    let (out, _) = play_with(velocity, None, n as f64 / RATE, &events);
    let mut st = EngineState::new(&sc);
    st.strike(&sc, 0.0, 0.0);
    st.set_drive_speed(
        &sc,
        drive_speed_m_per_s(0.2, impact_speed_m_per_s(velocity)),
    );
    let (k, c) = (2.0e5, 2.0);
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    let mut force = [0.0f64; 4];
    let mut loads = Vec::new();
    let mut next = 0;
    for (i, &o) in out[..n].iter().enumerate() {
        if next <= steps && i == at(next) {
            assert!(st.set_load(&sc, press_factor(next as f64 / steps as f64)));
            loads.push(st.load());
            next += 1;
        }
        let (y, m) = st.tick_with(&sc, |s| s.motion(&sc));
        if i >= from && m.in_contact {
            let (p, dp) = (m.x_contact - m.x_hammer, m.v_contact - m.v_hammer);
            if i < from + len {
                force[4 * (i - from) / len] += (k * p + c * dp).max(0.0);
            }
        }
        peak = peak.max(y[0].abs());
        worst = worst.max((f64::from(o) - y[0]).abs());
    }
    loads.dedup();
    let quarter = len as f64 / 4.0;
    let means: Vec<f64> = force.iter().map(|f| f / quarter).collect();
    // the hand's mean force over quarter q: 5 (1 + 3 p) at its middle
    let want: Vec<f64> = (0..4)
        .map(|q| 5.0 * (1.0 + 3.0 * (q as f64 + 0.5) / 4.0))
        .collect();
    println!(
        "mean contact force per quarter {means:.2?} N (the hand's {want:.2?}); {} loads; \
         instrument vs offline {worst:.1e} of peak {peak:.1e}",
        loads.len()
    );
    assert_eq!(loads.len(), steps + 1);
    assert!(peak > 1e-5 && worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
    for (m, w) in means.iter().zip(&want) {
        assert!((m / w - 1.0).abs() < 0.15, "{means:?} against {want:?}");
    }
}
