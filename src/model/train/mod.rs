//! Training GloGen and LocGen: batches of real windows, the paper's joint + motion-flow
//! loss, validation on the held-out split, atomic and resumable checkpoints.
//!
//! Determinism: every random choice of step `k` comes from an RNG seeded by (seed, k), and
//! the optimiser state is checkpointed, so a run killed and resumed follows the same path.

mod checkpoint;
mod inbetween;
mod stage;
mod styles;
mod widen;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::{Optimizer, ParamsAdamW, VarBuilder, VarMap};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use self::checkpoint::{checkpoint, publish, Checkpoint, Legacy};
pub use self::checkpoint::save_weights;
use self::inbetween::{inbetween_residual_scale, InbetweenTraining};
use self::stage::{locgen_residual_scale, GloGenTraining, LocGenTraining, StageTraining, TrainingData};
use self::styles::{style_corpus, style_indices, StyleInputs};
use self::widen::load_fine_tuned;
use super::adamw::AdamW;
use super::block::{seed_dropout, BlockConfig, Seq2SeqBlock};
use super::corpus::{CalmFrames, Corpus};
use super::glocal::SEEDS_FILE;
use super::spec::{GloGenSpec, InbetweenSpec, GAP_CHANNELS, DEFAULT_CLASS_STRENGTH, DEFAULT_CONTRAST_STRENGTH, GLOGEN_FILE, INBETWEEN_FILE, LOCGEN_FILE, LocGenSpec, LossKind, ModelSpec, PoseBase, SeamJoin, Seed, StageRecord, TrainingRecords, FORMAT_VERSION};
use crate::data::archive::DataRoot;
use crate::data::features::{Interpolation, Normalizer};
use crate::data::registry::Dataset;
use crate::data::write::{write_atomic, FolderLock};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Glogen,
    Locgen,
    /// The in-betweener that fills the gap before a key ([`crate::model::inbetween`]).
    Inbetween,
}

/// The one place that knows which parts of a model belong to which stage.
impl Stage {
    /// The stage's weights in a model folder.
    pub fn file(self) -> &'static str {
        match self {
            Stage::Glogen => GLOGEN_FILE,
            Stage::Locgen => LOCGEN_FILE,
            Stage::Inbetween => INBETWEEN_FILE,
        }
    }

    /// The record of the stage's training in `spec`.
    pub fn record(self, spec: &ModelSpec) -> Option<&StageRecord> {
        match self {
            Stage::Glogen => spec.training.glogen.as_ref(),
            Stage::Locgen => spec.training.locgen.as_ref(),
            Stage::Inbetween => spec.training.inbetween.as_ref(),
        }
    }

    fn record_mut(self, spec: &mut ModelSpec) -> &mut Option<StageRecord> {
        match self {
            Stage::Glogen => &mut spec.training.glogen,
            Stage::Locgen => &mut spec.training.locgen,
            Stage::Inbetween => &mut spec.training.inbetween,
        }
    }

    /// The stage's network and the normaliser of its features.
    fn block_and_norm(self, spec: &ModelSpec) -> (BlockConfig, Normalizer) {
        match self {
            Stage::Glogen => (spec.glogen.block.clone(), spec.sparse_norm.clone()),
            Stage::Locgen => (spec.locgen.block.clone(), spec.dense_norm.clone()),
            Stage::Inbetween => (spec.inbetween.as_ref().expect("set by prepare_spec").block.clone(), spec.dense_norm.clone()),
        }
    }

    /// Puts a LocGen's or an in-betweener's residual scale ([`residual_scale`]) in `spec`.
    fn set_residual_scale(self, spec: &mut ModelSpec, scale: Option<Vec<f32>>) {
        let Some(scale) = scale else { return };
        match self {
            Stage::Glogen => {}
            Stage::Locgen => spec.locgen.residual_scale = scale,
            Stage::Inbetween => spec.inbetween.as_mut().expect("set by prepare_spec").residual_scale = scale,
        }
    }

    /// Gives `spec` this run's shape of the stage.
    fn set_shape(self, spec: &mut ModelSpec, shapes: StageShapes) {
        match self {
            Stage::Glogen => spec.glogen = shapes.glogen,
            Stage::Locgen => spec.locgen = shapes.locgen,
            Stage::Inbetween => spec.inbetween = Some(shapes.inbetween),
        }
    }
}

/// Every stage's shape as a run describes it.
struct StageShapes {
    glogen: GloGenSpec,
    locgen: LocGenSpec,
    inbetween: InbetweenSpec,
}

/// Known frames the in-betweener reads before a gap and after its key, and the longest gap it
/// learns (seconds).
const INBETWEEN_CONTEXT: usize = 10;
const INBETWEEN_AFTER: usize = 5;
const INBETWEEN_MAX_GAP_SECONDS: f32 = 2.0;

/// One training run of one stage: what it trains on, where it writes, how long and how
/// often it checks itself.
#[derive(Clone, Debug)]
pub struct TrainOptions {
    pub dataset: Dataset,
    pub data: DataRoot,
    pub stage: Stage,
    pub steps: usize,
    pub out: PathBuf,
    pub seed: u64,
    pub resume: bool,
    pub eval_every: usize,
    pub checkpoint_every: usize,
    /// Start the stage from this folder's trained weights (with a fresh optimiser) instead
    /// of random ones: fine-tuning, e.g. after a change to the data.
    pub init_from: Option<PathBuf>,
    /// Train only these styles' label inputs of the GloGen `init_from` holds, every other
    /// weight frozen ([`styles`]).
    pub only_styles: Vec<String>,
    pub optimiser: OptimiserOptions,
    pub shape: ModelShape,
}

/// The optimiser's settings.
#[derive(Clone, Debug)]
pub struct OptimiserOptions {
    /// Training windows per step.
    pub batch: usize,
    pub lr: f32,
}

/// The model a run describes in a new model.json (and in the stage it trains): its
/// networks, what they read and learn from, and the windows of data they see.
#[derive(Clone, Debug)]
pub struct ModelShape {
    pub hidden: usize,
    pub loss: LossKind,
    pub use_class: bool,
    pub class_in_decoder: bool,
    pub class_dropout: f32,
    pub rollout_blocks: usize,
    /// What GloGen's poses are measured from ([`GloGenSpec::base`]).
    pub base: PoseBase,
    /// GloGen trains on its blocks joined at their seams ([`GloGenSpec::joined`]).
    pub joined: bool,
    /// How GloGen's blocks are joined, in training and in generation ([`GloGenSpec::seam_join`]).
    pub seam_join: SeamJoin,
    /// GloGen reads the next key it must reach ([`GloGenSpec::target`]).
    pub target: bool,
    pub stride: usize,
    pub block_len: usize,
    /// Sparse intervals per LocGen window (its dense frames are this many strides).
    pub locgen_keys: usize,
    /// Classes with fewer training clips are left out.
    pub min_clips: usize,
    /// The interpolation a new LocGen refines.
    pub interpolation: Interpolation,
}

impl TrainOptions {
    pub fn new(dataset: Dataset, stage: Stage, out: PathBuf) -> Self {
        Self {
            dataset,
            data: DataRoot::resolve(None),
            stage,
            steps: 4000,
            out,
            seed: 0,
            resume: false,
            eval_every: 250,
            checkpoint_every: 250,
            init_from: None,
            only_styles: Vec::new(),
            optimiser: OptimiserOptions { batch: 64, lr: 0.002 },
            shape: ModelShape {
                hidden: 200,
                loss: LossKind::JointFlow,
                use_class: true,
                class_in_decoder: true,
                class_dropout: 0.1,
                rollout_blocks: 2,
                base: PoseBase::Absolute,
                joined: false,
                seam_join: SeamJoin::OneSided,
                target: false,
                stride: 5,
                block_len: 10,
                locgen_keys: 4,
                min_clips: 3,
                interpolation: Interpolation::NaturalCubic,
            },
        }
    }
}

impl TrainOptions {
    /// The stage's published weights.
    pub fn weights_path(&self) -> PathBuf {
        self.out.join(self.stage.file())
    }

    /// The stage's training checkpoint, the one file `--resume` reads (a run of styles has
    /// its own, so it never resumes the GloGen's own training or the other way round).
    pub fn state_path(&self) -> PathBuf {
        let run = if self.only_styles.is_empty() { "" } else { "-styles" };
        self.out.join(format!("{}{run}{TRAIN_STATE_SUFFIX}", self.stage.file().trim_end_matches(".safetensors")))
    }

    /// The record of this run in `spec`: the stage's own, or that of the styles taught alone.
    pub fn record<'s>(&self, spec: &'s ModelSpec) -> Option<&'s StageRecord> {
        if self.only_styles.is_empty() {
            self.stage.record(spec)
        } else {
            spec.training.styles.as_ref()
        }
    }

    fn record_mut<'s>(&self, spec: &'s mut ModelSpec) -> &'s mut Option<StageRecord> {
        if self.only_styles.is_empty() {
            self.stage.record_mut(spec)
        } else {
            &mut spec.training.styles
        }
    }

    /// Every option in its range before anything is loaded: each problem names its flag.
    pub fn validate(&self) -> Result<()> {
        let whole = |flag: &str, v: usize, lo: usize, hi: usize| -> Result<()> {
            if !(lo..=hi).contains(&v) {
                bail!("--{flag} must be between {lo} and {hi}, got {v}");
            }
            Ok(())
        };
        whole("steps", self.steps, 1, 100_000_000)?;
        whole("batch", self.optimiser.batch, 1, 4096)?;
        whole("hidden", self.shape.hidden, 1, 4096)?;
        whole("stride", self.shape.stride, 1, 100)?;
        whole("rollout", self.shape.rollout_blocks, 1, 100)?;
        whole("eval-every", self.eval_every, 1, usize::MAX)?;
        whole("checkpoint-every", self.checkpoint_every, 1, usize::MAX)?;
        whole("block-len", self.shape.block_len, 1, 1000)?;
        whole("locgen-keys", self.shape.locgen_keys, 1, 1000 / self.shape.stride.max(1))?;
        if !(self.shape.class_dropout.is_finite() && (0.0..=1.0).contains(&self.shape.class_dropout)) {
            bail!("--class-dropout must be a probability between 0 and 1, got {}", self.shape.class_dropout);
        }
        if !(self.optimiser.lr.is_finite() && self.optimiser.lr > 0.0) {
            bail!("the learning rate must be a positive number, got {}", self.optimiser.lr);
        }
        if self.out.is_file() {
            bail!("--out {} is a file; training writes a model folder", self.out.display());
        }
        let two_sided = self.shape.seam_join == SeamJoin::TwoSided;
        if !self.only_styles.is_empty() && (self.stage != Stage::Glogen || self.init_from.is_none()) {
            bail!("--only-styles teaches a trained GloGen new styles: it needs --stage glogen and --fine-tune or --init-from");
        }
        if self.stage == Stage::Locgen && (self.shape.base != PoseBase::Absolute || self.shape.joined || two_sided || self.shape.target) {
            bail!("--residual, --residual-fade, --joined, --two-sided-join and --target shape GloGen's blocks; they do not apply to --stage locgen");
        }
        Ok(())
    }
}

/// What the progress callback sees.
#[derive(Clone, Debug)]
pub struct Progress {
    pub step: usize,
    pub steps: usize,
    pub loss: f32,
    pub val_error: Option<f32>,
    pub steps_per_s: f32,
}

const TRAIN_STATE_SUFFIX: &str = ".train.safetensors";

/// Trains one stage into `opts.out`, creating `model.json` and the seed bank when absent.
pub fn train(opts: &TrainOptions, on_progress: &mut dyn FnMut(&Progress), cancel: &AtomicBool) -> Result<ModelSpec> {
    let Inputs { corpus, from, only_styles, style_clips } = read_inputs(opts)?;
    std::fs::create_dir_all(&opts.out).with_context(|| format!("cannot create {}", opts.out.display()))?;
    let _lock = FolderLock::acquire(&opts.out)?;
    let mut spec = prepare_spec(opts, &corpus, from.as_ref())?;
    let (cfg, norm) = opts.stage.block_and_norm(&spec);
    if !opts.resume {
        let scale = residual_scale(TrainingData { opts, corpus: &corpus, spec: &spec, norm: &norm }, from.as_ref())?;
        opts.stage.set_residual_scale(&mut spec, scale);
        spec.write(&opts.out)?;
    }
    let varmap = VarMap::new();
    let block = Seq2SeqBlock::new(cfg.clone(), VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu))?;
    seeded_init(&varmap, opts.seed.wrapping_add(0x5EED), 4)?;
    if let (Some(dir), Some(from)) = (&opts.init_from, &from) {
        load_fine_tuned(dir, opts.stage, from, &spec, &varmap)?;
    }
    // `--only-styles` trains its styles' inputs alone.
    let (style_inputs, named) = if only_styles.is_empty() {
        (None, varmap.data().lock().map_err(|_| anyhow::anyhow!("poisoned"))?.iter().map(|(k, v)| (k.clone(), v.clone())).collect())
    } else {
        let (inputs, trained) = StyleInputs::new(&varmap, &cfg, &spec, &only_styles, !opts.resume)?;
        (Some(inputs), trained)
    };
    let mut run = Run {
        opts,
        opt: AdamW::named(named, ParamsAdamW { lr: opts.optimiser.lr as f64, ..Default::default() })?,
        record: StageRecord { seed: opts.seed, ..Default::default() },
        varmap: &varmap,
        style_inputs,
    };
    if opts.resume {
        run.resume(&mut spec)?;
    }
    let frozen_spec = spec.clone();
    let corpus = style_clips.as_ref().unwrap_or(&corpus);
    let trainer = stage_training(TrainingData { opts, corpus, spec: &frozen_spec, norm: &norm });
    run.steps(&block, trainer.as_ref(), &mut spec, on_progress, cancel)?;
    Ok(spec)
}

/// The training of `data.opts.stage`.
fn stage_training<'a>(data: TrainingData<'a>) -> Box<dyn StageTraining + 'a> {
    match data.opts.stage {
        Stage::Glogen => Box::new(GloGenTraining(data)),
        Stage::Locgen => Box::new(LocGenTraining(data)),
        Stage::Inbetween => Box::new(InbetweenTraining(data)),
    }
}

/// What a run reads before it writes anything: the data, the model fine-tuned from, the
/// styles taught alone and their clips, each checked.
struct Inputs {
    corpus: Corpus,
    from: Option<ModelSpec>,
    only_styles: Vec<usize>,
    style_clips: Option<Corpus>,
}

fn read_inputs(opts: &TrainOptions) -> Result<Inputs> {
    opts.validate()?;
    super::memory::retain_freed_memory();
    let (weights_path, state_path) = (opts.weights_path(), opts.state_path());
    if opts.resume && !state_path.exists() && weights_path.exists() {
        bail!(
            "--resume: {} has trained {} weights but no training state ({}) to resume from; to train on from those weights with a fresh optimiser use --fine-tune",
            opts.out.display(),
            opts.stage.file(),
            state_path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        );
    }
    let corpus = Corpus::load(opts.dataset, &opts.data, opts.shape.stride, opts.shape.min_clips)?;
    if corpus.classes.is_empty() || corpus.train.is_empty() {
        bail!("{} has no class with at least {} training clips", opts.dataset, opts.shape.min_clips);
    }
    // Read before this run rewrites the folder's model.json (a --fine-tune reads its own).
    let from = opts.init_from.as_deref().map(ModelSpec::read).transpose()?;
    if let (Some(from), Some(dir)) = (&from, &opts.init_from) {
        check_labels(from, &corpus, opts.stage).with_context(|| format!("cannot fine-tune from {}", dir.display()))?;
    }
    let only_styles = style_indices(&corpus, &opts.only_styles)?;
    let style_clips = (!only_styles.is_empty()).then(|| style_corpus(&corpus, &only_styles)).transpose()?;
    Ok(Inputs { corpus, from, only_styles, style_clips })
}

/// A LocGen's or an in-betweener's residual scale: a fine-tuned one keeps the scale its weights
/// were trained with, a new one measures its training windows; none for a GloGen.
fn residual_scale(data: TrainingData, from: Option<&ModelSpec>) -> Result<Option<Vec<f32>>> {
    Ok(match data.opts.stage {
        Stage::Glogen => None,
        Stage::Locgen => Some(match from {
            Some(from) => from.locgen.residual_scale.clone(),
            None => locgen_residual_scale(data)?,
        }),
        Stage::Inbetween => Some(match from.and_then(|f| f.inbetween.as_ref()) {
            Some(from) => from.residual_scale.clone(),
            None => inbetween_residual_scale(data)?,
        }),
    })
}

/// A run's optimiser, record and where it writes, from its first step to its last.
struct Run<'a> {
    opts: &'a TrainOptions,
    opt: AdamW,
    record: StageRecord,
    varmap: &'a VarMap,
    style_inputs: Option<StyleInputs>,
}

impl Run<'_> {
    /// Picks the run up where its checkpoint left it.
    fn resume(&mut self, spec: &mut ModelSpec) -> Result<()> {
        let (weights_path, state_path) = (self.opts.weights_path(), self.opts.state_path());
        if !state_path.exists() {
            return Ok(());
        }
        let previous = self.opts.record(spec).cloned();
        let checkpoint = Checkpoint::read(&state_path, self.varmap, Legacy { weights: &weights_path, record: previous })?;
        self.opt.load_state(&checkpoint.optimiser, checkpoint.step)?;
        self.record = checkpoint.record;
        // A run killed between the checkpoint and its published copies left them a step
        // behind; publish them again from the one consistent file.
        publish(self.varmap, spec, self.opts, &self.record, &weights_path)
    }

    /// The steps up to `opts.steps` or until `cancel`, validated and checkpointed as asked, and
    /// once more where a cancel stops between checkpoints.
    fn steps(&mut self, block: &Seq2SeqBlock, trainer: &dyn StageTraining, spec: &mut ModelSpec, on_progress: &mut dyn FnMut(&Progress), cancel: &AtomicBool) -> Result<()> {
        let opts = self.opts;
        let validation = trainer.validation_windows();
        let start = Instant::now();
        let seconds_before = self.record.seconds;
        let first = self.opt.step;
        while self.opt.step < opts.steps && !cancel.load(Ordering::Relaxed) {
            let step_seed = opts.seed ^ (self.opt.step as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let mut rng = StdRng::seed_from_u64(step_seed);
            seed_dropout(step_seed.rotate_left(17));
            let loss = trainer.loss(block, &mut rng)?;
            let last_loss = loss.to_scalar::<f32>()?;
            if !last_loss.is_finite() {
                bail!("training diverged at step {} (loss {last_loss})", self.opt.step);
            }
            self.opt.backward_step(&loss)?;
            if let Some(inputs) = &self.style_inputs {
                inputs.restore()?;
            }
            let step = self.opt.step;
            let done = step == opts.steps;
            let mut val_error = None;
            if step.is_multiple_of(opts.eval_every) || done {
                let (err, base) = trainer.validate(block, &validation)?;
                self.record.curve.push((step, last_loss, err));
                self.record.val_error = err;
                self.record.baseline_error = base;
                val_error = Some(err);
            }
            let rate = (step - first) as f32 / start.elapsed().as_secs_f32().max(1e-3);
            on_progress(&Progress { step, steps: opts.steps, loss: last_loss, val_error, steps_per_s: rate });
            if step.is_multiple_of(opts.checkpoint_every) || done {
                self.record.steps = step;
                self.record.seconds = seconds_before + start.elapsed().as_secs_f64();
                self.checkpoint(spec)?;
            }
        }
        if cancel.load(Ordering::Relaxed) && self.opt.step > self.record.steps {
            self.record.steps = self.opt.step;
            self.record.seconds = seconds_before + start.elapsed().as_secs_f64();
            self.checkpoint(spec)?;
        }
        Ok(())
    }

    fn checkpoint(&self, spec: &mut ModelSpec) -> Result<()> {
        checkpoint(self.varmap, &self.opt, spec, self.opts, &self.record, &self.opts.weights_path(), &self.opts.state_path())
    }
}

/// Whether a stage trained on `from`'s labels can be fine-tuned on the data of `corpus`: the
/// same classes, and the same styles, or (a GloGen) styles the data has, whose weights the
/// fine-tuned block takes by name ([`widen`]).
fn check_labels(from: &ModelSpec, corpus: &Corpus, stage: Stage) -> Result<()> {
    let widens = stage == Stage::Glogen && styles_within(&from.styles, &corpus.styles);
    for (what, trained, data, allowed) in [("classes", &from.classes, &corpus.classes, false), ("styles", &from.styles, &corpus.styles, widens)] {
        if trained != data && !allowed {
            bail!("its {what} ({}) are not the data's ({})", trained.join(", "), data.join(", "));
        }
    }
    Ok(())
}

/// Whether every style a GloGen was trained with is among `data`'s, so a fine-tuning can
/// widen it onto them by name.
fn styles_within(trained: &[String], data: &[String]) -> bool {
    trained.iter().all(|s| data.contains(s))
}

/// Reads `model.json` when the folder has one for this dataset, else describes a new model.
fn prepare_spec(opts: &TrainOptions, corpus: &Corpus, from: Option<&ModelSpec>) -> Result<ModelSpec> {
    let dim = corpus.layout.dim();
    let labels = corpus.classes.len() + corpus.styles.len();
    let shape = &opts.shape;
    // Styles taught alone keep the trained GloGen's shape, whatever the flags say.
    let trained_glogen = from.filter(|_| !opts.only_styles.is_empty()).map(|f| f.glogen.clone());
    let mut glogen = trained_glogen.unwrap_or_else(|| GloGenSpec {
        block: BlockConfig {
            in_dim: dim,
            cond_dim: 0,
            cond_in_decoder: shape.use_class && shape.class_in_decoder,
            hidden: shape.hidden,
            out_dim: dim,
            dropout: 0.25,
        },
        use_class: shape.use_class,
        class_dropout: if shape.use_class { shape.class_dropout } else { 0.0 },
        rollout_blocks: shape.rollout_blocks.max(1),
        loss: shape.loss,
        base: shape.base,
        joined: shape.joined,
        seam_join: shape.seam_join,
        target: shape.target,
    });
    glogen.block.cond_dim = glogen.cond_len(labels, dim);
    // No dropout in LocGen: noise before its head, on a residual this small, taught it to
    // keep the head near zero (its output stayed at the interpolation).
    let locgen = LocGenSpec {
        block: BlockConfig { in_dim: dim, cond_dim: 0, cond_in_decoder: false, hidden: shape.hidden, out_dim: dim, dropout: 0.0 },
        window: shape.locgen_keys * shape.stride,
        interpolation: shape.interpolation,
        residual_scale: Vec::new(),
        keep_sparse_poses: true,
        by_default: true,
    };
    let inbetween = InbetweenSpec {
        block: BlockConfig { in_dim: dim + GAP_CHANNELS, cond_dim: 0, cond_in_decoder: false, hidden: shape.hidden, out_dim: dim, dropout: 0.0 },
        context: INBETWEEN_CONTEXT,
        after: INBETWEEN_AFTER,
        max_gap: (INBETWEEN_MAX_GAP_SECONDS * corpus.fps).round() as usize,
        // Measured on the training data before the stage trains.
        residual_scale: vec![0.0; dim],
    };
    let shapes = StageShapes { glogen, locgen, inbetween };
    if opts.out.join("model.json").exists() {
        let mut spec = ModelSpec::read(&opts.out)?;
        if spec.dataset != opts.dataset.name() || spec.layout.dim() != dim || spec.classes != corpus.classes {
            bail!("{} holds a model of another dataset or layout ({}); choose another --out", opts.out.display(), spec.dataset);
        }
        // Its labels are indices into the styles it was trained with: a GloGen fine-tuned
        // onto more styles takes each trained one's weights by name.
        if spec.styles != corpus.styles {
            if opts.stage != Stage::Glogen || opts.resume || !styles_within(&spec.styles, &corpus.styles) {
                bail!("{} holds a model of the styles {}, the data has {}; train a new model in another --out", opts.out.display(), spec.styles.join(", "), corpus.styles.join(", "));
            }
            spec.usual_styles = spec.usual_styles.iter().map(|&u| corpus.styles.iter().position(|s| *s == spec.styles[u]).expect("checked above")).collect();
            spec.styles = corpus.styles.clone();
        }
        // The stage being trained takes this run's settings; the other keeps its own.
        if !opts.resume {
            opts.stage.set_shape(&mut spec, shapes);
        }
        // A GloGen trained again is calibrated again (`glocal calibrate`): its classes' own
        // guidance (strengths, contrasts, the lively classes) was tuned to the weights it
        // replaces (new styles leave them as they were).
        if opts.stage == Stage::Glogen && opts.only_styles.is_empty() {
            spec.class_strengths.clear();
            spec.class_contrasts.clear();
            spec.lively_classes.clear();
        }
        // The texture's shares make up what the dense frames lack, which either network moves.
        if opts.stage != Stage::Inbetween && opts.only_styles.is_empty() {
            spec.texture_gains.clear();
        }
        spec.write(&opts.out)?;
        return Ok(spec);
    }
    let (sparse_norm, dense_norm) = corpus.normalizers();
    let source = (*corpus.source_skeleton).clone();
    let spec = ModelSpec {
        format_version: FORMAT_VERSION,
        dataset: opts.dataset.name().to_string(),
        split: split_description(opts.dataset).to_string(),
        classes: corpus.classes.clone(),
        class_sources: corpus.class_sources.clone(),
        styles: corpus.styles.clone(),
        usual_styles: corpus.usual_styles(),
        fps: corpus.fps,
        stride: shape.stride,
        block_len: shape.block_len,
        layout: corpus.layout.clone(),
        source_skeleton: source,
        source_joints: corpus.source_joints.clone(),
        sparse_norm,
        dense_norm,
        class_speed: corpus.class_speeds(),
        style_speed: corpus.style_speeds(),
        foot_lock: true,
        carry_by_feet: carries_by_feet(opts.dataset),
        hold_course: holds_course(opts.dataset),
        class_strength: DEFAULT_CLASS_STRENGTH,
        class_strengths: BTreeMap::new(),
        class_contrasts: BTreeMap::new(),
        contrast_strength: DEFAULT_CONTRAST_STRENGTH,
        lively_classes: BTreeSet::new(),
        texture_gains: BTreeMap::new(),
        bone_turn_limits: corpus.bone_turn_limits(),
        glogen: shapes.glogen,
        locgen: shapes.locgen,
        inbetween: (opts.stage == Stage::Inbetween).then_some(shapes.inbetween),
        training: TrainingRecords::default(),
    };
    spec.write(&opts.out)?;
    write_seed_bank(&opts.out, &spec, corpus)?;
    Ok(spec)
}

/// Whether a new model of `dataset` has its body carried by its feet
/// ([`ModelSpec::carry_by_feet`]): Bandai's network slides its stance feet with the body (its
/// run's at 57 cm/s on the floor against the real 19), and so does `all`'s with Bandai's
/// classes (its dash's support point at a median 104 cm/s against 10, Bandai's classes 2.25x real); h36m's feet the
/// lock alone holds.
fn carries_by_feet(dataset: Dataset) -> bool {
    matches!(dataset, Dataset::Bandai | Dataset::Combined)
}

/// Whether a new model of `dataset` keeps a travelling class's course
/// ([`ModelSpec::hold_course`]): Human3.6M's walking goes round its capture room (a 10 s walk
/// turned through a full circle), and it is most of `all`'s; Bandai's walks go straight.
fn holds_course(dataset: Dataset) -> bool {
    matches!(dataset, Dataset::H36m | Dataset::Combined)
}

fn split_description(d: Dataset) -> &'static str {
    match d {
        Dataset::H36m => "test = subject S11; train = S1, S5, S6, S7, S8, S9",
        Dataset::Bandai => "test = styles tired and musical; train = the other styles",
        Dataset::CmuDance => "test = the highest-numbered clip of each class",
        Dataset::CmuExpmap => "the archive's train and test folders",
        Dataset::Combined => "each dataset's own: h36m S11, bandai styles tired and musical (half of their clips also teach the style, by its inputs alone: tired on odd contents, musical on even ones), cmu-dance the highest-numbered clip of each class, cmu-expmap its test folder",
    }
}

/// Up to 16 seeds per class, evenly spread over the class's training frames; a window that
/// holds a capture glitch ([`CalmFrames`]) gives way to the nearest calm one.
pub fn write_seed_bank(dir: &Path, spec: &ModelSpec, corpus: &Corpus) -> Result<()> {
    const PER_CLASS: usize = 16;
    let span = spec.block_len * spec.stride;
    let calm = CalmFrames::of(corpus);
    let mut seeds = Vec::new();
    for class in 0..spec.classes.len() {
        let candidates: Vec<(usize, usize)> = (0..corpus.train.len())
            .filter(|&i| corpus.train[i].class == class && corpus.train[i].motion.frames() > span + spec.stride)
            .flat_map(|i| (spec.stride..corpus.train[i].motion.frames() - span).step_by(span).map(move |f| (i, f)))
            .collect();
        let is_calm: Vec<bool> = candidates.iter().map(|&(clip, frame)| calm.holds(clip, frame..frame + span)).collect();
        let step = (candidates.len() / PER_CLASS).max(1);
        let mut picked: Vec<usize> = Vec::new();
        for spread in (0..candidates.len()).step_by(step).take(PER_CLASS) {
            let nearest_calm = (0..candidates.len()).filter(|&i| is_calm[i] && !picked.contains(&i)).min_by_key(|i| i.abs_diff(spread));
            picked.extend(nearest_calm);
        }
        picked.sort_unstable();
        for (clip, frame) in picked.into_iter().map(|i| candidates[i]) {
            let track = &corpus.train[clip];
            let features = spec.layout.encode_motion(&track.motion, frame, spec.stride, spec.block_len);
            seeds.push(Seed { class, clip: track.file.clone(), frame, features, style: None });
        }
    }
    set_seed_styles(&mut seeds, corpus, spec);
    write_seeds(dir, &seeds)
}

/// Each seed's style, read from its clip in `corpus` (a bank written before windows kept
/// their style gains them; `glocal calibrate` writes them); none where the model has no
/// styles.
pub fn set_seed_styles(seeds: &mut [Seed], corpus: &Corpus, spec: &ModelSpec) {
    let style_of: BTreeMap<&str, usize> = corpus
        .train
        .iter()
        .filter_map(|t| {
            let name = &corpus.styles[t.style?];
            Some((t.file.as_str(), spec.styles.iter().position(|s| s == name)?))
        })
        .collect();
    for seed in seeds {
        seed.style = style_of.get(seed.clip.as_str()).copied();
    }
}

/// `seeds` as the model folder `dir`'s seed bank.
pub fn write_seeds(dir: &Path, seeds: &[Seed]) -> Result<()> {
    write_atomic(&dir.join(SEEDS_FILE), serde_json::to_string(seeds)?.as_bytes())
}

/// PyTorch's default recurrent/linear initialisation, uniform in ±1/sqrt(fan), from our own
/// seed (candle's initialisers draw from an unseeded generator). `gates`: 4 for an LSTM, 3 for
/// a GRU.
pub fn seeded_init(varmap: &VarMap, seed: u64, gates: usize) -> Result<()> {
    let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
    let mut names: Vec<&String> = vars.keys().collect();
    names.sort();
    let mut rng = StdRng::seed_from_u64(seed);
    for name in names {
        let var = &vars[name];
        let dims = var.dims().to_vec();
        // Recurrent tensors are [gates * H, *] or [gates * H]; fan = H. Linear weights
        // [out, in]; fan = in.
        let fan = if name.contains("_ih") || name.contains("_hh") { dims[0] / gates } else { *dims.last().unwrap_or(&1) };
        let k = 1.0 / (fan.max(1) as f32).sqrt();
        let values: Vec<f32> = (0..var.elem_count()).map(|_| rng.random_range(-k..k)).collect();
        var.set(&Tensor::from_vec(values, var.shape(), &Device::Cpu)?)?;
    }
    Ok(())
}
