//! A travelling class keeps a straight course where the take has no root path. Human3.6M's
//! subjects walk round their capture room, and its model's walking, and `all`'s, mostly
//! theirs, went round in circles of about a metre's radius (`all`'s 35-40 degrees a second
//! from every one of its seed windows, Bandai's straight walks included): not what an
//! animator asking for a walk, or a game engine's locomotion clip, expects. Each block of a
//! travelling class that goes on from the same class (not the first of a walk set off from
//! another activity or a file: a walker turns as it sets off) has its mean turn taken out of
//! its heading changes, so the body sways and steps as made and its course stays where the
//! block found it; a path (`--path`) lays out any other course.

use super::init::InitPose;
use super::plan::{PlannedBlock, SparseTimeline, TakeConstraint};
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
    /// The class of each sparse pose of the take (the seed block's, the first segment's).
    pose_classes: Vec<usize>,
    /// The class of the seed window the take starts from (none for a file).
    seed_class: Option<usize>,
    /// The heading change's normalisation (mean, spread).
    heading_norm: (f32, f32),
    dim: usize,
    block_len: usize,
}

impl HoldCourse {
    /// The course keeping of `model`'s takes of `timeline` from `init`, when its model.json
    /// asks for it.
    pub fn new(model: &GlocalModel, timeline: &SparseTimeline, init: &InitPose) -> Option<Self> {
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
        let seed_class = match init {
            InitPose::SeedIndex(i) => model.seeds.get(*i).map(|s| s.class),
            InitPose::SeedClass { class, .. } => spec.class_index(class).ok(),
            InitPose::File { .. } => None,
        };
        let pose_classes = timeline.segment_of.iter().map(|&k| timeline.classes[k]).collect();
        let heading_norm = (spec.sparse_norm.mean[HEADING_CHANGE], spec.sparse_norm.std[HEADING_CHANGE]);
        Some(Self { travelling, pose_classes, seed_class, heading_norm, dim, block_len })
    }

    /// Block `b`'s class as its plan has it (the class at its middle pose).
    fn class_of(&self, b: usize) -> Option<usize> {
        let middle = self.block_len * (b + 1) + self.block_len / 2;
        self.pose_classes.get(middle.min(self.pose_classes.len().saturating_sub(1))).copied()
    }

    /// Whether block `b` travels on in the class of the block before it (the seed block's
    /// class being its seed window's): a walk set off from another activity or a file turns
    /// as made in its first block, as a walker sets off; the blocks after it hold.
    fn holds(&self, b: usize) -> bool {
        let Some(class) = self.class_of(b) else { return false };
        let before = if b == 0 { self.seed_class } else { self.class_of(b - 1) };
        self.travelling.get(class).copied().unwrap_or(false) && before == Some(class)
    }
}

impl TakeConstraint for HoldCourse {
    fn on_block(&self, _block: &PlannedBlock<'_>, _rollout: (&GloGen, &mut BlockWorkspace), sparse: &mut [f32]) {
        // The block just made is the last of `sparse`, after the seed block.
        let b = (sparse.len() / (self.block_len * self.dim)).saturating_sub(2);
        if !self.holds(b) {
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
