//! A strike on an object at rest takes both switches in O(N): the entry
//! skips the product with the zero object state, and the release writes the
//! free state the compiler stored (`compile::rest`; docs/numerics.md, "A
//! strike on an object at rest"). Checked here against a closed form (the
//! release instant of a hammer on a wall) and against the dense change of
//! basis it replaces, on every preset and stability case: same samples to
//! rounding, the same energy, no energy gain at the release. The independent
//! solver's comparisons (`tests/stiff.rs`, `tests/closed_forms.rs`) run on
//! the default engine, so they check this path too.

use modal_contact::compile::{compile_one, compile_with, CompiledScene};
use modal_contact::engine::{EngineState, ROOT_ULPS};
use modal_contact::presets;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::scenes::{c_for, wall_strike, ModalStrike, RATE};
use modal_testkit::stability;

#[test]
fn the_release_of_a_hammer_on_a_wall_is_half_a_damped_period() {
    for (m, k, zeta) in [
        (0.01, 1e6, 0.0),
        (0.01, 1e6, 0.3),
        (0.5, 2e4, 0.9),
        (1e-4, 1e9, 0.05),
    ] {
        let c = c_for(m, k, zeta);
        let sc = compile_one(&wall_strike(m, k, c, 0.0, -1.0), RATE).unwrap();
        let r = sc.rest.as_ref().expect("a wall strike has a rest release");
        let sigma = c / (2.0 * m);
        let wd = (k / m - sigma * sigma).sqrt();
        let want = std::f64::consts::PI / wd;
        let rel = (r.t_r - want).abs() / want;
        println!(
            "m {m} k {k} zeta {zeta}: t_r {:.17e} s, pi/w_d {want:.17e} s, rel {rel:.1e}",
            r.t_r
        );
        assert!(rel <= 1e-14, "{rel}");
        // the engine releases there and takes the stored state
        let mut st = EngineState::new(&sc);
        for _ in 0..((want / sc.h) as usize + 3) {
            st.tick(&sc);
        }
        assert!(!st.in_contact());
        assert_eq!(
            (st.exact_stats.rest_releases, st.exact_stats.rest_misses),
            (1, 0)
        );
    }
}

/// Every scene the comparison runs: the presets and the stability
/// catalogue, with their lengths.
fn scenes() -> Vec<(String, Scene, usize)> {
    let mut v: Vec<(String, Scene, usize)> = presets::one_contact()
        .map(|i| {
            let s = presets::scene(i).unwrap();
            let n = (s.duration_s.min(1.0) * RATE) as usize;
            (format!("preset {}", presets::NAMES[i]), s, n)
        })
        .collect();
    for c in stability::cases() {
        v.push((format!("stability {}", c.label), c.scene, c.samples));
    }
    v
}

struct Run {
    out: Vec<[f64; 2]>,
    /// Per sample: energy after the step.
    energy: Vec<f64>,
    st: EngineState,
}

fn run(sc: &CompiledScene, n: usize, rest: bool, time_scale: f64) -> Run {
    run_with(sc, n, rest, time_scale, false)
}

fn run_with(sc: &CompiledScene, n: usize, rest: bool, time_scale: f64, portable: bool) -> Run {
    let mut st = EngineState::new(sc);
    st.set_rest_strike(rest);
    st.set_portable_kernels(portable);
    st.set_time_scale(sc, time_scale).unwrap();
    st.reset(sc);
    let (mut out, mut energy) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        out.push(st.tick(sc));
        energy.push(st.energy(sc));
    }
    Run { out, energy, st }
}

#[test]
fn a_strike_from_rest_plays_as_the_dense_change_of_basis_does() {
    let (mut used, mut later_runs) = (0, 0);
    println!("scene | rest t_r ms | first releases stored / later switches stored / misses | max |out diff| / peak (rounding alone) | max energy diff / E0 | max energy gain / E0");
    for (name, scene, n) in scenes() {
        let sc = compile_with(&scene, RATE, Some(Switching::Exact)).unwrap();
        let Some(r) = sc.rest.as_ref() else {
            // gravity (an affine contact), a dense contact, or a contact
            // that never ends (a critically damped wall: p_eff only tends
            // to 0, until the state underflows to zero), which the engine
            // must then show too
            let endless = sc.g == 0.0 && sc.contact.dense.is_none();
            if endless {
                let b = run(&sc, n, false, 1.0);
                let e0 = b.energy.iter().fold(0.0f64, |m, &e| m.max(e));
                let e_end = b.energy[n - 1];
                assert!(
                    b.st.contacts_started == 1 && (b.st.in_contact() || e_end <= 1e-250 * e0),
                    "{name}: no rest release, but the contact ended with energy {e_end:e} of {e0:e}"
                );
            }
            println!(
                "{name} | none (gravity {}, dense {}, endless contact {endless})",
                sc.g,
                sc.contact.dense.is_some()
            );
            continue;
        };
        for ts in [1.0, 1.37] {
            if ts != 1.0 && sc.free.dense.is_some() {
                continue;
            }
            let (a, b) = (run(&sc, n, true, ts), run(&sc, n, false, ts));
            // what rounding alone moves: the dense path on the portable
            // kernels against the detected ones
            let c = run_with(&sc, n, false, ts, true);
            let peak = b.out.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            let (d_out, d_round) = (out_diff(&a, &b), out_diff(&c, &b));
            let e0 = a.energy.iter().fold(0.0f64, |m, &e| m.max(e));
            let d_e = energy_diff(&a, &b);
            let gain = largest_rise(&a.energy);
            let st = &a.st.exact_stats;
            println!(
                "{name} x{ts} | {:.4} | {} / {} / {} | {:.1e} ({:.1e}) | {:.1e} | {:.1e}",
                r.t_r * 1e3,
                st.rest_releases,
                st.rest_later,
                st.rest_misses,
                d_out / peak,
                d_round / peak,
                d_e / e0,
                gain / e0
            );
            assert!(
                st.rest_releases >= 1,
                "{name} x{ts}: the stored release was never used"
            );
            assert_eq!(b.st.exact_stats.rest_releases, 0);
            assert_eq!(a.st.contacts_started, b.st.contacts_started, "{name} x{ts}");
            // a stored state is exact to rounding, as the product is, but
            // rounded differently: where the scene amplifies rounding (a
            // lossless object that the hammer meets again and again), no
            // more than ten times what rounding alone moves
            assert!(
                d_out <= (1e-11 * peak).max(10.0 * d_round),
                "{name} x{ts}: outputs differ by {d_out:e} (peak {peak:e}, rounding alone {d_round:e})"
            );
            assert!(
                d_e <= 1e-11 * e0,
                "{name} x{ts}: energies differ by {d_e:e} (E0 {e0:e})"
            );
            let gain_dense = largest_rise(&b.energy);
            assert!(
                gain <= gain_dense.max(0.0) + 1e-13 * e0,
                "{name} x{ts}: energy gain {gain:e} vs dense {gain_dense:e} (E0 {e0:e})"
            );
            used += 1;
            later_runs += usize::from(st.rest_later > 0);
        }
    }
    assert!(used >= 20, "only {used} runs used the stored release");
    assert!(
        later_runs >= 8,
        "only {later_runs} runs used stored later switches"
    );
}

#[test]
fn a_ringing_object_or_a_pitch_change_in_contact_takes_the_dense_product() {
    let sc = compile_one(&ModalStrike::new(30, 200.0, 8000.0).scene("ring"), RATE).unwrap();
    assert!(sc.rest.is_some());
    // a second strike while the object rings: its state is not zero
    let mut st = EngineState::new(&sc);
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert_eq!(st.exact_stats.rest_releases, 1);
    st.strike(&sc, 0.0, -1.0);
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert_eq!(st.contacts_started, 2);
    assert_eq!(
        (st.exact_stats.rest_releases, st.exact_stats.rest_misses),
        (1, 0)
    );
    // a change of pitch during a strike from rest: the contact is then
    // counted in steps of two lengths, and the dense product is taken
    let mut st = EngineState::new(&sc);
    while !st.in_contact() {
        st.tick(&sc);
    }
    st.set_time_scale(&sc, 1.5).unwrap();
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert_eq!(st.exact_stats.rest_releases, 0);
    // a strike in the middle of a contact from rest ends it early: a miss
    let mut st = EngineState::new(&sc);
    while !st.in_contact() {
        st.tick(&sc);
    }
    st.tick(&sc);
    st.strike(&sc, 0.001, -1.0);
    assert!(!st.in_contact());
    assert_eq!(
        (st.exact_stats.rest_releases, st.exact_stats.rest_misses),
        (0, 1)
    );
}

/// The largest difference between two runs' energies.
fn energy_diff(p: &Run, q: &Run) -> f64 {
    p.energy
        .iter()
        .zip(&q.energy)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// The largest rise of an energy from one sample to the next.
fn largest_rise(e: &[f64]) -> f64 {
    e.windows(2).fold(0.0f64, |m, w| m.max(w[1] - w[0]))
}

/// The largest difference between two runs' outputs.
fn out_diff(p: &Run, q: &Run) -> f64 {
    diff_and_peak(&p.out, &q.out).0
}

/// The largest difference between two outputs, and the peak of `b`.
fn diff_and_peak(a: &[[f64; 2]], b: &[[f64; 2]]) -> (f64, f64) {
    let peak = b.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    let d = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    (d, peak)
}

/// A bar of many modes struck from rest meets the hammer again twice: the
/// compiler follows the strike past its first release, and the engine takes
/// every later entry and release from the store, O(N), where the dense
/// path takes a change of basis each; the same contacts, the outputs and
/// energies the same to rounding, no energy gain, at two pitches.
#[test]
fn the_later_contacts_of_a_strike_from_rest_take_the_stored_states() {
    println!("modes | pitch | stored later switches | contacts | later taken / misses | max |out diff| / peak (rounding alone) | max energy diff / E0");
    for n in [100, 200, 400] {
        let sc = compile_one(&modal_testkit::scenes::struck_bar(n, 0.1), RATE).unwrap();
        let r = sc
            .rest
            .as_ref()
            .expect("a struck bar has a strike from rest");
        assert!(
            r.later.len() >= 2,
            "{n} modes: {} later switches",
            r.later.len()
        );
        // alternating entries and releases, in time order, after t_r
        let mut t = r.t_r;
        for w in &r.later {
            assert!(w.t > t && w.rho > 0.0);
            assert!(w.s.iter().chain(&w.s_d).all(|x| x.is_finite()));
            t = w.t;
        }
        let len = (0.04 * RATE) as usize;
        for ts in [1.0, 1.37] {
            let (a, b) = (run(&sc, len, true, ts), run(&sc, len, false, ts));
            let c = run_with(&sc, len, false, ts, true);
            let peak = b.out.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            let (d_out, d_round) = (out_diff(&a, &b), out_diff(&c, &b));
            let e0 = b.energy.iter().fold(0.0f64, |m, &e| m.max(e));
            let d_e = energy_diff(&a, &b);
            let st = &a.st.exact_stats;
            println!(
                "{n} | {ts} | {} | {} | {} / {} | {:.1e} ({:.1e}) | {:.1e}",
                r.later.len(),
                a.st.contacts_started,
                st.rest_later,
                st.rest_misses,
                d_out / peak,
                d_round / peak,
                d_e / e0
            );
            assert_eq!(a.st.contacts_started, b.st.contacts_started, "{n} x{ts}");
            assert!(a.st.contacts_started >= 2, "{n} x{ts}: one contact");
            assert_eq!(st.rest_misses, 0, "{n} x{ts}");
            // every switch after the first contact came from the store
            assert_eq!(
                st.rest_later,
                2 * (a.st.contacts_started - 1) - u64::from(a.st.in_contact()),
                "{n} x{ts}"
            );
            assert_eq!(b.st.exact_stats.rest_later, 0);
            assert!(
                d_out <= (1e-11 * peak).max(10.0 * d_round),
                "{n} x{ts}: outputs differ by {d_out:e} (peak {peak:e}, rounding alone {d_round:e})"
            );
            assert!(d_e <= 1e-11 * e0, "{n} x{ts}: energies differ by {d_e:e}");
            let (gain, gain_dense) = (largest_rise(&a.energy), largest_rise(&b.energy));
            assert!(
                gain <= gain_dense.max(0.0) + 1e-13 * e0,
                "{n} x{ts}: energy gain {gain:e} vs dense {gain_dense:e}"
            );
        }
    }
}

/// Something done to a voice between two samples.
type Disturbance = fn(&CompiledScene, &mut EngineState);

/// Whatever disturbs a strike from rest between its contacts (a new strike
/// in flight, the damper scaling the free state, a change of pitch) ends
/// the stored run: the later contacts take the dense products, exactly as
/// the dense path does (the same samples bit for bit), and count no miss.
#[test]
fn a_disturbed_strike_from_rest_takes_the_dense_products_after() {
    let sc = compile_one(&modal_testkit::scenes::struck_bar(100, 0.1), RATE).unwrap();
    let r = sc.rest.as_ref().unwrap();
    assert!(r.later.len() >= 2);
    let disturbances: [(&str, Disturbance); 3] = [
        ("strike", |sc, st| st.strike(sc, 0.0, -0.5)),
        ("damper", |_, st| assert!(st.scale_free_state(0.999))),
        ("pitch", |sc, st| st.set_time_scale(sc, 1.01).unwrap()),
    ];
    for (what, disturb) in disturbances {
        let play = |rest: bool| {
            let mut st = EngineState::new(&sc);
            st.set_rest_strike(rest);
            st.reset(&sc);
            let mut out = Vec::new();
            let mut disturbed = false;
            for _ in 0..(0.04 * RATE) as usize {
                // two samples after the first release: in flight, the next
                // contact due
                if !disturbed && st.contacts_started == 1 && !st.in_contact() {
                    out.push(st.tick(&sc));
                    out.push(st.tick(&sc));
                    assert!(!st.in_contact());
                    disturb(&sc, &mut st);
                    disturbed = true;
                }
                out.push(st.tick(&sc));
            }
            (out, st)
        };
        let ((a, sa), (b, sb)) = (play(true), play(false));
        let s = &sa.exact_stats;
        println!(
            "{what}: contacts {}, first releases {}, later {}, misses {}",
            sa.contacts_started, s.rest_releases, s.rest_later, s.rest_misses
        );
        assert!(sa.contacts_started >= 2, "{what}");
        assert_eq!(
            (s.rest_releases, s.rest_later, s.rest_misses),
            (1, 0, 0),
            "{what}"
        );
        assert_eq!(sa.contacts_started, sb.contacts_started, "{what}");
        // up to the first release the runs differ by rounding only; after
        // it both take the same products from the state they have
        let (d, peak) = diff_and_peak(&a, &b);
        assert!(d <= 1e-12 * peak, "{what}: {d:e} of {peak:e}");
    }
}

/// The stored switch instants schedule the fast path's runs (a run ends
/// before the sample of the next stored switch, which skips the Hermite
/// certificate): the same samples bit for bit in 64-sample blocks, the same
/// switches, and less kernel work thrown away.
#[test]
fn stored_switch_instants_schedule_the_runs_without_changing_a_sample() {
    println!("scene | switches | kernel samples thrown away: scheduled / not");
    let mut cases: Vec<(String, CompiledScene)> = [100, 400]
        .into_iter()
        .map(|n| {
            let sc = compile_one(&modal_testkit::scenes::struck_bar(n, 0.1), RATE).unwrap();
            (format!("bar of {n} modes"), sc)
        })
        .collect();
    for (name, s, _) in scenes() {
        let sc = compile_one(&s, RATE).unwrap();
        if sc.rest.as_ref().is_some_and(|r| !r.later.is_empty()) {
            cases.push((name, sc));
        }
    }
    assert!(
        cases.len() >= 6,
        "{} scenes with stored later switches",
        cases.len()
    );
    let mut fewer = 0;
    for (name, sc) in &cases {
        let render = |schedule: bool| {
            let mut st = EngineState::new(sc);
            st.set_rest_schedule(schedule);
            st.reset(sc);
            let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
            let mut out = Vec::new();
            for _ in 0..(0.04 * RATE) as usize / 64 {
                st.process_block(sc, &mut l, &mut r);
                out.extend(l.iter().chain(&r).map(|x| x.to_bits()));
            }
            (out, st)
        };
        let ((a, sa), (b, sb)) = (render(true), render(false));
        let (ea, eb) = (&sa.exact_stats, &sb.exact_stats);
        println!(
            "{name} | {} | {} / {}",
            ea.located, ea.kernel_discarded, eb.kernel_discarded
        );
        assert!(a == b, "{name}: the schedule changed a sample");
        assert_eq!(
            (ea.located, ea.rest_releases, ea.rest_later, ea.rest_misses),
            (eb.located, eb.rest_releases, eb.rest_later, eb.rest_misses),
            "{name}"
        );
        assert!(ea.rest_later > 0, "{name}: no stored later switch taken");
        assert!(ea.kernel_discarded <= eb.kernel_discarded, "{name}");
        fewer += usize::from(ea.kernel_discarded < eb.kernel_discarded);
    }
    assert!(
        fewer * 2 > cases.len(),
        "less thrown away in {fewer} of {} scenes",
        cases.len()
    );
}

/// Before a scene plays, the engine runs a strike from rest on it and
/// counts the stored switches its certified search confirms
/// (`RestStrike::certified`); a voice takes those at their stored instants
/// without a search. Against
/// the same engine with every switch located by the search (the stored
/// instant a hint): on every preset and stability case with a stored
/// strike and bars of 100..1000 modes, at two pitches, the same contacts,
/// outputs within ten times what rounding alone moves (or 1e-13 of the
/// peak), energies within ten times what rounding alone moves (or 1e-13
/// of the strike's), no energy gain beyond the search's own, no search node spent on a trusted switch.
#[test]
fn certified_stored_switches_play_as_the_search_locates_them() {
    println!("scene | certified / stored | pitch | trusted / located | nodes: trusted / searched | max |out diff| / peak (rounding alone) | max energy diff / E0 (rounding alone) | rho x root resolution");
    let mut cases: Vec<(String, CompiledScene, usize)> = [100, 200, 1000]
        .into_iter()
        .map(|n| {
            let sc = compile_one(&modal_testkit::scenes::struck_bar(n, 0.1), RATE).unwrap();
            (format!("bar of {n} modes"), sc, (0.03 * RATE) as usize)
        })
        .collect();
    for (name, s, n) in scenes() {
        let sc = compile_with(&s, RATE, Some(Switching::Exact)).unwrap();
        if sc.rest.is_some() {
            cases.push((name, sc, n));
        }
    }
    let (mut trusted_runs, mut all_certified) = (0, 0);
    for (name, sc, n) in &cases {
        let r = sc.rest.as_ref().unwrap();
        let stored = r.later.len() + 1;
        let certified = modal_contact::engine::certify_rest_strike(sc);
        assert!(certified <= stored, "{name}");
        all_certified += usize::from(certified == stored);
        for ts in [1.0, 1.37] {
            if ts != 1.0 && sc.free.dense.is_some() {
                continue;
            }
            let play = |trust: bool, portable: bool| {
                let mut st = EngineState::new(sc);
                st.set_rest_trust(trust);
                st.set_portable_kernels(portable);
                st.set_time_scale(sc, ts).unwrap();
                st.reset(sc);
                let (mut out, mut energy) = (Vec::with_capacity(*n), Vec::with_capacity(*n));
                for _ in 0..*n {
                    out.push(st.tick(sc));
                    energy.push(st.energy(sc));
                }
                Run { out, energy, st }
            };
            let (a, b, c) = (play(true, false), play(false, false), play(false, true));
            let peak = b.out.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            let (d_out, d_round) = (out_diff(&a, &b), out_diff(&c, &b));
            let e0 = b.energy.iter().fold(0.0f64, |m, &e| m.max(e));
            let (d_e, d_e_round) = (energy_diff(&a, &b), energy_diff(&c, &b));
            let (x, y) = (&a.st.exact_stats, &b.st.exact_stats);
            println!(
                "{name} | {certified} / {stored} | {ts} | {} / {} | {} / {} | {:.1e} ({:.1e}) | {:.1e} ({:.1e}) | {:.1e}",
                x.rest_trusted,
                x.located,
                x.search_nodes,
                y.search_nodes,
                d_out / peak,
                d_round / peak,
                d_e / e0,
                d_e_round / e0,
                ROOT_ULPS * f64::EPSILON * sc.h * ts * r.later.iter().fold(r.rho, |m, w| m.max(w.rho))
            );
            assert_eq!(y.rest_trusted, 0, "{name} x{ts}");
            assert_eq!(a.st.contacts_started, b.st.contacts_started, "{name} x{ts}");
            assert_eq!(x.located, y.located, "{name} x{ts}");
            assert_eq!(
                (x.rest_releases + x.rest_later, x.rest_misses),
                (y.rest_releases + y.rest_later, y.rest_misses),
                "{name} x{ts}"
            );
            // a certified switch the voice reached is taken without a search
            let reached = (y.rest_releases + y.rest_later).min(certified as u64);
            assert_eq!(x.rest_trusted, reached, "{name} x{ts}");
            assert!(
                x.search_nodes < y.search_nodes || reached == 0,
                "{name} x{ts}: {} nodes, {} with the search",
                x.search_nodes,
                y.search_nodes
            );
            // the search locates a switch to its resolution, the compiler
            // to the last bit: instants that far apart move the state by up
            // to rho times that, relative (a stiff contact: rho large)
            let res = ROOT_ULPS * f64::EPSILON * sc.h * ts;
            let rho = r.later.iter().fold(r.rho, |m, w| m.max(w.rho));
            let timing = 2.0 * rho * res;
            assert!(
                d_out <= (1e-13 * peak).max(10.0 * d_round).max(timing * peak),
                "{name} x{ts}: outputs differ by {d_out:e} (peak {peak:e}, rounding alone {d_round:e})"
            );
            assert!(
                d_e <= (1e-13 * e0).max(10.0 * d_e_round).max(2.0 * timing * e0),
                "{name} x{ts}: energies differ by {d_e:e} (E0 {e0:e}, rounding alone {d_e_round:e})"
            );
            let (gain, gain_search) = (largest_rise(&a.energy), largest_rise(&b.energy));
            assert!(
                gain <= gain_search.max(0.0) + 1e-15 * e0,
                "{name} x{ts}: energy gain {gain:e} vs the search's {gain_search:e}"
            );
            trusted_runs += usize::from(reached > 0);
        }
    }
    assert!(
        trusted_runs >= 20,
        "only {trusted_runs} runs took trusted switches"
    );
    assert!(
        all_certified * 10 >= cases.len() * 9,
        "every stored switch certified in only {all_certified} of {} scenes",
        cases.len()
    );
}

/// A stored schedule that is wrong from some switch on (an instant moved
/// by a microsecond, as a compiler's grid that missed a crossing would
/// leave it) is certified only up to that switch: a voice takes the
/// switches before it at their stored instants, then locates the wrong
/// one with its search, counts a miss and takes the products, playing as
/// the engine does with the search alone.
#[test]
fn a_stored_switch_the_engine_does_not_confirm_is_not_trusted() {
    let mut sc = compile_one(&modal_testkit::scenes::struck_bar(100, 0.1), RATE).unwrap();
    let stored = sc.rest.as_ref().unwrap().later.len() + 1;
    assert!(stored >= 3, "{stored} stored switches");
    assert_eq!(modal_contact::engine::certify_rest_strike(&sc), stored);
    // later switch 1 (the second contact's release) moved, the count
    // forgotten
    let r = sc.rest.as_mut().unwrap();
    r.later[1].t += 1e-6;
    r.certified.take();
    // the first release and the second entry are confirmed
    assert_eq!(modal_contact::engine::certify_rest_strike(&sc), 2);
    let play = |trust: bool| {
        let mut st = EngineState::new(&sc);
        st.set_rest_trust(trust);
        st.reset(&sc);
        let out: Vec<[f64; 2]> = (0..(0.03 * RATE) as usize).map(|_| st.tick(&sc)).collect();
        (out, st)
    };
    let ((a, sa), (b, sb)) = (play(true), play(false));
    let (x, y) = (&sa.exact_stats, &sb.exact_stats);
    println!(
        "trusted {}, stored taken {} + {}, misses {}; with the search alone: {} + {}, misses {}",
        x.rest_trusted,
        x.rest_releases,
        x.rest_later,
        x.rest_misses,
        y.rest_releases,
        y.rest_later,
        y.rest_misses
    );
    assert_eq!(x.rest_trusted, 2);
    assert_eq!((x.rest_releases, x.rest_later, x.rest_misses), (1, 1, 1));
    assert_eq!((y.rest_releases, y.rest_later, y.rest_misses), (1, 1, 1));
    assert_eq!(sa.contacts_started, sb.contacts_started);
    let (d, peak) = diff_and_peak(&a, &b);
    assert!(d <= 1e-13 * peak, "{d:e} of {peak:e}");
}
