//! The viewport's camera: an orbit around a centre (the followed root or a free target), moved
//! by the pointer (orbit, pan, zoom) and fitted to the scene.

use glam::{Mat4, Vec3};

use super::{Scene, Viewport};

/// Vertical field of view.
const FOV_Y: f32 = 40.0 * std::f32::consts::PI / 180.0;

pub(super) const START_CAMERA: Camera = Camera { yaw: 0.6, pitch: 0.3, distance: 4.0, target: Vec3::new(0.0, 0.9, 0.0), pan: Vec3::ZERO };

#[derive(Clone, Copy, Debug)]
pub(super) struct Camera {
    /// Radians about +y; 0 looks from +z towards -z.
    yaw: f32,
    /// Radians above the horizon.
    pitch: f32,
    pub(super) distance: f32,
    /// Orbit centre when not following the root.
    pub(super) target: Vec3,
    /// Orbit centre relative to the followed root point when following.
    pub(super) pan: Vec3,
}

impl Camera {
    pub(super) fn back(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(cp * sy, sp, cp * cy)
    }
}

impl Viewport {
    /// The followed point: the layers' mean root ground position at the current frame, at the
    /// mean height of their bodies.
    pub(super) fn follow_point(&self, scene: &Scene) -> Vec3 {
        let mut sum = Vec3::ZERO;
        let mut height = 0.0;
        let mut n = 0.0;
        for (layer, info) in scene.layers.iter().zip(&self.layers) {
            let m = &layer.motion;
            if m.frames() == 0 || m.joints() == 0 {
                continue;
            }
            let p = m.frame(scene.frame.min(m.frames() - 1))[info.root] * m.skeleton.meters_per_unit() + layer.offset;
            sum += Vec3::new(p.x, 0.0, p.z);
            height += info.centre_height;
            n += 1.0;
        }
        if n == 0.0 {
            return self.camera.target;
        }
        let ground = self.ground();
        Vec3::new(sum.x / n, ground + height / n, sum.z / n)
    }

    pub(super) fn handle_input(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let cam = &mut self.camera;
        let shift = ui.input(|i| i.modifiers.shift);
        let delta = response.drag_delta();
        let primary = response.dragged_by(egui::PointerButton::Primary);
        let pan = response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) || (primary && shift);
        if pan {
            // Move the target so the point under the cursor follows it.
            let units_per_point = 2.0 * cam.distance * (FOV_Y / 2.0).tan() / rect.height().max(1.0);
            let back = cam.back();
            let right = Vec3::Y.cross(back).normalize_or_zero();
            let up = back.cross(right);
            let shift = (-right * delta.x + up * delta.y) * units_per_point;
            cam.target += shift;
            cam.pan += shift;
        } else if primary {
            cam.yaw -= delta.x * 0.008;
            cam.pitch = (cam.pitch + delta.y * 0.008).clamp(-1.45, 1.45);
        }
        if response.hovered() {
            let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta.y, i.zoom_delta()));
            // A wheel notch (about 50 points) zooms by 5%.
            let factor = (-scroll * 0.001).exp() / zoom.max(1e-3);
            cam.distance = (cam.distance * factor).clamp(0.2, 500.0);
        }
    }

    /// The camera's view-projection and eye for an orbit centre and aspect ratio.
    pub(super) fn view_proj(&self, target: Vec3, aspect: f32) -> (Mat4, Vec3) {
        let cam = self.camera;
        let eye = target + cam.back() * cam.distance;
        let view = Mat4::look_at_rh(eye, target, Vec3::Y);
        let near = (cam.distance * 0.01).clamp(0.005, 1.0);
        let far = cam.distance * 4.0 + 200.0;
        (Mat4::perspective_rh(FOV_Y, aspect.max(1e-3), near, far) * view, eye)
    }

    /// Fits the view: with follow-root, around the current poses; else the whole take.
    pub(super) fn frame_scene(&mut self, scene: &Scene, follow_point: Vec3) {
        let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for (layer, info) in scene.layers.iter().zip(&self.layers) {
            let m = &layer.motion;
            if m.frames() == 0 {
                continue;
            }
            if scene.settings.follow_root {
                let mpu = m.skeleton.meters_per_unit();
                let frame = m.frame(scene.frame.min(m.frames() - 1));
                for &j in &info.joints {
                    let p = frame[j] * mpu + layer.offset;
                    min = min.min(p);
                    max = max.max(p);
                }
            } else {
                min = min.min(info.min + layer.offset);
                max = max.max(info.max + layer.offset);
            }
        }
        if !min.is_finite() || !max.is_finite() {
            return;
        }
        let centre = (min + max) / 2.0;
        let radius = ((max - min).length() / 2.0).max(0.6);
        self.camera.distance = (radius / (FOV_Y / 2.0).sin() * 1.4).clamp(0.2, 500.0);
        self.camera.target = centre;
        self.camera.pan = if scene.settings.follow_root { Vec3::new(0.0, centre.y - follow_point.y, 0.0) } else { Vec3::ZERO };
    }
}
