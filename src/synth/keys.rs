//! Keyframes in the take: each key's pose is reached twice over. GloGen's sparse poses are
//! warped onto the key where the block that holds it comes out, with a raised-cosine share
//! over the 2 s before (and what the block still holds after), so every later block is
//! conditioned on the keyed pose and continues from it; then the dense frames get the small
//! residual LocGen and the foot lock leave, over half a second either side. A key within the
//! model's in-betweener's reach of the known pose before it has the gap between filled by the
//! in-betweener ([`crate::model::inbetween`]). The ablation in docs/RESULTS.md (`glocal eval
//! --suite constraints`) compares the ways of doing it.

use std::ops::Range;

use anyhow::{bail, Context, Result};
use glam::{Quat, Vec3};

use super::constraints::{check_keys, Key, KeySource};
use super::init::{read_on_model_skeleton, FileStart, InitPose};
use super::options::KeyMethod;
use super::plan::{PlannedBlock, SparseTimeline, TakeConstraint};
use super::{raised_cosine, smoothstep};
use crate::data::features::{wrap, FeatureLayout, Placement, ROOT_FEATURES};
use crate::model::block::BlockWorkspace;
use crate::model::glocal::GlocalModel;
use crate::model::inbetween::{bend_ends, BEND_SECONDS};
use crate::model::glogen::GloGen;
use crate::model::seam::Seam;
use crate::motion::{solve_local_poses, Motion};

/// Seconds before a key over which GloGen's sparse poses are warped towards it.
const SPARSE_REACH_SECONDS: f32 = 2.0;

/// Extra travel speed (m/s) a root-fixing key may add before the user is told: about a
/// third of a walk, where planted feet start to visibly slide.
const MAX_PULL_M_S: f32 = 0.4;

/// Half-width (seconds) of the dense residual warp around a key.
const DENSE_REACH_SECONDS: f32 = 0.5;

/// A key placed in the take.
#[derive(Clone, Debug)]
pub struct PlacedKey {
    /// The sparse pose the key lands on.
    pub sparse: usize,
    /// Its frame in the paced take.
    pub frame: usize,
    /// The pose, world positions on the model's skeleton with its bone lengths.
    pub pose: Vec<Vec3>,
    /// The pose as one normalised sparse feature vector.
    pub features: Vec<f32>,
    pub fix_root: bool,
    /// The last sparse pose and the last frame of the take's starting poses, which reaching
    /// the key leaves as they are.
    pub given_sparse: usize,
    pub given_frame: usize,
}

/// The key's pose as world positions on the model's skeleton, its bones set to the model's
/// lengths (a pose from another subject or file is reachable exactly), in the world of a take
/// started from `init`: a frame of the file the take starts from stands where that file
/// puts it relative to the start ([`FileStart`]).
pub fn key_pose(model: &GlocalModel, key: &Key, init: &InitPose) -> Result<Vec<Vec3>> {
    let spec = &model.spec;
    let joints = spec.layout.joints();
    let pose = match &key.source {
        KeySource::Pose(p) => {
            let flat: Vec<f32> = p.iter().flatten().copied().collect();
            // A pose saved before the skeleton kept the joints that only turn a chain (a project
            // of Human3.6M's 27-joint model) has each put back at its parent.
            let flat = spec.layout.skeleton.with_turning_joints(&flat, 3, <[f32]>::to_vec).unwrap_or(flat);
            if flat.len() != 3 * joints || flat.iter().any(|v| !v.is_finite()) {
                bail!("key at {} s: the pose has {} joints; the model's skeleton has {joints} (all finite)", key.seconds, p.len());
            }
            flat.chunks_exact(3).map(Vec3::from_slice).collect()
        }
        KeySource::Init(InitPose::SeedIndex(i)) => {
            let seed = model.seeds.get(*i).with_context(|| format!("key at {} s: seed {i} does not exist; the seed bank has {} seeds", key.seconds, model.seeds.len()))?;
            last_pose(&spec.layout, &seed.features)
        }
        KeySource::Init(InitPose::SeedClass { class, variant }) => {
            let k = spec.class_index(class)?;
            let seed = model.seed_of_class(k, *variant).with_context(|| format!("key at {} s: the seed bank has no seed of class '{class}'", key.seconds))?;
            last_pose(&spec.layout, &seed.features)
        }
        KeySource::Init(InitPose::File { path, frame, joint_map }) => {
            let file = read_on_model_skeleton(model, path, joint_map.as_ref())?;
            let at = file.frame_of(*frame).with_context(|| format!("key at {} s", key.seconds))?;
            let motion = &file.motion;
            match init {
                InitPose::File { path: start_file, frame: start, .. } if start_file == path && *start < file.file_frames => {
                    FileStart::of(model, motion, file.frame_of(*start)?).apply(motion.frame(at))
                }
                _ => {
                    // On the model's floor, as a starting clip is.
                    let lift = model.floor_height() - motion.floor_height();
                    motion.frame(at).iter().map(|p| *p + Vec3::Y * lift).collect()
                }
            }
        }
    };
    let skeleton = spec.layout.skeleton.clone();
    Ok(Motion::from_local_poses(skeleton.clone(), spec.fps, solve_local_poses(&skeleton, &pose)).frame(0).to_vec())
}

fn last_pose(layout: &FeatureLayout, window: &[f32]) -> Vec<Vec3> {
    let (positions, _) = layout.decode(window, Placement::default());
    positions[positions.len() - layout.joints()..].to_vec()
}

/// The features a key's pose sets: the root's height and the joints relative to the root.
fn keyed(d: usize) -> bool {
    d == 0 || d >= ROOT_FEATURES
}

/// Warps the normalised sparse poses generated so far (`sparse`, `dim` per pose) onto `key`:
/// exactly at its pose, by a raised-cosine share over [`SPARSE_REACH_SECONDS`] before it and
/// as far after it as poses exist.
pub fn warp_sparse(sparse: &mut [f32], dim: usize, key: &PlacedKey, step_seconds: f32) {
    let reach = (SPARSE_REACH_SECONDS / step_seconds).ceil().max(1.0) as usize;
    // The share falls to nothing by the last starting pose.
    let before = reach.min(key.sparse - key.given_sparse);
    let at = &sparse[key.sparse * dim..(key.sparse + 1) * dim];
    let delta: Vec<f32> = at.iter().zip(&key.features).enumerate().map(|(d, (v, k))| if keyed(d) { k - v } else { 0.0 }).collect();
    let poses = sparse.len() / dim;
    for i in key.sparse + 1 - before..poses.min(key.sparse + reach) {
        let w = raised_cosine(i.abs_diff(key.sparse) as f32 / if i < key.sparse { before } else { reach } as f32);
        sparse[i * dim..(i + 1) * dim].iter_mut().zip(&delta).for_each(|(v, d)| *v += w * d);
    }
}

/// Warps dense frames (`joints` per frame) so the body at the key's frame is the key's pose
/// relative to the root (and its root at the key's height), the residual fading over
/// [`DENSE_REACH_SECONDS`] either side. Returns the frames it touched.
pub fn warp_dense(positions: &mut [Vec3], layout: &FeatureLayout, fps: f32, key: &PlacedKey) -> std::ops::Range<usize> {
    let j = layout.joints();
    let frames = positions.len() / j;
    if key.frame >= frames {
        return 0..0;
    }
    let frame = &positions[key.frame * j..(key.frame + 1) * j];
    let (root, heading) = (frame[0], layout.heading(frame));
    let key_heading = layout.heading(&key.pose);
    let lift = key.pose[0].y - root.y;
    // Per joint, the residual in the body's own heading frame.
    let residual: Vec<Vec3> = (0..j)
        .map(|k| {
            let want = Quat::from_rotation_y(-key_heading) * (key.pose[k] - key.pose[0]);
            let have = Quat::from_rotation_y(-heading) * (frame[k] - root);
            want - have
        })
        .collect();
    let reach = (DENSE_REACH_SECONDS * fps).round().max(1.0) as usize;
    // The residual falls to nothing by the last frame of the starting poses.
    let before = reach.min(key.frame.saturating_sub(key.given_frame)).max(1);
    let touched = key.frame + 1 - before..frames.min(key.frame + reach);
    for f in touched.clone() {
        let w = raised_cosine(f.abs_diff(key.frame) as f32 / if f < key.frame { before } else { reach } as f32);
        let pose = &mut positions[f * j..(f + 1) * j];
        let turn = Quat::from_rotation_y(layout.heading(pose));
        for (p, r) in pose.iter_mut().zip(&residual) {
            *p += w * (Vec3::Y * lift + turn * *r);
        }
    }
    touched
}

/// The take's frames with each key's dense residual warped away again after the foot lock
/// (which may have moved a keyed foot, and takes a standing body's drift out, moving the
/// root), and root-fixing keys' roots put back; rotations solved again where frames moved.
pub fn rewarp(motion: Motion, layout: &FeatureLayout, keys: &[PlacedKey]) -> Motion {
    if keys.is_empty() {
        return motion;
    }
    let mut positions = motion.positions().to_vec();
    // What is left to fix is the lock's few centimetres, under any pull worth a warning.
    let moves_roots = keys.iter().any(|k| k.fix_root);
    if moves_roots {
        fix_roots(&mut positions, layout, motion.fps, keys);
    }
    let touched: Vec<std::ops::Range<usize>> = keys.iter().map(|k| warp_dense(&mut positions, layout, motion.fps, k)).collect();
    let skeleton = motion.skeleton.clone();
    let Some(mut poses) = motion.local_poses else {
        return Motion::from_positions(skeleton, motion.fps, positions);
    };
    if moves_roots {
        let poses = solve_local_poses(&skeleton, &positions);
        return Motion::from_local_poses(skeleton, motion.fps, poses);
    }
    let j = skeleton.len();
    for range in touched {
        let solved = solve_local_poses(&skeleton, &positions[range.start * j..range.end * j]);
        poses.splice(range, solved);
    }
    Motion::from_local_poses(skeleton, motion.fps, poses)
}

/// Moves where the body stands and faces so each root-fixing key's root is where its pose
/// stood: the offset (position and heading, about the body's own root) grows by a smoothstep
/// from the start (or the previous such key) to each key, and after the last one the rest of
/// the take is carried rigidly about that key's root, so it walks on in the keyed direction.
/// Returns a sentence per key that pulls the body faster than [`MAX_PULL_M_S`].
pub fn fix_roots(positions: &mut [Vec3], layout: &FeatureLayout, fps: f32, keys: &[PlacedKey]) -> Vec<String> {
    let j = layout.joints();
    let frames = positions.len() / j;
    // Per root-fixing key in time order: its frame, and the shift and turn that put the body
    // where the key's pose stands; the take's start is fixed where it is.
    let mut targets: Vec<(usize, Vec3, f32)> = keys
        .iter()
        .filter(|k| k.fix_root && k.frame < frames)
        .map(|k| {
            let frame = &positions[k.frame * j..(k.frame + 1) * j];
            let d = k.pose[0] - frame[0];
            (k.frame, Vec3::new(d.x, 0.0, d.z), wrap(layout.heading(&k.pose) - layout.heading(frame)))
        })
        .collect();
    targets.sort_by_key(|t| t.0);
    let Some(&(last_frame, last_shift, last_turn)) = targets.last() else { return Vec::new() };
    // The starting poses stay where they were given; the offsets grow after them.
    let given = keys[0].given_frame;
    let start = (given, Vec3::ZERO, 0.0f32);
    let metres = layout.skeleton.meters_per_unit();
    let mut warnings = Vec::new();
    for (&(pf, pd, _), &(kf, d, _)) in std::iter::once(&start).chain(&targets).zip(&targets) {
        let gap = (d - pd).length() * metres;
        let pull = gap * fps / (kf - pf).max(1) as f32;
        if pull > MAX_PULL_M_S {
            warnings.push(format!("the key at {:.1} s stands {gap:.1} m from where the take would be; reaching it adds {pull:.2} m/s to the body's travel, so its feet will slide (key a frame of this take, or give the key more time)", kf as f32 / fps));
        }
    }
    let pivot = positions[last_frame * j];
    for f in given..frames {
        let (shift, turn, about_own_root) = match targets.iter().position(|t| t.0 >= f) {
            Some(i) => {
                let ((pf, pd, ph), (kf, d, h)) = (if i == 0 { start } else { targets[i - 1] }, targets[i]);
                let s = smoothstep((f - pf) as f32 / (kf - pf).max(1) as f32);
                (pd.lerp(d, s), ph + s * (h - ph), true)
            }
            None => (last_shift, last_turn, false),
        };
        let pose = &mut positions[f * j..(f + 1) * j];
        let centre = if about_own_root { pose[0] } else { pivot };
        let rot = Quat::from_rotation_y(turn);
        pose.iter_mut().for_each(|p| *p = centre + rot * (*p - centre) + shift);
    }
    warnings
}

/// Each key on the sparse pose nearest its time after the seed block of `timeline`, with its
/// pose.
pub(super) fn place_keys(timeline: &SparseTimeline, model: &GlocalModel, keys: &[Key], init: &InitPose) -> Result<Vec<PlacedKey>> {
    let spec = &model.spec;
    let t = spec.block_len;
    let total = timeline.total();
    if keys.is_empty() {
        return Ok(Vec::new());
    }
    // A take no longer than its starting poses has no room for a key.
    let seed_end = timeline.frames[(t - 1).min(total - 1)] as f32 / spec.fps;
    check_keys(keys, timeline.frames[total - 1] as f32 / spec.fps, seed_end)?;
    if total <= t {
        bail!("keys need a take longer than its starting poses ({seed_end:.2} s)");
    }
    keys.iter()
        .map(|key| {
            let pose = key_pose(model, key, init)?;
            let frame = (key.seconds * spec.fps).round() as usize;
            let sparse = (t..total).min_by(|&a, &b| (timeline.frames[a] - frame as f64).abs().total_cmp(&(timeline.frames[b] - frame as f64).abs())).unwrap_or(t);
            let mut features = spec.layout.encode(&[&pose], None);
            spec.sparse_norm.normalize(&mut features);
            // The starting poses end at the seed's last pose.
            let given_frame = timeline.frames[t - 1].round() as usize;
            Ok(PlacedKey { sparse, frame, pose, features, fix_root: key.fix_root, given_sparse: t - 1, given_frame })
        })
        .collect()
}

/// The keys of a take as a constraint: GloGen's sparse poses warped onto each key as its
/// block comes out (and, for [`KeyMethod::RollOn`], the rest of that block rolled out again
/// from the keyed context), the dense frames' roots and poses pulled onto them, and the
/// residual the foot lock leaves warped away.
pub(super) struct KeyConstraint<'a> {
    /// Every key, placed.
    pub keys: Vec<PlacedKey>,
    /// The model whose in-betweener fills the gaps before keys ([`KeyMethod::Inbetween`]).
    pub model: &'a GlocalModel,
    /// The frames it fills ([`filled_gaps`]).
    pub gaps: Vec<Range<usize>>,
    /// Per key, seconds per sparse step at its segment's pace.
    pub step_seconds: Vec<f32>,
    pub method: KeyMethod,
}

/// The frames the in-betweener fills before keys, in time order: each key's gap from the
/// known pose before it (the last starting pose, or the key before), where `method` fills
/// gaps, the model has an in-betweener that reaches that far, and the take has the known
/// frames it reads before the gap. Each range ends at its key's frame.
pub(super) fn filled_gaps(model: &GlocalModel, method: KeyMethod, keys: &[PlacedKey]) -> Vec<Range<usize>> {
    let Some(spec) = model.inbetween().filter(|_| method == KeyMethod::Inbetween) else { return Vec::new() };
    let (max_gap, context) = (spec.max_gap, spec.context);
    let mut frames: Vec<usize> = keys.iter().map(|k| k.frame).collect();
    frames.sort_unstable();
    let mut known = keys.first().map_or(0, |k| k.given_frame);
    let mut gaps = Vec::new();
    for frame in frames {
        let gap = frame.saturating_sub(known + 1);
        if (1..=max_gap).contains(&gap) && known >= context {
            gaps.push(known + 1..frame);
        }
        known = frame;
    }
    gaps
}

/// The frames whose travel is real motion's, which a foot lock that carries the body by its
/// feet leaves as they are: the `gaps` the in-betweener fills ([`filled_gaps`]), and the
/// starting poses (a seed window or a file's frames) before a gap filled right after them.
pub(super) fn learnt_travel(gaps: &[Range<usize>], keys: &[PlacedKey]) -> Vec<Range<usize>> {
    let after_start = keys.first().map(|k| k.given_frame + 1);
    gaps.iter().map(|g| if Some(g.start) == after_start { 0..g.end } else { g.clone() }).collect()
}

impl KeyConstraint<'_> {
    /// The gaps before keys ([`Self::gaps`]) filled by the model's in-betweener, in time
    /// order, from the take's own frames either side.
    fn fill_gaps(&self, positions: &mut [Vec3], j: usize) {
        let Some(spec) = self.model.inbetween() else { return };
        let (context, after) = (spec.context, spec.after);
        let frames = positions.len() / j;
        let gaps = self.gaps.iter().filter(|g| g.end < frames);
        for gap in gaps.clone() {
            let known = gap.start - 1;
            let read = |range: Range<usize>| positions[range.start * j..range.end * j].to_vec();
            let ahead = gap.end..frames.min(gap.end + 1 + after);
            let (before, given, ahead) = (read(known - context..known + 1 - context), read(known + 1 - context..known + 1), read(ahead));
            if let Some(filled) = self.model.fill_gap(&before, &given, &ahead, gap.len()) {
                positions[gap.start * j..gap.end * j].copy_from_slice(&filled);
            }
        }
        // Each fill meets the take at both ends once every gap is filled (the frames after a
        // key may be the next gap's).
        let reach = (BEND_SECONDS * self.model.spec.fps).round() as usize;
        for gap in gaps {
            bend_ends(positions, j, gap.clone(), reach);
        }
    }
}

impl TakeConstraint for KeyConstraint<'_> {
    fn on_block(&self, block: &PlannedBlock<'_>, (glogen, ws): (&GloGen, &mut BlockWorkspace), sparse: &mut [f32]) {
        let (t, dim) = (glogen.block_len(), glogen.dim());
        let mut out = vec![0.0; t * dim];
        for &k in &block.plan.keys {
            let key = &self.keys[k];
            warp_sparse(sparse, dim, key, self.step_seconds[k]);
            // What the block held after the key was GloGen's way on without it: the rest of
            // the block is rolled out again from the context that ends on the key.
            let after = (key.sparse + 1) * dim;
            if after < sparse.len() && self.method == KeyMethod::RollOn {
                let input = sparse[after - t * dim..after].to_vec();
                let mut key = input[(t - 1) * dim..].to_vec();
                glogen.rollout_block(ws, &input, &block.plan.class, block.strength, block.join_seams.then_some(Seam::Own(&mut key[..])), &mut out);
                let rest = sparse.len() - after;
                sparse[after..].copy_from_slice(&out[..rest]);
            }
        }
    }

    fn on_dense(&self, positions: &mut [Vec3], layout: &FeatureLayout, fps: f32) -> Vec<String> {
        let warnings = fix_roots(positions, layout, fps, &self.keys);
        for key in &self.keys {
            warp_dense(positions, layout, fps, key);
        }
        self.fill_gaps(positions, layout.joints());
        warnings
    }

    fn own_frames(&self) -> &[Range<usize>] {
        &self.gaps
    }

    fn on_finished(&self, motion: Motion, layout: &FeatureLayout) -> Motion {
        rewarp(motion, layout, &self.keys)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raised_cosine_is_one_at_the_key_and_zero_at_its_reach() {
        assert_eq!(raised_cosine(0.0), 1.0);
        assert!((raised_cosine(0.5) - 0.5).abs() < 1e-6);
        assert_eq!(raised_cosine(1.0), 0.0);
        assert_eq!(raised_cosine(3.0), 0.0);
    }

    #[test]
    fn the_sparse_warp_lands_on_the_key_and_leaves_the_root_velocity() {
        let dim = ROOT_FEATURES + 3;
        let mut sparse = vec![0.0; 20 * dim];
        let key = PlacedKey { sparse: 10, frame: 0, pose: vec![], features: vec![1.0; dim], fix_root: false, given_sparse: 2, given_frame: 0 };
        warp_sparse(&mut sparse, dim, &key, 0.4);
        assert_eq!(&sparse[10 * dim..11 * dim], &[1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        // Five poses of reach before and after at 0.4 s a step: the fifth away is untouched.
        assert!(sparse[6 * dim] > 0.0 && sparse[5 * dim] == 0.0 && sparse[15 * dim] == 0.0);
        assert!(sparse[8 * dim] > sparse[7 * dim]);
        // A key two poses after the starting poses reaches only the pose between.
        let mut sparse = vec![0.0; 20 * dim];
        warp_sparse(&mut sparse, dim, &PlacedKey { given_sparse: 8, ..key }, 0.4);
        assert!(sparse[9 * dim] > 0.0 && sparse[8 * dim] == 0.0, "the warp moved the last starting pose");
    }
}
