//! Foot contacts: per foot and frame, whether the foot stands on the floor. A foot is its
//! ankle and every joint under it ([`Leg::foot_joints`]); its height is its lowest joint's above the
//! floor and its speed its slowest joint's (so a heel rising at toe-off still counts as
//! standing on the toe). Contact begins when the foot is low and slow, and ends only when it
//! is clearly high or fast (hysteresis); runs and gaps shorter than a few frames are removed,
//! so contacts do not flicker.

use glam::Vec3;

use super::{JointRoles, Leg, Motion, Side};

/// Thresholds in metres and metres per second (scaled by the skeleton's unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactConfig {
    /// A foot this low and this slow starts a contact...
    pub height_on: f32,
    pub speed_on: f32,
    /// ...which lasts until it is higher or faster than these.
    pub height_off: f32,
    pub speed_off: f32,
    /// A stance foot moves far slower than the body: both speed thresholds are at least this
    /// fraction of the body's own horizontal speed (over [`BODY_SPEED_SECONDS`]), so a
    /// runner's planted foot, which a network makes slide at walking speed, still stands.
    pub body_speed_fraction: f32,
    /// Contacts and gaps shorter than this many seconds are dropped (filled).
    pub min_seconds: f32,
    /// Half-width of the window whose lowest foot height is the local floor, seconds: wider
    /// than a swing phase, so every window holds a standing foot.
    pub floor_window: f32,
    /// On a floor sit (the seat within `height_off` of the local floor, or reaching it within
    /// [`SEAT_APPROACH_SECONDS`]), a slow foot this high still rests on the floor: the network
    /// raises a seated body's feet 16-33 cm for a second or more at a time, where someone
    /// sitting on the floor keeps them on it (at 25 cm, 4 of h36m's 200 random takes still
    /// floated 0.9-3.0 s with their feet 27-33 cm up).
    pub seated_height: f32,
}

impl Default for ContactConfig {
    fn default() -> Self {
        Self { height_on: 0.05, speed_on: 0.35, height_off: 0.08, speed_off: 0.6, body_speed_fraction: 0.25, min_seconds: 0.1, floor_window: 1.0, seated_height: 0.35 }
    }
}

/// Half-width (seconds) of the moving average of the body's speed that scales the speed
/// thresholds: a stride or so, so the thresholds follow the gait, not each step.
pub const BODY_SPEED_SECONDS: f32 = 0.5;

/// Per-foot contact flags over a take's frames.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FootContacts {
    pub left: Vec<bool>,
    pub right: Vec<bool>,
}

impl FootContacts {
    /// The flags of frames `range` (none where the range runs past them).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Self {
        let part = |flags: &[bool]| flags.get(range.clone()).map(<[bool]>::to_vec).unwrap_or_default();
        Self { left: part(&self.left), right: part(&self.right) }
    }

    pub fn side(&self, side: Side) -> &[bool] {
        match side {
            Side::Left => &self.left,
            Side::Right => &self.right,
        }
    }
}

/// A body whose seat reaches the floor within this many seconds is sitting down onto it, and
/// its feet rest as a seated body's do ([`ContactConfig::seated_height`]).
const SEAT_APPROACH_SECONDS: f32 = 0.3;

/// How far under the hip joints the seat is on a floor sit, metres: the buttocks under the
/// hip sockets' centres, about 10 cm on an adult.
pub const SEAT_DEPTH: f32 = 0.1;

/// Per frame, the height of what carries the body, in the motion's units: the lowest foot
/// joint, or on a floor sit with the feet raised the seat ([`SEAT_DEPTH`] under the lower hip
/// joint) where that is lower. Never a hand: a hand reaching the ground does not carry the
/// body, and a floor set under it leaves the feet hovering (the floor rule of DESIGN.md).
pub fn support_heights(motion: &Motion, roles: &JointRoles) -> Vec<f32> {
    lower_of(&lowest_foot_heights(motion, roles), &seat_heights(motion, roles))
}

/// Per frame, the lower of two heights.
fn lower_of(a: &[f32], b: &[f32]) -> Vec<f32> {
    a.iter().zip(b).map(|(a, b)| a.min(*b)).collect()
}

/// Per frame, the height of the seat: [`SEAT_DEPTH`] under the lower hip joint.
fn seat_heights(motion: &Motion, roles: &JointRoles) -> Vec<f32> {
    let seat_depth = SEAT_DEPTH / motion.skeleton.meters_per_unit();
    let hips = [roles.left.hip, roles.right.hip];
    (0..motion.frames()).map(|t| hips.iter().map(|&j| motion.frame(t)[j].y).fold(f32::INFINITY, f32::min) - seat_depth).collect()
}

/// The height of each frame's lowest foot joint ([`Leg::foot_joints`]), in the motion's units.
pub fn lowest_foot_heights(motion: &Motion, roles: &JointRoles) -> Vec<f32> {
    let joints: Vec<usize> = Side::BOTH.iter().flat_map(|&s| roles.leg(s).foot_joints(&motion.skeleton)).collect();
    (0..motion.frames()).map(|t| joints.iter().map(|&j| motion.frame(t)[j].y).fold(f32::INFINITY, f32::min)).collect()
}

/// The floor under each frame: the lowest foot height within `half_window` frames either
/// side, so a take that rises or sinks (or real data on a tilted floor) keeps its contacts.
pub fn local_floor(lowest: &[f32], half_window: usize) -> Vec<f32> {
    sliding(lowest, half_window, f32::min, f32::INFINITY)
}

/// Per frame, `values` within `half_window` frames either side folded by `pick` from `start`
/// (a sliding minimum or maximum).
pub fn sliding(values: &[f32], half_window: usize, pick: fn(f32, f32) -> f32, start: f32) -> Vec<f32> {
    (0..values.len()).map(|t| values[t.saturating_sub(half_window)..(t + half_window + 1).min(values.len())].iter().copied().fold(start, pick)).collect()
}

/// Contacts of both feet over the local floor (of the feet, or the seat on a floor sit).
pub fn foot_contacts(motion: &Motion, roles: &JointRoles, cfg: &ContactConfig) -> FootContacts {
    let half = (cfg.floor_window * motion.fps).round() as usize;
    let seat = seat_heights(motion, roles);
    let floor = local_floor(&lower_of(&lowest_foot_heights(motion, roles), &seat), half);
    let unit = motion.skeleton.meters_per_unit();
    let on_floor: Vec<bool> = seat.iter().zip(&floor).map(|(seat, floor)| (seat - floor) * unit <= cfg.height_off).collect();
    let ahead = (SEAT_APPROACH_SECONDS * motion.fps).round() as usize;
    let seated: Vec<bool> = (0..on_floor.len()).map(|t| on_floor[t..(t + ahead + 1).min(on_floor.len())].contains(&true)).collect();
    let ground = Ground { floor: &floor, seated: &seated };
    let body = body_speeds(motion, roles.body_root);
    let contacts = |leg: &Leg| leg_contacts(motion, leg, &ground, &body, cfg);
    FootContacts { left: contacts(&roles.left), right: contacts(&roles.right) }
}

/// The horizontal speed of joint `root` per frame (units/s), averaged over
/// [`BODY_SPEED_SECONDS`] either side.
pub fn body_speeds(motion: &Motion, root: usize) -> Vec<f32> {
    let flat = |t: usize| {
        let mut v = joint_velocity(motion, root, t);
        v.y = 0.0;
        v.length()
    };
    let speeds: Vec<f32> = (0..motion.frames()).map(flat).collect();
    box_average(&speeds, (BODY_SPEED_SECONDS * motion.fps).round() as usize)
}

/// Each value replaced by the mean of those within `half` places either side (fewer at the
/// ends, where the window is cut off).
pub fn box_average<T>(values: &[T], half: usize) -> Vec<T>
where
    T: Copy + std::iter::Sum<T> + std::ops::Div<f32, Output = T>,
{
    (0..values.len())
        .map(|t| {
            let window = &values[t.saturating_sub(half)..(t + half + 1).min(values.len())];
            window.iter().copied().sum::<T>() / window.len() as f32
        })
        .collect()
}

/// Three passes of a moving average `2 * half + 1` wide (close to a Gaussian): a single box
/// leaves corners in the velocity, which show as jerk.
pub fn smoothed<T>(values: &[T], half: usize) -> Vec<T>
where
    T: Copy + std::iter::Sum<T> + std::ops::Div<f32, Output = T>,
{
    box_average(&box_average(&box_average(values, half), half), half)
}

/// Per frame, the local floor and whether the body sits on it.
struct Ground<'a> {
    floor: &'a [f32],
    seated: &'a [bool],
}

/// One foot's contacts over `ground`, with the body moving at `body` (one each per frame).
fn leg_contacts(motion: &Motion, leg: &Leg, ground: &Ground<'_>, body: &[f32], cfg: &ContactConfig) -> Vec<bool> {
    let unit = motion.skeleton.meters_per_unit();
    let joints = leg.foot_joints(&motion.skeleton);
    let frames = motion.frames();
    let mut out = Vec::with_capacity(frames);
    let mut on = false;
    for t in 0..frames {
        let height = joints.iter().map(|&j| motion.frame(t)[j].y).fold(f32::INFINITY, f32::min) - ground.floor[t];
        let speed = joints.iter().map(|&j| joint_velocity(motion, j, t).length()).fold(f32::INFINITY, f32::min);
        let (h, v) = (height * unit, speed * unit);
        let relative = cfg.body_speed_fraction * body[t] * unit;
        let (speed_on, speed_off) = (cfg.speed_on.max(relative), cfg.speed_off.max(relative * cfg.speed_off / cfg.speed_on));
        let (height_on, height_off) = if ground.seated[t] { (cfg.seated_height, cfg.seated_height) } else { (cfg.height_on, cfg.height_off) };
        on = if on { h <= height_off && v <= speed_off } else { h <= height_on && v <= speed_on };
        out.push(on);
    }
    let min_frames = (cfg.min_seconds * motion.fps).round().max(1.0) as usize;
    fill_short_runs(&mut out, false, min_frames);
    fill_short_runs(&mut out, true, min_frames);
    out
}

/// Velocity of joint `j` at frame `t` (central difference, one-sided at the ends), units/s.
fn joint_velocity(motion: &Motion, j: usize, t: usize) -> Vec3 {
    let frames = motion.frames();
    if frames < 2 {
        return Vec3::ZERO;
    }
    let (a, b) = (t.saturating_sub(1), (t + 1).min(frames - 1));
    (motion.frame(b)[j] - motion.frame(a)[j]) * motion.fps / (b - a) as f32
}

/// Runs of `value` shorter than `min` frames between two runs of the other value take the
/// other value (gaps in contact are filled, then blips of contact dropped).
fn fill_short_runs(flags: &mut [bool], value: bool, min: usize) {
    let mut t = 0;
    while t < flags.len() {
        if flags[t] != value {
            t += 1;
            continue;
        }
        let start = t;
        while t < flags.len() && flags[t] == value {
            t += 1;
        }
        let inner = start > 0 && t < flags.len();
        if inner && t - start < min {
            flags[start..t].iter_mut().for_each(|f| *f = !value);
        }
    }
}

/// The maximal frame ranges where `flags` is set.
pub fn runs(flags: &[bool]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut t = 0;
    while t < flags.len() {
        if flags[t] {
            let start = t;
            while t < flags.len() && flags[t] {
                t += 1;
            }
            out.push(start..t);
        } else {
            t += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_are_maximal() {
        assert_eq!(runs(&[true, true, false, true, false, false, true]), vec![0..2, 3..4, 6..7]);
        assert_eq!(runs(&[false, false]), Vec::<std::ops::Range<usize>>::new());
    }

    #[test]
    fn short_gaps_and_blips_go() {
        let mut f = vec![true, true, false, true, true, true, false, false, false, true, false, false, false];
        fill_short_runs(&mut f, false, 2);
        fill_short_runs(&mut f, true, 2);
        assert_eq!(f, vec![true, true, true, true, true, true, false, false, false, false, false, false, false]);
        assert_eq!(runs(&f), vec![0..6]);
    }
}
