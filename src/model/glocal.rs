//! A trained GlocalNet loaded for generation: GloGen and LocGen frozen to plain f32, the
//! model description and the seed bank.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use glam::Vec3;

use super::block::{BlockConfig, FrozenBlock, Seq2SeqBlock};
use super::corpus::interpolated_window;
use super::spec::{ModelSpec, SeamJoin, Seed, GLOGEN_FILE, LOCGEN_FILE};
use super::Error;
use crate::data::features::{interpolate, Placement, ROOT_FEATURES};
use crate::motion::{floor_height, Motion};

pub const SEEDS_FILE: &str = "seeds.json";

/// LocGen windows per batch: 256 windows (102 s at 25 fps) keep its workspace near 20 MB.
const LOCGEN_CHUNK: usize = 256;

pub struct GlocalModel {
    pub dir: PathBuf,
    pub spec: ModelSpec,
    pub seeds: Vec<Seed>,
    glogen: FrozenBlock,
    locgen: Option<FrozenBlock>,
}

impl GlocalModel {
    /// Loads a model folder; every file is checked, and a missing or mismatched one is an
    /// error that names it. A folder without LocGen still generates (plain interpolation).
    pub fn load(dir: &Path) -> Result<Self, Error> {
        let spec = ModelSpec::read_verified(dir)?;
        let glogen = load_block(&dir.join(GLOGEN_FILE), &spec.glogen.block)?.freeze()?;
        let locgen_path = dir.join(LOCGEN_FILE);
        let locgen = if locgen_path.exists() { Some(load_block(&locgen_path, &spec.locgen.block)?.freeze()?) } else { None };
        let seeds_path = dir.join(SEEDS_FILE);
        let text = std::fs::read_to_string(&seeds_path).map_err(|e| file_error(format!("model folder has no readable {}", seeds_path.display()), e))?;
        let seeds: Vec<Seed> = serde_json::from_str(&text).map_err(|e| file_error(format!("{} is not a valid seed bank", seeds_path.display()), e))?;
        let width = spec.block_len * spec.layout.dim();
        if let Some(bad) = seeds.iter().position(|s| s.features.len() != width || s.class >= spec.classes.len()) {
            let problem = format!("seed {bad} does not fit the model ({} sparse poses of {} features, {} classes)", spec.block_len, spec.layout.dim(), spec.classes.len());
            return Err(Error::Mismatch { path: seeds_path, problem });
        }
        Ok(Self { dir: dir.to_path_buf(), spec, seeds, glogen, locgen })
    }

    pub fn has_locgen(&self) -> bool {
        self.locgen.is_some()
    }

    /// The height of the floor in the model's world: the mean over the seed bank of each
    /// window's lowest joint.
    pub fn floor_height(&self) -> f32 {
        let layout = &self.spec.layout;
        let lowest = |s: &Seed| floor_height(&layout.decode(&s.features, Placement::default()).0);
        self.seeds.iter().map(lowest).sum::<f32>() / self.seeds.len().max(1) as f32
    }

    /// The `variant`-th seed-bank window of `class` (wrapping around), if the class has any.
    pub fn seed_of_class(&self, class: usize, variant: usize) -> Option<&Seed> {
        self.seeds.iter().filter(|s| s.class == class).nth(self.class_seed_index(class, variant)?)
    }

    /// Which of `class`'s seed-bank windows (counted in seed-bank order) its `variant`-th is,
    /// wrapping around, if the class has any.
    pub fn class_seed_index(&self, class: usize, variant: usize) -> Option<usize> {
        let count = self.seeds.iter().filter(|s| s.class == class).count();
        (count > 0).then(|| variant % count)
    }

    /// One-hot class vector (all zeros when the model was trained without classes).
    pub fn class_vector(&self, class: usize) -> Vec<f32> {
        let mut v = vec![0.0; self.spec.glogen.block.cond_dim];
        if let Some(x) = v.get_mut(class) {
            *x = 1.0;
        }
        v
    }

    /// One GloGen block: `input` is `block_len` normalised sparse poses, `class` a class
    /// vector (may be a blend of two). `strength` > 1 applies classifier-free guidance
    /// (`uncond + strength * (cond - uncond)`), available when the model was trained with
    /// class dropout. Returns the block's embedding (as [`Self::embed`]), which the encoder
    /// computed on the way.
    pub fn glogen_block(&mut self, input: &[f32], class: &[f32], strength: f32, out: &mut [f32]) -> Vec<f32> {
        let t = self.spec.block_len;
        let cond = (self.spec.glogen.block.cond_dim > 0).then_some(class);
        let guided = cond.is_some() && self.spec.glogen.class_dropout > 0.0 && (strength - 1.0).abs() > 1e-6;
        if !guided {
            self.glogen.infer(input, cond, 1, t, out);
            self.offset_from_last(input, out);
            return self.glogen.last_encoding(1, t).to_vec();
        }
        // The conditioned and unconditioned passes as one batch of two: the weights stream
        // from memory once for both.
        let inputs = [input, input].concat();
        let conds = [class, &vec![0.0; class.len()]].concat();
        let mut both = vec![0.0; 2 * out.len()];
        self.glogen.infer(&inputs, Some(&conds), 2, t, &mut both);
        let (conditioned, unconditioned) = both.split_at(out.len());
        for ((o, c), u) in out.iter_mut().zip(conditioned).zip(unconditioned) {
            *o = u + strength * (c - u);
        }
        self.offset_from_last(input, out);
        self.glogen.last_encoding(2, t)[..t * 2 * self.spec.glogen.block.hidden].to_vec()
    }

    /// A residual GloGen's block is offsets from the last pose of its input.
    fn offset_from_last(&self, input: &[f32], out: &mut [f32]) {
        if !self.spec.glogen.residual {
            return;
        }
        let dim = self.spec.layout.dim();
        let last = &input[input.len() - dim..];
        for pose in out.chunks_exact_mut(dim) {
            pose.iter_mut().zip(last).for_each(|(o, l)| *o += l);
        }
    }

    /// One step of GloGen's rollout: a block from `input` (the context as GloGen should see
    /// it, eased towards an anchor or noised), joined onto the poses actually before it
    /// (normalised) when `join` names them: the whole block before, which a two-sided join
    /// may move, or only its last pose, which stays. Returns the block's embedding.
    ///
    /// A Bi-LSTM decoder places its first pose near, not at, where the context leaves off, so
    /// blocks pop at their seams (the interval before a seam moved 3.2x faster than those
    /// inside a block). Joining shifts the block so that its first pose is one of its own
    /// steps on from the context's last pose, and fades the shift out over the first half of
    /// the block with a raised cosine, which keeps the block's own motion and its end where
    /// GloGen put it; a two-sided join ([`SeamJoin`]) moves the block before by half of it.
    pub fn rollout_block(&mut self, input: &[f32], class: &[f32], strength: f32, join: Option<&mut [f32]>, out: &mut [f32]) -> Vec<f32> {
        let embedding = self.glogen_block(input, class, strength, out);
        if let Some(before) = join {
            join_seam(before, out, self.spec.layout.dim(), self.spec.glogen.seam_join);
        }
        embedding
    }

    /// GloGen's encoder states over one block, concatenated: the embedding of the t-SNE panel.
    pub fn embed(&mut self, input: &[f32], class: &[f32]) -> Vec<f32> {
        let t = self.spec.block_len;
        let cond = (self.spec.glogen.block.cond_dim > 0).then_some(class);
        let mut out = vec![0.0; t * 2 * self.spec.glogen.block.hidden];
        self.glogen.encode_infer(input, cond, 1, t, &mut out);
        out
    }

    /// LocGen over `windows` windows of normalised interpolated dense features, in place:
    /// LocGen predicts a residual on the interpolation. Returns false without LocGen.
    pub fn locgen(&mut self, frames: &mut [f32], windows: usize) -> bool {
        let Some(locgen) = self.locgen.as_mut() else { return false };
        let w = self.spec.locgen.window;
        let width = w * self.spec.layout.dim();
        // Chunks of windows bound the workspace (gates and states of every window in the
        // batch) whatever the take's length.
        let mut residual = vec![0.0; LOCGEN_CHUNK.min(windows) * width];
        for chunk in frames[..windows * width].chunks_mut(LOCGEN_CHUNK * width) {
            let n = chunk.len() / width;
            locgen.infer(chunk, None, n, w, &mut residual[..n * width]);
            chunk.iter_mut().zip(&residual).for_each(|(f, r)| *f += r);
        }
        true
    }
}

impl GlocalModel {
    /// GloGen continuing real motion: `blocks * block_len` sparse poses after frame `t0` of
    /// `m` (on the model's skeleton and frame rate), the `k`-th at frame `t0 + (k + 1) *
    /// stride`, rolled out block by block with [`Self::rollout_block`] from the `block_len`
    /// observed sparse poses ending at `t0`. Positions are in the motion's own world frame.
    pub fn forecast(&mut self, m: &Motion, t0: usize, class: usize, blocks: usize, join_seams: bool) -> Result<Vec<Vec3>> {
        let (s, t, dim) = (self.spec.stride, self.spec.block_len, self.spec.layout.dim());
        let first = t0 as isize - ((t - 1) * s) as isize;
        if first < s as isize || t0 >= m.frames() {
            bail!("frame {t0} has too little observed motion before it for the model ({} frames needed)", t * s);
        }
        let mut sparse = self.spec.layout.encode_motion(m, first as usize, s, t);
        self.spec.sparse_norm.normalize(&mut sparse);
        let class_vec = self.class_vector(class);
        let mut out = vec![0.0; t * dim];
        for b in 0..blocks {
            let context = sparse.len() - t * dim;
            let input = sparse[context..].to_vec();
            // The observed poses stay where they were observed: the join sees their last alone.
            let before = if b > 0 { context } else { sparse.len() - dim };
            self.rollout_block(&input, &class_vec, 1.0, join_seams.then_some(&mut sparse[before..]), &mut out);
            sparse.extend_from_slice(&out);
        }
        let mut predicted = sparse.split_off(t * dim);
        self.spec.sparse_norm.denormalize(&mut predicted);
        Ok(self.spec.layout.decode(&predicted, self.spec.layout.placement(m.frame(t0))).0)
    }

    /// The model's interpolation of the true sparse keyframes of `m` over the LocGen window
    /// that starts at frame `start` (what LocGen refines).
    pub fn keyframe_window(&self, m: &Motion, start: usize) -> Vec<Vec3> {
        interpolated_window(m, start, self.spec.locgen.window, self.spec.stride, self.spec.locgen.interpolation)
    }

    /// LocGen over whole windows of interpolated dense poses, each given with the pose just
    /// before it (which places it and starts its velocities); the refined poses, window after
    /// window. None without LocGen.
    pub fn refine_windows(&mut self, windows: &[(&[Vec3], &[Vec3])]) -> Option<Vec<Vec3>> {
        if !self.has_locgen() {
            return None;
        }
        let (layout, norm) = (self.spec.layout.clone(), self.spec.dense_norm.clone());
        let (j, width) = (layout.joints(), self.spec.locgen.window * layout.dim());
        let mut feats = Vec::with_capacity(windows.len() * width);
        for (poses, before) in windows {
            let refs: Vec<&[Vec3]> = poses.chunks_exact(j).collect();
            feats.extend(layout.encode(&refs, Some(before)));
        }
        norm.normalize(&mut feats);
        self.locgen(&mut feats, windows.len());
        norm.denormalize(&mut feats);
        Some(feats.chunks_exact(width).zip(windows).flat_map(|(f, (_, before))| layout.decode(f, layout.placement(before)).0).collect())
    }

    /// Dense frames between sparse poses at the model's native stride: their linear
    /// interpolation, refined by LocGen when asked and available.
    pub fn densify(&mut self, sparse: &[Vec3], refine: bool) -> Vec<Vec3> {
        let spec = &self.spec;
        let j = spec.layout.joints();
        let dense = interpolate(sparse, j, spec.stride, spec.locgen.interpolation);
        if !refine || !self.has_locgen() {
            return dense;
        }
        let (layout, norm, w) = (spec.layout.clone(), spec.dense_norm.clone(), spec.locgen.window);
        let dim = layout.dim();
        let frames = dense.len() / j;
        let windows = frames.div_ceil(w);
        let refs: Vec<&[Vec3]> = dense.chunks_exact(j).collect();
        let mut feats = layout.encode(&refs, None);
        // Pad to whole windows with the last pose standing still, then drop the pad.
        let mut still = feats[feats.len() - dim..].to_vec();
        still[1..4].fill(0.0);
        while feats.len() < windows * w * dim {
            feats.extend_from_slice(&still);
        }
        norm.normalize(&mut feats);
        self.locgen(&mut feats, windows);
        norm.denormalize(&mut feats);
        feats.truncate(frames * dim);
        // The first frame's features carry no displacement, so decoding starts where it stands.
        layout.decode(&feats, layout.placement(refs[0])).0
    }
}

/// See [`GlocalModel::rollout_block`]. Features 1-3 (the root's ground displacement and
/// heading change) are velocities already (the block's first moves halfway to the
/// context's last); the rest are positions, and the block's first pose moves to one of the
/// block's own first steps on from the context's last pose. The shift fades out over the
/// first half of the block with a raised cosine, so the block keeps its own motion and ends
/// where GloGen put it. Faded over the whole block, the shifted root height and joints kept
/// a running body off its feet for 1.5 s (Bandai floating 21% of frames against 13%; on the
/// final tree 23% with only the root's fade that long and 25% with only the joints',
/// against 16%). The join used to continue the context's last step instead (positions at
/// their last velocity): a sparse step is 0.17-0.2 s, and extrapolating it carried a
/// landing foot through the floor at every seam of a walk (Bandai's walks then floated 86%
/// of the time over the floor those dips set); the mean of the two steps left a hitch (the
/// seam interval 0.77x the others' speed). Measured in docs/DESIGN.md ("Seams").
///
/// `before` is the whole block before or only its last pose; with [`SeamJoin::TwoSided`] a
/// whole block takes half the shift, opposite, faded in over its last half, and the new
/// block the other half, so neither block's first half carries all of the other's pose.
fn join_seam(before: &mut [f32], block: &mut [f32], dim: usize, kind: SeamJoin) {
    let poses = block.len() / dim;
    if poses < 2 {
        return;
    }
    let last = &before[before.len() - dim..];
    let shift: Vec<f32> = (0..dim)
        .map(|f| {
            let target = if (1..ROOT_FEATURES).contains(&f) { 0.5 * (last[f] + block[dim + f]) } else { last[f] + block[dim + f] - block[f] };
            target - block[f]
        })
        .collect();
    let share = seam_share(kind, before.len() == block.len());
    let fade = join_fade(poses);
    for (k, w) in fade.iter().enumerate() {
        block[k * dim..(k + 1) * dim].iter_mut().zip(&shift).for_each(|(v, d)| *v += share * d * w);
    }
    if share < 1.0 {
        for (k, w) in fade.iter().enumerate() {
            let pose = poses - 1 - k;
            before[pose * dim..(pose + 1) * dim].iter_mut().zip(&shift).for_each(|(v, d)| *v -= (1.0 - share) * d * w);
        }
    }
}

/// The share of a seam's shift the new block takes; the block before, when it is there whole,
/// takes the rest.
fn seam_share(kind: SeamJoin, whole_block_before: bool) -> f32 {
    if kind == SeamJoin::TwoSided && whole_block_before {
        0.5
    } else {
        1.0
    }
}

/// The share of a seam's shift each of a block's `poses` keeps: a raised cosine from 1 at its
/// first pose to 0 at its middle.
fn join_fade(poses: usize) -> Vec<f32> {
    let span = poses / 2;
    (0..poses).map(|k| if k < span { 0.5 * (1.0 + (std::f32::consts::PI * k as f32 / span as f32).cos()) } else { 0.0 }).collect()
}

/// [`join_seam`] on a batch of blocks `[B, T, D]` onto the blocks before them `[B, T, D]`
/// (or their last poses `[B, 1, D]`, which stay where they are), as differentiable tensor
/// operations: what training on joined rollouts backpropagates through. Returns the joined
/// blocks before and the joined blocks.
pub fn join_seams_tensor(before: &Tensor, blocks: &Tensor, kind: SeamJoin) -> candle_core::Result<(Tensor, Tensor)> {
    let (_, poses, dim) = blocks.dims3()?;
    if poses < 2 {
        return Ok((before.clone(), blocks.clone()));
    }
    let device = blocks.device();
    let last = before.narrow(1, before.dim(1)? - 1, 1)?;
    let first = blocks.narrow(1, 0, 1)?;
    let second = blocks.narrow(1, 1, 1)?;
    let root: Vec<f32> = (0..dim).map(|f| if (1..ROOT_FEATURES).contains(&f) { 1.0 } else { 0.0 }).collect();
    let root = Tensor::from_vec(root, (1, 1, dim), device)?;
    let root_target = ((&last + &second)? * 0.5)?;
    let pose_target = ((&last + &second)? - &first)?;
    let target = (root_target.broadcast_mul(&root)? + pose_target.broadcast_mul(&(1.0 - &root)?)?)?;
    let shift = (target - first)?;
    let share = seam_share(kind, before.dim(1)? == poses) as f64;
    let fade = join_fade(poses);
    let head = Tensor::from_vec(fade.clone(), (1, poses, 1), device)?;
    let joined = (blocks + shift.broadcast_mul(&head)?.affine(share, 0.0)?)?;
    if share == 1.0 {
        return Ok((before.clone(), joined));
    }
    let tail = Tensor::from_vec(fade.into_iter().rev().collect(), (1, poses, 1), device)?;
    let before = (before - shift.broadcast_mul(&tail)?.affine(1.0 - share, 0.0)?)?;
    Ok((before, joined))
}

/// Builds a block and fills it from a safetensors file.
pub fn load_block(path: &Path, cfg: &BlockConfig) -> Result<Seq2SeqBlock, Error> {
    let varmap = VarMap::new();
    let block = Seq2SeqBlock::new(cfg.clone(), VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu))?;
    load_weights(path, &varmap)?;
    Ok(block)
}

/// Fills every variable from a safetensors file after checking that each is there with
/// the right shape and dtype and holds only finite values.
pub fn load_weights(path: &Path, varmap: &VarMap) -> Result<(), Error> {
    let bytes = std::fs::read(path).map_err(|e| file_error(format!("cannot read {}", path.display()), e))?;
    let file = safetensors::SafeTensors::deserialize(&bytes).map_err(|e| file_error(format!("{} is not a safetensors file", path.display()), e))?;
    let vars = varmap.data().lock().expect("no thread panics holding the variable map");
    let mut names: Vec<&String> = vars.keys().collect();
    names.sort();
    let mismatch = |problem: String| Error::Mismatch { path: path.to_path_buf(), problem };
    for name in names {
        let var = &vars[name];
        let view = file.tensor(name).map_err(|e| file_error(format!("{} has no tensor '{name}': it was saved for a different model", path.display()), e))?;
        if view.dtype() != safetensors::Dtype::F32 {
            return Err(mismatch(format!("tensor '{name}' is {:?}, expected F32", view.dtype())));
        }
        if view.shape() != var.dims() {
            return Err(mismatch(format!("tensor '{name}' has shape {:?}, the model needs {:?}", view.shape(), var.dims())));
        }
        let values: Vec<f32> = view.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(mismatch(format!("tensor '{name}' holds NaN or infinite values")));
        }
        var.set(&candle_core::Tensor::from_vec(values, var.shape(), &Device::Cpu)?)?;
    }
    Ok(())
}

fn file_error(what: String, cause: impl std::error::Error + Send + Sync + 'static) -> Error {
    Error::File { what, cause: cause.into() }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Training's tensor join is generation's join: the same poses to float rounding, for
    /// blocks of either parity of length, one-sided onto a last pose and two-sided onto a
    /// whole block before.
    #[test]
    fn tensor_join_matches_the_rollouts_join() {
        for (poses, dim) in [(10, 7), (9, 5)] {
            for (kind, before_poses) in [(SeamJoin::OneSided, 1), (SeamJoin::TwoSided, poses)] {
                let value = |i: usize| ((i * 7919) % 97) as f32 / 13.0 - 3.5;
                let blocks: Vec<f32> = (0..2 * poses * dim).map(value).collect();
                let before: Vec<f32> = (0..2 * before_poses * dim).map(|i| value(i + 5000)).collect();
                let tensor = |v: &[f32], p: usize| Tensor::from_vec(v.to_vec(), (2, p, dim), &Device::Cpu).unwrap();
                let (joined_before, joined) = join_seams_tensor(&tensor(&before, before_poses), &tensor(&blocks, poses), kind).unwrap();
                let flat = |t: Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
                let (joined_before, joined) = (flat(joined_before), flat(joined));
                for b in 0..2 {
                    let (width, before_width) = (poses * dim, before_poses * dim);
                    let mut block = blocks[b * width..(b + 1) * width].to_vec();
                    let mut prior = before[b * before_width..(b + 1) * before_width].to_vec();
                    join_seam(&mut prior, &mut block, dim, kind);
                    assert_ne!(block, blocks[b * width..(b + 1) * width], "the join moved nothing");
                    assert_eq!(prior != before[b * before_width..(b + 1) * before_width], kind == SeamJoin::TwoSided, "{kind:?} moved the block before or left it");
                    let expected = joined[b * width..(b + 1) * width].iter().chain(&joined_before[b * before_width..(b + 1) * before_width]);
                    for (a, t) in block.iter().chain(&prior).zip(expected) {
                        assert!((a - t).abs() < 1e-5, "{a} against {t}");
                    }
                }
            }
        }
    }

    /// A two-sided join leaves the seam's step what a one-sided join makes it: one of the
    /// new block's own steps on from the (moved) pose before.
    #[test]
    fn two_sided_join_closes_the_seam_as_the_one_sided_does() {
        let (poses, dim) = (10, 6);
        let value = |i: usize| ((i * 104729) % 89) as f32 / 11.0 - 4.0;
        let block: Vec<f32> = (0..poses * dim).map(value).collect();
        let before: Vec<f32> = (0..poses * dim).map(|i| value(i + 777)).collect();
        let mut seams = Vec::new();
        for kind in [SeamJoin::OneSided, SeamJoin::TwoSided] {
            let (mut prior, mut joined) = (before.clone(), block.clone());
            join_seam(&mut prior, &mut joined, dim, kind);
            let last = &prior[(poses - 1) * dim..];
            seams.push((ROOT_FEATURES..dim).map(|f| joined[f] - last[f]).collect::<Vec<f32>>());
        }
        for (a, b) in seams[0].iter().zip(&seams[1]) {
            assert!((a - b).abs() < 1e-5, "seam step {a} one-sided against {b} two-sided");
        }
    }
}
