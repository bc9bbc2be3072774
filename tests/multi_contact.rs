//! Several contacts at once (`modal_contact::multi`): the engine against
//! the independent reference solver (`pwl_reference`, its several-contact
//! model: physical coordinates, double-double exponentials, bisection),
//! which shares the model's numbers and nothing else; against the
//! one-contact engine where two contacts cannot interact (each hammer's
//! point on modes of its own: the sum of two one-contact runs); against
//! the closed form of two strikes that never meet; energy that never rises;
//! and bad models refused with the field named.
//!
//! Cases: an object of four modes (220, 950 and 3500 Hz and one at 28.9
//! kHz, 1.31x Nyquist) with a different weight vector at each hammer's
//! point, two to four hammers, contacts at 3.17x to 317x Nyquist (the
//! two-mass contact frequency of each hammer with the object's effective
//! mass at its point), mass ratios 1e-3 to 1e3, damping ratios 0 to 5,
//! strikes at different instants, at the same instant, and dropped under
//! gravity. 44.1 kHz, 50 ms.
//!
//! Tolerances (as the one-contact suite's, `tests/stiff_switching.rs`):
//! both solvers solve the same piecewise-linear equations exactly up to
//! rounding, so every hammer's height, velocity and contact point agree to
//! 1e-6 relative L2 and every contact's start and end to 1e-6 samples, and
//! the energy never rises from one sample to the next by more than `64 dim
//! kappa u` of its scale.
//!
//! Run with `--nocapture` for the table.

use modal_contact::compile::compile_with;
use modal_contact::engine::EngineState;
use modal_contact::multi::{
    CompiledMulti, MultiEnd, MultiError, MultiHammer, MultiModel, MultiState, MultiSwitch,
    MAX_CONTACTS, MAX_SPRINGS,
};
use modal_contact::scene::{Scene, Switching};
use modal_testkit::metrics::{instant_horizon, rel_l2, rod_energy_scale, Interval};
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder};
use pwl_reference as reference;
use std::f64::consts::PI;

const RATE: f64 = 44_100.0;
const NYQUIST: f64 = RATE / 2.0;
const SAMPLES: usize = 2205;
const TOL_TRACE: f64 = 1e-6;
const TOL_INSTANT: f64 = 1e-6;
const U: f64 = f64::EPSILON / 2.0;
/// Relative disturbance of the reference's twin run.
const DISTURBANCE: f64 = 1e-9;
/// Agreement of the reference and its twin that defines the window.
const HORIZON_TOL: f64 = 1e-7;
/// Shortest acceptable window [samples].
const MIN_WINDOW: usize = 20;

const FREQS: [f64; 4] = [220.0, 950.0, 3500.0, 28_900.0];
const WEIGHTS: [[f64; 4]; 4] = [
    [0.45, 0.40, 0.35, 0.15],
    [0.40, -0.30, 0.42, 0.12],
    [0.25, 0.50, -0.30, 0.18],
    [0.35, -0.45, -0.25, 0.10],
];

/// One hammer of a case: mass ratio to the object's effective mass at its
/// point, launch, contact frequency / Nyquist, damping ratio.
#[derive(Clone, Copy)]
struct Striker {
    mass_ratio: f64,
    /// Initial height \[m\] and velocity \[m/s\].
    height: f64,
    velocity: f64,
    fc_ratio: f64,
    zeta: f64,
}

struct Case {
    name: String,
    t60: Option<f64>,
    gravity: f64,
    strikers: Vec<Striker>,
}

fn m_eff(j: usize) -> f64 {
    1.0 / WEIGHTS[j].iter().map(|w| w * w).sum::<f64>()
}

fn hammer(j: usize, s: &Striker) -> MultiHammer {
    let me = m_eff(j);
    let m = s.mass_ratio * me;
    let mr = 1.0 / (1.0 / m + 1.0 / me);
    let k = (2.0 * PI * s.fc_ratio * NYQUIST).powi(2) * mr;
    let c = 2.0 * s.zeta * (k * mr).sqrt();
    MultiHammer {
        mass_kg: m,
        height_m: s.height,
        velocity_m_per_s: s.velocity,
        weights: WEIGHTS[j].to_vec(),
        stiffness_n_per_m: k,
        damping_n_s_per_m: c,
    }
}

fn hammers(case: &Case) -> Vec<MultiHammer> {
    case.strikers
        .iter()
        .enumerate()
        .map(|(j, s)| hammer(j, s))
        .collect()
}

fn model(case: &Case) -> MultiModel {
    let sigma = case.t60.map_or(0.0, |t| 1000f64.ln() / t);
    let n = FREQS.len();
    MultiModel::struck(
        FREQS.to_vec(),
        vec![sigma; n],
        &hammers(case),
        case.gravity,
        [
            (vec![1.0, 0.5, 0.25, 0.1], vec![0.0; n]),
            (vec![0.0; n], vec![1e-3; n]),
        ],
    )
}

/// The same numbers as the reference solver's model.
fn reference_model(m: &MultiModel, hammers: &[MultiHammer], t60: Option<f64>) -> reference::Model {
    let rh = |h: &MultiHammer| reference::Hammer {
        mass_kg: h.mass_kg,
        height_m: h.height_m,
        velocity_m_per_s: h.velocity_m_per_s,
        gravity_m_per_s2: m.gravity_m_per_s2,
    };
    let rc = |h: &MultiHammer| reference::Contact {
        stiffness_n_per_m: h.stiffness_n_per_m,
        damping_n_s_per_m: h.damping_n_s_per_m,
    };
    let h0 = &hammers[0];
    reference::Model {
        modes: m
            .freq_hz
            .iter()
            .zip(&h0.weights)
            .map(|(&f, &w)| reference::Mode {
                freq_hz: f,
                t60_s: t60,
                weight: w,
            })
            .collect(),
        hammer: rh(h0),
        contact: rc(h0),
        back: None,
        extra: hammers[1..]
            .iter()
            .map(|h| reference::ExtraHammer {
                hammer: rh(h),
                weights: h.weights.clone(),
                contact: rc(h),
            })
            .collect(),
        masses: vec![],
        links: vec![],
    }
}

/// Per contact: its intervals `[start, end]` in samples.
type Intervals = Vec<Vec<Interval>>;

fn intervals_of(switches: &[MultiSwitch], k: usize) -> Intervals {
    let mut out = vec![Vec::new(); k];
    for s in switches {
        let t = s.time_s * RATE;
        if s.entered {
            out[s.contact].push((t, None));
        } else if let Some(last) = out[s.contact].last_mut() {
            last.1 = Some(t);
        }
    }
    out
}

/// Contact `j`'s height, velocity and contact point (`q` = 0, 1, 2) in a
/// reference sample.
fn pick(s: &reference::Sample, j: usize, q: usize) -> f64 {
    if j == 0 {
        [s.x_hammer, s.v_hammer, s.x_contact][q]
    } else {
        s.extra[j - 1][q]
    }
}

/// The last sample up to which two reference runs agree to
/// [`HORIZON_TOL`] (running relative L2) on every hammer's traces.
fn trace_horizon(a: &[reference::Sample], b: &[reference::Sample], k: usize) -> usize {
    let mut num = vec![0.0; 3 * k];
    let mut den = vec![0.0; 3 * k];
    let mut last = 0;
    for i in 0..a.len().min(b.len()) {
        let mut agree = true;
        for j in 0..k {
            for q in 0..3 {
                let (x, y) = (pick(&a[i], j, q), pick(&b[i], j, q));
                num[3 * j + q] += (x - y) * (x - y);
                den[3 * j + q] += y * y;
                agree &= num[3 * j + q] <= HORIZON_TOL * HORIZON_TOL * den[3 * j + q];
            }
        }
        if agree {
            last = i;
        }
    }
    last
}

fn reference_intervals(sol: &reference::Solution, k: usize) -> Intervals {
    let mut out = vec![Vec::new(); k];
    for c in &sol.contacts {
        out[c.contact].push((c.start_s * RATE, c.end_s.map(|e| e * RATE)));
    }
    out
}

struct Outcome {
    /// Samples compared: where the reference and its twin (inputs moved
    /// by 1e-9) still agree.
    window: usize,
    count_mismatch: Option<String>,
    contacts: Vec<usize>,
    err_x: f64,
    err_v: f64,
    err_c: f64,
    dt: f64,
    de: f64,
    bound: f64,
    evaluations_per_switch: f64,
}

fn run_case(case: &Case) -> Outcome {
    let m = model(case);
    let rm = reference_model(&m, &hammers(case), case.t60);
    compare(&case.name, &m, &rm)
}

/// Run the engine on `m` and the reference on `rm` (the same model) and
/// compare them on the window where the reference and its twin agree.
fn compare(name: &str, m: &MultiModel, rm: &reference::Model) -> Outcome {
    let k = m.contacts.len();
    let sc = CompiledMulti::new(m, RATE).unwrap();
    assert!(
        sc.growth() - 1.0 < 1e-12,
        "{name}: a growing block {:e}",
        sc.growth() - 1.0
    );
    let mut st = MultiState::new(&sc);
    st.record(true);
    let mut obs = vec![st.observe(&sc)];
    for _ in 0..SAMPLES {
        let y = st.tick(&sc);
        assert!(y.iter().all(|v| v.is_finite()), "{name}");
        obs.push(st.observe(&sc));
    }
    let sol = reference::solve(rm, RATE, SAMPLES + 1);
    let twin = reference::solve(&rm.perturbed(DISTURBANCE), RATE, SAMPLES + 1);
    let n = sol.samples.len().min(obs.len()).min(twin.samples.len());
    // the window the inputs determine: the reference and its twin agree
    let hz_trace = trace_horizon(&sol.samples[..n], &twin.samples[..n], k);
    let ref_iv = reference_intervals(&sol, k);
    let hz_instants = (0..k)
        .map(|j| {
            instant_horizon(
                &ref_iv[j],
                &reference_intervals(&twin, k)[j],
                TOL_INSTANT,
                n,
            )
        })
        .min()
        .unwrap();
    let window = hz_trace.min(hz_instants);
    let (ex, ev, ec) = trace_errors(&obs, &sol, window, k);
    let (dt, counts, count_mismatch) = instant_errors(&st.switches, &ref_iv, window, k);
    let de = largest_energy_rise(m, &obs);
    let bound = 64.0 * sc.max_dim() as f64 * sc.kappa() * U;
    Outcome {
        window,
        count_mismatch,
        contacts: counts,
        err_x: ex,
        err_v: ev,
        err_c: ec,
        dt,
        de,
        bound,
        evaluations_per_switch: st.stats.evaluations as f64 / st.stats.switches.max(1) as f64,
    }
}

/// The largest relative L2 errors of the hammers' heights, velocities and
/// contact points' displacements in `obs` against the reference `sol`, on
/// the first `window` samples of its `k` contacts.
fn trace_errors(
    obs: &[modal_contact::multi::MultiObservation],
    sol: &reference::Solution,
    window: usize,
    k: usize,
) -> (f64, f64, f64) {
    let (mut ex, mut ev, mut ec) = (0.0f64, 0.0f64, 0.0f64);
    for j in 0..k {
        let x: Vec<f64> = obs[..window].iter().map(|o| o.x_hammer[j]).collect();
        let v: Vec<f64> = obs[..window].iter().map(|o| o.v_hammer[j]).collect();
        let c: Vec<f64> = obs[..window].iter().map(|o| o.x_contact[j]).collect();
        let r = &sol.samples[..window];
        ex = ex.max(rel_l2(
            &x,
            &r.iter().map(|s| pick(s, j, 0)).collect::<Vec<_>>(),
        ));
        ev = ev.max(rel_l2(
            &v,
            &r.iter().map(|s| pick(s, j, 1)).collect::<Vec<_>>(),
        ));
        ec = ec.max(rel_l2(
            &c,
            &r.iter().map(|s| pick(s, j, 2)).collect::<Vec<_>>(),
        ));
    }
    (ex, ev, ec)
}

/// The contact instants of the engine's `switches` against the
/// reference's intervals `ref_iv` on the first `window` samples, per
/// contact: the largest difference \[samples\], each contact's count of
/// contacts in the whole run, and a count that differs within the window.
fn instant_errors(
    switches: &[MultiSwitch],
    ref_iv: &[Vec<Interval>],
    window: usize,
    k: usize,
) -> (f64, Vec<usize>, Option<String>) {
    let mine = intervals_of(switches, k);
    let mut dt = 0.0f64;
    let mut counts = Vec::new();
    let mut count_mismatch = None;
    for j in 0..k {
        let within = |iv: &&Interval| iv.0 <= window as f64;
        let got: Vec<_> = mine[j].iter().filter(within).collect();
        let want: Vec<_> = ref_iv[j].iter().filter(within).collect();
        if got.len() != want.len() {
            count_mismatch = Some(format!(
                "contact {j}: {} contacts in the window against the reference's {} (first: {:?} / {:?})",
                got.len(),
                want.len(),
                got.first(),
                want.first()
            ));
        }
        counts.push(mine[j].len());

        for (a, b) in got.iter().zip(&want) {
            dt = dt.max((a.0 - b.0).abs());
            if let (Some(x), Some(y)) = (a.1, b.1) {
                if x.max(y) <= window as f64 {
                    dt = dt.max((x - y).abs());
                }
            }
        }
    }
    (dt, counts, count_mismatch)
}

/// The largest rise of the energy from one observation to the next in
/// `obs`, relative to its scale (the energy, and the hammers' fall).
fn largest_energy_rise(m: &MultiModel, obs: &[modal_contact::multi::MultiObservation]) -> f64 {
    let k = m.contacts.len();
    let g = m.gravity_m_per_s2;
    let scale = |o: &modal_contact::multi::MultiObservation| {
        o.energy.abs()
            + (0..k)
                .map(|j| {
                    2.0 * m.masses[j.min(m.masses.len() - 1)].mass_kg * g * o.x_hammer[j].abs()
                })
                .sum::<f64>()
    };
    let mut de = 0.0f64;
    for w in obs.windows(2) {
        let s = scale(&w[0]).max(scale(&w[1]));
        de = de.max((w[1].energy - w[0].energy) / s);
    }
    de
}

fn strike(mass_ratio: f64, height: f64, velocity: f64, fc_ratio: f64, zeta: f64) -> Striker {
    Striker {
        mass_ratio,
        height,
        velocity,
        fc_ratio,
        zeta,
    }
}

fn cases() -> Vec<Case> {
    let mut v = Vec::new();
    two_hammer_cases(&mut v);
    heavy_dropped_and_more_hammer_cases(&mut v);
    v
}

/// A closure that pushes a case (name, T60 \[s\], gravity [m/s^2],
/// strikers) to `v`.
fn adder(v: &mut Vec<Case>) -> impl FnMut(&str, Option<f64>, f64, Vec<Striker>) + '_ {
    |name: &str, t60: Option<f64>, gravity: f64, strikers: Vec<Striker>| {
        v.push(Case {
            name: name.into(),
            t60,
            gravity,
            strikers,
        })
    }
}

/// Two light hammers, a few samples apart or at the same instant.
fn two_hammer_cases(v: &mut Vec<Case>) {
    let mut add = adder(v);
    // two hammers a few samples apart, light, elastic and damped
    for (fc, zeta) in [(3.17, 0.0), (31.3, 0.05), (101.7, 1.0), (317.3, 5.0)] {
        add(
            &format!("2 apart f_c {fc}x zeta {zeta}"),
            Some(0.4),
            0.0,
            vec![
                strike(1e-3, 0.0, -1.0, fc, zeta),
                strike(1e-2, 3e-4, -0.8, fc * 1.13, zeta),
            ],
        );
    }
    // both at the same instant, same launch, different points
    add(
        "2 together f_c 31.3x",
        None,
        0.0,
        vec![
            strike(1e-3, 0.0, -1.0, 31.3, 0.0),
            strike(1e-3, 0.0, -1.0, 31.3, 0.0),
        ],
    );
    // the extremes of the one-contact family, two at once
    add(
        "2 together f_c 1013.7x mass 1e-6",
        Some(0.4),
        0.0,
        vec![
            strike(1e-6, 0.0, -1.0, 1013.7, 0.0),
            strike(1e-6, 0.0, -1.0, 1013.7, 0.0),
        ],
    );
    add(
        "2 together critical 101.7x mass 1",
        Some(0.4),
        0.0,
        vec![
            strike(1.0, 0.0, -0.5, 101.7, 1.0),
            strike(1.0, 0.0, -0.5, 101.7, 1.0),
        ],
    );
}

/// Heavy hammers, hammers dropped under gravity, three and four hammers.
fn heavy_dropped_and_more_hammer_cases(v: &mut Vec<Case>) {
    let mut add = adder(v);
    add(
        "2 apart 1013.7x zeta 5 mass 1e3",
        Some(0.25),
        0.0,
        vec![
            strike(1e3, 0.0, -0.1, 1013.7, 5.0),
            strike(1e-3, 2e-4, -1.0, 1013.7, 0.05),
        ],
    );
    // heavy and light
    add(
        "2 heavy + light f_c 101.7x",
        Some(0.25),
        0.0,
        vec![
            strike(1e3, 0.0, -0.1, 101.7, 0.0),
            strike(1e-3, 1e-4, -1.0, 101.7, 0.05),
        ],
    );
    add(
        "2 mass 1 f_c 3.17x zeta 0.05",
        Some(0.1),
        0.0,
        vec![
            strike(1.0, 0.0, -0.5, 3.17, 0.05),
            strike(1.0, 2e-4, -0.5, 3.17, 0.05),
        ],
    );
    // dropped under gravity
    add(
        "2 dropped, 10 g, zeta 1, 101.7x",
        Some(0.4),
        9.81,
        vec![
            strike(0.03, 1e-3, 0.0, 101.7, 1.0),
            strike(0.03, 1.3e-3, 0.0, 101.7, 1.0),
        ],
    );
    // three and four
    add(
        "3 apart f_c 31.3x",
        Some(0.4),
        0.0,
        vec![
            strike(1e-3, 0.0, -1.0, 31.3, 0.05),
            strike(1e-2, 2e-4, -0.8, 35.0, 0.05),
            strike(1e-1, 5e-4, -0.6, 28.0, 0.05),
        ],
    );
    add(
        "4 apart f_c 3.17..317x",
        Some(0.4),
        0.0,
        vec![
            strike(1e-3, 0.0, -1.0, 3.17, 0.0),
            strike(1e-2, 1e-4, -0.9, 31.3, 0.05),
            strike(1e-1, 3e-4, -0.7, 101.7, 1.0),
            strike(1.0, 6e-4, -0.5, 317.3, 5.0),
        ],
    );
}

#[test]
fn several_contacts_match_the_reference_solver() {
    let mut failures = Vec::new();
    println!("| case | contacts | window | x_h | v_h | x_c | instants [samples] | energy rise / bound | evaluations per switch |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let cases = cases();
    // the cases side by side: each is a run of the independent solver
    let outcomes = modal_testkit::parallel::map(&cases, run_case);
    for (case, o) in cases.iter().zip(outcomes) {
        println!(
            "| {} | {:?} | {} | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.1e} / {:.1e} | {:.0} |",
            case.name,
            o.contacts,
            o.window,
            o.err_x,
            o.err_v,
            o.err_c,
            o.dt,
            o.de,
            o.bound,
            o.evaluations_per_switch
        );
        if o.window < MIN_WINDOW {
            failures.push(format!("{}: window {} samples", case.name, o.window));
        }
        if let Some(m) = &o.count_mismatch {
            failures.push(format!("{}: {m}", case.name));
        }
        if o.contacts.contains(&0) {
            failures.push(format!("{}: a hammer never touched", case.name));
        }
        if !(o.err_x <= TOL_TRACE && o.err_v <= TOL_TRACE && o.err_c <= TOL_TRACE) {
            failures.push(format!("{}: traces", case.name));
        }
        if !(o.dt <= TOL_INSTANT) {
            failures.push(format!("{}: instants {:.1e} samples", case.name, o.dt));
        }
        if !(o.de <= o.bound) {
            failures.push(format!("{}: energy rose by {:.1e}", case.name, o.de));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Bad models: a clear error naming the field.
#[test]
fn bad_models_are_refused_with_the_field_named() {
    let base = model(&Case {
        name: String::new(),
        t60: None,
        gravity: 0.0,
        strikers: vec![
            strike(1e-3, 0.0, -1.0, 3.17, 0.0),
            strike(1e-3, 1e-4, -1.0, 3.17, 0.0),
        ],
    });
    let err = |f: &dyn Fn(&mut MultiModel)| {
        let mut m = base.clone();
        f(&mut m);
        CompiledMulti::new(&m, RATE).unwrap_err()
    };
    assert_eq!(err(&|m| m.contacts.clear()), MultiError::ContactCount(0));
    let e = err(&|m| {
        let c = m.contacts[0].clone();
        for j in 0..MAX_SPRINGS {
            let mut c = c.clone();
            c.gap_m = j as f64;
            m.contacts.push(c);
        }
    });
    assert_eq!(e, MultiError::ContactCount(MAX_SPRINGS + 2));
    let e = err(&|m| {
        m.contacts[1].lower = m.contacts[0].lower.clone();
        m.contacts[1].upper = MultiEnd::Mass(0);
    });
    assert_eq!(e, MultiError::SamePoint(0, 1));
    let e = err(&|m| m.contacts[1].upper = m.contacts[1].lower.clone());
    assert!(e.to_string().contains("with itself"), "{e}");
    let e = err(&|m| {
        m.contacts[1].lower = MultiEnd::Wall(0.0);
        m.contacts[1].upper = MultiEnd::Wall(1.0);
    });
    assert!(e.to_string().contains("two walls"), "{e}");
    let e = err(&|m| m.contacts[1].upper = MultiEnd::Mass(7));
    assert!(
        e.to_string().contains("contacts[1]: upper is mass 7"),
        "{e}"
    );
    let e = err(&|m| m.contacts[1].gap_m = -1e-3);
    assert!(e.to_string().contains("pressed in"), "{e}");
    let e = err(&|m| m.masses = vec![m.masses[0]; 2 * MAX_CONTACTS + 1]);
    assert!(
        e.to_string().contains("masses (more than two per contact)"),
        "{e}"
    );
    let e = err(&|m| m.masses[1].mass_kg = -1.0);
    assert!(e.to_string().contains("masses[1].mass_kg"), "{e}");
    let e = err(&|m| m.contacts[0].stiffness_n_per_m = f64::NAN);
    assert!(
        e.to_string().contains("contacts[0].stiffness_n_per_m"),
        "{e}"
    );
    let e = err(&|m| {
        if let MultiEnd::Point(w) = &mut m.contacts[0].lower {
            w.pop();
        }
    });
    assert!(e.to_string().contains("contacts[0].lower.weights"), "{e}");
    let e = err(&|m| m.sigma[2] = -1.0);
    assert!(e.to_string().contains("sigma[2]"), "{e}");
    println!("refused: {e}");
    // over the compile budget: refused at once, with its numbers
    let n = 1000;
    let h0 = hammer(0, &strike(1e-3, 0.0, -1.0, 3.17, 0.0));
    let big = MultiModel::struck(
        (0..n).map(|i| 50.0 + 10.0 * i as f64).collect(),
        vec![1.0; n],
        &(0..4)
            .map(|j| MultiHammer {
                weights: (0..n).map(|i| ((i * (j + 1)) as f64).sin()).collect(),
                ..h0.clone()
            })
            .collect::<Vec<_>>(),
        0.0,
        [(vec![1.0; n], vec![0.0; n]), (vec![0.0; n], vec![1.0; n])],
    );
    let t0 = std::time::Instant::now();
    let e = CompiledMulti::new(&big, RATE).unwrap_err();
    assert!(
        matches!(e, MultiError::OverBudget { phases: 16, .. }),
        "{e}"
    );
    assert!(t0.elapsed().as_secs_f64() < 1.0);
    println!("refused: {e}");
}

/// One hammer on modes of its own: a one-contact scene for the project's
/// one-contact engine (a separate implementation: secular route,
/// hierarchical bases, Hermite certificate, strike from rest).
fn one_contact_scene(
    h: &MultiHammer,
    modes: &[(f64, f64)],
    gravity: f64,
    switching: Switching,
) -> Scene {
    let mut bar = Modal::new("bar", &["a"]);
    for &(f, w) in modes {
        bar = bar.mode(f, Some(0.4), &[w]);
    }
    SceneBuilder::new("one")
        .object(bar)
        .hammer(
            Hammer::new(h.mass_kg)
                .height(h.height_m)
                .velocity(h.velocity_m_per_s)
                .gravity(gravity),
        )
        .contact(
            Contact::new("bar", h.stiffness_n_per_m)
                .point("a")
                .damping(h.damping_n_s_per_m)
                .switching(switching),
        )
        .pickup(Pickup::new("bar", "a"))
        .build()
}

/// Two contacts that cannot interact (each hammer's point moves modes of
/// its own, so the phases split into two independent systems) are two
/// runs of the one-contact engine: each hammer's height and its contact
/// point, sample by sample; switching exactly, and with an offset rod per
/// contact (the one-contact engine's own rod: the same samples decide).
#[test]
fn contacts_that_cannot_interact_are_two_one_contact_runs() {
    for sw in [Switching::Exact, Switching::OffsetRod] {
        cannot_interact(sw);
    }
}

fn cannot_interact(sw: Switching) {
    for (fc, zeta, gravity, heights) in [
        (31.3, 0.0, 0.0, [0.0, 2e-4]),
        (101.7, 0.05, 0.0, [0.0, 0.0]),
        (3.17, 1.0, 9.81, [1e-3, 1.5e-3]),
    ] {
        let sigma = 1000f64.ln() / 0.4;
        let weights = [[0.45, 0.40, 0.0, 0.0], [0.0, 0.0, 0.42, 0.12]];
        let mk = |j: usize| {
            let w = weights[j];
            let me = 1.0 / w.iter().map(|x| x * x).sum::<f64>();
            let m = 0.01 * me;
            let mr = 1.0 / (1.0 / m + 1.0 / me);
            let k = (2.0 * PI * fc * NYQUIST).powi(2) * mr;
            MultiHammer {
                mass_kg: m,
                height_m: heights[j],
                velocity_m_per_s: if gravity > 0.0 { 0.0 } else { -0.8 },
                weights: w.to_vec(),
                stiffness_n_per_m: k,
                damping_n_s_per_m: 2.0 * zeta * (k * mr).sqrt(),
            }
        };
        let hs = [mk(0), mk(1)];
        let m = MultiModel::struck(
            FREQS.to_vec(),
            vec![sigma; 4],
            &hs,
            gravity,
            [(vec![1.0; 4], vec![0.0; 4]), (vec![0.0; 4], vec![1.0; 4])],
        );
        let sc = CompiledMulti::with_switching(&m, RATE, sw).unwrap();
        let mut st = MultiState::new(&sc);
        let singles: Vec<_> = (0..2)
            .map(|j| {
                let modes: Vec<(f64, f64)> = (0..4)
                    .filter(|&i| weights[j][i] != 0.0)
                    .map(|i| (FREQS[i], weights[j][i]))
                    .collect();
                let scene = one_contact_scene(&hs[j], &modes, gravity, sw);
                compile_with(&scene, RATE, Some(sw)).unwrap()
            })
            .collect();
        let mut one: Vec<EngineState> = singles.iter().map(EngineState::new).collect();
        let mut series = vec![[Vec::new(), Vec::new(), Vec::new(), Vec::new()]; 2];
        for _ in 0..SAMPLES {
            st.tick(&sc);
            let o = st.observe(&sc);
            for j in 0..2 {
                one[j].tick(&singles[j]);
                let p = one[j].observe(&singles[j]);
                series[j][0].push(o.x_hammer[j]);
                series[j][1].push(p.x_hammer);
                series[j][2].push(o.x_contact[j]);
                series[j][3].push(p.x_contact);
            }
        }
        for (j, s) in series.iter().enumerate() {
            let (ex, ec) = (rel_l2(&s[0], &s[1]), rel_l2(&s[2], &s[3]));
            println!(
                "{} f_c {fc}x zeta {zeta} g {gravity}: hammer {j}: {} contacts ({}); against the one-contact engine: height {ex:.1e}, contact point {ec:.1e}",
                sw.as_str(),
                st.stats.contacts_started[j],
                one[j].contacts_started,
            );
            assert!(st.stats.contacts_started[j] >= 1);
            assert_eq!(st.stats.contacts_started[j], one[j].contacts_started);
            assert!(ex < 1e-9 && ec < 1e-9, "{ex:e} {ec:e}");
        }
    }
}

/// Random models of 2 to 4 hammers (masses, stiffness, damping, heights,
/// points, gravity): the energy never rises beyond rounding, nothing is
/// not a number, and no sample needs more switches than the cap.
#[test]
fn fuzzed_models_never_gain_energy() {
    for sw in [Switching::Exact, Switching::OffsetRod] {
        fuzzed(sw);
    }
}

/// With the offset rod the energy is observed after each sample's
/// decision too, so the switches' own change is checked; its rounding
/// scale takes the rods' shift of the equilibrium
/// (`modal_testkit::metrics::rod_energy_scale`).
fn fuzzed(sw: Switching) {
    let mut rng = modal_testkit::rng::TestRng(0x5eed);
    let mut worst = 0.0f64;
    let mut switches = 0;
    for case in 0..40 {
        let k = 2 + rng.below(3);
        let n = 2 + rng.below(6);
        let freq: Vec<f64> = (0..n).map(|_| 50.0 * 400f64.powf(rng.unit())).collect();
        let gravity = if rng.below(2) == 0 { 0.0 } else { 9.81 };
        let hammers: Vec<MultiHammer> = (0..k)
            .map(|_| {
                let weights: Vec<f64> = (0..n).map(|_| rng.uniform(-0.8, 0.8)).collect();
                let me = 1.0 / weights.iter().map(|x| x * x).sum::<f64>();
                let m = me * 10f64.powf(rng.uniform(-4.0, 2.0));
                let mr = 1.0 / (1.0 / m + 1.0 / me);
                let fc = NYQUIST * 10f64.powf(rng.uniform(-1.0, 2.5));
                let kk = (2.0 * PI * fc).powi(2) * mr;
                let zeta = [0.0, 0.05, 1.0, 5.0][rng.below(4)];
                MultiHammer {
                    mass_kg: m,
                    height_m: rng.uniform(0.0, 1e-3),
                    velocity_m_per_s: if gravity > 0.0 {
                        0.0
                    } else {
                        -rng.uniform(0.1, 2.0)
                    },
                    weights,
                    stiffness_n_per_m: kk,
                    damping_n_s_per_m: 2.0 * zeta * (kk * mr).sqrt(),
                }
            })
            .collect();
        let m = MultiModel::struck(
            freq,
            (0..n).map(|_| rng.uniform(0.0, 30.0)).collect(),
            &hammers,
            gravity,
            [(vec![1.0; n], vec![0.0; n]), (vec![0.0; n], vec![1.0; n])],
        );
        let sc = match CompiledMulti::with_switching(&m, RATE, sw) {
            Ok(sc) => sc,
            Err(e) => panic!("case {case}: {e}"),
        };
        assert!(sc.growth() - 1.0 < 1e-12, "case {case}: a growing block");
        let mut st = MultiState::new(&sc);
        let bound = 64.0 * sc.max_dim() as f64 * sc.kappa() * U;
        let scale = |o: &modal_contact::multi::MultiObservation| {
            o.energy.abs()
                + (0..k)
                    .map(|j| 2.0 * m.masses[j].mass_kg * gravity * o.x_hammer[j].abs())
                    .sum::<f64>()
        };
        let mut prev = st.observe(&sc);
        for _ in 0..1000 {
            let y = st.tick(&sc);
            assert!(y.iter().all(|v| v.is_finite()), "case {case}");
            let mut looks = vec![st.observe(&sc)];
            let e = prev.energy.abs().max(looks[0].energy.abs());
            let mut rods = rod_energy_scale(&m, &st, e);
            if sw == Switching::OffsetRod {
                st.decide(&sc);
                looks.push(st.observe(&sc));
                rods = rods.max(rod_energy_scale(&m, &st, e));
            }
            for o in looks {
                let rise = (o.energy - prev.energy) / (scale(&o).max(scale(&prev)) + rods);
                worst = worst.max(rise / bound);
                assert!(
                    rise <= bound,
                    "{} case {case}: energy rose {rise:e} > {bound:e}",
                    sw.as_str()
                );
                prev = o;
            }
        }
        assert_eq!(st.stats.capped, 0, "case {case}");
        switches += st.stats.switches;
    }
    println!(
        "{}: 40 random models, {switches} switches: largest energy rise {worst:.2} of its rounding bound",
        sw.as_str()
    );
    assert!(switches > 40);
}

/// The scene file's `[[striker]]`: the example scene makes a two-contact
/// model; the one-contact compiler refuses it with the field named; bad
/// strikers are refused with theirs.
#[test]
fn strikers_in_a_scene_file() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/presets/marimba-two-mallets.toml"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let scene: Scene = Scene::from_toml_str(&text).unwrap();
    let m = MultiModel::from_scene(&scene, RATE).unwrap();
    assert_eq!((m.masses.len(), m.contacts.len()), (2, 2));
    assert_ne!(m.contacts[0].lower, m.contacts[1].lower);
    let e = compile_with(&scene, RATE, None).unwrap_err().to_string();
    assert!(e.contains("striker"), "{e}");
    let bad = |from: &str, to: &str| {
        let t = text.replacen(from, to, 1);
        match Scene::from_toml_str(&t) {
            Err(e) => e.to_string(),
            Ok(s) => s
                .validate()
                .map_or_else(|e| e.to_string(), |_| "valid".into()),
        }
    };
    let e = bad("point = \"left\"", "point = \"nowhere\"");
    assert!(
        e.contains("striker[0].point") && e.contains("nowhere"),
        "{e}"
    );
    let e = bad("point = \"left\"", "point = \"contact\"");
    assert!(
        e.contains("striker[0].point") && e.contains("one point pair"),
        "{e}"
    );
    let e = bad(
        "mass_kg = 0.03\nheight_m = 0.121",
        "mass_kg = -1.0\nheight_m = 0.121",
    );
    assert!(e.contains("striker[0].mass_kg"), "{e}");
    let e = bad(
        "damping_n_s_per_m = 43.4722\n\n[[listener]]",
        "damping_n_s_per_m = 43.4722\nswitching = \"exact\"\n\n[[listener]]",
    );
    assert!(e.contains("switching"), "{e}");
    // the offset rod is a switching method of several contacts too
    let rod = text.replace(
        "point = \"contact\"\nstiffness",
        "point = \"contact\"\nswitching = \"offset-rod\"\nstiffness",
    );
    assert_ne!(rod, text);
    let rod = Scene::from_toml_str(&rod).unwrap();
    rod.validate().unwrap();
    assert_eq!(rod.contact.switching, Some(Switching::OffsetRod));
    let one = &text[text.find("[[striker]]").unwrap()..text.find("[[pickup]]").unwrap()];
    let more = one.replace("\"left\"", "\"pickup\"").repeat(3);
    let four = text.replace("[[pickup]]", &format!("{more}[[pickup]]"));
    let e = match Scene::from_toml_str(&four) {
        Err(e) => e.to_string(),
        Ok(s) => s
            .validate()
            .map_or_else(|e| e.to_string(), |_| "valid".into()),
    };
    assert!(e.contains("striker"), "{e}");
    println!("refused: {e}");
}

/// The scene file's `[[touch]]`: the examples make models of objects,
/// masses and walls in contact, the one-contact compiler refuses them
/// with the field named, and bad touches are refused with theirs.
#[test]
fn touches_in_a_scene_file() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/presets/");
    let load = |name: &str| std::fs::read_to_string(format!("{dir}{name}.toml")).unwrap();
    for (name, modes_of_objects, masses, contacts, phases) in [
        ("ball-between-plates", 2, 1, 2, 4),
        ("wind-chimes", 3, 1, 3, 8),
        // the stick's Hertz law of two pieces: its second piece a touch,
        // a stage of the first (never in contact without it)
        ("snare-pair", 2, 1, 3, 6),
    ] {
        let scene = Scene::from_toml_str(&load(name)).unwrap();
        let m = MultiModel::from_scene(&scene, RATE).unwrap();
        assert_eq!(
            (m.masses.len(), m.contacts.len()),
            (masses, contacts),
            "{name}"
        );
        // every object's modes are in the model, each object's pickups heard
        assert!(m.freq_hz.len() > modes_of_objects, "{name}");
        assert!(m.pickups[0].1.iter().any(|x| *x != 0.0), "{name}");
        let sc = CompiledMulti::new(&m, RATE).unwrap();
        assert_eq!(sc.phases.len(), phases, "{name}");
        let e = compile_with(&scene, RATE, None).unwrap_err().to_string();
        assert!(e.contains("touch: a scene of several contacts"), "{e}");
    }
    let text = load("ball-between-plates");
    bad_touch_keys_are_refused_by_field(&text);
    impossible_touches_are_refused(&text);
}

/// The upper side of the ball-between-plates preset's first touch.
const BALL_UPPER: &str = "upper = { object = \"lid\", point = \"ball\" }";

/// Each of the touch keys of the ball-between-plates preset's text `text`,
/// made wrong, is refused with an error naming the key.
fn bad_touch_keys_are_refused_by_field(text: &str) {
    let bad = |from: &str, to: &str| {
        assert!(text.contains(from), "{from}");
        let t = text.replacen(from, to, 1);
        match Scene::from_toml_str(&t) {
            Err(e) => e.to_string(),
            Ok(s) => s
                .validate()
                .map_or_else(|e| e.to_string(), |_| "valid".into()),
        }
    };
    let upper = BALL_UPPER;
    let cases = [
        (
            upper,
            "upper = { object = \"cap\", point = \"ball\" }",
            "touch[0].upper.object",
            "no object named \"cap\"",
        ),
        (
            upper,
            "upper = { object = \"lid\", point = \"rim\" }",
            "touch[0].upper.point",
            "no point \"rim\"",
        ),
        (
            upper,
            "upper = { object = \"lid\" }",
            "touch[0].upper.point",
            "missing",
        ),
        (
            "lower = { object = \"hammer\" }",
            "lower = { object = \"lid\", point = \"pickup\" }",
            "touch[0].upper.object",
            "in contact with itself",
        ),
        (
            upper,
            "upper = { object = \"hammer\" }",
            "touch[0].upper.object",
            "in contact with itself",
        ),
        (
            "lower = { object = \"hammer\" }",
            "lower = { object = \"hammer\", point = \"face\" }",
            "touch[0].lower.point",
            "no points",
        ),
        (
            upper,
            "upper = { object = \"floor\", point = \"ball\" }",
            "touch[0].upper",
            "one point pair",
        ),
        (
            "gap_m = 0.005",
            "gap_m = 0.0005",
            "touch[0].gap_m",
            "inside",
        ),
        ("gap_m = 0.005", "gap_m = -0.005", "touch[0].gap_m", ""),
        (
            "stiffness_n_per_m = 2.0e6\ndamping_n_s_per_m = 8.0\n\n[[pickup]]",
            "stiffness_n_per_m = -2.0e6\ndamping_n_s_per_m = 8.0\n\n[[pickup]]",
            "touch[0].stiffness_n_per_m",
            "",
        ),
        (
            "gap_m = 0.005",
            "gap_m = 0.005\nsolid = true",
            "",
            "unknown field `solid`",
        ),
    ];
    for (from, to, field, why) in cases {
        let e = bad(from, to);
        println!("refused: {e}");
        assert!(e.contains(field) && e.contains(why), "{to}: {e}");
    }
}

/// In the ball-between-plates preset's text `text`: a wall against a
/// wall, more than four contacts, and a lumped string are refused.
fn impossible_touches_are_refused(text: &str) {
    let upper = BALL_UPPER;
    // a wall against a wall, and more than four contacts
    let walls = text
        .replacen(
            "\n[hammer]",
            "\n[[object]]\nname = \"w1\"\nkind = \"wall\"\n\n[[object]]\nname = \"w2\"\nkind = \"wall\"\n\n[hammer]",
            1,
        )
        .replacen("lower = { object = \"hammer\" }", "lower = { object = \"w1\" }", 1)
        .replacen(upper, "upper = { object = \"w2\" }", 1);
    let e = Scene::from_toml_str(&walls).unwrap_err().to_string();
    assert!(
        e.contains("touch[0].upper") && e.contains("two walls"),
        "{e}"
    );
    let touch =
        &text[text.find("\n[[touch]]").unwrap() + 1..text.find("\n[[pickup]]").unwrap() + 1];
    let mut many = text.to_string();
    for gap in ["0.006", "0.007", "0.008", "0.009"] {
        let t = touch.replace("gap_m = 0.005", &format!("gap_m = {gap}"));
        many = many.replacen("[[pickup]]", &format!("{t}[[pickup]]"), 1);
    }
    let e = Scene::from_toml_str(&many).unwrap_err().to_string();
    assert!(e.contains("touch") && e.contains("6 contacts"), "{e}");
    // a lumped string cannot take part
    let strung = text.replacen(
        "\n[hammer]",
        "\n[[object]]\nname = \"s\"\nkind = \"string\"\nmasses = 4\nmass_kg = 1e-3\nspring_n_per_m = 1e4\npoints = { a = 1 }\n\n[hammer]",
        1,
    )
    .replacen(upper, "upper = { object = \"s\", point = \"a\" }", 1);
    let e = Scene::from_toml_str(&strung).unwrap_err().to_string();
    assert!(
        e.contains("touch[0].upper.object") && e.contains("lumped"),
        "{e}"
    );
}

/// Object B's modes \[Hz\] in the networks (object A's are [`FREQS`]).
const FREQ_B: [f64; 3] = [310.0, 1400.0, 5200.0];

/// Weights on object A's modes, none on object B's.
fn on_a(w: &[f64; 4]) -> Vec<f64> {
    let mut v = w.to_vec();
    v.extend([0.0; 3]);
    v
}

/// Weights on object B's modes, none on object A's.
fn on_b(w: [f64; 3]) -> Vec<f64> {
    let mut v = vec![0.0; 4];
    v.extend(w);
    v
}

/// Effective mass \[kg\] of a point of weights `w` on unit modal masses.
fn effective_mass(w: &[f64]) -> f64 {
    1.0 / w.iter().map(|x| x * x).sum::<f64>()
}

/// A contact law (stiffness [N/m], damping [N s/m]) at `fc` times Nyquist
/// and damping ratio `zeta` for two sides of effective masses `ma`, `mb`
/// \[kg\].
fn contact_law(fc: f64, zeta: f64, ma: f64, mb: f64) -> (f64, f64) {
    let mr = 1.0 / (1.0 / ma + 1.0 / mb);
    let k = (2.0 * PI * fc * NYQUIST).powi(2) * mr;
    (k, 2.0 * zeta * (k * mr).sqrt())
}

/// A network of [`networks_match_the_reference_solver`]: object A (struck
/// at its point 0 by mass 0) and object B, more masses and links.
struct Net {
    name: &'static str,
    /// The modes' T60 \[s\] (`None`: undamped).
    t60: Option<f64>,
    /// Gravity on the masses [m/s^2].
    gravity: f64,
    /// Each mass's (mass \[kg\], height \[m\], velocity [m/s]).
    masses: Vec<(f64, f64, f64)>,
    /// (lower, upper, gap, fc, zeta); contact 0 is mass 0 on A's point 0
    links: Vec<(MultiEnd, MultiEnd, f64, f64, f64)>,
    /// Contact 0's frequency, in times Nyquist.
    fc0: f64,
}

/// The networks compared with the reference.
fn networks() -> Vec<Net> {
    let wa1 = on_a(&WEIGHTS[1]);
    let wb = on_b([0.9, -0.6, 0.45]);
    let me_a = effective_mass(&on_a(&WEIGHTS[0]));
    vec![
        Net {
            name: "object on object 31.3x",
            t60: Some(0.5),
            gravity: 0.0,
            masses: vec![(me_a, 0.0, -1.0)],
            links: vec![(
                MultiEnd::Point(wb.clone()),
                MultiEnd::Point(wa1.clone()),
                2e-6,
                31.3,
                0.05,
            )],
            fc0: 3.17,
        },
        Net {
            name: "object on object 317x critical",
            t60: None,
            gravity: 0.0,
            masses: vec![(me_a, 0.0, -1.0)],
            links: vec![(
                MultiEnd::Point(wb.clone()),
                MultiEnd::Point(wa1.clone()),
                1e-6,
                317.3,
                1.0,
            )],
            fc0: 31.3,
        },
        Net {
            name: "ball between two objects, 10 g",
            t60: Some(0.3),
            gravity: 98.1,
            masses: vec![(0.1 * me_a, 5e-4, -1.5)],
            links: vec![(
                MultiEnd::Mass(0),
                MultiEnd::Point(wb.clone()),
                1e-3,
                101.7,
                0.1,
            )],
            fc0: 101.7,
        },
        Net {
            name: "mass falling on a hammer",
            t60: Some(0.5),
            gravity: 0.0,
            masses: vec![(me_a, 0.0, -0.5), (0.3 * me_a, 2e-4, -1.5)],
            links: vec![(MultiEnd::Mass(0), MultiEnd::Mass(1), 0.0, 31.3, 0.2)],
            fc0: 3.17,
        },
        Net {
            name: "object bottoming on a wall 101.7x",
            t60: Some(0.5),
            gravity: 0.0,
            masses: vec![(me_a, 0.0, -1.0)],
            links: vec![(
                MultiEnd::Wall(-2e-5),
                MultiEnd::Point(wa1.clone()),
                0.0,
                101.7,
                2.0,
            )],
            fc0: 3.17,
        },
    ]
    .into_iter()
    .chain(law_networks())
    .collect()
}

/// The networks of a contact law of three pieces (docs/design.md,
/// "Stiffening contacts"): two more springs between the hammer and its
/// point, each `(gap, fc, zeta)`, touching past its breakpoint.
fn law_networks() -> Vec<Net> {
    let law = |name, pieces: [(f64, f64, f64); 2]| Net {
        name,
        t60: Some(0.5),
        gravity: 0.0,
        masses: vec![(effective_mass(&on_a(&WEIGHTS[0])), 0.0, -1.0)],
        links: pieces
            .iter()
            .map(|&(gap, fc, zeta)| {
                let point = MultiEnd::Point(on_a(&WEIGHTS[0]));
                (point, MultiEnd::Mass(0), gap, fc, zeta)
            })
            .collect(),
        fc0: 3.17,
    };
    vec![
        // the mass reaches about 2.3 um
        law(
            "stiffening law, three pieces",
            [(0.5e-6, 4.0, 0.02), (1.0e-6, 6.0, 0.02)],
        ),
        // its last piece made stiff, at 317x Nyquist and damped (a hard
        // core under a soft felt)
        law(
            "stiffening law, last piece 317x",
            [(0.5e-6, 4.0, 0.02), (0.8e-6, 317.3, 0.3)],
        ),
    ]
}

/// The network `net` as a model of the engine and as the reference's.
fn network_models(net: &Net) -> (MultiModel, reference::Model) {
    let n = FREQS.len() + FREQ_B.len();
    let wa0 = on_a(&WEIGHTS[0]);
    let me_a = effective_mass(&wa0);
    let side_mass = |e: &MultiEnd| match e {
        MultiEnd::Point(w) => effective_mass(w),
        MultiEnd::Mass(j) => net.masses[*j].0,
        MultiEnd::Wall(_) => f64::INFINITY,
    };
    let (k0, c0) = contact_law(net.fc0, 0.05, net.masses[0].0, me_a);
    let mut contacts = vec![modal_contact::multi::MultiContact {
        lower: MultiEnd::Point(wa0.clone()),
        upper: MultiEnd::Mass(0),
        gap_m: 0.0,
        stiffness_n_per_m: k0,
        damping_n_s_per_m: c0,
    }];
    for (lo, up, gap, fc, zeta) in &net.links {
        let (k, c) = contact_law(*fc, *zeta, side_mass(lo), side_mass(up));
        contacts.push(modal_contact::multi::MultiContact {
            lower: lo.clone(),
            upper: up.clone(),
            gap_m: *gap,
            stiffness_n_per_m: k,
            damping_n_s_per_m: c,
        });
    }
    let sigma = net.t60.map_or(0.0, |t| 1000f64.ln() / t);
    let mut freq = FREQS.to_vec();
    freq.extend(FREQ_B);
    let m = MultiModel {
        freq_hz: freq.clone(),
        sigma: vec![sigma; n],
        masses: net
            .masses
            .iter()
            .map(
                |&(mass_kg, height_m, velocity_m_per_s)| modal_contact::multi::MultiMass {
                    mass_kg,
                    height_m,
                    velocity_m_per_s,
                },
            )
            .collect(),
        contacts: contacts.clone(),
        gravity_m_per_s2: net.gravity,
        pickups: [(vec![1.0; n], vec![0.0; n]), (vec![0.0; n], vec![1e-3; n])],
    };
    let rh = |&(mass_kg, height_m, velocity_m_per_s): &(f64, f64, f64)| reference::Hammer {
        mass_kg,
        height_m,
        velocity_m_per_s,
        gravity_m_per_s2: net.gravity,
    };
    let end = |e: &MultiEnd| match e {
        MultiEnd::Point(w) => reference::End::Point(w.clone()),
        MultiEnd::Mass(j) => reference::End::Mass(*j),
        MultiEnd::Wall(h) => reference::End::Wall(*h),
    };
    let rm = reference::Model {
        modes: freq
            .iter()
            .zip(&wa0)
            .map(|(&freq_hz, &weight)| reference::Mode {
                freq_hz,
                t60_s: net.t60,
                weight,
            })
            .collect(),
        hammer: rh(&net.masses[0]),
        contact: reference::Contact {
            stiffness_n_per_m: k0,
            damping_n_s_per_m: c0,
        },
        back: None,
        extra: vec![],
        masses: net.masses[1..].iter().map(rh).collect(),
        links: contacts[1..]
            .iter()
            .map(|c| reference::Link {
                lower: end(&c.lower),
                upper: end(&c.upper),
                gap_m: c.gap_m,
                contact: reference::Contact {
                    stiffness_n_per_m: c.stiffness_n_per_m,
                    damping_n_s_per_m: c.damping_n_s_per_m,
                },
            })
            .collect(),
    };
    (m, rm)
}

/// Push to `failures` what the outcome `o` of network `name` fails.
fn network_failures(name: &str, o: &Outcome, failures: &mut Vec<String>) {
    if o.window < MIN_WINDOW {
        failures.push(format!("{}: window {}", name, o.window));
    }
    if let Some(e) = &o.count_mismatch {
        failures.push(format!("{}: {e}", name));
    }
    if o.err_x.max(o.err_v).max(o.err_c) > TOL_TRACE {
        failures.push(format!(
            "{}: traces {:e} {:e} {:e}",
            name, o.err_x, o.err_v, o.err_c
        ));
    }
    if o.dt > TOL_INSTANT {
        failures.push(format!("{}: instants {:e} samples", name, o.dt));
    }
    if o.de > o.bound {
        failures.push(format!("{}: energy rose {:e}", name, o.de));
    }
    if o.contacts.contains(&0) {
        failures.push(format!("{}: a contact never closed {:?}", name, o.contacts));
    }
}

/// Contacts between two objects, a mass between two objects, a mass on a
/// mass, an object on a wall, a contact law of three pieces, against the reference solver's links (its
/// own model of the same numbers: physical coordinates, double-double
/// exponentials, bisection): every contact's two sides and instants on the
/// window where the reference and its twin agree, and the energy.
#[test]
fn networks_match_the_reference_solver() {
    let mut failures = vec![];
    println!("| network | contacts | window | x upper | v upper | x lower | instants [samples] | energy rise / bound |");
    println!("|---|---|---|---|---|---|---|---|");
    for net in &networks() {
        let (m, rm) = network_models(net);
        let o = compare(net.name, &m, &rm);
        println!(
            "| {} | {:?} | {} | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.1e} / {:.1e} |",
            net.name, o.contacts, o.window, o.err_x, o.err_v, o.err_c, o.dt, o.de, o.bound
        );
        network_failures(net.name, &o, &mut failures);
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Every preset of modes (geometry and material included, the modal
/// mallet joined) as a one-contact model of the several-contact engine
/// against the one-contact engine (its own compiler, secular route,
/// structured switches and certified search): the output, the hammer and
/// the contact point sample by sample, and the same contacts.
#[test]
fn one_contact_presets_match_the_one_contact_engine() {
    for sw in [Switching::Exact, Switching::OffsetRod] {
        presets_match(sw);
    }
}

fn presets_match(sw: Switching) {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/presets/");
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    names.sort();
    let mut compared = 0;
    for path in names {
        let scene = Scene::from_toml_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let name = scene.name.clone();
        if scene.several_contacts() {
            // a kit: the one-contact engine does not run it
            continue;
        }
        let m = match MultiModel::from_scene(&scene, RATE) {
            Ok(m) => m,
            Err(e) => {
                // lumped strings are not modal objects, and a driven
                // contact is the one-contact engine's: refused by name
                println!("{name}: not a several-contact scene ({e})");
                let e = e.to_string();
                assert!(
                    e.contains("lumped") || e.starts_with("drive"),
                    "{name}: {e}"
                );
                continue;
            }
        };
        let sc = CompiledMulti::with_switching(&m, RATE, sw).unwrap();
        let one = compile_with(&scene, RATE, Some(sw)).unwrap();
        let mut a = MultiState::new(&sc);
        let mut b = EngineState::new(&one);
        let n = (0.25 * RATE) as usize;
        let mut s = [(); 6].map(|_| Vec::with_capacity(n));
        let mut in_a = 0;
        let mut in_b = 0;
        let (mut was_a, mut was_b) = (false, false);
        for _ in 0..n {
            let ya = a.tick(&sc);
            let yb = b.tick(&one);
            let (oa, ob) = (a.observe(&sc), b.observe(&one));
            s[0].push(ya[0] + ya[1]);
            s[1].push(yb[0] + yb[1]);
            s[2].push(oa.x_hammer[0]);
            s[3].push(ob.x_hammer);
            s[4].push(oa.x_contact[0]);
            s[5].push(ob.x_contact);
            let (ca, cb) = (oa.active & 1 != 0, ob.in_contact);
            in_a += usize::from(ca && !was_a);
            in_b += usize::from(cb && !was_b);
            (was_a, was_b) = (ca, cb);
        }
        let (eo, ex, ec) = (
            rel_l2(&s[0], &s[1]),
            rel_l2(&s[2], &s[3]),
            rel_l2(&s[4], &s[5]),
        );
        println!(
            "{} {name}: {} modes, {in_a} contacts ({in_b}); output {eo:.1e}, hammer {ex:.1e}, contact point {ec:.1e}",
            sw.as_str(),
            m.freq_hz.len()
        );
        assert_eq!(in_a, in_b, "{name}");
        assert!(in_a >= 1, "{name}");
        assert!(
            eo < 1e-9 && ex < 1e-9 && ec < 1e-9,
            "{name}: {eo:e} {ex:e} {ec:e}"
        );
        compared += 1;
    }
    assert!(compared >= 9, "{compared}");
}

/// A modal mallet (the marimba-rubber-mallet preset's chain) with several
/// contacts: with a second mallet that arrives 100 ms in, the render is
/// the one-contact engine's of the preset until the second mallet's first
/// contact, then not; and the mallet's face as a touch's side: the mallet
/// thrown up into a ceiling is the mirror image of the one-contact
/// engine's mallet dropped on a floor (face `x_h + psi . a` on both
/// sides of a contact, not only `[contact]`'s).
#[test]
fn a_modal_mallet_takes_several_contacts() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/presets/marimba-rubber-mallet.toml"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let striker = "[[striker]]\nmass_kg = 0.03\nheight_m = 0.2\nvelocity_m_per_s = -2.0\n\
                   point = \"pickup\"\nstiffness_n_per_m = 1.5e6\ndamping_n_s_per_m = 37.5\n\n";
    let two = text.replacen("\n[[pickup]]", &format!("\n{striker}[[pickup]]"), 1);
    let scene = Scene::from_toml_str(&two).unwrap();
    let m = MultiModel::from_scene(&scene, RATE).unwrap();
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let one_scene = Scene::from_toml_str(&text).unwrap();
    let one = compile_with(&one_scene, RATE, Some(Switching::Exact)).unwrap();
    let (mut a, mut b) = (MultiState::new(&sc), EngineState::new(&one));
    a.record(true);
    let n = (0.3 * RATE) as usize;
    let (mut ya, mut yb) = (vec![], vec![]);
    let mut prev = a.observe(&sc);
    let mut worst = 0.0f64;
    for _ in 0..n {
        let y = a.tick(&sc);
        ya.push(y[0] + y[1]);
        let y = b.tick(&one);
        yb.push(y[0] + y[1]);
        let o = a.observe(&sc);
        worst = worst.max((o.energy - prev.energy) / prev.energy.abs());
        prev = o;
    }
    let arrive = a
        .switches
        .iter()
        .find(|s| s.contact == 1)
        .map(|s| (s.time_s * RATE) as usize)
        .expect("the second mallet strikes");
    let before = rel_l2(&ya[..arrive], &yb[..arrive]);
    let after = rel_l2(&ya[arrive..], &yb[arrive..]);
    println!(
        "modal mallet and a second mallet: contacts {:?}, second mallet at sample {arrive}; \
         against the one-contact engine before it {before:.1e}, after {after:.1e}; energy rose at most {worst:.1e}",
        a.stats.contacts_started
    );
    assert!((4400..4420).contains(&arrive), "{arrive}");
    assert!(before < 1e-9, "{before:e}");
    assert!(after > 1e-2, "{after:e}");
    assert!(worst < 1e-12, "{worst:e}");

    // the mirror: mallet at 0 thrown up at 2 m/s into a ceiling 3 mm up
    // (a touch: hammer below, wall above), the bar far below and left
    // behind; against the one-contact mallet dropped from 3 mm on a floor
    // and through a touch at another point of the mallet (its grip), the
    // one-contact mallet whose face is that point
    for point in [None, Some("grip")] {
        mirror(&text, point);
    }
    // a point the mallet does not have
    let bad = text.replacen(
        "\n[[pickup]]",
        "\n[[object]]\nname = \"lid\"\nkind = \"wall\"\n\n[[touch]]\n\
         lower = { object = \"hammer\", point = \"tip\" }\nupper = { object = \"lid\" }\n\
         gap_m = 0.01\nstiffness_n_per_m = 1e6\n\n[[pickup]]",
        1,
    );
    let e = Scene::from_toml_str(&bad).unwrap_err().to_string();
    assert!(
        e.contains("touch[0].lower.point") && e.contains("no point \"tip\""),
        "{e}"
    );
}

/// The mallet at 0 thrown up at 2 m/s into a ceiling 3 mm up (a touch:
/// the hammer's face, or its mallet's `point`, below; a wall above), the
/// bar far below and left behind; against the one-contact mallet touching
/// with that point dropped from 3 mm on a floor, until the mallet, back
/// from the ceiling, reaches the bar it left.
fn mirror(text: &str, point: Option<&str>) {
    let gap = 0.003;
    let side = match point {
        Some(p) => format!("{{ object = \"hammer\", point = \"{p}\" }}"),
        None => "{ object = \"hammer\" }".to_string(),
    };
    let up = text
        .replacen(
            "height_m = 0.001\nvelocity_m_per_s = -2.0",
            "height_m = 0.0\nvelocity_m_per_s = 2.0",
            1,
        )
        .replacen(
            "\n[hammer]",
            "\n[[object]]\nname = \"ceiling\"\nkind = \"wall\"\n\n[hammer]",
            1,
        )
        .replacen(
            "\n[[pickup]]",
            &format!(
                "\n[[touch]]\nlower = {side}\nupper = {{ object = \"ceiling\" }}\n\
                 gap_m = {gap}\nstiffness_n_per_m = 1.5e6\ndamping_n_s_per_m = 37.5\n\n[[pickup]]"
            ),
            1,
        );
    let down = text
        .replacen("height_m = 0.001", &format!("height_m = {gap}"), 1)
        .replacen(
            "point = \"cap\"",
            &format!("point = \"{}\"", point.unwrap_or("cap")),
            1,
        )
        .replacen(
            "\n[hammer]",
            "\n[[object]]\nname = \"floor\"\nkind = \"wall\"\n\n[hammer]",
            1,
        )
        .replacen(
            "object = \"bar\"\npoint = \"contact\"",
            "object = \"floor\"",
            1,
        );
    let su = Scene::from_toml_str(&up).unwrap();
    let sd = Scene::from_toml_str(&down).unwrap();
    let mu = MultiModel::from_scene(&su, RATE).unwrap();
    let scu = CompiledMulti::new(&mu, RATE).unwrap();
    let od = compile_with(&sd, RATE, Some(Switching::Exact)).unwrap();
    let (mut a, mut b) = (MultiState::new(&scu), EngineState::new(&od));
    let (mut xa, mut xb) = (vec![], vec![]);
    let (mut ca, mut cb) = (0, 0);
    loop {
        a.tick(&scu);
        b.tick(&od);
        let (oa, ob) = (a.observe(&scu), b.observe(&od));
        if oa.active & 1 != 0 {
            break;
        }
        // the touch's lower side is the mallet's rigid height
        xa.push(gap - oa.x_contact[1]);
        xb.push(ob.x_hammer);
        ca += usize::from(oa.active & 2 != 0);
        cb += usize::from(ob.in_contact);
    }
    let e = rel_l2(&xa, &xb);
    println!(
        "modal mallet's {} into a ceiling against onto a floor: {} samples, {ca} / {cb} in contact, heights {e:.1e}",
        point.unwrap_or("face"),
        xa.len()
    );
    assert!(ca > 0 && ca == cb, "{ca} {cb}");
    assert!(e < 1e-9, "{e:e}");
}

/// The offset rod per contact against its closed form: two masses, each
/// dropped on a wall of its own (one contact of about 14 samples, one 1000
/// times Nyquist, far shorter than a sample), no gravity. A mass flies
/// straight until the first sample at which it is below its wall; there
/// its rod takes that penetration (the spring starts unstretched) and the
/// mass moves as a damped oscillator about where it entered, `y(t) = (v /
/// omega_d) e^(-zeta omega t) sin(omega_d t)`, until the first sample with
/// `y >= 0` (`p - d <= 0`), where the spring is cut and it flies on at
/// that sample's velocity (for the stiff one, whatever the sampled
/// oscillation's phase gives: the offset rod's first-order behaviour,
/// docs/numerics.md section 7). Every sample's height and every rod agree
/// with this to rounding: 1e-11 of the largest height, as the stiff
/// oscillation's phase over a sample (`omega h`, about 3000 rad) is itself
/// known to `omega h u`, which the flight's velocity carries on.
#[test]
fn offset_rods_follow_the_closed_form() {
    // (mass, height, velocity, stiffness, damping ratio)
    let cases = [
        (0.01, 1.03e-3, -1.0, 1e6, 0.1),
        (
            0.05,
            2.31e-3,
            -0.7,
            0.05 * (2.0 * PI * 1000.3817 * NYQUIST).powi(2),
            0.0,
        ),
    ];
    let m = masses_on_walls(&cases);
    let sc = CompiledMulti::with_switching(&m, RATE, Switching::OffsetRod).unwrap();
    let mut st = MultiState::new(&sc);
    let n = 400;
    let want: Vec<(Vec<f64>, Vec<f64>)> = cases.iter().map(|&c| rod_closed_form(c, n)).collect();
    let o = st.observe(&sc);
    let mut got = [vec![o.x_hammer[0]], vec![o.x_hammer[1]]];
    let mut rods = [Vec::new(), Vec::new()];
    for _ in 0..n {
        let before = [st.rod(0), st.rod(1)];
        st.tick(&sc);
        let o = st.observe(&sc);
        for j in 0..2 {
            got[j].push(o.x_hammer[j]);
            // a new rod: the decision of the sample just run entered
            if st.rod(j) != before[j] && st.rod(j) != 0.0 {
                rods[j].push(st.rod(j));
            }
        }
    }
    for j in 0..2 {
        let scale = want[j].0.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let err = got[j]
            .iter()
            .zip(&want[j].0)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale;
        let rod_err = rods[j]
            .iter()
            .zip(&want[j].1)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale;
        println!(
            "mass {j}: height against the closed form {err:.1e} of its largest; {} rods, {rod_err:.1e} off",
            rods[j].len()
        );
        assert!(err < 1e-11, "mass {j}: {err:e}");
        assert_eq!(rods[j].len(), want[j].1.len(), "mass {j}");
        assert!(rod_err < 1e-12, "mass {j}: {rod_err:e}");
        assert_eq!(st.stats.contacts_started[j], rods[j].len() as u64);
    }
}

/// One mass per case `(mass, height, velocity, stiffness, damping ratio)`
/// above a wall at 0 of its own, no gravity, next to one 440 Hz mode.
fn masses_on_walls(cases: &[(f64, f64, f64, f64, f64)]) -> MultiModel {
    use modal_contact::multi::{MultiContact, MultiMass};
    MultiModel {
        freq_hz: vec![440.0],
        sigma: vec![0.0],
        masses: cases
            .iter()
            .map(|c| MultiMass {
                mass_kg: c.0,
                height_m: c.1,
                velocity_m_per_s: c.2,
            })
            .collect(),
        contacts: cases
            .iter()
            .enumerate()
            .map(|(j, c)| MultiContact {
                lower: MultiEnd::Wall(0.0),
                upper: MultiEnd::Mass(j),
                gap_m: 0.0,
                stiffness_n_per_m: c.3,
                damping_n_s_per_m: 2.0 * c.4 * (c.3 * c.0).sqrt(),
            })
            .collect(),
        gravity_m_per_s2: 0.0,
        pickups: [(vec![1.0], vec![0.0]), (vec![0.0], vec![1.0])],
    }
}

/// The offset rods' closed form for one mass `(mass, height, velocity,
/// stiffness, damping ratio)` on a wall, sample by sample for `n` samples,
/// each piece from where it began: the heights, and the rods' lengths.
fn rod_closed_form(
    (mass, x0, v0, k, zeta): (f64, f64, f64, f64, f64),
    n: usize,
) -> (Vec<f64>, Vec<f64>) {
    let h = 1.0 / RATE;
    let wn = (k / mass).sqrt();
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let osc = |t: f64| {
        let e = (-zeta * wn * t).exp();
        let (s, c) = (wd * t).sin_cos();
        // unit initial velocity
        (e * s / wd, e * (c - zeta * wn / wd * s))
    };
    // piece: (start sample, start height, start velocity, in contact)
    let (mut start, mut xs0, mut vs0, mut inside) = (0usize, x0, v0, false);
    let (mut xs, mut rods) = (Vec::with_capacity(n + 1), Vec::new());
    let at = |i: usize, start: usize, xs0: f64, vs0: f64, inside: bool| -> (f64, f64) {
        let t = (i - start) as f64 * h;
        if inside {
            let (y, yv) = osc(t);
            (xs0 + vs0 * y, vs0 * yv)
        } else {
            (xs0 + vs0 * t, vs0)
        }
    };
    for i in 0..=n {
        let (x, v) = at(i, start, xs0, vs0, inside);
        xs.push(x);
        // the decision at sample i
        if inside && x - xs0 >= 0.0 {
            (start, xs0, vs0, inside) = (i, x, v, false);
        } else if !inside && x < 0.0 {
            rods.push(-x);
            (start, xs0, vs0, inside) = (i, x, v, true);
        }
    }
    println!(
        "mass {mass} kg, {:.3e} Hz contact: {} rods, the first {:.3e} m",
        wn / (2.0 * PI),
        rods.len(),
        rods[0]
    );
    (xs, rods)
}

/// A striker may be a modal mallet (`[[striker]] mallet = { object, point
/// }`, as `hammer.object` and `hammer.point` make the hammer one): the
/// marimba-rubber-mallet preset with its chain mallet moved to a striker
/// (the `[hammer]` a point mass parked 0.5 m above another point, still,
/// never arriving) is the one-contact engine's render of the preset (a
/// separate implementation: the mallet's modes joined to the bar's, the
/// secular route), sample by sample: the output, the mallet's height and
/// the contact point (the bar's displacement less the mallet's face
/// modes), and the same contacts; the instrument's Hammer mass scales the
/// chain with its striker. Bad mallets are refused with the field named.
#[test]
fn a_striker_may_be_a_modal_mallet() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/presets/marimba-rubber-mallet.toml"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let hammer = "[hammer]\nmass_kg = 0.034\nheight_m = 0.001\nvelocity_m_per_s = -2.0\n\
                  gravity_m_per_s2 = 0.0\nobject = \"mallet\"\npoint = \"cap\"\n";
    assert!(text.contains(hammer));
    let striker = "[[striker]]\nmass_kg = 0.034\nheight_m = 0.001\nvelocity_m_per_s = -2.0\n\
                   point = \"contact\"\nstiffness_n_per_m = 1.5e6\ndamping_n_s_per_m = 37.5\n\
                   mallet = { object = \"mallet\", point = \"cap\" }\n\n";
    let moved = text
        .replace(
            hammer,
            "[hammer]\nmass_kg = 0.03\nheight_m = 0.5\nvelocity_m_per_s = 0.0\n",
        )
        .replace(
            "point = \"contact\"\nstiffness",
            "point = \"pickup\"\nstiffness",
        )
        .replacen("\n[[pickup]]", &format!("\n{striker}[[pickup]]"), 1);
    let scene = Scene::from_toml_str(&moved).unwrap();
    let m = MultiModel::from_scene(&scene, RATE).unwrap();
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let one = compile_with(
        &Scene::from_toml_str(&text).unwrap(),
        RATE,
        Some(Switching::Exact),
    )
    .unwrap();
    let (mut a, mut b) = (MultiState::new(&sc), EngineState::new(&one));
    let n = (0.25 * RATE) as usize;
    let mut s = [(); 6].map(|_| Vec::with_capacity(n));
    let (mut in_b, mut was_b) = (0u64, false);
    for _ in 0..n {
        let (ya, yb) = (a.tick(&sc), b.tick(&one));
        let (oa, ob) = (a.observe(&sc), b.observe(&one));
        s[0].push(ya[0] + ya[1]);
        s[1].push(yb[0] + yb[1]);
        s[2].push(oa.x_hammer[1]);
        s[3].push(ob.x_hammer);
        s[4].push(oa.x_contact[1]);
        s[5].push(ob.x_contact);
        in_b += u64::from(ob.in_contact && !was_b);
        was_b = ob.in_contact;
    }
    let (eo, ex, ec) = (
        rel_l2(&s[0], &s[1]),
        rel_l2(&s[2], &s[3]),
        rel_l2(&s[4], &s[5]),
    );
    println!(
        "the rubber mallet as a striker: {} modes, contacts {:?} ({in_b}); against the one-contact engine: output {eo:.1e}, mallet {ex:.1e}, contact point {ec:.1e}",
        m.freq_hz.len(),
        &a.stats.contacts_started[..2]
    );
    assert_eq!(a.stats.contacts_started[0], 0, "the parked hammer");
    assert_eq!(a.stats.contacts_started[1], in_b);
    assert!(in_b >= 3, "the shaft brings the head back: {in_b}");
    assert!(eo < 1e-9 && ex < 1e-9 && ec < 1e-9, "{eo:e} {ex:e} {ec:e}");
    hammer_mass_scales_the_striker_chain(&scene);
    bad_striker_mallets_are_refused(&moved);
}

/// The instrument's Hammer mass scales the chain with its striker in
/// `scene` (the chain's mass is the striker's rigid mass: a mismatch is
/// refused).
fn hammer_mass_scales_the_striker_chain(scene: &Scene) {
    let params = modal_contact::instrument::InstrumentParams {
        scene: modal_contact::instrument::SceneParams {
            hammer_mass_factor: 1.7,
            ..Default::default()
        },
        ..Default::default()
    };
    let heavier = modal_contact::instrument::scene_for(scene, &params);
    heavier.validate().unwrap();
    assert!((heavier.striker[0].mass_kg - 1.7 * 0.034).abs() < 1e-15);
}

/// In `moved` (the rubber-mallet preset with its mallet on a striker), a
/// bad striker mallet is refused with the field named.
fn bad_striker_mallets_are_refused(moved: &str) {
    let bad = |from: &str, to: &str| -> String {
        let t = moved.replacen(from, to, 1);
        assert_ne!(t, moved, "{from}");
        match Scene::from_toml_str(&t) {
            Err(e) => e.to_string(),
            Ok(s) => s
                .validate()
                .map_or_else(|e| e.to_string(), |_| "valid".into()),
        }
    };
    let m = "mallet = { object = \"mallet\", point = \"cap\" }";
    for (to, field, says) in [
        (
            "mallet = { object = \"nowhere\", point = \"cap\" }",
            "striker[0].mallet.object",
            "no object",
        ),
        (
            "mallet = { object = \"bar\", point = \"contact\" }",
            "striker[0].mallet.object",
            "struck object",
        ),
        (
            "mallet = { object = \"mallet\", point = \"tip\" }",
            "striker[0].mallet.point",
            "no point",
        ),
        (
            "mallet = { object = \"mallet\" }",
            "striker[0].mallet.point",
            "missing",
        ),
    ] {
        let e = bad(m, to);
        assert!(e.contains(field) && e.contains(says), "{to}: {e}");
    }
    let e = bad(
        "mass_kg = 0.034\nheight_m = 0.001\nvelocity_m_per_s = -2.0\npoint",
        "mass_kg = 0.05\nheight_m = 0.001\nvelocity_m_per_s = -2.0\npoint",
    );
    assert!(
        e.contains("striker[0].mass_kg") && e.contains("chain"),
        "{e}"
    );
    // the hammer's mallet and a striker's are two objects
    let e = bad(
        "[hammer]\nmass_kg = 0.03\n",
        "[hammer]\nmass_kg = 0.034\nobject = \"mallet\"\npoint = \"cap\"\n",
    );
    assert!(
        e.contains("striker[0].mallet.object") && e.contains("another mallet"),
        "{e}"
    );
    // a touch on a striker's mallet
    let touch = "[[touch]]\nlower = { object = \"mallet\", point = \"grip\" }\n\
                 upper = { object = \"hammer\" }\nstiffness_n_per_m = 1e5\n\n[[pickup]]";
    let e = bad("[[pickup]]", touch);
    assert!(
        e.contains("striker[0].mallet.object") && e.contains("touch"),
        "{e}"
    );
    println!("refused: {e}");
}
