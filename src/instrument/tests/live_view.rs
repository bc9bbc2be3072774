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
/// every sounding voice exactly once, sees each strike's contact, gives no
/// energy while a stored strike is played back and one after it, and its
/// energies equal the engine's own `energy` bit for bit; switched off, it
/// sees nothing.
#[test]
fn a_probe_changes_no_sample_and_sees_every_voice_sample() {
    for preset in presets::PRESETS {
        let p = params(preset.name);
        let mut plain_inst = instrument(&p);
        // a chord on the root, its third and fifth (a kit's pieces at 60,
        // 64 and 67): far above a low root a mallet's contact can be
        // shorter than a sample, which no sample shows
        let r = if plain_inst.cur.kit.is_some() {
            60
        } else {
            plain_inst.cur.root_note.round().clamp(0.0, 120.0) as u8
        };
        let keys = [r, r + 4, r + 7];
        let events = [
            on(10, keys[0], 0.8),
            on(10, keys[1], 0.5),
            on(700, keys[2], 0.6),
            on(3000, keys[0], 0.9),
            off(5000, keys[1]),
        ];
        let n = 8000;
        let plain = render(&mut plain_inst, &events, n);
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
        let replays = !probed.cur.key_props.is_empty() && !probed.cur.bouncing;
        for (v, key, start, m, e) in seen.iter() {
            if let Some(want) = next[*v] {
                assert_eq!(
                    *start, want,
                    "{}: voice {v} skipped or repeated samples",
                    preset.name
                );
            } else if replays {
                // a new note's first chunk: played back (no energy) while
                // its stored strike outlasts the chunk, with one after it
                let stored = probed.cur.key_props[usize::from(*key)]
                    .stored_strike()
                    .map_or(0, |s| s.len());
                if stored > m.len() {
                    assert!(e.is_none(), "{}: key {key}", preset.name);
                } else if stored < m.len() {
                    assert!(e.is_some(), "{}: key {key}", preset.name);
                }
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
        // the three notes from rest were played back
        if replays {
            assert!(probed.stats.strikes_replayed >= 3, "{}", preset.name);
        }
        assert!(seen.iter().any(|c| c.4.is_some()), "{}", preset.name);
        assert!(
            keys.iter().all(|k| contact_keys.contains(k)),
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

/// What the path test's probe keeps: (voice, chunk start, its length,
/// the path position at its end).
type PathSeen = std::sync::Arc<std::sync::Mutex<Vec<(usize, u64, usize, Option<f64>)>>>;

struct PathRecorder(PathSeen);

impl VoiceProbe for PathRecorder {
    fn voice_chunk(&mut self, c: &VoiceChunk) {
        self.0
            .lock()
            .unwrap()
            .push((c.voice, c.start, c.motion.len(), c.path_m));
    }
}

/// A driven voice tells the live view where it is on its path (the
/// editor's path view): at every chunk's end the path's start plus the
/// note's speed along it (the scene's at velocity 100, as
/// `drive_speed_m_per_s` maps it) times the time since its note-on, at
/// two keys an octave apart (the speed along the path is physical: the
/// pitch does not move it); a struck preset's chunks say no path.
#[test]
fn a_driven_voice_reports_its_path_position() {
    for preset in presets::PRESETS {
        let scene = base(preset.name);
        let p = params(preset.name);
        let seen: PathSeen = Default::default();
        let mut inst = instrument(&p);
        inst.set_probe(Some(Box::new(PathRecorder(seen.clone()))));
        inst.set_probe_on(true);
        let (t_on, n) = (100, 12_000);
        render(
            &mut inst,
            &[on(t_on, 60, 100.0 / 127.0), on(t_on, 72, 100.0 / 127.0)],
            n,
        );
        let seen = seen.lock().unwrap();
        let Some(d) = &scene.drive else {
            assert!(seen.iter().all(|c| c.3.is_none()), "{}", preset.name);
            continue;
        };
        let speed = drive_speed_m_per_s(d.speed_m_per_s, impact_speed_m_per_s(100.0 / 127.0));
        let mut worst = 0.0_f64;
        for &(v, start, len, path) in seen.iter() {
            let end = start + len as u64 - t_on as u64;
            let want = d.start_m + speed * end as f64 / RATE;
            let got = path.unwrap_or_else(|| panic!("{}: voice {v} says no path", preset.name));
            worst = worst.max((got - want).abs());
        }
        println!(
            "{}: {} chunks, path within {worst:.1e} m of start + speed x time ({speed} m/s)",
            preset.name,
            seen.len()
        );
        assert!(seen.len() > 10);
        assert!(worst < 1e-12, "{}: path off by {worst:e} m", preset.name);
    }
}
