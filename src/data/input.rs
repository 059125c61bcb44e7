//! Reading an input file within limits: only regular files (a FIFO would block forever, a
//! link to /dev/zero read until memory runs out) and at most a stated size.

use std::io::Read;
use std::path::Path;

use anyhow::{bail, Context, Result};
use glam::Vec3;

use crate::motion::{JointRoles, Motion, Skeleton};

/// The largest motion file (BVH, NPY, exponential map, JSON take) glocal reads: an hour-long
/// take at 25 fps is about 75 MB of JSON.
pub const MAX_MOTION_BYTES: u64 = 256 << 20;

/// The longest motion, in seconds, read from a file or generated (one hour).
pub const MAX_MOTION_SECONDS: f64 = 3600.0;

/// The whole of `path`, refused when it is not a regular file or larger than `limit` bytes.
pub fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let name = path.display();
    let meta = std::fs::metadata(path).with_context(|| format!("cannot read {name}"))?;
    if meta.is_dir() {
        bail!("{name} is a folder, not a file");
    }
    if !meta.is_file() {
        bail!("{name} is not a regular file (a device, FIFO or socket); give a file");
    }
    let file = std::fs::File::open(path).with_context(|| format!("cannot read {name}"))?;
    let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
    file.take(limit + 1).read_to_end(&mut bytes).with_context(|| format!("cannot read {name}"))?;
    if bytes.len() as u64 > limit {
        bail!("{name} is larger than {} MB, the most glocal reads from such a file", limit >> 20);
    }
    Ok(bytes)
}

/// [`read_bytes`] as UTF-8 text.
pub fn read_text(path: &Path, limit: u64) -> Result<String> {
    String::from_utf8(read_bytes(path, limit)?).map_err(|e| anyhow::anyhow!("{}: not UTF-8 text (byte {})", path.display(), e.utf8_error().valid_up_to()))
}

/// Farthest any joint may be from the world origin: 100 km.
pub const MAX_DISTANCE_M: f32 = 1e5;
/// Fastest the root may move between frames: 100 m/s, ten times a sprint.
pub const MAX_ROOT_SPEED_M_S: f32 = 100.0;
/// How far a joint may be from the body's root, against the farthest joint of the rest pose:
/// a real pose stretches a little past its rest extent, never to four times it.
const MAX_REACH: f32 = 4.0;

/// Refuses a motion no body could make: non-finite or astronomically far positions, a body
/// root that jumps faster than anything runs, body joints flung far beyond the skeleton's
/// size (`reference`'s rest pose, so a file cannot make itself look normal with huge
/// offsets), or a clip longer than [`MAX_MOTION_SECONDS`]. The body is the joint both legs
/// hang from and everything under it ([`JointRoles::body_of`]). The error names the first bad
/// frame (from 1, as files count them).
pub fn check_plausible(motion: &Motion, name: &str, reference: &Skeleton) -> Result<()> {
    if !(motion.fps.is_finite() && motion.fps > 0.0) || motion.frames() as f64 / motion.fps as f64 > MAX_MOTION_SECONDS {
        bail!("{name}: {} frames at {} fps is longer than the {} s glocal reads", motion.frames(), motion.fps, MAX_MOTION_SECONDS);
    }
    let unit = motion.skeleton.meters_per_unit();
    let rest_reach = JointRoles::rest_reach(reference) * reference.meters_per_unit();
    // A one-joint or collapsed skeleton still gets a body's size.
    let max_reach = MAX_REACH * rest_reach.max(1.0);
    let (body_root, body_joints) = JointRoles::body_of(&motion.skeleton);
    let mut previous_root: Option<Vec3> = None;
    for t in 0..motion.frames() {
        let frame = motion.frame(t);
        let root = frame[body_root];
        let bad = |what: String| anyhow::anyhow!("{name}: frame {}: {what}; the file is damaged or not motion capture", t + 1);
        if let Some(j) = frame.iter().position(|p| !p.is_finite() || p.length() * unit > MAX_DISTANCE_M) {
            return Err(bad(format!("joint {j} is at {} m, farther than {MAX_DISTANCE_M} m from the origin", frame[j].length() * unit)));
        }
        if let Some(&j) = body_joints.iter().find(|&&j| frame[j].distance(root) * unit > max_reach) {
            return Err(bad(format!("joint {j} is {:.1} m from the body's root, more than {MAX_REACH} times the skeleton's reach", frame[j].distance(root) * unit)));
        }
        if let Some(prev) = previous_root {
            let speed = prev.distance(root) * unit * motion.fps;
            if speed > MAX_ROOT_SPEED_M_S {
                return Err(bad(format!("the body's root moves at {speed:.0} m/s, faster than {MAX_ROOT_SPEED_M_S} m/s")));
            }
        }
        previous_root = Some(root);
    }
    Ok(())
}
