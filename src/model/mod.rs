//! GloGen and LocGen.
pub mod block;
pub mod lstm;
pub mod bench;
pub mod adamw;
pub mod corpus;
pub mod glocal;
pub mod glogen;
pub mod inbetween;
pub mod loss;
pub mod memory;
pub mod rollout;
pub mod seam;
pub mod spec;
pub mod target;
pub mod texture;
pub mod train;

use std::path::{Path, PathBuf};

/// Where shipped models are looked for, in order: beside the executable (an installed
/// studio, or `target/<profile>/` two levels below a checkout), the crate's own `models/`
/// (where it was built), and the working folder. Duplicates are dropped.
pub fn model_roots() -> Vec<PathBuf> {
    let exe_dir = std::env::current_exe().ok().and_then(|e| e.parent().map(Path::to_path_buf));
    let mut roots: Vec<PathBuf> = Vec::new();
    if let Some(dir) = &exe_dir {
        roots.push(dir.join("models"));
        roots.extend(dir.ancestors().nth(2).map(|d| d.join("models")));
    }
    roots.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("models"));
    if let Ok(cwd) = std::env::current_dir() {
        roots.push(cwd.join("models"));
    }
    let mut seen = Vec::new();
    roots.retain(|r| {
        let key = r.canonicalize().unwrap_or_else(|_| r.clone());
        let new = !seen.contains(&key);
        seen.push(key);
        new
    });
    roots
}

/// The shipped model folder `name` (`h36m`, `bandai`) where [`model_roots`] finds one, or
/// `models/NAME` in the working folder (which then says it is missing).
pub fn shipped_model(name: &str) -> PathBuf {
    model_roots().into_iter().map(|r| r.join(name)).find(|d| d.join("model.json").is_file()).unwrap_or_else(|| Path::new("models").join(name))
}

/// A model folder a project names: as saved when it is there, else the shipped model of that
/// folder's name (a project made on another machine or checkout).
pub fn project_model(saved: &Path) -> PathBuf {
    if saved.join("model.json").is_file() {
        return saved.to_path_buf();
    }
    saved.file_name().and_then(|n| n.to_str()).map_or_else(|| saved.to_path_buf(), shipped_model)
}

/// What goes wrong reading a model folder: its model.json, its checksums, its weight files
/// and its seed bank. Each message names the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{} is a file; --model takes the model folder (the one holding model.json)", .0.display())]
    FileNotFolder(PathBuf),
    #[error("model folder {} does not exist", .0.display())]
    NoFolder(PathBuf),
    /// A model.json that is not JSON of the right shape (`name` is the file).
    #[error("{name}: line {line}: {message}")]
    SpecSyntax { name: String, line: usize, message: String },
    /// A model.json with a field out of range or inconsistent with the others.
    #[error("{name}: {problem}")]
    SpecInvalid { name: String, problem: spec::SpecError },
    #[error("{}: checksum {found} does not match the {expected} in model.json: the file is damaged, or training was stopped between writing it and model.json (finish it with `glocal train --resume`)", path.display())]
    Checksum { path: PathBuf, found: String, expected: String },
    /// A file that cannot be read or is not what it should be; the cause is its source.
    #[error("{what}")]
    File {
        what: String,
        #[source]
        cause: anyhow::Error,
    },
    /// Weights or seeds that do not fit the model described by model.json.
    #[error("{}: {problem}", path.display())]
    Mismatch { path: PathBuf, problem: String },
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
}

#[cfg(test)]
mod tests {
    use super::spec::ModelSpec;
    use super::Error;

    #[test]
    fn a_wrong_model_folder_is_told_apart_by_kind() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("none");
        assert!(matches!(ModelSpec::read(&missing), Err(Error::NoFolder(p)) if p == missing));
        let file = dir.path().join("model.json");
        std::fs::write(&file, "{").unwrap();
        assert!(matches!(ModelSpec::read(&file), Err(Error::FileNotFolder(_))));
        let e = ModelSpec::read(dir.path()).unwrap_err();
        assert!(matches!(&e, Error::SpecSyntax { line: 1, .. }), "{e}");
        assert!(e.to_string().starts_with(&format!("{}: line 1:", file.display())), "{e}");
    }
}
