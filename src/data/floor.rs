//! Levelling a take on the floor its feet stand on.
//!
//! Human3.6M stores no absolute orientation, so a rebuilt take must be levelled somehow. The
//! torso is a poor reference (people lean: levelled by the mean hips-to-neck direction the
//! real clips stand on floors tilted 2.5-6 degrees, 16-23 when seated). The floor itself is a
//! good one: a plane fitted through the positions where a toe stands still.

use glam::{Quat, Vec3};

use crate::motion::Motion;

/// A toe moving slower than this (m/s) is standing.
const STILL_SPEED: f32 = 0.2;
/// Fewer standing toe samples than this (about half a second at 50 fps) cannot fix a plane.
const MIN_POINTS: usize = 25;
/// Spread of the foot positions (m) below which the tilt is pulled towards level: two feet a
/// shoulder apart cannot tell a tilt from a toe held a centimetre higher.
const SLOPE_PRIOR: f32 = 0.1;
/// Outlier rejection: a toe further than this (m) from the plane is not on the floor (a foot
/// held still in the air, a crossed leg); each pass refits without them.
const INLIER_PASSES: [f32; 3] = [0.08, 0.04, 0.025];

/// The floor found under a take, in the take's own units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floor {
    /// Rotates the take so that the floor is horizontal.
    pub levelling: Quat,
    /// The floor's height after `levelling`.
    pub height: f32,
    /// Standing toe samples the plane rests on.
    pub support: usize,
}

/// Fits the floor through the still samples of the `toes` joints, or `None` when the toes
/// never stand still long enough to fix a plane.
pub fn fit_floor(motion: &Motion, toes: &[usize]) -> Option<Floor> {
    let still = STILL_SPEED / motion.skeleton.meters_per_unit() / motion.fps;
    let mut points = Vec::new();
    for t in 1..motion.frames() {
        let (prev, cur) = (motion.frame(t - 1), motion.frame(t));
        points.extend(toes.iter().filter(|&&j| cur[j].distance(prev[j]) < still).map(|&j| cur[j]));
    }
    let unit = 1.0 / motion.skeleton.meters_per_unit();
    let mut plane = fit_plane(&points, SLOPE_PRIOR * unit)?;
    for limit in INLIER_PASSES {
        let inliers: Vec<Vec3> = points.iter().copied().filter(|p| plane.residual(*p).abs() < limit * unit).collect();
        plane = fit_plane(&inliers, SLOPE_PRIOR * unit)?;
        points = inliers;
    }
    let levelling = Quat::from_rotation_arc(plane.normal(), Vec3::Y);
    let height = points.iter().map(|p| (levelling * *p).y).sum::<f32>() / points.len() as f32;
    Some(Floor { levelling, height, support: points.len() })
}

/// `y = a (x - cx) + b (z - cz) + c`.
#[derive(Clone, Copy, Debug)]
struct Plane {
    a: f32,
    b: f32,
    c: f32,
    cx: f32,
    cz: f32,
}

impl Plane {
    fn residual(&self, p: Vec3) -> f32 {
        p.y - self.a * (p.x - self.cx) - self.b * (p.z - self.cz) - self.c
    }

    fn normal(&self) -> Vec3 {
        Vec3::new(-self.a, 1.0, -self.b).normalize()
    }
}

/// Least squares with a ridge on the slopes: `prior` is the spread of the points (in their
/// units) at which the data and the level prior weigh the same.
fn fit_plane(points: &[Vec3], prior: f32) -> Option<Plane> {
    if points.len() < MIN_POINTS {
        return None;
    }
    let n = points.len() as f64;
    let (cx, cy, cz) = points.iter().fold((0.0, 0.0, 0.0), |s, p| (s.0 + p.x as f64, s.1 + p.y as f64, s.2 + p.z as f64));
    let (cx, cy, cz) = (cx / n, cy / n, cz / n);
    let (mut sxx, mut sxz, mut szz, mut sxy, mut szy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let (x, y, z) = (p.x as f64 - cx, p.y as f64 - cy, p.z as f64 - cz);
        sxx += x * x;
        sxz += x * z;
        szz += z * z;
        sxy += x * y;
        szy += z * y;
    }
    let ridge = n * (prior as f64).powi(2);
    let (sxx, szz) = (sxx + ridge, szz + ridge);
    let det = sxx * szz - sxz * sxz;
    if det.abs() < f64::EPSILON {
        return None;
    }
    let a = (sxy * szz - szy * sxz) / det;
    let b = (szy * sxx - sxy * sxz) / det;
    Some(Plane { a: a as f32, b: b as f32, c: cy as f32, cx: cx as f32, cz: cz as f32 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_through_tilted_points() {
        // A 5-degree slope along x, points spread over 2 m.
        let slope = 5f32.to_radians().tan();
        let points: Vec<Vec3> = (0..100).map(|i| Vec3::new((i % 10) as f32 * 0.2, 0.0, (i / 10) as f32 * 0.2)).map(|p| Vec3::new(p.x, 3.0 + slope * p.x, p.z)).collect();
        let plane = fit_plane(&points, 0.01).expect("enough points");
        assert!((plane.a - slope).abs() < 1e-3, "slope {}", plane.a);
        assert!(plane.b.abs() < 1e-3);
        let level = Quat::from_rotation_arc(plane.normal(), Vec3::Y);
        let heights: Vec<f32> = points.iter().map(|p| (level * *p).y).collect();
        let spread = heights.iter().cloned().fold(f32::MIN, f32::max) - heights.iter().cloned().fold(f32::MAX, f32::min);
        assert!(spread < 1e-3, "levelled points still spread {spread}");
    }

    #[test]
    fn too_few_points_fix_no_plane() {
        assert!(fit_plane(&[Vec3::ZERO; 10], 0.1).is_none());
    }
}
