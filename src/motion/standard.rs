//! The game-ready humanoid every dataset is retargeted onto for the model of everything
//! (`models/all`): Mixamo's joint names (which Unity's and Unreal's humanoid mappers and
//! Blender's retargeting add-ons recognise), metres, y up, facing +z, standing in a T-pose
//! with every rotation identity, feet on the floor.
//!
//! Why a skeleton of its own rather than one of the datasets': Human3.6M's layout has no
//! usable spine and carries duplicate joints, CMU's two layouts differ from each other, and
//! Bandai's rest is not a standing pose (its joints' frames carry the exporter's joint orients),
//! so an engine importing it would need a pose fix. Bone lengths are an adult's of about
//! 1.75 m (Bandai's actor's proportions, rounded); toe ends give the feet a tip to stand on.

use std::sync::Arc;

use glam::Vec3;

use super::Skeleton;

/// Joints of the standard humanoid: name, parent (by name), offset from the parent in metres.
const JOINTS: [(&str, Option<&str>, [f32; 3]); 24] = [
    ("Hips", None, [0.0, 0.95, 0.0]),
    ("Spine", Some("Hips"), [0.0, 0.10, 0.0]),
    ("Spine1", Some("Spine"), [0.0, 0.14, 0.0]),
    ("Neck", Some("Spine1"), [0.0, 0.22, 0.0]),
    ("Head", Some("Neck"), [0.0, 0.10, 0.02]),
    ("HeadTop_End", Some("Head"), [0.0, 0.18, 0.0]),
    ("LeftShoulder", Some("Spine1"), [0.04, 0.17, 0.0]),
    ("LeftArm", Some("LeftShoulder"), [0.13, 0.0, 0.0]),
    ("LeftForeArm", Some("LeftArm"), [0.28, 0.0, 0.0]),
    ("LeftHand", Some("LeftForeArm"), [0.25, 0.0, 0.0]),
    ("RightShoulder", Some("Spine1"), [-0.04, 0.17, 0.0]),
    ("RightArm", Some("RightShoulder"), [-0.13, 0.0, 0.0]),
    ("RightForeArm", Some("RightArm"), [-0.28, 0.0, 0.0]),
    ("RightHand", Some("RightForeArm"), [-0.25, 0.0, 0.0]),
    ("LeftUpLeg", Some("Hips"), [0.09, -0.05, 0.0]),
    ("LeftLeg", Some("LeftUpLeg"), [0.0, -0.42, 0.0]),
    ("LeftFoot", Some("LeftLeg"), [0.0, -0.41, 0.0]),
    ("LeftToeBase", Some("LeftFoot"), [0.0, -0.07, 0.12]),
    ("LeftToe_End", Some("LeftToeBase"), [0.0, 0.0, 0.07]),
    ("RightUpLeg", Some("Hips"), [-0.09, -0.05, 0.0]),
    ("RightLeg", Some("RightUpLeg"), [0.0, -0.42, 0.0]),
    ("RightFoot", Some("RightLeg"), [0.0, -0.41, 0.0]),
    ("RightToeBase", Some("RightFoot"), [0.0, -0.07, 0.12]),
    ("RightToe_End", Some("RightToeBase"), [0.0, 0.0, 0.07]),
];

/// The standard humanoid (see the module's documentation).
pub fn standard_humanoid() -> Arc<Skeleton> {
    let index = |name: &str| JOINTS.iter().position(|(n, _, _)| *n == name).expect("parents are listed before their children");
    let names = JOINTS.iter().map(|(n, _, _)| n.to_string()).collect();
    let parents = JOINTS.iter().map(|(_, p, _)| p.map(index)).collect();
    let offsets = JOINTS.iter().map(|(_, _, o)| Vec3::from_array(*o)).collect();
    Arc::new(Skeleton::new(names, parents, offsets, 1.0).expect("the standard humanoid is a valid skeleton"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::{guess_key_joints, Key, RestPose};

    #[test]
    fn the_standard_humanoid_stands_on_the_floor_in_a_t_pose_with_every_key_found() {
        let skeleton = standard_humanoid();
        let keys = guess_key_joints(&skeleton);
        assert!(keys.missing_required().is_empty(), "missing {:?}", keys.missing_required());
        assert_eq!(keys.get(Key::Chest), skeleton.index_of("Spine1"));
        assert_eq!(RestPose::detect(&skeleton, &keys), RestPose::TPose);
        let lowest = skeleton.rest_positions().iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        assert!(lowest.abs() < 1e-6, "the toes stand at {lowest} m");
    }
}
