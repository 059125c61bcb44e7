//! `glocal bench ...`: speed measurements. Every comparison runs both sides in the same
//! process, one after the other, so the ratio holds on a noisy shared machine.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Result;
use clap::Subcommand;
use serde::Serialize;

use crate::model::bench::{bench_infer, bench_train, Budget, TrainBenchConfig};
use crate::model::glocal::GlocalModel;
use crate::synth::{generate, GenerateOptions, InitPose, Key, KeySource, RootPath, Segment, Timeline, Waypoint};

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Time to load a whole dataset from its archive.
    Load(super::data_cmd::DatasetArgs),
    /// GloGen training steps per second, fast LSTM against candle-nn's (the PyTorch reference's shapes).
    Train {
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
    /// One GloGen block at batch 1 on the generation path.
    Infer {
        #[arg(long, default_value_t = 3.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
    /// Studio frame time during playback (ghosts and trail on) against an empty window,
    /// 1280x800, and what an edit late in a 300 s take costs (as `bench edit`); or
    /// (`--memory`) its resident memory holding a long take and after closing it.
    /// Needs a display (`xvfb-run -a -s "-screen 0 1280x800x24" glocal bench studio`).
    #[cfg(feature = "studio")]
    Studio {
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        /// Play a take this long (the model's classes in turn, 60 s each) instead of the
        /// default take.
        #[arg(long)]
        take_seconds: Option<f32>,
        /// Report resident memory (VmRSS, VmHWM) with the default take, holding a take of
        /// `--take-seconds` (default 3600), after File > New and after one more take.
        #[arg(long)]
        memory: bool,
        /// Measure one window in this process (used by the command itself).
        #[arg(long, hide = true)]
        only: Option<String>,
        #[arg(long)]
        json: bool,
    },
    /// An edit in the last 20% of a 300 s timeline: resumed and as the studio makes it,
    /// against generating the edited take whole, in the same run.
    Edit {
        #[arg(long, default_value = "models/h36m")]
        model: PathBuf,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
    /// Time to generate 10 s, 60 s and 600 s of dense motion with a shipped model.
    Generate {
        #[arg(long, default_value = "models/h36m")]
        model: PathBuf,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// 1 does the PyTorch reference's work (no classifier-free guidance pass). Default:
        /// the model's own.
        #[arg(long)]
        class_strength: Option<f32>,
        /// Without the foot lock (its cost is the difference).
        #[arg(long)]
        no_foot_lock: bool,
        /// Without the model's motion texture (its cost is the difference).
        #[arg(long)]
        no_texture: bool,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(command: BenchCommand) -> Result<()> {
    match command {
        BenchCommand::Load(args) => super::data_cmd::bench_load(&args),
        BenchCommand::Train { seconds, json } => {
            let r = bench_train(TrainBenchConfig::default(), Budget::Seconds(seconds))?;
            print(&r, json, || {
                format!(
                    "fast LSTM {:.1} steps/s, candle-nn LSTM {:.1} steps/s ({:.1}x)",
                    r.fast_steps_per_s, r.candle_nn_steps_per_s, r.speedup
                )
            })
        }
        BenchCommand::Infer { seconds, json } => {
            let r = bench_infer(TrainBenchConfig::default(), 1, Budget::Seconds(seconds))?;
            print(&r, json, || {
                format!(
                    "one block (batch 1, t = {}): generation path {:.3} ms, candle tensors {:.3} ms, candle-nn {:.3} ms",
                    r.steps_in, r.frozen_ms_per_block, r.fast_ms_per_block, r.candle_nn_ms_per_block
                )
            })
        }
        #[cfg(feature = "studio")]
        BenchCommand::Studio { memory: true, take_seconds, json, .. } => bench_memory(take_seconds.unwrap_or(3600.0), json),
        #[cfg(feature = "studio")]
        BenchCommand::Studio { seconds, take_seconds, only, json, memory: false } => match only.as_deref() {
            Some(which) => {
                use crate::studio::bench::{measure, Window};
                let window = if which == "empty" { Window::Empty } else { Window::Studio { take_seconds } };
                let stats = measure(window, seconds)?;
                say!("{}", serde_json::to_string(&stats)?);
                Ok(())
            }
            None => {
                // The two windows take turns, so a change in the machine's load between
                // them shows up in both; each side's frames are pooled over its rounds.
                use crate::studio::bench::FrameStats;
                const ROUNDS: usize = 3;
                let (mut empties, mut studios) = (Vec::new(), Vec::new());
                for round in 1..=ROUNDS {
                    for (which, runs) in [("empty", &mut empties), ("studio", &mut studios)] {
                        if !json {
                            eprintln!("round {round}/{ROUNDS}: {which} window, {seconds} s...");
                        }
                        runs.push(measure_in_child(which, seconds, take_seconds)?);
                    }
                }
                let (empty, studio) = (FrameStats::pool(&empties), FrameStats::pool(&studios));
                let ratio = studio.mean_ms / empty.mean_ms;
                let median_ratio = studio.median_ms / empty.median_ms;
                let cpu_ratio = studio.cpu_ms / empty.cpu_ms;
                let round_ratios: Vec<f64> = studios.iter().zip(&empties).map(|(s, e)| s.mean_ms / e.mean_ms).collect();
                let studio_name = take_seconds.map_or_else(|| "studio playing, ghosts on".to_string(), |s| format!("studio playing {s} s, ghosts+trail"));
                // What an edit late in a long take costs the studio's worker, beside.
                let edit = super::bench_edit::bench_edit(Path::new("models/h36m"), 3)?;
                let r = serde_json::json!({
                    "edit": edit,
                    "take_seconds": take_seconds,
                    "empty": empty,
                    "studio": studio,
                    "ratio": ratio,
                    "median_ratio": median_ratio,
                    "cpu_ratio": cpu_ratio,
                    "round_ratios": round_ratios,
                    "rounds": ROUNDS,
                    "seconds_per_window_per_round": seconds,
                });
                print(&r, json, || {
                    let line = |name: &str, s: &FrameStats| {
                        format!(
                            "{name:<32} {:>5} frames  mean {:6.1} ms  median {:6.1} ms  p95 {:6.1} ms  cpu {:6.1} ms/frame",
                            s.frames, s.mean_ms, s.median_ms, s.p95_ms, s.cpu_ms
                        )
                    };
                    format!(
                        "{}x{}, {ROUNDS} rounds of {seconds} s per window\n{}\n{}\nstudio / empty: {ratio:.2}x mean, {median_ratio:.2}x median, {cpu_ratio:.2}x cpu (rounds: {})",
                        studio.width,
                        studio.height,
                        line("empty window", &empty),
                        line(&studio_name, &studio),
                        round_ratios.iter().map(|r| format!("{r:.2}x")).collect::<Vec<_>>().join(", ")
                    ) + "\n" + &edit.text()
                })
            }
        },
        BenchCommand::Edit { model, repeats, json } => {
            let r = super::bench_edit::bench_edit(&model, repeats.max(1))?;
            print(&r, json, || r.text())
        }
        BenchCommand::Generate { model, repeats, class_strength, no_foot_lock, no_texture, json } => {
            let stages = GenerateOptions { foot_lock: !no_foot_lock, texture: !no_texture, ..Default::default() };
            let r = bench_generate(&model, repeats, class_strength, &stages)?;
            print(&r, json, || {
                r.runs
                    .iter()
                    .map(|x| {
                        let with = if x.constrained { ", 4 keys and a path" } else { "" };
                        format!("{:>4} s of motion{with}: {:.1} ms ({:.3} ms per second of motion)", x.seconds, x.ms, x.ms / x.seconds as f64)
                    })
                    .chain(constraint_cost(&r.runs))
                    .collect::<Vec<_>>()
                    .join("\n")
            })
        }
    }
}

fn print<T: Serialize>(value: &T, json: bool, text: impl FnOnce() -> String) -> Result<()> {
    if json {
        say!("{}", serde_json::to_string(value)?);
    } else {
        say!("{}", text());
    }
    Ok(())
}

#[derive(Serialize)]
pub struct GenerateRun {
    pub seconds: f32,
    /// With four keys and a root path (the 60 s case is run both ways).
    pub constrained: bool,
    pub frames: usize,
    /// Best of the repeats, milliseconds.
    pub ms: f64,
}

#[derive(Serialize)]
pub struct GenerateBench {
    pub model: String,
    pub locgen: bool,
    pub class_strength: f32,
    pub foot_lock: bool,
    pub texture: bool,
    pub runs: Vec<GenerateRun>,
}

/// Best-of-`repeats` wall time of whole takes (GloGen + LocGen + pace + bone projection)
/// cycling through the model's classes in 10 s segments, with the stages `stages` turns on
/// (its foot lock and texture).
pub fn bench_generate(dir: &Path, repeats: usize, class_strength: Option<f32>, stages: &GenerateOptions) -> Result<GenerateBench> {
    let model = GlocalModel::load(dir)?;
    let class_strength = class_strength.unwrap_or(model.spec.class_strength);
    let classes = model.spec.classes.clone();
    let mut runs = Vec::new();
    for (seconds, constrained) in [(10.0f32, false), (60.0, false), (60.0, true), (600.0, false)] {
        let segments = (0..(seconds / 10.0) as usize)
            .map(|k| Segment::new(classes[k % classes.len()].clone(), 10.0))
            .collect();
        let mut opts = GenerateOptions { timeline: Timeline { segments }, init: InitPose::SeedIndex(0), class_strength: Some(class_strength), foot_lock: stages.foot_lock, texture: stages.texture, ..Default::default() };
        if constrained {
            // A seed pose of each of four classes, 12 s apart, and a 40 m zigzag.
            let key = |k: usize| Key { seconds: 12.0 * (k + 1) as f32, source: KeySource::Init(InitPose::SeedClass { class: classes[k % classes.len()].clone(), variant: 0 }), fix_root: false };
            opts.keys = (0..4).map(key).collect();
            let waypoints = (0..5).map(|k| Waypoint { x: 10.0 * k as f32, z: if k % 2 == 0 { 0.0 } else { 10.0 }, seconds: None }).collect();
            opts.path = Some(RootPath { waypoints });
        }
        let mut best = f64::INFINITY;
        let mut frames = 0;
        for _ in 0..repeats.max(1) {
            let start = Instant::now();
            let take = generate(&model, &opts, &mut |_| true)?;
            best = best.min(start.elapsed().as_secs_f64() * 1e3);
            frames = take.motion.frames();
        }
        runs.push(GenerateRun { seconds, constrained, frames, ms: best });
    }
    Ok(GenerateBench { model: dir.display().to_string(), locgen: model.has_locgen() && GenerateOptions::default().locgen_for(&model.spec), class_strength, foot_lock: stages.foot_lock, texture: stages.texture && model.texture().is_some(), runs })
}

/// The 60 s take's time with keys and a path over its time without, measured in one run.
fn constraint_cost(runs: &[GenerateRun]) -> Option<String> {
    let plain = runs.iter().find(|r| r.seconds == 60.0 && !r.constrained)?;
    let with = runs.iter().find(|r| r.seconds == 60.0 && r.constrained)?;
    Some(format!("keys and path: {:.2}x the unconstrained 60 s take", with.ms / plain.ms))
}

/// `glocal bench studio --memory`: the studio's resident memory at each step, with what each
/// step changed.
#[cfg(feature = "studio")]
fn bench_memory(take_seconds: f32, json: bool) -> Result<()> {
    let points = crate::studio::bench::measure_memory(take_seconds)?;
    print(&points, json, || {
        let mut last: Option<f64> = None;
        points
            .iter()
            .map(|p| {
                let change = last.map_or(String::new(), |l| format!(" ({:+.0} MB)", p.rss_mb - l));
                last = Some(p.rss_mb);
                format!("{:<52} {:>6} frames  resident {:7.1} MB{change}  peak {:7.1} MB  after malloc_trim {:7.1} MB", p.what, p.frames, p.rss_mb, p.peak_mb, p.trimmed_mb)
            })
            .collect::<Vec<_>>()
            .join("\n")
    })
}

/// Runs `glocal bench studio --only WHICH` in a child process (a process can open only one
/// event loop) and reads its statistics, frame intervals included.
#[cfg(feature = "studio")]
fn measure_in_child(which: &str, seconds: f64, take_seconds: Option<f32>) -> Result<crate::studio::bench::FrameStats> {
    let exe = std::env::current_exe()?;
    let mut args = vec!["bench".to_string(), "studio".into(), "--only".into(), which.into(), "--seconds".into(), seconds.to_string()];
    if let Some(s) = take_seconds {
        args.extend(["--take-seconds".to_string(), s.to_string()]);
    }
    let out = std::process::Command::new(exe)
        .args(&args)
        .stdin(std::process::Stdio::null())
        .output()?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        let last = stderr.lines().rev().find(|l| !l.trim().is_empty() && !l.contains("XDG_RUNTIME_DIR")).unwrap_or("");
        anyhow::bail!("the {which} window failed ({}): {last}", out.status);
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or("");
    serde_json::from_str(line).map_err(|e| anyhow::anyhow!("the {which} window printed no statistics ({e}): {line:?}"))
}
