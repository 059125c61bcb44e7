//! The command line's own choices, run as a user runs it: where it finds models, how a take
//! starts when not told, and a project's model.

use std::path::Path;
use std::process::{Command, Output};

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

/// Outside the checkout, with no --model, the command line finds the shipped model the way
/// the studio does; and `--project` generates on the project's own model (a Bandai project
/// with Bandai's classes), not on h36m.
#[test]
fn models_are_found_and_a_project_brings_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("walk.bvh");
    ok(glocal_in(dir.path(), &["generate", "--timeline", "walking:4", "--out", out.to_str().unwrap()]), "generate with no --model outside the checkout");
    let bandai = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/bandai");
    let mut document = glocal::synth::project::Document::new(bandai);
    document.options.timeline = "walk:3,bow:2".parse().unwrap();
    let project = dir.path().join("scene.glocal");
    std::fs::write(&project, serde_json::to_string(&document).unwrap()).unwrap();
    let take = dir.path().join("scene.json");
    ok(glocal_in(dir.path(), &["generate", "--project", project.to_str().unwrap(), "--out", take.to_str().unwrap(), "--json"]), "a Bandai project");
    let text = std::fs::read_to_string(&take).unwrap();
    assert!(text.contains("\"bow\""), "the take is not Bandai's: {}", &text[..200.min(text.len())]);
}
