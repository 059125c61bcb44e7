//! Joint roles on every dataset's skeleton, foot contacts on real walking, the foot lock on
//! generated takes, and the motion suite's measures on real clips.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;
use glocal::data::archive::DataRoot;
use glocal::data::bvh::read_bvh;
use glocal::data::registry::{expmap_format, Dataset};
use glocal::eval::motion::{longest_repeat, real_pools, BlockGrid, Measure, COMMON_FPS};
use glocal::model::corpus::Corpus;
use glocal::model::glocal::GlocalModel;
use glocal::motion::contacts::{foot_contacts, runs, ContactConfig};
use glocal::motion::{bone_turns, JointRoles, Motion, Side, Skeleton};
use glocal::synth::{generate, GenerateOptions, InitPose};

fn data() -> DataRoot {
    DataRoot::resolve(None)
}

fn model_dir(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)
}

fn model(name: &str) -> GlocalModel {
    GlocalModel::load(&model_dir(name)).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

/// The largest turn (degrees) of `joint`'s bone in one frame of `take`.
fn largest_turn(take: &Motion, joint: usize) -> f32 {
    let (_, turns) = bone_turns(take).into_iter().find(|(j, _)| *j == joint).expect("the bone is long enough to have a direction");
    turns.into_iter().fold(0.0, f32::max)
}

/// One file of a dataset archive, as text.
fn archive_text(dataset: &str, file: &str) -> String {
    let files = data().read_archive(dataset, |p| p == file).unwrap_or_else(|e| panic!("{dataset}: {e:#}"));
    let (_, bytes) = files.into_iter().next().unwrap_or_else(|| panic!("{file} is not in {dataset}"));
    String::from_utf8(bytes).unwrap()
}

fn h36m_clip(file: &str) -> Motion {
    let format = expmap_format(Dataset::H36m, &data()).unwrap();
    format.read(&archive_text("h36m", file), file).unwrap()
}

fn names(s: &Skeleton, joints: &[usize]) -> Vec<String> {
    joints.iter().map(|&j| s.names()[j].clone()).collect()
}

#[test]
fn roles_on_every_dataset_skeleton() {
    let h36m = expmap_format(Dataset::H36m, &data()).unwrap().skeleton;
    let r = JointRoles::new(&h36m).unwrap();
    assert_eq!(names(&h36m, &[r.body_root, r.left.hip, r.left.knee, r.left.ankle, r.left.toe.unwrap()]), ["Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"]);
    assert_eq!(names(&h36m, &[r.right.toe_end.unwrap(), r.head, r.head_end.unwrap(), r.left_hand, r.right_hand]), ["RightToeSite", "Head", "HeadSite", "LeftHand", "RightHand"]);

    let bandai = read_bvh(&archive_text("bandai", "bandai/data/dataset-1_walk_normal_001.bvh"), "walk").unwrap().skeleton;
    let r = JointRoles::new(&bandai).unwrap();
    assert_eq!(names(&bandai, &[r.body_root, r.left.hip, r.left.knee, r.left.ankle, r.left.toe.unwrap()]), ["Hips", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L"]);
    assert_eq!(names(&bandai, &[r.right.hip, r.head, r.left_hand, r.right_hand]), ["UpperLeg_R", "Head", "Hand_L", "Hand_R"]);

    // CMU BVH: lThigh / rShin style names, and no toe joint.
    let cmu = read_bvh(&archive_text("cmu-dance", "cmu-dance/standard.bvh"), "standard").unwrap().skeleton;
    let r = JointRoles::new(&cmu).unwrap();
    assert_eq!(names(&cmu, &[r.body_root, r.left.hip, r.left.knee, r.left.ankle, r.right.hip, r.head, r.left_hand]), ["hip", "lThigh", "lShin", "lFoot", "rThigh", "head", "lHand"]);
    assert_eq!(r.left.toe, None);

    // The CMU exponential maps have no names: the shape finds the legs (joints 2-6 on +x,
    // the side of up x the toes' direction, so the left), the arms and the head.
    let cmu_expmap = expmap_format(Dataset::CmuExpmap, &data()).unwrap().skeleton;
    let r = JointRoles::new(&cmu_expmap).unwrap();
    assert_eq!((r.left.hip, r.left.knee, r.left.ankle, r.left.toe, r.left.toe_end), (2, 3, 4, Some(5), Some(6)));
    assert_eq!((r.right.hip, r.right.ankle), (8, 10));
    assert_eq!((r.left_hand, r.right_hand, r.head), (23, 32, 19));
}

#[test]
fn missing_roles_are_named() {
    let s = Skeleton::new(
        vec!["Hips".into(), "Spine".into(), "Head".into()],
        vec![None, Some(0), Some(1)],
        vec![Vec3::ZERO, Vec3::new(0.0, 30.0, 0.0), Vec3::new(0.0, 30.0, 0.0)],
        0.01,
    )
    .unwrap();
    let e = JointRoles::new(&s).unwrap_err().to_string();
    for role in ["body root", "left hip", "right knee", "left hand"] {
        assert!(e.contains(role), "{e}");
    }
    assert!(!e.contains("head"), "{e}");
}

/// S11 walking at 50 fps: the detector's contacts are where the feet really stand. Walking
/// has no flight phase, so some foot stands almost always; each foot stands 50-80% of the
/// time (stance is about 60% of a gait cycle) in one phase per step; and a detected stance
/// foot's toe really stays put (under 5 cm of travel over the phase, where the swing foot
/// travels a stride).
#[test]
fn contacts_on_real_walking() {
    let clip = h36m_clip("h36m/S11/walking_1.txt");
    let m = clip.slice(0, 500);
    let roles = JointRoles::new(&m.skeleton).unwrap();
    let c = foot_contacts(&m, &roles, &ContactConfig::default());
    let supported = (0..m.frames()).filter(|&t| c.left[t] || c.right[t]).count() as f32 / m.frames() as f32;
    assert!(supported > 0.95, "some foot stands in {supported:.2} of the frames");
    for side in Side::BOTH {
        let flags = c.side(side);
        let fraction = flags.iter().filter(|&&f| f).count() as f32 / flags.len() as f32;
        assert!((0.5..0.8).contains(&fraction), "{side:?} stands {fraction:.2} of the time");
        let phases = runs(flags);
        // 10 s of walking at about one stride a second.
        assert!((7..=13).contains(&phases.len()), "{side:?}: {} stance phases", phases.len());
        // Speeds (m/s, horizontal) of the foot's slowest joint in stance and of the toe in swing.
        let foot = roles.leg(side).foot_joints(&m.skeleton);
        let unit = m.skeleton.meters_per_unit();
        let flat_speed = |t: usize, j: usize| {
            let d = m.frame(t + 1)[j] - m.frame(t)[j];
            Vec3::new(d.x, 0.0, d.z).length() * unit * m.fps
        };
        let (mut stance, mut swing) = (Vec::new(), Vec::new());
        for t in 0..m.frames() - 1 {
            if flags[t] {
                stance.push(foot.iter().map(|&j| flat_speed(t, j)).fold(f32::INFINITY, f32::min));
            } else {
                swing.push(flat_speed(t, roles.leg(side).toe.unwrap()));
            }
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        assert!(mean(&stance) < 0.1, "{side:?}: the standing foot moves {:.3} m/s", mean(&stance));
        assert!(mean(&swing) > 1.0, "{side:?}: the swinging toe moves only {:.3} m/s", mean(&swing));
    }
}

/// A generated walking take after the foot lock, on both models: each stance foot stays
/// within 1 cm over its stance phase (its heel may lift at the end), its lowest joint on the floor (no floating, no penetration anywhere),
/// bone lengths exact; and the lock leaves far less slide than the network's own take.
#[test]
fn foot_lock_plants_generated_walking() {
    for (name, class) in [("h36m", "walking"), ("bandai", "walk")] {
        let m = model(name);
        assert!(m.spec.foot_lock, "{name} locks its feet by default");
        let opts = GenerateOptions { timeline: format!("{class}:8").parse().unwrap(), init: InitPose::SeedClass { class: class.into(), variant: 0 }, seed: 1, variation: 0.05, ..Default::default() };
        assert!(opts.foot_lock, "the foot lock is on by default");
        let g = generate(&m, &opts, &mut |_| true).unwrap();
        let motion = &g.motion;
        let unit = motion.skeleton.meters_per_unit();
        let roles = JointRoles::new(&motion.skeleton).unwrap();
        assert_eq!(g.contacts.left.len(), motion.frames());
        let rest = motion.skeleton.rest_bone_lengths();
        for t in 0..motion.frames() {
            for (j, length) in motion.bone_lengths(t).iter().enumerate() {
                assert!((length - rest[j]).abs() * unit < 1e-5, "{name}: bone {j} at frame {t}: {length} against {}", rest[j]);
            }
        }
        let floor = motion.floor_height();
        for side in Side::BOTH {
            let foot = roles.leg(side).foot_joints(&motion.skeleton);
            let phases = runs(g.contacts.side(side));
            // At least a few steps to judge (a take can have stretches with both feet in the air).
            assert!(phases.len() >= 3, "{name} {side:?}: {} stance phases in 8 s of walking", phases.len());
            // Planted is what touches the floor: the toe never moves, and the ankle stays put
            // until the heel lifts at the end of the stance (a leg that would snap straight
            // turns the foot about its toe).
            let toe = roles.leg(side).toe.expect("both models' legs have toes");
            for std::ops::Range { start, end } in phases {
                for t in start..end {
                    for &j in &foot {
                        let moved = motion.frame(t)[j].distance(motion.frame(start)[j]) * unit;
                        let lifted = (motion.frame(t)[j].y - motion.frame(start)[j].y) * unit;
                        let on_floor = j == toe || lifted < 0.005;
                        assert!(!on_floor || moved < 0.01, "{name} {side:?}: joint {j} moved {moved:.4} m (up {lifted:.4}) by frame {t} of stance {start}..{end}");
                    }
                    let lowest = foot.iter().map(|&j| motion.frame(t)[j].y).fold(f32::INFINITY, f32::min);
                    assert!((lowest - floor).abs() * unit < 0.005, "{name} {side:?}: stance foot {:.3} m off the floor at {t}", (lowest - floor) * unit);
                }
            }
        }
        let unlocked = generate(&m, &GenerateOptions { foot_lock: false, ..opts }, &mut |_| true).unwrap();
        let slide = |m: &Motion| {
            let mut pool = glocal::eval::motion::Pool::default();
            pool.add_take(&m.resample(COMMON_FPS), &roles, None);
            pool.summary()[Measure::SupportSpeedMedian]
        };
        let (before, after) = (slide(&unlocked.motion), slide(motion));
        assert!(after < 0.5 * before, "{name}: support point {after:.1} cm/s with the lock, {before:.1} without");
    }
}

/// Bandai's real test split through the suite's measures: the figures real motion has
/// (feet on the floor almost always, planted feet nearly still, a flat block-phase
/// profile, no exact repeats); and a real clip played twice is found repeating at its length.
#[test]
fn suite_measures_reproduce_real_figures() {
    let corpus = Corpus::load(Dataset::Bandai, &data(), 3, 3).unwrap();
    let roles = JointRoles::new(&corpus.layout.skeleton).unwrap();
    let pools = real_pools(&corpus, &roles, BlockGrid::new(10, 3, 30.0), 10.0);
    let at = |class: &str, m: Measure| pools[corpus.classes.iter().position(|c| c == class).unwrap()].summary()[m];
    for class in ["walk", "bow", "bye", "guide"] {
        assert!(at(class, Measure::ContactFraction) > 0.95, "{class}: contact {}", at(class, Measure::ContactFraction));
        assert!(at(class, Measure::Floating) < 0.05, "{class}: floating {}", at(class, Measure::Floating));
        assert!((0.8..1.25).contains(&at(class, Measure::SeamRatio)), "{class}: seam ratio {}", at(class, Measure::SeamRatio));
        assert_eq!(at(class, Measure::LongestRepeat), 0.0, "{class}: real motion repeats");
    }
    for class in ["bow", "bye", "guide"] {
        assert!(at(class, Measure::SupportSpeedMedian) < 2.0, "{class}: a standing support point moves {} cm/s", at(class, Measure::SupportSpeedMedian));
        assert!(at(class, Measure::SkatingRatio) < 0.15, "{class}: skating {}", at(class, Measure::SkatingRatio));
    }
    let walk = at("walk", Measure::SkatingRatio);
    assert!((0.05..0.5).contains(&walk), "walk: skating {walk}");
    assert!((0.8..1.6).contains(&at("walk", Measure::JointSpeed)), "walk: joint speed {}", at("walk", Measure::JointSpeed));

    let clip = corpus.test.iter().find(|t| corpus.classes[t.class] == "bow").unwrap().motion.resample(COMMON_FPS);
    let twice: Vec<Vec3> = clip.positions().iter().chain(clip.positions()).copied().collect();
    let twice = Motion::from_positions(Arc::new((*clip.skeleton).clone()), COMMON_FPS, twice);
    let (seconds, lag) = longest_repeat(&twice);
    assert!((lag - clip.seconds()).abs() < 0.05, "lag {lag} s against a {} s clip", clip.seconds());
    assert!(seconds > 0.9 * clip.seconds(), "repeat of {seconds} s");
}

/// The JSON export carries the per-foot contact arrays of a generated take.
#[test]
fn json_export_has_contacts() {
    let m = model("h36m");
    let g = generate(&m, &GenerateOptions { timeline: "walking:3".parse().unwrap(), ..Default::default() }, &mut |_| true).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("take.json");
    glocal::synth::export::export_with_contacts(&g.motion, &g.segments, Some(&g.contacts), &path).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let left: Vec<bool> = serde_json::from_value(json["contacts"]["left_foot"].clone()).unwrap();
    assert_eq!(left, g.contacts.left);
    assert_eq!(json["contacts"]["right_foot"].as_array().unwrap().len(), g.motion.frames());
    let (back, _) = glocal::synth::export::read_take(&path, None).unwrap();
    assert_eq!(back.frames(), g.motion.frames());
}

/// The foot lock on a real CMU dance clip, whose BVH skeleton has no toes: the lock still
/// runs (contacts from ankles alone, no heel lift), keeps bone lengths, and leaves each knee
/// on the side it bent to in the clip wherever it clearly bent (the knee's forward direction
/// then comes from the knees themselves, not from toes).
#[test]
fn foot_lock_keeps_knees_on_a_skeleton_without_toes() {
    let clip = read_bvh(&archive_text("cmu-dance", "cmu-dance/indian/04.bvh"), "indian/04").unwrap();
    let m = clip.slice(0, clip.frames().min(1200));
    let roles = JointRoles::new(&m.skeleton).unwrap();
    assert_eq!(roles.left.toe, None);
    let locked = glocal::synth::foot_lock::foot_lock(m.clone(), true, &glocal::synth::foot_lock::Travel::FromFeet { kept: Vec::new() }).unwrap().motion;
    let unit = m.skeleton.meters_per_unit();
    let rest = m.skeleton.rest_bone_lengths();
    let (mut bent, mut kept) = (0, 0);
    for t in 0..m.frames() {
        for (j, length) in locked.bone_lengths(t).iter().enumerate() {
            assert!((length - rest[j]).abs() * unit < 1e-4, "bone {j} at frame {t}: {length} against {}", rest[j]);
        }
        for side in Side::BOTH {
            let leg = roles.leg(side);
            // The knee's offset from its hip-ankle line, in the clip and after the lock.
            let offset = |f: &[Vec3]| {
                let axis = (f[leg.ankle] - f[leg.hip]).normalize_or_zero();
                let k = f[leg.knee] - f[leg.hip];
                k - axis * k.dot(axis)
            };
            let (before, after) = (offset(m.frame(t)), offset(locked.frame(t)));
            if before.length() * unit > 0.03 {
                bent += 1;
                kept += usize::from(before.dot(after) > 0.0);
            }
        }
    }
    assert!(bent > 500, "only {bent} clearly bent knees to judge");
    let share = kept as f32 / bent as f32;
    assert!(share > 0.99, "a knee kept its side in {share:.3} of {bent} clearly bent ones");
}

/// A shuffle between two plants is lifted by its share of an ordinary swing: `all`'s
/// discussion started from its seed 26 steps its right foot 11 cm within its first second,
/// in 0.13 s between two locked stances. With the whole 5 cm swing lift over so short a gap
/// the foot hopped to 115 mm and back in four frames (the network's own foot rose to 75 mm),
/// the knee jerking at 9x the unlocked take's peak; now the locked foot rises no higher
/// than the network's own.
#[test]
fn a_shuffle_step_does_not_hop() {
    let m = model("all");
    let ankle = m.spec.layout.skeleton.index_of("RightFoot").unwrap();
    let highest = |foot_lock: bool| {
        let opts = GenerateOptions { timeline: "discussion:5".parse().unwrap(), init: InitPose::SeedIndex(26), foot_lock, ..Default::default() };
        let take = generate(&m, &opts, &mut |_| true).unwrap().motion;
        let first = (1.5 * take.fps) as usize;
        (0..first).map(|t| take.frame(t)[ankle].y).fold(f32::MIN, f32::max) * take.skeleton.meters_per_unit()
    };
    let (locked, own) = (highest(true), highest(false));
    println!("right ankle's highest point in the first 1.5 s: {:.0} mm locked, {:.0} mm the network's own", 1000.0 * locked, 1000.0 * own);
    assert!(locked < own + 0.01, "the locked shuffle lifts the ankle to {:.0} mm, the network's own to {:.0} mm", 1000.0 * locked, 1000.0 * own);
}

/// A hand kept above the floor bends its elbow on a side that turns, not flips, where the
/// network's arm passes through straight: `all`'s sittingdown started from its seed 115
/// straightens its right arm for 0.3 s and bends it again the other way with the hand at the
/// floor; the lifted elbow, bent on the side last seen, jumped 18 cm in one frame (9074
/// m/s^3 in the first second, 506 without the lift). Now 4.1 cm, the network's own elbow's
/// largest step 2.9 cm.
#[test]
fn a_lifted_hands_elbow_does_not_flip() {
    let m = model("all");
    let elbow = m.spec.layout.skeleton.index_of("RightForeArm").unwrap();
    let opts = GenerateOptions { timeline: "sittingdown:5".parse().unwrap(), init: InitPose::SeedIndex(115), ..Default::default() };
    let take = generate(&m, &opts, &mut |_| true).unwrap().motion;
    let (step, at) = largest_step(&take, elbow, |_| true);
    println!("the right elbow's largest step: {:.1} cm at frame {at}", 100.0 * step);
    assert!(step < 0.05, "the right elbow moves {:.1} cm between frames {} and {at}", 100.0 * step, at - 1);
}

/// The largest step (metres) `joint` of `take` makes from one frame to the next, among the
/// steps ending on a frame `counted` keeps, and the frame it ends on.
fn largest_step(take: &Motion, joint: usize, counted: impl Fn(usize) -> bool) -> (f32, usize) {
    let unit = take.skeleton.meters_per_unit();
    (1..take.frames()).filter(|&t| counted(t)).map(|t| (take.frame(t)[joint].distance(take.frame(t - 1)[joint]) * unit, t)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
}

/// The largest step of joint `name` ([`largest_step`]) in a take of `timeline` started from
/// seed `seed` of model `model_name`, with the feet locked and without.
fn largest_steps(model_name: &str, timeline: &str, seed: usize, name: &str) -> [(f32, usize); 2] {
    let m = model(model_name);
    let joint = m.spec.layout.skeleton.index_of(name).unwrap();
    [true, false].map(|foot_lock| {
        let opts = GenerateOptions { timeline: timeline.parse().unwrap(), init: InitPose::SeedIndex(seed), foot_lock, ..Default::default() };
        largest_step(&generate(&m, &opts, &mut |_| true).unwrap().motion, joint, |_| true)
    })
}

/// A knee bends the way a knee points on its leg as the leg swings: forwards on a hanging
/// leg, up on one raised in front. Human3.6M's sittingdown started from its
/// seed 117 brings a leg raised in front of the hips down to the floor; the lock's knee was
/// pulled the way the pelvis faces, which on a leg above the horizontal points down, and
/// flipped over as the leg came past it: 8.1 cm in one frame (the network's own knee's
/// largest step 3.1 cm). Now 3.9 cm.
#[test]
fn a_raised_legs_knee_does_not_flip() {
    let [(locked, at), (own, _)] = largest_steps("h36m", "sittingdown:5", 117, "LeftLeg");
    println!("the left knee's largest step: {:.1} cm at frame {at} (the network's own {:.1} cm)", 100.0 * locked, 100.0 * own);
    assert!(locked < 0.05, "the left knee moves {:.1} cm between frames {} and {at}", 100.0 * locked, at - 1);
}

/// A standing foot that slid out of its lock steps over to the next by a lift as long as
/// the step is (6 cm over 20 cm): a straight-legged standing body bends its knee deep for
/// every centimetre a foot rises. Bandai's guide from its seed 132 and `all`'s from its
/// seed 276 replant a foot 10 cm; lifted the whole 6 cm, their knees moved 3.3 and 3.8 cm
/// in one frame (the network's own 0.7); now 2.3 and 2.8.
#[test]
fn a_standing_replant_barely_lifts_the_knee() {
    for (model, seed, knee) in [("bandai", 132, "LowerLeg_R"), ("all", 276, "RightLeg")] {
        let [(locked, at), (own, _)] = largest_steps(model, "guide:5", seed, knee);
        println!("{model} guide from seed {seed}: the knee's largest step {:.1} cm at frame {at} (the network's own {:.1} cm)", 100.0 * locked, 100.0 * own);
        assert!(locked < 0.03, "{model}'s knee moves {:.1} cm between frames {} and {at}", 100.0 * locked, at - 1);
    }
}

/// A planted foot standing on its toes along the leg keeps still: turning the ankle about the
/// toe barely shortens such a leg, so the heel lift asked a large turn for a small change of
/// reach and the ankle jumped within its stance. `all`'s bye from its seed 259 plants its
/// right foot with the ankle 15 cm up, 17 degrees from the line of toe and hip: the ankle
/// moved 3.8 cm in one frame while planted as the hips came 5 mm nearer. Now 0.6 cm at most.
#[test]
fn a_tiptoe_planted_ankle_does_not_pop() {
    let m = model("all");
    let ankle = m.spec.layout.skeleton.index_of("RightFoot").unwrap();
    let opts = GenerateOptions { timeline: "bye:5".parse().unwrap(), init: InitPose::SeedIndex(259), ..Default::default() };
    let take = generate(&m, &opts, &mut |_| true).unwrap();
    let planted = &take.contacts.right;
    let (step, at) = largest_step(&take.motion, ankle, |t| planted[t - 1] && planted[t]);
    println!("the planted right ankle's largest step: {:.2} cm at frame {at}", 100.0 * step);
    assert!(step < 0.01, "the planted right ankle moves {:.1} cm between frames {} and {at}", 100.0 * step, at - 1);
}

/// A planted foot rolls onto its toe before it leaves the floor, as the network's foot does,
/// and the knee after toe-off bends about as fast as the network's. Held flat to the end of
/// its contact, the locked foot was 16 degrees flatter than the network's at its last planted
/// frame over h36m's walking takes from every walking seed, the leg stayed straight and then
/// folded at once: the knee's largest step in the frames after toe-off 1.73x the network's
/// own (the thighs over the real p99.9 turn of 6 degrees a frame). Now 2.6 degrees and
/// 1.26x.
#[test]
fn a_walking_heel_rolls_before_toe_off() {
    let m = model("h36m");
    let walking = m.spec.class_index("walking").unwrap();
    let roles = JointRoles::new(&m.spec.layout.skeleton).unwrap();
    let (mut lag, mut knee_steps, mut toe_offs) = (0.0, [0.0; 2], 0);
    for seed in (0..m.seeds.len()).filter(|&i| m.seeds[i].class == walking) {
        let take = |foot_lock: bool| generate(&m, &GenerateOptions { timeline: "walking:10".parse().unwrap(), init: InitPose::SeedIndex(seed), foot_lock, ..Default::default() }, &mut |_| true).unwrap();
        let [locked, own] = [take(true), take(false)];
        for side in Side::BOTH {
            let leg = roles.leg(side);
            let toe = leg.toe.unwrap();
            let pitch = |m: &Motion, t: usize| (m.frame(t)[leg.ankle] - m.frame(t)[toe]).normalize().y.asin().to_degrees();
            let bend = |m: &Motion, t: usize| (m.frame(t)[leg.hip] - m.frame(t)[leg.knee]).angle_between(m.frame(t)[leg.ankle] - m.frame(t)[leg.knee]).to_degrees();
            let planted = locked.contacts.side(side);
            for off in (1..planted.len() - 4).filter(|&t| planted[t - 1] && !planted[t]) {
                lag += pitch(&own.motion, off - 1) - pitch(&locked.motion, off - 1);
                for (sum, m) in knee_steps.iter_mut().zip([&locked.motion, &own.motion]) {
                    *sum += (off - 1..off + 3).map(|t| (bend(m, t + 1) - bend(m, t)).abs()).fold(0.0, f32::max);
                }
                toe_offs += 1;
            }
        }
    }
    let lag = lag / toe_offs as f32;
    let knee = knee_steps[0] / knee_steps[1];
    println!("{toe_offs} toe-offs: the locked foot {lag:.1} degrees flatter than the network's at its last planted frame; the knee's largest step after toe-off {knee:.2}x the network's");
    assert!(lag < 5.0, "the locked heel lags the network's by {lag:.1} degrees at toe-off");
    assert!(knee < 1.4, "the locked knee's largest step after toe-off is {knee:.2}x the network's");
}

/// Bandai's dash from its seed 32 flicks the right hand 55 degrees in one frame, where
/// Bandai's training clips turn that bone 39 degrees a frame but once in a thousand calm
/// frames (model.json's `bone_turn_limits`); from its seed window 2 the bone projection's
/// bridge of a collapsed forearm turned it 60 after the spread, until the projected take was
/// spread again. Spread, the hand turns within its limit (the projection may add a degree).
#[test]
fn a_hand_snap_is_spread_within_the_training_clips_turn() {
    let m = model("bandai");
    let hand = m.spec.layout.skeleton.index_of("Hand_R").unwrap();
    let limit = m.spec.bone_turn_limits["Hand_R"] / m.spec.fps;
    let seed_frames = m.spec.block_len * m.spec.stride;
    for (timeline, init) in [("dash:10", InitPose::SeedIndex(32)), ("dash:11", InitPose::SeedClass { class: "dash".into(), variant: 2 })] {
        let largest = |spread_snaps: bool| {
            let o = GenerateOptions { timeline: timeline.parse().unwrap(), init: init.clone(), spread_snaps, ..Default::default() }.varied(1);
            let take = generate(&m, &o, &mut |_| true).unwrap().motion;
            largest_turn(&take.slice(seed_frames, take.frames()), hand)
        };
        let (own, spread) = (largest(false), largest(true));
        println!("{timeline} from {init:?}: the right hand's largest turn in one frame {own:.1} degrees as made, {spread:.1} spread (limit {limit:.1})");
        assert!(own > 1.3 * limit, "{timeline}: the take no longer snaps ({own:.1} degrees against {limit:.1}): pick another");
        assert!(spread <= 1.1 * limit, "{timeline}: the spread hand turns {spread:.1} degrees in one frame (limit {limit:.1})");
    }
}

/// Without a texture, h36m's standing and seated classes were half as lively as capture
/// (discussion 0.50x, sitting 0.42x, sitting down 0.27x the test subject's mean jerk: the
/// small motion of a standing person gone, issue 39). Each class's share of the model's
/// texture, calibrated against its training clips, lays it back.
#[test]
fn a_standing_person_keeps_the_small_motion_of_capture() {
    let m = model("h36m");
    assert!(m.texture().is_some(), "models/h36m has no texture.safetensors");
    let corpus = Corpus::for_model(Dataset::H36m, &data(), &m.spec, &model_dir("h36m")).unwrap();
    let roles = JointRoles::new(&corpus.layout.skeleton).unwrap();
    let real = real_pools(&corpus, &roles, None, 10.0);
    let seed_frames = m.spec.block_len * m.spec.stride;
    for class in ["discussion", "sitting"] {
        let jerk = |texture: bool| {
            let mut pool = glocal::eval::motion::Pool::default();
            for variant in 0..3 {
                let o = GenerateOptions { timeline: format!("{class}:10").parse().unwrap(), init: InitPose::SeedClass { class: class.into(), variant }, texture, ..Default::default() }.varied(1);
                let take = generate(&m, &o, &mut |_| true).unwrap().motion;
                pool.add_take(&take.slice(seed_frames, take.frames()).resample(COMMON_FPS), &roles, None);
            }
            pool.summary()[Measure::JerkMean]
        };
        let capture = real[m.spec.class_index(class).unwrap()].summary()[Measure::JerkMean];
        let (plain, textured) = (jerk(false) / capture, jerk(true) / capture);
        println!("{class}: jerk {plain:.2}x the test subject's without the texture, {textured:.2}x with it");
        assert!(plain < 0.6, "{class} is lively without its texture ({plain:.2}x): the test no longer shows what it fixes");
        assert!((0.7..1.5).contains(&textured), "{class}: jerk {textured:.2}x the test subject's with the texture");
    }
}

/// The texture is capture detail of millimetres, which turned the 75 mm toe of h36m's
/// sitting down from the new-project seed 60 degrees in one frame and back in the next: laid
/// so that it turns no bone further than half the training clips' turn in a frame, the toe
/// turns within its limit (17 degrees, 13 without the texture, 29 held at the whole limit;
/// limit 25).
#[test]
fn the_texture_does_not_snap_a_toe() {
    let m = model("h36m");
    let toe = m.spec.layout.skeleton.index_of("LeftToeSite").unwrap();
    let limit = m.spec.bone_turn_limits["LeftToeSite"] / m.spec.fps;
    let largest = |texture: bool| {
        let o = GenerateOptions { timeline: "walking:4,sittingdown:4,sitting:5".parse().unwrap(), init: InitPose::SeedIndex(0), texture, ..Default::default() };
        largest_turn(&generate(&m, &o, &mut |_| true).unwrap().motion, toe)
    };
    let (plain, textured) = (largest(false), largest(true));
    println!("the left toe's largest turn in one frame: {plain:.1} degrees without the texture, {textured:.1} with it (limit {limit:.1})");
    assert!(textured <= limit, "the texture turns the toe {textured:.1} degrees in one frame ({plain:.1} without it, limit {limit:.1})");
}

/// h36m's posing from seed window 82 pivots both feet 106-113 degrees on the spot in its first
/// 2.2 s, turning them near the heel: the lock pivots each planted foot with it where it
/// turned. Held at its anchor's heading, the left foot turned all of it in the swing after,
/// 27 degrees in one frame (10.6 now; the training clips' limit 17.4); turned about the toe,
/// the locked ankles swept 31-35 cm over the floor where the network's moved 12-28 cm (1-7
/// now).
#[test]
fn a_pivoting_foot_turns_while_it_stands() {
    let m = model("h36m");
    let skeleton = &m.spec.layout.skeleton;
    let toe = skeleton.index_of("LeftToeBase").unwrap();
    let limit = m.spec.bone_turn_limits["LeftToeBase"] / m.spec.fps;
    let o = GenerateOptions { timeline: "posing:12".parse().unwrap(), init: InitPose::SeedIndex(82), seed: 1, ..Default::default() };
    let locked = generate(&m, &o, &mut |_| true).unwrap().motion;
    let largest = largest_turn(&locked, toe);
    println!("the left foot's largest turn in one frame: {largest:.1} degrees (limit {limit:.1})");
    assert!(largest <= limit, "the left foot turns {largest:.1} degrees in one frame (limit {limit:.1})");
    let own = generate(&m, &GenerateOptions { foot_lock: false, ..o }, &mut |_| true).unwrap().motion;
    let cm = 100.0 * skeleton.meters_per_unit();
    let path = |take: &Motion, ankle: usize| cm * (1..55).map(|t| (take.frame(t)[ankle] - take.frame(t - 1)[ankle]).with_y(0.0).length()).sum::<f32>();
    for ankle in ["LeftFoot", "RightFoot"] {
        let j = skeleton.index_of(ankle).unwrap();
        let (locked, own) = (path(&locked, j), path(&own, j));
        println!("{ankle} over the pivot: {locked:.1} cm locked, {own:.1} cm the network's own");
        assert!(locked < own, "the locked {ankle} sweeps {locked:.1} cm over the pivot, the network's own {own:.1} cm");
    }
}
