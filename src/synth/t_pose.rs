//! An exported skeleton's rest pose turned into a T-pose, for conventions whose tools expect
//! one (Mixamo rigs and Unity's Humanoid avatar stand in a T-pose): spine, neck and head
//! straight up, arms straight out sideways, legs straight down, feet and toes forward. Every
//! frame keeps its joint positions; only the rest the rotations are measured from changes.
//!
//! Each joint's rest frame is turned by a rotation `C` (the shortest arc from its old rest
//! direction towards its child to the T-pose direction; joints with no direction of their
//! own turn with their parent). A child's offset turns with its parent's `C`, and each
//! local rotation becomes `C_parent * L * C^-1`, so world rotations are `W * C^-1` and
//! `W * C^-1 * (C * offset) = W * offset`: every position is where it was.

use std::sync::Arc;

use anyhow::Result;
use glam::{Quat, Vec3};

use crate::motion::{Key, KeyJoints, LocalPose, Motion, Skeleton};

/// Offsets shorter than this fraction of the longest give no direction to aim.
const MIN_AIM_FRACTION: f32 = 1e-3;

/// The take on the same skeleton with a T-pose rest; `keys` are its key joints.
pub fn in_t_pose(motion: &Motion, keys: &KeyJoints) -> Result<Motion> {
    let s = &motion.skeleton;
    let turns = rest_turns(s, keys);
    let offsets = (0..s.len()).map(|j| s.parents()[j].map_or(s.offsets()[j], |p| turns[p] * s.offsets()[j])).collect();
    let skeleton = Arc::new(Skeleton::new(s.names().to_vec(), s.parents().to_vec(), offsets, s.meters_per_unit())?);
    let mut out = match &motion.local_poses {
        Some(poses) if poses.len() == motion.frames() => {
            let turned = poses.iter().map(|pose| turned_pose(s, &turns, pose)).collect();
            Motion::from_local_poses(skeleton, motion.fps, turned)
        }
        // Positions alone: BVH and glTF export solve the rotations against the new rest.
        _ => Motion::from_positions(skeleton, motion.fps, motion.positions().to_vec()),
    };
    out.fps = motion.fps;
    Ok(out)
}

fn turned_pose(s: &Skeleton, turns: &[Quat], pose: &LocalPose) -> LocalPose {
    let parent_turn = |j: usize| s.parents()[j].map_or(Quat::IDENTITY, |p| turns[p]);
    LocalPose {
        rotations: (0..s.len()).map(|j| parent_turn(j) * pose.rotations[j] * turns[j].inverse()).collect(),
        translations: (0..s.len()).map(|j| parent_turn(j) * pose.translations[j]).collect(),
    }
}

/// Each joint's rest turn `C`, parents before children (joint order).
fn rest_turns(s: &Skeleton, keys: &KeyJoints) -> Vec<Quat> {
    let aims = aims(s, keys);
    let longest = s.offsets().iter().fold(0.0f32, |m, o| m.max(o.length()));
    let mut turns = vec![Quat::IDENTITY; s.len()];
    for j in 0..s.len() {
        let inherited = s.parents()[j].map_or(Quat::IDENTITY, |p| turns[p]);
        turns[j] = match aims[j] {
            Some((child, target)) if s.offsets()[child].length() > MIN_AIM_FRACTION * longest => Quat::from_rotation_arc(s.offsets()[child].normalize(), target),
            _ => inherited,
        };
    }
    turns
}

/// Per joint, the child its bone points at and the T-pose direction of that bone.
fn aims(s: &Skeleton, keys: &KeyJoints) -> Vec<Option<(usize, Vec3)>> {
    use Key::*;
    let rest = s.rest_positions();
    let at = |k: Key| keys.get(k).map(|j| rest[j]);
    let left = match (at(LeftUpLeg), at(RightUpLeg)) {
        (Some(l), Some(r)) => Vec3::new(l.x - r.x, 0.0, l.z - r.z).normalize_or(Vec3::X),
        _ => Vec3::X,
    };
    let forward = left.cross(Vec3::Y);
    let mut aims = vec![None; s.len()];
    aim_chain(s, keys, &mut aims, Hips, Head, Vec3::Y);
    let ends = [(Head, Vec3::Y), (LeftHand, left), (RightHand, -left), (LeftToeBase, forward), (RightToeBase, forward)];
    for (side, [shoulder, arm, hand], [thigh, foot, toes]) in [
        (left, [LeftShoulder, LeftArm, LeftHand], [LeftUpLeg, LeftFoot, LeftToeBase]),
        (-left, [RightShoulder, RightArm, RightHand], [RightUpLeg, RightFoot, RightToeBase]),
    ] {
        aim_chain(s, keys, &mut aims, if keys.get(shoulder).is_some() { shoulder } else { arm }, hand, side);
        aim_chain(s, keys, &mut aims, thigh, foot, -Vec3::Y);
        aim_chain(s, keys, &mut aims, foot, toes, forward);
    }
    for (end, target) in ends {
        if let Some(j) = keys.get(end) {
            aims[j] = farthest_child(s, &rest, j).map(|c| (c, target));
        }
    }
    // The hips keep their rest: their legs and spine hang from them in every direction.
    if let Some(hips) = keys.get(Hips) {
        aims[hips] = None;
    }
    aims
}

/// Every joint from key `from` down to (not including) key `to` aims at its child on the way
/// to `to`, along `target`; nothing when `to` is not below `from`.
fn aim_chain(s: &Skeleton, keys: &KeyJoints, aims: &mut [Option<(usize, Vec3)>], from: Key, to: Key, target: Vec3) {
    let (Some(top), Some(mut child)) = (keys.get(from), keys.get(to)) else { return };
    let mut path = Vec::new();
    while let Some(parent) = s.parents()[child] {
        path.push((parent, child));
        if parent == top {
            for (joint, towards) in path {
                aims[joint] = Some((towards, target));
            }
            return;
        }
        child = parent;
    }
}

fn farthest_child(s: &Skeleton, rest: &[Vec3], joint: usize) -> Option<usize> {
    s.children(joint).max_by(|&a, &b| rest[a].distance(rest[joint]).total_cmp(&rest[b].distance(rest[joint])))
}
