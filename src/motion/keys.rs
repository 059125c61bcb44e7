//! The key joints a humanoid is retargeted by ([`Key`]: hips, chest, neck, head, collars,
//! arms, forearms, hands, thighs, shins, feet, toes), and finding them by name.
//!
//! A name is read as a side and words ([`JointName`]), and the words are looked up in the
//! table the common conventions use for each limb joint ([`words`]):
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
//! on the way to the head. A user's mapping (`data::joint_map`) settles what the table cannot.

use super::names::words::{ANKLE, FOREARM, HAND, SHIN, THIGH, TOES, UPPER_ARM};
use super::names::{JointName, Side};
use super::Skeleton;

/// The joints a humanoid is mapped by, named as Mixamo (and Human3.6M) name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Key {
    Hips,
    Chest,
    Neck,
    Head,
    LeftShoulder,
    LeftArm,
    LeftForeArm,
    LeftHand,
    RightShoulder,
    RightArm,
    RightForeArm,
    RightHand,
    LeftUpLeg,
    LeftLeg,
    LeftFoot,
    LeftToeBase,
    RightUpLeg,
    RightLeg,
    RightFoot,
    RightToeBase,
}

impl Key {
    pub const ALL: [Key; 20] = [
        Key::Hips,
        Key::Chest,
        Key::Neck,
        Key::Head,
        Key::LeftShoulder,
        Key::LeftArm,
        Key::LeftForeArm,
        Key::LeftHand,
        Key::RightShoulder,
        Key::RightArm,
        Key::RightForeArm,
        Key::RightHand,
        Key::LeftUpLeg,
        Key::LeftLeg,
        Key::LeftFoot,
        Key::LeftToeBase,
        Key::RightUpLeg,
        Key::RightLeg,
        Key::RightFoot,
        Key::RightToeBase,
    ];

    /// Without these a body cannot be posed: the trunk, both arms and both legs down to the
    /// hands and feet. Neck, collars and toes are used when both skeletons have them.
    pub fn is_required(self) -> bool {
        !matches!(self, Key::Neck | Key::LeftShoulder | Key::RightShoulder | Key::LeftToeBase | Key::RightToeBase)
    }

    pub fn name(self) -> &'static str {
        match self {
            Key::Hips => "Hips",
            Key::Chest => "Chest",
            Key::Neck => "Neck",
            Key::Head => "Head",
            Key::LeftShoulder => "LeftShoulder",
            Key::LeftArm => "LeftArm",
            Key::LeftForeArm => "LeftForeArm",
            Key::LeftHand => "LeftHand",
            Key::RightShoulder => "RightShoulder",
            Key::RightArm => "RightArm",
            Key::RightForeArm => "RightForeArm",
            Key::RightHand => "RightHand",
            Key::LeftUpLeg => "LeftUpLeg",
            Key::LeftLeg => "LeftLeg",
            Key::LeftFoot => "LeftFoot",
            Key::LeftToeBase => "LeftToeBase",
            Key::RightUpLeg => "RightUpLeg",
            Key::RightLeg => "RightLeg",
            Key::RightFoot => "RightFoot",
            Key::RightToeBase => "RightToeBase",
        }
    }

    /// The key of a name as [`Key::name`] spells it (case-insensitive).
    pub fn from_name(name: &str) -> Option<Key> {
        Key::ALL.into_iter().find(|k| k.name().eq_ignore_ascii_case(name))
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// Which joint of one skeleton plays each key joint.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KeyJoints {
    joints: [Option<usize>; 20],
}

impl KeyJoints {
    pub fn get(&self, key: Key) -> Option<usize> {
        self.joints[key.index()]
    }

    pub fn set(&mut self, key: Key, joint: Option<usize>) {
        self.joints[key.index()] = joint;
    }

    /// The required keys ([`Key::is_required`]) that have no joint.
    pub fn missing_required(&self) -> Vec<Key> {
        Key::ALL.into_iter().filter(|k| k.is_required() && self.get(*k).is_none()).collect()
    }

    /// (key, joint) for every mapped key.
    pub fn mapped(&self) -> impl Iterator<Item = (Key, usize)> + '_ {
        Key::ALL.into_iter().filter_map(|k| self.get(k).map(|j| (k, j)))
    }

    /// Fills the keys not set yet (a user's mapping sets some first) from the name table and
    /// the hierarchy.
    pub fn fill_by_names(&mut self, skeleton: &Skeleton) {
        let finder = Finder { skeleton, parsed: skeleton.names().iter().map(|n| JointName::parse(n)).collect() };
        finder.fill(self);
    }
}

/// What the name table and the hierarchy find in `skeleton`, missing keys left empty (the
/// studio's joint-mapping editor starts from these guesses).
pub fn guess_key_joints(skeleton: &Skeleton) -> KeyJoints {
    let mut keys = KeyJoints::default();
    keys.fill_by_names(skeleton);
    keys
}

struct Finder<'a> {
    skeleton: &'a Skeleton,
    parsed: Vec<JointName>,
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
            let named = self.skeleton.ancestors(m).find(|&j| self.is(j, side, upper_words));
            keys.set(upper, named.or(self.skeleton.parents()[m]));
        }
        if keys.get(lower).is_none() {
            keys.set(lower, self.nearest_descendant(m, side, lower_words));
        }
    }

    /// Hips where the thighs meet, chest where the upper arms meet, collars between chest and
    /// upper arms, the head by name below the chest, the neck between chest and head.
    fn fill_trunk(&self, keys: &mut KeyJoints) {
        use Key::*;
        let s = self.skeleton;
        let meet = |keys: &KeyJoints, a: Key, b: Key| Some(s.common_ancestor(keys.get(a)?, keys.get(b)?));
        if keys.get(Hips).is_none() {
            keys.set(Hips, meet(keys, LeftUpLeg, RightUpLeg));
        }
        if keys.get(Chest).is_none() {
            keys.set(Chest, meet(keys, LeftArm, RightArm));
        }
        let Some(chest) = keys.get(Chest) else { return };
        for (collar, arm) in [(LeftShoulder, LeftArm), (RightShoulder, RightArm)] {
            if keys.get(collar).is_none() {
                keys.set(collar, keys.get(arm).and_then(|a| s.child_towards(chest, a)).filter(|&c| Some(c) != keys.get(arm)));
            }
        }
        if keys.get(Head).is_none() {
            let head = (0..s.len()).find(|&j| self.parsed[j] == JointName { side: None, part: "head".into() } && j != chest && s.is_ancestor(chest, j));
            keys.set(Head, head);
        }
        if keys.get(Neck).is_none() {
            keys.set(Neck, keys.get(Head).and_then(|h| s.child_towards(chest, h)).filter(|&n| Some(n) != keys.get(Head)));
        }
    }

    fn is(&self, joint: usize, side: Side, words: &[&str]) -> bool {
        let name = &self.parsed[joint];
        name.side == Some(side) && words.contains(&name.part.as_str())
    }

    /// The named descendant of `joint` fewest bones away (ties: the first in joint order).
    fn nearest_descendant(&self, joint: usize, side: Side, words: &[&str]) -> Option<usize> {
        (joint + 1..self.skeleton.len())
            .filter(|&j| self.is(j, side, words))
            .filter_map(|j| self.skeleton.depth_below(j, joint).map(|d| (d, j)))
            .min()
            .map(|(_, j)| j)
    }
}
