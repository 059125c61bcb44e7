//! Long motion from a timeline: GloGen rolls out sparse poses block by block under each
//! segment's class, LocGen refines the interpolated frames between them, pace stretches
//! time, and a final projection restores the skeleton's bone lengths.

use anyhow::{bail, Context, Result};
use glam::Vec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use super::constraints::{check_keys, Key, RootPath};
use super::keys::{fix_roots, key_pose, rewarp, warp_dense, warp_sparse, PlacedKey};
use super::path_follow::{follow_path, GroundPath};
use super::foot_lock::{foot_lock, FootLocked, Travel};
use super::init::{initial_features, InitPose};
use super::smoothstep;
use super::steer::Steering;
use super::timeline::Timeline;
use crate::model::glocal::GlocalModel;
use crate::model::spec::{ModelSpec, MAX_CLASS_STRENGTH};
use crate::motion::contacts::FootContacts;
use crate::motion::{solve_local_poses, Motion};

/// How GloGen's class prior changes at a segment boundary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Transition {
    /// The paper's method: the block that starts in the new segment gets the new class.
    Cut,
    /// The class vector fades from the old class to the new one over the transition length.
    Blend,
    /// Blend, and GloGen's context is also eased towards a real pose window of the new
    /// class (from the seed bank) over the blocks of the transition, so the requested
    /// activity wins over the momentum of the previous one.
    #[default]
    Anchor,
}

/// How a key is reached (all but the default are for the ablation in docs/RESULTS.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum KeyMethod {
    /// Only the dense frames are warped onto the key, over half a second either side.
    DenseWarp,
    /// GloGen's sparse poses are warped onto the key too, over the 2 s before it (and what
    /// its block holds after it), so later blocks are conditioned on the keyed pose. The
    /// shipped method: of the three, the smoothest around keys on both models.
    #[default]
    SparseWarp,
    /// And the rest of the key's block is rolled out again from the keyed context: in the
    /// ablation it jerks more at its extra seam than the warp's fade does.
    RollOn,
}

/// The default length of a class change, centred on the boundary (one h36m block, two
/// Bandai blocks).
pub const DEFAULT_TRANSITION_SECONDS: f32 = 2.0;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GenerateOptions {
    pub timeline: Timeline,
    pub pace: f32,
    pub init: InitPose,
    pub locgen: bool,
    pub transition: Transition,
    /// Seconds over which the take changes class, centred on each boundary (a segment's own
    /// `transition` overrides it); 0 is a cut whatever `transition` says.
    pub transition_seconds: f32,
    /// Classifier-free guidance weight (1 = plain conditioning); none, the model's own
    /// ([`ModelSpec::class_strength`]).
    pub class_strength: Option<f32>,
    /// Seeds the choice of anchor windows and the small pose noise that make repeated takes
    /// differ.
    pub seed: u64,
    /// Noise added to each block's input, in normalised units, so takes with different
    /// seeds differ while staying in class (see [`GenerateOptions::varied`]).
    pub variation: f32,
    pub project_bones: bool,
    /// Re-anchor the context on a fresh seed window of the segment's class when GloGen's
    /// motion stalls, rushes or loops, and raise a stalled block's guidance (see
    /// `synth::steer`), so long segments neither freeze nor repeat.
    pub keep_alive: bool,
    /// Join each GloGen block onto the poses before it (see [`GlocalModel::rollout_block`]);
    /// off, the blocks pop at every seam as in the paper.
    pub join_seams: bool,
    /// Lock planted feet in place with leg IK (see [`super::foot_lock`]), on models whose
    /// takes it suits ([`crate::model::spec::ModelSpec::foot_lock`]).
    pub foot_lock: bool,
    /// Full-body poses the take passes through (see [`super::constraints`]).
    pub keys: Vec<Key>,
    /// A path on the ground the take's locomotion follows.
    pub path: Option<RootPath>,
    pub key_method: KeyMethod,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        Self {
            timeline: Timeline::default(),
            pace: 1.0,
            init: InitPose::default(),
            locgen: true,
            transition: Transition::Anchor,
            transition_seconds: DEFAULT_TRANSITION_SECONDS,
            class_strength: None,
            seed: 0,
            variation: 0.0,
            project_bones: true,
            keep_alive: true,
            join_seams: true,
            foot_lock: true,
            keys: Vec::new(),
            path: None,
            key_method: KeyMethod::default(),
        }
    }
}

/// Pose noise of a varied take: seed 0 is the canonical take, any other seed a variation.
pub const VARIATION: f32 = 0.05;

impl GenerateOptions {
    /// The options with variation `seed` (and the noise that goes with it).
    pub fn varied(mut self, seed: u64) -> Self {
        self.seed = seed;
        self.variation = if seed == 0 { 0.0 } else { VARIATION };
        self
    }

    /// The guidance a take of the model `spec` describes is made with.
    pub fn class_strength_for(&self, spec: &ModelSpec) -> f32 {
        self.class_strength.unwrap_or(spec.class_strength)
    }
}

/// A segment's place in the generated take.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentSpan {
    pub class: usize,
    pub name: String,
    pub start_frame: usize,
    pub end_frame: usize,
}

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
}

/// What one GloGen block is asked for, decided from the timeline before the rollout.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct BlockPlan {
    /// The class vector: one class, or a blend of two inside a transition.
    pub class: Vec<f32>,
    /// The class the block belongs to (the heavier of a blend): anchoring and keep-alive aim
    /// at it.
    pub target: usize,
    /// Blocks over which a change into `target` eases the context (0: no anchoring).
    pub ease_blocks: usize,
    /// The keys whose sparse pose this block produces (indices into the placed keys).
    pub keys: Vec<usize>,
}

/// The sparse poses of each segment and where its boundaries fall.
struct SparseTimeline {
    /// Segment index of each sparse pose (the seed block belongs to the first segment).
    segment_of: Vec<usize>,
    /// Per segment: sparse poses and class.
    counts: Vec<usize>,
    classes: Vec<usize>,
    /// Per segment: the length of the transition into it in sparse steps (for the first
    /// segment, from the initial poses' class).
    transition_steps: Vec<f32>,
    /// Frame of each sparse pose in the paced take.
    frames: Vec<f64>,
    /// Seconds per sparse step at each segment's pace.
    step_seconds: Vec<f32>,
}

impl SparseTimeline {
    fn new(model: &GlocalModel, opts: &GenerateOptions) -> Result<Self> {
        let spec = &model.spec;
        let classes = opts.timeline.validate(&spec.classes, opts.pace)?;
        crate::synth::timeline::check_transition(opts.transition_seconds, "transition length")?;
        let step_of = |pace: f32| spec.stride as f32 * pace / spec.fps;
        let segments = &opts.timeline.segments;
        let paces: Vec<f32> = segments.iter().map(|s| s.pace.unwrap_or(opts.pace)).collect();
        // Sparse poses per segment: its duration over the time one sparse step takes at its pace.
        let counts: Vec<usize> = segments.iter().zip(&paces).map(|(s, &p)| ((s.seconds / step_of(p)).round() as usize).max(1)).collect();
        let segment_of: Vec<usize> = counts.iter().enumerate().flat_map(|(k, &n)| std::iter::repeat_n(k, n)).collect();
        let transition_steps = segments
            .iter()
            .zip(&paces)
            .map(|(s, &p)| if opts.transition == Transition::Cut { 0.0 } else { s.transition.unwrap_or(opts.transition_seconds) / step_of(p) })
            .collect();
        let step_seconds = paces.iter().map(|&p| step_of(p)).collect();
        let mut frames = vec![0.0f64];
        for (i, &k) in segment_of.iter().enumerate() {
            frames.push(frames[i] + spec.stride as f64 * paces[k] as f64);
        }
        Ok(Self { segment_of, counts, classes, transition_steps, frames, step_seconds })
    }

    /// Each key on the sparse pose nearest its time after the seed block, with its pose.
    fn place_keys(&self, model: &GlocalModel, keys: &[Key]) -> Result<Vec<PlacedKey>> {
        let spec = &model.spec;
        let t = spec.block_len;
        let total = self.total();
        if keys.is_empty() {
            return Ok(Vec::new());
        }
        // A take no longer than its starting poses has no room for a key.
        let seed_end = self.frames[(t - 1).min(total - 1)] as f32 / spec.fps;
        check_keys(keys, self.frames[total - 1] as f32 / spec.fps, seed_end)?;
        if total <= t {
            bail!("keys need a take longer than its starting poses ({seed_end:.2} s)");
        }
        keys.iter()
            .map(|key| {
                let pose = key_pose(model, key)?;
                let frame = (key.seconds * spec.fps).round() as usize;
                let sparse = (t..total).min_by(|&a, &b| (self.frames[a] - frame as f64).abs().total_cmp(&(self.frames[b] - frame as f64).abs())).unwrap_or(t);
                let mut features = spec.layout.encode(&[&pose], None);
                spec.sparse_norm.normalize(&mut features);
                Ok(PlacedKey { sparse, frame, pose, features, fix_root: key.fix_root })
            })
            .collect()
    }

    /// Sparse poses of the take, the seed's last pose included.
    fn total(&self) -> usize {
        self.counts.iter().sum::<usize>() + 1
    }

    fn segment_at(&self, i: usize) -> usize {
        self.segment_of[i.min(self.segment_of.len() - 1)]
    }

    /// Sparse index at which segment `k` begins.
    fn boundary(&self, k: usize) -> usize {
        self.counts[..k].iter().sum()
    }

    /// The boundary whose transition covers sparse pose `i`, and how far through it `i` is
    /// (0 at its start, 1 at its end).
    fn transition_at(&self, i: usize) -> Option<(usize, f32)> {
        (1..self.counts.len()).find_map(|k| {
            let len = self.transition_steps[k];
            let through = (i as f32 - self.boundary(k) as f32) / len + 0.5;
            (len > 0.0 && (0.0..1.0).contains(&through)).then_some((k, through))
        })
    }

    /// The per-block plan: each block's class vector is the mean of its poses' class mixes,
    /// a pose inside a transition mixing the two classes by a smoothstep over it.
    fn plan(&self, model: &GlocalModel, anchored: bool, keys: &[PlacedKey]) -> Vec<BlockPlan> {
        let t = model.spec.block_len;
        let blocks = self.total().saturating_sub(t).div_ceil(t);
        let ease_of = |k: usize| if anchored && self.transition_steps[k] > 0.0 { 1 + (self.transition_steps[k] / t as f32).ceil() as usize } else { 0 };
        (0..blocks)
            .map(|b| {
                let mut class = vec![0.0; model.class_vector(0).len()];
                for i in t + b * t..t + (b + 1) * t {
                    let mix = match self.transition_at(i) {
                        Some((k, through)) => {
                            let s = smoothstep(through);
                            vec![(self.classes[k - 1], 1.0 - s), (self.classes[k], s)]
                        }
                        None => vec![(self.classes[self.segment_at(i)], 1.0)],
                    };
                    for (c, w) in mix {
                        if let Some(v) = class.get_mut(c) {
                            *v += w / t as f32;
                        }
                    }
                }
                let segment = self.segment_at(t + b * t + t / 2);
                let target = self.classes[segment];
                let ease_blocks = ease_of(segment);
                let produced = t + b * t..t + (b + 1) * t;
                let keys = (0..keys.len()).filter(|&k| produced.contains(&keys[k].sparse)).collect();
                BlockPlan { class, target, ease_blocks, keys }
            })
            .collect()
    }
}

/// Generates a take. `progress` gets the fraction done and returns false to cancel.
pub fn generate(model: &mut GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    let spec = model.spec.clone();
    let timeline = SparseTimeline::new(model, opts)?;
    let class_strength = opts.class_strength_for(&spec);
    if !(0.0..=MAX_CLASS_STRENGTH).contains(&class_strength) {
        bail!("class strength must be between 0 and {MAX_CLASS_STRENGTH}, got {class_strength}");
    }
    let dim = spec.layout.dim();
    let t = spec.block_len;
    let total = timeline.total();
    let keys = timeline.place_keys(model, &opts.keys)?;
    if let Some(path) = &opts.path {
        path.check().context("root path")?;
    }
    // GloGen's own poses are warped onto keys unless the ablation warps the dense frames alone.
    let sparse_keys = if opts.key_method == KeyMethod::DenseWarp { &[][..] } else { &keys[..] };
    let plans = timeline.plan(model, opts.transition == Transition::Anchor, sparse_keys);

    let (seed_raw, start) = initial_features(model, &opts.init)?;
    let mut steering = Steering::new(model, opts);
    let mut sparse = seed_raw;
    spec.sparse_norm.normalize(&mut sparse);
    let mut noise = StdRng::seed_from_u64(opts.seed);
    let (mut embeddings, mut block_classes) = (Vec::new(), Vec::new());
    let mut out = vec![0.0; t * dim];
    for (b, plan) in plans.iter().enumerate() {
        let context = sparse.len() - t * dim;
        let mut input = sparse[context..].to_vec();
        let strength = steering.block(plan, &mut input, &sparse);
        if opts.variation > 0.0 && opts.seed != 0 {
            input.iter_mut().for_each(|v| *v += opts.variation * noise.random_range(-1.0f32..1.0));
        }
        block_classes.push(plan.target);
        // The seed and a block that holds a key stay where they are: the join sees their last
        // pose alone.
        let movable = b > 0 && plans[b - 1].keys.is_empty();
        let before = if movable { context } else { sparse.len() - dim };
        embeddings.push(model.rollout_block(&input, &plan.class, strength, opts.join_seams.then_some(&mut sparse[before..]), &mut out));
        if movable && opts.join_seams {
            steering.amend_last(model, &sparse[context - dim..context], &sparse[context..]);
        }
        steering.record(model, plan.target, &sparse[sparse.len() - dim..], &out);
        if out.iter().any(|v| !v.is_finite()) {
            bail!("GloGen produced non-finite poses at block {b}");
        }
        sparse.extend_from_slice(&out);
        for &k in &plan.keys {
            let key = &keys[k];
            warp_sparse(&mut sparse, dim, key, timeline.step_seconds[timeline.segment_at(key.sparse)]);
            // What the block held after the key was GloGen's way on without it: the rest of
            // the block is rolled out again from the context that ends on the key.
            let after = (key.sparse + 1) * dim;
            if after < sparse.len() && opts.key_method == KeyMethod::RollOn {
                let input = sparse[after - t * dim..after].to_vec();
                let mut key = input[(t - 1) * dim..].to_vec();
                model.rollout_block(&input, &plan.class, strength, opts.join_seams.then_some(&mut key[..]), &mut out);
                let rest = sparse.len() - after;
                sparse[after..].copy_from_slice(&out[..rest]);
            }
        }
        if !progress(0.8 * (b + 1) as f32 / plans.len() as f32) {
            return Err(super::Error::Cancelled.into());
        }
    }
    sparse.truncate(total * dim);
    spec.sparse_norm.denormalize(&mut sparse);
    let (sparse_positions, _) = spec.layout.decode(&sparse, start);
    let dense = model.densify(&sparse_positions, opts.locgen);
    if !progress(0.9) {
        return Err(super::Error::Cancelled.into());
    }
    let (mut positions, interval_starts) = apply_pace(&dense, spec.layout.joints(), spec.stride, &timeline.frames);
    let units_per_metre = 1.0 / spec.layout.skeleton.meters_per_unit();
    let mut warnings = match &opts.path {
        Some(path) => follow_path(&mut positions, &spec.layout, spec.fps, &GroundPath::new(path, units_per_metre), units_per_metre),
        None => Vec::new(),
    };
    warnings.extend(fix_roots(&mut positions, &spec.layout, spec.fps, &keys));
    for key in &keys {
        warp_dense(&mut positions, &spec.layout, spec.fps, key);
    }
    let skeleton = spec.layout.skeleton.clone();
    let motion = if opts.project_bones {
        let poses = solve_local_poses(&skeleton, &positions);
        Motion::from_local_poses(skeleton, spec.fps, poses)
    } else {
        Motion::from_positions(skeleton, spec.fps, positions)
    };
    let segments = segment_spans(&timeline, &spec.classes, &interval_starts, motion.frames());
    // A root path has laid out where the body goes; without one, the feet of a model whose
    // network slides them say how far.
    let travel = if spec.carry_by_feet && opts.path.is_none() { Travel::FromFeet } else { Travel::Kept };
    let FootLocked { motion, contacts } = foot_lock(motion, opts.foot_lock && spec.foot_lock, travel)?;
    let motion = rewarp(motion, &spec.layout, &keys);
    progress(1.0);
    Ok(Generated { motion, segments, block_embeddings: embeddings, block_classes, contacts, warnings })
}

/// Where each segment falls in the paced take.
fn segment_spans(timeline: &SparseTimeline, names: &[String], interval_starts: &[usize], frames: usize) -> Vec<SegmentSpan> {
    let mut segments = Vec::new();
    let mut first_sparse = 0;
    let last = interval_starts.len() - 1;
    for (k, &n) in timeline.counts.iter().enumerate() {
        let start_frame = interval_starts[first_sparse.min(last)];
        let end_frame = if k + 1 == timeline.counts.len() { frames } else { interval_starts[(first_sparse + n).min(last)] };
        let class = timeline.classes[k];
        segments.push(SegmentSpan { class, name: names[class].clone(), start_frame, end_frame });
        first_sparse += n;
    }
    segments
}

/// The seed bank as anchors: each class's windows normalised once, with their
/// [`pose_motion`], and the class's typical motion (the mean over its windows).
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
