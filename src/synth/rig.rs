//! Rig-ready in and out: a BVH of another humanoid skeleton brought onto a model's joints
//! (to start a take), and a take moved onto another skeleton given as a BVH (to drop onto
//! that rig). Both map key joints by name (`data::joint_map`) and move bones with
//! `motion::Retarget`.

use std::path::Path;

use anyhow::{Context, Result};

use crate::data::bvh::read_bvh;
use crate::data::joint_map::{key_joints, UserJointMap};
use crate::data::registry::CMU_METRES_PER_UNIT;
use crate::model::spec::ModelSpec;
use crate::motion::{Key, KeyJoints, Motion, Retarget, Skeleton};

/// Units a foreign BVH may be in, metres per unit: m, cm, mm, inch, the CMU database's.
const PLAUSIBLE_UNITS: [f32; 5] = [1.0, 0.01, 0.001, 0.0254, CMU_METRES_PER_UNIT];
/// A grown-up's leg, hip to ankle, in metres: what a skeleton's unit is guessed from.
const TYPICAL_LEG: f32 = 0.85;

/// `motion` (read from `file`, on any humanoid skeleton) on the model's joints at the model's
/// frame rate.
pub fn onto_model(spec: &ModelSpec, motion: &Motion, file: &str, user: Option<&UserJointMap>) -> Result<Motion> {
    let source_keys = key_joints(&motion.skeleton, user, file)?;
    let target = spec.layout.skeleton.clone();
    let target_keys = key_joints(&target, None, &format!("the {} model's skeleton", spec.dataset))?;
    let retarget = Retarget::new(&motion.skeleton, &source_keys, target, &target_keys).with_context(|| format!("{file}: cannot retarget"))?;
    Ok(retarget.apply(motion).resample(spec.fps))
}

/// The entries of `map` that name joints of `skeleton`: one project mapping serves every
/// file, and a file without some of its joints is mapped by the name table there.
pub fn entries_for(map: &UserJointMap, skeleton: &Skeleton) -> UserJointMap {
    UserJointMap { entries: map.entries.iter().filter(|(joint, _)| skeleton.index_of(joint).is_some()).cloned().collect() }
}

/// `take` on the skeleton of the BVH file `skeleton_path` (its hierarchy and rest pose), same
/// frames and frame rate. The user mapping, if any, names that file's joints.
pub fn onto_skeleton_file(take: &Motion, skeleton_path: &Path, user: Option<&UserJointMap>) -> Result<Motion> {
    let name = skeleton_path.display().to_string();
    let text = std::fs::read_to_string(skeleton_path).with_context(|| format!("cannot read {name}"))?;
    let read = read_bvh(&text, &name)?.skeleton;
    let target_keys = key_joints(&read, user, &name)?;
    let unit = plausible_unit(&read, &target_keys);
    let target = Skeleton::new(read.names().to_vec(), read.parents().to_vec(), read.offsets().to_vec(), unit).with_context(|| format!("{name}: bad skeleton"))?;
    let source_keys = key_joints(&take.skeleton, None, "the take's skeleton")?;
    let retarget = Retarget::new(&take.skeleton, &source_keys, target.into(), &target_keys).with_context(|| format!("{name}: cannot retarget"))?;
    Ok(retarget.with_toes_to_tips(&take.skeleton).apply(take))
}

/// A BVH does not say its unit: the one of [`PLAUSIBLE_UNITS`] that gives the closest to a
/// typical leg length.
fn plausible_unit(skeleton: &Skeleton, keys: &KeyJoints) -> f32 {
    let rest = skeleton.rest_positions();
    let at = |k: Key| keys.get(k).map_or(glam::Vec3::ZERO, |j| rest[j]);
    let leg = at(Key::LeftUpLeg).distance(at(Key::LeftLeg)) + at(Key::LeftLeg).distance(at(Key::LeftFoot));
    nearest_plausible_unit(TYPICAL_LEG / leg).0
}

/// The one of [`PLAUSIBLE_UNITS`] nearest `guess` (metres per unit), and the factor between
/// them (1 or more).
pub(super) fn nearest_plausible_unit(guess: f32) -> (f32, f32) {
    let misfit = |unit: f32| (guess / unit).ln().abs();
    let unit = PLAUSIBLE_UNITS.into_iter().min_by(|a, b| misfit(*a).total_cmp(&misfit(*b))).expect("units to choose from");
    (unit, misfit(unit).exp())
}
