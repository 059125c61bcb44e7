//! The GlocalNet seq2seq block (paper section 3, GloGen / LocGen): an encoder Bi-LSTM over the
//! input poses (each concatenated with the optional conditioning vector, e.g. a one-hot class),
//! ALL encoder outputs fed to a decoder Bi-LSTM, dropout between layers in training, and a linear
//! head `2H -> out_dim` producing one pose per step.
//!
//! Weight names under the block's `VarBuilder`: `enc.*` and `dec.*` (see [`super::lstm::BiLstm`]:
//! `weight_ih_l0`, `weight_hh_l0`, `bias_ih_l0`, `bias_hh_l0` and the same with `_reverse`), and
//! `head.weight [out_dim, 2H]`, `head.bias [out_dim]`.
use super::lstm::{contiguous_f32, dispatch_simd, matmul, with_f32, BiLstm, CpuBiLstm, Scratch, Strided};
use candle_core::{bail, CpuStorage, CustomOp1, CustomOp3, DType, Device, Layout, Result, Shape, Tensor};
use candle_nn::VarBuilder;
use serde::{Deserialize, Serialize};
use std::sync::Mutex;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BlockConfig {
    /// Per-step input features (a pose).
    pub in_dim: usize,
    /// Conditioning vector length (0 = none), concatenated to every encoder input step.
    pub cond_dim: usize,
    /// Also concatenate the conditioning vector to every decoder input step.
    pub cond_in_decoder: bool,
    /// Hidden size per direction.
    pub hidden: usize,
    /// Per-step output features.
    pub out_dim: usize,
    /// Dropout after the encoder and after the decoder, in training only.
    pub dropout: f32,
}

impl Default for BlockConfig {
    fn default() -> Self {
        Self { in_dim: 80, cond_dim: 12, cond_in_decoder: false, hidden: 200, out_dim: 80, dropout: 0.25 }
    }
}

impl BlockConfig {
    pub fn enc_in(&self) -> usize {
        self.in_dim + self.cond_dim
    }
    pub fn dec_in(&self) -> usize {
        2 * self.hidden + if self.cond_in_decoder { self.cond_dim } else { 0 }
    }
}

#[derive(Clone, Debug)]
pub struct Seq2SeqBlock {
    pub cfg: BlockConfig,
    pub enc: BiLstm,
    pub dec: BiLstm,
    pub head_w: Tensor,
    pub head_b: Tensor,
}

impl Seq2SeqBlock {
    pub fn new(cfg: BlockConfig, vb: VarBuilder) -> Result<Self> {
        let enc = BiLstm::new(cfg.enc_in(), cfg.hidden, vb.pp("enc"))?;
        let dec = BiLstm::new(cfg.dec_in(), cfg.hidden, vb.pp("dec"))?;
        let head = candle_nn::linear(2 * cfg.hidden, cfg.out_dim, vb.pp("head"))?;
        let head_w = head.weight().clone();
        let head_b = match head.bias() {
            Some(b) => b.clone(),
            None => bail!("Seq2SeqBlock: head without bias"),
        };
        Ok(Self { cfg, enc, dec, head_w, head_b })
    }

    /// `cond [B, C]` -> `[B, T, C]` (contiguous), or None when the block has no conditioning.
    fn cond_steps(&self, cond: Option<&Tensor>, b: usize, t: usize) -> Result<Option<Tensor>> {
        match (self.cfg.cond_dim, cond) {
            (0, None) => Ok(None),
            (0, Some(_)) => bail!("Seq2SeqBlock: conditioning given but cond_dim = 0"),
            (_, None) => bail!("Seq2SeqBlock: conditioning vector required (cond_dim = {})", self.cfg.cond_dim),
            (c, Some(v)) => {
                let (vb_, vc) = v.dims2()?;
                if vb_ != b || vc != c {
                    bail!("Seq2SeqBlock: cond is [{vb_}, {vc}], expected [{b}, {c}]");
                }
                Ok(Some(v.unsqueeze(1)?.broadcast_as((b, t, c))?.contiguous()?))
            }
        }
    }

    fn run(&self, x: &Tensor, cond: Option<&Tensor>, train: bool, reference: bool) -> Result<(Tensor, Tensor)> {
        let (b, t, i) = x.dims3()?;
        if i != self.cfg.in_dim {
            bail!("Seq2SeqBlock: input dim {i}, expected {}", self.cfg.in_dim);
        }
        let cs = self.cond_steps(cond, b, t)?;
        let enc_in = match &cs {
            Some(c) => Tensor::cat(&[x, c], 2)?,
            None => x.clone(),
        };
        let lstm = |l: &BiLstm, v: &Tensor| if reference { l.forward_reference(v) } else { l.forward(v) };
        let e = lstm(&self.enc, &enc_in)?;
        let e_d = if train && self.cfg.dropout > 0.0 { dropout(&e, self.cfg.dropout)? } else { e.clone() };
        let dec_in = match (&cs, self.cfg.cond_in_decoder) {
            (Some(c), true) => Tensor::cat(&[&e_d, c], 2)?,
            _ => e_d,
        };
        let d = lstm(&self.dec, &dec_in)?;
        let d = if train && self.cfg.dropout > 0.0 { dropout(&d, self.cfg.dropout)? } else { d };
        let y = d.contiguous()?.apply_op3(&self.head_w, &self.head_b, HeadOp)?;
        Ok((y, e))
    }

    /// `x [B, T, in_dim]`, `cond [B, cond_dim]` -> `[B, T, out_dim]`, with the fast LSTM.
    pub fn forward(&self, x: &Tensor, cond: Option<&Tensor>, train: bool) -> Result<Tensor> {
        Ok(self.run(x, cond, train, false)?.0)
    }

    /// The same block through candle-nn's LSTMs (benchmark and equality tests).
    pub fn forward_with_reference_lstm(&self, x: &Tensor, cond: Option<&Tensor>, train: bool) -> Result<Tensor> {
        Ok(self.run(x, cond, train, true)?.0)
    }

    /// The encoder outputs `[B, T, 2H]` (concatenated forward/backward states; no dropout).
    pub fn encode(&self, x: &Tensor, cond: Option<&Tensor>) -> Result<Tensor> {
        let (b, t, _) = x.dims3()?;
        let cs = self.cond_steps(cond, b, t)?;
        let enc_in = match &cs {
            Some(c) => Tensor::cat(&[x, c], 2)?,
            None => x.clone(),
        };
        self.enc.forward(&enc_in)
    }

    /// Snapshot the current weights for allocation-free f32 inference.
    pub fn freeze(&self) -> Result<FrozenBlock> {
        let v = |t: &Tensor| -> Result<Vec<f32>> { t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>() };
        Ok(FrozenBlock {
            cfg: self.cfg.clone(),
            enc: self.enc.freeze()?,
            dec: self.dec.freeze()?,
            head_w: v(&self.head_w)?,
            head_b: v(&self.head_b)?,
        })
    }
}

// ---------------------------------------------------------------------------------------------
// The linear head

/// `out [rows, O] = d [rows, K] · wᵀ + b` for a PyTorch-layout `w [O, K]` and `b [O]`.
fn linear(d: &[f32], w: &[f32], b: &[f32], out: &mut [f32]) {
    let (o, k) = (b.len(), w.len() / b.len());
    for row in out.chunks_exact_mut(o) {
        row.copy_from_slice(b);
    }
    matmul((out.len() / o, o, k), out, o, Strided::rows(d, k), Strided::transpose_of(w, k), true, gemm::Parallelism::None);
}

/// The head `(d [B, T, K], w [O, K], b [O]) -> [B, T, O]` as one candle op: one gemm forward,
/// two and a column sum backward. As candle ops (reshape, transpose, matmul, broadcast add) its
/// backward copied `d`'s gradient once more through candle's gradient sums and transposed
/// operands for the matmuls.
struct HeadOp;

impl CustomOp3 for HeadOp {
    fn name(&self) -> &'static str {
        "linear-head"
    }

    fn cpu_fwd(&self, sd: &CpuStorage, ld: &Layout, sw: &CpuStorage, lw: &Layout, sb: &CpuStorage, lb: &Layout) -> Result<(CpuStorage, Shape)> {
        let operand = |s, l| contiguous_f32(s, l, "linear head");
        let (d, w, b) = (operand(sd, ld)?, operand(sw, lw)?, operand(sb, lb)?);
        let (o, k) = (b.len(), lw.dims()[1]);
        let dims = ld.dims();
        if lw.dims() != [o, k] || dims.last() != Some(&k) {
            bail!("linear head: d {dims:?}, w {:?}, b [{o}]", lw.dims());
        }
        let mut out = vec![0f32; d.len() / k * o];
        linear(d, w, b, &mut out);
        let mut shape = dims.to_vec();
        *shape.last_mut().unwrap() = o;
        Ok((CpuStorage::F32(out), Shape::from(shape)))
    }

    fn bwd(&self, d: &Tensor, w: &Tensor, _b: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let (o, k) = w.dims2()?;
        let rows = d.elem_count() / k;
        let (mut dd, mut dw, mut db) = (vec![0f32; rows * k], vec![0f32; o * k], vec![0f32; o]);
        let par = gemm::Parallelism::None;
        with_f32(grad, |g| {
            with_f32(w, |wv| {
                // d_d [rows, K] = grad [rows, O] · w [O, K]
                matmul((rows, k, o), &mut dd, k, Strided::rows(g, o), Strided::rows(wv, k), false, par);
            })?;
            with_f32(d, |dv| {
                // d_w [O, K] = gradᵀ [O, rows] · d [rows, K]
                matmul((o, k, rows), &mut dw, k, Strided::transpose_of(g, o), Strided::rows(dv, k), false, par);
            })?;
            for row in g.chunks_exact(o) {
                for (a, &v) in db.iter_mut().zip(row) {
                    *a += v;
                }
            }
            Ok::<(), candle_core::Error>(())
        })??;
        let dev = Device::Cpu;
        Ok((Some(Tensor::from_vec(dd, d.shape(), &dev)?), Some(Tensor::from_vec(dw, (o, k), &dev)?), Some(Tensor::from_vec(db, o, &dev)?)))
    }
}

// ---------------------------------------------------------------------------------------------
// Fused dropout

/// Inverted dropout as one candle op (one pass forward, one backward) instead of candle-nn's five;
/// the keep mask (already scaled by `1/(1-p)`) is kept for the backward pass.
struct DropoutOp {
    p: f32,
    seed: u64,
    mask: Mutex<Option<Vec<f32>>>,
}

/// The `n`-th draw (from 0) of SplitMix64 seeded with `seed`. Its state only adds a constant per
/// draw, so any draw is computed directly: the mask's draws are independent of one another and
/// its loop vectorises (a sequential generator made dropout 3.5% of a training step).
#[inline(always)]
fn splitmix64_at(seed: u64, n: u64) -> u64 {
    let mut z = seed.wrapping_add(n.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The keep mask (`scale` or 0) of every element, each kept if its uniform 24-bit draw is at
/// least `thr`, and `out = x * mask`.
#[inline(always)]
fn dropout_kernel_impl(seed: u64, thr: u32, scale: f32, x: &[f32], mask: &mut [f32], out: &mut [f32]) {
    // element e takes half e % 2 of draw e / 2
    for (e, (m, (o, &v))) in mask.iter_mut().zip(out.iter_mut().zip(x)).enumerate() {
        let r = splitmix64_at(seed, (e / 2) as u64);
        let u = ((r >> (32 * (e % 2))) as u32) >> 8;
        *m = if u >= thr { scale } else { 0.0 };
        *o = v * *m;
    }
}

dispatch_simd!(dropout_kernel, dropout_kernel_impl, (seed: u64, thr: u32, scale: f32, x: &[f32], mask: &mut [f32], out: &mut [f32]));

impl CustomOp1 for DropoutOp {
    fn name(&self) -> &'static str {
        "fused-dropout"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let x = contiguous_f32(s, l, "dropout")?;
        let scale = 1.0 / (1.0 - self.p);
        // keep if a uniform 24-bit draw >= p
        let thr = (self.p as f64 * (1u64 << 24) as f64) as u32;
        let (mut mask, mut out) = (vec![0f32; x.len()], vec![0f32; x.len()]);
        dropout_kernel(self.seed, thr, scale, x, &mut mask, &mut out);
        *self.mask.lock().unwrap() = Some(mask);
        Ok((CpuStorage::F32(out), l.shape().clone()))
    }

    fn bwd(&self, _arg: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        let guard = self.mask.lock().unwrap();
        let mask = match guard.as_ref() {
            Some(m) => m,
            None => bail!("dropout: backward without forward"),
        };
        let g = with_f32(grad, |g| g.iter().zip(mask).map(|(a, m)| a * m).collect::<Vec<f32>>())?;
        Ok(Some(Tensor::from_vec(g, grad.shape(), &Device::Cpu)?))
    }
}

thread_local! {
    static DROPOUT_RNG: std::cell::RefCell<Option<rand::rngs::StdRng>> = const { std::cell::RefCell::new(None) };
}

/// Makes this thread's dropout masks a function of `seed` (training calls it every step so
/// that a run, and a resumed run, is deterministic). Unseeded threads draw fresh masks.
pub fn seed_dropout(seed: u64) {
    use rand::SeedableRng;
    DROPOUT_RNG.with(|r| *r.borrow_mut() = Some(rand::rngs::StdRng::seed_from_u64(seed)));
}

fn next_dropout_seed() -> u64 {
    use rand::Rng;
    DROPOUT_RNG.with(|r| r.borrow_mut().as_mut().map_or_else(rand::random::<u64>, |rng| rng.random()))
}

/// Training-time inverted dropout of an f32 CPU tensor (one fused op; falls back to candle-nn's
/// dropout for other devices or dtypes).
pub fn dropout(x: &Tensor, p: f32) -> Result<Tensor> {
    if !(0.0..1.0).contains(&p) {
        bail!("dropout probability has to be in [0, 1), got {p}");
    }
    if p == 0.0 {
        return Ok(x.clone());
    }
    if !x.device().is_cpu() || x.dtype() != DType::F32 {
        return candle_nn::ops::dropout(x, p);
    }
    let x = x.contiguous()?;
    x.apply_op1(DropoutOp { p, seed: next_dropout_seed(), mask: Mutex::new(None) })
}

/// A [`Seq2SeqBlock`] frozen into plain f32 buffers: no autograd, no candle tensors. Its
/// weights are only read, so one frozen block serves any number of callers; each call brings
/// its own [`BlockWorkspace`].
#[derive(Clone, Debug)]
pub struct FrozenBlock {
    pub cfg: BlockConfig,
    pub enc: CpuBiLstm,
    pub dec: CpuBiLstm,
    /// `[out_dim, 2H]`.
    pub head_w: Vec<f32>,
    pub head_b: Vec<f32>,
}

/// What one caller of a [`FrozenBlock`] writes while it runs: the LSTMs' scratch and the
/// block's intermediate rows. It grows to the largest batch seen and is then reused, so a
/// rollout allocates nothing per block.
#[derive(Clone, Debug, Default)]
pub struct BlockWorkspace {
    scratch: Scratch,
    x_in: Vec<f32>,
    e: Vec<f32>,
    d_in: Vec<f32>,
    d: Vec<f32>,
}

impl BlockWorkspace {
    /// The encoder outputs `[B*T*2H]` of the last [`FrozenBlock::infer`] or
    /// [`FrozenBlock::encode_infer`] run in this workspace, for a block of `hidden` units.
    pub fn last_encoding(&self, b: usize, t: usize, hidden: usize) -> &[f32] {
        &self.e[..b * t * 2 * hidden]
    }
}

fn grow(v: &mut Vec<f32>, n: usize) {
    if v.len() < n {
        v.resize(n, 0.0);
    }
}

/// Copy rows of `a [rows, na]` and the per-batch vector `c [B, nc]` into `dst [rows, na + nc]`.
fn concat_rows(a: &[f32], na: usize, c: &[f32], nc: usize, b: usize, t: usize, dst: &mut [f32]) {
    let w = na + nc;
    for bb in 0..b {
        for tt in 0..t {
            let r = bb * t + tt;
            dst[r * w..r * w + na].copy_from_slice(&a[r * na..r * na + na]);
            dst[r * w + na..r * w + w].copy_from_slice(&c[bb * nc..bb * nc + nc]);
        }
    }
}

impl FrozenBlock {
    fn check(&self, x: &[f32], cond: Option<&[f32]>, b: usize, t: usize) {
        assert_eq!(x.len(), b * t * self.cfg.in_dim, "FrozenBlock: x has the wrong size");
        match (self.cfg.cond_dim, cond) {
            (0, None) => {}
            (0, Some(_)) => panic!("FrozenBlock: conditioning given but cond_dim = 0"),
            (_, None) => panic!("FrozenBlock: conditioning vector required"),
            (c, Some(v)) => assert_eq!(v.len(), b * c, "FrozenBlock: cond has the wrong size"),
        }
    }

    /// Runs the encoder into `ws.e` (`[B*T, 2H]`).
    fn run_encoder(&self, ws: &mut BlockWorkspace, x: &[f32], cond: Option<&[f32]>, b: usize, t: usize) {
        self.check(x, cond, b, t);
        let h2 = 2 * self.cfg.hidden;
        grow(&mut ws.e, b * t * h2);
        let e = &mut ws.e[..b * t * h2];
        match cond {
            Some(c) => {
                let w = self.cfg.enc_in();
                grow(&mut ws.x_in, b * t * w);
                let xin = &mut ws.x_in[..b * t * w];
                concat_rows(x, self.cfg.in_dim, c, self.cfg.cond_dim, b, t, xin);
                self.enc.infer(xin, b, t, e, &mut ws.scratch);
            }
            None => self.enc.infer(x, b, t, e, &mut ws.scratch),
        }
    }

    /// `x [B*T*in_dim]` (batch-major), `cond [B*cond_dim]` -> `out [B*T*out_dim]`.
    pub fn infer(&self, ws: &mut BlockWorkspace, x: &[f32], cond: Option<&[f32]>, b: usize, t: usize, out: &mut [f32]) {
        let (h2, o) = (2 * self.cfg.hidden, self.cfg.out_dim);
        assert_eq!(out.len(), b * t * o, "FrozenBlock: out has the wrong size");
        self.run_encoder(ws, x, cond, b, t);
        grow(&mut ws.d, b * t * h2);
        let BlockWorkspace { scratch, e, d_in, d, .. } = ws;
        let d = &mut d[..b * t * h2];
        match (cond, self.cfg.cond_in_decoder) {
            (Some(c), true) => {
                let w = self.cfg.dec_in();
                grow(d_in, b * t * w);
                let din = &mut d_in[..b * t * w];
                concat_rows(&e[..b * t * h2], h2, c, self.cfg.cond_dim, b, t, din);
                self.dec.infer(din, b, t, d, scratch);
            }
            _ => self.dec.infer(&e[..b * t * h2], b, t, d, scratch),
        }
        linear(d, &self.head_w, &self.head_b, out);
    }

    /// The encoder outputs `[B*T*2H]` (for embeddings).
    pub fn encode_infer(&self, ws: &mut BlockWorkspace, x: &[f32], cond: Option<&[f32]>, b: usize, t: usize, out: &mut [f32]) {
        let h2 = 2 * self.cfg.hidden;
        assert_eq!(out.len(), b * t * h2, "FrozenBlock: out has the wrong size");
        self.run_encoder(ws, x, cond, b, t);
        out.copy_from_slice(&ws.e[..b * t * h2]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::loss::motion_loss;
    use candle_core::Var;
    use candle_nn::{AdamW, Optimizer, ParamsAdamW, VarMap};

    fn max_abs(a: &Tensor, b: &Tensor) -> f32 {
        (a - b).unwrap().abs().unwrap().flatten_all().unwrap().max(0).unwrap().to_scalar::<f32>().unwrap()
    }

    fn cfg(cond_in_decoder: bool, cond_dim: usize) -> BlockConfig {
        BlockConfig { in_dim: 11, cond_dim, cond_in_decoder, hidden: 24, out_dim: 7, dropout: 0.25 }
    }

    fn one_hot(b: usize, c: usize) -> Tensor {
        let mut v = vec![0f32; b * c];
        for i in 0..b {
            v[i * c + (i * 7 + 3) % c] = 1.0;
        }
        Tensor::from_vec(v, (b, c), &Device::Cpu).unwrap()
    }

    #[test]
    fn block_fast_matches_candle_nn() {
        for (cid, cd) in [(false, 5usize), (true, 5), (false, 0)] {
            let vm = VarMap::new();
            let blk = Seq2SeqBlock::new(cfg(cid, cd), VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu)).unwrap();
            let (b, t) = (5, 10);
            let x = Tensor::randn(0f32, 1.0, (b, t, 11), &Device::Cpu).unwrap();
            let c = if cd > 0 { Some(one_hot(b, cd)) } else { None };
            let fast = blk.forward(&x, c.as_ref(), false).unwrap();
            let slow = blk.forward_with_reference_lstm(&x, c.as_ref(), false).unwrap();
            assert_eq!(fast.dims(), &[b, t, 7]);
            let d = max_abs(&fast, &slow);
            assert!(d < 1e-4, "block differs: {d} (cond_in_decoder {cid}, cond {cd})");
            // and the gradients of the whole block agree
            let y = Tensor::randn(0f32, 1.0, (b, t, 7), &Device::Cpu).unwrap();
            let gf = motion_loss(&fast, &y).unwrap().backward().unwrap();
            let gs = motion_loss(&slow, &y).unwrap().backward().unwrap();
            for v in vm.all_vars() {
                let (a, s) = (gf.get(v.as_tensor()).unwrap(), gs.get(v.as_tensor()).unwrap());
                let d = max_abs(a, s);
                assert!(d < 1e-4, "block grad differs by {d} for {:?}", v.shape());
            }
        }
    }

    /// The fused head against candle's matmul and broadcast add: output and all three gradients.
    #[test]
    fn head_op_matches_candle_ops() {
        let dev = Device::Cpu;
        let var = |shape: &[usize]| Var::from_tensor(&Tensor::randn(0f32, 1.0, shape, &dev).unwrap()).unwrap();
        let (d, w, b) = (var(&[3, 4, 6]), var(&[5, 6]), var(&[5]));
        let r = Tensor::randn(0f32, 1.0, (3, 4, 5), &dev).unwrap();
        let fused = d.as_tensor().apply_op3(w.as_tensor(), b.as_tensor(), HeadOp).unwrap();
        let plain = d.as_tensor().reshape((12, 6)).unwrap().matmul(&w.as_tensor().t().unwrap()).unwrap();
        let plain = plain.broadcast_add(b.as_tensor()).unwrap().reshape((3, 4, 5)).unwrap();
        assert!(max_abs(&fused, &plain) < 1e-5);
        let gf = (fused * &r).unwrap().sum_all().unwrap().backward().unwrap();
        let gp = (plain * &r).unwrap().sum_all().unwrap().backward().unwrap();
        for v in [&d, &w, &b] {
            let diff = max_abs(gf.get(v.as_tensor()).unwrap(), gp.get(v.as_tensor()).unwrap());
            assert!(diff < 1e-5, "head gradient differs by {diff} for {:?}", v.shape());
        }
    }

    #[test]
    fn frozen_block_matches_forward() {
        for (cid, cd) in [(false, 5usize), (true, 5), (false, 0)] {
            let vm = VarMap::new();
            let blk = Seq2SeqBlock::new(cfg(cid, cd), VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu)).unwrap();
            let (fz, mut ws) = (blk.freeze().unwrap(), BlockWorkspace::default());
            for b in [1usize, 3, 12] {
                let t = 10;
                let x = Tensor::randn(0f32, 1.0, (b, t, 11), &Device::Cpu).unwrap();
                let c = if cd > 0 { Some(one_hot(b, cd)) } else { None };
                let want = blk.forward(&x, c.as_ref(), false).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
                let xv = x.flatten_all().unwrap().to_vec1::<f32>().unwrap();
                let cv = c.as_ref().map(|c| c.flatten_all().unwrap().to_vec1::<f32>().unwrap());
                let mut out = vec![0f32; b * t * 7];
                fz.infer(&mut ws, &xv, cv.as_deref(), b, t, &mut out);
                let d = want.iter().zip(&out).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
                assert!(d < 1e-5, "frozen block differs by {d}");
                let we = blk.encode(&x, c.as_ref()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
                let mut e = vec![0f32; b * t * 48];
                fz.encode_infer(&mut ws, &xv, cv.as_deref(), b, t, &mut e);
                let d = we.iter().zip(&e).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
                assert!(d < 1e-5, "frozen encoder differs by {d}");
            }
        }
    }

    #[test]
    fn project_adamw_matches_candle_adamw() {
        use candle_nn::AdamW;
        let dev = Device::Cpu;
        let init = Tensor::randn(0f32, 1.0, (13, 7), &dev).unwrap();
        let (va, vb) = (Var::from_tensor(&init).unwrap(), Var::from_tensor(&init).unwrap());
        let p = ParamsAdamW { lr: 2e-3, ..Default::default() };
        let mut oa = AdamW::new(vec![va.clone()], p.clone()).unwrap();
        let mut ob = crate::model::adamw::AdamW::new(vec![vb.clone()], p).unwrap();
        let target = Tensor::randn(0f32, 1.0, (13, 7), &dev).unwrap();
        for _ in 0..20 {
            oa.backward_step(&(va.as_tensor() - &target).unwrap().sqr().unwrap().sum_all().unwrap()).unwrap();
            ob.backward_step(&(vb.as_tensor() - &target).unwrap().sqr().unwrap().sum_all().unwrap()).unwrap();
        }
        let d = max_abs(va.as_tensor(), vb.as_tensor());
        let moved = max_abs(va.as_tensor(), &init);
        assert!(moved > 1e-2, "parameters did not move");
        assert!(d < 1e-5, "fused AdamW differs from candle's by {d}");
    }

    #[test]
    fn fused_dropout_statistics_and_gradient() {
        let dev = Device::Cpu;
        let x = Var::from_tensor(&Tensor::ones((200, 100), DType::F32, &dev).unwrap()).unwrap();
        let y = dropout(x.as_tensor(), 0.25).unwrap();
        let v = y.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let kept = v.iter().filter(|&&a| a != 0.0).count() as f32 / v.len() as f32;
        assert!((kept - 0.75).abs() < 0.02, "kept fraction {kept}");
        assert!(v.iter().all(|&a| a == 0.0 || (a - 1.0 / 0.75).abs() < 1e-6));
        let g = y.sum_all().unwrap().backward().unwrap();
        let gv = g.get(x.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        assert_eq!(gv, v, "gradient of sum(dropout(1)) is the mask");
    }

    #[test]
    fn dropout_only_in_training() {
        let vm = VarMap::new();
        let blk = Seq2SeqBlock::new(cfg(false, 5), VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu)).unwrap();
        let x = Tensor::randn(0f32, 1.0, (2, 10, 11), &Device::Cpu).unwrap();
        let c = one_hot(2, 5);
        let a = blk.forward(&x, Some(&c), false).unwrap();
        let b = blk.forward(&x, Some(&c), false).unwrap();
        assert_eq!(max_abs(&a, &b), 0.0);
        let tr = blk.forward(&x, Some(&c), true).unwrap();
        assert!(max_abs(&a, &tr) > 1e-4);
    }

    /// A synthetic, learnable sequence-to-sequence regression: the block must bring the
    /// (dropout-free) loss down by at least 10x with AdamW at lr 2e-3.
    #[test]
    fn block_learns_synthetic_target() {
        let dev = Device::Cpu;
        let (b, t, i, c, o) = (32usize, 8usize, 6usize, 3usize, 4usize);
        let cfg = BlockConfig { in_dim: i, cond_dim: c, cond_in_decoder: true, hidden: 32, out_dim: o, dropout: 0.25 };
        let vm = VarMap::new();
        let blk = Seq2SeqBlock::new(cfg, VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
        let x = Tensor::randn(0f32, 1.0, (b, t, i), &dev).unwrap();
        let cond = one_hot(b, c);
        let a = Tensor::randn(0f32, 0.5, (i, o), &dev).unwrap();
        let cm = Tensor::randn(0f32, 1.0, (c, o), &dev).unwrap();
        // y_t = sin(x_t A) + mean over time of x (needs both directions) + class offset
        let xa = x.reshape((b * t, i)).unwrap().matmul(&a).unwrap().reshape((b, t, o)).unwrap().sin().unwrap();
        let xm = x.mean_keepdim(1).unwrap().narrow(2, 0, o).unwrap().broadcast_as((b, t, o)).unwrap();
        let co = cond.matmul(&cm).unwrap().unsqueeze(1).unwrap().broadcast_as((b, t, o)).unwrap();
        let y = ((xa + xm).unwrap() + co).unwrap().contiguous().unwrap();
        let eval = || motion_loss(&blk.forward(&x, Some(&cond), false).unwrap(), &y).unwrap().to_scalar::<f32>().unwrap();
        let l0 = eval();
        let mut opt = AdamW::new(vm.all_vars(), ParamsAdamW { lr: 2e-3, ..Default::default() }).unwrap();
        for _ in 0..400 {
            let loss = motion_loss(&blk.forward(&x, Some(&cond), true).unwrap(), &y).unwrap();
            opt.backward_step(&loss).unwrap();
        }
        let l1 = eval();
        assert!(l1 * 10.0 < l0, "loss fell from {l0} to only {l1}");
    }
}
