//! Every clip of a dataset, whichever it is: an archive's own, or the combined dataset made
//! from the four archives on the standard humanoid.

use anyhow::Result;

use super::archive::DataRoot;
use super::combined;
use super::registry::{load_archive, Dataset, DatasetClips};

/// Loads every clip of `dataset`.
pub fn load(dataset: Dataset, root: &DataRoot) -> Result<DatasetClips> {
    match dataset {
        Dataset::Combined => Ok(combined::load(root)?.0),
        archive => load_archive(archive, root),
    }
}
