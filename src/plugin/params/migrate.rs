//! Saved states made safe to load: missing or refused values get their
//! defaults before nice-plug applies the state.

use super::from_spec::FromSpec;
use super::metadata::Kind;
use super::{ids, PARAMS};
use nice_plug::plugin::{ParamValue, PluginState};
use nice_plug::prelude::*;

/// Make a state safe to load, before nice-plug applies it
/// ([`Plugin::filter_state`]): every parameter of [`PARAMS`] that the state
/// lacks (a project saved by an older version) gets its default, and every
/// value that is of the wrong type, not finite, outside its range, or an
/// unknown choice id (a preset this version does not have) is replaced by
/// the default too (without this, a missing or refused value would silently
/// keep whatever the instance had before the load). One exception: a state
/// that stores Damper but not Custom damper (saved before Custom damper
/// existed) gets Custom damper on, so its Damper keeps applying. Entries for
/// ids this version does not know are left alone (nice-plug skips them).
/// Returns one note per replaced value, for the log. \[main-thread\]
pub fn migrate_state(state: &mut PluginState) -> Vec<String> {
    let mut notes = Vec::new();
    // A state that stores the Damper but not Custom damper was saved when
    // the Damper always applied: it keeps applying (the project sounds as
    // it did), where a new instance plays the scene's own damper.
    if state.params.contains_key(ids::DAMPER) && !state.params.contains_key(ids::DAMPER_CUSTOM) {
        notes.push(format!(
            "{}: missing in a state that stores {}, using on (the saved Damper applies, as \
             when it was saved)",
            ids::DAMPER_CUSTOM,
            ids::DAMPER
        ));
        state
            .params
            .insert(ids::DAMPER_CUSTOM.to_string(), ParamValue::Bool(true));
    }
    for spec in PARAMS {
        let stored = state.params.get(spec.id);
        let ok = match (spec.kind, stored) {
            (Kind::Float { .. }, Some(ParamValue::F32(v))) => {
                float_in_range(&FloatParam::from_spec(spec), *v)
            }
            (Kind::Int { min, max, .. }, Some(ParamValue::I32(v))) => (min..=max).contains(v),
            (Kind::Bool { .. }, Some(ParamValue::Bool(_))) => true,
            (Kind::Choice { ids, .. }, Some(ParamValue::String(s))) => ids.contains(&s.as_str()),
            // nice-plug stores an index for enums without ids; accept one
            // that names a choice.
            (Kind::Choice { ids, .. }, Some(ParamValue::I32(i))) => {
                usize::try_from(*i).is_ok_and(|i| i < ids.len())
            }
            _ => false,
        };
        if !ok {
            let what = match stored {
                None => "missing".to_string(),
                Some(v) => format!("invalid value {v:?}"),
            };
            let default = spec.default_value();
            notes.push(format!(
                "{}: {what}, using the default {default:?}",
                spec.id
            ));
            state.params.insert(spec.id.to_string(), default);
        }
    }
    notes
}

/// Finite and inside the parameter's range (a round trip through the
/// normalised value changes nothing but rounding).
fn float_in_range(p: &FloatParam, v: f32) -> bool {
    if !v.is_finite() {
        return false;
    }
    let back = p.preview_plain(p.preview_normalized(v));
    (back - v).abs() <= 1e-4 * v.abs().max(1.0)
}
