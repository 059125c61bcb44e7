use std::sync::Arc;

use glam::{Quat, Vec3};

use super::contacts::support_heights;
use super::{forward_kinematics, JointRoles, LocalPose, Skeleton};

/// A take: world joint positions over time on one skeleton, optionally with the local
/// joint transforms they came from (kept for exporting rotations, e.g. to BVH).
#[derive(Clone, Debug)]
pub struct Motion {
    pub skeleton: Arc<Skeleton>,
    pub fps: f32,
    /// Frame-major world positions, `frames * joints` long.
    positions: Vec<Vec3>,
    /// Per-frame local transforms, when the source had rotations.
    pub local_poses: Option<Vec<LocalPose>>,
}

impl Motion {
    /// Panics only on a programming error: `positions` must hold whole frames.
    pub fn from_positions(skeleton: Arc<Skeleton>, fps: f32, positions: Vec<Vec3>) -> Self {
        assert_eq!(positions.len() % skeleton.len(), 0, "positions must hold whole frames");
        Self { skeleton, fps, positions, local_poses: None }
    }

    /// Positions by forward kinematics of each local pose; the poses are kept.
    pub fn from_local_poses(skeleton: Arc<Skeleton>, fps: f32, poses: Vec<LocalPose>) -> Self {
        let j = skeleton.len();
        let mut positions = vec![Vec3::ZERO; poses.len() * j];
        let mut world_rot = vec![Quat::IDENTITY; j];
        for (pose, out) in poses.iter().zip(positions.chunks_exact_mut(j)) {
            forward_kinematics(&skeleton, pose, out, &mut world_rot);
        }
        Self { skeleton, fps, positions, local_poses: Some(poses) }
    }

    pub fn frames(&self) -> usize {
        self.positions.len() / self.skeleton.len()
    }

    pub fn joints(&self) -> usize {
        self.skeleton.len()
    }

    pub fn seconds(&self) -> f32 {
        self.frames() as f32 / self.fps
    }

    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    pub fn frame(&self, t: usize) -> &[Vec3] {
        let j = self.joints();
        &self.positions[t * j..(t + 1) * j]
    }

    /// Distance from each joint to its parent in frame `t` (0 for the root).
    pub fn bone_lengths(&self, t: usize) -> Vec<f32> {
        let frame = self.frame(t);
        (0..self.joints())
            .map(|j| self.skeleton.parents()[j].map_or(0.0, |p| frame[j].distance(frame[p])))
            .collect()
    }

    /// The height of the take's floor, where exports and the studio set it: the lowest its
    /// feet go, or its seat on a floor sit ([`support_heights`]); not its lowest joint, which
    /// a hand on the ground would set. A skeleton whose legs are not found falls back to its
    /// lowest joint.
    pub fn floor_height(&self) -> f32 {
        let Ok(roles) = JointRoles::new(&self.skeleton) else { return floor_height(&self.positions) };
        let lowest = support_heights(self, &roles).into_iter().fold(f32::INFINITY, f32::min);
        if lowest.is_finite() {
            lowest
        } else {
            0.0
        }
    }

    /// The take moved by `offset` (positions and the roots' local translations).
    pub fn translated(&self, offset: Vec3) -> Motion {
        let mut moved = self.clone();
        moved.positions.iter_mut().for_each(|p| *p += offset);
        if let Some(poses) = moved.local_poses.as_mut() {
            let roots: Vec<usize> = (0..self.joints()).filter(|&j| self.skeleton.parents()[j].is_none()).collect();
            for pose in poses {
                roots.iter().for_each(|&r| pose.translations[r] += offset);
            }
        }
        moved
    }

    /// Frames `[start, end)` as a new motion.
    pub fn slice(&self, start: usize, end: usize) -> Motion {
        let j = self.joints();
        Motion {
            skeleton: self.skeleton.clone(),
            fps: self.fps,
            positions: self.positions[start * j..end * j].to_vec(),
            local_poses: self.local_poses.as_ref().map(|p| p[start..end].to_vec()),
        }
    }

    /// The same take on a sub-skeleton (see [`Skeleton::subset`]); local poses are dropped
    /// because removed joints' rotations no longer have a place.
    pub fn subset(&self, keep: &[usize]) -> Motion {
        let skeleton = Arc::new(self.skeleton.subset(keep));
        let positions = (0..self.frames()).flat_map(|t| keep.iter().map(move |&k| self.frame(t)[k])).collect();
        Motion::from_positions(skeleton, self.fps, positions)
    }

    /// Resampled to `fps` by linear interpolation of positions (and slerp of local rotations).
    /// An integer ratio (50 -> 25) picks existing frames exactly.
    pub fn resample(&self, fps: f32) -> Motion {
        if (fps - self.fps).abs() < 1e-6 || self.frames() < 2 {
            return Motion { fps, ..self.clone() };
        }
        let frames = ((self.frames() - 1) as f64 * fps as f64 / self.fps as f64).floor() as usize + 1;
        let j = self.joints();
        let mut positions = Vec::with_capacity(frames * j);
        let mut poses = self.local_poses.as_ref().map(|_| Vec::with_capacity(frames));
        for k in 0..frames {
            let src = k as f64 * self.fps as f64 / fps as f64;
            let a = (src.floor() as usize).min(self.frames() - 1);
            let b = (a + 1).min(self.frames() - 1);
            let w = (src - a as f64) as f32;
            let w = if w < 1e-5 { 0.0 } else { w };
            let (fa, fb) = (self.frame(a), self.frame(b));
            positions.extend(fa.iter().zip(fb).map(|(p, q)| p.lerp(*q, w)));
            if let (Some(out), Some(src)) = (poses.as_mut(), self.local_poses.as_ref()) {
                let (pa, pb): (&LocalPose, &LocalPose) = (&src[a], &src[b]);
                out.push(LocalPose {
                    rotations: pa.rotations.iter().zip(&pb.rotations).map(|(x, y)| x.slerp(*y, w)).collect(),
                    translations: pa.translations.iter().zip(&pb.translations).map(|(x, y)| x.lerp(*y, w)).collect(),
                });
            }
        }
        Motion { skeleton: self.skeleton.clone(), fps, positions, local_poses: poses }
    }

    /// Mean relative deviation of bone lengths from the skeleton's rest lengths, over all
    /// frames and every bone at least `min_bone` long.
    pub fn bone_length_error(&self, min_bone: f32) -> f32 {
        let rest = self.skeleton.rest_bone_lengths();
        let bones: Vec<usize> = (0..self.joints()).filter(|&j| rest[j] >= min_bone).collect();
        if bones.is_empty() || self.frames() == 0 {
            return 0.0;
        }
        let mut sum = 0.0f64;
        for t in 0..self.frames() {
            let f = self.frame(t);
            for &b in &bones {
                let p = self.skeleton.parents()[b].expect("bones have parents");
                sum += ((f[b].distance(f[p]) - rest[b]).abs() / rest[b]) as f64;
            }
        }
        (sum / (bones.len() * self.frames()) as f64) as f32
    }
}

/// Per frame of `positions` (`joints` per frame) at `fps`, the largest acceleration of a
/// joint there (the second difference about the frame, per second squared, in the
/// positions' unit); 0 on the first and last frames, which have none.
pub fn peak_accelerations(positions: &[Vec3], joints: usize, fps: f32) -> Vec<f32> {
    let frames = positions.len() / joints.max(1);
    let at = |f: usize| &positions[f * joints..(f + 1) * joints];
    let peak = |f: usize| at(f - 1).iter().zip(at(f)).zip(at(f + 1)).map(|((a, b), c)| (*a - 2.0 * *b + *c).length()).fold(0.0f32, f32::max) * fps * fps;
    (0..frames).map(|f| if f == 0 || f + 1 >= frames { 0.0 } else { peak(f) }).collect()
}

/// The `q` quantile of `v` (the nearest rank), NaN when it is empty.
pub fn quantile(v: &[f32], q: f32) -> f32 {
    if v.is_empty() {
        return f32::NAN;
    }
    let mut s = v.to_vec();
    let k = ((s.len() - 1) as f32 * q).round() as usize;
    *s.select_nth_unstable_by(k, f32::total_cmp).1
}

/// The mean distance a joint moves from one frame to the next over `positions` (`joints` per
/// frame, whole frames): the joint speed per frame step, 0 under two frames.
pub fn mean_joint_step(positions: &[Vec3], joints: usize) -> f64 {
    let frames = positions.len() / joints.max(1);
    if frames < 2 {
        return 0.0;
    }
    let sum: f64 = positions.chunks_exact(joints).zip(positions[joints..].chunks_exact(joints)).map(|(a, b)| a.iter().zip(b).map(|(p, q)| p.distance(*q) as f64).sum::<f64>()).sum();
    sum / ((frames - 1) * joints) as f64
}

/// The height of the lowest of `positions` (0 when there are none).
pub fn floor_height(positions: &[Vec3]) -> f32 {
    let lowest = positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    if lowest.is_finite() {
        lowest
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain() -> Arc<Skeleton> {
        Arc::new(
            Skeleton::new(
                vec!["root".into(), "dup".into(), "tip".into()],
                vec![None, Some(0), Some(1)],
                vec![Vec3::ZERO, Vec3::ZERO, Vec3::new(0.0, 2.0, 0.0)],
                0.01,
            )
            .unwrap(),
        )
    }

    /// One joint at 30 fps moving at 1 unit a frame, one frame 0.5 off its line: that frame
    /// accelerates at 2 x 0.5 x 30^2, the frames either side at half of it.
    #[test]
    fn a_jumping_frame_has_the_peak_acceleration() {
        let mut xs: Vec<Vec3> = (0..8).map(|f| Vec3::new(f as f32, 0.0, 0.0)).collect();
        xs[4].y = 0.5;
        let peaks = peak_accelerations(&xs, 1, 30.0);
        assert_eq!(peaks, vec![0.0, 0.0, 0.0, 450.0, 900.0, 450.0, 0.0, 0.0]);
    }

    #[test]
    fn resample_halves_integer_ratio_exactly() {
        let positions = (0..10).flat_map(|t| [Vec3::splat(t as f32); 3]).collect();
        let m = Motion::from_positions(chain(), 50.0, positions);
        let r = m.resample(25.0);
        assert_eq!(r.frames(), 5);
        assert_eq!(r.frame(2)[0], Vec3::splat(4.0));
    }

    #[test]
    fn subset_keeps_rest_positions() {
        let s = chain();
        let keep = s.informative_joints(1e-6);
        assert_eq!(keep, vec![0, 2]);
        let sub = s.subset(&keep);
        assert_eq!(sub.parents(), vec![None, Some(0)]);
        assert_eq!(sub.offsets()[1], Vec3::new(0.0, 2.0, 0.0));
    }
}
