//! Training material for one dataset: every clip resampled to the working frame rate, cut
//! to the model's joints, with the normalisation statistics of the training split.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use rand::Rng;

use crate::data::archive::DataRoot;
use crate::data::features::{interpolate, FeatureLayout, Interpolation, Normalizer};
use crate::data::loading;
use crate::data::registry::{self, Dataset, Split};
use super::spec::ModelSpec;
use crate::motion::{bone_turns, peak_accelerations, quantile, JointRoles, Motion, Skeleton, SHORT_BONE_FRACTION, SNAP_QUANTILE};

/// The styles that mean "no particular style", which a class's usual style falls to on a tie.
const PLAIN_STYLES: [&str; 2] = ["neutral", "normal"];

#[derive(Clone)]
pub struct Track {
    pub class: usize,
    pub file: String,
    /// Bandai's style, Human3.6M's subject ([`registry::Clip::tag`]).
    pub tag: String,
    /// Its style in [`Corpus::styles`] (a model with styles only).
    pub style: Option<usize>,
    /// A test clip whose style is learned from it ([`registry::Clip::teaches_style`]).
    pub teaches_style: bool,
    pub motion: Motion,
}

pub struct Corpus {
    pub dataset: Dataset,
    pub classes: Vec<String>,
    /// Where each class's clips come from (the combined dataset only).
    pub class_sources: Vec<String>,
    /// The styles a model of this corpus is conditioned on: those of the training clips and of
    /// the test clips that teach a style (the combined dataset only; empty otherwise).
    pub styles: Vec<String>,
    /// The dataset's whole skeleton, and the joints of it the model keeps.
    pub source_skeleton: Arc<Skeleton>,
    pub source_joints: Vec<usize>,
    pub layout: FeatureLayout,
    pub fps: f32,
    pub stride: usize,
    pub train: Vec<Track>,
    pub test: Vec<Track>,
}

impl Corpus {
    /// The data the model in `dir` (of `spec`) was trained on: `dataset` at the model's
    /// stride, refused when its classes are not the model's.
    pub fn for_model(dataset: Dataset, root: &DataRoot, spec: &ModelSpec, dir: &Path) -> Result<Self> {
        let corpus = Self::load(dataset, root, spec.stride, 3)?;
        if corpus.classes != spec.classes {
            bail!("{}: the model's classes ({}) differ from the data's ({})", dir.display(), spec.classes.join(", "), corpus.classes.join(", "));
        }
        Ok(corpus)
    }

    /// Loads a dataset. `min_clips` drops classes with fewer training clips (Bandai's
    /// one-clip contents cannot be learned or evaluated).
    pub fn load(dataset: Dataset, root: &DataRoot, stride: usize, min_clips: usize) -> Result<Self> {
        let loaded = loading::load(dataset, root)?;
        let Some(first) = loaded.clips.first() else { bail!("{dataset} has no readable clips") };
        let skeleton = first.motion.skeleton.clone();
        let roles = JointRoles::new(&skeleton).with_context(|| format!("{dataset}'s skeleton ({})", first.file))?;
        let source_joints = model_joints(&skeleton, roles.body_root);
        let layout = FeatureLayout::new(Arc::new(skeleton.subset(&source_joints)))
            .with_context(|| format!("{dataset}'s model skeleton ({})", first.file))?;
        let fps = dataset.working_fps();
        let mut counts = vec![0usize; loaded.classes.len()];
        for c in loaded.split(Split::Train) {
            counts[c.class] += 1;
        }
        let kept: Vec<usize> = (0..loaded.classes.len()).filter(|&k| counts[k] >= min_clips).collect();
        let classes = kept.iter().map(|&k| loaded.classes[k].clone()).collect();
        let class_sources = kept.iter().filter_map(|&k| loaded.class_sources.get(k).cloned()).collect();
        let taught = |c: &&registry::Clip| c.split == Split::Train || c.teaches_style;
        let styles: Vec<String> = loaded.styles.iter().filter(|s| loaded.clips.iter().filter(taught).any(|c| c.tag == **s)).cloned().collect();
        let (mut train, mut test) = (Vec::new(), Vec::new());
        for clip in loaded.clips {
            let Some(class) = kept.iter().position(|&k| k == clip.class) else { continue };
            let mut motion = clip.motion.resample(fps).subset(&source_joints);
            motion.skeleton = layout.skeleton.clone();
            let style = styles.iter().position(|s| *s == clip.tag);
            let track = Track { class, file: clip.file, tag: clip.tag, style, teaches_style: clip.teaches_style, motion };
            match clip.split {
                Split::Train => train.push(track),
                Split::Test => test.push(track),
            }
        }
        Ok(Self { dataset, classes, class_sources, styles, source_skeleton: skeleton, source_joints, layout, fps, stride, train, test })
    }

    /// The same data with other clips: `train` and `test` in place of its own.
    pub fn with_tracks(&self, train: Vec<Track>, test: Vec<Track>) -> Corpus {
        Corpus {
            dataset: self.dataset,
            classes: self.classes.clone(),
            class_sources: self.class_sources.clone(),
            styles: self.styles.clone(),
            source_skeleton: self.source_skeleton.clone(),
            source_joints: self.source_joints.clone(),
            layout: self.layout.clone(),
            fps: self.fps,
            stride: self.stride,
            train,
            test,
        }
    }

    /// The index of the style `name` in [`Corpus::styles`].
    pub fn style_index(&self, name: &str) -> Option<usize> {
        self.styles.iter().position(|s| s == name)
    }

    /// The clips styles are learned from: the training clips and the test clips that teach a
    /// style ([`Track::teaches_style`]).
    pub fn style_training(&self) -> impl Iterator<Item = &Track> {
        self.train.iter().chain(self.test.iter().filter(|t| t.teaches_style))
    }

    /// Each class's usual style: the one most of its training clips have (empty without styles).
    pub fn usual_styles(&self) -> Vec<usize> {
        if self.styles.is_empty() {
            return Vec::new();
        }
        (0..self.classes.len())
            .map(|k| {
                let mut counts = vec![0usize; self.styles.len()];
                for s in self.train.iter().filter(|t| t.class == k).filter_map(|t| t.style) {
                    counts[s] += 1;
                }
                // Ties (Bandai has one clip of each content in each style) go to the plain
                // style, Bandai's "normal".
                let plain = |s: usize| PLAIN_STYLES.contains(&self.styles[s].as_str());
                (0..counts.len()).max_by_key(|&s| (counts[s], plain(s), std::cmp::Reverse(s))).unwrap_or(0)
            })
            .collect()
    }

    /// Mean joint speed of each class over its training clips, in units per second.
    pub fn class_speeds(&self) -> Vec<f32> {
        (0..self.classes.len()).map(|k| frame_weighted_speed(self.train.iter().filter(|t| t.class == k))).collect()
    }

    /// Per class whose clips come in more than one style, the mean joint speed of each
    /// style's clips (those styles are learned from, [`Self::style_training`]), in units per
    /// second, by name ([`ModelSpec::style_speed`]): Bandai's byebye waves at 0.02 m/s sad
    /// and 0.71 m/s active.
    pub fn style_speeds(&self) -> BTreeMap<String, BTreeMap<String, f32>> {
        let mut speeds = BTreeMap::new();
        for (k, class) in self.classes.iter().enumerate() {
            let of_class: Vec<&Track> = self.style_training().filter(|t| t.class == k).collect();
            let mut styles: Vec<usize> = of_class.iter().filter_map(|t| t.style).collect();
            styles.sort_unstable();
            styles.dedup();
            if styles.len() < 2 {
                continue;
            }
            let by_style = styles.iter().map(|&s| (self.styles[s].clone(), frame_weighted_speed(of_class.iter().copied().filter(|t| t.style == Some(s))))).collect();
            speeds.insert(class.clone(), by_style);
        }
        speeds
    }

    /// Per bone of the model's skeleton (by its child joint), the turn of its direction in
    /// one frame that the training clips' calm frames ([`CalmFrames`]) stay within but once in
    /// a thousand ([`SNAP_QUANTILE`]), degrees a second: how far a take's bone may turn
    /// ([`ModelSpec::bone_turn_limits`]).
    pub fn bone_turn_limits(&self) -> BTreeMap<String, f32> {
        let calm = CalmFrames::of(self);
        let mut pooled: BTreeMap<usize, Vec<f32>> = BTreeMap::new();
        for (clip, track) in self.train.iter().enumerate() {
            for (j, turns) in bone_turns(&track.motion) {
                // Turn `t` is from frame `t` to `t + 1`.
                let calm_turns = turns.iter().enumerate().filter(|&(t, _)| calm.holds(clip, t..t + 2)).map(|(_, &turn)| turn);
                pooled.entry(j).or_default().extend(calm_turns);
            }
        }
        let names = self.layout.skeleton.names();
        pooled.into_iter().filter(|(_, turns)| !turns.is_empty()).map(|(j, turns)| (names[j].clone(), quantile(&turns, SNAP_QUANTILE) * self.fps)).collect()
    }

    /// Normalisation of sparse features (`stride` apart) and of dense ones (1 apart).
    pub fn normalizers(&self) -> (Normalizer, Normalizer) {
        let dim = self.layout.dim();
        let (mut sparse, mut dense) = (Vec::new(), Vec::new());
        for t in &self.train {
            let m = &t.motion;
            for phase in 0..self.stride.min(m.frames()) {
                let count = (m.frames() - phase).div_ceil(self.stride);
                sparse.extend(self.layout.encode_motion(m, phase, self.stride, count));
            }
            dense.extend(self.layout.encode_motion(m, 0, 1, m.frames()));
        }
        (Normalizer::fit(&sparse, dim), Normalizer::fit(&dense, dim))
    }
}

/// Which stretches of the training clips are free of capture glitches, for what is taken
/// from the clips as they are (the motion texture, the seed bank): every frame's largest
/// joint acceleration within [`CALM_OVER_P99`] times its class's 99th percentile.
pub struct CalmFrames {
    /// Per training clip (in [`Corpus::train`]'s order), each frame's largest joint
    /// acceleration ([`crate::motion::peak_accelerations`]).
    accelerations: Vec<Vec<f32>>,
    /// Per training clip, the largest acceleration a calm frame of its class has.
    limits: Vec<f32>,
}

/// A calm frame's joint acceleration stays within this many times its class's 99th
/// percentile. The rarest frames of a class are its capture's glitches (CMU's clips start
/// from a reference pose 0.7-1.4 m from their first frame; its dances lose a marker for a
/// frame or two; a Human3.6M sitting clip's joint jumps: 150-1440 m/s^2 where the class's
/// 99th percentile is 30-140) and its most violent moments. Gathered into the motion
/// texture, either came back every 10 s of the class as a pop (Indian dance's and salsa's
/// takes peaked at 2.5-15x their jerk without texture); in a seed window, a take started
/// from it popped in its first second (`all`'s sitting seed 102: 8156 m/s^3, 90x the
/// take's median).
pub const CALM_OVER_P99: f32 = 2.0;

impl CalmFrames {
    pub fn of(corpus: &Corpus) -> Self {
        let accelerations: Vec<Vec<f32>> = corpus.train.iter().map(|t| peak_accelerations(t.motion.positions(), t.motion.joints(), t.motion.fps)).collect();
        let class_limits: Vec<f32> = (0..corpus.classes.len())
            .map(|class| {
                let values: Vec<f32> = corpus.train.iter().zip(&accelerations).filter(|(t, _)| t.class == class).flat_map(|(_, a)| a.iter().copied()).collect();
                CALM_OVER_P99 * quantile(&values, 0.99)
            })
            .collect();
        let limits = corpus.train.iter().map(|t| class_limits[t.class]).collect();
        Self { accelerations, limits }
    }

    /// Whether frames `frames` of training clip `clip` (an index into [`Corpus::train`]) are
    /// all calm.
    pub fn holds(&self, clip: usize, frames: std::ops::Range<usize>) -> bool {
        self.accelerations[clip][frames].iter().all(|&a| a <= self.limits[clip])
    }
}

/// The joints a model of this skeleton keeps: bones shorter than a fraction of the longest
/// limb bone are duplicates or collapsed end sites. Joints above the body root (Bandai's
/// `joint_Root`, a placement handle above `Hips`) are dropped too, so the model's root is the
/// joint where the body branches, the one that carries the pelvis.
fn model_joints(skeleton: &Skeleton, body_root: usize) -> Vec<usize> {
    let longest_limb = (0..skeleton.len())
        .filter(|&j| skeleton.parents()[j].is_some_and(|p| p != 0))
        .map(|j| skeleton.offsets()[j].length())
        .fold(0.0, f32::max);
    let mut keep = skeleton.informative_joints(longest_limb * SHORT_BONE_FRACTION);
    let mut above = skeleton.parents()[body_root];
    while let Some(p) = above {
        keep.retain(|&j| j != p);
        above = skeleton.parents()[p];
    }
    if !keep.contains(&body_root) {
        keep.insert(0, body_root);
    }
    keep
}

/// Mean speed of all joints, units per second.
pub fn mean_joint_speed(m: &Motion) -> f32 {
    (crate::motion::mean_joint_step(m.positions(), m.joints()) * m.fps as f64) as f32
}

/// Mean joint speed over `tracks`, each clip weighed by its frames, in units per second.
fn frame_weighted_speed<'a>(tracks: impl Iterator<Item = &'a Track>) -> f32 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for t in tracks {
        sum += mean_joint_speed(&t.motion) as f64 * t.motion.frames() as f64;
        n += t.motion.frames();
    }
    (sum / n.max(1) as f64) as f32
}

/// A random training window: `count` sparse samples `stride` apart from one clip, class
/// chosen uniformly first so that rare classes are seen as often as common ones.
pub fn sample_window<'a>(tracks: &'a [Track], classes: usize, span: usize, rng: &mut impl Rng) -> Option<(&'a Track, usize)> {
    let class = rng.random_range(0..classes);
    let fits: Vec<&Track> = tracks.iter().filter(|t| t.class == class && t.motion.frames() > span).collect();
    let pool = if fits.is_empty() { tracks.iter().filter(|t| t.motion.frames() > span).collect() } else { fits };
    let total: usize = pool.iter().map(|t| t.motion.frames() - span).sum();
    if total == 0 {
        return None;
    }
    let mut pick = rng.random_range(0..total);
    for t in pool {
        let room = t.motion.frames() - span;
        if pick < room {
            return Some((t, pick));
        }
        pick -= room;
    }
    None
}

/// Keys a spline reads on each side of a LocGen window beyond the window's own. Generation
/// splines through a whole take, and a natural spline's end conditions fade by about a
/// quarter a key, so a window cut from a clip with three keys either side sees (within 2%)
/// the spline generation gives the same window.
const SPLINE_CONTEXT_KEYS: usize = 3;

/// LocGen's input for the dense frames `[start, start + window)`: the interpolation between
/// the sparse keyframes `stride` apart from `start` on. A spline also reads the keyframes
/// either side of the window, as far as the clip has them, as it does inside a generated take.
pub fn interpolated_window(m: &Motion, start: usize, window: usize, stride: usize, kind: Interpolation) -> Vec<Vec3> {
    let j = m.joints();
    let context = if kind == Interpolation::Linear { 0 } else { SPLINE_CONTEXT_KEYS };
    let before = (start / stride).min(context);
    let first = start - before * stride;
    let covering = (window - 1).div_ceil(stride);
    let after = (covering + context).min((m.frames() - 1 - start) / stride).max(covering);
    let keys: Vec<Vec3> = (0..=before + after).flat_map(|k| m.frame(first + k * stride).to_vec()).collect();
    let dense = interpolate(&keys, j, stride, kind);
    let skip = before * stride * j;
    dense[skip..skip + window * j].to_vec()
}
