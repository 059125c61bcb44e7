//! The given frames of a take started from a motion file, kept as given: the take shows the
//! file's own frames over its starting poses, joined onto the generated motion after them.

use glam::Vec3;

use super::plan::TakeConstraint;
use super::raised_cosine;
use crate::data::features::FeatureLayout;
use crate::motion::{solve_local_poses, Motion};

/// Seconds over which the difference between a given start and the generated take fades
/// out after the start's last frame.
const GIVEN_BLEND_SECONDS: f32 = 0.5;

/// The given frames of a file start as a constraint: the finished take shows them as given
/// (after the foot lock and the other constraints), and the difference they make at their
/// last frame fades out over the frames after it, ending before `until` (the first key).
pub(super) struct GivenStart {
    pub frames: Vec<Vec3>,
    pub until: usize,
}

impl TakeConstraint for GivenStart {
    fn on_finished(&self, motion: Motion, layout: &FeatureLayout) -> Motion {
        let (j, frames) = (layout.joints(), motion.frames());
        let given = self.frames.len() / j;
        if given == 0 || frames <= given {
            return motion;
        }
        let mut positions = motion.positions().to_vec();
        let last = given - 1;
        let residual: Vec<Vec3> = (0..j).map(|k| self.frames[last * j + k] - positions[last * j + k]).collect();
        positions[..given * j].copy_from_slice(&self.frames);
        let blend = ((GIVEN_BLEND_SECONDS * motion.fps).round() as usize).min(self.until.saturating_sub(given));
        let end = frames.min(given + blend);
        for f in given..end {
            let w = raised_cosine((f - last) as f32 / (blend + 1) as f32);
            positions[f * j..(f + 1) * j].iter_mut().zip(&residual).for_each(|(p, r)| *p += w * *r);
        }
        let skeleton = motion.skeleton.clone();
        let Some(mut poses) = motion.local_poses else { return Motion::from_positions(skeleton, motion.fps, positions) };
        poses.splice(0..end, solve_local_poses(&skeleton, &positions[..end * j]));
        Motion::from_local_poses(skeleton, motion.fps, poses)
    }
}
