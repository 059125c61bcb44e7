//! glTF export read back with the `gltf` crate: the skin's joints, a skinned mesh, the
//! animation's frame count and rate, and every joint's position in every frame (forward
//! kinematics of the node hierarchy under the animation) against the same take's JSON export,
//! within 1% of the body's height, on the floor, in metres. The Khronos validator runs too
//! when it is installed (GLTF_VALIDATOR_MODULES).

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

use glam::{Quat, Vec3};
use glocal::model::glocal::GlocalModel;
use glocal::synth::export::{export, read_take};
use glocal::synth::rig::onto_skeleton_file;
use glocal::synth::{generate, GenerateOptions, Generated};

fn take(name: &str) -> (Generated, f32) {
    let m = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap();
    let timeline = format!("{}:2,{}:2", m.spec.classes[0], m.spec.classes[2]);
    let take = generate(&m, &GenerateOptions { timeline: timeline.parse().unwrap(), ..Default::default() }, &mut |_| true).unwrap();
    let unit = take.motion.skeleton.meters_per_unit();
    (take, unit)
}

/// Per joint name, per frame, the world position the .glb's animation puts the joint at.
struct Animated {
    joints: Vec<String>,
    times: Vec<f32>,
    positions: HashMap<String, Vec<Vec3>>,
    skinned_vertices: usize,
}

fn read_glb(bytes: &[u8]) -> Animated {
    let glb = gltf::Gltf::from_slice(bytes).expect("a valid glTF binary");
    let blob = glb.blob.as_deref().expect("a binary chunk");
    let doc = &glb.document;
    let skin = doc.skins().next().expect("a skin");
    let joints: Vec<String> = skin.joints().map(|n| n.name().unwrap_or("").to_string()).collect();
    let mesh_node = doc.nodes().find(|n| n.skin().is_some()).expect("a skinned mesh node");
    let primitive = mesh_node.mesh().expect("a mesh").primitives().next().expect("a primitive");
    let reader = primitive.reader(|_| Some(blob));
    let skinned_vertices = reader.read_joints(0).expect("JOINTS_0").into_u16().count();
    assert_eq!(reader.read_weights(0).expect("WEIGHTS_0").into_f32().count(), skinned_vertices);
    assert_eq!(skin.reader(|_| Some(blob)).read_inverse_bind_matrices().expect("inverse bind matrices").count(), joints.len());

    let animation = doc.animations().next().expect("an animation");
    let mut times = Vec::new();
    let mut rotations: HashMap<usize, Vec<Quat>> = HashMap::new();
    let mut translations: HashMap<usize, Vec<Vec3>> = HashMap::new();
    for channel in animation.channels() {
        let r = channel.reader(|_| Some(blob));
        times = r.read_inputs().expect("times").collect();
        let node = channel.target().node().index();
        match r.read_outputs().expect("outputs") {
            gltf::animation::util::ReadOutputs::Rotations(q) => {
                rotations.insert(node, q.into_f32().map(Quat::from_array).collect());
            }
            gltf::animation::util::ReadOutputs::Translations(t) => {
                translations.insert(node, t.map(Vec3::from_array).collect());
            }
            _ => panic!("unexpected channel on node {node}: only rotations and translations are written"),
        }
    }
    let mut positions: HashMap<String, Vec<Vec3>> = HashMap::new();
    for frame in 0..times.len() {
        let mut stack: Vec<(gltf::Node, Vec3, Quat)> = doc.scenes().next().unwrap().nodes().map(|n| (n, Vec3::ZERO, Quat::IDENTITY)).collect();
        while let Some((node, parent_at, parent_rot)) = stack.pop() {
            let (t, r, _) = node.transform().decomposed();
            let t = translations.get(&node.index()).map_or(Vec3::from_array(t), |v| v[frame]);
            let r = rotations.get(&node.index()).map_or(Quat::from_array(r), |v| v[frame]);
            let (at, rot) = (parent_at + parent_rot * t, parent_rot * r);
            if let Some(name) = node.name() {
                positions.entry(name.to_string()).or_default().push(at);
            }
            stack.extend(node.children().map(|c| (c, at, rot)));
        }
    }
    Animated { joints, times, positions, skinned_vertices }
}

fn check_against_json(glb: &Path, json: &Path, what: &str) -> f32 {
    let (motion, _) = read_take(json, None).unwrap();
    let unit = motion.skeleton.meters_per_unit();
    let got = read_glb(&std::fs::read(glb).unwrap());
    assert_eq!(got.joints, motion.skeleton.names(), "{what}: skin joints");
    assert!(got.skinned_vertices > 100 * motion.joints() / 2, "{what}: {} mesh vertices", got.skinned_vertices);
    assert_eq!(got.times.len(), motion.frames(), "{what}: frame count");
    let step = got.times[1] - got.times[0];
    assert!((step - 1.0 / motion.fps).abs() < 1e-6, "{what}: {step} s per frame at {} fps", motion.fps);
    assert!((got.times.last().unwrap() - (motion.frames() - 1) as f32 / motion.fps).abs() < 1e-4);
    let height = (0..motion.frames())
        .map(|t| {
            let ys = motion.frame(t).iter().map(|p| p.y);
            ys.clone().fold(f32::NEG_INFINITY, f32::max) - ys.fold(f32::INFINITY, f32::min)
        })
        .fold(0.0, f32::max)
        * unit;
    let (mut worst, mut lowest) = (0.0f32, f32::INFINITY);
    for (j, name) in motion.skeleton.names().iter().enumerate() {
        for (t, p) in got.positions[name].iter().enumerate() {
            worst = worst.max(p.distance(motion.frame(t)[j] * unit));
            lowest = lowest.min(p.y);
        }
    }
    println!("{what}: {} joints, {} frames at {} fps, {} skinned vertices; largest joint difference {:.3} mm ({:.4}% of {height:.2} m), lowest joint {:.3} mm", motion.joints(), motion.frames(), motion.fps, got.skinned_vertices, worst * 1e3, 100.0 * worst / height, lowest * 1e3);
    assert!(worst < 0.01 * height, "{what}: joints up to {worst} m from the JSON export");
    assert!(lowest.abs() < 0.01 * height, "{what}: lowest joint at {lowest} m, not on the floor");
    height
}

/// Both shipped models' takes, and a take moved onto the CMU skeleton (43 joints, centimetres).
#[test]
fn glb_matches_the_json_export() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["h36m", "bandai", "all"] {
        let (take, unit) = take(name);
        let (glb, json) = (dir.path().join(format!("{name}.glb")), dir.path().join(format!("{name}.json")));
        export(&take.motion, &take.segments, &glb).unwrap();
        export(&take.motion, &take.segments, &json).unwrap();
        let height = check_against_json(&glb, &json, name);
        assert!((1.2..2.2).contains(&height), "{name}: a {height} m body is not in metres (unit {unit})");
        if name == "h36m" {
            let entries = glocal::data::archive::DataRoot::resolve(None).read_archive("cmu-dance", |p| p == "cmu-dance/standard.bvh").unwrap();
            let rig = dir.path().join("standard.bvh");
            std::fs::write(&rig, &entries[0].1).unwrap();
            let on_cmu = onto_skeleton_file(&take.motion, &rig, None).unwrap();
            let (glb, json) = (dir.path().join("cmu.glb"), dir.path().join("cmu.json"));
            export(&on_cmu, &take.segments, &glb).unwrap();
            export(&on_cmu, &take.segments, &json).unwrap();
            check_against_json(&glb, &json, "h36m on the CMU skeleton");
        }
    }
}

/// The Khronos validator, when installed (`npm install --prefix DIR gltf-validator`, then
/// GLTF_VALIDATOR_MODULES=DIR/node_modules): no errors and no warnings on either model's take.
#[test]
fn khronos_validator_reports_no_errors() {
    let Some(modules) = std::env::var_os("GLTF_VALIDATOR_MODULES") else {
        println!("skipped: GLTF_VALIDATOR_MODULES is not set (see tests/gltf/validate.cjs)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for name in ["h36m", "bandai", "all"] {
        let (take, _) = take(name);
        let glb = dir.path().join(format!("{name}.glb"));
        export(&take.motion, &take.segments, &glb).unwrap();
        files.push(glb);
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf/validate.cjs");
    let out = Command::new("node").arg(script).args(&files).env("NODE_PATH", modules).output().expect("node runs");
    let report = String::from_utf8_lossy(&out.stdout);
    println!("{report}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the validator found errors:\n{report}");
    assert!(report.lines().filter(|l| l.ends_with(')')).all(|l| l.contains(" 0 errors, 0 warnings")), "{report}");
}
