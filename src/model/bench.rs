//! Benchmarks of the seq2seq block: the fast fused LSTM against candle-nn's LSTM, with exactly the
//! shapes, loss and optimiser of `/work/shared/bench/torch_reference.py` (input 80 + 12 class,
//! hidden 200 per direction, 10 steps, batch 64, MSE + motion-flow MSE, AdamW lr 2e-3, dropout 0.25).
use super::adamw::AdamW as ProjectAdamW;
use super::block::{BlockConfig, BlockWorkspace, Seq2SeqBlock};
use super::loss::motion_loss;
use candle_core::{DType, Device, Result, Tensor};
use candle_nn::{AdamW, Optimizer, ParamsAdamW, VarBuilder, VarMap};
use serde::{Deserialize, Serialize};
use std::time::Instant;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainBenchConfig {
    pub batch: usize,
    pub steps_in: usize,
    pub feat: usize,
    pub classes: usize,
    pub hidden: usize,
    pub dropout: f32,
    pub lr: f64,
    /// Untimed steps before measuring.
    pub warmup: usize,
}

impl Default for TrainBenchConfig {
    fn default() -> Self {
        Self { batch: 64, steps_in: 10, feat: 80, classes: 12, hidden: 200, dropout: 0.25, lr: 2e-3, warmup: 3 }
    }
}

impl TrainBenchConfig {
    pub fn block_config(&self) -> BlockConfig {
        BlockConfig {
            in_dim: self.feat,
            cond_dim: self.classes,
            cond_in_decoder: false,
            hidden: self.hidden,
            out_dim: self.feat,
            dropout: self.dropout,
        }
    }
}

/// How long to measure: the set-ups are stepped round-robin, so `Seconds(s)` runs about `s`
/// seconds per set-up and `Steps(n)` runs `n` steps (calls, for inference) of each.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub enum Budget {
    /// At least this many seconds (whole steps).
    Seconds(f64),
    /// Exactly this many steps.
    Steps(usize),
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainBench {
    /// Fast LSTM + [`ProjectAdamW`] (the project's training setup).
    pub fast_steps_per_s: f64,
    /// Fast LSTM + `candle_nn::AdamW` (isolates the LSTM's share of the gain).
    pub fast_candle_adamw_steps_per_s: f64,
    /// candle-nn's `LSTM` + `candle_nn::AdamW` (the baseline).
    pub candle_nn_steps_per_s: f64,
    /// fast / candle-nn.
    pub speedup: f64,
    pub fast_final_loss: f32,
    pub candle_nn_final_loss: f32,
    pub config: TrainBenchConfig,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct InferBench {
    /// `Seq2SeqBlock::forward(train = false)` (candle tensors, fused LSTM op).
    pub fast_ms_per_block: f64,
    /// `Seq2SeqBlock::forward_with_reference_lstm` (candle-nn LSTMs).
    pub candle_nn_ms_per_block: f64,
    /// `FrozenBlock::infer` (plain f32).
    pub frozen_ms_per_block: f64,
    pub batch: usize,
    pub steps_in: usize,
    pub config: TrainBenchConfig,
}

fn one_hot(b: usize, c: usize, dev: &Device) -> Result<Tensor> {
    let mut v = vec![0f32; b * c];
    for i in 0..b {
        v[i * c + i % c.max(1)] = 1.0;
    }
    Tensor::from_vec(v, (b, c), dev)
}

/// Training steps per second of the block (each set-up its own freshly initialised model and
/// optimiser, same data): fast LSTM + [`ProjectAdamW`], fast LSTM + `candle_nn::AdamW`, and
/// candle-nn's LSTM + `candle_nn::AdamW`, stepped round-robin in the same call.
pub fn bench_train(cfg: TrainBenchConfig, budget: Budget) -> Result<TrainBench> {
    super::memory::retain_freed_memory();
    let dev = Device::Cpu;
    let (b, t, f, c) = (cfg.batch, cfg.steps_in, cfg.feat, cfg.classes);
    let x = Tensor::randn(0f32, 1.0, (b, t, f), &dev)?;
    let cond = one_hot(b, c, &dev)?;
    let y = Tensor::randn(0f32, 1.0, (b, t, f), &dev)?;
    let cond = if c > 0 { Some(&cond) } else { None };
    // The three set-ups are stepped round-robin, so that all see the same machine load (this
    // machine is shared); each is timed on its own steps only.
    type Step<'a> = Box<dyn FnMut() -> Result<f32> + 'a>;
    fn setup<'a, O: Optimizer<Config = ParamsAdamW> + 'a>(
        cfg: &TrainBenchConfig,
        reference: bool,
        x: &'a Tensor,
        cond: Option<&'a Tensor>,
        y: &'a Tensor,
    ) -> Result<Step<'a>> {
        let vm = VarMap::new();
        let blk = Seq2SeqBlock::new(cfg.block_config(), VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu))?;
        let mut opt = O::new(vm.all_vars(), ParamsAdamW { lr: cfg.lr, ..Default::default() })?;
        Ok(Box::new(move || {
            let out = if reference {
                blk.forward_with_reference_lstm(x, cond, true)?
            } else {
                blk.forward(x, cond, true)?
            };
            let loss = motion_loss(&out, y)?;
            opt.backward_step(&loss)?;
            loss.to_scalar::<f32>()
        }))
    }
    let mut steps: Vec<Step> = vec![
        setup::<ProjectAdamW>(&cfg, false, &x, cond, &y)?,
        setup::<AdamW>(&cfg, false, &x, cond, &y)?,
        setup::<AdamW>(&cfg, true, &x, cond, &y)?,
    ];
    let mut last = [0f32; 3];
    for _ in 0..cfg.warmup {
        for (k, s) in steps.iter_mut().enumerate() {
            last[k] = s()?;
        }
    }
    let mut spent = [0f64; 3];
    let t0 = Instant::now();
    let mut n = 0usize;
    loop {
        match budget {
            Budget::Steps(s) if n >= s.max(1) => break,
            Budget::Seconds(s) if n > 0 && t0.elapsed().as_secs_f64() >= 3.0 * s => break,
            _ => {}
        }
        for (k, s) in steps.iter_mut().enumerate() {
            let ts = Instant::now();
            last[k] = s()?;
            spent[k] += ts.elapsed().as_secs_f64();
        }
        n += 1;
    }
    let (fast, fast_c, slow) = (n as f64 / spent[0], n as f64 / spent[1], n as f64 / spent[2]);
    let (fl, sl) = (last[0], last[2]);
    Ok(TrainBench {
        fast_steps_per_s: fast,
        fast_candle_adamw_steps_per_s: fast_c,
        candle_nn_steps_per_s: slow,
        speedup: fast / slow,
        fast_final_loss: fl,
        candle_nn_final_loss: sl,
        config: cfg,
    })
}

/// Milliseconds for one block forward at `batch` (1 in the reference), three ways. The
/// generation path is timed on its own first, as the PyTorch reference times its block, and
/// the two candle paths round-robin after it: interleaved with them, the generation path ran
/// 0.74-1.12 ms a block against 0.43 alone, since candle's tensors evict the block's weights
/// from the caches between turns and candle's pool workers spin on the cores after their op.
pub fn bench_infer(cfg: TrainBenchConfig, batch: usize, budget: Budget) -> Result<InferBench> {
    let dev = Device::Cpu;
    let (t, f, c) = (cfg.steps_in, cfg.feat, cfg.classes);
    let vm = VarMap::new();
    let blk = Seq2SeqBlock::new(cfg.block_config(), VarBuilder::from_varmap(&vm, DType::F32, &dev))?;
    let x = Tensor::randn(0f32, 1.0, (batch, t, f), &dev)?;
    let cond_t = one_hot(batch, c, &dev)?;
    let cond = if c > 0 { Some(&cond_t) } else { None };
    let (fz, mut ws) = (blk.freeze()?, BlockWorkspace::default());
    let xv = x.flatten_all()?.to_vec1::<f32>()?;
    let cv = cond_t.flatten_all()?.to_vec1::<f32>()?;
    let cvo = if c > 0 { Some(cv.as_slice()) } else { None };
    let mut out = vec![0f32; batch * t * f];
    let [frozen] = timed_turns(&cfg, budget, [&mut || {
        fz.infer(&mut ws, &xv, cvo, batch, t, &mut out);
        Ok(())
    }])?;
    let [fast, slow] = timed_turns(&cfg, budget, [&mut || blk.forward(&x, cond, false).map(drop), &mut || blk.forward_with_reference_lstm(&x, cond, false).map(drop)])?;
    Ok(InferBench {
        fast_ms_per_block: fast,
        candle_nn_ms_per_block: slow,
        frozen_ms_per_block: frozen,
        batch,
        steps_in: t,
        config: cfg,
    })
}

/// Milliseconds per call of each of `calls`, taking turns of ten calls each (so a change in the
/// machine's load falls on all of them) after `cfg.warmup` untimed turns, until each has had
/// `budget`.
fn timed_turns<const N: usize>(cfg: &TrainBenchConfig, budget: Budget, mut calls: [&mut dyn FnMut() -> Result<()>; N]) -> Result<[f64; N]> {
    const TURN: usize = 10;
    let mut spent = [0f64; N];
    let (mut n, mut turn) = (0usize, 0usize);
    let t0 = Instant::now();
    loop {
        let timed = turn >= cfg.warmup.max(1);
        match budget {
            Budget::Steps(s) if timed && n >= s.max(1) => break,
            Budget::Seconds(s) if timed && n > 0 && t0.elapsed().as_secs_f64() >= N as f64 * s => break,
            _ => {}
        }
        for (call, spent) in calls.iter_mut().zip(&mut spent) {
            let ts = Instant::now();
            for _ in 0..TURN {
                call()?;
            }
            if timed {
                *spent += ts.elapsed().as_secs_f64();
            }
        }
        if timed {
            n += TURN;
        }
        turn += 1;
    }
    Ok(spent.map(|s| 1e3 * s / n as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_runs_small() {
        let cfg = TrainBenchConfig { batch: 4, steps_in: 5, feat: 6, classes: 3, hidden: 8, warmup: 1, ..Default::default() };
        let r = bench_train(cfg.clone(), Budget::Steps(2)).unwrap();
        assert!(r.fast_steps_per_s > 0.0 && r.candle_nn_steps_per_s > 0.0);
        let r = bench_infer(cfg, 1, Budget::Steps(2)).unwrap();
        assert!(r.frozen_ms_per_block > 0.0);
        serde_json::to_string(&r).unwrap();
    }

    /// `cargo test --release --lib model::bench -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn print_benchmarks() {
        let secs: f64 = std::env::var("GLOCAL_BENCH_SECS").ok().and_then(|s| s.parse().ok()).unwrap_or(5.0);
        let tr = bench_train(TrainBenchConfig::default(), Budget::Seconds(secs)).unwrap();
        println!("train: {}", serde_json::to_string_pretty(&tr).unwrap());
        let inf = bench_infer(TrainBenchConfig::default(), 1, Budget::Seconds(secs.min(3.0))).unwrap();
        println!("infer: {}", serde_json::to_string_pretty(&inf).unwrap());
    }
}
