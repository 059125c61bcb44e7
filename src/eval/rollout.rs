//! A trained model continuing real motion: GloGen blocks from observed sparse poses, and the
//! dense frames between them (interpolation, refined by LocGen when asked), mirroring what
//! [`crate::synth::generate`] does for takes that start from the seed bank.

use anyhow::{bail, Result};
use glam::Vec3;

use crate::model::glocal::GlocalModel;
use crate::motion::Motion;

/// `blocks * block_len` sparse poses after frame `t0` of `m` (on the model's skeleton and
/// frame rate), the `k`-th at frame `t0 + (k + 1) * stride`, from the `block_len` observed
/// sparse poses ending at `t0`. Positions are in the motion's own world frame.
pub fn glogen_forecast(model: &mut GlocalModel, m: &Motion, t0: usize, class: usize, blocks: usize, join_seams: bool) -> Result<Vec<Vec3>> {
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
        model.rollout_block(&input, &input[(t - 2) * dim..], &class_vec, 1.0, join_seams, &mut out);
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
    let keys: Vec<Vec3> = observed.iter().chain(sparse).copied().collect();
    model.densify(&keys, locgen)
}
