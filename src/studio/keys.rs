//! Keys and the root path in the studio: the edits (each one undoable, saved in the
//! project's [`GenerateOptions`](crate::synth::GenerateOptions)), the sidebar section that
//! makes them, and the viewport's path-drawing and posing modes. The engine applies them; the
//! studio only edits the document and shows what the take could not do.

use std::path::PathBuf;

use egui::{RichText, Slider};

use super::app::StudioApp;
use super::panels::ViewportTool;
use super::dialogs::Purpose;
use super::messages::{Level, Topic};
use super::timeline::{color32, waypoint_times, Mark, KEY_COLOR, PATH_COLOR};
use super::viewport::{PathEdit, PosedFrame};
use super::worker::ModelInfo;
use crate::motion::JointRoles;
use crate::synth::constraints::{Key, KeySource, RootPath, Waypoint, MIN_KEY_GAP_SECONDS};
use crate::synth::render::class_color;
use crate::synth::InitPose;

impl StudioApp {
    /// The time of the frame on screen, in seconds from the take's start.
    fn current_seconds(&self) -> f32 {
        let fps = self.engine.take.as_ref().map_or(25.0, |t| t.motion.fps);
        self.playback.frame() as f32 / fps
    }

    /// Adds a key at the current frame, replacing one closer than the engine allows.
    fn add_key(&mut self, source: KeySource, fix_root: bool) {
        self.add_key_at(self.current_seconds(), source, fix_root);
    }

    /// Adds a key at `seconds`, replacing one closer than the engine allows.
    fn add_key_at(&mut self, seconds: f32, source: KeySource, fix_root: bool) {
        let key = Key { seconds, source, fix_root };
        self.edit(|d| {
            d.options.keys.retain(|k| (k.seconds - seconds).abs() >= MIN_KEY_GAP_SECONDS);
            d.options.keys.push(key);
            d.options.keys.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        });
        let index = self.editing.doc.options.keys.iter().position(|k| k.seconds == seconds);
        self.editing.selected_mark = index.map(Mark::Key);
    }

    /// Pins the take's pose at the current frame (where it stands included), so the next
    /// take passes through it.
    pub fn add_key_from_frame(&mut self) {
        let Some(take) = self.engine.take.clone() else {
            self.messages.error("Generate a take before keying one of its frames");
            return;
        };
        let f = self.playback.frame().min(take.motion.frames().saturating_sub(1));
        let pose = take.motion.frame(f).iter().map(|p| p.to_array()).collect();
        self.add_key(KeySource::Pose(pose), true);
    }

    /// A pose made by hand in the viewport as a key at its frame: the body's pose, and where
    /// it stands when the hips were dragged or the key it replaces fixed that too.
    pub(super) fn add_key_from_posed(&mut self, posed: PosedFrame) {
        let Some(fps) = self.engine.take.as_ref().map(|t| t.motion.fps) else { return };
        let seconds = posed.frame as f32 / fps;
        let replaces_root_key = self.editing.doc.options.keys.iter().any(|k| k.fix_root && (k.seconds - seconds).abs() < MIN_KEY_GAP_SECONDS);
        let pose = posed.pose.iter().map(|p| p.to_array()).collect();
        self.add_key_at(seconds, KeySource::Pose(pose), posed.moves_root || replaces_root_key);
    }

    /// A seed-bank pose as a key at the current frame (the body's pose only).
    pub fn add_key_from_seed(&mut self, seed: usize) {
        self.add_key(KeySource::Init(InitPose::SeedIndex(seed)), false);
    }

    /// A frame of a motion file as a key at the current frame (the body's pose only).
    pub fn add_key_from_file(&mut self, path: PathBuf, frame: usize) {
        self.panels.fields.key_path = path.display().to_string();
        self.add_key(KeySource::Init(InitPose::file(path, frame)), false);
    }

    /// Applies a path edit from the viewport.
    pub(super) fn apply_path_edit(&mut self, edit: PathEdit) {
        match edit {
            PathEdit::BeginDrag => {
                self.editing.history.record(self.editing.doc.clone());
                self.editing.edit_open = true;
            }
            PathEdit::Add([x, z]) => {
                // A path starts where the take starts, so one click already makes a path.
                let start = self.editing.doc.options.path.is_none().then(|| self.take_start()).flatten();
                self.edit(|d| {
                    let path = d.options.path.get_or_insert_with(RootPath::default);
                    path.waypoints.extend(start.map(|[x, z]| Waypoint { x, z, seconds: Some(0.0) }));
                    path.waypoints.push(Waypoint { x, z, seconds: None });
                });
                let n = self.editing.doc.options.path.as_ref().map_or(0, |p| p.waypoints.len());
                self.editing.selected_mark = Some(Mark::Waypoint(n - 1));
            }
            PathEdit::Move { index, to: [x, z] } => {
                if let Some(w) = self.editing.doc.options.path.as_mut().and_then(|p| p.waypoints.get_mut(index)) {
                    (w.x, w.z) = (x, z);
                }
                self.editing.selected_mark = Some(Mark::Waypoint(index));
            }
        }
    }

    /// Where the take on screen starts on the ground (x, z), in metres.
    fn take_start(&self) -> Option<[f32; 2]> {
        let motion = &self.engine.take.as_ref().filter(|t| t.motion.frames() > 0)?.motion;
        let root = JointRoles::new(&motion.skeleton).map_or(0, |r| r.body_root);
        let p = *motion.frame(0).get(root)? * motion.skeleton.meters_per_unit();
        Some([p.x, p.z])
    }

    /// Moves a key or a waypoint in time (a waypoint between its timed neighbours).
    pub(super) fn move_mark(&mut self, mark: Mark, seconds: f32) {
        let end = self.editing.doc.options.timeline.seconds();
        let seconds = seconds.clamp(0.0, end);
        match mark {
            Mark::Key(k) => {
                if let Some(key) = self.editing.doc.options.keys.get_mut(k) {
                    key.seconds = seconds;
                }
            }
            Mark::Waypoint(k) => {
                let Some(path) = self.editing.doc.options.path.as_mut() else { return };
                let before = path.waypoints[..k.min(path.waypoints.len())].iter().rev().find_map(|w| w.seconds).map_or(0.0, |t| t + 0.05);
                let after = path.waypoints.iter().skip(k + 1).find_map(|w| w.seconds).map_or(end, |t| t - 0.05);
                if let Some(w) = path.waypoints.get_mut(k) {
                    w.seconds = Some(seconds.clamp(before, after.max(before)));
                }
            }
        }
    }

    pub(super) fn delete_mark(&mut self, mark: Mark) {
        self.edit(|d| match mark {
            Mark::Key(k) if k < d.options.keys.len() => {
                d.options.keys.remove(k);
            }
            Mark::Waypoint(k) => {
                if let Some(path) = d.options.path.as_mut().filter(|p| k < p.waypoints.len()) {
                    path.waypoints.remove(k);
                }
                if d.options.path.as_ref().is_some_and(|p| p.waypoints.is_empty()) {
                    d.options.path = None;
                }
            }
            Mark::Key(_) => {}
        });
        self.editing.selected_mark = None;
    }

    pub(super) fn clear_waypoint_time(&mut self, k: usize) {
        self.edit(|d| {
            if let Some(w) = d.options.path.as_mut().and_then(|p| p.waypoints.get_mut(k)) {
                w.seconds = None;
            }
        });
    }

    /// Each waypoint's time on the timeline: its own, else when the take on screen (made
    /// with this path) comes nearest to it, else spread by arc length ([`waypoint_times`]).
    pub(super) fn waypoint_times(&self) -> Vec<f32> {
        let Some(path) = self.editing.doc.options.path.as_ref() else { return Vec::new() };
        let mut times = waypoint_times(path, self.editing.doc.options.timeline.seconds());
        let Some(take) = self.engine.take.as_ref().filter(|t| t.options.path.as_ref() == Some(path) && t.motion.frames() > 0) else { return times };
        let motion = &take.motion;
        let root = JointRoles::new(&motion.skeleton).map_or(0, |r| r.body_root);
        let mpu = motion.skeleton.meters_per_unit();
        let mut from = 0;
        for (t, w) in times.iter_mut().zip(&path.waypoints) {
            if let Some(own) = w.seconds {
                *t = own;
                from = ((own * motion.fps) as usize).min(motion.frames() - 1);
                continue;
            }
            // The take passes the waypoints in order: search on from the previous one.
            let distance = |f: usize| {
                let p = motion.frame(f)[root] * mpu;
                (p.x - w.x).powi(2) + (p.z - w.z).powi(2)
            };
            from = (from..motion.frames()).min_by(|&a, &b| distance(a).total_cmp(&distance(b))).unwrap_or(from);
            *t = from as f32 / motion.fps;
        }
        times
    }

    /// The sidebar's "Keys and path" section.
    pub(super) fn keys_section(&mut self, ui: &mut egui::Ui) {
        let Some(model) = self.engine.model.clone() else {
            ui.label(RichText::new("Load a model first").weak());
            return;
        };
        self.new_key_buttons(ui, &model);
        let mut delete = None;
        self.key_list(ui, &mut delete);
        ui.separator();
        self.path_controls(ui);
        self.waypoint_list(ui, &mut delete);
        if let Some(mark) = delete {
            self.delete_mark(mark);
        }
        if let Some(take) = &self.engine.take {
            for w in &take.warnings {
                ui.label(RichText::new(w).color(ui.visuals().warn_fg_color));
            }
        }
    }

    /// Keys from the current frame, a file or a seed.
    fn new_key_buttons(&mut self, ui: &mut egui::Ui, model: &ModelInfo) {
        let at = self.current_seconds();
        ui.label(RichText::new(format!("New keys go at the current frame ({at:.2} s)")).weak());
        ui.horizontal_wrapped(|ui| {
            if ui.add_enabled(self.engine.take.is_some(), egui::Button::new("Key from current frame")).on_hover_text("Pin this frame's pose and where it stands: the next take passes through it").clicked() {
                self.add_key_from_frame();
            }
            if ui.button("Key from file…").on_hover_text("A frame of a BVH, NPY or dataset file (the pose only)").clicked() {
                self.open_dialog(Purpose::KeyFile, ui.ctx());
            }
            self.tool_toggle(ui, ViewportTool::Pose, "Pose by hand", "Drag a hand, a foot, the head or the hips in the viewport: the pose becomes a key at this frame");
        });
        if self.panels.tool == ViewportTool::Pose {
            ui.label(RichText::new("Posing: drag a handle (hands and head on the view's plane, feet along the floor, the hips with the feet kept planted); the view orbits from anywhere else").weak().small());
        }
        ui.horizontal(|ui| {
            let max = model.seeds.len().saturating_sub(1);
            ui.add(Slider::new(&mut self.panels.fields.key_seed, 0..=max).text("seed"));
            if ui.button("Key from seed pose").on_hover_text("The seed bank's pose (the pose only)").clicked() {
                self.add_key_from_seed(self.panels.fields.key_seed);
            }
        });
        if let Some(s) = model.seeds.get(self.panels.fields.key_seed) {
            ui.horizontal(|ui| {
                let (r, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
                ui.painter().circle_filled(r.center(), 5.0, color32(class_color(s.class)));
                ui.label(RichText::new(format!("{} · {} @ {}", model.spec.classes[s.class], s.clip, s.frame)).small());
            });
        }
        ui.add(egui::DragValue::new(&mut self.panels.fields.key_frame).range(0..=super::panels::MAX_INIT_FRAME).prefix("file frame "));
    }

    /// The keys, each selectable; its "x" marks it in `delete`.
    fn key_list(&mut self, ui: &mut egui::Ui, delete: &mut Option<Mark>) {
        for (k, key) in self.editing.doc.options.keys.iter().enumerate() {
            let what = match &key.source {
                KeySource::Pose(_) => "take frame".to_string(),
                KeySource::Init(InitPose::SeedIndex(i)) => format!("seed {i}"),
                KeySource::Init(InitPose::SeedClass { class, variant }) => format!("{class} seed {variant}"),
                KeySource::Init(InitPose::File { path, frame, .. }) => format!("{} @ {frame}", path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())),
            };
            ui.horizontal(|ui| {
                let selected = self.editing.selected_mark == Some(Mark::Key(k));
                let label = RichText::new(format!("Key {} at {:.2} s: {what}{}", k + 1, key.seconds, if key.fix_root { ", root" } else { "" })).color(KEY_COLOR);
                if ui.selectable_label(selected, label).clicked() {
                    self.editing.selected_mark = Some(Mark::Key(k));
                }
                if ui.small_button("x").on_hover_text("Delete this key").clicked() {
                    *delete = Some(Mark::Key(k));
                }
            });
        }
    }

    /// Drawing and clearing the root path.
    fn path_controls(&mut self, ui: &mut egui::Ui) {
        let n = self.editing.doc.options.path.as_ref().map_or(0, |p| p.waypoints.len());
        ui.horizontal_wrapped(|ui| {
            self.tool_toggle(ui, ViewportTool::DrawPath, "Draw path", "Click the ground in the viewport to add waypoints, drag one to move it");
            if ui.add_enabled(n > 0, egui::Button::new("Clear path")).clicked() {
                self.edit(|d| d.options.path = None);
                self.editing.selected_mark = None;
            }
            ui.label(RichText::new(format!("{n} waypoints")).color(PATH_COLOR));
        });
        if self.panels.tool == ViewportTool::DrawPath {
            ui.label(RichText::new("Drawing: the path starts where the take starts; click the ground to add a waypoint, drag one to move it (the view orbits from anywhere else)").weak().small());
        }
        if n == 1 {
            ui.label(RichText::new("A path needs a second waypoint").weak().small());
        }
    }

    /// A toggle of one viewport tool (turning it on turns the other off).
    fn tool_toggle(&mut self, ui: &mut egui::Ui, tool: ViewportTool, label: &str, hover: &str) {
        let mut on = self.panels.tool == tool;
        if ui.toggle_value(&mut on, label).on_hover_text(hover).changed() {
            self.panels.tool = if on { tool } else { ViewportTool::Orbit };
        }
    }

    /// The path's waypoints, each selectable with its time; its "x" marks it in `delete`.
    fn waypoint_list(&mut self, ui: &mut egui::Ui, delete: &mut Option<Mark>) {
        let times = self.waypoint_times();
        if let Some(path) = self.editing.doc.options.path.clone() {
            for (k, w) in path.waypoints.iter().enumerate() {
                ui.horizontal(|ui| {
                    let selected = self.editing.selected_mark == Some(Mark::Waypoint(k));
                    let label = RichText::new(format!("Point {}: ({:.2}, {:.2}) m", k + 1, w.x, w.z)).color(PATH_COLOR);
                    if ui.selectable_label(selected, label).clicked() {
                        self.editing.selected_mark = Some(Mark::Waypoint(k));
                    }
                    let mut timed = w.seconds.is_some();
                    if ui.checkbox(&mut timed, "at").on_hover_text("A time of its own; otherwise spread by arc length").changed() {
                        let t = times.get(k).copied().unwrap_or(0.0);
                        self.edit(|d| {
                            if let Some(w) = d.options.path.as_mut().and_then(|p| p.waypoints.get_mut(k)) {
                                w.seconds = timed.then_some(t);
                            }
                        });
                    }
                    if let Some(mut t) = self.editing.doc.options.path.as_ref().and_then(|p| p.waypoints[k].seconds) {
                        if ui.add(egui::DragValue::new(&mut t).range(0.0..=600.0).speed(0.05).suffix(" s").fixed_decimals(2)).changed() {
                            self.move_mark(Mark::Waypoint(k), t);
                        }
                    } else {
                        ui.label(RichText::new(format!("~{:.2} s", times.get(k).copied().unwrap_or(0.0))).weak());
                    }
                    if ui.small_button("x").on_hover_text("Delete this waypoint").clicked() {
                        *delete = Some(Mark::Waypoint(k));
                    }
                });
            }
        }
    }

    /// Shows what the new take could not do as asked (say, a path faster than its class
    /// walks), or withdraws the last such message.
    pub(super) fn show_warnings(&mut self, warnings: &[String]) {
        if warnings.is_empty() {
            self.messages.resolve(Topic::Constraints);
        } else {
            self.messages.set(Topic::Constraints, Level::Info, format!("The take could not do everything asked: {}", warnings.join("; ")));
        }
    }
}
