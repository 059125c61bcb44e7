//! The take's pace over its last few seconds, against its class's: what keeps a long
//! take's every stretch near its class's speed. Keep-alive's per-block test sees one block;
//! a gesture that rests a block and then rushes two passes it block by block and still runs
//! a ten-second stretch at 2.7x its class's speed (Bandai's bowing), and one that stalls
//! every other block sits at 0.4x (h36m's phoning). A segment that asks for a style keeps
//! the pace of that style's clips: a network's byebye moves about 2x between styles whose
//! clips differ 35x (sad 0.02 m/s, active 0.71).

use std::collections::VecDeque;

use crate::model::glocal::GlocalModel;

/// Seconds of the take the pace is measured over.
const PACE_SECONDS: f32 = 6.0;

/// The last few seconds' joint speed over the class's training speed, two ways.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pace {
    /// All joints, the body's travel over the ground included (what the finished take is
    /// measured by).
    pub whole: f32,
    /// The pose's own motion, without the travel: a standing network's body drifts over the
    /// floor, which the foot lock takes out (Bandai's guiding read 1.4x its class's speed
    /// with the travel in, where the finished take moved at 0.75x).
    pub pose: f32,
}

/// What a block's pace is held to: its class, and the style its segment asks for by name.
pub(super) type PaceKey = (usize, Option<usize>);

/// Per class, how far its joints move per sparse step at its training speed (with and
/// without travel), and the take's last blocks' own steps.
#[derive(Clone)]
pub(super) struct RecentPace {
    reference: Vec<(f32, f32)>,
    /// Per class and style, its speed against the class's
    /// ([`crate::model::spec::ModelSpec::style_pace`]).
    style_paces: Vec<Vec<Option<f32>>>,
    /// The last blocks' steps, each with its key (none for a block of a class change).
    blocks: VecDeque<(Option<PaceKey>, f32, f32)>,
    span: usize,
}

impl RecentPace {
    pub fn new(model: &GlocalModel) -> Self {
        let spec = &model.spec;
        let step_seconds = spec.stride as f32 / spec.fps;
        // The class's training speed (all joints, travel included) per sparse step, and the
        // share of it that is the pose's own motion in the class's seed windows.
        let mut sums = vec![(0.0f32, 0.0f32); spec.classes.len()];
        for seed in &model.seeds {
            if let Some((whole, pose)) = sums.get_mut(seed.class) {
                *whole += spec.layout.mean_joint_step(&seed.features);
                *pose += spec.layout.mean_pose_step(&seed.features);
            }
        }
        let reference = sums
            .iter()
            .zip(&spec.class_speed)
            .map(|(&(whole, pose), speed)| {
                let step = speed * step_seconds;
                (step, if whole > 0.0 { step * pose / whole } else { 0.0 })
            })
            .collect();
        let block_seconds = step_seconds * spec.block_len as f32;
        let span = (PACE_SECONDS / block_seconds).round().max(1.0) as usize;
        let style_paces = (0..spec.classes.len()).map(|c| (0..spec.styles.len()).map(|s| spec.style_pace(c, s)).collect()).collect();
        Self { reference, style_paces, blocks: VecDeque::with_capacity(span + 1), span }
    }

    /// How fast `key`'s blocks should move against their class's training speed: 1, or the
    /// speed of the style asked for.
    pub fn scale(&self, (class, style): PaceKey) -> f32 {
        style.and_then(|s| self.style_paces.get(class)?.get(s).copied().flatten()).unwrap_or(1.0)
    }

    /// One more block of `key` (none for a block of a class change, whose pace is the
    /// change's, not the class's): its sparse poses (raw features) after the pose before it.
    pub fn push(&mut self, model: &GlocalModel, key: Option<PaceKey>, poses: &[f32]) {
        self.blocks.push_back(block_steps(model, key, poses));
        if self.blocks.len() > self.span {
            self.blocks.pop_front();
        }
    }

    /// The last block again, as a two-sided seam join left it.
    pub fn amend_last(&mut self, model: &GlocalModel, poses: &[f32]) {
        if let Some(last) = self.blocks.back_mut() {
            *last = block_steps(model, last.0, poses);
        }
    }

    /// The last [`PACE_SECONDS`]' pace against `key`'s, once they are all of `key`.
    pub fn of(&self, key: PaceKey) -> Option<Pace> {
        let (whole, pose) = *self.reference.get(key.0)?;
        let scale = self.scale(key);
        let (whole, pose) = (whole * scale, pose * scale);
        let full = self.blocks.len() == self.span && self.blocks.iter().all(|(k, _, _)| *k == Some(key));
        if !full || whole <= 0.0 || pose <= 0.0 {
            return None;
        }
        let n = self.span as f32;
        Some(Pace { whole: self.blocks.iter().map(|b| b.1).sum::<f32>() / n / whole, pose: self.blocks.iter().map(|b| b.2).sum::<f32>() / n / pose })
    }
}

/// A block of `key` as the pace keeps it: its mean joint step with the body's travel and
/// without.
fn block_steps(model: &GlocalModel, key: Option<PaceKey>, poses: &[f32]) -> (Option<PaceKey>, f32, f32) {
    let layout = &model.spec.layout;
    (key, layout.mean_joint_step(poses), layout.mean_pose_step(poses))
}
