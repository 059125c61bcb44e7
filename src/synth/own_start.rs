//! A take started from a BVH and retargeted back onto that BVH's own skeleton begins with the
//! file's own frames. The Blender add-on's "Continue from the armature" does exactly this (the
//! armature's seconds before the current frame as the start, the take back onto the
//! armature), as does `--init clip:RIG.bvh@F --retarget-to RIG.bvh`. Through the model's
//! skeleton and back, a start loses what the model has no joints for (an Unreal mannequin's
//! joints came back turned up to 135 degrees off the file's, its pelvis pointing 22), and
//! the retargeting's foot placement could straighten a landing leg it cannot bend back (a
//! Rigify shin 40 degrees off the armature's in the last sparse step before the join).

use std::path::Path;

use anyhow::Result;
use glam::{Quat, Vec3};

use super::given::{keeps_given_frames, StartFade};
use super::init::{read_on_own_skeleton, window_frames, InitPose};
use super::keys::place_keys;
use super::options::GenerateOptions;
use super::plan::SparseTimeline;
use super::project::Request;
use super::rig::onto_skeleton_file;
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, LocalPose, Motion, Skeleton};

/// How far (in the skeleton's reach at rest) the retargeted start may be from the file's own
/// frames, once turned and moved onto them, for those to be taken as its start: a round trip
/// through the model's skeleton comes within a few centimetres; further means the file is not
/// this take's start.
const MOST_APART: f32 = 0.1;

/// The take `motion` that `request` made on `model`, on the skeleton of the BVH file `rig`,
/// the request's joint map naming that file's joints: a start from that very file shows its
/// own frames ([`with_own_start`]).
pub fn take_on_rig(model: &GlocalModel, request: &Request, motion: &Motion, rig: &Path) -> Result<Motion> {
    with_own_start(model, &request.engine_options(), onto_skeleton_file(motion, rig, request.joint_map.as_ref())?)
}

/// `retargeted` (the take on the skeleton of the file it started from) with the file's own
/// frames over its given start, turned and moved onto where the take puts them, and the
/// difference at the start's last frame faded out over the half second after it, as the
/// take's own given frames are. Unchanged for a start from the seed bank, from a file on
/// another skeleton, or at a first pace other than 1 (where the start is not kept as given).
pub fn with_own_start(model: &GlocalModel, opts: &GenerateOptions, retargeted: Motion) -> Result<Motion> {
    let InitPose::File { path, frame, .. } = &opts.init else { return Ok(retargeted) };
    let is_bvh = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("bvh"));
    if !is_bvh || !keeps_given_frames(opts) {
        return Ok(retargeted);
    }
    let file = read_on_own_skeleton(model, path)?;
    let (Some(own), Some(take)) = (file.motion.local_poses.as_ref(), retargeted.local_poses.as_ref()) else { return Ok(retargeted) };
    if !same_skeleton(&file.motion.skeleton, &retargeted.skeleton) {
        return Ok(retargeted);
    }
    let mut frames = window_frames(model, file.motion.frames(), file.frame_of(*frame)?).split_off(model.spec.stride);
    frames.truncate(retargeted.frames());
    let given = frames.len();
    let file_given: Vec<Vec3> = frames.iter().flat_map(|&f| file.motion.frame(f)).copied().collect();
    let take_given = &retargeted.positions()[..file_given.len()];
    let (turn, shift) = turn_onto(&file_given, take_given);
    if mean_apart(&file_given, take_given, turn, shift) > MOST_APART * JointRoles::rest_reach(&retargeted.skeleton) {
        return Ok(retargeted);
    }
    let skeleton = retargeted.skeleton.clone();
    let mut poses = take.clone();
    for (pose, &f) in poses.iter_mut().zip(&frames) {
        *pose = placed(&skeleton, &own[f], turn, shift);
    }
    // The fade ends before the first key, as the take's own given frames' does.
    let timeline = SparseTimeline::new(&model.spec, opts)?;
    let until = place_keys(&timeline, model, &opts.keys, &opts.init)?.iter().map(|k| k.frame).min().unwrap_or(usize::MAX);
    fade_after(&mut poses, take, &StartFade::new(given, retargeted.frames(), until, retargeted.fps));
    Ok(Motion::from_local_poses(skeleton, retargeted.fps, poses))
}

/// Whether `file` is `target`: the same joints, parents and rest offsets (the add-on writes the
/// armature's rest and its posed seconds from the same bones).
fn same_skeleton(file: &Skeleton, target: &Skeleton) -> bool {
    let size = JointRoles::rest_reach(target).max(f32::MIN_POSITIVE);
    file.names() == target.names()
        && file.parents() == target.parents()
        && file.offsets().iter().zip(target.offsets()).all(|(a, b)| a.distance(*b) <= 1e-4 * size)
}

/// The turn about the vertical and the shift that bring `from`'s joints nearest `onto`'s
/// (least squares over every joint of every frame).
fn turn_onto(from: &[Vec3], onto: &[Vec3]) -> (Quat, Vec3) {
    let mean = |v: &[Vec3]| v.iter().copied().sum::<Vec3>() / v.len().max(1) as f32;
    let (a, b) = (mean(from), mean(onto));
    let (mut along, mut across) = (0.0, 0.0);
    for (p, q) in from.iter().zip(onto) {
        let (p, q) = (*p - a, *q - b);
        along += p.x * q.x + p.z * q.z;
        across += p.z * q.x - p.x * q.z;
    }
    let turn = Quat::from_rotation_y(f32::atan2(across, along));
    (turn, b - turn * a)
}

/// The mean distance between `from`'s joints turned and shifted and `onto`'s.
fn mean_apart(from: &[Vec3], onto: &[Vec3], turn: Quat, shift: Vec3) -> f32 {
    from.iter().zip(onto).map(|(p, q)| (turn * *p + shift).distance(*q)).sum::<f32>() / from.len().max(1) as f32
}

/// A file pose turned and shifted as a whole: its root joints' rotations and places.
fn placed(skeleton: &Skeleton, pose: &LocalPose, turn: Quat, shift: Vec3) -> LocalPose {
    let mut pose = pose.clone();
    for j in (0..skeleton.len()).filter(|&j| skeleton.parents()[j].is_none()) {
        pose.rotations[j] = (turn * pose.rotations[j]).normalize();
        pose.translations[j] = turn * pose.translations[j] + shift;
    }
    pose
}

/// The difference the given start makes at its last pose (against the take's own pose there,
/// in `take`) added to the poses after it as `fade` weighs them: each joint's rotation and place.
fn fade_after(poses: &mut [LocalPose], take: &[LocalPose], fade: &StartFade) {
    let Some((first, _)) = fade.weights().next() else { return };
    let last = first - 1;
    let (start, own) = (&poses[last], &take[last]);
    let turns: Vec<Quat> = start.rotations.iter().zip(&own.rotations).map(|(s, t)| (*s * t.inverse()).normalize()).collect();
    let moves: Vec<Vec3> = start.translations.iter().zip(&own.translations).map(|(s, t)| *s - *t).collect();
    for (f, w) in fade.weights() {
        let pose = &mut poses[f];
        for (r, turn) in pose.rotations.iter_mut().zip(&turns) {
            *r = (Quat::IDENTITY.slerp(*turn, w) * *r).normalize();
        }
        for (t, moved) in pose.translations.iter_mut().zip(&moves) {
            *t += w * *moved;
        }
    }
}
