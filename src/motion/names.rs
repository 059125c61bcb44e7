//! What a joint's name says: its side and the words naming the limb joint, read the same way
//! for the joint roles ([`super::JointRoles`]) and the retargeting key joints
//! ([`super::guess_key_joints`]).
//!
//! Names are split into words (at separators, camel case and namespace prefixes such as
//! `mixamorig:`), a side is read off (`Left`/`L`/`l` first or last: `LeftArm`, `lShldr`,
//! `UpperArm_L`, `Bip01 L Thigh`, `left_elbow`, `lfemur`; else `Left` anywhere:
//! `Character1_LeftUpLeg`), and what remains is run together lower-case, to be looked up in
//! [`words`] (the roles look for the words inside it, the key joints for the exact word).

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Left,
    Right,
}

impl Side {
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];

    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }
}

/// Words naming each limb joint in the common rig conventions (h36m, Bandai, CMU, Mixamo,
/// Unreal, ...), lower-case: the one vocabulary of the roles and of the key joints, which
/// parse names into words and let the hierarchy choose.
pub mod words {
    pub const UPPER_ARM: &[&str] = &["arm", "upperarm", "armupper", "shldr", "shoulder", "humerus", "uparm"];
    pub const FOREARM: &[&str] = &["forearm", "lowerarm", "armlower", "elbow", "radius", "lowarm"];
    pub const HAND: &[&str] = &["hand", "wrist"];
    pub const THIGH: &[&str] = &["upleg", "upperleg", "legupper", "thigh", "femur", "hip"];
    pub const SHIN: &[&str] = &["leg", "lowerleg", "leglower", "knee", "shin", "calf", "tibia", "lowleg"];
    pub const ANKLE: &[&str] = &["foot", "ankle"];
    pub const TOES: &[&str] = &["toebase", "toe", "toes", "ball", "foot", "toe0"];
}

/// Prefixes some exporters put before every name.
const RIG_PREFIXES: &[&str] = &["mixamorig", "bip01", "bip001", "biped", "def", "jnt", "bn"];

/// A joint name as the side it names (none for the trunk and the head) and the words left
/// when the side and any rig prefix are removed, lower-case and run together
/// (`mixamorig:LeftUpLeg` -> (Left, "upleg")).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JointName {
    pub side: Option<Side>,
    pub part: String,
}

impl JointName {
    pub fn parse(name: &str) -> JointName {
        let mut words = words_of(name);
        words.retain(|w| !RIG_PREFIXES.contains(&w.as_str()));
        let side_of = |w: &str| match w {
            "left" | "l" => Some(Side::Left),
            "right" | "r" => Some(Side::Right),
            _ => None,
        };
        let mut side = None;
        if let Some(s) = words.first().and_then(|w| side_of(w)) {
            side = Some(s);
            words.remove(0);
        } else if let Some(s) = words.last().and_then(|w| side_of(w)) {
            side = Some(s);
            words.pop();
        } else if let Some(k) = words.iter().position(|w| w == "left" || w == "right") {
            // After a character's own prefix (`Character1_LeftUpLeg`).
            side = side_of(&words.remove(k));
        }
        let mut part = words.concat();
        if side.is_none() {
            // Run-together forms: "leftarm", "lfemur", "rhumerus", "LHand".
            for (prefix, s) in [("left", Side::Left), ("right", Side::Right), ("l", Side::Left), ("r", Side::Right)] {
                if let Some(rest) = part.strip_prefix(prefix).filter(|rest| is_limb_word(rest)) {
                    side = Some(s);
                    part = rest.to_string();
                    break;
                }
            }
        }
        JointName { side, part }
    }

    /// A collapsed end site or a marker rather than a joint (`HeadTop_End`, `ToeSite`,
    /// `Hand_Nub`).
    pub fn is_end_site(&self) -> bool {
        ["end", "site", "top", "nub"].iter().any(|e| self.part.contains(e))
    }
}

/// The words of a name after its last namespace (`:`, `|`), lower-case, split at every
/// separator and where a lower-case letter or digit meets a capital.
fn words_of(name: &str) -> Vec<String> {
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
    words
}

fn is_limb_word(word: &str) -> bool {
    use words::*;
    [UPPER_ARM, FOREARM, HAND, THIGH, SHIN, ANKLE, TOES].iter().any(|list| list.contains(&word))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_of_the_common_conventions_parse() {
        let cases = [
            ("mixamorig:LeftUpLeg", Some(Side::Left), "upleg"),
            ("lShldr", Some(Side::Left), "shldr"),
            ("rForeArm", Some(Side::Right), "forearm"),
            ("rShin", Some(Side::Right), "shin"),
            ("UpperArm_L", Some(Side::Left), "upperarm"),
            ("LowerArm_R", Some(Side::Right), "lowerarm"),
            ("Bip01 R Thigh", Some(Side::Right), "thigh"),
            ("left_elbow", Some(Side::Left), "elbow"),
            ("lfemur", Some(Side::Left), "femur"),
            ("rhumerus", Some(Side::Right), "humerus"),
            ("RHand", Some(Side::Right), "hand"),
            ("LHipJoint", None, "lhipjoint"),
            ("RightToeBase", Some(Side::Right), "toebase"),
            ("Hips", None, "hips"),
            ("lowerback", None, "lowerback"),
            ("HeadTop_End", None, "headtopend"),
            ("upperarm_l", Some(Side::Left), "upperarm"),
            ("calf_r", Some(Side::Right), "calf"),
            ("ball_l", Some(Side::Left), "ball"),
            ("spine_01", None, "spine01"),
            ("Character1_LeftUpLeg", Some(Side::Left), "character1upleg"),
        ];
        for (name, side, part) in cases {
            assert_eq!(JointName::parse(name), JointName { side, part: part.to_string() }, "{name}");
        }
    }
}
