//! The in-betweener's window: the known frames before a gap, the gap filled by linear
//! interpolation from the last known pose to the key, and the key, as normalised features
//! with two more channels per frame (whether the frame is given, how far through the gap it
//! is). The network predicts a residual on the gap's interpolation (the Δ-interpolator of
//! Oreshkin et al. 2022): with nothing learnt it is linear interpolation, the in-betweening
//! baseline it is judged against. Training and generation build it here alike.

use glam::Vec3;

use super::spec::InbetweenSpec;
use crate::data::features::{FeatureLayout, Normalizer};

/// Channels after the features: 1 on given frames (context and key), and the frame's share
/// of the way through the gap.
pub const GAP_CHANNELS: usize = 2;

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
/// before them, which starts their velocities), the gap's linear interpolation and `key`:
/// per frame its normalised features and the [`GAP_CHANNELS`]. Also returns the window's
/// frames as interpolated (context, gap, key).
pub fn gap_window(layout: &FeatureLayout, norm: &Normalizer, before: &[Vec3], context: &[Vec3], key: &[Vec3], gap: usize) -> (Vec<f32>, Vec<Vec3>) {
    let j = layout.joints();
    let last = &context[context.len() - j..];
    let mut frames = context.to_vec();
    frames.extend(linear_gap(last, key, gap));
    frames.extend_from_slice(key);
    let refs: Vec<&[Vec3]> = frames.chunks_exact(j).collect();
    let mut feats = layout.encode(&refs, Some(before));
    norm.normalize(&mut feats);
    let (dim, known) = (layout.dim(), context.len() / j);
    let mut input = Vec::with_capacity(refs.len() * (dim + GAP_CHANNELS));
    for (f, row) in feats.chunks_exact(dim).enumerate() {
        let in_gap = f >= known && f < known + gap;
        let share = (f + 1).saturating_sub(known) as f32 / (gap + 1) as f32;
        input.extend_from_slice(row);
        input.extend([if in_gap { 0.0 } else { 1.0 }, share.min(1.0)]);
    }
    (input, frames)
}

/// Per window frame and feature, the factor the network's output is scaled by: the
/// feature's residual scale in the gap, 0 on the given frames (they come out as given).
pub fn gap_gain(spec: &InbetweenSpec, gap: usize) -> Vec<f32> {
    let frames = spec.context + gap + 1;
    (0..frames).flat_map(|f| {
        let in_gap = f >= spec.context && f < spec.context + gap;
        spec.residual_scale.iter().map(move |s| if in_gap { *s } else { 0.0 })
    })
    .collect()
}

/// Decoded window frames (`joints` each: the context, the gap, the key) with what the learnt
/// steps miss the key by spread evenly over the gap: the key frame moves onto `key_root` on
/// the ground and each gap frame its share of the way, so the body arrives where the key
/// stands.
pub fn spread_arrival(frames: &mut [Vec3], joints: usize, context: usize, key_root: Vec3) {
    let windows = frames.len() / joints;
    let arrival = frames[(windows - 1) * joints] - key_root;
    let drift = Vec3::new(arrival.x, 0.0, arrival.z);
    let steps = windows - context;
    for (f, frame) in frames.chunks_exact_mut(joints).enumerate().skip(context) {
        let share = (f + 1 - context) as f32 / steps as f32;
        frame.iter_mut().for_each(|p| *p -= drift * share);
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
    fn the_arrival_is_spread_over_the_gap_and_the_context_stays() {
        // One joint: two context frames, a gap of one, a key that overshot by 2 on x.
        let mut frames = vec![Vec3::ZERO, Vec3::X, Vec3::new(3.0, 1.0, 0.0), Vec3::new(6.0, 1.0, 0.0)];
        spread_arrival(&mut frames, 1, 2, Vec3::new(4.0, 0.0, 0.0));
        assert_eq!(frames, vec![Vec3::ZERO, Vec3::X, Vec3::new(2.0, 1.0, 0.0), Vec3::new(4.0, 1.0, 0.0)]);
    }
}
