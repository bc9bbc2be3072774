//! How long the host's main thread waits in `activate` and `deactivate` of
//! the BUILT release plugin (clack-host), over every scene and a seeded
//! sweep of every parameter (docs/plugin.md, "Parameter changes: the swap
//! design").
//!
//! Each trial loads an instance, loads a state with random parameter
//! values in their ranges (the scene too), activates (timed), sends in
//! one block random values for every parameter, a third of them not a
//! number, infinite or out of range, as a host or a fuzzer may, deactivates
//! (timed), and activates again for those values (timed: this is the
//! activation a fuzzer's parameter values get) and deactivates at once,
//! while that compile may still run (timed). Every scene's own defaults
//! are trials too.
//!
//! `cargo bench -p plugin-tests --bench activation [-- TRIALS [SEED]]`
//! prints the worst and median of each, per scene and over all.

use modal_contact::instrument::MAX_LOOKAHEAD_S;
use modal_contact::plugin::params::{Kind, ParamSpec, PARAMS};
use modal_contact::presets::PRESETS;
use modal_testkit::rng::TestRng;
use plugin_tests::*;
use std::time::Instant;

const RATE: f64 = 48_000.0;
const BLOCK: usize = 256;

/// A saved state (nice-plug's: the JSON's length, then the JSON) with
/// `value(spec)` for every parameter.
fn state_with(value: impl FnMut(&ParamSpec) -> String) -> Vec<u8> {
    let params: Vec<String> = PARAMS
        .iter()
        .map(value)
        .zip(PARAMS)
        .map(|(v, spec)| format!(r#""{}":{v}"#, spec.id))
        .collect();
    let json = format!(
        r#"{{"version":"0.1.0","params":{{{}}},"fields":{{}}}}"#,
        params.join(",")
    );
    let mut out = (json.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(json.as_bytes());
    out
}

/// A random value of each parameter in its range, scene `scene`.
fn random_state(rng: &mut TestRng, scene: usize) -> Vec<u8> {
    state_with(|spec| match spec.kind {
        Kind::Float { min, max, .. } => {
            format!(r#"{{"f32":{}}}"#, spread(rng.uniform(0.0, 1.0), min, max))
        }
        Kind::Int { min, max, .. } => {
            let n = min + (rng.uniform(0.0, 1.0) * f64::from(max - min + 1)) as i32;
            format!(r#"{{"i32":{}}}"#, n.min(max))
        }
        Kind::Bool { .. } => format!(r#"{{"bool":{}}}"#, rng.uniform(0.0, 1.0) < 0.5),
        Kind::Choice { ids, .. } => {
            let i = if spec.id == "scene" {
                scene
            } else {
                ((rng.uniform(0.0, 1.0) * ids.len() as f64) as usize).min(ids.len() - 1)
            };
            format!(r#"{{"string":"{}"}}"#, ids[i])
        }
    })
}

/// Every parameter at its default, scene `scene`.
fn scene_state(scene: usize) -> Vec<u8> {
    state_with(|spec| match spec.kind {
        Kind::Float { default, .. } => format!(r#"{{"f32":{default}}}"#),
        Kind::Int { default, .. } => format!(r#"{{"i32":{default}}}"#),
        Kind::Bool { default } => format!(r#"{{"bool":{default}}}"#),
        Kind::Choice { ids, default, .. } => {
            let k = if spec.id == "scene" { scene } else { default };
            format!(r#"{{"string":"{}"}}"#, ids[k])
        }
    })
}

/// `u` in 0..1 spread over `min..max` (evenly in the logarithm for ranges
/// of positive factors, so that 0.01 .. 100 x is sampled at both ends).
fn spread(u: f64, min: f32, max: f32) -> f32 {
    let (a, b) = (f64::from(min), f64::from(max));
    let v = if a > 0.0 && b / a >= 50.0 {
        (a.ln() + u * (b.ln() - a.ln())).exp()
    } else {
        a + u * (b - a)
    };
    v as f32
}

/// One block's parameter events: every parameter, a third of them a value
/// no knob has (not a number, infinite, far out of range).
fn wild_events(rng: &mut TestRng) -> Vec<HostEvent> {
    PARAMS
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            let u = rng.uniform(0.0, 1.0);
            let value = if u < 1.0 / 9.0 {
                f64::NAN
            } else if u < 2.0 / 9.0 {
                if u < 1.5 / 9.0 {
                    f64::INFINITY
                } else {
                    f64::NEG_INFINITY
                }
            } else if u < 3.0 / 9.0 {
                1e9 * (rng.uniform(0.0, 1.0) - 0.5)
            } else {
                match spec.kind {
                    Kind::Float { min, max, .. } => {
                        f64::from(spread(rng.uniform(0.0, 1.0), min, max))
                    }
                    Kind::Int { min, max, .. } => {
                        f64::from(min) + (rng.uniform(0.0, 1.0) * f64::from(max - min)).round()
                    }
                    Kind::Bool { .. } => (rng.uniform(0.0, 1.0) < 0.5) as u8 as f64,
                    Kind::Choice { ids, .. } => {
                        (rng.uniform(0.0, 1.0) * (ids.len() - 1) as f64).round()
                    }
                }
            };
            param(i, spec.id, value)
        })
        .collect()
}

#[derive(Default)]
struct Times {
    activate: Vec<f64>,
    deactivate: Vec<f64>,
    activate_wild: Vec<f64>,
    deactivate_wild: Vec<f64>,
    /// Whether a note struck at the first sample after `activate` returned
    /// is heard in that block or the next ones of the plugin's latency.
    first_block_sounds: Vec<bool>,
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn trial(bundle: &std::path::Path, state: Option<&[u8]>, rng: &mut TestRng, t: &mut Times) {
    // a live host's instance (real-time mode)
    let mut p = LoadedPlugin::load_realtime(bundle);
    if let Some(s) = state {
        p.load_state(s);
    }
    let t0 = Instant::now();
    let mut s = p.activate(RATE, 1, BLOCK);
    t.activate.push(ms_since(t0));
    // the note comes out after the plugin's latency (the Lookahead, at
    // most MAX_LOOKAHEAD_S): blocks processed back to back, so it is heard
    // in them only if the scene was there when activate returned
    let blocks = 1 + (MAX_LOOKAHEAD_S * RATE).ceil() as usize / BLOCK + 1;
    let mut heard = false;
    for b in 0..blocks {
        let ev = if b == 0 { vec![on(0, 60, 0.9)] } else { vec![] };
        let out = s.process(BLOCK, 0, &ev);
        heard |= out.iter().any(|c| c.iter().any(|x| *x != 0.0));
    }
    t.first_block_sounds.push(heard);
    let events = wild_events(rng);
    s.process(BLOCK, 0, &events);
    let t0 = Instant::now();
    s.deactivate();
    t.deactivate.push(ms_since(t0));
    let t0 = Instant::now();
    let mut s = p.activate(RATE, 1, BLOCK);
    t.activate_wild.push(ms_since(t0));
    s.process(BLOCK, 0, &[]);
    let t0 = Instant::now();
    s.deactivate();
    t.deactivate_wild.push(ms_since(t0));
}

fn stats(x: &[f64]) -> (f64, f64) {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], *v.last().unwrap_or(&f64::NAN))
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let trials: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(4);
    let seed: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(48);
    let bundle = clap_bundle(Variant::Release);
    let mut rng = TestRng(seed);
    let mut all = Times::default();
    println!(
        "activation of the release plugin through clack-host, {RATE} Hz, blocks of {BLOCK}: \
         each scene at its defaults and {trials} random parameter sets per scene (seed {seed})"
    );
    println!(
        "| scene | activate median / worst [ms] | deactivate | activate (wild values) | \
         deactivate (its compile running) | a note at once |"
    );
    println!("|---|---|---|---|---|---|");
    for (i, preset) in PRESETS.iter().enumerate() {
        let mut t = Times::default();
        trial(&bundle, Some(&scene_state(i)), &mut rng, &mut t);
        for _ in 0..trials {
            let s = random_state(&mut rng, i);
            trial(&bundle, Some(&s), &mut rng, &mut t);
        }
        let cell = |x: &[f64]| {
            let (m, w) = stats(x);
            format!("{m:.1} / {w:.1}")
        };
        let sounds = t.first_block_sounds.iter().filter(|s| **s).count();
        println!(
            "| {} | {} | {} | {} | {} | {sounds} / {} |",
            preset.name,
            cell(&t.activate),
            cell(&t.deactivate),
            cell(&t.activate_wild),
            cell(&t.deactivate_wild),
            t.first_block_sounds.len()
        );
        all.activate.extend(t.activate);
        all.deactivate.extend(t.deactivate);
        all.activate_wild.extend(t.activate_wild);
        all.deactivate_wild.extend(t.deactivate_wild);
        all.first_block_sounds.extend(t.first_block_sounds);
    }
    let worst = |x: &[f64]| stats(x).1;
    println!(
        "worst over {} activations: activate {:.1} ms, deactivate {:.1} ms",
        2 * all.activate.len(),
        worst(&all.activate).max(worst(&all.activate_wild)),
        worst(&all.deactivate).max(worst(&all.deactivate_wild)),
    );
    println!(
        "a note at the first sample after activate is heard at once (after the latency) in {} \
         of {} first activations",
        all.first_block_sounds.iter().filter(|s| **s).count(),
        all.first_block_sounds.len()
    );
}
