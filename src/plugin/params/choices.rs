//! Enumerated parameters: a [`Choice`] of a [`ChoiceList`] whose ids and
//! names are the list's own, so no Rust enum repeats them.

use super::metadata::Kind;
use crate::presets;
use crate::scene::Switching;
use nice_plug::prelude::Enum;
use std::marker::PhantomData;

/// A list of named choices for an enumerated parameter.
pub trait ChoiceList: 'static {
    /// Stable ids, saved in projects (never change one).
    const IDS: &'static [&'static str];
    /// Names hosts show, in the order of `IDS`.
    const NAMES: &'static [&'static str];
}

/// One choice of the list `L`. nice-plug's [`Enum`] is implemented from the
/// list's ids and names, so an enumerated parameter needs no Rust enum that
/// would repeat them.
pub struct Choice<L> {
    index: usize,
    list: PhantomData<L>,
}

// Written out: derives would demand the same traits of the marker type `L`.
impl<L> Clone for Choice<L> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<L> Copy for Choice<L> {}
impl<L> PartialEq for Choice<L> {
    fn eq(&self, other: &Self) -> bool {
        self.index == other.index
    }
}
impl<L> Eq for Choice<L> {}
impl<L: ChoiceList> std::fmt::Debug for Choice<L> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Choice({:?})", self.id())
    }
}

impl<L: ChoiceList> Choice<L> {
    /// Position in the list.
    pub fn index(self) -> usize {
        self.index
    }
    /// Stable id.
    pub fn id(self) -> &'static str {
        L::IDS[self.index]
    }
}

impl<L: ChoiceList> Enum for Choice<L> {
    fn variants() -> &'static [&'static str] {
        L::NAMES
    }
    fn ids() -> Option<&'static [&'static str]> {
        Some(L::IDS)
    }
    fn to_index(self) -> usize {
        self.index
    }
    /// Out of range gives the first choice, as the trait asks.
    fn from_index(index: usize) -> Self {
        Self {
            index: if index < L::IDS.len() { index } else { 0 },
            list: PhantomData,
        }
    }
}

/// The embedded presets ([`crate::presets::PRESETS`], in its order).
pub struct Scenes;
impl ChoiceList for Scenes {
    const IDS: &'static [&'static str] = &presets::NAMES;
    const NAMES: &'static [&'static str] = &presets::TITLES;
}

/// The switching methods; the ids are the scene files' spellings.
pub struct SwitchingMethods;
impl ChoiceList for SwitchingMethods {
    const IDS: &'static [&'static str] = &["offset-rod", "exact"];
    const NAMES: &'static [&'static str] = &["Offset rod", "Exact"];
}
/// The method of each [`SwitchingMethods`] choice.
pub(super) const SWITCHING_METHOD: [Switching; 2] = [Switching::OffsetRod, Switching::Exact];

/// The "Scene" parameter's value.
pub type PresetChoice = Choice<Scenes>;
/// The "Switching" parameter's value.
pub type SwitchingChoice = Choice<SwitchingMethods>;

/// The choices of `L`, defaulting to the one with id `default` (a missing id
/// stops the build: this runs at compile time).
pub(super) const fn choice<L: ChoiceList>(default: &str) -> Kind {
    let mut i = 0;
    while i < L::IDS.len() {
        if str_eq(L::IDS[i], default) {
            return Kind::Choice {
                ids: L::IDS,
                names: L::NAMES,
                default: i,
            };
        }
        i += 1;
    }
    panic!("the default is not one of the choices");
}

const fn str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}
