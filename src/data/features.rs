//! The model's pose features and their exact inverse.
//!
//! Per frame, with the body's heading θ (the horizontal direction perpendicular to the
//! left-to-right hip line) and the root r:
//!
//! | index | feature |
//! |---|---|
//! | 0 | root height r.y |
//! | 1, 2 | root displacement on the ground since the previous sample, in the previous sample's heading frame (x: right, z: forward) |
//! | 3 | heading change since the previous sample (radians) |
//! | 4.. | every other kept joint relative to the root, in this frame's heading frame (x, y, z) |
//!
//! Displacements make walking travel instead of walking in place, and heading-relative
//! joints make a pose mean the same whichever way the body faces. Decoding integrates the
//! displacements and heading changes from a given start, so `decode(encode(x)) == x` up to
//! float rounding. A sample's "previous sample" is `stride` frames earlier: sparse poses use
//! the sparse stride, dense frames use 1.

use std::sync::Arc;

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::motion::{JointRoles, Motion, RolesError, Skeleton};

/// Values per frame before the joints.
pub const ROOT_FEATURES: usize = 4;

/// Where the body is on the ground and which way it faces.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    pub x: f32,
    pub z: f32,
    pub heading: f32,
}

impl Default for Placement {
    fn default() -> Self {
        Self { x: 0.0, z: 0.0, heading: 0.0 }
    }
}

/// How poses become feature vectors for one skeleton.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FeatureLayout {
    /// The model's skeleton (the dataset skeleton's informative joints).
    pub skeleton: Arc<Skeleton>,
    pub left_hip: usize,
    pub right_hip: usize,
}

impl FeatureLayout {
    /// Takes the hips from the skeleton's [`JointRoles`]; an error names the roles it lacks.
    pub fn new(skeleton: Arc<Skeleton>) -> Result<Self, RolesError> {
        let roles = JointRoles::new(&skeleton)?;
        Ok(Self { skeleton, left_hip: roles.left.hip, right_hip: roles.right.hip })
    }

    pub fn joints(&self) -> usize {
        self.skeleton.len()
    }

    pub fn dim(&self) -> usize {
        ROOT_FEATURES + 3 * (self.joints() - 1)
    }

    /// Heading angle of a frame: 0 when facing +z, positive turning towards +x.
    pub fn heading(&self, frame: &[Vec3]) -> f32 {
        crate::motion::facing(frame, self.left_hip, self.right_hip)
    }

    /// Features of `frames` (each `joints` long) taken `stride` frames apart; the first
    /// sample's displacement is measured from `previous` when given, else zero.
    pub fn encode(&self, frames: &[&[Vec3]], previous: Option<&[Vec3]>) -> Vec<f32> {
        let dim = self.dim();
        let mut out = Vec::with_capacity(frames.len() * dim);
        let mut prev = previous.map(|f| (f[0], self.heading(f)));
        for frame in frames {
            let root = frame[0];
            let heading = self.heading(frame);
            let (disp, turn) = match prev {
                Some((p, h)) => (yaw(-h) * Vec3::new(root.x - p.x, 0.0, root.z - p.z), wrap(heading - h)),
                None => (Vec3::ZERO, 0.0),
            };
            out.extend([root.y, disp.x, disp.z, turn]);
            let inv = yaw(-heading);
            for p in &frame[1..] {
                out.extend((inv * (*p - root)).to_array());
            }
            prev = Some((root, heading));
        }
        out
    }

    /// Features of a whole motion sampled every `stride` frames from `start`.
    pub fn encode_motion(&self, motion: &Motion, start: usize, stride: usize, count: usize) -> Vec<f32> {
        let frames: Vec<&[Vec3]> = (0..count).map(|k| motion.frame(start + k * stride)).collect();
        let previous = start.checked_sub(stride).map(|p| motion.frame(p));
        self.encode(&frames, previous)
    }

    /// Rebuilds world positions from features, starting from `start` (where the sample
    /// before the first one stood). Returns the positions and where the last sample ends.
    pub fn decode(&self, features: &[f32], start: Placement) -> (Vec<Vec3>, Placement) {
        let dim = self.dim();
        let mut out = Vec::with_capacity(features.len() / dim * self.joints());
        let mut place = start;
        for f in features.chunks_exact(dim) {
            let step = yaw(place.heading) * Vec3::new(f[1], 0.0, f[2]);
            place = Placement { x: place.x + step.x, z: place.z + step.z, heading: wrap(place.heading + f[3]) };
            let root = Vec3::new(place.x, f[0], place.z);
            let rot = yaw(place.heading);
            out.push(root);
            for j in f[ROOT_FEATURES..].chunks_exact(3) {
                out.push(root + rot * Vec3::new(j[0], j[1], j[2]));
            }
        }
        (out, place)
    }

    /// The mean distance every joint moves from one sample to the next (model units), over
    /// consecutive samples of `features`: the take's joint speed per sample step.
    pub fn mean_joint_step(&self, features: &[f32]) -> f32 {
        crate::motion::mean_joint_step(&self.decode(features, Placement::default()).0, self.joints()) as f32
    }

    /// [`FeatureLayout::mean_joint_step`] leaving out the body's travel over the ground (its
    /// turns and the root's height stay in): the pose's own speed per sample step.
    pub fn mean_pose_step(&self, features: &[f32]) -> f32 {
        let mut still = features.to_vec();
        still.chunks_exact_mut(self.dim()).for_each(|f| f[1..3].fill(0.0));
        self.mean_joint_step(&still)
    }

    /// Where a frame stands: its root on the ground and its heading.
    pub fn placement(&self, frame: &[Vec3]) -> Placement {
        Placement { x: frame[0].x, z: frame[0].z, heading: self.heading(frame) }
    }
}

fn yaw(angle: f32) -> Quat {
    Quat::from_rotation_y(angle)
}

/// An angle brought into [-pi, pi).
pub fn wrap(a: f32) -> f32 {
    let tau = std::f32::consts::TAU;
    a - tau * ((a + std::f32::consts::PI) / tau).floor()
}

/// Per-dimension mean and standard deviation, from the training split only.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Normalizer {
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
}

impl Normalizer {
    /// Statistics of `rows` (each `dim` long); a standard deviation is floored so that
    /// near-constant dimensions do not blow up.
    pub fn fit(data: &[f32], dim: usize) -> Self {
        let n = (data.len() / dim).max(1) as f64;
        let mut mean = vec![0f64; dim];
        let mut sq = vec![0f64; dim];
        for row in data.chunks_exact(dim) {
            for (k, v) in row.iter().enumerate() {
                mean[k] += *v as f64;
                sq[k] += (*v as f64) * (*v as f64);
            }
        }
        let mean: Vec<f64> = mean.iter().map(|m| m / n).collect();
        let std: Vec<f64> = sq.iter().zip(&mean).map(|(s, m)| (s / n - m * m).max(0.0).sqrt()).collect();
        let floor = std.iter().cloned().fold(0.0, f64::max) * 1e-3 + 1e-8;
        Self { mean: mean.iter().map(|m| *m as f32).collect(), std: std.iter().map(|s| s.max(floor) as f32).collect() }
    }

    pub fn normalize(&self, data: &mut [f32]) {
        let dim = self.mean.len();
        for row in data.chunks_exact_mut(dim) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = (*v - m) / s;
            }
        }
    }

    pub fn denormalize(&self, data: &mut [f32]) {
        let dim = self.mean.len();
        for row in data.chunks_exact_mut(dim) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = *v * s + m;
            }
        }
    }
}

/// How LocGen's input fills the frames between sparse poses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Interpolation {
    /// Straight lines between sparse poses (the paper's equation): every sparse pose is a
    /// kink, which LocGen does not smooth away (acceleration at sparse frames 3x the mean).
    #[default]
    Linear,
    /// A Catmull-Rom spline through the sparse poses: velocity is continuous at each of them.
    CatmullRom,
    /// The natural cubic spline through the sparse poses: acceleration is continuous too, so
    /// a velocity change at a sparse pose (a block seam among them) is spread over the
    /// intervals around it rather than taken at the pose.
    NaturalCubic,
}

/// Dense frames between sparse poses, interpolating world positions: `stride` frames per
/// interval, the last sparse pose included once at the end.
pub fn interpolate(sparse: &[Vec3], joints: usize, stride: usize, kind: Interpolation) -> Vec<Vec3> {
    let n = sparse.len() / joints;
    let pose = |k: usize| &sparse[k * joints..(k + 1) * joints];
    let tangents = match kind {
        Interpolation::Linear => Vec::new(),
        Interpolation::CatmullRom => catmull_rom_tangents(sparse, joints),
        Interpolation::NaturalCubic => natural_tangents(sparse, joints),
    };
    let mut out = Vec::with_capacity(((n.max(1) - 1) * stride + 1) * joints);
    for k in 0..n.saturating_sub(1) {
        let (a, b) = (pose(k), pose(k + 1));
        for s in 0..stride {
            let w = s as f32 / stride as f32;
            if kind == Interpolation::Linear {
                out.extend(a.iter().zip(b).map(|(p, q)| p.lerp(*q, w)));
                continue;
            }
            let (h00, h10, h01, h11) = hermite(w);
            let (m0, m1) = (&tangents[k * joints..(k + 1) * joints], &tangents[(k + 1) * joints..(k + 2) * joints]);
            out.extend((0..joints).map(|j| a[j] * h00 + m0[j] * h10 + b[j] * h01 + m1[j] * h11));
        }
    }
    if n > 0 {
        out.extend_from_slice(pose(n - 1));
    }
    out
}

/// The natural spline through every `stride`-th frame of `frames` (`joints` a frame, whole
/// strides of them and one frame more): what a take splined between GloGen's sparse poses
/// would be, were its poses these frames'.
pub fn spline_through_own_poses(frames: &[Vec3], joints: usize, stride: usize) -> Vec<Vec3> {
    let sparse: Vec<Vec3> = frames.chunks_exact(joints).step_by(stride).flatten().copied().collect();
    interpolate(&sparse, joints, stride, Interpolation::NaturalCubic)
}

/// Catmull-Rom tangents per sparse pose and joint: half the step from the pose before to the
/// pose after, one-sided at the ends.
fn catmull_rom_tangents(sparse: &[Vec3], joints: usize) -> Vec<Vec3> {
    let n = sparse.len() / joints;
    let at = |k: usize, j: usize| sparse[k * joints + j];
    (0..n)
        .flat_map(|k| {
            (0..joints).map(move |j| match (k, n) {
                (_, 1) => Vec3::ZERO,
                (0, _) => at(1, j) - at(0, j),
                _ if k + 1 == n => at(k, j) - at(k - 1, j),
                _ => (at(k + 1, j) - at(k - 1, j)) * 0.5,
            })
        })
        .collect()
}

/// Tangents of the natural cubic spline through each joint's sparse positions (unit knot
/// spacing): the tridiagonal system `m[k-1] + 4 m[k] + m[k+1] = 3 (p[k+1] - p[k-1])`, with
/// `2 m[0] + m[1] = 3 (p[1] - p[0])` and its mirror at the end (zero curvature there),
/// solved by forward elimination and back substitution. The elimination coefficients are
/// the same for every joint.
fn natural_tangents(sparse: &[Vec3], joints: usize) -> Vec<Vec3> {
    let n = sparse.len() / joints;
    if n < 2 {
        return vec![Vec3::ZERO; sparse.len()];
    }
    let at = |k: usize, j: usize| sparse[k * joints + j];
    let diagonal = |k: usize| if k == 0 || k + 1 == n { 2.0 } else { 4.0 };
    let rhs = |k: usize, j: usize| 3.0 * (at((k + 1).min(n - 1), j) - at(k.saturating_sub(1), j));
    // Forward elimination: c[k] is the eliminated super-diagonal.
    let mut c = vec![0.0f32; n];
    let mut m = vec![Vec3::ZERO; sparse.len()];
    c[0] = 1.0 / diagonal(0);
    for j in 0..joints {
        m[j] = rhs(0, j) / diagonal(0);
    }
    for k in 1..n {
        let pivot = diagonal(k) - c[k - 1];
        c[k] = 1.0 / pivot;
        for j in 0..joints {
            m[k * joints + j] = (rhs(k, j) - m[(k - 1) * joints + j]) / pivot;
        }
    }
    for k in (0..n - 1).rev() {
        for j in 0..joints {
            let next = m[(k + 1) * joints + j];
            m[k * joints + j] -= next * c[k];
        }
    }
    m
}

/// The cubic Hermite basis at `w` in [0, 1].
fn hermite(w: f32) -> (f32, f32, f32, f32) {
    let (w2, w3) = (w * w, w * w * w);
    (2.0 * w3 - 3.0 * w2 + 1.0, w3 - 2.0 * w2 + w, -2.0 * w3 + 3.0 * w2, w3 - w2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walker() -> (FeatureLayout, Vec<Vec<Vec3>>) {
        // Hips, then per side hip, knee, ankle, toe; head; per side hand.
        let names = "Hips LeftUpLeg LeftLeg LeftFoot LeftToeBase RightUpLeg RightLeg RightFoot RightToeBase Head LeftHand RightHand";
        let down = Vec3::new(0.0, -4.0, 0.0);
        let toe = Vec3::new(0.0, 0.0, 1.0);
        let skeleton = Skeleton::new(
            names.split(' ').map(String::from).collect(),
            vec![None, Some(0), Some(1), Some(2), Some(3), Some(0), Some(5), Some(6), Some(7), Some(0), Some(0), Some(0)],
            vec![Vec3::ZERO, Vec3::X, down, down, toe, -Vec3::X, down, down, toe, Vec3::new(0.0, 5.0, 0.0), Vec3::new(3.0, 3.0, 0.0), Vec3::new(-3.0, 3.0, 0.0)],
            0.01,
        )
        .unwrap();
        let layout = FeatureLayout::new(Arc::new(skeleton.clone())).unwrap();
        let frames = (0..12)
            .map(|t| {
                let turn = Quat::from_rotation_y(0.2 * t as f32);
                let root = Vec3::new(0.5 * t as f32, 9.0 + (t as f32).sin(), 0.3 * t as f32 * t as f32);
                skeleton.rest_positions().iter().map(|p| root + turn * *p).collect()
            })
            .collect();
        (layout, frames)
    }

    #[test]
    fn decode_inverts_encode() {
        let (layout, frames) = walker();
        let refs: Vec<&[Vec3]> = frames.iter().map(|f| f.as_slice()).collect();
        let feats = layout.encode(&refs[1..], Some(refs[0]));
        let (back, _) = layout.decode(&feats, layout.placement(refs[0]));
        for (t, f) in frames[1..].iter().enumerate() {
            for (j, joint) in f.iter().enumerate() {
                assert!(back[t * f.len() + j].distance(*joint) < 1e-4, "frame {t} joint {j}");
            }
        }
    }

    #[test]
    fn hips_give_heading() {
        let (layout, frames) = walker();
        // Left hip at +x, right at -x: facing +z, heading 0.
        assert!(layout.heading(&frames[0]).abs() < 1e-6);
        assert!((layout.heading(&frames[1]) - 0.2).abs() < 1e-5);
    }

    #[test]
    fn normalizer_round_trip() {
        let data = vec![1.0, 10.0, 3.0, 10.0, 5.0, 10.0];
        let n = Normalizer::fit(&data, 2);
        let mut x = data.clone();
        n.normalize(&mut x);
        assert!((x[0] + 1.2247).abs() < 1e-3);
        n.denormalize(&mut x);
        assert!(x.iter().zip(&data).all(|(a, b)| (a - b).abs() < 1e-5));
    }

    #[test]
    fn interpolation_keeps_keyframes() {
        let sparse = vec![Vec3::ZERO, Vec3::splat(5.0)];
        let dense = interpolate(&sparse, 1, 5, Interpolation::Linear);
        assert_eq!(dense.len(), 6);
        assert_eq!(dense[1], Vec3::ONE);
        assert_eq!(dense[5], Vec3::splat(5.0));
        // A spline passes through the keys and keeps a steady motion steady.
        let steady: Vec<Vec3> = (0..4).map(|k| Vec3::splat(5.0 * k as f32)).collect();
        let smooth = interpolate(&steady, 1, 5, Interpolation::CatmullRom);
        assert_eq!(smooth.len(), 16);
        for (f, p) in smooth.iter().enumerate() {
            assert!((p.x - f as f32).abs() < 1e-5, "frame {f}: {p}");
        }
        for kind in [Interpolation::CatmullRom, Interpolation::NaturalCubic] {
            let natural = interpolate(&steady, 1, 5, kind);
            assert!(natural.iter().enumerate().all(|(f, p)| (p.x - f as f32).abs() < 1e-4), "{kind:?} bends a steady motion");
        }
    }

    /// The natural spline's acceleration is continuous at the sparse poses; Catmull-Rom's
    /// jumps there (the kink the block-seam measures see).
    #[test]
    fn natural_spline_has_no_acceleration_jump_at_keys() {
        let keys: Vec<Vec3> = [0.0, 1.0, 0.0, 2.0, 1.0, 3.0, 0.0].iter().map(|&y| Vec3::new(0.0, y, 0.0)).collect();
        // Second differences just before and just after each inner key on a fine grid: a
        // jump in acceleration stays as the grid refines, a continuous one (with a jump in
        // its derivative) shrinks with the grid step.
        let stride = 64;
        let jump = |kind: Interpolation| -> f32 {
            let d = interpolate(&keys, 1, stride, kind);
            (2..keys.len() - 2)
                .map(|k| {
                    let f = k * stride;
                    let before = d[f - 2].y - 2.0 * d[f - 1].y + d[f].y;
                    let after = d[f].y - 2.0 * d[f + 1].y + d[f + 2].y;
                    (after - before).abs()
                })
                .fold(0.0, f32::max)
        };
        let (natural, catmull_rom) = (jump(Interpolation::NaturalCubic), jump(Interpolation::CatmullRom));
        assert!(natural < 0.2 * catmull_rom, "acceleration jump: natural {natural}, Catmull-Rom {catmull_rom}");
        let d = interpolate(&keys, 1, stride, Interpolation::NaturalCubic);
        for (k, key) in keys.iter().enumerate() {
            assert!((d[k * stride] - *key).length() < 1e-5, "key {k} missed");
        }
    }
}
