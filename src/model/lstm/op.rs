//! The training path: [`BiLstmOp`], the whole bidirectional layer as one candle `CustomOp2` on
//! `x [B*T, I]` and the flat concatenation of the eight parameters ([`FlatLayout`]).
//!
//! Forward: per direction the input projection of the whole sequence (one gemm), then the
//! recurrence ([`DirFwd`]); the two hidden-state buffers are interleaved into `[B, T, 2H]`.
//! Backward: hand-written backprop through time from the gate activations and cells kept by the
//! forward pass: per step one gemm for `dh_{t-1}`, then one gemm each for `dW_hh` and `dW_ih`,
//! and `dx` (skipped when `x` is not in the autograd graph); the bias gradients are column sums.
//! Each direction owns its buffers (gates, gate gradients, its parts of the parameter gradient),
//! so the two run side by side on plain borrows. The working buffers come from the layer's
//! [`Buffers`] and go back to it when the op is dropped.
use super::kernels::{cell_bwd, matmul, transpose_into, Strided};
use super::recurrence::{interleave, time_at, DirFwd};
use super::{run2, Pool, Threading};
use candle_core::{bail, CpuStorage, CustomOp2, Device, Layout, Result, Shape, Storage, Tensor};
use gemm::Parallelism;
use std::sync::{Arc, Mutex};

/// Working buffers an LSTM layer's ops keep between calls. A training step needs the same
/// ~10 MB of gates, cells and gate gradients per layer every time; fresh zeroed buffers cost
/// their memset every step (6% of a step's samples in perf), reused ones are already in cache.
#[derive(Default)]
pub struct Buffers(Mutex<Vec<Vec<f32>>>);

impl Buffers {
    /// A buffer of `n` floats holding whatever an earlier use left in it: only for buffers that
    /// are written before they are read. The smallest free one that fits, so each keeps to its
    /// size and steady-state training neither allocates nor clears.
    fn take(&self, n: usize) -> Vec<f32> {
        let mut free = self.0.lock().unwrap();
        let fit = (0..free.len()).filter(|&k| free[k].capacity() >= n).min_by_key(|&k| free[k].capacity());
        let mut v = fit.map(|k| free.swap_remove(k)).unwrap_or_default();
        v.resize(n, 0.0);
        v
    }

    fn give(&self, v: Vec<f32>) {
        self.0.lock().unwrap().push(v);
    }
}

impl std::fmt::Debug for Buffers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let free = self.0.lock().map_or(0, |v| v.len());
        write!(f, "Buffers({free} free)")
    }
}

/// What the backward pass needs from the forward pass, per direction.
struct FwdCache {
    acts: [Vec<f32>; 2],
    cs: [Vec<f32>; 2],
}

/// Offsets of the parameters in the flat parameter vector of [`BiLstmOp`] (`d` = direction).
#[derive(Clone, Copy, Debug)]
pub struct FlatLayout {
    pub i: usize,
    pub h: usize,
}

impl FlatLayout {
    pub fn w_ih(&self, d: usize) -> usize {
        d * 4 * self.h * self.i
    }
    pub fn w_hh(&self, d: usize) -> usize {
        8 * self.h * self.i + d * 4 * self.h * self.h
    }
    pub fn b_ih(&self, d: usize) -> usize {
        8 * self.h * (self.i + self.h) + d * 4 * self.h
    }
    pub fn b_hh(&self, d: usize) -> usize {
        8 * self.h * (self.i + self.h) + 8 * self.h + d * 4 * self.h
    }
    pub fn len(&self) -> usize {
        8 * self.h * (self.i + self.h) + 16 * self.h
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Fused bidirectional LSTM layer as one candle op: `(x [B*T, I], params) -> H [B, T, 2H]`, where
/// `params` is the flat concatenation `[W_ih_f, W_ih_b, W_hh_f, W_hh_b, b_ih_f, b_ih_b, b_hh_f, b_hh_b]`
/// (row-major, candle-nn shapes; see [`FlatLayout`]). `threading` says whether the directions
/// run side by side or in turn.
pub struct BiLstmOp {
    b: usize,
    t: usize,
    i: usize,
    h: usize,
    threading: Threading,
    cache: Mutex<Option<FwdCache>>,
    buffers: Arc<Buffers>,
}

impl BiLstmOp {
    /// With buffers of its own; [`Self::reusing`] shares a layer's.
    pub fn new(b: usize, t: usize, i: usize, h: usize, threading: Threading) -> Self {
        Self { b, t, i, h, threading, cache: Mutex::new(None), buffers: Arc::default() }
    }

    /// Takes its working buffers from (and returns them to) `buffers`.
    pub(super) fn reusing(mut self, buffers: Arc<Buffers>) -> Self {
        self.buffers = buffers;
        self
    }
    fn layout(&self) -> FlatLayout {
        FlatLayout { i: self.i, h: self.h }
    }
    fn directions_side_by_side(&self) -> bool {
        self.threading == Threading::PerDirection
    }
}

/// The f32 values of a custom op's contiguous CPU operand; `op` names the op in the error.
pub(crate) fn contiguous_f32<'a>(s: &'a CpuStorage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let data = s.as_slice::<f32>()?;
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => bail!("{op}: input must be contiguous"),
    }
}

/// Run `f` on the contiguous f32 data of a CPU tensor (copying only if it is not contiguous).
pub(crate) fn with_f32<R>(t: &Tensor, f: impl FnOnce(&[f32]) -> R) -> Result<R> {
    if !t.is_contiguous() {
        let t = t.contiguous()?;
        return with_f32(&t, f);
    }
    let (st, l) = t.storage_and_layout();
    match &*st {
        Storage::Cpu(cpu) => Ok(f(contiguous_f32(cpu, l, "fused lstm")?)),
        _ => bail!("fused lstm: only CPU tensors are supported"),
    }
}

/// One direction's buffers of the forward pass, each `[B*T, ..]` except `whh_t` (`[H, 4H]`)
/// and `z` (`[B, 4H]`).
struct DirBuffers {
    g: Vec<f32>,
    whh_t: Vec<f32>,
    hs: Vec<f32>,
    acts: Vec<f32>,
    cs: Vec<f32>,
    z: Vec<f32>,
}

impl DirBuffers {
    /// Every one is written before it is read (the gemms overwrite, the recurrence writes every
    /// row), so they need no clearing.
    fn take(buffers: &Buffers, b: usize, t: usize, h: usize) -> Self {
        let bt = b * t;
        let take = |n: usize| buffers.take(n);
        Self { g: take(bt * 4 * h), whh_t: take(4 * h * h), hs: take(bt * h), acts: take(bt * 4 * h), cs: take(bt * h), z: take(b * 4 * h) }
    }
}

impl Drop for BiLstmOp {
    /// The forward cache back to the layer's buffers, once the graph holding the op is gone.
    fn drop(&mut self) {
        if let Ok(Some(FwdCache { acts, cs })) = self.cache.get_mut().map(Option::take) {
            acts.into_iter().chain(cs).for_each(|v| self.buffers.give(v));
        }
    }
}

impl CustomOp2 for BiLstmOp {
    fn name(&self) -> &'static str {
        "fused-bilstm"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let (b, t, i, h) = (self.b, self.t, self.i, self.h);
        let fl = self.layout();
        let x = contiguous_f32(s1, l1, "fused lstm")?;
        let p = contiguous_f32(s2, l2, "fused lstm")?;
        if x.len() != b * t * i || p.len() != fl.len() {
            bail!("fused lstm: bad input sizes {} {}", x.len(), p.len());
        }
        let zeros = vec![0f32; h];
        let par = self.threading.gemm_parallelism();
        let direction = |d: usize, buf: &mut DirBuffers| {
            let bias: Vec<f32> = (0..4 * h).map(|j| p[fl.b_ih(d) + j] + p[fl.b_hh(d) + j]).collect();
            // W_hh transposed once per call rather than repacked by gemm at every step; here, not
            // before the directions split, so that the two transposes run side by side
            transpose_into(&p[fl.w_hh(d)..fl.w_hh(d) + 4 * h * h], 4 * h, h, &mut buf.whh_t);
            // g [BT, 4H] = x [BT, I] · W_ih[d]ᵀ
            let w_ih = Strided::transpose_of(&p[fl.w_ih(d)..fl.w_ih(d + 1)], i);
            matmul((b * t, 4 * h, i), &mut buf.g, 4 * h, Strided::rows(x, i), w_ih, false, par);
            let DirBuffers { g, whh_t, hs, acts, cs, z } = buf;
            DirFwd { d, b, t, h, g, whh_t, bias: &bias, hs, acts, cs, z, zeros: &zeros, par }.run();
        };
        let [mut fwd, mut bwd] = [0, 1].map(|_| DirBuffers::take(&self.buffers, b, t, h));
        run2(self.directions_side_by_side(), Pool::Candle, || direction(0, &mut fwd), || direction(1, &mut bwd));
        let mut out = vec![0f32; b * t * 2 * h];
        interleave(&mut out, [&fwd.hs, &bwd.hs], h);
        for v in [fwd.g, fwd.whh_t, fwd.hs, fwd.z, bwd.g, bwd.whh_t, bwd.hs, bwd.z] {
            self.buffers.give(v);
        }
        *self.cache.lock().unwrap() = Some(FwdCache { acts: [fwd.acts, bwd.acts], cs: [fwd.cs, bwd.cs] });
        Ok((CpuStorage::F32(out), Shape::from((b, t, 2 * h))))
    }

    fn bwd(&self, x: &Tensor, p: &Tensor, res: &Tensor, grad_res: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let (b, t, i, h) = (self.b, self.t, self.i, self.h);
        let fl = self.layout();
        let (bt, h4) = (b * t, 4 * h);
        let need_dx = x.track_op();
        let guard = self.cache.lock().unwrap();
        let cache = match guard.as_ref() {
            Some(c) => c,
            None => bail!("fused lstm: backward without forward cache"),
        };
        // every row written by the cell backward before any read
        let mut dg = [0, 1].map(|_| self.buffers.take(bt * h4));
        let mut dp = vec![0f32; fl.len()];
        let mut dx = if need_dx { vec![0f32; bt * i] } else { Vec::new() };
        let par = self.threading.gemm_parallelism();
        let parallel = self.directions_side_by_side();
        with_f32(x, |xs| {
            with_f32(p, |ps| {
                with_f32(res, |hs| {
                    with_f32(grad_res, |dout| {
                        // each direction's own parts of the parameter gradient
                        let (dwih, rest) = dp.split_at_mut(8 * h * i);
                        let (dwhh, dbias) = rest.split_at_mut(8 * h * h);
                        let (dwih0, dwih1) = dwih.split_at_mut(4 * h * i);
                        let (dwhh0, dwhh1) = dwhh.split_at_mut(4 * h * h);
                        let (db0, db1) = dbias[..8 * h].split_at_mut(4 * h);
                        let direction = |d: usize, dg: &mut [f32], dwih: &mut [f32], dwhh: &mut [f32], db: &mut [f32]| {
                            let whh = &ps[fl.w_hh(d)..fl.w_hh(d) + 4 * h * h];
                            let (acts, cs) = (&cache.acts[d], &cache.cs[d]);
                            let hp = self.buffers.take(bt * h);
                            let hp = DirBwd { d, b, t, h, dout, hs, whh, acts, cs, dg: &mut *dg, dw: dwhh, db, hp, par }.run();
                            self.buffers.give(hp);
                            // dW_ih[d] [4H, I] = dG_dᵀ [4H, BT] · x [BT, I]
                            matmul((h4, i, bt), dwih, i, Strided::transpose_of(dg, h4), Strided::rows(xs, i), false, par);
                        };
                        let [dg0, dg1] = &mut dg;
                        run2(parallel, Pool::Candle, || direction(0, dg0, dwih0, dwhh0, db0), || direction(1, dg1, dwih1, dwhh1, db1));
                        // the bias gradients: b_hh gets the same as b_ih
                        let (bi, bh) = dbias.split_at_mut(8 * h);
                        bh.copy_from_slice(bi);
                        if need_dx {
                            input_gradient(&mut dx, &dg, ps, fl, parallel, par);
                        }
                    })
                })
            })
        })????;
        drop(guard);
        dg.into_iter().for_each(|v| self.buffers.give(v));
        let dev = Device::Cpu;
        let dx = if need_dx { Some(Tensor::from_vec(dx, x.shape(), &dev)?) } else { None };
        Ok((dx, Some(Tensor::from_vec(dp, fl.len(), &dev)?)))
    }
}

/// `dx [BT, I] = dG_f [BT, 4H] · W_ih_f [4H, I] + dG_b · W_ih_b`, the rows split over two
/// threads when `parallel`.
fn input_gradient(dx: &mut [f32], dg: &[Vec<f32>; 2], ps: &[f32], fl: FlatLayout, parallel: bool, par: Parallelism) {
    let (i, h4) = (fl.i, 4 * fl.h);
    let rows = |r0: usize, dst: &mut [f32]| {
        for d in 0..2 {
            let w_ih = Strided::rows(&ps[fl.w_ih(d)..fl.w_ih(d + 1)], i);
            matmul((dst.len() / i, i, h4), dst, i, Strided::rows(&dg[d][r0 * h4..], h4), w_ih, d == 1, par);
        }
    };
    let bt = dx.len() / i;
    let half = if parallel { bt / 2 } else { bt };
    let (first, second) = dx.split_at_mut(half * i);
    run2(parallel, Pool::Candle, || rows(0, first), || rows(half, second));
}

/// Backprop through time for one direction.
struct DirBwd<'a> {
    d: usize,
    b: usize,
    t: usize,
    h: usize,
    /// Gradient of the output `[B*T, 2H]`.
    dout: &'a [f32],
    /// Output of the forward pass `[B*T, 2H]` (hidden states).
    hs: &'a [f32],
    whh: &'a [f32],
    acts: &'a [f32],
    cs: &'a [f32],
    /// Gradient of this direction's projected gates `[B*T, 4H]`, written.
    dg: &'a mut [f32],
    /// Gradient of this direction's `W_hh [4H, H]` and bias `[4H]`, written.
    dw: &'a mut [f32],
    db: &'a mut [f32],
    /// Scratch `[B*T, H]` for the previous hidden states (any contents), handed back by `run`.
    hp: Vec<f32>,
    par: Parallelism,
}

impl DirBwd<'_> {
    fn run(self) -> Vec<f32> {
        let DirBwd { d, b, t, h, dout, hs, whh, acts, cs, dg, dw, db, mut hp, par } = self;
        let h4 = 4 * h;
        let mut dh_rec = vec![0f32; b * h];
        let mut dc = vec![0f32; b * h];
        let zeros = vec![0f32; h];
        for s in (0..t).rev() {
            let tt = time_at(d, t, s);
            for bb in 0..b {
                let row = bb * t + tt;
                let c_prev: &[f32] = if s == 0 {
                    &zeros
                } else {
                    let prow = bb * t + time_at(d, t, s - 1);
                    &cs[prow * h..prow * h + h]
                };
                cell_bwd(
                    h,
                    &dout[row * 2 * h + d * h..row * 2 * h + d * h + h],
                    &dh_rec[bb * h..(bb + 1) * h],
                    &mut dc[bb * h..(bb + 1) * h],
                    &acts[row * h4..(row + 1) * h4],
                    &cs[row * h..row * h + h],
                    c_prev,
                    &mut dg[row * h4..(row + 1) * h4],
                );
            }
            if s > 0 {
                // dh_rec[B,H] = dz_t[B,4H] · W_hh[4H,H]
                let dz_t = Strided::rows(&dg[tt * h4..], t * h4);
                matmul((b, h, h4), &mut dh_rec, h, dz_t, Strided::rows(whh, h), false, par);
            }
        }
        // h_prev for every (b, t) of this direction, zero at the first step.
        for bb in 0..b {
            hp[(bb * t + time_at(d, t, 0)) * h..][..h].fill(0.0);
            for s in 1..t {
                let row = bb * t + time_at(d, t, s);
                let prow = bb * t + time_at(d, t, s - 1);
                hp[row * h..row * h + h]
                    .copy_from_slice(&hs[prow * 2 * h + d * h..prow * 2 * h + d * h + h]);
            }
        }
        // dW_hh[4H,H] = dZᵀ[4H, B*T] · h_prev[B*T, H]
        matmul((h4, h, b * t), dw, h, Strided::transpose_of(dg, h4), Strided::rows(&hp, h), false, par);
        db.fill(0.0);
        for dz in dg.chunks_exact(h4) {
            for (a, &v) in db.iter_mut().zip(dz) {
                *a += v;
            }
        }
        hp
    }
}
