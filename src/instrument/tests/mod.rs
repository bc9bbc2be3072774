//! Tests of the instrument: mappings, voices, swaps, fades.
//!
//! This file holds what the tests share (the scenes and instruments they
//! play, the events they send, the renders and the comparisons); the tests
//! are in its submodules, one per concern.

use super::*;
use crate::compile::{compile_with, CompiledScene};
use crate::physics::model::LN_1000;
use crate::presets;
use crate::scene::{ObjectSpec, Scene, Switching};

mod endings;
mod levels;
mod live_view;
mod mappings;
mod notes;
mod pedals;
mod pitch;
mod pressure;
mod steal;
mod swap;
mod warnings;

const RATE: f64 = 44_100.0;

fn params(preset: &str) -> InstrumentParams {
    let mut p = InstrumentParams::default();
    p.scene.preset = presets::index_of(preset).unwrap();
    p
}

fn base(preset: &str) -> Scene {
    presets::scene(presets::index_of(preset).unwrap()).unwrap()
}

/// A preset with its physical objects expanded to their modes at `RATE`
/// (docs/design.md, "Objects from geometry and material"): for the tests
/// of what the instrument does to a modal object.
fn modal_base(preset: &str) -> Scene {
    base(preset).expanded(RATE).unwrap()
}

fn instrument(p: &InstrumentParams) -> Instrument {
    Instrument::new(prepare(&p.scene, RATE, 0).unwrap(), p.play)
}

pub(super) fn render(inst: &mut Instrument, events: &[TimedEvent], n: usize) -> [Vec<f32>; 2] {
    let mut l = vec![0.0; n];
    let mut r = vec![0.0; n];
    inst.process(events, &mut l, &mut r);
    [l, r]
}

/// The gain of a voice stolen at sample `t0` at sample `k`: 1 before the
/// steal, then a linear ramp to 0 over `fade` samples (docs/plugin.md,
/// "Velocity, pitch, voices"), written out here, not taken from the mixer.
pub(super) fn steal_fade_gain(k: usize, t0: usize, fade: usize) -> f64 {
    if k < t0 {
        1.0
    } else {
        (fade.saturating_sub(k - t0)) as f64 / fade as f64
    }
}

/// One mode's free decay after its strike, `y` at `rate_hz` (the output
/// of a note from its onset until its voice stops), against the closed
/// form of a damped mode of frequency `f` and T60 `t60`: `y_(n+1) = 2 r
/// cos(w dt) y_n - r^2 y_(n-1)`, `w = sqrt(omega^2 - sigma^2)`, `r =
/// exp(-rate dt)`. The worst residual over the peak from sample 2000 to
/// the voice's end for `rate` = `sigma` and for `sigma + added_per_s`
/// (a pressed voice's, at the same `w`).
pub(super) fn one_mode_residuals(
    y: &[f32],
    rate_hz: f64,
    (f, t60): (f64, f64),
    added_per_s: f64,
) -> (f64, f64) {
    let y: Vec<f64> = y.iter().map(|&v| f64::from(v)).collect();
    let dt = 1.0 / rate_hz;
    let omega = 2.0 * std::f64::consts::PI * f;
    let sigma = LN_1000 / t60;
    let w = (omega * omega - sigma * sigma).sqrt();
    let peak = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    // until the voice stops (-90 dB: the silence test)
    let end = y.iter().rposition(|&v| v != 0.0).unwrap() - 1;
    assert!(end > 5000, "{end}");
    let worst = |rate: f64| {
        let r = (-rate * dt).exp();
        (2000..end)
            .map(|i| (y[i + 1] - 2.0 * r * (w * dt).cos() * y[i] + r * r * y[i - 1]).abs())
            .fold(0.0f64, f64::max)
            / peak
    };
    (worst(sigma), worst(sigma + added_per_s))
}

pub(super) fn on(offset: usize, key: u8, vel: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteOn {
            key,
            velocity_norm: vel,
        },
    }
}

pub(super) fn off(offset: usize, key: u8) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteOff { key },
    }
}

/// The left channel of `n` samples rendered in blocks of the lengths
/// `lens` (cycled), each block given the events that fall in it.
fn render_split(
    inst: &mut Instrument,
    events: &[TimedEvent],
    n: usize,
    lens: &[usize],
) -> Vec<f32> {
    let (mut left, mut right) = (vec![0.0f32; n], vec![0.0f32; n]);
    let (mut pos, mut ev) = (0, 0);
    for len in lens.iter().cycle() {
        if pos >= n {
            break;
        }
        let end = (pos + len).min(n);
        let mut evs = Vec::new();
        while ev < events.len() && events[ev].offset < end {
            evs.push(TimedEvent {
                offset: events[ev].offset - pos,
                ..events[ev]
            });
            ev += 1;
        }
        inst.process(&evs, &mut left[pos..end], &mut right[pos..end]);
        pos = end;
    }
    left
}

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

fn pedal(offset: usize, sustain: bool, down: bool) -> TimedEvent {
    TimedEvent {
        offset,
        event: if sustain {
            Event::Sustain { down }
        } else {
            Event::Sostenuto { down }
        },
    }
}

/// Render `events` (sorted) and return the left channel.
fn play(events: &[TimedEvent], n: usize) -> Vec<f32> {
    // the bar damped on release (the Damper parameter's 0.5; the preset has
    // no damper of its own), so that there is something for the pedals to hold
    let mut p = params("marimba-bar");
    p.scene.damper_custom = true;
    let mut inst = instrument(&p);
    render(&mut inst, events, n)[0].clone()
}

fn bend(offset: usize, value: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::PitchBend { value },
    }
}

fn tuning(offset: usize, key: Option<u8>, semitones: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NoteTuning { key, semitones },
    }
}

fn pressure(offset: usize, key: Option<u8>, value: f64) -> TimedEvent {
    TimedEvent {
        offset,
        event: Event::NotePressure { key, value },
    }
}

pub(super) fn at(offset: usize, event: Event) -> TimedEvent {
    TimedEvent { offset, event }
}

/// The largest distance of `y` from `expect` over both channels and every
/// sample, and a tolerance: `1e-6` of (`1e-2` plus) the largest `|y|`.
pub(super) fn worst_and_tol(y: &[Vec<f32>; 2], expect: impl Fn(usize, usize) -> f64) -> (f64, f64) {
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for (ch, x) in y.iter().enumerate() {
        for (k, &v) in x.iter().enumerate() {
            worst = worst.max((f64::from(v) - expect(ch, k)).abs());
            peak = peak.max(f64::from(v).abs());
        }
    }
    (worst, 1e-6 * (1e-2 + peak))
}

/// The largest `|x|` over both channels at the samples of `ks`, each
/// times `w(k)`.
pub(super) fn largest(
    x: &[Vec<f32>; 2],
    ks: std::ops::Range<usize>,
    w: impl Fn(usize) -> f64,
) -> f64 {
    ks.flat_map(|k| x.iter().map(move |c| (k, c[k])))
        .map(|(k, v)| (w(k) * f64::from(v)).abs())
        .fold(0.0, f64::max)
}
