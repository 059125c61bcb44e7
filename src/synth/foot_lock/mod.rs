//! The last stage of generation: planted feet stay planted. The take is first levelled on
//! its stance feet (its floor may rise and sink as GloGen drifts), and its body made to
//! travel as far as its feet on the floor carry it (or, where the travel is kept, the slow
//! drift of its standing stretches taken out); then each foot's contacts are found, each is
//! split where the network's foot slid through it (the foot steps over between the pieces), each piece
//! locks the whole foot where it stood at its slowest frame with its lowest joint on the
//! floor, blended in and out over a few frames, each swing is lifted clear of the floor
//! while the other foot carries the body, and analytic two-bone IK bends the legs to reach,
//! the heel lifting rather than the leg snapping straight and the hips moving only when a
//! leg cannot; a hand pushed through the floor is lifted onto it, and a body kneeling
//! through it onto its knees. Bone lengths stay exact,
//! and a take that came with rotations gets them solved again from the new positions.

use std::ops::Range;

use anyhow::{Context, Result};
use glam::Vec3;

mod ground;

use ground::{carried_by_feet, held_still, levelled};
use crate::motion::contacts::{foot_contacts, runs, smoothed, ContactConfig, FootContacts};
use crate::motion::ik::{hip_offset, knee_forward, two_bone, two_bone_folding, MAX_STRETCH};
use super::smoothstep;
use crate::motion::{keep_hands_above_floor, keep_knees_above_floor, solve_local_poses, JointRoles, Motion, Side, Skeleton};

/// Seconds over which a lock fades in before a contact and out after it, at least and at
/// most: within that, long enough that the foot travels to or from its lock at no more than
/// [`BLEND_SPEED`] (a foot that slid far in the network's take is not snapped back). At least
/// 0.3 s: with 0.2, Bandai's mean jerk was 1.32x real, with 0.3 1.30x (and 1.28x with 0.4,
/// but its skating ratio rose from 1.41x to 1.60x real), measured with half of each fade
/// towards the lock.
const BLEND_SECONDS: (f32, f32) = (0.3, 0.8);
const BLEND_SPEED: f32 = 0.4;

/// How much of a lock's fade pulls towards the lock itself rather than fading the boundary
/// offset (see [`Plant`]). More pull plants the feet better but drags the swing back, and a
/// running stride dragged back stops looking like one. Measured on Bandai (`glocal eval
/// --suite motion` and `--suite bandai`; support-point speed median / jerk p95 over real /
/// class control 2 s after another class's seed): 0 gives 3.00 / 1.47x / 96.3%, 0.25
/// 2.69 / 1.42x / 95.6%, 0.5 2.29 / 1.43x / 94.4% (run recognised in 62% of takes against
/// 75%); with 0.2 s shortest fades, 0.75 1.68 / 1.59x and 1 0.99 / 1.78x. (A hold on the
/// foot's own motion near the boundary, as before, did much as 1 with a burst after it.)
const TOWARDS_LOCK: f32 = 0.25;

/// The farthest (metres, horizontally) a lock holds a foot from where the network put it: a
/// stance phase over which the network's foot slides farther is split into plants each
/// within this of its own lock, with [`REPLANT_SECONDS`] between them for the foot to move
/// on. A lock that held a sliding foot through the whole phase would drag the hips tens of
/// centimetres and bend the legs deep.
const MAX_SLIDE: f32 = 0.08;
const REPLANT_SECONDS: f32 = 0.3;
const REPLANT_LIFT: f32 = 0.06;

/// Degrees between a planted foot's toe-to-ankle and toe-to-hip lines below which it takes
/// none of its heel lift and above which all of it ([`upright_share`]); a flat foot under a
/// standing body reads 30-80 (94% of the lifted frames of every seed's take), 1% under 25.
const TIPTOE_ANGLES: (f32, f32) = (15.0, 30.0);

/// Degrees the network's planted foot may pitch heel-up beyond its lock before the locked
/// heel follows ([`toe_rolled`]): a standing foot's own pitch wobbles by about this much.
const ROLL_SLACK: f32 = 3.0;

/// How far (degrees) the network's planted foot turns about the vertical from its lock
/// before the lock follows it whole: the lock pivots with it by the turn less this,
/// eased in from no turn ([`beyond`], [`pivoted`]). A pivot moves the toe's tip and the
/// heel over the floor, which the support-point speed reads: with every plant pivoting and
/// 5 degrees, `all`'s Bandai classes' support speed rose from 1.45x to 1.55x real (issue
/// 35's line 1.5x), with 25 degrees to 1.48x.
const PIVOT_SLACK: f32 = 25.0;
/// A foot whose toe-to-ankle line is steeper than this share of its length horizontally (on
/// tiptoe) has no heading to follow.
const LEVEL_ENOUGH: f32 = 0.3;
/// The shortest plant (seconds) that pivots: a body turns on the spot on a standing foot,
/// and a running foot stands a few frames. With every plant pivoting, `all`'s dash's support
/// point slid at a median 35 cm/s (32 without the pivot); with plants of 0.6 s or more
/// `all`'s Bandai classes' support speed reads 1.45x real (1.47x with 0.3).
const PIVOT_SECONDS: f32 = 0.6;

/// Toe clearance (metres) at the middle of an ordinary swing (see [`lift_swings`]). On
/// Bandai, 3 cm scaled by the other lock's weight left its skating ratio at 1.13x real; 5 cm
/// by the weight cubed gave 0.96x but a mean jerk of 1.303x; 4.5 cm by the weight squared
/// gave 1.00x and 1.300x, and 5 cm by the weight squared, since long takes keep their pace
/// ([`super::pace`]), 0.95x and 1.29x (4.5 cm then: 1.01x and 1.28x).
const SWING_LIFT: f32 = 0.05;
/// The shortest swing that gets all of [`SWING_LIFT`] (seconds; a walk's swing lasts
/// 0.35-0.45 s): a shorter one, a shuffle between two plants, is lifted by its share of this
/// squared, so its toe rises and falls no faster than an ordinary swing's. With the whole
/// lift over any gap, a standing take's 0.13 s shuffle hopped its foot 5-6 cm and back in
/// four frames, its knee jerking at 10-17x the take's p95 in its first second (`all`'s
/// discussion and guide, Bandai's guide, started from their own seeds).
const FULL_LIFT_SWING_SECONDS: f32 = 0.3;
/// The shortest step over to a replant (metres, horizontally between the two plants) that
/// gets the whole [`REPLANT_LIFT`]; a shorter one is lifted by its share of it, as a person
/// shifting a foot while standing barely lifts it. A straight-legged standing body bends its
/// knee deep for every centimetre its foot rises: lifted the whole 6 cm over a 10 cm replant,
/// Bandai's and `all`'s guide moved a knee 3.3-3.8 cm in one frame (the network's own
/// knee 0.7 cm; 2.3-2.8 since). A lower lift moves the foot nearer the floor, where the
/// suite counts it as support: at 30 cm, `all`'s Bandai classes' support-point speed rose from
/// 1.488x to 1.497x real (issue 35's line 1.5x), at 20 cm to 1.495x.
const FULL_LIFT_STEP: f32 = 0.2;

/// The fraction of a leg's length over which a planted leg's reach softens (see
/// [`heel_lifted`]).
const SOFT_REACH: f32 = 0.05;

/// Half-width (frames) of each of the three moving averages that smooth the hips' shift.
const SHIFT_SMOOTH_FRAMES: usize = 3;

pub struct FootLocked {
    pub motion: Motion,
    pub contacts: FootContacts,
}

/// Whether the lock may change how far the body travels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Travel {
    /// The body travels as far as its planted feet carry it (see [`carried_by_feet`]): for a
    /// network whose stance feet slide with the body; but for the frames `kept`, whose travel
    /// stays as it is (gaps the in-betweener filled: real motion's travel, learnt).
    FromFeet { kept: Vec<Range<usize>> },
    /// The body's travel stays as it is but for a standing body's drift ([`held_still`]): a
    /// root path has laid it out, or the model's feet need no carrying.
    Kept,
}

/// The take with its feet locked (when `enabled`) and the contacts of each foot; with
/// `enabled` false the take is returned as it is, with its contacts.
pub fn foot_lock(motion: Motion, enabled: bool, travel: &Travel) -> Result<FootLocked> {
    let roles = JointRoles::new(&motion.skeleton).context("cannot lock the feet")?;
    let cfg = ContactConfig::default();
    if !enabled || motion.frames() < 2 {
        let contacts = foot_contacts(&motion, &roles, &cfg);
        return Ok(FootLocked { motion, contacts });
    }
    let (levelled, floor) = levelled(&motion, &roles, &cfg);
    let contacts = foot_contacts(&levelled, &roles, &cfg);
    let carried = match travel {
        Travel::FromFeet { kept } => carried_by_feet(&levelled, &roles, &contacts, kept),
        Travel::Kept => held_still(&levelled, &roles, &contacts),
    };
    let detected = foot_contacts(&carried, &roles, &cfg);
    let (mut positions, contacts) = locked_positions(&carried, &roles, &detected);
    keep_knees_above_floor(&mut positions, &motion.skeleton, &roles, 0.0, motion.fps);
    keep_hands_above_floor(&mut positions, &motion.skeleton, &roles, 0.0, motion.fps);
    // Back to the model's world (Human3.6M's hips near 0, its floor near -0.9 m).
    positions.iter_mut().for_each(|p| p.y += floor);
    let skeleton = motion.skeleton.clone();
    let motion = if motion.local_poses.is_some() {
        let poses = solve_local_poses(&skeleton, &positions);
        Motion::from_local_poses(skeleton, motion.fps, poses)
    } else {
        Motion::from_positions(skeleton, motion.fps, positions)
    };
    Ok(FootLocked { motion, contacts })
}

/// A foot's joints (the ankle and everything below it), in index order.
fn foot_set(skeleton: &Skeleton, ankle: usize) -> Vec<usize> {
    let mut inside = vec![false; skeleton.len()];
    inside[ankle] = true;
    for j in ankle + 1..skeleton.len() {
        inside[j] = skeleton.parents()[j].is_some_and(|p| inside[p]);
    }
    (0..skeleton.len()).filter(|&j| inside[j]).collect()
}

/// One stance phase of one foot: its frames, the foot's locked joint positions, and how the
/// lock fades in before the phase and out after it: over how many frames, and from what
/// offset (lock minus the foot's own pose at the phase's first / last frame), three
/// quarters, and towards the lock itself, a quarter ([`TOWARDS_LOCK`]). Fading the offset
/// fixed at the boundary keeps the swing's own shape, but the foot leaves the lock at the
/// network's speed; fading towards the lock leaves it at rest, but drags the swinging foot
/// back.
struct Plant {
    start: usize,
    end: usize,
    /// The stance's frame the lock keeps the foot of (its slowest).
    anchor: usize,
    foot: Vec<Vec3>,
    /// How the network's foot turns over the plant; none for a plant too short to pivot
    /// ([`PIVOT_SECONDS`]).
    pivot: Option<Pivot>,
    fade_in: Fade,
    fade_out: Fade,
    /// Frames to the next plant, where there is one.
    gap_after: Option<usize>,
    /// How far the foot steps to the next plant (metres, horizontally; 0 without one).
    step_after: f32,
    /// The next plant continues this one's contact, which the network's foot slid through:
    /// the foot steps over, lifting [`REPLANT_LIFT`] by the step's length
    /// ([`FULL_LIFT_STEP`]); after an ordinary swing's gap it is lifted by [`lift_swings`].
    replant: bool,
}

struct Fade {
    frames: usize,
    /// The lock, flat, as it is turned at the boundary frame ([`pivoted`]).
    lock: Vec<Vec3>,
    /// Lock (heel rolled) minus the foot's own pose at the boundary frame, per foot joint.
    offset: Vec<Vec3>,
}

impl Plant {
    /// Outside the phase, the fade that applies at frame `t` with its weight (easing from 1
    /// to 0 over the fade).
    fn fade(&self, t: usize) -> Option<(f32, &Fade)> {
        let (away, fade) = if t < self.start {
            (self.start - t, &self.fade_in)
        } else if t >= self.end {
            (t + 1 - self.end, &self.fade_out)
        } else {
            return None;
        };
        let w = smoothstep(1.0 - away as f32 / (fade.frames + 1) as f32);
        (w > 0.0).then_some((w, fade))
    }

    /// In the gap after the plant, the fraction of a lift at frame `t`: a sin^2 arc over the
    /// gap, so the foot leaves and lands at rest.
    fn lift_at(&self, t: usize) -> Option<f32> {
        let gap = self.gap_after.filter(|&gap| (self.end..self.end + gap).contains(&t))?;
        let x = (t + 1 - self.end) as f32 / (gap + 1) as f32;
        Some((std::f32::consts::PI * x).sin().powi(2))
    }

    /// The share of a whole lift the step after the plant gets by its length
    /// ([`FULL_LIFT_STEP`]).
    fn step_share(&self) -> f32 {
        (self.step_after / FULL_LIFT_STEP).min(1.0)
    }

    /// The lock at frame `t` of the plant, where the network's foot is `own`:
    /// [`lock_at`] by the plant's turn there.
    fn lock_at(&self, t: usize, own: &[Vec3], toe_at: Option<usize>) -> (Vec<Vec3>, Vec<Vec3>) {
        lock_at(&self.foot, own, toe_at, turn_at(self.pivot.as_ref(), self.start, t), t > self.anchor)
    }
}

/// How the network turns a planted foot on the spot.
struct Pivot {
    /// Per frame of the plant, how far (radians, about +Y) the network's foot has turned its
    /// heading since the anchor ([`heading_turns`]).
    turns: Vec<f32>,
    /// Where on the foot it turns, from the ankle (0) to the toe (1): where the network turned
    /// it ([`least_moving`]) in a plant that turns past twice [`PIVOT_SLACK`], a body turning
    /// on the spot, else the toe. A smaller turn, eased in, barely moves the lock, and the
    /// network's foot sliding as it stands says nothing of where it turns: about the point
    /// that slid least, the toes of such plants swept the floor (every plant: `all`'s Bandai
    /// classes' support speed 1.45x -> 1.48x real), and a Bandai walk's stance turned about
    /// its heel slid its planted toe 1.7 cm by toe-off (past the slack alone), where a
    /// walking foot bears on its ball.
    about: f32,
}

/// A planted foot's turn at one frame: `angle` (radians, about +Y) about the point `about`
/// of the way from its ankle to its toe.
#[derive(Clone, Copy)]
struct Turn {
    angle: f32,
    about: f32,
}

/// Where a foot turns that the network does not turn on the spot ([`Pivot::about`]).
const AT_THE_TOE: f32 = 1.0;

/// Each stance locks the foot as it stood in the stance's anchor frame, set on the floor.
fn plants(motion: &Motion, foot: &[usize], toe_at: Option<usize>, contacts: &[bool]) -> Vec<Plant> {
    let unit = motion.skeleton.meters_per_unit();
    let (least, most) = (BLEND_SECONDS.0 * motion.fps, BLEND_SECONDS.1 * motion.fps);
    let pivot_frames = (PIVOT_SECONDS * motion.fps).round() as usize;
    // A fade leaves the lock as it stands at the plant's boundary frame `t`, where the
    // network's foot has turned by `turn` since the anchor.
    let fade = |locked: &[Vec3], t: usize, turn: Turn, anchor: usize| {
        let own: Vec<Vec3> = foot.iter().map(|&j| motion.frame(t)[j]).collect();
        let (lock, stands) = lock_at(locked, &own, toe_at, turn, t > anchor);
        let offset: Vec<Vec3> = stands.iter().zip(&own).map(|(l, o)| *l - *o).collect();
        let metres = offset[0].length() * unit;
        Fade { frames: (metres / BLEND_SPEED * motion.fps).clamp(least, most).round() as usize, lock, offset }
    };
    let stances = stances(motion, foot[0], &runs(contacts));
    // A fade ends before the neighbouring stance begins, or the foot would jump there.
    let gap_before = |k: usize| if k == 0 { usize::MAX } else { stances[k].start - stances[k - 1].end };
    let gap_after = |k: usize| stances.get(k + 1).map_or(usize::MAX, |next| next.start - stances[k].end);
    (0..stances.len())
        .map(|k| {
            let Stance { start, end, anchor, replant } = stances[k];
            let frame = motion.frame(anchor);
            let lowest = foot.iter().map(|&j| frame[j].y).fold(f32::INFINITY, f32::min);
            let locked: Vec<Vec3> = foot.iter().map(|&j| frame[j] - Vec3::Y * lowest).collect();
            let pivot = toe_at.filter(|_| end - start >= pivot_frames).map(|toe| {
                let turns = heading_turns(motion, (foot[0], foot[toe]), start..end, anchor);
                let spins = turns.iter().any(|turn| turn.abs() > 2.0 * PIVOT_SLACK.to_radians());
                Pivot { about: if spins { least_moving(motion, (foot[0], foot[toe]), start..end) } else { AT_THE_TOE }, turns }
            });
            let next = (k + 1 < stances.len()).then(|| gap_after(k));
            // A lock keeps its anchor frame's foot but for its height.
            let step_after = stances.get(k + 1).map_or(0.0, |next| {
                let step = motion.frame(next.anchor)[foot[0]] - frame[foot[0]];
                glam::Vec2::new(step.x, step.z).length() * unit
            });
            let mut fade_in = fade(&locked, start, turn_at(pivot.as_ref(), start, start), anchor);
            fade_in.frames = fade_in.frames.min(gap_before(k).saturating_sub(1));
            let mut fade_out = fade(&locked, end - 1, turn_at(pivot.as_ref(), start, end - 1), anchor);
            fade_out.frames = fade_out.frames.min(gap_after(k).saturating_sub(1));
            Plant { start, end, anchor, fade_in, fade_out, foot: locked, pivot, gap_after: next, step_after, replant }
        })
        .collect()
}

/// One plant of a foot: frames `[start, end)`, locked where the foot stood at `anchor`;
/// `replant` when the next plant continues the same detected contact.
#[derive(Clone, Copy)]
struct Stance {
    start: usize,
    end: usize,
    anchor: usize,
    replant: bool,
}

/// The detected contacts `[start, end)` as stances, split where the network's foot (joint
/// `ankle`) slides farther than [`MAX_SLIDE`]: each stance grows from its slowest frame while
/// the foot stays within reach of where it stood there, and what is left either side,
/// [`REPLANT_SECONDS`] short, is split the same way (dropped when shorter than a contact can
/// be).
fn stances(motion: &Motion, ankle: usize, contacts: &[std::ops::Range<usize>]) -> Vec<Stance> {
    let unit = motion.skeleton.meters_per_unit();
    let flat = |t: usize| {
        let p = motion.frame(t)[ankle] * unit;
        glam::Vec2::new(p.x, p.z)
    };
    let gap = (REPLANT_SECONDS * motion.fps).round() as usize;
    let shortest = (ContactConfig::default().min_seconds * motion.fps).round().max(1.0) as usize;
    let mut out = Vec::new();
    let mut todo: Vec<(usize, usize, usize)> = contacts.iter().enumerate().map(|(k, r)| (r.start, r.end, k)).collect();
    while let Some((start, end, contact)) = todo.pop() {
        if end - start < shortest {
            continue;
        }
        let step = |t: usize| flat((t + 1).min(end - 1)).distance(flat(t.saturating_sub(1).max(start)));
        let anchor = (start..end).min_by(|&a, &b| step(a).total_cmp(&step(b))).expect("a contact has frames");
        let within = |t: usize| flat(t).distance(flat(anchor)) <= MAX_SLIDE;
        let first = (start..anchor).rev().take_while(|&t| within(t)).last().unwrap_or(anchor);
        let last = (anchor + 1..end).take_while(|&t| within(t)).last().unwrap_or(anchor) + 1;
        out.push((contact, Stance { start: first, end: last, anchor, replant: false }));
        if first > start + gap {
            todo.push((start, first - gap, contact));
        }
        if end > last + gap {
            todo.push((last + gap, end, contact));
        }
    }
    out.sort_unstable_by_key(|(_, s)| s.start);
    let same_contact: Vec<bool> = out.windows(2).map(|w| w[0].0 == w[1].0).chain([false]).collect();
    out.into_iter().zip(same_contact).map(|((_, stance), replant)| Stance { replant, ..stance }).collect()
}

/// Per leg: its joints and plants, what IK needs each frame.
struct LegLock {
    hip: usize,
    knee: usize,
    foot: Vec<usize>,
    /// Where the toe is in `foot`.
    toe_at: Option<usize>,
    plants: Vec<Plant>,
}

/// The take's positions with its feet locked, and the contacts as locked (the detected ones
/// split where the network's foot slid).
fn locked_positions(motion: &Motion, roles: &JointRoles, contacts: &FootContacts) -> (Vec<Vec3>, FootContacts) {
    let skeleton = &motion.skeleton;
    let legs: Vec<LegLock> = Side::BOTH
        .iter()
        .map(|&side| {
            let leg = roles.leg(side);
            let foot = foot_set(skeleton, leg.ankle);
            let toe_at = leg.toe.and_then(|toe| foot.iter().position(|&j| j == toe));
            let plants = plants(motion, &foot, toe_at, contacts.side(side));
            LegLock { hip: leg.hip, knee: leg.knee, foot, toe_at, plants }
        })
        .collect();
    let mut targets: Vec<Vec<FootTarget>> = (0..motion.frames()).map(|t| legs.iter().map(|leg| foot_target(skeleton, motion.frame(t), leg, t)).collect()).collect();
    lift_swings(&mut targets, &legs, SWING_LIFT / skeleton.meters_per_unit(), FULL_LIFT_SWING_SECONDS * motion.fps);
    // The hips' shift, smoothed over time (a shift that starts or stops abruptly jerks the
    // whole body), then topped up where the smoothed shift leaves a leg short.
    let raw: Vec<Vec3> = (0..motion.frames()).map(|t| hip_offset(&pulls(motion.frame(t), &legs, &targets[t], Vec3::ZERO))).collect();
    let smooth = smoothed(&widest_nearby(&raw, 3 * SHIFT_SMOOTH_FRAMES), SHIFT_SMOOTH_FRAMES);
    let facing = pelvis_facing(motion, &legs);
    let mut out = Vec::with_capacity(motion.positions().len());
    for t in 0..motion.frames() {
        let frame = motion.frame(t);
        let shift = smooth[t] + hip_offset(&pulls(frame, &legs, &targets[t], smooth[t]));
        out.extend(locked_frame(frame, &legs, &targets[t], shift, facing[t]));
    }
    let locked = |leg: &LegLock| {
        let mut flags = vec![false; motion.frames()];
        leg.plants.iter().for_each(|p| flags[p.start..p.end].iter_mut().for_each(|f| *f = true));
        flags
    };
    (out, FootContacts { left: locked(&legs[0]), right: locked(&legs[1]) })
}

/// Per frame, the horizontal direction the pelvis faces: square to the line between the hips,
/// on the side the knees and toes point to over the take (a foot alone turns too far at
/// toe-off to say; a skeleton without toes still has knees).
fn pelvis_facing(motion: &Motion, legs: &[LegLock]) -> Vec<Vec3> {
    let square: Vec<Vec3> = (0..motion.frames()).map(|t| Vec3::Y.cross(motion.frame(t)[legs[1].hip] - motion.frame(t)[legs[0].hip]).normalize_or_zero()).collect();
    let ahead = |t: usize, leg: &LegLock| {
        let f = motion.frame(t);
        let knee = f[leg.knee] - (f[leg.hip] + f[leg.foot[0]]) / 2.0;
        let toe = leg.toe_at.map_or(Vec3::ZERO, |toe| f[leg.foot[toe]] - f[leg.foot[0]]);
        square[t].dot(knee + toe)
    };
    let forward: f32 = legs.iter().map(|leg| (0..motion.frames()).map(|t| ahead(t, leg)).sum::<f32>()).sum();
    let sign = if forward < 0.0 { -1.0 } else { 1.0 };
    square.into_iter().map(|f| f * sign).collect()
}

/// Each swing between two plants lifted by up to `height` (a sin^2 arc over the swing), as
/// far as the other foot carries the body (its lock's weight, squared): the network's
/// swinging toes skim the floor (Bandai's skating ratio 1.42x real with the feet locked,
/// 1.00x with 4.5 cm of clearance), and a lift while both feet are off the floor would only
/// make a runner float. A swing shorter than `full_lift_frames` is lifted by its share of
/// them squared ([`FULL_LIFT_SWING_SECONDS`]).
fn lift_swings(targets: &mut [Vec<FootTarget>], legs: &[LegLock], height: f32, full_lift_frames: f32) {
    for (i, leg) in legs.iter().enumerate() {
        for p in leg.plants.iter().filter(|p| !p.replant) {
            let share = p.gap_after.map_or(1.0, |gap| (gap as f32 / full_lift_frames).min(1.0).powi(2));
            for (t, frame) in targets.iter_mut().enumerate().skip(p.end) {
                let Some(arc) = p.lift_at(t) else { break };
                let carried = frame[1 - i].weight.powi(2);
                let up = height * share * carried * arc;
                frame[i].joints.iter_mut().for_each(|q| q.y += up);
            }
        }
    }
}

/// What each planted leg asks of the hips (hip, ankle target, reach), hips already shifted by
/// `shift`. The ankle is the one before its heel rolled ([`FootTarget::heel_roll`]): the hips
/// go where the flat lock would take them, and the heel's roll changes only the leg's own
/// shape. Reaching for the rolled ankle, the hips rose and went on at every toe-off and the
/// leg in front lifted its heel to reach its own lock, dropping it a centimetre in one frame
/// after landing (h36m bones over the real p99.9 in 48 takes of 190 against 39, Bandai's
/// transition peaks 1.27x the real p95 against 1.19x).
fn pulls(frame: &[Vec3], legs: &[LegLock], targets: &[FootTarget], shift: Vec3) -> Vec<(Vec3, Vec3, f32)> {
    legs.iter()
        .zip(targets)
        .filter(|(_, target)| target.weight > 0.0)
        .map(|(leg, target)| (frame[leg.hip] + shift, target.joints[0] - target.heel_roll, leg_length(frame, leg) * MAX_STRETCH))
        .collect()
}

/// Each frame's shift replaced by the largest within `half` frames: smoothed afterwards, it
/// still covers (nearly) what every frame needs, so little is left for the abrupt top-up.
fn widest_nearby(shifts: &[Vec3], half: usize) -> Vec<Vec3> {
    (0..shifts.len())
        .map(|t| shifts[t.saturating_sub(half)..(t + half + 1).min(shifts.len())].iter().copied().max_by(|a, b| a.length_squared().total_cmp(&b.length_squared())).unwrap_or(Vec3::ZERO))
        .collect()
}

/// One frame: the body shifted with the hips, then two-bone IK per leg towards its foot's
/// target.
fn locked_frame(frame: &[Vec3], legs: &[LegLock], targets: &[FootTarget], shift: Vec3, facing: Vec3) -> Vec<Vec3> {
    let mut out: Vec<Vec3> = frame.iter().map(|p| *p + shift).collect();
    for (leg, FootTarget { joints: target, weight, .. }) in legs.iter().zip(targets) {
        let ankle = leg.foot[0];
        let upper = frame[leg.knee].distance(frame[leg.hip]);
        let lower = frame[ankle].distance(frame[leg.knee]);
        let own_reach = frame[leg.hip].distance(frame[ankle]);
        let foot = &heel_lifted(out[leg.hip], target, leg, (upper + lower, own_reach), *weight);
        // The knee bends towards where it was, pulled by a whole thigh's length the way a knee
        // points on this leg (forwards on a hanging leg, up on one raised in front): a knee is
        // a hinge, and the network's knee sometimes bends backwards through the straight leg;
        // following it, a shortened leg's knee would flip from front to back in one frame.
        // Every frame is solved, locked or not, so the knee never switches between the
        // network's and the solver's side.
        let pole = out[leg.knee] + knee_forward(facing, foot[0] - out[leg.hip]) * upper;
        // A folded leg's knee keeps to the network's thigh where the foot is free to give.
        let (knee, reached) = two_bone_folding(out[leg.hip], foot[0], pole, frame[leg.knee] - frame[leg.hip], (upper, lower), 1.0 - weight);
        out[leg.knee] = knee;
        // A target out of reach (or given up by a folded free leg) leaves the foot as close as
        // the leg gets, shape unchanged.
        let miss = reached - foot[0];
        for (p, &j) in foot.iter().zip(&leg.foot) {
            out[j] = *p + miss;
        }
    }
    out
}

/// A locked foot whose leg would have to straighten fully lifts its heel instead: the ankle
/// turns about the toe until the hip-to-ankle distance is the soft reach (full for a leg well
/// bent, easing towards [`SOFT_REACH`] of the leg's `length` as it straightens, but never
/// shorter than the network's own leg, `own_reach`, up to 98.75% of its length: a leg it held
/// straight stands (nearly) straight),
/// blended by the lock's `weight`. A leg held on a planted foot while the hips go on would
/// otherwise snap straight at every toe-off and the knee with it (without the lift, Bandai's
/// transition peaks are 1.86x the real p95; with it, 1.43x).
fn heel_lifted(hip: Vec3, foot: &[Vec3], leg: &LegLock, (length, own_reach): (f32, f32), weight: f32) -> Vec<Vec3> {
    let Some(toe) = leg.toe_at else { return foot.to_vec() };
    let distance = hip.distance(foot[0]);
    let (start, soft) = (length * (1.0 - SOFT_REACH), length * SOFT_REACH);
    // Not the network's leg straight to the last percent either: near full stretch the knee
    // swings far for a small change of reach, and a toe-off straightening a planted leg from
    // 97 to 99.5% of its length in two frames snapped a carried Bandai walk's knee (2.3x the
    // take's peaks elsewhere near a key; 1.07x with this).
    let own_reach = own_reach.min(length * (1.0 - SOFT_REACH / 4.0));
    if weight <= 0.0 || distance <= start.max(own_reach) {
        return foot.to_vec();
    }
    let reach = (start + soft * (1.0 - (-(distance - start) / soft).exp())).max(own_reach);
    let reach = distance - weight * upright_share(hip, foot[toe], foot[0]) * (distance - reach);
    let (ankle, _) = two_bone(hip, foot[toe], foot[0], reach, foot[toe].distance(foot[0]));
    let mut out = foot.to_vec();
    out[0] = ankle;
    out
}

/// How much of its heel lift a foot takes by how far it stands from pointing at the hip:
/// none below the first of [`TIPTOE_ANGLES`] between toe-to-ankle and toe-to-hip, all above
/// the second. A foot already on its toes along the leg barely shortens the leg by turning
/// about the toe (first order in the turn, nothing when toe, ankle and hip are in a line), so
/// the lift asks a large turn for a small change of reach, and a planted ankle jumped 3.8 cm
/// in one frame as the hips came 5 mm nearer (`all`'s bye from its seed 259, at 17 degrees).
fn upright_share(hip: Vec3, toe: Vec3, ankle: Vec3) -> f32 {
    let (least, most) = TIPTOE_ANGLES;
    let angle = (ankle - toe).angle_between(hip - toe).to_degrees();
    smoothstep((angle - least) / (most - least))
}

fn leg_length(frame: &[Vec3], leg: &LegLock) -> f32 {
    frame[leg.knee].distance(frame[leg.hip]) + frame[leg.foot[0]].distance(frame[leg.knee])
}

/// Where a leg is to put its foot in one frame.
struct FootTarget {
    /// The foot's joints, ankle first.
    joints: Vec<Vec3>,
    /// The weight of the lock: 1 inside a stance, fading to 0 outside it.
    weight: f32,
    /// How far the heel's roll ([`toe_rolled`]) moved the ankle from the lock.
    heel_roll: Vec3,
}

/// The foot's target this frame: the lock itself inside a stance phase (turned with the
/// network's foot and its heel rolled after the anchor, [`Plant::lock_at`]), else the foot's
/// own pose plus the fading offsets of the phases nearby.
fn foot_target(skeleton: &Skeleton, frame: &[Vec3], leg: &LegLock, t: usize) -> FootTarget {
    let own: Vec<Vec3> = leg.foot.iter().map(|&j| frame[j]).collect();
    let (mut foot, weight, heel_roll) = match leg.plants.iter().find(|p| (p.start..p.end).contains(&t)) {
        Some(plant) => {
            let (turned, stands) = plant.lock_at(t, &own, leg.toe_at);
            let heel_roll = stands[0] - turned[0];
            (stands, 1.0, heel_roll)
        }
        None => {
            let fades: Vec<(f32, &Fade)> = leg.plants.iter().filter_map(|p| p.fade(t)).collect();
            let pull = |i: usize, p: Vec3, fade: &Fade| fade.offset[i] * (1.0 - TOWARDS_LOCK) + (fade.lock[i] - p) * TOWARDS_LOCK;
            let shifted: Vec<Vec3> = own.iter().enumerate().map(|(i, &p)| p + fades.iter().map(|&(w, f)| pull(i, p, f) * w).sum::<Vec3>()).collect();
            let weight = fades.iter().map(|(w, _)| *w).fold(0.0, f32::max);
            let mut foot = if fades.is_empty() { own } else { rigid(skeleton, &leg.foot, &own, &shifted) };
            if let Some((arc, share)) = leg.plants.iter().filter(|p| p.replant).find_map(|p| Some((p.lift_at(t)?, p.step_share()))) {
                let up = REPLANT_LIFT / skeleton.meters_per_unit() * arc * share;
                foot.iter_mut().for_each(|p| p.y += up);
            }
            (foot, weight, Vec3::ZERO)
        }
    };
    let lowest = foot.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    if lowest < 0.0 {
        foot.iter_mut().for_each(|p| p.y -= lowest);
    }
    FootTarget { joints: foot, weight, heel_roll }
}

/// The lock `locked` at a frame of its plant where the network's foot is `own` and has turned
/// by `turn` since the anchor: turned with it ([`pivoted`]), and as it stands, its heel
/// rolled after the anchor (`rolled`, [`toe_rolled`]). The fades leave the lock as the plant's
/// frames hold it, or the foot would jump at the plant's ends.
fn lock_at(locked: &[Vec3], own: &[Vec3], toe_at: Option<usize>, turn: Turn, rolled: bool) -> (Vec<Vec3>, Vec<Vec3>) {
    let turned = pivoted(locked, toe_at, turn);
    let stands = if rolled { toe_rolled(&turned, own, toe_at) } else { turned.clone() };
    (turned, stands)
}

/// Per frame of the plant `frames`, how far (radians, about +Y) the network's foot
/// (`ankle`, `toe`) has turned its heading since `anchor`, frame by frame so that a spin
/// past half a turn keeps counting; a frame on tiptoe ([`LEVEL_ENOUGH`]) adds no turn.
fn heading_turns(motion: &Motion, (ankle, toe): (usize, usize), frames: Range<usize>, anchor: usize) -> Vec<f32> {
    let headings: Vec<Option<Vec3>> = frames
        .clone()
        .map(|t| {
            let along = motion.frame(t)[toe] - motion.frame(t)[ankle];
            let level = along.with_y(0.0);
            (level.length() > LEVEL_ENOUGH * along.length()).then(|| level.normalize())
        })
        .collect();
    // The turn from plant frame `i` to the next.
    let step = |i: usize| match (headings[i], headings[i + 1]) {
        (Some(from), Some(to)) => from.cross(to).y.atan2(from.dot(to)),
        _ => 0.0,
    };
    let anchor = anchor - frames.start;
    let mut turns = vec![0.0; frames.len()];
    for i in anchor + 1..turns.len() {
        turns[i] = turns[i - 1] + step(i - 1);
    }
    for i in (0..anchor).rev() {
        turns[i] = turns[i + 1] - step(i);
    }
    turns
}

/// A plant's turn at frame `t` (its `pivot` from frame `start`; none for a plant that does
/// not pivot).
fn turn_at(pivot: Option<&Pivot>, start: usize, t: usize) -> Turn {
    pivot.map_or(Turn { angle: 0.0, about: AT_THE_TOE }, |pivot| Turn { angle: pivot.turns[t - start], about: pivot.about })
}

/// Where along the network's foot (`ankle` at 0 to `toe` at 1) the point lies that travels
/// least over the floor in `frames`, in tenths: the point it turns about, on the ball of the
/// foot or the heel. h36m's posing from seed window 82 turns its feet 106-113 degrees on the
/// spot with the ankles travelling 12-28 cm and the toes 39-45: turned about the toe, the
/// locked ankle swept 31-35 cm, and the hips' shift with it.
fn least_moving(motion: &Motion, (ankle, toe): (usize, usize), frames: Range<usize>) -> f32 {
    let feet: Vec<(Vec3, Vec3)> = frames.map(|t| (motion.frame(t)[ankle].with_y(0.0), motion.frame(t)[toe].with_y(0.0))).collect();
    let travel = |share: f32| {
        let at = |(ankle, toe): (Vec3, Vec3)| ankle + (toe - ankle) * share;
        feet.windows(2).map(|w| at(w[1]).distance(at(w[0]))).sum::<f32>()
    };
    (0..=10).map(|k| k as f32 / 10.0).min_by(|a, b| travel(*a).total_cmp(&travel(*b))).unwrap_or(AT_THE_TOE)
}

/// The locked foot turned about the vertical through its pivot point (`turn.about`) by the
/// network's own turn since the anchor less [`PIVOT_SLACK`], eased in. Held at its anchor's
/// heading, a foot the network pivots turned all of it in the swing after (h36m's posing
/// from seed window 82 pivots a foot 113 degrees on the spot, and the foot then turned 27
/// degrees a frame, limit 17).
fn pivoted(locked: &[Vec3], toe_at: Option<usize>, turn: Turn) -> Vec<Vec3> {
    let Some(toe) = toe_at.filter(|_| turn.angle != 0.0) else { return locked.to_vec() };
    let about = glam::Quat::from_rotation_y(beyond(turn.angle.abs(), PIVOT_SLACK.to_radians()) * turn.angle.signum());
    let pivot = locked[0] + (locked[toe] - locked[0]) * turn.about;
    locked.iter().map(|p| pivot + about * (*p - pivot)).collect()
}

/// The locked foot with its heel risen about the toe as far as the network's foot (`own`)
/// rises beyond its lock, less [`ROLL_SLACK`]: a foot rolls onto its toe before it leaves
/// the floor, and held flat to the end of its contact, the leg stays straight and then
/// folds at once (h36m's locked walking thighs turned 7-8 degrees a frame after toe-off,
/// the network's own 2-4).
fn toe_rolled(locked: &[Vec3], own: &[Vec3], toe_at: Option<usize>) -> Vec<Vec3> {
    let mut out = locked.to_vec();
    let Some(toe) = toe_at else { return out };
    // A foot with its toe above its ankle rests on its heel (legs out in front on a floor
    // seat): it has no toe on the floor to roll about.
    if pitch(locked, toe) < 0.0 {
        return out;
    }
    let rise = beyond(pitch(own, toe) - pitch(locked, toe), ROLL_SLACK.to_radians());
    let heel = locked[0] - locked[toe];
    if let Some(axis) = heel.cross(Vec3::Y).try_normalize().filter(|_| rise > 0.0) {
        out[0] = locked[toe] + glam::Quat::from_axis_angle(axis, rise) * heel;
    }
    out
}

/// How far (radians) the foot's heel is above its toe: its ankle-to-toe line's pitch.
fn pitch(foot: &[Vec3], toe: usize) -> f32 {
    (foot[0] - foot[toe]).try_normalize().map_or(0.0, |d| d.y.clamp(-1.0, 1.0).asin())
}

/// How far `x` is beyond `slack`, easing in from 0 at 0 with a continuous slope.
fn beyond(x: f32, slack: f32) -> f32 {
    if x <= 0.0 {
        0.0
    } else if x < 2.0 * slack {
        x * x / (4.0 * slack)
    } else {
        x - slack
    }
}

/// `mixed` with the foot's bone lengths (those of `from`) restored down the chain from the
/// ankle.
fn rigid(skeleton: &Skeleton, joints: &[usize], from: &[Vec3], mixed: &[Vec3]) -> Vec<Vec3> {
    let mut out = mixed.to_vec();
    for i in 1..joints.len() {
        let parent = skeleton.parents()[joints[i]].and_then(|p| joints.iter().position(|&j| j == p)).expect("a foot joint's parent is in the foot");
        let length = from[i].distance(from[parent]);
        let direction = (mixed[i] - mixed[parent]).try_normalize().unwrap_or((from[i] - from[parent]).normalize_or_zero());
        out[i] = out[parent] + direction * length;
    }
    out
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    /// A foot (ankle and toe, 15 cm apart, flat) spinning 10 degrees a frame about the
    /// vertical for 30 frames: its turn since the first frame adds up past half a turn to
    /// 290 degrees, as the anchor's heading against each frame's alone would not (it flips
    /// sign at 180).
    #[test]
    fn a_spinning_foot_counts_its_turn_past_half_a_turn() {
        let skeleton = Skeleton::new(vec!["ankle".into(), "toe".into()], vec![None, Some(0)], vec![Vec3::ZERO, Vec3::new(0.0, -0.05, 0.15)], 1.0).unwrap();
        let frames = 30;
        let positions: Vec<Vec3> = (0..frames).flat_map(|t| [Vec3::ZERO, glam::Quat::from_rotation_y((10.0 * t as f32).to_radians()) * Vec3::new(0.0, -0.05, 0.15)]).collect();
        let motion = Motion::from_positions(Arc::new(skeleton), 30.0, positions);
        let turns = heading_turns(&motion, (0, 1), 0..frames, 0);
        for (t, turn) in turns.iter().enumerate() {
            assert!((turn.to_degrees() - 10.0 * t as f32).abs() < 0.01, "frame {t}: {} degrees", turn.to_degrees());
        }
    }

    /// A foot (ankle and toe, 15 cm apart) turning 87 degrees on the spot about its ankle, its
    /// toe and a point between: the point found is the one it turned about, and the lock
    /// pivoted by it keeps that point where it stood.
    #[test]
    fn a_foot_turns_about_the_point_that_stays() {
        let skeleton = Arc::new(Skeleton::new(vec!["ankle".into(), "toe".into()], vec![None, Some(0)], vec![Vec3::ZERO, Vec3::new(0.0, -0.05, 0.15)], 1.0).unwrap());
        let toe = Vec3::new(0.0, -0.05, 0.15);
        for (about, expected) in [(Vec3::ZERO, 0.0), (toe.with_y(0.0), 1.0), (toe.with_y(0.0) * 0.6, 0.6)] {
            let positions: Vec<Vec3> = (0..30)
                .flat_map(|t| {
                    let turn = glam::Quat::from_rotation_y((3.0 * t as f32).to_radians());
                    [about + turn * (Vec3::ZERO - about), about + turn * (toe - about)]
                })
                .collect();
            let motion = Motion::from_positions(skeleton.clone(), 30.0, positions);
            let found = least_moving(&motion, (0, 1), 0..30);
            assert_eq!(found, expected, "turning about {about}");
            let locked = [Vec3::ZERO, toe];
            let turned = pivoted(&locked, Some(1), Turn { angle: 1.5, about: found });
            let stays = |foot: &[Vec3]| (foot[0] + (foot[1] - foot[0]) * found).with_y(0.0);
            assert!(stays(&turned).distance(stays(&locked)) < 1e-5, "the lock turned about another point than {found}");
        }
    }
}
