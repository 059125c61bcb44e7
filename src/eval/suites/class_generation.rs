//! `glocal eval --suite h36m`, `--suite bandai` and `--suite combined`: class-conditioned generation scored by
//! the action classifier (FID, accuracy, diversity, multimodality), and the class-control
//! matrix (every start, every transition length).

use anyhow::{bail, Result};
use serde_json::{json, Value};

use super::context::SuiteContext;
use crate::data::registry::Dataset;
use crate::eval::classifier::{real_windows, Classifier, ClassifierConfig};
use crate::eval::metrics;
use crate::eval::table::{fixed as f, Markdown, Table};
use crate::model::corpus::Corpus;
use crate::model::glocal::GlocalModel;
use crate::motion::Motion;
use crate::synth::{generate, GenerateOptions, InitPose, Segment, Timeline};

const GEN_VARIANTS: usize = 16;
const GEN_NOISE_SEEDS: [u64; 2] = [1, 2];
const REAL_PER_CLASS: usize = 64;
/// FID's second reading draws every set in the real test split's mix of classes, as
/// Action2Motion and MDM draw their conditioning labels from the data: of each class, this
/// share of the test split's windows of it (a class-control set has 16 takes a class, the
/// test split up to 64 windows). `all`'s test split is two thirds Human3.6M windows (the other
/// datasets' test clips are short), its generated sets a class each in turn, its training
/// windows half Human3.6M's: FID between sets of different mixes measures the mixes.
const TEST_MIX_SHARE: f64 = 0.25;
/// Seconds between the start of the requested class and the scored frames.
const TRANSITIONS_S: [f32; 3] = [0.0, 1.0, 2.0];
/// Length of the previous timeline segment in the "previous segment" start.
const PREVIOUS_SEGMENT_S: f32 = 4.0;

/// Where a scored take comes from before its requested class begins.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Start {
    /// A seed-bank window of the requested class.
    SameClass,
    /// A seed-bank window of another class.
    OtherSeed,
    /// The last poses of a timeline segment of another class (itself started from its seed).
    PreviousSegment,
}

impl Start {
    const ALL: [Start; 3] = [Start::SameClass, Start::OtherSeed, Start::PreviousSegment];

    fn label(self) -> &'static str {
        match self {
            Start::SameClass => "same class's seed",
            Start::OtherSeed => "other class's seed",
            Start::PreviousSegment => "previous segment of another class",
        }
    }
}

/// Generates a take that requests `class` from `start` and returns it with the first of the
/// `frames` scored frames, `transition_s` after the requested class begins.
#[allow(clippy::too_many_arguments)]
fn scored_take(model: &GlocalModel, generation: &GenerateOptions, class: usize, start: Start, other: usize, variant: usize, seed: u64, transition_s: f32, frames: usize) -> Result<(Motion, usize)> {
    let spec = model.spec.clone();
    let transition = (transition_s * spec.fps).round() as usize;
    let scored_s = (transition + frames + 2 * spec.stride) as f32 / spec.fps;
    let seed_s = (spec.block_len * spec.stride) as f32 / spec.fps;
    let segment = |c: usize, seconds: f32| Segment::new(spec.classes[c].clone(), seconds);
    let (segments, init_class) = match start {
        Start::SameClass => (vec![segment(class, seed_s + scored_s)], class),
        Start::OtherSeed => (vec![segment(class, seed_s + scored_s)], other),
        Start::PreviousSegment => (vec![segment(other, PREVIOUS_SEGMENT_S), segment(class, scored_s)], other),
    };
    let opts = GenerateOptions {
        timeline: Timeline { segments },
        init: InitPose::SeedClass { class: spec.classes[init_class].clone(), variant },
        ..generation.clone()
    }
    .varied(seed);
    let g = generate(model, &opts, &mut |_| true)?;
    // The seed's own poses open a single-segment take; the requested segment's span says
    // where it begins otherwise.
    let class_begins = if start == Start::PreviousSegment { g.segments[1].start_frame } else { spec.block_len * spec.stride };
    let first = class_begins + transition;
    if g.motion.frames() < first + frames {
        bail!("generated take too short: {} frames", g.motion.frames());
    }
    Ok((g.motion, first))
}

/// FID, accuracy, diversity and multimodality of clips against the real test features.
struct Scores {
    fid: f64,
    /// FID of the set drawn in the test split's class mix ([`TEST_MIX_SHARE`]).
    fid_test_mix: f64,
    accuracy: f64,
    diversity: f64,
    multimodality: f64,
    /// Accuracy per requested class.
    per_class: Vec<f64>,
    /// How often each requested class (row) was recognised as each class (column).
    confusion: Vec<Vec<usize>>,
}

impl Scores {
    fn json(&self) -> Value {
        json!({"fid": self.fid, "fid_test_mix": self.fid_test_mix, "accuracy": self.accuracy, "diversity": self.diversity, "multimodality": self.multimodality, "per_class_accuracy": self.per_class, "confusion": self.confusion})
    }

    fn row(&self, label: String) -> [String; 6] {
        [label, f(self.fid, 2), f(self.fid_test_mix, 2), f(self.accuracy, 3), f(self.diversity, 2), f(self.multimodality, 2)]
    }
}

/// How many windows of each of `classes` classes the test split's `labels` hold.
fn class_counts(labels: &[usize], classes: usize) -> Vec<usize> {
    (0..classes).map(|c| labels.iter().filter(|&&l| l == c).count()).collect()
}

/// The indices of a set labelled `labels` that draw it in the test split's class mix: of each
/// class, [`TEST_MIX_SHARE`] of as many as the test split has windows of it (`test_counts`),
/// or as many as the set has, spread evenly over the class's items (a real split's windows
/// run clip by clip, subject by subject).
fn in_test_mix(labels: &[usize], test_counts: &[usize]) -> Vec<usize> {
    let mut picked = Vec::new();
    for (class, &count) in test_counts.iter().enumerate() {
        let items: Vec<usize> = (0..labels.len()).filter(|&i| labels[i] == class).collect();
        let wanted = ((count as f64 * TEST_MIX_SHARE).round() as usize).min(items.len());
        picked.extend((0..wanted).map(|k| items[k * items.len() / wanted]));
    }
    picked
}

/// FID of the features `feats` (labelled `labels`) drawn in the test split's class mix.
fn fid_in_test_mix(feats: &[Vec<f32>], labels: &[usize], test_f: &[Vec<f32>], test_counts: &[usize]) -> f64 {
    let drawn: Vec<Vec<f32>> = in_test_mix(labels, test_counts).into_iter().map(|i| feats[i].clone()).collect();
    metrics::fid(&drawn, test_f)
}

fn score(clf: &Classifier, clips: &[Vec<f32>], labels: &[usize], test_f: &[Vec<f32>], test_counts: &[usize]) -> Result<Scores> {
    let k = test_counts.len();
    let feats = clf.features(clips)?;
    let pred = clf.predict(clips)?;
    let per_class = (0..k)
        .map(|c| {
            let idx: Vec<usize> = (0..labels.len()).filter(|&i| labels[i] == c).collect();
            idx.iter().filter(|&&i| pred[i] == c).count() as f64 / idx.len().max(1) as f64
        })
        .collect();
    let mut confusion = vec![vec![0; k]; k];
    for (&want, &got) in labels.iter().zip(&pred) {
        confusion[want][got] += 1;
    }
    Ok(Scores {
        fid: metrics::fid(&feats, test_f),
        fid_test_mix: fid_in_test_mix(&feats, labels, test_f, test_counts),
        accuracy: metrics::accuracy(&pred, labels),
        diversity: metrics::diversity(&feats, 200, 3),
        multimodality: metrics::multimodality(&feats, labels, k, 20, 4),
        per_class,
        confusion,
    })
}

pub(super) fn run(dataset: Dataset, ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let (opts, generation) = (&ctx.options, &ctx.generation);
    let dir = ctx.model_dir(dataset);
    let model = GlocalModel::load(&dir)?;
    let spec = model.spec.clone();
    log(&format!("{dataset}: loading data"));
    let corpus = Corpus::for_model(dataset, &opts.data, &spec, &dir)?;
    let cfg = ClassifierConfig::default();
    let clf = Classifier::load_or_train(&corpus, &cfg, &opts.cache, &format!("classifier-{dataset}"), log)?;
    let k = spec.classes.len();
    let frames = cfg.frames;
    let (test_labels, test_clips): (Vec<usize>, Vec<Vec<f32>>) = real_windows(&corpus.layout, &corpus.test, k, frames, frames / 2, REAL_PER_CLASS).into_iter().unzip();
    let (train_labels, train_clips): (Vec<usize>, Vec<Vec<f32>>) = real_windows(&corpus.layout, &corpus.train, k, frames, frames / 2, REAL_PER_CLASS).into_iter().unzip();
    let test_f = clf.features(&test_clips)?;
    let train_f = clf.features(&train_clips)?;
    let test_counts = class_counts(&test_labels, k);
    let mut real = score(&clf, &test_clips, &test_labels, &test_f, &test_counts)?;
    real.fid = metrics::fid(&train_f, &test_f);
    real.fid_test_mix = fid_in_test_mix(&train_f, &train_labels, &test_f, &test_counts);
    log(&format!("{dataset}: generating"));
    let (mut gen_clips, mut gen_labels) = (Vec::new(), Vec::new());
    for class in 0..k {
        for v in 0..GEN_VARIANTS {
            for seed in GEN_NOISE_SEEDS {
                let (m, first) = scored_take(&model, generation, class, Start::SameClass, class, v, seed, 0.0, frames)?;
                gen_clips.push(clf.clip(&m, first));
                gen_labels.push(class);
            }
        }
    }
    let generated = score(&clf, &gen_clips, &gen_labels, &test_f, &test_counts)?;
    // The class-control matrix: every start, every transition length, 16 takes per class
    // (the other class cycles through all the others).
    let mut conditions = Vec::new();
    for start in Start::ALL {
        for transition_s in TRANSITIONS_S {
            let (mut clips, mut labels) = (Vec::new(), Vec::new());
            for class in 0..k {
                // Past the class's seed windows the variants wrap, with other starts and seeds.
                for v in 0..opts.class_control_takes {
                    let other = (class + 1 + v % (k - 1)) % k;
                    // Each take its own variation seed, as repeated takes in the studio.
                    let (m, first) = scored_take(&model, generation, class, start, other, v, 1 + v as u64, transition_s, frames)?;
                    clips.push(clf.clip(&m, first));
                    labels.push(class);
                }
            }
            conditions.push((start, transition_s, clips.len(), score(&clf, &clips, &labels, &test_f, &test_counts)?));
        }
    }
    let class_strength = generation.class_strength_for(&spec);
    let mut md = Markdown::new(format!(
        "{dataset} ({}, {:?} transition, class strength {}, keep-alive {}): classifier GRU({}) on {frames}-frame clips at {} fps, trained on the real training split ({} steps, {:.0} s), test accuracy {:.3} on {} real test windows. FID against the real test windows' classifier features, of each set whole and drawn in the test split's class mix ({} of each class's test windows, {} clips of a full set); diversity over 200 random pairs, multimodality over 20 pairs per class (Action2Motion). Class-conditioned: {} clips ({} classes x {} seeds x {} noise seeds, the {frames} frames right after the seed). Class control: {} takes per class and condition, each requesting its class from a start (the class's own seed, another class's seed, or the last poses of a {PREVIOUS_SEGMENT_S} s timeline segment of another class), scored on the {frames} frames that follow a transition of 0, 1 or 2 s after the requested class begins.\n\n",
        dir.display(), generation.transition, class_strength, if generation.keep_alive { "on" } else { "off" }, cfg.hidden, spec.fps, cfg.steps, clf.record.train_seconds, clf.record.test_accuracy, clf.record.test_windows,
        TEST_MIX_SHARE, in_test_mix(&gen_labels, &test_counts).len(),
        gen_clips.len(), k, GEN_VARIANTS, GEN_NOISE_SEEDS.len(), opts.class_control_takes
    ));
    let mut samples = Table::new(["samples", "FID", "FID, test split's class mix", "accuracy", "diversity", "multimodality"]);
    samples.row(real.row("Real test split (reference; FID = train vs test)".into()));
    samples.row(generated.row("GlocalNet, class-conditioned".into()));
    for (start, transition_s, n, s) in &conditions {
        samples.row(s.row(format!("class control: {}, {transition_s} s transition ({n} clips)", start.label())));
    }
    md.table(samples);
    md.text("\nPer class, accuracy of the requested class (class control after a 2 s transition):\n\n");
    let mut per_class = Table::new(["class", "real test windows", "conditioned", "same class's seed", "other class's seed", "previous segment"]);
    let after_2s: Vec<&Scores> = conditions.iter().filter(|c| c.1 == 2.0).map(|c| &c.3).collect();
    for c in 0..k {
        let real_test = if test_labels.contains(&c) { f(real.per_class[c], 2) } else { "no test clip".into() };
        per_class.row([spec.classes[c].clone(), real_test, f(generated.per_class[c], 2)].into_iter().chain(after_2s.iter().map(|s| f(s.per_class[c], 2))));
    }
    md.table(per_class);
    Ok((md, json!({
        "model": dir, "classes": spec.classes, "transition": generation.transition, "class_strength": class_strength, "keep_alive": generation.keep_alive,
        "classifier": {"config": cfg, "test_accuracy": clf.record.test_accuracy, "test_windows": clf.record.test_windows, "train_seconds": clf.record.train_seconds},
        "real_test": real.json(), "generated": generated.json(),
        "class_control": conditions.iter().map(|(start, transition_s, n, s)| json!({"start": format!("{start:?}"), "transition_s": transition_s, "clips": n, "scores": s.json()})).collect::<Vec<_>>(),
        "samples": {"generated": gen_clips.len(), "real_test": test_clips.len(), "real_train": train_clips.len()},
    })))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A set is drawn in the test split's mix: a quarter as many of each class as the test
    /// split has windows of it, spread over the class's items, or all the set has.
    #[test]
    fn a_set_is_drawn_in_the_test_splits_class_mix() {
        let labels = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2];
        assert_eq!(class_counts(&[0, 0, 1, 2, 2, 2], 3), vec![2, 1, 3]);
        assert_eq!(in_test_mix(&labels, &[16, 4, 0]), vec![0, 2, 4, 6, 8]);
        assert_eq!(in_test_mix(&labels, &[64, 8, 8]), vec![0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 12]);
    }
}
