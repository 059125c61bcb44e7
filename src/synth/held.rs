//! Held stretches: frames of an earlier take that a new take keeps exactly, so one segment
//! can be rerolled or edited while every frame outside it and its two transitions stays as it
//! was, and a locked segment keeps its frames through edits of the others.
//!
//! The request carries the held frames themselves (local poses, or positions for a take
//! without bone rotations), so `glocal generate --project` makes the studio's take again
//! whatever seeds or edits the held segments came from. Generation meets them at every
//! stage, as keys are met: GloGen's sparse poses over held frames are the held take's, a
//! free stretch's poses are warped onto the held pose at each end (2 s reach, as a key's:
//! the following segments are joined onto the new one, not rolled out again), the dense
//! frames of a free stretch are turned and shifted to stand where the held frames on either
//! side stand, and the finished take shows the held frames exactly, the pose difference at
//! each end fading out inside the free stretch.

use std::ops::Range;
use std::sync::Arc;

use anyhow::{bail, Result};
use glam::{Quat, Vec3};

use super::held_frames::{HeldFrames, HeldStretch};
use super::keys::{warp_sparse, PlacedKey};
use super::options::{GenerateOptions, Transition};
use super::plan::{PlannedBlock, SegmentSpan, SparseTimeline, TakeConstraint};
use super::{raised_cosine, smoothstep};
use crate::data::features::{wrap, FeatureLayout, ROOT_FEATURES};
use crate::model::block::BlockWorkspace;
use crate::model::glogen::GloGen;
use crate::model::spec::ModelSpec;
use crate::motion::contacts::runs;
use crate::motion::{solve_local_poses, LocalPose, Motion};

/// The most frames a request holds, in seconds of the take: five minutes keep a project file
/// under about 20 MB (a frame of local poses is up to 111 numbers, ~24 bytes each in the
/// project's pretty JSON). Longer takes are generated whole.
pub const MAX_HELD_SECONDS: f32 = 300.0;

/// Seconds over which the pose difference at either end of a free stretch fades out (at
/// most half the stretch).
const JOIN_FADE_SECONDS: f32 = 1.0;

/// How a new take keeps one segment of the take before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Kept {
    /// The segment's index in the take before, and in the new take's timeline.
    pub before: usize,
    pub after: usize,
    /// All of it, transitions into free neighbours included (a locked segment); otherwise
    /// the halves of the transitions into free neighbours are left to them.
    pub whole: bool,
}

/// Where each segment of `opts`'s timeline falls in the take, before anything is generated
/// (the spans [`super::generate`] reports).
pub fn planned_spans(spec: &ModelSpec, opts: &GenerateOptions) -> Result<Vec<SegmentSpan>> {
    Ok(SparseTimeline::new(spec, opts)?.planned_spans(spec))
}

/// Frames of the transition into segment `k` on each side of its boundary.
fn half_transition(opts: &GenerateOptions, k: usize, fps: f32) -> usize {
    if k == 0 || opts.transition == Transition::Cut {
        return 0;
    }
    let seconds = opts.timeline.segments[k].transition.unwrap_or(opts.transition_seconds);
    (seconds * fps / 2.0).round() as usize
}

/// The stretches of `before` (a take made with `before_spans`) that a take of `opts` keeps:
/// each kept segment's frames, where the new timeline puts it. A kept segment whose length
/// changed is not kept. Fails when the frames held would pass [`MAX_HELD_SECONDS`].
pub fn hold_segments(spec: &ModelSpec, before: &Motion, before_spans: &[SegmentSpan], opts: &GenerateOptions, kept: &[Kept]) -> Result<Vec<HeldStretch>> {
    let spans = planned_spans(spec, opts)?;
    let is_kept = |k: usize| kept.iter().any(|s| s.after == k);
    let mut held = Vec::new();
    for keep in kept {
        let (Some(old), Some(new)) = (before_spans.get(keep.before), spans.get(keep.after)) else { continue };
        if old.end_frame - old.start_frame != new.end_frame - new.start_frame || old.end_frame > before.frames() {
            continue;
        }
        let k = keep.after;
        let trim_in = if keep.whole || k == 0 || is_kept(k - 1) { 0 } else { half_transition(opts, k, spec.fps) };
        let trim_out = if keep.whole || k + 1 >= spans.len() || is_kept(k + 1) { 0 } else { half_transition(opts, k + 1, spec.fps) };
        let (start, end) = (old.start_frame + trim_in, old.end_frame.saturating_sub(trim_out));
        if start < end {
            held.push(HeldStretch { first_frame: new.start_frame + trim_in, frames: Arc::new(HeldFrames::capture(before, start..end)) });
        }
    }
    held.sort_by_key(|h| h.first_frame);
    check_held_seconds(&held, spec.fps)?;
    Ok(held)
}

/// Refuses more held frames than a request may carry, whether an edit made them or a project
/// file brought them.
fn check_held_seconds(held: &[HeldStretch], fps: f32) -> Result<()> {
    let seconds = held.iter().map(|h| h.frames.len()).sum::<usize>() as f32 / fps;
    if seconds > MAX_HELD_SECONDS {
        bail!("held stretches: {seconds:.0} s of the take's frames; a request holds at most {MAX_HELD_SECONDS:.0} s, so the take is generated whole");
    }
    Ok(())
}

/// The held stretches of a request as a constraint on its take (see the module's text).
pub(super) struct HeldConstraint {
    /// Per frame of the take: its held world position, where it is held.
    positions: Vec<Option<Vec<Vec3>>>,
    /// Per held frame, its local pose where the stretch holds poses.
    poses: Vec<Option<LocalPose>>,
    /// Per sparse pose: its features (normalised) where its frame is held.
    sparse: Vec<Option<Vec<f32>>>,
    /// Runs of sparse poses between held ones.
    free_sparse: Vec<Range<usize>>,
    /// Runs of frames between held ones.
    free: Vec<Range<usize>>,
    /// Seconds per sparse step at each sparse pose's segment's pace.
    step_seconds: Vec<f32>,
    block_len: usize,
    /// Frames of the take's keys.
    key_frames: Vec<usize>,
}

impl HeldConstraint {
    pub(super) fn new(spec: &ModelSpec, held: &[HeldStretch], timeline: &SparseTimeline, key_frames: Vec<usize>) -> Result<Self> {
        let skeleton = &spec.layout.skeleton;
        let frames = timeline.take_frames();
        check_held_seconds(held, spec.fps)?;
        let mut positions = vec![None; frames];
        let mut poses = vec![None; frames];
        for (k, stretch) in held.iter().enumerate() {
            let what = format!("held stretch {} (frames {}..{})", k + 1, stretch.first_frame, stretch.first_frame + stretch.frames.len());
            let held = stretch.frames.fitted(skeleton);
            held.check(skeleton, &what)?;
            if stretch.first_frame + held.len() > frames {
                bail!("{what}: lies beyond the take's {frames} frames");
            }
            let j = skeleton.len();
            let world = held.positions(skeleton, spec.fps);
            let locals = held.local_poses(skeleton);
            for f in 0..held.len() {
                let at = stretch.first_frame + f;
                if positions[at].is_some() {
                    bail!("{what}: overlaps another held stretch at frame {at}");
                }
                positions[at] = Some(world[f * j..(f + 1) * j].to_vec());
                poses[at] = locals.as_ref().map(|p| p[f].clone());
            }
        }
        let sparse = sparse_features(spec, timeline, &positions);
        let free_sparse = runs(&sparse.iter().map(Option::is_none).collect::<Vec<_>>());
        let free = runs(&positions.iter().map(Option::is_none).collect::<Vec<_>>());
        let step_seconds = (0..sparse.len()).map(|i| timeline.step_seconds[timeline.segment_at(i)]).collect();
        Ok(Self { positions, poses, sparse, free_sparse, free, step_seconds, block_len: spec.block_len, key_frames })
    }

    /// The held pose at sparse index `i` as a key to warp GloGen's poses onto, leaving the
    /// poses up to `given` alone.
    fn key_at(&self, i: usize, given: usize) -> Option<PlacedKey> {
        let features = self.sparse.get(i)?.clone()?;
        Some(PlacedKey { sparse: i, frame: 0, pose: Vec::new(), features, fix_root: false, given_sparse: given, given_frame: 0 })
    }

    /// Runs of frames between held ones: all a take of these held frames has to make.
    pub(super) fn free_frames(&self) -> &[Range<usize>] {
        &self.free
    }

    /// The normalised sparse poses `poses` when all of them are held: a block of them need
    /// not be made.
    pub(super) fn held_block(&self, poses: Range<usize>) -> Option<Vec<f32>> {
        poses.map(|i| self.sparse.get(i)?.as_deref()).collect::<Option<Vec<&[f32]>>>().map(|p| p.concat())
    }

    /// Whether all of the sparse poses `poses` are held.
    pub(super) fn holds(&self, mut poses: Range<usize>) -> bool {
        poses.all(|i| self.sparse.get(i).is_some_and(Option::is_some))
    }

    /// The held world position of frame `f`.
    pub(super) fn held(&self, f: usize) -> Option<&[Vec3]> {
        self.positions.get(f)?.as_deref()
    }

    /// Turns and shifts each free stretch's frames so the body stands where the held frames
    /// on either side stand, the correction growing smoothly across the stretch; at a key's
    /// frame inside it there is none (the keys have put the body there).
    fn align_roots(&self, positions: &mut [Vec3], layout: &FeatureLayout) {
        let j = layout.joints();
        for free in &self.free {
            let offset = |f: Option<usize>| -> Option<(usize, Vec3, f32)> {
                let f = f?;
                let (held, have) = (self.held(f)?, &positions[f * j..(f + 1) * j]);
                let shift = held[0] - have[0];
                Some((f, Vec3::new(shift.x, 0.0, shift.z), wrap(layout.heading(held) - layout.heading(have))))
            };
            let keys = self.key_frames.iter().filter(|f| free.contains(f)).map(|&f| (f, Vec3::ZERO, 0.0));
            let targets: Vec<(usize, Vec3, f32)> = offset(free.start.checked_sub(1)).into_iter().chain(keys).chain(offset(Some(free.end))).collect();
            for f in free.clone() {
                let next = targets.partition_point(|t| t.0 < f);
                let (shift, turn) = match (next.checked_sub(1).map(|p| targets[p]), targets.get(next)) {
                    (Some((pf, ps, pt)), Some(&(nf, ns, nt))) => {
                        let s = smoothstep((f - pf) as f32 / (nf - pf) as f32);
                        (ps.lerp(ns, s), pt + s * wrap(nt - pt))
                    }
                    (Some((_, shift, turn)), None) | (None, Some(&(_, shift, turn))) => (shift, turn),
                    (None, None) => break,
                };
                let pose = &mut positions[f * j..(f + 1) * j];
                let (root, rot) = (pose[0], Quat::from_rotation_y(turn));
                pose.iter_mut().for_each(|p| *p = root + rot * (*p - root) + shift);
            }
        }
    }

    /// Fades the pose difference between each free stretch and the held frames at its ends
    /// out inside the stretch. A frame the fade takes below both its own lowest joint and
    /// the held frames' at the ends is lifted back: fading a lifted foot's difference onto a
    /// planted one pushed it 1-2 cm through the floor.
    fn fade_joins(&self, positions: &mut [Vec3], j: usize, fps: f32) {
        let lowest = |positions: &[Vec3], f: usize| positions[f * j..(f + 1) * j].iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        for free in &self.free {
            let ends_floor = [free.start.checked_sub(1), Some(free.end)].iter().flatten().filter_map(|&f| self.held(f)).flat_map(|h| h.iter().map(|p| p.y)).fold(f32::INFINITY, f32::min);
            let floors: Vec<f32> = free.clone().map(|f| lowest(positions, f).min(ends_floor)).collect();
            let fade = ((JOIN_FADE_SECONDS * fps).round() as usize).min((free.end - free.start) / 2).max(1);
            let residual = |f: Option<usize>, positions: &[Vec3]| -> Option<Vec<Vec3>> {
                let f = f?;
                Some(self.held(f)?.iter().zip(&positions[f * j..(f + 1) * j]).map(|(h, p)| *h - *p).collect())
            };
            let ends = [free.start.checked_sub(1), Some(free.end)];
            let residuals: Vec<(usize, Vec<Vec3>)> = ends.iter().filter_map(|&f| Some((f?, residual(f, positions)?))).collect();
            for (at, r) in residuals {
                for f in free.clone() {
                    let w = raised_cosine(f.abs_diff(at) as f32 / (fade + 1) as f32);
                    if w > 0.0 {
                        positions[f * j..(f + 1) * j].iter_mut().zip(&r).for_each(|(p, d)| *p += w * *d);
                    }
                }
            }
            for (f, floor) in free.clone().zip(floors) {
                let dip = floor - lowest(positions, f);
                if dip > 0.0 {
                    positions[f * j..(f + 1) * j].iter_mut().for_each(|p| p.y += dip);
                }
            }
        }
    }

    /// Puts the held positions back over the frames they hold.
    fn put_back(&self, positions: &mut [Vec3], j: usize) {
        for (f, held) in self.positions.iter().enumerate() {
            if let Some(held) = held {
                positions[f * j..(f + 1) * j].copy_from_slice(held);
            }
        }
    }
}

impl TakeConstraint for HeldConstraint {
    /// The poses of the block (and of the one before it, which its seam join may have moved)
    /// over held frames become the held take's; a free run's poses are warped onto the held
    /// pose at each of its ends as they come out.
    fn on_block(&self, _block: &PlannedBlock<'_>, (glogen, _): (&GloGen, &mut BlockWorkspace), sparse: &mut [f32]) {
        let dim = glogen.dim();
        let poses = sparse.len() / dim;
        let made = poses.saturating_sub(self.block_len)..poses;
        for free in &self.free_sparse {
            // Into the run: its first poses go on from the last held pose, the difference
            // from it fading over the poses after.
            if free.start > 0 && made.contains(&free.start) {
                if let Some(key) = self.key_at(free.start - 1, free.start.saturating_sub(2)) {
                    warp_sparse(sparse, dim, &key, self.step_seconds[key.sparse]);
                }
            }
            // Out of it: its last poses arrive at the first held pose after it.
            if made.contains(&free.end) {
                if let Some(key) = self.key_at(free.end, free.start.saturating_sub(1)) {
                    warp_sparse(sparse, dim, &key, self.step_seconds[key.sparse]);
                }
            }
        }
        for i in poses.saturating_sub(2 * self.block_len)..poses {
            if let Some(Some(features)) = self.sparse.get(i) {
                sparse[i * dim..(i + 1) * dim].copy_from_slice(features);
            }
        }
    }

    fn on_dense(&self, positions: &mut [Vec3], layout: &FeatureLayout, _fps: f32) -> Vec<String> {
        self.align_roots(positions, layout);
        self.put_back(positions, layout.joints());
        Vec::new()
    }

    /// The finished take: each free stretch aligned again (the foot lock may have carried the
    /// body on), the differences at its ends faded out, and the held frames exactly as held.
    fn on_finished(&self, motion: Motion, layout: &FeatureLayout) -> Motion {
        let (j, fps, skeleton) = (layout.joints(), motion.fps, motion.skeleton.clone());
        let mut positions = motion.positions().to_vec();
        self.align_roots(&mut positions, layout);
        self.fade_joins(&mut positions, j, fps);
        let Some(mut poses) = motion.local_poses else {
            self.put_back(&mut positions, j);
            return Motion::from_positions(skeleton, fps, positions);
        };
        for free in &self.free {
            poses.splice(free.clone(), solve_local_poses(&skeleton, &positions[free.start * j..free.end * j]));
        }
        for (f, pose) in self.poses.iter().enumerate() {
            match (pose, self.held(f)) {
                (Some(pose), _) => poses[f] = pose.clone(),
                (None, Some(held)) => poses[f] = solve_local_poses(&skeleton, held).remove(0),
                (None, None) => {}
            }
        }
        Motion::from_local_poses(skeleton, fps, poses)
    }
}

/// Each sparse pose's features (normalised) where the frames it falls between are held: the
/// held pose at its (possibly fractional) frame, its step measured from the sparse pose
/// before it, or (when that one is not held) taken from the step after it.
fn sparse_features(spec: &ModelSpec, timeline: &SparseTimeline, held: &[Option<Vec<Vec3>>]) -> Vec<Option<Vec<f32>>> {
    let layout = &spec.layout;
    let pose_at = |t: f64| -> Option<Vec<Vec3>> {
        let (a, b) = (t.floor() as usize, t.ceil() as usize);
        let (pa, pb) = (held.get(a)?.as_ref()?, held.get(b)?.as_ref()?);
        let w = (t - a as f64) as f32;
        Some(pa.iter().zip(pb).map(|(p, q)| p.lerp(*q, w)).collect())
    };
    let poses: Vec<Option<Vec<Vec3>>> = timeline.frames.iter().map(|&t| pose_at(t)).collect();
    let mut out = Vec::with_capacity(poses.len());
    for (i, pose) in poses.iter().enumerate() {
        let Some(pose) = pose else {
            out.push(None);
            continue;
        };
        let before = i.checked_sub(1).and_then(|p| poses[p].as_deref());
        let mut features = layout.encode(&[pose.as_slice()], before);
        if before.is_none() {
            if let Some(next) = poses.get(i + 1).and_then(|p| p.as_deref()) {
                let step = layout.encode(&[next], Some(pose));
                features[1..ROOT_FEATURES].copy_from_slice(&step[1..ROOT_FEATURES]);
            }
        }
        spec.sparse_norm.normalize(&mut features);
        out.push(Some(features));
    }
    out
}
