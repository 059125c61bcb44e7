//! The action classifier behind FID, accuracy, diversity and multimodality: a one-layer GRU
//! over the model's dense pose features (root height, root displacement and turn, joints
//! relative to the root in the body's heading frame; see [`crate::data::features`]) of
//! `frames` consecutive frames at the working frame rate, then `hidden -> hidden` (ReLU,
//! the penultimate features used for FID) and `hidden -> classes`.
//!
//! It is trained on the real training split only (class-balanced random windows) and
//! cached under the evaluation cache as safetensors plus a JSON description.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::rnn::{gru, GRUConfig, GRU, RNN};
use candle_nn::{linear, Linear, Module, Optimizer, ParamsAdamW, VarBuilder, VarMap};
use rand::rngs::StdRng;
use rand::SeedableRng;
use serde::{Deserialize, Serialize};

use crate::data::features::{FeatureLayout, Normalizer};
use crate::data::write::write_atomic;
use crate::model::corpus::{sample_window, Corpus, Track};
use crate::model::spec::sha256_hex;
use crate::model::train::save_weights;
use crate::motion::Motion;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ClassifierConfig {
    pub hidden: usize,
    /// Frames per clip (at the dataset's working frame rate).
    pub frames: usize,
    pub steps: usize,
    pub batch: usize,
    pub lr: f64,
    pub seed: u64,
}

impl Default for ClassifierConfig {
    fn default() -> Self {
        Self { hidden: 128, frames: 60, steps: 1500, batch: 32, lr: 2e-3, seed: 7 }
    }
}

/// What the cache's JSON holds beside the weights.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ClassifierRecord {
    pub dataset: String,
    pub classes: Vec<String>,
    /// The SHA-256 of the training clips' names ([`training_clips`]): a cached classifier of
    /// the same classes trained on another split is trained again, not reused.
    #[serde(default)]
    pub training_clips: String,
    pub config: ClassifierConfig,
    pub norm: Normalizer,
    pub train_seconds: f64,
    pub final_loss: f32,
    /// Accuracy on windows of the real test split (see [`real_windows`]).
    pub test_accuracy: f64,
    pub test_windows: usize,
}

/// A fingerprint of `corpus`'s training split: the SHA-256 of its clips' names, in order.
fn training_clips(corpus: &Corpus) -> String {
    sha256_hex(corpus.train.iter().map(|t| t.file.as_str()).collect::<Vec<_>>().join("\n").as_bytes())
}

pub struct Classifier {
    pub record: ClassifierRecord,
    pub layout: FeatureLayout,
    gru: GRU,
    fc1: Linear,
    fc2: Linear,
    varmap: VarMap,
}

fn build(vb: VarBuilder, in_dim: usize, hidden: usize, classes: usize) -> Result<(GRU, Linear, Linear)> {
    Ok((gru(in_dim, hidden, GRUConfig::default(), vb.pp("gru"))?, linear(hidden, hidden, vb.pp("fc1"))?, linear(hidden, classes, vb.pp("fc2"))?))
}

/// Features of `frames` frames of `m` from `start` (which needs a frame before it).
pub fn clip_features(layout: &FeatureLayout, m: &Motion, start: usize, frames: usize) -> Vec<f32> {
    layout.encode_motion(m, start, 1, frames)
}

/// Windows of the given tracks: every `hop` frames, `frames` long (each with a frame before
/// it), as (class, raw features). `per_class` caps the windows per class, evenly spread.
pub fn real_windows(layout: &FeatureLayout, tracks: &[Track], classes: usize, frames: usize, hop: usize, per_class: usize) -> Vec<(usize, Vec<f32>)> {
    let mut out = Vec::new();
    for k in 0..classes {
        let starts: Vec<(&Track, usize)> = tracks
            .iter()
            .filter(|t| t.class == k && t.motion.frames() > frames + 1)
            .flat_map(|t| (1..t.motion.frames() - frames).step_by(hop).map(move |s| (t, s)))
            .collect();
        let step = (starts.len() as f64 / per_class as f64).max(1.0);
        let mut x = 0.0;
        while (x as usize) < starts.len() {
            let (t, s) = starts[x as usize];
            out.push((k, clip_features(layout, &t.motion, s, frames)));
            x += step;
        }
    }
    out
}

pub fn cache_dir() -> PathBuf {
    std::env::var_os("GLOCAL_EVAL_CACHE").map(PathBuf::from).unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/eval-cache"))
}

impl Classifier {
    fn paths(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
        (dir.join(format!("{name}.safetensors")), dir.join(format!("{name}.json")))
    }

    /// Loads `name` from `dir` when it was trained with `cfg` on these classes, else trains
    /// it on `corpus`'s training split and saves it.
    pub fn load_or_train(corpus: &Corpus, cfg: &ClassifierConfig, dir: &Path, name: &str, log: &mut dyn FnMut(&str)) -> Result<Self> {
        let (weights, json) = Self::paths(dir, name);
        if weights.exists() && json.exists() {
            let record: ClassifierRecord = serde_json::from_str(&std::fs::read_to_string(&json)?).with_context(|| format!("{} is not a classifier record", json.display()))?;
            if record.config == *cfg && record.classes == corpus.classes && record.dataset == corpus.dataset.name() && record.training_clips == training_clips(corpus) {
                let varmap = VarMap::new();
                let (g, f1, f2) = build(VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu), corpus.layout.dim(), cfg.hidden, corpus.classes.len())?;
                // Weights of another feature layout (a model skeleton that changed since) are
                // trained again.
                if crate::model::glocal::load_weights(&weights, &varmap).is_ok() {
                    log(&format!("classifier: cached {} (test accuracy {:.3})", weights.display(), record.test_accuracy));
                    return Ok(Self { record, layout: corpus.layout.clone(), gru: g, fc1: f1, fc2: f2, varmap });
                }
                log(&format!("classifier: {} was trained on another feature layout; training again", weights.display()));
            }
        }
        let c = Self::train(corpus, cfg, log)?;
        std::fs::create_dir_all(dir)?;
        // Weights first: the record is what marks the pair complete.
        save_weights(&c.varmap, &weights)?;
        write_atomic(&json, serde_json::to_string_pretty(&c.record)?.as_bytes())?;
        Ok(c)
    }

    /// Trains on class-balanced random windows of the training split.
    pub fn train(corpus: &Corpus, cfg: &ClassifierConfig, log: &mut dyn FnMut(&str)) -> Result<Self> {
        let layout = corpus.layout.clone();
        let dim = layout.dim();
        let classes = corpus.classes.len();
        if corpus.train.is_empty() || classes < 2 {
            bail!("{}: a classifier needs at least two classes with training clips", corpus.dataset);
        }
        let dense: Vec<f32> = corpus.train.iter().flat_map(|t| layout.encode_motion(&t.motion, 0, 1, t.motion.frames())).collect();
        let norm = Normalizer::fit(&dense, dim);
        let varmap = VarMap::new();
        let (g, f1, f2) = build(VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu), dim, cfg.hidden, classes)?;
        crate::model::train::seeded_init(&varmap, cfg.seed, 3)?;
        let mut opt = candle_nn::AdamW::new(varmap.all_vars(), ParamsAdamW { lr: cfg.lr, weight_decay: 1e-4, ..Default::default() })?;
        let mut me = Self {
            record: ClassifierRecord {
                dataset: corpus.dataset.name().into(),
                classes: corpus.classes.clone(),
                training_clips: training_clips(corpus),
                config: cfg.clone(),
                norm,
                train_seconds: 0.0,
                final_loss: f32::NAN,
                test_accuracy: f64::NAN,
                test_windows: 0,
            },
            layout,
            gru: g,
            fc1: f1,
            fc2: f2,
            varmap: varmap.clone(),
        };
        let start = Instant::now();
        let mut avg = 0.0f32;
        for step in 0..cfg.steps {
            let mut rng = StdRng::seed_from_u64(cfg.seed ^ (step as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let (mut xs, mut ys) = (Vec::new(), Vec::new());
            for _ in 0..cfg.batch {
                let (t, s) = sample_window(&corpus.train, classes, cfg.frames + 1, &mut rng).context("no training clip is long enough for the classifier")?;
                xs.push(clip_features(&me.layout, &t.motion, s + 1, cfg.frames));
                ys.push(t.class as u32);
            }
            let logits = me.forward(&xs)?.1;
            let y = Tensor::from_vec(ys, cfg.batch, &Device::Cpu)?;
            let loss = candle_nn::loss::cross_entropy(&logits, &y)?;
            opt.backward_step(&loss)?;
            let l = loss.to_scalar::<f32>()?;
            avg = if step == 0 { l } else { 0.98 * avg + 0.02 * l };
            if (step + 1) % 250 == 0 {
                log(&format!("classifier {}: step {}/{} loss {avg:.3} ({:.0} s)", corpus.dataset, step + 1, cfg.steps, start.elapsed().as_secs_f32()));
            }
        }
        me.record.train_seconds = start.elapsed().as_secs_f64();
        me.record.final_loss = avg;
        let test = real_windows(&me.layout, &corpus.test, classes, cfg.frames, cfg.frames / 2, 200);
        let (feats, labels): (Vec<Vec<f32>>, Vec<usize>) = test.into_iter().map(|(k, f)| (f, k)).unzip();
        let pred = me.predict(&feats)?;
        me.record.test_accuracy = super::metrics::accuracy(&pred, &labels);
        me.record.test_windows = labels.len();
        log(&format!("classifier {}: {:.0} s, test accuracy {:.3} on {} windows", corpus.dataset, me.record.train_seconds, me.record.test_accuracy, labels.len()));
        Ok(me)
    }

    /// (penultimate features [B, H], logits [B, classes]) of raw clip features.
    fn forward(&self, clips: &[Vec<f32>]) -> Result<(Tensor, Tensor)> {
        let dim = self.layout.dim();
        let b = clips.len();
        let t = clips[0].len() / dim;
        let mut flat: Vec<f32> = clips.iter().flat_map(|c| c.iter().copied()).collect();
        self.record.norm.normalize(&mut flat);
        let x = Tensor::from_vec(flat, (b, t, dim), &Device::Cpu)?;
        let mut state = self.gru.zero_state(b)?;
        for k in 0..t {
            state = self.gru.step(&x.narrow(1, k, 1)?.squeeze(1)?.contiguous()?, &state)?;
        }
        let feat = self.fc1.forward(state.h())?.relu()?;
        let logits = self.fc2.forward(&feat)?;
        Ok((feat, logits))
    }

    /// Penultimate features of each clip (raw features, `frames * dim` long).
    pub fn features(&self, clips: &[Vec<f32>]) -> Result<Vec<Vec<f32>>> {
        let mut out = Vec::new();
        for chunk in clips.chunks(256) {
            let f = self.forward(chunk)?.0.to_vec2::<f32>()?;
            out.extend(f);
        }
        Ok(out)
    }

    pub fn predict(&self, clips: &[Vec<f32>]) -> Result<Vec<usize>> {
        let mut out = Vec::new();
        for chunk in clips.chunks(256) {
            let logits = self.forward(chunk)?.1.argmax(1)?.to_vec1::<u32>()?;
            out.extend(logits.into_iter().map(|v| v as usize));
        }
        Ok(out)
    }

    /// Features of `frames` frames of a motion on the classifier's skeleton from `start`.
    pub fn clip(&self, m: &Motion, start: usize) -> Vec<f32> {
        clip_features(&self.layout, m, start, self.record.config.frames)
    }
}
