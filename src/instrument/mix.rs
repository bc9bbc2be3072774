//! Rendering. The instrument keeps two kinds of clock: its own (the
//! events, the bend, the fade of a swap: `Instrument::sample_pos`) and one
//! per voice, which may stay behind it by up to the lookahead
//! ([`Instrument::set_lookahead`]; docs/plugin.md, "Lookahead"). Each
//! voice renders into its own lane (a ring of samples) in the chunks the
//! instrument's clock made (the silence-check grid, the events, the host's
//! blocks), and each output sample is its lanes summed in voice order,
//! times the gain at that sample, `lookahead` samples after the
//! instrument's clock. A voice does on its own clock what concerns only
//! itself (its samples, its pressure, its silence check, a brightness it
//! waits for); whatever concerns several voices or reads their state (a
//! note-on, a pressure or mod wheel that moves, a bend's update, a swap)
//! first brings them up to the instrument's clock. So every voice computes
//! the same samples, bit for bit, however far behind it runs, and the
//! output is the plain instrument's delayed by the lookahead (docs/plugin.md
//! says where it can differ in the last bit: the fade of a swap). With the
//! lookahead at 0 every voice keeps up with the clock: the plain
//! instrument.

use super::events::TimedEvent;
use super::probe::VoiceChunk;
use super::voices::{StealFade, FADE_LANE};
use super::{
    Event, Instrument, Prepared, BEND_TICK_SAMPLES, CHECK_INTERVAL_SAMPLES, MAX_VOICES,
    OUTPUT_CEILING, STEAL_FADES,
};
use crate::compile::CompiledScene;
use crate::engine::denormal::FlushDenormals;
use crate::engine::{EngineState, Motion};
use crate::multi::{CompiledMulti, MultiState};

/// Longest lookahead \[samples\] (85 ms at 48 kHz, 21 ms at 192 kHz; the
/// plugin's parameter stops at [`MAX_LOOKAHEAD_S`] before).
pub const MAX_LOOKAHEAD_SAMPLES: usize = 4096;
/// Longest lookahead the plugin offers \[s\] (its Lookahead parameter's
/// top; at most [`MAX_LOOKAHEAD_SAMPLES`] at any rate).
pub const MAX_LOOKAHEAD_S: f64 = 0.040;
/// While voices may run behind, they work ahead of the output only while
/// the block has taken less than this fraction of its real-time budget
/// ([`WorkMeter`]); what is left waits for later blocks, up to the
/// lookahead.
pub const LOOKAHEAD_WORK_FRACTION: f64 = 0.35;

/// How the lookahead measures a block's work when it decides whether the
/// voices may work ahead (docs/plugin.md, "Lookahead"). Either way it
/// decides only when work is done, never what is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WorkMeter {
    /// The monotonic clock since the block began (`std::time::Instant`:
    /// a read of the CPU's counter through the vDSO on Linux,
    /// `QueryPerformanceCounter` on Windows, `mach_absolute_time` on macOS;
    /// no system call, no lock): what the host's deadline is about. The
    /// default.
    Clock,
    /// A cost model of what the voices computed
    /// ([`Prepared::step_cost_ns`](super::Prepared::step_cost_ns) per
    /// sample, [`Prepared::contact_cost_ns`](super::Prepared::contact_cost_ns)
    /// per contact): the same schedule on every machine (tests).
    Estimate,
}
/// The instrument's clock runs at most this many samples past the output
/// before the output is read (a host block longer than this is read in
/// pieces), so a lane holds the lookahead plus this.
const OUT_EVERY: usize = 256;
/// Samples a lane's ring can hold: the longest lookahead plus a piece.
const RING_CAP: usize = (MAX_LOOKAHEAD_SAMPLES + OUT_EVERY).next_power_of_two();
const LANES: usize = MAX_VOICES + 1;

/// Each voice's clock and samples, the chunks and gains of the
/// instrument's clock, and where the output is. Allocated once.
pub(super) struct Lanes {
    /// Samples the output runs behind the instrument's clock.
    lookahead: usize,
    /// Ring length - 1 (a power of two: the lookahead plus a piece).
    mask: usize,
    /// Time of the next output sample (negative: the silence before the
    /// first sample, one lookahead long).
    out_pos: i64,
    /// Output before this time is silence (a host reset, a new lookahead).
    out_floor: i64,
    /// A lane holds samples for the times `start .. end`; a voice's `end`
    /// is its clock (the next sample it renders), the fade lane's the
    /// fade's.
    start: [u64; LANES],
    end: [u64; LANES],
    /// The voice has done its grid actions at its clock (or needs none
    /// there: it was just struck, or brought up to an event).
    settled: [bool; MAX_VOICES],
    /// `LANES` rings of `RING_CAP` stereo samples (each used up to `mask`).
    ring: Box<[[f64; 2]]>,
    /// The instrument's gain at each time.
    gain: Box<[f64]>,
    /// The length of the instrument's chunk that starts at each time (a
    /// voice renders in the same chunks).
    chunk: Box<[u8]>,
    /// Estimated work of the voices' chunks in this block \[ns\].
    work_ns: f64,
    /// When the block began ([`WorkMeter::Clock`]).
    block_start: Option<std::time::Instant>,
    /// How a block's work is measured.
    meter: WorkMeter,
    /// Work ahead while the block's work is below this fraction of its
    /// budget ([`LOOKAHEAD_WORK_FRACTION`] unless set).
    work_fraction: f64,
}

impl Lanes {
    pub(super) fn new() -> Self {
        let mut lanes = Self {
            lookahead: 0,
            mask: 0,
            out_pos: 0,
            out_floor: 0,
            start: [0; LANES],
            end: [0; LANES],
            settled: [true; MAX_VOICES],
            ring: vec![[0.0; 2]; LANES * RING_CAP].into_boxed_slice(),
            gain: vec![0.0; RING_CAP].into_boxed_slice(),
            chunk: vec![0; RING_CAP].into_boxed_slice(),
            work_ns: 0.0,
            block_start: None,
            meter: WorkMeter::Clock,
            work_fraction: LOOKAHEAD_WORK_FRACTION,
        };
        lanes.restart(0, 0);
        lanes
    }

    fn at(&self, lane: usize, t: u64) -> usize {
        lane * RING_CAP + (t as usize & self.mask)
    }

    /// Lane `lane` sounds again from time `t`: its run goes on (silence
    /// in between) while some of it is still to be read, else a new run
    /// starts at `t`.
    pub(super) fn begin(&mut self, lane: usize, t: u64) {
        if self.end[lane] as i64 > self.out_pos {
            for u in self.end[lane]..t {
                let k = self.at(lane, u);
                self.ring[k] = [0.0; 2];
            }
        } else {
            self.start[lane] = t;
        }
        self.end[lane] = t;
        if lane < MAX_VOICES {
            self.settled[lane] = true;
        }
    }

    /// Every lane empty at time `now`, the output silent before it, the
    /// output `lookahead` samples behind it.
    fn restart(&mut self, now: u64, lookahead: usize) {
        self.lookahead = lookahead;
        self.mask = (lookahead + OUT_EVERY).next_power_of_two() - 1;
        self.out_pos = now as i64 - lookahead as i64;
        self.out_floor = now as i64;
        self.start = [now; LANES];
        self.end = [now; LANES];
        self.settled = [true; MAX_VOICES];
    }

    /// Write `len` samples of `buf` into lane `lane` from its end on.
    fn push(&mut self, lane: usize, buf: &[[f64; CHECK_INTERVAL_SAMPLES]; 2], len: usize) {
        let t0 = self.end[lane];
        for k in 0..len {
            let j = self.at(lane, t0 + k as u64);
            self.ring[j] = [buf[0][k], buf[1][k]];
        }
        self.end[lane] = t0 + len as u64;
    }
}

impl Instrument {
    /// Samples the output runs behind the instrument's clock (the latency
    /// the plugin reports to its host).
    pub fn lookahead(&self) -> usize {
        self.lanes.lookahead
    }

    /// How far the voice furthest behind is behind the instrument's clock
    /// \[samples\] (0 without a lookahead, at most the lookahead plus a
    /// chunk between blocks). \[audio-thread\]
    pub fn lag(&self) -> usize {
        (0..MAX_VOICES)
            .filter(|&i| self.voices[i].active)
            .map(|i| (self.sample_pos - self.lanes.end[i]) as usize)
            .max()
            .unwrap_or(0)
    }

    /// Let the voices run up to `samples` (at most
    /// [`MAX_LOOKAHEAD_SAMPLES`]) behind the instrument's clock and delay
    /// the output by as much, so that the work of a chord's strikes spreads
    /// over the blocks of the lookahead (docs/plugin.md, "Lookahead"). The
    /// output is the same as without, that many samples later. A change
    /// brings every voice up to the clock and drops the output still to be
    /// read (a host restarts its audio when a plugin's latency changes).
    /// Allocation-free. \[audio-thread\]
    pub fn set_lookahead(&mut self, samples: usize) {
        let l = samples.min(MAX_LOOKAHEAD_SAMPLES);
        if l == self.lanes.lookahead {
            return;
        }
        self.sync_all(true);
        self.lanes.restart(self.sample_pos, l);
    }

    /// How much of each block's real-time budget the voices may fill by
    /// working ahead with a lookahead (estimated; [`LOOKAHEAD_WORK_FRACTION`]
    /// unless set; 0: only what the output needs now, every voice the
    /// whole lookahead behind; not a number: 0). It decides when the work
    /// is done, never what is computed. \[audio-thread\]
    pub fn set_lookahead_work(&mut self, fraction: f64) {
        self.lanes.work_fraction = if fraction > 0.0 { fraction } else { 0.0 };
    }

    /// How a block's work is measured for the lookahead ([`WorkMeter`];
    /// the clock unless set). \[audio-thread\]
    pub fn set_work_meter(&mut self, meter: WorkMeter) {
        self.lanes.meter = meter;
    }

    /// The voices and the output start over at the instrument's clock
    /// (every voice stopped: [`Instrument::silence`]).
    pub(super) fn restart_lanes(&mut self) {
        let l = self.lanes.lookahead;
        self.lanes.restart(self.sample_pos, l);
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
        let (left, right) = (&mut left[..n], &mut right[..n]);
        let out0 = self.lanes.out_pos;
        self.lanes.work_ns = 0.0;
        self.lanes.block_start = (self.lanes.lookahead > 0 && self.lanes.meter == WorkMeter::Clock)
            .then(std::time::Instant::now);
        let mut pos = 0;
        for ev in events {
            let at = ev.offset.clamp(pos, n);
            self.run_clock(at - pos, out0, left, right);
            pos = at;
            self.handle(ev.event);
        }
        self.run_clock(n - pos, out0, left, right);
        self.emit(out0 + n as i64, out0, left, right);
        self.work_ahead(n);
    }

    /// Apply one event now (between two samples), first bringing the
    /// voices it concerns up to the instrument's clock. \[audio-thread\]
    pub fn handle(&mut self, event: Event) {
        match event {
            // a key that comes up concerns its own voices only
            Event::NoteOff { key } | Event::NoteOn { key, .. } if !matches!(event, Event::NoteOn { velocity_norm, .. } if velocity_norm > 0.0) => {
                for i in 0..MAX_VOICES {
                    if self.voices[i].key == key {
                        self.advance_voice(i, self.sample_pos, true);
                    }
                }
            }
            // the wheel moves the voices on the bend's grid, which brings
            // them up first; a pedal going down touches no voice
            Event::PitchBend { .. }
            | Event::Sustain { down: true }
            | Event::Sostenuto { down: true } => {}
            _ => self.sync_all(true),
        }
        self.apply(event);
    }

    /// Run the instrument's clock `len` samples on: its chunks (on the
    /// silence-check grid, the bend's while it moves), their gain, the fade
    /// of a swap, the bend's updates; the output is read whenever the clock
    /// would run a piece past it.
    fn run_clock(&mut self, len: usize, out0: i64, left: &mut [f32], right: &mut [f32]) {
        let mut rest = len;
        while rest > 0 {
            // a moving bend updates the voices on a finer grid
            let grid = if self.bend_moving() {
                BEND_TICK_SAMPLES
            } else {
                CHECK_INTERVAL_SAMPLES
            };
            let phase = (self.sample_pos % grid as u64) as usize;
            let step = (grid - phase).min(rest);
            let l = &self.lanes;
            if self.sample_pos as i64 + step as i64 - l.out_pos > (l.lookahead + OUT_EVERY) as i64 {
                let upto = self.sample_pos as i64 - l.lookahead as i64;
                self.emit(upto, out0, left, right);
            }
            self.clock_chunk(step);
            rest -= step;
            if self.sample_pos.is_multiple_of(BEND_TICK_SAMPLES as u64) && self.bend_moving() {
                self.sync_all(false);
                self.bend_tick();
            }
        }
    }

    /// One chunk of the instrument's clock (`len` at most
    /// [`CHECK_INTERVAL_SAMPLES`]).
    fn clock_chunk(&mut self, len: usize) {
        let t0 = self.sample_pos;
        let l = &mut self.lanes;
        l.chunk[t0 as usize & l.mask] = len as u8;
        for k in 0..len as u64 {
            l.gain[(t0 + k) as usize & l.mask] = self.gain;
        }
        let steals = self.steal_fades.iter().any(Option::is_some);
        if self.fading.is_none() && !steals {
            self.sample_pos += len as u64;
            return;
        }
        if t0.is_multiple_of(CHECK_INTERVAL_SAMPLES as u64) {
            // the fading voices' damper decisions on the silence-check
            // grid, as the voices' own
            self.repress_fades();
        }
        for ch in &mut self.acc {
            ch[..len].iter_mut().for_each(|x| *x = 0.0);
        }
        if let Some(f) = self.fading.as_deref_mut() {
            for i in 0..MAX_VOICES {
                let Some((at, on_damped)) = self.fade_voices[i] else {
                    continue;
                };
                if self.fade_left == 0 {
                    break;
                }
                let g0 = self.fade_left as f64 / self.fade_len as f64;
                let dg = 1.0 / self.fade_len as f64;
                if let Some(kit) = f.kit.as_deref_mut() {
                    let kat = super::kit::KitAt::of(at, on_damped);
                    if kit.tick_into(
                        (i, kat),
                        &mut self.vbuf,
                        len,
                        (g0, dg),
                        None::<fn(usize, &MultiState, &CompiledMulti)>,
                    ) {
                        add_into(&mut self.acc, &self.vbuf, len);
                    } else {
                        self.fade_voices[i] = None;
                        self.stats.nonfinite_resets += 1;
                    }
                    continue;
                }
                let scene = f.scenes.bound(at, on_damped);
                if tick_into(&mut f.states[i], scene, &mut self.vbuf, len, g0, dg, None) {
                    add_into(&mut self.acc, &self.vbuf, len);
                } else {
                    self.fade_voices[i] = None;
                    self.stats.nonfinite_resets += 1;
                }
            }
            // stolen voices that were fading at the swap
            let fades = &mut self.old_steal_fades;
            let (acc, vbuf) = (&mut self.acc, &mut self.vbuf);
            let bad = &mut self.stats.nonfinite_resets;
            steal_fades_into(f, fades, self.fade_len, (acc, vbuf), len, bad);
        }
        if steals {
            let fades = &mut self.steal_fades;
            let (acc, vbuf) = (&mut self.acc, &mut self.vbuf);
            let bad = &mut self.stats.nonfinite_resets;
            steal_fades_into(&mut self.cur, fades, self.fade_len, (acc, vbuf), len, bad);
        }
        self.lanes.push(FADE_LANE, &self.acc, len);
        if self.fading.is_some() {
            self.fade_left = self.fade_left.saturating_sub(len);
            if self.fade_left == 0 {
                self.fade_voices = [None; MAX_VOICES];
                // the old box goes back once its stolen voices have faded too
                if self.old_steal_fades.iter().all(Option::is_none) {
                    if let Some(slot) = self.retired.iter_mut().find(|s| s.is_none()) {
                        *slot = self.fading.take();
                    }
                }
            }
        }
        self.sample_pos += len as u64;
    }

    /// Bring every sounding voice up to the instrument's clock (with its
    /// grid actions there when `settle`; not before a bend's update, which
    /// comes first).
    pub(super) fn sync_all(&mut self, settle: bool) {
        for i in 0..MAX_VOICES {
            self.advance_voice(i, self.sample_pos, settle);
        }
    }

    /// Run voice `i` on its own clock in the instrument's chunks until it
    /// reaches `to` (at most the instrument's clock; it stops at the first
    /// chunk boundary at or after `to`), with its grid actions on the way,
    /// and at its arrival when `settle`.
    fn advance_voice(&mut self, i: usize, to: u64, settle: bool) {
        loop {
            if !self.voices[i].active {
                return;
            }
            let t = self.lanes.end[i];
            if !self.lanes.settled[i]
                && t.is_multiple_of(CHECK_INTERVAL_SAMPLES as u64)
                && (t < to || settle)
            {
                // the silence check, and a brightness that waited for its
                // contact to end (on the instrument's silence-check grid)
                // (with the damper's decision, taken on the same grid)
                self.lanes.settled[i] = true;
                self.press_flush(i);
                self.stop_if_silent(i);
                self.move_timbre(i);
                self.press_decide(i);
                continue;
            }
            if t >= to {
                return;
            }
            self.voice_chunk(i);
        }
    }

    /// Render voice `i`'s next chunk into its lane (a voice that produced a
    /// sample that is not a number is reset and stops: nothing of that
    /// chunk sounds).
    fn voice_chunk(&mut self, i: usize) {
        let t0 = self.lanes.end[i];
        let len = usize::from(self.lanes.chunk[t0 as usize & self.lanes.mask]);
        debug_assert!(len > 0 && t0 + len as u64 <= self.sample_pos);
        if self.cur.kit.is_some() {
            // a kit voice: the whole scene in its voice's lane
            if let Some(new_contacts) = self.kit_render(i, t0, len) {
                if self.lanes.meter == WorkMeter::Estimate {
                    self.lanes.work_ns += len as f64 * self.cur.step_cost_ns()
                        + new_contacts as f64 * self.cur.contact_cost_ns();
                }
                self.lanes.push(i, &self.vbuf, len);
                self.lanes.settled[i] = false;
            }
            return;
        }
        let p = &mut *self.cur;
        let v = &mut self.voices[i];
        let scene = p.scenes.bound(v.at, v.on_damped);
        let st = &mut p.states[i];
        let observe = if self.probe_on {
            Some(&mut self.motion[..len])
        } else {
            None
        };
        // contacts the voice switched itself (a replayed strike's cost
        // nothing: they are not work to estimate)
        let contacts = st.contacts_started - st.contacts_replayed;
        let observing = observe.is_some();
        if tick_into(st, scene, &mut self.vbuf, len, 1.0, 0.0, observe) {
            // damper pressure (docs/plugin.md, "Pressure and the mod
            // wheel"): the voice was found clear of its hammer when it was
            // last decided, so its pressed motion is the free motion times
            // the damper's decay, sample by sample
            if let Some(pr) = v.pressing.as_mut() {
                debug_assert!(
                    !st.in_contact() && st.contacts_started - st.contacts_replayed == contacts
                );
                let motion = observing.then_some(&mut self.motion[..len]);
                pr.g = super::decay_into(&mut self.vbuf, len, pr.g, pr.q, motion);
                self.stats.pressed_samples += len as u64;
            }
            let new_contacts = st.contacts_started - st.contacts_replayed - contacts;
            if let Some(probe) = self.probe.as_deref_mut().filter(|_| self.probe_on) {
                probe.voice_chunk(&VoiceChunk {
                    voice: i,
                    key: v.key,
                    released: v.released,
                    start: t0,
                    motion: &self.motion[..len],
                    // (asking a replaying voice would run its strike)
                    energy_j: (!st.replaying())
                        .then(|| st.energy_rt_scaled(scene, v.pressing.map_or(1.0, |pr| pr.g))),
                    path_m: st.surface_at(scene).map(|s| s.path_m),
                });
            }
            if self.lanes.meter == WorkMeter::Estimate {
                self.lanes.work_ns +=
                    len as f64 * p.step_cost_ns() + new_contacts as f64 * p.contact_cost_ns();
            }
            self.lanes.push(i, &self.vbuf, len);
            self.lanes.settled[i] = false;
        } else {
            st.reset(&p.scenes.scene);
            v.active = false;
            v.pressing = None;
            self.stats.nonfinite_resets += 1;
        }
    }

    /// Write the output up to time `upto` (the block's first sample is
    /// time `out0`): every voice brought up to it first (a voice not struck
    /// within the last two lookaheads up to the clock), then each sample
    /// its lanes summed in voice order (the fade last), times its gain,
    /// through the output guard.
    fn emit(&mut self, upto: i64, out0: i64, left: &mut [f32], right: &mut [f32]) {
        if upto <= self.lanes.out_pos {
            return;
        }
        if upto > 0 {
            for i in 0..MAX_VOICES {
                // only a voice struck within the last two lookaheads may
                // stay behind: the others keep up with the clock, so an
                // event that needs every voice (a note-on) never has a
                // lookahead's worth of every voice to catch up
                let v = &self.voices[i];
                let striking = self.sample_pos < v.onset_pos + 2 * self.lanes.lookahead as u64;
                let to = if striking {
                    upto as u64
                } else {
                    self.sample_pos
                };
                self.advance_voice(i, to, true);
            }
        }
        let mut hits = 0u64;
        let mut t = self.lanes.out_pos;
        while t < upto {
            let m = ((upto - t) as usize).min(CHECK_INTERVAL_SAMPLES);
            let l = &self.lanes;
            for ch in &mut self.acc {
                ch[..m].iter_mut().for_each(|x| *x = 0.0);
            }
            for lane in 0..LANES {
                let a = (l.start[lane] as i64).max(t);
                let b = (l.end[lane] as i64).min(t + m as i64);
                for u in a..b {
                    let s = l.ring[l.at(lane, u as u64)];
                    let k = (u - t) as usize;
                    self.acc[0][k] += s[0];
                    self.acc[1][k] += s[1];
                }
            }
            for k in 0..m {
                let u = t + k as i64;
                let j = (u - out0) as usize;
                if u < l.out_floor || u < 0 {
                    left[j] = 0.0;
                    right[j] = 0.0;
                } else {
                    let g = l.gain[u as usize & l.mask];
                    left[j] = guarded(self.acc[0][k] * g, &mut hits);
                    right[j] = guarded(self.acc[1][k] * g, &mut hits);
                }
            }
            t += m as i64;
        }
        self.lanes.out_pos = upto;
        self.stats.ceiling_hits += hits;
    }

    /// With a lookahead: the voices furthest behind the instrument's clock
    /// render on, a chunk at a time (one whose hammer is in contact or not
    /// yet gone only when a contact's estimated cost still fits), while the block's work is
    /// below its share of the block's budget (`n` samples;
    /// [`Instrument::set_lookahead_work`], [`WorkMeter`]).
    fn work_ahead(&mut self, n: usize) {
        if self.lanes.lookahead == 0 {
            return;
        }
        let budget_ns = self.lanes.work_fraction * n as f64 / self.cur.rate_hz * 1e9;
        loop {
            let spent_ns = match self.lanes.block_start {
                Some(t0) => t0.elapsed().as_nanos() as f64,
                None => self.lanes.work_ns,
            };
            if spent_ns >= budget_ns {
                break;
            }
            let l = &self.lanes;
            let mut behind: Option<usize> = None;
            for i in 0..MAX_VOICES {
                if self.voices[i].active
                    && l.end[i] < self.sample_pos
                    && behind.is_none_or(|b| l.end[i] < l.end[b])
                {
                    behind = Some(i);
                }
            }
            let Some(i) = behind else {
                break;
            };
            // a chunk that may hold a contact's switches is started only
            // when the estimate of a contact still fits (it waits for a
            // later block, at the latest for the output)
            let st = &self.cur.states[i];
            // a kit may switch at any sample
            let leaving = self.cur.kit.is_none()
                && st
                    .hammer_in_flight()
                    .is_some_and(|(x, up)| x > 0.0 && up >= 0.0);
            if (st.in_contact() || !leaving) && spent_ns + self.cur.contact_cost_ns() > budget_ns {
                break;
            }
            let to = self.lanes.end[i] + 1;
            self.advance_voice(i, to, true);
        }
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

/// Add `len` samples of the stolen voices fading out in `p`'s spare states
/// (`fades`, by spare; a kit's spare kit states when `p` is a kit) into
/// `acc`, each times its damper's decay when pressed and its fade's gain
/// ([`StealFade`]); a fade that ends frees
/// its spare, one that produced a sample that is not a number stops there
/// (nothing of that chunk sounds; its spare is reset; counted in
/// `nonfinite`). `vbuf` is scratch.
fn steal_fades_into(
    p: &mut Prepared,
    fades: &mut [Option<StealFade>; STEAL_FADES],
    fade_len: usize,
    (acc, vbuf): (
        &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
        &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
    ),
    len: usize,
    nonfinite: &mut u64,
) {
    for (f, slot) in fades.iter_mut().enumerate() {
        let Some(fade) = slot.as_mut() else {
            continue;
        };
        let m = len.min(fade.left);
        let finite = match p.kit.as_deref_mut() {
            Some(kit) => kit.tick_spare_into((f, fade.kit_at()), vbuf, m),
            None => {
                let scene = p.scenes.bound(fade.at, fade.on_damped);
                let st = &mut p.spares[f];
                let ok = tick_into(st, scene, vbuf, m, 1.0, 0.0, None);
                if !ok {
                    st.reset(&p.scenes.scene);
                }
                ok
            }
        };
        if finite {
            // a pressed fade: its damper's decay, as a pressed voice's
            // (`Instrument::voice_chunk`), under the fade's gain
            if let Some(pr) = fade.pressing.as_mut() {
                pr.g = super::decay_into(vbuf, m, pr.g, pr.q, None);
            }
            for k in 0..m {
                let g = (fade.left - k) as f64 / fade_len as f64;
                acc[0][k] += vbuf[0][k] * g;
                acc[1][k] += vbuf[1][k] * g;
            }
            fade.left -= m;
        } else {
            *nonfinite += 1;
            fade.left = 0;
        }
        if fade.left == 0 {
            *slot = None;
        }
    }
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
