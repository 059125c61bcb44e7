//! Retargeting with real files: BVH files of four other conventions (CMU dance's acLSTM
//! names with fingers, a Mixamo-named A-pose rig written from a Bandai clip, the CMU
//! database's ASF names on its own skeleton, and Unreal mannequin names on an A-pose rig as
//! Blender's own exporter writes it) start takes on both shipped models with the
//! source's pose; a take written onto the CMU skeleton reads back with its bones, frames and
//! rate; a skeleton that cannot be mapped is refused in one line naming what is missing.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Quat, Vec3};
use glocal::data::archive::DataRoot;
use glocal::data::bvh::{read_bvh, write_bvh};
use glocal::data::joint_map::{key_joints, UserJointMap};
use glocal::data::registry::{expmap_format, Dataset};
use glocal::model::glocal::GlocalModel;
use glocal::motion::{mapped_bones, mean_bone_angle, solve_local_poses, Key, KeyJoints, Motion, RestPose, Skeleton};
use glocal::synth::export::export;
use glocal::synth::own_start::with_own_start;
use glocal::synth::rig::{onto_model, onto_skeleton_file};
use glocal::synth::{generate, GenerateOptions, InitPose};

fn model(name: &str) -> GlocalModel {
    GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

/// One file of a dataset archive, as text.
fn archive_text(dataset: &str, path: &str) -> String {
    let entries = DataRoot::resolve(None).read_archive(dataset, |p| p == path).unwrap_or_else(|e| panic!("{dataset}: {e:#}"));
    let (_, bytes) = entries.into_iter().next().unwrap_or_else(|| panic!("{dataset} has no {path}"));
    String::from_utf8(bytes).expect("text")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A CMU dance clip as the archive has it: acLSTM's names (hip, lShldr, rShin, ...), 43 joints
/// with fingers, a T-pose rest.
fn cmu_dance(dir: &Path) -> PathBuf {
    write(dir, "cmu-salsa.bvh", &archive_text("cmu-dance", "cmu-dance/salsa/01.bvh"))
}

/// A CMU dance clip whose first frame is a reference pose 11 units (centimetres, read as the
/// file's) from where the capture starts: its size, not Bandai's root joint placed 4.5 m from
/// the hips, sets its unit (read as decimetres, the root moved at 138 m/s and was refused).
fn cmu_dance_with_reference_frame(dir: &Path) -> PathBuf {
    write(dir, "cmu-indian.bvh", &archive_text("cmu-dance", "cmu-dance/indian/04.bvh"))
}

const MIXAMO_NAMES: [(&str, &str); 21] = [
    ("Hips", "Hips"),
    ("Spine", "Spine"),
    ("Chest", "Spine2"),
    ("Neck", "Neck"),
    ("Head", "Head"),
    ("Shoulder_L", "LeftShoulder"),
    ("UpperArm_L", "LeftArm"),
    ("LowerArm_L", "LeftForeArm"),
    ("Hand_L", "LeftHand"),
    ("Shoulder_R", "RightShoulder"),
    ("UpperArm_R", "RightArm"),
    ("LowerArm_R", "RightForeArm"),
    ("Hand_R", "RightHand"),
    ("UpperLeg_L", "LeftUpLeg"),
    ("LowerLeg_L", "LeftLeg"),
    ("Foot_L", "LeftFoot"),
    ("Toes_L", "LeftToeBase"),
    ("UpperLeg_R", "RightUpLeg"),
    ("LowerLeg_R", "RightLeg"),
    ("Foot_R", "RightFoot"),
    ("Toes_R", "RightToeBase"),
];

/// A Bandai clip rewritten as a Mixamo rig would export it: `mixamorig:` names, no placement
/// handle above the hips, and a standing A-pose rest (arms 45 degrees down, facing +z) instead
/// of Bandai's; the world motion is the clip's, its rotations solved against the new rest.
fn mixamo_from_bandai(dir: &Path, renamed: &[(&str, &str)]) -> PathBuf {
    mixamo_from_bandai_in(dir, renamed, CENTIMETRE)
}

const CENTIMETRE: f32 = 0.01;
const INCH: f32 = 0.0254;

/// [`mixamo_from_bandai`] written in `unit` (metres per unit; Bandai's is the centimetre).
fn mixamo_from_bandai_in(dir: &Path, renamed: &[(&str, &str)], unit: f32) -> PathBuf {
    let mut clip = read_bvh(&archive_text("bandai", "bandai/data/dataset-1_dance-short_normal_001.bvh"), "bandai dance").unwrap();
    let scale = CENTIMETRE / unit;
    let s = &clip.skeleton;
    let scaled = Skeleton::new(s.names().to_vec(), s.parents().to_vec(), s.offsets().iter().map(|o| *o * scale).collect(), unit).unwrap();
    clip = Motion::from_positions(Arc::new(scaled), clip.fps, clip.positions().iter().map(|p| *p * scale).collect());
    let keep: Vec<usize> = (1..clip.joints()).collect();
    let on_hips = clip.subset(&keep);
    let s = &on_hips.skeleton;
    let lengths = s.rest_bone_lengths();
    let a_pose = |name: &str| -> Vec3 {
        let side = if name.ends_with("_L") { 1.0 } else { -1.0 };
        let arm = Vec3::new(side, -1.0, 0.0).normalize();
        match name {
            "Spine" | "Chest" | "Neck" | "Head" => Vec3::Y,
            // Each offset is the bone that ends at the joint: chest to collar, the collarbone,
            // the upper arm, the forearm.
            _ if name.starts_with("Shoulder") => Vec3::new(0.35 * side, 1.0, 0.0).normalize(),
            _ if name.starts_with("UpperArm") => Vec3::new(side, 0.0, 0.0),
            _ if name.starts_with("LowerArm") || name.starts_with("Hand") => arm,
            _ if name.starts_with("UpperLeg") => Vec3::new(side, -0.4, 0.0).normalize(),
            _ if name.starts_with("Toes") => Vec3::Z,
            _ => Vec3::NEG_Y,
        }
    };
    let names = s.names().iter().map(|n| {
        let to = renamed.iter().find(|(from, _)| from == n).map_or(n.as_str(), |(_, to)| to);
        format!("mixamorig:{to}")
    });
    let offsets = s.names().iter().zip(&lengths).enumerate().map(|(j, (n, l))| if j == 0 { s.offsets()[0] } else { a_pose(n) * *l });
    let rig = Arc::new(Skeleton::new(names.collect(), s.parents().to_vec(), offsets.collect(), unit).unwrap());
    let poses = solve_local_poses(&rig, on_hips.positions());
    let text = write_bvh(&Motion::from_local_poses(rig, on_hips.fps, poses), None);
    write(dir, &format!("mixamo-dance-{}mm.bvh", unit * 1000.0), &text)
}

/// The CMU database's own skeleton (the motion-prediction set's exponential maps, 38 joints)
/// with the ASF names of the database (lfemur, ltibia, lhumerus, lradius, ...), as BVH.
fn cmu_asf(dir: &Path) -> PathBuf {
    const ASF: [&str; 38] = [
        "root", "lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes", "ltoes_end", "rhipjoint", "rfemur", "rtibia", "rfoot", "rtoes",
        "rtoes_end", "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head", "head_end", "lclavicle", "lhumerus",
        "lradius", "lwrist", "lhand", "lfingers", "lfingers_end", "lthumb", "lthumb_end", "rclavicle", "rhumerus", "rradius",
        "rwrist", "rhand", "rfingers", "rfingers_end", "rthumb", "rthumb_end",
    ];
    let format = expmap_format(Dataset::CmuExpmap, &DataRoot::resolve(None)).unwrap();
    let path = "cmu-expmap/test/soccer/soccer_1.txt";
    let mut motion = format.read(&archive_text("cmu-expmap", path), path).unwrap();
    let s = &motion.skeleton;
    assert_eq!(s.len(), ASF.len());
    let named = Skeleton::new(ASF.map(String::from).to_vec(), s.parents().to_vec(), s.offsets().to_vec(), s.meters_per_unit()).unwrap();
    motion.skeleton = Arc::new(named);
    write(dir, "cmu-asf-soccer.bvh", &write_bvh(&motion, None))
}

/// A CMU salsa clip written by Blender's own BVH exporter (not ours) onto a rig with Unreal
/// mannequin names (pelvis, spine_01, upperarm_l, calf_l, ball_l, ...), an unanimated `root`
/// on the floor, an A-pose rest, position channels on every joint, 60 fps
/// (tests/blender/make_foreign_bvh.py; tests/assets/README.md).
fn blender_unreal() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/assets/blender-unreal-salsa.bvh")
}

fn keys_of(skeleton: &Skeleton) -> KeyJoints {
    key_joints(skeleton, None, "test").unwrap_or_else(|e| panic!("{e:#}"))
}

/// Mean angle in degrees between corresponding bones of two poses, after turning `b` about the
/// vertical to face the way `a` does (a take starts facing the model's own way).
fn facing_bone_angle(bones: &[(Key, Key)], a: &[Vec3], ak: &KeyJoints, b: &[Vec3], bk: &KeyJoints) -> f32 {
    let mean_at = |yaw: f32| -> f32 {
        let turn = Quat::from_rotation_y(yaw);
        let turned: Vec<Vec3> = b.iter().map(|p| turn * *p).collect();
        mean_bone_angle(bones, a, ak, &turned, bk)
    };
    (0..720).map(|k| mean_at((k as f32 * 0.5).to_radians())).fold(f32::INFINITY, f32::min)
}

/// Each source starts a take on each model, and the take's first pose has the source's
/// pose at that moment (the frame the first sparse pose is taken from, a sparse step after
/// the file's own start frame).
#[test]
fn foreign_bvh_files_start_takes_on_both_models() {
    let dir = tempfile::tempdir().unwrap();
    let sources = [(cmu_dance(dir.path()), 200), (cmu_dance_with_reference_frame(dir.path()), 200), (mixamo_from_bandai(dir.path(), &MIXAMO_NAMES), 100), (cmu_asf(dir.path()), 30), (blender_unreal(), 20)];
    for name in ["h36m", "bandai", "all"] {
        let m = model(name);
        let target = m.spec.layout.skeleton.clone();
        let tk = keys_of(&target);
        for (path, frame) in &sources {
            let file = path.file_name().unwrap().to_string_lossy().into_owned();
            let source = read_bvh(&std::fs::read_to_string(path).unwrap(), &file).unwrap();
            let sk = keys_of(&source.skeleton);
            let o = GenerateOptions { timeline: format!("{}:4", m.spec.classes[0]).parse().unwrap(), init: InitPose::file(path.clone(), *frame), ..Default::default() };
            let take = generate(&m, &o, &mut |_| true).unwrap_or_else(|e| panic!("{file} on {name}: {e:#}"));
            let at_start = source.resample(m.spec.fps);
            let bones = mapped_bones(&tk, &target, &sk, &source.skeleton);
            assert!(bones.len() >= 14, "{file} on {name}: only {} mapped bones", bones.len());
            // `@frame` is the file's own frame; the take's first pose is a sparse step after it.
            let at = (*frame as f32 * m.spec.fps / source.fps).round() as usize;
            let angle = facing_bone_angle(&bones, at_start.frame(at + m.spec.stride), &sk, take.motion.frame(0), &tk);
            println!("{file} ({} joints, rest {}) -> {name}: {} bones, first pose {angle:.1} degrees from the source's", source.joints(), RestPose::detect(&source.skeleton, &sk).describe(), bones.len());
            assert!(angle < 10.0, "{file} on {name}: bones {angle} degrees from the source's");
        }
    }
}

/// A BVH says nothing of its unit: the same rig written in inches (as 3ds Max writes) starts
/// the same take as in centimetres on every model. Read by powers of ten alone, the inch
/// file was taken in the model's own unit, 39 times too big on `models/all`, which refused it
/// as damaged.
#[test]
fn a_rig_in_inches_starts_the_take_it_starts_in_centimetres() {
    let dir = tempfile::tempdir().unwrap();
    let files = [CENTIMETRE, INCH].map(|unit| mixamo_from_bandai_in(dir.path(), &MIXAMO_NAMES, unit));
    for name in ["h36m", "bandai", "all"] {
        let m = model(name);
        let takes = files.clone().map(|path| {
            let o = GenerateOptions { timeline: format!("{}:2", m.spec.classes[0]).parse().unwrap(), init: InitPose::file(path.clone(), 100), ..Default::default() };
            generate(&m, &o, &mut |_| true).unwrap_or_else(|e| panic!("{} on {name}: {e:#}", path.display())).motion
        });
        let apart = takes[0].positions().iter().zip(takes[1].positions()).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
        let millimetres = apart * m.spec.layout.skeleton.meters_per_unit() * 1000.0;
        assert!(millimetres < 1.0, "on {name} the takes from centimetres and inches are {millimetres} mm apart");
    }
}

#[test]
fn rest_poses_of_the_conventions_are_detected() {
    let dir = tempfile::tempdir().unwrap();
    let rest = |path: PathBuf| {
        let m = read_bvh(&std::fs::read_to_string(&path).unwrap(), "rest").unwrap();
        RestPose::detect(&m.skeleton, &keys_of(&m.skeleton))
    };
    assert_eq!(rest(cmu_dance(dir.path())), RestPose::TPose);
    assert_eq!(rest(mixamo_from_bandai(dir.path(), &MIXAMO_NAMES)), RestPose::APose);
    assert_eq!(rest(blender_unreal()), RestPose::APose);
    let bandai = model("bandai").spec.layout.skeleton;
    assert_eq!(RestPose::detect(&bandai, &keys_of(&bandai)), RestPose::Other, "Bandai's rest is not a standing pose");
}

/// A generated take written onto the CMU dance skeleton (its hierarchy and T-pose rest) and
/// read back: same frames and rate, the mapped bones pointing where the take's do.
#[test]
fn a_take_retargeted_onto_the_cmu_skeleton_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let rig = write(dir.path(), "standard.bvh", &archive_text("cmu-dance", "cmu-dance/standard.bvh"));
    for name in ["h36m", "bandai", "all"] {
        let m = model(name);
        let timeline = format!("{}:3,{}:3", m.spec.classes[0], m.spec.classes[1]);
        let take = generate(&m, &GenerateOptions { timeline: timeline.parse().unwrap(), ..Default::default() }, &mut |_| true).unwrap();
        let out = dir.path().join(format!("{name}-on-cmu.bvh"));
        export(&onto_skeleton_file(&take.motion, &rig, None).unwrap(), &take.segments, &out).unwrap();
        let back = read_bvh(&std::fs::read_to_string(&out).unwrap(), "back").unwrap();
        let cmu = read_bvh(&std::fs::read_to_string(&rig).unwrap(), "rig").unwrap();
        assert_eq!(back.skeleton.names(), cmu.skeleton.names(), "{name}: the CMU hierarchy");
        assert_eq!(back.skeleton.parents(), cmu.skeleton.parents());
        assert!(back.skeleton.offsets().iter().zip(cmu.skeleton.offsets()).all(|(a, b)| a.distance(*b) < 1e-4), "{name}: the CMU rest pose");
        assert_eq!((back.frames(), back.fps), (take.motion.frames(), take.motion.fps), "{name}: frames and rate");
        let (tk, ck) = (keys_of(&take.motion.skeleton), keys_of(&back.skeleton));
        let bones = mapped_bones(&ck, &back.skeleton, &tk, &take.motion.skeleton);
        let dir_of = |f: &[Vec3], k: &KeyJoints, (key, parent): (Key, Key)| (f[k.get(key).unwrap()] - f[k.get(parent).unwrap()]).normalize();
        let (mut sum, mut worst_frame, mut worst_bone) = (0.0f32, 0.0f32, (0.0f32, bones[0]));
        for t in 0..back.frames() {
            let angles: Vec<f32> = bones
                .iter()
                .map(|&bone| dir_of(back.frame(t), &ck, bone).dot(dir_of(take.motion.frame(t), &tk, bone)).clamp(-1.0, 1.0).acos().to_degrees())
                .collect();
            let mean = angles.iter().sum::<f32>() / angles.len() as f32;
            assert!(mean < 10.0, "{name} frame {t}: bones {mean} degrees off on average ({angles:.1?})");
            sum += mean;
            worst_frame = worst_frame.max(mean);
            for (&a, &bone) in angles.iter().zip(&bones) {
                if a > worst_bone.0 {
                    worst_bone = (a, bone);
                }
            }
        }
        println!(
            "{name} on CMU: {} bones, {} frames at {} fps; mean angle {:.2} degrees, worst frame {worst_frame:.2}, worst bone {:.1} ({:?} from {:?})",
            bones.len(), back.frames(), back.fps, sum / back.frames() as f32, worst_bone.0, worst_bone.1 .0, worst_bone.1 .1
        );
    }
}

/// A rig with unknown forearm names is refused in one line naming them; a joint map fixes it.
#[test]
fn unmappable_skeletons_are_named_and_a_joint_map_fixes_them() {
    let dir = tempfile::tempdir().unwrap();
    let mut renamed = MIXAMO_NAMES.to_vec();
    renamed.retain(|(from, _)| !from.starts_with("LowerArm"));
    renamed.extend([("LowerArm_L", "Bone017"), ("LowerArm_R", "Bone022")]);
    let path = mixamo_from_bandai(dir.path(), &renamed);
    let source = read_bvh(&std::fs::read_to_string(&path).unwrap(), "odd.bvh").unwrap();
    let spec = &model("h36m").spec;
    let e = format!("{:#}", onto_model(spec, &source, "odd.bvh", None).unwrap_err());
    assert!(e.starts_with("odd.bvh: ") && e.contains("no joint found for LeftForeArm, RightForeArm") && !e.contains('\n'), "{e}");

    let map = write(dir.path(), "map.json", r#"{"mixamorig:Bone017": "LeftForeArm", "mixamorig:Bone022": "RightForeArm"}"#);
    let user = UserJointMap::read(&map).unwrap();
    let on_model = onto_model(spec, &source, "odd.bvh", Some(&user)).unwrap();
    assert_eq!(on_model.skeleton.names(), spec.layout.skeleton.names());

    // Not a humanoid at all: a three-joint chain.
    let chain = "HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n JOINT b\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 10 0\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.04\n0 0 0 0 0 0 0 0 0\n";
    let chain = read_bvh(chain, "chain.bvh").unwrap();
    let e = format!("{:#}", onto_model(spec, &chain, "chain.bvh", None).unwrap_err());
    assert!(e.contains("no joint found for Hips, Chest, Head, LeftArm") && e.contains("its joints: a, b"), "{e}");

    // A bad map names the file and the problem.
    let bad = write(dir.path(), "bad.json", r#"{"mixamorig:Bone017": "LeftElbow"}"#);
    let e = format!("{:#}", UserJointMap::read(&bad).unwrap_err());
    assert!(e.contains("bad.json") && e.contains("'LeftElbow'") && e.contains("LeftForeArm"), "{e}");
}

/// A generated take's retargeted toe points as the take's toe, not as its foot: as the heel
/// rolls at toe-off, the toes stay on the floor. Carried by the foot, the toe of `all`'s
/// skeleton (the standard humanoid, with toe ends) tilted with an h36m walk's rising heel, 21
/// degrees from the take's toe at worst, and a Mixamo-named rig's toe tips sank 2.2 cm into
/// the floor in Blender (tests/blender.rs).
#[test]
fn a_retargeted_toe_points_as_the_sources() {
    let (h36m, all) = (model("h36m"), model("all"));
    let take = generate(&h36m, &GenerateOptions { timeline: "walking:6".parse().unwrap(), init: InitPose::SeedClass { class: "walking".into(), variant: 0 }, ..Default::default() }, &mut |_| true).unwrap();
    let source = &take.motion;
    let target = all.spec.layout.skeleton.clone();
    let keys = |s: &Skeleton| key_joints(s, None, "a skeleton").unwrap();
    let moved = glocal::motion::Retarget::new(&source.skeleton, &keys(&source.skeleton), target.clone(), &keys(&target)).unwrap().with_toes_to_tips(&source.skeleton).apply(source);
    let mut worst: f32 = 0.0;
    for side in ["Left", "Right"] {
        let bone = |m: &Motion, toe: &str, tip: &str, t: usize| {
            let [toe, tip] = [toe, tip].map(|n| m.skeleton.index_of(&format!("{side}{n}")).unwrap());
            m.frame(t)[tip] - m.frame(t)[toe]
        };
        for t in 0..source.frames() {
            worst = worst.max(bone(source, "ToeBase", "ToeSite", t).angle_between(bone(&moved, "ToeBase", "Toe_End", t)).to_degrees());
        }
    }
    println!("the retargeted toe's largest angle from the source's toe: {worst:.1} degrees");
    assert!(worst < 5.0, "the retargeted toe turns {worst:.1} degrees from the source's");
}

/// The angle in degrees from rotation `b` to `a`, read from the sine of its half (which keeps
/// its precision near zero, where `Quat::angle_between`'s arc cosine reads 0.04 degrees for
/// quaternions a bit apart).
fn turn_between(a: Quat, b: Quat) -> f32 {
    2.0 * (a * b.inverse()).xyz().length().min(1.0).asin().to_degrees()
}

/// The largest turn of any bone's direction from one frame to the next over `frames`.
fn largest_bone_turn(m: &Motion, frames: std::ops::Range<usize>) -> f32 {
    let parents = m.skeleton.parents();
    let bone = |t: usize, j: usize| parents[j].and_then(|p| (m.frame(t)[j] - m.frame(t)[p]).try_normalize());
    frames
        .flat_map(|t| (0..m.joints()).filter_map(move |j| Some(bone(t, j)?.angle_between(bone(t + 1, j)?).to_degrees())))
        .fold(0.0, f32::max)
}

/// A take started from a rig's BVH and retargeted back onto that rig (the Blender add-on's
/// Continue from the armature) shows the file's own frames over its start, every joint, and
/// joins on no faster than the file moves. Through the model's joints and back, this
/// mannequin's start came back with joints turned up to 135 degrees off the file's (where the
/// model has no joint), its bones pointing 1.5 degrees off on average and its pelvis 22, and
/// a Rigify leg straightened before the join (tests/blender/check_addon.py).
#[test]
fn a_start_retargeted_back_onto_its_own_rig_is_the_rigs_own_frames() {
    let m = model("h36m");
    let path = blender_unreal();
    let frame = 60;
    let o = GenerateOptions { timeline: "walking:3".parse().unwrap(), init: InitPose::file(path.clone(), frame), ..Default::default() };
    let take = generate(&m, &o, &mut |_| true).unwrap();
    let round_trip = onto_skeleton_file(&take.motion, &path, None).unwrap();
    let kept = with_own_start(&m, &o, round_trip.clone()).unwrap();
    let file = read_bvh(&std::fs::read_to_string(&path).unwrap(), "salsa").unwrap();
    let file = file.resample(m.spec.fps);
    // The take's frame 0 is a sparse step after the file's start frame; its start runs to the
    // start window's last pose.
    let first = (frame as f32 * m.spec.fps / 60.0).round() as usize + m.spec.stride;
    let given = m.spec.stride * (m.spec.block_len - 1) + 1;
    let parents = kept.skeleton.parents();
    let worst_off = |take: &Motion| -> f32 {
        let (ours, theirs) = (take.local_poses.as_ref().unwrap(), file.local_poses.as_ref().unwrap());
        (0..given)
            .flat_map(|k| (0..take.joints()).filter(|&j| parents[j].is_some()).map(move |j| turn_between(ours[k].rotations[j], theirs[first + k].rotations[j])))
            .fold(0.0, f32::max)
    };
    let (before, after) = (worst_off(&round_trip), worst_off(&kept));
    let half = (m.spec.fps / 2.0).round() as usize;
    let (join, own) = (largest_bone_turn(&kept, given - 1..given + half), largest_bone_turn(&file, first..first + given - 1));
    println!("the start's joints against the file's, worst: {before:.2} degrees through the model's joints, {after:.4} kept; largest bone turn in a frame over the half second after the join {join:.1} degrees, over the file's start {own:.1}");
    assert!(after < 0.01, "the kept start is {after} degrees off the file's own frames");
    assert!(before > 5.0, "the round trip alone is {before} degrees off: the test no longer tells the two apart");
    assert!(join <= 1.5 * own, "a bone turns {join:.1} degrees in one frame after the join, the file's own at most {own:.1}");
}
