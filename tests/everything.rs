//! The model of everything (`models/all`, issue 35): one model of every activity of the four
//! datasets on the standard humanoid, with styles.

use std::path::{Path, PathBuf};

use glocal::eval::constraints::frame_jerk;
use glocal::eval::motion::{Measure, Pool, COMMON_FPS};
use glocal::model::corpus::mean_joint_speed;
use glocal::model::glocal::GlocalModel;
use glocal::motion::{standard_humanoid, JointRoles};
use glocal::synth::class_map::ClassMap;
use glocal::synth::{generate, GenerateOptions, InitPose, Key, KeySource, Timeline};

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)
}

fn take(model: &GlocalModel, timeline: &str, init_class: &str) -> glocal::motion::Motion {
    let opts = GenerateOptions { timeline: timeline.parse::<Timeline>().unwrap(), init: InitPose::SeedClass { class: init_class.into(), variant: 0 }, ..Default::default() }.varied(3);
    generate(model, &opts, &mut |_| true).unwrap_or_else(|e| panic!("{timeline}: {e:#}")).motion
}

/// Mean distance (m) between the joints of two takes of the same length.
fn mean_distance(a: &glocal::motion::Motion, b: &glocal::motion::Motion) -> f32 {
    let n = a.positions().len().min(b.positions().len());
    a.positions()[..n].iter().zip(&b.positions()[..n]).map(|(p, q)| p.distance(*q)).sum::<f32>() / n as f32
}

#[test]
fn the_model_of_everything_has_every_activity_and_the_styles_on_the_standard_humanoid() {
    let model = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    let spec = &model.spec;
    assert!(spec.classes.len() >= 25, "{:?}", spec.classes);
    assert_eq!(spec.class_sources.len(), spec.classes.len());
    assert_eq!(spec.styles.len(), 16, "Bandai's 15 styles and neutral: {:?}", spec.styles);
    assert_eq!(spec.source_skeleton.names(), standard_humanoid().names());
    let size: u64 = ["glogen.safetensors", "locgen.safetensors"].iter().map(|f| std::fs::metadata(shipped("all").join(f)).unwrap().len()).sum();
    assert!(size < 20 << 20, "checkpoints of {size} bytes");
    // A project made on either shipped model keeps its activities by name.
    for other in ["h36m", "bandai"] {
        let from = GlocalModel::load(&shipped(other)).unwrap().spec.classes;
        let map = ClassMap::build(&from, &spec.classes, &ClassMap::shipped_table());
        let lost: Vec<_> = map.pairs.iter().filter(|p| !p.to.starts_with(&p.from)).collect();
        assert!(lost.is_empty(), "{other}: {lost:?}");
    }
}

/// A style changes the take: the same walk from the same seed and noise is repeatable in one
/// style and another in the other (happy and sad 2 cm apart on average at least); and an
/// activity of each dataset follows another in one take.
#[test]
fn styles_change_the_take_and_activities_of_every_dataset_follow_each_other() {
    let model = GlocalModel::load(&shipped("all")).unwrap();
    let happy = take(&model, "walking/happy:4", "walking");
    let sad = take(&model, "walking/sad:4", "walking");
    let again = take(&model, "walking/happy:4", "walking");
    let apart = mean_distance(&happy, &sad);
    println!("happy against sad: {apart:.3} m apart; happy twice: {:.4} m", mean_distance(&happy, &again));
    assert_eq!(mean_distance(&happy, &again), 0.0, "a take is repeatable");
    assert!(apart > 0.02, "happy and sad walks are {apart} m apart");
    let mixed = take(&model, "sitting:3,salsa:3,bow/proud:2,basketball:3", "sitting");
    assert!(mixed.positions().iter().all(|p| p.is_finite()));
    assert!(mixed.seconds() > 10.0);
}

/// A style asked for by name keeps the pace of its clips (model.json's `style_speed`): a
/// network's byebye moves about 2x between styles whose clips differ 35x (before, from 6 s
/// on: active 0.42x its clips' speed, normal 2.3x, proud 2.9x; feminine 3.8x and sad 1.7x
/// until a styled segment's blocks were scaled down to its pace, feminine 1.60x when its
/// class's texture grew until a calm style took its own share of it; now 1.27x and 1.34x).
#[test]
fn a_style_asked_for_keeps_the_pace_of_its_clips() {
    let model = GlocalModel::load(&shipped("all")).unwrap();
    for style in ["active", "normal", "proud", "feminine", "sad"] {
        let wave = take(&model, &format!("byebye/{style}:12"), "byebye");
        let settled = wave.slice((6.0 * wave.fps) as usize, wave.frames());
        let clips = model.spec.style_speed["byebye"][style];
        let ratio = mean_joint_speed(&settled) / clips;
        println!("byebye/{style}: {ratio:.2}x its clips' speed from 6 s on");
        assert!((0.6..=1.6).contains(&ratio), "byebye/{style} at {ratio:.2}x its clips' speed");
    }
}

/// A class the calibration gave its own guidance (`glocal calibrate`; `all`'s CMU dances and
/// sports came out damped at the model's 1.5) is made with it: its take is the one the same
/// strength asked for take-wide makes, and not the one the model's own makes.
#[test]
fn a_calibrated_class_is_made_with_its_own_guidance() {
    let model = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    let spec = &model.spec;
    let salsa = spec.class_index("salsa").unwrap();
    let own = spec.class_strength_of(salsa);
    assert!(own > spec.class_strength, "salsa's guidance {own} against the model's {}", spec.class_strength);
    let with = |strength: Option<f32>| {
        let opts = GenerateOptions { timeline: "salsa:4".parse().unwrap(), init: InitPose::SeedClass { class: "salsa".into(), variant: 0 }, class_strength: strength, ..Default::default() }.varied(3);
        generate(&model, &opts, &mut |_| true).unwrap().motion
    };
    let calibrated = with(None);
    assert_eq!(mean_distance(&calibrated, &with(Some(own))), 0.0);
    assert!(mean_distance(&calibrated, &with(Some(spec.class_strength))) > 0.01);
}

/// Bandai's classes in `all` are carried by their feet (`carry_by_feet`): with the travel
/// kept, its dash's support point slid over the floor at a median 104 cm/s (the real clips'
/// 10), which the lock alone could not hold without the body gliding on; carried, 33.
#[test]
fn the_dash_of_everything_is_carried_by_its_feet() {
    let carried = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(carried.spec.carry_by_feet, "models/all/model.json: carry_by_feet");
    let mut kept = GlocalModel::load(&shipped("all")).unwrap();
    kept.spec.carry_by_feet = false;
    // As the motion suite takes them: every seed window of the class (the first are its
    // fastest styles), 10 s after the seed block.
    let support = |model: &GlocalModel| {
        let spec = &model.spec;
        let roles = JointRoles::new(&spec.layout.skeleton).unwrap();
        let dash = spec.class_index("dash").unwrap();
        let seed_frames = spec.block_len * spec.stride;
        let mut pool = Pool::default();
        for variant in 0..model.seeds.iter().filter(|s| s.class == dash).count() {
            let opts = GenerateOptions { timeline: "dash:11".parse().unwrap(), init: InitPose::SeedClass { class: "dash".into(), variant }, ..Default::default() }.varied(1);
            let m = generate(model, &opts, &mut |_| true).unwrap().motion;
            pool.add_take(&m.slice(seed_frames, m.frames()).resample(COMMON_FPS), &roles, None);
        }
        pool.summary()[Measure::SupportSpeedMedian]
    };
    let (carried, kept) = (support(&carried), support(&kept));
    eprintln!("dash support-point speed, median: carried {carried:.1} cm/s, travel kept {kept:.1} cm/s");
    assert!(carried < 50.0 && carried < 0.5 * kept, "carried {carried:.1} cm/s against {kept:.1} with the travel kept");
}

/// Human3.6M's walking, and `all`'s, mostly Human3.6M's, went round in circles of about a
/// metre's radius (its subjects walked round their room): a travelling class keeps its course
/// (`hold_course`), so a 10 s walk from walking's first and last seed windows (on `all`,
/// Human3.6M's and Bandai's) ends at least 0.9 of its path's length after the seed block from
/// where that path started,
/// where without the course it ends within half; a class that only moves about (salsa) is
/// made as before.
#[test]
fn a_walk_keeps_its_course() {
    for name in ["all", "h36m"] {
        let model = GlocalModel::load(&shipped(name)).unwrap_or_else(|e| panic!("{e:#}"));
        assert!(model.spec.hold_course, "models/{name}/model.json: hold_course");
        let metres = model.spec.layout.skeleton.meters_per_unit();
        let walking = model.spec.class_index("walking").unwrap();
        let seeds: Vec<usize> = model.seeds.iter().enumerate().filter(|(_, s)| s.class == walking).map(|(i, _)| i).collect();
        let hips_path = |timeline: &str, init: InitPose, hold_course: bool| {
            let opts = GenerateOptions { timeline: timeline.parse().unwrap(), init, hold_course, ..Default::default() };
            let m = generate(&model, &opts, &mut |_| true).unwrap().motion;
            // After the seed block, real motion that keeps its own course.
            let seed_frames = model.spec.block_len * model.spec.stride;
            let ground: Vec<glam::Vec2> = (seed_frames..m.frames()).map(|t| glam::Vec2::new(m.frame(t)[0].x, m.frame(t)[0].z) * metres).collect();
            let walked: f32 = ground.windows(2).map(|w| w[0].distance(w[1])).sum();
            (ground[ground.len() - 1].distance(ground[0]), walked, m)
        };
        for seed in [seeds[0], seeds[seeds.len() - 1]] {
            let (straight, walked, _) = hips_path("walking:10", InitPose::SeedIndex(seed), true);
            let (round, round_walked, _) = hips_path("walking:10", InitPose::SeedIndex(seed), false);
            println!("{name} walking from seed {seed}: {straight:.2} m from the start after {walked:.2} m; without the course {round:.2} after {round_walked:.2}");
            assert!(straight > 0.9 * walked && walked > 3.0, "{name}, seed {seed}: {straight:.2} m from the start after {walked:.2} m");
            assert!(round < 0.5 * round_walked, "{name}, seed {seed}: without the course {round:.2} m after {round_walked:.2} (the case this guards)");
        }
        if name == "all" {
            let salsa = || InitPose::SeedClass { class: "salsa".into(), variant: 0 };
            let (a, b) = (hips_path("salsa:6", salsa(), true).2, hips_path("salsa:6", salsa(), false).2);
            assert_eq!(mean_distance(&a, &b), 0.0, "salsa travels only about: its course is its own");
        }
    }
}

/// `all`'s sidesteps are steered away from `walking` (model.json's `class_contrasts`, written
/// by `glocal calibrate --contrast walk-left=walking,walk-right=walking`): made plainly they
/// walk forwards, a third to a half as far sideways as their data, and read as walking.
/// Steered, each travels further to its own side for every metre forwards; a class that
/// steers away from nothing (walking) is made exactly as without.
#[test]
fn a_steered_sidestep_travels_further_to_its_side() {
    let steered = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    for side in ["walk-left", "walk-right"] {
        assert_eq!(steered.spec.class_contrasts.get(side).map(String::as_str), Some("walking"), "models/all/model.json: class_contrasts.{side}");
    }
    let plain = GlocalModel::load(&shipped("all")).unwrap().with_class_contrasts(Default::default()).unwrap();
    let skeleton = &plain.spec.layout.skeleton;
    let (left, right) = (skeleton.index_of("LeftUpLeg").unwrap(), skeleton.index_of("RightUpLeg").unwrap());
    let take = |model: &GlocalModel, class: &str| {
        let opts = GenerateOptions { timeline: format!("{class}:8").parse().unwrap(), init: InitPose::SeedClass { class: class.into(), variant: 0 }, ..Default::default() };
        generate(model, &opts, &mut |_| true).unwrap().motion
    };
    // Leftwards travel over forwards travel after 2.5 s, in the frame of the hip sockets.
    let flat = glam::Vec3::new(1.0, 0.0, 1.0);
    let sideways_share = |m: &glocal::motion::Motion| {
        let (mut sideways, mut forwards) = (0.0, 0.0);
        for t in (m.fps * 2.5) as usize + 1..m.frames() {
            let (before, now) = (m.frame(t - 1), m.frame(t));
            let to_left = ((now[left] - now[right]) * flat).normalize();
            let step = (now[0] - before[0]) * flat;
            sideways += step.dot(to_left);
            forwards += step.dot(to_left.cross(glam::Vec3::Y));
        }
        sideways / forwards.abs()
    };
    for (side, sign) in [("walk-left", 1.0), ("walk-right", -1.0)] {
        let (pushed, made_plainly) = (sign * sideways_share(&take(&steered, side)), sign * sideways_share(&take(&plain, side)));
        println!("{side}: {pushed:.2} of the forward distance to its side; made plainly {made_plainly:.2}");
        assert!(pushed > made_plainly + 0.03 && pushed > 0.15, "{side}: {pushed:.2} to its side, {made_plainly:.2} made plainly");
    }
    assert_eq!(mean_distance(&take(&steered, "walking"), &take(&plain, "walking")), 0.0, "walking steers away from nothing");
}

/// A take's joints relative to its root joint in each frame.
fn about_the_hips(m: &glocal::motion::Motion) -> glocal::motion::Motion {
    let relative = m.positions().chunks_exact(m.joints()).flat_map(|f| f.iter().map(move |p| *p - f[0])).collect();
    glocal::motion::Motion::from_positions(m.skeleton.clone(), m.fps, relative)
}

/// A spline through a clip's own sparse poses keeps a third to a half of its jerk, so a take
/// splined between GloGen's poses was smoother than capture (`all`'s CMU dances at 0.57x
/// their real jerk): each class's motion texture, its share calibrated against its training
/// clips, lays back the detail. Salsa's take gets it (jerk up by half, each pose within a
/// centimetre of what it was), walk-left, lively enough without, gets none, and a take
/// asked without texture is the take before it.
#[test]
fn the_texture_makes_a_dance_as_lively_as_its_capture() {
    let model = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(model.texture().is_some(), "models/all has no texture.safetensors");
    let spec = &model.spec;
    let roles = JointRoles::new(&spec.layout.skeleton).unwrap();
    let gains = spec.texture_gain_per_class();
    let made = |class: &str, texture: bool| {
        let opts = GenerateOptions { timeline: format!("{class}:8").parse().unwrap(), init: InitPose::SeedClass { class: class.into(), variant: 0 }, texture, ..Default::default() }.varied(3);
        generate(&model, &opts, &mut |_| true).unwrap().motion
    };
    let jerk = |m: &glocal::motion::Motion| {
        let mut pool = Pool::default();
        pool.add_take(&m.resample(COMMON_FPS), &roles, None);
        pool.summary()[Measure::JerkMean]
    };
    assert!(gains[spec.class_index("salsa").unwrap()] > 0.5, "salsa's texture share {:?}", spec.texture_gains.get("salsa"));
    let (plain, textured) = (made("salsa", false), made("salsa", true));
    let (before, after) = (jerk(&plain), jerk(&textured));
    // The pose about the hips: where the feet carry the body differs a little with them.
    let moved = mean_distance(&about_the_hips(&plain), &about_the_hips(&textured));
    eprintln!("salsa: jerk {before:.0} -> {after:.0} m/s^3, joints moved {:.1} mm about the hips on average", moved * 1000.0);
    assert!(after > 1.5 * before, "salsa's jerk {before:.0} -> {after:.0}");
    assert!(moved < 0.01, "the texture moved salsa's joints {moved} m about the hips on average");
    assert_eq!(gains[spec.class_index("walk-left").unwrap()], 0.0);
    assert_eq!(mean_distance(&made("walk-left", false), &made("walk-left", true)), 0.0);
}

/// The texture bank holds no capture glitch: a CMU clip's reference pose before its first
/// frame and a dance's marker lost for a frame or two (a knee 40 cm off) had been gathered
/// with the rest, and every 10 s of Indian dance or salsa popped with them (peak jerk 2.5-15x
/// the same take's without texture; 0.7-2.0x now). Four variations of each dance, 12 s.
#[test]
fn the_texture_adds_no_pop_to_a_dance() {
    let model = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    let peak = |class: &str, seed: u64, texture: bool| {
        let opts = GenerateOptions { timeline: format!("{class}:12").parse().unwrap(), seed, texture, ..Default::default() };
        frame_jerk(&generate(&model, &opts, &mut |_| true).unwrap().motion).into_iter().fold(0.0f32, f32::max)
    };
    for class in ["indian", "salsa"] {
        for seed in 0..4 {
            let (plain, textured) = (peak(class, seed, false), peak(class, seed, true));
            println!("{class} seed {seed}: peak jerk {plain:.0} -> {textured:.0} m/s^3 with texture");
            assert!(textured < 2.5 * plain, "{class} seed {seed}: the texture takes the peak jerk from {plain:.0} to {textured:.0} m/s^3");
        }
    }
}

/// The gap the in-betweener fills before a key gets the take's motion texture again (it
/// was laid before the gap was filled, so a keyed second was calmer than the rest): a salsa
/// keyed 1.5 s after its starting poses has a livelier gap with its texture than without,
/// and the key's pose is where it was.
#[test]
fn a_keys_filled_gap_has_the_takes_texture() {
    let model = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    let spec = &model.spec;
    let gap = (1.5 * spec.fps) as usize;
    let key_frame = spec.observed_span() + gap;
    let made = |texture: bool| {
        let key = Key { seconds: key_frame as f32 / spec.fps, source: KeySource::Init(InitPose::SeedClass { class: "salsa".into(), variant: 1 }), fix_root: false };
        let opts = GenerateOptions { timeline: "salsa:6".parse().unwrap(), init: InitPose::SeedClass { class: "salsa".into(), variant: 0 }, keys: vec![key], texture, ..Default::default() }.varied(3);
        generate(&model, &opts, &mut |_| true).unwrap().motion
    };
    let (plain, textured) = (made(false), made(true));
    let gap_jerk = |m: &glocal::motion::Motion| {
        let jerk = frame_jerk(&m.slice(spec.observed_span() + 1, key_frame));
        jerk.iter().sum::<f32>() / jerk.len() as f32
    };
    let (before, after) = (gap_jerk(&plain), gap_jerk(&textured));
    let (plain_pose, textured_pose) = (about_the_hips(&plain), about_the_hips(&textured));
    let key_moved = plain_pose.frame(key_frame).iter().zip(textured_pose.frame(key_frame)).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max);
    eprintln!("salsa's keyed gap: jerk {before:.0} m/s^3 without texture, {after:.0} with; key frames {:.2} mm apart", key_moved * 1000.0);
    assert!(after > 1.3 * before, "the gap's jerk {before:.0} without texture, {after:.0} with");
    assert!(key_moved < 1e-3, "the texture moved the key's frame {key_moved} m");
}

/// `all`'s dash is steered away from running too (`dash=running`): made plainly it ran at
/// 0.77x its real joint speed and was read as running in the style suite's takes (class kept
/// 0.45); steered, it runs at its data's speed. From each of its first four seed windows, the
/// hips cover more ground a second steered than made plainly.
#[test]
fn a_dash_steered_from_running_runs_faster_than_made_plainly() {
    let steered = GlocalModel::load(&shipped("all")).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(steered.spec.class_contrasts.get("dash").map(String::as_str), Some("running"), "models/all/model.json: class_contrasts.dash");
    let mut pairs = steered.spec.class_contrasts.clone();
    pairs.remove("dash");
    let plain = GlocalModel::load(&shipped("all")).unwrap().with_class_contrasts(pairs).unwrap();
    let speed = |model: &GlocalModel, variant: usize| {
        let opts = GenerateOptions { timeline: "dash:6".parse().unwrap(), init: InitPose::SeedClass { class: "dash".into(), variant }, ..Default::default() };
        let m = generate(model, &opts, &mut |_| true).unwrap().motion;
        let hips = |t: usize| m.frame(t)[0] * glam::Vec3::new(1.0, 0.0, 1.0);
        let from = (2.0 * m.fps) as usize;
        (from + 1..m.frames()).map(|t| hips(t).distance(hips(t - 1))).sum::<f32>() * m.fps / (m.frames() - from - 1) as f32
    };
    for variant in 0..4 {
        let (fast, slow) = (speed(&steered, variant), speed(&plain, variant));
        println!("dash from seed window {variant}: {fast:.2} m/s steered, {slow:.2} made plainly");
        assert!(fast > 1.1 * slow, "dash from seed window {variant}: {fast:.2} m/s steered, {slow:.2} made plainly");
    }
}
