//! Posing by hand (issue 36): the pose rig on real takes of both shipped models, and the
//! whole studio in egui_kittest (the wgpu renderer, the real worker, models/h36m): a hand
//! dragged in the viewport, the key it makes, the take made through it, the command line's
//! take of the saved project, and undo.

#[path = "support/studio.rs"]
mod support;

use std::path::Path;
use std::sync::Arc;

use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use glam::{Quat, Vec3};
use glocal::model::glocal::GlocalModel;
use glocal::motion::{facing, solve_local_poses, Effector, JointRoles, Motion, PoseRig, Side, Skeleton};
use glocal::studio::viewport::Viewport;
use glocal::studio::StudioApp;
use glocal::synth::constraints::KeySource;
use glocal::synth::{generate, GenerateOptions};
use support::{harness, temp_dir, wait};

fn model(name: &str) -> GlocalModel {
    GlocalModel::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models").join(name)).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

/// Largest distance between two poses' joints.
fn worst(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max)
}

/// Where a test drags each effector's joint (`cm`: a centimetre in the take's units): a hand
/// a third of the way to its shoulder and 6 cm aside, the head a sixth of the way to the
/// spine's base and 6 cm aside (places the arm and spine reach), a foot along the floor (as
/// the viewport moves it; further than a straight leg reaches, so the hips follow), the hips
/// down (a crouch).
fn drag_target(skeleton: &Skeleton, roles: &JointRoles, frame: &[Vec3], effector: Effector, cm: f32) -> Vec3 {
    let towards = |at: Vec3, base: Vec3, share: f32| at + (base - at) * share + (base - at).cross(Vec3::Y).normalize() * 6.0 * cm;
    let parent = |j: usize| skeleton.parents()[j].unwrap();
    match effector {
        Effector::Hand(side) => {
            let hand = if side == Side::Left { roles.left_hand } else { roles.right_hand };
            towards(frame[hand], frame[parent(parent(hand))], 1.0 / 3.0)
        }
        Effector::Head => towards(frame[roles.head], frame[skeleton.child_towards(roles.body_root, roles.head).unwrap()], 1.0 / 6.0),
        Effector::Foot(side) => frame[roles.leg(side).ankle] + Vec3::new(8.0, 0.0, 10.0) * cm,
        Effector::Hips => frame[roles.body_root] + Vec3::new(3.0, -12.0, 0.0) * cm,
    }
}

/// Every handle on a frame of a real take of each model: the joint reaches its target, every
/// bone keeps its length, what the drag should leave stays, and the pose's rotations solve
/// back to it (a key of it is reached as made).
#[test]
fn each_handle_poses_real_frames_of_both_models() {
    for (name, class) in [("h36m", "walking"), ("bandai", "walk")] {
        let m = model(name);
        let opts = GenerateOptions { timeline: format!("{class}:4").parse().unwrap(), ..Default::default() };
        let take = generate(&m, &opts, &mut |_| true).unwrap().motion;
        let skeleton = &take.skeleton;
        let (rig, roles) = (PoseRig::new(skeleton).unwrap(), JointRoles::new(skeleton).unwrap());
        let mm = 0.001 / skeleton.meters_per_unit();
        let frame = take.frame(take.frames() / 2);
        let bones = |p: &[Vec3]| -> Vec<f32> { (0..p.len()).map(|j| skeleton.parents()[j].map_or(0.0, |q| p[j].distance(p[q]))).collect() };
        // Every handle, and a left foot dragged 40 cm further out than its leg reaches (the
        // stance widens: the hips follow).
        let out = frame[roles.left.ankle] - frame[roles.right.ankle];
        let wide = frame[roles.left.ankle] + Vec3::new(out.x, 0.0, out.z).normalize() * 400.0 * mm;
        let cases = Effector::ALL.map(|e| (e, drag_target(skeleton, &roles, frame, e, 10.0 * mm))).into_iter().chain([(Effector::Foot(Side::Left), wide)]);
        for (effector, target) in cases {
            let joint = rig.joint(effector);
            let posed = rig.posed(skeleton, frame, effector, target);
            let miss = posed[joint].distance(target) / mm;
            let stretch = bones(&posed).iter().zip(bones(frame)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max) / mm;
            let solved = Motion::from_local_poses(skeleton.clone(), take.fps, solve_local_poses(skeleton, &posed));
            let round_trip = worst(solved.frame(0), &posed) / mm;
            // What each drag leaves where it was.
            let kept: Vec<usize> = match effector {
                Effector::Hand(side) => vec![other_hand(&roles, side), roles.left.ankle, roles.right.ankle],
                Effector::Foot(side) => roles.leg(other(side)).foot_joints(skeleton),
                Effector::Head | Effector::Hips => roles.left.foot_joints(skeleton).into_iter().chain(roles.right.foot_joints(skeleton)).collect(),
            };
            let moved = kept.iter().map(|&j| posed[j].distance(frame[j])).fold(0.0, f32::max) / mm;
            let hips = posed[roles.body_root].distance(frame[roles.body_root]) / mm;
            println!("{name} {effector:?}: {miss:.3} mm from the target (the hips moved {hips:.1} mm), bones within {stretch:.4} mm, kept joints within {moved:.4} mm, rotations solve back within {round_trip:.4} mm");
            assert!(miss < 0.1, "{name} {effector:?}: {miss:.3} mm from its target");
            assert!(stretch < 0.01, "{name} {effector:?}: a bone changed by {stretch} mm");
            assert!(moved < 0.01, "{name} {effector:?}: a joint it should leave moved {moved} mm");
            assert!(round_trip < 0.1, "{name} {effector:?}: the solved pose is {round_trip} mm off");
            if target == wide {
                assert!(hips > 10.0, "{name}: a foot beyond its leg's reach brings the hips along (they moved {hips} mm)");
            }
        }
    }
}

fn other(side: Side) -> Side {
    match side {
        Side::Left => Side::Right,
        Side::Right => Side::Left,
    }
}

fn other_hand(roles: &JointRoles, side: Side) -> usize {
    match side {
        Side::Left => roles.right_hand,
        Side::Right => roles.left_hand,
    }
}

// ---- the studio ----

/// Waits for the take the document asks for (keys or none) to be on screen, up to date.
fn wait_take(h: &mut Harness<'_, StudioApp>, keys: usize) -> Arc<Motion> {
    wait(h, &format!("a take with {keys} keys"), |a| a.take().is_some_and(|t| t.options.keys.len() == keys) && a.stale_reason().is_none() && !a.is_busy());
    h.state().take().unwrap().motion.clone()
}

fn pointer(h: &mut Harness<'_, StudioApp>, pos: egui::Pos2, pressed: Option<bool>) {
    h.event(egui::Event::PointerMoved(pos));
    if let Some(pressed) = pressed {
        h.event(egui::Event::PointerButton { pos, button: egui::PointerButton::Primary, pressed, modifiers: Modifiers::default() });
    }
    h.run_ok();
}

/// The point of the plane through `through` facing `normal` that shows at `screen`, found
/// from the viewport's forward projection alone (Newton's method on the plane's two axes).
fn plane_point_at(viewport: &Viewport, screen: egui::Pos2, through: Vec3, normal: Vec3) -> Vec3 {
    let u = Vec3::Y.cross(normal).normalize();
    let v = normal.cross(u);
    let (mut a, mut b) = (0.0f32, 0.0f32);
    let at = |a: f32, b: f32| viewport.project(through + u * a + v * b).unwrap();
    for _ in 0..20 {
        let (p, step) = (at(a, b), 1e-3);
        let (du, dv) = ((at(a + step, b) - p) / step, (at(a, b + step) - p) / step);
        let miss = screen - p;
        let det = du.x * dv.y - du.y * dv.x;
        a += (miss.x * dv.y - miss.y * dv.x) / det;
        b += (du.x * miss.y - du.y * miss.x) / det;
    }
    through + u * a + v * b
}

/// A pose relative to its root, turned so it faces +z (how a key holds the body's pose).
fn body_pose(pose: &[Vec3], roles: &JointRoles) -> Vec<Vec3> {
    let turn = Quat::from_rotation_y(-facing(pose, roles.left.hip, roles.right.hip));
    pose.iter().map(|p| turn * (*p - pose[roles.body_root])).collect()
}

/// The workflow of issue 36: with a frame on screen, turn on "Pose by hand", drag the left
/// hand's handle; the hand follows the pointer on the view's plane, the release keys the
/// pose at that frame (on the keys track, in the saved project), the take is made again
/// through it, `glocal generate --project` makes the same take, and Ctrl+Z brings back the
/// take before.
#[test]
fn dragging_a_hand_keys_the_pose_and_the_take_passes_through_it() {
    let dir = temp_dir("posing-hand");
    let mut h = harness("posing-hand");
    let before = wait_take(&mut h, 0);
    let skeleton = before.skeleton.clone();
    let unit = skeleton.meters_per_unit();
    let roles = JointRoles::new(&skeleton).unwrap();
    let hand = roles.left_hand;

    // A frame on screen: about 5 s into the take, by a click on the ruler.
    let ruler = h.get_by_label("Timeline ruler").rect();
    let at = egui::pos2(ruler.left() + 5.0 / before.seconds() * (ruler.width() - 8.0), ruler.center().y);
    pointer(&mut h, at, Some(true));
    pointer(&mut h, at, Some(false));
    let frame = h.state().frame();
    assert!((frame as f32 / before.fps - 5.0).abs() < 0.2, "the ruler click seeks to 5 s: frame {frame}");
    h.get_by_label("Pose by hand").click_accesskit();
    h.run_ok();

    // The hand is dragged 15 cm up the view's plane (a hanging hand reaches it) and 5 cm aside.
    let start = before.frame(frame)[hand] * unit;
    let towards_camera = h.state().viewport().towards_camera();
    let aside = Vec3::Y.cross(towards_camera).normalize();
    let up = towards_camera.cross(aside);
    let on_screen = h.state().viewport().project(start).expect("the hand is in view");
    let to = h.state().viewport().project(start + up * 0.15 + aside * 0.05).unwrap();
    let shown_before = h.render().unwrap();
    pointer(&mut h, on_screen, None);
    pointer(&mut h, on_screen, Some(true));
    for k in 1..=10 {
        pointer(&mut h, on_screen + (to - on_screen) * (k as f32 / 10.0), None);
    }
    // While dragging the viewport shows the edited pose, and nothing is keyed yet.
    assert!(h.state().project().options.keys.is_empty());
    let shown_dragging = h.render().unwrap();
    let changed = changed_pixels_near(&shown_before, &shown_dragging, to);
    assert!(changed > 40, "the viewport does not show the hand at the pointer ({changed} pixels changed there)");
    pointer(&mut h, to, Some(false));
    assert!(h.state().viewport().project(start).unwrap().distance(on_screen) < 1e-3, "the drag moved the camera");

    // The key: at the frame, the body's pose only, on the keys track.
    let keys = h.state().project().options.keys.clone();
    assert_eq!(keys.len(), 1, "one key in the project");
    assert!((keys[0].seconds - frame as f32 / before.fps).abs() < 1e-5 && !keys[0].fix_root, "{:?}", (keys[0].seconds, keys[0].fix_root));
    let KeySource::Pose(pose) = &keys[0].source else { panic!("a posed key holds its pose") };
    let pose: Vec<Vec3> = pose.iter().map(|p| Vec3::from(*p)).collect();
    assert!(h.query_by_label("Key 1").is_some(), "the key is on its track");
    let target = plane_point_at(h.state().viewport(), to, start, h.state().viewport().towards_camera());
    let reached = (pose[hand] * unit).distance(target);
    println!("the hand moved {:.1} cm and is {:.3} mm from the pointer's view-plane target", start.distance(target) * 100.0, reached * 1000.0);
    assert!(start.distance(target) > 0.1, "the drag moves the hand more than 10 cm");
    assert!(reached < 0.01, "the hand is {:.2} cm from the pointer's target", reached * 100.0);

    // The take made through the key.
    let keyed = wait_take(&mut h, 1);
    let (made, wanted) = (body_pose(keyed.frame(frame), &roles), body_pose(&pose, &roles));
    let hand_off = made[hand].distance(wanted[hand]) * unit;
    let body_off = worst(&made, &wanted) * unit;
    println!("the keyed take at the key's frame, relative to the root: the hand {:.3} mm from the key, the worst joint {:.3} mm", hand_off * 1000.0, body_off * 1000.0);
    assert!(hand_off < 0.02 && body_off < 0.02, "the take passes {:.2} cm (hand) and {:.2} cm (worst joint) from the key", hand_off * 100.0, body_off * 100.0);
    assert!(h.state().messages().log().iter().all(|m| !m.text.contains("failed")), "{:?}", h.state().messages().log());

    // The command line makes the same take from the saved project.
    let (project, from_cli, from_studio) = (dir.join("posed.glocal.json"), dir.join("cli.npy"), dir.join("studio.npy"));
    assert!(h.state_mut().save_project(&project));
    let saved = glocal::studio::project::Project::load(&project).unwrap();
    assert_eq!(saved.options.keys, keys, "the key is saved in the project");
    h.state_mut().fields_mut().export_path = from_studio.display().to_string();
    h.get_by_label("Export").click_accesskit();
    wait(&mut h, "the export", |_| from_studio.exists());
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_glocal"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["generate", "--project", project.to_str().unwrap(), "--out", from_cli.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(&from_cli).unwrap() == std::fs::read(&from_studio).unwrap(), "glocal generate --project makes another take than the studio's");

    // Undo: no key, and the take before, to the bit.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.run_ok();
    assert!(h.state().project().options.keys.is_empty(), "Ctrl+Z takes the key away");
    let undone = wait_take(&mut h, 0);
    assert_eq!(undone.positions(), before.positions(), "the take after undo is the take before");
}

/// Pixels that differ between two renders within 12 points of `at` (the window renders at one
/// pixel a point).
fn changed_pixels_near(a: &image::RgbaImage, b: &image::RgbaImage, at: egui::Pos2) -> usize {
    let (x0, y0) = ((at.x - 12.0).max(0.0) as u32, (at.y - 12.0).max(0.0) as u32);
    let mut n = 0;
    for y in y0..(y0 + 24).min(a.height()) {
        for x in x0..(x0 + 24).min(a.width()) {
            let (p, q) = (a.get_pixel(x, y).0, b.get_pixel(x, y).0);
            n += usize::from(p.iter().zip(q).any(|(u, v)| u.abs_diff(v) > 24));
        }
    }
    n
}

/// Pose mode does not take the camera away: a drag that starts off the handles orbits and
/// keys nothing; a drag of the hips handle keys a root-fixing pose with the feet where they
/// were.
#[test]
fn off_the_handles_the_view_orbits_and_the_hips_make_a_root_key() {
    let mut h = harness("posing-hips");
    let take = wait_take(&mut h, 0);
    let (unit, roles) = (take.skeleton.meters_per_unit(), JointRoles::new(&take.skeleton).unwrap());
    let frame = take.frames() / 2;
    let ruler = h.get_by_label("Timeline ruler").rect();
    let at = egui::pos2(ruler.left() + frame as f32 / take.frames() as f32 * (ruler.width() - 8.0), ruler.center().y);
    pointer(&mut h, at, Some(true));
    pointer(&mut h, at, Some(false));
    let frame = h.state().frame();
    h.get_by_label("Pose by hand").click_accesskit();
    h.run_ok();
    let hips = take.frame(frame)[roles.body_root] * unit;
    let drag = |h: &mut Harness<'_, StudioApp>, from: egui::Pos2, by: egui::Vec2| {
        pointer(h, from, None);
        pointer(h, from, Some(true));
        for k in 1..=5 {
            pointer(h, from + by * (k as f32 / 5.0), None);
        }
        pointer(h, from + by, Some(false));
    };

    // The hips stand on the orbit's axis when the view follows them: the hand shows the turn.
    let hand = take.frame(frame)[roles.left_hand] * unit;
    let before = h.state().viewport().project(hand).unwrap();
    let beside = h.state().viewport().project(hips).unwrap() + egui::vec2(250.0, 0.0);
    drag(&mut h, beside, egui::vec2(40.0, 0.0));
    let after = h.state().viewport().project(hand).unwrap();
    assert!(before.distance(after) > 5.0, "a drag off the handles orbits the view (the hand moved {} points on screen)", before.distance(after));
    assert!(h.state().project().options.keys.is_empty(), "and keys nothing");

    let handle = h.state().viewport().project(hips).unwrap();
    drag(&mut h, handle, egui::vec2(0.0, 30.0));
    let keys = h.state().project().options.keys.clone();
    assert_eq!(keys.len(), 1);
    assert!(keys[0].fix_root, "dragging the hips fixes where the body stands");
    let KeySource::Pose(pose) = &keys[0].source else { panic!("a posed key holds its pose") };
    let pose: Vec<Vec3> = pose.iter().map(|p| Vec3::from(*p)).collect();
    let feet: Vec<usize> = roles.left.foot_joints(&take.skeleton).into_iter().chain(roles.right.foot_joints(&take.skeleton)).collect();
    let feet_moved = feet.iter().map(|&j| pose[j].distance(take.frame(frame)[j])).fold(0.0, f32::max) * unit;
    let lowered = hips.y - pose[roles.body_root].y * unit;
    println!("the hips dragged {:.1} cm down, the feet within {:.4} mm of where they were", lowered * 100.0, feet_moved * 1000.0);
    assert!(lowered > 0.03 && feet_moved < 1e-4, "hips {:.1} cm lower, feet moved {:.3} mm", lowered * 100.0, feet_moved * 1000.0);

    // The take made through it stands in the keyed pose where the key stands.
    let keyed = wait_take(&mut h, 1);
    let off = worst(keyed.frame(frame), &pose) * unit;
    println!("the take through the root key: worst joint {:.2} mm from the key, in the world", off * 1000.0);
    assert!(off < 0.02, "the take passes {:.1} cm from the crouch it was given", off * 100.0);
}
