//! The menu bar.

use egui::{Button, KeyboardShortcut, Key, Modifiers};

use super::app::StudioApp;
use super::dialogs::Purpose;

impl StudioApp {
    pub(super) fn menu_bar(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        let fmt = |s: KeyboardShortcut| ctx.format_shortcut(&s);
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("New project").clicked() {
                    let model = self.doc.model.clone();
                    let classes = self.classes().to_vec();
                    self.edit(|d| {
                        *d = super::project::Project::new(model);
                        d.timeline = super::project::Project::default_timeline(&classes);
                    });
                    self.project_path = None;
                    ui.close();
                }
                if ui.button("Open project…").clicked() {
                    self.open_dialog(Purpose::OpenProject, ui.ctx());
                    ui.close();
                }
                if ui.add(Button::new("Save project").shortcut_text(fmt(KeyboardShortcut::new(Modifiers::COMMAND, Key::S)))).clicked() {
                    self.save_shortcut(ui.ctx());
                    ui.close();
                }
                if ui.button("Save project as…").clicked() {
                    self.open_dialog(Purpose::SaveProject, ui.ctx());
                    ui.close();
                }
                ui.separator();
                ui.menu_button("Models", |ui| {
                    if self.shipped.is_empty() {
                        ui.label("No models found under models/");
                    }
                    for dir in self.shipped.clone() {
                        let name = dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned());
                        let current = self.model.as_ref().is_some_and(|m| m.dir == dir);
                        if ui.selectable_label(current, name).clicked() {
                            self.load_model(dir);
                            ui.close();
                        }
                    }
                });
                if ui.button("Open model folder…").clicked() {
                    self.open_dialog(Purpose::OpenModel, ui.ctx());
                    ui.close();
                }
                ui.separator();
                if ui.button("Export take…").clicked() {
                    self.open_dialog(Purpose::Export, ui.ctx());
                    ui.close();
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                }
            });
            ui.menu_button("Edit", |ui| {
                let can_undo = self.history.can_undo();
                let can_redo = self.history.can_redo();
                if ui.add_enabled(can_undo, Button::new("Undo").shortcut_text(fmt(KeyboardShortcut::new(Modifiers::COMMAND, Key::Z)))).clicked() {
                    self.undo();
                    ui.close();
                }
                if ui.add_enabled(can_redo, Button::new("Redo").shortcut_text(fmt(KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z)))).clicked() {
                    self.redo();
                    ui.close();
                }
                ui.separator();
                if ui.button("Add segment").clicked() {
                    self.add_segment();
                    ui.close();
                }
                if ui.add_enabled(self.selected.is_some(), Button::new("Delete segment").shortcut_text("Del")).clicked() {
                    if let Some(k) = self.selected {
                        self.delete_segment(k);
                    }
                    ui.close();
                }
                if ui.add_enabled(self.playback.selection.is_some(), Button::new("Clear range")).clicked() {
                    self.playback.selection = None;
                    ui.close();
                }
            });
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.show_side, "Settings panel");
                ui.checkbox(&mut self.show_map, "Seed map panel");
                ui.checkbox(&mut self.compare, "Overlay the previous take");
                ui.separator();
                let v = &mut self.doc.view;
                ui.checkbox(&mut v.grid, "Grid");
                ui.checkbox(&mut v.trail, "Root trail");
                ui.checkbox(&mut v.follow_root, "Follow the root");
                ui.add(egui::Slider::new(&mut v.ghosts, 0..=8).text("ghosts"));
                ui.add(egui::Slider::new(&mut v.ghost_step, 1..=20).text("frames between ghosts"));
            });
            ui.menu_button("Help", |ui| {
                if ui.button("Keyboard shortcuts").clicked() {
                    self.show_help = true;
                    ui.close();
                }
            });
        });
        if self.show_help {
            let mut open = true;
            egui::Window::new("Keyboard shortcuts").open(&mut open).collapsible(false).resizable(false).show(ui.ctx(), |ui| {
                egui::Grid::new("shortcuts").striped(true).show(ui, |ui| {
                    for (k, what) in [
                        ("Space", "play / pause"),
                        ("Left / Right", "step one frame"),
                        ("Home / End", "first / last frame"),
                        ("Ctrl+Z", "undo"),
                        ("Ctrl+Shift+Z, Ctrl+Y", "redo"),
                        ("Ctrl+S", "save the project"),
                        ("Delete", "delete the selected segment"),
                        ("Shift-drag on the ruler", "select a range"),
                    ] {
                        ui.monospace(k);
                        ui.label(what);
                        ui.end_row();
                    }
                });
            });
            self.show_help = open;
        }
    }
}
