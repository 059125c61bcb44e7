//! A request carried from one model to another and back: a switch remembers the request
//! before and after it ([`ModelSwitch`]), so switching back restores every segment, start and
//! key the user left as the switch made it, instead of mapping a mapped name again (h36m's
//! `posing` went to Bandai's `bow` and came back as `greeting`). Key poses are moved onto the
//! new model's skeleton by [`pose_onto`].

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use glam::Vec3;

use super::{GenerateOptions, Key};
use crate::data::joint_map::key_joints;
use crate::model::spec::ModelSpec;
use crate::motion::{Motion, Retarget};

/// One model switch: the model folders and the request before and after it.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSwitch {
    pub from: PathBuf,
    pub to: PathBuf,
    before: GenerateOptions,
    after: GenerateOptions,
}

/// A request on its way back over a switch: the options with what came back restored, and
/// which keys did (the others are still the other model's).
pub struct Restored {
    pub options: GenerateOptions,
    pub keys: Vec<bool>,
}

impl ModelSwitch {
    pub fn new(from: PathBuf, to: PathBuf, before: GenerateOptions, after: GenerateOptions) -> Self {
        Self { from, to, before, after }
    }

    /// The request after the switch as it settled (a start the new model could not take
    /// replaced once checked).
    pub fn settle(&mut self, after: GenerateOptions) {
        self.after = after;
    }

    /// `options` (on the switch's `to` model) back on its `from` model: each segment whose
    /// class is still the one the switch gave it (by position), the start and each key still
    /// as the switch left them, get back what they were before it.
    pub fn restore(&self, options: &GenerateOptions) -> Restored {
        let mut restored = options.clone();
        for (k, segment) in restored.timeline.segments.iter_mut().enumerate() {
            if let (Some(after), Some(before)) = (self.after.timeline.segments.get(k), self.before.timeline.segments.get(k)) {
                if after.class == segment.class {
                    segment.class = before.class.clone();
                }
            }
        }
        if options.init == self.after.init {
            restored.init = self.before.init.clone();
        }
        let keys = restored
            .keys
            .iter_mut()
            .map(|key| match self.after.keys.iter().position(|a| a == key).and_then(|j| self.before.keys.get(j)) {
                Some(before) => {
                    *key = before.clone();
                    true
                }
                None => false,
            })
            .collect();
        Restored { options: restored, keys }
    }
}

/// The last of `switches` that went from `to` to `from`: the one a switch from `from` to
/// `to` undoes.
pub fn switch_back<'a>(switches: &'a [ModelSwitch], from: &std::path::Path, to: &std::path::Path) -> Option<&'a ModelSwitch> {
    switches.iter().rev().find(|s| s.from == to && s.to == from)
}

/// A pose of world joint positions on `from`'s skeleton (its units) on `to`'s skeleton: each
/// bone pointing the same way at `to`'s lengths, the hips moved by the ratio of leg lengths
/// (`motion::Retarget`).
pub fn pose_onto(pose: &[[f32; 3]], from: &ModelSpec, to: &ModelSpec) -> Result<Vec<[f32; 3]>> {
    let skeleton = &from.layout.skeleton;
    if pose.len() != skeleton.len() {
        bail!("the pose has {} joints; the {} model's skeleton has {}", pose.len(), from.dataset, skeleton.len());
    }
    let source_name = format!("the {} model's skeleton", from.dataset);
    let target_name = format!("the {} model's skeleton", to.dataset);
    let source_keys = key_joints(skeleton, None, &source_name)?;
    let target_keys = key_joints(&to.layout.skeleton, None, &target_name)?;
    let retarget = Retarget::new(skeleton, &source_keys, to.layout.skeleton.clone(), &target_keys).with_context(|| format!("cannot retarget {source_name} onto {target_name}"))?;
    let motion = Motion::from_positions(skeleton.clone(), from.fps, pose.iter().map(|&p| Vec3::from(p)).collect());
    Ok(retarget.apply(&motion).frame(0).iter().map(|p| p.to_array()).collect())
}

/// "4.0 s" for a key's time, as messages name keys.
pub fn key_name(key: &Key) -> String {
    format!("the key at {:.1} s", key.seconds)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::glocal::GlocalModel;
    use crate::synth::{InitPose, KeySource};
    use std::path::Path;

    fn options(timeline: &str, init: &str, keys: &[f32]) -> GenerateOptions {
        let keys = keys.iter().map(|&seconds| Key { seconds, source: KeySource::Init(InitPose::SeedIndex(seconds as usize)), fix_root: false }).collect();
        GenerateOptions { timeline: timeline.parse().unwrap(), init: InitPose::SeedClass { class: init.into(), variant: 0 }, keys, ..Default::default() }
    }

    /// What the user left as the switch made it comes back; what they changed on the other
    /// model stays theirs.
    #[test]
    fn a_switch_back_restores_what_was_left_alone() {
        let before = options("posing:3,directions:4,sitting:2", "posing", &[1.0, 5.0]);
        let after = options("bow:3,guide:4,guide:2", "bow", &[1.0, 5.0]);
        let switch = ModelSwitch::new("models/h36m".into(), "models/bandai".into(), before.clone(), after.clone());
        assert_eq!(switch_back(std::slice::from_ref(&switch), Path::new("models/bandai"), Path::new("models/h36m")), Some(&switch));
        assert_eq!(switch_back(std::slice::from_ref(&switch), Path::new("models/h36m"), Path::new("models/bandai")), None);
        let back = switch.restore(&after);
        assert_eq!(back.options, before);
        let mut edited = after.clone();
        edited.timeline.segments[1].class = "walk".into();
        edited.keys[1].seconds = 6.0;
        let back = switch.restore(&edited);
        assert_eq!(back.options.timeline.to_string(), "posing:3,walk:4,sitting:2");
        assert_eq!(back.options.init, before.init);
        assert_eq!(back.keys, [true, false]);
    }

    /// A pose on Bandai's 21 joints lands on h36m's 27 with its bones h36m's lengths.
    #[test]
    fn a_pose_moves_onto_another_skeleton() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let (h36m, bandai) = (GlocalModel::load(&root.join("models/h36m")).unwrap(), GlocalModel::load(&root.join("models/bandai")).unwrap());
        let rest: Vec<[f32; 3]> = bandai.spec.layout.skeleton.rest_positions().iter().map(|p| p.to_array()).collect();
        let moved = pose_onto(&rest, &bandai.spec, &h36m.spec).unwrap();
        assert_eq!(moved.len(), h36m.spec.layout.skeleton.len());
        assert!(moved.iter().flatten().all(|v| v.is_finite()));
        let wrong = pose_onto(&rest[1..], &bandai.spec, &h36m.spec).unwrap_err();
        assert!(wrong.to_string().contains("has 20 joints"), "{wrong}");
    }
}
