//! Looping takes (`--loop`) on both shipped models, every class: the cycle played again from
//! where its travel leaves it continues in pose and velocity across the wrap, against real
//! motion's own velocity changes; in place, the hips stay put over a cycle; the project file
//! and the command line keep the loop.

use std::path::Path;

use glam::Vec3;
use glocal::data::archive::DataRoot;
use glocal::data::registry::Dataset;
use glocal::eval::metrics::quantile;
use glocal::model::corpus::Corpus;
use glocal::model::glocal::GlocalModel;
use glocal::motion::{with_root_motion, JointRoles, Motion, RootMotion};
use glocal::synth::{generate, Document, GenerateOptions, InitPose, Key, KeySource, Timeline};

fn model(name: &str) -> GlocalModel {
    GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

fn loop_options(class: &str, seconds: f32) -> GenerateOptions {
    let timeline: Timeline = format!("{class}:{seconds}").parse().unwrap();
    let init = InitPose::SeedClass { class: class.to_string(), variant: 0 };
    GenerateOptions { timeline, init, cycle: true, ..Default::default() }
}

/// Mean over joints of the distance between two frames.
fn mean_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).sum::<f32>() / a.len() as f32
}

/// Mean over joints of the change of velocity at the middle frame of three.
fn velocity_jump(a: &[Vec3], b: &[Vec3], c: &[Vec3]) -> f32 {
    a.iter().zip(b).zip(c).map(|((p, q), r)| (*r - *q - (*q - *p)).length()).sum::<f32>() / a.len() as f32
}

/// The 95th percentile of every frame's velocity jump over the real test clips, and over
/// each class's own (none for a class without test clips).
fn real_jump_p95(dataset: Dataset, stride: usize) -> (f32, Vec<Option<f32>>) {
    let corpus = Corpus::load(dataset, &DataRoot::resolve(None), stride, 3).unwrap();
    let jumps = |class: Option<usize>| -> Vec<f32> {
        corpus
            .test
            .iter()
            .filter(|track| class.is_none_or(|c| track.class == c))
            .flat_map(|track| {
                let m = &track.motion;
                (1..m.frames().saturating_sub(1)).map(move |t| velocity_jump(m.frame(t - 1), m.frame(t), m.frame(t + 1)))
            })
            .collect()
    };
    let per_class = (0..corpus.classes.len()).map(|c| Some(jumps(Some(c))).filter(|j| !j.is_empty()).map(|j| quantile(&j, 0.95))).collect();
    (quantile(&jumps(None), 0.95), per_class)
}

/// The cycle's frames and `after` more, played again moved by its travel.
fn played_twice(m: &Motion, travel: Vec3, after: usize) -> Vec<Vec<Vec3>> {
    let n = m.frames();
    (0..n + after).map(|t| m.frame(t % n).iter().map(|&p| if t >= n { p + travel } else { p }).collect()).collect()
}

struct WrapMeasure {
    /// The pose speed over 0.2 s either side of the wrap over the cycle's median of the same.
    speed_ratio: f32,
    /// The largest velocity change at the wrap's two frames.
    jump: f32,
}

fn wrap_measure(m: &Motion, travel: Vec3) -> WrapMeasure {
    let (n, half) = (m.frames(), (0.2 * m.fps).round() as usize);
    let frames = played_twice(m, travel, 2);
    let steps: Vec<f32> = (0..n).map(|t| mean_distance(&frames[t], &frames[t + 1])).collect();
    // The speed over 0.2 s either side of every frame of the cycle played round; the wrap's
    // against the median.
    let around = |t: usize| (0..2 * half).map(|k| steps[(t + n - half + k) % n]).sum::<f32>() / (2 * half) as f32;
    let mut typical: Vec<f32> = (0..n).map(around).collect();
    let wrap = typical[0];
    typical.sort_by(f32::total_cmp);
    let jump = velocity_jump(&frames[n - 2], &frames[n - 1], &frames[n]).max(velocity_jump(&frames[n - 1], &frames[n], &frames[n + 1]));
    WrapMeasure { speed_ratio: wrap / typical[n / 2], jump }
}

/// Every class's 4 s loop closes: the speed around its wrap within 1.3x of its median, the
/// velocity change at the wrap within 1.5x the real p95 (of the whole test split, or with
/// `own_class` of the class's own test clips where that is larger: a dance's or a kick's
/// frames change velocity more than a model's data does overall), no drift in place, and
/// about the asked length.
fn check_every_class(name: &str, dataset: Dataset, own_class: bool) {
    let model = model(name);
    let (real_p95, class_p95) = real_jump_p95(dataset, model.spec.stride);
    let roles = JointRoles::new(&model.spec.layout.skeleton).unwrap();
    println!("{name}: real velocity jump p95 {real_p95:.4} units/frame^2");
    println!("{:<16} {:>7} {:>9} {:>11} {:>12} {:>14}", "class", "seconds", "travel m", "wrap speed", "jump / p95", "in-place drift");
    let mut failures = Vec::new();
    for (k, class) in model.spec.classes.iter().enumerate() {
        let real_p95 = if own_class { class_p95[k].map_or(real_p95, |p| p.max(real_p95)) } else { real_p95 };
        let take = generate(&model, &loop_options(class, 4.0), &mut |_| true).unwrap();
        let cycle = take.cycle.clone().expect("a loop take reports its cycle");
        assert_eq!(take.motion.frames(), cycle.frames);
        assert_eq!((take.segments[0].start_frame, take.segments[0].end_frame), (0, cycle.frames));
        assert_eq!(take.contacts.left.len(), cycle.frames);
        let wrap = wrap_measure(&take.motion, cycle.travel);
        let in_place = with_root_motion(&take.motion, RootMotion::InPlace).unwrap();
        let hips = |t: usize| in_place.frame(t)[roles.body_root] * Vec3::new(1.0, 0.0, 1.0);
        let drift = (0..in_place.frames()).map(|t| hips(t).distance(hips(0))).fold(0.0f32, f32::max) * in_place.skeleton.meters_per_unit();
        let metres = cycle.travel.length() * take.motion.skeleton.meters_per_unit();
        let seconds = cycle.frames as f32 / take.motion.fps;
        println!("{class:<16} {seconds:>7.2} {metres:>9.2} {:>10.2}x {:>11.2}x {:>12.1} mm", wrap.speed_ratio, wrap.jump / real_p95, drift * 1000.0);
        if !(1.0 / 1.3..=1.3).contains(&wrap.speed_ratio) || wrap.jump > 1.5 * real_p95 || drift > 0.02 || !(3.4..=4.6).contains(&seconds) {
            failures.push(class.clone());
        }
    }
    assert!(failures.is_empty(), "{name}: loops that do not close: {failures:?}");
}

#[test]
fn h36m_loops_close_on_every_class() {
    check_every_class("h36m", Dataset::H36m, false);
}

#[test]
fn bandai_loops_close_on_every_class() {
    check_every_class("bandai", Dataset::Bandai, false);
}

#[test]
fn a_loop_is_one_activity_without_keys_or_path() {
    let model = model("h36m");
    let err = |opts: GenerateOptions| format!("{:#}", generate(&model, &opts, &mut |_| true).err().expect("refused"));
    let mut two = loop_options("walking", 4.0);
    two.timeline = "walking:4,sitting:3".parse().unwrap();
    assert!(err(two).contains("a loop is one activity: the timeline has 2 segments"));
    assert!(err(loop_options("walking", 0.2)).contains("a loop lasts at least 0.5 s"));
    let mut keyed = loop_options("walking", 4.0);
    keyed.keys = vec![Key { seconds: 2.0, source: KeySource::Init(InitPose::SeedClass { class: "walking".into(), variant: 0 }), fix_root: false }];
    assert!(err(keyed).contains("a loop cannot have keys or a root path"));
}

#[test]
fn the_command_line_and_a_project_make_the_same_loop() {
    let dir = tempfile::tempdir().unwrap();
    let exe = env!("CARGO_BIN_EXE_glocal");
    let run = |args: &[&str]| {
        let out = std::process::Command::new(exe).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let direct = dir.path().join("direct.json");
    let said = run(&["generate", "--timeline", "walking:4", "--loop", "--out", direct.to_str().unwrap()]);
    assert!(said.contains("loop of ") && said.contains("m per cycle"), "{said}");
    // With --json the output is one JSON document, the loop in it.
    let json = run(&["generate", "--timeline", "walking:4", "--loop", "--json", "--out", dir.path().join("j.json").to_str().unwrap()]);
    let summary: serde_json::Value = serde_json::from_str(&json).unwrap_or_else(|e| panic!("--json printed more than JSON ({e}): {json}"));
    assert!(summary["loop"].as_str().is_some_and(|l| l.contains("m per cycle")), "{summary}");
    // The same request saved as a project reproduces the loop exactly.
    let mut document = Document::new(Path::new("models/h36m").to_path_buf());
    document.options = loop_options("walking", 4.0);
    let project = dir.path().join("loop.glocal");
    std::fs::write(&project, serde_json::to_string_pretty(&document).unwrap()).unwrap();
    let saved = dir.path().join("saved.json");
    run(&["generate", "--project", project.to_str().unwrap(), "--out", saved.to_str().unwrap()]);
    assert_eq!(std::fs::read(&direct).unwrap(), std::fs::read(&saved).unwrap());
}

/// The studio's model's loops close on every class too, with its motion texture laid over
/// them, each judged against its own class's capture where that moves more.
#[test]
fn the_model_of_everythings_loops_close_on_every_class() {
    check_every_class("all", Dataset::Combined, true);
}
