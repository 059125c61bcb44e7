//! Where the studio keeps things between runs and finds models: the autosave, the remembered
//! paths and class-mapping edits (`studio.json`), and the folders of shipped models.

use std::path::{Path, PathBuf};

use super::messages::first_line;
use super::project::{self, Project};

pub struct Storage {
    /// The autosave file (none: no autosave, or it failed).
    pub(super) autosave: Option<PathBuf>,
    /// The document as last autosaved.
    pub(super) autosaved: Option<Project>,
    /// When the pause after an edit is over and the autosave is written.
    pub(super) autosave_at: Option<f64>,
    /// `studio.json`, beside the autosave.
    pub(super) state_path: Option<PathBuf>,
    /// The user's class-mapping edits, used before the shipped table.
    pub(super) class_table: Vec<(String, String)>,
    /// The shipped models found, and the folders they were looked for in.
    pub(super) shipped: Vec<PathBuf>,
    pub(super) model_roots: Vec<PathBuf>,
}

/// An autosave that could not be read is moved aside (so the next autosave does not
/// overwrite it) and the message says where it went.
pub fn broken_autosave_message(path: &Path, error: &anyhow::Error) -> String {
    let why = first_line(&format!("{error:#}")).to_string();
    match project::keep_broken_autosave(path) {
        Ok(kept) => format!("The autosave could not be restored ({why}); it is kept as {}", project::shown_path(&kept)),
        Err(e) => format!("The autosave could not be restored ({why}) nor moved aside ({e:#}); it will be overwritten by the next autosave"),
    }
}
