//! What the command-line tests share: the shipped models' folders, and copies of them to change.

use std::path::{Path, PathBuf};

use tempfile::TempDir;

/// The folder of the shipped model `name`, in the checkout.
pub fn shipped_model(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)
}

/// A copy of a shipped model in a fresh folder (never the shipped folder itself).
pub fn model_copy(name: &str) -> (TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join(name);
    std::fs::create_dir(&to).unwrap();
    for entry in std::fs::read_dir(shipped_model(name)).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
    }
    (dir, to)
}
