//! The document the studio edits, as plain data: a project (timeline, pace, initial pose,
//! generation settings, model, view settings) that saves as readable JSON, and the undo
//! history of its edits. No egui here.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use super::viewport::ViewSettings;
use crate::data::write::write_atomic;
use crate::synth::{GenerateOptions, InitPose, Segment, Timeline, Transition, DEFAULT_CLASS_STRENGTH};

/// The project file format this build writes; files of a newer version are refused.
pub const PROJECT_VERSION: u32 = 1;

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
    pub timeline: Timeline,
    /// Global pace (a segment's own pace replaces it for that segment).
    pub pace: f32,
    pub init: InitPose,
    pub transition: Transition,
    /// Classifier-free guidance weight (1: plain conditioning).
    pub class_strength: f32,
    /// LocGen refinement between sparse poses (off: plain interpolation).
    pub locgen: bool,
    /// Variation seed: 0 gives the model's deterministic take.
    pub variation_seed: u64,
    #[serde(default)]
    pub view: ViewSettings,
    #[serde(default)]
    pub playback: PlaybackSettings,
}

impl Project {
    pub fn new(model: PathBuf) -> Self {
        Self {
            version: PROJECT_VERSION,
            model,
            timeline: Timeline::default(),
            pace: 1.0,
            init: InitPose::SeedIndex(0),
            transition: Transition::Anchor,
            class_strength: DEFAULT_CLASS_STRENGTH,
            locgen: true,
            variation_seed: 0,
            view: ViewSettings::default(),
            playback: PlaybackSettings::default(),
        }
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

    /// What the engine needs to generate this project's take.
    pub fn options(&self) -> GenerateOptions {
        GenerateOptions {
            timeline: self.timeline.clone(),
            pace: self.pace,
            init: self.init.clone(),
            locgen: self.locgen,
            transition: self.transition,
            class_strength: self.class_strength,
            ..Default::default()
        }
        .varied(self.variation_seed)
    }

    /// Whether a change from `other` to `self` changes the generated take (and not only how
    /// it is viewed or played).
    pub fn same_take(&self, other: &Project) -> bool {
        self.options() == other.options() && self.model == other.model
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a project always serialises")
    }

    /// Parses a project file; `name` names it in errors. The version is checked before
    /// anything else so a newer file says so instead of failing on an unknown field.
    pub fn from_json(text: &str, name: &str) -> Result<Self> {
        let value: serde_json::Value = serde_json::from_str(text).with_context(|| format!("{name} is not a valid project file (not JSON)"))?;
        let version = value
            .get("version")
            .and_then(serde_json::Value::as_u64)
            .with_context(|| format!("{name} is not a Glocal Studio project: it has no \"version\" field"))?;
        if version > u64::from(PROJECT_VERSION) {
            bail!("{name} is a version {version} project, newer than this studio understands (version {PROJECT_VERSION}); update Glocal Studio to open it");
        }
        let project: Project = serde_json::from_value(value).with_context(|| format!("{name} is not a valid project file"))?;
        for (k, s) in project.timeline.segments.iter().enumerate() {
            if !(s.seconds > 0.0 && s.seconds.is_finite()) {
                bail!("{name}: segment {} has a duration of {} seconds", k + 1, s.seconds);
            }
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
        p.timeline = "walking:4,sitting:3@1.5".parse().unwrap();
        p
    }

    #[test]
    fn round_trips_and_refuses_newer_or_broken_files() {
        let p = sample();
        assert_eq!(Project::from_json(&p.to_json(), "p").unwrap(), p);
        let newer = p.to_json().replace("\"version\": 1", "\"version\": 99");
        assert!(format!("{:#}", Project::from_json(&newer, "p").unwrap_err()).contains("newer"));
        assert!(Project::from_json("{ not json", "p").is_err());
        assert!(format!("{:#}", Project::from_json("{}", "p").unwrap_err()).contains("version"));
    }

    #[test]
    fn undo_redo() {
        let mut h = History::default();
        let mut cur = sample();
        let before = cur.clone();
        cur.timeline.segments.pop();
        h.record(before.clone());
        assert!(h.undo(&mut cur));
        assert_eq!(cur, before);
        assert!(h.redo(&mut cur));
        assert_eq!(cur.timeline.segments.len(), 1);
        assert!(!h.redo(&mut cur));
    }
}
