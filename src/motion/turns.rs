//! How far bones turn from frame to frame, and single-frame snaps spread out: a bone whose
//! direction turns farther between two frames than its limit (the model's training clips'
//! turn of that bone once in a thousand frames) has the turn spread over the few frames
//! around it, each bone on its own, every bone keeping its length and every other bone its
//! direction. The network now and then flips a hand: Bandai's dash from its seed 32 turns the
//! right hand 55 degrees in one frame, where its training clips turn it 39.

use std::ops::Range;

use glam::Vec3;

use super::{Motion, Skeleton};

/// The share of real frames a bone's turn in one frame stays within for it to count as a
/// snap beyond it: the real clips' turn once in a thousand frames (the motion suite's limit
/// against the test clips, the spread's against the training clips).
pub const SNAP_QUANTILE: f32 = 0.999;
/// Bones shorter than this (metres) have no direction worth measuring: duplicate joints and
/// collapsed end sites.
const MIN_BONE_M: f32 = 0.01;

/// Per bone long enough to have a direction (by its child joint), the angle in degrees its
/// direction turns between each frame and the next of `m` (a frame where the bone has no
/// length reads as a right angle: as the motion suite has always counted it).
pub fn bone_turns(m: &Motion) -> Vec<(usize, Vec<f32>)> {
    let rest = m.skeleton.rest_bone_lengths();
    let unit = m.skeleton.meters_per_unit();
    (0..m.joints())
        .filter_map(|j| {
            let parent = m.skeleton.parents()[j]?;
            (rest[j] * unit >= MIN_BONE_M).then(|| {
                let direction = |t: usize| (m.frame(t)[j] - m.frame(t)[parent]).normalize_or_zero();
                (j, (1..m.frames()).map(|t| direction(t - 1).dot(direction(t)).clamp(-1.0, 1.0).acos().to_degrees()).collect())
            })
        })
        .collect()
}

/// The most frames a snap is spread over either side; a turn that needs more is the motion's
/// own (a fast swing) and is left as it is.
const MAX_SPREAD: usize = 8;
/// The farthest (radians) a bone may travel over a window for the window to be put on the
/// shortest turn between its ends: three quarters of a turn. Further, its frames go round
/// every way and say nothing of which way it went ([`goes_the_short_way`]).
const MAX_WINDOW_TRAVEL: f32 = 1.5 * std::f32::consts::PI;
/// Ends nearer than this (radians) to opposite have no one shortest turn between them.
const MAX_APART: f32 = 3.0;

/// `positions` (frames of `skeleton`'s joints) with every bone `j` that has a limit
/// (`limits[j]`, radians a frame) turning no farther than it from one frame to the next,
/// where spreading over at most [`MAX_SPREAD`] frames either side can make it so. Returns
/// how many frames changed.
pub fn spread_snaps(positions: &mut [Vec3], skeleton: &Skeleton, limits: &[Option<f32>]) -> usize {
    let joints = skeleton.len();
    let frames = positions.len() / joints;
    let parents = skeleton.parents();
    let mut new_directions: Vec<Option<Vec<Vec3>>> = vec![None; joints];
    let mut changed = vec![false; frames];
    for j in 1..joints {
        let (Some(parent), Some(limit)) = (parents[j], limits[j]) else { continue };
        let mut directions: Vec<Vec3> = positions.chunks_exact(joints).map(|f| (f[j] - f[parent]).normalize_or_zero()).collect();
        let spread = spread_turns(&mut directions, limit);
        for range in &spread {
            changed[range.clone()].iter_mut().for_each(|c| *c = true);
        }
        if !spread.is_empty() {
            new_directions[j] = Some(directions);
        }
    }
    for (t, frame) in positions.chunks_exact_mut(joints).enumerate().filter(|(t, _)| changed[*t]) {
        let bones: Vec<Vec3> = (0..joints).map(|j| parents[j].map_or(frame[j], |p| frame[j] - frame[p])).collect();
        for j in 1..joints {
            let parent = parents[j].expect("only the root has no parent");
            let bone = new_directions[j].as_ref().map_or(bones[j], |d| d[t] * bones[j].length());
            frame[j] = frame[parent] + bone;
        }
    }
    changed.iter().filter(|&&c| c).count()
}

/// The angle (radians) between unit directions `a` and `b`; zero where either is zero.
fn turn(a: Vec3, b: Vec3) -> f32 {
    if a == Vec3::ZERO || b == Vec3::ZERO {
        return 0.0;
    }
    a.dot(b).clamp(-1.0, 1.0).acos()
}

/// `directions` (unit vectors, one a frame) with each turn over `limit` spread: the frames
/// between the nearest frames either side that `limit` a frame can join in a shortest turn
/// are put on that turn ([`shares`]). Returns the frames changed.
fn spread_turns(directions: &mut [Vec3], limit: f32) -> Vec<Range<usize>> {
    let mut spread = Vec::new();
    let mut t = 1;
    while t < directions.len() {
        if turn(directions[t - 1], directions[t]) <= limit {
            t += 1;
            continue;
        }
        let Some((a, b, shares)) = window_around(directions, t, limit) else {
            t += 1;
            continue;
        };
        let (from, to) = (directions[a], directions[b]);
        for (d, share) in directions[a + 1..b].iter_mut().zip(shares) {
            *d = from.slerp(to, share);
        }
        spread.push(a + 1..b);
        t = b + 1;
    }
    spread
}

/// The frames `(a, b)` around the turn ending at frame `t`, widened a frame each side at a
/// time (less at an end), that the bone travels less than [`MAX_WINDOW_TRAVEL`] over, the
/// short way round, and whose frames between can be put on the shortest turn at most `limit`
/// a frame apart: with their [`shares`] of it, or even shares where those turn too fast in
/// the middle (the bone arriving fast at one end and leaving slowly at the other).
fn window_around(directions: &[Vec3], t: usize, limit: f32) -> Option<(usize, usize, Vec<f32>)> {
    let last = directions.len() - 1;
    let (mut a, mut b) = (t - 1, t);
    for _ in 0..MAX_SPREAD {
        a = a.saturating_sub(1);
        b = (b + 1).min(last);
        let (from, to) = (directions[a], directions[b]);
        let travelled: f32 = directions[a..=b].windows(2).map(|d| turn(d[0], d[1])).sum();
        let apart = turn(from, to);
        if from == Vec3::ZERO || to == Vec3::ZERO || travelled >= MAX_WINDOW_TRAVEL || apart >= MAX_APART || !goes_the_short_way(directions, a, b) {
            continue;
        }
        let fits = |shares: &[f32]| {
            let steps: Vec<f32> = std::iter::once(0.0).chain(shares.iter().copied()).chain(std::iter::once(1.0)).collect();
            steps.windows(2).all(|s| (s[1] - s[0]).abs() * apart <= limit)
        };
        let even: Vec<f32> = (a + 1..b).map(|k| (k - a) as f32 / (b - a) as f32).collect();
        if let Some(shares) = [shares(directions, a, b), even].into_iter().find(|s| fits(s)) {
            return Some((a, b, shares));
        }
    }
    None
}

/// Whether the bone goes from `directions[a]` to `directions[b]` the short way round: its
/// directions between them lie, on the whole, on the side of the shortest turn's middle. A
/// hand flipping 137 degrees in two frames goes the short way, and a window wide enough to
/// spread it travels over half a turn; a bone swinging round past a half turn has its ends
/// nearer the other way, and put on the shortest turn it would swing back.
fn goes_the_short_way(directions: &[Vec3], a: usize, b: usize) -> bool {
    let middle = directions[a].slerp(directions[b], 0.5);
    directions[a + 1..b].iter().sum::<Vec3>().dot(middle) > 0.0
}

/// Where along the shortest turn from `directions[a]` to `directions[b]` (0 at `a`, 1 at
/// `b`) each frame between them goes: a cubic that leaves `a` and reaches `b` at the speed the
/// bone has there along that turn, so it neither stops nor lurches at the window's ends (put
/// on the turn evenly, Bandai's takes jerked 2% more); none where the bone moves against the
/// turn, at most three times the even speed, so it never turns back.
fn shares(directions: &[Vec3], a: usize, b: usize) -> Vec<f32> {
    let (from, to) = (directions[a], directions[b]);
    let span = (b - a) as f32;
    let apart = turn(from, to).max(f32::EPSILON);
    let chord = to - from;
    // The speed along the turn (radians a frame, for a short step) of `step` at `at`, as a
    // slope of the share against the window's even one.
    let slope = |at: Vec3, step: Vec3| (step.dot((chord - at * chord.dot(at)).normalize_or_zero()) * span / apart).clamp(0.0, 3.0);
    let leaving = if a > 0 { slope(from, from - directions[a - 1]) } else { 0.0 };
    let arriving = directions.get(b + 1).map_or(0.0, |&next| slope(to, next - to));
    (a + 1..b)
        .map(|k| {
            let u = (k - a) as f32 / span;
            let (u2, u3) = (u * u, u * u * u);
            (3.0 * u2 - 2.0 * u3) + leaving * (u3 - 2.0 * u2 + u) + arriving * (u3 - u2)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;

    /// A root, an upper arm and a forearm: the forearm swings about z at `steps[t]` degrees
    /// from frame to frame, the upper arm still.
    fn swinging_arm(steps: &[f32]) -> (Skeleton, Vec<Vec3>) {
        let skeleton = Skeleton::new(["root", "elbow", "wrist"].map(String::from).to_vec(), vec![None, Some(0), Some(1)], vec![Vec3::ZERO, Vec3::X * 0.3, Vec3::X * 0.25], 1.0).unwrap();
        let mut angle = 0.0f32;
        let mut positions = Vec::new();
        for t in 0..=steps.len() {
            if t > 0 {
                angle += steps[t - 1];
            }
            let forearm = Quat::from_rotation_z(angle.to_radians()) * Vec3::X * 0.25;
            positions.extend([Vec3::ZERO, Vec3::X * 0.3, Vec3::X * 0.3 + forearm]);
        }
        (skeleton, positions)
    }

    fn forearm_turns(positions: &[Vec3]) -> Vec<f32> {
        let directions: Vec<Vec3> = positions.chunks_exact(3).map(|f| (f[2] - f[1]).normalize()).collect();
        directions.windows(2).map(|d| turn(d[0], d[1]).to_degrees()).collect()
    }

    /// A forearm that snaps 60 degrees in one frame between frames turning 2 a frame, with a
    /// limit of 20: the snap is spread so no frame turns over 20, the forearm keeps its
    /// length, frames away from the snap are untouched, and the turn in all is the same.
    #[test]
    fn a_snap_is_spread_over_the_frames_around_it() {
        let mut steps = vec![2.0; 20];
        steps[10] = 60.0;
        let (skeleton, mut positions) = swinging_arm(&steps);
        let before = positions.clone();
        let changed = spread_snaps(&mut positions, &skeleton, &[None, None, Some(20f32.to_radians())]);
        let turns = forearm_turns(&positions);
        assert!(turns.iter().all(|&t| t <= 20.0 + 1e-3), "{turns:?}");
        assert!((2..=4).contains(&changed), "{changed} frames changed");
        assert!((turns.iter().sum::<f32>() - steps.iter().sum::<f32>()).abs() < 1e-2);
        for (t, (now, was)) in positions.chunks_exact(3).zip(before.chunks_exact(3)).enumerate() {
            assert!(((now[2] - now[1]).length() - 0.25).abs() < 1e-5);
            assert_eq!(now[..2], was[..2], "frame {t}: the upper arm moved");
            if !(8..=13).contains(&t) {
                assert_eq!(now, was, "frame {t} is far from the snap");
            }
        }
    }

    /// A forearm that flicks out 50 degrees for one frame and back: the flick is taken out
    /// (the frame put between its neighbours), so the forearm barely moves.
    #[test]
    fn a_one_frame_flick_is_taken_out() {
        let mut steps = vec![0.0; 10];
        steps[4] = 50.0;
        steps[5] = -50.0;
        let (skeleton, mut positions) = swinging_arm(&steps);
        spread_snaps(&mut positions, &skeleton, &[None, None, Some(20f32.to_radians())]);
        assert!(forearm_turns(&positions).iter().all(|&t| t < 1e-3), "{:?}", forearm_turns(&positions));
    }

    /// A hand that flips 137 degrees in two frames between frames turning 10 (Bandai's dash
    /// from its seed window 13): a window wide enough to spread it travels past a half turn,
    /// the short way round; spread, no frame turns over the limit of 38.7.
    #[test]
    fn a_two_frame_flip_is_spread() {
        let mut steps = vec![10.0; 20];
        steps[9] = 73.0;
        steps[10] = 64.0;
        let (skeleton, mut positions) = swinging_arm(&steps);
        spread_snaps(&mut positions, &skeleton, &[None, None, Some(38.7f32.to_radians())]);
        let turns = forearm_turns(&positions);
        assert!(turns.iter().all(|&t| t <= 38.7 + 1e-3), "{turns:?}");
    }

    /// A swing that turns 25 degrees a frame for a whole second against a limit of 20 cannot
    /// be spread within a few frames: it is the motion's own and is left as it is; so is
    /// every bone without a limit.
    #[test]
    fn a_long_fast_swing_and_a_bone_without_a_limit_are_left() {
        let (skeleton, positions) = swinging_arm(&[25.0; 30]);
        for limits in [[None, None, Some(20f32.to_radians())], [None, None, None]] {
            let mut spread = positions.clone();
            assert_eq!(spread_snaps(&mut spread, &skeleton, &limits), 0);
            assert_eq!(spread, positions);
        }
    }
}
