//! Training GloGen and LocGen: batches of real windows, the paper's joint + motion-flow
//! loss, validation on the held-out split, atomic and resumable checkpoints.
//!
//! Determinism: every random choice of step `k` comes from an RNG seeded by (seed, k), and
//! the optimiser state is checkpointed, so a run killed and resumed follows the same path.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::{Optimizer, ParamsAdamW, VarBuilder, VarMap};
use glam::Vec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::adamw::AdamW;
use super::block::{seed_dropout, BlockConfig, Seq2SeqBlock};
use super::corpus::{interpolated_window, sample_window, Corpus, Track};
use super::glocal::{join_seams_tensor, load_weights, SEEDS_FILE};
use super::spec::{sha256_hex, GloGenSpec, DEFAULT_CLASS_STRENGTH, GLOGEN_FILE, LOCGEN_FILE, LocGenSpec, LossKind, ModelSpec, SeamJoin, Seed, StageRecord, FORMAT_VERSION};
use crate::data::archive::DataRoot;
use crate::data::features::{FeatureLayout, Interpolation, Normalizer, Placement};
use crate::data::registry::Dataset;
use crate::data::input::read_bytes;
use crate::data::write::{write_atomic, FolderLock};
use crate::motion::clipped;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Glogen,
    Locgen,
}

impl Stage {
    fn file(self) -> &'static str {
        match self {
            Stage::Glogen => GLOGEN_FILE,
            Stage::Locgen => LOCGEN_FILE,
        }
    }
}

#[derive(Clone, Debug)]
pub struct TrainOptions {
    pub dataset: Dataset,
    pub data: DataRoot,
    pub stage: Stage,
    pub steps: usize,
    pub out: PathBuf,
    pub seed: u64,
    pub resume: bool,
    pub batch: usize,
    pub lr: f32,
    pub hidden: usize,
    pub loss: LossKind,
    pub use_class: bool,
    pub class_in_decoder: bool,
    pub class_dropout: f32,
    pub rollout_blocks: usize,
    /// GloGen predicts offsets from the last pose of its input ([`GloGenSpec::residual`]).
    pub residual: bool,
    /// GloGen trains on its blocks joined at their seams ([`GloGenSpec::joined`]).
    pub joined: bool,
    /// How GloGen's blocks are joined, in training and in generation ([`GloGenSpec::seam_join`]).
    pub seam_join: SeamJoin,
    pub stride: usize,
    pub block_len: usize,
    pub locgen_window: usize,
    /// Classes with fewer training clips are left out.
    pub min_clips: usize,
    pub eval_every: usize,
    pub checkpoint_every: usize,
    /// Start the stage from this folder's trained weights (with a fresh optimiser) instead
    /// of random ones: fine-tuning, e.g. after a change to the data.
    pub init_from: Option<PathBuf>,
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
            batch: 64,
            lr: 0.002,
            hidden: 200,
            loss: LossKind::JointFlow,
            use_class: true,
            class_in_decoder: true,
            class_dropout: 0.1,
            rollout_blocks: 2,
            residual: false,
            joined: false,
            seam_join: SeamJoin::OneSided,
            stride: 5,
            block_len: 10,
            locgen_window: 10,
            min_clips: 3,
            eval_every: 250,
            checkpoint_every: 250,
            init_from: None,
            interpolation: Interpolation::CatmullRom,
        }
    }
}

impl TrainOptions {
    /// The stage's published weights.
    pub fn weights_path(&self) -> PathBuf {
        self.out.join(self.stage.file())
    }

    /// The stage's training checkpoint, the one file `--resume` reads.
    pub fn state_path(&self) -> PathBuf {
        self.out.join(format!("{}{TRAIN_STATE_SUFFIX}", self.stage.file().trim_end_matches(".safetensors")))
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
        whole("batch", self.batch, 1, 4096)?;
        whole("hidden", self.hidden, 1, 4096)?;
        whole("stride", self.stride, 1, 100)?;
        whole("rollout", self.rollout_blocks, 1, 100)?;
        whole("eval-every", self.eval_every, 1, usize::MAX)?;
        whole("checkpoint-every", self.checkpoint_every, 1, usize::MAX)?;
        whole("block-len", self.block_len, 1, 1000)?;
        whole("locgen-window", self.locgen_window, 1, 1000)?;
        if !(self.class_dropout.is_finite() && (0.0..=1.0).contains(&self.class_dropout)) {
            bail!("--class-dropout must be a probability between 0 and 1, got {}", self.class_dropout);
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            bail!("the learning rate must be a positive number, got {}", self.lr);
        }
        if self.out.is_file() {
            bail!("--out {} is a file; training writes a model folder", self.out.display());
        }
        let two_sided = self.seam_join == SeamJoin::TwoSided;
        if self.stage == Stage::Locgen && (self.residual || self.joined || two_sided) {
            bail!("--residual, --joined and --two-sided-join shape GloGen's blocks; they do not apply to --stage locgen");
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
const VALIDATION_WINDOWS: usize = 256;

/// Trains one stage into `opts.out`, creating `model.json` and the seed bank when absent.
pub fn train(opts: &TrainOptions, on_progress: &mut dyn FnMut(&Progress), cancel: &AtomicBool) -> Result<ModelSpec> {
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
    let corpus = Corpus::load(opts.dataset, &opts.data, opts.stride, opts.min_clips)?;
    if corpus.classes.is_empty() || corpus.train.is_empty() {
        bail!("{} has no class with at least {} training clips", opts.dataset, opts.min_clips);
    }
    std::fs::create_dir_all(&opts.out).with_context(|| format!("cannot create {}", opts.out.display()))?;
    let _lock = FolderLock::acquire(&opts.out)?;
    let mut spec = prepare_spec(opts, &corpus)?;
    let (cfg, norm) = match opts.stage {
        Stage::Glogen => (spec.glogen.block.clone(), spec.sparse_norm.clone()),
        Stage::Locgen => (spec.locgen.block.clone(), spec.dense_norm.clone()),
    };
    let varmap = VarMap::new();
    let block = Seq2SeqBlock::new(cfg.clone(), VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu))?;
    seeded_init(&varmap, opts.seed.wrapping_add(0x5EED), 4)?;
    if let Some(dir) = &opts.init_from {
        let from = dir.join(opts.stage.file());
        load_weights(&from, &varmap).with_context(|| format!("cannot fine-tune from {}", from.display()))?;
    }
    let named: Vec<_> = varmap.data().lock().map_err(|_| anyhow::anyhow!("poisoned"))?.iter().map(|(k, v)| (k.clone(), v.clone())).collect();
    let mut opt = AdamW::named(named, ParamsAdamW { lr: opts.lr as f64, ..Default::default() })?;
    let mut record = StageRecord { seed: opts.seed, ..Default::default() };
    if opts.resume {
        if state_path.exists() {
            let previous = match opts.stage {
                Stage::Glogen => spec.glogen_training.clone(),
                Stage::Locgen => spec.locgen_training.clone(),
            };
            let checkpoint = Checkpoint::read(&state_path, &varmap, Legacy { weights: &weights_path, record: previous })?;
            opt.load_state(&checkpoint.optimiser, checkpoint.step)?;
            record = checkpoint.record;
            // A run killed between the checkpoint and its published copies left them a step
            // behind; publish them again from the one consistent file.
            publish(&varmap, &mut spec, opts, &record, &weights_path)?;
        }
    }
    let frozen_spec = spec.clone();
    let trainer = StageTrainer { opts, corpus: &corpus, spec: &frozen_spec, norm: &norm };
    let validation = trainer.validation_windows();
    let start = Instant::now();
    let seconds_before = record.seconds;
    let first = opt.step;
    while opt.step < opts.steps && !cancel.load(Ordering::Relaxed) {
        let step_seed = opts.seed ^ (opt.step as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let mut rng = StdRng::seed_from_u64(step_seed);
        seed_dropout(step_seed.rotate_left(17));
        let loss = trainer.loss(&block, &mut rng)?;
        let last_loss = loss.to_scalar::<f32>()?;
        if !last_loss.is_finite() {
            bail!("training diverged at step {} (loss {last_loss})", opt.step);
        }
        opt.backward_step(&loss)?;
        let step = opt.step;
        let done = step == opts.steps;
        let mut val_error = None;
        if step % opts.eval_every == 0 || done {
            let (err, base) = trainer.validate(&block, &validation)?;
            record.curve.push((step, last_loss, err));
            record.val_error = err;
            record.baseline_error = base;
            val_error = Some(err);
        }
        let rate = (step - first) as f32 / start.elapsed().as_secs_f32().max(1e-3);
        on_progress(&Progress { step, steps: opts.steps, loss: last_loss, val_error, steps_per_s: rate });
        if step % opts.checkpoint_every == 0 || done {
            record.steps = step;
            record.seconds = seconds_before + start.elapsed().as_secs_f64();
            checkpoint(&varmap, &opt, &mut spec, opts, &record, &weights_path, &state_path)?;
        }
    }
    if cancel.load(Ordering::Relaxed) && opt.step > record.steps {
        record.steps = opt.step;
        record.seconds = seconds_before + start.elapsed().as_secs_f64();
        checkpoint(&varmap, &opt, &mut spec, opts, &record, &weights_path, &state_path)?;
    }
    Ok(spec)
}

/// Reads `model.json` when the folder has one for this dataset, else describes a new model.
fn prepare_spec(opts: &TrainOptions, corpus: &Corpus) -> Result<ModelSpec> {
    let dim = corpus.layout.dim();
    let classes = corpus.classes.len();
    let cond_dim = if opts.use_class { classes } else { 0 };
    let glogen = GloGenSpec {
        block: BlockConfig {
            in_dim: dim,
            cond_dim,
            cond_in_decoder: opts.use_class && opts.class_in_decoder,
            hidden: opts.hidden,
            out_dim: dim,
            dropout: 0.25,
        },
        use_class: opts.use_class,
        class_dropout: if opts.use_class { opts.class_dropout } else { 0.0 },
        rollout_blocks: opts.rollout_blocks.max(1),
        loss: opts.loss,
        residual: opts.residual,
        joined: opts.joined,
        seam_join: opts.seam_join,
    };
    let locgen = LocGenSpec {
        block: BlockConfig { in_dim: dim, cond_dim: 0, cond_in_decoder: false, hidden: opts.hidden, out_dim: dim, dropout: 0.25 },
        window: opts.locgen_window,
        interpolation: opts.interpolation,
    };
    if opts.out.join("model.json").exists() {
        let mut spec = ModelSpec::read(&opts.out)?;
        if spec.dataset != opts.dataset.name() || spec.layout.dim() != dim || spec.classes != corpus.classes {
            bail!("{} holds a model of another dataset or layout ({}); choose another --out", opts.out.display(), spec.dataset);
        }
        // The stage being trained takes this run's settings; the other keeps its own.
        match opts.stage {
            Stage::Glogen if !opts.resume => spec.glogen = glogen,
            Stage::Locgen if !opts.resume => spec.locgen = locgen,
            _ => {}
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
        fps: corpus.fps,
        stride: opts.stride,
        block_len: opts.block_len,
        layout: corpus.layout.clone(),
        source_skeleton: source,
        source_joints: corpus.source_joints.clone(),
        sparse_norm,
        dense_norm,
        class_speed: corpus.class_speeds(),
        foot_lock: true,
        carry_by_feet: false,
        class_strength: DEFAULT_CLASS_STRENGTH,
        glogen,
        locgen,
        glogen_training: None,
        locgen_training: None,
        weights_sha256: Default::default(),
    };
    spec.write(&opts.out)?;
    write_seed_bank(&opts.out, &spec, corpus)?;
    Ok(spec)
}


fn split_description(d: Dataset) -> &'static str {
    match d {
        Dataset::H36m => "test = subject S11; train = S1, S5, S6, S7, S8, S9",
        Dataset::Bandai => "test = styles tired and musical; train = the other styles",
        Dataset::CmuDance => "test = the highest-numbered clip of each class",
        Dataset::CmuExpmap => "the archive's train and test folders",
    }
}

/// Up to 16 seeds per class, evenly spread over the class's training frames.
fn write_seed_bank(dir: &Path, spec: &ModelSpec, corpus: &Corpus) -> Result<()> {
    const PER_CLASS: usize = 16;
    let span = spec.block_len * spec.stride;
    let mut seeds = Vec::new();
    for class in 0..spec.classes.len() {
        let candidates: Vec<(&Track, usize)> = corpus
            .train
            .iter()
            .filter(|t| t.class == class && t.motion.frames() > span + spec.stride)
            .flat_map(|t| (spec.stride..t.motion.frames() - span).step_by(span).map(move |f| (t, f)))
            .collect();
        let step = (candidates.len() / PER_CLASS).max(1);
        for (t, frame) in candidates.into_iter().step_by(step).take(PER_CLASS) {
            let features = spec.layout.encode_motion(&t.motion, frame, spec.stride, spec.block_len);
            seeds.push(Seed { class, clip: t.file.clone(), frame, features });
        }
    }
    write_atomic(&dir.join(SEEDS_FILE), serde_json::to_string(&seeds)?.as_bytes())
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

/// Commits one checkpoint. The training state file is the unit `--resume` reads: weights,
/// optimiser moments, step and the stage's record in one file, renamed into place at once,
/// so a kill at any moment leaves either the previous checkpoint or this one. Only then are
/// the published copies (the weights a model loads, model.json with their checksum) replaced.
fn checkpoint(
    varmap: &VarMap,
    opt: &AdamW,
    spec: &mut ModelSpec,
    opts: &TrainOptions,
    record: &StageRecord,
    weights_path: &Path,
    state_path: &Path,
) -> Result<()> {
    let mut tensors = named_tensors(varmap, WEIGHT_PREFIX)?;
    tensors.extend(opt.state_tensors()?.into_iter().map(|(k, v)| (format!("{OPTIMISER_PREFIX}{k}"), v)));
    let metadata = HashMap::from([
        (STEP_KEY.to_string(), opt.step.to_string()),
        (RECORD_KEY.to_string(), serde_json::to_string(record)?),
    ]);
    write_atomic(state_path, &safetensors_bytes(&tensors, Some(metadata), state_path)?)
        .with_context(|| format!("cannot write the training checkpoint {}", state_path.display()))?;
    publish(varmap, spec, opts, record, weights_path)
}

/// Writes the stage's weights and model.json (its record and the weights' checksum).
fn publish(varmap: &VarMap, spec: &mut ModelSpec, opts: &TrainOptions, record: &StageRecord, weights_path: &Path) -> Result<()> {
    let bytes = save_weights(varmap, weights_path)?;
    spec.weights_sha256.insert(opts.stage.file().to_string(), sha256_hex(&bytes));
    match opts.stage {
        Stage::Glogen => spec.glogen_training = Some(record.clone()),
        Stage::Locgen => spec.locgen_training = Some(record.clone()),
    }
    spec.write(&opts.out)
}

/// Writes every variable of `varmap` to a safetensors file, atomically; returns its bytes.
pub fn save_weights(varmap: &VarMap, path: &Path) -> Result<Vec<u8>> {
    let bytes = safetensors_bytes(&named_tensors(varmap, "")?, None, path)?;
    write_atomic(path, &bytes).with_context(|| format!("cannot write the weights {}", path.display()))?;
    Ok(bytes)
}

const WEIGHT_PREFIX: &str = "weight.";
const OPTIMISER_PREFIX: &str = "optimiser.";
const STEP_KEY: &str = "step";
const RECORD_KEY: &str = "record";

fn named_tensors(varmap: &VarMap, prefix: &str) -> Result<Vec<(String, Tensor)>> {
    let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("variable map poisoned"))?;
    Ok(vars.iter().map(|(k, v)| (format!("{prefix}{k}"), v.as_tensor().clone())).collect())
}

fn safetensors_bytes(tensors: &[(String, Tensor)], metadata: Option<HashMap<String, String>>, path: &Path) -> Result<Vec<u8>> {
    let mut data = Vec::with_capacity(tensors.len());
    for (name, t) in tensors {
        let values = t.flatten_all()?.to_vec1::<f32>()?;
        data.push((name.clone(), t.dims().to_vec(), values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()));
    }
    let views = data
        .iter()
        .map(|(name, shape, bytes)| Ok((name.as_str(), safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), bytes)?)))
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()
        .with_context(|| format!("cannot encode {}", path.display()))?;
    safetensors::serialize(views, metadata).with_context(|| format!("cannot encode {}", path.display()))
}

/// What `--resume` reads back from a training state file.
struct Checkpoint {
    step: usize,
    record: StageRecord,
    optimiser: HashMap<String, Tensor>,
}

impl Checkpoint {
    /// Reads the state file and fills `varmap` with its weights; every problem names the file.
    fn read(path: &Path, varmap: &VarMap, legacy: Legacy) -> Result<Self> {
        let name = path.display();
        let bytes = read_bytes(path, MAX_CHECKPOINT_BYTES).with_context(|| format!("cannot read the training checkpoint {name}"))?;
        let (_, header) = safetensors::SafeTensors::read_metadata(&bytes).with_context(|| format!("{name} is not a training checkpoint"))?;
        let meta = header.metadata().clone().unwrap_or_default();
        let mut tensors = candle_core::safetensors::load_buffer(&bytes, &Device::Cpu).with_context(|| format!("{name} is not a training checkpoint"))?;
        if let Some((k, _)) = tensors.iter().find(|(_, t)| t.flatten_all().and_then(|t| t.to_vec1::<f32>()).map_or(true, |v| v.iter().any(|x| !x.is_finite()))) {
            bail!("{name}: tensor '{}' is not finite f32 values", clipped(k));
        }
        let (Some(step), Some(record)) = (meta.get(STEP_KEY), meta.get(RECORD_KEY)) else {
            return Self::read_legacy(path, tensors, varmap, legacy);
        };
        let step: usize = step.parse().with_context(|| format!("{name}: step '{}' is not a whole number", clipped(step)))?;
        let record: StageRecord = serde_json::from_str(record).with_context(|| format!("{name}: the stage record is damaged"))?;
        if record.steps != step {
            bail!("{name}: its record says step {}, its optimiser step {step}; the file is damaged", record.steps);
        }
        let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("variable map poisoned"))?;
        for (var_name, var) in vars.iter() {
            let t = tensors.remove(&format!("{WEIGHT_PREFIX}{var_name}")).with_context(|| format!("{name} has no weights '{var_name}': it was saved for a different model"))?;
            if t.dims() != var.dims() {
                bail!("{name}: weights '{var_name}' have shape {:?}, the model needs {:?}", t.dims(), var.dims());
            }
            var.set(&t).with_context(|| format!("{name}: cannot load '{var_name}'"))?;
        }
        let optimiser = tensors.into_iter().filter_map(|(k, v)| k.strip_prefix(OPTIMISER_PREFIX).map(|k| (k.to_string(), v))).collect();
        Ok(Self { step, record, optimiser })
    }

    /// A state file from before checkpoints were one unit: moments and a `step` tensor, with
    /// the weights and record in their published files (kept readable so a run under way
    /// when this changed can still be resumed).
    fn read_legacy(path: &Path, mut tensors: HashMap<String, Tensor>, varmap: &VarMap, legacy: Legacy) -> Result<Self> {
        let name = path.display();
        let step = tensors.remove(STEP_KEY).with_context(|| format!("{name} has no step: not a training checkpoint"))?;
        let step = step.to_vec1::<f32>().ok().and_then(|v| v.first().copied()).with_context(|| format!("{name}: the step is damaged"))?;
        let record = legacy.record.with_context(|| format!("{name}: model.json has no record of this stage to resume"))?;
        if record.steps != step as usize {
            bail!("{name} is at step {step}, model.json's record at {}; they were written by different checkpoints", record.steps);
        }
        load_weights(legacy.weights, varmap).with_context(|| format!("cannot resume from {}", legacy.weights.display()))?;
        Ok(Self { step: record.steps, record, optimiser: tensors })
    }
}

/// Where a legacy state file's weights and record are.
struct Legacy<'a> {
    weights: &'a Path,
    record: Option<StageRecord>,
}

const MAX_CHECKPOINT_BYTES: u64 = 8 << 30;

/// A held-out window: inputs, targets and where it starts, all fixed for the whole run.
struct ValWindow {
    input: Vec<f32>,
    class: usize,
    target_positions: Vec<Vec3>,
    start: Placement,
    /// GloGen: the last input pose repeated (zero-velocity); LocGen: the interpolation.
    baseline_positions: Vec<Vec3>,
}

struct StageTrainer<'a> {
    opts: &'a TrainOptions,
    corpus: &'a Corpus,
    spec: &'a ModelSpec,
    norm: &'a Normalizer,
}

impl StageTrainer<'_> {
    fn layout(&self) -> &FeatureLayout {
        &self.spec.layout
    }

    /// GloGen window: (rollout + 1) blocks of sparse poses; LocGen: one dense window.
    fn span(&self) -> usize {
        match self.opts.stage {
            Stage::Glogen => self.spec.stride * (self.spec.block_len * (1 + self.spec.glogen.rollout_blocks)),
            Stage::Locgen => self.spec.locgen.window + 1,
        }
    }

    /// Features of one window starting at `frame` (which has a frame before it):
    /// (input, target), normalised.
    fn window(&self, track: &Track, frame: usize, blocks: usize) -> (Vec<f32>, Vec<f32>) {
        let m = &track.motion;
        let s = self.spec.stride;
        match self.opts.stage {
            Stage::Glogen => {
                let t = self.spec.block_len;
                let mut all = self.layout().encode_motion(m, frame, s, t * (1 + blocks));
                self.norm.normalize(&mut all);
                let split = t * self.layout().dim();
                (all[..split].to_vec(), all[split..].to_vec())
            }
            Stage::Locgen => {
                let w = self.spec.locgen.window;
                let interp = interpolated_window(m, frame, w, s, self.spec.locgen.interpolation);
                let frames: Vec<&[glam::Vec3]> = interp.chunks_exact(m.joints()).collect();
                let mut input = self.layout().encode(&frames, Some(m.frame(frame - 1)));
                let mut target = self.layout().encode_motion(m, frame, 1, w);
                self.norm.normalize(&mut input);
                self.norm.normalize(&mut target);
                (input, target)
            }
        }
    }

    fn loss(&self, block: &Seq2SeqBlock, rng: &mut StdRng) -> Result<Tensor> {
        let dim = self.layout().dim();
        let b = self.opts.batch;
        let blocks = if self.opts.stage == Stage::Glogen { self.spec.glogen.rollout_blocks } else { 1 };
        let span = self.span() + self.spec.stride;
        let (mut xs, mut ys, mut conds) = (Vec::new(), Vec::new(), Vec::new());
        let cond_dim = block.cfg.cond_dim;
        for _ in 0..b {
            let (track, start) = sample_window(&self.corpus.train, self.corpus.classes.len(), span, rng).context("no training clip is long enough")?;
            let (x, y) = self.window(track, start + self.spec.stride, blocks);
            xs.extend(x);
            ys.extend(y);
            let mut c = vec![0f32; cond_dim];
            if cond_dim > 0 && rng.random::<f32>() >= self.spec.glogen.class_dropout {
                c[track.class] = 1.0;
            }
            conds.extend(c);
        }
        let steps_in = xs.len() / b / dim;
        let x = Tensor::from_vec(xs, (b, steps_in, dim), &Device::Cpu)?;
        let y = Tensor::from_vec(ys, (b, steps_in * blocks, dim), &Device::Cpu)?;
        let cond = (cond_dim > 0).then(|| Tensor::from_vec(conds, (b, cond_dim), &Device::Cpu)).transpose()?;
        let loss_kind = if self.opts.stage == Stage::Glogen { self.spec.glogen.loss } else { LossKind::JointFlow };
        // Every block of the rollout, as generation leaves it: joined onto the block before,
        // which a two-sided join moves in turn (the observed context stays).
        let mut preds: Vec<Tensor> = Vec::with_capacity(blocks);
        let mut input = x.clone();
        for _ in 0..blocks {
            let mut pred = self.predict(block, &input, cond.as_ref(), true)?;
            if self.joins_blocks() {
                let before = match preds.last() {
                    Some(previous) => previous.clone(),
                    None => input.narrow(1, steps_in - 1, 1)?,
                };
                let (before, joined) = join_seams_tensor(&before, &pred, self.spec.glogen.seam_join)?;
                if let Some(previous) = preds.last_mut() {
                    *previous = before;
                }
                pred = joined;
            }
            input = pred.clone();
            preds.push(pred);
        }
        let mut total: Option<Tensor> = None;
        for (r, pred) in preds.iter().enumerate() {
            let target = y.narrow(1, r * steps_in, steps_in)?;
            let last = if r == 0 { x.narrow(1, steps_in - 1, 1)? } else { preds[r - 1].narrow(1, steps_in - 1, 1)? };
            let l = joint_flow_loss(pred, &target, &last, loss_kind)?;
            total = Some(match total {
                Some(t) => (t + l)?,
                None => l,
            });
        }
        Ok((total.expect("at least one block") / blocks as f64)?)
    }

    fn validation_windows(&self) -> Vec<ValWindow> {
        let mut rng = StdRng::seed_from_u64(1234);
        let s = self.spec.stride;
        let span = match self.opts.stage {
            Stage::Glogen => s * 2 * self.spec.block_len,
            Stage::Locgen => self.spec.locgen.window + 1,
        } + s;
        let tracks = if self.corpus.test.is_empty() { &self.corpus.train } else { &self.corpus.test };
        let mut out = Vec::new();
        for _ in 0..VALIDATION_WINDOWS {
            let Some((track, start)) = sample_window(tracks, self.corpus.classes.len(), span, &mut rng) else { break };
            let frame = start + s;
            let m = &track.motion;
            let (input, _) = self.window(track, frame, 1);
            let (target_positions, start_place, baseline_positions) = match self.opts.stage {
                Stage::Glogen => {
                    let t = self.spec.block_len;
                    let first_out = frame + t * s;
                    let last_in = m.frame(first_out - s);
                    let target: Vec<Vec3> = (0..t).flat_map(|k| m.frame(first_out + k * s).to_vec()).collect();
                    let baseline: Vec<Vec3> = (0..t).flat_map(|_| last_in.to_vec()).collect();
                    (target, self.layout().placement(last_in), baseline)
                }
                Stage::Locgen => {
                    let w = self.spec.locgen.window;
                    let target: Vec<Vec3> = (0..w).flat_map(|k| m.frame(frame + k).to_vec()).collect();
                    let baseline = interpolated_window(m, frame, w, s, self.spec.locgen.interpolation);
                    (target, self.layout().placement(m.frame(frame - 1)), baseline)
                }
            };
            out.push(ValWindow { input, class: track.class, target_positions, start: start_place, baseline_positions });
        }
        out
    }

    /// Whether the stage is a GloGen trained on its blocks joined at their seams.
    fn joins_blocks(&self) -> bool {
        self.opts.stage == Stage::Glogen && self.spec.glogen.joined
    }

    /// The stage's prediction from `input` `[B, T, dim]`: LocGen's is a residual on its
    /// interpolated input, a residual GloGen's an offset from the input's last pose.
    fn predict(&self, block: &Seq2SeqBlock, input: &Tensor, cond: Option<&Tensor>, train: bool) -> Result<Tensor> {
        let pred = block.forward(input, cond, train)?;
        if self.opts.stage == Stage::Locgen {
            return Ok((pred + input)?);
        }
        let last = input.narrow(1, input.dim(1)? - 1, 1)?;
        Ok(if self.spec.glogen.residual { pred.broadcast_add(&last)? } else { pred })
    }

    /// Mean joint position error (skeleton units) of the block and of the stage's baseline.
    fn validate(&self, block: &Seq2SeqBlock, windows: &[ValWindow]) -> Result<(f32, f32)> {
        let dim = self.layout().dim();
        let n = windows.len();
        if n == 0 {
            return Ok((f32::NAN, f32::NAN));
        }
        let steps = windows[0].input.len() / dim;
        let x: Vec<f32> = windows.iter().flat_map(|w| w.input.iter().copied()).collect();
        let x = Tensor::from_vec(x, (n, steps, dim), &Device::Cpu)?;
        let cond_dim = block.cfg.cond_dim;
        let cond = (cond_dim > 0)
            .then(|| {
                let c: Vec<f32> = windows.iter().flat_map(|w| (0..cond_dim).map(move |k| if k == w.class { 1.0 } else { 0.0 })).collect();
                Tensor::from_vec(c, (n, cond_dim), &Device::Cpu)
            })
            .transpose()?;
        let mut pred = self.predict(block, &x, cond.as_ref(), false)?;
        if self.joins_blocks() {
            pred = join_seams_tensor(&x.narrow(1, steps - 1, 1)?, &pred, self.spec.glogen.seam_join)?.1;
        }
        let pred = pred.flatten_all()?.to_vec1::<f32>()?;
        let (mut err, mut base, mut count) = (0.0f64, 0.0f64, 0usize);
        for (w, p) in windows.iter().zip(pred.chunks_exact(steps * dim)) {
            let mut p = p.to_vec();
            self.norm.denormalize(&mut p);
            let (positions, _) = self.layout().decode(&p, w.start);
            for ((a, b), c) in positions.iter().zip(&w.target_positions).zip(&w.baseline_positions) {
                err += a.distance(*b) as f64;
                base += c.distance(*b) as f64;
                count += 1;
            }
        }
        Ok(((err / count as f64) as f32, (base / count as f64) as f32))
    }
}

/// λ1·L_J + λ2·L_MF with λ1 = λ2 = 1 (mean squared errors). Motion flow includes the step
/// from the last input pose into the block, so blocks join smoothly.
pub fn joint_flow_loss(pred: &Tensor, target: &Tensor, last_input: &Tensor, kind: LossKind) -> Result<Tensor> {
    let joint = (pred - target)?.sqr()?.mean_all()?;
    let steps = pred.dim(1)?;
    let flow = || -> Result<Tensor> {
        let p = Tensor::cat(&[last_input, pred], 1)?;
        let t = Tensor::cat(&[last_input, target], 1)?;
        let vp = (p.narrow(1, 1, steps)? - p.narrow(1, 0, steps)?)?;
        let vt = (t.narrow(1, 1, steps)? - t.narrow(1, 0, steps)?)?;
        Ok((vp - vt)?.sqr()?.mean_all()?)
    };
    Ok(match kind {
        LossKind::Joint => joint,
        LossKind::Flow => flow()?,
        LossKind::JointFlow => (joint + flow()?)?,
    })
}
