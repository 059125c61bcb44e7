//! What the command-line tests share: copies of the shipped models to change.

use std::path::{Path, PathBuf};

use tempfile::TempDir;

/// A copy of a shipped model in a fresh folder (never the shipped folder itself).
pub fn model_copy(name: &str) -> (TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join(name);
    std::fs::create_dir(&to).unwrap();
    for entry in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
    }
    (dir, to)
}
