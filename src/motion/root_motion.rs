//! Where a take's travel goes, as game engines ask for it: carried by the hips as captured,
//! taken out so the body moves in place, or carried by an added root joint on the floor under
//! the hips, the root-motion bone Unreal and Unity extract travel and turning from.

use std::sync::Arc;

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::kinematics::LocalPose;
use super::roles::{JointRoles, RolesError};
use super::skeleton::{Skeleton, SkeletonError};
use super::solve::solve_local_poses;
use super::take::Motion;

/// How an exported take carries its travel over the ground and its turning.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum RootMotion {
    /// The hips travel and turn, as generated.
    #[default]
    Travel,
    /// The hips' travel on the ground and their turning are taken out: the body moves in
    /// place, facing where it faced at the first frame.
    InPlace,
    /// A root joint ([`ROOT_BONE`]) on the floor under the hips carries the travel and the
    /// turning; the hips move relative to it.
    RootBone,
}

/// The added root joint's name: Unreal's mannequin and Unity's root-motion import use `root`.
pub const ROOT_BONE: &str = "root";

#[derive(Debug, thiserror::Error)]
pub enum RootMotionError {
    #[error(transparent)]
    Roles(#[from] RolesError),
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    #[error("the skeleton already has a joint named '{ROOT_BONE}'")]
    RootTaken,
}

/// Which way a frame faces about the vertical: 0 facing +z, positive towards +x, from the
/// line through the hips (the heading every feature and export shares).
pub fn facing(frame: &[Vec3], left_hip: usize, right_hip: usize) -> f32 {
    let lateral = frame[right_hip] - frame[left_hip];
    // Facing +z, the right hip lies at -x: up x (right - left) points forward.
    let forward = Vec3::Y.cross(lateral);
    if forward.x.abs() + forward.z.abs() < 1e-8 {
        0.0
    } else {
        forward.x.atan2(forward.z)
    }
}

/// The take with its travel carried as `mode` asks.
pub fn with_root_motion(motion: &Motion, mode: RootMotion) -> Result<Motion, RootMotionError> {
    match mode {
        RootMotion::Travel => Ok(motion.clone()),
        RootMotion::InPlace => in_place(motion),
        RootMotion::RootBone => with_root_bone(motion),
    }
}

/// Per frame, the ground point under the hips and the turn from the first frame's facing.
fn ground_track(motion: &Motion) -> Result<Vec<(Vec3, f32)>, RootMotionError> {
    let roles = JointRoles::new(&motion.skeleton)?;
    let (left, right) = (roles.left.hip, roles.right.hip);
    let first = motion.frames().checked_sub(1).map_or(0.0, |_| facing(motion.frame(0), left, right));
    Ok((0..motion.frames())
        .map(|t| {
            let frame = motion.frame(t);
            (Vec3::new(frame[0].x, 0.0, frame[0].z), facing(frame, left, right) - first)
        })
        .collect())
}

/// `skeleton` under a new root joint `name` at its origin: the old root its child.
pub fn under_new_root(skeleton: &Skeleton, name: &str) -> Result<Arc<Skeleton>, SkeletonError> {
    let names = std::iter::once(name.to_string()).chain(skeleton.names().iter().cloned()).collect();
    let parents = std::iter::once(None).chain(skeleton.parents().iter().map(|p| Some(p.map_or(0, |p| p + 1)))).collect();
    let offsets = std::iter::once(Vec3::ZERO).chain(skeleton.offsets().iter().copied()).collect();
    Ok(Arc::new(Skeleton::new(names, parents, offsets, skeleton.meters_per_unit())?))
}

/// The take's local poses, solved from its positions when it has none.
pub fn local_poses(motion: &Motion) -> Vec<LocalPose> {
    match &motion.local_poses {
        Some(poses) if poses.len() == motion.frames() => poses.clone(),
        _ => solve_local_poses(&motion.skeleton, motion.positions()),
    }
}

/// The body moving in place: every frame carried back so the hips stand over the first
/// frame's ground point, facing the first frame's way.
fn in_place(motion: &Motion) -> Result<Motion, RootMotionError> {
    let track = ground_track(motion)?;
    let Some(&(start, _)) = track.first() else { return Ok(motion.clone()) };
    let poses = local_poses(motion)
        .into_iter()
        .zip(&track)
        .map(|(mut pose, &(ground, turn))| {
            let back = Quat::from_rotation_y(-turn);
            // The root (joint 0) holds the world placement; its height stays.
            pose.translations[0] = start + back * (pose.translations[0] - ground);
            pose.rotations[0] = back * pose.rotations[0];
            pose
        })
        .collect();
    Ok(Motion::from_local_poses(motion.skeleton.clone(), motion.fps, poses))
}

/// A [`ROOT_BONE`] joint above the hips, on the floor under them and turned with them from
/// the first frame's facing; the hips keep the rest of their motion relative to it.
fn with_root_bone(motion: &Motion) -> Result<Motion, RootMotionError> {
    let s = &motion.skeleton;
    if s.index_of(ROOT_BONE).is_some() {
        return Err(RootMotionError::RootTaken);
    }
    let track = ground_track(motion)?;
    let skeleton = under_new_root(s, ROOT_BONE)?;
    let poses = local_poses(motion)
        .into_iter()
        .zip(&track)
        .map(|(pose, &(ground, turn))| {
            let carry = Quat::from_rotation_y(turn);
            let mut translations = vec![ground];
            translations.extend(pose.translations.iter().enumerate().map(|(j, &v)| if j == 0 { carry.inverse() * (v - ground) } else { v }));
            let mut rotations = vec![carry];
            rotations.extend(pose.rotations.iter().enumerate().map(|(j, &r)| if j == 0 { carry.inverse() * r } else { r }));
            LocalPose { rotations, translations }
        })
        .collect();
    Ok(Motion::from_local_poses(skeleton, motion.fps, poses))
}
