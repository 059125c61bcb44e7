//! The last stage of generation: planted feet stay planted. The take is first levelled on
//! its stance feet (its floor may rise and sink as GloGen drifts), then each foot's contacts
//! are found, each stance phase locks the whole foot where it stood mid-phase with its lowest
//! joint on the floor, blended in and out over a few frames, and analytic two-bone IK bends
//! the legs to reach, the hips moving only when a leg cannot. Bone lengths stay exact, and a
//! take that came with rotations gets them solved again from the new positions.

use anyhow::{Context, Result};
use glam::Vec3;

use crate::motion::contacts::{foot_contacts, local_floor, lowest_foot_heights, runs, ContactConfig, FootContacts};
use crate::motion::ik::{hip_offset, two_bone, MAX_STRETCH};
use crate::motion::{solve_local_poses, JointRoles, Motion, Side, Skeleton};

/// Seconds over which a lock fades in before a contact and out after it, at least and at
/// most: within that, long enough that the foot travels to or from its lock at no more than
/// [`BLEND_SPEED`] (a foot that slid far in the network's take is not snapped back).
const BLEND_SECONDS: (f32, f32) = (0.2, 0.8);
const BLEND_SPEED: f32 = 0.4;

/// Half-width (frames) of each of the three moving averages that smooth the hips' shift.
const SHIFT_SMOOTH_FRAMES: usize = 3;

/// About the half-width (seconds) of the smoothing of the stance-foot floor before the take is
/// levelled on it: the local floor is a staircase, the take should not jump.
const LEVEL_SMOOTH_SECONDS: f32 = 0.5;

pub struct FootLocked {
    pub motion: Motion,
    pub contacts: FootContacts,
}

/// The take with its feet locked (when `enabled`) and the contacts of each foot; with
/// `enabled` false the take is returned as it is, with its contacts.
pub fn foot_lock(motion: Motion, enabled: bool) -> Result<FootLocked> {
    let roles = JointRoles::new(&motion.skeleton).context("cannot lock the feet")?;
    let cfg = ContactConfig::default();
    if !enabled || motion.frames() < 2 {
        let contacts = foot_contacts(&motion, &roles, &cfg);
        return Ok(FootLocked { motion, contacts });
    }
    let (levelled, floor) = levelled(&motion, &roles, &cfg);
    let contacts = foot_contacts(&levelled, &roles, &cfg);
    let mut positions = locked_positions(&levelled, &roles, &contacts);
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

/// The take moved up or down per frame so the floor under its stance feet is at height 0,
/// and the mean height of that floor before.
fn levelled(motion: &Motion, roles: &JointRoles, cfg: &ContactConfig) -> (Motion, f32) {
    let half = (cfg.floor_window * motion.fps).round() as usize;
    let floor = smoothed(&local_floor(&lowest_foot_heights(motion, roles), half), (LEVEL_SMOOTH_SECONDS * motion.fps / 2.0).round() as usize);
    let j = motion.joints();
    let mut positions = motion.positions().to_vec();
    for (frame, lift) in positions.chunks_exact_mut(j).zip(&floor) {
        frame.iter_mut().for_each(|p| p.y -= lift);
    }
    let mean = floor.iter().sum::<f32>() / floor.len().max(1) as f32;
    (Motion::from_positions(motion.skeleton.clone(), motion.fps, positions), mean)
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
/// offset (lock minus the foot's own pose at the phase's first / last frame). Fading an
/// offset fixed at the boundary keeps the swing's own shape; fading towards the lock itself
/// would drag the swinging foot back. Near the boundary the foot's own motion is also held
/// back (a faster fade towards its own boundary pose), so it leaves the lock at no speed.
struct Plant {
    start: usize,
    end: usize,
    foot: Vec<Vec3>,
    fade_in: Fade,
    fade_out: Fade,
}

struct Fade {
    frames: usize,
    /// Lock minus the foot's own pose at the boundary frame, per foot joint.
    offset: Vec<Vec3>,
    /// The foot's own pose at the boundary frame.
    own: Vec<Vec3>,
}

impl Plant {
    /// Outside the phase, the fade that applies at frame `t` with its two weights: of the
    /// offset (easing from 1 to 0 over the fade) and of the hold on the foot's own motion
    /// (over the first half of it).
    fn fade(&self, t: usize) -> Option<(f32, f32, &Fade)> {
        let (away, fade) = if t < self.start {
            (self.start - t, &self.fade_in)
        } else if t >= self.end {
            (t + 1 - self.end, &self.fade_out)
        } else {
            return None;
        };
        let ease = |frames: usize| {
            let x = (1.0 - away as f32 / (frames + 1) as f32).max(0.0);
            x * x * (3.0 - 2.0 * x)
        };
        let w = ease(fade.frames);
        (w > 0.0).then(|| (w, ease(fade.frames / 2), fade))
    }
}

/// Each phase locks the foot as it stood in the phase's middle frame, set on the floor.
fn plants(motion: &Motion, foot: &[usize], contacts: &[bool]) -> Vec<Plant> {
    let unit = motion.skeleton.meters_per_unit();
    let (least, most) = (BLEND_SECONDS.0 * motion.fps, BLEND_SECONDS.1 * motion.fps);
    let fade = |locked: &[Vec3], t: usize| {
        let own: Vec<Vec3> = foot.iter().map(|&j| motion.frame(t)[j]).collect();
        let offset: Vec<Vec3> = locked.iter().zip(&own).map(|(l, o)| *l - *o).collect();
        let metres = offset[0].length() * unit;
        Fade { frames: (metres / BLEND_SPEED * motion.fps).clamp(least, most).round() as usize, offset, own }
    };
    let phases = runs(contacts);
    // A fade ends before the neighbouring phase begins, or the foot would jump there.
    let gap_before = |k: usize| if k == 0 { usize::MAX } else { phases[k].0 - phases[k - 1].1 };
    let gap_after = |k: usize| phases.get(k + 1).map_or(usize::MAX, |next| next.0 - phases[k].1);
    (0..phases.len())
        .map(|k| {
            let (start, end) = phases[k];
            let frame = motion.frame((start + end - 1) / 2);
            let lowest = foot.iter().map(|&j| frame[j].y).fold(f32::INFINITY, f32::min);
            let locked: Vec<Vec3> = foot.iter().map(|&j| frame[j] - Vec3::Y * lowest).collect();
            let mut fade_in = fade(&locked, start);
            fade_in.frames = fade_in.frames.min(gap_before(k).saturating_sub(1));
            let mut fade_out = fade(&locked, end - 1);
            fade_out.frames = fade_out.frames.min(gap_after(k).saturating_sub(1));
            Plant { start, end, fade_in, fade_out, foot: locked }
        })
        .collect()
}

/// Per leg: its joints and plants, what IK needs each frame.
struct LegLock {
    hip: usize,
    knee: usize,
    toe: Option<usize>,
    foot: Vec<usize>,
    plants: Vec<Plant>,
}

fn locked_positions(motion: &Motion, roles: &JointRoles, contacts: &FootContacts) -> Vec<Vec3> {
    let skeleton = &motion.skeleton;
    let legs: Vec<LegLock> = Side::BOTH
        .iter()
        .map(|&side| {
            let leg = roles.leg(side);
            let foot = foot_set(skeleton, leg.ankle);
            let plants = plants(motion, &foot, contacts.side(side));
            LegLock { hip: leg.hip, knee: leg.knee, toe: leg.toe, foot, plants }
        })
        .collect();
    let targets: Vec<Vec<(Vec<Vec3>, f32)>> = (0..motion.frames()).map(|t| legs.iter().map(|leg| foot_target(skeleton, motion.frame(t), leg, t)).collect()).collect();
    // The hips' shift, smoothed over time (a shift that starts or stops abruptly jerks the
    // whole body), then topped up where the smoothed shift leaves a leg short.
    let raw: Vec<Vec3> = (0..motion.frames()).map(|t| hip_offset(&pulls(motion.frame(t), &legs, &targets[t], Vec3::ZERO))).collect();
    let smooth = smoothed(&widest_nearby(&raw, 3 * SHIFT_SMOOTH_FRAMES), SHIFT_SMOOTH_FRAMES);
    let mut out = Vec::with_capacity(motion.positions().len());
    for t in 0..motion.frames() {
        let frame = motion.frame(t);
        let shift = smooth[t] + hip_offset(&pulls(frame, &legs, &targets[t], smooth[t]));
        out.extend(locked_frame(frame, &legs, &targets[t], shift));
    }
    out
}

/// What each planted leg asks of the hips (hip, ankle target, reach), hips already shifted by `shift`.
fn pulls(frame: &[Vec3], legs: &[LegLock], targets: &[(Vec<Vec3>, f32)], shift: Vec3) -> Vec<(Vec3, Vec3, f32)> {
    legs.iter()
        .zip(targets)
        .filter(|(_, (_, w))| *w > 0.0)
        .map(|(leg, (foot, _))| (frame[leg.hip] + shift, foot[0], leg_length(frame, leg) * MAX_STRETCH))
        .collect()
}

/// Each frame's shift replaced by the largest within `half` frames: smoothed afterwards, it
/// still covers (nearly) what every frame needs, so little is left for the abrupt top-up.
fn widest_nearby(shifts: &[Vec3], half: usize) -> Vec<Vec3> {
    (0..shifts.len())
        .map(|t| shifts[t.saturating_sub(half)..(t + half + 1).min(shifts.len())].iter().copied().max_by(|a, b| a.length_squared().total_cmp(&b.length_squared())).unwrap_or(Vec3::ZERO))
        .collect()
}

/// Three passes of a moving average `2 * half + 1` wide (close to a Gaussian): a single box
/// leaves corners in the velocity, which show as jerk.
fn smoothed<T>(values: &[T], half: usize) -> Vec<T>
where
    T: Copy + std::iter::Sum<T> + std::ops::Div<f32, Output = T>,
{
    let pass = |v: &[T]| -> Vec<T> {
        (0..v.len())
            .map(|t| {
                let window = &v[t.saturating_sub(half)..(t + half + 1).min(v.len())];
                window.iter().copied().sum::<T>() / window.len() as f32
            })
            .collect()
    };
    pass(&pass(&pass(values)))
}

/// One frame: the body shifted with the hips, then two-bone IK per leg towards its foot's
/// target.
fn locked_frame(frame: &[Vec3], legs: &[LegLock], targets: &[(Vec<Vec3>, f32)], shift: Vec3) -> Vec<Vec3> {
    let mut out: Vec<Vec3> = frame.iter().map(|p| *p + shift).collect();
    for (leg, (foot, _)) in legs.iter().zip(targets) {
        let ankle = leg.foot[0];
        let moved = shift != Vec3::ZERO || foot.iter().zip(&leg.foot).any(|(p, &j)| *p != frame[j]);
        if !moved {
            continue;
        }
        let upper = frame[leg.knee].distance(frame[leg.hip]);
        let lower = frame[ankle].distance(frame[leg.knee]);
        // The knee bends towards where it was, and forwards over the toes: a leg the network
        // held nearly straight gives its knee no side of its own, and it would flip.
        let forward = leg.toe.map_or(Vec3::ZERO, |toe| (frame[toe] - frame[ankle]).normalize_or_zero());
        let pole = out[leg.knee] + forward * (0.2 * upper);
        let (knee, reached) = two_bone(out[leg.hip], foot[0], pole, upper, lower);
        out[leg.knee] = knee;
        // A target out of reach leaves the foot as close as the leg gets, shape unchanged.
        let miss = reached - foot[0];
        for (p, &j) in foot.iter().zip(&leg.foot) {
            out[j] = *p + miss;
        }
    }
    out
}

fn leg_length(frame: &[Vec3], leg: &LegLock) -> f32 {
    frame[leg.knee].distance(frame[leg.hip]) + frame[leg.foot[0]].distance(frame[leg.knee])
}

/// The foot's joint positions this frame (ankle first) and the weight of its lock: the lock
/// itself inside a stance phase, else the foot's own pose plus the fading offsets of the
/// phases nearby.
fn foot_target(skeleton: &Skeleton, frame: &[Vec3], leg: &LegLock, t: usize) -> (Vec<Vec3>, f32) {
    let own: Vec<Vec3> = leg.foot.iter().map(|&j| frame[j]).collect();
    let (mut foot, weight) = match leg.plants.iter().find(|p| (p.start..p.end).contains(&t)) {
        Some(plant) => (plant.foot.clone(), 1.0),
        None => {
            let fades: Vec<(f32, f32, &Fade)> = leg.plants.iter().filter_map(|p| p.fade(t)).collect();
            let shifted: Vec<Vec3> =
                own.iter().enumerate().map(|(i, p)| *p + fades.iter().map(|(w, hold, f)| f.offset[i] * *w + (f.own[i] - *p) * *hold).sum::<Vec3>()).collect();
            let weight = fades.iter().map(|(w, _, _)| *w).fold(0.0, f32::max);
            (if fades.is_empty() { own } else { rigid(skeleton, &leg.foot, &own, &shifted) }, weight)
        }
    };
    let lowest = foot.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    if lowest < 0.0 {
        foot.iter_mut().for_each(|p| p.y -= lowest);
    }
    (foot, weight)
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
