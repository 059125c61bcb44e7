//! `glocal bench ...`: speed measurements. Every comparison runs both sides in the same
//! process, one after the other, so the ratio holds on a noisy shared machine.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Result;
use clap::Subcommand;
use serde::Serialize;

use crate::model::bench::{bench_infer, bench_train, Budget, TrainBenchConfig};
use crate::model::glocal::GlocalModel;
use crate::synth::{generate, GenerateOptions, InitPose, Segment, Timeline};

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Time to load a whole dataset from its archive.
    Load {
        #[arg(long)]
        dataset: String,
        #[arg(long)]
        data: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
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
    /// Studio frame time during playback (ghosts on) against an empty window, 1280x800.
    /// Needs a display (`xvfb-run -a -s "-screen 0 1280x800x24" glocal bench studio`).
    Studio {
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        /// Measure one window in this process (used by the command itself).
        #[arg(long, hide = true)]
        only: Option<String>,
        #[arg(long)]
        json: bool,
    },
    /// Time to generate 10 s, 60 s and 600 s of dense motion with a shipped model.
    Generate {
        #[arg(long, default_value = "models/h36m")]
        model: PathBuf,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(command: BenchCommand) -> Result<()> {
    match command {
        BenchCommand::Load { dataset, data, json } => super::data_cmd::bench_load(&dataset, data.as_deref(), json),
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
        BenchCommand::Studio { seconds, only, json } => match only.as_deref() {
            Some(which) => {
                let stats = crate::studio::bench::measure(which == "empty", seconds)?;
                println!("{}", serde_json::to_string(&stats)?);
                Ok(())
            }
            None => {
                let empty = measure_in_child("empty", seconds)?;
                let studio = measure_in_child("studio", seconds)?;
                let ratio = studio.mean_ms / empty.mean_ms;
                let r = serde_json::json!({"empty": empty, "studio": studio, "ratio": ratio});
                print(&r, json, || {
                    format!(
                        "empty window {:.1} ms/frame, studio playing with ghosts {:.1} ms/frame (median {:.1}, p95 {:.1}) at {}x{}: {:.2}x",
                        empty.mean_ms, studio.mean_ms, studio.median_ms, studio.p95_ms, studio.width, studio.height, ratio
                    )
                })
            }
        },
        BenchCommand::Generate { model, repeats, json } => {
            let r = bench_generate(&model, repeats)?;
            print(&r, json, || {
                r.runs
                    .iter()
                    .map(|x| format!("{:>4} s of motion: {:.1} ms ({:.3} ms per second of motion)", x.seconds, x.ms, x.ms / x.seconds as f64))
                    .collect::<Vec<_>>()
                    .join("\n")
            })
        }
    }
}

fn print<T: Serialize>(value: &T, json: bool, text: impl FnOnce() -> String) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string(value)?);
    } else {
        println!("{}", text());
    }
    Ok(())
}

#[derive(Serialize)]
pub struct GenerateRun {
    pub seconds: f32,
    pub frames: usize,
    /// Best of the repeats, milliseconds.
    pub ms: f64,
}

#[derive(Serialize)]
pub struct GenerateBench {
    pub model: String,
    pub locgen: bool,
    pub runs: Vec<GenerateRun>,
}

/// Best-of-`repeats` wall time of whole takes (GloGen + LocGen + pace + bone projection)
/// cycling through the model's classes in 10 s segments.
pub fn bench_generate(dir: &Path, repeats: usize) -> Result<GenerateBench> {
    let mut model = GlocalModel::load(dir)?;
    let classes = model.spec.classes.clone();
    let mut runs = Vec::new();
    for seconds in [10.0f32, 60.0, 600.0] {
        let segments = (0..(seconds / 10.0) as usize)
            .map(|k| Segment { class: classes[k % classes.len()].clone(), seconds: 10.0, pace: None })
            .collect();
        let opts = GenerateOptions { timeline: Timeline { segments }, init: InitPose::SeedIndex(0), ..Default::default() };
        let mut best = f64::INFINITY;
        let mut frames = 0;
        for _ in 0..repeats.max(1) {
            let start = Instant::now();
            let take = generate(&mut model, &opts, &mut |_| true)?;
            best = best.min(start.elapsed().as_secs_f64() * 1e3);
            frames = take.motion.frames();
        }
        runs.push(GenerateRun { seconds, frames, ms: best });
    }
    Ok(GenerateBench { model: dir.display().to_string(), locgen: model.has_locgen(), runs })
}

/// Runs `glocal bench studio --only WHICH` in a child process and reads its statistics.
fn measure_in_child(which: &str, seconds: f64) -> Result<crate::studio::bench::FrameStats> {
    let exe = std::env::current_exe()?;
    let out = std::process::Command::new(exe)
        .args(["bench", "studio", "--only", which, "--seconds", &seconds.to_string()])
        .output()?;
    if !out.status.success() {
        anyhow::bail!("the {which} window failed: {}", String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or(""));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().last().unwrap_or("");
    Ok(serde_json::from_str(line)?)
}
