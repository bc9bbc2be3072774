//! `cargo xtask golden [--write]`: renders every preset and every stability
//! case of the report, in both switching modes, and hashes the WAV and the
//! trace of each (64-bit FNV-1a of the WAV's bytes as the render command
//! writes them, and of the trace's numbers as its CSV text reads back:
//! every number is checked to read back bit for bit, and the hash does not
//! depend on how the text spells a number).
//! `--write` records them in `tests/golden-hashes.txt`; without it the
//! hashes are compared with that file and any difference is an error.
//!
//! Why: a refactoring that must not change behaviour is shown to be one by
//! bit-identical renders. Every scene runs on the portable kernels (the
//! baseline target, no FMA), whose rounding is the same on every x86-64,
//! and on this CPU's detected kernels; each path has its own lines. A
//! scene of several contacts hashes its trace's further contacts after the
//! rows.

use anyhow::{bail, Context, Result};
use clap::Args;
use modal_contact::compile::compile_with;
use modal_contact::engine::{has_faster_kernels, EngineState};
use modal_contact::render::{render_several_on, write_trace_csv, TraceRow};
use modal_contact::scene::{Scene, Switching};
use modal_contact::Compiled;
use modal_testkit::scenes::RATE;
use modal_testkit::stability;
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

/// `cargo xtask golden [--write]`.
#[derive(Args, Debug)]
pub(crate) struct GoldenArgs {
    /// Record the hashes in tests/golden-hashes.txt instead of checking
    /// them (only when a change of the renders is intended).
    #[arg(long)]
    write: bool,
}

/// Where the recorded hashes live (relative to the workspace root).
pub(crate) const HASH_FILE: &str = "tests/golden-hashes.txt";

/// 64-bit FNV-1a.
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Render `n` samples of `scene` with `switching` on the portable kernels or this CPU's fastest, and
/// hash the WAV (32-bit float stereo, as `cargo xtask render` writes it)
/// and the trace CSV.
fn render_hashes(
    scene: &Scene,
    n: usize,
    switching: Switching,
    portable: bool,
) -> Result<(u64, u64)> {
    let sc = compile_with(scene, RATE, Some(switching))?;
    let mut st = EngineState::new(&sc);
    st.set_portable_kernels(portable);
    let (mut left, mut right) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut rows = Vec::with_capacity(n);
    for i in 0..n {
        let (out, obs) = st.tick_observed(&sc);
        rows.push(TraceRow {
            t: i as f64 / RATE,
            obs,
            surface: [0.0; 2],
        });
        left.push(out[0]);
        right.push(out[1]);
    }
    let mut csv = Vec::new();
    write_trace_csv(&rows, &mut csv)?;
    Ok((fnv1a(&wav_bytes(&left, &right)?), trace_hash(&rows, &csv)?))
}

/// A scene of several contacts rendered by the render's own path on the
/// portable kernels or this CPU's fastest: the WAV hashed as above, and
/// the trace's numbers bit for bit (every row's seven columns, then every
/// further contact's motion, row by row).
fn render_hashes_several(
    scene: &Scene,
    n: usize,
    switching: Switching,
    portable: bool,
) -> Result<(u64, u64)> {
    let Compiled::Several(c) = Compiled::new(scene, RATE, Some(switching))? else {
        bail!("not a scene of several contacts");
    };
    let out = render_several_on(&c, n, true, portable);
    let rows = out.trace.as_deref().context("no trace")?;
    let mut bits = Vec::with_capacity(rows.len() * 7 * 8 * 4);
    for r in rows {
        for x in r.columns() {
            bits.extend_from_slice(&x.to_le_bytes());
        }
    }
    for m in &out.trace_further {
        let in_contact = f64::from(u8::from(m.in_contact));
        for x in [m.x_hammer, m.v_hammer, m.x_contact, m.v_contact, in_contact] {
            bits.extend_from_slice(&x.to_le_bytes());
        }
    }
    Ok((fnv1a(&wav_bytes(&out.left, &out.right)?), fnv1a(&bits)))
}

/// The WAV file `cargo xtask render` writes of these channels (32-bit
/// float stereo).
fn wav_bytes(left: &[f64], right: &[f64]) -> Result<Vec<u8>> {
    let mut wav = Cursor::new(Vec::new());
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: RATE as u32,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::new(&mut wav, spec)?;
    for (l, r) in left.iter().zip(right) {
        w.write_sample(*l as f32)?;
        w.write_sample(*r as f32)?;
    }
    w.finalize()?;
    Ok(wav.into_inner())
}

/// FNV-1a of the little-endian bits of every number of the CSV text `csv`
/// (header, then one line per row), after checking that the text reads
/// back to `rows` bit for bit.
fn trace_hash(rows: &[TraceRow], csv: &[u8]) -> Result<u64> {
    let text = std::str::from_utf8(csv)?;
    let mut lines = text.lines();
    lines.next().context("no header")?;
    let mut bits = Vec::with_capacity(rows.len() * 7 * 8);
    let mut read = 0;
    for (i, (line, r)) in lines.zip(rows).enumerate() {
        let want = r.columns();
        let mut fields = line.split(',');
        for (k, w) in want.iter().enumerate() {
            let f = fields
                .next()
                .with_context(|| format!("row {i}: no column {k}"))?;
            let x: f64 = f
                .parse()
                .with_context(|| format!("row {i} column {k}: {f:?}"))?;
            if x.to_bits() != w.to_bits() {
                bail!("row {i} column {k}: {f:?} reads back as {x:e}, the row holds {w:e}");
            }
            bits.extend_from_slice(&x.to_le_bytes());
        }
        if fields.next().is_some() {
            bail!("row {i}: more than 7 columns");
        }
        read += 1;
    }
    if read != rows.len() || text.lines().count() != rows.len() + 1 {
        bail!(
            "{} rows, {} lines after the header",
            rows.len(),
            text.lines().count() - 1
        );
    }
    Ok(fnv1a(&bits))
}

/// Every case: (name, scene, samples).
fn cases(root: &Path) -> Result<Vec<(String, Scene, usize)>> {
    let mut v = Vec::new();
    let mut presets: Vec<_> = std::fs::read_dir(root.join("presets"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    presets.sort();
    for p in presets {
        let scene = Scene::from_file(&p).with_context(|| format!("{}", p.display()))?;
        let n = (scene.duration_s.min(2.0) * RATE) as usize;
        let name = format!("preset {}", p.file_stem().unwrap().to_string_lossy());
        v.push((name, scene, n));
    }
    // recorded under the cases' numerics labels, which outlive renames
    for c in stability::cases() {
        v.push((format!("stability {}", c.label), c.scene, c.samples));
    }
    Ok(v)
}

/// Compute every hash: `"<case> | <switching> | <kernels>" -> "wav trace"`.
fn compute(root: &Path) -> Result<BTreeMap<String, String>> {
    let mut paths = vec![true];
    if has_faster_kernels() {
        paths.push(false);
    }
    let mut out = BTreeMap::new();
    for (name, scene, n) in cases(root)? {
        for sw in [Switching::Exact, Switching::OffsetRod] {
            for &portable in &paths {
                let (w, t) = if scene.several_contacts() {
                    render_hashes_several(&scene, n, sw, portable)
                } else {
                    render_hashes(&scene, n, sw, portable)
                }
                .with_context(|| format!("{name} ({})", sw.as_str()))?;
                let kernels = if portable { "portable" } else { "avx2+fma" };
                out.insert(
                    format!("{name} | {} | {kernels}", sw.as_str()),
                    format!("wav {w:016x} trace {t:016x}"),
                );
            }
        }
        eprintln!("  {name}");
    }
    Ok(out)
}

/// Run `cargo xtask golden`.
pub(crate) fn run(args: GoldenArgs) -> Result<()> {
    let write = args.write;
    nice_plug_xtask::chdir_workspace_root()?;
    let root = Path::new(".");
    let now = compute(root)?;
    let file = root.join(HASH_FILE);
    if write {
        let mut text = String::from(
            "# Render hashes of every preset and stability case (cargo xtask golden --write).\n\
             # case | switching | kernels = wav <fnv1a-64 of the WAV> trace <fnv1a-64 of the trace's numbers>\n",
        );
        for (k, v) in &now {
            text += &format!("{k} = {v}\n");
        }
        std::fs::write(&file, text)?;
        eprintln!("wrote {} ({} renders)", file.display(), now.len());
        return Ok(());
    }
    let text = std::fs::read_to_string(&file).with_context(|| format!("{}", file.display()))?;
    let mut recorded = BTreeMap::new();
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let (k, v) = line.rsplit_once(" = ").context("malformed line")?;
        recorded.insert(k.to_string(), v.to_string());
    }
    let mut bad = Vec::new();
    for (k, v) in &now {
        match recorded.get(k) {
            Some(r) if r == v => {}
            Some(r) => bad.push(format!("{k}: recorded {r}, now {v}")),
            // a CPU without the recorded kernel path checks the portable one
            None if k.ends_with("| avx2+fma") => {}
            None => bad.push(format!("{k}: not recorded")),
        }
    }
    for k in recorded.keys() {
        if !now.contains_key(k) && !k.ends_with("| avx2+fma") {
            bad.push(format!("{k}: recorded but not rendered"));
        }
    }
    if !bad.is_empty() {
        bail!(
            "{} of {} renders differ:\n{}",
            bad.len(),
            now.len(),
            bad.join("\n")
        );
    }
    eprintln!(
        "all {} renders bit-identical to {}",
        now.len(),
        file.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The renders `cargo xtask golden` hashes are the ones the file
    /// records, and each case compiles in both switching modes for the
    /// engine that runs it (a preset its compiler refuses would stop the
    /// command before it hashed anything).
    #[test]
    fn every_golden_case_is_recorded_and_compiles() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let text = std::fs::read_to_string(root.join(HASH_FILE)).unwrap();
        let recorded: std::collections::BTreeSet<String> = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .map(|l| l.split(" | ").next().unwrap().to_string())
            .collect();
        let cases = cases(&root).unwrap();
        let names: std::collections::BTreeSet<String> =
            cases.iter().map(|(name, _, _)| name.clone()).collect();
        assert_eq!(names, recorded);
        for (name, scene, _) in &cases {
            for sw in [Switching::Exact, Switching::OffsetRod] {
                Compiled::new(scene, RATE, Some(sw))
                    .unwrap_or_else(|e| panic!("{name} ({}): {e}", sw.as_str()));
            }
        }
        println!("{} golden cases, each recorded and compiled", cases.len());
    }
}
