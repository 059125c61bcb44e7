//! What a take is generated from, as the command line and the studio both ask for it: a
//! [`Request`] (the generation options with their timeline, starting pose, keys and path,
//! and the user's joint map for foreign BVH files), and the project [`Document`] that saves
//! one as readable JSON (`glocal generate --project` reads the studio's files with it).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use super::constraints::KeySource;
use super::{generate, generate_with, GenerateOptions, Generated, InitPose, Segment, TakeCache, TakeEvents, Timeline, Transition};
use crate::data::input::read_text;
use crate::data::joint_map::UserJointMap;
use crate::model::glocal::GlocalModel;
use crate::motion::Key;

/// The project file format this build writes; files of a newer version are refused and
/// older ones migrated ([`Document::from_value`]). Version 2 holds the engine's
/// [`GenerateOptions`] as they are (keys and a root path included); version 1 had the
/// timeline and settings as separate fields. Version 3 adds per-segment seeds, held frames
/// and loops, which a version 2 reader would drop without a word, so it refuses them instead;
/// a version 2 file reads as version 3 unchanged.
pub const PROJECT_VERSION: u32 = 3;

/// A project file larger than this is not one (a project with a thousand keys is ~1 MB).
const MAX_PROJECT_BYTES: u64 = 64 << 20;

/// A take to generate: the options, and the joints of foreign BVH files (start and key files)
/// where the name table does not find the model's key joints in them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Request {
    pub options: GenerateOptions,
    pub joint_map: Option<UserJointMap>,
}

impl Request {
    /// The options as the engine reads them: every start and key file carries the joint map,
    /// so a foreign BVH is retargeted with it where it is read.
    pub fn engine_options(&self) -> GenerateOptions {
        let mut options = self.options.clone();
        if let Some(map) = &self.joint_map {
            for init in files_mut(&mut options) {
                if let InitPose::File { joint_map, .. } = init {
                    *joint_map = Some(map.clone());
                }
            }
        }
        options
    }

    /// Generates the take; `progress` as for [`generate`].
    pub fn generate(&self, model: &GlocalModel, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
        generate(model, &self.engine_options(), progress)
    }

    /// Generates the take resuming `cache`'s, as [`generate_with`] does.
    pub fn generate_with(&self, model: &GlocalModel, cache: &mut TakeCache, events: &mut dyn TakeEvents) -> Result<Generated> {
        generate_with(model, &self.engine_options(), cache, events)
    }
}

/// The start and key poses of `options` that a file may give.
fn files_mut(options: &mut GenerateOptions) -> impl Iterator<Item = &mut InitPose> {
    let keyed = options.keys.iter_mut().filter_map(|k| match &mut k.source {
        KeySource::Init(init) => Some(init),
        KeySource::Pose(_) => None,
    });
    std::iter::once(&mut options.init).chain(keyed)
}

/// A project file's generation part: the model and the [`Request`] as saved. Other fields
/// of the file (the studio's view settings) are left to whoever reads them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Document {
    /// The file format's version; read as `format_version` too (model.json's name for it),
    /// so a newer file spelled that way is still recognised as newer.
    #[serde(alias = "format_version")]
    pub version: u32,
    /// Model folder.
    pub model: PathBuf,
    /// What the engine generates the take from, exactly as it takes it. The variation seed
    /// is set through [`GenerateOptions::varied`] so its noise goes with it.
    pub options: GenerateOptions,
    /// Joints of foreign BVH files (start and key files) for the model's key joints, as
    /// `{"joint in the file": "Key"}` like a `--joint-map` file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_map: Option<BTreeMap<String, String>>,
}

/// A version 1 project: the generation settings as fields of their own.
#[derive(Deserialize)]
struct DocumentV1 {
    model: PathBuf,
    timeline: Timeline,
    pace: f32,
    init: InitPose,
    transition: Transition,
    class_strength: f32,
    locgen: bool,
    variation_seed: u64,
}

impl From<DocumentV1> for Document {
    fn from(v1: DocumentV1) -> Self {
        let options = GenerateOptions {
            timeline: v1.timeline,
            pace: v1.pace,
            init: v1.init,
            locgen: Some(v1.locgen),
            transition: v1.transition,
            class_strength: Some(v1.class_strength),
            ..Default::default()
        }
        .varied(v1.variation_seed);
        Self { version: PROJECT_VERSION, model: v1.model, options, joint_map: None }
    }
}

impl Document {
    pub fn new(model: PathBuf) -> Self {
        Self { version: PROJECT_VERSION, model, options: GenerateOptions::default(), joint_map: None }
    }

    /// A first timeline for a model's classes: a walk and then a second activity.
    pub fn default_timeline(classes: &[String]) -> Timeline {
        let walk = classes.iter().find(|c| c.to_lowercase().contains("walk")).or(classes.first());
        let other = classes.iter().find(|c| Some(*c) != walk);
        let segments = walk.into_iter().chain(other).map(|c| Segment::new(c.clone(), 4.0)).collect();
        Timeline { segments }
    }

    /// Sets the variation seed (0: the model's deterministic take).
    pub fn set_variation_seed(&mut self, seed: u64) {
        self.options = std::mem::take(&mut self.options).varied(seed);
    }

    /// Whether a change from `other` to `self` changes the generated take.
    pub fn same_take(&self, other: &Document) -> bool {
        self.options == other.options && self.model == other.model
    }

    /// The take this document asks for.
    pub fn request(&self) -> Request {
        Request { options: self.options.clone(), joint_map: self.joint_map.as_ref().map(user_joint_map) }
    }

    /// The project in `value` (`name` names it in errors). The version is checked before
    /// anything else so a newer file says so instead of failing on an unknown field; a
    /// version 1 file is migrated.
    pub fn from_value(value: &serde_json::Value, name: &str) -> Result<Self> {
        let version = ["version", "format_version"]
            .iter()
            .find_map(|field| value.get(field))
            .and_then(serde_json::Value::as_u64)
            .with_context(|| format!("{name} is not a Glocal Studio project: it has no \"version\" field"))?;
        if version > u64::from(PROJECT_VERSION) {
            bail!("{name} is a version {version} project, made by a newer version of glocal (this one reads versions 1 to {PROJECT_VERSION}); update glocal to open it");
        }
        let document: Document = if version == 1 {
            DocumentV1::deserialize(value).with_context(|| format!("{name} is not a valid version 1 project file"))?.into()
        } else {
            Document::deserialize(value).with_context(|| format!("{name} is not a valid project file"))?
        };
        document.check(value, name)?;
        Ok(Document { version: PROJECT_VERSION, ..document })
    }

    /// What serde cannot say of a project: durations, the root path and the joint map.
    fn check(&self, value: &serde_json::Value, name: &str) -> Result<()> {
        for (k, s) in self.options.timeline.segments.iter().enumerate() {
            if !(s.seconds > 0.0 && s.seconds.is_finite()) {
                bail!("{name}: segment {} has a duration of {} seconds", k + 1, s.seconds);
            }
        }
        if let Some(path) = &self.options.path {
            path.check().with_context(|| format!("{name}: root path"))?;
        }
        if let Some(map) = value.get("joint_map").filter(|m| !m.is_null()) {
            UserJointMap::from_value(map, &format!("{name}: joint_map"))?;
        }
        Ok(())
    }

    /// Parses a project file; `name` names it in errors.
    pub fn from_json(text: &str, name: &str) -> Result<Self> {
        Self::from_value(&parse_json(text, name)?, name)
    }

    pub fn load(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        Self::from_json(&read_project(path)?, &name)
    }
}

/// The text of the project file at `path` (errors name it).
pub fn read_project(path: &Path) -> Result<String> {
    read_text(path, MAX_PROJECT_BYTES)
}

/// A project file's text as JSON (`name` names it in errors).
pub fn parse_json(text: &str, name: &str) -> Result<serde_json::Value> {
    serde_json::from_str(text).with_context(|| format!("{name} is not a valid project file (not JSON)"))
}

/// A project's mapping (`{"joint in the file": "Key"}`, as `--joint-map` files spell it);
/// names that are no key joint are left out ([`Document::from_value`] refuses them).
pub fn user_joint_map(map: &BTreeMap<String, String>) -> UserJointMap {
    UserJointMap { entries: map.iter().filter_map(|(joint, key)| Some((joint.clone(), Key::from_name(key)?))).collect() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Document {
        let mut d = Document::new(PathBuf::from("models/h36m"));
        d.options.timeline = "walking:4,sitting:3@1.5".parse().unwrap();
        d
    }

    fn to_json(d: &Document) -> String {
        serde_json::to_string_pretty(d).unwrap()
    }

    #[test]
    fn round_trips_and_refuses_newer_or_broken_files() {
        let d = sample();
        assert_eq!(Document::from_json(&to_json(&d), "p").unwrap(), d);
        let current = format!("\"version\": {PROJECT_VERSION}");
        let newer = to_json(&d).replace(&current, "\"version\": 99");
        assert!(format!("{:#}", Document::from_json(&newer, "p").unwrap_err()).contains("newer"));
        let spelled_as_models_do = to_json(&d).replace(&current, "\"format_version\": 99");
        assert!(format!("{:#}", Document::from_json(&spelled_as_models_do, "p").unwrap_err()).contains("version 99 project, made by a newer version of glocal"));
        assert!(Document::from_json("{ not json", "p").is_err());
        assert!(format!("{:#}", Document::from_json("{}", "p").unwrap_err()).contains("version"));
        let bad_map = to_json(&d).replacen('{', "{\"joint_map\": {\"a\": \"Elbow\"},", 1);
        assert!(format!("{:#}", Document::from_json(&bad_map, "p").unwrap_err()).contains("p: joint_map: 'Elbow'"));
    }

    #[test]
    fn the_request_gives_every_start_and_key_file_the_joint_map() {
        let mut d = sample();
        d.options.init = InitPose::file("a.bvh".into(), 3);
        d.options.keys.push(super::super::Key { seconds: 1.0, source: KeySource::Init(InitPose::file("b.bvh".into(), 0)), fix_root: false });
        d.joint_map = Some(BTreeMap::from([("bend".to_string(), "LeftForeArm".to_string())]));
        let request = d.request();
        assert_eq!(request.options, d.options, "the document's options stay as saved");
        let engine = request.engine_options();
        let map = Some(UserJointMap { entries: vec![("bend".into(), Key::LeftForeArm)] });
        assert!(matches!(&engine.init, InitPose::File { joint_map, .. } if *joint_map == map));
        assert!(matches!(&engine.keys[0].source, KeySource::Init(InitPose::File { joint_map, .. }) if *joint_map == map));
        assert_eq!(serde_json::to_string(&engine).unwrap(), serde_json::to_string(&d.options).unwrap(), "the map is not saved with the options");
    }
}
