//! The desktop studio (egui). Nothing below this module knows egui exists.
//!
//! The studio is its editing state, an engine, and panels that each draw one part:
//!
//! - the editing state: [`project`] (the document, saved as the synth project document with
//!   the view settings, and its undo history) and [`editing`] (the document being edited,
//!   what was saved, the selection); `edits` changes it
//! - the engine: [`worker`] (the background thread that owns the model), [`engine`] (the
//!   model, takes and generation under way as the UI knows them), [`retarget`] (foreign BVH
//!   files for a preview); `generation` asks for takes and takes in the replies, `hold` says what a
//!   regeneration keeps of the take on screen
//! - the panels: [`panels`] (what they remember between frames), and `menu`, `sidebar`,
//!   `bottom`, `central`, `map_panel`, `keys` and `joint_mapping` that draw them, with the
//!   widgets [`timeline`], [`viewport`] (the 3D view) and [`transport`] (playback)
//! - around them: [`app`] (the frame loop), `files` and [`storage`] (projects, exports, the
//!   autosave), [`dialogs`], [`messages`], [`advice`] (timelines the model will not follow as
//!   written, and their fixes) and [`tsne`] (the seed map)

pub mod advice;
pub mod app;
pub mod bench;
mod bottom;
mod central;
mod command_line;
pub mod dialogs;
pub mod editing;
mod edits;
pub mod engine;
mod files;
mod generation;
mod hold;
mod joint_mapping;
mod keys;
mod map_panel;
mod menu;
pub mod messages;
pub mod panels;
pub mod project;
pub mod retarget;
mod sidebar;
pub mod storage;
mod switch;
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
