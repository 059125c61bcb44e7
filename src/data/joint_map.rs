//! Finding a humanoid's key joints ([`Key`]) by name, for retargeting.
//!
//! Names are split into words (at separators, camel case and namespace prefixes such as
//! `mixamorig:`), a side is read off (`Left`/`L`/`l` first or last: `LeftArm`, `lShldr`,
//! `UpperArm_L`, `Bip01 L Thigh`, `left_elbow`, `lfemur`), and what remains is looked up in a
//! table of the words the common conventions use for each limb joint:
//!
//! | key | CMU (acLSTM) | CMU (ASF) | Mixamo / Human3.6M | Bandai | SMPL | Unreal |
//! |---|---|---|---|---|---|---|
//! | arm | lShldr | lhumerus | LeftArm | UpperArm_L | left_shoulder | upperarm_l |
//! | forearm | lForeArm | lradius | LeftForeArm | LowerArm_L | left_elbow | lowerarm_l |
//! | hand | lHand | lwrist | LeftHand | Hand_L | left_wrist | hand_l |
//! | thigh | lThigh | lfemur | LeftUpLeg | UpperLeg_L | left_hip | thigh_l |
//! | shin | lShin | ltibia | LeftLeg | LowerLeg_L | left_knee | calf_l |
//! | foot | lFoot | lfoot | LeftFoot | Foot_L | left_ankle | foot_l |
//! | toes | - | ltoes | LeftToeBase | Toes_L | left_foot | ball_l |
//!
//! Words shared between conventions with different meanings ("shoulder" is Mixamo's collar
//! and SMPL's upper arm, "foot" Mixamo's ankle and SMPL's toes) are settled by the hierarchy:
//! the forearm is found first, the upper arm is its nearest named ancestor, the hand its
//! nearest named descendant (and likewise thigh, ankle and toes around the knee). The trunk
//! is found by structure alone: the hips are where the legs meet, the chest where the arms
//! meet, the collar the joint between chest and upper arm, the neck the joint after the chest
//! on the way to the head.
//!
//! A user mapping (`--joint-map FILE`, JSON `{"joint name in the file": "Key"}`, keys as
//! [`Key::name`] spells them) settles what the table cannot; the rest is still found
//! automatically around it.

use std::path::Path;

use anyhow::{bail, Context, Result};

use crate::motion::words::{ANKLE, FOREARM, HAND, SHIN, THIGH, TOES, UPPER_ARM};
use crate::motion::{Key, KeyJoints, Skeleton};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    Left,
    Right,
    Centre,
}

/// Prefixes some exporters put before every name.
const RIG_PREFIXES: &[&str] = &["mixamorig", "bip01", "bip001", "biped", "def", "jnt", "bn"];

/// A joint name's side and the words left when the side and any rig prefix are removed,
/// lower-case and run together (`mixamorig:LeftUpLeg` -> (Left, "upleg")).
fn parse_name(name: &str) -> (Side, String) {
    let base = name.rsplit([':', '|']).next().unwrap_or(name);
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    let mut previous_lower = false;
    for c in base.chars() {
        if !c.is_ascii_alphanumeric() {
            words.extend((!word.is_empty()).then(|| std::mem::take(&mut word)));
            previous_lower = false;
            continue;
        }
        if c.is_ascii_uppercase() && previous_lower {
            words.push(std::mem::take(&mut word));
        }
        previous_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
        word.push(c.to_ascii_lowercase());
    }
    words.extend((!word.is_empty()).then_some(word));
    words.retain(|w| !RIG_PREFIXES.contains(&w.as_str()));
    let side_of = |w: &str| match w {
        "left" | "l" => Some(Side::Left),
        "right" | "r" => Some(Side::Right),
        _ => None,
    };
    let mut side = Side::Centre;
    if let Some(s) = words.first().and_then(|w| side_of(w)) {
        side = s;
        words.remove(0);
    } else if let Some(s) = words.last().and_then(|w| side_of(w)) {
        side = s;
        words.pop();
    }
    let mut part = words.concat();
    if side == Side::Centre {
        // Run-together forms: "leftarm", "lfemur", "rhumerus", "LHip".
        for (prefix, s) in [("left", Side::Left), ("right", Side::Right), ("l", Side::Left), ("r", Side::Right)] {
            if let Some(rest) = part.strip_prefix(prefix) {
                if is_limb_word(rest) {
                    side = s;
                    part = rest.to_string();
                    break;
                }
            }
        }
    }
    (side, part)
}

fn is_limb_word(word: &str) -> bool {
    [UPPER_ARM, FOREARM, HAND, THIGH, SHIN, ANKLE, TOES].iter().any(|list| list.contains(&word))
}

/// A user's joint mapping: (joint name in the file, key).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UserJointMap {
    pub entries: Vec<(String, Key)>,
}

impl UserJointMap {
    /// Reads `{"joint name": "Key", ...}`; every problem is one line naming the file.
    pub fn read(path: &Path) -> Result<UserJointMap> {
        let name = path.display();
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read joint map {name}"))?;
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{name}: not JSON ({e})"))?;
        Self::from_value(&value, &name.to_string())
    }

    /// The mapping in `value` (`name` names it in errors), as a file or a project holds it.
    pub fn from_value(value: &serde_json::Value, name: &str) -> Result<UserJointMap> {
        let Some(object) = value.as_object() else {
            bail!("{name}: expected a JSON object of \"joint name\": \"Key\" pairs");
        };
        let mut entries = Vec::new();
        for (joint, key) in object {
            let Some(key_name) = key.as_str() else {
                bail!("{name}: the value for '{joint}' must be a key name in quotes, found {key}");
            };
            let Some(key) = Key::from_name(key_name) else {
                let names: Vec<&str> = Key::ALL.iter().map(|k| k.name()).collect();
                bail!("{name}: '{key_name}' (for '{joint}') is not a key joint; use one of {}", names.join(", "));
            };
            entries.push((joint.clone(), key));
        }
        Ok(UserJointMap { entries })
    }
}

/// The key joints of `skeleton` (read from `file`, named in messages): the user's entries,
/// then the name table and the hierarchy for the rest. A skeleton missing a required key is
/// an error that names the missing keys and the joints the file has.
pub fn key_joints(skeleton: &Skeleton, user: Option<&UserJointMap>, file: &str) -> Result<KeyJoints> {
    let mut keys = KeyJoints::default();
    for (joint, key) in user.map_or(&[][..], |u| &u.entries[..]) {
        let j = skeleton.index_of(joint).with_context(|| format!("{file}: the joint map names '{joint}', which is not a joint of this skeleton"))?;
        keys.set(*key, Some(j));
    }
    fill_by_names(skeleton, &mut keys);
    let missing = keys.missing_required();
    if !missing.is_empty() {
        let names: Vec<&str> = missing.iter().map(|k| k.name()).collect();
        // Clipped: a hostile file's joint name can be megabytes long.
        let shown: Vec<String> = skeleton.names().iter().take(12).map(|n| crate::motion::clipped(n)).collect();
        let more = if skeleton.len() > shown.len() { format!(", ... ({} in all)", skeleton.len()) } else { String::new() };
        bail!(
            "{file}: cannot map this skeleton onto a humanoid: no joint found for {} (its joints: {}{more}); name them in a --joint-map file",
            names.join(", "),
            shown.join(", ")
        );
    }
    Ok(keys)
}

/// What the name table and the hierarchy find in `skeleton`, missing keys left empty (the
/// studio's joint-mapping editor starts from these guesses).
pub fn guess_key_joints(skeleton: &Skeleton) -> KeyJoints {
    let mut keys = KeyJoints::default();
    fill_by_names(skeleton, &mut keys);
    keys
}

/// Fills the keys `keys` does not have yet from the name table and the hierarchy.
fn fill_by_names(skeleton: &Skeleton, keys: &mut KeyJoints) {
    let finder = Finder { skeleton, parsed: skeleton.names().iter().map(|n| parse_name(n)).collect() };
    finder.fill(keys);
}

struct Finder<'a> {
    skeleton: &'a Skeleton,
    parsed: Vec<(Side, String)>,
}

impl Finder<'_> {
    fn fill(&self, keys: &mut KeyJoints) {
        use Key::*;
        for (side, arm) in [(Side::Left, [LeftArm, LeftForeArm, LeftHand]), (Side::Right, [RightArm, RightForeArm, RightHand])] {
            self.fill_limb(keys, side, arm, [UPPER_ARM, FOREARM, HAND]);
        }
        for (side, [thigh, shin, ankle, toes]) in [(Side::Left, [LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase]), (Side::Right, [RightUpLeg, RightLeg, RightFoot, RightToeBase])] {
            self.fill_limb(keys, side, [thigh, shin, ankle], [THIGH, SHIN, ANKLE]);
            if keys.get(toes).is_none() {
                let found = keys.get(ankle).and_then(|a| self.nearest_descendant(a, side, TOES));
                keys.set(toes, found);
            }
        }
        self.fill_trunk(keys);
    }

    /// The middle joint by its words (the first one in joint order), then the upper joint as
    /// its nearest named ancestor (else its parent) and the lower as its nearest named
    /// descendant.
    fn fill_limb(&self, keys: &mut KeyJoints, side: Side, [upper, middle, lower]: [Key; 3], [upper_words, middle_words, lower_words]: [&[&str]; 3]) {
        let first_named = |words: &[&str]| (0..self.skeleton.len()).find(|&j| self.is(j, side, words));
        if keys.get(middle).is_none() {
            keys.set(middle, first_named(middle_words));
        }
        let Some(m) = keys.get(middle) else {
            // Without the middle joint the others are still worth finding (for the message).
            for (key, words) in [(upper, upper_words), (lower, lower_words)] {
                if keys.get(key).is_none() {
                    keys.set(key, first_named(words));
                }
            }
            return;
        };
        if keys.get(upper).is_none() {
            let mut a = self.skeleton.parents()[m];
            let mut found = None;
            while let Some(j) = a {
                if self.is(j, side, upper_words) {
                    found = Some(j);
                    break;
                }
                a = self.skeleton.parents()[j];
            }
            keys.set(upper, found.or(self.skeleton.parents()[m]));
        }
        if keys.get(lower).is_none() {
            keys.set(lower, self.nearest_descendant(m, side, lower_words));
        }
    }

    /// Hips where the thighs meet, chest where the upper arms meet, collars between chest and
    /// upper arms, the head by name below the chest, the neck between chest and head.
    fn fill_trunk(&self, keys: &mut KeyJoints) {
        use Key::*;
        let meet = |keys: &KeyJoints, a: Key, b: Key| self.common_ancestor(keys.get(a)?, keys.get(b)?);
        if keys.get(Hips).is_none() {
            keys.set(Hips, meet(keys, LeftUpLeg, RightUpLeg));
        }
        if keys.get(Chest).is_none() {
            keys.set(Chest, meet(keys, LeftArm, RightArm));
        }
        let Some(chest) = keys.get(Chest) else { return };
        for (collar, arm) in [(LeftShoulder, LeftArm), (RightShoulder, RightArm)] {
            if keys.get(collar).is_none() {
                keys.set(collar, keys.get(arm).and_then(|a| self.child_towards(chest, a)).filter(|&c| Some(c) != keys.get(arm)));
            }
        }
        if keys.get(Head).is_none() {
            let head = (0..self.skeleton.len()).find(|&j| self.parsed[j] == (Side::Centre, "head".to_string()) && self.is_below(j, chest));
            keys.set(Head, head);
        }
        if keys.get(Neck).is_none() {
            keys.set(Neck, keys.get(Head).and_then(|h| self.child_towards(chest, h)).filter(|&n| Some(n) != keys.get(Head)));
        }
    }

    fn is(&self, joint: usize, side: Side, words: &[&str]) -> bool {
        let (s, part) = &self.parsed[joint];
        *s == side && words.contains(&part.as_str())
    }

    /// The named descendant of `joint` fewest bones away (ties: the first in joint order).
    fn nearest_descendant(&self, joint: usize, side: Side, words: &[&str]) -> Option<usize> {
        (joint + 1..self.skeleton.len())
            .filter(|&j| self.is(j, side, words))
            .filter_map(|j| self.depth_below(j, joint).map(|d| (d, j)))
            .min()
            .map(|(_, j)| j)
    }

    /// How many bones `joint` is below `ancestor` (None when it is not below it).
    fn depth_below(&self, joint: usize, ancestor: usize) -> Option<usize> {
        let mut depth = 0;
        let mut a = Some(joint);
        while let Some(j) = a {
            if j == ancestor {
                return Some(depth);
            }
            depth += 1;
            a = self.skeleton.parents()[j];
        }
        None
    }

    fn is_below(&self, joint: usize, ancestor: usize) -> bool {
        joint != ancestor && self.depth_below(joint, ancestor).is_some()
    }

    fn common_ancestor(&self, a: usize, b: usize) -> Option<usize> {
        let mut x = Some(a);
        while let Some(j) = x {
            if self.depth_below(b, j).is_some() {
                return Some(j);
            }
            x = self.skeleton.parents()[j];
        }
        None
    }

    /// The child of `ancestor` on the way down to `joint`.
    fn child_towards(&self, ancestor: usize, joint: usize) -> Option<usize> {
        let mut j = joint;
        loop {
            let p = self.skeleton.parents()[j]?;
            if p == ancestor {
                return Some(j);
            }
            j = p;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_of_the_common_conventions_parse() {
        let cases = [
            ("mixamorig:LeftUpLeg", Side::Left, "upleg"),
            ("lShldr", Side::Left, "shldr"),
            ("rForeArm", Side::Right, "forearm"),
            ("UpperArm_L", Side::Left, "upperarm"),
            ("Bip01 R Thigh", Side::Right, "thigh"),
            ("left_elbow", Side::Left, "elbow"),
            ("lfemur", Side::Left, "femur"),
            ("rhumerus", Side::Right, "humerus"),
            ("LHipJoint", Side::Centre, "lhipjoint"),
            ("RightToeBase", Side::Right, "toebase"),
            ("Hips", Side::Centre, "hips"),
            ("lowerback", Side::Centre, "lowerback"),
            ("HeadTop_End", Side::Centre, "headtopend"),
            ("upperarm_l", Side::Left, "upperarm"),
            ("calf_r", Side::Right, "calf"),
            ("ball_l", Side::Left, "ball"),
            ("spine_01", Side::Centre, "spine01"),
        ];
        for (name, side, part) in cases {
            assert_eq!(parse_name(name), (side, part.to_string()), "{name}");
        }
    }

    /// Blender's export of an Unreal-mannequin-named rig (tests/assets): the table and the
    /// hierarchy put every key on the joint an Unreal user means.
    #[test]
    fn unreal_mannequin_names_find_their_keys() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/assets/blender-unreal-salsa.bvh");
        let motion = crate::data::bvh::read_bvh(&std::fs::read_to_string(path).unwrap(), path).unwrap();
        let keys = key_joints(&motion.skeleton, None, path).unwrap();
        let expected = [
            "pelvis", "spine_02", "neck_01", "head", "clavicle_l", "upperarm_l", "lowerarm_l", "hand_l", "clavicle_r", "upperarm_r", "lowerarm_r", "hand_r",
            "thigh_l", "calf_l", "foot_l", "ball_l", "thigh_r", "calf_r", "foot_r", "ball_r",
        ];
        for (key, joint) in Key::ALL.iter().zip(expected) {
            assert_eq!(keys.get(*key).map(|j| motion.skeleton.names()[j].as_str()), Some(joint), "{}", key.name());
        }
    }
}
