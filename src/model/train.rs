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
use super::glocal::{load_weights, GLOGEN_FILE, LOCGEN_FILE, SEEDS_FILE};
use super::spec::{GloGenSpec, LocGenSpec, LossKind, ModelSpec, Seed, StageRecord, FORMAT_VERSION};
use crate::data::archive::DataRoot;
use crate::data::features::{FeatureLayout, Interpolation, Normalizer, Placement};
use crate::data::registry::Dataset;
use crate::data::write::write_atomic;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
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
    let corpus = Corpus::load(opts.dataset, &opts.data, opts.stride, opts.min_clips)?;
    if corpus.classes.is_empty() || corpus.train.is_empty() {
        bail!("{} has no class with at least {} training clips", opts.dataset, opts.min_clips);
    }
    std::fs::create_dir_all(&opts.out).with_context(|| format!("cannot create {}", opts.out.display()))?;
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
    let weights_path = opts.out.join(opts.stage.file());
    let state_path = opts.out.join(format!("{}{TRAIN_STATE_SUFFIX}", opts.stage.file().trim_end_matches(".safetensors")));
    let mut record = StageRecord { seed: opts.seed, ..Default::default() };
    if opts.resume && weights_path.exists() && state_path.exists() {
        load_weights(&weights_path, &varmap)?;
        let state = candle_core::safetensors::load(&state_path, &Device::Cpu)?;
        let step = state.get("step").context("training state has no step")?.to_vec1::<f32>()?[0] as usize;
        opt.load_state(&state, step)?;
        if let Some(prev) = match opts.stage {
            Stage::Glogen => spec.glogen_training.clone(),
            Stage::Locgen => spec.locgen_training.clone(),
        } {
            record = prev;
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
            save_checkpoint(&varmap, &opt, &weights_path, &state_path)?;
            match opts.stage {
                Stage::Glogen => spec.glogen_training = Some(record.clone()),
                Stage::Locgen => spec.locgen_training = Some(record.clone()),
            }
            spec.write(&opts.out)?;
        }
    }
    if cancel.load(Ordering::Relaxed) {
        record.steps = opt.step;
        save_checkpoint(&varmap, &opt, &weights_path, &state_path)?;
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
        glogen,
        locgen,
        glogen_training: None,
        locgen_training: None,
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

fn save_checkpoint(varmap: &VarMap, opt: &AdamW, weights: &Path, state: &Path) -> Result<()> {
    let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
    let tensors: HashMap<String, Tensor> = vars.iter().map(|(k, v)| (k.clone(), v.as_tensor().clone())).collect();
    drop(vars);
    save_safetensors(&tensors, weights)?;
    let mut st: HashMap<String, Tensor> = opt.state_tensors()?.into_iter().collect();
    st.insert("step".into(), Tensor::new(&[opt.step as f32], &Device::Cpu)?);
    save_safetensors(&st, state)
}

fn save_safetensors(tensors: &HashMap<String, Tensor>, path: &Path) -> Result<()> {
    let tmp = path.with_extension("safetensors.tmp");
    candle_core::safetensors::save(tensors, &tmp).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot replace {}", path.display()))?;
    Ok(())
}

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
        let mut input = x.clone();
        let mut total: Option<Tensor> = None;
        for r in 0..blocks {
            let mut pred = block.forward(&input, cond.as_ref(), true)?;
            if self.opts.stage == Stage::Locgen {
                pred = (pred + &input)?;
            }
            let target = y.narrow(1, r * steps_in, steps_in)?;
            let last = input.narrow(1, steps_in - 1, 1)?;
            let l = joint_flow_loss(&pred, &target, &last, loss_kind)?;
            total = Some(match total {
                Some(t) => (t + l)?,
                None => l,
            });
            input = pred;
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
        let mut pred = block.forward(&x, cond.as_ref(), false)?;
        if self.opts.stage == Stage::Locgen {
            pred = (pred + &x)?;
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
