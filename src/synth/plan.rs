//! The plan of a take: where its segments, transitions and keys fall among GloGen's sparse
//! poses, what each block is asked for ([`BlockPlan`]), and the constraints applied to the
//! take stage by stage ([`TakeConstraint`]).

use std::ops::Range;

use anyhow::Result;
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::options::{GenerateOptions, Transition};
use super::smoothstep;
use crate::data::features::FeatureLayout;
use crate::model::block::BlockWorkspace;
use crate::model::glocal::GlocalModel;
use crate::model::glogen::GloGen;
use crate::model::spec::ModelSpec;
use crate::motion::contacts::FootContacts;
use crate::motion::Motion;

/// A segment's place in the generated take.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentSpan {
    pub class: usize,
    pub name: String,
    pub start_frame: usize,
    pub end_frame: usize,
    /// The style the segment asks for by name (none where it takes its class's usual one):
    /// exports name it beside the class (`walking/tired`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub style: Option<String>,
}

impl SegmentSpan {
    /// The segment as the timeline names it: `CLASS` or `CLASS/STYLE`.
    pub fn label(&self) -> String {
        super::timeline::spelled(&self.name, self.style.as_deref())
    }
}

/// What one GloGen block is asked for, decided from the timeline before the rollout.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockPlan {
    /// The class vector: one class, or a blend of two inside a transition.
    pub class: Vec<f32>,
    /// The class the block belongs to (the heavier of a blend): anchoring and keep-alive aim
    /// at it.
    pub target: usize,
    /// Blocks over which a change into `target` eases the context (0: no anchoring).
    pub ease_blocks: usize,
    /// The keys whose sparse pose this block produces (indices into the placed keys).
    pub keys: Vec<usize>,
    /// Blocks from this one on that aim at `target` (this one included): a class change
    /// that waited for the easing before it would leave a short segment none.
    pub run: usize,
    /// The block's segment holds more sparse poses than a block: an activity, not a passing
    /// moment (h36m's 2 s sittingdown before a sit) that a change may let go by.
    pub lasting: bool,
    /// The style the block's segment asks for by name (none where it leaves its class's usual
    /// one): keep-alive keeps the pace of that style's clips ([`crate::synth::pace`]).
    pub style: Option<usize>,
}

/// The sparse poses of each segment and where its boundaries fall.
pub(super) struct SparseTimeline {
    /// Segment index of each sparse pose (the seed block belongs to the first segment).
    pub(super) segment_of: Vec<usize>,
    /// Per segment: sparse poses and class.
    pub(super) counts: Vec<usize>,
    pub(super) classes: Vec<usize>,
    /// Per segment: the style it asks for by name, if it does (its poses are conditioned on
    /// its class's usual one otherwise, [`Self::plan`]).
    pub(super) asked_styles: Vec<Option<usize>>,
    /// Per segment: the transition into it in sparse steps, before and after its boundary
    /// (for the first segment, from the initial poses' class). Each half is counted at its
    /// own side's pace: a slow segment before a fast one would otherwise have its second of
    /// transition counted in the fast one's long steps and cover most of it.
    pub(super) transition_steps: Vec<(f32, f32)>,
    /// Frame of each sparse pose in the paced take.
    pub(super) frames: Vec<f64>,
    /// Seconds per sparse step at each segment's pace.
    pub(super) step_seconds: Vec<f32>,
}

impl SparseTimeline {
    pub(super) fn new(spec: &ModelSpec, opts: &GenerateOptions) -> Result<Self> {
        let classes = opts.timeline.validate(&spec.classes, opts.pace)?;
        let asked_styles = opts.timeline.validate_styles(&spec.styles, &spec.dataset)?;
        crate::synth::timeline::check_transition(opts.transition_seconds, "transition length")?;
        let step_of = |pace: f32| spec.stride as f32 * pace / spec.fps;
        let segments = &opts.timeline.segments;
        let paces: Vec<f32> = segments.iter().map(|s| s.pace.unwrap_or(opts.pace)).collect();
        // Sparse poses per segment: its duration over the time one sparse step takes at its pace.
        let counts: Vec<usize> = segments.iter().zip(&paces).map(|(s, &p)| ((s.seconds / step_of(p)).round() as usize).max(1)).collect();
        let segment_of: Vec<usize> = counts.iter().enumerate().flat_map(|(k, &n)| std::iter::repeat_n(k, n)).collect();
        let transition_steps = segments
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let half = if opts.transition == Transition::Cut { 0.0 } else { s.transition.unwrap_or(opts.transition_seconds) / 2.0 };
                let before = paces[k.saturating_sub(1)];
                (half / step_of(before), half / step_of(paces[k]))
            })
            .collect();
        let step_seconds = paces.iter().map(|&p| step_of(p)).collect();
        let mut frames = vec![0.0f64];
        for (i, &k) in segment_of.iter().enumerate() {
            frames.push(frames[i] + spec.stride as f64 * paces[k] as f64);
        }
        Ok(Self { segment_of, counts, classes, asked_styles, transition_steps, frames, step_seconds })
    }

    /// Sparse poses of the take, the seed's last pose included.
    pub(super) fn total(&self) -> usize {
        self.counts.iter().sum::<usize>() + 1
    }

    pub(super) fn segment_at(&self, i: usize) -> usize {
        self.segment_of[i.min(self.segment_of.len() - 1)]
    }

    /// Sparse index at which segment `k` begins.
    fn boundary(&self, k: usize) -> usize {
        self.counts[..k].iter().sum()
    }

    /// The boundary whose transition covers sparse pose `i`, and how far through it `i` is
    /// (0 at its start, 0.5 at the boundary, 1 at its end).
    fn transition_at(&self, i: usize) -> Option<(usize, f32)> {
        (1..self.counts.len()).find_map(|k| {
            let (before, after) = self.transition_steps[k];
            let from_boundary = i as f32 - self.boundary(k) as f32;
            let half = if from_boundary < 0.0 { before } else { after };
            let through = 0.5 + from_boundary / (2.0 * half);
            (half > 0.0 && (0.0..1.0).contains(&through)).then_some((k, through))
        })
    }

    /// The per-block plan: each block's class vector is the mean of its poses' class mixes,
    /// a pose inside a transition mixing the two classes by a smoothstep over it; the keys a
    /// block produces are those whose sparse pose (`key_poses`, by key) falls in it.
    pub(super) fn plan(&self, model: &GlocalModel, anchored: bool, key_poses: &[usize]) -> Vec<BlockPlan> {
        let t = model.spec.block_len;
        let blocks = self.total().saturating_sub(t).div_ceil(t);
        // The easing starts where the new segment's blocks do: its length is the transition's
        // after the boundary, twice over (the whole transition when both sides share a pace).
        let ease_of = |k: usize| {
            let after = self.transition_steps[k].1;
            if anchored && after > 0.0 {
                1 + (2.0 * after / t as f32).ceil() as usize
            } else {
                0
            }
        };
        // Each segment's style: its own, else its class's usual one (a model with styles).
        let styles: Vec<Option<usize>> = self.asked_styles.iter().zip(&self.classes).map(|(s, &c)| s.or_else(|| model.spec.usual_styles.get(c).copied())).collect();
        let mut plans = (0..blocks)
            .map(|b| {
                let mut class = vec![0.0; model.class_vector(0).len()];
                for i in t + b * t..t + (b + 1) * t {
                    let mix = match self.transition_at(i) {
                        Some((k, through)) => {
                            let s = smoothstep(through);
                            vec![(k - 1, 1.0 - s), (k, s)]
                        }
                        None => vec![(self.segment_at(i), 1.0)],
                    };
                    for (k, w) in mix {
                        for label in model.spec.label_indices(self.classes[k], styles[k]) {
                            if let Some(v) = class.get_mut(label) {
                                *v += w / t as f32;
                            }
                        }
                    }
                }
                let segment = self.segment_at(t + b * t + t / 2);
                let target = self.classes[segment];
                let ease_blocks = ease_of(segment);
                let produced = t + b * t..t + (b + 1) * t;
                let keys = (0..key_poses.len()).filter(|&k| produced.contains(&key_poses[k])).collect();
                BlockPlan { class, target, ease_blocks, keys, run: 1, lasting: self.counts[segment] > t, style: self.asked_styles[segment] }
            })
            .collect::<Vec<_>>();
        for b in (0..plans.len().saturating_sub(1)).rev() {
            if plans[b + 1].target == plans[b].target {
                plans[b].run = plans[b + 1].run + 1;
            }
        }
        plans
    }

    /// Frames of the paced take.
    pub(super) fn take_frames(&self) -> usize {
        paced_frames(&self.frames)
    }

    /// Where each segment falls in the paced take, each sparse pose at its nearest frame.
    pub(super) fn planned_spans(&self, spec: &ModelSpec) -> Vec<SegmentSpan> {
        let starts: Vec<usize> = self.frames.iter().map(|t| t.round() as usize).collect();
        self.segment_spans(spec, &starts, self.take_frames())
    }

    /// Where each segment falls in the paced take.
    fn segment_spans(&self, spec: &ModelSpec, interval_starts: &[usize], frames: usize) -> Vec<SegmentSpan> {
        let mut segments = Vec::new();
        let mut first_sparse = 0;
        let last = interval_starts.len() - 1;
        for (k, &n) in self.counts.iter().enumerate() {
            let start_frame = interval_starts[first_sparse.min(last)];
            let end_frame = if k + 1 == self.counts.len() { frames } else { interval_starts[(first_sparse + n).min(last)] };
            let class = self.classes[k];
            let style = self.asked_styles[k].and_then(|s| spec.styles.get(s).cloned());
            segments.push(SegmentSpan { class, name: spec.classes[class].clone(), start_frame, end_frame, style });
            first_sparse += n;
        }
        segments
    }
}

/// Frames of a take whose sparse poses fall at the paced frames `times`: the last one's,
/// rounded down, plus one.
pub(super) fn paced_frames(times: &[f64]) -> usize {
    times.last().copied().unwrap_or(0.0).floor() as usize + 1
}

/// A constraint on the take besides its classes, applied where generation can meet it: on
/// GloGen's sparse poses as each block comes out (the blocks the plan gives it), on the dense
/// positions of the paced take, and on the finished motion after the foot lock. Transitions,
/// anchoring and keep-alive act on each block's context instead ([`BlockPlan`],
/// `synth::steer`). Keys and a root path are constraints; features that pin more add theirs.
pub(super) trait TakeConstraint: Sync {
    /// Block `b` of `plans` has just been appended to `sparse` (normalised), made with
    /// `strength`; `glogen` and `ws` roll it on again where the constraint needs it.
    fn on_block(&self, _block: &PlannedBlock<'_>, _rollout: (&GloGen, &mut BlockWorkspace), _sparse: &mut [f32]) {}

    /// The paced take's positions (model units); returns what it could not do as asked.
    fn on_dense(&self, _positions: &mut [Vec3], _layout: &FeatureLayout, _fps: f32) -> Vec<String> {
        Vec::new()
    }

    /// The take's frames `on_dense` replaced with motion of the constraint's own (the gaps an
    /// in-betweener fills), which get the take's motion texture again.
    fn own_frames(&self) -> &[Range<usize>] {
        &[]
    }

    /// The finished take, after the foot lock.
    fn on_finished(&self, motion: Motion, _layout: &FeatureLayout) -> Motion {
        motion
    }

    /// The finished take's foot contacts, the lock's, for a constraint that put back frames
    /// of its own in `motion` (the take after every `on_finished`).
    fn on_contacts(&self, _motion: &Motion, _contacts: &mut FootContacts) {}
}

/// A constraint borrowed from where the take keeps it (held frames, which the rollout and the
/// finishing read besides).
impl<T: TakeConstraint + ?Sized> TakeConstraint for &T {
    fn on_block(&self, block: &PlannedBlock<'_>, rollout: (&GloGen, &mut BlockWorkspace), sparse: &mut [f32]) {
        (**self).on_block(block, rollout, sparse)
    }

    fn on_dense(&self, positions: &mut [Vec3], layout: &FeatureLayout, fps: f32) -> Vec<String> {
        (**self).on_dense(positions, layout, fps)
    }

    fn own_frames(&self) -> &[Range<usize>] {
        (**self).own_frames()
    }

    fn on_finished(&self, motion: Motion, layout: &FeatureLayout) -> Motion {
        (**self).on_finished(motion, layout)
    }

    fn on_contacts(&self, motion: &Motion, contacts: &mut FootContacts) {
        (**self).on_contacts(motion, contacts)
    }
}

/// A block of the rollout as the constraints see it: its plan, the guidance it was made with
/// and whether seams are joined.
pub(super) struct PlannedBlock<'a> {
    pub plan: &'a BlockPlan,
    pub strength: f32,
    pub join_seams: bool,
}
