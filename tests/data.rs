//! The foundation's acceptance on the real datasets: exact counts, constant bone lengths,
//! readers that name the file and the problem.

use glocal::data::archive::DataRoot;
use glocal::data::registry::{self, Dataset, DatasetClips};
use glocal::model::corpus::Corpus;

fn load(d: Dataset) -> DatasetClips {
    registry::load(d, &DataRoot::resolve(None)).unwrap_or_else(|e| panic!("{d}: {e:#}"))
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
    let err = format!("{:#}", registry::load(Dataset::Bandai, &root).unwrap_err());
    assert!(err.contains("bandai.tar.zst") && err.contains("missing"), "{err}");

    // A copy with one byte changed fails its checksum.
    let shared = DataRoot::resolve(None);
    std::fs::copy(shared.file("SHA256SUMS"), dir.path().join("SHA256SUMS")).unwrap();
    let mut bytes = std::fs::read(shared.file("bandai.tar.zst")).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0xff;
    std::fs::write(dir.path().join("bandai.tar.zst"), bytes).unwrap();
    let err = format!("{:#}", registry::load(Dataset::Bandai, &root).unwrap_err());
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
