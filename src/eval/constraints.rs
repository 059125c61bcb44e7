//! How well a take honours its keys and its root path: the key errors (the body relative to
//! its root, the root on the ground), the jerk around keys against the take elsewhere, and the
//! root's distance from the drawn path with the body's facing along it.

use anyhow::Result;
use glam::{Quat, Vec2, Vec3};
use serde_json::{json, Value};

use super::classifier::{Classifier, ClassifierConfig};
use super::motion::{mean, Pool, COMMON_FPS};
use super::suites::{model_dir, SuiteOptions};
use super::table::{Markdown, Table};
use crate::data::features::{wrap, FeatureLayout};
use crate::model::corpus::Corpus;
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, Motion};
use crate::synth::constraints::{Key, KeySource, RootPath, Waypoint};
use crate::synth::keys::key_pose;
use crate::synth::path_follow::{arc_lengths, GroundPath};
use crate::synth::{generate, GenerateOptions, InitPose, KeyMethod, Segment, Timeline};

/// Half-width (seconds) of the stretch around a key whose jerk is compared with the take's.
pub const NEAR_KEY_SECONDS: f32 = 0.5;

/// A take moving slower than this (m/s) has no direction of travel to compare its facing with.
const MIN_TRAVEL_M_S: f32 = 0.3;

/// Per frame (from the first), the largest joint jerk (third difference of world positions,
/// m/s^3); the last three frames have none.
pub fn frame_jerk(m: &Motion) -> Vec<f32> {
    let (n, p) = (m.joints(), m.positions());
    let scale = m.fps.powi(3) * m.skeleton.meters_per_unit();
    (0..m.frames().saturating_sub(3))
        .map(|t| (0..n).map(|j| (p[(t + 3) * n + j] - 3.0 * p[(t + 2) * n + j] + 3.0 * p[(t + 1) * n + j] - p[t * n + j]).length() * scale).fold(0.0, f32::max))
        .collect()
}

/// The peak per-frame jerk within [`NEAR_KEY_SECONDS`] of each of `frames` (mean over
/// them), over the mean peak of the take's windows of the same width that hold none of them.
pub fn jerk_near_frames(m: &Motion, frames: &[usize]) -> f64 {
    let jerk = frame_jerk(m);
    let half = (NEAR_KEY_SECONDS * m.fps).round() as usize;
    // The jerk of frame t spans frames t..t + 3: it is centred on t + 1.
    let window = |f: usize| f.saturating_sub(half + 1)..(f + half).min(jerk.len());
    let peak = |r: std::ops::Range<usize>| jerk[r].iter().copied().fold(0.0f32, f32::max) as f64;
    let near = frames.iter().map(|&f| peak(window(f))).sum::<f64>() / frames.len().max(1) as f64;
    let width = 2 * half + 1;
    let clear = |start: usize| frames.iter().all(|&f| f + half + 3 < start || f > start + width + half + 1);
    let elsewhere: Vec<f64> = (0..jerk.len() / width).map(|w| w * width).filter(|&s| clear(s)).map(|s| peak(s..s + width)).collect();
    near / (elsewhere.iter().sum::<f64>() / elsewhere.len().max(1) as f64).max(f64::EPSILON)
}

/// The largest distance (metres) of a joint of frame `frame` from `pose` relative to their
/// roots, each in its own heading frame, and the roots' distance on the ground.
pub fn key_errors(m: &Motion, layout: &FeatureLayout, frame: usize, pose: &[Vec3]) -> (f32, f32) {
    let have = m.frame(frame.min(m.frames() - 1));
    let (h, kh) = (layout.heading(have), layout.heading(pose));
    let relative = |p: &[Vec3], k: usize, heading: f32| Quat::from_rotation_y(-heading) * (p[k] - p[0]);
    let body = (0..have.len()).map(|k| (relative(have, k, h) - relative(pose, k, kh)).length()).fold(0.0f32, f32::max);
    let d = have[0] - pose[0];
    let unit = m.skeleton.meters_per_unit();
    (body * unit, Vec2::new(d.x, d.z).length() * unit)
}

/// How a take follows a path.
#[derive(Clone, Copy, Debug)]
pub struct PathFit {
    /// The root's distance from the drawn path (metres), mean and largest, over the frames
    /// until the take has walked the path's length.
    pub mean: f32,
    pub max: f32,
    /// Mean angle (degrees) between the body's facing and the path's direction where the
    /// take travels.
    pub facing_degrees: f32,
}

pub fn path_fit(m: &Motion, layout: &FeatureLayout, path: &RootPath) -> PathFit {
    let unit = m.skeleton.meters_per_unit();
    let drawn: Vec<Vec2> = path.waypoints.iter().map(|w| Vec2::new(w.x, w.z)).collect();
    let ground = GroundPath::new(path, 1.0);
    let root: Vec<Vec2> = (0..m.frames()).map(|f| Vec2::new(m.frame(f)[0].x, m.frame(f)[0].z) * unit).collect();
    let walked = arc_lengths(&root);
    let mut distances = Vec::new();
    let mut facing = Vec::new();
    let step = (0.25 * m.fps).round().max(1.0) as usize;
    for f in (0..root.len()).take_while(|&f| walked[f] <= ground.length()) {
        distances.push(GroundPath::distance_to_polyline(&drawn, root[f]));
        let (a, b) = (root[f.saturating_sub(step)], root[(f + step).min(root.len() - 1)]);
        let travel = b - a;
        if travel.length() * m.fps / (2 * step) as f32 > MIN_TRAVEL_M_S {
            let (_, tangent) = ground.at(nearest_arc(&ground, root[f]));
            facing.push(wrap(layout.heading(m.frame(f)) - tangent).abs().to_degrees());
        }
    }
    PathFit { mean: mean(&distances) as f32, max: distances.iter().copied().fold(0.0, f32::max), facing_degrees: mean(&facing) as f32 }
}

/// Arc length of the point of the (rounded) path nearest `p`, to 1 cm.
fn nearest_arc(path: &GroundPath, p: Vec2) -> f32 {
    let samples = (path.length() / 0.01).ceil() as usize;
    (0..=samples).map(|k| k as f32 * 0.01).min_by(|&a, &b| path.at(a).0.distance(p).total_cmp(&path.at(b).0.distance(p))).unwrap_or(0.0)
}

/// Seconds of each constrained take, and where its two keys fall.
const TAKE_SECONDS: f32 = 12.0;
const KEY_SECONDS: [f32; 2] = [4.0, 8.0];

/// Takes per class (seed-bank variants) for the key rows and per locomotion class for the path.
const VARIANTS: usize = 3;

/// The L the path rows walk: 6 m ahead, then 6 m to the right.
fn l_path() -> RootPath {
    let w = |x, z| Waypoint { x, z, seconds: None };
    RootPath { waypoints: vec![w(0.0, 0.0), w(0.0, 6.0), w(6.0, 6.0)] }
}

/// The two keys of a take of `class`: another seed-bank pose of the class at 4 s (the body
/// only) and the free take's frame at 8 s moved 30 cm and turned 20 degrees (root too).
fn two_keys(model: &GlocalModel, class: &str, variant: usize, free: &Motion) -> Vec<Key> {
    let frame = (KEY_SECONDS[1] * model.spec.fps).round() as usize;
    let pose = free.frame(frame.min(free.frames() - 1));
    let (root, turn) = (pose[0], Quat::from_rotation_y(20f32.to_radians()));
    let shift = Vec3::new(0.3, 0.0, 0.0) / model.spec.layout.skeleton.meters_per_unit();
    let moved = pose.iter().map(|p| (root + turn * (*p - root) + shift).to_array()).collect();
    vec![
        Key { seconds: KEY_SECONDS[0], source: KeySource::Init(InitPose::SeedClass { class: class.into(), variant: variant + VARIANTS }), fix_root: false },
        Key { seconds: KEY_SECONDS[1], source: KeySource::Pose(moved), fix_root: true },
    ]
}

/// Figures of one row: means over its takes.
#[derive(Default)]
struct Row {
    body: Vec<f32>,
    root: Vec<f32>,
    jerk: Vec<f32>,
    correct: usize,
    clips: usize,
    path: Vec<PathFit>,
    pool: Pool,
}

impl Row {
    /// Scores `take` of class `class`: the classifier on its clip from `clip_start`, and the
    /// motion suite's figures.
    fn add_take(&mut self, take: &Motion, class: usize, clip_start: usize, clf: &Classifier, roles: &JointRoles) -> Result<()> {
        self.correct += usize::from(clf.predict(&[clf.clip(take, clip_start)])?[0] == class);
        self.clips += 1;
        self.pool.add_take(&take.resample(COMMON_FPS), roles, None);
        Ok(())
    }

    fn json(&self, label: &str) -> Value {
        let s = self.pool.summary();
        json!({
            "method": label,
            "key_body_cm_mean": 100.0 * mean(&self.body), "key_body_cm_max": 100.0 * self.body.iter().copied().fold(0.0, f32::max),
            "key_root_cm_mean": 100.0 * mean(&self.root),
            "jerk_near_keys_mean": mean(&self.jerk), "jerk_near_keys_max": self.jerk.iter().copied().fold(0.0, f32::max),
            "accuracy": self.correct as f64 / self.clips.max(1) as f64,
            "path_cm_mean": 100.0 * mean(&self.path.iter().map(|p| p.mean).collect::<Vec<_>>()),
            "path_cm_max": 100.0 * self.path.iter().map(|p| p.max).fold(0.0, f32::max),
            "facing_degrees": mean(&self.path.iter().map(|p| p.facing_degrees).collect::<Vec<_>>()),
            "skating_ratio": s["skating_ratio"], "support_speed_median_cm_s": s["support_speed_median_cm_s"], "jerk_mean": s["jerk_mean"],
        })
    }
}

/// A take of `class` alone, from its `variant`-th seed-bank window.
fn one_class(class: &str, variant: usize) -> GenerateOptions {
    GenerateOptions { timeline: Timeline { segments: vec![Segment::new(class.to_string(), TAKE_SECONDS)] }, init: InitPose::SeedClass { class: class.to_string(), variant }, ..Default::default() }
}

/// `glocal eval --suite constraints`: keys (three ways of reaching them, and none) and the L
/// path against the same takes without it, on each shipped model.
pub fn constraints_suite(opts: &SuiteOptions, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let mut md = Markdown::new(DEFINITIONS);
    let mut models = Vec::new();
    for dataset in super::suites::suite_datasets(opts)? {
        let mut model = GlocalModel::load(&model_dir(opts, dataset))?;
        log(&format!("constraints: {dataset} classifier"));
        let corpus = Corpus::load(dataset, &opts.data, model.spec.stride, 3)?;
        let clf = Classifier::load_or_train(&corpus, &ClassifierConfig::default(), &opts.cache, &format!("classifier-{dataset}"), log)?;
        let roles = JointRoles::new(&model.spec.layout.skeleton)?;
        log(&format!("constraints: {dataset} keys"));
        let key_rows = key_rows(&mut model, &clf, &roles)?;
        log(&format!("constraints: {dataset} paths"));
        let path_rows = path_rows(&mut model, &clf, &roles)?;
        md.text(&format!("\n**{dataset}**\n\n"));
        let mut keys = Table::new(["keys", "body error mean / max (cm)", "root error (cm)", "jerk near keys mean / max (x elsewhere)", "class accuracy"]);
        let g = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
        for (label, r) in &key_rows {
            let v = r.json(label);
            keys.row([
                label.to_string(),
                format!("{:.2} / {:.2}", g(&v, "key_body_cm_mean"), g(&v, "key_body_cm_max")),
                format!("{:.2}", g(&v, "key_root_cm_mean")),
                format!("{:.2} / {:.2}", g(&v, "jerk_near_keys_mean"), g(&v, "jerk_near_keys_max")),
                format!("{:.3}", g(&v, "accuracy")),
            ]);
        }
        md.table(keys);
        md.text("\n");
        let mut paths = Table::new(["path, class", "error mean / max (cm)", "facing (degrees)", "class accuracy", "skating ratio", "support speed median (cm/s)", "jerk mean (m/s^3)"]);
        paths.row(["", "along the L", "without / along", "without / along", "without / along", "without / along", "without / along"]);
        for (class, [free, along]) in &path_rows {
            let (a, b) = (free.json(class), along.json(class));
            let pair = |k: &str, d: usize| format!("{:.d$} / {:.d$}", g(&a, k), g(&b, k));
            paths.row([
                class.to_string(),
                format!("{:.1} / {:.1}", g(&b, "path_cm_mean"), g(&b, "path_cm_max")),
                pair("facing_degrees", 1),
                pair("accuracy", 3),
                pair("skating_ratio", 3),
                pair("support_speed_median_cm_s", 1),
                pair("jerk_mean", 1),
            ]);
        }
        md.table(paths);
        let paths: Vec<Value> = path_rows.iter().map(|(class, [free, along])| json!({"class": class, "without": free.json(class), "along": along.json(class)})).collect();
        models.push(json!({"model": dataset.name(), "keys": key_rows.iter().map(|(l, r)| r.json(l)).collect::<Vec<_>>(), "paths": paths}));
    }
    Ok((md, json!({"models": models})))
}

const DEFINITIONS: &str = "Keys: per class, takes of 12 s from the class's first three seed-bank windows with two keys, a later seed-bank pose of the class at 4 s (the body only) and the free take's frame at 8 s moved 30 cm and turned 20 degrees (the root too). **Body error**: the largest joint distance from the key relative to the root (each in its heading frame), mean over keys and the worst; **root error**: the root's distance on the ground from a root-fixing key; **jerk near keys**: the peak per-frame jerk within 0.5 s of a key over the mean peak of the take's 1 s windows elsewhere; **class accuracy**: the action classifier on the 2.4 s clip that ends at the second key. \"none\" is the free take measured against the same keys. Path: every locomotion class (walking; walk, run, dash, walk-back, walk-left, walk-right) along an L of 6 m then 6 m to the right, against the same takes without the path; **error**: the root's distance from the drawn L until the take has walked its length; **facing**: the mean angle between the body's facing and the path's direction while the take travels (a sideways or backwards walk keeps its angle); the motion suite's skating ratio, support-point speed and jerk on the whole takes at 30 fps.\n";

fn key_rows(model: &mut GlocalModel, clf: &Classifier, roles: &JointRoles) -> Result<Vec<(&'static str, Row)>> {
    let methods = [("none", None), ("dense warp only", Some(KeyMethod::DenseWarp)), ("sparse warp (shipped)", Some(KeyMethod::SparseWarp)), ("sparse warp + roll-on", Some(KeyMethod::RollOn))];
    let mut rows: Vec<(&str, Row)> = methods.iter().map(|(l, _)| (*l, Row::default())).collect();
    let classes = model.spec.classes.clone();
    let clip = ClassifierConfig::default().frames;
    for (c, class) in classes.iter().enumerate() {
        for variant in 0..VARIANTS {
            let base = one_class(class, variant);
            let free = generate(model, &base, &mut |_| true)?.motion;
            let keys = two_keys(model, class, variant, &free);
            let frames: Vec<usize> = keys.iter().map(|k| (k.seconds * model.spec.fps).round() as usize).collect();
            let poses = keys.iter().map(|k| key_pose(model, k, &InitPose::default())).collect::<Result<Vec<_>>>()?;
            for ((_, method), (_, row)) in methods.iter().zip(rows.iter_mut()) {
                let take = match method {
                    None => free.clone(),
                    Some(m) => generate(model, &GenerateOptions { keys: keys.clone(), key_method: *m, ..base.clone() }, &mut |_| true)?.motion,
                };
                for ((key, &frame), pose) in keys.iter().zip(&frames).zip(&poses) {
                    let (body, root) = key_errors(&take, &model.spec.layout, frame, pose);
                    row.body.push(body);
                    if key.fix_root {
                        row.root.push(root);
                    }
                    row.jerk.push(jerk_near_frames(&take, &[frame]) as f32);
                }
                row.add_take(&take, c, frames[1].saturating_sub(clip), clf, roles)?;
            }
        }
    }
    Ok(rows)
}

/// Per locomotion class, the takes without the path and along it.
fn path_rows(model: &mut GlocalModel, clf: &Classifier, roles: &JointRoles) -> Result<Vec<(String, [Row; 2])>> {
    let path = l_path();
    let classes = model.spec.classes.clone();
    let clip = ClassifierConfig::default().frames;
    let mut out = Vec::new();
    for (c, class) in classes.iter().enumerate().filter(|(_, c)| c.starts_with("walk") || ["run", "dash"].contains(&c.as_str())) {
        let mut rows = [Row::default(), Row::default()];
        for variant in 0..VARIANTS {
            let base = one_class(class, variant);
            for (k, row) in rows.iter_mut().enumerate() {
                let opts = GenerateOptions { path: (k == 1).then(|| path.clone()), ..base.clone() };
                let take = generate(model, &opts, &mut |_| true)?.motion;
                row.path.push(path_fit(&take, &model.spec.layout, &path));
                row.add_take(&take, c, take.frames().saturating_sub(clip + 1) / 2, clf, roles)?;
            }
        }
        out.push((class.clone(), rows));
    }
    Ok(out)
}
