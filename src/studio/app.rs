//! The studio application: the document and its history, the worker, playback, and the
//! frame loop that ties the panels together. Panels live in their own modules as further
//! `impl StudioApp` blocks; this file holds the state and everything that is not drawing.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use egui::{Key, KeyboardShortcut, Modifiers};

use super::dialogs::{self, Dialogs, Outcome, Purpose};
use super::joint_mapping::PreviewFor;
use super::messages::{Level, Messages, Topic};
use super::project::{self, History, Project, StudioState};
use super::timeline::{Action, Mark, TimelineState, MIN_SECONDS};
use super::transport::Playback;
use super::viewport::Viewport;
use super::worker::{ModelInfo, Reply, SeedMap, Take, Worker};
use crate::synth::class_map::ClassMap;
use crate::synth::export::{segments_in_range, ExportFormat, ExportOptions};
use crate::synth::project::user_joint_map;
use crate::synth::{Document, GenerateOptions, InitPose, Request as TakeRequest, Segment};

/// Edits regenerate after this pause (seconds).
pub const DEBOUNCE: f64 = 0.3;

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
    /// The shipped models wherever they are found ([`model_roots`]), h36m first.
    fn default() -> Self {
        let model_roots = model_roots();
        let model_dir = model_roots.iter().map(|r| r.join("h36m")).find(|d| d.join("model.json").is_file()).unwrap_or_else(|| PathBuf::from("models/h36m"));
        Self { model_dir, model_roots, autosave: Some(project::default_autosave_path()), restore_autosave: true, system_dialogs: dialogs::system_dialog_available() }
    }
}

/// Where shipped models are looked for, in order: beside the executable (an installed
/// studio, or `target/<profile>/` two levels below a checkout), the crate's own `models/`
/// (where it was built), and the working folder. Duplicates are dropped.
pub fn model_roots() -> Vec<PathBuf> {
    let exe_dir = std::env::current_exe().ok().and_then(|e| e.parent().map(Path::to_path_buf));
    let mut roots: Vec<PathBuf> = Vec::new();
    if let Some(dir) = &exe_dir {
        roots.push(dir.join("models"));
        roots.extend(dir.ancestors().nth(2).map(|d| d.join("models")));
    }
    roots.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("models"));
    if let Ok(cwd) = std::env::current_dir() {
        roots.push(cwd.join("models"));
    }
    let mut seen = Vec::new();
    roots.retain(|r| {
        let key = r.canonicalize().unwrap_or_else(|_| r.clone());
        let new = !seen.contains(&key);
        seen.push(key);
        new
    });
    roots
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

impl InitTab {
    fn of(init: &InitPose) -> Self {
        match init {
            InitPose::SeedClass { .. } => InitTab::Class,
            InitPose::SeedIndex(_) => InitTab::Seed,
            InitPose::File { .. } => InitTab::File,
        }
    }
}

/// Actions that would discard unsaved work, held until the user answers.
#[derive(Clone, Debug, PartialEq)]
pub enum Guarded {
    New,
    Open(PathBuf),
}

/// The classes carried over at the last model switch, for the mapping window.
pub struct MappingNote {
    pub map: ClassMap,
    pub classes: Vec<String>,
    /// The segments each pair retagged (indices at the time of the switch).
    pub segments: Vec<Vec<usize>>,
    /// The timeline right after the switch: edits apply to it only while it is unchanged.
    pub timeline: crate::synth::Timeline,
}

/// Text fields of the UI (typed paths and the like).
pub struct Fields {
    pub model_path: String,
    pub project_path: String,
    pub export_path: String,
    pub init_path: String,
    pub init_frame: usize,
    pub new_class: usize,
    /// The seed the Seed tab offers.
    pub seed_index: usize,
    /// The seed "Key from seed pose" keys.
    pub key_seed: usize,
    /// The file and frame the last "Key from file" used.
    pub key_path: String,
    pub key_frame: usize,
}

/// The furthest "from frame" the UI accepts for an initial-pose file (a day at 120 fps).
pub const MAX_INIT_FRAME: usize = 120 * 86_400;

pub struct StudioApp {
    pub(super) doc: Project,
    pub(super) history: History,
    /// The document as last saved, opened or started: unsaved work is what differs from it.
    pub(super) saved: Project,
    pub(super) confirm: Option<Guarded>,
    /// An edit (e.g. a drag) is under way and has been recorded in the history.
    pub(super) edit_open: bool,
    pub(super) worker: Worker,
    pub(super) model: Option<Arc<ModelInfo>>,
    pub(super) model_loading: Option<PathBuf>,
    pub(super) map: Option<Arc<SeedMap>>,
    pub(super) map_error: Option<String>,
    pub(super) take: Option<Arc<Take>>,
    /// The take before the current one, for comparison, and its overlay colours.
    pub(super) previous: Option<(Arc<Take>, Arc<Vec<[u8; 3]>>)>,
    pub(super) compare: bool,
    /// Id and progress of the generation under way.
    pub(super) pending: Option<(u64, f32)>,
    /// Options of the last generation asked for.
    pub(super) requested: Option<GenerateOptions>,
    /// Why the last generation failed (the take on screen is then older than the document).
    pub(super) generation_error: Option<String>,
    pub(super) regen_at: Option<f64>,
    pub(super) auto_regen: bool,
    pub(super) playback: Playback,
    pub(super) viewport: Viewport,
    pub(super) timeline_state: TimelineState,
    pub(super) selected: Option<usize>,
    /// The key or waypoint selected on its track.
    pub(super) selected_mark: Option<Mark>,
    /// Clicks on the viewport's ground add path waypoints.
    pub(super) path_edit: bool,
    /// The advice last given (a message is posted when it changes).
    pub(super) advised: Option<String>,
    pub(super) messages: Messages,
    pub(super) fields: Fields,
    pub(super) init_tab: InitTab,
    /// An initial-pose file is being checked against a newly loaded model.
    pub(super) init_after_switch: bool,
    pub(super) export_range: ExportRange,
    pub(super) export_options: ExportOptions,
    pub(super) project_path: Option<PathBuf>,
    pub(super) autosave: Option<PathBuf>,
    pub(super) autosaved: Option<Project>,
    pub(super) autosave_at: Option<f64>,
    pub(super) state_path: Option<PathBuf>,
    /// The user's class-mapping edits, used before the shipped table.
    pub(super) class_table: Vec<(String, String)>,
    pub(super) mapping: Option<MappingNote>,
    pub(super) show_mapping: bool,
    pub(super) dialogs: Dialogs,
    pub(super) show_map: bool,
    pub(super) show_side: bool,
    pub(super) show_help: bool,
    pub(super) show_log: bool,
    pub(super) shipped: Vec<PathBuf>,
    pub(super) model_roots: Vec<PathBuf>,
    pub(super) now: f64,
    /// A foreign BVH's retarget preview, failure and mapping editor.
    pub(super) rig: super::joint_mapping::RigState,
}

impl StudioApp {
    pub fn new(cc: &eframe::CreationContext<'_>, options: StudioOptions) -> Self {
        Self::with_context(&cc.egui_ctx, options)
    }

    pub fn with_context(ctx: &egui::Context, options: StudioOptions) -> Self {
        let mut worker = Worker::spawn(ctx.clone());
        let mut messages = Messages::default();
        let mut doc = Project::new(options.model_dir.clone());
        let mut restored = false;
        if options.restore_autosave {
            if let Some(path) = options.autosave.as_ref().filter(|p| p.exists()) {
                match Project::load(path) {
                    Ok(p) => {
                        doc = p;
                        restored = true;
                        messages.info(format!("Restored from the autosave ({})", project::shown_path(path)));
                    }
                    Err(e) => messages.set(Topic::Autosave, Level::Error, broken_autosave_message(path, &e)),
                }
            }
        }
        let state_path = options.autosave.as_deref().map(StudioState::path_beside);
        let state = state_path.as_deref().map(StudioState::load).unwrap_or_default();
        let work = project::default_work_folder();
        let project_path = state.project_path.clone();
        worker.load_model(doc.model.clone());
        let shipped = scan_models(&options.model_roots);
        if shipped.is_empty() {
            let looked: Vec<String> = options.model_roots.iter().map(|r| project::shown_path(r)).collect();
            messages.set(Topic::Model, Level::Error, format!("No shipped models found; looked in {}. Open a model folder with File > Open model folder…", looked.join(", ")));
        }
        let fields = Fields {
            model_path: doc.model.display().to_string(),
            project_path: project_path.as_ref().map_or_else(|| work.join("project.glocal.json"), Clone::clone).display().to_string(),
            export_path: state.export_path.unwrap_or_else(|| work.join("take.bvh")).display().to_string(),
            init_path: String::new(),
            init_frame: 0,
            new_class: 0,
            seed_index: 0,
            key_seed: 0,
            key_path: String::new(),
            key_frame: 0,
        };
        let saved = if restored { Project::new(doc.model.clone()) } else { doc.clone() };
        Self {
            model_loading: Some(doc.model.clone()),
            init_tab: InitTab::of(&doc.options.init),
            saved,
            doc,
            history: History::default(),
            confirm: None,
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
            generation_error: None,
            regen_at: None,
            auto_regen: true,
            playback: Playback::default(),
            viewport: Viewport::new(),
            timeline_state: TimelineState::default(),
            selected: None,
            selected_mark: None,
            path_edit: false,
            advised: None,
            messages,
            fields,
            init_after_switch: false,
            export_range: ExportRange::Whole,
            export_options: ExportOptions::default(),
            project_path,
            autosave: options.autosave,
            autosaved: None,
            autosave_at: None,
            state_path,
            class_table: state.class_table,
            mapping: None,
            show_mapping: false,
            dialogs: Dialogs::new(options.system_dialogs),
            show_map: true,
            show_side: true,
            show_help: false,
            show_log: false,
            shipped,
            model_roots: options.model_roots,
            now: 0.0,
            rig: Default::default(),
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

    /// The folders searched for shipped models, and the models found there.
    pub fn model_search(&self) -> (&[PathBuf], &[PathBuf]) {
        (&self.model_roots, &self.shipped)
    }

    pub fn project_path(&self) -> Option<&Path> {
        self.project_path.as_deref()
    }

    /// The classes carried over at the last model switch.
    pub fn class_mapping(&self) -> Option<&ClassMap> {
        self.mapping.as_ref().map(|m| &m.map)
    }

    /// Whether the worker still has something to do for the UI (loading, generating, or a
    /// regeneration waiting for its pause).
    pub fn is_busy(&self) -> bool {
        self.model_loading.is_some() || self.pending.is_some() || self.regen_at.is_some()
    }

    pub fn fields_mut(&mut self) -> &mut Fields {
        &mut self.fields
    }

    pub fn export_options_mut(&mut self) -> &mut ExportOptions {
        &mut self.export_options
    }

    pub fn set_selection(&mut self, selection: Option<(usize, usize)>) {
        self.playback.selection = selection;
    }

    /// Whether the document differs from what was last saved, opened or started.
    pub fn has_unsaved_work(&self) -> bool {
        !self.doc.same_take(&self.saved)
    }

    /// Why the take on screen is not the document's, if it is not: an edit not generated
    /// yet, a generation under way or failed, or another model.
    pub fn stale_reason(&self) -> Option<String> {
        let take = self.take.as_ref()?;
        if self.model.as_ref().is_none_or(|m| m.dir != take.model_dir) || self.doc.model != take.model_dir {
            return Some("it was generated with another model".into());
        }
        if take.options == self.engine_options() {
            return None;
        }
        Some(match (&self.generation_error, self.pending) {
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

    // ---- the document ----

    /// Replaces the document by `f(doc)` as one undoable edit.
    pub fn edit(&mut self, f: impl FnOnce(&mut Project)) {
        let before = self.doc.clone();
        f(&mut self.doc);
        if self.doc.options != before.options {
            self.history.record(before);
        }
    }

    pub fn undo(&mut self) {
        if self.history.undo(&mut self.doc) {
            self.after_history_step();
        } else {
            self.messages.info("Nothing to undo");
        }
    }

    pub fn redo(&mut self) {
        if self.history.redo(&mut self.doc) {
            self.after_history_step();
        } else {
            self.messages.info("Nothing to redo");
        }
    }

    fn after_history_step(&mut self) {
        let n = self.doc.options.timeline.segments.len();
        self.selected = self.selected.filter(|&k| k < n);
        self.selected_mark = None;
        self.init_tab = InitTab::of(&self.doc.options.init);
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
        let at = self.selected.map_or(self.doc.options.timeline.segments.len(), |k| k + 1).min(self.doc.options.timeline.segments.len());
        self.edit(|d| d.options.timeline.segments.insert(at, Segment::new(class, 3.0)));
        self.selected = Some(at);
    }

    pub fn delete_segment(&mut self, k: usize) {
        if k < self.doc.options.timeline.segments.len() {
            self.edit(|d| {
                d.options.timeline.segments.remove(k);
            });
            let n = self.doc.options.timeline.segments.len();
            self.selected = self.selected.filter(|&s| s < n);
        }
    }

    pub fn set_segment_class(&mut self, k: usize, class: &str) {
        if k < self.doc.options.timeline.segments.len() {
            self.edit(|d| d.options.timeline.segments[k].class = class.to_string());
        }
    }

    /// Chooses where the take starts from, as the Initial pose tabs do: the tab's choice is
    /// applied at once. "By class" starts from the class's most typical seed window (the
    /// first segment's class unless one is chosen).
    pub fn set_init_tab(&mut self, tab: InitTab) {
        self.init_tab = tab;
        let Some(model) = self.model.clone() else { return };
        match tab {
            InitTab::Class => {
                if !matches!(self.doc.options.init, InitPose::SeedClass { .. }) {
                    let first = self.doc.options.timeline.segments.first().and_then(|s| model.spec.class_index(&s.class).ok()).unwrap_or(0);
                    self.set_init_class(first, 0);
                }
            }
            InitTab::Seed => self.doc.options.init = InitPose::SeedIndex(self.fields.seed_index.min(model.seeds.len().saturating_sub(1))),
            InitTab::File => {
                if self.fields.init_path.trim().is_empty() {
                    self.messages.set(Topic::Init, Level::Info, "Choose a motion file: the take starts from it once it has been checked");
                } else if !matches!(self.doc.options.init, InitPose::File { .. }) {
                    let p = PathBuf::from(self.fields.init_path.trim());
                    self.use_init_file(p, self.fields.init_frame);
                }
            }
        }
    }

    /// Starts the take from the `rank`-th most typical seed window of `class`.
    pub fn set_init_class(&mut self, class: usize, rank: usize) {
        let Some(model) = self.model.clone() else { return };
        let Some(name) = model.spec.classes.get(class).cloned() else { return };
        self.init_tab = InitTab::Class;
        self.doc.options.init = InitPose::SeedClass { class: name, variant: model.typical_variant(class, rank) };
    }

    /// Applies what the timeline widget reports.
    pub(super) fn apply_timeline(&mut self, actions: Vec<Action>) {
        let frames = self.take.as_ref().map_or(0, |t| t.motion.frames());
        for a in actions {
            match a {
                Action::Select(k) => {
                    self.selected = k;
                    self.selected_mark = None;
                }
                Action::BeginEdit => {
                    self.history.record(self.doc.clone());
                    self.edit_open = true;
                }
                Action::Resize { index, seconds } => {
                    if let Some(s) = self.doc.options.timeline.segments.get_mut(index) {
                        s.seconds = seconds.max(MIN_SECONDS);
                    }
                }
                Action::Move { from, to } => {
                    let n = self.doc.options.timeline.segments.len();
                    if from < n && to < n {
                        let s = self.doc.options.timeline.segments.remove(from);
                        self.doc.options.timeline.segments.insert(to, s);
                        self.selected = Some(to);
                    }
                }
                Action::SetClass { index, class } => self.set_segment_class(index, &class),
                Action::Duplicate(k) => {
                    if let Some(s) = self.doc.options.timeline.segments.get(k).cloned() {
                        self.edit(|d| d.options.timeline.segments.insert(k + 1, s));
                        self.selected = Some(k + 1);
                    }
                }
                Action::Delete(k) => self.delete_segment(k),
                Action::Seek(f) => {
                    self.playback.playing = false;
                    self.playback.seek(f, frames);
                }
                Action::SetSelection(s) => self.playback.selection = s,
                Action::SelectMark(m) => {
                    self.selected_mark = m;
                    self.selected = None;
                }
                Action::MoveMark { mark, seconds } => self.move_mark(mark, seconds),
                Action::DeleteMark(m) => self.delete_mark(m),
                Action::ClearWaypointTime(k) => self.clear_waypoint_time(k),
            }
        }
    }

    // ---- files ----

    pub fn load_model(&mut self, dir: PathBuf) {
        // A generation asked for on the current model would only fail on the next one.
        self.cancel();
        self.fields.model_path = dir.display().to_string();
        self.model_loading = Some(dir.clone());
        self.worker.load_model(dir);
    }

    /// Runs `action` now, or asks first when it would discard unsaved work.
    pub fn request(&mut self, action: Guarded) {
        if self.has_unsaved_work() {
            self.confirm = Some(action);
        } else {
            self.run_guarded(action);
        }
    }

    pub(super) fn run_guarded(&mut self, action: Guarded) {
        self.confirm = None;
        match action {
            Guarded::New => self.new_project(),
            Guarded::Open(path) => {
                self.open_project(&path);
            }
        }
    }

    /// A fresh project on the current model (undoable, like any edit).
    pub fn new_project(&mut self) {
        let model = self.doc.model.clone();
        let classes = self.classes().to_vec();
        self.edit(|d| {
            *d = Project::new(model);
            d.options.timeline = Document::default_timeline(&classes);
        });
        self.saved = self.doc.clone();
        self.project_path = None;
        self.fields.project_path = project::default_work_folder().join("project.glocal.json").display().to_string();
        self.selected = None;
        self.init_tab = InitTab::of(&self.doc.options.init);
        self.save_state();
        self.messages.set(Topic::Project, Level::Info, "New project (not saved yet)");
    }

    pub fn save_project(&mut self, path: &Path) -> bool {
        let shown = project::shown_path(path);
        match ensure_parent(path).and_then(|()| self.doc.save(path)) {
            Ok(()) => {
                self.project_path = Some(std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()));
                self.fields.project_path = shown.clone();
                self.saved = self.doc.clone();
                self.save_state();
                self.messages.set(Topic::Project, Level::Info, format!("Saved {shown}"));
                true
            }
            Err(e) => {
                self.messages.set(Topic::Project, Level::Error, format!("Could not save the project to {shown}: {e:#}"));
                false
            }
        }
    }

    /// Opens a project; on any error the current one stays as it is.
    pub fn open_project(&mut self, path: &Path) -> bool {
        let shown = project::shown_path(path);
        match Project::load(path) {
            Ok(p) => {
                let model_changed = p.model != self.doc.model || self.model.is_none();
                self.history.record(self.doc.clone());
                let current_model = self.doc.model.clone();
                self.doc = p;
                self.saved = self.doc.clone();
                self.project_path = Some(std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()));
                self.fields.project_path = shown.clone();
                self.selected = None;
                self.init_tab = InitTab::of(&self.doc.options.init);
                if model_changed {
                    // The project's model replaces the current one only once it has loaded.
                    let wanted = std::mem::replace(&mut self.doc.model, current_model);
                    self.saved.model = wanted.clone();
                    self.load_model(wanted);
                }
                self.save_state();
                self.messages.set(Topic::Project, Level::Info, format!("Opened {shown}"));
                true
            }
            Err(e) => {
                self.messages.set(Topic::Project, Level::Error, format!("Could not open the project: {e:#}"));
                false
            }
        }
    }

    /// Exports the take on screen (whole or the selected range) on the worker; refused when
    /// that take is not the document's.
    pub fn export_to(&mut self, path: PathBuf) {
        let (Some(take), Some(model)) = (self.take.clone(), self.model.clone()) else {
            self.messages.set(Topic::Export, Level::Error, "Nothing to export yet: the take has not been generated");
            return;
        };
        if let Some(why) = self.stale_reason() {
            self.messages.set(Topic::Stale, Level::Error, format!("Not exported: the take on screen is out of date ({why}). Generate it first (or undo the edit), then export."));
            return;
        }
        if let Err(e) = ExportFormat::from_path(&path) {
            self.messages.set(Topic::Export, Level::Error, format!("Could not export: {e:#}"));
            return;
        }
        let frames = take.motion.frames();
        let (a, b) = match (self.export_range, self.playback.selection) {
            (ExportRange::Selection, Some((a, b))) => (a.min(frames), b.min(frames)),
            (ExportRange::Selection, None) => {
                self.messages.set(Topic::Export, Level::Error, "No range is selected: shift-drag on the timeline ruler, or export the whole take");
                return;
            }
            (ExportRange::Whole, _) => (0, frames),
        };
        if b <= a {
            self.messages.set(Topic::Export, Level::Error, "The selected range is empty");
            return;
        }
        if let Err(e) = ensure_parent(&path) {
            self.messages.set(Topic::Export, Level::Error, format!("Could not export {}: {e:#}", project::shown_path(&path)));
            return;
        }
        let motion = if (a, b) == (0, frames) { take.motion.clone() } else { Arc::new(take.motion.slice(a, b)) };
        let contacts = take.contacts.slice(a..b);
        let path = std::path::absolute(&path).unwrap_or(path);
        self.fields.export_path = path.display().to_string();
        self.save_state();
        let source = Arc::new(model.spec.source_skeleton.clone());
        self.worker.export(motion, segments_in_range(&take.segments, a, b), contacts, path, self.export_options.clone(), source);
    }

    pub fn use_init_file(&mut self, path: PathBuf, frame: usize) {
        self.fields.init_path = path.display().to_string();
        self.worker.check_init(InitPose::file(path, frame));
    }

    fn save_state(&mut self) {
        let Some(path) = &self.state_path else { return };
        let state = StudioState {
            project_path: self.project_path.clone(),
            export_path: Some(PathBuf::from(self.fields.export_path.trim())).filter(|p| !p.as_os_str().is_empty()),
            class_table: self.class_table.clone(),
        };
        if let Err(e) = state.save(path) {
            self.messages.set(Topic::Autosave, Level::Error, format!("Could not remember the studio's paths: {e:#}"));
        }
    }

    fn suggested_path(&self, purpose: Purpose) -> Option<PathBuf> {
        match purpose {
            Purpose::SaveProject | Purpose::OpenProject => Some(PathBuf::from(&self.fields.project_path)),
            Purpose::Export => Some(PathBuf::from(&self.fields.export_path)),
            Purpose::InitFile => Some(PathBuf::from(&self.fields.init_path)).filter(|p| !p.as_os_str().is_empty()),
            Purpose::KeyFile => Some(PathBuf::from(&self.fields.key_path)).filter(|p| !p.as_os_str().is_empty()),
            Purpose::OpenModel => Some(PathBuf::from(&self.fields.model_path)),
        }
    }

    /// A file dialog: the system's, else the in-app one (with a word on why).
    pub fn open_dialog(&mut self, purpose: Purpose, ctx: &egui::Context) {
        let suggested = self.suggested_path(purpose);
        if !self.dialogs.open(purpose, ctx, suggested.clone()) {
            self.prompt_for_path(purpose, suggested);
        }
    }

    fn prompt_for_path(&mut self, purpose: Purpose, suggested: Option<PathBuf>) {
        self.dialogs.prompt(purpose, suggested);
        self.messages.set(Topic::Dialog, Level::Info, "No system file dialog is available: type the path in the dialog");
    }

    fn handle_dialogs(&mut self, ctx: &egui::Context) {
        let mut done = self.dialogs.poll();
        done.extend(self.dialogs.prompt_ui(ctx));
        for (purpose, outcome) in done {
            match outcome {
                Outcome::Chosen(path) => self.dialog_chosen(purpose, path),
                Outcome::Cancelled => self.messages.resolve(Topic::Dialog),
                Outcome::Unavailable => {
                    let suggested = self.suggested_path(purpose);
                    self.prompt_for_path(purpose, suggested);
                }
            }
        }
    }

    fn dialog_chosen(&mut self, purpose: Purpose, path: PathBuf) {
        self.messages.resolve(Topic::Dialog);
        match purpose {
            Purpose::OpenModel => self.load_model(path),
            Purpose::OpenProject => self.request(Guarded::Open(path)),
            Purpose::SaveProject => {
                self.save_project(&path);
            }
            Purpose::Export => self.export_to(path),
            Purpose::InitFile => {
                self.fields.init_path = path.display().to_string();
                let frame = self.fields.init_frame;
                self.retarget_file(PreviewFor::Init, path, frame);
            }
            Purpose::KeyFile => {
                self.fields.key_path = path.display().to_string();
                let frame = self.fields.key_frame;
                self.retarget_file(PreviewFor::Key, path, frame);
            }
        }
    }

    // ---- the worker ----

    fn handle_replies(&mut self) {
        if self.worker.take_lost() > 0 {
            self.messages.set(Topic::Generation, Level::Error, "The background worker had stopped and was started again; the model is loading again");
            self.pending = None;
            let dir = self.doc.model.clone();
            self.load_model(dir);
        }
        for reply in self.worker.poll() {
            match reply {
                Reply::ModelLoaded(info) => self.model_loaded(info),
                Reply::ModelFailed { dir, error } => {
                    self.model_loading = None;
                    let keep = match &self.model {
                        Some(m) => format!(" The current model ({}) stays loaded, with its take.", m.spec.dataset),
                        None => String::new(),
                    };
                    self.messages.set(Topic::Model, Level::Error, format!("Could not load the model {}: {}.{keep}", project::shown_path(&dir), first_line(&error)));
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
                    self.generation_error = None;
                    self.messages.resolve(Topic::Generation);
                    self.messages.resolve(Topic::Stale);
                    let frames = take.motion.frames();
                    self.show_warnings(&take.warnings);
                    if let Some(old) = self.take.replace(take) {
                        let white = Arc::new(vec![PREVIOUS_TAKE_COLOR; old.motion.frames()]);
                        self.previous = Some((old, white));
                    }
                    self.playback.clamp(frames);
                }
                Reply::GenerateFailed { id, error, cancelled } => {
                    if self.pending.is_some_and(|(p, _)| p == id) {
                        self.pending = None;
                    }
                    if !cancelled {
                        let shown = if self.take.is_some() { " The viewport shows the previous take, marked out of date." } else { "" };
                        self.messages.set(Topic::Generation, Level::Error, format!("Generation failed: {error}.{shown}"));
                        self.generation_error = Some(error);
                    }
                }
                Reply::Path { id, path } => {
                    if let Some(t) = self.take.as_mut().filter(|t| t.id == id) {
                        if let Some(t) = Arc::get_mut(t) {
                            t.path = path;
                        } else {
                            *t = Arc::new(Take { path, ..clone_take(t) });
                        }
                    }
                }
                Reply::InitOk(init) => {
                    let name = match &init {
                        InitPose::File { path, frame, .. } => format!("{} from frame {frame}", project::shown_path(path)),
                        _ => String::new(),
                    };
                    self.init_after_switch = false;
                    self.edit(|d| d.options.init = init);
                    self.init_tab = InitTab::File;
                    self.messages.set(Topic::Init, Level::Info, format!("Initial pose: {name}"));
                }
                Reply::InitFailed { error, .. } if self.init_after_switch => {
                    self.init_after_switch = false;
                    let dataset = self.model.as_ref().map_or_else(String::new, |m| m.spec.dataset.clone());
                    let first = self.doc.options.timeline.segments.first().and_then(|s| self.model.as_ref().and_then(|m| m.spec.class_index(&s.class).ok())).unwrap_or(0);
                    self.set_init_class(first, 0);
                    let class = match &self.doc.options.init {
                        InitPose::SeedClass { class, .. } => class.clone(),
                        _ => String::new(),
                    };
                    self.messages.set(Topic::Init, Level::Info, format!("The initial-pose file does not fit the {dataset} model ({}): the take now starts from a typical '{class}' pose", first_line(&error)));
                }
                Reply::InitFailed { error, .. } => {
                    self.messages.set(Topic::Init, Level::Error, format!("That file cannot start a take: {}", first_line(&error)));
                }
                reply @ (Reply::Retargeted(_) | Reply::RetargetFailed(_) | Reply::NotForeign { .. }) => self.retarget_reply(reply),
                Reply::Exported(path) => self.messages.set(Topic::Export, Level::Info, format!("Exported {}", project::shown_path(&path))),
                Reply::ExportFailed { path, error } => self.messages.set(Topic::Export, Level::Error, format!("Could not export {}: {error}", project::shown_path(&path))),
            }
        }
    }

    fn model_loaded(&mut self, info: Arc<ModelInfo>) {
        let previous = self.model.take();
        self.model_loading = None;
        self.map = None;
        self.map_error = None;
        self.doc.model = info.dir.clone();
        self.fields.model_path = info.dir.display().to_string();
        if self.doc.options.timeline.segments.is_empty() {
            self.doc.options.timeline = Document::default_timeline(&info.spec.classes);
        }
        if previous.is_none() && self.saved.options.timeline.segments.is_empty() {
            // The first model of a fresh start: its default timeline is not unsaved work.
            self.saved = self.doc.clone();
        }
        self.carry_classes(&info);
        self.carry_init(&info);
        self.fields.new_class = self.fields.new_class.min(info.spec.classes.len().saturating_sub(1));
        self.fields.seed_index = self.fields.seed_index.min(info.seeds.len().saturating_sub(1));
        if previous.is_some() {
            self.messages.set(Topic::Model, Level::Info, format!("Loaded model {} ({})", project::shown_path(&info.dir), info.spec.dataset));
        } else {
            self.messages.resolve(Topic::Model);
        }
        self.model = Some(info);
        self.previous = None;
        self.requested = None;
        self.generation_error = None;
        self.regen_at = Some(self.now);
    }

    /// Retags segments whose class the new model does not have (by [`ClassMap`]), in the
    /// document and its history, and says what was mapped.
    fn carry_classes(&mut self, info: &ModelInfo) {
        let classes = &info.spec.classes;
        let mut unknown: Vec<String> = Vec::new();
        for s in &self.doc.options.timeline.segments {
            if info.spec.class_index(&s.class).is_err() && !unknown.contains(&s.class) {
                unknown.push(s.class.clone());
            }
        }
        if unknown.is_empty() || classes.is_empty() {
            return;
        }
        let table: Vec<(String, String)> = self.class_table.iter().cloned().chain(ClassMap::shipped_table()).collect();
        let map = ClassMap::build(&unknown, classes, &table);
        let described = map.describe(&self.doc.options.timeline);
        let segments = map.pairs.iter().map(|p| self.doc.options.timeline.segments.iter().enumerate().filter(|(_, s)| s.class == p.from).map(|(k, _)| k).collect()).collect();
        let (timeline, changed) = map.apply(&self.doc.options.timeline);
        self.doc.options.timeline = timeline;
        let carry = |p: &mut Project| {
            p.options.timeline = map.apply(&p.options.timeline).0;
            if let InitPose::SeedClass { class, .. } = &mut p.options.init {
                if let Some(to) = map.get(class) {
                    *class = to.to_string();
                }
            }
        };
        self.history.map_states(carry);
        self.messages.set(
            Topic::Classes,
            Level::Info,
            format!("Classes carried over to {}: {described} ({changed} segments, durations kept). Edit > Class mapping… changes a pairing.", info.spec.dataset),
        );
        self.mapping = Some(MappingNote { map, classes: classes.clone(), segments, timeline: self.doc.options.timeline.clone() });
    }

    /// Keeps the initial pose meaningful on a new model: a class start moves to the mapped
    /// class's typical window, a seed index out of range is reset, and a file is checked
    /// again (and reset with a message if it does not fit).
    fn carry_init(&mut self, info: &ModelInfo) {
        match self.doc.options.init.clone() {
            InitPose::SeedClass { class, variant } => {
                let k = match info.spec.class_index(&class) {
                    Ok(k) => k,
                    Err(_) => self.mapping.as_ref().and_then(|m| m.map.get(&class)).and_then(|c| info.spec.class_index(c).ok()).unwrap_or(0),
                };
                let variant = if info.spec.classes[k] == class { variant } else { info.typical_variant(k, 0) };
                self.doc.options.init = InitPose::SeedClass { class: info.spec.classes[k].clone(), variant };
            }
            InitPose::SeedIndex(i) if i >= info.seeds.len() => {
                self.doc.options.init = InitPose::SeedIndex(0);
                self.messages.set(Topic::Init, Level::Info, format!("Seed {i} does not exist in the {} model: the take starts from seed 0", info.spec.dataset));
            }
            InitPose::SeedIndex(_) => {}
            init @ InitPose::File { .. } => {
                self.init_after_switch = true;
                self.worker.check_init(init);
            }
        }
    }

    /// Changes the counterpart of `from` in the last model switch's mapping: the segments it
    /// retagged get `to` (while the timeline is as the switch left it), and the pairing is
    /// remembered for later switches.
    pub fn set_mapping(&mut self, from: &str, to: &str) {
        let Some(note) = self.mapping.as_mut() else { return };
        let Some(k) = note.map.pairs.iter().position(|p| p.from == from) else { return };
        note.map.set(from, to);
        self.class_table.retain(|(a, _)| a != from);
        self.class_table.insert(0, (from.to_string(), to.to_string()));
        if self.doc.options.timeline.segments.len() == note.timeline.segments.len() {
            let indices = note.segments[k].clone();
            self.edit(|d| indices.iter().for_each(|&i| d.options.timeline.segments[i].class = to.to_string()));
            if let Some(note) = self.mapping.as_mut() {
                note.timeline = self.doc.options.timeline.clone();
            }
        }
        self.save_state();
    }

    /// Asks for a new take when the options changed and the pause is over.
    fn schedule(&mut self, ctx: &egui::Context) {
        let Some(model) = &self.model else { return };
        // Not while another model loads (the request would reach it), nor before the
        // initial-pose file has been checked against a new model.
        if model.dir != self.doc.model || self.model_loading.is_some() || self.init_after_switch {
            return;
        }
        let options = self.engine_options();
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
        let options = self.engine_options();
        let joint_map = self.doc.joint_map.as_ref().map(user_joint_map);
        let id = self.worker.generate(TakeRequest { options: options.clone(), joint_map });
        self.requested = Some(options);
        self.generation_error = None;
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
                self.messages.set(Topic::Autosave, Level::Error, format!("Autosave failed: {e:#}"));
                self.autosave = None;
            }
            self.autosaved = Some(self.doc.clone());
        } else {
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(at - self.now));
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let save = KeyboardShortcut::new(Modifiers::COMMAND, Key::S);
        if ctx.input_mut(|i| i.consume_shortcut(&save)) {
            self.save_shortcut(ctx);
        }
        // A focused text field keeps every other key, Ctrl+Z included (its own undo).
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let redo = KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
        let undo = KeyboardShortcut::new(Modifiers::COMMAND, Key::Z);
        let redo_y = KeyboardShortcut::new(Modifiers::COMMAND, Key::Y);
        let (r, u) = ctx.input_mut(|i| (i.consume_shortcut(&redo) || i.consume_shortcut(&redo_y), i.consume_shortcut(&undo)));
        if r {
            self.redo();
        } else if u {
            self.undo();
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
            if let Some(mark) = self.selected_mark {
                self.delete_mark(mark);
            } else if let Some(k) = self.selected {
                self.delete_segment(k);
            }
        }
    }

    pub(super) fn save_shortcut(&mut self, ctx: &egui::Context) -> bool {
        match self.project_path.clone() {
            Some(p) => self.save_project(&p),
            None if !self.fields.project_path.trim().is_empty() => {
                let p = PathBuf::from(self.fields.project_path.trim());
                self.save_project(&p)
            }
            None => {
                self.open_dialog(Purpose::SaveProject, ctx);
                false
            }
        }
    }

    /// Closes the open edit once the pointer is released, and records edits made by
    /// ordinary widgets this frame as one undo step each.
    fn finish_edits(&mut self, ctx: &egui::Context, before: Project) {
        if self.doc.options != before.options && !self.edit_open {
            self.history.record(before);
            self.edit_open = true;
        }
        if ctx.input(|i| !i.pointer.any_down()) {
            self.edit_open = false;
        }
    }

    /// Says when the model will not follow the timeline as written, once per piece of
    /// advice (the fixes are in the sidebar).
    fn advise(&mut self) {
        let found = super::advice::seated_too_short(&self.doc.options.timeline, self.classes());
        let advice = found.first().map(|short| format!("{} The sidebar proposes a fix.", short.message()));
        if advice == self.advised {
            return;
        }
        match &advice {
            Some(text) => self.messages.set(Topic::Advice, Level::Info, text.clone()),
            None => self.messages.resolve(Topic::Advice),
        }
        self.advised = advice;
    }

    /// The question before New or Open discards unsaved work.
    fn confirm_ui(&mut self, ctx: &egui::Context) {
        let Some(action) = self.confirm.clone() else { return };
        let what = match &action {
            Guarded::New => "Start a new project".to_string(),
            Guarded::Open(p) => format!("Open {}", project::shown_path(p)),
        };
        let mut answer = None;
        egui::Modal::new(egui::Id::unique("glocal_confirm_discard")).show(ctx, |ui| {
            ui.set_max_width(420.0);
            ui.heading("Unsaved changes");
            ui.label(format!("{what}? The current project has changes that are not saved."));
            ui.horizontal(|ui| {
                if ui.button("Save first").clicked() {
                    answer = Some(0);
                }
                if ui.button("Discard changes").clicked() {
                    answer = Some(1);
                }
                if ui.button("Cancel").clicked() || ui.input(|i| i.key_pressed(Key::Escape)) {
                    answer = Some(2);
                }
            });
        });
        match answer {
            Some(0) => {
                if self.save_shortcut(ctx) {
                    self.run_guarded(action);
                } else {
                    self.confirm = None;
                }
            }
            Some(1) => self.run_guarded(action),
            Some(_) => self.confirm = None,
            None => {}
        }
    }
}

/// The previous take's overlay colour: white, unlike any class colour (ghosts keep theirs).
pub const PREVIOUS_TAKE_COLOR: [u8; 3] = [245, 245, 245];

pub(super) fn first_line(text: &str) -> &str {
    text.lines().next().unwrap_or("")
}

/// Creates the default work folder when a file is about to be written in it (it may not
/// exist yet); other folders are the user's to create.
fn ensure_parent(path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| *d == project::default_work_folder() && !d.exists()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("cannot create the folder {}: {e}", dir.display()))?;
    }
    Ok(())
}

/// An autosave that could not be read is moved aside (so the next autosave does not
/// overwrite it) and the message says where it went.
fn broken_autosave_message(path: &Path, error: &anyhow::Error) -> String {
    let why = first_line(&format!("{error:#}")).to_string();
    match project::keep_broken_autosave(path) {
        Ok(kept) => format!("The autosave could not be restored ({why}); it is kept as {}", project::shown_path(&kept)),
        Err(e) => format!("The autosave could not be restored ({why}) nor moved aside ({e:#}); it will be overwritten by the next autosave"),
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
        self.handle_dialogs(&ctx);
        self.rig_windows(&ctx);
        self.shortcuts(&ctx);
        let before = self.doc.clone();

        // Side panels give way on a small window so the viewport keeps some room.
        let width = ctx.content_rect().width();
        let frame = unfilled_panel_frame(ui.style());
        egui::Panel::top("menu_bar").frame(frame).show(ui, |ui| self.menu_bar(ui));
        egui::Panel::bottom("transport").frame(frame).resizable(false).show(ui, |ui| self.bottom_panel(ui));
        let mut show_side = self.show_side;
        egui::Panel::left("side").frame(frame).resizable(true).default_size(300.0f32.min(width * 0.3)).min_size(240.0).max_size((width * 0.4).max(240.0)).show_collapsible(ui, &mut show_side, |ui| {
            on_panel_background(ui, |ui| egui::ScrollArea::vertical().show(ui, |ui| self.side_panel(ui)));
        });
        self.show_side = show_side;
        let mut show_map = self.show_map;
        egui::Panel::right("map").frame(frame).resizable(true).default_size(330.0f32.min(width * 0.25)).min_size(200.0).max_size((width * 0.35).max(200.0)).show_collapsible(ui, &mut show_map, |ui| self.map_panel(ui));
        self.show_map = show_map;
        egui::CentralPanel::no_frame().show(ui, |ui| self.central(ui));
        self.windows(&ctx);
        self.confirm_ui(&ctx);

        self.finish_edits(&ctx, before);
        self.advise();
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

fn clone_take(t: &Take) -> Take {
    Take {
        id: t.id,
        model_dir: t.model_dir.clone(),
        motion: t.motion.clone(),
        segments: t.segments.clone(),
        frame_colors: t.frame_colors.clone(),
        block_classes: t.block_classes.clone(),
        path: t.path.clone(),
        options: t.options.clone(),
        warnings: t.warnings.clone(),
        contacts: t.contacts.clone(),
        millis: t.millis,
    }
}
