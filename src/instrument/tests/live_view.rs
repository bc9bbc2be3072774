//! Tests of the live view's probe: it changes no sample and sees every
//! voice's samples and energies.

use super::*;

/// What a test probe keeps of each chunk.
type Seen = std::sync::Arc<std::sync::Mutex<Vec<(usize, u8, u64, Vec<Motion>, Option<f64>)>>>;

struct Recorder(Seen);

impl VoiceProbe for Recorder {
    fn voice_chunk(&mut self, c: &VoiceChunk) {
        self.0
            .lock()
            .unwrap()
            .push((c.voice, c.key, c.start, c.motion.to_vec(), c.energy_j));
    }
}

/// The live view's probe changes no output sample (bit for bit, on every
/// preset, with a chord, a restrike and a release), sees every sample of
/// every sounding voice exactly once, sees each strike's contact, and its
/// energies equal the engine's own `energy` bit for bit; switched off, it
/// sees nothing.
#[test]
fn a_probe_changes_no_sample_and_sees_every_voice_sample() {
    for preset in presets::PRESETS {
        let p = params(preset.name);
        let events = [
            on(10, 60, 0.8),
            on(10, 64, 0.5),
            on(700, 67, 0.6),
            on(3000, 60, 0.9),
            off(5000, 64),
        ];
        let n = 8000;
        let plain = render(&mut instrument(&p), &events, n);
        let seen: Seen = Default::default();
        let mut probed = instrument(&p);
        assert!(probed
            .set_probe(Some(Box::new(Recorder(seen.clone()))))
            .is_none());
        probed.set_probe_on(true);
        let got = render(&mut probed, &events, n);
        assert!(
            plain == got,
            "{}: the probe changed the output",
            preset.name
        );
        let seen = seen.lock().unwrap();
        assert!(!seen.is_empty());
        // per voice: chunks follow each other without gap or overlap
        let mut next: [Option<u64>; MAX_VOICES] = [None; MAX_VOICES];
        let mut contact_keys = std::collections::BTreeSet::new();
        for (v, key, start, m, e) in seen.iter() {
            if let Some(want) = next[*v] {
                assert_eq!(
                    *start, want,
                    "{}: voice {v} skipped or repeated samples",
                    preset.name
                );
            }
            next[*v] = Some(start + m.len() as u64);
            // (none while a strike is played back)
            // (a hammer under a constant force pressed into the contact
            // sits below its rest height: its potential is negative)
            assert!(
                e.is_none_or(|e| e.is_finite() && (e >= 0.0 || probed.cur.bouncing)),
                "{}: energy {e:?}",
                preset.name
            );
            if m.iter().any(|x| x.in_contact) {
                contact_keys.insert(*key);
            }
        }
        // a new note's first chunks are played back (no energy), the later
        // ones have one
        if !probed.cur.key_props.is_empty() && !probed.cur.bouncing {
            assert!(seen.iter().any(|c| c.4.is_none()), "{}", preset.name);
        }
        assert!(seen.iter().any(|c| c.4.is_some()), "{}", preset.name);
        assert!(
            [60, 64, 67].iter().all(|k| contact_keys.contains(k)),
            "{}: a strike's contact was not seen ({contact_keys:?})",
            preset.name
        );
        drop(seen);
        // off: nothing more is recorded
        let before = probed.probe.is_some();
        probed.set_probe_on(false);
        let more: Seen = Default::default();
        probed.set_probe(Some(Box::new(Recorder(more.clone()))));
        render(&mut probed, &[on(0, 72, 0.7)], 2000);
        assert!(before && more.lock().unwrap().is_empty());
    }
}

/// `energy_rt` (the probe's, allocation-free) is `energy` bit for bit, in
/// flight and in a coupled (dense) contact phase.
#[test]
fn energy_rt_equals_energy() {
    for preset in presets::PRESETS {
        let pr = prepare(&params(preset.name).scene, RATE, 0).unwrap();
        let sc = &pr.scenes.scene;
        let mut st = EngineState::new(sc);
        st.reserve_observation();
        let mut checked_contact = false;
        let mut left = 400;
        for _ in 0..2 * RATE as usize {
            st.tick(sc);
            let e = st.energy(sc);
            assert_eq!(e.to_bits(), st.energy_rt(sc).to_bits(), "{}", preset.name);
            checked_contact |= st.in_contact();
            left -= usize::from(checked_contact);
            if left == 0 {
                break;
            }
        }
        assert!(checked_contact, "{}: never in contact", preset.name);
    }
}
