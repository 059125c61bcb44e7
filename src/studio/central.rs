//! The central area: the 3D viewport with an overlay (frame, segment, status) and the
//! message toasts.

use egui::{Align2, Color32, FontId, RichText};

use super::app::StudioApp;
use super::panels::ViewportTool;
use super::timeline::Mark;
use super::viewport::{Layer, PathOverlay, Scene};

impl StudioApp {
    pub(super) fn central(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        let mut layers = Vec::new();
        let previewing = self.preview_layers();
        // Posing edits the take's own frame, held still.
        self.viewport.set_posing(self.panels.tool == ViewportTool::Pose && previewing.is_none() && !self.playback.playing);
        if let Some(preview) = previewing {
            layers = preview;
        } else if let Some(t) = &self.engine.take {
            layers.push(Layer { motion: t.motion.clone(), frame_colors: t.frame_colors.clone(), offset: glam::Vec3::ZERO, opacity: 1.0, contacts: Some(t.contacts.clone()) });
            if self.panels.compare {
                if let Some((p, white)) = &self.engine.previous {
                    layers.push(Layer { motion: p.motion.clone(), frame_colors: white.clone(), offset: glam::Vec3::ZERO, opacity: 0.45, contacts: None });
                }
            }
        }
        let frame = self.playback.frame();
        let waypoints: Vec<[f32; 2]> = self.editing.doc.options.path.as_ref().map_or_else(Vec::new, |p| p.waypoints.iter().map(|w| [w.x, w.z]).collect());
        let selected = match self.editing.selected_mark {
            Some(Mark::Waypoint(k)) => Some(k),
            _ => None,
        };
        let drawing = self.panels.tool == ViewportTool::DrawPath;
        let path = (drawing || !waypoints.is_empty()).then_some(PathOverlay { waypoints: &waypoints, selected, editing: drawing });
        let scene = Scene { layers: &layers, frame, settings: &self.editing.doc.view, path };
        self.viewport.ui(ui, &scene);
        for edit in self.viewport.take_path_edits() {
            self.apply_path_edit(edit);
        }
        if let Some(posed) = self.viewport.take_posed() {
            self.add_key_from_posed(posed);
        }

        // Overlay: where we are, and what the worker is doing.
        let painter = ui.painter_at(rect);
        let text_color = Color32::from_gray(225);
        if let Some(t) = &self.engine.take {
            let seg = t.segments.iter().find(|s| frame >= s.start_frame && frame < s.end_frame.max(s.start_frame + 1));
            let label = format!(
                "frame {frame} / {}   {:.2} s   {}",
                t.motion.frames().saturating_sub(1),
                frame as f32 / t.motion.fps,
                seg.map_or_else(String::new, |s| s.label())
            );
            painter.text(rect.left_top() + egui::vec2(12.0, 10.0), Align2::LEFT_TOP, label, FontId::monospace(13.0), text_color);
            if let Some(why) = self.stale_reason() {
                let warn = Color32::from_rgb(255, 190, 70);
                painter.text(rect.left_top() + egui::vec2(12.0, 30.0), Align2::LEFT_TOP, format!("OUT OF DATE: {why}"), FontId::proportional(14.0), warn);
            }
        } else {
            let msg = if self.engine.model_loading.is_some() {
                "Loading the model…"
            } else if self.engine.pending.is_some() {
                "Generating…"
            } else if self.engine.model.is_none() {
                "No model loaded: choose one in the Model section or the File menu"
            } else {
                "Nothing generated yet"
            };
            painter.text(rect.center(), Align2::CENTER_CENTER, msg, FontId::proportional(18.0), text_color);
        }
        if let Some((_, p)) = self.engine.pending {
            let r = egui::Rect::from_min_size(rect.left_bottom() + egui::vec2(12.0, -30.0), egui::vec2(220.0, 18.0));
            ui.put(r, egui::ProgressBar::new(p).text(RichText::new(format!("generating {:.0}%", p * 100.0)).small()));
        }
        // The retarget windows sit at the top right, where the toasts would cover their buttons.
        let rig = &self.panels.rig;
        let rig_window = rig.preview.is_some() || rig.failure.is_some();
        self.messages.show(ui, rect, rig_window);
    }
}
