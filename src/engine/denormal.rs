//! Subnormal numbers off for the engine's own arithmetic (docs/numerics.md,
//! "f32 or f64").
//!
//! A struck object rings on in its slow modes while its fast ones decay by
//! hundreds of orders of magnitude: a mode with a 0.1 s decay time reaches
//! the subnormal range of f64 (below 2.2e-308) about 10 s after the strike,
//! and stays there for about half a second before it underflows to zero.
//! Arithmetic on subnormals can be one to two orders of magnitude slower
//! than on normal numbers, so a voice would get slower as it fades (the
//! `tail` benchmark measures it). The engine therefore runs with the CPU's
//! flush-to-zero (a result below the normal range becomes 0) and
//! denormals-are-zero (such an input reads as 0) modes on, the standard
//! choice for audio code.
//!
//! What this changes: a number below 2.2e-308 becomes 0. The largest row an
//! output can have (a weight of 1e6 1/sqrt(kg), a gain of 1e6, 1/omega <=
//! 160 s at the lowest allowed mode) turns that into less than 4e-294 at an
//! output, far below the smallest f32 (1.4e-45) the plugin writes, and the
//! energy can only lose it. Samples whose numbers all stay normal are bit
//! for bit what they would be without it.
//!
//! The modes are set for the duration of a [`FlushDenormals`] guard and
//! restored when it drops, only if they were not on already (a host that
//! sets them itself, as many do, costs one register read). x86-64 (MXCSR
//! FTZ and DAZ) and aarch64 (FPCR FZ) are covered; on other targets the
//! guard does nothing.

use std::marker::PhantomData;

#[cfg(target_arch = "x86_64")]
const MXCSR_DAZ: u32 = 1 << 6;
#[cfg(target_arch = "x86_64")]
const MXCSR_FTZ: u32 = 1 << 15;
#[cfg(target_arch = "aarch64")]
const FPCR_FZ: u64 = 1 << 24;

/// Flush-to-zero and denormals-are-zero while alive (this thread only).
/// Not `Send`: it must drop on the thread that made it. \[audio-thread\]
pub struct FlushDenormals {
    /// The control register's value before, if the guard changed it.
    #[allow(dead_code)]
    restore: Option<u64>,
    _not_send: PhantomData<*const ()>,
}

impl FlushDenormals {
    /// Turn the modes on (if `on`; `false` gives a guard that does nothing,
    /// for measuring what the modes save). No allocation, no system call.
    /// \[audio-thread\]
    #[inline]
    pub fn new(on: bool) -> Self {
        let restore = if on { set_flush_modes() } else { None };
        Self {
            restore,
            _not_send: PhantomData,
        }
    }

    /// Whether the modes are on now (on this thread).
    pub fn active() -> bool {
        flush_modes_on()
    }
}

impl Drop for FlushDenormals {
    #[inline]
    fn drop(&mut self) {
        if let Some(old) = self.restore {
            write_control(old);
        }
    }
}

/// Set the modes; `Some(old register)` if that changed the register.
#[inline]
fn set_flush_modes() -> Option<u64> {
    #[cfg(target_arch = "x86_64")]
    {
        let old = read_control();
        let want = old | (MXCSR_DAZ | MXCSR_FTZ) as u64;
        if want != old {
            write_control(want);
            return Some(old);
        }
        None
    }
    #[cfg(target_arch = "aarch64")]
    {
        let old = read_control();
        let want = old | FPCR_FZ;
        if want != old {
            write_control(want);
            return Some(old);
        }
        None
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        None
    }
}

fn flush_modes_on() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let m = (MXCSR_DAZ | MXCSR_FTZ) as u64;
        read_control() & m == m
    }
    #[cfg(target_arch = "aarch64")]
    {
        read_control() & FPCR_FZ != 0
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        false
    }
}

#[cfg(target_arch = "x86_64")]
#[inline]
fn read_control() -> u64 {
    let mut mxcsr: u32 = 0;
    // SAFETY: stores the SSE control/status register into a local u32.
    unsafe {
        std::arch::asm!("stmxcsr [{}]", in(reg) &mut mxcsr, options(nostack, preserves_flags));
    }
    mxcsr as u64
}

#[cfg(target_arch = "x86_64")]
#[inline]
fn write_control(v: u64) {
    let mxcsr = v as u32;
    // SAFETY: loads a value read from MXCSR with only the FTZ/DAZ bits
    // changed (valid bits, no exception unmasked): it changes how this
    // thread rounds subnormal numbers and nothing else.
    unsafe {
        std::arch::asm!("ldmxcsr [{}]", in(reg) &mxcsr, options(nostack, preserves_flags, readonly));
    }
}

#[cfg(target_arch = "aarch64")]
#[inline]
fn read_control() -> u64 {
    let v: u64;
    // SAFETY: reads the floating-point control register.
    unsafe {
        std::arch::asm!("mrs {}, fpcr", out(reg) v, options(nomem, nostack, preserves_flags))
    };
    v
}

#[cfg(target_arch = "aarch64")]
#[inline]
fn write_control(v: u64) {
    // SAFETY: writes back a value read from FPCR with only the FZ bit changed.
    unsafe { std::arch::asm!("msr fpcr, {}", in(reg) v, options(nomem, nostack, preserves_flags)) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::hint::black_box;

    #[test]
    fn flushes_inside_the_guard_and_restores_after() {
        // black_box inside each scope: the multiply happens between the
        // guard's register writes, not where the optimiser would put it.
        let tiny = || black_box(f64::MIN_POSITIVE);
        let half = || black_box(0.5);
        let before = FlushDenormals::active();
        {
            let _g = FlushDenormals::new(true);
            if cfg!(any(target_arch = "x86_64", target_arch = "aarch64")) {
                assert!(FlushDenormals::active());
                // a subnormal result becomes 0
                assert_eq!(black_box(tiny() * half()), 0.0);
                // nested guards leave the modes on
                {
                    let _inner = FlushDenormals::new(true);
                }
                assert!(FlushDenormals::active());
            }
        }
        assert_eq!(FlushDenormals::active(), before);
        if !before {
            // outside: gradual underflow as usual
            let x = black_box(tiny() * half());
            assert!(x > 0.0 && x.is_subnormal(), "{x:e}");
        }
        // an inactive guard changes nothing
        let _off = FlushDenormals::new(false);
        assert_eq!(FlushDenormals::active(), before);
    }
}
