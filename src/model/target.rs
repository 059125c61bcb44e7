//! Where a target-conditioned GloGen must arrive ([`super::spec::GloGenSpec::target`]): the
//! next key's pose, how far it stands from the context's last pose and how many sparse steps
//! are left to it, read beside the class by every step of the block. This is the in-between
//! models' target and time-to-arrival input (Harvey et al. 2020); training draws the targets
//! from the real clip ahead of each window.
//!
//! A block with a target predicts its poses as offsets from the straight way to it
//! ([`straight_way`]): the context's last pose blended linearly into the target's, at the
//! target's mean step, as linear interpolation would go. Untrained, the block is linear
//! interpolation; training only has to learn how real motion differs from it (the two-stage
//! in-betweeners start from the same line, Qin et al. 2022).

use glam::{Quat, Vec3};

use crate::data::features::{wrap, FeatureLayout, Normalizer, Placement, ROOT_FEATURES};

/// Values after the target's pose features: the steps left to it (over one block), whether
/// there is a target at all, and whether its root (where it stands, which way it faces) is
/// pinned.
pub const TARGET_EXTRA: usize = 3;

/// The length of a target's conditioning for poses of `pose_dim` features.
pub fn target_len(pose_dim: usize) -> usize {
    pose_dim + TARGET_EXTRA
}

/// Where a target condition for poses of `pose_dim` features holds its flag (1 with a
/// target, 0 without): after the pose and the steps left.
pub fn target_flag(pose_dim: usize) -> usize {
    pose_dim + 1
}

/// Whether `target` (a [`target_condition`] for poses of `pose_dim` features) holds a target.
pub fn has_target(target: &[f32], pose_dim: usize) -> bool {
    target.len() >= target_len(pose_dim) && target[target_flag(pose_dim)] != 0.0
}

/// A pose a block aims at.
#[derive(Clone, Copy, Debug)]
pub struct Target<'a> {
    /// World positions on the model's skeleton (model units).
    pub pose: &'a [Vec3],
    /// Sparse steps from the context's last pose to the target (at least 1).
    pub steps: f32,
    /// Whether the target's place on the ground and heading count, or only its pose.
    pub fix_root: bool,
}

/// The conditioning of a block aiming at `target` from `from`, where the context's last pose
/// stands: the target's pose features with its displacement and turn from `from` spread over
/// the steps left (so they read like one sparse step of the data), normalised like sparse
/// poses; then the steps left over `block_len`, 1, and whether the root is pinned. Without a
/// target, zeros.
pub fn target_condition(layout: &FeatureLayout, norm: &Normalizer, block_len: usize, from: Placement, target: Option<Target<'_>>) -> Vec<f32> {
    let dim = layout.dim();
    let Some(target) = target else { return vec![0.0; target_len(dim)] };
    let steps = target.steps.max(1.0);
    let mut features = layout.encode(&[target.pose], None);
    let root = target.pose[0];
    let away = Quat::from_rotation_y(-from.heading) * Vec3::new(root.x - from.x, 0.0, root.z - from.z);
    features[1] = away.x / steps;
    features[2] = away.z / steps;
    features[3] = wrap(layout.heading(target.pose) - from.heading) / steps;
    norm.normalize(&mut features);
    if !target.fix_root {
        // The mean step: the target's place is left to the motion.
        features[1..ROOT_FEATURES].fill(0.0);
    }
    features.extend([steps / block_len as f32, 1.0, if target.fix_root { 1.0 } else { 0.0 }]);
    features
}

/// The straight way from `last` (the context's last normalised pose) to the target in
/// `target` (a [`target_condition`]) over a block of `block_len` poses: the pose and the root's
/// height blend linearly into the target's and reach it at its step (and stay), the root
/// walks the straight line to the target at its mean step. `None` without a target.
pub fn straight_way(last: &[f32], target: &[f32], block_len: usize, norm: &Normalizer) -> Option<Vec<f32>> {
    let way = Way::to(target, last.len(), block_len, norm)?;
    Some(way.shares.iter().zip(&way.ends).enumerate().map(|(i, (s, e))| last[i % last.len()] + s * (e - last[i % last.len()])).collect())
}

/// What the straight way to a target is made of, per pose of a block (`block_len * dim`
/// values each): `last + shares * (ends - last)`, so training can form it from a context
/// that is itself a prediction.
pub struct Way {
    /// How much of `ends` each feature has taken: the root's steps all of it, the others
    /// `(k + 1) / steps` up to 1.
    pub shares: Vec<f32>,
    /// The target's features, its root step turned for each pose: a step is taken in the
    /// heading of the pose before it, so with the way's even turn a constant step would bend
    /// into an arc that misses the target; turned back by the turns made so far, the steps
    /// add up to the straight line.
    pub ends: Vec<f32>,
}

impl Way {
    /// The way to `target` (a [`target_condition`] for poses of `dim` features, normalised by
    /// `norm`); `None` without a target.
    pub fn to(target: &[f32], dim: usize, block_len: usize, norm: &Normalizer) -> Option<Self> {
        if !has_target(target, dim) {
            return None;
        }
        let steps = (target[dim] * block_len as f32).max(1.0);
        let raw = |d: usize| target[d] * norm.std[d] + norm.mean[d];
        let (step, turn) = (Vec3::new(raw(1), 0.0, raw(2)), raw(3));
        let (mut shares, mut ends) = (Vec::with_capacity(block_len * dim), Vec::with_capacity(block_len * dim));
        for k in 0..block_len {
            let share = ((k + 1) as f32 / steps).min(1.0);
            shares.extend((0..dim).map(|d| if (1..ROOT_FEATURES).contains(&d) { 1.0 } else { share }));
            let turned = Quat::from_rotation_y(-(k as f32) * turn) * step;
            ends.extend_from_slice(&target[..dim]);
            let at = ends.len() - dim;
            ends[at + 1] = (turned.x - norm.mean[1]) / norm.std[1];
            ends[at + 2] = (turned.z - norm.mean[2]) / norm.std[2];
        }
        Some(Self { shares, ends })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::glocal::GlocalModel;
    use std::path::Path;

    /// A target 2 m ahead (in the context's heading) and 4 steps away reads as a 0.5 m step
    /// forward with no turn; without a pinned root its place is the mean step, and no target
    /// is all zeros.
    #[test]
    fn a_target_reads_as_the_step_towards_it() {
        let model = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/h36m")).unwrap();
        let (layout, dim) = (&model.spec.layout, model.spec.layout.dim());
        let norm = Normalizer { mean: vec![0.0; dim], std: vec![1.0; dim] };
        let pose = layout.decode(&model.seeds[0].features[..dim], Placement { x: 3.0, z: -1.0, heading: 0.7 }).0;
        assert_eq!(pose.len(), layout.joints());
        let heading = layout.heading(&pose);
        let back = Quat::from_rotation_y(heading) * Vec3::new(0.0, 0.0, 2.0);
        let from = Placement { x: pose[0].x - back.x, z: pose[0].z - back.z, heading };
        let pinned = target_condition(layout, &norm, 10, from, Some(Target { pose: &pose, steps: 4.0, fix_root: true }));
        assert_eq!(pinned.len(), target_len(dim));
        assert!((pinned[2] - 0.5).abs() < 1e-4 && pinned[1].abs() < 1e-4 && pinned[3].abs() < 1e-4, "{:?}", &pinned[..4]);
        assert_eq!(&pinned[dim..], &[0.4, 1.0, 1.0]);
        let free = target_condition(layout, &norm, 10, from, Some(Target { pose: &pose, steps: 4.0, fix_root: false }));
        assert_eq!(&free[1..4], &[0.0; 3]);
        assert_eq!(free[dim + 2], 0.0);
        assert!(target_condition(layout, &norm, 10, from, None).iter().all(|&v| v == 0.0));
    }

    /// Two features and a root step: halfway at the first of two steps, there at the second,
    /// held after it; the root steps along the straight line to the target while the way
    /// turns; no target, no way.
    #[test]
    fn the_straight_way_reaches_the_target_at_its_step() {
        let last = [1.0, 0.0, 0.0, 0.0, 2.0];
        let target = [3.0, 0.5, 0.0, 0.1, 4.0, 2.0 / 4.0, 1.0, 1.0];
        let norm = Normalizer { mean: vec![0.0; 5], std: vec![1.0; 5] };
        let way = straight_way(&last, &target, 4, &norm).unwrap();
        let column = |d: usize| way.chunks_exact(5).map(|p| p[d]).collect::<Vec<_>>();
        assert_eq!(column(0), [2.0, 3.0, 3.0, 3.0]);
        assert_eq!(column(4), [3.0, 4.0, 4.0, 4.0]);
        assert_eq!(column(3), [0.1; 4]);
        // Each step turned back by the turns before it: together a straight line.
        let (x, z) = (column(1), column(2));
        let mut heading = 0.0f32;
        let mut at = Vec3::ZERO;
        for k in 0..4 {
            at += Quat::from_rotation_y(heading) * Vec3::new(x[k], 0.0, z[k]);
            heading += 0.1;
            assert!(at.normalize().abs_diff_eq(Vec3::X, 1e-5), "step {k} leaves the line: {at:?}");
        }
        assert!(straight_way(&last, &[0.0; 8], 4, &norm).is_none());
    }
}
