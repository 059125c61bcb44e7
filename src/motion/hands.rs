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
        let sides = bend_sides(positions, joints, (shoulder, elbow, wrist));
        for ((frame, lift), side) in positions.chunks_exact_mut(joints).zip(eased(&under, fps)).zip(sides) {
            if lift > 0.0 {
                let target = frame[wrist] + Vec3::Y * lift;
                // The side from the shoulder (the IK reads the pole's direction from there):
                // added to the elbow, a unit vector was 1 mm on h36m's skeleton, and the
                // straight arm's own few millimetres off its line, turning round from frame to
                // frame, chose the lifted elbow's side (an upper arm 25 degrees in one frame).
                let pole = side.map_or(frame[elbow], |side| frame[shoulder] + side);
                reach(skeleton, frame, [shoulder, elbow, wrist], target, pole);
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

/// Per frame of `positions` (`joints` a frame), the direction the elbow of `arm` stands out
/// ([`bend_side`]); over a stretch where the arm is too straight to say, turned evenly from
/// the side before it to the side after it (before the first bent frame, the first side;
/// after the last, the last). The network's elbow may pass through straight to its other
/// side, and a lifted hand's elbow, bent on the side last seen, then flipped in one frame:
/// `all`'s sittingdown from its seed 115 jumped its right elbow 18 cm (9074 m/s^3; 506
/// without the lift).
fn bend_sides(positions: &[Vec3], joints: usize, arm: (usize, usize, usize)) -> Vec<Option<Vec3>> {
    let own: Vec<Option<Vec3>> = positions.chunks_exact(joints).map(|frame| bend_side(frame, arm)).collect();
    let bent: Vec<usize> = (0..own.len()).filter(|&t| own[t].is_some()).collect();
    (0..own.len())
        .map(|t| {
            own[t].or_else(|| {
                let next = bent.partition_point(|&b| b < t);
                match (next.checked_sub(1).map(|i| bent[i]), bent.get(next).copied()) {
                    (Some(a), Some(b)) => Some(own[a]?.slerp(own[b]?, (t - a) as f32 / (b - a) as f32)),
                    (Some(a), None) => own[a],
                    (None, Some(b)) => own[b],
                    (None, None) => None,
                }
            })
        })
        .collect()
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

    /// An arm (shoulder, elbow, wrist) bent to +x for five frames, straight for five, then
    /// bent to -z: the straight frames' sides turn from +x to -z in even steps of 15 degrees,
    /// the bent frames keep their own.
    #[test]
    fn a_straight_stretch_turns_the_bend_from_one_side_to_the_other() {
        let elbow_out = |t: usize| match t {
            0..5 => Vec3::X * 0.1,
            5..10 => Vec3::ZERO,
            _ => Vec3::NEG_Z * 0.1,
        };
        let positions: Vec<Vec3> = (0..15).flat_map(|t| [Vec3::Y, Vec3::new(0.0, 0.75, 0.0) + elbow_out(t), Vec3::new(0.0, 0.5, 0.0)]).collect();
        let sides: Vec<Vec3> = bend_sides(&positions, 3, (0, 1, 2)).into_iter().map(Option::unwrap).collect();
        assert!(sides[..5].iter().all(|s| s.abs_diff_eq(Vec3::X, 1e-6)) && sides[10..].iter().all(|s| s.abs_diff_eq(Vec3::NEG_Z, 1e-6)), "{sides:?}");
        for t in 4..10 {
            let degrees = sides[t].angle_between(sides[t + 1]).to_degrees();
            assert!((degrees - 15.0).abs() < 0.1, "frames {t}-{}: {degrees} degrees", t + 1);
        }
    }

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

    /// The standard humanoid in millimetres (as h36m's skeleton is), its right arm hanging bent
    /// 40 degrees at the elbow, then for a second straight but for a degree of bend whose side
    /// turns from frame to frame, then bent again, its hand under a floor 8 cm above the
    /// hanging wrist throughout: the lifted straight arm's elbow bends to the side of the bent
    /// frames around it and the upper arm turns smoothly. With the side added to the elbow as
    /// a unit vector (1 mm here) the noise chose the side: 32.5 degrees in one frame.
    #[test]
    fn a_lifted_straight_arm_bends_smoothly_in_millimetres() {
        let metres = standard_humanoid();
        let offsets: Vec<Vec3> = metres.offsets().iter().map(|o| *o * 1000.0).collect();
        let skeleton = Skeleton::new(metres.names().to_vec(), metres.parents().to_vec(), offsets, 0.001).unwrap();
        let roles = JointRoles::new(&skeleton).unwrap();
        let wrist = roles.right_hand;
        let elbow = skeleton.parents()[wrist].unwrap();
        let shoulder = skeleton.parents()[elbow].unwrap();
        let rest = skeleton.rest_positions();
        let mut hanging = rest.clone();
        turn_below(&skeleton, &mut hanging, shoulder, Quat::from_rotation_arc((rest[elbow] - rest[shoulder]).normalize(), Vec3::NEG_Y));
        let bent_at_elbow = |angle: f32, axis: Vec3| {
            let mut pose = hanging.clone();
            turn_below(&skeleton, &mut pose, elbow, Quat::from_axis_angle(axis, angle.to_radians()));
            pose
        };
        let (fps, frames) = (30.0, 90);
        // Bent 40 degrees, straightening over a third of a second, and back.
        let bend = |t: usize| 1.0 + 39.0 * ((t.abs_diff(45) as f32 - 15.0) / 10.0).clamp(0.0, 1.0);
        let poses: Vec<Vec<Vec3>> = (0..frames).map(|t| bent_at_elbow(bend(t), if (30..60).contains(&t) && t % 2 == 1 { Vec3::Z } else { Vec3::X })).collect();
        let floor = hanging[wrist].y + 80.0;
        let mut positions: Vec<Vec3> = poses.concat();
        keep_hands_above_floor(&mut positions, &skeleton, &roles, floor, fps);
        let joints = skeleton.len();
        let upper: Vec<Vec3> = positions.chunks_exact(joints).map(|f| (f[elbow] - f[shoulder]).normalize()).collect();
        let turns: Vec<f32> = upper.windows(2).map(|w| w[0].angle_between(w[1]).to_degrees()).collect();
        let largest = turns.iter().copied().fold(0.0, f32::max);
        assert!(largest < 5.0, "the upper arm turns {largest} degrees in one frame: {turns:?}");
        let side = |t: usize| bend_side(&positions[t * joints..(t + 1) * joints], (shoulder, elbow, wrist)).expect("the lifted arm is bent");
        let apart = side(45).angle_between(side(0)).to_degrees();
        assert!(apart < 30.0, "the lifted elbow stands out {apart} degrees from the bent frames' side");
    }
}
