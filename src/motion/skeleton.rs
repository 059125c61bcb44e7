use glam::Vec3;
use serde::{Deserialize, Serialize};

/// A joint hierarchy with rest offsets: joint `j` sits at `offsets[j]` in its parent's frame.
/// Parents come before children (`parents[j] < j`), the root has no parent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Skeleton {
    pub names: Vec<String>,
    pub parents: Vec<Option<usize>>,
    pub offsets: Vec<Vec3>,
    /// Metres per unit of `offsets` and of every position (mm: 0.001, cm: 0.01).
    pub meters_per_unit: f32,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SkeletonError {
    #[error("skeleton has {names} names, {parents} parents and {offsets} offsets; they must agree")]
    LengthMismatch { names: usize, parents: usize, offsets: usize },
    #[error("joint {joint} ('{name}') has parent {parent}, which does not come before it")]
    BadParent { joint: usize, name: String, parent: usize },
    #[error("skeleton has no joints")]
    Empty,
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
        for (j, p) in parents.iter().enumerate() {
            if let Some(p) = *p {
                if p >= j {
                    return Err(SkeletonError::BadParent { joint: j, name: names[j].clone(), parent: p });
                }
            }
        }
        Ok(Self { names, parents, offsets, meters_per_unit })
    }

    pub fn len(&self) -> usize {
        self.names.len()
    }

    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
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

    /// Joints worth modelling: the root plus every joint whose rest bone is at least `min_bone`
    /// long. Zero-length bones (duplicate joints, collapsed end sites) only repeat their parent.
    pub fn informative_joints(&self, min_bone: f32) -> Vec<usize> {
        (0..self.len())
            .filter(|&j| self.parents[j].is_none() || self.offsets[j].length() >= min_bone)
            .collect()
    }

    /// The sub-skeleton of `keep` (ascending indices, root first). A dropped joint's offset is
    /// folded into its kept descendants so rest positions are unchanged.
    pub fn subset(&self, keep: &[usize]) -> Skeleton {
        let rest = self.rest_positions();
        let new_index = |j: usize| keep.iter().position(|&k| k == j);
        let mut parents = Vec::with_capacity(keep.len());
        let mut offsets = Vec::with_capacity(keep.len());
        for &j in keep {
            let mut p = self.parents[j];
            while let Some(pj) = p {
                if new_index(pj).is_some() {
                    break;
                }
                p = self.parents[pj];
            }
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

    /// Human-readable list of how two skeletons differ (empty when they match by name and parent).
    pub fn differences(&self, other: &Skeleton) -> Vec<String> {
        let mut out = Vec::new();
        if self.len() != other.len() {
            out.push(format!("{} joints against {}", self.len(), other.len()));
        }
        for name in &self.names {
            if other.index_of(name).is_none() {
                out.push(format!("joint '{name}' is missing"));
            }
        }
        for name in &other.names {
            if self.index_of(name).is_none() {
                out.push(format!("unexpected joint '{name}'"));
            }
        }
        if out.is_empty() {
            for (j, name) in self.names.iter().enumerate() {
                let mine = self.parents[j].map(|p| self.names[p].as_str());
                let theirs = other.parents[other.index_of(name).unwrap_or(j)].map(|p| other.names[p].as_str());
                if mine != theirs {
                    out.push(format!("joint '{name}' has parent {mine:?} against {theirs:?}"));
                }
            }
        }
        out
    }
}
