//! Where the body stands and travels before its feet are locked: the take levelled on the
//! floor under its stance feet and set down where it floats ([`levelled`]), and carried as
//! far as its planted feet carry it ([`carried_by_feet`]) or, with its travel kept, held
//! still where it stands ([`held_still`]).

use std::ops::Range;

use glam::Vec3;

use super::SHIFT_SMOOTH_FRAMES;
use crate::motion::contacts::{body_speeds, local_floor, runs, sliding, smoothed, support_heights, ContactConfig, FootContacts};
use crate::motion::{JointRoles, Motion, Side};
use crate::synth::smoothstep;

/// Seconds over which a contact's share in carrying the body eases in and out at its ends
/// (see [`carried_by_feet`]).
const CARRY_EASE_SECONDS: f32 = 0.05;
/// A foot that is not in a detected contact still carries the body while its lowest joint
/// is within the first height of the floor (metres), easing out by the second, and it moves
/// slower than the hips. Measured on Bandai (`glocal eval --suite motion`, support-point
/// speed mean over real): detected contacts alone 2.06x (run 38.9 cm/s against the real
/// 19.0); with low feet up to 2-5 cm 1.67x, 3-6 cm 1.56x, 4-7 cm 1.48x, 5-8 cm 1.42x.
const CARRY_HEIGHT: (f32, f32) = (0.05, 0.08);
/// With the travel kept ([`held_still`]), a stretch of both feet standing at least this long
/// (seconds) is someone standing, whose drift is taken out, easing in and out over its
/// first and last [`STAND_EASE_SECONDS`].
const STAND_SECONDS: f32 = 0.6;
const STAND_EASE_SECONDS: f32 = 0.25;
/// Half-width (seconds) of the smoothing of the feet's common step before it is taken out
/// of the body: about a frame (with 0.05 s, detected contacts alone, support speed 2.06x as
/// with this, mean jerk 1.27x against 1.28x).
const CARRY_SMOOTH_SECONDS: f32 = 0.025;

/// The longest both feet leave the floor in a run or a jump, seconds (a run's flight phase is
/// about 0.1-0.15 s): a body floating longer is set down on the floor ([`set_down`]).
const LONGEST_FLIGHT_SECONDS: f32 = 0.4;

/// A body leaves the floor only by running or by jumping off it: below this horizontal speed
/// (metres per second, the body's average, [`body_speeds`]) a shorter float is kept only as
/// long as its launch could carry it ([`launched`]). An `all` walk started from a wave glided
/// with both feet 3-8 cm up for 0.3 s at a time while its hips rose at 0.2 m/s; real walking
/// has no flight, and a run's body moves at 2.5 m/s and more.
const RUN_SPEED: f32 = 2.0;
/// How much longer than a ballistic flight from its launch a float may last (seconds of
/// flight per second of `2 v / g`): the hips' speed at take-off underestimates the centre of
/// mass's, and a network's jump lands a little late.
const FLIGHT_SLACK: f32 = 1.5;
const GRAVITY: f32 = 9.81;
/// The longest lift an unlaunched float keeps (seconds, see [`set_down`]). With 0.2, `all`
/// walked to the right in hops of 0.2 s with both feet 5-8 cm up (13% of a first take's frames);
/// Bandai's jerk reads the same with either.
const UNLAUNCHED_LIFT_SECONDS: f32 = 0.1;

/// A body is set down only by as much as its support is higher than this above the floor
/// (metres): within the contact band, so the lock plants what it sets down, and a standing
/// body's millimetres of bob over the smoothed floor stay.
const FLOAT_TOLERANCE: f32 = 0.03;

/// About the half-width (seconds) of the smoothing of the stance-foot floor before the take is
/// levelled on it: the local floor is a staircase, the take should not jump.
const LEVEL_SMOOTH_SECONDS: f32 = 0.5;

/// The take with its body carried by its feet: each frame, the horizontal step of the feet
/// on the floor (each foot weighted by its contact, eased in and out over
/// [`CARRY_EASE_SECONDS`], or by how near the floor it is while it moves slower than the
/// hips, [`CARRY_HEIGHT`]; the mean where both stand) is taken out of the whole body. The
/// network's stance feet slide with the body (Bandai's running feet at 57 cm/s on the floor
/// against the real 19), and locking each foot where it stood would leave the body gliding
/// on and the legs stretched after it; so the body travels as far as its planted feet carry
/// it, and a standing body's slow drift goes with the same rule (Bandai's bowing feet
/// travelled 12 cm/s). The lock then has only the feet's own jitter left to hold.
pub(super) fn carried_by_feet(motion: &Motion, roles: &JointRoles, contacts: &FootContacts, kept: &[Range<usize>]) -> Motion {
    let frames = motion.frames();
    let step = |t: usize, joint: usize| {
        let step = motion.frame(t)[joint] - motion.frame(t.saturating_sub(1))[joint];
        Vec3::new(step.x, 0.0, step.z)
    };
    let unit = motion.skeleton.meters_per_unit();
    let (low, high) = CARRY_HEIGHT;
    let carrying = |side: Side| {
        let leg = roles.leg(side);
        let contact = eased(runs(contacts.side(side)), frames, (CARRY_EASE_SECONDS * motion.fps).max(1.0));
        let foot = leg.foot_joints(&motion.skeleton);
        (0..frames)
            .map(|t| {
                let height = foot.iter().map(|&j| motion.frame(t)[j].y * unit).fold(f32::INFINITY, f32::min);
                let slower = step(t, leg.ankle).length() < step(t, roles.body_root).length();
                let near = if slower { 1.0 - smoothstep((height - low) / (high - low)) } else { 0.0 };
                contact[t].max(near)
            })
            .collect::<Vec<f32>>()
    };
    let (left, right) = (carrying(Side::Left), carrying(Side::Right));
    let (left_ankle, right_ankle) = (roles.left.ankle, roles.right.ankle);
    let kept = |t: usize| kept.iter().any(|r| r.contains(&t));
    let steps: Vec<Vec3> = (0..frames)
        .map(|t| if kept(t) { Vec3::ZERO } else { (step(t, left_ankle) * left[t] + step(t, right_ankle) * right[t]) / (left[t] + right[t]).max(1.0) })
        .collect();
    let steps = smoothed(&steps, (CARRY_SMOOTH_SECONDS * motion.fps).round() as usize);
    moved_back(motion, steps)
}

/// The take with every frame's body moved back by the sum of the horizontal `steps` up to
/// it.
fn moved_back(motion: &Motion, steps: impl IntoIterator<Item = Vec3>) -> Motion {
    let mut drift = Vec3::ZERO;
    let mut positions = motion.positions().to_vec();
    for (frame, step) in positions.chunks_exact_mut(motion.joints()).zip(steps).skip(1) {
        drift += step;
        frame.iter_mut().for_each(|p| *p -= drift);
    }
    Motion::from_positions(motion.skeleton.clone(), motion.fps, positions)
}

/// The take with the drift of its standing stretches taken out: where both feet stand for at
/// least [`STAND_SECONDS`], the whole body moves back by what the feet moved together (their
/// mean horizontal step), easing in and out over [`STAND_EASE_SECONDS`] inside the stretch.
/// A network's standing character slides slowly as a whole (Bandai's bowing feet travel
/// 12 cm/s); locking each foot where it stood would leave the body gliding away from them.
pub(super) fn held_still(motion: &Motion, roles: &JointRoles, contacts: &FootContacts) -> Motion {
    let frames = motion.frames();
    let both: Vec<bool> = contacts.left.iter().zip(&contacts.right).map(|(l, r)| *l && *r).collect();
    let shortest = (STAND_SECONDS * motion.fps).round() as usize;
    let standing = runs(&both).into_iter().filter(|r| r.len() >= shortest);
    let weight = eased(standing, frames, (STAND_EASE_SECONDS * motion.fps).max(1.0));
    let ankles = [roles.left.ankle, roles.right.ankle];
    // The feet's own frame-to-frame jitter is not drift: subtracted from the whole body, it
    // would shake the hips (a standing h36m take's hip jerk 1.75x the network's).
    let steps: Vec<Vec3> = (0..frames)
        .map(|t| {
            let step = ankles.iter().map(|&a| motion.frame(t)[a] - motion.frame(t.saturating_sub(1))[a]).sum::<Vec3>() / 2.0;
            Vec3::new(step.x, 0.0, step.z)
        })
        .collect();
    let steps = smoothed(&steps, (STAND_EASE_SECONDS * motion.fps / 2.0).round() as usize);
    moved_back(motion, steps.iter().zip(&weight).map(|(s, w)| *s * *w))
}

/// Per frame of `frames`, 1 inside each of the runs `[start, end)` and easing to 0 over
/// `ease` frames at its ends.
fn eased(runs: impl IntoIterator<Item = std::ops::Range<usize>>, frames: usize, ease: f32) -> Vec<f32> {
    let mut weight = vec![0.0f32; frames];
    for std::ops::Range { start, end } in runs {
        for (t, w) in weight.iter_mut().enumerate().take(end).skip(start) {
            *w = smoothstep((t - start + 1).min(end - t) as f32 / ease);
        }
    }
    weight
}

/// The take moved up or down per frame so the floor under its stance feet (or its seat, on
/// a floor sit: [`support_heights`]) is at height 0, and set down where it floats, and the
/// height of that floor at the first frame: the whole take is put back on the floor it starts
/// on, where a file start's given frames stand (on the mean floor of a take that sank, a
/// Bandai walk's given start stood 6 cm above the rest).
pub(super) fn levelled(motion: &Motion, roles: &JointRoles, cfg: &ContactConfig) -> (Motion, f32) {
    let half = (cfg.floor_window * motion.fps).round() as usize;
    let support = support_heights(motion, roles);
    let floor = smoothed(&local_floor(&support, half), (LEVEL_SMOOTH_SECONDS * motion.fps / 2.0).round() as usize);
    let near = FLOAT_TOLERANCE / motion.skeleton.meters_per_unit();
    let above: Vec<f32> = support.iter().zip(&floor).map(|(s, f)| (s - f - near).max(0.0)).collect();
    let float = set_down(&above, motion, roles);
    let j = motion.joints();
    let mut positions = motion.positions().to_vec();
    for ((frame, lift), down) in positions.chunks_exact_mut(j).zip(&floor).zip(&float) {
        frame.iter_mut().for_each(|p| p.y -= lift + down);
    }
    (Motion::from_positions(motion.skeleton.clone(), motion.fps, positions), floor.first().copied().unwrap_or(0.0))
}

/// Per frame, how far to set the body down so that a stretch with both feet (and the seat)
/// off the floor longer than [`LONGEST_FLIGHT_SECONDS`], or one its launch could not carry
/// ([`launched`]), stands on it: `above` (the support's height over the floor) opened (the
/// lowest within half a window either side, then the highest of that within half a window),
/// which keeps every shorter lift and follows a longer one's height. The window is a flight
/// (a run's flight phase, a step stay), or for an unlaunched float [`UNLAUNCHED_LIFT_SECONDS`]
/// (setting such a float down whole, frame by frame, raised Bandai's run jerk from 1.19x to
/// 1.28x real). Smoothed, but never by more than the support is above the floor, so nothing
/// goes under it. The network's sitting down and standing up lift both feet off the ground
/// for up to 1.9 s instead of pushing through them.
fn set_down(above: &[f32], motion: &Motion, roles: &JointRoles) -> Vec<f32> {
    let opened = |seconds: f32| {
        let half = (seconds * motion.fps / 2.0).round() as usize;
        sliding(&local_floor(above, half), half, f32::max, 0.0)
    };
    let mut down = opened(LONGEST_FLIGHT_SECONDS);
    let unlaunched = opened(UNLAUNCHED_LIFT_SECONDS);
    let floating: Vec<bool> = above.iter().map(|&a| a > 0.0).collect();
    let body = body_speeds(motion, roles.body_root);
    for float in runs(&floating) {
        if !launched(motion, roles, &body, float.clone()) {
            float.for_each(|t| down[t] = down[t].max(unlaunched[t]));
        }
    }
    smoothed(&down, SHIFT_SMOOTH_FRAMES).iter().zip(above).map(|(d, a)| d.min(*a)).collect()
}

/// Whether the body could be in the air over the frames `float`: running (its average
/// horizontal speed `body` at least [`RUN_SPEED`]), or thrown up fast enough to stay up that
/// long: the hips' fastest rise from a tenth of a second before the float to its middle, as
/// a ballistic flight's time `2 v / g`, times [`FLIGHT_SLACK`].
fn launched(motion: &Motion, roles: &JointRoles, body: &[f32], float: Range<usize>) -> bool {
    let unit = motion.skeleton.meters_per_unit();
    let speed = float.clone().map(|t| body[t]).sum::<f32>() / float.len() as f32 * unit;
    if speed >= RUN_SPEED {
        return true;
    }
    let hips = |t: usize| motion.frame(t.min(motion.frames() - 1))[roles.body_root].y;
    let lead = (0.1 * motion.fps).round() as usize;
    let rise = (float.start.saturating_sub(lead)..float.start + float.len().div_ceil(2))
        .map(|t| (hips(t + 1) - hips(t.saturating_sub(1))) * motion.fps / 2.0 * unit)
        .fold(0.0f32, f32::max);
    float.len() as f32 / motion.fps <= FLIGHT_SLACK * 2.0 * rise / GRAVITY
}
