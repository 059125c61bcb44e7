//! Per-class guidance (`glocal calibrate`): the lowest classifier-free guidance at which each
//! class's generated motion is as lively as its training clips. One guidance for a model of
//! 26 activities left some of them damped: at 1.5, `all`'s CMU dances and sports moved at
//! 0.42x / 0.45x their real jerk, while its Human3.6M and Bandai classes were within 0.8-0.9x;
//! guidance raised for every class at once took those past 1.3x (docs/RESULTS.md).
//!
//! Guidance is calibrated on takes without motion texture; a model with a texture then gets
//! each class's share of it ([`texture_gain`]): what its guided takes still lack of their
//! training clips' jerk.

use anyhow::{bail, Result};
use glam::Vec3;

use super::motion::{real_pieces, Measure, Pool, COMMON_FPS};
use super::suites::motion::scored_take;
use crate::model::corpus::Corpus;
use crate::model::glocal::GlocalModel;
use crate::motion::{JointRoles, Motion};
use crate::synth::GenerateOptions;

/// A class is lively enough once its generated mean jerk is this share of its training
/// clips': issue 39's lower bound on jerk against real motion.
pub const LIVELY_SHARE: f64 = 0.7;
/// A class whose generated mean jerk at the model's guidance is over this share of its
/// training clips' (issue 39's upper bound) is lively already: more guidance only exaggerates
/// it ([`crate::model::spec::ModelSpec::lively_classes`]), and it is calmed with less
/// ([`CALMER_STRENGTHS`]).
pub const LIVELY_CEILING: f64 = 1.3;
/// The guidance under the model's own (1.5) a lively class is tried at, calmest last. (At 1.4
/// `all`'s bow, dash and walk-right read as at 1.5.)
const CALMER_STRENGTHS: [f32; 2] = [1.25, 1.0];
/// A stronger guidance is not taken where any of the class's takes travels less than this
/// share of what the same take travels at the model's own, less [`TRAVEL_SLACK`] (m/s) for
/// classes that stand: calibrated on takes with variation noise, `all`'s walk got 3.5, and
/// its default take from the first walking window then covered 3.0 m in 6 s against 4.0 at
/// 1.5, curving where it had walked on.
const KEPT_TRAVEL: f64 = 0.8;
const TRAVEL_SLACK: f64 = 0.05;
const TRAVEL_HOP_SECONDS: f32 = 0.5;
/// A textured class is as lively as this share of its training clips' mean jerk.
const TEXTURED_SHARE: f64 = 1.0;
/// Seed-bank windows per class and strength, and seconds scored after each seed block; each
/// take without variation noise, as a take is made by default.
const TAKES: usize = 8;
const TAKE_SECONDS: f32 = 10.0;

/// One class's readings: its training clips' mean jerk (m/s^3), the generated takes at each
/// strength tried, and the strength chosen.
pub struct ClassCalibration {
    pub class: String,
    pub real_jerk: f64,
    pub readings: Vec<Reading>,
    pub chosen: f32,
    /// With the model's texture: the jerk of the chosen strength's takes with all of the
    /// texture laid, and the share of it chosen.
    pub texture: Option<(f64, f32)>,
}

/// A class's takes at one strength: their mean jerk (m/s^3) and how fast the body travels in
/// each ([`travel_speed`], m/s).
#[derive(Debug)]
pub struct Reading {
    pub strength: f32,
    pub jerk: f64,
    pub travels: Vec<f64>,
}

impl Reading {
    pub fn mean_travel(&self) -> f64 {
        self.travels.iter().sum::<f64>() / self.travels.len().max(1) as f64
    }
}

/// Each class of `model`, generated at each of `strengths` (ascending, the model's
/// own first) from its first seed windows, against the mean jerk of its training clips (in
/// `corpus`, the data it was trained on): the
/// lowest strength at which the class reaches [`LIVELY_SHARE`] of it, or the liveliest when
/// none does, but never one at which it travels less than [`KEPT_TRAVEL`] of its own; a
/// class over [`LIVELY_CEILING`] of it at the model's own and not steered apart from another
/// ([`crate::model::spec::ModelSpec::class_contrasts`]), the first of the
/// [`CALMER_STRENGTHS`] that brings it under, or the calmest still lively enough.
pub fn calibrate(model: &GlocalModel, corpus: &Corpus, strengths: &[f32], log: &mut dyn FnMut(&str)) -> Result<Vec<ClassCalibration>> {
    let spec = &model.spec;
    if strengths.is_empty() || strengths.windows(2).any(|w| w[0] >= w[1]) || strengths[0] < spec.class_strength {
        bail!("the strengths to try must rise from the model's own ({}), got {strengths:?}", spec.class_strength);
    }
    let roles = JointRoles::new(&spec.layout.skeleton)?;
    let real_jerks = training_jerks(corpus, &roles);
    let mut out = Vec::new();
    for (class, name) in spec.classes.iter().enumerate() {
        let real_jerk = real_jerks[class];
        let mut readings: Vec<Reading> = Vec::new();
        for &strength in strengths {
            log(&format!("calibrate: {name} at {strength}"));
            let reading = read_class(model, &roles, class, strength, false)?;
            let done = reading.jerk >= LIVELY_SHARE * real_jerk || readings.first().is_some_and(|own| !keeps_travel(own, &reading));
            readings.push(reading);
            if done {
                break;
            }
        }
        let mut chosen = choose(&readings, real_jerk);
        // A class steered apart keeps its guidance: it carries the push from its pair
        // (`all`'s walk-right calmed to 1.25 kept its class in 0.77 of its styled takes after
        // 2 s, against 0.90).
        if over_ceiling(&readings[0], real_jerk) && spec.contrast_indices()[class].is_none() {
            chosen = calmed(model, &roles, class, &mut readings, real_jerk, log)?;
        }
        let texture = match model.texture() {
            Some(_) => {
                log(&format!("calibrate: {name} textured"));
                let textured = read_class(model, &roles, class, chosen, true)?.jerk;
                Some((textured, texture_gain(jerk_at(&readings, chosen), textured, TEXTURED_SHARE * real_jerk)))
            }
            None => None,
        };
        out.push(ClassCalibration { class: name.clone(), real_jerk, readings, chosen, texture });
    }
    Ok(out)
}

/// The strength a class lively already at the model's own guidance (the first of
/// `readings`) is calmed to: the first of [`CALMER_STRENGTHS`] under the model's own at which
/// its jerk is within [`LIVELY_CEILING`] of `real_jerk`, else the calmest at which it keeps
/// [`LIVELY_SHARE`] of it and its travel; each strength read is added to `readings`.
fn calmed(model: &GlocalModel, roles: &JointRoles, class: usize, readings: &mut Vec<Reading>, real_jerk: f64, log: &mut dyn FnMut(&str)) -> Result<f32> {
    let own = readings[0].strength;
    let mut chosen = own;
    for strength in CALMER_STRENGTHS.into_iter().filter(|&s| s < own) {
        log(&format!("calibrate: {} at {strength}, calmer", model.spec.classes[class]));
        let reading = read_class(model, roles, class, strength, false)?;
        let (lively, within) = (reading.jerk >= LIVELY_SHARE * real_jerk && keeps_travel(&readings[0], &reading), !over_ceiling(&reading, real_jerk));
        readings.push(reading);
        if !lively {
            break;
        }
        chosen = strength;
        if within {
            break;
        }
    }
    Ok(chosen)
}

impl ClassCalibration {
    /// The mean jerk of the class's takes at the strength chosen, without texture.
    pub fn chosen_jerk(&self) -> f64 {
        jerk_at(&self.readings, self.chosen)
    }

    /// Whether the class's takes at the model's own guidance (the first strength read) move
    /// more sharply than [`LIVELY_CEILING`] of its training clips.
    pub fn over_lively(&self) -> bool {
        self.readings.first().is_some_and(|own| over_ceiling(own, self.real_jerk))
    }
}

/// Whether takes of `reading` move more sharply than [`LIVELY_CEILING`] of `real_jerk`.
fn over_ceiling(reading: &Reading, real_jerk: f64) -> bool {
    reading.jerk > LIVELY_CEILING * real_jerk
}

/// The mean jerk of `readings` at guidance `strength` (NaN where none was read there).
fn jerk_at(readings: &[Reading], strength: f32) -> f64 {
    readings.iter().find(|r| r.strength == strength).map_or(f64::NAN, |r| r.jerk)
}

/// Per class, the mean jerk (m/s^3) of its training clips in pieces as long as the takes.
fn training_jerks(corpus: &Corpus, roles: &JointRoles) -> Vec<f64> {
    let mut pools: Vec<Pool> = corpus.classes.iter().map(|_| Pool::default()).collect();
    for track in &corpus.train {
        let m = track.motion.resample(COMMON_FPS);
        for piece in real_pieces(&m, TAKE_SECONDS) {
            pools[track.class].add_take(&m.slice(piece.start, piece.end), roles, None);
        }
    }
    pools.iter().map(|p| p.summary()[Measure::JerkMean]).collect()
}

/// The share of its texture a class gets for its jerk to reach `target`, from its takes'
/// jerk without texture (`plain`) and with all of it (`textured`). The texture's detail is
/// unrelated to the motion under it, so their jerks add roughly as the squares do.
fn texture_gain(plain: f64, textured: f64, target: f64) -> f32 {
    let (lacking, added) = (target * target - plain * plain, textured * textured - plain * plain);
    if lacking <= 0.0 || !lacking.is_finite() {
        return 0.0;
    }
    if added <= lacking {
        return 1.0;
    }
    (lacking / added).sqrt() as f32
}

/// The class's [`TAKES`] takes at guidance `strength`, measured, with or without the
/// model's texture.
fn read_class(model: &GlocalModel, roles: &JointRoles, class: usize, strength: f32, texture: bool) -> Result<Reading> {
    let spec = &model.spec;
    let seed_s = (spec.block_len * spec.stride) as f32 / spec.fps;
    let base = GenerateOptions { class_strength: Some(strength), texture, ..Default::default() };
    let mut pool = Pool::default();
    let mut travels = Vec::new();
    for variant in 0..TAKES {
        let (m, _) = scored_take(model, &base, &[(class, seed_s + TAKE_SECONDS)], class, variant, 0)?;
        pool.add_take(&m, roles, None);
        travels.push(travel_speed(&m, roles.body_root));
    }
    Ok(Reading { strength, jerk: pool.summary()[Measure::JerkMean], travels })
}

/// The hips' horizontal path over the take in hops of [`TRAVEL_HOP_SECONDS`] (the sway of a
/// step left out, the circles Human3.6M's subjects walk in kept), per second (m/s).
fn travel_speed(m: &Motion, root: usize) -> f64 {
    let hop = ((TRAVEL_HOP_SECONDS * m.fps).round() as usize).max(1);
    let at = |t: usize| Vec3::new(m.frame(t)[root].x, 0.0, m.frame(t)[root].z);
    let path: f32 = (hop..m.frames()).step_by(hop).map(|t| at(t).distance(at(t - hop))).sum();
    (path * m.skeleton.meters_per_unit()) as f64 / m.seconds().max(f32::EPSILON) as f64
}

/// Whether every take of the class at `reading` travels about as far as the same take at the
/// model's own strength (`own`).
fn keeps_travel(own: &Reading, reading: &Reading) -> bool {
    reading.travels.iter().zip(&own.travels).all(|(t, o)| *t >= KEPT_TRAVEL * o - TRAVEL_SLACK)
}

/// Of the readings that keep the class's travel, the first whose jerk reaches [`LIVELY_SHARE`]
/// of `real_jerk`, else the liveliest.
fn choose(readings: &[Reading], real_jerk: f64) -> f32 {
    let kept: Vec<&Reading> = readings.iter().filter(|r| keeps_travel(&readings[0], r)).collect();
    kept.iter()
        .find(|r| r.jerk >= LIVELY_SHARE * real_jerk)
        .or_else(|| kept.iter().max_by(|a, b| a.jerk.total_cmp(&b.jerk)))
        .map_or(f32::NAN, |r| r.strength)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn readings(of: &[(f32, f64, f64)]) -> Vec<Reading> {
        of.iter().map(|&(strength, jerk, travel)| Reading { strength, jerk, travels: vec![travel, 0.5] }).collect()
    }

    #[test]
    fn the_first_lively_strength_is_chosen_else_the_liveliest() {
        assert_eq!(choose(&readings(&[(1.5, 60.0, 0.0), (2.5, 95.0, 0.0), (3.5, 120.0, 0.0)]), 100.0), 2.5);
        assert_eq!(choose(&readings(&[(1.5, 90.0, 0.0)]), 100.0), 1.5);
        assert_eq!(choose(&readings(&[(1.5, 30.0, 0.0), (2.5, 50.0, 0.0), (3.5, 45.0, 0.0)]), 100.0), 2.5);
    }

    /// A class is lively already when its takes at the model's own guidance (the first read)
    /// move more sharply than 1.3x its training clips, calmed since or not; more jerk at a
    /// stronger guidance does not count.
    #[test]
    fn a_class_over_the_ceiling_at_the_models_guidance_is_lively() {
        let class = |chosen: f32, of: &[(f32, f64, f64)]| ClassCalibration { class: "bow".into(), real_jerk: 100.0, readings: readings(of), chosen, texture: None };
        assert!(class(1.5, &[(1.5, 131.0, 0.0)]).over_lively());
        assert!(class(1.25, &[(1.5, 131.0, 0.0), (1.25, 122.0, 0.0)]).over_lively());
        assert!(!class(1.5, &[(1.5, 129.0, 0.0), (2.5, 160.0, 0.0)]).over_lively());
    }

    #[test]
    fn a_class_gets_the_texture_it_lacks() {
        assert_eq!(texture_gain(100.0, 150.0, 90.0), 0.0);
        assert_eq!(texture_gain(60.0, 90.0, 120.0), 1.0);
        // Jerk 60 lacks 80 of 100 in squares (100^2 - 60^2 = 80^2); all of the texture adds 160
        // in squares, so half of it is laid.
        let gain = texture_gain(60.0, 60.0f64.hypot(160.0), 100.0);
        assert!((gain - 0.5).abs() < 1e-6, "{gain}");
    }

    /// A strength at which one of the class's takes travels much less is not taken, even
    /// where it is the only one lively enough: the liveliest that keeps the travel is.
    #[test]
    fn a_strength_that_slows_a_take_is_not_chosen() {
        assert_eq!(choose(&readings(&[(1.5, 57.0, 0.66), (2.5, 68.0, 0.60), (3.5, 87.0, 0.40)]), 100.0), 2.5);
        assert_eq!(choose(&readings(&[(1.5, 57.0, 0.66), (2.5, 75.0, 0.64)]), 100.0), 2.5);
        assert_eq!(choose(&readings(&[(1.5, 57.0, 0.66), (2.5, 75.0, 0.40)]), 100.0), 1.5);
    }
}
