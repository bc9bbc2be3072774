//! The plugin's parameters. Ids are stable strings (saved projects and
//! automation refer to them); never rename one. Every parameter is
//! automatable and saved with the host's project by nice-plug.

use crate::instrument::{InstrumentParams, PlayParams, SceneParams};
use crate::scene::Switching;
use nice_plug::plugin::{ParamValue, PluginState};
use nice_plug::prelude::*;

/// The embedded presets, in the order of [`crate::presets::PRESETS`] (a test
/// checks that the ids match the file names).
#[derive(Enum, Debug, PartialEq, Eq, Clone, Copy)]
pub enum PresetChoice {
    /// presets/bell.toml
    #[id = "bell"]
    #[name = "Bell"]
    Bell,
    /// presets/glockenspiel-bar.toml
    #[id = "glockenspiel-bar"]
    #[name = "Glockenspiel bar"]
    GlockenspielBar,
    /// presets/marimba-bar.toml
    #[id = "marimba-bar"]
    #[name = "Marimba bar"]
    MarimbaBar,
    /// presets/paper-bounce.toml
    #[id = "paper-bounce"]
    #[name = "Paper bounce"]
    PaperBounce,
    /// presets/paper-string.toml
    #[id = "paper-string"]
    #[name = "Paper string"]
    PaperString,
    /// presets/steel-plate.toml
    #[id = "steel-plate"]
    #[name = "Steel plate"]
    SteelPlate,
    /// presets/wood-block.toml
    #[id = "wood-block"]
    #[name = "Wood block"]
    WoodBlock,
}

/// Switching method choice.
#[derive(Enum, Debug, PartialEq, Eq, Clone, Copy)]
pub enum SwitchingChoice {
    /// The paper's offset rod (first order in the contact onset).
    #[id = "offset-rod"]
    #[name = "Offset rod"]
    OffsetRod,
    /// Switch instants located inside the sample (falls back to the offset
    /// rod, with a log line, while the compiler refuses it).
    #[id = "exact"]
    #[name = "Exact"]
    Exact,
}

/// Parameter ids (stable).
pub mod ids {
    /// Scene (preset).
    pub const SCENE: &str = "scene";
    /// Hammer mass factor.
    pub const HAMMER_MASS: &str = "hammer_mass";
    /// Contact stiffness factor.
    pub const HARDNESS: &str = "hardness";
    /// Contact damping factor.
    pub const CONTACT_DAMPING: &str = "contact_damping";
    /// Use the strike position parameter.
    pub const STRIKE_CUSTOM: &str = "strike_custom";
    /// Strike position 0..1.
    pub const STRIKE_POS: &str = "strike_pos";
    /// Decay scale.
    pub const DECAY: &str = "decay";
    /// Damper amount.
    pub const DAMPER: &str = "damper";
    /// Pitch tracking.
    pub const PITCH_TRACKING: &str = "pitch_tracking";
    /// Gravity (bouncing scenes).
    pub const GRAVITY: &str = "gravity";
    /// Drop height (bouncing scenes).
    pub const DROP_HEIGHT: &str = "drop_height";
    /// Output gain.
    pub const GAIN: &str = "gain";
    /// Switching method.
    pub const SWITCHING: &str = "switching";
    /// Every id, in the order of the parameter struct.
    pub const ALL: [&str; 13] = [
        SCENE,
        HAMMER_MASS,
        HARDNESS,
        CONTACT_DAMPING,
        STRIKE_CUSTOM,
        STRIKE_POS,
        DECAY,
        DAMPER,
        PITCH_TRACKING,
        GRAVITY,
        DROP_HEIGHT,
        GAIN,
        SWITCHING,
    ];
}

/// Every parameter (see docs/plugin.md for ranges and meaning).
#[derive(Params)]
pub struct ModalContactParams {
    /// Which embedded scene is struck.
    #[id = "scene"]
    pub scene: EnumParam<PresetChoice>,
    /// Hammer mass multiplier, 0.1..10 x.
    #[id = "hammer_mass"]
    pub hammer_mass: FloatParam,
    /// Contact stiffness multiplier (hardness), 0.01..100 x.
    #[id = "hardness"]
    pub hardness: FloatParam,
    /// Contact damping multiplier, 0..10 x.
    #[id = "contact_damping"]
    pub contact_damping: FloatParam,
    /// Off: strike where the scene says; on: use "Strike position".
    #[id = "strike_custom"]
    pub strike_custom: BoolParam,
    /// Strike position along the object, 0..1.
    #[id = "strike_pos"]
    pub strike_pos: FloatParam,
    /// Decay time multiplier, 0.1..10 x.
    #[id = "decay"]
    pub decay: FloatParam,
    /// Damper after note-off, 0..1 (released T60 / (1 + 50 damper)).
    #[id = "damper"]
    pub damper: FloatParam,
    /// Notes change the pitch.
    #[id = "pitch_tracking"]
    pub pitch_tracking: BoolParam,
    /// Gravity for bouncing scenes, 0.5..30 m/s^2.
    #[id = "gravity"]
    pub gravity: FloatParam,
    /// Drop height for bouncing scenes, 1..100 mm.
    #[id = "drop_height"]
    pub drop_height_mm: FloatParam,
    /// Output gain, -60..+12 dB.
    #[id = "gain"]
    pub gain_db: FloatParam,
    /// Switching method.
    #[id = "switching"]
    pub switching: EnumParam<SwitchingChoice>,
}

fn factor_range(min: f32, max: f32) -> FloatRange {
    // Skewed so that 1 x sits near the middle of the knob.
    FloatRange::Skewed {
        min,
        max,
        factor: FloatRange::skew_factor(-2.0),
    }
}

impl Default for ModalContactParams {
    fn default() -> Self {
        let d = InstrumentParams::default();
        Self {
            scene: EnumParam::new("Scene", PresetChoice::MarimbaBar),
            hammer_mass: FloatParam::new("Hammer mass", 1.0, factor_range(0.1, 10.0))
                .with_unit(" x")
                .with_value_to_string(formatters::v2s_f32_rounded(3)),
            hardness: FloatParam::new("Hardness", 1.0, factor_range(0.01, 100.0))
                .with_unit(" x")
                .with_value_to_string(formatters::v2s_f32_rounded(3)),
            contact_damping: FloatParam::new("Contact damping", 1.0, factor_range(0.0, 10.0))
                .with_unit(" x")
                .with_value_to_string(formatters::v2s_f32_rounded(3)),
            strike_custom: BoolParam::new("Custom strike position", false),
            strike_pos: FloatParam::new(
                "Strike position",
                0.5,
                FloatRange::Linear { min: 0.0, max: 1.0 },
            )
            .with_value_to_string(formatters::v2s_f32_rounded(3)),
            decay: FloatParam::new("Decay", 1.0, factor_range(0.1, 10.0))
                .with_unit(" x")
                .with_value_to_string(formatters::v2s_f32_rounded(3)),
            damper: FloatParam::new(
                "Damper",
                d.scene.damper_norm as f32,
                FloatRange::Linear { min: 0.0, max: 1.0 },
            )
            .with_value_to_string(formatters::v2s_f32_rounded(3)),
            pitch_tracking: BoolParam::new("Pitch tracking", d.play.pitch_tracking),
            gravity: FloatParam::new(
                "Gravity",
                d.scene.gravity_m_per_s2 as f32,
                FloatRange::Linear {
                    min: 0.5,
                    max: 30.0,
                },
            )
            .with_unit(" m/s2")
            .with_value_to_string(formatters::v2s_f32_rounded(2)),
            drop_height_mm: FloatParam::new(
                "Drop height",
                (d.play.drop_height_m * 1000.0) as f32,
                FloatRange::Skewed {
                    min: 1.0,
                    max: 100.0,
                    factor: FloatRange::skew_factor(-1.0),
                },
            )
            .with_unit(" mm")
            .with_value_to_string(formatters::v2s_f32_rounded(1)),
            gain_db: FloatParam::new(
                "Output gain",
                d.play.gain_db as f32,
                FloatRange::Linear {
                    min: -60.0,
                    max: 12.0,
                },
            )
            .with_unit(" dB")
            .with_value_to_string(formatters::v2s_f32_rounded(1)),
            switching: EnumParam::new("Switching", SwitchingChoice::Exact),
        }
    }
}

impl ModalContactParams {
    /// Snapshot of the parameters that need a compile (atomic loads only).
    /// \[any-thread\]
    pub fn scene_params(&self) -> SceneParams {
        SceneParams {
            preset: self.scene.value().to_index(),
            hammer_mass_factor: self.hammer_mass.value() as f64,
            stiffness_factor: self.hardness.value() as f64,
            damping_factor: self.contact_damping.value() as f64,
            strike_pos_norm: self
                .strike_custom
                .value()
                .then(|| self.strike_pos.value() as f64),
            decay_scale: self.decay.value() as f64,
            damper_norm: self.damper.value() as f64,
            gravity_m_per_s2: self.gravity.value() as f64,
            switching: match self.switching.value() {
                SwitchingChoice::OffsetRod => Switching::OffsetRod,
                SwitchingChoice::Exact => Switching::Exact,
            },
        }
    }

    /// Snapshot of the parameters read without a compile. \[any-thread\]
    pub fn play_params(&self) -> PlayParams {
        PlayParams {
            pitch_tracking: self.pitch_tracking.value(),
            drop_height_m: self.drop_height_mm.value() as f64 / 1000.0,
            gain_db: self.gain_db.value() as f64,
        }
    }

    /// Both snapshots. \[any-thread\]
    pub fn instrument_params(&self) -> InstrumentParams {
        InstrumentParams {
            scene: self.scene_params(),
            play: self.play_params(),
        }
    }
}

/// Make a state safe to load, before nice-plug applies it
/// ([`Plugin::filter_state`]): every parameter of this version that the
/// state lacks (a project saved by an older version) gets its default, and
/// every value that is of the wrong type, not finite, outside its range, or
/// an unknown enum id is replaced by the default too (without this, a
/// missing or refused value would silently keep whatever the instance had
/// before the load). Entries for ids this version does not know are left
/// alone (nice-plug skips them). Returns one note per replaced value, for
/// the log. \[main-thread\]
pub fn migrate_state(state: &mut PluginState) -> Vec<String> {
    let d = ModalContactParams::default();
    let mut notes = Vec::new();
    let mut fix = |state: &mut PluginState, id: &str, ok: bool, default: ParamValue| {
        if !ok {
            let what = match state.params.get(id) {
                None => "missing".to_string(),
                Some(v) => format!("invalid value {v:?}"),
            };
            notes.push(format!("{id}: {what}, using the default {default:?}"));
            state.params.insert(id.to_string(), default);
        }
    };
    let floats: [(&str, &FloatParam); 9] = [
        (ids::HAMMER_MASS, &d.hammer_mass),
        (ids::HARDNESS, &d.hardness),
        (ids::CONTACT_DAMPING, &d.contact_damping),
        (ids::STRIKE_POS, &d.strike_pos),
        (ids::DECAY, &d.decay),
        (ids::DAMPER, &d.damper),
        (ids::GRAVITY, &d.gravity),
        (ids::DROP_HEIGHT, &d.drop_height_mm),
        (ids::GAIN, &d.gain_db),
    ];
    for (id, p) in floats {
        let ok = match state.params.get(id) {
            Some(ParamValue::F32(v)) => float_in_range(p, *v),
            _ => false,
        };
        fix(state, id, ok, ParamValue::F32(p.default_plain_value()));
    }
    for (id, p) in [
        (ids::STRIKE_CUSTOM, &d.strike_custom),
        (ids::PITCH_TRACKING, &d.pitch_tracking),
    ] {
        let ok = matches!(state.params.get(id), Some(ParamValue::Bool(_)));
        fix(state, id, ok, ParamValue::Bool(p.default_plain_value()));
    }
    let (ok, default) = enum_ok(state.params.get(ids::SCENE), &d.scene);
    fix(state, ids::SCENE, ok, default);
    let (ok, default) = enum_ok(state.params.get(ids::SWITCHING), &d.switching);
    fix(state, ids::SWITCHING, ok, default);
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

/// Whether a stored enum value names a variant, and the default as stored.
fn enum_ok<T: Enum + PartialEq>(v: Option<&ParamValue>, p: &EnumParam<T>) -> (bool, ParamValue) {
    let ids = T::ids();
    let n = T::variants().len();
    let default = p.default_plain_value();
    let stored = match ids {
        Some(ids) => ParamValue::String(ids[default.to_index()].to_string()),
        None => ParamValue::I32(default.to_index() as i32),
    };
    let ok = match (v, ids) {
        (Some(ParamValue::String(s)), Some(ids)) => ids.contains(&s.as_str()),
        (Some(ParamValue::I32(i)), _) => *i >= 0 && (*i as usize) < n,
        _ => false,
    };
    (ok, stored)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// `ParamValue` has no `PartialEq`: compare the debug forms.
    macro_rules! same {
        ($a:expr, $b:expr $(, $m:expr)?) => {
            assert_eq!(format!("{:?}", $a), format!("{:?}", $b) $(, $m)?)
        };
    }

    fn full_state() -> PluginState {
        let mut state = PluginState {
            version: "0.0.1".into(),
            params: BTreeMap::new(),
            fields: BTreeMap::new(),
        };
        assert_eq!(migrate_state(&mut state).len(), 13, "all 13 filled in");
        state
    }

    #[test]
    fn an_empty_older_state_gets_every_default() {
        let state = full_state();
        let d = ModalContactParams::default();
        same!(
            state.params[ids::HARDNESS],
            ParamValue::F32(d.hardness.default_plain_value())
        );
        same!(
            state.params[ids::SCENE],
            ParamValue::String("marimba-bar".into())
        );
        same!(
            state.params[ids::SWITCHING],
            ParamValue::String("exact".into())
        );
        same!(state.params[ids::PITCH_TRACKING], ParamValue::Bool(true));
        // a filled-in state is left as it is
        let mut again = state.clone();
        assert!(migrate_state(&mut again).is_empty());
        same!(again.params, state.params);
    }

    #[test]
    fn bad_values_are_replaced_and_good_ones_kept() {
        let mut state = full_state();
        let p = &mut state.params;
        p.insert(ids::HARDNESS.into(), ParamValue::F32(f32::NAN));
        p.insert(ids::DECAY.into(), ParamValue::F32(1e30));
        p.insert(ids::GAIN.into(), ParamValue::F32(-3.0));
        p.insert(ids::DAMPER.into(), ParamValue::Bool(true));
        p.insert(
            ids::SCENE.into(),
            ParamValue::String("no-such-preset".into()),
        );
        p.insert(ids::SWITCHING.into(), ParamValue::I32(0));
        p.insert(ids::STRIKE_CUSTOM.into(), ParamValue::F32(1.0));
        p.insert("from_the_future".into(), ParamValue::F32(3.0));
        let notes = migrate_state(&mut state);
        println!("{notes:#?}");
        assert_eq!(notes.len(), 5, "{notes:?}");
        let d = ModalContactParams::default();
        let p = &state.params;
        same!(
            p[ids::HARDNESS],
            ParamValue::F32(d.hardness.default_plain_value())
        );
        same!(p[ids::DECAY], ParamValue::F32(1.0));
        same!(p[ids::GAIN], ParamValue::F32(-3.0), "in range: kept");
        same!(p[ids::SWITCHING], ParamValue::I32(0), "a valid index: kept");
        same!(p[ids::SCENE], ParamValue::String("marimba-bar".into()));
        same!(p[ids::STRIKE_CUSTOM], ParamValue::Bool(false));
        same!(p["from_the_future"], ParamValue::F32(3.0));
    }

    #[test]
    fn preset_choice_ids_match_the_embedded_presets() {
        let ids = PresetChoice::ids().expect("ids are set");
        let names: Vec<&str> = crate::presets::PRESETS.iter().map(|p| p.name).collect();
        assert_eq!(ids, &names[..]);
    }

    #[test]
    fn defaults_are_the_instrument_defaults() {
        let p = ModalContactParams::default();
        let d = InstrumentParams::default();
        let got = p.instrument_params();
        assert_eq!(got.scene.preset, d.scene.preset);
        assert_eq!(got.scene.strike_pos_norm, None);
        assert_eq!(got.scene.switching, d.scene.switching);
        assert!((got.scene.hammer_mass_factor - 1.0).abs() < 1e-6);
        assert!((got.play.gain_db - d.play.gain_db).abs() < 1e-6);
        assert!((got.play.drop_height_m - d.play.drop_height_m).abs() < 1e-6);
    }
}
