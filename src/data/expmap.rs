//! Exponential-map text files (Human3.6M and the CMU motion-prediction set): one frame a
//! line of comma-separated values, each joint's rotation as axis * angle relative to its
//! parent. The skeletons come from `h36m-skeleton.json` and `cmu-expmap-skeleton.json`.
//!
//! The files use row vectors (`R_i = expmap(r_i) * R_parent`); in our column-vector
//! convention that local rotation is `expmap(-r_i)`.

use std::sync::Arc;

use glam::{Quat, Vec3};
use serde::Deserialize;

use super::floor::fit_floor;
use super::FormatError;
use super::input::{MAX_DISTANCE_M, MAX_ROOT_SPEED_M_S};
use crate::motion::{clipped, JointRoles, LocalPose, Motion, Skeleton};

/// How the first six values of a line place the root.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RootEncoding {
    /// Human3.6M: values 0-2 are the root's translation increment in the previous frame's
    /// root coordinates, values 3-5 its rotation increment; joint rotations start at value 6.
    Incremental,
    /// CMU: values 0-2 are the root's absolute position; values 3.. are every joint's
    /// rotation, joint 0 (the root) first.
    Absolute,
}

/// An exponential-map format: its skeleton and how a line is laid out.
#[derive(Clone, Debug)]
pub struct ExpmapFormat {
    pub skeleton: Arc<Skeleton>,
    pub root: RootEncoding,
    pub fps: f32,
    /// The 15-joint subset for the 2D experiments (Human3.6M only).
    pub major15: Option<Vec<usize>>,
}

#[derive(Deserialize)]
struct SkeletonFile {
    joints: Option<Vec<String>>,
    parents: Vec<i64>,
    #[serde(alias = "offsets_mm")]
    offsets: Vec<[f32; 3]>,
    major15: Option<Vec<usize>>,
}

impl ExpmapFormat {
    /// Reads a skeleton JSON (`h36m-skeleton.json` or `cmu-expmap-skeleton.json`).
    pub fn from_skeleton_json(text: &str, file: &str, root: RootEncoding, fps: f32, meters_per_unit: f32) -> Result<Self, FormatError> {
        let parsed: SkeletonFile =
            serde_json::from_str(text).map_err(|e| FormatError::at_line(file, e.line(), format!("not a skeleton file: {e}")))?;
        let n = parsed.parents.len();
        let names = parsed.joints.unwrap_or_else(|| (0..n).map(|j| format!("joint{j}")).collect());
        let parents = parsed
            .parents
            .iter()
            .map(|&p| if p < 0 { None } else { Some(p as usize) })
            .collect();
        let offsets = parsed.offsets.iter().map(|o| Vec3::from_array(*o)).collect();
        let skeleton = Skeleton::new(names, parents, offsets, meters_per_unit).map_err(|e| FormatError::new(file, e.to_string()))?;
        Ok(Self { skeleton: Arc::new(skeleton), root, fps, major15: parsed.major15 })
    }

    /// Values per line.
    pub fn values_per_frame(&self) -> usize {
        3 + 3 * self.skeleton.len()
    }

    /// Parses a whole file into a motion with world positions (and the local poses).
    pub fn read(&self, text: &str, file: &str) -> Result<Motion, FormatError> {
        let width = self.values_per_frame();
        let mut poses = Vec::new();
        let mut root_rot = Quat::IDENTITY;
        let mut root_pos = Vec3::ZERO;
        let mut values = Vec::with_capacity(width);
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            values.clear();
            for token in line.split(',') {
                let v: f32 = token.trim().parse().map_err(|_| {
                    FormatError::at_line(file, i + 1, format!("'{}' is not a number", clipped(token.trim())))
                })?;
                if !v.is_finite() {
                    return Err(FormatError::at_line(file, i + 1, format!("value {v} is not finite")));
                }
                values.push(v);
            }
            if values.len() != width {
                return Err(FormatError::at_line(file, i + 1, format!("expected {width} values, found {}", values.len())));
            }
            self.check_root(&values, file, i + 1)?;
            poses.push(self.pose(&values, &mut root_rot, &mut root_pos));
        }
        if poses.is_empty() {
            return Err(FormatError::new(file, "no frames"));
        }
        let mut motion = Motion::from_local_poses(self.skeleton.clone(), self.fps, poses);
        if self.root == RootEncoding::Incremental {
            motion = level_to_vertical(&motion);
        }
        if let Some(bad) = motion.positions().iter().position(|p| !p.is_finite()) {
            let frame = bad / motion.joints();
            return Err(FormatError::new(file, format!("frame {} gives a joint a non-finite position (values too large)", frame + 1)));
        }
        Ok(motion)
    }

    /// The root's translation on a line within a body's reach: a position within
    /// [`MAX_DISTANCE_M`] of the origin, or a step of at most [`MAX_ROOT_SPEED_M_S`]. Checked
    /// where the value enters, so the error names its line (levelling the take spreads one
    /// bad frame over all of them).
    fn check_root(&self, v: &[f32], file: &str, line: usize) -> Result<(), FormatError> {
        let metres = Vec3::new(v[0], v[1], v[2]).length() * self.skeleton.meters_per_unit();
        let (limit, what) = match self.root {
            RootEncoding::Absolute => (MAX_DISTANCE_M, "from the origin"),
            RootEncoding::Incremental => (MAX_ROOT_SPEED_M_S / self.fps, "in one frame"),
        };
        if metres > limit {
            return Err(FormatError::at_line(file, line, format!("the root moves {metres} m {what}, more than {limit} m; the file is damaged")));
        }
        Ok(())
    }

    fn pose(&self, v: &[f32], root_rot: &mut Quat, root_pos: &mut Vec3) -> LocalPose {
        let j = self.skeleton.len();
        let expmap = |k: usize| local_rotation(Vec3::new(v[3 + 3 * k], v[4 + 3 * k], v[5 + 3 * k]));
        let mut rotations: Vec<Quat> = (0..j).map(expmap).collect();
        let mut translations = self.skeleton.offsets().to_vec();
        match self.root {
            RootEncoding::Absolute => translations[0] = Vec3::new(v[0], v[1], v[2]),
            RootEncoding::Incremental => {
                // T_t = T_(t-1) + R_(t-1)^T v_t (row-vector R, i.e. our column rotation).
                *root_pos += *root_rot * Vec3::new(v[0], v[1], v[2]);
                *root_rot = (*root_rot * rotations[0]).normalize();
                rotations[0] = *root_rot;
                translations[0] = *root_pos;
            }
        }
        LocalPose { rotations, translations }
    }
}

/// The column-vector local rotation of an exponential map given in the row-vector convention.
fn local_rotation(r: Vec3) -> Quat {
    Quat::from_scaled_axis(-r)
}

/// Human3.6M stores no absolute starting orientation, so a rebuilt take can stand tilted.
/// Levels the take on the floor its toes stand on ([`fit_floor`]), with the floor at height
/// 0 and the first frame's root on the vertical axis through the origin. A take whose toes
/// never stand still is levelled by its mean hips-to-neck direction instead, with the floor
/// under its lowest toe.
fn level_to_vertical(motion: &Motion) -> Motion {
    let neck = motion.skeleton.index_of("Neck").unwrap_or(motion.joints() - 1);
    let mut up = Vec3::ZERO;
    for t in 0..motion.frames() {
        let f = motion.frame(t);
        up += (f[neck] - f[0]).normalize_or_zero();
    }
    let by_torso = Quat::from_rotation_arc(up.normalize_or(Vec3::Y), Vec3::Y);
    // The fit needs positions only: rotating them is the same as rotating the root, without
    // a second forward-kinematics pass over the take.
    let torso_levelled = Motion::from_positions(motion.skeleton.clone(), motion.fps, motion.positions().iter().map(|p| by_torso * *p).collect());
    let toes: Vec<usize> = JointRoles::new(&motion.skeleton).map(|r| [r.left.toe, r.right.toe].into_iter().flatten().collect()).unwrap_or_default();
    let (fix, floor) = match fit_floor(&torso_levelled, &toes) {
        Some(floor) => (floor.levelling * by_torso, floor.height),
        None => {
            let lowest = (0..motion.frames()).flat_map(|t| toes.iter().map(move |&j| (t, j))).map(|(t, j)| torso_levelled.frame(t)[j].y).fold(f32::INFINITY, f32::min);
            (by_torso, if lowest.is_finite() { lowest } else { 0.0 })
        }
    };
    let origin = fix * motion.frame(0)[0];
    rotate_about_origin(motion, fix, Vec3::new(origin.x, floor, origin.z))
}

/// The take rotated by `rotation` about the origin, then moved by `-shift`.
fn rotate_about_origin(motion: &Motion, rotation: Quat, shift: Vec3) -> Motion {
    let poses = motion.local_poses.as_ref().expect("expmap takes have local poses");
    let moved = poses
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p.rotations[0] = rotation * p.rotations[0];
            p.translations[0] = rotation * p.translations[0] - shift;
            p
        })
        .collect();
    Motion::from_local_poses(motion.skeleton.clone(), motion.fps, moved)
}

/// Human3.6M's 2D view: the given joints, root-relative, projected orthographically onto the
/// plane of the body's lateral axis and the vertical (a front view). The lateral axis is the
/// mean left-hip to right-hip direction of the take, flattened to the ground.
pub fn front_view_2d(motion: &Motion, joints: &[usize], left_hip: usize, right_hip: usize) -> Vec<[f32; 2]> {
    let mut lateral = Vec3::ZERO;
    for t in 0..motion.frames() {
        let f = motion.frame(t);
        lateral += f[right_hip] - f[left_hip];
    }
    let lateral = Vec3::new(lateral.x, 0.0, lateral.z).normalize_or(Vec3::X);
    let mut out = Vec::with_capacity(motion.frames() * joints.len());
    for t in 0..motion.frames() {
        let f = motion.frame(t);
        out.extend(joints.iter().map(|&j| {
            let p = f[j] - f[0];
            [p.dot(lateral), p.y]
        }));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> ExpmapFormat {
        let json = r#"{"parents": [-1, 0], "offsets": [[0,0,0],[0,1,0]]}"#;
        ExpmapFormat::from_skeleton_json(json, "tiny.json", RootEncoding::Absolute, 30.0, 1.0).unwrap()
    }

    #[test]
    fn row_vector_rotation_matches_the_files_convention() {
        // Row-vector FK: p = offset * expmap(r). Rotating (0,1,0) by +90 deg about z in the
        // row convention gives (-1,0,0)*... ; check against an explicit row-vector product.
        let r = Vec3::new(0.0, 0.0, std::f32::consts::FRAC_PI_2);
        let row_matrix = glam::Mat3::from_axis_angle(Vec3::Z, r.length()); // column form of expmap(r)
        let offset = Vec3::Y;
        let row_result = row_matrix.transpose() * offset; // offset * R (row) == R^T offset
        let ours = local_rotation(r) * offset;
        assert!(row_result.distance(ours) < 1e-6);
    }

    #[test]
    fn bad_lines_name_file_and_line() {
        let f = tiny();
        let good = "0,0,0,0,0,0,0,0,0";
        assert_eq!(f.read(good, "a.txt").unwrap().frames(), 1);
        let e = f.read(&format!("{good}\n0,0,x,0,0,0,0,0,0"), "a.txt").unwrap_err();
        assert_eq!(e.to_string(), "a.txt:2: 'x' is not a number");
        let e = f.read("0,0,0", "b.txt").unwrap_err();
        assert_eq!(e.to_string(), "b.txt:1: expected 9 values, found 3");
        assert!(f.read("", "c.txt").is_err());
        assert!(f.read("\u{0}\u{1}garbage", "d.txt").is_err());
        assert!(ExpmapFormat::from_skeleton_json("{", "s.json", RootEncoding::Absolute, 1.0, 1.0).is_err());
    }

    /// Found by the fuzzer: a finite but enormous angle used to yield NaN positions.
    #[test]
    fn enormous_values_are_an_error_not_nan() {
        let f = tiny();
        let e = f.read("0,0,0,0,6444444444444444444444444444444444440,0,0,0,0", "big.txt").unwrap_err();
        assert!(e.to_string().starts_with("big.txt: frame 1 gives a joint a non-finite position"), "{e}");
    }
}
