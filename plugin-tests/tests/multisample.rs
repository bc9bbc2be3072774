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
use std::time::Instant;
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

/// Play `notes` from `sf2` in FluidSynth; both channels.
fn fluidsynth(sf2: &Path, notes: &[(u8, u8)], dir: &Path, name: &str) -> [Vec<f32>; 2] {
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
    read_stereo(&wav)
}

fn read_stereo(path: &Path) -> [Vec<f32>; 2] {
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
    assert_eq!(ch, 2, "{}: stereo", path.display());
    [0, 1].map(|c| all.iter().skip(c).step_by(2).copied().collect())
}

/// First sample above 1e-3 of the signal's peak.
fn onset(x: &[f32]) -> usize {
    let p = peak(x) as f32;
    x.iter().position(|v| v.abs() > 1e-3 * p).expect("sound")
}

/// In-place radix-2 FFT of (`re`, `im`); the length is a power of two.
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * std::f64::consts::PI / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (c, s) = ((ang * k as f64).cos(), (ang * k as f64).sin());
                let (a, b) = (start + k, start + k + len / 2);
                let (tr, ti) = (re[b] * c - im[b] * s, re[b] * s + im[b] * c);
                (re[b], im[b]) = (re[a] - tr, im[a] - ti);
                (re[a], im[a]) = (re[a] + tr, im[a] + ti);
            }
        }
        len <<= 1;
    }
}

/// Frequency of the strongest spectral peak between 60 Hz and 4 kHz over
/// `x` (a power-of-two length): Hann window, the strongest FFT bin, then
/// the maximum of the windowed spectrum's magnitude (evaluated directly at
/// any frequency) within one bin of it, by golden-section search.
fn main_frequency(x: &[f32]) -> f64 {
    let n = x.len();
    let w: Vec<f64> = (0..n)
        .map(|i| {
            let h = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
            h * f64::from(x[i])
        })
        .collect();
    let (mut re, mut im) = (w.clone(), vec![0.0; n]);
    fft(&mut re, &mut im);
    let bin = RATE / n as f64;
    let k = ((60.0 / bin) as usize..(4000.0 / bin) as usize)
        .max_by(|&a, &b| (re[a].hypot(im[a])).total_cmp(&re[b].hypot(im[b])))
        .unwrap();
    let mag = |f: f64| {
        let dphi = 2.0 * std::f64::consts::PI * f / RATE;
        let (c, s) = (dphi.cos(), dphi.sin());
        let (mut sr, mut si, mut cr, mut ci) = (0.0, 0.0, 1.0f64, 0.0f64);
        for v in &w {
            sr += v * cr;
            si -= v * ci;
            (cr, ci) = (cr * c - ci * s, cr * s + ci * c);
        }
        sr.hypot(si)
    };
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = ((k as f64 - 1.0) * bin, (k as f64 + 1.0) * bin);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (mag(c), mag(d));
    while b - a > 1e-6 {
        if fc > fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = mag(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = mag(d);
        }
    }
    0.5 * (a + b)
}

fn db(x: f64) -> f64 {
    20.0 * x.log10()
}

/// RMS of `x` from 20 ms to 300 ms after `at`.
fn level(x: &[f32], at: usize) -> f64 {
    let a = at + (0.02 * RATE) as usize;
    rms(&x[a..at + (0.3 * RATE) as usize])
}

fn plugin_note(bundle: &Path, key: u8, vel: u8) -> [Vec<f32>; 2] {
    let mut p = LoadedPlugin::load(bundle);
    let spec = RenderSpec::new(
        RATE,
        256,
        (HOLD_S * RATE) as usize,
        vec![on(0, key, f64::from(vel) / 127.0)],
    );
    p.render(&spec)
}

/// Export the preset's notes 48, 54 and 60 at 2 velocity layers with the
/// command's library function; the export directory.
fn export(dir: &Path) -> PathBuf {
    let out = dir.join("export");
    run(&MultisampleArgs {
        scene: modal_testkit::scenes::preset_path("marimba-bar"),
        notes: "48..60".into(),
        step: 6,
        velocities: 2,
        out: out.clone(),
        rate: RATE,
        seconds: Some(1.4),
        name: None,
        force: false,
        jobs: None,
    })
    .expect("export");
    out
}

/// The calibration instrument: one constant 220 Hz stereo sine at -12
/// dBFS for every key and velocity, with the export's opcodes. Its SFZ
/// and its samples.
fn calibration(dir: &Path) -> (PathBuf, Vec<f32>) {
    let cal = dir.join("cal");
    std::fs::create_dir_all(&cal).unwrap();
    let sine: Vec<f32> = (0..(1.4 * RATE) as usize)
        .map(|i| 0.25 * (2.0 * std::f64::consts::PI * 220.0 * i as f64 / RATE).sin() as f32)
        .collect();
    write_wav(&cal.join("sine.wav"), RATE, &sine, &sine, WavFormat::Pcm24).unwrap();
    let sfz = cal.join("cal.sfz");
    std::fs::write(
        &sfz,
        "<control>\ndefault_path=./\n<global>\namp_veltrack=0\nloop_mode=one_shot\n\
         trigger=attack\n\
         <region> sample=sine.wav pitch_keycenter=57 lokey=0 hikey=127 lovel=1 hivel=127\n",
    )
    .unwrap();
    (sfz, sine)
}

/// One note: the sampler's channels and the calibration sine played in
/// the same slot (same MIDI timing and velocity), and the plugin's render.
struct Note<'a> {
    key: u8,
    vel: u8,
    sampler: [&'a [f32]; 2],
    cal: &'a [f32],
    plugin: [Vec<f32>; 2],
}

/// Measure, print and check one note; `cal_ref` is the calibration
/// sine's own level.
fn compare(n: &Note, cal_ref: f64) {
    let (key, vel) = (n.key, n.vel);
    let (s, p) = (n.sampler, &n.plugin);
    // FluidSynth starts notes on its 64-sample blocks: the player's start
    // is the calibration sine's onset in the same slot
    let (os, oc, op) = (onset(s[0]), onset(n.cal), onset(&p[0]));
    let rel = os as f64 - oc as f64;
    let d_onset_ms = (rel - op as f64) / RATE * 1e3;
    let win = |x: &[f32], at: usize| x[at + 2205..at + 2205 + 16384].to_vec();
    let (fs, fp) = (
        main_frequency(&win(s[0], os)),
        main_frequency(&win(&p[0], op)),
    );
    let cents = 1200.0 * (fs / fp).log2();
    // the player's own gain at this velocity (SF2's default velocity
    // curve), from the calibration sine, divided out
    let gain = level(n.cal, oc) / cal_ref;
    let ls = [0, 1].map(|c| db(level(s[c], os) / gain));
    let lp = [0, 1].map(|c| db(level(&p[c], op)));
    println!(
        "{key} {vel:3} | {:.3} / {:.3} ({d_onset_ms:+.3}) | {fs:.3} / {fp:.3} ({cents:+.4}) | \
         {:+.2} | L {:.3} / {:.3} ({:+.3}) R {:.3} / {:.3} ({:+.3})",
        rel / RATE * 1e3,
        op as f64 / RATE * 1e3,
        db(gain),
        ls[0],
        lp[0],
        ls[0] - lp[0],
        ls[1],
        lp[1],
        ls[1] - lp[1]
    );
    assert!(
        d_onset_ms.abs() <= 0.5,
        "{key}/{vel}: onset {os} (player start {oc}) vs {op}"
    );
    // between sampled keys too: the plugin's pitch is a time scaling,
    // which is what the sampler's resampling does
    assert!(cents.abs() <= 1.0, "{key}/{vel}: pitch {fs} vs {fp} Hz");
    for c in 0..2 {
        assert!(
            (ls[c] - lp[c]).abs() <= 0.25,
            "{key}/{vel} channel {c}: level {} vs {} dB",
            ls[c],
            lp[c]
        );
    }
}

#[test]
fn a_real_sfz_player_plays_the_export_as_the_plugin_does() {
    let t0 = Instant::now();
    let dir = temp("sfz");
    let export = export(&dir);
    let (cal_sfz, sine) = calibration(&dir);
    let t_export = t0.elapsed().as_secs_f64();
    let sf2 = to_sf2(&export.join("marimba-bar.sfz"), &dir.join("sf2"), "marimba");
    let cal_sf2 = to_sf2(&cal_sfz, &dir.join("sf2"), "cal");
    let t_convert = t0.elapsed().as_secs_f64();
    // sampled notes at each layer's top velocity, and two notes between
    // sampled ones (pitch-shifted by the sampler)
    let notes: [(u8, u8); 8] = [
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
    let [cal_played, _] = fluidsynth(&cal_sf2, &cal_notes, &dir, "cal");
    let t_play = t0.elapsed().as_secs_f64();

    let bundle = clap_bundle(Variant::Release);
    let t_bundle = t0.elapsed().as_secs_f64();
    let slot = |k: usize| {
        let a = (k as f64 * SPACING_S * RATE) as usize;
        a..a + (HOLD_S * RATE) as usize
    };
    println!(
        "note vel | onset sampler (after the player's start) / plugin ms | \
         f sampler / plugin Hz (cents) | player gain dB | \
         level sampler (calibrated) / plugin dB, per channel"
    );
    for (k, &(key, vel)) in notes.iter().enumerate() {
        compare(
            &Note {
                key,
                vel,
                sampler: [&played[0][slot(k)], &played[1][slot(k)]],
                cal: &cal_played[slot(k)],
                plugin: plugin_note(&bundle, key, vel),
            },
            level(&sine, 0),
        );
    }
    println!(
        "seconds: export {t_export:.2}, polyphone {:.2}, fluidsynth {:.2}, \
         plugin bundle {:.2}, plugin notes and analysis {:.2}",
        t_convert - t_export,
        t_play - t_convert,
        t_bundle - t_play,
        t0.elapsed().as_secs_f64() - t_bundle
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
