//! The frames a request holds from an earlier take (see [`super::held`]): plain data the
//! generation options carry and projects save.

use std::borrow::Cow;
use std::ops::Range;
use std::sync::Arc;

use anyhow::{bail, Result};
use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::motion::{LocalPose, Motion, Skeleton};

/// Frames of an earlier take, kept from `first_frame` of the new one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldStretch {
    pub first_frame: usize,
    /// Shared: the studio's undo history holds many requests with the same frames.
    pub frames: Arc<HeldFrames>,
}

impl HeldStretch {
    /// Whether its frames are frames of `skeleton`, or were before it kept the joints that only
    /// turn a chain ([`HeldFrames::fitted`]); a model switch leaves the other model's.
    pub fn fits(&self, skeleton: &Skeleton) -> bool {
        self.frames.fitted(skeleton).check(skeleton, "held stretch").is_ok()
    }
}

/// A held stretch's frames, exactly as the earlier take made them (JSON numbers are written
/// in the shortest form that reads back to the same `f32`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum HeldFrames {
    /// Per frame: the root's position (x, y, z), then each joint's local rotation
    /// (x, y, z, w); the other joints sit at the skeleton's offsets.
    Poses(Vec<Vec<f32>>),
    /// Per frame: each joint's world position (x, y, z), for takes without bone rotations.
    Positions(Vec<Vec<f32>>),
}

impl HeldFrames {
    /// Frames `range` of `motion`.
    pub fn capture(motion: &Motion, range: Range<usize>) -> Self {
        match &motion.local_poses {
            Some(poses) => HeldFrames::Poses(poses[range].iter().map(|p| std::iter::once(p.translations[0]).flat_map(|v| v.to_array()).chain(p.rotations.iter().flat_map(|q| q.to_array())).collect()).collect()),
            None => HeldFrames::Positions(range.map(|f| motion.frame(f).iter().flat_map(|v| v.to_array()).collect()).collect()),
        }
    }

    pub fn len(&self) -> usize {
        match self {
            HeldFrames::Poses(f) | HeldFrames::Positions(f) => f.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The frames on `skeleton`: as they are, or, saved before the skeleton kept the joints that
    /// only turn a chain ([`Skeleton::with_turning_joints`]: a project of Human3.6M's 27-joint
    /// model), with each such joint put back at its parent (positions) and with no turn of its
    /// own (poses: the chain it turns keeps its saved turn from the parent, which it now takes
    /// from that joint).
    pub fn fitted(&self, skeleton: &Skeleton) -> Cow<'_, HeldFrames> {
        let identity = |_: &[f32]| Quat::IDENTITY.to_array().to_vec();
        let frames = match self {
            HeldFrames::Poses(f) => f.iter().map(|f| f.get(3..).and_then(|turns| skeleton.with_turning_joints(turns, 4, identity)).map(|turns| [&f[..3], &turns[..]].concat())).collect::<Option<Vec<_>>>().map(HeldFrames::Poses),
            HeldFrames::Positions(f) => f.iter().map(|f| skeleton.with_turning_joints(f, 3, <[f32]>::to_vec)).collect::<Option<Vec<_>>>().map(HeldFrames::Positions),
        };
        match frames {
            Some(frames) if !self.is_empty() => Cow::Owned(frames),
            _ => Cow::Borrowed(self),
        }
    }

    /// Checks each frame's numbers against `skeleton`: their count, and that all are finite.
    pub(super) fn check(&self, skeleton: &Skeleton, what: &str) -> Result<()> {
        let j = skeleton.len();
        let (frames, width, kind) = match self {
            HeldFrames::Poses(f) => (f, 3 + 4 * j, "a root position and a rotation per joint"),
            HeldFrames::Positions(f) => (f, 3 * j, "a position per joint"),
        };
        if let Some((k, frame)) = frames.iter().enumerate().find(|(_, f)| f.len() != width) {
            bail!("{what}, frame {k}: {width} numbers expected ({kind} of the model's {j} joints), got {}", frame.len());
        }
        if let Some(k) = frames.iter().position(|f| f.iter().any(|v| !v.is_finite())) {
            bail!("{what}, frame {k}: holds a number that is not finite");
        }
        Ok(())
    }

    /// The local poses, with the other joints at the skeleton's offsets (None for positions).
    pub(super) fn local_poses(&self, skeleton: &Skeleton) -> Option<Vec<LocalPose>> {
        let HeldFrames::Poses(frames) = self else { return None };
        let pose = |f: &Vec<f32>| {
            let mut translations = skeleton.offsets().to_vec();
            translations[0] = Vec3::new(f[0], f[1], f[2]);
            let rotations = f[3..].chunks_exact(4).map(|q| Quat::from_xyzw(q[0], q[1], q[2], q[3])).collect();
            LocalPose { rotations, translations }
        };
        Some(frames.iter().map(pose).collect())
    }

    /// World positions of every frame (forward kinematics of the poses, as the take made them).
    pub(super) fn positions(&self, skeleton: &Arc<Skeleton>, fps: f32) -> Vec<Vec3> {
        match self {
            HeldFrames::Poses(_) => Motion::from_local_poses(skeleton.clone(), fps, self.local_poses(skeleton).unwrap_or_default()).positions().to_vec(),
            HeldFrames::Positions(frames) => frames.iter().flat_map(|f| f.chunks_exact(3).map(|v| Vec3::new(v[0], v[1], v[2]))).collect(),
        }
    }
}
