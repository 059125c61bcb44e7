//! The first sparse poses of a take: from the model's seed bank, or from a motion file on
//! the model's skeleton (or a BVH of another humanoid skeleton, retargeted).

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use glam::Vec3;

use super::rig::{entries_for, nearest_plausible_unit, onto_model};
use crate::data::bvh::read_bvh_with_unit;
use crate::data::expmap::ExpmapFormat;
use crate::data::features::Placement;
use crate::data::joint_map::UserJointMap;
use crate::data::input::{check_plausible, read_bytes, read_text, MAX_MOTION_BYTES};
use crate::data::npy::{motion_from_npy, read_npy};
use crate::data::registry::Dataset;
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, Motion, Skeleton};
use super::export::in_units;

/// Where the first sparse poses come from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum InitPose {
    /// A seed-bank entry of this class (the `variant`-th one, wrapping around).
    SeedClass { class: String, variant: usize },
    /// A seed-bank entry by index.
    SeedIndex(usize),
    /// A motion file (BVH, NPY (T, J, 3), or an exponential-map text of the model's
    /// dataset) from this frame on: the file's own frame number, at its own frame rate.
    File {
        path: PathBuf,
        frame: usize,
        /// Joints of the file for the model's key joints where the name table does not find
        /// them (a BVH of another skeleton): a request's joint map
        /// ([`super::project::Request::engine_options`]), never saved with the options.
        #[serde(skip)]
        joint_map: Option<UserJointMap>,
    },
}

impl InitPose {
    /// Frame `frame` on of the file at `path`, its joints found by the name table.
    pub fn file(path: PathBuf, frame: usize) -> Self {
        InitPose::File { path, frame, joint_map: None }
    }
}

impl Default for InitPose {
    fn default() -> Self {
        InitPose::SeedIndex(0)
    }
}

/// Raw (un-normalised) sparse features of the first block, and where the take starts.
pub fn initial_features(model: &GlocalModel, init: &InitPose) -> Result<(Vec<f32>, Placement)> {
    let spec = &model.spec;
    match init {
        InitPose::SeedIndex(i) => {
            let seed = model.seeds.get(*i).with_context(|| format!("seed {i} does not exist; the seed bank has {} seeds", model.seeds.len()))?;
            Ok((seed.features.clone(), Placement::default()))
        }
        InitPose::SeedClass { class, variant } => {
            let k = spec.class_index(class)?;
            let seed = model.seed_of_class(k, *variant).with_context(|| format!("the seed bank has no seed of class '{class}'"))?;
            Ok((seed.features.clone(), Placement::default()))
        }
        InitPose::File { path, frame, joint_map } => {
            let file = read_on_model_skeleton(model, path, joint_map.as_ref())?;
            let (motion, at) = start_window(model, &file.motion, file.frame_of(*frame)?);
            let motion = motion.translated(Vec3::new(0.0, FileStart::of(model, &motion, at).lift, 0.0));
            let start = at + spec.stride;
            Ok((spec.layout.encode_motion(&motion, start, spec.stride, spec.block_len), Placement::default()))
        }
    }
}

/// The dense frames a take from a motion file starts with, in the take's world: the file's
/// frames over the starting poses, from the first to the last ([`initial_features`] takes
/// every `stride`-th of them). None for a seed-bank start, which has only its sparse poses.
pub fn given_frames(model: &GlocalModel, init: &InitPose) -> Result<Option<Vec<Vec3>>> {
    let InitPose::File { path, frame, joint_map } = init else { return Ok(None) };
    let spec = &model.spec;
    let file = read_on_model_skeleton(model, path, joint_map.as_ref())?;
    let (motion, at) = start_window(model, &file.motion, file.frame_of(*frame)?);
    let start = FileStart::of(model, &motion, at);
    let frames = at + spec.stride..=at + spec.stride * spec.block_len;
    Ok(Some(frames.filter(|&f| f < motion.frames()).flat_map(|f| start.apply(motion.frame(f))).collect()))
}

/// The frames a start reads from model-rate frame `at` of a file's `motion`, and where they
/// begin: the file itself where it holds the start's seconds from there; where it holds fewer
/// (a single pose, a clip shorter than the start), its frame `at` held before the rest, so the
/// take stands in that pose and goes on from the file's last frame. (A start used to refuse
/// such a file: a pose from a rig, the commonest start an animator has, could not start a take.)
fn start_window<'m>(model: &GlocalModel, motion: &'m Motion, at: usize) -> (Cow<'m, Motion>, usize) {
    let frames = window_frames(model, motion.frames(), at);
    if frames.windows(2).all(|w| w[1] == w[0] + 1) {
        return (Cow::Borrowed(motion), at);
    }
    let positions: Vec<Vec3> = frames.iter().flat_map(|&f| motion.frame(f)).copied().collect();
    (Cow::Owned(Motion::from_positions(motion.skeleton.clone(), motion.fps, positions)), 0)
}

/// Which of a file's `frames` (at the model's rate) each frame of [`start_window`] is, for a
/// start from frame `at`: `at` on, its first held as long as the file falls short.
pub(super) fn window_frames(model: &GlocalModel, frames: usize, at: usize) -> Vec<usize> {
    let window = model.spec.stride * model.spec.block_len + 1;
    let held = window.saturating_sub(frames.saturating_sub(at));
    (0..window).map(|i| at + i.saturating_sub(held)).collect()
}

/// Where a take started from frame `frame` of a motion file puts the file's world: that
/// frame's root on the origin, facing +z (the take's first features are its steps from it),
/// and the frames the start uses on the model's floor (an exported take stands at 0,
/// Human3.6M's world lower). A key from the same file lands where this puts it.
#[derive(Clone, Copy, Debug)]
pub struct FileStart {
    /// Where the file's start frame stands in the file's world.
    pub place: Placement,
    /// The height added to every position.
    pub lift: f32,
}

impl FileStart {
    /// The start of a take from `frame` of `motion` (on the model's skeleton and frame rate).
    pub fn of(model: &GlocalModel, motion: &Motion, frame: usize) -> Self {
        let spec = &model.spec;
        let frame = frame.min(motion.frames().saturating_sub(1));
        let used = motion.slice(frame, frame.saturating_add(spec.stride * spec.block_len + 1).min(motion.frames()));
        Self { place: spec.layout.placement(motion.frame(frame)), lift: model.floor_height() - used.floor_height() }
    }

    /// A frame of the file in the take's world.
    pub fn apply(&self, frame: &[Vec3]) -> Vec<Vec3> {
        let turn = glam::Quat::from_rotation_y(-self.place.heading);
        let origin = Vec3::new(self.place.x, -self.lift, self.place.z);
        frame.iter().map(|p| turn * (*p - origin)).collect()
    }
}

/// A BVH exported in metres or centimetres (`glocal generate --units`) read as if in the
/// model's unit: rescaled by the power of ten that makes its bones the model's length. A file
/// on another skeleton (whose bones named as the model's are not its lengths times a power of
/// ten) is judged by its size instead: the power of ten that makes its legs (hip to knee to
/// ankle at rest) a person's, as the model's are, within a factor of two (a Bandai file in
/// centimetres on the standard humanoid in metres), else the other units a BVH may be in
/// (inches, the CMU database's, [`nearest_plausible_unit`]) within a factor of two. Powers of
/// ten first: a small rig in centimetres (legs half the model's) would read nearer inches.
/// The same Bandai file in inches, which no power of ten fits, was read in the model's unit,
/// 39 times too big on `models/all`, which refused it as damaged. A rig whose legs are not
/// found is sized by its body's reach at rest. Both leave out a root joint resting far from
/// the body (Bandai's `joint_Root`, 4.5 m from its hips), by whose reach a CMU dance file in
/// centimetres read as decimetres.
fn in_model_units(m: Motion, model: &Skeleton) -> Result<Motion> {
    let s = &m.skeleton;
    let mut ratios: Vec<f32> = (0..s.len())
        .filter_map(|j| {
            let k = model.index_of(&s.names()[j])?;
            let (a, b) = (model.offsets()[k].length(), s.offsets()[j].length());
            (j > 0 && k > 0 && a > 0.0 && b > 0.0).then_some(a / b)
        })
        .collect();
    ratios.sort_by(f32::total_cmp);
    let power_of_ten = |ratio: f32, tolerance: f32| {
        let power = ratio.log10().round();
        ((ratio.log10() - power).abs() <= tolerance && power.abs() <= 3.0).then_some(power)
    };
    let in_tens = |power: f32| s.meters_per_unit() * 10f32.powf(power);
    let by_names = ratios.get(ratios.len() / 2).and_then(|&r| power_of_ten(r, 0.02)).map(in_tens);
    let by_size = || {
        let ratio = size_ratio(model, s);
        power_of_ten(ratio, 0.3).map(in_tens).or_else(|| {
            let (unit, off) = nearest_plausible_unit(s.meters_per_unit() * ratio);
            (off <= 2.0).then_some(unit)
        })
    };
    let Some(unit) = by_names.or_else(by_size) else { return Ok(m) };
    if (unit / s.meters_per_unit() - 1.0).abs() < 1e-3 {
        return Ok(m);
    }
    let skeleton = Skeleton::new(s.names().to_vec(), s.parents().to_vec(), s.offsets().to_vec(), unit)?;
    let mut file = m;
    file.skeleton = Arc::new(skeleton);
    in_units(&file, model.meters_per_unit())
}

/// How many times `b`'s body is `a`'s, by their legs where both have them, else by their reach.
fn size_ratio(a: &Skeleton, b: &Skeleton) -> f32 {
    let legs = |k: &Skeleton| JointRoles::new(k).ok().map(|r| r.rest_leg_length(k));
    let (size_a, size_b) = match (legs(a), legs(b)) {
        (Some(la), Some(lb)) if la > 0.0 && lb > 0.0 => (la, lb),
        _ => (JointRoles::rest_reach(a), JointRoles::rest_reach(b)),
    };
    size_a / size_b.max(f32::MIN_POSITIVE)
}

/// A motion file brought onto the model's joints and frame rate, with what frame numbers
/// mean in the file itself: `clip:FILE@N` is the file's own frame N (line N of a 50 fps
/// dataset text, frame N of a 120 fps BVH), whatever the model's rate.
pub struct FileMotion {
    pub motion: Motion,
    /// The file's frame rate and frame count (an NPY has no rate: the model's is assumed).
    pub file_fps: f32,
    pub file_frames: usize,
    name: String,
}

impl FileMotion {
    /// The model-rate frame of the file's frame `frame`, or an error naming the file when it
    /// has no such frame.
    pub fn frame_of(&self, frame: usize) -> Result<usize> {
        if frame >= self.file_frames {
            bail!("{}: frame {frame} is past the file's {} frames", self.name, self.file_frames);
        }
        let at = (frame as f64 * self.motion.fps as f64 / self.file_fps as f64).round() as usize;
        Ok(at.min(self.motion.frames().saturating_sub(1)))
    }
}

/// A BVH start on its own skeleton at the model's frame rate, its local rotations kept: what
/// a take retargeted back onto that skeleton shows over its start ([`super::own_start`]).
pub(super) fn read_on_own_skeleton(model: &GlocalModel, path: &Path) -> Result<FileMotion> {
    let name = path.display().to_string();
    let text = read_text(path, MAX_MOTION_BYTES)?;
    let m = read_bvh_with_unit(&text, &name, model.spec.source_skeleton.meters_per_unit())?;
    let (file_fps, file_frames) = (m.fps, m.frames());
    let resampled = m.resample(model.spec.fps);
    let motion = match resampled.local_poses {
        // Positions from the slerped rotations, not the interpolated positions they came with.
        Some(poses) => Motion::from_local_poses(resampled.skeleton, resampled.fps, poses),
        None => resampled,
    };
    Ok(FileMotion { motion, file_fps, file_frames, name })
}

/// Reads a BVH, NPY or exponential-map file and brings it onto the model's joints and
/// frame rate; a BVH of another humanoid skeleton is retargeted onto the model's joints, its
/// key joints found by the entries of `joint_map` that name its joints, then by name.
pub fn read_on_model_skeleton(model: &GlocalModel, path: &Path, joint_map: Option<&UserJointMap>) -> Result<FileMotion> {
    let name = path.display().to_string();
    let (motion, file_fps, file_frames) = read_onto_model(model, path, &name, joint_map)?;
    Ok(FileMotion { motion, file_fps, file_frames, name })
}

/// [`read_on_model_skeleton`]'s motion, with the file's own frame rate and count.
fn read_onto_model(model: &GlocalModel, path: &Path, name: &str, joint_map: Option<&UserJointMap>) -> Result<(Motion, f32, usize)> {
    let spec = &model.spec;
    let name = name.to_string();
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_lowercase();
    let source = Arc::new(spec.source_skeleton.clone());
    let m = match ext.as_str() {
        "bvh" => {
            let text = read_text(path, MAX_MOTION_BYTES)?;
            let m = read_bvh_with_unit(&text, &name, spec.source_skeleton.meters_per_unit())?;
            let m = in_model_units(m, &spec.source_skeleton)?;
            check_plausible(&m, &name, &spec.source_skeleton)?;
            let file = (m.fps, m.frames());
            // A take this model exported is on its own joints already.
            if m.skeleton.differences(&spec.layout.skeleton).is_empty() {
                let mut m = m.resample(spec.fps);
                m.skeleton = spec.layout.skeleton.clone();
                return Ok((m, file.0, file.1));
            }
            if !m.skeleton.differences(&spec.source_skeleton).is_empty() {
                // Another humanoid skeleton: retargeted by its joint names.
                let own = joint_map.map(|map| entries_for(map, &m.skeleton));
                return Ok((onto_model(spec, &m, &name, own.as_ref())?, file.0, file.1));
            }
            m
        }
        "npy" => {
            let bytes = read_bytes(path, MAX_MOTION_BYTES)?;
            // The joint count picks the skeleton: the model's own joints need no subsetting.
            let shape = read_npy(&bytes, &name)?.shape;
            let (model_joints, source_joints) = (spec.layout.joints(), spec.source_skeleton.len());
            let on_model = shape.get(1) == Some(&model_joints);
            let skeleton = match shape.get(1) {
                _ if on_model => spec.layout.skeleton.clone(),
                Some(&j) if j == source_joints => source.clone(),
                _ => bail!("{name}: array has shape {shape:?}; expected (T, {model_joints}, 3) or (T, {source_joints}, 3)"),
            };
            let m = motion_from_npy(&bytes, &name, skeleton, spec.fps)?;
            check_plausible(&m, &name, &m.skeleton)?;
            if on_model {
                let frames = m.frames();
                return Ok((m, spec.fps, frames));
            }
            m
        }
        "txt" => {
            let dataset: Dataset = spec.dataset.parse()?;
            let root = dataset
                .root_encoding()
                .with_context(|| format!("{name}: the {dataset} model reads BVH or NPY starts; exponential-map text is read by the model of its own dataset"))?;
            let format = ExpmapFormat { skeleton: source.clone(), root, fps: dataset.source_fps(), major15: None };
            let text = read_text(path, MAX_MOTION_BYTES)?;
            let m = format.read(&text, &name)?;
            check_plausible(&m, &name, &spec.source_skeleton)?;
            m
        }
        _ => bail!("{name}: unsupported file type '{ext}' (use .bvh, .npy or an exponential-map .txt)"),
    };
    let file = (m.fps, m.frames());
    let mut m = m.resample(spec.fps).subset(&spec.source_joints);
    m.skeleton = spec.layout.skeleton.clone();
    Ok((m, file.0, file.1))
}
