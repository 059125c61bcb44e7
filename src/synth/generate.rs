//! Long motion from a timeline: GloGen rolls out sparse poses block by block under each
//! segment's class, as the take's plan asks ([`super::plan`]), LocGen refines the
//! interpolated frames between them, pace stretches time, the constraints pull the take onto
//! its keys and path, and a final projection restores the skeleton's bone lengths.

use std::ops::Range;

use anyhow::{bail, Context, Result};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::finish::{above_the_legs, chunks, ChunkFinish, Finishing, Stretch, Textured};
use super::finish_thread::{FinishingThread, Shown};
use super::course::HoldCourse;
use super::foot_lock::Travel;
use super::generated::{Generated, TakeEvents};
use super::given::{keeps_given_frames, GivenFloor, GivenStart};
use super::held::HeldConstraint;
use super::init::{given_frames, initial_features, InitPose};
use super::keys::{filled_gaps, learnt_travel, place_keys, KeyConstraint, PlacedKey};
use super::options::{variation_for, GenerateOptions, KeyMethod, Transition};
use super::path_follow::{GroundPath, PathConstraint};
use super::plan::{BlockPlan, PlannedBlock, SparseTimeline, TakeConstraint};
use super::reuse::{block_prints, settled_poses, take_print, Checkpoint, Resume, RolloutState, TakeCache, TakeRecord};
use super::steer::Steering;
use crate::model::block::BlockWorkspace;
use crate::model::glocal::GlocalModel;
use crate::data::features::Placement;
use crate::model::glogen::GloGen;
use crate::model::rollout::{rollout_blocks, RolloutSteps};
use crate::model::spec::{ModelSpec, MAX_CLASS_STRENGTH};
use crate::model::texture::TexturedPose;
use crate::model::target::{target_condition, Target};

/// Generates a take as its timeline lays it out, from its start to its end (a loop is cut
/// from one, [`super::looping`]). `progress` gets the fraction done and returns false to
/// cancel.
pub fn continuous_take(model: &GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    generate_reusing(model, opts, &mut TakeCache::default(), &mut &mut *progress)
}

/// [`continuous_take`], resuming the take in `cache` where this one begins to differ from
/// it (see [`super::reuse`]) and keeping this one there for the next; `events` sees the
/// take's frames as they become final. The take is the one a fresh generation makes.
pub fn generate_reusing(model: &GlocalModel, opts: &GenerateOptions, cache: &mut TakeCache, events: &mut dyn TakeEvents) -> Result<Generated> {
    let spec = &model.spec;
    let timeline = SparseTimeline::new(spec, opts)?;
    let class_strength = opts.class_strength_for(spec);
    if !(0.0..=MAX_CLASS_STRENGTH).contains(&class_strength) {
        bail!("class strength must be between 0 and {MAX_CLASS_STRENGTH}, got {class_strength}");
    }
    let (dim, total, t) = (spec.layout.dim(), timeline.total(), spec.block_len);
    // The start first: a file that cannot start the take is named before anything else.
    let (seed_block, start) = initial_features(model, &opts.init)?;
    let keys = place_keys(&timeline, model, &opts.keys, &opts.init)?;
    // GloGen's own poses are warped onto keys unless the ablation warps the dense frames alone.
    let key_poses: Vec<usize> = if opts.key_method == KeyMethod::DenseWarp { Vec::new() } else { keys.iter().map(|k| k.sparse).collect() };
    let plans = timeline.plan(model, opts.transition == Transition::Anchor, &key_poses);
    let mut targets = if model.glogen().reads_target() { keys.clone() } else { Vec::new() };
    targets.sort_by_key(|k| k.sparse);
    let held = if opts.held.is_empty() { None } else { Some(HeldConstraint::new(spec, &opts.held, &timeline, keys.iter().map(|k| k.frame).collect())?) };
    let gaps = filled_gaps(model, opts.key_method, &keys);
    // The in-betweener's gaps travel as it learnt them from real motion, not as their feet say.
    let learnt = learnt_travel(&gaps, &keys);
    let constraints = take_constraints(model, opts, &timeline, (keys, gaps), held.as_ref())?;
    let block_segments: Vec<usize> = (0..plans.len()).map(|b| timeline.segment_at(t + b * t + t / 2)).collect();
    // Keys and held frames warp poses far behind the block being made; they and a path reach
    // across the take's frames too.
    let resumable = opts.keys.is_empty() && opts.held.is_empty();
    // Takes of one chunk, and those keys, held frames or a path reach across, are finished whole.
    let layout = Some(chunks(total, spec.stride as f32 / spec.fps)).filter(|l| resumable && opts.path.is_none() && l.len() > 1);
    // A root path has laid out where the body goes; without one, the feet of a model whose
    // network slides them say how far.
    let travel = if spec.carry_by_feet && opts.path.is_none() { Travel::FromFeet { kept: learnt } } else { Travel::Kept };
    let block_classes: Vec<usize> = plans.iter().map(|p| p.target).collect();
    let texture = model.texture().filter(|_| opts.texture).map(|bank| Textured { bank, poses: textured_poses(spec, &plans, t, total), seed: opts.seed });
    let turn_limits = (opts.spread_snaps && !spec.bone_turn_limits.is_empty()).then(|| above_the_legs(spec.turn_limits_per_frame(), &spec.layout.skeleton));
    let finishing = Finishing { model, locgen: opts.locgen_for(&model.spec), project_bones: opts.project_bones, foot_lock: opts.foot_lock, travel, times: &timeline.frames, constraints: &constraints, texture, turn_limits };
    let segments = timeline.planned_spans(spec);

    // Only a resumable take is printed: the print of a request's held frames would cost
    // more than the blocks it could spare.
    let prints = resumable.then(|| (take_print(model, opts, &seed_block), block_prints(opts, &plans, &block_segments)));
    let resume = prints.as_ref().and_then(|(take, blocks)| cache.resume(*take, blocks));
    let Resumed { mut sparse, state, first_block, mut embeddings, checkpoints } = match &resume {
        Some(r) => Resumed::from(r, t, dim),
        None => Resumed::fresh(model, opts, seed_block),
    };
    let kept = resume.as_ref().and_then(|r| Some((r.record.chunks.as_ref()?, settled_poses(r.block, t), r.record.times.as_slice())));
    let chunked = layout.map(|layout| ChunkFinish::resumed(&finishing, layout, kept, start, &timeline.frames));
    let shown = Shown { segments: &segments, block_classes: &block_classes };
    let (made, checkpoints, chunked) = std::thread::scope(|scope| -> Result<_> {
        let mut steps = TakeSteps {
            model,
            opts,
            plans: &plans,
            targets,
            start,
            cond: Vec::new(),
            state,
            block_segments,
            constraints: &constraints,
            held: held.as_ref(),
            strength: class_strength,
            checkpoints: resumable.then_some(checkpoints),
            finishing: chunked.map(|chunked| FinishingThread::spawn(scope, chunked, model, shown)),
            events: &mut *events,
        };
        let made = rollout_blocks(model.glogen(), &mut BlockWorkspace::default(), &mut sparse, first_block..plans.len(), opts.join_seams, &mut steps);
        let TakeSteps { checkpoints, finishing, events, .. } = steps;
        let made = match made {
            Ok(made) => made,
            // The finishing's own error, where it stopped first, is what stopped the rollout.
            Err(e) => return Err(finishing.and_then(|thread| thread.stop().err()).unwrap_or(e)),
        };
        let chunked = finishing.map(|thread| thread.finish(&sparse, total, dim, events)).transpose()?;
        Ok((made, checkpoints, chunked))
    })?;
    embeddings.extend(made);
    let (motion, contacts, warnings, chunked) = match chunked {
        Some(chunked) => {
            let motion = chunked.done.motion(model);
            let contacts = chunked.done.contacts().clone();
            (motion, contacts, Vec::new(), Some(chunked))
        }
        None => {
            // Held frames without keys or a path leave only their free runs to finish.
            let held = held.as_ref().filter(|_| opts.keys.is_empty() && opts.path.is_none());
            let stretch = finish_whole(&finishing, &sparse[..total * dim], start, held, events)?;
            (stretch.motion, stretch.contacts, stretch.warnings, None)
        }
    };
    events.progress(1.0);
    let generated = Generated { motion, segments: segments.clone(), block_embeddings: embeddings, block_classes: block_classes.clone(), contacts, warnings, cycle: None };
    cache.record = checkpoints.zip(prints).map(|(checkpoints, (take_print, block_prints))| TakeRecord {
        take_print,
        block_prints,
        checkpoints,
        sparse,
        embeddings: generated.block_embeddings.clone(),
        times: timeline.frames.clone(),
        chunks: chunked.map(ChunkFinish::into_record),
    });
    Ok(generated)
}

/// What each of a take's `total` sparse poses reads of the texture: the seed's `block_len`
/// poses the first block's, then each block's its own: its class's, all of it, or in a style
/// calmer than its class that style's share of the class's pace. The texture is laid from
/// the class's clips in every style, and a calm style's clips barely move: `all`'s byebye
/// in the feminine style (0.02 m/s against the class's 0.23) waved at 1.60x its clips with
/// its class's whole share.
fn textured_poses(spec: &ModelSpec, plans: &[BlockPlan], block_len: usize, total: usize) -> Vec<TexturedPose> {
    let blocks: Vec<TexturedPose> = plans
        .iter()
        .map(|plan| TexturedPose { class: plan.target, share: plan.style.and_then(|style| spec.style_pace(plan.target, style)).map_or(1.0, |pace| pace.min(1.0)) })
        .collect();
    let Some(last) = blocks.len().checked_sub(1) else { return Vec::new() };
    (0..total).map(|i| blocks[(i.saturating_sub(block_len) / block_len).min(last)]).collect()
}

/// The take's constraints in the order they apply: a file start's floor carries the take, a
/// travelling class holds its course or the root path lays it out, the keys pin it, the file
/// start's given frames are put back as given, and held frames as held.
/// `held` is the request's held frames as a constraint, kept by the caller (the rollout and
/// the finishing read them too); the keys come with the gaps before them the in-betweener
/// fills.
fn take_constraints<'a>(model: &'a GlocalModel, opts: &GenerateOptions, timeline: &SparseTimeline, (keys, gaps): (Vec<PlacedKey>, Vec<Range<usize>>), held: Option<&'a HeldConstraint>) -> Result<Vec<Box<dyn TakeConstraint + 'a>>> {
    let spec = &model.spec;
    let mut constraints: Vec<Box<dyn TakeConstraint + 'a>> = Vec::new();
    let given = given_frames(model, &opts.init)?.filter(|_| keeps_given_frames(opts));
    // First: the take onto the given frames' floor, which the keys and the path then keep.
    if let Some(frames) = &given {
        constraints.push(Box::new(GivenFloor { frames: frames.clone() }));
    }
    // A travelling class keeps its course unless a path lays out another.
    if let Some(course) = (opts.hold_course && opts.path.is_none()).then(|| HoldCourse::new(model, timeline, &opts.init)).flatten() {
        constraints.push(Box::new(course));
    }
    if let Some(path) = &opts.path {
        path.check().context("root path")?;
        let units_per_metre = 1.0 / spec.layout.skeleton.meters_per_unit();
        constraints.push(Box::new(PathConstraint { path: GroundPath::new(path, units_per_metre), units_per_metre }));
    }
    let first_key = keys.iter().map(|k| k.frame).min();
    if !keys.is_empty() {
        let step_seconds = keys.iter().map(|k| timeline.step_seconds[timeline.segment_at(k.sparse)]).collect();
        constraints.push(Box::new(KeyConstraint { keys, model, gaps, step_seconds, method: opts.key_method }));
    }
    if let Some(frames) = given {
        constraints.push(Box::new(GivenStart { frames, until: first_key.unwrap_or(usize::MAX) }));
    }
    // Last: the held frames come out exactly as held, whatever the others did.
    if let Some(held) = held {
        constraints.push(Box::new(held));
    }
    Ok(constraints)
}

/// Where a take's rollout starts: its sparse poses so far (normalised), the rollout's state,
/// the first block to make, and the embeddings and checkpoints of the blocks before it.
struct Resumed {
    sparse: Vec<f32>,
    state: RolloutState,
    first_block: usize,
    embeddings: Vec<Vec<f32>>,
    checkpoints: Vec<Checkpoint>,
}

impl Resumed {
    /// From the starting poses `seed_block`.
    fn fresh(model: &GlocalModel, opts: &GenerateOptions, mut seed_block: Vec<f32>) -> Self {
        model.spec.sparse_norm.normalize(&mut seed_block);
        let state = RolloutState { steering: Steering::new(model, opts), noise: StdRng::seed_from_u64(opts.seed), segment_noise: None };
        Self { sparse: seed_block, state, first_block: 0, embeddings: Vec::new(), checkpoints: Vec::new() }
    }

    /// Where the cached take stood before the block `resume` starts at.
    fn from(resume: &Resume<'_>, block_len: usize, dim: usize) -> Self {
        let (record, block) = (resume.record, resume.block);
        Self { sparse: resume.sparse(block_len, dim), state: record.checkpoints[block - 1].state.clone(), first_block: block, embeddings: record.embeddings[..block].to_vec(), checkpoints: record.checkpoints[..block].to_vec() }
    }
}

/// A take finished whole from its sparse poses (normalised), or around the free runs of its
/// `held` frames.
fn finish_whole(finishing: &Finishing<'_>, sparse: &[f32], start: Placement, held: Option<&HeldConstraint>, events: &mut dyn TakeEvents) -> Result<Stretch> {
    let spec = &finishing.model.spec;
    let mut raw = sparse.to_vec();
    spec.sparse_norm.denormalize(&mut raw);
    let (positions, _) = spec.layout.decode(&raw, start);
    if !events.progress(0.9) {
        return Err(super::Error::Cancelled.into());
    }
    match held {
        Some(held) => finishing.around_free_frames(&positions, held),
        None => finishing.stretch(&positions, 0..positions.len() / spec.layout.joints()),
    }
}

/// How the take's rollout goes block by block: the plan's class, the steering's easing and
/// guidance, the variation's noise, and the constraints after each block; a resumable take
/// keeps its state after each block, and a take finished in chunks hands each block's
/// settled poses to its finishing thread.
struct TakeSteps<'s, 'a: 's> {
    model: &'a GlocalModel,
    opts: &'a GenerateOptions,
    plans: &'a [BlockPlan],
    /// The keys a target-conditioned GloGen aims at, in time order.
    targets: Vec<PlacedKey>,
    /// Where the take starts (the sparse poses are steps from it).
    start: Placement,
    /// The conditioning of the block under way: its plan's class, then its target.
    cond: Vec<f32>,
    state: RolloutState,
    /// The segment each block belongs to (its plan's target).
    block_segments: Vec<usize>,
    constraints: &'a [Box<dyn TakeConstraint + 'a>],
    /// The held frames, whose blocks GloGen need not make.
    held: Option<&'a HeldConstraint>,
    /// The guidance of the block under way.
    strength: f32,
    /// The state after each block made, for a take that can be resumed.
    checkpoints: Option<Vec<Checkpoint>>,
    /// The take's chunks finishing beside the rollout, for a take finished in chunks.
    finishing: Option<FinishingThread<'s, 'a>>,
    events: &'s mut dyn TakeEvents,
}

impl TakeSteps<'_, '_> {
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
        let class_len = spec.label_len();
        self.cond[class_len..].copy_from_slice(&condition);
    }

    /// At the first block of a segment with its own seed, its noise and the steering's anchor
    /// draws start from that seed, so the segment can be rerolled alone.
    fn enter_segment(&mut self, b: usize) {
        let segment = self.block_segments[b];
        let entering = self.state.segment_noise.as_ref().is_none_or(|(s, _)| *s != segment);
        if let Some(seed) = self.opts.timeline.segments[segment].seed.filter(|_| entering) {
            self.state.segment_noise = Some((segment, StdRng::seed_from_u64(seed)));
            self.state.steering.reseed(seed);
        }
    }

    /// Adds block `b`'s variation noise to its `input`: from its segment's own seed where it
    /// has one, else from the take's.
    fn vary(&mut self, b: usize, input: &mut [f32]) {
        let own_seed = self.opts.timeline.segments[self.block_segments[b]].seed;
        let state = &mut self.state;
        let (noise, variation) = match (own_seed, state.segment_noise.as_mut()) {
            (Some(seed), Some((_, noise))) => (noise, variation_for(seed)),
            _ => (&mut state.noise, if self.opts.seed == 0 { 0.0 } else { self.opts.variation }),
        };
        if variation > 0.0 {
            input.iter_mut().for_each(|v| *v += variation * noise.random_range(-1.0f32..1.0));
        }
    }

    /// The sparse poses block `b` makes.
    fn block_poses(&self, b: usize) -> std::ops::Range<usize> {
        let t = self.model.spec.block_len;
        t + b * t..t + (b + 1) * t
    }

    /// Whether every pose of block `b` is held.
    fn holds(&self, b: usize) -> bool {
        self.held.is_some_and(|h| h.holds(self.block_poses(b)))
    }

    /// After block `b`: its state kept, and the poses it settles handed to the finishing thread.
    fn settle(&mut self, b: usize, sparse: &[f32]) -> Result<()> {
        let spec = &self.model.spec;
        let settled = settled_poses(b + 1, spec.block_len);
        if let Some(checkpoints) = self.checkpoints.as_mut() {
            checkpoints.push(Checkpoint { state: self.state.clone(), unsettled: sparse[settled * spec.layout.dim()..].to_vec() });
        }
        match self.finishing.as_mut() {
            Some(thread) => thread.send(sparse, settled, spec.layout.dim(), &mut *self.events),
            None => Ok(()),
        }
    }
}

impl RolloutSteps for TakeSteps<'_, '_> {
    fn class(&self, _b: usize) -> &[f32] {
        &self.cond
    }

    fn ask(&mut self, b: usize, input: &mut [f32], sparse: &[f32]) -> f32 {
        self.cond = self.plans[b].class.clone();
        self.aim(sparse);
        self.enter_segment(b);
        // A held block is not made: there is nothing to steer (the steering takes up the
        // take again at the next free block, easing into its class if that changed).
        if !self.holds(b) {
            self.strength = self.state.steering.block(&self.plans[b], input, sparse);
        }
        self.vary(b, input);
        self.strength
    }

    fn given(&self, b: usize) -> Option<Vec<f32>> {
        self.held?.held_block(self.block_poses(b))
    }

    /// The seed and a block that holds a key stay where they are: the join sees their last
    /// pose alone.
    fn may_move_block_before(&self, b: usize) -> bool {
        self.plans[b - 1].keys.is_empty()
    }

    fn starts_from_given_motion(&self) -> bool {
        matches!(self.opts.init, InitPose::File { .. })
    }

    fn made(&mut self, b: usize, moved_before: bool, sparse: &[f32], block: &[f32]) {
        let spec = &self.model.spec;
        let dim = spec.layout.dim();
        let context = sparse.len() - spec.block_len * dim;
        if moved_before {
            self.state.steering.amend_last(self.model, &sparse[context - dim..context], &sparse[context..]);
        }
        self.state.steering.record(self.model, &self.plans[b], &sparse[sparse.len() - dim..], block);
    }

    fn appended(&mut self, b: usize, glogen: &GloGen, ws: &mut BlockWorkspace, sparse: &mut [f32]) -> Result<()> {
        if !self.holds(b) {
            self.state.steering.hold_pace(self.model, &self.plans[b], sparse);
        }
        let block = PlannedBlock { plan: &self.plans[b], strength: self.strength, join_seams: self.opts.join_seams };
        for constraint in self.constraints {
            constraint.on_block(&block, (glogen, &mut *ws), sparse);
        }
        self.settle(b, sparse)?;
        if !self.events.progress(0.8 * (b + 1) as f32 / self.plans.len() as f32) {
            return Err(super::Error::Cancelled.into());
        }
        Ok(())
    }
}
