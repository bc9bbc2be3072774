//! Why a model or a decomposition could not be built: typed, so callers
//! decide by variant (never by reading a message), and each variant prints
//! what was measured.

use std::fmt;

/// A failure of the rank-one secular route (`physics::secular`). Each one
/// sends the compiler to the general eigensolver (within the budget).
#[derive(Debug, Clone, PartialEq)]
pub enum SecularError {
    /// Mode data of different lengths.
    MismatchedData,
    /// Contact stiffness, damping or hammer mass out of range.
    ContactOutOfRange,
    /// A mode with a non-positive or non-finite frequency or decay.
    ModeOutOfRange(usize),
    /// A mode with zero weight at the contact point (it belongs outside).
    ModeNotCoupled(usize),
    /// Two modes with the same pole: a combination of them does not couple,
    /// and its eigenvector is not of the closed form.
    SharedPole,
    /// The root iteration produced a non-finite step.
    IterationBrokeDown {
        /// Sweep at which it happened.
        sweep: usize,
    },
    /// Roots that did not converge.
    NotConverged {
        /// How many did not.
        count: usize,
        /// Of how many.
        of: usize,
        /// Sweeps run before giving up.
        sweeps: usize,
    },
    /// Roots not in conjugate pairs.
    NotConjugate {
        /// Roots in the upper half plane.
        upper: usize,
        /// Roots in the lower half plane.
        lower: usize,
        /// Real roots.
        real: usize,
    },
    /// An eigenvalue with `v^T J v = 0` (defective).
    Defective,
    /// A near-critical pair whose mean and divided difference are dependent.
    NoIndependentBasis,
    /// A near-critical pair whose left basis is singular.
    SingularLeftBasis,
    /// Non-finite eigenvectors or inverse.
    NotFinite(&'static str),
    /// The eigenvector matrix could not be inverted.
    Singular,
}

impl fmt::Display for SecularError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "secular route: ")?;
        match self {
            Self::MismatchedData => write!(f, "mismatched mode data"),
            Self::ContactOutOfRange => write!(f, "contact parameters out of range"),
            Self::ModeOutOfRange(i) => write!(f, "mode {i} out of range"),
            Self::ModeNotCoupled(i) => write!(f, "mode {i} is not coupled"),
            Self::SharedPole => write!(f, "two modes share a pole (degenerate pair)"),
            Self::IterationBrokeDown { sweep } => {
                write!(f, "the iteration broke down (sweep {sweep})")
            }
            Self::NotConverged { count, of, sweeps } => write!(
                f,
                "{count} of {of} roots did not converge in {sweeps} sweeps"
            ),
            Self::NotConjugate { upper, lower, real } => write!(
                f,
                "roots are not in conjugate pairs ({upper} upper, {lower} lower, {real} real)"
            ),
            Self::Defective => write!(f, "a defective eigenvalue (v^T J v = 0)"),
            Self::NoIndependentBasis => write!(f, "a near-critical pair has no independent basis"),
            Self::SingularLeftBasis => write!(f, "a near-critical pair has a singular left basis"),
            Self::NotFinite(what) => write!(f, "{what} are not finite"),
            Self::Singular => write!(f, "eigenvector matrix is singular"),
        }
    }
}

impl std::error::Error for SecularError {}

/// What a decomposition check measured against its limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Check {
    /// `|A V - V G| / (|A| |V|)`.
    Residual,
    /// The condition number of `V` (near-defective when large).
    Kappa,
    /// `|V^-1 V - I|`, per unit of kappa.
    Inverse,
    /// `V exp(G h) V^-1` against the dense Pade `exp(A h)`.
    Propagator,
}

/// Why a phase generator could not be decomposed (or exponentiated).
#[derive(Debug, Clone, PartialEq)]
pub enum DecompError {
    /// The generator has non-finite entries.
    NonFinite,
    /// `exp(A h)` is not finite.
    ExpNotFinite,
    /// A block decomposition of the wrong shape.
    WrongShape,
    /// Eigenvectors not finite (a defective generator).
    EigenvectorsNotFinite,
    /// The eigenvector matrix is singular (a defective generator).
    EigenvectorsSingular,
    /// The SVD of the eigenvector matrix failed.
    SvdFailed,
    /// faer's eigensolver did not converge (its message).
    NoConvergence(String),
    /// A complex eigenvalue without its conjugate.
    UnpairedComplex,
    /// An odd number of real eigenvalues.
    OddReal,
    /// A decomposition that failed one of its checks.
    Failed {
        /// Which check.
        check: Check,
        /// The measured value.
        value: f64,
        /// Its limit.
        limit: f64,
    },
    /// The rank-one secular route failed.
    Secular(SecularError),
    /// A structured route was refused and the general eigensolver is over
    /// the compile budget, so it was not attempted.
    GeneralOverBudget {
        /// Why the structured route was refused.
        refused: Box<DecompError>,
    },
}

impl fmt::Display for DecompError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite => write!(f, "phase generator has non-finite entries"),
            Self::ExpNotFinite => write!(f, "exp(A h) is not finite"),
            Self::WrongShape => write!(f, "block decomposition has the wrong shape"),
            Self::EigenvectorsNotFinite => {
                write!(f, "eigenvectors are not finite (defective generator)")
            }
            Self::EigenvectorsSingular => {
                write!(f, "eigenvector matrix is singular (defective generator)")
            }
            Self::SvdFailed => write!(f, "eigenvector matrix: SVD failed"),
            Self::NoConvergence(m) => write!(f, "eigensolver did not converge: {m}"),
            Self::UnpairedComplex => write!(f, "unpaired complex eigenvalue"),
            Self::OddReal => write!(f, "odd number of real eigenvalues"),
            Self::Failed {
                check,
                value,
                limit,
            } => match check {
                Check::Residual => write!(f, "eigen residual {value:.1e} > {limit:.0e}"),
                Check::Kappa => write!(f, "kappa(V) {value:.1e} > {limit:.0e} (near-defective)"),
                Check::Inverse => write!(
                    f,
                    "|V^-1 V - I| = {value:.1e} > {limit:.1e} (the inverse is not accurate)"
                ),
                Check::Propagator => write!(
                    f,
                    "V exp(G h) V^-1 differs from exp(A h) by {value:.1e} > {limit:.1e}"
                ),
            },
            Self::Secular(e) => write!(f, "{e}"),
            Self::GeneralOverBudget { refused } => write!(
                f,
                "{refused}, and the general eigensolver is over the compile budget"
            ),
        }
    }
}

impl std::error::Error for DecompError {}

impl From<SecularError> for DecompError {
    fn from(e: SecularError) -> Self {
        Self::Secular(e)
    }
}

/// Why an object's model could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelError {
    /// A lumped object's stiffness matrix is not positive definite.
    StiffnessNotPositiveDefinite,
    /// A physically described object reached the model without being
    /// turned into its modes first (`Scene::expanded`).
    NotExpanded,
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::StiffnessNotPositiveDefinite => {
                write!(f, "stiffness matrix is not positive definite")
            }
            Self::NotExpanded => write!(
                f,
                "the object is described by geometry and material or as a free chain; expand the scene to its modes first"
            ),
        }
    }
}

impl std::error::Error for ModelError {}
