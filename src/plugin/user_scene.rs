//! The user's own scenes in the plugin: the scene text a user loaded (from
//! the editor's scene browser or a file dialog), compiled on the worker,
//! reported to the editor, and saved with the host's project.
//!
//! Threads (docs/design.md, "The editor"): the audio thread only reads
//! [`SceneLibrary::active`], an atomic generation number that is part of
//! [`SceneParams`] (0: the Scene parameter's preset plays). The editor and
//! the worker share the scene text and the compile report behind mutexes the
//! audio thread never touches. A scene that fails to parse, validate or
//! compile never stops the sound: the last good scene keeps playing and the
//! error, with the field's path, is shown in the window and logged.

use crate::compile::{
    prune::{struck_mode_fates, StruckModes},
    CompileOptions,
};
use crate::instrument::{
    lookahead_samples, prepare_scene_staged, prepare_staged, scene_for, InstrumentParams, Prepared,
    SceneParams, Stage, StrikeCost,
};
use crate::presets;
use crate::scene::{ObjectSpec, Scene};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

/// A scene file's text as the user loaded it: saved in the project, so it
/// plays on a machine without the file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct UserScene {
    /// Shown in the window (the file's stem).
    pub name: String,
    /// The whole TOML text.
    pub text: String,
    /// Where it was loaded from, if from a file (for "changed on disk").
    #[serde(default)]
    pub path: Option<PathBuf>,
}

impl UserScene {
    /// Read a scene file (not parsed here: the worker validates it).
    pub fn from_file(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        Ok(Self {
            name: path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into()),
            text,
            path: Some(path.to_path_buf()),
        })
    }
}

/// One mode of the struck object, for the editor's spectrum.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectrumLine {
    /// Frequency at the scene's root note \[Hz\].
    pub freq_hz: f64,
    /// Level relative to the loudest mode (1 = loudest).
    pub level: f64,
    /// Left out by the compiler (why), or `None` if kept.
    pub pruned: Option<String>,
    /// Above the output band at the root note (not heard).
    pub out_of_band: bool,
    /// A modal mallet's mode (joined to the struck object, as the compiler
    /// does: docs/design.md, "Modal mallets").
    pub mallet: bool,
}

/// Why a report has no spectrum.
#[derive(Debug, Clone, PartialEq)]
pub enum NoSpectrum {
    /// The struck object has no modes to list (a lumped string, a wall):
    /// said plainly, not an error.
    NoModes(String),
    /// Turning the struck object into its modes failed: the error, with
    /// the field's path (shown as an error).
    Failed(String),
}

/// What the worker last did, for the editor (and the log).
#[derive(Debug, Clone, Default)]
pub struct CompileReport {
    /// Increases with every report.
    pub serial: u64,
    /// The scene's name.
    pub scene: String,
    /// A user scene (else a preset).
    pub user: bool,
    /// The compile summary's key facts, one line.
    pub summary: String,
    /// The error, if this compile failed (the previous scene plays on).
    pub error: Option<String>,
    /// Modes of the struck object (empty for strings and walls, and when
    /// `no_spectrum` says why).
    pub spectrum: Vec<SpectrumLine>,
    /// Why `spectrum` is empty (`None` before the first compile).
    pub no_spectrum: Option<NoSpectrum>,
    /// The scene's root note.
    pub root_note: f64,
    /// Sample rate compiled for \[Hz\].
    pub rate_hz: f64,
    /// What the user should know (exact switching refused, a stiff
    /// contact, a scene too large for the brightness levels).
    pub warnings: Vec<String>,
    /// The scene's strike cost and the host's largest block: the editor
    /// says the strike warning for the Polyphony and Lookahead of the
    /// moment ([`CompileReport::strike_warning`]).
    pub strike: Option<(StrikeCost, usize)>,
    /// A driven scene's path (`None`: the scene is struck).
    pub path: Option<PathView>,
}

/// Columns of a driven scene's path the editor draws.
pub const PATH_COLUMNS: usize = 512;

/// A driven scene's path for the editor (docs/plugin.md, "The editor"):
/// the profile the contact follows (the surface as the rolling body sees
/// it), as the lowest and highest height of each of [`PATH_COLUMNS`]
/// equal stretches of the path (fewer when the profile has fewer points).
#[derive(Debug, Clone, PartialEq)]
pub struct PathView {
    /// The path's length \[m\] (its period when it wraps).
    pub length_m: f64,
    /// Whether the path wraps (a position beyond it is taken modulo it).
    pub periodic: bool,
    /// Each column's lowest and highest height \[m\].
    pub columns: Vec<(f32, f32)>,
}

impl PathView {
    /// The view of a compiled drive's profile.
    pub fn of(d: &crate::compile::drive::DrivePlan) -> Self {
        let h = &d.profile.heights;
        let n = h.len();
        let cols = PATH_COLUMNS.min(n.max(1));
        let columns = (0..cols)
            .map(|c| {
                let (a, b) = (
                    c * n / cols,
                    ((c + 1) * n / cols).max(c * n / cols + 1).min(n),
                );
                h[a..b]
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                        (lo.min(v as f32), hi.max(v as f32))
                    })
            })
            .collect();
        Self {
            length_m: d.profile.length(),
            periodic: d.profile.periodic,
            columns,
        }
    }
}

impl CompileReport {
    /// The strike warning at `polyphony` voices and a lookahead of
    /// `lookahead_s` seconds (`None`: it fits, or no scene compiled).
    /// \[main-thread\]
    pub fn strike_warning(&self, polyphony: usize, lookahead_s: f64) -> Option<String> {
        let (cost, max_block) = self.strike.as_ref()?;
        cost.warning(
            *max_block,
            polyphony,
            lookahead_samples(lookahead_s, cost.rate_hz),
        )
    }
}

/// The user scene state of one plugin instance (see the module doc).
pub struct SceneLibrary {
    /// Generation of the user scene to play (0: the preset). \[any-thread\]
    active: AtomicU64,
    next_gen: AtomicU64,
    /// The scene of generation `active` (GUI and worker).
    requested: Mutex<Option<(u64, Arc<UserScene>)>>,
    /// The last user scene that compiled (what is heard and saved).
    playing: Mutex<Option<Arc<UserScene>>>,
    report: Mutex<CompileReport>,
}

/// Lock a mutex, taking the value even if a panicking thread poisoned it
/// (its data is plain values, always consistent).
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Default for SceneLibrary {
    fn default() -> Self {
        Self {
            active: AtomicU64::new(0),
            next_gen: AtomicU64::new(1),
            requested: Mutex::new(None),
            playing: Mutex::new(None),
            report: Mutex::new(CompileReport::default()),
        }
    }
}

impl SceneLibrary {
    /// Generation of the user scene to play, 0 for the preset. Atomic load.
    /// \[any-thread\]
    pub fn active(&self) -> u64 {
        self.active.load(Ordering::Acquire)
    }

    /// Ask for `scene` to be played (compiled on the worker at the next
    /// block). \[gui-thread\] \[main-thread\]
    pub fn load(&self, scene: UserScene) {
        let g = self.next_gen.fetch_add(1, Ordering::Relaxed);
        *lock(&self.requested) = Some((g, Arc::new(scene)));
        self.active.store(g, Ordering::Release);
    }

    /// Go back to the Scene parameter's preset. \[gui-thread\]
    pub fn clear(&self) {
        *lock(&self.requested) = None;
        *lock(&self.playing) = None;
        self.active.store(0, Ordering::Release);
    }

    /// The user scene heard now, if any.
    pub fn playing(&self) -> Option<Arc<UserScene>> {
        lock(&self.playing).clone()
    }

    /// The user scene asked for (it may not have compiled).
    pub fn requested(&self) -> Option<Arc<UserScene>> {
        lock(&self.requested).as_ref().map(|(_, s)| s.clone())
    }

    /// The last compile report.
    pub fn report(&self) -> CompileReport {
        lock(&self.report).clone()
    }

    /// What a saved project stores: the scene heard, else the one asked
    /// for (a scene that failed to compile is kept, never lost).
    pub fn to_saved(&self) -> Option<UserScene> {
        self.playing()
            .or_else(|| self.requested())
            .map(|s| (*s).clone())
    }

    /// Restore a saved project's user scene (`None`: the preset).
    pub fn restore(&self, saved: Option<UserScene>) {
        match saved {
            Some(s) => self.load(s),
            None => self.clear(),
        }
    }

    /// Build the scene `params` asks for: the preset, or the user scene of
    /// generation `params.user_scene` (if the editor loaded another since,
    /// the newest; the result's `params.user_scene` says which). Parses,
    /// validates and compiles; on failure the previous scene plays on and a
    /// user scene that fails is not made current. Writes the report, with
    /// the warnings (also returned, for the log): a switching fallback, a
    /// stiff contact, a strike that may overrun the host's block, a scene
    /// too large for the brightness levels.
    /// \[worker\] \[main-thread\]
    pub fn prepare(
        &self,
        params: &SceneParams,
        rate_hz: f64,
        revision: u64,
        host: HostBlocks,
    ) -> Result<(Box<Prepared>, Vec<String>), String> {
        self.prepare_staged(params, rate_hz, revision, host, Stage::Full)
    }

    /// [`Self::prepare`] of `stage` (an activation's first scene on a live
    /// host is [`Stage::Playable`]). \[worker\] \[main-thread\]
    pub fn prepare_staged(
        &self,
        params: &SceneParams,
        rate_hz: f64,
        revision: u64,
        host: HostBlocks,
        stage: Stage,
    ) -> Result<(Box<Prepared>, Vec<String>), String> {
        let t0 = Instant::now();
        let mut params = *params;
        let user = if params.user_scene == 0 {
            None
        } else {
            let r = lock(&self.requested).clone();
            params.user_scene = r.as_ref().map_or(0, |(g, _)| *g);
            r.map(|(_, s)| s)
        };
        let (name, base) = match &user {
            Some(u) => (
                u.name.clone(),
                Scene::from_toml_str(&u.text).map_err(|e| format!("scene {:?}: {e}", u.name)),
            ),
            None => (
                presets::PRESETS
                    .get(params.preset)
                    .map_or("?", |p| p.name)
                    .to_string(),
                presets::scene(params.preset).map_err(|e| e.to_string()),
            ),
        };
        let result = base.and_then(|base| {
            let p = match &user {
                Some(_) => prepare_scene_staged(&base, &params, rate_hz, revision, stage),
                None => prepare_staged(&params, rate_hz, revision, stage),
            }
            .map_err(|e| format!("scene {name:?}: {e}"))?;
            Ok((base, p))
        });
        // a cancelled compile (the instance deactivated) reports nothing:
        // the editor keeps what it showed
        if crate::compile::cancel::cancelled() {
            return Err(format!(
                "scene {name:?}: {}",
                crate::compile::cancel::Cancelled
            ));
        }
        let mut report = lock(&self.report);
        report.serial += 1;
        report.scene = name;
        report.user = user.is_some();
        match result {
            Ok((base, p)) => {
                if let Some(u) = user {
                    *lock(&self.playing) = Some(u);
                }
                let ms = t0.elapsed().as_secs_f64() * 1e3;
                report.error = None;
                (report.spectrum, report.no_spectrum) = match spectrum(&base, &params, &p) {
                    Ok(s) => (s, None),
                    Err(why) => (Vec::new(), Some(why)),
                };
                report.summary = summary_line(&p, &report.spectrum, ms);
                report.root_note = p.root_note;
                report.rate_hz = rate_hz;
                report.warnings = [
                    p.fallback_note.clone(),
                    p.realtime_warning(),
                    p.timbre_note(),
                ]
                .into_iter()
                .flatten()
                .collect();
                report.strike = Some((p.strike_cost(), host.max_block));
                report.path = p.scenes.scene.drive.as_ref().map(PathView::of);
                // the log says the strike warning for the compile's
                // parameters; the editor says it for the current ones
                let mut log = report.warnings.clone();
                log.extend(p.strike_warning(host.max_block, host.polyphony, host.lookahead));
                Ok((p, log))
            }
            Err(e) => {
                if user.is_some() {
                    // the failed scene is not current: go back to what plays
                    let back = lock(&self.playing).clone();
                    let mut req = lock(&self.requested);
                    match back {
                        Some(b) if req.as_ref().is_some_and(|(g, _)| *g == params.user_scene) => {
                            let g = self.next_gen.fetch_add(1, Ordering::Relaxed);
                            *req = Some((g, b));
                            self.active.store(g, Ordering::Release);
                        }
                        None if req.as_ref().is_some_and(|(g, _)| *g == params.user_scene) => {
                            // keep the text (saved with the project) but play the preset
                            self.active.store(0, Ordering::Release);
                        }
                        _ => {}
                    }
                }
                report.error = Some(e.clone());
                Err(e)
            }
        }
    }
}

/// The host's largest block, the polyphony and the lookahead, for the
/// strike-cost warning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HostBlocks {
    /// Largest block \[samples\].
    pub max_block: usize,
    /// Voices.
    pub polyphony: usize,
    /// The lookahead \[samples\].
    pub lookahead: usize,
}

/// The compile summary's facts for the window: modes kept, route, the
/// engine's cost per sample (its dimensions) and per strike (the estimate
/// the strike warning uses), compile time.
fn summary_line(p: &Prepared, spectrum: &[SpectrumLine], ms: f64) -> String {
    if let Some(kit) = &p.kit {
        return format!(
            "{}, strike ~{:.0} us, compiled in {ms:.1} ms",
            kit.summary(),
            p.strike_cost_estimate_s() * 1e6,
        );
    }
    let sc = &p.scenes.scene;
    let route = sc
        .summary
        .lines()
        .find(|l| l.starts_with("contact phase"))
        .and_then(|l| l.split(", ").nth(1))
        .unwrap_or("?");
    let modes = if spectrum.is_empty() {
        String::new()
    } else {
        format!(
            "{} of {} modes kept, ",
            spectrum.iter().filter(|m| m.pruned.is_none()).count(),
            spectrum.len()
        )
    };
    format!(
        "{modes}{} states free / {} in contact (per sample O(states)), contact route: {route}, {} switching, strike ~{:.0} us, root note {:.1}, compiled in {ms:.1} ms",
        sc.free.dim,
        sc.contact.dim,
        p.switching_used.as_str(),
        p.strike_cost_estimate_s() * 1e6,
        p.root_note,
    )
}

/// The struck object's modes as the compiler treats them, at the root note:
/// resolved to its modes as the compiler does
/// ([`struck_mode_fates`]: an object from geometry and material expanded at
/// the compile's rate, a modal mallet's modes joined). A kit's engine keeps
/// every mode (docs/design.md, "Several contacts"): none is shown left out.
fn spectrum(
    base: &Scene,
    params: &SceneParams,
    p: &Prepared,
) -> Result<Vec<SpectrumLine>, NoSpectrum> {
    let played = scene_for(
        base,
        &InstrumentParams {
            scene: *params,
            play: Default::default(),
        },
    );
    let opts = if played.several_contacts() {
        CompileOptions {
            exact_savings: false,
            approximations: false,
            ..CompileOptions::DEFAULT
        }
    } else {
        CompileOptions::DEFAULT
    };
    let struck = struck_mode_fates(&played, p.rate_hz, &opts)
        .map_err(|e| NoSpectrum::Failed(e.to_string()))?;
    let Some(StruckModes { fates, own }) = struck else {
        let name = &played.contact.object;
        let what = match played.object_index(name).map(|i| &played.object[i]) {
            Some(ObjectSpec::String(st)) => format!(
                "{name:?} is a lumped string of {} masses, not a table of modes: no spectrum to show",
                st.masses
            ),
            _ => format!("{name:?} is a wall, without modes: no spectrum to show"),
        };
        return Err(NoSpectrum::NoModes(what));
    };
    let band_hz = crate::instrument::OUTPUT_BAND_FRACTION * 0.5 * p.rate_hz;
    Ok(fates
        .into_iter()
        .enumerate()
        .map(|(i, f)| SpectrumLine {
            freq_hz: f.freq_hz,
            level: f.level,
            out_of_band: f.freq_hz > band_hz,
            pruned: f.dropped,
            mallet: i >= own,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The example of docs/plugin.md, "Write your first scene".
    const THREE_MODES: &str = r#"
version = 1
name = "three"
duration_s = 1.0

[[object]]
name = "bar"
kind = "modal"
points = ["contact", "pickup"]

[[object.mode]]
freq_hz = 220.0
t60_s = 1.0
weights = [1.0, 1.0]

[[object.mode]]
freq_hz = 880.0
t60_s = 0.5
weights = [0.8, -0.6]

[[object.mode]]
freq_hz = 2000.0
t60_s = 0.3
weights = [0.0, 0.0]

[hammer]
mass_kg = 0.03
height_m = 0.001
velocity_m_per_s = -2.0

[contact]
object = "bar"
point = "contact"
stiffness_n_per_m = 3e5
damping_n_s_per_m = 40.0

[[pickup]]
object = "bar"
point = "pickup"
quantity = "velocity"
gain = 0.5
"#;

    fn user(text: &str) -> UserScene {
        UserScene {
            name: "mine".into(),
            text: text.into(),
            path: None,
        }
    }

    const HOST: HostBlocks = HostBlocks {
        max_block: 512,
        polyphony: 16,
        lookahead: 0,
    };

    fn wanted(lib: &SceneLibrary) -> SceneParams {
        SceneParams {
            user_scene: lib.active(),
            ..SceneParams::default()
        }
    }

    #[test]
    fn a_user_scene_compiles_and_reports_its_modes() {
        let lib = SceneLibrary::default();
        lib.load(user(THREE_MODES));
        let p = lib
            .prepare(&wanted(&lib), 48_000.0, 1, HOST)
            .expect("compiles")
            .0;
        assert_eq!(p.params.user_scene, lib.active());
        assert_eq!(p.scenes.scene.name, "three");
        let r = lib.report();
        assert!(r.user && r.error.is_none(), "{r:?}");
        assert_eq!(r.spectrum.len(), 3);
        assert!(r.spectrum[2]
            .pruned
            .as_deref()
            .unwrap()
            .contains("zero at the contact"));
        assert_eq!(r.spectrum[0].level, 1.0);
        assert!(r.summary.contains("compiled in"), "{}", r.summary);
        assert_eq!(lib.playing().unwrap().name, "mine");
    }

    /// The strike warning follows the Polyphony and Lookahead of the
    /// moment (the editor asks the report again at every frame), not those
    /// of the compile; the log gets it for the compile's.
    #[test]
    fn the_strike_warning_follows_polyphony_and_lookahead() {
        // THREE_MODES with 300 modes: a 16-note chord overruns 64 samples
        let head = THREE_MODES.split("[[object.mode]]").next().unwrap();
        let tail = &THREE_MODES[THREE_MODES.find("[hammer]").unwrap()..];
        let modes: String = (0..300)
            .map(|k| {
                format!(
                    "[[object.mode]]\nfreq_hz = {}\nt60_s = 1.0\nweights = [1.0, {}]\n\n",
                    220.0 * 1.013f64.powi(k),
                    if k % 2 == 0 { 0.7 } else { -0.5 }
                )
            })
            .collect();
        let lib = SceneLibrary::default();
        lib.load(user(&format!("{head}{modes}{tail}")));
        let host = HostBlocks {
            max_block: 64,
            polyphony: 16,
            lookahead: 0,
        };
        let (_, log) = lib.prepare(&wanted(&lib), 48_000.0, 1, host).unwrap();
        let r = lib.report();
        let w = r
            .strike_warning(16, 0.0)
            .expect("16 strikes overrun 64 samples");
        assert!(
            log.contains(&w),
            "the log says it for the compile's parameters"
        );
        assert!(
            !r.warnings.contains(&w),
            "the report keeps the cost, not the text"
        );
        let ms: f64 = w
            .split("a Lookahead of ")
            .nth(1)
            .and_then(|x| x.split(" ms").next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("{w}"));
        println!("300 modes at 64 samples: {w}");
        assert!(
            r.strike_warning(16, ms * 1e-3).is_none(),
            "that lookahead spreads it"
        );
        // one strike alone takes more than half the block; a millisecond of
        // lookahead spreads it
        assert!(r.strike_warning(1, 0.0).is_some());
        assert!(r.strike_warning(1, 1e-3).is_none());
        assert!(
            r.strike_warning(64, ms * 1e-3).is_some(),
            "64 voices need more"
        );
    }

    /// Preset `i` prepared at 48 kHz by a new library: the library, the
    /// parameters and its report.
    fn preset_report(i: usize) -> (SceneLibrary, SceneParams, CompileReport) {
        let lib = SceneLibrary::default();
        let params = SceneParams {
            preset: i,
            ..SceneParams::default()
        };
        lib.prepare(&params, 48_000.0, 1, HOST)
            .unwrap_or_else(|e| panic!("{}: {e}", presets::PRESETS[i].name));
        let r = lib.report();
        (lib, params, r)
    }

    /// A driven preset's report carries its path for the editor: the
    /// compiled profile's length, and columns whose lows and highs are
    /// the profile's own extremes (every height inside its column's
    /// range); a struck preset's carries none.
    #[test]
    fn driven_presets_report_their_path() {
        for (i, pr) in presets::PRESETS.iter().enumerate() {
            let (_, _, r) = preset_report(i);
            let scene = presets::scene(i).unwrap();
            let Some(spec) = &scene.drive else {
                assert!(r.path.is_none(), "{}", pr.name);
                continue;
            };
            let plan = crate::compile::drive::plan(spec).unwrap();
            let path = r.path.as_ref().expect("a path");
            let h = &plan.profile.heights;
            assert_eq!(path.length_m, plan.profile.length(), "{}", pr.name);
            assert_eq!(path.columns.len(), PATH_COLUMNS.min(h.len()));
            // the columns tile the points in order, each its stretch's extremes
            let cols = path.columns.len();
            let mut next = 0;
            for (c, &(lo, hi)) in path.columns.iter().enumerate() {
                let end = ((c + 1) * h.len() / cols).max(next + 1);
                let stretch = &h[next..end];
                let lo_want = stretch.iter().fold(f64::INFINITY, |m, &v| m.min(v)) as f32;
                let hi_want = stretch.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v)) as f32;
                assert_eq!((lo, hi), (lo_want, hi_want), "{}: column {c}", pr.name);
                next = end;
            }
            assert_eq!(next, h.len(), "{}", pr.name);
            let lo = path
                .columns
                .iter()
                .map(|c| c.0)
                .fold(f32::INFINITY, f32::min);
            let hi = path
                .columns
                .iter()
                .map(|c| c.1)
                .fold(f32::NEG_INFINITY, f32::max);
            let (min, max) = h
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            assert_eq!((lo, hi), (min as f32, max as f32), "{}", pr.name);
            println!(
                "{}: {} points in {} columns over {:.3} m",
                pr.name,
                h.len(),
                cols,
                path.length_m
            );
        }
    }

    /// Every preset's mode spectrum, played as the preset and as a user
    /// scene of the same text: the struck object's modes as the compiler
    /// resolves them (objects from geometry and material included), the
    /// lowest kept one at the frequency the instrument tunes to (the root
    /// note is the MIDI note nearest it; a `fundamental_hz` is met); a
    /// lumped string says plainly that it has no spectrum.
    #[test]
    fn every_preset_shows_its_modes_at_its_tuning() {
        for (i, pr) in presets::PRESETS.iter().enumerate() {
            let (lib, params, r) = preset_report(i);
            lib.load(user(pr.toml));
            lib.prepare(&wanted(&lib), 48_000.0, 2, HOST)
                .unwrap_or_else(|e| panic!("{} as a user scene: {e}", pr.name));
            let u = lib.report();
            assert!(u.user && !r.user);
            assert_eq!(u.spectrum, r.spectrum, "{}", pr.name);
            assert_eq!(u.no_spectrum, r.no_spectrum, "{}", pr.name);
            let played = scene_for(
                &presets::scene(i).unwrap(),
                &InstrumentParams {
                    scene: params,
                    play: Default::default(),
                },
            );
            let ci = played.object_index(&played.contact.object).unwrap();
            if matches!(played.object[ci], ObjectSpec::String(_)) {
                assert!(r.spectrum.is_empty(), "{}", pr.name);
                assert!(
                    matches!(&r.no_spectrum, Some(NoSpectrum::NoModes(w)) if w.contains("lumped string")),
                    "{}: {:?}",
                    pr.name,
                    r.no_spectrum
                );
                println!("{:24} {:?}", pr.name, r.no_spectrum);
                continue;
            }
            assert_eq!(r.no_spectrum, None, "{}", pr.name);
            let own: Vec<&SpectrumLine> = r.spectrum.iter().filter(|m| !m.mallet).collect();
            let lowest = own
                .iter()
                .filter(|m| m.pruned.is_none())
                .map(|m| m.freq_hz)
                .min_by(f64::total_cmp)
                .unwrap_or_else(|| panic!("{}: no mode kept: {:?}", pr.name, r.spectrum));
            let tuned = crate::instrument::lowest_frequency_hz(&played).unwrap();
            assert!(
                (lowest / tuned - 1.0).abs() < 1e-9,
                "{}: lowest kept mode {lowest} Hz, tuned to {tuned} Hz",
                pr.name
            );
            // the root note is the named pitch's (`[play] pitch_hz`: a
            // chime's strike note, a bell's prime), else the lowest mode's
            let named = played.play.as_ref().and_then(|p| p.pitch_hz);
            let pitch = named.unwrap_or(lowest);
            let note = 69.0 + 12.0 * (pitch / 440.0).log2();
            assert!(
                (note - r.root_note).abs() <= 0.5,
                "{}: pitch {pitch} Hz (note {note:.2}; lowest kept mode {lowest} Hz), root note {}",
                pr.name,
                r.root_note
            );
            let fundamental = pr
                .toml
                .lines()
                .find_map(|l| l.trim().strip_prefix("fundamental_hz = "))
                .map(|v| v.trim().parse::<f64>().unwrap());
            if let Some(f) = fundamental {
                assert!(
                    (lowest / f - 1.0).abs() < 1e-9,
                    "{}: lowest kept mode {lowest} Hz, fundamental_hz {f}",
                    pr.name
                );
            }
            println!(
                "{:24} {:3} modes ({:3} kept, {} of the mallet), lowest kept {lowest:8.2} Hz, root note {}",
                pr.name,
                r.spectrum.len(),
                r.spectrum.iter().filter(|m| m.pruned.is_none()).count(),
                r.spectrum.len() - own.len(),
                r.root_note
            );
        }
    }

    #[test]
    fn a_bad_user_scene_keeps_the_last_good_one() {
        let lib = SceneLibrary::default();
        lib.load(user(THREE_MODES));
        let good = lib.active();
        lib.prepare(&wanted(&lib), 48_000.0, 1, HOST).unwrap();
        let bad = THREE_MODES.replace("t60_s = 0.5", "t60_s = -1.0");
        lib.load(user(&bad));
        let e = lib.prepare(&wanted(&lib), 48_000.0, 2, HOST).unwrap_err();
        assert!(
            e.contains("object[0].mode[1].t60_s: must be > 0, got -1"),
            "{e}"
        );
        assert_eq!(lib.report().error.as_deref(), Some(e.as_str()));
        // what plays (and is saved) is still the good text, under a new generation
        assert_eq!(lib.playing().unwrap().text, THREE_MODES);
        assert_eq!(lib.to_saved().unwrap().text, THREE_MODES);
        assert!(lib.active() != good && lib.active() != 0);
        assert!(lib.prepare(&wanted(&lib), 48_000.0, 3, HOST).is_ok());
    }

    /// A scene of several contacts (docs/design.md, "Several contacts")
    /// plays as a kit, its summary says so; one that names an unknown
    /// point is refused with the field named and the last good scene plays
    /// on.
    #[test]
    fn a_scene_of_several_contacts_plays_as_a_kit_and_a_bad_one_is_refused() {
        let lib = SceneLibrary::default();
        lib.load(user(THREE_MODES));
        lib.prepare(&wanted(&lib), 48_000.0, 1, HOST).unwrap();
        let two = include_str!("../../presets/marimba-two-mallets.toml");
        lib.load(user(two));
        let p = lib.prepare(&wanted(&lib), 48_000.0, 2, HOST).unwrap().0;
        let kit = p.kit.as_ref().expect("a kit");
        assert_eq!((kit.mallets, kit.sc.contacts()), (2, 2));
        let r = lib.report();
        assert!(r.error.is_none(), "{r:?}");
        assert!(
            r.summary.contains("several contacts, played as a kit")
                && r.summary.contains("2 mallets")
                && r.summary.contains("4 phases"),
            "{}",
            r.summary
        );
        assert_eq!(lib.playing().unwrap().text, two);
        let bad = two.replace("point = \"left\"", "point = \"nowhere\"");
        lib.load(user(&bad));
        let e = lib.prepare(&wanted(&lib), 48_000.0, 3, HOST).unwrap_err();
        assert!(e.contains("striker[0].point"), "{e}");
        assert!(e.contains("nowhere"), "{e}");
        assert_eq!(lib.playing().unwrap().text, two);
    }

    #[test]
    fn a_saved_scene_that_no_longer_validates_plays_the_preset_and_keeps_its_text() {
        let lib = SceneLibrary::default();
        lib.restore(Some(user("not = [toml")));
        let e = lib.prepare(&wanted(&lib), 48_000.0, 1, HOST).unwrap_err();
        assert!(e.contains("mine"), "{e}");
        assert_eq!(lib.active(), 0, "the preset plays");
        assert_eq!(
            lib.to_saved().unwrap().text,
            "not = [toml",
            "the text is kept"
        );
        let p = lib.prepare(&wanted(&lib), 48_000.0, 2, HOST).unwrap().0;
        assert_eq!(p.params.user_scene, 0);
        assert!(!lib.report().user);
    }
}
