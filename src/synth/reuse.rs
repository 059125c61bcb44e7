//! What a take keeps of how it was made, so the next take of an edited request starts where
//! the edit begins to matter ([`TakeCache`]).
//!
//! Each GloGen block reads the take-wide options (model, start, seed, guidance, stages) and
//! its own part of the timeline: its plan (class mix, easing, the run it belongs to) and its
//! segment's seed. A block's *print* hashes that part; the first block whose print differs
//! from the cached take's is the first block the edit affects. The rollout resumes there from
//! the state the cached take had before it (the steering, the noise streams and the sparse
//! poses), so every block before it is the cached one bit for bit, and every block from it on
//! is computed as a full generation computes it: the result is the full generation's.
//!
//! Keys and held frames warp poses far behind the block being made, so a take with either is
//! not resumed (its print is take-wide and every block is made again).

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use rand::rngs::StdRng;

use super::finish::ChunkRecord;
use super::options::GenerateOptions;
use super::plan::BlockPlan;
use super::steer::Steering;
use crate::model::glocal::GlocalModel;

/// The state a take's rollout carries from block to block, besides its sparse poses.
#[derive(Clone)]
pub(super) struct RolloutState {
    pub steering: Steering,
    /// The take's variation noise.
    pub noise: StdRng,
    /// The segment with its own seed whose blocks are under way, and its noise.
    pub segment_noise: Option<(usize, StdRng)>,
}

/// The rollout as it stood after one block: its state, and the sparse poses the next block's
/// seam join may still move (those before them are final).
#[derive(Clone)]
pub(super) struct Checkpoint {
    pub state: RolloutState,
    pub unsettled: Vec<f32>,
}

/// A finished take's record for the next generation (see the module docs). Empty by default:
/// the first take is made whole.
#[derive(Default)]
pub struct TakeCache {
    pub(super) record: Option<TakeRecord>,
}

pub(super) struct TakeRecord {
    pub take_print: u64,
    pub block_prints: Vec<u64>,
    /// After block `b`: `checkpoints[b]`.
    pub checkpoints: Vec<Checkpoint>,
    /// The normalised sparse poses of the whole rollout, the seed's first.
    pub sparse: Vec<f32>,
    pub embeddings: Vec<Vec<f32>>,
    /// The paced frame of each sparse pose.
    pub times: Vec<f64>,
    /// The take's chunks, when it was finished in chunks.
    pub chunks: Option<ChunkRecord>,
}

/// Where a generation resumes a cached take: the blocks before `block` are the cached ones.
pub(super) struct Resume<'a> {
    pub block: usize,
    pub record: &'a TakeRecord,
}

impl TakeCache {
    /// Forgets the cached take (another model, or memory to give back).
    pub fn clear(&mut self) {
        self.record = None;
    }

    /// Where a take with these prints can resume this cache's take: at its first block that
    /// differs (none before block 1, nothing to reuse).
    pub(super) fn resume(&self, take_print: u64, block_prints: &[u64]) -> Option<Resume<'_>> {
        let record = self.record.as_ref().filter(|r| r.take_print == take_print)?;
        let same = record.block_prints.iter().zip(block_prints).take_while(|(a, b)| a == b).count();
        // A block of the new take past the cached rollout's end is new too.
        let block = same.min(record.checkpoints.len());
        (block > 0).then_some(Resume { block, record })
    }
}

impl Resume<'_> {
    /// The normalised sparse poses as they stood before block `self.block`: the final poses
    /// up to the ones its seam join may move, then those as they were then.
    pub fn sparse(&self, block_len: usize, dim: usize) -> Vec<f32> {
        let settled = settled_poses(self.block, block_len) * dim;
        let mut sparse = self.record.sparse[..settled].to_vec();
        sparse.extend_from_slice(&self.record.checkpoints[self.block - 1].unsettled);
        sparse
    }
}

/// Sparse poses no later block moves once `blocks` blocks are made after the seed block of
/// `block_len` poses: all but the last block's, which the next seam join may move.
pub(super) fn settled_poses(blocks: usize, block_len: usize) -> usize {
    blocks * block_len
}

/// What every block of a take reads besides its own part of the timeline: the model, the
/// starting poses (a start file may have changed on disk) and the options with the timeline
/// left out (start, seed, guidance, stages, keys, path, held frames).
pub(super) fn take_print(model: &GlocalModel, opts: &GenerateOptions, start: &[f32]) -> u64 {
    let mut hasher = DefaultHasher::new();
    start.iter().for_each(|v| v.to_bits().hash(&mut hasher));
    model.spec.training.weights_sha256.hash(&mut hasher);
    model.spec.classes.hash(&mut hasher);
    model.dir.hash(&mut hasher);
    let mut rest = opts.clone();
    rest.timeline.segments.clear();
    serde_json::to_string(&rest).unwrap_or_default().hash(&mut hasher);
    hasher.finish()
}

/// Each block's print: its plan, and the segment (with its seed) it and the block before it
/// belong to (a block entering a seeded segment restarts its noise).
pub(super) fn block_prints(opts: &GenerateOptions, plans: &[BlockPlan], block_segments: &[usize]) -> Vec<u64> {
    let seed_of = |b: usize| opts.timeline.segments[block_segments[b]].seed;
    (0..plans.len())
        .map(|b| {
            let mut hasher = DefaultHasher::new();
            hash_plan(&plans[b], &mut hasher);
            (block_segments[b], seed_of(b)).hash(&mut hasher);
            b.checked_sub(1).map(|p| block_segments[p]).hash(&mut hasher);
            hasher.finish()
        })
        .collect()
}

fn hash_plan(plan: &BlockPlan, hasher: &mut DefaultHasher) {
    plan.class.iter().for_each(|v| v.to_bits().hash(hasher));
    (plan.target, plan.ease_blocks, &plan.keys, plan.run, plan.lasting).hash(hasher);
}
