//! The editor window (egui through nice-plug-egui): the parameters in named
//! groups, the live view of the voices, the object's mode spectrum, the
//! scene browser and the audition pads (docs/plugin.md, "The editor").
//!
//! Threads: the window runs on the GUI thread, with one helper, the watch
//! thread, while it is open. They talk to the audio thread only through
//! lock-free structures: the host's parameter gestures (begin/set/end), the
//! live ring's consumer end ([`super::live`], held by the watch thread), and
//! the pad queue ([`EditorLink::pads`]). The scene library's mutexes are
//! shared with the worker, never with the audio thread.
//!
//! Repaints: the window is drawn when something it shows changed, and
//! otherwise not (docs/plugin.md, "The editor"). Input, the host's
//! parameter and state changes and egui's own animations ask for a frame
//! by themselves; the watch thread asks for one when the live ring brought
//! frames (a voice sounds), when the worker starts or ends a compile, and
//! when the playing scene's file changed on disk; the folder listing and
//! the file dialog ask when they are done.

mod view;

use super::browser::{self, Folder};
use super::import::{import_recording, Imported};
use super::live::{LiveConsumer, LiveHistory, LiveRing};
use super::params::{ModalContactParams, EDITOR_SIZE};
use super::user_scene::{lock, UserScene};
use crate::instrument::Event;
use crossbeam::queue::ArrayQueue;
use egui::{self, Color32, RichText};
use nice_plug::context::gui::GuiContext;
use nice_plug::editor::dpi::LogicalSize;
use nice_plug::prelude::*;
use nice_plug_egui::{
    create_egui_editor, widgets::ParamSlider, EguiEditor, EguiEditorState, EguiNiceSettings,
    NiceEguiApp, RepaintNotifier,
};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

/// Audition pad strikes waiting for the audio thread (it plays them at the
/// start of its next block, through the same path as MIDI notes).
pub const PAD_QUEUE: usize = 64;

/// What the editor shares with the plugin instance.
pub struct EditorLink {
    /// The parameters (and what is saved with them).
    pub params: Arc<ModalContactParams>,
    /// The live view's ring (the editor holds its consumer while open).
    pub ring: Arc<LiveRing>,
    /// Pad strikes for the audio thread.
    pub pads: Arc<ArrayQueue<Event>>,
    /// The compile worker's handoff: the editor reads its atomics
    /// (compiling or not, the last error) and never its queues.
    pub handoff: Arc<super::worker::Handoff>,
}

/// The built-in scenes the browser shows at once; more scroll.
pub const BUILT_IN_ROWS: usize = 19;

/// The height of one row of the browser's lists \[logical px\].
const ROW_PX: f32 = 23.0;

/// The editor's type (the plugin's `Plugin::Editor`).
pub type ModalEditor = EguiEditor<App>;

/// Build the editor (a new window state sized as saved). \[main-thread\]
pub fn create(link: EditorLink) -> Option<ModalEditor> {
    let (w, h) = link.params.persisted.editor_size.load();
    let state = EguiEditorState::from_size(LogicalSize::new(w as f32, h as f32), 1.0);
    let notifier = RepaintNotifier::new();
    let settings = EguiNiceSettings::new()
        .with_tile("Modal Contact")
        .with_resize_hint(ResizeHint {
            can_resize: true,
            ..ResizeHint::default()
        });
    let app = App::new(link, notifier.clone(), state.clone());
    create_egui_editor(state, notifier, settings, app)
}

/// A listing of the user folder, made on a background thread.
type Listing = Arc<Mutex<Option<(PathBuf, Result<Folder, String>)>>>;

/// How often the watch thread looks (the live view's frame rate at most).
const WATCH_INTERVAL: Duration = Duration::from_millis(16);
/// How often the watch thread looks at the playing scene's file.
const DISK_INTERVAL: Duration = Duration::from_secs(1);

/// The live view's data: the ring's reading end (held while the window is
/// open: the audio thread records only then) and what was read.
#[derive(Default)]
struct Live {
    consumer: Option<LiveConsumer>,
    history: LiveHistory,
}

/// The playing file's modification time when it was loaded, and whether
/// the file changed since.
#[derive(Default)]
struct Disk {
    loaded_mtime: Option<SystemTime>,
    changed: bool,
}

/// What the watch thread shares with the GUI thread (never with the audio
/// thread).
#[derive(Default)]
struct Shared {
    live: Mutex<Live>,
    disk: Mutex<Disk>,
}

/// The running watch thread and its stop flag.
struct Watch {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Watch {
    fn stop(self) {
        self.stop.store(true, Ordering::Release);
        let _ = self.thread.join();
    }
}

/// The editor's state on the GUI thread.
pub struct App {
    link: EditorLink,
    notifier: RepaintNotifier,
    state: Arc<EguiEditorState>,
    gui: Option<GuiContext>,
    shared: Arc<Shared>,
    watch: Option<Watch>,
    listing: Listing,
    listed_at: Option<Instant>,
    folder_text: String,
    picked: Arc<Mutex<Option<PathBuf>>>,
    open_error: Option<String>,
    /// The library's generation and the worker's failure count when the
    /// editor last chose a scene (see [`App::refused`]).
    chosen: (u64, u64),
    /// Pads held down: (key).
    pad_down: Option<u8>,
    /// What the import thread reports (GUI and import threads only).
    import_msg: Arc<Mutex<Option<ImportMsg>>>,
    /// The last import: running, its fit, or why it failed.
    import: Option<ImportView>,
}

/// What the import thread tells the GUI thread.
enum ImportMsg {
    /// The file chosen is being analysed (its name).
    Started(String),
    /// The analysis ended: the scene saved, or why not.
    Done(Result<Imported, String>),
}

/// The import the editor shows (below the mode spectrum).
pub(super) enum ImportView {
    /// Analysing the named file.
    Running(String),
    /// Saved and loaded: its fit.
    Done(Imported),
    /// Refused: why.
    Failed(String),
}

impl App {
    fn new(link: EditorLink, notifier: RepaintNotifier, state: Arc<EguiEditorState>) -> Self {
        Self {
            link,
            notifier,
            state,
            gui: None,
            shared: Arc::default(),
            watch: None,
            listing: Arc::new(Mutex::new(None)),
            listed_at: None,
            folder_text: String::new(),
            picked: Arc::new(Mutex::new(None)),
            open_error: None,
            chosen: (0, 0),
            pad_down: None,
            import_msg: Arc::new(Mutex::new(None)),
            import: None,
        }
    }

    /// Analyse the recording at `wav` (or the one a file dialog picks, when
    /// `None`) on a background thread and save its scene into the user
    /// folder (docs/plugin.md, "Import a recording"); [`Self::take_import`]
    /// loads it when done. The audio thread plays on meanwhile: nothing here
    /// touches it.
    fn start_import(&mut self, wav: Option<PathBuf>) {
        let Some(folder) = self.folder() else {
            self.import = Some(ImportView::Failed(
                "this platform has no user data directory: choose a folder first".into(),
            ));
            return;
        };
        let out = self.import_msg.clone();
        let n = self.notifier.clone();
        let spawned = std::thread::Builder::new()
            .name("modal-contact-import".into())
            .spawn(move || {
                // the native dialog blocks: never on the GUI thread
                let wav = wav.or_else(|| {
                    rfd::FileDialog::new()
                        .add_filter("WAV recording", &["wav", "WAV", "wave"])
                        .pick_file()
                });
                let Some(wav) = wav else { return };
                let name = wav
                    .file_name()
                    .map_or(String::new(), |s| s.to_string_lossy().into_owned());
                *lock(&out) = Some(ImportMsg::Started(name));
                n.request_repaint();
                let r = import_recording(&wav, &folder);
                *lock(&out) = Some(ImportMsg::Done(r));
                n.request_repaint();
            });
        if let Err(e) = spawned {
            self.import = Some(ImportView::Failed(format!("the import cannot start: {e}")));
        }
    }

    /// What the import thread reported since the last frame: a finished
    /// import's scene is listed and loaded (it plays like any user scene).
    fn take_import(&mut self) {
        let msg = lock(&self.import_msg).take();
        match msg {
            None => {}
            Some(ImportMsg::Started(name)) => self.import = Some(ImportView::Running(name)),
            Some(ImportMsg::Done(Ok(a))) => {
                self.relist();
                self.load_file(&a.path);
                self.import = Some(ImportView::Done(a));
            }
            Some(ImportMsg::Done(Err(e))) => self.import = Some(ImportView::Failed(e)),
        }
    }

    /// Remember what was chosen now (a user scene loaded, a preset
    /// clicked, the window opened).
    fn note_choice(&mut self) {
        self.chosen = (
            self.link.params.persisted.library.active(),
            self.link.handoff.failures.load(Ordering::Acquire),
        );
    }

    /// Whether the worker refused the user scene last chosen. The library
    /// then goes back to what plays (the last good user scene under a new
    /// generation, or the preset while the refused text is kept), and that
    /// compile succeeds: neither the report nor the handoff's newest
    /// request holds the error any more, so the editor tells it from the
    /// generation having moved after a failure.
    fn refused(&self) -> bool {
        let lib = &self.link.params.persisted.library;
        let (generation, failures) = self.chosen;
        (lib.active() == 0 && lib.requested().is_some())
            || (lib.active() != generation
                && self.link.handoff.failures.load(Ordering::Acquire) > failures)
    }

    /// Start the watch thread for a window being opened (after stopping a
    /// previous one: nice-plug-egui says when a window opens, not when it
    /// closes, so the thread ends by itself once the window it saw open is
    /// closed).
    fn start_watch(&mut self) {
        if let Some(w) = self.watch.take() {
            w.stop();
        }
        let stop = Arc::new(AtomicBool::new(false));
        let w = Watcher {
            stop: stop.clone(),
            shared: self.shared.clone(),
            ring: self.link.ring.clone(),
            params: self.link.params.clone(),
            handoff: self.link.handoff.clone(),
            state: self.state.clone(),
            notifier: self.notifier.clone(),
        };
        match std::thread::Builder::new()
            .name("modal-contact-editor-watch".into())
            .spawn(move || w.run())
        {
            Ok(thread) => self.watch = Some(Watch { stop, thread }),
            Err(e) => self.open_error = Some(format!("the live view cannot start: {e}")),
        }
    }

    fn folder(&self) -> Option<PathBuf> {
        let saved = lock(&self.link.params.persisted.scene_folder).clone();
        saved.or_else(browser::default_folder)
    }

    /// List the folder on a background thread (validating each file).
    fn relist(&mut self) {
        let Some(dir) = self.folder() else {
            *lock(&self.listing) = Some((
                PathBuf::new(),
                Err("this platform has no user data directory: choose a folder".into()),
            ));
            return;
        };
        self.listed_at = Some(Instant::now());
        let out = self.listing.clone();
        let n = self.notifier.clone();
        std::thread::spawn(move || {
            let r = browser::list_folder(&dir);
            *lock(&out) = Some((dir, r));
            n.request_repaint();
        });
    }

    fn load_file(&mut self, path: &std::path::Path) {
        match UserScene::from_file(path) {
            Ok(s) => {
                *lock(&self.shared.disk) = Disk {
                    loaded_mtime: mtime(path),
                    changed: false,
                };
                self.open_error = None;
                self.link.params.persisted.library.load(s);
                self.note_choice();
            }
            Err(e) => self.open_error = Some(e),
        }
    }

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        let lib = self.link.params.persisted.library.clone();
        let report = lib.report();
        // the newest request: still compiling, or its error, or that of
        // the user scene chosen last if it was refused (the last good scene
        // plays on)
        let h = &self.link.handoff;
        let compiling = h.compiling();
        let error = if compiling {
            None
        } else {
            h.error()
                .or_else(|| self.refused().then(|| h.last_error()).flatten())
                .or_else(|| report.error.clone())
        };
        let changed_on_disk = lock(&self.shared.disk).changed;
        ui.horizontal(|ui| {
            ui.heading("Modal Contact");
            ui.separator();
            let what = if report.user { "user scene" } else { "preset" };
            ui.label(RichText::new(format!("{} ({what})", report.scene)).strong());
            if compiling {
                ui.label(RichText::new("compiling\u{2026}").italics());
            }
            if changed_on_disk && ui.button("File changed on disk: reload").clicked() {
                if let Some(p) = lib.playing().and_then(|s| s.path.clone()) {
                    self.load_file(&p);
                }
            }
        });
        match &error {
            Some(e) => {
                ui.colored_label(Color32::from_rgb(240, 90, 80), format!("Not loaded: {e}"));
            }
            None => {
                ui.label(RichText::new(&report.summary).small());
            }
        }
        // the strike warning for the Polyphony and Lookahead of the moment
        let play = self.link.params.play_params();
        let strike = report.strike_warning(play.polyphony, play.lookahead_s);
        for w in report.warnings.iter().chain(&strike) {
            ui.colored_label(Color32::from_rgb(240, 180, 60), RichText::new(w).small());
        }
    }

    fn browser_panel(&mut self, ui: &mut egui::Ui, setter: &ParamSetter) {
        let params = self.link.params.clone();
        let lib = &params.persisted.library;
        ui.heading("Scenes");
        ui.label("Built in");
        let current = params.scene.value().index();
        let user_active = lib.active() != 0;
        // at most BUILT_IN_ROWS rows tall, scrolled beyond: the user
        // folder below stays in the window at the editor's size
        egui::ScrollArea::vertical()
            .id_salt("built-in")
            .max_height(BUILT_IN_ROWS as f32 * ROW_PX)
            .show(ui, |ui| {
                for (i, p) in crate::presets::PRESETS.iter().enumerate() {
                    let selected = !user_active && i == current;
                    if ui.selectable_label(selected, p.title).clicked() {
                        lib.clear();
                        self.note_choice();
                        setter.begin_set_parameter(&params.scene);
                        setter.set_parameter(
                            &params.scene,
                            super::params::PresetChoice::from_index(i),
                        );
                        setter.end_set_parameter(&params.scene);
                    }
                }
            });
        ui.separator();
        ui.label("User folder");
        if self.listed_at.is_none() {
            self.folder_text = self
                .folder()
                .map(|p| p.display().to_string())
                .unwrap_or_default();
            self.relist();
        }
        ui.horizontal(|ui| {
            let r = ui.text_edit_singleline(&mut self.folder_text);
            if r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                let f = PathBuf::from(self.folder_text.trim());
                *lock(&params.persisted.scene_folder) = Some(f);
                self.relist();
            }
        });
        self.folder_actions(ui);
        let picked = lock(&self.picked).take();
        if let Some(p) = picked {
            self.load_file(&p);
        }
        if let Some(e) = &self.open_error {
            ui.colored_label(Color32::from_rgb(240, 90, 80), e);
        }
        let listing = lock(&self.listing).clone();
        let playing = lib.playing();
        egui::ScrollArea::vertical().id_salt("user-scenes").show(ui, |ui| match listing {
            None => {
                ui.label("listing...");
            }
            Some((_, Err(e))) => {
                ui.colored_label(Color32::from_rgb(240, 90, 80), e);
            }
            Some((_, Ok(Folder::Missing))) => {
                ui.label("This folder does not exist yet: \"Create folder\" makes it.");
            }
            Some((_, Ok(Folder::Listed(entries)))) if entries.is_empty() => {
                ui.label("No .toml scene files here yet (see docs/plugin.md, \"Write your first scene\").");
            }
            Some((_, Ok(Folder::Listed(entries)))) => {
                for e in entries {
                    let selected = playing
                        .as_ref()
                        .is_some_and(|p| p.path.as_deref() == Some(e.path.as_path()));
                    match &e.status {
                        Ok(desc) => {
                            if ui.selectable_label(selected, &e.name).on_hover_text(desc).clicked() {
                                self.load_file(&e.path);
                            }
                        }
                        Err(err) => {
                            ui.label(RichText::new(&e.name).strikethrough());
                            ui.colored_label(Color32::from_rgb(240, 90, 80), RichText::new(err).small());
                        }
                    }
                }
            }
        });
    }

    /// The user folder's buttons: refresh, create, open a file, import a
    /// recording.
    fn folder_actions(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if ui.button("Refresh").clicked() {
                self.relist();
            }
            if ui.button("Create folder").clicked() {
                if let Some(f) = self.folder() {
                    if let Err(e) = std::fs::create_dir_all(&f) {
                        self.open_error = Some(format!("cannot create {}: {e}", f.display()));
                    }
                    self.relist();
                }
            }
            if ui.button("Open file...").clicked() {
                let out = self.picked.clone();
                let start = self.folder();
                let n = self.notifier.clone();
                // the native dialog blocks: never on the GUI thread
                std::thread::spawn(move || {
                    let mut d = rfd::FileDialog::new().add_filter("scene", &["toml"]);
                    if let Some(s) = start.filter(|s| s.is_dir()) {
                        d = d.set_directory(s);
                    }
                    *lock(&out) = d.pick_file();
                    n.request_repaint();
                });
            }
        });
        if ui
            .button("Import recording...")
            .on_hover_text(
                "Analyse a recorded strike (WAV) into a scene of its modes, saved in this folder",
            )
            .clicked()
        {
            self.start_import(None);
        }
    }

    fn params_panel(&self, ui: &mut egui::Ui, setter: &ParamSetter) {
        let p = &*self.link.params;
        egui::ScrollArea::vertical()
            .id_salt("params")
            .show(ui, |ui| {
                group(ui, "Mallet", |ui| {
                    slider(ui, &p.hammer_mass, setter);
                    slider(ui, &p.hardness, setter);
                    slider(ui, &p.contact_damping, setter);
                    toggle(ui, &p.strike_custom, setter);
                    slider(ui, &p.strike_pos, setter);
                });
                group(ui, "Object", |ui| {
                    slider(ui, &p.decay, setter);
                    // off: the scene's own damper plays (its `[play]` table)
                    // and the knob is not used
                    toggle(ui, &p.damper_custom, setter);
                    ui.add_enabled_ui(p.damper_custom.value(), |ui| slider(ui, &p.damper, setter));
                    slider(ui, &p.gravity, setter);
                    slider(ui, &p.drop_height_mm, setter);
                });
                group(ui, "Playing", |ui| {
                    toggle(ui, &p.pitch_tracking, setter);
                    slider(ui, &p.bend_range, setter);
                    slider(ui, &p.polyphony, setter);
                });
                group(ui, "Engine and output", |ui| {
                    slider(ui, &p.switching, setter);
                    slider(ui, &p.gain_db, setter);
                });
            });
    }

    /// The audition pads: one per note, the click's height is the velocity.
    fn pads(&mut self, ui: &mut egui::Ui) {
        let root = self
            .link
            .params
            .persisted
            .library
            .report()
            .root_note
            .round();
        let root = if root.is_finite() && root > 0.0 {
            root as i32
        } else {
            60
        };
        ui.horizontal(|ui| {
            ui.label("Audition (click height = velocity):");
        });
        const PADS: [(i32, &str); 5] = [
            (-12, "-1 oct"),
            (0, "root"),
            (7, "+5th"),
            (12, "+1 oct"),
            (24, "+2 oct"),
        ];
        let gap = ui.spacing().item_spacing.x;
        let w = ((ui.available_width() - gap * (PADS.len() as f32 - 1.0)) / PADS.len() as f32)
            .max(30.0);
        ui.horizontal(|ui| {
            for (dk, label) in PADS {
                let key = (root + dk).clamp(0, 127) as u8;
                let size = egui::vec2(w, 64.0);
                let (resp, painter) = ui.allocate_painter(size, egui::Sense::click_and_drag());
                let r = resp.rect;
                let held = self.pad_down == Some(key);
                painter.rect_filled(
                    r,
                    6.0,
                    if held {
                        Color32::from_rgb(230, 160, 60)
                    } else {
                        Color32::from_gray(60)
                    },
                );
                painter.text(
                    r.center_top() + egui::vec2(0.0, 12.0),
                    egui::Align2::CENTER_CENTER,
                    format!("{} ({label})", view::note_name(key)),
                    egui::FontId::proportional(12.0),
                    Color32::WHITE,
                );
                if resp.is_pointer_button_down_on() && self.pad_down.is_none() {
                    if let Some(pos) = resp.interact_pointer_pos() {
                        let vel: f32 = (1.0 - (pos.y - r.top()) / r.height()).clamp(0.05, 1.0);
                        self.strike(key, vel as f64);
                    }
                }
            }
        });
        if self.pad_down.is_some() && !ui.input(|i| i.pointer.any_down()) {
            if let Some(key) = self.pad_down.take() {
                let _ = self.link.pads.push(Event::NoteOff { key });
            }
        }
    }

    fn strike(&mut self, key: u8, velocity_norm: f64) {
        if self
            .link
            .pads
            .push(Event::NoteOn { key, velocity_norm })
            .is_ok()
        {
            self.pad_down = Some(key);
        }
    }
}

fn mtime(path: &std::path::Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

fn group(ui: &mut egui::Ui, title: &str, body: impl FnOnce(&mut egui::Ui)) {
    egui::CollapsingHeader::new(RichText::new(title).strong())
        .default_open(true)
        .show(ui, body);
}

/// A labelled slider with the host's gestures (begin on press, set while
/// dragging, end on release) and the value with its unit.
fn slider<P: Param>(ui: &mut egui::Ui, p: &P, setter: &ParamSetter) {
    ui.label(p.name());
    ui.add(ParamSlider::for_param(p, setter).with_width(160.0));
}

/// A check box for a switch, with one complete gesture per click.
fn toggle(ui: &mut egui::Ui, p: &BoolParam, setter: &ParamSetter) {
    let mut v = p.value();
    if ui.checkbox(&mut v, p.name()).changed() {
        setter.begin_set_parameter(p);
        setter.set_parameter(p, v);
        setter.end_set_parameter(p);
    }
}

impl NiceEguiApp for App {
    fn build(
        &mut self,
        _egui_ctx: egui::Context,
        gui: GuiContext,
        _frame: &mut nice_plug_egui::Frame,
    ) -> Result<(), nice_plug_egui::baseview::HandlerError> {
        self.gui = Some(gui);
        self.note_choice();
        // the watch thread holds the ring's reading end while the window is
        // open, which switches the audio thread's recording on
        self.start_watch();
        Ok(())
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut nice_plug_egui::Frame) {
        let Some(gui) = self.gui.clone() else {
            return;
        };
        let setter = gui.param_setter();
        // a recording dropped on the window, where the windowing layer
        // passes drops on to egui
        let dropped = ui.ctx().input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .find(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("wav")))
        });
        if dropped.is_some() {
            self.start_import(dropped);
        }
        self.take_import();
        egui::Panel::top("top").show(ui, |ui| self.top_bar(ui));
        egui::Panel::left("browser")
            .resizable(true)
            .default_size(240.0)
            .show(ui, |ui| self.browser_panel(ui, &setter));
        egui::Panel::right("params")
            .resizable(true)
            .default_size(230.0)
            .show(ui, |ui| self.params_panel(ui, &setter));
        egui::Panel::bottom("pads").show(ui, |ui| self.pads(ui));
        egui::CentralPanel::default().show(ui, |ui| {
            let rate = self.link.ring.rate_hz();
            let report = self.link.params.persisted.library.report();
            view::live_view(
                ui,
                &lock(&self.shared.live).history,
                rate,
                self.link.ring.dropped(),
            );
            view::spectrum(ui, &report);
            view::path_view(ui, &report, &lock(&self.shared.live).history);
            if let Some(im) = &self.import {
                if view::import_view(ui, im) {
                    self.import = None;
                }
            }
        });
        // no repaint asked here: see the module doc
    }

    fn resized(&mut self, size: nice_plug_egui::baseview::WindowSize) {
        let l = size.logical;
        let w = (l.width.round() as u32).max(200);
        let h = (l.height.round() as u32).max(150);
        self.link.params.persisted.editor_size.store((w, h));
    }

    fn editor_closed(&mut self) {
        // the watch thread gives the ring's reading end back, which
        // switches the recording off
        if let Some(w) = self.watch.take() {
            w.stop();
        }
        self.gui = None;
    }
}

impl Drop for App {
    fn drop(&mut self) {
        if let Some(w) = self.watch.take() {
            w.stop();
        }
    }
}

/// The watch thread's view of the plugin (see the module doc).
struct Watcher {
    stop: Arc<AtomicBool>,
    shared: Arc<Shared>,
    ring: Arc<LiveRing>,
    params: Arc<ModalContactParams>,
    handoff: Arc<super::worker::Handoff>,
    state: Arc<EguiEditorState>,
    notifier: RepaintNotifier,
}

impl Watcher {
    /// Look every [`WATCH_INTERVAL`] until stopped or until the window,
    /// once seen open, is closed; ask for a repaint when something shown
    /// changed. \[watch thread\]
    fn run(self) {
        let mut seen_open = false;
        let mut compile = None;
        let mut disk_at: Option<Instant> = None;
        while !self.stop.load(Ordering::Acquire) {
            let open = self.state.is_open();
            if !open && seen_open {
                break;
            }
            seen_open |= open;
            let mut repaint = false;
            if open {
                let mut live = lock(&self.shared.live);
                let Live { consumer, history } = &mut *live;
                if consumer.is_none() {
                    *consumer = self.ring.consumer();
                    *history = LiveHistory::default();
                }
                if let Some(c) = consumer.as_mut() {
                    repaint |= history.drain(c) > 0;
                }
            }
            // the worker started or ended a compile (its report changed)
            let h = &self.handoff;
            let now = (
                h.compiling(),
                h.compiles.load(Ordering::Acquire),
                h.failures.load(Ordering::Acquire),
                self.params.persisted.library.active(),
            );
            repaint |= compile.replace(now) != Some(now);
            if disk_at.is_none_or(|t| t.elapsed() >= DISK_INTERVAL) {
                disk_at = Some(Instant::now());
                repaint |= self.check_disk();
            }
            if repaint {
                self.notifier.request_repaint();
            }
            std::thread::sleep(WATCH_INTERVAL);
        }
        // giving the reading end back switches the recording off
        lock(&self.shared.live).consumer = None;
    }

    /// Whether the playing scene's file changed on disk since it was
    /// loaded (offered for reload, never swapped silently); true when that
    /// answer changed.
    fn check_disk(&self) -> bool {
        let playing = self.params.persisted.library.playing();
        let mut disk = lock(&self.shared.disk);
        let was = disk.changed;
        match playing.as_ref().and_then(|p| Some((p, p.path.as_ref()?))) {
            None => disk.changed = false,
            Some((playing, path)) => {
                let now = mtime(path);
                if disk.loaded_mtime.is_none() || now != disk.loaded_mtime {
                    // (a project opened with this scene: its text is
                    // compared once)
                    disk.loaded_mtime = now;
                    disk.changed = std::fs::read_to_string(path).is_ok_and(|t| t != playing.text);
                }
            }
        }
        disk.changed != was
    }
}

/// The default size, for the standalone's window and the docs.
pub const DEFAULT_SIZE: (u32, u32) = EDITOR_SIZE;
