//! What each parameter is, as data: its entry of [`PARAMS`] (id, name,
//! kind with range and default, when a change is heard, what it does).

use super::PARAMS;
use nice_plug::plugin::ParamValue;

/// One parameter's metadata: an entry of [`PARAMS`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Stable id (what saved projects and automation refer to).
    pub id: &'static str,
    /// Name hosts show.
    pub name: &'static str,
    /// Value type, range, default and unit.
    pub kind: Kind,
    /// When a change is heard.
    pub applies: Applies,
    /// What the parameter does (Markdown, for docs/plugin.md).
    pub doc: &'static str,
}

/// A parameter's value type, with its range, default and display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A continuous value.
    Float {
        /// Smallest value.
        min: f32,
        /// Largest value.
        max: f32,
        /// Default value.
        default: f32,
        /// How the host's knob maps onto the range.
        taper: Taper,
        /// Unit appended to the value, with its leading space (`" dB"`), or `""`.
        unit: &'static str,
        /// Decimal places hosts show.
        digits: usize,
    },
    /// A whole number (hosts show and step it as one).
    Int {
        /// Smallest value.
        min: i32,
        /// Largest value.
        max: i32,
        /// Default value.
        default: i32,
        /// Unit appended to the value, with its leading space, or `""`.
        unit: &'static str,
    },
    /// Off or on.
    Bool {
        /// Default value.
        default: bool,
    },
    /// One of a list of named choices.
    Choice {
        /// Stable ids, saved in projects.
        ids: &'static [&'static str],
        /// Names hosts show, in the order of `ids`.
        names: &'static [&'static str],
        /// Index of the default choice.
        default: usize,
    },
}

/// How a float parameter's normalised (knob) position maps to its value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Taper {
    /// Evenly spread.
    Linear,
    /// nice-plug's `FloatRange::Skewed` with `factor = skew_factor(exponent)`:
    /// a negative exponent gives the low end more of the knob.
    Skewed {
        /// Power-of-two exponent of the skew factor.
        exponent: f32,
    },
}

/// When a parameter change is heard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applies {
    /// It changes the matrices: the worker recompiles the scene off the
    /// audio thread and the result is swapped in (docs/plugin.md,
    /// "Parameter changes: the swap design"). Part of
    /// [`SceneParams`](crate::instrument::SceneParams).
    Recompile,
    /// Read when a note starts. Part of [`PlayParams`](crate::instrument::PlayParams).
    NextNote,
    /// Read at every block. Part of [`PlayParams`](crate::instrument::PlayParams).
    NextBlock,
}

impl ParamSpec {
    /// The default as nice-plug stores it in a saved state.
    pub fn default_value(&self) -> ParamValue {
        match self.kind {
            Kind::Float { default, .. } => ParamValue::F32(default),
            Kind::Int { default, .. } => ParamValue::I32(default),
            Kind::Bool { default } => ParamValue::Bool(default),
            Kind::Choice { ids, default, .. } => ParamValue::String(ids[default].to_string()),
        }
    }
}

/// The metadata of the parameter `id`.
pub fn spec(id: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|s| s.id == id)
}

/// A multiplier of a scene quantity, skewed so that 1 x sits near the middle
/// of the knob.
pub(super) const fn factor(min: f32, max: f32, digits: usize) -> Kind {
    Kind::Float {
        min,
        max,
        default: 1.0,
        taper: Taper::Skewed { exponent: -2.0 },
        unit: " x",
        digits,
    }
}

/// A linear float parameter.
pub(super) const fn linear(
    min: f32,
    max: f32,
    default: f32,
    unit: &'static str,
    digits: usize,
) -> Kind {
    Kind::Float {
        min,
        max,
        default,
        taper: Taper::Linear,
        unit,
        digits,
    }
}
