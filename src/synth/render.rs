//! A contact sheet: frames of a take drawn side by side as stick figures, each in its
//! segment's class colour, so a person can look at a clip without the studio.

use std::path::Path;

use anyhow::Result;
use glam::Vec3;
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_filled_circle_mut, draw_line_segment_mut};

use super::SegmentSpan;
use crate::data::write::write_atomic;
use crate::motion::{floor_height, JointRoles, Motion};

/// A palette of distinct colours for classes, shared by the sheet and the studio.
pub fn class_color(class: usize) -> [u8; 3] {
    PALETTE[class % PALETTE.len()]
}

/// How many times the palette has come round before `class`'s colour: classes of the same
/// colour (the model of everything has 26) tell themselves apart by it, in the studio's seed
/// map by the marker's shape.
pub fn palette_round(class: usize) -> usize {
    class / PALETTE.len()
}

// Tableau's 10 categorical colours (its grey replaced by teal: grey is how the studio shows a
// segment of an unknown class), then two more distinct ones.
const PALETTE: [[u8; 3]; 12] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [0, 140, 110],
    [188, 189, 34],
    [23, 190, 207],
    [255, 215, 0],
    [0, 0, 139],
];

pub struct SheetOptions {
    pub columns: usize,
    pub rows: usize,
    pub cell: u32,
}

impl Default for SheetOptions {
    fn default() -> Self {
        Self { columns: 8, rows: 3, cell: 160 }
    }
}

/// Draws `columns x rows` evenly spaced frames, viewed from the front-right, each figure
/// centred on its own root so the sheet reads as poses over time.
pub fn contact_sheet(motion: &Motion, segments: &[SegmentSpan], opts: &SheetOptions) -> RgbImage {
    let n = opts.columns * opts.rows;
    let mut img = RgbImage::from_pixel(opts.columns as u32 * opts.cell, opts.rows as u32 * opts.cell, Rgb([250, 250, 247]));
    let height = body_height(motion);
    let view = glam::Quat::from_rotation_y(-0.5);
    let head = JointRoles::new(&motion.skeleton).ok().map(|r| r.head_top());
    for k in 0..n.min(motion.frames()) {
        let t = if n > 1 { k * (motion.frames() - 1) / (n - 1) } else { 0 };
        let class = segments.iter().find(|s| t >= s.start_frame && t < s.end_frame.max(s.start_frame + 1)).map_or(0, |s| s.class);
        let color = Rgb(class_color(class));
        let (cx, cy) = ((k % opts.columns) as f32 * opts.cell as f32, (k / opts.columns) as f32 * opts.cell as f32);
        let frame = motion.frame(t);
        let ground = floor_height(frame);
        let scale = 0.8 * opts.cell as f32 / height;
        let project = |p: Vec3| {
            let q = view * (p - Vec3::new(frame[0].x, ground, frame[0].z));
            (cx + opts.cell as f32 * 0.5 + q.x * scale, cy + opts.cell as f32 * 0.92 - q.y * scale)
        };
        draw_line_segment_mut(&mut img, (cx + 8.0, cy + opts.cell as f32 * 0.92), (cx + opts.cell as f32 - 8.0, cy + opts.cell as f32 * 0.92), Rgb([200, 200, 195]));
        for (j, parent) in motion.skeleton.parents().iter().enumerate() {
            if let Some(p) = parent {
                draw_line_segment_mut(&mut img, project(frame[*p]), project(frame[j]), color);
            }
        }
        if let Some(head) = head {
            let top = project(frame[head]);
            draw_filled_circle_mut(&mut img, (top.0 as i32, top.1 as i32), 3, color);
        }
    }
    img
}

/// The take's standing height: the largest vertical extent of any frame.
fn body_height(motion: &Motion) -> f32 {
    let mut h: f32 = 0.0;
    for t in (0..motion.frames()).step_by(10.max(motion.frames() / 50)) {
        let f = motion.frame(t);
        let (lo, hi) = f.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p.y), hi.max(p.y)));
        h = h.max(hi - lo);
    }
    h.max(1e-6)
}

/// Renders a contact sheet to a PNG file (atomically).
pub fn write_contact_sheet(motion: &Motion, segments: &[SegmentSpan], path: &Path, opts: &SheetOptions) -> Result<()> {
    let img = contact_sheet(motion, segments, opts);
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)?;
    write_atomic(path, &bytes)
}
