//! The multisample export played by real third-party SFZ software against
//! the built plugin: `cargo xtask multisample`'s library function exports
//! the marimba preset, Polyphone (Debian) reads the SFZ and converts it to
//! SF2, FluidSynth (Debian) plays it from a standard MIDI file, and the
//! plugin, loaded through the CLAP host, plays the same notes. Compared per
//! note and velocity layer: onset (within 0.5 ms), pitch (the strongest
//! spectral peak, within 1 cent) and level (RMS from 20 to 300 ms, within
//! 0.25 dB), at sampled notes and at notes between them.
//!
//! The SFZ says `amp_veltrack=0` (each layer plays at its recorded level);
//! Polyphone does not carry that opcode into SF2, so FluidSynth applies
//! SF2's default velocity-to-attenuation curve. The test measures that curve
//! with a second, test-written SFZ (one constant 220 Hz sine for every key
//! and velocity) played the same way, and divides it out.
//!
//! Needs `polyphone` and `fluidsynth` on the PATH (`.ci/run` installs the
//! Debian packages); it fails, not skips, without them.

use plugin_tests::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use xtask::multisample::{run, MultisampleArgs};
use xtask::offline::{write_wav, WavFormat};

const RATE: f64 = 44_100.0;
/// Seconds between notes in the MIDI file, and how long each is held.
const SPACING_S: f64 = 1.5;
const HOLD_S: f64 = 1.2;

fn tool(name: &str) -> PathBuf {
    let found = std::env::var_os("PATH")
        .into_iter()
        .flat_map(|p| std::env::split_paths(&p).collect::<Vec<_>>())
        .map(|d| d.join(name))
        .find(|p| p.is_file());
    found.unwrap_or_else(|| {
        panic!("{name} is not installed: apt-get install polyphone fluidsynth (see .ci/run)")
    })
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("multisample-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn sh(cmd: &mut Command) {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// SFZ -> SF2 with Polyphone (headless).
fn to_sf2(sfz: &Path, out: &Path, name: &str) -> PathBuf {
    std::fs::create_dir_all(out).unwrap();
    sh(Command::new(tool("polyphone"))
        .env("QT_QPA_PLATFORM", "offscreen")
        .env("XDG_RUNTIME_DIR", out)
        .args(["-1", "-i"])
        .arg(sfz)
        .arg("-d")
        .arg(out)
        .args(["-o", name]));
    let sf2 = out.join(format!("{name}.sf2"));
    assert!(sf2.is_file(), "polyphone wrote no {}", sf2.display());
    sf2
}

fn vlq(mut n: u32) -> Vec<u8> {
    let mut b = vec![(n & 0x7f) as u8];
    n >>= 7;
    while n > 0 {
        b.push(0x80 | (n & 0x7f) as u8);
        n >>= 7;
    }
    b.reverse();
    b
}

/// A type-0 MIDI file: note k at `k * SPACING_S`, held `HOLD_S`
/// (1 tick = 1 ms: 500 000 us per quarter, 500 ticks per quarter).
fn midi_file(path: &Path, notes: &[(u8, u8)]) {
    let ms = |s: f64| (s * 1000.0).round() as u32;
    let mut ev: Vec<(u32, [u8; 3])> = Vec::new();
    for (k, &(key, vel)) in notes.iter().enumerate() {
        let t = ms(k as f64 * SPACING_S);
        ev.push((t, [0x90, key, vel]));
        ev.push((t + ms(HOLD_S), [0x80, key, 0]));
    }
    ev.sort_by_key(|e| e.0);
    let mut track = vec![0x00, 0xFF, 0x51, 0x03, 0x07, 0xA1, 0x20];
    let mut now = 0;
    for (t, bytes) in ev {
        track.extend(vlq(t - now));
        track.extend(bytes);
        now = t;
    }
    track.extend([0x00, 0xFF, 0x2F, 0x00]);
    let mut f = b"MThd\0\0\0\x06\0\0\0\x01\x01\xf4MTrk".to_vec();
    f.extend((track.len() as u32).to_be_bytes());
    f.extend(track);
    std::fs::write(path, f).unwrap();
}

/// Play `notes` from `sf2` in FluidSynth; the left channel.
fn fluidsynth(sf2: &Path, notes: &[(u8, u8)], dir: &Path, name: &str) -> Vec<f32> {
    let mid = dir.join(format!("{name}.mid"));
    let wav = dir.join(format!("{name}-fluidsynth.wav"));
    midi_file(&mid, notes);
    sh(Command::new(tool("fluidsynth"))
        .args([
            "-ni", "-q", "-R", "0", "-C", "0", "-g", "1.0", "-r", "44100", "-F",
        ])
        .arg(&wav)
        .arg(sf2)
        .arg(&mid));
    read_left(&wav)
}

fn read_left(path: &Path) -> Vec<f32> {
    let mut r = hound::WavReader::open(path).unwrap();
    let spec = r.spec();
    let ch = spec.channels as usize;
    let all: Vec<f32> = match spec.sample_format {
        hound::SampleFormat::Float => r.samples::<f32>().map(|s| s.unwrap()).collect(),
        hound::SampleFormat::Int => {
            let full = (1u64 << (spec.bits_per_sample - 1)) as f32;
            r.samples::<i32>()
                .map(|s| s.unwrap() as f32 / full)
                .collect()
        }
    };
    all.chunks(ch).map(|c| c[0]).collect()
}

/// First sample above 1e-3 of the signal's peak.
fn onset(x: &[f32]) -> usize {
    let p = peak(x) as f32;
    x.iter().position(|v| v.abs() > 1e-3 * p).expect("sound")
}

/// Frequency of the strongest spectral peak between 60 Hz and 4 kHz over
/// `x` (Hann window, DFT on a 0.5 Hz grid, parabolic refinement).
fn main_frequency(x: &[f32]) -> f64 {
    let n = x.len();
    let w: Vec<f64> = (0..n)
        .map(|i| {
            let h = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
            h * f64::from(x[i])
        })
        .collect();
    let mag = |f: f64| {
        let (mut re, mut im) = (0.0, 0.0);
        let dphi = 2.0 * std::f64::consts::PI * f / RATE;
        let (c, s) = (dphi.cos(), dphi.sin());
        let (mut cr, mut ci) = (1.0f64, 0.0f64);
        for v in &w {
            re += v * cr;
            im -= v * ci;
            let t = cr * c - ci * s;
            ci = cr * s + ci * c;
            cr = t;
        }
        (re * re + im * im).sqrt()
    };
    let grid: Vec<f64> = (120..8000).map(|k| k as f64 * 0.5).collect();
    let mags: Vec<f64> = grid.iter().map(|&f| mag(f)).collect();
    let k = (1..mags.len() - 1)
        .max_by(|&a, &b| mags[a].total_cmp(&mags[b]))
        .unwrap();
    let (a, b, c) = (mags[k - 1].ln(), mags[k].ln(), mags[k + 1].ln());
    grid[k] + 0.5 * 0.5 * (a - c) / (a - 2.0 * b + c)
}

fn db(x: f64) -> f64 {
    20.0 * x.log10()
}

/// RMS of `x` from 20 ms to 300 ms after `at`.
fn level(x: &[f32], at: usize) -> f64 {
    let a = at + (0.02 * RATE) as usize;
    rms(&x[a..at + (0.3 * RATE) as usize])
}

fn plugin_note(bundle: &Path, key: u8, vel: u8) -> Vec<f32> {
    let mut p = LoadedPlugin::load(bundle);
    let spec = RenderSpec::new(
        RATE,
        256,
        (HOLD_S * RATE) as usize,
        vec![on(0, key, f64::from(vel) / 127.0)],
    );
    let [l, _] = p.render(&spec);
    l
}

#[test]
fn a_real_sfz_player_plays_the_export_as_the_plugin_does() {
    let dir = temp("sfz");
    let export = dir.join("export");
    run(&MultisampleArgs {
        scene: modal_testkit::scenes::preset_path("marimba-bar"),
        notes: "48..60".into(),
        step: 6,
        velocities: 2,
        out: export.clone(),
        rate: RATE,
        seconds: Some(1.4),
        name: None,
        force: false,
        jobs: None,
    })
    .expect("export");
    // the calibration instrument: a constant 220 Hz sine at -12 dBFS
    let cal = dir.join("cal");
    std::fs::create_dir_all(&cal).unwrap();
    let sine: Vec<f32> = (0..(1.4 * RATE) as usize)
        .map(|i| 0.25 * (2.0 * std::f64::consts::PI * 220.0 * i as f64 / RATE).sin() as f32)
        .collect();
    write_wav(&cal.join("sine.wav"), RATE, &sine, &sine, WavFormat::Pcm24).unwrap();
    std::fs::write(
        cal.join("cal.sfz"),
        "<control>\ndefault_path=./\n<global>\namp_veltrack=0\nloop_mode=one_shot\n\
         <region> sample=sine.wav pitch_keycenter=57 lokey=0 hikey=127 lovel=1 hivel=127\n",
    )
    .unwrap();
    let sf2 = to_sf2(&export.join("marimba-bar.sfz"), &dir.join("sf2"), "marimba");
    let cal_sf2 = to_sf2(&cal.join("cal.sfz"), &dir.join("sf2"), "cal");

    // sampled notes at each layer's top velocity, and two notes between
    // sampled ones (pitch-shifted by the sampler)
    let notes: Vec<(u8, u8)> = vec![
        (48, 63),
        (48, 127),
        (54, 63),
        (54, 127),
        (60, 63),
        (60, 127),
        (51, 127),
        (57, 63),
    ];
    let played = fluidsynth(&sf2, &notes, &dir, "marimba");
    let cal_notes: Vec<(u8, u8)> = notes.iter().map(|&(_, v)| (57, v)).collect();
    let cal_played = fluidsynth(&cal_sf2, &cal_notes, &dir, "cal");
    let cal_ref = level(&sine, 0);

    let bundle = clap_bundle(Variant::Release);
    let spacing = (SPACING_S * RATE) as usize;
    let hold = (HOLD_S * RATE) as usize;
    println!("note vel | onset sampler (after the player's start)/plugin ms | f sampler/plugin Hz (cents) | level sampler/plugin dB");
    for (k, &(key, vel)) in notes.iter().enumerate() {
        let s = &played[k * spacing..k * spacing + hold];
        let c = &cal_played[k * spacing..k * spacing + hold];
        let p = plugin_note(&bundle, key, vel);
        // FluidSynth starts notes on its 64-sample blocks: its onset is
        // taken from the calibration note of the same slot (same MIDI
        // timing, a sine that sounds at once)
        let (os, oc, op) = (onset(s), onset(c), onset(&p));
        let win = |x: &[f32], at: usize| x[at + 2205..at + 2205 + 16384].to_vec();
        let (fs, fp) = (main_frequency(&win(s, os)), main_frequency(&win(&p, op)));
        let cents = 1200.0 * (fs / fp).log2();
        // the player's own gain at this velocity, from the calibration sine
        let gain = level(c, onset(c)) / cal_ref;
        let (ls, lp) = (db(level(s, os) / gain), db(level(&p, op)));
        let rel = os as f64 - oc as f64;
        println!(
            "{key} {vel:3} | {:.2} / {:.2} | {fs:.2} / {fp:.2} ({cents:+.2}) | {ls:.2} / {lp:.2} ({:+.2})",
            rel / RATE * 1e3,
            op as f64 / RATE * 1e3,
            ls - lp
        );
        assert!(
            (rel - op as f64).abs() / RATE <= 0.5e-3,
            "{key}/{vel}: onset {os} (player start {oc}) vs {op}"
        );
        assert!(cents.abs() <= 1.0, "{key}/{vel}: pitch {fs} vs {fp} Hz");
        // between sampled keys too: the plugin's pitch is a time scaling,
        // which is what the sampler's resampling does
        assert!(
            (ls - lp).abs() <= 0.25,
            "{key}/{vel}: level {ls} vs {lp} dB"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
