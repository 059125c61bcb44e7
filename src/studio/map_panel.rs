//! The right panel: the seed bank's t-SNE map, coloured by class, with the current take's
//! blocks as a path through it. Hover a point for its class and clip; click one to start
//! the take from that seed.

use egui::{Color32, RichText};
use egui_plot::{MarkerShape, Plot, PlotPoints, Points};

use super::app::StudioApp;
use super::panels::InitTab;
use super::timeline::color32;
use crate::synth::render::{class_color, palette_round};
use super::worker::Take;
use crate::synth::InitPose;

/// The most of the map panel's height its key takes.
const KEY_SHARE: f32 = 0.45;

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
        // The key below the map takes the height its content took last frame, at most
        // KEY_SHARE of the panel's (on a small window it scrolls rather than crowd out the map).
        let key_height = self.panels.map.key_height.min(ui.available_height() * KEY_SHARE);
        let hidden = &self.panels.map.hidden_classes;
        let resp = Plot::new("seed_map")
            .height((ui.available_height() - key_height - ui.spacing().item_spacing.y).max(0.0))
            .data_aspect(1.0)
            .show_axes(false)
            .show_grid(false)
            .allow_boxed_zoom(false)
            .label_formatter(formatter)
            .show(ui, |plot| {
                for (k, idx) in by_class.iter().enumerate() {
                    if idx.is_empty() || hidden.contains(&classes[k]) {
                        continue;
                    }
                    let pts: Vec<[f64; 2]> = idx.iter().map(|&i| [f64::from(map.points[i][0]), f64::from(map.points[i][1])]).collect();
                    plot.points(Points::new(classes[k].clone(), PlotPoints::new(pts)).color(color32(class_color(k))).shape(class_marker(k)).radius(3.0).filled(true));
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
        let hidden = &mut self.panels.map.hidden_classes;
        let key = egui::ScrollArea::vertical().id_salt("seed_map_key").max_height(key_height).show(ui, |ui| map_key(ui, classes, &by_class, hidden));
        self.panels.map.key_height = key.content_size.y;
        let shown = |i: usize| !self.panels.map.hidden_classes.contains(&classes[seeds[i].class]);
        if let Some(i) = clicked_seed(&resp, &map.points, shown) {
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

/// The map's key, below it: each class with seeds as its marker and its name, in the model's
/// order (a dataset's classes together), wrapped to the panel's width; a click hides
/// or shows its seeds. egui_plot's legend, drawn over the plot, covered the whole map once a
/// model had 26 classes.
fn map_key(ui: &mut egui::Ui, classes: &[String], by_class: &[Vec<usize>], hidden: &mut std::collections::BTreeSet<String>) {
    ui.add_space(4.0);
    ui.horizontal_wrapped(|ui| {
        ui.spacing_mut().item_spacing = egui::vec2(10.0, 2.0);
        for (k, class) in classes.iter().enumerate().filter(|(k, _)| !by_class[*k].is_empty()) {
            let shown = !hidden.contains(class);
            let entry = key_entry(ui, k, shown, class)
                .on_hover_text(format!("{} seeds of {class}; click to {} them", by_class[k].len(), if shown { "hide" } else { "show" }));
            if entry.clicked() && !hidden.remove(class) {
                hidden.insert(class.clone());
            }
        }
    });
    ui.label(RichText::new("White ring: the initial pose; diamonds: the take's blocks, the one playing ringed").weak().small());
    ui.add_space(2.0);
}

/// A class's marker on the map: a dot, then, for the classes whose colour the palette gives
/// again, a square, then a triangle (the take's blocks are diamonds).
fn class_marker(class: usize) -> MarkerShape {
    [MarkerShape::Circle, MarkerShape::Square, MarkerShape::Up][palette_round(class) % 3]
}

/// A class in the map's key, one widget so a row wraps whole: its marker in its colour,
/// filled while its seeds show and outlined while they are hidden, and its name.
fn key_entry(ui: &mut egui::Ui, class: usize, shown: bool, name: &str) -> egui::Response {
    const MARK: f32 = 8.0;
    const GAP: f32 = 4.0;
    let text = if shown { RichText::new(name) } else { RichText::new(name).weak() };
    let galley = egui::WidgetText::from(text).into_galley(ui, Some(egui::TextWrapMode::Extend), f32::INFINITY, egui::TextStyle::Body);
    let (rect, response) = ui.allocate_exact_size(egui::vec2(MARK + GAP + galley.size().x, galley.size().y), egui::Sense::click());
    let mark = egui::Rect::from_center_size(egui::pos2(rect.left() + MARK / 2.0, rect.center().y), egui::Vec2::splat(MARK));
    let color = color32(class_color(class));
    let (fill, stroke) = if shown { (color, egui::Stroke::NONE) } else { (Color32::TRANSPARENT, egui::Stroke::new(1.0, color)) };
    let painter = ui.painter();
    match class_marker(class) {
        MarkerShape::Square => painter.rect(mark.shrink(0.5), 0.0, fill, stroke, egui::StrokeKind::Inside),
        MarkerShape::Up => painter.add(egui::Shape::convex_polygon(vec![mark.center_top(), mark.right_bottom(), mark.left_bottom()], fill, stroke)),
        _ => painter.add(egui::epaint::CircleShape { center: mark.center(), radius: MARK / 2.0 - 0.5, fill, stroke }),
    };
    painter.galley(egui::pos2(rect.left() + MARK + GAP, rect.top()), galley, ui.visuals().text_color());
    response.widget_info(|| egui::WidgetInfo::selected(egui::Role::CheckBox, true, shown, format!("Seed map key: {name}")));
    response
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
/// The path itself is a [`TakePath`] (one mesh per take); the ring alone changes as it plays.
fn plot_take_path<'a>(plot: &mut egui_plot::PlotUi<'a>, t: &'a Take, current_block: Option<usize>) {
    plot.add(TakePath::new(t));
    if let Some(p) = current_block.and_then(|b| t.path.get(b)) {
        let ring = PlotPoints::new(vec![[f64::from(p[0]), f64::from(p[1])]]);
        plot.points(Points::new("take", ring).shape(MarkerShape::Circle).radius(6.0).filled(false).color(Color32::from_rgb(255, 90, 60)).allow_hover(false));
    }
}

/// Width of the line joining the blocks, points.
const PATH_WIDTH: f32 = 1.5;
/// Half the diagonal of a block's diamond, points.
const DIAMOND_RADIUS: f32 = 4.5;

/// A take's path through the seed map as one plot item: an image of the line through the
/// blocks and a diamond on each, drawn once per take (again only when the plot is zoomed,
/// panned or resized). A ten-minute take has 300 blocks whose joins cross the whole map;
/// as shapes, re-tessellated and rasterised every frame (the egui plot items it was), they
/// cost a software rasteriser more than the rest of the window; as an image, one quad.
struct TakePath<'a> {
    base: egui_plot::PlotItemBase,
    take: &'a Take,
}

/// What an image of the path was drawn for: the take, and where the plot put it on screen.
#[derive(Clone, PartialEq)]
struct PathKey {
    take: u64,
    /// The take's blocks placed so far (its path arrives after it, once the map exists).
    blocks: usize,
    frame: egui::Rect,
    bounds: egui_plot::PlotBounds,
    pixels_per_point: f32,
}

/// The path's image, kept in egui's memory between frames.
#[derive(Clone)]
struct CachedPath {
    key: PathKey,
    texture: egui::TextureHandle,
}

impl<'a> TakePath<'a> {
    fn new(take: &'a Take) -> Self {
        Self { base: egui_plot::PlotItemBase::new("take".into()), take }
    }

    /// The path drawn over the plot's frame, `pixels_per_point` pixels a point.
    fn draw(&self, transform: &egui_plot::PlotTransform, pixels_per_point: f32) -> egui::ColorImage {
        let frame = *transform.frame();
        let size = [(frame.width() * pixels_per_point).round().max(1.0) as usize, (frame.height() * pixels_per_point).round().max(1.0) as usize];
        let mut canvas = Canvas { size, pixels: vec![Color32::TRANSPARENT; size[0] * size[1]] };
        let pixel = |p: &[f32; 2]| (transform.position_from_point(&egui_plot::PlotPoint::new(p[0], p[1])) - frame.min) * pixels_per_point;
        let points: Vec<egui::Vec2> = self.take.path.iter().map(pixel).collect();
        let line = Color32::from_gray(230);
        for pair in points.windows(2) {
            canvas.segment(pair[0], pair[1], PATH_WIDTH * pixels_per_point, line);
        }
        for (b, &centre) in points.iter().enumerate() {
            let color = self.take.block_classes.get(b).map_or(Color32::GRAY, |&c| color32(class_color(c)));
            canvas.diamond(centre, DIAMOND_RADIUS * pixels_per_point, color);
        }
        egui::ColorImage::new(size, canvas.pixels)
    }
}

/// An image drawn on the CPU with anti-aliased lines and diamonds (premultiplied colours).
struct Canvas {
    size: [usize; 2],
    pixels: Vec<Color32>,
}

impl Canvas {
    /// Paints `color` with coverage 0..1 over pixel (x, y), if it is in the image.
    fn blend(&mut self, x: i64, y: i64, color: Color32, coverage: f32) {
        if coverage <= 0.0 || x < 0 || y < 0 || x as usize >= self.size[0] || y as usize >= self.size[1] {
            return;
        }
        let dst = &mut self.pixels[y as usize * self.size[0] + x as usize];
        let src = color.gamma_multiply(coverage.min(1.0));
        let keep = 1.0 - f32::from(src.a()) / 255.0;
        let mix = |s: u8, d: u8| (f32::from(s) + f32::from(d) * keep).round().min(255.0) as u8;
        *dst = Color32::from_rgba_premultiplied(mix(src.r(), dst.r()), mix(src.g(), dst.g()), mix(src.b(), dst.b()), mix(src.a(), dst.a()));
    }

    /// A line `width` pixels wide from `a` to `b`: each pixel within reach once, covered by
    /// how much of it lies within the line.
    fn segment(&mut self, a: egui::Vec2, b: egui::Vec2, width: f32, color: Color32) {
        let reach = width / 2.0 + 1.0;
        let (lo, hi) = (a.min(b) - egui::Vec2::splat(reach), a.max(b) + egui::Vec2::splat(reach));
        let along = b - a;
        let length_sq = along.length_sq().max(1e-6);
        // Rows of the line's bounding box, and in each only the columns near the line.
        for y in lo.y.floor() as i64..=hi.y.ceil() as i64 {
            let py = y as f32 + 0.5;
            let (x0, x1) = if along.y.abs() < 1e-3 {
                (lo.x, hi.x)
            } else {
                let xa = a.x + (py - reach - a.y) / along.y * along.x;
                let xb = a.x + (py + reach - a.y) / along.y * along.x;
                (xa.min(xb).max(lo.x) - reach, xa.max(xb).min(hi.x) + reach)
            };
            for x in x0.floor() as i64..=x1.ceil() as i64 {
                let p = egui::vec2(x as f32 + 0.5, py);
                let t = ((p - a).dot(along) / length_sq).clamp(0.0, 1.0);
                let distance = (p - (a + along * t)).length();
                self.blend(x, y, color, width / 2.0 + 0.5 - distance);
            }
        }
    }

    /// A filled diamond (a square on its corner) `radius` pixels from centre to corner.
    fn diamond(&mut self, centre: egui::Vec2, radius: f32, color: Color32) {
        let reach = radius.ceil() as i64 + 1;
        let (cx, cy) = (centre.x.floor() as i64, centre.y.floor() as i64);
        for y in cy - reach..=cy + reach {
            for x in cx - reach..=cx + reach {
                let d = (x as f32 + 0.5 - centre.x).abs() + (y as f32 + 0.5 - centre.y).abs();
                self.blend(x, y, color, (radius - d) / std::f32::consts::SQRT_2 + 0.5);
            }
        }
    }
}

impl egui_plot::PlotItem for TakePath<'_> {
    fn shapes(&self, ui: &egui::Ui, transform: &egui_plot::PlotTransform, shapes: &mut Vec<egui::Shape>) {
        let pixels_per_point = ui.ctx().pixels_per_point();
        let key = PathKey { take: self.take.id, blocks: self.take.path.len(), frame: *transform.frame(), bounds: *transform.bounds(), pixels_per_point };
        let id = ui.scope_id().with("take_path");
        let cached = ui.data(|d| d.get_temp::<CachedPath>(id)).filter(|c| c.key == key);
        let texture = cached.map_or_else(
            || {
                let texture = ui.ctx().load_texture("glocal_take_path", self.draw(transform, pixels_per_point), egui::TextureOptions::NEAREST);
                ui.data_mut(|d| d.insert_temp(id, CachedPath { key, texture: texture.clone() }));
                texture
            },
            |c| c.texture,
        );
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        shapes.push(egui::Shape::image(texture.id(), *transform.frame(), uv, Color32::WHITE));
    }

    fn initialize(&mut self, _x_range: std::ops::RangeInclusive<f64>) {}

    fn color(&self) -> Color32 {
        Color32::from_gray(230)
    }

    fn geometry(&self) -> egui_plot::PlotGeometry<'_> {
        egui_plot::PlotGeometry::None
    }

    /// Nothing of its own: each block sits at a weighted mean of seeds' positions
    /// ([`super::tsne::project`]), inside the seeds' bounds, which the plot already fits.
    fn bounds(&self) -> egui_plot::PlotBounds {
        egui_plot::PlotBounds::NOTHING
    }

    fn base(&self) -> &egui_plot::PlotItemBase {
        &self.base
    }

    fn base_mut(&mut self) -> &mut egui_plot::PlotItemBase {
        &mut self.base
    }
}

/// The seed a click on the map picked: the nearest `shown` one within a few pixels (a class
/// hidden in the key cannot be picked unseen).
fn clicked_seed<R>(resp: &egui_plot::PlotResponse<R>, points: &[[f32; 2]], shown: impl Fn(usize) -> bool) -> Option<usize> {
    if !resp.response.clicked() {
        return None;
    }
    let pos = resp.response.interact_pointer_pos()?;
    let (i, d) = points
        .iter()
        .enumerate()
        .filter(|(i, _)| shown(*i))
        .map(|(i, p)| (i, resp.transform.position_from_point(&egui_plot::PlotPoint::new(p[0], p[1])).distance(pos)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    (d < 10.0).then_some(i)
}
