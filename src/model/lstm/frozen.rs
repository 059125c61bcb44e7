//! The frozen inference path synthesis uses: a [`super::BiLstm`]'s weights copied into plain f32
//! buffers, no candle tensors, no autograd, and reusable [`Scratch`] so a call allocates nothing
//! once the largest batch has been seen.
use super::kernels::{matmul, Strided};
use super::recurrence::{interleave, DirFwd};
use super::{run2, Pool, Threading};
use gemm::Parallelism;

/// Frozen weights of a [`super::BiLstm`] for autograd-free inference.
#[derive(Clone, Debug)]
pub struct CpuBiLstm {
    pub in_dim: usize,
    pub hidden: usize,
    /// Per direction `W_ihᵀ [I, 4H]` (the layout gemm takes without repacking).
    pub w_ih_t: Vec<f32>,
    /// Per direction `W_hhᵀ [H, 4H]` (likewise).
    pub w_hh_t: Vec<f32>,
    /// `b_ih + b_hh`, `[8H]`.
    pub bias: Vec<f32>,
    /// Whether the two directions run side by side (anything but [`Threading::Single`]); the
    /// gemms inside are single-threaded either way.
    pub threading: Threading,
}

/// One direction's reusable buffers: gates `[B*T, 4H]`, hidden states `[B*T, H]`, activations
/// `[B*T, 4H]`, cells `[B*T, H]`, recurrent products `[B, 4H]`.
#[derive(Default, Debug, Clone)]
struct DirScratch {
    g: Vec<f32>,
    hs: Vec<f32>,
    acts: Vec<f32>,
    cs: Vec<f32>,
    z: Vec<f32>,
}

/// Reusable buffers for [`CpuBiLstm::infer`]; grows on demand, never shrinks.
#[derive(Default, Debug, Clone)]
pub struct Scratch {
    dirs: [DirScratch; 2],
    zeros: Vec<f32>,
}

fn grow(v: &mut Vec<f32>, n: usize) {
    if v.len() < n {
        v.resize(n, 0.0);
    }
}

impl CpuBiLstm {
    /// `x [B*T, I]` (row-major, batch-major) -> `out [B*T, 2H]`.
    pub fn infer(&self, x: &[f32], b: usize, t: usize, out: &mut [f32], sc: &mut Scratch) {
        let h = self.hidden;
        assert_eq!(x.len(), b * t * self.in_dim, "CpuBiLstm::infer: x has the wrong size");
        assert_eq!(out.len(), b * t * 2 * h, "CpuBiLstm::infer: out has the wrong size");
        grow(&mut sc.zeros, h);
        for dir in &mut sc.dirs {
            grow(&mut dir.g, b * t * 4 * h);
            grow(&mut dir.hs, b * t * h);
            grow(&mut dir.acts, b * t * 4 * h);
            grow(&mut dir.cs, b * t * h);
            grow(&mut dir.z, b * 4 * h);
        }
        // The two directions run side by side on rayon's pool, each with a single-threaded
        // gemm: at batch 1 the recurrence is bound by streaming each direction's weights, and
        // at LocGen's batch 150 this measured a little faster than directions in turn with a
        // parallel gemm. (Unlike a spawned thread, `rayon::join` costs microseconds.)
        let parallel = self.threading != Threading::Single;
        let Scratch { dirs: [fwd, bwd], zeros } = sc;
        let zeros: &[f32] = zeros;
        run2(parallel, Pool::Rayon, || self.infer_dir(0, x, b, t, fwd, zeros), || self.infer_dir(1, x, b, t, bwd, zeros));
        interleave(out, [&fwd.hs[..b * t * h], &bwd.hs[..b * t * h]], h);
    }

    fn infer_dir(&self, d: usize, x: &[f32], b: usize, t: usize, sc: &mut DirScratch, zeros: &[f32]) {
        let (h, i) = (self.hidden, self.in_dim);
        let h4 = 4 * h;
        // this direction's gate projection: g = x · W_ih[d]ᵀ
        let w_ih_t = Strided::rows(&self.w_ih_t[d * i * h4..(d + 1) * i * h4], h4);
        matmul((b * t, h4, i), &mut sc.g, h4, Strided::rows(x, i), w_ih_t, false, Parallelism::None);
        let DirScratch { g, hs, acts, cs, z } = sc;
        DirFwd {
            d,
            b,
            t,
            h,
            g,
            whh_t: &self.w_hh_t[d * h4 * h..(d + 1) * h4 * h],
            bias: &self.bias[d * h4..(d + 1) * h4],
            hs,
            acts,
            cs,
            z,
            zeros,
            par: Parallelism::None,
        }
        .run();
    }
}
