//! Advice on timelines the model is known not to follow as written, with a fix the user can
//! apply in one click. No egui here.

use crate::synth::{Segment, Timeline};

/// How long a seated activity needs, right after a standing one, for the take to end
/// seated. Measured on the shipped h36m model with the default anchored 2 s transition
/// (`glocal generate --timeline "walking:4,sitting:S" --json`, hips above the lowest joint
/// at the last frame), before this round's seam join: S = 3 s ended at 0.90 m, still
/// standing as in the walk; 3.5 s at 0.72 m, on the way down; 4 s at 0.58 m and 5-6 s at
/// 0.64-0.68 m, seated. With the join that takes the block's own first step (2026-12-01),
/// S = 3 s ends at 0.55 m from the canonical start and 4.5-6 s at 0.59-0.67 m, so the rule
/// is now on the safe side: the seated run (consecutive seated segments) after a standing
/// segment lasts at least 4 s.
pub const SEATED_AFTER_STANDING_SECONDS: f32 = 4.0;

/// How long a `sittingdown` segment the fix inserts lasts: about as long as a real sit-down.
/// walking:4, sittingdown:1, sitting:3 ends at 0.67 m (0.76 of standing, still on the way
/// down); with 2 s of sittingdown it ends at 0.60 m (noise seeds 0-2: 0.43-0.60 m).
pub const SITTING_DOWN_SECONDS: f32 = 2.0;

/// A class whose poses are seated (h36m's `sitting` and `sittingdown`; Bandai has none).
pub fn is_seated(class: &str) -> bool {
    class.to_lowercase().contains("sit")
}

/// A way to make a seated run long enough.
#[derive(Clone, Debug, PartialEq)]
pub enum Fix {
    /// Insert the model's sitting-down class before segment `at`.
    InsertSittingDown { at: usize, class: String },
    /// Make segment `index` last `seconds`.
    Lengthen { index: usize, seconds: f32 },
}

/// A seated run too short to end seated.
#[derive(Clone, Debug, PartialEq)]
pub struct SeatedTooShort {
    /// The run's segments (indices), the first after a standing segment.
    pub first: usize,
    pub last: usize,
    pub seconds: f32,
    pub fixes: Vec<Fix>,
}

impl SeatedTooShort {
    pub fn message(&self) -> String {
        let which = if self.first == self.last { format!("segment {}", self.first + 1) } else { format!("segments {}-{}", self.first + 1, self.last + 1) };
        format!("The seated activity in {which} follows a standing one and lasts under {SEATED_AFTER_STANDING_SECONDS:.0} s: the take will likely end it still standing (the model needs about that long to sit down from a walk).")
    }
}

impl Fix {
    pub fn label(&self) -> String {
        match self {
            Fix::InsertSittingDown { class, .. } => format!("Insert {class} ({SITTING_DOWN_SECONDS:.0} s) before it"),
            Fix::Lengthen { index, seconds } => format!("Lengthen segment {} to {seconds:.1} s", index + 1),
        }
    }

    pub fn apply(&self, timeline: &mut Timeline) {
        match self {
            Fix::InsertSittingDown { at, class } => timeline.segments.insert((*at).min(timeline.segments.len()), Segment::new(class.clone(), SITTING_DOWN_SECONDS)),
            Fix::Lengthen { index, seconds } => {
                if let Some(s) = timeline.segments.get_mut(*index) {
                    s.seconds = *seconds;
                }
            }
        }
    }
}

/// Seated runs after a standing segment that are shorter than
/// [`SEATED_AFTER_STANDING_SECONDS`], with their fixes (`classes`: the model's).
pub fn seated_too_short(timeline: &Timeline, classes: &[String]) -> Vec<SeatedTooShort> {
    let segments = &timeline.segments;
    let sitting_down = classes.iter().find(|c| c.to_lowercase().contains("sittingdown") || c.to_lowercase().contains("sit down"));
    let mut out = Vec::new();
    let mut k = 1;
    while k < segments.len() {
        if !is_seated(&segments[k].class) || is_seated(&segments[k - 1].class) {
            k += 1;
            continue;
        }
        let first = k;
        while k + 1 < segments.len() && is_seated(&segments[k + 1].class) {
            k += 1;
        }
        let seconds: f32 = segments[first..=k].iter().map(|s| s.seconds).sum();
        if seconds < SEATED_AFTER_STANDING_SECONDS {
            let mut fixes = Vec::new();
            let starts_down = sitting_down.is_some_and(|c| segments[first].class.eq_ignore_ascii_case(c));
            if let (Some(class), false) = (sitting_down, starts_down) {
                if seconds + SITTING_DOWN_SECONDS >= SEATED_AFTER_STANDING_SECONDS {
                    fixes.push(Fix::InsertSittingDown { at: first, class: class.clone() });
                }
            }
            fixes.push(Fix::Lengthen { index: k, seconds: segments[k].seconds + SEATED_AFTER_STANDING_SECONDS - seconds });
            out.push(SeatedTooShort { first, last: k, seconds, fixes });
        }
        k += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h36m() -> Vec<String> {
        ["directions", "sitting", "sittingdown", "walking"].map(String::from).to_vec()
    }

    #[test]
    fn a_short_sit_after_a_walk_gets_both_fixes() {
        let timeline: Timeline = "walking:4,sitting:3".parse().unwrap();
        let found = seated_too_short(&timeline, &h36m());
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].fixes, vec![Fix::InsertSittingDown { at: 1, class: "sittingdown".into() }, Fix::Lengthen { index: 1, seconds: 4.0 }]);
        for fix in &found[0].fixes {
            let mut fixed = timeline.clone();
            fix.apply(&mut fixed);
            assert!(seated_too_short(&fixed, &h36m()).is_empty(), "{fix:?} leaves {fixed:?} too short");
        }
    }

    #[test]
    fn long_runs_seated_starts_and_no_sitting_down_class() {
        let ok = |t: &str| seated_too_short(&t.parse().unwrap(), &h36m()).is_empty();
        assert!(ok("walking:4,sitting:4"));
        assert!(ok("walking:4,sittingdown:1,sitting:3"));
        assert!(ok("sitting:2,walking:4"), "a take that starts seated");
        assert!(!ok("walking:4,sittingdown:1,sitting:2"));
        let bandai: Vec<String> = ["walk", "bow"].map(String::from).to_vec();
        assert!(seated_too_short(&"walk:4,bow:1".parse().unwrap(), &bandai).is_empty());
        let no_down = seated_too_short(&"walking:4,sitting:2".parse().unwrap(), &["walking".to_string(), "sitting".to_string()]);
        assert_eq!(no_down[0].fixes, vec![Fix::Lengthen { index: 1, seconds: 4.0 }]);
    }
}
