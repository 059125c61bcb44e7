//! The 2D map of the seed bank: an exact t-SNE (the `bhtsne` crate) of GloGen's encoder
//! embeddings, and the projection of new embeddings (a generated take's blocks) into it.
//!
//! Everything here is deterministic: the embedding starts from a fixed pseudo-random layout
//! and the fit runs on one thread, so the same model always gives the same map.

use anyhow::{bail, Result};

/// Iterations of the fit.
pub const EPOCHS: usize = 500;
/// Target perplexity (lowered automatically for very small seed banks).
pub const PERPLEXITY: f32 = 15.0;
/// Neighbours used to place a new point in the map.
pub const PROJECT_K: usize = 5;

/// Embeds `points` (all the same length) in 2D. Needs at least 4 points.
pub fn tsne_2d(points: &[Vec<f32>], seed: u64) -> Result<Vec<[f32; 2]>> {
    let n = points.len();
    if n < 4 {
        bail!("the seed bank has {n} seeds; the map needs at least 4");
    }
    // bhtsne panics unless n - 1 >= 3 * perplexity.
    let perplexity = PERPLEXITY.min(((n - 1) / 3) as f32).max(1.0);
    let samples: Vec<&[f32]> = points.iter().map(Vec::as_slice).collect();
    let mut rng = XorShift::new(seed);
    let init: Vec<f32> = (0..n * 2).map(|_| 1e-4 * rng.next_signed()).collect();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let y = pool.install(|| {
        let mut tsne: bhtsne::tSNE<f32, &[f32]> = bhtsne::tSNE::new(&samples);
        tsne.perplexity(perplexity).epochs(EPOCHS).initial_embedding(init).exact(|a, b| squared_distance(a, b));
        tsne.embedding()
    });
    if y.iter().any(|v| !v.is_finite()) {
        bail!("the t-SNE fit diverged");
    }
    Ok(y.chunks_exact(2).map(|p| [p[0], p[1]]).collect())
}

/// Places each of `queries` in the map: the inverse-distance weighted mean of the 2D
/// positions of its `k` nearest neighbours among `points` (whose map positions are `map`).
/// t-SNE has no out-of-sample mapping; this keeps a new point next to the seeds it
/// resembles, which is what the path through the map is meant to show.
pub fn project(queries: &[Vec<f32>], points: &[Vec<f32>], map: &[[f32; 2]], k: usize) -> Vec<[f32; 2]> {
    queries
        .iter()
        .map(|q| {
            let mut d: Vec<(f32, usize)> = points.iter().enumerate().map(|(i, p)| (squared_distance(q, p).sqrt(), i)).collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (mut x, mut y, mut w) = (0.0, 0.0, 0.0);
            for &(dist, i) in d.iter().take(k.max(1)) {
                let wi = 1.0 / (dist + 1e-6);
                x += wi * map[i][0];
                y += wi * map[i][1];
                w += wi;
            }
            if w > 0.0 {
                [x / w, y / w]
            } else {
                [0.0, 0.0]
            }
        })
        .collect()
}

fn squared_distance(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

struct XorShift(u64);

impl XorShift {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    fn next_signed(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 23) as f32 - 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two well separated clusters stay separated in the map, and the map is deterministic.
    #[test]
    fn separates_clusters_deterministically() {
        let mut pts = Vec::new();
        for i in 0..20 {
            let c = if i < 10 { 0.0 } else { 50.0 };
            pts.push((0..8).map(|d| c + ((i * 7 + d * 3) % 5) as f32 * 0.1).collect::<Vec<f32>>());
        }
        let a = tsne_2d(&pts, 1).unwrap();
        let b = tsne_2d(&pts, 1).unwrap();
        assert_eq!(a, b);
        let mean = |r: std::ops::Range<usize>| {
            let n = r.len() as f32;
            r.fold([0.0f32; 2], |m, i| [m[0] + a[i][0] / n, m[1] + a[i][1] / n])
        };
        let (m0, m1) = (mean(0..10), mean(10..20));
        let between = ((m0[0] - m1[0]).powi(2) + (m0[1] - m1[1]).powi(2)).sqrt();
        let spread = (0..10).map(|i| ((a[i][0] - m0[0]).powi(2) + (a[i][1] - m0[1]).powi(2)).sqrt()).fold(0.0, f32::max);
        assert!(between > 2.0 * spread, "between {between}, spread {spread}");
        // A query equal to a point lands on it.
        let p = project(&pts[3..4], &pts, &a, 5);
        assert!((p[0][0] - a[3][0]).abs() < 1e-2 && (p[0][1] - a[3][1]).abs() < 1e-2);
    }
}
