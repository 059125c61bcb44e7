//! Root motion for game engines (`--root-motion`): the body in place, or its travel carried by
//! an added root joint on the floor, on both shipped models.

use std::path::Path;

use glam::Vec3;
use glocal::model::glocal::GlocalModel;
use glocal::motion::{facing, JointRoles, Motion, ROOT_BONE};
use glocal::synth::export::{export, prepare, read_take, ExportOptions};
use glocal::synth::{generate, GenerateOptions, InitPose};
use glocal::motion::RootMotion;

fn take(name: &str) -> (GlocalModel, Motion, Vec<glocal::synth::SegmentSpan>) {
    let m = GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap();
    let walk = m.spec.classes.iter().find(|c| c.starts_with("walk")).unwrap().clone();
    let opts = GenerateOptions { timeline: format!("{walk}:6").parse().unwrap(), init: InitPose::SeedClass { class: walk, variant: 0 }, ..Default::default() };
    let g = generate(&m, &opts, &mut |_| true).unwrap();
    (m, g.motion, g.segments)
}

fn exported(m: &GlocalModel, motion: &Motion, segments: &[glocal::synth::SegmentSpan], mode: RootMotion) -> Motion {
    prepare(motion, segments, &ExportOptions { root_motion: mode, ..Default::default() }, &m.spec.source_skeleton).unwrap().0
}

/// In place: the hips' horizontal position constant within 1 mm and their facing that of the
/// first frame, while the pose about the hips is the travelling take's. Root bone: a `root`
/// joint on the floor under the hips carrying all their travel and turning, every other
/// joint where the travelling take has it; both read back from BVH and JSON files (glTF in
/// Blender: tests/blender.rs).
#[test]
fn in_place_stays_and_the_root_bone_carries_the_travel() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["h36m", "bandai", "all"] {
        let (m, motion, segments) = take(name);
        let travel = exported(&m, &motion, &segments, RootMotion::Travel);
        let roles = JointRoles::new(&travel.skeleton).unwrap();
        let face = |f: &[Vec3]| facing(f, roles.left.hip, roles.right.hip);
        let moved = travel.frame(travel.frames() - 1)[0] - travel.frame(0)[0];
        assert!(Vec3::new(moved.x, 0.0, moved.z).length() > 2.0, "{name}: the walk travels ({moved})");

        let still = exported(&m, &motion, &segments, RootMotion::InPlace);
        let hips0 = still.frame(0)[0];
        for t in 0..still.frames() {
            let (h, f) = (still.frame(t)[0], travel.frame(t)[0]);
            assert!(Vec3::new(h.x - hips0.x, 0.0, h.z - hips0.z).length() < 0.001, "{name} frame {t}: the hips drift {h} from {hips0}");
            assert!((h.y - f.y).abs() < 1e-4, "{name} frame {t}: the hips' height changed");
            let turn = glocal::data::features::wrap(face(still.frame(t)) - face(still.frame(0)));
            assert!(turn.abs() < 1e-3, "{name} frame {t}: the body turned {turn} rad in place");
        }

        let rooted = exported(&m, &motion, &segments, RootMotion::RootBone);
        assert_eq!(rooted.skeleton.names()[0], ROOT_BONE);
        assert_eq!(rooted.skeleton.len(), travel.skeleton.len() + 1);
        for t in 0..rooted.frames() {
            let (root, hips) = (rooted.frame(t)[0], travel.frame(t)[0]);
            assert!(root.y.abs() < 1e-5 && (Vec3::new(root.x, 0.0, root.z) - Vec3::new(hips.x, 0.0, hips.z)).length() < 1e-4, "{name} frame {t}: root {root} is not on the floor under the hips {hips}");
            let off = rooted.frame(t)[1..].iter().zip(travel.frame(t)).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
            assert!(off < 1e-4, "{name} frame {t}: a joint moved {off} m under the root bone");
        }

        for (mode, want) in [("in-place", &still), ("root-bone", &rooted)] {
            for ext in ["bvh", "json"] {
                let file = dir.path().join(format!("{name}-{mode}.{ext}"));
                export(want, &segments, &file).unwrap();
                let (back, _) = read_take(&file, Some(&m.dir)).unwrap();
                let off = back.positions().iter().zip(want.positions()).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                println!("{name} {mode} {ext}: read back within {:.4} mm", 1000.0 * off);
                assert!(off < 1e-5, "{name} {mode} {ext}: read back {off} m off");
            }
        }
    }
}
