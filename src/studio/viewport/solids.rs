//! The instances a frame draws: bones as cylinders, joints as spheres, floor marks as
//! flattened spheres, in linear colour, sorted into opaque and translucent draw ranges.

use glam::{Mat4, Quat, Vec3};

use super::render::Instance;

fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub(super) fn linear_rgba(rgb: [u8; 3], lighten: f32, alpha: f32) -> [f32; 4] {
    let [r, g, b] = rgb.map(|c| {
        let l = srgb_to_linear(c);
        l + (1.0 - l) * lighten
    });
    [r, g, b, alpha]
}

/// Instances of one frame, split into the four draw ranges.
#[derive(Default)]
pub(super) struct Solids {
    bones: Vec<Instance>,
    joints: Vec<Instance>,
    /// Translucent ones with their distance from the eye (drawn far to near).
    blend_bones: Vec<(f32, Instance)>,
    blend_joints: Vec<(f32, Instance)>,
}

impl Solids {
    pub(super) fn push(&mut self, bone: bool, translucent: bool, eye: Vec3, centre: Vec3, instance: Instance) {
        match (bone, translucent) {
            (true, false) => self.bones.push(instance),
            (false, false) => self.joints.push(instance),
            (true, true) => self.blend_bones.push((eye.distance(centre), instance)),
            (false, true) => self.blend_joints.push((eye.distance(centre), instance)),
        }
    }

    pub(super) fn finish(mut self) -> (Vec<Instance>, [u32; 4]) {
        let far_first = |a: &(f32, Instance), b: &(f32, Instance)| b.0.total_cmp(&a.0);
        self.blend_bones.sort_by(far_first);
        self.blend_joints.sort_by(far_first);
        let counts = [self.bones.len(), self.joints.len(), self.blend_bones.len(), self.blend_joints.len()].map(|c| c as u32);
        let mut all = self.bones;
        all.append(&mut self.joints);
        all.extend(self.blend_bones.into_iter().map(|b| b.1));
        all.extend(self.blend_joints.into_iter().map(|b| b.1));
        (all, counts)
    }
}

pub(super) fn sphere(centre: Vec3, radius: f32, color: [f32; 4]) -> Instance {
    let model = Mat4::from_scale_rotation_translation(Vec3::splat(radius), Quat::IDENTITY, centre);
    Instance { model: model.to_cols_array_2d(), color }
}

/// A sphere squashed to a disc lying on the floor (a waypoint, a planted foot's mark).
pub(super) fn floor_disc(centre: Vec3, radius: f32, thickness: f32, color: [f32; 4]) -> Instance {
    let model = Mat4::from_scale_rotation_translation(Vec3::new(radius, thickness, radius), Quat::IDENTITY, centre);
    Instance { model: model.to_cols_array_2d(), color }
}

pub(super) fn cylinder(a: Vec3, b: Vec3, radius: f32, color: [f32; 4]) -> Option<Instance> {
    let d = b - a;
    let len = d.length();
    if len < 1e-6 {
        return None;
    }
    let rotation = Quat::from_rotation_arc(Vec3::Y, d / len);
    let model = Mat4::from_scale_rotation_translation(Vec3::new(radius, len, radius), rotation, a);
    Some(Instance { model: model.to_cols_array_2d(), color })
}
