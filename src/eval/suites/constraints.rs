//! `glocal eval --suite constraints`: keys (three ways of reaching them, and none) and the L
//! path against the same takes without it, on each shipped model, through the measures of
//! [`crate::eval::constraints`] and the motion suite's.

use anyhow::Result;
use glam::{Quat, Vec3};
use serde::Serialize;
use serde_json::{json, Value};

use super::context::SuiteContext;
use crate::eval::classifier::{Classifier, ClassifierConfig};
use crate::eval::constraints::{jerk_near_frames, key_errors, path_fit, PathFit};
use crate::eval::metrics::mean;
use crate::eval::motion::{Measure, Pool, COMMON_FPS};
use crate::eval::table::{Markdown, Table};
use crate::model::corpus::Corpus;
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, Motion};
use crate::synth::constraints::{Key, KeySource, RootPath, Waypoint};
use crate::synth::keys::key_pose;
use crate::synth::{generate, GenerateOptions, InitPose, KeyMethod, Segment, Timeline};

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

    /// The row's figures under `label`; the largest values are taken in `f32`, as measured.
    fn figures(&self, label: &str) -> Figures {
        let s = self.pool.summary();
        Figures {
            method: label.to_string(),
            key_body_cm_mean: 100.0 * mean(&self.body),
            key_body_cm_max: (100.0 * largest(self.body.iter().copied())) as f64,
            key_root_cm_mean: 100.0 * mean(&self.root),
            jerk_near_keys_mean: mean(&self.jerk),
            jerk_near_keys_max: largest(self.jerk.iter().copied()) as f64,
            accuracy: self.correct as f64 / self.clips.max(1) as f64,
            path_cm_mean: 100.0 * mean(&self.path.iter().map(|p| p.mean).collect::<Vec<_>>()),
            path_cm_max: (100.0 * largest(self.path.iter().map(|p| p.max))) as f64,
            facing_degrees: mean(&self.path.iter().map(|p| p.facing_degrees).collect::<Vec<_>>()),
            skating_ratio: s[Measure::SkatingRatio],
            support_speed_median_cm_s: s[Measure::SupportSpeedMedian],
            jerk_mean: s[Measure::JerkMean],
        }
    }
}

/// The largest of `v`, 0 when it is empty.
fn largest(v: impl Iterator<Item = f32>) -> f32 {
    v.fold(0.0, f32::max)
}

/// One row's figures, printed in the tables and written to the JSON under these names.
#[derive(Serialize)]
struct Figures {
    method: String,
    key_body_cm_mean: f64,
    key_body_cm_max: f64,
    key_root_cm_mean: f64,
    /// Times the jerk elsewhere ([`jerk_near_frames`]).
    jerk_near_keys_mean: f64,
    jerk_near_keys_max: f64,
    /// Of the action classifier.
    accuracy: f64,
    path_cm_mean: f64,
    path_cm_max: f64,
    facing_degrees: f64,
    skating_ratio: f64,
    support_speed_median_cm_s: f64,
    /// m/s^3.
    jerk_mean: f64,
}

/// A take of `class` alone, from its `variant`-th seed-bank window, made as `generation`
/// (the suite's options) asks.
fn one_class(generation: &GenerateOptions, class: &str, variant: usize) -> GenerateOptions {
    GenerateOptions { timeline: Timeline { segments: vec![Segment::new(class.to_string(), TAKE_SECONDS)] }, init: InitPose::SeedClass { class: class.to_string(), variant }, ..generation.clone() }
}

/// Every model's key rows and path rows, in two tables a model.
pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let mut md = Markdown::new(DEFINITIONS);
    let mut models = Vec::new();
    for &dataset in &ctx.datasets {
        let model = GlocalModel::load(&ctx.model_dir(dataset))?;
        log(&format!("constraints: {dataset} classifier"));
        let corpus = Corpus::load(dataset, &ctx.options.data, model.spec.stride, 3)?;
        let clf = Classifier::load_or_train(&corpus, &ClassifierConfig::default(), &ctx.options.cache, &format!("classifier-{dataset}"), log)?;
        let roles = JointRoles::new(&model.spec.layout.skeleton)?;
        log(&format!("constraints: {dataset} keys"));
        let keys: Vec<Figures> = key_rows(&model, &ctx.generation, &clf, &roles)?.iter().map(|(label, row)| row.figures(label)).collect();
        log(&format!("constraints: {dataset} paths"));
        let paths: Vec<(String, [Figures; 2])> = path_rows(&model, &ctx.generation, &clf, &roles)?.iter().map(|(class, rows)| (class.clone(), rows.each_ref().map(|r| r.figures(class)))).collect();
        md.text(&format!("\n**{dataset}**\n\n"));
        md.table(key_table(&keys));
        md.text("\n");
        md.table(path_table(&paths));
        let paths: Vec<Value> = paths.iter().map(|(class, [free, along])| json!({"class": class, "without": free, "along": along})).collect();
        models.push(json!({"model": dataset.name(), "keys": keys, "paths": paths}));
    }
    Ok((md, json!({"models": models})))
}

fn key_table(rows: &[Figures]) -> Table {
    let mut table = Table::new(["keys", "body error mean / max (cm)", "root error (cm)", "jerk near keys mean / max (x elsewhere)", "class accuracy"]);
    for r in rows {
        table.row([
            r.method.clone(),
            format!("{:.2} / {:.2}", r.key_body_cm_mean, r.key_body_cm_max),
            format!("{:.2}", r.key_root_cm_mean),
            format!("{:.2} / {:.2}", r.jerk_near_keys_mean, r.jerk_near_keys_max),
            format!("{:.3}", r.accuracy),
        ]);
    }
    table
}

/// Per class, the take along the L beside the same take without it.
fn path_table(rows: &[(String, [Figures; 2])]) -> Table {
    let mut table = Table::new(["path, class", "error mean / max (cm)", "facing (degrees)", "class accuracy", "skating ratio", "support speed median (cm/s)", "jerk mean (m/s^3)"]);
    table.row(["", "along the L", "without / along", "without / along", "without / along", "without / along", "without / along"]);
    for (class, [free, along]) in rows {
        let pair = |figure: fn(&Figures) -> f64, d: usize| format!("{:.d$} / {:.d$}", figure(free), figure(along));
        table.row([
            class.clone(),
            format!("{:.1} / {:.1}", along.path_cm_mean, along.path_cm_max),
            pair(|f| f.facing_degrees, 1),
            pair(|f| f.accuracy, 3),
            pair(|f| f.skating_ratio, 3),
            pair(|f| f.support_speed_median_cm_s, 1),
            pair(|f| f.jerk_mean, 1),
        ]);
    }
    table
}

const DEFINITIONS: &str = "Keys: per class, takes of 12 s from the class's first three seed-bank windows with two keys, a later seed-bank pose of the class at 4 s (the body only) and the free take's frame at 8 s moved 30 cm and turned 20 degrees (the root too). **Body error**: the largest joint distance from the key relative to the root (each in its heading frame), mean over keys and the worst; **root error**: the root's distance on the ground from a root-fixing key; **jerk near keys**: the peak per-frame jerk within 0.5 s of a key over the mean peak of the take's 1 s windows elsewhere; **class accuracy**: the action classifier on the 2.4 s clip that ends at the second key. \"none\" is the free take measured against the same keys. Path: every locomotion class (walking; walk, run, dash, walk-back, walk-left, walk-right) along an L of 6 m then 6 m to the right, against the same takes without the path; **error**: the root's distance from the drawn L until the take has walked its length; **facing**: the mean angle between the body's facing and the path's direction while the take travels (a sideways or backwards walk keeps its angle); the motion suite's skating ratio, support-point speed and jerk on the whole takes at 30 fps.\n";

fn key_rows(model: &GlocalModel, generation: &GenerateOptions, clf: &Classifier, roles: &JointRoles) -> Result<Vec<(&'static str, Row)>> {
    let methods = [("none", None), ("dense warp only", Some(KeyMethod::DenseWarp)), ("sparse warp (shipped, keys over 2 s apart)", Some(KeyMethod::SparseWarp)), ("sparse warp + roll-on", Some(KeyMethod::RollOn))];
    let mut rows: Vec<(&str, Row)> = methods.iter().map(|(l, _)| (*l, Row::default())).collect();
    let classes = model.spec.classes.clone();
    let clip = ClassifierConfig::default().frames;
    for (c, class) in classes.iter().enumerate() {
        for variant in 0..VARIANTS {
            let base = one_class(generation, class, variant);
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
fn path_rows(model: &GlocalModel, generation: &GenerateOptions, clf: &Classifier, roles: &JointRoles) -> Result<Vec<(String, [Row; 2])>> {
    let path = l_path();
    let classes = model.spec.classes.clone();
    let clip = ClassifierConfig::default().frames;
    let mut out = Vec::new();
    for (c, class) in classes.iter().enumerate().filter(|(_, c)| c.starts_with("walk") || ["run", "dash"].contains(&c.as_str())) {
        let mut rows = [Row::default(), Row::default()];
        for variant in 0..VARIANTS {
            let base = one_class(generation, class, variant);
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
