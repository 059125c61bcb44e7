//! The motion-quality measures of `glocal eval --suite motion` (and of the constraints
//! suite's takes): how usable a take is as it comes out, measured the same way on real and
//! generated motion, everything resampled to [`COMMON_FPS`] and measured in metres, pooled
//! per class in a [`Pool`] and read as typed [`Measure`]s. The definitions are in
//! [`DEFINITIONS`], printed next to the suite's table.

use std::collections::{BTreeMap, HashMap};
use std::ops::Index;

use glam::Vec3;
use serde::{Serialize, Serializer};

use super::metrics::{mean, quantile, std_dev};
use crate::model::corpus::{Corpus, Track};
use crate::motion::{JointRoles, Motion, Side};

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
        let feet: Vec<usize> = Side::BOTH.iter().flat_map(|&s| roles.leg(s).foot_joints(&m.skeleton)).collect();
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

    /// The pooled measures (see [`DEFINITIONS`]).
    pub fn summary(&self) -> Summary {
        Summary::from_fn(|m| self.measure(m))
    }

    /// One pooled measure; NaN where a take kind was absent.
    fn measure(&self, m: Measure) -> f64 {
        let ratio = |a: usize, b: usize| if b == 0 { f64::NAN } else { a as f64 / b as f64 };
        let seam = |i: usize| self.seam.as_ref().map_or(f64::NAN, |s| s.ratios()[i]);
        match m {
            Measure::SkatingRatio => ratio(self.skate_steps, self.steps),
            Measure::ContactFraction => ratio(self.contact_steps, self.steps),
            Measure::SupportSpeedMean => mean(&self.support_speeds) * 100.0,
            Measure::SupportSpeedMedian => quantile(&self.support_speeds, 0.5) as f64 * 100.0,
            Measure::Floating => ratio(self.floating, self.frames),
            Measure::GroundDrift => mean(&self.drifts) * 100.0,
            Measure::JerkMean => mean(&self.jerks),
            Measure::JerkMedian => quantile(&self.jerks, 0.5) as f64,
            Measure::JerkP95 => quantile(&self.jerks, 0.95) as f64,
            Measure::FrameJerkMean => mean(&self.frame_jerks),
            Measure::WindowPeakP95 => quantile(&self.window_peaks, 0.95) as f64,
            Measure::JointSpeed => if self.speed_count == 0 { f64::NAN } else { self.speed_sum / self.speed_count as f64 },
            Measure::SeamRatio => seam(0),
            Measure::SeamAccelRatio => seam(1),
            Measure::SparseAccelRatio => seam(2),
            Measure::TransitionPeak => mean(&self.transition_peaks),
            Measure::ElsewherePeak => mean(&self.elsewhere_peaks),
            Measure::LongestRepeat => self.longest_repeat.map_or(f64::NAN, |r| r.0 as f64),
            Measure::RepeatLag => self.longest_repeat.map_or(f64::NAN, |r| r.1 as f64),
        }
    }

    /// Mean pose speed in each sparse interval of a block, over the block's mean.
    pub fn interval_profile(&self) -> Vec<f64> {
        self.seam.as_ref().map(SeamProfile::intervals).unwrap_or_default()
    }
}

/// One measure of a [`Pool`] (see [`DEFINITIONS`]): a cell of the motion suite's tables, and a
/// named number of its JSON.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measure {
    SkatingRatio,
    ContactFraction,
    /// cm/s.
    SupportSpeedMean,
    /// cm/s.
    SupportSpeedMedian,
    Floating,
    /// cm.
    GroundDrift,
    /// m/s^3, as every jerk below.
    JerkMean,
    JerkMedian,
    JerkP95,
    FrameJerkMean,
    WindowPeakP95,
    /// m/s.
    JointSpeed,
    SeamRatio,
    SeamAccelRatio,
    SparseAccelRatio,
    TransitionPeak,
    ElsewherePeak,
    /// Seconds.
    LongestRepeat,
    /// Seconds.
    RepeatLag,
}

impl Measure {
    pub const ALL: [Measure; 19] = [
        Measure::SkatingRatio,
        Measure::ContactFraction,
        Measure::SupportSpeedMean,
        Measure::SupportSpeedMedian,
        Measure::Floating,
        Measure::GroundDrift,
        Measure::JerkMean,
        Measure::JerkMedian,
        Measure::JerkP95,
        Measure::FrameJerkMean,
        Measure::WindowPeakP95,
        Measure::JointSpeed,
        Measure::SeamRatio,
        Measure::SeamAccelRatio,
        Measure::SparseAccelRatio,
        Measure::TransitionPeak,
        Measure::ElsewherePeak,
        Measure::LongestRepeat,
        Measure::RepeatLag,
    ];

    /// Its name in the JSON.
    pub fn key(self) -> &'static str {
        match self {
            Measure::SkatingRatio => "skating_ratio",
            Measure::ContactFraction => "contact_fraction",
            Measure::SupportSpeedMean => "support_speed_mean_cm_s",
            Measure::SupportSpeedMedian => "support_speed_median_cm_s",
            Measure::Floating => "floating",
            Measure::GroundDrift => "ground_drift_cm",
            Measure::JerkMean => "jerk_mean",
            Measure::JerkMedian => "jerk_median",
            Measure::JerkP95 => "jerk_p95",
            Measure::FrameJerkMean => "frame_jerk_mean",
            Measure::WindowPeakP95 => "window_peak_p95",
            Measure::JointSpeed => "joint_speed",
            Measure::SeamRatio => "seam_ratio",
            Measure::SeamAccelRatio => "seam_accel_ratio",
            Measure::SparseAccelRatio => "sparse_accel_ratio",
            Measure::TransitionPeak => "transition_peak",
            Measure::ElsewherePeak => "elsewhere_peak",
            Measure::LongestRepeat => "longest_repeat_s",
            Measure::RepeatLag => "repeat_lag_s",
        }
    }
}

/// Every [`Measure`] of one pool (or their class-balanced means), serialised as a map from
/// each measure's [`Measure::key`].
#[derive(Clone, Copy, Debug)]
pub struct Summary([f64; Measure::ALL.len()]);

impl Summary {
    /// Each measure's value given by `value`.
    pub fn from_fn(value: impl FnMut(Measure) -> f64) -> Self {
        Self(Measure::ALL.map(value))
    }
}

impl Index<Measure> for Summary {
    type Output = f64;

    fn index(&self, m: Measure) -> &f64 {
        &self.0[m as usize]
    }
}

impl Serialize for Summary {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(Measure::ALL.iter().map(|&m| (m.key(), self[m])))
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
        let pool = &mut pools[track.class];
        for piece in real_pieces(&m, piece_seconds) {
            pool.add_take(&m.slice(piece.start, piece.end), roles, grid);
        }
        pool.add_repeats(&m);
    }
    pools
}

/// A real clip at [`COMMON_FPS`] cut into pieces of `piece_seconds` to stand beside generated
/// takes that long: the last piece what is left, when at least a measuring window long.
pub fn real_pieces(m: &Motion, piece_seconds: f32) -> Vec<std::ops::Range<usize>> {
    let (piece, window) = ((piece_seconds * COMMON_FPS) as usize, (WINDOW_S * COMMON_FPS) as usize);
    let mut pieces = Vec::new();
    let mut start = 0;
    while start + window <= m.frames() {
        let end = (start + piece).min(m.frames());
        pieces.push(start..end);
        start = end;
    }
    pieces
}

/// Per class, the sum of every joint's speed and how many speeds it sums ([`joint_speed_sum`])
/// over each tag's tracks of `tracks`.
pub fn joint_speed_sums<'a>(tracks: impl IntoIterator<Item = &'a Track>, classes: usize) -> Vec<BTreeMap<&'a str, (f64, usize)>> {
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
pub fn joint_speed_per_class(sums: &[BTreeMap<&str, (f64, usize)>]) -> Vec<f64> {
    sums.iter()
        .map(|tags| {
            let (sum, count) = tags.values().fold((0.0, 0), |(s, c), &(ts, tc)| (s + ts, c + tc));
            sum / count.max(1) as f64
        })
        .collect()
}

/// Mean joint speed (m/s) of each tag, per class, slowest first.
pub fn joint_speed_per_tag(sums: &[BTreeMap<&str, (f64, usize)>]) -> Vec<Vec<(String, f64)>> {
    sums.iter()
        .map(|tags| {
            let mut speeds: Vec<(String, f64)> = tags.iter().map(|(tag, &(s, c))| (tag.to_string(), s / c.max(1) as f64)).collect();
            speeds.sort_by(|a, b| a.1.total_cmp(&b.1));
            speeds
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A summary is indexed by the measure's place in its declaration, which `ALL` follows;
    /// every measure has its own JSON name.
    #[test]
    fn measures_are_listed_in_declaration_order_with_distinct_keys() {
        for (i, m) in Measure::ALL.into_iter().enumerate() {
            assert_eq!(m as usize, i, "{m:?}");
        }
        let keys: std::collections::BTreeSet<&str> = Measure::ALL.iter().map(|m| m.key()).collect();
        assert_eq!(keys.len(), Measure::ALL.len());
    }
}
