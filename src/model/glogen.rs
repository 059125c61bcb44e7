//! GloGen frozen for generation: one block of sparse poses at a time from the block before
//! it, with classifier-free guidance, joined at its seam. Its weights are only read; each
//! caller brings a [`BlockWorkspace`].

use super::block::{BlockWorkspace, FrozenBlock};
use super::seam::{half_block, join_seam, Seam};
use super::spec::{GloGenSpec, ModelSpec};
use super::target::{has_target, straight_way};
use crate::data::features::Normalizer;
use crate::motion::JointRoles;

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
    /// Per class, the label of the class its guidance steers away from
    /// ([`ModelSpec::class_contrasts`]), and how far.
    contrasts: Vec<Option<Vec<f32>>>,
    contrast_strength: f32,
    /// The change of the hips' height at a seam past which it is joined over
    /// [`LONG_JOIN_SECONDS`]: [`LONG_JOIN_LEGS`] of the skeleton's leg (hip to knee to ankle at
    /// rest), in its units; 0 where the legs are not found.
    long_climb: f32,
    /// The poses a change of posture's seam is joined over ([`LONG_JOIN_SECONDS`]).
    long_span: usize,
}

/// A block whose first pose holds the hips further than this many leg lengths from the pose
/// before it (a seat before a stand, a stand before a sit: an anchored change of posture) is
/// joined over [`LONG_JOIN_SECONDS`] rather than its first half. Over the first half (1 s on
/// Human3.6M), a crouch before a walk stood up in 0.3 s (the hips climbing 1.7 m/s once the
/// foot lock kept the feet planted; Human3.6M's fastest real climb is 1.75).
const LONG_JOIN_LEGS: f32 = 0.25;

/// How long a change of posture's seam shift fades over, the block's length at most. Over
/// Human3.6M's whole 2 s block, a body rising from a floor seat was still rising 1 s into the
/// new class (class control 1 s after a change from another class's seed 92.5 -> 88.3%);
/// over 1.4 s it reads 91.9% and climbs no faster (h36m walks from its 160 seed windows: 11
/// over 1.2 m/s and 1 over 1.75, against 8 and 2 over the whole block and 18 and 9 over its
/// half). Bandai's and `all`'s blocks are 1 s: joined whole, as before.
const LONG_JOIN_SECONDS: f32 = 1.4;

impl GloGen {
    pub fn new(block: FrozenBlock, spec: &ModelSpec) -> Self {
        let class_len = spec.label_len();
        let long_climb = LONG_JOIN_LEGS * JointRoles::new(&spec.layout.skeleton).map_or(0.0, |roles| roles.rest_leg_length(&spec.layout.skeleton));
        let long_span = ((LONG_JOIN_SECONDS * spec.fps / spec.stride as f32).round() as usize).clamp(half_block(spec.block_len), spec.block_len);
        let mut glogen = Self { block, spec: spec.glogen.clone(), block_len: spec.block_len, dim: spec.layout.dim(), class_len, norm: spec.sparse_norm.clone(), contrasts: Vec::new(), contrast_strength: 0.0, long_climb, long_span };
        glogen.set_contrasts(spec);
        glogen
    }

    /// The same GloGen steering its guidance away from other classes as `spec` says
    /// ([`ModelSpec::class_contrasts`]).
    pub fn set_contrasts(&mut self, spec: &ModelSpec) {
        let label = |pair: usize| {
            let mut row = vec![0.0; self.class_len];
            spec.set_labels(&mut row, pair, spec.usual_styles.get(pair).copied());
            row
        };
        self.contrasts = if self.class_len > 0 { spec.contrast_indices().into_iter().map(|pair| pair.map(label)).collect() } else { Vec::new() };
        self.contrast_strength = spec.contrast_strength;
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
    /// (cond - uncond)`, the unconditioned pass without the label but with the target),
    /// available when the model was trained with class dropout; a class that steers away from
    /// another ([`ModelSpec::class_contrasts`]) is also pushed away from that class
    /// (`+ contrast_strength * (cond - contrasted)`, [`Self::contrasted`]). Returns the
    /// block's embedding (as [`Self::embed`]), which the encoder computed on the way.
    pub fn block(&self, ws: &mut BlockWorkspace, input: &[f32], class: &[f32], strength: f32, out: &mut [f32]) -> Vec<f32> {
        let (t, hidden) = (self.block_len, self.spec.block.hidden);
        let cond = (self.spec.block.cond_dim > 0).then_some(class);
        let guided = cond.is_some() && self.spec.class_dropout > 0.0 && (strength - 1.0).abs() > 1e-6;
        if !guided {
            self.block.infer(ws, input, cond, 1, t, out);
            self.add_base(input, class, out);
            return ws.last_encoding(1, t, hidden).to_vec();
        }
        // The conditioned and the other passes as one batch: the weights stream from memory
        // once for all of them.
        let mut unconditioned = class.to_vec();
        unconditioned[..self.class_len].fill(0.0);
        let mut conds = [class, &unconditioned].concat();
        let contrasted = self.contrasted(class);
        conds.extend(contrasted.iter().flatten());
        let passes = conds.len() / class.len();
        let inputs = input.repeat(passes);
        let mut all = vec![0.0; passes * out.len()];
        self.block.infer(ws, &inputs, Some(&conds), passes, t, &mut all);
        let (conditioned, others) = all.split_at(out.len());
        let (unconditioned, contrasted) = others.split_at(out.len());
        for (k, ((o, c), u)) in out.iter_mut().zip(conditioned).zip(unconditioned).enumerate() {
            let away = contrasted.get(k).map_or(0.0, |a| c - a);
            *o = u + strength * (c - u) + self.contrast_strength * away;
        }
        self.add_base(input, class, out);
        ws.last_encoding(passes, t, hidden)[..t * 2 * hidden].to_vec()
    }

    /// The conditioning a class vector's classes that steer away from another are pushed away
    /// from: each such class's weight given to its pair's label as the model makes that class
    /// by default (its usual style: `all`'s `walking` is Human3.6M's and CMU's, "neutral"),
    /// the take's style keeping what is left and every other class kept, so the push is what
    /// tells the class and its style from the plain pair; none where the vector holds no such
    /// class.
    fn contrasted(&self, class: &[f32]) -> Option<Vec<f32>> {
        let classes = self.contrasts.len();
        let pushed: f32 = self.contrasts.iter().zip(class).filter(|(pair, _)| pair.is_some()).map(|(_, &w)| w).sum();
        if pushed <= 0.0 {
            return None;
        }
        let mut away = class.to_vec();
        away[classes..self.class_len].iter_mut().for_each(|s| *s *= 1.0 - pushed);
        for (k, pair) in self.contrasts.iter().enumerate() {
            if let Some(pair) = pair {
                away[k] -= class[k];
                away[..self.class_len].iter_mut().zip(pair).for_each(|(a, p)| *a += class[k] * p);
            }
        }
        Some(away)
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
    /// (normalised) when `join` names them ([`Seam`]: GloGen's own, or real motion it was
    /// given). Returns the block's embedding.
    ///
    /// A Bi-LSTM decoder places its first pose near, not at, where the context leaves off, so
    /// blocks pop at their seams (the interval before a seam moved 3.2x faster than those
    /// inside a block). Joining shifts the block so that its first pose is one of its own
    /// steps on from the context's last pose, and fades the shift out over the first half of
    /// the block with a raised cosine, which keeps the block's own motion and its end where
    /// GloGen put it; a two-sided join ([`super::spec::SeamJoin`]) moves the block before by
    /// half of it; onto given motion its first step blends in that motion's own
    /// ([`super::seam::GIVEN_STEP_SHARE`]). A block that changes the body's height a long way
    /// is joined over longer ([`LONG_JOIN_LEGS`], [`LONG_JOIN_SECONDS`]).
    pub fn rollout_block(&self, ws: &mut BlockWorkspace, input: &[f32], class: &[f32], strength: f32, join: Option<Seam<'_>>, out: &mut [f32]) -> Vec<f32> {
        let embedding = self.block(ws, input, class, strength, out);
        if let Some(seam) = join {
            let climb = (seam.last(self.dim)[0] - out[0]) * self.norm.std[0];
            let poses = out.len() / self.dim;
            let span = if climb.abs() > self.long_climb { self.long_span.min(poses) } else { half_block(poses) };
            join_seam(seam, out, self.dim, self.spec.seam_join, !self.aims(class), span);
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
