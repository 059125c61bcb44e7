//! A take as generation hands it over, and what its caller sees of it while it is made.

use super::plan::SegmentSpan;
use crate::motion::contacts::FootContacts;
use crate::motion::cycle::Cycle;
use crate::motion::Motion;

/// A finished take: its frames with the segments and blocks they were made of, where its
/// feet stand, and what it could not do as asked.
pub struct Generated {
    pub motion: Motion,
    pub segments: Vec<SegmentSpan>,
    /// GloGen's encoder embedding of each generated block's input (the t-SNE path); empty
    /// for a block of held frames, which GloGen did not make.
    pub block_embeddings: Vec<Vec<f32>>,
    /// Class (segment) of each block.
    pub block_classes: Vec<usize>,
    /// Per foot and frame, whether the foot stands on the floor.
    pub contacts: FootContacts,
    /// What the take could not do as asked (a path faster than its class walks), for the
    /// user to see.
    pub warnings: Vec<String>,
    /// A looping take's cycle: where it was cut and how far one play of it travels.
    pub cycle: Option<Cycle>,
}

/// What a caller sees of a take while it is made.
pub trait TakeEvents {
    /// The fraction done; false cancels.
    fn progress(&mut self, fraction: f32) -> bool;

    /// Whether [`TakeEvents::frames`] is wanted (the take so far is a copy).
    fn wants_frames(&self) -> bool {
        false
    }

    /// The take so far, each time more of its frames are final: the finished take begins
    /// with these frames, bit for bit.
    fn frames(&mut self, _so_far: Generated) {}
}

/// A progress callback alone.
impl<F: FnMut(f32) -> bool> TakeEvents for F {
    fn progress(&mut self, fraction: f32) -> bool {
        self(fraction)
    }
}
