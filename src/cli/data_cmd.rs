use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::{Args, Subcommand};
use serde::Serialize;

use crate::data::archive::DataRoot;
use crate::data::combined;
use crate::data::loading;
use crate::data::registry::{Dataset, DatasetClips, Skipped};

/// Which dataset, where, and how to print.
#[derive(Args, Debug)]
pub struct DatasetArgs {
    #[arg(long)]
    pub dataset: String,
    /// Dataset folder (default: $GLOCAL_DATA, else ../shared/data).
    #[arg(long)]
    pub data: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

#[derive(Subcommand, Debug)]
pub enum DataCommand {
    /// Per-class clip and frame counts, fps, joints, and every skipped file.
    Stats(DatasetArgs),
    /// Every clip of the four datasets retargeted onto the standard humanoid, checked per
    /// dataset like an export: bone directions against the source, feet on the floor, bone
    /// lengths kept.
    CheckRetarget {
        #[arg(long)]
        data: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Serialize)]
pub struct ClassStats {
    pub name: String,
    pub clips: usize,
    pub frames: usize,
}

#[derive(Serialize)]
pub struct Stats {
    pub dataset: String,
    pub fps: f32,
    pub joints: usize,
    pub clips: usize,
    pub frames: usize,
    pub classes: Vec<ClassStats>,
    pub skipped: Vec<Skipped>,
}

/// Counts of a loaded dataset, as `glocal data stats` prints them.
pub fn stats(d: &DatasetClips) -> Stats {
    let classes = d
        .classes
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let clips: Vec<_> = d.clips.iter().filter(|c| c.class == k).collect();
            ClassStats { name: name.clone(), clips: clips.len(), frames: clips.iter().map(|c| c.motion.frames()).sum() }
        })
        .collect();
    Stats {
        dataset: d.dataset.name().to_string(),
        fps: d.dataset.source_fps(),
        joints: d.clips.first().map_or(0, |c| c.motion.joints()),
        clips: d.clips.len(),
        frames: d.clips.iter().map(|c| c.motion.frames()).sum(),
        classes,
        skipped: d.skipped.clone(),
    }
}

pub fn run(command: DataCommand) -> Result<()> {
    match command {
        DataCommand::Stats(DatasetArgs { dataset, data, json }) => {
            let dataset: Dataset = dataset.parse()?;
            let loaded = loading::load(dataset, &DataRoot::resolve(data.as_deref()))?;
            let s = stats(&loaded);
            if json {
                say!("{}", serde_json::to_string_pretty(&s)?);
            } else {
                print_stats(&s);
            }
            Ok(())
        }
        DataCommand::CheckRetarget { data, json } => check_retarget(&DataRoot::resolve(data.as_deref()), json),
    }
}

fn check_retarget(root: &DataRoot, json: bool) -> Result<()> {
    let (loaded, checks) = combined::load(root)?;
    if json {
        say!("{}", serde_json::to_string_pretty(&checks)?);
        return Ok(());
    }
    say!("{} clips on the standard humanoid: {} classes, {} styles", loaded.clips.len(), loaded.classes.len(), loaded.styles.len());
    say!("| dataset | clips | bone direction, mean (degrees) | worst clip | lowest foot, median over frames (cm): mean / worst clip | bone length change (mm) |");
    say!("|---|---|---|---|---|---|");
    for c in &checks {
        say!(
            "| {} | {} | {:.2} | {:.2} ({}) | {:.1} / {:.1} ({}) | {:.3} |",
            c.dataset, c.clips, c.mean_bone_degrees, c.worst_clip_degrees, c.worst_clip, c.mean_foot_height * 100.0, c.worst_foot_height * 100.0, c.worst_foot_clip, c.bone_length_change * 1000.0
        );
    }
    Ok(())
}

fn print_stats(s: &Stats) {
    say!("{}: {} clips, {} frames at {} fps, {} joints", s.dataset, s.clips, s.frames, s.fps, s.joints);
    say!("{:<20} {:>6} {:>9}", "class", "clips", "frames");
    for c in &s.classes {
        say!("{:<20} {:>6} {:>9}", c.name, c.clips, c.frames);
    }
    if s.skipped.is_empty() {
        say!("no files skipped");
    }
    for k in &s.skipped {
        say!("skipped {}: {}", k.file, k.reason);
    }
}

pub fn bench_load(args: &DatasetArgs) -> Result<()> {
    let (dataset, json): (Dataset, bool) = (args.dataset.parse()?, args.json);
    let root = DataRoot::resolve(args.data.as_deref());
    let start = Instant::now();
    let loaded = loading::load(dataset, &root)?;
    let seconds = start.elapsed().as_secs_f64();
    let s = stats(&loaded);
    if json {
        say!("{}", serde_json::json!({"dataset": s.dataset, "seconds": seconds, "clips": s.clips, "frames": s.frames}));
    } else {
        say!("loaded {} ({} clips, {} frames) in {:.2} s", s.dataset, s.clips, s.frames, seconds);
    }
    Ok(())
}
