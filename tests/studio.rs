//! Studio tests: the whole app in egui_kittest with the wgpu renderer, driving the real
//! worker and the shipped models (see `support/studio.rs`).

#[path = "support/studio.rs"]
mod support;

use std::path::Path;

use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::{Harness, SnapshotOptions};
use glocal::studio::{StudioApp, StudioOptions};
use glocal::synth::render::class_color;
use glocal::synth::Preset;
use support::*;

/// Model loaded, seed map built, take generated, nothing pending.
fn wait_ready(h: &mut Harness<'_, StudioApp>) {
    wait(h, "the model, the map and a take", |a| a.model_info().is_some() && a.seed_map().is_some() && a.take().is_some_and(|t| !t.path.is_empty()) && !a.is_busy());
}

fn frames(h: &Harness<'_, StudioApp>) -> usize {
    h.state().take().map_or(0, |t| t.motion.frames())
}

/// The thresholds of kittest.toml (software rendering differs slightly between drivers).
fn snapshot_options() -> SnapshotOptions {
    SnapshotOptions::default()
}

/// Paths that depend on the machine (home folder, test folder) replaced by fixed ones, so
/// that snapshots compare.
fn fixed_paths(h: &mut Harness<'_, StudioApp>) {
    let f = h.state_mut().fields_mut();
    f.project_path = "project.glocal.json".into();
    f.export_path = "take.bvh".into();
    h.run_ok();
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
    // The Project section is on screen at 1280x800 without scrolling.
    assert!(h.get_by_label("Save as…").rect().bottom() < 800.0);
    fixed_paths(&mut h);
    egui_kittest::image_snapshot_options(&render_on_clear_color(&mut h), "studio_app", &snapshot_options());
}

/// The seed map's key sits below the map, every class in it and inside the window, and a
/// click on a class hides its seeds (the legend egui_plot drew over the map covered it all
/// on the model of everything's 26 classes).
#[test]
fn the_seed_map_key_lists_every_class_and_hides_one_on_a_click() {
    let _g = serial();
    let mut h = harness("map-key");
    wait_ready(&mut h);
    let classes = h.state().model_info().unwrap().spec.classes.clone();
    for class in &classes {
        let r = h.get_by_label(&format!("Seed map key: {class}")).rect();
        assert!(r.right() <= 1280.0 && r.bottom() <= 800.0, "{class} is at {r:?}");
    }
    h.get_by_label("Seed map key: walking").click();
    h.run_ok();
    assert!(h.state().hidden_on_map().contains("walking") && h.state().hidden_on_map().len() == 1, "hidden: {:?}", h.state().hidden_on_map());
    h.get_by_label("Seed map key: walking").click();
    h.run_ok();
    assert!(h.state().hidden_on_map().is_empty());
}

#[test]
fn the_layout_holds_at_900x600() {
    let _g = serial();
    let mut h = harness_with(options("small"), egui::vec2(900.0, 600.0));
    wait_ready(&mut h);
    h.state_mut().add_segment();
    wait(&mut h, "the longer take", |a| a.take().is_some_and(|t| t.segments.len() == 3) && !a.is_busy());
    // The whole timeline, its last block included, is inside the window, and so are the
    // transport controls.
    let last = h.get_by_label("Segment 3: directions").rect();
    assert!(last.right() <= 900.0 && last.left() > 0.0 && last.bottom() <= 600.0, "the last block is at {last:?}");
    for label in ["Play", "+ Add segment", "Timeline ruler"] {
        let r = h.get_by_label(label).rect();
        assert!(r.right() <= 900.0 && r.bottom() <= 600.0, "{label} is at {r:?}");
    }
    fixed_paths(&mut h);
    egui_kittest::image_snapshot_options(&render_on_clear_color(&mut h), "studio_app_900x600", &snapshot_options());
}

#[test]
fn adding_a_segment_and_changing_its_class_regenerates() {
    let _g = serial();
    let mut h = harness("add");
    wait_ready(&mut h);
    let before = frames(&h);
    assert_eq!(h.state().project().options.timeline.segments.len(), 2);
    h.get_by_label("+ Add segment").click();
    wait(&mut h, "the segment", |a| a.project().options.timeline.segments.len() == 3);
    // Change the new segment's class through its context menu on the timeline.
    h.get_by_label("Segment 3: directions").click_secondary();
    h.run_ok();
    h.get_by_label("Class").hover();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::Button, "sitting").click();
    wait(&mut h, "the class change", |a| a.project().options.timeline.segments[2].class == "sitting");
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
    assert_eq!(h.state().project().options.timeline.segments[2].class, "directions");
    h.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    h.step();
    assert_eq!(h.state().project().options.timeline.segments[2].class, "sitting");
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
    let saved = h.state().project().options.timeline.clone();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"version\": 3"), "readable JSON with a version");
    // Change the timeline, then load the file back.
    h.state_mut().add_segment();
    h.step();
    assert_ne!(h.state().project().options.timeline, saved);
    assert!(h.state_mut().open_project(&path));
    h.step();
    assert_eq!(h.state().project().options.timeline, saved);

    // A broken and a newer file: an error in the UI, the timeline untouched.
    h.state_mut().add_segment();
    h.step();
    let current = h.state().project().options.timeline.clone();
    let broken = dir.join("broken.json");
    std::fs::write(&broken, "{ \"version\": 1, \"timeline\": [oops").unwrap();
    assert!(!h.state_mut().open_project(&broken));
    h.run_ok();
    assert_eq!(h.state().project().options.timeline, current);
    assert!(has_error(h.state(), "Could not open the project"));
    assert!(shows(&h, "Could not open the project"), "the error is visible");
    let newer = dir.join("newer.json");
    std::fs::write(&newer, text.replace("\"version\": 3", "\"version\": 7")).unwrap();
    assert!(!h.state_mut().open_project(&newer));
    h.run_ok();
    assert_eq!(h.state().project().options.timeline, current);
    assert!(has_error(h.state(), "made by a newer version of glocal"));
    assert!(shows(&h, "made by a newer version of glocal"));
}

#[test]
fn bad_input_gives_messages_and_keeps_the_work() {
    let _g = serial();
    let dir = temp_dir("bad");
    let mut h = harness("bad");
    wait_ready(&mut h);
    let timeline = h.state().project().options.timeline.clone();
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
    let init = h.state().project().options.init.clone();
    h.state_mut().use_init_file(bvh, 0);
    wait(&mut h, "the initial pose error", |a| has_error(a, "cannot start a take"));
    h.run_ok();
    assert!(shows(&h, "cannot start a take"));
    assert_eq!(h.state().project().options.init, init);

    assert_eq!(h.state().project().options.timeline, timeline, "the timeline is untouched");
    assert_eq!(frames(&h), take_frames, "the take is untouched");
}

/// A take's root height above its lowest joint at frame `t` (model units).
fn hip_height(motion: &glocal::motion::Motion, t: usize) -> f32 {
    let f = motion.frame(t);
    f[0].y - f.iter().map(|p| p.y).fold(f32::INFINITY, f32::min)
}

/// The foot lock as a user meets it: on by default, its contacts exported with the take
/// (per foot, per frame), and its toggle regenerates the take with the feet as the network
/// made them, which slide.
#[test]
fn the_foot_lock_toggle_and_its_contacts() {
    let _g = serial();
    let dir = temp_dir("feet");
    let mut h = harness("feet");
    wait_take(&mut h);
    let take = h.state().take().unwrap();
    let locked = (take.motion.clone(), take.contacts.clone());
    assert!(h.state().take().unwrap().options.foot_lock, "the lock is on by default");
    assert!(locked.1.left.iter().any(|&c| c) && locked.1.right.iter().any(|&c| c), "both feet stand somewhere in the take");
    let out = dir.join("feet.json");
    h.state_mut().export_to(out.clone());
    wait(&mut h, "the export", |_| out.exists());
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    for foot in ["left_foot", "right_foot"] {
        let flags = json["contacts"][foot].as_array().unwrap_or_else(|| panic!("the export has {foot} contacts"));
        assert_eq!(flags.len(), locked.0.frames(), "{foot}: one flag per frame");
    }

    h.get_by_label("Foot lock").click_accesskit();
    wait(&mut h, "the unlocked take", |a| a.take().is_some_and(|t| !t.options.foot_lock) && !a.is_busy());
    let unlocked = h.state().take().unwrap().motion.clone();
    let roles = glocal::motion::JointRoles::new(&locked.0.skeleton).unwrap();
    let slide = |m: &glocal::motion::Motion| {
        let mut pool = glocal::eval::motion::Pool::default();
        pool.add_take(&m.resample(glocal::eval::motion::COMMON_FPS), &roles, None);
        pool.summary()[glocal::eval::motion::Measure::SupportSpeedMedian]
    };
    let (with, without) = (slide(&locked.0), slide(&unlocked));
    assert!(with < 0.5 * without, "support point {with:.1} cm/s with the lock, {without:.1} without");
}

#[test]
fn a_stale_take_is_flagged_and_not_exported() {
    let _g = serial();
    let dir = temp_dir("stale");
    let mut h = harness("stale");
    wait_take(&mut h);
    h.get_by_label("Regenerate after every edit").click_accesskit();
    h.run_ok();
    h.state_mut().add_segment();
    h.run_ok();
    assert!(shows(&h, "Out of date: an edit has not been generated yet"), "the export section says so");
    let out = dir.join("stale.json");
    // The Export buttons are disabled; the File menu's Export… ends in the same call.
    h.state_mut().export_to(out.clone());
    h.run_ok();
    assert!(has_error(h.state(), "Not exported: the take on screen is out of date"));
    assert!(!out.exists(), "nothing was written");

    // Generated: current again, and the export is of the take on screen.
    h.get_by_label("Generate").click_accesskit();
    wait(&mut h, "the new take", |a| a.stale_reason().is_none() && !a.is_busy());
    assert!(!shows(&h, "Not exported"), "the refusal went away with its cause");
    h.state_mut().export_to(out.clone());
    wait(&mut h, "the export", |_| out.exists());
    let (m, segments) = glocal::synth::export::read_take(&out, None).unwrap();
    assert_eq!((m.frames(), segments.len()), (frames(&h), 3));

    // A failed generation leaves the old take on screen, flagged, and not exportable.
    h.state_mut().set_segment_class(0, "flying");
    h.state_mut().regenerate();
    wait(&mut h, "the failure", |a| has_error(a, "Generation failed") && !a.is_busy());
    assert!(h.state().stale_reason().unwrap().contains("the last generation failed"));
    std::fs::remove_file(&out).unwrap();
    h.state_mut().export_to(out.clone());
    h.run_ok();
    assert!(!out.exists() && has_error(h.state(), "Not exported"));
}

#[test]
fn a_range_export_writes_the_frames_its_label_names() {
    let _g = serial();
    let dir = temp_dir("range");
    let mut h = harness("range");
    wait_take(&mut h);
    h.state_mut().set_selection(Some((56, 118)));
    h.run_ok();
    let label = h.state().range_label().unwrap();
    assert_eq!(label, "Range 56–117 (62 frames)");
    assert!(shows(&h, &label), "the transport bar shows it");
    h.get_by_label_contains("Selected range 56–117").click_accesskit();
    h.run_ok();
    let out = dir.join("range.json");
    h.state_mut().fields_mut().export_path = out.display().to_string();
    h.get_by_label("Export").click_accesskit();
    wait(&mut h, "the export", |_| out.exists());
    let (exported, _) = glocal::synth::export::read_take(&out, None).unwrap();
    assert_eq!(exported.frames(), 62, "the label's frame count");
    // Its first frame is frame 56 (set on the floor, in metres).
    let take = h.state().take().unwrap();
    let range = take.motion.slice(56, 118);
    let unit = take.motion.skeleton.meters_per_unit();
    let expected = (range.frame(0)[0] - glam::Vec3::Y * range.floor_height()) * unit;
    assert!(exported.frame(0)[0].distance(expected) < 1e-4, "{} vs {expected}", exported.frame(0)[0]);
}

#[test]
fn by_class_starts_from_a_pose_of_that_class() {
    let _g = serial();
    let mut h = harness("byclass");
    wait_take(&mut h);
    let standing = hip_height(&h.state().take().unwrap().motion, 0);
    h.get_by_label("By class").click_accesskit();
    h.run_ok();
    assert!(matches!(h.state().project().options.init, glocal::synth::InitPose::SeedClass { .. }), "choosing the tab applies it");
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "Start class").click_accesskit();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::Button, "sitting").click();
    h.run_ok();
    let glocal::synth::InitPose::SeedClass { class, variant } = h.state().project().options.init.clone() else { panic!("not a class start") };
    assert_eq!(class, "sitting");
    assert_ne!(variant, 0, "the class's first seed window (the start of a clip, standing) is not its typical one");
    // The tab names the window the start is (its clip names its style on Bandai's data).
    let model = h.state().model_info().unwrap();
    let sitting_class = model.spec.class_index("sitting").unwrap();
    let window = model.seeds.iter().filter(|s| s.class == sitting_class).nth(variant).unwrap();
    let named = format!("{} @ {}", window.clip, window.frame);
    h.run_ok();
    assert!(shows(&h, &named), "the tab does not name the start window {named}");
    wait(&mut h, "the sitting start", |a| a.take().is_some_and(|t| t.options.init == a.project().options.init) && !a.is_busy());
    let sitting = hip_height(&h.state().take().unwrap().motion, 0);
    assert!(sitting < 0.75 * standing, "a sitting start has the hips low: {sitting:.0} against {standing:.0} standing");
}

#[test]
fn ctrl_z_in_a_text_field_undoes_the_typing_only() {
    let _g = serial();
    let mut h = harness("typing");
    wait_take(&mut h);
    h.state_mut().add_segment();
    h.run_ok();
    let field = "Export file (.bvh, .json, .npy or .glb)";
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, field).focus();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, field).type_text("xyz");
    h.run_ok();
    assert!(h.state_mut().fields_mut().export_path.ends_with("xyz"));
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.run_ok();
    assert_eq!(h.state().project().options.timeline.segments.len(), 3, "the project edit stays");
    assert!(!h.state_mut().fields_mut().export_path.ends_with("xyz"), "the typing is undone");
}

#[test]
fn new_and_open_ask_before_discarding_unsaved_work() {
    let _g = serial();
    let dir = temp_dir("discard");
    let mut h = harness("discard");
    wait_take(&mut h);
    assert!(!h.state().has_unsaved_work(), "a fresh start has nothing to lose");
    h.state_mut().add_segment();
    h.run_ok();
    let menu = file_new;
    menu(&mut h);
    assert!(shows(&h, "Unsaved changes"), "New asks");
    assert_eq!(h.state().project().options.timeline.segments.len(), 3, "nothing is discarded yet");
    h.get_by_label("Discard changes").click();
    h.run_ok();
    assert_eq!(h.state().project().options.timeline.segments.len(), 2, "a new project");
    assert!(!shows(&h, "Unsaved changes"));

    // Open with unsaved work: "Save first" saves, then opens.
    let other = dir.join("other.json");
    h.state_mut().save_project(&other);
    menu(&mut h);
    assert!(!shows(&h, "Unsaved changes"), "nothing to lose: no question");
    let mine = dir.join("mine.json");
    h.state_mut().add_segment();
    h.state_mut().fields_mut().project_path = mine.display().to_string();
    h.run_ok();
    h.state_mut().request(glocal::studio::panels::Guarded::Open(other.clone()));
    h.run_ok();
    assert!(shows(&h, "Unsaved changes"), "Open asks");
    h.get_by_label("Save first").click();
    h.run_ok();
    // A project never saved asks where to save, starting from the typed path.
    let field = h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Path");
    assert_eq!(field.value().as_deref(), Some(mine.display().to_string().as_str()));
    h.get_by_label("OK").click();
    h.run_ok();
    assert_eq!(glocal::studio::project::Project::load(&mine).unwrap().options.timeline.segments.len(), 3, "the work was saved");
    assert_eq!(h.state().project().options.timeline.segments.len(), 2, "then the other project opened");
    assert!(has_message(h.state(), &format!("Opened {}", other.display())), "{:?}", h.state().messages().all());
}

#[test]
fn switching_models_maps_classes_keeps_durations_and_says_so() {
    let _g = serial();
    let dir = temp_dir("switch");
    let mut h = harness("switch");
    wait_take(&mut h);
    let sitting = h.state().model_info().unwrap().spec.class_index("sitting").unwrap();
    h.state_mut().fields_mut().new_class = sitting;
    h.state_mut().add_segment();
    // An initial pose from a file only this model can read (an NPY on its 27 joints).
    wait(&mut h, "three segments", |a| a.take().is_some_and(|t| t.segments.len() == 3) && !a.is_busy());
    let clip = dir.join("h36m.npy");
    h.state_mut().export_to(clip.clone());
    wait(&mut h, "the export", |_| clip.exists());
    h.state_mut().use_init_file(clip.clone(), 0);
    wait(&mut h, "the file start", |a| matches!(a.project().options.init, glocal::synth::InitPose::File { .. }));
    let before: Vec<f32> = h.state().project().options.timeline.segments.iter().map(|s| s.seconds).collect();

    h.get_by_label("bandai").click_accesskit();
    wait(&mut h, "bandai and its take", |a| a.model_info().is_some_and(|m| m.spec.dataset == "bandai") && a.take().is_some_and(|t| t.model_dir.ends_with("bandai")) && !a.is_busy());
    let app = h.state();
    let classes: Vec<&str> = app.project().options.timeline.segments.iter().map(|s| s.class.as_str()).collect();
    assert_eq!(classes, ["walk", "guide", "guide"]);
    let after: Vec<f32> = app.project().options.timeline.segments.iter().map(|s| s.seconds).collect();
    assert_eq!(after, before, "durations are kept");
    assert!(has_message(app, "Classes carried over to bandai: walking -> walk, directions -> guide, sitting -> guide (3 segments"), "{:?}", app.messages().log());
    assert!(has_message(app, "does not fit the bandai model"), "the h36m file start is reset: {:?}", app.messages().log());
    assert!(matches!(app.project().options.init, glocal::synth::InitPose::SeedClass { .. }));
    assert_eq!(app.messages().errors().count(), 0, "no unknown-class errors: {:?}", app.messages().all());
    assert_eq!(app.take().unwrap().segments.len(), 3);

    // A pairing edited by the user.
    h.state_mut().set_mapping("directions", "bow");
    wait(&mut h, "the retagged take", |a| a.take().is_some() && a.stale_reason().is_none() && !a.is_busy());
    assert_eq!(h.state().project().options.timeline.segments[1].class, "bow");

    // Bandai in centimetres at 60 fps with its source root joint.
    *h.state_mut().export_options_mut() = glocal::synth::export::ExportOptions { units: glocal::synth::export::Units::Centimetres, fps: Some(60.0), source_root: true, ..Default::default() };
    let out = dir.join("bandai.bvh");
    h.state_mut().export_to(out.clone());
    wait(&mut h, "the bandai export", |_| out.exists());
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("ROOT joint_Root") && text.contains("JOINT Hips"), "the source root is kept");
    assert!(text.contains("Frame Time: 0.01666667"));
    let n = frames(&h);
    let written: usize = text.lines().find_map(|l| l.strip_prefix("Frames:")).unwrap().trim().parse().unwrap();
    assert_eq!(written, 2 * n - 1, "{n} frames at 30 fps resampled to 60");

    // And back.
    h.get_by_label("h36m").click_accesskit();
    wait(&mut h, "h36m again", |a| a.model_info().is_some_and(|m| m.spec.dataset == "h36m") && a.take().is_some_and(|t| t.model_dir.ends_with("h36m")) && !a.is_busy());
    let classes: Vec<String> = h.state().project().options.timeline.segments.iter().map(|s| s.class.clone()).collect();
    // A segment left as the switch made it gets its own class back; the one the user
    // retagged on Bandai (bow) is mapped.
    assert_eq!(classes, ["walking", "greeting", "sitting"]);
}

#[test]
fn starts_from_a_working_folder_outside_the_repository() {
    let _g = serial();
    // kittest reads kittest.toml from the working folder once: read it before leaving.
    let _ = SnapshotOptions::default();
    let elsewhere = temp_dir("elsewhere");
    let repo = std::env::current_dir().unwrap();
    std::env::set_current_dir(&elsewhere).unwrap();
    let found = StudioOptions::default();
    let options = StudioOptions { autosave: Some(elsewhere.join("autosave.json")), restore_autosave: false, system_dialogs: false, ..found.clone() };
    let h = harness_with(options, egui::vec2(1280.0, 800.0));
    std::env::set_current_dir(&repo).unwrap();
    let mut h = h;

    let exe_dir = std::env::current_exe().unwrap().parent().unwrap().to_path_buf();
    let crate_models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    assert_eq!(found.model_roots.first(), Some(&exe_dir.join("models")), "beside the executable first");
    assert!(found.model_roots.contains(&crate_models), "the crate's models/: {:?}", found.model_roots);
    assert!(found.model_roots.iter().any(|r| r.starts_with(&elsewhere) || r.canonicalize().ok() == elsewhere.canonicalize().ok().map(|e| e.join("models"))), "and the working folder: {:?}", found.model_roots);
    assert_eq!(found.model_dir, crate_models.join("all"));
    wait_take(&mut h);
    let (roots, shipped) = h.state().model_search();
    assert_eq!(roots, found.model_roots.as_slice());
    let names: Vec<_> = shipped.iter().filter_map(|p| p.file_name()).collect();
    assert_eq!(names, ["all", "bandai", "h36m"]);
    assert_eq!(h.state().model_info().unwrap().dir, crate_models.join("all"));
}

#[test]
fn a_worker_panic_reaches_the_ui_and_the_worker_keeps_serving() {
    let _g = serial();
    let dir = temp_dir("panic");
    let mut h = harness("panic");
    wait_take(&mut h);
    let npy = dir.join("take.npy");
    h.state_mut().export_to(npy.clone());
    wait(&mut h, "the export", |_| npy.exists());
    // The furthest frame there is: its arithmetic overflows inside the engine.
    h.state_mut().use_init_file(npy, usize::MAX);
    wait(&mut h, "the error", |a| has_error(a, "cannot start a take"));
    let first = h.state().take().unwrap().id;
    h.state_mut().edit(|d| d.set_variation_seed(7));
    wait(&mut h, "a take after the failure", |a| a.take().is_some_and(|t| t.id != first) && !a.is_busy());
}

#[test]
fn a_broken_autosave_is_kept_and_paths_survive_a_restart() {
    let _g = serial();
    let dir = temp_dir("restart");
    let autosave = dir.join("autosave.json");
    std::fs::write(&autosave, "{ \"version\": 1, broken").unwrap();
    let restoring = StudioOptions { autosave: Some(autosave.clone()), restore_autosave: true, ..options("restart") };
    let mut h = harness_with(restoring.clone(), egui::vec2(1280.0, 800.0));
    wait_take(&mut h);
    let kept = std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok()).map(|e| e.path()).find(|p| p.to_string_lossy().contains("autosave.broken-")).expect("the broken autosave is kept");
    assert_eq!(std::fs::read_to_string(&kept).unwrap(), "{ \"version\": 1, broken");
    assert!(has_error(h.state(), &format!("it is kept as {}", kept.display())), "{:?}", h.state().messages().all());
    let project = dir.join("p.json");
    assert!(h.state_mut().save_project(&project));
    assert!(has_message(h.state(), &format!("Saved {}", project.display())), "the full path");
    h.state_mut().add_segment();
    wait(&mut h, "the autosave", |_| glocal::studio::project::Project::load(&autosave).is_ok_and(|p| p.options.timeline.segments.len() == 3));
    drop(h);

    let mut h = harness_with(restoring, egui::vec2(1280.0, 800.0));
    wait_take(&mut h);
    assert!(has_message(h.state(), "Restored from the autosave"));
    assert_eq!(h.state().project().options.timeline.segments.len(), 3);
    assert_eq!(h.state().project_path(), Some(project.as_path()), "the open project's path survives");
}

#[test]
fn without_a_system_dialog_export_opens_a_typed_path_dialog() {
    let _g = serial();
    let dir = temp_dir("dialog");
    let mut h = harness("dialog");
    wait_take(&mut h);
    let out = dir.join("typed.bvh");
    h.state_mut().fields_mut().export_path = out.display().to_string();
    h.get_by_label("Export…").click_accesskit();
    h.run_ok();
    assert!(shows(&h, "No system file dialog is available here"), "the in-app dialog is open");
    let field = h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Path");
    assert!(field.is_focused(), "the path field is focused");
    assert_eq!(field.value().as_deref(), Some(out.display().to_string().as_str()));
    h.get_by_label("OK").click();
    // The file is written before the worker's reply reaches the UI: wait for both.
    wait(&mut h, "the export", |a| out.exists() && has_message(a, &format!("Exported {}", out.display())));
    assert!(has_message(h.state(), &format!("Exported {}", out.display())));
}

/// The take's body root on the ground at frame `t`, in metres (x, z).
fn root_on_ground(motion: &glocal::motion::Motion, t: usize) -> glam::Vec2 {
    let root = glocal::motion::JointRoles::new(&motion.skeleton).unwrap().body_root;
    let p = motion.frame(t)[root] * motion.skeleton.meters_per_unit();
    glam::vec2(p.x, p.z)
}

/// A press and release at `pos` (a click that does not drag).
fn click_at(h: &mut Harness<'_, StudioApp>, pos: egui::Pos2) {
    h.event(egui::Event::PointerMoved(pos));
    h.run_ok();
    for pressed in [true, false] {
        h.event(egui::Event::PointerButton { pos, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() });
        h.run_ok();
    }
}

/// Where the test clicks the viewport's ground (at 1280x800, the camera on the take's start).
const CLICK: egui::Pos2 = egui::pos2(470.0, 470.0);

/// The workflow the studio is built for: draw a path, generate a take along it, key a frame
/// of that take (its pose and where it stands), change the activity around the key, and
/// generate again. A root-fixing key bends the take towards where its pose stood from the
/// start of the take, so a key taken from a take that follows the path keeps the path.
#[test]
fn a_drawn_waypoint_and_a_key_from_the_current_frame_shape_the_next_take() {
    use glocal::synth::constraints::KeySource;
    let _g = serial();
    let dir = temp_dir("keys");
    let mut h = harness("keys");
    wait_take(&mut h);
    h.state_mut().edit(|d| d.options.timeline = "walking:6,directions:4".parse().unwrap());
    wait(&mut h, "the 10 s take", |a| a.take().is_some_and(|t| t.options.timeline.seconds() == 10.0) && !a.is_busy());
    let first = h.state().take().unwrap().motion.clone();
    let fps = first.fps;

    // Draw a path: one click on the ground in the viewport (the path starts where the take does).
    h.get_by_label("Draw path").click_accesskit();
    h.run_ok();
    click_at(&mut h, CLICK);
    let path = h.state().project().options.path.clone().expect("a path");
    assert_eq!(path.waypoints.len(), 2, "the take's start and the clicked point: {path:?}");
    let start = root_on_ground(&first, 0);
    assert!(glam::vec2(path.waypoints[0].x, path.waypoints[0].z).distance(start) < 1e-4);
    let target = glam::vec2(path.waypoints[1].x, path.waypoints[1].z);
    assert!(h.query_by_label("Waypoint 2").is_some(), "the waypoint is on its track");
    let nearest = |m: &glocal::motion::Motion| (0..m.frames()).map(|t| root_on_ground(m, t).distance(target)).fold(f32::INFINITY, f32::min);
    let missed = nearest(&first);
    assert!(missed > 0.5, "the waypoint is off the first take's way (it passes {missed:.2} m from it; waypoint {target}, start {start})");

    // Undo takes the waypoint away, redo brings it back.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.run_ok();
    assert!(h.state().project().options.path.is_none());
    h.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    h.run_ok();
    assert_eq!(h.state().project().options.path, Some(path.clone()));
    h.get_by_label("Draw path").click_accesskit();
    wait(&mut h, "the take along the path", |a| a.take().is_some_and(|t| t.options.path.is_some()) && a.stale_reason().is_none() && !a.is_busy());
    let along = h.state().take().unwrap().motion.clone();
    let passes = nearest(&along);
    assert!(passes < 0.25, "the take passes {passes:.2} m from the waypoint {target} (the first passed {missed:.2} m)");

    // Key the pose at 9 s of that take.
    let ruler = h.get_by_label("Timeline ruler").rect();
    click_at(&mut h, egui::pos2(ruler.left() + 9.0 * (ruler.width() - 8.0) / 10.0, ruler.center().y));
    let key_frame = h.state().frame();
    assert!((key_frame as f32 / fps - 9.0).abs() < 0.1, "the ruler click seeks to 9 s: frame {key_frame}");
    h.get_by_label("Key from current frame").click_accesskit();
    h.run_ok();
    let keys = h.state().project().options.keys.clone();
    assert_eq!(keys.len(), 1, "one key in the project's options");
    assert!((keys[0].seconds - key_frame as f32 / fps).abs() < 1e-4 && keys[0].fix_root);
    let KeySource::Pose(pose) = &keys[0].source else { panic!("a key from the take's frame holds its pose") };
    assert_eq!(pose.len(), first.joints());
    assert!(h.query_by_label("Key 1").is_some(), "the key is on its track");

    // The second segment becomes another activity: the key still holds its pose there.
    h.state_mut().set_segment_class(1, "phoning");
    wait(&mut h, "the constrained take", |a| a.take().is_some_and(|t| !t.options.keys.is_empty() && t.options.timeline.segments[1].class == "phoning") && a.stale_reason().is_none() && !a.is_busy());
    let motion = h.state().take().unwrap().motion.clone();
    let saved = dir.join("keys.json");
    assert!(h.state_mut().save_project(&saved));
    let back = glocal::studio::project::Project::load(&saved).unwrap();
    assert_eq!((back.options.keys.clone(), back.options.path.clone()), (keys.clone(), Some(path)));

    // The take passes through the key (body and root) and still near the waypoint.
    let unit = motion.skeleton.meters_per_unit();
    let root = glocal::motion::JointRoles::new(&motion.skeleton).unwrap().body_root;
    let at = motion.frame(key_frame.min(motion.frames() - 1));
    let key_root = glam::Vec3::from(pose[root]);
    let body = (0..motion.joints()).map(|j| ((at[j] - at[root]) - (glam::Vec3::from(pose[j]) - key_root)).length() * unit).fold(0.0f32, f32::max);
    assert!(body < 0.05, "the keyed pose is {:.1} cm away at its joint furthest off", body * 100.0);
    assert!((at[root] - key_root).length() * unit < 0.05, "the root is {:.1} cm from the key's", (at[root] - key_root).length() * unit * 100.0);
    let still = nearest(&motion);
    assert!(still < 0.3, "with the key the take passes {still:.2} m from the waypoint");
    assert!(h.state().messages().log().iter().all(|m| !m.text.contains("Generation failed")), "{:?}", h.state().messages().log());
    println!("waypoint {:.2} m from the start: first take {missed:.2} m from it, along the path {passes:.2} m, with the key {still:.2} m; key: body {:.1} cm (worst joint), root {:.1} cm", target.distance(start), body * 100.0, (at[root] - key_root).length() * unit * 100.0);
}

#[test]
fn a_sit_too_short_after_a_walk_is_explained_and_fixed_in_one_click() {
    let _g = serial();
    let mut h = harness("advice");
    wait_take(&mut h);
    h.state_mut().edit(|d| d.options.timeline = "walking:4,sitting:3".parse().unwrap());
    h.run_ok();
    assert!(has_message(h.state(), "The seated activity in segment 2 follows a standing one"), "{:?}", h.state().messages().log());
    assert!(shows(&h, "Insert sittingdown (2 s) before it") && shows(&h, "Lengthen segment 2 to 4.0 s"));
    h.get_by_label("Insert sittingdown (2 s) before it").click_accesskit();
    h.run_ok();
    let classes: Vec<String> = h.state().project().options.timeline.segments.iter().map(|s| s.class.clone()).collect();
    assert_eq!(classes, ["walking", "sittingdown", "sitting"]);
    assert!(!shows(&h, "Insert sittingdown"), "the advice went away with its cause");
    wait(&mut h, "the fixed take", |a| a.take().is_some_and(|t| t.segments.len() == 3) && a.stale_reason().is_none() && !a.is_busy());
    let motion = &h.state().take().unwrap().motion;
    let (start, end) = (hip_height(motion, 0), hip_height(motion, motion.frames() - 1));
    assert!(end < 0.75 * start, "the take ends seated: hips {end:.2} against {start:.2} standing");

    // The transition into segment 3, of its own length, saved with the project.
    h.get_by_label("Segment 3: sitting").click();
    h.run_ok();
    // Off the timeline, the row under it shows the segment's settings (not the hover hint).
    h.event(egui::Event::PointerMoved(egui::pos2(640.0, 300.0)));
    h.run_ok();
    h.get_by_label("own transition").click_accesskit();
    h.run_ok();
    assert_eq!(h.state().project().options.timeline.segments[2].transition, Some(2.0), "starts at the global length");
    h.get_by_label("Segment 3: sitting").hover();
    h.run_ok();
    assert!(shows(&h, "Segment 3: sitting · 3.0s · in 2.0s"), "the block says so");
    let path = temp_dir("advice").join("p.json");
    assert!(h.state_mut().save_project(&path));
    assert_eq!(glocal::studio::project::Project::load(&path).unwrap().options.timeline.segments[2].transition, Some(2.0));
}

/// Mean angle in degrees between corresponding bones (joint minus parent) of two poses on
/// the same skeleton, after turning `b` about the vertical to face like `a` (a take starts
/// facing the model's way); bones of no length are skipped.
fn mean_bone_angle(skeleton: &glocal::motion::Skeleton, a: &[glam::Vec3], b: &[glam::Vec3]) -> f32 {
    let mean_at = |yaw: f32| {
        let turn = glam::Quat::from_rotation_y(yaw);
        let angles: Vec<f32> = (0..skeleton.len())
            .filter_map(|j| {
                let p = skeleton.parents()[j]?;
                let (u, v) = ((a[j] - a[p]).try_normalize()?, (turn * (b[j] - b[p])).try_normalize()?);
                Some(u.dot(v).clamp(-1.0, 1.0).acos().to_degrees())
            })
            .collect();
        angles.iter().sum::<f32>() / angles.len() as f32
    };
    (0..360).map(|d| mean_at((d as f32).to_radians())).fold(f32::INFINITY, f32::min)
}

/// Picks `joint` in the mapping editor's combo box for `key`.
fn choose_joint(h: &mut Harness<'_, StudioApp>, key: &str, joint: &str) {
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, key).click_accesskit();
    h.run_ok();
    h.get_by_label(joint).click();
    h.run_ok();
}

/// An Unreal-named BVH with two key joints renamed to words no table knows: the studio says
/// which keys are missing, the mapping editor (pre-filled with the table's guesses) names
/// them, the preview shows the retargeted pose, and the take generated from it starts there.
#[test]
fn a_foreign_bvh_is_mapped_in_the_editor_previewed_and_starts_the_take() {
    let _g = serial();
    let dir = temp_dir("joint-map");
    let bvh = dir.join("renamed-unreal.bvh");
    let text = std::fs::read_to_string("tests/assets/blender-unreal-salsa.bvh").unwrap();
    std::fs::write(&bvh, text.replace("JOINT lowerarm_l\n", "JOINT zz_bend_a\n").replace("JOINT calf_r\n", "JOINT zz_bend_b\n")).unwrap();
    let mut h = harness("joint-map");
    wait_take(&mut h);
    let seed_take = h.state().take().unwrap().motion.clone();

    h.state_mut().set_init_tab(glocal::studio::panels::InitTab::File);
    h.run_ok();
    h.state_mut().fields_mut().init_path = bvh.display().to_string();
    h.get_by_label("Use file").click();
    wait(&mut h, "the mapping error", |a| has_error(a, "cannot be mapped"));
    h.run_ok();
    let error = h.state().messages().errors().map(|m| m.text.clone()).collect::<Vec<_>>().join("; ");
    assert!(error.contains("LeftForeArm") && error.contains("RightLeg"), "the message names the missing keys: {error}");
    assert!(error.contains("name them with Edit mapping"), "the studio points at its editor: {error}");
    assert!(h.state().retarget_preview().is_none());

    h.get_by_label("Edit mapping…").click();
    h.run_ok();
    assert!(shows(&h, "The file's joint for each of the model's key joints"));
    let guessed = h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "LeftHand").value();
    assert_eq!(guessed.as_deref(), Some("hand_l"), "pre-filled by the name table");
    choose_joint(&mut h, "LeftForeArm", "zz_bend_a");
    choose_joint(&mut h, "RightLeg", "zz_bend_b");
    h.get_by_label("Apply").click();
    wait(&mut h, "the retarget preview", |a| a.retarget_preview().is_some());
    h.run_ok();
    assert!(shows(&h, "Retargeted pose"));
    let map = h.state().project().joint_map.clone().expect("the mapping is in the project");
    assert_eq!(map.get("zz_bend_a").map(String::as_str), Some("LeftForeArm"));
    assert_eq!(map.get("zz_bend_b").map(String::as_str), Some("RightLeg"));
    let preview = h.state().retarget_preview().unwrap();
    let retargeted = preview.retargeted.clone();
    assert!(preview.source.skeleton.index_of("zz_bend_a").is_some(), "the source is the file's own skeleton");
    assert_eq!(retargeted.skeleton.len(), seed_take.skeleton.len(), "the retargeted pose is on the model's joints");

    h.get_by_label("Use").click();
    wait(&mut h, "a take from the retargeted file", |a| {
        a.take().is_some_and(|t| matches!(&t.options.init, glocal::synth::InitPose::File { path, .. } if path == &bvh)) && !a.is_busy()
    });
    assert!(h.state().retarget_preview().is_none());
    let take = h.state().take().unwrap().motion.clone();
    let from_file = mean_bone_angle(&take.skeleton, take.frame(0), retargeted.frame(0));
    let from_seed = mean_bone_angle(&take.skeleton, seed_take.frame(0), retargeted.frame(0));
    eprintln!("mean bone angle to the retargeted pose: take {from_file:.1} deg, seed take {from_seed:.1} deg");
    assert!(from_file < 10.0, "the take starts from the retargeted pose ({from_file:.1} degrees off)");
    assert!(from_seed > 3.0 * from_file.max(10.0) / 3.0, "the seed take starts elsewhere ({from_seed:.1} degrees off), so the check can fail");

    // A key from the same file, mid-take: previewed at once with the project's mapping.
    h.get_by_label("Timeline ruler").click();
    h.run_ok();
    h.get_by_label("Key from file…").click_accesskit();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Path").type_text(&bvh.display().to_string());
    h.get_by_label("OK").click();
    wait(&mut h, "the key's retarget preview", |a| a.retarget_preview().is_some());
    h.get_by_label("Use").click();
    wait(&mut h, "a take with the key", |a| a.take().is_some_and(|t| t.options.keys.len() == 1) && !a.is_busy());
    // The built-in table cannot map this file: a take with the key means the mapping was used.
    let key = &h.state().take().unwrap().options.keys[0];
    assert!(matches!(&key.source, glocal::synth::constraints::KeySource::Init(glocal::synth::InitPose::File { path, .. }) if path == &bvh));
    assert!(h.state().stale_reason().is_none(), "the take is the document's");

    // The mapping is saved with the project.
    let project = dir.join("mapped.glocal.json");
    assert!(h.state_mut().save_project(&project));
    let saved = glocal::studio::project::Project::load(&project).unwrap();
    assert_eq!(saved.joint_map, Some(map));
}

/// The Generation section's "The paper's method" sets the one paper preset that `glocal
/// generate --paper` and `glocal eval --paper` apply, as one undoable edit.
#[test]
fn the_papers_method_is_the_one_paper_preset() {
    let mut h = harness("paper-preset");
    wait_ready(&mut h);
    let before = h.state().project().options.clone();
    assert_ne!(Preset::Paper.apply(before.clone()), before, "the shipped options are not the paper's already");
    h.get_by_label("The paper's method").click();
    h.run_ok();
    assert_eq!(h.state().project().options, Preset::Paper.apply(before.clone()));
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.step();
    assert_eq!(h.state().project().options, before, "Ctrl+Z brings the shipped options back");
}

/// The Export section's "root bone" exports the take with a `root` joint on the floor above
/// the hips, as `--root-motion root-bone` does.
#[test]
fn the_export_section_chooses_the_root_motion() {
    let _g = serial();
    let mut h = harness("root-motion");
    wait_ready(&mut h);
    h.get_by_label("root bone").click_accesskit();
    h.run_ok();
    assert_eq!(h.state_mut().export_options_mut().root_motion, glocal::motion::RootMotion::RootBone);
    let out = temp_dir("root-motion").join("take.bvh");
    h.state_mut().export_to(out.clone());
    wait(&mut h, "the export", |_| out.exists());
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("ROOT root") && text.contains("JOINT Hips"), "no root bone above the hips:\n{}", &text[..300.min(text.len())]);
}

/// The Export section offers GLB beside BVH, JSON and NPY, and 60 fps is a click away at
/// 1280x800 (the popup it was in was clipped below the sidebar).
#[test]
fn the_export_section_offers_glb_and_60_fps() {
    let mut h = harness("glb-60");
    wait_ready(&mut h);
    h.get_by_label("GLB").click_accesskit();
    h.get_by_label("60").click_accesskit();
    h.run_ok();
    assert!(h.state_mut().fields_mut().export_path.ends_with(".glb"), "{}", h.state_mut().fields_mut().export_path);
    assert_eq!(h.state_mut().export_options_mut().fps, Some(60.0));
}

/// The window's title names the project and marks unsaved work.
#[test]
fn the_title_names_the_project_and_marks_unsaved_work() {
    let dir = temp_dir("title");
    let mut h = harness("title");
    wait_ready(&mut h);
    assert!(h.state().window_title().starts_with("untitled"), "{}", h.state().window_title());
    h.state_mut().edit(|p| p.options.pace = 1.5);
    h.run_ok();
    assert!(h.state().window_title().contains('•'), "an edit marks the title: {}", h.state().window_title());
    assert!(h.state_mut().save_project(&dir.join("scene.glocal.json")), "saved");
    h.run_ok();
    assert_eq!(h.state().window_title(), "scene.glocal.json — Glocal Studio");
}

/// A segment with its own pace that does not divide into whole sparse steps says what length
/// the take makes of it (4 s at pace 1.5 made 3.92 s while the block said 4.0 s), and ticking
/// "own pace" leaves the widgets after it where they were (the slider it added took the
/// next click).
#[test]
fn a_segment_says_the_length_its_pace_makes() {
    let mut h = harness("own-pace");
    wait_ready(&mut h);
    h.get_by_label("Segment 2: directions").click();
    h.run_ok();
    h.event(egui::Event::PointerMoved(egui::pos2(640.0, 300.0)));
    h.run_ok();
    let before = h.get_by_label("own transition").rect();
    h.get_by_label("own pace").click_accesskit();
    h.run_ok();
    assert_eq!(h.get_by_label("own transition").rect(), before, "ticking own pace moved the row");
    h.state_mut().edit(|p| p.options.timeline.segments[1].pace = Some(1.5));
    wait(&mut h, "the paced take", |a| a.take().is_some_and(|t| t.options.timeline.segments[1].pace == Some(1.5)) && a.stale_reason().is_none() && !a.is_busy());
    h.get_by_label("Segment 2: directions").hover();
    h.run_ok();
    assert!(shows(&h, "4.0s (makes 3.9"), "the block does not say the length the take makes");
}

/// A right-click selects the block its menu is about, and a shift-drag on the ruler starts
/// its range at the frame where the button went down (it started 1-4 frames on).
#[test]
fn right_click_selects_and_a_range_starts_at_the_press() {
    let mut h = harness("right-click");
    wait_ready(&mut h);
    h.get_by_label("Segment 2: directions").click_secondary();
    h.run_ok();
    h.key_press(Key::Escape);
    // Off the timeline, the row under it shows the selected segment's settings.
    h.event(egui::Event::PointerMoved(egui::pos2(640.0, 300.0)));
    h.run_ok();
    assert!(h.query_by_label("Segment 2").is_some(), "the right-clicked segment's row is not shown");
    let ruler = h.get_by_label("Timeline ruler").rect();
    let press = egui::pos2(ruler.left() + 0.3 * ruler.width(), ruler.center().y);
    h.get_by_label("Timeline ruler").hover();
    h.event(egui::Event::PointerMoved(press));
    h.event(egui::Event::PointerButton { pos: press, button: egui::PointerButton::Primary, pressed: true, modifiers: Default::default() });
    h.event(egui::Event::PointerButton { pos: press, button: egui::PointerButton::Primary, pressed: false, modifiers: Default::default() });
    h.run_ok();
    let at_press = h.state().frame();
    h.event(egui::Event::ModifiersChanged(Modifiers::SHIFT));
    h.event(egui::Event::PointerButton { pos: press, button: egui::PointerButton::Primary, pressed: true, modifiers: Modifiers::SHIFT });
    h.step();
    for dx in [3.0, 6.0, 20.0, 60.0] {
        h.event(egui::Event::PointerMoved(press + egui::vec2(dx, 0.0)));
        h.step();
    }
    h.event(egui::Event::PointerButton { pos: press + egui::vec2(60.0, 0.0), button: egui::PointerButton::Primary, pressed: false, modifiers: Modifiers::SHIFT });
    h.step();
    h.event(egui::Event::ModifiersChanged(Modifiers::NONE));
    h.run_ok();
    let (start, end) = h.state().selection().expect("the shift-drag selects a range");
    assert_eq!(start, at_press, "the range starts {} frames after the press", start as i64 - at_press as i64);
    assert!(end > start + 5, "{start}..{end}");
}

/// On the model of everything the selected segment's row has a style combo beside its class:
/// the usual style until one is picked, and the take is made in the style picked (issue 35).
#[test]
fn a_segment_takes_a_style_on_the_model_of_everything() {
    let _g = serial();
    let options = StudioOptions { model_dir: "models/all".into(), ..options("styles") };
    let mut h = harness_with(options, egui::vec2(1280.0, 800.0));
    wait_ready(&mut h);
    assert_eq!(h.state().model_info().unwrap().spec.dataset, "all");
    let first = h.state().take().unwrap().options.timeline.segments[0].class.clone();
    h.get_by_label(&format!("Segment 1: {first}")).click_secondary();
    h.run_ok();
    h.key_press(Key::Escape);
    h.event(egui::Event::PointerMoved(egui::pos2(640.0, 300.0)));
    h.run_ok();
    assert_eq!(h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "style").value().as_deref(), Some("usual style"));
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "style").click_accesskit();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::Button, "happy").click();
    h.run_ok();
    wait(&mut h, "the take in its style", |a| a.take().is_some_and(|t| t.options.timeline.segments[0].style.as_deref() == Some("happy")) && !a.is_busy());
    assert_eq!(h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "style").value().as_deref(), Some("happy"), "the combo shows the style picked");
    // The block names its style as the command line does.
    h.get_by_label(&format!("Segment 1: {first}")).hover();
    h.run_ok();
    assert!(shows(&h, &format!("Segment 1: {first}/happy · ")), "the block does not name its style");
}
