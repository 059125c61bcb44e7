//! The evaluation measures on real data and on cases with known answers: MMD, FID and its
//! matrix square root, the horizon errors of the CMU table, and the action classifier.
//!
//! The Human3.6M clips come from the dataset archive (`GLOCAL_DATA` or `../shared/data`);
//! these tests fail, rather than skip, when it is missing.

use std::sync::OnceLock;

use glam::Vec3;
use glocal::data::archive::DataRoot;
use glocal::data::registry::Dataset;
use glocal::eval::classifier::{real_windows, Classifier, ClassifierConfig};
use glocal::eval::metrics::{self, fid, horizon_errors, mmd2, mmd_avg_seq, sqrtm_symmetric, symmetric_eigen};
use glocal::model::corpus::Corpus;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn h36m() -> &'static Corpus {
    static CORPUS: OnceLock<Corpus> = OnceLock::new();
    CORPUS.get_or_init(|| Corpus::load(Dataset::H36m, &DataRoot::resolve(None), 5, 3).expect("the h36m archive is readable"))
}

/// Root-relative poses (meters) of `frames`-frame windows of one class of the test split.
fn class_sequences(class: &str, frames: usize, count: usize) -> Vec<Vec<f32>> {
    let c = h36m();
    let k = c.classes.iter().position(|x| x == class).expect("class exists");
    let mut out = Vec::new();
    for t in c.test.iter().filter(|t| t.class == k) {
        let m = &t.motion;
        let mut s = 0;
        while s + frames <= m.frames() && out.len() < count {
            let seq: Vec<f32> = (s..s + frames)
                .flat_map(|f| {
                    let fr = m.frame(f);
                    fr.iter().flat_map(move |p| ((*p - fr[0]) * 0.001).to_array()).collect::<Vec<_>>()
                })
                .collect();
            out.push(seq);
            s += frames;
        }
    }
    assert!(out.len() >= 8, "{class}: too few windows ({})", out.len());
    out
}

fn rows(v: &[Vec<f32>]) -> Vec<&[f32]> {
    v.iter().map(|x| x.as_slice()).collect()
}

#[test]
fn mmd_is_near_zero_within_a_class_and_positive_between_classes() {
    let walking = class_sequences("walking", 10, 40);
    let sitting = class_sequences("sitting", 10, 40);
    let n = walking.len().min(sitting.len());
    let (w, s) = (&walking[..n], &sitting[..n]);
    let frame_dim = w[0].len() / 10;
    // A set against itself: the unbiased estimate is within 2/n of zero by construction.
    let (self_avg, self_seq) = mmd_avg_seq(w, w, frame_dim);
    assert!(self_avg.abs() <= 2.0 / n as f64 + 1e-9 && self_seq.abs() <= 2.0 / n as f64 + 1e-9, "self MMD {self_avg} {self_seq}");
    // Two halves of one class are close; two classes are far apart.
    let half = n / 2;
    let within = mmd2(&rows(&w[..half]), &rows(&w[half..2 * half]));
    let between = mmd2(&rows(&w[..half]), &rows(&s[..half]));
    let (avg, seq) = mmd_avg_seq(w, s, frame_dim);
    assert!(between > 0.2, "walking vs sitting MMD {between}");
    assert!(between > 3.0 * within.max(0.0), "between {between}, within {within}");
    assert!(avg > 0.2 && seq > 0.2, "walking vs sitting MMD_avg {avg}, MMD_seq {seq}");
    assert!(avg <= 2.0 + 1e-9 && seq <= 2.0 + 1e-9);
}

#[test]
fn jacobi_eigen_and_square_root_are_exact() {
    let mut rng = StdRng::seed_from_u64(3);
    let d = 12;
    let b: Vec<f64> = (0..d * d).map(|_| rng.random_range(-1.0..1.0)).collect();
    // A = B Bᵀ is symmetric positive semi-definite.
    let a: Vec<f64> = (0..d * d).map(|ij| (0..d).map(|k| b[(ij / d) * d + k] * b[(ij % d) * d + k]).sum()).collect();
    let (w, v) = symmetric_eigen(&a, d);
    for c in 0..d {
        for i in 0..d {
            let av: f64 = (0..d).map(|k| a[i * d + k] * v[k * d + c]).sum();
            assert!((av - w[c] * v[i * d + c]).abs() < 1e-9, "A v != λ v");
        }
    }
    let r = sqrtm_symmetric(&a, d);
    for i in 0..d {
        for j in 0..d {
            let rr: f64 = (0..d).map(|k| r[i * d + k] * r[k * d + j]).sum();
            assert!((rr - a[i * d + j]).abs() < 1e-8, "sqrt(A)² != A at {i},{j}");
        }
    }
}

#[test]
fn fid_of_identical_sets_is_zero_and_a_shift_costs_its_square() {
    let mut rng = StdRng::seed_from_u64(5);
    let x: Vec<Vec<f32>> = (0..300).map(|_| (0..16).map(|_| rng.random_range(-1.0f32..1.0)).collect()).collect();
    assert!(fid(&x, &x) < 1e-6, "FID(x, x) = {}", fid(&x, &x));
    let shifted: Vec<Vec<f32>> = x.iter().map(|r| r.iter().map(|v| v + 0.5).collect()).collect();
    let expected = 16.0 * 0.25;
    assert!((fid(&x, &shifted) - expected).abs() < 1e-3, "FID under a shift: {}", fid(&x, &shifted));
    // Scaling by 2: Σ₂ = 4Σ₁, so the trace term is tr(Σ₁ + 4Σ₁ − 4Σ₁) = tr(Σ₁).
    let scaled: Vec<Vec<f32>> = x.iter().map(|r| r.iter().map(|v| 2.0 * v).collect()).collect();
    let (_, cov) = metrics::mean_cov(&x);
    let tr: f64 = (0..16).map(|i| cov[i * 16 + i]).sum();
    let (m, _) = metrics::mean_cov(&x);
    let mean_term: f64 = m.iter().map(|v| v * v).sum();
    assert!((fid(&x, &scaled) - (tr + mean_term)).abs() < 1e-6 * tr.max(1.0), "FID under scaling");
}

#[test]
fn horizon_errors_on_a_known_motion() {
    // One joint moving 1 unit per frame along x at 30 fps, frame 0 the last observed pose.
    let truth: Vec<Vec3> = (0..=20).map(|f| Vec3::new(f as f32, 0.0, 0.0)).collect();
    let still = vec![Vec3::ZERO];
    let e = horizon_errors(&still, &truth, 1, 30.0, 30.0);
    for (k, ms) in metrics::HORIZONS_MS.iter().enumerate() {
        assert!((e[k] - *ms as f64 * 0.03).abs() < 1e-4, "zero-velocity at {ms} ms: {}", e[k]);
    }
    // The same motion sampled every second frame (15 fps), as GloGen's sparse poses are.
    let sparse: Vec<Vec3> = (0..=10).map(|k| Vec3::new(2.0 * k as f32, 0.0, 0.0)).collect();
    assert!(horizon_errors(&sparse, &truth, 1, 15.0, 30.0).iter().all(|v| *v < 1e-4));
    // Two joints, one off by 3 units: the mean over joints is 1.5.
    let a = [Vec3::ZERO, Vec3::ZERO];
    let b = [Vec3::ZERO, Vec3::new(0.0, 3.0, 4.0) * 0.6];
    assert!((metrics::pose_error(&a, &b) - 1.5).abs() < 1e-6);
}

#[test]
fn diversity_and_multimodality_follow_their_definitions() {
    // Two classes, each a single point: multimodality 0, diversity half the pairs cross.
    let f: Vec<Vec<f32>> = (0..100).map(|i| vec![if i % 2 == 0 { 0.0 } else { 2.0 }]).collect();
    let labels: Vec<usize> = (0..100).map(|i| i % 2).collect();
    assert_eq!(metrics::multimodality(&f, &labels, 2, 20, 1), 0.0);
    let d = metrics::diversity(&f, 100, 1);
    assert!(d > 0.5 && d < 1.5, "diversity {d}");
    assert_eq!(metrics::accuracy(&[0, 1, 1, 0], &[0, 1, 0, 0]), 0.75);
}

#[test]
fn a_small_classifier_beats_chance_on_the_h36m_test_split() {
    let corpus = h36m();
    let cfg = ClassifierConfig { hidden: 48, frames: 30, steps: 300, batch: 16, lr: 3e-3, seed: 1 };
    let clf = Classifier::train(corpus, &cfg, &mut |m| eprintln!("{m}")).expect("training runs");
    let chance = 1.0 / corpus.classes.len() as f64;
    assert!(clf.record.test_windows >= 100, "{} test windows", clf.record.test_windows);
    assert!(clf.record.test_accuracy > 2.0 * chance, "test accuracy {} vs chance {chance}", clf.record.test_accuracy);
    // Its features feed FID: the real test windows against themselves give 0.
    let (_, clips): (Vec<usize>, Vec<Vec<f32>>) = real_windows(&corpus.layout, &corpus.test, corpus.classes.len(), cfg.frames, cfg.frames, 20).into_iter().unzip();
    let feats = clf.features(&clips).unwrap();
    assert_eq!(feats[0].len(), cfg.hidden);
    assert!(fid(&feats, &feats) < 1e-6);
}

/// Issue 13's acceptance with the shipped h36m model, through the suite itself: from another
/// class's poses the requested class wins after a 2 s transition (at least 80%, and no more
/// than 10 points under the classifier's accuracy on real clips), same-class starts stay
/// within 5 points of it, FID within 3x of the real split-to-split FID, and repeated takes
/// differ. The paper's mechanism alone (`Transition::Cut`) fails the first of these (26%).
#[test]
fn class_control_holds_on_h36m() {
    let ctx = glocal::eval::SuiteContext::new(glocal::eval::SuiteOptions::default()).expect("the shipped models are readable");
    let report = glocal::eval::run_suite(glocal::eval::Suite::H36m, &ctx, &mut |m| eprintln!("{m}")).expect("the h36m suite runs");
    let j = &report.json;
    let real_accuracy = j["real_test"]["accuracy"].as_f64().unwrap();
    let real_fid = j["real_test"]["fid"].as_f64().unwrap();
    let scores = |start: &str| {
        let c = j["class_control"].as_array().unwrap().iter().find(|c| c["start"] == start && c["transition_s"].as_f64() == Some(2.0)).unwrap();
        (c["scores"]["accuracy"].as_f64().unwrap(), c["scores"]["fid"].as_f64().unwrap(), c["scores"]["multimodality"].as_f64().unwrap())
    };
    for start in ["OtherSeed", "PreviousSegment"] {
        let (accuracy, fid, multimodality) = scores(start);
        assert!(accuracy >= 0.8 && accuracy >= real_accuracy - 0.10, "{start}: accuracy {accuracy} (real clips {real_accuracy})");
        assert!(fid <= 3.0 * real_fid, "{start}: FID {fid} against the real {real_fid}");
        assert!(multimodality > 1.0, "{start}: multimodality {multimodality}");
    }
    let (same, _, _) = scores("SameClass");
    assert!(same >= real_accuracy - 0.05, "same-class accuracy {same} (real clips {real_accuracy})");
}

/// Issue 34's in-betweening on both shipped models, through the suite itself (takes started
/// from held-out clips, keyed a gap later with the clip's own frame): the in-betweener fills
/// gaps of 1 s and 2 s closer to the real frames than linear interpolation, in the world and
/// relative to the root, with the real rhythm at 2 s (NPSS), and (on Bandai) a 6-frame gap
/// within 1.5x of it. Reached by the sparse warp alone, every keyed gap lost to it in global
/// L2P (h36m 2 s: 13.30 against 11.30 cm).
#[test]
fn keyed_gaps_beat_linear_interpolation() {
    let ctx = glocal::eval::SuiteContext::new(glocal::eval::SuiteOptions::default()).expect("the shipped models are readable");
    let report = glocal::eval::run_suite(glocal::eval::Suite::Inbetween, &ctx, &mut |m| eprintln!("{m}")).expect("the inbetween suite runs");
    for model in report.json["models"].as_array().unwrap() {
        let name = model["model"].as_str().unwrap();
        for row in model["gaps"].as_array().unwrap() {
            let gap = row["gap"].as_str().unwrap();
            let score = |way: &str, what: &str| row[way][what].as_f64().unwrap();
            let (global, root, npss) = (score("keyed", "l2p_global_cm"), score("keyed", "l2p_root_cm"), score("keyed", "npss"));
            let (linear_global, linear_root, linear_npss) = (score("linear", "l2p_global_cm"), score("linear", "l2p_root_cm"), score("linear", "npss"));
            eprintln!("{name} {gap}: global {global:.2} / {linear_global:.2}, root-relative {root:.2} / {linear_root:.2}, NPSS {npss:.3} / {linear_npss:.3}");
            if gap.ends_with("frames") {
                // h36m's given poses and keys come out up to 4.7 cm off on its 27-joint
                // skeleton (docs/DESIGN.md, "Keys from files"), more than a 6-frame gap's
                // whole error (1.8 against 0.9 cm); Bandai's come out exact.
                if name == "bandai" {
                    assert!(global <= 1.5 * linear_global, "{name} {gap}: {global:.2} cm against linear {linear_global:.2}");
                }
                continue;
            }
            assert!(global < linear_global && root < linear_root, "{name} {gap}: {global:.2} / {root:.2} cm against linear {linear_global:.2} / {linear_root:.2}");
            if gap == "2 s" {
                assert!(npss < linear_npss, "{name} {gap}: NPSS {npss:.3} against linear {linear_npss:.3}");
            }
        }
    }
}

/// The studio's own model forecasting CMU's held-out clips (issue 39's CMU line, read on the
/// shipped `models/all` rather than a GloGen trained per CMU set), through the cmu-euclid
/// suite with nothing trained in its cache: the suite runs, says which of its own GloGens and
/// baselines are not trained, and the shipped GloGen beats holding the last pose on Walking,
/// Indian Dance and Martial Arts at every horizon. (Martial Arts at 80 ms was the closest,
/// 56.3 against 55.6 mm, while the first step after given motion was GloGen's own; with six
/// tenths of that motion's own step it reads 40.0, and the closest is Martial Arts at 640
/// ms, 322.7 against 357.0; docs/RESULTS.md.)
#[test]
fn the_shipped_model_forecasts_cmu_better_than_holding_the_pose() {
    let cache = tempfile::tempdir().unwrap();
    let options = glocal::eval::SuiteOptions { cache: cache.path().to_path_buf(), ..Default::default() };
    let ctx = glocal::eval::SuiteContext::new(options).expect("the shipped models are readable");
    let report = glocal::eval::run_suite(glocal::eval::Suite::CmuEuclid, &ctx, &mut |m| eprintln!("{m}")).expect("the cmu-euclid suite runs untrained");
    let untrained = report.json["tables"].as_array().unwrap().iter().flat_map(|t| t["rows"].as_array().unwrap()).filter(|r| r["method"].as_str().unwrap().contains("not trained")).count();
    assert!(untrained > 0, "no row says its method is not trained, with an empty cache");
    let shipped = report.json["shipped_all"].as_array().unwrap();
    assert_eq!(shipped.len(), 3);
    for motion in shipped {
        let errors = |key: &str| -> Vec<f64> { motion[key].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect() };
        let (zero, glogen) = (errors("zero_velocity_m"), errors("glogen_m"));
        eprintln!("{}: GloGen {glogen:.4?} against zero-velocity {zero:.4?} m", motion["motion"]);
        for (k, (g, z)) in glogen.iter().zip(&zero).enumerate() {
            assert!(g < z, "{} at {} ms: {g:.4} m against zero-velocity's {z:.4}", motion["motion"], metrics::HORIZONS_MS[k]);
        }
    }
}
