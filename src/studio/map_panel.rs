//! The right panel: the seed bank's t-SNE map, coloured by class, with the current take's
//! blocks as a path through it. Hover a point for its class and clip; click one to start
//! the take from that seed.

use egui::{Color32, RichText};
use egui_plot::{Legend, Line, MarkerShape, Plot, PlotPoints, Points};

use super::app::StudioApp;
use super::panels::InitTab;
use super::timeline::color32;
use crate::synth::render::class_color;
use super::worker::Take;
use crate::synth::InitPose;

/// The share of the points' height kept free below them for the legend.
const LEGEND_ROOM: f32 = 0.8;

impl StudioApp {
    pub(super) fn map_panel(&mut self, ui: &mut egui::Ui) {
        ui.add_space(4.0);
        ui.label(RichText::new("Seed map (t-SNE of GloGen embeddings)").strong());
        let (Some(model), Some(map)) = (self.engine.model.clone(), self.engine.map.clone()) else {
            self.no_map_yet(ui);
            return;
        };
        let classes = &model.spec.classes;
        // Seeds of each class, in map order.
        let by_class: Vec<Vec<usize>> = (0..classes.len()).map(|c| (0..model.seeds.len()).filter(|&i| model.seeds[i].class == c).collect()).collect();
        let chosen = chosen_seed(&self.editing.doc.options.init, classes, &by_class);
        let take = self.engine.take.clone();
        let current_block = take.as_ref().filter(|t| !t.path.is_empty()).map(|t| {
            let frames = t.motion.frames().max(1);
            ((self.playback.frame() as f32 / frames as f32) * t.path.len() as f32) as usize % t.path.len()
        });
        let seeds = &model.seeds;
        let by_class_ref = &by_class;
        let formatter = move |pos: &egui_plot::HoverPosition<'_>| -> Option<String> {
            match pos {
                egui_plot::HoverPosition::NearDataPoint { plot_name, index, .. } => {
                    let k = classes.iter().position(|c| c == plot_name)?;
                    let i = *by_class_ref.get(k)?.get(*index)?;
                    let s = &seeds[i];
                    Some(format!("{}\n{} @ frame {}\nseed #{i} (click to start from it)", classes[s.class], s.clip, s.frame))
                }
                egui_plot::HoverPosition::Elsewhere { .. } => None,
            }
        };
        // Room below the points for the legend, which covered them: the panel is tall, so the
        // cloud moves up rather than shrinks.
        let (low, high) = map.points.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), p| (l.min(p[1]), h.max(p[1])));
        let legend_room = if low.is_finite() { f64::from(low - LEGEND_ROOM * (high - low)) } else { 0.0 };
        let resp = Plot::new("seed_map")
            .data_aspect(1.0)
            .include_y(legend_room)
            .legend(Legend::default().position(egui_plot::Corner::LeftBottom))
            .show_axes(false)
            .show_grid(false)
            .allow_boxed_zoom(false)
            .label_formatter(formatter)
            .show(ui, |plot| {
                for (k, idx) in by_class.iter().enumerate() {
                    if idx.is_empty() {
                        continue;
                    }
                    let pts: Vec<[f64; 2]> = idx.iter().map(|&i| [f64::from(map.points[i][0]), f64::from(map.points[i][1])]).collect();
                    plot.points(Points::new(classes[k].clone(), PlotPoints::new(pts)).color(color32(class_color(k))).radius(3.0).filled(true));
                }
                if let Some(i) = chosen.filter(|&i| i < map.points.len()) {
                    let p = map.points[i];
                    plot.points(
                        Points::new("initial pose", PlotPoints::new(vec![[f64::from(p[0]), f64::from(p[1])]]))
                            .shape(MarkerShape::Circle)
                            .radius(7.0)
                            .filled(false)
                            .color(Color32::WHITE)
                            .allow_hover(false),
                    );
                }
                if let Some(t) = take.as_ref().filter(|t| !t.path.is_empty()) {
                    plot_take_path(plot, t, current_block);
                }
            });
        if let Some(i) = clicked_seed(&resp, &map.points) {
            self.editing.doc.options.init = InitPose::SeedIndex(i);
            self.panels.init_tab = InitTab::Seed;
            self.panels.fields.seed_index = i;
        }
    }

    /// What stands in for the map until it exists: why not, or that it is being computed.
    fn no_map_yet(&self, ui: &mut egui::Ui) {
        ui.add_space(8.0);
        if let Some(e) = &self.engine.map_error {
            ui.colored_label(Color32::from_rgb(230, 90, 80), format!("No map: {e}"));
        } else if self.engine.model.is_some() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("Computing the map…");
            });
        } else {
            ui.label(RichText::new("Load a model to see its seed bank").weak());
        }
    }
}

/// The seed the take starts from, if it starts from one (`by_class`: each class's seeds).
fn chosen_seed(init: &InitPose, classes: &[String], by_class: &[Vec<usize>]) -> Option<usize> {
    match init {
        InitPose::SeedIndex(i) => Some(*i),
        InitPose::SeedClass { class, variant } => classes
            .iter()
            .position(|c| c.eq_ignore_ascii_case(class))
            .and_then(|k| by_class.get(k).filter(|v| !v.is_empty()).map(|v| v[variant % v.len()])),
        InitPose::File { .. } => None,
    }
}

/// The take's blocks on the map, coloured by class, joined in order, the one playing ringed.
fn plot_take_path(plot: &mut egui_plot::PlotUi, t: &Take, current_block: Option<usize>) {
    let path: Vec<[f64; 2]> = t.path.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]).collect();
    plot.line(Line::new("take", PlotPoints::new(path.clone())).color(Color32::from_gray(230)).width(1.5).allow_hover(false));
    for (b, p) in path.iter().enumerate() {
        let c = t.block_classes.get(b).map_or(Color32::GRAY, |&c| color32(class_color(c)));
        plot.points(Points::new("take", PlotPoints::new(vec![*p])).shape(MarkerShape::Diamond).radius(4.5).color(c).allow_hover(false));
    }
    if let Some(b) = current_block {
        plot.points(Points::new("take", PlotPoints::new(vec![path[b]])).shape(MarkerShape::Circle).radius(6.0).filled(false).color(Color32::from_rgb(255, 90, 60)).allow_hover(false));
    }
}

/// The seed a click on the map picked: the nearest within a few pixels.
fn clicked_seed<R>(resp: &egui_plot::PlotResponse<R>, points: &[[f32; 2]]) -> Option<usize> {
    if !resp.response.clicked() {
        return None;
    }
    let pos = resp.response.interact_pointer_pos()?;
    let (i, d) = points
        .iter()
        .enumerate()
        .map(|(i, p)| (i, resp.transform.position_from_point(&egui_plot::PlotPoint::new(p[0], p[1])).distance(pos)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    (d < 10.0).then_some(i)
}
