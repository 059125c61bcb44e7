//! The hand-written kernels: branch-free exp/sigmoid/tanh, the fused LSTM cell forward and
//! backward, the register-blocked small-batch recurrent product, and a bounds-checked wrapper
//! around `gemm` for everything larger. Every function here takes slices. The only `unsafe` is
//! calling the target-feature builds of the kernels on a CPU that was checked to have the
//! features, and calling `gemm` (raw pointers) once its strided operands were checked to lie
//! inside their slices.
use gemm::Parallelism;

/// A row-major `[rows, cols]` matrix transposed to `[cols, rows]`. gemm streams a right
/// operand stored `[K, N]` row-major as it is, while the transposed view of a PyTorch-layout
/// weight `[N, K]` is repacked on every call: at batch 1 that repacking was a fifth of a block.
pub(super) fn transposed(w: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    let mut t = vec![0f32; rows * cols];
    transpose_into(w, rows, cols, &mut t);
    t
}

/// [`transposed`] into `t` (`rows * cols` values).
pub(super) fn transpose_into(w: &[f32], rows: usize, cols: usize, t: &mut [f32]) {
    for r in 0..rows {
        for c in 0..cols {
            t[c * rows + r] = w[r * cols + c];
        }
    }
}

/// [`transposed`] for each direction's block of two stacked `[rows, cols]` matrices.
pub(super) fn transposed_per_direction(w: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    w.chunks_exact(rows * cols).flat_map(|m| transposed(m, rows, cols)).collect()
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

/// The four gate blocks `[i, f, g, o]`, `h` each, of a `4H` gate vector.
#[inline(always)]
fn gates(v: &[f32], h: usize) -> [&[f32]; 4] {
    let (i, r) = v[..4 * h].split_at(h);
    let (f, r) = r.split_at(h);
    let (g, o) = r.split_at(h);
    [i, f, g, o]
}

/// [`gates`], writable.
#[inline(always)]
fn gates_mut(v: &mut [f32], h: usize) -> [&mut [f32]; 4] {
    let (i, r) = v[..4 * h].split_at_mut(h);
    let (f, r) = r.split_at_mut(h);
    let (g, o) = r.split_at_mut(h);
    [i, f, g, o]
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
    let [zi, zf, zg, zo] = gates(z, h);
    let [gi, gf, gg, go] = gates(g, h);
    let [bi, bf, bg, bo] = gates(bias, h);
    let [ai, af, ag, ao] = gates_mut(acts, h);
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
    let [ai, af, ag, ao] = gates(acts, h);
    let [di, df, dg, dout_gate] = gates_mut(dz, h);
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

/// `z_r[n] += sum_k h_r[k] * wt[k, n]` for `R` batch rows at once (the small-batch recurrent
/// product with `W_hhᵀ` stored `[H, 4H]`). Register-blocked over column chunks so the
/// accumulators stay in registers and only the weights stream from memory, once for all `R`
/// rows: batch-1 inference is bound by that stream, so a guided block's second and third
/// passes (the unconditioned one, a contrast's) are nearly free.
#[inline(always)]
fn axpy_rows_n<const R: usize>(hs: [&[f32]; R], wt: &[f32], mut zs: [&mut [f32]; R]) {
    #[inline(always)]
    fn chunk<const R: usize, const C: usize>(hs: &[&[f32]; R], wt: &[f32], zs: &mut [&mut [f32]; R], j: usize) {
        let n = zs[0].len();
        let mut acc = [[0f32; C]; R];
        for (a, z) in acc.iter_mut().zip(zs.iter()) {
            a.copy_from_slice(&z[j..j + C]);
        }
        for k in 0..hs[0].len() {
            let row: &[f32; C] = wt[k * n + j..k * n + j + C].try_into().unwrap();
            for (a, h) in acc.iter_mut().zip(hs) {
                let hv = h[k];
                for c in 0..C {
                    a[c] += hv * row[c];
                }
            }
        }
        for (a, z) in acc.iter().zip(zs.iter_mut()) {
            z[j..j + C].copy_from_slice(a);
        }
    }
    let (n, k) = (zs[0].len(), hs[0].len());
    assert!(hs.iter().all(|h| h.len() == k) && zs.iter().all(|z| z.len() == n) && wt.len() >= k * n);
    let mut j = 0;
    while j + 128 <= n {
        chunk::<R, 128>(&hs, wt, &mut zs, j);
        j += 128;
    }
    while j + 32 <= n {
        chunk::<R, 32>(&hs, wt, &mut zs, j);
        j += 32;
    }
    while j + 8 <= n {
        chunk::<R, 8>(&hs, wt, &mut zs, j);
        j += 8;
    }
    while j < n {
        chunk::<R, 1>(&hs, wt, &mut zs, j);
        j += 1;
    }
}

#[inline(always)]
fn axpy_rows_impl(hk: &[f32], wt: &[f32], z: &mut [f32]) {
    axpy_rows_n([hk], wt, [z]);
}

#[inline(always)]
fn axpy_rows2_impl(ha: &[f32], hb: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32]) {
    axpy_rows_n([ha, hb], wt, [za, zb]);
}

#[inline(always)]
fn axpy_rows3_impl(ha: &[f32], hb: &[f32], hc: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32], zc: &mut [f32]) {
    axpy_rows_n([ha, hb, hc], wt, [za, zb, zc]);
}

/// Defines `$name`, which runs `$impl_` compiled for AVX-512 or AVX2+FMA when the CPU has them
/// (the loops above are written to auto-vectorise) and as plain code otherwise. `$impl_` must
/// be `#[inline(always)]`, so that it is compiled inside each build.
macro_rules! dispatch_simd {
    ($name:ident, $impl_:ident, ($($arg:ident : $ty:ty),*)) => {
        #[allow(clippy::too_many_arguments)]
        #[inline]
        pub(super) fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                fn v4($($arg: $ty),*) { $impl_($($arg),*) }
                #[target_feature(enable = "avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                fn v3($($arg: $ty),*) { $impl_($($arg),*) }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: `v4` only differs from `$impl_` in using AVX-512F/AVX2/FMA
                    // instructions; the CPU was just detected to have AVX-512F, and every
                    // AVX-512F CPU has AVX2 and FMA.
                    return unsafe { v4($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: `v3` needs AVX2 and FMA, both just detected on this CPU.
                    return unsafe { v3($($arg),*) };
                }
            }
            $impl_($($arg),*)
        }
    };
}

// for the other elementwise kernels of training (dropout, AdamW)
pub(crate) use dispatch_simd;

dispatch_simd!(cell_fwd, cell_fwd_impl, (h: usize, z: &[f32], g: &[f32], bias: &[f32], c_prev: &[f32], acts: &mut [f32], c: &mut [f32], hout: &mut [f32]));
dispatch_simd!(cell_bwd, cell_bwd_impl, (h: usize, dout: &[f32], dh_rec: &[f32], dc: &mut [f32], acts: &[f32], c: &[f32], c_prev: &[f32], dz: &mut [f32]));
dispatch_simd!(axpy_rows, axpy_rows_impl, (hk: &[f32], wt: &[f32], z: &mut [f32]));
dispatch_simd!(axpy_rows2, axpy_rows2_impl, (ha: &[f32], hb: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32]));
dispatch_simd!(axpy_rows3, axpy_rows3_impl, (ha: &[f32], hb: &[f32], hc: &[f32], wt: &[f32], za: &mut [f32], zb: &mut [f32], zc: &mut [f32]));

/// A matrix read from a slice: element `(r, c)` at `r * row_stride + c * col_stride`.
#[derive(Clone, Copy)]
pub(crate) struct Strided<'a> {
    data: &'a [f32],
    row_stride: usize,
    col_stride: usize,
}

impl<'a> Strided<'a> {
    /// Row-major, `row_stride` apart.
    pub(crate) fn rows(data: &'a [f32], row_stride: usize) -> Self {
        Self { data, row_stride, col_stride: 1 }
    }

    /// The transpose of a row-major matrix whose rows are `row_stride` apart.
    pub(crate) fn transpose_of(data: &'a [f32], row_stride: usize) -> Self {
        Self { data, row_stride: 1, col_stride: row_stride }
    }

    /// Whether a `[rows, cols]` matrix at these strides lies inside the slice.
    fn covers(&self, rows: usize, cols: usize) -> bool {
        rows == 0 || cols == 0 || (rows - 1) * self.row_stride + (cols - 1) * self.col_stride < self.data.len()
    }
}

/// `dst[m, n] = lhs[m, k] · rhs[k, n]` (`+=` when `accumulate`), `dst` row-major with its rows
/// `dst_stride` apart. Panics if an operand does not fit its slice.
#[inline]
pub(crate) fn matmul(
    (m, n, k): (usize, usize, usize),
    dst: &mut [f32],
    dst_stride: usize,
    lhs: Strided,
    rhs: Strided,
    accumulate: bool,
    par: Parallelism,
) {
    assert!(
        m == 0 || n == 0 || (n <= dst_stride && (m - 1) * dst_stride + n <= dst.len()),
        "matmul: a [{m}, {n}] destination {dst_stride} apart does not fit {} values",
        dst.len()
    );
    assert!(lhs.covers(m, k) && rhs.covers(k, n), "matmul: an operand does not fit its slice");
    // SAFETY: gemm reads `lhs` at `r * row_stride + c * col_stride` for r < m, c < k and `rhs`
    // likewise for r < k, c < n, and writes `dst` at `r * dst_stride + c` for r < m, c < n; the
    // asserts above put the largest of those offsets inside each slice (strides are
    // non-negative, so the largest is the last element). `dst` is a unique borrow, so it aliases
    // neither operand, and `n <= dst_stride` keeps its rows apart, so no element is written by
    // two of gemm's threads.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            dst_stride as isize,
            accumulate,
            lhs.data.as_ptr(),
            lhs.col_stride as isize,
            lhs.row_stride as isize,
            rhs.data.as_ptr(),
            rhs.col_stride as isize,
            rhs.row_stride as isize,
            1.0f32,
            1.0f32,
            false,
            false,
            false,
            par,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
