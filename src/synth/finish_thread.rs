//! A take finished in chunks on a thread of its own while GloGen makes the blocks after them.
//!
//! A chunk's finishing (LocGen, the texture, pace, the bone projection and the foot lock)
//! reads only sparse poses the rollout has settled and writes nothing the rollout reads, so
//! the two overlap: the rollout sends each block's newly settled poses and goes on, and the
//! finishing thread finishes whatever chunks they complete. Both share rayon's pool (the
//! LSTMs' two directions, the bone projection's frames); a pool of the finishing thread's
//! own measured slower on 60 s takes, whose last chunk is finished after the rollout
//! (docs/BENCHMARKS.md). Every chunk is finished exactly as in line: the same calls on the
//! same poses, the same take to the byte.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::thread::{Scope, ScopedJoinHandle};

use anyhow::{anyhow, Result};

use super::finish::ChunkFinish;
use super::generated::{Generated, TakeEvents};
use super::plan::SegmentSpan;
use crate::model::glocal::GlocalModel;

/// What the caller is shown of a take while it is made, besides its frames.
#[derive(Clone, Copy)]
pub(super) struct Shown<'a> {
    pub segments: &'a [SegmentSpan],
    pub block_classes: &'a [usize],
}

/// The rollout's newly settled sparse poses (normalised, flat), how many are settled in all,
/// and whether the take so far is wanted back once more of it is finished.
struct Settled {
    poses: Vec<f32>,
    settled: usize,
    show: bool,
}

/// The rollout's end of the finishing thread.
pub(super) struct FinishingThread<'scope, 'env> {
    settled: Sender<Settled>,
    /// Values of the sparse poses sent so far.
    sent: usize,
    shown: Receiver<Generated>,
    /// Set when the rollout stops early: the chunks still queued are not finished.
    stopping: Arc<AtomicBool>,
    thread: ScopedJoinHandle<'scope, Result<ChunkFinish<'env>>>,
}

impl<'scope, 'env: 'scope> FinishingThread<'scope, 'env> {
    /// Starts finishing `chunked`'s chunks on a thread of `scope`.
    pub fn spawn(scope: &'scope Scope<'scope, 'env>, mut chunked: ChunkFinish<'env>, model: &'env GlocalModel, shown: Shown<'env>) -> Self {
        let (settled_tx, settled_rx) = channel::<Settled>();
        let (shown_tx, shown_rx) = channel();
        let stopping = Arc::new(AtomicBool::new(false));
        let stop_seen = stopping.clone();
        let thread = scope.spawn(move || {
            let mut sparse = Vec::new();
            for Settled { poses, settled, show } in settled_rx {
                if stop_seen.load(Ordering::Relaxed) {
                    break;
                }
                sparse.extend(poses);
                if chunked.advance(&sparse, settled)? && show {
                    // The rollout may have stopped listening (cancelled): nothing to show then.
                    let _ = shown_tx.send(so_far(&chunked, model, shown));
                }
            }
            Ok(chunked)
        });
        Self { settled: settled_tx, sent: 0, shown: shown_rx, stopping, thread }
    }

    /// Hands the thread the poses of `sparse` settled since the last call (the first `settled`
    /// are), and shows `events` the takes finished meanwhile. An error when the thread has
    /// stopped (its own error is [`Self::stop`]'s).
    pub fn send(&mut self, sparse: &[f32], settled: usize, dim: usize, events: &mut dyn TakeEvents) -> Result<()> {
        self.hand(sparse, settled, dim, events.wants_frames())?;
        self.shown.try_iter().for_each(|so_far| events.frames(so_far));
        Ok(())
    }

    /// Sends the thread the poses of `sparse` settled since the last call, asking for the take
    /// so far back when `show`.
    fn hand(&mut self, sparse: &[f32], settled: usize, dim: usize, show: bool) -> Result<()> {
        let end = (settled * dim).min(sparse.len()).max(self.sent);
        let message = Settled { poses: sparse[self.sent..end].to_vec(), settled, show };
        self.sent = end;
        self.settled.send(message).map_err(|_| anyhow!("the take's finishing stopped"))
    }

    /// Sends the last poses, waits for the thread and shows `events` what it finished before
    /// them (the whole take is the caller's to give, not a take so far).
    pub fn finish(mut self, sparse: &[f32], total: usize, dim: usize, events: &mut dyn TakeEvents) -> Result<ChunkFinish<'env>> {
        // A thread that stopped has its own error to give.
        let _ = self.hand(sparse, total, dim, false);
        let Self { settled, shown, thread, .. } = self;
        drop(settled);
        let chunked = join(thread);
        shown.try_iter().for_each(|so_far| events.frames(so_far));
        chunked
    }

    /// The rollout stopped early: the thread stops before its next chunk, and its error, if
    /// it had one, is returned.
    pub fn stop(self) -> Result<ChunkFinish<'env>> {
        self.stopping.store(true, Ordering::Relaxed);
        drop(self.settled);
        join(self.thread)
    }
}

fn join<'env>(thread: ScopedJoinHandle<'_, Result<ChunkFinish<'env>>>) -> Result<ChunkFinish<'env>> {
    thread.join().map_err(|_| anyhow!("the thread finishing the take's chunks panicked"))?
}

/// The take as finished so far.
fn so_far(chunked: &ChunkFinish<'_>, model: &GlocalModel, shown: Shown<'_>) -> Generated {
    Generated {
        motion: chunked.done.motion(model),
        segments: shown.segments.to_vec(),
        block_embeddings: Vec::new(),
        block_classes: shown.block_classes.to_vec(),
        contacts: chunked.done.contacts().clone(),
        warnings: Vec::new(),
        cycle: None,
    }
}
