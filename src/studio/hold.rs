//! What a regeneration keeps of the take on screen (issue 36): an edit of one segment
//! (its class, length, pace, transition or a reroll) keeps every other segment's frames, and
//! any other change keeps the locked segments. The kept frames go into the document's
//! request (`options.held`), so the saved project makes the same take on the command line,
//! and undo brings back a request that makes the take before exactly.

use super::app::StudioApp;
use crate::synth::held::{hold_segments, planned_spans, Kept};
use crate::synth::{GenerateOptions, Segment};

impl StudioApp {
    /// Sets the document's held frames for the regeneration about to start, from the take
    /// on screen, when the document is the last request edited (not a request brought back
    /// by undo or opened, whose held frames are what it needs). Locked segments that an edit
    /// moves in time are unlocked, and the user is told. Frames that do not fit the model
    /// (another model's, left by a model switch) are dropped.
    pub(super) fn hold_for_regeneration(&mut self) {
        let Some(model) = self.engine.model.clone() else { return };
        // Frames of another model's skeleton (kept from before a model switch) hold nothing.
        if !self.editing.doc.options.held.iter().all(|h| h.fits(&model.spec.layout.skeleton)) {
            self.editing.doc.options.held.clear();
        }
        let Some(take) = self.engine.take.clone() else { return };
        let doc = &self.editing.doc;
        let edited_request = self.engine.requested.as_ref().is_some_and(|r| r.held == doc.options.held);
        if take.model_dir != doc.model || !edited_request {
            return;
        }
        let request = self.editing.take_request().options;
        let segments = &doc.options.timeline.segments;
        let Ok(spans) = planned_spans(&model.spec, &request) else { return };
        let edited = edited_segment(&take.options, &request);
        let mut kept = Vec::new();
        let mut unlocked = Vec::new();
        for (k, segment) in segments.iter().enumerate() {
            // The same segment at the same place in the take on screen, if it is there.
            let same = take.options.timeline.segments.get(k).is_some_and(|old| same_segment(old, segment));
            let moved = !same || take.segments.get(k).is_none_or(|old| old.start_frame != spans[k].start_frame || old.end_frame != spans[k].end_frame);
            if segment.locked && moved {
                unlocked.push(k);
            }
            if same && (edited.is_some() || (segment.locked && !moved)) {
                kept.push(Kept { before: k, after: k, whole: segment.locked && !moved });
            }
        }
        for &k in &unlocked {
            self.editing.doc.options.timeline.segments[k].locked = false;
            let start = spans.get(k).map_or(0.0, |s| s.start_frame as f32 / model.spec.fps);
            self.messages.info(format!("Segment {} is unlocked: this edit moves it in time (it now starts at {start:.1} s) or changes it, so it cannot keep its frames where they were", k + 1));
        }
        let request = self.editing.take_request().options;
        self.editing.doc.options.held = match hold_segments(&model.spec, &take.motion, &take.segments, &request, &kept) {
            Ok(held) => held,
            Err(e) => {
                self.messages.info(format!("The whole take is generated again: {e:#}"));
                Vec::new()
            }
        };
    }
}

/// The one segment whose edit makes `after` from `before` (everything else the same), if
/// the change is an edit of one segment.
fn edited_segment(before: &GenerateOptions, after: &GenerateOptions) -> Option<usize> {
    let (a, b) = (&before.timeline.segments, &after.timeline.segments);
    let others_same = GenerateOptions { timeline: before.timeline.clone(), held: Vec::new(), ..after.clone() } == GenerateOptions { held: Vec::new(), ..before.clone() };
    if !others_same || a.len() != b.len() {
        return None;
    }
    let changed: Vec<usize> = (0..a.len()).filter(|&k| !same_segment(&a[k], &b[k])).collect();
    match changed[..] {
        [k] => Some(k),
        _ => None,
    }
}

/// Whether two segments ask for the same motion (a lock is the studio's, not the take's).
fn same_segment(a: &Segment, b: &Segment) -> bool {
    Segment { locked: false, ..a.clone() } == Segment { locked: false, ..b.clone() }
}
