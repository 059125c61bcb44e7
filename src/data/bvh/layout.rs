//! The channels each joint of a BVH file carries: what a file was read with, and what a
//! motion is written with when no layout is given.

use crate::motion::{EulerOrder, LocalPose, Motion, Skeleton};

/// The channels one joint carries in a BVH file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointChannels {
    /// The order of the joint's rotation channels. A joint that lists fewer than three rotation
    /// channels gets the listed axes first, then the missing ones in X, Y, Z order (the missing
    /// angles are zero, so the rotation is the same).
    pub rotation_order: EulerOrder,
    /// Whether the joint has position channels (they replace its offset).
    pub has_position: bool,
}

/// The per-joint channel layout of a BVH file, in skeleton joint order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BvhLayout {
    pub joints: Vec<JointChannels>,
}

impl BvhLayout {
    /// The layout [`write_bvh`] uses when given none: every root has position channels, every
    /// other joint has them only when the motion's local translations leave its rest offset
    /// (by more than `1e-5 * (1 + |offset|)` in any frame, e.g. Bandai's `Hips`); every joint
    /// rotates in `Z X Y` order.
    pub fn default_for(motion: &Motion) -> BvhLayout {
        let poses = usable_poses(motion);
        Self::default_for_poses(&motion.skeleton, poses.unwrap_or(&[]))
    }

    pub(super) fn default_for_poses(skeleton: &Skeleton, poses: &[LocalPose]) -> BvhLayout {
        let joints = (0..skeleton.len())
            .map(|j| {
                let offset = skeleton.offsets()[j];
                let tol = 1e-5 * (1.0 + offset.length());
                let moves = poses.iter().any(|p| (p.translations[j] - offset).abs().max_element() > tol);
                JointChannels { rotation_order: EulerOrder::ZXY, has_position: skeleton.parents()[j].is_none() || moves }
            })
            .collect();
        BvhLayout { joints }
    }
}

/// The motion's local poses when they fit its skeleton and frame count.
pub(super) fn usable_poses(motion: &Motion) -> Option<&[LocalPose]> {
    let j = motion.skeleton.len();
    motion
        .local_poses
        .as_deref()
        .filter(|p| p.len() == motion.frames() && p.iter().all(|p| p.rotations.len() == j && p.translations.len() == j))
}
