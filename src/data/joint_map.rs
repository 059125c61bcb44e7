//! A user's joint mapping (`--joint-map FILE`, JSON `{"joint name in the file": "Key"}`, keys
//! as [`Key::name`] spells them), and the key joints of a skeleton it is checked against: the
//! user's entries settle what the name table cannot, the rest is still found automatically
//! around them ([`KeyJoints::fill_by_names`]).

use std::path::Path;

use anyhow::{bail, Context, Result};

use crate::motion::{Key, KeyJoints, Skeleton};

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
    keys.fill_by_names(skeleton);
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

#[cfg(test)]
mod tests {
    use super::*;

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
