//! BVH (Biovision Hierarchy) motion files: a reader for any hierarchy and channel layout, and
//! a writer that reproduces a layout or picks a standard one.
//!
//! Reading:
//! - `ROOT` / `JOINT` blocks become joints in file order (depth first, so parents come before
//!   children and the frame values follow joint order). Several `ROOT`s are allowed.
//! - `End Site` blocks are **not** joints: they carry no channels and only mark where a leaf
//!   bone ends, so they are checked and dropped. Joint counts are therefore those of the
//!   `ROOT`/`JOINT` lines (Bandai: 22, CMU dance: 43).
//! - `CHANNELS` may list position and rotation channels in any order on any joint. Rotation
//!   channels compose in the order listed (`Zrotation Xrotation Yrotation` is
//!   `Rz * Rx * Ry`, angles in degrees). Position channels *replace* the matching component of
//!   the joint's `OFFSET` (the offset stays the skeleton's rest offset).
//! - Keywords are case-insensitive; tokens may be separated by spaces or tabs; lines may end
//!   in LF or CRLF; a UTF-8 byte-order mark is skipped.
//! - `fps` is `1 / Frame Time`, snapped to the nearest integer when within 1e-4 of it
//!   relatively (files store `0.0333333` for 30 fps).
//! - Every problem is a [`FormatError`] naming the file and line; no input makes the reader
//!   panic (see the fuzz target in `fuzz/`).
//!
//! Writing: see [`write_bvh`].

use std::fmt::Write as _;
use std::sync::Arc;

use glam::{DQuat, Quat, Vec3};

use super::FormatError;
use crate::motion::{clipped as clip, quat_to_euler, solve_local_poses, EulerOrder, LocalPose, Motion, Skeleton};

/// The channels one joint carries in a BVH file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointChannels {
    /// The order of the joint's rotation channels. A joint that lists fewer than three rotation
    /// channels gets the listed axes first, then the missing ones in X, Y, Z order (the missing
    /// angles are zero, so the rotation is the same).
    pub rotation_order: EulerOrder,
    /// Whether the joint has position channels (they replace its offset).
    pub has_position: bool,
}

/// The per-joint channel layout of a BVH file, in skeleton joint order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BvhLayout {
    pub joints: Vec<JointChannels>,
}

impl BvhLayout {
    /// The layout [`write_bvh`] uses when given none: every root has position channels, every
    /// other joint has them only when the motion's local translations leave its rest offset
    /// (by more than `1e-5 * (1 + |offset|)` in any frame, e.g. Bandai's `Hips`); every joint
    /// rotates in `Z X Y` order.
    pub fn default_for(motion: &Motion) -> BvhLayout {
        let poses = usable_poses(motion);
        Self::default_for_poses(&motion.skeleton, poses.unwrap_or(&[]))
    }

    fn default_for_poses(skeleton: &Skeleton, poses: &[LocalPose]) -> BvhLayout {
        let joints = (0..skeleton.len())
            .map(|j| {
                let offset = skeleton.offsets()[j];
                let tol = 1e-5 * (1.0 + offset.length());
                let moves = poses.iter().any(|p| (p.translations[j] - offset).abs().max_element() > tol);
                JointChannels { rotation_order: EulerOrder::ZXY, has_position: skeleton.parents()[j].is_none() || moves }
            })
            .collect();
        BvhLayout { joints }
    }
}

/// Reads a BVH file whose offsets are in centimetres (`meters_per_unit` 0.01).
pub fn read_bvh(text: &str, file: &str) -> Result<Motion, FormatError> {
    read_bvh_with_unit(text, file, 0.01)
}

/// Reads a BVH file; `meters_per_unit` is stored in the skeleton (the file does not say).
pub fn read_bvh_with_unit(text: &str, file: &str, meters_per_unit: f32) -> Result<Motion, FormatError> {
    read_bvh_layout_with_unit(text, file, meters_per_unit).map(|(m, _)| m)
}

/// Reads a BVH file in centimetres, with the channel layout it used.
pub fn read_bvh_layout(text: &str, file: &str) -> Result<(Motion, BvhLayout), FormatError> {
    read_bvh_layout_with_unit(text, file, 0.01)
}

/// Reads a BVH file with the channel layout it used.
pub fn read_bvh_layout_with_unit(text: &str, file: &str, meters_per_unit: f32) -> Result<(Motion, BvhLayout), FormatError> {
    Reader { file }.read(text, meters_per_unit)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Channel {
    Position(usize),
    Rotation(usize),
}

struct RawJoint {
    name: String,
    parent: Option<usize>,
    line: usize,
    offset: Option<Vec3>,
    channels: Option<Vec<Channel>>,
}

enum Block {
    Joint(usize),
    EndSite { line: usize, offset: bool },
}

const AXES: [Vec3; 3] = [Vec3::X, Vec3::Y, Vec3::Z];
const AXIS_NAMES: [char; 3] = ['X', 'Y', 'Z'];

struct Reader<'a> {
    file: &'a str,
}

impl Reader<'_> {
    fn err(&self, line: usize, message: impl Into<String>) -> FormatError {
        FormatError::at_line(self.file, line, message)
    }

    fn read(&self, text: &str, meters_per_unit: f32) -> Result<(Motion, BvhLayout), FormatError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        if text.trim().is_empty() {
            return Err(FormatError::new(self.file, "empty file: expected a BVH file starting with HIERARCHY"));
        }
        let lines: Vec<&str> = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l)).collect();

        // Tokens of the hierarchy, up to the line starting with MOTION.
        let mut tokens: Vec<(usize, &str)> = Vec::new();
        let mut motion_line = None;
        for (i, line) in lines.iter().enumerate() {
            let mut it = line.split_whitespace().peekable();
            if it.peek().is_some_and(|t| t.eq_ignore_ascii_case("MOTION")) {
                motion_line = Some(i);
                break;
            }
            tokens.extend(it.map(|t| (i + 1, t)));
        }
        match tokens.first() {
            Some((_, t)) if t.eq_ignore_ascii_case("HIERARCHY") => {}
            Some((line, t)) => return Err(self.err(*line, format!("missing HIERARCHY: the file starts with '{}'", clip(t)))),
            None => return Err(self.err(motion_line.unwrap_or(0) + 1, "missing HIERARCHY: MOTION comes first")),
        }
        let joints = self.parse_hierarchy(&tokens[1..], motion_line, lines.len())?;
        let Some(motion_line) = motion_line else {
            return Err(self.err(lines.len(), "missing MOTION section: the file ends after the hierarchy"));
        };

        let channels: Vec<Vec<Channel>> = joints.iter().map(|j| j.channels.clone().unwrap_or_default()).collect();
        let total: usize = channels.iter().map(Vec::len).sum();
        if total == 0 {
            return Err(self.err(motion_line + 1, "the hierarchy declares no CHANNELS"));
        }

        // MOTION: Frames, Frame Time, then one line per frame.
        let mut rest = lines.iter().enumerate().skip(motion_line + 1).map(|(i, l)| (i + 1, *l)).filter(|(_, l)| !l.trim().is_empty());
        let (frames_line, frames_text) = self.header_field(rest.next(), "Frames", motion_line + 1)?;
        let frames: usize =
            frames_text.parse().map_err(|_| self.err(frames_line, format!("bad frame count '{}' after Frames:", clip(frames_text))))?;
        let (time_line, time_text) = self.header_field(rest.next(), "Frame Time", frames_line)?;
        let frame_time: f64 =
            time_text.parse().map_err(|_| self.err(time_line, format!("bad frame time '{}' after Frame Time:", clip(time_text))))?;
        if !(frame_time.is_finite() && frame_time > 0.0) {
            return Err(self.err(time_line, format!("frame time must be a positive number of seconds, found {}", clip(time_text))));
        }
        let fps = snap_fps(1.0 / frame_time);
        if !(fps.is_finite() && fps > 0.0) {
            return Err(self.err(time_line, format!("frame time {} is out of range", clip(time_text))));
        }

        let skeleton = Skeleton::new(
            joints.iter().map(|j| j.name.clone()).collect(),
            joints.iter().map(|j| j.parent).collect(),
            joints.iter().map(|j| j.offset.unwrap_or(Vec3::ZERO)).collect(),
            meters_per_unit,
        )
        .map_err(|e| self.err(1, e.to_string()))?;

        let mut poses = Vec::with_capacity(frames.min(lines.len()));
        let mut values = Vec::with_capacity(total);
        let mut last_line = time_line;
        for (line_no, line) in rest.by_ref().take(frames) {
            last_line = line_no;
            values.clear();
            let found = line.split_whitespace().count();
            if found != total {
                return Err(self.err(line_no, format!("frame {} has {found} values, expected {total}", poses.len() + 1)));
            }
            for (k, tok) in line.split_whitespace().enumerate() {
                let v: f64 = tok.parse().map_err(|_| self.err(line_no, format!("value {} '{}' is not a number", k + 1, clip(tok))))?;
                if !v.is_finite() || !(v as f32).is_finite() {
                    return Err(self.err(line_no, format!("value {} '{}' is not finite", k + 1, clip(tok))));
                }
                values.push(v);
            }
            poses.push(self.pose(&skeleton, &channels, &values));
        }
        if poses.len() < frames {
            return Err(self.err(last_line, format!("Frames: says {frames} but only {} frame lines follow (file truncated?)", poses.len())));
        }
        if let Some((line_no, _)) = rest.next() {
            return Err(self.err(line_no, format!("more frame lines than the {frames} that Frames: declares")));
        }

        let layout = BvhLayout {
            joints: channels
                .iter()
                .map(|ch| {
                    let mut axes: Vec<usize> =
                        ch.iter().filter_map(|c| if let Channel::Rotation(a) = c { Some(*a) } else { None }).collect();
                    axes.extend((0..3).filter(|a| !axes.contains(a)).collect::<Vec<_>>());
                    let letters = [AXIS_NAMES[axes[0]], AXIS_NAMES[axes[1]], AXIS_NAMES[axes[2]]];
                    JointChannels {
                        rotation_order: EulerOrder::from_axes(letters).unwrap_or(EulerOrder::ZXY),
                        has_position: ch.iter().any(|c| matches!(c, Channel::Position(_))),
                    }
                })
                .collect(),
        };
        let motion = Motion::from_local_poses(Arc::new(skeleton), fps, poses);
        if let Some(k) = motion.positions().iter().position(|p| !p.is_finite()) {
            let (t, j) = (k / motion.joints(), k % motion.joints());
            return Err(self.err(
                time_line + 1 + t,
                format!("joint '{}' lands at a non-finite position in frame {} (values too large)", clip(&motion.skeleton.names()[j]), t + 1),
            ));
        }
        Ok((motion, layout))
    }

    /// `Frames:` or `Frame Time:`: the text after the colon.
    fn header_field<'t>(&self, line: Option<(usize, &'t str)>, key: &str, previous: usize) -> Result<(usize, &'t str), FormatError> {
        let Some((line_no, text)) = line else {
            return Err(self.err(previous, format!("the MOTION section has no '{key}:' line")));
        };
        let found_key = text.split_once(':').map(|(k, v)| (k.split_whitespace().collect::<Vec<_>>().join(" "), v.trim()));
        match found_key {
            Some((k, v)) if k.eq_ignore_ascii_case(key) => Ok((line_no, v)),
            _ => Err(self.err(line_no, format!("expected '{key}:', found '{}'", clip(text.trim())))),
        }
    }

    fn parse_hierarchy(
        &self,
        tokens: &[(usize, &str)],
        motion_line: Option<usize>,
        line_count: usize,
    ) -> Result<Vec<RawJoint>, FormatError> {
        let mut joints: Vec<RawJoint> = Vec::new();
        let mut stack: Vec<Block> = Vec::new();
        let mut i = 0;
        let end_line = motion_line.map_or(line_count, |m| m + 1);
        let expect_open = |i: &mut usize, after_line: usize, what: &str| -> Result<(), FormatError> {
            match tokens.get(*i) {
                Some((_, "{")) => {
                    *i += 1;
                    Ok(())
                }
                Some((line, t)) => Err(self.err(*line, format!("expected '{{' after {what}, found '{}'", clip(t)))),
                None => Err(self.err(after_line, format!("expected '{{' after {what}, found the end of the hierarchy"))),
            }
        };
        while i < tokens.len() {
            let (line, tok) = tokens[i];
            i += 1;
            let key = tok.to_ascii_uppercase();
            match key.as_str() {
                "ROOT" | "JOINT" => {
                    let parent = match (key.as_str(), stack.last()) {
                        ("ROOT", None) => None,
                        ("ROOT", Some(_)) => return Err(self.err(line, "ROOT inside another joint's braces (unbalanced braces?)")),
                        (_, Some(Block::Joint(p))) => Some(*p),
                        (_, Some(Block::EndSite { .. })) => return Err(self.err(line, "JOINT inside an End Site")),
                        (_, None) => return Err(self.err(line, "JOINT outside any ROOT (unbalanced braces?)")),
                    };
                    let mut parts = Vec::new();
                    while i < tokens.len() && tokens[i].0 == line && tokens[i].1 != "{" {
                        parts.push(tokens[i].1);
                        i += 1;
                    }
                    if parts.is_empty() {
                        return Err(self.err(line, format!("{tok} without a name")));
                    }
                    let name = parts.join(" ");
                    expect_open(&mut i, line, &format!("{tok} {}", clip(&name)))?;
                    stack.push(Block::Joint(joints.len()));
                    joints.push(RawJoint { name, parent, line, offset: None, channels: None });
                }
                "END" => {
                    match tokens.get(i) {
                        Some((_, s)) if s.eq_ignore_ascii_case("Site") => i += 1,
                        _ => return Err(self.err(line, "expected 'Site' after 'End'")),
                    }
                    match stack.last() {
                        Some(Block::Joint(_)) => {}
                        _ => return Err(self.err(line, "End Site outside a joint")),
                    }
                    expect_open(&mut i, line, "End Site")?;
                    stack.push(Block::EndSite { line, offset: false });
                }
                "OFFSET" => {
                    let mut v = [0f32; 3];
                    for (k, c) in v.iter_mut().enumerate() {
                        let Some(&(l, t)) = tokens.get(i).filter(|(l, _)| *l == line) else {
                            return Err(self.err(line, format!("OFFSET needs 3 numbers, found {k}")));
                        };
                        *c =
                            number(t).ok_or_else(|| self.err(l, format!("OFFSET value {} '{}' is not a finite number", k + 1, clip(t))))?;
                        i += 1;
                    }
                    let offset = Vec3::from_array(v);
                    match stack.last_mut() {
                        Some(Block::Joint(j)) => {
                            if joints[*j].offset.replace(offset).is_some() {
                                return Err(self.err(line, format!("second OFFSET for joint '{}'", clip(&joints[*j].name))));
                            }
                        }
                        Some(Block::EndSite { offset: seen, .. }) => {
                            if std::mem::replace(seen, true) {
                                return Err(self.err(line, "second OFFSET in an End Site"));
                            }
                        }
                        None => return Err(self.err(line, "OFFSET outside any joint")),
                    }
                }
                "CHANNELS" => {
                    let j = match stack.last() {
                        Some(Block::Joint(j)) => *j,
                        _ => return Err(self.err(line, "CHANNELS outside a joint")),
                    };
                    let Some(&(cl, count_tok)) = tokens.get(i) else {
                        return Err(self.err(line, "CHANNELS without a count"));
                    };
                    i += 1;
                    let count: usize = count_tok
                        .parse()
                        .ok()
                        .filter(|c| *c <= 6)
                        .ok_or_else(|| self.err(cl, format!("bad channel count '{}' (expected 0 to 6)", clip(count_tok))))?;
                    let mut list = Vec::with_capacity(count);
                    for k in 0..count {
                        let Some(&(l, name)) = tokens.get(i) else {
                            return Err(self.err(line, format!("CHANNELS {count} lists only {k} channels")));
                        };
                        i += 1;
                        let ch = channel(name).ok_or_else(|| {
                            self.err(l, format!("unknown channel '{}' (expected Xposition..Zposition or Xrotation..Zrotation)", clip(name)))
                        })?;
                        if list.contains(&ch) {
                            return Err(self.err(l, format!("channel '{name}' listed twice")));
                        }
                        list.push(ch);
                    }
                    if joints[j].channels.replace(list).is_some() {
                        return Err(self.err(line, format!("second CHANNELS for joint '{}'", clip(&joints[j].name))));
                    }
                }
                "}" => match stack.pop() {
                    Some(Block::Joint(j)) => {
                        if joints[j].offset.is_none() {
                            return Err(self.err(joints[j].line, format!("joint '{}' has no OFFSET", clip(&joints[j].name))));
                        }
                    }
                    Some(Block::EndSite { line, offset }) => {
                        if !offset {
                            return Err(self.err(line, "End Site has no OFFSET"));
                        }
                    }
                    None => return Err(self.err(line, "unbalanced braces: '}' closes nothing")),
                },
                _ => {
                    return Err(self.err(
                        line,
                        format!(
                            "unexpected '{}' in the hierarchy (expected ROOT, JOINT, End Site, OFFSET, CHANNELS or a brace)",
                            clip(tok)
                        ),
                    ))
                }
            }
        }
        if let Some(open) = stack.last() {
            let (what, line) = match open {
                Block::Joint(j) => (format!("joint '{}'", clip(&joints[*j].name)), joints[*j].line),
                Block::EndSite { line, .. } => ("End Site".to_string(), *line),
            };
            let place = if motion_line.is_some() { "before MOTION" } else { "at the end of the file (missing MOTION section)" };
            return Err(self.err(
                end_line,
                format!("unbalanced braces: {} still open {place}; the innermost, {what}, opened on line {line}", stack.len()),
            ));
        }
        if joints.is_empty() {
            return Err(self.err(end_line, "the hierarchy has no ROOT"));
        }
        Ok(joints)
    }

    fn pose(&self, skeleton: &Skeleton, channels: &[Vec<Channel>], values: &[f64]) -> LocalPose {
        let mut rotations = Vec::with_capacity(skeleton.len());
        let mut translations = Vec::with_capacity(skeleton.len());
        let mut k = 0;
        for (j, chans) in channels.iter().enumerate() {
            let mut t = skeleton.offsets()[j];
            let mut q = DQuat::IDENTITY;
            for c in chans {
                let v = values[k];
                k += 1;
                match *c {
                    Channel::Position(a) => t[a] = v as f32,
                    Channel::Rotation(a) => {
                        // Reduce first so large unwrapped angles keep their precision.
                        let rad = v.rem_euclid(360.0).to_radians();
                        q *= DQuat::from_axis_angle(AXES[a].as_dvec3(), rad);
                    }
                }
            }
            rotations.push(q.normalize().as_quat());
            translations.push(t);
        }
        LocalPose { rotations, translations }
    }
}

fn channel(name: &str) -> Option<Channel> {
    if name.len() != 9 || !name.is_ascii() {
        return None;
    }
    let axis = match name.as_bytes()[0].to_ascii_uppercase() {
        b'X' => 0,
        b'Y' => 1,
        b'Z' => 2,
        _ => return None,
    };
    let kind = &name[1..];
    if kind.eq_ignore_ascii_case("position") {
        Some(Channel::Position(axis))
    } else if kind.eq_ignore_ascii_case("rotation") {
        Some(Channel::Rotation(axis))
    } else {
        None
    }
}

fn number(tok: &str) -> Option<f32> {
    tok.parse::<f32>().ok().filter(|v| v.is_finite())
}

/// A token shortened for error messages.

fn snap_fps(fps: f64) -> f32 {
    let r = fps.round();
    if r >= 1.0 && (fps - r).abs() <= 1e-4 * r {
        r as f32
    } else {
        fps as f32
    }
}

/// The motion's local poses when they fit its skeleton and frame count.
fn usable_poses(motion: &Motion) -> Option<&[LocalPose]> {
    let j = motion.skeleton.len();
    motion
        .local_poses
        .as_deref()
        .filter(|p| p.len() == motion.frames() && p.iter().all(|p| p.rotations.len() == j && p.translations.len() == j))
}

/// Writes `motion` as BVH text.
///
/// - HIERARCHY from the skeleton: joints depth first, children in index order (a skeleton
///   read from BVH is already in that order, so indices survive a round trip), `OFFSET` the
///   rest offsets. A joint without children gets an `End Site` whose offset continues the
///   joint's own bone direction at half its length (zero for a root). Names have whitespace
///   runs collapsed to one space and braces removed; an empty name becomes `joint<index>`.
/// - Channels: `layout` when given and it has one entry per joint, else
///   [`BvhLayout::default_for`] (roots `Xposition Yposition Zposition Zrotation Xrotation
///   Yrotation`, other joints `Zrotation Xrotation Yrotation`). Position channels always come
///   first, in X Y Z order.
/// - MOTION: `Frames:`, `Frame Time:` = 1/fps with 8 decimals (exponent form above 1000
///   fps), then one line per frame with 6
///   decimals per value. Euler angles come straight from each local rotation in the joint's
///   order; of the two Euler solutions of a rotation, the one closest to the previous frame's
///   angles is written, unwrapped by whole turns, so no channel jumps by 360 (or flips
///   through the alternate solution) between frames.
/// - Rotations: the motion's `local_poses` when present (and consistent with the skeleton),
///   otherwise solved from positions with [`solve_local_poses`] against the rest pose.
pub fn write_bvh(motion: &Motion, layout: Option<&BvhLayout>) -> String {
    let skeleton = &*motion.skeleton;
    let n = skeleton.len();
    let solved;
    let poses: &[LocalPose] = match usable_poses(motion) {
        Some(p) => p,
        None => {
            solved = solve_local_poses(skeleton, motion.positions());
            &solved
        }
    };
    let default;
    let layout = match layout {
        Some(l) if l.joints.len() == n => l,
        _ => {
            default = BvhLayout::default_for_poses(skeleton, poses);
            &default
        }
    };

    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut roots = Vec::new();
    for j in 0..n {
        match skeleton.parents()[j] {
            Some(p) if p < j => children[p].push(j),
            _ => roots.push(j),
        }
    }

    let mut out = String::with_capacity(64 * n + poses.len() * n * 40);
    out.push_str("HIERARCHY\n");
    enum Ev {
        Open(usize, usize),
        Close(usize),
    }
    let mut order = Vec::with_capacity(n);
    let mut stack: Vec<Ev> = roots.iter().rev().map(|&r| Ev::Open(r, 0)).collect();
    let indent = |out: &mut String, depth: usize| out.extend(std::iter::repeat_n('\t', depth));
    while let Some(ev) = stack.pop() {
        match ev {
            Ev::Open(j, depth) => {
                order.push(j);
                indent(&mut out, depth);
                let kind = if skeleton.parents()[j].is_some() && depth > 0 { "JOINT" } else { "ROOT" };
                let _ = writeln!(out, "{kind} {}", joint_name(&skeleton.names()[j], j));
                indent(&mut out, depth);
                out.push_str("{\n");
                indent(&mut out, depth + 1);
                let o = skeleton.offsets()[j];
                let _ = writeln!(out, "OFFSET {:.6} {:.6} {:.6}", o.x, o.y, o.z);
                indent(&mut out, depth + 1);
                let ch = layout.joints[j];
                let axes = ch.rotation_order.axes();
                if ch.has_position {
                    out.push_str("CHANNELS 6 Xposition Yposition Zposition");
                } else {
                    out.push_str("CHANNELS 3");
                }
                let _ = writeln!(out, " {}rotation {}rotation {}rotation", axes[0], axes[1], axes[2]);
                stack.push(Ev::Close(depth));
                if children[j].is_empty() {
                    let tip = if depth > 0 { skeleton.offsets()[j] * 0.5 } else { Vec3::ZERO };
                    indent(&mut out, depth + 1);
                    out.push_str("End Site\n");
                    indent(&mut out, depth + 1);
                    out.push_str("{\n");
                    indent(&mut out, depth + 2);
                    let _ = writeln!(out, "OFFSET {:.6} {:.6} {:.6}", tip.x, tip.y, tip.z);
                    indent(&mut out, depth + 1);
                    out.push_str("}\n");
                }
                stack.extend(children[j].iter().rev().map(|&c| Ev::Open(c, depth + 1)));
            }
            Ev::Close(depth) => {
                indent(&mut out, depth);
                out.push_str("}\n");
            }
        }
    }

    let frame_time = 1.0 / motion.fps as f64;
    out.push_str("MOTION\n");
    let _ = writeln!(out, "Frames: {}", poses.len());
    if frame_time >= 1e-3 {
        let _ = writeln!(out, "Frame Time: {frame_time:.8}");
    } else {
        // Above 1000 fps eight decimals are too few: shortest exact form instead.
        let _ = writeln!(out, "Frame Time: {frame_time:e}");
    }
    let mut previous: Vec<Option<[f64; 3]>> = vec![None; n];
    for pose in poses {
        let mut first = true;
        let mut sep = |out: &mut String| {
            if !std::mem::take(&mut first) {
                out.push(' ');
            }
        };
        for &j in &order {
            let ch = layout.joints[j];
            if ch.has_position {
                for v in pose.translations[j].to_array() {
                    sep(&mut out);
                    let _ = write!(out, "{v:.6}");
                }
            }
            let angles = continuous_euler(ch.rotation_order, pose.rotations[j], previous[j]);
            previous[j] = Some(angles);
            for v in angles {
                sep(&mut out);
                let _ = write!(out, "{v:.6}");
            }
        }
        out.push('\n');
    }
    out
}

fn joint_name(name: &str, j: usize) -> String {
    let clean: String = name.split_whitespace().collect::<Vec<_>>().join(" ").replace(['{', '}'], "");
    if clean.is_empty() {
        format!("joint{j}")
    } else {
        clean
    }
}

/// Euler angles (degrees) of `q` in `order`, as close as possible to `previous`: of the two
/// solutions `(a, b, c)` and `(a + 180, 180 - b, c + 180)`, each unwrapped by whole turns, the
/// nearer one.
fn continuous_euler(order: EulerOrder, q: Quat, previous: Option<[f64; 3]>) -> [f64; 3] {
    let a = quat_to_euler(order, q).map(f64::from);
    let Some(p) = previous else { return a };
    let unwrap = |x: [f64; 3]| -> [f64; 3] { std::array::from_fn(|i| x[i] - 360.0 * ((x[i] - p[i]) / 360.0).round()) };
    let first = unwrap(a);
    let second = unwrap([a[0] + 180.0, 180.0 - a[1], a[2] + 180.0]);
    let dist = |x: &[f64; 3]| (0..3).map(|i| (x[i] - p[i]).abs()).sum::<f64>();
    if dist(&second) < dist(&first) {
        second
    } else {
        first
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Location;
    use crate::motion::euler_to_quat;

    /// Root ZYX with position, joint `a` ZXY, leaf `b` under it, and `c`: a non-root joint
    /// with position channels (its OFFSET must be replaced). Tabs, CRLF, keyword spacing.
    const HAND: &str =
        "HIERARCHY\r\nROOT root\r\n{\r\n\tOFFSET 0 0 0\r\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\r\n\
\tJOINT a\r\n\t{\r\n\t\tOFFSET 0 10 0\r\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\r\n\
\t\tJOINT b\r\n\t\t{\r\n\t\t\tOFFSET 0 0 5\r\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\r\n\
\t\t\tEnd Site\r\n\t\t\t{\r\n\t\t\t\tOFFSET 0 0 1\r\n\t\t\t}\r\n\t\t}\r\n\t}\r\n\
\tJOINT c\r\n\t{\r\n\t\tOFFSET 100 100 100\r\n\t\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\r\n\
\t\tEnd Site\r\n\t\t{\r\n\t\t\tOFFSET 0 1 0\r\n\t\t}\r\n\t}\r\n}\r\n\
MOTION\r\nFrames:\t2\r\nFrame Time:\t0.0333333\r\n\
1\t2\t3\t90\t0\t90\t90 0 90\t0 0 0\t1 0 0 0 0 0\r\n\
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n";

    fn err(text: &str) -> FormatError {
        match read_bvh(text, "test.bvh") {
            Ok(_) => panic!("expected an error for:\n{text}"),
            Err(e) => {
                assert_eq!(e.file, "test.bvh");
                e
            }
        }
    }

    fn line_of(e: &FormatError) -> usize {
        match e.location {
            Some(Location::Line(l)) => l,
            other => panic!("expected a line in {e} ({other:?})"),
        }
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        a.distance(b) < 1e-4
    }

    #[test]
    fn rotation_orders_give_known_positions() {
        let (m, layout) = read_bvh_layout(HAND, "hand.bvh").unwrap();
        let s = &m.skeleton;
        assert_eq!(s.names(), vec!["root", "a", "b", "c"], "End Sites must not be joints");
        assert_eq!(s.parents(), vec![None, Some(0), Some(1), Some(0)]);
        assert_eq!(m.fps, 30.0);
        assert_eq!(m.frames(), 2);
        // Root: Rz(90) Ry(0) Rx(90); a: Rz(90) Rx(0) Ry(90) (values "90 0 90" in ZXY order).
        let f = m.frame(0);
        assert!(close(f[0], Vec3::new(1.0, 2.0, 3.0)), "{:?}", f[0]);
        assert!(close(f[1], Vec3::new(1.0, 2.0, 13.0)), "a: {:?}", f[1]);
        assert!(close(f[2], Vec3::new(1.0, 2.0, 18.0)), "b: {:?}", f[2]);
        assert!(close(f[3], Vec3::new(1.0, 3.0, 3.0)), "c (position channels replace OFFSET): {:?}", f[3]);
        // Frame 1: rest pose, but c's channels still replace its offset with zero.
        let f = m.frame(1);
        assert!(close(f[2], Vec3::new(0.0, 10.0, 5.0)), "{:?}", f[2]);
        assert!(close(f[3], Vec3::ZERO), "{:?}", f[3]);
        assert_eq!(s.offsets()[3], Vec3::splat(100.0), "the skeleton keeps the OFFSET");
        let orders: Vec<_> = layout.joints.iter().map(|j| (j.rotation_order, j.has_position)).collect();
        assert_eq!(orders, vec![(EulerOrder::ZYX, true), (EulerOrder::ZXY, false), (EulerOrder::ZXY, false), (EulerOrder::ZXY, true)]);
    }

    #[test]
    fn write_read_reproduces_hand_example_with_and_without_layout() {
        let (m, layout) = read_bvh_layout(HAND, "hand.bvh").unwrap();
        for l in [Some(&layout), None] {
            let text = write_bvh(&m, l);
            let (back, back_layout) = read_bvh_layout(&text, "written.bvh").unwrap_or_else(|e| panic!("{e}\n{text}"));
            if l.is_some() {
                assert_eq!(back_layout, layout);
            } else {
                assert_eq!(back_layout, BvhLayout::default_for(&m));
                assert!(back_layout.joints[3].has_position, "c moves off its offset, so it keeps position channels");
                assert!(!back_layout.joints[1].has_position);
            }
            assert_eq!(back.skeleton.names(), m.skeleton.names());
            assert_eq!(back.fps, 30.0);
            for (a, b) in back.positions().iter().zip(m.positions()) {
                assert!(close(*a, *b), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn writer_end_site_and_header() {
        let (m, _) = read_bvh_layout(HAND, "hand.bvh").unwrap();
        let text = write_bvh(&m, None);
        // b's own offset is (0, 0, 5): its End Site continues it at half length.
        assert!(text.contains("End Site\n\t\t\t{\n\t\t\t\tOFFSET 0.000000 0.000000 2.500000\n"), "{text}");
        assert!(text.contains("Frame Time: 0.03333333\n"), "{text}");
        assert!(text.contains("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"));
        assert!(text.contains("Frames: 2\n"));
    }

    #[test]
    fn angles_are_continuous_over_full_turns_and_gimbal() {
        // One joint spinning about Y through 720 degrees, and one passing the ZXY gimbal pole
        // (X = 90) so the principal Euler solution would flip.
        let s = Arc::new(Skeleton::new(vec!["r".into(), "j".into()], vec![None, Some(0)], vec![Vec3::ZERO, Vec3::Y], 0.01).unwrap());
        let poses: Vec<LocalPose> = (0..=144)
            .map(|t| {
                let a = t as f32 * 5.0;
                LocalPose {
                    rotations: vec![
                        Quat::from_rotation_y(a.to_radians()),
                        euler_to_quat(EulerOrder::ZXY, [20.0, 60.0 + t as f32 * 0.37, 30.0]),
                    ],
                    translations: vec![Vec3::ZERO, Vec3::Y],
                }
            })
            .collect();
        let m = Motion::from_local_poses(s, 30.0, poses);
        let text = write_bvh(&m, None);
        let frames: Vec<Vec<f64>> = text
            .lines()
            .skip_while(|l| !l.starts_with("Frame Time"))
            .skip(1)
            .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(frames.len(), 145);
        for w in frames.windows(2) {
            for k in 3..9 {
                assert!((w[1][k] - w[0][k]).abs() < 10.0, "channel {k} jumps: {:?} -> {:?}", w[0], w[1]);
            }
        }
        // The spin accumulates instead of wrapping.
        assert!((frames[144][5] - 720.0).abs() < 1e-3, "root Y should reach 720: {:?}", frames[144]);
        let back = read_bvh(&text, "spin.bvh").unwrap();
        for (a, b) in back.positions().iter().zip(m.positions()) {
            assert!(close(*a, *b), "{a} vs {b}");
        }
        for (pa, pb) in back.local_poses.unwrap().iter().zip(m.local_poses.as_ref().unwrap()) {
            for (qa, qb) in pa.rotations.iter().zip(&pb.rotations) {
                assert!(qa.dot(*qb).abs() > 1.0 - 1e-6);
            }
        }
    }

    #[test]
    fn alternate_euler_solution_is_the_same_rotation() {
        for order in [EulerOrder::XYZ, EulerOrder::XZY, EulerOrder::YXZ, EulerOrder::YZX, EulerOrder::ZXY, EulerOrder::ZYX] {
            let [a, b, c] = [31.0f32, -47.0, 112.0];
            let q = euler_to_quat(order, [a, b, c]);
            let alt = euler_to_quat(order, [a + 180.0, 180.0 - b, c + 180.0]);
            assert!(q.dot(alt).abs() > 1.0 - 1e-6, "{order:?}");
        }
    }

    #[test]
    fn writes_from_positions_when_no_local_poses() {
        let m = read_bvh(HAND, "hand.bvh").unwrap();
        // Drop c's moving translation by only keeping root, a, b (rest offsets below the root).
        let keep = m.subset(&[0, 1, 2]);
        assert!(keep.local_poses.is_none());
        let back = read_bvh(&write_bvh(&keep, None), "solved.bvh").unwrap();
        for (a, b) in back.positions().iter().zip(keep.positions()) {
            assert!(close(*a, *b), "{a} vs {b}");
        }
    }

    #[test]
    fn fps_snaps_and_keeps_odd_rates() {
        let with_time = |t: &str| HAND.replace("0.0333333", t);
        assert_eq!(read_bvh(&with_time("0.00833333"), "f").unwrap().fps, 120.0);
        let odd = read_bvh(&with_time("0.0333667"), "f").unwrap().fps;
        assert!((odd - 29.97).abs() < 0.01, "{odd}");
    }

    #[test]
    fn empty_and_whitespace_files() {
        for text in ["", "   \n\t\r\n", "\u{feff}"] {
            let e = err(text);
            assert!(e.message.contains("empty"), "{e}");
        }
    }

    #[test]
    fn missing_sections() {
        let e = err("MOTION\nFrames: 1\nFrame Time: 0.1\n0\n");
        assert!(e.message.contains("missing HIERARCHY"), "{e}");
        let e = err("ROOT a\n{\nOFFSET 0 0 0\n}\n");
        assert!(e.message.contains("missing HIERARCHY"), "{e}");
        let hierarchy_only = HAND.split("MOTION").next().unwrap();
        let e = err(hierarchy_only);
        assert!(e.message.contains("missing MOTION"), "{e}");
        let e = err(&HAND.replace("Frames:\t2\r\n", ""));
        assert!(e.message.contains("expected 'Frames:'"), "{e}");
        let e = err(&HAND.replace("Frame Time:\t0.0333333\r\n", ""));
        assert!(e.message.contains("expected 'Frame Time:'"), "{e}");
        let e = err("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n");
        assert!(e.message.contains("no ROOT"), "{e}");
    }

    #[test]
    fn bad_numbers_name_line_and_token() {
        let e = err(&HAND.replace("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n", "0 0 0 0 0 0 0 0 0 0 0 0 0 0 1.2.3 0 0 0\r\n"));
        assert_eq!(line_of(&e), 34);
        assert!(e.message.contains("'1.2.3'") && e.message.contains("value 15"), "{e}");
        let e = err(&HAND.replace("OFFSET 0 10 0", "OFFSET 0 1x 0"));
        assert_eq!(line_of(&e), 8);
        assert!(e.message.contains("'1x'"), "{e}");
        let e = err(&HAND.replace("Frames:\t2", "Frames:\ttwo"));
        assert!(e.message.contains("'two'"), "{e}");
        let e = err(&HAND.replace("OFFSET 0 10 0", "OFFSET 0 10"));
        assert!(e.message.contains("OFFSET needs 3 numbers"), "{e}");
    }

    #[test]
    fn wrong_value_count_says_expected_and_found() {
        let e = err(&HAND.replace("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n", "0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n"));
        assert_eq!(line_of(&e), 34);
        assert!(e.message.contains("17 values") && e.message.contains("expected 18"), "{e}");
    }

    #[test]
    fn fewer_frames_than_declared_says_how_many() {
        let e = err(&HAND.replace("Frames:\t2", "Frames:\t5"));
        assert!(e.message.contains("5") && e.message.contains("only 2 frame lines"), "{e}");
        let e = err(&HAND.replace("Frames:\t2", "Frames:\t1"));
        assert!(e.message.contains("more frame lines"), "{e}");
    }

    #[test]
    fn unknown_channel_and_bad_count() {
        let e = err(&HAND.replace("Zrotation Xrotation Yrotation\r\n\t\tJOINT b", "Zrotation Wrotation Yrotation\r\n\t\tJOINT b"));
        assert_eq!(line_of(&e), 9);
        assert!(e.message.contains("unknown channel 'Wrotation'"), "{e}");
        let e = err(&HAND
            .replace("CHANNELS 3 Zrotation Xrotation Yrotation\r\n\t\tJOINT b", "CHANNELS 9 Zrotation Xrotation Yrotation\r\n\t\tJOINT b"));
        assert!(e.message.contains("bad channel count '9'"), "{e}");
        let e = err(&HAND
            .replace("CHANNELS 3 Zrotation Xrotation Yrotation\r\n\t\tJOINT b", "CHANNELS 3 Zrotation Zrotation Yrotation\r\n\t\tJOINT b"));
        assert!(e.message.contains("twice"), "{e}");
    }

    #[test]
    fn unbalanced_braces() {
        let e = err(&HAND.replacen("\t}\r\n}\r\nMOTION", "\t}\r\nMOTION", 1));
        assert!(e.message.contains("unbalanced braces") && e.message.contains("joint 'root'"), "{e}");
        let e = err(&HAND.replacen("}\r\nMOTION", "}\r\n}\r\nMOTION", 1));
        assert!(e.message.contains("unbalanced braces: '}' closes nothing"), "{e}");
        let e = err(&HAND.replacen("\tJOINT a\r\n\t{", "\tJOINT a\r\n", 1));
        assert!(e.message.contains("expected '{'"), "{e}");
    }

    #[test]
    fn frame_time_must_be_positive() {
        for t in ["0", "-0.1", "0.0", "nan", "inf"] {
            let e = err(&HAND.replace("0.0333333", t));
            assert!(e.message.contains("frame time"), "{t}: {e}");
            assert_eq!(line_of(&e), 32);
        }
    }

    #[test]
    fn nan_and_inf_values_are_rejected() {
        for v in ["NaN", "inf", "-infinity", "1e40"] {
            let e = err(&HAND.replace("1\t2\t3\t90", &format!("1\t{v}\t3\t90")));
            assert_eq!(line_of(&e), 33);
            assert!(e.message.contains("not finite"), "{v}: {e}");
        }
        let e = err(&HAND.replace("OFFSET 0 10 0", "OFFSET 0 nan 0"));
        assert!(e.message.contains("finite"), "{e}");
    }

    #[test]
    fn every_truncation_is_handled() {
        // Every prefix either reads (cut at a line end after enough frames) or is an error
        // naming the file; none panics.
        let mut errors = 0;
        for (cut, _) in HAND.char_indices() {
            match read_bvh(&HAND[..cut], "cut.bvh") {
                Ok(m) => assert_eq!(m.frames(), 2, "prefix of {cut} bytes read with a wrong frame count"),
                Err(e) => {
                    assert_eq!(e.file, "cut.bvh");
                    errors += 1;
                }
            }
        }
        // Only cuts inside the last frame line's trailing whitespace or its last number may read.
        assert!(errors > HAND.len() - 40, "{errors} of {}", HAND.len());
    }

    #[test]
    fn garbage_is_an_error() {
        let mut state = 12345u64;
        let alphabet = b" \n\t{}0123456789.-eHIERARCHYROOTJOINTMOTIONFrames:";
        for len in [1, 7, 100, 3000] {
            let text: String = (0..len)
                .map(|_| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    char::from(alphabet[(state >> 33) as usize % alphabet.len()])
                })
                .collect();
            let e = err(&text);
            assert!(!e.message.is_empty());
        }
        let e = err("\u{0}\u{1}binary\u{7f}");
        assert!(e.message.contains("missing HIERARCHY"), "{e}");
    }
}
