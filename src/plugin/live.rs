//! The live view's data path: the audio thread records what each sounding
//! voice's hammer and contact point do into a wait-free single-producer,
//! single-consumer ring of fixed-size frames; the editor window drains it at
//! its display rate into a [`LiveHistory`] it draws from.
//!
//! The audio thread never waits for the window: [`LiveProducer::push`] is a
//! few atomic loads and stores, allocates nothing, and drops the frame
//! (counting it) when the ring is full because the window is slow or closed.
//! While the window is closed the instrument's probe is switched off and the
//! voices run the plain block path (docs/design.md, "The editor").

use crate::instrument::{VoiceChunk, VoiceProbe, CHECK_INTERVAL_SAMPLES};
use std::cell::UnsafeCell;
use std::collections::VecDeque;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

/// The live view keeps one point per this many samples of the instrument's
/// clock (4 samples: 83 us at 48 kHz, finer than any contact of the presets
/// at their highest notes is short).
pub const DECIMATION: usize = 4;
/// Points per frame: one chunk of the instrument.
pub const FRAME_POINTS: usize = CHECK_INTERVAL_SAMPLES / DECIMATION;
/// Frames the ring holds: 16 voices for 0.34 s at 48 kHz, far more than a
/// window refreshing at 30 Hz or faster ever leaves in it.
pub const RING_FRAMES: usize = 4096;
/// How much history the view shows \[s\].
pub const HISTORY_S: f64 = 0.1;

/// One chunk of one voice, decimated: the point of group `g` (samples
/// `g * DECIMATION ..` of the instrument's clock) is the first sample of the
/// group the chunk holds, and its contact flag says whether any sample of
/// the group in the chunk was in contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveFrame {
    /// Voice index.
    pub voice: u8,
    /// Its MIDI key.
    pub key: u8,
    /// Released (after note-off).
    pub released: bool,
    /// Group of the first point.
    pub first_group: u64,
    /// Points used.
    pub points: u8,
    /// Hammer height \[m\] per point.
    pub hammer_m: [f32; FRAME_POINTS],
    /// Contact-point displacement \[m\] per point.
    pub contact_m: [f32; FRAME_POINTS],
    /// Bit `k`: point `k`'s group was in contact.
    pub contact_bits: u16,
    /// The voice's energy at the chunk's end \[J\] (`None` while its
    /// strike is played back from a recording).
    pub energy_j: Option<f64>,
    /// A driven voice's position along its path at the chunk's end \[m\].
    pub path_m: Option<f32>,
}

impl LiveFrame {
    /// Decimate one chunk (see the type's doc). Allocation-free.
    pub fn from_chunk(c: &VoiceChunk) -> Self {
        let mut f = LiveFrame {
            voice: c.voice as u8,
            key: c.key,
            released: c.released,
            first_group: c.start / DECIMATION as u64,
            points: 0,
            hammer_m: [0.0; FRAME_POINTS],
            contact_m: [0.0; FRAME_POINTS],
            contact_bits: 0,
            energy_j: c.energy_j,
            path_m: c.path_m.map(|x| x as f32),
        };
        for (j, m) in c.motion.iter().enumerate() {
            let g = (c.start + j as u64) / DECIMATION as u64;
            let k = (g - f.first_group) as usize;
            if k >= FRAME_POINTS {
                break;
            }
            if k + 1 > f.points as usize {
                f.points = (k + 1) as u8;
                f.hammer_m[k] = m.x_hammer as f32;
                f.contact_m[k] = m.x_contact as f32;
            }
            if m.in_contact {
                f.contact_bits |= 1 << k;
            }
        }
        f
    }
}

/// The ring shared by one producer (the audio thread's probe) and one
/// consumer (the editor window). Each side is a handle that only one owner
/// can hold at a time ([`LiveRing::producer`], [`LiveRing::consumer`]), so
/// the single-producer single-consumer rule holds by construction.
pub struct LiveRing {
    slots: Box<[UnsafeCell<MaybeUninit<LiveFrame>>]>,
    /// Next slot to read (consumer writes, producer reads).
    head: AtomicUsize,
    /// Next slot to write (producer writes, consumer reads).
    tail: AtomicUsize,
    producer_taken: AtomicBool,
    consumer_taken: AtomicBool,
    /// Frames dropped because the ring was full.
    dropped: AtomicU64,
    /// Sample rate of the frames \[Hz\] (set at activation).
    rate_hz: AtomicU64,
}

// SAFETY: a slot is written only by the one producer while it is outside
// head..tail (the consumer does not read it), and read only by the one
// consumer while inside (the producer does not write it); the Release store
// of tail after the write and the Acquire load before the read order the
// two, and likewise head for the slot's reuse.
unsafe impl Sync for LiveRing {}
// SAFETY: the ring owns its frames (plain numbers, no references or
// thread-bound handles), so moving it to another thread moves only data;
// the concurrent access that follows is the `Sync` case above.
unsafe impl Send for LiveRing {}

impl LiveRing {
    /// A ring of `capacity` frames (one slot stays empty to tell full from
    /// empty). Allocates. \[main-thread\]
    pub fn new(capacity: usize) -> Arc<Self> {
        let n = capacity.max(1) + 1;
        Arc::new(Self {
            slots: (0..n)
                .map(|_| UnsafeCell::new(MaybeUninit::uninit()))
                .collect(),
            head: AtomicUsize::new(0),
            tail: AtomicUsize::new(0),
            producer_taken: AtomicBool::new(false),
            consumer_taken: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
            rate_hz: AtomicU64::new(48_000f64.to_bits()),
        })
    }

    /// The producer handle, if no one holds it.
    pub fn producer(self: &Arc<Self>) -> Option<LiveProducer> {
        (!self.producer_taken.swap(true, Ordering::AcqRel)).then(|| LiveProducer(self.clone()))
    }

    /// The consumer handle, if no one holds it.
    pub fn consumer(self: &Arc<Self>) -> Option<LiveConsumer> {
        (!self.consumer_taken.swap(true, Ordering::AcqRel)).then(|| LiveConsumer(self.clone()))
    }

    /// Whether someone holds the reading end (the editor is open): the
    /// audio thread records only then. \[audio-thread\]
    pub fn has_consumer(&self) -> bool {
        self.consumer_taken.load(Ordering::Acquire)
    }

    /// Frames dropped so far because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Set the sample rate the frames' clock counts in.
    pub fn set_rate_hz(&self, rate_hz: f64) {
        self.rate_hz.store(rate_hz.to_bits(), Ordering::Relaxed);
    }

    /// The sample rate the frames' clock counts in \[Hz\].
    pub fn rate_hz(&self) -> f64 {
        f64::from_bits(self.rate_hz.load(Ordering::Relaxed))
    }
}

/// The writing end (see [`LiveRing`]).
pub struct LiveProducer(Arc<LiveRing>);

impl LiveProducer {
    /// Append a frame; false (and counted) if the ring is full. Wait-free,
    /// allocation-free. \[audio-thread\]
    pub fn push(&mut self, frame: LiveFrame) -> bool {
        let r = &*self.0;
        let tail = r.tail.load(Ordering::Relaxed);
        let next = (tail + 1) % r.slots.len();
        if next == r.head.load(Ordering::Acquire) {
            r.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        // SAFETY: see `LiveRing`: slot `tail` is outside head..tail.
        unsafe { (*r.slots[tail].get()).write(frame) };
        r.tail.store(next, Ordering::Release);
        true
    }
}

impl Drop for LiveProducer {
    fn drop(&mut self) {
        self.0.producer_taken.store(false, Ordering::Release);
    }
}

/// The reading end (see [`LiveRing`]).
pub struct LiveConsumer(Arc<LiveRing>);

impl LiveConsumer {
    /// Take the oldest frame, if any. Wait-free. \[gui-thread\]
    pub fn pop(&mut self) -> Option<LiveFrame> {
        let r = &*self.0;
        let head = r.head.load(Ordering::Relaxed);
        if head == r.tail.load(Ordering::Acquire) {
            return None;
        }
        // SAFETY: see `LiveRing`: slot `head` is inside head..tail, written
        // before the producer's Release store of tail.
        let f = unsafe { (*r.slots[head].get()).assume_init_read() };
        r.head.store((head + 1) % r.slots.len(), Ordering::Release);
        Some(f)
    }

    /// The ring (its rate and drop count).
    pub fn ring(&self) -> &LiveRing {
        &self.0
    }
}

impl Drop for LiveConsumer {
    fn drop(&mut self) {
        self.0.consumer_taken.store(false, Ordering::Release);
    }
}

/// The instrument's probe for the live view: decimates each chunk into a
/// frame and pushes it. \[audio-thread\]
pub struct LiveProbe(pub LiveProducer);

impl VoiceProbe for LiveProbe {
    fn voice_chunk(&mut self, chunk: &VoiceChunk) {
        self.0.push(LiveFrame::from_chunk(chunk));
    }
}

/// One voice's recent history, as the view draws it.
#[derive(Debug, Clone, Default)]
pub struct VoiceHistory {
    /// Its MIDI key (of the latest frame).
    pub key: u8,
    /// Released.
    pub released: bool,
    /// Points: (group, hammer height, contact displacement, in contact).
    pub points: VecDeque<(u64, f32, f32, bool)>,
    /// Energy at each chunk's end: (group, joules).
    pub energy: VecDeque<(u64, f64)>,
    /// A driven voice's latest position along its path \[m\].
    pub path_m: Option<f32>,
}

/// What the editor keeps of the frames: per voice, the last
/// [`HISTORY_S`] of points and energies. \[gui-thread\]
#[derive(Debug, Clone, Default)]
pub struct LiveHistory {
    /// By voice index.
    pub voices: Vec<VoiceHistory>,
    /// The latest group seen (the view's "now").
    pub now_group: u64,
    /// Frames taken so far.
    pub frames: u64,
}

impl LiveHistory {
    /// Groups kept at `rate_hz`.
    pub fn span_groups(rate_hz: f64) -> u64 {
        (HISTORY_S * rate_hz / DECIMATION as f64).ceil() as u64
    }

    /// Add one frame and forget what is older than [`HISTORY_S`] before it.
    pub fn ingest(&mut self, f: &LiveFrame, rate_hz: f64) {
        let v = usize::from(f.voice);
        if self.voices.len() <= v {
            self.voices.resize_with(v + 1, VoiceHistory::default);
        }
        let h = &mut self.voices[v];
        h.key = f.key;
        h.released = f.released;
        h.path_m = f.path_m;
        for k in 0..usize::from(f.points) {
            let g = f.first_group + k as u64;
            if h.points.back().is_some_and(|p| p.0 >= g) {
                // a group split across two chunks: keep its first point,
                // but its contact flag covers both parts
                if let Some(p) = h.points.back_mut().filter(|p| p.0 == g) {
                    p.3 |= f.contact_bits & (1 << k) != 0;
                }
                continue;
            }
            h.points.push_back((
                g,
                f.hammer_m[k],
                f.contact_m[k],
                f.contact_bits & (1 << k) != 0,
            ));
        }
        let last = f.first_group + u64::from(f.points.max(1)) - 1;
        // (no energy while a strike is played back from its recording)
        if let Some(e) = f.energy_j {
            h.energy.push_back((last, e));
        }
        self.now_group = self.now_group.max(last);
        self.frames += 1;
        self.forget(rate_hz);
    }

    /// Drop what is older than the view's span.
    pub fn forget(&mut self, rate_hz: f64) {
        let oldest = self.now_group.saturating_sub(Self::span_groups(rate_hz));
        for h in &mut self.voices {
            while h.points.front().is_some_and(|p| p.0 < oldest) {
                h.points.pop_front();
            }
            while h.energy.front().is_some_and(|p| p.0 < oldest) {
                h.energy.pop_front();
            }
        }
    }

    /// Drain everything the ring holds.
    pub fn drain(&mut self, consumer: &mut LiveConsumer) -> usize {
        let rate = consumer.ring().rate_hz();
        let mut n = 0;
        while let Some(f) = consumer.pop() {
            self.ingest(&f, rate);
            n += 1;
        }
        n
    }

    /// Voices with points in the span, by voice index.
    pub fn sounding(&self) -> impl Iterator<Item = (usize, &VoiceHistory)> {
        self.voices
            .iter()
            .enumerate()
            .filter(|(_, h)| !h.points.is_empty())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Motion;

    fn motion(x_hammer: f64, x_contact: f64, in_contact: bool) -> Motion {
        Motion {
            x_hammer,
            x_contact,
            in_contact,
            ..Motion::default()
        }
    }

    fn frame(voice: u8, group: u64) -> LiveFrame {
        LiveFrame {
            voice,
            key: 60,
            released: false,
            first_group: group,
            points: 1,
            hammer_m: [0.0; FRAME_POINTS],
            contact_m: [0.0; FRAME_POINTS],
            contact_bits: 0,
            energy_j: Some(1.0),
            path_m: None,
        }
    }

    #[test]
    fn the_ring_keeps_order_and_drops_when_full() {
        let ring = LiveRing::new(3);
        let mut p = ring.producer().unwrap();
        let mut c = ring.consumer().unwrap();
        assert!(ring.producer().is_none(), "one producer at a time");
        assert!(ring.consumer().is_none(), "one consumer at a time");
        for g in 0..3 {
            assert!(p.push(frame(0, g)));
        }
        assert!(!p.push(frame(0, 99)), "full: the frame is dropped");
        assert_eq!(ring.dropped(), 1);
        let got: Vec<u64> = std::iter::from_fn(|| c.pop())
            .map(|f| f.first_group)
            .collect();
        assert_eq!(got, [0, 1, 2]);
        assert!(c.pop().is_none());
        // wraps around
        for round in 0..10u64 {
            assert!(p.push(frame(1, round)));
            assert_eq!(c.pop().map(|f| f.first_group), Some(round));
        }
        drop(p);
        assert!(ring.producer().is_some(), "a dropped handle frees its side");
    }

    /// Two threads: every frame the consumer sees is one the producer
    /// pushed, in order, none twice, and pushed = seen + dropped.
    #[test]
    fn the_ring_is_consistent_across_threads() {
        let ring = LiveRing::new(64);
        let mut p = ring.producer().unwrap();
        let mut c = ring.consumer().unwrap();
        let n = 200_000u64;
        let t = std::thread::spawn(move || {
            let mut pushed = 0u64;
            for g in 0..n {
                if p.push(frame(0, g)) {
                    pushed += 1;
                }
            }
            pushed
        });
        let mut seen = 0u64;
        let mut last = None;
        loop {
            match c.pop() {
                Some(f) => {
                    assert!(last.is_none_or(|l| f.first_group > l), "out of order");
                    last = Some(f.first_group);
                    seen += 1;
                }
                None if t.is_finished() => {
                    if c.pop().is_none() {
                        break;
                    }
                    seen += 1;
                }
                None => std::hint::spin_loop(),
            }
        }
        let pushed = t.join().unwrap();
        assert_eq!(seen, pushed);
        assert_eq!(pushed + ring.dropped(), n);
        println!("pushed {pushed}, dropped {}", ring.dropped());
    }

    #[test]
    fn a_chunk_is_decimated_on_the_instruments_clock() {
        // a chunk starting mid-group (clock 6): groups 1 (samples 6, 7),
        // 2 (8..11), 3 (12, 13); contact on sample 9 only
        let m: Vec<Motion> = (0..8)
            .map(|j| motion(j as f64, -(j as f64), j == 3))
            .collect();
        let f = LiveFrame::from_chunk(&VoiceChunk {
            voice: 3,
            key: 61,
            released: true,
            start: 6,
            motion: &m,
            energy_j: Some(0.25),
            path_m: Some(0.25),
        });
        assert_eq!((f.first_group, f.points), (1, 3));
        assert_eq!(&f.hammer_m[..3], &[0.0, 2.0, 6.0]);
        assert_eq!(&f.contact_m[..3], &[-0.0, -2.0, -6.0]);
        assert_eq!(f.contact_bits, 0b010);
        assert_eq!(
            (f.voice, f.key, f.released, f.energy_j),
            (3, 61, true, Some(0.25))
        );
        assert_eq!(f.path_m, Some(0.25));
    }

    #[test]
    fn the_history_keeps_the_last_span_per_voice() {
        let rate = 48_000.0;
        let span = LiveHistory::span_groups(rate);
        assert_eq!(span, 1200);
        let mut h = LiveHistory::default();
        let mut g = 0;
        while g < 3 * span {
            let mut f = frame(2, g);
            f.points = FRAME_POINTS as u8;
            f.contact_bits = if g == 0 { 1 } else { 0 };
            h.ingest(&f, rate);
            g += FRAME_POINTS as u64;
        }
        let (idx, v) = h.sounding().next().unwrap();
        assert_eq!(idx, 2);
        let first = v.points.front().unwrap().0;
        let last = v.points.back().unwrap().0;
        assert_eq!(last, 3 * span - 1);
        assert_eq!(first, last - span, "exactly the span is kept");
        assert!(
            v.points.iter().all(|p| !p.3),
            "the old contact was forgotten"
        );
        assert_eq!(h.sounding().count(), 1);
    }
}
