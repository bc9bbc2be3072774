//! `cargo xtask render --trace T.npy`: NumPy itself reads the trace, with
//! the CSV's column names, and every number equals the CSV's (read by
//! NumPy's own text parser) exactly. NumPy is the venv's that `cargo xtask
//! test` makes (`MODAL_CONTACT_PYTHON`).

use modal_testkit::scenes::preset_path;
use std::path::PathBuf;
use std::process::Command;
use xtask::render::{run, RenderArgs};

fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("MODAL_CONTACT_PYTHON") {
        return PathBuf::from(p);
    }
    let venv = modal_testkit::workspace_root().join("target/venv/bin/python");
    assert!(
        venv.is_file(),
        "no Python with NumPy: run `cargo xtask test` (it makes target/venv) or set MODAL_CONTACT_PYTHON"
    );
    venv
}

const CHECK: &str = r#"
import sys
import numpy as np
npy, csv = sys.argv[1], sys.argv[2]
a = np.load(npy)
with open(csv) as f:
    names = f.readline().strip().split(",")
assert list(a.dtype.names) == names, (a.dtype.names, names)
c = np.loadtxt(csv, delimiter=",", skiprows=1)
assert a.shape == (c.shape[0],), (a.shape, c.shape)
for k, n in enumerate(names):
    if not np.array_equal(a[n], c[:, k]):
        print("column", n, "differs by up to", np.max(np.abs(a[n] - c[:, k])))
        sys.exit(1)
print("rows", a.shape[0], "in contact", int(a["in_contact"].sum()))
"#;

#[test]
fn numpy_reads_the_npy_trace_as_the_csv_trace() {
    let dir = std::env::temp_dir().join(format!("trace-npy-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let seconds = 0.5;
    for ext in ["npy", "csv"] {
        let a = RenderArgs {
            scenes: vec![preset_path("paper-bounce")],
            out: dir.join(format!("{ext}.wav")),
            trace: Some(Some(dir.join(format!("t.{ext}")))),
            trace_format: Default::default(),
            plot: None,
            seconds: Some(seconds),
            rate: 44100.0,
            switching: None,
            notes: None,
            velocities: None,
            jobs: Some(1),
        };
        run(&a).unwrap();
    }
    // the WAV does not depend on the trace's format
    assert!(
        std::fs::read(dir.join("npy.wav")).unwrap() == std::fs::read(dir.join("csv.wav")).unwrap()
    );
    let out = Command::new(python())
        .args(["-c", CHECK])
        .arg(dir.join("t.npy"))
        .arg(dir.join("t.csv"))
        .output()
        .expect("python");
    let said = String::from_utf8_lossy(&out.stdout);
    println!("{said}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "NumPy's check failed");
    let rows = (seconds * 44100.0) as usize;
    assert!(said.contains(&format!("rows {rows} ")), "{said}");
    let contact: usize = said.split_whitespace().last().unwrap().parse().unwrap();
    assert!(contact > 0, "the render should hold contacts");
    std::fs::remove_dir_all(&dir).unwrap();
}
