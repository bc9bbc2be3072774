//! The compile budget: an estimate of what a compile will cost, made before
//! any O(d^3) work, so that a scene too big for the machine is refused with a
//! message instead of being attempted (docs/design.md, "The compiler").
//!
//! What dominates the cost (see `compile_opts`), with `n` the struck object's
//! degrees of freedom after pruning, `nf = 2 n` the free-phase dimension and
//! `d = 2 n + 2` the contact-phase dimension:
//! - each general non-symmetric eigendecomposition of dimension `x` (faer's
//!   real EVD with eigenvectors, the inverse of V, the residual product and
//!   the condition number): [`EIG_FLOPS_PER_DIM3`] `* x^3`. A string needs
//!   two, of dimension `2 n` (free) and `2 n + 2` (contact);
//! - a modal object's free phase needs none (closed form), and its contact
//!   phase, of dimension `x = 2 n_c + 2` (`n_c` the modes with a non-zero
//!   weight at the contact point; the others stay out of the eigenproblem),
//!   takes the rank-one secular route (O(x^2) roots and eigenvectors, plus
//!   the O(x^3) residual product): [`SECULAR_FLOPS_PER_DIM3`] `* x^3`. If
//!   that route fails, the general one is used only if its own estimate fits
//!   the budget too ([`CompileCost::general_fits`]);
//! - a string's changes of basis between the phases, four dense products:
//!   `4 d^2 nf + 4 d nf^2` flops (a modal object's are gathers, O(d^2));
//! - with gravity, the LU solve for the static equilibrium: `2/3 d^3`;
//! - a string's Cholesky factor and its inverse: `~2 n^3`.
//!
//! Memory: [`DENSE_MATRICES_KEPT`] dense matrices of about `d x d` (object and
//! contact generators, V and V^-1 of both phases, the changes of basis and
//! the temporaries of the products), plus [`EIG_SCRATCH_MATRICES`] of `x x x`
//! per general eigendecomposition (one for the secular route), 8 bytes per
//! entry.
//!
//! Calibration (release profile, on the 2-core AMD EPYC development
//! machine): one estimated flop is ~45 ps there, so the default budget of
//! 1.5e12 is about a minute. The estimates against the measured compiles:
//! modal objects by the secular route, 800 to 1900 modes all coupled, time
//! 0.5x-0.9x of the measured and peak RSS within 3 %; 1000 modes through
//! the general route (a degenerate pair refuses the secular one) time 1.0x,
//! memory 1.2x; strings of 400 to 1000 masses time 1.2x-1.4x, memory
//! 1.2x-1.3x. `cargo bench --bench engine -- summary` prints the compile
//! time of 100, 400 and 1000 modes on the machine it runs on
//! (docs/benchmarks.md).

use super::error::OverBudget;
use crate::scene::{ObjectSpec, Scene};

/// Flop-equivalents per `x^3` for one general eigendecomposition of
/// dimension `x` (calibrated, see the module doc).
pub const EIG_FLOPS_PER_DIM3: f64 = 25.0;
/// Flop-equivalents per `x^3` for the rank-one secular route (calibrated).
pub const SECULAR_FLOPS_PER_DIM3: f64 = 5.0;
/// Dense matrices of about `d x d` alive at the peak of a compile.
pub const DENSE_MATRICES_KEPT: f64 = 12.0;
/// Extra dense matrices of `x x x` during one general eigendecomposition.
pub const EIG_SCRATCH_MATRICES: f64 = 6.0;
/// Extra dense matrices of `x x x` for the secular route.
pub const SECULAR_SCRATCH_MATRICES: f64 = 1.0;

/// Limits on what one compile may cost (see the module doc for the model).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompileBudget {
    /// Largest estimated work [flop-equivalents]. The default, 1.5e12, is
    /// about a minute on the 2-core development machine: it admits an
    /// 800-mass string (1.1e12) and refuses a 1000-mass one (2.2e12).
    pub max_flops: f64,
    /// Largest estimated peak memory \[bytes\]. The default, 1 GiB, admits
    /// 1500 fully coupled modes (~0.94 GB) and refuses 1600 (1.07 GB).
    pub max_bytes: f64,
}

impl CompileBudget {
    /// The default budget (see the field docs).
    pub const DEFAULT: Self = Self {
        max_flops: 1.5e12,
        max_bytes: (1u64 << 30) as f64,
    };
    /// No limit (tests that must compile whatever the cost).
    pub const UNLIMITED: Self = Self {
        max_flops: f64::INFINITY,
        max_bytes: f64::INFINITY,
    };
}

impl Default for CompileBudget {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What a compile of one struck object is estimated to cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompileCost {
    /// Degrees of freedom of the struck object after pruning.
    pub n: usize,
    /// Of those, the modes inside the contact eigenproblem (modal objects;
    /// `n` otherwise).
    pub n_coupled: usize,
    /// Dimension of the free phase (`2 n`).
    pub free_dim: usize,
    /// Dimension of the contact phase (`2 n + 2`).
    pub contact_dim: usize,
    /// Dimension of the free-phase eigenproblem (0: closed form).
    pub free_eig_dim: usize,
    /// Dimension of the contact-phase eigenproblem.
    pub contact_eig_dim: usize,
    /// The contact eigenproblem takes the rank-one secular route (a modal
    /// object) rather than the general eigensolver.
    pub secular: bool,
    /// With gravity (the static-equilibrium solve).
    pub gravity: bool,
    /// Estimated work [flop-equivalents].
    pub flops: f64,
    /// Estimated peak memory \[bytes\].
    pub bytes: f64,
}

impl CompileCost {
    /// Estimate from the dimensions (see the module doc). `secular`: the
    /// contact eigenproblem takes the rank-one route (modal objects).
    pub fn from_dims(
        n: usize,
        n_coupled: usize,
        free_eig: bool,
        contact_eig_dim: usize,
        gravity: bool,
        secular: bool,
    ) -> Self {
        let nf = (2 * n) as f64;
        let d = nf + 2.0;
        let free_eig_dim = if free_eig { 2 * n } else { 0 };
        let (xf, xc) = (free_eig_dim as f64, contact_eig_dim as f64);
        let (per_dim3, scratch) = if secular {
            (SECULAR_FLOPS_PER_DIM3, SECULAR_SCRATCH_MATRICES)
        } else {
            (EIG_FLOPS_PER_DIM3, EIG_SCRATCH_MATRICES)
        };
        let mut flops = EIG_FLOPS_PER_DIM3 * xf.powi(3) + per_dim3 * xc.powi(3);
        if free_eig {
            // a string: dense changes of basis, Cholesky of K and the
            // inverse of its factor
            flops += 4.0 * d * d * nf + 4.0 * d * nf * nf;
            flops += 2.0 * (n as f64).powi(3);
        }
        if gravity {
            flops += 2.0 / 3.0 * d.powi(3);
        }
        let bytes = 8.0
            * (DENSE_MATRICES_KEPT * d * d + EIG_SCRATCH_MATRICES * xf * xf + scratch * xc * xc);
        Self {
            n,
            n_coupled,
            free_dim: 2 * n,
            contact_dim: 2 * n + 2,
            free_eig_dim,
            contact_eig_dim,
            secular,
            gravity,
            flops,
            bytes,
        }
    }

    /// The same compile through the general eigensolver (what a failed
    /// secular route falls back to).
    pub fn general(&self) -> Self {
        Self::from_dims(
            self.n,
            self.n_coupled,
            self.free_eig_dim > 0,
            self.contact_eig_dim,
            self.gravity,
            false,
        )
    }

    /// Whether the general eigensolver's estimate also fits `budget` (a
    /// failed secular route may fall back to it only then).
    pub fn general_fits(&self, budget: &CompileBudget) -> bool {
        let g = self.general();
        g.flops <= budget.max_flops && g.bytes <= budget.max_bytes
    }

    /// Estimate for compiling `spec` (the struck object after pruning) struck
    /// at `contact_point`. With `exact_savings`, modes with zero weight at the
    /// contact point stay out of the contact eigenproblem (as `compile` does).
    pub fn estimate(
        spec: &ObjectSpec,
        contact_point: Option<&str>,
        gravity: bool,
        exact_savings: bool,
    ) -> Self {
        match spec {
            ObjectSpec::Modal(m) => {
                let n = m.mode.len();
                let cp = contact_point.and_then(|p| m.points.iter().position(|x| x == p));
                let n_coupled = match cp {
                    Some(cp) if exact_savings => {
                        m.mode.iter().filter(|md| md.weights[cp] != 0.0).count()
                    }
                    _ => n,
                };
                Self::from_dims(n, n_coupled, false, 2 * n_coupled + 2, gravity, true)
            }
            ObjectSpec::String(s) => {
                Self::from_dims(s.masses, s.masses, true, 2 * s.masses + 2, gravity, false)
            }
            ObjectSpec::Wall(_) => Self::from_dims(0, 0, false, 2, gravity, true),
            // the compiler estimates the expanded scene
            // ([`Scene::expanded`]), where a physical object is modal
            ObjectSpec::Bar(_)
            | ObjectSpec::Tube(_)
            | ObjectSpec::Plate(_)
            | ObjectSpec::Membrane(_)
            | ObjectSpec::StiffString(_)
            | ObjectSpec::Chain(_) => Self::from_dims(0, 0, false, 2, gravity, true),
        }
    }

    /// `Ok` when the cost fits `budget`; otherwise what the estimate is,
    /// what the limit is, and how to get under it. `scene` and `obj_idx`
    /// name the struck object.
    pub fn check(
        &self,
        budget: &CompileBudget,
        scene: &Scene,
        obj_idx: usize,
    ) -> Result<(), Box<OverBudget>> {
        let over_flops = !(self.flops <= budget.max_flops);
        let over_bytes = !(self.bytes <= budget.max_bytes);
        if !over_flops && !over_bytes {
            return Ok(());
        }
        let obj = &scene.object[obj_idx];
        let what = match obj {
            ObjectSpec::String(_) => format!(
                "{} masses: eigenproblems of dimension {} (free) and {} (contact)",
                self.n, self.free_eig_dim, self.contact_eig_dim
            ),
            _ => format!(
                "{} modes kept, {} of them coupled to the contact point: a contact eigenproblem of dimension {}, changes of basis of {}x{}",
                self.n, self.n_coupled, self.contact_eig_dim, self.contact_dim, self.free_dim
            ),
        };
        let hint = match obj {
            ObjectSpec::String(_) => format!("use fewer masses (object[{obj_idx}].masses)"),
            _ => "use fewer modes, drop high or quiet modes with [approximate] nyquist_fraction, max_freq_hz or quiet_below_db, or give modes that need not be struck a zero weight at the contact point (they stay out of the eigenproblem)".to_string(),
        };
        Err(Box::new(OverBudget {
            object: obj_idx,
            name: obj.name().to_string(),
            what,
            flops: over_flops.then_some((self.flops, budget.max_flops)),
            bytes: over_bytes.then_some((self.bytes, budget.max_bytes)),
            hint,
        }))
    }
}
