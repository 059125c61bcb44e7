//! What an artist pins on the timeline besides the classes: keyframe poses the take passes
//! through, and a root path on the ground that its locomotion follows. Parsed and checked
//! here; [`super::generate`] plans and applies them.

use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use super::init::InitPose;
use crate::data::input::read_text;

/// Keys closer together than this are refused: two full-body poses a fraction of a second
/// apart leave the body no room to move naturally between them.
pub const MIN_KEY_GAP_SECONDS: f32 = 0.5;

/// Most keys one take may hold (each is a pose to reach; this keeps a take's plan bounded).
pub const MAX_KEYS: usize = 1000;

/// Most waypoints one path may hold.
pub const MAX_WAYPOINTS: usize = 10_000;

/// Consecutive waypoints closer than this (metres) are one place clicked twice: the path has
/// no direction between them.
const MIN_WAYPOINT_GAP_M: f32 = 0.01;

/// A path file larger than this is not a path (10 000 waypoints take well under 1 MB).
const MAX_PATH_BYTES: u64 = 4 << 20;

/// Where a key's pose comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum KeySource {
    /// The last pose of a seed-bank window, or the first frame a motion file gives from its
    /// frame on, as `--init` chooses them.
    Init(InitPose),
    /// World joint positions on the model's skeleton, in its units (a frame of a take).
    Pose(Vec<[f32; 3]>),
}

/// A full-body pose the take passes through at a time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Key {
    /// Seconds from the take's start.
    pub seconds: f32,
    pub source: KeySource,
    /// The key also fixes where the body stands and which way it faces (a frame of a take
    /// does); otherwise only the body's pose relative to its root is pinned.
    #[serde(default)]
    pub fix_root: bool,
}

/// One waypoint of a root path, on the ground in metres (x right, z forward).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    pub x: f32,
    pub z: f32,
    /// When the root should pass here; waypoints without a time are spread by arc length
    /// between the timed ones, at the class's own speed where no time bounds them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f32>,
}

/// The path the root follows on the ground, from its first waypoint.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RootPath {
    pub waypoints: Vec<Waypoint>,
}

impl Key {
    /// Parses the CLI's `TIME=SOURCE[,root]`, SOURCE as `--init` takes it
    /// (`seed:CLASS`, `seed:N`, `clip:PATH@FRAME`).
    pub fn parse(s: &str, parse_source: impl Fn(&str) -> Result<InitPose>) -> Result<Self> {
        let (time, rest) = s.split_once('=').with_context(|| format!("--key {s}: expected TIME=SOURCE, for example 3.5=seed:walking"))?;
        let seconds: f32 = time.trim().parse().ok().filter(|t: &f32| t.is_finite()).with_context(|| format!("--key {s}: time '{time}' is not a number of seconds"))?;
        let (source, fix_root) = match rest.strip_suffix(",root") {
            Some(source) => (source, true),
            None => (rest, false),
        };
        Ok(Self { seconds, source: KeySource::Init(parse_source(source)?), fix_root })
    }
}

/// Checks keys against the take's length: inside the take, after its seed, apart.
pub fn check_keys(keys: &[Key], take_seconds: f32, seed_seconds: f32) -> Result<()> {
    if keys.len() > MAX_KEYS {
        bail!("{} keys: a take holds at most {MAX_KEYS}", keys.len());
    }
    let mut times: Vec<f32> = keys.iter().map(|k| k.seconds).collect();
    times.sort_by(f32::total_cmp);
    for &t in &times {
        if !t.is_finite() || t < seed_seconds || t > take_seconds {
            bail!("key at {t} s: keys must lie between the end of the starting poses ({seed_seconds:.2} s) and the take's end ({take_seconds:.2} s)");
        }
    }
    if let Some(w) = times.windows(2).find(|w| w[1] - w[0] < MIN_KEY_GAP_SECONDS) {
        bail!("keys at {} s and {} s: keys must be at least {MIN_KEY_GAP_SECONDS} s apart", w[0], w[1]);
    }
    Ok(())
}

impl RootPath {
    /// Reads a path file: JSON (`[{"x": 0, "z": 0, "seconds": 0}, ...]` or
    /// `{"waypoints": [...]}`) or CSV (`seconds,x,z` per line, `seconds` may be empty, an
    /// optional header line), in metres.
    pub fn read(path: &Path) -> Result<Self> {
        let text = read_text(path, MAX_PATH_BYTES)?;
        let is_json = text.trim_start().starts_with(['[', '{']);
        let parsed = if is_json { Self::from_json(&text) } else { Self::from_csv(&text) };
        let route = parsed.with_context(|| format!("{}", path.display()))?;
        route.check().with_context(|| format!("{}", path.display()))?;
        Ok(route)
    }

    fn from_json(text: &str) -> Result<Self> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Form {
            List(Vec<Waypoint>),
            Object(RootPath),
        }
        Ok(match serde_json::from_str::<Form>(text).context("not a path: expected a list of {\"x\", \"z\", \"seconds\"} waypoints")? {
            Form::List(waypoints) => Self { waypoints },
            Form::Object(path) => path,
        })
    }

    fn from_csv(text: &str) -> Result<Self> {
        let mut waypoints = Vec::new();
        for (n, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#')) {
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if n == 0 && fields.iter().any(|f| f.chars().any(char::is_alphabetic)) {
                continue;
            }
            let [t, x, z] = fields[..] else { bail!("line {}: expected seconds,x,z, got {} fields", n + 1, fields.len()) };
            let number = |v: &str, what: &str| v.parse::<f32>().ok().filter(|v| v.is_finite()).with_context(|| format!("line {}: {what} '{v}' is not a number", n + 1));
            let seconds = if t.is_empty() { None } else { Some(number(t, "seconds")?) };
            waypoints.push(Waypoint { x: number(x, "x")?, z: number(z, "z")?, seconds });
        }
        Ok(Self { waypoints })
    }

    /// At least two waypoints, finite, times increasing where given.
    pub fn check(&self) -> Result<()> {
        let n = self.waypoints.len();
        if !(2..=MAX_WAYPOINTS).contains(&n) {
            bail!("a path needs 2 to {MAX_WAYPOINTS} waypoints, got {n}");
        }
        for (i, w) in self.waypoints.iter().enumerate() {
            if !(w.x.is_finite() && w.z.is_finite() && w.x.abs() < 1e5 && w.z.abs() < 1e5) {
                bail!("waypoint {}: position ({}, {}) is not a finite point within 100 km", i + 1, w.x, w.z);
            }
            if w.seconds.is_some_and(|t| !(t.is_finite() && t >= 0.0)) {
                bail!("waypoint {}: time {:?} is not a non-negative number of seconds", i + 1, w.seconds);
            }
        }
        if let Some(i) = (1..n).find(|&i| {
            let (a, b) = (self.waypoints[i - 1], self.waypoints[i]);
            (a.x - b.x).hypot(a.z - b.z) < MIN_WAYPOINT_GAP_M
        }) {
            bail!("waypoint {}: at the same place as waypoint {i} (waypoints must be at least {} cm apart)", i + 1, MIN_WAYPOINT_GAP_M * 100.0);
        }
        let times: Vec<(usize, f32)> = self.waypoints.iter().enumerate().filter_map(|(i, w)| Some((i, w.seconds?))).collect();
        if let Some(w) = times.windows(2).find(|w| w[1].1 <= w[0].1) {
            bail!("waypoint {}: time {} s is not after waypoint {}'s {} s", w[1].0 + 1, w[1].1, w[0].0 + 1, w[0].1);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_syntax() {
        let seed = |s: &str| Ok(InitPose::SeedClass { class: s.trim_start_matches("seed:").into(), variant: 0 });
        let key = Key::parse("3.5=seed:walking,root", seed).unwrap();
        assert_eq!((key.seconds, key.fix_root), (3.5, true));
        assert_eq!(key.source, KeySource::Init(InitPose::SeedClass { class: "walking".into(), variant: 0 }));
        assert!(!Key::parse("2=seed:eating", seed).unwrap().fix_root);
        assert!(Key::parse("x=seed:eating", seed).unwrap_err().to_string().contains("time 'x'"));
        assert!(Key::parse("seed:eating", seed).is_err());
    }

    #[test]
    fn keys_inside_and_apart() {
        let key = |t| Key { seconds: t, source: KeySource::Pose(vec![]), fix_root: false };
        assert!(check_keys(&[key(3.0), key(6.0)], 10.0, 2.0).is_ok());
        assert!(check_keys(&[key(1.0)], 10.0, 2.0).unwrap_err().to_string().contains("between"));
        assert!(check_keys(&[key(3.0), key(3.2)], 10.0, 2.0).unwrap_err().to_string().contains("apart"));
    }

    #[test]
    fn path_forms() {
        let csv = RootPath::from_csv("seconds,x,z\n0,0,0\n,2,0\n5,2,3\n").unwrap();
        assert_eq!(csv.waypoints.len(), 3);
        assert_eq!(csv.waypoints[1].seconds, None);
        let json = RootPath::from_json(r#"[{"x":0,"z":0,"seconds":0},{"x":2,"z":0},{"x":2,"z":3,"seconds":5}]"#).unwrap();
        assert_eq!(csv, json);
        assert!(RootPath::from_csv("0,0\n").unwrap_err().to_string().contains("line 1"));
        let backwards = RootPath { waypoints: vec![Waypoint { x: 0.0, z: 0.0, seconds: Some(3.0) }, Waypoint { x: 1.0, z: 0.0, seconds: Some(1.0) }] };
        assert!(backwards.check().unwrap_err().to_string().contains("waypoint 2"));
        let twice = RootPath { waypoints: vec![Waypoint { x: 1.0, z: 0.0, seconds: None }; 2] };
        assert!(twice.check().unwrap_err().to_string().contains("same place"));
    }
}
