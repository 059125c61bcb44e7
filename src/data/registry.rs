//! The four datasets: where their files are, their classes, and their train/test splits.
//!
//! Splits follow `../shared/data/README.md`: h36m tests on subject S11; bandai on the styles
//! `tired` and `musical`; cmu-dance on the highest-numbered clip of each class; cmu-expmap on
//! its own `test` folder. Bandai's held-out styles are each taught from half of their test
//! clips ([`Clip::teaches_style`]) so a model with styles knows all fifteen.

use std::fmt;
use std::str::FromStr;

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;

use super::archive::DataRoot;
use super::bvh;
use super::expmap::{ExpmapFormat, RootEncoding};
use super::FormatError;
use crate::motion::Motion;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Dataset {
    H36m,
    Bandai,
    CmuDance,
    CmuExpmap,
    /// The four archives' clips on the standard humanoid ([`super::combined`]): `models/all`.
    Combined,
}

impl Dataset {
    /// The datasets stored as archives.
    pub const ARCHIVES: [Dataset; 4] = [Dataset::H36m, Dataset::Bandai, Dataset::CmuDance, Dataset::CmuExpmap];
    pub const ALL: [Dataset; 5] = [Dataset::H36m, Dataset::Bandai, Dataset::CmuDance, Dataset::CmuExpmap, Dataset::Combined];

    pub fn name(self) -> &'static str {
        match self {
            Dataset::H36m => "h36m",
            Dataset::Bandai => "bandai",
            Dataset::CmuDance => "cmu-dance",
            Dataset::CmuExpmap => "cmu-expmap",
            Dataset::Combined => "all",
        }
    }

    /// The frame rate the files are stored at (cmu-dance: what the headers say).
    pub fn source_fps(self) -> f32 {
        match self {
            Dataset::H36m => 50.0,
            Dataset::Bandai | Dataset::Combined => 30.0,
            Dataset::CmuDance | Dataset::CmuExpmap => 120.0,
        }
    }

    /// The frame rate the models work at.
    pub fn working_fps(self) -> f32 {
        match self {
            Dataset::H36m => 25.0,
            Dataset::Bandai | Dataset::CmuDance | Dataset::CmuExpmap | Dataset::Combined => 30.0,
        }
    }

    /// How an exponential-map file of this dataset encodes the root (None: a BVH dataset).
    pub fn root_encoding(self) -> Option<RootEncoding> {
        match self {
            Dataset::H36m => Some(RootEncoding::Incremental),
            Dataset::CmuExpmap => Some(RootEncoding::Absolute),
            Dataset::Bandai | Dataset::CmuDance | Dataset::Combined => None,
        }
    }

    pub fn meters_per_unit(self) -> f32 {
        match self {
            Dataset::H36m => 0.001,
            Dataset::Bandai => 0.01,
            // The acLSTM BVH files measure about 62 units from hips to head: centimetres.
            Dataset::CmuDance => 0.01,
            Dataset::CmuExpmap => CMU_METRES_PER_UNIT,
            Dataset::Combined => 1.0,
        }
    }
}

/// The CMU motion capture database's length unit in metres: its skeleton files declare
/// `length 0.45`, a unit of 1 / 0.45 inches.
pub const CMU_METRES_PER_UNIT: f32 = 0.056444;

impl fmt::Display for Dataset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Dataset {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Self> {
        Dataset::ALL.into_iter().find(|d| d.name() == s).with_context(|| {
            let names: Vec<_> = Dataset::ALL.iter().map(|d| d.name()).collect();
            format!("unknown dataset '{s}'; valid: {}", names.join(", "))
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    Train,
    Test,
}

/// One take with its labels.
#[derive(Clone, Debug)]
pub struct Clip {
    /// Path inside the archive.
    pub file: String,
    pub class: usize,
    pub split: Split,
    /// Bandai's style, Human3.6M's subject; on the combined dataset, the style (Bandai's, else
    /// [`super::combined::NEUTRAL`]).
    pub tag: String,
    /// A test clip a model with styles learns its style from, by the style's inputs alone
    /// (`glocal train --only-styles`): Bandai's tired clips of odd-numbered contents and its
    /// musical clips of even-numbered ones. Every class figure still tests on it; the style
    /// figures test on the other half.
    pub teaches_style: bool,
    pub motion: Motion,
}

#[derive(Clone, Debug, Serialize)]
pub struct Skipped {
    pub file: String,
    pub reason: String,
}

/// A loaded dataset: its classes, its clips at the source frame rate, and what was skipped.
#[derive(Clone, Debug)]
pub struct DatasetClips {
    pub dataset: Dataset,
    pub classes: Vec<String>,
    pub clips: Vec<Clip>,
    pub skipped: Vec<Skipped>,
    /// The styles the clips' tags name (the combined dataset only; empty otherwise).
    pub styles: Vec<String>,
    /// Where each class's clips come from ("h36m walking + bandai walk"; the combined dataset
    /// only).
    pub class_sources: Vec<String>,
}

impl DatasetClips {
    pub fn split(&self, split: Split) -> impl Iterator<Item = &Clip> {
        self.clips.iter().filter(move |c| c.split == split)
    }

    pub fn class_index(&self, name: &str) -> Option<usize> {
        self.classes.iter().position(|c| c == name)
    }
}

/// Loads every clip of one of [`Dataset::ARCHIVES`] from its archive (any dataset, the
/// combined one too: [`super::loading::load`]).
pub fn load_archive(dataset: Dataset, root: &DataRoot) -> Result<DatasetClips> {
    match dataset {
        Dataset::H36m | Dataset::CmuExpmap => load_expmap(dataset, root),
        Dataset::Bandai => load_bandai(root),
        Dataset::CmuDance => load_cmu_dance(root),
        Dataset::Combined => anyhow::bail!("{dataset} has no archive of its own: it is made from the others"),
    }
}

/// The exponential-map format of h36m or cmu-expmap, from its skeleton file.
pub fn expmap_format(dataset: Dataset, root: &DataRoot) -> Result<ExpmapFormat> {
    let encoding = dataset.root_encoding().with_context(|| format!("{dataset} is not an exponential-map dataset"))?;
    let file = if dataset == Dataset::H36m { "h36m-skeleton.json" } else { "cmu-expmap-skeleton.json" };
    let path = root.file(file);
    let text = std::fs::read_to_string(&path).with_context(|| format!("skeleton file {} is missing", path.display()))?;
    Ok(ExpmapFormat::from_skeleton_json(&text, &path.display().to_string(), encoding, dataset.source_fps(), dataset.meters_per_unit())?)
}

fn load_expmap(dataset: Dataset, root: &DataRoot) -> Result<DatasetClips> {
    let format = expmap_format(dataset, root)?;
    let entries = root.read_archive(dataset.name(), |p| p.ends_with(".txt"))?;
    let labelled: Vec<_> = entries
        .into_iter()
        .filter_map(|(path, bytes)| {
            let parts: Vec<&str> = path.split('/').collect();
            let stem = parts.last()?.strip_suffix(".txt")?;
            match dataset {
                // h36m/S1/walking_1.txt
                Dataset::H36m if parts.len() == 3 => {
                    let action = stem.rsplit_once('_')?.0.to_string();
                    let split = if parts[1] == "S11" { Split::Test } else { Split::Train };
                    Some((path.clone(), action, split, parts[1].to_string(), bytes))
                }
                // cmu-expmap/train/walking/walking_1.txt
                _ if parts.len() == 4 => {
                    let split = if parts[1] == "test" { Split::Test } else { Split::Train };
                    Some((path.clone(), parts[2].to_string(), split, parts[1].to_string(), bytes))
                }
                _ => None,
            }
        })
        .collect();
    let mut classes: Vec<String> = labelled.iter().map(|l| l.1.clone()).collect();
    classes.sort();
    classes.dedup();
    let parsed: Vec<Result<Clip, Skipped>> = labelled
        .into_par_iter()
        .map(|(file, action, split, tag, bytes)| {
            let class = classes.iter().position(|c| *c == action).expect("class collected above");
            let text = String::from_utf8(bytes).map_err(|_| skipped(&file, "not UTF-8 text"))?;
            let motion = format.read(&text, &file).map_err(|e| skipped_err(&file, e))?;
            Ok(Clip { file, class, split, tag, teaches_style: false, motion })
        })
        .collect();
    Ok(collect(dataset, classes, parsed))
}

/// Bandai's test styles; the one at a content's index modulo 2 is taught from that content's
/// clip ([`Clip::teaches_style`]), so each is taught on some contents and tested on the others.
const HELD_OUT_STYLES: [&str; 2] = ["musical", "tired"];

fn load_bandai(root: &DataRoot) -> Result<DatasetClips> {
    let dataset = Dataset::Bandai;
    let entries = root.read_archive("bandai", |p| p.ends_with(".bvh") || p.ends_with(".json") || p.contains("/cfg/"))?;
    let text_of = |name: &str| -> Result<String> {
        let (_, bytes) = entries.iter().find(|(p, _)| p.ends_with(name)).with_context(|| format!("bandai archive has no {name}"))?;
        Ok(String::from_utf8_lossy(bytes).into_owned())
    };
    let label = |l: &str| l.trim().trim_start_matches("dataset-1_").to_string();
    let contents: Vec<String> = text_of("cfg/content_label.txt")?.lines().filter(|l| !l.trim().is_empty()).map(label).collect();
    let styles: Vec<String> = text_of("cfg/style_label.txt")?.lines().filter(|l| !l.trim().is_empty()).map(label).collect();
    let json_of = |bvh_path: &str| entries.iter().find(|(p, _)| p == &bvh_path.replace(".bvh", ".json")).map(|(_, b)| b);

    #[derive(serde::Deserialize)]
    struct Labels {
        content: usize,
        style: usize,
    }
    let parsed: Vec<(Result<Clip, Skipped>, Option<String>)> = entries
        .par_iter()
        .filter(|(p, _)| p.ends_with(".bvh"))
        .map(|(file, bytes)| {
            let result = (|| {
                let labels: Labels = serde_json::from_slice(json_of(file).ok_or_else(|| skipped(file, "no label JSON beside it"))?)
                    .map_err(|e| skipped(file, &format!("label JSON: {e}")))?;
                let content = contents.get(labels.content).ok_or_else(|| skipped(file, "content index out of range"))?;
                let style = styles.get(labels.style).ok_or_else(|| skipped(file, "style index out of range"))?;
                let text = std::str::from_utf8(bytes).map_err(|_| skipped(file, "not UTF-8 text"))?;
                let motion = bvh::read_bvh_with_unit(text, file, dataset.meters_per_unit()).map_err(|e| skipped_err(file, e))?;
                let split = if HELD_OUT_STYLES.contains(&style.as_str()) { Split::Test } else { Split::Train };
                let teaches_style = HELD_OUT_STYLES.get(labels.content % 2) == Some(&style.as_str());
                Ok((content.clone(), Clip { file: file.clone(), class: 0, split, tag: style.clone(), teaches_style, motion }))
            })();
            match result {
                Ok((content, clip)) => (Ok(clip), Some(content)),
                Err(s) => (Err(s), None),
            }
        })
        .collect();
    // Classes: the contents that have clips, in the label file's order.
    let present: Vec<&String> = parsed.iter().filter_map(|(_, c)| c.as_ref()).collect();
    let classes: Vec<String> = contents.iter().filter(|c| present.contains(c)).cloned().collect();
    let parsed = parsed
        .into_iter()
        .map(|(clip, content)| {
            clip.map(|mut c| {
                c.class = classes.iter().position(|x| Some(x) == content.as_ref()).expect("present class");
                c
            })
        })
        .collect();
    Ok(collect(dataset, classes, parsed))
}

fn load_cmu_dance(root: &DataRoot) -> Result<DatasetClips> {
    let dataset = Dataset::CmuDance;
    let classes: Vec<String> = ["indian", "martial", "salsa"].map(String::from).to_vec();
    let test_clip = ["15", "10", "30"];
    let entries = root.read_archive("cmu-dance", |p| p.ends_with(".bvh") && p.matches('/').count() == 2)?;
    let parsed = entries
        .par_iter()
        .map(|(file, bytes)| {
            let parts: Vec<&str> = file.split('/').collect();
            let class = classes.iter().position(|c| c == parts[1]).ok_or_else(|| skipped(file, "not in a class folder"))?;
            let number = parts[2].trim_end_matches(".bvh");
            let text = std::str::from_utf8(bytes).map_err(|_| skipped(file, "not UTF-8 text"))?;
            let mut motion = bvh::read_bvh_with_unit(text, file, dataset.meters_per_unit()).map_err(|e| skipped_err(file, e))?;
            if classes[class] == "salsa" {
                // The source's readme: salsa was captured at 60 fps, whatever the header says.
                motion.fps = 60.0;
            }
            let split = if number == test_clip[class] { Split::Test } else { Split::Train };
            Ok(Clip { file: file.clone(), class, split, tag: number.to_string(), teaches_style: false, motion })
        })
        .collect();
    Ok(collect(dataset, classes, parsed))
}

fn skipped(file: &str, reason: &str) -> Skipped {
    Skipped { file: file.to_string(), reason: reason.to_string() }
}

fn skipped_err(file: &str, e: FormatError) -> Skipped {
    Skipped { file: file.to_string(), reason: e.to_string() }
}

fn collect(dataset: Dataset, classes: Vec<String>, parsed: Vec<Result<Clip, Skipped>>) -> DatasetClips {
    let mut clips = Vec::new();
    let mut skipped = Vec::new();
    for p in parsed {
        match p {
            Ok(c) => clips.push(c),
            Err(s) => skipped.push(s),
        }
    }
    clips.sort_by(|a, b| a.file.cmp(&b.file));
    skipped.sort_by(|a, b| a.file.cmp(&b.file));
    DatasetClips { dataset, classes, clips, skipped, styles: Vec::new(), class_sources: Vec::new() }
}
