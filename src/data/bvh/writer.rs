//! The BVH writer.

use std::fmt::Write as _;

use glam::{Quat, Vec3};

use super::layout::{usable_poses, BvhLayout};
use crate::motion::{quat_to_euler, solve_local_poses, EulerOrder, LocalPose, Motion};

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
