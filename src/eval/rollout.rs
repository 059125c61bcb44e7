//! A trained model continuing real motion: GloGen blocks from observed sparse poses, and the
//! dense frames between them (interpolation, refined by LocGen when asked), mirroring what
//! [`crate::synth::generate`] does for takes that start from the seed bank.

use anyhow::{bail, Result};
use glam::Vec3;

use crate::data::features::interpolate;
use crate::model::glocal::GlocalModel;
use crate::motion::Motion;

/// `blocks * block_len` sparse poses after frame `t0` of `m` (on the model's skeleton and
/// frame rate), the `k`-th at frame `t0 + (k + 1) * stride`, from the `block_len` observed
/// sparse poses ending at `t0`. Positions are in the motion's own world frame.
pub fn glogen_forecast(model: &mut GlocalModel, m: &Motion, t0: usize, class: usize, blocks: usize) -> Result<Vec<Vec3>> {
    let spec = model.spec.clone();
    let (s, t, dim) = (spec.stride, spec.block_len, spec.layout.dim());
    let first = t0 as isize - ((t - 1) * s) as isize;
    if first < s as isize || t0 >= m.frames() {
        bail!("frame {t0} has too little observed motion before it for the model ({} frames needed)", t * s);
    }
    let mut sparse = spec.layout.encode_motion(m, first as usize, s, t);
    spec.sparse_norm.normalize(&mut sparse);
    let class_vec = model.class_vector(class);
    let mut out = vec![0.0; t * dim];
    for _ in 0..blocks {
        let input = sparse[sparse.len() - t * dim..].to_vec();
        model.glogen_block(&input, &class_vec, 1.0, &mut out);
        sparse.extend_from_slice(&out);
    }
    let mut predicted = sparse[t * dim..].to_vec();
    spec.sparse_norm.denormalize(&mut predicted);
    Ok(spec.layout.decode(&predicted, spec.layout.placement(m.frame(t0))).0)
}

/// Dense frames at the model's frame rate from `observed` (frame 0) through the sparse
/// poses `stride` frames apart: linear interpolation, then LocGen when `locgen` is set and
/// the model has one.
pub fn densify(model: &mut GlocalModel, observed: &[Vec3], sparse: &[Vec3], locgen: bool) -> Vec<Vec3> {
    let spec = model.spec.clone();
    let j = spec.layout.joints();
    let keys: Vec<Vec3> = observed.iter().chain(sparse).copied().collect();
    let dense = interpolate(&keys, j, spec.stride);
    if !locgen || !model.has_locgen() {
        return dense;
    }
    let (layout, norm, w, dim) = (&spec.layout, &spec.dense_norm, spec.locgen.window, spec.layout.dim());
    let frames = dense.len() / j;
    let windows = frames.div_ceil(w);
    let refs: Vec<&[Vec3]> = dense.chunks_exact(j).collect();
    let mut feats = layout.encode(&refs, None);
    let mut still = feats[feats.len() - dim..].to_vec();
    still[1..4].fill(0.0);
    while feats.len() < windows * w * dim {
        feats.extend_from_slice(&still);
    }
    norm.normalize(&mut feats);
    model.locgen(&mut feats, windows);
    norm.denormalize(&mut feats);
    feats.truncate(frames * dim);
    layout.decode(&feats, layout.placement(refs[0])).0
}
