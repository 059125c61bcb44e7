//! How well a take honours its keys and its root path: the key errors (the body relative to
//! its root, the root on the ground), the jerk around keys against the take elsewhere, and the
//! root's distance from the drawn path with the body's facing along it; the measures of
//! `glocal eval --suite constraints`.

use glam::{Quat, Vec2, Vec3};

use super::metrics::mean;
use crate::data::features::{wrap, FeatureLayout};
use crate::motion::Motion;
use crate::synth::constraints::RootPath;
use crate::synth::path_follow::{arc_lengths, GroundPath};

/// Half-width (seconds) of the stretch around a key whose jerk is compared with the take's.
pub const NEAR_KEY_SECONDS: f32 = 0.5;

/// A take moving slower than this (m/s) has no direction of travel to compare its facing with.
const MIN_TRAVEL_M_S: f32 = 0.3;

/// Per frame (from the first), the largest joint jerk (third difference of world positions,
/// m/s^3); the last three frames have none.
pub fn frame_jerk(m: &Motion) -> Vec<f32> {
    let (n, p) = (m.joints(), m.positions());
    let scale = m.fps.powi(3) * m.skeleton.meters_per_unit();
    (0..m.frames().saturating_sub(3))
        .map(|t| (0..n).map(|j| (p[(t + 3) * n + j] - 3.0 * p[(t + 2) * n + j] + 3.0 * p[(t + 1) * n + j] - p[t * n + j]).length() * scale).fold(0.0, f32::max))
        .collect()
}

/// The peak per-frame jerk within [`NEAR_KEY_SECONDS`] of each of `frames` (mean over
/// them), over the mean peak of the take's windows of the same width that hold none of them.
pub fn jerk_near_frames(m: &Motion, frames: &[usize]) -> f64 {
    let jerk = frame_jerk(m);
    let half = (NEAR_KEY_SECONDS * m.fps).round() as usize;
    // The jerk of frame t spans frames t..t + 3: it is centred on t + 1.
    let window = |f: usize| f.saturating_sub(half + 1)..(f + half).min(jerk.len());
    let peak = |r: std::ops::Range<usize>| jerk[r].iter().copied().fold(0.0f32, f32::max) as f64;
    let near = frames.iter().map(|&f| peak(window(f))).sum::<f64>() / frames.len().max(1) as f64;
    let width = 2 * half + 1;
    let clear = |start: usize| frames.iter().all(|&f| f + half + 3 < start || f > start + width + half + 1);
    let elsewhere: Vec<f64> = (0..jerk.len() / width).map(|w| w * width).filter(|&s| clear(s)).map(|s| peak(s..s + width)).collect();
    near / (elsewhere.iter().sum::<f64>() / elsewhere.len().max(1) as f64).max(f64::EPSILON)
}

/// The largest distance (metres) of a joint of frame `frame` from `pose` relative to their
/// roots, each in its own heading frame, and the roots' distance on the ground.
pub fn key_errors(m: &Motion, layout: &FeatureLayout, frame: usize, pose: &[Vec3]) -> (f32, f32) {
    let have = m.frame(frame.min(m.frames() - 1));
    let (h, kh) = (layout.heading(have), layout.heading(pose));
    let relative = |p: &[Vec3], k: usize, heading: f32| Quat::from_rotation_y(-heading) * (p[k] - p[0]);
    let body = (0..have.len()).map(|k| (relative(have, k, h) - relative(pose, k, kh)).length()).fold(0.0f32, f32::max);
    let d = have[0] - pose[0];
    let unit = m.skeleton.meters_per_unit();
    (body * unit, Vec2::new(d.x, d.z).length() * unit)
}

/// How a take follows a path.
#[derive(Clone, Copy, Debug)]
pub struct PathFit {
    /// The root's distance from the drawn path (metres), mean and largest, over the frames
    /// until the take has walked the path's length.
    pub mean: f32,
    pub max: f32,
    /// Mean angle (degrees) between the body's facing and the path's direction where the
    /// take travels.
    pub facing_degrees: f32,
}

pub fn path_fit(m: &Motion, layout: &FeatureLayout, path: &RootPath) -> PathFit {
    let unit = m.skeleton.meters_per_unit();
    let drawn: Vec<Vec2> = path.waypoints.iter().map(|w| Vec2::new(w.x, w.z)).collect();
    let ground = GroundPath::new(path, 1.0);
    let root: Vec<Vec2> = (0..m.frames()).map(|f| Vec2::new(m.frame(f)[0].x, m.frame(f)[0].z) * unit).collect();
    let walked = arc_lengths(&root);
    let mut distances = Vec::new();
    let mut facing = Vec::new();
    let step = (0.25 * m.fps).round().max(1.0) as usize;
    for f in (0..root.len()).take_while(|&f| walked[f] <= ground.length()) {
        distances.push(GroundPath::distance_to_polyline(&drawn, root[f]));
        let (a, b) = (root[f.saturating_sub(step)], root[(f + step).min(root.len() - 1)]);
        let travel = b - a;
        if travel.length() * m.fps / (2 * step) as f32 > MIN_TRAVEL_M_S {
            let (_, tangent) = ground.at(nearest_arc(&ground, root[f]));
            facing.push(wrap(layout.heading(m.frame(f)) - tangent).abs().to_degrees());
        }
    }
    PathFit { mean: mean(&distances) as f32, max: distances.iter().copied().fold(0.0, f32::max), facing_degrees: mean(&facing) as f32 }
}

/// Arc length of the point of the (rounded) path nearest `p`, to 1 cm.
fn nearest_arc(path: &GroundPath, p: Vec2) -> f32 {
    let samples = (path.length() / 0.01).ceil() as usize;
    (0..=samples).map(|k| k as f32 * 0.01).min_by(|&a, &b| path.at(a).0.distance(p).total_cmp(&path.at(b).0.distance(p))).unwrap_or(0.0)
}
