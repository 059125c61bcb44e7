//! `glocal eval --suite NAME`: runs one evaluation suite (or `all`), prints its markdown
//! table and writes its numbers as JSON.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::data::archive::DataRoot;
use crate::data::write::write_atomic;
use crate::eval::suites::context::CLASS_CONTROL_TAKES;
use crate::eval::{run_suite, Suite, SuiteContext, SuiteOptions};
use crate::synth::Preset;
use super::args::TransitionArg;

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// cmu-euclid, h36m-mmd, h36m, bandai, locgen, long-term, motion, constraints, inbetween,
    /// first-takes, combined, styles, or all (the first nine).
    #[arg(long, value_parser = suites_named)]
    suite: Suites,
    /// Write the suite's numbers here as JSON (for `all`: one file per suite, NAME inserted
    /// before the extension).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Train the baselines and the suite's own GloGen variants when they are not cached.
    #[arg(long)]
    train_baselines: bool,
    /// The model folder to evaluate (default: models/<dataset>).
    #[arg(long)]
    model: Option<PathBuf>,
    #[arg(long)]
    data: Option<PathBuf>,
    /// Where trained baselines and classifiers are cached (default: target/eval-cache).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// The class-generation suites' transition (ablation: `cut` is the paper's class prior alone).
    #[arg(long, value_enum, default_value = "anchor")]
    transition: TransitionArg,
    /// The suites' classifier-free guidance weight (default: each model's own).
    #[arg(long)]
    class_strength: Option<f32>,
    /// The class-generation suites without keep-alive (with `--transition cut --class-strength
    /// 1`: the paper's mechanism alone).
    #[arg(long)]
    no_keep_alive: bool,
    /// The suites' takes and forecasts with GloGen's blocks unjoined at their seams.
    #[arg(long)]
    no_seam_join: bool,
    /// The suites' takes without the models' motion texture (`glocal generate --no-texture`).
    #[arg(long)]
    no_texture: bool,
    /// The suites' takes with the spline between GloGen's sparse poses, no LocGen (`glocal
    /// generate --no-locgen`).
    #[arg(long)]
    no_locgen: bool,
    /// The paper's GlocalNet (`synth::Preset::Paper`, as `glocal generate --paper`): cut transitions, class strength 1, no keep-alive, no seam join, no foot lock, no texture.
    #[arg(long)]
    paper: bool,
    /// Fewer and shorter takes (the motion suite), for a quick look.
    #[arg(long)]
    quick: bool,
    /// Takes per class and condition in the class-control matrix of the h36m, bandai and combined suites.
    #[arg(long, default_value_t = CLASS_CONTROL_TAKES as u64, value_parser = clap::value_parser!(u64).range(1..=1000))]
    class_control_takes: u64,
}

/// The suites one `--suite` value names: one, or every suite for `all`.
#[derive(Clone, Debug)]
struct Suites(Vec<Suite>);

fn suites_named(name: &str) -> Result<Suites, String> {
    if name == "all" {
        return Ok(Suites(Suite::ALL.to_vec()));
    }
    name.parse().map(|s| Suites(vec![s])).map_err(|e: anyhow::Error| format!("{e}, all"))
}

pub fn run(args: EvalArgs) -> Result<()> {
    let mut opts = SuiteOptions {
        data: DataRoot::resolve(args.data.as_deref()),
        train_baselines: args.train_baselines,
        model: args.model,
        transition: args.transition.into(),
        class_strength: args.class_strength,
        keep_alive: !args.no_keep_alive,
        join_seams: !args.no_seam_join,
        texture: !args.no_texture,
        locgen: args.no_locgen.then_some(false),
        preset: Preset::from_paper_flag(args.paper),
        quick: args.quick,
        class_control_takes: args.class_control_takes as usize,
        ..Default::default()
    };
    if let Some(c) = args.cache {
        opts.cache = c;
    }
    let ctx = SuiteContext::new(opts)?;
    let suites = &args.suite.0;
    for &suite in suites {
        let report = run_suite(suite, &ctx, &mut |m| eprintln!("{m}"))?;
        say!("## {suite}\n\n{}", report.markdown);
        say!("(suite took {:.0} s)\n", report.json["seconds"].as_f64().unwrap_or(0.0));
        if let Some(path) = &args.json {
            let path = if suites.len() > 1 {
                let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("eval");
                path.with_file_name(format!("{stem}-{suite}.json"))
            } else {
                path.clone()
            };
            write_atomic(&path, serde_json::to_string_pretty(&report.json)?.as_bytes())?;
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}
