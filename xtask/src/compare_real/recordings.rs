//! Which recordings are played: the key each is played at (within an
//! octave of its recording), another recording of an instrument for the
//! scale of "close", the confusion set and the scale pairs, every
//! recording played once, and what FluidR3 offers for bells and plates.

use super::*;

/// The keys nearest `key` first (`key`, then one below, one above, ...).
fn keys_around(key: u8) -> impl Iterator<Item = u8> {
    let k = i32::from(key);
    std::iter::once(k)
        .chain((1..128).flat_map(move |d| [k - d, k + d]))
        .filter(|k| (0..128).contains(k))
        .map(|k| k as u8)
}

/// Whether `s` played at `key` is transposed at most
/// [`MAX_TRANSPOSE_CENTS`] (a percussion key always is: it plays at its
/// own key).
fn near_recorded(sf: &SoundFont, s: GmSound, key: u8) -> bool {
    let (bank, program) = s.bank_program();
    sf.transposition(bank, program, s.key_for(key), VELOCITY)
        .is_some_and(|c| c <= MAX_TRANSPOSE_CENTS + 1e-9)
}

/// The key `s` is played at to stand for `key`: its percussion key; else
/// `key` itself when that is within an octave of the recording, otherwise
/// the nearest key that is ([`MAX_TRANSPOSE_CENTS`]); `key` when none is.
pub(super) fn playable_key(sf: &SoundFont, s: GmSound, key: u8) -> u8 {
    if s.is_drum() {
        return s.key_for(key);
    }
    keys_around(key)
        .find(|&k| near_recorded(sf, s, k))
        .unwrap_or(key)
}

/// The common key of two recordings compared with each other: the
/// nearest key to `key` at which both are within an octave of their
/// recordings ([`MAX_TRANSPOSE_CENTS`]), `key` when there is none.
fn common_key(sf: &SoundFont, a: GmSound, b: GmSound, key: u8) -> u8 {
    keys_around(key)
        .find(|&k| near_recorded(sf, a, k) && near_recorded(sf, b, k))
        .unwrap_or(key)
}

/// Another recording of `s` at `key`, for the scale of "close": for a
/// pitched instrument the samples of the nearest other key range of the
/// same preset, played at `key` (transposed at most an octave,
/// [`MAX_TRANSPOSE_CENTS`]); for a percussion key the same key of the
/// first other kit ([`OTHER_KITS`]) whose samples differ (a brush kit's
/// own sounds have no other kit). `None` when the soundfont has no such
/// recording.
pub(super) fn another_recording(sf: &SoundFont, s: GmSound, key: u8) -> Option<KeyRegion> {
    let (bank, program) = s.bank_program();
    let key = s.key_for(key);
    let own = sf.key_region(bank, program, key, VELOCITY).ok()?;
    let names = |r: &KeyRegion| -> Vec<String> { r.zones.iter().map(|z| z.name.clone()).collect() };
    let own_names = names(&own);
    let differs = |r: &KeyRegion| names(r).iter().all(|n| !own_names.contains(n));
    if let GmSound::Brush(_) = s {
        return None;
    }
    if s.is_drum() {
        return OTHER_KITS.iter().find_map(|&kit| {
            sf.key_region(bank, kit, key, VELOCITY)
                .ok()
                .filter(|r| differs(r))
        });
    }
    keys_around(key)
        .skip(1)
        .take_while(|&k| k.abs_diff(key) <= 12)
        .find_map(|k| {
            sf.key_region_played_at(bank, program, k, key, VELOCITY)
                .ok()
                .filter(|r| {
                    differs(r)
                        && r.zones
                            .iter()
                            .all(|z| z.cents.abs() <= MAX_TRANSPOSE_CENTS + 1e-9)
                })
        })
}

/// What FluidR3 offers for the presets that name no recording: preset
/// headers whose names say bell, chime, gong, plate, cymbal, triangle,
/// agogo or steel (not the steel-string guitar), each with the samples its zones play at key 72, and the
/// standard kit's metal keys with theirs.
pub(super) fn bells_and_plates(sf: &SoundFont) -> String {
    const WORDS: [&str; 8] = [
        "bell", "chime", "gong", "plate", "cymbal", "triangle", "agogo", "steel",
    ];
    let samples = |bank: u16, program: u16, key: u8| -> String {
        match sf.key_region(bank, program, key, VELOCITY) {
            Ok(r) => {
                let mut names: Vec<String> = Vec::new();
                for z in &r.zones {
                    let n = format!("\"{}\"", z.name);
                    if !names.contains(&n) {
                        names.push(n);
                    }
                }
                names.join(", ")
            }
            Err(_) => "no zone".into(),
        }
    };
    let mut s = String::new();
    for h in sf.presets() {
        let low = h.name.to_lowercase();
        if h.bank < 128 && WORDS.iter().any(|w| low.contains(w)) && !low.contains("guitar") {
            let _ = writeln!(
                s,
                "- bank {} program {} \"{}\": key 72 plays {}",
                h.bank,
                h.program,
                h.name,
                samples(h.bank, h.program, 72)
            );
        }
    }
    for key in [49u8, 51, 52, 53, 55, 56, 57, 59, 80, 81] {
        let _ = writeln!(
            s,
            "- kit (bank 128 program 0) key {key} {}: plays {}",
            GmSound::Drum(key).name(),
            samples(128, 0, key)
        );
    }
    s
}

/// The confusion set: every instrument a preset names, then
/// [`CONFUSION_EXTRA`], each once.
pub(super) fn confusion_set(all: &[PresetFile]) -> Vec<GmSound> {
    let mut set: Vec<GmSound> = Vec::new();
    for p in all {
        if let Ok(Some(s)) = p.real {
            if !set.contains(&s) {
                set.push(s);
            }
        }
    }
    for n in CONFUSION_EXTRA {
        let s = GmSound::parse(n).expect("a GM name");
        if !set.contains(&s) {
            set.push(s);
        }
    }
    set
}

/// The key each recording of the set is played at, for each compared
/// preset's key; and the recordings that takes, each once.
pub(super) fn recording_keys(
    sf: &SoundFont,
    compared: &[(&PresetFile, GmSound)],
    set: &[GmSound],
) -> (BTreeMap<RecordingKey, u8>, Vec<RecordingKey>) {
    let mut keys: BTreeMap<RecordingKey, u8> = BTreeMap::new();
    let mut wanted: Vec<RecordingKey> = Vec::new();
    for (p, _) in compared {
        for &o in set {
            let k = playable_key(sf, o, p.key);
            keys.insert((o, p.key), k);
            if !wanted.contains(&(o, k)) {
                wanted.push((o, k));
            }
        }
    }
    (keys, wanted)
}

/// The [`SCALE_PAIRS`] with the key both are played at (the first's
/// preset's key, or middle C), their recordings added to `wanted`.
pub(super) fn scale_pairs(
    sf: &SoundFont,
    all: &[PresetFile],
    wanted: &mut Vec<RecordingKey>,
) -> Vec<(GmSound, GmSound, u8)> {
    let key_of = |s: GmSound| -> u8 {
        all.iter()
            .find(|p| matches!(p.real, Ok(Some(x)) if x == s))
            .map_or(60, |p| p.key)
    };
    let pairs: Vec<(GmSound, GmSound, u8)> = SCALE_PAIRS
        .iter()
        .map(|(x, y)| {
            let (x, y) = (
                GmSound::parse(x).expect("GM"),
                GmSound::parse(y).expect("GM"),
            );
            (x, y, common_key(sf, x, y, key_of(x)))
        })
        .collect();
    for &(x, y, k) in &pairs {
        for s in [x, y] {
            if !wanted.contains(&(s, s.key_for(k))) {
                wanted.push((s, s.key_for(k)));
            }
        }
    }
    pairs
}

/// The same instruments, another recording each, at the first preset's
/// key.
pub(super) fn other_recordings(
    sf: &SoundFont,
    compared: &[(&PresetFile, GmSound)],
) -> Vec<(GmSound, u8, Option<Played>)> {
    let mut own_sounds: Vec<(GmSound, u8)> = Vec::new();
    for (p, s) in compared {
        if !own_sounds.iter().any(|(x, _)| x == s) {
            own_sounds.push((*s, playable_key(sf, *s, p.key)));
        }
    }
    own_sounds
        .par_iter()
        .map(|&(s, k)| (s, k, another_recording(sf, s, k).map(Recording::new)))
        .collect()
}

/// Every recording of `wanted`, played.
pub(super) fn play_recordings(
    sf: &SoundFont,
    wanted: &[RecordingKey],
) -> BTreeMap<RecordingKey, std::result::Result<Recording, String>> {
    wanted
        .par_iter()
        .map(|&(s, key)| {
            let (bank, program) = s.bank_program();
            let r = sf
                .key_region(bank, program, key, VELOCITY)
                .map_err(|e| format!("{e:#}"))
                .and_then(Recording::new);
            ((s, key), r)
        })
        .collect()
}
