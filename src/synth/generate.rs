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
use super::pace::RecentPace;
use super::path_follow::{follow_path, GroundPath};
use super::foot_lock::{foot_lock, FootLocked, Travel};
use super::init::{initial_features, InitPose};
use super::smoothstep;
use super::timeline::Timeline;
use crate::data::features::ROOT_FEATURES;
use crate::model::glocal::GlocalModel;
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

/// The default classifier-free guidance weight. Measured on both shipped models (docs/RESULTS.md):
/// against plain conditioning (1.0) it lifts class control after a 2 s transition from 89-93%
/// to 94-97% with FID at the real data's level; stronger guidance (2.5) adds 1-3 points but
/// moves FID and poses away from the data (seated hips 5-9 cm higher in one take).
pub const DEFAULT_CLASS_STRENGTH: f32 = 1.5;

/// Guidance at least this strong in the blocks of an anchored class change.
const CHANGE_CLASS_STRENGTH: f32 = 2.5;

/// The default length of a class change, centred on the boundary (one h36m block, two
/// Bandai blocks).
pub const DEFAULT_TRANSITION_SECONDS: f32 = 2.0;

/// A block whose poses move less than this fraction of its class's typical motion (the mean
/// over the seed bank) has stalled: deterministic regression drifts towards the mean pose
/// over minutes, so keep-alive re-anchors it.
const STALL_BELOW: f32 = 0.9;

/// A block whose poses move less than this fraction of its class's typical motion has
/// nearly frozen: keep-alive leans on its window harder.
const FROZEN_BELOW: f32 = 0.5;

/// The most a stalled block's guidance is raised (times the class strength, in proportion to
/// how far its motion fell below [`STALL_BELOW`]): leaning on seed windows alone left h36m's
/// greeting and discussion at 0.59 and 0.57 of the real class's joint speed (the network
/// regresses to slow motion from a lively context), guidance urges the class's own motion
/// on (0.74 and 0.66 with 2, 0.76 and 0.68 with 3, where Bandai's bowing rushed to 3.1x its
/// training speed over ten minutes).
const STALLED_GUIDANCE_GAIN: f32 = 2.0;

/// A block whose poses move more than this multiple of its class's typical motion is
/// rushing (a gesture repeated ever faster): keep-alive re-anchors it too.
const RUSH_ABOVE: f32 = 1.5;

/// A take whose last seconds move slower than this fraction of its class's training speed
/// ([`RecentPace`]) is leant on and urged on however its last block moved; one faster than
/// [`PACE_FAST`] is leant towards its class's calmer windows, with plain conditioning, until
/// it slows. Measured on ten-minute takes of every class (`cargo test --test synth
/// ten_minute`): without the pace, 10 s windows ran at 0.37-2.12x the training speed on
/// h36m and 0.46-2.71x on Bandai; with it, 0.52-1.92x and 0.62-1.98x.
const PACE_SLOW: f32 = 0.7;
const PACE_FAST: f32 = 1.3;

/// A still block in a take whose last seconds ran faster than this ([`RecentPace`]) is its
/// rest, not a stall: urging it on made Bandai's bowing burst to 2.2x its class's speed.
const RESTING_ABOVE: f32 = 1.2;

/// Blocks a keep-alive waits after any anchoring before it may re-anchor again, so a
/// naturally still moment (a pause in a gesture) is not cut short at once.
const KEEP_ALIVE_GAP: usize = 1;

/// Blocks over which a keep-alive eases the context towards its anchor window.
const KEEP_ALIVE_EASE: usize = 2;

/// A keep-alive pulls the context this far (at random in this range) towards its anchor, so
/// no two re-anchorings are alike.
const KEEP_ALIVE_STRENGTH: std::ops::Range<f32> = 0.6..1.0;

/// How far the block after a slow stretch ([`PACE_SLOW`]) starts from its anchor window: all
/// the way, the same window chosen twice in a take gave the same block twice.
const SLOW_TAKE_STRENGTH: std::ops::Range<f32> = 0.8..0.95;

/// The rollout is deterministic, so a take that moves at its class's pace can still settle
/// into a loop: a steady walk became one gait cycle repeated exactly for six minutes. When
/// the last half block of poses comes back to an earlier stretch within this fraction of
/// the class's typical step (per pose, over the joint features), keep-alive leans the
/// context towards a seed window as it does for a stalled take.
const LOOP_TOLERANCE: f32 = 0.25;

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
    /// Classifier-free guidance weight (1 = plain conditioning).
    pub class_strength: f32,
    /// Seeds the choice of anchor windows and the small pose noise that make repeated takes
    /// differ.
    pub seed: u64,
    /// Noise added to each block's input, in normalised units, so takes with different
    /// seeds differ while staying in class (see [`GenerateOptions::varied`]).
    pub variation: f32,
    pub project_bones: bool,
    /// Re-anchor the context on a fresh seed window of the segment's class when GloGen's
    /// motion stalls (see [`STALL_BELOW`]) or loops, and raise a stalled block's guidance
    /// ([`STALLED_GUIDANCE_GAIN`]), so long segments neither freeze nor repeat.
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
            class_strength: DEFAULT_CLASS_STRENGTH,
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

    /// The paper's GlocalNet: cut transitions, plain conditioning, no keep-alive, blocks
    /// that pop at their seams, feet as the network made them.
    pub fn paper(mut self) -> Self {
        self.transition = Transition::Cut;
        self.transition_seconds = 0.0;
        self.class_strength = 1.0;
        self.keep_alive = false;
        self.join_seams = false;
        self.foot_lock = false;
        self
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
struct BlockPlan {
    /// The class vector: one class, or a blend of two inside a transition.
    class: Vec<f32>,
    /// The class the block belongs to (the heavier of a blend): anchoring and keep-alive aim
    /// at it.
    target: usize,
    /// Blocks over which a change into `target` eases the context (0: no anchoring).
    ease_blocks: usize,
    /// The keys whose sparse pose this block produces (indices into the placed keys).
    keys: Vec<usize>,
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

/// A context being eased towards a real window of its class, by a growing share at each of
/// its `blocks` blocks (the seam join keeps the easing from popping).
struct Easing {
    /// A class change (not a keep-alive).
    change: bool,
    anchor: Vec<f32>,
    step: usize,
    blocks: usize,
    /// The block by which the easing reaches its full `strength`.
    reach: usize,
    strength: f32,
}

/// Generates a take. `progress` gets the fraction done and returns false to cancel.
pub fn generate(model: &mut GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    let spec = model.spec.clone();
    let timeline = SparseTimeline::new(model, opts)?;
    if !(0.0..=10.0).contains(&opts.class_strength) {
        bail!("class strength must be between 0 and 10, got {}", opts.class_strength);
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
    // The seed window the take starts from, as (class, its index among the class's windows):
    // leaning on it again from a similar pose replays the start of the take.
    let start_window = match &opts.init {
        InitPose::SeedIndex(i) => model.seeds.get(*i).map(|s| (s.class, model.seeds[..*i].iter().filter(|o| o.class == s.class).count())),
        InitPose::SeedClass { class, variant } => spec.class_index(class).ok().and_then(|c| Some((c, model.class_seed_index(c, *variant)?))),
        InitPose::File { .. } => None,
    };
    let mut context_class = start_window.map(|(class, _)| class);
    let mut easing: Option<Easing> = None;
    let bank = AnchorBank::new(model);
    let mut pace = RecentPace::new(model);
    let mut since_anchor = 0;
    let mut last_anchor = None;
    let mut sparse = seed_raw;
    spec.sparse_norm.normalize(&mut sparse);
    let mut noise = StdRng::seed_from_u64(opts.seed);
    let mut anchors = StdRng::seed_from_u64(opts.seed ^ 0xA1C4_0125);
    let (mut embeddings, mut block_classes) = (Vec::new(), Vec::new());
    let mut out = vec![0.0; t * dim];
    for (b, plan) in plans.iter().enumerate() {
        let context = &sparse[sparse.len() - t * dim..];
        let mut input = context.to_vec();
        let previous = context[context.len() - dim..].to_vec();
        let motion = pose_motion(&input, dim) / bank.typical[plan.target].max(f32::EPSILON);
        let may_keep_alive = opts.keep_alive && since_anchor >= KEEP_ALIVE_GAP;
        let recent = pace.of(plan.target);
        // Slow when either measure says so (a drifting stand reads fast with its travel in);
        // fast by the whole body's speed, which the finished take keeps.
        let slow_take = recent.is_some_and(|p| p.whole.min(p.pose) < PACE_SLOW);
        let fast_take = recent.is_some_and(|p| p.whole > PACE_FAST);
        let slow_block = motion < STALL_BELOW && !recent.is_some_and(|p| p.whole > RESTING_ABOVE);
        let rushing = motion > RUSH_ABOVE || fast_take;
        let stalled = may_keep_alive && (slow_block || slow_take || rushing);
        let switching = plan.ease_blocks > 0 && context_class != Some(plan.target);
        let changing = switching || easing.as_ref().is_some_and(|e| e.change);
        // A loop is broken even while a keep-alive eases: leaning on a window the take leant
        // on before, from a similar pose, replays that stretch. (While a class change eases,
        // the search would decide nothing.)
        let leaning = easing.as_ref().is_some_and(|e| !e.change);
        let looping = may_keep_alive && (easing.is_none() || leaning) && repeats_earlier(&sparse, dim, t / 2, t, LOOP_TOLERANCE * bank.typical[plan.target]);
        if (easing.is_none() && (switching || stalled || looping)) || (leaning && looping && !switching) {
            // A take slow for seconds starts its next block from (nearly) a lively window, one
            // block only: twice from the same context gives the same block twice.
            let (blocks, strength) = if switching {
                (plan.ease_blocks, 1.0)
            } else if slow_take {
                (1, anchors.random_range(SLOW_TAKE_STRENGTH))
            } else {
                (KEEP_ALIVE_EASE, anchors.random_range(KEEP_ALIVE_STRENGTH))
            };
            let typical = bank.typical[plan.target];
            // A loop is broken by any other window; a lively one thrown into a still take
            // made Bandai's bowing burst to 3-4x its typical motion.
            let wanted = if switching || !stalled { 0.0..=f32::INFINITY } else if rushing { 0.0..=typical } else { typical..=f32::INFINITY };
            let start = start_window.and_then(|(class, k)| (class == plan.target).then_some(k));
            let avoid: Vec<usize> = last_anchor.into_iter().chain(start).collect();
            easing = bank.pick(plan.target, wanted, &mut anchors, &avoid).map(|(k, anchor)| {
                last_anchor = Some(k);
                // A class change ends on the new class's window. A keep-alive leans towards its
                // window by its random strength (0.6-1.0): a take far below its class's motion
                // by its last block (a third less had kept a stalled h36m phoning take at
                // 0.2-0.5x its typical motion however often it leant), any other a block later
                // (leaning every slow take that hard raised Bandai's mean jerk from 1.21x to
                // 1.34x real). A loop the lean makes is caught by [`repeats_earlier`].
                let reach = if switching { (blocks - 1).max(1) } else if motion < FROZEN_BELOW || slow_take { blocks } else { blocks + 1 };
                Easing { change: switching, anchor, step: 0, blocks, reach, strength }
            });
            context_class = Some(plan.target);
            since_anchor = 0;
        }
        since_anchor += 1;
        if let Some(e) = easing.as_mut() {
            e.step += 1;
            let alpha = (e.strength * e.step as f32 / e.reach as f32).min(1.0);
            input.iter_mut().zip(&e.anchor).for_each(|(v, a)| *v += alpha * (a - *v));
            if e.step == e.blocks {
                easing = None;
            }
        }
        if opts.variation > 0.0 && opts.seed != 0 {
            input.iter_mut().for_each(|v| *v += opts.variation * noise.random_range(-1.0f32..1.0));
        }
        block_classes.push(plan.target);
        // A class change is where the prior must beat the context's momentum most: its blocks
        // get at least the stronger guidance of [`CHANGE_CLASS_STRENGTH`].
        let strength = if changing { opts.class_strength.max(CHANGE_CLASS_STRENGTH) } else { opts.class_strength };
        // A stalled block's class is urged on too: guidance scaled by how far it fell short.
        let strength = if !opts.keep_alive || changing {
            strength
        } else if fast_take {
            strength.min(1.0)
        } else if slow_block || slow_take {
            strength * (STALL_BELOW / motion.max(f32::EPSILON)).clamp(1.0, STALLED_GUIDANCE_GAIN)
        } else {
            strength
        };
        embeddings.push(model.rollout_block(&input, &previous, &plan.class, strength, opts.join_seams, &mut out));
        if opts.keep_alive {
            pace.push(model, plan.target, &raw_block(&spec, &previous, &out));
        }
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
                let context = &sparse[after - t * dim..after];
                let previous = context[context.len() - dim..].to_vec();
                model.rollout_block(context, &previous, &plan.class, strength, opts.join_seams, &mut out);
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
struct AnchorBank {
    /// Per class: (normalised window, its motion), in seed-bank order.
    windows: Vec<Vec<(Vec<f32>, f32)>>,
    typical: Vec<f32>,
}

impl AnchorBank {
    fn new(model: &GlocalModel) -> Self {
        let dim = model.spec.layout.dim();
        let mut windows = vec![Vec::new(); model.spec.classes.len()];
        for seed in &model.seeds {
            let mut window = seed.features.clone();
            model.spec.sparse_norm.normalize(&mut window);
            if let Some(w) = windows.get_mut(seed.class) {
                let motion = pose_motion(&window, dim);
                w.push((window, motion));
            }
        }
        let typical = windows.iter().map(|w| if w.is_empty() { 0.0 } else { w.iter().map(|(_, m)| m).sum::<f32>() / w.len() as f32 }).collect();
        Self { windows, typical }
    }

    /// A random window of `class` whose motion is in `wanted` (a keep-alive wants a window
    /// that moves: re-anchoring a stalled take on a still window of the class keeps it still;
    /// a rushing one wants a calm window), none of `avoid` where there is a choice, with its
    /// index.
    fn pick(&self, class: usize, wanted: std::ops::RangeInclusive<f32>, rng: &mut StdRng, avoid: &[usize]) -> Option<(usize, Vec<f32>)> {
        let windows: Vec<(usize, &(Vec<f32>, f32))> = self.windows.get(class)?.iter().enumerate().collect();
        let fitting: Vec<&(usize, &(Vec<f32>, f32))> = windows.iter().filter(|(_, (_, m))| wanted.contains(m)).collect();
        let pool = if fitting.is_empty() { windows.iter().collect() } else { fitting };
        let fresh: Vec<_> = pool.iter().filter(|(k, _)| !avoid.contains(k)).collect();
        let &(k, (window, _)) = if fresh.is_empty() { pool.first().copied()? } else { *fresh[rng.random_range(0..fresh.len())] };
        Some((k, window.clone()))
    }
}

/// A block's poses after the pose before it (all normalised), as raw features.
fn raw_block(spec: &crate::model::spec::ModelSpec, previous: &[f32], block: &[f32]) -> Vec<f32> {
    let mut poses = [previous, block].concat();
    spec.sparse_norm.denormalize(&mut poses);
    poses
}

/// Mean distance between consecutive poses of a normalised sparse window, over the joint
/// features (the root's velocities stay constant in steady walking, so they are left out).
fn pose_motion(window: &[f32], dim: usize) -> f32 {
    let poses: Vec<&[f32]> = window.chunks_exact(dim).collect();
    let steps = poses.windows(2).map(|p| distance2(&p[0][ROOT_FEATURES..], &p[1][ROOT_FEATURES..]).sqrt());
    steps.sum::<f32>() / (poses.len().max(2) - 1) as f32
}

/// The squared distance between two feature vectors.
fn distance2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum()
}

/// Whether the last `span` poses of `sparse` (normalised) repeat a stretch of the take at
/// least `min_lag` poses earlier: the root-mean-square distance between the joint features
/// of corresponding poses is within `tolerance`. Without the lag a still take would match
/// the poses just before it and count as a loop. Each candidate stops at the first pose that
/// puts it out of reach, so the search over the whole take costs about one pose comparison
/// per earlier pose.
fn repeats_earlier(sparse: &[f32], dim: usize, span: usize, min_lag: usize, tolerance: f32) -> bool {
    let poses = sparse.len() / dim;
    if span == 0 || poses < span + min_lag.max(span) {
        return false;
    }
    let joints = |k: usize| &sparse[k * dim + ROOT_FEATURES..(k + 1) * dim];
    let recent = poses - span;
    let budget = tolerance * tolerance * span as f32;
    (0..=recent - min_lag.max(span)).any(|start| {
        let mut total = 0.0;
        (0..span).all(|i| {
            total += distance2(joints(start + i), joints(recent + i));
            total <= budget
        })
    })
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
