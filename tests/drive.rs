//! A contact driven over a moving surface (`[drive]`, docs/numerics.md, "A
//! driven contact"): against the closed form of a mass resting on a
//! spring over a moving surface, the energy ledger `E(t) - E(0) = W(t) -
//! D(t)` on lossless and damped scenes with lift-offs, and its bad input.

use modal_contact::compile::CompiledScene;
use modal_contact::engine::Motion;
use modal_contact::scene::{Beyond, DriveSpec, SurfaceSpec};
use modal_contact::{compile_one, EngineState, Scene};
use modal_testkit::scenes::{wall_strike, Contact, Hammer, Modal, Pickup, SceneBuilder};

/// `[drive]` over ridges.
fn ridges(speed: f64, spacing: f64, depth: f64, rise: f64, radius: f64) -> DriveSpec {
    DriveSpec {
        speed_m_per_s: speed,
        start_m: 0.0,
        radius_m: radius,
        press_n: 0.0,
        beyond: Beyond::Wrap,
        surface: SurfaceSpec::Ridges {
            length_m: 20.0 * spacing,
            spacing_m: spacing,
            depth_m: depth,
            rise,
        },
    }
}

/// The physical (lab-frame) state at each sample instant of a driven
/// voice: the hammer's height and velocity, the surface's height and
/// rate over the coming sample, and the voice's own energy (hammer
/// relative to the surface).
struct Lab {
    x: f64,
    v: f64,
    s: f64,
    rate: f64,
    e_rel: f64,
    m: Motion,
}

/// The lab-frame energy of `l` for a hammer of mass `m` under the constant
/// acceleration `g`: the voice's own energy with the hammer's kinetic
/// energy taken in the lab instead of relative to the surface, and its
/// potential from the surface's height too.
fn lab_energy(l: &Lab, m: f64, g: f64) -> f64 {
    l.e_rel + m * l.v * l.v / 2.0 - m * (l.v - l.rate).powi(2) / 2.0 + m * g * l.s
}

fn lab(st: &mut EngineState, sc: &CompiledScene) -> Lab {
    let (_, (m, e_rel, at)) = st.tick_with(sc, |st| {
        (
            st.motion(sc),
            st.energy(sc),
            st.surface_at(sc).expect("a driven scene"),
        )
    });
    Lab {
        x: m.x_hammer + at.height_m,
        v: m.v_hammer + at.frame_rate_m_per_s,
        s: at.height_m,
        rate: at.rate_m_per_s,
        e_rel,
        m,
    }
}

/// A 50 g mass resting under gravity on a spring-damper over a rigid
/// floor whose surface moves (triangular ridges): below lift-off its
/// height is, per sample, `s(t) - m g / k` plus the damped oscillation
/// of `m y'' + c y' + k y = 0` that the slope changes start (the
/// position and velocity continuous, `y' = x' - s'` jumping with `s'`),
/// written out here in closed form. A third of the way through, a hand
/// presses the mass 1.5 times its weight more ([`EngineState::set_load`]
/// 2.5): the equilibrium drops to `2.5 m g / k` below the surface and the
/// mass swings about it. The engine agrees to rounding.
#[test]
fn a_mass_resting_on_a_moving_surface_follows_the_closed_form() {
    let (m, k, c, g, rate) = (0.05, 1.0e5, 5.0, 9.81, 44100.0);
    let mut scene = wall_strike(m, k, c, 0.0, 0.0);
    scene.hammer.gravity_m_per_s2 = g;
    scene.drive = Some(ridges(0.1, 0.01, 1.0e-6, 0.3, 0.0));
    let sc = compile_one(&scene, rate).unwrap();
    let mut st = EngineState::new(&sc);
    st.rest_in_contact();
    let h = 1.0 / rate;
    let w0 = (k / m).sqrt();
    let zeta = c / (2.0 * (k * m).sqrt());
    let wd = w0 * (1.0 - zeta * zeta).sqrt();
    let (a, b) = (zeta * w0, wd);
    // lab state: at rest at the static equilibrium below s(0) = 0
    let (mut x, mut v) = (-m * g / k, 0.0);
    let (mut worst, mut peak, mut lowest_force) = (0.0f64, 0.0f64, f64::INFINITY);
    let n = (0.25 * rate) as usize;
    for i in 0..n {
        let load = if i < n / 3 { 1.0 } else { 2.5 };
        assert!(st.set_load(&sc, load));
        let g = g * load;
        let got = lab(&mut st, &sc);
        assert!(got.m.in_contact, "sample {i}: lifted off");
        let err = (got.x - x).abs().max((got.v - v).abs() / w0);
        worst = worst.max(err);
        peak = peak.max((x - got.s).abs());
        if i == n / 3 {
            // refused, and nothing moves
            for bad in [f64::NAN, -1.0, f64::INFINITY] {
                assert!(!st.set_load(&sc, bad));
            }
            assert_eq!(st.load(), 2.5);
        }
        lowest_force = lowest_force.min(k * (got.s - got.x) + c * (got.rate - got.v));
        // one sample of the closed form from (x, v), surface from s with rate
        let y0 = x - (got.s - m * g / k);
        let dy0 = v - got.rate;
        let (cc, ss) = ((b * h).cos(), (b * h).sin());
        let e = (-a * h).exp();
        let y = e * (y0 * cc + (dy0 + a * y0) / b * ss);
        let dy = e * (dy0 * cc - (a * dy0 + w0 * w0 * y0) / b * ss);
        x = y + got.s + got.rate * h - m * g / k;
        v = dy + got.rate;
    }
    println!(
        "resting mass over moving ridges, {n} samples: largest difference {worst:.2e} m \
         (displacement below the surface up to {peak:.2e} m, least contact force {lowest_force:.3} N)"
    );
    assert!(lowest_force > 0.0);
    assert!(worst < 1e-12 * peak.max(m * g / k), "{worst:e}");
}

/// A scene whose hammer lifts off the moving surface and lands again: a
/// 20 g ball on a modal bar of three modes rolling over sharp ridges.
fn bouncing(damped: bool, radius: f64) -> Scene {
    let t60 = |t: f64| if damped { Some(t) } else { None };
    let bar = Modal::new("bar", &["c", "p"])
        .mode(180.0, t60(1.5), &[0.9, 0.5])
        .mode(720.0, t60(0.8), &[-0.6, 0.7])
        .mode(1650.0, t60(0.4), &[0.4, -0.3]);
    let mut scene = SceneBuilder::new("rolling-ball")
        .duration(0.5)
        .object(bar)
        .hammer(Hammer::new(0.02).height(0.0).gravity(9.81))
        .contact(
            Contact::new("bar", 3.0e5)
                .point("c")
                .damping(if damped { 4.0 } else { 0.0 }),
        )
        .pickup(Pickup::new("bar", "p"))
        .build();
    scene.drive = Some(ridges(0.4, 3.0e-3, 4.0e-5, 0.8, radius));
    scene
}

/// The energy ledger of a driven voice: with `E` the lab-frame energy
/// (object, hammer `m v^2 / 2 + m g x`, spring) and `W` the work of the
/// moving surface (over a sample its rate times the contact force's
/// impulse, which the hammer's momentum gives: `m (v(t+h) - v(t)) + m g
/// h`), returns the largest `|E - E(0) - W|` and the largest rise of `E -
/// W` from one sample to the next, both relative to the largest energy, and
/// the number of contacts. `load(i)` is the constant force's factor from
/// sample `i` on ([`EngineState::set_load`]: a hand pressing harder or
/// lighter); where it steps, the force's potential `m g x` steps with it
/// at the same height `x`, and `W` counts that step as the hand's.
fn ledger(
    scene: &Scene,
    seconds: f64,
    speed: impl Fn(usize) -> f64,
    load: impl Fn(usize) -> f64,
) -> (f64, f64, u64, f64) {
    let rate = 44100.0;
    let sc = compile_one(scene, rate).unwrap();
    let mut st = EngineState::new(&sc);
    st.set_drive_speed(&sc, speed(0));
    assert!(st.set_load(&sc, load(0)));
    let (m, h) = (sc.m_h, 1.0 / rate);
    let mut g = sc.g * load(0);
    let n = (seconds * rate) as usize;
    let first = lab(&mut st, &sc);
    let e0 = lab_energy(&first, m, g);
    let (mut prev, mut work) = (first, 0.0);
    let (mut worst, mut rise, mut scale) = (0.0f64, 0.0f64, e0.abs());
    let mut last_balance = 0.0;
    for i in 1..n {
        st.set_drive_speed(&sc, speed(i));
        assert!(st.set_load(&sc, load(i)));
        let now = lab(&mut st, &sc);
        work += prev.rate * m * (now.v - prev.v + g * h);
        let g_now = sc.g * load(i);
        work += m * (g_now - g) * now.x;
        g = g_now;
        let e = lab_energy(&now, m, g);
        scale = scale.max(e.abs()).max(work.abs());
        let balance = e - e0 - work;
        worst = worst.max(balance.abs());
        rise = rise.max(balance - last_balance);
        last_balance = balance;
        prev = now;
    }
    (worst / scale, rise / scale, st.contacts_started, scale)
}

/// The speed of a player's stroke: from the scene's 0.4 m/s down to
/// rest and back up and backwards, changed every 100 samples.
fn stroke(i: usize) -> f64 {
    0.4 * (2.0 * std::f64::consts::PI * (i / 100) as f64 / 150.0).cos()
}

/// A hand pressing the ball harder and lighter: the force's factor 1 to
/// 4, stepped every 64 samples along a slow wave.
fn pressing(i: usize) -> f64 {
    1.0 + 1.5 * (1.0 - (2.0 * std::f64::consts::PI * (i / 64) as f64 / 90.0).cos())
}

/// Lossless (undamped modes, no contact damping): the energy is the
/// surface's work, to rounding, through every lift-off and landing, at a
/// constant speed, at a speed that changes, and under a force that
/// changes.
#[test]
fn lossless_driven_energy_is_the_surfaces_work() {
    let cases = [
        ("constant speed", false, false),
        ("changing speed", true, false),
        ("changing speed and force", true, true),
    ];
    for (what, changing, pressed) in cases {
        let speed = |i: usize| if changing { stroke(i) } else { 0.4 };
        let load = |i: usize| if pressed { pressing(i) } else { 1.0 };
        let (worst, _, contacts, scale) = ledger(&bouncing(false, 0.0), 0.5, speed, load);
        println!(
            "lossless rolling ball, {what}: |E - E0 - W| <= {worst:.2e} of {scale:.2e} J, \
             {contacts} contacts"
        );
        assert!(
            contacts > 5,
            "the ball should lift off and land again: {contacts}"
        );
        assert!(worst < 1e-9, "{worst:e}");
    }
}

/// Damped: `E - W` never rises (the dissipation only grows), also with
/// the rolling filter of a 2 mm ball.
#[test]
fn damped_driven_energy_never_exceeds_the_work() {
    for (radius, pressed) in [(0.0, false), (2e-3, false), (2e-3, true)] {
        let load = |i: usize| if pressed { pressing(i) } else { 1.0 };
        let (_, rise, contacts, scale) = ledger(&bouncing(true, radius), 0.5, |_| 0.4, load);
        println!(
            "damped rolling ball, radius {radius}, pressed {pressed}: largest rise of E - W \
             {rise:.2e} of {scale:.2e} J, {contacts} contacts"
        );
        assert!(contacts > 2, "{contacts}");
        assert!(rise < 1e-10, "{rise:e}");
    }
}

/// Every driven preset keeps the ledger: `E - W` never rises (its modes
/// and contacts are damped), over its stroke at the scene's speed and
/// over one slowed, stopped and reversed by a player's hand pressing
/// harder and lighter.
#[test]
fn every_driven_preset_keeps_its_ledger() {
    let driven = modal_testkit::scenes::driven_presets();
    assert!(driven.len() >= 5, "{driven:?}");
    for name in driven {
        let scene = modal_testkit::scenes::preset(name);
        let v = scene.drive.as_ref().expect("a driven preset").speed_m_per_s;
        let played = |i: usize| v * stroke(i) / 0.4;
        for (what, speed, load) in [
            (
                "its stroke",
                &(|_| v) as &dyn Fn(usize) -> f64,
                &(|_| 1.0) as &dyn Fn(usize) -> f64,
            ),
            ("played", &played, &pressing),
        ] {
            let (_, rise, contacts, scale) = ledger(&scene, 0.3, speed, load);
            println!(
                "{} ({what}): largest rise of E - W {rise:.2e} of {scale:.2e} J, {contacts} contacts",
                name
            );
            assert!(contacts >= 1, "{}: {contacts}", name);
            assert!(rise < 1e-10, "{} ({what}): {rise:e}", name);
        }
    }
}

/// A driven render is the same in any blocks and in the tick path, and a
/// standing surface (speed 0) is the struck scene bit for bit.
#[test]
fn driven_blocks_and_ticks_agree_and_speed_zero_is_struck() {
    let mut scene = bouncing(true, 0.0);
    scene.hammer.height_m = 1e-3;
    scene.hammer.velocity_m_per_s = -0.5;
    let sc = compile_one(&scene, 44100.0).unwrap();
    let n = 8000;
    let mut a = EngineState::new(&sc);
    let ticks: Vec<f64> = (0..n).map(|_| a.tick(&sc)[0]).collect();
    let mut b = EngineState::new(&sc);
    let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
    for (lc, rc) in l.chunks_mut(333).zip(r.chunks_mut(333)) {
        b.process_block(&sc, lc, rc);
    }
    assert_eq!(ticks, l);
    let mut still = scene.clone();
    still.drive.as_mut().unwrap().speed_m_per_s = 0.0;
    let mut plain = scene.clone();
    plain.drive = None;
    let render = |s: &Scene| modal_contact::render(s, &Default::default()).unwrap().left;
    assert_eq!(render(&still), render(&plain));
    assert_ne!(render(&scene), render(&plain));
}

/// Bad input: clear errors with the field path.
#[test]
fn bad_drive_input_is_refused_by_field() {
    let base = bouncing(true, 0.0);
    let err = |d: DriveSpec| {
        let mut s = base.clone();
        s.drive = Some(d);
        match s.validate() {
            Err(e) => e.to_string(),
            Ok(()) => match compile_one(&s, 44100.0) {
                Err(e) => e.to_string(),
                Ok(_) => String::from("accepted"),
            },
        }
    };
    let mut d = ridges(0.4, 3e-3, 4e-5, 0.8, 0.0);
    d.speed_m_per_s = f64::NAN;
    assert!(err(d).contains("drive.speed_m_per_s"));
    let mut d = ridges(0.4, 3e-3, 4e-5, 0.8, 0.0);
    d.radius_m = -1.0;
    assert!(err(d).contains("drive.radius_m"));
    let d = ridges(0.4, 3e-3, 4e-5, 1.5, 0.0);
    assert!(err(d).contains("drive.surface.rise"));
    let mut d = ridges(0.4, 3e-3, 4e-5, 0.8, 0.0);
    let dir = std::env::temp_dir().join(format!("modal-drive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = dir.join("missing.wav");
    let not_audio = dir.join("not-audio.wav");
    std::fs::write(&not_audio, b"this is not a WAV file").unwrap();
    let empty = dir.join("empty.wav");
    hound::WavWriter::create(
        &empty,
        hound::WavSpec {
            channels: 1,
            sample_rate: 44100,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        },
    )
    .unwrap()
    .finalize()
    .unwrap();
    for (file, says) in [
        (&missing, "cannot read"),
        (&not_audio, "as a WAV file"),
        (&empty, "holds 0 sample frames"),
    ] {
        d.surface = SurfaceSpec::Wav {
            file: file.to_string_lossy().into_owned(),
            length_m: 0.1,
            depth_m: 1e-5,
        };
        let e = err(d.clone());
        println!("{e}");
        assert!(e.contains("drive.surface.file") && e.contains(says), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
    // a scene of several contacts cannot be driven yet
    let mut several = base.clone();
    several.striker.push(modal_contact::scene::StrikerSpec {
        mass_kg: 0.01,
        height_m: 0.01,
        velocity_m_per_s: 0.0,
        point: "p".into(),
        stiffness_n_per_m: 1e5,
        damping_n_s_per_m: 0.0,
        law: None,
        notes: Vec::new(),
        mallet: None,
    });
    several.drive = Some(ridges(0.4, 3e-3, 4e-5, 0.8, 0.0));
    let e = several.validate().unwrap_err().to_string();
    assert!(e.starts_with("drive"), "{e}");
}

/// The engine's driven contact against the independent reference solver
/// (`pwl_reference::solve_on_surface`: the augmented system `[z; s; s']`
/// stepped by dense exponentials, events by bisection), on the rolling
/// ball over sharp ridges, lossless and damped: hammer height, velocity
/// and contact point, and every contact instant, within the reference's
/// own predictability horizon (its run against a twin with the hammer's
/// mass moved by 1e-9).
#[test]
fn driven_contact_matches_the_reference_solver() {
    use pwl_reference as reference;
    let rate = 44100.0;
    let n = 4410;
    for damped in [false, true] {
        let scene = bouncing(damped, 0.0);
        let sc = compile_one(&scene, rate).unwrap();
        let model = reference_model(&scene);
        let d = sc.drive.as_ref().unwrap();
        // lossless: the player's changing stroke; damped: the scene's speed
        let speed = |i: usize| if damped { 0.4 } else { stroke(i) };
        let mut path = d.start_m;
        let surface: Vec<f64> = (0..=n)
            .map(|i| {
                let s = d.profile.at(path) - d.base_m;
                path += speed(i) * sc.h;
                s
            })
            .collect();
        let sol = reference::solve_on_surface(&model, &surface, rate, n);
        let twin = reference::solve_on_surface(&model.perturbed(1e-9), &surface, rate, n);
        let hz = reference::horizon(&sol, &twin, 1e-7);
        let mut st = EngineState::new(&sc);
        let mut starts = Vec::new();
        let (mut num, mut den) = ([0.0f64; 3], [0.0f64; 3]);
        for i in 0..=hz {
            st.set_drive_speed(&sc, speed(i));
            let got = lab(&mut st, &sc);
            assert_eq!(got.s, surface[i]);
            let want = &sol.samples[i];
            for (k, (a, b)) in [
                (got.x, want.x_hammer),
                (got.v, want.v_hammer),
                (got.m.x_contact, want.x_contact),
            ]
            .into_iter()
            .enumerate()
            {
                num[k] += (a - b) * (a - b);
                den[k] += b * b;
            }
            for e in st.switch_events() {
                if e.entered {
                    starts.push(i as f64 + e.after_s * rate);
                }
            }
        }
        let errs: Vec<f64> = (0..3).map(|k| (num[k] / den[k]).sqrt()).collect();
        let ref_starts: Vec<f64> = sol
            .contacts
            .iter()
            .map(|c| c.start_s * rate)
            .filter(|&t| t < hz as f64 - 1.0)
            .collect();
        let dt = starts
            .iter()
            .zip(&ref_starts)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!(
            "{} rolling ball vs reference over {hz} samples: hammer {:.1e}, velocity {:.1e}, \
             contact point {:.1e}; {} contacts, starts within {dt:.1e} samples",
            if damped {
                "damped, constant speed,"
            } else {
                "lossless, changing speed,"
            },
            errs[0],
            errs[1],
            errs[2],
            ref_starts.len()
        );
        assert!(hz > 1000, "horizon {hz}");
        assert!(ref_starts.len() >= 3, "{}", ref_starts.len());
        assert_eq!(starts.len().min(ref_starts.len()), ref_starts.len());
        assert!(errs.iter().all(|&e| e < 1e-9), "{errs:?}");
        assert!(dt < 1e-6, "{dt:e}");
    }
}

/// The reference solver's model of [`bouncing`]: its bar's modes with
/// their weights at the contact point, the ball and its contact.
fn reference_model(scene: &Scene) -> pwl_reference::Model {
    use modal_contact::scene::ObjectSpec;
    use pwl_reference as reference;
    let ObjectSpec::Modal(bar) = &scene.object[0] else {
        panic!("a modal bar");
    };
    reference::Model {
        modes: bar
            .mode
            .iter()
            .map(|m| reference::Mode {
                freq_hz: m.freq_hz,
                t60_s: m.t60_s,
                weight: m.weights[0],
            })
            .collect(),
        hammer: reference::Hammer {
            mass_kg: scene.hammer.mass_kg,
            height_m: scene.hammer.height_m,
            velocity_m_per_s: scene.hammer.velocity_m_per_s,
            gravity_m_per_s2: scene.hammer.gravity_m_per_s2,
        },
        contact: reference::Contact {
            stiffness_n_per_m: scene.contact.stiffness_n_per_m,
            damping_n_s_per_m: scene.contact.damping_n_s_per_m,
        },
        back: None,
        extra: Vec::new(),
        masses: vec![],
        links: vec![],
    }
}

/// 200 random driven scenes, stiff and extreme: contacts from 0.01x to 1000x
/// Nyquist, 1 g to 1 kg hammers, surfaces from smooth to far steeper than
/// the hammer can follow, speeds up to 5 m/s forwards and backwards,
/// rolling radii, pressing forces, every kind of surface: each sample
/// finite, and `E - W` (the lab-frame energy less the surface's work)
/// never rising beyond rounding.
#[test]
fn random_driven_scenes_stay_finite_and_passive() {
    use modal_contact::test_rng::TestRng;
    let mut rng = TestRng(0x0064_7269_7665);
    let rate = 44100.0;
    let mut worst = 0.0f64;
    let (mut contacts, mut ran, mut lifted) = (0u64, 0, 0);
    let cases = 200;
    for case in 0..cases {
        let scene = random_driven_scene(&mut rng);
        if scene.validate().is_err() {
            continue;
        }
        let Ok(sc) = compile_one(&scene, rate) else {
            continue;
        };
        let mut st = EngineState::new(&sc);
        let (mass, g, h) = (sc.m_h, sc.g, 1.0 / rate);
        let energy = |l: &Lab| lab_energy(l, mass, g);
        let first = lab(&mut st, &sc);
        let e0 = energy(&first);
        let (mut prev, mut work, mut last, mut scale) = (first, 0.0, 0.0, e0.abs());
        for i in 1..2000 {
            let now = lab(&mut st, &sc);
            assert!(
                now.x.is_finite() && now.v.is_finite() && now.e_rel.is_finite(),
                "case {case}, sample {i}: not finite"
            );
            work += prev.rate * mass * (now.v - prev.v + g * h);
            let e = energy(&now);
            // the terms the lab energy is summed from, whose rounding it carries
            let terms = now.e_rel.abs() + mass * now.v * now.v + mass * (g * now.s).abs();
            scale = scale.max(e.abs()).max(work.abs()).max(terms);
            let balance = e - e0 - work;
            let rise = (balance - last) / scale.max(f64::MIN_POSITIVE);
            assert!(
                rise < 1e-9,
                "case {case}, sample {i}: E - W rose by {rise:e} ({last:e} J to {balance:e} J, \
                 scale {scale:e} J): {scene:?}"
            );
            worst = worst.max(rise);
            last = balance;
            prev = now;
        }
        contacts += st.contacts_started;
        ran += 1;
        lifted += usize::from(st.contacts_started > 1);
    }
    println!(
        "{ran} of {cases} random driven scenes compiled and ran ({lifted} lifting off and landing \
         again, {contacts} contacts): largest rise of E - W {worst:.1e} of the energy"
    );
    assert!(
        ran > cases / 2 && lifted > cases / 10,
        "{ran} ran, {lifted} lifted off"
    );
}

/// A random driven scene of [`random_driven_scenes_stay_finite_and_passive`].
fn random_driven_scene(rng: &mut modal_contact::test_rng::TestRng) -> Scene {
    let m = 10f64.powf(rng.uniform(-3.0, 0.0));
    // contact frequency sqrt(k / m) from 0.01x to 1000x Nyquist
    let f_c = 44100.0 / 2.0 * 10f64.powf(rng.uniform(-2.0, 3.0));
    let k = m * (2.0 * std::f64::consts::PI * f_c).powi(2);
    let zeta = [0.0, 0.05, 0.5, 1.0, 3.0][rng.below(5)];
    let c = 2.0 * zeta * (k * m).sqrt();
    let n_modes = 1 + rng.below(6);
    let mut bar = Modal::new("bar", &["c", "p"]);
    for j in 0..n_modes {
        let f = 10f64.powf(rng.uniform(1.5, 4.3));
        bar = bar.mode(
            f,
            Some(rng.uniform(0.05, 3.0)),
            &[rng.uniform(-2.0, 2.0), 0.3 + j as f64],
        );
    }
    let mut scene = SceneBuilder::new("random-drive")
        .object(bar)
        .hammer(
            Hammer::new(m)
                .height(rng.uniform(0.0, 1e-3))
                .gravity([0.0, 9.81, 200.0][rng.below(3)]),
        )
        .contact(
            Contact::new("bar", k.min(1e12))
                .point("c")
                .damping(c.min(1e6)),
        )
        .pickup(Pickup::new("bar", "p"))
        .build();
    let length = rng.uniform(0.01, 1.0);
    let surface = match rng.below(2) {
        0 => SurfaceSpec::Ridges {
            length_m: length,
            spacing_m: length * rng.uniform(0.01, 0.5),
            depth_m: 10f64.powf(rng.uniform(-8.0, -2.5)),
            rise: rng.uniform(0.05, 1.0),
        },
        _ => SurfaceSpec::Fractal {
            length_m: length,
            rms_m: 10f64.powf(rng.uniform(-8.0, -3.0)),
            correlation_m: length * rng.uniform(0.001, 0.2),
            exponent: rng.uniform(0.5, 4.0),
            seed: rng.next_u64(),
        },
    };
    scene.drive = Some(DriveSpec {
        speed_m_per_s: rng.uniform(-5.0, 5.0),
        start_m: rng.uniform(-1.0, 1.0),
        radius_m: [0.0, 1e-3, 0.02][rng.below(3)],
        press_n: [0.0, 1.0, 20.0][rng.below(3)],
        beyond: [Beyond::Wrap, Beyond::Stop][rng.below(2)],
        surface,
    });
    scene
}

/// Every driven preset renders the same samples on every path: the block
/// path, the tick path, and the block path that observes the motion and
/// the energy (what a trace runs), bit for bit.
#[test]
fn driven_presets_render_the_same_on_every_path() {
    let driven = modal_testkit::scenes::driven_presets();
    assert!(driven.len() >= 5, "{driven:?}");
    for name in driven {
        let scene = modal_testkit::scenes::preset(name);
        let sc = compile_one(&scene, 44100.0).unwrap();
        let n = 20000;
        let mut a = EngineState::new(&sc);
        let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
        a.process_block(&sc, &mut l, &mut r);
        let mut b = EngineState::new(&sc);
        let ticks: Vec<f64> = (0..n).map(|_| b.tick(&sc)[0]).collect();
        let mut c = EngineState::new(&sc);
        let (mut lt, mut rt) = (vec![0.0; n], vec![0.0; n]);
        let mut motion = vec![Motion::default(); n];
        let mut energy = vec![0.0; n];
        c.process_block_traced(&sc, &mut lt, &mut rt, &mut motion, &mut energy);
        let first = |x: &[f64]| x.iter().zip(&l).position(|(p, q)| p != q);
        println!(
            "{name}: ticks differ first at {:?}, traced at {:?}; {} contacts",
            first(&ticks),
            first(&lt),
            a.contacts_started
        );
        assert_eq!(first(&ticks), None, "{name}");
        assert_eq!(first(&lt), None, "{name}");
    }
}

/// A driven scene's trace (docs/design.md, "Rolling and scraping") ends
/// each row with the path position and the surface's height under the
/// contact: the rows a render keeps, its CSV and its NPY carry the
/// engine's own `surface_at` at each row's instant (the CSV's numbers
/// read back to the same doubles, the NPY's are their bits), the path
/// advances by the speed's step per sample, and `x_hammer + surface` is
/// the hammer's height in the room. A trace made for a scene that is not
/// driven refuses a surface, and a driven one a row without it.
#[test]
fn a_driven_trace_has_the_surfaces_columns() {
    use modal_contact::render::{
        render_stream, CsvTrace, NpyTrace, TraceRows, TraceSink, DRIVE_COLUMNS, TRACE_HEADER,
    };
    let scene = bouncing(true, 0.0);
    let sc = compile_one(&scene, 44100.0).unwrap();
    let n = 3000;
    let rows = TraceRows {
        rate_hz: 44100.0,
        rows: Vec::new(),
        further: Vec::new(),
        contacts: 1,
    };
    let csv = CsvTrace::driven(44100.0, Vec::new()).unwrap();
    let npy = NpyTrace::driven(44100.0, n, Vec::new()).unwrap();
    let mut sinks = (rows, (csv, npy));
    render_stream(&sc, n, |_, _| Ok(()), Some(&mut sinks)).unwrap();
    let (rows, (csv, npy)) = sinks;
    let (csv, npy) = (
        String::from_utf8(csv.finish().unwrap()).unwrap(),
        npy.finish().unwrap(),
    );
    // the engine's own view, sample by sample
    let mut st = EngineState::new(&sc);
    let want: Vec<Lab> = (0..n).map(|_| lab(&mut st, &sc)).collect();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        format!("{TRACE_HEADER},{DRIVE_COLUMNS}")
    );
    let step = 0.4 / 44100.0;
    let mut worst_step = 0.0f64;
    let data = &npy[npy.len() - n * 72..];
    for (i, (r, w)) in rows.rows.iter().zip(&want).enumerate() {
        assert_eq!(r.obs.x_hammer, w.m.x_hammer, "row {i}");
        assert_eq!(r.surface[1], w.s, "row {i}");
        assert_eq!(r.obs.x_hammer + r.surface[1], w.x, "row {i}");
        let cols: Vec<f64> = lines
            .next()
            .unwrap()
            .split(',')
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(cols.len(), 9);
        assert_eq!(&cols[7..], &r.surface[..], "csv row {i}");
        let rec = &data[72 * i..72 * i + 72];
        let field = |k: usize| f64::from_le_bytes(rec[8 * k..8 * k + 8].try_into().unwrap());
        assert_eq!([field(7), field(8)], r.surface, "npy row {i}");
        if i > 0 {
            let d = r.surface[0] - rows.rows[i - 1].surface[0];
            worst_step = worst_step.max((d - step).abs() / step);
        }
    }
    assert_eq!(rows.rows.len(), n);
    assert!(lines.next().is_none());
    println!(
        "{n} rows: path steps within {worst_step:.1e} of speed / rate, surfaces {:.2e} .. {:.2e} m",
        rows.rows
            .iter()
            .map(|r| r.surface[1])
            .fold(f64::INFINITY, f64::min),
        rows.rows
            .iter()
            .map(|r| r.surface[1])
            .fold(f64::NEG_INFINITY, f64::max)
    );
    assert!(worst_step < 1e-9, "{worst_step:e}");
    // the columns are the file's kind: never dropped, never made up
    let m = Motion::default();
    let mut plain = CsvTrace::new(44100.0, Vec::new()).unwrap();
    assert!(plain.record_driven(0, &m, Some(0.0), [0.0; 2]).is_err());
    let mut driven = CsvTrace::driven(44100.0, Vec::new()).unwrap();
    assert!(driven.record(0, &m, Some(0.0)).is_err());
    let mut plain = NpyTrace::new(44100.0, 1, Vec::new()).unwrap();
    assert!(plain.record_driven(0, &m, Some(0.0), [0.0; 2]).is_err());
    let mut driven = NpyTrace::driven(44100.0, 1, Vec::new()).unwrap();
    assert!(driven.record(0, &m, Some(0.0)).is_err());
}
