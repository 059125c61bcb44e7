//! The timeline widget: a time ruler with the playback cursor and the selected range, and
//! the timeline's segments as coloured, labelled blocks. It edits nothing itself: it
//! returns [`Action`]s for the app to apply.
//!
//! Mouse: click or drag on the ruler scrubs, shift-drag on it selects a range; click a
//! block to select it, double-click to select its frames, drag its right edge to resize,
//! drag its body to reorder; right-click for class, reroll, lock, duplicate and delete; the
//! dice on a block rerolls it, the padlock locks it. Under the
//! segments, a track of keys (diamonds) and one of root-path waypoints (dots; hollow when
//! the waypoint has no time of its own and sits where arc length spreads it): click to
//! select, drag to move in time, right-click to delete.

use egui::{pos2, vec2, Align2, Color32, CursorIcon, FontId, Rect, Sense, Stroke, StrokeKind};

use super::viewport::CONTACT_RGB;
use crate::motion::contacts::{runs, FootContacts};
use crate::motion::Side;
use crate::synth::constraints::{Key, RootPath};
use crate::synth::render::class_color;
use crate::synth::{SegmentSpan, Timeline};
use crate::synth::timeline::spelled;

/// The shortest segment the timeline allows, in seconds.
pub const MIN_SECONDS: f32 = 0.4;

#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Select(Option<usize>),
    /// The start of a drag that edits (for undo: one step per drag).
    BeginEdit,
    Resize { index: usize, seconds: f32 },
    Move { from: usize, to: usize },
    SetClass { index: usize, class: String },
    Duplicate(usize),
    Delete(usize),
    /// A new variation seed for the segment: it alone is generated again.
    Reroll(usize),
    /// Locks or unlocks the segment: a locked one keeps its frames through other edits.
    ToggleLock(usize),
    Seek(usize),
    SetSelection(Option<(usize, usize)>),
    /// A key or waypoint clicked (None: cleared).
    SelectMark(Option<Mark>),
    /// A key or waypoint dragged to a time (seconds from the take's start).
    MoveMark { mark: Mark, seconds: f32 },
    DeleteMark(Mark),
    /// A waypoint goes back to being spread by arc length.
    ClearWaypointTime(usize),
}

/// A key or a root-path waypoint on its track.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    Key(usize),
    Waypoint(usize),
}

pub struct Input<'a> {
    pub timeline: &'a Timeline,
    pub classes: &'a [String],
    /// The generated take's segments, when it matches the timeline.
    pub spans: Option<&'a [SegmentSpan]>,
    pub frames: usize,
    pub fps: f32,
    pub frame: usize,
    pub selection: Option<(usize, usize)>,
    pub selected: Option<usize>,
    pub keys: &'a [Key],
    pub path: Option<&'a RootPath>,
    /// Each waypoint's time as the take will pass it ([`waypoint_times`]).
    pub waypoint_times: &'a [f32],
    pub selected_mark: Option<Mark>,
    /// The take's foot contacts (per frame), drawn on the feet track.
    pub contacts: Option<&'a FootContacts>,
}

#[derive(Clone, Copy, Debug)]
enum Drag {
    Resize { index: usize, start_seconds: f32, start_x: f32 },
    Move { index: usize },
    Scrub,
    Range { anchor: usize },
    Mark(Mark),
}

/// What the widget remembers between frames.
#[derive(Default)]
pub struct TimelineState {
    drag: Option<Drag>,
    /// Pixels per second, held while a drag edits durations so the blocks don't rescale.
    frozen_scale: Option<f32>,
    /// What the pointer is over, for the line under the timeline (tooltips there would cover
    /// the transport bar).
    hint: Option<String>,
}

impl TimelineState {
    pub fn hint(&self) -> Option<&str> {
        self.hint.as_deref()
    }
}

/// Fill of a segment whose class the model does not have (no class colour is this dark).
const UNKNOWN_FILL: Color32 = Color32::from_rgb(60, 40, 40);

pub fn class_index(classes: &[String], name: &str) -> Option<usize> {
    classes.iter().position(|c| c.eq_ignore_ascii_case(name))
}

pub fn color32(rgb: [u8; 3]) -> Color32 {
    Color32::from_rgb(rgb[0], rgb[1], rgb[2])
}

/// Draws the timeline in the available width; returns what the user did.
pub fn timeline_ui(ui: &mut egui::Ui, state: &mut TimelineState, input: &Input) -> Vec<Action> {
    state.hint = None;
    let layout = Layout::new(ui, state, input);
    let mut pass = Pass { input, painter: ui.painter_at(layout.outer.expand(2.0)), visuals: ui.visuals().clone(), layout, actions: Vec::new() };
    pass.ruler(ui, state);
    let pointer = ui.input(|i| i.pointer.interact_pos());
    pass.segments(ui, state);
    let tracks = [pass.layout.key_track, pass.layout.path_track];
    marks_ui(ui, state, input, &pass.painter, tracks, pass.layout.scale, &mut pass.actions);
    contacts_track(&pass.painter, &pass.visuals, input, pass.layout.feet_track, pass.layout.scale);
    pass.drags(ui, state, pointer);
    pass.empty_lane(ui);
    pass.selection_and_cursor();
    pass.actions
}

/// Where the timeline's rows are, and how seconds map to pixels.
struct Layout {
    outer: Rect,
    ruler: Rect,
    lane: Rect,
    key_track: Rect,
    path_track: Rect,
    feet_track: Rect,
    /// Pixels per second.
    scale: f32,
    fps: f32,
    /// Each segment's start, in seconds, and the timeline's end.
    starts: Vec<f32>,
    end: f32,
}

impl Layout {
    fn new(ui: &mut egui::Ui, state: &TimelineState, input: &Input) -> Self {
        let width = ui.available_width().max(100.0);
        let (ruler_h, lane_h, track_h) = (20.0, 44.0, 16.0);
        let (outer, _) = ui.allocate_exact_size(vec2(width, ruler_h + lane_h + 3.0 * (track_h + 2.0) + 6.0), Sense::hover());
        let ruler = Rect::from_min_size(outer.min, vec2(width, ruler_h));
        let below = |r: Rect, h: f32| Rect::from_min_size(pos2(outer.left(), r.bottom() + 2.0), vec2(width, h));
        let lane = below(ruler, lane_h);
        let key_track = below(lane, track_h);
        let path_track = below(key_track, track_h);
        let feet_track = below(path_track, track_h);
        let total = input.timeline.seconds().max(1.0);
        let scale = state.frozen_scale.unwrap_or((width - 8.0) / total);
        let mut starts = Vec::with_capacity(input.timeline.segments.len());
        let mut end = 0.0;
        for s in &input.timeline.segments {
            starts.push(end);
            end += s.seconds;
        }
        Self { outer, ruler, lane, key_track, path_track, feet_track, scale, fps: input.fps.max(1.0), starts, end }
    }

    fn x_of(&self, t: f32) -> f32 {
        self.outer.left() + t * self.scale
    }

    fn frame_at(&self, x: f32) -> usize {
        (((x - self.outer.left()) / self.scale).max(0.0) * self.fps).round() as usize
    }
}

/// One frame's drawing of the timeline: what it draws with and the actions it collects.
struct Pass<'a> {
    input: &'a Input<'a>,
    layout: Layout,
    painter: egui::Painter,
    visuals: egui::Visuals,
    actions: Vec<Action>,
}

impl Pass<'_> {
    /// The ruler: seconds, and scrubbing or selecting a range.
    fn ruler(&mut self, ui: &mut egui::Ui, state: &mut TimelineState) {
        let (at, visuals) = (&self.layout, &self.visuals);
        let ruler = at.ruler;
        self.painter.rect_filled(ruler, 3.0, visuals.extreme_bg_color);
        let step = [0.5f32, 1.0, 2.0, 5.0, 10.0, 30.0, 60.0].into_iter().find(|s| s * at.scale >= 48.0).unwrap_or(120.0);
        let mut t = 0.0;
        while at.x_of(t) <= at.outer.right() {
            let x = at.x_of(t);
            self.painter.line_segment([pos2(x, ruler.bottom() - 6.0), pos2(x, ruler.bottom())], Stroke::new(1.0, visuals.weak_text_color()));
            self.painter.text(pos2(x + 3.0, ruler.center().y - 2.0), Align2::LEFT_CENTER, format!("{t}s"), FontId::proportional(11.0), visuals.weak_text_color());
            t += step;
        }
        let ruler_resp = ui.interact(ruler, ui.scope_id().with("ruler"), Sense::click_and_drag()).on_hover_cursor(CursorIcon::Text);
        ruler_resp.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Slider, true, "Timeline ruler"));
        if ruler_resp.hovered() {
            state.hint = Some("Ruler: click or drag to scrub; shift-drag to select a range".into());
        }
        let Some(pos) = ruler_resp.interact_pointer_pos() else { return };
        let last = self.input.frames.saturating_sub(1);
        let f = at.frame_at(pos.x).min(last);
        if ruler_resp.drag_started() || ruler_resp.clicked() {
            // A range starts where the button went down: by the time egui calls it a drag
            // the pointer has moved a few pixels (1-4 frames) on.
            let pressed = ui.input(|i| i.pointer.press_origin()).map_or(f, |p| at.frame_at(p.x).min(last));
            state.drag = Some(if ui.input(|i| i.modifiers.shift) { Drag::Range { anchor: pressed } } else { Drag::Scrub });
        }
        match state.drag {
            Some(Drag::Range { anchor }) => {
                let (a, b) = (anchor.min(f), anchor.max(f) + 1);
                self.actions.push(Action::SetSelection((b > a + 1).then_some((a, b))));
            }
            _ => self.actions.push(Action::Seek(f)),
        }
    }

    /// The segments' lane: a block per segment.
    fn segments(&mut self, ui: &mut egui::Ui, state: &mut TimelineState) {
        self.painter.rect_filled(self.layout.lane, 3.0, self.visuals.faint_bg_color);
        let moving = match state.drag {
            Some(Drag::Move { index }) => Some(index),
            _ => None,
        };
        for k in 0..self.input.timeline.segments.len() {
            self.segment(ui, state, k, moving == Some(k));
        }
    }

    /// Segment `k`'s block (faded while it is being moved), its menu and its resize handle.
    fn segment(&mut self, ui: &mut egui::Ui, state: &mut TimelineState, k: usize, moving: bool) {
        let (input, lane) = (self.input, self.layout.lane);
        let seg = &input.timeline.segments[k];
        let (x0, x1) = (self.layout.x_of(self.layout.starts[k]), self.layout.x_of(self.layout.starts[k] + seg.seconds));
        let rect = Rect::from_min_max(pos2(x0 + 1.0, lane.top() + 2.0), pos2(x1 - 1.0, lane.bottom() - 2.0));
        let known = class_index(input.classes, &seg.class);
        let fill = known.map_or(UNKNOWN_FILL, |c| color32(class_color(c)));
        let made = input.spans.and_then(|spans| spans.get(k)).map(|span| (span.end_frame - span.start_frame) as f32 / input.fps);
        let label = segment_label(seg, k, known.is_some(), made);
        let id = ui.scope_id().with(("segment", k));
        let resp = ui.interact(rect, id, Sense::click_and_drag());
        resp.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Button, true, format!("Segment {}: {}", k + 1, seg.class)));
        self.painter.rect_filled(rect, 4.0, if moving { fill.gamma_multiply(0.35) } else { fill });
        let stroke = if input.selected == Some(k) {
            Stroke::new(2.0, Color32::WHITE)
        } else if known.is_none() {
            Stroke::new(2.0, Color32::from_rgb(230, 60, 60))
        } else {
            Stroke::new(1.0, fill.gamma_multiply(0.6))
        };
        self.painter.rect_stroke(rect, 4.0, stroke, StrokeKind::Inside);
        let icons = self.segment_icons(ui, state, k, rect);
        let text_painter = self.painter.with_clip_rect(Rect::from_min_max(rect.min, pos2(icons, rect.max.y)).shrink(3.0));
        text_painter.text(rect.left_center() + vec2(6.0, 0.0), Align2::LEFT_CENTER, &label, FontId::proportional(13.0), Color32::WHITE);
        if resp.hovered() {
            let unknown = if known.is_none() { " · this model has no such class: right-click to choose one" } else { "" };
            let locked = if seg.locked { " · locked: its frames stay through other edits" } else { "" };
            let seed = seg.seed.map(|n| format!(" · seed #{n}")).unwrap_or_default();
            state.hint = Some(format!("Segment {}: {label}{seed}{unknown}{locked} · drag to reorder, drag the right edge to resize, right-click for more", k + 1));
        }
        self.segment_clicks(&resp, state, k);
        self.resize_handle(ui, state, k, x1, id);
    }

    /// The dice (reroll) and padlock (lock) buttons at the top right of segment `k`'s block
    /// `rect`, where it is wide enough; returns where the label must end.
    fn segment_icons(&mut self, ui: &mut egui::Ui, state: &mut TimelineState, k: usize, rect: Rect) -> f32 {
        const SIZE: f32 = 14.0;
        let locked = self.input.timeline.segments[k].locked;
        if rect.width() < 4.0 * SIZE {
            return rect.right();
        }
        let top = rect.top() + 3.0;
        let lock_rect = Rect::from_min_size(pos2(rect.right() - SIZE - 8.0, top), vec2(SIZE, SIZE));
        let dice_rect = lock_rect.translate(vec2(-SIZE - 4.0, 0.0));
        let (lock_name, lock_hint) = if locked { ("Unlock", "unlock it: edits of the others may regenerate it") } else { ("Lock", "lock it: it keeps its frames through edits of the others") };
        let buttons = [
            (dice_rect, format!("Reroll segment {}", k + 1), "reroll it: a new variation of this segment alone, the rest of the take kept".to_string(), Action::Reroll(k)),
            (lock_rect, format!("{lock_name} segment {}", k + 1), lock_hint.to_string(), Action::ToggleLock(k)),
        ];
        for (r, name, hint, action) in buttons {
            let resp = ui.interact(r, ui.scope_id().with((name.as_str(), k)), Sense::click());
            resp.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Button, true, &name));
            let strong = resp.hovered() || (locked && action == Action::ToggleLock(k));
            let color = if strong { Color32::WHITE } else { Color32::from_white_alpha(150) };
            match action {
                Action::Reroll(_) => paint_dice(&self.painter, r, color),
                _ => paint_padlock(&self.painter, r, color, locked),
            }
            if resp.hovered() {
                state.hint = Some(format!("Segment {}: {hint}", k + 1));
            }
            if resp.clicked() {
                self.actions.push(action);
            }
        }
        dice_rect.left() - 2.0
    }

    /// Selecting, selecting the frames of, moving, and the right-click menu of segment `k`.
    fn segment_clicks(&mut self, resp: &egui::Response, state: &mut TimelineState, k: usize) {
        let input = self.input;
        // A right-click selects the block its menu is about, as a left click does.
        if resp.clicked() || resp.secondary_clicked() {
            self.actions.push(Action::Select(Some(k)));
        }
        if resp.double_clicked() {
            if let Some(s) = input.spans.and_then(|s| s.get(k)) {
                self.actions.push(Action::SetSelection(Some((s.start_frame, s.end_frame))));
            }
        }
        if resp.drag_started() {
            state.drag = Some(Drag::Move { index: k });
            self.actions.push(Action::Select(Some(k)));
        }
        let actions = &mut self.actions;
        resp.context_menu(|ui| {
            ui.menu_button("Class", |ui| {
                for c in input.classes {
                    if ui.selectable_label(input.timeline.segments[k].class.eq_ignore_ascii_case(c), c).clicked() {
                        actions.push(Action::SetClass { index: k, class: c.clone() });
                        ui.close();
                    }
                }
            });
            if ui.button("Reroll").clicked() {
                actions.push(Action::Reroll(k));
                ui.close();
            }
            if ui.button(if input.timeline.segments[k].locked { "Unlock" } else { "Lock" }).clicked() {
                actions.push(Action::ToggleLock(k));
                ui.close();
            }
            if ui.button("Duplicate").clicked() {
                actions.push(Action::Duplicate(k));
                ui.close();
            }
            if ui.button("Delete").clicked() {
                actions.push(Action::Delete(k));
                ui.close();
            }
        });
    }

    /// The resize handle over segment `k`'s right edge (at `x1`), on top of the block.
    fn resize_handle(&mut self, ui: &mut egui::Ui, state: &mut TimelineState, k: usize, x1: f32, id: egui::Id) {
        let lane = self.layout.lane;
        let handle = Rect::from_min_max(pos2(x1 - 6.0, lane.top()), pos2(x1 + 3.0, lane.bottom()));
        let h = ui.interact(handle, id.with("edge"), Sense::drag()).on_hover_cursor(CursorIcon::ResizeHorizontal);
        if h.drag_started() {
            let x = h.interact_pointer_pos().map_or(x1, |p| p.x);
            state.drag = Some(Drag::Resize { index: k, start_seconds: self.input.timeline.segments[k].seconds, start_x: x });
            state.frozen_scale = Some(self.layout.scale);
            self.actions.push(Action::BeginEdit);
            self.actions.push(Action::Select(Some(k)));
        }
        if h.hovered() || matches!(state.drag, Some(Drag::Resize { index, .. }) if index == k) {
            self.painter.line_segment([pos2(x1 - 2.0, lane.top() + 6.0), pos2(x1 - 2.0, lane.bottom() - 6.0)], Stroke::new(2.0, Color32::WHITE));
        }
    }

    /// The drag under way, if any, followed to the `pointer`; a release ends it.
    fn drags(&mut self, ui: &egui::Ui, state: &mut TimelineState, pointer: Option<egui::Pos2>) {
        let released = ui.input(|i| !i.pointer.any_down());
        match (state.drag, pointer) {
            (Some(Drag::Resize { index, start_seconds, start_x }), Some(p)) => {
                let seconds = ((start_seconds + (p.x - start_x) / self.layout.scale) * 10.0).round() / 10.0;
                let seconds = seconds.max(MIN_SECONDS);
                if self.input.timeline.segments.get(index).is_some_and(|s| (s.seconds - seconds).abs() > 1e-4) {
                    self.actions.push(Action::Resize { index, seconds });
                }
            }
            (Some(Drag::Move { index }), Some(p)) => self.move_drag(state, index, p, released),
            (Some(Drag::Mark(mark)), Some(p)) => {
                let fps = self.layout.fps;
                let seconds = (((p.x - self.layout.outer.left()) / self.layout.scale).max(0.0) * fps).round() / fps;
                self.actions.push(Action::MoveMark { mark, seconds });
            }
            _ => {}
        }
        if released {
            state.drag = None;
            state.frozen_scale = None;
        }
    }

    /// Segment `index` dragged to the pointer at `p`: the insertion marker where it would
    /// land, and the move once `released`.
    fn move_drag(&mut self, state: &mut TimelineState, index: usize, p: egui::Pos2, released: bool) {
        let (at, segments) = (&self.layout, &self.input.timeline.segments);
        // Where it would land: after every other block whose centre is left of the pointer.
        let others: Vec<usize> = (0..segments.len()).filter(|&j| j != index).collect();
        let to = others.iter().filter(|&&j| at.x_of(at.starts[j] + segments[j].seconds / 2.0) < p.x).count();
        let slot_x = if to == 0 { at.x_of(0.0) } else { at.x_of(at.starts[others[to - 1]] + segments[others[to - 1]].seconds) };
        // The insertion marker: a bar with a notch above and below.
        let (lane, accent) = (at.lane, Color32::from_rgb(255, 210, 80));
        self.painter.line_segment([pos2(slot_x, lane.top() - 2.0), pos2(slot_x, lane.bottom() + 2.0)], Stroke::new(3.0, accent));
        for (y, dy) in [(lane.top() - 2.0, 6.0), (lane.bottom() + 2.0, -6.0)] {
            self.painter.add(egui::Shape::convex_polygon(vec![pos2(slot_x - 6.0, y), pos2(slot_x + 6.0, y), pos2(slot_x, y + dy)], accent, Stroke::NONE));
        }
        state.hint = Some(format!("Release to move segment {} to position {}", index + 1, to + 1));
        if released && to != index {
            self.actions.push(Action::BeginEdit);
            self.actions.push(Action::Move { from: index, to });
        }
    }

    /// Clicks on the empty lane after the last segment clear the segment selection.
    fn empty_lane(&mut self, ui: &mut egui::Ui) {
        let (lane, end_x) = (self.layout.lane, self.layout.x_of(self.layout.end));
        if end_x < lane.right() - 4.0 {
            let empty = Rect::from_min_max(pos2(end_x + 4.0, lane.top()), lane.max);
            if ui.interact(empty, ui.scope_id().with("empty"), Sense::click()).clicked() {
                self.actions.push(Action::Select(None));
            }
        }
    }

    /// The selected range and the playback cursor, over everything.
    fn selection_and_cursor(&self) {
        let (at, input) = (&self.layout, self.input);
        let (top, bottom) = (at.ruler.top(), at.feet_track.bottom());
        if let Some((a, b)) = input.selection {
            let r = Rect::from_min_max(pos2(at.x_of(a as f32 / at.fps), top), pos2(at.x_of(b as f32 / at.fps), bottom));
            self.painter.rect_filled(r, 0.0, Color32::from_rgba_unmultiplied(120, 180, 255, 40));
            self.painter.rect_stroke(r, 0.0, Stroke::new(1.0, Color32::from_rgb(120, 180, 255)), StrokeKind::Inside);
        }
        if input.frames > 0 {
            let x = at.x_of(input.frame as f32 / at.fps);
            let c = Color32::from_rgb(255, 90, 60);
            self.painter.line_segment([pos2(x, top), pos2(x, bottom)], Stroke::new(2.0, c));
            self.painter.add(egui::Shape::convex_polygon(vec![pos2(x - 5.0, top), pos2(x + 5.0, top), pos2(x, top + 7.0)], c, Stroke::NONE));
        }
    }
}

/// A segment block's text: its class (with a question mark when the model lacks it) and the
/// style it asks for, as the command line spells them (`walking/tired`), duration (and the take's, `made`, where the rounding to whole sparse steps at its pace
/// changed it), pace and transition.
fn segment_label(seg: &crate::synth::Segment, k: usize, known: bool, made: Option<f32>) -> String {
    let class = if known { seg.class.clone() } else { format!("{}?", seg.class) };
    let name = spelled(&class, seg.style.as_deref());
    let mut length = format!("{:.1}s", seg.seconds);
    if let Some(made) = made.filter(|m| (m - seg.seconds).abs() >= 0.05) {
        length.push_str(&format!(" (makes {made:.2}s)"));
    }
    let mut label = match seg.pace {
        Some(p) => format!("{name} · {length} · pace {p:.2}"),
        None => format!("{name} · {length}"),
    };
    if let Some(t) = seg.transition.filter(|_| k > 0) {
        label.push_str(&format!(" · in {t:.1}s"));
    }
    label
}

/// A die's face in `r`: a rounded square with three pips on its diagonal.
fn paint_dice(painter: &egui::Painter, r: Rect, color: Color32) {
    painter.rect_stroke(r.shrink(1.0), 3.0, Stroke::new(1.5, color), StrokeKind::Inside);
    for t in [0.3, 0.5, 0.7] {
        painter.circle_filled(r.lerp_inside(vec2(t, t)), 1.4, color);
    }
}

/// A padlock in `r`: its shackle closed on the body when `locked`, raised and open otherwise.
fn paint_padlock(painter: &egui::Painter, r: Rect, color: Color32, locked: bool) {
    let body = Rect::from_min_max(r.lerp_inside(vec2(0.15, 0.5)), r.lerp_inside(vec2(0.85, 1.0)));
    if locked {
        painter.rect_filled(body, 2.0, color);
    } else {
        painter.rect_stroke(body, 2.0, Stroke::new(1.5, color), StrokeKind::Inside);
    }
    let lift = if locked { 0.0 } else { 0.15 };
    let (left, right) = (r.lerp_inside(vec2(0.3, 0.5)), r.lerp_inside(vec2(0.7, 0.5)));
    let top = |p: egui::Pos2| pos2(p.x, r.lerp_inside(vec2(0.0, 0.1 - lift * 0.5)).y);
    let shackle = vec![pos2(left.x, left.y - r.height() * lift), top(left), top(right), pos2(right.x, right.y - if locked { 0.0 } else { r.height() * 0.3 })];
    painter.add(egui::Shape::line(shackle, Stroke::new(1.5, color)));
}

/// Colour of keys on their track (and in the viewport's key list).
pub const KEY_COLOR: Color32 = Color32::from_rgb(255, 210, 80);
/// Colour of the root path and its waypoints.
pub const PATH_COLOR: Color32 = Color32::from_rgb(80, 220, 200);

/// The key and path tracks: a diamond per key, a dot per waypoint.
fn marks_ui(ui: &mut egui::Ui, state: &mut TimelineState, input: &Input, painter: &egui::Painter, tracks: [Rect; 2], scale: f32, actions: &mut Vec<Action>) {
    let visuals = ui.visuals().clone();
    let x_of = |t: f32| tracks[0].left() + t * scale;
    for (track, name) in tracks.iter().zip(["keys", "path"]) {
        painter.rect_filled(*track, 2.0, visuals.faint_bg_color);
        painter.text(track.right_center() - vec2(4.0, 0.0), Align2::RIGHT_CENTER, name, FontId::proportional(10.0), visuals.weak_text_color());
    }
    let keys = input.keys.iter().enumerate().map(|(k, key)| (Mark::Key(k), key.seconds, true));
    let waypoints = input.path.map_or(&[][..], |p| p.waypoints.as_slice());
    let points = waypoints.iter().zip(input.waypoint_times).enumerate().map(|(k, (w, &t))| (Mark::Waypoint(k), t, w.seconds.is_some()));
    for (mark, seconds, timed) in keys.chain(points) {
        let (track, color, label) = match mark {
            Mark::Key(k) => (tracks[0], KEY_COLOR, format!("Key {}", k + 1)),
            Mark::Waypoint(k) => (tracks[1], PATH_COLOR, format!("Waypoint {}", k + 1)),
        };
        let centre = pos2(x_of(seconds), track.center().y);
        let rect = Rect::from_center_size(centre, vec2(12.0, track.height()));
        let resp = ui.interact(rect, ui.scope_id().with(("mark", format!("{mark:?}"))), Sense::click_and_drag());
        resp.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Button, true, &label));
        let selected = input.selected_mark == Some(mark);
        let stroke = Stroke::new(if selected { 2.0 } else { 1.0 }, if selected { Color32::WHITE } else { color });
        let r = 5.0;
        let fill = if timed { color } else { Color32::TRANSPARENT };
        match mark {
            Mark::Key(_) => {
                let diamond = vec![centre + vec2(0.0, -r - 1.0), centre + vec2(r + 1.0, 0.0), centre + vec2(0.0, r + 1.0), centre + vec2(-r - 1.0, 0.0)];
                painter.add(egui::Shape::convex_polygon(diamond, fill, stroke));
            }
            Mark::Waypoint(_) => {
                painter.circle(centre, r, fill, stroke);
            }
        }
        if resp.hovered() {
            let when = if timed { format!("{seconds:.2} s") } else { format!("about {seconds:.2} s (spread by arc length)") };
            state.hint = Some(format!("{label} at {when} · drag to move in time, right-click to delete"));
        }
        if resp.clicked() {
            actions.push(Action::SelectMark(Some(mark)));
        }
        if resp.drag_started() {
            state.drag = Some(Drag::Mark(mark));
            state.frozen_scale = Some(scale);
            actions.push(Action::BeginEdit);
            actions.push(Action::SelectMark(Some(mark)));
        }
        resp.context_menu(|ui| {
            if let Mark::Waypoint(k) = mark {
                if ui.add_enabled(timed, egui::Button::new("Spread by arc length")).clicked() {
                    actions.push(Action::ClearWaypointTime(k));
                    ui.close();
                }
            }
            if ui.button("Delete").clicked() {
                actions.push(Action::DeleteMark(mark));
                ui.close();
            }
        });
    }
}

/// Colour of the planted feet on the feet track, the viewport's.
const CONTACT_COLOR: Color32 = {
    let [r, g, b] = CONTACT_RGB;
    Color32::from_rgb(r, g, b)
};

/// The feet track: where each foot is planted, the left foot above the right, one bar per
/// stance.
fn contacts_track(painter: &egui::Painter, visuals: &egui::Visuals, input: &Input, track: Rect, scale: f32) {
    painter.rect_filled(track, 2.0, visuals.faint_bg_color);
    if let Some(contacts) = input.contacts {
        let fps = input.fps.max(1.0);
        let half = track.height() / 2.0;
        for (row, side) in Side::BOTH.into_iter().enumerate() {
            let top = track.top() + row as f32 * half;
            for (x0, x1) in stance_bars(contacts.side(side), scale / fps) {
                let (x0, x1) = (track.left() + x0, track.left() + x1);
                painter.rect_filled(Rect::from_min_max(pos2(x0, top + 1.5), pos2(x1, top + half - 1.5)), 1.0, CONTACT_COLOR);
            }
        }
    }
    // Over the bars, which reach the take's end.
    painter.text(track.right_center() - vec2(4.0, 0.0), Align2::RIGHT_CENTER, "feet", FontId::proportional(10.0), visuals.text_color());
}

/// A foot's stances as bars on the feet track, `pixels_per_frame` wide a frame, from the
/// track's left: stances less than a pixel apart make one bar, each at least a pixel wide.
/// A ten-minute take has more stances than the track has pixels; one bar each cost more to
/// draw every frame than the rest of the timeline.
fn stance_bars(planted: &[bool], pixels_per_frame: f32) -> Vec<(f32, f32)> {
    let mut bars: Vec<(f32, f32)> = Vec::new();
    for std::ops::Range { start, end } in runs(planted) {
        let (x0, x1) = (start as f32 * pixels_per_frame, end as f32 * pixels_per_frame);
        match bars.last_mut() {
            Some(last) if x0 <= last.1 + 1.0 => last.1 = last.1.max(x1),
            _ => bars.push((x0, x1)),
        }
    }
    for bar in &mut bars {
        bar.1 = bar.1.max(bar.0 + 1.0);
    }
    bars
}

/// When the take passes each waypoint: its own time where it has one; between two timed
/// waypoints (or the take's start and end) the others are spread by arc length.
pub fn waypoint_times(path: &RootPath, take_seconds: f32) -> Vec<f32> {
    let w = &path.waypoints;
    let mut times: Vec<Option<f32>> = w.iter().map(|p| p.seconds).collect();
    if let Some(first) = times.first_mut() {
        first.get_or_insert(0.0);
    }
    if let Some(last) = times.last_mut() {
        last.get_or_insert(take_seconds.max(0.0));
    }
    let mut along = vec![0.0f32; w.len()];
    for k in 1..w.len() {
        along[k] = along[k - 1] + ((w[k].x - w[k - 1].x).powi(2) + (w[k].z - w[k - 1].z).powi(2)).sqrt();
    }
    let timed: Vec<usize> = (0..w.len()).filter(|&k| times[k].is_some()).collect();
    let mut out: Vec<f32> = times.iter().map(|t| t.unwrap_or(0.0)).collect();
    for pair in timed.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let (ta, tb, span) = (out[a], out[b], along[b] - along[a]);
        for k in a + 1..b {
            let f = if span > 1e-6 { (along[k] - along[a]) / span } else { (k - a) as f32 / (b - a) as f32 };
            out[k] = ta + (tb - ta) * f;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::constraints::Waypoint;

    #[test]
    fn stances_closer_than_a_pixel_make_one_bar() {
        // Three stances: the first two two frames apart, the third ten frames on.
        let mut planted = vec![false; 30];
        for t in (2..5).chain(7..9).chain(19..22) {
            planted[t] = true;
        }
        // Half a pixel a frame: the first gap is one pixel, the second five.
        assert_eq!(stance_bars(&planted, 0.5), vec![(1.0, 4.5), (9.5, 11.0)]);
        // Ten pixels a frame: every stance its own bar.
        assert_eq!(stance_bars(&planted, 10.0), vec![(20.0, 50.0), (70.0, 90.0), (190.0, 220.0)]);
    }

    #[test]
    fn untimed_waypoints_are_spread_by_arc_length() {
        let wp = |x: f32, z: f32, seconds: Option<f32>| Waypoint { x, z, seconds };
        let path = RootPath { waypoints: vec![wp(0.0, 0.0, None), wp(1.0, 0.0, None), wp(1.0, 3.0, Some(8.0)), wp(1.0, 4.0, None)] };
        let t = waypoint_times(&path, 10.0);
        assert_eq!(t, vec![0.0, 2.0, 8.0, 10.0]);
    }
}
