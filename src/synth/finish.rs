//! Finishing a take: its sparse poses made into frames (LocGen over the interpolation, pace,
//! the bones projected, the feet locked), in chunks of [`CHUNK_SECONDS`].
//!
//! Each chunk is finished from the sparse poses of its own stretch and [`MARGIN_SECONDS`]
//! either side (the spline, LocGen's windows and the foot lock all look a little ahead and
//! behind), and only its own stretch is kept. A chunk is placed where the one before it
//! left the body and joined onto that one's look-ahead over [`JOIN_SECONDS`], so the take
//! has no seam at chunk boundaries. So a frame depends on the sparse poses near it and on the
//! chunks before it, never on what comes more than a margin after it: a take's frames are
//! final as soon as the rollout is a margin past them (they stream as they are made), and an
//! edit late in a take leaves every chunk before it as it was (they are reused).
//!
//! A take with keys, a root path or held frames is finished whole: those reach across the
//! take (a key's warp, the path's layout by arc length, a held stretch's alignment).

use std::ops::Range;

use anyhow::Result;
use glam::{Quat, Vec3};

use super::foot_lock::{foot_lock, FootLocked, Travel};
use super::held::HeldConstraint;
use super::plan::{paced_frames, TakeConstraint};
use super::smoothstep;
use crate::data::features::{wrap, FeatureLayout, Placement};
use crate::model::glocal::GlocalModel;
use crate::model::texture::{Texture, TexturedPose};
use crate::motion::contacts::{support_heights, FootContacts};
use crate::motion::{solve_local_poses, spread_snaps, JointRoles, LocalPose, Motion, Skeleton};

/// The length of a chunk of the take (at pace 1).
pub const CHUNK_SECONDS: f32 = 20.0;
/// Sparse poses a chunk reads before and after its own (at pace 1).
const MARGIN_SECONDS: f32 = 2.0;
/// The join of a chunk onto the look-ahead of the chunk before it.
const JOIN_SECONDS: f32 = 0.5;

/// The sparse poses one chunk finishes (`core`) and those it reads (`window`).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Chunk {
    pub core: Range<usize>,
    pub window: Range<usize>,
}

/// The chunks of a take of `total` sparse poses, `step_seconds` apart at pace 1: one when
/// the take is shorter than one and a half chunks, the last absorbing what is left.
pub(super) fn chunks(total: usize, step_seconds: f32) -> Vec<Chunk> {
    let length = (CHUNK_SECONDS / step_seconds).round().max(2.0) as usize;
    let margin = (MARGIN_SECONDS / step_seconds).round().max(1.0) as usize;
    let mut starts = vec![0];
    while starts.last().unwrap() + length + length / 2 < total {
        starts.push(starts.last().unwrap() + length);
    }
    let ends = starts.iter().skip(1).copied().chain([total]);
    starts.iter().zip(ends).map(|(&s, e)| Chunk { core: s..e, window: s.saturating_sub(margin)..(e + margin).min(total) }).collect()
}

/// How the sparse poses of a stretch become frames of the take.
pub(super) struct Finishing<'a> {
    pub model: &'a GlocalModel,
    pub locgen: bool,
    pub project_bones: bool,
    pub foot_lock: bool,
    pub travel: Travel,
    /// The paced frame of each sparse pose (fractional).
    pub times: &'a [f64],
    /// Applied to the stretch that starts the take (all of them finish a take made whole).
    pub constraints: &'a [Box<dyn TakeConstraint + 'a>],
    pub texture: Option<Textured<'a>>,
    /// Per joint, how far its bone may turn in one frame (radians), when the take spreads
    /// snaps ([`crate::model::spec::ModelSpec::turn_limits_per_frame`]).
    pub turn_limits: Option<Vec<Option<f32>>>,
}

/// The motion texture a take's frames get between its sparse poses.
pub(super) struct Textured<'a> {
    pub bank: &'a Texture,
    /// The class and share of each of the take's sparse poses (those of the block it
    /// belongs to).
    pub poses: Vec<TexturedPose>,
    /// The take's variation seed: where it reads each class's bank.
    pub seed: u64,
}

/// A finished stretch: frames `first..first + motion.frames()` of the take.
pub(super) struct Stretch {
    pub first: usize,
    pub motion: Motion,
    pub contacts: FootContacts,
    pub warnings: Vec<String>,
}

impl Finishing<'_> {
    /// The take's frames: `floor` of the last pose's time, plus one.
    pub fn take_frames(&self) -> usize {
        paced_frames(self.times)
    }

    /// The first frame at or after sparse pose `i` (the take's end past the last).
    pub fn frame_of(&self, i: usize) -> usize {
        match self.times.get(i) {
            Some(t) => t.ceil() as usize,
            None => self.take_frames(),
        }
    }

    /// The frames sparse poses `window` cover: from the first pose's to the last one's.
    fn frames_of(&self, window: &Range<usize>) -> Range<usize> {
        let end = if window.end == self.times.len() { self.take_frames() } else { self.times[window.end - 1].floor() as usize + 1 };
        self.frame_of(window.start)..end
    }

    /// Finishes the stretch of sparse poses `window`, whose decoded positions are `sparse`.
    pub fn stretch(&self, sparse: &[Vec3], window: Range<usize>) -> Result<Stretch> {
        let spec = &self.model.spec;
        let layout = &spec.layout;
        let mut dense = self.model.densify(sparse, self.locgen);
        let starts_take = window.start == 0;
        let constraints = if starts_take { self.constraints } else { &[] };
        // Frames a constraint replaces with motion of its own (the in-betweener's gaps before
        // keys) lose the texture laid here, so it is laid on them again after.
        let own_frames: Vec<Range<usize>> = constraints.iter().flat_map(|c| c.own_frames().iter().cloned()).collect();
        let untextured = (self.texture.is_some() && !own_frames.is_empty()).then(|| dense.clone());
        self.lay_texture(&mut dense, &window);
        let frames = self.frames_of(&window);
        let j = layout.joints();
        let pace = |dense: &[Vec3], to: Range<usize>| apply_pace(dense, j, spec.stride, &self.times[window.clone()], to);
        let mut positions = self.paced(&dense, &window);
        let warnings = constraints.iter().flat_map(|c| c.on_dense(&mut positions, layout, spec.fps)).collect();
        if let Some(untextured) = untextured {
            let texture: Vec<Vec3> = dense.iter().zip(&untextured).map(|(with, without)| *with - *without).collect();
            // Each run from the frame before it to its end (a key's frame), when both are in
            // the stretch.
            for run in own_frames.iter().filter(|run| run.start > frames.start && run.end < frames.end) {
                let span = run.start - 1..run.end + 1;
                let local = (span.start - frames.start) * j..(span.end - frames.start) * j;
                lay_again(&mut positions[local], &pace(&texture, span), j);
            }
        }
        let FootLocked { motion, mut contacts } = self.locked(positions)?;
        let motion = constraints.iter().fold(motion, |m, c| c.on_finished(m, layout));
        constraints.iter().for_each(|c| c.on_contacts(&motion, &mut contacts));
        Ok(Stretch { first: frames.start, motion, contacts, warnings })
    }

    /// The texture laid over the dense frames of sparse poses `window`, when the take has one.
    fn lay_texture(&self, dense: &mut [Vec3], window: &Range<usize>) {
        if let Some(t) = &self.texture {
            t.bank.lay_over(dense, &self.model.spec, window.start, &t.poses, t.seed);
        }
    }

    /// The dense frames of sparse poses `window` at the take's pace, their snaps spread.
    fn paced(&self, dense: &[Vec3], window: &Range<usize>) -> Vec<Vec3> {
        let spec = &self.model.spec;
        let mut paced = apply_pace(dense, spec.layout.joints(), spec.stride, &self.times[window.clone()], self.frames_of(window));
        self.spread_snaps(&mut paced);
        paced
    }

    /// Paced frames `positions` with their bones' snaps spread, when the take spreads them.
    /// Before the constraints (a key's or a start's frames stay as given) and the foot lock
    /// (a planted foot stays where the lock puts it). Returns how many frames changed.
    fn spread_snaps(&self, positions: &mut [Vec3]) -> usize {
        self.turn_limits.as_ref().map_or(0, |limits| spread_snaps(positions, &self.model.spec.layout.skeleton, limits))
    }

    /// The projected take's frames with its snaps spread once more, when the take spreads
    /// them and any is: the projection bridges a bone the network collapses while it turns,
    /// and the bridge may turn it past its limit again (Bandai's dash from seed window 2: a
    /// forearm 38 degrees a frame spread, 60 bridged).
    fn spread_again(&self, projected: &Motion) -> Option<Vec<Vec3>> {
        self.turn_limits.as_ref()?;
        let mut positions = projected.positions().to_vec();
        (self.spread_snaps(&mut positions) > 0).then_some(positions)
    }

    /// Whether the take's feet are locked: asked for, and the model's skeleton has feet to lock.
    fn locks_feet(&self) -> bool {
        self.foot_lock && self.model.spec.foot_lock
    }

    /// Frames of the paced take (model units) with the bones projected, when asked, and the
    /// feet locked.
    fn locked(&self, positions: Vec<Vec3>) -> Result<FootLocked> {
        let spec = &self.model.spec;
        let skeleton = spec.layout.skeleton.clone();
        let motion = if self.project_bones {
            let projected = Motion::from_local_poses(skeleton.clone(), spec.fps, solve_local_poses(&skeleton, &positions));
            // Solved again where spread, exactly now that every bone has its rest length.
            match self.spread_again(&projected) {
                Some(again) => Motion::from_local_poses(skeleton.clone(), spec.fps, solve_local_poses(&skeleton, &again)),
                None => projected,
            }
        } else {
            Motion::from_positions(skeleton, spec.fps, positions)
        };
        foot_lock(motion, self.locks_feet(), &self.travel)
    }

    /// A take that holds all but its `held` constraint's free frames: only the stretches of
    /// sparse poses around each run of free frames (a margin either side) are finished, the
    /// held frames put in around them and the joins made as a take finished whole makes them
    /// (the constraints of the take's start apply to a stretch that starts it).
    pub fn around_free_frames(&self, sparse: &[Vec3], held: &HeldConstraint) -> Result<Stretch> {
        let spec = &self.model.spec;
        let (layout, j) = (&spec.layout, spec.layout.joints());
        let frames = self.take_frames();
        let mut positions = vec![Vec3::ZERO; frames * j];
        for f in 0..frames {
            if let Some(pose) = held.held(f) {
                positions[f * j..(f + 1) * j].copy_from_slice(pose);
            }
        }
        let windows = self.free_windows(held.free_frames());
        for window in &windows {
            let mut dense = self.model.densify(&sparse[window.start * j..window.end * j], self.locgen);
            self.lay_texture(&mut dense, window);
            let frames = self.frames_of(window);
            positions[frames.start * j..frames.end * j].copy_from_slice(&self.paced(&dense, window));
        }
        held.on_dense(&mut positions, layout, spec.fps);
        let mut poses: Vec<LocalPose> = Vec::new();
        let mut contacts = FootContacts { left: vec![false; frames], right: vec![false; frames] };
        let mut at = 0;
        for window in &windows {
            let frames = self.frames_of(window);
            let FootLocked { motion, contacts: locked } = self.locked(positions[frames.start * j..frames.end * j].to_vec())?;
            positions[frames.start * j..frames.end * j].copy_from_slice(motion.positions());
            contacts.left[frames.clone()].copy_from_slice(&locked.left);
            contacts.right[frames.clone()].copy_from_slice(&locked.right);
            if let Some(window_poses) = motion.local_poses {
                poses.extend((at..frames.start).map(|f| stand_in(&positions[f * j..(f + 1) * j])));
                poses.extend(window_poses);
                at = frames.end;
            }
        }
        let poses = self.project_bones.then(|| {
            poses.extend((at..frames).map(|f| stand_in(&positions[f * j..(f + 1) * j])));
            poses
        });
        let mut motion = Motion::from_positions(layout.skeleton.clone(), spec.fps, positions);
        motion.local_poses = poses;
        let motion = self.constraints.iter().fold(motion, |m, c| c.on_finished(m, layout));
        self.constraints.iter().for_each(|c| c.on_contacts(&motion, &mut contacts));
        Ok(Stretch { first: 0, motion, contacts, warnings: Vec::new() })
    }

    /// The stretches of sparse poses to finish for runs `free` of frames: from a margin
    /// before the held frame before each run to a margin after the held frame after it,
    /// merged where they overlap.
    fn free_windows(&self, free: &[Range<usize>]) -> Vec<Range<usize>> {
        let margin = (MARGIN_SECONDS * self.model.spec.fps / self.model.spec.stride as f32).round().max(1.0) as usize;
        let total = self.times.len();
        let mut windows: Vec<Range<usize>> = Vec::new();
        for run in free {
            let first = self.times.partition_point(|&t| t <= run.start.saturating_sub(1) as f64).saturating_sub(1);
            let last = self.times.partition_point(|&t| t < run.end as f64);
            let window = first.saturating_sub(margin)..(last + margin + 1).min(total);
            match windows.last_mut() {
                Some(before) if before.end >= window.start => before.end = before.end.max(window.end),
                _ => windows.push(window),
            }
        }
        windows
    }
}

/// Bones' turn limits `limits` (per joint of `skeleton`) without the legs': a foot's flick
/// spread over the frames around it moves the foot while it stands (`all`'s Bandai classes'
/// support-point speed 1.42 -> 1.49x real with the legs spread too), and after the foot lock,
/// in the frames a foot is up, Bandai's running legs, faster than its clips for frames on
/// end, jerked 1.35x real (docs/RESULTS.md, "Snaps spread").
pub(super) fn above_the_legs(mut limits: Vec<Option<f32>>, skeleton: &Skeleton) -> Vec<Option<f32>> {
    if let Ok(roles) = JointRoles::new(skeleton) {
        for leg in [roles.left, roles.right] {
            skeleton.subtree(leg.hip).into_iter().for_each(|j| limits[j] = None);
        }
    }
    limits
}

/// The paced `texture` frames held before a constraint replaced them with motion of its own,
/// added again to them (`positions`, from the frame before the replaced run to its end),
/// less its straight line between those two frames, so the frames either side stay as they
/// are.
fn lay_again(positions: &mut [Vec3], texture: &[Vec3], j: usize) {
    let last = positions.len() / j - 1;
    for f in 1..last {
        let along = f as f32 / last as f32;
        for joint in 0..j {
            let trend = texture[joint].lerp(texture[last * j + joint], along);
            positions[f * j + joint] += texture[f * j + joint] - trend;
        }
    }
}

/// A held frame's place in the poses until the held constraint puts its pose there (it
/// replaces every held frame's pose).
fn stand_in(frame: &[Vec3]) -> LocalPose {
    LocalPose { rotations: vec![Quat::IDENTITY; frame.len()], translations: frame.to_vec() }
}

/// Stretches sparse intervals (native `stride` frames each) to the frames `frames` of the
/// paced take, where `times` puts the stretch's sparse poses, by linear interpolation in time.
pub(super) fn apply_pace(dense: &[Vec3], joints: usize, stride: usize, times: &[f64], frames: Range<usize>) -> Vec<Vec3> {
    let native_frames = dense.len() / joints;
    let intervals = times.len().saturating_sub(1);
    let mut out = Vec::with_capacity(frames.len() * joints);
    let mut interval = 0;
    for f in frames {
        let tf = f as f64;
        while interval + 1 < intervals && times[interval + 1] <= tf {
            interval += 1;
        }
        let local = if intervals == 0 { 0.0 } else { (tf - times[interval]) / (times[interval + 1] - times[interval]) };
        let src = ((interval as f64 + local.clamp(0.0, 1.0)) * stride as f64).min((native_frames - 1) as f64);
        let a = src.floor() as usize;
        let b = (a + 1).min(native_frames - 1);
        let w = (src - a as f64) as f32;
        let (fa, fb) = (&dense[a * joints..(a + 1) * joints], &dense[b * joints..(b + 1) * joints]);
        out.extend(fa.iter().zip(fb).map(|(p, q)| p.lerp(*q, w)));
    }
    out
}

/// Chunks finished as the rollout settles their sparse poses.
pub(super) struct ChunkFinish<'a> {
    finishing: &'a Finishing<'a>,
    pub done: FinishedChunks,
    /// The settled sparse poses decoded (model units), and where each stands.
    decoded: Vec<Vec3>,
    placements: Vec<Placement>,
    start: Placement,
}

/// What a take finished in chunks keeps for the next one.
pub(super) struct ChunkRecord {
    done: FinishedChunks,
    decoded: Vec<Vec3>,
    placements: Vec<Placement>,
}

impl<'a> ChunkFinish<'a> {
    /// Chunks laid out as `layout`, from a take starting at `start`, at the paced frames
    /// `times`, keeping those of an earlier take (`kept`: its record, how many of its sparse
    /// poses the new take shares, and its times) that read only poses it shares, at the same
    /// times.
    pub fn resumed(finishing: &'a Finishing<'a>, layout: Vec<Chunk>, kept: Option<(&ChunkRecord, usize, &[f64])>, start: Placement, times: &[f64]) -> Self {
        let joints = finishing.model.spec.layout.joints();
        let Some((old, shared, old_times)) = kept else {
            return Self { finishing, done: FinishedChunks::new(layout, joints, finishing.project_bones), decoded: Vec::new(), placements: Vec::new(), start };
        };
        let same = |k: usize| {
            let window = layout[k].window.clone();
            old.done.layout[k] == layout[k] && window.end <= shared && old_times.get(window.clone()) == times.get(window)
        };
        let keep = (0..old.done.done().min(layout.len())).take_while(|&k| same(k)).count();
        let poses = old.placements.len().min(shared);
        Self { finishing, done: old.done.kept(layout, keep), decoded: old.decoded[..poses * joints].to_vec(), placements: old.placements[..poses].to_vec(), start }
    }

    /// Finishes every chunk whose poses are among the first `settled` of `sparse`
    /// (normalised); returns whether any was.
    pub fn advance(&mut self, sparse: &[f32], settled: usize) -> Result<bool> {
        let spec = &self.finishing.model.spec;
        let (dim, joints) = (spec.layout.dim(), spec.layout.joints());
        let settled = settled.min(self.finishing.times.len());
        for i in self.placements.len()..settled {
            let mut pose = sparse[i * dim..(i + 1) * dim].to_vec();
            spec.sparse_norm.denormalize(&mut pose);
            let (positions, place) = spec.layout.decode(&pose, self.placements.last().copied().unwrap_or(self.start));
            self.decoded.extend(positions);
            self.placements.push(place);
        }
        let before = self.done.done();
        while let Some(chunk) = self.done.next().filter(|c| c.window.end <= settled).cloned() {
            let stretch = self.finishing.stretch(&self.decoded[chunk.window.start * joints..chunk.window.end * joints], chunk.window.clone())?;
            self.done.push(stretch, self.finishing.frame_of(chunk.core.start)..self.finishing.frame_of(chunk.core.end), &spec.layout, self.finishing.locks_feet());
        }
        Ok(self.done.done() > before)
    }

    pub fn into_record(self) -> ChunkRecord {
        ChunkRecord { done: self.done, decoded: self.decoded, placements: self.placements }
    }
}

/// The frames of a chunk past its own, as the take placed them: the next chunk joins onto
/// them.
#[derive(Clone)]
struct LookAhead {
    first: usize,
    positions: Vec<Vec3>,
}

/// The take's frames, chunk after chunk (see the module docs).
#[derive(Clone)]
pub(super) struct FinishedChunks {
    pub layout: Vec<Chunk>,
    joints: usize,
    positions: Vec<Vec3>,
    /// The local poses of the frames, when bones are projected.
    poses: Option<Vec<LocalPose>>,
    contacts: FootContacts,
    /// Per chunk done: the take's frames after it and its look-ahead.
    ends: Vec<usize>,
    look_aheads: Vec<LookAhead>,
}

impl FinishedChunks {
    pub fn new(layout: Vec<Chunk>, joints: usize, project_bones: bool) -> Self {
        Self { layout, joints, positions: Vec::new(), poses: project_bones.then(Vec::new), contacts: FootContacts::default(), ends: Vec::new(), look_aheads: Vec::new() }
    }

    /// Chunks finished so far.
    pub fn done(&self) -> usize {
        self.ends.len()
    }

    /// The next chunk to finish, if any.
    pub fn next(&self) -> Option<&Chunk> {
        self.layout.get(self.done())
    }

    /// The first `keep` chunks of an earlier take whose chunks are laid out as `layout`'s
    /// first `keep` (the caller has checked their sparse poses are the same).
    pub fn kept(&self, layout: Vec<Chunk>, keep: usize) -> Self {
        let mut kept = Self::new(layout, self.joints, self.poses.is_some());
        if keep == 0 {
            return kept;
        }
        let frames = self.ends[keep - 1];
        kept.positions = self.positions[..frames * self.joints].to_vec();
        kept.poses = self.poses.as_ref().map(|p| p[..frames].to_vec());
        kept.contacts = self.contacts.slice(0..frames);
        kept.ends = self.ends[..keep].to_vec();
        kept.look_aheads = self.look_aheads[..keep].to_vec();
        kept
    }

    /// Adds the next chunk, finished as `stretch`, whose own frames are `core`: turned and
    /// placed where the chunk before left the body (LocGen's turns drift a take's heading a
    /// little from its sparse poses', and the foot lock its travel), at the same floor when
    /// the feet are locked (`on_floor`), and joined onto that chunk's look-ahead.
    pub fn push(&mut self, stretch: Stretch, core: Range<usize>, layout: &FeatureLayout, on_floor: bool) {
        let j = self.joints;
        let local = |f: usize| f - stretch.first;
        let previous = self.look_aheads.last().cloned();
        let own_start = stretch.motion.frame(local(core.start));
        let placing = previous.as_ref().and_then(|p| {
            let before = p.positions.get((core.start - p.first) * j..(core.start - p.first + 1) * j)?;
            let floors = on_floor.then(|| shared_floors(&stretch.motion, local(core.start), p)).flatten();
            let (from_y, onto_y) = floors.unwrap_or((own_start[0].y, before[0].y));
            Some(Placing::onto(layout.placement(own_start), layout.placement(before), from_y, onto_y))
        });
        let placed = placing.unwrap_or_else(Placing::none).apply(&stretch.motion, local(core.start));
        let mut positions = placed.positions().to_vec();
        let mut poses = placed.local_poses;
        if let Some(previous) = previous {
            let blended = join(&mut positions, j, &previous, core.start, JOIN_SECONDS * stretch.motion.fps);
            if let (Some(poses), false) = (poses.as_mut(), blended.is_empty()) {
                let solved = solve_local_poses(&stretch.motion.skeleton, &positions[..blended.len() * j]);
                let fk = Motion::from_local_poses(stretch.motion.skeleton.clone(), stretch.motion.fps, solved);
                positions[..blended.len() * j].copy_from_slice(fk.positions());
                poses.splice(..blended.len(), fk.local_poses.unwrap_or_default());
            }
        }
        let own = core.len();
        self.positions.extend_from_slice(&positions[..own * j]);
        if let (Some(all), Some(poses)) = (self.poses.as_mut(), poses.as_mut()) {
            all.extend(poses.drain(..own));
        }
        let contacts = stretch.contacts.slice(local(core.start)..local(core.end));
        self.contacts.left.extend(contacts.left);
        self.contacts.right.extend(contacts.right);
        self.ends.push(core.end);
        self.look_aheads.push(LookAhead { first: core.end, positions: positions[own * j..].to_vec() });
    }

    /// The take so far.
    pub fn motion(&self, model: &GlocalModel) -> Motion {
        let spec = &model.spec;
        match &self.poses {
            Some(poses) => Motion::from_local_poses(spec.layout.skeleton.clone(), spec.fps, poses.clone()),
            None => Motion::from_positions(spec.layout.skeleton.clone(), spec.fps, self.positions.clone()),
        }
    }

    pub fn contacts(&self) -> &FootContacts {
        &self.contacts
    }
}

/// A turn about the vertical through `pivot`, then a move by `offset`: what brings a
/// chunk's first frame onto where the chunk before left the body.
struct Placing {
    turn: Quat,
    pivot: Vec3,
    offset: Vec3,
}

impl Placing {
    fn none() -> Self {
        Self { turn: Quat::IDENTITY, pivot: Vec3::ZERO, offset: Vec3::ZERO }
    }

    /// From a frame placed at `from` (its root at height `from_y`) onto one at `onto`.
    fn onto(from: Placement, onto: Placement, from_y: f32, onto_y: f32) -> Self {
        let pivot = Vec3::new(from.x, from_y, from.z);
        Self { turn: Quat::from_rotation_y(wrap(onto.heading - from.heading)), pivot, offset: Vec3::new(onto.x, onto_y, onto.z) - pivot }
    }

    fn point(&self, p: Vec3) -> Vec3 {
        self.pivot + self.offset + self.turn * (p - self.pivot)
    }

    /// Frames `from..` of `motion`, placed (its roots' transforms, when it has local poses,
    /// and its positions by forward kinematics of them).
    fn apply(&self, motion: &Motion, from: usize) -> Motion {
        let j = motion.joints();
        match &motion.local_poses {
            Some(poses) => {
                let mut poses = poses[from..].to_vec();
                let roots: Vec<usize> = (0..j).filter(|&k| motion.skeleton.parents()[k].is_none()).collect();
                for pose in &mut poses {
                    for &r in &roots {
                        pose.translations[r] = self.point(pose.translations[r]);
                        pose.rotations[r] = self.turn * pose.rotations[r];
                    }
                }
                Motion::from_local_poses(motion.skeleton.clone(), motion.fps, poses)
            }
            None => Motion::from_positions(motion.skeleton.clone(), motion.fps, motion.positions()[from * j..].iter().map(|&p| self.point(p)).collect()),
        }
    }
}

/// The floor under `motion`'s frames from `first` and the floor under the chunk before's
/// look-ahead, which starts at the same frame: the lowest support (a foot, or the seat of a
/// floor sit) of each over the frames both hold. A chunk is placed to stand on the floor of
/// the chunk before, not by its root's height: each chunk's foot lock levels it on its own
/// floor, and placed by its root's height a chunk whose body stood a little higher over its
/// floor at the boundary took its floor with it (h36m's 60 s walk at seed 1 stood its last
/// 40 s 1.3-3.3 cm over the first chunk's floor; `tests/synth.rs`,
/// `a_long_takes_chunks_stand_on_one_floor`).
fn shared_floors(motion: &Motion, first: usize, previous: &LookAhead) -> Option<(f32, f32)> {
    let roles = JointRoles::new(&motion.skeleton).ok()?;
    let j = motion.joints();
    let shared = (previous.positions.len() / j).min(motion.frames() - first);
    if shared == 0 {
        return None;
    }
    let before = Motion::from_positions(motion.skeleton.clone(), motion.fps, previous.positions[..shared * j].to_vec());
    let lowest = |m: &Motion| support_heights(m, &roles).into_iter().fold(f32::INFINITY, f32::min);
    Some((lowest(&motion.slice(first, first + shared)), lowest(&before)))
}

/// Fades `positions` (frames from `first`) in from the chunk before's look-ahead over
/// `join_frames`: returns the frames changed (empty when the look-ahead does not reach).
fn join(positions: &mut [Vec3], joints: usize, previous: &LookAhead, first: usize, join_frames: f32) -> Range<usize> {
    let available = (previous.positions.len() / joints).saturating_sub(first - previous.first);
    let n = (join_frames.round() as usize).min(available).min(positions.len() / joints);
    for f in 0..n {
        let w = smoothstep((f + 1) as f32 / (n + 1) as f32);
        let before = &previous.positions[(first - previous.first + f) * joints..][..joints];
        for (p, q) in positions[f * joints..(f + 1) * joints].iter_mut().zip(before) {
            *p = q.lerp(*p, w);
        }
    }
    0..n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pace_stretches_time() {
        let dense: Vec<Vec3> = (0..11).map(|f| Vec3::splat(f as f32)).collect();
        let out = apply_pace(&dense, 1, 5, &[0.0, 10.0, 20.0], 0..21);
        assert_eq!(out.len(), 21);
        assert_eq!(out[10], Vec3::splat(5.0));
        assert_eq!(out[5], Vec3::splat(2.5));
        // Fractional: the first interval takes 7.5 frames, the second 2.5.
        let frac = apply_pace(&dense, 1, 5, &[0.0, 7.5, 10.0], 0..11);
        assert_eq!(frac.len(), 11);
        assert!((frac[5].x - 5.0 / 1.5).abs() < 1e-4);
        assert_eq!(frac[10], Vec3::splat(10.0));
        // A window of it gives the same frames.
        assert_eq!(apply_pace(&dense[5..], 1, 5, &[7.5, 10.0], 8..11), frac[8..11].to_vec());
    }

    #[test]
    fn chunks_cover_the_take_once() {
        assert_eq!(chunks(120, 0.2), vec![Chunk { core: 0..120, window: 0..120 }]);
        let long = chunks(1500, 0.2);
        assert_eq!(long.len(), 15);
        assert_eq!(long[1], Chunk { core: 100..200, window: 90..210 });
        assert_eq!(long[14].core, 1400..1500);
        assert!(long.windows(2).all(|w| w[0].core.end == w[1].core.start));
        // The last absorbs a remainder under half a chunk.
        assert_eq!(chunks(1549, 0.2).last().unwrap().core, 1400..1549);
    }
}
