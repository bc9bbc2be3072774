//! The General MIDI names a preset's `real_instrument` key may give: the 128
//! program names of General MIDI Level 1 (bank 0) and the GM1 percussion
//! key names of channel 10 (keys 35 to 81, a soundfont's bank 128), as the
//! MIDI Manufacturers Association's GM1 sound set lists them; and the three
//! brush sounds of the Roland GS brush kit (bank 128 program 40), which
//! General MIDI Level 1 has no name for.

/// The GM1 program names, program 0 (MIDI program change 1) first.
pub const PROGRAMS: [&str; 128] = [
    "Acoustic Grand Piano",
    "Bright Acoustic Piano",
    "Electric Grand Piano",
    "Honky-tonk Piano",
    "Electric Piano 1",
    "Electric Piano 2",
    "Harpsichord",
    "Clavi",
    "Celesta",
    "Glockenspiel",
    "Music Box",
    "Vibraphone",
    "Marimba",
    "Xylophone",
    "Tubular Bells",
    "Dulcimer",
    "Drawbar Organ",
    "Percussive Organ",
    "Rock Organ",
    "Church Organ",
    "Reed Organ",
    "Accordion",
    "Harmonica",
    "Tango Accordion",
    "Acoustic Guitar (nylon)",
    "Acoustic Guitar (steel)",
    "Electric Guitar (jazz)",
    "Electric Guitar (clean)",
    "Electric Guitar (muted)",
    "Overdriven Guitar",
    "Distortion Guitar",
    "Guitar Harmonics",
    "Acoustic Bass",
    "Electric Bass (finger)",
    "Electric Bass (pick)",
    "Fretless Bass",
    "Slap Bass 1",
    "Slap Bass 2",
    "Synth Bass 1",
    "Synth Bass 2",
    "Violin",
    "Viola",
    "Cello",
    "Contrabass",
    "Tremolo Strings",
    "Pizzicato Strings",
    "Orchestral Harp",
    "Timpani",
    "String Ensemble 1",
    "String Ensemble 2",
    "SynthStrings 1",
    "SynthStrings 2",
    "Choir Aahs",
    "Voice Oohs",
    "Synth Voice",
    "Orchestra Hit",
    "Trumpet",
    "Trombone",
    "Tuba",
    "Muted Trumpet",
    "French Horn",
    "Brass Section",
    "SynthBrass 1",
    "SynthBrass 2",
    "Soprano Sax",
    "Alto Sax",
    "Tenor Sax",
    "Baritone Sax",
    "Oboe",
    "English Horn",
    "Bassoon",
    "Clarinet",
    "Piccolo",
    "Flute",
    "Recorder",
    "Pan Flute",
    "Blown Bottle",
    "Shakuhachi",
    "Whistle",
    "Ocarina",
    "Lead 1 (square)",
    "Lead 2 (sawtooth)",
    "Lead 3 (calliope)",
    "Lead 4 (chiff)",
    "Lead 5 (charang)",
    "Lead 6 (voice)",
    "Lead 7 (fifths)",
    "Lead 8 (bass + lead)",
    "Pad 1 (new age)",
    "Pad 2 (warm)",
    "Pad 3 (polysynth)",
    "Pad 4 (choir)",
    "Pad 5 (bowed)",
    "Pad 6 (metallic)",
    "Pad 7 (halo)",
    "Pad 8 (sweep)",
    "FX 1 (rain)",
    "FX 2 (soundtrack)",
    "FX 3 (crystal)",
    "FX 4 (atmosphere)",
    "FX 5 (brightness)",
    "FX 6 (goblins)",
    "FX 7 (echoes)",
    "FX 8 (sci-fi)",
    "Sitar",
    "Banjo",
    "Shamisen",
    "Koto",
    "Kalimba",
    "Bag pipe",
    "Fiddle",
    "Shanai",
    "Tinkle Bell",
    "Agogo",
    "Steel Drums",
    "Woodblock",
    "Taiko Drum",
    "Melodic Tom",
    "Synth Drum",
    "Reverse Cymbal",
    "Guitar Fret Noise",
    "Breath Noise",
    "Seashore",
    "Bird Tweet",
    "Telephone Ring",
    "Helicopter",
    "Applause",
    "Gunshot",
];

/// The first GM1 percussion key.
pub const FIRST_DRUM_KEY: u8 = 35;

/// The GM1 percussion key names, key [`FIRST_DRUM_KEY`] first.
pub const DRUMS: [&str; 47] = [
    "Acoustic Bass Drum",
    "Bass Drum 1",
    "Side Stick",
    "Acoustic Snare",
    "Hand Clap",
    "Electric Snare",
    "Low Floor Tom",
    "Closed Hi Hat",
    "High Floor Tom",
    "Pedal Hi-Hat",
    "Low Tom",
    "Open Hi-Hat",
    "Low-Mid Tom",
    "Hi-Mid Tom",
    "Crash Cymbal 1",
    "High Tom",
    "Ride Cymbal 1",
    "Chinese Cymbal",
    "Ride Bell",
    "Tambourine",
    "Splash Cymbal",
    "Cowbell",
    "Crash Cymbal 2",
    "Vibraslap",
    "Ride Cymbal 2",
    "Hi Bongo",
    "Low Bongo",
    "Mute Hi Conga",
    "Open Hi Conga",
    "Low Conga",
    "High Timbale",
    "Low Timbale",
    "High Agogo",
    "Low Agogo",
    "Cabasa",
    "Maracas",
    "Short Whistle",
    "Long Whistle",
    "Short Guiro",
    "Long Guiro",
    "Claves",
    "Hi Wood Block",
    "Low Wood Block",
    "Mute Cuica",
    "Open Cuica",
    "Mute Triangle",
    "Open Triangle",
];

/// The GS brush kit's program in bank 128.
pub const BRUSH_KIT: u16 = 40;

/// The GS brush kit's own sounds and their keys (the rest of that kit is
/// the standard kit's).
pub const BRUSHES: [(u8, &str); 3] = [(38, "Brush Tap"), (39, "Brush Slap"), (40, "Brush Swirl")];

/// A General MIDI sound: a melodic program or a percussion key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum GmSound {
    /// Program 0-127 of bank 0, played at any key.
    Program(u8),
    /// Percussion key 35-81 of the drum kit (bank 128, program 0),
    /// always played at that key.
    Drum(u8),
    /// One of [`BRUSHES`]: a key of the GS brush kit (bank 128, program
    /// [`BRUSH_KIT`]), always played at that key.
    Brush(u8),
}

/// A name compared loosely: case-insensitive, `-` and runs of spaces
/// taken as one space ("closed hi-hat" is "Closed Hi Hat").
fn loose(name: &str) -> String {
    name.to_lowercase()
        .replace('-', " ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

impl GmSound {
    /// The sound a General MIDI name names (case-insensitive, `-` taken
    /// as a space, runs of spaces as one), or `None`.
    pub fn parse(name: &str) -> Option<Self> {
        let n = loose(name);
        if let Some(p) = PROGRAMS.iter().position(|p| loose(p) == n) {
            return Some(Self::Program(p as u8));
        }
        if let Some(k) = DRUMS.iter().position(|d| loose(d) == n) {
            return Some(Self::Drum(FIRST_DRUM_KEY + k as u8));
        }
        BRUSHES
            .iter()
            .find(|(_, b)| loose(b) == n)
            .map(|&(k, _)| Self::Brush(k))
    }

    /// Its General MIDI name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Program(p) => PROGRAMS[p as usize],
            Self::Drum(k) => DRUMS[(k - FIRST_DRUM_KEY) as usize],
            Self::Brush(k) => BRUSHES
                .iter()
                .find(|(key, _)| *key == k)
                .map_or("Brush", |(_, n)| n),
        }
    }

    /// Whether it is a percussion key (played at its key, never transposed).
    pub fn is_drum(self) -> bool {
        matches!(self, Self::Drum(_) | Self::Brush(_))
    }

    /// The soundfont bank and program that hold it (GM: programs in bank
    /// 0, the standard drum kit in bank 128 program 0, GS's brush kit in
    /// bank 128 program 40).
    pub fn bank_program(self) -> (u16, u16) {
        match self {
            Self::Program(p) => (0, u16::from(p)),
            Self::Drum(_) => (128, 0),
            Self::Brush(_) => (128, BRUSH_KIT),
        }
    }

    /// The key it is played at: the percussion key itself, else `key`.
    pub fn key_for(self, key: u8) -> u8 {
        match self {
            Self::Program(_) => key,
            Self::Drum(k) | Self::Brush(k) => k,
        }
    }

    /// How the report names it: the GM name with its program or key.
    pub fn label(self) -> String {
        match self {
            Self::Program(p) => format!("{} (program {})", self.name(), p),
            Self::Drum(k) => format!("{} (kit key {})", self.name(), k),
            Self::Brush(k) => format!("{} (brush kit key {})", self.name(), k),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_parses_back_and_no_name_is_both() {
        for (p, name) in PROGRAMS.iter().enumerate() {
            assert_eq!(GmSound::parse(name), Some(GmSound::Program(p as u8)));
            assert_eq!(GmSound::Program(p as u8).name(), *name);
        }
        for (k, name) in DRUMS.iter().enumerate() {
            let key = FIRST_DRUM_KEY + k as u8;
            assert_eq!(GmSound::parse(name), Some(GmSound::Drum(key)));
            assert!(!PROGRAMS.iter().any(|p| loose(p) == loose(name)));
        }
        assert_eq!(FIRST_DRUM_KEY as usize + DRUMS.len() - 1, 81);
        assert_eq!(GmSound::parse("Acoustic Snare"), Some(GmSound::Drum(38)));
        assert_eq!(GmSound::parse("low floor tom"), Some(GmSound::Drum(41)));
        assert_eq!(GmSound::parse("Hi Wood Block"), Some(GmSound::Drum(76)));
        assert_eq!(GmSound::parse("MARIMBA"), Some(GmSound::Program(12)));
        assert_eq!(GmSound::parse("closed hi-hat"), Some(GmSound::Drum(42)));
        assert_eq!(GmSound::parse("Marimbaphone"), None);
        for (k, name) in BRUSHES {
            let s = GmSound::parse(name).expect("a brush");
            assert_eq!((s, s.name(), s.key_for(60)), (GmSound::Brush(k), name, k));
            assert_eq!(s.bank_program(), (128, BRUSH_KIT));
            assert!(s.is_drum());
            assert!(!PROGRAMS
                .iter()
                .chain(&DRUMS)
                .any(|p| loose(p) == loose(name)));
        }
        assert_eq!(GmSound::parse("brush swirl"), Some(GmSound::Brush(40)));
    }
}
