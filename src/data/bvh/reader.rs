//! The BVH reader: the HIERARCHY's joints, offsets and channels, then the MOTION section's
//! frames, every problem a [`FormatError`] naming the file and line.

use std::sync::Arc;

use glam::{DQuat, Vec3};

use super::layout::{BvhLayout, JointChannels};
use crate::data::FormatError;
use crate::motion::{clipped as clip, EulerOrder, LocalPose, Motion, Skeleton};

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

fn snap_fps(fps: f64) -> f32 {
    let r = fps.round();
    if r >= 1.0 && (fps - r).abs() <= 1e-4 * r {
        r as f32
    } else {
        fps as f32
    }
}
