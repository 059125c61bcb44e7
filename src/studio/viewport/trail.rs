//! The root's trail on the ground: its geometry, built once per take (simplified for the
//! faded whole, at every frame for the highlighted part), and the part highlighted each frame.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use super::render::{TrailDraw, TrailGeometry, TrailVertex};
use super::{Scene, Viewport};

/// How far the faded trail may stray from the root's path, metres: under a pixel wherever the
/// camera shows a whole body. A ten-minute walk's 15 000 frames make about 3 000 lines then,
/// and a software rasteriser's cost is per line.
const TRAIL_TOLERANCE: f32 = 0.002;

/// The trail of the layers shown, built once per take (and per offset, ground and colours).
pub(super) struct TrailCache {
    key: Vec<(usize, usize, [u32; 3])>,
    ground: u32,
    version: u64,
    geometry: Arc<TrailGeometry>,
    /// Where each layer's full-resolution path starts in `geometry.vertices`.
    full_starts: Vec<u32>,
}

fn next_version() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

impl Viewport {
    /// The trail of the scene's layers: its geometry (made when a layer's take, colours or
    /// offset changes) and, this frame, the highlighted part: the `window` frames up to the
    /// current one.
    pub(super) fn trail(&mut self, scene: &Scene, window: usize) -> TrailDraw {
        let ground = self.ground();
        let key: Vec<_> = scene
            .layers
            .iter()
            .map(|l| (Arc::as_ptr(&l.motion) as usize, Arc::as_ptr(&l.frame_colors) as usize, l.offset.to_array().map(f32::to_bits)))
            .collect();
        if self.trail.as_ref().is_none_or(|c| c.key != key || c.ground != ground.to_bits()) {
            let (geometry, full_starts) = self.trail_geometry(scene, ground);
            self.trail = Some(TrailCache { key, ground: ground.to_bits(), version: next_version(), geometry: Arc::new(geometry), full_starts });
        }
        let cache = self.trail.as_ref().expect("made above");
        let highlighted = scene
            .layers
            .iter()
            .zip(&cache.full_starts)
            .map(|(layer, &start)| {
                let frames = layer.motion.frames();
                if frames < 2 {
                    return 0..0;
                }
                // Line k joins frames k - 1 and k (vertices 2k - 2 and 2k - 1).
                let current = scene.frame.min(frames - 1);
                let (first, last) = (current.saturating_sub(window).max(1), (current + 1).min(frames - 1));
                start + 2 * (first as u32 - 1)..start + 2 * last as u32
            })
            .collect();
        TrailDraw { version: cache.version, geometry: cache.geometry.clone(), highlighted }
    }

    /// Every layer's root path on the ground: simplified for the faded whole, then at every
    /// frame for the highlighted part; and where each layer's full path starts.
    fn trail_geometry(&self, scene: &Scene, ground: f32) -> (TrailGeometry, Vec<u32>) {
        let paths: Vec<Vec<TrailVertex>> = scene
            .layers
            .iter()
            .zip(&self.layers)
            .map(|(layer, info)| {
                let m = &layer.motion;
                let mpu = m.skeleton.meters_per_unit();
                let last = m.frames().saturating_sub(1) as f32;
                (0..m.frames())
                    .map(|t| {
                        let p = m.frame(t)[info.root] * mpu + layer.offset;
                        let [r, g, b] = layer.frame_colors.get(t).copied().unwrap_or([200, 200, 200]);
                        TrailVertex { position: [p.x, ground, p.z], frame: t as f32, last_frame: last, color: [r, g, b, 255] }
                    })
                    .collect()
            })
            .collect();
        let mut vertices = Vec::new();
        for path in &paths {
            let kept = simplify_path(path, TRAIL_TOLERANCE);
            for pair in kept.windows(2) {
                vertices.extend([path[pair[0]], path[pair[1]]]);
            }
        }
        let simplified = vertices.len() as u32;
        let mut full_starts = Vec::new();
        for path in &paths {
            full_starts.push(vertices.len() as u32);
            for pair in path.windows(2) {
                vertices.extend_from_slice(pair);
            }
        }
        (TrailGeometry { vertices, simplified }, full_starts)
    }
}

/// The vertices of a ground path (in order) kept when it may stray `tolerance` metres from
/// it (Ramer-Douglas-Peucker on x and z), always the first and last, and both ends of every
/// change of colour (so the simplified path's colours change where the take's do).
fn simplify_path(path: &[TrailVertex], tolerance: f32) -> Vec<usize> {
    if path.len() < 2 {
        return Vec::new();
    }
    let xz = |k: usize| glam::Vec2::new(path[k].position[0], path[k].position[2]);
    let mut keep = vec![false; path.len()];
    keep[0] = true;
    keep[path.len() - 1] = true;
    for t in 1..path.len() {
        if path[t].color != path[t - 1].color {
            keep[t - 1] = true;
            keep[t] = true;
        }
    }
    let anchors: Vec<usize> = (0..path.len()).filter(|&k| keep[k]).collect();
    let mut stack: Vec<(usize, usize)> = anchors.windows(2).map(|w| (w[0], w[1])).collect();
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (pa, pb) = (xz(a), xz(b));
        let along = pb - pa;
        let length = along.length();
        let distance = |k: usize| {
            let d = xz(k) - pa;
            if length > 1e-6 { along.perp_dot(d).abs() / length } else { d.length() }
        };
        let (far, dist) = (a + 1..b).map(|k| (k, distance(k))).fold((a, -1.0f32), |best, c| if c.1 > best.1 { c } else { best });
        if dist > tolerance {
            keep[far] = true;
            stack.push((a, far));
            stack.push((far, b));
        }
    }
    (0..path.len()).filter(|&k| keep[k]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vertex(x: f32, z: f32, color: u8) -> TrailVertex {
        TrailVertex { position: [x, 0.0, z], frame: 0.0, last_frame: 0.0, color: [color, 0, 0, 255] }
    }

    #[test]
    fn simplified_path_keeps_corners_and_colour_changes() {
        // A straight line with a 5 mm bump at 3, a corner at 6, a colour change between 8 and 9.
        let mut path: Vec<TrailVertex> = (0..=6).map(|k| vertex(k as f32 * 0.1, if k == 3 { 0.005 } else { 0.0 }, 1)).collect();
        path.extend((1..=2).map(|k| vertex(0.6, k as f32 * 0.1, 1)));
        path.extend((3..=5).map(|k| vertex(0.6, k as f32 * 0.1, 2)));
        assert_eq!(simplify_path(&path, 0.002), vec![0, 2, 3, 4, 6, 8, 9, 11]);
        assert_eq!(simplify_path(&path, 0.01), vec![0, 6, 8, 9, 11]);
        assert_eq!(simplify_path(&path[..1], 0.01), Vec::<usize>::new());
    }
}
