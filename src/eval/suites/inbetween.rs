//! `glocal eval --suite inbetween`: keys filling a gap of real motion, by the LaFAN1 protocol
//! (Harvey et al., "Robust Motion In-betweening", SIGGRAPH 2020). A take starts from a real
//! held-out clip as a user starts one (`--init clip:FILE@F`), a later frame of the same clip
//! is its key (`--key T=clip:FILE@K,root`), and the frames between are scored against the
//! real ones, beside zero-velocity and linear interpolation on the same cases.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use glam::Vec3;
use serde_json::{json, Value};

use super::context::SuiteContext;
use crate::eval::constraints::{frame_jerk, NEAR_KEY_SECONDS};
use crate::eval::metrics::mean;
use crate::eval::table::{fixed, Markdown, Table};
use crate::motion::Motion;
use crate::data::npy::motion_to_npy;
use crate::data::write::write_atomic;
use crate::model::corpus::{Corpus, Track};
use crate::model::glocal::GlocalModel;
use crate::synth::init::FileStart;
use crate::synth::{generate, GenerateOptions, InitPose, Key, KeySource, Segment, Timeline};

const DEFINITIONS: &str = "Per model, takes started from held-out clips (h36m: subject S11; Bandai: styles tired and musical), written as NPY files on the model's skeleton: `--init clip:FILE@F`, and a root-fixing key from the same file `GAP` after the last starting pose (`--key T=clip:FILE@K,root`), the take's class the clip's. **L2P**: mean joint distance to the real frames over the gap (the frames between the last starting pose and the key), in the take's world and relative to the root; **NPSS**: the normalised power spectrum similarity of the root-relative joints over the gap (0 = the real rhythm); against linear interpolation of every joint from the last starting pose to the key's real pose and zero-velocity (the last starting pose held). **Key error**: the take's frame at the key against the real frame, mean joint distance per case; **given poses**: the largest joint distance of the take's frames over the starting poses from the real ones, per case; **jerk at the key**: the peak per-frame jerk of any joint within 0.5 s of the key, over the real frames' peak there, per case; **jerk over the gap**: the mean over the gap's frames of each frame's peak joint jerk, over the real frames', per case.\n";

/// The gaps between the last given pose and the key: LaFAN1's shortest and two longer ones.
const GAPS: [Gap; 3] = [Gap::Frames(6), Gap::Seconds(1.0), Gap::Seconds(2.0)];

/// Cases per gap (a start frame of a held-out clip each), and in a quick run.
const CASES: usize = 64;
const QUICK_CASES: usize = 12;

/// Seconds of take after the key, so the key is not the take's last frame.
const AFTER_KEY_SECONDS: f32 = 1.0;

#[derive(Clone, Copy, Debug)]
enum Gap {
    Frames(usize),
    Seconds(f32),
}

impl Gap {
    fn frames(self, fps: f32) -> usize {
        match self {
            Gap::Frames(n) => n,
            Gap::Seconds(s) => (s * fps).round() as usize,
        }
    }

    fn label(self) -> String {
        match self {
            Gap::Frames(n) => format!("{n} frames"),
            Gap::Seconds(s) => format!("{s} s"),
        }
    }
}

/// What one way of filling the gap scores, summed over cases.
#[derive(Clone, Copy, Debug, Default)]
struct GapScores {
    /// Mean joint distance to the real frames over the gap (cm), in the world and relative
    /// to the root.
    l2p_global: f64,
    l2p_root: f64,
    npss: f64,
    cases: usize,
}

impl GapScores {
    fn add(&mut self, filled: &[Vec3], real: &[Vec3], joints: usize, cm: f32) {
        self.l2p_global += mean_distance(filled, real) as f64 * cm as f64;
        self.l2p_root += mean_distance(&root_relative(filled, joints), &root_relative(real, joints)) as f64 * cm as f64;
        self.npss += npss(&root_relative(filled, joints), &root_relative(real, joints), joints) as f64;
        self.cases += 1;
    }

    fn mean(&self) -> [f64; 3] {
        let n = self.cases.max(1) as f64;
        [self.l2p_global / n, self.l2p_root / n, self.npss / n]
    }

    fn json(&self) -> Value {
        let [global, root, npss] = self.mean();
        json!({"l2p_global_cm": global, "l2p_root_cm": root, "npss": npss, "cases": self.cases})
    }
}

/// Largest and mean over cases of a per-case score (an error in cm, a jerk ratio).
#[derive(Clone, Copy, Debug, Default)]
struct Spread {
    sum: f64,
    max: f64,
    cases: usize,
}

impl Spread {
    fn add(&mut self, v: f32) {
        self.sum += v as f64;
        self.max = self.max.max(v as f64);
        self.cases += 1;
    }

    fn mean(&self) -> f64 {
        self.sum / self.cases.max(1) as f64
    }

    fn json(&self) -> Value {
        json!({"mean": self.mean(), "max": self.max})
    }
}

/// One gap's results on one model.
#[derive(Default)]
struct GapRow {
    keyed: GapScores,
    zero_velocity: GapScores,
    linear: GapScores,
    /// The take's key frame against the real one: mean joint distance per case.
    key: Spread,
    /// The given starting poses as the take shows them: the largest joint distance per case.
    context: Spread,
    /// The peak jerk of the take's frames within [`NEAR_KEY_SECONDS`] of the key over the real
    /// frames' there, per case.
    arrival_jerk: Spread,
    /// The mean over the gap of each frame's peak joint jerk, over the real frames', per case.
    gap_jerk: Spread,
}

pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let mut md = Markdown::new(DEFINITIONS);
    let mut models = Vec::new();
    for &dataset in &ctx.datasets {
        models.push(one_model(&ctx.model_dir(dataset), ctx, &mut md, log)?);
    }
    Ok((md, json!({"models": models})))
}

/// The suite on the model in `model_dir`; the evaluation cache holds the clips written as
/// files for the takes to start from.
fn one_model(model_dir: &Path, ctx: &SuiteContext, md: &mut Markdown, log: &mut dyn FnMut(&str)) -> Result<Value> {
    let model = GlocalModel::load(model_dir)?;
    let dataset = model.spec.dataset.parse()?;
    log(&format!("inbetween: {dataset} held-out clips"));
    let corpus = Corpus::load(dataset, &ctx.options.data, model.spec.stride, 3)?;
    let dir = ctx.options.cache.join(format!("inbetween-{dataset}"));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let cases = cases(&model, &corpus.test, if ctx.options.quick { QUICK_CASES } else { CASES });
    let mut rows: Vec<GapRow> = GAPS.iter().map(|_| GapRow::default()).collect();
    for (k, &(track, first)) in cases.iter().enumerate() {
        let file = clip_file(&dir, &corpus.test[track], track)?;
        for (gap, row) in GAPS.iter().zip(&mut rows) {
            score_case(&model, &ctx.generation, &corpus.test[track], &file, first, gap.frames(model.spec.fps), row)?;
        }
        if k % 16 == 15 {
            log(&format!("inbetween: {dataset} {} of {} cases", k + 1, cases.len()));
        }
    }
    Ok(report(&model, &rows, md))
}

/// Start frames spread over the held-out clips long enough for the longest gap, round robin
/// so every clip counts before any counts twice.
fn cases(model: &GlocalModel, tracks: &[Track], wanted: usize) -> Vec<(usize, usize)> {
    let spec = &model.spec;
    let longest = GAPS.iter().map(|g| g.frames(spec.fps)).max().unwrap_or(0);
    let need = spec.stride * (spec.block_len + 1) + longest + (AFTER_KEY_SECONDS * spec.fps) as usize + 1;
    let mut per_track: Vec<Vec<(usize, usize)>> = tracks
        .iter()
        .enumerate()
        .filter(|(_, t)| t.motion.frames() > need)
        .map(|(k, t)| (0..t.motion.frames() - need).step_by(need).map(|f| (k, f)).collect())
        .collect();
    let mut out = Vec::new();
    while out.len() < wanted && per_track.iter().any(|c| !c.is_empty()) {
        for c in per_track.iter_mut().filter(|c| !c.is_empty()) {
            if out.len() < wanted {
                out.push(c.remove(0));
            }
        }
    }
    out
}

/// The clip as an NPY file on the model's skeleton, as a user would start a take from it
/// (named by its joints too: a model of another skeleton writes its own).
fn clip_file(dir: &Path, track: &Track, index: usize) -> Result<PathBuf> {
    let path = dir.join(format!("clip-{index}-{}j.npy", track.motion.joints()));
    if !path.exists() {
        write_atomic(&path, &motion_to_npy(&track.motion))?;
    }
    Ok(path)
}

/// One case: a take started at `first` of the clip, keyed `gap` frames after its last given
/// pose with the clip's own frame (the suites' generation options otherwise), against the
/// real frames and the baselines.
fn score_case(model: &GlocalModel, generation: &GenerateOptions, track: &Track, file: &Path, first: usize, gap: usize, row: &mut GapRow) -> Result<()> {
    let spec = &model.spec;
    let (s, joints) = (spec.stride, spec.layout.joints());
    let cm = 100.0 * spec.layout.skeleton.meters_per_unit();
    // The take's frame 0 is the clip's first + s; its given poses end one observed span on.
    let last_given = spec.observed_span();
    let key_frame = last_given + gap;
    let seconds = key_frame as f32 / spec.fps;
    let key = Key { seconds, source: KeySource::Init(InitPose::file(file.to_path_buf(), first + s + key_frame)), fix_root: true };
    let class = spec.classes[track.class].clone();
    let opts = GenerateOptions {
        timeline: Timeline { segments: vec![Segment::new(class, seconds + AFTER_KEY_SECONDS)] },
        init: InitPose::file(file.to_path_buf(), first),
        keys: vec![key],
        ..generation.clone()
    };
    let take = generate(model, &opts, &mut |_| true)?.motion;
    let start = FileStart::of(model, &track.motion, first);
    let real = |f: usize| start.apply(track.motion.frame(first + s + f));
    let frames = |m: &dyn Fn(usize) -> Vec<Vec3>, range: std::ops::Range<usize>| -> Vec<Vec3> { range.flat_map(m).collect() };
    let gap_frames = last_given + 1..key_frame;
    let truth = frames(&real, gap_frames.clone());
    row.keyed.add(&frames(&|f| take.frame(f).to_vec(), gap_frames.clone()), &truth, joints, cm);
    let (from, to) = (real(last_given), real(key_frame));
    row.zero_velocity.add(&frames(&|_| from.clone(), gap_frames.clone()), &truth, joints, cm);
    let lerp = |f: usize| {
        let w = (f - last_given) as f32 / gap as f32;
        from.iter().zip(&to).map(|(a, b)| a.lerp(*b, w)).collect::<Vec<Vec3>>()
    };
    row.linear.add(&frames(&lerp, gap_frames.clone()), &truth, joints, cm);
    row.key.add(mean_distance(take.frame(key_frame), &to) * cm);
    let context = (0..=last_given).map(|f| max_distance(take.frame(f), &real(f))).fold(0.0, f32::max);
    row.context.add(context * cm);
    // The jerk of a frame spans it and the three after it.
    let half = (NEAR_KEY_SECONDS * spec.fps).round() as usize;
    let near = key_frame.saturating_sub(half)..(key_frame + half + 3).min(take.frames());
    let real_near = Motion::from_positions(take.skeleton.clone(), take.fps, frames(&real, near.clone()));
    row.arrival_jerk.add((peak_jerk(&take.slice(near.start, near.end)) / peak_jerk(&real_near).max(f32::EPSILON)) as f32);
    let real_gap = Motion::from_positions(take.skeleton.clone(), take.fps, truth);
    row.gap_jerk.add(mean_jerk(&take.slice(gap_frames.start, gap_frames.end)) / mean_jerk(&real_gap).max(f32::EPSILON));
    Ok(())
}

/// The mean over frames of the largest per-frame jerk of any joint (m/s^3).
fn mean_jerk(m: &Motion) -> f32 {
    mean(&frame_jerk(m)) as f32
}

/// The largest per-frame jerk of any joint (m/s^3).
fn peak_jerk(m: &Motion) -> f32 {
    frame_jerk(m).into_iter().fold(0.0, f32::max)
}

fn report(model: &GlocalModel, rows: &[GapRow], md: &mut Markdown) -> Value {
    md.text(&format!("\n**{}**\n\n", model.spec.dataset));
    let mut table = Table::new(["gap", "L2P global (cm): keyed / linear / zero-velocity", "L2P root-relative (cm)", "NPSS", "key error mean / max (cm)", "given poses max (cm): mean / worst", "jerk at the key over real: mean / worst", "jerk over the gap over real: mean / worst"]);
    let mut json_rows = Vec::new();
    for (gap, row) in GAPS.iter().zip(rows) {
        let (k, l, z) = (row.keyed.mean(), row.linear.mean(), row.zero_velocity.mean());
        let three = |i: usize, d: usize| format!("{} / {} / {}", fixed(k[i], d), fixed(l[i], d), fixed(z[i], d));
        table.row([
            format!("{} ({} cases)", gap.label(), row.keyed.cases),
            three(0, 2),
            three(1, 2),
            three(2, 3),
            format!("{} / {}", fixed(row.key.mean(), 2), fixed(row.key.max, 2)),
            format!("{} / {}", fixed(row.context.mean(), 2), fixed(row.context.max, 2)),
            format!("{}x / {}x", fixed(row.arrival_jerk.mean(), 2), fixed(row.arrival_jerk.max, 2)),
            format!("{}x / {}x", fixed(row.gap_jerk.mean(), 2), fixed(row.gap_jerk.max, 2)),
        ]);
        json_rows.push(json!({
            "gap": gap.label(), "keyed": row.keyed.json(), "linear": row.linear.json(), "zero_velocity": row.zero_velocity.json(),
            "key_error_cm": row.key.json(), "given_poses_error_cm": row.context.json(), "arrival_jerk_over_real": row.arrival_jerk.json(), "gap_jerk_over_real": row.gap_jerk.json(),
        }));
    }
    md.table(table);
    json!({"model": model.spec.dataset, "gaps": json_rows})
}

/// Mean distance between corresponding points.
fn mean_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).sum::<f32>() / a.len().max(1) as f32
}

fn max_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max)
}

/// Each frame's joints relative to its root (the root itself left out).
fn root_relative(frames: &[Vec3], joints: usize) -> Vec<Vec3> {
    frames.chunks_exact(joints).flat_map(|f| f[1..].iter().map(move |p| *p - f[0])).collect()
}

/// The normalised power spectrum similarity (Gopalakrishnan et al. 2019) of `filled` against
/// `real` (`per_frame` points a frame): per coordinate, the earth mover's distance between
/// the two normalised power spectra over time, weighted by the real coordinate's power.
fn npss(filled: &[Vec3], real: &[Vec3], joints: usize) -> f32 {
    let per_frame = joints - 1;
    let frames = real.len() / per_frame.max(1);
    if frames < 2 {
        return 0.0;
    }
    let series = |points: &[Vec3], c: usize| -> Vec<f32> { (0..frames).map(|f| points[f * per_frame + c / 3][c % 3]).collect() };
    let (mut total, mut weights) = (0.0f64, 0.0f64);
    for c in 0..per_frame * 3 {
        let (p, r) = (power_spectrum(&series(filled, c)), power_spectrum(&series(real, c)));
        let (sp, sr) = (p.iter().sum::<f32>(), r.iter().sum::<f32>());
        if sr <= 0.0 || sp <= 0.0 {
            continue;
        }
        let (mut cp, mut cr, mut emd) = (0.0f32, 0.0f32, 0.0f32);
        for (a, b) in p.iter().zip(&r) {
            cp += a / sp;
            cr += b / sr;
            emd += (cp - cr).abs();
        }
        total += emd as f64 * sr as f64;
        weights += sr as f64;
    }
    if weights > 0.0 {
        (total / weights) as f32
    } else {
        0.0
    }
}

/// Squared magnitudes of the discrete Fourier transform of `x` (a gap is at most a few dozen
/// frames, so the plain transform is cheap).
fn power_spectrum(x: &[f32]) -> Vec<f32> {
    let n = x.len();
    (0..n / 2 + 1)
        .map(|k| {
            let (mut re, mut im) = (0.0f32, 0.0f32);
            for (i, v) in x.iter().enumerate() {
                let a = -2.0 * std::f32::consts::PI * (k * i) as f32 / n as f32;
                re += v * a.cos();
                im += v * a.sin();
            }
            re * re + im * im
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Identical motion scores zero NPSS, and a motion at another frequency scores more.
    #[test]
    fn npss_tells_a_different_rhythm() {
        let wave = |freq: f32| -> Vec<Vec3> { (0..30).flat_map(|f| [Vec3::ZERO, Vec3::new((f as f32 * freq).sin(), 0.0, 0.0)]).collect() };
        let real = root_relative(&wave(0.3), 2);
        assert!(npss(&real, &real, 2) < 1e-6);
        assert!(npss(&root_relative(&wave(1.2), 2), &real, 2) > 0.1);
    }
}
