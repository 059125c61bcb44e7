//! The in-betweener's window: the known frames before a gap, the gap filled by linear
//! interpolation from the last known pose to the key, the key and the known frames after it,
//! as normalised features
//! with two more channels per frame (whether the frame is given, how far through the gap it
//! is). The network predicts a residual on the gap's interpolation (the Δ-interpolator of
//! Oreshkin et al. 2022): with nothing learnt it is linear interpolation, the in-betweening
//! baseline it is judged against. Training and generation build it here alike.

use glam::Vec3;

use super::spec::{InbetweenSpec, GAP_CHANNELS};
use crate::data::features::{FeatureLayout, Normalizer, Placement};

/// The frames strictly between `last` and `key` (`joints` each) on the straight line from
/// one to the other, joint by joint.
pub fn linear_gap(last: &[Vec3], key: &[Vec3], gap: usize) -> Vec<Vec3> {
    (1..=gap).flat_map(|f| {
        let s = f as f32 / (gap + 1) as f32;
        last.iter().zip(key).map(move |(a, b)| a.lerp(*b, s))
    })
    .collect()
}

/// The window of `context` (its known frames, the gap's start last), `before` (the frame
/// before them, which starts their velocities), the gap's linear interpolation, and `ahead`:
/// the key and the known frames after it, which say how the body leaves the key (`joints`
/// each). Per frame its normalised features and the [`GAP_CHANNELS`]; also the window's frames
/// as interpolated.
pub fn gap_window(layout: &FeatureLayout, norm: &Normalizer, before: &[Vec3], context: &[Vec3], ahead: &[Vec3], gap: usize) -> (Vec<f32>, Vec<Vec3>) {
    let j = layout.joints();
    let last = &context[context.len() - j..];
    let mut frames = context.to_vec();
    frames.extend(linear_gap(last, &ahead[..j], gap));
    frames.extend_from_slice(ahead);
    let refs: Vec<&[Vec3]> = frames.chunks_exact(j).collect();
    let mut feats = layout.encode(&refs, Some(before));
    norm.normalize(&mut feats);
    let (dim, known) = (layout.dim(), context.len() / j);
    let mut input = Vec::with_capacity(refs.len() * (dim + GAP_CHANNELS));
    for (f, row) in feats.chunks_exact(dim).enumerate() {
        input.extend_from_slice(row);
        input.extend([if in_gap(f, known, gap) { 0.0 } else { 1.0 }, share_of_gap(f, known, gap)]);
    }
    (input, frames)
}

fn in_gap(frame: usize, context: usize, gap: usize) -> bool {
    (context..context + gap).contains(&frame)
}

/// How far through the gap a window frame is: 0 over the context, 1 from the key on.
fn share_of_gap(frame: usize, context: usize, gap: usize) -> f32 {
    ((frame + 1).saturating_sub(context) as f32 / (gap + 1) as f32).min(1.0)
}

/// Per frame of a window of `frames` and per feature, the factor the network's output is
/// scaled by: the feature's residual scale in the gap, 0 on the given frames (they come out
/// as given).
pub fn gap_gain(spec: &InbetweenSpec, gap: usize, frames: usize) -> Vec<f32> {
    (0..frames).flat_map(|f| spec.residual_scale.iter().map(move |s| if in_gap(f, spec.context, gap) { *s } else { 0.0 })).collect()
}

/// A window's refined features (normalised; the context, the gap, the key and the frames
/// after it) as frames in the world `start` places them (the placement of the frame before
/// the window), the body arriving where the key stands ([`spread_arrival`]).
pub fn fill_frames(layout: &FeatureLayout, norm: &Normalizer, mut feats: Vec<f32>, start: Placement, context: usize, gap: usize, key_root: Vec3) -> Vec<Vec3> {
    norm.denormalize(&mut feats);
    let mut frames = layout.decode(&feats, start).0;
    spread_arrival(&mut frames, layout.joints(), context, gap, key_root);
    frames
}

/// Decoded window frames (`joints` each: the context, the gap, the key and the frames after
/// it) with what the learnt steps miss the key by spread evenly over the gap: the key and
/// the frames after it move by all of it (the key onto `key_root` on the ground) and each gap
/// frame by its share, so the body arrives where the key stands.
fn spread_arrival(frames: &mut [Vec3], joints: usize, context: usize, gap: usize, key_root: Vec3) {
    let arrival = frames[(context + gap) * joints] - key_root;
    let drift = Vec3::new(arrival.x, 0.0, arrival.z);
    for (f, frame) in frames.chunks_exact_mut(joints).enumerate().skip(context) {
        let share = share_of_gap(f, context, gap);
        frame.iter_mut().for_each(|p| *p -= drift * share);
    }
}

/// Seconds at each end of a gap over which a fill is bent to meet the take.
pub const BEND_SECONDS: f32 = 0.3;

/// Frames (`joints` each) with the gap `gap` (frame indices, the known pose before it and the
/// key after it) bent at both ends so each joint moves through the known pose and through
/// the key without a change of velocity. The network's fill neither leaves its known pose
/// nor reaches its key quite at the pace of the frames either side (a key far from where the
/// motion was going bends it most): unbent, Bandai's fills met their keys at 5-9x the real
/// jerk. Each bend is a cubic bump over `reach` frames, all of the change at the frame next
/// to the pose, falling flat to nothing; the known pose and the key do not move.
pub fn bend_ends(frames: &mut [Vec3], joints: usize, gap: std::ops::Range<usize>, reach: usize) {
    let count = frames.len() / joints;
    let reach = reach.min(gap.len());
    if reach == 0 || gap.start < 2 || gap.end + 1 >= count {
        return;
    }
    bend(frames, joints, gap.start - 1, (1..=reach).map(|d| gap.start - 1 + d), reach);
    bend(frames, joints, gap.end, (1..=reach).map(|d| gap.end - d), reach);
}

/// Takes the change of velocity at frame `pivot` out by moving the frames `moved` (nearest
/// first) by it times a cubic bump that is 1 at the first and falls flat to nothing one past
/// the last.
fn bend(frames: &mut [Vec3], joints: usize, pivot: usize, moved: impl Iterator<Item = usize>, reach: usize) {
    let at = |f: usize, j: usize| frames[f * joints + j];
    let change: Vec<Vec3> = (0..joints).map(|j| at(pivot + 1, j) - 2.0 * at(pivot, j) + at(pivot - 1, j)).collect();
    let end = (reach + 1) as f32;
    let shape = |d: f32| d * (1.0 - d / end).powi(2) / (1.0 - 1.0 / end).powi(2);
    for (d, f) in moved.enumerate() {
        let w = shape((d + 1) as f32);
        frames[f * joints..(f + 1) * joints].iter_mut().zip(&change).for_each(|(p, c)| *p -= *c * w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_linear_gap_leaves_both_ends_out() {
        let (a, b) = ([Vec3::ZERO], [Vec3::new(4.0, 0.0, 0.0)]);
        let gap = linear_gap(&a, &b, 3);
        assert_eq!(gap, vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)]);
    }

    #[test]
    fn a_bent_fill_moves_through_its_known_pose_and_its_key() {
        // One joint: the known pose at frame 2 reached at 1 a frame, a gap of 4 filled at 2 a
        // frame, the key at frame 7 left at 3 a frame.
        let xs = [0.0, 1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0];
        let mut frames: Vec<Vec3> = xs.iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect();
        bend_ends(&mut frames, 1, 3..7, 2);
        let accel = |f: usize| frames[f + 1].x - 2.0 * frames[f].x + frames[f - 1].x;
        assert!(accel(2).abs() < 1e-5 && accel(7).abs() < 1e-5, "{frames:?}");
        assert_eq!((frames[..3].to_vec(), frames[7..].to_vec()), (xs[..3].iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect(), xs[7..].iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect()), "the known frames stay");
    }

    #[test]
    fn the_arrival_is_spread_over_the_gap_and_the_context_stays() {
        // One joint: two context frames, a gap of one, a key that overshot by 2 on x and a
        // frame after it.
        let mut frames = vec![Vec3::ZERO, Vec3::X, Vec3::new(3.0, 1.0, 0.0), Vec3::new(6.0, 1.0, 0.0)];
        frames.push(Vec3::new(7.0, 1.0, 0.0));
        spread_arrival(&mut frames, 1, 2, 1, Vec3::new(4.0, 0.0, 0.0));
        assert_eq!(frames, vec![Vec3::ZERO, Vec3::X, Vec3::new(2.0, 1.0, 0.0), Vec3::new(4.0, 1.0, 0.0), Vec3::new(5.0, 1.0, 0.0)]);
    }
}
