//! The editing state: the document, its undo history, what was last saved, and what is
//! selected in it.

use std::path::PathBuf;

use super::project::{History, Project};
use super::timeline::Mark;
use crate::synth::model_switch::ModelSwitch;
use crate::synth::Request as TakeRequest;

pub struct Editing {
    pub(super) doc: Project,
    pub(super) history: History,
    /// The document as last saved, opened or started: unsaved work is what differs from it.
    /// None when no file holds the document (work restored from the autosave that its
    /// project file lacks): all of it is unsaved until it is saved.
    pub(super) saved: Option<Project>,
    /// Where the document was last saved or opened from.
    pub(super) project_path: Option<PathBuf>,
    /// An edit (e.g. a drag) is under way and has been recorded in the history.
    pub(super) edit_open: bool,
    /// The selected segment.
    pub(super) selected: Option<usize>,
    /// The key or waypoint selected on its track.
    pub(super) selected_mark: Option<Mark>,
    /// The model switches made, so a switch back restores what the first one changed.
    pub(super) switches: Vec<ModelSwitch>,
}

impl Editing {
    /// `doc` to edit; `saved` is what counts as no unsaved work.
    pub fn new(doc: Project, saved: Option<Project>, project_path: Option<PathBuf>) -> Self {
        Self { doc, history: History::default(), saved, project_path, edit_open: false, selected: None, selected_mark: None, switches: Vec::new() }
    }

    /// Replaces the document by `f(doc)` as one undoable edit.
    pub fn edit(&mut self, f: impl FnOnce(&mut Project)) {
        let before = self.doc.clone();
        f(&mut self.doc);
        if self.doc.options != before.options {
            self.history.record(before);
        }
    }

    /// Steps the document back; false when there is nothing to undo.
    pub fn undo(&mut self) -> bool {
        let stepped = self.history.undo(&mut self.doc);
        if stepped {
            self.after_history_step();
        }
        stepped
    }

    /// Steps the document forward again; false when there is nothing to redo.
    pub fn redo(&mut self) -> bool {
        let stepped = self.history.redo(&mut self.doc);
        if stepped {
            self.after_history_step();
        }
        stepped
    }

    /// Keeps the selection to what the document still has.
    fn after_history_step(&mut self) {
        let n = self.doc.options.timeline.segments.len();
        self.selected = self.selected.filter(|&k| k < n);
        self.selected_mark = None;
    }

    /// What the engine is asked to generate: the document's request, where a path of one
    /// waypoint (while it is being drawn) is no path yet, and locks (the studio's, not the
    /// engine's) are left out, so locking a segment generates nothing.
    pub fn take_request(&self) -> TakeRequest {
        let mut request = self.doc.request();
        if request.options.path.as_ref().is_some_and(|p| p.waypoints.len() < 2) {
            request.options.path = None;
        }
        request.options.timeline.segments.iter_mut().for_each(|s| s.locked = false);
        request
    }

    /// Whether the document differs from what was last saved, opened or started.
    pub fn has_unsaved_work(&self) -> bool {
        self.saved.as_ref().is_none_or(|saved| !self.doc.same_take(saved))
    }

    /// The document as it is now counts as saved (it was saved, or is a fresh start).
    pub fn mark_saved(&mut self) {
        self.saved = Some(self.doc.clone());
    }
}
