//! The command line's own choices, run as a user runs it: where it finds models, how a take
//! starts when not told, a project's model, and a walk at its own pace among others.

use std::path::Path;
use std::process::{Command, Output};

#[path = "support/models.rs"]
mod models;
use models::{model_copy, shipped_model};

const BIN: &str = env!("CARGO_BIN_EXE_glocal");

/// `glocal ARGS` run in `dir`.
fn glocal_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(BIN).current_dir(dir).args(args).output().unwrap()
}

fn ok(out: Output, what: &str) {
    assert!(out.status.success(), "{what}: {}", String::from_utf8_lossy(&out.stderr));
}

/// Without --init a take starts from its first activity's first seed window: `--timeline
/// walking:8` is the take of `--init seed:walking`, not of seed 0 (a directions window).
#[test]
fn a_take_starts_in_its_first_activity() {
    let dir = tempfile::tempdir().unwrap();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let takes: Vec<Vec<u8>> = [&[][..], &["--init", "seed:walking"][..], &["--init", "seed:0"][..]]
        .iter()
        .enumerate()
        .map(|(k, init)| {
            let out = dir.path().join(format!("take{k}.bvh"));
            let mut args = vec!["generate", "--model", "models/h36m", "--timeline", "walking:8", "--out", out.to_str().unwrap()];
            args.extend_from_slice(init);
            ok(glocal_in(crate_dir, &args), "generate");
            std::fs::read(out).unwrap()
        })
        .collect();
    assert_eq!(takes[0], takes[1], "the default start is not the first activity's seed window");
    assert_ne!(takes[0], takes[2], "seed 0 is a different start");
}

/// A take whose first segment asks for a style starts on a seed window of its activity in
/// that style, where the activity has one (from byebye's first window, an active wave,
/// byebye/happy waved at 2.0x its clips' speed over its first seconds; from a happy one,
/// 1.3x); the JSON take and the command's summary name each segment's style.
#[test]
fn a_styled_take_starts_in_its_style_and_its_segments_name_it() {
    let dir = tempfile::tempdir().unwrap();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let model = glocal::model::glocal::GlocalModel::load(&crate_dir.join("models/all")).unwrap();
    let (byebye, happy) = (model.spec.class_index("byebye").unwrap(), model.spec.styles.iter().position(|s| s == "happy").unwrap());
    let variant = model.class_seed_variant_in_style(byebye, happy).expect("a happy byebye window");
    assert_ne!(variant, 0, "byebye's first window is already happy: the test shows nothing");
    let window = model.seeds.iter().enumerate().filter(|(_, s)| s.class == byebye).nth(variant).unwrap().0;
    let generate = |name: &str, init: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec!["generate", "--model", "models/all", "--timeline", "byebye/happy:3,bow:2", "--json", "--out", out.to_str().unwrap()];
        args.extend_from_slice(init);
        let run = glocal_in(crate_dir, &args);
        assert!(run.status.success(), "generate: {}", String::from_utf8_lossy(&run.stderr));
        (std::fs::read(&out).unwrap(), String::from_utf8(run.stdout).unwrap())
    };
    let (default, summary) = generate("default.json", &[]);
    let seed = format!("seed:{window}");
    assert_eq!(default, generate("happy.json", &["--init", &seed]).0, "the default start is not byebye's first happy window");
    assert_ne!(default, generate("first.json", &["--init", "seed:byebye"]).0);
    let take: serde_json::Value = serde_json::from_slice(&default).unwrap();
    let summary: serde_json::Value = serde_json::from_str(summary.lines().last().unwrap()).unwrap();
    for segments in [&take["segments"], &summary["segments"]] {
        assert_eq!(segments[0]["style"], "happy", "{segments}");
        assert!(segments[1].get("style").is_none(), "bow asked for no style: {segments}");
    }
}

/// A file holding fewer frames than a start reads (here one pose, cut from an export) starts
/// a take: the take stands in that pose over the start's seconds and then moves (such a file
/// was refused: "0.04 s from frame 0 are too few: a start needs 2.00 s").
#[test]
fn a_single_pose_starts_a_take() {
    let dir = tempfile::tempdir().unwrap();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    ok(glocal_in(crate_dir, &["generate", "--model", "models/h36m", "--timeline", "phoning:3", "--init", "seed:phoning", "--out", &path("clip.bvh")]), "the clip");
    let clip = std::fs::read_to_string(path("clip.bvh")).unwrap();
    let (hierarchy, motion) = clip.split_once("MOTION").unwrap();
    let lines: Vec<&str> = motion.trim().lines().collect();
    std::fs::write(path("pose.bvh"), format!("{hierarchy}MOTION\nFrames: 1\n{}\n{}\n", lines[1], lines[2])).unwrap();
    ok(glocal_in(crate_dir, &["generate", "--model", "models/h36m", "--timeline", "walking:6", "--init", &format!("clip:{}@0", path("pose.bvh")), "--out", &path("take.json")]), "a take from one pose");
    let take: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path("take.json")).unwrap()).unwrap();
    let frames: Vec<Vec<[f32; 3]>> = serde_json::from_value(take["frames"].clone()).unwrap();
    let from_hips = |f: &[[f32; 3]]| f.iter().map(|p| [p[0] - f[0][0], p[1] - f[0][1], p[2] - f[0][2]]).collect::<Vec<_>>();
    let apart = |a: &[[f32; 3]], b: &[[f32; 3]]| from_hips(a).iter().zip(from_hips(b)).map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f32>().sqrt()).fold(0.0f32, f32::max);
    let held = (1..25).map(|t| apart(&frames[0], &frames[t])).fold(0.0f32, f32::max);
    let speed = |from: usize| frames[from..].windows(2).map(|w| w[1][0].iter().zip(&w[0][0]).map(|(a, b)| (a - b).powi(2)).sum::<f32>().sqrt()).sum::<f32>() * 25.0 / (frames.len() - from - 1) as f32;
    println!("one pose: held within {held:.5} m over the first second; the hips then travel at {:.2} m/s", speed(75));
    assert!(held < 1e-3, "the first second moves {held} m from the pose");
    assert!(speed(75) > 0.3, "the take does not walk after the pose: {} m/s", speed(75));
}

/// Outside the checkout, with no --model, the command line finds the shipped model the way
/// the studio does; and `--project` generates on the project's own model (a Bandai project
/// with Bandai's classes), not on h36m.
#[test]
fn models_are_found_and_a_project_brings_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("walk.bvh");
    ok(glocal_in(dir.path(), &["generate", "--timeline", "walking:4", "--out", out.to_str().unwrap()]), "generate with no --model outside the checkout");
    let bandai = shipped_model("bandai");
    let mut document = glocal::synth::project::Document::new(bandai);
    document.options.timeline = "walk:3,bow:2".parse().unwrap();
    let project = dir.path().join("scene.glocal");
    std::fs::write(&project, serde_json::to_string(&document).unwrap()).unwrap();
    let take = dir.path().join("scene.json");
    ok(glocal_in(dir.path(), &["generate", "--project", project.to_str().unwrap(), "--out", take.to_str().unwrap(), "--json"]), "a Bandai project");
    let text = std::fs::read_to_string(&take).unwrap();
    assert!(text.contains("\"bow\""), "the take is not Bandai's: {}", &text[..200.min(text.len())]);
}

/// The walking segment of a take in the JSON `glocal generate` wrote: the hips' mean height
/// over the floor and their speed over the ground (metres, m/s), leaving out the second of
/// transition at each end.
fn walking_hips(take: &Path) -> (f32, f32) {
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(take).unwrap()).unwrap();
    let (fps, mpu) = (json["fps"].as_f64().unwrap() as f32, json["meters_per_unit"].as_f64().unwrap() as f32);
    let walking = json["segments"].as_array().unwrap().iter().find(|s| s["name"] == "walking").unwrap();
    let second = fps as usize;
    let (a, b) = (walking["start_frame"].as_u64().unwrap() as usize + second, walking["end_frame"].as_u64().unwrap() as usize - second);
    let frames: Vec<Vec<[f32; 3]>> = serde_json::from_value(json["frames"].clone()).unwrap();
    let floor = frames[a..b].iter().flatten().map(|p| p[1]).fold(f32::INFINITY, f32::min);
    let height = frames[a..b].iter().map(|f| f[0][1] - floor).sum::<f32>() / (b - a) as f32 * mpu;
    let (from, to) = (frames[a][0], frames[b - 1][0]);
    let speed = (to[0] - from[0]).hypot(to[2] - from[2]) * mpu / ((b - 1 - a) as f32 / fps);
    (height, speed)
}

/// A walk at its own pace between two activities at another global pace walks, whatever the
/// global pace: its hips at standing height and its speed near a walk's at that pace. At
/// global pace 0.5 the eating segment's easing ran over the walk's only block and it stayed
/// seated (hips 0.71 m, 0.03 m/s).
#[test]
fn a_walk_at_its_own_pace_walks_whatever_the_global_pace() {
    let dir = tempfile::tempdir().unwrap();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let take = |timeline: &str, pace: &str, init: &str| {
        let out = dir.path().join(format!("{timeline}-{pace}.json").replace([':', ',', '@'], "_"));
        ok(glocal_in(crate_dir, &["generate", "--model", "models/h36m", "--timeline", timeline, "--pace", pace, "--init", init, "--out", out.to_str().unwrap()]), "generate");
        walking_hips(&out)
    };
    let (standing, walk_speed) = take("walking:6@2.0", "1.0", "seed:walking");
    eprintln!("a walk alone at pace 2: hips {standing:.3} m, {walk_speed:.2} m/s");
    for pace in ["0.5", "1.0", "2.0"] {
        let (height, speed) = take("eating:3,walking:6@2.0,sitting:3", pace, "seed:0");
        eprintln!("global pace {pace}: the walk's hips {height:.3} m, {speed:.2} m/s");
        assert!(height > 0.8 && height > standing - 0.05, "at global pace {pace} the walk's hips are at {height:.3} m (standing: {standing:.3})");
        assert!(speed > 0.6 * walk_speed, "at global pace {pace} the walk moves at {speed:.2} m/s (a walk alone: {walk_speed:.2})");
    }
}

/// `glocal calibrate --contrast` that is not CLASS=OTHER of two of the model's classes is one
/// line naming what is wrong, and the model folder is left as it was.
#[test]
fn a_wrong_contrast_is_refused_before_the_model_is_touched() {
    let (dir, model) = model_copy("all");
    let before = std::fs::read(model.join("model.json")).unwrap();
    for (contrast, says) in [("walk-left", "is not CLASS=OTHER"), ("walk-left=tango", "class_contrasts.walk-left"), ("walking=walking", "two different ones")] {
        let out = glocal_in(dir.path(), &["calibrate", "--model", model.to_str().unwrap(), "--contrast", contrast]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says) && err.lines().filter(|l| !l.trim().is_empty()).count() <= 2, "--contrast {contrast}: {err}");
    }
    assert_eq!(std::fs::read(model.join("model.json")).unwrap(), before, "model.json changed");
}

/// The shipped models' bones' turn limits, styles' speeds and seed windows' styles are what
/// the README's `glocal calibrate --clips-only` writes from the data: on a copy of the h36m
/// model and of `all` without them, model.json and seeds.json come out byte for byte the
/// shipped ones.
#[test]
fn the_shipped_figures_of_the_clips_come_from_the_readme_command() {
    for name in ["h36m", "all"] {
        let (dir, model) = model_copy(name);
        let shipped = shipped_model(name);
        let mut spec: serde_json::Value = serde_json::from_slice(&std::fs::read(model.join("model.json")).unwrap()).unwrap();
        for field in ["bone_turn_limits", "style_speed"] {
            spec.as_object_mut().unwrap().remove(field);
        }
        std::fs::write(model.join("model.json"), serde_json::to_vec_pretty(&spec).unwrap()).unwrap();
        // The seeds' styles cut out of the text, every feature's digits left as they are.
        let seeds = std::fs::read_to_string(model.join("seeds.json")).unwrap();
        let unstyled: String = seeds.split(",\"style\":").enumerate().map(|(k, piece)| if k == 0 { piece } else { piece.trim_start_matches(|c: char| c.is_ascii_digit()) }).collect();
        std::fs::write(model.join("seeds.json"), unstyled).unwrap();
        ok(glocal_in(dir.path(), &["calibrate", "--model", model.to_str().unwrap(), "--clips-only"]), "calibrate --clips-only");
        for file in ["model.json", "seeds.json"] {
            assert!(std::fs::read(model.join(file)).unwrap() == std::fs::read(shipped.join(file)).unwrap(), "{name}: {file} differs from the shipped one");
        }
    }
}

/// h36m's shares of its motion texture are what the README's `glocal calibrate --strengths
/// 1.5 --contrast phoning=eating` writes: on a copy without them, the same classes get the
/// same shares (within 0.02; the calibration generates takes, whose last digits may differ on
/// another processor) and nothing else in model.json changes, the guidance the model's one
/// and phoning steered from eating.
#[test]
fn the_shipped_texture_shares_come_from_the_readme_command() {
    let (dir, model) = model_copy("h36m");
    let read = |path: &Path| -> serde_json::Value { serde_json::from_slice(&std::fs::read(path.join("model.json")).unwrap()).unwrap() };
    let shipped = read(&shipped_model("h36m"));
    let mut spec = shipped.clone();
    spec.as_object_mut().unwrap().remove("texture_gains");
    std::fs::write(model.join("model.json"), serde_json::to_vec_pretty(&spec).unwrap()).unwrap();
    ok(glocal_in(dir.path(), &["calibrate", "--model", model.to_str().unwrap(), "--strengths", "1.5", "--contrast", "phoning=eating"]), "calibrate --strengths 1.5 --contrast phoning=eating");
    let mut written = read(&model);
    let shares = |spec: &mut serde_json::Value| -> Vec<(String, f64)> {
        let gains = spec.as_object_mut().unwrap().remove("texture_gains").expect("no texture_gains");
        gains.as_object().unwrap().iter().map(|(class, gain)| (class.clone(), gain.as_f64().unwrap())).collect()
    };
    let (made, expected) = (shares(&mut written), shares(&mut shipped.clone()));
    assert_eq!(made.iter().map(|(c, _)| c).collect::<Vec<_>>(), expected.iter().map(|(c, _)| c).collect::<Vec<_>>(), "other classes have shares");
    for ((class, a), (_, b)) in made.iter().zip(&expected) {
        assert!((a - b).abs() < 0.02, "{class}: share {a:.3}, shipped {b:.3}");
    }
    let mut rest = shipped;
    rest.as_object_mut().unwrap().remove("texture_gains");
    assert!(written == rest, "calibrate changed more of model.json than the texture shares");
}

/// `--no-texture` is a setting a project saves: a project on `all` asking no texture makes the
/// take the flag makes, and both differ from the textured take (a studio user who turned the
/// "Motion texture" box off and copied the command line gets the take they saw).
#[test]
fn a_project_without_texture_makes_the_no_texture_take() {
    let dir = tempfile::tempdir().unwrap();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut document = glocal::synth::project::Document::new(crate_dir.join("models/all"));
    document.options.timeline = "salsa:3".parse().unwrap();
    document.options.init = glocal::synth::InitPose::SeedClass { class: "salsa".into(), variant: 0 };
    document.options.texture = false;
    let project = dir.path().join("plain.glocal");
    std::fs::write(&project, serde_json::to_string(&document).unwrap()).unwrap();
    let take = |args: &[&str], name: &str| {
        let out = dir.path().join(name);
        let mut all = args.to_vec();
        all.extend(["--out", out.to_str().unwrap()]);
        ok(glocal_in(crate_dir, &all), name);
        std::fs::read(out).unwrap()
    };
    let from_project = take(&["generate", "--project", project.to_str().unwrap()], "project.npy");
    let flags = ["generate", "--model", "models/all", "--timeline", "salsa:3", "--init", "seed:salsa"];
    let plain = take(&[&flags[..], &["--no-texture"]].concat(), "plain.npy");
    let textured = take(&flags, "textured.npy");
    assert!(from_project == plain, "the project's take differs from --no-texture's");
    assert!(plain != textured, "--no-texture made the textured take");
}

/// A new user's first slips on `all` are answered in one line that says what was meant:
/// Bandai's "walk" is `walking` there, and FBX goes through Blender. Nothing is written.
#[test]
fn a_mistyped_class_and_an_fbx_say_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (timeline, file, says) in [
        ("walk:4,sitting down:3", "take.bvh", "unknown class 'walk' (did you mean 'walking'?)"),
        ("walking:4,sitting down:3", "take.bvh", "unknown class 'sitting down' (did you mean 'sittingdown'?)"),
        ("walking:4", "take.fbx", "export FBX from Blender"),
    ] {
        let out = dir.path().join(file);
        let run = glocal_in(crate_dir, &["generate", "--model", "models/all", "--timeline", timeline, "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success() && err.contains(says) && err.lines().filter(|l| !l.trim().is_empty()).count() == 1, "{timeline} -> {file}: {err}");
        assert!(!out.exists(), "{file} was written");
    }
}
