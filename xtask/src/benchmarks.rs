//! `cargo xtask benchmarks [--out docs/benchmarks.md] [--quick] [--only
//! NAME]...`: runs the project's measurement benches, captures the tables
//! they print and writes them to `docs/benchmarks.md`, each section stamped
//! with the machine (CPU model, cores), the OS, the compiler and the date
//! of its run. The page is written by this command only: a table is
//! regenerated, never edited by hand, and every document that quotes a
//! measured time points at it (or at the bench that prints it) instead of
//! copying a run.
//!
//! Each bench of [`BENCHES`] is one cargo command whose standard output is
//! captured ([`capture`]: criterion's progress and estimate lines are
//! dropped, the bench's own lines kept, tables as Markdown tables and other
//! lines as text); criterion's estimates are kept apart
//! ([`criterion_estimates`]) for the benches whose tables are built from
//! them (the several-contact engine's cost per switch). `--only NAME` runs
//! the named benches and keeps the other sections of the existing page as
//! they were (each carries its own stamp). Timing is reported, never
//! asserted. The error-against-run-time report and the comparison with
//! recordings have their own generated pages (`cargo xtask report`,
//! docs/report.md; `cargo xtask compare-real`, docs/compare-real.md).

use anyhow::{bail, Context, Result};
use clap::Args;
use std::fmt::Write as _;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// `cargo xtask benchmarks [--out docs/benchmarks.md] [--quick] [--only NAME]...`.
#[derive(Args, Debug, Clone)]
pub struct BenchmarksArgs {
    /// The page written (relative to the workspace root).
    #[arg(long, default_value = "docs/benchmarks.md")]
    pub out: PathBuf,
    /// Shorter runs where a bench allows it (criterion's warm-up and
    /// measurement times, fewer activation trials); the page says so.
    #[arg(long)]
    pub quick: bool,
    /// Run only these benches (engine, worst_block, several_contacts,
    /// render_command, activation, stiff_switching) and keep the page's
    /// other sections as they are.
    #[arg(long)]
    pub only: Vec<String>,
}

/// Where a bench's tables come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The command's standard output.
    Stdout,
    /// A Markdown file the command writes (relative to the workspace root).
    File(&'static str),
}

/// One measurement command and what its section says about it.
#[derive(Clone, Copy, Debug)]
pub struct Bench {
    /// The name `--only` takes, and the section's marker.
    pub name: &'static str,
    /// The section's heading.
    pub title: &'static str,
    /// `cargo` and its arguments.
    pub args: &'static [&'static str],
    /// Appended with `--quick`.
    pub quick_args: &'static [&'static str],
    /// What the numbers are (the page's text above the tables).
    pub about: &'static str,
    /// Where the tables are read.
    pub source: Source,
}

/// The benches, in the page's order.
pub const BENCHES: [Bench; 6] = [
    Bench {
        name: "engine",
        title: "The engine: per sample, per switch, renders and compiles",
        args: &["bench", "--bench", "engine", "--", "summary"],
        quick_args: &[],
        about: "The engine as the plugin drives it (`EngineState::process_block` on \
blocks of samples), each phase beside a naive baseline that multiplies the dense \
transition matrix every sample, measured in the same run: free = a ringing object, \
the hammer flying away; contact = a weight resting at its static equilibrium on a \
vibrating object. Median of 5; the SIMD path chosen at run time, and the portable \
(generic) path beside it. Then: one switch at 100 modes (the change of basis alone, \
and the whole sample holding a located impact), the worst sample of the exact event \
search under a hammer rattling through a critically damped contact, every preset \
struck at full velocity at every Hardness (worst sample of the first 100 ms against \
the 22.7 us sample period), the paper's two presets and the three driven ones \
(rolling and scraping) rendered against real time and per sample, 16 voices of 200 \
modes, the compile of 100 / 400 / 1000 modes, and 200 modes in the subnormal range \
with and without the flush. The targets these are held to: \
docs/design.md, \"Speed targets\".",
        source: Source::Stdout,
    },
    Bench {
        name: "worst_block",
        title: "The worst block",
        args: &["bench", "--bench", "worst_block"],
        quick_args: &[],
        about: "The instrument (`Instrument::process`, what the plugin runs per host \
block) at 48 kHz, 2 s per cell (each block the least of three runs of the same \
work, so that a pause of the machine's does not stand for the instrument's cost), \
chords of 1, 4 or 16 notes (keys 48-83) struck \
together every 125 ms on voices that still ring, on modal objects of 10 to 1000 \
modes: the largest and the 99.9th percentile block as a percentage of the block's \
real-time budget (above 100 % a block is late). \"dense switches\" is the same \
scene with its structured changes of basis removed, \"strikes not played back\" \
with its recorded strikes dropped. Beside it: what one strike costs (ringing, at \
rest, played back), one note's first block at three pitches, 64 voices of the \
heaviest preset with and without the editor's live view, every preset's 16-note \
chord struck again on its ringing voices (on a driven preset, 16 strokes rolling or \
scraping at once), four presets and the 200-mode object with a stiffening law in \
place of their spring beside their spring, without and with a lookahead (a law makes a \
scene of several contacts), bad input (all 128 keys in one block, a note on every sample), a pitch bend, a 16-note chord with a \
brightness on every note, and the lookahead table. A largest far above its \
percentile is one block the machine interrupted; compare rows of one run, not runs \
of different days. What the numbers mean for the plugin: \
docs/design.md, \"The instrument\", \
docs/numerics.md, \"A strike from rest played back\", and \
docs/plugin.md, \"Lookahead\".",
        source: Source::Stdout,
    },
    Bench {
        name: "several_contacts",
        title: "Several contacts and kits",
        args: &["bench", "--bench", "several_contacts"],
        quick_args: &["--", "--warm-up-time", "1", "--measurement-time", "2"],
        about: "The several-contact engine: one switch with 2, 3 and 4 contacts on a \
100-mode object, as the difference between a sample in which a hammer meets the \
object and the same sample with that hammer far away (criterion's estimates, the \
same run; docs/numerics.md section 14), the compile of every phase, and each kit \
preset played through the instrument at 48 kHz for 4 s with notes every 125 ms, 1, \
4 or 16 keys at an instant, each block the least of three runs of the same work \
(docs/design.md, \"Played as a kit\"), and strikes through a law on a ringing \
200-mode object with the switches' products structured and dense (docs/numerics.md \
section 14, \"Structured switches\"), its phases that can be reached compiled beside \
every combination of its pieces (\"Phases that are reached\").",
        source: Source::Stdout,
    },
    Bench {
        name: "render_command",
        title: "The render command",
        args: &[
            "bench",
            "-p",
            "xtask",
            "--bench",
            "render_command",
            "--",
            "summary",
        ],
        quick_args: &[],
        about: "`cargo xtask render` of a struck modal object to files against \
`EngineState::process_block` over the same samples, at two lengths `L` and `3 L` \
(`L` = 10 s at 10 modes, 4 s at 100, 1 s at 1000, 44.1 kHz): the cost per sample is \
the slope between the two, as a ratio to the engine's, and the fixed cost of a \
render what is left of the shorter one; median of 7 interleaved rounds. \"CSV text \
alone\" is the same rows through the CSV writer with every core free of the engine, \
into no file: the floor of a CSV render. Each timed render writes new files. Why \
the numbers are what they are, and where the 3x target holds: \
docs/design.md, \"Offline rendering\".",
        source: Source::Stdout,
    },
    Bench {
        name: "activation",
        title: "Activation",
        args: &["bench", "-p", "plugin-tests", "--bench", "activation"],
        quick_args: &["--", "1"],
        about: "How long the host's main thread waits in `activate` and `deactivate` \
of the built release plugin through clack-host, per scene: at its defaults and with \
random parameter sets (a third of the values not a number, infinite or out of \
range), and whether a note sent at the first sample after `activate` sounds at once \
(docs/plugin.md, \"Parameter changes: the swap design\").",
        source: Source::Stdout,
    },
    Bench {
        name: "stiff_switching",
        title: "Exact switching at any stiffness",
        args: &[
            "test",
            "--profile",
            "test-release",
            "--features",
            modal_testkit::bundles::TEST_FEATURES,
            "--test",
            "numerics",
            "stiff_switching::",
            "--",
            "--nocapture",
        ],
        quick_args: &[],
        about: "The 46 stiff cases of `tests/stiff_switching.rs` (the test writes this \
table to `target/stiff_switching.md`; it fails if a case fails). Each case runs the \
engine in exact mode and an independent solver that shares only the scene's numbers \
with it (`reference-solver/`, \
docs/numerics.md, \"How it is checked\"), 50 ms at 44.1 kHz. \
`C1`, `C2`, `C3`: a hammer of 1e-6 of the object's effective mass at 1 m/s \
against an undamped 4-mode object with a mode above Nyquist, contact at about 100x \
Nyquist lasting about 1 % of a sample; a 10 g hammer dropped 1 mm through a \
critically damped contact, rattling; a hammer 1000x the object's effective mass \
pressing at 0.1 m/s. The others vary one factor or combine several. Errors are \
relative L2 over the window; the window is the predictability horizon, where a 1e-9 \
disturbance of the hammer (height under gravity, else mass) changes the solver's \
traces by less than 1e-7 and its contact instants by less than 1e-6 samples \
(chaotic cases: C2 rattles, C3 chatters). \"twin dt\" is that disturbance's largest \
instant change within the window. The errors are the same on every run of a build \
on one CPU; \"worst us/sample\" is indicative only (other cases run on the other \
cores).",
        source: Source::File("target/stiff_switching.md"),
    },
];

/// The first line of the page.
pub const TITLE: &str = "# Benchmarks: what the measurement benches print";

/// The line that says who writes the page.
pub const GENERATED: &str = "Generated by `cargo xtask benchmarks`; do not edit by hand.";

/// The machine, OS and compiler a section was measured with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stamp {
    /// The CPU model (`/proc/cpuinfo`'s `model name`).
    pub cpu: String,
    /// Cores available to the process.
    pub cores: usize,
    /// The OS's name and kernel.
    pub os: String,
    /// `rustc --version`.
    pub rustc: String,
    /// The day of the run, UTC, `YYYY-MM-DD`.
    pub date: String,
}

impl Stamp {
    /// This machine, today.
    pub fn here() -> Self {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let os_release = std::fs::read_to_string("/etc/os-release").unwrap_or_default();
        let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
        Stamp {
            cpu: cpu_model(&cpuinfo),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            os: os_name(&os_release, kernel.trim()),
            rustc: command_line("rustc", &["--version"]),
            date: today(),
        }
    }

    /// The stamp line of a section.
    pub fn line(&self, options: &str, seconds: f64) -> String {
        format!(
            "Measured {} on {} ({} cores), {}, {}; {options}; the run took {:.0} s.",
            self.date, self.cpu, self.cores, self.os, self.rustc, seconds
        )
    }
}

/// The CPU model named in `/proc/cpuinfo`'s text (x86's `model name`,
/// else ARM's `Hardware` or `Model`), or "unknown CPU".
pub fn cpu_model(cpuinfo: &str) -> String {
    for key in ["model name", "Hardware", "Model"] {
        for line in cpuinfo.lines() {
            if let Some((k, v)) = line.split_once(':') {
                if k.trim() == key && !v.trim().is_empty() {
                    return v.split_whitespace().collect::<Vec<_>>().join(" ");
                }
            }
        }
    }
    "unknown CPU".into()
}

/// The OS's `PRETTY_NAME` from `/etc/os-release`'s text and the kernel's
/// release, e.g. "Debian GNU/Linux 12 (bookworm), Linux 6.1.0".
pub fn os_name(os_release: &str, kernel: &str) -> String {
    let name = os_release
        .lines()
        .find_map(|l| l.strip_prefix("PRETTY_NAME="))
        .map(|v| v.trim().trim_matches('"').to_string())
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    if kernel.is_empty() {
        name
    } else {
        format!("{name}, {} {kernel}", capitalised(std::env::consts::OS))
    }
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// `rustc --version`, or a note that it is unknown.
pub fn rustc_version() -> String {
    command_line("rustc", &["--version"])
}

/// The first line a command prints, or a note that it could not run.
pub fn command_line(cmd: &str, args: &[&str]) -> String {
    Command::new(cmd)
        .args(args)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| {
            String::from_utf8_lossy(&o.stdout)
                .lines()
                .next()
                .map(str::to_string)
        })
        .unwrap_or_else(|| format!("{cmd} (version unknown)"))
}

/// Today (UTC), `YYYY-MM-DD`.
pub fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    civil_date(secs / 86_400)
}

/// `YYYY-MM-DD` of the day `days` after 1970-01-01 (H. Hinnant's
/// days-to-civil algorithm).
pub fn civil_date(days: u64) -> String {
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// Is this line criterion's own (a benchmark's id line, its estimates,
/// outliers, change reports) rather than the bench's?
fn is_criterion_line(line: &str, next: Option<&str>) -> bool {
    let t = line.trim();
    let starts = [
        "time:",
        "thrpt:",
        "change:",
        "Found ",
        "Benchmarking ",
        "Performance has ",
        "No change in performance",
        "Change within noise",
        "Gnuplot not found",
        "WARNING: ",
    ];
    if starts.iter().any(|s| t.starts_with(s)) || t.contains(" time:   [") {
        return true;
    }
    // "  3 (3.00%) high mild"
    if t.ends_with(" high mild")
        || t.ends_with(" high severe")
        || t.ends_with(" low mild")
        || t.ends_with(" low severe")
    {
        return true;
    }
    // an id line: a single word with a '/' followed by its "time:" line
    !t.is_empty()
        && !t.contains(' ')
        && t.contains('/')
        && next.is_some_and(|n| n.trim_start().starts_with("time:"))
}

/// A benchmark's estimate: its id and criterion's middle estimate \[s\].
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// `group/function/parameter`.
    pub id: String,
    /// The middle of criterion's three numbers, in seconds.
    pub seconds: f64,
}

/// Criterion's estimates in a bench's standard output: `ID` then `time:
/// [low mid high]` on the next line, or both on one line.
pub fn criterion_estimates(stdout: &str) -> Vec<Estimate> {
    let lines: Vec<&str> = stdout.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let Some(at) = line.find("time:") else {
            continue;
        };
        let before = line[..at].trim();
        let id = if before.is_empty() {
            match i.checked_sub(1).map(|j| lines[j].trim()) {
                Some(prev) if !prev.is_empty() => prev.to_string(),
                _ => continue,
            }
        } else {
            before.to_string()
        };
        let Some(inside) = line[at..]
            .split_once('[')
            .and_then(|(_, r)| r.split_once(']'))
            .map(|(i, _)| i)
        else {
            continue;
        };
        let words: Vec<&str> = inside.split_whitespace().collect();
        if words.len() != 6 {
            continue;
        }
        if let Some(seconds) = seconds_of(words[2], words[3]) {
            out.push(Estimate { id, seconds });
        }
    }
    out
}

fn seconds_of(number: &str, unit: &str) -> Option<f64> {
    let x: f64 = number.parse().ok()?;
    let scale = match unit {
        "ps" => 1e-12,
        "ns" => 1e-9,
        "µs" | "us" => 1e-6,
        "ms" => 1e-3,
        "s" => 1.0,
        _ => return None,
    };
    Some(x * scale)
}

/// The several-contact engine's cost per switch: `sample_with_a_switch/K`
/// less `plain_sample/K` for each `K` both were measured at, as a table.
pub fn per_switch_table(estimates: &[Estimate]) -> Option<String> {
    let find = |id: String| estimates.iter().find(|e| e.id == id).map(|e| e.seconds);
    let mut rows = Vec::new();
    for k in 1..=8 {
        let (Some(with), Some(plain)) = (
            find(format!("several_contacts/sample_with_a_switch/{k}")),
            find(format!("several_contacts/plain_sample/{k}")),
        ) else {
            continue;
        };
        rows.push(format!(
            "| {k} | {:.1} | {:.1} | {:.1} |",
            with * 1e6,
            plain * 1e6,
            (with - plain) * 1e6
        ));
    }
    if rows.is_empty() {
        return None;
    }
    Some(format!(
        "per switch on a 100-mode object (criterion's middle estimates, the same run):\n\
         | contacts | sample with a switch us | plain sample us | per switch us |\n\
         |---|---|---|---|\n{}\n",
        rows.join("\n")
    ))
}

/// The bench's own lines of its standard output as Markdown: criterion's
/// lines dropped, table rows kept as tables, a line ending in `:` right
/// before a table as its caption, every other run of lines as a text
/// block.
pub fn capture(stdout: &str) -> String {
    let lines: Vec<&str> = stdout.lines().collect();
    let kept: Vec<&str> = lines
        .iter()
        .enumerate()
        .filter(|(i, l)| !is_criterion_line(l, lines.get(i + 1).copied()))
        .map(|(_, l)| l.trim_end())
        .collect();
    let mut out = String::new();
    let mut text: Vec<&str> = Vec::new();
    let flush_text = |text: &mut Vec<&str>, out: &mut String| {
        while text.last().is_some_and(|l| l.trim().is_empty()) {
            text.pop();
        }
        let start = text.iter().position(|l| !l.trim().is_empty());
        if let Some(start) = start {
            out.push_str("```text\n");
            for l in &text[start..] {
                out.push_str(l);
                out.push('\n');
            }
            out.push_str("```\n\n");
        }
        text.clear();
    };
    let mut i = 0;
    while i < kept.len() {
        let l = kept[i];
        let is_row = |s: &str| s.trim_start().starts_with('|');
        if is_row(l) {
            // a caption: the text line just before the table
            let caption = match text.last() {
                Some(c) if c.trim_end().ends_with(':') => text.pop(),
                _ => None,
            };
            flush_text(&mut text, &mut out);
            if let Some(c) = caption {
                out.push_str(c.trim());
                out.push_str("\n\n");
            }
            while i < kept.len() && is_row(kept[i]) {
                out.push_str(kept[i].trim());
                out.push('\n');
                i += 1;
            }
            out.push('\n');
            continue;
        }
        text.push(l);
        i += 1;
    }
    flush_text(&mut text, &mut out);
    out
}

/// The marker lines around a section.
fn markers(name: &str) -> (String, String) {
    (
        format!("<!-- bench: {name} -->"),
        format!("<!-- end of bench: {name} -->"),
    )
}

/// The sections of an existing page, by name (the text between a
/// section's markers, markers included).
pub fn sections(page: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut rest = page;
    while let Some(at) = rest.find("<!-- bench: ") {
        let after = &rest[at + "<!-- bench: ".len()..];
        let Some(close) = after.find(" -->") else {
            break;
        };
        let name = after[..close].to_string();
        let (_, end) = markers(&name);
        let Some(end_at) = rest[at..].find(&end) else {
            break;
        };
        let stop = at + end_at + end.len();
        out.push((name, rest[at..stop].to_string()));
        rest = &rest[stop..];
    }
    out
}

/// One section: heading, the command, what it measures, the stamp and the
/// captured tables.
pub fn section(bench: &Bench, command: &str, stamp_line: &str, body: &str) -> String {
    let (start, end) = markers(bench.name);
    let mut s = String::new();
    let _ = writeln!(s, "{start}");
    let _ = writeln!(s, "## {}\n", bench.title);
    let _ = writeln!(s, "`{command}`\n");
    let _ = writeln!(s, "{}\n", bench.about);
    let _ = writeln!(s, "{stamp_line}\n");
    s.push_str(body.trim_end());
    let _ = write!(s, "\n{end}");
    s
}

/// A section no run has written yet.
fn missing_section(bench: &Bench) -> String {
    section(
        bench,
        &command_text(bench, false),
        &format!(
            "Not measured yet: `cargo xtask benchmarks --only {}` writes it.",
            bench.name
        ),
        "",
    )
}

/// The command as a reader types it.
pub fn command_text(bench: &Bench, quick: bool) -> String {
    let mut words: Vec<&str> = vec!["cargo"];
    words.extend(bench.args.iter().copied());
    if quick {
        let extra = bench.quick_args;
        // a second `--` would end up among the bench's own arguments
        let skip = usize::from(extra.first() == Some(&"--") && words.contains(&"--"));
        words.extend(extra[skip..].iter().copied());
    }
    words.join(" ")
}

/// The whole page from its sections, in [`BENCHES`]' order.
pub fn page(sections: &[(String, String)]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{TITLE}\n");
    let _ = writeln!(s, "{GENERATED}\n");
    s.push_str(
        "Every table below is printed by one of the project's benches (or, for the \
stiff cases, by a test) and copied here as it was printed; `cargo xtask benchmarks` \
runs them all again and rewrites this page, and `cargo xtask benchmarks --only NAME` \
rewrites one section. Each section says on which machine, with which compiler and on \
which day it was measured. Timings are reported, never asserted by a test: they move \
with the machine and with what else it runs, so compare the rows of one section, not \
sections of different runs. Documents that discuss a timing point here rather than \
quoting one.\n\n\
Elsewhere: error against run time and the stability table, `cargo xtask report` \
(docs/report.md); the presets against recordings of the real instruments, \
`cargo xtask compare-real` (docs/compare-real.md).\n\n",
    );
    for b in &BENCHES {
        let _ = writeln!(s, "- [{}](#{}) (`{}`)", b.title, anchor(b.title), b.name);
    }
    s.push('\n');
    for b in &BENCHES {
        let text = sections
            .iter()
            .find(|(n, _)| n == b.name)
            .map(|(_, t)| t.clone())
            .unwrap_or_else(|| missing_section(b));
        s.push_str(&text);
        s.push_str("\n\n");
    }
    s.truncate(s.trim_end().len());
    s.push('\n');
    s
}

/// GitHub's anchor of a heading.
pub fn anchor(title: &str) -> String {
    title
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// Run one bench: its command, with its standard output echoed to this
/// process's standard error as it comes and captured.
fn run_bench(bench: &Bench, quick: bool) -> Result<(String, f64)> {
    let mut args: Vec<&str> = bench.args.to_vec();
    if quick {
        let extra = bench.quick_args;
        let skip = usize::from(extra.first() == Some(&"--") && args.contains(&"--"));
        args.extend(extra[skip..].iter().copied());
    }
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("+ cargo {}", args.join(" "));
    let t0 = Instant::now();
    let mut child = Command::new(cargo)
        .args(&args)
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot run cargo {}", args.join(" ")))?;
    let mut stdout = String::new();
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines() {
            let line = line.context("reading the bench's output")?;
            eprintln!("{line}");
            stdout.push_str(&line);
            stdout.push('\n');
        }
    }
    let status = child.wait()?;
    let seconds = t0.elapsed().as_secs_f64();
    if !status.success() {
        bail!("cargo {} failed: {status}", args.join(" "));
    }
    let body = match bench.source {
        Source::Stdout => {
            let mut body = capture(&stdout);
            if let Some(t) = per_switch_table(&criterion_estimates(&stdout)) {
                body.push_str(&capture(&t));
            }
            body
        }
        Source::File(path) => std::fs::read_to_string(path)
            .with_context(|| format!("reading {path}, which the command writes"))?,
    };
    Ok((body, seconds))
}

/// `cargo xtask benchmarks`.
pub fn run(args: &BenchmarksArgs) -> Result<()> {
    for name in &args.only {
        if !BENCHES.iter().any(|b| b.name == name) {
            let names: Vec<&str> = BENCHES.iter().map(|b| b.name).collect();
            bail!("no bench named {name:?}; the benches: {}", names.join(", "));
        }
    }
    let old = std::fs::read_to_string(&args.out).unwrap_or_default();
    let mut kept = sections(&old);
    let stamp = Stamp::here();
    let mut failed = Vec::new();
    for bench in BENCHES
        .iter()
        .filter(|b| args.only.is_empty() || args.only.iter().any(|n| n == b.name))
    {
        let quick = args.quick && !bench.quick_args.is_empty();
        let options = if quick {
            "`--quick`: shortened as the command shows"
        } else if args.quick {
            "`--quick` (no shorter form of this bench: the full run)"
        } else {
            "the full run"
        };
        match run_bench(bench, quick) {
            Ok((body, seconds)) => {
                let text = section(
                    bench,
                    &command_text(bench, quick),
                    &stamp.line(options, seconds),
                    &body,
                );
                kept.retain(|(n, _)| n != bench.name);
                kept.push((bench.name.to_string(), text));
                write_page(&args.out, &kept)?;
            }
            Err(e) => {
                eprintln!("{}: {e:#}", bench.name);
                failed.push(bench.name);
            }
        }
    }
    write_page(&args.out, &kept)?;
    eprintln!("wrote {}", args.out.display());
    if !failed.is_empty() {
        bail!(
            "{} failed (their sections keep the last run's tables): {}",
            failed.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// Write the page after each bench, so a long run that stops keeps what
/// it measured.
fn write_page(out: &Path, sections: &[(String, String)]) -> Result<()> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(out, page(sections)).with_context(|| format!("writing {}", out.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_from_days_since_1970() {
        assert_eq!(civil_date(0), "1970-01-01");
        assert_eq!(civil_date(59), "1970-03-01");
        assert_eq!(civil_date(11_016), "2000-02-29");
        assert_eq!(civil_date(19_782), "2024-02-29");
        assert_eq!(civil_date(20_454), "2026-01-01");
    }

    #[test]
    fn the_stamp_names_machine_os_compiler_and_day() {
        let cpuinfo = "processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC  7B13 64-Core Processor\n\nprocessor\t: 1\nmodel name\t: AMD EPYC 7B13 64-Core Processor\n";
        assert_eq!(cpu_model(cpuinfo), "AMD EPYC 7B13 64-Core Processor");
        assert_eq!(cpu_model("Hardware\t: BCM2835\n"), "BCM2835");
        assert_eq!(cpu_model(""), "unknown CPU");
        let os = os_name(
            "NAME=\"Debian GNU/Linux\"\nPRETTY_NAME=\"Debian GNU/Linux 12 (bookworm)\"\n",
            "6.1.0-18-amd64",
        );
        assert!(os.starts_with("Debian GNU/Linux 12 (bookworm), "), "{os}");
        assert!(os.ends_with(" 6.1.0-18-amd64"), "{os}");
        let stamp = Stamp {
            cpu: "AMD EPYC 7B13".into(),
            cores: 2,
            os: "Debian GNU/Linux 12, Linux 6.1".into(),
            rustc: "rustc 1.91.0 (f8297e351 2025-10-28)".into(),
            date: "2026-01-02".into(),
        };
        assert_eq!(
            stamp.line("the full run", 131.6),
            "Measured 2026-01-02 on AMD EPYC 7B13 (2 cores), Debian GNU/Linux 12, Linux 6.1, \
             rustc 1.91.0 (f8297e351 2025-10-28); the full run; the run took 132 s."
        );
    }

    const CRITERION: &str = "\
several_contacts/sample_with_a_switch/2
                        time:   [18.485 µs 19.626 µs 20.979 µs]
Found 14 outliers among 100 measurements (14.00%)
  2 (2.00%) high mild
  12 (12.00%) high severe
several_contacts/plain_sample/2
                        time:   [1.8956 µs 1.9177 µs 1.9479 µs]
                        change: [-1.2% +0.3% +1.9%] (p = 0.71 > 0.05)
                        No change in performance detected.
short/id                time:   [850.00 ns 900.00 ns 950.00 ns]


2 contacts, 100 modes: 4 phases of up to 204 coordinates compiled in 0.09 s

kits: worst block at 48 kHz, % of the block's budget:
| kit | keys at once | 32 samples |
|---|---|---|
| marimba-two-mallets | 1 | 9 / 7 |
a closing line
";

    #[test]
    fn criterion_lines_go_and_the_bench_lines_stay() {
        let md = capture(CRITERION);
        assert_eq!(
            md,
            "```text\n2 contacts, 100 modes: 4 phases of up to 204 coordinates compiled in 0.09 s\n```\n\n\
             kits: worst block at 48 kHz, % of the block's budget:\n\n\
             | kit | keys at once | 32 samples |\n|---|---|---|\n| marimba-two-mallets | 1 | 9 / 7 |\n\n\
             ```text\na closing line\n```\n\n"
        );
    }

    #[test]
    fn criterion_estimates_and_the_cost_per_switch() {
        let e = criterion_estimates(CRITERION);
        let ids: Vec<&str> = e.iter().map(|e| e.id.as_str()).collect();
        assert_eq!(
            ids,
            [
                "several_contacts/sample_with_a_switch/2",
                "several_contacts/plain_sample/2",
                "short/id"
            ]
        );
        assert!((e[0].seconds - 19.626e-6).abs() < 1e-15);
        assert!((e[2].seconds - 900e-9).abs() < 1e-15);
        let t = per_switch_table(&e).expect("a table");
        assert!(t.contains("| 2 | 19.6 | 1.9 | 17.7 |"), "{t}");
        assert_eq!(per_switch_table(&e[2..]), None);
    }

    #[test]
    fn a_section_run_alone_replaces_only_its_own() {
        let b = &BENCHES[1];
        let first = section(
            b,
            "cargo bench --bench worst_block",
            "Measured A.",
            "| a |\n",
        );
        let p = page(&[(b.name.to_string(), first)]);
        assert!(p.starts_with(&format!("{TITLE}\n\n{GENERATED}\n")));
        // every other bench has its placeholder, in the page's order
        let names: Vec<String> = sections(&p).into_iter().map(|(n, _)| n).collect();
        let all: Vec<&str> = BENCHES.iter().map(|b| b.name).collect();
        assert_eq!(names, all);
        assert!(p.contains("`cargo xtask benchmarks --only engine` writes it"));
        // a new run of another section keeps this one byte for byte
        let mut kept = sections(&p);
        let engine = section(&BENCHES[0], "cargo bench", "Measured B.", "x");
        kept.retain(|(n, _)| n != "engine");
        kept.push(("engine".into(), engine));
        let q = page(&kept);
        let again = sections(&q);
        assert_eq!(again[1], sections(&p)[1]);
        assert!(again[0].1.contains("Measured B."));
        assert_eq!(
            page(&sections(&q)),
            q,
            "reading and writing is a fixed point"
        );
    }

    #[test]
    fn quick_arguments_join_the_bench_arguments() {
        let sc = BENCHES
            .iter()
            .find(|b| b.name == "several_contacts")
            .unwrap();
        assert_eq!(
            command_text(sc, true),
            "cargo bench --bench several_contacts -- --warm-up-time 1 --measurement-time 2"
        );
        let a = BENCHES.iter().find(|b| b.name == "activation").unwrap();
        assert_eq!(
            command_text(a, true),
            "cargo bench -p plugin-tests --bench activation -- 1"
        );
        let e = &BENCHES[0];
        assert_eq!(
            command_text(e, true),
            "cargo bench --bench engine -- summary"
        );
        assert_eq!(anchor(BENCHES[2].title), "several-contacts-and-kits");
        assert_eq!(
            anchor(BENCHES[0].title),
            "the-engine-per-sample-per-switch-renders-and-compiles"
        );
    }
}
