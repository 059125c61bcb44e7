//! How the training process uses the allocator.
//!
//! A training step allocates and frees megabytes of short-lived buffers: candle's tensors
//! (every gradient in its backprop is a fresh `zeros_like` plus an `add`), the fused ops'
//! outputs and caches. With glibc's defaults the largest come from `mmap` and go back with
//! `munmap`, and the heaps of rayon's threads are trimmed with `madvise`, so every step faults
//! its pages in afresh: perf showed ~10 000 page faults a step, 12% of the CPU time in the
//! kernel and ~17% of the samples under page faults (docs/history/benchmarks-2026-12-01.md,
//! "Training against PyTorch"). Keeping freed memory in the heaps lets the next step reuse it.

/// Largest allocation still served from the heaps (glibc's ceiling for this setting on
/// 64-bit); a training step's largest buffer is a few MB.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: libc::c_int = 32 << 20;
/// Free memory a heap keeps before trimming: above a step's working set, so the memory a step
/// frees stays for the next one, and a bound on what an idle process holds.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TRIM_THRESHOLD: libc::c_int = 512 << 20;

/// Makes the allocator keep freed memory for reuse (see the module comment). Process-wide and
/// idempotent; the training loop and the training benchmark call it before their first step.
/// Does nothing off glibc.
pub fn retain_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes two of glibc's allocator parameters; it is safe to call at any
    // time from any thread.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
    }
}
