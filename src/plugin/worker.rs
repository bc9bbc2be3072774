//! The per-instance background compile thread and its lock-free handoff.
//!
//! Four bounded queues (crossbeam `ArrayQueue`, lock-free, no allocation
//! after construction) connect the audio thread, the host's main thread and
//! the worker:
//!
//! - `requests` (audio or main -> worker): a tiny `Copy` [`CompileRequest`].
//!   If it is full the audio thread retries at the next block.
//! - `first` (worker -> audio or main): an activation's first scene with the
//!   instrument built around it (`Box<Instrument>`: made on the worker, as
//!   building one allocates), taken by `activate` if it is ready within
//!   [`ACTIVATE_WAIT_MS`], else by the first block after it is.
//! - `ready` (worker -> audio): a `Box<Prepared>` (compiled scene, its damped
//!   variant and fresh per-voice states). The audio thread pops it at a block
//!   boundary and swaps it in.
//! - `returned` (audio -> worker): retired boxes, freed here. If it is full the
//!   box stays in the instrument's fixed retired slots until the next block.
//!
//! The worker lives as long as the plugin instance: spawned at the first
//! activation, kept across deactivations, stopped and joined when the
//! instance is dropped. Deactivation never waits for it: it cancels the
//! compiles of the old activation ([`Handoff::cancel_through`]) and the
//! compile gives up at its next look at the flag (docs/design.md, "The
//! plugin and its threads").
//!
//! The worker polls with `park_timeout` (the audio thread never wakes it: an
//! unpark is a system call). The shared nice-plug background thread is not
//! used (one long eigensolve there would stall every other plugin instance).

use super::user_scene::{HostBlocks, SceneLibrary};
use super::waits::{Held, Shared};
use crate::compile::cancel::{self, Cancel};
use crate::instrument::{Instrument, Kit, PlayParams, Prepared, SceneParams, Stage};
use atomic_float::AtomicF64;
use crossbeam::queue::ArrayQueue;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Worker poll interval: a parameter change is heard within a compile time
/// plus this.
pub const POLL_INTERVAL_MS: u64 = 2;
/// Capacity of the request queue (requests are coalesced: newest wins).
pub const REQUEST_CAPACITY: usize = 8;
/// Capacity of the ready queue.
pub const READY_CAPACITY: usize = 2;
/// Capacity of the return queue.
pub const RETURN_CAPACITY: usize = 8;
/// Capacity of the queue of activations' first instruments.
pub const FIRST_CAPACITY: usize = 2;
/// How long `activate` waits for its first scene \[ms\]: the host's main
/// thread is never held longer (a scene that takes longer is installed by
/// the first block after it is ready; until then the instance is silent,
/// and the editor says it compiles).
pub const ACTIVATE_WAIT_MS: u64 = 80;

/// A request to compile a parameter set (a plain value, never a heap payload).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompileRequest {
    /// Increases with every request of this instance.
    pub revision: u64,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// The host's largest block \[samples\] and the polyphony (for the
    /// strike-cost warning).
    pub max_block: usize,
    /// See `max_block`.
    pub polyphony: usize,
    /// The lookahead \[samples\] (for the same warning).
    pub lookahead: usize,
    /// What to compile.
    pub params: SceneParams,
    /// An activation's first scene: the worker builds the instrument with
    /// these play parameters around it, and tries the activation's
    /// fallbacks (the preset with the same parameters when a user scene
    /// fails, then the preset's defaults) before it gives up.
    pub first: Option<PlayParams>,
    /// How much to compile: an activation's first scene on a live host is
    /// [`Stage::Playable`], and the worker follows it with the whole scene
    /// (an upgrade of the same revision) unless it is already complete.
    pub stage: Stage,
    /// This is such an upgrade: installed as a later scene; if it fails,
    /// the playable scene plays on and no failure is reported.
    pub upgrade: bool,
}

/// State shared by the audio thread and the worker (queues and counters).
pub struct Handoff {
    requests: ArrayQueue<CompileRequest>,
    first: ArrayQueue<Box<Instrument>>,
    ready: ArrayQueue<Box<Prepared>>,
    returned: ArrayQueue<Box<Prepared>>,
    stop: AtomicBool,
    /// Compiles of revisions up to this one are cancelled (main thread
    /// writes: deactivation, the instance's end).
    cancelled_through: AtomicU64,
    /// The compile running now and its flag (worker and main thread only:
    /// the audio thread never touches this lock).
    running: Shared<Option<(u64, Cancel)>>,
    /// Successful compiles (worker writes, anyone reads).
    pub compiles: AtomicU64,
    /// Failed compiles: the last good scene stays (worker writes).
    pub failures: AtomicU64,
    /// Revision of the last published scene (worker writes).
    pub published_revision: AtomicU64,
    /// Wall time of the last compile \[ms\] (worker writes; diagnostics only).
    pub last_compile_ms: AtomicF64,
    /// Revision of the newest request posted (audio thread or activation
    /// writes): the editor says "compiling" while it is ahead of
    /// `published_revision` and no failure answered it.
    pub requested_revision: AtomicU64,
    /// Revision the last failure answered (worker writes).
    pub failed_revision: AtomicU64,
    /// The worker is compiling now (worker writes).
    pub busy: AtomicBool,
    /// The last compile error, for the editor (worker and GUI threads
    /// only: the audio thread never touches this lock).
    last_error: Shared<Option<String>>,
}

impl Handoff {
    /// Allocate the queues. \[main-thread\]
    pub fn new() -> Arc<Self> {
        Arc::new(Self {
            requests: ArrayQueue::new(REQUEST_CAPACITY),
            first: ArrayQueue::new(FIRST_CAPACITY),
            ready: ArrayQueue::new(READY_CAPACITY),
            returned: ArrayQueue::new(RETURN_CAPACITY),
            stop: AtomicBool::new(false),
            cancelled_through: AtomicU64::new(0),
            running: Shared::new(None),
            compiles: AtomicU64::new(0),
            failures: AtomicU64::new(0),
            published_revision: AtomicU64::new(0),
            last_compile_ms: AtomicF64::new(0.0),
            requested_revision: AtomicU64::new(0),
            failed_revision: AtomicU64::new(0),
            busy: AtomicBool::new(false),
            last_error: Shared::new(None),
        })
    }

    /// Post a request; false if the queue is full (retry later). Lock-free,
    /// no allocation. \[audio-thread\] \[main-thread\]
    pub fn request(&self, req: CompileRequest) -> bool {
        let ok = self.requests.push(req).is_ok();
        if ok {
            self.requested_revision
                .fetch_max(req.revision, Ordering::AcqRel);
        }
        ok
    }

    /// Take an activation's first instrument if one is ready. Lock-free.
    /// \[audio-thread\] \[main-thread\]
    pub fn take_first(&self) -> Option<Box<Instrument>> {
        self.first.pop()
    }

    /// Whether the worker was told to stop (the instance ends).
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }

    /// Whether the request of `revision` failed (every fallback refused).
    pub fn failed(&self, revision: u64) -> bool {
        self.failed_revision.load(Ordering::Acquire) >= revision
    }

    /// The last compile error (also of a candidate an activation's
    /// fallbacks passed over). \[GUI thread\]
    pub fn last_error(&self) -> Option<String> {
        self.last_error.get().clone()
    }

    /// Cancel the compiles of every revision up to `revision` (the running
    /// one gives up at its next look at its flag), and drop what they
    /// already delivered. Returns at once: it never waits for the worker.
    /// Blocks only on the worker's short critical sections (no compile runs
    /// under the lock). \[main-thread\]
    pub fn cancel_through(&self, revision: u64) {
        self.cancelled_through.fetch_max(revision, Ordering::AcqRel);
        let running = self.running.get();
        if let Some((r, c)) = running.as_ref() {
            if *r <= revision {
                c.cancel();
            }
        }
        // under the lock: the worker delivers under it too, and looks at
        // `cancelled_through` first, so nothing of these revisions comes after
        while self.first.pop().is_some() {}
        while self.ready.pop().is_some() {}
        while self.requests.pop().is_some() {}
    }

    fn is_cancelled(&self, revision: u64) -> bool {
        revision <= self.cancelled_through.load(Ordering::Acquire)
    }

    /// Take a compiled scene if one is ready. Lock-free. \[audio-thread\]
    pub fn take_ready(&self) -> Option<Box<Prepared>> {
        self.ready.pop()
    }

    /// Hand a retired box back to be freed by the worker; gives it back if
    /// the queue is full. Lock-free, never drops. \[audio-thread\]
    pub fn give_back(&self, b: Box<Prepared>) -> Result<(), Box<Prepared>> {
        self.returned.push(b)
    }

    /// Whether a requested scene is still being compiled (neither
    /// published nor refused yet). \[any thread\]
    pub fn compiling(&self) -> bool {
        let want = self.requested_revision.load(Ordering::Acquire);
        want > self.published_revision.load(Ordering::Acquire)
            && want > self.failed_revision.load(Ordering::Acquire)
    }

    /// The last compile error, if the newest request failed. \[GUI thread\]
    pub fn error(&self) -> Option<String> {
        let want = self.requested_revision.load(Ordering::Acquire);
        if self.failed_revision.load(Ordering::Acquire) < want {
            return None;
        }
        self.last_error()
    }

    /// Free everything still queued (when no worker runs). \[main-thread\]
    pub fn drain(&self) {
        while self.returned.pop().is_some() {}
        while self.first.pop().is_some() {}
        while self.ready.pop().is_some() {}
        while self.requests.pop().is_some() {}
    }
}

/// The worker thread of one plugin instance.
pub struct Worker {
    handoff: Arc<Handoff>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Spawn the worker. \[main-thread\]
    pub fn spawn(handoff: Arc<Handoff>, library: Arc<SceneLibrary>) -> std::io::Result<Self> {
        handoff.stop.store(false, Ordering::Release);
        let h = handoff.clone();
        let thread = std::thread::Builder::new()
            .name("modal-contact-compile".into())
            .spawn(move || run(&h, &library))?;
        Ok(Self {
            handoff,
            thread: Some(thread),
        })
    }

    /// Stop and join the worker (its compile cancelled first), then free
    /// whatever is still queued. \[main-thread\]
    pub fn stop(&mut self) {
        if let Some(t) = self.thread.take() {
            self.handoff.stop.store(true, Ordering::Release);
            self.handoff.cancel_through(u64::MAX);
            t.thread().unpark();
            let _ = t.join();
        }
        self.handoff.drain();
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The worker loop: free returned boxes, coalesce requests (newest revision
/// wins), compile, publish; sleep with `park_timeout` when idle. \[worker\]
fn run(h: &Handoff, lib: &SceneLibrary) {
    while !h.stop.load(Ordering::Acquire) {
        while let Some(old) = h.returned.pop() {
            drop(old);
        }
        let Some(req) = newest_request(h) else {
            std::thread::park_timeout(Duration::from_millis(POLL_INTERVAL_MS));
            continue;
        };
        if h.is_cancelled(req.revision) {
            continue;
        }
        let c = Cancel::new();
        *h.running.get() = Some((req.revision, c.clone()));
        if h.is_cancelled(req.revision) {
            c.cancel();
        }
        h.busy.store(true, Ordering::Release);
        let t0 = Instant::now();
        // a panic in a compile is a failed compile, not a dead worker (an
        // offline render waits for the worker's answer)
        let done = cancel::scope(&c, || {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                compile(lib, &req, |e| *h.last_error.get() = Some(e.to_string()))
            }))
            .unwrap_or_else(|_| Err("the compile panicked".to_string()))
        });
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        // an activation's first scene comes with its instrument, built
        // here (building one allocates)
        let done = done.map(|(p, warnings)| deliverable(p, warnings, &req));
        h.busy.store(false, Ordering::Release);
        let mut running = h.running.get();
        *running = None;
        if c.is_cancelled() || h.is_cancelled(req.revision) {
            // an old activation's: dropped here, on the worker, after the
            // lock is released
            drop(running);
            drop(done);
            continue;
        }
        answer(h, &req, done, running, ms);
    }
}

/// The request to compile next: the newest queued, but never past an
/// activation's first request (a later parameter change follows it).
/// \[worker\]
fn newest_request(h: &Handoff) -> Option<CompileRequest> {
    let mut newest: Option<CompileRequest> = None;
    while let Some(r) = h.requests.pop() {
        // an activation's first request is never dropped for a later
        // parameter change: the later one follows it
        if newest.is_some_and(|n| n.first.is_some() && r.first.is_none()) {
            let _ = h.requests.push(r);
            break;
        }
        if newest.is_none_or(|n| r.revision >= n.revision) {
            newest = Some(r);
        }
    }
    newest
}

/// What a compile of `req` hands on: its delivery, its warnings, how many
/// variant scenes it holds, and the request for the whole scene when it
/// is only playable. \[worker\]
type Outcome = (Delivery, Vec<String>, usize, Option<CompileRequest>);

/// The [`Outcome`] of `p`, compiled for `req`. \[worker\]
fn deliverable(p: Box<Prepared>, warnings: Vec<String>, req: &CompileRequest) -> Outcome {
    let variants = p.scenes.variant_count() + p.kit.as_deref().map_or(0, Kit::level_count);
    // the whole scene follows a playable one, compiled with what
    // that one used (a fallback's parameters, the generation of
    // the user scene)
    let upgrade = (!p.complete).then_some(CompileRequest {
        params: p.params,
        first: None,
        stage: Stage::Full,
        upgrade: true,
        ..*req
    });
    let delivery = match req.first {
        Some(play) => Delivery::First(Box::new(Instrument::new(p, play))),
        None => Delivery::Ready(p),
    };
    (delivery, warnings, variants, upgrade)
}

/// Publish what the compile of `req` delivered (under the `running` lock,
/// released here), or count and log its failure; `ms`: the compile's wall
/// time. \[worker\]
fn answer(
    h: &Handoff,
    req: &CompileRequest,
    done: Result<Outcome, String>,
    running: Held<'_, Option<(u64, Cancel)>>,
    ms: f64,
) {
    match done {
        Ok((delivery, warnings, variants, upgrade)) => {
            // delivered under the lock: `cancel_through` drains after
            // it, so nothing of a cancelled revision stays queued
            match delivery {
                Delivery::First(inst) => publish(&h.first, inst),
                Delivery::Ready(p) => publish(&h.ready, p),
            }
            h.published_revision
                .fetch_max(req.revision, Ordering::AcqRel);
            // queued behind any newer request: coalescing drops it
            // when a parameter moved meanwhile (a full queue holds
            // newer requests: it is dropped then too)
            if let Some(u) = upgrade {
                let _ = h.requests.push(u);
            }
            drop(running);
            for w in warnings {
                nice_plug::nice_log!("modal_contact: {w}");
            }
            if req.params.variants != Default::default() {
                nice_plug::nice_log!(
                    "modal_contact: {variants} per-voice variant scenes (hardness, strike \
                     position, damper levels for polyphonic modulation) compiled with the \
                     scene in {ms:.0} ms",
                );
            }
            h.last_compile_ms.store(ms, Ordering::Relaxed);
            h.compiles.fetch_add(1, Ordering::Relaxed);
        }
        Err(e) if req.upgrade => {
            drop(running);
            nice_plug::nice_log!(
                "modal_contact: the variants of revision {} did not compile, the scene \
                 plays without them: {e}",
                req.revision
            );
        }
        Err(e) => {
            drop(running);
            h.failures.fetch_add(1, Ordering::Relaxed);
            nice_plug::nice_log!(
                "modal_contact: compile of revision {} failed, keeping the last scene: {e}",
                req.revision
            );
            *h.last_error.get() = Some(e);
            h.failed_revision.fetch_max(req.revision, Ordering::AcqRel);
        }
    }
}

/// What a compile delivers.
enum Delivery {
    /// An activation's first scene, in its instrument.
    First(Box<Instrument>),
    /// A later scene, for the instrument to install.
    Ready(Box<Prepared>),
}

/// Compile one request: what was asked for, and for an activation's first
/// scene its fallbacks (the user scene did not compile: the preset with the
/// same parameters; else the preset's defaults). \[worker\]
/// Each candidate's error goes to `refused` as it comes (the editor shows
/// why a saved user scene plays the preset instead). \[worker\]
fn compile(
    lib: &SceneLibrary,
    req: &CompileRequest,
    mut refused: impl FnMut(&str),
) -> Result<(Box<Prepared>, Vec<String>), String> {
    let host = HostBlocks {
        max_block: req.max_block,
        polyphony: req.polyphony,
        lookahead: req.lookahead,
    };
    let candidates = if req.first.is_some() && !req.upgrade {
        vec![
            req.params,
            SceneParams {
                user_scene: 0,
                ..req.params
            },
            SceneParams {
                preset: req.params.preset,
                ..SceneParams::default()
            },
        ]
    } else {
        vec![req.params]
    };
    let mut errors = Vec::new();
    for c in candidates {
        match lib.prepare_staged(&c, req.rate_hz, req.revision, host, req.stage) {
            Ok(done) => return Ok(done),
            Err(e) => {
                cancel::check().map_err(|c| c.to_string())?;
                nice_plug::nice_log!("modal_contact: {e}; trying the next fallback");
                refused(&e);
                errors.push(e);
            }
        }
    }
    Err(errors.join("; "))
}

/// Publish, replacing a stale unread result if the queue is full (the stale
/// box is freed here, on the worker). \[worker\]
fn publish<T>(q: &ArrayQueue<T>, mut p: T) {
    loop {
        match q.push(p) {
            Ok(()) => return,
            Err(back) => {
                p = back;
                if let Some(stale) = q.pop() {
                    drop(stale);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(revision: u64, first: bool) -> CompileRequest {
        CompileRequest {
            revision,
            rate_hz: 48_000.0,
            max_block: 256,
            polyphony: 16,
            lookahead: 0,
            params: SceneParams::default(),
            first: first.then(PlayParams::default),
            stage: Stage::Full,
            upgrade: false,
        }
    }

    fn wait_for(h: &Handoff, what: impl Fn(&Handoff) -> bool) {
        let t0 = Instant::now();
        while !what(h) {
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "the worker never answered"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// A cancelled activation's scene is never delivered, whether its
    /// compile had started or not; the next activation's is, in its
    /// instrument; a later request arrives as a scene to install.
    #[test]
    fn a_cancelled_revision_is_never_delivered() {
        let h = Handoff::new();
        let mut w = Worker::spawn(h.clone(), Arc::new(SceneLibrary::default())).unwrap();
        for wait_ms in [0u64, 5, 20] {
            let base = h.requested_revision.load(Ordering::Acquire);
            assert!(h.request(request(base + 1, true)));
            assert!(h.compiling());
            std::thread::sleep(Duration::from_millis(wait_ms));
            h.cancel_through(base + 1);
            assert!(h.request(request(base + 2, true)));
            wait_for(&h, |h| !h.compiling());
            assert_eq!(h.published_revision.load(Ordering::Acquire), base + 2);
            let inst = h.take_first().expect("the second activation's instrument");
            assert_eq!(inst.prepared().revision, base + 2);
            assert!(h.take_first().is_none(), "the cancelled one came too");
            assert!(h.take_ready().is_none());
            assert!(!h.failed(base + 2));
        }
        let base = h.requested_revision.load(Ordering::Acquire);
        assert!(h.request(request(base + 1, false)));
        wait_for(&h, |h| !h.compiling());
        assert_eq!(h.take_ready().expect("a scene").revision, base + 1);
        assert!(h.take_first().is_none());
        w.stop();
        assert!(h.stopped());
    }

    fn preset(name: &str) -> usize {
        crate::presets::PRESETS
            .iter()
            .position(|p| p.name == name)
            .unwrap()
    }

    fn playable_first(revision: u64, name: &str) -> CompileRequest {
        let mut r = request(revision, true);
        r.params.preset = preset(name);
        r.stage = Stage::Playable;
        r
    }

    /// Wait for the next later scene (or none within `ms`).
    fn next_ready(h: &Handoff, ms: u64) -> Option<Box<Prepared>> {
        let t0 = Instant::now();
        loop {
            if let Some(p) = h.take_ready() {
                return Some(p);
            }
            if t0.elapsed() > Duration::from_millis(ms) {
                return None;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// A live host's first scene is playable at once (no variants, no
    /// stored strikes) and the whole scene of the same revision follows as
    /// a later scene; a cancellation drops that upgrade too, and a newer
    /// request replaces it; a kit's hardness levels follow as its whole
    /// scene.
    #[test]
    fn a_playable_first_scene_is_followed_by_the_whole_one() {
        let h = Handoff::new();
        let mut w = Worker::spawn(h.clone(), Arc::new(SceneLibrary::default())).unwrap();
        assert!(h.request(playable_first(1, "marimba-bar")));
        wait_for(&h, |h| !h.compiling());
        let inst = h.take_first().expect("the playable scene");
        let first = inst.prepared();
        assert!(!first.complete);
        assert_eq!(first.scenes.variant_count(), 0);
        let full = next_ready(&h, 60_000).expect("the whole scene follows");
        assert_eq!(full.revision, 1);
        assert!(full.complete);
        assert!(full.scenes.variant_count() > 0);
        assert_eq!(full.params, first.params);
        assert_eq!(h.failures.load(Ordering::Acquire), 0);

        // cancelled as soon as the playable scene is there: no upgrade
        assert!(h.request(playable_first(2, "marimba-bar")));
        wait_for(&h, |h| !h.compiling());
        assert!(h.take_first().is_some());
        h.cancel_through(2);
        let mut later = request(3, false);
        later.params.preset = preset("steel-plate");
        assert!(h.request(later));
        let got = next_ready(&h, 60_000).expect("the later request's scene");
        assert_eq!(got.revision, 3, "the cancelled upgrade came");
        assert!(next_ready(&h, 200).is_none());

        // a kit's playable scene leaves its hardness levels out, and the
        // whole kit follows with them
        assert!(h.request(playable_first(4, "snare-pair")));
        wait_for(&h, |h| !h.compiling());
        let inst = h.take_first().expect("the kit");
        let first = inst.prepared();
        assert!(!first.complete);
        assert_eq!(first.kit.as_ref().unwrap().hardness_levels(), 0);
        let full = next_ready(&h, 60_000).expect("the whole kit follows");
        assert!(full.complete);
        assert_eq!(full.kit.as_ref().unwrap().hardness_levels(), 4);
        assert!(
            next_ready(&h, 500).is_none(),
            "an upgrade of a complete scene"
        );
        w.stop();
    }

    /// A compile cancelled inside its scope gives up and says so.
    #[test]
    fn a_compile_cancelled_in_its_scope_reports_cancelled() {
        let lib = SceneLibrary::default();
        let c = Cancel::new();
        c.cancel();
        let r = cancel::scope(&c, || compile(&lib, &request(1, true), |_| {}));
        assert_eq!(r.err().as_deref(), Some("compile cancelled"));
    }
}
