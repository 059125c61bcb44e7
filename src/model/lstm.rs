//! Fast LSTM layers for CPU training and inference.
//!
//! * [`BiLstm`] — a bidirectional single-layer LSTM whose weights use candle-nn's (and PyTorch's)
//!   names and layout, so the same `VarBuilder` can also drive candle-nn's `LSTM`:
//!   `weight_ih_l0 [4H, I]`, `weight_hh_l0 [4H, H]`, `bias_ih_l0 [4H]`, `bias_hh_l0 [4H]` for the
//!   forward direction and the same names with the suffix `_reverse` for the backward direction
//!   (candle-nn's `Direction::Backward`, PyTorch's `bidirectional=True`). Gate order i, f, g, o.
//! * Training path ([`BiLstm::forward`]): ONE candle custom op ([`BiLstmOp`], a `CustomOp2` on
//!   `x [B*T, I]` and the flat concatenation of the eight parameters, see [`FlatLayout`]) does the
//!   whole layer on contiguous f32 buffers with the `gemm` crate: the input projection of the whole
//!   sequence for both directions in one gemm (`x · [W_ih_fwd; W_ih_bwd]ᵀ`), then per time step one
//!   gemm `h_{t-1} · W_hhᵀ` per direction and a fused, allocation-free, SIMD cell (the backward
//!   direction walks time in reverse inside the op), writing `[B, T, 2H]` directly. Its `bwd` is
//!   hand-written backprop through time using the gate activations and cells kept from the forward
//!   pass: per step one gemm for `dh_{t-1}`, then one gemm each for `dW_hh`, `dW_ih` (both
//!   directions at once) and `dx` (skipped when `x` is not in the autograd graph); the bias
//!   gradients are column sums. Candle only sees a `cat` of the parameters and this op.
//! * Inference path ([`CpuBiLstm::infer`]): a frozen copy of the weights as `Vec<f32>`, no candle
//!   tensors, reusable [`Scratch`] buffers.
use candle_core::{
    backprop::GradStore, bail, CpuStorage, CustomOp2, DType, Device, Layout, Result, Shape,
    Storage, Tensor,
};
use candle_nn::rnn::{Direction, LSTMConfig, LSTM, RNN};
use candle_nn::{Init, VarBuilder};
use gemm::Parallelism;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Mutex;

/// A row-major `[rows, cols]` matrix transposed to `[cols, rows]`. gemm streams a right
/// operand stored `[K, N]` row-major as it is, while the transposed view of a PyTorch-layout
/// weight `[N, K]` is repacked on every call: at batch 1 that repacking was a fifth of a block.
fn transposed(w: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    let mut t = vec![0f32; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            t[c * rows + r] = w[r * cols + c];
        }
    }
    t
}

/// [`transposed`] for each direction's block of two stacked `[rows, cols]` matrices.
fn transposed_per_direction(w: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    w.chunks_exact(rows * cols).flat_map(|m| transposed(m, rows, cols)).collect()
}

// ---------------------------------------------------------------------------------------------
// Threading policy

/// How the two directions of a bidirectional LSTM use the cores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Threading {
    /// The two directions side by side on rayon's pool, single-threaded gemm inside (default).
    PerDirection,
    /// Directions one after the other, gemm parallel over rayon.
    RayonGemm,
    /// Everything on the calling thread.
    Single,
}

/// Default: [`Threading::PerDirection`]. With the directions on `rayon::join` (no threads
/// spawned beside rayon's), a training step measured 1.15-1.37x faster than with a parallel
/// gemm per call, which wakes rayon's workers for every small gemm (docs/BENCHMARKS.md).
static THREADING: AtomicU8 = AtomicU8::new(0);

/// Select the threading policy of the fused LSTM (process wide; for benchmarking).
pub fn set_threading(t: Threading) {
    THREADING.store(
        match t {
            Threading::PerDirection => 0,
            Threading::RayonGemm => 1,
            Threading::Single => 2,
        },
        Ordering::Relaxed,
    );
}

pub fn threading() -> Threading {
    match THREADING.load(Ordering::Relaxed) {
        0 => Threading::PerDirection,
        1 => Threading::RayonGemm,
        _ => Threading::Single,
    }
}

/// Batches up to this size use the register-blocked small-batch kernels in inference.
const SMALL_BATCH: usize = 4;

fn run2<A: FnOnce() + Send, B: FnOnce() + Send>(parallel: bool, a: A, b: B) {
    if parallel {
        rayon::join(a, b);
    } else {
        a();
        b();
    }
}

fn gemm_par(t: Threading) -> Parallelism {
    match t {
        Threading::RayonGemm => Parallelism::Rayon(0),
        _ => Parallelism::None,
    }
}

/// A raw pointer that may cross to the per-direction worker thread. The two directions only
/// ever write disjoint columns of the shared buffers.
#[derive(Clone, Copy)]
struct SPtr(*mut f32);
unsafe impl Send for SPtr {}
unsafe impl Sync for SPtr {}
impl SPtr {
    #[inline(always)]
    fn get(self) -> *mut f32 {
        self.0
    }
}

// ---------------------------------------------------------------------------------------------
// Fast elementwise math (branch free, auto-vectorisable)

#[inline(always)]
fn fast_exp(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5 * 2^23: adding it rounds to an integer
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    let x = x.max(-87.0).min(88.0);
    let tm = x * std::f32::consts::LOG2_E + MAGIC;
    let n = tm - MAGIC;
    let ni = tm.to_bits().wrapping_sub(MAGIC.to_bits()) as i32;
    let r = x - n * LN2_HI - n * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
    p * f32::from_bits(((ni + 127) as u32) << 23)
}

#[inline(always)]
fn sigm(x: f32) -> f32 {
    1.0 / (1.0 + fast_exp(-x))
}

#[inline(always)]
fn tanh_f(x: f32) -> f32 {
    2.0 / (1.0 + fast_exp(-2.0 * x)) - 1.0
}

/// Forward LSTM cell for one batch row. `z` = recurrent pre-activations `h·W_hhᵀ`, `g` = projected
/// input, `bias` = `b_ih + b_hh` (all `4H`). Writes the gate activations, the new cell and `h`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn cell_fwd_impl(
    h: usize,
    z: &[f32],
    g: &[f32],
    bias: &[f32],
    c_prev: &[f32],
    acts: &mut [f32],
    c: &mut [f32],
    hout: &mut [f32],
) {
    let (zi, r) = z[..4 * h].split_at(h);
    let (zf, r) = r.split_at(h);
    let (zg, zo) = r.split_at(h);
    let (gi, r) = g[..4 * h].split_at(h);
    let (gf, r) = r.split_at(h);
    let (gg, go) = r.split_at(h);
    let (bi, r) = bias[..4 * h].split_at(h);
    let (bf, r) = r.split_at(h);
    let (bg, bo) = r.split_at(h);
    let (ai, r) = acts[..4 * h].split_at_mut(h);
    let (af, r) = r.split_at_mut(h);
    let (ag, ao) = r.split_at_mut(h);
    let c_prev = &c_prev[..h];
    let c = &mut c[..h];
    let hout = &mut hout[..h];
    for j in 0..h {
        let i = sigm(zi[j] + gi[j] + bi[j]);
        let f = sigm(zf[j] + gf[j] + bf[j]);
        let gt = tanh_f(zg[j] + gg[j] + bg[j]);
        let o = sigm(zo[j] + go[j] + bo[j]);
        let cn = f * c_prev[j] + i * gt;
        ai[j] = i;
        af[j] = f;
        ag[j] = gt;
        ao[j] = o;
        c[j] = cn;
        hout[j] = o * tanh_f(cn);
    }
}

/// Backward LSTM cell for one batch row: from `dh = dout + dh_rec` and the running `dc`,
/// writes the pre-activation gate gradients `dz` (4H) and updates `dc` to the gradient w.r.t. `c_prev`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn cell_bwd_impl(
    h: usize,
    dout: &[f32],
    dh_rec: &[f32],
    dc: &mut [f32],
    acts: &[f32],
    c: &[f32],
    c_prev: &[f32],
    dz: &mut [f32],
) {
    let (ai, r) = acts[..4 * h].split_at(h);
    let (af, r) = r.split_at(h);
    let (ag, ao) = r.split_at(h);
    let (di, r) = dz[..4 * h].split_at_mut(h);
    let (df, r) = r.split_at_mut(h);
    let (dg, dout_gate) = r.split_at_mut(h);
    let dout = &dout[..h];
    let dh_rec = &dh_rec[..h];
    let dc = &mut dc[..h];
    let c = &c[..h];
    let c_prev = &c_prev[..h];
    for j in 0..h {
        let dh = dout[j] + dh_rec[j];
        let (i, f, gt, o) = (ai[j], af[j], ag[j], ao[j]);
        let tc = tanh_f(c[j]);
        let dct = dc[j] + dh * o * (1.0 - tc * tc);
        di[j] = dct * gt * i * (1.0 - i);
        df[j] = dct * c_prev[j] * f * (1.0 - f);
        dg[j] = dct * i * (1.0 - gt * gt);
        dout_gate[j] = dh * tc * o * (1.0 - o);
        dc[j] = dct * f;
    }
}

/// `z[n] += sum_k h[k] * wt[k, n]` (small-batch recurrent product with `W_hhᵀ` stored `[H, 4H]`).
/// Register-blocked over column chunks so the accumulators stay in registers and only the weights
/// stream from memory.
#[inline(always)]
fn axpy_rows_impl(hk: &[f32], wt: &[f32], z: &mut [f32]) {
    #[inline(always)]
    fn chunk<const C: usize>(hk: &[f32], wt: &[f32], z: &mut [f32], j: usize) {
        let n = z.len();
        let mut acc = [0f32; C];
        acc.copy_from_slice(&z[j..j + C]);
        for (k, &hv) in hk.iter().enumerate() {
            let row: &[f32; C] = wt[k * n + j..k * n + j + C].try_into().unwrap();
            for c in 0..C {
                acc[c] += hv * row[c];
            }
        }
        z[j..j + C].copy_from_slice(&acc);
    }
    let n = z.len();
    assert!(wt.len() >= hk.len() * n);
    let mut j = 0;
    while j + 128 <= n {
        chunk::<128>(hk, wt, z, j);
        j += 128;
    }
    while j + 32 <= n {
        chunk::<32>(hk, wt, z, j);
        j += 32;
    }
    while j + 8 <= n {
        chunk::<8>(hk, wt, z, j);
        j += 8;
    }
    while j < n {
        chunk::<1>(hk, wt, z, j);
        j += 1;
    }
}

/// [`axpy_rows_impl`] for two batch rows at once: each weight row streams from memory once for
/// both (batch-1 inference is bound by that stream, so the second row is nearly free).
#[inline(always)]
fn axpy_rows2_impl(ha: &[f32], hb: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32]) {
    #[inline(always)]
    fn chunk<const C: usize>(ha: &[f32], hb: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32], j: usize) {
        let n = za.len();
        let (mut acc_a, mut acc_b) = ([0f32; C], [0f32; C]);
        acc_a.copy_from_slice(&za[j..j + C]);
        acc_b.copy_from_slice(&zb[j..j + C]);
        for (k, (&va, &vb)) in ha.iter().zip(hb).enumerate() {
            let row: &[f32; C] = wt[k * n + j..k * n + j + C].try_into().unwrap();
            for c in 0..C {
                acc_a[c] += va * row[c];
                acc_b[c] += vb * row[c];
            }
        }
        za[j..j + C].copy_from_slice(&acc_a);
        zb[j..j + C].copy_from_slice(&acc_b);
    }
    let n = za.len();
    assert!(zb.len() == n && hb.len() == ha.len() && wt.len() >= ha.len() * n);
    let mut j = 0;
    while j + 128 <= n {
        chunk::<128>(ha, hb, wt, za, zb, j);
        j += 128;
    }
    while j + 32 <= n {
        chunk::<32>(ha, hb, wt, za, zb, j);
        j += 32;
    }
    while j + 8 <= n {
        chunk::<8>(ha, hb, wt, za, zb, j);
        j += 8;
    }
    while j < n {
        chunk::<1>(ha, hb, wt, za, zb, j);
        j += 1;
    }
}

macro_rules! dispatch_simd {
    ($name:ident, $impl_:ident, ($($arg:ident : $ty:ty),*)) => {
        #[allow(clippy::too_many_arguments)]
        #[inline]
        fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn v4($($arg: $ty),*) { $impl_($($arg),*) }
                #[target_feature(enable = "avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn v3($($arg: $ty),*) { $impl_($($arg),*) }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    return unsafe { v4($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    return unsafe { v3($($arg),*) };
                }
            }
            $impl_($($arg),*)
        }
    };
}

dispatch_simd!(cell_fwd, cell_fwd_impl, (h: usize, z: &[f32], g: &[f32], bias: &[f32], c_prev: &[f32], acts: &mut [f32], c: &mut [f32], hout: &mut [f32]));
dispatch_simd!(cell_bwd, cell_bwd_impl, (h: usize, dout: &[f32], dh_rec: &[f32], dc: &mut [f32], acts: &[f32], c: &[f32], c_prev: &[f32], dz: &mut [f32]));
dispatch_simd!(axpy_rows, axpy_rows_impl, (hk: &[f32], wt: &[f32], z: &mut [f32]));
dispatch_simd!(axpy_rows2, axpy_rows2_impl, (ha: &[f32], hb: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32]));

/// `dst[m, n] = lhs[m, k] · rhs[k, n]` with explicit (row, column) strides.
#[allow(clippy::too_many_arguments)]
#[inline]
unsafe fn mm(
    m: usize,
    n: usize,
    k: usize,
    dst: *mut f32,
    dst_rs: usize,
    lhs: *const f32,
    lhs_rs: usize,
    lhs_cs: usize,
    rhs: *const f32,
    rhs_rs: usize,
    rhs_cs: usize,
    accumulate: bool,
    par: Parallelism,
) {
    gemm::gemm(
        m,
        n,
        k,
        dst,
        1,
        dst_rs as isize,
        accumulate,
        lhs,
        lhs_cs as isize,
        lhs_rs as isize,
        rhs,
        rhs_cs as isize,
        rhs_rs as isize,
        1.0f32,
        1.0f32,
        false,
        false,
        false,
        par,
    )
}

// ---------------------------------------------------------------------------------------------
// One direction of the recurrence on raw buffers

/// Buffers and sizes of one direction's forward recurrence.
struct DirFwd<'a> {
    d: usize,
    b: usize,
    t: usize,
    h: usize,
    /// Projected gates `[B*T, 8H]` (this direction's columns start at `d*4H`), no bias.
    g: *const f32,
    /// This direction's `W_hhᵀ [H, 4H]`.
    whh_t: &'a [f32],
    /// `b_ih + b_hh` of this direction `[4H]`.
    bias: &'a [f32],
    /// Output `[B*T, 2H]` (this direction's columns start at `d*H`).
    out: SPtr,
    /// Gate activations `[B*T, 4H]` and cells `[B*T, H]` of this direction (written).
    acts: &'a mut [f32],
    cs: &'a mut [f32],
    /// Scratch `[B*4H]` and zeros `[H]`.
    z: &'a mut [f32],
    zeros: &'a [f32],
    par: Parallelism,
}

#[inline(always)]
fn time_at(d: usize, t: usize, s: usize) -> usize {
    if d == 0 {
        s
    } else {
        t - 1 - s
    }
}

impl DirFwd<'_> {
    fn run(self) {
        let DirFwd { d, b, t, h, g, whh_t, bias, out, acts, cs, z, zeros, par } = self;
        let h4 = 4 * h;
        let out = out.get();
        for s in 0..t {
            let tt = time_at(d, t, s);
            let z = &mut z[..b * h4];
            if s == 0 {
                z.fill(0.0);
            } else {
                let tp = time_at(d, t, s - 1);
                // h_prev rows: out[(bb*T + tp)*2H + d*H], row stride T*2H
                let hp = unsafe { out.add(tp * 2 * h + d * h) } as *const f32;
                if b <= SMALL_BATCH {
                    z.fill(0.0);
                    let hrow = |bb: usize| unsafe { std::slice::from_raw_parts(hp.add(bb * t * 2 * h), h) };
                    let mut rows = z.chunks_exact_mut(h4).enumerate();
                    while let Some((bb, za)) = rows.next() {
                        match rows.next() {
                            Some((_, zb)) => axpy_rows2(hrow(bb), hrow(bb + 1), whh_t, za, zb),
                            None => axpy_rows(hrow(bb), whh_t, za),
                        }
                    }
                } else {
                    // z[B,4H] = h_prev[B,H] · W_hhᵀ, from the stored transpose (see [`transposed`])
                    unsafe { mm(b, h4, h, z.as_mut_ptr(), h4, hp, t * 2 * h, 1, whh_t.as_ptr(), h4, 1, false, par) };
                }
            }
            for bb in 0..b {
                let row = bb * t + tt;
                let grow = unsafe { std::slice::from_raw_parts(g.add(row * 8 * h + d * h4), h4) };
                let (c_prev, c_now): (&[f32], &mut [f32]) = if s == 0 {
                    (zeros, &mut cs[row * h..row * h + h])
                } else {
                    let prow = bb * t + time_at(d, t, s - 1);
                    // split the borrow: prow != row
                    let ptr = cs.as_mut_ptr();
                    unsafe {
                        (
                            std::slice::from_raw_parts(ptr.add(prow * h), h),
                            std::slice::from_raw_parts_mut(ptr.add(row * h), h),
                        )
                    }
                };
                let hout = unsafe { std::slice::from_raw_parts_mut(out.add(row * 2 * h + d * h), h) };
                cell_fwd(
                    h,
                    &z[bb * h4..(bb + 1) * h4],
                    grow,
                    bias,
                    c_prev,
                    &mut acts[row * h4..(row + 1) * h4],
                    c_now,
                    hout,
                );
            }
        }
    }
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
    /// Gradient of the projected gates `[B*T, 8H]` (this direction's columns at `d*4H`), written.
    dg: SPtr,
    /// Gradient of this direction's `W_hh [4H, H]` and bias `[4H]`, written.
    dw: &'a mut [f32],
    db: &'a mut [f32],
    par: Parallelism,
}

impl DirBwd<'_> {
    fn run(self) {
        let DirBwd { d, b, t, h, dout, hs, whh, acts, cs, dg, dw, db, par } = self;
        let h4 = 4 * h;
        let dg = dg.get();
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
                let dz = unsafe { std::slice::from_raw_parts_mut(dg.add(row * 8 * h + d * h4), h4) };
                cell_bwd(
                    h,
                    &dout[row * 2 * h + d * h..row * 2 * h + d * h + h],
                    &dh_rec[bb * h..(bb + 1) * h],
                    &mut dc[bb * h..(bb + 1) * h],
                    &acts[row * h4..(row + 1) * h4],
                    &cs[row * h..row * h + h],
                    c_prev,
                    dz,
                );
            }
            if s > 0 {
                // dh_rec[B,H] = dz_t[B,4H] · W_hh[4H,H]
                unsafe {
                    mm(
                        b,
                        h,
                        h4,
                        dh_rec.as_mut_ptr(),
                        h,
                        dg.add(tt * 8 * h + d * h4),
                        t * 8 * h,
                        1,
                        whh.as_ptr(),
                        h,
                        1,
                        false,
                        par,
                    );
                }
            }
        }
        // h_prev for every (b, t) of this direction, zero at the first step.
        let mut hp = vec![0f32; b * t * h];
        for bb in 0..b {
            for s in 1..t {
                let row = bb * t + time_at(d, t, s);
                let prow = bb * t + time_at(d, t, s - 1);
                hp[row * h..row * h + h]
                    .copy_from_slice(&hs[prow * 2 * h + d * h..prow * 2 * h + d * h + h]);
            }
        }
        // dW_hh[4H,H] = dZᵀ[4H, B*T] · h_prev[B*T, H]
        unsafe {
            mm(
                h4,
                h,
                b * t,
                dw.as_mut_ptr(),
                h,
                dg.add(d * h4),
                1,
                8 * h,
                hp.as_ptr(),
                h,
                1,
                false,
                par,
            );
        }
        db.fill(0.0);
        for row in 0..b * t {
            let dz = unsafe { std::slice::from_raw_parts(dg.add(row * 8 * h + d * h4), h4) };
            for (a, &v) in db.iter_mut().zip(dz) {
                *a += v;
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The candle custom op

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
/// (row-major, candle-nn shapes; see [`FlatLayout`]). Each direction runs on its own thread: its
/// input projection for the whole sequence (one gemm), then the recurrence (one gemm per step and
/// a fused cell). The backward pass is hand-written BPTT; the input gradient is only computed when
/// `x` is part of the autograd graph.
pub struct BiLstmOp {
    b: usize,
    t: usize,
    i: usize,
    h: usize,
    cache: Mutex<Option<FwdCache>>,
}

impl BiLstmOp {
    pub fn new(b: usize, t: usize, i: usize, h: usize) -> Self {
        Self { b, t, i, h, cache: Mutex::new(None) }
    }
    fn layout(&self) -> FlatLayout {
        FlatLayout { i: self.i, h: self.h }
    }
}

fn contiguous_f32<'a>(s: &'a CpuStorage, l: &Layout) -> Result<&'a [f32]> {
    let data = s.as_slice::<f32>()?;
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => bail!("fused lstm: input must be contiguous"),
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
        Storage::Cpu(cpu) => Ok(f(contiguous_f32(cpu, l)?)),
        _ => bail!("fused lstm: only CPU tensors are supported"),
    }
}

/// `g[:, d*4H..(d+1)*4H] = x[BT, I] · W_ih[d]ᵀ` (g has row stride 8H).
unsafe fn project(d: usize, bt: usize, i: usize, h: usize, x: *const f32, w_ih_d: *const f32, g: *mut f32, par: Parallelism) {
    mm(bt, 4 * h, i, g.add(d * 4 * h), 8 * h, x, i, 1, w_ih_d, 1, i, false, par);
}

impl CustomOp2 for BiLstmOp {
    fn name(&self) -> &'static str {
        "fused-bilstm"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let (b, t, i, h) = (self.b, self.t, self.i, self.h);
        let fl = self.layout();
        let x = contiguous_f32(s1, l1)?;
        let p = contiguous_f32(s2, l2)?;
        if x.len() != b * t * i || p.len() != fl.len() {
            bail!("fused lstm: bad input sizes {} {}", x.len(), p.len());
        }
        let bsum: [Vec<f32>; 2] = [0, 1].map(|d| {
            (0..4 * h).map(|j| p[fl.b_ih(d) + j] + p[fl.b_hh(d) + j]).collect::<Vec<f32>>()
        });
        let mut out = vec![0f32; b * t * 2 * h];
        let mut g = vec![0f32; b * t * 8 * h];
        let mut acts = [vec![0f32; b * t * 4 * h], vec![0f32; b * t * 4 * h]];
        let mut cs = [vec![0f32; b * t * h], vec![0f32; b * t * h]];
        let mut z = [vec![0f32; b * 4 * h], vec![0f32; b * 4 * h]];
        let zeros = vec![0f32; h];
        // once per call rather than a repack at every step
        let whh_t: [Vec<f32>; 2] = [0, 1].map(|d| transposed(&p[fl.w_hh(d)..fl.w_hh(d) + 4 * h * h], 4 * h, h));
        let th = threading();
        let par = gemm_par(th);
        let outp = SPtr(out.as_mut_ptr());
        let gp = SPtr(g.as_mut_ptr());
        {
            let [a0, a1] = &mut acts;
            let [c0, c1] = &mut cs;
            let [z0, z1] = &mut z;
            let mk = |d: usize, acts, cs, z| DirFwd {
                d,
                b,
                t,
                h,
                g: gp.get(),
                whh_t: &whh_t[d],
                bias: &bsum[d],
                out: outp,
                acts,
                cs,
                z,
                zeros: &zeros,
                par,
            };
            let f0 = SendBox(mk(0, &mut a0[..], &mut c0[..], &mut z0[..]));
            let f1 = SendBox(mk(1, &mut a1[..], &mut c1[..], &mut z1[..]));
            let xp = SPtr(x.as_ptr() as *mut f32);
            let wp = SPtr(p.as_ptr() as *mut f32);
            if th == Threading::PerDirection {
                // each thread projects its own direction, then runs its recurrence
                run2(
                    true,
                    move || unsafe {
                        project(0, b * t, i, h, xp.get(), wp.get().add(fl.w_ih(0)), gp.get(), par);
                        f0.into_inner().run()
                    },
                    move || unsafe {
                        project(1, b * t, i, h, xp.get(), wp.get().add(fl.w_ih(1)), gp.get(), par);
                        f1.into_inner().run()
                    },
                );
            } else {
                // both directions' projections in one gemm: g [BT, 8H] = x · [W_ih_f; W_ih_b]ᵀ
                unsafe { mm(b * t, 8 * h, i, gp.get(), 8 * h, xp.get(), i, 1, wp.get(), 1, i, false, par) };
                f0.into_inner().run();
                f1.into_inner().run();
            }
        }
        *self.cache.lock().unwrap() = Some(FwdCache { acts, cs });
        Ok((CpuStorage::F32(out), Shape::from((b, t, 2 * h))))
    }

    fn bwd(&self, x: &Tensor, p: &Tensor, res: &Tensor, grad_res: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let (b, t, i, h) = (self.b, self.t, self.i, self.h);
        let fl = self.layout();
        let bt = b * t;
        let need_dx = x.track_op();
        let guard = self.cache.lock().unwrap();
        let cache = match guard.as_ref() {
            Some(c) => c,
            None => bail!("fused lstm: backward without forward cache"),
        };
        let mut dg = vec![0f32; bt * 8 * h];
        let mut dp = vec![0f32; fl.len()];
        let mut dx = if need_dx { vec![0f32; bt * i] } else { Vec::new() };
        let th = threading();
        let par = gemm_par(th);
        let parallel = th == Threading::PerDirection;
        let dgp = SPtr(dg.as_mut_ptr());
        with_f32(x, |xs| {
            with_f32(p, |ps| {
                with_f32(res, |hs| {
                    with_f32(grad_res, |dout| {
                        // disjoint parameter-gradient regions of each direction
                        let (dwih, rest) = dp.split_at_mut(8 * h * i);
                        let (dwhh, dbias) = rest.split_at_mut(8 * h * h);
                        let (dwhh0, dwhh1) = dwhh.split_at_mut(4 * h * h);
                        let (db0, db1) = dbias[..8 * h].split_at_mut(4 * h);
                        let mk = |d: usize, dw, db| DirBwd {
                            d,
                            b,
                            t,
                            h,
                            dout,
                            hs,
                            whh: &ps[fl.w_hh(d)..fl.w_hh(d) + 4 * h * h],
                            acts: &cache.acts[d],
                            cs: &cache.cs[d],
                            dg: dgp,
                            dw,
                            db,
                            par,
                        };
                        let (f0, f1) = (SendBox(mk(0, dwhh0, db0)), SendBox(mk(1, dwhh1, db1)));
                        let xp = SPtr(xs.as_ptr() as *mut f32);
                        // dW_ih[d] [4H, I] = dG_dᵀ [4H, BT] · x [BT, I]
                        let dwih_job = move |d: usize, dst: &mut [f32]| unsafe {
                            mm(4 * h, i, bt, dst.as_mut_ptr(), i, dgp.get().add(d * 4 * h), 1, 8 * h, xp.get(), i, 1, false, par);
                        };
                        if parallel {
                            let (dwih0, dwih1) = dwih.split_at_mut(4 * h * i);
                            let (w0, w1) = (SendBox(dwih0), SendBox(dwih1));
                            run2(
                                true,
                                move || {
                                    f0.into_inner().run();
                                    dwih_job(0, w0.into_inner());
                                },
                                move || {
                                    f1.into_inner().run();
                                    dwih_job(1, w1.into_inner());
                                },
                            );
                        } else {
                            f0.into_inner().run();
                            f1.into_inner().run();
                            // both directions in one gemm: dW_ih [8H, I] = dGᵀ [8H, BT] · x [BT, I]
                            let dst = dwih.as_mut_ptr();
                            unsafe { mm(8 * h, i, bt, dst, i, dgp.get(), 1, 8 * h, xp.get(), i, 1, false, par) };
                        }
                        // the bias gradients: b_hh gets the same as b_ih
                        let (bi, bh) = dbias.split_at_mut(8 * h);
                        bh.copy_from_slice(bi);
                        if need_dx {
                            // dx [BT, I] = dG [BT, 8H] · W_ih [8H, I], rows split over the threads
                            let half = if parallel { bt / 2 } else { bt };
                            let (dx0, dx1) = dx.split_at_mut(half * i);
                            let wih = SPtr(ps.as_ptr() as *mut f32);
                            let job = move |r0: usize, rows: usize, dst: SendBox<&mut [f32]>| unsafe {
                                if rows > 0 {
                                    mm(rows, i, 8 * h, dst.into_inner().as_mut_ptr(), i, dgp.get().add(r0 * 8 * h), 8 * h, 1, wih.get(), i, 1, false, par);
                                }
                            };
                            let (d0, d1) = (SendBox(dx0), SendBox(dx1));
                            run2(parallel, move || job(0, half, d0), move || job(half, bt - half, d1));
                        }
                    })
                })
            })
        })????;
        drop(guard);
        let dev = Device::Cpu;
        let dx = if need_dx { Some(Tensor::from_vec(dx, x.shape(), &dev)?) } else { None };
        Ok((dx, Some(Tensor::from_vec(dp, fl.len(), &dev)?)))
    }
}

/// Wrapper that lets a per-direction job (holding raw pointers into buffers whose disjoint parts
/// it writes) move to the worker thread.
struct SendBox<T>(T);
unsafe impl<T> Send for SendBox<T> {}
impl<T> SendBox<T> {
    fn into_inner(self) -> T {
        self.0
    }
}

// ---------------------------------------------------------------------------------------------
// BiLstm module

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
    ref_fwd: LSTM,
    ref_bwd: LSTM,
}

impl BiLstm {
    /// Weights under `vb`: `weight_ih_l0`, `weight_hh_l0`, `bias_ih_l0`, `bias_hh_l0` (forward) and
    /// the same with `_reverse` (backward). New variables are initialised like PyTorch:
    /// U(-1/sqrt(H), 1/sqrt(H)).
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
        let ref_fwd = LSTM::new(in_dim, hidden, LSTMConfig::default(), vb.clone())?;
        let ref_bwd = LSTM::new(
            in_dim,
            hidden,
            LSTMConfig { direction: Direction::Backward, ..LSTMConfig::default() },
            vb,
        )?;
        Ok(Self { in_dim, hidden, fwd, bwd, ref_fwd, ref_bwd })
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
        x2.apply_op2(&p, BiLstmOp::new(b, t, i, self.hidden))
    }

    /// The same computation through candle-nn's `LSTM` (the backward one over the reversed
    /// sequence). For tests and benchmarks.
    pub fn forward_reference(&self, x: &Tensor) -> Result<Tensor> {
        let t = x.dim(1)?;
        let rev: Vec<u32> = (0..t as u32).rev().collect();
        let rev = Tensor::new(rev.as_slice(), x.device())?;
        let f = self.ref_fwd.states_to_tensor(&self.ref_fwd.seq(x)?)?;
        let xr = x.index_select(&rev, 1)?;
        let br = self.ref_bwd.states_to_tensor(&self.ref_bwd.seq(&xr)?)?;
        let bk = br.index_select(&rev, 1)?;
        Tensor::cat(&[&f, &bk], 2)
    }

    /// Copy the current weights out into plain f32 buffers for [`CpuBiLstm::infer`].
    pub fn freeze(&self) -> Result<CpuBiLstm> {
        let v = |t: &Tensor| -> Result<Vec<f32>> {
            t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()
        };
        let h = self.hidden;
        let mut w_ih = v(&self.fwd.w_ih)?;
        w_ih.extend(v(&self.bwd.w_ih)?);
        let w_ih_t = transposed_per_direction(&w_ih, 4 * h, self.in_dim);
        let mut w_hh = v(&self.fwd.w_hh)?;
        w_hh.extend(v(&self.bwd.w_hh)?);
        let mut bias = Vec::with_capacity(8 * h);
        for dir in [&self.fwd, &self.bwd] {
            let (bi, bh) = (v(&dir.b_ih)?, v(&dir.b_hh)?);
            bias.extend(bi.iter().zip(&bh).map(|(a, b)| a + b));
        }
        let w_hh_t = transposed_per_direction(&w_hh, 4 * h, h);
        Ok(CpuBiLstm { in_dim: self.in_dim, hidden: h, w_ih_t, w_hh_t, bias })
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

// ---------------------------------------------------------------------------------------------
// Plain-f32 inference

/// Frozen weights of a [`BiLstm`] for autograd-free inference.
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
}

/// Reusable buffers for [`CpuBiLstm::infer`]; grows on demand, never shrinks.
#[derive(Default, Debug, Clone)]
pub struct Scratch {
    g: Vec<f32>,
    acts: [Vec<f32>; 2],
    cs: [Vec<f32>; 2],
    z: [Vec<f32>; 2],
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
        let (h, i) = (self.hidden, self.in_dim);
        assert_eq!(x.len(), b * t * i, "CpuBiLstm::infer: x has the wrong size");
        assert_eq!(out.len(), b * t * 2 * h, "CpuBiLstm::infer: out has the wrong size");
        grow(&mut sc.g, b * t * 8 * h);
        grow(&mut sc.zeros, h);
        for d in 0..2 {
            grow(&mut sc.acts[d], b * t * 4 * h);
            grow(&mut sc.cs[d], b * t * h);
            grow(&mut sc.z[d], b * 4 * h);
        }
        // The two directions run side by side on rayon's pool, each with a single-threaded
        // gemm: at batch 1 the recurrence is bound by streaming each direction's weights, and
        // at LocGen's batch 150 this measured a little faster than directions in turn with a
        // parallel gemm. (Unlike a spawned thread, `rayon::join` costs microseconds.)
        let parallel = threading() != Threading::Single;
        let gp = SPtr(sc.g.as_mut_ptr());
        let outp = SPtr(out.as_mut_ptr());
        let Scratch { acts, cs, z, zeros, .. } = sc;
        let [a0, a1] = acts;
        let [c0, c1] = cs;
        let [z0, z1] = z;
        let zeros: &[f32] = zeros;
        let j0 = SendBox((&mut a0[..], &mut c0[..], &mut z0[..]));
        let j1 = SendBox((&mut a1[..], &mut c1[..], &mut z1[..]));
        let f0 = move || {
            let (a, c, z) = j0.into_inner();
            self.infer_dir(0, x, b, t, gp, outp, a, c, z, zeros)
        };
        let f1 = move || {
            let (a, c, z) = j1.into_inner();
            self.infer_dir(1, x, b, t, gp, outp, a, c, z, zeros)
        };
        run2(parallel, f0, f1);
    }

    #[allow(clippy::too_many_arguments)]
    fn infer_dir(
        &self,
        d: usize,
        x: &[f32],
        b: usize,
        t: usize,
        gp: SPtr,
        outp: SPtr,
        acts: &mut [f32],
        cs: &mut [f32],
        z: &mut [f32],
        zeros: &[f32],
    ) {
        let (h, i) = (self.hidden, self.in_dim);
        let h4 = 4 * h;
        // this direction's gate projection: g[:, d*4H..] = x · W_ih[d]ᵀ
        unsafe {
            mm(
                b * t,
                h4,
                i,
                gp.get().add(d * h4),
                8 * h,
                x.as_ptr(),
                i,
                1,
                self.w_ih_t.as_ptr().add(d * i * h4),
                h4,
                1,
                false,
                Parallelism::None,
            );
        }
        DirFwd {
            d,
            b,
            t,
            h,
            g: gp.get(),
            whh_t: &self.w_hh_t[d * h4 * h..(d + 1) * h4 * h],
            bias: &self.bias[d * h4..(d + 1) * h4],
            out: outp,
            acts,
            cs,
            z,
            zeros,
            par: Parallelism::None,
        }
        .run();
    }
}

/// Gradients of the eight parameters of a [`BiLstm`] from a `GradStore` (None if absent).
pub fn grads_of(lstm: &BiLstm, grads: &GradStore) -> Vec<Option<Tensor>> {
    lstm.tensors().iter().map(|t| grads.get(t).cloned()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Var;
    use candle_nn::VarMap;

    fn max_abs(a: &Tensor, b: &Tensor) -> f32 {
        (a - b).unwrap().abs().unwrap().flatten_all().unwrap().max(0).unwrap().to_scalar::<f32>().unwrap()
    }

    fn build(i: usize, h: usize) -> (VarMap, BiLstm) {
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
        let l = BiLstm::new(i, h, vb.pp("lstm")).unwrap();
        // non-zero biases everywhere (PyTorch-style init already gives that)
        (vm, l)
    }

    #[test]
    fn fast_math_accuracy() {
        let mut worst_e = 0f32;
        let mut worst_t = 0f32;
        for k in -2000..=2000 {
            let x = k as f32 * 0.01;
            let e = fast_exp(x);
            worst_e = worst_e.max(((e - x.exp()) / x.exp()).abs());
            worst_t = worst_t.max((tanh_f(x) - x.tanh()).abs());
        }
        assert!(worst_e < 1e-6, "exp rel err {worst_e}");
        assert!(worst_t < 1e-6, "tanh abs err {worst_t}");
        assert!(fast_exp(-200.0) >= 0.0 && fast_exp(-200.0) < 1e-37);
        assert!(fast_exp(200.0).is_finite());
    }

    #[test]
    fn forward_matches_candle_nn() {
        for &(b, t, i, h) in &[(3usize, 7usize, 5usize, 6usize), (9, 10, 92, 40), (1, 4, 3, 17)] {
            for th in [Threading::PerDirection, Threading::RayonGemm, Threading::Single] {
                set_threading(th);
                let (_vm, l) = build(i, h);
                let x = Tensor::randn(0f32, 1.0, (b, t, i), &Device::Cpu).unwrap();
                let fast = l.forward(&x).unwrap();
                let slow = l.forward_reference(&x).unwrap();
                assert_eq!(fast.dims(), &[b, t, 2 * h]);
                let dfwd = max_abs(&fast.narrow(2, 0, h).unwrap(), &slow.narrow(2, 0, h).unwrap());
                let dbwd = max_abs(&fast.narrow(2, h, h).unwrap(), &slow.narrow(2, h, h).unwrap());
                assert!(dfwd < 1e-4, "forward direction differs: {dfwd}");
                assert!(dbwd < 1e-4, "backward direction differs: {dbwd}");
            }
        }
        set_threading(Threading::PerDirection);
    }

    #[test]
    fn frozen_infer_matches_forward() {
        for &(b, t, i, h) in &[(1usize, 10usize, 12usize, 20usize), (2, 10, 12, 40), (3, 5, 7, 9), (16, 6, 10, 8)] {
            let (_vm, l) = build(i, h);
            let x = Tensor::randn(0f32, 1.0, (b, t, i), &Device::Cpu).unwrap();
            let fast = l.forward(&x).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
            let frozen = l.freeze().unwrap();
            let xv = x.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            let mut out = vec![0f32; b * t * 2 * h];
            let mut sc = Scratch::default();
            frozen.infer(&xv, b, t, &mut out, &mut sc);
            let d = fast.iter().zip(&out).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
            assert!(d < 1e-5, "frozen differs by {d}");
            // second call on the same scratch gives the same
            let mut out2 = vec![0f32; b * t * 2 * h];
            frozen.infer(&xv, b, t, &mut out2, &mut sc);
            assert_eq!(out, out2);
        }
    }

    /// Loss = sum(out * r) through the fast op; its gradients w.r.t. the input and every parameter
    /// (both directions' W_ih, W_hh, biases) vs central finite differences of the op's forward
    /// (accumulated in f64).
    #[test]
    fn op_gradients_match_finite_differences() {
        let (b, t, i, h) = (2usize, 4usize, 3usize, 5usize);
        let fl = FlatLayout { i, h };
        let dev = Device::Cpu;
        let x = Var::from_tensor(&Tensor::randn(0f32, 1.0, (b * t, i), &dev).unwrap()).unwrap();
        let p = Var::from_tensor(&Tensor::randn(0f32, 0.5, fl.len(), &dev).unwrap()).unwrap();
        let r = Tensor::randn(0f32, 1.0, (b, t, 2 * h), &dev).unwrap();
        let rv = r.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let loss_of = |xv: &[f32], pv: &[f32]| -> f64 {
            let xt = Tensor::from_slice(xv, (b * t, i), &dev).unwrap();
            let pt = Tensor::from_slice(pv, fl.len(), &dev).unwrap();
            let o = xt.apply_op2_no_bwd(&pt, &BiLstmOp::new(b, t, i, h)).unwrap();
            let o = o.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            o.iter().zip(&rv).map(|(a, b)| *a as f64 * *b as f64).sum()
        };
        let out = x.as_tensor().apply_op2(p.as_tensor(), BiLstmOp::new(b, t, i, h)).unwrap();
        let loss = (out * &r).unwrap().sum_all().unwrap();
        let grads = loss.backward().unwrap();
        let gx = grads.get(x.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let gp = grads.get(p.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let xv = x.as_tensor().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let pv = p.as_tensor().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        // five-point stencil: truncation error O(eps^4), f32 rounding noise ~1e-6 / eps
        let eps = 1e-2f32;
        let stencil = |f: &dyn Fn(f32) -> f64| -> f64 {
            (8.0 * (f(eps) - f(-eps)) - (f(2.0 * eps) - f(-2.0 * eps))) / (12.0 * eps as f64)
        };
        // relative error of the whole gradient block: |fd - analytic| / |fd| (2-norms)
        let rel = |fd: &[f64], an: &[f32]| -> f64 {
            let num: f64 = fd.iter().zip(an).map(|(a, b)| (a - *b as f64).powi(2)).sum();
            let den: f64 = fd.iter().map(|a| a * a).sum();
            (num / den).sqrt()
        };
        let fd_x: Vec<f64> = (0..xv.len())
            .map(|k| {
                stencil(&|e| {
                    let mut a = xv.clone();
                    a[k] += e;
                    loss_of(&a, &pv)
                })
            })
            .collect();
        let fd_p: Vec<f64> = (0..pv.len())
            .map(|k| {
                stencil(&|e| {
                    let mut a = pv.clone();
                    a[k] += e;
                    loss_of(&xv, &a)
                })
            })
            .collect();
        let rx = rel(&fd_x, &gx);
        eprintln!("finite differences: input rel err {rx:.2e}");
        assert!(rx < 1e-3, "input gradient: finite-difference mismatch {rx}");
        // each parameter block separately: W_ih, W_hh, biases of each direction
        for (name, lo, hi) in [
            ("w_ih fwd", fl.w_ih(0), fl.w_ih(1)),
            ("w_ih bwd", fl.w_ih(1), fl.w_hh(0)),
            ("w_hh fwd", fl.w_hh(0), fl.w_hh(1)),
            ("w_hh bwd", fl.w_hh(1), fl.b_ih(0)),
            ("b_ih", fl.b_ih(0), fl.b_hh(0)),
            ("b_hh", fl.b_hh(0), fl.len()),
        ] {
            let r = rel(&fd_p[lo..hi], &gp[lo..hi]);
            eprintln!("finite differences: {name} rel err {r:.2e}");
            assert!(r < 1e-3, "{name} gradient: finite-difference mismatch {r}");
        }
        // not trivially zero, in every block of the parameters
        for (lo, hi) in [(fl.w_ih(0), fl.w_ih(1)), (fl.w_hh(1), fl.b_ih(0)), (fl.b_hh(1), fl.len())] {
            assert!(gp[lo..hi].iter().any(|v| v.abs() > 1e-3));
        }
        // without x in the graph, no input gradient is produced
        let xc = Tensor::from_slice(&xv, (b * t, i), &dev).unwrap();
        let l2 = (xc.apply_op2(p.as_tensor(), BiLstmOp::new(b, t, i, h)).unwrap() * &r).unwrap().sum_all().unwrap();
        let g2 = l2.backward().unwrap();
        assert!(g2.get(&xc).is_none());
        let gp2 = g2.get(p.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        assert_eq!(gp, gp2);
    }

    /// Same loss through the fast path and through candle-nn's LSTM; gradients w.r.t. all eight
    /// weights and the input must agree.
    #[test]
    fn gradients_match_candle_nn_autograd() {
        for th in [Threading::PerDirection, Threading::RayonGemm, Threading::Single] {
            set_threading(th);
            let (b, t, i, h) = (4usize, 6usize, 7usize, 9usize);
            let (_vm, l) = build(i, h);
            let x = Var::from_tensor(&Tensor::randn(0f32, 1.0, (b, t, i), &Device::Cpu).unwrap()).unwrap();
            let r = Tensor::randn(0f32, 1.0, (b, t, 2 * h), &Device::Cpu).unwrap();
            let lf = (l.forward(x.as_tensor()).unwrap() * &r).unwrap().sqr().unwrap().sum_all().unwrap();
            let lr = (l.forward_reference(x.as_tensor()).unwrap() * &r).unwrap().sqr().unwrap().sum_all().unwrap();
            let gf = lf.backward().unwrap();
            let gr = lr.backward().unwrap();
            for (k, p) in l.tensors().iter().enumerate() {
                let a = gf.get(p).expect("fast grad");
                let c = gr.get(p).expect("reference grad");
                let d = max_abs(a, c);
                let scale = c.abs().unwrap().flatten_all().unwrap().max(0).unwrap().to_scalar::<f32>().unwrap();
                assert!(d < 1e-4 * (1.0 + scale), "param {k}: grad diff {d} (scale {scale})");
            }
            let d = max_abs(gf.get(x.as_tensor()).unwrap(), gr.get(x.as_tensor()).unwrap());
            assert!(d < 1e-4, "input grad diff {d}");
        }
        set_threading(Threading::PerDirection);
    }
}
