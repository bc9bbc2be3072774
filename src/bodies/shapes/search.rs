//! Two searches the kinds share: a root in a sign-change bracket
//! (Newton's method safeguarded by bisection: beam roots, Bessel zeros),
//! and the points of a two-index mode family in ascending frequency
//! (plates, membranes).

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

/// Newton's method kept inside a sign-change bracket `[lo, hi]` (bisection
/// when a step leaves it). Returns the best point found.
pub(super) fn safeguarded_newton(
    f: impl Fn(f64) -> f64,
    df: impl Fn(f64) -> f64,
    mut lo: f64,
    mut hi: f64,
    guess: f64,
) -> f64 {
    let f_lo = f(lo);
    if f_lo == 0.0 {
        return lo;
    }
    let lo_negative = f_lo < 0.0;
    let mut x = if guess > lo && guess < hi {
        guess
    } else {
        0.5 * (lo + hi)
    };
    for _ in 0..200 {
        let fx = f(x);
        if fx == 0.0 {
            return x;
        }
        if (fx < 0.0) == lo_negative {
            lo = x;
        } else {
            hi = x;
        }
        let d = df(x);
        let newton = x - fx / d;
        let next = if d != 0.0 && newton.is_finite() && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        let step = (next - x).abs();
        x = next;
        if step <= 4.0 * f64::EPSILON * x.abs() || hi - lo <= 4.0 * f64::EPSILON * x.abs() {
            break;
        }
    }
    x
}

/// `f64` with a total order, for the heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Key(f64);

impl Eq for Key {}

impl PartialOrd for Key {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Key {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// Visit the lattice `m >= m0`, `n >= n0` in ascending `value(m, n)`, for a
/// `value` nondecreasing in each index, until `visit` returns false. Only
/// the visited points and their successors are evaluated.
pub(super) fn lattice_ascending(
    m0: usize,
    n0: usize,
    mut value: impl FnMut(usize, usize) -> Result<f64, String>,
    mut visit: impl FnMut(usize, usize, f64) -> bool,
) -> Result<(), String> {
    let mut heap = BinaryHeap::new();
    heap.push(Reverse((Key(value(m0, n0)?), m0, n0)));
    while let Some(Reverse((Key(v), m, n))) = heap.pop() {
        if !visit(m, n, v) {
            break;
        }
        heap.push(Reverse((Key(value(m, n + 1)?), m, n + 1)));
        if n == n0 {
            heap.push(Reverse((Key(value(m + 1, n0)?), m + 1, n0)));
        }
    }
    Ok(())
}
