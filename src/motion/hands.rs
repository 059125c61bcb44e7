//! Hands stay on top of the floor. Sitting down onto the floor and seated there, h36m's
//! network pushes a hand flat on the ground through it: a wrist end 3-12 cm under the floor
//! in 30 of 400 random takes. A hand that goes under is lifted by two-bone IK of its arm
//! (shoulder, elbow, wrist; the elbow bending in its own plane, the hand keeping its
//! orientation, [`reach`]), the lift eased in and out so the arm does not jump.

use glam::Vec3;

use super::contacts::{sliding, smoothed};
use super::ik::reach;
use super::{JointRoles, Skeleton};

/// Roughly the half-width (seconds) over which a lift eases in before the hand would go under
/// and out after it has come back up.
const EASE_SECONDS: f32 = 0.15;
/// An elbow nearer than this fraction of the arm's length to the shoulder-to-wrist line is
/// straight (see [`bend_side`]).
const STRAIGHT_ARM: f32 = 0.05;

/// `positions` (frames of `skeleton`'s joints, at `fps`) with every hand's joints at or above
/// the height `floor`.
pub fn keep_hands_above_floor(positions: &mut [Vec3], skeleton: &Skeleton, roles: &JointRoles, floor: f32, fps: f32) {
    let joints = skeleton.len();
    for wrist in [roles.left_hand, roles.right_hand] {
        let Some(elbow) = skeleton.parents()[wrist] else { continue };
        let Some(shoulder) = skeleton.parents()[elbow] else { continue };
        let hand = skeleton.subtree(wrist);
        let under: Vec<f32> = positions.chunks_exact(joints).map(|f| (floor - hand.iter().map(|&j| f[j].y).fold(f32::INFINITY, f32::min)).max(0.0)).collect();
        if under.iter().all(|&u| u == 0.0) {
            continue;
        }
        let mut bend = None;
        for (frame, lift) in positions.chunks_exact_mut(joints).zip(eased(&under, fps)) {
            bend = bend_side(frame, (shoulder, elbow, wrist)).or(bend);
            if lift > 0.0 {
                let target = frame[wrist] + Vec3::Y * lift;
                reach(skeleton, frame, [shoulder, elbow, wrist], target, frame[elbow] + bend.unwrap_or(Vec3::ZERO));
            }
        }
    }
}

/// `under` widened and smoothed so that it eases in and out, never below `under` itself: the
/// largest within three smoothing half-widths either side, then three moving averages.
pub(super) fn eased(under: &[f32], fps: f32) -> Vec<f32> {
    let half = (EASE_SECONDS * fps / 3.0).round().max(1.0) as usize;
    let widest = sliding(under, 3 * half, f32::max, 0.0);
    smoothed(&widest, half)
}

/// The direction the elbow stands out from the shoulder-to-wrist line (a unit vector), or
/// none for an arm too straight to say ([`STRAIGHT_ARM`]): a hand pushing on the floor comes
/// with a straight arm, whose bending plane [`reach`] would otherwise take from rounding noise,
/// turning the elbow round from one frame to the next; the last arm bent enough says.
fn bend_side(frame: &[Vec3], (shoulder, elbow, wrist): (usize, usize, usize)) -> Option<Vec3> {
    let line = (frame[wrist] - frame[shoulder]).try_normalize()?;
    let out = frame[elbow] - frame[shoulder];
    let side = out - line * out.dot(line);
    let arm = frame[elbow].distance(frame[shoulder]) + frame[wrist].distance(frame[elbow]);
    (side.length() > STRAIGHT_ARM * arm).then(|| side.normalize())
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;
    use crate::motion::ik::turn_below;
    use crate::motion::standard_humanoid;

    /// The standard humanoid with its right arm hanging straight down for a second, the
    /// floor 8 cm above its lowest hand joint there: every hand joint ends on or above the
    /// floor, the arm's bones keep their lengths, and frames well away from the push are as
    /// they were.
    #[test]
    fn a_hand_pushed_through_the_floor_comes_up_onto_it() {
        let skeleton = standard_humanoid();
        let roles = JointRoles::new(&skeleton).unwrap();
        let wrist = roles.right_hand;
        let elbow = skeleton.parents()[wrist].unwrap();
        let shoulder = skeleton.parents()[elbow].unwrap();
        let hand = skeleton.subtree(wrist);
        let rest = skeleton.rest_positions();
        let mut hanging = rest.clone();
        turn_below(&skeleton, &mut hanging, shoulder, Quat::from_rotation_arc((rest[elbow] - rest[shoulder]).normalize(), Vec3::NEG_Y));
        let lowest = |frame: &[Vec3]| hand.iter().map(|&j| frame[j].y).fold(f32::INFINITY, f32::min);
        let floor = lowest(&hanging) + 0.08 / skeleton.meters_per_unit();
        let (fps, frames) = (30.0, 90);
        let before: Vec<Vec3> = (0..frames).flat_map(|t| if (30..60).contains(&t) { hanging.clone() } else { rest.clone() }).collect();
        let mut after = before.clone();
        keep_hands_above_floor(&mut after, &skeleton, &roles, floor, fps);
        let joints = skeleton.len();
        for (t, (b, a)) in before.chunks_exact(joints).zip(after.chunks_exact(joints)).enumerate() {
            assert!(lowest(a) >= floor - 1e-4, "frame {t}: a hand joint {} under the floor", floor - lowest(a));
            for j in [elbow, wrist] {
                let parent = skeleton.parents()[j].unwrap();
                let (was, is) = (b[j].distance(b[parent]), a[j].distance(a[parent]));
                assert!((was - is).abs() < 1e-4 * was, "frame {t}: bone {j} {was} -> {is}");
            }
            if !(15..75).contains(&t) {
                assert_eq!(b, a, "frame {t} is far from the push");
            }
        }
    }
}
