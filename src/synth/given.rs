//! The given frames of a take started from a motion file, kept as given: the take shows the
//! file's own frames over its starting poses, joined onto the generated motion after them,
//! on one floor with them.

use glam::Vec3;

use super::options::GenerateOptions;
use super::plan::TakeConstraint;
use super::raised_cosine;
use crate::data::features::FeatureLayout;
use crate::model::glocal::GlocalModel;
use crate::motion::contacts::{foot_contacts, ContactConfig, FootContacts};
use crate::motion::{solve_local_poses, JointRoles, Motion};

/// Seconds over which the difference between a given start and the generated take fades
/// out after the start's last frame.
const GIVEN_BLEND_SECONDS: f32 = 0.5;

/// Whether a file start's given frames are kept as given: only at the pace they were
/// captured at (the first segment's pace 1).
pub(super) fn keeps_given_frames(opts: &GenerateOptions) -> bool {
    opts.timeline.segments.first().and_then(|s| s.pace).unwrap_or(opts.pace) == 1.0
}

/// How many frames at the start of a take from a motion file are the file's own: its given
/// frames and the fade after them (where no key comes sooner).
pub fn file_start_frames(model: &GlocalModel) -> usize {
    let spec = &model.spec;
    spec.observed_span() + 1 + blend_frames(spec.fps)
}

/// [`GIVEN_BLEND_SECONDS`] in frames at `fps`.
fn blend_frames(fps: f32) -> usize {
    (GIVEN_BLEND_SECONDS * fps).round() as usize
}

/// The floor of a file start's given frames as a constraint: the finished take raised or
/// lowered onto it ([`floor_gap`]), before the keys and the path place what they place in
/// the file's world (which is the given frames').
pub(super) struct GivenFloor {
    pub frames: Vec<Vec3>,
}

impl TakeConstraint for GivenFloor {
    fn on_finished(&self, motion: Motion, layout: &FeatureLayout) -> Motion {
        let given = self.frames.len() / layout.joints();
        if given == 0 || motion.frames() <= given {
            return motion;
        }
        let gap = floor_gap(&self.frames, &motion, given);
        motion.translated(Vec3::Y * gap)
    }
}

/// The given frames of a file start as a constraint: the finished take shows them as given
/// (after the foot lock and the other constraints), and the difference they make at their
/// last frame fades out over the frames after it, ending before `until` (the first key).
pub(super) struct GivenStart {
    pub frames: Vec<Vec3>,
    pub until: usize,
}

/// How a file start's given frames hand over to the take after them: the difference at their
/// last frame fades out over [`GIVEN_BLEND_SECONDS`] after it, ending before the first key.
pub(super) struct StartFade {
    last: usize,
    blend: usize,
    /// The first frame the fade leaves as it was.
    pub end: usize,
}

impl StartFade {
    /// The fade after `given` frames (at least one) of a take of `frames` at `fps`, its first
    /// key at frame `until`.
    pub fn new(given: usize, frames: usize, until: usize, fps: f32) -> Self {
        let blend = blend_frames(fps).min(until.saturating_sub(given));
        Self { last: given.saturating_sub(1), blend, end: frames.min(given + blend) }
    }

    /// Each frame after the given ones and how much of the difference it takes.
    pub fn weights(&self) -> impl Iterator<Item = (usize, f32)> + '_ {
        (self.last + 1..self.end).map(|f| (f, raised_cosine((f - self.last) as f32 / (self.blend + 1) as f32)))
    }
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
        let fade = StartFade::new(given, frames, self.until, motion.fps);
        for (f, w) in fade.weights() {
            positions[f * j..(f + 1) * j].iter_mut().zip(&residual).for_each(|(p, r)| *p += w * *r);
        }
        let skeleton = motion.skeleton.clone();
        let Some(mut poses) = motion.local_poses else { return Motion::from_positions(skeleton, motion.fps, positions) };
        poses.splice(0..fade.end, solve_local_poses(&skeleton, &positions[..fade.end * j]));
        Motion::from_local_poses(skeleton, motion.fps, poses)
    }

    /// Over the given frames and the blend after them, the contacts the feet there make: where
    /// they stand on the floor (the lock planted feet the file's frames then replaced, and a
    /// contact marker was drawn under a salsa's lifted foot, or a cross-legged sit's).
    fn on_contacts(&self, motion: &Motion, contacts: &mut FootContacts) {
        let given = self.frames.len() / motion.joints();
        if given == 0 || motion.frames() <= given {
            return;
        }
        let end = StartFade::new(given, motion.frames(), self.until, motion.fps).end;
        let Ok(roles) = JointRoles::new(&motion.skeleton) else { return };
        let defaults = ContactConfig::default();
        let standing = ContactConfig { height_off: defaults.height_on, seated_height: defaults.height_on, ..defaults };
        let own = foot_contacts(motion, &roles, &standing);
        contacts.left[..end].copy_from_slice(&own.left[..end]);
        contacts.right[..end].copy_from_slice(&own.right[..end]);
    }
}

/// How far the given frames' floor (their lowest support, feet or seat:
/// [`Motion::floor_height`], as [`super::init::FileStart`] puts them on the model's floor) is
/// above the finished take's over the same frames. A file's frames stand on the file's own
/// floor where they are, which can differ from where the take's levelled floor puts them: a
/// CMU salsa start stood 9 cm above it (the dance floor of that capture is not level), so the
/// given frames and the half second after them floated with both feet up, 26% of a 9 s take.
fn floor_gap(given: &[Vec3], take: &Motion, frames: usize) -> f32 {
    let given = Motion::from_positions(take.skeleton.clone(), take.fps, given.to_vec());
    given.floor_height() - take.slice(0, frames).floor_height()
}
