//! Single-frame bone snaps: per bone, the angle its direction turns from one frame to the
//! next at [`COMMON_FPS`], against the real test clips' 99.9th percentile of the same bone.
//! A take whose bone turns farther in one frame than real motion does once in a thousand
//! frames snaps (a hand-end bone turning 79 degrees at one frame of an h36m take).

use std::collections::{BTreeMap, HashMap};

use serde::Serialize;

use super::metrics::quantile;
use super::motion::COMMON_FPS;
use crate::model::corpus::Track;
use crate::motion::{Motion, SNAP_QUANTILE};

/// A bone by its child joint, named `parent>child`.
fn bone_name(m: &Motion, j: usize) -> String {
    let names = m.skeleton.names();
    m.skeleton.parents()[j].map_or_else(|| names[j].clone(), |p| format!("{}>{}", names[p], names[j]))
}

/// Per bone (its child joint, with the bone's name), the angle in degrees its direction turns
/// between each frame and the next of `m`.
pub fn bone_turns(m: &Motion) -> Vec<(usize, String, Vec<f32>)> {
    crate::motion::bone_turns(m).into_iter().map(|(j, turns)| (j, bone_name(m, j), turns)).collect()
}

/// Per bone name, the real clips' [`SNAP_QUANTILE`] of the per-frame turn (degrees).
#[derive(Clone, Debug, Serialize)]
pub struct SnapLimits(pub HashMap<String, f32>);

impl SnapLimits {
    /// From every clip of `tracks`, resampled to [`COMMON_FPS`] as the suites measure.
    pub fn from_tracks(tracks: &[Track]) -> Self {
        let mut pooled: HashMap<String, Vec<f32>> = HashMap::new();
        for track in tracks {
            for (_, name, turns) in bone_turns(&track.motion.resample(COMMON_FPS)) {
                pooled.entry(name).or_default().extend(turns);
            }
        }
        Self(pooled.into_iter().map(|(name, turns)| (name, quantile(&turns, SNAP_QUANTILE))).collect())
    }
}

/// One bone's largest turn in one take.
#[derive(Clone, Debug, Serialize)]
pub struct Snap {
    pub take: String,
    pub bone: String,
    /// The frame (at [`COMMON_FPS`]) the turn ends at.
    pub frame: usize,
    pub degrees: f32,
    pub limit: f32,
}

impl Snap {
    fn excess(&self) -> f32 {
        self.degrees / self.limit
    }

    /// `bone 79 deg at 2.20 s (real p99.9 31)`.
    pub fn describe(&self) -> String {
        format!("{} {:.0} deg at {:.2} s (real p99.9 {:.0})", self.bone, self.degrees, self.frame as f32 / COMMON_FPS, self.limit)
    }
}

/// Over a set of takes: how many have a bone over its real limit, how many bones are over in
/// all, in how many takes each bone is over (where the snaps are), and the worst (the largest
/// turn over its limit).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SnapTally {
    pub takes: usize,
    pub takes_over: usize,
    pub bones_over: usize,
    pub takes_over_per_bone: BTreeMap<String, usize>,
    pub worst: Option<Snap>,
}

impl SnapTally {
    /// Adds take `m` (at [`COMMON_FPS`]), named `take`, judged on the turns that end after frame
    /// `given_until` (a file start's given frames up to it are the file's own motion; 0
    /// judges every turn); returns its bones over their `limits`, farthest over first, or its
    /// nearest bone when none is over.
    pub fn add(&mut self, limits: &SnapLimits, take: &str, m: &Motion, given_until: usize) -> Vec<Snap> {
        let worst_per_bone = bone_turns(m).into_iter().filter_map(|(_, bone, turns)| {
            let limit = *limits.0.get(&bone)?;
            // Turn `t` ends at frame `t + 1`.
            let (frame, degrees) = turns.iter().copied().enumerate().skip(given_until).max_by(|a, b| a.1.total_cmp(&b.1))?;
            Some(Snap { take: take.to_string(), bone, frame: frame + 1, degrees, limit })
        });
        let mut bones: Vec<Snap> = worst_per_bone.collect();
        bones.sort_by(|a, b| b.excess().total_cmp(&a.excess()));
        let over = bones.iter().filter(|s| s.degrees > s.limit).count();
        for snap in &bones[..over] {
            *self.takes_over_per_bone.entry(snap.bone.clone()).or_default() += 1;
        }
        self.takes += 1;
        self.takes_over += usize::from(over > 0);
        self.bones_over += over;
        if let Some(w) = bones.first() {
            if self.worst.as_ref().is_none_or(|old| w.excess() > old.excess()) {
                self.worst = Some(w.clone());
            }
        }
        bones.truncate(over.max(1));
        bones
    }

    /// `2 of 160 takes, 3 bones in all (most often over: BONE in N, ...); the largest over its
    /// limit: ... in TAKE`.
    pub fn describe(&self) -> String {
        let worst = self.worst.as_ref().map_or("-".to_string(), Snap::describe);
        format!("{} of {} takes, {} bones in all (most often over: {}); the largest over its limit: {} in {}", self.takes_over, self.takes, self.bones_over, self.most_often_over(3), worst, self.worst.as_ref().map_or("-", |w| w.take.as_str()))
    }

    /// The `n` bones over their limit in the most takes, `bone in N takes, ...`.
    fn most_often_over(&self, n: usize) -> String {
        let mut bones: Vec<(&String, &usize)> = self.takes_over_per_bone.iter().collect();
        bones.sort_by(|a, b| b.1.cmp(a.1));
        let named: Vec<String> = bones.iter().take(n).map(|(bone, takes)| format!("{bone} in {takes}")).collect();
        if named.is_empty() {
            "none".to_string()
        } else {
            named.join(", ")
        }
    }
}
