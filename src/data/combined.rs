//! The data of the model of everything (`models/all`): every clip of the four datasets
//! retargeted onto the standard humanoid ([`standard_humanoid`]) at 30 fps, its classes
//! merged where two datasets hold the same activity, Bandai's style kept on each clip.
//!
//! Each dataset keeps its own test split (h36m S11, Bandai tired and musical, CMU's test clips).
//! A clip from a dataset without styles carries [`NEUTRAL`]. Retargeting is checked like an
//! export ([`SourceCheck`]): the bones of the retargeted clip point where its source's do.

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context, Result};
use glam::Vec3;
use rayon::prelude::*;

use super::archive::DataRoot;
use super::joint_map::{key_joints, UserJointMap};
use super::registry::{self, Clip, Dataset, DatasetClips};
use crate::motion::contacts::lowest_foot_heights;
use crate::motion::{guess_key_joints, mapped_bones, mean_bone_angle, standard_humanoid, JointRoles, Key, KeyJoints, Motion, Retarget, Skeleton};

/// The style of a clip from a dataset that has none.
pub const NEUTRAL: &str = "neutral";

/// The frame rate of the standard humanoid's data.
pub const FPS: f32 = 30.0;

/// Activities two datasets name differently: (a dataset's name, the merged class's name).
const SAME_ACTIVITY: [(&str, &str); 2] = [("walk", "walking"), ("run", "running")];

/// Heights of the lowest foot joint are binned this finely (m) to find the floor.
const FLOOR_BIN: f32 = 0.01;

/// cmu-expmap's joints have no names (`joint0` ...): its key joints by index, read off the
/// skeleton file's hierarchy (the legs, spine and arms of the CMU ASF layout; a zero-length
/// joint at the chest starts each collar).
const CMU_EXPMAP_KEYS: [(usize, Key); 20] = [
    (0, Key::Hips),
    (15, Key::Chest),
    (17, Key::Neck),
    (18, Key::Head),
    (20, Key::LeftShoulder),
    (21, Key::LeftArm),
    (22, Key::LeftForeArm),
    (23, Key::LeftHand),
    (29, Key::RightShoulder),
    (30, Key::RightArm),
    (31, Key::RightForeArm),
    (32, Key::RightHand),
    (2, Key::LeftUpLeg),
    (3, Key::LeftLeg),
    (4, Key::LeftFoot),
    (5, Key::LeftToeBase),
    (8, Key::RightUpLeg),
    (9, Key::RightLeg),
    (10, Key::RightFoot),
    (11, Key::RightToeBase),
];

/// Every `CHECK_STRIDE`-th frame of a clip is compared with its source.
const CHECK_STRIDE: usize = 5;

/// How faithfully one dataset's clips landed on the standard humanoid.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SourceCheck {
    pub dataset: Dataset,
    pub clips: usize,
    /// Mean angle between each mapped bone and its source bone, degrees: the mean over clips
    /// and the worst clip's.
    pub mean_bone_degrees: f32,
    pub worst_clip_degrees: f32,
    pub worst_clip: String,
    /// The median over frames of the lowest foot joint's height, m: the mean over clips and
    /// the largest clip's (feet on the floor: a few centimetres at most).
    pub mean_foot_height: f32,
    pub worst_foot_height: f32,
    pub worst_foot_clip: String,
    /// The largest change of any bone's length between any two frames of any clip, m.
    pub bone_length_change: f32,
}

/// Every clip of the four datasets on the standard humanoid, with each dataset's check.
pub fn load(root: &DataRoot) -> Result<(DatasetClips, Vec<SourceCheck>)> {
    let target = standard_humanoid();
    let target_keys = guess_key_joints(&target);
    let roles = JointRoles::new(&target).context("the standard humanoid's legs")?;
    let mut classes: Vec<String> = Vec::new();
    let mut sources: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut styles = vec![NEUTRAL.to_string()];
    let (mut clips, mut skipped, mut checks) = (Vec::new(), Vec::new(), Vec::new());
    for dataset in Dataset::ARCHIVES {
        let loaded = registry::load_archive(dataset, root)?;
        let joint_map = (dataset == Dataset::CmuExpmap).then(|| UserJointMap { entries: CMU_EXPMAP_KEYS.iter().map(|&(j, k)| (format!("joint{j}"), k)).collect() });
        let moved: Vec<(Clip, ClipCheck)> = loaded
            .clips
            .into_par_iter()
            .map(|clip| {
                let (motion, check) = onto(&clip.motion, joint_map.as_ref(), &target, &target_keys, &roles, &clip.file)?;
                Ok((Clip { motion, ..clip }, check))
            })
            .collect::<Result<_>>()?;
        let merged: Vec<usize> = loaded
            .classes
            .iter()
            .map(|name| {
                let merged = SAME_ACTIVITY.iter().find(|(from, _)| from == name).map_or(name.as_str(), |(_, to)| *to);
                sources.entry(merged.to_string()).or_default().push(format!("{dataset} {name}"));
                classes.iter().position(|c| c == merged).unwrap_or_else(|| {
                    classes.push(merged.to_string());
                    classes.len() - 1
                })
            })
            .collect();
        checks.push(check_of(dataset, &moved));
        for (mut clip, _) in moved {
            clip.class = merged[clip.class];
            if dataset == Dataset::Bandai {
                if !styles.contains(&clip.tag) {
                    styles.push(clip.tag.clone());
                }
            } else {
                clip.tag = NEUTRAL.to_string();
            }
            clips.push(clip);
        }
        skipped.extend(loaded.skipped);
    }
    let class_sources = classes.iter().map(|c| sources[c].join(" + ")).collect();
    Ok((DatasetClips { dataset: Dataset::Combined, classes, clips, skipped, styles, class_sources }, checks))
}

/// How one clip landed on the standard humanoid.
struct ClipCheck {
    /// Mean angle between each mapped limb bone and its source bone, degrees.
    bone_degrees: f32,
    /// The median over frames of the lowest foot joint's height, m.
    foot_height: f32,
    /// The largest change of any bone's length over the clip, m.
    bone_length_change: f32,
}

/// `motion` resampled to 30 fps and retargeted onto `target`, stood on the floor, and how it
/// landed there.
fn onto(motion: &Motion, joint_map: Option<&UserJointMap>, target: &Arc<Skeleton>, target_keys: &KeyJoints, roles: &JointRoles, file: &str) -> Result<(Motion, ClipCheck)> {
    let source = motion.resample(FPS);
    let source_keys = key_joints(&source.skeleton, joint_map, file)?;
    let retarget = Retarget::new(&source.skeleton, &source_keys, target.clone(), target_keys).with_context(|| format!("{file}: cannot retarget onto the standard humanoid"))?.as_all_was_trained();
    let moved = retarget.apply(&source);
    let lowest = lowest_foot_heights(&moved, roles);
    let floor = floor(&lowest);
    let moved = moved.translated(Vec3::new(0.0, -floor, 0.0));
    // The bones inside the pelvis and the chest (hips to thighs, chest to collars) are left out:
    // those pieces are shaped differently on every skeleton and turn as a whole.
    let in_piece = |(_, parent): &(Key, Key)| matches!(parent, Key::Hips | Key::Chest);
    let bones: Vec<(Key, Key)> = mapped_bones(&source_keys, &source.skeleton, target_keys, target).into_iter().filter(|b| !in_piece(b) || b.0 == Key::Neck || b.0 == Key::Chest).collect();
    let angles: Vec<f32> = (0..moved.frames()).step_by(CHECK_STRIDE).map(|t| mean_bone_angle(&bones, source.frame(t), &source_keys, moved.frame(t), target_keys)).collect();
    let check = ClipCheck {
        bone_degrees: angles.iter().sum::<f32>() / angles.len().max(1) as f32,
        foot_height: median(lowest) - floor,
        bone_length_change: bone_length_change(&moved),
    };
    Ok((moved, check))
}

/// The largest change of any bone's length over the take.
fn bone_length_change(m: &Motion) -> f32 {
    let lengths: Vec<Vec<f32>> = (0..m.frames()).map(|t| m.bone_lengths(t)).collect();
    (0..m.joints())
        .map(|j| {
            let (lo, hi) = lengths.iter().map(|l| l[j]).fold((f32::INFINITY, 0.0f32), |(lo, hi), l| (lo.min(l), hi.max(l)));
            hi - lo
        })
        .fold(0.0, f32::max)
}

/// The floor under a take, from each frame's lowest foot height: the height the feet rest at
/// most often (the middle of the fullest bin). Neither the lowest frames (a leg through the
/// floor while sitting down, 33 cm deep in a Human3.6M clip) nor the median (a dance spends
/// half its time on one raised foot) would do.
fn floor(lowest: &[f32]) -> f32 {
    let mut bins: BTreeMap<i64, usize> = BTreeMap::new();
    for h in lowest.iter().filter(|h| h.is_finite()) {
        *bins.entry((h / FLOOR_BIN).floor() as i64).or_default() += 1;
    }
    bins.into_iter().max_by_key(|&(bin, count)| (count, std::cmp::Reverse(bin))).map_or(0.0, |(bin, _)| (bin as f32 + 0.5) * FLOOR_BIN)
}

fn median(mut values: Vec<f32>) -> f32 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f32::total_cmp);
    values[(values.len() - 1) / 2]
}

fn check_of(dataset: Dataset, moved: &[(Clip, ClipCheck)]) -> SourceCheck {
    let n = moved.len().max(1) as f32;
    let worst = moved.iter().max_by(|a, b| a.1.bone_degrees.total_cmp(&b.1.bone_degrees));
    let worst_foot = moved.iter().max_by(|a, b| a.1.foot_height.abs().total_cmp(&b.1.foot_height.abs()));
    SourceCheck {
        dataset,
        clips: moved.len(),
        mean_bone_degrees: moved.iter().map(|m| m.1.bone_degrees).sum::<f32>() / n,
        worst_clip_degrees: worst.map_or(0.0, |w| w.1.bone_degrees),
        worst_clip: worst.map_or(String::new(), |w| w.0.file.clone()),
        mean_foot_height: moved.iter().map(|m| m.1.foot_height).sum::<f32>() / n,
        worst_foot_height: worst_foot.map_or(0.0, |w| w.1.foot_height),
        worst_foot_clip: worst_foot.map_or(String::new(), |w| w.0.file.clone()),
        bone_length_change: moved.iter().map(|m| m.1.bone_length_change).fold(0.0, f32::max),
    }
}
