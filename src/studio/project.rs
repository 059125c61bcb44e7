//! The document the studio edits, as plain data: a project (the synth [`Document`]: model,
//! generation options and joint map, with the view and playback settings) that saves as
//! readable JSON, and the undo history of its edits. No egui here.

use std::ops::{Deref, DerefMut};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::viewport::ViewSettings;
use crate::data::write::write_atomic;
use crate::synth::project::{parse_json, read_project, Document};

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

/// Everything a take is made from, and how it is viewed. It reads as the synth document it
/// extends (`project.options`, `project.joint_map`): the file is that document's fields and
/// the studio's view and playback settings side by side.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Project {
    #[serde(flatten)]
    pub document: Document,
    pub view: ViewSettings,
    pub playback: PlaybackSettings,
}

/// The studio's fields of a project file, as every version keeps them: at the top level.
#[derive(Deserialize)]
struct StudioFields {
    #[serde(default)]
    view: ViewSettings,
    #[serde(default)]
    playback: PlaybackSettings,
}

impl Deref for Project {
    type Target = Document;

    fn deref(&self) -> &Document {
        &self.document
    }
}

impl DerefMut for Project {
    fn deref_mut(&mut self) -> &mut Document {
        &mut self.document
    }
}

impl Project {
    pub fn new(model: PathBuf) -> Self {
        Self { document: Document::new(model), view: ViewSettings::default(), playback: PlaybackSettings::default() }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a project always serialises")
    }

    /// Parses a project file; `name` names it in errors. The document is read (and
    /// migrated) as `glocal generate --project` reads it.
    pub fn from_json(text: &str, name: &str) -> Result<Self> {
        let value = parse_json(text, name)?;
        let document = Document::from_value(&value, name)?;
        let StudioFields { view, playback } = StudioFields::deserialize(&value).with_context(|| format!("{name} is not a valid project file (view or playback settings)"))?;
        Ok(Self { document, view, playback })
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        write_atomic(path, self.to_json().as_bytes())
    }

    pub fn load(path: &Path) -> Result<Self> {
        Self::from_json(&read_project(path)?, &path.display().to_string())
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

/// Whether `a` and `b` name the same file, through links and relative forms (as far as
/// they exist; a path that does not is compared in its absolute form).
pub fn same_file(a: &Path, b: &Path) -> bool {
    let key = |p: &Path| p.canonicalize().or_else(|_| std::path::absolute(p)).unwrap_or_else(|_| p.to_path_buf());
    key(a) == key(b)
}

/// Moves an autosave that could not be read aside (`autosave.broken-<unix seconds>.json`
/// beside it), so the next autosave does not overwrite it; returns where it went.
pub fn keep_broken_autosave(path: &Path) -> Result<PathBuf> {
    let stamp = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let stem = path.file_stem().map_or_else(|| "autosave".into(), |s| s.to_string_lossy().into_owned());
    let kept = path.with_file_name(format!("{stem}.broken-{stamp}.json"));
    crate::data::write::move_aside(path, &kept)?;
    Ok(kept)
}

/// What the studio remembers between runs besides the autosave: the open project's path,
/// the export path and the user's class-mapping edits. Kept in `studio.json` beside the
/// autosave.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StudioState {
    pub project_path: Option<PathBuf>,
    pub export_path: Option<PathBuf>,
    /// The rig the last export was written on, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub export_rig: Option<PathBuf>,
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

/// Undo and redo of edits: whole-project snapshots (a project is small), each on its own
/// model: undoing a model switch brings the model before it back.
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
        let Some(prev) = self.undo.pop() else { return false };
        self.redo.push(std::mem::replace(current, prev));
        true
    }

    pub fn redo(&mut self, current: &mut Project) -> bool {
        let Some(next) = self.redo.pop() else { return false };
        self.undo.push(std::mem::replace(current, next));
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{InitPose, Transition};
    use crate::synth::project::PROJECT_VERSION;

    fn sample() -> Project {
        let mut p = Project::new(PathBuf::from("models/h36m"));
        p.options.timeline = "walking:4,sitting:3@1.5".parse().unwrap();
        p
    }

    #[test]
    fn round_trips_with_the_view_settings() {
        let mut p = sample();
        p.view.ghosts = 3;
        p.playback.speed = 0.5;
        assert_eq!(Project::from_json(&p.to_json(), "p").unwrap(), p);
        let broken = p.to_json().replace("\"speed\": 0.5", "\"speed\": \"slow\"");
        assert!(format!("{:#}", Project::from_json(&broken, "p").unwrap_err()).contains("playback"));
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
        assert_eq!((o.pace, o.transition, o.class_strength, o.locgen), (1.2, Transition::Blend, Some(2.0), Some(false)));
        assert_eq!(o.init, InitPose::SeedClass { class: "sitting".into(), variant: 3 });
        assert_eq!(*o, o.clone().varied(7), "the seed comes with its variation");
        assert_eq!((o.keys.len(), o.path.is_none()), (0, true));
        assert_eq!((p.view.ghosts, p.view.follow_root), (2, false));
        // Saved again, it is a file of the current version that reads back the same.
        let again = p.to_json();
        assert!(again.contains(&format!("\"version\": {PROJECT_VERSION}")) && again.contains("\"options\""));
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
