//! The engine's side of the studio: the worker that owns the model, what the UI knows of the
//! model and its seed map, the takes it made, and the generation under way.

use std::path::PathBuf;
use std::sync::Arc;

use super::worker::{ModelInfo, SeedMap, Take, Worker};
use crate::synth::{GenerateOptions, Request as TakeRequest};

/// Edits regenerate after this pause (seconds).
pub const DEBOUNCE: f64 = 0.3;

/// The previous take's overlay colour: white, unlike any class colour (ghosts keep theirs).
pub const PREVIOUS_TAKE_COLOR: [u8; 3] = [245, 245, 245];

pub struct Engine {
    pub(super) worker: Worker,
    pub(super) model: Option<Arc<ModelInfo>>,
    /// The model folder being loaded, if any.
    pub(super) model_loading: Option<PathBuf>,
    pub(super) map: Option<Arc<SeedMap>>,
    pub(super) map_error: Option<String>,
    pub(super) take: Option<Arc<Take>>,
    /// The take before the current one, for comparison, and its overlay colours.
    pub(super) previous: Option<(Arc<Take>, Arc<Vec<[u8; 3]>>)>,
    /// Id and progress of the generation under way.
    pub(super) pending: Option<(u64, f32)>,
    /// Options of the last generation asked for.
    pub(super) requested: Option<GenerateOptions>,
    /// Why the last generation failed (the take on screen is then older than the document).
    pub(super) generation_error: Option<String>,
    /// When the pause after an edit is over and the take is generated again.
    pub(super) regen_at: Option<f64>,
    pub(super) auto_regen: bool,
    /// An initial-pose file is being checked against a newly loaded model.
    pub(super) init_after_switch: bool,
    /// The model being loaded is a switch the user asked for ([`super::app::StudioApp::switch_model`]).
    pub(super) switching: bool,
    /// Another document replaced the take's (File > New or Open): the next take does not keep
    /// the one on screen as the previous take, so a closed take's memory is given back.
    pub(super) document_closed: bool,
}

impl Engine {
    /// The document on screen was closed: its takes are not compared with the next.
    pub fn close_document(&mut self) {
        self.previous = None;
        self.document_closed = true;
    }

    /// The worker, loading the model in `model_dir`.
    pub fn new(mut worker: Worker, model_dir: PathBuf) -> Self {
        worker.load_model(model_dir.clone());
        Self {
            worker,
            model: None,
            model_loading: Some(model_dir),
            map: None,
            map_error: None,
            take: None,
            previous: None,
            pending: None,
            requested: None,
            generation_error: None,
            regen_at: None,
            auto_regen: true,
            init_after_switch: false,
            switching: false,
            document_closed: false,
        }
    }

    /// Whether the worker still has something to do for the UI (loading, generating, or a
    /// regeneration waiting for its pause).
    pub fn is_busy(&self) -> bool {
        self.model_loading.is_some() || self.pending.is_some() || self.regen_at.is_some()
    }

    /// The loaded model's classes (none before a model is loaded).
    pub fn classes(&self) -> &[String] {
        self.model.as_ref().map_or(&[], |m| m.spec.classes.as_slice())
    }

    /// The styles the model is conditioned on (none for a model without styles).
    pub fn styles(&self) -> &[String] {
        self.model.as_ref().map_or(&[], |m| m.spec.styles.as_slice())
    }

    /// Asks the worker for the take of `request`, cancelling any older one.
    pub fn generate(&mut self, request: TakeRequest) {
        self.requested = Some(request.options.clone());
        let id = self.worker.generate(request);
        self.generation_error = None;
        self.pending = Some((id, 0.0));
        self.regen_at = None;
    }

    /// Stops the generation under way and any waiting for its pause.
    pub fn cancel(&mut self) {
        self.worker.cancel();
        self.pending = None;
        self.regen_at = None;
    }
}
