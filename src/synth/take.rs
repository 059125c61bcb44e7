//! The one way in to generation: a take as its timeline lays it out, or a loop cut from one.

use anyhow::Result;

use super::generate::generate_reusing;
use super::generated::{Generated, TakeEvents};
use super::looping::generate_loop;
use super::options::GenerateOptions;
use super::reuse::TakeCache;
use crate::model::glocal::GlocalModel;

/// Generates the take `opts` asks for. `progress` gets the fraction done and returns false to
/// cancel.
pub fn generate(model: &GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    generate_with(model, opts, &mut TakeCache::default(), &mut &mut *progress)
}

/// [`generate`], resuming the take `cache` holds where this one begins to differ from it and
/// keeping this one there (a loop is cut anew whole, and clears it); `events` see the take's
/// frames as they become final.
pub fn generate_with(model: &GlocalModel, opts: &GenerateOptions, cache: &mut TakeCache, events: &mut dyn TakeEvents) -> Result<Generated> {
    if opts.cycle {
        cache.clear();
        generate_loop(model, opts, &mut |f| events.progress(f))
    } else {
        generate_reusing(model, opts, cache, events)
    }
}
