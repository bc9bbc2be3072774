//! `cargo xtask levels` on copies of presets, through the library the
//! command runs: `--check` names every preset off the target, `--write`
//! sets each file's `level_db` in one pass (the file otherwise unchanged)
//! after which `--check` passes, and the page is written.

use modal_testkit::scenes::preset_path;
use std::path::{Path, PathBuf};
use xtask::levels::{measure, run, write_level, LevelsArgs, TARGET_LUFS, WRITTEN_BY};

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("xtask-levels-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn args(dir: &Path, check: bool, write: bool) -> LevelsArgs {
    LevelsArgs {
        presets: Some(dir.join("presets")),
        out: Some(dir.join("levels.md")),
        check,
        write,
    }
}

/// The text without its `level_db` lines.
fn without_level(text: &str) -> String {
    text.lines()
        .filter(|l| !l.starts_with("level_db"))
        .map(|l| format!("{l}\n"))
        .collect()
}

#[test]
fn write_sets_every_level_in_one_pass_and_check_then_passes() {
    let dir = temp("write");
    let presets = dir.join("presets");
    std::fs::create_dir_all(&presets).unwrap();
    // a struck object, a drum kit (one kit voice) and a pitched kit
    let names = ["paper-bounce", "snare-pair", "marimba-two-mallets"];
    for n in names {
        std::fs::copy(preset_path(n), presets.join(format!("{n}.toml"))).unwrap();
    }
    // 10 dB above and below the target, whatever the presets' own levels
    for (n, off) in [("paper-bounce", 10.0), ("snare-pair", -10.0)] {
        let f = presets.join(format!("{n}.toml"));
        let m = measure(&f).unwrap();
        write_level(&f, m.level_for_target() + off).unwrap();
    }
    let originals: Vec<String> = names
        .iter()
        .map(|n| std::fs::read_to_string(preset_path(n)).unwrap())
        .collect();

    let e = run(&args(&dir, true, false)).unwrap_err().to_string();
    println!("{e}");
    for n in ["paper-bounce: loudness", "snare-pair: loudness"] {
        assert!(e.contains(n), "{n}: {e}");
    }
    let page = std::fs::read_to_string(dir.join("levels.md")).unwrap();
    assert!(page.contains("do not edit by hand"), "{page}");

    run(&args(&dir, true, true)).expect("--write --check passes");
    let page = std::fs::read_to_string(dir.join("levels.md")).unwrap();
    assert!(page.contains("in 1 pass "), "one pass: {page}");
    for (n, orig) in names.iter().zip(&originals) {
        let f = presets.join(format!("{n}.toml"));
        let text = std::fs::read_to_string(&f).unwrap();
        assert_eq!(without_level(&text), without_level(orig), "{n}");
        let lines: Vec<&str> = text.lines().filter(|l| l.starts_with("level_db")).collect();
        assert_eq!(lines.len(), 1, "{n}: {lines:?}");
        assert!(lines[0].ends_with(WRITTEN_BY), "{n}: {}", lines[0]);
        let m = measure(&f).unwrap();
        println!("{n}: level_db {} -> {:.3} LUFS", m.level_db, m.lufs);
        // the level is written to 0.1 dB
        assert!((m.lufs - TARGET_LUFS).abs() <= 0.06, "{n}: {}", m.lufs);
    }
    // a second --write moves nothing
    let before: Vec<Vec<u8>> = names
        .iter()
        .map(|n| std::fs::read(presets.join(format!("{n}.toml"))).unwrap())
        .collect();
    run(&args(&dir, true, true)).unwrap();
    for (n, b) in names.iter().zip(&before) {
        assert_eq!(
            &std::fs::read(presets.join(format!("{n}.toml"))).unwrap(),
            b,
            "{n}"
        );
    }
    let page = std::fs::read_to_string(dir.join("levels.md")).unwrap();
    assert!(page.contains("wrote 0 levels in 0 passes"), "{page}");
    std::fs::remove_dir_all(&dir).unwrap();
}
