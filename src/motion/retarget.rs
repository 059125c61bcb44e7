//! Retargeting: a take on one humanoid skeleton moved onto another with other joint names,
//! bone lengths, joint counts and rest pose.
//!
//! Both skeletons name the same twenty key joints ([`Key`]: hips, chest, neck, head, collars,
//! arms, forearms, hands, thighs, shins, feet, toes; [`super::guess_key_joints`] finds them).
//! The key joints that both skeletons have form a small tree (each one's parent is its nearest
//! mapped ancestor). Each frame, every bone of that tree points on the target where the same
//! bone points on the source, at the target's own rest length; the hips follow the source's
//! hips scaled by the ratio of leg lengths (a shorter character takes shorter steps). Joint
//! rotations are then solved against the target's rest pose ([`solve_local_poses`] on the
//! mapped tree), and the target's other joints (extra spine joints, fingers, twist joints,
//! end sites) are carried rigidly by their nearest mapped ancestor.
//!
//! Why bone directions rather than copying local rotations: a local rotation only means
//! something relative to its skeleton's rest pose, and rest poses differ (the CMU files stand
//! in a T-pose, Mixamo-style rigs in an A-pose, Human3.6M with its arms straight up, and
//! Bandai's rest is not a standing pose at all: its joints' frames carry the exporter's joint
//! orients). Transferring each bone's world direction is the same as transferring rotations
//! relative to a common rest pose, without having to build one; [`RestPose`] is detected and
//! reported so a user can see what the two rigs stand in.

use std::sync::Arc;

use glam::{Quat, Vec3};

use super::keys::{Key, KeyJoints};
use super::{solve_local_poses, LocalPose, Motion, Skeleton};

/// What a skeleton's rest pose (all rotations identity) looks like, judged from the angle
/// between the upper arms and the body's up direction (hips to head), with the legs hanging
/// down: arms out sideways is a T-pose, arms 25-70 degrees below that an A-pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RestPose {
    TPose,
    APose,
    /// Arms up or down, legs not hanging, or a rest that is not a standing pose (Bandai's).
    Other,
}

impl RestPose {
    pub fn detect(skeleton: &Skeleton, keys: &KeyJoints) -> RestPose {
        let rest = skeleton.rest_positions();
        let dir = |a: Key, b: Key| -> Option<Vec3> { Some((rest[keys.get(b)?] - rest[keys.get(a)?]).normalize_or_zero()) };
        let (Some(up), Some(left_arm), Some(right_arm), Some(left_leg), Some(right_leg)) = (
            dir(Key::Hips, Key::Head),
            dir(Key::LeftArm, Key::LeftForeArm),
            dir(Key::RightArm, Key::RightForeArm),
            dir(Key::LeftUpLeg, Key::LeftFoot),
            dir(Key::RightUpLeg, Key::RightFoot),
        ) else {
            return RestPose::Other;
        };
        let legs_hang = left_leg.dot(up) < -0.9 && right_leg.dot(up) < -0.9;
        let arm_angle = (left_arm.dot(up).clamp(-1.0, 1.0).acos() + right_arm.dot(up).clamp(-1.0, 1.0).acos()).to_degrees() / 2.0;
        match (legs_hang, arm_angle) {
            (true, a) if (70.0..115.0).contains(&a) => RestPose::TPose,
            (true, a) if (115.0..160.0).contains(&a) => RestPose::APose,
            _ => RestPose::Other,
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            RestPose::TPose => "T-pose",
            RestPose::APose => "A-pose",
            RestPose::Other => "neither T- nor A-pose",
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RetargetError {
    #[error("the {side} skeleton has no joint for {}", .keys.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "))]
    MissingKeys { side: &'static str, keys: Vec<Key> },
    #[error("the {side} skeleton's {key} is not below its hips")]
    NotBelowHips { side: &'static str, key: &'static str },
}

/// One bone of the mapped tree: a key joint both skeletons have.
#[derive(Clone, Debug)]
struct Link {
    key: Key,
    target: usize,
    source: usize,
    /// Index of the nearest mapped ancestor in `links` (None for the hips).
    parent: Option<usize>,
    /// Target rest distance from the parent link's joint.
    length: f32,
}

/// A prepared mapping from one skeleton onto another; [`Retarget::apply`] moves takes.
#[derive(Clone, Debug)]
pub struct Retarget {
    target: Arc<Skeleton>,
    /// Mapped key joints in target joint order (the hips first).
    links: Vec<Link>,
    /// The target reduced to the mapped joints, for solving their rotations.
    mapped_skeleton: Skeleton,
    /// For each target joint, its link when it is a mapped joint.
    link_of: Vec<Option<usize>>,
    /// For the first unmapped joint on the way from one mapped joint to the next (an extra
    /// spine joint, CMU's buttock joint between hips and thigh), the link it turns towards, so
    /// the chain reaches where the next mapped joint should be.
    aims: Vec<Option<usize>>,
    /// Target units of hips motion per source unit: the ratio of leg lengths.
    root_scale: f32,
    pub source_rest: RestPose,
    pub target_rest: RestPose,
}

impl Retarget {
    pub fn new(source: &Skeleton, source_keys: &KeyJoints, target: Arc<Skeleton>, target_keys: &KeyJoints) -> Result<Retarget, RetargetError> {
        for (side, keys) in [("source", source_keys), ("target", target_keys)] {
            let missing = keys.missing_required();
            if !missing.is_empty() {
                return Err(RetargetError::MissingKeys { side, keys: missing });
            }
        }
        // A source key on its mapped parent (the CMU database's zero-length lowerneck and
        // clavicle joints) hands on no direction: its goal sits on its parent's, which the
        // solver then leaves out of the parent's fit, and the bone after it still points right.
        let mut pairs: Vec<(usize, usize, Key)> =
            Key::ALL.into_iter().filter_map(|k| Some((target_keys.get(k)?, source_keys.get(k)?, k))).collect();
        pairs.sort_by_key(|p| p.0);
        let target_rest = target.rest_positions();
        let mut links: Vec<Link> = Vec::with_capacity(pairs.len());
        for (t, s, key) in pairs {
            let parent = target.ancestors(t).find_map(|a| links.iter().position(|l| l.target == a));
            if parent.is_none() && key != Key::Hips {
                return Err(RetargetError::NotBelowHips { side: "target", key: key.name() });
            }
            let length = parent.map_or(0.0, |p| target_rest[t].distance(target_rest[links[p].target]));
            links.push(Link { key, target: t, source: s, parent, length });
        }
        let link_of: Vec<Option<usize>> = (0..target.len()).map(|j| links.iter().position(|l| l.target == j)).collect();
        let mut aims = vec![None; target.len()];
        for (i, link) in links.iter().enumerate() {
            let Some(parent) = link.parent.map(|p| links[p].target) else { continue };
            let first = target.child_towards(parent, link.target).filter(|&c| c != link.target);
            if let Some(f) = first.filter(|&f| aims[f].is_none()) {
                aims[f] = Some(i);
            }
        }
        let keep: Vec<usize> = links.iter().map(|l| l.target).collect();
        let root_scale = leg_length(&target, target_keys) / leg_length(source, source_keys).max(f32::MIN_POSITIVE);
        Ok(Retarget {
            mapped_skeleton: target.subset(&keep),
            source_rest: RestPose::detect(source, source_keys),
            target_rest: RestPose::detect(&target, target_keys),
            target,
            links,
            link_of,
            aims,
            root_scale,
        })
    }

    /// The keys this mapping moves (those both skeletons have).
    pub fn keys(&self) -> impl Iterator<Item = Key> + '_ {
        self.links.iter().map(|l| l.key)
    }

    /// Target units of hips travel per source unit.
    pub fn root_scale(&self) -> f32 {
        self.root_scale
    }

    /// `motion` (on the source skeleton) on the target skeleton, with its rotations, at the
    /// same frame rate and frame count.
    pub fn apply(&self, motion: &Motion) -> Motion {
        let mut mapped = Vec::with_capacity(motion.frames() * self.links.len());
        for t in 0..motion.frames() {
            let frame = motion.frame(t);
            let start = mapped.len();
            for link in &self.links {
                let p = match link.parent {
                    None => frame[link.source] * self.root_scale,
                    Some(parent) => {
                        let bone = frame[link.source] - frame[self.links[parent].source];
                        mapped[start + parent] + bone.normalize_or_zero() * link.length
                    }
                };
                mapped.push(p);
            }
        }
        let solved = solve_local_poses(&self.mapped_skeleton, &mapped);
        let poses = solved.iter().zip(mapped.chunks_exact(self.links.len())).map(|(pose, goals)| self.full_pose(pose, goals)).collect();
        Motion::from_local_poses(self.target.clone(), motion.fps, poses)
    }

    /// The target's whole pose from the mapped joints' solved pose and where they should be
    /// (`goals`, one per link): a mapped joint takes its solved world rotation, the first joint
    /// of an unmapped stretch turns towards the next mapped joint's goal, every other joint
    /// moves rigidly with its parent.
    fn full_pose(&self, mapped: &LocalPose, goals: &[Vec3]) -> LocalPose {
        let mut link_world = vec![Quat::IDENTITY; self.links.len()];
        for (i, link) in self.links.iter().enumerate() {
            let base = link.parent.map_or(Quat::IDENTITY, |p| link_world[p]);
            link_world[i] = base * mapped.rotations[i];
        }
        let skeleton = &*self.target;
        let rest = skeleton.rest_positions();
        let hips = self.links[0].target;
        let translations: Vec<Vec3> = (0..skeleton.len())
            .map(|j| match skeleton.parents()[j] {
                Some(_) => skeleton.offsets()[j],
                // A root above the hips does not rotate: place it so the hips land right.
                None if j == hips => goals[0],
                None if skeleton.is_ancestor(j, hips) => goals[0] - (rest[hips] - rest[j]),
                None => skeleton.offsets()[j],
            })
            .collect();
        let mut world = vec![Quat::IDENTITY; skeleton.len()];
        let mut position = vec![Vec3::ZERO; skeleton.len()];
        for j in 0..skeleton.len() {
            let (base, at) = match skeleton.parents()[j] {
                Some(p) => (world[p], position[p] + world[p] * translations[j]),
                None => (Quat::IDENTITY, translations[j]),
            };
            position[j] = at;
            world[j] = match (self.link_of[j], self.aims[j]) {
                (Some(i), _) => link_world[i],
                (None, Some(k)) => turn_towards(base, rest[self.links[k].target] - rest[j], goals[k] - at),
                (None, None) => base,
            };
        }
        let rotations = (0..skeleton.len())
            .map(|j| match skeleton.parents()[j] {
                Some(p) => (world[p].inverse() * world[j]).normalize(),
                None => world[j],
            })
            .collect();
        LocalPose { rotations, translations }
    }
}

/// `base` followed by the shortest rotation taking `base * rest` onto `wanted`.
fn turn_towards(base: Quat, rest: Vec3, wanted: Vec3) -> Quat {
    let from = (base * rest).normalize_or_zero();
    let to = wanted.normalize_or_zero();
    if from == Vec3::ZERO || to == Vec3::ZERO {
        return base;
    }
    (Quat::from_rotation_arc(from, to) * base).normalize()
}

/// Mean rest length of the two legs, hip to knee to ankle.
fn leg_length(skeleton: &Skeleton, keys: &KeyJoints) -> f32 {
    let rest = skeleton.rest_positions();
    let at = |k: Key| keys.get(k).map_or(Vec3::ZERO, |j| rest[j]);
    let leg = |hip: Key, knee: Key, ankle: Key| at(hip).distance(at(knee)) + at(knee).distance(at(ankle));
    (leg(Key::LeftUpLeg, Key::LeftLeg, Key::LeftFoot) + leg(Key::RightUpLeg, Key::RightLeg, Key::RightFoot)) / 2.0
}

/// Bones between key joints both skeletons map, as (key, parent key) with the parent the
/// nearest mapped ancestor on skeleton `a`: the bones a retargeted take should point the same
/// way as its source on. Bones of no rest length on either skeleton have no direction and are
/// left out.
pub fn mapped_bones(a: &KeyJoints, a_skeleton: &Skeleton, b: &KeyJoints, b_skeleton: &Skeleton) -> Vec<(Key, Key)> {
    let both: Vec<(Key, usize)> = a.mapped().filter(|(k, _)| b.get(*k).is_some()).collect();
    let (rest_a, rest_b) = (a_skeleton.rest_positions(), b_skeleton.rest_positions());
    let has_length = |rest: &[Vec3], keys: &KeyJoints, skeleton: &Skeleton, key: Key, parent: Key| {
        let (Some(j), Some(p)) = (keys.get(key), keys.get(parent)) else { return false };
        rest[j].distance(rest[p]) > 1e-3 * leg_length(skeleton, keys)
    };
    both.iter()
        .filter_map(|&(key, joint)| {
            let parent = a_skeleton.ancestors(joint).find_map(|p| both.iter().find(|(_, j)| *j == p).map(|(k, _)| *k))?;
            Some((key, parent))
        })
        .filter(|&(key, parent)| has_length(&rest_a, a, a_skeleton, key, parent) && has_length(&rest_b, b, b_skeleton, key, parent))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stick figure standing in a T-pose, with `spine` extra joints between hips and chest.
    fn figure(spine: usize, arm_drop_degrees: f32, scale: f32) -> (Skeleton, KeyJoints) {
        let mut names = Vec::new();
        let mut parents = Vec::new();
        let mut offsets = Vec::new();
        let mut keys = KeyJoints::default();
        let mut add = |name: &str, parent: Option<usize>, offset: Vec3, key: Option<Key>| -> usize {
            names.push(name.to_string());
            parents.push(parent);
            offsets.push(offset * scale);
            let j = names.len() - 1;
            if let Some(k) = key {
                keys.set(k, Some(j));
            }
            j
        };
        let hips = add("hips", None, Vec3::new(0.0, 90.0, 0.0), Some(Key::Hips));
        let mut below = hips;
        for s in 0..spine {
            below = add(&format!("spine{s}"), Some(below), Vec3::new(0.0, 30.0 / (spine + 1) as f32, 0.0), None);
        }
        let chest = add("chest", Some(below), Vec3::new(0.0, 30.0 / (spine + 1) as f32, 0.0), Some(Key::Chest));
        let neck = add("neck", Some(chest), Vec3::new(0.0, 15.0, 0.0), Some(Key::Neck));
        add("head", Some(neck), Vec3::new(0.0, 10.0, 0.0), Some(Key::Head));
        let drop = arm_drop_degrees.to_radians();
        for (side, x, keys3) in [(1.0f32, "l", [Key::LeftArm, Key::LeftForeArm, Key::LeftHand]), (-1.0, "r", [Key::RightArm, Key::RightForeArm, Key::RightHand])] {
            let along = Vec3::new(side * drop.cos(), -drop.sin(), 0.0);
            let arm = add(&format!("{x}arm"), Some(chest), Vec3::new(side * 15.0, 10.0, 0.0), Some(keys3[0]));
            let fore = add(&format!("{x}fore"), Some(arm), along * 28.0, Some(keys3[1]));
            add(&format!("{x}hand"), Some(fore), along * 25.0, Some(keys3[2]));
        }
        for (side, x, keys3) in [(1.0f32, "l", [Key::LeftUpLeg, Key::LeftLeg, Key::LeftFoot]), (-1.0, "r", [Key::RightUpLeg, Key::RightLeg, Key::RightFoot])] {
            let up = add(&format!("{x}thigh"), Some(hips), Vec3::new(side * 10.0, -5.0, 0.0), Some(keys3[0]));
            let knee = add(&format!("{x}knee"), Some(up), Vec3::new(0.0, -42.0, 0.0), Some(keys3[1]));
            add(&format!("{x}ankle"), Some(knee), Vec3::new(0.0, -43.0, 0.0), Some(keys3[2]));
        }
        (Skeleton::new(names, parents, offsets, 0.01).unwrap(), keys)
    }

    #[test]
    fn rest_poses_are_told_apart() {
        let (t, tk) = figure(1, 0.0, 1.0);
        let (a, ak) = figure(1, 45.0, 1.0);
        let (down, dk) = figure(1, 88.0, 1.0);
        assert_eq!(RestPose::detect(&t, &tk), RestPose::TPose);
        assert_eq!(RestPose::detect(&a, &ak), RestPose::APose);
        assert_eq!(RestPose::detect(&down, &dk), RestPose::Other);
    }

    /// A-pose source onto a T-pose target with another spine and size: every mapped bone
    /// points the same way, the hips travel scaled by leg length.
    #[test]
    fn bones_follow_the_source_across_rest_poses_and_sizes() {
        let (src, sk) = figure(0, 45.0, 1.0);
        let (dst, dk) = figure(3, 0.0, 1.2);
        let turn = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.3);
        let mut pose = LocalPose { rotations: vec![Quat::IDENTITY; src.len()], translations: src.offsets().to_vec() };
        pose.rotations[0] = turn;
        pose.rotations[sk.get(Key::LeftForeArm).unwrap()] = Quat::from_rotation_z(1.1);
        pose.rotations[sk.get(Key::RightLeg).unwrap()] = Quat::from_rotation_x(-0.8);
        pose.translations[0] = Vec3::new(50.0, 88.0, -20.0);
        let source = Motion::from_local_poses(Arc::new(src.clone()), 30.0, vec![pose]);
        let r = Retarget::new(&src, &sk, Arc::new(dst.clone()), &dk).unwrap();
        assert_eq!((r.source_rest, r.target_rest), (RestPose::APose, RestPose::TPose));
        let out = r.apply(&source);
        assert_eq!((out.frames(), out.fps, out.joints()), (1, 30.0, dst.len()));
        let (s, d) = (source.frame(0), out.frame(0));
        for (key, parent) in mapped_bones(&sk, &src, &dk, &dst) {
            let bone = |f: &[Vec3], k: &KeyJoints| (f[k.get(key).unwrap()] - f[k.get(parent).unwrap()]).normalize();
            let angle = bone(s, &sk).dot(bone(d, &dk)).clamp(-1.0, 1.0).acos().to_degrees();
            // Hips and chest fit several bones at once (least squares); single bones are exact.
            assert!(angle < 3.0, "{key:?} from {parent:?}: {angle} degrees");
        }
        let hips = d[dk.get(Key::Hips).unwrap()];
        assert!(hips.distance(Vec3::new(50.0, 88.0, -20.0) * 1.2) < 1e-3, "{hips}");
    }

    #[test]
    fn missing_keys_are_named() {
        let (src, mut sk) = figure(0, 0.0, 1.0);
        let (dst, dk) = figure(0, 0.0, 1.0);
        sk.set(Key::LeftForeArm, None);
        let e = Retarget::new(&src, &sk, Arc::new(dst), &dk).unwrap_err();
        assert_eq!(e.to_string(), "the source skeleton has no joint for LeftForeArm");
    }
}
