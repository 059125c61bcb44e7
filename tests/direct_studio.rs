//! Reroll and lock in the studio (issue 36), in egui_kittest with the wgpu renderer and the
//! real worker on the shipped h36m model: the dice on a segment rerolls it alone, the
//! padlock keeps a segment's frames through edits of the others, an edit that moves a locked
//! segment in time unlocks it and says so, undo brings back the take before, and the saved
//! project makes the same take on the command line.

use std::sync::Arc;

use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use glocal::motion::Motion;
use glocal::studio::StudioApp;
use glocal::synth::export::{export_with_contacts, prepare, ExportOptions};

#[path = "support/studio.rs"]
mod support;
use support::{harness, temp_dir, wait};

const BIN: &str = env!("CARGO_BIN_EXE_glocal");

/// The take on screen once it is the document's and nothing is pending.
fn settled(h: &mut Harness<'_, StudioApp>, what: &str) -> Arc<Motion> {
    wait(h, what, |a| a.take().is_some() && !a.is_busy() && a.stale_reason().is_none());
    h.state().take().unwrap().motion.clone()
}

/// The largest position difference of two takes over `frames`.
fn difference(a: &Motion, b: &Motion, frames: std::ops::Range<usize>) -> f32 {
    frames.flat_map(|f| a.frame(f).iter().zip(b.frame(f)).map(|(p, q)| (*p - *q).abs().max_element())).fold(0.0, f32::max)
}

/// Segment `k`'s frames and those of its transitions (1 s each side at h36m's 25 fps).
fn around(h: &Harness<'_, StudioApp>, k: usize) -> std::ops::Range<usize> {
    let span = &h.state().take().unwrap().segments[k];
    span.start_frame.saturating_sub(25)..span.end_frame + 25
}

/// Frames of `all` outside `changed`.
fn outside(all: usize, changed: &std::ops::Range<usize>) -> [std::ops::Range<usize>; 2] {
    [0..changed.start, changed.end.min(all)..all]
}

#[test]
fn the_dice_rerolls_one_segment_and_the_padlock_keeps_one() {
    let mut h = harness("reroll");
    settled(&mut h, "the first take");
    h.state_mut().edit(|p| p.options.timeline = "walking:8,discussion:8,walking:8,phoning:8".parse().unwrap());
    let first = settled(&mut h, "the four-segment take");
    let frames = first.frames();

    // The dice on segment 2: a new seed for it, and only it and its transitions change.
    h.get_by_label("Reroll segment 2").click();
    h.run_ok();
    let seed = h.state().project().options.timeline.segments[1].seed;
    assert!(seed.is_some(), "the dice gave segment 2 no seed");
    let rerolled = settled(&mut h, "the rerolled take");
    let changed = around(&h, 1);
    let kept = outside(frames, &changed).map(|r| difference(&first, &rerolled, r)).into_iter().fold(0.0, f32::max);
    let inside = difference(&first, &rerolled, changed.clone());
    println!("studio reroll of segment 2 (seed {seed:?}): outside frames {changed:?} max difference {kept}, inside {inside:.1} mm");
    assert_eq!(kept, 0.0, "the reroll changed frames outside segment 2");
    assert!(inside > 1.0, "the reroll did not change segment 2");

    // The padlock on segment 3: nothing is generated, the segment is locked.
    let id = h.state().take().unwrap().id;
    h.get_by_label("Lock segment 3").click();
    h.run_ok();
    assert!(h.state().project().options.timeline.segments[2].locked);
    assert!(h.query_by_label("Unlock segment 3").is_some(), "the padlock does not offer to unlock");
    settled(&mut h, "the lock");
    assert_eq!(h.state().take().unwrap().id, id, "locking regenerated the take");

    // Rerolling its neighbour keeps every frame of the locked segment, transitions included.
    let locked = h.state().take().unwrap().segments[2].clone();
    h.get_by_label("Reroll segment 4").click();
    h.run_ok();
    let next = settled(&mut h, "segment 4 rerolled");
    let held = difference(&rerolled, &next, locked.start_frame..locked.end_frame);
    println!("studio: locked segment 3 (frames {}..{}) through a reroll of segment 4: max difference {held}", locked.start_frame, locked.end_frame);
    assert_eq!(held, 0.0, "the reroll of segment 4 changed the locked segment 3");

    // Lengthening segment 1 moves segment 3 in time: it is unlocked, and the studio says so.
    h.state_mut().edit(|p| p.options.timeline.segments[0].seconds = 10.0);
    settled(&mut h, "segment 1 lengthened");
    assert!(!h.state().project().options.timeline.segments[2].locked, "segment 3 stayed locked though it moved");
    let said = h.state().messages().log().iter().any(|m| m.text.contains("Segment 3 is unlocked"));
    assert!(said, "the studio did not say segment 3 was unlocked: {:?}", h.state().messages().log());

    // Undo brings back the take before the edit, exactly.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.run_ok();
    let undone = settled(&mut h, "the take before the edit");
    assert_eq!(undone.frames(), next.frames());
    let back = difference(&next, &undone, 0..next.frames());
    println!("studio: undo of the edit: max difference from the take before it {back}");
    assert_eq!(back, 0.0, "undo did not bring back the take before");

    // The saved project makes the same take on the command line.
    let dir = temp_dir("direct-studio-reroll");
    let project = dir.join("take.glocal.json");
    std::fs::write(&project, h.state().project().to_json()).unwrap();
    let cli = dir.join("cli.bvh");
    let status = std::process::Command::new(BIN).current_dir(env!("CARGO_MANIFEST_DIR")).args(["generate", "--project"]).arg(&project).arg("--out").arg(&cli).status().unwrap();
    assert!(status.success());
    let take = h.state().take().unwrap();
    let spec = &h.state().model_info().unwrap().spec;
    let (m, segments) = prepare(&take.motion, &take.segments, &ExportOptions::default(), &spec.source_skeleton).unwrap();
    let here = dir.join("studio.bvh");
    export_with_contacts(&m, &segments, Some(&take.contacts), &here).unwrap();
    assert!(std::fs::read(&cli).unwrap() == std::fs::read(&here).unwrap(), "glocal generate --project made another take than the studio's");
}
