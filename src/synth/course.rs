//! A travelling class keeps a straight course where the take has no root path. Human3.6M's
//! subjects walk round their capture room, and its model's walking, and `all`'s, mostly
//! theirs, went round in circles of about a metre's radius (`all`'s 35-40 degrees a second
//! from every one of its seed windows, Bandai's straight walks included): not what an
//! animator asking for a walk, or a game engine's locomotion clip, expects. Each block of a travelling class has its mean
//! turn taken out of its heading changes, so the body sways and steps as made and its
//! course stays where the block found it; a path (`--path`) lays out any other course.

use super::plan::{PlannedBlock, TakeConstraint};
use crate::data::features::ROOT_FEATURES;
use crate::model::block::BlockWorkspace;
use crate::model::glocal::GlocalModel;
use crate::model::glogen::GloGen;

/// A class travels when its seed windows' root moves at least this fast over the ground
/// (m/s): every walk, run and sidestep of the shipped models (the slowest `all`'s walking at
/// 0.72, Human3.6M's at 0.75), none of the activities that only move about (soccer 0.61;
/// salsa 0.51, which spins at 90 degrees a second).
const TRAVELLING_M_S: f32 = 0.65;

/// The sparse feature that is the heading change since the pose before.
const HEADING_CHANGE: usize = ROOT_FEATURES - 1;

pub(super) struct HoldCourse {
    /// Per class: whether it travels.
    travelling: Vec<bool>,
    /// The heading change's normalisation (mean, spread).
    heading_norm: (f32, f32),
    dim: usize,
    block_len: usize,
}

impl HoldCourse {
    /// The course keeping of `model`'s takes, when its model.json asks for it.
    pub fn new(model: &GlocalModel) -> Option<Self> {
        let spec = &model.spec;
        if !spec.hold_course {
            return None;
        }
        let (dim, block_len) = (spec.layout.dim(), spec.block_len);
        let metres_per_second = spec.layout.skeleton.meters_per_unit() * spec.fps / spec.stride as f32;
        let mut sums = vec![(0.0f32, 0usize); spec.classes.len()];
        for seed in &model.seeds {
            let Some((sum, count)) = sums.get_mut(seed.class) else { continue };
            for pose in seed.features.chunks_exact(dim) {
                *sum += pose[1].hypot(pose[2]);
                *count += 1;
            }
        }
        let travelling = sums.iter().map(|&(sum, count)| count > 0 && sum / count as f32 * metres_per_second >= TRAVELLING_M_S).collect();
        let heading_norm = (spec.sparse_norm.mean[HEADING_CHANGE], spec.sparse_norm.std[HEADING_CHANGE]);
        Some(Self { travelling, heading_norm, dim, block_len })
    }
}

impl TakeConstraint for HoldCourse {
    fn on_block(&self, block: &PlannedBlock<'_>, _rollout: (&GloGen, &mut BlockWorkspace), sparse: &mut [f32]) {
        if !self.travelling.get(block.plan.target).copied().unwrap_or(false) {
            return;
        }
        let (mean, spread) = self.heading_norm;
        let start = sparse.len() - self.block_len * self.dim;
        let poses = &mut sparse[start..];
        // Normalised values: the raw turn is `v * spread + mean`.
        let turn = poses.chunks_exact(self.dim).map(|p| p[HEADING_CHANGE] * spread + mean).sum::<f32>() / self.block_len as f32;
        let shift = turn / spread;
        poses.chunks_exact_mut(self.dim).for_each(|p| p[HEADING_CHANGE] -= shift);
    }
}
