//! The studio application: its parts (the editing state in `editing`, the engine in
//! `engine`, the panels' state in `panels`, what is kept between runs in `storage`) and the
//! frame loop that ties the panels together. What the app does lives in further
//! `impl StudioApp` blocks: edits in `edits`, files in `files`, the worker's side in
//! `generation`, and each panel in its own module.

use std::path::{Path, PathBuf};

use super::dialogs;
use super::editing::Editing;
use super::engine::Engine;
use super::messages::{first_line, Level, Messages, Topic};
use super::panels::{Fields, Panels};
use super::project::{self, Project, StudioState};
use super::storage::{broken_autosave_message, Storage};
use super::transport::Playback;
use super::viewport::Viewport;
use super::worker::{ModelInfo, SeedMap, Take, Worker};
use crate::synth::class_map::ClassMap;
use crate::synth::export::ExportOptions;

/// How the studio starts.
#[derive(Clone, Debug)]
pub struct StudioOptions {
    pub model_dir: PathBuf,
    /// Folders where shipped models are looked for (`<root>/*/model.json`), in order.
    pub model_roots: Vec<PathBuf>,
    /// Autosave file (None: no autosave, and nothing remembered between runs).
    pub autosave: Option<PathBuf>,
    /// Start from the autosave when there is a valid one.
    pub restore_autosave: bool,
    /// Try the system's file dialogs (false: always the in-app typed-path dialog).
    pub system_dialogs: bool,
}

impl Default for StudioOptions {
    /// The shipped models wherever they are found ([`crate::model::model_roots`]), opening on
    /// the model of everything (every activity of the four datasets, with styles).
    fn default() -> Self {
        let model_roots = crate::model::model_roots();
        let model_dir = crate::model::shipped_model("all");
        Self { model_dir, model_roots, autosave: Some(project::default_autosave_path()), restore_autosave: true, system_dialogs: dialogs::system_dialog_available() }
    }
}

/// The studio: the editing state, the engine, the panels' state and where things are kept;
/// playback, the viewport and the message log beside them.
pub struct StudioApp {
    pub(super) editing: Editing,
    pub(super) engine: Engine,
    pub(super) panels: Panels,
    pub(super) storage: Storage,
    pub(super) playback: Playback,
    pub(super) viewport: Viewport,
    pub(super) messages: Messages,
    /// The time of the frame being drawn (egui's clock, seconds).
    pub(super) now: f64,
}

impl StudioApp {
    pub fn new(cc: &eframe::CreationContext<'_>, options: StudioOptions) -> Self {
        Self::with_context(&cc.egui_ctx, options)
    }

    pub fn with_context(ctx: &egui::Context, options: StudioOptions) -> Self {
        let mut messages = Messages::default();
        let (doc, restored) = restore_autosave(&options, &mut messages);
        let state_path = options.autosave.as_deref().map(StudioState::path_beside);
        let state = state_path.as_deref().map(StudioState::load).unwrap_or_default();
        let shipped = scan_models(&options.model_roots);
        if shipped.is_empty() {
            let looked: Vec<String> = options.model_roots.iter().map(|r| project::shown_path(r)).collect();
            messages.set(Topic::Model, Level::Error, format!("No shipped models found; looked in {}. Open a model folder with File > Open model folder…", looked.join(", ")));
        }
        let work = project::default_work_folder();
        let fields = Fields {
            model_path: doc.model.display().to_string(),
            project_path: state.project_path.as_ref().map_or_else(|| work.join("project.glocal.json"), Clone::clone).display().to_string(),
            export_path: state.export_path.clone().unwrap_or_else(|| work.join("take.bvh")).display().to_string(),
            export_rig: state.export_rig.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
            init_path: String::new(),
            init_frame: 0,
            new_class: 0,
            seed_index: 0,
            key_seed: 0,
            key_path: String::new(),
            key_frame: 0,
        };
        let saved = if restored { state.project_path.as_deref().and_then(|p| Project::load(p).ok()) } else { Some(doc.clone()) };
        Self {
            engine: Engine::new(Worker::spawn(ctx.clone()), doc.model.clone()),
            panels: Panels::new(fields, &doc.options.init, options.system_dialogs),
            editing: Editing::new(doc, saved, state.project_path),
            storage: Storage { autosave: options.autosave, autosaved: None, autosave_at: None, state_path, class_table: state.class_table, shipped, model_roots: options.model_roots },
            playback: Playback::default(),
            viewport: Viewport::new(),
            messages,
            now: 0.0,
        }
    }

    // ---- read access (for tests and panels) ----

    pub fn project(&self) -> &Project {
        &self.editing.doc
    }

    pub fn take(&self) -> Option<&Take> {
        self.engine.take.as_deref()
    }

    /// The 3D view (where a point shows, for tests that drag in it).
    pub fn viewport(&self) -> &Viewport {
        &self.viewport
    }

    pub fn model_info(&self) -> Option<&ModelInfo> {
        self.engine.model.as_deref()
    }

    pub fn seed_map(&self) -> Option<&SeedMap> {
        self.engine.map.as_deref()
    }

    /// Classes whose seeds the seed map hides (clicked off in its key).
    pub fn hidden_on_map(&self) -> &std::collections::BTreeSet<String> {
        &self.panels.map.hidden_classes
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

    /// The folders searched for shipped models, and the models found there.
    pub fn model_search(&self) -> (&[PathBuf], &[PathBuf]) {
        (&self.storage.model_roots, &self.storage.shipped)
    }

    pub fn project_path(&self) -> Option<&Path> {
        self.editing.project_path.as_deref()
    }

    /// The classes carried over at the last model switch.
    pub fn class_mapping(&self) -> Option<&ClassMap> {
        self.panels.mapping.as_ref().map(|m| &m.map)
    }

    /// Whether the worker still has something to do for the UI (loading, generating, or a
    /// regeneration waiting for its pause).
    pub fn is_busy(&self) -> bool {
        self.engine.is_busy()
    }

    pub fn fields_mut(&mut self) -> &mut Fields {
        &mut self.panels.fields
    }

    pub fn export_options_mut(&mut self) -> &mut ExportOptions {
        &mut self.panels.export_options
    }

    /// The export's settings with its rig, if one is named (a take on a rig has no source
    /// root joint to put back: that is the model's source skeleton's).
    pub fn export_options(&self) -> ExportOptions {
        let rig = Some(PathBuf::from(self.panels.fields.export_rig.trim())).filter(|p| !p.as_os_str().is_empty());
        let source_root = self.panels.export_options.source_root && rig.is_none();
        ExportOptions { rig, source_root, ..self.panels.export_options.clone() }
    }

    pub fn set_selection(&mut self, selection: Option<(usize, usize)>) {
        self.playback.selection = selection;
    }

    /// Whether the document differs from what was last saved, opened or started.
    pub fn has_unsaved_work(&self) -> bool {
        self.editing.has_unsaved_work()
    }

    /// The window's title: the project's file name ("untitled" before it has one), marked
    /// while it has unsaved work.
    pub fn window_title(&self) -> String {
        let name = self.project_path().and_then(Path::file_name).map_or_else(|| "untitled".into(), |n| n.to_string_lossy().into_owned());
        let mark = if self.has_unsaved_work() { " •" } else { "" };
        format!("{name}{mark} — Glocal Studio")
    }

    /// Why the take on screen is not the document's, if it is not: an edit not generated
    /// yet, a generation under way or failed, or another model.
    pub fn stale_reason(&self) -> Option<String> {
        let take = self.engine.take.as_ref()?;
        if self.engine.model.as_ref().is_none_or(|m| m.dir != take.model_dir) || self.editing.doc.model != take.model_dir {
            return Some("it was generated with another model".into());
        }
        if take.options == self.editing.take_request().options {
            return None;
        }
        Some(match (&self.engine.generation_error, self.engine.pending) {
            (Some(e), _) => format!("the last generation failed: {}", first_line(e)),
            (None, Some(_)) => "the new take is still being generated".into(),
            (None, None) => "an edit has not been generated yet".into(),
        })
    }

    /// The selected range as the UI states it: first and last frame (both included) and
    /// the frame count. The selection itself is `[start, end)`.
    pub fn range_label(&self) -> Option<String> {
        let (a, b) = self.playback.selection?;
        Some(format!("Range {a}–{} ({} frames)", b.saturating_sub(1), b - a))
    }

    pub fn classes(&self) -> &[String] {
        self.engine.classes()
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

/// The autosave's document when the options ask for it and it reads (else a new one on the
/// options' model), and whether it was restored. Restored work counts as saved only as far
/// as its project file (the one last saved or opened, which it keeps) holds it.
fn restore_autosave(options: &StudioOptions, messages: &mut Messages) -> (Project, bool) {
    if let Some(path) = options.autosave.as_ref().filter(|p| options.restore_autosave && p.exists()) {
        match Project::load(path) {
            Ok(p) => {
                messages.info(format!("Restored from the autosave ({})", project::shown_path(path)));
                return (p, true);
            }
            Err(e) => messages.set(Topic::Autosave, Level::Error, broken_autosave_message(path, &e)),
        }
    }
    (Project::new(options.model_dir.clone()), false)
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
        self.handle_dialogs(&ctx);
        self.rig_windows(&ctx);
        self.shortcuts(&ctx);
        let title = self.window_title();
        if title != self.panels.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.panels.title = title;
        }
        let before = self.editing.doc.clone();

        // Side panels give way on a small window so the viewport keeps some room.
        let width = ctx.content_rect().width();
        let frame = unfilled_panel_frame(ui.style());
        egui::Panel::top("menu_bar").frame(frame).show(ui, |ui| self.menu_bar(ui));
        egui::Panel::bottom("transport").frame(frame).resizable(false).show(ui, |ui| self.bottom_panel(ui));
        let mut show_side = self.panels.show_side;
        egui::Panel::left("side").frame(frame).resizable(true).default_size(300.0f32.min(width * 0.3)).min_size(240.0).max_size((width * 0.4).max(240.0)).show_collapsible(ui, &mut show_side, |ui| {
            on_panel_background(ui, |ui| egui::ScrollArea::vertical().show(ui, |ui| self.side_panel(ui)));
        });
        self.panels.show_side = show_side;
        let mut show_map = self.panels.map.shown;
        egui::Panel::right("map").frame(frame).resizable(true).default_size(330.0f32.min(width * 0.25)).min_size(200.0).max_size((width * 0.35).max(200.0)).show_collapsible(ui, &mut show_map, |ui| self.map_panel(ui));
        self.panels.map.shown = show_map;
        egui::CentralPanel::no_frame().show(ui, |ui| self.central(ui));
        self.windows(&ctx);
        self.confirm_ui(&ctx);

        self.finish_edits(&ctx, before);
        self.advise();
        self.schedule(&ctx);
        self.autosave_tick(&ctx);
        let frames = self.engine.take.as_ref().map_or(0, |t| t.motion.frames());
        if self.playback.playing {
            let fps = self.engine.take.as_ref().map_or(25.0, |t| t.motion.fps);
            let dt = ctx.input(|i| f64::from(i.stable_dt.min(0.1)));
            let growing = self.engine.take.as_ref().is_some_and(|t| !t.complete && self.engine.pending.is_some_and(|(id, _)| id == t.id));
            self.playback.advance(dt, fps, frames, &self.editing.doc.playback, growing);
            ctx.request_repaint();
        }
    }
}

/// Model folders under `roots` that hold a `model.json`, sorted within each root; a model
/// name found in an earlier root hides the same name in later ones.
pub fn scan_models(roots: &[PathBuf]) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = Vec::new();
    for root in roots {
        let mut here: Vec<PathBuf> = std::fs::read_dir(root)
            .map(|rd| rd.filter_map(|e| e.ok()).map(|e| e.path()).filter(|p| p.join("model.json").is_file()).collect())
            .unwrap_or_default();
        here.sort();
        here.retain(|p| !found.iter().any(|f| f.file_name() == p.file_name()));
        found.extend(here);
    }
    found
}
