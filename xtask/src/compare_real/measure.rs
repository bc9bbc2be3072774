//! The measuring of one preset against its recording ([`compare`]): the
//! partials and their decays, the attack, the 1/3-octave distance and the
//! distances to the confusion set.

use super::targets::targets;
use super::*;

/// The partials of a sound: the strongest peaks of its long spectrum.
fn partials(s: &Sound, range_db: f64) -> Vec<Peak> {
    let (spec, n) = analysis::long_spectrum(&s.x, RATE_HZ, PARTIAL_WINDOW_S);
    let hi = (0.95 * s.band_limit_hz).min(20000.0);
    analysis::peaks(&spec, n, 30.0, hi, range_db)
}

/// The 1/3-octave distance between two sounds over the first
/// [`WINDOW_S`] (or the shorter one's length).
pub(super) fn distance(a: &Sound, b: &Sound) -> f64 {
    let t = WINDOW_S.min(a.seconds()).min(b.seconds());
    let la = analysis::band_levels(&analysis::welch(&a.x, RATE_HZ, t));
    let lb = analysis::band_levels(&analysis::welch(&b.x, RATE_HZ, t));
    analysis::third_octave_distance(&la, &lb)
}

/// The decays of a sound's partials.
fn decays(s: &Sound, frames: &[Vec<f64>], peaks: &[Peak]) -> Decays {
    peaks
        .iter()
        .map(|p| {
            (
                p.freq_hz,
                analysis::fit_t60(&analysis::track(frames, RATE_HZ, p.freq_hz)),
            )
        })
        .filter(|_| !s.x.is_empty())
        .collect()
}

/// Measure a preset against its recording and the confusion set.
pub(super) fn compare(
    p: &PresetFile,
    sound: GmSound,
    render: &Sound,
    recs: &BTreeMap<RecordingKey, std::result::Result<Recording, String>>,
    keys: &BTreeMap<RecordingKey, u8>,
    set: &[GmSound],
) -> Result<Comparison> {
    let own_key = keys[&(sound, p.key)];
    let own = match &recs[&(sound, own_key)] {
        Ok(r) => r,
        Err(e) => bail!("{e}"),
    };
    let real = &own.played;
    let window_s = WINDOW_S.min(real.seconds()).min(render.seconds());

    // partials
    let real_peaks = partials(real, PEAK_RANGE_DB);
    let render_peaks = partials(render, RENDER_RANGE_DB);
    let real_frames = analysis::stft(&real.x);
    let render_frames = analysis::stft(&render.x);
    let rows = partial_rows(&real_peaks, &render_peaks, &real_frames, &render_frames);

    // attack
    let ra = analysis::attack_spectrum(&real.x, RATE_HZ, ATTACK_S);
    let ga = analysis::attack_spectrum(&render.x, RATE_HZ, ATTACK_S);
    let centroid = (analysis::centroid(&ra), analysis::centroid(&ga));
    let hf_db = (
        analysis::fraction_above_db(&ra, HF_HZ),
        analysis::fraction_above_db(&ga, HF_HZ),
    );

    // bands
    let spectra = (
        analysis::welch(&real.x, RATE_HZ, window_s),
        analysis::welch(&render.x, RATE_HZ, window_s),
    );
    let dist = analysis::third_octave_distance(
        &analysis::band_levels(&spectra.0),
        &analysis::band_levels(&spectra.1),
    );
    let confusion = confusion_distances(render, p.key, recs, keys, set);

    let real_top: Vec<Peak> = real_peaks.iter().copied().take(PLOT_PARTIALS).collect();
    let render_top: Vec<Peak> = render_peaks.iter().copied().take(PLOT_PARTIALS).collect();
    let mut c = Comparison {
        stem: p.stem.clone(),
        sound,
        key: p.key,
        recording: if own_key == sound.key_for(p.key) {
            own.describe()
        } else {
            format!(
                "{}. Played at key {own_key}, not at the preset's key {}: there the recording would be \
                 transposed by more than an octave (see the method)",
                own.describe(),
                p.key
            )
        },
        render_onset_s: render.onset_s,
        window_s,
        rows,
        centroid,
        hf_db,
        distance: dist,
        confusion,
        targets: Vec::new(),
        decays: (
            decays(real, &real_frames, &real_top),
            decays(render, &render_frames, &render_top),
        ),
        spectra,
        signals: (real.x.clone(), render.x.clone()),
        strokes: p.scene.drive.is_some().then(|| {
            (
                stroke::stroke(&real.x, RATE_HZ),
                stroke::stroke(&render.x, RATE_HZ),
            )
        }),
    };
    c.targets = targets(&c, real.band_limit_hz, own_key);
    Ok(c)
}

/// The recording's strongest [`PARTIALS`] partials, each with the
/// render's nearest partial and both decays (`*_frames`: the two STFTs).
fn partial_rows(
    real_peaks: &[Peak],
    render_peaks: &[Peak],
    real_frames: &[Vec<f64>],
    render_frames: &[Vec<f64>],
) -> Vec<PartialRow> {
    let strongest: Vec<Peak> = real_peaks.iter().copied().take(PARTIALS).collect();
    let lowest = strongest
        .iter()
        .map(|p| p.freq_hz)
        .fold(f64::INFINITY, f64::min);
    strongest
        .iter()
        .map(|&rp| {
            let near = render_peaks
                .iter()
                .map(|q| (*q, analysis::cents(rp.freq_hz, q.freq_hz)))
                .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
            let t60_render = near
                .filter(|(_, c)| c.abs() <= T60_MATCH_CENTS)
                .map(|(q, _)| {
                    analysis::fit_t60(&analysis::track(render_frames, RATE_HZ, q.freq_hz))
                });
            PartialRow {
                real: rp,
                ratio: rp.freq_hz / lowest,
                render: near,
                t60_real: analysis::fit_t60(&analysis::track(real_frames, RATE_HZ, rp.freq_hz)),
                t60_render,
            }
        })
        .collect::<Vec<_>>()
}

/// The render's distance to the recording of every sound of the set
/// `set` at `key` (`None`: no zone), and the key each was played at.
fn confusion_distances(
    render: &Sound,
    key: u8,
    recs: &BTreeMap<RecordingKey, std::result::Result<Recording, String>>,
    keys: &BTreeMap<RecordingKey, u8>,
    set: &[GmSound],
) -> Vec<(GmSound, Option<f64>, u8)> {
    set.iter()
        .map(|&s| {
            let k = keys[&(s, key)];
            let d = recs[&(s, k)]
                .as_ref()
                .ok()
                .map(|r| distance(render, &r.played));
            (s, d, k)
        })
        .collect()
}
