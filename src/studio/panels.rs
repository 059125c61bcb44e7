//! What the panels remember between frames, apart from the document: typed paths, tabs,
//! which windows are open, the timeline widget's drag, the dialogs and the retarget preview.
//! The panels themselves (`menu`, `sidebar`, `bottom`, `central`, `map_panel`, `keys`,
//! `joint_mapping`) each draw one part of the window from it.

use std::path::{Path, PathBuf};

use super::dialogs::Dialogs;
use super::project::same_file;
use super::retarget::RigState;
use super::timeline::TimelineState;
use crate::synth::class_map::ClassMap;
use crate::synth::export::ExportOptions;
use crate::synth::InitPose;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportRange {
    Whole,
    Selection,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InitTab {
    Class,
    Seed,
    File,
}

impl InitTab {
    pub fn of(init: &InitPose) -> Self {
        match init {
            InitPose::SeedClass { .. } => InitTab::Class,
            InitPose::SeedIndex(_) => InitTab::Seed,
            InitPose::File { .. } => InitTab::File,
        }
    }
}

/// Actions that would discard unsaved work, held until the user answers.
#[derive(Clone, Debug, PartialEq)]
pub enum Guarded {
    New,
    Open(PathBuf),
}

impl Guarded {
    /// Whether this action opens the file at `path` (which saving first must not write).
    pub fn opens(&self, path: &Path) -> bool {
        matches!(self, Guarded::Open(target) if same_file(target, path))
    }
}

/// The classes carried over at the last model switch, for the mapping window.
pub struct MappingNote {
    pub map: ClassMap,
    pub classes: Vec<String>,
    /// The segments each pair retagged (indices at the time of the switch).
    pub segments: Vec<Vec<usize>>,
    /// The timeline right after the switch: edits apply to it only while it is unchanged.
    pub timeline: crate::synth::Timeline,
}

/// Text fields of the UI (typed paths and the like).
pub struct Fields {
    pub model_path: String,
    pub project_path: String,
    pub export_path: String,
    /// A BVH whose skeleton the export is written on (empty: the model's own).
    pub export_rig: String,
    pub init_path: String,
    pub init_frame: usize,
    pub new_class: usize,
    /// The seed the Seed tab offers.
    pub seed_index: usize,
    /// The seed "Key from seed pose" keys.
    pub key_seed: usize,
    /// The file and frame the last "Key from file" used.
    pub key_path: String,
    pub key_frame: usize,
}

/// The furthest "from frame" the UI accepts for an initial-pose file (a day at 120 fps).
pub const MAX_INIT_FRAME: usize = 120 * 86_400;

/// How the seed map panel is shown.
pub struct MapView {
    pub(super) shown: bool,
    /// Classes whose seeds the map hides (clicked off in its key), by name.
    pub(super) hidden_classes: std::collections::BTreeSet<String>,
    /// The height the map's key took last frame (the map gets the rest).
    pub(super) key_height: f32,
}

impl Default for MapView {
    fn default() -> Self {
        Self { shown: true, hidden_classes: Default::default(), key_height: 0.0 }
    }
}

/// The panels' state.
pub struct Panels {
    pub(super) fields: Fields,
    pub(super) init_tab: InitTab,
    pub(super) export_range: ExportRange,
    pub(super) export_options: ExportOptions,
    /// An action that would discard unsaved work, waiting for the user's answer.
    pub(super) confirm: Option<Guarded>,
    /// An action waiting for the project to be saved where the user chooses ("Save first"
    /// on a project with no file of its own, or whose file is the one being opened).
    pub(super) save_before: Option<Guarded>,
    pub(super) timeline_state: TimelineState,
    /// What a drag in the viewport does besides orbiting (drawing the path, posing).
    pub(super) tool: ViewportTool,
    /// The previous take drawn over the current one.
    pub(super) compare: bool,
    /// The advice last given (a message is posted when it changes).
    pub(super) advised: Option<String>,
    /// The classes carried over at the last model switch, and whether its window is open.
    pub(super) mapping: Option<MappingNote>,
    pub(super) show_mapping: bool,
    pub(super) map: MapView,
    pub(super) show_side: bool,
    pub(super) show_help: bool,
    pub(super) show_log: bool,
    pub(super) dialogs: Dialogs,
    /// A foreign BVH's retarget preview, failure and mapping editor.
    pub(super) rig: RigState,
    /// The window title last sent (it is sent again only when it changes).
    pub(super) title: String,
}

impl Panels {
    pub fn new(fields: Fields, init: &InitPose, system_dialogs: bool) -> Self {
        Self {
            fields,
            init_tab: InitTab::of(init),
            export_range: ExportRange::Whole,
            export_options: ExportOptions::default(),
            confirm: None,
            save_before: None,
            timeline_state: TimelineState::default(),
            tool: ViewportTool::Orbit,
            compare: false,
            advised: None,
            title: String::new(),
            mapping: None,
            show_mapping: false,
            map: MapView::default(),
            show_side: true,
            show_help: false,
            show_log: false,
            dialogs: Dialogs::new(system_dialogs),
            rig: RigState::default(),
        }
    }
}

/// What a drag in the viewport does besides orbiting: one tool at a time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewportTool {
    #[default]
    Orbit,
    /// Clicks on the ground add path waypoints, drags move them.
    DrawPath,
    /// Drags on the handles pose the frame on screen.
    Pose,
}
