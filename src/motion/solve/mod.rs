//! Joint rotations from joint positions (inverse kinematics per frame, no optimisation).
//!
//! Every joint's world rotation is chosen so that its children's *rest* offsets point at where
//! the children actually are:
//! - no usable child (a leaf, or only zero-length bones): the parent's world rotation (local
//!   identity);
//! - one child: the minimal rotation (swing) taking the rest direction, as the parent's world
//!   rotation carries it, onto the actual direction, applied on top of the parent's rotation,
//!   so the bone's twist follows the parent;
//! - several children whose rest directions span a plane (hips, chest): the rotation that best
//!   maps the rest child directions onto the actual ones in the least-squares sense (unit
//!   vectors, equal weights), by Horn's quaternion method: the eigenvector of the largest
//!   eigenvalue of a symmetric 4x4 matrix, found with Jacobi rotations in f64;
//! - several children along one line (rest or actual): treated as one child along their mean
//!   direction.
//!
//! A child on a near-zero bone that turns a chain of its own (Human3.6M's `Spine`, at the hips,
//! whose turn bends the back against the pelvis) does not pull on its parent's fit: the
//! parent fits its other children, and only the turn they leave open (the pelvis's tilt about
//! the line of the hips) is taken from where that chain leads ([`fit_leaning`]); the short
//! joint then turns its chain exactly. So a bent back and the hip sockets are both where the
//! input has them.
//!
//! A joint whose only rotation places end sites (two or more leaf children: a Human3.6M hand,
//! its end and its thumb) that the input does not keep at their rest angles (a network's
//! output; motion capture keeps them, [`keeps_shape`]) turns at most
//! [`MAX_HAND_TURN_PER_FRAME`] from one frame to the next ([`limit_turns`]): the network sometimes bends such a hand 140 degrees back and spins its
//! thumb once round in five frames, and the fit of two end sites nearly opposite each other
//! swings about their bisector, so a hand end turned 79 degrees in one frame.
//!
//! A bone the input collapses to under half its rest length while it snaps round is bridged
//! first ([`bridge_collapsed_bones`]), and a forearm folded nearly shut above such a hand
//! carries its twist from frame to frame ([`carry_twist_through_folds`]): neither the
//! collapsed bone's direction nor the swing's axis at a full fold says anything.
//!
//! The root's translation is its position; every other translation is its rest offset, so the
//! result has the skeleton's rest bone lengths whatever the input's (a bone-length projection).
//! Directions are taken from the input positions (not from the rebuilt ones), so errors do not
//! accumulate down the chains; only bone-length differences do. Always solved against the rest
//! pose, never against another frame, so frames are independent (but for the limited turn of
//! an end-site joint, which follows the frame before).

use std::ops::Range;

use glam::{DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;

mod horn;

use horn::horn;
use super::contacts::runs;
use super::{LocalPose, Skeleton, SHORT_BONE_FRACTION};

/// Local poses whose forward kinematics reproduce `positions` (frame-major, `frames * joints`
/// world positions; a trailing partial frame is ignored) as closely as rest bone lengths allow.
pub fn solve_local_poses(skeleton: &Skeleton, positions: &[Vec3]) -> Vec<LocalPose> {
    let n = skeleton.len();
    if n == 0 {
        return Vec::new();
    }
    let scale = skeleton.offsets().iter().map(|o| o.length()).fold(0.0f32, f32::max).max(f32::MIN_POSITIVE);
    let eps = 1e-6 * scale;
    // Each joint's children with a usable rest bone, and that bone's rest direction: the same
    // for every frame.
    let mut children: Vec<Vec<(usize, Vec3)>> = vec![Vec::new(); n];
    let mut leans: Vec<Option<(usize, Vec3)>> = vec![None; n];
    let short = skeleton.longest_bone() * SHORT_BONE_FRACTION;
    for (j, p) in skeleton.parents().iter().enumerate() {
        let rest = skeleton.offsets()[j];
        let Some(p) = p.filter(|&p| p < j) else { continue };
        match skeleton.turning_chain(j, short) {
            // Seen through to the chain it turns: the rest direction from the parent to it.
            Some(chain) => leans[p] = leans[p].or(Some((chain, (rest + skeleton.offsets()[chain]).normalize()))),
            None if rest.length() > eps => children[p].push((j, rest.normalize())),
            None => {}
        }
    }
    let is_leaf = |j: usize| children[j].is_empty();
    let end_site_joints: Vec<usize> = (0..n).filter(|&j| children[j].len() >= 2 && children[j].iter().all(|&(c, _)| is_leaf(c)) && !keeps_shape(positions, n, j, &children[j])).collect();
    // A hand's end sites are left to the limit on its turn: bridged alone, one was set against
    // the other. Parents in index order, each child after its parent (`children` keeps p < c).
    let bridged_bones: Vec<(usize, usize)> = (0..n).filter(|p| !end_site_joints.contains(p)).flat_map(|p| children[p].iter().map(move |&(c, _)| (p, c))).collect();
    let bridged = bridge_collapsed_bones(skeleton, positions, &bridged_bones);
    let positions = bridged.as_ref().map_or(positions, |b| &b.positions);
    let solver = FrameSolver { skeleton, children, leans, eps };
    // Frames are independent: spread them over the cores, each thread with its own scratch.
    let mut poses: Vec<LocalPose> = positions.par_chunks_exact(n).map_init(|| Scratch::new(n), |scratch, frame| solver.solve(frame, scratch)).collect();
    for (j, run) in bridged.iter().flat_map(|b| &b.stretches).filter(|(j, _)| end_site_joints.contains(j)) {
        bridge_rotation(&mut poses, *j, run);
    }
    for &hand in &end_site_joints {
        if let Some(forearm) = skeleton.parents()[hand].filter(|&f| solver.children[f].len() == 1 && solver.leans[f].is_none()) {
            carry_twist_through_folds(skeleton, &mut poses, forearm, hand, solver.children[forearm][0].1);
        }
    }
    end_site_joints.into_iter().for_each(|j| limit_turns(&mut poses, j));
    poses
}

/// A bone bent further than this from its rest direction (degrees; an elbow nearly folded
/// shut) has no stable smallest swing: its twist is carried from frame to frame instead. The
/// swing's twist turns tan(bend / 2) times as fast as the bone, 3.6x at 149 degrees: at 150,
/// an h36m elbow bent to 142-149 turned its hand's end 94 degrees in one frame; at 135-140 the
/// ease back after such shallow folds turned a thumb 64-78.
const FOLDED_ABOVE: f32 = 145.0;

/// Frames over which a carried twist eases back to the solved one after a fold.
const TWIST_EASE_FRAMES: usize = 10;

/// The twist of `forearm` (one child, `hand`, whose own turn is limited; `rest` the forearm's
/// rest direction) carried from frame to frame while the forearm is folded past
/// [`FOLDED_ABOVE`], and eased back to the solved twist over [`TWIST_EASE_FRAMES`] after; the
/// hand keeps its world rotation. The solve's smallest swing from the rest direction,
/// collinear with the upper arm, turns about an unstable axis near a full fold: an h36m elbow
/// bent to 171-175 degrees flipped the forearm's twist, and the hand, limited in its local
/// turn, was carried round (its thumb 107-112 degrees in one frame while the forearm and
/// hand bones turned at most 8).
fn carry_twist_through_folds(skeleton: &Skeleton, poses: &mut [LocalPose], forearm: usize, hand: usize, rest: Vec3) {
    let upper = skeleton.ancestors(forearm).next();
    let world_of = |pose: &LocalPose, j: Option<usize>| j.map_or(Quat::IDENTITY, |j| std::iter::once(j).chain(skeleton.ancestors(j)).fold(Quat::IDENTITY, |w, a| pose.rotations[a] * w));
    let parents: Vec<Quat> = poses.iter().map(|pose| world_of(pose, upper)).collect();
    let solved: Vec<Quat> = poses.iter().zip(&parents).map(|(pose, p)| *p * pose.rotations[forearm]).collect();
    let folded: Vec<bool> = solved.iter().zip(&parents).map(|(w, p)| (*p * rest).angle_between(*w * rest) > FOLDED_ABOVE.to_radians()).collect();
    // A fold that follows within the easing of the one before carries on from it.
    let mut folds: Vec<Range<usize>> = Vec::new();
    for run in runs(&folded) {
        match folds.last_mut() {
            Some(last) if run.start <= last.end + TWIST_EASE_FRAMES => last.end = run.end,
            _ => folds.push(run),
        }
    }
    for run in folds {
        let end = (run.end + TWIST_EASE_FRAMES).min(poses.len());
        let mut carried = solved[run.start.saturating_sub(1)];
        for t in run.start..end {
            let direction = solved[t] * rest;
            carried = (Quat::from_rotation_arc((carried * rest).normalize(), direction.normalize()) * carried).normalize();
            let back = t.saturating_sub(run.end - 1) as f32 / TWIST_EASE_FRAMES as f32;
            let world = carried.slerp(solved[t], back.min(1.0)).normalize();
            let hand_world = solved[t] * poses[t].rotations[hand];
            poses[t].rotations[forearm] = (parents[t].inverse() * world).normalize();
            poses[t].rotations[hand] = (world.inverse() * hand_world).normalize();
        }
    }
}

/// A bone shorter than this fraction of its rest length has collapsed: its direction says
/// nothing, and restored to full length it flips (a Bandai run's wrist passing 2 cm from its
/// elbow turned the forearm 90 degrees in one frame).
const COLLAPSED_BELOW: f32 = 0.5;

/// A collapsed bone is bridged when its direction turns more than this in one frame (degrees)
/// somewhere between the whole frames either side of its collapse.
const COLLAPSED_SNAP: f32 = 20.0;

/// Input positions whose collapsed bones were bridged, and the stretches of frames each
/// bridged bone's child joint was moved in.
struct Bridged {
    positions: Vec<Vec3>,
    stretches: Vec<(usize, Range<usize>)>,
}

/// `positions` with every stretch of frames in which a bone of `bones` (parent, child) has
/// collapsed and snaps (turns more than [`COLLAPSED_SNAP`] in a frame, from the whole frame
/// before the stretch to the one after) bridged: the bone turns with its parent's bone from
/// its direction in the whole frame before the stretch to the one after ([`Ends::at`]; its
/// length likewise), and the child moves with everything below it. `bones` lists parents before
/// their children, so a bone is measured once the bones above it are bridged. None when no
/// bone is bridged (motion capture never collapses); a bone collapsed all take long is left.
fn bridge_collapsed_bones(skeleton: &Skeleton, positions: &[Vec3], bones: &[(usize, usize)]) -> Option<Bridged> {
    let n = skeleton.len();
    let frames = positions.len() / n;
    let rest = skeleton.rest_bone_lengths();
    let mut out: Option<Bridged> = None;
    for &(p, c) in bones {
        let current = out.as_ref().map_or(positions, |b| &b.positions);
        let bone = |t: usize| current[t * n + c] - current[t * n + p];
        // The parent's own bone, about which a bridged bone turns (none for the root's children).
        let grandparent = skeleton.parents()[p];
        let axis = |positions: &[Vec3], t: usize| grandparent.map(|g| positions[t * n + p] - positions[t * n + g]).and_then(|d| d.try_normalize());
        let collapsed: Vec<bool> = (0..frames).map(|t| bone(t).length() < COLLAPSED_BELOW * rest[c]).collect();
        // A collapsed bone whose direction holds (an h36m forearm shortened while its elbow
        // bent from 162 to 74 degrees and back, smoothly) is left as it is: bridged, its arc
        // passed through the folded elbow and twisted the hand.
        // (A bone of no length at all has no direction: it counts as a snap.)
        let snaps = |r: &Range<usize>| (r.start.saturating_sub(1)..r.end.min(frames - 1)).any(|t| !(bone(t).angle_between(bone(t + 1)) <= COLLAPSED_SNAP.to_radians()));
        let runs: Vec<Range<usize>> = runs(&collapsed).into_iter().filter(|r| r.len() < frames && snaps(r)).collect();
        if runs.is_empty() {
            continue;
        }
        // A stretch at either end of the take keeps the one whole frame it has.
        let ends: Vec<Ends> = runs.iter().map(|r| whole_either_side(r, frames)).map(|(a, b)| Ends::new(bone(a), bone(b), axis(current, a).zip(axis(current, b)))).collect();
        let bridged = out.get_or_insert_with(|| Bridged { positions: positions.to_vec(), stretches: Vec::new() });
        let below = skeleton.subtree(c);
        for (run, ends) in runs.into_iter().zip(ends) {
            let mut way_round = None;
            for (t, share) in shares(&run) {
                let shift = bridged.positions[t * n + p] + ends.at(share, axis(&bridged.positions, t), &mut way_round) - bridged.positions[t * n + c];
                below.iter().for_each(|&j| bridged.positions[t * n + j] += shift);
            }
            bridged.stretches.push((c, run));
        }
    }
    out
}

/// A collapsed bone in the whole frames either side of its stretch, and its parent's bone
/// (unit directions) in each: none for the root's children.
struct Ends {
    before: Vec3,
    after: Vec3,
    parent_bone: Option<(Vec3, Vec3)>,
    /// Whether the bone goes round its parent's bone rather than along the arc between its ends.
    goes_round: bool,
}

impl Ends {
    fn new(before: Vec3, after: Vec3, parent_bone: Option<(Vec3, Vec3)>) -> Self {
        let goes_round = parent_bone.is_some_and(|(from, to)| arc_bends_further(from, before.normalize(), Quat::from_rotation_arc(to, from) * after.normalize()));
        Self { before, after, parent_bone, goes_round }
    }

    /// The bone a `share` of the way through its stretch, its parent's bone pointing `now`
    /// there: both ends carried onto `now` by the parent bone's own turn, then along the
    /// shortest arc between them, or round the parent bone ([`round_parent_bone`]) where that
    /// arc would bend the bone further than either end, towards a joint folded shut. A
    /// world-space arc ignores the parent moving meanwhile: an h36m forearm bent 81 degrees
    /// before its collapse and 69 after was carried through an elbow bent 164 degrees, where
    /// the forearm's twist flips, and the hand's thumb turned 166 degrees in one frame.
    fn at(&self, share: f32, now: Option<Vec3>, way_round: &mut Option<f32>) -> Vec3 {
        let (before, after) = (self.before.normalize(), self.after.normalize());
        let arc = |from: Vec3, to: Vec3| Quat::IDENTITY.slerp(Quat::from_rotation_arc(from, to), share) * from;
        let direction = match self.parent_bone.zip(now) {
            Some(((from, to), now)) => {
                let (before, after) = (Quat::from_rotation_arc(from, now) * before, Quat::from_rotation_arc(to, now) * after);
                let round = self.goes_round.then(|| round_parent_bone(now, before, after, share, way_round)).flatten();
                round.unwrap_or_else(|| arc(before, after))
            }
            None => arc(before, after),
        };
        direction * (self.before.length() + share * (self.after.length() - self.before.length()))
    }
}

/// Whether the shortest arc from `before` to `after` (unit) bends further from `axis` than
/// both ends do at its middle (or has no middle: the ends opposite).
fn arc_bends_further(axis: Vec3, before: Vec3, after: Vec3) -> bool {
    (before + after).try_normalize().is_none_or(|middle| axis.angle_between(middle) > axis.angle_between(before).max(axis.angle_between(after)))
}

/// A bone's direction a `share` of the way from `before` to `after` round its parent's bone
/// `now` (all unit): the angle to the parent bone and the way round it interpolated. The way
/// round (radians) stays within half a turn of the frame before's (`way_round`, updated):
/// ends on opposite sides of the parent bone would otherwise go round one way in one frame
/// and the other way in the next. None when an end lies along the parent bone (no way round
/// it to interpolate).
fn round_parent_bone(now: Vec3, before: Vec3, after: Vec3, share: f32, way_round: &mut Option<f32>) -> Option<Vec3> {
    let across = |d: Vec3| (d - now * d.dot(now)).try_normalize().filter(|_| d.cross(now).length() > ALONG_PARENT_BONE.to_radians().sin());
    let (side_before, side_after) = (across(before)?, across(after)?);
    let bend = now.angle_between(before) + share * (now.angle_between(after) - now.angle_between(before));
    let mut round = side_before.cross(side_after).dot(now).atan2(side_before.dot(side_after));
    if let Some(previous) = *way_round {
        round += std::f32::consts::TAU * ((previous - round) / std::f32::consts::TAU).round();
    }
    *way_round = Some(round);
    let side = Quat::from_axis_angle(now, share * round) * side_before;
    Some(now * bend.cos() + side * bend.sin())
}

/// A bone within this angle of its parent's bone (degrees) has no way round it to follow.
const ALONG_PARENT_BONE: f32 = 10.0;

/// The whole frames either side of the stretch `run` of a take of `frames` frames: the
/// frame before it and the one after, or the one it has twice at an end of the take.
fn whole_either_side(run: &Range<usize>, frames: usize) -> (usize, usize) {
    match (run.start.checked_sub(1), (run.end < frames).then_some(run.end)) {
        (Some(a), Some(b)) => (a, b),
        (Some(a), None) => (a, a),
        (None, Some(b)) => (b, b),
        (None, None) => unreachable!("a stretch of every frame is not bridged"),
    }
}

/// Each frame of the stretch `run` with its share of the way from the whole frame before it
/// to the one after.
fn shares(run: &Range<usize>) -> impl Iterator<Item = (usize, f32)> + '_ {
    let span = (run.len() + 1) as f32;
    run.clone().enumerate().map(move |(k, t)| (t, (k + 1) as f32 / span))
}

/// Joint `j`'s local rotation through the stretch `run` turned along the shortest way from
/// the whole frame before it to the one after: a hand whose forearm collapsed is as
/// unreliable as the forearm (an h36m posing take's wrist end otherwise turned 105 degrees in
/// one frame once its forearm was bridged).
fn bridge_rotation(poses: &mut [LocalPose], j: usize, run: &Range<usize>) {
    let (a, b) = whole_either_side(run, poses.len());
    let (before, after) = (poses[a].rotations[j], poses[b].rotations[j]);
    for (t, share) in shares(run) {
        poses[t].rotations[j] = before.slerp(after, share).normalize();
    }
}

/// Whether every frame of `positions` keeps joint `j`'s end sites (`children`, rest
/// directions) at their rest angles to each other, within a degree: then one rotation places
/// them all exactly (motion capture, or a take already solved), and nothing is limited.
fn keeps_shape(positions: &[Vec3], n: usize, j: usize, children: &[(usize, Vec3)]) -> bool {
    let tolerance = 1.0f32.to_radians();
    positions.chunks_exact(n).all(|frame| {
        let actual = |c: usize| (frame[c] - frame[j]).normalize_or_zero();
        children.iter().zip(children.iter().skip(1)).all(|(&(a, rest_a), &(b, rest_b))| {
            let (da, db) = (actual(a), actual(b));
            da == Vec3::ZERO || db == Vec3::ZERO || (da.angle_between(db) - rest_a.angle_between(rest_b)).abs() <= tolerance
        })
    })
}

/// The most a joint that only places end sites turns (its local rotation) from one frame to
/// the next, degrees: Human3.6M's real thumb turns at most 24 degrees a frame at 30 fps (p99.9
/// of the S11 clips), the forearm's own turn included.
const MAX_HAND_TURN_PER_FRAME: f32 = 20.0;

/// Joint `j`'s local rotation turning at most [`MAX_HAND_TURN_PER_FRAME`] a frame: followed
/// at that speed forwards and backwards in time, and the two halfway met, so a snap is spread
/// evenly before and after it rather than trailing behind; the meeting is followed forwards
/// once more, which leaves it as it is but where it still snaps. Through a half-turn flip of
/// the input the two passes are nearly half a turn apart, and the shorter way from one to the
/// other changes sides from one frame to the next: the residual h36m GloGen's hand turned 179
/// degrees in one frame there (its thumb 159). Meeting on the side nearer the frame before's
/// instead (the first try) ran on along the far side until the passes met, then snapped back
/// (a wrist end of the shipped h36m's posing take 145 degrees in one frame).
fn limit_turns(poses: &mut [LocalPose], j: usize) {
    let own: Vec<Quat> = poses.iter().map(|p| p.rotations[j]).collect();
    let forwards = followed(own.iter().copied());
    let mut backwards = followed(own.iter().rev().copied());
    backwards.reverse();
    let met = forwards.into_iter().zip(backwards).map(|(a, b)| a.slerp(b, 0.5).normalize());
    for (pose, q) in poses.iter_mut().zip(followed(met)) {
        pose.rotations[j] = q;
    }
}

/// `rotations` followed in order, turning at most [`MAX_HAND_TURN_PER_FRAME`] a step.
fn followed(rotations: impl Iterator<Item = Quat>) -> Vec<Quat> {
    let limit = MAX_HAND_TURN_PER_FRAME.to_radians();
    let mut out: Vec<Quat> = Vec::new();
    for q in rotations {
        let next = match out.last() {
            Some(&p) if p.angle_between(q) > limit => p.slerp(q, limit / p.angle_between(q)).normalize(),
            _ => q,
        };
        out.push(next);
    }
    out
}

struct FrameSolver<'a> {
    skeleton: &'a Skeleton,
    children: Vec<Vec<(usize, Vec3)>>,
    /// Per joint, the chain a short child of it turns (the chain's first joint and its rest
    /// direction from this joint), which only sets the turn its other children leave open.
    leans: Vec<Option<(usize, Vec3)>>,
    eps: f32,
}

/// A frame's working space, reused from frame to frame.
struct Scratch {
    world: Vec<Quat>,
    pairs: Vec<(Vec3, Vec3)>,
}

impl Scratch {
    fn new(joints: usize) -> Self {
        Self { world: vec![Quat::IDENTITY; joints], pairs: Vec::new() }
    }
}

impl FrameSolver<'_> {
    fn solve(&self, frame: &[Vec3], scratch: &mut Scratch) -> LocalPose {
        let n = self.skeleton.len();
        let mut rotations = vec![Quat::IDENTITY; n];
        let mut translations = self.skeleton.offsets().to_vec();
        let Scratch { world, pairs } = scratch;
        for j in 0..n {
            let parent = self.skeleton.parents()[j].filter(|&p| p < j);
            let base = parent.map_or(Quat::IDENTITY, |p| world[p]);
            if parent.is_none() {
                translations[j] = frame[j];
            }
            pairs.clear();
            for &(c, rest) in &self.children[j] {
                let actual = frame[c] - frame[j];
                if actual.length() > self.eps && actual.is_finite() {
                    pairs.push((rest, actual.normalize()));
                }
            }
            let lean = self.leans[j].map(|(c, rest)| (rest, frame[c] - frame[j])).filter(|(_, actual)| actual.length() > self.eps && actual.is_finite());
            let w = lean.map_or_else(|| fit(base, pairs), |(rest, actual)| fit_leaning(base, pairs, rest, actual.normalize()));
            world[j] = w;
            rotations[j] = (base.inverse() * w).normalize();
        }
        LocalPose { rotations, translations }
    }
}

/// The world rotation of a joint whose parent's world rotation is `base`, from (rest, actual)
/// unit child directions.
fn fit(base: Quat, pairs: &[(Vec3, Vec3)]) -> Quat {
    match pairs {
        [] => base,
        [(rest, actual)] => swing(base, *rest, *actual),
        _ => {
            if spans_plane(pairs.iter().map(|p| p.0)) && spans_plane(pairs.iter().map(|p| p.1)) {
                horn(pairs)
            } else {
                let rest: Vec3 = pairs.iter().map(|p| p.0).sum();
                let actual: Vec3 = pairs.iter().map(|p| p.1).sum();
                if rest.length() > 1e-6 && actual.length() > 1e-6 {
                    swing(base, rest.normalize(), actual.normalize())
                } else {
                    swing(base, pairs[0].0, pairs[0].1)
                }
            }
        }
    }
}

/// [`fit`] where the children's fit leaves a turn open (one child, or all along one line: the
/// hips' two sockets), that turn taken so the leaning chain's rest direction `rest` comes
/// as near `actual` as it can; with children spanning a plane, their fit alone.
fn fit_leaning(base: Quat, pairs: &[(Vec3, Vec3)], rest: Vec3, actual: Vec3) -> Quat {
    let (axis_rest, axis) = match pairs {
        [] => return swing(base, rest, actual),
        _ if spans_plane(pairs.iter().map(|p| p.0)) && spans_plane(pairs.iter().map(|p| p.1)) => return horn(pairs),
        [first, ..] => *first,
    };
    let swung = swing(base, axis_rest, axis);
    // About the now exact axis, the turn taking the chain's direction nearest its actual one.
    let flat = |v: Vec3| (v - axis * v.dot(axis)).normalize_or_zero();
    let (from, to) = (flat(swung * rest), flat(actual));
    if from == Vec3::ZERO || to == Vec3::ZERO {
        return swung;
    }
    let angle = from.cross(to).dot(axis).atan2(from.dot(to));
    (Quat::from_axis_angle(axis, angle) * swung).normalize()
}

/// `base` followed by the shortest rotation taking `base * rest` onto `actual`.
fn swing(base: Quat, rest: Vec3, actual: Vec3) -> Quat {
    let base = base.as_dquat();
    let from = (base * rest.as_dvec3()).normalize();
    let to = actual.as_dvec3().normalize();
    (shortest_arc(from, to) * base).normalize().as_quat()
}

/// The shortest rotation taking unit `from` onto unit `to`, through the half-way vector: it
/// stays precise up to nearly opposite directions (where `1 + from.to` loses its digits);
/// exactly opposite ones turn half a turn about an axis perpendicular to `from`.
fn shortest_arc(from: DVec3, to: DVec3) -> DQuat {
    let half = from + to;
    let len = half.length();
    if len.is_nan() || len <= 1e-9 {
        let axis = from.any_orthonormal_vector();
        return DQuat::from_xyzw(axis.x, axis.y, axis.z, 0.0);
    }
    let h = half / len;
    let v = from.cross(h);
    DQuat::from_xyzw(v.x, v.y, v.z, from.dot(h)).normalize()
}

/// Whether some two of the unit vectors are at least ~0.6 degrees from (anti)parallel.
fn spans_plane(mut dirs: impl Iterator<Item = Vec3>) -> bool {
    let Some(first) = dirs.next() else { return false };
    dirs.any(|d| first.cross(d).length() > 1e-2)
}

#[cfg(test)]
mod tests {
    use super::horn::{horn_matrix, jacobi_largest_eigenvector, largest_eigenvector};
    use super::*;
    use crate::motion::forward_kinematics;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        }
        fn quat(&mut self) -> Quat {
            Quat::from_xyzw(self.next(), self.next(), self.next(), self.next()).normalize()
        }
        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next())
        }
    }

    /// A small body: root with three children (spine and two legs), a chest with three
    /// children (neck and two arms), single-child chains, a zero-length duplicate joint.
    fn body() -> Skeleton {
        let j = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        Skeleton::new(
            [
                "hips",
                "spine",
                "chest",
                "neck",
                "head",
                "l_arm",
                "l_hand",
                "r_arm",
                "r_hand",
                "l_leg",
                "l_foot",
                "r_leg",
                "r_foot",
                "r_foot_dup",
            ]
            .map(String::from)
            .to_vec(),
            vec![
                None,
                Some(0),
                Some(1),
                Some(2),
                Some(3),
                Some(2),
                Some(5),
                Some(2),
                Some(7),
                Some(0),
                Some(9),
                Some(0),
                Some(11),
                Some(12),
            ],
            vec![
                j(0.0, 90.0, 0.0),
                j(0.0, 10.0, -1.0),
                j(0.0, 20.0, 0.0),
                j(0.0, 15.0, 2.0),
                j(0.0, 10.0, 0.0),
                j(15.0, 10.0, 0.0),
                j(25.0, 0.0, 0.0),
                j(-15.0, 10.0, 0.0),
                j(-25.0, 0.0, 0.0),
                j(10.0, -5.0, 0.0),
                j(0.0, -40.0, 0.0),
                j(-10.0, -5.0, 0.0),
                j(0.0, -40.0, 0.0),
                j(0.0, 0.0, 0.0),
            ],
            0.01,
        )
        .unwrap()
    }

    fn fk(s: &Skeleton, pose: &LocalPose) -> Vec<Vec3> {
        let mut p = vec![Vec3::ZERO; s.len()];
        let mut w = vec![Quat::IDENTITY; s.len()];
        forward_kinematics(s, pose, &mut p, &mut w);
        p
    }

    #[test]
    fn shortest_arc_is_precise_near_opposite() {
        let from = DVec3::X;
        for angle in [0.0f64, 1e-6, 0.5, 3.0, std::f64::consts::PI - 1e-4, std::f64::consts::PI - 1e-6, std::f64::consts::PI] {
            let to = DVec3::new(angle.cos(), angle.sin(), 0.0);
            let q = shortest_arc(from, to);
            // `to` itself only carries ~1e-16 / (pi - angle) of precision near the opposite.
            let tol = 1e-12 + 1e-15 / (std::f64::consts::PI - angle).max(1e-6);
            assert!((q * from - to).length() < tol, "{angle}: {}", (q * from - to).length());
            assert!((q.w.clamp(-1.0, 1.0).acos() * 2.0 - angle).abs() < 1e-7, "not the shortest: {angle}");
        }
    }

    /// A forearm that sweeps from level to hanging over eight frames while, for three of
    /// them, the hand passes a centimetre from the elbow (backwards): the solve turns the bone
    /// along the sweep through the collapse instead of flipping it, holds it at its last whole
    /// direction through a collapse that ends the take, and leaves motion without a collapse
    /// as it is.
    #[test]
    fn a_collapsed_bone_turns_along_its_arc() {
        let s = body();
        let (arm, hand, n) = (5, 6, s.len());
        let sweep = |t: usize| Quat::from_rotation_z(-(t as f32) * std::f32::consts::FRAC_PI_2 / 8.0) * s.offsets()[hand];
        let take = |collapsed: std::ops::RangeInclusive<usize>| -> Vec<Vec3> {
            (0..=8)
                .flat_map(|t| {
                    let mut frame = s.rest_positions();
                    frame[hand] = frame[arm] + if collapsed.contains(&t) { -sweep(t).normalize() } else { sweep(t) };
                    frame
                })
                .collect()
        };
        let bones: Vec<(usize, usize)> = (1..n).filter_map(|c| Some((s.parents()[c]?, c))).collect();
        assert!(bridge_collapsed_bones(&s, &s.rest_positions(), &bones).is_none(), "nothing collapsed, nothing moved");
        let direction = |f: &[Vec3]| (f[hand] - f[arm]).normalize();
        for collapsed in [3..=5, 7..=8] {
            let solved: Vec<Vec<Vec3>> = solve_local_poses(&s, &take(collapsed.clone())).iter().map(|pose| fk(&s, pose)).collect();
            for pair in solved.windows(2) {
                let turn = direction(&pair[0]).angle_between(direction(&pair[1])).to_degrees();
                assert!(turn < 11.3, "collapsed over {collapsed:?}: the forearm turned {turn:.1} degrees in one frame");
            }
        }
    }

    /// A forearm bent 110 degrees that goes 170 degrees round its upper arm while the hand
    /// passes the elbow: bridged, it goes round the upper arm at the same bend (a world-space
    /// arc between its ends bent the elbow to 143 degrees).
    #[test]
    fn a_collapsed_bone_goes_round_its_parent_bone() {
        let s = body();
        let (chest, arm, hand) = (2, 5, 6);
        let upper = s.offsets()[arm].normalize();
        let across = upper.cross(Vec3::Z);
        let bend = 110.0f32.to_radians();
        let forearm = |round: f32| (upper * bend.cos() + (Vec3::Z * round.cos() + across * round.sin()) * bend.sin()) * s.offsets()[hand].length();
        let take: Vec<Vec3> = (0..=8)
            .flat_map(|t| {
                let mut frame = s.rest_positions();
                frame[hand] = frame[arm]
                    + match t {
                        0..=2 => forearm(0.0),
                        3..=5 => -0.04 * forearm(0.0),
                        _ => forearm(170.0f32.to_radians()),
                    };
                frame
            })
            .collect();
        for pose in solve_local_poses(&s, &take) {
            let f = fk(&s, &pose);
            let solved = (f[arm] - f[chest]).angle_between(f[hand] - f[arm]).to_degrees();
            assert!((solved - 110.0).abs() < 1.0, "the elbow bent {solved:.1} degrees, not 110");
        }
    }

    /// A hand whose input turns anywhere from frame to frame (flips of half a turn among
    /// them) comes out turning at most the limit a frame, wherever its two passes meet.
    #[test]
    fn a_limited_hand_never_turns_faster_than_the_limit() {
        let s = body();
        let hand = 6;
        let mut rng = Rng(7);
        let mut poses: Vec<LocalPose> = (0..300)
            .map(|_| {
                let mut rotations = vec![Quat::IDENTITY; s.len()];
                rotations[hand] = rng.quat();
                LocalPose { rotations, translations: s.offsets().to_vec() }
            })
            .collect();
        limit_turns(&mut poses, hand);
        for (t, pair) in poses.windows(2).enumerate() {
            let turn = pair[0].rotations[hand].angle_between(pair[1].rotations[hand]).to_degrees();
            assert!(turn <= MAX_HAND_TURN_PER_FRAME + 0.01, "the hand turned {turn:.1} degrees at frame {}", t + 1);
        }
    }

    #[test]
    fn horn_recovers_random_rotations() {
        let mut rng = Rng(7);
        for _ in 0..200 {
            let r = rng.quat();
            let pairs: Vec<(Vec3, Vec3)> = (0..3)
                .map(|_| {
                    let v = rng.vec().normalize();
                    (v, r * v)
                })
                .collect();
            let q = horn(&pairs);
            assert!(q.dot(r).abs() > 1.0 - 1e-5, "{q} vs {r}");
        }
    }

    /// The closed form and Jacobi agree on Horn's matrices of noisy fits (the eigenvector up
    /// to its sign), and a repeated largest eigenvalue falls back to Jacobi's answer.
    #[test]
    fn the_closed_form_eigenvector_is_jacobis() {
        let mut rng = Rng(3);
        for noise in [0.0, 0.1, 1.0] {
            for _ in 0..500 {
                let r = rng.quat();
                let pairs: Vec<(Vec3, Vec3)> = (0..3)
                    .map(|_| {
                        let v = rng.vec().normalize();
                        (v, (r * v + rng.vec() * noise).normalize())
                    })
                    .collect();
                let n = horn_matrix(&pairs);
                let (fast, slow) = (largest_eigenvector(n), jacobi_largest_eigenvector(n));
                let dot: f64 = fast.iter().zip(&slow).map(|(a, b)| a * b).sum();
                assert!(dot.abs() > 1.0 - 1e-9, "noise {noise}: {fast:?} against {slow:?}");
            }
        }
        // Two opposite pairs about one axis: every rotation about it that maps them fits as well.
        let x = Vec3::X;
        let degenerate = horn_matrix(&[(x, x), (-x, -x)]);
        assert_eq!(largest_eigenvector(degenerate), jacobi_largest_eigenvector(degenerate));
    }

    #[test]
    fn random_poses_round_trip_through_solve() {
        let s = body();
        let mut rng = Rng(11);
        let mut frames = Vec::new();
        let mut originals = Vec::new();
        for _ in 0..50 {
            let pose = LocalPose {
                rotations: (0..s.len()).map(|_| rng.quat()).collect(),
                translations: (0..s.len()).map(|j| if j == 0 { rng.vec() * 100.0 } else { s.offsets()[j] }).collect(),
            };
            let p = fk(&s, &pose);
            frames.extend_from_slice(&p);
            originals.push(p);
        }
        let solved = solve_local_poses(&s, &frames);
        assert_eq!(solved.len(), 50);
        for (pose, want) in solved.iter().zip(&originals) {
            let got = fk(&s, pose);
            for (a, b) in got.iter().zip(want) {
                assert!(a.distance(*b) < 1e-3, "{a} vs {b}");
            }
            assert_eq!(pose.translations[0], want[0]);
            assert_eq!(&pose.translations[1..], &s.offsets()[1..]);
        }
    }

    #[test]
    fn rest_pose_solves_to_identity_and_twist_follows_parent() {
        let s = body();
        let rest = s.rest_positions();
        let pose = &solve_local_poses(&s, &rest)[0];
        for q in &pose.rotations {
            assert!(q.dot(Quat::IDENTITY).abs() > 1.0 - 1e-6, "{q}");
        }
        // Turn the whole body 90 degrees about y: every local rotation but the root's stays
        // identity (single-child bones inherit the twist instead of inventing one).
        let turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let turned: Vec<Vec3> = rest.iter().map(|p| turn * *p).collect();
        let pose = &solve_local_poses(&s, &turned)[0];
        assert!(pose.rotations[0].dot(turn).abs() > 1.0 - 1e-5);
        for q in &pose.rotations[1..] {
            assert!(q.dot(Quat::IDENTITY).abs() > 1.0 - 1e-5, "{q}");
        }
    }

    #[test]
    fn stretched_bones_come_back_at_rest_length_and_right_direction() {
        let s = body();
        let mut stretched = s.rest_positions();
        // Stretch the left forearm to twice its length and bend it down.
        stretched[6] = stretched[5] + Vec3::new(0.0, -50.0, 0.0);
        let pose = &solve_local_poses(&s, &stretched)[0];
        let p = fk(&s, pose);
        let bone = p[6] - p[5];
        assert!((bone.length() - 25.0).abs() < 1e-3);
        assert!(bone.normalize().dot(Vec3::NEG_Y) > 1.0 - 1e-5, "{bone}");
    }

    #[test]
    fn degenerate_input_does_not_panic() {
        let s = body();
        let all_same = vec![Vec3::ZERO; s.len()];
        let nan = vec![Vec3::NAN; s.len()];
        for frame in [all_same, nan] {
            let poses = solve_local_poses(&s, &frame);
            assert_eq!(poses.len(), 1);
        }
        // A partial trailing frame is ignored.
        assert_eq!(solve_local_poses(&s, &vec![Vec3::ZERO; s.len() + 3]).len(), 1);
    }
}
