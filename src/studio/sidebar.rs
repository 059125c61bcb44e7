//! The left panel: project, model, initial pose, generation settings and export.

use std::path::PathBuf;

use egui::{RichText, Slider};

use super::app::{ExportRange, InitTab, StudioApp};
use super::dialogs::Purpose;
use super::timeline::color32;
use crate::synth::render::class_color;
use crate::synth::timeline::{MAX_PACE, MIN_PACE};
use crate::synth::{InitPose, Transition};

fn section(ui: &mut egui::Ui, title: &str, add: impl FnOnce(&mut egui::Ui)) {
    egui::CollapsingHeader::new(RichText::new(title).strong()).default_open(true).show(ui, add);
    ui.add_space(2.0);
}

/// A text field with a label the tests (and screen readers) can find.
fn path_field(ui: &mut egui::Ui, label: &str, value: &mut String, hint: &str) -> egui::Response {
    let l = ui.label(label);
    ui.add(egui::TextEdit::singleline(value).hint_text(hint).desired_width(f32::INFINITY)).labelled_by(l.id)
}

impl StudioApp {
    pub(super) fn side_panel(&mut self, ui: &mut egui::Ui) {
        ui.add_space(4.0);
        section(ui, "Model", |ui| self.model_section(ui));
        section(ui, "Initial pose", |ui| self.init_section(ui));
        section(ui, "Generation", |ui| self.generation_section(ui));
        section(ui, "Export take", |ui| self.export_section(ui));
        section(ui, "Project", |ui| self.project_section(ui));
    }

    fn model_section(&mut self, ui: &mut egui::Ui) {
        match &self.model {
            Some(m) => {
                let s = &m.spec;
                ui.label(RichText::new(m.dir.display().to_string()).monospace());
                ui.label(format!("{} · {} classes · {} fps · {} joints", s.dataset, s.classes.len(), s.fps, s.layout.joints()));
                if !m.has_locgen {
                    ui.label(RichText::new("No LocGen yet: frames are interpolated").weak());
                }
            }
            None => {
                ui.label(RichText::new("No model loaded").weak());
            }
        }
        if let Some(dir) = &self.model_loading {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!("Loading {}…", dir.display()));
            });
        }
        if !self.shipped.is_empty() {
            ui.horizontal_wrapped(|ui| {
                ui.label("Shipped:");
                for dir in self.shipped.clone() {
                    let name = dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned());
                    let current = self.model.as_ref().is_some_and(|m| m.dir == dir);
                    if ui.selectable_label(current, name).clicked() && !current {
                        self.load_model(dir);
                    }
                }
            });
        }
        let r = path_field(ui, "Model folder", &mut self.fields.model_path, "path/to/model");
        let enter = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        ui.horizontal(|ui| {
            if ui.button("Load model").clicked() || enter {
                let p = PathBuf::from(self.fields.model_path.trim());
                self.load_model(p);
            }
            if ui.button("Browse…").clicked() {
                self.open_dialog(Purpose::OpenModel, ui.ctx());
            }
        });
    }

    fn init_section(&mut self, ui: &mut egui::Ui) {
        let Some(model) = self.model.clone() else {
            ui.label(RichText::new("Load a model first").weak());
            return;
        };
        let classes = &model.spec.classes;
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.init_tab, InitTab::Class, "By class");
            ui.selectable_value(&mut self.init_tab, InitTab::Seed, "Seed");
            ui.selectable_value(&mut self.init_tab, InitTab::File, "File");
        });
        match self.init_tab {
            InitTab::Class => {
                let (mut class, mut variant) = match &self.doc.init {
                    InitPose::SeedClass { class, variant } => (class.clone(), *variant),
                    InitPose::SeedIndex(i) => (model.seeds.get(*i).map_or_else(|| classes[0].clone(), |s| classes[s.class].clone()), 0),
                    InitPose::File { .. } => (classes[0].clone(), 0),
                };
                egui::ComboBox::from_label("Seed class").selected_text(&class).show_ui(ui, |ui| {
                    for c in classes {
                        ui.selectable_value(&mut class, c.clone(), c);
                    }
                });
                let k = classes.iter().position(|c| c.eq_ignore_ascii_case(&class)).unwrap_or(0);
                let n = model.seeds.iter().filter(|s| s.class == k).count().max(1);
                ui.add(Slider::new(&mut variant, 0..=n - 1).text("variant"));
                let init = InitPose::SeedClass { class, variant };
                if ui.button("Use this seed").clicked() || (matches!(self.doc.init, InitPose::SeedClass { .. }) && self.doc.init != init) {
                    self.doc.init = init;
                }
            }
            InitTab::Seed => {
                let mut index = match &self.doc.init {
                    InitPose::SeedIndex(i) => *i,
                    _ => 0,
                };
                if let Some(s) = model.seeds.get(index) {
                    ui.horizontal(|ui| {
                        let (r, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
                        ui.painter().circle_filled(r.center(), 5.0, color32(class_color(s.class)));
                        ui.label(format!("{} · {} @ {}", classes[s.class], s.clip, s.frame));
                    });
                }
                let max = model.seeds.len().saturating_sub(1);
                let changed = ui.add(Slider::new(&mut index, 0..=max).text("seed")).changed();
                ui.label(RichText::new("Or click a point in the seed map").weak());
                if changed || (ui.button("Use this seed").clicked()) {
                    self.doc.init = InitPose::SeedIndex(index);
                }
            }
            InitTab::File => {
                if let InitPose::File { path, frame } = &self.doc.init {
                    ui.label(format!("In use: {} @ {frame}", path.display()));
                }
                path_field(ui, "Motion file (BVH, NPY or dataset .txt)", &mut self.fields.init_path, "clip.bvh");
                ui.add(egui::DragValue::new(&mut self.fields.init_frame).prefix("from frame "));
                ui.horizontal(|ui| {
                    if ui.button("Use file").clicked() {
                        let p = PathBuf::from(self.fields.init_path.trim());
                        self.use_init_file(p, self.fields.init_frame);
                    }
                    if ui.button("Browse…").clicked() {
                        self.open_dialog(Purpose::InitFile, ui.ctx());
                    }
                });
            }
        }
    }

    fn generation_section(&mut self, ui: &mut egui::Ui) {
        let has_locgen = self.model.as_ref().is_some_and(|m| m.has_locgen);
        let guidance = self.model.as_ref().is_some_and(|m| m.spec.glogen.class_dropout > 0.0);
        ui.add(Slider::new(&mut self.doc.pace, MIN_PACE..=4.0f32.min(MAX_PACE)).logarithmic(true).text("global pace"))
            .on_hover_text("Below 1: slower motion, above 1: faster. A segment may set its own pace.");
        ui.horizontal(|ui| {
            ui.label("Transitions:");
            ui.selectable_value(&mut self.doc.transition, Transition::Anchor, "Anchor").on_hover_text("Mix both classes and ease the poses towards the new activity: it wins over the old one's momentum");
            ui.selectable_value(&mut self.doc.transition, Transition::Blend, "Blend").on_hover_text("Blocks across a boundary mix both classes");
            ui.selectable_value(&mut self.doc.transition, Transition::Cut, "Cut").on_hover_text("The class changes at the first block of a segment");
        });
        ui.add_enabled(guidance, Slider::new(&mut self.doc.class_strength, 0.0..=3.0).text("class strength"))
            .on_disabled_hover_text("This model was trained without class dropout, so classifier-free guidance is not available");
        ui.add_enabled(has_locgen, egui::Checkbox::new(&mut self.doc.locgen, "LocGen refinement"));
        ui.horizontal(|ui| {
            ui.add(egui::DragValue::new(&mut self.doc.variation_seed).range(0..=9999)).on_hover_text("0: the model's deterministic take");
            ui.label("variation seed");
        });
        ui.checkbox(&mut self.auto_regen, "Regenerate after every edit");
        ui.horizontal(|ui| {
            if ui.add_enabled(self.model.is_some(), egui::Button::new("Generate")).clicked() {
                self.regenerate();
            }
            if let Some((_, p)) = self.pending {
                if ui.button("Cancel").clicked() {
                    self.cancel();
                }
                ui.add(egui::ProgressBar::new(p).show_percentage().desired_width(110.0));
            }
        });
        if let Some(t) = &self.take {
            ui.label(RichText::new(format!("{} frames ({:.1} s) in {:.0} ms", t.motion.frames(), t.motion.seconds(), t.millis)).weak());
        }
    }

    fn export_section(&mut self, ui: &mut egui::Ui) {
        path_field(ui, "Export file (.bvh, .json or .npy)", &mut self.fields.export_path, "take.bvh");
        ui.horizontal(|ui| {
            for (ext, name) in [("bvh", "BVH"), ("json", "JSON"), ("npy", "NPY")] {
                let current = PathBuf::from(&self.fields.export_path);
                let is = current.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext));
                if ui.selectable_label(is, name).clicked() {
                    self.fields.export_path = current.with_extension(ext).display().to_string();
                }
            }
        });
        ui.horizontal(|ui| {
            ui.radio_value(&mut self.export_range, ExportRange::Whole, "Whole take");
            ui.add_enabled(self.playback.selection.is_some(), egui::RadioButton::new(self.export_range == ExportRange::Selection, "Selected range"))
                .clicked()
                .then(|| self.export_range = ExportRange::Selection);
        });
        ui.horizontal(|ui| {
            if ui.add_enabled(self.take.is_some(), egui::Button::new("Export")).clicked() {
                let p = PathBuf::from(self.fields.export_path.trim());
                self.export_to(p);
            }
            if ui.add_enabled(self.take.is_some(), egui::Button::new("Export…")).clicked() {
                self.open_dialog(Purpose::Export, ui.ctx());
            }
        });
    }

    fn project_section(&mut self, ui: &mut egui::Ui) {
        path_field(ui, "Project file", &mut self.fields.project_path, "project.glocal.json");
        ui.horizontal(|ui| {
            if ui.button("Open").clicked() {
                let p = PathBuf::from(self.fields.project_path.trim());
                self.open_project(&p);
            }
            if ui.button("Save").clicked() {
                let p = PathBuf::from(self.fields.project_path.trim());
                self.save_project(&p);
            }
            if ui.button("Open…").clicked() {
                self.open_dialog(Purpose::OpenProject, ui.ctx());
            }
            if ui.button("Save as…").clicked() {
                self.open_dialog(Purpose::SaveProject, ui.ctx());
            }
        });
        if let Some(p) = &self.autosave {
            ui.label(RichText::new(format!("Autosave: {}", p.display())).weak().small());
        }
    }
}
