//! Joint names that other tools map by themselves (`--joint-names`): an exported skeleton's
//! joints renamed by the role they play, so Mixamo-based tools, Unreal's IK Retargeter and
//! Unity's Humanoid avatar recognise the rig without a bone-by-bone mapping.
//!
//! Roles come from the key joints (`data::joint_map`: hips, chest, neck, head, collars, arms,
//! forearms, hands, thighs, shins, feet, toes) and the joint roles' end sites
//! (`motion::roles`: the top of the head, the tips of the toes). The joints between the hips
//! and the chest are the spine, numbered from the hips; those between the chest and the
//! head, the neck. Any other joint (a hand's end sites, a twist joint) keeps its own name
//! behind the convention's prefix. Mixamo and Unity names also bring the T-pose rest those
//! tools expect ([`super::t_pose`]); the Unreal mannequin keeps the skeleton's own rest.
//! Hierarchy and every frame's joint positions stay as they are.

use std::sync::Arc;

use anyhow::{Context, Result};

use crate::data::joint_map::{key_joints, UserJointMap};
use super::t_pose::in_t_pose;
use crate::motion::{JointRoles, Key, KeyJoints, Motion, Side, Skeleton};

/// The naming convention of an exported skeleton.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointNames {
    /// The model's (or the retarget rig's) own names.
    Native,
    /// `mixamorig:Hips`, `mixamorig:LeftUpLeg`, ..., in a T-pose rest.
    Mixamo,
    /// The Unreal mannequin's `pelvis`, `spine_01`, `thigh_l`, `ball_l`, ...
    Unreal,
    /// Unity Mecanim's humanoid bone names: `Hips`, `LeftUpperLeg`, `LeftToes`, ..., in a
    /// T-pose rest.
    Unity,
}

/// Where a joint sits in the body, beyond its key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Key(Key),
    /// The `index`-th of `count` joints from the hips up to the chest (the chest last).
    Spine { index: usize, count: usize },
    /// The `index`-th joint between the chest and the head.
    Neck { index: usize },
    HeadEnd,
    ToeEnd(Side),
}

impl JointNames {
    /// The take with its skeleton's joints renamed. Key joints are found by the name table
    /// and the hierarchy, after the entries of the user's joint map that name this skeleton's
    /// joints (a retarget rig's own mapping).
    pub fn apply(self, motion: &Motion, user_map: Option<&UserJointMap>) -> Result<Motion> {
        if self == JointNames::Native {
            return Ok(motion.clone());
        }
        let s = &motion.skeleton;
        let own = user_map.map(|m| UserJointMap { entries: m.entries.iter().filter(|(joint, _)| s.index_of(joint).is_some()).cloned().collect() });
        let keys = key_joints(s, own.as_ref(), &format!("--joint-names {}", self.label()))?;
        let roles = joint_roles(s, &keys);
        let names = s.names().iter().zip(&roles).map(|(native, role)| self.name(native, *role)).collect();
        let skeleton = Skeleton::new(names, s.parents().to_vec(), s.offsets().to_vec(), s.meters_per_unit()).with_context(|| format!("--joint-names {}: the renamed skeleton", self.label()))?;
        let mut out = motion.clone();
        out.skeleton = Arc::new(skeleton);
        match self {
            JointNames::Mixamo | JointNames::Unity => in_t_pose(&out, &keys),
            JointNames::Native | JointNames::Unreal => Ok(out),
        }
    }

    fn label(self) -> &'static str {
        match self {
            JointNames::Native => "native",
            JointNames::Mixamo => "mixamo",
            JointNames::Unreal => "unreal",
            JointNames::Unity => "unity",
        }
    }

    fn name(self, native: &str, role: Option<Role>) -> String {
        let named = role.and_then(|r| match self {
            JointNames::Native => None,
            JointNames::Mixamo => Some(format!("mixamorig:{}", mixamo(r))),
            JointNames::Unreal => unreal(r),
            JointNames::Unity => unity(r),
        });
        named.unwrap_or_else(|| format!("{}{native}", self.unrole_prefix()))
    }

    /// What a joint without a name in the convention is prefixed with: Mixamo's namespace,
    /// which it gives every bone, or a mark that keeps it apart from the convention's names.
    fn unrole_prefix(self) -> &'static str {
        match self {
            JointNames::Native => "",
            JointNames::Mixamo => "mixamorig:",
            JointNames::Unreal | JointNames::Unity => "glocal_",
        }
    }
}

/// Each joint's role, where it has one.
fn joint_roles(s: &Skeleton, keys: &KeyJoints) -> Vec<Option<Role>> {
    let mut roles = vec![None; s.len()];
    for (key, j) in keys.mapped() {
        roles[j] = Some(Role::Key(key));
    }
    if let (Some(hips), Some(chest)) = (keys.get(Key::Hips), keys.get(Key::Chest)) {
        let spine = chain_between(s, hips, chest);
        let count = spine.len() + 1;
        for (index, j) in spine.into_iter().chain([chest]).enumerate() {
            roles[j] = Some(Role::Spine { index, count });
        }
        if let Some(head) = keys.get(Key::Head) {
            for (index, j) in chain_between(s, chest, head).into_iter().enumerate() {
                roles[j] = Some(Role::Neck { index });
            }
        }
    }
    if let Ok(found) = JointRoles::new(s) {
        let mut mark = |joint: Option<usize>, role: Role| {
            if let Some(j) = joint.filter(|&j| roles[j].is_none()) {
                roles[j] = Some(role);
            }
        };
        mark(found.head_end, Role::HeadEnd);
        for side in Side::BOTH {
            mark(found.leg(side).toe_end, Role::ToeEnd(side));
        }
    }
    roles
}

/// The joints strictly between `ancestor` and `joint`, from the ancestor down (empty when
/// `joint` is not below `ancestor`).
fn chain_between(s: &Skeleton, ancestor: usize, joint: usize) -> Vec<usize> {
    let mut chain = Vec::new();
    let mut j = s.parents()[joint];
    while let Some(p) = j {
        if p == ancestor {
            chain.reverse();
            return chain;
        }
        chain.push(p);
        j = s.parents()[p];
    }
    Vec::new()
}

fn side_word(side: Side) -> &'static str {
    match side {
        Side::Left => "Left",
        Side::Right => "Right",
    }
}

/// A key's side and its limb word in Mixamo's spelling (`LeftForeArm` -> (Left, "ForeArm")).
fn limb(key: Key) -> Option<(Side, &'static str)> {
    let name = key.name();
    let (side, part) = match name.strip_prefix("Left") {
        Some(part) => (Side::Left, part),
        None => (Side::Right, name.strip_prefix("Right")?),
    };
    Some((side, part))
}

fn numbered(word: &str, index: usize) -> String {
    if index == 0 {
        word.to_string()
    } else {
        format!("{word}{index}")
    }
}

fn mixamo(role: Role) -> String {
    match role {
        Role::Key(key) => key.name().to_string(),
        Role::Spine { index, .. } => numbered("Spine", index),
        Role::Neck { index } => numbered("Neck", index),
        Role::HeadEnd => "HeadTop_End".into(),
        Role::ToeEnd(side) => format!("{}Toe_End", side_word(side)),
    }
}

fn unreal(role: Role) -> Option<String> {
    let side_suffix = |side: Side| if side == Side::Left { "l" } else { "r" };
    Some(match role {
        Role::Key(Key::Hips) => "pelvis".into(),
        Role::Key(Key::Head) => "head".into(),
        Role::Key(key) => {
            let (side, part) = limb(key)?;
            let word = match part {
                "Shoulder" => "clavicle",
                "Arm" => "upperarm",
                "ForeArm" => "lowerarm",
                "Hand" => "hand",
                "UpLeg" => "thigh",
                "Leg" => "calf",
                "Foot" => "foot",
                "ToeBase" => "ball",
                _ => return None,
            };
            format!("{word}_{}", side_suffix(side))
        }
        Role::Spine { index, .. } => format!("spine_{:02}", index + 1),
        Role::Neck { index } => format!("neck_{:02}", index + 1),
        Role::HeadEnd | Role::ToeEnd(_) => return None,
    })
}

/// Mecanim's spine is Spine, Chest, UpperChest (the last two optional): a shorter chain
/// takes the first names, a longer one keeps Chest and UpperChest for its top two joints.
fn unity(role: Role) -> Option<String> {
    const SPINE: [&str; 3] = ["Spine", "Chest", "UpperChest"];
    Some(match role {
        Role::Key(key) => match limb(key) {
            None => key.name().to_string(),
            Some((side, part)) => {
                let word = match part {
                    "Arm" => "UpperArm",
                    "ForeArm" => "LowerArm",
                    "UpLeg" => "UpperLeg",
                    "Leg" => "LowerLeg",
                    "ToeBase" => "Toes",
                    other => other,
                };
                format!("{}{word}", side_word(side))
            }
        },
        Role::Spine { index, count } if count <= SPINE.len() => SPINE[index].into(),
        Role::Spine { index: 0, .. } => "Spine".into(),
        Role::Spine { index, count } if index + 2 >= count => SPINE[3 - (count - index)].into(),
        Role::Neck { index: 0 } => "Neck".into(),
        Role::Spine { .. } | Role::Neck { .. } | Role::HeadEnd | Role::ToeEnd(_) => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unity_spines_keep_chest_and_upper_chest_on_top() {
        let names = |count: usize| (0..count).map(|index| unity(Role::Spine { index, count })).collect::<Vec<_>>();
        assert_eq!(names(1), [Some("Spine".to_string())]);
        assert_eq!(names(2), [Some("Spine".to_string()), Some("Chest".to_string())]);
        assert_eq!(names(4), [Some("Spine".to_string()), None, Some("Chest".to_string()), Some("UpperChest".to_string())]);
    }

    #[test]
    fn unreal_limbs_take_the_mannequin_names() {
        assert_eq!(unreal(Role::Key(Key::LeftToeBase)).as_deref(), Some("ball_l"));
        assert_eq!(unreal(Role::Key(Key::RightForeArm)).as_deref(), Some("lowerarm_r"));
        assert_eq!(unreal(Role::Spine { index: 2, count: 3 }).as_deref(), Some("spine_03"));
    }
}
