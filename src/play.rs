//! One way in for every scene: [`compile`] takes a scene of one to four
//! contacts and gives a [`Compiled`]; a [`Voice`] plays it in blocks
//! (docs/design.md, "Layers" and "Several contacts").
//!
//! Inside, a scene of one contact runs on the engine's two-phase route
//! ([`crate::engine::EngineState`] over a [`CompiledScene`]), a scene of
//! several on the phases indexed by the set of closed contacts
//! ([`crate::multi::MultiState`] over a [`CompiledMulti`]). Both share the
//! event search and the block kernel; the embedder sees one type of each
//! and one set of errors.

use crate::compile::{compile_with, CompileError, CompiledScene, RATE_RANGE_HZ};
use crate::engine::{EngineState, TimeScaleError};
use crate::multi::{CompiledMulti, MultiModel, MultiState, StrikeRefused};
use crate::scene::{Scene, Switching};

/// A compiled scene of one to four contacts.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)]
pub enum Compiled {
    /// A scene of one contact.
    One(CompiledScene),
    /// A scene of several contacts (`[[striker]]`, `[[touch]]`).
    Several(CompiledMulti),
}

/// Compile any scene the validator accepts (one to four contacts) at
/// `rate_hz`, its switching method as the scene says. Off the audio
/// thread: the eigendecompositions and propagators are made here. A
/// refusal names the scene's field ([`CompileError`]).
pub fn compile(scene: &Scene, rate_hz: f64) -> Result<Compiled, CompileError> {
    Compiled::new(scene, rate_hz, None)
}

impl Compiled {
    /// Compile `scene` at `rate_hz`, with `switching` overriding the
    /// scene's switching method: through [`compile_with`] for one contact,
    /// through [`MultiModel::from_scene`] and [`CompiledMulti`] for
    /// several (their refusals name the scene's field).
    pub fn new(
        scene: &Scene,
        rate_hz: f64,
        switching: Option<Switching>,
    ) -> Result<Self, CompileError> {
        if !scene.several_contacts() {
            return compile_with(scene, rate_hz, switching).map(Self::One);
        }
        if !(rate_hz.is_finite() && (RATE_RANGE_HZ.0..=RATE_RANGE_HZ.1).contains(&rate_hz)) {
            return Err(CompileError::SampleRate(rate_hz));
        }
        let model = MultiModel::from_scene(scene, rate_hz)?;
        let switching = switching.or(scene.contact.switching).unwrap_or_default();
        CompiledMulti::with_switching(&model, rate_hz, switching)
            .map(Self::Several)
            .map_err(|e| CompileError::Scene(e.in_scene(scene)))
    }

    /// Sample rate \[Hz\].
    pub fn rate_hz(&self) -> f64 {
        match self {
            Self::One(c) => c.rate_hz,
            Self::Several(c) => c.rate_hz,
        }
    }

    /// A scene whose contact is driven over a surface (its trace has
    /// the surface's columns, `render::DRIVE_COLUMNS`).
    pub fn driven(&self) -> bool {
        matches!(self, Compiled::One(c) if c.drive.is_some())
    }

    /// Number of contacts.
    pub fn contacts(&self) -> usize {
        match self {
            Self::One(_) => 1,
            Self::Several(c) => c.contacts(),
        }
    }

    /// The switching method it runs with.
    pub fn switching(&self) -> Switching {
        match self {
            Self::One(c) => c.switching,
            Self::Several(c) => c.switching,
        }
    }
}

/// Why a [`Voice`] did not strike: nothing changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StrikeError {
    /// The height is negative or not a number, or the velocity is not
    /// finite.
    NotFinite,
    /// No contact of that index, or its upper side is not a mass (a
    /// `[[touch]]` between two objects).
    NoMallet,
    /// The mass has no place with its contacts open (a ball pressed
    /// between two plates).
    Wedged,
    /// The voice was made for another compiled scene.
    OtherScene,
}

impl std::fmt::Display for StrikeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::NotFinite => "the height must be finite and not negative, the velocity finite",
            Self::NoMallet => "no mass on the upper side of that contact",
            Self::Wedged => "the mass has no place with its contacts open",
            Self::OtherScene => "the voice was made for another compiled scene",
        })
    }
}

impl std::error::Error for StrikeError {}

/// The running state of a [`Compiled`] scene: objects, masses and
/// contacts, advanced exactly sample by sample. Made once per scene
/// (allocates); then every method is allocation-free and never fails on
/// the audio thread. Every call takes the [`Compiled`] the voice was made
/// for (a compile of the other kind, one contact for several or the
/// reverse, changes nothing and plays silence).
#[derive(Debug)]
pub struct Voice {
    kind: Kind,
}

#[derive(Debug)]
enum Kind {
    One(Box<EngineState>),
    Several(Box<MultiState>),
}

impl Voice {
    /// The scene's initial state: objects at rest, masses where the scene
    /// puts them, moving as it says. \[worker\]
    pub fn new(compiled: &Compiled) -> Self {
        let kind = match compiled {
            Compiled::One(c) => Kind::One(Box::new(EngineState::new(c))),
            Compiled::Several(c) => Kind::Several(Box::new(MultiState::new(c))),
        };
        Self { kind }
    }

    /// Throw the mass on the upper side of contact `contact` (0: the
    /// scene's `[contact]`, its `[hammer]`; then each `[[striker]]`'s, in
    /// order) from `height_m` above the point it strikes \[m\], at
    /// `velocity_m_per_s` (positive up: a strike is negative), while the
    /// objects keep their motion. Where it is in contact it is lifted off
    /// first: its spring's energy leaves, none is added. O(N) in flight,
    /// O(N^2) when a contact opens; allocation-free. \[audio-thread\]
    pub fn strike(
        &mut self,
        compiled: &Compiled,
        contact: usize,
        height_m: f64,
        velocity_m_per_s: f64,
    ) -> Result<(), StrikeError> {
        if !(height_m >= 0.0 && height_m.is_finite() && velocity_m_per_s.is_finite()) {
            return Err(StrikeError::NotFinite);
        }
        match (&mut self.kind, compiled) {
            (Kind::One(st), Compiled::One(c)) => {
                if contact != 0 {
                    return Err(StrikeError::NoMallet);
                }
                st.strike(c, height_m, velocity_m_per_s);
                Ok(())
            }
            (Kind::Several(st), Compiled::Several(c)) => st
                .strike(c, contact, height_m, velocity_m_per_s)
                .map_err(|e| match e {
                    StrikeRefused::NotAMass => StrikeError::NoMallet,
                    StrikeRefused::NotFinite => StrikeError::NotFinite,
                    StrikeRefused::Wedged => StrikeError::Wedged,
                }),
            _ => Err(StrikeError::OtherScene),
        }
    }

    /// Advance one block: `left.len()` samples (`right` as long) of the
    /// scene's two outputs. \[audio-thread\]
    pub fn process_block(&mut self, compiled: &Compiled, left: &mut [f64], right: &mut [f64]) {
        match (&mut self.kind, compiled) {
            (Kind::One(st), Compiled::One(c)) => st.process_block(c, left, right),
            (Kind::Several(st), Compiled::Several(c)) => st.process_block(c, left, right),
            _ => {
                left.fill(0.0);
                right.fill(0.0);
            }
        }
    }

    /// Play the scene `scale` times faster, a pitch `scale` times higher
    /// (stiffnesses times `scale^2`, dampings times `scale`, masses kept).
    /// A scale that is not finite and positive, or one the scene cannot
    /// take, is refused and nothing changes. \[audio-thread\]
    pub fn set_time_scale(
        &mut self,
        compiled: &Compiled,
        scale: f64,
    ) -> Result<(), TimeScaleError> {
        match (&mut self.kind, compiled) {
            (Kind::One(st), Compiled::One(c)) => st.set_time_scale(c, scale),
            (Kind::Several(st), Compiled::Several(c)) => st.set_time_scale(c, scale),
            _ => Err(TimeScaleError::Invalid),
        }
    }

    /// Leave the objects' modes above `band_hz` (physical, at the current
    /// time scale) out of the outputs (not of the dynamics); infinite:
    /// every mode heard. \[audio-thread\]
    pub fn set_output_band(&mut self, compiled: &Compiled, band_hz: f64) {
        match (&mut self.kind, compiled) {
            (Kind::One(st), Compiled::One(c)) => st.set_output_band(c, band_hz),
            (Kind::Several(st), Compiled::Several(c)) => st.set_output_band(c, band_hz),
            _ => {}
        }
    }

    /// The one-contact engine's state, for what only it offers (played-back
    /// strikes, traces, energy); `None` for several contacts.
    pub fn one_contact(&mut self) -> Option<&mut EngineState> {
        match &mut self.kind {
            Kind::One(st) => Some(st),
            Kind::Several(_) => None,
        }
    }

    /// The several-contact state (observations per contact, statistics);
    /// `None` for one contact.
    pub fn several_contacts(&mut self) -> Option<&mut MultiState> {
        match &mut self.kind {
            Kind::One(_) => None,
            Kind::Several(st) => Some(st),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets;

    const RATE: f64 = 44_100.0;

    fn preset(name: &str) -> (Scene, Compiled) {
        let scene = presets::scene(presets::index_of(name).unwrap()).unwrap();
        let compiled = compile(&scene, RATE).unwrap();
        (scene, compiled)
    }

    /// `n` samples of `voice` in blocks of 64.
    fn play(voice: &mut Voice, compiled: &Compiled, n: usize) -> Vec<f64> {
        let (mut l, mut r) = ([0.0; 64], [0.0; 64]);
        let mut out = Vec::with_capacity(2 * n);
        for _ in 0..n / 64 {
            voice.process_block(compiled, &mut l, &mut r);
            out.extend(l.iter().zip(&r).flat_map(|(a, b)| [*a, *b]));
        }
        out
    }

    #[test]
    fn one_contact_plays_the_engine_bit_for_bit() {
        let (_, compiled) = preset("marimba-bar");
        let Compiled::One(c) = &compiled else {
            panic!("marimba-bar has one contact")
        };
        let mut voice = Voice::new(&compiled);
        voice.strike(&compiled, 0, 0.0, -2.0).unwrap();
        let got = play(&mut voice, &compiled, 4096);
        let mut st = EngineState::new(c);
        st.strike(c, 0.0, -2.0);
        let (mut l, mut r) = (vec![0.0; 4096], vec![0.0; 4096]);
        for (lc, rc) in l.chunks_mut(64).zip(r.chunks_mut(64)) {
            st.process_block(c, lc, rc);
        }
        let want: Vec<f64> = l.iter().zip(&r).flat_map(|(a, b)| [*a, *b]).collect();
        assert!(got.iter().any(|x| x.abs() > 1e-6), "silent");
        assert_eq!(got, want);
    }

    #[test]
    fn several_contacts_play_the_several_contact_state_bit_for_bit() {
        let (scene, compiled) = preset("marimba-two-mallets");
        assert!(scene.several_contacts());
        let Compiled::Several(c) = &compiled else {
            panic!("marimba-two-mallets has several contacts")
        };
        assert_eq!(compiled.contacts(), c.contacts());
        let mut voice = Voice::new(&compiled);
        voice.strike(&compiled, 1, 0.0, -1.5).unwrap();
        let got = play(&mut voice, &compiled, 4096);
        let mut st = MultiState::new(c);
        st.strike(c, 1, 0.0, -1.5).unwrap();
        let (mut l, mut r) = (vec![0.0; 4096], vec![0.0; 4096]);
        for (lc, rc) in l.chunks_mut(64).zip(r.chunks_mut(64)) {
            st.process_block(c, lc, rc);
        }
        let want: Vec<f64> = l.iter().zip(&r).flat_map(|(a, b)| [*a, *b]).collect();
        assert!(got.iter().any(|x| x.abs() > 1e-6), "silent");
        assert_eq!(got, want);
    }

    #[test]
    fn compile_takes_every_preset_and_compile_one_refuses_several() {
        for i in 0..presets::PRESETS.len() {
            let scene = presets::scene(i).unwrap();
            let compiled = compile(&scene, RATE).unwrap_or_else(|e| panic!("{i}: {e}"));
            let several = scene.several_contacts();
            assert_eq!(matches!(compiled, Compiled::Several(_)), several);
            assert_eq!(compiled.contacts() > 1, several);
            assert_eq!(crate::compile::compile_one(&scene, RATE).is_err(), several);
        }
    }

    #[test]
    fn bad_strikes_are_refused_and_change_nothing() {
        let (_, one) = preset("marimba-bar");
        let (_, two) = preset("ball-between-plates");
        for compiled in [&one, &two] {
            let mut voice = Voice::new(compiled);
            let silent = play(&mut Voice::new(compiled), compiled, 256);
            for (h, v) in [(f64::NAN, -1.0), (-1e-3, -1.0), (0.0, f64::INFINITY)] {
                assert_eq!(voice.strike(compiled, 0, h, v), Err(StrikeError::NotFinite));
            }
            assert_eq!(
                voice.strike(compiled, 9, 0.0, -1.0),
                Err(StrikeError::NoMallet)
            );
            assert_eq!(play(&mut voice, compiled, 256), silent);
        }
        // a voice given another scene: refused, silence, no panic
        let mut voice = Voice::new(&one);
        assert_eq!(
            voice.strike(&two, 0, 0.0, -1.0),
            Err(StrikeError::OtherScene)
        );
        assert_eq!(
            voice.set_time_scale(&two, 2.0),
            Err(TimeScaleError::Invalid)
        );
        let (mut l, mut r) = ([1.0; 64], [1.0; 64]);
        voice.process_block(&two, &mut l, &mut r);
        assert!(l.iter().chain(&r).all(|x| *x == 0.0));
    }
}
