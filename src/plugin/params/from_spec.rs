//! The typed nice-plug parameters, each built from its entry of
//! [`PARAMS`](super::PARAMS), and the parameters a host may modulate per
//! voice.

use super::choices::{Choice, ChoiceList};
use super::metadata::{Kind, ParamSpec, Taper};
use super::{ids, POLY_DAMPER, POLY_HARDNESS, POLY_POSITION};
use nice_plug::prelude::*;

/// Builds a nice-plug parameter from its entry of [`PARAMS`](super::PARAMS).
pub(super) trait FromSpec {
    fn from_spec(s: &ParamSpec) -> Self;
}

impl FromSpec for FloatParam {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Float {
            min,
            max,
            default,
            taper,
            unit,
            digits,
        } = s.kind
        else {
            panic!(
                "{}: declared {:?}, but its field is a FloatParam",
                s.id, s.kind
            );
        };
        let range = match taper {
            Taper::Linear => FloatRange::Linear { min, max },
            Taper::Skewed { exponent } => FloatRange::Skewed {
                min,
                max,
                factor: FloatRange::skew_factor(exponent),
            },
        };
        let p = FloatParam::new(s.name, default, range)
            .with_unit(unit)
            .with_value_to_string(formatters::v2s_f32_rounded(digits));
        match poly_modulation_id(s.id) {
            Some(id) => p.with_poly_modulation_id(id),
            None => p,
        }
    }
}

/// The parameters a CLAP host may modulate per voice, with their
/// polyphonic modulation ids.
pub const POLY_MODULATED: &[(&str, u32)] = &[
    (ids::HARDNESS, POLY_HARDNESS),
    (ids::STRIKE_POS, POLY_POSITION),
    (ids::DAMPER, POLY_DAMPER),
];

/// The polyphonic modulation id of parameter `id`, if it has one.
pub fn poly_modulation_id(id: &str) -> Option<u32> {
    POLY_MODULATED
        .iter()
        .find(|(p, _)| *p == id)
        .map(|&(_, poly)| poly)
}

impl FromSpec for IntParam {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Int {
            min,
            max,
            default,
            unit,
        } = s.kind
        else {
            panic!(
                "{}: declared {:?}, but its field is an IntParam",
                s.id, s.kind
            );
        };
        IntParam::new(s.name, default, IntRange::Linear { min, max }).with_unit(unit)
    }
}

impl FromSpec for BoolParam {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Bool { default } = s.kind else {
            panic!(
                "{}: declared {:?}, but its field is a BoolParam",
                s.id, s.kind
            );
        };
        BoolParam::new(s.name, default)
    }
}

impl<L: ChoiceList> FromSpec for EnumParam<Choice<L>> {
    fn from_spec(s: &ParamSpec) -> Self {
        let Kind::Choice { ids, default, .. } = s.kind else {
            panic!(
                "{}: declared {:?}, but its field is an EnumParam",
                s.id, s.kind
            );
        };
        assert!(
            ids == L::IDS,
            "{}: the entry's choices are not its field's",
            s.id
        );
        EnumParam::new(s.name, Choice::from_index(default))
    }
}
