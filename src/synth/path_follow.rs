//! A take's locomotion laid along a root path, after Gleicher's motion path editing (2001):
//! the root's travel is split into a smooth centre line and the sway about it; the centre is
//! moved onto the path at the arc length the take itself walks (or the waypoints' times ask),
//! and each frame's body is turned by the angle between the path's tangent and the take's own
//! direction of travel there. The body's motion relative to its travel stays the class's
//! (a sideways or backwards walk stays one), only where it goes changes.

use glam::{Quat, Vec2, Vec3};

use super::constraints::RootPath;
use super::plan::TakeConstraint;
use crate::data::features::{wrap, FeatureLayout};

/// Radius (metres) of the arcs that round the path's corners: a walker turns a corner over
/// about a step, not on the spot (a 90-degree corner's arc passes 17 cm from the corner,
/// 12 cm from the drawn legs).
const CORNER_RADIUS_M: f32 = 0.4;

/// Half-width (seconds) of the moving average that separates the root's travel from its sway.
const CENTRE_SMOOTH_SECONDS: f32 = 0.25;

/// Half-width (seconds) of the moving average over each frame's turn: the take's own
/// direction of travel wavers with its steps, and a body turned by every waver jerks.
const TURN_SMOOTH_SECONDS: f32 = 0.5;

/// Below this speed (m/s) the take is not travelling and has no direction of its own: the
/// turn found while it last travelled holds.
const MIN_TRAVEL_M_S: f32 = 0.15;

/// Speed a path may ask of the take, as a multiple of its own speed there, before the user
/// is told the class cannot follow it (the feet would visibly slide beyond this).
const SPEED_RATIO_LIMIT: f32 = 2.0;

/// Metres between the points the path's arcs are sampled at.
const ARC_STEP_M: f32 = 0.02;

/// The path on the ground in the model's units, corners rounded, sampled densely.
pub struct GroundPath {
    points: Vec<Vec2>,
    /// Arc length at each point.
    arc: Vec<f32>,
    /// Arc length at each waypoint (a rounded corner's waypoint sits at its arc's middle).
    waypoint_arc: Vec<f32>,
    /// Each waypoint's time, where it has one.
    waypoint_seconds: Vec<Option<f32>>,
}

impl GroundPath {
    pub fn new(path: &RootPath, units_per_metre: f32) -> Self {
        let radius = CORNER_RADIUS_M * units_per_metre;
        let step = ARC_STEP_M * units_per_metre;
        let w: Vec<Vec2> = path.waypoints.iter().map(|p| Vec2::new(p.x, p.z) * units_per_metre).collect();
        let mut points = vec![w[0]];
        let mut waypoint_index = vec![0];
        for i in 1..w.len() - 1 {
            let (inc, out) = (w[i] - w[i - 1], w[i + 1] - w[i]);
            let turn = inc.angle_to(out);
            let (li, lo) = (inc.length(), out.length());
            // The arc's tangent points lie `cut` before and after the corner, no further than
            // most of each leg.
            let cut = (radius * (turn.abs() / 2.0).tan()).min(0.45 * li.min(lo));
            if turn.abs() < 1e-3 || li < 1e-6 || lo < 1e-6 || cut < 1e-6 {
                points.push(w[i]);
                waypoint_index.push(points.len() - 1);
                continue;
            }
            let a = w[i] - inc / li * cut;
            let r = cut / (turn.abs() / 2.0).tan();
            let normal = inc.perp().normalize() * turn.signum();
            let centre = a + normal * r;
            let samples = ((r * turn.abs()) / step).ceil().max(2.0) as usize;
            let start = a - centre;
            for k in 0..=samples {
                points.push(centre + Vec2::from_angle(turn * k as f32 / samples as f32).rotate(start));
                if k == samples / 2 {
                    waypoint_index.push(points.len() - 1);
                }
            }
        }
        points.push(w[w.len() - 1]);
        waypoint_index.push(points.len() - 1);
        let arc = arc_lengths(&points);
        let waypoint_arc = waypoint_index.iter().map(|&i| arc[i]).collect();
        let waypoint_seconds = path.waypoints.iter().map(|p| p.seconds).collect();
        Self { points, arc, waypoint_arc, waypoint_seconds }
    }

    pub fn length(&self) -> f32 {
        *self.arc.last().expect("non-empty")
    }

    /// The point at arc length `s` and the tangent's heading there (0 along +z, positive
    /// towards +x, as [`FeatureLayout::heading`]); past the end the path goes straight on.
    pub fn at(&self, s: f32) -> (Vec2, f32) {
        let n = self.points.len();
        let i = self.arc.partition_point(|&a| a <= s).clamp(1, n - 1);
        let (a, b) = (self.points[i - 1], self.points[i]);
        let dir = (b - a).normalize_or_zero();
        let point = a + dir * (s - self.arc[i - 1]);
        (point, dir.x.atan2(dir.y))
    }

    /// Distance from `p` to the drawn path (the waypoints' polyline, corners not rounded).
    pub fn distance_to_polyline(waypoints: &[Vec2], p: Vec2) -> f32 {
        waypoints
            .windows(2)
            .map(|w| {
                let d = w[1] - w[0];
                let t = ((p - w[0]).dot(d) / d.length_squared().max(f32::EPSILON)).clamp(0.0, 1.0);
                p.distance(w[0] + d * t)
            })
            .fold(f32::INFINITY, f32::min)
    }
}

/// A root path as a constraint: the paced take's locomotion laid along it.
pub(super) struct PathConstraint {
    pub path: GroundPath,
    pub units_per_metre: f32,
}

impl TakeConstraint for PathConstraint {
    fn on_dense(&self, positions: &mut [Vec3], layout: &FeatureLayout, fps: f32) -> Vec<String> {
        follow_path(positions, layout, fps, &self.path, self.units_per_metre)
    }
}

/// Metres past a path's last waypoint a take may end without a word (its last step).
const PAST_THE_END_M: f32 = 0.1;

/// Lays the take (`joints` per frame, `fps`) along `path`; returns a sentence per stretch
/// where the path's times ask a speed the take cannot walk, and one when the take walks on
/// past the path's end.
pub fn follow_path(positions: &mut [Vec3], layout: &FeatureLayout, fps: f32, path: &GroundPath, units_per_metre: f32) -> Vec<String> {
    let j = layout.joints();
    let frames = positions.len() / j;
    if frames < 2 {
        return Vec::new();
    }
    let root: Vec<Vec2> = (0..frames).map(|f| Vec2::new(positions[f * j].x, positions[f * j].z)).collect();
    let centre = moving_average(&root, (CENTRE_SMOOTH_SECONDS * fps).round() as usize);
    let natural = arc_lengths(&centre);
    let (arc, mut warnings) = schedule(path, &natural, fps, units_per_metre);
    warnings.extend(walked_past_the_end(path, &arc, fps, units_per_metre));
    let turns = turns(path, &centre, &arc, MIN_TRAVEL_M_S * units_per_metre / fps, (TURN_SMOOTH_SECONDS * fps).round() as usize);
    for f in 0..frames {
        let (point, _) = path.at(arc[f]);
        let rot = Quat::from_rotation_y(turns[f]);
        let sway = rot * Vec3::new(root[f].x - centre[f].x, 0.0, root[f].y - centre[f].y);
        let new_root = Vec3::new(point.x, 0.0, point.y) + sway;
        let old_root = Vec3::new(root[f].x, 0.0, root[f].y);
        for p in &mut positions[f * j..(f + 1) * j] {
            *p = new_root + rot * (*p - old_root);
        }
    }
    warnings
}

/// A path the take walks beyond (its segment lasts longer than the path takes to walk) says
/// so: past its last waypoint the take goes on in the last leg's direction.
fn walked_past_the_end(path: &GroundPath, arc: &[f32], fps: f32, units_per_metre: f32) -> Option<String> {
    let end = path.length() + PAST_THE_END_M * units_per_metre;
    let first = arc.iter().position(|&s| s > end)?;
    let beyond = (arc.last()? - path.length()) / units_per_metre;
    Some(format!(
        "the take walks {beyond:.2} m past the path's end ({:.1} m) from {:.1} s on: lengthen the path or shorten the walk",
        path.length() / units_per_metre,
        first as f32 / fps
    ))
}

fn moving_average<T>(values: &[T], half: usize) -> Vec<T>
where
    T: Copy + Default + std::ops::Add<Output = T> + std::ops::Sub<Output = T> + std::ops::Div<f32, Output = T>,
{
    let n = values.len();
    let mut prefix = vec![T::default()];
    for v in values {
        prefix.push(*prefix.last().expect("non-empty") + *v);
    }
    (0..n)
        .map(|f| {
            // The window shrinks symmetrically at the ends, so the centre starts where the root does.
            let h = half.min(f).min(n - 1 - f);
            (prefix[f + h + 1] - prefix[f - h]) / (2 * h + 1) as f32
        })
        .collect()
}

/// Distance along `points` from the first to each.
pub fn arc_lengths(points: &[Vec2]) -> Vec<f32> {
    let mut arc = Vec::with_capacity(points.len());
    arc.push(0.0);
    for p in points.windows(2) {
        arc.push(arc.last().expect("non-empty") + p[0].distance(p[1]));
    }
    arc
}

/// Arc length along the path at each frame: the take's own travel, stretched between timed
/// waypoints so it passes each at its time (the first waypoint is the take's start).
fn schedule(path: &GroundPath, natural: &[f32], fps: f32, units_per_metre: f32) -> (Vec<f32>, Vec<String>) {
    let frames = natural.len();
    let mut anchors = vec![(0usize, 0.0f32, 1usize)];
    for (i, t) in path.waypoint_seconds.iter().enumerate().skip(1) {
        if let Some(t) = t {
            let f = ((t * fps).round() as usize).min(frames - 1);
            if f > anchors.last().expect("non-empty").0 {
                anchors.push((f, path.waypoint_arc[i], i + 1));
            }
        }
    }
    let mut arc = natural.to_vec();
    let mut warnings = Vec::new();
    for w in anchors.windows(2) {
        let ((fa, sa, ia), (fb, sb, ib)) = (w[0], w[1]);
        let (walked, asked) = (natural[fb] - natural[fa], sb - sa);
        let seconds = (fb - fa) as f32 / fps;
        let ratio = asked / walked.max(f32::EPSILON);
        if !(1.0 / SPEED_RATIO_LIMIT..=SPEED_RATIO_LIMIT).contains(&ratio) && asked > 0.5 * units_per_metre {
            warnings.push(format!(
                "the path asks {:.1} m/s from waypoint {ia} to {ib} ({:.1}-{:.1} s); the take moves at {:.1} m/s there, so its feet will slide (give those waypoints more or less time, or a faster class)",
                asked / units_per_metre / seconds, fa as f32 / fps, fb as f32 / fps, walked / units_per_metre / seconds
            ));
        }
        for f in fa..=fb {
            let share = if walked > 1e-3 * units_per_metre { (natural[f] - natural[fa]) / walked } else { (f - fa) as f32 / (fb - fa) as f32 };
            arc[f] = sa + share * asked;
        }
    }
    let (fl, sl, _) = *anchors.last().expect("non-empty");
    for f in fl..frames {
        arc[f] = sl + natural[f] - natural[fl];
    }
    (arc, warnings)
}

/// The turn of each frame: the path's heading at its arc length less the take's own direction
/// of travel, held where the take stands still, unwrapped so it never jumps a full turn, and
/// smoothed over [`TURN_SMOOTH_SECONDS`].
fn turns(path: &GroundPath, centre: &[Vec2], arc: &[f32], min_step: f32, smooth: usize) -> Vec<f32> {
    let n = centre.len();
    let direction = |f: usize| {
        let d = centre[(f + 1).min(n - 1)] - centre[f.saturating_sub(1)];
        (d.length() > 2.0 * min_step).then(|| d.x.atan2(d.y))
    };
    let raw: Vec<Option<f32>> = (0..n).map(|f| direction(f).map(|own| path.at(arc[f]).1 - own)).collect();
    let first = raw.iter().flatten().next().copied().unwrap_or(path.at(0.0).1);
    let mut held = first;
    let mut out = Vec::with_capacity(n);
    for r in raw {
        if let Some(t) = r {
            held += wrap(t - held);
        }
        out.push(held);
    }
    moving_average(&out, smooth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::constraints::Waypoint;

    fn l_path() -> RootPath {
        let w = |x, z| Waypoint { x, z, seconds: None };
        RootPath { waypoints: vec![w(0.0, 0.0), w(0.0, 4.0), w(3.0, 4.0)] }
    }

    #[test]
    fn the_corner_is_rounded_and_the_path_stays_close() {
        let path = GroundPath::new(&l_path(), 1.0);
        // Two straight legs of 4 and 3 m less the corner's cut, plus its quarter arc.
        let expected = 7.0 - 2.0 * CORNER_RADIUS_M + std::f32::consts::FRAC_PI_2 * CORNER_RADIUS_M;
        assert!((path.length() - expected).abs() < 0.01, "{}", path.length());
        let drawn = [Vec2::new(0.0, 0.0), Vec2::new(0.0, 4.0), Vec2::new(3.0, 4.0)];
        let worst = path.points.iter().map(|p| GroundPath::distance_to_polyline(&drawn, *p)).fold(0.0, f32::max);
        assert!((worst - CORNER_RADIUS_M * (1.0 - std::f32::consts::FRAC_1_SQRT_2)).abs() < 0.01, "{worst}");
        let (start, heading) = path.at(1.0);
        assert!(start.distance(Vec2::new(0.0, 1.0)) < 1e-4 && heading.abs() < 1e-4);
        let (end, heading) = path.at(path.length() + 1.0);
        assert!(end.distance(Vec2::new(4.0, 4.0)) < 1e-3 && (heading - std::f32::consts::FRAC_PI_2).abs() < 1e-3);
    }
}
