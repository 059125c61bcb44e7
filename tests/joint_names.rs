//! `--joint-names`: both shipped models' takes renamed to each convention keep every joint
//! where it was (in the motion and through a BVH written and read back), name the key joints
//! as the convention does, and stand in a T-pose rest for Mixamo and Unity.

use std::path::Path;

use glam::Vec3;
use glocal::data::bvh::{read_bvh_with_unit, write_bvh};
use glocal::model::glocal::GlocalModel;
use glocal::motion::Motion;
use glocal::synth::joint_names::JointNames;
use glocal::synth::{generate, GenerateOptions};

fn take(model: &str) -> Motion {
    let m = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(model)).unwrap();
    let timeline = format!("{}:3", m.spec.classes[0]);
    generate(&m, &GenerateOptions { timeline: timeline.parse().unwrap(), ..Default::default() }, &mut |_| true).unwrap().motion
}

fn farthest(a: &Motion, b: &Motion) -> f32 {
    a.positions().iter().zip(b.positions()).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max)
}

fn rest_direction(m: &Motion, from: &str, to: &str) -> Vec3 {
    let s = &m.skeleton;
    let rest = s.rest_positions();
    (rest[s.index_of(to).unwrap()] - rest[s.index_of(from).unwrap()]).normalize()
}

#[test]
fn renamed_takes_keep_their_positions_and_name_the_key_joints() {
    let expected = [
        (JointNames::Mixamo, ["mixamorig:Hips", "mixamorig:Spine", "mixamorig:LeftForeArm", "mixamorig:RightUpLeg", "mixamorig:LeftToeBase"]),
        (JointNames::Unreal, ["pelvis", "spine_01", "lowerarm_l", "thigh_r", "ball_l"]),
        (JointNames::Unity, ["Hips", "Spine", "LeftLowerArm", "RightUpperLeg", "LeftToes"]),
    ];
    for model in ["h36m", "bandai", "all"] {
        let native = take(model);
        let unit = native.skeleton.meters_per_unit();
        for (names, joints) in &expected {
            let renamed = names.apply(&native, None).unwrap();
            for joint in joints {
                assert!(renamed.skeleton.index_of(joint).is_some(), "{model} {names:?}: no {joint} in {:?}", renamed.skeleton.names());
            }
            assert_eq!(renamed.skeleton.parents(), native.skeleton.parents());
            let moved = farthest(&native, &renamed) * unit;
            let back = read_bvh_with_unit(&write_bvh(&renamed, None), "renamed.bvh", unit).unwrap();
            let through_bvh = farthest(&native, &back) * unit;
            println!("{model} {names:?}: joints moved {:.2e} m by renaming, {:.2e} m through BVH", moved, through_bvh);
            assert!(moved < 1e-5 && through_bvh < 1e-4, "{model} {names:?}: {moved} m, {through_bvh} m through BVH");
        }
    }
}

#[test]
fn mixamo_and_unity_names_stand_in_a_t_pose() {
    for model in ["h36m", "bandai", "all"] {
        let mixamo = JointNames::Mixamo.apply(&take(model), None).unwrap();
        let left = rest_direction(&mixamo, "mixamorig:RightUpLeg", "mixamorig:LeftUpLeg");
        let along = |from: &str, to: &str, want: Vec3| {
            let got = rest_direction(&mixamo, &format!("mixamorig:{from}"), &format!("mixamorig:{to}"));
            assert!(got.angle_between(want).to_degrees() < 1.0, "{model}: {from}->{to} points {got}, not {want}");
        };
        along("LeftArm", "LeftForeArm", Vec3::new(left.x, 0.0, left.z).normalize());
        along("RightForeArm", "RightHand", -Vec3::new(left.x, 0.0, left.z).normalize());
        along("LeftUpLeg", "LeftLeg", -Vec3::Y);
        along("RightLeg", "RightFoot", -Vec3::Y);
        along("Neck", "Head", Vec3::Y);
    }
}
