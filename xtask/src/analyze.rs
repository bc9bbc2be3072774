//! `cargo xtask analyze STRIKE.wav --out my-object.toml`: the modes of a
//! struck object from a recording of one strike (`modal_contact::recording`,
//! whose module documentation has the method), written as a scene file
//! with that object, a mallet and a pickup; and a report: the modes
//! (frequency, T60, level), the poles dropped and why, the resynthesis's
//! 1/3-octave distance to the recording over the first 0.5 s
//! (`compare_real::analysis`, as `cargo xtask compare-real` measures it),
//! the residual's energy, and the distance of the written scene's render.

use anyhow::{Context, Result};
use clap::Args;
// the 1/3-octave distance over the first 0.5 s after the onset, the one
// the mallet is fitted by
use modal_contact::recording::fit_distance as distance;
use modal_contact::recording::{
    analyze, object_scene, read_wav, render_from_onset, Analysis, AnalysisOptions, Channel,
    DropReason, MalletEstimate, DEFAULT_MALLET_KG,
};
use std::path::PathBuf;

/// The stretch the 1/3-octave distances are measured over \[s\]: the one
/// the mallet's contact time is fitted over.
pub const DISTANCE_S: f64 = modal_contact::recording::FIT_S;

/// `cargo xtask analyze STRIKE.wav --out OBJECT.toml [options]`.
#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    /// The recorded strike: a WAV file (16/24/32-bit integer or 32-bit
    /// float, 22.05 to 192 kHz), the strike near its start and its decay
    /// after it.
    wav: PathBuf,
    /// The scene file to write.
    #[arg(long)]
    out: PathBuf,
    /// The channel analysed (0 = the first, the left); default: the mean
    /// of all channels.
    #[arg(long)]
    channel: Option<usize>,
    /// Start of the span fitted, from the file's start [s]; default: 5 ms
    /// after the onset (and after any clipping).
    #[arg(long)]
    start: Option<f64>,
    /// End of the span fitted [s]; default: the file's end.
    #[arg(long)]
    end: Option<f64>,
    /// Keep at most this many modes (the strongest).
    #[arg(long)]
    modes: Option<usize>,
    /// Lowest mode frequency [Hz].
    #[arg(long, default_value_t = 20.0)]
    min_freq: f64,
    /// Highest mode frequency [Hz] (capped at Nyquist).
    #[arg(long, default_value_t = 20_000.0)]
    max_freq: f64,
    /// The mallet's mass in the scene [kg].
    #[arg(long, default_value_t = DEFAULT_MALLET_KG)]
    mallet_kg: f64,
    /// The scene's name; default: the WAV file's name without extension.
    #[arg(long)]
    name: Option<String>,
}

/// An analysis and what it gives: the scene written, its mallet, and the
/// distances `cargo xtask analyze` reports.
pub struct Fit {
    /// The modes, the poles dropped, onset and span.
    pub an: Analysis,
    /// The scene file's text.
    pub text: String,
    /// The mallet estimated from the attack.
    pub mallet: MalletEstimate,
    /// The resynthesis's 1/3-octave distance to the recording over the
    /// first [`DISTANCE_S`] after the onset \[dB\].
    pub resynthesis_db: f64,
    /// The residual's energy (recording - resynthesis) over the span
    /// fitted, relative to the recording's \[dB\].
    pub residual_db: f64,
    /// The written scene's render: its 1/3-octave distance to the
    /// recording over the first [`DISTANCE_S`] \[dB\].
    pub render_db: f64,
    /// The same two distances over [`DISTANCE_S`] from the start of the
    /// span fitted instead of the onset (resynthesis, render): the free
    /// decay the modes were fitted on, without the attack \[dB\].
    pub decay_db: (f64, f64),
}

/// The analysis of `x` (at `rate_hz`) with `opts`, the scene named `name`
/// with a mallet of `mallet_kg`, and the distances: what `cargo xtask
/// analyze` does, for it and for `cargo xtask analyze-real`.
pub fn fit(
    x: &[f64],
    rate_hz: f64,
    opts: &AnalysisOptions,
    name: &str,
    mallet_kg: f64,
) -> Result<Fit> {
    let an = analyze(x, rate_hz, opts)?;
    let (text, mallet) = object_scene(&an, x, name, mallet_kg)?;
    let model = an.resynthesize(x.len());
    let from = an.onset;
    let resynthesis_db = distance(&x[from..], &model[from..], an.rate_hz);
    let residual_db = an.residual_db(x);
    let render = render_aligned(&an, &text)?;
    let render_db = distance(&x[from..], &render, an.rate_hz);
    let settle = an.span.0 - from;
    let decay_db = (
        distance(&x[an.span.0..], &model[an.span.0..], an.rate_hz),
        distance(
            &x[an.span.0..],
            render.get(settle..).unwrap_or(&[]),
            an.rate_hz,
        ),
    );
    Ok(Fit {
        an,
        text,
        mallet,
        resynthesis_db,
        residual_db,
        render_db,
        decay_db,
    })
}

/// Analyse, write the scene, print the report.
pub fn run(a: &AnalyzeArgs) -> Result<()> {
    let channel = a.channel.map_or(Channel::Mix, Channel::Index);
    let rec = read_wav(&a.wav, channel)?;
    let opts = AnalysisOptions {
        freq_range_hz: (a.min_freq, a.max_freq),
        start_s: a.start,
        end_s: a.end,
        max_modes: a.modes,
        ..AnalysisOptions::default()
    };
    let x = &rec.samples;
    let name = a.name.clone().unwrap_or_else(|| {
        a.wav
            .file_stem()
            .map_or("recording".into(), |s| s.to_string_lossy().into_owned())
    });
    let f = fit(x, rec.rate_hz, &opts, &name, a.mallet_kg)?;
    std::fs::write(&a.out, &f.text).with_context(|| format!("writing {}", a.out.display()))?;
    println!(
        "{}: {} channel(s), {}, {} Hz, {:.3} s; analysed {}",
        a.wav.display(),
        rec.channels,
        rec.format,
        rec.rate_hz,
        x.len() as f64 / rec.rate_hz,
        match channel {
            Channel::Mix => "the mean of the channels".to_string(),
            Channel::Index(c) => format!("channel {c}"),
        }
    );
    let an = &f.an;
    print_span(an);
    print_modes(an);
    print_dropped(an);
    println!(
        "resynthesis: 1/3-octave distance to the recording {:.2} dB over the first {DISTANCE_S} s; \
         residual (recording - resynthesis) {:.1} dB of the recording's energy over the span fitted",
        f.resynthesis_db, f.residual_db
    );
    println!(
        "the scene's render: 1/3-octave distance to the recording {:.2} dB over the first {DISTANCE_S} s",
        f.render_db
    );
    println!(
        "over {DISTANCE_S} s from the span fitted's start (the free decay, no attack): \
         resynthesis {:.2} dB, render {:.2} dB",
        f.decay_db.0, f.decay_db.1
    );
    let mallet = &f.mallet;
    println!(
        "mallet: {:.0} g, contact {:.3} ms (fitted against {} renders from {:.3} ms; onset slope {:.3} ms, \
         highest strong mode {:.0} Hz), stiffness {:.4e} N/m, damping ratio {:.3}, weights corrected \
         in {} round(s)",
        1e3 * mallet.mass_kg,
        1e3 * mallet.contact_s,
        mallet.renders,
        1e3 * mallet.first_s,
        1e3 * mallet.rise_s,
        mallet.top_mode_hz,
        mallet.stiffness_n_per_m,
        mallet.damping_ratio,
        mallet.weight_rounds
    );
    println!("wrote {}", a.out.display());
    Ok(())
}

/// Onset, span, clipping, noise, bands.
fn print_span(an: &Analysis) {
    let s = |i: usize| i as f64 / an.rate_hz;
    println!(
        "onset at {:.4} s; fitted {:.4} to {:.4} s; noise {:.1} dB under the peak; \
         {} bands of {:.1} Hz (decimation {})",
        s(an.onset),
        s(an.span.0),
        s(an.span.1),
        -an.noise_db,
        an.bands.0,
        an.bands.1,
        an.bands.2
    );
    if let Some(c) = &an.clipping {
        println!(
            "CLIPPED: {} run(s) of {} samples at full scale, the last ending at {:.4} s; \
             the fit starts after it",
            c.runs,
            c.samples,
            s(c.end)
        );
    }
}

/// The modes found.
fn print_modes(an: &Analysis) {
    println!("{} modes:", an.modes.len());
    println!(
        "  {:>12} {:>10} {:>9} {:>9} {:>8}   {:>10} {:>8}",
        "freq [Hz]", "T60 [s]", "level dB", "phase", "SNR dB", "sd(f) Hz", "sd(T60)"
    );
    for m in &an.modes {
        println!(
            "  {:>12.4} {:>10.4} {:>9.1} {:>9.3} {:>8.1}   {:>10.2e} {:>7.2}%",
            m.freq_hz,
            m.t60_s,
            m.level_db(),
            m.phase_rad,
            m.snr_db,
            m.freq_sd_hz,
            100.0 * m.t60_rel_sd
        );
    }
}

/// The poles dropped: counted by reason; listed, but for those outside a
/// band's centre (each is the neighbouring band's to fit).
fn print_dropped(an: &Analysis) {
    let outside = an
        .dropped
        .iter()
        .filter(|d| d.reason == DropReason::OutsideBandCentre)
        .count();
    println!(
        "{} poles dropped ({} outside their band's centre, fitted by the neighbouring band):",
        an.dropped.len(),
        outside
    );
    for d in an
        .dropped
        .iter()
        .filter(|d| d.reason != DropReason::OutsideBandCentre)
    {
        println!(
            "  {:>12.4} Hz  T60 {:>10.4} s  {:>7.1} dB  {}",
            d.freq_hz, d.t60_s, d.level_db, d.reason
        );
    }
}

/// The written scene rendered offline from its onset, long enough for the
/// distance over the free decay.
fn render_aligned(an: &Analysis, text: &str) -> Result<Vec<f64>> {
    Ok(render_from_onset(text, an.rate_hz, 2.0 * DISTANCE_S + 0.1)?)
}
