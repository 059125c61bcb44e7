//! `model.json`: everything about a trained model except its weights, so a model folder is
//! self-contained: skeleton, classes, frame rate, feature layout and normalisation,
//! hyperparameters, how it was trained and how well it validated.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::block::BlockConfig;
use super::Error;
use crate::data::features::{FeatureLayout, Interpolation, Normalizer};
use crate::data::input::{read_bytes, read_text};
use crate::data::registry::Dataset;
use crate::data::write::write_atomic;
use crate::motion::{clipped, Skeleton};

pub const FORMAT_VERSION: u32 = 1;

/// The weight files of a model folder, beside its model.json (whose checksums name them).
pub const GLOGEN_FILE: &str = "glogen.safetensors";
pub const LOCGEN_FILE: &str = "locgen.safetensors";
pub const INBETWEEN_FILE: &str = "inbetween.safetensors";

/// Which terms the training loss has (the paper's ablations).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LossKind {
    /// Joint error only (L_J).
    Joint,
    /// Motion-flow error only (L_MF).
    Flow,
    /// Both, as the paper trains (L_J + L_MF).
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
    /// What each predicted pose is measured from.
    #[serde(flatten)]
    pub base: PoseBase,
    /// Trained on its blocks joined at their seams as generation joins them
    /// (`GloGen::rollout_block`): the loss sees the joined block and the rollout's next
    /// block reads it.
    #[serde(default)]
    pub joined: bool,
    /// How generation joins a block onto the block before it (models saved before the
    /// choice: one-sided).
    #[serde(default)]
    pub seam_join: SeamJoin,
    /// Each block also reads the next key it must reach ([`super::target`]): its pose, where
    /// it stands and the steps left to it (models saved before the choice: class only).
    #[serde(default)]
    pub target: bool,
}

impl GloGenSpec {
    /// The label part of the conditioning vector, `labels` one-hot entries (the classes, then
    /// the styles): 0 without the class prior.
    pub fn class_len(&self, labels: usize) -> usize {
        if self.use_class {
            labels
        } else {
            0
        }
    }

    /// How much of the input's last pose each of a block's `block_len` poses is an offset
    /// from ([`PoseBase`]); None for absolute poses.
    pub fn base_weights(&self, block_len: usize) -> Option<Vec<f32>> {
        match self.base {
            PoseBase::Absolute => None,
            PoseBase::Residual => Some(vec![1.0; block_len]),
            PoseBase::ResidualFade => {
                let last = block_len.saturating_sub(1).max(1) as f32;
                Some((0..block_len).map(|k| 0.5 * (1.0 + (std::f32::consts::PI * k as f32 / last).cos())).collect())
            }
        }
    }

    /// The whole conditioning vector: the labels, then the target when the block reads one.
    pub fn cond_len(&self, labels: usize, pose_dim: usize) -> usize {
        self.class_len(labels) + if self.target { super::target::target_len(pose_dim) } else { 0 }
    }
}

/// What each pose a GloGen block predicts is measured from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "PoseBaseFlags", into = "PoseBaseFlags")]
pub enum PoseBase {
    /// Poses of their own, wherever the decoder places the block's first (the paper's).
    #[default]
    Absolute,
    /// Each pose an offset from the last pose of the block's input (Seq2Seq's residual), so
    /// a block starts where its context leaves off.
    Residual,
    /// The offset from the last pose of the block's input fading out over the block (a raised
    /// cosine, whole at its first pose, gone at its last): a block continues its context where
    /// it meets it, as a residual GloGen does, and ends on poses of its own, as an absolute
    /// one does.
    ResidualFade,
}

/// How model.json spells a [`PoseBase`]: the flags it had before there were three choices, so
/// folders saved before and after read alike (saved before either flag: absolute poses).
#[derive(Serialize, Deserialize)]
struct PoseBaseFlags {
    #[serde(default)]
    residual: bool,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    residual_fade: bool,
}

impl PoseBase {
    /// The base the `residual` and `residual_fade` flags (model.json's, the command line's)
    /// name: residual wins where both are set.
    pub fn from_flags(residual: bool, residual_fade: bool) -> Self {
        match (residual, residual_fade) {
            (true, _) => Self::Residual,
            (false, true) => Self::ResidualFade,
            (false, false) => Self::Absolute,
        }
    }
}

impl From<PoseBaseFlags> for PoseBase {
    fn from(flags: PoseBaseFlags) -> Self {
        Self::from_flags(flags.residual, flags.residual_fade)
    }
}

impl From<PoseBase> for PoseBaseFlags {
    fn from(base: PoseBase) -> Self {
        Self { residual: base == PoseBase::Residual, residual_fade: base == PoseBase::ResidualFade }
    }
}

/// Where a seam's shift goes when a GloGen block is joined onto the block before it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SeamJoin {
    /// All of it on the new block's first half: the first half of every block is pulled
    /// towards where the block before ended.
    #[default]
    OneSided,
    /// Half on the new block's first half and half, opposite, on the previous block's last
    /// half, where that block may still move (not the seed, not a block holding a key).
    TwoSided,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LocGenSpec {
    pub block: BlockConfig,
    /// Dense frames per LocGen window.
    pub window: usize,
    /// The interpolation LocGen refines (models saved before it had a choice: linear).
    #[serde(default)]
    pub interpolation: Interpolation,
    /// Per feature, the spread of the real frames about their interpolation in the training
    /// data (normalised units): LocGen's output is scaled by it, so the network predicts a
    /// residual of unit size rather than one a hundred times smaller than the features; 0
    /// leaves a feature as interpolated. Empty for models saved before it (their output is
    /// the residual itself).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub residual_scale: Vec<f32>,
    /// The sparse poses come out of LocGen as they went in (GloGen's poses and the user's
    /// keys stay put; the interpolation is exact there). Windows then start on a sparse pose.
    #[serde(default)]
    pub keep_sparse_poses: bool,
    /// Whether a take that does not say ([`crate::synth::GenerateOptions::locgen`]) is
    /// refined by LocGen: Bandai's is not, its LocGen being further from the held-out styles
    /// than the spline it refines (1.076x between keys) and its takes jerkier for it (1.18x
    /// real's mean jerk, 1.04x with the spline alone; docs/DESIGN.md, "LocGen on the spline").
    /// A LocGen trained again refines by default until it is measured otherwise.
    #[serde(default = "refines_by_default", skip_serializing_if = "is_true")]
    pub by_default: bool,
}

/// Channels of the in-betweener's input after each step's features: 1 on given frames
/// (context and key), and the frame's share of the way through the gap.
pub const GAP_CHANNELS: usize = 2;

/// The in-betweener ([`super::inbetween`]): fills the frames between a known pose and a key
/// with a residual on their linear interpolation, reading the frames before the gap.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct InbetweenSpec {
    /// Per step: the interpolated features, then [`GAP_CHANNELS`] more.
    pub block: BlockConfig,
    /// Known frames read before the gap (the last one is the gap's start).
    pub context: usize,
    /// Known frames read after the key, at most (fewer where the take ends sooner): how the
    /// body leaves the key, so the gap arrives at it moving as the take goes on.
    #[serde(default)]
    pub after: usize,
    /// The longest gap (frames strictly between the known pose and the key) it was trained
    /// on; longer gaps are left to GloGen and LocGen.
    pub max_gap: usize,
    /// Per feature, the spread of the real frames about the linear interpolation over the
    /// training gaps (normalised units); 0 leaves a feature as interpolated.
    pub residual_scale: Vec<f32>,
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
    /// Where each class's clips come from ("h36m walking + bandai walk"; a model of the
    /// combined dataset only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub class_sources: Vec<String>,
    /// The styles GloGen is conditioned on beside the class (a model of the combined dataset;
    /// none otherwise): a second one-hot after the class's, dropped with it for guidance.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub styles: Vec<String>,
    /// Each class's usual style (the one most of its training clips have), which a segment
    /// that names none is made in (a model with styles only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub usual_styles: Vec<usize>,
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
    /// Per class whose clips come in more than one style, the mean joint speed of each
    /// style's clips, units per second (`crate::model::corpus::Corpus::style_speeds`): the
    /// pace a segment that asks for a style keeps (`crate::synth::pace`). A style moves a
    /// network's wave about 2x where its clips differ 35x. Written at training and by `glocal
    /// calibrate`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub style_speed: BTreeMap<String, BTreeMap<String, f32>>,
    /// Whether the foot lock suits this model's takes (measured with `glocal eval --suite
    /// motion`); a model whose locked takes jerk more than they gain can opt out. Both shipped
    /// models lock (Bandai since its lock splits the contacts its network's feet slide through).
    #[serde(default = "locks_feet")]
    pub foot_lock: bool,
    /// Whether the foot lock makes the body travel as far as its feet carry it
    /// ([`crate::synth::foot_lock::Travel::FromFeet`]): for a network whose stance feet slide
    /// with the body (Bandai's run). Off, the lock holds the feet and moves the hips only as far
    /// as the legs need; h36m's walk, whose feet the lock already holds (support-point speed
    /// 1.27x real), slowed from 0.73 to 0.62x its real speed when carried, and its class
    /// control 1 s after another class's seed fell from 93.1 to 89.4%.
    #[serde(default)]
    pub carry_by_feet: bool,
    /// Whether a travelling class keeps a straight course where the take has no root path
    /// (`synth::course`): for a model whose walking went round its capture room (Human3.6M's,
    /// and `all`, whose walking is mostly Human3.6M's).
    #[serde(default)]
    pub hold_course: bool,
    /// The classifier-free guidance weight its takes are made with unless one is asked for
    /// (1 = plain conditioning), tuned per model with `glocal eval` (docs/RESULTS.md): more
    /// guidance holds the requested class better but moves the motion away from the data.
    #[serde(default = "default_class_strength")]
    pub class_strength: f32,
    /// Per class, the guidance a class is made with where the model's own leaves it damped,
    /// tuned by `glocal calibrate` ([`crate::eval::calibrate`]): `all`'s CMU dances and sports
    /// came out at 0.42x / 0.45x their real jerk at 1.5. A class not named takes
    /// [`Self::class_strength`].
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub class_strengths: BTreeMap<String, f32>,
    /// Per class, the class its guidance steers away from (written by `glocal calibrate
    /// --contrast`): its unconditioned pass is given that class (and the take's style)
    /// instead of no label, so guidance strengthens what tells the two apart. `all`'s
    /// sidesteps walked forwards at any plain guidance (a fifth as far sideways as their
    /// data), their difference from `walking` being a small share of what the label moves.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub class_contrasts: BTreeMap<String, String>,
    /// How far guidance pushes a contrasted class from its pair, on top of its own guidance
    /// (docs/DESIGN.md, "Sidesteps steered away from walking").
    #[serde(default = "default_contrast_strength")]
    pub contrast_strength: f32,
    /// The classes whose takes at the model's guidance already move more sharply than their
    /// training clips (mean jerk over 1.3x theirs, issue 39's bound, found by `glocal
    /// calibrate`, which also calms those not steered apart in [`Self::class_strengths`]): a
    /// class change keeps them at their own guidance instead of raising it to the change's,
    /// which exaggerates them (`all`'s bow, at 1.31x its clips' jerk, pitched and shifted back
    /// until it read as walking backwards).
    #[serde(default, skip_serializing_if = "BTreeSet::is_empty")]
    pub lively_classes: BTreeSet<String>,
    /// Per class, the share of its motion texture a take lays over its frames (the model's
    /// `texture.safetensors`, [`crate::model::texture`]), tuned by `glocal calibrate` so the
    /// class is as lively as its training clips: a class not named gets all of it.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub texture_gains: BTreeMap<String, f32>,
    /// Per bone (by its child joint), the farthest its direction turns in one frame of a take,
    /// degrees a second: the training clips' turn of the bone once in a thousand calm frames
    /// (`crate::model::corpus::Corpus::bone_turn_limits`); a snap beyond it is spread over the
    /// frames around it ([`crate::motion::spread_snaps`]). Written at training and by
    /// `glocal calibrate`; a bone not named is left as the network made it.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub bone_turn_limits: BTreeMap<String, f32>,
    pub glogen: GloGenSpec,
    pub locgen: LocGenSpec,
    /// The in-betweener, for models trained with one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inbetween: Option<InbetweenSpec>,
    #[serde(flatten)]
    pub training: TrainingRecords,
}

/// What training wrote beside a stage's weights: its record (none before the stage is
/// trained) and the weights' checksums. In model.json these are fields of the model itself;
/// serde reads flattened fields after the others, so a wrong type in one is reported at the
/// end of the file rather than at its line, which is why only fields that training writes
/// are grouped here and the ones tuned by hand (`foot_lock`, `class_strength`) are not.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct TrainingRecords {
    #[serde(default, rename = "glogen_training")]
    pub glogen: Option<StageRecord>,
    #[serde(default, rename = "locgen_training")]
    pub locgen: Option<StageRecord>,
    #[serde(default, rename = "inbetween_training", skip_serializing_if = "Option::is_none")]
    pub inbetween: Option<StageRecord>,
    /// The run that taught GloGen styles by their label inputs alone (`--only-styles`),
    /// after its own training.
    #[serde(default, rename = "styles_training", skip_serializing_if = "Option::is_none")]
    pub styles: Option<StageRecord>,
    /// SHA-256 of each weight file (by file name), written with it and checked at load.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub weights_sha256: BTreeMap<String, String>,
}

/// A model.json field that is wrong, and how.
#[derive(Debug, thiserror::Error)]
#[error("field `{field}` {problem}")]
pub struct SpecError {
    pub field: String,
    pub problem: String,
}

impl SpecError {
    fn field(field: &str, problem: String) -> Self {
        Self { field: field.to_string(), problem }
    }
}

// Limits far above any model this project trains, low enough that a hostile or damaged
// model.json cannot ask for more memory than the machine has.
const MAX_SPEC_BYTES: u64 = 256 << 20;
const MAX_WEIGHTS_BYTES: u64 = 2 << 30;
const MAX_CLASSES: usize = 1000;
const MAX_JOINTS: usize = 1000;
const MIN_FPS: f32 = 1.0;
const MAX_FPS: f32 = 1000.0;
const MAX_STRIDE: usize = 100;
const MAX_BLOCK_LEN: usize = 1000;
const MAX_ROLLOUT: usize = 100;
const MAX_LOCGEN_WINDOW: usize = 1000;
const MAX_HIDDEN: usize = 4096;
/// A bone's turn limit: from a bone that barely moves to a half turn every frame at the
/// highest rate.
const MIN_TURN_DEGREES_A_SECOND: f32 = 1.0;
const MAX_TURN_DEGREES_A_SECOND: f32 = 180.0 * MAX_FPS;
/// Parameters of one block (about 4 bytes each, several copies while loading).
const MAX_BLOCK_PARAMETERS: usize = 100_000_000;

fn in_range(field: &str, v: f32, lo: f32, hi: f32) -> Result<(), SpecError> {
    if !(v.is_finite() && (lo..=hi).contains(&v)) {
        return Err(SpecError::field(field, format!("is {v}; it must be between {lo} and {hi}")));
    }
    Ok(())
}

fn whole_in_range(field: &str, v: usize, lo: usize, hi: usize) -> Result<(), SpecError> {
    if !(lo..=hi).contains(&v) {
        return Err(SpecError::field(field, format!("is {v}; it must be between {lo} and {hi}")));
    }
    Ok(())
}

fn validate_norm(field: &str, norm: &Normalizer, dim: usize) -> Result<(), SpecError> {
    for (part, values) in [("mean", &norm.mean), ("std", &norm.std)] {
        if values.len() != dim {
            return Err(SpecError::field(&format!("{field}.{part}"), format!("has {} values; the feature layout needs {dim}", values.len())));
        }
    }
    if let Some(k) = norm.mean.iter().position(|v| !v.is_finite()) {
        return Err(SpecError::field(&format!("{field}.mean[{k}]"), "is not finite".into()));
    }
    if let Some(k) = norm.std.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(SpecError::field(&format!("{field}.std[{k}]"), format!("is {}; a standard deviation must be positive and finite", norm.std[k])));
    }
    Ok(())
}

/// A block that reads `in_dim` features a step (with `cond` of conditioning) and writes `dim`.
fn validate_block(field: &str, b: &BlockConfig, in_dim: usize, dim: usize, cond: usize) -> Result<(), SpecError> {
    for (name, v, want) in [("in_dim", b.in_dim, in_dim), ("out_dim", b.out_dim, dim), ("cond_dim", b.cond_dim, cond)] {
        if v != want {
            return Err(SpecError::field(&format!("{field}.{name}"), format!("is {v}; the layout and classes need {want}")));
        }
    }
    whole_in_range(&format!("{field}.hidden"), b.hidden, 1, MAX_HIDDEN)?;
    if !(b.dropout.is_finite() && (0.0..1.0).contains(&b.dropout)) {
        return Err(SpecError::field(&format!("{field}.dropout"), format!("is {}; it must be at least 0 and below 1", b.dropout)));
    }
    // Encoder and decoder, two directions each: 4 gates x hidden x (input + hidden + bias).
    let h = b.hidden;
    let per_direction = 4 * h * (b.in_dim + b.cond_dim + 2 * h + 2);
    let parameters = 2 * 2 * per_direction + (2 * h + 1) * b.out_dim;
    if parameters > MAX_BLOCK_PARAMETERS {
        return Err(SpecError::field(&format!("{field}.hidden"), format!("{h} makes a block of {parameters} parameters, more than {MAX_BLOCK_PARAMETERS}")));
    }
    Ok(())
}

fn validate_inbetween(spec: &InbetweenSpec, dim: usize) -> Result<(), SpecError> {
    validate_block("inbetween.block", &spec.block, dim + GAP_CHANNELS, dim, 0)?;
    whole_in_range("inbetween.context", spec.context, 2, MAX_LOCGEN_WINDOW)?;
    whole_in_range("inbetween.max_gap", spec.max_gap, 1, MAX_LOCGEN_WINDOW)?;
    whole_in_range("inbetween.after", spec.after, 0, MAX_LOCGEN_WINDOW)?;
    validate_scale("inbetween.residual_scale", &spec.residual_scale, dim)
}

/// A residual scale: one number of 0 or more per feature (`dim`).
fn validate_scale(field: &str, scale: &[f32], dim: usize) -> Result<(), SpecError> {
    if scale.len() != dim || scale.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
        return Err(SpecError::field(field, format!("must hold {dim} numbers of 0 or more, one per feature")));
    }
    Ok(())
}

pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

fn locks_feet() -> bool {
    true
}

fn refines_by_default() -> bool {
    true
}

fn is_true(value: &bool) -> bool {
    *value
}

/// The guidance of models saved before each chose its own: 1.5, which against plain
/// conditioning lifted class control after a 2 s transition from 89-93% to 94-97% on both
/// shipped models with FID at the real data's level.
pub const DEFAULT_CLASS_STRENGTH: f32 = 1.5;

/// The most classifier-free guidance a take may ask for.
pub const MAX_CLASS_STRENGTH: f32 = 10.0;

fn default_class_strength() -> f32 {
    DEFAULT_CLASS_STRENGTH
}

/// The push away from a contrasted class's pair: at 1.5 `all`'s sidesteps travel 0.39 of
/// their forward distance sideways, their data about 0.45 (0.27-0.33 at 1, 0.12 without).
pub const DEFAULT_CONTRAST_STRENGTH: f32 = 1.5;

fn default_contrast_strength() -> f32 {
    DEFAULT_CONTRAST_STRENGTH
}

impl ModelSpec {
    /// Reads and validates `dir/model.json` (see [`ModelSpec::validate`]). A missing folder, a
    /// file given as the folder and an unreadable file are each named as such.
    pub fn read(dir: &Path) -> Result<Self, Error> {
        let path = dir.join("model.json");
        if dir.is_file() {
            return Err(Error::FileNotFolder(dir.to_path_buf()));
        }
        if !dir.is_dir() {
            return Err(Error::NoFolder(dir.to_path_buf()));
        }
        let text = read_text(&path, MAX_SPEC_BYTES).map_err(|cause| Error::File { what: format!("model folder {} has no readable model.json", dir.display()), cause })?;
        Self::from_json(&text, &path.display().to_string())
    }

    /// Parses and validates the text of a model.json; errors start with `name`.
    pub fn from_json(text: &str, name: &str) -> Result<Self, Error> {
        let spec: ModelSpec = serde_json::from_str(text).map_err(|e| Error::SpecSyntax { name: name.to_string(), line: e.line(), message: e.to_string() })?;
        spec.validate().map_err(|problem| Error::SpecInvalid { name: name.to_string(), problem })?;
        Ok(spec)
    }

    /// Reads `dir/model.json` and checks each weight file's checksum against it, for
    /// loading a model to generate with. A model.json without checksums (written before
    /// they existed) is accepted as it is.
    pub fn read_verified(dir: &Path) -> Result<Self, Error> {
        let spec = Self::read(dir)?;
        for (file, expected) in &spec.training.weights_sha256 {
            let path = dir.join(file);
            let Ok(bytes) = read_bytes(&path, MAX_WEIGHTS_BYTES) else { continue };
            let found = sha256_hex(&bytes);
            if &found != expected {
                return Err(Error::Checksum { path, found, expected: expected.clone() });
            }
        }
        Ok(spec)
    }

    /// Every field checked against the others and against sane limits, before anything is
    /// allocated from it: the first problem found, naming its field.
    pub fn validate(&self) -> Result<(), SpecError> {
        use SpecError as E;
        if self.format_version == 0 || self.format_version > FORMAT_VERSION {
            return Err(E::field("format_version", format!("is {}; this build understands 1 to {FORMAT_VERSION}", self.format_version)));
        }
        self.dataset.parse::<Dataset>().map_err(|e| E::field("dataset", e.to_string()))?;
        self.validate_classes()?;
        in_range("fps", self.fps, MIN_FPS, MAX_FPS)?;
        whole_in_range("stride", self.stride, 1, MAX_STRIDE)?;
        whole_in_range("block_len", self.block_len, 1, MAX_BLOCK_LEN)?;
        self.validate_skeletons()?;
        let dim = self.layout.dim();
        validate_norm("sparse_norm", &self.sparse_norm, dim)?;
        validate_norm("dense_norm", &self.dense_norm, dim)?;
        if self.class_speed.len() != self.classes.len() {
            return Err(E::field("class_speed", format!("has {} entries for {} classes", self.class_speed.len(), self.classes.len())));
        }
        if let Some(k) = self.class_speed.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(E::field(&format!("class_speed[{k}]"), format!("is {}; it must be a finite speed of 0 or more", self.class_speed[k])));
        }
        for (class, speeds) in &self.style_speed {
            for (style, &speed) in speeds {
                if !self.classes.contains(class) || !self.styles.contains(style) {
                    return Err(E::field("style_speed", format!("names '{}/{}'; both must be the model's, a class and a style", clipped(class), clipped(style))));
                }
                if !(speed.is_finite() && speed >= 0.0) {
                    return Err(E::field(&format!("style_speed.{class}.{style}"), format!("is {speed}; it must be a finite speed of 0 or more")));
                }
            }
        }
        if !self.class_sources.is_empty() && self.class_sources.len() != self.classes.len() {
            return Err(E::field("class_sources", format!("has {} entries for {} classes", self.class_sources.len(), self.classes.len())));
        }
        if self.styles.len() > MAX_CLASSES || self.styles.iter().any(|s| s.trim().is_empty()) {
            return Err(E::field("styles", format!("must hold at most {MAX_CLASSES} names, none empty")));
        }
        if !self.styles.is_empty() && (self.usual_styles.len() != self.classes.len() || self.usual_styles.iter().any(|&s| s >= self.styles.len())) {
            return Err(E::field("usual_styles", format!("must name one of the {} styles for each of the {} classes", self.styles.len(), self.classes.len())));
        }
        validate_block("glogen.block", &self.glogen.block, dim, dim, self.glogen.cond_len(self.labels(), dim))?;
        in_range("glogen.class_dropout", self.glogen.class_dropout, 0.0, 1.0)?;
        in_range("class_strength", self.class_strength, 0.0, MAX_CLASS_STRENGTH)?;
        for (class, &strength) in &self.class_strengths {
            if !self.classes.contains(class) {
                return Err(E::field("class_strengths", format!("names '{}', which is not one of the model's classes", clipped(class))));
            }
            in_range(&format!("class_strengths.{class}"), strength, 0.0, MAX_CLASS_STRENGTH)?;
        }
        in_range("contrast_strength", self.contrast_strength, 0.0, MAX_CLASS_STRENGTH)?;
        if let Some(class) = self.lively_classes.iter().find(|c| !self.classes.contains(c)) {
            return Err(E::field("lively_classes", format!("names '{}', which is not one of the model's classes", clipped(class))));
        }
        for (class, &gain) in &self.texture_gains {
            if !self.classes.contains(class) {
                return Err(E::field("texture_gains", format!("names '{}', which is not one of the model's classes", clipped(class))));
            }
            in_range(&format!("texture_gains.{class}"), gain, 0.0, 1.0)?;
        }
        for (joint, &limit) in &self.bone_turn_limits {
            if self.layout.skeleton.index_of(joint).is_none_or(|j| j == 0) {
                return Err(E::field("bone_turn_limits", format!("names '{}', which is not a bone of the model's skeleton", clipped(joint))));
            }
            in_range(&format!("bone_turn_limits.{joint}"), limit, MIN_TURN_DEGREES_A_SECOND, MAX_TURN_DEGREES_A_SECOND)?;
        }
        for (class, away) in &self.class_contrasts {
            if !self.classes.contains(class) || !self.classes.contains(away) || class == away {
                return Err(E::field(&format!("class_contrasts.{}", clipped(class)), format!("pairs '{}' with '{}'; both must be the model's classes, and two different ones", clipped(class), clipped(away))));
            }
        }
        if !self.class_contrasts.is_empty() && (self.glogen.class_dropout <= 0.0 || !self.glogen.use_class) {
            return Err(E::field("class_contrasts", "are given, but the GloGen was trained without classes or class dropout, so it has no guidance to steer".into()));
        }
        whole_in_range("glogen.rollout_blocks", self.glogen.rollout_blocks, 1, MAX_ROLLOUT)?;
        validate_block("locgen.block", &self.locgen.block, dim, dim, 0)?;
        whole_in_range("locgen.window", self.locgen.window, 1, MAX_LOCGEN_WINDOW)?;
        // Empty in models saved before LocGen had a scale.
        if !self.locgen.residual_scale.is_empty() {
            validate_scale("locgen.residual_scale", &self.locgen.residual_scale, dim)?;
        }
        if self.locgen.keep_sparse_poses && !self.locgen.window.is_multiple_of(self.stride) {
            return Err(E::field("locgen.window", format!("is {}; a LocGen that keeps the sparse poses needs a whole number of strides ({})", self.locgen.window, self.stride)));
        }
        if let Some(inbetween) = &self.inbetween {
            validate_inbetween(inbetween, dim)?;
        }
        for file in self.training.weights_sha256.keys() {
            if ![GLOGEN_FILE, LOCGEN_FILE, INBETWEEN_FILE].contains(&file.as_str()) {
                return Err(E::field("weights_sha256", format!("names '{}', which is not a weight file of a model", clipped(file))));
            }
        }
        Ok(())
    }

    /// Where `class` and `style` sit in the label part of a conditioning row: the class's
    /// one-hot entry, then the style's after all the classes'.
    pub fn label_indices(&self, class: usize, style: Option<usize>) -> impl Iterator<Item = usize> {
        std::iter::once(class).chain(style.map(|s| self.classes.len() + s))
    }

    /// Dense frames from the first to the last of the sparse poses a block observes: what a
    /// start from a file gives of its own motion before GloGen's first pose.
    pub fn observed_span(&self) -> usize {
        (self.block_len - 1) * self.stride
    }

    /// Sets `class` and `style` in the label part of a conditioning row.
    pub fn set_labels(&self, row: &mut [f32], class: usize, style: Option<usize>) {
        for i in self.label_indices(class, style) {
            row[i] = 1.0;
        }
    }

    /// Per joint of the model's skeleton, how far (radians) its bone may turn in one frame of
    /// a take ([`Self::bone_turn_limits`] at the model's rate); none for a bone without one.
    pub fn turn_limits_per_frame(&self) -> Vec<Option<f32>> {
        self.layout.skeleton.names().iter().map(|n| self.bone_turn_limits.get(n).map(|d| (d / self.fps).to_radians())).collect()
    }

    /// One-hot entries of the label part of the conditioning: the classes, then the styles.
    pub fn labels(&self) -> usize {
        self.classes.len() + self.styles.len()
    }

    /// What LocGen's output is multiplied by before it is added to its input, per frame of
    /// a window and feature (`window * dim`): the residual's scale, 0 on the sparse poses
    /// the model keeps.
    pub fn locgen_gain(&self) -> Vec<f32> {
        let (locgen, dim) = (&self.locgen, self.layout.dim());
        let scale = |i: usize| locgen.residual_scale.get(i).copied().unwrap_or(1.0);
        let kept = |frame: usize| locgen.keep_sparse_poses && frame.is_multiple_of(self.stride);
        (0..locgen.window).flat_map(|f| (0..dim).map(move |i| if kept(f) { 0.0 } else { scale(i) })).collect()
    }

    /// Entries of the conditioning vector GloGen reads as labels (0 without the class prior);
    /// the target, where it reads one, follows them.
    pub fn label_len(&self) -> usize {
        self.glogen.class_len(self.labels())
    }

    fn validate_classes(&self) -> Result<(), SpecError> {
        if self.classes.is_empty() || self.classes.len() > MAX_CLASSES {
            return Err(SpecError::field("classes", format!("has {} names; a model has 1 to {MAX_CLASSES}", self.classes.len())));
        }
        for (k, c) in self.classes.iter().enumerate() {
            if c.trim().is_empty() {
                return Err(SpecError::field(&format!("classes[{k}]"), "is empty".into()));
            }
            // Class names are looked up ignoring case, so two that differ only in case clash.
            if let Some(first) = self.classes[..k].iter().position(|o| o.eq_ignore_ascii_case(c)) {
                return Err(SpecError::field(&format!("classes[{k}]"), format!("'{}' repeats classes[{first}]", clipped(c))));
            }
        }
        Ok(())
    }

    /// The model's skeleton must be the source skeleton's `source_joints`, and small enough.
    fn validate_skeletons(&self) -> Result<(), SpecError> {
        let (layout, source) = (&self.layout, &self.source_skeleton);
        let joints = layout.joints();
        if !(2..=MAX_JOINTS).contains(&joints) {
            return Err(SpecError::field("layout.skeleton", format!("has {joints} joints; a model has 2 to {MAX_JOINTS}")));
        }
        if source.len() > MAX_JOINTS {
            return Err(SpecError::field("source_skeleton", format!("has {} joints, more than {MAX_JOINTS}", source.len())));
        }
        for (field, hip) in [("layout.left_hip", layout.left_hip), ("layout.right_hip", layout.right_hip)] {
            if hip >= joints {
                return Err(SpecError::field(field, format!("is joint {hip}; the skeleton has {joints}")));
            }
        }
        let keep = &self.source_joints;
        if keep.len() != joints || keep.windows(2).any(|w| w[0] >= w[1]) || keep.iter().any(|&j| j >= source.len()) {
            return Err(SpecError::field("source_joints", format!("must be {joints} ascending joints of source_skeleton ({} joints)", source.len())));
        }
        // One root: every kept joint but the first descends from another kept joint.
        let kept: std::collections::HashSet<usize> = keep.iter().copied().collect();
        let has_kept_ancestor = |j: usize| std::iter::successors(source.parents()[j], |&p| source.parents()[p]).any(|p| kept.contains(&p));
        if let Some(&j) = keep[1..].iter().find(|&&j| !has_kept_ancestor(j)) {
            return Err(SpecError::field("source_joints", format!("keeps joint {j} but none of its ancestors, which would make a second root")));
        }
        let diff = source.subset(keep).differences(&layout.skeleton);
        if !diff.is_empty() {
            return Err(SpecError::field("layout.skeleton", format!("is not source_skeleton's source_joints: {}", diff.join("; "))));
        }
        Ok(())
    }

    pub fn write(&self, dir: &Path) -> Result<()> {
        write_atomic(&dir.join("model.json"), serde_json::to_string_pretty(self)?.as_bytes())
    }

    /// The guidance the class `class` is made with unless a take asks for its own.
    pub fn class_strength_of(&self, class: usize) -> f32 {
        self.class_strengths.get(&self.classes[class]).copied().unwrap_or(self.class_strength)
    }

    /// How fast `class` moves in `style` against its speed over all its clips
    /// ([`Self::style_speed`]); none where the model has no speed of that style.
    pub fn style_pace(&self, class: usize, style: usize) -> Option<f32> {
        let speed = self.style_speed.get(self.classes.get(class)?)?.get(self.styles.get(style)?)?;
        let all = *self.class_speed.get(class)?;
        (all > 0.0).then(|| speed / all)
    }

    /// Per class, the share of its texture a take gets ([`Self::texture_gains`]).
    pub fn texture_gain_per_class(&self) -> Vec<f32> {
        self.classes.iter().map(|c| self.texture_gains.get(c).copied().unwrap_or(1.0)).collect()
    }

    /// Per class, the index of the class its guidance steers away from
    /// ([`Self::class_contrasts`]).
    pub fn contrast_indices(&self) -> Vec<Option<usize>> {
        self.classes.iter().map(|c| self.class_contrasts.get(c).and_then(|away| self.classes.iter().position(|k| k == away))).collect()
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
    /// Its clip's style (index into [`ModelSpec::styles`]; a model with styles only): a take
    /// asking for a style eases onto a window of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub style: Option<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    /// Whether `written` has every field of `read` with its value (and maybe the defaults of
    /// fields `read` was saved without).
    fn holds(written: &Value, read: &Value) -> bool {
        match (written, read) {
            (Value::Object(w), Value::Object(r)) => r.iter().all(|(k, v)| w.get(k).is_some_and(|w| holds(w, v))),
            (Value::Array(w), Value::Array(r)) => w.len() == r.len() && w.iter().zip(r).all(|(w, r)| holds(w, r)),
            _ => written == read,
        }
    }

    /// The fields in sub-structs are flattened into model.json: a shipped model's file,
    /// checksums verified, writes back every value it was read with.
    #[test]
    fn a_shipped_model_json_writes_back_every_value_it_read() {
        let json = |dir: &Path| -> Value { serde_json::from_str(&std::fs::read_to_string(dir.join("model.json")).unwrap()).unwrap() };
        for model in ["h36m", "bandai", "all"] {
            let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(model);
            let out = tempfile::tempdir().unwrap();
            ModelSpec::read_verified(&dir).unwrap().write(out.path()).unwrap();
            let (read, written) = (json(&dir), json(out.path()));
            for (field, value) in read.as_object().unwrap() {
                assert!(written.get(field).is_some_and(|w| holds(w, value)), "{model}: {field}");
            }
        }
    }

    fn shipped_json(model: &str) -> Value {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(model).join("model.json");
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    /// `model` with `field` set to `value`, read as a model.json.
    fn with_field(model: &mut Value, field: &str, value: Value) -> Result<ModelSpec, Error> {
        model[field] = value;
        ModelSpec::from_json(&model.to_string(), "model.json")
    }

    /// A class's own guidance names one of the model's classes and is a strength a take may
    /// ask for; a class without one takes the model's.
    #[test]
    fn class_strengths_name_a_class_and_a_strength_in_range() {
        let mut model = shipped_json("h36m");
        let with = |model: &mut Value, strengths: Value| with_field(model, "class_strengths", strengths);
        let spec = with(&mut model, serde_json::json!({"walking": 3.5})).unwrap();
        assert_eq!(spec.class_strength_of(spec.class_index("walking").unwrap()), 3.5);
        assert_eq!(spec.class_strength_of(spec.class_index("eating").unwrap()), spec.class_strength);
        let unknown = with(&mut model, serde_json::json!({"salsa": 3.5})).unwrap_err().to_string();
        assert!(unknown.contains("class_strengths") && unknown.contains("'salsa'"), "{unknown}");
        let strong = with(&mut model, serde_json::json!({"walking": 11.0})).unwrap_err().to_string();
        assert!(strong.contains("class_strengths.walking") && strong.contains("between 0 and 10"), "{strong}");
    }

    /// The lively classes are the model's own: an unknown one is refused, naming the field.
    #[test]
    fn lively_classes_are_the_models_classes() {
        let mut model = shipped_json("h36m");
        let spec = with_field(&mut model, "lively_classes", serde_json::json!(["eating"])).unwrap();
        assert!(spec.lively_classes.contains("eating"));
        let unknown = with_field(&mut model, "lively_classes", serde_json::json!(["bow"])).unwrap_err().to_string();
        assert!(unknown.contains("lively_classes") && unknown.contains("'bow'"), "{unknown}");
    }

    /// A class's texture gain names one of the model's classes and is a share of its texture;
    /// a class without one gets all of it.
    #[test]
    fn texture_gains_name_a_class_and_a_share() {
        let mut model = shipped_json("h36m");
        let with = |model: &mut Value, gains: Value| with_field(model, "texture_gains", gains);
        let spec = with(&mut model, serde_json::json!({"walking": 0.25})).unwrap();
        let gains = spec.texture_gain_per_class();
        assert_eq!((gains[spec.class_index("walking").unwrap()], gains[spec.class_index("eating").unwrap()]), (0.25, 1.0));
        let unknown = with(&mut model, serde_json::json!({"salsa": 0.5})).unwrap_err().to_string();
        assert!(unknown.contains("texture_gains") && unknown.contains("'salsa'"), "{unknown}");
        let over = with(&mut model, serde_json::json!({"walking": 1.5})).unwrap_err().to_string();
        assert!(over.contains("texture_gains.walking") && over.contains("between 0 and 1"), "{over}");
    }

    /// A bone's turn limit names a bone of the model's skeleton (not its root, which has no
    /// bone) and is a turn a second in range; it is read a frame at the model's rate.
    #[test]
    fn bone_turn_limits_name_a_bone_and_a_turn_in_range() {
        let mut model = shipped_json("h36m");
        let with = |model: &mut Value, limits: Value| with_field(model, "bone_turn_limits", limits);
        let spec = with(&mut model, serde_json::json!({"LeftHand": 500.0})).unwrap();
        let per_frame = spec.turn_limits_per_frame();
        let hand = spec.layout.skeleton.index_of("LeftHand").unwrap();
        assert!((per_frame[hand].unwrap() - (500.0 / spec.fps).to_radians()).abs() < 1e-6);
        assert_eq!(per_frame.iter().filter(|l| l.is_some()).count(), 1);
        for (bad, says) in [(serde_json::json!({"Tail": 500.0}), "'Tail'"), (serde_json::json!({"Hips": 500.0}), "'Hips'"), (serde_json::json!({"LeftHand": -3.0}), "bone_turn_limits.LeftHand")] {
            let e = with(&mut model, bad).unwrap_err().to_string();
            assert!(e.contains("bone_turn_limits") && e.contains(says), "{e}");
        }
    }

    /// A style's speed names one of the model's classes and styles and is a speed; a style
    /// asked for is read against its class's.
    #[test]
    fn style_speeds_name_a_class_and_a_style() {
        let mut model = shipped_json("all");
        let with = |model: &mut Value, speeds: Value| with_field(model, "style_speed", speeds);
        let spec = with(&mut model, serde_json::json!({"byebye": {"sad": 0.05}})).unwrap();
        let (byebye, sad) = (spec.class_index("byebye").unwrap(), spec.styles.iter().position(|s| s == "sad").unwrap());
        assert!((spec.style_pace(byebye, sad).unwrap() - 0.05 / spec.class_speed[byebye]).abs() < 1e-6);
        assert_eq!(spec.style_pace(byebye, 0), None);
        for (bad, says) in [(serde_json::json!({"byebye": {"sleepy": 0.1}}), "'byebye/sleepy'"), (serde_json::json!({"flying": {"sad": 0.1}}), "'flying/sad'"), (serde_json::json!({"byebye": {"sad": -1.0}}), "style_speed.byebye.sad")] {
            let e = with(&mut model, bad).unwrap_err().to_string();
            assert!(e.contains("style_speed") && e.contains(says), "{e}");
        }
    }

    /// A contrast pairs two of the model's classes, different ones, on a GloGen with guidance;
    /// anything else is one line naming the field.
    #[test]
    fn class_contrasts_pair_two_classes_of_a_guided_model() {
        let mut model = shipped_json("h36m");
        let with = |model: &mut Value, contrasts: Value| with_field(model, "class_contrasts", contrasts);
        let spec = with(&mut model, serde_json::json!({"sitting": "sittingdown"})).unwrap();
        let sittingdown = spec.class_index("sittingdown").unwrap();
        let pairs = spec.contrast_indices();
        assert_eq!(pairs[spec.class_index("sitting").unwrap()], Some(sittingdown));
        assert_eq!(pairs.iter().flatten().count(), 1);
        assert_eq!(spec.contrast_strength, DEFAULT_CONTRAST_STRENGTH);
        for (bad, field) in [(serde_json::json!({"salsa": "walking"}), "class_contrasts.salsa"), (serde_json::json!({"walking": "salsa"}), "class_contrasts.walking"), (serde_json::json!({"walking": "walking"}), "class_contrasts.walking")] {
            let e = with(&mut model, bad).unwrap_err().to_string();
            assert!(e.contains(field) && e.contains("two different ones"), "{e}");
        }
        model["glogen"]["class_dropout"] = serde_json::json!(0.0);
        let unguided = with(&mut model, serde_json::json!({"sitting": "sittingdown"})).unwrap_err().to_string();
        assert!(unguided.contains("class_contrasts") && unguided.contains("no guidance"), "{unguided}");
    }

    /// model.json's two flags read as the three pose bases and are written back as they were
    /// (`residual_fade` only when set; a GloGen saved before either flag is absolute).
    #[test]
    fn pose_base_reads_and_writes_model_json_flags() {
        let model = shipped_json("h36m");
        for (flags, base) in [(None, PoseBase::Absolute), (Some((false, false)), PoseBase::Absolute), (Some((true, false)), PoseBase::Residual), (Some((false, true)), PoseBase::ResidualFade)] {
            let mut glogen = model["glogen"].clone();
            let fields = glogen.as_object_mut().unwrap();
            fields.remove("residual");
            if let Some((residual, fade)) = flags {
                fields.insert("residual".into(), residual.into());
                fields.insert("residual_fade".into(), fade.into());
            }
            let spec: GloGenSpec = serde_json::from_value(glogen).unwrap();
            assert_eq!(spec.base, base, "{flags:?}");
            let written = serde_json::to_value(&spec).unwrap();
            assert_eq!(written["residual"], base == PoseBase::Residual, "{flags:?}");
            assert_eq!(written.get("residual_fade").is_some(), base == PoseBase::ResidualFade, "{flags:?}");
        }
    }
}
