//! The per-instance background compile thread and its lock-free handoff.
//!
//! Three bounded queues (crossbeam `ArrayQueue`, lock-free, no allocation
//! after construction) connect the audio thread and the worker:
//!
//! - `requests` (audio -> worker): a tiny `Copy` [`CompileRequest`]. If it is
//!   full the audio thread retries at the next block.
//! - `ready` (worker -> audio): a `Box<Prepared>` (compiled scene, its damped
//!   variant and fresh per-voice states). The audio thread pops it at a block
//!   boundary and swaps it in.
//! - `returned` (audio -> worker): retired boxes, freed here. If it is full the
//!   box stays in the instrument's fixed retired slots until the next block.
//!
//! The worker polls with `park_timeout` (the audio thread never wakes it: an
//! unpark is a system call). It is spawned in `activate` and joined in
//! `deactivate`/drop; the shared nice-plug background thread is not used (one
//! long eigensolve there would stall every other plugin instance).

use super::user_scene::{HostBlocks, SceneLibrary};
use crate::instrument::{Prepared, SceneParams};
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
}

/// State shared by the audio thread and the worker (queues and counters).
pub struct Handoff {
    requests: ArrayQueue<CompileRequest>,
    ready: ArrayQueue<Box<Prepared>>,
    returned: ArrayQueue<Box<Prepared>>,
    stop: AtomicBool,
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
    pub last_error: std::sync::Mutex<Option<String>>,
}

impl Handoff {
    /// Allocate the queues. \[main-thread\]
    pub fn new() -> Arc<Self> {
        Arc::new(Self {
            requests: ArrayQueue::new(REQUEST_CAPACITY),
            ready: ArrayQueue::new(READY_CAPACITY),
            returned: ArrayQueue::new(RETURN_CAPACITY),
            stop: AtomicBool::new(false),
            compiles: AtomicU64::new(0),
            failures: AtomicU64::new(0),
            published_revision: AtomicU64::new(0),
            last_compile_ms: AtomicF64::new(0.0),
            requested_revision: AtomicU64::new(0),
            failed_revision: AtomicU64::new(0),
            busy: AtomicBool::new(false),
            last_error: std::sync::Mutex::new(None),
        })
    }

    /// Post a request; false if the queue is full (retry later). Lock-free,
    /// no allocation. \[audio-thread\]
    pub fn request(&self, req: CompileRequest) -> bool {
        self.requests.push(req).is_ok()
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
        self.last_error.lock().ok().and_then(|e| e.clone())
    }

    /// Free everything still queued (when no worker runs). \[main-thread\]
    pub fn drain(&self) {
        while self.returned.pop().is_some() {}
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

    /// Stop and join the worker, then free whatever is still queued.
    /// \[main-thread\]
    pub fn stop(&mut self) {
        if let Some(t) = self.thread.take() {
            self.handoff.stop.store(true, Ordering::Release);
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
        let mut newest: Option<CompileRequest> = None;
        while let Some(r) = h.requests.pop() {
            if newest.is_none_or(|n| r.revision >= n.revision) {
                newest = Some(r);
            }
        }
        let Some(req) = newest else {
            std::thread::park_timeout(Duration::from_millis(POLL_INTERVAL_MS));
            continue;
        };
        let t0 = Instant::now();
        let host = HostBlocks {
            max_block: req.max_block,
            polyphony: req.polyphony,
            lookahead: req.lookahead,
        };
        match lib.prepare(&req.params, req.rate_hz, req.revision, host) {
            Ok((p, warnings)) => {
                for w in warnings {
                    nice_plug::nice_log!("modal_contact: {w}");
                }
                if req.params.variants != Default::default() {
                    nice_plug::nice_log!(
                        "modal_contact: {} per-voice variant scenes (hardness, strike position, \
                         damper levels for polyphonic modulation) compiled with the scene in \
                         {:.0} ms",
                        p.scenes.variant_count(),
                        t0.elapsed().as_secs_f64() * 1e3
                    );
                }
                h.last_compile_ms
                    .store(t0.elapsed().as_secs_f64() * 1e3, Ordering::Relaxed);
                h.compiles.fetch_add(1, Ordering::Relaxed);
                h.published_revision.store(req.revision, Ordering::Release);
                publish(h, p);
            }
            Err(e) => {
                h.failures.fetch_add(1, Ordering::Relaxed);
                nice_plug::nice_log!(
                    "modal_contact: compile of revision {} failed, keeping the last scene: {e}",
                    req.revision
                );
            }
        }
    }
}

/// Publish, replacing a stale unread result if the queue is full (the stale
/// box is freed here, on the worker). \[worker\]
fn publish(h: &Handoff, mut p: Box<Prepared>) {
    loop {
        match h.ready.push(p) {
            Ok(()) => return,
            Err(back) => {
                p = back;
                if let Some(stale) = h.ready.pop() {
                    drop(stale);
                }
            }
        }
    }
}
