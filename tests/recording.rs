//! The recording analysis (`modal_contact::recording`) on known answers:
//! exact sums of damped sinusoids (10 to 200 modes, T60 from 0.05 to 20 s,
//! pairs 1 Hz apart) with seeded white noise 60 and 40 dB under the peak,
//! and the engine's render of a modal scene; each mode more than 40 dB
//! above the noise within 1e-5 in frequency and 2 % in T60. "Above the
//! noise" is the mode's amplitude over the noise's RMS; with noise 40 dB
//! under the peak no mode can be 40 dB over it, so there it is the noise's
//! RMS in the mode's analysis band (the band filter's valid width, 250 Hz:
//! 20 dB under the noise's RMS over the whole spectrum at 48 kHz).
//! Breadth: of the modes 30 dB over the noise in their band, the share
//! found within 1e-4 and 10 %. The worst errors are printed.

use modal_contact::recording::{
    analyze, object_scene, Analysis, AnalysisOptions, DEFAULT_MALLET_KG, FIT_S,
};
use modal_contact::render::{render, RenderOptions};
use modal_contact::test_rng::TestRng;
use modal_contact::Scene;
use modal_testkit::analysis::{band_levels, third_octave_distance, welch};
use std::f64::consts::PI;

const LN_1000: f64 = 6.907_755_278_982_137;

/// A mode of a test signal: `amp exp(-ln(1000) t / t60) cos(2 pi f t + phase)`.
#[derive(Debug, Clone, Copy)]
struct Truth {
    f: f64,
    t60: f64,
    amp: f64,
    phase: f64,
}

/// The exact sum of the modes over `seconds`, from t = 0.
fn synth(modes: &[Truth], rate: f64, seconds: f64) -> Vec<f64> {
    let n = (rate * seconds) as usize;
    let mut x = vec![0.0; n];
    for m in modes {
        let alpha = LN_1000 / m.t60;
        for (i, v) in x.iter_mut().enumerate() {
            let t = i as f64 / rate;
            let e = (-alpha * t).exp();
            if e < 1e-12 {
                break;
            }
            *v += m.amp * e * (2.0 * PI * m.f * t + m.phase).cos();
        }
    }
    x
}

/// Add white Gaussian noise `db` under the signal's peak (RMS); returns
/// the noise's RMS.
fn add_noise(x: &mut [f64], db: f64, seed: u64) -> f64 {
    let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let sigma = peak * 10f64.powf(-db / 20.0);
    let mut rng = TestRng(seed);
    for v in x.iter_mut() {
        // Box-Muller
        let (u1, u2) = (1.0 - rng.unit(), rng.unit());
        *v += sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos();
    }
    sigma
}

/// The worst relative frequency and T60 errors of the modes more than
/// 40 dB above `sigma`, and how many those are; panics past 1e-5 and 2 %.
/// Also: every mode found that loud is one of the true modes.
fn check(
    label: &str,
    truth: &[Truth],
    a: &Analysis,
    sigma: f64,
    natural: bool,
    in_band: bool,
) -> (f64, f64) {
    // The noise in a mode's analysis band (the band filter's valid width).
    let sigma = if in_band {
        sigma * (a.bands.1 / (0.5 * a.rate_hz)).sqrt()
    } else {
        sigma
    };
    let loud: Vec<&Truth> = truth.iter().filter(|m| m.amp > 100.0 * sigma).collect();
    let (mut wf, mut wt) = ((0.0, 0.0), (0.0, 0.0));
    let mut bad = Vec::new();
    for m in &loud {
        let found = a
            .modes
            .iter()
            .map(|x| {
                (
                    if natural {
                        x.natural_freq_hz()
                    } else {
                        x.freq_hz
                    },
                    x,
                )
            })
            .min_by(|p, q| (p.0 - m.f).abs().total_cmp(&(q.0 - m.f).abs()));
        let Some((f, x)) = found else {
            bad.push(format!("{:.3} Hz not found", m.f));
            continue;
        };
        let (ef, et) = ((f - m.f).abs() / m.f, (x.t60_s / m.t60 - 1.0).abs());
        if ef > wf.0 {
            wf = (ef, m.f);
        }
        if et > wt.0 {
            wt = (et, m.f);
        }
        if ef > 1e-5 || et > 0.02 {
            for d in a
                .dropped
                .iter()
                .filter(|d| (d.freq_hz - m.f).abs() < 0.01 * m.f)
            {
                eprintln!("  dropped near {:.3}: {d:?}", m.f);
            }
            bad.push(format!(
                "{:.3} Hz T60 {:.3} s at {:.1} dB over the noise: found {:.5} Hz ({ef:.2e}) T60 {:.4} s ({:+.2} %)",
                m.f,
                m.t60,
                20.0 * (m.amp / sigma).log10(),
                f,
                x.t60_s,
                100.0 * (x.t60_s / m.t60 - 1.0)
            ));
        }
    }
    let spurious: Vec<String> = a
        .modes
        .iter()
        .filter(|x| x.amplitude > 100.0 * sigma)
        .filter(|x| {
            let f = if natural {
                x.natural_freq_hz()
            } else {
                x.freq_hz
            };
            !truth.iter().any(|m| (m.f - f).abs() < 1e-4 * m.f)
        })
        .map(|x| format!("{:.3} Hz {:.1} dB", x.freq_hz, x.level_db()))
        .collect();
    eprintln!(
        "{label}: {} of {} modes over 40 dB above the noise, {} found in all, {} dropped; \
         worst frequency error {:.2e} (at {:.1} Hz), worst T60 error {:.3} % (at {:.1} Hz)",
        loud.len(),
        truth.len(),
        a.modes.len(),
        a.dropped.len(),
        wf.0,
        wf.1,
        100.0 * wt.0,
        wt.1
    );
    assert!(bad.is_empty(), "{label}:\n{}", bad.join("\n"));
    assert!(spurious.is_empty(), "{label}: spurious modes {spurious:?}");
    assert!(!loud.is_empty(), "{label}: no mode to check");
    (wf.0, wt.0)
}

/// The fraction of the modes more than 30 dB above the noise in their
/// band (`sigma` the noise's RMS over the whole spectrum) found within
/// 1e-4 and 10 %, printed.
fn breadth(label: &str, truth: &[Truth], a: &Analysis, sigma: f64) -> f64 {
    let band_sigma = sigma * (a.bands.1 / (0.5 * a.rate_hz)).sqrt();
    let audible: Vec<&Truth> = truth.iter().filter(|m| m.amp > 31.6 * band_sigma).collect();
    let found = audible
        .iter()
        .filter(|m| {
            a.modes.iter().any(|x| {
                (x.freq_hz - m.f).abs() < 1e-4 * m.f && (x.t60_s / m.t60 - 1.0).abs() < 0.1
            })
        })
        .count();
    eprintln!(
        "{label}: {found} of the {} modes 30 dB over the noise in their band found within 1e-4 and 10 % ({} modes in all)",
        audible.len(),
        truth.len()
    );
    found as f64 / audible.len().max(1) as f64
}

/// `n` modes from 100 Hz to `top` Hz, the T60 falling with frequency
/// from 20 s to 0.05 s (as metal's does), at least 5 Hz plus their
/// half-power bandwidths apart, levels over 30 dB, random phases; plus
/// `pairs` partners 1 Hz above modes of T60 over 2 s.
fn object(n: usize, top: f64, pairs: usize, seed: u64) -> Vec<Truth> {
    let mut rng = TestRng(seed);
    let mut modes: Vec<Truth> = Vec::new();
    let t60_at = |f: f64| {
        let octaves = (f / 100.0).log2();
        (20.0 * 2f64.powf(-octaves * 8.64 / (top / 100.0).log2())).clamp(0.05, 20.0)
    };
    // Neighbours at least 5 Hz plus their half-power bandwidths apart.
    let bandwidth = |f: f64| LN_1000 / t60_at(f) / PI;
    while modes.len() < n {
        let f = 100.0 * (top / 100.0).powf(rng.unit());
        if modes
            .iter()
            .any(|m| (m.f - f).abs() < 5.0 + bandwidth(m.f) + bandwidth(f))
        {
            continue;
        }
        let t60 = t60_at(f);
        modes.push(Truth {
            f,
            t60,
            amp: 10f64.powf(-rng.uniform(0.0, 30.0) / 20.0),
            phase: rng.uniform(-PI, PI),
        });
    }
    // The extremes of T60: 20 s at the lowest mode, 0.05 s at the highest.
    modes.sort_by(|a, b| a.f.total_cmp(&b.f));
    modes[0].t60 = 20.0;
    modes[n - 1].t60 = 0.05;
    let long: Vec<Truth> = modes.iter().filter(|m| m.t60 > 2.0).copied().collect();
    for m in long.iter().take(pairs) {
        modes.push(Truth {
            f: m.f + 1.0,
            t60: m.t60 * 0.8,
            amp: m.amp * 0.7,
            phase: m.phase + 1.0,
        });
    }
    modes
}

fn options(hi: f64) -> AnalysisOptions {
    AnalysisOptions {
        freq_range_hz: (50.0, hi),
        ..AnalysisOptions::default()
    }
}

#[test]
fn ten_modes_with_a_close_pair_at_60_db() {
    let truth = object(8, 8000.0, 2, 11);
    let mut x = synth(&truth, 44_100.0, 2.0);
    let sigma = add_noise(&mut x, 60.0, 12);
    let a = analyze(&x, 44_100.0, &options(9000.0)).unwrap();
    check("10 modes, noise -60 dB", &truth, &a, sigma, false, false);
    assert!(breadth("10 modes", &truth, &a, sigma) == 1.0);
}

#[test]
fn two_hundred_modes_at_60_db() {
    let mut truth = object(195, 12_000.0, 5, 21);
    // A few strong modes over the crowd, as in any struck object, so some
    // modes stand 40 dB over noise 60 dB under the peak of 200 modes.
    for i in [2, 20, 60, 100, 150] {
        truth[i].amp = 30.0;
    }
    let mut x = synth(&truth, 32_000.0, 2.0);
    let sigma = add_noise(&mut x, 60.0, 22);
    let a = analyze(&x, 32_000.0, &options(12_500.0)).unwrap();
    check("200 modes, noise -60 dB", &truth, &a, sigma, false, false);
    // The modes missed are the crowded, fast-decaying ones above 8 kHz.
    assert!(breadth("200 modes", &truth, &a, sigma) >= 0.75);
}

#[test]
fn forty_modes_with_pairs_at_40_db() {
    // A strike whose first mode dominates (as a bell's hum or a bowl's
    // fundamental does), so modes 40 dB above noise 40 dB under the peak
    // exist; the others are printed with their errors.
    let mut truth = object(36, 6000.0, 4, 31);
    truth[0].amp = 30.0;
    let mut x = synth(&truth, 48_000.0, 2.0);
    let sigma = add_noise(&mut x, 40.0, 32);
    let a = analyze(&x, 48_000.0, &options(6500.0)).unwrap();
    check("40 modes, noise -40 dB", &truth, &a, sigma, false, true);
    assert!(breadth("40 modes", &truth, &a, sigma) >= 0.9);
}

/// A modal scene: a bowl-like object with a pair 1 Hz apart, T60 from
/// 0.08 to 8 s, a hard 30 g mallet (a contact of 0.1 ms, so every mode
/// is struck well above the analysis's floor).
const SCENE: &str = r#"
version = 1
name = "analysis-check"
duration_s = 2.0

[[object]]
name = "bowl"
kind = "modal"
points = ["contact", "pickup"]

[[object.mode]]
freq_hz = 220.0
t60_s = 8.0
weights = [1.0, 1.0]

[[object.mode]]
freq_hz = 221.0
t60_s = 6.0
weights = [0.7, 0.7]

[[object.mode]]
freq_hz = 587.0
t60_s = 3.0
weights = [0.8, -0.6]

[[object.mode]]
freq_hz = 1230.0
t60_s = 1.5
weights = [0.5, 0.7]

[[object.mode]]
freq_hz = 2710.0
t60_s = 0.3
weights = [0.5, 0.4]

[[object.mode]]
freq_hz = 5400.0
t60_s = 0.08
weights = [0.4, 0.3]

[hammer]
mass_kg = 0.03
height_m = 0.001
velocity_m_per_s = -2.0

[contact]
object = "bowl"
point = "contact"
stiffness_n_per_m = 3e7
damping_n_s_per_m = 40.0

[[pickup]]
object = "bowl"
point = "pickup"
quantity = "velocity"
gain = 0.5
"#;

#[test]
fn the_modes_of_a_rendered_scene_are_found() {
    let scene = Scene::from_toml_str(SCENE).unwrap();
    let out = render(
        &scene,
        &RenderOptions {
            rate_hz: 48_000.0,
            ..RenderOptions::default()
        },
    )
    .unwrap();
    let a = analyze(&out.left, 48_000.0, &options(8000.0)).unwrap();
    let modal_contact::scene::ObjectSpec::Modal(m) = &scene.object[0] else {
        panic!("a modal object")
    };
    let truth: Vec<Truth> = m
        .mode
        .iter()
        .map(|md| Truth {
            f: md.freq_hz,
            t60: md.t60_s.unwrap(),
            amp: 1.0,
            phase: 0.0,
        })
        .collect();
    // The render has no noise but its rounding: every mode is checked
    // (against the natural frequency, the scene's `freq_hz`).
    check("rendered scene", &truth, &a, 1e-9, true, false);
    assert_eq!(a.modes.len(), truth.len(), "{:?}", a.modes);
}

/// The first sample at a tenth of the peak.
fn onset(x: &[f64]) -> usize {
    let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    x.iter().position(|v| v.abs() >= 0.1 * peak).unwrap_or(0)
}

#[test]
fn the_scene_written_for_a_render_sounds_like_it() {
    // A hard mallet (0.1 ms) and a soft one (1 ms, whose pulse leaves the
    // 2.7 kHz mode 33 dB down and the 5.4 kHz one 45 dB), both with the
    // scene's contact damping (a damping ratio of 0.22 on the soft one):
    // within 1 dB, the written scene's weights corrected by the amplitudes
    // its render plays and its damping fitted.
    for (stiffness, bound) in [("3e7", 1.0), ("3e5", 1.0)] {
        let text = SCENE.replace(
            "stiffness_n_per_m = 3e7",
            &format!("stiffness_n_per_m = {stiffness}"),
        );
        let scene = Scene::from_toml_str(&text).unwrap();
        let rate = 48_000.0;
        let opts = RenderOptions {
            rate_hz: rate,
            ..RenderOptions::default()
        };
        let original = render(&scene, &opts).unwrap().left;
        let a = analyze(&original, rate, &options(8000.0)).unwrap();
        let (written, mallet) = object_scene(&a, &original, "copy", DEFAULT_MALLET_KG).unwrap();
        let copy = Scene::from_toml_str(&written).unwrap();
        let again = render(&copy, &opts).unwrap().left;
        let (o1, o2) = (onset(&original), onset(&again));

        // the 1/3-octave distance as `cargo xtask compare-real` measures it
        let d = third_octave_distance(
            &band_levels(&welch(&original[o1..], rate, 0.5)),
            &band_levels(&welch(&again[o2..], rate, 0.5)),
        );
        let peak = |x: &[f64]| x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        eprintln!(
            "contact stiffness {stiffness}: {} modes, mallet contact {:.3} ms (rise {:.3} ms, top mode {:.0} Hz), \
             damping ratio {}, {} round(s) of weights, 1/3-octave distance {d:.3} dB, peak {:.4} against {:.4}",
            a.modes.len(),
            1e3 * mallet.contact_s,
            1e3 * mallet.rise_s,
            mallet.top_mode_hz,
            mallet.damping_ratio,
            mallet.weight_rounds,
            peak(&again),
            peak(&original)
        );
        assert!(d <= bound, "1/3-octave distance {d} dB");
    }
}

/// The mallet's contact time is fitted against renders: the distance the
/// fit reports is its written scene's, no worse than the first
/// estimate's; and where the onset's slope misreads the contact (a click
/// on the first sample of a soft mallet's strike, as a trimmed recording
/// or a microphone's pop leaves), the fit finds the real contact (0.96
/// ms) from the slope's 0.02 ms, and comes nearer the recording.
#[test]
fn the_mallet_is_fitted_against_renders() {
    let text = SCENE.replace("stiffness_n_per_m = 3e7", "stiffness_n_per_m = 3e5");
    let scene = Scene::from_toml_str(&text).unwrap();
    let rate = 48_000.0;
    let opts = RenderOptions {
        rate_hz: rate,
        ..RenderOptions::default()
    };
    let mut x = render(&scene, &opts).unwrap().left;
    let o = onset(&x);
    let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    x[o] += 0.5 * peak * x[o].signum();
    let a = analyze(&x, rate, &options(8000.0)).unwrap();
    let (written, mallet) = object_scene(&a, &x, "copy", DEFAULT_MALLET_KG).unwrap();
    let again = render(&Scene::from_toml_str(&written).unwrap(), &opts)
        .unwrap()
        .left;
    let (rec, copy) = (&x[a.onset..], &again[onset(&again)..]);
    let n = rec.len().min(copy.len());
    let d = third_octave_distance(
        &band_levels(&welch(&rec[..n], rate, FIT_S)),
        &band_levels(&welch(&copy[..n], rate, FIT_S)),
    );
    eprintln!(
        "slope {:.3} ms, first {:.3} ms ({:.2} dB), fitted {:.3} ms ({:.2} dB, measured again {d:.2} dB), {} renders",
        1e3 * mallet.rise_s,
        1e3 * mallet.first_s,
        mallet.first_db,
        1e3 * mallet.contact_s,
        mallet.render_db,
        mallet.renders
    );
    assert!(
        (d - mallet.render_db).abs() < 1e-9,
        "{d} against {}",
        mallet.render_db
    );
    assert!(mallet.render_db <= mallet.first_db);
    // contact times (at most 21), damping ratios (at most 10), the
    // weights' correction (one render per round and one before: at most 5)
    assert!((10..=36).contains(&mallet.renders), "{}", mallet.renders);
    assert!(mallet.rise_s < 0.2e-3, "{}", mallet.rise_s);
    // the contact this stiffness gives on the bowl lasts 0.96 ms (the
    // test above reads 0.90 from the clean onset's slope)
    assert!(
        (0.8e-3..1.2e-3).contains(&mallet.contact_s),
        "{}",
        mallet.contact_s
    );
    // (the click stays in the recording and in the distance)
    assert!(mallet.render_db < mallet.first_db - 1.0);
}
