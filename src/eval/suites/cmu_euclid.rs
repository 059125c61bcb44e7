//! `glocal eval --suite cmu-euclid`: acLSTM's table, the Euclidean distance per frame at
//! 80..640 ms on CMU walking, Indian dance and martial arts, for the paper's GloGen and its
//! ablations (trained here), the shipped design, and the baselines of [`crate::eval::baselines`].

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use serde_json::{json, Value};

use super::context::{SuiteContext, SuiteOptions};
use crate::data::features::Normalizer;
use crate::data::registry::Dataset;
use crate::eval::baselines::{ArConfig, ArKind, ArModel};
use crate::eval::metrics::{self, HORIZONS_MS};
use crate::eval::table::{fixed as f, Markdown, Table};
use crate::model::corpus::Corpus;
use crate::model::glocal::GlocalModel;
use crate::model::spec::{LossKind, ModelSpec, PoseBase, SeamJoin};
use crate::model::train::{train, Stage, TrainOptions};

/// One GloGen the CMU suite trains and forecasts with.
struct CmuGlogen {
    /// Appended to the cache folder's name.
    suffix: &'static str,
    label: &'static str,
    loss: LossKind,
    use_class: bool,
    /// The paper's GloGen (class at the encoder input only, no class dropout, one block per
    /// training window) rather than the shipped design (class in the decoder too, 10% class
    /// dropout, two-block rollout).
    paper: bool,
    /// What its poses are measured from: the last observed pose, wholly or fading, or none.
    base: PoseBase,
    /// The variant (its suffix) this one fine-tunes on its blocks joined two-sided at their
    /// seams ([`crate::model::spec::GloGenSpec::joined`]), as the shipped models are.
    joins: Option<&'static str>,
}

/// The paper's GloGen and its three ablations, then the design the shipped models use (a
/// joined one fine-tunes the one it names, so it comes after it).
const GLOGEN_VARIANTS: [CmuGlogen; 9] = [
    CmuGlogen { suffix: "", label: "GloGen (L_J + L_MF)", loss: LossKind::JointFlow, use_class: true, paper: true, base: PoseBase::Absolute, joins: None },
    CmuGlogen { suffix: "-lj", label: "GloGen, L_J only", loss: LossKind::Joint, use_class: true, paper: true, base: PoseBase::Absolute, joins: None },
    CmuGlogen { suffix: "-lmf", label: "GloGen, L_MF only", loss: LossKind::Flow, use_class: true, paper: true, base: PoseBase::Absolute, joins: None },
    CmuGlogen { suffix: "-noclass", label: "GloGen, no class prior", loss: LossKind::JointFlow, use_class: false, paper: true, base: PoseBase::Absolute, joins: None },
    CmuGlogen { suffix: "-shipped", label: "GloGen, shipped design (class in the decoder, class dropout, two-block rollout)", loss: LossKind::JointFlow, use_class: true, paper: false, base: PoseBase::Absolute, joins: None },
    CmuGlogen { suffix: "-shipped-joined", label: "GloGen, shipped design, then on two-sided joined blocks (as the shipped models)", loss: LossKind::JointFlow, use_class: true, paper: false, base: PoseBase::Absolute, joins: Some("-shipped") },
    CmuGlogen { suffix: "-residual", label: "GloGen, shipped design, residual poses", loss: LossKind::JointFlow, use_class: true, paper: false, base: PoseBase::Residual, joins: None },
    CmuGlogen { suffix: "-residual-joined", label: "GloGen, shipped design, residual poses, then on two-sided joined blocks", loss: LossKind::JointFlow, use_class: true, paper: false, base: PoseBase::Residual, joins: Some("-residual") },
    CmuGlogen { suffix: "-residual-fade", label: "GloGen, shipped design, residual fading over the block", loss: LossKind::JointFlow, use_class: true, paper: false, base: PoseBase::ResidualFade, joins: None },
];
const CMU_STRIDE: usize = 2;
/// Validation error was still falling at 1200 steps (the budget when GloGen trained at a
/// tenth of today's speed); by 6000 it has levelled off and a GloGen trains in 2-3 minutes.
const CMU_GLOGEN_STEPS: usize = 6000;
/// The joined fine-tuning's steps, as the shipped `all` model's (2000 after its GloGen).
const CMU_JOINED_STEPS: usize = 2000;
const CMU_CONTEXT: usize = 21;
const CMU_HORIZON: usize = 20;
const CMU_WINDOWS_PER_CLASS: usize = 64;

/// Where the variant with `suffix` is cached.
fn variant_dir(opts: &SuiteOptions, dataset: Dataset, suffix: &str) -> PathBuf {
    opts.cache.join(format!("glogen-{}{suffix}", dataset.name()))
}

/// The cached variant, trained first with `--train-baselines`; None when it is missing and
/// training was not asked for (its row then says so).
fn cmu_glogen(opts: &SuiteOptions, dataset: Dataset, variant: &CmuGlogen, log: &mut dyn FnMut(&str)) -> Result<Option<PathBuf>> {
    let dir = variant_dir(opts, dataset, variant.suffix);
    let steps = if variant.joins.is_some() { CMU_JOINED_STEPS } else { CMU_GLOGEN_STEPS };
    let done = ModelSpec::read(&dir).ok().and_then(|s| s.training.glogen).is_some_and(|r| r.steps >= steps);
    if done {
        return Ok(Some(dir));
    }
    if !opts.train_baselines {
        log(&format!("{} on {dataset} is not trained yet; run with --train-baselines", variant.label));
        return Ok(None);
    }
    log(&format!("training {} on {dataset} into {} ({steps} steps)", variant.label, dir.display()));
    let mut t = TrainOptions::new(dataset, Stage::Glogen, dir.clone());
    t.data = opts.data.clone();
    t.steps = steps;
    t.shape.stride = CMU_STRIDE;
    t.shape.block_len = 10;
    t.shape.hidden = 128;
    t.optimiser.batch = 32;
    t.shape.loss = variant.loss;
    t.shape.use_class = variant.use_class;
    t.shape.base = variant.base;
    if let Some(base) = variant.joins {
        t.init_from = Some(variant_dir(opts, dataset, base));
        t.shape.joined = true;
        t.shape.seam_join = SeamJoin::TwoSided;
    }
    if variant.paper {
        t.shape.class_in_decoder = false;
        t.shape.class_dropout = 0.0;
        t.shape.rollout_blocks = 1;
    }
    t.resume = true;
    t.eval_every = 500;
    t.checkpoint_every = 500;
    let started = Instant::now();
    train(&t, &mut |p| {
        if let Some(v) = p.val_error {
            eprintln!("  step {}: loss {:.4}, validation error {v:.3} ({:.0} s)", p.step, p.loss, started.elapsed().as_secs_f32());
        }
    }, &AtomicBool::new(false))?;
    Ok(Some(dir))
}

/// The cached baseline, trained first with `--train-baselines`; None when it is missing
/// and training was not asked for (the table then says so).
fn baseline(opts: &SuiteOptions, corpus: &Corpus, norm: &Normalizer, kind: ArKind, log: &mut dyn FnMut(&str)) -> Result<Option<ArModel>> {
    let cfg = ArConfig::new(kind, CMU_CONTEXT, CMU_HORIZON);
    let name = corpus.dataset.name();
    if let Some(m) = ArModel::load_cached(&opts.cache, name, &cfg, corpus.layout.dim())? {
        return Ok(Some(m));
    }
    if !opts.train_baselines {
        log(&format!("baseline {} on {name} is not trained yet; run with --train-baselines", kind.name()));
        return Ok(None);
    }
    log(&format!("training {} on {name} ({} steps)", kind.name(), cfg.steps));
    let m = ArModel::train(corpus, norm, &cfg, log)?;
    m.save(&opts.cache)?;
    Ok(Some(m))
}

pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let (opts, join_seams) = (&ctx.options, ctx.generation.join_seams);
    let sets = [(Dataset::CmuExpmap, vec![("walking", "Walking")]), (Dataset::CmuDance, vec![("indian", "Indian Dance"), ("martial", "Martial Arts")])];
    let published: [(&str, [(&str, [f64; 8]); 4]); 3] = [
        ("Walking", [
            ("acLSTM", [1.05, 1.77, 2.20, 2.46, 2.66, 2.79, 2.99, 3.24]),
            ("Scheduled sampling", [0.42, 0.56, 0.71, 0.83, 0.93, 0.99, 1.02, 1.05]),
            ("Seq2Seq", [0.09, 0.13, 0.24, 0.42, 0.74, 1.22, 1.85, 2.79]),
            ("GlocalNet (GloGen)", [0.36, 0.47, 0.52, 0.60, 0.62, 0.65, 0.71, 0.82]),
        ]),
        ("Indian Dance", [
            ("acLSTM", [0.685, 0.99, 1.22, 1.53, 1.89, 2.08, 2.27, 2.55]),
            ("Scheduled sampling", [1.54, 2.24, 2.49, 2.52, 2.65, 2.90, 2.94, 3.12]),
            ("Seq2Seq", [0.49, 0.79, 1.48, 2.95, 5.41, 8.88, 13.29, 18.73]),
            ("GlocalNet (GloGen)", [0.50, 0.56, 0.64, 0.68, 0.69, 0.69, 0.79, 0.84]),
        ]),
        ("Martial Arts", [
            ("acLSTM", [0.52, 0.74, 0.95, 1.14, 1.35, 1.56, 1.73, 1.88]),
            ("Scheduled sampling", [0.63, 0.86, 0.91, 0.98, 1.07, 1.12, 1.20, 1.28]),
            ("Seq2Seq", [0.28, 0.43, 0.87, 1.57, 2.53, 3.89, 5.83, 8.62]),
            ("GlocalNet (GloGen)", [0.40, 0.43, 0.47, 0.52, 0.55, 0.59, 0.67, 0.71]),
        ]),
    ];
    let header = || std::iter::once("method".to_string()).chain(HORIZONS_MS.map(|h| format!("{h} ms")));
    let intro = format!(
        "Euclidean distance per frame at 80..640 ms (30 fps data, linear interpolation between frames; GloGen predicts sparse poses {CMU_STRIDE} frames apart from {} observed sparse poses, the baselines dense frames from {CMU_CONTEXT} observed frames). The paper's rows are in the paper's (unstated) units and are not directly comparable.\n",
        10
    );
    let mut md = Markdown::new(intro);
    let mut out = Vec::new();
    for (dataset, classes) in sets {
        let mut glogens = Vec::new();
        for variant in &GLOGEN_VARIANTS {
            glogens.push((variant.label, cmu_glogen(opts, dataset, variant, log)?.map(|dir| GlocalModel::load(&dir)).transpose()?));
        }
        let corpus = Corpus::load(dataset, &opts.data, CMU_STRIDE, 3)?;
        let (_, dense_norm) = corpus.normalizers();
        let mut bases = Vec::new();
        for kind in ArKind::ALL {
            bases.push((kind, baseline(opts, &corpus, &dense_norm, kind, log)?));
        }
        let layout = &corpus.layout;
        let j = layout.joints();
        let fps = corpus.fps;
        for (class_name, title) in classes {
            let class = corpus.classes.iter().position(|c| c == class_name).with_context(|| format!("{dataset} has no class {class_name}"))?;
            let starts = test_windows(&corpus, class, "", CMU_CONTEXT)?;
            let truths = true_futures(&corpus, &starts);
            let mean_rows = |preds: &[Vec<Vec3>], pred_fps: f32| mean_errors(preds, &truths, j, pred_fps, fps);
            let mut rows = vec![("Zero-velocity".to_string(), mean_rows(&zero_velocity(&corpus, &starts), fps))];
            let observed: Vec<Vec<f32>> = starts.iter().map(|&(ti, t0)| layout.encode_motion(&corpus.test[ti].motion, t0 + 1 - CMU_CONTEXT, 1, CMU_CONTEXT)).collect();
            for (kind, b) in &bases {
                let Some(b) = b else {
                    rows.push(untrained(kind.label()));
                    continue;
                };
                let feats = b.predict(&observed, CMU_HORIZON)?;
                let preds: Vec<Vec<Vec3>> = feats
                    .iter()
                    .zip(&starts)
                    .map(|(fe, &(ti, t0))| {
                        let m = &corpus.test[ti].motion;
                        let mut p = m.frame(t0).to_vec();
                        p.extend(layout.decode(fe, layout.placement(m.frame(t0))).0);
                        p
                    })
                    .collect();
                rows.push((b.record.config.kind.label().to_string(), mean_rows(&preds, fps)));
            }
            for (label, model) in &glogens {
                let Some(model) = model else {
                    rows.push(untrained(label));
                    continue;
                };
                let k = model.spec.classes.iter().position(|c| c == class_name).unwrap_or(0);
                rows.push((label.to_string(), mean_rows(&forecasts(model, &corpus, &starts, k, join_seams)?, fps / CMU_STRIDE as f32)));
            }
            let unit = corpus.layout.skeleton.meters_per_unit();
            md.text(&format!(
                "\n**{title}** ({dataset}, class `{class_name}`, {} test windows; mean joint distance in the files' own units, world positions including the root's path)\n\n",
                starts.len()
            ));
            let mut table = Table::new(header());
            for (label, r) in &rows {
                table.row(std::iter::once(label.clone()).chain(r.map(|v| f(v, 3))));
            }
            if let Some((_, pubrows)) = published.iter().find(|(t, _)| *t == title) {
                for (label, r) in pubrows {
                    table.row(std::iter::once(format!("*paper: {label}*")).chain(r.map(|v| f(v, 2))));
                }
            }
            md.table(table);
            out.push(json!({
                "motion": title, "dataset": dataset.name(), "class": class_name, "windows": starts.len(),
                "unit_meters": unit,
                "rows": rows.iter().map(|(l, r)| json!({"method": l, "errors": r})).collect::<Vec<_>>(),
            }));
        }
    }
    let shipped = shipped_all(ctx, &mut md)?;
    Ok((md, json!({"horizons_ms": HORIZONS_MS, "tables": out, "shipped_all": shipped})))
}

/// The studio's own model, `models/all`, forecasting the same three motions' test clips
/// retargeted onto its skeleton, against zero-velocity on the same windows: the tables above
/// train each GloGen on one CMU set at its stride; this is the shipped GloGen itself.
fn shipped_all(ctx: &SuiteContext, md: &mut Markdown) -> Result<Value> {
    let dir = ctx.model_dir(Dataset::Combined);
    let model = GlocalModel::load(&dir).with_context(|| format!("the shipped model {}", dir.display()))?;
    let corpus = Corpus::load(Dataset::Combined, &ctx.options.data, model.spec.stride, 3)?;
    let (j, fps) = (corpus.layout.joints(), corpus.fps);
    let context = model.spec.observed_span() + model.spec.stride;
    md.text(&format!(
        "\n**The shipped `{}`** (every clip retargeted onto its skeleton, metres; it forecasts {} sparse poses {} frames apart from {} observed, class strength 1, blocks joined as in generation; the same test clips as above, windows of each motion's clips from its CMU set only)\n\n",
        dir.display(),
        model.spec.block_len,
        model.spec.stride,
        model.spec.block_len
    ));
    let mut table = Table::new(std::iter::once("motion, method".to_string()).chain(HORIZONS_MS.map(|h| format!("{h} ms"))));
    let mut out = Vec::new();
    for (class_name, source, title) in [("walking", "cmu-expmap", "Walking"), ("indian", "cmu-dance", "Indian Dance"), ("martial", "cmu-dance", "Martial Arts")] {
        let class = corpus.classes.iter().position(|c| c == class_name).with_context(|| format!("{} has no class {class_name}", dir.display()))?;
        let starts = test_windows(&corpus, class, source, context)?;
        let truths = true_futures(&corpus, &starts);
        let zero = mean_errors(&zero_velocity(&corpus, &starts), &truths, j, fps, fps);
        let glogen = mean_errors(&forecasts(&model, &corpus, &starts, class, ctx.generation.join_seams)?, &truths, j, fps / model.spec.stride as f32, fps);
        for (label, r) in [("Zero-velocity", zero), ("GloGen (shipped)", glogen)] {
            table.row(std::iter::once(format!("{title} ({} windows), {label}", starts.len())).chain(r.map(|v| f(v * 1000.0, 1))));
        }
        out.push(json!({"motion": title, "windows": starts.len(), "zero_velocity_m": zero, "glogen_m": glogen}));
    }
    md.text("Errors in millimetres.\n\n");
    md.table(table);
    Ok(Value::Array(out))
}

/// Up to [`CMU_WINDOWS_PER_CLASS`] test windows of `class`, evenly over those of its clips
/// whose file starts with `source` (every clip for ""), as (clip, last observed frame) with
/// `context` frames observed before and [`CMU_HORIZON`] after.
fn test_windows(corpus: &Corpus, class: usize, source: &str, context: usize) -> Result<Vec<(usize, usize)>> {
    let mut starts = Vec::new();
    for (ti, t) in corpus.test.iter().enumerate().filter(|(_, t)| t.class == class && t.file.starts_with(source)) {
        let n = t.motion.frames();
        if n > context + CMU_HORIZON + 1 {
            starts.extend((context..n - CMU_HORIZON - 1).step_by(5).map(|t0| (ti, t0)));
        }
    }
    let step = (starts.len() as f64 / CMU_WINDOWS_PER_CLASS as f64).max(1.0);
    let starts: Vec<(usize, usize)> = (0..).map(|k| (k as f64 * step) as usize).take_while(|&i| i < starts.len()).map(|i| starts[i]).collect();
    if starts.is_empty() {
        bail!("{} {}: no test window", corpus.dataset, corpus.classes[class]);
    }
    Ok(starts)
}

/// The row of a method not trained yet.
fn untrained(label: &str) -> (String, [f64; 8]) {
    (format!("{label} (not trained: run with --train-baselines)"), [f64::NAN; 8])
}

/// Each window's last observed frame and the [`CMU_HORIZON`] frames after it.
fn true_futures(corpus: &Corpus, starts: &[(usize, usize)]) -> Vec<Vec<Vec3>> {
    starts.iter().map(|&(ti, t0)| (0..=CMU_HORIZON).flat_map(|k| corpus.test[ti].motion.frame(t0 + k).to_vec()).collect()).collect()
}

/// Each window's last observed frame, held.
fn zero_velocity(corpus: &Corpus, starts: &[(usize, usize)]) -> Vec<Vec<Vec3>> {
    starts.iter().map(|&(ti, t0)| corpus.test[ti].motion.frame(t0).to_vec()).collect()
}

/// `model`'s block after each window, its last observed frame first.
fn forecasts(model: &GlocalModel, corpus: &Corpus, starts: &[(usize, usize)], class: usize, join_seams: bool) -> Result<Vec<Vec<Vec3>>> {
    starts
        .iter()
        .map(|&(ti, t0)| {
            let m = &corpus.test[ti].motion;
            let mut p = m.frame(t0).to_vec();
            p.extend(model.forecast(m, t0, class, 1, join_seams)?);
            Ok(p)
        })
        .collect()
}

/// The mean over windows of the joint error at each horizon.
fn mean_errors(preds: &[Vec<Vec3>], truths: &[Vec<Vec3>], joints: usize, pred_fps: f32, truth_fps: f32) -> [f64; 8] {
    let mut acc = [0.0; 8];
    for (p, t) in preds.iter().zip(truths) {
        let e = metrics::horizon_errors(p, t, joints, pred_fps, truth_fps);
        for k in 0..8 {
            acc[k] += e[k] / preds.len() as f64;
        }
    }
    acc
}
