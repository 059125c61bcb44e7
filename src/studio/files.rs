//! Projects, models and exports on disk: new, open and save (asking before unsaved work is
//! discarded), the file dialogs, exports on the worker, the autosave and the remembered paths.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use egui::Key;

use super::app::StudioApp;
use super::dialogs::{Outcome, Purpose};
use super::engine::DEBOUNCE;
use super::messages::{Level, Topic};
use super::panels::{ExportRange, Guarded, InitTab};
use super::project::{self, Project, StudioState};
use super::retarget::PreviewFor;
use super::worker::ExportJob;
use crate::synth::export::{segments_in_range, ExportFormat};
use crate::synth::{Document, InitPose};

impl StudioApp {
    pub fn load_model(&mut self, dir: PathBuf) {
        // A generation asked for on the current model would only fail on the next one.
        self.cancel();
        self.engine.switching = false;
        self.panels.fields.model_path = dir.display().to_string();
        self.engine.model_loading = Some(dir.clone());
        self.engine.worker.load_model(dir);
    }

    /// Runs `action` now, or asks first when it would discard unsaved work.
    pub fn request(&mut self, action: Guarded) {
        if self.has_unsaved_work() {
            self.panels.confirm = Some(action);
        } else {
            self.run_guarded(action);
        }
    }

    pub(super) fn run_guarded(&mut self, action: Guarded) {
        self.panels.confirm = None;
        match action {
            Guarded::New => self.new_project(),
            Guarded::Open(path) => {
                self.open_project(&path);
            }
        }
    }

    /// A fresh project on the current model (undoable, like any edit).
    pub fn new_project(&mut self) {
        let model = self.editing.doc.model.clone();
        let classes = self.classes().to_vec();
        self.edit(|d| {
            *d = Project::new(model);
            d.options.timeline = Document::default_timeline(&classes);
        });
        self.editing.mark_saved();
        self.engine.close_document();
        self.editing.project_path = None;
        self.panels.fields.project_path = project::default_work_folder().join("project.glocal.json").display().to_string();
        self.editing.selected = None;
        self.panels.init_tab = InitTab::of(&self.editing.doc.options.init);
        self.save_state();
        self.messages.set(Topic::Project, Level::Info, "New project (not saved yet)");
    }

    pub fn save_project(&mut self, path: &Path) -> bool {
        let shown = project::shown_path(path);
        match ensure_parent(path).and_then(|()| self.editing.doc.save(path)) {
            Ok(()) => {
                self.editing.project_path = Some(std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()));
                self.panels.fields.project_path = shown.clone();
                self.editing.mark_saved();
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
                let model_changed = p.model != self.editing.doc.model || self.engine.model.is_none();
                self.editing.history.record(self.editing.doc.clone());
                let current_model = self.editing.doc.model.clone();
                self.editing.saved = Some(p.clone());
                self.editing.doc = p;
                self.engine.close_document();
                self.editing.project_path = Some(std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()));
                self.panels.fields.project_path = shown.clone();
                self.editing.selected = None;
                self.panels.init_tab = InitTab::of(&self.editing.doc.options.init);
                if model_changed {
                    // The project's model replaces the current one only once it has loaded.
                    let wanted = std::mem::replace(&mut self.editing.doc.model, current_model);
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
        let (Some(take), Some(model)) = (self.engine.take.clone(), self.engine.model.clone()) else {
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
        let (a, b) = match (self.panels.export_range, self.playback.selection) {
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
        let contacts = take.contacts.slice(a..b);
        let path = std::path::absolute(&path).unwrap_or(path);
        self.panels.fields.export_path = path.display().to_string();
        self.save_state();
        let source = Arc::new(model.spec.source_skeleton.clone());
        let segments = segments_in_range(&take.segments, a, b);
        let job = ExportJob { motion: take.motion.clone(), range: a..b, segments, contacts, path, options: self.export_options(), source, request: self.editing.doc.request() };
        self.engine.worker.export(job);
    }

    pub fn use_init_file(&mut self, path: PathBuf, frame: usize) {
        self.panels.fields.init_path = path.display().to_string();
        self.engine.worker.check_init(InitPose::file(path, frame));
    }

    pub(super) fn save_state(&mut self) {
        let Some(path) = &self.storage.state_path else { return };
        let state = StudioState {
            project_path: self.editing.project_path.clone(),
            export_path: Some(PathBuf::from(self.panels.fields.export_path.trim())).filter(|p| !p.as_os_str().is_empty()),
            export_rig: self.export_options().rig,
            class_table: self.storage.class_table.clone(),
        };
        if let Err(e) = state.save(path) {
            self.messages.set(Topic::Autosave, Level::Error, format!("Could not remember the studio's paths: {e:#}"));
        }
    }

    fn suggested_path(&self, purpose: Purpose) -> Option<PathBuf> {
        match purpose {
            Purpose::SaveProject => Some(self.save_suggestion()),
            Purpose::OpenProject => Some(PathBuf::from(&self.panels.fields.project_path)),
            Purpose::Export => Some(PathBuf::from(&self.panels.fields.export_path)),
            Purpose::InitFile => Some(PathBuf::from(&self.panels.fields.init_path)).filter(|p| !p.as_os_str().is_empty()),
            Purpose::KeyFile => Some(PathBuf::from(&self.panels.fields.key_path)).filter(|p| !p.as_os_str().is_empty()),
            Purpose::OpenModel => Some(PathBuf::from(&self.panels.fields.model_path)),
        }
    }

    /// Where a save is suggested: the typed project path, unless it is the file that
    /// waits to be opened (then a new file beside it).
    fn save_suggestion(&self) -> PathBuf {
        let typed = PathBuf::from(self.panels.fields.project_path.trim());
        match &self.panels.save_before {
            Some(action) if action.opens(&typed) => typed.with_file_name("untitled.glocal.json"),
            _ => typed,
        }
    }

    /// A file dialog: the system's, else the in-app one (with a word on why).
    pub fn open_dialog(&mut self, purpose: Purpose, ctx: &egui::Context) {
        let suggested = self.suggested_path(purpose);
        if !self.panels.dialogs.open(purpose, ctx, suggested.clone()) {
            self.prompt_for_path(purpose, suggested);
        }
    }

    fn prompt_for_path(&mut self, purpose: Purpose, suggested: Option<PathBuf>) {
        self.panels.dialogs.prompt(purpose, suggested);
        self.messages.set(Topic::Dialog, Level::Info, "No system file dialog is available: type the path in the dialog");
    }

    pub(super) fn handle_dialogs(&mut self, ctx: &egui::Context) {
        let mut done = self.panels.dialogs.poll();
        done.extend(self.panels.dialogs.prompt_ui(ctx));
        for (purpose, outcome) in done {
            match outcome {
                Outcome::Chosen(path) => self.dialog_chosen(purpose, path),
                Outcome::Cancelled => {
                    self.messages.resolve(Topic::Dialog);
                    if purpose == Purpose::SaveProject {
                        self.panels.save_before = None;
                    }
                }
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
            Purpose::OpenModel => self.switch_model(path),
            Purpose::OpenProject => self.request(Guarded::Open(path)),
            Purpose::SaveProject => self.save_chosen(&path),
            Purpose::Export => self.export_to(path),
            Purpose::InitFile => {
                self.panels.fields.init_path = path.display().to_string();
                let frame = self.panels.fields.init_frame;
                self.retarget_file(PreviewFor::Init, path, frame);
            }
            Purpose::KeyFile => {
                self.panels.fields.key_path = path.display().to_string();
                let frame = self.panels.fields.key_frame;
                self.retarget_file(PreviewFor::Key, path, frame);
            }
        }
    }

    pub(super) fn autosave_tick(&mut self, ctx: &egui::Context) {
        let Some(path) = self.storage.autosave.clone() else { return };
        if self.engine.model.is_none() || self.storage.autosaved.as_ref() == Some(&self.editing.doc) {
            self.storage.autosave_at = None;
            return;
        }
        let at = *self.storage.autosave_at.get_or_insert(self.now + DEBOUNCE);
        if self.now >= at {
            self.storage.autosave_at = None;
            if let Err(e) = project::autosave(&self.editing.doc, &path) {
                self.messages.set(Topic::Autosave, Level::Error, format!("Autosave failed: {e:#}"));
                self.storage.autosave = None;
            }
            self.storage.autosaved = Some(self.editing.doc.clone());
        } else {
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(at - self.now));
        }
    }

    pub(super) fn save_shortcut(&mut self, ctx: &egui::Context) -> bool {
        match self.editing.project_path.clone() {
            Some(p) => self.save_project(&p),
            None if !self.panels.fields.project_path.trim().is_empty() => {
                let p = PathBuf::from(self.panels.fields.project_path.trim());
                self.save_project(&p)
            }
            None => {
                self.open_dialog(Purpose::SaveProject, ctx);
                false
            }
        }
    }

    /// "Save first": saves to the project's own file, then runs `action`. It never writes
    /// the file `action` opens: a project with no file of its own, or whose file is that
    /// one, asks where to save, and `action` waits for that save.
    fn save_first(&mut self, action: Guarded, ctx: &egui::Context) {
        self.panels.confirm = None;
        match self.editing.project_path.clone().filter(|p| !action.opens(p)) {
            Some(own) => {
                if self.save_project(&own) {
                    self.run_guarded(action);
                }
            }
            None => {
                self.panels.save_before = Some(action);
                self.open_dialog(Purpose::SaveProject, ctx);
            }
        }
    }

    /// Saves where a dialog chose, then runs the action waiting for that save (if any);
    /// the file that action opens is refused, and the action dropped, with the work kept.
    fn save_chosen(&mut self, path: &Path) {
        let waiting = self.panels.save_before.take();
        if waiting.as_ref().is_some_and(|action| action.opens(path)) {
            let shown = project::shown_path(path);
            self.messages.set(Topic::Project, Level::Error, format!("Not saved, and nothing opened: {shown} is the project being opened; saving there would overwrite it"));
            return;
        }
        if self.save_project(path) {
            if let Some(action) = waiting {
                self.run_guarded(action);
            }
        }
    }

    /// The question before New or Open discards unsaved work.
    pub(super) fn confirm_ui(&mut self, ctx: &egui::Context) {
        let Some(action) = self.panels.confirm.clone() else { return };
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
            Some(0) => self.save_first(action, ctx),
            Some(1) => self.run_guarded(action),
            Some(_) => self.panels.confirm = None,
            None => {}
        }
    }
}

/// Creates the default work folder when a file is about to be written in it (it may not
/// exist yet); other folders are the user's to create.
fn ensure_parent(path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| *d == project::default_work_folder() && !d.exists()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("cannot create the folder {}: {e}", dir.display()))?;
    }
    Ok(())
}
