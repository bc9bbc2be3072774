//! The compile budget: an estimate of what a compile will cost, made before
//! any O(d^3) work, so that a scene too big for the machine is refused with a
//! message instead of being attempted (issue #6: "a compile that would take
//! too long or too much memory is refused with a message, not attempted").
//!
//! What dominates the cost (see `compile_opts`), with `n` the struck object's
//! degrees of freedom after pruning, `nf = 2 n` the free-phase dimension and
//! `d = 2 n + 2` the contact-phase dimension:
//! - each non-symmetric eigendecomposition of dimension `x` (faer's real EVD
//!   with eigenvectors, the SVD for kappa(V), the inverse of V and the
//!   residual product): [`EIG_FLOPS_PER_DIM3`] `* x^3`. A modal object's free
//!   phase needs none (closed form); its contact phase needs one of dimension
//!   `2 n_c + 2`, `n_c` the modes with a non-zero weight at the contact point
//!   (the others stay out of the eigenproblem). A string needs two, of
//!   dimension `2 n` (free) and `2 n + 2` (contact);
//! - the two changes of basis between the phases, four dense products:
//!   `4 d^2 nf + 4 d nf^2` flops;
//! - with gravity, the LU solve for the static equilibrium: `2/3 d^3`;
//! - a string's Cholesky factor and its inverse: `~2 n^3`.
//!
//! Memory: [`DENSE_MATRICES_KEPT`] dense matrices of about `d x d` (object and
//! contact generators, V and V^-1 of both phases, the changes of basis and
//! the temporaries of the products), plus [`EIG_SCRATCH_MATRICES`] of `x x x`
//! per eigendecomposition, 8 bytes per entry.
//!
//! Calibration (2-core development machine, test-release profile): a fully
//! coupled 800-mode object (d = 1602) estimates 6.5e11 flops and compiles in
//! 29 s at 315 MB peak RSS (estimate 370 MB); an 800-mass string estimates
//! 1.3e12 flops and compiles in 75 s at 380 MB (estimate 490 MB); 2000 modes
//! of which 200 are coupled estimate 5.2e11 flops and 1.5 GB and take 28 s at
//! 1.66 GB. So one estimated flop is ~45 ps here (~2e10 per second).

use crate::scene::{ObjectSpec, Scene};

/// Flop-equivalents per `x^3` for one eigendecomposition of dimension `x`
/// (measured: the EVD with eigenvectors, an SVD and an inverse cost ~150
/// times what a dense product of the same size costs per `x^3` flop pair).
pub const EIG_FLOPS_PER_DIM3: f64 = 150.0;
/// Dense matrices of about `d x d` alive at the peak of a compile.
pub const DENSE_MATRICES_KEPT: f64 = 12.0;
/// Extra dense matrices of `x x x` during one eigendecomposition.
pub const EIG_SCRATCH_MATRICES: f64 = 6.0;

/// Limits on what one compile may cost (see the module doc for the model).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompileBudget {
    /// Largest estimated work [flop-equivalents]. The default, 1.5e12, is
    /// about a minute on the 2-core development machine: it admits a fully
    /// coupled 1000-mode object (1.27e12; the stability suite compiles one)
    /// and refuses a 2000-mass string (2.0e13).
    pub max_flops: f64,
    /// Largest estimated peak memory [bytes]. The default, 1 GiB, admits
    /// 1000 fully coupled modes (~0.6 GB).
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
    /// Estimated work [flop-equivalents].
    pub flops: f64,
    /// Estimated peak memory [bytes].
    pub bytes: f64,
}

impl CompileCost {
    /// Estimate from the dimensions (see the module doc).
    pub fn from_dims(
        n: usize,
        n_coupled: usize,
        free_eig: bool,
        contact_eig_dim: usize,
        gravity: bool,
    ) -> Self {
        let nf = (2 * n) as f64;
        let d = nf + 2.0;
        let free_eig_dim = if free_eig { 2 * n } else { 0 };
        let (xf, xc) = (free_eig_dim as f64, contact_eig_dim as f64);
        let mut flops = EIG_FLOPS_PER_DIM3 * (xf.powi(3) + xc.powi(3));
        flops += 4.0 * d * d * nf + 4.0 * d * nf * nf;
        if gravity {
            flops += 2.0 / 3.0 * d.powi(3);
        }
        if free_eig {
            // a string: Cholesky of K and the inverse of its factor
            flops += 2.0 * (n as f64).powi(3);
        }
        let bytes =
            8.0 * (DENSE_MATRICES_KEPT * d * d + EIG_SCRATCH_MATRICES * (xf * xf + xc * xc));
        Self {
            n,
            n_coupled,
            free_dim: 2 * n,
            contact_dim: 2 * n + 2,
            free_eig_dim,
            contact_eig_dim,
            flops,
            bytes,
        }
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
                Self::from_dims(n, n_coupled, false, 2 * n_coupled + 2, gravity)
            }
            ObjectSpec::String(s) => {
                Self::from_dims(s.masses, s.masses, true, 2 * s.masses + 2, gravity)
            }
            ObjectSpec::Wall(_) => Self::from_dims(0, 0, false, 2, gravity),
        }
    }

    /// `Ok` when the cost fits `budget`; otherwise a message that says what
    /// the estimate is, what the limit is, and how to get under it. `scene`
    /// and `obj_idx` name the struck object in the message.
    pub fn check(
        &self,
        budget: &CompileBudget,
        scene: &Scene,
        obj_idx: usize,
    ) -> Result<(), String> {
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
        let mut over = Vec::new();
        if over_flops {
            over.push(format!(
                "estimated work {:.1e} flops exceeds the limit {:.1e}",
                self.flops, budget.max_flops
            ));
        }
        if over_bytes {
            over.push(format!(
                "estimated memory {:.0} MB exceeds the limit {:.0} MB",
                self.bytes / 1e6,
                budget.max_bytes / 1e6
            ));
        }
        let hint = match obj {
            ObjectSpec::String(_) => format!("use fewer masses (object[{obj_idx}].masses)"),
            _ => "use fewer modes, drop high or quiet modes with [approximate] nyquist_fraction, max_freq_hz or quiet_below_db, or give modes that need not be struck a zero weight at the contact point (they stay out of the eigenproblem)".to_string(),
        };
        Err(format!(
            "compile budget exceeded for object[{obj_idx}] {:?} ({what}): {}; not attempted. To get under it, {hint}; or raise CompileOptions::budget",
            obj.name(),
            over.join(" and ")
        ))
    }
}
