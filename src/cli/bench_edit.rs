//! `glocal bench edit`: what an edit late in a five-minute take costs, against generating
//! the edited take whole, in the same run (issue 38). Three ways to the edited take:
//! - **whole**: the edited request generated from nothing (what every edit cost before);
//! - **resumed**: the same request, resuming the take before it (`synth::TakeCache`), as the
//!   command line and the studio do for a request that holds no frames; the take is checked
//!   to be the whole one bit for bit;
//! - **studio edit**: the studio's request for a one-segment edit, every other segment held
//!   from the take before (issue 36), so only the edited segment and its joins are made.

use std::path::Path;
use std::time::Instant;

use anyhow::{ensure, Result};
use serde::Serialize;

use crate::model::glocal::GlocalModel;
use crate::synth::held::{hold_segments, Kept};
use crate::synth::{generate_with, GenerateOptions, Generated, InitPose, TakeCache};

#[derive(Serialize)]
pub struct EditRun {
    /// Which segment was edited, and where in the take it starts (fraction of its length).
    pub edit: String,
    pub starts_at: f32,
    pub whole_ms: f64,
    pub resumed_ms: f64,
    pub studio_ms: f64,
}

#[derive(Serialize)]
pub struct EditBench {
    pub model: String,
    pub timeline: String,
    pub repeats: usize,
    pub runs: Vec<EditRun>,
}

/// A 300 s timeline of six segments, the last two 30 s each: their edits fall in the take's
/// last 20%.
fn five_minutes(model: &GlocalModel) -> GenerateOptions {
    let c = &model.spec.classes;
    let class = |k: usize| c[k % c.len()].clone();
    let lengths = [60, 60, 60, 60, 30, 30];
    let timeline = lengths.iter().enumerate().map(|(k, s)| format!("{}:{s}", class(k * 3))).collect::<Vec<_>>().join(",");
    GenerateOptions { timeline: timeline.parse().expect("a valid timeline"), init: InitPose::SeedClass { class: class(0), variant: 0 }, ..Default::default() }
}

fn timed(model: &GlocalModel, opts: &GenerateOptions, cache: &mut TakeCache) -> Result<(Generated, f64)> {
    let start = Instant::now();
    let take = generate_with(model, opts, cache, &mut |_: f32| true)?;
    Ok((take, start.elapsed().as_secs_f64() * 1e3))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn bench_edit(dir: &Path, repeats: usize) -> Result<EditBench> {
    let model = GlocalModel::load(dir)?;
    let before = five_minutes(&model);
    let (take_before, _) = timed(&model, &before, &mut TakeCache::default())?;
    let frames = take_before.motion.frames() as f32;
    let mut runs = Vec::new();
    for k in [5, 4] {
        let mut edited = before.clone();
        edited.timeline.segments[k].class = model.spec.classes[(k * 3 + 1) % model.spec.classes.len()].clone();
        let kept: Vec<Kept> = (0..edited.timeline.segments.len()).filter(|&j| j != k).map(|j| Kept { before: j, after: j, whole: false }).collect();
        let studio = GenerateOptions { held: hold_segments(&model.spec, &take_before.motion, &take_before.segments, &edited, &kept)?, ..edited.clone() };
        let (mut whole, mut resumed, mut held) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..repeats {
            let (full, ms) = timed(&model, &edited, &mut TakeCache::default())?;
            whole.push(ms);
            let mut cache = TakeCache::default();
            timed(&model, &before, &mut cache)?;
            let (again, ms) = timed(&model, &edited, &mut cache)?;
            resumed.push(ms);
            ensure!(again.motion.positions() == full.motion.positions() && again.contacts == full.contacts, "the resumed take differs from the whole one");
            held.push(timed(&model, &studio, &mut TakeCache::default())?.1);
        }
        let starts_at = take_before.segments[k].start_frame as f32 / frames;
        runs.push(EditRun { edit: format!("segment {} of 6 ({})", k + 1, edited.timeline.segments[k].class), starts_at, whole_ms: median(whole), resumed_ms: median(resumed), studio_ms: median(held) });
    }
    Ok(EditBench { model: dir.display().to_string(), timeline: before.timeline.to_string(), repeats, runs })
}

impl EditBench {
    pub fn text(&self) -> String {
        let mut lines = vec![format!("{}: {} (300 s), median of {}", self.model, self.timeline, self.repeats)];
        for r in &self.runs {
            lines.push(format!(
                "edit of {} starting at {:.0}% of the take: whole {:.1} ms; resumed {:.1} ms ({:.2}x of whole, identical); studio edit, other segments held {:.1} ms ({:.2}x)",
                r.edit,
                r.starts_at * 100.0,
                r.whole_ms,
                r.resumed_ms,
                r.resumed_ms / r.whole_ms,
                r.studio_ms,
                r.studio_ms / r.whole_ms
            ));
        }
        lines.join("\n")
    }
}
