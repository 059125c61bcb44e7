//! What the studio's kittest files share: one wgpu device for the test process with a fresh
//! egui renderer per harness (kittest refuses a render state that has drawn before), the
//! viewport registered on it, and waiting for the app.

use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use eframe::egui_wgpu::{self, RenderState};
use egui_kittest::Harness;
use glocal::studio::viewport::Viewport;
use glocal::studio::StudioApp;

fn base_render_state() -> &'static RenderState {
    static BASE: OnceLock<RenderState> = OnceLock::new();
    BASE.get_or_init(|| egui_kittest::wgpu::create_render_state(egui_kittest::wgpu::default_wgpu_setup(), egui_wgpu::RendererOptions::PREDICTABLE))
}

/// A fresh egui renderer on the shared device, with the viewport's pipeline installed.
pub fn render_state() -> RenderState {
    let base = base_render_state();
    let renderer = egui_wgpu::Renderer::new(&base.device, base.target_format, egui_wgpu::RendererOptions::PREDICTABLE);
    let rs = RenderState { renderer: Arc::new(egui::mutex::RwLock::new(renderer)), ..base.clone() };
    Viewport::register(&rs);
    rs
}

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
