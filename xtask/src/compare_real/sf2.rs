//! The recordings: the raw sample data of a SoundFont 2 file's key regions
//! (SoundFont 2.04 specification, E-mu Systems / Creative Technology),
//! played back as a sampler plays them, without the synthesizer's
//! envelopes, filters, effects or loops.
//!
//! The file is parsed by the `rustysynth` crate (its `SoundFont` type only,
//! never its synthesizer): it resolves every preset's and instrument's zones
//! with their global zones and generators. From there this module picks the
//! zones that sound for a key and velocity and reads their 16-bit samples.

use super::analysis::resample;
use anyhow::{anyhow, bail, Context, Result};
use rustysynth::{InstrumentRegion, LoopMode, PresetRegion};
use std::path::Path;

/// The MIDI velocity whose zones are taken (soundfonts switch samples by
/// velocity; 100 is a firm mezzo-forte stroke).
pub const VELOCITY: u8 = 100;

/// A parsed SoundFont 2 file.
pub struct SoundFont {
    sf: rustysynth::SoundFont,
}

/// One sample zone that sounds for a key: its raw data and how a sampler
/// transposes it.
#[derive(Debug, Clone)]
pub struct ZoneSample {
    /// The sample header's name.
    pub name: String,
    /// The sample's own rate \[Hz\].
    pub rate_hz: f64,
    /// The key at which the sample plays at its recorded pitch (the
    /// zone's overridingRootKey generator, else the sample's original
    /// pitch).
    pub root_key: i32,
    /// Transposition at the played key \[cents\]: scaleTuning x (key -
    /// root key) + 100 coarseTune + fineTune + the sample's pitch
    /// correction, preset and instrument generators added (SoundFont 2.04,
    /// section 8.1.3).
    pub cents: f64,
    /// Gain of the zone, from its initialAttenuation (preset plus
    /// instrument) \[linear\].
    pub gain: f64,
    /// Loop start and end (samples from the start) when the zone loops.
    pub looped: Option<(usize, usize)>,
    /// Stereo role: 1 mono, 2 right, 4 left (SoundFont sample types).
    pub sample_type: i32,
    /// The samples (16-bit values over 32768), sample start to end.
    pub data: Vec<f64>,
}

impl ZoneSample {
    /// The sample played at its key and at `rate_hz`: read at 2^(cents/1200)
    /// times its own rate, band-limited ([`resample`]).
    pub fn play(&self, rate_hz: f64) -> Result<Vec<f64>, String> {
        let step = 2f64.powf(self.cents / 1200.0) * self.rate_hz / rate_hz;
        resample(&self.data, step)
    }

    /// Length of the raw sample \[s\].
    pub fn seconds(&self) -> f64 {
        self.data.len() as f64 / self.rate_hz
    }

    /// Which channel of a stereo pair it is.
    pub fn channel(&self) -> &'static str {
        match self.sample_type & 0x7 {
            2 => "right",
            4 => "left",
            _ => "mono",
        }
    }
}

/// The zones that sound for one key and velocity of one preset.
#[derive(Debug, Clone)]
pub struct KeyRegion {
    /// The soundfont preset's name.
    pub preset_name: String,
    /// Bank.
    pub bank: u16,
    /// Program.
    pub program: u16,
    /// The key played.
    pub key: u8,
    /// The velocity played.
    pub velocity: u8,
    /// The zones, in the file's order.
    pub zones: Vec<ZoneSample>,
}

impl KeyRegion {
    /// What a sampler plays for the key (no envelope, filter, effect or
    /// loop): every zone played at `rate_hz` ([`ZoneSample::play`]), times
    /// its gain, summed and divided by the number of zones (a stereo
    /// pair's left and right are mixed to mono).
    pub fn play(&self, rate_hz: f64) -> Result<Vec<f64>, String> {
        let played: Vec<Vec<f64>> = self
            .zones
            .iter()
            .map(|z| z.play(rate_hz))
            .collect::<Result<_, _>>()?;
        let n = played.iter().map(Vec::len).max().unwrap_or(0);
        let mut out = vec![0.0; n];
        let k = self.zones.len().max(1) as f64;
        for (z, p) in self.zones.iter().zip(&played) {
            for (o, x) in out.iter_mut().zip(p) {
                *o += z.gain * x / k;
            }
        }
        Ok(out)
    }

    /// The band limit of the played sound \[Hz\]: the lowest zone's
    /// Nyquist frequency after its transposition.
    pub fn band_limit_hz(&self) -> f64 {
        self.zones
            .iter()
            .map(|z| 0.5 * z.rate_hz * 2f64.powf(z.cents / 1200.0))
            .fold(f64::INFINITY, f64::min)
    }
}

/// A preset header: bank, program, name.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct PresetHeader {
    /// Bank.
    pub bank: u16,
    /// Program.
    pub program: u16,
    /// Name.
    pub name: String,
}

impl SoundFont {
    /// Parse the file at `path`.
    pub fn open(path: &Path) -> Result<Self> {
        let f = std::fs::File::open(path)
            .with_context(|| format!("cannot open soundfont {}", path.display()))?;
        Self::read(&mut std::io::BufReader::with_capacity(1 << 20, f))
            .with_context(|| format!("soundfont {}", path.display()))
    }

    /// Parse a SoundFont 2 file from a reader.
    pub fn read(r: &mut impl std::io::Read) -> Result<Self> {
        let sf = rustysynth::SoundFont::new(r).map_err(|e| anyhow!("{e:?}"))?;
        if sf.get_bits_per_sample() != 16 {
            bail!("{}-bit samples: only 16-bit", sf.get_bits_per_sample());
        }
        Ok(Self { sf })
    }

    /// Every preset header, sorted by bank and program.
    pub fn presets(&self) -> Vec<PresetHeader> {
        let mut v: Vec<PresetHeader> = self
            .sf
            .get_presets()
            .iter()
            .map(|p| PresetHeader {
                bank: p.get_bank_number() as u16,
                program: p.get_patch_number() as u16,
                name: p.get_name().to_string(),
            })
            .collect();
        v.sort();
        v
    }

    /// The zones of preset `bank`/`program` that sound when `key` is played
    /// at `velocity`: every preset zone whose key and velocity ranges hold
    /// them, and in each of their instruments every zone whose ranges hold
    /// them (SoundFont 2.04, section 9.6: all such zones play together).
    pub fn key_region(&self, bank: u16, program: u16, key: u8, velocity: u8) -> Result<KeyRegion> {
        self.key_region_played_at(bank, program, key, key, velocity)
    }

    /// The zones that sound for `source_key` at `velocity`, as a sampler
    /// would play them at `key` ([`ZoneSample::cents`] at `key`): another
    /// recording of the instrument, the samples of a neighbouring key
    /// range, heard at the same pitch.
    pub fn key_region_played_at(
        &self,
        bank: u16,
        program: u16,
        source_key: u8,
        key: u8,
        velocity: u8,
    ) -> Result<KeyRegion> {
        let preset = self
            .sf
            .get_presets()
            .iter()
            .find(|p| {
                p.get_bank_number() == i32::from(bank) && p.get_patch_number() == i32::from(program)
            })
            .ok_or_else(|| anyhow!("no preset bank {bank} program {program} in the soundfont"))?;
        let (k, v) = (i32::from(source_key), i32::from(velocity));
        let mut zones = Vec::new();
        for pr in preset.get_regions().iter().filter(|r| r.contains(k, v)) {
            let inst = &self.sf.get_instruments()[pr.get_instrument_id()];
            for ir in inst.get_regions().iter().filter(|r| r.contains(k, v)) {
                zones.push(self.zone(pr, ir, key)?);
            }
        }
        if zones.is_empty() {
            bail!(
                "preset {:?} (bank {bank} program {program}) has no zone for key {source_key} velocity {velocity}",
                preset.get_name()
            );
        }
        Ok(KeyRegion {
            preset_name: preset.get_name().to_string(),
            bank,
            program,
            key,
            velocity,
            zones,
        })
    }

    /// The largest transposition \[cents\] of the zones that sound for
    /// `key` at `velocity` ([`ZoneSample::cents`]), without reading their
    /// samples; `None` when no zone sounds.
    pub fn transposition(&self, bank: u16, program: u16, key: u8, velocity: u8) -> Option<f64> {
        let preset = self.sf.get_presets().iter().find(|p| {
            p.get_bank_number() == i32::from(bank) && p.get_patch_number() == i32::from(program)
        })?;
        let (k, v) = (i32::from(key), i32::from(velocity));
        let mut worst: Option<f64> = None;
        for pr in preset.get_regions().iter().filter(|r| r.contains(k, v)) {
            let inst = &self.sf.get_instruments()[pr.get_instrument_id()];
            for ir in inst.get_regions().iter().filter(|r| r.contains(k, v)) {
                let c = zone_cents(pr, ir, key).abs();
                worst = Some(worst.map_or(c, |w: f64| w.max(c)));
            }
        }
        worst
    }

    fn zone(&self, pr: &PresetRegion, ir: &InstrumentRegion, key: u8) -> Result<ZoneSample> {
        let header = &self.sf.get_sample_headers()[ir.get_sample_id()];
        let (start, end) = (ir.get_sample_start(), ir.get_sample_end());
        let wave = self.sf.get_wave_data();
        if start < 0 || end <= start || end as usize > wave.len() {
            bail!("sample {:?}: bad range {start}..{end}", header.get_name());
        }
        let data: Vec<f64> = wave[start as usize..end as usize]
            .iter()
            .map(|&s| f64::from(s) / 32768.0)
            .collect();
        let root_key = ir.get_root_key();
        let cents = zone_cents(pr, ir, key);
        let att_db = f64::from(pr.get_initial_attenuation() + ir.get_initial_attenuation());
        let looped = (ir.get_sample_modes() != LoopMode::NoLoop).then(|| {
            (
                (ir.get_sample_start_loop() - start).max(0) as usize,
                (ir.get_sample_end_loop() - start).max(0) as usize,
            )
        });
        Ok(ZoneSample {
            name: header.get_name().to_string(),
            rate_hz: f64::from(header.get_sample_rate()),
            root_key,
            cents,
            gain: 10f64.powf(-att_db / 20.0),
            looped,
            sample_type: header.get_sample_type(),
            data,
        })
    }
}

/// The transposition of a zone played at `key` \[cents\]: scaleTuning x
/// (key - root key) + 100 coarseTune + fineTune, the preset's generators
/// added to the instrument's (SoundFont 2.04, sections 8.1.3 and 9.4);
/// `rustysynth`'s instrument fine tune includes the sample's pitch
/// correction.
fn zone_cents(pr: &PresetRegion, ir: &InstrumentRegion, key: u8) -> f64 {
    let scale = f64::from(pr.get_scale_tuning() + ir.get_scale_tuning());
    scale * (f64::from(key) - f64::from(ir.get_root_key()))
        + 100.0 * f64::from(pr.get_coarse_tune() + ir.get_coarse_tune())
        + f64::from(pr.get_fine_tune() + ir.get_fine_tune())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A RIFF chunk: id, little-endian size, data, a pad byte if odd.
    fn chunk(id: &[u8; 4], data: &[u8]) -> Vec<u8> {
        let mut v = id.to_vec();
        v.extend_from_slice(&(data.len() as u32).to_le_bytes());
        v.extend_from_slice(data);
        if data.len() % 2 == 1 {
            v.push(0);
        }
        v
    }

    fn list(kind: &[u8; 4], chunks: &[Vec<u8>]) -> Vec<u8> {
        let mut d = kind.to_vec();
        for c in chunks {
            d.extend_from_slice(c);
        }
        chunk(b"LIST", &d)
    }

    fn name20(s: &str) -> Vec<u8> {
        let mut v = s.as_bytes().to_vec();
        v.resize(20, 0);
        v
    }

    fn gens(list: &[(u16, u16)]) -> Vec<u8> {
        list.iter()
            .flat_map(|(op, amt)| [op.to_le_bytes(), amt.to_le_bytes()].concat())
            .collect()
    }

    fn bags(starts: &[u16]) -> Vec<u8> {
        starts
            .iter()
            .flat_map(|g| [g.to_le_bytes(), 0u16.to_le_bytes()].concat())
            .collect()
    }

    #[allow(clippy::too_many_arguments)]
    fn shdr(
        name: &str,
        start: u32,
        end: u32,
        rate: u32,
        pitch: u8,
        corr: i8,
        kind: u16,
    ) -> Vec<u8> {
        let mut v = name20(name);
        for x in [start, end, start, end, rate] {
            v.extend_from_slice(&x.to_le_bytes());
        }
        v.push(pitch);
        v.push(corr as u8);
        v.extend_from_slice(&0u16.to_le_bytes());
        v.extend_from_slice(&kind.to_le_bytes());
        v
    }

    /// The generator numbers used (SoundFont 2.04, section 8.1.2).
    const FINE_TUNE: u16 = 52;
    const INSTRUMENT: u16 = 41;
    const KEY_RANGE: u16 = 43;
    const OVERRIDING_ROOT_KEY: u16 = 58;
    const SAMPLE_ID: u16 = 53;
    const SCALE_TUNING: u16 = 56;

    /// A small SoundFont: preset bank 0 program 12 "Test Marimba" with one
    /// instrument of two zones (keys 0-59: sample "low", a 440 Hz sine at
    /// 22050 Hz, overridingRootKey 69, fineTune -7, the sample's pitch
    /// correction +3; keys 60-127: sample "high", constant 0.25 at 32000
    /// Hz, scaleTuning 50), and the kit preset bank 128 program 0 whose
    /// key 38 plays sample "high".
    pub(crate) fn tiny_sf2() -> Vec<u8> {
        let low: Vec<i16> = (0..2205)
            .map(|i| {
                (16384.0 * (2.0 * std::f64::consts::PI * 440.0 * i as f64 / 22050.0).sin()) as i16
            })
            .collect();
        let high = vec![8192i16; 1000];
        let mut smpl: Vec<u8> = Vec::new();
        for s in low
            .iter()
            .chain(&vec![0i16; 46])
            .chain(&high)
            .chain(&vec![0i16; 46])
        {
            smpl.extend_from_slice(&s.to_le_bytes());
        }
        let (low_end, high_start) = (2205u32, 2205 + 46);
        let high_end = high_start + 1000;
        let info = list(
            b"INFO",
            &[chunk(b"ifil", &[2, 0, 1, 0]), chunk(b"INAM", b"tiny\0\0")],
        );
        let sdta = list(b"sdta", &[chunk(b"smpl", &smpl)]);
        // presets: 0 "Test Marimba" (bag 0), 1 "Test Kit" (bag 1), EOP (bag 2)
        let mut phdr = Vec::new();
        for (name, prog, bank, bag) in [
            ("Test Marimba", 12u16, 0u16, 0u16),
            ("Test Kit", 0, 128, 1),
            ("EOP", 0, 0, 2),
        ] {
            phdr.extend(name20(name));
            for x in [prog, bank, bag] {
                phdr.extend_from_slice(&x.to_le_bytes());
            }
            phdr.extend_from_slice(&[0u8; 12]);
        }
        let pgen = gens(&[
            (INSTRUMENT, 0),
            (KEY_RANGE, 38 | (38 << 8)),
            (INSTRUMENT, 1),
            (0, 0),
        ]);
        let pbag = bags(&[0, 1, 3]);
        // instruments: 0 "Test Inst" (bags 0, 1), 1 "Test Drum" (bag 2), EOI (bag 3)
        let mut inst = Vec::new();
        for (name, bag) in [("Test Inst", 0u16), ("Test Drum", 2), ("EOI", 3)] {
            inst.extend(name20(name));
            inst.extend_from_slice(&bag.to_le_bytes());
        }
        let igen = gens(&[
            (KEY_RANGE, 59 << 8),
            (FINE_TUNE, (-7i16) as u16),
            (OVERRIDING_ROOT_KEY, 69),
            (SAMPLE_ID, 0),
            (KEY_RANGE, 60 | (127 << 8)),
            (SCALE_TUNING, 50),
            (SAMPLE_ID, 1),
            (KEY_RANGE, 38 | (38 << 8)),
            (SAMPLE_ID, 1),
            (0, 0),
        ]);
        let ibag = bags(&[0, 4, 7, 9]);
        let mut sh = shdr("low", 0, low_end, 22050, 60, 3, 1);
        sh.extend(shdr("high", high_start, high_end, 32000, 60, 0, 1));
        sh.extend(shdr("EOS", 0, 0, 0, 0, 0, 0));
        let pdta = list(
            b"pdta",
            &[
                chunk(b"phdr", &phdr),
                chunk(b"pbag", &pbag),
                chunk(b"pmod", &[0u8; 10]),
                chunk(b"pgen", &pgen),
                chunk(b"inst", &inst),
                chunk(b"ibag", &ibag),
                chunk(b"imod", &[0u8; 10]),
                chunk(b"igen", &igen),
                chunk(b"shdr", &sh),
            ],
        );
        let mut body = b"sfbk".to_vec();
        body.extend(info);
        body.extend(sdta);
        body.extend(pdta);
        chunk(b"RIFF", &body)
    }

    #[test]
    fn a_small_soundfont_gives_its_zones_tunings_and_samples() {
        let sf = SoundFont::read(&mut std::io::Cursor::new(tiny_sf2())).unwrap();
        let names: Vec<_> = sf
            .presets()
            .into_iter()
            .map(|p| (p.bank, p.program, p.name))
            .collect();
        assert_eq!(
            names,
            [
                (0, 12, "Test Marimba".to_string()),
                (128, 0, "Test Kit".to_string())
            ]
        );
        let r = sf.key_region(0, 12, 57, VELOCITY).unwrap();
        assert_eq!(r.zones.len(), 1);
        let z = &r.zones[0];
        assert_eq!(
            (z.name.as_str(), z.root_key, z.rate_hz),
            ("low", 69, 22050.0)
        );
        // 100 cents x (57 - 69) - 7 fine + 3 correction
        assert_eq!(z.cents, -1204.0);
        assert_eq!(sf.transposition(0, 12, 57, VELOCITY), Some(1204.0));
        assert_eq!(sf.transposition(0, 13, 57, VELOCITY), None);
        assert_eq!(z.data.len(), 2205);
        assert!(
            (z.data[5] - 0.5 * (2.0 * std::f64::consts::PI * 440.0 * 5.0 / 22050.0).sin()).abs()
                < 1e-4
        );
        assert_eq!(z.channel(), "mono");
        // played at 44.1 kHz: about an octave down, twice the rate -> 4x as long
        let played = r.play(44100.0).unwrap();
        let expect = 2205.0 * 2.0 * 2f64.powf(1204.0 / 1200.0);
        assert!(
            (played.len() as f64 - expect).abs() < 2.0,
            "{} vs {expect}",
            played.len()
        );

        let hi = sf.key_region(0, 12, 64, VELOCITY).unwrap();
        assert_eq!(hi.zones[0].name, "high");
        assert_eq!(hi.zones[0].cents, 50.0 * 4.0);
        assert!((hi.zones[0].data[10] - 0.25).abs() < 1e-12);

        // the high range's sample heard at key 57: its zone, transposed as
        // the zone would be at 57 (scale tuning 50: 50 x (57 - 60))
        let other = sf.key_region_played_at(0, 12, 64, 57, VELOCITY).unwrap();
        assert_eq!((other.key, other.zones[0].name.as_str()), (57, "high"));
        assert_eq!(other.zones[0].cents, 50.0 * -3.0);
        assert!(sf.key_region_played_at(0, 12, 64, 57, 0).is_ok());
        assert!(sf.key_region_played_at(0, 13, 64, 57, VELOCITY).is_err());

        let kit = sf.key_region(128, 0, 38, VELOCITY).unwrap();
        assert_eq!(kit.zones[0].name, "high");
        assert!(sf.key_region(128, 0, 40, VELOCITY).is_err());
        assert!(sf.key_region(0, 13, 60, VELOCITY).is_err());
    }

    /// FluidR3's marimba (bank 0 program 12) has a zone for A3 (key 57)
    /// with a plausible sample, when the soundfont is installed.
    #[test]
    fn fluidr3_marimba_has_a_zone_for_key_57() {
        let path = Path::new(super::super::DEFAULT_SF2);
        if !path.exists() {
            eprintln!("{} not installed: skipped", path.display());
            return;
        }
        let sf = SoundFont::open(path).unwrap();
        let r = sf.key_region(0, 12, 57, VELOCITY).unwrap();
        assert!(!r.zones.is_empty());
        for z in &r.zones {
            assert!((22050.0..=96000.0).contains(&z.rate_hz), "{z:?}");
            assert!((0.2..20.0).contains(&z.seconds()), "{} s", z.seconds());
            assert!((45..=75).contains(&z.root_key));
            assert!(z.data.iter().any(|x| x.abs() > 0.05));
        }
    }
}
