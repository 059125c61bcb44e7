//! The studio application: the document and its history, the worker, playback, and the
//! frame loop that ties the panels together. Panels live in their own modules as further
//! `impl StudioApp` blocks; this file holds the state and everything that is not drawing.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use egui::{Key, KeyboardShortcut, Modifiers};

use super::dialogs::{Dialogs, Purpose};
use super::messages::Messages;
use super::project::{self, History, Project};
use super::timeline::{Action, TimelineState, MIN_SECONDS};
use super::transport::Playback;
use super::viewport::Viewport;
use super::worker::{ModelInfo, Reply, SeedMap, Take, Worker};
use crate::synth::export::{segments_in_range, ExportFormat};
use crate::synth::{GenerateOptions, InitPose, Segment};

/// Edits regenerate after this pause (seconds).
pub const DEBOUNCE: f64 = 0.3;

/// How the studio starts.
#[derive(Clone, Debug)]
pub struct StudioOptions {
    pub model_dir: PathBuf,
    /// Where shipped models are looked for (`<root>/*/model.json`).
    pub models_root: PathBuf,
    /// Autosave file (None: no autosave).
    pub autosave: Option<PathBuf>,
    /// Start from the autosave when there is a valid one.
    pub restore_autosave: bool,
}

impl Default for StudioOptions {
    fn default() -> Self {
        Self {
            model_dir: PathBuf::from("models/h36m"),
            models_root: PathBuf::from("models"),
            autosave: Some(project::default_autosave_path()),
            restore_autosave: true,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportRange {
    Whole,
    Selection,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InitTab {
    Class,
    Seed,
    File,
}

/// Text fields of the UI (typed paths and the like).
pub struct Fields {
    pub model_path: String,
    pub project_path: String,
    pub export_path: String,
    pub init_path: String,
    pub init_frame: usize,
    pub new_class: usize,
}

pub struct StudioApp {
    pub(super) doc: Project,
    pub(super) history: History,
    /// An edit (e.g. a drag) is under way and has been recorded in the history.
    pub(super) edit_open: bool,
    pub(super) worker: Worker,
    pub(super) model: Option<Arc<ModelInfo>>,
    pub(super) model_loading: Option<PathBuf>,
    pub(super) map: Option<Arc<SeedMap>>,
    pub(super) map_error: Option<String>,
    pub(super) take: Option<Arc<Take>>,
    /// The take before the current one, for comparison.
    pub(super) previous: Option<Arc<Take>>,
    pub(super) compare: bool,
    /// Id and progress of the generation under way.
    pub(super) pending: Option<(u64, f32)>,
    /// Options of the last generation asked for.
    pub(super) requested: Option<GenerateOptions>,
    pub(super) regen_at: Option<f64>,
    pub(super) auto_regen: bool,
    pub(super) playback: Playback,
    pub(super) viewport: Viewport,
    pub(super) timeline_state: TimelineState,
    pub(super) selected: Option<usize>,
    pub(super) messages: Messages,
    pub(super) fields: Fields,
    pub(super) init_tab: InitTab,
    pub(super) export_range: ExportRange,
    pub(super) project_path: Option<PathBuf>,
    pub(super) autosave: Option<PathBuf>,
    pub(super) autosaved: Option<Project>,
    pub(super) autosave_at: Option<f64>,
    pub(super) dialogs: Dialogs,
    pub(super) show_map: bool,
    pub(super) show_side: bool,
    pub(super) show_help: bool,
    pub(super) shipped: Vec<PathBuf>,
    pub(super) now: f64,
}

impl StudioApp {
    pub fn new(cc: &eframe::CreationContext<'_>, options: StudioOptions) -> Self {
        Self::with_context(&cc.egui_ctx, options)
    }

    pub fn with_context(ctx: &egui::Context, options: StudioOptions) -> Self {
        let worker = Worker::spawn(ctx.clone());
        let mut messages = Messages::default();
        let mut doc = Project::new(options.model_dir.clone());
        if options.restore_autosave {
            if let Some(path) = options.autosave.as_ref().filter(|p| p.exists()) {
                match Project::load(path) {
                    Ok(p) => {
                        doc = p;
                        messages.info(format!("Restored the autosaved project ({})", path.display()));
                    }
                    Err(e) => messages.error(format!("The autosave could not be restored: {e:#}")),
                }
            }
        }
        worker.load_model(doc.model.clone());
        let fields = Fields {
            model_path: doc.model.display().to_string(),
            project_path: "project.glocal.json".into(),
            export_path: "take.bvh".into(),
            init_path: String::new(),
            init_frame: 0,
            new_class: 0,
        };
        Self {
            model_loading: Some(doc.model.clone()),
            doc,
            history: History::default(),
            edit_open: false,
            worker,
            model: None,
            map: None,
            map_error: None,
            take: None,
            previous: None,
            compare: false,
            pending: None,
            requested: None,
            regen_at: None,
            auto_regen: true,
            playback: Playback::default(),
            viewport: Viewport::new(),
            timeline_state: TimelineState::default(),
            selected: None,
            messages,
            fields,
            init_tab: InitTab::Seed,
            export_range: ExportRange::Whole,
            project_path: None,
            autosave: options.autosave,
            autosaved: None,
            autosave_at: None,
            dialogs: Dialogs::default(),
            show_map: true,
            show_side: true,
            show_help: false,
            shipped: scan_models(&options.models_root),
            now: 0.0,
        }
    }

    // ---- read access (for tests and panels) ----

    pub fn project(&self) -> &Project {
        &self.doc
    }

    pub fn take(&self) -> Option<&Take> {
        self.take.as_deref()
    }

    pub fn model_info(&self) -> Option<&ModelInfo> {
        self.model.as_deref()
    }

    pub fn seed_map(&self) -> Option<&SeedMap> {
        self.map.as_deref()
    }

    pub fn frame(&self) -> usize {
        self.playback.frame()
    }

    pub fn selection(&self) -> Option<(usize, usize)> {
        self.playback.selection
    }

    pub fn messages(&self) -> &Messages {
        &self.messages
    }

    /// Whether the worker still has something to do for the UI (loading, generating, or a
    /// regeneration waiting for its pause).
    pub fn is_busy(&self) -> bool {
        self.model_loading.is_some() || self.pending.is_some() || self.regen_at.is_some()
    }

    pub fn fields_mut(&mut self) -> &mut Fields {
        &mut self.fields
    }

    pub fn set_selection(&mut self, selection: Option<(usize, usize)>) {
        self.playback.selection = selection;
    }

    // ---- the document ----

    /// Replaces the document by `f(doc)` as one undoable edit.
    pub fn edit(&mut self, f: impl FnOnce(&mut Project)) {
        let before = self.doc.clone();
        f(&mut self.doc);
        if self.doc.options() != before.options() {
            self.history.record(before);
        }
    }

    pub fn undo(&mut self) {
        if self.history.undo(&mut self.doc) {
            self.clamp_selected();
        } else {
            self.messages.info("Nothing to undo");
        }
    }

    pub fn redo(&mut self) {
        if self.history.redo(&mut self.doc) {
            self.clamp_selected();
        } else {
            self.messages.info("Nothing to redo");
        }
    }

    fn clamp_selected(&mut self) {
        let n = self.doc.timeline.segments.len();
        self.selected = self.selected.filter(|&k| k < n);
    }

    pub fn classes(&self) -> &[String] {
        self.model.as_ref().map_or(&[], |m| m.spec.classes.as_slice())
    }

    /// Adds a segment of the class chosen in the UI after the selected one (or at the end).
    pub fn add_segment(&mut self) {
        let Some(class) = self.classes().get(self.fields.new_class).or(self.classes().first()).cloned() else {
            self.messages.error("Load a model before adding segments");
            return;
        };
        let at = self.selected.map_or(self.doc.timeline.segments.len(), |k| k + 1).min(self.doc.timeline.segments.len());
        self.edit(|d| d.timeline.segments.insert(at, Segment::new(class, 3.0)));
        self.selected = Some(at);
    }

    pub fn delete_segment(&mut self, k: usize) {
        if k < self.doc.timeline.segments.len() {
            self.edit(|d| {
                d.timeline.segments.remove(k);
            });
            self.clamp_selected();
        }
    }

    pub fn set_segment_class(&mut self, k: usize, class: &str) {
        if k < self.doc.timeline.segments.len() {
            self.edit(|d| d.timeline.segments[k].class = class.to_string());
        }
    }

    /// Applies what the timeline widget reports.
    pub(super) fn apply_timeline(&mut self, actions: Vec<Action>) {
        let frames = self.take.as_ref().map_or(0, |t| t.motion.frames());
        for a in actions {
            match a {
                Action::Select(k) => self.selected = k,
                Action::BeginEdit => {
                    self.history.record(self.doc.clone());
                    self.edit_open = true;
                }
                Action::Resize { index, seconds } => {
                    if let Some(s) = self.doc.timeline.segments.get_mut(index) {
                        s.seconds = seconds.max(MIN_SECONDS);
                    }
                }
                Action::Move { from, to } => {
                    let n = self.doc.timeline.segments.len();
                    if from < n && to < n {
                        let s = self.doc.timeline.segments.remove(from);
                        self.doc.timeline.segments.insert(to, s);
                        self.selected = Some(to);
                    }
                }
                Action::SetClass { index, class } => self.set_segment_class(index, &class),
                Action::Duplicate(k) => {
                    if let Some(s) = self.doc.timeline.segments.get(k).cloned() {
                        self.edit(|d| d.timeline.segments.insert(k + 1, s));
                        self.selected = Some(k + 1);
                    }
                }
                Action::Delete(k) => self.delete_segment(k),
                Action::Seek(f) => {
                    self.playback.playing = false;
                    self.playback.seek(f, frames);
                }
                Action::SetSelection(s) => self.playback.selection = s,
            }
        }
    }

    // ---- files ----

    pub fn load_model(&mut self, dir: PathBuf) {
        self.fields.model_path = dir.display().to_string();
        self.model_loading = Some(dir.clone());
        self.worker.load_model(dir);
    }

    pub fn save_project(&mut self, path: &Path) -> bool {
        match self.doc.save(path) {
            Ok(()) => {
                self.project_path = Some(path.to_path_buf());
                self.fields.project_path = path.display().to_string();
                self.messages.info(format!("Saved {}", path.display()));
                true
            }
            Err(e) => {
                self.messages.error(format!("Could not save the project: {e:#}"));
                false
            }
        }
    }

    /// Opens a project; on any error the current one stays as it is.
    pub fn open_project(&mut self, path: &Path) -> bool {
        match Project::load(path) {
            Ok(p) => {
                let model_changed = p.model != self.doc.model || self.model.is_none();
                self.history.record(self.doc.clone());
                let current_model = self.doc.model.clone();
                self.doc = p;
                self.project_path = Some(path.to_path_buf());
                self.fields.project_path = path.display().to_string();
                self.selected = None;
                if model_changed {
                    // The project's model replaces the current one only once it has loaded.
                    let wanted = std::mem::replace(&mut self.doc.model, current_model);
                    self.load_model(wanted);
                }
                self.messages.info(format!("Opened {}", path.display()));
                true
            }
            Err(e) => {
                self.messages.error(format!("Could not open the project: {e:#}"));
                false
            }
        }
    }

    /// Exports the take (whole or the selected range) on the worker.
    pub fn export_to(&mut self, path: PathBuf) {
        let Some(take) = self.take.clone() else {
            self.messages.error("Nothing to export yet: the take has not been generated");
            return;
        };
        if let Err(e) = ExportFormat::from_path(&path) {
            self.messages.error(format!("Could not export: {e:#}"));
            return;
        }
        let frames = take.motion.frames();
        let (a, b) = match (self.export_range, self.playback.selection) {
            (ExportRange::Selection, Some((a, b))) => (a.min(frames), b.min(frames)),
            (ExportRange::Selection, None) => {
                self.messages.error("No range is selected: shift-drag on the timeline ruler, or export the whole take");
                return;
            }
            (ExportRange::Whole, _) => (0, frames),
        };
        if b <= a {
            self.messages.error("The selected range is empty");
            return;
        }
        let motion = if (a, b) == (0, frames) { take.motion.clone() } else { Arc::new(take.motion.slice(a, b)) };
        self.fields.export_path = path.display().to_string();
        self.worker.export(motion, segments_in_range(&take.segments, a, b), path);
    }

    pub fn use_init_file(&mut self, path: PathBuf, frame: usize) {
        self.fields.init_path = path.display().to_string();
        self.worker.check_init(InitPose::File { path, frame });
    }

    pub(super) fn open_dialog(&mut self, purpose: Purpose, ctx: &egui::Context) {
        let suggested = match purpose {
            Purpose::SaveProject => Some(PathBuf::from(&self.fields.project_path)),
            Purpose::Export => Some(PathBuf::from(&self.fields.export_path)),
            _ => None,
        };
        self.dialogs.open(purpose, ctx, suggested);
    }

    fn handle_dialogs(&mut self) {
        for (purpose, path) in self.dialogs.poll() {
            let Some(path) = path else { continue };
            match purpose {
                Purpose::OpenModel => self.load_model(path),
                Purpose::OpenProject => {
                    self.open_project(&path);
                }
                Purpose::SaveProject => {
                    self.save_project(&path);
                }
                Purpose::Export => self.export_to(path),
                Purpose::InitFile => {
                    let frame = self.fields.init_frame;
                    self.use_init_file(path, frame);
                }
            }
        }
    }

    // ---- the worker ----

    fn handle_replies(&mut self) {
        for reply in self.worker.poll() {
            match reply {
                Reply::ModelLoaded(info) => {
                    let first = self.model.is_none();
                    self.model_loading = None;
                    self.map = None;
                    self.map_error = None;
                    self.doc.model = info.dir.clone();
                    self.fields.model_path = info.dir.display().to_string();
                    if self.doc.timeline.segments.is_empty() {
                        self.doc.timeline = Project::default_timeline(&info.spec.classes);
                    }
                    if !first {
                        self.messages.info(format!("Loaded model {} ({})", info.dir.display(), info.spec.dataset));
                    }
                    self.fields.new_class = self.fields.new_class.min(info.spec.classes.len().saturating_sub(1));
                    self.model = Some(info);
                    self.previous = None;
                    self.requested = None;
                    self.regen_at = Some(self.now);
                }
                Reply::ModelFailed { dir, error } => {
                    self.model_loading = None;
                    let keep = if self.model.is_some() { " The current model stays loaded." } else { "" };
                    self.messages.error(format!("Could not load the model {}: {error}.{keep}", dir.display()));
                    if let Some(m) = &self.model {
                        self.fields.model_path = m.dir.display().to_string();
                    }
                }
                Reply::Map(map) => {
                    if self.model.as_ref().is_some_and(|m| m.dir == map.model_dir) {
                        self.map = Some(map);
                    }
                }
                Reply::MapFailed(e) => self.map_error = Some(e),
                Reply::Progress { id, fraction } => {
                    if let Some((pid, p)) = self.pending.as_mut() {
                        if *pid == id {
                            *p = fraction;
                        }
                    }
                }
                Reply::Generated(take) => {
                    if self.pending.is_some_and(|(id, _)| id == take.id) {
                        self.pending = None;
                    }
                    let frames = take.motion.frames();
                    if let Some(old) = self.take.replace(take) {
                        self.previous = Some(old);
                    }
                    self.playback.clamp(frames);
                }
                Reply::GenerateFailed { id, error, cancelled } => {
                    if self.pending.is_some_and(|(p, _)| p == id) {
                        self.pending = None;
                    }
                    if !cancelled {
                        self.messages.error(format!("Generation failed: {error}"));
                    }
                }
                Reply::Path { id, path } => {
                    if let Some(t) = self.take.as_mut().filter(|t| t.id == id) {
                        if let Some(t) = Arc::get_mut(t) {
                            t.path = path;
                        } else {
                            let mut copy = Take { path, ..clone_take(t) };
                            copy.id = id;
                            *t = Arc::new(copy);
                        }
                    }
                }
                Reply::InitOk(init) => {
                    let name = match &init {
                        InitPose::File { path, frame } => format!("{} from frame {frame}", path.display()),
                        _ => String::new(),
                    };
                    self.edit(|d| d.init = init);
                    self.init_tab = InitTab::File;
                    self.messages.info(format!("Initial pose: {name}"));
                }
                Reply::InitFailed { error, .. } => {
                    self.messages.error(format!("That file cannot start a take: {error}"));
                }
                Reply::Exported(path) => self.messages.info(format!("Exported {}", path.display())),
                Reply::ExportFailed { path, error } => self.messages.error(format!("Could not export {}: {error}", path.display())),
            }
        }
    }

    /// Asks for a new take when the options changed and the pause is over.
    fn schedule(&mut self, ctx: &egui::Context) {
        let Some(model) = &self.model else { return };
        if model.dir != self.doc.model {
            return;
        }
        let options = self.doc.options();
        if self.requested.as_ref() != Some(&options) && self.auto_regen && self.regen_at.is_none() {
            self.regen_at = Some(self.now + DEBOUNCE);
        }
        if let Some(at) = self.regen_at {
            if self.now >= at {
                self.regen_at = None;
                if self.requested.as_ref() != Some(&options) || self.take.is_none() {
                    self.regenerate();
                }
            } else {
                ctx.request_repaint_after(std::time::Duration::from_secs_f64(at - self.now));
            }
        }
    }

    /// Generates now with the current options.
    pub fn regenerate(&mut self) {
        if self.model.is_none() {
            return;
        }
        let options = self.doc.options();
        let id = self.worker.generate(options.clone());
        self.requested = Some(options);
        self.pending = Some((id, 0.0));
        self.regen_at = None;
    }

    pub fn cancel(&mut self) {
        self.worker.cancel();
        self.pending = None;
        self.regen_at = None;
    }

    fn autosave_tick(&mut self, ctx: &egui::Context) {
        let Some(path) = self.autosave.clone() else { return };
        if self.model.is_none() || self.autosaved.as_ref() == Some(&self.doc) {
            self.autosave_at = None;
            return;
        }
        let at = *self.autosave_at.get_or_insert(self.now + DEBOUNCE);
        if self.now >= at {
            self.autosave_at = None;
            if let Err(e) = project::autosave(&self.doc, &path) {
                self.messages.error(format!("Autosave failed: {e:#}"));
                self.autosave = None;
            }
            self.autosaved = Some(self.doc.clone());
        } else {
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(at - self.now));
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let redo = KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
        let undo = KeyboardShortcut::new(Modifiers::COMMAND, Key::Z);
        let redo_y = KeyboardShortcut::new(Modifiers::COMMAND, Key::Y);
        let save = KeyboardShortcut::new(Modifiers::COMMAND, Key::S);
        let (r, u, s) = ctx.input_mut(|i| {
            let r = i.consume_shortcut(&redo) || i.consume_shortcut(&redo_y);
            let u = i.consume_shortcut(&undo);
            let s = i.consume_shortcut(&save);
            (r, u, s)
        });
        if r {
            self.redo();
        } else if u {
            self.undo();
        }
        if s {
            self.save_shortcut(ctx);
        }
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let frames = self.take.as_ref().map_or(0, |t| t.motion.frames());
        let (space, left, right, home, end, del) = ctx.input_mut(|i| {
            (
                i.consume_key(Modifiers::NONE, Key::Space),
                i.consume_key(Modifiers::NONE, Key::ArrowLeft),
                i.consume_key(Modifiers::NONE, Key::ArrowRight),
                i.consume_key(Modifiers::NONE, Key::Home),
                i.consume_key(Modifiers::NONE, Key::End),
                i.consume_key(Modifiers::NONE, Key::Delete),
            )
        });
        if space {
            self.playback.toggle(frames, &self.doc.playback);
        }
        if left {
            self.playback.step(-1, frames);
        }
        if right {
            self.playback.step(1, frames);
        }
        if home {
            self.playback.seek(0, frames);
        }
        if end {
            self.playback.seek(frames.saturating_sub(1), frames);
        }
        if del {
            if let Some(k) = self.selected {
                self.delete_segment(k);
            }
        }
    }

    pub(super) fn save_shortcut(&mut self, ctx: &egui::Context) {
        match self.project_path.clone() {
            Some(p) => {
                self.save_project(&p);
            }
            None if !self.fields.project_path.trim().is_empty() => {
                let p = PathBuf::from(self.fields.project_path.trim());
                self.save_project(&p);
            }
            None => self.open_dialog(Purpose::SaveProject, ctx),
        }
    }

    /// Closes the open edit once the pointer is released, and records edits made by
    /// ordinary widgets this frame as one undo step each.
    fn finish_edits(&mut self, ctx: &egui::Context, before: Project) {
        if self.doc.options() != before.options() && !self.edit_open {
            self.history.record(before);
            self.edit_open = true;
        }
        if ctx.input(|i| !i.pointer.any_down()) {
            self.edit_open = false;
        }
    }
}

/// The panels' usual frame without its fill: the window is cleared to the same colour
/// ([`StudioApp::clear_color`]), which is nearly free. On a software rasteriser (llvmpipe) a
/// frame's cost is mostly egui's per-pixel shading, and filling the panels again under their
/// widgets was about a third of the studio's frame time.
fn unfilled_panel_frame(style: &egui::Style) -> egui::Frame {
    egui::Frame::side_top_panel(style).fill(egui::Color32::TRANSPARENT)
}

/// Runs `add` in a `Ui` that knows it is on the panels' background (the clear colour), for
/// what blends into it (a scroll area's edge fades), without painting it.
fn on_panel_background<R>(ui: &mut egui::Ui, add: impl FnOnce(&mut egui::Ui) -> R) -> R {
    let background = egui::Frame::NONE.fill(ui.visuals().panel_fill);
    ui.scope_builder(egui::UiBuilder::new().ui_stack_info(egui::UiStackInfo::default().with_frame(background)), add).inner
}

impl eframe::App for StudioApp {
    /// The panels' background (see [`unfilled_panel_frame`]).
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.now = ctx.input(|i| i.time);
        self.messages.tick(&ctx);
        self.handle_replies();
        self.handle_dialogs();
        self.shortcuts(&ctx);
        let before = self.doc.clone();

        let frame = unfilled_panel_frame(ui.style());
        egui::Panel::top("menu_bar").frame(frame).show(ui, |ui| self.menu_bar(ui));
        egui::Panel::bottom("transport").frame(frame).resizable(false).show(ui, |ui| self.bottom_panel(ui));
        let mut show_side = self.show_side;
        egui::Panel::left("side").frame(frame).resizable(true).default_size(300.0).min_size(240.0).show_collapsible(ui, &mut show_side, |ui| {
            on_panel_background(ui, |ui| egui::ScrollArea::vertical().show(ui, |ui| self.side_panel(ui)));
        });
        self.show_side = show_side;
        let mut show_map = self.show_map;
        egui::Panel::right("map").frame(frame).resizable(true).default_size(330.0).min_size(220.0).show_collapsible(ui, &mut show_map, |ui| self.map_panel(ui));
        self.show_map = show_map;
        egui::CentralPanel::no_frame().show(ui, |ui| self.central(ui));

        self.finish_edits(&ctx, before);
        self.schedule(&ctx);
        self.autosave_tick(&ctx);
        let frames = self.take.as_ref().map_or(0, |t| t.motion.frames());
        if self.playback.playing {
            let fps = self.take.as_ref().map_or(25.0, |t| t.motion.fps);
            let dt = ctx.input(|i| f64::from(i.stable_dt.min(0.1)));
            self.playback.advance(dt, fps, frames, &self.doc.playback);
            ctx.request_repaint();
        }
    }
}

/// Model folders under `root` that hold a `model.json`, sorted.
pub fn scan_models(root: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(root)
        .map(|rd| rd.filter_map(|e| e.ok()).map(|e| e.path()).filter(|p| p.join("model.json").is_file()).collect())
        .unwrap_or_default();
    found.sort();
    found
}

fn clone_take(t: &Take) -> Take {
    Take {
        id: t.id,
        motion: t.motion.clone(),
        segments: t.segments.clone(),
        frame_colors: t.frame_colors.clone(),
        block_classes: t.block_classes.clone(),
        path: t.path.clone(),
        options: t.options.clone(),
        millis: t.millis,
    }
}
