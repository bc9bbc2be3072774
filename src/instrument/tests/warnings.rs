//! Tests of the instrument's warnings: the real-time warning of a stiff
//! scene's event search and the strike-cost warning at the host's block
//! size.

use super::*;

/// The real-time warning of a stiff scene's event search: no shipped
/// preset needs it at any Hardness (its estimate stays a few nodes per
/// sample), so users only see it for their own stiff scenes.
#[test]
fn presets_need_no_realtime_warning_at_any_hardness() {
    for i in 0..presets::PRESETS.len() {
        for hf in [0.01, 1.0, 100.0] {
            let p = SceneParams {
                preset: i,
                stiffness_factor: hf,
                ..SceneParams::default()
            };
            let pr = prepare(&p, RATE, 1).unwrap();
            assert!(
                pr.realtime_warning().is_none(),
                "{} x{hf}: {:?}",
                pr.scenes.scene.name,
                pr.realtime_warning()
            );
            // a few nodes per sample near a switch; the glockenspiel's
            // brass mallet (a contact of three samples at 44.1 kHz) takes
            // about ten
            assert!(
                pr.scenes.scene.search_nodes_estimate <= 12.0,
                "{}",
                pr.scenes.scene.summary
            );
        }
    }
}

/// The strike-cost warning: no shipped preset needs it at 64-sample
/// blocks, and at 32 samples only the 50-mass paper string, the frame
/// drum (37 coupled membrane modes), the two rolling balls (47 and 46
/// plate modes, each coupled to the ball) and the scenes made from
/// recordings (up to 40 modes; the guiro's scraped one by a stick) and the brushed
/// snare head (39 membrane modes) do (a 16-note
/// chord on a 50-mode object takes about 70 % of such a block, measured by
/// `cargo bench --bench worst_block`); a 400-mode object warns at 64-sample
/// blocks (a 16-note chord would take several blocks' worth of CPU), and a
/// large buffer fits it.
#[test]
fn strike_warning_names_what_fits_at_the_hosts_block_size() {
    let mut warned_at_32 = Vec::new();
    for i in 0..presets::PRESETS.len() {
        let p = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        let pr = prepare(&p, RATE, 1).unwrap();
        assert!(
            pr.strike_warning(64, DEFAULT_POLYPHONY, 0).is_none(),
            "{:?}",
            pr.strike_warning(64, DEFAULT_POLYPHONY, 0)
        );
        if pr.strike_warning(32, DEFAULT_POLYPHONY, 0).is_some() {
            warned_at_32.push(pr.scenes.scene.name.clone());
        }
        // a kit's strike switches its largest phase (the snare's head and
        // wires: 110 states); the snare lists its notes, so its one kit
        // voice throws its one mallet at most once an instant
        let limit = if pr.kit.is_some() { 100e-6 } else { 40e-6 };
        assert!(
            pr.strike_cost_estimate_s() < limit,
            "{}",
            pr.scenes.scene.name
        );
    }
    assert_eq!(
        warned_at_32,
        [
            "paper-string",
            "frame-drum",
            "ball-on-plate",
            "marble-on-board",
            "glockenspiel-recorded",
            "marimba-recorded",
            "timpani-recorded",
            "guiro-recorded",
            "snare-brush"
        ]
    );
    let mut big = modal_base("marimba-bar");
    let ObjectSpec::Modal(m) = &mut big.object[0] else {
        panic!("marimba-bar is modal")
    };
    let first = m.mode[0].clone();
    m.mode = (0..400)
        .map(|k| {
            let mut md = first.clone();
            md.freq_hz = first.freq_hz * (1.0 + 0.37 * k as f64);
            md
        })
        .collect();
    let pr = prepare_scene(&big, &SceneParams::default(), 48_000.0, 1).unwrap();
    let est = pr.strike_cost_estimate_s();
    let w = pr
        .strike_warning(64, DEFAULT_POLYPHONY, 0)
        .expect("400 modes at 64 samples");
    println!("{w}");
    assert!(
        w.contains("even one strike takes more than half the block") && w.contains("64 samples"),
        "{w}"
    );
    assert!(est > 200e-6 && est < 5e-3, "{est}");
    assert!(pr.strike_warning(8192, DEFAULT_POLYPHONY, 0).is_none());
    let mid = pr
        .strike_warning(1024, DEFAULT_POLYPHONY, 0)
        .expect("a chord still overruns 1024 samples");
    assert!(mid.contains("simultaneous strikes fit"), "{mid}");
    // the lookahead it names spreads the chord: with it, no warning; with
    // a millisecond less, the same warning
    let ms: f64 = w
        .split("a Lookahead of ")
        .nth(1)
        .and_then(|r| r.split(" ms").next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no lookahead named: {w}"));
    let samples = |ms: f64| lookahead_samples(ms * 1e-3, 48_000.0);
    println!(
        "64-sample blocks: a lookahead of {ms} ms ({} samples)",
        samples(ms)
    );
    assert!(pr
        .strike_warning(64, DEFAULT_POLYPHONY, samples(ms))
        .is_none());
    assert!(pr
        .strike_warning(64, DEFAULT_POLYPHONY, samples(ms - 1.0))
        .is_some());
    // 64 voices at once need more than the longest lookahead
    let all = pr
        .strike_warning(64, MAX_VOICES, lookahead_samples(MAX_LOOKAHEAD_S, 48_000.0))
        .expect("64 strikes");
    assert!(all.contains("even the largest Lookahead"), "{all}");
}
