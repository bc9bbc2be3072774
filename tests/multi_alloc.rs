//! The several-contact engine's step allocates nothing once its state is
//! made (`MultiState::new`), switches and event searches included: a
//! counting allocator around a render of two hammers that strike, bounce
//! and strike again (the first stage towards the audio thread,
//! docs/numerics.md section 14).
//!
//! Built without the `rt-checks` feature only: with it, nice-plug installs
//! its own global allocator (the allocation checker of the plugin's
//! `process`), and a binary has one. `cargo test --release --test
//! multi_alloc` runs it; the CI command, built with `rt-checks`, leaves it
//! out.
#![cfg(not(feature = "rt-checks"))]

use modal_contact::multi::{CompiledMulti, MultiHammer, MultiModel, MultiState};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every method passes its arguments unchanged to the system
// allocator and returns its result, so the memory handed out is `System`'s
// and meets the `GlobalAlloc` contract exactly as `System` does. The counting
// around the calls only updates an atomic counter.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: our caller upholds `alloc`'s contract for `layout`, the
        // same contract `System.alloc` asks for.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator with `layout`, so from
        // `System` (every block of ours is `System`'s), as `dealloc` requires.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: `ptr` came from this allocator, so from `System`, with
        // `layout`, and our caller upholds `realloc`'s contract for
        // `new_size`: what `System.realloc` asks for.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn steps_with_switches_allocate_nothing() {
    let n = 40;
    let freq: Vec<f64> = (0..n).map(|i| 100.0 * (1.0 + i as f64).powf(1.3)).collect();
    // contacts at about 100x Nyquist, critically damped: a penetration
    // that dwells near 0 makes the search halve deep (and takes its stack)
    let hammer = |j: usize, height: f64| MultiHammer {
        mass_kg: 0.02,
        height_m: height,
        velocity_m_per_s: -1.0,
        weights: (0..n)
            .map(|i| ((i * (j + 2)) as f64 * 0.41).cos() / (1.0 + 0.05 * i as f64))
            .collect(),
        stiffness_n_per_m: 4.6e12,
        damping_n_s_per_m: 6e5,
    };
    let m = MultiModel::struck(
        freq.clone(),
        freq.iter().map(|f| 1.0 + f * 1e-3).collect(),
        &[hammer(0, 0.0), hammer(1, 3e-4), hammer(2, 1e-3)],
        9.81,
        [(vec![1.0; n], vec![0.0; n]), (vec![0.0; n], vec![1.0; n])],
    );
    let sc = CompiledMulti::new(&m, 48_000.0).unwrap();
    let mut st = MultiState::new(&sc);
    let before = ALLOCS.load(Ordering::Relaxed);
    let mut peak = 0.0f64;
    for _ in 0..9600 {
        let [l, r] = st.tick(&sc);
        peak = peak.max(l.abs()).max(r.abs());
    }
    let allocs = ALLOCS.load(Ordering::Relaxed) - before;
    let starts = st.stats.contacts_started;
    println!(
        "200 ms, 3 hammers on 40 modes: {} switches, contacts {:?}, {} evaluations, {allocs} allocations",
        st.stats.switches,
        &starts[..3],
        st.stats.evaluations
    );
    assert!(
        st.stats.evaluations > 20 * st.stats.switches,
        "the search went deep"
    );
    assert!(st.stats.switches >= 6 && starts[..3].iter().all(|&c| c >= 1));
    assert!(peak > 0.0 && peak.is_finite());
    assert_eq!(allocs, 0);
}
