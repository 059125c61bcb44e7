//! A timeline of activities: ordered segments, each a class held for a duration at a pace.

use std::fmt;
use std::str::FromStr;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use crate::data::input::MAX_MOTION_SECONDS;

pub const MIN_PACE: f32 = 0.1;

/// The longest take: one hour. Checked before anything is generated; memory for a take of
/// this length is measured in docs/BENCHMARKS.md.
pub const MAX_TAKE_SECONDS: f32 = MAX_MOTION_SECONDS as f32;
pub const MAX_PACE: f32 = 10.0;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    pub class: String,
    /// The style it is made in (a model with styles only); none: the class's usual style.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub style: Option<String>,
    pub seconds: f32,
    /// Overrides the global pace for this segment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pace: Option<f32>,
    /// Seconds over which the take changes into this segment from the previous one,
    /// overriding the take's transition length (0: a cut).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transition: Option<f32>,
    /// This segment's own variation seed: its blocks' pose noise and anchor windows are
    /// drawn from it instead of the take's seed (0: no noise), so it can be rerolled alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The studio keeps this segment's frames through edits of the others (see
    /// `synth::held`); generation itself does not read it.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub locked: bool,
}

impl Segment {
    pub fn new(class: impl Into<String>, seconds: f32) -> Self {
        Self { class: class.into(), style: None, seconds, pace: None, transition: None, seed: None, locked: false }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timeline {
    pub segments: Vec<Segment>,
}

impl Timeline {
    pub fn seconds(&self) -> f32 {
        self.segments.iter().map(|s| s.seconds).sum()
    }

    /// Checks durations and paces, and resolves each class name against `classes`.
    pub fn validate(&self, classes: &[String], global_pace: f32) -> Result<Vec<usize>> {
        check_pace(global_pace, "global pace")?;
        if self.segments.is_empty() {
            bail!("the timeline is empty: add at least one segment, e.g. \"walk:5\"");
        }
        let total = self.segments.iter().map(|s| s.seconds as f64).sum::<f64>();
        if total > MAX_TAKE_SECONDS as f64 {
            bail!("the timeline lasts {total} s; a take lasts at most {MAX_TAKE_SECONDS} s (one hour): split it into several takes");
        }
        self.segments
            .iter()
            .enumerate()
            .map(|(k, s)| {
                if !(s.seconds > 0.0 && s.seconds.is_finite()) {
                    bail!("segment {} ('{}'): duration must be a positive number of seconds, got {}", k + 1, s.class, s.seconds);
                }
                if let Some(p) = s.pace {
                    check_pace(p, &format!("segment {} ('{}') pace", k + 1, s.class))?;
                }
                if let Some(t) = s.transition {
                    check_transition(t, &format!("segment {} ('{}') transition", k + 1, s.class))?;
                }
                position_of(classes, &s.class)
                    .with_context(|| format!("segment {}: unknown class '{}'{}; valid classes: {}", k + 1, s.class, meant(&s.class, classes), classes.join(", ")))
            })
            .collect()
    }

    /// Resolves each segment's style against a model's `styles`, where it names one. A model
    /// without styles refuses any.
    pub fn validate_styles(&self, styles: &[String], model: &str) -> Result<Vec<Option<usize>>> {
        self.segments
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let Some(style) = &s.style else { return Ok(None) };
                if styles.is_empty() {
                    bail!("segment {} ('{}/{style}'): the {model} model has no styles; remove '/{style}' or choose a model with styles (models/all)", k + 1, s.class);
                }
                position_of(styles, style).map(Some).with_context(|| format!("segment {} ('{}/{style}'): unknown style '{style}'{}; valid styles: {}", k + 1, s.class, meant(style, styles), styles.join(", ")))
            })
            .collect()
    }

    /// Clears each segment's style that `styles` (a model's) does not have; how many were.
    pub fn keep_styles(&mut self, styles: &[String]) -> usize {
        let mut cleared = 0;
        for s in &mut self.segments {
            if s.style.as_ref().is_some_and(|n| position_of(styles, n).is_none()) {
                s.style = None;
                cleared += 1;
            }
        }
        cleared
    }

    /// Gives every segment without a style of its own `style` (a take's `--style`).
    pub fn with_style(mut self, style: &str) -> Timeline {
        for s in self.segments.iter_mut().filter(|s| s.style.is_none()) {
            s.style = Some(style.to_string());
        }
        self
    }
}

/// " (did you mean 'X'?)" when one of `names` is likely what a mistyped `name` meant.
fn meant(name: &str, names: &[String]) -> String {
    super::class_map::closest(name, names).map(|n| format!(" (did you mean '{n}'?)")).unwrap_or_default()
}

/// An activity as a timeline spells it: `CLASS`, or `CLASS/STYLE` where it names a style.
pub fn spelled(class: &str, style: Option<&str>) -> String {
    match style {
        Some(style) => format!("{class}/{style}"),
        None => class.to_string(),
    }
}

/// Where a model's class or style `name` is among `names`, whatever its case.
fn position_of(names: &[String], name: &str) -> Option<usize> {
    names.iter().position(|n| n.eq_ignore_ascii_case(name))
}

/// Longest transition between two segments, in seconds.
pub const MAX_TRANSITION_SECONDS: f32 = 10.0;

pub fn check_transition(t: f32, what: &str) -> Result<()> {
    if !(0.0..=MAX_TRANSITION_SECONDS).contains(&t) {
        bail!("{what} must be between 0 and {MAX_TRANSITION_SECONDS} seconds, got {t}");
    }
    Ok(())
}

fn check_pace(p: f32, what: &str) -> Result<()> {
    if !(MIN_PACE..=MAX_PACE).contains(&p) {
        bail!("{what} must be between {MIN_PACE} and {MAX_PACE}, got {p}");
    }
    Ok(())
}

/// `"sit:3,drink:5,walk:10"`; a segment may name its style after its class (`walk/tired:6`,
/// models with styles), and carry its own pace as `walk:10@1.5`, its own
/// transition length (seconds, into it from the previous segment) as `walk:10~0.5` and its
/// own variation seed as `walk:10#7`, in that order (`walk:10@1.5~0.5#7`).
impl FromStr for Timeline {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Self> {
        let mut segments = Vec::new();
        for (k, part) in s.split(',').map(str::trim).enumerate() {
            if part.is_empty() {
                continue;
            }
            let (class, rest) = part
                .split_once(':')
                .with_context(|| format!("segment {} '{part}': expected CLASS:SECONDS, e.g. walk:5", k + 1))?;
            let (rest, seed) = match rest.split_once('#') {
                Some((r, n)) => (r, Some(n.trim().parse::<u64>().with_context(|| format!("segment {} '{part}': seed '{n}' is not a whole number from 0 to {}", k + 1, u64::MAX))?)),
                None => (rest, None),
            };
            let (rest, transition) = match rest.split_once('~') {
                Some((r, t)) => (r, Some(t.trim().parse::<f32>().with_context(|| format!("segment {} '{part}': transition '{t}' is not a number of seconds", k + 1))?)),
                None => (rest, None),
            };
            let (secs, pace) = match rest.split_once('@') {
                Some((s, p)) => (s, Some(p.trim().parse::<f32>().with_context(|| format!("segment {} '{part}': pace '{p}' is not a number", k + 1))?)),
                None => (rest, None),
            };
            let seconds = secs.trim().parse::<f32>().with_context(|| format!("segment {} '{part}': duration '{secs}' is not a number", k + 1))?;
            let (class, style) = match class.split_once('/') {
                Some((c, s)) if s.trim().is_empty() => bail!("segment {} '{part}': the style after '{}/' is empty", k + 1, c.trim()),
                Some((c, s)) => (c, Some(s.trim().to_string())),
                None => (class, None),
            };
            segments.push(Segment { class: class.trim().to_string(), style, seconds, pace, transition, seed, locked: false });
        }
        Ok(Timeline { segments })
    }
}

impl fmt::Display for Timeline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .segments
            .iter()
            .map(|s| {
                let pace = s.pace.map(|p| format!("@{p}")).unwrap_or_default();
                let transition = s.transition.map(|t| format!("~{t}")).unwrap_or_default();
                let seed = s.seed.map(|n| format!("#{n}")).unwrap_or_default();
                format!("{}:{}{pace}{transition}{seed}", spelled(&s.class, s.style.as_deref()), s.seconds)
            })
            .collect();
        f.write_str(&parts.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn classes() -> Vec<String> {
        ["sitting", "eating", "walking"].map(String::from).to_vec()
    }

    #[test]
    fn parses_and_prints() {
        let t: Timeline = "sitting:3, eating:5@1.5,walking:10".parse().unwrap();
        assert_eq!(t.segments.len(), 3);
        assert_eq!(t.segments[1].pace, Some(1.5));
        assert_eq!(t.to_string(), "sitting:3,eating:5@1.5,walking:10");
        assert_eq!(t.validate(&classes(), 1.0).unwrap(), vec![0, 1, 2]);
        let t: Timeline = "sitting:3,walking:4@2~0.5".parse().unwrap();
        assert_eq!(t.segments[1].transition, Some(0.5));
        assert_eq!(t.to_string(), "sitting:3,walking:4@2~0.5");
        assert!(format!("{:#}", "sitting:3,walking:4~-1".parse::<Timeline>().unwrap().validate(&classes(), 1.0).unwrap_err()).contains("transition must be between 0 and 10"));
        let t: Timeline = "sitting:3#0,walking:4@2~0.5#18446744073709551615,eating:2~1#7".parse().unwrap();
        assert_eq!(t.segments.iter().map(|s| s.seed).collect::<Vec<_>>(), [Some(0), Some(u64::MAX), Some(7)]);
        assert_eq!(t.segments[1].transition, Some(0.5));
        assert_eq!(t.to_string().parse::<Timeline>().unwrap(), t, "seeds round-trip through the text form");
        assert!(format!("{:#}", "walking:4#x".parse::<Timeline>().unwrap_err()).contains("segment 1 'walking:4#x': seed 'x' is not a whole number"));
        assert!(format!("{:#}", "walking:4#-3".parse::<Timeline>().unwrap_err()).contains("seed '-3'"));
    }

    #[test]
    fn styles_are_parsed_printed_and_checked_against_the_model() {
        let t: Timeline = "walking/tired:6,sitting:3@1.5".parse().unwrap();
        assert_eq!(t.segments[0].style.as_deref(), Some("tired"));
        assert_eq!(t.segments[0].class, "walking");
        assert_eq!(t.to_string(), "walking/tired:6,sitting:3@1.5");
        let styles = ["neutral", "tired"].map(String::from);
        assert_eq!(t.validate_styles(&styles, "all").unwrap(), [Some(1), None]);
        assert_eq!(t.clone().with_style("neutral").validate_styles(&styles, "all").unwrap(), [Some(1), Some(0)]);
        assert!(format!("{:#}", t.validate_styles(&[], "h36m").unwrap_err()).contains("the h36m model has no styles"));
        assert!(format!("{:#}", "walking/sad:2".parse::<Timeline>().unwrap().validate_styles(&styles, "all").unwrap_err()).contains("unknown style 'sad'; valid styles: neutral, tired"));
        assert!(format!("{:#}", "walking/tird:2".parse::<Timeline>().unwrap().validate_styles(&styles, "all").unwrap_err()).contains("unknown style 'tird' (did you mean 'tired'?); valid styles"));
        assert!(format!("{:#}", "walking/:2".parse::<Timeline>().unwrap_err()).contains("the style after 'walking/' is empty"));
    }

    #[test]
    fn bad_timelines_say_what_is_wrong() {
        let err = |s: &str, pace: f32| format!("{:#}", s.parse::<Timeline>().and_then(|t| t.validate(&classes(), pace).map(|_| ())).unwrap_err());
        assert!(err("dance:3", 1.0).contains("unknown class 'dance'; valid classes: sitting, eating, walking"));
        assert!(err("walk:3", 1.0).contains("unknown class 'walk' (did you mean 'walking'?); valid classes: sitting, eating, walking"));
        assert!(err("sitting:2,Eat ing:3", 1.0).contains("segment 2: unknown class 'Eat ing' (did you mean 'eating'?)"));
        assert!(err("", 1.0).contains("empty"));
        assert!(err("walking:0", 1.0).contains("positive"));
        assert!(err("walking:-2", 1.0).contains("positive"));
        assert!(err("walking:x", 1.0).contains("not a number"));
        assert!(err("walking", 1.0).contains("CLASS:SECONDS"));
        assert!(err("walking:3", 11.0).contains("between 0.1 and 10"));
        assert!(err("walking:3@0.05", 1.0).contains("pace"));
        assert!(err("walking:3000,sitting:601", 1.0).contains("at most 3600 s"));
        assert!(err("walking:1e9", 1.0).contains("at most 3600 s"));
    }
}
