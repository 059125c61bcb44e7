//! The first-takes suite's random takes: beyond the fixed first takes, timelines a user trying
//! the model might lay out (1-4 segments of 2-6 s, classes drawn at random, started from a
//! random seed-bank pose or from a random frame of one of the model's real test clips, a
//! random variation seed), each measured as exported like a first take. A take of a class
//! whose real clips leave the ground (a run, a jump, a dance's hops), or started from one's
//! pose, may float; the takes without one are held to issue 39's first-take lines: feet up in
//! at most 10% of frames, no float over 0.5 s. Every take is also checked for joints under
//! its floor.

use std::collections::hash_map::{Entry, HashMap};
use std::ops::Range;
use std::path::PathBuf;

use anyhow::Result;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use super::feet_up::{feet_on_the_floor, FEET_UP_M};
use crate::data::registry::Dataset;
use crate::eval::table::{fixed_or, Markdown};
use crate::model::corpus::Corpus;
use crate::model::glocal::GlocalModel;
use crate::motion::contacts::{local_floor, support_heights};
use crate::motion::{JointRoles, Motion};
use crate::synth::init::read_on_model_skeleton;
use crate::synth::{file_start_frames, generate, GenerateOptions, Generated, InitPose};

/// How many random takes each model makes from its seed bank, how many from its test clips'
/// files, and the seed that draws them.
const TAKES: usize = 200;
const FILE_TAKES: usize = 100;
const DRAW_SEED: u64 = 11;
const SEGMENTS: Range<usize> = 1..5;
const SEGMENT_SECONDS: Range<u32> = 2..7;
const VARIATION_SEEDS: Range<u64> = 0..5;
/// A class whose real training clips are in the air in more than this fraction of frames
/// leaves the ground by nature ([`in_the_air`]).
const AIRBORNE_CLASS: f64 = 0.05;
/// Half-width (seconds) of the window whose lowest support is a real clip's local floor.
const FLOOR_WINDOW_SECONDS: f32 = 1.0;
/// How high the hips are in the air, in leg lengths (hip to knee to ankle, at rest): a
/// standing body's are at about 1, a seated one's at half that or less.
const AIRBORNE_HIPS: f32 = 0.8;
/// A joint further under the floor than this (metres) is through it.
const THROUGH_FLOOR_M: f32 = 0.01;

#[derive(Clone, Debug, Serialize)]
pub struct RandomTakes {
    pub takes: usize,
    /// The classes whose real clips leave the ground, each with the fraction of their frames
    /// in the air.
    pub airborne_classes: Vec<String>,
    /// Takes without an airborne class, in their timeline or their start.
    pub grounded_takes: usize,
    /// Those over a first-take line (feet up more than 10% of frames, or a float over
    /// 0.5 s), as `glocal generate` arguments with what they measure.
    pub grounded_over: Vec<String>,
    /// The takes started from a frame of a real test clip's file, those without an airborne
    /// class in their timeline or their clip, and those of them over a first-take line.
    pub file_takes: usize,
    pub file_grounded: usize,
    pub file_over: Vec<String>,
    /// Takes with a joint more than [`THROUGH_FLOOR_M`] under their floor, and the deepest (m).
    pub through_floor: usize,
    pub deepest_m: f32,
}

/// `model`'s random takes with the suite's generation options `base`, its classes' real clips
/// in `corpus`; `file_of` brings a test clip's archive entry out as a file to start from.
pub fn random_takes(model: &GlocalModel, corpus: &Corpus, base: &GenerateOptions, file_of: &dyn Fn(&str) -> Result<PathBuf>, log: &mut dyn FnMut(&str)) -> Result<RandomTakes> {
    let classes = &model.spec.classes;
    let in_air = in_the_air(corpus)?;
    let airborne: Vec<bool> = in_air.iter().map(|&f| f > AIRBORNE_CLASS).collect();
    let mut rng = StdRng::seed_from_u64(DRAW_SEED);
    let airborne_classes = classes.iter().zip(&in_air).filter(|(_, &f)| f > AIRBORNE_CLASS).map(|(c, f)| format!("{c} {f:.2}")).collect();
    let mut r = RandomTakes { takes: TAKES, airborne_classes, grounded_takes: 0, grounded_over: Vec::new(), file_takes: 0, file_grounded: 0, file_over: Vec::new(), through_floor: 0, deepest_m: 0.0 };
    for i in 0..TAKES {
        let (drawn, timeline, seed) = drawn_timeline(&mut rng, classes);
        let seed_index = rng.random_range(0..model.seeds.len());
        let command = format!("--timeline {timeline} --init seed:{seed_index} --seed {seed}");
        if i % 50 == 0 {
            log(&format!("random takes: {} {i}/{TAKES}", corpus.dataset));
        }
        let opts = GenerateOptions { timeline: timeline.parse()?, init: InitPose::SeedIndex(seed_index), ..base.clone() }.varied(seed);
        let g = generate(model, &opts, &mut |_| true)?;
        // A take started from an airborne class's pose may float while it lands.
        let grounded = !drawn.iter().chain([&model.seeds[seed_index].class]).any(|&c| airborne[c]);
        r.grounded_takes += usize::from(grounded);
        if let Some(over) = r.measure(&g, &command, grounded, 0, log)? {
            r.grounded_over.push(over);
        }
    }
    // The clips a user could start from: every BVH, the model's own dataset's other formats.
    // Their given frames and the fade after them are the file's own motion (a seated
    // Human3.6M subject lifts both feet 25 cm, a hand pushing up from the floor reaches under
    // the feet's markers): the take is judged after them.
    let own_formats = corpus.dataset != Dataset::Combined;
    let clips: Vec<_> = corpus.test.iter().filter(|t| own_formats || t.file.ends_with(".bvh")).collect();
    // Each file's frame count, read once (a clip is drawn several times).
    let mut file_frames = HashMap::new();
    let draws = if clips.is_empty() { 0 } else { FILE_TAKES };
    for i in 0..draws {
        let (drawn, timeline, seed) = drawn_timeline(&mut rng, classes);
        let clip = clips[rng.random_range(0..clips.len())];
        let path = file_of(&clip.file)?;
        let frames = match file_frames.entry(clip.file.as_str()) {
            Entry::Occupied(known) => *known.get(),
            Entry::Vacant(new) => *new.insert(read_on_model_skeleton(model, &path, None)?.file_frames),
        };
        let frame = rng.random_range(0..frames);
        let command = format!("--timeline {timeline} --init clip:{}@{frame} --seed {seed}", clip.file);
        if i % 20 == 0 {
            log(&format!("random takes from files: {} {i}/{FILE_TAKES}", corpus.dataset));
        }
        let opts = GenerateOptions { timeline: timeline.parse()?, init: InitPose::file(path, frame), ..base.clone() }.varied(seed);
        let g = generate(model, &opts, &mut |_| true)?;
        let grounded = !drawn.iter().chain([&clip.class]).any(|&c| airborne[c]);
        r.file_takes += 1;
        r.file_grounded += usize::from(grounded);
        if let Some(over) = r.measure(&g, &command, grounded, file_start_frames(model), log)? {
            r.file_over.push(over);
        }
    }
    Ok(r)
}

/// A random timeline of `classes` (its classes, as `--timeline` spells it) and a variation
/// seed.
fn drawn_timeline(rng: &mut StdRng, classes: &[String]) -> (Vec<usize>, String, u64) {
    let drawn: Vec<usize> = (0..rng.random_range(SEGMENTS)).map(|_| rng.random_range(0..classes.len())).collect();
    let timeline = drawn.iter().map(|&c| format!("{}:{}", classes[c], rng.random_range(SEGMENT_SECONDS))).collect::<Vec<_>>().join(",");
    (drawn, timeline, rng.random_range(VARIATION_SEEDS))
}

impl RandomTakes {
    /// Tallies how deep `g`'s joints go under its floor; when `grounded`, what it measures
    /// if it is over a first-take line; both judged from frame `from` on.
    fn measure(&mut self, g: &Generated, command: &str, grounded: bool, from: usize, log: &mut dyn FnMut(&str)) -> Result<Option<String>> {
        let under = deepest_under_floor(&g.motion, from);
        if under > THROUGH_FLOOR_M {
            self.through_floor += 1;
            log(&format!("random takes: `{command}` has a joint {:.1} cm under its floor", 100.0 * under));
        }
        self.deepest_m = self.deepest_m.max(under);
        if !grounded {
            return Ok(None);
        }
        let (feet_up, float, _) = feet_on_the_floor(&g.motion, &g.contacts, from)?;
        Ok((feet_up > 0.10 || float > 0.5).then(|| format!("`{command}`: feet up {:.0}%, longest float {float:.1} s", 100.0 * feet_up)))
    }
}

/// Per class of `corpus`, the fraction of its real training clips' frames in the air (their
/// support, feet or seat, more than [`FEET_UP_M`] above the local floor, the lowest support
/// within [`FLOOR_WINDOW_SECONDS`], with the hips at least [`AIRBORNE_HIPS`] of a leg's length
/// up). A clip's lowest frame would set its floor for the whole clip: on CMU's dances, where
/// the floor is not level, 90% of frames were in the air by it. The
/// hips tell a flight from a seat: someone on a chair, or seated on the floor with the knees
/// drawn up, has the feet off the floor too.
fn in_the_air(corpus: &Corpus) -> Result<Vec<f64>> {
    let mut up = vec![(0usize, 0usize); corpus.classes.len()];
    for track in &corpus.train {
        let m = &track.motion;
        let roles = JointRoles::new(&m.skeleton)?;
        let unit = m.skeleton.meters_per_unit();
        let leg = roles.rest_leg_length(&m.skeleton);
        let support = support_heights(m, &roles);
        let floor = local_floor(&support, (FLOOR_WINDOW_SECONDS * m.fps).round() as usize);
        let flying = |t: usize| (support[t] - floor[t]) * unit > FEET_UP_M && m.frame(t)[roles.body_root].y - floor[t] >= AIRBORNE_HIPS * leg;
        up[track.class].0 += (0..m.frames()).filter(|&t| flying(t)).count();
        up[track.class].1 += m.frames();
    }
    Ok(up.iter().map(|&(flying, all)| flying as f64 / all.max(1) as f64).collect())
}

/// How far (metres) the take's lowest joint from frame `from` on goes under its floor at
/// worst (0 if never).
fn deepest_under_floor(m: &Motion, from: usize) -> f32 {
    let floor = m.floor_height();
    let lowest = m.positions().iter().skip(from * m.joints()).map(|p| p.y).fold(f32::INFINITY, f32::min);
    ((floor - lowest) * m.skeleton.meters_per_unit()).max(0.0)
}

/// The random takes' paragraph.
pub fn markdown(r: &RandomTakes, md: &mut Markdown) {
    md.text(&format!(
        "\nRandom takes ({} timelines of 1-4 segments of 2-6 s from random seed poses and variation seeds): {} without a class whose real clips leave the ground ({}); {} of them over a first-take line (feet up in more than 10% of frames or a float over 0.5 s){}. From a random frame of a real test clip's file, {} more (judged after the file's given frames and their fade): {} without such a class in their timeline or clip, {} of them over a line{}. Takes with a joint more than 1 cm under their floor: {} (deepest {} cm).\n",
        r.takes,
        r.grounded_takes,
        if r.airborne_classes.is_empty() { "none".to_string() } else { r.airborne_classes.join(", ") },
        r.grounded_over.len(),
        listed(&r.grounded_over),
        r.file_takes,
        r.file_grounded,
        r.file_over.len(),
        listed(&r.file_over),
        r.through_floor,
        fixed_or(100.0 * r.deepest_m as f64, 1, "-"),
    ));
}

/// `": a; b"` of a non-empty list, nothing of an empty one.
fn listed(takes: &[String]) -> String {
    if takes.is_empty() {
        String::new()
    } else {
        format!(": {}", takes.join("; "))
    }
}
