use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use crate::data::joint_map::UserJointMap;
use crate::data::write::{check_extension, check_output};
use crate::model::glocal::GlocalModel;
use crate::synth::own_start::take_on_rig;
use crate::synth::export::{export_with_contacts, prepare, ExportFormat, ExportOptions};
use crate::synth::render::{write_contact_sheet, SheetOptions};
use super::args::{JointNamesArg, RootMotionArg, TransitionArg, UnitsArg};
use crate::synth::joint_names::JointNames;
use crate::synth::{Document, GenerateOptions, InitPose, Key, KeySource, Preset, Request, RootPath, SegmentSpan, Timeline, DEFAULT_TRANSITION_SECONDS};

#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// Model folder (default: the project's model with --project, else the shipped h36m
    /// model: models/h36m in the working folder, beside the executable or in the checkout it
    /// was built in).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Segments as CLASS[/STYLE]:SECONDS[@PACE][~TRANSITION], comma-separated, e.g.
    /// "sitting:3,eating:5,walking:10~0.5" (TRANSITION: seconds into that segment; STYLE on
    /// a model with styles, e.g. "walking/tired:6").
    #[arg(long, required_unless_present = "project")]
    pub timeline: Option<String>,
    /// The style of every segment that names none (a model with styles, e.g. models/all).
    #[arg(long, conflicts_with = "project")]
    pub style: Option<String>,
    /// A studio project (.glocal): the take it describes, with its model, activities, keys,
    /// path and generation settings as saved (--model picks another model).
    #[arg(long, conflicts_with_all = ["timeline", "keys", "path"])]
    pub project: Option<PathBuf>,
    #[arg(long, default_value_t = 1.0)]
    pub pace: f32,
    /// seed:CLASS, seed:N, or clip:PATH@FRAME (a BVH, NPY or exponential-map file; FRAME the
    /// file's own; a file shorter than the start's 2 s, one pose even, holds its frame FRAME
    /// before the rest). Default: the first seed-bank window of the first segment's class, in
    /// the style that segment names where the class has one.
    #[arg(long)]
    pub init: Option<String>,
    /// Plain interpolation between sparse poses instead of LocGen.
    #[arg(long, conflicts_with = "locgen")]
    pub no_locgen: bool,
    /// LocGen on a model whose takes go without it unless asked (Bandai's: its LocGen takes
    /// them further from capture than the spline alone).
    #[arg(long)]
    pub locgen: bool,
    #[arg(long, value_enum, default_value = "anchor")]
    pub transition: TransitionArg,
    /// Seconds over which each class change happens, centred on its boundary (0: a cut).
    #[arg(long, default_value_t = DEFAULT_TRANSITION_SECONDS)]
    pub transition_seconds: f32,
    /// A full-body pose the take passes through: TIME=SOURCE[,root], SOURCE as --init
    /// (seed:CLASS, seed:N, clip:PATH@FRAME); `,root` also fixes where the body stands and
    /// faces. Repeatable.
    #[arg(long = "key", value_name = "TIME=SOURCE")]
    pub keys: Vec<String>,
    /// A root path for the take's locomotion: JSON or CSV of (seconds, x, z) waypoints in
    /// metres (see the README).
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Leave GloGen's blocks unjoined at their seams (as in the paper), for comparison.
    #[arg(long)]
    pub no_seam_join: bool,
    /// The paper's GlocalNet: cut transitions, class strength 1, no keep-alive, unjoined seams.
    #[arg(long)]
    pub paper: bool,
    /// Classifier-free guidance weight (1: plain conditioning; ignored by models trained
    /// without class dropout). Default: the model's own (its model.json's `class_strength`).
    #[arg(long)]
    pub class_strength: Option<f32>,
    /// Variation seed: 0 gives the model's deterministic take, others differ slightly.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Skip the bone-length projection.
    #[arg(long)]
    pub no_projection: bool,
    /// Let a long segment's motion stall instead of re-anchoring it on the class's seed windows and urging it on with stronger guidance.
    #[arg(long)]
    pub no_keep_alive: bool,
    /// Leave planted feet as the network made them (no contact locking with leg IK).
    #[arg(long)]
    pub no_foot_lock: bool,
    /// Let a travelling class turn as the network makes it (on the h36m and `all` models a
    /// walk goes round in circles, as Human3.6M's subjects did round their room) instead of
    /// keeping a straight course where no --path is given.
    #[arg(long)]
    pub no_hold_course: bool,
    /// The frames between GloGen's poses as LocGen leaves them, without the motion texture of
    /// the classes' training clips (on models that ship one: `all`).
    #[arg(long)]
    pub no_texture: bool,
    /// Leave a bone that turns farther in one frame than the model's training clips do as
    /// the network made it, instead of spreading its turn over the frames around it.
    #[arg(long)]
    pub no_snap_spread: bool,
    /// Cut the take (one activity) to a cycle of about its duration whose end joins its
    /// start in pose and velocity, for a game engine's loop; the travel per cycle is printed.
    #[arg(long = "loop")]
    pub cycle: bool,
    #[command(flatten)]
    pub output: OutputArgs,
}

/// The file a take is written to, and on which skeleton, in which units, at which frame
/// rate and with which joint names.
#[derive(Args, Debug)]
pub struct OutputArgs {
    /// Output file: .bvh, .json, .npy, or .glb (a skinned glTF character).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long)]
    pub json: bool,
    /// Write the take on another humanoid skeleton: a BVH whose hierarchy and rest pose the
    /// output takes (e.g. a Mixamo or CMU rig), joints mapped by name.
    #[arg(long)]
    pub retarget_to: Option<PathBuf>,
    /// A JSON file {"joint name": "Key", ...} naming key joints (Hips, LeftArm, LeftForeArm,
    /// ...) of the foreign BVH (--init clip:FILE.bvh or --retarget-to) where the built-in name
    /// table does not find them.
    #[arg(long)]
    pub joint_map: Option<PathBuf>,
    /// Length unit of the file: metres (what engines expect), centimetres, or the model's own.
    #[arg(long, value_enum, default_value = "metres")]
    pub units: UnitsArg,
    /// Frame rate of the file (e.g. 24, 30, 60); the model's own by default.
    #[arg(long)]
    pub fps: Option<f32>,
    /// Joint names of the file: the skeleton's own, or those Mixamo tools, Unreal's
    /// mannequin or Unity's Humanoid avatar recognise, given by each joint's role.
    #[arg(long, value_enum, default_value = "native")]
    pub joint_names: JointNamesArg,
    /// Where the take's travel goes: the hips (travel), nowhere (in-place: the body moves on
    /// the spot), or an added root joint on the floor (root-bone: Unreal's and Unity's root
    /// motion).
    #[arg(long, value_enum, default_value = "travel")]
    pub root_motion: RootMotionArg,
}

/// `seed:CLASS`, `seed:N` or `clip:PATH@FRAME`.
pub fn parse_init(s: &str) -> Result<InitPose> {
    if let Some(rest) = s.strip_prefix("seed:") {
        return Ok(match rest.parse::<usize>() {
            Ok(i) => InitPose::SeedIndex(i),
            Err(_) => InitPose::SeedClass { class: rest.to_string(), variant: 0 },
        });
    }
    if let Some(rest) = s.strip_prefix("clip:") {
        let (path, frame) = match rest.rsplit_once('@') {
            Some((p, f)) => (p, f.parse::<usize>().with_context(|| format!("--init {s}: frame '{f}' is not a whole number"))?),
            None => (rest, 0),
        };
        return Ok(InitPose::file(PathBuf::from(path), frame));
    }
    bail!("--init {s}: expected seed:CLASS, seed:N or clip:PATH@FRAME")
}

pub fn run_generate(args: GenerateArgs) -> Result<()> {
    let output = &args.output;
    ExportFormat::from_path(&output.out)?;
    if let Some(fps) = output.fps.filter(|f| !(f.is_finite() && (1.0..=1000.0).contains(f))) {
        bail!("--fps {fps}: expected a frame rate from 1 to 1000");
    }
    let document = args.project.as_deref().map(Document::load).transpose()?;
    let model_dir = match (&args.model, &document) {
        (Some(dir), _) => dir.clone(),
        (None, Some(document)) => crate::model::project_model(&document.model),
        (None, None) => crate::model::shipped_model("h36m"),
    };
    let model = GlocalModel::load(&model_dir)?;
    let mut request = match (document, &args.timeline) {
        (Some(document), _) => document.request(),
        (None, Some(timeline)) => Request { options: options_from_args(&args, timeline, &model)?, joint_map: None },
        (None, None) => bail!("--timeline or --project is needed"),
    };
    // Every file the take reads: the output may be none of them.
    let inputs: Vec<&Path> = args.project.iter().map(PathBuf::as_path).chain(input_files(&request.options)).chain(output.retarget_to.as_deref()).chain(output.joint_map.as_deref()).collect();
    check_output(&output.out, &inputs)?;
    if let Some(path) = &output.joint_map {
        request.joint_map = Some(UserJointMap::read(path)?);
    }
    request.options = Preset::from_paper_flag(args.paper).apply(request.options);
    let start = Instant::now();
    let bar = ProgressBar::new(1000);
    bar.set_style(ProgressStyle::with_template("{bar:30} {percent}% {elapsed}")?);
    if output.json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let take = request.generate(&model, &mut |f| {
        bar.set_position((f * 1000.0) as u64);
        true
    })?;
    let elapsed = start.elapsed();
    bar.finish_and_clear();
    let options = ExportOptions { units: output.units.into(), fps: output.fps, source_root: false, root_motion: output.root_motion.into(), rig: output.retarget_to.clone() };
    let motion = match &options.rig {
        Some(rig) => take_on_rig(&model, &request, &take.motion, rig)?,
        None => take.motion.clone(),
    };
    let (m, segments) = prepare(&motion, &take.segments, &options, &model.spec.source_skeleton)?;
    let m = JointNames::from(output.joint_names).apply(&m, request.joint_map.as_ref())?;
    export_with_contacts(&m, &segments, Some(&take.contacts), &output.out)?;
    note_rounded_durations(&request.options, &take.segments, take.motion.fps);
    for warning in &take.warnings {
        eprintln!("warning: {warning}");
    }
    let cycle = take.cycle.as_ref().map(|c| c.summary(take.motion.fps, take.motion.skeleton.meters_per_unit()));
    let m = &m;
    if output.json {
        let summary = serde_json::json!({
            "frames": m.frames(),
            "fps": m.fps,
            "seconds": m.seconds(),
            "segments": segments,
            "elapsed_ms": elapsed.as_secs_f64() * 1e3,
            "warnings": take.warnings,
            "loop": cycle,
            "out": output.out,
        });
        say!("{summary}");
    } else {
        say!("{} frames at {} fps ({:.2} s) in {:.1} ms -> {}", m.frames(), m.fps, m.seconds(), elapsed.as_secs_f64() * 1e3, output.out.display());
        for s in &segments {
            say!("  {:<14} frames {:>6} .. {:>6}", s.label(), s.start_frame, s.end_frame);
        }
        if let Some(cycle) = &cycle {
            say!("{cycle}");
        }
    }
    Ok(())
}

/// Where a take starts unless told: in its first activity, on the first of its seed windows
/// in the style the first segment asks for where the class has one (a take would otherwise
/// spend its first seconds easing out of another style's window), else on its first.
fn first_activity_start(timeline: &Timeline, model: &GlocalModel) -> InitPose {
    let Some(first) = timeline.segments.first() else { return InitPose::SeedClass { class: String::new(), variant: 0 } };
    let spec = &model.spec;
    let in_style = || {
        let style = spec.styles.iter().position(|s| Some(s) == first.style.as_ref())?;
        model.class_seed_variant_in_style(spec.class_index(&first.class).ok()?, style)
    };
    InitPose::SeedClass { class: first.class.clone(), variant: in_style().unwrap_or(0) }
}

/// The generation options the command line's flags ask for.
fn options_from_args(args: &GenerateArgs, timeline: &str, model: &GlocalModel) -> Result<GenerateOptions> {
    let timeline: Timeline = timeline.parse()?;
    let timeline = match &args.style {
        Some(style) => timeline.with_style(style),
        None => timeline,
    };
    let init = match &args.init {
        Some(init) => parse_init(init)?,
        None => first_activity_start(&timeline, model),
    };
    Ok(GenerateOptions {
        timeline,
        pace: args.pace,
        init,
        locgen: if args.no_locgen { Some(false) } else { args.locgen.then_some(true) },
        transition: args.transition.into(),
        transition_seconds: args.transition_seconds,
        class_strength: args.class_strength,
        project_bones: !args.no_projection,
        keep_alive: !args.no_keep_alive,
        join_seams: !args.no_seam_join,
        foot_lock: !args.no_foot_lock,
        hold_course: !args.no_hold_course,
        texture: !args.no_texture,
        spread_snaps: !args.no_snap_spread,
        keys: args.keys.iter().map(|k| Key::parse(k, parse_init)).collect::<Result<_>>()?,
        path: args.path.as_deref().map(RootPath::read).transpose()?,
        cycle: args.cycle,
        ..Default::default()
    }
    .varied(args.seed))
}

/// The motion files a take starts from or takes keys from.
fn input_files(opts: &GenerateOptions) -> impl Iterator<Item = &Path> {
    let keyed = opts.keys.iter().filter_map(|k| match &k.source {
        KeySource::Init(init) => Some(init),
        KeySource::Pose(_) => None,
    });
    std::iter::once(&opts.init).chain(keyed).filter_map(|init| match init {
        InitPose::File { path, .. } => Some(path.as_path()),
        _ => None,
    })
}

/// Segments last whole sparse steps (`stride * pace` frames), so a duration that is not a
/// multiple of one is rounded; say so rather than let a take run longer or shorter unseen.
fn note_rounded_durations(opts: &GenerateOptions, segments: &[SegmentSpan], fps: f32) {
    for (asked, got) in opts.timeline.segments.iter().zip(segments) {
        let seconds = (got.end_frame - got.start_frame) as f32 / fps;
        if (seconds - asked.seconds).abs() > 1.5 / fps {
            eprintln!("note: segment '{}' lasts {seconds:.2} s, not {} s: durations are rounded to whole sparse steps", got.label(), asked.seconds);
        }
    }
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A take exported by `glocal generate` (.json keeps the segment colours; .bvh and .npy
    /// need --model for the skeleton of an NPY).
    #[arg(long = "in")]
    pub input: PathBuf,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value = "models/h36m")]
    pub model: PathBuf,
    #[arg(long, default_value_t = 8)]
    pub columns: usize,
    #[arg(long, default_value_t = 3)]
    pub rows: usize,
}

/// Cells per side of a contact sheet: 64 x 160 px is a 10240 px image.
const MAX_SHEET_CELLS: usize = 64;

pub fn run_render(args: RenderArgs) -> Result<()> {
    for (flag, v) in [("columns", args.columns), ("rows", args.rows)] {
        if !(1..=MAX_SHEET_CELLS).contains(&v) {
            bail!("--{flag} must be between 1 and {MAX_SHEET_CELLS}, got {v}");
        }
    }
    check_extension(&args.out, &["png"])?;
    check_output(&args.out, &[&args.input])?;
    let (motion, segments) = crate::synth::export::read_take(&args.input, Some(&args.model).filter(|p| p.exists()).map(Path::new))?;
    write_contact_sheet(&motion, &segments, &args.out, &SheetOptions { columns: args.columns, rows: args.rows, cell: 160 })?;
    say!("{} frames -> {}", motion.frames(), args.out.display());
    Ok(())
}
