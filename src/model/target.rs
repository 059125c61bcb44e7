//! Where a target-conditioned GloGen must arrive ([`super::spec::GloGenSpec::target`]): the
//! next key's pose, how far it stands from the context's last pose and how many sparse steps
//! are left to it, read beside the class by every step of the block. This is the in-between
//! models' target and time-to-arrival input (Harvey et al. 2020); training draws the targets
//! from the real clip ahead of each window.

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
}
