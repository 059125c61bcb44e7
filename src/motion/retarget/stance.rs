//! Where the retargeted body stands: its planted feet where the source's are.
//!
//! The hips are placed by the middle of the hip sockets (the source's, scaled by the ratio of
//! leg lengths), so a leg hangs from the same height whatever the pelvis looks like. That
//! alone leaves two differences that lift or sink the feet: the legs' proportions (a longer
//! thigh and shorter shin reach as far down standing, not sitting) and the feet's shape
//! (Human3.6M's ankle is 2-3 cm above the floor when planted, a Rigify metarig's 8.5 cm, with
//! a heel below it). So each frame the whole body is shifted by how far the target's planted
//! feet miss the source's: across the floor by the legs (socket to ankle, the source's
//! scaled), so a planted foot stays where the source's stands; up and down by the soles (each
//! foot's lowest joint), so it stands on the floor. Every bone still points as the source's.
//! Contacts are the source's ([`foot_contacts`]); with both feet planted the shift is their
//! mean and each leg makes up the rest. A contact weighs fully while it holds and fades in and
//! out over a few frames either side, so the shift does not jump when a foot lands or lifts;
//! frames with both feet in the air take the shift in between.

use glam::{Quat, Vec3};

use super::super::contacts::{box_average, foot_contacts, ContactConfig};
use super::super::keys::{Key, KeyJoints};
use super::super::ik::two_bone;
use super::super::{JointRoles, LocalPose, Leg, Motion, Skeleton};
use super::{required, RetargetError};

/// Seconds either side over which a contact fades in and out of the shift.
const BLEND_SECONDS: f32 = 0.1;

/// One leg's joints that standing reads, on one skeleton.
#[derive(Clone, Debug)]
struct LegJoints {
    socket: usize,
    knee: usize,
    ankle: usize,
    /// The ankle and every joint below it (toes, toe tips, heel): what can touch the floor.
    foot: Vec<usize>,
}

impl LegJoints {
    fn new(skeleton: &Skeleton, [socket, knee, ankle]: [usize; 3]) -> LegJoints {
        LegJoints { socket, knee, ankle, foot: skeleton.subtree(ankle) }
    }

    /// Socket to ankle in `frame`.
    fn reach(&self, frame: &[Vec3]) -> Vec3 {
        frame[self.ankle] - frame[self.socket]
    }

    /// The height of the foot's lowest joint in `frame`.
    fn sole(&self, frame: &[Vec3]) -> f32 {
        self.foot.iter().map(|&j| frame[j].y).fold(f32::INFINITY, f32::min)
    }
}

/// One frame's placement of the target body.
#[derive(Clone, Copy, Debug)]
pub(super) struct Placement {
    /// The whole body's shift.
    pub shift: Vec3,
    /// How far each planted foot (left, right) still has to move after the shift.
    pub lifts: [Vec3; 2],
}

/// The legs of both skeletons (left, right) and how the source's contacts are read.
#[derive(Clone, Debug)]
pub(super) struct Stance {
    source: [LegJoints; 2],
    target: [LegJoints; 2],
    source_roles: JointRoles,
    /// Target units per source unit.
    scale: f32,
    /// Whether a planted foot keeps, through its contact, the place across the floor its
    /// hip socket gave it as the contact began ([`held_in_contact`]).
    pub holds_planted_feet: bool,
}

const LEGS: [[Key; 4]; 2] = [
    [Key::LeftUpLeg, Key::LeftLeg, Key::LeftFoot, Key::LeftToeBase],
    [Key::RightUpLeg, Key::RightLeg, Key::RightFoot, Key::RightToeBase],
];

impl Stance {
    pub fn new(source: &Skeleton, source_keys: &KeyJoints, target: &Skeleton, target_keys: &KeyJoints, scale: f32) -> Result<Stance, RetargetError> {
        let legs = |skeleton: &Skeleton, keys: &KeyJoints, side: &'static str| -> Result<[LegJoints; 2], RetargetError> {
            let [left, right] = LEGS.map(|[socket, knee, ankle, _]| Ok(LegJoints::new(skeleton, [required(keys, socket, side)?, required(keys, knee, side)?, required(keys, ankle, side)?])));
            Ok([left?, right?])
        };
        Ok(Stance { source: legs(source, source_keys, "source")?, target: legs(target, target_keys, "target")?, source_roles: roles(source_keys)?, scale, holds_planted_feet: true })
    }

    /// Per frame, where the whole target body goes (`target`: its joint positions, frame
    /// after frame, as placed by the hip sockets) to stand where `source` stands.
    pub fn placements(&self, source: &Motion, target: &[Vec3]) -> Vec<Placement> {
        let frames = source.frames();
        let joints = target.len() / frames.max(1);
        let contacts = foot_contacts(source, &self.source_roles, &ContactConfig::default());
        let half = (BLEND_SECONDS * source.fps).round() as usize;
        let weights = [&contacts.left, &contacts.right].map(|flags| box_average(&grown(flags, half), half));
        let mut misses: Vec<[Vec3; 2]> = (0..frames).map(|t| [0, 1].map(|side| self.miss(side, source.frame(t), &target[t * joints..(t + 1) * joints]))).collect();
        if self.holds_planted_feet {
            let sockets: Vec<[Vec3; 2]> = (0..frames).map(|t| [0, 1].map(|side| self.socket_offset(side, source.frame(t), &target[t * joints..(t + 1) * joints]))).collect();
            for side in 0..2 {
                for (t, held) in held_in_contact(&weights[side], &sockets, side) {
                    misses[t][side] += held - sockets[t][side];
                }
            }
        }
        let shifts = filled_in(
            &(0..frames)
                .map(|t| {
                    let weight = weights[0][t] + weights[1][t];
                    (weight > 1e-3).then(|| (misses[t][0] * weights[0][t] + misses[t][1] * weights[1][t]) / weight)
                })
                .collect::<Vec<_>>(),
        );
        (0..frames).map(|t| Placement { shift: shifts[t], lifts: [0, 1].map(|side| (misses[t][side] - shifts[t]) * weights[side][t]) }).collect()
    }

    /// Bends the target's leg on `side` so that its ankle moves by `lift`, the foot keeping
    /// its turn (`pose` of one frame, `world` its joints' world rotations and `at` their
    /// positions): with both feet planted, the shift of the body is their mean, and each leg
    /// makes up the rest (Human3.6M's two ankles stand 1-3 cm apart in height, which a heeled
    /// foot turns into a sole above the floor; and a stance wider or narrower than the
    /// source's would slide the feet as the weight moves from one to the other).
    pub fn lift_foot(&self, side: usize, lift: Vec3, skeleton: &Skeleton, pose: &mut LocalPose, world: &[Quat], at: &[Vec3]) {
        let leg = &self.target[side];
        let (hip, knee, ankle) = (at[leg.socket], at[leg.knee], at[leg.ankle]);
        let (new_knee, new_ankle) = two_bone(hip, ankle + lift, knee, hip.distance(knee), knee.distance(ankle));
        let arc = |from: Vec3, to: Vec3| match (from.try_normalize(), to.try_normalize()) {
            (Some(a), Some(b)) => Quat::from_rotation_arc(a, b),
            _ => Quat::IDENTITY,
        };
        let thigh = arc(knee - hip, new_knee - hip);
        let shin = arc(thigh * (ankle - knee), new_ankle - new_knee) * thigh;
        // The thigh's joints turn by `thigh`, the shin's by `shin`, the foot's not at all.
        let turn = |j: usize| match () {
            _ if leg.foot.contains(&j) => Quat::IDENTITY,
            _ if j == leg.knee || skeleton.is_ancestor(leg.knee, j) => shin,
            _ if j == leg.socket || skeleton.is_ancestor(leg.socket, j) => thigh,
            _ => Quat::IDENTITY,
        };
        for j in [leg.socket, leg.knee, leg.ankle] {
            let Some(p) = skeleton.parents()[j] else { continue };
            pose.rotations[j] = ((turn(p) * world[p]).inverse() * turn(j) * world[j]).normalize();
        }
    }

    /// Where the target's hip socket on `side` stands across the floor from the source's,
    /// scaled (the source's `frame`, the target's `placed`): a planted foot is placed from
    /// its socket, and two pelvises of other widths or depths turning alike move their
    /// sockets differently.
    fn socket_offset(&self, side: usize, frame: &[Vec3], placed: &[Vec3]) -> Vec3 {
        let offset = placed[self.target[side].socket] - frame[self.source[side].socket] * self.scale;
        Vec3::new(offset.x, 0.0, offset.z)
    }

    /// How far the target's foot on `side` is from where the source's stands in the source's
    /// `frame` (the target's frame `placed`): across the floor, the target's socket-to-ankle
    /// against the source's (scaled); up, the target's sole against the source's (scaled).
    fn miss(&self, side: usize, frame: &[Vec3], placed: &[Vec3]) -> Vec3 {
        let (source, target) = (&self.source[side], &self.target[side]);
        let across = source.reach(frame) * self.scale - target.reach(placed);
        Vec3::new(across.x, source.sole(frame) * self.scale - target.sole(placed), across.z)
    }
}

/// The source's roles for contact detection, from its key joints (the foot: ankle and toe).
fn roles(keys: &KeyJoints) -> Result<JointRoles, RetargetError> {
    let get = |key: Key| required(keys, key, "source");
    let leg = |[hip, knee, ankle, toe]: [Key; 4]| -> Result<Leg, RetargetError> { Ok(Leg { hip: get(hip)?, knee: get(knee)?, ankle: get(ankle)?, toe: keys.get(toe), toe_end: None }) };
    let [left, right] = LEGS.map(leg);
    Ok(JointRoles { body_root: get(Key::Hips)?, left: left?, right: right?, head: get(Key::Head)?, head_end: None, left_hand: get(Key::LeftHand)?, right_hand: get(Key::RightHand)? })
}

/// Each frame of a contact on `side` (where its `weight` is above zero), with the socket
/// offset the contact began with: through the contact the foot keeps the place that offset
/// gave it while the pelvis turns, as the source's planted foot keeps its own. Placed from
/// its socket frame by frame, a Rigify metarig's planted ankle slid 3.9 cm within one
/// contact of a walk from `models/all` (its sockets 6 cm above and 3 cm in front of its
/// pelvis bone, 19.6 cm apart).
fn held_in_contact(weight: &[f32], sockets: &[[Vec3; 2]], side: usize) -> Vec<(usize, Vec3)> {
    let mut held = Vec::new();
    let mut start = None;
    for (t, w) in weight.iter().enumerate() {
        if *w <= 0.0 {
            start = None;
            continue;
        }
        let first = *start.get_or_insert(t);
        held.push((t, sockets[first][side]));
    }
    held
}

/// 1 where a flag is set within `half` places, else 0: averaged over the same window, a
/// contact weighs fully on every frame it holds and fades out over `half` frames either side.
fn grown(flags: &[bool], half: usize) -> Vec<f32> {
    (0..flags.len()).map(|t| if flags[t.saturating_sub(half)..(t + half + 1).min(flags.len())].contains(&true) { 1.0 } else { 0.0 }).collect()
}

/// `values` with each gap (None) filled by the straight line between its neighbours, held
/// at the ends; all zero when there is no value at all.
fn filled_in(values: &[Option<Vec3>]) -> Vec<Vec3> {
    let known: Vec<(usize, Vec3)> = values.iter().enumerate().filter_map(|(t, v)| v.map(|v| (t, v))).collect();
    let (Some(&first), Some(&last)) = (known.first(), known.last()) else { return vec![Vec3::ZERO; values.len()] };
    let mut out = vec![first.1; values.len()];
    for pair in known.windows(2) {
        let ((a, va), (b, vb)) = (pair[0], pair[1]);
        for (t, v) in out.iter_mut().enumerate().take(b + 1).skip(a) {
            *v = va.lerp(vb, (t - a) as f32 / (b - a) as f32);
        }
    }
    out[last.0..].iter_mut().for_each(|v| *v = last.1);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each contact holds the socket offset of its own first frame, fade-in included; the
    /// frames between contacts hold none.
    #[test]
    fn a_contact_holds_the_offset_it_began_with() {
        let weight = [0.0, 0.5, 1.0, 1.0, 0.0, 1.0, 0.5];
        let sockets: Vec<[Vec3; 2]> = (0..weight.len()).map(|t| [Vec3::ZERO, Vec3::splat(t as f32)]).collect();
        let held: Vec<(usize, f32)> = held_in_contact(&weight, &sockets, 1).into_iter().map(|(t, v)| (t, v.x)).collect();
        assert_eq!(held, vec![(1, 1.0), (2, 1.0), (3, 1.0), (5, 5.0), (6, 5.0)]);
    }

    #[test]
    fn gaps_are_bridged_and_ends_held() {
        let v = |x: f32| Some(Vec3::splat(x));
        let filled = filled_in(&[None, v(1.0), None, None, v(4.0), None]);
        assert_eq!(filled.iter().map(|p| p.x).collect::<Vec<_>>(), vec![1.0, 1.0, 2.0, 3.0, 4.0, 4.0]);
        assert_eq!(filled_in(&[None, None]), vec![Vec3::ZERO; 2]);
    }
}
