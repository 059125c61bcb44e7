//! A BVH of another humanoid skeleton as a start pose or a key: the worker retargets a frame
//! of it onto the model, the studio shows the source and the retargeted pose side by side
//! ("Use" / "Cancel"), and where the names do not match a small editor maps the model's key
//! joints onto the file's joints. The mapping is saved in the project
//! ([`crate::synth::Document::joint_map`]) and used when generating.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use egui::RichText;

use super::app::{InitTab, StudioApp};
use super::messages::{Level, Topic};
use super::project;
use super::viewport::Layer;
use super::worker::Reply;
use crate::data::bvh::read_bvh;
use crate::data::input::{read_text, MAX_MOTION_BYTES};
use crate::data::joint_map::{guess_key_joints, UserJointMap};
use crate::model::spec::ModelSpec;
use crate::motion::{Key as JointKey, Motion, Skeleton};
use crate::synth::constraints::KeySource;
use crate::synth::rig::{entries_for, onto_model};
use crate::synth::project::user_joint_map;
use crate::synth::{GenerateOptions, InitPose};

/// Where a retargeted file goes once the user takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PreviewFor {
    Init,
    Key,
}

/// The joints of a foreign file and the joint each key would take (the mapping's guesses,
/// then the name table's), what the mapping editor starts from.
#[derive(Clone, Debug, Default)]
pub struct SourceJoints {
    pub names: Vec<String>,
    pub guesses: Vec<(JointKey, Option<String>)>,
}

/// A frame of a foreign BVH and the same frame on the model's joints: the pose a take from
/// it starts with.
pub struct RetargetPreview {
    pub purpose: PreviewFor,
    pub path: PathBuf,
    pub frame: usize,
    /// One frame each.
    pub source: Arc<Motion>,
    pub retargeted: Arc<Motion>,
    pub joints: SourceJoints,
}

/// A foreign BVH that could not be retargeted (the engine's message names the missing keys).
pub struct RetargetFailure {
    pub purpose: PreviewFor,
    pub path: PathBuf,
    pub frame: usize,
    pub error: String,
    pub joints: SourceJoints,
}

/// The mapping editor's state: a joint of the file (or none: found automatically) per key.
pub struct JointMapEditor {
    purpose: PreviewFor,
    path: PathBuf,
    frame: usize,
    joints: Vec<String>,
    choices: Vec<(JointKey, Option<String>)>,
}

/// What the studio shows of a retarget: at most one of each.
#[derive(Default)]
pub struct RigState {
    pub preview: Option<Arc<RetargetPreview>>,
    pub failure: Option<Arc<RetargetFailure>>,
    pub editor: Option<JointMapEditor>,
}

fn is_bvh(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("bvh"))
}

/// Neither the model's joints nor its dataset's: a skeleton to retarget.
fn is_foreign(spec: &ModelSpec, skeleton: &Skeleton) -> bool {
    !skeleton.differences(&spec.layout.skeleton).is_empty() && !skeleton.differences(&spec.source_skeleton).is_empty()
}

fn source_joints(skeleton: &Skeleton, map: Option<&UserJointMap>) -> SourceJoints {
    let guessed = guess_key_joints(skeleton);
    let names = skeleton.names().to_vec();
    let guesses = JointKey::ALL
        .into_iter()
        .map(|key| {
            let mapped = map.and_then(|m| m.entries.iter().find(|(_, k)| *k == key)).map(|(joint, _)| joint.clone());
            (key, mapped.or_else(|| guessed.get(key).map(|j| names[j].clone())))
        })
        .collect();
    SourceJoints { names, guesses }
}

/// The worker's answer to a retarget request.
pub fn preview(spec: &ModelSpec, purpose: PreviewFor, path: PathBuf, frame: usize, map: Option<&UserJointMap>) -> Reply {
    if !is_bvh(&path) {
        return Reply::NotForeign { purpose, path, frame };
    }
    let name = path.display().to_string();
    let failed = |path: PathBuf, error: String, joints: SourceJoints| Reply::RetargetFailed(Arc::new(RetargetFailure { purpose, path, frame, error, joints }));
    let source = match read_text(&path, MAX_MOTION_BYTES).and_then(|text| Ok(read_bvh(&text, &name)?)) {
        Ok(m) if m.frames() > 0 => m,
        Ok(_) => return failed(path, format!("{name}: the file has no frames"), SourceJoints::default()),
        Err(e) => return failed(path, format!("{e:#}"), SourceJoints::default()),
    };
    if !is_foreign(spec, &source.skeleton) {
        return Reply::NotForeign { purpose, path, frame };
    }
    let map = map.map(|m| entries_for(m, &source.skeleton));
    let joints = source_joints(&source.skeleton, map.as_ref());
    match onto_model(spec, &source, &name, map.as_ref()) {
        Ok(on_model) if on_model.frames() > 0 => {
            // The pose a take starts from: `frame` counts the model's frames (the file is read
            // at the model's rate), and the first block ends one stride after it.
            let g = (frame + spec.stride).min(on_model.frames() - 1);
            let f = ((g as f32 / on_model.fps * source.fps).round() as usize).min(source.frames() - 1);
            let (source, retargeted) = (Arc::new(source.slice(f, f + 1)), Arc::new(on_model.slice(g, g + 1)));
            Reply::Retargeted(Arc::new(RetargetPreview { purpose, path, frame, source, retargeted, joints }))
        }
        Ok(_) => failed(path, format!("{name}: no frames left after retargeting"), joints),
        Err(e) => failed(path, format!("{e:#}"), joints),
    }
}

/// Whether the start or a key of `options` comes from `path`.
fn uses_file(options: &GenerateOptions, path: &Path) -> bool {
    let is_it = |init: &InitPose| matches!(init, InitPose::File { path: p, .. } if p == path);
    is_it(&options.init) || options.keys.iter().any(|k| matches!(&k.source, KeySource::Init(init) if is_it(init)))
}

/// Where the preview puts a pose: its root over (`x`, 0), whatever the file's world.
fn beside(motion: &Motion, x: f32) -> glam::Vec3 {
    let root = motion.frame(0).first().copied().unwrap_or_default() * motion.skeleton.meters_per_unit();
    glam::Vec3::new(x - root.x, 0.0, -root.z)
}

/// The engine's message as the studio says it: the mapping is made in the editor here.
fn studio_wording(error: &str) -> String {
    super::app::first_line(error).replace("name them in a --joint-map file", "name them with Edit mapping…")
}

/// Colours of the preview: the file's skeleton, and the model's pose.
pub const SOURCE_COLOR: [u8; 3] = [235, 150, 60];
pub const RETARGETED_COLOR: [u8; 3] = [90, 170, 240];

impl StudioApp {
    /// The retarget preview on screen, if any.
    pub fn retarget_preview(&self) -> Option<&RetargetPreview> {
        self.rig.preview.as_deref()
    }

    /// Asks the worker to retarget a frame of `path` (a BVH of another skeleton gets a
    /// preview; any other file goes on as before).
    pub(super) fn retarget_file(&mut self, purpose: PreviewFor, path: PathBuf, frame: usize) {
        let map = self.doc.joint_map.as_ref().map(user_joint_map);
        self.worker.retarget(purpose, path, frame, map);
    }

    /// Handles the worker's retarget replies.
    pub(super) fn retarget_reply(&mut self, reply: Reply) {
        match reply {
            Reply::Retargeted(preview) => {
                self.rig.failure = None;
                self.messages.set(Topic::Init, Level::Info, format!("{}: retargeted onto the model; check the preview and Use it", project::shown_path(&preview.path)));
                self.rig.preview = Some(preview);
            }
            Reply::RetargetFailed(failure) => {
                self.rig.preview = None;
                self.messages.set(Topic::Init, Level::Error, format!("That file cannot be mapped onto the model: {}", studio_wording(&failure.error)));
                self.rig.failure = Some(failure);
            }
            Reply::NotForeign { purpose: PreviewFor::Init, path, frame } => self.use_init_file(path, frame),
            Reply::NotForeign { purpose: PreviewFor::Key, path, frame } => self.add_key_from_file(path, frame),
            _ => {}
        }
    }

    /// The preview's viewport layers, while a preview is on screen.
    pub(super) fn preview_layers(&self) -> Option<Vec<Layer>> {
        self.rig.preview.as_ref().map(|p| p.layers())
    }

    /// The preview, failure and mapping-editor windows.
    pub(super) fn rig_windows(&mut self, ctx: &egui::Context) {
        self.preview_window(ctx);
        self.failure_window(ctx);
        self.editor_window(ctx);
    }

    fn preview_window(&mut self, ctx: &egui::Context) {
        let Some(p) = self.rig.preview.clone() else { return };
        egui::Window::new("Retargeted pose").collapsible(false).resizable(false).anchor(egui::Align2::RIGHT_TOP, egui::vec2(-16.0, 40.0)).show(ctx, |ui| {
            ui.label(format!("{} @ {}", project::shown_path(&p.path), p.frame));
            ui.label(RichText::new("Left, orange: the file's skeleton").color(super::timeline::color32(SOURCE_COLOR)));
            ui.label(RichText::new("Right, blue: the model's pose").color(super::timeline::color32(RETARGETED_COLOR)));
            ui.horizontal(|ui| {
                if ui.button("Use").clicked() {
                    self.rig.preview = None;
                    self.use_retargeted(p.purpose, p.path.clone(), p.frame);
                }
                if ui.button("Edit mapping…").clicked() {
                    self.rig.editor = Some(JointMapEditor::new(p.purpose, &p.path, p.frame, &p.joints));
                }
                if ui.button("Cancel").clicked() {
                    self.rig.preview = None;
                    self.messages.resolve(Topic::Init);
                }
            });
        });
    }

    fn failure_window(&mut self, ctx: &egui::Context) {
        let Some(f) = self.rig.failure.clone() else { return };
        egui::Window::new("Cannot map the skeleton").collapsible(false).resizable(false).anchor(egui::Align2::RIGHT_TOP, egui::vec2(-16.0, 40.0)).show(ctx, |ui| {
            ui.set_max_width(420.0);
            ui.label(studio_wording(&f.error));
            ui.horizontal(|ui| {
                if ui.add_enabled(!f.joints.names.is_empty(), egui::Button::new("Edit mapping…")).clicked() {
                    self.rig.editor = Some(JointMapEditor::new(f.purpose, &f.path, f.frame, &f.joints));
                }
                if ui.button("Cancel").clicked() {
                    self.rig.failure = None;
                }
            });
        });
    }

    fn editor_window(&mut self, ctx: &egui::Context) {
        let Some(editor) = self.rig.editor.as_mut() else { return };
        let mut action = None;
        egui::Window::new("Joint mapping").collapsible(false).resizable(false).anchor(egui::Align2::CENTER_CENTER, egui::vec2(0.0, 0.0)).show(ctx, |ui| {
            ui.label(RichText::new("The file's joint for each of the model's key joints").weak());
            egui::Grid::new("joint-mapping").num_columns(2).show(ui, |ui| {
                for (key, choice) in &mut editor.choices {
                    // Tall enough for a whole skeleton's names without scrolling.
                    egui::ComboBox::from_label(key.name()).height(600.0).selected_text(choice.as_deref().unwrap_or("(none)")).show_ui(ui, |ui| {
                        ui.selectable_value(choice, None, "(none)");
                        for joint in &editor.joints {
                            ui.selectable_value(choice, Some(joint.clone()), joint);
                        }
                    });
                    ui.end_row();
                }
            });
            ui.horizontal(|ui| {
                if ui.button("Apply").clicked() {
                    action = Some(true);
                }
                if ui.button("Close").clicked() {
                    action = Some(false);
                }
            });
        });
        match action {
            Some(true) => self.apply_joint_map(),
            Some(false) => self.rig.editor = None,
            None => {}
        }
    }

    /// Saves the editor's mapping in the project and retargets the file with it again.
    fn apply_joint_map(&mut self) {
        let Some(editor) = self.rig.editor.take() else { return };
        let map: BTreeMap<String, String> = editor.choices.iter().filter_map(|(key, joint)| Some((joint.clone()?, key.name().to_string()))).collect();
        self.edit(|d| d.joint_map = Some(map));
        if uses_file(&self.doc.options, &editor.path) {
            // The options are unchanged but the take from this file is not: generate again.
            self.requested = None;
        }
        self.retarget_file(editor.purpose, editor.path, editor.frame);
    }

    fn use_retargeted(&mut self, purpose: PreviewFor, path: PathBuf, frame: usize) {
        match purpose {
            PreviewFor::Init => {
                self.fields.init_path = path.display().to_string();
                let name = format!("{} from frame {frame}", project::shown_path(&path));
                self.edit(|d| d.options.init = InitPose::file(path, frame));
                self.init_tab = InitTab::File;
                self.messages.set(Topic::Init, Level::Info, format!("Initial pose: {name} (retargeted)"));
            }
            PreviewFor::Key => {
                self.messages.resolve(Topic::Init);
                self.add_key_from_file(path, frame);
            }
        }
    }
}

impl RetargetPreview {
    /// The two poses for the viewport: the file's on the left, the model's on the right.
    pub fn layers(&self) -> Vec<Layer> {
        let layer = |motion: &Arc<Motion>, x: f32, color: [u8; 3]| Layer { motion: motion.clone(), frame_colors: Arc::new(vec![color]), offset: beside(motion, x), opacity: 1.0, contacts: None };
        vec![layer(&self.source, -0.6, SOURCE_COLOR), layer(&self.retargeted, 0.6, RETARGETED_COLOR)]
    }
}

impl JointMapEditor {
    fn new(purpose: PreviewFor, path: &Path, frame: usize, joints: &SourceJoints) -> Self {
        Self { purpose, path: path.to_path_buf(), frame, joints: joints.names.clone(), choices: joints.guesses.clone() }
    }
}
