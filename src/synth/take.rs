//! The one way in to generation: a take as its timeline lays it out, or a loop cut from one.

use anyhow::Result;

use super::generate::{continuous_take, Generated};
use super::looping::generate_loop;
use super::options::GenerateOptions;
use crate::model::glocal::GlocalModel;

/// Generates the take `opts` asks for. `progress` gets the fraction done and returns false to
/// cancel.
pub fn generate(model: &GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    if opts.cycle {
        generate_loop(model, opts, progress)
    } else {
        continuous_take(model, opts, progress)
    }
}
