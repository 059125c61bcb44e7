//! One direction's forward recurrence over time, shared by the training op and the frozen
//! inference path: per step the recurrent product `h_{t-1} · W_hhᵀ` (the register-blocked
//! kernels at small batch, gemm above it), then the fused cell for every batch row. Each
//! direction has buffers of its own, so the two can run on two threads with plain borrows.
use super::kernels::{axpy_rows, axpy_rows2, axpy_rows3, cell_fwd, matmul, Strided};
use gemm::Parallelism;

/// Batches up to this size use the register-blocked small-batch kernels.
const SMALL_BATCH: usize = 4;

/// The time index of step `s` of direction `d` (the backward direction walks time in reverse).
#[inline(always)]
pub(super) fn time_at(d: usize, t: usize, s: usize) -> usize {
    if d == 0 {
        s
    } else {
        t - 1 - s
    }
}

/// Buffers and sizes of one direction's forward recurrence. Rows are `bb * T + t` (batch-major).
pub(super) struct DirFwd<'a> {
    pub d: usize,
    pub b: usize,
    pub t: usize,
    pub h: usize,
    /// This direction's projected gates `[B*T, 4H]`, no bias.
    pub g: &'a [f32],
    /// This direction's `W_hhᵀ [H, 4H]`.
    pub whh_t: &'a [f32],
    /// `b_ih + b_hh` of this direction `[4H]`.
    pub bias: &'a [f32],
    /// This direction's hidden states `[B*T, H]` (written).
    pub hs: &'a mut [f32],
    /// Gate activations `[B*T, 4H]` and cells `[B*T, H]` of this direction (written).
    pub acts: &'a mut [f32],
    pub cs: &'a mut [f32],
    /// Scratch `[B*4H]` and zeros `[H]`.
    pub z: &'a mut [f32],
    pub zeros: &'a [f32],
    pub par: Parallelism,
}

impl DirFwd<'_> {
    pub(super) fn run(self) {
        let DirFwd { d, b, t, h, g, whh_t, bias, hs, acts, cs, z, zeros, par } = self;
        let h4 = 4 * h;
        for s in 0..t {
            let tt = time_at(d, t, s);
            let z = &mut z[..b * h4];
            if s == 0 {
                z.fill(0.0);
            } else {
                recurrent_product(b, t, h, time_at(d, t, s - 1), hs, whh_t, z, par);
            }
            for bb in 0..b {
                let row = bb * t + tt;
                let (c_prev, c_now): (&[f32], &mut [f32]) = if s == 0 {
                    (zeros, &mut cs[row * h..(row + 1) * h])
                } else {
                    previous_and_current(cs, bb * t + time_at(d, t, s - 1), row, h)
                };
                cell_fwd(
                    h,
                    &z[bb * h4..(bb + 1) * h4],
                    &g[row * h4..(row + 1) * h4],
                    bias,
                    c_prev,
                    &mut acts[row * h4..(row + 1) * h4],
                    c_now,
                    &mut hs[row * h..(row + 1) * h],
                );
            }
        }
    }
}

/// `z[B, 4H] = h_prev[B, H] · W_hhᵀ`, `h_prev` being the hidden states at time `tp` (rows
/// `bb * T + tp` of `hs [B*T, H]`), from the stored transpose `whh_t [H, 4H]`.
#[allow(clippy::too_many_arguments)]
fn recurrent_product(b: usize, t: usize, h: usize, tp: usize, hs: &[f32], whh_t: &[f32], z: &mut [f32], par: Parallelism) {
    let h4 = 4 * h;
    if b <= SMALL_BATCH {
        z.fill(0.0);
        let hrow = |bb: usize| &hs[(bb * t + tp) * h..(bb * t + tp + 1) * h];
        // Rows in pairs, the last three together: the weights stream once per pair or triple.
        let mut rows = z.chunks_exact_mut(h4).enumerate();
        while let Some((bb, za)) = rows.next() {
            match (rows.next(), rows.len()) {
                (Some((_, zb)), 1) => {
                    let (_, zc) = rows.next().expect("one row left");
                    axpy_rows3(hrow(bb), hrow(bb + 1), hrow(bb + 2), whh_t, za, zb, zc);
                }
                (Some((_, zb)), _) => axpy_rows2(hrow(bb), hrow(bb + 1), whh_t, za, zb),
                (None, _) => axpy_rows(hrow(bb), whh_t, za),
            }
        }
    } else {
        let h_prev = Strided::rows(&hs[tp * h..], t * h);
        matmul((b, h4, h), z, h4, h_prev, Strided::rows(whh_t, h4), false, par);
    }
}

/// Row `prev` of `cs [.., H]` to read and row `cur` to write (`prev != cur`).
pub(super) fn previous_and_current(cs: &mut [f32], prev: usize, cur: usize, h: usize) -> (&[f32], &mut [f32]) {
    if prev < cur {
        let (before, from_cur) = cs.split_at_mut(cur * h);
        (&before[prev * h..(prev + 1) * h], &mut from_cur[..h])
    } else {
        let (before, from_prev) = cs.split_at_mut(prev * h);
        (&from_prev[..h], &mut before[cur * h..(cur + 1) * h])
    }
}

/// `out [B*T, 2H]` from the two directions' hidden states `[B*T, H]` (forward states first).
pub(super) fn interleave(out: &mut [f32], hs: [&[f32]; 2], h: usize) {
    let rows = out.chunks_exact_mut(2 * h).zip(hs[0].chunks_exact(h).zip(hs[1].chunks_exact(h)));
    for (row, (fwd, bwd)) in rows {
        row[..h].copy_from_slice(fwd);
        row[h..].copy_from_slice(bwd);
    }
}
