//! The evaluation suites behind `glocal eval --suite NAME`, one module each. Each is given
//! the run's [`SuiteContext`] and returns a markdown table (printed) and the same numbers as
//! JSON. Everything a suite trains is cached under the evaluation cache (`target/eval-cache`,
//! or `$GLOCAL_EVAL_CACHE`).

mod class_generation;
mod cmu_euclid;
mod constraints;
pub mod context;
mod feet_up;
mod first_takes;
mod h36m_mmd;
mod inbetween;
mod locgen;
mod long_term;
pub(crate) mod motion;
mod random_takes;
mod style_control;

use std::str::FromStr;
use std::time::Instant;

use anyhow::{anyhow, Result};
use serde_json::{json, Value};

use super::table::Table;
use crate::data::registry::Dataset;
use context::SuiteContext;

/// The suites behind `glocal eval --suite NAME`, in the order `all` runs them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Suite {
    CmuEuclid,
    H36mMmd,
    H36m,
    Bandai,
    /// Class control on the model of everything (`models/all`).
    Combined,
    /// Style control on the model of everything.
    Styles,
    Locgen,
    LongTerm,
    Motion,
    Constraints,
    Inbetween,
    /// The motion suite's first takes alone, and random takes ([`random_takes`]).
    FirstTakes,
}

impl Suite {
    pub const ALL: [Suite; 9] = [Suite::CmuEuclid, Suite::H36mMmd, Suite::H36m, Suite::Bandai, Suite::Locgen, Suite::LongTerm, Suite::Motion, Suite::Constraints, Suite::Inbetween];

    /// The name on the command line, in the report and in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Suite::CmuEuclid => "cmu-euclid",
            Suite::H36mMmd => "h36m-mmd",
            Suite::H36m => "h36m",
            Suite::Bandai => "bandai",
            Suite::Combined => "combined",
            Suite::Styles => "styles",
            Suite::Locgen => "locgen",
            Suite::LongTerm => "long-term",
            Suite::Motion => "motion",
            Suite::Constraints => "constraints",
            Suite::Inbetween => "inbetween",
            Suite::FirstTakes => "first-takes",
        }
    }
}

impl std::fmt::Display for Suite {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Suite {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Self> {
        // `first-takes` (the motion suite's first takes and random takes of its own), `combined`
        // and `styles` (the model of everything's) are not the paper's tables: `all` leaves them out.
        let named = Self::ALL.into_iter().chain([Suite::FirstTakes, Suite::Combined, Suite::Styles]);
        named.clone().find(|x| x.name() == s).ok_or_else(|| anyhow!("unknown suite '{s}'; valid: {}", named.map(Suite::name).collect::<Vec<_>>().join(", ")))
    }
}

pub struct SuiteReport {
    pub suite: Suite,
    pub markdown: String,
    /// The suite's numbers, with its printed tables under `rendered_tables`.
    pub json: Value,
}

/// Runs `suite` with the run's context; its JSON also holds its name, its seconds and its
/// printed tables.
pub fn run_suite(suite: Suite, ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<SuiteReport> {
    let start = Instant::now();
    let (markdown, mut json) = match suite {
        Suite::CmuEuclid => cmu_euclid::run(ctx, log)?,
        Suite::H36mMmd => h36m_mmd::run(ctx, log)?,
        Suite::H36m => class_generation::run(Dataset::H36m, ctx, log)?,
        Suite::Bandai => class_generation::run(Dataset::Bandai, ctx, log)?,
        Suite::Combined => class_generation::run(Dataset::Combined, ctx, log)?,
        Suite::Styles => style_control::run(ctx, log)?,
        Suite::Locgen => locgen::run(ctx, log)?,
        Suite::LongTerm => long_term::run(ctx, log)?,
        Suite::Motion => motion::run(ctx, log)?,
        Suite::Constraints => constraints::run(ctx, log)?,
        Suite::Inbetween => inbetween::run(ctx, log)?,
        Suite::FirstTakes => first_takes::run(ctx, log)?,
    };
    let (markdown, tables) = markdown.into_parts();
    json["suite"] = json!(suite.name());
    json["seconds"] = json!(start.elapsed().as_secs_f64());
    json["rendered_tables"] = tables.iter().map(Table::json).collect();
    Ok(SuiteReport { suite, markdown, json })
}
