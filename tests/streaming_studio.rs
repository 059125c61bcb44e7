//! Streaming in the studio (issue 38), the whole app in egui_kittest with the real worker and
//! the shipped h36m model: a ten-minute take plays while it is made, every take shown on the
//! way is the first frames of the finished one bit for bit, the playhead runs on over the
//! frames that exist without waiting for the rest, and Cancel keeps what was done (a prefix
//! of the take the edit asked for).

#[path = "support/studio.rs"]
mod support;

use std::sync::Arc;
use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable;
use glocal::motion::Motion;
use glocal::studio::StudioApp;
use glocal::synth::{generate, GenerateOptions};
use support::{harness, serial, wait_take};

const TEN_MINUTES: &str = "walking:120,eating:120,walking:120,sitting:120,walking:120";

fn same_start(shown: &Motion, finished: &Motion) -> bool {
    let frames = shown.frames();
    let bits = |m: &Motion| m.positions()[..frames * m.joints()].iter().flat_map(|p| p.to_array()).map(f32::to_bits).collect::<Vec<_>>();
    frames <= finished.frames() && bits(shown) == bits(finished)
}

/// Steps the studio until no generation is under way, keeping every take shown on the way
/// (its motion, whether it was complete, and the playhead then).
fn shown_until_done(h: &mut egui_kittest::Harness<'_, StudioApp>, mut cancel_after_first: bool) -> Vec<(Arc<Motion>, bool, usize)> {
    let start = Instant::now();
    let mut shown: Vec<(Arc<Motion>, bool, usize)> = Vec::new();
    loop {
        h.step();
        let app = h.state();
        if let Some(take) = app.take() {
            if shown.last().is_none_or(|(m, _, _)| !Arc::ptr_eq(m, &take.motion)) {
                shown.push((take.motion.clone(), take.complete, app.frame()));
            }
            if cancel_after_first && !take.complete {
                cancel_after_first = false;
                h.state_mut().cancel();
            }
        }
        if !h.state().is_busy() && shown.last().is_some_and(|(_, complete, _)| *complete || !cancel_after_first) {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "the take did not finish");
        std::thread::sleep(Duration::from_millis(5));
    }
    shown
}

fn edited(h: &mut egui_kittest::Harness<'_, StudioApp>, timeline: &str) -> GenerateOptions {
    let timeline = timeline.parse().unwrap();
    h.state_mut().edit(|d| d.options.timeline = timeline);
    h.state().project().options.clone()
}

#[test]
fn a_long_take_plays_while_it_is_made_and_cancel_keeps_what_is_done() {
    let _serial = serial();
    let mut h = harness("streaming");
    wait_take(&mut h);
    let first_take = h.state().take().unwrap().id;

    // Edit, then play while the take is made.
    edited(&mut h, TEN_MINUTES);
    h.get_by_label("Play").click();
    let shown: Vec<_> = shown_until_done(&mut h, false).into_iter().skip_while(|_| h.state().take().is_some_and(|t| t.id == first_take)).collect();
    let finished = h.state().take().unwrap().motion.clone();
    let partial: Vec<_> = shown.iter().filter(|(_, complete, _)| !complete).collect();
    assert!(partial.len() >= 2, "a ten-minute take showed {} takes before it was finished", partial.len());
    for (motion, _, frame) in &partial {
        assert!(same_start(motion, &finished), "a take of {} frames shown while generating is not the finished take's start", motion.frames());
        assert!(*frame < motion.frames(), "the playhead ({frame}) ran past the frames shown ({})", motion.frames());
    }
    let played = partial.iter().map(|(_, _, f)| *f).max().unwrap();
    assert!(played > 0, "the playhead did not move while the take was made");
    println!("{} takes shown while generating ({} to {} frames of {}), the playhead at frame {played} meanwhile; each the finished take's start", partial.len(), partial[0].0.frames(), partial.last().unwrap().0.frames(), finished.frames());

    // Another edit, cancelled as soon as its first frames show: they stay, and they are the
    // start of the take that edit asks for.
    let options = edited(&mut h, &TEN_MINUTES.replace("sitting", "phoning"));
    let shown = shown_until_done(&mut h, true);
    let kept = h.state().take().unwrap();
    assert!(!kept.complete, "the cancelled take finished anyway");
    assert!(shown.iter().any(|(m, _, _)| Arc::ptr_eq(m, &kept.motion)));
    let model = glocal::model::glocal::GlocalModel::load(std::path::Path::new(support::MODEL)).unwrap();
    let whole = generate(&model, &options, &mut |_| true).unwrap();
    assert!(same_start(&kept.motion, &whole.motion), "the take kept after Cancel is not the start of the take the edit asks for");
    println!("cancelled: {} of {} frames kept, the start of the edited take bit for bit", kept.motion.frames(), whole.motion.frames());
}
