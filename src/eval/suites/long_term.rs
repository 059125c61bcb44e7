//! `glocal eval --suite long-term`: two-minute takes of every class, judged per 10 s window
//! (speed against the class's real speed, bone lengths, finiteness), with and without the
//! bone projection and keep-alive.

use anyhow::Result;
use serde_json::{json, Value};

use super::context::SuiteContext;
use crate::eval::metrics;
use crate::eval::table::{fixed as f, Markdown, Table};
use crate::model::glocal::GlocalModel;
use crate::synth::{generate, GenerateOptions, InitPose, Segment, Timeline};

pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let mut md = Markdown::new("Each class generated for 120 s from its first seed (noise seed 1), judged per 10 s window: mean joint speed over the class's real mean speed (training split), relative bone-length error (after the shipped bone projection, and of the raw network output without it), and whether every value is finite. Keep-alive (re-anchoring a stalled segment on its class's seed windows) is on, as shipped; one column gives the lowest window speed with it off. The 60 s columns are the first six windows of the same take.\n");
    let mut out = Vec::new();
    for &dataset in &ctx.datasets {
        let dir = ctx.model_dir(dataset);
        if !dir.join("glogen.safetensors").exists() {
            md.text(&format!("\n{}: no model.\n", dir.display()));
            continue;
        }
        let model = GlocalModel::load(&dir)?;
        let spec = model.spec.clone();
        log(&format!("long-term: {}", dir.display()));
        md.text(&format!("\n**{}** ({}; LocGen: {})\n\n", dir.display(), dataset, model.has_locgen()));
        let mut table = Table::new(["class", "speed ratio 0-10 s", "50-60 s", "110-120 s", "min / max over 120 s", "min without keep-alive", "bone error (projected, max)", "bone error (raw, mean / max)", "finite"]);
        let rest = spec.layout.skeleton.rest_bone_lengths();
        let min_bone = 0.02 * rest.iter().cloned().fold(0.0, f32::max);
        for class in 0..spec.classes.len() {
            let mut stats = Vec::new();
            for (project, keep_alive) in [(true, true), (false, true), (true, false)] {
                let o = GenerateOptions {
                    timeline: Timeline { segments: vec![Segment::new(spec.classes[class].clone(), 120.0)] },
                    init: InitPose::SeedClass { class: spec.classes[class].clone(), variant: 0 },
                    project_bones: project,
                    keep_alive,
                    ..ctx.generation.clone()
                }
                .varied(1);
                match generate(&model, &o, &mut |_| true) {
                    Ok(g) => stats.push(metrics::window_stats(&g.motion, 10.0, spec.class_speed[class], min_bone)),
                    Err(e) => {
                        log(&format!("{} {}: generation failed: {e:#}", dataset, spec.classes[class]));
                        stats.push(Vec::new());
                    }
                }
            }
            let (p, raw, stalling) = (&stats[0], &stats[1], &stats[2]);
            let sr = |i: usize| p.get(i).map_or(f64::NAN, |w| w.speed_ratio as f64);
            let min = p.iter().map(|w| w.speed_ratio).fold(f32::INFINITY, f32::min);
            let max = p.iter().map(|w| w.speed_ratio).fold(0.0, f32::max);
            let min_stalling = stalling.iter().map(|w| w.speed_ratio).fold(f32::INFINITY, f32::min);
            let bmax = p.iter().map(|w| w.bone_error).fold(0.0, f32::max);
            let rmean = raw.iter().map(|w| w.bone_error).sum::<f32>() / raw.len().max(1) as f32;
            let rmax = raw.iter().map(|w| w.bone_error).fold(0.0, f32::max);
            let finite = !p.is_empty() && p.iter().chain(raw.iter()).all(|w| w.finite && w.speed_ratio.is_finite());
            table.row([
                spec.classes[class].clone(),
                f(sr(0), 2),
                f(sr(5), 2),
                f(sr(11), 2),
                format!("{} / {}", f(min as f64, 2), f(max as f64, 2)),
                f(min_stalling as f64, 2),
                f(bmax as f64, 4),
                format!("{} / {}", f(rmean as f64, 3), f(rmax as f64, 3)),
                (if finite { "yes" } else { "NO" }).into(),
            ]);
            out.push(json!({"dataset": dataset.name(), "class": spec.classes[class], "windows_projected": p, "windows_raw": raw, "windows_without_keep_alive": stalling, "finite": finite}));
        }
        md.table(table);
    }
    Ok((md, json!({"classes": out})))
}
