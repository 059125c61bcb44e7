//! The seam join: a GloGen block shifted onto the poses before it, so blocks do not pop
//! where they meet; once on plain f32 buffers for generation and once as differentiable
//! tensor operations for training on joined rollouts (tested equal; the join onto given
//! motion, [`Seam::Given`], is generation's alone: training joins the whole step).

use candle_core::Tensor;

use super::spec::SeamJoin;
use crate::data::features::ROOT_FEATURES;

/// What a new block is joined onto ([`join_seam`]).
pub enum Seam<'a> {
    /// GloGen's own poses: the whole block before, which a two-sided join may move, or only
    /// its last pose, which stays.
    Own(&'a mut [f32]),
    /// Real motion given from outside the seed bank (a file's frames, the held-out clip a
    /// forecast continues), its last two poses at least, which stay: the block's first step becomes
    /// [`GIVEN_STEP_SHARE`] of its own first step and the rest the given poses' last step.
    Given(&'a [f32]),
}

impl Seam<'_> {
    /// The last pose before the block.
    pub fn last(&self, dim: usize) -> &[f32] {
        let before: &[f32] = match self {
            Seam::Own(before) => before,
            Seam::Given(given) => given,
        };
        &before[before.len() - dim..]
    }
}

/// The share of GloGen's own first step in a block's first step on from real motion it was
/// given ([`Seam::Given`]); the rest is that motion's own last step, continued. After its
/// own block GloGen continues motion it made, and its first step is the block's; after a
/// real person's poses its first step is a guess at where that person goes next, and the
/// person's own last step is part of a better guess. On the held-out clips of Human3.6M
/// (S11) and Bandai (its tired and musical styles) with `models/all`, the first forecast
/// pose (0.1 s on) comes nearest the real one at a share of 0.4 (mean joint error 20.2 mm,
/// against 26.7 with GloGen's own step alone; 22.6 mm at 0.75). Continuing a walk from a
/// Rigify armature (the Blender add-on's test), a foot pointing down at the first toe-off
/// pivots more, the nearer the share comes to 0.4: while the retargeting levelled every foot,
/// its heel turned 164 degrees in a frame at 0.4 (19 at 0.75); a steep foot now turns on its
/// ankle's hinge (`motion::retarget`), and at 0.4 the heel turns 15.6 degrees a frame at most.
/// docs/DESIGN.md, "The first step from a file". CMU's clips, which the forecast table
/// scores, were not used to choose it.
pub const GIVEN_STEP_SHARE: f32 = 0.4;

/// Joins `block` onto the poses before it, `seam` (see [`super::glogen::GloGen::rollout_block`]).
/// Features 1-3 (the root's ground displacement and heading change) are velocities already
/// (the block's first moves halfway to the context's last); the rest are positions, and the block's first pose moves to one of the
/// block's own first steps on from the context's last pose. The shift fades out over the
/// first half of the block with a raised cosine, so the block keeps its own motion and ends
/// where GloGen put it. Faded over the whole block, the shifted root height and joints kept
/// a running body off its feet for 1.5 s (Bandai floating 21% of frames against 13%; on the
/// final tree 23% with only the root's fade that long and 25% with only the joints',
/// against 16%). The join used to continue the context's last step instead (positions at
/// their last velocity): a sparse step is 0.17-0.2 s, and extrapolating it carried a
/// landing foot through the floor at every seam of a walk (Bandai's walks then floated 86%
/// of the time over the floor those dips set); the mean of the two steps left a hitch (the
/// seam interval 0.77x the others' speed). Measured in docs/DESIGN.md ("Seams"). Onto given
/// motion ([`Seam::Given`]) the first step blends in that motion's own last step, once.
///
/// [`Seam::Own`] is the whole block before or only its last pose; with [`SeamJoin::TwoSided`] a
/// whole block takes half the shift, opposite, faded in over its last half, and the new
/// block the other half, so neither block's first half carries all of the other's pose.
///
/// A block on its way to a key (`steps: false`) keeps its root's steps: they are the
/// straight line to where the key stands, and a step bent towards the context's would turn
/// the whole way off it (Bandai's 2 s in-betweens strayed 13 cm from the line).
///
/// The shift fades out over `span` poses: the first half of the block ([`half_block`]), or
/// longer for a block that changes the body's height a long way (standing up from a seat,
/// [`super::glogen::GloGen::rollout_block`]).
pub fn join_seam(seam: Seam<'_>, block: &mut [f32], dim: usize, kind: SeamJoin, steps: bool, span: usize) {
    let poses = block.len() / dim;
    if poses < 2 {
        return;
    }
    let last = seam.last(dim);
    let given_step = |f: usize| match &seam {
        Seam::Given(given) if given.len() >= 2 * dim => Some(last[f] - given[given.len() - 2 * dim + f]),
        _ => None,
    };
    let shift: Vec<f32> = (0..dim)
        .map(|f| {
            let own_step = block[dim + f] - block[f];
            if (1..ROOT_FEATURES).contains(&f) {
                if steps { 0.5 * (last[f] + block[dim + f]) - block[f] } else { 0.0 }
            } else if let Some(given) = given_step(f) {
                last[f] + GIVEN_STEP_SHARE * own_step + (1.0 - GIVEN_STEP_SHARE) * given - block[f]
            } else {
                last[f] + own_step - block[f]
            }
        })
        .collect();
    let share = match &seam {
        Seam::Own(before) => seam_share(kind, before.len() == block.len()),
        Seam::Given(_) => 1.0,
    };
    let fade = join_fade(poses, span);
    for (k, w) in fade.iter().enumerate() {
        block[k * dim..(k + 1) * dim].iter_mut().zip(&shift).for_each(|(v, d)| *v += share * d * w);
    }
    if let (Seam::Own(before), true) = (seam, share < 1.0) {
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

/// The poses of a block of `poses` that a seam's shift usually fades over: its first half.
pub fn half_block(poses: usize) -> usize {
    poses / 2
}

/// The share of a seam's shift each of a block's `poses` keeps: a raised cosine from 1 at its
/// first pose to 0 at pose `span`.
fn join_fade(poses: usize, span: usize) -> Vec<f32> {
    (0..poses).map(|k| if k < span { 0.5 * (1.0 + (std::f32::consts::PI * k as f32 / span as f32).cos()) } else { 0.0 }).collect()
}

/// [`join_seam`] on a batch of blocks `[B, T, D]` onto the blocks before them `[B, T, D]`
/// (or their last poses `[B, 1, D]`, which stay where they are), as differentiable tensor
/// operations: what training on joined rollouts backpropagates through. `steps` `[B, 1, 1]`
/// is 1 where a block's root steps are joined too, 0 where it is on its way to a key (all
/// joined without it). Returns the joined blocks before and the joined blocks.
pub fn join_seams_tensor(before: &Tensor, blocks: &Tensor, kind: SeamJoin, steps: Option<&Tensor>) -> candle_core::Result<(Tensor, Tensor)> {
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
    let mut shift = (target - first)?;
    if let Some(steps) = steps {
        // Per block, 1 on the pose's features and `steps` on the root's steps.
        let weight = (1.0 - &root)?.broadcast_add(&root.broadcast_mul(steps)?)?;
        shift = shift.broadcast_mul(&weight)?;
    }
    let share = seam_share(kind, before.dim(1)? == poses) as f64;
    let fade = join_fade(poses, half_block(poses));
    let head = Tensor::from_vec(fade.clone(), (1, poses, 1), device)?;
    let joined = (blocks + shift.broadcast_mul(&head)?.affine(share, 0.0)?)?;
    if share == 1.0 {
        return Ok((before.clone(), joined));
    }
    let tail = Tensor::from_vec(fade.into_iter().rev().collect(), (1, poses, 1), device)?;
    let before = (before - shift.broadcast_mul(&tail)?.affine(1.0 - share, 0.0)?)?;
    Ok((before, joined))
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

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
                let steps = Tensor::from_vec(vec![1.0f32, 0.0], (2, 1, 1), &Device::Cpu).unwrap();
                let (joined_before, joined) = join_seams_tensor(&tensor(&before, before_poses), &tensor(&blocks, poses), kind, Some(&steps)).unwrap();
                let flat = |t: Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
                let (joined_before, joined) = (flat(joined_before), flat(joined));
                for b in 0..2 {
                    let (width, before_width) = (poses * dim, before_poses * dim);
                    let mut block = blocks[b * width..(b + 1) * width].to_vec();
                    let mut prior = before[b * before_width..(b + 1) * before_width].to_vec();
                    let span = half_block(block.len() / dim);
                    join_seam(Seam::Own(&mut prior), &mut block, dim, kind, b == 0, span);
                    if b == 1 {
                        let steps_kept = (0..poses).all(|k| (1..ROOT_FEATURES).all(|f| block[k * dim + f] == blocks[b * width + k * dim + f]));
                        assert!(steps_kept, "a block on its way to a key had its root steps joined");
                    }
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

    /// A seam onto given poses makes the block's first step [`GIVEN_STEP_SHARE`] of its own
    /// first step and the rest the given poses' last step, and leaves them where they were; a
    /// seam onto GloGen's own last pose makes it the block's own step.
    #[test]
    fn a_seam_onto_given_poses_blends_in_their_last_step() {
        let (poses, dim) = (8, 6);
        let value = |i: usize| ((i * 7919) % 83) as f32 / 9.0 - 4.0;
        let block: Vec<f32> = (0..poses * dim).map(value).collect();
        let given: Vec<f32> = (0..3 * dim).map(|i| value(i + 333)).collect();
        let (prev, last) = (&given[dim..2 * dim], &given[2 * dim..]);
        for onto_given in [true, false] {
            let mut joined = block.clone();
            let mut own = last.to_vec();
            let seam = if onto_given { Seam::Given(&given) } else { Seam::Own(&mut own) };
            join_seam(seam, &mut joined, dim, SeamJoin::TwoSided, true, half_block(poses));
            assert_eq!(own, last, "the join moved the pose before");
            for f in ROOT_FEATURES..dim {
                let own_step = block[dim + f] - block[f];
                let expected = if onto_given { GIVEN_STEP_SHARE * own_step + (1.0 - GIVEN_STEP_SHARE) * (last[f] - prev[f]) } else { own_step };
                let step = joined[f] - last[f];
                assert!((step - expected).abs() < 1e-5, "feature {f}: step {step} against {expected} (onto given poses: {onto_given})");
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
            let span = half_block(joined.len() / dim);
            join_seam(Seam::Own(&mut prior), &mut joined, dim, kind, true, span);
            let last = &prior[(poses - 1) * dim..];
            seams.push((ROOT_FEATURES..dim).map(|f| joined[f] - last[f]).collect::<Vec<f32>>());
        }
        for (a, b) in seams[0].iter().zip(&seams[1]) {
            assert!((a - b).abs() < 1e-5, "seam step {a} one-sided against {b} two-sided");
        }
    }
}
