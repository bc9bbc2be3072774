//! Tests of the exact event search against `phi` evaluated through the
//! state (exact partial propagators): the batched partial propagators, the
//! fast path's margin and the Hermite certificate's remainder, the Hermite
//! certificate against the search, and the search's model.

use super::ROUND_UNITS;
use crate::compile::{compile_one, CompiledScene};
use crate::engine::search::Found;
use crate::engine::{current_phase, kernel, EngineState, Phase};
use crate::physics::block::exp2;
use crate::presets;

/// The batched partial propagators (vectorised exp/sin/cos, split form)
/// against `exp2` (libm) block by block, in both phases of every preset.
#[test]
fn batched_partial_propagators_match_exp2() {
    let mut worst: f64 = 0.0;
    for i in presets::one_contact() {
        let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
        let mut st = EngineState::new(&sc);
        for contact in [false, true] {
            st.phase = if contact { Phase::Contact } else { Phase::Free };
            let ph = current_phase(&st, &sc);
            let Some(gens) = ph.gens.clone() else {
                continue;
            };
            for frac in [1e-9, 0.013, 0.5, 0.999, 3.0] {
                let tau = frac * sc.h;
                st.part_ok = false;
                st.ensure_partial(&sc, tau);
                for (k, g) in gens.iter().enumerate() {
                    let want = exp2(g, tau);
                    let got = st.p_part.get(k);
                    let norm = want.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let e = got
                        .iter()
                        .zip(&want)
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max)
                        / norm;
                    worst = worst.max(e);
                    assert!(
                        e < 1e-15,
                        "preset {i} contact {contact} tau {tau:e} block {k}: {e:e}"
                    );
                }
            }
        }
    }
    println!("batched partial propagators vs exp2: worst {worst:.1e} of the block norm");
}

/// A voice of `sc` in the free or the contact phase, at time scale
/// `scale`, its block state filled with a fixed pattern of size `size`
/// (every block ringing), the hammer at 0.1 mm falling at 0.3 m/s;
/// `None` where that phase is not in blocks.
fn ringing_state(
    sc: &CompiledScene,
    contact: bool,
    seed: usize,
    scale: f64,
    size: f64,
) -> Option<EngineState> {
    let mut st = EngineState::new(sc);
    st.set_time_scale(sc, scale).unwrap();
    st.phase = if contact { Phase::Contact } else { Phase::Free };
    current_phase(&st, sc).gens.as_ref()?;
    st.x_h = 1e-4;
    st.v_h = -0.3;
    let dim = current_phase(&st, sc).dim;
    for j in 0..dim {
        let v = size * ((j * seed % 101) as f64 / 101.0 - 0.5);
        st.phases[st.phase.index()].s[j] = v;
    }
    Some(st)
}

/// The fast path's margin bounds how far `phi` strays from the chord
/// between a step's end values, checked against `phi` through the state
/// (exact partial propagators) at 64 instants of each of 6 later steps,
/// in both phases of every preset, for steps of half, one and three
/// samples (a note pitched an octave and more up), with the margin
/// taken once at the start; and it is never above the curvature bound's.
#[test]
fn fast_margin_bounds_the_chord_error() {
    let (mut tightest, mut used) = (f64::INFINITY, 0.0f64);
    for i in presets::one_contact() {
        let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
        for contact in [false, true] {
            for (seed, mult) in [(7919usize, 0.5), (104_729, 1.0), (1299, 3.0)] {
                let Some(mut st) = ringing_state(&sc, contact, seed, 1.0, 1e-3) else {
                    continue;
                };
                let dt = mult * st.step_s;
                let margin = st.fast_margin(&sc, dt);
                let ph = current_phase(&st, &sc);
                let (e, w) =
                    kernel::block_measures(&st.phases[st.phase.index()].s, &ph.ev_dd_block);
                let curv = (ph.ev_dd_norm * ph.ev_dd_norm * e)
                    .min(ph.ev_dd_block_sum * w)
                    .sqrt();
                let g = if contact { 0.0 } else { st.g };
                let old = (g + curv) * dt * dt / 8.0 * (1.0 + 1e-12);
                assert!(margin <= old, "preset {i}: {margin:e} > {old:e}");
                tightest = tightest.min(margin / old);
                for _ in 0..6 {
                    let f0 = st.eval_event3(&sc, 0.0, false)[0];
                    let f1 = st.eval_event3(&sc, dt, false)[0];
                    for j in 1..64 {
                        let t = dt * j as f64 / 64.0;
                        st.part_ok = false;
                        let f = st.eval_event3(&sc, t, false)[0];
                        let chord = f0 + (f1 - f0) * (j as f64 / 64.0);
                        let dev = (f - chord).abs();
                        used = used.max(dev / margin);
                        assert!(
                            dev <= margin,
                            "preset {i} contact {contact} step x{mult}: |phi - chord| = {dev:e} > {margin:e}"
                        );
                    }
                    st.part_ok = false;
                    st.advance_by(&sc, dt, false);
                    st.part_ok = false;
                }
            }
        }
    }
    println!(
        "fast margin: at most {used:.3} of it used; down to {tightest:.3} of the curvature bound's"
    );
}

/// The Hermite certificate's remainder bounds what the cubic Hermite
/// interpolant of `phi` (value and slope at both ends, evaluated
/// through the state) misses of `phi` at 64 instants of each of 6
/// later steps, in both phases of every preset, for steps of half, one
/// and three samples, the remainder taken from the state at each
/// step's start.
#[test]
fn hermite_remainder_bounds_the_interpolation_error() {
    let mut used = 0.0f64;
    for i in presets::one_contact() {
        let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
        for contact in [false, true] {
            for (seed, mult) in [(7919usize, 0.5), (104_729, 1.0), (1299, 3.0)] {
                let Some(mut st) = ringing_state(&sc, contact, seed, 1.0, 1e-3) else {
                    continue;
                };
                let dt = mult * st.step_s;
                let (dt4, tail) = (dt.powi(4) / 384.0, 8.0 / 27.0 * dt);
                for _ in 0..6 {
                    let ph = current_phase(&st, &sc);
                    let s = &st.phases[st.phase.index()].s;
                    let nb = ph.dim / 2;
                    let rem: f64 = (0..nb)
                        .map(|k| {
                            kernel::hermite_block(
                                ph.ev_d_block[k],
                                ph.ev_d4_block[k],
                                ph.ev_block[k],
                                dt4,
                                tail,
                            ) * s[k].hypot(s[nb + k])
                        })
                        .sum();
                    st.part_ok = false;
                    let [f0, d0, _] = st.eval_event3(&sc, 0.0, false);
                    st.part_ok = false;
                    let [f1, d1, _] = st.eval_event3(&sc, dt, false);
                    for j in 1..64 {
                        let u = j as f64 / 64.0;
                        st.part_ok = false;
                        let f = st.eval_event3(&sc, u * dt, false)[0];
                        let h = f0 * (2.0 * u * u * u - 3.0 * u * u + 1.0)
                            + dt * d0 * (u * u * u - 2.0 * u * u + u)
                            + f1 * (-2.0 * u * u * u + 3.0 * u * u)
                            + dt * d1 * (u * u * u - u * u);
                        let dev = (f - h).abs();
                        used = used.max(dev / rem);
                        assert!(
                            dev <= rem,
                            "preset {i} contact {contact} step x{mult}: |phi - H| = {dev:e} > {rem:e}"
                        );
                    }
                    st.part_ok = false;
                    st.advance_by(&sc, dt, false);
                    st.part_ok = false;
                }
            }
        }
    }
    println!("Hermite remainder: at most {used:.3} of it used");
    assert!(used > 1e-3, "the test should come near its bound somewhere");
}

/// Where the Hermite certificate clears a sample, the search finds no
/// crossing in it and the state is bit for bit the search's: states of
/// every preset in both phases, scaled so that `phi` starts from a
/// margin of 1e-3 down to 1e-12 of the motion (clears and refusals
/// both happen), at one and 2.7 samples' steps.
#[test]
fn hermite_clear_agrees_with_the_search() {
    let (mut cleared, mut refused) = (0usize, 0usize);
    for i in presets::one_contact() {
        let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
        for contact in [false, true] {
            for (seed, scale) in [(7919usize, 1.0), (1299, 2.7)] {
                for gap in [1e-3, 1e-5, 1e-7, 1e-9, 1e-12, -1e-9] {
                    let Some(mut st) = ringing_state(&sc, contact, seed, scale, 1e-4) else {
                        continue;
                    };
                    // put phi(0) at `gap` (times the motion's size)
                    st.part_ok = false;
                    let f = st.eval_event3(&sc, 0.0, false)[0];
                    let size = 1e-4;
                    if contact {
                        // scale the state: phi = ev.s + off
                        let off = sc.offsets.pi / sc.sk;
                        let evs = f - off;
                        if evs.abs() < 1e-300 {
                            continue;
                        }
                        let want = gap * size - off;
                        let k = want / evs;
                        for x in st.phases[st.phase.index()].s.iter_mut() {
                            *x *= k;
                        }
                    } else {
                        st.x_h += gap * size - f;
                    }
                    let mut a = st.clone();
                    let mut b = st.clone();
                    if a.hermite_clear(&sc) {
                        cleared += 1;
                        let step = b.step_s;
                        b.build_model(&sc, step);
                        let mut nodes = 0;
                        let found = b.first_root(&sc, step, false, &mut nodes);
                        assert!(
                            matches!(found, Found::None),
                            "preset {i} contact {contact} gap {gap:e}: cleared, but the search finds a crossing"
                        );
                        b.advance_by(&sc, step, true);
                        let (sa, sb) = (&a.phases[a.phase.index()].s, &b.phases[b.phase.index()].s);
                        assert!(
                            sa.iter().zip(sb).all(|(x, y)| x.to_bits() == y.to_bits())
                                && a.x_h.to_bits() == b.x_h.to_bits()
                                && a.v_h.to_bits() == b.v_h.to_bits(),
                            "preset {i} contact {contact} gap {gap:e}: not the search's state"
                        );
                    } else {
                        refused += 1;
                        let (sa, sb) =
                            (&a.phases[a.phase.index()].s, &st.phases[st.phase.index()].s);
                        assert!(
                            sa.iter().zip(sb).all(|(x, y)| x.to_bits() == y.to_bits()),
                            "a refusal changed the state"
                        );
                    }
                }
            }
        }
    }
    println!("Hermite certificate: {cleared} samples cleared, {refused} left to the search");
    assert!(cleared > 20 && refused > 20);
}

/// The search's model of `phi` (slow polynomial + fast blocks + other
/// blocks + polynomial part) against `phi` through the state (a sweep
/// of exact partial propagators), in both phases of every preset, at
/// several instants of a sample, with the state of a ringing object.
#[test]
fn model_matches_the_state_evaluation() {
    let mut worst = [0.0f64; 3];
    for i in presets::one_contact() {
        let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
        let mut st = EngineState::new(&sc);
        // ring the object: one strike's worth of state in every block
        for contact in [false, true] {
            st.phase = if contact { Phase::Contact } else { Phase::Free };
            st.x_h = 1e-4;
            st.v_h = -0.3;
            let dim = current_phase(&st, &sc).dim;
            for j in 0..dim {
                let v = 1e-3 * ((j * 7919 % 101) as f64 / 101.0 - 0.5);
                st.phases[st.phase.index()].s[j] = v;
            }
            st.part_ok = false;
            let step = st.step_s;
            st.build_model(&sc, step);
            for frac in [0.0, 1e-9, 0.013, 0.5, 0.999, 1.0] {
                let tau = frac * step;
                let want = st.eval_event3(&sc, tau, false);
                let got = st.model_eval(&sc, tau);
                // value and slope within the model's rounding
                // allowances; curvature to 1e-12 of its scale
                let curv_scale = st.search.tol_d / (ROUND_UNITS * f64::EPSILON) / step;
                let tols = [st.search.tol, st.search.tol_d, 1e-12 * curv_scale];
                for d in 0..3 {
                    let e = (got[d] - want[d]).abs();
                    worst[d] = worst[d].max(e / tols[d]);
                    assert!(
                        e <= tols[d],
                        "preset {i} contact {contact} tau {tau:e} deriv {d}: model {} state {} (allowance {:e})",
                        got[d],
                        want[d],
                        tols[d]
                    );
                }
            }
        }
    }
    println!(
        "model vs state evaluation: worst {:.3} / {:.3} / {:.3} of the allowance (value / slope / curvature)",
        worst[0], worst[1], worst[2]
    );
}
