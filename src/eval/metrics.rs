//! The evaluation measures, as plain functions over `f32` rows (computed in `f64`).
//!
//! - **MMD** (maximum mean discrepancy, the measure of Wang et al. 2019 and SA-GCN): the
//!   unbiased estimate of MMD² with a Gaussian kernel `k(x, y) = exp(-‖x − y‖² / b)`, for
//!   bandwidths `b = 10^k`, `k = −4..=9`, taking the largest value over `b`. `MMD_avg` is the
//!   mean over frames of the per-frame MMD; `MMD_seq` treats each whole sequence, flattened,
//!   as one sample. Callers pass equal numbers of real and generated samples.
//! - **Euclidean distance per frame** (acLSTM's measure): the mean over joints of the distance
//!   between predicted and true joint positions at a time horizon, in the data's own units.
//! - **FID**: the Fréchet distance between Gaussians fitted (mean, covariance) to classifier
//!   features; the matrix square root comes from a Jacobi eigen-decomposition.
//! - **Diversity** and **multimodality** (Action2Motion, Guo et al. 2020): mean distance
//!   between features of random pairs of samples, over all samples and within each class.
//!
//! And the plain statistics the motion and constraint measures share: mean, standard
//! deviation, quantile.

pub use crate::motion::quantile;
use glam::Vec3;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::SeedableRng;

use crate::motion::{JointRoles, Motion, RolesError};

/// Bandwidth exponents of the MMD kernel: `b = 10^k`.
pub const MMD_BANDWIDTH_EXPONENTS: std::ops::RangeInclusive<i32> = -4..=9;

fn sq_dist(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum()
}

/// Unbiased MMD² between the sample sets `x` and `y` (rows of equal length), maximised
/// over the kernel bandwidths. Needs at least two samples in each set.
pub fn mmd2(x: &[&[f32]], y: &[&[f32]]) -> f64 {
    let (n, m) = (x.len(), y.len());
    assert!(n >= 2 && m >= 2, "MMD needs at least two samples per set");
    let pairs = |a: &[&[f32]], b: &[&[f32]], same: bool| -> Vec<f64> {
        let mut d = Vec::new();
        for i in 0..a.len() {
            for j in 0..b.len() {
                if same && i == j {
                    continue;
                }
                if same && j < i {
                    continue;
                }
                d.push(sq_dist(a[i], b[j]));
            }
        }
        d
    };
    let (dxx, dyy, dxy) = (pairs(x, x, true), pairs(y, y, true), pairs(y, x, false));
    MMD_BANDWIDTH_EXPONENTS
        .map(|k| {
            let b = 10f64.powi(k);
            let s = |d: &[f64]| d.iter().map(|v| (-v / b).exp()).sum::<f64>();
            // Unordered pairs counted once: the sum over i != j is twice that.
            let kxx = 2.0 * s(&dxx) / (n * (n - 1)) as f64;
            let kyy = 2.0 * s(&dyy) / (m * (m - 1)) as f64;
            let kxy = s(&dxy) / (n * m) as f64;
            kxx + kyy - 2.0 * kxy
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// MMD_avg and MMD_seq of two sets of sequences, each `frames * frame_dim` long.
pub fn mmd_avg_seq(real: &[Vec<f32>], generated: &[Vec<f32>], frame_dim: usize) -> (f64, f64) {
    let frames = real[0].len() / frame_dim;
    let mut avg = 0.0;
    for f in 0..frames {
        let r: Vec<&[f32]> = real.iter().map(|s| &s[f * frame_dim..(f + 1) * frame_dim]).collect();
        let g: Vec<&[f32]> = generated.iter().map(|s| &s[f * frame_dim..(f + 1) * frame_dim]).collect();
        avg += mmd2(&r, &g);
    }
    let r: Vec<&[f32]> = real.iter().map(|s| s.as_slice()).collect();
    let g: Vec<&[f32]> = generated.iter().map(|s| s.as_slice()).collect();
    (avg / frames as f64, mmd2(&r, &g))
}

/// Mean over joints of the distance between two poses.
pub fn pose_error(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q) as f64).sum::<f64>() / a.len() as f64
}

/// The pose at time `seconds` of frames sampled every `1 / fps` seconds from time 0, by
/// linear interpolation between the two nearest frames (clamped at the last frame).
pub fn pose_at(frames: &[Vec3], joints: usize, fps: f32, seconds: f32) -> Vec<Vec3> {
    let n = frames.len() / joints;
    let f = (seconds as f64 * fps as f64).max(0.0);
    let a = (f.floor() as usize).min(n - 1);
    let b = (a + 1).min(n - 1);
    let w = (f - a as f64) as f32;
    frames[a * joints..(a + 1) * joints].iter().zip(&frames[b * joints..(b + 1) * joints]).map(|(p, q)| p.lerp(*q, w)).collect()
}

/// The horizons of the CMU table: 80, 160, ..., 640 ms.
pub const HORIZONS_MS: [u32; 8] = [80, 160, 240, 320, 400, 480, 560, 640];

/// Per-horizon error of a prediction. `pred` and `truth` are frames at `fps` whose frame 0
/// is the last observed pose (time 0), so frame `k` is `k / fps` seconds into the future.
pub fn horizon_errors(pred: &[Vec3], truth: &[Vec3], joints: usize, pred_fps: f32, truth_fps: f32) -> [f64; 8] {
    HORIZONS_MS.map(|ms| {
        let s = ms as f32 / 1000.0;
        pose_error(&pose_at(pred, joints, pred_fps, s), &pose_at(truth, joints, truth_fps, s))
    })
}

/// Mean and (unbiased) covariance of feature rows.
pub fn mean_cov(rows: &[Vec<f32>]) -> (Vec<f64>, Vec<f64>) {
    let n = rows.len();
    let d = rows[0].len();
    let mut mean = vec![0.0; d];
    for r in rows {
        for (m, v) in mean.iter_mut().zip(r) {
            *m += *v as f64 / n as f64;
        }
    }
    let mut cov = vec![0.0; d * d];
    for r in rows {
        let c: Vec<f64> = r.iter().zip(&mean).map(|(v, m)| *v as f64 - m).collect();
        for i in 0..d {
            for j in i..d {
                cov[i * d + j] += c[i] * c[j];
            }
        }
    }
    let denom = (n.max(2) - 1) as f64;
    for i in 0..d {
        for j in i..d {
            let v = cov[i * d + j] / denom;
            cov[i * d + j] = v;
            cov[j * d + i] = v;
        }
    }
    (mean, cov)
}

/// Eigen-decomposition of a symmetric `d × d` matrix (row-major) by cyclic Jacobi rotations:
/// (eigenvalues, eigenvectors as the columns of a row-major matrix).
pub fn symmetric_eigen(a: &[f64], d: usize) -> (Vec<f64>, Vec<f64>) {
    let mut a = a.to_vec();
    let mut v = vec![0.0; d * d];
    for i in 0..d {
        v[i * d + i] = 1.0;
    }
    let scale: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
    for _sweep in 0..100 {
        let off: f64 = (0..d).flat_map(|i| (0..d).filter(move |&j| j != i).map(move |j| (i, j))).map(|(i, j)| a[i * d + j].powi(2)).sum();
        if off.sqrt() <= 1e-14 * scale {
            break;
        }
        for p in 0..d {
            for q in p + 1..d {
                let apq = a[p * d + q];
                if apq.abs() <= 1e-300 {
                    continue;
                }
                let (app, aqq) = (a[p * d + p], a[q * d + q]);
                let theta = (aqq - app) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..d {
                    let (akp, akq) = (a[k * d + p], a[k * d + q]);
                    a[k * d + p] = c * akp - s * akq;
                    a[k * d + q] = s * akp + c * akq;
                }
                for k in 0..d {
                    let (apk, aqk) = (a[p * d + k], a[q * d + k]);
                    a[p * d + k] = c * apk - s * aqk;
                    a[q * d + k] = s * apk + c * aqk;
                }
                for k in 0..d {
                    let (vkp, vkq) = (v[k * d + p], v[k * d + q]);
                    v[k * d + p] = c * vkp - s * vkq;
                    v[k * d + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..d).map(|i| a[i * d + i]).collect(), v)
}

/// The symmetric positive semi-definite square root of a symmetric matrix (negative
/// eigenvalues, from rounding, are clipped to zero).
pub fn sqrtm_symmetric(a: &[f64], d: usize) -> Vec<f64> {
    let (w, v) = symmetric_eigen(a, d);
    let s: Vec<f64> = w.iter().map(|x| x.max(0.0).sqrt()).collect();
    let mut out = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..d {
            out[i * d + j] = (0..d).map(|k| v[i * d + k] * s[k] * v[j * d + k]).sum();
        }
    }
    out
}

fn matmul(a: &[f64], b: &[f64], d: usize) -> Vec<f64> {
    let mut out = vec![0.0; d * d];
    for i in 0..d {
        for k in 0..d {
            let aik = a[i * d + k];
            if aik == 0.0 {
                continue;
            }
            for j in 0..d {
                out[i * d + j] += aik * b[k * d + j];
            }
        }
    }
    out
}

/// Fréchet distance between Gaussians fitted to two sets of feature rows:
/// `‖μ₁ − μ₂‖² + tr(Σ₁ + Σ₂ − 2 (Σ₁^½ Σ₂ Σ₁^½)^½)`.
pub fn fid(a: &[Vec<f32>], b: &[Vec<f32>]) -> f64 {
    let d = a[0].len();
    let (m1, s1) = mean_cov(a);
    let (m2, s2) = mean_cov(b);
    let mean_term: f64 = m1.iter().zip(&m2).map(|(x, y)| (x - y).powi(2)).sum();
    let r1 = sqrtm_symmetric(&s1, d);
    let mut inner = matmul(&matmul(&r1, &s2, d), &r1, d);
    // Symmetrise against rounding before the eigen-decomposition.
    for i in 0..d {
        for j in i + 1..d {
            let v = 0.5 * (inner[i * d + j] + inner[j * d + i]);
            inner[i * d + j] = v;
            inner[j * d + i] = v;
        }
    }
    let (w, _) = symmetric_eigen(&inner, d);
    let tr_sqrt: f64 = w.iter().map(|x| x.max(0.0).sqrt()).sum();
    let tr: f64 = (0..d).map(|i| s1[i * d + i] + s2[i * d + i]).sum();
    (mean_term + tr - 2.0 * tr_sqrt).max(0.0)
}

fn dist(a: &[f32], b: &[f32]) -> f64 {
    sq_dist(a, b).sqrt()
}

/// Action2Motion's diversity: two random subsets of `pairs` samples (with the same seed,
/// reproducible), mean distance between paired features.
pub fn diversity(features: &[Vec<f32>], pairs: usize, seed: u64) -> f64 {
    let mut rng = StdRng::seed_from_u64(seed);
    let n = features.len();
    let pairs = pairs.min(n);
    let mut idx: Vec<usize> = (0..n).collect();
    idx.shuffle(&mut rng);
    let first = idx[..pairs].to_vec();
    idx.shuffle(&mut rng);
    let second = idx[..pairs].to_vec();
    first.iter().zip(&second).map(|(&i, &j)| dist(&features[i], &features[j])).sum::<f64>() / pairs as f64
}

/// Action2Motion's multimodality: per class, the diversity of `pairs` random pairs within
/// the class; averaged over classes that have at least two samples.
pub fn multimodality(features: &[Vec<f32>], labels: &[usize], classes: usize, pairs: usize, seed: u64) -> f64 {
    let mut sum = 0.0;
    let mut count = 0;
    for k in 0..classes {
        let of: Vec<Vec<f32>> = features.iter().zip(labels).filter(|(_, &l)| l == k).map(|(f, _)| f.clone()).collect();
        if of.len() < 2 {
            continue;
        }
        sum += diversity(&of, pairs, seed.wrapping_add(k as u64));
        count += 1;
    }
    sum / count.max(1) as f64
}

/// Fraction of predictions equal to their labels.
pub fn accuracy(predicted: &[usize], labels: &[usize]) -> f64 {
    predicted.iter().zip(labels).filter(|(p, l)| p == l).count() as f64 / labels.len().max(1) as f64
}

/// The mean of `v`, NaN when it is empty.
pub fn mean(v: &[f32]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64
    }
}

/// The population standard deviation of `v`.
pub fn std_dev(v: &[f32]) -> f32 {
    let m = mean(v);
    (v.iter().map(|x| (*x as f64 - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt() as f32
}

/// Long-take statistics of one window.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WindowStats {
    pub start_s: f32,
    /// Mean joint speed over the class's mean joint speed in the real training data.
    pub speed_ratio: f32,
    /// Mean relative bone-length deviation from the rest skeleton.
    pub bone_error: f32,
    pub finite: bool,
}

/// Per `window_s`-second window of a take: speed ratio, bone-length error, finiteness.
pub fn window_stats(m: &Motion, window_s: f32, class_speed: f32, min_bone: f32) -> Vec<WindowStats> {
    let w = (window_s * m.fps).round() as usize;
    let mut out = Vec::new();
    let mut start = 0;
    while start + w <= m.frames() {
        let part = m.slice(start, start + w);
        let finite = part.positions().iter().all(|p| p.is_finite());
        out.push(WindowStats {
            start_s: start as f32 / m.fps,
            speed_ratio: crate::model::corpus::mean_joint_speed(&part) / class_speed.max(1e-6),
            bone_error: part.bone_length_error(min_bone),
            finite,
        });
        start += w;
    }
    out
}

/// The window (seconds) over which the hips' climb is measured ([`fastest_rise`]).
const RISE_WINDOW_S: f32 = 0.2;

/// The fastest the hips climb (metres a second) over any [`RISE_WINDOW_S`] of `m` from frame
/// `from` on: a body that stands up without pushing through its feet rises faster than any
/// real one.
pub fn fastest_rise(m: &Motion, from: usize) -> Result<f32, RolesError> {
    let hips = JointRoles::new(&m.skeleton)?.body_root;
    let unit = m.skeleton.meters_per_unit();
    let span = ((RISE_WINDOW_S * m.fps).round() as usize).max(1);
    let seconds = span as f32 / m.fps;
    let height = |t: usize| m.frame(t)[hips].y * unit;
    Ok((from..m.frames().saturating_sub(span)).map(|t| (height(t + span) - height(t)) / seconds).fold(0.0, f32::max))
}
