//! Retargeting: a take on one humanoid skeleton moved onto another with other joint names,
//! bone lengths, joint counts and rest pose.
//!
//! Both skeletons name the same twenty key joints ([`Key`]: hips, chest, neck, head, collars,
//! arms, forearms, hands, thighs, shins, feet, toes; [`super::guess_key_joints`] finds them).
//! The key joints that both skeletons have form a small tree (each one's parent is its nearest
//! mapped ancestor). Each frame, every bone of that tree below the trunk (neck, collars, arms,
//! legs, feet) turns the shortest way from its parent's turn to point on the target where
//! the same bone points on the source; the pelvis and the chest, rigid pieces that carry
//! several bones and are shaped differently on every skeleton, turn as the source's pieces
//! turn ([`body`]). The first joint of an unmapped stretch between two mapped ones (extra spine
//! joints, CMU's buttock joint) turns towards where the next mapped joint should be; the
//! target's other joints (fingers, twist joints, end sites) are carried rigidly by their
//! nearest mapped ancestor. The hips are placed by the middle of the hip sockets (the
//! source's, scaled by the ratio of leg lengths: a shorter character takes shorter steps), and
//! the body is shifted so the planted feet stand where the source's do ([`stance`]).
//!
//! Why bone directions rather than copying local rotations: a local rotation only means
//! something relative to its skeleton's rest pose, and rest poses differ (the CMU files stand
//! in a T-pose, Mixamo-style rigs in an A-pose, Human3.6M with its arms straight up, and
//! Bandai's rest is not a standing pose at all: its joints' frames carry the exporter's joint
//! orients). Transferring each bone's world direction is the same as transferring rotations
//! relative to a common rest pose, without having to build one; [`RestPose`] is detected and
//! reported so a user can see what the two rigs stand in.

use std::sync::Arc;

use glam::{Quat, Vec3};

use super::keys::{Key, KeyJoints};
use super::roles::mean_leg_length;
use super::{LocalPose, Motion, Skeleton};
use body::BodyPiece;
use stance::Stance;

mod body;
mod stance;

/// What a skeleton's rest pose (all rotations identity) looks like, judged from the angle
/// between the upper arms and the body's up direction (hips to head), with the legs hanging
/// down: arms out sideways is a T-pose, arms 25-70 degrees below that an A-pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RestPose {
    TPose,
    APose,
    /// Arms up or down, legs not hanging, or a rest that is not a standing pose (Bandai's).
    Other,
}

impl RestPose {
    pub fn detect(skeleton: &Skeleton, keys: &KeyJoints) -> RestPose {
        let rest = skeleton.rest_positions();
        let dir = |a: Key, b: Key| -> Option<Vec3> { Some((rest[keys.get(b)?] - rest[keys.get(a)?]).normalize_or_zero()) };
        let (Some(up), Some(left_arm), Some(right_arm), Some(left_leg), Some(right_leg)) = (
            dir(Key::Hips, Key::Head),
            dir(Key::LeftArm, Key::LeftForeArm),
            dir(Key::RightArm, Key::RightForeArm),
            dir(Key::LeftUpLeg, Key::LeftFoot),
            dir(Key::RightUpLeg, Key::RightFoot),
        ) else {
            return RestPose::Other;
        };
        let legs_hang = left_leg.dot(up) < -0.9 && right_leg.dot(up) < -0.9;
        let arm_angle = (left_arm.dot(up).clamp(-1.0, 1.0).acos() + right_arm.dot(up).clamp(-1.0, 1.0).acos()).to_degrees() / 2.0;
        match (legs_hang, arm_angle) {
            (true, a) if (70.0..115.0).contains(&a) => RestPose::TPose,
            (true, a) if (115.0..160.0).contains(&a) => RestPose::APose,
            _ => RestPose::Other,
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            RestPose::TPose => "T-pose",
            RestPose::APose => "A-pose",
            RestPose::Other => "neither T- nor A-pose",
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RetargetError {
    #[error("the {side} skeleton has no joint for {}", .keys.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "))]
    MissingKeys { side: &'static str, keys: Vec<Key> },
    #[error("the {side} skeleton's {key} is not below its hips")]
    NotBelowHips { side: &'static str, key: &'static str },
    #[error("the target skeleton's {part} faces nowhere: its side-to-side and up lines are parallel")]
    NoFacing { part: &'static str },
}

/// One bone of the mapped tree: a key joint both skeletons have.
#[derive(Clone, Debug)]
struct Link {
    key: Key,
    target: usize,
    source: usize,
    /// Index of the nearest mapped ancestor in `links` (None for the hips).
    parent: Option<usize>,
    /// Target rest distance from the parent link's joint.
    length: f32,
    turn: Turn,
}

/// How a link's joint turns each frame.
#[derive(Clone, Debug)]
enum Turn {
    /// The hips and the chest: as the source's pelvis and chest turn ([`BodyPiece`]).
    Piece(BodyPiece),
    /// Towards its child link (index into `links`) as the source's bone points, the shortest
    /// way from its parent link's turn (so its twist follows the parent's); `rest` is that
    /// bone's direction on the target at rest. A foot is then twisted about that bone so
    /// that its rest side-to-side line (`level`) lies level: the twist the leg hands down is
    /// arbitrary (a direction says nothing about it), and a rolled foot sinks one edge of its
    /// heel into the floor (2 cm on a Rigify metarig); a steep foot turns on its ankle's hinge
    /// instead ([`foot_across_line`]).
    Towards { child: usize, rest: Vec3, level: Option<Vec3> },
    /// A toe with a tip on both skeletons, for a generated take
    /// ([`Retarget::with_toes_to_tips`]): towards the source joint `tip` as the source's toe
    /// points, the shortest way from its foot's turn; `rest` is the target's toe at rest.
    TowardsTip { tip: usize, rest: Vec3 },
    /// No child link (hands, feet without toes, the head): carried by its parent link.
    Carried,
}

/// An unmapped joint that turns towards the joint of `link`, from that of `from` (its parent
/// link) along the source's bone.
#[derive(Clone, Copy, Debug)]
struct Aim {
    link: usize,
    from: usize,
}

/// A prepared mapping from one skeleton onto another; [`Retarget::apply`] moves takes.
#[derive(Clone, Debug)]
pub struct Retarget {
    target: Arc<Skeleton>,
    rest_positions: Vec<Vec3>,
    source_keys: KeyJoints,
    /// Mapped key joints in target joint order (the hips first).
    links: Vec<Link>,
    /// For each target joint, its link when it is a mapped joint.
    link_of: Vec<Option<usize>>,
    /// For the first unmapped joint on the way from one mapped joint to the next (an extra
    /// spine joint, CMU's buttock joint between hips and thigh), the link it turns towards, so
    /// the chain reaches where the next mapped joint should be.
    aims: Vec<Option<Aim>>,
    /// The target's root (the hips, or a joint above them that carries them unturned).
    root: usize,
    /// Hips to the middle of the hip sockets on the target at rest.
    sockets_at_rest: Vec3,
    /// The source's hip sockets, whose middle places the target's.
    source_sockets: (usize, usize),
    /// Target units of hips motion per source unit: the ratio of leg lengths.
    root_scale: f32,
    stance: Stance,
    /// Whether a steep foot turns on its ankle's hinge rather than lying level
    /// ([`foot_across_line`]; [`Retarget::as_all_was_trained`]).
    steep_feet_on_hinges: bool,
    pub source_rest: RestPose,
    pub target_rest: RestPose,
}

impl Retarget {
    pub fn new(source: &Skeleton, source_keys: &KeyJoints, target: Arc<Skeleton>, target_keys: &KeyJoints) -> Result<Retarget, RetargetError> {
        for (side, keys) in [("source", source_keys), ("target", target_keys)] {
            let missing = keys.missing_required();
            if !missing.is_empty() {
                return Err(RetargetError::MissingKeys { side, keys: missing });
            }
        }
        let rest = target.rest_positions();
        let links = links(source, source_keys, &target, target_keys, &rest)?;
        let link_of: Vec<Option<usize>> = (0..target.len()).map(|j| links.iter().position(|l| l.target == j)).collect();
        let mut aims = vec![None; target.len()];
        for (i, link) in links.iter().enumerate() {
            let Some(parent) = link.parent else { continue };
            let first = target.child_towards(links[parent].target, link.target).filter(|&c| c != link.target);
            if let Some(f) = first.filter(|&f| aims[f].is_none()) {
                aims[f] = Some(Aim { link: i, from: parent });
            }
        }
        let (left, right) = (required(target_keys, Key::LeftUpLeg, "target")?, required(target_keys, Key::RightUpLeg, "target")?);
        let hips = links[0].target;
        let root_scale = leg_length(&rest, target_keys) / leg_length(&source.rest_positions(), source_keys).max(f32::MIN_POSITIVE);
        Ok(Retarget {
            source_rest: RestPose::detect(source, source_keys),
            target_rest: RestPose::detect(&target, target_keys),
            stance: Stance::new(source, source_keys, &target, target_keys, root_scale)?,
            steep_feet_on_hinges: true,
            root: target.chain_from_root(hips)[0],
            sockets_at_rest: (rest[left] + rest[right]) / 2.0 - rest[hips],
            source_sockets: (required(source_keys, Key::LeftUpLeg, "source")?, required(source_keys, Key::RightUpLeg, "source")?),
            source_keys: source_keys.clone(),
            target,
            rest_positions: rest,
            links,
            link_of,
            aims,
            root_scale,
        })
    }

    /// The mapping with each toe turning towards its tip as the source's toe points, where
    /// both skeletons give it one (`source` is the skeleton `new` was given), instead of riding
    /// on its foot. For generated takes: the foot lock rolls a planted heel about toes it keeps
    /// on the floor, and a toe carried by its foot tilted with it (a Mixamo-named rig's toe
    /// tips 2.2 cm into the floor in Blender). Not for captures, whose toe markers whip with
    /// the foot (Human3.6M's: `all`'s clips read capture glitches in their toes).
    pub fn with_toes_to_tips(mut self, source: &Skeleton) -> Retarget {
        let source_rest = source.rest_positions();
        for link in self.links.iter_mut().filter(|l| matches!(l.key, Key::LeftToeBase | Key::RightToeBase) && matches!(l.turn, Turn::Carried)) {
            if let (Some(tip), Some(end)) = (toe_tip(source, &source_rest, link.source), toe_tip(&self.target, &self.rest_positions, link.target)) {
                link.turn = Turn::TowardsTip { tip, rest: self.rest_positions[end] - self.rest_positions[link.target] };
            }
        }
        self
    }

    /// The mapping as `models/all`'s training clips were retargeted: every foot's
    /// side-to-side line level however steep the foot, and each planted foot placed from its
    /// hip socket frame by frame. Its weights, seed bank and texture learned those feet, and a
    /// steep foot's roll moves its heel and toes (Bandai's runs and dashes in their back
    /// swing). The next training of `all` drops it (docs/DESIGN.md, "Steep feet on their
    /// hinges").
    pub fn as_all_was_trained(mut self) -> Retarget {
        self.steep_feet_on_hinges = false;
        self.stance.holds_planted_feet = false;
        self
    }

    /// The keys this mapping moves (those both skeletons have).
    pub fn keys(&self) -> impl Iterator<Item = Key> + '_ {
        self.links.iter().map(|l| l.key)
    }

    /// Target units of hips travel per source unit.
    pub fn root_scale(&self) -> f32 {
        self.root_scale
    }

    /// `motion` (on the source skeleton) on the target skeleton, with its rotations, at the
    /// same frame rate and frame count.
    pub fn apply(&self, motion: &Motion) -> Motion {
        let joints = self.target.len();
        let mut poses = Vec::with_capacity(motion.frames());
        let mut positions = Vec::with_capacity(motion.frames() * joints);
        let mut turns = vec![Quat::IDENTITY; self.links.len()];
        let mut worlds = Vec::with_capacity(motion.frames());
        for t in 0..motion.frames() {
            let (pose, world, placed) = self.pose(motion.frame(t), &mut turns);
            poses.push(pose);
            worlds.push(world);
            positions.extend(placed);
        }
        let placements = self.stance.placements(motion, &positions);
        for (t, (pose, place)) in poses.iter_mut().zip(placements).enumerate() {
            pose.translations[self.root] += place.shift;
            for (side, lift) in place.lifts.into_iter().enumerate() {
                self.stance.lift_foot(side, lift, &self.target, pose, &worlds[t], &positions[t * joints..(t + 1) * joints]);
            }
        }
        Motion::from_local_poses(self.target.clone(), motion.fps, poses)
    }

    /// Each link's world rotation in the source's `frame`. `turns` holds the previous frame's,
    /// which a pelvis or chest keeps where the source's has collapsed to a line.
    fn turn_links(&self, frame: &[Vec3], turns: &mut [Quat]) {
        for (i, link) in self.links.iter().enumerate() {
            let base = link.parent.map_or(Quat::IDENTITY, |p| turns[p]);
            turns[i] = match &link.turn {
                Turn::Piece(piece) => piece.turn(frame, &self.source_keys).unwrap_or(turns[i]),
                Turn::Towards { child, rest, level } => {
                    let bone = frame[self.links[*child].source] - frame[link.source];
                    let turned = turn_towards(base, *rest, bone);
                    let shin = link.parent.filter(|_| self.steep_feet_on_hinges).map(|p| frame[link.source] - frame[self.links[p].source]);
                    level.map_or(turned, |across| level_foot(turned, across, bone, shin))
                }
                Turn::TowardsTip { tip, rest } => turn_towards(base, *rest, frame[*tip] - frame[link.source]),
                Turn::Carried => base,
            };
        }
    }

    /// The target's whole pose for the source's `frame`, with its joints' world rotations and
    /// positions, the hips placed by the hip sockets: a mapped joint takes its link's turn,
    /// the first joint of an unmapped stretch turns towards where the next mapped joint should
    /// be (from where the previous one is, along the source's bone), every other joint moves
    /// rigidly with its parent.
    fn pose(&self, frame: &[Vec3], turns: &mut [Quat]) -> (LocalPose, Vec<Quat>, Vec<Vec3>) {
        self.turn_links(frame, turns);
        let skeleton = &*self.target;
        let rest = &self.rest_positions;
        let hips = self.links[0].target;
        let (left, right) = self.source_sockets;
        let hips_at = (frame[left] + frame[right]) / 2.0 * self.root_scale - turns[0] * self.sockets_at_rest;
        let mut world = vec![Quat::IDENTITY; skeleton.len()];
        let mut position = vec![Vec3::ZERO; skeleton.len()];
        let mut translations = skeleton.offsets().to_vec();
        // A root above the hips does not turn: it is placed so the hips land right.
        translations[self.root] = hips_at - (rest[hips] - rest[self.root]);
        for j in 0..skeleton.len() {
            let (base, at) = match skeleton.parents()[j] {
                Some(p) => (world[p], position[p] + world[p] * translations[j]),
                None => (Quat::IDENTITY, translations[j]),
            };
            position[j] = at;
            world[j] = match (self.link_of[j], self.aims[j]) {
                (Some(i), _) => turns[i],
                (None, Some(Aim { link, from })) => {
                    let (link, from) = (&self.links[link], &self.links[from]);
                    let goal = position[from.target] + (frame[link.source] - frame[from.source]).normalize_or_zero() * link.length;
                    turn_towards(base, rest[link.target] - rest[j], goal - at)
                }
                (None, None) => base,
            };
        }
        let rotations = (0..skeleton.len())
            .map(|j| match skeleton.parents()[j] {
                Some(p) => (world[p].inverse() * world[j]).normalize(),
                None => world[j],
            })
            .collect();
        (LocalPose { rotations, translations }, world, position)
    }
}

/// The mapped tree: the key joints both skeletons have, in target joint order, each with its
/// nearest mapped ancestor and how it turns.
fn links(source: &Skeleton, source_keys: &KeyJoints, target: &Skeleton, target_keys: &KeyJoints, target_rest: &[Vec3]) -> Result<Vec<Link>, RetargetError> {
    // A source key on its mapped parent (the CMU database's zero-length lowerneck and
    // clavicle joints) hands on no direction: its link keeps its parent's turn, and the bone
    // after it still points right.
    let mut pairs: Vec<(usize, usize, Key)> = Key::ALL.into_iter().filter_map(|k| Some((target_keys.get(k)?, source_keys.get(k)?, k))).collect();
    pairs.sort_by_key(|p| p.0);
    let mut links: Vec<Link> = Vec::with_capacity(pairs.len());
    for (t, s, key) in pairs {
        let parent = target.ancestors(t).find_map(|a| links.iter().position(|l| l.target == a));
        if parent.is_none() && key != Key::Hips {
            return Err(RetargetError::NotBelowHips { side: "target", key: key.name() });
        }
        let length = parent.map_or(0.0, |p| target_rest[t].distance(target_rest[links[p].target]));
        links.push(Link { key, target: t, source: s, parent, length, turn: Turn::Carried });
    }
    // The chest's up line runs to the neck where both have one clear of the chest.
    let source_rest = source.rest_positions();
    let clear = |rest: &[Vec3], keys: &KeyJoints| match (keys.get(Key::Chest), keys.get(Key::Neck)) {
        (Some(c), Some(n)) => rest[c].distance(rest[n]) > 1e-3 * leg_length(rest, keys),
        _ => false,
    };
    let neck = clear(&source_rest, source_keys) && clear(target_rest, target_keys);
    let side_to_side = match (target_keys.get(Key::LeftUpLeg), target_keys.get(Key::RightUpLeg)) {
        (Some(l), Some(r)) => target_rest[l] - target_rest[r],
        _ => Vec3::X,
    };
    for i in 0..links.len() {
        let children: Vec<usize> = (0..links.len()).filter(|&c| links[c].parent == Some(i)).collect();
        links[i].turn = match (links[i].key, children.as_slice()) {
            (Key::Hips, _) => Turn::Piece(BodyPiece::pelvis(target_rest, target_keys)?),
            (Key::Chest, _) => Turn::Piece(BodyPiece::chest(target_rest, target_keys, neck)?),
            (_, []) => Turn::Carried,
            // One child link, or (with an unusual joint map) the first of several.
            (key, [child, ..]) => Turn::Towards {
                child: *child,
                rest: target_rest[links[*child].target] - target_rest[links[i].target],
                level: matches!(key, Key::LeftFoot | Key::RightFoot).then_some(side_to_side),
            },
        };
    }
    Ok(links)
}

/// A toe's tip on `skeleton` (rest positions `rest`): its first child joint clear of it by a
/// tenth of its foot (the toe's distance from its parent).
fn toe_tip(skeleton: &Skeleton, rest: &[Vec3], toe: usize) -> Option<usize> {
    let foot = skeleton.parents()[toe].map_or(0.0, |ankle| rest[toe].distance(rest[ankle]));
    skeleton.children(toe).find(|&c| rest[c].distance(rest[toe]) > 0.1 * foot)
}

/// `base` followed by the shortest rotation taking `base * rest` onto `wanted`.
fn turn_towards(base: Quat, rest: Vec3, wanted: Vec3) -> Quat {
    let from = (base * rest).normalize_or_zero();
    let to = wanted.normalize_or_zero();
    if from == Vec3::ZERO || to == Vec3::ZERO {
        return base;
    }
    (Quat::from_rotation_arc(from, to) * base).normalize()
}

/// How far below level (degrees) a foot's side-to-side line starts to fade from level onto
/// the ankle's hinge, and where the hinge has it all.
const HINGE_FADE_DEGREES: (f32, f32) = (50.0, 70.0);

/// A foot's `turn` twisted about its bone `along` so that `across` (a rest direction, turned
/// by `turn`) lies on the foot's side-to-side line, of the two sides the one nearer where
/// the leg's turn left it; unchanged where there is no such line.
fn level_foot(turn: Quat, across: Vec3, along: Vec3, shin: Option<Vec3>) -> Quat {
    let Some(along) = along.try_normalize() else { return turn };
    let now = turn * across;
    let (Some(now), Some(line)) = ((now - along * now.dot(along)).try_normalize(), foot_across_line(along, shin)) else { return turn };
    let line = if line.dot(now) < 0.0 { -line } else { line };
    (Quat::from_rotation_arc(now, line) * turn).normalize()
}

/// The side-to-side line of a foot pointing along `along` (unit) below a shin running
/// `shin` (knee to ankle; without one, level however steep). A foot up to 50 degrees down
/// lies level, square to the floor's up (a heel flat on the floor, or lifting at toe-off). A
/// steeper foot (a dancer's point, a run's back swing) fades onto the ankle's hinge, square
/// to shin and foot, by 70 degrees down: the level line of a foot near upright swings half a
/// turn as its heading does, and a foot so levelled is rolled off its own hinge (the two
/// agree within 6 degrees on the training clips' feet 10-50 degrees down, 18-37 apart
/// steeper).
fn foot_across_line(along: Vec3, shin: Option<Vec3>) -> Option<Vec3> {
    let level = along.cross(Vec3::Y);
    let level = (level.length() > 0.1).then(|| level.normalize());
    let (from, to) = HINGE_FADE_DEGREES;
    let down = (-along.y).clamp(-1.0, 1.0).asin().to_degrees();
    let share = ((down - from) / (to - from)).clamp(0.0, 1.0);
    let hinge = shin.and_then(Vec3::try_normalize).map(|shin| shin.cross(along)).filter(|h| h.length() > 0.1).map(Vec3::normalize);
    match (level, hinge) {
        (Some(level), _) if share == 0.0 => Some(level),
        (Some(level), Some(hinge)) => {
            let hinge = if hinge.dot(level) < 0.0 { -hinge } else { hinge };
            level.lerp(hinge, share).try_normalize()
        }
        (level, hinge) => level.or(hinge),
    }
}

/// The joint of a key joint every humanoid has (checked when a [`Retarget`] is made).
fn required(keys: &KeyJoints, key: Key, side: &'static str) -> Result<usize, RetargetError> {
    keys.get(key).ok_or(RetargetError::MissingKeys { side, keys: vec![key] })
}

/// Mean rest length of the two legs, hip to knee to ankle.
fn leg_length(rest: &[Vec3], keys: &KeyJoints) -> f32 {
    let at = |k: Key| keys.get(k).map_or(Vec3::ZERO, |j| rest[j]);
    mean_leg_length([[Key::LeftUpLeg, Key::LeftLeg, Key::LeftFoot], [Key::RightUpLeg, Key::RightLeg, Key::RightFoot]].map(|leg| leg.map(at)))
}

/// Mean angle in degrees between the `bones` (as [`mapped_bones`] gives them) of two poses in
/// the same world: how far a retargeted pose points its limbs from its source's.
pub fn mean_bone_angle(bones: &[(Key, Key)], a: &[Vec3], a_keys: &KeyJoints, b: &[Vec3], b_keys: &KeyJoints) -> f32 {
    let dir = |f: &[Vec3], k: &KeyJoints, (key, parent): (Key, Key)| match (k.get(key), k.get(parent)) {
        (Some(j), Some(p)) => (f[j] - f[p]).normalize_or_zero(),
        _ => Vec3::ZERO,
    };
    let sum: f32 = bones.iter().map(|&bone| dir(a, a_keys, bone).dot(dir(b, b_keys, bone)).clamp(-1.0, 1.0).acos()).sum();
    sum.to_degrees() / bones.len().max(1) as f32
}

/// Bones between key joints both skeletons map, as (key, parent key) with the parent the
/// nearest mapped ancestor on skeleton `a`: the bones a retargeted take should point the same
/// way as its source on. Bones of no rest length on either skeleton have no direction and are
/// left out.
pub fn mapped_bones(a: &KeyJoints, a_skeleton: &Skeleton, b: &KeyJoints, b_skeleton: &Skeleton) -> Vec<(Key, Key)> {
    let both: Vec<(Key, usize)> = a.mapped().filter(|(k, _)| b.get(*k).is_some()).collect();
    let (rest_a, rest_b) = (a_skeleton.rest_positions(), b_skeleton.rest_positions());
    let has_length = |rest: &[Vec3], keys: &KeyJoints, key: Key, parent: Key| {
        let (Some(j), Some(p)) = (keys.get(key), keys.get(parent)) else { return false };
        rest[j].distance(rest[p]) > 1e-3 * leg_length(rest, keys)
    };
    both.iter()
        .filter_map(|&(key, joint)| {
            let parent = a_skeleton.ancestors(joint).find_map(|p| both.iter().find(|(_, j)| *j == p).map(|(k, _)| *k))?;
            Some((key, parent))
        })
        .filter(|&(key, parent)| has_length(&rest_a, a, key, parent) && has_length(&rest_b, b, key, parent))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stick figure standing in a T-pose, with `spine` extra joints between hips and chest.
    fn figure(spine: usize, arm_drop_degrees: f32, scale: f32) -> (Skeleton, KeyJoints) {
        let mut names = Vec::new();
        let mut parents = Vec::new();
        let mut offsets = Vec::new();
        let mut keys = KeyJoints::default();
        let mut add = |name: &str, parent: Option<usize>, offset: Vec3, key: Option<Key>| -> usize {
            names.push(name.to_string());
            parents.push(parent);
            offsets.push(offset * scale);
            let j = names.len() - 1;
            if let Some(k) = key {
                keys.set(k, Some(j));
            }
            j
        };
        let hips = add("hips", None, Vec3::new(0.0, 90.0, 0.0), Some(Key::Hips));
        let mut below = hips;
        for s in 0..spine {
            below = add(&format!("spine{s}"), Some(below), Vec3::new(0.0, 30.0 / (spine + 1) as f32, 0.0), None);
        }
        let chest = add("chest", Some(below), Vec3::new(0.0, 30.0 / (spine + 1) as f32, 0.0), Some(Key::Chest));
        let neck = add("neck", Some(chest), Vec3::new(0.0, 15.0, 0.0), Some(Key::Neck));
        add("head", Some(neck), Vec3::new(0.0, 10.0, 0.0), Some(Key::Head));
        let drop = arm_drop_degrees.to_radians();
        for (side, x, keys3) in [(1.0f32, "l", [Key::LeftArm, Key::LeftForeArm, Key::LeftHand]), (-1.0, "r", [Key::RightArm, Key::RightForeArm, Key::RightHand])] {
            let along = Vec3::new(side * drop.cos(), -drop.sin(), 0.0);
            let arm = add(&format!("{x}arm"), Some(chest), Vec3::new(side * 15.0, 10.0, 0.0), Some(keys3[0]));
            let fore = add(&format!("{x}fore"), Some(arm), along * 28.0, Some(keys3[1]));
            add(&format!("{x}hand"), Some(fore), along * 25.0, Some(keys3[2]));
        }
        for (side, x, keys3) in [(1.0f32, "l", [Key::LeftUpLeg, Key::LeftLeg, Key::LeftFoot]), (-1.0, "r", [Key::RightUpLeg, Key::RightLeg, Key::RightFoot])] {
            let up = add(&format!("{x}thigh"), Some(hips), Vec3::new(side * 10.0, -5.0, 0.0), Some(keys3[0]));
            let knee = add(&format!("{x}knee"), Some(up), Vec3::new(0.0, -42.0, 0.0), Some(keys3[1]));
            add(&format!("{x}ankle"), Some(knee), Vec3::new(0.0, -43.0, 0.0), Some(keys3[2]));
        }
        (Skeleton::new(names, parents, offsets, 0.01).unwrap(), keys)
    }

    #[test]
    fn rest_poses_are_told_apart() {
        let (t, tk) = figure(1, 0.0, 1.0);
        let (a, ak) = figure(1, 45.0, 1.0);
        let (down, dk) = figure(1, 88.0, 1.0);
        assert_eq!(RestPose::detect(&t, &tk), RestPose::TPose);
        assert_eq!(RestPose::detect(&a, &ak), RestPose::APose);
        assert_eq!(RestPose::detect(&down, &dk), RestPose::Other);
    }

    /// A-pose source onto a T-pose target with another spine and size: every mapped bone
    /// points the same way, the hips travel scaled by leg length.
    #[test]
    fn bones_follow_the_source_across_rest_poses_and_sizes() {
        let (src, sk) = figure(0, 45.0, 1.0);
        let (dst, dk) = figure(3, 0.0, 1.2);
        let turn = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.3);
        let mut pose = LocalPose { rotations: vec![Quat::IDENTITY; src.len()], translations: src.offsets().to_vec() };
        pose.rotations[0] = turn;
        pose.rotations[sk.get(Key::LeftForeArm).unwrap()] = Quat::from_rotation_z(1.1);
        pose.rotations[sk.get(Key::RightLeg).unwrap()] = Quat::from_rotation_x(-0.8);
        pose.translations[0] = Vec3::new(50.0, 88.0, -20.0);
        let source = Motion::from_local_poses(Arc::new(src.clone()), 30.0, vec![pose]);
        let r = Retarget::new(&src, &sk, Arc::new(dst.clone()), &dk).unwrap();
        assert_eq!((r.source_rest, r.target_rest), (RestPose::APose, RestPose::TPose));
        let out = r.apply(&source);
        assert_eq!((out.frames(), out.fps, out.joints()), (1, 30.0, dst.len()));
        let (s, d) = (source.frame(0), out.frame(0));
        for (key, parent) in mapped_bones(&sk, &src, &dk, &dst) {
            let bone = |f: &[Vec3], k: &KeyJoints| (f[k.get(key).unwrap()] - f[k.get(parent).unwrap()]).normalize();
            let angle = bone(s, &sk).dot(bone(d, &dk)).clamp(-1.0, 1.0).acos().to_degrees();
            // Hips and chest fit several bones at once (least squares); single bones are exact.
            assert!(angle < 3.0, "{key:?} from {parent:?}: {angle} degrees");
        }
        let hips = d[dk.get(Key::Hips).unwrap()];
        assert!(hips.distance(Vec3::new(50.0, 88.0, -20.0) * 1.2) < 1e-3, "{hips}");
    }

    /// A target whose hip sockets sit 6 units above and 3 in front of its hips joint (a Rigify
    /// metarig's pelvis) and whose thighs are longer than its shins, under a source crouching
    /// and turned: the feet stand on the source's floor, the socket line points as the
    /// source's, and the shins still point as the source's.
    #[test]
    fn feet_stand_on_the_floor_whatever_the_pelvis_and_legs() {
        let (src, sk) = figure(0, 0.0, 1.0);
        let (shape, dk) = figure(2, 0.0, 1.0);
        let offsets = shape.names().iter().zip(shape.offsets()).map(|(name, o)| match name.as_str() {
            "lthigh" | "rthigh" => Vec3::new(o.x, 6.0, 3.0),
            "lknee" | "rknee" => Vec3::new(0.0, -50.0, 0.0),
            "lankle" | "rankle" => Vec3::new(0.0, -35.0, 0.0),
            _ => *o,
        });
        let dst = Skeleton::new(shape.names().to_vec(), shape.parents().to_vec(), offsets.collect(), 0.01).unwrap();
        let mut pose = LocalPose { rotations: vec![Quat::IDENTITY; src.len()], translations: src.offsets().to_vec() };
        pose.rotations[0] = Quat::from_rotation_y(0.6);
        for (thigh, knee) in [(Key::LeftUpLeg, Key::LeftLeg), (Key::RightUpLeg, Key::RightLeg)] {
            pose.rotations[sk.get(thigh).unwrap()] = Quat::from_rotation_x(-0.7);
            pose.rotations[sk.get(knee).unwrap()] = Quat::from_rotation_x(1.2);
        }
        let crouched = Motion::from_local_poses(Arc::new(src.clone()), 30.0, vec![pose.clone()]);
        pose.translations[0].y -= crouched.frame(0)[sk.get(Key::LeftFoot).unwrap()].y;
        let source = Motion::from_local_poses(Arc::new(src.clone()), 30.0, vec![pose; 10]);
        let out = Retarget::new(&src, &sk, Arc::new(dst), &dk).unwrap().apply(&source);
        let line = |f: &[Vec3], k: &KeyJoints, a: Key, b: Key| (f[k.get(b).unwrap()] - f[k.get(a).unwrap()]).normalize();
        for t in 0..out.frames() {
            let (s, d) = (source.frame(t), out.frame(t));
            for (foot, knee) in [(Key::LeftFoot, Key::LeftLeg), (Key::RightFoot, Key::RightLeg)] {
                assert!(d[dk.get(foot).unwrap()].y.abs() < 0.1, "frame {t}: {foot:?} at {}", d[dk.get(foot).unwrap()].y);
                let shin = line(s, &sk, knee, foot).angle_between(line(d, &dk, knee, foot)).to_degrees();
                assert!(shin < 3.0, "frame {t}: {knee:?} {shin} degrees off");
            }
            let sockets = line(s, &sk, Key::RightUpLeg, Key::LeftUpLeg).angle_between(line(d, &dk, Key::RightUpLeg, Key::LeftUpLeg));
            assert!(sockets.to_degrees() < 0.1, "frame {t}: the socket line {} degrees off", sockets.to_degrees());
        }
    }

    /// A foot up to 50 degrees down lies level; from 70 down it lies on its ankle's hinge,
    /// square to shin and foot, even where the shin leans sideways and the level line would
    /// roll it; in between the line turns smoothly from one onto the other.
    #[test]
    fn a_steep_foot_turns_on_its_hinge_a_flat_one_lies_level() {
        let shin = Vec3::new(0.4, -1.0, 0.1);
        let foot = |down_degrees: f32| {
            let down = down_degrees.to_radians();
            Vec3::new(0.0, -down.sin(), down.cos())
        };
        let flat = foot_across_line(foot(20.0), Some(shin)).unwrap();
        assert!(flat.y.abs() < 1e-6 && flat.dot(foot(20.0)).abs() < 1e-6, "{flat}");
        let hinge = shin.cross(foot(80.0)).normalize();
        let steep = foot_across_line(foot(80.0), Some(shin)).unwrap();
        assert!(steep.dot(hinge).abs() > 1.0 - 1e-6 && hinge.y.abs() > 0.1, "{steep} against the hinge {hinge}");
        let mut before = flat;
        for down in 21..=89 {
            let line = foot_across_line(foot(down as f32), Some(shin)).unwrap();
            let line = if line.dot(before) < 0.0 { -line } else { line };
            assert!(line.angle_between(before).to_degrees() < 5.0, "{down} degrees down: {line} after {before}");
            before = line;
        }
    }

    #[test]
    fn missing_keys_are_named() {
        let (src, mut sk) = figure(0, 0.0, 1.0);
        let (dst, dk) = figure(0, 0.0, 1.0);
        sk.set(Key::LeftForeArm, None);
        let e = Retarget::new(&src, &sk, Arc::new(dst), &dk).unwrap_err();
        assert_eq!(e.to_string(), "the source skeleton has no joint for LeftForeArm");
    }
}
