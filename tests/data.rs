//! The foundation's acceptance on the real datasets: exact counts, constant bone lengths,
//! readers that name the file and the problem.

use glocal::data::archive::DataRoot;
use glocal::data::loading;
use glocal::data::registry::{self, Dataset, DatasetClips};
use glocal::model::corpus::Corpus;

fn load(d: Dataset) -> DatasetClips {
    loading::load(d, &DataRoot::resolve(None)).unwrap_or_else(|e| panic!("{d}: {e:#}"))
}

fn per_class(d: &DatasetClips) -> Vec<(String, usize, usize)> {
    d.classes
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let clips: Vec<_> = d.clips.iter().filter(|c| c.class == k).collect();
            (name.clone(), clips.len(), clips.iter().map(|c| c.motion.frames()).sum())
        })
        .collect()
}

fn totals(d: &DatasetClips) -> (usize, usize) {
    (d.clips.len(), d.clips.iter().map(|c| c.motion.frames()).sum())
}

#[test]
fn h36m_counts_match_the_readme() {
    let d = load(Dataset::H36m);
    assert!(d.skipped.is_empty(), "{:?}", d.skipped);
    assert_eq!(totals(&d), (123, 307_301));
    assert_eq!(d.clips[0].motion.joints(), 32);
    let expected = [
        ("directions", 13, 28_693),
        ("discussion", 8, 21_669),
        ("eating", 14, 37_183),
        ("greeting", 14, 25_770),
        ("phoning", 13, 38_626),
        ("posing", 14, 25_997),
        ("sitting", 13, 34_654),
        ("sittingdown", 10, 24_625),
        ("smoking", 10, 29_582),
        ("walking", 14, 40_502),
    ];
    let got = per_class(&d);
    for ((name, clips, frames), (en, ec, ef)) in got.iter().zip(expected) {
        assert_eq!((name.as_str(), *clips, *frames), (en, ec, ef));
    }
    // Test split: subject S11, every action present.
    let test: Vec<_> = d.clips.iter().filter(|c| c.split == registry::Split::Test).collect();
    assert!(test.iter().all(|c| c.tag == "S11"));
    assert_eq!(test.iter().map(|c| c.class).collect::<std::collections::BTreeSet<_>>().len(), 10);
}

#[test]
fn bandai_cmu_counts_match_the_readme() {
    let b = load(Dataset::Bandai);
    assert_eq!(totals(&b), (174, 31_914));
    assert_eq!(b.classes.len(), 16);
    assert_eq!(b.clips[0].motion.joints(), 22);
    assert_eq!(per_class(&b)[0], ("walk".to_string(), 30, 6_876));
    assert_eq!(b.clips.iter().filter(|c| c.split == registry::Split::Test).count(), 22);

    let dance = load(Dataset::CmuDance);
    assert_eq!(totals(&dance), (43, 90_808));
    let clips: Vec<usize> = per_class(&dance).iter().map(|c| c.1).collect();
    assert_eq!(clips, vec![7, 8, 28]);
    assert_eq!(dance.clips[0].motion.joints(), 43);

    let expmap = load(Dataset::CmuExpmap);
    assert_eq!(totals(&expmap), (38, 40_331));
    assert_eq!(expmap.clips[0].motion.joints(), 38);
}

/// Every bone of at least 1 cm keeps its length within 0.1% over every frame of every
/// h36m and Bandai clip. Bandai's `joint_Root` is a placement handle, not a bone end: the
/// segment from it to `Hips` moves freely and is left out.
#[test]
fn bone_lengths_are_constant() {
    for dataset in [Dataset::H36m, Dataset::Bandai] {
        let d = load(dataset);
        let mut worst = 0.0f32;
        for clip in &d.clips {
            let m = &clip.motion;
            let sk = &m.skeleton;
            let handle = sk.children(0).count() == 1;
            let first = m.bone_lengths(0);
            let bones: Vec<usize> = (0..m.joints())
                .filter(|&j| first[j] * sk.meters_per_unit() >= 0.01 && !(handle && sk.parents()[j] == Some(0)))
                .collect();
            for t in 0..m.frames() {
                let lengths = m.bone_lengths(t);
                for &j in &bones {
                    worst = worst.max((lengths[j] - first[j]).abs() / first[j]);
                }
            }
        }
        assert!(worst < 1e-3, "{dataset}: a bone length varies by {:.4}%", worst * 100.0);
    }
}

#[test]
fn missing_or_corrupt_archives_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let root = DataRoot::resolve(Some(dir.path()));
    let err = format!("{:#}", registry::load_archive(Dataset::Bandai, &root).unwrap_err());
    assert!(err.contains("bandai.tar.zst") && err.contains("missing"), "{err}");

    // A copy with one byte changed fails its checksum.
    let shared = DataRoot::resolve(None);
    std::fs::copy(shared.file("SHA256SUMS"), dir.path().join("SHA256SUMS")).unwrap();
    let mut bytes = std::fs::read(shared.file("bandai.tar.zst")).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0xff;
    std::fs::write(dir.path().join("bandai.tar.zst"), bytes).unwrap();
    let err = format!("{:#}", registry::load_archive(Dataset::Bandai, &root).unwrap_err());
    assert!(err.contains("bandai.tar.zst is corrupt"), "{err}");
}

#[test]
fn features_invert_exactly_on_real_clips() {
    let c = Corpus::load(Dataset::Bandai, &DataRoot::resolve(None), 5, 3).unwrap();
    for track in c.train.iter().take(20) {
        let m = &track.motion;
        let n = (m.frames() - 5) / 5;
        let feats = c.layout.encode_motion(m, 5, 5, n);
        let (back, _) = c.layout.decode(&feats, c.layout.placement(m.frame(0)));
        for k in 0..n {
            for (a, b) in back[k * m.joints()..(k + 1) * m.joints()].iter().zip(m.frame(5 + 5 * k)) {
                assert!(a.distance(*b) < 1e-2, "{}: sample {k} off by {}", track.file, a.distance(*b));
            }
        }
    }
}

/// Heights (m) of the toes in the frames where they stand still, per class of the h36m test
/// subject, after the reader levelled each take on its floor.
fn still_toe_heights(d: &DatasetClips, class: usize) -> Vec<f32> {
    let mut heights = Vec::new();
    for clip in d.clips.iter().filter(|c| c.class == class && c.split == registry::Split::Test) {
        let m = &clip.motion;
        let unit = m.skeleton.meters_per_unit();
        let toes: Vec<usize> = ["LeftToeBase", "RightToeBase"].iter().filter_map(|n| m.skeleton.index_of(n)).collect();
        for t in 1..m.frames() {
            for &j in &toes {
                let speed = m.frame(t)[j].distance(m.frame(t - 1)[j]) * unit * m.fps;
                if speed < 0.2 {
                    heights.push(m.frame(t)[j].y * unit);
                }
            }
        }
    }
    heights
}

#[test]
fn h36m_takes_stand_on_a_level_floor_at_zero() {
    let d = load(Dataset::H36m);
    for (k, name) in d.classes.iter().enumerate() {
        let mut h = still_toe_heights(&d, k);
        h.sort_by(f32::total_cmp);
        let q = |p: f32| h[((h.len() - 1) as f32 * p) as usize];
        eprintln!("{name}: {} still toe samples; heights p10 {:.3} p50 {:.3} p90 {:.3} m", h.len(), q(0.1), q(0.5), q(0.9));
        if name == "walking" {
            // Over metres of travel the standing toes stay at one height near the floor.
            assert!(q(0.5).abs() < 0.03, "walking: median standing toe at {:.3} m", q(0.5));
            assert!(q(0.9) - q(0.1) < 0.04, "walking: standing toes spread {:.3} m", q(0.9) - q(0.1));
        }
    }
}

/// The model of everything's data (issue 35): every clip of the four datasets on the standard
/// humanoid, each dataset checked like an export (bones within 5 degrees of the source's on
/// every clip, feet on the floor, no bone-length change), at least 25 activities of 3 or more
/// training clips, classes merged across datasets and Bandai's styles on its clips.
#[test]
fn every_dataset_lands_on_the_standard_humanoid() {
    let (all, checks) = glocal::data::combined::load(&DataRoot::resolve(None)).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(all.clips.len(), 123 + 174 + 43 + 38);
    for c in &checks {
        println!("{c:?}");
        assert!(c.worst_clip_degrees < 5.0, "{}: {} bones {:.2} degrees from the source's", c.dataset, c.worst_clip, c.worst_clip_degrees);
        assert!(c.worst_foot_height.abs() < 0.05, "{}: {}'s lowest foot stands {:.3} m from the floor", c.dataset, c.worst_foot_clip, c.worst_foot_height);
        assert!(c.bone_length_change < 1e-4, "{}: a bone changes length by {} m", c.dataset, c.bone_length_change);
    }
    assert!(all.clips.iter().all(|c| c.motion.fps == 30.0 && c.motion.skeleton.names()[0] == "Hips"));
    let walking = all.class_sources[all.class_index("walking").unwrap()].clone();
    assert_eq!(walking, "h36m walking + bandai walk + cmu-expmap walking");
    assert_eq!(all.class_sources[all.class_index("running").unwrap()], "bandai run + cmu-expmap running");
    let corpus = Corpus::load(Dataset::Combined, &DataRoot::resolve(None), 3, 3).unwrap();
    assert!(corpus.classes.len() >= 25, "{} activities: {:?}", corpus.classes.len(), corpus.classes);
    // Bandai's 15 styles and neutral: its test styles (tired, musical) are each taught by the
    // test clips of half its contents and tested on the other half's.
    assert_eq!(corpus.styles.len(), 16, "{:?}", corpus.styles);
    for held_out in ["tired", "musical"] {
        let of_style: Vec<_> = corpus.test.iter().filter(|t| t.tag == held_out).collect();
        let (teach, test) = (of_style.iter().filter(|t| t.teaches_style).count(), of_style.iter().filter(|t| !t.teaches_style).count());
        println!("{held_out}: {teach} clips teach it, {test} test it");
        assert!(teach >= 4 && test >= 4, "{held_out}: {teach} clips teach it, {test} test it");
        assert!(!corpus.train.iter().any(|t| t.tag == held_out), "{held_out} has no training clip");
    }
    assert!(corpus.test.iter().filter(|t| t.teaches_style).all(|t| t.tag == "tired" || t.tag == "musical"));
    assert!(corpus.train.iter().filter(|t| t.file.starts_with("bandai")).all(|t| t.style.is_some_and(|s| corpus.styles[s] != "neutral")));
    assert!(corpus.train.iter().filter(|t| t.file.starts_with("h36m")).all(|t| t.style.is_some_and(|s| corpus.styles[s] == "neutral")));
}

/// Every real pose of each dataset's training split, through the model's skeleton (the joints
/// a model keeps, rotations solved from positions and forward kinematics again), lands within
/// 1 cm of itself: a key or a start from a real clip is a pose the model's skeleton can hold.
/// Human3.6M needs its `Spine` for this (0.1 mm above the hips, it bends the back against the
/// pelvis: without it the worst pose missed by 8.6 cm).
#[test]
fn real_poses_round_trip_through_the_model_skeleton() {
    use glocal::motion::{solve_local_poses, Motion};
    for dataset in [Dataset::H36m, Dataset::Bandai] {
        let corpus = Corpus::load(dataset, &DataRoot::resolve(None), 5, 3).unwrap();
        let skeleton = corpus.layout.skeleton.clone();
        let cm = 100.0 * skeleton.meters_per_unit();
        let (mut worst, mut sum, mut count) = (0.0f32, 0.0f64, 0usize);
        for track in &corpus.train {
            let positions = track.motion.positions();
            let solved = Motion::from_local_poses(skeleton.clone(), track.motion.fps, solve_local_poses(&skeleton, positions));
            for (a, b) in solved.positions().iter().zip(positions) {
                let d = a.distance(*b) * cm;
                worst = worst.max(d);
                sum += d as f64;
                count += 1;
            }
        }
        println!("{dataset}: {} joints, mean {:.4} cm, worst {worst:.3} cm", skeleton.len(), sum / count as f64);
        assert!(worst <= 1.0, "{dataset}: a real pose misses itself by {worst:.2} cm through the model's skeleton");
    }
}
