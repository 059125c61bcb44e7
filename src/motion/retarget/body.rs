//! The pelvis and the chest: the two rigid pieces of the trunk that carry several bones each
//! (the pelvis the hip sockets and the spine, the chest the neck and the collars).
//!
//! Their shapes differ from skeleton to skeleton (Human3.6M's hip sockets are level with its
//! hips joint and its collars start at the neck; a Rigify metarig's sockets sit 6 cm above
//! and 4 cm in front of its pelvis bone's head, its collars in front of the spine), so no turn
//! of the target's piece points all of its bones where the source's point: fitting one to all
//! of them (least squares) tilts the piece by the difference in shape. A piece is instead
//! turned as the source's piece turns, read from two lines between key joints every humanoid
//! has: side to side (right to left hip socket, right to left shoulder socket) and up the body
//! (hips to chest, chest to neck). The target's own rest shape then decides where its sockets
//! and collars are, as its own pelvis and ribcage would. At rest the chest is taken to face
//! the way the pelvis does, its side-to-side line read off the hip sockets: Human3.6M rests
//! with its arms straight up and both shoulder sockets on one point, which gives no line.

use glam::{Mat3, Quat, Vec3};

use super::super::keys::{Key, KeyJoints};
use super::RetargetError;

/// Which of a frame's two lines is kept exactly; the other is squared to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Exact {
    /// The pelvis: both sockets are fixed in it, while hips to chest bends with the spine.
    SideToSide,
    /// The chest: the neck's base is fixed in it, while the shoulder sockets move with the
    /// collars.
    Up,
}

/// A rigid piece of the trunk, turned as the source's.
#[derive(Clone, Debug)]
pub(super) struct BodyPiece {
    /// From the right key joint to the left one, in the source's frames.
    side_to_side: (Key, Key),
    /// From the lower key joint to the upper one.
    up: (Key, Key),
    exact: Exact,
    /// The target's rest frame, inverted: a source frame times this is the piece's turn.
    rest_inverse: Quat,
}

impl BodyPiece {
    /// The pelvis (the hips key joint's piece) of the target at rest (`rest`, `keys`).
    pub fn pelvis(rest: &[Vec3], keys: &KeyJoints) -> Result<BodyPiece, RetargetError> {
        BodyPiece::new("hips", HIP_SOCKETS, (Key::Hips, Key::Chest), Exact::SideToSide, rest, keys)
    }

    /// The chest's piece, its up line to the neck where `neck` (both skeletons have a neck
    /// apart from the chest), else to the head.
    pub fn chest(rest: &[Vec3], keys: &KeyJoints, neck: bool) -> Result<BodyPiece, RetargetError> {
        let top = if neck { Key::Neck } else { Key::Head };
        BodyPiece::new("chest", (Key::RightArm, Key::LeftArm), (Key::Chest, top), Exact::Up, rest, keys)
    }

    fn new(part: &'static str, side_to_side: (Key, Key), up: (Key, Key), exact: Exact, rest: &[Vec3], keys: &KeyJoints) -> Result<BodyPiece, RetargetError> {
        let rest_frame = frame_of(line(rest, keys, HIP_SOCKETS), line(rest, keys, up), exact).ok_or(RetargetError::NoFacing { part })?;
        Ok(BodyPiece { side_to_side, up, exact, rest_inverse: rest_frame.inverse() })
    }

    /// The piece's turn from the target's rest to where the source's piece faces in `frame`
    /// (the source's joint positions, `keys` its key joints); None where the source's two
    /// lines have collapsed into one.
    pub fn turn(&self, frame: &[Vec3], keys: &KeyJoints) -> Option<Quat> {
        let source_frame = frame_of(line(frame, keys, self.side_to_side), line(frame, keys, self.up), self.exact)?;
        Some((source_frame * self.rest_inverse).normalize())
    }
}

const HIP_SOCKETS: (Key, Key) = (Key::RightUpLeg, Key::LeftUpLeg);

/// From key joint `from` to `to` in `points` (zero where either is not mapped).
fn line(points: &[Vec3], keys: &KeyJoints, (from, to): (Key, Key)) -> Vec3 {
    match (keys.get(from), keys.get(to)) {
        (Some(a), Some(b)) => points[b] - points[a],
        _ => Vec3::ZERO,
    }
}

/// The rotation whose x axis is `side_to_side`, y `up` and z their cross product, one of the
/// two kept exactly; None when they are (nearly) parallel or either has no length.
fn frame_of(side_to_side: Vec3, up: Vec3, exact: Exact) -> Option<Quat> {
    let forward = side_to_side.cross(up);
    if forward.length() <= 1e-2 * side_to_side.length() * up.length() || !forward.is_finite() {
        return None;
    }
    let z = forward.normalize();
    let (x, y) = match exact {
        Exact::SideToSide => {
            let x = side_to_side.normalize();
            (x, z.cross(x))
        }
        Exact::Up => {
            let y = up.normalize();
            (y.cross(z), y)
        }
    };
    Some(Quat::from_mat3(&Mat3::from_cols(x, y, z)).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exact_line_is_kept_and_the_other_squared() {
        let leaning_up = Vec3::new(0.3, 1.0, 0.0);
        let pelvis = frame_of(Vec3::X * 2.0, leaning_up, Exact::SideToSide).unwrap();
        assert!((pelvis * Vec3::X).distance(Vec3::X) < 1e-6);
        assert!((pelvis * Vec3::Y).distance(Vec3::Y) < 1e-6, "up is squared to the exact side-to-side line");
        let tilted_up = Vec3::new(0.0, 1.0, 0.3);
        let chest = frame_of(Vec3::new(1.0, 0.2, 0.0), tilted_up, Exact::Up).unwrap();
        assert!((chest * Vec3::Y).distance(tilted_up.normalize()) < 1e-6);
        assert!((chest * Vec3::X).dot(Vec3::new(1.0, 0.2, 0.0)) > 0.9, "side to side is squared to the exact up line");
        assert!(frame_of(Vec3::Y, Vec3::Y * 3.0, Exact::Up).is_none(), "parallel lines face nowhere");
    }
}
