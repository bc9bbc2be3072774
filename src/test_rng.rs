//! The one seeded generator of the project's tests (splitmix64): random
//! arguments, block sizes, events and scenes that are the same on every run,
//! so a red run is a regression and not a new draw. Tiny and without
//! dependencies because the plugin library carries it (hidden): its own unit
//! tests use it, and everything else reaches it through
//! `modal_testkit::rng`. Not for the audio path.

/// splitmix64: a 64-bit state advanced by a fixed odd increment and mixed.
/// Any seed, 0 included, gives a full-period stream.
pub struct TestRng(pub u64);

impl TestRng {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// An index in `0..n` (0 when `n` is 0). The modulo bias, below
    /// `n / 2^64`, does not matter for test inputs.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
}
