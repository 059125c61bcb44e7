//! `glocal eval --suite styles`: style control on a model with styles (`models/all`). A style
//! classifier is trained on the Bandai clips styles are learned from (the training clips and
//! the test clips that teach tired and musical), on the model's skeleton, by style; each of
//! Bandai's classes is then generated in each style, and the classifier says which style it
//! sees. How far the classifier can be trusted is measured by a second one, trained without
//! one content's clips and tested on them.

use anyhow::{bail, Context, Result};
use serde_json::{json, Value};

use super::context::SuiteContext;
use crate::data::combined::NEUTRAL;
use crate::data::registry::Dataset;
use crate::eval::classifier::{Classifier, ClassifierConfig};
use crate::eval::motion::joint_speed_sums;
use crate::eval::table::{fixed as f, Markdown, Table};
use crate::model::corpus::{mean_joint_speed, Corpus, Track};
use crate::model::glocal::GlocalModel;
use crate::synth::{generate, GenerateOptions, InitPose, Segment, Timeline};

/// The Bandai content whose clips test the style classifier (it never trains on them).
const HELD_OUT_CONTENT: &str = "bye";
/// Generated takes per class and style.
const TAKES: usize = 4;
/// Where each take is scored: the window right after the seed, and after a 2 s transition
/// from the seed's own style (as class control is scored after 2 s from another class's seed).
const SETTLE_SECONDS: [f32; 2] = [0.0, 2.0];

/// Seconds of the takes a style's settled pace is read on, and from when: after the pace's
/// first 6 s (the seed's own motion and the style's taking over).
const SETTLED_SECONDS: f32 = 12.0;
const SETTLED_FROM: f32 = 6.0;

/// Each Bandai class's generated joint speed in each style against its training clips of that
/// style (Bandai's byebye waves at 0.02 m/s sad and 0.71 active: judged per style, a class's
/// speed over all its clips says little), the takes read `when`. Returns (class, style,
/// generated / training) rows.
fn speed_markdown(corpus: &Corpus, classes: &[String], bandai_classes: &[usize], styles: &[usize], speeds: &[Vec<f32>], when: &str, md: &mut Markdown) -> Vec<(String, String, f32)> {
    let mut rows = Vec::new();
    let mut ratios = Vec::new();
    // The style-training clips' speed per class and tag: a Bandai clip's tag is its style.
    let training = joint_speed_sums(corpus.style_training(), classes.len());
    for (row, &class) in bandai_classes.iter().enumerate() {
        for (label, &style) in styles.iter().enumerate() {
            let Some(&(sum, count)) = training[class].get(corpus.styles[style].as_str()) else { continue };
            let ratio = speeds[row][label] / (sum / count.max(1) as f64) as f32;
            ratios.push(ratio);
            rows.push((classes[class].clone(), corpus.styles[style].clone(), ratio));
        }
    }
    let within = ratios.iter().filter(|r| (0.6..=1.6).contains(*r)).count();
    md.text(&format!(
        "\nJoint speed of each class in each style, generated ({when}) over its training clips of that style: {within} of {} within 0.6-1.6x; byebye by style: {}.\n",
        ratios.len(),
        rows.iter().filter(|r| r.0 == "byebye").map(|r| format!("{} {:.2}", r.1, r.2)).collect::<Vec<_>>().join(", ")
    ));
    rows
}

/// The Bandai clips of `corpus` styles are learned from, labelled by style (among `styles`,
/// indices into the corpus's), the `held_out` content's as the test split.
fn style_corpus(corpus: &Corpus, styles: &[usize], held_out: Option<&str>) -> Corpus {
    let held_out = held_out.and_then(|h| corpus.classes.iter().position(|c| c == h));
    let relabel = |t: &Track| -> Option<Track> {
        let label = styles.iter().position(|&s| Some(s) == t.style)?;
        t.file.starts_with("bandai").then(|| Track { class: label, ..t.clone() })
    };
    let (test, train): (Vec<(bool, Track)>, Vec<(bool, Track)>) = corpus.style_training().filter_map(|t| relabel(t).map(|r| (Some(t.class) == held_out, r))).partition(|(held, _)| *held);
    let tracks = |split: Vec<(bool, Track)>| split.into_iter().map(|(_, t)| t).collect();
    // The style classifier's classes are the styles.
    Corpus { classes: styles.iter().map(|&s| corpus.styles[s].clone()).collect(), class_sources: Vec::new(), styles: Vec::new(), ..corpus.with_tracks(tracks(train), tracks(test)) }
}

pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let dir = ctx.model_dir(Dataset::Combined);
    let model = GlocalModel::load(&dir)?;
    let spec = model.spec.clone();
    if spec.styles.is_empty() {
        bail!("{}: the model has no styles", dir.display());
    }
    log("styles: loading data");
    let corpus = Corpus::load(Dataset::Combined, &ctx.options.data, spec.stride, 3)?;
    // The model's styles as indices into the data's: the two lists differ when the data's
    // split has changed since the model was trained (a style-classifier label is the data's).
    let styles: Vec<usize> = spec
        .styles
        .iter()
        .filter(|s| *s != NEUTRAL)
        .map(|s| corpus.style_index(s).with_context(|| format!("{}: the model's style '{s}' is not in the data", dir.display())))
        .collect::<Result<_>>()?;
    let cfg = ClassifierConfig::default();
    let reference = Classifier::load_or_train(&style_corpus(&corpus, &styles, Some(HELD_OUT_CONTENT)), &cfg, &ctx.options.cache, "style-classifier-held-out-bye", log)?;
    let clf = Classifier::load_or_train(&style_corpus(&corpus, &styles, None), &cfg, &ctx.options.cache, "style-classifier-every-content", log)?;
    // The class classifier of the class-control suite: does a style cost the take its class?
    let class_clf = Classifier::load_or_train(&corpus, &cfg, &ctx.options.cache, &format!("classifier-{}", Dataset::Combined), log)?;
    let bandai_classes: Vec<usize> = (0..spec.classes.len()).filter(|&c| spec.class_sources.get(c).is_some_and(|s| s.contains("bandai"))).collect();
    log("styles: generating");
    // Per settle, per class and style: takes whose style was recognised.
    let mut hits = vec![vec![vec![0usize; styles.len()]; bandai_classes.len()]; SETTLE_SECONDS.len()];
    // Per class and style: takes whose class was recognised after the transition.
    let mut class_hits = vec![vec![0usize; styles.len()]; bandai_classes.len()];
    // Joint speed (m/s) of each class's generated takes in each style, averaged over the
    // takes: from right after the seed, and settled.
    let mut speeds = vec![vec![0.0f32; styles.len()]; bandai_classes.len()];
    let mut settled_speeds = speeds.clone();
    let seed_frames = spec.block_len * spec.stride;
    let settle_frames = SETTLE_SECONDS.map(|s| (s * spec.fps).round() as usize);
    let seconds = (seed_frames + settle_frames[1] + cfg.frames + 2 * spec.stride) as f32 / spec.fps;
    for (row, &class) in bandai_classes.iter().enumerate() {
        for (label, &style) in styles.iter().enumerate() {
            for v in 0..TAKES {
                let segment = Segment { style: Some(corpus.styles[style].clone()), ..Segment::new(spec.classes[class].clone(), seconds) };
                let opts = GenerateOptions { timeline: Timeline { segments: vec![segment] }, init: InitPose::SeedClass { class: spec.classes[class].clone(), variant: v }, ..ctx.generation.clone() }.varied(1 + v as u64);
                let take = generate(&model, &opts, &mut |_| true)?;
                let clips: Vec<Vec<f32>> = settle_frames.iter().map(|&s| clf.clip(&take.motion, seed_frames + s)).collect();
                for (settle, predicted) in clf.predict(&clips)?.into_iter().enumerate() {
                    hits[settle][row][label] += usize::from(predicted == label);
                }
                let settled = class_clf.clip(&take.motion, seed_frames + settle_frames[1]);
                class_hits[row][label] += usize::from(class_clf.predict(&[settled])?[0] == class);
                speeds[row][label] += mean_joint_speed(&take.motion.slice(seed_frames, take.motion.frames())) / TAKES as f32;
                let long = GenerateOptions { timeline: Timeline { segments: vec![Segment { seconds: SETTLED_SECONDS, ..opts.timeline.segments[0].clone() }] }, ..opts };
                let take = generate(&model, &long, &mut |_| true)?.motion;
                let from = (SETTLED_FROM * take.fps).round() as usize;
                settled_speeds[row][label] += mean_joint_speed(&take.slice(from, take.frames())) / TAKES as f32;
            }
        }
    }
    let accuracy = |h: &[usize]| h.iter().sum::<usize>() as f64 / (h.len() * TAKES) as f64;
    let overall: Vec<f64> = hits.iter().map(|by_class| by_class.iter().map(|h| accuracy(h)).sum::<f64>() / by_class.len().max(1) as f64).collect();
    let mut md = Markdown::new(format!(
        "Style control ({}, class strength {}): a GRU style classifier ({} frames at {} fps) trained on Bandai's clips by style (its training clips and the test clips that teach a style; {} styles; chance {:.3}). The same classifier trained without the content '{HELD_OUT_CONTENT}' recognises the style of its real clips at {:.3} ({} windows): the classifier's own reliability on unseen clips. Each of Bandai's {} classes generated {TAKES} times in each style from its own seed (a clip of any style), scored on the {} frames right after the seed and on those after a {} s transition; the same {TAKES} again {SETTLED_SECONDS} s long, whose joint speed is read from {SETTLED_FROM} s on (a style asked for by name keeps its clips' pace).\n\n",
        dir.display(), ctx.generation.class_strength_for(&spec), cfg.frames, spec.fps, styles.len(), 1.0 / styles.len() as f64, reference.record.test_accuracy, reference.record.test_windows, bandai_classes.len(), cfg.frames, SETTLE_SECONDS[1]
    ));
    let kept: Vec<f64> = class_hits.iter().map(|h| accuracy(h)).collect();
    let kept_overall = kept.iter().sum::<f64>() / kept.len().max(1) as f64;
    let mut table = Table::new(["class", "style recognised, right after the seed", "after a 2 s transition", "class recognised after 2 s (class-control classifier)"]);
    for (row, &class) in bandai_classes.iter().enumerate() {
        table.row([spec.classes[class].clone(), f(accuracy(&hits[0][row]), 2), f(accuracy(&hits[1][row]), 2), f(kept[row], 2)]);
    }
    table.row(["all Bandai classes".to_string(), f(overall[0], 3), f(overall[1], 3), f(kept_overall, 3)]);
    md.table(table);
    let per_style: Vec<Vec<f64>> = hits.iter().map(|by_class| (0..styles.len()).map(|l| by_class.iter().map(|h| h[l]).sum::<usize>() as f64 / (by_class.len() * TAKES) as f64).collect()).collect();
    let speed_rows = speed_markdown(&corpus, &spec.classes, &bandai_classes, &styles, &speeds, "right after the seed", &mut md);
    let settled_rows = speed_markdown(&corpus, &spec.classes, &bandai_classes, &styles, &settled_speeds, &format!("{SETTLED_SECONDS} s takes from {SETTLED_FROM} s on"), &mut md);
    let listed = |accuracies: &[f64]| styles.iter().zip(accuracies).map(|(&s, a)| format!("{} {a:.2}", corpus.styles[s])).collect::<Vec<_>>().join(", ");
    md.text(&format!("\nPer style, right after the seed: {}; after 2 s: {}.\n", listed(&per_style[0]), listed(&per_style[1])));
    Ok((md, json!({
        "model": dir, "styles": styles.iter().map(|&s| corpus.styles[s].clone()).collect::<Vec<_>>(),
        "reference_classifier": {"test_accuracy": reference.record.test_accuracy, "test_windows": reference.record.test_windows, "held_out_content": HELD_OUT_CONTENT},
        "settle_seconds": SETTLE_SECONDS,
        "per_class": bandai_classes.iter().enumerate().map(|(row, &c)| json!({"class": spec.classes[c], "accuracy": hits.iter().map(|h| accuracy(&h[row])).collect::<Vec<_>>()})).collect::<Vec<_>>(),
        "per_style": per_style, "accuracy": overall, "class_kept": kept, "class_kept_overall": kept_overall, "speed_per_style": speed_rows, "settled_speed_per_style": settled_rows,
    })))
}
