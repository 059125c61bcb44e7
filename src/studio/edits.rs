//! Edits of the document: segments, the initial pose, what the timeline widget reports, and
//! the undo history they go into; the keyboard shortcuts.

use std::path::PathBuf;

use egui::{Key, KeyboardShortcut, Modifiers};

use super::app::StudioApp;
use super::messages::{Level, Topic};
use super::panels::InitTab;
use super::project::Project;
use super::timeline::{Action, MIN_SECONDS};
use crate::synth::{InitPose, Segment};

impl StudioApp {
    /// Replaces the document by `f(doc)` as one undoable edit.
    pub fn edit(&mut self, f: impl FnOnce(&mut Project)) {
        self.editing.edit(f);
    }

    pub fn undo(&mut self) {
        if self.editing.undo() {
            self.after_history_step();
        } else {
            self.messages.info("Nothing to undo");
        }
    }

    pub fn redo(&mut self) {
        if self.editing.redo() {
            self.after_history_step();
        } else {
            self.messages.info("Nothing to redo");
        }
    }

    /// The panels as the document stepped to says, and its model loaded if it is another
    /// (undoing a model switch).
    fn after_history_step(&mut self) {
        self.viewport.forget_posed();
        self.panels.init_tab = InitTab::of(&self.editing.doc.options.init);
        let loaded = self.engine.model_loading.as_ref().or(self.engine.model.as_ref().map(|m| &m.dir));
        if loaded != Some(&self.editing.doc.model) {
            let dir = self.editing.doc.model.clone();
            self.load_model(dir);
        }
    }

    /// Adds a segment of the class chosen in the UI after the selected one (or at the end).
    pub fn add_segment(&mut self) {
        let Some(class) = self.classes().get(self.panels.fields.new_class).or(self.classes().first()).cloned() else {
            self.messages.error("Load a model before adding segments");
            return;
        };
        let at = self.editing.selected.map_or(self.editing.doc.options.timeline.segments.len(), |k| k + 1).min(self.editing.doc.options.timeline.segments.len());
        self.edit(|d| d.options.timeline.segments.insert(at, Segment::new(class, 3.0)));
        self.editing.selected = Some(at);
    }

    pub fn delete_segment(&mut self, k: usize) {
        if k < self.editing.doc.options.timeline.segments.len() {
            self.edit(|d| {
                d.options.timeline.segments.remove(k);
            });
            let n = self.editing.doc.options.timeline.segments.len();
            self.editing.selected = self.editing.selected.filter(|&s| s < n);
        }
    }

    /// A new variation of segment `k` alone: a fresh seed of its own (the rest of the take is
    /// kept, see `hold`).
    pub fn reroll_segment(&mut self, k: usize) {
        if k < self.editing.doc.options.timeline.segments.len() {
            let seed = u64::from(rand::random::<u32>()) + 1;
            self.edit(|d| d.options.timeline.segments[k].seed = Some(seed));
        }
    }

    pub fn set_segment_class(&mut self, k: usize, class: &str) {
        if k < self.editing.doc.options.timeline.segments.len() {
            self.edit(|d| d.options.timeline.segments[k].class = class.to_string());
        }
    }

    /// Chooses where the take starts from, as the Initial pose tabs do: the tab's choice is
    /// applied at once. "By class" starts from the class's most typical seed window (the
    /// first segment's class unless one is chosen).
    pub fn set_init_tab(&mut self, tab: InitTab) {
        self.panels.init_tab = tab;
        let Some(model) = self.engine.model.clone() else { return };
        match tab {
            InitTab::Class => {
                if !matches!(self.editing.doc.options.init, InitPose::SeedClass { .. }) {
                    let first = self.editing.doc.options.timeline.segments.first().and_then(|s| model.spec.class_index(&s.class).ok()).unwrap_or(0);
                    self.set_init_class(first, 0);
                }
            }
            InitTab::Seed => self.editing.doc.options.init = InitPose::SeedIndex(self.panels.fields.seed_index.min(model.seeds.len().saturating_sub(1))),
            InitTab::File => {
                if self.panels.fields.init_path.trim().is_empty() {
                    self.messages.set(Topic::Init, Level::Info, "Choose a motion file: the take starts from it once it has been checked");
                } else if !matches!(self.editing.doc.options.init, InitPose::File { .. }) {
                    let p = PathBuf::from(self.panels.fields.init_path.trim());
                    self.use_init_file(p, self.panels.fields.init_frame);
                }
            }
        }
    }

    /// Starts the take from the `rank`-th most typical seed window of `class`.
    pub fn set_init_class(&mut self, class: usize, rank: usize) {
        let Some(model) = self.engine.model.clone() else { return };
        let Some(name) = model.spec.classes.get(class).cloned() else { return };
        self.panels.init_tab = InitTab::Class;
        self.editing.doc.options.init = InitPose::SeedClass { class: name, variant: model.typical_variant(class, rank) };
    }

    /// Applies what the timeline widget reports.
    pub(super) fn apply_timeline(&mut self, actions: Vec<Action>) {
        let frames = self.engine.take.as_ref().map_or(0, |t| t.motion.frames());
        for a in actions {
            match a {
                Action::Select(k) => {
                    self.editing.selected = k;
                    self.editing.selected_mark = None;
                }
                Action::BeginEdit => {
                    self.editing.history.record(self.editing.doc.clone());
                    self.editing.edit_open = true;
                }
                Action::Resize { index, seconds } => {
                    if let Some(s) = self.editing.doc.options.timeline.segments.get_mut(index) {
                        s.seconds = seconds.max(MIN_SECONDS);
                    }
                }
                Action::Move { from, to } => {
                    let n = self.editing.doc.options.timeline.segments.len();
                    if from < n && to < n {
                        let s = self.editing.doc.options.timeline.segments.remove(from);
                        self.editing.doc.options.timeline.segments.insert(to, s);
                        self.editing.selected = Some(to);
                    }
                }
                Action::SetClass { index, class } => self.set_segment_class(index, &class),
                Action::Duplicate(k) => {
                    if let Some(s) = self.editing.doc.options.timeline.segments.get(k).cloned() {
                        self.edit(|d| d.options.timeline.segments.insert(k + 1, s));
                        self.editing.selected = Some(k + 1);
                    }
                }
                Action::Delete(k) => self.delete_segment(k),
                Action::Reroll(k) => self.reroll_segment(k),
                Action::ToggleLock(k) => {
                    if k < self.editing.doc.options.timeline.segments.len() {
                        self.edit(|d| d.options.timeline.segments[k].locked ^= true);
                    }
                }
                Action::Seek(f) => {
                    self.playback.playing = false;
                    self.playback.seek(f, frames);
                }
                Action::SetSelection(s) => self.playback.selection = s,
                Action::SelectMark(m) => {
                    self.editing.selected_mark = m;
                    self.editing.selected = None;
                }
                Action::MoveMark { mark, seconds } => self.move_mark(mark, seconds),
                Action::DeleteMark(m) => self.delete_mark(m),
                Action::ClearWaypointTime(k) => self.clear_waypoint_time(k),
            }
        }
    }

    /// Closes the open edit once the pointer is released, and records edits made by
    /// ordinary widgets this frame as one undo step each.
    pub(super) fn finish_edits(&mut self, ctx: &egui::Context, before: Project) {
        if self.editing.doc.options != before.options && !self.editing.edit_open {
            self.editing.history.record(before);
            self.editing.edit_open = true;
        }
        if ctx.input(|i| !i.pointer.any_down()) {
            self.editing.edit_open = false;
        }
    }

    /// Says when the model will not follow the timeline as written, once per piece of
    /// advice (the fixes are in the sidebar).
    pub(super) fn advise(&mut self) {
        let found = super::advice::seated_too_short(&self.editing.doc.options.timeline, self.classes());
        let advice = found.first().map(|short| format!("{} The sidebar proposes a fix.", short.message()));
        if advice == self.panels.advised {
            return;
        }
        match &advice {
            Some(text) => self.messages.set(Topic::Advice, Level::Info, text.clone()),
            None => self.messages.resolve(Topic::Advice),
        }
        self.panels.advised = advice;
    }

    pub(super) fn shortcuts(&mut self, ctx: &egui::Context) {
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
        let frames = self.engine.take.as_ref().map_or(0, |t| t.motion.frames());
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
            self.playback.toggle(frames, &self.editing.doc.playback);
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
            if let Some(mark) = self.editing.selected_mark {
                self.delete_mark(mark);
            } else if let Some(k) = self.editing.selected {
                self.delete_segment(k);
            }
        }
    }
}
