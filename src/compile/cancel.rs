//! Cooperative cancellation of long compiles (docs/design.md, "The plugin
//! and its threads").
//!
//! The plugin's worker runs each compile inside [`scope`] with a
//! [`Cancel`] of its own; deactivation and the instance's end cancel it.
//! The compiler's long loops (following a strike from rest, recording the
//! keys' strikes, the variants compiled side by side) ask [`cancelled`]
//! every few thousand steps and give up; the caller then reports
//! [`Cancelled`]. Outside a scope nothing is ever cancelled (the command
//! line, the tests, the benches compile as before).
//!
//! The scope is per thread: work spread over threads takes the scope along
//! with [`current`] and [`scope`].

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A flag that cancels the work running in its [`scope`]. Cloning shares
/// the flag.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A fresh, uncancelled flag.
    pub fn new() -> Self {
        Self::default()
    }

    /// Cancel the work in every scope of this flag (any thread; no lock,
    /// no allocation).
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Release);
    }

    /// Whether it was cancelled.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }
}

thread_local! {
    static CURRENT: RefCell<Option<Cancel>> = const { RefCell::new(None) };
}

/// Run `f` with `cancel` as this thread's cancellation (restored after,
/// also if `f` panics through it).
pub fn scope<R>(cancel: &Cancel, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<Cancel>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let prev = self.0.take();
            CURRENT.with(|c| *c.borrow_mut() = prev);
        }
    }
    let prev = CURRENT.with(|c| c.borrow_mut().replace(cancel.clone()));
    let _restore = Restore(prev);
    f()
}

/// This thread's cancellation, to hand to threads it spawns.
pub fn current() -> Option<Cancel> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Run `f` in the scope of `cancel` if there is one, else as it is.
pub fn within<R>(cancel: Option<&Cancel>, f: impl FnOnce() -> R) -> R {
    match cancel {
        Some(c) => scope(c, f),
        None => f(),
    }
}

/// Whether the work on this thread was cancelled (false outside a scope).
pub fn cancelled() -> bool {
    CURRENT.with(|c| c.borrow().as_ref().is_some_and(Cancel::is_cancelled))
}

/// A compile given up because it was cancelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cancelled;

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "compile cancelled")
    }
}

impl std::error::Error for Cancelled {}

/// `Err(Cancelled)` if the work on this thread was cancelled.
pub fn check() -> Result<(), Cancelled> {
    if cancelled() {
        Err(Cancelled)
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scope_sees_its_flag_and_ends_with_it() {
        assert!(!cancelled(), "outside a scope nothing is cancelled");
        let c = Cancel::new();
        scope(&c, || {
            assert!(!cancelled());
            c.cancel();
            assert!(cancelled());
            assert_eq!(check(), Err(Cancelled));
            // a thread it spawns sees it only when handed over
            let cur = current();
            std::thread::spawn(move || {
                assert!(!cancelled());
                within(cur.as_ref(), || assert!(cancelled()));
            })
            .join()
            .unwrap();
            // an inner scope of another flag hides it, then restores it
            scope(&Cancel::new(), || assert!(!cancelled()));
            assert!(cancelled());
        });
        assert!(!cancelled());
    }
}
