//! Reading and writing motion files, the dataset registry and the model's pose features.

pub mod archive;
pub mod bvh;
pub mod combined;
mod error;
pub mod expmap;
pub mod features;
pub mod floor;
pub mod input;
pub mod joint_map;
pub mod loading;
pub mod npy;
pub mod registry;
pub mod write;

pub use error::{FormatError, Location};
