//! The report `cargo xtask compare-real` writes (docs/compare-real.md):
//! its header and method, the summary and its tally, the scales of
//! "close", the confusion table, the strokes, and each preset's section
//! with its plots. The measuring is in `measure.rs`.

use super::measure::distance;
use super::wavs::write_pair;
use super::*;

/// The stroke of each scraped or rolled preset beside its recording's
/// (nothing for a set of struck presets).
pub(super) fn write_strokes(body: &mut String, comparisons: &[Result<Comparison>]) {
    let strokes: Vec<(&Comparison, (stroke::Stroke, stroke::Stroke))> = comparisons
        .iter()
        .flatten()
        .filter_map(|c| c.strokes.map(|s| (c, s)))
        .collect();
    if strokes.is_empty() {
        return;
    }
    let _ = writeln!(
        body,
        "## Strokes\n\nA scraped or rolled preset against its recording: how long it sounds \
         (from the first to the last 5 ms frame within 20 dB of the loudest) and how often its \
         contact clicks (the strongest period, 1.5 to 40 ms, of the autocorrelation of its RMS \
         envelope in 0.5 ms frames over that time, with that correlation). The partial and decay \
         targets are a strike's and do not apply to a stroke.\n\n\
         | preset | recording | sounding render / real [s] | clicks a second render / real (correlation) |\n\
         |---|---|---|---|"
    );
    let clicks = |s: &stroke::Stroke| {
        s.clicks
            .map_or("none".into(), |(hz, r)| format!("{hz:.0} ({r:.2})"))
    };
    for (c, (real, render)) in strokes {
        let _ = writeln!(
            body,
            "| {} | {} | {:.3} / {:.3} | {} / {} |",
            c.stem,
            c.sound.label(),
            render.sounding_s,
            real.sounding_s,
            clicks(&render),
            clicks(&real)
        );
    }
    body.push('\n');
}

pub(super) fn fmt_t60(t: &T60) -> String {
    match t {
        T60::Fit { t60_s, to_end, .. } => {
            format!("{t60_s:.2}{}", if *to_end { " (to end)" } else { "" })
        }
        T60::NoFit(why) => format!("no fit: {why}"),
    }
}

pub(super) fn fmt_hz(f: f64) -> String {
    if f >= 1000.0 {
        format!("{:.2} k", f / 1000.0)
    } else {
        format!("{f:.1}")
    }
}

/// The report's method section.
pub(super) fn method_text(seconds: f64) -> String {
    format!(
        "Each preset's strike is rendered as `cargo xtask render presets/NAME.toml --seconds {seconds}` renders it \
(the scene as written, {RATE_HZ} Hz, the two channels mixed to mono). The recording is the raw sample data of \
the FluidR3 soundfont's zones for the instrument (General MIDI bank 0 program, or the standard kit, bank 128, for a \
percussion key) at the preset's key (`modal_contact::instrument::root_note`, rounded) and velocity {VELOCITY}, played as a sampler plays it \
and nothing more: transposed by scaleTuning x (key - root key) + coarse and fine tune + the sample's pitch \
correction, resampled to {RATE_HZ} Hz by windowed-sinc interpolation, the zones (a stereo pair's left and right) \
mixed to mono; no envelope, filter, effect or loop (a looped sample ends where its data ends). Percussion keys \
are played at their own key (only their fine tune applies). A pitched recording is never transposed by more than \
an octave (further from its recorded pitch a sample no longer sounds like the instrument: its timbre and band \
limit move with it): where the preset's key would ask for more, it is played at the nearest key within an octave \
and the report says so. Both signals start at their onset (1 ms before the \
first sample within 40 dB of the peak); levels are normalised (every measure below is a ratio).

- **Partials**: peaks of a Hann-windowed spectrum of the first {PARTIAL_WINDOW_S} s (zero-padded 4x, \
parabolic interpolation), each the largest within +-3 % and within {PEAK_RANGE_DB} dB of the strongest; the \
recording's {PARTIALS} strongest, their ratio to the lowest of them, and the render's nearest peak (render peaks \
count within {RENDER_RANGE_DB} dB of the render's strongest), its level relative to the render's strongest and \
the error in cents.
- **T60**: each partial's level per frame of a 4096-point Hann STFT (hop 512; the largest bin within +-2 bins), \
a least-squares line in dB from 3 dB below its peak down to 10 dB above the noise floor (the median of the last \
10 % of the frames when the track has levelled off there; when it still falls, the signal ended first and the \
line runs to its end: \"to end\") or 60 dB below its start, whichever comes first (a render has no noise floor); \
T60 = 60 dB / slope, no fit below {min} dB of fitted decay. The render's decay is fitted at its partial within \
{T60_MATCH_CENTS} cents of the real one.
- **Attack**: the first {attack} ms (1 ms fade-in, 5 ms fade-out): the power-weighted spectral centroid above 20 Hz, \
and the energy above {hf} kHz as a fraction of the total, in dB.
- **1/3-octave distance**: band energies of the first {WINDOW_S} s (or the shorter signal's length; 8192-point \
Hann frames at hop 2048, a 10 ms fade-out at the end), 26 bands 50 Hz - 16 kHz (IEC 61260 base-10 centres), each \
over the sum of the 26 bands in dB and floored {floor} dB below the loudest band; the distance is the RMS over the \
bands of the two sets' difference (`analysis::third_octave_distance`).
- **Targets** (issue 49): distance <= {TARGET_DISTANCE_DB} dB; centroid ratio (render / real) within \
{c0}-{c1}; energy above 5 kHz within +-{TARGET_HF_DB} dB of the real's; the recording's {PARTIALS} strongest \
partials present in the render within {TARGET_CENTS} cents; T60 ratio within {TARGET_T60_FACTOR}x for each \
partial with a fit on both; the nearest recording in the confusion table is the preset's own instrument.",
        min = analysis::MIN_FIT_DB,
        attack = ATTACK_S * 1000.0,
        hf = HF_HZ / 1000.0,
        floor = analysis::BAND_FLOOR_DB,
        c0 = TARGET_CENTROID.0,
        c1 = TARGET_CENTROID.1,
    )
}

/// The report's title and the line that says how it was made.
pub(super) fn report_header(a: &CompareRealArgs) -> String {
    let sf_size = std::fs::metadata(&a.sf2).map(|m| m.len()).unwrap_or(0);
    let mut md = String::new();
    let _ = writeln!(md, "# Presets against real recordings\n");
    let only = if a.presets.is_empty() {
        String::new()
    } else {
        format!(" --preset {}", a.presets.join(" --preset "))
    };
    let _ = writeln!(
        md,
        "Generated by `cargo xtask compare-real{only}` on {} with {}, soundfont {} ({sf_size} bytes, Debian \
         package `{SF2_PACKAGE}`); do not edit by hand.\n",
        today(),
        rustc_version(),
        file_name(&a.sf2)
    );
    md
}

/// The targets' count over the report.
pub(super) struct Tally {
    /// The summary's last line.
    pub(super) summary: String,
    /// Targets failed (an error or an unknown instrument counts one).
    pub(super) failed: usize,
    /// What failed: the presets, or the errors.
    pub(super) failures: Vec<String>,
}

/// The summary section: a line per comparison, the presets not compared,
/// and the targets' count.
pub(super) fn write_summary(
    body: &mut String,
    comparisons: &[Result<Comparison>],
    chosen: &[&PresetFile],
) -> Tally {
    let _ = writeln!(body, "## Summary\n");
    let _ = writeln!(
        body,
        "| preset | real instrument | key | distance [dB] | centroid render/real | > 5 kHz render-real [dB] | partials within 15 cents | T60 within 1.5x | nearest recording | targets passed |"
    );
    let _ = writeln!(body, "|---|---|---|---|---|---|---|---|---|---|");
    let (mut passed, mut failed, mut failures) = (0, 0, Vec::new());
    for c in comparisons {
        match c {
            Ok(c) => {
                let t =
                    |i: usize| format!("{} {}", c.targets[i].detail, c.targets[i].verdict.word());
                let p = c
                    .targets
                    .iter()
                    .filter(|t| t.verdict == Verdict::Pass)
                    .count();
                let f = c
                    .targets
                    .iter()
                    .filter(|t| t.verdict == Verdict::Fail)
                    .count();
                passed += p;
                failed += f;
                if f > 0 {
                    failures.push(c.stem.clone());
                }
                let _ = writeln!(
                    body,
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {p} of {} |",
                    c.stem,
                    c.sound.label(),
                    c.key,
                    t(0),
                    t(1),
                    t(2),
                    t(3),
                    t(4),
                    t(5),
                    c.targets
                        .iter()
                        .filter(|t| t.verdict != Verdict::NotApplicable)
                        .count()
                );
            }
            Err(e) => {
                failed += 1;
                let _ = writeln!(body, "| error | {e:#} | | | | | | | | |");
                failures.push(format!("{e:#}"));
            }
        }
    }
    let mut not_compared = Vec::new();
    for p in chosen {
        match &p.real {
            Ok(Some(_)) => {}
            Ok(None) => {
                let why = NO_RECORDING
                    .iter()
                    .find(|(s, _)| *s == p.stem)
                    .map_or("names no real instrument".to_string(), |(_, w)| {
                        format!("no fitting recording in FluidR3: {w}")
                    });
                not_compared.push(format!("- {}: not compared ({why})", p.stem));
            }
            Err(e) => {
                failed += 1;
                failures.push(format!("{}: {e}", p.stem));
                not_compared.push(format!("- {}: not compared ({e})", p.stem));
            }
        }
    }
    let summary = format!(
        "Targets: {passed} passed, {failed} failed over {} compared presets ({} pass all); n/a targets are not counted.",
        comparisons.len(),
        comparisons
            .iter()
            .filter(|c| c.as_ref().is_ok_and(|c| c.targets.iter().all(|t| t.verdict != Verdict::Fail)))
            .count()
    );
    let _ = writeln!(body, "\n{summary}\n");
    if !not_compared.is_empty() {
        let _ = writeln!(body, "{}\n", not_compared.join("\n"));
    }
    Tally {
        summary,
        failed,
        failures,
    }
}

/// The scale of close: recordings of related instruments, pair by pair.
pub(super) fn write_scale_pairs(
    body: &mut String,
    pairs: &[(GmSound, GmSound, u8)],
    recs: &BTreeMap<RecordingKey, Played>,
) {
    let _ = writeln!(
        body,
        "## The scale of \"close\": recordings of related instruments\n"
    );
    let _ = writeln!(body, "| recording | recording | key | distance [dB] |");
    let _ = writeln!(body, "|---|---|---|---|");
    for &(x, y, k) in pairs {
        let (rx, ry) = (&recs[&(x, x.key_for(k))], &recs[&(y, y.key_for(k))]);
        let key = match (x.is_drum(), y.is_drum()) {
            (true, true) => "kit keys".to_string(),
            (false, false) => k.to_string(),
            _ => format!("{k} (the program)"),
        };
        let d = match (rx, ry) {
            (Ok(a), Ok(b)) => format!("{:.1}", distance(&a.played, &b.played)),
            (Err(e), _) | (_, Err(e)) => format!("n/a: {e}"),
        };
        let _ = writeln!(body, "| {} | {} | {key} | {d} |", x.label(), y.label());
    }
    let _ = writeln!(body);
}

/// The scale of close: each instrument's recording against another
/// recording of it.
pub(super) fn write_other_recordings(
    body: &mut String,
    others: &[(GmSound, u8, Option<Played>)],
    recs: &BTreeMap<RecordingKey, Played>,
) {
    let _ = writeln!(
        body,
        "## The scale of \"close\": the same instrument, another recording\n\n\
         Each instrument a preset names, at that preset's key: its recording against another recording of the \
         same instrument in FluidR3 (a pitched instrument: the samples of the nearest other key range, played at \
         the key, transposed at most an octave; a percussion key: the same key of another kit, {}), by the same \
         1/3-octave distance. Two recordings of one instrument differ by this much; a render cannot be expected \
         to come much closer.\n",
        OTHER_KITS
            .iter()
            .map(|k| format!("bank 128 program {k}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        body,
        "| instrument | key | recording | another recording | distance [dB] |"
    );
    let _ = writeln!(body, "|---|---|---|---|---|");
    let sample_names = |r: &KeyRegion| {
        r.zones
            .iter()
            .map(|z| format!("\"{}\"", z.name))
            .collect::<Vec<_>>()
            .join(" + ")
    };
    for (s, k, other) in others {
        let own = &recs.get(&(*s, s.key_for(*k)));
        let (own_desc, d) = match (own, other) {
            (Some(Ok(a)), Some(Ok(b))) => (
                sample_names(&a.region),
                format!("{:.1}", distance(&a.played, &b.played)),
            ),
            (Some(Ok(a)), None) => (sample_names(&a.region), "n/a: no other recording".into()),
            (Some(Err(e)), _) | (_, Some(Err(e))) => (String::new(), format!("n/a: {e}")),
            (None, _) => (String::new(), "n/a: not played".into()),
        };
        let other_desc = match other {
            Some(Ok(b)) => {
                let r = &b.region;
                let semis = r
                    .zones
                    .iter()
                    .map(|z| z.cents / 100.0)
                    .fold(0.0, |a: f64, c| if c.abs() > a.abs() { c } else { a });
                format!(
                    "{} (\"{}\", bank {} program {}), transposed {semis:+.2} semitones",
                    sample_names(r),
                    r.preset_name,
                    r.bank,
                    r.program
                )
            }
            _ => "none".into(),
        };
        let _ = writeln!(
            body,
            "| {} | {} | {own_desc} | {other_desc} | {d} |",
            s.label(),
            s.key_for(*k)
        );
    }
    let _ = writeln!(body);
}

/// The confusion table: each preset's render against every recording of
/// the set.
pub(super) fn write_confusion(
    body: &mut String,
    set: &[GmSound],
    comparisons: &[Result<Comparison>],
) {
    let _ = writeln!(
        body,
        "## Confusion table\n\nThe 1/3-octave distance [dB] of each preset's render (its key in brackets) to every \
         recording, pitched recordings played at the preset's key; **bold**: the nearest; `!`: the nearest is not \
         the preset's own instrument (marked `=`).\n"
    );
    let mut head = "| preset |".to_string();
    let mut rule = "|---|".to_string();
    for s in set {
        let _ = write!(head, " {} |", s.name());
        rule.push_str("---|");
    }
    let _ = writeln!(body, "{head}\n{rule}");
    let mut moved = false;
    for c in comparisons.iter().flatten() {
        let nearest = c
            .confusion
            .iter()
            .filter_map(|(s, d, _)| d.map(|d| (*s, d)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(s, _)| s);
        let flag = if nearest == Some(c.sound) { "" } else { " !" };
        let _ = write!(body, "| {} ({}){flag} |", c.stem, c.key);
        for (s, d, k) in &c.confusion {
            let own = if *s == c.sound { "=" } else { "" };
            let at = if *k != s.key_for(c.key) {
                moved = true;
                format!(" @{k}")
            } else {
                String::new()
            };
            let cell = match d {
                Some(d) if Some(*s) == nearest => format!("**{own}{d:.1}**{at}"),
                Some(d) => format!("{own}{d:.1}{at}"),
                None => "n/a".into(),
            };
            let _ = write!(body, " {cell} |");
        }
        let _ = writeln!(body);
    }
    if moved {
        let _ = writeln!(
            body,
            "\n`@K`: played at key K, the nearest key within an octave of the recording (at the preset's key it \
             would be transposed further)."
        );
    }
    let _ = writeln!(body);
}

/// A preset's section: its recording, its partials and measures, its
/// targets (`seconds`: the render's length).
pub(super) fn write_preset_table(body: &mut String, c: &Comparison, seconds: f64) {
    let _ = writeln!(body, "## {} ({})\n", c.stem, c.sound.label());
    let _ = writeln!(body, "Recording: {}.\n", c.recording);
    let _ = writeln!(
        body,
        "Render: {} s at {RATE_HZ} Hz, onset at {:.1} ms. Spectra over the first {:.2} s.\n",
        seconds,
        c.render_onset_s * 1000.0,
        c.window_s
    );
    let _ = writeln!(
        body,
        "| # | real [Hz] | ratio | real level [dB] | render nearest [Hz] | render level [dB] | error [cents] | within 15 cents | T60 real [s] | T60 render [s] | render/real |"
    );
    let _ = writeln!(body, "|---|---|---|---|---|---|---|---|---|---|---|");
    for (i, r) in c.rows.iter().enumerate() {
        let (rf, rl, rc) = match r.render {
            Some((q, cents)) => (
                fmt_hz(q.freq_hz),
                format!("{:.1}", q.level_db),
                format!("{cents:+.1}"),
            ),
            None => ("none".into(), String::new(), String::new()),
        };
        let _ = writeln!(
            body,
            "| {} | {} | {:.3} | {:.1} | {rf} | {rl} | {rc} | {} | {} | {} | {} |",
            i + 1,
            fmt_hz(r.real.freq_hz),
            r.ratio,
            r.real.level_db,
            if r.present() { "yes" } else { "no" },
            fmt_t60(&r.t60_real),
            r.t60_render
                .as_ref()
                .map_or("no partial within 50 cents".into(), fmt_t60),
            r.t60_ratio().map_or(String::new(), |x| format!("{x:.2}")),
        );
    }
    let _ = writeln!(body);
    let _ = writeln!(body, "| measure | real | render | render vs real |");
    let _ = writeln!(body, "|---|---|---|---|");
    let _ = writeln!(
        body,
        "| attack centroid ({} ms) | {:.0} Hz | {:.0} Hz | {:.2}x |",
        ATTACK_S * 1000.0,
        c.centroid.0,
        c.centroid.1,
        c.centroid.1 / c.centroid.0
    );
    let _ = writeln!(
        body,
        "| energy above 5 kHz ({} ms) | {:.1} dB | {:.1} dB | {:+.1} dB |",
        ATTACK_S * 1000.0,
        c.hf_db.0,
        c.hf_db.1,
        c.hf_db.1 - c.hf_db.0
    );
    let _ = writeln!(body, "| 1/3-octave distance | | | {:.1} dB |\n", c.distance);
    let line: Vec<String> = c
        .targets
        .iter()
        .map(|t| format!("{}: {} ({})", t.name, t.verdict.word(), t.detail))
        .collect();
    let _ = writeln!(body, "Targets: {}.\n", line.join("; "));
}

/// A preset's plots, linked from its section, and its WAV pair.
pub(super) fn write_preset_plots(
    body: &mut String,
    c: &Comparison,
    plot_dir: &Path,
    wav_dir: &Path,
) -> Result<()> {
    let spec_svg = plot_dir.join(format!("{}-spectrum.svg", c.stem));
    let t60_svg = plot_dir.join(format!("{}-t60.svg", c.stem));
    plots::spectra(
        &c.spectra.0,
        &c.spectra.1,
        &c.rows.iter().map(|r| r.real.freq_hz).collect::<Vec<_>>(),
        &format!(
            "{} against {}: first {:.2} s",
            c.stem,
            c.sound.name(),
            c.window_s
        ),
        &spec_svg,
    )?;
    if c.strokes.is_some() {
        // a stroke has no partials ringing down: no T60 plot
        let _ = writeln!(
            body,
            "![{0} spectra](compare-real/{0}-spectrum.svg)\n",
            c.stem
        );
    } else {
        plots::decays(
            &c.decays.0,
            &c.decays.1,
            &format!("{} against {}: T60 per partial", c.stem, c.sound.name()),
            &t60_svg,
        )?;
        let _ = writeln!(
            body,
            "![{0} spectra](compare-real/{0}-spectrum.svg)\n![{0} T60](compare-real/{0}-t60.svg)\n",
            c.stem
        );
    }
    write_pair(wav_dir, &c.stem, &c.signals.0, &c.signals.1)
}
