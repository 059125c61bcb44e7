//! How each block of the rollout is steered: its context eased towards a real window of its
//! class at a class change, and keep-alive's rule on the take's own motion (a stalled,
//! rushing, slow or looping take leans on a seed window of its class and is urged on).
//! The plan (`plan::SparseTimeline::plan`) says what each block asks for; this says what
//! the motion so far makes of it.

use std::sync::Arc;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::options::GenerateOptions;
use super::plan::BlockPlan;
use super::init::InitPose;
use super::pace::RecentPace;
use crate::data::features::ROOT_FEATURES;
use crate::model::glocal::GlocalModel;

/// Guidance at least this strong in the blocks of an anchored class change and the
/// [`CHANGE_SETTLE_SECONDS`] after it.
const CHANGE_CLASS_STRENGTH: f32 = 2.75;

/// Seconds after a class change's easing whose guidance stays at least
/// [`CHANGE_CLASS_STRENGTH`]: where the easing ends, the new class's window still competes with
/// the old class's momentum.
const CHANGE_SETTLE_SECONDS: f32 = 4.0;

/// Seconds after a class change's easing over which a take whose last seconds ran fast is
/// leant on calm windows only while its block still moves (twice the pace's 6 s, which it
/// reads from the blocks after the change only, [`Steering::record`]). The new class's first
/// seconds run fast (a wave after another activity at 1.3x its class's speed, the change
/// and keep-alive's urging), and leant on calm windows with plain conditioning however
/// still it already was, the wave died down to 0.6x; `all`'s bow then stood at its
/// segment's end where a run began (Bandai's reroll joins 1.41x the real seam ratio, limit
/// 1.3). Over a whole take of one class the same rule slowed h36m's ten-minute phoning to
/// 0.46x its class's speed and let Bandai's bow repeat itself.
const CHANGE_PACE_SECONDS: f32 = 12.0;

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
/// training speed over ten minutes). 2.5 since h36m's model keeps `Spine` (28 joints): with 2
/// its ten-minute greeting's slowest 10 s window ran at 0.497x the training speed, with 2.5 at
/// 0.50x, Bandai's bowing at most 1.52x (`cargo test --release --test synth ten_minute`).
const STALLED_GUIDANCE_GAIN: f32 = 2.5;

/// A block whose poses move more than this multiple of its class's typical motion is
/// rushing (a gesture repeated ever faster): keep-alive re-anchors it too.
const RUSH_ABOVE: f32 = 1.5;

/// A take whose last seconds move slower than this fraction of its class's training speed
/// ([`RecentPace`]) is leant on and urged on however its last block moved; one faster than
/// [`PACE_FAST`] is leant towards its class's calmer windows, with plain conditioning, until
/// it slows. Measured on ten-minute takes of every class (`cargo test --test synth
/// ten_minute`): without the pace, 10 s windows ran at 0.37-2.12x the training speed on
/// h36m and 0.46-2.71x on Bandai; with it, 0.52-1.92x and 0.62-1.98x. A segment that has
/// run faster than [`PACE_FAST`] over the pace's whole seconds also has its blocks scaled
/// down to it ([`Steering::hold_pace`]): leaning alone left `all`'s sittingdown, restless in
/// a half crouch, at 1.61x its clips.
const PACE_SLOW: f32 = 0.7;
const PACE_FAST: f32 = 1.3;

/// A still block in a take whose last seconds ran faster than this ([`RecentPace`]) is its
/// rest, not a stall: urging it on made Bandai's bowing burst to 2.2x its class's speed.
const RESTING_ABOVE: f32 = 1.2;

/// A segment that names a style calmer than its class and has run faster than this multiple
/// of the style's pace over the pace's last seconds has each block's motion scaled down to it
/// ([`Steering::hold_pace`]): the network's byebye waves at about one speed whatever its
/// style, where Bandai's feminine and sad byebye clips barely move (0.023 and 0.037 m/s
/// against the class's 0.23), and neither guidance nor leaning on calm windows slowed it below
/// 3.8x and 1.8x their clips. Held above 1.0 it slowed 44 of the styles suite's 140 settled
/// speeds, some to 0.65x their clips; above 1.3 the feminine wave stayed at 1.60x.
const STYLE_PACE_ABOVE: f32 = 1.2;
/// The least share of its motion a block held to its pace keeps (its class's or its style's,
/// [`Steering::hold_pace`]): at 0.3 the feminine wave stayed at 1.61x its clips.
const PACE_DAMPING_FLOOR: f32 = 0.2;

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
/// the class's typical step (per pose, over the joints, in the skeleton's units), keep-alive
/// leans the context towards a seed window as it does for a stalled take.
const LOOP_TOLERANCE: f32 = 0.25;

/// A take started from a file whose start holds the hips lower than its first segment's
/// class's own height by more than this share of it (a floor sit or a chair before a walk)
/// waits with that class's easing for the network to stand the body up ([`Steering::block`]).
const POSTURE_GAP: f32 = 0.25;

/// Seconds the change into the first segment waits at most for the body to stand up: the
/// network rises at its own pace, from a chair or the floor in about 3 s (waiting up to 4 s,
/// h36m's walks started from S11 sitting stood 3.3-3.5 s after the file's frames), and the
/// anchoring that ends the wait takes the rest of the way, a gap the wait leaves short
/// enough to climb at a person's speed (standing within 2 s of the file's frames, the hips
/// climbing at most 1.24 m/s over 0.2 s).
const POSTURE_WAIT_SECONDS: f32 = 2.0;

/// A context being eased towards a real window of its class, by a growing share at each of
/// its `blocks` blocks (the seam join keeps the easing from popping).
#[derive(Clone)]
struct Easing {
    /// A class or style change (not a keep-alive).
    change: bool,
    /// A class change: its blocks are the change's, not the class's pace, and get the
    /// change's guidance (a style change within a class does not).
    new_class: bool,
    anchor: Vec<f32>,
    step: usize,
    blocks: usize,
    /// The block by which the easing reaches its full `strength`.
    reach: usize,
    strength: f32,
}

/// The steering's state over a take.
#[derive(Clone)]
pub(super) struct Steering {
    /// The seed windows, the same all take long: shared by the copies a resumable rollout keeps.
    bank: Arc<AnchorBank>,
    pace: RecentPace,
    easing: Option<Easing>,
    /// The class the context was last anchored on, cut to (or started from).
    context_class: Option<usize>,
    /// The style of the window the context last changed class or style on (or started
    /// from), if known.
    context_style: Option<usize>,
    /// The seed window the take starts from, as (class, its index among the class's
    /// windows): leaning on it again from a similar pose replays the start of the take.
    start_window: Option<(usize, usize)>,
    since_anchor: usize,
    /// Blocks the change from a file start into the first segment's class has waited for the
    /// body to stand up ([`POSTURE_GAP`]); `None` once the take is in a class of its timeline,
    /// or when it starts from a seed.
    posture_wait: Option<usize>,
    /// [`POSTURE_WAIT_SECONDS`] in blocks.
    posture_wait_blocks: usize,
    /// Blocks steered since the last one of a class change (an anchored change's switch or
    /// easing, the first block of a class cut or blended to without one): 0 when the last
    /// block steered was one, `usize::MAX` before any. A change's [`CHANGE_SETTLE_SECONDS`]
    /// and [`CHANGE_PACE_SECONDS`] count from it.
    since_change: usize,
    settle_blocks: usize,
    change_pace_blocks: usize,
    last_anchor: Option<usize>,
    anchors: StdRng,
    keep_alive: bool,
    /// Per class, the guidance its blocks are made with.
    class_strengths: Vec<f32>,
    /// Per class, whether a class change keeps its own guidance: a class whose guidance
    /// steers it away from another ([`crate::model::spec::ModelSpec::class_contrasts`], not
    /// where the take asks for plain conditioning, strength 1, which has no push to do a
    /// change's work), or one lively already at its own
    /// ([`crate::model::spec::ModelSpec::lively_classes`]).
    keeps_own_guidance: Vec<bool>,
    dim: usize,
    block_len: usize,
}

impl Steering {
    pub fn new(model: &GlocalModel, opts: &GenerateOptions) -> Self {
        let spec = &model.spec;
        let start_window = match &opts.init {
            InitPose::SeedIndex(i) => model.seeds.get(*i).map(|s| (s.class, model.seeds[..*i].iter().filter(|o| o.class == s.class).count())),
            InitPose::SeedClass { class, variant } => spec.class_index(class).ok().and_then(|c| Some((c, model.class_seed_index(c, *variant)?))),
            InitPose::File { .. } => None,
        };
        let bank = AnchorBank::new(model);
        Self {
            pace: RecentPace::new(model),
            easing: None,
            context_class: start_window.map(|(class, _)| class),
            context_style: start_window.and_then(|(class, k)| *bank.styles.get(class)?.get(k)?),
            start_window,
            bank: Arc::new(bank),
            since_anchor: 0,
            posture_wait: matches!(opts.init, InitPose::File { .. }).then_some(0),
            posture_wait_blocks: blocks_in(POSTURE_WAIT_SECONDS, spec),
            since_change: usize::MAX,
            settle_blocks: blocks_in(CHANGE_SETTLE_SECONDS, spec),
            change_pace_blocks: blocks_in(CHANGE_PACE_SECONDS, spec),
            last_anchor: None,
            anchors: anchor_draws(opts.seed),
            keep_alive: opts.keep_alive,
            class_strengths: (0..spec.classes.len()).map(|c| opts.class_strength_of(spec, c)).collect(),
            // Guidance only pushes a class from its pair when it guides at all (not at 1).
            keeps_own_guidance: spec
                .contrast_indices()
                .iter()
                .enumerate()
                .map(|(c, pair)| pair.is_some() && opts.class_strength_of(spec, c) != 1.0 || spec.lively_classes.contains(&spec.classes[c]))
                .collect(),
            dim: spec.layout.dim(),
            block_len: spec.block_len,
        }
    }

    /// Steers the block `plan` asks for: eases `input` (its context, normalised) as the plan
    /// and the take so far (`sparse`, normalised) ask, and returns the block's guidance.
    pub fn block(&mut self, plan: &BlockPlan, input: &mut [f32], sparse: &[f32]) -> f32 {
        let (dim, t) = (self.dim, self.block_len);
        // A style asked for by name is held to its own clips' pace.
        let key = (plan.target, plan.style);
        let scale = self.pace.scale(key);
        let typical = self.bank.typical[plan.target] * scale;
        let motion = pose_motion(input, dim) / typical.max(f32::EPSILON);
        let may_keep_alive = self.keep_alive && self.since_anchor >= KEEP_ALIVE_GAP;
        let recent = self.pace.of(key);
        // Slow when either measure says so (a drifting stand reads fast with its travel in);
        // fast by the whole body's speed, which the finished take keeps, but soon after a
        // class change only while the block still moves ([`CHANGE_PACE_SECONDS`]).
        let slow_take = recent.is_some_and(|p| p.whole.min(p.pose) < PACE_SLOW);
        let fast_take = recent.is_some_and(|p| p.whole > PACE_FAST) && (self.since_change >= self.change_pace_blocks || motion >= STALL_BELOW);
        let slow_block = motion < STALL_BELOW && !recent.is_some_and(|p| p.whole > RESTING_ABOVE);
        let rushing = motion > RUSH_ABOVE || fast_take;
        let stalled = may_keep_alive && (slow_block || slow_take || rushing);
        // A style asked for by name that the context is not in is changed to as a class is,
        // where the class has windows of it.
        let restyling = plan.style.is_some_and(|s| self.context_style != Some(s) && self.bank.has_style(plan.target, s));
        let new_class = plan.ease_blocks > 0 && self.context_class != Some(plan.target);
        let switching = new_class || (plan.ease_blocks > 0 && restyling);
        let changing = new_class || self.easing.as_ref().is_some_and(|e| e.new_class);
        // A cut or a blend has no easing: its change is the first block of the new class, which
        // still carries the class before (its pace the change's, not the class's).
        let cut = plan.ease_blocks == 0 && self.context_class != Some(plan.target);
        if cut {
            (self.context_class, self.context_style) = (Some(plan.target), plan.style);
        }
        let settling = !changing && plan.ease_blocks > 0 && self.since_change < self.settle_blocks;
        self.since_change = if changing || cut { 0 } else { self.since_change.saturating_add(1) };
        // A loop is broken even while a keep-alive eases: leaning on a window the take leant
        // on before, from a similar pose, replays that stretch. (While a class change eases,
        // the search would decide nothing.)
        let leaning = self.easing.as_ref().is_some_and(|e| !e.change);
        // The half block before the last is compared too: the next seam join still moves
        // the last half, so a loop can differ from its earlier turn there alone (with
        // keep-alive's windows drawn near the take, tried and not kept, `all`'s ten-minute
        // phoning repeated one 3 s stretch exactly for eight minutes unseen).
        let settled = &sparse[..sparse.len().saturating_sub(t / 2 * dim)];
        let repeats = |poses: &[f32]| repeats_earlier(poses, &self.bank.spread, t / 2, t, LOOP_TOLERANCE * scale * self.bank.typical_step[plan.target]);
        let looping = may_keep_alive && (self.easing.is_none() || leaning) && (repeats(sparse) || repeats(settled));
        // A class change waits for the easing into the class before it, unless that would
        // leave its segment, longer than a block, no block of its own: a 6 s walk at pace 2
        // between two segments at pace 0.5 has one block, which the first segment's easing
        // still held, and never walked. (A segment a block long may go by: a 2 s sittingdown
        // anchored between a walk and a sit left the sit's end less seated.)
        let eased_into_another = switching && plan.lasting && self.easing.as_ref().is_some_and(|e| e.change && plan.run <= e.blocks - e.step);
        // A file's poses are given, so the change into the first segment has no time before
        // its boundary: anchored at once, a floor sit stood up into a walk within the seam
        // join, the hips climbing 2.5 m/s with a foot off the floor. Guided towards the
        // class, the network stands up through its feet by itself; the easing waits for it
        // ([`POSTURE_WAIT_SECONDS`] at most). Not on a seed start: there the wait cost the
        // class control after another class's seed (DESIGN, "A file start stands up").
        if !new_class {
            self.posture_wait = None;
        }
        let waiting = new_class && self.posture_wait.is_some_and(|w| w < self.posture_wait_blocks) && self.bank.posture_gap(plan.target, input) > POSTURE_GAP;
        if waiting {
            self.posture_wait = self.posture_wait.map(|w| w + 1);
        } else if eased_into_another || (self.easing.is_none() && (switching || stalled || looping)) || (leaning && looping && !switching) {
            self.posture_wait = None;
            // A take slow for seconds starts its next block from (nearly) a lively window, one
            // block only: twice from the same context gives the same block twice.
            let (blocks, strength) = if switching {
                (plan.ease_blocks, 1.0)
            } else if slow_take {
                (1, self.anchors.random_range(SLOW_TAKE_STRENGTH))
            } else {
                (KEEP_ALIVE_EASE, self.anchors.random_range(KEEP_ALIVE_STRENGTH))
            };
            // A loop is broken by any other window; a lively one thrown into a still take
            // made Bandai's bowing burst to 3-4x its typical motion.
            let wanted = if switching || !stalled { 0.0..=f32::INFINITY } else if rushing { 0.0..=typical } else { typical..=f32::INFINITY };
            let start = self.start_window.and_then(|(class, k)| (class == plan.target).then_some(k));
            let avoid: Vec<usize> = self.last_anchor.into_iter().chain(start).collect();
            self.easing = self.bank.pick(plan.target, plan.style, wanted, &mut self.anchors, &avoid).map(|(k, anchor)| {
                if switching {
                    self.context_style = self.bank.styles[plan.target][k];
                }
                self.last_anchor = Some(k);
                // A class change ends on the new class's window. A keep-alive leans towards its
                // window by its random strength (0.6-1.0): a take far below its class's motion
                // by its last block (a third less had kept a stalled h36m phoning take at
                // 0.2-0.5x its typical motion however often it leant), any other a block later
                // (leaning every slow take that hard raised Bandai's mean jerk from 1.21x to
                // 1.34x real). A loop the lean makes is caught by [`repeats_earlier`].
                let reach = if switching { (blocks - 1).max(1) } else if motion < FROZEN_BELOW || slow_take { blocks } else { blocks + 1 };
                Easing { change: switching, new_class, anchor, step: 0, blocks, reach, strength }
            });
            self.context_class = Some(plan.target);
            self.since_anchor = 0;
        }
        self.since_anchor += 1;
        if let Some(e) = self.easing.as_mut() {
            e.step += 1;
            let alpha = (e.strength * e.step as f32 / e.reach as f32).min(1.0);
            input.iter_mut().zip(&e.anchor).for_each(|(v, a)| *v += alpha * (a - *v));
            if e.step == e.blocks {
                self.easing = None;
            }
        }
        // A class change is where the prior must beat the context's momentum most: its blocks
        // get at least the stronger guidance of [`CHANGE_CLASS_STRENGTH`]. A class steered
        // away from another keeps its own: the push away from its pair does that work, and
        // with both `all`'s sidesteps skipped, both feet up for 4-5 frames a stride. So does a
        // class lively already: `all`'s bow, pushed, pitched and shifted back until it read
        // as walking backwards (recognised 96 of 128 takes 2 s after a change, 110 kept).
        let own = self.class_strengths[plan.target];
        let boosted = (changing || settling) && !self.keeps_own_guidance[plan.target];
        let strength = if boosted { own.max(CHANGE_CLASS_STRENGTH) } else { own };
        // A stalled block's class is urged on too: guidance scaled by how far it fell short.
        if !self.keep_alive || changing {
            strength
        } else if fast_take {
            strength.min(1.0)
        } else if slow_block || slow_take {
            strength * (STALL_BELOW / motion.max(f32::EPSILON)).clamp(1.0, STALLED_GUIDANCE_GAIN)
        } else {
            strength
        }
    }

    /// Draws the anchor windows from `seed` from here on (a segment with its own seed).
    pub fn reseed(&mut self, seed: u64) {
        self.anchors = anchor_draws(seed);
    }

    /// The block GloGen made of it, after the pose before it (both normalised): what the
    /// take's pace is measured on. A class change's blocks are not the class's pace: a bow
    /// after a run came out of the run's momentum travelling a metre, and its first six
    /// seconds read 3.4x bowing's speed, so keep-alive leant the bow on its stillest windows
    /// and it stood.
    pub fn record(&mut self, model: &GlocalModel, plan: &BlockPlan, previous: &[f32], block: &[f32]) {
        if self.keep_alive {
            let key = (self.since_change > 0).then_some((plan.target, plan.style));
            self.pace.push(model, key, &raw_block(&model.spec, previous, block));
        }
    }

    /// Holds a segment to its pace: when its last seconds ran faster than [`PACE_FAST`] times
    /// its class's clips (or [`STYLE_PACE_ABOVE`] times those of a style calmer than its
    /// class that it names), the block just appended to `sparse` (normalised) moves that much
    /// less from the pose before it, every step scaled by the same share, so it starts where
    /// the join put it and keeps its own shape, smaller. A class's pace is held only
    /// [`CHANGE_PACE_SECONDS`] after a class change, as its lean is: `all`'s bye cut to from
    /// a guide, whose momentum its first seconds carry, was held to a still wave (0.56x its
    /// class's speed from 6 s on).
    pub fn hold_pace(&mut self, model: &GlocalModel, plan: &BlockPlan, sparse: &mut [f32]) {
        if !self.keep_alive {
            return;
        }
        let key = (plan.target, plan.style);
        let Some(pace) = self.pace.of(key) else { return };
        let above = if self.pace.scale(key) < 1.0 {
            STYLE_PACE_ABOVE
        } else if self.since_change >= self.change_pace_blocks {
            PACE_FAST
        } else {
            return;
        };
        if pace.whole <= above {
            return;
        }
        let share = (above / pace.whole).max(PACE_DAMPING_FLOOR);
        let dim = self.dim;
        let start = sparse.len() - self.block_len * dim;
        let mut poses = raw_block(&model.spec, &sparse[start - dim..start], &sparse[start..]);
        damp_block(&mut poses, dim, share);
        self.pace.amend_last(model, &poses);
        let block = &mut poses[dim..];
        model.spec.sparse_norm.normalize(block);
        sparse[start..].copy_from_slice(block);
    }

    /// The last block recorded, again as the next block's seam join left it (a two-sided
    /// join moves its last half): the pace is measured on the poses the take keeps.
    pub fn amend_last(&mut self, model: &GlocalModel, previous: &[f32], block: &[f32]) {
        if self.keep_alive {
            self.pace.amend_last(model, &raw_block(&model.spec, previous, block));
        }
    }
}

/// The blocks `seconds` of sparse poses take (at pace 1), rounded up.
fn blocks_in(seconds: f32, spec: &crate::model::spec::ModelSpec) -> usize {
    (seconds * spec.fps / (spec.stride * spec.block_len) as f32).ceil() as usize
}

/// The random stream anchor windows are drawn from, for a variation seed.
fn anchor_draws(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed ^ 0xA1C4_0125)
}

struct AnchorBank {
    /// Per class: (normalised window, its motion), in seed-bank order.
    windows: Vec<Vec<(Vec<f32>, f32)>>,
    /// Per class: each window's style, if known.
    styles: Vec<Vec<Option<usize>>>,
    /// Per class: the mean motion of its windows (normalised features).
    typical: Vec<f32>,
    /// Per class: the mean step between its windows' poses in the skeleton's units, which
    /// loops are judged against: in normalised features a joint that barely moves against
    /// the hips (`all`'s shoulders spread 5-13 mm) counts its millimetres as much as a hand
    /// its decimetres, and a ten-minute walk that repeated itself for 12 s within 5 mm read
    /// as 1.3x the tolerance.
    typical_step: Vec<f32>,
    /// The sparse features' spread, which takes a normalised difference back to the
    /// skeleton's units.
    spread: Vec<f32>,
    /// Per class: the mean hips height of its windows, in the skeleton's units.
    hips: Vec<f32>,
    /// The root height's mean, which with its spread takes a context's back to the
    /// skeleton's units ([`hips_height`]).
    root_mean: f32,
}

impl AnchorBank {
    fn new(model: &GlocalModel) -> Self {
        let dim = model.spec.layout.dim();
        let mut windows = vec![Vec::new(); model.spec.classes.len()];
        let mut styles = vec![Vec::new(); model.spec.classes.len()];
        for seed in &model.seeds {
            let mut window = seed.features.clone();
            model.spec.sparse_norm.normalize(&mut window);
            if let Some(w) = windows.get_mut(seed.class) {
                let motion = pose_motion(&window, dim);
                w.push((window, motion));
                styles[seed.class].push(seed.style);
            }
        }
        let spread = model.spec.sparse_norm.std.clone();
        let mean = |values: Vec<f32>| if values.is_empty() { 0.0 } else { values.iter().sum::<f32>() / values.len() as f32 };
        let typical = windows.iter().map(|w| mean(w.iter().map(|(_, m)| *m).collect())).collect();
        let typical_step = windows.iter().map(|w| mean(w.iter().map(|(window, _)| skeleton_step(window, &spread)).collect())).collect();
        let root_mean = model.spec.sparse_norm.mean[0];
        let height = |window: &[f32]| mean(window.chunks_exact(dim).map(|pose| hips_height(root_mean, spread[0], pose)).collect());
        let hips = windows.iter().map(|w| mean(w.iter().map(|(window, _)| height(window)).collect())).collect();
        Self { windows, styles, typical, typical_step, spread, hips, root_mean }
    }

    /// How far below `class`'s own height the last pose of the normalised `context` holds the
    /// hips, as a share of it (negative above it).
    fn posture_gap(&self, class: usize, context: &[f32]) -> f32 {
        let Some(&own) = self.hips.get(class).filter(|h| **h > f32::EPSILON) else { return 0.0 };
        let Some(pose) = context.chunks_exact(self.spread.len()).last() else { return 0.0 };
        (own - hips_height(self.root_mean, self.spread[0], pose)) / own
    }

    /// Whether `class` has a window of `style`.
    fn has_style(&self, class: usize, style: usize) -> bool {
        self.styles.get(class).is_some_and(|s| s.contains(&Some(style)))
    }

    /// A random window of `class` whose motion is in `wanted` (a keep-alive wants a window
    /// that moves: re-anchoring a stalled take on a still window of the class keeps it still;
    /// a rushing one wants a calm window), of `style` where some of those are, none of `avoid`
    /// where there is a choice, with its index.
    fn pick(&self, class: usize, style: Option<usize>, wanted: std::ops::RangeInclusive<f32>, rng: &mut StdRng, avoid: &[usize]) -> Option<(usize, Vec<f32>)> {
        let windows: Vec<(usize, &(Vec<f32>, f32))> = self.windows.get(class)?.iter().enumerate().collect();
        let fitting: Vec<&(usize, &(Vec<f32>, f32))> = windows.iter().filter(|(_, (_, m))| wanted.contains(m)).collect();
        let pool: Vec<_> = if fitting.is_empty() { windows.iter().collect() } else { fitting };
        let styled: Vec<_> = pool.iter().copied().filter(|(k, _)| style.is_some() && self.styles[class][*k] == style).collect();
        let pool = if styled.is_empty() { pool } else { styled };
        let fresh: Vec<_> = pool.iter().filter(|(k, _)| !avoid.contains(k)).collect();
        let &(k, (window, _)) = if fresh.is_empty() { pool.first().copied()? } else { *fresh[rng.random_range(0..fresh.len())] };
        Some((k, window.clone()))
    }
}

/// The height of the hips (the root) of a normalised pose, by the root height's normalisation
/// (`mean`, `spread`).
fn hips_height(mean: f32, spread: f32, pose: &[f32]) -> f32 {
    mean + pose[0] * spread
}

/// A block of raw poses after the pose before it (`poses`, `dim` features each, that pose
/// first) moving `share` as far: positions come `share` of the way from the pose before, the
/// root's steps over the ground and turns (features 1-3, velocities) are scaled by `share`.
fn damp_block(poses: &mut [f32], dim: usize, share: f32) {
    let (previous, block) = poses.split_at_mut(dim);
    for pose in block.chunks_exact_mut(dim) {
        for (f, (v, p)) in pose.iter_mut().zip(&*previous).enumerate() {
            *v = if (1..ROOT_FEATURES).contains(&f) { share * *v } else { p + share * (*v - p) };
        }
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
    mean_step(window, dim, |a, b| distance2(&a[ROOT_FEATURES..], &b[ROOT_FEATURES..]))
}

/// The mean step between consecutive poses of a normalised window, over the joints in the
/// skeleton's units.
fn skeleton_step(window: &[f32], spread: &[f32]) -> f32 {
    mean_step(window, spread.len(), |a, b| joint_distance2(a, b, spread))
}

/// The mean distance between consecutive poses (`dim` features each) of `window`, by the
/// squared distance `distance2`.
fn mean_step(window: &[f32], dim: usize, distance2: impl Fn(&[f32], &[f32]) -> f32) -> f32 {
    let poses: Vec<&[f32]> = window.chunks_exact(dim).collect();
    let steps = poses.windows(2).map(|p| distance2(p[0], p[1]).sqrt());
    steps.sum::<f32>() / (poses.len().max(2) - 1) as f32
}

/// The squared distance between two feature vectors.
fn distance2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum()
}

/// The squared distance between the joints of two normalised poses, in the skeleton's units
/// (`spread`: the features' standard deviations).
fn joint_distance2(a: &[f32], b: &[f32], spread: &[f32]) -> f32 {
    let joints = ROOT_FEATURES..a.len();
    a[joints.clone()].iter().zip(&b[joints.clone()]).zip(&spread[joints]).map(|((a, b), s)| ((a - b) * s).powi(2)).sum()
}

/// Whether the last `span` poses of `sparse` (normalised) repeat a stretch of the take at
/// least `min_lag` poses earlier: the root-mean-square distance between the joints of
/// corresponding poses, in the skeleton's units (`spread`: the features' standard
/// deviations), is within `tolerance`. Without the lag a still take would match the poses
/// just before it and count as a loop. Each candidate stops at the first pose that puts it
/// out of reach, so the search over the whole take costs about one pose comparison per
/// earlier pose.
fn repeats_earlier(sparse: &[f32], spread: &[f32], span: usize, min_lag: usize, tolerance: f32) -> bool {
    let dim = spread.len();
    let poses = sparse.len() / dim;
    if span == 0 || poses < span + min_lag.max(span) {
        return false;
    }
    let pose = |k: usize| &sparse[k * dim..(k + 1) * dim];
    let recent = poses - span;
    let budget = tolerance * tolerance * span as f32;
    (0..=recent - min_lag.max(span)).any(|start| {
        let mut total = 0.0;
        (0..span).all(|i| {
            total += joint_distance2(pose(start + i), pose(recent + i), spread);
            total <= budget
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A class change's guidance holds over its easing and the [`CHANGE_SETTLE_SECONDS`] after
    /// it (two h36m blocks), then falls back to the take's own.
    #[test]
    fn a_class_change_keeps_its_guidance_while_it_settles() {
        let model = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/h36m")).unwrap();
        let spec = &model.spec;
        let (walking, sitting) = (spec.class_index("walking").unwrap(), spec.class_index("sitting").unwrap());
        let opts = GenerateOptions { init: InitPose::SeedClass { class: "walking".into(), variant: 0 }, keep_alive: false, ..Default::default() };
        let mut steering = Steering::new(&model, &opts);
        let mut context = model.seed_of_class(walking, 0).unwrap().features.clone();
        spec.sparse_norm.normalize(&mut context);
        let plan = BlockPlan { class: model.class_vector(sitting), target: sitting, ease_blocks: 2, keys: Vec::new(), run: 6, lasting: true, style: None };
        let strengths: Vec<f32> = (0..6).map(|_| steering.block(&plan, &mut context.clone(), &context)).collect();
        let (held, own) = (CHANGE_CLASS_STRENGTH.max(spec.class_strength), spec.class_strength);
        assert!(held > own, "the change's guidance {held} is no stronger than the model's {own}");
        assert_eq!(strengths, [held, held, held, held, own, own], "two easing blocks, two settling, then the take's own");
    }

    /// A change into a class steered away from another (`all`'s sidesteps) or into one lively
    /// already at its own guidance (`all`'s bow) keeps the class's own guidance; a change into
    /// any other class of the same model, or into a steered one in a take made with plain
    /// conditioning, gets the change's.
    #[test]
    fn a_class_steered_apart_or_lively_keeps_its_own_guidance_through_a_change() {
        let model = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/all")).unwrap();
        let spec = &model.spec;
        let sitting = spec.class_index("sitting").unwrap();
        let guided = GenerateOptions { init: InitPose::SeedClass { class: "sitting".into(), variant: 0 }, keep_alive: false, ..Default::default() };
        let plain = GenerateOptions { class_strength: Some(1.0), ..guided.clone() };
        let first_strength = |opts: &GenerateOptions, target: &str| {
            let target = spec.class_index(target).unwrap();
            let mut steering = Steering::new(&model, opts);
            let mut context = model.seed_of_class(sitting, 0).unwrap().features.clone();
            spec.sparse_norm.normalize(&mut context);
            let plan = BlockPlan { class: model.class_vector(target), target, ease_blocks: 2, keys: Vec::new(), run: 6, lasting: true, style: None };
            steering.block(&plan, &mut context.clone(), &context)
        };
        assert!(spec.class_contrasts.contains_key("walk-left"), "models/all/model.json steers walk-left apart");
        assert_eq!(first_strength(&guided, "walk-left"), spec.class_strength_of(spec.class_index("walk-left").unwrap()));
        assert_eq!(first_strength(&guided, "walk-back"), CHANGE_CLASS_STRENGTH.max(spec.class_strength));
        // Asked for plain conditioning, no push is made: the change's guidance as for any class.
        assert_eq!(first_strength(&plain, "walk-left"), CHANGE_CLASS_STRENGTH);
        assert!(spec.lively_classes.contains("bow"), "models/all/model.json finds bow lively at its own guidance");
        assert_eq!(first_strength(&guided, "bow"), spec.class_strength_of(spec.class_index("bow").unwrap()));
        assert_eq!(first_strength(&plain, "bow"), 1.0);
    }

    /// A take asking for a style its start window is not in eases onto a window of that
    /// style of its class, as onto another class's, with the take's own guidance (a style
    /// change within a class is not a class change); asking for the start window's own style,
    /// or for none, it does not.
    #[test]
    fn a_style_the_context_is_not_in_is_eased_onto() {
        let model = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/all")).unwrap();
        let spec = &model.spec;
        let byebye = spec.class_index("byebye").unwrap();
        let style = |name: &str| spec.styles.iter().position(|s| s == name);
        let opts = GenerateOptions { init: InitPose::SeedClass { class: "byebye".into(), variant: 0 }, keep_alive: false, ..Default::default() };
        let start = model.seed_of_class(byebye, 0).unwrap();
        assert_eq!(start.style, style("active"), "models/all/seeds.json: byebye's first window is active's");
        let first_block = |asked: Option<usize>| {
            let mut steering = Steering::new(&model, &opts);
            let mut context = start.features.clone();
            spec.sparse_norm.normalize(&mut context);
            let plan = BlockPlan { class: model.class_vector(byebye), target: byebye, ease_blocks: 2, keys: Vec::new(), run: 6, lasting: true, style: asked };
            let strength = steering.block(&plan, &mut context.clone(), &context);
            (steering.easing.is_some(), steering.context_style, strength)
        };
        assert_eq!(first_block(style("happy")), (true, style("happy"), spec.class_strength_of(byebye)));
        assert_eq!(first_block(style("active")), (false, style("active"), spec.class_strength_of(byebye)));
        assert_eq!(first_block(None).0, false);
    }
}
