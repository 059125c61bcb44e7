//! Motion file formats against the real datasets: BVH read/write round trips on every Bandai
//! and CMU-dance clip, solving rotations from positions, NPY round trips, and a mutation
//! test that the BVH reader never panics.
//!
//! The clips come from the dataset archives through `DataRoot` (`--data`/`GLOCAL_DATA`, else
//! `../shared/data`); these tests fail, rather than skip, when the archives are missing.

use std::sync::Arc;

use glam::Vec3;
use glocal::data::archive::DataRoot;
use glocal::data::bvh::{read_bvh, read_bvh_layout_with_unit, write_bvh, BvhLayout};
use glocal::data::npy::{motion_from_npy, motion_to_npy, read_npy};
use glocal::data::registry::{self, Dataset};
use glocal::motion::{solve_local_poses, Motion};

/// Every `.bvh` of a dataset archive whose path `keep` accepts, as (path, text).
fn clips(dataset: &str, keep: impl Fn(&str) -> bool) -> Vec<(String, String)> {
    let root = DataRoot::resolve(None);
    let mut entries: Vec<(String, String)> = root
        .read_archive(dataset, |p| p.ends_with(".bvh") && keep(p))
        .unwrap_or_else(|e| panic!("cannot read the {dataset} archive: {e:#}"))
        .into_iter()
        .map(|(p, b)| (p, String::from_utf8(b).expect("BVH files are UTF-8")))
        .collect();
    entries.sort();
    entries
}

fn max_distance(a: &Motion, b: &Motion) -> f32 {
    assert_eq!(a.frames(), b.frames());
    assert_eq!(a.joints(), b.joints());
    a.positions().iter().zip(b.positions()).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max)
}

/// Reads every clip, writes it with its own layout and with the default one, reads it back.
/// Returns (clips, frames, max error with own layout, max error with default layout).
fn round_trip_all(entries: &[(String, String)], unit: f32, joints: usize) -> (usize, usize, f32, f32) {
    let (mut frames, mut worst_own, mut worst_default) = (0, 0.0f32, 0.0f32);
    for (path, text) in entries {
        let (m, layout) = read_bvh_layout_with_unit(text, path, unit).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.joints(), joints, "{path}");
        assert_eq!(m.skeleton.meters_per_unit(), unit);
        frames += m.frames();
        for (own, l) in [(true, Some(&layout)), (false, None)] {
            let written = write_bvh(&m, l);
            let (back, back_layout) =
                read_bvh_layout_with_unit(&written, path, unit).unwrap_or_else(|e| panic!("{path} written back: {e}"));
            assert_eq!(back.skeleton.names(), m.skeleton.names(), "{path}");
            assert_eq!(back.skeleton.parents(), m.skeleton.parents(), "{path}");
            assert!((back.fps - m.fps).abs() < 1e-3, "{path}: fps {} against {}", back.fps, m.fps);
            let err = max_distance(&m, &back);
            assert!(err < 1e-3, "{path} (own layout: {own}): positions differ by up to {err}");
            if own {
                assert_eq!(back_layout, layout, "{path}: layout not reproduced");
                worst_own = worst_own.max(err);
            } else {
                assert_eq!(back_layout, BvhLayout::default_for(&m), "{path}");
                worst_default = worst_default.max(err);
            }
        }
    }
    (entries.len(), frames, worst_own, worst_default)
}

#[test]
fn bandai_bvh_round_trip_every_clip() {
    let entries = clips("bandai", |_| true);
    let (n, frames, own, default) = round_trip_all(&entries, Dataset::Bandai.meters_per_unit(), 22);
    println!("bandai: {n} clips, {frames} frames; max position error own layout {own:.2e} cm, default layout {default:.2e} cm");
    assert_eq!((n, frames), (174, 31_914), "counts from the data README");
}

#[test]
fn cmu_dance_bvh_round_trip_every_clip() {
    let entries = clips("cmu-dance", |p| p.matches('/').count() == 2);
    let (n, frames, own, default) = round_trip_all(&entries, Dataset::CmuDance.meters_per_unit(), 43);
    println!("cmu-dance: {n} clips, {frames} frames; max position error own layout {own:.2e}, default layout {default:.2e} (file units)");
    assert_eq!((n, frames), (43, 90_808), "counts from the data README");
    let (_, text) = &entries[0];
    let (_, layout) = read_bvh_layout_with_unit(text, "cmu", 1.0).unwrap();
    assert_eq!(layout.joints[0].rotation_order, glocal::motion::EulerOrder::ZYX, "the root is ZYX");
    assert!(layout.joints[1..].iter().all(|j| j.rotation_order == glocal::motion::EulerOrder::ZXY && !j.has_position));
    let standard = clips("cmu-dance", |p| p.ends_with("standard.bvh"));
    let m = read_bvh(&standard[0].1, &standard[0].0).unwrap();
    assert_eq!((m.joints(), m.frames()), (43, 3));
}

#[test]
fn registry_reads_every_bvh_clip() {
    let root = DataRoot::resolve(None);
    for (dataset, clips, joints) in [(Dataset::Bandai, 174, 22), (Dataset::CmuDance, 43, 43)] {
        let loaded = registry::load_archive(dataset, &root).unwrap();
        assert!(loaded.skipped.is_empty(), "{dataset}: {:?}", loaded.skipped);
        assert_eq!(loaded.clips.len(), clips, "{dataset}");
        assert!(loaded.clips.iter().all(|c| c.motion.joints() == joints && c.motion.local_poses.is_some()));
    }
}

/// Mean and max distance per joint between `m` and the forward kinematics of rotations solved
/// from its positions.
fn solve_error(m: &Motion) -> (f32, f32) {
    let poses = solve_local_poses(&m.skeleton, m.positions());
    let rebuilt = Motion::from_local_poses(m.skeleton.clone(), m.fps, poses);
    let d: Vec<f32> = m.positions().iter().zip(rebuilt.positions()).map(|(p, q)| p.distance(*q)).collect();
    (d.iter().sum::<f32>() / d.len() as f32, d.iter().copied().fold(0.0, f32::max))
}

#[test]
fn solve_reproduces_bandai_and_cmu_positions() {
    // Bandai's `joint_Root` mostly stays at the origin while `Hips` moves through its own
    // position channels, so the joint_Root->Hips "bone" has no fixed length (its rest offset is where
    // the capture started, up to 4.6 m away): solve from Hips down, i.e. on the sub-skeleton
    // without joint_Root. Every clip, every frame.
    let (mut sum, mut count, mut worst) = (0.0f64, 0usize, 0.0f32);
    let (mut with_root, mut moving_root) = (0.0f64, 0);
    for (path, text) in clips("bandai", |_| true) {
        let m = read_bvh(&text, &path).unwrap();
        let root = m.skeleton.index_of("joint_Root").expect("bandai has joint_Root");
        assert_eq!(root, 0);
        moving_root += usize::from((0..m.frames()).any(|t| m.frame(t)[0] != Vec3::ZERO));
        let (mean, max) = solve_error(&m.subset(&(1..m.joints()).collect::<Vec<_>>()));
        sum += mean as f64 * m.frames() as f64;
        count += m.frames();
        worst = worst.max(max);
        with_root = with_root.max(solve_error(&m).0 as f64);
    }
    let mean = (sum / count as f64) as f32;
    println!("solve, bandai without joint_Root, {count} frames: mean {mean:.2e} cm, max {worst:.2e} cm");
    println!("bandai: joint_Root leaves the origin in {moving_root} clips");
    println!("solve, bandai with joint_Root (rest Hips offset used as a bone): mean up to {with_root:.1} cm per clip");
    assert!(mean < 1e-4 && worst < 1e-3, "mean {mean} max {worst}");

    let (mut sum, mut count, mut worst) = (0.0f64, 0usize, 0.0f32);
    for (path, text) in clips("cmu-dance", |p| p.matches('/').count() == 2) {
        let m = read_bvh(&text, &path).unwrap();
        let (mean, max) = solve_error(&m);
        sum += mean as f64 * m.frames() as f64;
        count += m.frames();
        worst = worst.max(max);
    }
    let mean = (sum / count as f64) as f32;
    println!("solve, cmu-dance {count} frames: mean {mean:.2e}, max {worst:.2e} (file units)");
    assert!(mean < 1e-4 && worst < 1e-3, "mean {mean} max {worst}");

    // Export from positions alone: write_bvh solves, the file reads back to the same positions.
    let cmu = clips("cmu-dance", |p| p.ends_with("salsa/01.bvh"));
    let m = read_bvh(&cmu[0].1, &cmu[0].0).unwrap();
    let positions_only = Motion::from_positions(m.skeleton.clone(), m.fps, m.positions().to_vec());
    let back = read_bvh(&write_bvh(&positions_only, None), "solved.bvh").unwrap();
    let err = max_distance(&positions_only, &back);
    println!("cmu-dance salsa/01 positions -> solve -> BVH -> read: max error {err:.2e}");
    assert!(err < 1e-3);
}

#[test]
fn npy_round_trip_real_clip() {
    let bandai = clips("bandai", |p| p.contains("bow_normal"));
    let m = read_bvh(&bandai[0].1, &bandai[0].0).unwrap();
    let bytes = motion_to_npy(&m);
    let a = read_npy(&bytes, "bow.npy").unwrap();
    assert_eq!(a.shape, vec![m.frames(), 22, 3]);
    let back = motion_from_npy(&bytes, "bow.npy", m.skeleton.clone(), m.fps).unwrap();
    assert_eq!(back.positions(), m.positions());
    let other = Arc::new(m.skeleton.subset(&(1..22).collect::<Vec<_>>()));
    let e = motion_from_npy(&bytes, "bow.npy", other, m.fps).unwrap_err();
    assert!(e.to_string().contains("bow.npy") && e.message.contains("(frames, 21, 3)"), "{e}");
}

/// 20,000 random mutations (byte flips, truncations, line duplications, deletions and swaps)
/// of a real Bandai file: `read_bvh` returns, and every error names the file.
#[test]
fn bvh_reader_survives_20000_mutations() {
    let bandai = clips("bandai", |_| true);
    let (_, base) = bandai.iter().min_by_key(|(_, t)| t.len()).unwrap();
    let base = base.as_bytes();
    let mut state = 0x5eed_u64;
    let mut next = |n: usize| {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 33) as usize) % n.max(1)
    };
    let started = std::time::Instant::now();
    let (mut ok, mut errors) = (0, 0);
    for _ in 0..20_000 {
        let mut b = base.to_vec();
        for _ in 0..1 + next(4) {
            match next(6) {
                0 => {
                    let at = next(b.len());
                    b[at] ^= 1 << next(8);
                }
                1 => {
                    let at = next(b.len());
                    b[at] = b" \t\r\n{}-.e0123456789ABCabcNaN"[next(28)];
                }
                2 => b.truncate(next(b.len())),
                3 | 4 => {
                    let lines: Vec<&[u8]> = b.split(|&c| c == b'\n').collect();
                    let k = next(lines.len());
                    let mut out: Vec<&[u8]> = lines.clone();
                    match next(3) {
                        0 => out.insert(k, lines[k]),
                        1 => {
                            out.remove(k);
                        }
                        _ => out.swap(k, next(lines.len())),
                    }
                    b = out.join(&b'\n');
                }
                _ => {
                    let at = next(b.len());
                    let len = next(64).min(b.len() - at);
                    b.drain(at..at + len);
                }
            }
            if b.is_empty() {
                break;
            }
        }
        let text = String::from_utf8_lossy(&b);
        match read_bvh(&text, "mutant.bvh") {
            Ok(m) => {
                ok += 1;
                assert!(m.positions().iter().all(|p: &Vec3| p.is_finite()));
            }
            Err(e) => {
                assert_eq!(e.file, "mutant.bvh");
                errors += 1;
            }
        }
    }
    println!("mutations: {ok} read, {errors} rejected, in {:.1} s", started.elapsed().as_secs_f32());
    assert!(errors > 10_000, "most mutations should be rejected: {errors}");
}
