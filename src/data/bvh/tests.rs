//! The reader and the writer on hand-written files, round trips and broken input.

use std::sync::Arc;

use glam::{Quat, Vec3};

use super::*;
use crate::data::{FormatError, Location};
use crate::motion::{euler_to_quat, EulerOrder, LocalPose, Motion, Skeleton};

/// Root ZYX with position, joint `a` ZXY, leaf `b` under it, and `c`: a non-root joint
/// with position channels (its OFFSET must be replaced). Tabs, CRLF, keyword spacing.
const HAND: &str =
    "HIERARCHY\r\nROOT root\r\n{\r\n\tOFFSET 0 0 0\r\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\r\n\
\tJOINT a\r\n\t{\r\n\t\tOFFSET 0 10 0\r\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\r\n\
\t\tJOINT b\r\n\t\t{\r\n\t\t\tOFFSET 0 0 5\r\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\r\n\
\t\t\tEnd Site\r\n\t\t\t{\r\n\t\t\t\tOFFSET 0 0 1\r\n\t\t\t}\r\n\t\t}\r\n\t}\r\n\
\tJOINT c\r\n\t{\r\n\t\tOFFSET 100 100 100\r\n\t\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\r\n\
\t\tEnd Site\r\n\t\t{\r\n\t\t\tOFFSET 0 1 0\r\n\t\t}\r\n\t}\r\n}\r\n\
MOTION\r\nFrames:\t2\r\nFrame Time:\t0.0333333\r\n\
1\t2\t3\t90\t0\t90\t90 0 90\t0 0 0\t1 0 0 0 0 0\r\n\
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n";

fn err(text: &str) -> FormatError {
    match read_bvh(text, "test.bvh") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => {
            assert_eq!(e.file, "test.bvh");
            e
        }
    }
}

fn line_of(e: &FormatError) -> usize {
    match e.location {
        Some(Location::Line(l)) => l,
        other => panic!("expected a line in {e} ({other:?})"),
    }
}

fn close(a: Vec3, b: Vec3) -> bool {
    a.distance(b) < 1e-4
}

#[test]
fn rotation_orders_give_known_positions() {
    let (m, layout) = read_bvh_layout(HAND, "hand.bvh").unwrap();
    let s = &m.skeleton;
    assert_eq!(s.names(), vec!["root", "a", "b", "c"], "End Sites must not be joints");
    assert_eq!(s.parents(), vec![None, Some(0), Some(1), Some(0)]);
    assert_eq!(m.fps, 30.0);
    assert_eq!(m.frames(), 2);
    // Root: Rz(90) Ry(0) Rx(90); a: Rz(90) Rx(0) Ry(90) (values "90 0 90" in ZXY order).
    let f = m.frame(0);
    assert!(close(f[0], Vec3::new(1.0, 2.0, 3.0)), "{:?}", f[0]);
    assert!(close(f[1], Vec3::new(1.0, 2.0, 13.0)), "a: {:?}", f[1]);
    assert!(close(f[2], Vec3::new(1.0, 2.0, 18.0)), "b: {:?}", f[2]);
    assert!(close(f[3], Vec3::new(1.0, 3.0, 3.0)), "c (position channels replace OFFSET): {:?}", f[3]);
    // Frame 1: rest pose, but c's channels still replace its offset with zero.
    let f = m.frame(1);
    assert!(close(f[2], Vec3::new(0.0, 10.0, 5.0)), "{:?}", f[2]);
    assert!(close(f[3], Vec3::ZERO), "{:?}", f[3]);
    assert_eq!(s.offsets()[3], Vec3::splat(100.0), "the skeleton keeps the OFFSET");
    let orders: Vec<_> = layout.joints.iter().map(|j| (j.rotation_order, j.has_position)).collect();
    assert_eq!(orders, vec![(EulerOrder::ZYX, true), (EulerOrder::ZXY, false), (EulerOrder::ZXY, false), (EulerOrder::ZXY, true)]);
}

#[test]
fn write_read_reproduces_hand_example_with_and_without_layout() {
    let (m, layout) = read_bvh_layout(HAND, "hand.bvh").unwrap();
    for l in [Some(&layout), None] {
        let text = write_bvh(&m, l);
        let (back, back_layout) = read_bvh_layout(&text, "written.bvh").unwrap_or_else(|e| panic!("{e}\n{text}"));
        if l.is_some() {
            assert_eq!(back_layout, layout);
        } else {
            assert_eq!(back_layout, BvhLayout::default_for(&m));
            assert!(back_layout.joints[3].has_position, "c moves off its offset, so it keeps position channels");
            assert!(!back_layout.joints[1].has_position);
        }
        assert_eq!(back.skeleton.names(), m.skeleton.names());
        assert_eq!(back.fps, 30.0);
        for (a, b) in back.positions().iter().zip(m.positions()) {
            assert!(close(*a, *b), "{a} vs {b}");
        }
    }
}

#[test]
fn writer_end_site_and_header() {
    let (m, _) = read_bvh_layout(HAND, "hand.bvh").unwrap();
    let text = write_bvh(&m, None);
    // b's own offset is (0, 0, 5): its End Site continues it at half length.
    assert!(text.contains("End Site\n\t\t\t{\n\t\t\t\tOFFSET 0.000000 0.000000 2.500000\n"), "{text}");
    assert!(text.contains("Frame Time: 0.03333333\n"), "{text}");
    assert!(text.contains("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"));
    assert!(text.contains("Frames: 2\n"));
}

#[test]
fn angles_are_continuous_over_full_turns_and_gimbal() {
    // One joint spinning about Y through 720 degrees, and one passing the ZXY gimbal pole
    // (X = 90) so the principal Euler solution would flip.
    let s = Arc::new(Skeleton::new(vec!["r".into(), "j".into()], vec![None, Some(0)], vec![Vec3::ZERO, Vec3::Y], 0.01).unwrap());
    let poses: Vec<LocalPose> = (0..=144)
        .map(|t| {
            let a = t as f32 * 5.0;
            LocalPose {
                rotations: vec![
                    Quat::from_rotation_y(a.to_radians()),
                    euler_to_quat(EulerOrder::ZXY, [20.0, 60.0 + t as f32 * 0.37, 30.0]),
                ],
                translations: vec![Vec3::ZERO, Vec3::Y],
            }
        })
        .collect();
    let m = Motion::from_local_poses(s, 30.0, poses);
    let text = write_bvh(&m, None);
    let frames: Vec<Vec<f64>> = text
        .lines()
        .skip_while(|l| !l.starts_with("Frame Time"))
        .skip(1)
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(frames.len(), 145);
    for w in frames.windows(2) {
        for k in 3..9 {
            assert!((w[1][k] - w[0][k]).abs() < 10.0, "channel {k} jumps: {:?} -> {:?}", w[0], w[1]);
        }
    }
    // The spin accumulates instead of wrapping.
    assert!((frames[144][5] - 720.0).abs() < 1e-3, "root Y should reach 720: {:?}", frames[144]);
    let back = read_bvh(&text, "spin.bvh").unwrap();
    for (a, b) in back.positions().iter().zip(m.positions()) {
        assert!(close(*a, *b), "{a} vs {b}");
    }
    for (pa, pb) in back.local_poses.unwrap().iter().zip(m.local_poses.as_ref().unwrap()) {
        for (qa, qb) in pa.rotations.iter().zip(&pb.rotations) {
            assert!(qa.dot(*qb).abs() > 1.0 - 1e-6);
        }
    }
}

#[test]
fn alternate_euler_solution_is_the_same_rotation() {
    for order in [EulerOrder::XYZ, EulerOrder::XZY, EulerOrder::YXZ, EulerOrder::YZX, EulerOrder::ZXY, EulerOrder::ZYX] {
        let [a, b, c] = [31.0f32, -47.0, 112.0];
        let q = euler_to_quat(order, [a, b, c]);
        let alt = euler_to_quat(order, [a + 180.0, 180.0 - b, c + 180.0]);
        assert!(q.dot(alt).abs() > 1.0 - 1e-6, "{order:?}");
    }
}

#[test]
fn writes_from_positions_when_no_local_poses() {
    let m = read_bvh(HAND, "hand.bvh").unwrap();
    // Drop c's moving translation by only keeping root, a, b (rest offsets below the root).
    let keep = m.subset(&[0, 1, 2]);
    assert!(keep.local_poses.is_none());
    let back = read_bvh(&write_bvh(&keep, None), "solved.bvh").unwrap();
    for (a, b) in back.positions().iter().zip(keep.positions()) {
        assert!(close(*a, *b), "{a} vs {b}");
    }
}

#[test]
fn fps_snaps_and_keeps_odd_rates() {
    let with_time = |t: &str| HAND.replace("0.0333333", t);
    assert_eq!(read_bvh(&with_time("0.00833333"), "f").unwrap().fps, 120.0);
    let odd = read_bvh(&with_time("0.0333667"), "f").unwrap().fps;
    assert!((odd - 29.97).abs() < 0.01, "{odd}");
}

#[test]
fn empty_and_whitespace_files() {
    for text in ["", "   \n\t\r\n", "\u{feff}"] {
        let e = err(text);
        assert!(e.message.contains("empty"), "{e}");
    }
}

#[test]
fn missing_sections() {
    let e = err("MOTION\nFrames: 1\nFrame Time: 0.1\n0\n");
    assert!(e.message.contains("missing HIERARCHY"), "{e}");
    let e = err("ROOT a\n{\nOFFSET 0 0 0\n}\n");
    assert!(e.message.contains("missing HIERARCHY"), "{e}");
    let hierarchy_only = HAND.split("MOTION").next().unwrap();
    let e = err(hierarchy_only);
    assert!(e.message.contains("missing MOTION"), "{e}");
    let e = err(&HAND.replace("Frames:\t2\r\n", ""));
    assert!(e.message.contains("expected 'Frames:'"), "{e}");
    let e = err(&HAND.replace("Frame Time:\t0.0333333\r\n", ""));
    assert!(e.message.contains("expected 'Frame Time:'"), "{e}");
    let e = err("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n");
    assert!(e.message.contains("no ROOT"), "{e}");
}

#[test]
fn bad_numbers_name_line_and_token() {
    let e = err(&HAND.replace("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n", "0 0 0 0 0 0 0 0 0 0 0 0 0 0 1.2.3 0 0 0\r\n"));
    assert_eq!(line_of(&e), 34);
    assert!(e.message.contains("'1.2.3'") && e.message.contains("value 15"), "{e}");
    let e = err(&HAND.replace("OFFSET 0 10 0", "OFFSET 0 1x 0"));
    assert_eq!(line_of(&e), 8);
    assert!(e.message.contains("'1x'"), "{e}");
    let e = err(&HAND.replace("Frames:\t2", "Frames:\ttwo"));
    assert!(e.message.contains("'two'"), "{e}");
    let e = err(&HAND.replace("OFFSET 0 10 0", "OFFSET 0 10"));
    assert!(e.message.contains("OFFSET needs 3 numbers"), "{e}");
}

#[test]
fn wrong_value_count_says_expected_and_found() {
    let e = err(&HAND.replace("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n", "0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\r\n"));
    assert_eq!(line_of(&e), 34);
    assert!(e.message.contains("17 values") && e.message.contains("expected 18"), "{e}");
}

#[test]
fn fewer_frames_than_declared_says_how_many() {
    let e = err(&HAND.replace("Frames:\t2", "Frames:\t5"));
    assert!(e.message.contains("5") && e.message.contains("only 2 frame lines"), "{e}");
    let e = err(&HAND.replace("Frames:\t2", "Frames:\t1"));
    assert!(e.message.contains("more frame lines"), "{e}");
}

#[test]
fn unknown_channel_and_bad_count() {
    let e = err(&HAND.replace("Zrotation Xrotation Yrotation\r\n\t\tJOINT b", "Zrotation Wrotation Yrotation\r\n\t\tJOINT b"));
    assert_eq!(line_of(&e), 9);
    assert!(e.message.contains("unknown channel 'Wrotation'"), "{e}");
    let e = err(&HAND
        .replace("CHANNELS 3 Zrotation Xrotation Yrotation\r\n\t\tJOINT b", "CHANNELS 9 Zrotation Xrotation Yrotation\r\n\t\tJOINT b"));
    assert!(e.message.contains("bad channel count '9'"), "{e}");
    let e = err(&HAND
        .replace("CHANNELS 3 Zrotation Xrotation Yrotation\r\n\t\tJOINT b", "CHANNELS 3 Zrotation Zrotation Yrotation\r\n\t\tJOINT b"));
    assert!(e.message.contains("twice"), "{e}");
}

#[test]
fn unbalanced_braces() {
    let e = err(&HAND.replacen("\t}\r\n}\r\nMOTION", "\t}\r\nMOTION", 1));
    assert!(e.message.contains("unbalanced braces") && e.message.contains("joint 'root'"), "{e}");
    let e = err(&HAND.replacen("}\r\nMOTION", "}\r\n}\r\nMOTION", 1));
    assert!(e.message.contains("unbalanced braces: '}' closes nothing"), "{e}");
    let e = err(&HAND.replacen("\tJOINT a\r\n\t{", "\tJOINT a\r\n", 1));
    assert!(e.message.contains("expected '{'"), "{e}");
}

#[test]
fn frame_time_must_be_positive() {
    for t in ["0", "-0.1", "0.0", "nan", "inf"] {
        let e = err(&HAND.replace("0.0333333", t));
        assert!(e.message.contains("frame time"), "{t}: {e}");
        assert_eq!(line_of(&e), 32);
    }
}

#[test]
fn nan_and_inf_values_are_rejected() {
    for v in ["NaN", "inf", "-infinity", "1e40"] {
        let e = err(&HAND.replace("1\t2\t3\t90", &format!("1\t{v}\t3\t90")));
        assert_eq!(line_of(&e), 33);
        assert!(e.message.contains("not finite"), "{v}: {e}");
    }
    let e = err(&HAND.replace("OFFSET 0 10 0", "OFFSET 0 nan 0"));
    assert!(e.message.contains("finite"), "{e}");
}

#[test]
fn every_truncation_is_handled() {
    // Every prefix either reads (cut at a line end after enough frames) or is an error
    // naming the file; none panics.
    let mut errors = 0;
    for (cut, _) in HAND.char_indices() {
        match read_bvh(&HAND[..cut], "cut.bvh") {
            Ok(m) => assert_eq!(m.frames(), 2, "prefix of {cut} bytes read with a wrong frame count"),
            Err(e) => {
                assert_eq!(e.file, "cut.bvh");
                errors += 1;
            }
        }
    }
    // Only cuts inside the last frame line's trailing whitespace or its last number may read.
    assert!(errors > HAND.len() - 40, "{errors} of {}", HAND.len());
}

#[test]
fn garbage_is_an_error() {
    let mut state = 12345u64;
    let alphabet = b" \n\t{}0123456789.-eHIERARCHYROOTJOINTMOTIONFrames:";
    for len in [1, 7, 100, 3000] {
        let text: String = (0..len)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                char::from(alphabet[(state >> 33) as usize % alphabet.len()])
            })
            .collect();
        let e = err(&text);
        assert!(!e.message.is_empty());
    }
    let e = err("\u{0}\u{1}binary\u{7f}");
    assert!(e.message.contains("missing HIERARCHY"), "{e}");
}
