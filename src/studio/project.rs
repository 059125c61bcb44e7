//! The document the studio edits, as plain data: a project (timeline, pace, initial pose,
//! generation settings, model, view settings) that saves as readable JSON, and the undo
//! history of its edits. No egui here.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use super::viewport::ViewSettings;
use crate::data::write::write_atomic;
use crate::synth::{GenerateOptions, InitPose, Segment, Timeline, Transition};

/// The project file format this build writes; files of a newer version are refused and
/// older ones migrated ([`Project::from_json`]). Version 2 holds the engine's
/// [`GenerateOptions`] as they are (keys and a root path included); version 1 had the
/// timeline and settings as separate fields.
pub const PROJECT_VERSION: u32 = 2;

/// How playback repeats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum LoopMode {
    Off,
    #[default]
    All,
    Selection,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlaybackSettings {
    pub speed: f32,
    pub loop_mode: LoopMode,
}

impl Default for PlaybackSettings {
    fn default() -> Self {
        Self { speed: 1.0, loop_mode: LoopMode::All }
    }
}

/// Everything a take is made from, and how it is viewed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Project {
    pub version: u32,
    /// Model folder.
    pub model: PathBuf,
    /// What the engine generates the take from, exactly as it takes it. The variation seed
    /// is set through [`GenerateOptions::varied`] so its noise goes with it.
    pub options: GenerateOptions,
    #[serde(default)]
    pub view: ViewSettings,
    #[serde(default)]
    pub playback: PlaybackSettings,
    /// Joints of foreign BVH files (start and key files) for the model's key joints, as
    /// `{"joint in the file": "Key"}` like a `--joint-map` file (see `joint_mapping`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_map: Option<std::collections::BTreeMap<String, String>>,
}

/// A version 1 project: the generation settings as fields of their own.
#[derive(Deserialize)]
struct ProjectV1 {
    model: PathBuf,
    timeline: Timeline,
    pace: f32,
    init: InitPose,
    transition: Transition,
    class_strength: f32,
    locgen: bool,
    variation_seed: u64,
    #[serde(default)]
    view: ViewSettings,
    #[serde(default)]
    playback: PlaybackSettings,
}

impl From<ProjectV1> for Project {
    fn from(v1: ProjectV1) -> Self {
        let options = GenerateOptions {
            timeline: v1.timeline,
            pace: v1.pace,
            init: v1.init,
            locgen: v1.locgen,
            transition: v1.transition,
            class_strength: Some(v1.class_strength),
            ..Default::default()
        }
        .varied(v1.variation_seed);
        Self { version: PROJECT_VERSION, model: v1.model, options, view: v1.view, playback: v1.playback, joint_map: None }
    }
}

impl Project {
    pub fn new(model: PathBuf) -> Self {
        Self { version: PROJECT_VERSION, model, options: GenerateOptions::default(), view: ViewSettings::default(), playback: PlaybackSettings::default(), joint_map: None }
    }

    /// A first timeline for a model's classes: a walk and then a second activity.
    pub fn default_timeline(classes: &[String]) -> Timeline {
        let walk = classes.iter().find(|c| c.to_lowercase().contains("walk")).or(classes.first());
        let other = classes.iter().find(|c| Some(*c) != walk);
        let segments = walk
            .into_iter()
            .chain(other)
            .map(|c| Segment::new(c.clone(), 4.0))
            .collect();
        Timeline { segments }
    }

    /// Sets the variation seed (0: the model's deterministic take).
    pub fn set_variation_seed(&mut self, seed: u64) {
        self.options = std::mem::take(&mut self.options).varied(seed);
    }

    /// Whether a change from `other` to `self` changes the generated take (and not only how
    /// it is viewed or played).
    pub fn same_take(&self, other: &Project) -> bool {
        self.options == other.options && self.model == other.model
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a project always serialises")
    }

    /// Parses a project file; `name` names it in errors. The version is checked before
    /// anything else so a newer file says so instead of failing on an unknown field; a
    /// version 1 file is migrated.
    pub fn from_json(text: &str, name: &str) -> Result<Self> {
        let value: serde_json::Value = serde_json::from_str(text).with_context(|| format!("{name} is not a valid project file (not JSON)"))?;
        let version = value
            .get("version")
            .and_then(serde_json::Value::as_u64)
            .with_context(|| format!("{name} is not a Glocal Studio project: it has no \"version\" field"))?;
        if version > u64::from(PROJECT_VERSION) {
            bail!("{name} is a version {version} project, newer than this studio understands (version {PROJECT_VERSION}); update Glocal Studio to open it");
        }
        let project: Project = if version == 1 {
            serde_json::from_value::<ProjectV1>(value).with_context(|| format!("{name} is not a valid version 1 project file"))?.into()
        } else {
            serde_json::from_value(value).with_context(|| format!("{name} is not a valid project file"))?
        };
        for (k, s) in project.options.timeline.segments.iter().enumerate() {
            if !(s.seconds > 0.0 && s.seconds.is_finite()) {
                bail!("{name}: segment {} has a duration of {} seconds", k + 1, s.seconds);
            }
        }
        if let Some(path) = &project.options.path {
            path.check().with_context(|| format!("{name}: root path"))?;
        }
        Ok(Project { version: PROJECT_VERSION, ..project })
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        write_atomic(path, self.to_json().as_bytes())
    }

    pub fn load(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read project {name}"))?;
        Self::from_json(&text, &name)
    }
}

/// The studio's data folder: `$XDG_DATA_HOME/glocal`, else `~/.local/share/glocal`, else
/// the working folder.
pub fn data_folder() -> PathBuf {
    let base = std::env::var_os("XDG_DATA_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")));
    base.map_or_else(|| PathBuf::from("."), |b| b.join("glocal"))
}

/// Where projects and exports go unless the user says otherwise: `~/Documents/Glocal Studio`
/// when there is a Documents folder, else the data folder.
pub fn default_work_folder() -> PathBuf {
    match std::env::var_os("HOME").map(|h| PathBuf::from(h).join("Documents")).filter(|d| d.is_dir()) {
        Some(docs) => docs.join("Glocal Studio"),
        None => data_folder(),
    }
}

/// Where autosaves go: `autosave.json` in the data folder.
pub fn default_autosave_path() -> PathBuf {
    data_folder().join("autosave.json")
}

/// An absolute form of `path` for messages (the path itself when that fails).
pub fn shown_path(path: &Path) -> String {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()).display().to_string()
}

/// Moves an autosave that could not be read aside (`autosave.broken-<unix seconds>.json`
/// beside it), so the next autosave does not overwrite it; returns where it went.
pub fn keep_broken_autosave(path: &Path) -> Result<PathBuf> {
    let stamp = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let stem = path.file_stem().map_or_else(|| "autosave".into(), |s| s.to_string_lossy().into_owned());
    let kept = path.with_file_name(format!("{stem}.broken-{stamp}.json"));
    std::fs::rename(path, &kept).with_context(|| format!("cannot move {} aside", path.display()))?;
    Ok(kept)
}

/// What the studio remembers between runs besides the autosave: the open project's path,
/// the export path and the user's class-mapping edits. Kept in `studio.json` beside the
/// autosave.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StudioState {
    pub project_path: Option<PathBuf>,
    pub export_path: Option<PathBuf>,
    #[serde(default)]
    pub class_table: Vec<(String, String)>,
}

impl StudioState {
    pub fn path_beside(autosave: &Path) -> PathBuf {
        autosave.with_file_name("studio.json")
    }

    /// The state saved at `path`; the default when there is none or it is unreadable (it
    /// holds nothing that cannot be chosen again).
    pub fn load(path: &Path) -> Self {
        std::fs::read_to_string(path).ok().and_then(|t| serde_json::from_str(&t).ok()).unwrap_or_default()
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        write_atomic(path, serde_json::to_string_pretty(self)?.as_bytes())
    }
}

/// Writes an autosave, creating its folder.
pub fn autosave(project: &Project, path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    project.save(path)
}

/// Undo and redo of edits: whole-project snapshots (a project is small). The model folder
/// is not part of the history: undo never reloads a model.
#[derive(Default)]
pub struct History {
    undo: Vec<Project>,
    redo: Vec<Project>,
}

impl History {
    const LIMIT: usize = 200;

    /// Records the state before an edit.
    pub fn record(&mut self, before: Project) {
        if self.undo.last() == Some(&before) {
            return;
        }
        self.undo.push(before);
        if self.undo.len() > Self::LIMIT {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Steps `current` back; false when there is nothing to undo.
    pub fn undo(&mut self, current: &mut Project) -> bool {
        let Some(mut prev) = self.undo.pop() else { return false };
        prev.model = current.model.clone();
        self.redo.push(std::mem::replace(current, prev));
        true
    }

    pub fn redo(&mut self, current: &mut Project) -> bool {
        let Some(mut next) = self.redo.pop() else { return false };
        next.model = current.model.clone();
        self.undo.push(std::mem::replace(current, next));
        true
    }

    /// Applies `f` to every recorded state (e.g. class names carried to a new model).
    pub fn map_states(&mut self, mut f: impl FnMut(&mut Project)) {
        self.undo.iter_mut().chain(self.redo.iter_mut()).for_each(&mut f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Project {
        let mut p = Project::new(PathBuf::from("models/h36m"));
        p.options.timeline = "walking:4,sitting:3@1.5".parse().unwrap();
        p
    }

    #[test]
    fn round_trips_and_refuses_newer_or_broken_files() {
        let p = sample();
        assert_eq!(Project::from_json(&p.to_json(), "p").unwrap(), p);
        let newer = p.to_json().replace("\"version\": 2", "\"version\": 99");
        assert!(format!("{:#}", Project::from_json(&newer, "p").unwrap_err()).contains("newer"));
        assert!(Project::from_json("{ not json", "p").is_err());
        assert!(format!("{:#}", Project::from_json("{}", "p").unwrap_err()).contains("version"));
    }

    /// A version 1 project exactly as the studio wrote it before version 2.
    const V1: &str = r#"{
  "version": 1,
  "model": "models/h36m",
  "timeline": {
    "segments": [
      {
        "class": "walking",
        "seconds": 4.0
      },
      {
        "class": "sitting",
        "seconds": 3.0,
        "pace": 1.5
      }
    ]
  },
  "pace": 1.2,
  "init": {
    "SeedClass": {
      "class": "sitting",
      "variant": 3
    }
  },
  "transition": "Blend",
  "class_strength": 2.0,
  "locgen": false,
  "variation_seed": 7,
  "view": {
    "ghosts": 2,
    "ghost_step": 5,
    "trail": true,
    "follow_root": false,
    "grid": true
  },
  "playback": {
    "speed": 1.0,
    "loop_mode": "All"
  }
}"#;

    #[test]
    fn a_version_1_project_is_migrated() {
        let p = Project::from_json(V1, "v1.json").unwrap();
        assert_eq!(p.version, PROJECT_VERSION);
        let o = &p.options;
        assert_eq!(o.timeline, "walking:4,sitting:3@1.5".parse().unwrap());
        assert_eq!((o.pace, o.transition, o.class_strength, o.locgen), (1.2, Transition::Blend, Some(2.0), false));
        assert_eq!(o.init, InitPose::SeedClass { class: "sitting".into(), variant: 3 });
        assert_eq!(*o, o.clone().varied(7), "the seed comes with its variation");
        assert_eq!((o.keys.len(), o.path.is_none()), (0, true));
        assert_eq!((p.view.ghosts, p.view.follow_root), (2, false));
        // Saved again, it is a version 2 file that reads back the same.
        let again = p.to_json();
        assert!(again.contains("\"version\": 2") && again.contains("\"options\""));
        assert_eq!(Project::from_json(&again, "v2.json").unwrap(), p);
        let broken = V1.replace("\"pace\": 1.2", "\"pace\": \"fast\"");
        assert!(format!("{:#}", Project::from_json(&broken, "v1.json").unwrap_err()).contains("version 1"));
    }

    #[test]
    fn undo_redo() {
        let mut h = History::default();
        let mut cur = sample();
        let before = cur.clone();
        cur.options.timeline.segments.pop();
        h.record(before.clone());
        assert!(h.undo(&mut cur));
        assert_eq!(cur, before);
        assert!(h.redo(&mut cur));
        assert_eq!(cur.options.timeline.segments.len(), 1);
        assert!(!h.redo(&mut cur));
    }
}
