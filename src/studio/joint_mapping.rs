//! A BVH of another humanoid skeleton as a start pose or a key: the worker retargets a frame
//! of it onto the model, the studio shows the source and the retargeted pose side by side
//! ("Use" / "Cancel"), and where the names do not match a small editor maps the model's key
//! joints onto the file's joints. The mapping is saved in the project
//! ([`crate::synth::Document::joint_map`]) and used when generating.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use egui::RichText;

use super::app::StudioApp;
use super::messages::{first_line, Level, Topic};
use super::panels::InitTab;
use super::project;
use super::retarget::{JointMapEditor, PreviewFor, RetargetPreview, Retargeting, RETARGETED_COLOR, SOURCE_COLOR};
use crate::synth::constraints::KeySource;
use crate::synth::project::user_joint_map;
use crate::synth::{GenerateOptions, InitPose};

/// Whether the start or a key of `options` comes from `path`.
fn uses_file(options: &GenerateOptions, path: &Path) -> bool {
    let is_it = |init: &InitPose| matches!(init, InitPose::File { path: p, .. } if p == path);
    is_it(&options.init) || options.keys.iter().any(|k| matches!(&k.source, KeySource::Init(init) if is_it(init)))
}

/// The engine's message as the studio says it: the mapping is made in the editor here.
fn studio_wording(error: &str) -> String {
    first_line(error).replace("name them in a --joint-map file", "name them with Edit mapping…")
}

impl StudioApp {
    /// The retarget preview on screen, if any.
    pub fn retarget_preview(&self) -> Option<&RetargetPreview> {
        self.panels.rig.preview.as_deref()
    }

    /// Asks the worker to retarget a frame of `path` (a BVH of another skeleton gets a
    /// preview; any other file goes on as before).
    pub(super) fn retarget_file(&mut self, purpose: PreviewFor, path: PathBuf, frame: usize) {
        let map = self.editing.doc.joint_map.as_ref().map(user_joint_map);
        self.engine.worker.retarget(purpose, path, frame, map);
    }

    /// Handles the worker's answer to a retarget request.
    pub(super) fn retarget_reply(&mut self, reply: Retargeting) {
        match reply {
            Retargeting::Previewed(preview) => {
                self.panels.rig.failure = None;
                self.messages.set(Topic::Init, Level::Info, format!("{}: retargeted onto the model; check the preview and Use it", project::shown_path(&preview.path)));
                self.panels.rig.preview = Some(preview);
                self.viewport.frame_all();
            }
            Retargeting::Failed(failure) => {
                self.panels.rig.preview = None;
                self.messages.set(Topic::Init, Level::Error, format!("That file cannot be mapped onto the model: {}", studio_wording(&failure.error)));
                self.panels.rig.failure = Some(failure);
            }
            Retargeting::NotForeign { purpose: PreviewFor::Init, path, frame } => self.use_init_file(path, frame),
            Retargeting::NotForeign { purpose: PreviewFor::Key, path, frame } => self.add_key_from_file(path, frame),
        }
    }

    /// The preview's viewport layers, while a preview is on screen.
    pub(super) fn preview_layers(&self) -> Option<Vec<super::viewport::Layer>> {
        self.panels.rig.preview.as_ref().map(|p| p.layers())
    }

    /// The preview, failure and mapping-editor windows.
    pub(super) fn rig_windows(&mut self, ctx: &egui::Context) {
        self.preview_window(ctx);
        self.failure_window(ctx);
        self.editor_window(ctx);
    }

    fn preview_window(&mut self, ctx: &egui::Context) {
        let Some(p) = self.panels.rig.preview.clone() else { return };
        egui::Window::new("Retargeted pose").collapsible(false).resizable(false).anchor(egui::Align2::RIGHT_TOP, egui::vec2(-16.0, 40.0)).show(ctx, |ui| {
            // The file's name keeps the window narrow; its full path is on hover.
            let name = p.path.file_name().map_or_else(|| p.path.display().to_string(), |n| n.to_string_lossy().into_owned());
            ui.label(format!("{name} @ {}", p.frame)).on_hover_text(project::shown_path(&p.path));
            ui.label(RichText::new("Left, orange: the file's skeleton").color(super::timeline::color32(SOURCE_COLOR)));
            ui.label(RichText::new("Right, blue: the model's pose").color(super::timeline::color32(RETARGETED_COLOR)));
            ui.horizontal(|ui| {
                if ui.button("Use").clicked() {
                    self.panels.rig.preview = None;
                    self.viewport.frame_all();
                    self.use_retargeted(p.purpose, p.path.clone(), p.frame);
                }
                if ui.button("Edit mapping…").clicked() {
                    self.panels.rig.editor = Some(JointMapEditor::new(p.purpose, &p.path, p.frame, &p.joints));
                }
                if ui.button("Cancel").clicked() {
                    self.panels.rig.preview = None;
                    self.viewport.frame_all();
                    self.messages.resolve(Topic::Init);
                }
            });
        });
    }

    fn failure_window(&mut self, ctx: &egui::Context) {
        let Some(f) = self.panels.rig.failure.clone() else { return };
        egui::Window::new("Cannot map the skeleton").collapsible(false).resizable(false).anchor(egui::Align2::RIGHT_TOP, egui::vec2(-16.0, 40.0)).show(ctx, |ui| {
            ui.set_max_width(420.0);
            ui.label(studio_wording(&f.error));
            ui.horizontal(|ui| {
                if ui.add_enabled(!f.joints.names.is_empty(), egui::Button::new("Edit mapping…")).clicked() {
                    self.panels.rig.editor = Some(JointMapEditor::new(f.purpose, &f.path, f.frame, &f.joints));
                }
                if ui.button("Cancel").clicked() {
                    self.panels.rig.failure = None;
                }
            });
        });
    }

    fn editor_window(&mut self, ctx: &egui::Context) {
        let Some(editor) = self.panels.rig.editor.as_mut() else { return };
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
            Some(false) => self.panels.rig.editor = None,
            None => {}
        }
    }

    /// Saves the editor's mapping in the project and retargets the file with it again.
    fn apply_joint_map(&mut self) {
        let Some(editor) = self.panels.rig.editor.take() else { return };
        let map: BTreeMap<String, String> = editor.choices.iter().filter_map(|(key, joint)| Some((joint.clone()?, key.name().to_string()))).collect();
        self.edit(|d| d.joint_map = Some(map));
        if uses_file(&self.editing.doc.options, &editor.path) {
            // The options are unchanged but the take from this file is not: generate again.
            self.engine.requested = None;
        }
        self.retarget_file(editor.purpose, editor.path, editor.frame);
    }

    fn use_retargeted(&mut self, purpose: PreviewFor, path: PathBuf, frame: usize) {
        match purpose {
            PreviewFor::Init => {
                self.panels.fields.init_path = path.display().to_string();
                let name = format!("{} from frame {frame}", project::shown_path(&path));
                self.edit(|d| d.options.init = InitPose::file(path, frame));
                self.panels.init_tab = InitTab::File;
                self.messages.set(Topic::Init, Level::Info, format!("Initial pose: {name} (retargeted)"));
            }
            PreviewFor::Key => {
                self.messages.resolve(Topic::Init);
                self.add_key_from_file(path, frame);
            }
        }
    }
}
