//! Fast LSTM layers for CPU training and inference.
//!
//! [`BiLstm`] is a bidirectional single-layer LSTM whose weights use candle-nn's (and PyTorch's)
//! names and layout: `weight_ih_l0 [4H, I]`, `weight_hh_l0 [4H, H]`, `bias_ih_l0 [4H]`,
//! `bias_hh_l0 [4H]` for the forward direction and the same names with the suffix `_reverse` for
//! the backward direction (candle-nn's `Direction::Backward`, PyTorch's `bidirectional=True`).
//! Gate order i, f, g, o. Its parts:
//!
//! * `kernels`: exp/sigmoid/tanh, the fused cell forward and backward, the small-batch
//!   recurrent product, and the bounds-checked gemm wrapper;
//! * `recurrence`: one direction's forward loop over time, shared by the next two;
//! * `op`: the training path ([`BiLstm::forward`]), one candle custom op ([`BiLstmOp`]) for
//!   the whole layer with hand-written backprop through time;
//! * `frozen`: the inference path synthesis uses ([`CpuBiLstm::infer`]), plain f32 buffers;
//! * `reference`: the same layer through candle-nn's `LSTM` ([`BiLstm::forward_reference`]),
//!   which the tests check both paths against and `glocal bench` times as the baseline;
//! * `tests`: those equivalence tests and the finite-difference gradient check.
//!
//! How the two directions share the cores is a [`Threading`] value the layer carries (and
//! hands to its op and its frozen copy), not process state.
use candle_core::{bail, DType, Result, Tensor};
use candle_nn::{Init, VarBuilder};
use gemm::Parallelism;
use std::sync::Arc;

mod frozen;
mod kernels;
mod op;
mod recurrence;
mod reference;
#[cfg(test)]
mod tests;

pub use frozen::{CpuBiLstm, Scratch};
pub(crate) use kernels::{dispatch_simd, matmul, Strided};
use op::Buffers;
pub use op::{BiLstmOp, FlatLayout};
pub(crate) use op::{contiguous_f32, with_f32};

/// How the two directions of a bidirectional LSTM use the cores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Threading {
    /// The two directions side by side, single-threaded gemm inside (training on candle's
    /// worker pool, inference on rayon's, see [`Pool`]). The default: side by side, a training
    /// step measured 1.15-1.37x faster than with a parallel gemm per call, which wakes the
    /// workers for every small gemm (docs/BENCHMARKS.md).
    #[default]
    PerDirection,
    /// Directions one after the other in training, gemm parallel over rayon (the frozen path
    /// still runs its directions side by side).
    RayonGemm,
    /// Everything on the calling thread.
    Single,
}

impl Threading {
    /// Every policy, for the tests that run each.
    #[cfg(test)]
    pub(crate) const ALL: [Threading; 3] = [Threading::PerDirection, Threading::RayonGemm, Threading::Single];

    fn gemm_parallelism(self) -> Parallelism {
        match self {
            Threading::RayonGemm => Parallelism::Rayon(0),
            _ => Parallelism::None,
        }
    }
}

/// Where [`run2`] puts its two halves when they run side by side.
#[derive(Clone, Copy)]
enum Pool {
    /// rayon's: the frozen path, which runs among rayon work (the bone projection) and no
    /// candle ops.
    Rayon,
    /// candle's own worker pool, the threads of candle's elementwise ops: the training op, which
    /// runs among candle ops. Those workers spin for a while (~0.25 ms) after every op, so halves
    /// handed to rayon's threads instead fight them for the cores: a training step measured
    /// 1.05-1.10x faster this way with the machine otherwise quiet (with both cores busy with other
    /// work, ~0.9x: candle's pool waits for a descheduled worker, rayon's does not).
    Candle,
}

/// `a` and `b` side by side on `pool` when `parallel`, else one after the other. On candle's
/// pool the calling thread takes whichever half no worker has taken.
fn run2<A: FnOnce() + Send, B: FnOnce() + Send>(parallel: bool, pool: Pool, a: A, b: B) {
    if !parallel {
        a();
        b();
        return;
    }
    // Without workers (CANDLE_NUM_THREADS=1, the setting for a busy machine) candle's pool would
    // run both halves on this thread: rayon's then.
    let candle = match pool {
        Pool::Candle => Some(candle_core::utils::barrier_pool()).filter(|p| p.n_workers() > 0),
        Pool::Rayon => None,
    };
    match candle {
        None => {
            rayon::join(a, b);
        }
        Some(candle) => {
            fn run_once<F: FnOnce()>(f: &std::sync::Mutex<Option<F>>) {
                if let Some(f) = f.lock().unwrap().take() {
                    f()
                }
            }
            let (a, b) = (std::sync::Mutex::new(Some(a)), std::sync::Mutex::new(Some(b)));
            candle.execute_chunked(2, |halves| {
                for half in halves {
                    if half == 0 {
                        run_once(&a)
                    } else {
                        run_once(&b)
                    }
                }
            });
        }
    }
}

/// One direction's parameters (candle tensors backed by `Var`s when built from a `VarMap`).
#[derive(Clone, Debug)]
pub struct LstmWeights {
    pub w_ih: Tensor,
    pub w_hh: Tensor,
    pub b_ih: Tensor,
    pub b_hh: Tensor,
}

#[derive(Clone, Debug)]
pub struct BiLstm {
    pub in_dim: usize,
    pub hidden: usize,
    pub fwd: LstmWeights,
    pub bwd: LstmWeights,
    /// Used by [`BiLstm::forward`] and passed on to [`BiLstm::freeze`]'s copy.
    pub threading: Threading,
    /// The training op's working memory, kept from one call to the next.
    buffers: Arc<Buffers>,
}

impl BiLstm {
    /// Weights under `vb`: `weight_ih_l0`, `weight_hh_l0`, `bias_ih_l0`, `bias_hh_l0` (forward) and
    /// the same with `_reverse` (backward). New variables are initialised like PyTorch:
    /// U(-1/sqrt(H), 1/sqrt(H)). Threading is the default, [`Threading::PerDirection`].
    pub fn new(in_dim: usize, hidden: usize, vb: VarBuilder) -> Result<Self> {
        let k = 1.0 / (hidden as f64).sqrt();
        let init = Init::Uniform { lo: -k, up: k };
        let get = |sfx: &str| -> Result<LstmWeights> {
            Ok(LstmWeights {
                w_ih: vb.get_with_hints((4 * hidden, in_dim), &format!("weight_ih_l0{sfx}"), init)?,
                w_hh: vb.get_with_hints((4 * hidden, hidden), &format!("weight_hh_l0{sfx}"), init)?,
                b_ih: vb.get_with_hints(4 * hidden, &format!("bias_ih_l0{sfx}"), init)?,
                b_hh: vb.get_with_hints(4 * hidden, &format!("bias_hh_l0{sfx}"), init)?,
            })
        };
        let fwd = get("")?;
        let bwd = get("_reverse")?;
        Ok(Self { in_dim, hidden, fwd, bwd, threading: Threading::default(), buffers: Arc::default() })
    }

    /// Fast training/inference forward with autograd: `[B, T, I] -> [B, T, 2H]`
    /// (forward states in `[.., :H]`, backward states in `[.., H:]`).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (b, t, i) = x.dims3()?;
        if i != self.in_dim {
            bail!("BiLstm: input dim {i}, expected {}", self.in_dim);
        }
        let x2 = x.reshape((b * t, i))?.contiguous()?;
        let p = Tensor::cat(
            &[
                &self.fwd.w_ih.flatten_all()?,
                &self.bwd.w_ih.flatten_all()?,
                &self.fwd.w_hh.flatten_all()?,
                &self.bwd.w_hh.flatten_all()?,
                &self.fwd.b_ih,
                &self.bwd.b_ih,
                &self.fwd.b_hh,
                &self.bwd.b_hh,
            ],
            0,
        )?;
        x2.apply_op2(&p, BiLstmOp::new(b, t, i, self.hidden, self.threading).reusing(self.buffers.clone()))
    }

    /// Copy the current weights out into plain f32 buffers for [`CpuBiLstm::infer`].
    pub fn freeze(&self) -> Result<CpuBiLstm> {
        let v = |t: &Tensor| -> Result<Vec<f32>> {
            t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()
        };
        let h = self.hidden;
        let mut w_ih = v(&self.fwd.w_ih)?;
        w_ih.extend(v(&self.bwd.w_ih)?);
        let w_ih_t = kernels::transposed_per_direction(&w_ih, 4 * h, self.in_dim);
        let mut w_hh = v(&self.fwd.w_hh)?;
        w_hh.extend(v(&self.bwd.w_hh)?);
        let mut bias = Vec::with_capacity(8 * h);
        for dir in [&self.fwd, &self.bwd] {
            let (bi, bh) = (v(&dir.b_ih)?, v(&dir.b_hh)?);
            bias.extend(bi.iter().zip(&bh).map(|(a, b)| a + b));
        }
        let w_hh_t = kernels::transposed_per_direction(&w_hh, 4 * h, h);
        Ok(CpuBiLstm { in_dim: self.in_dim, hidden: h, w_ih_t, w_hh_t, bias, threading: self.threading })
    }

    /// All eight parameter tensors (forward then backward: w_ih, w_hh, b_ih, b_hh).
    pub fn tensors(&self) -> [&Tensor; 8] {
        [
            &self.fwd.w_ih,
            &self.fwd.w_hh,
            &self.fwd.b_ih,
            &self.fwd.b_hh,
            &self.bwd.w_ih,
            &self.bwd.w_hh,
            &self.bwd.b_ih,
            &self.bwd.b_hh,
        ]
    }
}
