//! A scene of several contacts played as one instrument (docs/design.md,
//! "Played as a kit"): its objects are one physical system that
//! every note strikes, so the whole scene is one voice, the kit. A note
//! throws the mallets the scene gives it (`notes` of `[hammer]` and each
//! `[[striker]]`; without any, the next mallet in turn) at the note's
//! impact speed from the surface of the point it strikes (from the drop
//! height in a scene with gravity); a mallet still in contact leaves it
//! first ([`MultiState::strike`]). The kit plays at the scene's own pitch
//! (its contacts are compiled at the scene's time scale), keeps ringing
//! after note-off (mallets have no damper) and stops when it is silent:
//! its output below [`SILENCE_AMPLITUDE_RATIO`] of its loudest since the
//! last strike for a whole check interval while its masses' kinetic energy
//! is below [`SILENCE_ENERGY_RATIO`] of the strike's (nothing in flight
//! still to land).
//!
//! The kit renders in voice 0's lane, so the lookahead, the gain, the
//! output guard and the fade of a swap are the voices' own.

use super::{impact_speed_m_per_s, Instrument, CHECK_INTERVAL_SAMPLES, SILENCE_ENERGY_RATIO};
use crate::multi::{CompiledMulti, MultiModel, MultiState, MAX_CONTACTS};
use crate::scene::{Scene, SceneError};

/// The kit stops when its output stays below this fraction of its loudest
/// since the last strike for a whole check interval (-90 dB, the voices'
/// energy ratio [`SILENCE_ENERGY_RATIO`] as an amplitude).
pub const SILENCE_AMPLITUDE_RATIO: f64 = 3.1622776601683795e-5;

/// The compiled scene of several contacts, its running state and which
/// note strikes which mallet. Built off the audio thread; everything the
/// instrument does with it is allocation-free.
#[derive(Clone)]
pub struct Kit {
    /// Every phase of the scene's contacts.
    pub sc: CompiledMulti,
    /// The running state.
    pub(super) st: MultiState,
    /// Per MIDI note: the mallets it strikes (bit `i`: mallet `i`, whose
    /// contact is contact `i`; `[hammer]` is mallet 0, striker `i` mallet
    /// `i + 1`).
    keys: [u8; 128],
    /// No mallet lists notes: each note strikes the next mallet in turn.
    in_turn: bool,
    /// The mallet a note strikes next when in turn.
    next: usize,
    /// How many mallets.
    pub mallets: usize,
    /// The masses fall (the scene has gravity).
    pub bouncing: bool,
    /// The last note that struck each mallet (the live view).
    pub(super) last_key: [u8; MAX_CONTACTS],
    /// The loudest output since the last strike, the loudest of the
    /// current check interval, and the strike's energy \[J\].
    peak: f64,
    interval_peak: f64,
    strike_energy: f64,
    /// Strikes refused (a mallet wedged, [`MultiState::strike`]).
    pub refused: u64,
}

impl Kit {
    /// The kit of a scene of several contacts (as played: the parameters
    /// already applied) at `rate_hz`. \[worker\] \[main-thread\]
    pub fn new(scene: &Scene, rate_hz: f64) -> Result<Self, SceneError> {
        let model = MultiModel::from_scene(scene, rate_hz)?;
        let sc = CompiledMulti::new(&model, rate_hz).map_err(|e| {
            let key = if scene.touch.is_empty() {
                "striker"
            } else {
                "touch"
            };
            SceneError::new(key, e.to_string())
        })?;
        let mut st = MultiState::new(&sc);
        st.rest(&sc);
        let lists: Vec<&Vec<u8>> = std::iter::once(&scene.hammer.notes)
            .chain(scene.striker.iter().map(|s| &s.notes))
            .collect();
        let mut keys = [0u8; 128];
        for (i, notes) in lists.iter().enumerate() {
            for &n in notes.iter() {
                keys[usize::from(n.min(127))] |= 1 << i;
            }
        }
        Ok(Self {
            mallets: lists.len(),
            in_turn: lists.iter().all(|l| l.is_empty()),
            keys,
            next: 0,
            bouncing: scene.hammer.gravity_m_per_s2 > 0.0,
            last_key: [0; MAX_CONTACTS],
            peak: 0.0,
            interval_peak: 0.0,
            strike_energy: 0.0,
            refused: 0,
            sc,
            st,
        })
    }

    /// The mallets note `key` strikes (bit `i`: mallet `i`), taking the
    /// turn when the scene lists no notes.
    fn mallets_for(&mut self, key: u8) -> u8 {
        if self.in_turn {
            let i = self.next;
            self.next = (self.next + 1) % self.mallets;
            1 << i
        } else {
            self.keys[usize::from(key.min(127))]
        }
    }

    /// Which note strikes which mallet, in words (the summary).
    pub fn notes_rule(&self) -> &'static str {
        if self.mallets == 1 {
            "every note strikes the mallet"
        } else if self.in_turn {
            "each note strikes the next mallet in turn"
        } else {
            "notes strike the mallets that list them"
        }
    }

    /// What was compiled, in words (the plugin's compile summary, the
    /// offline render's).
    pub fn summary(&self) -> String {
        let m = &self.sc.model;
        format!(
            "several contacts, played as one voice: {} modes, {} mallets, {} masses, {} \
             contacts ({} phases, all compiled), largest phase {} states (per sample \
             O(states)), {}, exact switching",
            m.freq_hz.len(),
            self.mallets,
            m.masses.len(),
            m.contacts.len(),
            self.sc.phases.len(),
            self.max_dim(),
            self.notes_rule(),
        )
    }

    /// The largest state dimension of its phases.
    pub fn max_dim(&self) -> usize {
        self.sc.max_dim()
    }

    /// Tick `len` samples into `buf` with a linear gain ramp `g0 - k dg`,
    /// calling `look` on the state before each sample (the live view);
    /// false if a sample was not a number (the kit then rests).
    /// \[audio-thread\]
    pub(super) fn tick_into(
        &mut self,
        buf: &mut [[f64; CHECK_INTERVAL_SAMPLES]; 2],
        len: usize,
        (g0, dg): (f64, f64),
        mut look: impl FnMut(usize, &MultiState, &CompiledMulti),
    ) -> bool {
        let mut finite = true;
        for k in 0..len {
            look(k, &self.st, &self.sc);
            let [l, r] = self.st.tick(&self.sc);
            finite &= l.is_finite() && r.is_finite();
            let g = (g0 - k as f64 * dg).max(0.0);
            buf[0][k] = l * g;
            buf[1][k] = r * g;
        }
        if !finite {
            self.st.rest(&self.sc);
        }
        finite
    }

    /// Take over the running state of `old`, a kit of the same scene
    /// compiled with other parameters, while none of its contacts is
    /// closed ([`MultiState::carry`]: the physical state and so the energy
    /// unchanged), with its turn, its keys and its silence test's
    /// references; `old` keeps this kit's fresh state (to be retired). False
    /// (nothing changed) when a contact is closed or the bodies differ.
    /// Allocation-free. \[audio-thread\]
    pub(super) fn take_over(&mut self, old: &mut Kit) -> bool {
        if self.mallets != old.mallets || !old.st.carry(&old.sc, &self.sc) {
            return false;
        }
        std::mem::swap(&mut self.st, &mut old.st);
        self.next = old.next;
        self.last_key = old.last_key;
        self.peak = old.peak;
        self.interval_peak = old.interval_peak;
        self.strike_energy = old.strike_energy;
        true
    }

    /// The running state (tests, tools). \[audio-thread\]
    pub fn state(&self) -> &MultiState {
        &self.st
    }
}

impl Instrument {
    /// A note on a kit: wake it at rest if it was silent, then throw the
    /// note's mallets. \[audio-thread\]
    pub(super) fn kit_note_on(&mut self, key: u8, velocity_norm: f64) {
        let speed = impact_speed_m_per_s(velocity_norm);
        let drop = self.play.drop_height_m.max(0.0);
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        self.stats.notes += 1;
        let which = kit.mallets_for(key);
        if which == 0 {
            return;
        }
        let v = &mut self.voices[0];
        if !v.active {
            kit.st.rest(&kit.sc);
            kit.peak = 0.0;
            kit.interval_peak = 0.0;
            self.lanes.begin(0, self.sample_pos);
            v.active = true;
        }
        v.key = key;
        v.onset_pos = self.sample_pos;
        let height = if kit.bouncing { drop } else { 0.0 };
        let g = kit.sc.model.gravity_m_per_s2;
        let mut energy = 0.0;
        for i in 0..kit.mallets {
            if which & (1 << i) == 0 {
                continue;
            }
            if kit.st.strike(&kit.sc, i, height, -speed).is_ok() {
                let m = kit.sc.model.masses[i].mass_kg;
                energy += 0.5 * m * speed * speed + m * g * height;
                kit.last_key[i] = key;
            } else {
                kit.refused += 1;
            }
        }
        if energy > 0.0 {
            // a new strike: the silence test's references start again
            kit.strike_energy = energy;
            kit.peak = 0.0;
        }
    }

    /// Render the kit's chunk of `len` samples starting at time `t0` into
    /// `vbuf` (voice 0's lane takes it); the contacts it started, or `None`
    /// when a sample was not a number (the kit rests and stops: nothing of
    /// that chunk sounds). With the live view on, every contact is shown as
    /// a voice of its own (voice `j` for contact `j`: its upper side as the
    /// hammer, its lower side as the contact point; a mallet's contact
    /// under the key that last threw it).
    /// \[audio-thread\]
    pub(super) fn kit_render(&mut self, t0: u64, len: usize) -> Option<u64> {
        let kit = self.cur.kit.as_deref_mut()?;
        let started: u64 = kit.st.stats.contacts_started.iter().sum();
        let observe = self.probe_on && self.probe.is_some();
        let contacts = kit.sc.contacts();
        let motion = &mut self.kit_motion;
        let finite = kit.tick_into(&mut self.vbuf, len, (1.0, 0.0), |k, st, sc| {
            if observe {
                let o = st.observe(sc);
                for (j, m) in motion.iter_mut().enumerate().take(contacts) {
                    m[k] = crate::engine::Motion {
                        x_hammer: o.x_hammer[j],
                        v_hammer: o.v_hammer[j],
                        x_contact: o.x_contact[j],
                        v_contact: o.v_contact[j],
                        in_contact: o.active & (1 << j) != 0,
                    };
                }
            }
        });
        if !finite {
            self.voices[0].active = false;
            self.stats.nonfinite_resets += 1;
            return None;
        }
        let mut peak = kit.interval_peak;
        for k in 0..len {
            peak = peak.max(self.vbuf[0][k].abs()).max(self.vbuf[1][k].abs());
        }
        kit.interval_peak = peak;
        kit.peak = kit.peak.max(peak);
        if observe {
            let energy_j = kit.st.observe(&kit.sc).energy;
            if let Some(probe) = self.probe.as_deref_mut() {
                for j in 0..contacts {
                    probe.voice_chunk(&super::VoiceChunk {
                        voice: j,
                        key: kit.last_key[j],
                        released: false,
                        start: t0,
                        motion: &self.kit_motion[j][..len],
                        energy_j,
                    });
                }
            }
        }
        let now: u64 = kit.st.stats.contacts_started.iter().sum();
        Some(now - started)
    }

    /// The kit's silence check (on the silence-check grid): it stops when
    /// its last interval's output stayed below [`SILENCE_AMPLITUDE_RATIO`]
    /// of its loudest since the strike and its masses hardly move.
    /// \[audio-thread\]
    pub(super) fn kit_silence(&mut self) {
        let Some(kit) = self.cur.kit.as_deref_mut() else {
            return;
        };
        if !self.voices[0].active {
            return;
        }
        let quiet = kit.interval_peak < SILENCE_AMPLITUDE_RATIO * kit.peak;
        kit.interval_peak = 0.0;
        if quiet && kit.st.masses_to_land(&kit.sc) < SILENCE_ENERGY_RATIO * kit.strike_energy {
            self.voices[0].active = false;
            self.stats.silent_stops += 1;
        }
    }
}
