//! Why a scene could not be compiled: one variant per cause, each keeping
//! what callers need (the scene's field path, the measured numbers, the
//! object), so the plugin's log and the tools show the reason and what to
//! change, and code decides by variant, never by reading the message.

use crate::physics::{DecompError, ModelError};
use crate::scene::{ObjectSpec, Scene, SceneError};
use std::fmt;

/// Which phase of the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PhaseKind {
    /// The struck object alone (the hammer flies in closed form).
    Free,
    /// Object, contact spring-damper and hammer together.
    Contact,
}

impl PhaseKind {
    /// `"free"` or `"contact"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Free => "free",
            Self::Contact => "contact",
        }
    }
}

/// What the compile budget refused (see [`super::budget`]): the estimate,
/// the limit that was exceeded and how to get under it.
#[derive(Debug, Clone, PartialEq)]
pub struct OverBudget {
    /// Index of the struck object in the scene.
    pub object: usize,
    /// Its name.
    pub name: String,
    /// What would be decomposed (dimensions).
    pub what: String,
    /// `(estimate, limit)` of the work \[flops\], when over.
    pub flops: Option<(f64, f64)>,
    /// `(estimate, limit)` of the memory \[bytes\], when over.
    pub bytes: Option<(f64, f64)>,
    /// How to get under it.
    pub hint: String,
}

impl fmt::Display for OverBudget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut over = Vec::new();
        if let Some((e, l)) = self.flops {
            over.push(format!(
                "estimated work {e:.1e} flops exceeds the limit {l:.1e}"
            ));
        }
        if let Some((e, l)) = self.bytes {
            over.push(format!(
                "estimated memory {:.0} MB exceeds the limit {:.0} MB",
                e / 1e6,
                l / 1e6
            ));
        }
        write!(
            f,
            "compile budget exceeded for object[{}] {:?} ({}): {}; not attempted. To get under it, {}; or raise CompileOptions::budget",
            self.object,
            self.name,
            self.what,
            over.join(" and "),
            self.hint
        )
    }
}

/// Why a scene could not be compiled.
#[derive(Debug, Clone, PartialEq)]
pub enum CompileError {
    /// The scene is invalid (its field path and reason).
    Scene(SceneError),
    /// The sample rate is outside 1 kHz .. 10 MHz.
    SampleRate(f64),
    /// The contact object named by the contact section does not exist.
    MissingObject(String),
    /// The contact point does not exist on the struck object.
    MissingPoint(String),
    /// The contact system is larger than the compiler ever attempts.
    TooLarge {
        /// Its dimension.
        dim: usize,
        /// [`super::MAX_CONTACT_DIM`].
        limit: usize,
        /// The struck object's name.
        object: String,
    },
    /// The estimated work or memory exceeds the compile budget.
    OverBudget(Box<OverBudget>),
    /// The struck object's model could not be built.
    Model {
        /// Index of the object.
        object: usize,
        /// Its name.
        name: String,
        /// Why.
        source: ModelError,
    },
    /// A phase could not be decomposed, or its exponential is not finite.
    Decomposition {
        /// Which phase.
        phase: PhaseKind,
        /// Why.
        source: DecompError,
        /// The sample rate \[Hz\].
        rate_hz: f64,
        /// What to change in the scene.
        hint: String,
    },
    /// The structured (secular) route of the contact phase was refused and
    /// the general eigensolver is over the compile budget: not attempted.
    GeneralOverBudget {
        /// Why the structured route was refused.
        refused: DecompError,
        /// The general eigensolver's estimated work \[flops\] and memory \[bytes\].
        flops: f64,
        /// See `flops`.
        bytes: f64,
    },
    /// A phase's one-sample propagator would create energy in f64.
    NotPassive {
        /// Which phase.
        phase: PhaseKind,
        /// How it was built.
        method: String,
        /// `sigma_max - 1`, and the allowance it exceeds.
        excess: f64,
        /// See `excess`.
        tol: f64,
        /// `|A| h` of the phase.
        norm_h: f64,
        /// The sample rate \[Hz\].
        rate_hz: f64,
        /// What to change in the scene.
        hint: String,
    },
    /// The contact system is singular under gravity (no static equilibrium),
    /// or its equilibrium is not finite.
    NoEquilibrium,
    /// A compiled matrix has non-finite entries.
    NonFinite(&'static str),
    /// The compile was cancelled ([`super::cancel`]: the plugin instance
    /// that asked for it was deactivated or ended).
    Cancelled,
}

impl CompileError {
    /// A short, stable name of the cause (for statistics and tests).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Scene(_) => "scene",
            Self::SampleRate(_) => "sample rate",
            Self::MissingObject(_) => "missing object",
            Self::MissingPoint(_) => "missing point",
            Self::TooLarge { .. } => "too large",
            Self::OverBudget(_) => "over budget",
            Self::Model { .. } => "model",
            Self::Decomposition { .. } => "decomposition",
            Self::GeneralOverBudget { .. } => "general eigensolver over budget",
            Self::NotPassive { .. } => "not passive",
            Self::NoEquilibrium => "no equilibrium",
            Self::NonFinite(_) => "non-finite",
            Self::Cancelled => "cancelled",
        }
    }

    /// The scene field the error is about, when it is about one.
    pub fn field_path(&self) -> Option<&str> {
        match self {
            Self::Scene(e) if !e.path.is_empty() => Some(&e.path),
            _ => None,
        }
    }
}

impl fmt::Display for CompileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "cannot compile scene: ")?;
        match self {
            Self::Scene(e) => write!(f, "{e}"),
            Self::SampleRate(r) => write!(f, "sample rate must be in 1 kHz..10 MHz, got {r}"),
            Self::MissingObject(o) => write!(f, "contact object {o:?} missing"),
            Self::MissingPoint(p) => write!(f, "no point {p}"),
            Self::TooLarge { dim, limit, object } => write!(
                f,
                "contact system of dimension {dim} exceeds the limit {limit} (object {object:?}: use fewer modes or masses); not attempted"
            ),
            Self::OverBudget(b) => write!(f, "{b}"),
            Self::Model {
                object,
                name,
                source,
            } => write!(f, "object[{object}] {name:?}: {source}"),
            Self::GeneralOverBudget {
                refused,
                flops,
                bytes,
            } => write!(
                f,
                "contact phase: {refused}, and the general eigensolver is over the compile budget (estimate {flops:.1e} flops, {:.0} MB); not attempted",
                bytes / 1e6
            ),
            Self::Decomposition {
                phase,
                source,
                rate_hz,
                hint,
            } => write!(
                f,
                "{} phase: {source}. Its generator is too stiff or too damped to be advanced in f64 at {rate_hz} Hz: {hint}",
                phase.as_str()
            ),
            Self::NotPassive {
                phase,
                method,
                excess,
                tol,
                norm_h,
                rate_hz,
                hint,
            } => write!(
                f,
                "{} phase is not passive in f64 at {rate_hz} Hz: its one-sample propagator ({method}) has largest singular value 1 + {excess:.1e} > 1 + {tol:.1e}, so stepping it could create energy. \
                 The phase is too stiff or too damped for this rate (|A| h = {norm_h:.1e}): {hint}",
                phase.as_str()
            ),
            Self::NoEquilibrium => write!(
                f,
                "the contact system has no finite static equilibrium under gravity"
            ),
            Self::NonFinite(what) => write!(f, "{what} has non-finite entries"),
            Self::Cancelled => write!(f, "{}", super::cancel::Cancelled),
        }
    }
}

impl std::error::Error for CompileError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Scene(e) => Some(e),
            Self::Model { source, .. } => Some(source),
            Self::Decomposition { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl From<SceneError> for CompileError {
    fn from(e: SceneError) -> Self {
        Self::Scene(e)
    }
}

/// What to change when a phase of `scene` (struck object `ci`) is too stiff
/// or too damped for f64.
pub(crate) fn stiffness_hint(phase: PhaseKind, scene: &Scene, ci: usize) -> String {
    let obj = match &scene.object[ci] {
        ObjectSpec::String(_) => format!(
            "lower object[{ci}]'s damping (dashpots, rayleigh_alpha_per_s, rayleigh_beta_s) or spring_n_per_m, or raise its mass_kg"
        ),
        ObjectSpec::Modal(_) => format!(
            "lengthen the shortest t60_s of object[{ci}] or lower its weights at the contact point (|w| is 1/sqrt(effective mass))"
        ),
        ObjectSpec::Wall(_) => String::new(),
        obj => format!(
            "lower the loss of object[{ci}] ({}: loss, material.loss_factor) or choose its contact point nearer a node",
            obj.kind()
        ),
    };
    match phase {
        PhaseKind::Free => obj,
        PhaseKind::Contact if obj.is_empty() => {
            "lower contact.stiffness_n_per_m or contact.damping_n_s_per_m, or raise hammer.mass_kg"
                .into()
        }
        PhaseKind::Contact => format!(
            "lower contact.stiffness_n_per_m or contact.damping_n_s_per_m, raise hammer.mass_kg, or {obj}"
        ),
    }
}
