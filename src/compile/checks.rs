//! Stage 5 of the compiler: what must hold before the engine may step a
//! compiled scene (docs/numerics.md, "Energy coordinates and passivity" and
//! "Where the claims stop"):
//!
//! - every matrix finite;
//! - every one-sample propagator passive in f64 (largest singular value at
//!   most `1 + 16 dim kappa u`), else the scene is refused with the reason;
//! - exact switching only where its partial steps are affordable: a dense
//!   fallback phase needs `ceil(|A|_F tau / 0.5)` Taylor sub-steps per
//!   evaluation, so a large or very stiff one gets the offset rod, and the
//!   summary says so.

use super::error::{stiffness_hint, CompileError, PhaseKind};
use super::CompiledPhase;
use crate::scene::{Scene, Switching};

/// Largest dense-fallback phase for which exact switching is offered (its
/// partial steps cost O(dim^2) per Taylor term; near-defective phases are in
/// practice small).
pub const MAX_DENSE_EXACT_DIM: usize = 16;
/// Largest `|A|_F h` of a dense-fallback phase for which exact switching is
/// offered: the engine's partial dense steps take `ceil(|A|_F tau / 0.5)`
/// Taylor sub-steps of 20 mat-vecs each, per event-function evaluation, so a
/// very stiff or very damped dense phase (the scene fuzzer found `|A| h ~
/// 1e6`, which made one sample take minutes) gets the offset rod instead.
/// 8 allows 16 sub-steps (~80k flops per evaluation at dimension 16).
pub const MAX_DENSE_EXACT_NORM_H: f64 = 8.0;
/// Passivity check of every compiled propagator: its largest singular value
/// over one sample, in energy coordinates, may exceed 1 by at most this many
/// units of `dim * kappa(V) * u` (the rounding of forming `V exp(G h) V^-1`,
/// or of the dense `exp(A h)` with `kappa = 1`). A larger excess means the
/// decomposition or the Pade exponential is not accurate enough for the
/// phase to be passive in f64, and stepping it could create energy (the
/// scene fuzzer found a dense contact phase with `|A| h = 1.6e9` and
/// `sigma_max - 1 = 4.5e-8`): such a scene is refused.
pub const PASSIVITY_TOL_PER_DIM_KAPPA_U: f64 = 16.0;

/// The switching method the scene gets, and why when it is not the one
/// asked for.
pub(super) fn switching(
    asked: Switching,
    phases: [&CompiledPhase; 2],
    h: f64,
) -> (Switching, Option<String>) {
    if asked != Switching::Exact {
        return (asked, None);
    }
    let mut out = (asked, None);
    for ph in phases {
        let Some((a, _)) = &ph.dense else { continue };
        let norm_h = a.norm() * h;
        if ph.dim > MAX_DENSE_EXACT_DIM {
            out = (
                Switching::OffsetRod,
                Some(format!(
                    "exact switching needs partial dense steps of dimension {} > {MAX_DENSE_EXACT_DIM}: using the offset rod",
                    ph.dim
                )),
            );
        } else if !(norm_h <= MAX_DENSE_EXACT_NORM_H) {
            out = (
                Switching::OffsetRod,
                Some(format!(
                    "exact switching needs partial dense steps with |A| h = {norm_h:.1e} > {MAX_DENSE_EXACT_NORM_H} (too many Taylor sub-steps): using the offset rod"
                )),
            );
        }
    }
    out
}

/// Every entry finite, and every one-sample propagator passive in f64.
pub(super) fn finite_and_passive(
    phases: [(PhaseKind, &CompiledPhase); 2],
    h: f64,
    scene: &Scene,
    ci: usize,
) -> Result<(), CompileError> {
    for (what, ph) in phases {
        let all_finite = ph.v.iter().all(|x| x.is_finite())
            && ph.gens.iter().flatten().flatten().all(|x| x.is_finite());
        if !all_finite {
            return Err(CompileError::NonFinite(match what {
                PhaseKind::Free => "free phase",
                PhaseKind::Contact => "contact phase",
            }));
        }
    }
    for (what, ph) in phases {
        let d = &ph.diag;
        let kappa = if ph.dense.is_some() || !d.kappa.is_finite() {
            1.0
        } else {
            d.kappa.max(1.0)
        };
        let tol = PASSIVITY_TOL_PER_DIM_KAPPA_U * ph.dim as f64 * kappa * (f64::EPSILON / 2.0);
        if !(d.sigma_max - 1.0 <= tol) {
            let norm_h = match &ph.dense {
                Some((a, _)) => a.norm() * h,
                None => {
                    ph.gens
                        .iter()
                        .flatten()
                        .map(|g| g.iter().map(|x| x * x).sum::<f64>().sqrt())
                        .fold(0.0, f64::max)
                        * h
                }
            };
            return Err(CompileError::NotPassive {
                phase: what,
                method: d.method.clone(),
                excess: d.sigma_max - 1.0,
                tol,
                norm_h,
                rate_hz: 1.0 / h,
                hint: stiffness_hint(what, scene, ci),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compile::compile_one;
    use crate::presets;

    fn any_phase() -> CompiledPhase {
        compile_one(&presets::scene(0).unwrap(), 44100.0)
            .unwrap()
            .free
    }

    /// A phase whose propagator's largest singular value exceeds 1 by more
    /// than rounding is refused as not passive, with the phase named.
    #[test]
    fn a_non_passive_phase_is_refused() {
        let good = any_phase();
        let mut bad = good.clone();
        bad.diag.sigma_max = 1.0 + 1e-9;
        let sc = presets::scene(0).unwrap();
        let h = 1.0 / 44100.0;
        finite_and_passive(
            [(PhaseKind::Free, &good), (PhaseKind::Contact, &good)],
            h,
            &sc,
            0,
        )
        .unwrap();
        let e = finite_and_passive(
            [(PhaseKind::Free, &good), (PhaseKind::Contact, &bad)],
            h,
            &sc,
            0,
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                CompileError::NotPassive {
                    phase: PhaseKind::Contact,
                    ..
                }
            ),
            "{e}"
        );
        let mut nan = good.clone();
        nan.v[(0, 0)] = f64::NAN;
        let e = finite_and_passive(
            [(PhaseKind::Free, &nan), (PhaseKind::Contact, &good)],
            h,
            &sc,
            0,
        )
        .unwrap_err();
        assert_eq!(e, CompileError::NonFinite("free phase"));
    }

    /// Exact switching stays for block phases; a large dense fallback phase
    /// gets the offset rod with a note.
    #[test]
    fn large_dense_phases_get_the_offset_rod() {
        let blocks = any_phase();
        let h = 1.0 / 44100.0;
        assert_eq!(
            switching(Switching::Exact, [&blocks, &blocks], h),
            (Switching::Exact, None)
        );
        let mut dense = blocks.clone();
        let n = MAX_DENSE_EXACT_DIM + 2;
        dense.dim = n;
        dense.dense = Some((nalgebra::DMatrix::zeros(n, n), vec![0.0; n * n]));
        let (sw, note) = switching(Switching::Exact, [&blocks, &dense], h);
        assert_eq!(sw, Switching::OffsetRod);
        assert!(note.unwrap().contains("partial dense steps of dimension"));
        assert_eq!(
            switching(Switching::OffsetRod, [&blocks, &dense], h).0,
            Switching::OffsetRod
        );
    }
}
