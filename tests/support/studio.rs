//! What the studio's kittests share: the whole app in egui_kittest with the wgpu renderer (no
//! display needed), driving the real worker and the shipped model `models/h36m`.
//!
//! One wgpu device for the whole test process; each harness gets its own egui renderer on
//! it (kittest refuses a render state that has drawn before), with the viewport
//! registered. Tests take a lock so they run one at a time (model loads and generation
//! are CPU-bound).
#![allow(dead_code)] // each test file uses its own share of these

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

use eframe::egui_wgpu::{self, RenderState};
use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::wgpu::WgpuTestRenderer;
use egui_kittest::Harness;
use glocal::studio::viewport::Viewport;
use glocal::studio::{StudioApp, StudioOptions};

pub const MODEL: &str = "models/h36m";

pub fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

pub fn base_render_state() -> &'static RenderState {
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

/// A fresh folder for one test's files, under cargo's scratch space for integration tests
/// (`target/tmp`), emptied at the start of each run rather than left behind in `/tmp`.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("studio-test-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Options for a test: the shipped h36m model, an autosave in the test's own folder, no
/// system file dialogs (the in-app one is what a test can drive).
pub fn options(name: &str) -> StudioOptions {
    StudioOptions {
        model_dir: PathBuf::from(MODEL),
        model_roots: vec![PathBuf::from("models")],
        autosave: Some(temp_dir(&format!("{name}-autosave")).join("autosave.json")),
        restore_autosave: false,
        system_dialogs: false,
    }
}

pub fn harness(name: &str) -> Harness<'static, StudioApp> {
    harness_with(options(name), egui::vec2(1280.0, 800.0))
}

pub fn harness_with(options: StudioOptions, size: egui::Vec2) -> Harness<'static, StudioApp> {
    Harness::builder()
        .with_size(size)
        .with_accessibility_check(false)
        .renderer(WgpuTestRenderer::from_render_state(render_state()))
        .build_eframe(move |cc| StudioApp::new(cc, options))
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

/// Model loaded and a take generated, nothing pending (the seed map may still be building).
pub fn wait_take(h: &mut Harness<'_, StudioApp>) {
    wait(h, "the model and a take", |a| a.model_info().is_some() && a.take().is_some() && !a.is_busy());
}

pub fn shows(h: &Harness<'_, StudioApp>, text: &str) -> bool {
    h.query_by_label_contains(text).is_some()
}

pub fn has_error(app: &StudioApp, text: &str) -> bool {
    app.messages().errors().any(|m| m.text.contains(text))
}

pub fn has_message(app: &StudioApp, text: &str) -> bool {
    app.messages().log().iter().any(|m| m.text.contains(text))
}

/// File > New project.
pub fn file_new(h: &mut Harness<'_, StudioApp>) {
    h.get_all_by_label("File").next().unwrap().click();
    h.run_ok();
    h.get_by_label("New project").click();
    h.run_ok();
}

/// Types `text` over what the focused in-app path dialog holds, and presses OK.
pub fn answer_path_dialog(h: &mut Harness<'_, StudioApp>, text: &str) {
    h.key_press_modifiers(Modifiers::COMMAND, Key::A);
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Path").type_text(text);
    h.run_ok();
    h.get_by_label("OK").click();
    h.run_ok();
}

pub fn segments_in(path: &Path) -> usize {
    glocal::studio::project::Project::load(path).unwrap().options.timeline.segments.len()
}
