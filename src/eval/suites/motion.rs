//! `glocal eval --suite motion`: the motion-quality measures of [`crate::eval::motion`] on the
//! real test split and on generated takes (without and with the foot lock), per class and
//! class-balanced, for each shipped model.

use anyhow::Result;
use serde_json::{json, Value};

use super::context::SuiteContext;
use super::first_takes::{self, FirstTake};
use crate::data::registry::Dataset;
use crate::eval::motion::{joint_speed_per_class, joint_speed_per_tag, joint_speed_sums, real_pieces, real_pools, BlockGrid, Measure, Pool, Summary, COMMON_FPS, DEFINITIONS};
use crate::eval::snaps::{SnapLimits, SnapTally};
use crate::eval::table::{fixed_or, Markdown, Table};
use crate::model::corpus::{Corpus, Track};
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, Motion};
use crate::synth::{generate, GenerateOptions, InitPose, Segment, Timeline};

/// How many takes the suite generates, and how long.
#[derive(Clone, Debug)]
struct MotionSuiteConfig {
    /// Seed-bank windows per class, each with every noise seed; `None` is every window of the
    /// class's bank. The bank is in clip order, which for Bandai is its styles in alphabetical
    /// order: the first three byebye windows are all the style "active", which waves at 0.66
    /// m/s against a training median of 0.11, so a few first windows are not a fair sample.
    variants: Option<usize>,
    seeds: Vec<u64>,
    /// Seconds of each scored single-class take (after the seed).
    take_seconds: f32,
    /// Seconds of each of the two segments of a transition take.
    segment_seconds: f32,
    /// Transition takes per class (each to a different next class).
    transitions: usize,
    /// Seconds of the long take per class searched for exact repeats.
    long_seconds: f32,
}

impl MotionSuiteConfig {
    fn full() -> Self {
        Self { variants: None, seeds: vec![1], take_seconds: 10.0, segment_seconds: 5.0, transitions: 2, long_seconds: 120.0 }
    }

    /// A reduced setting for a quick look (`--quick`).
    fn quick() -> Self {
        Self { variants: Some(1), seeds: vec![1], take_seconds: 6.0, segment_seconds: 4.0, transitions: 1, long_seconds: 20.0 }
    }
}

/// Generated takes of every class under `base`'s options (with `foot_lock` as given), pooled per
/// class; the seed block is cut off every take. Where `snaps` is given, every take's bone turns
/// are tallied against its limits.
fn generated_pools(model: &GlocalModel, cfg: &MotionSuiteConfig, base: &GenerateOptions, foot_lock: bool, mut snaps: Option<(&SnapLimits, &mut SnapTally)>) -> Result<Vec<Pool>> {
    let spec = model.spec.clone();
    let roles = JointRoles::new(&spec.layout.skeleton)?;
    let grid = BlockGrid::new(spec.block_len, spec.stride, spec.fps);
    let seed_s = (spec.block_len * spec.stride) as f32 / spec.fps;
    let k = spec.classes.len();
    let mut pools: Vec<Pool> = (0..k).map(|_| Pool::default()).collect();
    let base = GenerateOptions { foot_lock, ..base.clone() };
    let mut take = |model: &GlocalModel, segments: Vec<(usize, f32)>, init: usize, variant: usize, seed: u64| -> Result<(Motion, Vec<usize>)> {
        let (m, boundaries) = scored_take(model, &base, &segments, init, variant, seed)?;
        if let Some((limits, tally)) = snaps.as_mut() {
            let label = format!("{} from {} variant {variant}, seed {seed}", segments.iter().map(|(c, s)| format!("{}:{s:.1}", spec.classes[*c])).collect::<Vec<_>>().join(","), spec.classes[init]);
            tally.add(limits, &label, &m, 0);
        }
        Ok((m, boundaries))
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

/// The model of everything's changes between activities of two datasets (issue 35), and, to
/// compare, within one: (from, to).
const ACROSS_DATASETS: [(&str, &str); 4] = [("sitting", "salsa"), ("bow", "basketball"), ("walking", "martial"), ("soccer", "greeting")];
const WITHIN_A_DATASET: [(&str, &str); 3] = [("sitting", "eating"), ("bow", "walk-left"), ("salsa", "indian")];
/// Takes per pair (variants of the first class's seed, each its own noise seed).
const PAIR_TAKES: usize = 4;

/// A take of `segments` ((class, seconds)) from `init`'s seed window `variant` under `base`'s
/// options and noise seed `seed`: the take after its seed block at [`COMMON_FPS`], and where each
/// later segment begins in it.
pub(crate) fn scored_take(model: &GlocalModel, base: &GenerateOptions, segments: &[(usize, f32)], init: usize, variant: usize, seed: u64) -> Result<(Motion, Vec<usize>)> {
    let spec = &model.spec;
    let segments = segments.iter().map(|&(c, s)| Segment::new(spec.classes[c].clone(), s)).collect();
    let opts = GenerateOptions { timeline: Timeline { segments }, init: InitPose::SeedClass { class: spec.classes[init].clone(), variant }, ..base.clone() }.varied(seed);
    let g = generate(model, &opts, &mut |_| true)?;
    let seed_frames = spec.block_len * spec.stride;
    let m = g.motion.slice(seed_frames.min(g.motion.frames()), g.motion.frames()).resample(COMMON_FPS);
    let to_common = |f: usize| ((f.saturating_sub(seed_frames)) as f32 * COMMON_FPS / spec.fps).round() as usize;
    Ok((m, g.segments.iter().skip(1).map(|s| to_common(s.start_frame)).collect()))
}

/// The mean transition peak jerk (m/s^3, within 1 s of the change) of takes that change from
/// one activity into another, per (from, to) pair.
fn pair_transition_peaks(model: &GlocalModel, cfg: &MotionSuiteConfig, base: &GenerateOptions, pairs: &[(&str, &str)]) -> Result<Vec<(String, f64)>> {
    let spec = &model.spec;
    let seed_s = (spec.block_len * spec.stride) as f32 / spec.fps;
    pairs
        .iter()
        .map(|&(from, to)| {
            let (a, b) = (spec.class_index(from)?, spec.class_index(to)?);
            let mut pool = Pool::default();
            for v in 0..PAIR_TAKES {
                let (m, boundaries) = scored_take(model, base, &[(a, seed_s + cfg.segment_seconds), (b, cfg.segment_seconds)], a, v, 1 + v as u64)?;
                pool.add_transitions(&m, &boundaries);
            }
            Ok((format!("{from} -> {to}"), pool.summary()[Measure::TransitionPeak]))
        })
        .collect()
}

/// The measures of one source of takes (real, or generated one way) of one model.
struct Source {
    name: &'static str,
    per_class: Vec<Summary>,
    /// The class-balanced value of each measure: the mean over classes that have one.
    balanced: Summary,
    /// Per class, [`Pool::interval_profile`].
    profile: Vec<Vec<f64>>,
}

impl Source {
    fn new(name: &'static str, pools: &[Pool]) -> Self {
        let per_class: Vec<Summary> = pools.iter().map(Pool::summary).collect();
        let balanced = Summary::from_fn(|m| balanced(&per_class, m));
        Self { name, per_class, balanced, profile: pools.iter().map(Pool::interval_profile).collect() }
    }

    fn json(&self) -> Value {
        json!({"source": self.name, "balanced": self.balanced, "per_class": self.per_class, "interval_profile": self.profile})
    }
}

/// One model's three sources: real, generated without and with the foot lock.
struct ModelResult {
    dataset: Dataset,
    dir: String,
    classes: Vec<String>,
    sources: [Source; 3],
    /// Mean joint speed per class on the training split, which the model learnt from: where a
    /// class moves differently in the test split's styles, the two bounds differ.
    train_speed: Vec<f64>,
    /// Per class, the mean joint speed of each style (Bandai) or subject (Human3.6M), training
    /// split and test split, slowest first.
    tag_speeds: Vec<[Vec<(String, f64)>; 2]>,
    /// Bones over the real p99.9 turn in one frame, in the shipped takes above.
    snaps: SnapTally,
    /// The same limits on the training split's clips in pieces as long as the takes: how
    /// often real motion itself goes past them.
    train_snaps: SnapTally,
    /// The same on the test split's own clips, whose turns the limits are: once in a thousand
    /// frames by their definition, so most pieces of a take's length go past one.
    test_snaps: SnapTally,
    first_takes: Vec<FirstTake>,
    /// The real clips' fastest climb of the hips, which the first takes' is read against.
    real_rise: f32,
    /// Bones over the real p99.9 turn in one frame, in the first takes.
    first_snaps: SnapTally,
    /// The model of everything: transition peaks between activities of two datasets, then
    /// within one (empty for the other models).
    pairs: [Vec<(String, f64)>; 2],
    /// Where each class's clips come from (the model of everything; empty otherwise).
    class_sources: Vec<String>,
}

/// Rows of the class-balanced table: (measure, label, digits).
const ROWS: [(Measure, &str, usize); 19] = [
    (Measure::SkatingRatio, "skating ratio", 3),
    (Measure::ContactFraction, "contact fraction", 3),
    (Measure::SupportSpeedMean, "support speed mean (cm/s)", 1),
    (Measure::SupportSpeedMedian, "support speed median (cm/s)", 1),
    (Measure::Floating, "floating (lowest foot > 5 cm)", 3),
    (Measure::GroundDrift, "ground drift (cm)", 2),
    (Measure::JerkMean, "jerk mean (m/s^3)", 1),
    (Measure::JerkMedian, "jerk median (m/s^3)", 1),
    (Measure::JerkP95, "jerk p95 (m/s^3)", 1),
    (Measure::FrameJerkMean, "per-frame jerk, FlowMDM (m/s^3)", 1),
    (Measure::WindowPeakP95, "2 s window peak jerk p95 (m/s^3)", 1),
    (Measure::SeamRatio, "seam ratio", 2),
    (Measure::SeamAccelRatio, "acceleration at the seam / block mean", 2),
    (Measure::SparseAccelRatio, "acceleration at sparse poses / block mean", 2),
    (Measure::TransitionPeak, "transition peak jerk, within 1 s (m/s^3)", 1),
    (Measure::ElsewherePeak, "2 s window peak jerk elsewhere (m/s^3)", 1),
    (Measure::JointSpeed, "mean joint speed (m/s)", 3),
    (Measure::LongestRepeat, "longest exact repeat (s)", 1),
    (Measure::RepeatLag, "its lag (s)", 1),
];

/// The class-balanced value of `m`: the mean over classes that have one.
fn balanced(per_class: &[Summary], m: Measure) -> f64 {
    let v: Vec<f64> = per_class.iter().map(|s| s[m]).filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn cell(v: f64, digits: usize) -> String {
    fixed_or(v, digits, "-")
}

pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let cfg = &if ctx.options.quick { MotionSuiteConfig::quick() } else { MotionSuiteConfig::full() };
    let mut results = Vec::new();
    for &dataset in &ctx.datasets {
        results.push(model_result(dataset, ctx, cfg, log)?);
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

/// The training split's clips in pieces as the real test split is cut ([`real_pieces`]), each
/// tallied against `limits` as a generated take is.
fn real_snaps(tracks: &[Track], limits: &SnapLimits, seconds: f32) -> SnapTally {
    let mut tally = SnapTally::default();
    for track in tracks {
        let m = track.motion.resample(COMMON_FPS);
        for piece in real_pieces(&m, seconds) {
            tally.add(limits, &format!("{} at {:.1} s", track.file, piece.start as f32 / COMMON_FPS), &m.slice(piece.start, piece.end), 0);
        }
    }
    tally
}

fn model_result(dataset: Dataset, ctx: &SuiteContext, cfg: &MotionSuiteConfig, log: &mut dyn FnMut(&str)) -> Result<ModelResult> {
    let dir = ctx.model_dir(dataset);
    let model = GlocalModel::load(&dir)?;
    let spec = model.spec.clone();
    log(&format!("motion: {dataset} real test split"));
    let corpus = Corpus::for_model(dataset, &ctx.options.data, &spec, &dir)?;
    let roles = JointRoles::new(&corpus.layout.skeleton)?;
    let grid = BlockGrid::new(spec.block_len, spec.stride, spec.fps);
    let real = real_pools(&corpus, &roles, grid, cfg.take_seconds);
    log(&format!("motion: {dataset} generated, no foot lock"));
    let unlocked = generated_pools(&model, cfg, &ctx.generation, false, None)?;
    log(&format!("motion: {dataset} generated, shipped"));
    let limits = SnapLimits::from_tracks(&corpus.test);
    let mut snaps = SnapTally::default();
    let shipped = generated_pools(&model, cfg, &ctx.generation, true, Some((&limits, &mut snaps)))?;
    let mut first_snaps = SnapTally::default();
    let first_takes = first_takes::first_takes(dataset, ctx, &limits, &mut first_snaps, log)?;
    let real_rise = first_takes::real_fastest_rise(&corpus)?;
    let pairs = if dataset == Dataset::Combined {
        log("motion: all, changes between datasets");
        [pair_transition_peaks(&model, cfg, &ctx.generation, &ACROSS_DATASETS)?, pair_transition_peaks(&model, cfg, &ctx.generation, &WITHIN_A_DATASET)?]
    } else {
        Default::default()
    };
    let classes = spec.classes.len();
    let train_sums = joint_speed_sums(&corpus.train, classes);
    Ok(ModelResult {
        dataset,
        dir: dir.display().to_string(),
        classes: spec.classes.clone(),
        sources: [Source::new("real", &real), Source::new("no lock", &unlocked), Source::new("generated", &shipped)],
        train_speed: joint_speed_per_class(&train_sums),
        tag_speeds: joint_speed_per_tag(&train_sums).into_iter().zip(joint_speed_per_tag(&joint_speed_sums(&corpus.test, classes))).map(|(a, b)| [a, b]).collect(),
        snaps,
        train_snaps: real_snaps(&corpus.train, &limits, cfg.take_seconds),
        test_snaps: real_snaps(&corpus.test, &limits, cfg.take_seconds),
        first_takes,
        real_rise,
        first_snaps,
        pairs,
        class_sources: spec.class_sources.clone(),
    })
}

fn model_markdown(r: &ModelResult, md: &mut Markdown) {
    let [real, unlocked, shipped] = &r.sources;
    md.text(&format!("\n**{} ({})**, class-balanced (mean over the {} classes)\n\n", r.dataset, r.dir, r.classes.len()));
    let mut balanced_table = Table::new(["measure", "real test", "no lock", "generated", "no lock / real", "generated / real"]);
    for (m, label, digits) in ROWS {
        let (a, b, c) = (real.balanced[m], unlocked.balanced[m], shipped.balanced[m]);
        balanced_table.row([label.to_string(), cell(a, digits), cell(b, digits), cell(c, digits), cell(b / a, 2), cell(c / a, 2)]);
    }
    let real_p95 = real.balanced[Measure::WindowPeakP95];
    balanced_table.row([
        "transition peak / real window peak p95".to_string(),
        String::new(),
        cell(unlocked.balanced[Measure::TransitionPeak] / real_p95, 2),
        cell(shipped.balanced[Measure::TransitionPeak] / real_p95, 2),
    ]);
    md.table(balanced_table);
    per_source_markdown(r, md);
    if !r.pairs[0].is_empty() {
        md.text(&format!("\nChanges of activity across datasets and within one ({PAIR_TAKES} two-segment takes each, the shipped defaults; transition peak jerk within 1 s of the change):\n\n"));
        let mut pairs = Table::new(["change", "datasets", "transition peak jerk (m/s^3)", "/ real window peak p95"]);
        for (kind, rows) in ["across", "within one"].into_iter().zip(&r.pairs) {
            for (name, peak) in rows {
                pairs.row([name.clone(), kind.to_string(), cell(*peak, 1), cell(peak / real_p95, 2)]);
            }
        }
        md.table(pairs);
    }
    md.text(&format!("\nBones over the real test clips' p99.9 turn in one frame (each bone against its own), generated takes: {}. The training split's clips, in pieces as the test split's are cut, against the same limits: {}. The test split's own clips so cut: {}.\n", r.snaps.describe(), r.train_snaps.describe(), r.test_snaps.describe()));
    // Over the classes that have a profile (the model of everything has classes without a test clip).
    let profile = |p: &[Vec<f64>]| -> String {
        let k = p.iter().map(Vec::len).max().unwrap_or(0);
        let with: Vec<&Vec<f64>> = p.iter().filter(|c| c.len() == k).collect();
        (0..k).map(|i| cell(with.iter().map(|c| c[i]).sum::<f64>() / with.len() as f64, 2)).collect::<Vec<_>>().join(" ")
    };
    md.text(&format!("\nPose speed per sparse interval of a block, over the block's mean (class-balanced; the last interval crosses the seam): real {}; generated {}.\n", profile(&real.profile), profile(&shipped.profile)));
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
        let (real, unlocked, shipped) = (&real.per_class[c], &unlocked.per_class[c], &shipped.per_class[c]);
        let three = |m: Measure, d: usize| format!("{} / {} / {}", cell(real[m], d), cell(unlocked[m], d), cell(shipped[m], d));
        let speed = Measure::JointSpeed;
        per_class.row([
            name.clone(),
            cell(real[speed], 3),
            cell(shipped[speed] / real[speed], 2),
            cell(unlocked[speed] / real[speed], 2),
            cell(r.train_speed[c], 3),
            cell(shipped[speed] / r.train_speed[c], 2),
            three(Measure::SupportSpeedMedian, 1),
            three(Measure::SkatingRatio, 3),
            three(Measure::ContactFraction, 2),
            three(Measure::Floating, 2),
            cell(shipped[Measure::JerkMean] / real[Measure::JerkMean], 2),
        ]);
    }
    md.table(per_class);
    tag_markdown(r, md);
    first_takes::markdown(r.dataset, &r.first_takes, r.real_rise, md);
    md.text(&format!("\nBones over the real p99.9 in one frame, first takes: {}.\n", r.first_snaps.describe()));
}

/// The model of everything's measures per source dataset: the mean over the classes that have
/// clips of that dataset (walking counts for Human3.6M, Bandai and cmu-expmap), real test split
/// against generated.
fn per_source_markdown(r: &ModelResult, md: &mut Markdown) {
    if r.class_sources.is_empty() {
        return;
    }
    let [real, _, shipped] = &r.sources;
    let datasets = Dataset::ARCHIVES;
    let of = |d: Dataset| -> Vec<usize> { (0..r.classes.len()).filter(|&c| r.class_sources[c].split(" + ").any(|s| s.starts_with(&format!("{d} ")))).collect() };
    let mean = |source: &Source, classes: &[usize], m: Measure| balanced(&classes.iter().map(|&c| source.per_class[c]).collect::<Vec<_>>(), m);
    md.text("\nPer source dataset (mean over the classes with clips of it), real test / generated:\n\n");
    let mut table = Table::new(std::iter::once("measure".to_string()).chain(datasets.iter().map(|d| format!("{d} ({} classes)", of(*d).len()))));
    for (m, label, digits) in ROWS.iter().filter(|(m, ..)| PER_SOURCE.contains(m)) {
        table.row(std::iter::once(label.to_string()).chain(datasets.iter().map(|&d| {
            let classes = of(d);
            let (a, b) = (mean(real, &classes, *m), mean(shipped, &classes, *m));
            format!("{} / {} ({}x)", cell(a, *digits), cell(b, *digits), cell(b / a, 2))
        })));
    }
    md.table(table);
}

/// The measures the per-dataset table shows.
const PER_SOURCE: [Measure; 8] = [Measure::SkatingRatio, Measure::ContactFraction, Measure::SupportSpeedMean, Measure::Floating, Measure::JerkMean, Measure::JerkP95, Measure::SeamRatio, Measure::JointSpeed];

/// Each class's joint speed by style or subject: how far the test split's own spread sits
/// from the training split's, which bounds how near any model of the training split can come.
fn tag_markdown(r: &ModelResult, md: &mut Markdown) {
    let tag = if matches!(r.dataset, Dataset::Bandai | Dataset::Combined) { "style" } else { "subject" };
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
    json!({"dataset": r.dataset.name(), "model": r.dir, "bone_snaps": r.snaps, "training_clips_bone_snaps": r.train_snaps, "test_clips_bone_snaps": r.test_snaps, "first_takes": r.first_takes, "first_takes_real_fastest_rise_m_s": r.real_rise, "first_takes_bone_snaps": r.first_snaps, "transitions_across_datasets": r.pairs[0], "transitions_within_a_dataset": r.pairs[1], "classes": r.classes, "sources": r.sources.iter().map(Source::json).collect::<Vec<_>>(), "train_joint_speed": r.train_speed, "joint_speed_per_tag": r.tag_speeds})
}
