//! `glocal eval --suite motion`: how usable the motion is as it comes out, measured the same
//! way on the real test split and on generated takes, per class and class-balanced, for each
//! shipped model, everything resampled to [`COMMON_FPS`] and measured in metres.
//! The definitions are in [`DEFINITIONS`], printed next to the table.

use std::collections::{BTreeMap, HashMap};

use anyhow::{bail, Result};
use glam::Vec3;
use serde_json::{json, Value};

use super::suites::{model_dir, SuiteOptions};
use super::table::{fixed_or, Markdown, Table};
use crate::data::registry::Dataset;
use crate::model::corpus::{Corpus, Track};
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, Motion, Side};
use crate::synth::{generate, GenerateOptions, InitPose, Segment, Timeline};

/// Every take, real or generated, is resampled to this rate before it is measured.
pub const COMMON_FPS: f32 = 30.0;
/// A foot joint this close to the floor is in contact (GMD's 5 cm); the lowest one farther
/// than this is floating.
const FLOOR_BAND_M: f32 = 0.05;
/// A foot joint in contact moving faster than this horizontally is skating (GMD).
const SKATE_SPEED: f32 = 0.5;
/// Windows for the ground drift and the jerk peaks, seconds.
const WINDOW_S: f32 = 2.0;
/// Transition peaks are looked for this close to a class boundary, seconds.
const TRANSITION_S: f32 = 1.0;
/// An exact repeat: every pairwise joint distance within this, metres...
const REPEAT_TOLERANCE_M: f32 = 0.005;
/// ...for longer than this, seconds, at a lag of at least this, seconds.
const REPEAT_MIN_S: f32 = 1.0;
const REPEAT_MIN_LAG_S: f32 = 1.0;
/// The take's floor: this quantile of its per-frame lowest foot height (a single dipping
/// frame does not set it).
const FLOOR_QUANTILE: f32 = 0.01;

pub const DEFINITIONS: &str = "Definitions (all at 30 fps, metres; the floor of a take is the 1st percentile of its per-frame lowest foot-joint height; foot joints are each leg's ankle, toe and toe tip; real takes are the test split's clips cut into pieces as long as the generated ones):
- **skating ratio** (GMD / OmniControl): the fraction of frame pairs in which some foot joint is under 5 cm in both frames (contact) and moves horizontally faster than 0.5 m/s; **contact** is the fraction of frame pairs with some foot joint in contact.
- **support speed**: the horizontal speed of the support point (the lowest foot joint, while it is within 5 cm of the floor), mean and median, cm/s.
- **floating**: the fraction of frames whose lowest foot joint is more than 5 cm above the floor. **ground drift**: the standard deviation, over a take's 2 s windows, of each window's lowest foot height (cm), averaged over takes.
- **jerk**: the magnitude of the third finite difference of every joint's world position times fps^3 (m/s^3), mean, median and 95th percentile over joints and frames; **per-frame jerk** (FlowMDM): the largest joint jerk of each frame, mean over frames; **window peak p95**: the 95th percentile over 2 s windows of the window's largest per-frame jerk.
- **block seams**: joint positions relative to the body root, speed (first difference) and acceleration (second difference) averaged over joints, by phase inside a GloGen block (generated: blocks counted from the end of the seed; real: the same grid from each piece's start). **seam ratio**: mean speed in the last sparse interval of a block (the one that crosses into the next block) over the mean of the block's other intervals; **seam acceleration**: acceleration at the block's first frame (the seam) over its mean over the block; **sparse-pose acceleration**: at frames where a sparse pose falls, over the mean.
- **transition peak**: in takes of two classes, the largest per-frame jerk within 1 s of the class boundary (mean over boundaries), against the same takes' 2 s windows elsewhere (mean of their peaks) and against the real test split's window peak p95.
- **joint speed**: mean speed of all joints (m/s); the ratio is generated over real, per class.
- **exact repeat**: in one long single-class take per class, the longest stretch (s) of poses whose pairwise joint distances (heading-invariant) all match those at some lag >= 1 s within 5 mm, counted when longer than 1 s; real: each whole test clip.";

/// How many takes the suite generates, and how long.
#[derive(Clone, Debug)]
pub struct MotionSuiteConfig {
    /// Seed-bank windows per class, each with every noise seed; `None` is every window of the
    /// class's bank. The bank is in clip order, which for Bandai is its styles in alphabetical
    /// order: the first three byebye windows are all the style "active", which waves at 0.66
    /// m/s against a training median of 0.11, so a few first windows are not a fair sample.
    pub variants: Option<usize>,
    pub seeds: Vec<u64>,
    /// Seconds of each scored single-class take (after the seed).
    pub take_seconds: f32,
    /// Seconds of each of the two segments of a transition take.
    pub segment_seconds: f32,
    /// Transition takes per class (each to a different next class).
    pub transitions: usize,
    /// Seconds of the long take per class searched for exact repeats.
    pub long_seconds: f32,
}

impl MotionSuiteConfig {
    pub fn full() -> Self {
        Self { variants: None, seeds: vec![1], take_seconds: 10.0, segment_seconds: 5.0, transitions: 2, long_seconds: 120.0 }
    }

    /// A reduced setting for tests and a quick look.
    pub fn quick() -> Self {
        Self { variants: Some(1), seeds: vec![1], take_seconds: 6.0, segment_seconds: 4.0, transitions: 1, long_seconds: 20.0 }
    }
}

/// A GloGen block's grid at [`COMMON_FPS`]: frames per block and per sparse interval.
#[derive(Clone, Copy, Debug)]
pub struct BlockGrid {
    pub block: usize,
    pub interval: usize,
}

impl BlockGrid {
    /// The grid of a model with `block_len` sparse poses `stride` frames apart at `fps`;
    /// `None` when it does not fall on whole frames at the common rate.
    pub fn new(block_len: usize, stride: usize, fps: f32) -> Option<Self> {
        let interval = stride as f32 * COMMON_FPS / fps;
        let whole = (interval - interval.round()).abs() < 1e-4 && interval >= 1.0;
        whole.then(|| Self { block: block_len * interval.round() as usize, interval: interval.round() as usize })
    }
}

/// Everything measured over the takes of one class from one source, pooled.
#[derive(Default)]
pub struct Pool {
    frames: usize,
    floating: usize,
    steps: usize,
    contact_steps: usize,
    skate_steps: usize,
    support_speeds: Vec<f32>,
    drifts: Vec<f32>,
    jerks: Vec<f32>,
    frame_jerks: Vec<f32>,
    window_peaks: Vec<f32>,
    speed_sum: f64,
    speed_count: usize,
    seam: Option<SeamProfile>,
    transition_peaks: Vec<f32>,
    elsewhere_peaks: Vec<f32>,
    longest_repeat: Option<(f32, f32)>,
}

#[derive(Clone)]
struct SeamProfile {
    grid: BlockGrid,
    speed: Vec<f64>,
    accel: Vec<f64>,
    count: Vec<usize>,
}

impl Pool {
    /// Adds one take (at [`COMMON_FPS`]); `grid` where its block phases are known.
    pub fn add_take(&mut self, m: &Motion, roles: &JointRoles, grid: Option<BlockGrid>) {
        let p = metres(m);
        let n = m.joints();
        let frames = m.frames();
        if frames < 4 {
            return;
        }
        let feet: Vec<usize> = Side::BOTH.iter().flat_map(|&s| roles.leg(s).foot_joints()).collect();
        let lowest: Vec<f32> = (0..frames).map(|t| feet.iter().map(|&j| p[t * n + j].y).fold(f32::INFINITY, f32::min)).collect();
        let floor = quantile(&lowest, FLOOR_QUANTILE);
        self.add_feet(&p, n, &feet, &lowest, floor);
        let frame_jerk = self.add_jerk(&p, n);
        self.window_peaks.extend(window_peaks(&frame_jerk, 0, frame_jerk.len(), &[]));
        let (sum, count) = joint_speed_sum(&p, n);
        self.speed_sum += sum;
        self.speed_count += count;
        if let Some(grid) = grid {
            self.add_seams(&p, n, roles.body_root, grid);
        }
    }

    fn add_feet(&mut self, p: &[Vec3], n: usize, feet: &[usize], lowest: &[f32], floor: f32) {
        let frames = lowest.len();
        self.frames += frames;
        self.floating += lowest.iter().filter(|&&h| h - floor > FLOOR_BAND_M).count();
        let height = |t: usize, j: usize| p[t * n + j].y - floor;
        let flat_speed = |t: usize, j: usize| {
            let d = p[(t + 1) * n + j] - p[t * n + j];
            Vec3::new(d.x, 0.0, d.z).length() * COMMON_FPS
        };
        for t in 0..frames - 1 {
            let contacts: Vec<usize> = feet.iter().copied().filter(|&j| height(t, j) < FLOOR_BAND_M && height(t + 1, j) < FLOOR_BAND_M).collect();
            self.steps += 1;
            if !contacts.is_empty() {
                self.contact_steps += 1;
            }
            if contacts.iter().any(|&j| flat_speed(t, j) > SKATE_SPEED) {
                self.skate_steps += 1;
            }
            let support = feet.iter().copied().min_by(|&a, &b| p[t * n + a].y.total_cmp(&p[t * n + b].y)).expect("legs have feet");
            if height(t, support) <= FLOOR_BAND_M {
                self.support_speeds.push(flat_speed(t, support));
            }
        }
        let window = (WINDOW_S * COMMON_FPS) as usize;
        let floors: Vec<f32> = lowest.chunks_exact(window).map(|w| w.iter().copied().fold(f32::INFINITY, f32::min)).collect();
        if floors.len() >= 2 {
            self.drifts.push(std_dev(&floors));
        }
    }

    /// Adds every joint's jerk; returns the per-frame (largest joint) jerk, one per frame
    /// from the second on (a third difference spans four frames).
    fn add_jerk(&mut self, p: &[Vec3], n: usize) -> Vec<f32> {
        let frames = p.len() / n;
        let scale = COMMON_FPS.powi(3);
        let mut per_frame = Vec::with_capacity(frames.saturating_sub(3));
        for t in 0..frames.saturating_sub(3) {
            let mut peak = 0.0f32;
            for j in 0..n {
                let q = |k: usize| p[(t + k) * n + j];
                let jerk = (q(3) - 3.0 * q(2) + 3.0 * q(1) - q(0)).length() * scale;
                self.jerks.push(jerk);
                peak = peak.max(jerk);
            }
            per_frame.push(peak);
        }
        self.frame_jerks.extend_from_slice(&per_frame);
        per_frame
    }

    fn add_seams(&mut self, p: &[Vec3], n: usize, root: usize, grid: BlockGrid) {
        let profile = self.seam.get_or_insert_with(|| SeamProfile { grid, speed: vec![0.0; grid.block], accel: vec![0.0; grid.block], count: vec![0; grid.block] });
        let frames = p.len() / n;
        let rel = |t: usize, j: usize| p[t * n + j] - p[t * n + root];
        for t in 1..frames - 1 {
            let phase = t % grid.block;
            let (mut v, mut a) = (0.0f64, 0.0f64);
            for j in 0..n {
                v += ((rel(t + 1, j) - rel(t, j)).length() * COMMON_FPS) as f64;
                a += ((rel(t + 1, j) - 2.0 * rel(t, j) + rel(t - 1, j)).length() * COMMON_FPS * COMMON_FPS) as f64;
            }
            profile.speed[phase] += v / n as f64;
            profile.accel[phase] += a / n as f64;
            profile.count[phase] += 1;
        }
    }

    /// Adds a two-class take's transition peaks: `boundaries` are frames (at the common rate).
    pub fn add_transitions(&mut self, m: &Motion, boundaries: &[usize]) {
        let p = metres(m);
        let mut scratch = Pool::default();
        let frame_jerk = scratch.add_jerk(&p, m.joints());
        let near = (TRANSITION_S * COMMON_FPS) as usize;
        for &b in boundaries {
            let window = &frame_jerk[b.saturating_sub(near).min(frame_jerk.len())..(b + near).min(frame_jerk.len())];
            if !window.is_empty() {
                self.transition_peaks.push(window.iter().copied().fold(0.0, f32::max));
            }
        }
        let excluded: Vec<(usize, usize)> = boundaries.iter().map(|&b| (b.saturating_sub(near), b + near)).collect();
        self.elsewhere_peaks.extend(window_peaks(&frame_jerk, 0, frame_jerk.len(), &excluded));
    }

    /// Records a take's longest exact repeat (seconds and lag), keeping the longest.
    pub fn add_repeats(&mut self, m: &Motion) {
        let found = longest_repeat(m);
        if self.longest_repeat.is_none_or(|(s, _)| found.0 > s) {
            self.longest_repeat = Some(found);
        }
    }

    /// The pooled measures by name (see [`DEFINITIONS`]); NaN where a take kind was absent.
    pub fn summary(&self) -> BTreeMap<&'static str, f64> {
        let ratio = |a: usize, b: usize| if b == 0 { f64::NAN } else { a as f64 / b as f64 };
        let mut out = BTreeMap::new();
        out.insert("skating_ratio", ratio(self.skate_steps, self.steps));
        out.insert("contact_fraction", ratio(self.contact_steps, self.steps));
        out.insert("support_speed_mean_cm_s", mean(&self.support_speeds) * 100.0);
        out.insert("support_speed_median_cm_s", quantile(&self.support_speeds, 0.5) as f64 * 100.0);
        out.insert("floating", ratio(self.floating, self.frames));
        out.insert("ground_drift_cm", mean(&self.drifts) * 100.0);
        out.insert("jerk_mean", mean(&self.jerks));
        out.insert("jerk_median", quantile(&self.jerks, 0.5) as f64);
        out.insert("jerk_p95", quantile(&self.jerks, 0.95) as f64);
        out.insert("frame_jerk_mean", mean(&self.frame_jerks));
        out.insert("window_peak_p95", quantile(&self.window_peaks, 0.95) as f64);
        out.insert("joint_speed", if self.speed_count == 0 { f64::NAN } else { self.speed_sum / self.speed_count as f64 });
        let seams = self.seam.as_ref().map(SeamProfile::ratios).unwrap_or([f64::NAN; 3]);
        out.insert("seam_ratio", seams[0]);
        out.insert("seam_accel_ratio", seams[1]);
        out.insert("sparse_accel_ratio", seams[2]);
        out.insert("transition_peak", mean(&self.transition_peaks));
        out.insert("elsewhere_peak", mean(&self.elsewhere_peaks));
        out.insert("longest_repeat_s", self.longest_repeat.map_or(f64::NAN, |r| r.0 as f64));
        out.insert("repeat_lag_s", self.longest_repeat.map_or(f64::NAN, |r| r.1 as f64));
        out
    }

    /// Mean pose speed in each sparse interval of a block, over the block's mean.
    fn interval_profile(&self) -> Vec<f64> {
        self.seam.as_ref().map(SeamProfile::intervals).unwrap_or_default()
    }
}

impl SeamProfile {
    fn phase_means(values: &[f64], count: &[usize]) -> Vec<f64> {
        values.iter().zip(count).map(|(v, &c)| if c == 0 { f64::NAN } else { v / c as f64 }).collect()
    }

    fn intervals(&self) -> Vec<f64> {
        let speed = Self::phase_means(&self.speed, &self.count);
        let per: Vec<f64> = speed.chunks(self.grid.interval).map(|c| c.iter().sum::<f64>() / c.len() as f64).collect();
        let overall = per.iter().sum::<f64>() / per.len() as f64;
        per.iter().map(|v| v / overall).collect()
    }

    /// (seam ratio, seam acceleration ratio, sparse-pose acceleration ratio).
    fn ratios(&self) -> [f64; 3] {
        let speed = Self::phase_means(&self.speed, &self.count);
        let accel = Self::phase_means(&self.accel, &self.count);
        let per: Vec<f64> = speed.chunks(self.grid.interval).map(|c| c.iter().sum::<f64>() / c.len() as f64).collect();
        let inner = &per[..per.len() - 1];
        let seam = per[per.len() - 1] / (inner.iter().sum::<f64>() / inner.len().max(1) as f64);
        let mean_accel = accel.iter().sum::<f64>() / accel.len() as f64;
        let sparse: Vec<f64> = accel.iter().step_by(self.grid.interval).copied().collect();
        [seam, accel[0] / mean_accel, sparse.iter().sum::<f64>() / sparse.len() as f64 / mean_accel]
    }
}

/// The sum of every joint's speed over every frame step (m/s, positions `p` in metres at
/// [`COMMON_FPS`], `n` joints a frame) and how many speeds it sums.
fn joint_speed_sum(p: &[Vec3], n: usize) -> (f64, usize) {
    let frames = p.len() / n.max(1);
    let sum = (1..frames).map(|t| (0..n).map(|j| p[t * n + j].distance(p[(t - 1) * n + j]) as f64).sum::<f64>()).sum::<f64>();
    (sum * COMMON_FPS as f64, n * frames.saturating_sub(1))
}

fn metres(m: &Motion) -> Vec<Vec3> {
    let unit = m.skeleton.meters_per_unit();
    m.positions().iter().map(|p| *p * unit).collect()
}

/// The mean of `v`, NaN when it is empty.
pub(crate) fn mean(v: &[f32]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64
    }
}

fn std_dev(v: &[f32]) -> f32 {
    let m = mean(v);
    (v.iter().map(|x| (*x as f64 - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt() as f32
}

fn quantile(v: &[f32], q: f32) -> f32 {
    if v.is_empty() {
        return f32::NAN;
    }
    let mut s = v.to_vec();
    let k = ((s.len() - 1) as f32 * q).round() as usize;
    *s.select_nth_unstable_by(k, f32::total_cmp).1
}

/// The peak of each whole 2 s window of `per_frame` in `[start, end)` that overlaps none of
/// the `excluded` ranges.
fn window_peaks(per_frame: &[f32], start: usize, end: usize, excluded: &[(usize, usize)]) -> Vec<f32> {
    let window = (WINDOW_S * COMMON_FPS) as usize;
    (start..end.saturating_sub(window - 1))
        .step_by(window)
        .filter(|&w| excluded.iter().all(|&(a, b)| w + window <= a || w >= b))
        .map(|w| per_frame[w..w + window].iter().copied().fold(0.0, f32::max))
        .collect()
}

/// Pairwise joint distances of every frame (heading- and position-invariant), metres.
fn pair_distances(m: &Motion) -> (Vec<f32>, usize) {
    let p = metres(m);
    let n = m.joints();
    let pairs: Vec<(usize, usize)> = (0..n).flat_map(|a| (a + 1..n).map(move |b| (a, b))).collect();
    let mut out = Vec::with_capacity(m.frames() * pairs.len());
    for t in 0..m.frames() {
        out.extend(pairs.iter().map(|&(a, b)| p[t * n + a].distance(p[t * n + b])));
    }
    (out, pairs.len())
}

/// The longest exact repeat of a take: (seconds, lag in seconds), (0, NaN) when none lasts
/// longer than [`REPEAT_MIN_S`]. Anchor frames every half second are looked up in a grid
/// over the three most varying distances; each candidate match at a lag of at least
/// [`REPEAT_MIN_LAG_S`] is followed along its diagonal.
pub fn longest_repeat(m: &Motion) -> (f32, f32) {
    let (d, dim) = pair_distances(m);
    let frames = m.frames();
    let min_run = (REPEAT_MIN_S * m.fps).round() as usize;
    let min_lag = (REPEAT_MIN_LAG_S * m.fps).round() as usize;
    if dim == 0 || frames < min_lag + min_run {
        return (0.0, f32::NAN);
    }
    let row = |t: usize| &d[t * dim..(t + 1) * dim];
    let matches = |a: usize, b: usize| row(a).iter().zip(row(b)).all(|(x, y)| (x - y).abs() <= REPEAT_TOLERANCE_M);
    let keys = most_varying(&d, dim, frames, 3);
    let cell = |t: usize| -> [i64; 3] { std::array::from_fn(|k| (row(t)[keys[k]] / REPEAT_TOLERANCE_M).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for t in 0..frames {
        grid.entry(cell(t)).or_default().push(t);
    }
    let mut best = (0usize, 0usize);
    for anchor in (0..frames).step_by((min_run / 2).max(1)) {
        let c = cell(anchor);
        let mut candidates: Vec<usize> = neighbour_cells(c).iter().filter_map(|k| grid.get(k)).flatten().copied().filter(|&t| t >= anchor + min_lag).collect();
        // A frozen stretch puts many frames in one cell; a sample of them tells as much.
        candidates.sort_unstable();
        let step = (candidates.len() / 64).max(1);
        for &other in candidates.iter().step_by(step) {
            if !matches(anchor, other) {
                continue;
            }
            let lag = other - anchor;
            let mut start = anchor;
            while start > 0 && matches(start - 1, start - 1 + lag) {
                start -= 1;
            }
            let mut end = anchor + 1;
            while end + lag < frames && matches(end, end + lag) {
                end += 1;
            }
            if end - start > best.0 {
                best = (end - start, lag);
            }
        }
    }
    if best.0 > min_run {
        (best.0 as f32 / m.fps, best.1 as f32 / m.fps)
    } else {
        (0.0, f32::NAN)
    }
}

fn most_varying(d: &[f32], dim: usize, frames: usize, count: usize) -> Vec<usize> {
    let mut spread: Vec<(usize, f32)> = (0..dim)
        .map(|k| {
            let column: Vec<f32> = (0..frames).map(|t| d[t * dim + k]).collect();
            (k, std_dev(&column))
        })
        .collect();
    spread.sort_by(|a, b| b.1.total_cmp(&a.1));
    (0..count).map(|i| spread[i.min(spread.len() - 1)].0).collect()
}

fn neighbour_cells(c: [i64; 3]) -> Vec<[i64; 3]> {
    let mut out = Vec::with_capacity(27);
    for dx in -1..=1 {
        for dy in -1..=1 {
            for dz in -1..=1 {
                out.push([c[0] + dx, c[1] + dy, c[2] + dz]);
            }
        }
    }
    out
}

/// The real test split of `corpus`, per class: pieces of `piece_seconds` for the per-take
/// measures (the floor and its drift are per take), whole clips for repeats.
pub fn real_pools(corpus: &Corpus, roles: &JointRoles, grid: Option<BlockGrid>, piece_seconds: f32) -> Vec<Pool> {
    let mut pools: Vec<Pool> = (0..corpus.classes.len()).map(|_| Pool::default()).collect();
    for track in &corpus.test {
        let m = track.motion.resample(COMMON_FPS);
        let piece = (piece_seconds * COMMON_FPS) as usize;
        let pool = &mut pools[track.class];
        let mut start = 0;
        while start + (WINDOW_S * COMMON_FPS) as usize <= m.frames() {
            let end = (start + piece).min(m.frames());
            pool.add_take(&m.slice(start, end), roles, grid);
            start = end;
        }
        pool.add_repeats(&m);
    }
    pools
}

/// Generated takes of every class under `base`'s options (with `foot_lock` as given), pooled per
/// class; the seed block is cut off every take.
pub fn generated_pools(model: &mut GlocalModel, cfg: &MotionSuiteConfig, base: &GenerateOptions, foot_lock: bool) -> Result<Vec<Pool>> {
    let spec = model.spec.clone();
    let roles = JointRoles::new(&spec.layout.skeleton)?;
    let grid = BlockGrid::new(spec.block_len, spec.stride, spec.fps);
    let seed_s = (spec.block_len * spec.stride) as f32 / spec.fps;
    let k = spec.classes.len();
    let mut pools: Vec<Pool> = (0..k).map(|_| Pool::default()).collect();
    let take = |model: &mut GlocalModel, segments: Vec<(usize, f32)>, init: usize, variant: usize, seed: u64| -> Result<(Motion, Vec<usize>)> {
        let segments = segments.into_iter().map(|(c, s)| Segment { class: spec.classes[c].clone(), seconds: s, pace: None, transition: None }).collect();
        let opts = GenerateOptions { timeline: Timeline { segments }, init: InitPose::SeedClass { class: spec.classes[init].clone(), variant }, foot_lock, ..base.clone() }.varied(seed);
        let g = generate(model, &opts, &mut |_| true)?;
        let seed_frames = spec.block_len * spec.stride;
        let m = g.motion.slice(seed_frames.min(g.motion.frames()), g.motion.frames()).resample(COMMON_FPS);
        let to_common = |f: usize| ((f.saturating_sub(seed_frames)) as f32 * COMMON_FPS / spec.fps).round() as usize;
        Ok((m, g.segments.iter().skip(1).map(|s| to_common(s.start_frame)).collect()))
    };
    for class in 0..k {
        let bank = model.seeds.iter().filter(|s| s.class == class).count();
        for variant in 0..cfg.variants.unwrap_or(bank) {
            for &seed in &cfg.seeds {
                let (m, _) = take(model, vec![(class, seed_s + cfg.take_seconds)], class, variant, seed)?;
                pools[class].add_take(&m, &roles, grid);
            }
        }
        for v in 0..cfg.transitions.min(k - 1) {
            let next = (class + 1 + v) % k;
            let (m, boundaries) = take(model, vec![(class, seed_s + cfg.segment_seconds), (next, cfg.segment_seconds)], class, v, 1 + v as u64)?;
            pools[class].add_transitions(&m, &boundaries);
        }
        let (m, _) = take(model, vec![(class, seed_s + cfg.long_seconds)], class, 0, 1)?;
        pools[class].add_repeats(&m);
    }
    Ok(pools)
}

/// One model's three sources: real, generated without and with the foot lock.
struct ModelResult {
    dataset: Dataset,
    dir: String,
    classes: Vec<String>,
    sources: [(&'static str, Vec<BTreeMap<&'static str, f64>>, Vec<Vec<f64>>); 3],
    /// Mean joint speed per class on the training split, which the model learnt from: where a
    /// class moves differently in the test split's styles, the two bounds differ.
    train_speed: Vec<f64>,
    /// Per class, the mean joint speed of each style (Bandai) or subject (Human3.6M), training
    /// split and test split, slowest first.
    tag_speeds: Vec<[Vec<(String, f64)>; 2]>,
}

/// Per class, the sum of every joint's speed and how many speeds it sums ([`joint_speed_sum`])
/// over each tag's tracks of `tracks`.
fn joint_speed_sums(tracks: &[Track], classes: usize) -> Vec<BTreeMap<&str, (f64, usize)>> {
    let mut sums: Vec<BTreeMap<&str, (f64, usize)>> = vec![BTreeMap::new(); classes];
    for track in tracks {
        let m = track.motion.resample(COMMON_FPS);
        let (sum, count) = joint_speed_sum(&metres(&m), m.joints());
        let entry = sums[track.class].entry(&track.tag).or_default();
        entry.0 += sum;
        entry.1 += count;
    }
    sums
}

/// Mean joint speed (m/s, at [`COMMON_FPS`]) per class, all its tags together.
fn joint_speed_per_class(sums: &[BTreeMap<&str, (f64, usize)>]) -> Vec<f64> {
    sums.iter()
        .map(|tags| {
            let (sum, count) = tags.values().fold((0.0, 0), |(s, c), &(ts, tc)| (s + ts, c + tc));
            sum / count.max(1) as f64
        })
        .collect()
}

/// Mean joint speed (m/s) of each tag, per class, slowest first.
fn joint_speed_per_tag(sums: &[BTreeMap<&str, (f64, usize)>]) -> Vec<Vec<(String, f64)>> {
    sums.iter()
        .map(|tags| {
            let mut speeds: Vec<(String, f64)> = tags.iter().map(|(tag, &(s, c))| (tag.to_string(), s / c.max(1) as f64)).collect();
            speeds.sort_by(|a, b| a.1.total_cmp(&b.1));
            speeds
        })
        .collect()
}

/// Rows of the main table: (key, label, digits).
const ROWS: [(&str, &str, usize); 19] = [
    ("skating_ratio", "skating ratio", 3),
    ("contact_fraction", "contact fraction", 3),
    ("support_speed_mean_cm_s", "support speed mean (cm/s)", 1),
    ("support_speed_median_cm_s", "support speed median (cm/s)", 1),
    ("floating", "floating (lowest foot > 5 cm)", 3),
    ("ground_drift_cm", "ground drift (cm)", 2),
    ("jerk_mean", "jerk mean (m/s^3)", 1),
    ("jerk_median", "jerk median (m/s^3)", 1),
    ("jerk_p95", "jerk p95 (m/s^3)", 1),
    ("frame_jerk_mean", "per-frame jerk, FlowMDM (m/s^3)", 1),
    ("window_peak_p95", "2 s window peak jerk p95 (m/s^3)", 1),
    ("seam_ratio", "seam ratio", 2),
    ("seam_accel_ratio", "acceleration at the seam / block mean", 2),
    ("sparse_accel_ratio", "acceleration at sparse poses / block mean", 2),
    ("transition_peak", "transition peak jerk, within 1 s (m/s^3)", 1),
    ("elsewhere_peak", "2 s window peak jerk elsewhere (m/s^3)", 1),
    ("joint_speed", "mean joint speed (m/s)", 3),
    ("longest_repeat_s", "longest exact repeat (s)", 1),
    ("repeat_lag_s", "its lag (s)", 1),
];

/// The class-balanced value: the mean over classes that have one.
fn balanced(per_class: &[BTreeMap<&'static str, f64>], key: &str) -> f64 {
    let v: Vec<f64> = per_class.iter().filter_map(|s| s.get(key).copied()).filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn cell(v: f64, digits: usize) -> String {
    fixed_or(v, digits, "-")
}

pub fn motion_suite(opts: &SuiteOptions, cfg: &MotionSuiteConfig, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let mut results = Vec::new();
    for dataset in super::suites::suite_datasets(opts)? {
        results.push(model_result(dataset, opts, cfg, log)?);
    }
    let mut md = Markdown::new(format!("{DEFINITIONS}\n\nGenerated: the shipped defaults (anchored transitions, class strength, keep-alive, LocGen, bone projection) from {} with noise seeds {:?}, {} s scored after the seed block per take; {} two-class takes per class ({} s + {} s); one {} s take per class for repeats. \"no lock\" is the same takes with `foot_lock` off.\n", cfg.variants.map_or("every window of each class's seed bank (up to 16, spread over the class's training clips)".to_string(), |v| format!("each class's first {v} seed-bank windows")), cfg.seeds, cfg.take_seconds, cfg.transitions, cfg.segment_seconds, cfg.segment_seconds, cfg.long_seconds));
    for r in &results {
        model_markdown(r, &mut md);
    }
    let json = json!({
        "fps": COMMON_FPS,
        "config": {"variants": cfg.variants, "seeds": cfg.seeds, "take_seconds": cfg.take_seconds, "segment_seconds": cfg.segment_seconds, "transitions": cfg.transitions, "long_seconds": cfg.long_seconds},
        "models": results.iter().map(model_json).collect::<Vec<_>>(),
    });
    Ok((md, json))
}

fn model_result(dataset: Dataset, opts: &SuiteOptions, cfg: &MotionSuiteConfig, log: &mut dyn FnMut(&str)) -> Result<ModelResult> {
    let dir = model_dir(opts, dataset);
    let mut model = GlocalModel::load(&dir)?;
    let spec = model.spec.clone();
    log(&format!("motion: {dataset} real test split"));
    let corpus = Corpus::load(dataset, &opts.data, spec.stride, 3)?;
    if corpus.classes != spec.classes {
        bail!("{}: the model's classes ({}) differ from the data's ({})", dir.display(), spec.classes.join(", "), corpus.classes.join(", "));
    }
    let roles = JointRoles::new(&corpus.layout.skeleton)?;
    let grid = BlockGrid::new(spec.block_len, spec.stride, spec.fps);
    let real = real_pools(&corpus, &roles, grid, cfg.take_seconds);
    log(&format!("motion: {dataset} generated, no foot lock"));
    let base = opts.generate_options();
    let unlocked = generated_pools(&mut model, cfg, &base, false)?;
    log(&format!("motion: {dataset} generated, shipped"));
    let shipped = generated_pools(&mut model, cfg, &base, true)?;
    let classes = spec.classes.len();
    let train_sums = joint_speed_sums(&corpus.train, classes);
    let summarise = |pools: &[Pool]| (pools.iter().map(Pool::summary).collect(), pools.iter().map(Pool::interval_profile).collect());
    let (r, u, s) = (summarise(&real), summarise(&unlocked), summarise(&shipped));
    Ok(ModelResult {
        dataset,
        dir: dir.display().to_string(),
        classes: spec.classes.clone(),
        sources: [("real", r.0, r.1), ("no lock", u.0, u.1), ("generated", s.0, s.1)],
        train_speed: joint_speed_per_class(&train_sums),
        tag_speeds: joint_speed_per_tag(&train_sums).into_iter().zip(joint_speed_per_tag(&joint_speed_sums(&corpus.test, classes))).map(|(a, b)| [a, b]).collect(),
    })
}

fn model_markdown(r: &ModelResult, md: &mut Markdown) {
    let [(_, real, real_prof), (_, unlocked, _), (_, shipped, shipped_prof)] = &r.sources;
    md.text(&format!("\n**{} ({})**, class-balanced (mean over the {} classes)\n\n", r.dataset, r.dir, r.classes.len()));
    let mut balanced_table = Table::new(["measure", "real test", "no lock", "generated", "no lock / real", "generated / real"]);
    for (key, label, digits) in ROWS {
        let (a, b, c) = (balanced(real, key), balanced(unlocked, key), balanced(shipped, key));
        balanced_table.row([label.to_string(), cell(a, digits), cell(b, digits), cell(c, digits), cell(b / a, 2), cell(c / a, 2)]);
    }
    let real_p95 = balanced(real, "window_peak_p95");
    balanced_table.row([
        "transition peak / real window peak p95".to_string(),
        String::new(),
        cell(balanced(unlocked, "transition_peak") / real_p95, 2),
        cell(balanced(shipped, "transition_peak") / real_p95, 2),
    ]);
    md.table(balanced_table);
    let profile = |p: &[Vec<f64>]| -> String {
        let k = p.first().map_or(0, Vec::len);
        (0..k).map(|i| cell(p.iter().map(|c| c[i]).sum::<f64>() / p.len() as f64, 2)).collect::<Vec<_>>().join(" ")
    };
    md.text(&format!("\nPose speed per sparse interval of a block, over the block's mean (class-balanced; the last interval crosses the seam): real {}; generated {}.\n", profile(real_prof), profile(shipped_prof)));
    md.text("\nPer class (generated = shipped defaults, foot lock on):\n\n");
    let mut per_class = Table::new([
        "class",
        "joint speed real (m/s)",
        "generated / real",
        "no lock / real",
        "joint speed train (m/s)",
        "generated / train",
        "support speed real / no lock / generated (cm/s)",
        "skating real / no lock / generated",
        "contact real / no lock / generated",
        "floating real / no lock / generated",
        "jerk mean generated / real",
    ]);
    for (c, name) in r.classes.iter().enumerate() {
        let v = |s: &[BTreeMap<&str, f64>], key: &str| s[c].get(key).copied().unwrap_or(f64::NAN);
        let three = |key: &str, d: usize| format!("{} / {} / {}", cell(v(real, key), d), cell(v(unlocked, key), d), cell(v(shipped, key), d));
        per_class.row([
            name.clone(),
            cell(v(real, "joint_speed"), 3),
            cell(v(shipped, "joint_speed") / v(real, "joint_speed"), 2),
            cell(v(unlocked, "joint_speed") / v(real, "joint_speed"), 2),
            cell(r.train_speed[c], 3),
            cell(v(shipped, "joint_speed") / r.train_speed[c], 2),
            three("support_speed_median_cm_s", 1),
            three("skating_ratio", 3),
            three("contact_fraction", 2),
            three("floating", 2),
            cell(v(shipped, "jerk_mean") / v(real, "jerk_mean"), 2),
        ]);
    }
    md.table(per_class);
    tag_markdown(r, md);
}

/// Each class's joint speed by style or subject: how far the test split's own spread sits
/// from the training split's, which bounds how near any model of the training split can come.
fn tag_markdown(r: &ModelResult, md: &mut Markdown) {
    let tag = if r.dataset == Dataset::Bandai { "style" } else { "subject" };
    md.text(&format!("\nJoint speed per {tag} (m/s, each {tag}'s clips of the class):\n\n"));
    let mut table = Table::new(["class".to_string(), format!("training split: slowest / median / fastest {tag}"), format!("test split, each {tag}")]);
    let named = |(name, speed): &(String, f64)| format!("{} {name}", cell(*speed, 3));
    for (name, [train, test]) in r.classes.iter().zip(&r.tag_speeds) {
        let spread = match (train.first(), train.get(train.len() / 2), train.last()) {
            (Some(a), Some(m), Some(b)) => format!("{} / {} / {}", named(a), named(m), named(b)),
            _ => "-".to_string(),
        };
        table.row([name.clone(), spread, test.iter().map(named).collect::<Vec<_>>().join(", ")]);
    }
    md.table(table);
}

fn model_json(r: &ModelResult) -> Value {
    let source = |(name, per_class, profile): &(&str, Vec<BTreeMap<&'static str, f64>>, Vec<Vec<f64>>)| {
        let balanced: BTreeMap<&str, f64> = ROWS.iter().map(|(k, _, _)| (*k, balanced(per_class, k))).collect();
        json!({"source": name, "balanced": balanced, "per_class": per_class, "interval_profile": profile})
    };
    json!({"dataset": r.dataset.name(), "model": r.dir, "classes": r.classes, "sources": r.sources.iter().map(source).collect::<Vec<_>>(), "train_joint_speed": r.train_speed, "joint_speed_per_tag": r.tag_speeds})
}
