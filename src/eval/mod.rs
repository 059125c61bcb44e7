//! The evaluation suite: the paper's measures (MMD, Euclidean distance per frame), the
//! Action2Motion measures (FID, accuracy, diversity, multimodality) through an action
//! classifier trained here, the motion-quality and constraint measures, baselines trained by
//! this crate on the same splits, and the suites that print the paper's tables
//! (`glocal eval --suite NAME`).

pub mod baselines;
pub mod calibrate;
pub mod classifier;
pub mod constraints;
pub mod metrics;
pub mod motion;
pub mod snaps;
pub mod suites;
pub mod table;

pub use suites::context::{SuiteContext, SuiteOptions};
pub use suites::{run_suite, Suite, SuiteReport};
