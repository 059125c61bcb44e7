//! Motion texture: the detail of real motion that a spline through its own sparse poses
//! misses, taken from each class's training clips and laid over a take's dense frames.
//!
//! The natural spline through a real clip's sparse poses (`stride` frames apart, as GloGen
//! makes them) keeps 0.33-0.47x the clip's jerk (`glocal eval --suite locgen`), and that detail is not predictable from the
//! poses around it (no LocGen beats the spline by more than a few percent), so a take that
//! is splined between its sparse poses is smoother than capture however good the poses are.
//! The texture bank holds, per class, stretches of `real - spline(real's sparse poses)` from
//! its training clips, in the body's heading frame; it is zero at every sparse pose (the
//! spline passes through them), so laying it over a take keeps GloGen's poses and adds
//! the missing detail between them, turned to the take's heading (Pullen and Bregler's
//! "motion texture", 2002, with the spline as the keyframed motion).

use std::collections::{BTreeMap, HashMap};
use std::ops::Range;
use std::path::Path;

use anyhow::{Context, Result};
use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::corpus::{CalmFrames, Corpus};
use super::spec::ModelSpec;
use super::Error;
use crate::data::features::{spline_through_own_poses, FeatureLayout};
use crate::data::write::write_atomic;
use crate::motion::{JointRoles, RolesError};

/// The texture bank of a model folder, beside its weights.
pub const TEXTURE_FILE: &str = "texture.safetensors";
/// Texture kept per class (at pace 1): long enough not to repeat within a take's
/// segment of one class, small enough to ship (about 40 kB a class).
const SECONDS_PER_CLASS: f32 = 10.0;
/// A change of class fades the texture of one into the other's over this much either side.
const BLEND_SECONDS: f32 = 0.5;
/// The shortest stretch taken from one clip (a clip's texture is continuous only within it).
const MIN_STRETCH_SECONDS: f32 = 2.0;
/// A foot slower than this (m/s) may be planted: it gets no texture.
const PLANTED_SPEED: f32 = 0.15;
/// A foot this fast (m/s) is stepping: it gets all of its texture.
const SWING_SPEED: f32 = 0.6;
/// A foot slow enough to be planted this long before or after gets none either: a running
/// foot touches down for a few frames, between frames of swing.
const SWING_MARGIN_SECONDS: f32 = 0.07;
/// Largest texture file read.
const MAX_TEXTURE_BYTES: u64 = 16 << 20;

/// Per class, whole sparse intervals (`stride` frames each, the first of each a sparse pose)
/// of texture in the heading frame of the pose it was taken from.
pub struct Texture {
    stride: usize,
    joints: usize,
    classes: Vec<Vec<Vec3>>,
    /// Each leg's ankle and the joints under it, whose texture fades as the foot slows.
    feet: [(usize, Vec<usize>); 2],
}

/// What a take's sparse pose reads of the texture: its class's, and how much of it (a pose
/// in a style calmer than its class gets that style's share of the class's pace).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexturedPose {
    pub class: usize,
    pub share: f32,
}

impl Texture {
    /// The bank of `corpus`'s training clips for a model of `spec`.
    pub fn build(corpus: &Corpus, spec: &ModelSpec) -> Result<Self, RolesError> {
        let (stride, layout) = (spec.stride, &spec.layout);
        let budget = (SECONDS_PER_CLASS * spec.fps / stride as f32).round() as usize;
        let min_stretch = (MIN_STRETCH_SECONDS * spec.fps / stride as f32).round() as usize;
        let calm_frames = CalmFrames::of(corpus);
        let classes = (0..spec.classes.len())
            .map(|class| {
                let clips: Vec<usize> = (0..corpus.train.len()).filter(|&i| corpus.train[i].class == class).collect();
                // An even share of the class's budget from each clip, at least a stretch long.
                let share = (budget / clips.len().max(1)).max(min_stretch);
                let mut bank = Vec::new();
                for &clip in &clips {
                    let left = budget.saturating_sub(bank.len() / (stride * layout.joints()));
                    if left == 0 {
                        break;
                    }
                    let calm = |frames: Range<usize>| calm_frames.holds(clip, frames);
                    bank.extend(clip_texture(layout, corpus.train[clip].motion.positions(), stride, share.min(left), calm));
                }
                bank
            })
            .collect();
        Self::with_classes(stride, layout, classes)
    }

    fn with_classes(stride: usize, layout: &FeatureLayout, classes: Vec<Vec<Vec3>>) -> Result<Self, RolesError> {
        let roles = JointRoles::new(&layout.skeleton)?;
        let feet = [&roles.left, &roles.right].map(|leg| (leg.ankle, leg.foot_joints(&layout.skeleton)));
        Ok(Self { stride, joints: layout.joints(), classes, feet })
    }

    /// Sparse intervals of texture class `class` holds.
    fn intervals(&self, class: usize) -> usize {
        self.classes.get(class).map_or(0, |c| c.len() / (self.stride * self.joints))
    }

    /// Lays the texture over `dense`: the frames from sparse pose `first` of a take onwards,
    /// `stride` per interval, the interval starting at each pose textured from the class of
    /// that pose in `poses` (the whole take's), scaled by the pose's own share of it. Each
    /// class's texture is also scaled by its share in `spec`'s `texture_gains`, a change of
    /// class or of share fades one into the next over [`BLEND_SECONDS`] either side of it,
    /// and a foot's fades out as it slows to a stand ([`swing_weights`]). Which stretch of a
    /// class's bank a take reads is chosen by `seed`;
    /// the interval at the take's sparse pose `k` reads the bank's interval `offset + k`, so a
    /// class's texture runs on unbroken through its segment and any stretch of the take gets
    /// the same texture whether it is finished alone or with the rest.
    pub fn lay_over(&self, dense: &mut [Vec3], spec: &ModelSpec, first: usize, poses: &[TexturedPose], seed: u64) {
        let (s, j, layout) = (self.stride, self.joints, &spec.layout);
        let gains = spec.texture_gain_per_class();
        let reach = (BLEND_SECONDS * spec.fps / s as f32).round() as usize;
        let (parents, limits) = (layout.skeleton.parents(), spec.turn_limits_per_frame());
        let swing = self.feet.each_ref().map(|(ankle, _)| swing_weights(dense, j, *ankle, spec.fps, layout.skeleton.meters_per_unit()));
        let (mut mix, mut reads, mut texture, mut weights, mut laid) = (Vec::new(), Vec::new(), vec![Vec3::ZERO; j], vec![1.0; j], Vec::with_capacity(j));
        for (i, interval) in dense.chunks_mut(s * j).enumerate() {
            let k = first + i;
            if k >= poses.len() {
                break;
            }
            // Each class's share of the interval and the bank interval it reads, once for its frames.
            shares_around(poses, k, reach, &gains, &mut mix);
            reads.clear();
            reads.extend(mix.iter().filter_map(|&(class, share)| {
                let n = self.intervals(class);
                (n > 0 && share != 0.0).then(|| (&self.classes[class][(bank_offset(seed, class) + k) % n * s * j..], share))
            }));
            // The interval's first frame is its sparse pose, where the texture is zero.
            for (phase, frame) in interval.chunks_exact_mut(j).enumerate().skip(1) {
                texture.fill(Vec3::ZERO);
                for (bank, share) in &reads {
                    texture.iter_mut().zip(&bank[phase * j..(phase + 1) * j]).for_each(|(t, b)| *t += *b * *share);
                }
                weights.fill(1.0);
                for ((_, joints), swings) in self.feet.iter().zip(&swing) {
                    joints.iter().for_each(|&joint| weights[joint] = swings[i * s + phase]);
                }
                let turn = Quat::from_rotation_y(layout.heading(frame));
                texture.iter_mut().zip(&weights).for_each(|(t, w)| *t = turn * *t * *w);
                hold_turns(frame, &mut texture, &mut laid, &weights, parents, &limits);
                frame.iter_mut().zip(&texture).for_each(|(p, t)| *p += *t);
            }
        }
    }

    /// Writes the bank to `path` atomically: one i16 tensor per class (frames, joints, 3),
    /// and a [`Header`] as the one metadata entry (one, so the file is the same byte for byte
    /// each time it is gathered).
    pub fn save(&self, path: &Path, spec: &ModelSpec) -> Result<()> {
        let mut header = Header { stride: self.stride, joints: self.joints, scales: BTreeMap::new() };
        let mut data = Vec::new();
        for (class, bank) in spec.classes.iter().zip(&self.classes) {
            let peak = bank.iter().map(|v| v.abs().max_element()).fold(0.0f32, f32::max);
            let scale = if peak > 0.0 { peak / i16::MAX as f32 } else { 1.0 };
            header.scales.insert(class.clone(), scale);
            let bytes: Vec<u8> = bank.iter().flat_map(|v| v.to_array()).flat_map(|x| ((x / scale).round() as i16).to_le_bytes()).collect();
            data.push((class.clone(), vec![bank.len() / self.joints, self.joints, 3], bytes));
        }
        let views = data
            .iter()
            .map(|(name, shape, bytes)| Ok((name.as_str(), safetensors::tensor::TensorView::new(safetensors::Dtype::I16, shape.clone(), bytes)?)))
            .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()
            .with_context(|| format!("cannot encode {}", path.display()))?;
        let metadata = HashMap::from([(HEADER_KEY.to_string(), serde_json::to_string(&header)?)]);
        let bytes = safetensors::serialize(views, Some(metadata)).with_context(|| format!("cannot encode {}", path.display()))?;
        write_atomic(path, &bytes)
    }

    /// Reads the bank at `path` for a model of `spec`: every class's tensor there, of the
    /// model's stride and joints.
    pub fn load(path: &Path, spec: &ModelSpec) -> Result<Self, Error> {
        let mismatch = |problem: String| Error::Mismatch { path: path.to_path_buf(), problem };
        let bytes = crate::data::input::read_bytes(path, MAX_TEXTURE_BYTES).map_err(|cause| Error::File { what: format!("cannot read {}", path.display()), cause })?;
        let (_, header) = safetensors::SafeTensors::read_metadata(&bytes).map_err(|e| mismatch(format!("not a safetensors file: {e}")))?;
        let file = safetensors::SafeTensors::deserialize(&bytes).map_err(|e| mismatch(format!("not a safetensors file: {e}")))?;
        let text = header.metadata().as_ref().and_then(|m| m.get(HEADER_KEY)).ok_or_else(|| mismatch(format!("has no '{HEADER_KEY}' entry in its metadata")))?;
        let Header { stride, joints, scales } = serde_json::from_str(text).map_err(|e| mismatch(format!("its '{HEADER_KEY}' metadata is not a texture header: {e}")))?;
        if stride != spec.stride || joints != spec.layout.joints() {
            return Err(mismatch(format!("is of stride {stride} and {joints} joints; the model's are {} and {}", spec.stride, spec.layout.joints())));
        }
        let classes = spec
            .classes
            .iter()
            .map(|class| {
                let view = file.tensor(class).map_err(|_| mismatch(format!("has no texture of class '{class}'")))?;
                let scale = *scales.get(class).ok_or_else(|| mismatch(format!("has no scale for class '{class}'")))?;
                let shape = view.shape();
                if view.dtype() != safetensors::Dtype::I16 || shape.len() != 3 || shape[1] != joints || shape[2] != 3 || shape[0] % stride != 0 || !scale.is_finite() {
                    return Err(mismatch(format!("class '{class}': a {:?} tensor of shape {shape:?} with scale {scale}; expected i16 (a whole number of {stride}-frame intervals, {joints}, 3)", view.dtype())));
                }
                let values: Vec<f32> = view.data().chunks_exact(2).map(|b| i16::from_le_bytes([b[0], b[1]]) as f32 * scale).collect();
                Ok(values.chunks_exact(3).map(|v| Vec3::new(v[0], v[1], v[2])).collect())
            })
            .collect::<Result<_, Error>>()?;
        Self::with_classes(stride, &spec.layout, classes).map_err(|e| mismatch(e.to_string()))
    }
}

/// The metadata entry that holds a texture file's [`Header`].
const HEADER_KEY: &str = "texture";

/// What a texture file says of its tensors: the stride and joints they were gathered at, and
/// each class's i16 step (in the skeleton's units).
#[derive(Serialize, Deserialize)]
struct Header {
    stride: usize,
    joints: usize,
    scales: BTreeMap<String, f32>,
}

/// Per frame, how far a foot (its `ankle`, in `dense` frames of `joints`) swings: 0 while
/// it moves slower than a planted foot can and for [`SWING_MARGIN_SECONDS`] either side (so a
/// foot about to land or just lifting is as still as the foot lock finds it), 1 once it
/// moves as a stepping foot does. `fps` and `metres_per_unit` turn a step between frames into
/// metres a second.
fn swing_weights(dense: &[Vec3], joints: usize, ankle: usize, fps: f32, metres_per_unit: f32) -> Vec<f32> {
    let frames = dense.len() / joints;
    let at = |f: usize| dense[f.min(frames - 1) * joints + ankle];
    let moving: Vec<f32> = (0..frames)
        .map(|f| {
            let speed = (at(f + 1) - at(f.saturating_sub(1))).length() / 2.0 * fps * metres_per_unit;
            ((speed - PLANTED_SPEED) / (SWING_SPEED - PLANTED_SPEED)).clamp(0.0, 1.0)
        })
        .collect();
    let margin = (SWING_MARGIN_SECONDS * fps).round() as usize;
    (0..frames).map(|f| moving[f.saturating_sub(margin)..(f + margin + 1).min(frames)].iter().copied().fold(1.0, f32::min)).collect()
}

/// `moves` (per joint of `frame`, the texture laid on it) with no bone turned by them further
/// than half its limit (`limits`, radians a frame; a bone without one is left), so the texture
/// alone turns no bone past its limit from one frame to the next. The texture is capture
/// detail of a few millimetres, which turns a long bone by a degree or two but a short one (a
/// toe, a thumb) by as much as the offset is long. Laid whole, h36m's sitting down from the
/// new-project seed turned a 75 mm toe 60 degrees in one frame and back in the next. Each
/// bone keeps the texture's move of its child relative to its parent, less what turns it past
/// half its limit, and shortens by at most half its length (further, it would turn round its
/// parent); parents come first, so a held bone carries the joints below it. A joint with a
/// share of its texture under 1 (`weights`: a foot as it slows to a stand) takes that share
/// of the held move and the rest as laid, so a planted foot stays where the lock finds it.
/// `laid`: room for the moves as laid.
fn hold_turns(frame: &[Vec3], moves: &mut [Vec3], laid: &mut Vec<Vec3>, weights: &[f32], parents: &[Option<usize>], limits: &[Option<f32>]) {
    laid.clear();
    laid.extend_from_slice(moves);
    for j in 0..moves.len() {
        let Some(parent) = parents[j] else { continue };
        let mut own = laid[j] - laid[parent];
        let bone = frame[j] - frame[parent];
        if let (Some(Some(limit)), Some(along)) = (limits.get(j), bone.try_normalize()) {
            let (length, reach) = (bone.length(), own.dot(along));
            let lengthened = reach.max(-0.5 * length);
            let across = own - along * reach;
            let max_across = (length + lengthened) * (limit / 2.0).tan();
            own = along * lengthened + across * (max_across / across.length()).min(1.0);
        }
        let held = moves[parent] + own;
        moves[j] = laid[j].lerp(held, weights[j]);
    }
}

/// Each class's share of the texture at sparse pose `k` of a take of `poses`: the sum of
/// the poses' own shares within `reach` of `k` over how many poses that is, times the
/// class's gain.
fn shares_around(poses: &[TexturedPose], k: usize, reach: usize, gains: &[f32], mix: &mut Vec<(usize, f32)>) {
    mix.clear();
    let around = &poses[k.saturating_sub(reach)..(k + reach + 1).min(poses.len())];
    for pose in around {
        match mix.iter_mut().find(|(c, _)| *c == pose.class) {
            Some((_, sum)) => *sum += pose.share,
            None => mix.push((pose.class, pose.share)),
        }
    }
    let total = around.len() as f32;
    mix.iter_mut().for_each(|(class, share)| *share *= gains.get(*class).copied().unwrap_or(1.0) / total);
}

/// Where a take of variation `seed` starts reading class `class`'s bank.
fn bank_offset(seed: u64, class: usize) -> usize {
    // SplitMix64's finaliser: neighbouring seeds and classes land far apart.
    let mut z = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (class as u64).wrapping_add(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as usize
}

/// Up to `intervals` sparse intervals of one clip's texture (`positions`, `joints` a frame),
/// each frame's in the heading frame of its pose: the stretch nearest the clip's middle (a
/// clip's start and end are often a standing pose) whose frames are all `calm`
/// ([`CalmFrames`]); none where no stretch of that length is.
fn clip_texture(layout: &FeatureLayout, positions: &[Vec3], stride: usize, intervals: usize, calm: impl Fn(Range<usize>) -> bool) -> Vec<Vec3> {
    let j = layout.joints();
    let frames = positions.len() / j;
    let available = frames.saturating_sub(1) / stride;
    let take = intervals.min(available);
    if take == 0 {
        return Vec::new();
    }
    let frames_of = |first: usize| first * stride..(first + take) * stride + 1;
    let middle = (available - take) / 2;
    let Some(first) = (0..=available - take).filter(|&f| calm(frames_of(f))).min_by_key(|f| f.abs_diff(middle)) else { return Vec::new() };
    let real = &positions[frames_of(first).start * j..frames_of(first).end * j];
    let spline = spline_through_own_poses(real, j, stride);
    let mut out = Vec::with_capacity(take * stride * j);
    for (pose, smooth) in real.chunks_exact(j).zip(spline.chunks_exact(j)).take(take * stride) {
        let unturn = Quat::from_rotation_y(-layout.heading(pose));
        out.extend(pose.iter().zip(smooth).map(|(p, q)| unturn * (*p - *q)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_change_of_class_shares_the_texture_around_it() {
        let mut mix = Vec::new();
        let poses = [0, 0, 0, 1, 1, 1].map(|class| TexturedPose { class, share: 1.0 });
        shares_around(&poses, 2, 1, &[1.0, 0.5], &mut mix);
        assert_eq!(mix, vec![(0, 2.0 / 3.0), (1, 0.5 / 3.0)]);
        shares_around(&poses, 0, 1, &[1.0, 0.5], &mut mix);
        assert_eq!(mix, vec![(0, 1.0)]);
        // A pose's own share (a calm style's) weighs in as its class's gain does.
        let calm = [(0, 1.0), (0, 1.0), (0, 0.25)].map(|(class, share)| TexturedPose { class, share });
        shares_around(&calm, 1, 1, &[1.0], &mut mix);
        assert_eq!(mix, vec![(0, 0.75)]);
    }

    /// A chain ankle -> toe -> toe end: 7 cm of texture across the 75 mm toe turns it by half
    /// its limit (5 of 10 degrees) and no further, and the toe end, moved as the toe was, moves
    /// with the toe as held; a move along the toe is kept but for shortening it by more than
    /// half (the bone projection sees to lengths), and the cap holds on the toe as moved; a
    /// toe without a limit is left, and a toe end with no share of the texture (a planted
    /// foot's) stays where it was laid whatever its parent's hold.
    #[test]
    fn texture_turns_no_bone_past_its_limit() {
        let frame = [Vec3::ZERO, Vec3::new(0.0, 0.0, 75.0), Vec3::new(0.0, 0.0, 150.0)];
        let parents = [None, Some(0), Some(1)];
        let limit = 10f32.to_radians();
        let limits = [None, Some(limit), Some(limit)];
        let hold = |moves: &mut [Vec3], weights: &[f32], limits: &[Option<f32>]| hold_turns(&frame, moves, &mut Vec::new(), weights, &parents, limits);
        let turned = |moves: &[Vec3]| (frame[1] + moves[1] - frame[0] - moves[0]).angle_between(frame[1] - frame[0]);
        let mut moves = [Vec3::ZERO, Vec3::new(0.0, -70.0, 0.0), Vec3::new(0.0, -70.0, 0.0)];
        hold(&mut moves, &[1.0; 3], &limits);
        assert!((turned(&moves) - limit / 2.0).abs() < 1e-4, "{moves:?}");
        assert_eq!(moves[2] - moves[1], Vec3::ZERO);
        let mut along = [Vec3::ZERO, Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, 5.0)];
        hold(&mut along, &[1.0; 3], &limits);
        assert_eq!(along[1], Vec3::new(0.0, 0.0, 5.0));
        let mut shortened = [Vec3::ZERO, Vec3::new(0.0, -70.0, -60.0), Vec3::ZERO];
        hold(&mut shortened, &[1.0; 3], &limits);
        assert!((turned(&shortened) - limit / 2.0).abs() < 1e-4 && (shortened[1].z + 37.5).abs() < 1e-4, "{shortened:?}");
        let mut free = [Vec3::ZERO, Vec3::new(0.0, -70.0, 0.0), Vec3::ZERO];
        hold(&mut free, &[1.0; 3], &[None, None, None]);
        assert_eq!(free[1], Vec3::new(0.0, -70.0, 0.0));
        let mut planted = [Vec3::ZERO, Vec3::new(0.0, -70.0, 0.0), Vec3::ZERO];
        hold(&mut planted, &[1.0, 1.0, 0.0], &limits);
        assert_eq!(planted[2], Vec3::ZERO);
    }

    /// A foot planted for 10 frames and then stepping at 1 m/s (30 fps, metres) gets no texture
    /// while planted and for the two frames after, then all of it.
    #[test]
    fn a_planted_foot_gets_no_texture() {
        let dense: Vec<Vec3> = (0..20usize).map(|f| Vec3::new(f.saturating_sub(10) as f32 / 30.0, 0.0, 0.0)).collect();
        let weights = swing_weights(&dense, 1, 0, 30.0, 1.0);
        assert!(weights[..12].iter().all(|&w| w == 0.0), "{weights:?}");
        assert!(weights[13..17].iter().all(|&w| w == 1.0), "{weights:?}");
    }

    #[test]
    fn bank_offsets_differ_by_seed_and_class() {
        assert_ne!(bank_offset(0, 0), bank_offset(1, 0));
        assert_ne!(bank_offset(0, 0), bank_offset(0, 1));
        assert_eq!(bank_offset(7, 3), bank_offset(7, 3));
    }
}
