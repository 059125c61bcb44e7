//! `model.json`: everything about a trained model except its weights, so a model folder is
//! self-contained: skeleton, classes, frame rate, feature layout and normalisation,
//! hyperparameters, how it was trained and how well it validated.

use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use super::block::BlockConfig;
use crate::data::features::{FeatureLayout, Interpolation, Normalizer};
use crate::data::write::write_atomic;
use crate::motion::Skeleton;

pub const FORMAT_VERSION: u32 = 1;

/// Which terms the training loss has (the paper's ablations).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum LossKind {
    /// Joint error only (L_J).
    #[value(name = "j")]
    Joint,
    /// Motion-flow error only (L_MF).
    #[value(name = "mf")]
    Flow,
    /// Both, as the paper trains (L_J + L_MF).
    #[value(name = "j+mf")]
    JointFlow,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GloGenSpec {
    pub block: BlockConfig,
    /// Whether the class vector is given at all (`--no-class` turns it off).
    pub use_class: bool,
    /// Probability of training with the class vector zeroed, which lets generation use
    /// classifier-free guidance (0 in the paper's setting).
    pub class_dropout: f32,
    /// Blocks the model rolls out on its own outputs per training window (1 in the paper).
    pub rollout_blocks: usize,
    pub loss: LossKind,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LocGenSpec {
    pub block: BlockConfig,
    /// Dense frames per LocGen window.
    pub window: usize,
    /// The interpolation LocGen refines (models saved before it had a choice: linear).
    #[serde(default)]
    pub interpolation: Interpolation,
}

/// What training recorded, per stage.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct StageRecord {
    pub steps: usize,
    pub seed: u64,
    pub seconds: f64,
    /// (step, training loss, validation error in skeleton units).
    pub curve: Vec<(usize, f32, f32)>,
    /// Mean per-joint position error on the test split, in skeleton units.
    pub val_error: f32,
    /// The same for the baseline of that stage (zero-velocity for GloGen, plain
    /// interpolation for LocGen).
    pub baseline_error: f32,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelSpec {
    pub format_version: u32,
    pub dataset: String,
    pub split: String,
    pub classes: Vec<String>,
    pub fps: f32,
    /// Dense frames per sparse step (the paper's M + 1).
    pub stride: usize,
    /// Sparse poses per GloGen block (the paper's t).
    pub block_len: usize,
    pub layout: FeatureLayout,
    /// The dataset's whole skeleton (for Bandai, its real BVH hierarchy) and which of its
    /// joints the model keeps.
    pub source_skeleton: Skeleton,
    pub source_joints: Vec<usize>,
    pub sparse_norm: Normalizer,
    pub dense_norm: Normalizer,
    /// Mean joint speed of each class in the training data, units per second.
    pub class_speed: Vec<f32>,
    /// Whether the foot lock suits this model's takes (measured with `glocal eval --suite
    /// motion`): on Bandai, whose generated feet slide faster than a contact is detected, the
    /// few locks that engage doubled the peak jerk, so its takes are left unlocked.
    #[serde(default = "locks_feet")]
    pub foot_lock: bool,
    pub glogen: GloGenSpec,
    pub locgen: LocGenSpec,
    #[serde(default)]
    pub glogen_training: Option<StageRecord>,
    #[serde(default)]
    pub locgen_training: Option<StageRecord>,
}

fn locks_feet() -> bool {
    true
}

impl ModelSpec {
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join("model.json");
        let text = std::fs::read_to_string(&path).with_context(|| format!("model folder {} has no readable model.json", dir.display()))?;
        let spec: ModelSpec = serde_json::from_str(&text).with_context(|| format!("{} is not a valid model description", path.display()))?;
        if spec.format_version > FORMAT_VERSION {
            bail!("{} has format version {}, newer than this build understands ({FORMAT_VERSION})", path.display(), spec.format_version);
        }
        let dim = spec.layout.dim();
        if spec.sparse_norm.mean.len() != dim || spec.dense_norm.mean.len() != dim {
            bail!("{}: normalisation has {} values, the feature layout needs {dim}", path.display(), spec.sparse_norm.mean.len());
        }
        if spec.class_speed.len() != spec.classes.len() {
            bail!("{}: {} class speeds for {} classes", path.display(), spec.class_speed.len(), spec.classes.len());
        }
        Ok(spec)
    }

    pub fn write(&self, dir: &Path) -> Result<()> {
        write_atomic(&dir.join("model.json"), serde_json::to_string_pretty(self)?.as_bytes())
    }

    pub fn class_index(&self, name: &str) -> Result<usize> {
        self.classes
            .iter()
            .position(|c| c.eq_ignore_ascii_case(name))
            .with_context(|| format!("unknown class '{name}'; this model knows: {}", self.classes.join(", ")))
    }
}

/// A starting point: `block_len` consecutive sparse poses from a training clip, as raw
/// (un-normalised) sparse features.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Seed {
    pub class: usize,
    pub clip: String,
    pub frame: usize,
    pub features: Vec<f32>,
}
