//! Which joint of a skeleton does what: the body root, the two legs (hip, knee, ankle, toe),
//! the head and the hands. Found once per skeleton, by name where the rig follows a common
//! convention (h36m, Bandai, CMU BVH, Mixamo-like), else by its shape (the two lowest leaves'
//! chains for the legs, the two longest upper chains for the arms), and checked either way.
//! Features, the corpus, contacts, IK, the suites and the drawing code all read them here.

use glam::Vec3;

use super::names::{words, JointName, Side};
use super::Skeleton;

/// Bones shorter than this fraction of the longest bone are duplicates or collapsed end
/// sites, and do not count as a segment of a limb.
const MIN_SEGMENT_FRACTION: f32 = 0.02;

/// One leg, from the hip joint (where the thigh turns) down to the toe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Leg {
    pub hip: usize,
    pub knee: usize,
    pub ankle: usize,
    /// The toe, where the rig has one (CMU's BVH keeps only the foot's end site, which the
    /// reader drops).
    pub toe: Option<usize>,
    /// The tip of the toe, where the rig has one (h36m's `ToeSite`).
    pub toe_end: Option<usize>,
}

impl Leg {
    /// The joints that can touch the floor: the ankle and every joint under it (toes, toe tip,
    /// and a heel where a rig has one: a Rigify metarig's `heel.02` hangs under its ankle,
    /// beside the toes, and is the foot's lowest point when it stands flat).
    pub fn foot_joints(&self, skeleton: &Skeleton) -> Vec<usize> {
        skeleton.subtree(self.ankle)
    }
}

/// The roles of one skeleton's joints (indices into it).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JointRoles {
    /// The joint where legs and spine branch, the one that carries the pelvis.
    pub body_root: usize,
    pub left: Leg,
    pub right: Leg,
    pub head: usize,
    /// The head's child towards the top of the head, where the rig has one.
    pub head_end: Option<usize>,
    pub left_hand: usize,
    pub right_hand: usize,
}

#[derive(Debug, thiserror::Error, PartialEq)]
#[error("the skeleton has no {} (looked for them by name and by shape)", .missing.join(", "))]
pub struct RolesError {
    pub missing: Vec<String>,
}

impl JointRoles {
    /// Roles by name convention, else by the skeleton's shape; an error names every role
    /// that neither found.
    pub fn new(skeleton: &Skeleton) -> Result<Self, RolesError> {
        let name_missing = match Partial::by_name(skeleton).validated(skeleton) {
            Ok(roles) => return Ok(roles),
            Err(missing) => missing,
        };
        Partial::by_shape(skeleton).validated(skeleton).map_err(|shape_missing| {
            let both: Vec<String> = name_missing.iter().filter(|m| shape_missing.contains(m)).cloned().collect();
            RolesError { missing: if both.is_empty() { name_missing } else { both } }
        })
    }

    pub fn leg(&self, side: Side) -> &Leg {
        match side {
            Side::Left => &self.left,
            Side::Right => &self.right,
        }
    }

    /// The legs' mean rest length, hip to knee to ankle, in the skeleton's units: the body's
    /// size whatever else the rig holds (fingers, props, a root joint placed far from the body).
    pub fn rest_leg_length(&self, skeleton: &Skeleton) -> f32 {
        let rest = skeleton.rest_positions();
        mean_leg_length([&self.left, &self.right].map(|l| [rest[l.hip], rest[l.knee], rest[l.ankle]]))
    }

    /// The joint both legs hang from (the skeleton's root where the legs are not found) and
    /// its subtree: the body, without a placement joint above it (Bandai's `joint_Root` rests
    /// where the capture began, 4.5 m from the hips in some of its files).
    pub fn body_of(skeleton: &Skeleton) -> (usize, Vec<usize>) {
        let root = Self::new(skeleton).map_or(0, |r| r.body_root);
        (root, skeleton.subtree(root))
    }

    /// The body's reach at rest ([`JointRoles::body_of`]): its farthest joint from its root, in
    /// the skeleton's units.
    pub fn rest_reach(skeleton: &Skeleton) -> f32 {
        let (root, body) = Self::body_of(skeleton);
        let rest = skeleton.rest_positions();
        body.iter().map(|&j| rest[j].distance(rest[root])).fold(0.0f32, f32::max)
    }

    /// The joint drawn as the top of the head.
    pub fn head_top(&self) -> usize {
        self.head_end.unwrap_or(self.head)
    }
}

/// The mean length of two legs, each given by its hip, knee and ankle positions: hip to knee
/// to ankle.
pub(super) fn mean_leg_length(legs: [[Vec3; 3]; 2]) -> f32 {
    legs.iter().map(|[hip, knee, ankle]| hip.distance(*knee) + knee.distance(*ankle)).sum::<f32>() / 2.0
}

/// Roles as one finder saw them, some perhaps missing.
#[derive(Clone, Debug, Default)]
struct Partial {
    body_root: Option<usize>,
    legs: [Option<PartialLeg>; 2],
    head: Option<usize>,
    head_end: Option<usize>,
    hands: [Option<usize>; 2],
}

#[derive(Clone, Copy, Debug, Default)]
struct PartialLeg {
    hip: Option<usize>,
    knee: Option<usize>,
    ankle: Option<usize>,
    toe: Option<usize>,
    toe_end: Option<usize>,
}

impl Partial {
    fn by_name(s: &Skeleton) -> Self {
        let mut out = Partial::default();
        for (k, side) in Side::BOTH.into_iter().enumerate() {
            let hip = named(s, Some(side), words::THIGH, None);
            let knee = hip.and_then(|h| named(s, Some(side), words::SHIN, Some(h)));
            let ankle = knee.and_then(|k| named(s, Some(side), words::ANKLE, Some(k)));
            let toe = ankle.and_then(|a| named(s, Some(side), words::TOES, Some(a)).or_else(|| farthest_child(s, a)));
            let toe_end = toe.and_then(|t| farthest_child(s, t));
            out.legs[k] = Some(PartialLeg { hip, knee, ankle, toe, toe_end });
            out.hands[k] = named(s, Some(side), words::HAND, None);
        }
        if let [Some(PartialLeg { hip: Some(l), .. }), Some(PartialLeg { hip: Some(r), .. })] = out.legs {
            out.body_root = Some(s.common_ancestor(l, r));
        }
        out.head = named(s, None, &["head"], None);
        out.head_end = out.head.and_then(|h| farthest_child(s, h));
        out
    }

    /// Legs: the chains from the body root to the two lowest leaves that both hold a
    /// thigh and a shin (the two longest consecutive segments), left being the side of
    /// up x forward with forward the toes' direction. Arms: the same two-long-segments rule
    /// on the two upper leaves farthest along the skeleton. Head: the highest other joint.
    fn by_shape(s: &Skeleton) -> Self {
        let mut out = Partial::default();
        let rest = s.rest_positions();
        let leaves: Vec<usize> = (0..s.len()).filter(|&j| s.children(j).next().is_none()).collect();
        let mut low = leaves.clone();
        low.sort_by(|&a, &b| rest[a].y.total_cmp(&rest[b].y));
        let Some((root, legs)) = lowest_leg_pair(s, &low) else { return out };
        out.body_root = Some(root);
        let forward = legs.iter().filter_map(|l| Some(flat(rest[l.toe?] - rest[l.ankle]))).sum::<Vec3>().normalize_or(Vec3::Z);
        let left_dir = Vec3::Y.cross(forward);
        let left_first = rest[legs[0].hip].dot(left_dir) >= rest[legs[1].hip].dot(left_dir);
        let [a, b] = legs;
        let (left, right) = if left_first { (a, b) } else { (b, a) };
        out.legs = [Some(left.into()), Some(right.into())];
        let in_legs = |j: usize| s.is_ancestor(left.hip, j) || s.is_ancestor(right.hip, j) || s.is_ancestor(j, root);
        let upper: Vec<usize> = leaves.iter().copied().filter(|&j| !in_legs(j)).collect();
        let reach = path_lengths(s);
        if let Some((hands, branch)) = arm_pair(s, &upper, &reach, &rest, left_dir) {
            out.hands = [Some(hands[0]), Some(hands[1])];
            let arm_tops: Vec<usize> = s.children(branch).filter(|&c| hands.iter().any(|&h| s.is_ancestor(c, h))).collect();
            let in_arms = |j: usize| arm_tops.iter().any(|&a| s.is_ancestor(a, j));
            out.head = (0..s.len()).filter(|&j| !in_legs(j) && !in_arms(j)).max_by(|&a, &b| rest[a].y.total_cmp(&rest[b].y));
        }
        out
    }

    fn missing(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut need = |found: Option<usize>, what: String| {
            if found.is_none() {
                out.push(what);
            }
        };
        need(self.body_root, "body root".into());
        for (k, side) in Side::BOTH.into_iter().enumerate() {
            let leg = self.legs[k].unwrap_or_default();
            for (found, part) in [(leg.hip, "hip"), (leg.knee, "knee"), (leg.ankle, "ankle")] {
                need(found, format!("{} {part}", side.name()));
            }
            need(self.hands[k], format!("{} hand", side.name()));
        }
        need(self.head, "head".into());
        out
    }

    /// The complete roles, checked: each leg a chain hanging from the body root, the two
    /// legs apart, no joint with two roles. Otherwise the missing (or inconsistent) roles.
    fn validated(&self, s: &Skeleton) -> Result<JointRoles, Vec<String>> {
        let missing = self.missing();
        if !missing.is_empty() {
            return Err(missing);
        }
        let leg = |k: usize| {
            let p = self.legs[k].expect("checked by missing()");
            Leg { hip: p.hip.unwrap(), knee: p.knee.unwrap(), ankle: p.ankle.unwrap(), toe: p.toe, toe_end: p.toe_end }
        };
        let roles = JointRoles {
            body_root: self.body_root.unwrap(),
            left: leg(0),
            right: leg(1),
            head: self.head.unwrap(),
            head_end: self.head_end,
            left_hand: self.hands[0].unwrap(),
            right_hand: self.hands[1].unwrap(),
        };
        let mut bad = Vec::new();
        for side in Side::BOTH {
            let l = roles.leg(side);
            let chain: Vec<usize> = [Some(roles.body_root), Some(l.hip), Some(l.knee), Some(l.ankle), l.toe, l.toe_end].into_iter().flatten().collect();
            if chain.windows(2).any(|w| w[0] == w[1] || !s.is_ancestor(w[0], w[1])) {
                bad.push(format!("{} leg as one chain from the body root", side.name()));
            }
        }
        if s.is_ancestor(roles.left.hip, roles.right.hip) || s.is_ancestor(roles.right.hip, roles.left.hip) {
            bad.push("separate left and right legs".into());
        }
        if roles.left_hand == roles.right_hand {
            bad.push("separate left and right hands".into());
        }
        if bad.is_empty() {
            Ok(roles)
        } else {
            Err(bad)
        }
    }
}

impl From<Leg> for PartialLeg {
    fn from(l: Leg) -> Self {
        PartialLeg { hip: Some(l.hip), knee: Some(l.knee), ankle: Some(l.ankle), toe: l.toe, toe_end: l.toe_end }
    }
}

/// The first joint (by keyword priority, then index) on `side` whose name's words hold a
/// keyword, is no end site, and lies strictly below `below` when given.
fn named(s: &Skeleton, side: Option<Side>, keywords: &[&str], below: Option<usize>) -> Option<usize> {
    let parsed: Vec<JointName> = s.names().iter().map(|n| JointName::parse(n)).collect();
    keywords.iter().find_map(|k| {
        (0..s.len()).find(|&j| {
            let name = &parsed[j];
            name.part.contains(k)
                && !name.is_end_site()
                && side.is_none_or(|sd| name.side == Some(sd))
                && below.is_none_or(|b| b != j && s.is_ancestor(b, j))
                // `leg` names the shin only when it is not the thigh (`UpLeg`, `UpperLeg`).
                && !(*k == "leg" && name.part.contains("up"))
        })
    })
}

/// The child whose subtree reaches farthest from `joint` in the rest pose.
fn farthest_child(s: &Skeleton, joint: usize) -> Option<usize> {
    let rest = s.rest_positions();
    s.children(joint).max_by(|&a, &b| rest[a].distance(rest[joint]).total_cmp(&rest[b].distance(rest[joint])))
}

/// Summed rest bone length from the root to each joint.
fn path_lengths(s: &Skeleton) -> Vec<f32> {
    let bones = s.rest_bone_lengths();
    let mut out = vec![0.0; s.len()];
    for j in 0..s.len() {
        out[j] = s.parents()[j].map_or(0.0, |p| out[p]) + bones[j];
    }
    out
}

fn flat(v: Vec3) -> Vec3 {
    Vec3::new(v.x, 0.0, v.z)
}

/// The segments of the chain from `from` (exclusive) down to `leaf`, without duplicate
/// joints (bones too short to be a segment).
fn segments(s: &Skeleton, from: usize, leaf: usize) -> Vec<usize> {
    let bones = s.rest_bone_lengths();
    let min = bones.iter().fold(0.0f32, |m, b| m.max(*b)) * MIN_SEGMENT_FRACTION;
    let chain = s.chain_from_root(leaf);
    let start = chain.iter().position(|&j| j == from).map_or(chain.len(), |i| i + 1);
    chain[start..].iter().copied().filter(|&j| bones[j] >= min).collect()
}

/// A limb in a chain below a branch: the two longest consecutive segments are the upper and
/// lower limb (thigh and shin, upper arm and forearm). Returns (upper joint, middle, end,
/// the segments after the end); `None` when the chain has no joint above the upper segment.
fn limb(chain: &[usize], s: &Skeleton) -> Option<(usize, usize, usize, Vec<usize>)> {
    let bones = s.rest_bone_lengths();
    let k = (1..chain.len().checked_sub(1)?).max_by(|&a, &b| (bones[chain[a]] + bones[chain[a + 1]]).total_cmp(&(bones[chain[b]] + bones[chain[b + 1]])))?;
    Some((chain[k - 1], chain[k], chain[k + 1], chain[k + 2..].to_vec()))
}

/// The two lowest leaves whose chains from their common ancestor are both legs.
fn lowest_leg_pair(s: &Skeleton, low: &[usize]) -> Option<(usize, [Leg; 2])> {
    let leg = |root: usize, leaf: usize| {
        let (hip, knee, ankle, rest) = limb(&segments(s, root, leaf), s)?;
        Some(Leg { hip, knee, ankle, toe: rest.first().copied(), toe_end: rest.get(1).copied() })
    };
    let first = *low.first()?;
    low[1..].iter().find_map(|&other| {
        let root = s.common_ancestor(first, other);
        Some((root, [leg(root, first)?, leg(root, other)?]))
    })
}

/// The hands (left, right) and the joint their arms branch from: the two upper leaves
/// farthest along the skeleton whose chains below their common ancestor are both arms.
fn arm_pair(s: &Skeleton, upper: &[usize], reach: &[f32], rest: &[Vec3], left_dir: Vec3) -> Option<([usize; 2], usize)> {
    let mut far = upper.to_vec();
    far.sort_by(|&a, &b| reach[b].total_cmp(&reach[a]));
    let first = *far.first()?;
    far[1..].iter().find_map(|&other| {
        let branch = s.common_ancestor(first, other);
        if branch == first || branch == other {
            return None;
        }
        let (_, _, hand_a, _) = limb(&segments(s, branch, first), s)?;
        let (_, _, hand_b, _) = limb(&segments(s, branch, other), s)?;
        let (da, db) = (rest[hand_a].dot(left_dir), rest[hand_b].dot(left_dir));
        // Arms straight up or down give no side: then the shape cannot tell them apart.
        if (da - db).abs() < 1e-6 * (1.0 + da.abs() + db.abs()) {
            return None;
        }
        Some((if da > db { [hand_a, hand_b] } else { [hand_b, hand_a] }, branch))
    })
}
