//! Strikes played into a running several-contact state (what the
//! instrument's kit does at a note-on, docs/design.md section 20): a
//! strike on a kit at rest is the model started there, a strike that
//! opens a closed contact removes exactly its spring's and the mass's old
//! energy and adds exactly the new throw's, and a mass that cannot be put
//! where asked is refused without a change.

use modal_contact::multi::{
    CompiledMulti, MultiContact, MultiEnd, MultiHammer, MultiMass, MultiModel, MultiState,
    StrikeRefused,
};
use modal_testkit::rng::TestRng;

const RATE: f64 = 48_000.0;

/// A bar-like object of `n` modes struck by two hammers (contact 0 and
/// contact 1) parked at the given heights, at rest; velocity and
/// displacement pickups.
fn two_mallets(n: usize, heights: [f64; 2], g: f64) -> MultiModel {
    let mut rng = TestRng(7);
    let freq: Vec<f64> = (0..n).map(|i| 180.0 * (1.0 + i as f64).powf(1.7)).collect();
    let sigma: Vec<f64> = (0..n).map(|i| 1.0 + 0.3 * i as f64).collect();
    let w = |rng: &mut TestRng| -> Vec<f64> { (0..n).map(|_| rng.uniform(-2.0, 2.0)).collect() };
    let hammers: Vec<MultiHammer> = heights
        .iter()
        .map(|&h| MultiHammer {
            mass_kg: 0.03,
            height_m: h,
            velocity_m_per_s: 0.0,
            weights: w(&mut rng),
            stiffness_n_per_m: 3e5,
            damping_n_s_per_m: 20.0,
        })
        .collect();
    let pick = w(&mut rng);
    MultiModel::struck(
        freq,
        sigma,
        &hammers,
        g,
        [(pick.clone(), vec![0.0; n]), (vec![0.0; n], pick)],
    )
}

/// A strike on a kit at rest gives the samples of the model whose mass
/// starts there: the strike's placement and the model's start agree.
#[test]
fn a_strike_at_rest_is_the_model_started_there() {
    for g in [0.0, 9.81] {
        let parked = two_mallets(24, [0.02, 0.03], g);
        let sc = CompiledMulti::new(&parked, RATE).unwrap();
        let mut st = MultiState::new(&sc);
        st.rest(&sc);
        st.strike(&sc, 1, 0.001, -1.7).unwrap();
        let mut started = parked.clone();
        started.masses[1] = MultiMass {
            mass_kg: 0.03,
            height_m: 0.001,
            velocity_m_per_s: -1.7,
        };
        let sc2 = CompiledMulti::new(&started, RATE).unwrap();
        let mut st2 = MultiState::new(&sc2);
        let (mut peak, mut worst) = (0.0f64, 0.0f64);
        for _ in 0..6000 {
            let (a, b) = (st.tick(&sc), st2.tick(&sc2));
            for ch in 0..2 {
                peak = peak.max(b[ch].abs());
                worst = worst.max((a[ch] - b[ch]).abs());
            }
        }
        println!("g {g}: strike vs started model {worst:.3e} of peak {peak:.3e}");
        assert!(st.stats.contacts_started[1] >= 1, "{:?}", st.stats);
        assert_eq!(st.stats.contacts_started, st2.stats.contacts_started);
        assert!(peak > 1e-4);
        assert!(worst <= 1e-13 * peak, "{worst:e} of {peak:e}");
    }
}

/// `rest` puts every mass back at its height, still, and the objects at
/// rest, from any state.
#[test]
fn rest_is_the_model_at_rest() {
    let m = two_mallets(12, [0.0, 0.01], 0.0);
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    st.strike(&sc, 0, 0.0, -2.0).unwrap();
    for _ in 0..40 {
        st.tick(&sc);
    }
    assert_ne!(st.active(), 0, "the first mallet is in contact");
    st.rest(&sc);
    let o = st.observe_physical(&sc);
    assert_eq!(st.active(), 0);
    assert_eq!(o.x_hammer[..2], [0.0, 0.01]);
    assert_eq!(o.v_hammer[..2], [0.0, 0.0]);
    assert_eq!(o.x_contact[..2], [0.0, 0.0]);
    assert_eq!(o.energy, 0.0);
    assert_eq!(st.tick(&sc), [0.0, 0.0]);
}

/// A strike on a mallet in contact: the contact opens through the
/// physical state, so the energy after is the energy before less the
/// spring's and the mass's old energy, plus the new throw's; from there
/// the energy never rises and the mallet strikes again.
#[test]
fn a_strike_in_contact_opens_it_and_adds_only_the_throw() {
    for g in [0.0, 9.81] {
        let m = two_mallets(30, [0.0, 0.02], g);
        let sc = CompiledMulti::new(&m, RATE).unwrap();
        let mut st = MultiState::new(&sc);
        st.rest(&sc);
        st.strike(&sc, 0, 0.0, -1.0).unwrap();
        let mut n = 0;
        while n < 8 {
            st.tick(&sc);
            n += (st.active() & 1) as usize;
        }
        let before = st.observe_physical(&sc);
        let ct = &m.contacts[0];
        let p = before.x_contact[0] - before.x_hammer[0];
        assert!(p > 0.0, "pressed in: {p:e}");
        let spring = 0.5 * ct.stiffness_n_per_m * p * p;
        let (mk, v0, x0) = (0.03, before.v_hammer[0], before.x_hammer[0]);
        let old = 0.5 * mk * v0 * v0 + mk * g * x0;
        let v_new = -2.5;
        let started = st.stats.contacts_started[0];
        st.strike(&sc, 0, 0.0, v_new).unwrap();
        let after = st.observe_physical(&sc);
        let new = 0.5 * mk * v_new * v_new + mk * g * after.x_hammer[0];
        let expect = before.energy - spring - old + new;
        let err = (after.energy - expect).abs() / expect;
        println!(
            "g {g}: spring {spring:.4e} J left, throw {new:.4e} J; energy after within {err:.2e}"
        );
        assert_eq!(st.active() & 1, 0, "the contact opened");
        // thrown from the surface (the two views of it differ by rounding)
        let gap = (after.x_hammer[0] - after.x_contact[0]).abs();
        assert!(gap <= 1e-12 * after.x_contact[0].abs(), "{gap:e}");
        assert_eq!(after.v_hammer[0], v_new);
        assert!(err < 1e-12, "{err:e}");
        // the observation the trace takes agrees with the physical one
        let fast = st.observe(&sc);
        assert!((fast.energy - after.energy).abs() <= 1e-12 * after.energy);
        let mut e_prev = after.energy;
        let mut rise = 0.0f64;
        for _ in 0..4000 {
            st.tick(&sc);
            let e = st.observe(&sc).energy;
            rise = rise.max((e - e_prev) / after.energy);
            e_prev = e;
        }
        println!("g {g}: largest energy step after the strike {rise:.2e} of it");
        assert!(rise < 1e-12, "{rise:e}");
        assert!(st.stats.contacts_started[0] > started, "it struck again");
    }
}

/// A ball between a floor and a lid 1 mm above, thrown from 2 mm, starts
/// under the lid (as high as it can be); a mass pressed into the floor by
/// a heavy one above it has no place with its contacts open: refused,
/// nothing changed; the heavy one can be thrown.
#[test]
fn a_wedged_mass_is_refused_without_a_change() {
    let c = |lower, upper| MultiContact {
        lower,
        upper,
        gap_m: 0.0,
        stiffness_n_per_m: 1e6,
        damping_n_s_per_m: 1.0,
    };
    let mass = |m, x, v| MultiMass {
        mass_kg: m,
        height_m: x,
        velocity_m_per_s: v,
    };
    let lid = MultiModel {
        freq_hz: vec![],
        sigma: vec![],
        masses: vec![mass(0.01, 0.0, 0.0)],
        contacts: vec![
            c(MultiEnd::Wall(0.0), MultiEnd::Mass(0)),
            c(MultiEnd::Mass(0), MultiEnd::Wall(0.001)),
        ],
        gravity_m_per_s2: 0.0,
        pickups: [(vec![], vec![]), (vec![], vec![])],
    };
    let sc = CompiledMulti::new(&lid, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    assert_eq!(st.strike(&sc, 1, 0.0, -1.0), Err(StrikeRefused::NotAMass));
    assert_eq!(
        st.strike(&sc, 0, f64::NAN, -1.0),
        Err(StrikeRefused::NotFinite)
    );
    st.strike(&sc, 0, 0.002, 1.0).unwrap();
    let o = st.observe_physical(&sc);
    assert_eq!(
        (o.x_hammer[0], o.v_hammer[0]),
        (0.001, 1.0),
        "under the lid"
    );
    for _ in 0..2000 {
        st.tick(&sc);
    }
    assert!(st.stats.contacts_started[0] >= 1 && st.stats.contacts_started[1] >= 1);

    let stack = MultiModel {
        masses: vec![mass(0.01, 0.0, 0.0), mass(1.0, 0.0005, -3.0)],
        contacts: vec![
            c(MultiEnd::Wall(0.0), MultiEnd::Mass(0)),
            c(MultiEnd::Mass(0), MultiEnd::Mass(1)),
        ],
        ..lid
    };
    let sc = CompiledMulti::new(&stack, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    while st.active() != 3 || st.observe_physical(&sc).x_hammer[1] >= 0.0 {
        st.tick(&sc);
    }
    let before = st.observe_physical(&sc);
    println!(
        "pressed: the light mass at {:.3e} m, the heavy one at {:.3e} m",
        before.x_contact[1], before.x_hammer[1]
    );
    assert_eq!(st.strike(&sc, 0, 0.0, 1.0), Err(StrikeRefused::Wedged));
    assert_eq!(st.observe_physical(&sc), before, "nothing changed");
    assert_eq!(st.active(), 3);
    st.strike(&sc, 1, 0.002, -1.0).unwrap();
    let o = st.observe_physical(&sc);
    assert_eq!(st.active(), 1, "the heavy one left");
    assert!((o.x_hammer[1] - (o.x_contact[1] + 0.002)).abs() < 1e-15);
}

/// A time scale `s` plays the model `s` times faster: the same samples as
/// the model compiled with every frequency and decay rate times `s`,
/// stiffness times `s^2`, damping times `s`, gravity times `s^2` and the
/// masses' velocities times `s` (its own compile: other eigendecompositions,
/// the same physics), with and without gravity, up and down an octave and
/// more; the same contacts. Within 1e-9 relative L2, or, where the mallets
/// bounce back onto the ringing bar under gravity, within ten times what a
/// change of 1e-12 in one stiffness of the compiled model does to it (the
/// motion's own sensitivity, measured in the same run; with a slower
/// second mallet that chatters, 1e-12 moves it by 2.6e-5 to 7e-2).
#[test]
fn a_time_scale_is_the_model_played_faster() {
    for g in [0.0, 9.81] {
        for s in [0.5, 2f64.powf(7.0 / 12.0), 2.3] {
            let mut m = two_mallets(24, [0.0, 0.004], g);
            m.masses[0].velocity_m_per_s = -1.2;
            m.masses[1].velocity_m_per_s = -1.0;
            let sc = CompiledMulti::new(&m, RATE).unwrap();
            let mut st = MultiState::new(&sc);
            st.set_time_scale(&sc, s).unwrap();
            let mut fast = m.clone();
            fast.freq_hz.iter_mut().for_each(|f| *f *= s);
            fast.sigma.iter_mut().for_each(|x| *x *= s);
            fast.gravity_m_per_s2 *= s * s;
            for ms in &mut fast.masses {
                ms.velocity_m_per_s *= s;
            }
            for ct in &mut fast.contacts {
                ct.stiffness_n_per_m *= s * s;
                ct.damping_n_s_per_m *= s;
            }
            let sc2 = CompiledMulti::new(&fast, RATE).unwrap();
            let mut st2 = MultiState::new(&sc2);
            let mut twin = fast.clone();
            twin.contacts[0].stiffness_n_per_m *= 1.0 + 1e-12;
            let sc3 = CompiledMulti::new(&twin, RATE).unwrap();
            let mut st3 = MultiState::new(&sc3);
            let (mut num, mut den, mut num3) = (0.0f64, 0.0f64, 0.0f64);
            for _ in 0..6000 {
                let (a, b, c) = (st.tick(&sc), st2.tick(&sc2), st3.tick(&sc3));
                for ch in 0..2 {
                    num += (a[ch] - b[ch]).powi(2);
                    num3 += (c[ch] - b[ch]).powi(2);
                    den += b[ch] * b[ch];
                }
            }
            let (rel, sens) = ((num / den).sqrt(), (num3 / den).sqrt());
            println!(
                "g {g}, scale {s:.4}: relative L2 {rel:.2e} (a 1e-12 stiffness change: \
                 {sens:.2e}), contacts {:?}",
                &st.stats.contacts_started[..2]
            );
            assert_eq!(st.stats.contacts_started, st2.stats.contacts_started);
            assert!(st.stats.contacts_started[0] >= 1 && st.stats.contacts_started[1] >= 1);
            assert!(rel < 1e-9_f64.max(10.0 * sens), "{rel:e} {sens:e}");
        }
    }
}

/// A bend ([`MultiState::bend_time_scale`]) with no contact closed: the
/// physical energy (the model's times the scale squared) is unchanged,
/// and from there the state is the unbent model run faster: at scale `s =
/// q / p`, sample `p k` of the bent run is sample `q k` of the unbent one,
/// its displacement times `1 / s` (the same energy at `s` times the
/// frequency), its velocity the same, and a flying mallet keeps its
/// physical speed (its height at sample `n` is the unbent run's at `n`).
/// An octave up and a fifth up (3 / 2). In contact it waits (`Ok(false)`,
/// nothing changed); with gravity it is refused.
#[test]
fn a_bend_keeps_the_energy_and_plays_the_model_faster() {
    use modal_contact::engine::TimeScaleError;
    let m = two_mallets(24, [0.02, 0.03], 0.0);
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    st.rest(&sc);
    st.strike(&sc, 0, 0.0005, -1.7).unwrap();
    // in contact: it waits, and nothing changes
    while st.active() == 0 {
        st.tick(&sc);
    }
    let before = st.output(&sc);
    assert_eq!(st.bend_time_scale(&sc, 2.0), Ok(false));
    assert_eq!(st.time_scale(), 1.0);
    assert_eq!(st.output(&sc), before);
    // the mallet leaves and flies up for good (no gravity)
    for _ in 0..3000 {
        st.tick(&sc);
    }
    assert_eq!(st.active(), 0);
    let o = st.observe(&sc);
    assert!(o.v_hammer[0] > 0.0, "flying away: {}", o.v_hammer[0]);
    for (p, q) in [(1usize, 2usize), (2, 3)] {
        let s = q as f64 / p as f64;
        let (mut a, mut b) = (st.clone(), st.clone());
        assert_eq!(b.bend_time_scale(&sc, s), Ok(true));
        assert_eq!(b.time_scale(), s);
        let (ea, eb) = (a.observe(&sc).energy, b.observe(&sc).energy * s * s);
        let de = (eb - ea).abs() / ea;
        let n = 3000;
        let (mut ya, mut xa) = (Vec::new(), Vec::new());
        for _ in 0..n * q / p + 1 {
            xa.push(a.observe(&sc).x_hammer[0]);
            ya.push(a.tick(&sc));
        }
        let (mut peak, mut worst, mut worst_x) = ([0.0f64; 2], [0.0f64; 2], 0.0f64);
        for k in 0..n {
            let x = b.observe(&sc).x_hammer[0];
            worst_x = worst_x.max((x - xa[k]).abs() / xa[k].abs());
            let y = b.tick(&sc);
            if k % p != 0 {
                continue;
            }
            let j = k / p * q;
            // displacement times 1 / s, velocity kept
            let want = [ya[j][0] / s, ya[j][1]];
            for ch in 0..2 {
                peak[ch] = peak[ch].max(want[ch].abs());
                worst[ch] = worst[ch].max((y[ch] - want[ch]).abs());
            }
        }
        println!(
            "scale {s}: energy {de:.1e}; displacement {:.1e}, velocity {:.1e} of their peaks; mallet height {worst_x:.1e}",
            worst[0] / peak[0],
            worst[1] / peak[1]
        );
        assert!(de < 1e-14, "{de:e}");
        assert!(
            worst[0] < 1e-12 * peak[0] && worst[1] < 1e-12 * peak[1],
            "{worst:?} {peak:?}"
        );
        assert!(worst_x < 1e-13, "{worst_x:e}");
    }
    // gravity's physical value would change with the time axis
    let g = two_mallets(4, [0.02, 0.03], 9.81);
    let scg = CompiledMulti::new(&g, RATE).unwrap();
    let mut sg = MultiState::new(&scg);
    assert_eq!(sg.bend_time_scale(&scg, 1.5), Err(TimeScaleError::Gravity));
    assert_eq!(
        sg.bend_time_scale(&scg, f64::NAN),
        Err(TimeScaleError::Invalid)
    );
}

/// A time scale that is not finite and positive is refused, as the
/// one-contact engine refuses it (`EngineState::set_time_scale`), and the
/// state plays on as it was, sample for sample.
#[test]
fn a_bad_time_scale_is_refused_and_changes_nothing() {
    use modal_contact::engine::TimeScaleError;
    let mut m = two_mallets(24, [0.0, 0.004], 0.0);
    m.masses[0].velocity_m_per_s = -1.2;
    let sc = CompiledMulti::new(&m, RATE).unwrap();
    let mut st = MultiState::new(&sc);
    st.set_time_scale(&sc, 1.5).unwrap();
    // refused in contact, where a switch is near
    let mut k = 0;
    while st.active() == 0 && k < 48_000 {
        st.tick(&sc);
        k += 1;
    }
    assert_ne!(st.active(), 0, "in contact within {k} samples");
    let mut same = st.clone();
    for bad in [f64::NAN, 0.0, -1.0, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(
            st.set_time_scale(&sc, bad),
            Err(TimeScaleError::Invalid),
            "{bad}"
        );
        assert_eq!(st.time_scale(), 1.5);
    }
    for k in 0..4000 {
        assert_eq!(st.tick(&sc), same.tick(&sc), "sample {k}");
    }
}

/// The output band ([`MultiState::set_output_band`]): the outputs are
/// those of the same model whose pickups leave out the modes above the
/// band (at the state's scale): its own compile, whose phases step the
/// same state, with rows built without those modes. Through strikes,
/// contacts, a bend that moves the band over more modes, with exact
/// switching and with the offset rod; an infinite band hears every mode.
#[test]
fn the_output_band_hears_the_model_without_its_top_modes() {
    use modal_contact::scene::Switching;
    let m = two_mallets(24, [0.02, 0.03], 0.0);
    let band = 9000.0;
    let without = |scale: f64| {
        let mut w = m.clone();
        let mut muted = 0;
        for (i, f) in m.freq_hz.iter().enumerate() {
            if f * scale > band {
                muted += 1;
                for c in 0..2 {
                    w.pickups[c].0[i] = 0.0;
                    w.pickups[c].1[i] = 0.0;
                }
            }
        }
        (w, muted)
    };
    for sw in [Switching::Exact, Switching::OffsetRod] {
        let sc = CompiledMulti::with_switching(&m, RATE, sw).unwrap();
        let (s1, s2) = (1.3, 1.9);
        let ((w1, muted1), (w2, muted2)) = (without(s1), without(s2));
        let sc1 = CompiledMulti::with_switching(&w1, RATE, sw).unwrap();
        let sc2 = CompiledMulti::with_switching(&w2, RATE, sw).unwrap();
        let mut st = MultiState::new(&sc);
        st.set_time_scale(&sc, s1).unwrap();
        st.set_output_band(&sc, band);
        let mut all = st.clone();
        all.set_output_band(&sc, f64::INFINITY);
        let mut reference = MultiState::new(&sc1);
        reference.set_time_scale(&sc1, s1).unwrap();
        let mut full = MultiState::new(&sc);
        full.set_time_scale(&sc, s1).unwrap();
        assert_eq!(st.band_muted_modes(), muted1);
        let (mut peak, mut worst, mut worst_all) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..12000 {
            if k == 0 || k == 5000 {
                let c = usize::from(k > 0);
                for x in [&mut st, &mut all, &mut full] {
                    x.strike(&sc, c, 0.0004, -1.2).unwrap();
                }
                reference.strike(&sc1, c, 0.0004, -1.2).unwrap();
            }
            if k == 9000 {
                // a bend with no contact closed: the band covers more modes
                assert_eq!(st.active(), 0);
                for x in [&mut st, &mut all, &mut full] {
                    assert_eq!(x.bend_time_scale(&sc, s2), Ok(true));
                }
                assert_eq!(reference.bend_time_scale(&sc2, s2), Ok(true));
                assert_eq!(st.band_muted_modes(), muted2);
            }
            let r = if k < 9000 {
                reference.tick(&sc1)
            } else {
                reference.tick(&sc2)
            };
            let y = st.tick(&sc);
            let (ya, yf) = (all.tick(&sc), full.tick(&sc));
            for ch in 0..2 {
                peak = peak.max(r[ch].abs());
                worst = worst.max((y[ch] - r[ch]).abs());
                worst_all = worst_all.max((ya[ch] - yf[ch]).abs());
            }
        }
        println!(
            "{}: band {band} Hz at scales {s1} / {s2}: {muted1} / {muted2} modes left out; against the model without their pickups {:.1e} of its peak; an infinite band {worst_all:.1e}",
            sw.as_str(),
            worst / peak
        );
        assert!(muted1 > 0 && muted2 > muted1);
        assert!(st.stats.contacts_started[0] >= 1 && st.stats.contacts_started[1] >= 1);
        assert_eq!(st.stats.contacts_started, reference.stats.contacts_started);
        assert!(worst < 1e-12 * peak, "{worst:e} of {peak:e}");
        assert_eq!(worst_all, 0.0);
    }
}
