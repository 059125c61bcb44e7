//! The bottom panel: transport (play, step, loop, speed), the timeline, and the selected
//! segment's settings.

use egui::{Button, RichText, Slider};

use super::app::StudioApp;
use super::project::LoopMode;
use super::timeline::{self, class_index, color32, timeline_ui, Input, MIN_SECONDS};
use crate::synth::render::class_color;
use crate::synth::timeline::{MAX_PACE, MAX_TRANSITION_SECONDS, MIN_PACE};

impl StudioApp {
    pub(super) fn bottom_panel(&mut self, ui: &mut egui::Ui) {
        ui.add_space(4.0);
        self.transport_row(ui);
        ui.add_space(2.0);
        let classes = self.classes().to_vec();
        let (frames, fps) = self.engine.take.as_ref().map_or((0, 25.0), |t| (t.motion.frames(), t.motion.fps));
        let spans = self.engine.take.as_ref().filter(|t| t.options.timeline == self.editing.take_request().options.timeline).map(|t| t.segments.clone());
        let waypoint_times = self.waypoint_times();
        let input = Input {
            timeline: &self.editing.doc.options.timeline,
            classes: &classes,
            spans: spans.as_deref(),
            frames,
            fps,
            frame: self.playback.frame(),
            selection: self.playback.selection,
            selected: self.editing.selected,
            keys: &self.editing.doc.options.keys,
            path: self.editing.doc.options.path.as_ref(),
            waypoint_times: &waypoint_times,
            selected_mark: self.editing.selected_mark,
            contacts: self.engine.take.as_ref().map(|t| t.contacts.as_ref()),
        };
        let actions = timeline_ui(ui, &mut self.panels.timeline_state, &input);
        self.apply_timeline(actions);
        ui.add_space(2.0);
        let styles = self.engine.styles().to_vec();
        self.segment_row(ui, &classes, &styles);
        ui.add_space(4.0);
    }

    fn transport_row(&mut self, ui: &mut egui::Ui) {
        let (frames, fps) = self.engine.take.as_ref().map_or((0, 25.0), |t| (t.motion.frames(), t.motion.fps));
        ui.horizontal_wrapped(|ui| {
            let play = if self.playback.playing { "Pause" } else { "Play" };
            if ui.add_enabled(frames > 1, Button::new(play).min_size(egui::vec2(76.0, 0.0))).on_hover_text("Space").clicked() {
                self.playback.toggle(frames, &self.editing.doc.playback);
            }
            if ui.add_enabled(frames > 1, Button::new(" < ")).on_hover_text("Previous frame (Left arrow)").clicked() {
                self.playback.step(-1, frames);
            }
            if ui.add_enabled(frames > 1, Button::new(" > ")).on_hover_text("Next frame (Right arrow)").clicked() {
                self.playback.step(1, frames);
            }
            // Typeable frame and time (click to type, drag to scrub).
            let last = frames.saturating_sub(1);
            let mut f = self.playback.frame();
            let frame_edit = ui.add(egui::DragValue::new(&mut f).range(0..=last).speed(0.5).prefix("frame ").suffix(format!(" / {last}")));
            let mut t = f as f32 / fps;
            let time_edit = ui.add(egui::DragValue::new(&mut t).range(0.0..=last as f32 / fps).speed(0.02).fixed_decimals(2).suffix(" s"));
            if time_edit.changed() {
                f = (t * fps).round() as usize;
            }
            if frame_edit.changed() || time_edit.changed() {
                self.playback.playing = false;
                self.playback.seek(f, frames);
            }
            ui.separator();
            ui.label("Loop");
            let lm = &mut self.editing.doc.playback.loop_mode;
            ui.selectable_value(lm, LoopMode::Off, "Off");
            ui.selectable_value(lm, LoopMode::All, "All");
            ui.add_enabled_ui(self.playback.selection.is_some(), |ui| ui.selectable_value(lm, LoopMode::Selection, "Range"))
                .inner
                .on_disabled_hover_text("Shift-drag on the ruler to select a range");
            ui.separator();
            ui.add(Slider::new(&mut self.editing.doc.playback.speed, 0.1..=4.0).logarithmic(true).text("speed"));
            ui.separator();
            if ui.button("+ Add segment").clicked() {
                self.add_segment();
            }
            let classes = self.classes().to_vec();
            if !classes.is_empty() {
                let k = self.panels.fields.new_class.min(classes.len() - 1);
                egui::ComboBox::from_id_salt("new_class").selected_text(&classes[k]).width(110.0).height(400.0).show_ui(ui, |ui| {
                    for (i, c) in classes.iter().enumerate() {
                        ui.selectable_value(&mut self.panels.fields.new_class, i, c);
                    }
                });
            }
            if let Some(label) = self.range_label() {
                ui.separator();
                ui.label(label).on_hover_text("First and last frame, both included: what a range export writes");
                if ui.small_button("x").on_hover_text("Clear the range").clicked() {
                    self.playback.selection = None;
                }
            }
            if let Some((_, p)) = self.engine.pending {
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                    if ui.button("Cancel").clicked() {
                        self.cancel();
                    }
                    ui.add(egui::ProgressBar::new(p).desired_width(120.0).text("generating"));
                });
            }
        });
    }

    fn segment_row(&mut self, ui: &mut egui::Ui, classes: &[String], styles: &[String]) {
        ui.horizontal_wrapped(|ui| {
            // What the pointer is over on the timeline, here rather than in a tooltip that
            // would cover the transport bar.
            if let Some(hint) = self.panels.timeline_state.hint() {
                ui.label(RichText::new(hint).weak());
                return;
            }
            let Some(k) = self.editing.selected.filter(|&k| k < self.editing.doc.options.timeline.segments.len()) else {
                ui.label(RichText::new("Select a segment to edit it · drag blocks to reorder, their right edge to resize · right-click for more").weak());
                return;
            };
            let n = self.editing.doc.options.timeline.segments.len();
            let (global_transition, global_pace) = (self.editing.doc.options.transition_seconds, self.editing.doc.options.pace);
            let seg = &mut self.editing.doc.options.timeline.segments[k];
            let (r, _) = ui.allocate_exact_size(egui::vec2(12.0, 12.0), egui::Sense::hover());
            let color = class_index(classes, &seg.class).map_or(egui::Color32::GRAY, |c| color32(class_color(c)));
            ui.painter().circle_filled(r.center(), 6.0, color);
            ui.label(RichText::new(format!("Segment {}", k + 1)).strong());
            egui::ComboBox::from_id_salt("segment_class").selected_text(&seg.class).width(120.0).height(400.0).show_ui(ui, |ui| {
                for c in classes {
                    ui.selectable_value(&mut seg.class, c.clone(), c);
                }
            });
            if !styles.is_empty() {
                // A model with styles: the segment's own, or its class's usual one.
                let shown = seg.style.clone().unwrap_or_else(|| "usual style".into());
                egui::ComboBox::from_label("style").selected_text(shown).width(110.0).height(400.0).show_ui(ui, |ui| {
                    ui.selectable_value(&mut seg.style, None, "usual style").on_hover_text("The style most of this activity's training clips have, at the pace of all its clips (a style chosen by name keeps the pace of its own clips: a sad wave is slower than an active one)");
                    for s in styles {
                        ui.selectable_value(&mut seg.style, Some(s.clone()), s);
                    }
                });
            }
            ui.add(egui::DragValue::new(&mut seg.seconds).range(MIN_SECONDS..=600.0).speed(0.05).suffix(" s").fixed_decimals(1));
            let mut own = seg.pace.is_some();
            if ui.checkbox(&mut own, "own pace").on_hover_text("This segment's pace replaces the global pace (it does not multiply it)").changed() {
                seg.pace = own.then_some(global_pace);
            }
            // The slider is always there (greyed without a pace of its own), so ticking the box
            // does not move the widgets after it under the next click.
            let mut shown = seg.pace.unwrap_or(global_pace);
            ui.add_enabled(seg.pace.is_some(), Slider::new(&mut shown, MIN_PACE..=4.0f32.min(MAX_PACE)).logarithmic(true))
                .on_disabled_hover_text("The global pace; tick \"own pace\" to give this segment its own");
            if let Some(p) = seg.pace.as_mut() {
                *p = shown;
            }
            if k > 0 {
                // The transition into this segment, from the one before it.
                let mut own = seg.transition.is_some();
                if ui.checkbox(&mut own, "own transition").on_hover_text("How long the change from the previous segment into this one lasts, centred on the boundary (0: a cut); otherwise the global transition length").changed() {
                    seg.transition = own.then_some(global_transition);
                }
                if let Some(t) = seg.transition.as_mut() {
                    ui.add(egui::DragValue::new(t).range(0.0..=MAX_TRANSITION_SECONDS).speed(0.05).suffix(" s").fixed_decimals(1));
                }
            }
            ui.separator();
            if ui.add_enabled(k > 0, Button::new("Move earlier")).clicked() {
                self.apply_timeline(vec![timeline::Action::BeginEdit, timeline::Action::Move { from: k, to: k - 1 }]);
            }
            if ui.add_enabled(k + 1 < n, Button::new("Move later")).clicked() {
                self.apply_timeline(vec![timeline::Action::BeginEdit, timeline::Action::Move { from: k, to: k + 1 }]);
            }
            if ui.button("Delete").clicked() {
                self.delete_segment(k);
            }
        });
    }
}
