//! The `glocal generate` command line that makes the studio's take: what "Copy as command
//! line" puts on the clipboard. Every setting the command line has a flag for is spelled
//! out; a take pinned by what only a project file holds (keys made from a take's frames, a
//! root path drawn in the viewport, a joint map made in the editor) is made from its saved
//! project with `--project`.

use std::path::{Path, PathBuf};

use super::app::StudioApp;
use super::messages::{Level, Topic};
use super::worker::ModelInfo;
use crate::synth::export::{ExportOptions, Units};
use crate::synth::{Document, GenerateOptions, InitPose, KeySource, Transition, DEFAULT_TRANSITION_SECONDS};
use crate::motion::RootMotion;

impl StudioApp {
    /// The arguments after `glocal` that make the document's take and export it to the
    /// export file with the export's settings.
    pub fn command_args(&self) -> Result<Vec<String>, String> {
        let model = self.engine.model.as_ref().filter(|m| m.dir == self.editing.doc.model).ok_or("the model is still loading")?;
        let out = PathBuf::from(self.panels.fields.export_path.trim());
        let saved_at = self.editing.project_path.as_deref().filter(|_| !self.has_unsaved_work());
        generate_args(&self.editing.doc, model, &out, &self.export_options(), saved_at)
    }

    /// Puts the command line on the clipboard and shows it.
    pub fn copy_command_line(&mut self, ctx: &egui::Context) {
        match self.command_args() {
            Ok(args) => {
                let line = shell_line(&args);
                ctx.copy_text(line.clone());
                self.messages.set(Topic::Export, Level::Info, format!("Copied: {line}"));
            }
            Err(why) => self.messages.set(Topic::Export, Level::Error, format!("No command line: {why}")),
        }
    }
}

/// The arguments after `glocal` that make `doc`'s take on `model` and write it to `out` as
/// `export` says; `saved_at` is where the project was saved (for what only it can hold).
/// Err says why there is none.
pub fn generate_args(doc: &Document, model: &ModelInfo, out: &Path, export: &ExportOptions, saved_at: Option<&Path>) -> Result<Vec<String>, String> {
    let mut args: Vec<String> = vec!["generate".into()];
    match only_in_a_project(&doc.options, doc.joint_map.is_some()) {
        None => {
            args.extend(["--model".into(), doc.model.display().to_string()]);
            args.extend(option_args(&doc.options, model));
        }
        Some(what) => {
            let path = saved_at.ok_or_else(|| format!("the take has {what}, which only its project file holds: save the project first"))?;
            args.extend(["--project".into(), path.display().to_string()]);
        }
    }
    args.extend(["--out".into(), out.display().to_string()]);
    args.extend(export_args(export));
    Ok(args)
}

/// `args` as one line a shell reads back as they are.
pub fn shell_line(args: &[String]) -> String {
    std::iter::once("glocal".to_string()).chain(args.iter().map(|a| quoted(a))).collect::<Vec<_>>().join(" ")
}

/// What the take has that no flag says, if anything.
fn only_in_a_project(options: &GenerateOptions, joint_map: bool) -> Option<&'static str> {
    if options.keys.iter().any(|k| matches!(k.source, KeySource::Pose(_))) {
        Some("keys made from a take's frames")
    } else if options.path.is_some() {
        Some("a root path")
    } else if !options.held.is_empty() {
        Some("frames kept from rerolled, edited or locked segments")
    } else if joint_map {
        Some("a joint map")
    } else if options.key_method != GenerateOptions::default().key_method {
        Some("a key method of the ablation")
    } else {
        None
    }
}

/// The flags of the generation options (those at their command-line default left out).
fn option_args(options: &GenerateOptions, model: &ModelInfo) -> Vec<String> {
    let mut args = vec!["--timeline".to_string(), options.timeline.to_string(), "--pace".into(), options.pace.to_string()];
    args.extend(["--init".into(), init_arg(&options.init, model)]);
    let transition = match options.transition {
        Transition::Anchor => "anchor",
        Transition::Blend => "blend",
        Transition::Cut => "cut",
    };
    args.extend(["--transition".into(), transition.into()]);
    if options.transition_seconds != DEFAULT_TRANSITION_SECONDS {
        args.extend(["--transition-seconds".into(), options.transition_seconds.to_string()]);
    }
    if let Some(strength) = options.class_strength {
        args.extend(["--class-strength".into(), strength.to_string()]);
    }
    if options.seed != 0 {
        args.extend(["--seed".into(), options.seed.to_string()]);
    }
    for key in &options.keys {
        if let KeySource::Init(init) = &key.source {
            let root = if key.fix_root { ",root" } else { "" };
            args.extend(["--key".into(), format!("{}={}{root}", key.seconds, init_arg(init, model))]);
        }
    }
    // LocGen's flags say only where the take's choice is not its model's.
    let (by_default, refines) = (model.spec.locgen.by_default, options.locgen_for(&model.spec));
    let switches = [
        (by_default && !refines, "--no-locgen"),
        (!by_default && refines, "--locgen"),
        (!options.project_bones, "--no-projection"),
        (!options.keep_alive, "--no-keep-alive"),
        (!options.join_seams, "--no-seam-join"),
        (!options.foot_lock, "--no-foot-lock"),
        (!options.hold_course, "--no-hold-course"),
        (!options.texture, "--no-texture"),
        (!options.spread_snaps, "--no-snap-spread"),
        (options.cycle, "--loop"),
    ];
    args.extend(switches.into_iter().filter(|(on, _)| *on).map(|(_, flag)| flag.to_string()));
    args
}

/// `--init`'s spelling of a start: a class's variant is its seed-bank entry.
fn init_arg(init: &InitPose, model: &ModelInfo) -> String {
    match init {
        InitPose::SeedClass { class, variant } => {
            let entry = model.spec.class_index(class).ok().and_then(|c| {
                let windows: Vec<usize> = model.seeds.iter().enumerate().filter(|(_, s)| s.class == c).map(|(i, _)| i).collect();
                windows.get(variant % windows.len().max(1)).copied()
            });
            entry.map_or_else(|| format!("seed:{class}"), |i| format!("seed:{i}"))
        }
        InitPose::SeedIndex(i) => format!("seed:{i}"),
        InitPose::File { path, frame, .. } => format!("clip:{}@{frame}", path.display()),
    }
}

/// The export's flags (a Bandai source root joint has none: the take is the same without).
fn export_args(export: &ExportOptions) -> Vec<String> {
    let mut args = Vec::new();
    let units = match export.units {
        Units::Metres => None,
        Units::Centimetres => Some("centimetres"),
        Units::Native => Some("native"),
    };
    if let Some(units) = units {
        args.extend(["--units".into(), units.into()]);
    }
    if let Some(fps) = export.fps {
        args.extend(["--fps".into(), fps.to_string()]);
    }
    let root_motion = match export.root_motion {
        RootMotion::Travel => None,
        RootMotion::InPlace => Some("in-place"),
        RootMotion::RootBone => Some("root-bone"),
    };
    if let Some(root_motion) = root_motion {
        args.extend(["--root-motion".into(), root_motion.into()]);
    }
    if let Some(rig) = &export.rig {
        args.extend(["--retarget-to".into(), rig.display().to_string()]);
    }
    args
}

/// `arg` as a shell word: as it is when it has nothing a shell reads specially, else in
/// single quotes.
fn quoted(arg: &str) -> String {
    let plain = !arg.is_empty() && arg.chars().all(|c| c.is_ascii_alphanumeric() || "-_./:@,=~+%".contains(c));
    if plain {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::{option_args, quoted, ModelInfo};
    use crate::model::spec::ModelSpec;
    use crate::synth::GenerateOptions;

    /// LocGen's flag is written where the take's choice is not its model's: `--no-locgen` on
    /// h36m, `--locgen` on Bandai (whose takes go without it unless asked), none otherwise.
    #[test]
    fn locgen_is_a_flag_only_against_the_models_word() {
        for (name, asked, flag) in [("h36m", Some(false), Some("--no-locgen")), ("h36m", Some(true), None), ("h36m", None, None), ("bandai", Some(true), Some("--locgen")), ("bandai", Some(false), None), ("bandai", None, None)] {
            let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name);
            let model = ModelInfo { spec: ModelSpec::read(&dir).unwrap(), dir, seeds: Vec::new(), typical: Vec::new(), has_locgen: true, has_texture: false };
            let args = option_args(&GenerateOptions { locgen: asked, ..Default::default() }, &model);
            let flags: Vec<&str> = args.iter().map(String::as_str).filter(|a| a.contains("locgen")).collect();
            assert_eq!(flags, flag.into_iter().collect::<Vec<_>>(), "{name}, {asked:?}");
        }
    }

    #[test]
    fn shell_words_are_quoted_only_when_needed() {
        assert_eq!(quoted("walking:3@1.5,sitting:2~0.5"), "walking:3@1.5,sitting:2~0.5");
        assert_eq!(quoted("my take.bvh"), "'my take.bvh'");
        assert_eq!(quoted("it's"), r"'it'\''s'");
        assert_eq!(quoted(""), "''");
    }
}
