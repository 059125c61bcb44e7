use std::collections::HashMap;

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Bones shorter than this fraction of a skeleton's longest are duplicates, collapsed end
/// sites, or joints that only turn a chain ([`Skeleton::turning_chain`]).
pub const SHORT_BONE_FRACTION: f32 = 0.02;

/// A joint hierarchy with rest offsets: joint `j` sits at `offsets[j]` in its parent's frame.
///
/// Invariants, checked by [`Skeleton::new`] and by deserialisation (which goes through it):
/// at least one joint; as many names, parents and offsets; parents come before children
/// (`parents[j] < j`) so one pass in index order is forward kinematics; exactly one root,
/// joint 0; unique names (files and skeleton comparisons find joints by name); finite
/// offsets and a positive, finite unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SkeletonFields")]
pub struct Skeleton {
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    offsets: Vec<Vec3>,
    /// Metres per unit of `offsets` and of every position (mm: 0.001, cm: 0.01).
    meters_per_unit: f32,
}

/// The serialised form, before its invariants are checked.
#[derive(Deserialize)]
struct SkeletonFields {
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    offsets: Vec<Vec3>,
    meters_per_unit: f32,
}

impl TryFrom<SkeletonFields> for Skeleton {
    type Error = SkeletonError;

    fn try_from(f: SkeletonFields) -> Result<Self, SkeletonError> {
        Skeleton::new(f.names, f.parents, f.offsets, f.meters_per_unit)
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SkeletonError {
    #[error("skeleton has {names} names, {parents} parents and {offsets} offsets; they must agree")]
    LengthMismatch { names: usize, parents: usize, offsets: usize },
    #[error("joint {joint} ('{name}') has parent {parent}, which does not come before it")]
    BadParent { joint: usize, name: String, parent: usize },
    #[error("skeleton has no joints")]
    Empty,
    #[error("joint 0 ('{name}') must be the root, but it has a parent")]
    RootNotFirst { name: String },
    #[error("joint {joint} ('{name}') is a second root; a skeleton has exactly one")]
    SecondRoot { joint: usize, name: String },
    #[error("joint {joint} and joint {first} are both named '{name}'; joint names must be unique")]
    DuplicateName { joint: usize, first: usize, name: String },
    #[error("joint {joint} ('{name}') has a non-finite offset")]
    NonFiniteOffset { joint: usize, name: String },
    #[error("meters_per_unit must be a positive finite number, found {0}")]
    BadUnit(f32),
}

/// `s` cut to 40 characters for an error message (a hostile file can hold a 50 MB name).
pub fn clipped(s: &str) -> String {
    if s.chars().count() <= 40 {
        s.to_string()
    } else {
        format!("{}...", s.chars().take(40).collect::<String>())
    }
}

impl Skeleton {
    pub fn new(
        names: Vec<String>,
        parents: Vec<Option<usize>>,
        offsets: Vec<Vec3>,
        meters_per_unit: f32,
    ) -> Result<Self, SkeletonError> {
        if names.is_empty() {
            return Err(SkeletonError::Empty);
        }
        if names.len() != parents.len() || names.len() != offsets.len() {
            return Err(SkeletonError::LengthMismatch {
                names: names.len(),
                parents: parents.len(),
                offsets: offsets.len(),
            });
        }
        if !(meters_per_unit.is_finite() && meters_per_unit > 0.0) {
            return Err(SkeletonError::BadUnit(meters_per_unit));
        }
        let name = |j: usize| clipped(&names[j]);
        if parents[0].is_some() {
            return Err(SkeletonError::RootNotFirst { name: name(0) });
        }
        let mut seen: HashMap<&str, usize> = HashMap::with_capacity(names.len());
        for (j, p) in parents.iter().enumerate() {
            match *p {
                Some(p) if p >= j => return Err(SkeletonError::BadParent { joint: j, name: name(j), parent: p }),
                None if j > 0 => return Err(SkeletonError::SecondRoot { joint: j, name: name(j) }),
                _ => {}
            }
            if !offsets[j].is_finite() {
                return Err(SkeletonError::NonFiniteOffset { joint: j, name: name(j) });
            }
            if let Some(first) = seen.insert(names[j].as_str(), j) {
                return Err(SkeletonError::DuplicateName { joint: j, first, name: name(j) });
            }
        }
        Ok(Self { names, parents, offsets, meters_per_unit })
    }

    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Each joint's parent (`None` only for joint 0, the root).
    pub fn parents(&self) -> &[Option<usize>] {
        &self.parents
    }

    /// Rest offsets, each in its parent's frame.
    pub fn offsets(&self) -> &[Vec3] {
        &self.offsets
    }

    /// Metres per unit of the offsets and of every position (mm: 0.001, cm: 0.01).
    pub fn meters_per_unit(&self) -> f32 {
        self.meters_per_unit
    }

    pub fn len(&self) -> usize {
        self.names.len()
    }

    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    fn name_index(&self) -> HashMap<&str, usize> {
        self.names.iter().enumerate().map(|(j, n)| (n.as_str(), j)).collect()
    }

    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Rest length of the bone from each joint to its parent (0 for the root).
    pub fn rest_bone_lengths(&self) -> Vec<f32> {
        self.offsets.iter().zip(&self.parents).map(|(o, p)| if p.is_some() { o.length() } else { 0.0 }).collect()
    }

    pub fn children(&self, joint: usize) -> impl Iterator<Item = usize> + '_ {
        self.parents.iter().enumerate().filter(move |(_, p)| **p == Some(joint)).map(|(c, _)| c)
    }

    /// The joints above `joint`, nearest first: its parent, its parent's parent, ... the root.
    pub fn ancestors(&self, joint: usize) -> impl Iterator<Item = usize> + '_ {
        std::iter::successors(self.parents[joint], |&j| self.parents[j])
    }

    /// `joint` and every joint under it, in index order.
    pub fn subtree(&self, joint: usize) -> Vec<usize> {
        (0..self.len()).filter(|&j| self.is_ancestor(joint, j)).collect()
    }

    /// Whether `joint` is `ancestor` or hangs below it.
    pub fn is_ancestor(&self, ancestor: usize, joint: usize) -> bool {
        self.depth_below(joint, ancestor).is_some()
    }

    /// How many bones `joint` is below `ancestor` (0 for the joint itself; None when it is
    /// not below it).
    pub fn depth_below(&self, joint: usize, ancestor: usize) -> Option<usize> {
        std::iter::once(joint).chain(self.ancestors(joint)).position(|j| j == ancestor)
    }

    /// The joints from the root down to `joint`, both included.
    pub fn chain_from_root(&self, joint: usize) -> Vec<usize> {
        let mut chain: Vec<usize> = std::iter::once(joint).chain(self.ancestors(joint)).collect();
        chain.reverse();
        chain
    }

    /// The lowest joint that both `a` and `b` are (or hang below); the root at the latest.
    pub fn common_ancestor(&self, a: usize, b: usize) -> usize {
        std::iter::once(a).chain(self.ancestors(a)).find(|&j| self.is_ancestor(j, b)).expect("a skeleton has one root, above every joint")
    }

    /// The child of `ancestor` on the way down to `joint` (None when `joint` is not strictly
    /// below it).
    pub fn child_towards(&self, ancestor: usize, joint: usize) -> Option<usize> {
        std::iter::once(joint).chain(self.ancestors(joint)).find(|&j| self.parents[j] == Some(ancestor))
    }

    /// Joints worth modelling: the root, every joint whose rest bone is at least `min_bone`
    /// long, and the short ones that turn a chain of their own ([`Self::turning_chain`]).
    /// Other zero-length bones (duplicate joints, collapsed end sites) only repeat their parent.
    pub fn informative_joints(&self, min_bone: f32) -> Vec<usize> {
        (0..self.len())
            .filter(|&j| self.parents[j].is_none() || self.offsets[j].length() >= min_bone || self.turning_chain(j, min_bone).is_some())
            .collect()
    }

    /// The longest bone (the root's offset, a placement, is not one).
    pub fn longest_bone(&self) -> f32 {
        (0..self.len()).filter(|&j| self.parents[j].is_some()).map(|j| self.offsets[j].length()).fold(0.0, f32::max)
    }

    /// The chain joint `j` turns when its bone is shorter than `short` but it is the one way
    /// to a chain of its own (its only child has children) beside its parent's other children:
    /// Human3.6M's `Spine`, 0.1 mm above the hips, whose turn bends the back against the
    /// pelvis. Left out, that bend would be tied to the pelvis's turn. Returns the chain's
    /// first joint.
    pub fn turning_chain(&self, j: usize, short: f32) -> Option<usize> {
        let parent = self.parents[j]?;
        if self.offsets[j].length() >= short || self.children(parent).count() < 2 {
            return None;
        }
        let mut children = self.children(j);
        let (Some(chain), None) = (children.next(), children.next()) else { return None };
        (self.offsets[chain].length() >= short && self.children(chain).next().is_some()).then_some(chain)
    }

    /// The joints that only turn a chain ([`Self::turning_chain`], at [`SHORT_BONE_FRACTION`]
    /// of the longest bone).
    pub fn turning_joints(&self) -> Vec<usize> {
        let short = self.longest_bone() * SHORT_BONE_FRACTION;
        (0..self.len()).filter(|&j| self.turning_chain(j, short).is_some()).collect()
    }

    /// A frame of `width` numbers per joint saved on this skeleton before it kept the joints
    /// that only turn a chain ([`Self::turning_joints`]: Human3.6M's `Spine`, a model joint
    /// since 2026-12-03), with each such joint put back as `missing` makes it from its
    /// parent's numbers. None when the frame is not one of those (it has another length, or
    /// the skeleton has no such joint).
    pub fn with_turning_joints(&self, frame: &[f32], width: usize, missing: impl Fn(&[f32]) -> Vec<f32>) -> Option<Vec<f32>> {
        let turning = self.turning_joints();
        if turning.is_empty() || frame.len() != width * (self.len() - turning.len()) {
            return None;
        }
        let mut saved = frame.chunks_exact(width);
        let mut out = Vec::with_capacity(width * self.len());
        for j in 0..self.len() {
            match self.parents[j].filter(|_| turning.contains(&j)) {
                // Parents come before children, so the parent's numbers are already out.
                Some(p) => {
                    let parent = out[p * width..(p + 1) * width].to_vec();
                    out.extend(missing(&parent));
                }
                None => out.extend_from_slice(saved.next()?),
            }
        }
        Some(out)
    }

    /// The sub-skeleton of `keep`: ascending indices, each but the first descending from
    /// another kept joint (as a validated model.json's `source_joints` are), so it has one
    /// root. A dropped joint's offset is folded into its kept descendants so rest positions
    /// are unchanged.
    pub fn subset(&self, keep: &[usize]) -> Skeleton {
        let rest = self.rest_positions();
        let new_index = |j: usize| keep.iter().position(|&k| k == j);
        let mut parents = Vec::with_capacity(keep.len());
        let mut offsets = Vec::with_capacity(keep.len());
        for &j in keep {
            let p = self.ancestors(j).find(|&a| new_index(a).is_some());
            parents.push(p.and_then(new_index));
            offsets.push(match p {
                Some(pj) => rest[j] - rest[pj],
                None => self.offsets[j],
            });
        }
        Skeleton {
            names: keep.iter().map(|&j| self.names[j].clone()).collect(),
            parents,
            offsets,
            meters_per_unit: self.meters_per_unit,
        }
    }

    /// World positions of the rest pose (root at its offset).
    pub fn rest_positions(&self) -> Vec<Vec3> {
        let mut out: Vec<Vec3> = Vec::with_capacity(self.len());
        for j in 0..self.len() {
            let base = self.parents[j].map_or(Vec3::ZERO, |p| out[p]);
            out.push(base + self.offsets[j]);
        }
        out
    }

    /// How two skeletons differ by name and parent (empty when they match), summarised: a
    /// count and the first few names of each kind, each name clipped, so a file with
    /// thousands of joints or a huge name still gives a one-line message.
    pub fn differences(&self, other: &Skeleton) -> Vec<String> {
        let mut out = Vec::new();
        if self.len() != other.len() {
            out.push(format!("{} joints against {}", self.len(), other.len()));
        }
        let (mine, theirs) = (self.name_index(), other.name_index());
        let missing: Vec<&String> = self.names.iter().filter(|n| !theirs.contains_key(n.as_str())).collect();
        let unexpected: Vec<&String> = other.names.iter().filter(|n| !mine.contains_key(n.as_str())).collect();
        push_summary(&mut out, "missing joint", &missing);
        push_summary(&mut out, "unexpected joint", &unexpected);
        if out.is_empty() {
            let reparented: Vec<&String> = self
                .names
                .iter()
                .enumerate()
                .filter(|&(j, name)| {
                    let own_parent = self.parents[j].map(|p| &self.names[p]);
                    let other_parent = theirs.get(name.as_str()).and_then(|&k| other.parents[k]).map(|p| &other.names[p]);
                    own_parent != other_parent
                })
                .map(|(_, name)| name)
                .collect();
            push_summary(&mut out, "joint with another parent", &reparented);
        }
        out
    }
}

/// "3 missing joints: 'a', 'b', 'c'" or "40 missing joints: 'a', 'b', 'c' and 37 more".
fn push_summary(out: &mut Vec<String>, what: &str, names: &[&String]) {
    const SHOWN: usize = 3;
    if names.is_empty() {
        return;
    }
    let plural = if names.len() == 1 { "" } else { "s" };
    let listed: Vec<String> = names.iter().take(SHOWN).map(|n| format!("'{}'", clipped(n))).collect();
    let more = if names.len() > SHOWN { format!(" and {} more", names.len() - SHOWN) } else { String::new() };
    out.push(format!("{} {what}{plural}: {}{more}", names.len(), listed.join(", ")));
}
