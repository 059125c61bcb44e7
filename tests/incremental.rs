//! Incremental regeneration and streaming (issue 38), on both shipped models: a take made by
//! resuming the cached take of an earlier request is the take a fresh generation of the
//! edited request makes, bit for bit, and only the blocks from the edit on are made again;
//! the frames streamed while a take is made are always the first frames of the finished take.

use std::path::Path;

use glocal::model::glocal::GlocalModel;
use glocal::motion::Motion;
use glocal::synth::{generate_reusing, GenerateOptions, Generated, InitPose, TakeCache, TakeEvents, Timeline};

fn model(name: &str) -> GlocalModel {
    GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap()
}

/// Five minutes of each model in five segments.
fn five_minutes(name: &str) -> GenerateOptions {
    let (timeline, start) = match name {
        "h36m" => ("walking:60,eating:60,walking:60,sitting:60,walking:60", "walking"),
        "all" => ("walking:60,salsa:60,sitting:60,bow/happy:60,basketball:60", "walking"),
        _ => ("walk:60,bow:60,run:60,walk-left:60,byebye:60", "walk"),
    };
    GenerateOptions { timeline: timeline.parse().unwrap(), init: InitPose::SeedClass { class: start.into(), variant: 0 }, ..Default::default() }
}

/// Generates `opts` resuming `cache`; returns the take and the first progress reported (how
/// much of the rollout was already done).
fn resumed(model: &GlocalModel, opts: &GenerateOptions, cache: &mut TakeCache) -> (Generated, f32) {
    let mut first = None;
    let take = generate_reusing(model, opts, cache, &mut |f: f32| {
        first.get_or_insert(f);
        true
    })
    .unwrap();
    (take, first.unwrap_or(1.0))
}

fn same_bits(a: &Motion, b: &Motion) -> bool {
    let positions = a.positions().len() == b.positions().len() && a.positions().iter().zip(b.positions()).all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits));
    let poses = match (&a.local_poses, &b.local_poses) {
        (Some(x), Some(y)) => x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.rotations == q.rotations && p.translations == q.translations),
        (None, None) => true,
        _ => false,
    };
    positions && poses
}

fn assert_same_take(incremental: &Generated, full: &Generated, what: &str) {
    assert!(same_bits(&incremental.motion, &full.motion), "{what}: the incremental take differs from the full generation");
    assert_eq!(incremental.contacts, full.contacts, "{what}: contacts");
    assert_eq!(incremental.segments, full.segments, "{what}: segments");
    assert_eq!(incremental.block_embeddings, full.block_embeddings, "{what}: block embeddings");
    assert_eq!(incremental.block_classes, full.block_classes, "{what}: block classes");
}

/// Edits of a five-minute timeline, each resumed from the take before it: the result is the
/// full generation of the edited request, and an edit of the last segment resumes late.
fn edits_resume_exactly(name: &str) {
    let model = model(name);
    let last_class = if name == "h36m" { "greeting" } else { "bow" };
    let mut opts = five_minutes(name);
    let mut cache = TakeCache::default();
    resumed(&model, &opts, &mut cache);
    let edits: Vec<(&str, Box<dyn Fn(&mut Timeline)>, f32)> = vec![
        ("the same request again", Box::new(|_| {}), 0.79),
        ("the last segment's class", Box::new(move |t| t.segments[4].class = last_class.into()), 0.6),
        ("the last segment rerolled", Box::new(|t| t.segments[4].seed = Some(7)), 0.6),
        ("the last segment's pace", Box::new(|t| t.segments[4].pace = Some(1.5)), 0.6),
        ("the last segment shorter", Box::new(|t| t.segments[4].seconds = 40.0), 0.6),
        ("the middle segment's class", Box::new(move |t| t.segments[2].class = last_class.into()), 0.15),
    ];
    for (what, edit, resumed_at_least) in edits {
        edit(&mut opts.timeline);
        let (incremental, first_progress) = resumed(&model, &opts, &mut cache);
        let (full, _) = resumed(&model, &opts, &mut TakeCache::default());
        assert_same_take(&incremental, &full, &format!("{name}, {what}"));
        println!("{name}: {what}: identical, resumed at {:.0}% of the rollout", (first_progress / 0.8).min(1.0) * 100.0);
        assert!(first_progress >= resumed_at_least, "{name}, {what}: resumed at {first_progress}, expected at least {resumed_at_least}");
    }
    // A take-wide change (the variation seed) makes every block again.
    opts = opts.varied(3);
    let (incremental, first_progress) = resumed(&model, &opts, &mut cache);
    assert_same_take(&incremental, &resumed(&model, &opts, &mut TakeCache::default()).0, &format!("{name}, another seed"));
    assert!(first_progress < 0.05, "{name}: another seed must make every block again");
}

#[test]
fn h36m_edits_resume_exactly() {
    edits_resume_exactly("h36m");
}

#[test]
fn bandai_edits_resume_exactly() {
    edits_resume_exactly("bandai");
}

/// Every take shown while the take is made.
#[derive(Default)]
struct Stream {
    shown: Vec<Generated>,
}

impl TakeEvents for Stream {
    fn progress(&mut self, _fraction: f32) -> bool {
        true
    }

    fn wants_frames(&self) -> bool {
        true
    }

    fn frames(&mut self, so_far: Generated) {
        self.shown.push(so_far);
    }
}

#[test]
fn a_streamed_take_is_always_a_prefix_of_the_finished_one() {
    for name in ["h36m", "bandai", "all"] {
        let model = model(name);
        let opts = five_minutes(name);
        let mut stream = Stream::default();
        let finished = generate_reusing(&model, &opts, &mut TakeCache::default(), &mut stream).unwrap();
        assert!(stream.shown.len() >= 10, "{name}: {} streamed takes of a five-minute take", stream.shown.len());
        let mut frames_before = 0;
        for shown in &stream.shown {
            let frames = shown.motion.frames();
            assert!(frames > frames_before && frames <= finished.motion.frames());
            assert!(same_bits(&shown.motion, &finished.motion.slice(0, frames)), "{name}: the take shown at {frames} frames is not the finished take's start");
            assert_eq!(shown.contacts, finished.contacts.slice(0..frames));
            frames_before = frames;
        }
        println!("{name}: {} streamed takes, the first of {} frames, all prefixes of the finished {}", stream.shown.len(), stream.shown[0].motion.frames(), finished.motion.frames());
    }
}
