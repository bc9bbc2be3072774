//! What of the compile handoff may block, kept out of the files the
//! real-time rules scan (plugin-tests/tests/host_abuse.rs): the short
//! critical sections the worker and the main thread share (the running
//! compile's flag, the last error) and the waits for a scene. The only
//! caller on the audio thread is an offline render (the host's offline
//! mode, where a block may take its time: docs/design.md, "The plugin and
//! its threads"); a real-time `process` never comes here.

use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The access [`Shared::get`] gives: the value, held until it is dropped
/// (the worker's compile hands it to the step that publishes the result).
/// \[worker\] \[main-thread\]
pub type Held<'a, T> = MutexGuard<'a, T>;

/// A value the worker and the main or GUI thread share behind a lock the
/// audio thread never takes. \[worker\] \[main-thread\]
#[derive(Debug, Default)]
pub struct Shared<T>(Mutex<T>);

impl<T> Shared<T> {
    /// Share `v`.
    pub fn new(v: T) -> Self {
        Self(Mutex::new(v))
    }

    /// The value, even if a panicking thread poisoned the lock (plain
    /// values, always consistent).
    pub fn get(&self) -> Held<'_, T> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// How long a wait sleeps between two looks.
const NAP: Duration = Duration::from_micros(500);

/// Sleep while `busy` holds, until `deadline` if there is one; whether it
/// still held at the end. Offline renders and activation only.
pub fn while_busy(busy: impl Fn() -> bool, deadline: Option<Instant>) -> bool {
    loop {
        if !busy() {
            return false;
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            return true;
        }
        std::thread::sleep(NAP);
    }
}
