//! `glocal calibrate`: per-class guidance for a trained model ([`crate::eval::calibrate`]).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::data::archive::DataRoot;
use crate::eval::calibrate::{calibrate, LIVELY_CEILING, LIVELY_SHARE};
use crate::model::corpus::Corpus;
use crate::model::glocal::{GlocalModel, SEEDS_FILE};
use crate::model::train::{set_seed_styles, write_seeds};
use crate::model::spec::ModelSpec;

#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// The model folder; its model.json gains the classes' own guidance.
    #[arg(long)]
    model: PathBuf,
    #[arg(long)]
    data: Option<PathBuf>,
    /// The guidance weights to try, rising from the model's own.
    #[arg(long, value_delimiter = ',', default_value = "1.5,2.5,3.5,5")]
    strengths: Vec<f32>,
    /// Print the readings without writing model.json.
    #[arg(long)]
    dry_run: bool,
    /// CLASS=OTHER pairs: CLASS's guidance steers away from OTHER, which it is mistaken for
    /// (model.json's `class_contrasts`; calibrated with them). Without it the model keeps its
    /// own.
    #[arg(long, value_delimiter = ',', value_parser = parse_contrast)]
    contrast: Vec<(String, String)>,
    /// Write only what is read off the training clips alone (model.json's `bone_turn_limits`
    /// and `style_speed`, seeds.json's styles; a full calibration writes them too) and leave
    /// the guidance as it is.
    #[arg(long, alias = "turn-limits-only", conflicts_with_all = ["contrast", "strengths"])]
    clips_only: bool,
}

fn parse_contrast(pair: &str) -> Result<(String, String), String> {
    match pair.split_once('=') {
        Some((class, away)) if !class.trim().is_empty() && !away.trim().is_empty() => Ok((class.trim().to_string(), away.trim().to_string())),
        _ => Err(format!("'{pair}' is not CLASS=OTHER (e.g. walk-left=walking)")),
    }
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    let data = DataRoot::resolve(args.data.as_deref());
    let mut model = GlocalModel::load(&args.model)?;
    if !args.contrast.is_empty() {
        model = model.with_class_contrasts(args.contrast.iter().cloned().collect())?;
    }
    eprintln!("calibrate: {} training clips", model.spec.dataset);
    let corpus = Corpus::for_model(model.spec.dataset.parse()?, &data, &model.spec, &args.model)?;
    let limits = turn_limits(&corpus, model.spec.fps);
    model = model.with_bone_turn_limits(limits)?.with_style_speeds(corpus.style_speeds())?;
    write_seed_styles(&model, &corpus, &args)?;
    if args.clips_only {
        return write(&model.spec, &args);
    }
    // The texture is calibrated from all of it.
    let model = model.with_texture_gains(BTreeMap::new())?;
    let classes = calibrate(&model, &corpus, &args.strengths, &mut |m| eprintln!("{m}"))?;
    let mut spec = model.spec.clone();
    say!("| class | training clips' jerk (m/s^3) | at each strength: generated jerk over the training clips', travel (m/s) | chosen |\n|---|---|---|---|");
    for c in &classes {
        let readings: Vec<String> = c.readings.iter().map(|r| format!("{}: {:.2}, {:.2}", r.strength, r.jerk / c.real_jerk, r.mean_travel())).collect();
        say!("| {} | {:.1} | {} | {} |", c.class, c.real_jerk, readings.join(", "), c.chosen);
    }
    spec.class_strengths = classes.iter().filter(|c| c.chosen != spec.class_strength).map(|c| (c.class.clone(), c.chosen)).collect();
    spec.texture_gains = classes.iter().filter_map(|c| Some((c.class.clone(), c.texture?.1))).filter(|(_, gain)| *gain != 1.0).collect();
    spec.lively_classes = classes.iter().filter(|c| c.over_lively()).map(|c| c.class.clone()).collect();
    if model.texture().is_some() {
        say!("\n| class | training clips' jerk (m/s^3) | chosen strength, generated jerk over the training clips' | with all of the texture | texture share chosen |\n|---|---|---|---|---|");
        for c in &classes {
            let (textured, gain) = c.texture.unwrap_or((f64::NAN, f32::NAN));
            say!("| {} | {:.1} | {}: {:.2} | {:.2} | {:.2} |", c.class, c.real_jerk, c.chosen, c.chosen_jerk() / c.real_jerk, textured / c.real_jerk, gain);
        }
    }
    say!("{} of {} classes need more than the model's guidance ({}) to reach {LIVELY_SHARE} of their training clips' jerk", spec.class_strengths.len(), classes.len(), spec.class_strength);
    let lively: Vec<&str> = spec.lively_classes.iter().map(String::as_str).collect();
    say!("over {LIVELY_CEILING} of it at the model's own, calmed unless steered apart and kept at their own through a class change: {}", if lively.is_empty() { "none".to_string() } else { lively.join(", ") });
    write(&spec, &args)
}

/// The bones' turn limits from the training clips of `corpus` (a model at `fps`), printed.
fn turn_limits(corpus: &Corpus, fps: f32) -> BTreeMap<String, f32> {
    let limits = corpus.bone_turn_limits();
    let row = |(bone, limit): (&String, &f32)| format!("{bone} {:.0} ({:.1} a frame)", limit, limit / fps);
    say!("bones' turn limits, degrees a second: {}", limits.iter().map(row).collect::<Vec<_>>().join(", "));
    limits
}

/// The model's seed bank with each window's style, where it lacked them (unless only a dry
/// run is asked for).
fn write_seed_styles(model: &GlocalModel, corpus: &Corpus, args: &CalibrateArgs) -> Result<()> {
    let mut seeds = model.seeds.clone();
    set_seed_styles(&mut seeds, corpus, &model.spec);
    let styled = seeds.iter().filter(|s| s.style.is_some()).count();
    if seeds.iter().zip(&model.seeds).any(|(a, b)| a.style != b.style) && !args.dry_run {
        write_seeds(&args.model, &seeds)?;
        say!("wrote {} ({styled} of {} windows with their clip's style)", args.model.join(SEEDS_FILE).display(), seeds.len());
    }
    Ok(())
}

/// `spec` into the model's model.json, unless only a dry run is asked for.
fn write(spec: &ModelSpec, args: &CalibrateArgs) -> Result<()> {
    if !args.dry_run {
        spec.write(&args.model)?;
        say!("wrote {}", args.model.join("model.json").display());
    }
    Ok(())
}
