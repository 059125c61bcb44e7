//! What the studio's kittest files share: stepping the whole app until something holds.

use std::time::{Duration, Instant};

use egui_kittest::Harness;
use glocal::studio::StudioApp;

/// Steps the harness until `done` holds (at most two minutes).
pub fn wait(h: &mut Harness<'_, StudioApp>, what: &str, done: impl Fn(&StudioApp) -> bool) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(start.elapsed() < Duration::from_secs(120), "timed out waiting for {what}; messages: {:?}", h.state().messages().log());
        h.step();
        std::thread::sleep(Duration::from_millis(15));
    }
    h.step();
}
