//! Glocal Studio: long-term, class-aware human motion synthesis after GlocalNet.
//!
//! Layers, each depending only on those above it:
//! `motion` (skeletons, kinematics) <- `data` (formats, datasets, features) <- `model`
//! (LSTM, GloGen, LocGen, training) <- `synth` (timelines, generation, export) and `eval`
//! (metrics, baselines, suites) <- `studio` (the egui app) and `cli`.

pub mod data;
pub mod model;
pub mod synth;
pub mod eval;
pub mod motion;
pub mod cli;
#[cfg(feature = "studio")]
pub mod studio;
