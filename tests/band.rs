//! The output band (`EngineState::set_output_band`): modes above it are left
//! out of the outputs, not of the dynamics, consistently in both phases.
//!
//! 1. Exactness: a voice with the band equals (to round-off) the same scene
//!    whose pickup weights of those modes are zero, at a time scale that
//!    puts them above the band, with a displacement and a velocity pickup,
//!    without and with gravity (the contact rows' static offset), in both
//!    switching modes.
//! 2. No aliasing: a note pitched up so that four modes lie above Nyquist:
//!    without the band each folds back to `|f - k f_s|` and is seen there
//!    in the spectrum; with the band the level at each fold-back frequency
//!    drops to the kept modes' own spectral skirt.

use modal_contact::compile::compile_with;
use modal_contact::engine::EngineState;
use modal_contact::scene::{ObjectSpec, Scene, Switching};
use modal_testkit::metrics::rel_l2;
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder};

/// Eleven modes from 300 Hz to 19 kHz: at s = 2.5 the top ones are above
/// 22.05 kHz. Pickups at a point other than the contact.
fn bar(gravity: f64) -> Scene {
    let freqs = [
        300.0, 820.0, 1610.0, 2650.0, 3950.0, 5500.0, 7300.0, 9350.0, 11650.0, 15600.0, 19000.0,
    ];
    let mut bar = Modal::new("bar", &["contact", "pickup"]);
    for (i, &f) in freqs.iter().enumerate() {
        let w_c = 1.0 + 0.1 * i as f64;
        let w_p = if i % 2 == 0 { 0.8 } else { -0.6 } * (1.0 + 0.05 * i as f64);
        bar = bar.mode(f, 2.0 / (1.0 + i as f64), &[w_c, w_p]);
    }
    let (height, v0) = if gravity > 0.0 {
        (0.01, 0.0)
    } else {
        (0.0, -1.0)
    };
    SceneBuilder::new("band-bar")
        .object(bar)
        .hammer(
            Hammer::new(0.02)
                .height(height)
                .velocity(v0)
                .gravity(gravity),
        )
        .contact(Contact::new("bar", 1e6).point("contact").damping(3.0))
        .pickup(
            Pickup::new("bar", "pickup")
                .displacement()
                .gain(1000.0)
                .pan(-0.5),
        )
        .pickup(Pickup::new("bar", "pickup").gain(1.0).pan(0.7))
        .build()
}

/// The same scene with the pickup weight of every mode above `band_hz` at
/// time scale `s` set to zero.
fn without_modes_above(scene: &Scene, s: f64, band_hz: f64) -> (Scene, usize) {
    let mut out = scene.clone();
    let mut n = 0;
    if let ObjectSpec::Modal(m) = &mut out.object[0] {
        for mode in &mut m.mode {
            if mode.freq_hz * s > band_hz {
                mode.weights[1] = 0.0;
                n += 1;
            }
        }
    }
    (out, n)
}

fn run(
    scene: &Scene,
    rate: f64,
    s: f64,
    band_hz: f64,
    switching: Switching,
    n: usize,
) -> (Vec<f64>, Vec<f64>, usize) {
    let c = compile_with(scene, rate, Some(switching)).expect("compile");
    let mut st = EngineState::new(&c);
    st.set_time_scale(&c, s).expect("time scale");
    st.set_output_band(&c, band_hz);
    st.reset(&c);
    let muted = st.band_muted_modes();
    let (mut l, mut r) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let o = st.tick(&c);
        l.push(o[0]);
        r.push(o[1]);
    }
    (l, r, muted)
}

#[test]
fn band_equals_zeroed_pickup_weights() {
    let rate = 44_100.0;
    let s = 2.5;
    let band = 0.5 * rate;
    for gravity in [0.0, 9.81] {
        for switching in [Switching::Exact, Switching::OffsetRod] {
            let full = bar(gravity);
            let (zeroed, n_zeroed) = without_modes_above(&full, s, band);
            assert!(n_zeroed >= 3, "the test needs modes above the band");
            let n = 30_000;
            let (l, r, muted) = run(&full, rate, s, band, switching, n);
            let (l0, r0, muted0) = run(&zeroed, rate, s, f64::INFINITY, switching, n);
            let (lf, _, _) = run(&full, rate, s, f64::INFINITY, switching, n);
            let (dl, dr) = (rel_l2(&l, &l0), rel_l2(&r, &r0));
            let heard = rel_l2(&lf, &l0);
            println!(
                "g {gravity}, {switching:?}: {muted} modes left out; band vs zeroed weights: \
                 rel L2 left {dl:.2e}, right {dr:.2e}; the left-out modes' share without \
                 the band: {heard:.2e}"
            );
            assert_eq!(muted, n_zeroed);
            assert_eq!(muted0, 0);
            assert!(l.iter().chain(&r).all(|x| x.is_finite()));
            assert!(dl < 1e-11 && dr < 1e-11, "{dl} {dr}");
            // and the band really changed something audible
            assert!(heard > 1e-3, "{heard}");
        }
    }
}

/// Magnitude of the Hann-windowed DFT of `x[start..start + n]` at `f` [Hz].
fn dft_mag(x: &[f64], start: usize, n: usize, f: f64, rate: f64) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for k in 0..n {
        let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / n as f64).cos();
        let ph = 2.0 * std::f64::consts::PI * f * k as f64 / rate;
        re += w * x[start + k] * ph.cos();
        im -= w * x[start + k] * ph.sin();
    }
    (re * re + im * im).sqrt() / n as f64
}

#[test]
fn pitched_up_note_is_not_aliased() {
    let rate = 44_100.0;
    let s = 2.5; // modes up to 47.5 kHz
    let band = 0.5 * rate;
    let (start, n) = (2_000, 8_192);
    let sc = bar(0.0);
    let ObjectSpec::Modal(m) = &sc.object[0] else {
        unreachable!()
    };
    // where each mode above Nyquist lands when sampled
    let aliases: Vec<(f64, f64)> = m
        .mode
        .iter()
        .map(|md| md.freq_hz * s)
        .filter(|f| *f > band)
        .map(|f| {
            let r = f % rate;
            (f, if r > band { rate - r } else { r })
        })
        .collect();
    assert!(aliases.len() >= 3);
    for switching in [Switching::Exact, Switching::OffsetRod] {
        let (l, r, muted) = run(&sc, rate, s, band, switching, start + n);
        let (la, ra, _) = run(&sc, rate, s, f64::INFINITY, switching, start + n);
        assert_eq!(muted, aliases.len());
        for (ch, (x, xa)) in [(&l, &la), (&r, &ra)].into_iter().enumerate() {
            for &(f, fa) in &aliases {
                let with = dft_mag(x, start, n, fa, rate);
                let without = dft_mag(xa, start, n, fa, rate);
                let removed: Vec<f64> = xa.iter().zip(x.iter()).map(|(a, b)| a - b).collect();
                let folded = dft_mag(&removed, start, n, fa, rate);
                println!(
                    "{switching:?} ch {ch}: mode at {f:.0} Hz folds to {fa:.0} Hz: level there \
                     {without:.3e} without the band, {with:.3e} with it ({:.1} dB; what is \
                     left is the kept modes' own spectral skirt); the removed part has \
                     {folded:.3e} there",
                    20.0 * (with / without).log10()
                );
                assert!(with.is_finite() && without > 0.0);
                // the level at the alias frequency was the folded mode ...
                assert!(folded > 0.9 * without, "{folded} vs {without}");
                // ... and the band took it out
                assert!(with < 0.5 * without, "alias of {f} Hz at {fa} Hz remains");
            }
        }
    }
}
