//! Carrying a timeline from one model to another: each class of the old model is mapped to
//! a class of the new one, by a small table for the shipped pair (Human3.6M and Bandai) and
//! by name similarity otherwise. Plain data, so the studio can show and edit the result.

use serde::{Deserialize, Serialize};

use super::Timeline;

/// How a class found its counterpart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MatchKind {
    /// The same name (ignoring case and punctuation).
    Same,
    /// The shipped table (or an edit by the user).
    Table,
    /// The most similar name.
    Similar,
    /// Nothing alike: the new model's first class.
    Fallback,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassPair {
    pub from: String,
    pub to: String,
    pub kind: MatchKind,
}

/// The mapping from every class of one model to a class of another.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassMap {
    pub pairs: Vec<ClassPair>,
}

/// Human3.6M's ten actions and Bandai's ten motions, both ways. Bandai has no sitting or
/// eating: standing activities with the hands busy go to `guide` (a pointing gesture),
/// greetings to `bye` / `bow`; every kind of walk, run and dash goes to `walking`.
pub const SHIPPED_TABLE: &[(&str, &str)] = &[
    ("walking", "walk"),
    ("directions", "guide"),
    ("discussion", "guide"),
    ("eating", "guide"),
    ("phoning", "guide"),
    ("smoking", "guide"),
    ("posing", "bow"),
    ("greeting", "bye"),
    ("sitting", "guide"),
    ("sittingdown", "bow"),
    ("walk", "walking"),
    ("run", "walking"),
    ("dash", "walking"),
    ("walk-back", "walking"),
    ("walk-left", "walking"),
    ("walk-right", "walking"),
    ("bow", "greeting"),
    ("bye", "greeting"),
    ("byebye", "greeting"),
    ("guide", "directions"),
];

/// Below this similarity (0..1) a name is not taken as a counterpart.
const MIN_SIMILARITY: f64 = 0.6;
/// From this similarity a name unknown to a model is taken for a typo of one it knows: a
/// letter left out or swapped ("bybye", "tird") reads 0.9 and more, an unrelated activity
/// ("salsa" against "walk-back") 0.6.
const TYPO_SIMILARITY: f64 = 0.85;

fn normalized(name: &str) -> String {
    name.chars().filter(|c| c.is_alphanumeric()).flat_map(char::to_lowercase).collect()
}

/// Similarity of two class names: 1 when one is the other plus a suffix ("walk",
/// "walking"), else Jaro-Winkler on the normalised names.
fn similarity(a: &str, b: &str) -> f64 {
    let (a, b) = (normalized(a), normalized(b));
    if a.is_empty() || b.is_empty() {
        return 0.0;
    }
    if a.starts_with(&b) || b.starts_with(&a) {
        return 0.95;
    }
    strsim::jaro_winkler(&a, &b)
}

/// The one of `names` that is `name` but for case and punctuation.
fn same_name<'n>(name: &str, names: &'n [String]) -> Option<&'n String> {
    let key = normalized(name);
    names.iter().find(|n| normalized(n) == key)
}

/// The shortest of `names` that is `name` plus a suffix: the same activity in another
/// dataset's words ("run", "running"; "walk", "walking", not "walk-back").
fn longer_form<'n>(name: &str, names: &'n [String]) -> Option<&'n String> {
    let key = normalized(name);
    if key.is_empty() {
        return None;
    }
    names.iter().filter(|n| normalized(n).starts_with(&key)).min_by_key(|n| normalized(n).len())
}

/// The one of `names` most similar to `name`, when it is at least `at_least` similar.
fn most_similar<'n>(name: &str, names: &'n [String], at_least: f64) -> Option<&'n String> {
    names.iter().map(|n| (similarity(name, n), n)).max_by(|x, y| x.0.total_cmp(&y.0)).filter(|(s, _)| *s >= at_least).map(|(_, n)| n)
}

/// The one of `names` a mistyped `name` most likely meant: the same name but for case and
/// punctuation ("sitting down", "sittingdown"), its longer form ("walk", "walking"), or a
/// name as similar as a typo makes it ([`TYPO_SIMILARITY`]).
pub fn closest<'n>(name: &str, names: &'n [String]) -> Option<&'n str> {
    if normalized(name).is_empty() {
        return None;
    }
    let found = same_name(name, names).or_else(|| longer_form(name, names)).or_else(|| most_similar(name, names, TYPO_SIMILARITY));
    found.map(String::as_str)
}

impl ClassMap {
    /// Maps each of `from` to one of `to` (which must not be empty). `table` pairs are
    /// used when both names exist; user edits come first in it.
    pub fn build(from: &[String], to: &[String], table: &[(String, String)]) -> ClassMap {
        let pairs = from
            .iter()
            .map(|f| {
                let pair = |to: &String, kind| ClassPair { from: f.clone(), to: to.clone(), kind };
                if let Some(same) = same_name(f, to) {
                    return pair(same, MatchKind::Same);
                }
                if let Some(longer) = longer_form(f, to) {
                    return pair(longer, MatchKind::Similar);
                }
                if let Some(t) = table.iter().filter(|(a, _)| normalized(a) == normalized(f)).find_map(|(_, b)| same_name(b, to)) {
                    return pair(t, MatchKind::Table);
                }
                match most_similar(f, to, MIN_SIMILARITY) {
                    Some(c) => pair(c, MatchKind::Similar),
                    None => pair(&to[0], MatchKind::Fallback),
                }
            })
            .collect();
        ClassMap { pairs }
    }

    /// The shipped table as owned pairs (for [`ClassMap::build`]).
    pub fn shipped_table() -> Vec<(String, String)> {
        SHIPPED_TABLE.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect()
    }

    /// The new class for `name`, if `name` is one of the old model's classes.
    pub fn get(&self, name: &str) -> Option<&str> {
        self.pairs.iter().find(|p| normalized(&p.from) == normalized(name)).map(|p| p.to.as_str())
    }

    /// Sets the counterpart of `from` (an edit by the user).
    pub fn set(&mut self, from: &str, to: &str) {
        if let Some(p) = self.pairs.iter_mut().find(|p| p.from == from) {
            p.to = to.to_string();
            p.kind = MatchKind::Table;
        }
    }

    /// The timeline with every known class replaced; durations and paces are kept.
    /// Returns it and how many segments changed class.
    pub fn apply(&self, timeline: &Timeline) -> (Timeline, usize) {
        let mut out = timeline.clone();
        let mut changed = 0;
        for s in &mut out.segments {
            if let Some(to) = self.get(&s.class) {
                if to != s.class {
                    s.class = to.to_string();
                    changed += 1;
                }
            }
        }
        (out, changed)
    }

    /// "walking -> walk, sitting -> guide" for the pairs that occur in `timeline` and change.
    pub fn describe(&self, timeline: &Timeline) -> String {
        let mut used: Vec<&ClassPair> = Vec::new();
        for s in &timeline.segments {
            if let Some(p) = self.pairs.iter().find(|p| normalized(&p.from) == normalized(&s.class)) {
                if p.from != p.to && !used.iter().any(|u| u.from == p.from) {
                    used.push(p);
                }
            }
        }
        used.iter().map(|p| format!("{} -> {}", p.from, p.to)).collect::<Vec<_>>().join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    const H36M: &[&str] = &["directions", "discussion", "eating", "greeting", "phoning", "posing", "sitting", "sittingdown", "smoking", "walking"];
    const BANDAI: &[&str] = &["walk", "run", "dash", "walk-back", "walk-left", "walk-right", "bow", "bye", "guide", "byebye"];

    #[test]
    fn the_shipped_pair_maps_every_class_by_the_table() {
        let map = ClassMap::build(&names(H36M), &names(BANDAI), &ClassMap::shipped_table());
        assert_eq!(map.get("walking"), Some("walk"));
        assert_eq!(map.get("directions"), Some("guide"));
        assert!(map.pairs.iter().all(|p| p.kind == MatchKind::Table), "{map:?}");
        let back = ClassMap::build(&names(BANDAI), &names(H36M), &ClassMap::shipped_table());
        assert_eq!(back.get("walk-left"), Some("walking"));
        assert!(back.pairs.iter().all(|p| H36M.contains(&p.to.as_str())));
    }

    /// The model of everything merges "walk" and "walking", "run" and "running": a Bandai
    /// timeline's run stays a run there, though the shipped table sends it to h36m's walking.
    #[test]
    fn a_shorter_name_goes_to_its_longer_form_before_the_table() {
        let all = names(&["walking", "running", "walk-back", "walk-left", "bow", "sitting"]);
        let map = ClassMap::build(&names(BANDAI), &all, &ClassMap::shipped_table());
        assert_eq!((map.get("walk"), map.get("run"), map.get("walk-back")), (Some("walking"), Some("running"), Some("walk-back")));
        let back = ClassMap::build(&names(BANDAI), &names(H36M), &ClassMap::shipped_table());
        assert_eq!(back.get("run"), Some("walking"));
    }

    #[test]
    fn a_mistyped_name_finds_the_one_meant() {
        let all = names(&["walking", "walk-back", "sittingdown", "byebye", "basketball_signal"]);
        assert_eq!(closest("sitting down", &all), Some("sittingdown"));
        assert_eq!(closest("walk", &all), Some("walking"));
        assert_eq!(closest("Basketball-Signal", &all), Some("basketball_signal"));
        assert_eq!(closest("bybye", &all), Some("byebye"));
        assert_eq!(closest("salsa", &all), None);
        assert_eq!(closest("tango", &all), None);
        assert_eq!(closest("-", &all), None);
    }

    #[test]
    fn similar_names_match_and_durations_stay() {
        let map = ClassMap::build(&names(&["Walking", "jumping", "xyz"]), &names(&["walk", "jump_high", "idle"]), &[]);
        assert_eq!(map.pairs[0].kind, MatchKind::Similar);
        assert_eq!(map.get("walking"), Some("walk"));
        assert_eq!(map.get("jumping"), Some("jump_high"));
        assert_eq!((map.get("xyz"), map.pairs[2].kind), (Some("walk"), MatchKind::Fallback));
        let t: Timeline = "Walking:3.5,xyz:2@1.5".parse().unwrap();
        let (mapped, changed) = map.apply(&t);
        assert_eq!(changed, 2);
        assert_eq!(mapped.segments[0].seconds, 3.5);
        assert_eq!(mapped.segments[1].pace, Some(1.5));
        assert_eq!(map.describe(&t), "Walking -> walk, xyz -> walk");
    }
}
