use glam::{Quat, Vec3};

use super::Skeleton;

/// One frame's local joint transforms: joint `j` sits at `translations[j]` in its parent's
/// frame, rotated by `rotations[j]` relative to it. For most joints the translation is the
/// rest offset; the root (and joints with position channels in BVH) move it.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalPose {
    pub rotations: Vec<Quat>,
    pub translations: Vec<Vec3>,
}

/// World positions of every joint of one frame (and, in `world_rot`, their world rotations).
pub fn forward_kinematics(skeleton: &Skeleton, pose: &LocalPose, positions: &mut [Vec3], world_rot: &mut [Quat]) {
    for j in 0..skeleton.len() {
        match skeleton.parents()[j] {
            None => {
                world_rot[j] = pose.rotations[j];
                positions[j] = pose.translations[j];
            }
            Some(p) => {
                world_rot[j] = world_rot[p] * pose.rotations[j];
                positions[j] = positions[p] + world_rot[p] * pose.translations[j];
            }
        }
    }
}
