//! Posing a frame by hand: the joints an animator drags (hands, feet, head, hips) and what
//! dragging one does to the rest of the body, on [`super::ik`]'s whole-pose solvers.
//!
//! - A hand or a foot is the end of a two-bone limb (shoulder-elbow-wrist, hip-knee-ankle):
//!   the limb reaches for the target, the elbow or knee bending the way it bent, the hand or
//!   foot keeping its orientation.
//! - The head bends the spine (the joints between the hips and the head), spread along it.
//! - The hips carry the body to the target while the feet stay where they were (each leg
//!   reaches back for its own foot), so dragging them down crouches.
//! - A foot dragged further than its leg reaches carries the hips along as far as it lacks
//!   ([`hip_offset`]), the other foot staying planted: a stride widens instead of stopping
//!   short.

use glam::Vec3;

use super::ik::{bend_towards, hip_offset, reach, MAX_STRETCH};
use super::{JointRoles, RolesError, Side, Skeleton};

/// A joint that can be dragged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effector {
    Hand(Side),
    Foot(Side),
    Head,
    Hips,
}

impl Effector {
    pub const ALL: [Effector; 6] = [Effector::Hand(Side::Left), Effector::Hand(Side::Right), Effector::Foot(Side::Left), Effector::Foot(Side::Right), Effector::Head, Effector::Hips];

    /// Whether dragging it moves where the body stands (a key of it fixes the root).
    pub fn moves_root(self) -> bool {
        self == Effector::Hips
    }
}

/// The chains of one skeleton that posing moves.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseRig {
    /// Per side (left, right): shoulder, elbow, wrist.
    arms: [[usize; 3]; 2],
    /// Per side: hip, knee, ankle.
    legs: [[usize; 3]; 2],
    /// The joints between the body root and the head, from the bottom up.
    spine: Vec<usize>,
    head: usize,
    hips: usize,
}

impl PoseRig {
    /// The rig of a humanoid skeleton (its [`JointRoles`]); an error names what it lacks.
    pub fn new(skeleton: &Skeleton) -> Result<Self, RolesError> {
        let roles = JointRoles::new(skeleton)?;
        let arm = |hand: usize| -> Result<[usize; 3], RolesError> {
            let elbow = joint_above(skeleton, hand);
            let shoulder = elbow.and_then(|e| joint_above(skeleton, e));
            match (shoulder, elbow) {
                (Some(s), Some(e)) if s != roles.body_root && e != roles.body_root => Ok([s, e, hand]),
                _ => Err(RolesError { missing: vec![format!("an arm above joint '{}'", skeleton.names()[hand])] }),
            }
        };
        let leg = |side: Side| {
            let l = roles.leg(side);
            [l.hip, l.knee, l.ankle]
        };
        let mut spine: Vec<usize> = skeleton.ancestors(roles.head).take_while(|&j| j != roles.body_root).collect();
        spine.reverse();
        Ok(Self { arms: [arm(roles.left_hand)?, arm(roles.right_hand)?], legs: [leg(Side::Left), leg(Side::Right)], spine, head: roles.head, hips: roles.body_root })
    }

    /// The joint an effector drags.
    pub fn joint(&self, effector: Effector) -> usize {
        match effector {
            Effector::Hand(side) => self.arms[side_index(side)][2],
            Effector::Foot(side) => self.legs[side_index(side)][2],
            Effector::Head => self.head,
            Effector::Hips => self.hips,
        }
    }

    /// `frame` (world positions on the rig's skeleton) with `effector`'s joint dragged to
    /// `target` (same units), the body following as the module says.
    pub fn posed(&self, skeleton: &Skeleton, frame: &[Vec3], effector: Effector, target: Vec3) -> Vec<Vec3> {
        let mut pose = frame.to_vec();
        match effector {
            Effector::Hand(side) => {
                let limb = self.arms[side_index(side)];
                reach(skeleton, &mut pose, limb, target, frame[limb[1]]);
            }
            Effector::Foot(side) => {
                let (limb, other) = (self.legs[side_index(side)], self.legs[1 - side_index(side)]);
                let shift = hip_offset(&[(frame[limb[0]], target, leg_reach(frame, limb)), (frame[other[0]], frame[other[2]], leg_reach(frame, other))]);
                self.carry_body(skeleton, &mut pose, frame, shift);
                reach(skeleton, &mut pose, limb, target, frame[limb[1]] + shift);
            }
            Effector::Head => bend_towards(skeleton, &mut pose, &self.spine, self.head, target),
            Effector::Hips => self.carry_body(skeleton, &mut pose, frame, target - frame[self.hips]),
        }
        pose
    }

    /// Moves the body by `shift` with its feet staying where `frame` has them.
    fn carry_body(&self, skeleton: &Skeleton, pose: &mut [Vec3], frame: &[Vec3], shift: Vec3) {
        if shift == Vec3::ZERO {
            return;
        }
        for (j, p) in pose.iter_mut().enumerate() {
            if skeleton.is_ancestor(self.hips, j) {
                *p += shift;
            }
        }
        for limb in self.legs {
            // Each knee bends the way it did: towards its old place, carried with the hips.
            reach(skeleton, pose, limb, frame[limb[2]], frame[limb[1]] + shift);
        }
    }
}

/// How far a leg may reach from its hip: nearly straight ([`MAX_STRETCH`]), or as straight
/// as it already is.
fn leg_reach(frame: &[Vec3], [hip, knee, ankle]: [usize; 3]) -> f32 {
    let length = frame[knee].distance(frame[hip]) + frame[ankle].distance(frame[knee]);
    (length * MAX_STRETCH).max(frame[ankle].distance(frame[hip]))
}

fn side_index(side: Side) -> usize {
    match side {
        Side::Left => 0,
        Side::Right => 1,
    }
}

/// The nearest ancestor of `joint` not at its place in the rest pose (a zero-length bone
/// joins two names for one point).
fn joint_above(skeleton: &Skeleton, joint: usize) -> Option<usize> {
    let rest = skeleton.rest_positions();
    let scale = rest.iter().map(|p| p.length()).fold(0.0, f32::max);
    skeleton.ancestors(joint).find(|&a| rest[a].distance(rest[joint]) > scale * 1e-4)
}
