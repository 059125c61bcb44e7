//! The desktop studio (egui). Nothing below this module knows egui exists.
//!
//! - [`advice`]: timelines the model will not follow as written, and their fixes
//! - [`project`]: the document (timeline, pace, initial pose, settings) and its undo history
//! - [`worker`]: the background thread that owns the model
//! - [`tsne`]: the seed map
//! - [`transport`]: playback
//! - [`timeline`]: the timeline widget (segments, key and path tracks)
//! - `keys`: keys and the root path (edits, their sidebar section)
//! - [`app`]: the application state and frame loop; the panels are in `menu`, `sidebar`,
//!   `bottom`, `central` and `map_panel`
//! - [`viewport`]: the 3D view

pub mod advice;
pub mod app;
pub mod bench;
mod bottom;
mod central;
pub mod dialogs;
pub mod joint_mapping;
mod keys;
mod map_panel;
mod menu;
pub mod messages;
pub mod project;
mod sidebar;
pub mod timeline;
pub mod transport;
pub mod tsne;
pub mod viewport;
pub mod worker;

use anyhow::Result;

pub use app::{StudioApp, StudioOptions};

/// Opens the studio window.
pub fn run() -> Result<()> {
    let options = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_min_inner_size([900.0, 600.0]).with_title("Glocal Studio"),
        ..Default::default()
    };
    eframe::run_native(
        "Glocal Studio",
        options,
        Box::new(|cc| {
            if let Some(rs) = &cc.wgpu_render_state {
                viewport::Viewport::register(rs);
            }
            Ok(Box::new(StudioApp::new(cc, StudioOptions::default())))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the studio window could not open: {e}"))
}
