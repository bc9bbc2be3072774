//! The one-contact engine's event model as the certified search sees it
//! (`engine/search.rs`: the bisection and the root's refinement, shared
//! with the several-contact engine; docs/numerics.md, "Certified isolation
//! of the first crossing").

use super::STACK;
use crate::compile::CompiledScene;
use crate::engine::search::{self, EventModel, Found, NodeBounds, Tally};
use crate::engine::EngineState;

/// The current model of `phi` (built by `build_model`) over the rest of
/// the sample.
struct OneContact<'a> {
    st: &'a mut EngineState,
    scene: &'a CompiledScene,
}

impl EventModel for OneContact<'_> {
    #[inline]
    fn bounds(&mut self, a: f64, w: f64) -> NodeBounds {
        self.st.node_bounds(self.scene, a, w, false)
    }

    #[inline]
    fn eval(&mut self, t: f64) -> [f64; 3] {
        self.st.model_eval(self.scene, t)
    }

    #[inline]
    fn tolerances(&self) -> (f64, f64) {
        (self.st.search.tol, self.st.search.tol_d)
    }

    #[inline]
    fn stack(&mut self) -> &mut [(f64, f64); STACK] {
        &mut self.st.search.stack
    }
}

impl EngineState {
    /// The first crossing of the model in `(0, rem]` (`open`: the origin is
    /// a switch instant, where `phi` is zero to rounding and rising).
    pub(super) fn first_root(
        &mut self,
        scene: &CompiledScene,
        rem: f64,
        open: bool,
        nodes: &mut u64,
    ) -> Found {
        let step_s = self.step_s;
        let mut tally = Tally::default();
        let found = search::first_root(
            &mut OneContact { st: self, scene },
            step_s,
            rem,
            open,
            &mut tally,
        );
        *nodes += tally.nodes;
        let x = &mut self.exact_stats;
        x.grazing += tally.grazing;
        x.uncertified += tally.uncertified;
        x.roots_refined += tally.refined;
        x.root_evals += tally.root_evals;
        found
    }
}
