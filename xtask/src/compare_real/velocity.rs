//! Brightness against velocity (issue 51's pp-ff table): each compared
//! preset's attack centroid with its `[hammer]` thrown at the impact speed
//! the instrument gives MIDI velocities 20 to 127
//! (`instrument::impact_speed_m_per_s`), beside the attack centroid of
//! each velocity layer of its recording in FluidR3 (the zones that sound at
//! each of those velocities; velocities that play the same samples are one
//! layer: the raw samples carry no velocity filter).

use super::analysis::{attack_spectrum, centroid};
use super::gm::GmSound;
use super::sf2::SoundFont;
use super::{render_mono, PresetFile, RecordingKey, Sound, ATTACK_S, RATE_HZ};
use modal_contact::instrument::{drive_speed_m_per_s, impact_speed_m_per_s};
use modal_contact::scene::Scene;
use rayon::prelude::*;
use std::fmt::Write as _;

/// The MIDI velocities measured (pp to ff).
pub(super) const VELOCITIES: [u8; 5] = [20, 40, 64, 100, 127];

/// How long each render is \[s\] (the attack is its first [`ATTACK_S`]).
const RENDER_S: f64 = 0.5;

/// One preset's row: its render's centroid at each of [`VELOCITIES`], and
/// its recording's layers (the velocities that play them, their samples'
/// names, their centroid).
pub(super) struct VelocityRow {
    stem: String,
    renders: Vec<Result<f64, String>>,
    layers: Vec<(Vec<u8>, String, Result<f64, String>)>,
}

/// The attack centroid \[Hz\] of a played or rendered signal, from its
/// onset.
fn attack_centroid(full: &[f64], band_limit_hz: f64) -> f64 {
    let s = Sound::new(full, band_limit_hz);
    centroid(&attack_spectrum(&s.x, RATE_HZ, ATTACK_S))
}

/// The attack centroid \[Hz\] of `scene` struck at each of [`VELOCITIES`]
/// (its `[hammer]` at the instrument's impact speed; a driven scene's
/// stroke at the speed the instrument gives that velocity, its hammer as
/// written), side by side.
fn render_centroids(scene: &Scene) -> Vec<Result<f64, String>> {
    VELOCITIES
        .par_iter()
        .map(|&v| {
            let mut scene = scene.clone();
            let speed = impact_speed_m_per_s(f64::from(v) / 127.0);
            match &mut scene.drive {
                Some(d) => d.speed_m_per_s = drive_speed_m_per_s(d.speed_m_per_s, speed),
                None => scene.hammer.velocity_m_per_s = -speed,
            }
            render_mono(&scene, RENDER_S)
                .map(|x| attack_centroid(&x, 0.5 * RATE_HZ))
                .map_err(|e| format!("{e:#}"))
        })
        .collect()
}

/// The rows of `compared`, each recording at the key `keys` gives its
/// preset (the key its comparison plays). Renders and recordings side by
/// side.
pub(super) fn rows(
    sf: &SoundFont,
    compared: &[(&PresetFile, GmSound)],
    key_of: impl Fn(&PresetFile, GmSound) -> u8 + Sync,
) -> Vec<VelocityRow> {
    compared
        .par_iter()
        .map(|(p, s)| {
            let renders = render_centroids(&p.scene);
            let key: RecordingKey = (*s, key_of(p, *s));
            let (bank, program) = s.bank_program();
            let mut layers: Vec<(Vec<u8>, String, Result<f64, String>)> = Vec::new();
            for &v in &VELOCITIES {
                let region = match sf.key_region(bank, program, key.1, v) {
                    Ok(r) => r,
                    Err(e) => {
                        layers.push((vec![v], String::new(), Err(format!("{e:#}"))));
                        continue;
                    }
                };
                let names: Vec<&str> = region.zones.iter().map(|z| z.name.as_str()).collect();
                let names = names.join(" + ");
                if let Some(l) = layers.iter_mut().find(|l| l.1 == names) {
                    l.0.push(v);
                    continue;
                }
                let limit = region.band_limit_hz().min(0.5 * RATE_HZ);
                let c = region.play(RATE_HZ).map(|x| attack_centroid(&x, limit));
                layers.push((vec![v], names, c));
            }
            VelocityRow {
                stem: p.stem.clone(),
                renders,
                layers,
            }
        })
        .collect()
}

/// The section: a row per preset, its centroid at each velocity and the
/// ratio of ff's to pp's, then its recording's layers.
pub(super) fn write(body: &mut String, rows: &[VelocityRow]) {
    let _ = writeln!(
        body,
        "## Brightness against velocity\n\nThe attack centroid (first {} ms, as above) of each preset struck \
         at the impact speed the instrument gives a MIDI velocity (`instrument::impact_speed_m_per_s`: {}), its \
         `[hammer]` thrown as written otherwise, and of each velocity layer of its recording (FluidR3's zones at \
         those velocities at the compared key; velocities that play the same samples are one layer). A contact of \
         one linear piece lasts the same at every speed, so its centroid does not move; a stiffening law's rises \
         with the speed (docs/design.md, \"Stiffening contacts\").\n",
        (ATTACK_S * 1000.0).round(),
        VELOCITIES
            .iter()
            .map(|&v| format!("{v} -> {:.2} m/s", impact_speed_m_per_s(f64::from(v) / 127.0)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let head: Vec<String> = VELOCITIES.iter().map(|v| format!("{v} [Hz]")).collect();
    let _ = writeln!(
        body,
        "| preset | {} | {}/{} | recording's layers: velocities, centroid |",
        head.join(" | "),
        VELOCITIES[VELOCITIES.len() - 1],
        VELOCITIES[0]
    );
    let _ = writeln!(body, "|---|{}---|---|", "---|".repeat(VELOCITIES.len()));
    for r in rows {
        let cells: Vec<String> = r
            .renders
            .iter()
            .map(|c| match c {
                Ok(c) => format!("{c:.0}"),
                Err(_) => "error".to_string(),
            })
            .collect();
        let ratio = match (r.renders.first(), r.renders.last()) {
            (Some(Ok(a)), Some(Ok(b))) if *a > 0.0 => format!("{:.2}x", b / a),
            _ => "n/a".to_string(),
        };
        let layers: Vec<String> = r
            .layers
            .iter()
            .map(|(vs, _, c)| {
                let vs: Vec<String> = vs.iter().map(u8::to_string).collect();
                match c {
                    Ok(c) => format!("{}: {c:.0} Hz", vs.join(", ")),
                    Err(e) => format!("{}: {e}", vs.join(", ")),
                }
            })
            .collect();
        let _ = writeln!(
            body,
            "| {} | {} | {ratio} | {} |",
            r.stem,
            cells.join(" | "),
            layers.join("; ")
        );
    }
    let errors: Vec<String> = rows
        .iter()
        .flat_map(|r| {
            r.renders
                .iter()
                .filter_map(move |c| c.as_ref().err().map(|e| format!("{}: {e}", r.stem)))
        })
        .collect();
    if !errors.is_empty() {
        let _ = writeln!(body, "\nRenders that failed: {}", errors.join("; "));
    }
    let _ = writeln!(body);
}

#[cfg(test)]
mod tests {
    use super::super::sf2;
    use super::*;

    /// A bar of ten modes struck through `contact` (a `[contact]` body).
    fn bar(contact: &str) -> Scene {
        let modes: Vec<String> = (1..=10)
            .map(|i| {
                let f = 180.0 * f64::from(i * i);
                format!(
                    "{{ freq_hz = {f}, t60_s = 1.0, weights = [{}, 1.0] }}",
                    3.0 / f64::from(i)
                )
            })
            .collect();
        Scene::from_toml_str(&format!(
            r#"
version = 1
name = "bar"
[[object]]
name = "bar"
kind = "modal"
points = ["hit", "mic"]
mode = [{}]
[hammer]
mass_kg = 0.02
height_m = 0.0005
[contact]
object = "bar"
point = "hit"
{contact}
[[pickup]]
object = "bar"
point = "mic"
"#,
            modes.join(", ")
        ))
        .unwrap()
    }

    /// The table's premise, measured: a linear spring's attack centroid
    /// is the same at every velocity (the strike scales with the speed),
    /// a stiffening law's rises with it.
    #[test]
    fn a_linear_contact_keeps_its_centroid_and_a_stiffening_law_raises_it() {
        let all = |r: Vec<Result<f64, String>>| -> Vec<f64> {
            r.into_iter().map(|c| c.unwrap()).collect()
        };
        let linear = all(render_centroids(&bar("stiffness_n_per_m = 2e5")));
        let law = all(render_centroids(&bar(
            "law = { power = 2.5, force_n_at = [0.001, 200.0], pieces = 4, up_to_m = 0.002 }",
        )));
        println!("centroid at velocities {VELOCITIES:?}: linear {linear:.0?}, law {law:.0?}");
        let spread = |c: &[f64]| {
            c.iter().copied().fold(0.0, f64::max) / c.iter().copied().fold(f64::INFINITY, f64::min)
        };
        assert!(spread(&linear) < 1.03, "{linear:?}");
        assert!(law[4] > 1.2 * law[0], "{law:?}");
        assert!(law.windows(2).all(|w| w[1] > w[0]), "{law:?}");
    }

    /// A recording whose zones hold every velocity is one layer.
    #[test]
    fn velocities_that_play_the_same_samples_are_one_layer() {
        let sf = SoundFont::read(&mut std::io::Cursor::new(sf2::tests::tiny_sf2())).unwrap();
        let marimba = GmSound::parse("Marimba").unwrap();
        let p = PresetFile {
            stem: "bar".into(),
            scene: bar("stiffness_n_per_m = 2e5"),
            key: 57,
            real: Ok(Some(marimba)),
        };
        let rows = rows(&sf, &[(&p, marimba)], |p, _| p.key);
        assert_eq!(rows.len(), 1);
        assert_eq!(
            rows[0].layers.len(),
            1,
            "{:?}",
            rows[0].layers.iter().map(|l| &l.1).collect::<Vec<_>>()
        );
        assert_eq!(rows[0].layers[0].0, VELOCITIES.to_vec());
        assert!(rows[0].renders.iter().all(Result::is_ok));
        let mut body = String::new();
        write(&mut body, &rows);
        assert!(body.contains("| bar | "), "{body}");
    }
}
