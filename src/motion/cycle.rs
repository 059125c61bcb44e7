//! A looping cycle cut from a longer take, for a game engine's locomotion and gesture loops:
//! the two frames of the take that best continue each other (pose and velocity, with the
//! body's travel and turning taken out) bound the cycle, its turning is straightened out, and
//! what is left of the mismatch is spread smoothly over the cycle, so that the cycle played
//! again from where its travel left it is continuous in pose and velocity across the wrap.

use glam::{Quat, Vec3};

use super::roles::{JointRoles, RolesError};
use super::root_motion::facing;
use super::solve::solve_local_poses;
use super::take::Motion;
use super::unwrap_angle;

/// Where the cycle lies in the take it was cut from, and what one play of it does.
#[derive(Clone, Debug, PartialEq)]
pub struct Cycle {
    /// The take's frame the cycle starts at; the cycle is `frames` frames from there.
    pub start: usize,
    pub frames: usize,
    /// The hips' travel over one cycle on the ground, in the skeleton's units (x, 0, z): the
    /// next play starts from the first frame moved by it.
    pub travel: Vec3,
    /// The turn the take made over the cycle's frames, taken out (radians, about the vertical).
    pub straightened: f32,
}

impl Cycle {
    /// One line for the user: the loop's length, its travel per play in metres and the turn
    /// taken out.
    pub fn summary(&self, fps: f32, metres_per_unit: f32) -> String {
        let metres = self.travel * metres_per_unit;
        format!(
            "loop of {} frames ({:.2} s) from frame {} of the generated motion; travels {:.2} m per cycle (x {:.2}, z {:.2}); {:.1} degrees of turning straightened out",
            self.frames,
            self.frames as f32 / fps,
            self.start,
            metres.length(),
            metres.x,
            metres.z,
            self.straightened.to_degrees()
        )
    }
}

/// The frames a cycle may start at and the lengths it may have.
#[derive(Clone, Debug, PartialEq)]
pub struct CycleSearch {
    pub starts: std::ops::Range<usize>,
    pub lengths: std::ops::RangeInclusive<usize>,
}

/// How much a velocity mismatch counts against a pose mismatch: velocities are per frame, and
/// a mismatch of v per frame shows as v * this over the frames around the wrap.
const VELOCITY_WEIGHT_FRAMES: f32 = 6.0;
/// And an acceleration mismatch of a per frame squared shows as about a * 6^2 / 2 over them.
const ACCELERATION_WEIGHT_FRAMES2: f32 = 18.0;

/// Cuts the best cycle `search` allows out of `motion` and closes it. The motion needs a frame
/// after the longest cycle from the last start (for the velocity at the wrap).
///
/// The pairs of ends that continue each other best (pose, velocity and acceleration) are
/// closed, and of those the one whose wrap moves like the rest of its cycle (its speed around
/// the wrap within [`SPEED_TOLERANCE`] of the cycle's median) with the smallest change of
/// velocity at the wrap is kept: a wrap in a pause or a burst of the motion shows.
pub fn closed_cycle(motion: &Motion, search: &CycleSearch) -> Result<(Motion, Cycle), CycleError> {
    let roles = JointRoles::new(&motion.skeleton)?;
    let last_needed = search.starts.end.saturating_sub(1) + search.lengths.end() + 1;
    if search.starts.is_empty() || search.starts.start == 0 || *search.lengths.start() < 2 || last_needed >= motion.frames() {
        return Err(CycleError::TooShort { frames: motion.frames(), needed: last_needed + 1 });
    }
    let track = GroundTrack::new(motion, &roles);
    let half = (motion.fps * SPEED_WINDOW_SECONDS).round().max(1.0) as usize;
    // Smooth wraps first, by their jump; failing any, the wrap nearest the cycle's speed.
    // Each candidate is ranked once, as it is closed.
    let rank = |c: &Closed| {
        let off_speed = (c.speed_ratio(half) - 1.0).abs();
        if off_speed <= SPEED_TOLERANCE { (0, c.jump()) } else { (1, off_speed) }
    };
    let (_, best) = closest_pairs(motion, &track, search)
        .into_iter()
        .map(|(a, n)| {
            let closed = Closed::new(motion, &track, a, n);
            (rank(&closed), closed)
        })
        .min_by(|(x, _), (y, _)| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)))
        .expect("the search has at least one pair");
    let cycle = Cycle { start: best.start, frames: best.frames, travel: best.travel, straightened: best.turn };
    Ok((best.cycle, cycle))
}

/// Seconds either side of the wrap over which its speed is taken.
const SPEED_WINDOW_SECONDS: f32 = 0.2;
/// How far from the cycle's median speed the speed around its wrap may be.
const SPEED_TOLERANCE: f32 = 0.15;
/// How many of the best-continuing pairs of ends are closed and compared: over a take's 4 s
/// of starts, 256 crowded into one stretch and left none with a wrap at its cycle's speed
/// (Bandai's bow at 0.68x).
const CANDIDATES: usize = 512;

/// A candidate cycle, straightened, closed and on the skeleton's bone lengths, with the two
/// frames a replay continues it with.
struct Closed {
    start: usize,
    frames: usize,
    joints: usize,
    cycle: Motion,
    /// The cycle's first two frames moved by its travel.
    replayed: Vec<Vec3>,
    travel: Vec3,
    turn: f32,
}

impl Closed {
    /// The cycle of `frames` from `start`, closed and projected onto the skeleton's bone
    /// lengths; the two frames after it are its first two moved by its travel, as a replay
    /// shows them.
    fn new(motion: &Motion, track: &GroundTrack, start: usize, frames: usize) -> Self {
        let span: Vec<usize> = (start..=start + frames + 1).collect();
        let (mut positions, turn) = straightened(motion, track, &span);
        let joints = motion.joints();
        let travel = ground(positions[frames * joints]) - ground(positions[0]);
        close_wrap(&mut positions, joints, frames, travel);
        positions.truncate(frames * joints);
        let poses = solve_local_poses(&motion.skeleton, &positions);
        let cycle = Motion::from_local_poses(motion.skeleton.clone(), motion.fps, poses);
        let replayed = cycle.positions()[..2 * joints].iter().map(|&p| p + travel).collect();
        Self { start, frames, joints, cycle, replayed, travel, turn }
    }

    fn frame(&self, t: usize) -> &[Vec3] {
        match t.checked_sub(self.frames) {
            None => self.cycle.frame(t),
            Some(k) => &self.replayed[k * self.joints..(k + 1) * self.joints],
        }
    }

    /// Mean over joints of the distance from frame `t` to the next.
    fn step(&self, t: usize) -> f32 {
        self.frame(t).iter().zip(self.frame(t + 1)).map(|(p, q)| p.distance(*q)).sum::<f32>() / self.joints as f32
    }

    /// The speed over `half` frames either side of the wrap over the cycle's typical speed:
    /// the median of the same measure at every frame of the cycle played round (a gesture's
    /// bursts would pull a mean up and make every rest look like a pause).
    fn speed_ratio(&self, half: usize) -> f32 {
        let n = self.frames;
        let half = half.min(n / 2);
        // Steps round the cycle: the last one is the wrap's, into the replayed first frame.
        let steps: Vec<f32> = (0..n).map(|t| self.step(t)).collect();
        let around = |t: usize| (0..2 * half).map(|k| steps[(t + n - half + k) % n]).sum::<f32>() / (2 * half) as f32;
        let mut typical: Vec<f32> = (0..n).map(around).collect();
        let wrap = typical[0];
        typical.sort_by(f32::total_cmp);
        wrap / typical[n / 2].max(f32::MIN_POSITIVE)
    }

    /// The larger change of velocity at the wrap's two frames, mean over joints.
    fn jump(&self) -> f32 {
        let change = |t: usize| -> f32 {
            let (p, q, r) = (self.frame(t - 1), self.frame(t), self.frame(t + 1));
            (0..self.joints).map(|j| (r[j] - q[j] - (q[j] - p[j])).length()).sum::<f32>() / self.joints as f32
        };
        change(self.frames - 1).max(change(self.frames))
    }
}

#[derive(Debug, thiserror::Error)]
pub enum CycleError {
    #[error(transparent)]
    Roles(#[from] RolesError),
    #[error("a cycle needs {needed} frames of motion to choose from, the take has {frames}")]
    TooShort { frames: usize, needed: usize },
}

fn ground(p: Vec3) -> Vec3 {
    Vec3::new(p.x, 0.0, p.z)
}

/// Per frame, the ground point under the hips and the heading (unwrapped, so a turn of more
/// than half a circle over the take stays one turn).
struct GroundTrack {
    points: Vec<Vec3>,
    headings: Vec<f32>,
}

impl GroundTrack {
    fn new(motion: &Motion, roles: &JointRoles) -> Self {
        let (left, right, root) = (roles.left.hip, roles.right.hip, roles.body_root);
        let mut headings: Vec<f32> = Vec::with_capacity(motion.frames());
        let mut points = Vec::with_capacity(motion.frames());
        for t in 0..motion.frames() {
            let frame = motion.frame(t);
            let h = facing(frame, left, right);
            headings.push(headings.last().map_or(h, |&previous| unwrap_angle(h, previous)));
            points.push(ground(frame[root]));
        }
        Self { points, headings }
    }

    /// Frame `t`'s joints seen from frame `from`'s ground point and heading.
    fn seen_from(&self, motion: &Motion, from: usize, t: usize) -> impl Iterator<Item = Vec3> + '_ {
        let to_local = Quat::from_rotation_y(-self.headings[from]);
        let origin = self.points[from];
        motion.frame(t).to_vec().into_iter().map(move |p| to_local * (p - origin))
    }
}

/// The [`CANDIDATES`] starts and lengths whose wrap mismatches least: frame `a + n` against
/// frame `a`, in pose and in the steps before and after each, every frame seen from its own
/// ground point and heading.
fn closest_pairs(motion: &Motion, track: &GroundTrack, search: &CycleSearch) -> Vec<(usize, usize)> {
    let last = search.starts.end - 1 + search.lengths.end();
    let seen = |t: usize| -> [Vec<Vec3>; 3] { [t - 1, t, t + 1].map(|u| track.seen_from(motion, t, u).collect()) };
    let frames: Vec<[Vec<Vec3>; 3]> = (search.starts.start..=last).map(seen).collect();
    let mismatch = |a: usize, b: usize| -> f32 {
        let ([pa, a0, na], [pb, b0, nb]) = (&frames[a], &frames[b]);
        let mut cost = 0.0;
        for j in 0..a0.len() {
            let (step_a, step_b) = (na[j] - a0[j], nb[j] - b0[j]);
            let (turn_a, turn_b) = (step_a - (a0[j] - pa[j]), step_b - (b0[j] - pb[j]));
            cost += a0[j].distance_squared(b0[j]) + (VELOCITY_WEIGHT_FRAMES * step_a.distance(step_b)).powi(2) + (ACCELERATION_WEIGHT_FRAMES2 * turn_a.distance(turn_b)).powi(2);
        }
        cost
    };
    let offset = search.starts.start;
    let mut pairs: Vec<(f32, usize, usize)> = search.starts.clone().flat_map(|a| search.lengths.clone().map(move |n| (a, n))).map(|(a, n)| (mismatch(a - offset, a + n - offset), a, n)).collect();
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
    pairs.into_iter().take(CANDIDATES).map(|(_, a, n)| (a, n)).collect()
}

/// The frames `span` with the take's turn over the cycle (its first to its last-but-one frame)
/// taken out evenly, frame by frame: each frame's body and its step over the ground turn back
/// by the share of the turn made so far. Returns the positions and the turn.
fn straightened(motion: &Motion, track: &GroundTrack, span: &[usize]) -> (Vec<Vec3>, f32) {
    let (first, cycle) = (span[0], span.len() - 2);
    let turn = track.headings[first + cycle] - track.headings[first];
    let mut positions = Vec::with_capacity(span.len() * motion.joints());
    let mut point = track.points[first];
    for (i, &t) in span.iter().enumerate() {
        let back = Quat::from_rotation_y(-turn * i as f32 / cycle as f32);
        if i > 0 {
            point += back * (track.points[t] - track.points[t - 1]);
        }
        positions.extend(motion.frame(t).iter().map(|&p| point + back * (p - track.points[t])));
    }
    (positions, turn)
}

/// Spreads the wrap's mismatch over the cycle's `frames` (plus the one frame after it): the
/// frame after the cycle becomes the first frame moved by `travel`, and the step into it the
/// first frame's step, by a correction that is 0 at the first frame, rises smoothly, and
/// splits the step mismatch evenly between the cycle's two ends. The rise is u - sin(2 pi u)
/// / 2 pi: flat at both ends and rising by exactly 1 per cycle, so its first step and its
/// step past the end are the same and add nothing to the wrap's step.
fn close_wrap(positions: &mut [Vec3], joints: usize, frames: usize, travel: Vec3) {
    let at = |positions: &[Vec3], t: usize, j: usize| positions[t * joints + j];
    let offsets: Vec<(Vec3, Vec3)> = (0..joints)
        .map(|j| {
            let pose = at(positions, 0, j) + travel - at(positions, frames, j);
            let step = (at(positions, 1, j) - at(positions, 0, j)) - (at(positions, frames + 1, j) - at(positions, frames, j));
            (pose, step)
        })
        .collect();
    let n = frames as f32;
    for t in 0..=frames + 1 {
        let u = t as f32 / n;
        let ramp = u - (std::f32::consts::TAU * u).sin() / std::f32::consts::TAU;
        let bow = n * (u * u - u) / 2.0;
        for (j, (pose, step)) in offsets.iter().enumerate() {
            positions[t * joints + j] += *pose * ramp + *step * bow;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wrap_continues_pose_and_step() {
        // One joint drifting on a curve: after closing, frame `frames` is frame 0 moved by the
        // travel, and the step into it is the first step.
        let joints = 1;
        let frames = 20;
        let mut positions: Vec<Vec3> = (0..=frames + 1).map(|t| Vec3::new(t as f32 * 0.1, (t as f32 * 0.3).sin(), 0.0)).collect();
        let travel = Vec3::new(2.0, 0.0, 0.0);
        close_wrap(&mut positions, joints, frames, travel);
        assert!((positions[frames] - (positions[0] + travel)).length() < 1e-5);
        let first_step = positions[1] - positions[0];
        let wrap_step = positions[frames + 1] - positions[frames];
        assert!((first_step - wrap_step).length() < 1e-5, "{first_step} {wrap_step}");
    }
}
