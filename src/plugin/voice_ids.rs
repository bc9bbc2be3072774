//! The host's voice ids (CLAP note ids) and polyphonic modulation
//! (docs/plugin.md, "Polyphonic modulation").
//!
//! The instrument has one voice per key, so a voice id names a key: a
//! note-on records the id of its key, a polyphonic modulation finds its
//! key by the id, and a voice that stops sounding (silence, stealing, a
//! new note on its key, a scene swap that fades it) is reported to the host
//! as terminated so that it can end that voice's modulation. The plugin
//! does not support overlapping voices on one key (the instrument strikes
//! the ringing voice again), and says so to the host.
//!
//! Plain data, fixed size: the audio thread owns it; no allocation.

use crate::instrument::MAX_VOICES;

/// Keys of MIDI.
const KEYS: usize = 128;

/// One key's host voice: its id and the channel of its note.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HostVoice {
    /// The host's id of the note (CLAP note id).
    pub id: i32,
    /// The note's channel.
    pub channel: u8,
    /// The note's key.
    pub key: u8,
}

/// The parameters a host may modulate per voice, by polyphonic
/// modulation id (`params::POLY_*`): Hardness, Strike position, Damper.
pub const MODULATED: usize = 3;

/// Voice ids by key, the modulations of each, and the voices that ended
/// since the host was last told.
#[derive(Debug, Clone)]
pub struct VoiceIds {
    ids: [Option<HostVoice>; KEYS],
    /// Normalized offset of each key's modulation of each parameter.
    offsets: [[f32; KEYS]; MODULATED],
    /// Voices that ended, to report (at most one per key and block, plus
    /// one per note-on that replaced an id: bounded by `ENDED_CAP`).
    ended: [HostVoice; ENDED_CAP],
    ended_len: usize,
}

/// Room for ended voices in one block (a note-on on a key whose voice had
/// another id ends that id: a block of more note-ons than this reports the
/// rest at the block's end, as stopped voices).
const ENDED_CAP: usize = 2 * KEYS;

impl Default for VoiceIds {
    fn default() -> Self {
        Self {
            ids: [None; KEYS],
            offsets: [[0.0; KEYS]; MODULATED],
            ended: [HostVoice {
                id: 0,
                channel: 0,
                key: 0,
            }; ENDED_CAP],
            ended_len: 0,
        }
    }
}

impl VoiceIds {
    fn end(&mut self, v: HostVoice) {
        if self.ended_len < ENDED_CAP {
            self.ended[self.ended_len] = v;
            self.ended_len += 1;
        }
    }

    /// A note-on of `key` with the host's `id` (if it gave one): the key's
    /// voice now belongs to that id; an earlier id of the key has ended (the
    /// voice is struck again as a new note), and the new note starts
    /// without modulation.
    pub fn note_on(&mut self, key: u8, id: Option<i32>, channel: u8) {
        let k = usize::from(key) & (KEYS - 1);
        if let Some(old) = self.ids[k] {
            if Some(old.id) != id {
                self.end(old);
            }
        }
        self.ids[k] = id.map(|id| HostVoice { id, channel, key });
        self.offsets.iter_mut().for_each(|o| o[k] = 0.0);
    }

    /// The key whose voice has the host's `id`.
    pub fn key_of(&self, id: i32) -> Option<u8> {
        self.ids
            .iter()
            .flatten()
            .find(|v| v.id == id)
            .map(|v| v.key)
    }

    /// A polyphonic modulation by `offset` (normalized) of parameter
    /// `poly` (a polyphonic modulation id below [`MODULATED`]) on the voice
    /// with `id`: the key to give `event` (`None`: an id that is not
    /// sounding, or a parameter not modulated per voice).
    pub fn modulate(&mut self, id: i32, poly: u32, offset: f32) -> Option<u8> {
        let m = usize::try_from(poly).ok().filter(|&m| m < MODULATED)?;
        let key = self.key_of(id)?;
        self.offsets[m][usize::from(key)] = offset;
        Some(key)
    }

    /// The modulated voices of parameter `poly` and their offsets (to
    /// take again when the parameter itself moves).
    pub fn modulated(&self, poly: u32) -> impl Iterator<Item = (u8, f32)> + '_ {
        let m = usize::try_from(poly).unwrap_or(MODULATED);
        self.ids.iter().flatten().filter_map(move |v| {
            let off = *self.offsets.get(m)?.get(usize::from(v.key))?;
            (off != 0.0).then_some((v.key, off))
        })
    }

    /// After a block: the voices whose keys no longer sound have ended.
    pub fn block_done(&mut self, sounding: &[Option<u8>; MAX_VOICES]) {
        // which keys sound, once (not a search of the voices per key)
        let mut on = [false; KEYS];
        for &key in sounding.iter().flatten() {
            on[usize::from(key) & (KEYS - 1)] = true;
        }
        for k in 0..KEYS {
            let Some(v) = self.ids[k] else { continue };
            if !on[usize::from(v.key) & (KEYS - 1)] {
                self.end(v);
                self.ids[k] = None;
                self.offsets.iter_mut().for_each(|o| o[k] = 0.0);
            }
        }
    }

    /// The voices that ended since the last call (to report to the host).
    pub fn take_ended(&mut self) -> impl Iterator<Item = HostVoice> + '_ {
        let n = std::mem::take(&mut self.ended_len);
        self.ended[..n].iter().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sounding(keys: &[u8]) -> [Option<u8>; MAX_VOICES] {
        std::array::from_fn(|i| keys.get(i).copied())
    }

    #[test]
    fn ids_find_keys_and_end_when_the_voice_stops_or_is_replaced() {
        let mut ids = VoiceIds::default();
        ids.note_on(60, Some(7), 0);
        ids.note_on(64, Some(8), 1);
        ids.note_on(67, None, 0);
        assert_eq!(ids.key_of(7), Some(60));
        assert_eq!(ids.key_of(8), Some(64));
        assert_eq!(ids.key_of(9), None);
        // a modulation of an unknown id, or of a parameter not modulated
        // per voice, is nothing
        assert_eq!(ids.modulate(9, 0, 0.1), None);
        assert_eq!(ids.modulate(8, MODULATED as u32, 0.1), None);
        assert_eq!(ids.modulate(8, 0, 0.1), Some(64));
        assert_eq!(ids.modulate(8, 2, -0.3), Some(64));
        assert_eq!(ids.modulated(0).collect::<Vec<_>>(), [(64, 0.1)]);
        assert_eq!(ids.modulated(2).collect::<Vec<_>>(), [(64, -0.3)]);
        assert_eq!(ids.modulated(1).count(), 0);
        ids.block_done(&sounding(&[60, 64, 67]));
        assert_eq!(ids.take_ended().count(), 0);
        // a new note on key 60 with another id ends id 7
        ids.note_on(60, Some(11), 0);
        let ended: Vec<_> = ids.take_ended().collect();
        assert_eq!(
            ended,
            [HostVoice {
                id: 7,
                channel: 0,
                key: 60
            }]
        );
        // key 64 falls silent: id 8 ends, and its modulations are forgotten
        ids.block_done(&sounding(&[60]));
        let ended: Vec<_> = ids.take_ended().map(|v| v.id).collect();
        assert_eq!(ended, [8]);
        assert_eq!(ids.key_of(8), None);
        assert_eq!(ids.modulated(0).count() + ids.modulated(2).count(), 0);
        // a new note on a key starts unmodulated
        assert_eq!(ids.modulate(11, 1, 0.2), Some(60));
        ids.note_on(60, Some(12), 0);
        assert_eq!(ids.modulated(1).count(), 0);
        ids.block_done(&sounding(&[]));
        assert_eq!(ids.take_ended().map(|v| v.id).collect::<Vec<_>>(), [11, 12]);
        assert_eq!(ids.take_ended().count(), 0);
    }
}
