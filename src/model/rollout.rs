//! GloGen's rollout: block after block on its own outputs, each joined at its seam. One loop
//! for generation (`synth`, which steers each block), forecasting real motion (`eval`) and
//! training's validation; what differs between them is what they decide per block
//! ([`RolloutSteps`]).

use std::ops::Range;

use anyhow::{bail, Result};

use super::block::BlockWorkspace;
use super::glogen::GloGen;
use super::seam::Seam;

/// What the caller of a [`rollout`] decides, block by block.
pub trait RolloutSteps {
    /// The class vector block `b` is conditioned on.
    fn class(&self, b: usize) -> &[f32];

    /// Block `b`'s guidance; it may ease or noise the block's `input` (its context, the last
    /// block of `sparse`, normalised) first.
    fn ask(&mut self, _b: usize, _input: &mut [f32], _sparse: &[f32]) -> f32 {
        1.0
    }

    /// Block `b`'s poses when they are given (held frames): GloGen does not make them (nor
    /// an embedding: the rollout returns an empty one), and no seam join moves the block
    /// before.
    fn given(&self, _b: usize) -> Option<Vec<f32>> {
        None
    }

    /// Whether the seam join may move the block before block `b` (b > 0): otherwise only its
    /// last pose is seen, and stays (observed or given poses).
    fn may_move_block_before(&self, _b: usize) -> bool {
        true
    }

    /// Whether the rollout starts from real motion other than the model's seed bank (a file,
    /// the held-out clip a forecast continues): the first block's first step then blends in
    /// that motion's own last step ([`Seam::Given`]). A take from the seed bank, windows of
    /// the clips GloGen learned to continue, joins its first block as every other.
    fn starts_from_given_motion(&self) -> bool {
        true
    }

    /// Block `b` as GloGen made it and the join left it, after the poses before it
    /// (`sparse`; `moved_before` when the join moved its last block).
    fn made(&mut self, _b: usize, _moved_before: bool, _sparse: &[f32], _block: &[f32]) {}

    /// Block `b` has been appended to `sparse`: constraints may change the poses (and roll
    /// the block on again with `glogen`). An error (a cancel) ends the rollout.
    fn appended(&mut self, _b: usize, _glogen: &GloGen, _ws: &mut BlockWorkspace, _sparse: &mut [f32]) -> Result<()> {
        Ok(())
    }
}

/// A rollout of one class at plain guidance: real motion continued.
pub struct OneClass(pub Vec<f32>);

impl RolloutSteps for OneClass {
    fn class(&self, _b: usize) -> &[f32] {
        &self.0
    }
}

/// Rolls `blocks` blocks out after `sparse` (normalised sparse poses, at least one block of
/// context), appending them, each joined onto the poses before it when `join_seams`.
/// Returns each block's embedding.
pub fn rollout(glogen: &GloGen, ws: &mut BlockWorkspace, sparse: &mut Vec<f32>, blocks: usize, join_seams: bool, steps: &mut dyn RolloutSteps) -> Result<Vec<Vec<f32>>> {
    rollout_blocks(glogen, ws, sparse, 0..blocks, join_seams, steps)
}

/// [`rollout`] of blocks `blocks` only: `sparse` holds what the blocks before made (a rollout
/// resumed where an earlier one left off, its `steps` in the state they were then).
pub fn rollout_blocks(glogen: &GloGen, ws: &mut BlockWorkspace, sparse: &mut Vec<f32>, blocks: Range<usize>, join_seams: bool, steps: &mut dyn RolloutSteps) -> Result<Vec<Vec<f32>>> {
    let (t, dim) = (glogen.block_len(), glogen.dim());
    let mut out = vec![0.0; t * dim];
    let mut embeddings = Vec::with_capacity(blocks.len());
    for b in blocks {
        let context = sparse.len() - t * dim;
        let mut input = sparse[context..].to_vec();
        let strength = steps.ask(b, &mut input, sparse);
        if let Some(given) = steps.given(b) {
            embeddings.push(Vec::new());
            steps.made(b, false, sparse, &given);
            sparse.extend_from_slice(&given);
            steps.appended(b, glogen, ws, sparse)?;
            continue;
        }
        let movable = b > 0 && steps.may_move_block_before(b);
        let seam = match (b, movable) {
            (0, _) if steps.starts_from_given_motion() => Seam::Given(&sparse[context..]),
            (_, true) => Seam::Own(&mut sparse[context..]),
            (_, false) => {
                let last = sparse.len() - dim;
                Seam::Own(&mut sparse[last..])
            }
        };
        embeddings.push(glogen.rollout_block(ws, &input, steps.class(b), strength, join_seams.then_some(seam), &mut out));
        steps.made(b, movable && join_seams, sparse, &out);
        if out.iter().any(|v| !v.is_finite()) {
            bail!("GloGen produced non-finite poses at block {b}");
        }
        sparse.extend_from_slice(&out);
        steps.appended(b, glogen, ws, sparse)?;
    }
    Ok(embeddings)
}
