//! Studio tests: the whole app in egui_kittest with the wgpu renderer (no display needed),
//! driving the real worker and the shipped model `models/h36m`.
//!
//! One wgpu device for the whole test process; each harness gets its own egui renderer on
//! it (kittest refuses a render state that has drawn before), with the viewport
//! registered. Tests take a lock so they run one at a time (model loads and generation
//! are CPU-bound).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

use eframe::egui_wgpu::{self, RenderState};
use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::wgpu::WgpuTestRenderer;
use egui_kittest::{Harness, SnapshotOptions};
use glocal::studio::viewport::Viewport;
use glocal::studio::{StudioApp, StudioOptions};
use glocal::synth::render::class_color;

const MODEL: &str = "models/h36m";

fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

fn base_render_state() -> &'static RenderState {
    static BASE: OnceLock<RenderState> = OnceLock::new();
    BASE.get_or_init(|| egui_kittest::wgpu::create_render_state(egui_kittest::wgpu::default_wgpu_setup(), egui_wgpu::RendererOptions::PREDICTABLE))
}

/// A fresh egui renderer on the shared device, with the viewport's pipeline installed.
fn render_state() -> RenderState {
    let base = base_render_state();
    let renderer = egui_wgpu::Renderer::new(&base.device, base.target_format, egui_wgpu::RendererOptions::PREDICTABLE);
    let rs = RenderState { renderer: Arc::new(egui::mutex::RwLock::new(renderer)), ..base.clone() };
    Viewport::register(&rs);
    rs
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("glocal-studio-test-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn harness(name: &str) -> Harness<'static, StudioApp> {
    let options = StudioOptions {
        model_dir: PathBuf::from(MODEL),
        models_root: PathBuf::from("models"),
        autosave: Some(temp_dir(name).join("autosave.json")),
        restore_autosave: false,
    };
    Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .with_accessibility_check(false)
        .renderer(WgpuTestRenderer::from_render_state(render_state()))
        .build_eframe(move |cc| StudioApp::new(cc, options))
}

/// Steps the harness until `done` holds (at most two minutes).
fn wait(h: &mut Harness<'_, StudioApp>, what: &str, done: impl Fn(&StudioApp) -> bool) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(start.elapsed() < Duration::from_secs(120), "timed out waiting for {what}; messages: {:?}", h.state().messages().all());
        h.step();
        std::thread::sleep(Duration::from_millis(15));
    }
    h.step();
}

/// Model loaded, seed map built, take generated, nothing pending.
fn wait_ready(h: &mut Harness<'_, StudioApp>) {
    wait(h, "the model, the map and a take", |a| a.model_info().is_some() && a.seed_map().is_some() && a.take().is_some_and(|t| !t.path.is_empty()) && !a.is_busy());
}

fn frames(h: &Harness<'_, StudioApp>) -> usize {
    h.state().take().map_or(0, |t| t.motion.frames())
}

fn shows(h: &Harness<'_, StudioApp>, text: &str) -> bool {
    h.query_by_label_contains(text).is_some()
}

fn has_error(app: &StudioApp, text: &str) -> bool {
    app.messages().errors().any(|m| m.text.contains(text))
}

fn snapshot_options() -> SnapshotOptions {
    // Software rendering differs slightly between drivers.
    SnapshotOptions::new().threshold(2.0).max_failed_pixels(2000)
}

/// The window as eframe shows it: kittest clears to transparent, eframe to the app's clear
/// colour, which the studio's panels leave as their background.
fn render_on_clear_color(h: &mut Harness<'_, StudioApp>) -> image::RgbaImage {
    let mut img = h.render().unwrap();
    let clear = eframe::App::clear_color(h.state(), &h.ctx.global_style().visuals).map(|c| c * 255.0);
    for p in img.pixels_mut() {
        // egui's output is premultiplied: what shows is the pixel over the clear colour.
        let cover = 1.0 - f32::from(p[3]) / 255.0;
        for k in 0..3 {
            p[k] = (f32::from(p[k]) + cover * clear[k]).round().min(255.0) as u8;
        }
        p[3] = 255;
    }
    img
}

/// The viewport's part of a rendered image (between the side panels, above the timeline).
fn viewport_pixels(img: &image::RgbaImage) -> Vec<u8> {
    let mut out = Vec::new();
    for y in 60..560 {
        for x in 360..900 {
            out.extend_from_slice(&img.get_pixel(x, y).0);
        }
    }
    out
}

#[test]
fn whole_app_with_a_generated_take_and_the_seed_map() {
    let _g = serial();
    let mut h = harness("snapshot");
    wait_ready(&mut h);
    let app = h.state();
    let take = app.take().unwrap();
    assert!(take.segments.len() >= 2, "the default timeline has two segments");
    assert!(take.motion.frames() > 100);
    let model = app.model_info().unwrap();
    assert_eq!(app.seed_map().unwrap().points.len(), model.seeds.len(), "every seed is on the map");
    assert!(take.path.len() == take.block_classes.len() && !take.path.is_empty(), "the take's blocks are projected into the map");
    assert!(shows(&h, "Segment 1: walking") && shows(&h, "Segment 2:"));
    egui_kittest::image_snapshot_options(&render_on_clear_color(&mut h), "studio_app", &snapshot_options());
}

#[test]
fn adding_a_segment_and_changing_its_class_regenerates() {
    let _g = serial();
    let mut h = harness("add");
    wait_ready(&mut h);
    let before = frames(&h);
    assert_eq!(h.state().project().timeline.segments.len(), 2);
    h.get_by_label("+ Add segment").click();
    wait(&mut h, "the segment", |a| a.project().timeline.segments.len() == 3);
    // Change the new segment's class through its context menu on the timeline.
    h.get_by_label("Segment 3: directions").click_secondary();
    h.run_ok();
    h.get_by_label("Class").hover();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::Button, "sitting").click();
    wait(&mut h, "the class change", |a| a.project().timeline.segments[2].class == "sitting");
    wait(&mut h, "the regenerated take", |a| a.take().is_some_and(|t| t.segments.len() == 3) && !a.is_busy());
    let app = h.state();
    let take = app.take().unwrap();
    assert!(take.motion.frames() > before + 50, "3 more seconds: {} -> {}", before, take.motion.frames());
    let sitting = app.model_info().unwrap().spec.class_index("sitting").unwrap();
    assert_eq!(take.segments[2].class, sitting);
    assert_eq!(*take.frame_colors.last().unwrap(), class_color(sitting), "the new frames have the new class colour");
    // Undo and redo from the keyboard.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.step();
    assert_eq!(h.state().project().timeline.segments[2].class, "directions");
    h.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    h.step();
    assert_eq!(h.state().project().timeline.segments[2].class, "sitting");
}

#[test]
fn scrubbing_moves_the_pose() {
    let _g = serial();
    let mut h = harness("scrub");
    wait_ready(&mut h);
    h.run_ok();
    assert_eq!(h.state().frame(), 0);
    let first = h.render().unwrap();
    h.get_by_label("Timeline ruler").click();
    h.run_ok();
    let f = h.state().frame();
    let n = frames(&h);
    assert!(f > n / 3 && f < 2 * n / 3, "clicking the ruler's middle seeks to the middle: frame {f} of {n}");
    let second = h.render().unwrap();
    assert_ne!(viewport_pixels(&first), viewport_pixels(&second), "the viewport shows another pose");
    h.key_press(Key::ArrowRight);
    h.step();
    assert_eq!(h.state().frame(), f + 1);
    h.key_press(Key::ArrowLeft);
    h.key_press(Key::ArrowLeft);
    h.step();
    h.step();
    assert_eq!(h.state().frame(), f - 1);
}

#[test]
fn projects_save_load_and_refuse_bad_files() {
    let _g = serial();
    let dir = temp_dir("project");
    let mut h = harness("project");
    wait_ready(&mut h);
    let path = dir.join("p.json");
    assert!(h.state_mut().save_project(&path));
    let saved = h.state().project().timeline.clone();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"version\": 1"), "readable JSON with a version");
    // Change the timeline, then load the file back.
    h.state_mut().add_segment();
    h.step();
    assert_ne!(h.state().project().timeline, saved);
    assert!(h.state_mut().open_project(&path));
    h.step();
    assert_eq!(h.state().project().timeline, saved);

    // A broken and a newer file: an error in the UI, the timeline untouched.
    h.state_mut().add_segment();
    h.step();
    let current = h.state().project().timeline.clone();
    let broken = dir.join("broken.json");
    std::fs::write(&broken, "{ \"version\": 1, \"timeline\": [oops").unwrap();
    assert!(!h.state_mut().open_project(&broken));
    h.run_ok();
    assert_eq!(h.state().project().timeline, current);
    assert!(has_error(h.state(), "Could not open the project"));
    assert!(shows(&h, "Could not open the project"), "the error is visible");
    let newer = dir.join("newer.json");
    std::fs::write(&newer, text.replace("\"version\": 1", "\"version\": 7")).unwrap();
    assert!(!h.state_mut().open_project(&newer));
    h.run_ok();
    assert_eq!(h.state().project().timeline, current);
    assert!(has_error(h.state(), "newer than this studio understands"));
    assert!(shows(&h, "newer than this studio understands"));
}

#[test]
fn bad_input_gives_messages_and_keeps_the_work() {
    let _g = serial();
    let dir = temp_dir("bad");
    let mut h = harness("bad");
    wait_ready(&mut h);
    let timeline = h.state().project().timeline.clone();
    let take_frames = frames(&h);

    // An unwritable export path, through the Export button.
    h.state_mut().fields_mut().export_path = "/nonexistent-folder/glocal/take.bvh".into();
    h.get_by_label("Export").click_accesskit();
    wait(&mut h, "the export error", |a| has_error(a, "Could not export"));
    h.run_ok();
    assert!(shows(&h, "Could not export /nonexistent-folder/glocal/take.bvh"));

    // A folder that is not a model, typed in the model field.
    h.state_mut().fields_mut().model_path = dir.display().to_string();
    h.get_by_label("Load model").click_accesskit();
    wait(&mut h, "the model error", |a| has_error(a, "Could not load the model"));
    h.run_ok();
    assert!(shows(&h, "Could not load the model"));
    assert_eq!(h.state().model_info().unwrap().dir, Path::new(MODEL), "the current model stays");

    // A BVH of another skeleton as the initial pose.
    let bvh = dir.join("other.bvh");
    std::fs::write(
        &bvh,
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n JOINT Head\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 5 0\n  }\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.04\n0 0 0 0 0 0 0 0 0\n0 0 0 0 0 0 0 0 0\n",
    )
    .unwrap();
    let init = h.state().project().init.clone();
    h.state_mut().use_init_file(bvh, 0);
    wait(&mut h, "the initial pose error", |a| has_error(a, "cannot start a take"));
    h.run_ok();
    assert!(shows(&h, "cannot start a take"));
    assert_eq!(h.state().project().init, init);

    assert_eq!(h.state().project().timeline, timeline, "the timeline is untouched");
    assert_eq!(frames(&h), take_frames, "the take is untouched");
}
