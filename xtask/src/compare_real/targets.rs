//! The targets of one compared preset and their verdicts: the 1/3-octave
//! distance, the attack centroid, the energy above 5 kHz, the partials,
//! their decays and the nearest recording.

use super::*;

/// The targets of the comparison `c` (its `targets` not yet set), the
/// recording's band limit \[Hz\] and the key it was played at.
pub(super) fn targets(c: &Comparison, band_limit_hz: f64, own_key: u8) -> Vec<Target> {
    let (dist, centroid, hf_db, rows, sound) = (c.distance, c.centroid, c.hf_db, &c.rows, c.sound);
    let mut targets = Vec::new();
    targets.push(Target {
        name: "1/3-octave distance <= 6 dB",
        verdict: Verdict::of(dist <= TARGET_DISTANCE_DB),
        detail: format!("{dist:.1} dB"),
    });
    let cr = centroid.1 / centroid.0;
    targets.push(Target {
        name: "attack centroid 0.75-1.33x",
        verdict: Verdict::of((TARGET_CENTROID.0..=TARGET_CENTROID.1).contains(&cr)),
        detail: format!("{cr:.2}x"),
    });
    let hd = hf_db.1 - hf_db.0;
    let (hf_verdict, hf_detail) = if band_limit_hz < HF_HZ * 1.1 {
        (
            Verdict::NotApplicable,
            format!(
                "{hd:+.1} dB, but the recording stops at {:.1} kHz",
                band_limit_hz / 1000.0
            ),
        )
    } else {
        (
            Verdict::of(hd.abs() <= TARGET_HF_DB),
            format!("{hd:+.1} dB"),
        )
    };
    targets.push(Target {
        name: "energy > 5 kHz within +-6 dB",
        verdict: hf_verdict,
        detail: hf_detail,
    });
    let present = rows.iter().filter(|r| r.present()).count();
    let elsewhere = if own_key == sound.key_for(c.key) {
        String::new()
    } else {
        format!(", the recording at key {own_key}")
    };
    if c.strokes.is_some() {
        // a stroke's spectrum is its clicks' on the object, not partials
        // ringing down from one strike ("Strokes" says how it moves)
        for name in ["4 strongest partials within 15 cents", "T60 within 1.5x"] {
            targets.push(Target {
                name,
                verdict: Verdict::NotApplicable,
                detail: "a stroke, not a strike".into(),
            });
        }
    } else {
        targets.push(Target {
            name: "4 strongest partials within 15 cents",
            verdict: Verdict::of(present == rows.len() && rows.len() == PARTIALS),
            detail: format!("{present} of {}{elsewhere}", rows.len()),
        });
        targets.push(t60_target(rows));
    }
    let nearest = c
        .confusion
        .iter()
        .filter_map(|(s, d, _)| d.map(|d| (*s, d)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    targets.push(Target {
        name: "nearest recording is its own",
        verdict: Verdict::of(nearest.is_some_and(|(s, _)| s == sound)),
        detail: nearest.map_or("none".into(), |(s, d)| format!("{} ({d:.1} dB)", s.name())),
    });
    targets
}

/// The decay target: every partial fitted on both within
/// [`TARGET_T60_FACTOR`].
fn t60_target(rows: &[PartialRow]) -> Target {
    let ratios: Vec<f64> = rows.iter().filter_map(PartialRow::t60_ratio).collect();
    if ratios.is_empty() {
        return Target {
            name: "T60 within 1.5x",
            verdict: Verdict::NotApplicable,
            detail: "no partial with a fit on both".into(),
        };
    }
    let ok = ratios
        .iter()
        .filter(|r| (1.0 / TARGET_T60_FACTOR..=TARGET_T60_FACTOR).contains(*r))
        .count();
    Target {
        name: "T60 within 1.5x",
        verdict: Verdict::of(ok == ratios.len()),
        detail: format!("{ok} of {} fitted", ratios.len()),
    }
}
