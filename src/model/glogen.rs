//! GloGen frozen for generation: one block of sparse poses at a time from the block before
//! it, with classifier-free guidance, joined at its seam. Its weights are only read; each
//! caller brings a [`BlockWorkspace`].

use super::block::{BlockWorkspace, FrozenBlock};
use super::seam::join_seam;
use super::spec::{GloGenSpec, ModelSpec};
use super::target::{has_target, straight_way};
use crate::data::features::Normalizer;

#[derive(Clone, Debug)]
pub struct GloGen {
    block: FrozenBlock,
    spec: GloGenSpec,
    /// Sparse poses per block.
    block_len: usize,
    /// Features per pose.
    dim: usize,
    /// The class part of the conditioning vector, which guidance drops in its
    /// unconditioned pass (a target stays).
    class_len: usize,
    /// The sparse poses' normalisation, which the straight way to a target reads.
    norm: Normalizer,
}

impl GloGen {
    pub fn new(block: FrozenBlock, spec: &ModelSpec) -> Self {
        let class_len = spec.label_len();
        Self { block, spec: spec.glogen.clone(), block_len: spec.block_len, dim: spec.layout.dim(), class_len, norm: spec.sparse_norm.clone() }
    }

    pub fn block_len(&self) -> usize {
        self.block_len
    }

    /// Features per sparse pose.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Whether blocks read a target ([`super::target`]) after the class.
    pub fn reads_target(&self) -> bool {
        self.spec.target
    }

    /// One block: `input` is `block_len` normalised sparse poses, `cond` the conditioning: a
    /// class vector (may be a blend of two), then the target for a target-conditioned GloGen.
    /// `strength` > 1 applies classifier-free guidance to the class (`uncond + strength *
    /// (cond - uncond)`, the unconditioned pass without the class but with the target),
    /// available when the model was trained with class dropout. Returns the block's embedding
    /// (as [`Self::embed`]), which the encoder computed on the way.
    pub fn block(&self, ws: &mut BlockWorkspace, input: &[f32], class: &[f32], strength: f32, out: &mut [f32]) -> Vec<f32> {
        let (t, hidden) = (self.block_len, self.spec.block.hidden);
        let cond = (self.spec.block.cond_dim > 0).then_some(class);
        let guided = cond.is_some() && self.spec.class_dropout > 0.0 && (strength - 1.0).abs() > 1e-6;
        if !guided {
            self.block.infer(ws, input, cond, 1, t, out);
            self.add_base(input, class, out);
            return ws.last_encoding(1, t, hidden).to_vec();
        }
        // The conditioned and unconditioned passes as one batch of two: the weights stream
        // from memory once for both.
        let inputs = [input, input].concat();
        let mut unconditioned = class.to_vec();
        unconditioned[..self.class_len].fill(0.0);
        let conds = [class, &unconditioned].concat();
        let mut both = vec![0.0; 2 * out.len()];
        self.block.infer(ws, &inputs, Some(&conds), 2, t, &mut both);
        let (conditioned, unconditioned) = both.split_at(out.len());
        for ((o, c), u) in out.iter_mut().zip(conditioned).zip(unconditioned) {
            *o = u + strength * (c - u);
        }
        self.add_base(input, class, out);
        ws.last_encoding(2, t, hidden)[..t * 2 * hidden].to_vec()
    }

    /// Whether a block with conditioning `cond` is on its way to a target.
    fn aims(&self, cond: &[f32]) -> bool {
        self.spec.target && has_target(&cond[self.class_len..], self.dim)
    }

    /// What the network's block is an offset from: the straight way to the target when the
    /// block has one ([`straight_way`]), else (a share of) the last pose of its input for a
    /// residual GloGen ([`GloGenSpec::base_weights`]).
    fn add_base(&self, input: &[f32], cond: &[f32], out: &mut [f32]) {
        let last = &input[input.len() - self.dim..];
        let way = if self.spec.target { straight_way(last, &cond[self.class_len..], self.block_len, &self.norm) } else { None };
        if let Some(way) = way {
            out.iter_mut().zip(&way).for_each(|(o, w)| *o += w);
        } else if let Some(weights) = self.spec.base_weights(self.block_len) {
            for (pose, w) in out.chunks_exact_mut(self.dim).zip(weights) {
                pose.iter_mut().zip(last).for_each(|(o, l)| *o += w * l);
            }
        }
    }

    /// One step of the rollout: a block from `input` (the context as GloGen should see it,
    /// eased towards an anchor or noised), joined onto the poses actually before it
    /// (normalised) when `join` names them: the whole block before, which a two-sided join
    /// may move, or only its last pose, which stays. Returns the block's embedding.
    ///
    /// A Bi-LSTM decoder places its first pose near, not at, where the context leaves off, so
    /// blocks pop at their seams (the interval before a seam moved 3.2x faster than those
    /// inside a block). Joining shifts the block so that its first pose is one of its own
    /// steps on from the context's last pose, and fades the shift out over the first half of
    /// the block with a raised cosine, which keeps the block's own motion and its end where
    /// GloGen put it; a two-sided join ([`super::spec::SeamJoin`]) moves the block before by
    /// half of it.
    pub fn rollout_block(&self, ws: &mut BlockWorkspace, input: &[f32], class: &[f32], strength: f32, join: Option<&mut [f32]>, out: &mut [f32]) -> Vec<f32> {
        let embedding = self.block(ws, input, class, strength, out);
        if let Some(before) = join {
            join_seam(before, out, self.dim, self.spec.seam_join, !self.aims(class));
        }
        embedding
    }

    /// The encoder states over one block, concatenated: the embedding of the t-SNE panel.
    pub fn embed(&self, input: &[f32], class: &[f32]) -> Vec<f32> {
        let t = self.block_len;
        let cond = (self.spec.block.cond_dim > 0).then_some(class);
        let mut out = vec![0.0; t * 2 * self.spec.block.hidden];
        self.block.encode_infer(&mut BlockWorkspace::default(), input, cond, 1, t, &mut out);
        out
    }
}
