//! AdamW (decoupled weight decay, the same update as PyTorch's and candle-nn's) computed in
//! one pass per parameter on f32 buffers, split over two threads, instead of a dozen candle
//! ops per parameter. Its moments are named, so a checkpoint can hold them and a resumed run
//! continues exactly where it stopped.

use std::cell::RefCell;
use std::collections::HashMap;

use candle_core::{backprop::GradStore, bail, CpuStorage, DType, InplaceOp2, Layout, Result, Tensor, Var};
use candle_nn::{Optimizer, ParamsAdamW};

use super::lstm::dispatch_simd;

struct Param {
    name: String,
    var: Var,
    m: Vec<f32>,
    v: Vec<f32>,
}

pub struct AdamW {
    params: Vec<Param>,
    config: ParamsAdamW,
    pub step: usize,
}

pub(super) struct Coefficients {
    lr: f32,
    decay: f32,
    b1: f32,
    b2: f32,
    bias1: f32,
    bias2: f32,
    eps: f32,
}

impl AdamW {
    /// Variables by name (order-independent: they are sorted by size, then name).
    pub fn named(vars: Vec<(String, Var)>, config: ParamsAdamW) -> Result<Self> {
        let mut params = Vec::with_capacity(vars.len());
        for (name, var) in vars {
            if var.dtype() != DType::F32 || !var.device().is_cpu() {
                bail!("AdamW: only f32 CPU variables are supported ({name})");
            }
            let n = var.elem_count();
            params.push(Param { name, var, m: vec![0.0; n], v: vec![0.0; n] });
        }
        // Largest first, for a balanced split over two threads; names break ties.
        params.sort_by(|a, b| b.var.elem_count().cmp(&a.var.elem_count()).then_with(|| a.name.cmp(&b.name)));
        Ok(Self { params, config, step: 0 })
    }

    /// The moments as named tensors, for a checkpoint.
    pub fn state_tensors(&self) -> Result<Vec<(String, Tensor)>> {
        let mut out = Vec::new();
        for p in &self.params {
            out.push((format!("m.{}", p.name), Tensor::from_slice(&p.m, p.var.shape(), p.var.device())?));
            out.push((format!("v.{}", p.name), Tensor::from_slice(&p.v, p.var.shape(), p.var.device())?));
        }
        Ok(out)
    }

    /// Restores moments saved by [`Self::state_tensors`].
    pub fn load_state(&mut self, tensors: &HashMap<String, Tensor>, step: usize) -> Result<()> {
        self.step = step;
        for p in &mut self.params {
            match (tensors.get(&format!("m.{}", p.name)), tensors.get(&format!("v.{}", p.name))) {
                (Some(m), Some(v)) => {
                    p.m = m.flatten_all()?.to_vec1()?;
                    p.v = v.flatten_all()?.to_vec1()?;
                }
                _ => bail!("training state has no moments for {}", p.name),
            }
        }
        Ok(())
    }

    fn update(c: &Coefficients, p: &mut Param, grads: &GradStore) -> Result<()> {
        let Some(g) = grads.get(p.var.as_tensor()) else { return Ok(()) };
        let g = g.contiguous()?;
        let step = Update { c, moments: RefCell::new((&mut p.m, &mut p.v)) };
        p.var.as_tensor().inplace_op2(&g, &step)
    }
}

/// One parameter's update as an in-place candle op: written straight into the variable's
/// storage, not collected into a new buffer that `Var::set` then copies (a step's 1.5 M
/// parameters, 6 MB, allocated and copied every step).
struct Update<'a> {
    c: &'a Coefficients,
    moments: RefCell<(&'a mut Vec<f32>, &'a mut Vec<f32>)>,
}

impl InplaceOp2 for Update<'_> {
    fn name(&self) -> &'static str {
        "adamw-update"
    }

    fn cpu_fwd(&self, s1: &mut CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<()> {
        let (CpuStorage::F32(theta), Some((a, b)), Some((ga, gb))) = (s1, l1.contiguous_offsets(), l2.contiguous_offsets()) else {
            bail!("AdamW: f32 contiguous parameters only");
        };
        let g = &s2.as_slice::<f32>()?[ga..gb];
        let mut moments = self.moments.borrow_mut();
        let (m, v) = &mut *moments;
        adamw_kernel(self.c, &mut theta[a..b], g, m, v);
        Ok(())
    }
}

#[inline(always)]
fn adamw_kernel_impl(c: &Coefficients, theta: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32]) {
    // zipped, not indexed, so the loop vectorises (no bounds checks)
    for ((theta, &g), (m, v)) in theta.iter_mut().zip(g).zip(m.iter_mut().zip(v.iter_mut())) {
        *m = *m * c.b1 + g * (1.0 - c.b1);
        *v = *v * c.b2 + g * g * (1.0 - c.b2);
        *theta = *theta * c.decay - c.lr * (*m * c.bias1) / ((*v * c.bias2).sqrt() + c.eps);
    }
}

// The same arithmetic in every build (no fused multiply-adds are formed), so the update is
// bit-identical with or without AVX-512.
dispatch_simd!(adamw_kernel, adamw_kernel_impl, (c: &Coefficients, theta: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32]));

impl Optimizer for AdamW {
    type Config = ParamsAdamW;

    fn new(vars: Vec<Var>, config: ParamsAdamW) -> Result<Self> {
        Self::named(vars.into_iter().enumerate().map(|(i, v)| (format!("p{i:04}"), v)).collect(), config)
    }

    fn step(&mut self, grads: &GradStore) -> Result<()> {
        self.step += 1;
        let p = &self.config;
        let t = self.step as i32;
        let c = Coefficients {
            lr: p.lr as f32,
            decay: (1.0 - p.lr * p.weight_decay) as f32,
            b1: p.beta1 as f32,
            b2: p.beta2 as f32,
            bias1: (1.0 / (1.0 - p.beta1.powi(t))) as f32,
            bias2: (1.0 / (1.0 - p.beta2.powi(t))) as f32,
            eps: p.eps as f32,
        };
        // Greedy split into two groups of similar size, one per core.
        let (mut a, mut b): (Vec<&mut Param>, Vec<&mut Param>) = (Vec::new(), Vec::new());
        let (mut na, mut nb) = (0usize, 0usize);
        for param in self.params.iter_mut() {
            let n = param.var.elem_count();
            if na <= nb {
                na += n;
                a.push(param);
            } else {
                nb += n;
                b.push(param);
            }
        }
        let run = |group: Vec<&mut Param>| -> Result<()> { group.into_iter().try_for_each(|p| Self::update(&c, p, grads)) };
        std::thread::scope(|s| {
            let hb = s.spawn(|| run(b));
            let ra = run(a);
            let rb = hb.join().expect("AdamW thread panicked");
            ra.and(rb)
        })
    }

    fn learning_rate(&self) -> f64 {
        self.config.lr
    }

    fn set_learning_rate(&mut self, lr: f64) {
        self.config.lr = lr
    }
}
