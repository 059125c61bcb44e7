//! Posing by hand: in pose mode, handles on the take's hands, feet, head and hips; a drag
//! that starts on one poses the frame on screen ([`PoseRig`]), a drag anywhere else still
//! orbits. Hands, the head and the hips move on the plane facing the camera through the
//! joint; feet on the level plane through the ankle, so a foot slides at its height and a
//! planted one stays on the floor. The edited pose is drawn while dragging and after the
//! release until the take or the frame changes; the release hands it to the studio
//! ([`Viewport::take_posed`]), which keys it.
//!
//! Handles are painted by egui over the 3D image (six circles), so they are always visible
//! and cost nothing of the scene's frame time.

use std::sync::Arc;

use egui::{Color32, Stroke};
use glam::Vec3;

use super::{Scene, Viewport, GRAB_POINTS};
use crate::motion::{Effector, Motion, Skeleton};

/// A pose made by dragging a handle, released: the studio keys it at its frame.
#[derive(Clone, Debug, PartialEq)]
pub struct PosedFrame {
    pub frame: usize,
    /// World positions on the take's skeleton, in its units.
    pub pose: Vec<Vec3>,
    /// The hips were dragged: the key also fixes where the body stands.
    pub moves_root: bool,
}

/// The viewport's posing state.
#[derive(Default)]
pub(super) struct Posing {
    /// Pose mode is on (and the studio allows it: a take of its own on screen, paused).
    pub(super) enabled: bool,
    drag: Option<Drag>,
    /// The pose last made, drawn in place of the take's frame while it is the same take
    /// and frame (until the take made through it arrives).
    shown: Option<Shown>,
    released: Option<PosedFrame>,
}

struct Drag {
    effector: Effector,
    /// The frame on screen, as the drag found it (take units), and its skeleton.
    frame: usize,
    base: Vec<Vec3>,
    skeleton: Arc<Skeleton>,
    /// The plane the joint moves on (a point and its normal, metres).
    plane: (Vec3, Vec3),
    /// Where the press met the plane, and where the joint was (metres).
    press: Vec3,
    joint: Vec3,
}

struct Shown {
    motion: Arc<Motion>,
    frame: usize,
    pose: Vec<Vec3>,
}

/// Handle colour (sRGB) and radius, points; the hips' is larger.
const HANDLE_RGB: [u8; 3] = [255, 214, 90];
const HANDLE_RADIUS: f32 = 7.0;

impl Viewport {
    /// Turns pose mode on or off (the studio's "Pose by hand" toggle).
    pub fn set_posing(&mut self, enabled: bool) {
        self.posing.enabled = enabled;
        if !enabled {
            self.posing.drag = None;
        }
    }

    /// The pose made by the drag released since the last call.
    pub fn take_posed(&mut self) -> Option<PosedFrame> {
        self.posing.released.take()
    }

    /// Stops drawing the last pose made in place of the take's frame (its key was undone).
    pub fn forget_posed(&mut self) {
        self.posing.shown = None;
    }

    /// The frame `t` of layer `layer` as drawn: the pose being made, on its take and frame.
    pub(super) fn frame_shown<'a>(&'a self, layer: usize, motion: &'a Arc<Motion>, t: usize) -> &'a [Vec3] {
        match &self.posing.shown {
            Some(s) if layer == 0 && s.frame == t && Arc::ptr_eq(&s.motion, motion) => &s.pose,
            _ => motion.frame(t),
        }
    }

    /// Pose mode's pointer handling: a press on a handle starts a drag, which poses the frame
    /// until it is released. Returns whether the pointer was used (the camera then stays).
    pub(super) fn pose_input(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect, scene: &Scene, target: Vec3) -> bool {
        let Some(layer) = scene.layers.first().filter(|l| l.motion.frames() > 0) else { return false };
        let frame = scene.frame.min(layer.motion.frames() - 1);
        if self.posing.shown.as_ref().is_some_and(|s| s.frame != frame || !Arc::ptr_eq(&s.motion, &layer.motion)) {
            self.posing.shown = None;
        }
        if !self.posing.enabled {
            return false;
        }
        if response.drag_started_by(egui::PointerButton::Primary) && !ui.input(|i| i.modifiers.shift) {
            let origin = ui.input(|i| i.pointer.press_origin()).or_else(|| response.interact_pointer_pos());
            self.posing.drag = origin.and_then(|o| self.start_drag(o, rect, scene, target));
        }
        let Some(drag) = &self.posing.drag else { return false };
        // Another frame (scrubbing) or a take on another skeleton (a model switch) ends the
        // drag: the pose it edits is no longer the one on screen.
        let rig = self.layers.first().and_then(|i| i.rig.as_ref()).filter(|_| frame == drag.frame && *layer.motion.skeleton == *drag.skeleton);
        let Some(rig) = rig else {
            self.posing.drag = None;
            return true;
        };
        let pointer = response.interact_pointer_pos().or_else(|| ui.input(|i| i.pointer.interact_pos()));
        if let Some(hit) = pointer.and_then(|p| self.plane_point(p, rect, target, drag.plane)) {
            let goal = (drag.joint + hit - drag.press - layer.offset) / drag.skeleton.meters_per_unit();
            let pose = rig.posed(&drag.skeleton, &drag.base, drag.effector, goal);
            self.posing.shown = Some(Shown { motion: layer.motion.clone(), frame, pose });
        }
        if !response.dragged() {
            let effector = self.posing.drag.take().map(|d| d.effector);
            let posed = self.posing.shown.as_ref().filter(|s| s.frame == frame);
            self.posing.released = posed.zip(effector).map(|(s, e)| PosedFrame { frame, pose: s.pose.clone(), moves_root: e.moves_root() });
        }
        true
    }

    /// A drag of the handle under `origin`, if one is.
    fn start_drag(&self, origin: egui::Pos2, rect: egui::Rect, scene: &Scene, target: Vec3) -> Option<Drag> {
        let (effector, joint, _) = self.handles(scene, rect, target).into_iter().filter(|(_, _, at)| at.distance(origin) <= GRAB_POINTS).min_by(|a, b| a.2.distance(origin).total_cmp(&b.2.distance(origin)))?;
        let normal = if matches!(effector, Effector::Foot(_)) { Vec3::Y } else { self.camera.back() };
        let plane = (joint, normal);
        let press = self.plane_point(origin, rect, target, plane)?;
        let layer = &scene.layers[0];
        let frame = scene.frame.min(layer.motion.frames() - 1);
        let base = self.frame_shown(0, &layer.motion, frame).to_vec();
        Some(Drag { effector, frame, base, skeleton: layer.motion.skeleton.clone(), plane, press, joint })
    }

    /// Each handle: its effector, its joint (metres) and where it shows. None outside pose
    /// mode or without a rig.
    fn handles(&self, scene: &Scene, rect: egui::Rect, target: Vec3) -> Vec<(Effector, Vec3, egui::Pos2)> {
        let (Some(layer), Some(rig)) = (scene.layers.first(), self.layers.first().and_then(|i| i.rig.as_ref())) else { return Vec::new() };
        if !self.posing.enabled || layer.motion.frames() == 0 {
            return Vec::new();
        }
        let frame = self.frame_shown(0, &layer.motion, scene.frame.min(layer.motion.frames() - 1));
        let unit = layer.motion.skeleton.meters_per_unit();
        Effector::ALL
            .into_iter()
            .filter_map(|e| {
                let joint = frame[rig.joint(e)] * unit + layer.offset;
                Some((e, joint, self.screen_of(joint, rect, target)?))
            })
            .collect()
    }

    /// Paints the handles over the scene; the one dragged or under the pointer brighter.
    pub(super) fn paint_handles(&self, ui: &egui::Ui, rect: egui::Rect, scene: &Scene, target: Vec3) {
        let hover = ui.input(|i| i.pointer.hover_pos());
        let dragged = self.posing.drag.as_ref().map(|d| d.effector);
        let painter = ui.painter_at(rect);
        let [r, g, b] = HANDLE_RGB;
        for (effector, _, at) in self.handles(scene, rect, target) {
            let lit = dragged == Some(effector) || (dragged.is_none() && hover.is_some_and(|h| h.distance(at) <= GRAB_POINTS));
            let radius = if effector == Effector::Hips { HANDLE_RADIUS * 1.5 } else { HANDLE_RADIUS };
            let fill = Color32::from_rgba_unmultiplied(r, g, b, if lit { 200 } else { 70 });
            painter.circle(at, radius, fill, Stroke::new(if lit { 2.5 } else { 1.5 }, Color32::from_rgb(r, g, b)));
        }
    }
}
