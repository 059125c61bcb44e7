//! The engine's side of the app: asking the worker for takes when the document changed,
//! and what its replies change (takes, models, seed maps, initial-pose checks), classes
//! and starts carried over to a newly loaded model.

use std::sync::Arc;

use super::app::StudioApp;
use super::engine::{DEBOUNCE, PREVIOUS_TAKE_COLOR};
use super::messages::{first_line, Level, Topic};
use super::panels::InitTab;
use super::project;
use super::worker::{ModelInfo, Reply, Take};
use crate::synth::{Document, InitPose};

impl StudioApp {
    /// Takes in what the worker sent since the last frame.
    pub(super) fn handle_replies(&mut self) {
        if self.engine.worker.take_lost() > 0 {
            self.messages.set(Topic::Generation, Level::Error, "The background worker had stopped and was started again; the model is loading again");
            self.engine.pending = None;
            let dir = self.editing.doc.model.clone();
            self.load_model(dir);
        }
        for reply in self.engine.worker.poll() {
            match reply {
                Reply::ModelLoaded(info) => self.model_loaded(info),
                Reply::ModelFailed { dir, error } => self.model_failed(&dir, &error),
                Reply::Map(map) => {
                    if self.engine.model.as_ref().is_some_and(|m| m.dir == map.model_dir) {
                        self.engine.map = Some(map);
                    }
                }
                Reply::MapFailed(e) => self.engine.map_error = Some(e),
                Reply::Progress { id, fraction } => {
                    if let Some((pid, p)) = self.engine.pending.as_mut() {
                        if *pid == id {
                            *p = fraction;
                        }
                    }
                }
                Reply::Streamed(take) => self.take_streamed(take),
                Reply::Generated(take) => self.take_generated(take),
                Reply::GenerateFailed { id, error, cancelled } => self.generation_failed(id, error, cancelled),
                Reply::Path { id, path } => self.place_take(id, path),
                Reply::InitOk(init) => self.init_checked(init),
                Reply::InitFailed { error, .. } if self.engine.init_after_switch => self.init_does_not_fit(&error),
                Reply::InitFailed { error, .. } => {
                    self.messages.set(Topic::Init, Level::Error, format!("That file cannot start a take: {}", first_line(&error)));
                }
                Reply::Retarget(retargeting) => self.retarget_reply(retargeting),
                Reply::Exported(path) => self.messages.set(Topic::Export, Level::Info, format!("Exported {}", project::shown_path(&path))),
                Reply::ExportFailed { path, error } => self.messages.set(Topic::Export, Level::Error, format!("Could not export {}: {error}", project::shown_path(&path))),
            }
        }
    }

    /// A model that did not load: the current one, if any, stays.
    fn model_failed(&mut self, dir: &std::path::Path, error: &str) {
        self.engine.model_loading = None;
        let keep = match &self.engine.model {
            Some(m) => format!(" The current model ({}) stays loaded, with its take.", m.spec.dataset),
            None => String::new(),
        };
        self.messages.set(Topic::Model, Level::Error, format!("Could not load the model {}: {}.{keep}", project::shown_path(dir), first_line(error)));
        if let Some(m) = &self.engine.model {
            self.panels.fields.model_path = m.dir.display().to_string();
        }
    }

    /// The first frames of the take being made, on screen as they come: playback goes on
    /// over them (and waits at their end, [`super::transport::Playback::advance`]).
    fn take_streamed(&mut self, take: Arc<Take>) {
        if self.engine.pending.is_some_and(|(id, _)| id == take.id) {
            self.show_take(take);
        }
    }

    /// A new take on screen; the one before it kept for comparison.
    fn take_generated(&mut self, take: Arc<Take>) {
        if self.engine.pending.is_some_and(|(id, _)| id == take.id) {
            self.engine.pending = None;
        }
        self.engine.generation_error = None;
        self.messages.resolve(Topic::Generation);
        self.messages.resolve(Topic::Stale);
        self.show_warnings(&take.warnings);
        self.show_take(take);
    }

    /// Puts `take` on screen. The take before it is kept for comparison, unless it was this
    /// one's first frames or another document's.
    fn show_take(&mut self, take: Arc<Take>) {
        let frames = take.motion.frames();
        let id = take.id;
        let keep = !std::mem::take(&mut self.engine.document_closed);
        if let Some(old) = self.engine.take.replace(take).filter(|old| old.id != id && keep) {
            let white = Arc::new(vec![PREVIOUS_TAKE_COLOR; old.motion.frames()]);
            self.engine.previous = Some((old, white));
        }
        self.playback.clamp(frames);
    }

    fn generation_failed(&mut self, id: u64, error: String, cancelled: bool) {
        if self.engine.pending.is_some_and(|(p, _)| p == id) {
            self.engine.pending = None;
        }
        if !cancelled {
            let shown = if self.engine.take.is_some() { " The viewport shows the previous take, marked out of date." } else { "" };
            self.messages.set(Topic::Generation, Level::Error, format!("Generation failed: {error}.{shown}"));
            self.engine.generation_error = Some(error);
        }
    }

    /// The seed-map path of take `id`, made once the map exists.
    fn place_take(&mut self, id: u64, path: Vec<[f32; 2]>) {
        if let Some(t) = self.engine.take.as_mut().filter(|t| t.id == id) {
            if let Some(t) = Arc::get_mut(t) {
                t.path = path;
            } else {
                *t = Arc::new(Take { path, ..Take::clone(t) });
            }
        }
    }

    /// An initial-pose file that starts a take on this model: the take starts from it.
    fn init_checked(&mut self, init: InitPose) {
        let name = match &init {
            InitPose::File { path, frame, .. } => format!("{} from frame {frame}", project::shown_path(path)),
            _ => String::new(),
        };
        self.engine.init_after_switch = false;
        self.edit(|d| d.options.init = init);
        self.panels.init_tab = InitTab::File;
        self.messages.set(Topic::Init, Level::Info, format!("Initial pose: {name}"));
    }

    /// The initial-pose file does not fit the model just loaded: the take starts from a
    /// typical pose of its first segment's class instead.
    fn init_does_not_fit(&mut self, error: &str) {
        self.engine.init_after_switch = false;
        let dataset = self.engine.model.as_ref().map_or_else(String::new, |m| m.spec.dataset.clone());
        let first = self.editing.doc.options.timeline.segments.first().and_then(|s| self.engine.model.as_ref().and_then(|m| m.spec.class_index(&s.class).ok())).unwrap_or(0);
        self.set_init_class(first, 0);
        self.switch_settled();
        let class = match &self.editing.doc.options.init {
            InitPose::SeedClass { class, .. } => class.clone(),
            _ => String::new(),
        };
        self.messages.set(Topic::Init, Level::Info, format!("The initial-pose file does not fit the {dataset} model ({}): the take now starts from a typical '{class}' pose", first_line(error)));
    }

    fn model_loaded(&mut self, info: Arc<ModelInfo>) {
        let previous = self.engine.model.take();
        // A switch the user asked for is carried over as one undo step; any other load (the
        // first, a project's model, an undo's) finds the document already on this model.
        let switched_from = previous.clone().filter(|p| std::mem::take(&mut self.engine.switching) && p.dir != info.dir);
        self.engine.model_loading = None;
        self.engine.map = None;
        self.engine.map_error = None;
        if switched_from.is_none() {
            self.editing.doc.model = info.dir.clone();
        }
        self.panels.fields.model_path = info.dir.display().to_string();
        if self.editing.doc.options.timeline.segments.is_empty() {
            self.editing.doc.options.timeline = Document::default_timeline(&info.spec.classes);
        }
        if previous.is_none() && self.editing.saved.as_ref().is_some_and(|s| s.options.timeline.segments.is_empty()) {
            // The first model of a fresh start: its default timeline is not unsaved work.
            self.editing.mark_saved();
        }
        match &switched_from {
            Some(from) => self.carry_over(from, &info),
            None => {
                self.carry_classes(&info);
                self.carry_init(&info);
            }
        }
        self.panels.fields.new_class = self.panels.fields.new_class.min(info.spec.classes.len().saturating_sub(1));
        self.panels.fields.seed_index = self.panels.fields.seed_index.min(info.seeds.len().saturating_sub(1));
        if previous.is_some() {
            self.messages.set(Topic::Model, Level::Info, format!("Loaded model {} ({})", project::shown_path(&info.dir), info.spec.dataset));
        } else {
            self.messages.resolve(Topic::Model);
        }
        self.engine.model = Some(info);
        self.engine.previous = None;
        self.engine.requested = None;
        self.engine.generation_error = None;
        self.engine.regen_at = Some(self.now);
    }

    /// Asks for a new take when the options changed and the pause is over.
    pub(super) fn schedule(&mut self, ctx: &egui::Context) {
        let Some(model) = &self.engine.model else { return };
        // Not while another model loads (the request would reach it), nor before the
        // initial-pose file has been checked against a new model.
        if model.dir != self.editing.doc.model || self.engine.model_loading.is_some() || self.engine.init_after_switch {
            return;
        }
        let options = self.editing.take_request().options;
        if self.engine.requested.as_ref() != Some(&options) && self.engine.auto_regen && self.engine.regen_at.is_none() {
            self.engine.regen_at = Some(self.now + DEBOUNCE);
        }
        if let Some(at) = self.engine.regen_at {
            if self.now >= at {
                self.engine.regen_at = None;
                if self.engine.requested.as_ref() != Some(&options) || self.engine.take.is_none() {
                    self.regenerate();
                }
            } else {
                ctx.request_repaint_after(std::time::Duration::from_secs_f64(at - self.now));
            }
        }
    }

    /// Generates now with the document's request.
    pub fn regenerate(&mut self) {
        if self.engine.model.is_none() {
            return;
        }
        self.hold_for_regeneration();
        let request = self.editing.take_request();
        self.engine.generate(request);
    }

    pub fn cancel(&mut self) {
        self.engine.cancel();
    }
}
