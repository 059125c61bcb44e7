//! Analytic two-bone inverse kinematics on joint positions (hip, knee, ankle), the hip
//! offset that lets legs reach their targets, and the same reach on a whole pose (a limb
//! with everything it carries, a spine bending a head towards a point) for posing by hand.
//!
//! A whole pose is changed only by turning a joint (everything below it turns about it), so
//! every bone keeps its length and the pose stays one a skeleton can hold: solving its
//! rotations ([`super::solve_local_poses`]) gives it back.

use glam::{Mat3, Quat, Vec3};

use super::Skeleton;

/// The fraction of a fully stretched leg the hips are kept within: a straight knee has no
/// bending direction, and one that snaps straight looks mechanical.
pub const MAX_STRETCH: f32 = 0.995;

/// Where knee and ankle go so that the ankle reaches `target` from `hip` with bones of
/// lengths `upper` (hip-knee) and `lower` (knee-ankle), bending in the plane of the old knee
/// `pole`. An unreachable target is approached as far as the leg reaches along its line.
/// Bone lengths are exact whatever the target.
pub fn two_bone(hip: Vec3, target: Vec3, pole: Vec3, upper: f32, lower: f32) -> (Vec3, Vec3) {
    let to_target = target - hip;
    let reach_min = (upper - lower).abs() * 1.0001 + 1e-6 * (upper + lower);
    let reach_max = (upper + lower) * 0.99999;
    let d = to_target.length().clamp(reach_min, reach_max.max(reach_min));
    let bend = pole - hip;
    let axis = to_target.try_normalize().or_else(|| bend.try_normalize()).unwrap_or(Vec3::NEG_Y);
    let along = (upper * upper - lower * lower + d * d) / (2.0 * d);
    let out = (upper * upper - along * along).max(0.0).sqrt();
    let side = (bend - axis * bend.dot(axis)).try_normalize().unwrap_or_else(|| axis.any_orthonormal_vector());
    let knee = hip + axis * along + side * out;
    let ankle = hip + axis * d;
    (knee, ankle)
}

/// Below this fraction of the leg's length from hip to ankle, a leg is folded (a martial-arts
/// kick's heel at the hip): the hip-to-ankle line, a few centimetres long, swings from frame
/// to frame and takes the bending plane [`two_bone`] reads from it along (an `all` kick's
/// thigh turned 101 degrees in one frame where the network's own turned 27).
const FOLDED_BELOW: f32 = 0.25;

/// [`two_bone`]'s knee and ankle, with the knee turned towards the leg's own thigh direction
/// `own_thigh` as the leg folds (fully from half of [`FOLDED_BELOW`]), by as much as the ankle
/// is `free` to leave `target` (0 for a planted foot, which stays exact; 1 for a swinging
/// one): the ankle then follows the knee and misses the target by at most the hip-to-target
/// distance plus the difference of the two bones, a few centimetres in a fold.
pub fn two_bone_folding(hip: Vec3, target: Vec3, pole: Vec3, own_thigh: Vec3, (upper, lower): (f32, f32), free: f32) -> (Vec3, Vec3) {
    let (knee, ankle) = two_bone(hip, target, pole, upper, lower);
    let fold = target.distance(hip) / (upper + lower);
    let folded = ((FOLDED_BELOW - fold) / (FOLDED_BELOW / 2.0)).clamp(0.0, 1.0) * free.clamp(0.0, 1.0);
    let Some(own) = own_thigh.try_normalize().filter(|_| folded > 0.0) else { return (knee, ankle) };
    let thigh = ((knee - hip) / upper).lerp(own, folded).try_normalize().unwrap_or(own);
    let knee = hip + thigh * upper;
    let shin = (target - knee).try_normalize().unwrap_or(-thigh);
    (knee, knee + shin * lower)
}

/// The way a knee points on a leg running from hip to ankle along `leg`, on a body facing
/// `facing` (horizontal): the facing carried by the shortest turn from a leg hanging straight
/// down to `leg`. Forwards on a standing leg, up on a leg raised in front, down on one
/// stretched behind, still forwards on one lifted to the side. The facing's part square to
/// the leg says the same on a leg below the hip but turns over as a leg in front rises past
/// the horizontal (Human3.6M's sittingdown from its seed 117: the knee 8.1 cm in one frame).
pub fn knee_forward(facing: Vec3, leg: Vec3) -> Vec3 {
    let Some(leg) = leg.try_normalize() else { return facing };
    Quat::from_rotation_arc(Vec3::NEG_Y, leg) * facing
}

/// The smallest-effort shift of the hips that brings every `(hip, target, reach)` within
/// reach: each leg pulls the hips straight towards its target by what it lacks, a few rounds
/// so two planted legs settle together. Zero when every target is already in reach.
pub fn hip_offset(legs: &[(Vec3, Vec3, f32)]) -> Vec3 {
    let mut offset = Vec3::ZERO;
    for _ in 0..8 {
        let mut moved = false;
        for &(hip, target, reach) in legs {
            let to = target - (hip + offset);
            let lack = to.length() - reach;
            if lack > 1e-6 * reach {
                offset += to.normalize() * lack;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    offset
}

/// Most rounds of [`bend_towards`]; a reachable target is met to a hundredth of a
/// millimetre (on a metre-long chain) in far fewer.
const BEND_ROUNDS: usize = 100;

/// The largest turn (radians) a joint takes in one round of [`bend_towards`], so a far target
/// is approached along a smooth path rather than in one overshooting step.
const BEND_STEP: f32 = 0.2;

/// Turns everything below `joint` (not the joint itself) about it by `turn`, as a change of
/// that joint's rotation does.
pub fn turn_below(skeleton: &Skeleton, pose: &mut [Vec3], joint: usize, turn: Quat) {
    let pivot = pose[joint];
    // Parents come before their children, so the joints below lie after it.
    for (j, p) in pose.iter_mut().enumerate().skip(joint + 1) {
        if skeleton.is_ancestor(joint, j) {
            *p = pivot + turn * (*p - pivot);
        }
    }
}

/// The turn about `pivot` that points `from` at `to` (the shortest one; none when either is
/// at the pivot).
fn aim(pivot: Vec3, from: Vec3, to: Vec3) -> Quat {
    match ((from - pivot).try_normalize(), (to - pivot).try_normalize()) {
        (Some(a), Some(b)) => Quat::from_rotation_arc(a, b),
        _ => Quat::IDENTITY,
    }
}

/// Moves the end of the limb `[upper, middle, end]` (shoulder, elbow, wrist or hip, knee,
/// ankle) to `target` by turning the upper and middle joints, the middle one bending in the
/// plane of `pole` ([`two_bone`]); what the end carries (hand, foot) keeps its orientation in
/// the world, as an IK controller's does. A target out of reach is approached as far as the
/// limb stretches.
pub fn reach(skeleton: &Skeleton, pose: &mut [Vec3], [upper, middle, end]: [usize; 3], target: Vec3, pole: Vec3) {
    let (upper_len, lower_len) = (pose[middle].distance(pose[upper]), pose[end].distance(pose[middle]));
    let (new_middle, new_end) = two_bone(pose[upper], target, pole, upper_len, lower_len);
    let first = aim(pose[upper], pose[middle], new_middle);
    turn_below(skeleton, pose, upper, first);
    let second = aim(pose[middle], pose[end], new_end);
    turn_below(skeleton, pose, middle, second);
    turn_below(skeleton, pose, end, (second * first).inverse());
}

/// Bends the chain `spine` (joints from the bottom up, each an ancestor of `effector`) so `effector` comes to
/// `target`. Each round is a damped least-squares step: the smallest set of turns of the
/// chain's joints that moves the effector towards the target, in which a joint turns in
/// proportion to its lever (its distance to the effector), so a spine bends mostly low and
/// the neck follows, as a body bows. A target out of reach is approached as far as the chain
/// bends.
pub fn bend_towards(skeleton: &Skeleton, pose: &mut [Vec3], spine: &[usize], effector: usize, target: Vec3) {
    let length: f32 = spine.iter().map(|&j| pose[j].distance(pose[effector])).fold(0.0, f32::max);
    // Damping keeps the step finite where the chain cannot move the effector (straight
    // towards or away from a joint).
    let damping = Mat3::from_diagonal(Vec3::splat((0.1 * length).powi(2)));
    for _ in 0..BEND_ROUNDS {
        let error = target - pose[effector];
        if error.length() <= length * 1e-5 {
            break;
        }
        // With r the lever from a joint to the effector, a turn w moves the effector by
        // w x r; the Jacobian's J J^T sums |r|^2 I - r r^T over the joints, and J^T x is r x x.
        let levers: Vec<Vec3> = spine.iter().map(|&j| pose[effector] - pose[j]).collect();
        let jjt = levers.iter().fold(damping, |m, r| m + Mat3::from_diagonal(Vec3::splat(r.length_squared())) - outer(*r, *r));
        let x = jjt.inverse() * error;
        let turns: Vec<Vec3> = levers.iter().map(|r| r.cross(x)).collect();
        let largest = turns.iter().map(|w| w.length()).fold(0.0, f32::max);
        let scale = if largest > BEND_STEP { BEND_STEP / largest } else { 1.0 };
        // Top joint first: a turn then never moves a pivot still to turn about.
        for (&joint, turn) in spine.iter().zip(&turns).rev() {
            turn_below(skeleton, pose, joint, Quat::from_scaled_axis(*turn * scale));
        }
    }
}

/// The outer product a b^T.
fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_knee_points_forwards_on_a_hanging_leg_and_turns_smoothly_as_it_rises() {
        let facing = Vec3::Z;
        let close = |a: Vec3, b: Vec3| a.distance(b) < 1e-5;
        assert!(close(knee_forward(facing, Vec3::NEG_Y), facing));
        assert!(close(knee_forward(facing, Vec3::Z), Vec3::Y), "a leg raised in front: knee up");
        assert!(close(knee_forward(facing, Vec3::NEG_Z), Vec3::NEG_Y), "a leg stretched behind: knee down");
        assert!(close(knee_forward(facing, Vec3::X), facing), "a leg lifted to the side: knee forwards");
        // A leg in front swinging up past the horizontal: the knee's way turns by as much as
        // the leg does, never over.
        let mut last = knee_forward(facing, Vec3::new(0.0, -0.5, 1.0));
        for step in 1..=40 {
            let leg = Vec3::new(0.0, -0.5 + step as f32 * 0.025, 1.0);
            let knee = knee_forward(facing, leg);
            assert!(knee.dot(leg.normalize()).abs() < 1e-5, "square to the leg");
            assert!(knee.angle_between(last) < 0.05, "turned {} rad at step {step}", knee.angle_between(last));
            last = knee;
        }
    }

    #[test]
    fn reaches_with_exact_bones() {
        let hip = Vec3::new(0.0, 1.0, 0.0);
        let pole = Vec3::new(0.0, 0.5, 0.3);
        for target in [Vec3::new(0.1, 0.2, 0.1), Vec3::new(0.0, 0.05, 0.0), Vec3::new(0.3, -0.5, 0.0)] {
            let (knee, ankle) = two_bone(hip, target, pole, 0.45, 0.45);
            assert!((knee.distance(hip) - 0.45).abs() < 1e-5);
            assert!((ankle.distance(knee) - 0.45).abs() < 1e-5);
            if target.distance(hip) < 0.9 {
                assert!(ankle.distance(target) < 1e-5);
                // The knee bends towards the pole (forward, +z).
                assert!(knee.z > 0.0);
            }
        }
    }

    /// A kick's heel circling two centimetres from the hip while the thigh points forward: the
    /// knee stays with the thigh (plain two-bone IK swings it round with the heel), the bones
    /// keep their lengths, and a leg far from folded is solved as [`two_bone`] solves it.
    #[test]
    fn a_folded_leg_keeps_its_knee() {
        let hip = Vec3::new(0.0, 1.0, 0.0);
        let thigh = Vec3::new(0.0, 0.0, 0.45);
        let pole = hip + thigh + Vec3::Z * 0.45;
        let knees: Vec<Vec3> = (0..12)
            .map(|k| {
                let angle = k as f32 * std::f32::consts::TAU / 12.0;
                let heel = hip + Vec3::new(angle.cos(), angle.sin(), 0.3).normalize() * 0.02;
                let (knee, ankle) = two_bone_folding(hip, heel, pole, thigh, (0.45, 0.45), 1.0);
                assert!((knee.distance(hip) - 0.45).abs() < 1e-4 && (ankle.distance(knee) - 0.45).abs() < 1e-4);
                knee
            })
            .collect();
        for pair in knees.windows(2) {
            let turn = (pair[0] - hip).angle_between(pair[1] - hip).to_degrees();
            assert!(turn < 1.0, "the thigh turned {turn:.1} degrees between two heel positions");
        }
        let target = Vec3::new(0.1, 0.2, 0.1);
        assert_eq!(two_bone_folding(hip, target, pole, thigh, (0.45, 0.45), 1.0), two_bone(hip, target, pole, 0.45, 0.45));
        // A planted foot's ankle stays on its target however far the leg folds.
        let heel = hip + Vec3::new(0.0, 0.01, 0.02);
        assert_eq!(two_bone_folding(hip, heel, pole, thigh, (0.45, 0.45), 0.0), two_bone(hip, heel, pole, 0.45, 0.45));
        // Folding gradually, from a quarter of the leg's length to a twentieth, the knee
        // moves on smoothly: no step where the turn towards the thigh sets in.
        let knees: Vec<Vec3> = (0..=40)
            .map(|k| {
                let heel = hip + Vec3::new(0.0, -1.0, 0.3).normalize() * (0.225 - k as f32 * 0.18 / 40.0);
                two_bone_folding(hip, heel, pole, thigh, (0.45, 0.45), 1.0).0
            })
            .collect();
        for pair in knees.windows(2) {
            let turn = (pair[0] - hip).angle_between(pair[1] - hip).to_degrees();
            assert!(turn < 3.0, "the thigh turned {turn:.1} degrees between two folds");
        }
    }

    #[test]
    fn hips_move_only_as_far_as_needed() {
        let legs = [(Vec3::new(0.1, 1.0, 0.0), Vec3::new(0.1, 0.0, 0.5), 0.9)];
        let offset = hip_offset(&legs);
        let (hip, target, reach) = legs[0];
        assert!(((target - (hip + offset)).length() - reach).abs() < 1e-4);
        assert_eq!(hip_offset(&[(hip, Vec3::new(0.1, 0.3, 0.0), 0.9)]), Vec3::ZERO);
    }

    /// A pelvis, and below it a hip, a knee, an ankle, a toe, and a second branch (the other
    /// leg's top) that nothing here may move.
    fn leg() -> Skeleton {
        let names = ["pelvis", "hip", "knee", "ankle", "toe", "other"].map(String::from).to_vec();
        let offsets = vec![Vec3::new(0.0, 1.0, 0.0), Vec3::new(-0.1, 0.0, 0.0), Vec3::new(0.0, -0.45, 0.02), Vec3::new(0.0, -0.45, -0.02), Vec3::new(0.0, -0.05, 0.15), Vec3::new(0.1, 0.0, 0.0)];
        Skeleton::new(names, vec![None, Some(0), Some(1), Some(2), Some(3), Some(0)], offsets, 1.0).unwrap()
    }

    fn bones(s: &Skeleton, pose: &[Vec3]) -> Vec<f32> {
        (0..s.len()).map(|j| s.parents()[j].map_or(0.0, |p| pose[j].distance(pose[p]))).collect()
    }

    #[test]
    fn a_limb_reaches_and_its_foot_keeps_its_orientation() {
        let s = leg();
        let rest = s.rest_positions();
        for target in [Vec3::new(0.0, 0.3, 0.3), Vec3::new(-0.3, 0.5, 0.0), Vec3::new(-0.1, 2.5, 0.0)] {
            let mut pose = rest.clone();
            reach(&s, &mut pose, [1, 2, 3], target, rest[2]);
            let lengths = bones(&s, &pose).into_iter().zip(bones(&s, &rest)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            assert!(lengths < 1e-5, "bones changed by {lengths}");
            assert!((pose[4] - pose[3]).distance(rest[4] - rest[3]) < 1e-5, "the foot turned");
            assert_eq!([pose[0], pose[1], pose[5]], [rest[0], rest[1], rest[5]], "joints outside the limb moved");
            if target.distance(rest[1]) < 0.89 {
                assert!(pose[3].distance(target) < 1e-5, "the ankle is {} from {target}", pose[3].distance(target));
            } else {
                // Out of reach: stretched along the line to it.
                let towards = (target - pose[1]).normalize();
                assert!((pose[3] - pose[1]).normalize().dot(towards) > 0.9999);
            }
        }
    }

    #[test]
    fn a_chain_bends_its_end_onto_a_target_with_the_bend_spread() {
        let s = leg();
        let rest = s.rest_positions();
        let mut pose = rest.clone();
        let target = Vec3::new(0.2, 0.4, 0.2);
        bend_towards(&s, &mut pose, &[1, 2], 4, target);
        assert!(pose[4].distance(target) < 1e-4, "the end is {} off", pose[4].distance(target));
        let lengths = bones(&s, &pose).into_iter().zip(bones(&s, &rest)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        assert!(lengths < 1e-5);
        // Both joints bent (neither took it all): the thigh turned, and the knee's angle changed.
        let thigh = (rest[2] - rest[1]).angle_between(pose[2] - pose[1]);
        let knee = |p: &[Vec3]| (p[1] - p[2]).angle_between(p[3] - p[2]);
        assert!(thigh > 0.05 && (knee(&pose) - knee(&rest)).abs() > 0.05, "thigh turned {thigh}, knee {} -> {}", knee(&rest), knee(&pose));
        let mut untouched = rest.clone();
        turn_below(&s, &mut untouched, 4, Quat::from_rotation_y(1.0));
        assert_eq!(untouched, rest, "a leaf turns nothing");
    }
}
