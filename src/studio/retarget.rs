//! Retargeting a BVH of another humanoid skeleton for the studio, without its UI: a frame of
//! the file and the same frame on the model's joints for the preview (the worker makes it,
//! [`preview`]), or why it cannot be mapped, and the state of the mapping editor
//! (`joint_mapping` draws them).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::viewport::Layer;
use crate::data::bvh::read_bvh;
use crate::data::input::{read_text, MAX_MOTION_BYTES};
use crate::data::joint_map::UserJointMap;
use crate::motion::guess_key_joints;
use crate::model::spec::ModelSpec;
use crate::motion::{Key as JointKey, Motion, Skeleton};
use crate::synth::rig::{entries_for, onto_model};

/// Where a retargeted file goes once the user takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PreviewFor {
    Init,
    Key,
}

/// The joints of a foreign file and the joint each key would take (the mapping's guesses,
/// then the name table's), what the mapping editor starts from.
#[derive(Clone, Debug, Default)]
pub struct SourceJoints {
    pub names: Vec<String>,
    pub guesses: Vec<(JointKey, Option<String>)>,
}

/// A frame of a foreign BVH and the same frame on the model's joints: the pose a take from
/// it starts with.
pub struct RetargetPreview {
    pub purpose: PreviewFor,
    pub path: PathBuf,
    pub frame: usize,
    /// One frame each.
    pub source: Arc<Motion>,
    pub retargeted: Arc<Motion>,
    pub joints: SourceJoints,
}

/// A foreign BVH that could not be retargeted (the engine's message names the missing keys).
pub struct RetargetFailure {
    pub purpose: PreviewFor,
    pub path: PathBuf,
    pub frame: usize,
    pub error: String,
    pub joints: SourceJoints,
}

/// The mapping editor's state: a joint of the file (or none: found automatically) per key.
pub struct JointMapEditor {
    pub purpose: PreviewFor,
    pub path: PathBuf,
    pub frame: usize,
    pub joints: Vec<String>,
    pub choices: Vec<(JointKey, Option<String>)>,
}

/// What the studio shows of a retarget: at most one of each.
#[derive(Default)]
pub struct RigState {
    pub preview: Option<Arc<RetargetPreview>>,
    pub failure: Option<Arc<RetargetFailure>>,
    pub editor: Option<JointMapEditor>,
}

fn is_bvh(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("bvh"))
}

/// Neither the model's joints nor its dataset's: a skeleton to retarget.
fn is_foreign(spec: &ModelSpec, skeleton: &Skeleton) -> bool {
    !skeleton.differences(&spec.layout.skeleton).is_empty() && !skeleton.differences(&spec.source_skeleton).is_empty()
}

fn source_joints(skeleton: &Skeleton, map: Option<&UserJointMap>) -> SourceJoints {
    let guessed = guess_key_joints(skeleton);
    let names = skeleton.names().to_vec();
    let guesses = JointKey::ALL
        .into_iter()
        .map(|key| {
            let mapped = map.and_then(|m| m.entries.iter().find(|(_, k)| *k == key)).map(|(joint, _)| joint.clone());
            (key, mapped.or_else(|| guessed.get(key).map(|j| names[j].clone())))
        })
        .collect();
    SourceJoints { names, guesses }
}

/// What became of a request to retarget a file.
pub enum Retargeting {
    Previewed(Arc<RetargetPreview>),
    Failed(Arc<RetargetFailure>),
    /// The file is on the model's own skeleton (or not a BVH): it goes on as it is.
    NotForeign { purpose: PreviewFor, path: PathBuf, frame: usize },
}

/// Retargets frame `frame` of `path` onto the model for a preview (the worker's answer to a
/// retarget request).
pub fn preview(spec: &ModelSpec, purpose: PreviewFor, path: PathBuf, frame: usize, map: Option<&UserJointMap>) -> Retargeting {
    if !is_bvh(&path) {
        return Retargeting::NotForeign { purpose, path, frame };
    }
    let name = path.display().to_string();
    let failed = |path: PathBuf, error: String, joints: SourceJoints| Retargeting::Failed(Arc::new(RetargetFailure { purpose, path, frame, error, joints }));
    let source = match read_text(&path, MAX_MOTION_BYTES).and_then(|text| Ok(read_bvh(&text, &name)?)) {
        Ok(m) if m.frames() > 0 => m,
        Ok(_) => return failed(path, format!("{name}: the file has no frames"), SourceJoints::default()),
        Err(e) => return failed(path, format!("{e:#}"), SourceJoints::default()),
    };
    if !is_foreign(spec, &source.skeleton) {
        return Retargeting::NotForeign { purpose, path, frame };
    }
    let map = map.map(|m| entries_for(m, &source.skeleton));
    let joints = source_joints(&source.skeleton, map.as_ref());
    match onto_model(spec, &source, &name, map.as_ref()) {
        Ok(on_model) if on_model.frames() > 0 => {
            // The pose a take starts from: `frame` counts the model's frames (the file is read
            // at the model's rate), and the first block ends one stride after it.
            let g = (frame + spec.stride).min(on_model.frames() - 1);
            let f = ((g as f32 / on_model.fps * source.fps).round() as usize).min(source.frames() - 1);
            let retargeted = on_model.slice(g, g + 1);
            let source = at_height(&source.slice(f, f + 1), height(&retargeted));
            let (source, retargeted) = (Arc::new(source), Arc::new(retargeted));
            Retargeting::Previewed(Arc::new(RetargetPreview { purpose, path, frame, source, retargeted, joints }))
        }
        Ok(_) => failed(path, format!("{name}: no frames left after retargeting"), joints),
        Err(e) => failed(path, format!("{e:#}"), joints),
    }
}

/// Colours of the preview: the file's skeleton, and the model's pose.
pub const SOURCE_COLOR: [u8; 3] = [235, 150, 60];
pub const RETARGETED_COLOR: [u8; 3] = [90, 170, 240];

/// Where the preview puts a pose: its root over (`x`, 0) and its lowest joint on the floor,
/// whatever the file's world.
fn beside(motion: &Motion, x: f32) -> glam::Vec3 {
    let mpu = motion.skeleton.meters_per_unit();
    let root = motion.frame(0).first().copied().unwrap_or_default() * mpu;
    let lowest = motion.frame(0).iter().map(|p| p.y).fold(f32::INFINITY, f32::min) * mpu;
    glam::Vec3::new(x - root.x, if lowest.is_finite() { -lowest } else { 0.0 }, -root.z)
}

/// The height of a one-frame pose in metres, lowest joint to highest.
fn height(pose: &Motion) -> f32 {
    let ys = pose.frame(0).iter().map(|p| p.y);
    let (low, high) = ys.fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), y| (l.min(y), h.max(y)));
    (high - low) * pose.skeleton.meters_per_unit()
}

/// `pose` drawn `metres` tall: its skeleton's unit set so it stands as tall as the model's
/// pose beside it. A BVH does not say its unit, and one guessed wrong drew the file's
/// skeleton at a third of the model's height; the preview compares directions, not sizes.
fn at_height(pose: &Motion, metres: f32) -> Motion {
    let own = height(pose);
    let skeleton = &pose.skeleton;
    let unit = skeleton.meters_per_unit() * metres / own;
    if !(unit.is_finite() && unit > 0.0) {
        return pose.clone();
    }
    match Skeleton::new(skeleton.names().to_vec(), skeleton.parents().to_vec(), skeleton.offsets().to_vec(), unit) {
        Ok(scaled) => Motion::from_positions(Arc::new(scaled), pose.fps, pose.positions().to_vec()),
        Err(_) => pose.clone(),
    }
}

impl RetargetPreview {
    /// The two poses for the viewport: the file's on the left, the model's on the right.
    pub fn layers(&self) -> Vec<Layer> {
        let layer = |motion: &Arc<Motion>, x: f32, color: [u8; 3]| Layer { motion: motion.clone(), frame_colors: Arc::new(vec![color]), offset: beside(motion, x), opacity: 1.0, contacts: None };
        vec![layer(&self.source, -0.6, SOURCE_COLOR), layer(&self.retargeted, 0.6, RETARGETED_COLOR)]
    }
}

impl JointMapEditor {
    pub fn new(purpose: PreviewFor, path: &Path, frame: usize, joints: &SourceJoints) -> Self {
        Self { purpose, path: path.to_path_buf(), frame, joints: joints.names.clone(), choices: joints.guesses.clone() }
    }
}
