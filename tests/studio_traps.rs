//! Issue 40's traps in the studio, as a user meets them: a session that must lose nothing
//! (a kill, New, Open, Save first, a model round trip), the command line that makes the
//! studio's take, and the retarget preview. Real worker, shipped models (see
//! `support/studio.rs`).

#[path = "support/studio.rs"]
mod support;

use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use glocal::studio::{StudioApp, StudioOptions};
use glocal::studio::panels::InitTab;
use glocal::synth::{InitPose, Key as TakeKey, KeySource};
use support::*;

/// Issue 40, items 1 to 3, as a session: work restored after a kill is unsaved (so New
/// asks, and Save first writes it to its own project file); "Save first" before opening a
/// file never writes that file (a never-saved project asks where to save, and refuses the
/// file being opened); a model round trip h36m -> Bandai -> h36m brings back every class and
/// key, Ctrl+Z undoes a switch with its model, and a key made on Bandai is retargeted onto
/// h36m; nothing is lost on the way.
#[test]
fn a_session_loses_nothing_through_a_kill_new_open_save_first_and_a_model_round_trip() {
    let _g = serial();
    let dir = temp_dir("traps");
    let storage = StudioOptions { restore_autosave: true, ..options("traps") };
    let autosave = storage.autosave.clone().unwrap();
    let mut h = harness_with(storage.clone(), egui::vec2(1280.0, 800.0));
    wait_take(&mut h);
    let mine = dir.join("mine.glocal.json");
    assert!(h.state_mut().save_project(&mine));
    h.state_mut().add_segment();
    wait(&mut h, "the autosave of the edit", |_| glocal::studio::project::Project::load(&autosave).is_ok_and(|p| p.options.timeline.segments.len() == 3));
    drop(h);

    // Restarted: the edit is back, with its path, and counted as unsaved.
    let mut h = harness_with(storage.clone(), egui::vec2(1280.0, 800.0));
    wait_take(&mut h);
    assert_eq!(h.state().project().options.timeline.segments.len(), 3, "the autosave is restored");
    assert_eq!(h.state().project_path(), Some(mine.as_path()), "with its project's path");
    assert_eq!(segments_in(&mine), 2, "the project file lacks the edit");
    assert!(h.state().has_unsaved_work(), "restored work is unsaved");
    assert!(shows(&h, "unsaved changes"));
    file_new(&mut h);
    assert!(shows(&h, "Unsaved changes"), "New asks");
    h.get_by_label("Save first").click();
    h.run_ok();
    assert_eq!(segments_in(&mine), 3, "Save first wrote the restored work to its own file");
    assert_eq!(h.state().project().options.timeline.segments.len(), 2, "then a new project");

    // A never-saved project, the path of an existing project typed, Open, Save first.
    h.state_mut().add_segment();
    h.state_mut().add_segment();
    h.run_ok();
    let before = std::fs::read(&mine).unwrap();
    h.state_mut().fields_mut().project_path = mine.display().to_string();
    h.get_by_label("Open").click_accesskit();
    h.run_ok();
    assert!(shows(&h, "Unsaved changes"), "Open asks");
    h.get_by_label("Save first").click();
    h.run_ok();
    assert_eq!(std::fs::read(&mine).unwrap(), before, "the file being opened is not written");
    let field = h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Path");
    assert_eq!(field.value().as_deref(), Some(dir.join("untitled.glocal.json").display().to_string().as_str()), "a save-as dialog, not on the file being opened");
    // Choosing the file being opened is refused: nothing written, nothing opened.
    answer_path_dialog(&mut h, &mine.display().to_string());
    assert_eq!(std::fs::read(&mine).unwrap(), before, "the file being opened is still not written");
    assert!(has_error(h.state(), "is the project being opened"), "{:?}", h.state().messages().all());
    assert_eq!(h.state().project().options.timeline.segments.len(), 4, "the work is still there");
    assert!(h.state().has_unsaved_work());
    // Again, saved elsewhere: then the project opens.
    h.get_by_label("Open").click_accesskit();
    h.run_ok();
    h.get_by_label("Save first").click();
    h.run_ok();
    let new = dir.join("new.glocal.json");
    answer_path_dialog(&mut h, &new.display().to_string());
    assert_eq!(segments_in(&new), 4, "the new project was saved where asked");
    assert_eq!(std::fs::read(&mine).unwrap(), before, "the opened file is as it was");
    assert_eq!(h.state().project().options.timeline.segments.len(), 3, "and it opened");
    assert!(has_message(h.state(), &format!("Opened {}", mine.display())));
    assert!(!h.state().has_unsaved_work());
    wait(&mut h, "the autosave of the opened project", |_| glocal::studio::project::Project::load(&autosave).is_ok_and(|p| p.options.timeline.segments.len() == 3));
    drop(h);

    // Restarted on work its project file holds: saved.
    let mut h = harness_with(storage, egui::vec2(1280.0, 800.0));
    wait_take(&mut h);
    assert_eq!(h.state().project_path(), Some(mine.as_path()));
    assert!(!h.state().has_unsaved_work(), "restored work its project file holds is saved");
    model_round_trip(&mut h);
}

/// The timeline's classes.
fn classes(app: &StudioApp) -> Vec<String> {
    app.project().options.timeline.segments.iter().map(|s| s.class.clone()).collect()
}

/// Waits until `dataset`'s model is loaded and the document's take generated on it.
fn wait_on(h: &mut Harness<'_, StudioApp>, dataset: &str) {
    wait(h, &format!("{dataset}'s take"), |a| {
        a.model_info().is_some_and(|m| m.spec.dataset == dataset) && a.take().is_some_and(|t| t.model_dir.ends_with(dataset)) && !a.is_busy() && a.stale_reason().is_none()
    });
}

/// The joints of each key made from a take's frame.
fn pose_keys(app: &StudioApp) -> Vec<usize> {
    app.project().options.keys.iter().filter_map(|k| match &k.source {
        KeySource::Pose(p) => Some(p.len()),
        KeySource::Init(_) => None,
    }).collect()
}

/// Item 3: h36m -> Bandai -> h36m with a key from a take's frame on each model.
fn model_round_trip(h: &mut Harness<'_, StudioApp>) {
    let mine = ["posing", "directions", "sitting"];
    for (k, class) in mine.iter().enumerate() {
        h.state_mut().set_segment_class(k, class);
    }
    h.get_by_label("Timeline ruler").click();
    h.run_ok();
    h.state_mut().add_key_from_frame();
    wait(h, "the keyed h36m take", |a| a.take().is_some_and(|t| t.options.keys.len() == 1) && !a.is_busy() && a.stale_reason().is_none());
    let on_h36m = h.state().project().document.clone();
    let h36m_joints = h.state().model_info().unwrap().spec.layout.skeleton.len();

    h.get_by_label("bandai").click_accesskit();
    wait_on(h, "bandai");
    let bandai_joints = h.state().model_info().unwrap().spec.layout.skeleton.len();
    assert_eq!(classes(h.state()), ["bow", "guide", "guide"]);
    assert_eq!(pose_keys(h.state()), [bandai_joints], "the h36m key is retargeted onto Bandai's skeleton");
    assert_eq!(h.state().messages().errors().count(), 0, "{:?}", h.state().messages().all());

    // Ctrl+Z undoes the switch, model included; Ctrl+Shift+Z makes it again.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    wait_on(h, "h36m");
    assert_eq!(h.state().project().document, on_h36m, "the undo brings the h36m project back as it was");
    h.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    wait_on(h, "bandai");
    assert_eq!(classes(h.state()), ["bow", "guide", "guide"]);

    // A key made on Bandai, then back to h36m.
    h.key_press(Key::End);
    h.run_ok();
    h.state_mut().add_key_from_frame();
    wait(h, "the keyed Bandai take", |a| a.take().is_some_and(|t| t.options.keys.len() == 2) && !a.is_busy() && a.stale_reason().is_none());
    h.get_by_label("h36m").click_accesskit();
    wait_on(h, "h36m");
    let app = h.state();
    assert_eq!(classes(app), mine, "the classes come back, not the classes of the classes");
    assert_eq!(app.project().options.keys[0], on_h36m.options.keys[0], "the h36m key comes back as it was");
    assert_eq!(pose_keys(app), [h36m_joints, h36m_joints], "the Bandai key is retargeted onto h36m's skeleton");
    assert_eq!(app.take().unwrap().options.keys.len(), 2, "the take has both keys");
    assert_eq!(app.messages().errors().count(), 0, "no 'the pose has 21 joints' or any other error: {:?}", app.messages().all());
}

/// The take the studio makes is the take its command line makes, exactly: File > Copy as
/// command line, run as a user runs it, writes the same file as the studio's own export. The
/// take's settings are off their defaults where the command line has a flag (a class start's
/// variant, a seed key, a segment's own pace and transition, guidance, the walk's course
/// left to the network, snaps left unspread, variation).
#[test]
fn the_command_line_the_studio_copies_makes_the_same_take() {
    let _g = serial();
    let dir = temp_dir("command-line");
    let mut h = harness("command-line");
    wait_take(&mut h);
    h.state_mut().edit(|d| {
        let o = &mut d.options;
        o.timeline = "walking:4,sitting:3@1.5~1,eating:3".parse().unwrap();
        o.pace = 1.2;
        o.class_strength = Some(2.0);
        o.hold_course = false;
        o.spread_snaps = false;
        o.init = InitPose::SeedClass { class: "sitting".into(), variant: 3 };
        o.keys = vec![TakeKey { seconds: 5.0, source: KeySource::Init(InitPose::SeedClass { class: "walking".into(), variant: 0 }), fix_root: false }];
        *o = o.clone().varied(5);
    });
    wait(&mut h, "the edited take", |a| a.take().is_some_and(|t| t.options.seed == 5) && a.stale_reason().is_none() && !a.is_busy());
    let studio = dir.join("studio.json");
    h.state_mut().export_to(studio.clone());
    wait(&mut h, "the studio's export", |_| studio.exists());

    let cli = dir.join("cli.json");
    h.state_mut().fields_mut().export_path = cli.display().to_string();
    h.get_all_by_label("File").next().unwrap().click();
    h.run_ok();
    h.get_by_label("Copy as command line").click();
    h.run_ok();
    let copied = h.state().messages().log().iter().find_map(|m| m.text.strip_prefix("Copied: ")).expect("the command line is shown").to_string();
    eprintln!("{copied}");
    assert!(copied.starts_with("glocal generate --model models/h36m --timeline walking:4,sitting:3@1.5~1,eating:3 --pace 1.2 --init seed:"), "{copied}");
    let args = h.state().command_args().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_glocal")).args(&args).output().unwrap();
    assert!(out.status.success(), "{copied}: {}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(&cli).unwrap() == std::fs::read(&studio).unwrap(), "the command line's take differs from the studio's: {copied}");
}

/// The take written on a rig from the studio (Export take > On a rig) is the command line's
/// `--retarget-to` take, byte for byte, on the rig's joints; started from that rig's own
/// file, it shows the file's own poses over its start (`synth::own_start`: through the
/// model's joints and back this mannequin's joints came back up to 135 degrees off).
#[test]
fn the_studio_writes_a_take_on_a_rig_as_the_command_line_does() {
    let _g = serial();
    let dir = temp_dir("rig-export");
    let storage = options("rig-export");
    let mut h = harness_with(storage.clone(), egui::vec2(1280.0, 800.0));
    wait_take(&mut h);
    let rig = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/assets/blender-unreal-salsa.bvh");
    h.state_mut().use_init_file(rig.clone(), 60);
    wait(&mut h, "the take from the rig's file", |a| a.take().is_some_and(|t| matches!(t.options.init, InitPose::File { .. })) && a.stale_reason().is_none() && !a.is_busy());
    // Typed into the export section's field, as a user does.
    let field = "On a rig (optional): a BVH whose skeleton the take is written on";
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, field).focus();
    h.run_ok();
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, field).type_text(&rig.display().to_string());
    h.run_ok();
    assert_eq!(h.state_mut().fields_mut().export_rig, rig.display().to_string());
    let studio = dir.join("studio.bvh");
    h.state_mut().export_to(studio.clone());
    wait(&mut h, "the export on the rig", |_| studio.exists());
    let read = |path: &std::path::Path| glocal::data::bvh::read_bvh(&std::fs::read_to_string(path).unwrap(), "a bvh").unwrap();
    let (written, file) = (read(&studio), read(&rig));
    assert_eq!(written.skeleton.names(), file.skeleton.names(), "the rig's joints");
    // The start: the file's poses from a sparse step after frame 60 (the file at 60 fps, the take at 25).
    let (ours, theirs) = (written.local_poses.as_ref().unwrap(), file.resample(25.0).local_poses.unwrap());
    let first = 25 + 5;
    let worst = (0..40).flat_map(|k| (1..written.joints()).map(move |j| (k, j))).map(|(k, j)| 2.0 * (ours[k].rotations[j] * theirs[first + k].rotations[j].inverse()).xyz().length().min(1.0).asin().to_degrees()).fold(0.0f32, f32::max);
    assert!(worst < 0.01, "the start is {worst} degrees off the rig's own poses");

    let cli = dir.join("cli.bvh");
    h.state_mut().fields_mut().export_path = cli.display().to_string();
    let args = h.state().command_args().unwrap();
    assert!(args.windows(2).any(|w| w[0] == "--retarget-to" && w[1] == rig.display().to_string()), "{args:?}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_glocal")).args(&args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(&cli).unwrap() == std::fs::read(&studio).unwrap(), "the command line's take on the rig differs from the studio's: {args:?}");
    // The studio opened again remembers the rig, as it remembers the export file.
    drop(h);
    let mut h = harness_with(storage, egui::vec2(1280.0, 800.0));
    assert_eq!(h.state_mut().fields_mut().export_rig, rig.display().to_string());
}

/// A one-frame pose's height, lowest joint to highest, in metres.
fn height(pose: &glocal::motion::Motion) -> f32 {
    let ys = pose.frame(0).iter().map(|p| p.y);
    let (low, high) = ys.fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), y| (l.min(y), h.max(y)));
    (high - low) * pose.skeleton.meters_per_unit()
}

/// The retarget preview (item 5): the file's skeleton as tall as the model's pose beside it,
/// both framed in the view, and its Use and Cancel buttons clear of an error's toast.
#[test]
fn the_retarget_preview_is_readable_and_its_buttons_uncovered() {
    let _g = serial();
    let mut h = harness("retarget-preview");
    wait(&mut h, "the model, the map and a take", |a| a.model_info().is_some() && a.seed_map().is_some() && a.take().is_some_and(|t| !t.path.is_empty()) && !a.is_busy());
    h.state_mut().set_init_tab(InitTab::File);
    h.state_mut().fields_mut().init_path = "tests/assets/blender-unreal-salsa.bvh".into();
    h.state_mut().fields_mut().project_path = "project.glocal.json".into();
    h.run_ok();
    h.get_by_label("Use file").click();
    wait(&mut h, "the retarget preview", |a| a.retarget_preview().is_some());
    h.state_mut().export_to("take.xyz".into());
    h.run_ok();
    let preview = h.state().retarget_preview().unwrap();
    let (file, model) = (height(&preview.source), height(&preview.retargeted));
    assert!((file / model - 1.0).abs() < 0.02, "the file's skeleton is {file:.2} m tall, the model's pose {model:.2} m");
    let toast = h.get_by_label_contains("Could not export").rect().expand(8.0);
    for button in ["Use", "Cancel"] {
        let r = h.get_by_label(button).rect();
        assert!(!r.intersects(toast), "the error's toast {toast:?} covers {button} {r:?}");
    }
    // The notice naming the file by its absolute path, dismissed: the snapshot holds on any
    // checkout.
    let notice = h.get_by_label_contains("retargeted onto the model").rect();
    let dismiss = h.get_all_by_label("x").find(|x| (notice.top()..notice.bottom()).contains(&x.rect().center().y)).expect("the notice's dismiss button");
    dismiss.click();
    h.run_ok();
    assert!(h.query_by_label_contains("retargeted onto the model").is_none());
    h.snapshot("retarget_preview");
}
