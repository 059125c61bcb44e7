//! Looping takes for a game engine's cycles (`--loop`): one activity generated for longer
//! than asked, and the cycle of about the asked length whose end best continues its start
//! cut out of it and closed ([`crate::motion::cycle`]).

use anyhow::{bail, Context, Result};

use super::generate::continuous_take;
use super::generated::Generated;
use super::options::GenerateOptions;
use super::plan::SegmentSpan;
use crate::model::glocal::GlocalModel;
use crate::motion::cycle::{closed_cycle, CycleSearch};

/// How far a cycle's length may stray from the asked duration, as a fraction of it: room
/// for the motion's own period (a gait cycle, a wave) to fit a whole number of times.
const LENGTH_TOLERANCE: f32 = 0.15;
/// Seconds of the take the cycle may start in, after the starting poses: 2 s left no steady
/// stretch to a 4 s cycle of an activity that stands for 3 s and then walks off (h36m's
/// phoning wrapped at half its speed).
const START_WINDOW_SECONDS: f32 = 4.0;
/// The shortest loop.
pub const MIN_LOOP_SECONDS: f32 = 0.5;

/// The take of a one-activity `opts` as a closed cycle of about its duration.
pub fn generate_loop(model: &GlocalModel, opts: &GenerateOptions, progress: &mut dyn FnMut(f32) -> bool) -> Result<Generated> {
    let [segment] = opts.timeline.segments.as_slice() else {
        bail!("a loop is one activity: the timeline has {} segments", opts.timeline.segments.len());
    };
    if !opts.keys.is_empty() || opts.path.is_some() {
        bail!("a loop cannot have keys or a root path: it repeats from where its own travel leaves it");
    }
    if segment.seconds < MIN_LOOP_SECONDS {
        bail!("a loop lasts at least {MIN_LOOP_SECONDS} s, the segment '{}' asks {} s", segment.class, segment.seconds);
    }
    let fps = model.spec.fps;
    let asked = segment.seconds * fps;
    // The cycle starts after the starting poses, which are the start's, not the activity's.
    let skip = (model.spec.block_len * model.spec.stride) as f32;
    let starts = skip.round() as usize..(skip + START_WINDOW_SECONDS * fps).round() as usize;
    let lengths = (asked * (1.0 - LENGTH_TOLERANCE)).round().max(2.0) as usize..=(asked * (1.0 + LENGTH_TOLERANCE)).round() as usize;
    let needed = starts.end + lengths.end() + 2;
    let mut longer = opts.clone();
    longer.cycle = false;
    // Held frames are frames of an earlier cycle, not of the longer take the cycle is cut
    // from: a loop is cut anew whole.
    longer.held.clear();
    longer.timeline.segments[0].seconds = needed as f32 / fps + 1.0;
    let take = continuous_take(model, &longer, progress)?;
    let (motion, cycle) = closed_cycle(&take.motion, &CycleSearch { starts, lengths })?;
    let range = cycle.start..cycle.start + cycle.frames;
    // The take of a one-segment timeline has that segment's span.
    let first = take.segments.first().context("the loop's take has no segment")?;
    let segments = vec![SegmentSpan { start_frame: 0, end_frame: cycle.frames, ..first.clone() }];
    Ok(Generated { motion, segments, contacts: take.contacts.slice(range), cycle: Some(cycle), ..take })
}
