//! Long motion from a timeline: GloGen rolls out sparse poses block by block under each
//! segment's class, as the take's plan asks ([`super::plan`]), LocGen refines the
//! interpolated frames between them, pace stretches time, the constraints pull the take onto
//! its keys and path, and a final projection restores the skeleton's bone lengths.

use anyhow::{bail, Context, Result};
use glam::Vec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::foot_lock::{foot_lock, FootLocked, Travel};
use super::given::GivenStart;
use super::held::HeldConstraint;
use super::init::{given_frames, initial_features};
use super::keys::{place_keys, KeyConstraint, PlacedKey};
use super::options::{variation_for, GenerateOptions, KeyMethod, Transition};
use super::path_follow::{GroundPath, PathConstraint};
use super::plan::{BlockPlan, PlannedBlock, SegmentSpan, SparseTimeline, TakeConstraint};
use super::steer::Steering;
use crate::model::block::BlockWorkspace;
use crate::model::glocal::GlocalModel;
use crate::data::features::Placement;
use crate::model::glogen::GloGen;
use crate::model::rollout::{rollout, RolloutSteps};
use crate::model::spec::MAX_CLASS_STRENGTH;
use crate::model::target::{target_condition, Target};
use crate::motion::contacts::FootContacts;
use crate::motion::cycle::Cycle;
use crate::motion::{solve_local_poses, Motion};

pub struct Generated {
    pub motion: Motion,
    pub segments: Vec<SegmentSpan>,
    /// GloGen's encoder embedding of each generated block's input (the t-SNE path).
    pub block_embeddings: Vec<Vec<f32>>,
    /// Class (segment) of each block.
    pub block_classes: Vec<usize>,
    /// Per foot and frame, whether the foot stands on the floor.
    pub contacts: FootContacts,
    /// What the take could not do as asked (a path faster than its class walks), for the
    /// user to see.
    pub warnings: Vec<String>,
    /// A looping take's cycle: where it was cut and how far one play of it travels.
    pub cycle: Option<Cycle>,
}

/// Generates a take as its timeline lays it out, from its start to its end (a loop is cut
/// from one, [`super::looping`]). `progress` gets the fraction done and returns false to
/// cancel.
pub fn continuous_take(model: &GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    let spec = &model.spec;
    let timeline = SparseTimeline::new(spec, opts)?;
    let class_strength = opts.class_strength_for(spec);
    if !(0.0..=MAX_CLASS_STRENGTH).contains(&class_strength) {
        bail!("class strength must be between 0 and {MAX_CLASS_STRENGTH}, got {class_strength}");
    }
    let (dim, total) = (spec.layout.dim(), timeline.total());
    // The start first: a file that cannot start the take is named before anything else.
    let (mut sparse, start) = initial_features(model, &opts.init)?;
    let keys = place_keys(&timeline, model, &opts.keys, &opts.init)?;
    // GloGen's own poses are warped onto keys unless the ablation warps the dense frames alone.
    let key_poses: Vec<usize> = if opts.key_method == KeyMethod::DenseWarp { Vec::new() } else { keys.iter().map(|k| k.sparse).collect() };
    let plans = timeline.plan(model, opts.transition == Transition::Anchor, &key_poses);
    let mut targets = if model.glogen().reads_target() { keys.clone() } else { Vec::new() };
    targets.sort_by_key(|k| k.sparse);
    let constraints = take_constraints(model, opts, &timeline, keys)?;
    let t = spec.block_len;
    let block_segments = (0..plans.len()).map(|b| timeline.segment_at(t + b * t + t / 2)).collect();

    spec.sparse_norm.normalize(&mut sparse);
    let mut steps = TakeSteps {
        model,
        opts,
        plans: &plans,
        targets,
        start,
        cond: Vec::new(),
        steering: Steering::new(model, opts),
        noise: StdRng::seed_from_u64(opts.seed),
        block_segments,
        segment_noise: None,
        constraints: &constraints,
        strength: class_strength,
        progress,
    };
    let embeddings = rollout(model.glogen(), &mut BlockWorkspace::default(), &mut sparse, plans.len(), opts.join_seams, &mut steps)?;
    let progress = steps.progress;
    sparse.truncate(total * dim);
    spec.sparse_norm.denormalize(&mut sparse);
    let (sparse_positions, _) = spec.layout.decode(&sparse, start);
    let dense = model.densify(&sparse_positions, opts.locgen);
    if !progress(0.9) {
        return Err(super::Error::Cancelled.into());
    }
    let (mut positions, interval_starts) = apply_pace(&dense, spec.layout.joints(), spec.stride, &timeline.frames);
    let warnings = constraints.iter().flat_map(|c| c.on_dense(&mut positions, &spec.layout, spec.fps)).collect();
    let skeleton = spec.layout.skeleton.clone();
    let motion = if opts.project_bones {
        let poses = solve_local_poses(&skeleton, &positions);
        Motion::from_local_poses(skeleton, spec.fps, poses)
    } else {
        Motion::from_positions(skeleton, spec.fps, positions)
    };
    let segments = timeline.segment_spans(&spec.classes, &interval_starts, motion.frames());
    // A root path has laid out where the body goes; without one, the feet of a model whose
    // network slides them say how far.
    let travel = if spec.carry_by_feet && opts.path.is_none() { Travel::FromFeet } else { Travel::Kept };
    let FootLocked { motion, contacts } = foot_lock(motion, opts.foot_lock && spec.foot_lock, travel)?;
    let motion = constraints.iter().fold(motion, |m, c| c.on_finished(m, &spec.layout));
    progress(1.0);
    let block_classes = plans.iter().map(|p| p.target).collect();
    Ok(Generated { motion, segments, block_embeddings: embeddings, block_classes, contacts, warnings, cycle: None })
}

/// The take's constraints in the order they apply: the root path lays the take out, the keys
/// pin it, a file start's given frames are put back as given, and held frames as held.
fn take_constraints(model: &GlocalModel, opts: &GenerateOptions, timeline: &SparseTimeline, keys: Vec<PlacedKey>) -> Result<Vec<Box<dyn TakeConstraint>>> {
    let spec = &model.spec;
    let mut constraints: Vec<Box<dyn TakeConstraint>> = Vec::new();
    if let Some(path) = &opts.path {
        path.check().context("root path")?;
        let units_per_metre = 1.0 / spec.layout.skeleton.meters_per_unit();
        constraints.push(Box::new(PathConstraint { path: GroundPath::new(path, units_per_metre), units_per_metre }));
    }
    let first_key = keys.iter().map(|k| k.frame).min();
    let key_frames = keys.iter().map(|k| k.frame).collect();
    if !keys.is_empty() {
        let step_seconds = keys.iter().map(|k| timeline.step_seconds[timeline.segment_at(k.sparse)]).collect();
        constraints.push(Box::new(KeyConstraint { keys, step_seconds, method: opts.key_method }));
    }
    // The given frames of a file start keep their own timing only at pace 1.
    let first_pace = opts.timeline.segments.first().and_then(|s| s.pace).unwrap_or(opts.pace);
    if let Some(frames) = given_frames(model, &opts.init)?.filter(|_| first_pace == 1.0) {
        constraints.push(Box::new(GivenStart { frames, until: first_key.unwrap_or(usize::MAX) }));
    }
    // Last: the held frames come out exactly as held, whatever the others did.
    if !opts.held.is_empty() {
        constraints.push(Box::new(HeldConstraint::new(spec, &opts.held, timeline, key_frames)?));
    }
    Ok(constraints)
}

/// How the take's rollout goes block by block: the plan's class, the steering's easing and
/// guidance, the variation's noise, and the constraints after each block.
struct TakeSteps<'a> {
    model: &'a GlocalModel,
    opts: &'a GenerateOptions,
    plans: &'a [BlockPlan],
    /// The keys a target-conditioned GloGen aims at, in time order.
    targets: Vec<PlacedKey>,
    /// Where the take starts (the sparse poses are steps from it).
    start: Placement,
    /// The conditioning of the block under way: its plan's class, then its target.
    cond: Vec<f32>,
    steering: Steering,
    noise: StdRng,
    /// The segment each block belongs to (its plan's target).
    block_segments: Vec<usize>,
    /// The segment with its own seed whose blocks are under way, and its noise.
    segment_noise: Option<(usize, StdRng)>,
    constraints: &'a [Box<dyn TakeConstraint>],
    /// The guidance of the block under way.
    strength: f32,
    progress: &'a mut dyn FnMut(f32) -> bool,
}

impl TakeSteps<'_> {
    /// A target-conditioned GloGen's block aims at the next key within the reach it was
    /// trained on: the conditioning's target part, after the class.
    fn aim(&mut self, sparse: &[f32]) {
        let spec = &self.model.spec;
        let (dim, t) = (spec.layout.dim(), spec.block_len);
        let last = sparse.len() / dim - 1;
        let reach = (spec.glogen.rollout_blocks + 1) * t;
        let Some(key) = self.targets.iter().find(|k| k.sparse > last && k.sparse - last <= reach) else { return };
        let mut raw = sparse.to_vec();
        spec.sparse_norm.denormalize(&mut raw);
        let from = spec.layout.decode(&raw, self.start).1;
        let target = Target { pose: &key.pose, steps: (key.sparse - last) as f32, fix_root: key.fix_root };
        let condition = target_condition(&spec.layout, &spec.sparse_norm, t, from, Some(target));
        let class_len = spec.glogen.class_len(spec.classes.len());
        self.cond[class_len..].copy_from_slice(&condition);
    }

    /// At the first block of a segment with its own seed, its noise and the steering's anchor
    /// draws start from that seed, so the segment can be rerolled alone.
    fn enter_segment(&mut self, b: usize) {
        let segment = self.block_segments[b];
        let entering = self.segment_noise.as_ref().is_none_or(|(s, _)| *s != segment);
        if let Some(seed) = self.opts.timeline.segments[segment].seed.filter(|_| entering) {
            self.segment_noise = Some((segment, StdRng::seed_from_u64(seed)));
            self.steering.reseed(seed);
        }
    }

    /// Adds block `b`'s variation noise to its `input`: from its segment's own seed where it
    /// has one, else from the take's.
    fn vary(&mut self, b: usize, input: &mut [f32]) {
        let own_seed = self.opts.timeline.segments[self.block_segments[b]].seed;
        let (noise, variation) = match (own_seed, self.segment_noise.as_mut()) {
            (Some(seed), Some((_, noise))) => (noise, variation_for(seed)),
            _ => (&mut self.noise, if self.opts.seed == 0 { 0.0 } else { self.opts.variation }),
        };
        if variation > 0.0 {
            input.iter_mut().for_each(|v| *v += variation * noise.random_range(-1.0f32..1.0));
        }
    }
}

impl RolloutSteps for TakeSteps<'_> {
    fn class(&self, _b: usize) -> &[f32] {
        &self.cond
    }

    fn ask(&mut self, b: usize, input: &mut [f32], sparse: &[f32]) -> f32 {
        self.cond = self.plans[b].class.clone();
        self.aim(sparse);
        self.enter_segment(b);
        self.strength = self.steering.block(&self.plans[b], input, sparse);
        self.vary(b, input);
        self.strength
    }

    /// The seed and a block that holds a key stay where they are: the join sees their last
    /// pose alone.
    fn may_move_block_before(&self, b: usize) -> bool {
        self.plans[b - 1].keys.is_empty()
    }

    fn made(&mut self, b: usize, moved_before: bool, sparse: &[f32], block: &[f32]) {
        let spec = &self.model.spec;
        let dim = spec.layout.dim();
        let context = sparse.len() - spec.block_len * dim;
        if moved_before {
            self.steering.amend_last(self.model, &sparse[context - dim..context], &sparse[context..]);
        }
        self.steering.record(self.model, self.plans[b].target, &sparse[sparse.len() - dim..], block);
    }

    fn appended(&mut self, b: usize, glogen: &GloGen, ws: &mut BlockWorkspace, sparse: &mut [f32]) -> Result<()> {
        let block = PlannedBlock { plan: &self.plans[b], strength: self.strength, join_seams: self.opts.join_seams };
        for constraint in self.constraints {
            constraint.on_block(&block, (glogen, &mut *ws), sparse);
        }
        if !(self.progress)(0.8 * (b + 1) as f32 / self.plans.len() as f32) {
            return Err(super::Error::Cancelled.into());
        }
        Ok(())
    }
}

/// Stretches each sparse interval (native `stride` frames) to span the output frames `times`
/// puts its poses at (`stride * pace` apart, [`SparseTimeline::frames`]), by linear
/// interpolation in time. Returns the frames and the output frame at which each sparse pose
/// falls.
fn apply_pace(dense: &[Vec3], joints: usize, stride: usize, times: &[f64]) -> (Vec<Vec3>, Vec<usize>) {
    let native_frames = dense.len() / joints;
    let intervals = times.len().saturating_sub(1);
    let total = times.last().copied().unwrap_or(0.0).floor() as usize + 1;
    let mut out = Vec::with_capacity(total * joints);
    let mut interval = 0;
    for f in 0..total {
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
    let starts = times.iter().map(|t| t.round() as usize).collect();
    (out, starts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pace_stretches_time() {
        let dense: Vec<Vec3> = (0..11).map(|f| Vec3::splat(f as f32)).collect();
        let (out, starts) = apply_pace(&dense, 1, 5, &[0.0, 10.0, 20.0]);
        assert_eq!(out.len(), 21);
        assert_eq!(starts, vec![0, 10, 20]);
        assert_eq!(out[10], Vec3::splat(5.0));
        assert_eq!(out[5], Vec3::splat(2.5));
        // Fractional: the first interval takes 7.5 frames, the second 2.5.
        let (frac, starts) = apply_pace(&dense, 1, 5, &[0.0, 7.5, 10.0]);
        assert_eq!(frac.len(), 11);
        assert_eq!(starts, vec![0, 8, 10]);
        assert!((frac[5].x - 5.0 / 1.5).abs() < 1e-4);
        assert_eq!(frac[10], Vec3::splat(10.0));
    }
}
