//! The `glocal` command line: every subcommand is a thin layer over the library.

/// `println!` that does not panic when stdout is gone (`glocal generate ... | head`): the
/// work is done and its files written by then; a reader that left early misses only the
/// summary.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

mod args;
mod bench_cmd;
mod bench_edit;
mod calibrate_cmd;
mod data_cmd;
mod eval_cmd;
mod synth_cmd;
mod train_cmd;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(name = "glocal", version, about = "Glocal Studio: long-term, class-aware human motion synthesis")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Inspect the datasets.
    Data {
        #[command(subcommand)]
        command: data_cmd::DataCommand,
    },
    /// Train GloGen or LocGen on a dataset.
    Train(train_cmd::TrainArgs),
    /// Generate a take from a timeline of activities and export it.
    Generate(synth_cmd::GenerateArgs),
    /// Draw a contact sheet (PNG) of a take.
    Render(synth_cmd::RenderArgs),
    /// Run an evaluation suite and print its table.
    Eval(eval_cmd::EvalArgs),
    /// Tune a trained model's guidance per class: the lowest at which each class's generated
    /// motion is as lively as its training clips (writes model.json's `class_strengths`, and its
    /// `lively_classes`: those livelier than their clips already, calmed and kept at their own
    /// through a class change).
    Calibrate(calibrate_cmd::CalibrateArgs),
    /// Time the engine's parts.
    Bench {
        #[command(subcommand)]
        command: bench_cmd::BenchCommand,
    },
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        #[cfg(feature = "studio")]
        None => crate::studio::run(),
        #[cfg(not(feature = "studio"))]
        None => anyhow::bail!("this glocal was built without the studio (the `studio` feature); give a command (see --help)"),
        Some(Command::Data { command }) => data_cmd::run(command),
        Some(Command::Train(args)) => train_cmd::run(args),
        Some(Command::Generate(args)) => synth_cmd::run_generate(args),
        Some(Command::Render(args)) => synth_cmd::run_render(args),
        Some(Command::Eval(args)) => eval_cmd::run(args),
        Some(Command::Calibrate(args)) => calibrate_cmd::run(args),
        Some(Command::Bench { command }) => bench_cmd::run(command),
    }
}
