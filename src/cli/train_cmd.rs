use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use crate::data::archive::DataRoot;
use crate::data::features::Interpolation;
use super::args::{LossArg, StageArg};
use crate::model::spec::{ModelSpec, PoseBase, SeamJoin};
use crate::data::registry::Dataset;
use crate::model::corpus::Corpus;
use crate::model::texture::{Texture, TEXTURE_FILE};
use crate::model::glocal::SEEDS_FILE;
use crate::model::train::{train, write_seed_bank, ModelShape, TrainOptions};

#[derive(Args, Debug)]
pub struct TrainArgs {
    #[arg(long)]
    dataset: String,
    #[arg(long, value_enum)]
    stage: StageArg,
    #[arg(long, default_value_t = 4000)]
    steps: usize,
    /// Model folder (created when missing; both stages train into the same one).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Continue from the folder's last checkpoint of this stage.
    #[arg(long)]
    resume: bool,
    #[arg(long)]
    data: Option<PathBuf>,
    #[arg(long, default_value_t = 64)]
    batch: usize,
    /// AdamW's learning rate.
    #[arg(long, default_value_t = 0.002)]
    lr: f32,
    #[command(flatten)]
    shape: ShapeArgs,
    #[arg(long, default_value_t = 250)]
    eval_every: usize,
    #[arg(long, default_value_t = 250)]
    checkpoint_every: usize,
    /// Start from the trained weights of this stage in DIR (a fresh optimiser): fine-tuning.
    #[arg(long, value_name = "DIR")]
    init_from: Option<PathBuf>,
    /// Fine-tune the stage already trained in --out (the same as --init-from OUT).
    #[arg(long)]
    fine_tune: bool,
    /// Teach the GloGen of --fine-tune or --init-from these styles alone (comma-separated):
    /// only their label inputs train, from zero, on the clips of these styles; every other
    /// weight stays as it is, so every other class's and style's motion is unchanged.
    #[arg(long, value_delimiter = ',', value_name = "STYLES")]
    only_styles: Vec<String>,
}

/// The flags that shape the model a run trains.
#[derive(Args, Debug)]
struct ShapeArgs {
    #[arg(long, default_value_t = 200)]
    hidden: usize,
    #[arg(long, value_enum, default_value = "j+mf")]
    loss: LossArg,
    /// Train GloGen without the class prior (ablation).
    #[arg(long)]
    no_class: bool,
    /// The paper's GloGen: class only at the encoder input, no class dropout, one block per window.
    #[arg(long)]
    paper: bool,
    /// Blocks GloGen rolls out on its own outputs per training window.
    #[arg(long, default_value_t = 2)]
    rollout: usize,
    #[arg(long, default_value_t = 0.1)]
    class_dropout: f32,
    /// GloGen predicts each pose as an offset from the last pose of its input, so blocks
    /// start where their context leaves off.
    #[arg(long)]
    residual: bool,
    /// GloGen's offset from the last pose of its input fades out over the block: a block
    /// continues its context where it meets it and ends on poses of its own.
    #[arg(long, conflicts_with = "residual")]
    residual_fade: bool,
    /// GloGen trains on its blocks joined at their seams, as generation shows them.
    #[arg(long)]
    joined: bool,
    /// GloGen's blocks are joined two-sided: half of each seam's shift goes on the block
    /// before (in generation, and in training with --joined).
    #[arg(long)]
    two_sided_join: bool,
    /// GloGen also reads the next key it must reach (its pose, where it stands, the steps
    /// left), trained with targets drawn from the clip ahead: keys it arrives at.
    #[arg(long)]
    target: bool,
    /// Dense frames between sparse poses (the paper's M + 1).
    #[arg(long, default_value_t = 5)]
    stride: usize,
    /// Sparse intervals per LocGen window: each window starts on a sparse pose and reads
    /// this many intervals of the interpolation.
    #[arg(long, default_value_t = 4)]
    locgen_keys: usize,
}

impl ShapeArgs {
    /// Gives `shape` these flags' settings, `--paper` last.
    fn apply(&self, shape: &mut ModelShape) -> Result<()> {
        shape.hidden = self.hidden;
        shape.loss = self.loss.into();
        shape.use_class = !self.no_class;
        shape.rollout_blocks = self.rollout;
        shape.class_dropout = self.class_dropout;
        shape.base = PoseBase::from_flags(self.residual, self.residual_fade);
        shape.joined = self.joined;
        shape.seam_join = if self.two_sided_join { SeamJoin::TwoSided } else { SeamJoin::OneSided };
        shape.target = self.target;
        shape.stride = self.stride;
        shape.locgen_keys = self.locgen_keys;
        if self.paper {
            if self.residual || self.residual_fade || self.joined || self.two_sided_join || self.target {
                bail!("--paper trains the paper's GloGen, which has neither --residual, --residual-fade, --joined, --two-sided-join nor --target");
            }
            shape.class_in_decoder = false;
            shape.class_dropout = 0.0;
            shape.rollout_blocks = 1;
            shape.interpolation = Interpolation::Linear;
        }
        Ok(())
    }
}

/// The first Ctrl-C asks training to stop after the current step and save a checkpoint; a
/// second one exits at once (losing only the steps since the last checkpoint).
fn stop_on_interrupt(cancel: Arc<AtomicBool>) -> Result<()> {
    ctrlc::set_handler(move || {
        if cancel.swap(true, Ordering::SeqCst) {
            eprintln!("\ninterrupted again: exiting without a checkpoint");
            std::process::exit(130);
        }
        eprintln!("\ninterrupted: saving a checkpoint after this step (Ctrl-C again to exit at once)");
    })
    .context("cannot install the Ctrl-C handler")
}

/// `--stage texture` or `--stage seeds`: the motion texture or the seed bank of the model in
/// `--out`, from its training clips.
fn gather(args: &TrainArgs) -> Result<()> {
    let dataset: Dataset = args.dataset.parse()?;
    // The spec alone: a texture or seed bank there before is replaced, not read.
    let spec = ModelSpec::read_verified(&args.out)?;
    let corpus = Corpus::for_model(dataset, &DataRoot::resolve(args.data.as_deref()), &spec, &args.out)?;
    let path = if args.stage == StageArg::Seeds {
        write_seed_bank(&args.out, &spec, &corpus)?;
        args.out.join(SEEDS_FILE)
    } else {
        let path = args.out.join(TEXTURE_FILE);
        Texture::build(&corpus, &spec)?.save(&path, &spec)?;
        path
    };
    say!("wrote {} ({} classes)", path.display(), spec.classes.len());
    Ok(())
}

pub fn run(args: TrainArgs) -> Result<()> {
    let Some(stage) = args.stage.network() else { return gather(&args) };
    let mut opts = TrainOptions::new(args.dataset.parse()?, stage, args.out);
    opts.data = DataRoot::resolve(args.data.as_deref());
    opts.steps = args.steps;
    opts.seed = args.seed;
    opts.resume = args.resume;
    opts.optimiser.batch = args.batch;
    opts.optimiser.lr = args.lr;
    opts.eval_every = args.eval_every;
    opts.checkpoint_every = args.checkpoint_every;
    opts.init_from = if args.fine_tune { Some(opts.out.clone()) } else { args.init_from };
    opts.only_styles = args.only_styles;
    args.shape.apply(&mut opts.shape)?;
    let bar = ProgressBar::new(opts.steps as u64);
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed} < {eta}]")?);
    // Said once the weights are read: a refused fine-tuning says only why.
    let fine_tuned = opts.init_from.as_ref().map_or_else(String::new, |dir| format!(", fine-tuned from the trained weights in {}", dir.display()));
    let cancel = Arc::new(AtomicBool::new(false));
    stop_on_interrupt(cancel.clone())?;
    let mut last_val = f32::NAN;
    let spec = train(
        &opts,
        &mut |p| {
            if let Some(v) = p.val_error {
                last_val = v;
                let line = format!("step {}: loss {:.4}, validation error {:.2} ({:.1} steps/s)", p.step, p.loss, v, p.steps_per_s);
                // A hidden bar (output to a log file) drops its printed lines.
                if bar.is_hidden() {
                    eprintln!("{line}");
                } else {
                    bar.println(line);
                }
            }
            bar.set_position(p.step as u64);
            bar.set_message(format!("loss {:.4} val {:.2} {:.1} steps/s", p.loss, last_val, p.steps_per_s));
        },
        &cancel,
    )?;
    bar.finish();
    if cancel.load(Ordering::SeqCst) {
        let steps = opts.record(&spec).map_or(0, |r| r.steps);
        eprintln!("interrupted: checkpoint at step {steps} saved in {}; continue with --resume", opts.out.display());
        std::process::exit(130);
    }
    if let Some(r) = opts.record(&spec) {
        say!(
            "{} steps{fine_tuned}; validation joint error {:.2} (baseline {:.2}) in skeleton units ({} m each)",
            r.steps, r.val_error, r.baseline_error, spec.source_skeleton.meters_per_unit()
        );
    }
    Ok(())
}
