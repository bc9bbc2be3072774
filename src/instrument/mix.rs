//! Rendering: voices ticked in chunks of the silence-check grid, the fade of
//! voices that could not be carried across a swap, the gain and the output
//! ceiling.

use super::events::TimedEvent;
use super::probe::VoiceChunk;
use super::{
    Instrument, BEND_TICK_SAMPLES, CHECK_INTERVAL_SAMPLES, MAX_PRESSURE_DECAY_PER_S, MAX_VOICES,
    OUTPUT_CEILING,
};
use crate::compile::CompiledScene;
use crate::engine::denormal::FlushDenormals;
use crate::engine::{EngineState, Motion};

impl Instrument {
    /// Render consecutive samples into `left`/`right` (overwritten).
    /// Allocation-free. \[audio-thread\]
    pub fn render(&mut self, left: &mut [f32], right: &mut [f32]) {
        let n = left.len().min(right.len());
        let mut i = 0;
        while i < n {
            // a moving bend updates the voices on a finer grid
            let grid = if self.bend_moving() {
                BEND_TICK_SAMPLES
            } else {
                CHECK_INTERVAL_SAMPLES
            };
            let phase = (self.sample_pos % grid as u64) as usize;
            let len = (grid - phase).min(n - i);
            self.render_chunk(&mut left[i..i + len], &mut right[i..i + len]);
            i += len;
            self.sample_pos += len as u64;
            if self.sample_pos.is_multiple_of(BEND_TICK_SAMPLES as u64) && self.bend_moving() {
                self.bend_tick();
            }
            if self
                .sample_pos
                .is_multiple_of(CHECK_INTERVAL_SAMPLES as u64)
            {
                self.stop_silent_voices();
                if self.timbre_pending {
                    self.apply_timbre();
                }
            }
        }
    }

    /// Render `left.len()` samples, applying `events` (sorted by offset, offsets
    /// within the span) at their sample offsets. \[audio-thread\]
    pub fn process(&mut self, events: &[TimedEvent], left: &mut [f32], right: &mut [f32]) {
        self.process_events(events.iter().copied(), left, right);
    }

    /// [`process`](Self::process) for events that come one at a time (the
    /// plugin reads them from the host as it goes): each is applied at its
    /// offset, clamped to the span and to the previous one's. Subnormal
    /// numbers are flushed for the whole span. Allocation-free unless the
    /// iterator allocates. \[audio-thread\]
    pub fn process_events(
        &mut self,
        events: impl IntoIterator<Item = TimedEvent>,
        left: &mut [f32],
        right: &mut [f32],
    ) {
        // Subnormals off for the whole block (each voice's engine would set
        // it too; once here, the voices find it on and leave it).
        let _flush = FlushDenormals::new(true);
        let n = left.len().min(right.len());
        let mut pos = 0;
        for ev in events {
            let at = ev.offset.clamp(pos, n);
            self.render(&mut left[pos..at], &mut right[pos..at]);
            pos = at;
            self.handle(ev.event);
        }
        self.render(&mut left[pos..n], &mut right[pos..n]);
    }

    fn render_chunk(&mut self, left: &mut [f32], right: &mut [f32]) {
        let len = left.len();
        for ch in &mut self.acc {
            ch[..len].iter_mut().for_each(|x| *x = 0.0);
        }
        let p = &mut *self.cur;
        for i in 0..MAX_VOICES {
            let v = &mut self.voices[i];
            if !v.active {
                continue;
            }
            let scene = p.scenes.bound(v.at, v.on_damped);
            let st = &mut p.states[i];
            let observe = if self.probe_on {
                Some(&mut self.motion[..len])
            } else {
                None
            };
            let start = self.sample_pos;
            // damper pressure (docs/plugin.md, "Pressure and the mod
            // wheel"): applied exactly where the hammer has left for good
            // (no gravity, above the object's rest position and rising) and
            // the chunk held no contact
            let press = v.pressure.max(self.channel_pressure).max(self.mod_wheel);
            let leaving = press > 0.0
                && !p.bouncing
                && st
                    .hammer_in_flight()
                    .is_some_and(|(x, up)| x > 0.0 && up >= 0.0);
            let contacts = st.contacts_started;
            let observing = observe.is_some();
            if tick_into(st, scene, &mut self.vbuf, len, 1.0, 0.0, observe) {
                if leaving && !st.in_contact() && st.contacts_started == contacts {
                    let q = (-MAX_PRESSURE_DECAY_PER_S * press / p.rate_hz).exp();
                    let motion = observing.then_some(&mut self.motion[..len]);
                    let g = decay_into(&mut self.vbuf, len, q, motion);
                    st.scale_free_state(g);
                }
                add_into(&mut self.acc, &self.vbuf, len);
                if let Some(probe) = self.probe.as_deref_mut().filter(|_| self.probe_on) {
                    probe.voice_chunk(&VoiceChunk {
                        voice: i,
                        key: v.key,
                        released: v.released,
                        start,
                        motion: &self.motion[..len],
                        energy_j: st.energy_rt(scene),
                    });
                }
            } else {
                st.reset(&p.scenes.scene);
                v.active = false;
                self.stats.nonfinite_resets += 1;
            }
        }
        if let Some(f) = self.fading.as_deref_mut() {
            for i in 0..MAX_VOICES {
                let Some((at, on_damped)) = self.fade_voices[i] else {
                    continue;
                };
                if self.fade_left == 0 {
                    break;
                }
                let scene = f.scenes.bound(at, on_damped);
                let g0 = self.fade_left as f64 / self.fade_len as f64;
                let dg = 1.0 / self.fade_len as f64;
                if tick_into(&mut f.states[i], scene, &mut self.vbuf, len, g0, dg, None) {
                    add_into(&mut self.acc, &self.vbuf, len);
                } else {
                    self.fade_voices[i] = None;
                    self.stats.nonfinite_resets += 1;
                }
            }
            self.fade_left = self.fade_left.saturating_sub(len);
            if self.fade_left == 0 {
                self.fade_voices = [None; MAX_VOICES];
                if let Some(slot) = self.retired.iter_mut().find(|s| s.is_none()) {
                    *slot = self.fading.take();
                }
            }
        }
        let g = self.gain;
        let mut hits = 0u64;
        for k in 0..len {
            left[k] = guarded(self.acc[0][k] * g, &mut hits);
            right[k] = guarded(self.acc[1][k] * g, &mut hits);
        }
        self.stats.ceiling_hits += hits;
    }
}

/// The output guard: `x` when within [`OUTPUT_CEILING`], else the ceiling
/// with `x`'s sign (0 for NaN), counted in `hits`. A value below the
/// smallest normal f32 (1.2e-38) is written as 0: it would be a subnormal
/// f32, which some hosts and effects after the plugin process slowly. The
/// flush-to-zero mode the instrument runs with does this already on
/// x86-64 and aarch64; this makes it hold on every target and whatever the
/// caller's floating-point modes.
#[inline]
pub(super) fn guarded(x: f64, hits: &mut u64) -> f32 {
    if x.abs() < f64::from(f32::MIN_POSITIVE) {
        0.0
    } else if x.abs() <= OUTPUT_CEILING {
        x as f32
    } else {
        *hits += 1;
        if x.is_nan() {
            0.0
        } else {
            OUTPUT_CEILING.copysign(x) as f32
        }
    }
}

/// Tick `len` samples of one voice into `buf` with a linear gain ramp
/// `g0 - k dg`, writing each sample's motion into `observe` if given (the
/// same samples either way); false if a sample was not finite.
fn tick_into(
    st: &mut EngineState,
    scene: &CompiledScene,
    buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
    g0: f64,
    dg: f64,
    observe: Option<&mut [Motion]>,
) -> bool {
    let [l, r] = buf;
    match observe {
        Some(m) => st.process_block_observed(scene, &mut l[..len], &mut r[..len], m),
        None => st.process_block(scene, &mut l[..len], &mut r[..len]),
    }
    let mut finite = true;
    for k in 0..len {
        finite &= l[k].is_finite() && r[k].is_finite();
        if dg != 0.0 || g0 != 1.0 {
            let g = (g0 - k as f64 * dg).max(0.0);
            l[k] *= g;
            r[k] *= g;
        }
    }
    finite
}

/// The samples of a chunk rendered without the pressure, as with it: sample
/// `k` (the state at the chunk's start `k` samples on) times `q^k`, and
/// the contact point's motion likewise; returns `q^len`, the factor the
/// state after the chunk takes.
fn decay_into(
    buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
    q: f64,
    mut motion: Option<&mut [Motion]>,
) -> f64 {
    let mut g = 1.0;
    for k in 0..len {
        buf[0][k] *= g;
        buf[1][k] *= g;
        if let Some(m) = motion.as_deref_mut() {
            m[k].x_contact *= g;
            m[k].v_contact *= g;
        }
        g *= q;
    }
    g
}

fn add_into(
    acc: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    buf: &[[f64; CHECK_INTERVAL_SAMPLES]; 2],
    len: usize,
) {
    for ch in 0..2 {
        for k in 0..len {
            acc[ch][k] += buf[ch][k];
        }
    }
}
