//! The comparison methods of the CMU table, trained by this crate on the same splits and
//! the same dense pose features (normalised with the training split's statistics):
//!
//! - **zero-velocity**: the last observed pose held still;
//! - **Seq2Seq** (Martinez et al. 2017): one GRU cell used as encoder over the observed
//!   frames and as decoder, with a residual connection (the cell predicts the velocity
//!   `x[t+1] − x[t]`), trained with the sampling-based loss (the decoder is fed its own
//!   outputs) on the predicted frames only;
//! - **acLSTM** (Li et al. 2018): an LSTM trained with auto-conditioning: along the training
//!   window it alternately gets `ac_truth` ground-truth frames and `ac_own` of its own
//!   outputs, loss on every step;
//! - **scheduled sampling** (Bengio et al. 2015): the same LSTM, each step fed its own output
//!   with a probability that rises linearly from 0 to 1 over the first 3/4 of training.
//!
//! All three share [`ArModel`], one autoregressive RNN with a mode switch. At test time each
//! reads the observed frames and then runs on its own outputs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::rnn::{gru, lstm, GRUConfig, LSTMConfig, GRU, LSTM, RNN};
use candle_nn::{linear, Linear, Module, Optimizer, ParamsAdamW, VarBuilder, VarMap};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::data::features::Normalizer;
use crate::data::write::write_atomic;
use crate::model::corpus::{sample_window, Corpus};
use crate::model::train::save_weights;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ArKind {
    Seq2Seq,
    AcLstm,
    Scheduled,
}

impl ArKind {
    pub const ALL: [ArKind; 3] = [ArKind::Seq2Seq, ArKind::AcLstm, ArKind::Scheduled];

    pub fn name(self) -> &'static str {
        match self {
            ArKind::Seq2Seq => "seq2seq",
            ArKind::AcLstm => "aclstm",
            ArKind::Scheduled => "scheduled-sampling",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            ArKind::Seq2Seq => "Seq2Seq (Martinez et al. 2017)",
            ArKind::AcLstm => "acLSTM (Li et al. 2018)",
            ArKind::Scheduled => "Scheduled sampling (Bengio et al. 2015)",
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ArConfig {
    pub kind: ArKind,
    pub hidden: usize,
    /// Observed frames (the last one is the pose at time 0).
    pub context: usize,
    /// Predicted frames.
    pub horizon: usize,
    pub steps: usize,
    pub batch: usize,
    pub lr: f64,
    pub seed: u64,
    pub ac_truth: usize,
    pub ac_own: usize,
}

impl ArConfig {
    pub fn new(kind: ArKind, context: usize, horizon: usize) -> Self {
        Self { kind, hidden: 256, context, horizon, steps: 1500, batch: 32, lr: 1e-3, seed: 11, ac_truth: 5, ac_own: 5 }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ArRecord {
    pub dataset: String,
    pub config: ArConfig,
    pub norm: Normalizer,
    pub train_seconds: f64,
    pub final_loss: f32,
}

enum Cell {
    Gru(GRU),
    Lstm(LSTM),
}

#[derive(Clone)]
enum State {
    Gru(candle_nn::rnn::GRUState),
    Lstm(candle_nn::rnn::LSTMState),
}

impl State {
    fn h(&self) -> &Tensor {
        match self {
            State::Gru(s) => s.h(),
            State::Lstm(s) => s.h(),
        }
    }
}

impl Cell {
    fn zero(&self, b: usize) -> Result<State> {
        Ok(match self {
            Cell::Gru(c) => State::Gru(c.zero_state(b)?),
            Cell::Lstm(c) => State::Lstm(c.zero_state(b)?),
        })
    }

    fn step(&self, x: &Tensor, s: &State) -> Result<State> {
        Ok(match (self, s) {
            (Cell::Gru(c), State::Gru(s)) => State::Gru(c.step(x, s)?),
            (Cell::Lstm(c), State::Lstm(s)) => State::Lstm(c.step(x, s)?),
            _ => unreachable!("cell and state kinds always match"),
        })
    }
}

/// One autoregressive RNN: a cell and a linear head predicting the next frame's change.
pub struct ArModel {
    pub record: ArRecord,
    cell: Cell,
    head: Linear,
    varmap: VarMap,
}

fn build(kind: ArKind, dim: usize, hidden: usize, vb: VarBuilder) -> Result<(Cell, Linear)> {
    let cell = match kind {
        ArKind::Seq2Seq => Cell::Gru(gru(dim, hidden, GRUConfig::default(), vb.pp("cell"))?),
        ArKind::AcLstm | ArKind::Scheduled => Cell::Lstm(lstm(dim, hidden, LSTMConfig::default(), vb.pp("cell"))?),
    };
    Ok((cell, linear(hidden, dim, vb.pp("head"))?))
}

pub fn cache_paths(dir: &Path, dataset: &str, kind: ArKind) -> (PathBuf, PathBuf) {
    (dir.join(format!("baseline-{dataset}-{}.safetensors", kind.name())), dir.join(format!("baseline-{dataset}-{}.json", kind.name())))
}

impl ArModel {
    /// Loads the cached model if it was trained with `cfg` on this dataset.
    pub fn load_cached(dir: &Path, dataset: &str, cfg: &ArConfig, dim: usize) -> Result<Option<Self>> {
        let (w, j) = cache_paths(dir, dataset, cfg.kind);
        if !(w.exists() && j.exists()) {
            return Ok(None);
        }
        let record: ArRecord = serde_json::from_str(&std::fs::read_to_string(&j)?).with_context(|| format!("{} is not a baseline record", j.display()))?;
        if record.config != *cfg || record.dataset != dataset {
            return Ok(None);
        }
        let varmap = VarMap::new();
        let (cell, head) = build(cfg.kind, dim, cfg.hidden, VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu))?;
        crate::model::glocal::load_weights(&w, &varmap)?;
        Ok(Some(Self { record, cell, head, varmap }))
    }

    pub fn save(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir)?;
        let (w, j) = cache_paths(dir, &self.record.dataset, self.record.config.kind);
        // Weights first: the record is what marks the pair complete.
        save_weights(&self.varmap, &w)?;
        write_atomic(&j, serde_json::to_string_pretty(&self.record)?.as_bytes())?;
        Ok(())
    }

    /// Trains on random windows (`context + horizon` frames) of the training split.
    pub fn train(corpus: &Corpus, norm: &Normalizer, cfg: &ArConfig, log: &mut dyn FnMut(&str)) -> Result<Self> {
        let layout = &corpus.layout;
        let dim = layout.dim();
        let varmap = VarMap::new();
        let (cell, head) = build(cfg.kind, dim, cfg.hidden, VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu))?;
        crate::model::train::seeded_init(&varmap, cfg.seed, 3)?;
        let mut opt = candle_nn::AdamW::new(varmap.all_vars(), ParamsAdamW { lr: cfg.lr, weight_decay: 1e-4, ..Default::default() })?;
        let me = Self {
            record: ArRecord { dataset: corpus.dataset.name().into(), config: cfg.clone(), norm: norm.clone(), train_seconds: 0.0, final_loss: f32::NAN },
            cell,
            head,
            varmap,
        };
        let len = cfg.context + cfg.horizon;
        let start = Instant::now();
        let mut avg = 0.0f32;
        for step in 0..cfg.steps {
            let mut rng = StdRng::seed_from_u64(cfg.seed ^ (step as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let mut xs = Vec::with_capacity(cfg.batch * len * dim);
            for _ in 0..cfg.batch {
                let (t, s) = sample_window(&corpus.train, corpus.classes.len(), len + 1, &mut rng).context("no training clip is long enough")?;
                xs.extend(layout.encode_motion(&t.motion, s + 1, 1, len));
            }
            norm.normalize(&mut xs);
            let x = Tensor::from_vec(xs, (cfg.batch, len, dim), &Device::Cpu)?;
            let own_p = (step as f64 / (0.75 * cfg.steps as f64)).min(1.0);
            let loss = me.training_loss(&x, &mut rng, own_p)?;
            opt.backward_step(&loss)?;
            let l = loss.to_scalar::<f32>()?;
            if !l.is_finite() {
                anyhow::bail!("baseline {} diverged at step {step}", cfg.kind.name());
            }
            avg = if step == 0 { l } else { 0.98 * avg + 0.02 * l };
            if (step + 1) % 250 == 0 {
                log(&format!("{} on {}: step {}/{} loss {avg:.4} ({:.0} s)", cfg.kind.name(), corpus.dataset, step + 1, cfg.steps, start.elapsed().as_secs_f32()));
            }
        }
        let mut me = me;
        me.record.train_seconds = start.elapsed().as_secs_f64();
        me.record.final_loss = avg;
        Ok(me)
    }

    fn predict_next(&self, x: &Tensor, s: &State) -> Result<(State, Tensor)> {
        let s = self.cell.step(x, s)?;
        let y = (x + self.head.forward(s.h())?)?;
        Ok((s, y))
    }

    /// x: [B, T, D] normalised ground truth.
    fn training_loss(&self, x: &Tensor, rng: &mut StdRng, own_p: f64) -> Result<Tensor> {
        let cfg = &self.record.config;
        let (b, t, _) = x.dims3()?;
        let mut state = self.cell.zero(b)?;
        let frame = |k: usize| -> Result<Tensor> { Ok(x.narrow(1, k, 1)?.squeeze(1)?.contiguous()?) };
        let mut prev_pred: Option<Tensor> = None;
        let mut losses = Vec::new();
        for k in 0..t - 1 {
            let use_own = match cfg.kind {
                ArKind::Seq2Seq => k >= cfg.context,
                ArKind::AcLstm => k >= cfg.ac_truth && (k % (cfg.ac_truth + cfg.ac_own)) >= cfg.ac_truth,
                ArKind::Scheduled => k > 0 && rng.random::<f64>() < own_p,
            };
            let input = match (&prev_pred, use_own) {
                (Some(p), true) => p.clone(),
                _ => frame(k)?,
            };
            let (s, y) = self.predict_next(&input, &state)?;
            state = s;
            let scored = match cfg.kind {
                ArKind::Seq2Seq => k + 1 >= cfg.context,
                _ => true,
            };
            if scored {
                losses.push((&y - frame(k + 1)?)?.sqr()?.mean_all()?);
            }
            prev_pred = Some(y);
        }
        let n = losses.len() as f64;
        Ok((Tensor::stack(&losses, 0)?.sum_all()? / n)?)
    }

    /// Predicts `horizon` frames after each observed sequence. `observed`: raw features,
    /// each `context * dim` long; returns raw features, each `horizon * dim` long.
    pub fn predict(&self, observed: &[Vec<f32>], horizon: usize) -> Result<Vec<Vec<f32>>> {
        let norm = &self.record.norm;
        let dim = norm.mean.len();
        let b = observed.len();
        let t = observed[0].len() / dim;
        let mut flat: Vec<f32> = observed.iter().flat_map(|o| o.iter().copied()).collect();
        norm.normalize(&mut flat);
        let x = Tensor::from_vec(flat, (b, t, dim), &Device::Cpu)?;
        let mut state = self.cell.zero(b)?;
        let mut y = x.narrow(1, 0, 1)?.squeeze(1)?.contiguous()?;
        for k in 0..t {
            let (s, p) = self.predict_next(&x.narrow(1, k, 1)?.squeeze(1)?.contiguous()?, &state)?;
            state = s;
            y = p;
        }
        let mut outs = vec![y.clone()];
        for _ in 1..horizon {
            let (s, p) = self.predict_next(&y, &state)?;
            state = s;
            y = p.detach();
            outs.push(y.clone());
        }
        let all = Tensor::stack(&outs, 1)?.to_vec3::<f32>()?;
        Ok(all
            .into_iter()
            .map(|seq| {
                let mut v: Vec<f32> = seq.into_iter().flatten().collect();
                norm.denormalize(&mut v);
                v
            })
            .collect())
    }
}
