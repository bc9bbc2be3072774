//! Settings that choose between equivalent ways to the same samples: the
//! kernels, subnormal flushing, and the shortcuts of exact switching. Each
//! default is the fast way; benchmarks and tests turn one off to measure
//! what it saves or to compare it with the plain way.

use super::vmath::SimdPath;
use super::EngineState;

impl EngineState {
    /// Flush subnormal numbers to zero while stepping (default: on; see
    /// [`denormal`](super::denormal)). Off only to measure what it saves. \[any-thread\]
    pub fn set_flush_denormals(&mut self, on: bool) {
        self.flush_denormals = on;
    }

    /// Run the portable kernels (`true`) or the fastest ones this CPU has
    /// (`false`, the default). The two round differently (fused
    /// multiply-adds), each deterministically; benchmarks and equivalence
    /// tests compare them. \[any-thread\]
    pub fn set_portable_kernels(&mut self, portable: bool) {
        self.simd = if portable {
            SimdPath::Generic
        } else {
            SimdPath::detect()
        };
    }

    /// Whether the portable kernels run (see
    /// [`set_portable_kernels`](Self::set_portable_kernels)).
    pub fn portable_kernels(&self) -> bool {
        self.simd == SimdPath::Generic
    }

    /// Let a strike from rest's stored switch instants end the fast path's
    /// runs before the samples that hold them (`true`, the default) or not:
    /// only for tests that check it changes no sample. \[any-thread\]
    #[doc(hidden)]
    pub fn set_rest_schedule(&mut self, on: bool) {
        self.rest_schedule = on;
    }

    /// Take strikes from rest through the stored release (`true`, the
    /// default) or always through the dense change of basis (`false`): only
    /// for tests and benchmarks that compare the two. \[any-thread\]
    #[doc(hidden)]
    pub fn set_rest_strike(&mut self, on: bool) {
        self.rest_enabled = on;
        if !on {
            self.rest_run = None;
        }
    }

    /// Take a strike from rest's stored switches that the engine's
    /// certifying run confirmed at their stored instants without a search
    /// (`true`, the default) or locate each with the search, the stored
    /// instant a hint (`false`): only for tests and benchmarks that compare
    /// the two. \[any-thread\]
    #[doc(hidden)]
    pub fn set_rest_trust(&mut self, on: bool) {
        self.rest_trust = on;
    }

    /// Switch through the hierarchical changes of basis where the scene has
    /// them (`true`, the default) or always through the dense matrices
    /// (`false`): only for tests and benchmarks that compare the two.
    /// \[any-thread\]
    #[doc(hidden)]
    pub fn set_structured_switch(&mut self, on: bool) {
        self.structured = on;
    }

    /// Let the fast path try the Hermite certificate after a failed sample
    /// (`true`, the default) or leave every such sample to the slow path
    /// (`false`): only for tests and benchmarks that compare the two.
    /// \[any-thread\]
    #[doc(hidden)]
    pub fn set_fast_hermite(&mut self, on: bool) {
        self.fast_hermite = on;
    }

    /// Begin the contact of a strike that puts the hammer on the surface
    /// moving into it at the strike's instant (`true`, the default) or
    /// leave that to the search (`false`): only for tests that compare the
    /// two. \[any-thread\]
    #[doc(hidden)]
    pub fn set_strike_entry(&mut self, on: bool) {
        self.strike_entry = on;
    }

    /// Clear the rest of a sample after a located switch with the Hermite
    /// certificate (`true`, the default) or always with the search
    /// (`false`): only for tests and benchmarks that compare the two.
    /// \[any-thread\]
    #[doc(hidden)]
    pub fn set_hermite_after_switch(&mut self, on: bool) {
        self.hermite_after_switch = on;
    }
}
