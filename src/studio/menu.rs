//! The menu bar and the windows it opens (help, message log, class mapping).

use egui::{Button, Key, KeyboardShortcut, Modifiers, PopupCloseBehavior};

use super::app::StudioApp;
use super::panels::Guarded;
use super::dialogs::Purpose;

/// Keyboard and mouse, as the Help window lists them.
const CONTROLS: &[(&str, &str)] = &[
    ("Space", "play / pause"),
    ("Left / Right", "step one frame"),
    ("Home / End", "first / last frame"),
    ("Ctrl+Z", "undo (in a text field: undo the typing)"),
    ("Ctrl+Shift+Z, Ctrl+Y", "redo"),
    ("Ctrl+S", "save the project"),
    ("Delete", "delete the selected segment"),
    ("Shift-drag on the ruler", "select a range"),
    ("Viewport: drag", "orbit"),
    ("Viewport: right or middle drag, Shift+drag", "pan"),
    ("Viewport: scroll or pinch", "zoom"),
    ("Viewport: double-click", "frame the take"),
    ("View > Reset camera", "the starting view"),
];

/// How the platform writes `shortcut` (Ctrl+S, ⌘S).
fn shortcut_text(ui: &egui::Ui, shortcut: KeyboardShortcut) -> String {
    ui.ctx().format_shortcut(&shortcut)
}

impl StudioApp {
    pub(super) fn menu_bar(&mut self, ui: &mut egui::Ui) {
        // Checkboxes and sliders keep a menu open; buttons close it themselves.
        let config = egui::containers::menu::MenuConfig::new().close_behavior(PopupCloseBehavior::CloseOnClickOutside);
        egui::MenuBar::new().config(config).ui(ui, |ui| {
            ui.menu_button("File", |ui| self.file_menu(ui));
            ui.menu_button("Edit", |ui| self.edit_menu(ui));
            ui.menu_button("View", |ui| self.view_menu(ui));
            ui.menu_button("Help", |ui| self.help_menu(ui));
        });
    }

    fn file_menu(&mut self, ui: &mut egui::Ui) {
        if ui.button("New project").clicked() {
            self.request(Guarded::New);
            ui.close();
        }
        if ui.button("Open project…").clicked() {
            self.open_dialog(Purpose::OpenProject, ui.ctx());
            ui.close();
        }
        if ui.add(Button::new("Save project").shortcut_text(shortcut_text(ui, KeyboardShortcut::new(Modifiers::COMMAND, Key::S)))).clicked() {
            self.save_shortcut(ui.ctx());
            ui.close();
        }
        if ui.button("Save project as…").clicked() {
            self.open_dialog(Purpose::SaveProject, ui.ctx());
            ui.close();
        }
        ui.separator();
        ui.menu_button("Models", |ui| {
            if self.storage.shipped.is_empty() {
                ui.label("No shipped models found");
            }
            for dir in self.storage.shipped.clone() {
                let name = dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned());
                let current = self.engine.model.as_ref().is_some_and(|m| m.dir == dir);
                if ui.selectable_label(current, name).on_hover_text(dir.display().to_string()).clicked() {
                    self.switch_model(dir);
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
        if ui.button("Copy as command line").on_hover_text("The glocal generate command that makes this take and exports it as set in Export take").clicked() {
            self.copy_command_line(ui.ctx());
            ui.close();
        }
        ui.separator();
        if ui.button("Quit").clicked() {
            ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    fn edit_menu(&mut self, ui: &mut egui::Ui) {
        let can_undo = self.editing.history.can_undo();
        let can_redo = self.editing.history.can_redo();
        if ui.add_enabled(can_undo, Button::new("Undo").shortcut_text(shortcut_text(ui, KeyboardShortcut::new(Modifiers::COMMAND, Key::Z)))).clicked() {
            self.undo();
            ui.close();
        }
        if ui.add_enabled(can_redo, Button::new("Redo").shortcut_text(shortcut_text(ui, KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z)))).clicked() {
            self.redo();
            ui.close();
        }
        ui.separator();
        if ui.button("Add segment").clicked() {
            self.add_segment();
            ui.close();
        }
        if ui.add_enabled(self.editing.selected.is_some(), Button::new("Delete segment").shortcut_text("Del")).clicked() {
            if let Some(k) = self.editing.selected {
                self.delete_segment(k);
            }
            ui.close();
        }
        if ui.add_enabled(self.playback.selection.is_some(), Button::new("Clear range")).clicked() {
            self.playback.selection = None;
            ui.close();
        }
        ui.separator();
        if ui.add_enabled(self.panels.mapping.is_some(), Button::new("Class mapping…")).on_disabled_hover_text("Appears after a model switch carried classes over").clicked() {
            self.panels.show_mapping = true;
            ui.close();
        }
    }

    fn view_menu(&mut self, ui: &mut egui::Ui) {
        ui.checkbox(&mut self.panels.show_side, "Settings panel");
        ui.checkbox(&mut self.panels.map.shown, "Seed map panel");
        ui.checkbox(&mut self.panels.compare, "Overlay the previous take (white)");
        ui.separator();
        let v = &mut self.editing.doc.view;
        ui.checkbox(&mut v.grid, "Grid");
        ui.checkbox(&mut v.trail, "Root trail");
        ui.checkbox(&mut v.follow_root, "Follow the root");
        ui.add(egui::Slider::new(&mut v.ghosts, 0..=8).text("ghosts"));
        ui.add(egui::Slider::new(&mut v.ghost_step, 1..=20).text("frames between ghosts"));
        ui.separator();
        if ui.button("Reset camera").clicked() {
            self.viewport.reset_camera();
            ui.close();
        }
        if ui.button("Frame the take").on_hover_text("Double-click in the viewport").clicked() {
            self.viewport.frame_all();
            ui.close();
        }
    }

    fn help_menu(&mut self, ui: &mut egui::Ui) {
        if ui.button("Keyboard and mouse").clicked() {
            self.panels.show_help = true;
            ui.close();
        }
        if ui.button("Message log").clicked() {
            self.panels.show_log = true;
            ui.close();
        }
    }

    /// Help, the message log and the class mapping, when open.
    pub(super) fn windows(&mut self, ctx: &egui::Context) {
        if self.panels.show_help {
            let mut open = true;
            egui::Window::new("Keyboard and mouse").open(&mut open).collapsible(false).resizable(false).show(ctx, |ui| {
                egui::Grid::new("shortcuts").striped(true).show(ui, |ui| {
                    for (k, what) in CONTROLS {
                        ui.monospace(*k);
                        ui.label(*what);
                        ui.end_row();
                    }
                });
            });
            self.panels.show_help = open;
        }
        if self.panels.show_log {
            let mut open = true;
            egui::Window::new("Message log").open(&mut open).default_width(520.0).show(ctx, |ui| self.messages.log_ui(ui));
            self.panels.show_log = open;
        }
        if self.panels.show_mapping {
            let mut open = true;
            egui::Window::new("Class mapping").open(&mut open).collapsible(false).show(ctx, |ui| self.mapping_ui(ui));
            self.panels.show_mapping = open && self.panels.mapping.is_some();
        }
    }

    fn mapping_ui(&mut self, ui: &mut egui::Ui) {
        let Some(note) = &self.panels.mapping else { return };
        ui.label("Segments of the previous model's classes were retagged as below. A change applies to those segments and is remembered for later switches.");
        let (pairs, classes) = (note.map.pairs.clone(), note.classes.clone());
        let mut change = None;
        egui::Grid::new("class_mapping").striped(true).show(ui, |ui| {
            for p in &pairs {
                ui.label(&p.from);
                ui.label("->");
                egui::ComboBox::from_id_salt(("map", &p.from)).selected_text(&p.to).height(400.0).show_ui(ui, |ui| {
                    for c in &classes {
                        if ui.selectable_label(*c == p.to, c).clicked() {
                            change = Some((p.from.clone(), c.clone()));
                        }
                    }
                });
                ui.end_row();
            }
        });
        if let Some((from, to)) = change {
            self.set_mapping(&from, &to);
        }
    }
}
