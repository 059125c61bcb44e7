//! Robustness (issue 20): each bug of the fault-injection trial reproduced on real files
//! (copies of a shipped model, takes it generates, dataset files) through the `glocal`
//! command a user runs, and refused with a one-line error or fixed; then every reader run
//! over a fixed corpus of mutated real files.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use glocal::data::archive::DataRoot;
use glocal::data::bvh::read_bvh;
use glocal::data::expmap::{ExpmapFormat, RootEncoding};
use glocal::data::npy::{motion_from_npy, read_npy};
use glocal::data::write::{write_atomic, FolderLock};
use glocal::model::glocal::GlocalModel;
use glocal::model::spec::ModelSpec;
use glocal::studio::project::Project;
use glocal::synth::export::parse_json_take;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde_json::Value;

#[path = "support/models.rs"]
mod models;
use models::{model_copy, shipped_model};

const BIN: &str = env!("CARGO_BIN_EXE_glocal");

fn glocal(args: &[&str]) -> Output {
    Command::new(BIN).args(args).stdin(Stdio::null()).output().unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs a command that must fail: exit 1 (no panic, no signal), one line on stderr that
/// holds every `expected` piece. Returns the line.
fn refused(args: &[&str], expected: &[&str]) -> String {
    let out = glocal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
    assert_eq!(out.status.code(), Some(1), "{args:?} should fail: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{args:?}: not one line: {stderr}");
    for e in expected {
        assert!(stderr.contains(e), "{args:?}: '{e}' not in: {stderr}");
    }
    stderr
}

fn succeeds(args: &[&str]) -> Output {
    let out = glocal(args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

/// A 3 s Bandai take written by `glocal generate` in `dir`.
fn take(model: &Path, dir: &Path, file: &str) -> PathBuf {
    let out = dir.join(file);
    succeeds(&["generate", "--model", s(model), "--timeline", "walk:3", "--out", s(&out)]);
    out
}

/// Every file in `dir` whose name marks it as a temporary file of ours.
fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).filter(|n| n.contains(".glocal-tmp-")).collect()
}

/// The BVH's lines with frame `frame`'s (from 1) first value replaced by `value`.
fn bvh_with_root_x(bvh: &str, frame: usize, value: &str) -> String {
    let lines: Vec<&str> = bvh.lines().collect();
    let first = lines.iter().position(|l| l.starts_with("Frame Time")).unwrap() + 1;
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let mut values: Vec<&str> = lines[first + frame - 1].split_whitespace().collect();
    values[0] = value;
    out[first + frame - 1] = values.join(" ");
    out.join("\n")
}

#[test]
fn h1_resume_without_training_state_refuses_and_keeps_the_weights() {
    let (_t, model) = model_copy("bandai");
    let before = std::fs::read(model.join("locgen.safetensors")).unwrap();
    let args = ["train", "--dataset", "bandai", "--stage", "locgen", "--steps", "5", "--checkpoint-every", "5", "--out", s(&model), "--resume"];
    refused(&args, &["--fine-tune", "locgen.safetensors", "no training state"]);
    assert_eq!(std::fs::read(model.join("locgen.safetensors")).unwrap(), before);
}

#[test]
fn a_fine_tuned_locgen_keeps_the_residual_scale_it_was_trained_with() {
    let (_t, model) = model_copy("h36m");
    let trained = ModelSpec::read(&model).unwrap().locgen.residual_scale;
    assert!(!trained.is_empty());
    succeeds(&["train", "--dataset", "h36m", "--stage", "locgen", "--steps", "3", "--eval-every", "3", "--checkpoint-every", "3", "--hidden", "128", "--out", s(&model), "--fine-tune"]);
    assert_eq!(ModelSpec::read(&model).unwrap().locgen.residual_scale, trained);
}

/// `--only-styles` trains those styles' label inputs alone: on a copy of the shipped `all`,
/// 3 steps teaching tired (its inputs zeroed first) leave a take in another style the same to
/// the byte and change one in tired; the GloGen's own record and the classes' calibrated
/// guidance stay, the run has its own record.
#[test]
fn a_style_taught_alone_leaves_every_other_take_as_it_was() {
    let (t, model) = model_copy("all");
    let shipped = shipped_model("all");
    let before = ModelSpec::read(&model).unwrap();
    succeeds(&["train", "--dataset", "all", "--stage", "glogen", "--steps", "3", "--eval-every", "3", "--checkpoint-every", "3", "--stride", "3", "--out", s(&model), "--fine-tune", "--only-styles", "tired"]);
    let after = ModelSpec::read(&model).unwrap();
    assert_eq!((&after.styles, &after.class_strengths, &after.training.glogen), (&before.styles, &before.class_strengths, &before.training.glogen));
    assert_eq!(after.training.styles.as_ref().map(|r| r.steps), Some(3));
    let take = |model: &Path, timeline: &str, name: &str| {
        let out = t.path().join(name);
        succeeds(&["generate", "--model", s(model), "--timeline", timeline, "--seed", "2", "--out", s(&out), "--json"]);
        std::fs::read(out).unwrap()
    };
    assert_eq!(take(&model, "walk-back/happy:3", "a.json"), take(&shipped, "walk-back/happy:3", "b.json"), "a take in another style changed");
    assert_ne!(take(&model, "walk-back/tired:3", "c.json"), take(&shipped, "walk-back/tired:3", "d.json"), "the take in tired did not change");
    // A style the data does not have is refused before the folder is touched.
    let files = |dir: &Path| ["model.json", "glogen.safetensors"].map(|f| std::fs::read(dir.join(f)).unwrap());
    let kept = files(&model);
    refused(&["train", "--dataset", "all", "--stage", "glogen", "--steps", "3", "--stride", "3", "--out", s(&model), "--fine-tune", "--only-styles", "tired,sleepy"], &["--only-styles", "'sleepy' is not a style of the data", "musical"]);
    assert!(files(&model) == kept, "a refused run changed the model");
}

#[test]
fn fine_tuning_from_a_model_of_other_labels_is_refused_before_anything_is_written() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("new");
    let from = shipped_model("h36m");
    refused(&["train", "--dataset", "bandai", "--stage", "glogen", "--steps", "3", "--stride", "3", "--out", s(&out), "--init-from", s(&from)], &["cannot fine-tune from", "models/h36m", "its classes (directions", "are not the data's (walk"]);
    assert!(!out.exists());
}

#[test]
fn h2_h3_overlong_inputs_and_takes_are_refused_up_front() {
    let (t, model) = model_copy("bandai");
    let start = take(&model, t.path(), "start.bvh");
    let text = std::fs::read_to_string(&start).unwrap();
    let slow = t.path().join("slow.bvh");
    let lines: Vec<String> = text.lines().map(|l| if l.starts_with("Frame Time") { "Frame Time: 1000".to_string() } else { l.to_string() }).collect();
    std::fs::write(&slow, lines.join("\n")).unwrap();
    let out = t.path().join("out.bvh");
    let init = format!("clip:{}@0", s(&slow));
    refused(&["generate", "--model", s(&model), "--init", &init, "--timeline", "walk:3", "--out", s(&out)], &["slow.bvh", "longer than the 3600 s"]);
    for long in ["walk:86400", "walk:1e9", "walk:3000,bow:601"] {
        refused(&["generate", "--model", s(&model), "--timeline", long, "--out", s(&out)], &["at most 3600 s"]);
    }
    assert!(!out.exists());
}

#[test]
fn m1_m2_implausible_start_poses_name_their_frame() {
    let (t, model) = model_copy("bandai");
    let start = take(&model, t.path(), "start.bvh");
    let text = std::fs::read_to_string(&start).unwrap();
    let out = t.path().join("out.json");
    let generate = |file: &Path| {
        let init = format!("clip:{}@0", s(file));
        ["generate".to_string(), "--model".into(), s(&model).into(), "--init".into(), init, "--timeline".into(), "walk:3".into(), "--out".into(), s(&out).into()]
    };
    for (name, value, frame) in [("spike.bvh", "3e38", 5), ("far.bvh", "1e20", 7)] {
        let file = t.path().join(name);
        std::fs::write(&file, bvh_with_root_x(&text, frame, value)).unwrap();
        let args = generate(&file);
        refused(&args.iter().map(String::as_str).collect::<Vec<_>>(), &[name, &format!("frame {frame}:")]);
    }
    // +3e38 in one frame, -3e38 in the next: the NaN of M1 never forms.
    let both = t.path().join("both.bvh");
    std::fs::write(&both, bvh_with_root_x(&bvh_with_root_x(&text, 3, "3e38"), 4, "-3e38")).unwrap();
    refused(&generate(&both).iter().map(String::as_str).collect::<Vec<_>>(), &["both.bvh", "frame 3:"]);
    // A bone of 1e30 units.
    let offset = t.path().join("offset.bvh");
    let mut seen = 0;
    let huge: Vec<String> = text
        .lines()
        .map(|l| {
            if l.trim_start().starts_with("OFFSET") {
                seen += 1;
                if seen == 3 {
                    return "OFFSET 1e30 0 0".to_string();
                }
            }
            l.to_string()
        })
        .collect();
    std::fs::write(&offset, huge.join("\n")).unwrap();
    refused(&generate(&offset).iter().map(String::as_str).collect::<Vec<_>>(), &["offset.bvh", "frame 1:"]);
    // One translation of 3e38 in a Human3.6M exponential-map file.
    let (h, h36m) = model_copy("h36m");
    let files = DataRoot::resolve(None).read_archive("h36m", |n| n == "h36m/S1/walking_1.txt").unwrap();
    let mut rows: Vec<String> = String::from_utf8(files[0].1.clone()).unwrap().lines().map(str::to_string).collect();
    let mut values: Vec<String> = rows[40].split(',').map(str::to_string).collect();
    values[0] = "3e38".into();
    rows[40] = values.join(",");
    let expmap = h.path().join("spike.txt");
    std::fs::write(&expmap, rows.join("\n")).unwrap();
    let init = format!("clip:{}@0", s(&expmap));
    let hout = h.path().join("out.bvh");
    refused(&["generate", "--model", s(&h36m), "--init", &init, "--timeline", "walking:3", "--out", s(&hout)], &["spike.txt:41", "the root moves"]);
    assert!(!out.exists() && !hout.exists());
}

#[test]
fn m4_l1_outputs_that_are_inputs_or_not_files_are_refused() {
    let (t, model) = model_copy("bandai");
    let start = take(&model, t.path(), "start.bvh");
    let before = std::fs::read(&start).unwrap();
    refused(&["render", "--in", s(&start), "--out", s(&start)], &["start.bvh", ".png"]);
    let init = format!("clip:{}@0", s(&start));
    refused(&["generate", "--model", s(&model), "--init", &init, "--timeline", "walk:3", "--out", s(&start)], &["overwrite the input"]);
    // The rig a take is written on, and a joint map, are inputs too (the rig was replaced by
    // the take written on it).
    refused(&["generate", "--model", s(&model), "--timeline", "walk:3", "--retarget-to", s(&start), "--out", s(&start)], &["overwrite the input"]);
    let map = t.path().join("map.json");
    std::fs::write(&map, "{}").unwrap();
    refused(&["generate", "--model", s(&model), "--timeline", "walk:3", "--joint-map", s(&map), "--out", s(&map)], &["overwrite the input"]);
    assert_eq!(std::fs::read(&start).unwrap(), before, "a refused command leaves its target as it was");
    assert_eq!(std::fs::read_to_string(&map).unwrap(), "{}");
    let dev = t.path().join("null.png");
    std::os::unix::fs::symlink("/dev/null", &dev).unwrap();
    refused(&["render", "--in", s(&start), "--out", s(&dev)], &["null.png", "not a regular file"]);
    let fifo = t.path().join("fifo.png");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    refused(&["render", "--in", s(&start), "--out", s(&fifo)], &["fifo.png", "not a regular file"]);
    let folder = t.path().join("folder.png");
    std::fs::create_dir(&folder).unwrap();
    refused(&["render", "--in", s(&start), "--out", s(&folder)], &["folder.png", "is a folder"]);
    // A link to a regular file is written through: the link stays, its file gets the PNG.
    let real = t.path().join("real.png");
    std::fs::write(&real, b"old").unwrap();
    let link = t.path().join("link.png");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    succeeds(&["render", "--in", s(&start), "--out", s(&link)]);
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert!(std::fs::read(&real).unwrap().starts_with(b"\x89PNG"));
    assert!(temp_files(t.path()).is_empty(), "{:?}", temp_files(t.path()));
}

/// Each damaged field is refused at load, by name, before anything is allocated.
#[test]
fn m5_model_json_is_validated_field_by_field() {
    let (_t, model) = model_copy("bandai");
    let original: Value = serde_json::from_str(&std::fs::read_to_string(model.join("model.json")).unwrap()).unwrap();
    let cases: Vec<(&str, Box<dyn Fn(&mut Value)>, &str)> = vec![
        ("hidden 1e6", Box::new(|v| v["glogen"]["block"]["hidden"] = 1_000_000.into()), "glogen.block.hidden"),
        ("stride 0", Box::new(|v| v["stride"] = 0.into()), "`stride`"),
        ("fps 1e30", Box::new(|v| v["fps"] = 1e30.into()), "`fps`"),
        ("fps 0", Box::new(|v| v["fps"] = 0.into()), "`fps`"),
        ("fps -25", Box::new(|v| v["fps"] = (-25).into()), "`fps`"),
        ("window 0", Box::new(|v| v["locgen"]["window"] = 0.into()), "locgen.window"),
        ("kept sparse poses off the window's strides", Box::new(|v| v["locgen"]["keep_sparse_poses"] = true.into()), "locgen.window"),
        ("residual scale one short", Box::new(|v| v["locgen"]["residual_scale"] = vec![1.0; 3].into()), "locgen.residual_scale"),
        ("in-betweener without context", Box::new(|v| v["inbetween"]["context"] = 0.into()), "inbetween.context"),
        ("in-betweener reading poses alone", Box::new(|v| v["inbetween"]["block"]["in_dim"] = v["locgen"]["block"]["in_dim"].clone()), "inbetween.block"),
        ("in-betweener scale one short", Box::new(|v| v["inbetween"]["residual_scale"] = vec![1.0; 3].into()), "inbetween.residual_scale"),
        ("hip out of range", Box::new(|v| v["layout"]["left_hip"] = 999.into()), "layout.left_hip"),
        ("joint out of range", Box::new(|v| v["source_joints"][3] = 999.into()), "source_joints"),
        ("forward parent", Box::new(|v| v["layout"]["skeleton"]["parents"][1] = 5.into()), "does not come before it"),
        ("norm one short", Box::new(|v| drop(v["sparse_norm"]["std"].as_array_mut().unwrap().pop())), "sparse_norm.std"),
        ("std 0", Box::new(|v| v["dense_norm"]["std"][3] = 0.into()), "dense_norm.std[3]"),
        ("duplicate class", Box::new(|v| v["classes"][1] = v["classes"][0].clone()), "classes[1]"),
        ("class dropout 2", Box::new(|v| v["glogen"]["class_dropout"] = 2.into()), "glogen.class_dropout"),
    ];
    for (what, edit, field) in cases {
        let mut v = original.clone();
        edit(&mut v);
        std::fs::write(model.join("model.json"), serde_json::to_string_pretty(&v).unwrap()).unwrap();
        let e = format!("{:#}", GlocalModel::load(&model).err().unwrap_or_else(|| panic!("{what}: loaded")));
        assert!(e.contains("model.json") && e.contains(field), "{what}: {e}");
        assert_eq!(e.lines().count(), 1, "{what}: {e}");
    }
}

fn train_args<'a>(out: &'a str, steps: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let every = if steps == "100000" { "1000" } else { "2" };
    let mut a = vec!["train", "--dataset", "bandai", "--stage", "locgen", "--hidden", "8", "--batch", "2", "--eval-every", "1", "--checkpoint-every", every, "--steps", steps, "--out", out];
    a.extend_from_slice(extra);
    a
}

/// M3: a run stopped after its checkpoint committed but before the published weights and
/// model.json were replaced resumes to exactly the weights of a run never stopped. M6: a
/// Ctrl-C saves a checkpoint and exits cleanly. L13: a second run into the same folder is
/// refused. L14: a damaged checkpoint is named.
#[test]
fn m3_m6_l13_l14_checkpoints_resume_exactly_and_interrupts_save() {
    let t = tempfile::tempdir().unwrap();
    let (whole, part) = (t.path().join("whole"), t.path().join("part"));
    succeeds(&train_args(s(&whole), "6", &[]));
    succeeds(&train_args(s(&part), "2", &[]));
    let step2: Vec<(PathBuf, Vec<u8>)> =
        ["locgen.safetensors", "model.json"].iter().map(|f| (part.join(f), std::fs::read(part.join(f)).unwrap())).collect();
    succeeds(&train_args(s(&part), "4", &["--resume"]));
    // As if killed after step 4's checkpoint file was renamed in, before its copies were.
    for (path, bytes) in &step2 {
        std::fs::write(path, bytes).unwrap();
    }
    succeeds(&train_args(s(&part), "6", &["--resume"]));
    assert!(
        std::fs::read(whole.join("locgen.safetensors")).unwrap() == std::fs::read(part.join("locgen.safetensors")).unwrap(),
        "stopped and resumed training differs from an uninterrupted run"
    );
    let spec = ModelSpec::read_verified(&part).unwrap();
    assert_eq!(spec.training.locgen.unwrap().steps, 6);

    {
        let _held = FolderLock::acquire(&part).unwrap();
        refused(&train_args(s(&part), "8", &["--resume"]), &["in use by another glocal process"]);
    }

    let state = part.join("locgen.train.safetensors");
    let good = std::fs::read(&state).unwrap();
    std::fs::write(&state, &good[..good.len() / 2]).unwrap();
    refused(&train_args(s(&part), "8", &["--resume"]), &["locgen.train.safetensors"]);
    std::fs::write(&state, &good).unwrap();

    // Ctrl-C once a checkpoint exists: the run stops at a step, saved, with exit 130.
    let long = train_args(s(&part), "100000", &["--resume"]);
    let child = Command::new(BIN).args(&long).stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let written = std::fs::metadata(&state).unwrap().modified().unwrap();
    std::thread::sleep(std::time::Duration::from_secs(8));
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("checkpoint at step") && !stderr.contains("panicked"), "{stderr}");
    assert!(std::fs::metadata(&state).unwrap().modified().unwrap() > written, "no checkpoint saved on Ctrl-C");
    let steps = ModelSpec::read_verified(&part).unwrap().training.locgen.unwrap().steps;
    assert!(steps > 6, "Ctrl-C saved step {steps}");
    assert!(temp_files(&part).is_empty());
}

#[test]
fn l3_l4_l5_l6_l16_flags_out_of_range_are_refused() {
    let (t, model) = model_copy("bandai");
    let start = take(&model, t.path(), "start.bvh");
    let out = t.path().join("out.bvh");
    let init = format!("clip:{}@18446744073709551615", s(&start));
    refused(&["generate", "--model", s(&model), "--init", &init, "--timeline", "walk:3", "--out", s(&out)], &["start.bvh", "is past the file's"]);
    let fresh = t.path().join("fresh");
    for (flag, value) in [("--eval-every", "0"), ("--checkpoint-every", "0"), ("--batch", "0"), ("--stride", "0"), ("--hidden", "0"), ("--class-dropout", "nan"), ("--class-dropout", "2")] {
        let args = ["train", "--dataset", "bandai", "--stage", "glogen", "--steps", "5", "--out", s(&fresh), flag, value];
        refused(&args, &[flag]);
        assert!(!fresh.exists(), "{flag} {value} left a folder");
    }
    // GloGen's block options on a stage or variant that has no such blocks.
    let variants = [("locgen", &["--residual"][..]), ("locgen", &["--joined"]), ("locgen", &["--two-sided-join"]), ("glogen", &["--paper", "--joined"]), ("glogen", &["--paper", "--two-sided-join"])];
    for (stage, flags) in variants {
        let mut args = vec!["train", "--dataset", "bandai", "--stage", stage, "--steps", "5", "--out", s(&fresh)];
        args.extend(flags);
        refused(&args, &["--residual", "--joined", "--two-sided-join"]);
        assert!(!fresh.exists(), "{stage} {flags:?} left a folder");
    }
    let sheet = t.path().join("sheet.png");
    refused(&["render", "--in", s(&start), "--out", s(&sheet), "--columns", "1000", "--rows", "1000"], &["--columns"]);
    refused(&["render", "--in", s(&start), "--out", s(&sheet), "--columns", "26843546"], &["--columns"]);
    refused(&["generate", "--model", s(&model.join("model.json")), "--timeline", "walk:3", "--out", s(&out)], &["is a file", "model folder"]);
}

#[test]
fn l7_l8_l17_bad_files_say_what_is_wrong_in_a_line() {
    let (t, model) = model_copy("bandai");
    let npy = take(&model, t.path(), "start.npy");
    let mut bytes = std::fs::read(&npy).unwrap();
    let at = bytes.len() - 40;
    bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&npy, bytes).unwrap();
    let out = t.path().join("out.bvh");
    let init = format!("clip:{}@0", s(&npy));
    refused(&["generate", "--model", s(&model), "--init", &init, "--timeline", "walk:3", "--out", s(&out)], &["start.npy", "not finite"]);

    // 60 joints with 10 000-character names: the mismatch is summarised, names clipped.
    let name = "x".repeat(10_000);
    let mut bvh = String::from("HIERARCHY\n");
    for k in 0..60 {
        bvh += &format!("{} {name}{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n", if k == 0 { "ROOT" } else { "JOINT" });
    }
    bvh += "End Site\n{\nOFFSET 0 1 0\n}\n";
    bvh += &"}\n".repeat(60);
    bvh += &format!("MOTION\nFrames: 40\nFrame Time: 0.0333333\n{}", format!("{}\n", vec!["0"; 180].join(" ")).repeat(40));
    let wide = t.path().join("wide.bvh");
    std::fs::write(&wide, bvh).unwrap();
    let init = format!("clip:{}@0", s(&wide));
    let line = refused(&["generate", "--model", s(&model), "--init", &init, "--timeline", "walk:3", "--out", s(&out)], &["wide.bvh", "cannot map this skeleton", "60 in all"]);
    assert!(line.len() < 1000, "{} characters", line.len());

    let json = take(&model, t.path(), "take.json");
    let original: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let sheet = t.path().join("sheet.png");
    for (field, value, expected) in [("fps", Value::from(1e39), "fps"), ("fps", Value::from(0), "fps"), ("frames", Value::Array(vec![]), "no frames")] {
        let mut v = original.clone();
        v[field] = value;
        std::fs::write(&json, v.to_string()).unwrap();
        refused(&["render", "--in", s(&json), "--out", s(&sheet)], &["take.json", expected]);
    }
    assert!(!sheet.exists() && !out.exists());
}

#[test]
fn l9_l10_rounded_durations_are_noted_and_a_closed_pipe_is_no_panic() {
    let (t, model) = model_copy("h36m");
    let out = t.path().join("take.json");
    let run = succeeds(&["generate", "--model", s(&model), "--timeline", "walking:1@10", "--out", s(&out)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("note: segment 'walking' lasts 2.04 s, not 1 s"), "{stderr}");
    let mut child = Command::new(BIN)
        .args(["generate", "--model", s(&model), "--timeline", "walking:2", "--out", s(&out)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let done = child.wait_with_output().unwrap();
    assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
}

#[test]
fn l11_damaged_weights_fail_their_checksum_and_an_old_model_json_still_loads() {
    let (_t, model) = model_copy("bandai");
    let spec = ModelSpec::read(&model).unwrap();
    assert!(spec.training.weights_sha256.contains_key("glogen.safetensors"), "the shipped model carries its checksums");
    let weights = model.join("glogen.safetensors");
    let good = std::fs::read(&weights).unwrap();
    let mut flipped = good.clone();
    let n = flipped.len();
    for k in 0..2000 {
        flipped[n - 1 - k * 97 % (n / 2)] ^= 1;
    }
    std::fs::write(&weights, &flipped).unwrap();
    let e = format!("{:#}", GlocalModel::load(&model).err().unwrap());
    assert!(e.contains("glogen.safetensors") && e.contains("checksum"), "{e}");
    std::fs::write(&weights, &good).unwrap();
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(model.join("model.json")).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("weights_sha256");
    std::fs::write(model.join("model.json"), v.to_string()).unwrap();
    GlocalModel::load(&model).unwrap();
}

/// A seed bank with a value no f32 holds (read as infinity) or one beyond any pose is
/// refused at load, naming the file, the seed and the feature; it used to panic in a clamp.
#[test]
fn l11_a_seed_bank_with_a_non_finite_or_huge_value_is_refused_by_name() {
    let (t, model) = model_copy("bandai");
    let seeds_path = model.join("seeds.json");
    let good = std::fs::read_to_string(&seeds_path).unwrap();
    let out = t.path().join("out.bvh");
    for (bad, shown) in [("1e39", "inf"), ("-3e30", "-3e30")] {
        let mut v: Value = serde_json::from_str(&good).unwrap();
        v[2]["features"][5] = Value::Null;
        let text = v.to_string().replacen("null", bad, 1);
        std::fs::write(&seeds_path, text).unwrap();
        refused(&["generate", "--model", s(&model), "--timeline", "walk:3", "--out", s(&out)], &["seeds.json", "seed 2: feature 5 is", shown, "finite"]);
    }
}

/// A motion texture cut short, or of another model's skeleton, is refused at load naming the
/// file (it would otherwise index past a class's bank while finishing a take).
#[test]
fn l11_a_damaged_or_foreign_texture_is_refused_by_name() {
    let (t, model) = model_copy("all");
    let texture = model.join("texture.safetensors");
    let good = std::fs::read(&texture).unwrap();
    let out = t.path().join("out.bvh");
    std::fs::write(&texture, &good[..good.len() / 2]).unwrap();
    refused(&["generate", "--model", s(&model), "--timeline", "salsa:3", "--out", s(&out)], &["texture.safetensors", "not a safetensors file"]);
    let (_bandai_dir, bandai) = model_copy("bandai");
    std::fs::write(bandai.join("texture.safetensors"), &good).unwrap();
    refused(&["generate", "--model", s(&bandai), "--timeline", "walk:3", "--out", s(&out)], &["texture.safetensors", "the model's are"]);
    assert!(!out.exists());
}

/// A project file of a newer format is called that, whichever name its version field has
/// (`format_version`, as model.json spells it, was called a file with no version).
#[test]
fn l11_a_newer_project_file_says_it_is_newer() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("out.bvh");
    for field in ["version", "format_version"] {
        let project = t.path().join(format!("{field}.glocal.json"));
        std::fs::write(&project, format!(r#"{{"{field}": 99, "model": "models/h36m", "options": {{}}}}"#)).unwrap();
        refused(&["generate", "--project", s(&project), "--out", s(&out)], &[&format!("{field}.glocal.json is a version 99 project, made by a newer version of glocal")]);
    }
}

#[test]
fn l12_fifos_and_devices_are_not_read() {
    let (t, model) = model_copy("bandai");
    let fifo = t.path().join("fifo.bvh");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let zero = t.path().join("zero.bvh");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let out = t.path().join("out.bvh");
    for (file, name) in [(&fifo, "fifo.bvh"), (&zero, "zero.bvh")] {
        let init = format!("clip:{}@0", s(file));
        refused(&["generate", "--model", s(&model), "--init", &init, "--timeline", "walk:3", "--out", s(&out)], &[name, "not a regular file"]);
        refused(&["render", "--in", s(file), "--out", s(&t.path().join("sheet.png"))], &[name, "not a regular file"]);
    }
}

/// L2: a kill during a write leaves `.NAME.glocal-tmp-PID-N`; the next write of that file
/// removes it when its process is gone, and leaves a live writer's and anyone else's files.
#[test]
fn l2_stale_temp_files_of_ours_are_cleaned() {
    let t = tempfile::tempdir().unwrap();
    let target = t.path().join("take.json");
    let dead = t.path().join(".take.json.glocal-tmp-4000000000-0");
    let live = t.path().join(format!(".take.json.glocal-tmp-{}-99", std::process::id()));
    let other = t.path().join(".take.json.tmpAbC123");
    for f in [&dead, &live, &other] {
        std::fs::write(f, b"partial").unwrap();
    }
    write_atomic(&target, b"{}").unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"{}");
    assert!(!dead.exists() && live.exists() && other.exists());
}

/// Deterministic mutations of a real file: byte flips, extreme numbers in place of numbers,
/// lines dropped or repeated, truncation, random bytes.
fn mutants(original: &[u8], count: usize, seed: u64) -> Vec<Vec<u8>> {
    const NUMBERS: [&str; 10] = ["3e38", "-3e38", "1e39", "nan", "inf", "0", "-1", "1e30", "18446744073709551615", "1e-45"];
    let mut rng = StdRng::seed_from_u64(seed);
    let number_at = |bytes: &[u8], rng: &mut StdRng| -> Option<(usize, usize)> {
        let starts: Vec<usize> = (1..bytes.len()).filter(|&i| bytes[i].is_ascii_digit() && !bytes[i - 1].is_ascii_digit() && bytes[i - 1] != b'.').collect();
        let start = *starts.get(rng.random_range(0..starts.len().max(1)))?;
        let end = (start..bytes.len()).find(|&i| !(bytes[i].is_ascii_digit() || b".eE-+".contains(&bytes[i]))).unwrap_or(bytes.len());
        Some((start, end))
    };
    (0..count)
        .map(|_| {
            let mut m = original.to_vec();
            for _ in 0..rng.random_range(1..4) {
                let n = m.len().max(1);
                match rng.random_range(0..6) {
                    0 => {
                        let i = rng.random_range(0..n);
                        if let Some(b) = m.get_mut(i) {
                            *b ^= 1 << rng.random_range(0..8);
                        }
                    }
                    1 | 2 => {
                        if let Some((a, b)) = number_at(&m, &mut rng) {
                            let v = NUMBERS[rng.random_range(0..NUMBERS.len())];
                            m.splice(a..b, v.bytes());
                        }
                    }
                    3 => {
                        let lines: Vec<&[u8]> = m.split(|&b| b == b'\n').collect();
                        let k = rng.random_range(0..lines.len());
                        let repeat = rng.random_bool(0.5);
                        let mut out = Vec::with_capacity(m.len());
                        for (i, l) in lines.iter().enumerate() {
                            let times = if i != k { 1 } else if repeat { 2 } else { 0 };
                            for _ in 0..times {
                                out.extend_from_slice(l);
                                out.push(b'\n');
                            }
                        }
                        m = out;
                    }
                    4 => m.truncate(rng.random_range(0..n)),
                    _ => {
                        let at = rng.random_range(0..n);
                        let junk: Vec<u8> = (0..rng.random_range(1..16)).map(|_| rng.random()).collect();
                        m.splice(at.min(m.len())..at.min(m.len()), junk);
                    }
                }
            }
            m
        })
        .collect()
}

/// The seeded corpus that stands in for `cargo fuzz` in `cargo test`: every reader over
/// mutants of a real file never panics, and whatever it accepts is finite and consistent.
#[test]
fn readers_survive_a_fixed_corpus_of_mutated_real_files() {
    const PER_READER: usize = 150;
    let (t, model) = model_copy("bandai");
    let bvh = std::fs::read(take(&model, t.path(), "take.bvh")).unwrap();
    let npy = std::fs::read(take(&model, t.path(), "take.npy")).unwrap();
    let json = std::fs::read(take(&model, t.path(), "take.json")).unwrap();
    let model_json = std::fs::read(model.join("model.json")).unwrap();
    let project = Project::new(model.clone()).to_json().into_bytes();
    let root = DataRoot::resolve(None);
    let cmu = root.read_archive("cmu-expmap", |n| n.ends_with("walking/walking_1.txt") && n.contains("train")).unwrap();
    let skeleton_json = std::fs::read_to_string(root.file("cmu-expmap-skeleton.json")).unwrap();
    let expmap = ExpmapFormat::from_skeleton_json(&skeleton_json, "cmu-expmap-skeleton.json", RootEncoding::Absolute, 30.0, 0.001).unwrap();
    let spec = ModelSpec::read(&model).unwrap();

    let finite = |m: &glocal::motion::Motion| m.positions().iter().all(|p| p.is_finite());
    type Reader<'a> = Box<dyn Fn(&[u8]) -> bool + 'a>;
    let readers: Vec<(&str, &[u8], Reader)> = vec![
        ("bvh", &bvh, Box::new(|b| read_bvh(&String::from_utf8_lossy(b), "m.bvh").map_or(true, |m| finite(&m)))),
        (
            "npy",
            &npy,
            Box::new(|b| {
                let _ = read_npy(b, "m.npy");
                motion_from_npy(b, "m.npy", spec.layout.skeleton.clone(), spec.fps).map_or(true, |m| finite(&m))
            }),
        ),
        ("expmap", &cmu[0].1, Box::new(|b| expmap.read(&String::from_utf8_lossy(b), "m.txt").map_or(true, |m| finite(&m)))),
        (
            "json take",
            &json,
            Box::new(|b| parse_json_take(b, "m.json").map_or(true, |(m, segs)| finite(&m) && segs.iter().all(|s| s.end_frame <= m.frames()))),
        ),
        (
            "project",
            &project,
            Box::new(|b| Project::from_json(&String::from_utf8_lossy(b), "m.glocal").map_or(true, |p| p.options.timeline.segments.iter().all(|s| s.seconds > 0.0 && s.seconds.is_finite()))),
        ),
        ("model.json", &model_json, Box::new(|b| ModelSpec::from_json(&String::from_utf8_lossy(b), "model.json").map_or(true, |s| s.validate().is_ok()))),
    ];
    let mut failures = Vec::new();
    for (seed, (name, original, read)) in readers.iter().enumerate() {
        assert!(read(original), "{name}: the unmutated file does not read");
        for (k, m) in mutants(original, PER_READER, seed as u64).iter().enumerate() {
            match catch_unwind(AssertUnwindSafe(|| read(m))) {
                Ok(true) => {}
                Ok(false) => failures.push(format!("{name} mutant {k}: accepted with non-finite or inconsistent values")),
                Err(_) => failures.push(format!("{name} mutant {k}: panicked")),
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
