//! Between the screen and the viewport's world (metres): where a point shows, and where the
//! pointer's ray meets a plane (the ground for waypoints, a plane through a dragged joint).

use glam::Vec3;

use super::Viewport;

impl Viewport {
    /// Where a world point (metres) shows in the last frame drawn; None before the first
    /// frame or behind the camera.
    pub fn project(&self, point: Vec3) -> Option<egui::Pos2> {
        let (rect, target) = self.last_view?;
        self.screen_of(point, rect, target)
    }

    /// The direction from the orbit centre to the camera (the normal of the view plane a
    /// hand, the head or the hips are dragged on).
    pub fn towards_camera(&self) -> Vec3 {
        self.camera.back()
    }

    /// Where a world point shows on screen for an orbit centre `target` (None: behind the
    /// camera).
    pub(super) fn screen_of(&self, point: Vec3, rect: egui::Rect, target: Vec3) -> Option<egui::Pos2> {
        let (view_proj, _) = self.view_proj(target, rect.aspect_ratio());
        let clip = view_proj * point.extend(1.0);
        (clip.w > 1e-6).then(|| {
            let ndc = clip.truncate() / clip.w;
            egui::pos2(rect.left() + (ndc.x + 1.0) / 2.0 * rect.width(), rect.top() + (1.0 - ndc.y) / 2.0 * rect.height())
        })
    }

    /// Where the ray through a screen point meets the plane through `point` with `normal`,
    /// if it does in front of the camera.
    pub(super) fn plane_point(&self, pos: egui::Pos2, rect: egui::Rect, target: Vec3, (point, normal): (Vec3, Vec3)) -> Option<Vec3> {
        let (view_proj, _) = self.view_proj(target, rect.aspect_ratio());
        let ndc = |z: f32| Vec3::new((pos.x - rect.left()) / rect.width() * 2.0 - 1.0, 1.0 - (pos.y - rect.top()) / rect.height() * 2.0, z);
        let inverse = view_proj.inverse();
        let (near, far) = (inverse.project_point3(ndc(0.0)), inverse.project_point3(ndc(1.0)));
        let dir = far - near;
        let facing = dir.dot(normal);
        let t = (point - near).dot(normal) / facing;
        (facing.abs() > 1e-6 && t > 0.0 && t.is_finite()).then(|| near + dir * t)
    }

    /// Where the ray through a screen point meets the ground plane (x, z), if it does.
    pub(super) fn ground_point(&self, pos: egui::Pos2, rect: egui::Rect, target: Vec3) -> Option<[f32; 2]> {
        let ground = (Vec3::Y * self.ground(), Vec3::Y);
        self.plane_point(pos, rect, target, ground).map(|p| [p.x, p.z])
    }

    /// Where a ground point shows on screen (None: behind the camera).
    pub(super) fn screen_point(&self, point: [f32; 2], rect: egui::Rect, target: Vec3) -> Option<egui::Pos2> {
        self.screen_of(Vec3::new(point[0], self.ground(), point[1]), rect, target)
    }
}
