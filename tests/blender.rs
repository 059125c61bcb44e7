//! The Blender add-on (integrations/blender) driven in Blender itself, and `--joint-names
//! mixamo` exports read by Blender's importers: tests/blender/check_addon.py, run with the
//! Python that has Blender's `bpy` module (GLOCAL_BLENDER_PYTHON, else /tmp/bpy/bin/python;
//! `.ci/run` installs it). Without it the test fails and says how to install it.

use std::path::{Path, PathBuf};
use std::process::Command;

const TIMELINE: &str = "walking:4,sitting:3";
const SEED: &str = "2";
const INSTALL: &str = "python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy==4.2.0";

fn crate_path(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// The Python with `bpy`; panics with the install command when it is missing.
fn blender_python() -> PathBuf {
    let python = std::env::var_os("GLOCAL_BLENDER_PYTHON").map_or_else(|| PathBuf::from("/tmp/bpy/bin/python"), PathBuf::from);
    let probe = Command::new(&python).args(["-c", "import bpy"]).output();
    match probe {
        Ok(out) if out.status.success() => python,
        _ => panic!("Blender's bpy module is needed at {} (GLOCAL_BLENDER_PYTHON names another Python): {INSTALL}", python.display()),
    }
}

/// `glocal generate` of the test's take with Mixamo names into `out`.
fn generate_mixamo(out: &Path) {
    let status = Command::new(env!("CARGO_BIN_EXE_glocal"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["generate", "--model", "models/h36m", "--timeline", TIMELINE, "--seed", SEED, "--joint-names", "mixamo", "--out"])
        .arg(out)
        .output()
        .expect("glocal runs");
    assert!(status.status.success(), "glocal generate --out {}: {}", out.display(), String::from_utf8_lossy(&status.stderr));
}

#[test]
fn addon_generates_onto_rigify_and_mixamo_rigs_and_mixamo_names_import() {
    let python = blender_python();
    let dir = tempfile::tempdir().unwrap();
    let [json, bvh, glb] = ["json", "bvh", "glb"].map(|ext| dir.path().join(format!("take.{ext}")));
    for file in [&json, &bvh, &glb] {
        generate_mixamo(file);
    }
    khronos_validator(&glb);
    let out = Command::new(python)
        .arg(crate_path("tests/blender/check_addon.py"))
        .arg(env!("CARGO_BIN_EXE_glocal"))
        .arg(crate_path("models/h36m"))
        .args([TIMELINE, SEED])
        .args([&json, &bvh, &glb])
        .arg(dir.path())
        // The add-on is installed into a scratch user folder, not the user's own Blender.
        .env("BLENDER_USER_SCRIPTS", dir.path().join("scripts"))
        .env("BLENDER_USER_CONFIG", dir.path().join("config"))
        .output()
        .expect("the Blender Python runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let report: Vec<&str> = stdout.lines().filter(|l| l.starts_with("rigify") || l.starts_with("mixamo") || l.starts_with("styles") || l.contains("FAIL") || l.contains(".bvh:") || l.contains(".glb:")).collect();
    println!("{}", report.join("\n"));
    assert!(out.status.success(), "tests/blender/check_addon.py failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
}

/// The Khronos validator on the Mixamo-named .glb (tests/gltf/validate.cjs), when installed
/// (GLTF_VALIDATOR_MODULES, as tests/gltf.rs).
fn khronos_validator(glb: &Path) {
    let Some(modules) = std::env::var_os("GLTF_VALIDATOR_MODULES") else {
        println!("validator skipped: GLTF_VALIDATOR_MODULES is not set (see tests/gltf/validate.cjs)");
        return;
    };
    let out = Command::new("node").arg(crate_path("tests/gltf/validate.cjs")).arg(glb).env("NODE_PATH", modules).output().expect("node runs");
    let report = String::from_utf8_lossy(&out.stdout);
    println!("{report}");
    assert!(out.status.success() && report.contains(" 0 errors, 0 warnings"), "the validator on the Mixamo-named glb:\n{report}");
}

/// `--root-motion in-place` and `root-bone` exports, and a take of the model of everything,
/// read by Blender's BVH and glTF importers, every joint where the same take's JSON export puts
/// it (tests/blender/check_*_import.py), and the glTF valid.
#[test]
fn root_motion_exports_import_in_blender() {
    let python = blender_python();
    let dir = tempfile::tempdir().unwrap();
    let mut pairs = [Vec::new(), Vec::new()];
    // (name, model, its arguments): h36m's walk in both root-motion modes, and a take of the
    // model of everything, on its standard humanoid, across datasets and in a style.
    let cases: [(&str, &str, &[&str]); 3] = [
        ("in-place", "models/h36m", &["--timeline", "walking:4", "--init", "seed:walking", "--root-motion", "in-place"]),
        ("root-bone", "models/h36m", &["--timeline", "walking:4", "--init", "seed:walking", "--root-motion", "root-bone"]),
        ("all", "models/all", &["--timeline", "walking/happy:2,salsa:2"]),
    ];
    for (mode, model, args) in cases {
        for ext in ["json", "bvh", "glb"] {
            let out = dir.path().join(format!("{mode}.{ext}"));
            let run = Command::new(env!("CARGO_BIN_EXE_glocal"))
                .current_dir(env!("CARGO_MANIFEST_DIR"))
                .args(["generate", "--model", model])
                .args(args)
                .arg("--out")
                .arg(&out)
                .output()
                .expect("glocal runs");
            assert!(run.status.success(), "{mode} --out {}: {}", out.display(), String::from_utf8_lossy(&run.stderr));
        }
        khronos_validator(&dir.path().join(format!("{mode}.glb")));
        for (k, ext) in ["bvh", "glb"].iter().enumerate() {
            pairs[k].push(dir.path().join(format!("{mode}.{ext}")));
            pairs[k].push(dir.path().join(format!("{mode}.json")));
        }
    }
    for (script, files) in ["tests/blender/check_bvh_import.py", "tests/blender/check_gltf_import.py"].iter().zip(&pairs) {
        let out = Command::new(&python).arg(crate_path(script)).args(files).output().expect("the Blender Python runs");
        let stdout = String::from_utf8_lossy(&out.stdout);
        println!("{script}:\n{stdout}");
        assert!(out.status.success(), "{script} failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    }
}
