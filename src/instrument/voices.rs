//! Voices: one per sounding note; allocation (a repeated note restrikes its
//! own voice, a new note takes a free voice or steals the quietest, whose
//! running state fades out in a spare), the damper at note-off, and
//! silence detection.

use super::mapping::{drive_speed_m_per_s, key_scale, wheel_speed_factor};
use super::prepared::{Prepared, Variant};
use super::{
    impact_speed_m_per_s, slew, Instrument, MAX_PRESSURE_DECAY_PER_S, MAX_VOICES,
    SILENCE_ENERGY_RATIO, STEAL_FADES,
};
use crate::compile::CompiledScene;
use crate::engine::EngineState;

#[derive(Debug, Clone, Copy, Default)]
/// One voice's note bookkeeping (its engine state lives in
/// `Prepared::states` at the same index).
pub(super) struct Voice {
    /// Sounding.
    pub(super) active: bool,
    /// Its MIDI key.
    pub(super) key: u8,
    /// Released (note-off seen).
    pub(super) released: bool,
    /// Bound to the damped scene rather than the played one.
    pub(super) on_damped: bool,
    /// Energy of the last strike (reference units), for the silence test.
    pub(super) strike_energy: f64,
    /// Time scale of its note without the pitch bend.
    pub(super) base_scale: f64,
    /// Per-note tuning asked for \[semitones\] ([`super::Event::NoteTuning`]).
    pub(super) tuning_target: f64,
    /// Per-note tuning the voice is at (gliding towards the target).
    pub(super) tuning_now: f64,
    /// The instrument's clock at its last note-on: a tuning at this very
    /// sample applies at once.
    pub(super) onset_pos: u64,
    /// Its last note-on struck it from rest (a new voice, not a repeated
    /// note on its ringing one): while the clock is still at `onset_pos`
    /// nothing of it has sounded, and a steal there takes it without a
    /// fade.
    pub(super) fresh: bool,
    /// Its note's pressure, 0 .. 1 ([`super::Event::NotePressure`]).
    pub(super) pressure: f64,
    /// The variant of the scene it is bound to (hardness and position
    /// levels; the damper level once released; all 0: the played one;
    /// [`super::Event::NoteBrightness`], docs/plugin.md "Polyphonic
    /// modulation").
    pub(super) at: Variant,
    /// The variant its note asks for (taken when its hammer is out of
    /// contact): the hardness level is its brightness's plus its hardness
    /// modulation's, within the compiled levels ([`super::wanted_level`]).
    pub(super) want: Variant,
    /// Its note's brightness level ([`super::Event::NoteBrightness`]).
    pub(super) bright_level: i8,
    /// Its note's hardness modulation level ([`super::Event::NoteHardness`]).
    pub(super) hard_level: i8,
    /// The damper pressing it since its last decision (`None`: not
    /// pressed), see [`Instrument::press_decide`].
    pub(super) pressing: Option<Pressing>,
    /// A driven scene's speed along the path its note's velocity set
    /// \[m/s\], before the mod wheel ([`wheel_speed_factor`]) and its
    /// slide.
    pub(super) drive_base: f64,
    /// A driven scene's factor on that speed from its note's brightness
    /// (MPE's slide, [`super::slide_speed_factor`]); 1 until one comes.
    pub(super) slide: f64,
}

impl Voice {
    /// A driven scene's speed along the path \[m/s\]: its velocity's,
    /// times the mod wheel's factor `wheel` and its slide.
    fn drive_speed(&self, wheel: f64) -> f64 {
        self.drive_base * wheel * self.slide
    }
}

/// A pressed voice between two updates of its state (docs/plugin.md,
/// "Pressure and the mod wheel"): its engine runs the free motion, each
/// sample leaves multiplied by `g` (then `g *= q`), and the state takes the
/// product at the next decision ([`Instrument::press_flush`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Pressing {
    /// `e^(-a dt)`: the decay the damper adds per sample.
    pub(super) q: f64,
    /// What the damper took since the decision: `q^k` after `k` samples.
    pub(super) g: f64,
}

impl Instrument {
    pub(super) fn note_on(&mut self, key: u8, velocity_norm: f64) {
        if self.cur.kit.is_some() {
            return self.kit_note_on(key, velocity_norm);
        }
        self.stats.notes += 1;
        let speed = impact_speed_m_per_s(velocity_norm);
        // a new note on a voice at rest whose key's propagators were copied:
        // the key's stored strike from rest, where it has one
        let mut stored = None;
        let idx = if let Some(i) = self.voices.iter().position(|v| v.active && v.key == key) {
            // Same key still ringing: strike the moving object again (what
            // its damper took so far goes into its state first).
            self.restrike(i);
            i
        } else {
            let i = self.voice_for_note();
            stored = self.start_voice(i, key);
            i
        };
        self.strike_voice(idx, speed, stored);
    }

    /// Voice `i`, still ringing, takes a new note on its key: back to the
    /// played scene, its note's levels, pressure and tuning reset.
    /// \[audio-thread\]
    fn restrike(&mut self, i: usize) {
        self.press_flush(i);
        let p = &mut *self.cur;
        let v = &mut self.voices[i];
        if v.on_damped || v.at != Variant::default() {
            // back to the played scene: a new note starts at level 0
            let from = p.scenes.bound(v.at, v.on_damped);
            if !std::ptr::eq(from, &p.scenes.scene) && !p.states[i].rebind(from, &p.scenes.scene) {
                p.states[i].reset(&p.scenes.scene);
            }
            v.on_damped = false;
            v.at = Variant::default();
        }
        v.want = Variant::default();
        v.bright_level = 0;
        v.hard_level = 0;
        v.released = false;
        v.fresh = false;
        v.pressure = 0.0;
        // a new note starts untuned (from where it is, gliding)
        v.tuning_target = 0.0;
        if v.tuning_now != 0.0 {
            self.tuning_moving = true;
        }
    }

    /// The voice a note on a key that is not ringing takes.
    /// \[audio-thread\]
    fn voice_for_note(&mut self) -> usize {
        // a free voice while fewer than the Polyphony sound, else the
        // quietest is stolen (the voices that sound may be any of the
        // 64: a lowered Polyphony ends the quietest, wherever they are)
        let poly = self.play.polyphony.clamp(1, MAX_VOICES);
        let sounding = self.voices.iter().filter(|v| v.active).count();
        let free = self.voices.iter().position(|v| !v.active);
        match free.filter(|_| sounding < poly) {
            Some(i) => {
                // its lane sounds again from now
                self.lanes.begin(i, self.sample_pos);
                i
            }
            None => {
                self.stats.steals += 1;
                let mut among = [false; MAX_VOICES];
                (0..MAX_VOICES).for_each(|i| among[i] = self.voices[i].active);
                let i = self.quietest(&among).unwrap_or(0);
                if self.fade_voice(i, false) {
                    self.stats.steals_faded += 1;
                }
                i
            }
        }
    }

    /// Voice `i` starts over for `key` at rest: its time scale (the key's,
    /// with the bend) and a fresh [`Voice`]. The slot of the key's
    /// propagators when they were copied (its stored strike from rest may
    /// then be replayed). \[audio-thread\]
    fn start_voice(&mut self, i: usize, key: u8) -> Option<usize> {
        let p = &mut *self.cur;
        let st = &mut p.states[i];
        st.reset(&p.scenes.scene);
        let base = if self.play.pitch_tracking {
            key_scale(key, p.root_note)
        } else {
            1.0
        };
        let s = if p.bouncing || self.bend_now == 0.0 {
            base
        } else {
            base * 2f64.powf(self.bend_now / 12.0)
        };
        // the propagators made ahead for the key's scale (the root's,
        // scale 1, without pitch tracking) when no bend moves it, else
        // computed here
        let slot = if self.play.pitch_tracking {
            usize::from(key)
        } else {
            p.root_note as usize
        };
        let made = p.key_props.get(slot).filter(|k| k.scale() == s);
        let set = match made {
            Some(k) => {
                self.stats.key_props_copied += 1;
                st.set_time_scale_from(&p.scenes.scene, k)
            }
            None => st.set_time_scale(&p.scenes.scene, s),
        };
        match set {
            Ok(()) => {}
            Err(_) => {
                self.stats.dense_pitch_fallbacks += u64::from(s != 1.0);
                let _ = st.set_time_scale(&p.scenes.scene, 1.0);
            }
        }
        st.reset(&p.scenes.scene);
        let stored = made.map(|_| slot);
        self.voices[i] = Voice {
            active: true,
            key,
            released: false,
            on_damped: false,
            strike_energy: 0.0,
            base_scale: base,
            tuning_target: 0.0,
            tuning_now: 0.0,
            onset_pos: 0,
            fresh: true,
            pressure: 0.0,
            at: Variant::default(),
            want: Variant::default(),
            bright_level: 0,
            hard_level: 0,
            pressing: None,
            drive_base: 0.0,
            slide: 1.0,
        };
        stored
    }

    /// Voice `idx` struck at `speed` (from its drop height when the hammer
    /// bounces; the key's stored strike `stored` where it has one), and its
    /// strike's energy. \[audio-thread\]
    fn strike_voice(&mut self, idx: usize, speed: f64, stored: Option<usize>) {
        let p = &mut *self.cur;
        let st = &mut p.states[idx];
        let s = st.time_scale();
        let v_ref = speed / s;
        let m_h = p.scenes.scene.m_h;
        let mut e = 0.5 * m_h * v_ref * v_ref;
        if let Some(d) = &p.scenes.scene.drive {
            // a driven scene: a new note puts the hammer on the surface at
            // rest at the path's start (its voice was reset); a note on a
            // ringing key keeps it where it is; either way the note's
            // velocity sets the speed along the path, the mod wheel
            // multiplies it
            let path_speed = drive_speed_m_per_s(d.speed_m_per_s, speed);
            if self.voices[idx].fresh {
                st.strike(&p.scenes.scene, 0.0, 0.0);
            }
            self.voices[idx].drive_base = path_speed;
            let speed = self.voices[idx].drive_speed(wheel_speed_factor(self.mod_wheel));
            st.set_drive_speed(&p.scenes.scene, speed);
            e = 0.5 * m_h * (path_speed / s) * (path_speed / s);
        } else if p.bouncing {
            let h = self.play.drop_height_m.max(0.0);
            st.strike(&p.scenes.scene, h, -speed);
            e += m_h * p.scenes.scene.g * h;
        } else if let Some(pre) = stored.and_then(|k| p.key_props.get(k)) {
            if st.strike_stored(&p.scenes.scene, speed, pre) {
                self.stats.strikes_replayed += 1;
            }
        } else {
            st.strike(&p.scenes.scene, 0.0, -speed);
        }
        self.voices[idx].strike_energy = e;
        self.voices[idx].onset_pos = self.sample_pos;
        // a pressed channel presses a new stroke from its start
        self.press_drive(idx);
    }

    /// Voice `i`'s note fades out from here: stolen by a new note, choked,
    /// ended by All Sound Off or a lowered Polyphony (docs/plugin.md,
    /// "Velocity, pitch, voices"). Unless nothing of it has sounded yet
    /// (struck from rest at this very sample), its running state (with
    /// what its damper took so far) moves into a spare state
    /// ([`spare_for_fade`]; a kit's spare kit state) and fades out from
    /// here over [`super::FADE_S`] on the instrument's clock, in the fade's
    /// lane, following the bend, its note's tuning and the pressure
    /// ([`StealFade`]), while the voice keeps the spare's state (a new note
    /// starts it over). `together`: one of several voices ended at once,
    /// the loudest first ([`spare_for_fade_together`]): when every spare
    /// holds the fade of a louder one that began at this sample, it is not
    /// faded (cut, counted). Whether it fades. A swap of two states: O(1),
    /// allocation-free. \[audio-thread\]
    pub(super) fn fade_voice(&mut self, i: usize, together: bool) -> bool {
        let v = self.voices[i];
        if !v.active || v.fresh && v.onset_pos == self.sample_pos {
            return false;
        }
        let spares = match self.cur.kit.as_deref() {
            Some(kit) if i < kit.voices.len() => kit.spares.len(),
            Some(_) => 0,
            None => STEAL_FADES,
        };
        if spares == 0 {
            return false;
        }
        let (fades, cut) = (&self.steal_fades, &mut self.stats.steal_fades_cut);
        let f = if together {
            match spare_for_fade_together(fades, spares, self.fade_len, cut) {
                Some(f) => f,
                None => return false,
            }
        } else {
            spare_for_fade(fades, spares, cut)
        };
        self.press_flush(i);
        let p = &mut *self.cur;
        let mut fade = StealFade::of(&v, self.fade_len);
        match p.kit.as_deref_mut() {
            Some(kit) => {
                std::mem::swap(&mut kit.voices[i].st, &mut kit.spares[f]);
                // a kit voice fades on the compile it runs on (its note's
                // levels, or the damped one once released)
                fade.at = v.at;
                fade.on_damped = v.on_damped;
            }
            None => std::mem::swap(&mut p.states[i], &mut p.spares[f]),
        }
        fade_decide(p, f, &mut fade, self.channel_pressure.max(self.mod_wheel));
        self.steal_fades[f] = Some(fade);
        self.lanes.begin(FADE_LANE, self.sample_pos);
        true
    }

    /// End voice `i` now, without a click (a choke, All Sound Off, a
    /// lowered Polyphony): it fades out as a stolen voice does
    /// ([`Instrument::fade_voice`]) and is free for the next note.
    /// Allocation-free. \[audio-thread\]
    pub(super) fn end_voice(&mut self, i: usize, together: bool) {
        if !self.voices[i].active {
            return;
        }
        self.stats.voices_ended += 1;
        if self.fade_voice(i, together) {
            self.stats.voices_ended_faded += 1;
        }
        let v = &mut self.voices[i];
        v.active = false;
        v.pressing = None;
    }

    /// End the voices of `ending` together, the loudest first, so that
    /// when there are more of them than spare states the quietest are the
    /// ones cut ([`spare_for_fade_together`]). Allocation-free.
    /// \[audio-thread\]
    pub(super) fn end_voices(&mut self, ending: &[bool; MAX_VOICES]) {
        let mut loud = [0.0f64; MAX_VOICES];
        let mut left = [false; MAX_VOICES];
        for i in 0..MAX_VOICES {
            left[i] = ending[i] && self.voices[i].active;
            if left[i] {
                let e = self.loudness(i);
                loud[i] = if e.is_nan() { 0.0 } else { e };
            }
        }
        while let Some(i) = (0..MAX_VOICES)
            .filter(|&i| left[i])
            .max_by(|&a, &b| loud[a].total_cmp(&loud[b]))
        {
            left[i] = false;
            self.end_voice(i, true);
        }
    }

    /// Every voice fades out (All Sound Off, a choke of every note).
    /// \[audio-thread\]
    pub(super) fn end_all(&mut self) {
        self.end_voices(&[true; MAX_VOICES]);
    }

    /// A lowered Polyphony: while more voices sound than `limit` (a
    /// pitched kit: its kit voices, up to [`super::MAX_KIT_VOICES`]), the
    /// quietest ([`Instrument::quietest`], the rule of a steal) are ended
    /// as stolen voices fade. Allocation-free. \[audio-thread\]
    pub(super) fn end_beyond(&mut self, limit: usize) {
        let limit = match self.cur.kit.as_deref() {
            Some(kit) => limit.min(kit.voices.len()),
            None => limit,
        };
        let count = |inst: &Self| inst.voices.iter().filter(|v| v.active).count();
        if count(self) <= limit {
            return;
        }
        // every voice at the clock (a silent one stops first)
        self.sync_all(true);
        let mut among = [false; MAX_VOICES];
        (0..MAX_VOICES).for_each(|i| among[i] = self.voices[i].active);
        let mut ending = [false; MAX_VOICES];
        for _ in limit..count(self) {
            let Some(q) = self.quietest(&among) else {
                break;
            };
            among[q] = false;
            ending[q] = true;
        }
        self.end_voices(&ending);
    }

    /// The voice a steal takes among `among`: the quietest (a voice: the
    /// lowest energy, [`EngineState::energy_proxy`] in physical units; a
    /// kit voice: the lowest peak since its throw), the first of equals.
    pub(super) fn quietest(&self, among: &[bool; MAX_VOICES]) -> Option<usize> {
        if let Some(kit) = self.cur.kit.as_deref() {
            let n = kit.voices.len().min(MAX_VOICES);
            return (0..n)
                .filter(|&i| among[i])
                .min_by(|&a, &b| kit.loudness(a).total_cmp(&kit.loudness(b)));
        }
        let mut best = None;
        let mut best_e = f64::INFINITY;
        for i in (0..MAX_VOICES).filter(|&i| among[i]) {
            let e = self.loudness(i);
            if !(e >= best_e) {
                best = Some(i);
                best_e = e;
            }
        }
        best
    }

    /// How loud voice `i` is, as a steal compares voices: a voice's energy
    /// in physical units ([`EngineState::energy_proxy`] times its time
    /// scale squared), a kit voice's peak since its throw.
    fn loudness(&self, i: usize) -> f64 {
        let p = &*self.cur;
        if let Some(kit) = p.kit.as_deref() {
            return kit.loudness(i);
        }
        let (v, st) = (&self.voices[i], &p.states[i]);
        let s = st.time_scale();
        st.energy_proxy(p.scenes.bound(v.at, v.on_damped)) * s * s
    }

    /// A choke ([`super::Event::Choke`]): the voice of `key` (every voice
    /// for `None`; a kit voice is its last note's) fades out now.
    /// \[audio-thread\]
    pub(super) fn choke(&mut self, key: Option<u8>) {
        match key {
            None => self.end_all(),
            Some(k) => {
                for i in 0..MAX_VOICES {
                    if self.voices[i].active && self.voices[i].key == k {
                        self.end_voice(i, false);
                    }
                }
            }
        }
    }

    pub(super) fn note_off(&mut self, key: Option<u8>) {
        if self.cur.kit.is_some() {
            return self.kit_note_off(key);
        }
        for i in 0..MAX_VOICES {
            let v = self.voices[i];
            if !v.active || v.released || key.is_some_and(|k| k != v.key) {
                continue;
            }
            self.release_voice(i);
        }
    }

    /// Release voice `i`: the damper falls (it continues on the damped
    /// scene of its damper level when there is one); a driven scene's
    /// surface stops (the stroke ends where it is).
    pub(super) fn release_voice(&mut self, i: usize) {
        self.press_flush(i);
        let p = &mut *self.cur;
        let v = &mut self.voices[i];
        v.released = true;
        p.states[i].set_drive_speed(&p.scenes.scene, 0.0);
        if let Some(d) = p.scenes.damped_for(v.want.damper) {
            if p.states[i].rebind(p.scenes.bound(v.at, false), d) {
                v.on_damped = true;
                v.at.damper = v.want.damper;
            }
        }
        self.press_decide(i);
    }

    /// Move every voice whose note asks for another variant (a brightness,
    /// a host's polyphonic modulation) to that variant's scene
    /// ([`Instrument::move_timbre`]); a voice whose hammer is in contact
    /// waits for its next grid actions (on its own clock, in
    /// `Instrument::advance_voice`).
    /// Allocation-free. \[audio-thread\]
    pub(super) fn apply_timbre(&mut self) {
        let mut pending = false;
        for i in 0..MAX_VOICES {
            pending |= self.move_timbre(i);
        }
        self.timbre_pending = pending;
    }

    /// Move voice `i` to the variant its note asks for, if it asks for
    /// another one ([`EngineState::rebind_same_free`] between played
    /// variants that step the free phase in the same coordinates, as every
    /// preset's hardness levels do: the state kept bit for bit, O(N); else
    /// [`EngineState::rebind`], O(N^2)), unless its hammer is in contact:
    /// then it returns true (it waits; its voice's grid actions try again
    /// on the silence-check grid). A released voice moves between the
    /// damped scenes of its damper levels. Allocation-free. \[audio-thread\]
    pub(super) fn move_timbre(&mut self, i: usize) -> bool {
        let p = &*self.cur;
        let v = &mut self.voices[i];
        if !v.active || v.at == v.want {
            return false;
        }
        let to_damped = v.released && p.scenes.damped_for(v.want.damper).is_some();
        if std::ptr::eq(
            p.scenes.bound(v.at, v.on_damped),
            p.scenes.bound(v.want, to_damped),
        ) {
            v.at = v.want;
            v.on_damped = to_damped;
            return false;
        }
        if p.states[i].in_contact() {
            return true;
        }
        self.press_flush(i);
        let p = &mut *self.cur;
        let v = &mut self.voices[i];
        let from = p.scenes.bound(v.at, v.on_damped);
        let to = p.scenes.bound(v.want, to_damped);
        let st = &mut p.states[i];
        let moved = if !v.on_damped && !to_damped && p.scenes.same_free(v.at, v.want) {
            st.rebind_same_free(from, to)
        } else {
            st.rebind(from, to)
        };
        if moved {
            v.at = v.want;
            v.on_damped = to_damped;
        } else {
            // a variant it cannot be carried to: it stays where it is
            v.want = v.at;
        }
        self.press_decide(i);
        false
    }

    /// Put what voice `i`'s damper took since its last decision into its
    /// state ([`EngineState::scale_free_state`]) and stop pressing it; the
    /// first thing anything that changes the voice does, so the damper
    /// acts between decisions taken on the instrument's grid and at events,
    /// never where a host block ends. O(N). \[audio-thread\]
    pub(super) fn press_flush(&mut self, i: usize) {
        if let Some(pr) = self.voices[i].pressing.take() {
            if pr.g != 1.0 {
                let taken = match self.cur.kit.as_deref_mut() {
                    Some(kit) => kit
                        .voices
                        .get_mut(i)
                        .is_some_and(|kv| kv.st.scale_objects(pr.g)),
                    None => self.cur.states[i].scale_free_state(pr.g),
                };
                debug_assert!(taken, "a pressed voice is out of contact");
            }
        }
    }

    /// Decide whether voice `i` is pressed from now to its next decision:
    /// when its pressure (the largest of its note's, the channel's and the
    /// mod wheel's) is above 0, the scene does not bounce, and its hammer is
    /// clear of the object ([`EngineState::hammer_clear`]: no contact can
    /// start before the next decision, pressed or not, so scaling the free
    /// motion's samples is the pressed motion exactly). Taken on the
    /// voice's 64-sample grid and after every event that changes it (a
    /// pressure, a release, a bend's update, a move to another variant).
    /// O(N). \[audio-thread\]
    pub(super) fn press_decide(&mut self, i: usize) {
        let p = &*self.cur;
        let v = &self.voices[i];
        if !v.active || v.pressing.is_some() || p.bouncing {
            return;
        }
        let press = v.pressure.max(self.channel_pressure).max(self.mod_wheel);
        let clear = || match p.kit.as_deref() {
            // a kit voice: no contact of it can close
            Some(kit) => kit
                .voices
                .get(i)
                .is_some_and(|kv| kv.st.contacts_clear(kit.sc_for(super::kit::kit_at(v)))),
            None => p.states[i].hammer_clear(p.scenes.bound(v.at, v.on_damped)),
        };
        if press > 0.0 && clear() {
            let q = (-MAX_PRESSURE_DECAY_PER_S * press / p.rate_hz).exp();
            self.voices[i].pressing = Some(Pressing { q, g: 1.0 });
        }
    }

    /// [`press_flush`](Self::press_flush) then
    /// [`press_decide`](Self::press_decide): a voice whose pressure
    /// changed. \[audio-thread\]
    pub(super) fn repress(&mut self, i: usize) {
        self.press_flush(i);
        self.press_decide(i);
    }

    /// Voice `i` of a driven scene under a constant force pressed by its
    /// pressure (its note's or the channel's, the larger): the force times
    /// [`super::press_factor`], from this sample on
    /// ([`EngineState::set_load`]: the same physical state, in contact
    /// too, now under that force). Released voices keep theirs. O(N) when
    /// the pressure changes, else O(1). \[audio-thread\]
    pub(super) fn press_drive(&mut self, i: usize) {
        let p = &mut *self.cur;
        let v = &self.voices[i];
        if !p.bouncing || p.scenes.scene.drive.is_none() || !v.active || v.released {
            return;
        }
        let load = super::press_factor(v.pressure.max(self.channel_pressure));
        let taken = p.states[i].set_load(p.scenes.bound(v.at, v.on_damped), load);
        debug_assert!(taken, "a press factor is finite and positive");
    }

    /// A driven scene's held notes at the mod wheel's speed: each the
    /// speed its velocity set times [`wheel_speed_factor`] (released
    /// notes stay stopped). \[audio-thread\]
    pub(super) fn drive_wheel(&mut self) {
        let p = &mut *self.cur;
        if p.scenes.scene.drive.is_none() {
            return;
        }
        let factor = wheel_speed_factor(self.mod_wheel);
        for (v, st) in self.voices.iter().zip(p.states.iter_mut()) {
            if v.active && !v.released {
                st.set_drive_speed(&p.scenes.scene, v.drive_speed(factor));
            }
        }
    }

    /// A driven scene's notes of `key` (every note for `None`) slide to
    /// `factor` times their velocity's speed (times the mod wheel's):
    /// MPE's slide on their channel, or a host's brightness
    /// ([`super::slide_speed_factor`]). A released note's surface has
    /// stopped and stays still. \[audio-thread\]
    pub(super) fn drive_slide(&mut self, key: Option<u8>, factor: f64) {
        let p = &mut *self.cur;
        let wheel = wheel_speed_factor(self.mod_wheel);
        for (v, st) in self.voices.iter_mut().zip(p.states.iter_mut()) {
            if v.active && key.is_none_or(|k| k == v.key) {
                v.slide = factor;
                if !v.released {
                    st.set_drive_speed(&p.scenes.scene, v.drive_speed(wheel));
                }
            }
        }
    }

    /// Stop voice `i` if it fell silent (its energy below
    /// [`SILENCE_ENERGY_RATIO`] of its strike's). \[audio-thread\]
    pub(super) fn stop_if_silent(&mut self, i: usize) {
        if self.cur.kit.is_some() {
            return self.kit_silence(i);
        }
        let p = &*self.cur;
        let v = &mut self.voices[i];
        if !v.active {
            return;
        }
        let scene = p.scenes.bound(v.at, v.on_damped);
        if p.states[i].drive_speed() != 0.0 && scene.drive.is_some() {
            // a surface still moving under the hammer keeps feeding it
            return;
        }
        if let Some(e) = audible_energy(&p.states[i], scene) {
            if e < SILENCE_ENERGY_RATIO * v.strike_energy {
                v.active = false;
                self.stats.silent_stops += 1;
            }
        }
    }
}

impl Instrument {
    /// The fading voices' damper decisions (as a voice's,
    /// [`Instrument::repress`]): what each took goes into its spare's
    /// state, then it is decided again at the pressure now. Taken on the
    /// instrument's silence-check grid and after every event that changes
    /// a pressure. O(fades N). \[audio-thread\]
    pub(super) fn repress_fades(&mut self) {
        let floor = self.channel_pressure.max(self.mod_wheel);
        let sets = [
            (Some(&mut *self.cur), &mut self.steal_fades),
            (self.fading.as_deref_mut(), &mut self.old_steal_fades),
        ];
        for (p, fades) in sets {
            let Some(p) = p else { continue };
            for (f, slot) in fades.iter_mut().enumerate() {
                if let Some(fade) = slot.as_mut() {
                    fade_flush(p, f, fade);
                    fade_decide(p, f, fade, floor);
                }
            }
        }
    }

    /// Set what `set` sets on the fading voices of `key` (every one for
    /// `None`), in the scene set played and in the one a swap left fading.
    pub(super) fn for_fades(&mut self, key: Option<u8>, mut set: impl FnMut(&mut StealFade)) {
        for fades in [&mut self.steal_fades, &mut self.old_steal_fades] {
            for fade in fades.iter_mut().flatten() {
                if key.is_none_or(|k| k == fade.key) {
                    set(fade);
                }
            }
        }
    }

    /// One update of a moving bend for the fading voices (the sounding
    /// voices' rule, [`Instrument::bend_tick`]): each steps its tuning and
    /// takes its new time scale without adding or removing energy; one in
    /// contact takes it at a later update; a bouncing scene's are not bent.
    /// Whether one waits, and whether a tuning still moves. O(fades N),
    /// allocation-free. \[audio-thread\]
    pub(super) fn fades_bend_tick(&mut self, step: f64) -> (bool, bool) {
        let (bend, floor) = (self.bend_now, self.channel_pressure.max(self.mod_wheel));
        let (mut pending, mut moving) = (false, false);
        let sets = [
            (Some(&mut *self.cur), &mut self.steal_fades),
            (self.fading.as_deref_mut(), &mut self.old_steal_fades),
        ];
        for (p, fades) in sets {
            let Some(p) = p else { continue };
            for (f, slot) in fades.iter_mut().enumerate() {
                let Some(fade) = slot.as_mut() else { continue };
                fade.tuning_now = slew(fade.tuning_now, fade.tuning_target, step);
                if p.kit.as_deref().map_or(p.bouncing, |k| k.bouncing) {
                    continue;
                }
                moving |= fade.tuning_now != fade.tuning_target;
                let s = fade.base_scale * 2f64.powf((bend + fade.tuning_now) / 12.0);
                let bent = match p.kit.as_deref_mut() {
                    Some(kit) => match kit.spares.get_mut(f) {
                        Some(st) if st.time_scale() != s => {
                            let at = fade.kit_at();
                            let sc = super::kit::compile_for(&kit.sc, &kit.damped, &kit.levels, at);
                            st.bend_time_scale(sc, s)
                        }
                        _ => continue,
                    },
                    None => {
                        if p.spares.get(f).is_none_or(|st| st.time_scale() == s) {
                            continue;
                        }
                        // pressed: its damper's decay first, and decided
                        // again at its new pitch
                        fade_flush(p, f, fade);
                        let scene = p.scenes.bound(fade.at, fade.on_damped);
                        let bent = p.spares[f].bend_time_scale(scene, s);
                        fade_decide(p, f, fade, floor);
                        bent
                    }
                };
                // Err: a fade that cannot scale time stays put
                if let Ok(false) = bent {
                    pending = true;
                }
            }
        }
        (pending, moving)
    }
}

/// Put what fade `f`'s damper took since its last decision into its spare
/// state of `p` and stop pressing it ([`Instrument::press_flush`]'s rule).
fn fade_flush(p: &mut Prepared, f: usize, fade: &mut StealFade) {
    if let Some(pr) = fade.pressing.take() {
        if pr.g != 1.0 {
            let taken = match p.kit.as_deref_mut() {
                Some(kit) => kit
                    .spares
                    .get_mut(f)
                    .is_some_and(|st| st.scale_objects(pr.g)),
                None => p
                    .spares
                    .get_mut(f)
                    .is_some_and(|st| st.scale_free_state(pr.g)),
            };
            debug_assert!(taken, "a pressed fade is out of contact");
        }
    }
}

/// Decide whether fade `f` of `p` is pressed from now to its next decision
/// ([`Instrument::press_decide`]'s rule): its note's pressure or `floor`
/// (the channel's and the mod wheel's) above 0, not a bouncing scene, its
/// hammer clear of the object (a kit's: no contact of it can close).
pub(super) fn fade_decide(p: &Prepared, f: usize, fade: &mut StealFade, floor: f64) {
    if fade.pressing.is_some() || p.bouncing {
        return;
    }
    let press = fade.pressure.max(floor);
    let clear = || match p.kit.as_deref() {
        Some(kit) => kit
            .spares
            .get(f)
            .is_some_and(|st| st.contacts_clear(kit.sc_for(fade.kit_at()))),
        None => p
            .spares
            .get(f)
            .is_some_and(|st| st.hammer_clear(p.scenes.bound(fade.at, fade.on_damped))),
    };
    if press > 0.0 && clear() {
        let q = (-MAX_PRESSURE_DECAY_PER_S * press / p.rate_hz).exp();
        fade.pressing = Some(Pressing { q, g: 1.0 });
    }
}

/// Energy that decides whether a voice still sounds (reference units), or
/// `None` while the hammer is still on its way (the strike is to come).
fn audible_energy(st: &EngineState, scene: &CompiledScene) -> Option<f64> {
    let proxy = st.energy_proxy(scene);
    if st.in_contact() {
        return Some(proxy);
    }
    let (_, v_phys) = st.hammer_in_flight()?;
    let v_ref = v_phys / st.time_scale();
    if scene.g > 0.0 {
        // Falling hammer: its height above the surface is energy to come.
        let above = (-st.penetration(scene)).max(0.0);
        Some(proxy + scene.m_h * scene.g * above)
    } else if v_ref < 0.0 {
        None
    } else {
        // The hammer flies away for good: only the object sounds.
        Some((proxy - 0.5 * scene.m_h * v_ref * v_ref).max(0.0))
    }
}

/// The lane of the voices that fade out after a swap or a steal (after the
/// voices' own).
pub(super) const FADE_LANE: usize = MAX_VOICES;
/// A voice fading out in a spare state (stolen, choked, ended by All
/// Sound Off or a lowered Polyphony: docs/plugin.md, "Velocity, pitch,
/// voices"), on the instrument's clock: the variant of the scene it plays,
/// and the samples of the fade still to come. The next sample's gain is
/// `left / fade_len`: 1 at the sample of the steal, `1 / fade_len` at the
/// fade's last; a function of the sample alone, not of where the clock's
/// chunks fall. While it fades it follows the pitch bend, its note's
/// tuning and the pressure as a sounding voice does: its note's pitch
/// without them, its tuning, its key and its note's pressure are kept
/// here, and its damper between two decisions
/// ([`Instrument::fades_bend_tick`], [`Instrument::repress_fades`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct StealFade {
    pub(super) at: Variant,
    pub(super) on_damped: bool,
    pub(super) left: usize,
    /// Its note's key (a per-note tuning or pressure of that key still
    /// reaches it).
    pub(super) key: u8,
    /// Time scale of its note without the bend and its tuning.
    pub(super) base_scale: f64,
    /// Its note's tuning now and where it glides \[semitones\].
    pub(super) tuning_now: f64,
    pub(super) tuning_target: f64,
    /// Its note's pressure, 0 .. 1.
    pub(super) pressure: f64,
    /// The damper pressing it since its last decision.
    pub(super) pressing: Option<Pressing>,
}

impl StealFade {
    /// The kit compile it fades on, when its scene is a kit (its note's
    /// hardness level, or the damped one).
    pub(super) fn kit_at(&self) -> super::kit::KitAt {
        super::kit::KitAt::of(self.at, self.on_damped)
    }

    /// The fade of voice `v` starting now (`fade_len` samples).
    pub(super) fn of(v: &Voice, fade_len: usize) -> Self {
        Self {
            at: v.at,
            on_damped: v.on_damped,
            left: fade_len,
            key: v.key,
            base_scale: v.base_scale,
            tuning_now: v.tuning_now,
            tuning_target: v.tuning_target,
            pressure: v.pressure,
            pressing: None,
        }
    }
}

/// The spare a new steal fade takes among the first `n` of `fades` (`n`
/// within 1 ..= [`STEAL_FADES`]): a free one, else the one nearest the
/// end of its fade (that fade is cut: counted in `cut`).
pub(super) fn spare_for_fade(
    fades: &[Option<StealFade>; STEAL_FADES],
    n: usize,
    cut: &mut u64,
) -> usize {
    let fades = &fades[..n.clamp(1, STEAL_FADES)];
    if let Some(f) = fades.iter().position(Option::is_none) {
        return f;
    }
    *cut += 1;
    let left = |f: usize| fades[f].map_or(0, |d| d.left);
    (0..fades.len()).min_by_key(|&f| left(f)).unwrap_or(0)
}

/// [`spare_for_fade`] for voices ended together, loudest first (All Sound
/// Off, a choke of every note, a lowered Polyphony): a free spare, else
/// the one nearest the end of its fade if that fade began before this
/// sample (it is cut: counted in `cut`), else `None`: every spare holds
/// the fade of a louder voice ended at this very sample, and this one is
/// the one to cut.
pub(super) fn spare_for_fade_together(
    fades: &[Option<StealFade>; STEAL_FADES],
    n: usize,
    fade_len: usize,
    cut: &mut u64,
) -> Option<usize> {
    let fades = &fades[..n.clamp(1, STEAL_FADES)];
    if let Some(f) = fades.iter().position(Option::is_none) {
        return Some(f);
    }
    let left = |f: usize| fades[f].map_or(0, |d| d.left);
    let f = (0..fades.len()).min_by_key(|&f| left(f)).unwrap_or(0);
    *cut += 1;
    (left(f) < fade_len).then_some(f)
}
