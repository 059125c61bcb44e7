//! What every suite is given: the options of `glocal eval`, and what they resolve to (the
//! generation options, the shipped models' datasets and folders), resolved once for every
//! suite of a run.

use std::path::{Path, PathBuf};

use anyhow::Result;

use crate::data::archive::DataRoot;
use crate::data::registry::Dataset;
use crate::eval::classifier::cache_dir;
use crate::model::spec::ModelSpec;
use crate::synth::{GenerateOptions, Preset, Transition};

/// Takes per class and condition in the class-control matrix by default.
pub const CLASS_CONTROL_TAKES: usize = 16;

#[derive(Clone, Debug)]
pub struct SuiteOptions {
    pub data: DataRoot,
    /// Train the baselines (and the suite's own GloGen variants) when they are not cached.
    pub train_baselines: bool,
    /// The shipped model to evaluate (default `models/<dataset>`).
    pub model: Option<PathBuf>,
    pub cache: PathBuf,
    /// How the class-generation suites' takes change class (the shipped anchored transition,
    /// or the paper's class prior alone) and their class strength: for ablations.
    pub transition: Transition,
    /// None: each model's own ([`crate::model::spec::ModelSpec::class_strength`]).
    pub class_strength: Option<f32>,
    pub keep_alive: bool,
    /// GloGen's blocks joined at their seams ([`crate::model::glogen::GloGen::rollout_block`]).
    pub join_seams: bool,
    /// The models' motion texture laid over the takes' frames ([`crate::model::texture`]).
    pub texture: bool,
    /// LocGen refines the spline between GloGen's sparse poses (off: the spline alone; none:
    /// as each model's LocGen says).
    pub locgen: Option<bool>,
    /// Applied over the fields above: `Preset::Paper` is `glocal eval --paper`.
    pub preset: Preset,
    /// A reduced setting (fewer and shorter takes) where a suite has one.
    pub quick: bool,
    /// Takes per class and condition in the class-control matrix: each is 1 / (classes x
    /// takes) of an accuracy, so more takes tell 94% from 95%.
    pub class_control_takes: usize,
}

impl Default for SuiteOptions {
    fn default() -> Self {
        Self { data: DataRoot::resolve(None), train_baselines: false, model: None, cache: cache_dir(), transition: Transition::default(), class_strength: None, keep_alive: true, join_seams: true, texture: true, locgen: None, preset: Preset::Shipped, quick: false, class_control_takes: CLASS_CONTROL_TAKES }
    }
}

/// The options and what they resolve to, built once and handed to every suite of a run.
pub struct SuiteContext {
    pub options: SuiteOptions,
    /// The generation options the suite options ask for, the rest as shipped.
    pub generation: GenerateOptions,
    /// The shipped models' datasets a two-model suite runs on: `--model`'s own alone, or both.
    pub datasets: Vec<Dataset>,
}

impl SuiteContext {
    /// Fails when `--model` names a folder without a readable model.json.
    pub fn new(options: SuiteOptions) -> Result<Self> {
        let o = &options;
        let generation = o.preset.apply(GenerateOptions { transition: o.transition, class_strength: o.class_strength, keep_alive: o.keep_alive, join_seams: o.join_seams, texture: o.texture, locgen: o.locgen, ..Default::default() });
        let datasets = match &o.model {
            Some(p) => vec![ModelSpec::read(p)?.dataset.parse()?],
            None => vec![Dataset::H36m, Dataset::Bandai],
        };
        Ok(Self { options, generation, datasets })
    }

    /// The model folder evaluated on `dataset`: `--model`, or the shipped `models/<dataset>`
    /// (here, else in the crate).
    pub fn model_dir(&self, dataset: Dataset) -> PathBuf {
        self.options.model.clone().unwrap_or_else(|| {
            let here = PathBuf::from("models").join(dataset.name());
            if here.exists() {
                here
            } else {
                Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(dataset.name())
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-model suite given `--model` runs that model's dataset alone (the constraints
    /// suite once loaded an h36m model for Bandai too and failed on the classifier's shapes).
    #[test]
    fn a_given_model_runs_its_own_dataset_alone() {
        let shipped = |name: &str| Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name);
        let datasets = |model: Option<PathBuf>| SuiteContext::new(SuiteOptions { model, ..Default::default() }).map(|c| c.datasets);
        for (name, dataset) in [("h36m", Dataset::H36m), ("bandai", Dataset::Bandai)] {
            assert_eq!(datasets(Some(shipped(name))).unwrap(), vec![dataset]);
        }
        assert_eq!(datasets(None).unwrap(), vec![Dataset::H36m, Dataset::Bandai]);
        assert!(datasets(Some(PathBuf::from("no/such/model"))).is_err());
    }
}
