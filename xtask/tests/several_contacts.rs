//! `cargo xtask render` on a scene of several contacts
//! (`presets/marimba-two-mallets.toml`, docs/design.md "Several
//! contacts"), through the library the command runs: the WAV, the trace
//! with a group of columns per further contact, the plot and the sidecar;
//! until the second mallet arrives the sound is the one-contact engine's
//! render of the same scene without it (two separate implementations);
//! the same job twice gives the same bytes; the instrument's path refuses
//! the scene with the field named.

use std::path::{Path, PathBuf};
use xtask::render::{run, RenderArgs};

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../presets/marimba-two-mallets.toml")
}

fn args(scenes: Vec<PathBuf>, out: &Path) -> RenderArgs {
    RenderArgs {
        scenes,
        out: out.to_path_buf(),
        trace: None,
        trace_format: Default::default(),
        plot: None,
        seconds: Some(0.15),
        rate: 48000.0,
        switching: None,
        notes: None,
        velocities: None,
        jobs: Some(2),
    }
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("xtask-multi-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn wav(path: &Path) -> Vec<f32> {
    hound::WavReader::open(path)
        .unwrap()
        .samples::<f32>()
        .map(|s| s.unwrap())
        .step_by(2)
        .collect()
}

#[test]
fn two_mallets_render_trace_plot_and_agree_with_one_contact_until_the_second() {
    let dir = temp("two");
    let mut a = args(vec![example()], &dir.join("two.wav"));
    a.trace = Some(Some(dir.join("two.csv")));
    a.plot = Some(Some(dir.join("two.svg")));
    run(&a).unwrap();
    let two = wav(&dir.join("two.wav"));
    assert_eq!(two.len(), 7200);
    // the trace: the one-contact columns, then contact 1's
    let csv = std::fs::read_to_string(dir.join("two.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,x_hammer,v_hammer,x_contact,v_contact,in_contact,energy,\
         x_hammer_1,v_hammer_1,x_contact_1,v_contact_1,in_contact_1"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 7200);
    let first = |col: usize| rows.iter().position(|r| r[col] == 1.0).map(|i| rows[i][0]);
    let (t0, t1) = (first(5).unwrap(), first(11).unwrap());
    println!(
        "first contact of mallet 0 at {:.3} ms, of mallet 1 at {:.3} ms",
        t0 * 1e3,
        t1 * 1e3
    );
    assert!(t0 < 1e-3);
    // 121 mm at 2 m/s: 60.5 ms, less what the ringing bar comes up
    assert!((0.059..0.0606).contains(&t1), "{t1}");
    // the energy never rises
    let rise = rows
        .windows(2)
        .map(|w| w[1][6] - w[0][6])
        .fold(f64::MIN, f64::max);
    assert!(rise <= 1e-15 * rows[0][6], "energy rose by {rise:e}");
    let svg = std::fs::read_to_string(dir.join("two.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.len() > 10_000);
    // without the second mallet, through the one-contact engine
    let text = std::fs::read_to_string(example()).unwrap();
    // the striker's table runs to the next table header
    let striker = text.find("[[striker]]").unwrap();
    let next = striker + 1 + text[striker + 1..].find("\n[").unwrap() + 1;
    let one_scene = text[..striker].to_string() + &text[next..];
    std::fs::write(dir.join("one.toml"), one_scene).unwrap();
    run(&args(vec![dir.join("one.toml")], &dir.join("one.wav"))).unwrap();
    let one = wav(&dir.join("one.wav"));
    let peak = one.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let arrive = (t1 * 48000.0) as usize;
    let before = (0..arrive)
        .map(|i| (two[i] - one[i]).abs())
        .fold(0.0f32, f32::max);
    let after = (arrive + 1..two.len())
        .map(|i| (two[i] - one[i]).abs())
        .fold(0.0f32, f32::max);
    println!(
        "before the second mallet: largest difference {:.1e} of the peak; after it {:.1e}",
        before / peak,
        after / peak
    );
    assert!(before <= 1e-6 * peak, "{before:e}");
    assert!(after > 0.05 * peak, "{after:e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_batch_with_several_contacts_writes_sidecars_and_repeats_bytes() {
    let dir = temp("batch");
    let mut outs = Vec::new();
    for k in 0..2 {
        let d = dir.join(format!("run{k}"));
        let mut a = args(vec![example()], &d);
        a.scenes
            .push(modal_testkit::scenes::preset_path("wood-block"));
        a.trace = Some(None);
        run(&a).unwrap();
        outs.push(d);
    }
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(outs[0].join("marimba-two-mallets.json")).unwrap())
            .unwrap();
    assert_eq!(side["compile"]["contacts"], 2);
    assert_eq!(side["compile"]["phases"], 4);
    let per = side["contacts_per_contact"].as_array().unwrap();
    assert!(per.iter().all(|c| c.as_u64().unwrap() >= 1), "{side}");
    assert_eq!(side["exact_switching"]["capped"], 0);
    assert_eq!(side["exact_switching"]["uncertified"], 0);
    for name in [
        "marimba-two-mallets.wav",
        "marimba-two-mallets.csv",
        "wood-block.wav",
    ] {
        assert_eq!(
            std::fs::read(outs[0].join(name)).unwrap(),
            std::fs::read(outs[1].join(name)).unwrap(),
            "{name}"
        );
    }
    // notes are the instrument's, which plays the scene as a kit: the
    // note throws the first mallet (in turn), its contact and only its
    // starts, as the sidecar says
    let mut a = args(vec![example()], &dir.join("notes"));
    a.notes = Some("60".into());
    a.velocities = Some("100".into());
    run(&a).unwrap();
    let side: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.join("notes").join("marimba-two-mallets_n060_v100.json")).unwrap(),
    )
    .unwrap();
    println!("{}", side["compile"]["summary"]);
    assert_eq!(side["compile"]["kit"], true);
    assert_eq!(side["compile"]["mallets"], 2);
    assert!(side["contacts"].as_u64().unwrap() >= 1, "{side}");
    assert!(side["peak"].as_f64().unwrap() > 1e-3, "{side}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--trace T.npy` on a scene of several contacts: the CSV's columns as
/// named f64 fields, every number the CSV's bit for bit.
#[test]
fn the_numpy_trace_holds_the_csvs_numbers() {
    let dir = temp("npy");
    let mut a = args(vec![example()], &dir.join("two.wav"));
    a.seconds = Some(0.07);
    a.trace = Some(Some(dir.join("two.csv")));
    run(&a).unwrap();
    a.trace = Some(Some(dir.join("two.npy")));
    run(&a).unwrap();
    let npy = std::fs::read(dir.join("two.npy")).unwrap();
    assert_eq!(&npy[..8], b"\x93NUMPY\x01\x00");
    let hlen = u16::from_le_bytes([npy[8], npy[9]]) as usize;
    let header = std::str::from_utf8(&npy[10..10 + hlen]).unwrap();
    assert!(header.contains("('in_contact_1', '<f8')"), "{header}");
    assert!(header.contains("'shape': (3360,)"), "{header}");
    assert_eq!((10 + hlen) % 64, 0);
    let data = &npy[10 + hlen..];
    let csv = std::fs::read_to_string(dir.join("two.csv")).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(data.len(), rows.len() * 12 * 8);
    for (r, row) in rows.iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            let at = (r * 12 + c) * 8;
            let y = f64::from_le_bytes(data[at..at + 8].try_into().unwrap());
            assert_eq!(y.to_bits(), x.to_bits(), "row {r} column {c}");
        }
    }
    assert!(
        rows.iter().any(|r| r[11] == 1.0),
        "the second mallet's contact is in the window"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The three examples of touches (objects against objects, a ball between
/// two plates, tubes that touch) through the render command in one batch:
/// every contact closes, the sidecar says so, each trace has a group of
/// columns per contact and an energy that never rises beyond rounding.
#[test]
fn the_touch_examples_render_and_every_contact_closes() {
    let dir = temp("touch");
    let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../presets");
    let scenes: Vec<PathBuf> = ["ball-between-plates", "wind-chimes", "snare-pair"]
        .iter()
        .map(|n| ex.join(format!("{n}.toml")))
        .collect();
    // one batch: a WAV, a trace and a sidecar per scene in `dir`
    let mut a = args(scenes.clone(), &dir);
    a.seconds = Some(1.0);
    a.trace = Some(None);
    run(&a).unwrap();
    for s in &scenes {
        let stem = s.file_stem().unwrap().to_str().unwrap();
        let side: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(format!("{stem}.json"))).unwrap(),
        )
        .unwrap();
        let per: Vec<u64> = side["contacts_per_contact"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap())
            .collect();
        let csv = std::fs::read_to_string(dir.join(format!("{stem}.csv"))).unwrap();
        let mut lines = csv.lines();
        let header = lines.next().unwrap();
        assert_eq!(
            header.split(',').count(),
            7 + 5 * (per.len() - 1),
            "{header}"
        );
        let energy: Vec<f64> = lines
            .map(|l| l.split(',').nth(6).unwrap().parse().unwrap())
            .collect();
        let top = energy.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        let rise = energy
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::MIN, f64::max);
        println!("{stem}: contacts per contact {per:?}; energy from {:.3e} to {:.3e} J, largest rise {rise:.1e}", energy[0], energy.last().unwrap());
        assert!(per.iter().all(|&c| c >= 1), "{stem}: {per:?}");
        assert!(rise <= 1e-12 * top, "{stem}: {rise:e}");
        assert!(energy.last().unwrap() < &energy[0], "{stem}");
    }
}

/// `--switching offset-rod` on a scene of several contacts: every contact
/// closes, the sidecar names the method, and the trace's energy (the
/// objects', the mallets' motion and weight, each closed spring with its
/// rod) never rises from one row to the next beyond rounding: a row is
/// taken after its sample's decision, so a contact's first row holds a
/// spring of energy 0 and takes nothing from the row before.
#[test]
fn the_offset_rod_plays_several_contacts() {
    let dir = temp("rod");
    // a batch (two scenes, a directory): the sidecar and the trace next
    // to each WAV
    let mut a = args(
        vec![example(), modal_testkit::scenes::preset_path("wood-block")],
        &dir.join("out"),
    );
    a.switching = Some(xtask::render::SwitchingArg::OffsetRod);
    a.trace = Some(None);
    a.seconds = Some(0.3);
    run(&a).unwrap();
    let out = dir.join("out");
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("marimba-two-mallets.json")).unwrap())
            .unwrap();
    assert_eq!(side["switching"], "OffsetRod");
    let per = side["contacts_per_contact"].as_array().unwrap();
    assert!(per.iter().all(|c| c.as_u64().unwrap() >= 1), "{side}");
    let csv = std::fs::read_to_string(out.join("marimba-two-mallets.csv")).unwrap();
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (e, c0, c1) = (col("energy"), col("in_contact"), col("in_contact_1"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let scale = rows.iter().map(|r| r[e].abs()).fold(0.0, f64::max);
    let mut worst = f64::NEG_INFINITY;
    let mut entries = 0;
    for w in rows.windows(2) {
        worst = worst.max((w[1][e] - w[0][e]) / scale);
        entries += usize::from(w[1][c0] > w[0][c0]) + usize::from(w[1][c1] > w[0][c1]);
    }
    println!(
        "offset rod, two mallets: {} rows, {entries} entries, largest energy rise {worst:.1e} of the largest energy",
        rows.len()
    );
    assert!(entries >= 2);
    assert!(worst < 1e-12, "{worst:e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
