//! The 3D skeleton viewport: a wgpu paint callback inside egui.
//!
//! Bones are instanced 12-sided cylinders and joints instanced icospheres (one subdivision),
//! lit with lambert + hemisphere ambient, over a ground grid with the root's trajectory,
//! onion-skin ghosts, and several layers (side by side or overlaid). Everything is drawn in
//! metres: each take is scaled by its skeleton's `meters_per_unit`. A root path is drawn on
//! the floor with its waypoints; in path-edit mode a click on the ground adds a waypoint
//! (the pointer's ray met with the ground plane) and a drag moves one ([`PathEdit`]). In pose
//! mode, handles on the take's hands, feet, head and hips pose the frame on screen
//! (`viewport/posing.rs`). The camera and its pointer input are in `viewport/camera.rs`, the
//! root's trail on the floor in `viewport/trail.rs`.
//!
//! Rendering (see `viewport/render.rs`): egui's render pass has no depth buffer by default, so
//! the scene is drawn during the callback's `prepare` into an offscreen colour + depth image
//! the size of the view (4x MSAA on GPUs, none on software rasterisers), and `paint` copies that image into egui's pass.

mod camera;
mod mesh;
mod posing;
mod projection;
mod render;
mod solids;
mod trail;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use eframe::egui_wgpu::{self, wgpu};
use glam::Vec3;

use crate::motion::contacts::FootContacts;
use crate::motion::{JointRoles, Motion, PoseRig, Side};
use camera::{Camera, START_CAMERA};
use posing::Posing;
pub use posing::PosedFrame;
use render::{Globals, Resources, SceneCallback, TrailVertex};
use solids::{cylinder, floor_disc, linear_rgba, sphere, Solids};
use trail::TrailCache;
pub use render::HostPass;

/// One take drawn in the viewport.
#[derive(Clone)]
pub struct Layer {
    pub motion: Arc<Motion>,
    /// RGB colour of each frame (e.g. its segment's class colour), `motion.frames()` long.
    pub frame_colors: Arc<Vec<[u8; 3]>>,
    /// Shift in world units, for side-by-side comparison (zero for overlay). The viewport's
    /// world is in metres (every take is scaled by its `meters_per_unit`), so this is metres,
    /// whatever the take's own unit; e.g. `Vec3::new(1.0, 0.0, 0.0)` puts a take 1 m to the right.
    pub offset: glam::Vec3,
    /// 0..1; a second overlaid take is drawn translucent.
    pub opacity: f32,
    /// Each foot's contacts, marked under the planted feet of the current pose.
    pub contacts: Option<Arc<FootContacts>>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ViewSettings {
    /// Onion-skin ghosts drawn before and after the current frame.
    pub ghosts: usize,
    /// Frames between ghosts.
    pub ghost_step: usize,
    pub trail: bool,
    pub follow_root: bool,
    pub grid: bool,
}

impl Default for ViewSettings {
    fn default() -> Self {
        Self { ghosts: 3, ghost_step: 5, trail: true, follow_root: true, grid: true }
    }
}

/// What to draw this frame.
pub struct Scene<'a> {
    pub layers: &'a [Layer],
    /// The frame shown; clamped to each layer's last frame.
    pub frame: usize,
    pub settings: &'a ViewSettings,
    pub path: Option<PathOverlay<'a>>,
}

/// A root path on the ground: waypoints (x, z) in metres, in the viewport's world.
#[derive(Clone, Copy, Debug)]
pub struct PathOverlay<'a> {
    pub waypoints: &'a [[f32; 2]],
    pub selected: Option<usize>,
    /// Clicks on the ground add waypoints and drags move them (instead of orbiting).
    pub editing: bool,
}

/// What the user did to the path in path-edit mode (collect with [`Viewport::take_path_edits`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathEdit {
    /// A drag that moves a waypoint starts (for undo: one step per drag).
    BeginDrag,
    Add([f32; 2]),
    Move { index: usize, to: [f32; 2] },
}

/// Path colour (sRGB) on the floor and its waypoints.
const PATH_RGB: [u8; 3] = [80, 220, 200];
/// Waypoint discs: radius and thickness, metres.
const WAYPOINT_RADIUS: f32 = 0.08;
/// Planted feet (sRGB; the timeline's feet track too) and the radius of their mark on the
/// floor, metres.
pub const CONTACT_RGB: [u8; 3] = [255, 150, 60];
const CONTACT_RADIUS: f32 = 0.06;
/// A press within this many points of a waypoint or a pose handle grabs it.
const GRAB_POINTS: f32 = 14.0;

const BONE_RADIUS: f32 = 0.022;
const JOINT_RADIUS: f32 = 0.03;
const HEAD_RADIUS: f32 = 0.1;
/// Bones shorter than this (metres, in the rest pose) are not drawn, nor their end joint.
const MIN_BONE: f32 = 0.005;
/// Fewest frames of the trail highlighted before the current one.
const MIN_HIGHLIGHT: usize = 30;
/// Most ghosts drawn on each side of the current frame.
const MAX_GHOSTS: usize = 32;
/// Background (sRGB).
const BACKGROUND: [u8; 3] = [30, 32, 38];

/// Camera state and interaction (orbit: drag, pan: right/middle drag or shift+drag, zoom:
/// scroll, frame the take: double-click). Create once with [`Viewport::new`]; call
/// [`Viewport::register`] once with the wgpu render state (eframe's `cc.wgpu_render_state`,
/// or egui_kittest's) to install the pipeline in the renderer's callback resources; then
/// [`Viewport::ui`] every frame.
pub struct Viewport {
    id: egui::Id,
    camera: Camera,
    /// Frame the scene on the next `ui` (set at start, by double-click, by `frame_all`).
    reframe: bool,
    was_following: Option<bool>,
    layers: Vec<LayerInfo>,
    trail: Option<TrailCache>,
    /// The waypoint being dragged in path-edit mode.
    path_drag: Option<usize>,
    path_edits: Vec<PathEdit>,
    posing: Posing,
    /// The last frame's view rectangle and orbit centre (for [`Viewport::project`]).
    last_view: Option<(egui::Rect, Vec3)>,
}

impl Default for Viewport {
    fn default() -> Self {
        Self::new()
    }
}

/// What the viewport derives once per take (recomputed when a layer's motion changes).
struct LayerInfo {
    motion: Arc<Motion>,
    /// Lowest point of the take, metres.
    ground: f32,
    /// Mean height of the joints' centroid above `ground`, metres.
    centre_height: f32,
    /// Bounds of the whole take, metres, without the layer's offset.
    min: Vec3,
    max: Vec3,
    /// The joint whose ground projection is the take's trajectory.
    root: usize,
    /// Joints drawn as spheres.
    joints: Vec<usize>,
    /// (parent, child) pairs drawn as bones.
    bones: Vec<(usize, usize)>,
    /// The head joint and, if it has one, its child towards the top of the head.
    head: Option<(usize, usize, Option<usize>)>,
    /// Each foot's joints (left, right), where the skeleton's legs are known.
    feet: [Vec<usize>; 2],
    /// What posing by hand moves, on a humanoid skeleton.
    rig: Option<PoseRig>,
}

impl LayerInfo {
    fn new(motion: &Arc<Motion>) -> Self {
        let skeleton = &motion.skeleton;
        let mpu = skeleton.meters_per_unit();
        let n = motion.joints();
        let frames = motion.frames();
        let ground = motion.floor_height() * mpu;
        let roles = JointRoles::new(skeleton).ok();
        let first_root = skeleton.parents().iter().position(Option::is_none).unwrap_or(0);
        // Joints above the body root (e.g. Bandai's `joint_Root`, fixed at the origin while
        // the hips carry the motion) are not part of the body: hide them and their bones, and
        // take the trajectory from the body root.
        let root = roles.as_ref().map_or(first_root, |r| r.body_root);
        let above_root: Vec<usize> = std::iter::successors(skeleton.parents()[root], |&p| skeleton.parents()[p]).collect();
        let long = |j: usize| skeleton.offsets().get(j).is_some_and(|o| o.length() * mpu >= MIN_BONE);
        let hidden = |j: usize| above_root.contains(&j);
        let mut joints = Vec::new();
        let mut bones = Vec::new();
        for j in 0..n {
            match skeleton.parents()[j] {
                None => {
                    if !hidden(j) {
                        joints.push(j);
                    }
                }
                Some(p) => {
                    if !hidden(j) && long(j) {
                        joints.push(j);
                        if !hidden(p) {
                            bones.push((p, j));
                        }
                    }
                }
            }
        }
        let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut centre_sum = 0.0f64;
        for t in 0..frames {
            let frame = motion.frame(t);
            let mut sum = 0.0;
            for &j in &joints {
                let p = frame[j] * mpu;
                min = min.min(p);
                max = max.max(p);
                sum += p.y;
            }
            centre_sum += (sum / joints.len().max(1) as f32 - ground) as f64;
        }
        if !min.is_finite() || !max.is_finite() {
            (min, max) = (Vec3::ZERO, Vec3::ZERO);
        }
        let centre_height = (centre_sum / frames.max(1) as f64) as f32;
        let head = roles.as_ref().and_then(|r| Some((r.head, skeleton.parents()[r.head]?, r.head_end.filter(|&c| long(c)))));
        let feet = Side::BOTH.map(|side| roles.as_ref().map_or_else(Vec::new, |r| r.leg(side).foot_joints(skeleton)));
        let rig = PoseRig::new(skeleton).ok();
        Self { motion: motion.clone(), ground, centre_height, min, max, root, joints, bones, head, feet, rig }
    }
}

impl Viewport {
    pub fn new() -> Self {
        static NEXT_ID: AtomicU64 = AtomicU64::new(0);
        Self {
            id: egui::Id::unique(("glocal_viewport", NEXT_ID.fetch_add(1, Ordering::Relaxed))),
            camera: START_CAMERA,
            reframe: true,
            was_following: None,
            layers: Vec::new(),
            trail: None,
            path_drag: None,
            path_edits: Vec::new(),
            posing: Posing::default(),
            last_view: None,
        }
    }

    /// The path edits made since the last call.
    pub fn take_path_edits(&mut self) -> Vec<PathEdit> {
        std::mem::take(&mut self.path_edits)
    }

    /// Installs the pipelines for an egui render pass with eframe's default setup (no MSAA,
    /// no depth buffer), which is also egui_kittest's.
    pub fn register(render_state: &egui_wgpu::RenderState) {
        Self::register_with(render_state, HostPass::default());
    }

    /// Installs the pipelines for an egui render pass set up as `host` says (if the app turns
    /// on eframe's `multisampling` or `depth_buffer`).
    pub fn register_with(render_state: &egui_wgpu::RenderState, host: HostPass) {
        let resources = Resources::new(&render_state.adapter, &render_state.device, &render_state.queue, render_state.target_format, host);
        render_state.renderer.write().callback_resources.insert(resources);
    }

    /// How many times the viewports drawn with `render_state` uploaded a take's geometry (the
    /// root trail, the one buffer as long as the take): once per take shown, not per frame;
    /// everything else uploaded per frame (ghosts, the current pose, the root path) has a
    /// size independent of the take's length.
    pub fn geometry_uploads(render_state: &egui_wgpu::RenderState) -> u64 {
        render_state.renderer.read().callback_resources.get::<Resources>().map_or(0, |r| r.geometry_uploads)
    }

    /// Frames the whole scene on the next [`Viewport::ui`] (like a double-click).
    pub fn frame_all(&mut self) {
        self.reframe = true;
    }

    /// Back to the starting view (angle and distance), framed on the take.
    pub fn reset_camera(&mut self) {
        self.camera = START_CAMERA;
        self.reframe = true;
    }

    /// Fills the available space with the 3D view.
    pub fn ui(&mut self, ui: &mut egui::Ui, scene: &Scene) -> egui::Response {
        let size = ui.available_size();
        let (rect, response) = ui.allocate_exact_size(size, egui::Sense::click_and_drag());
        self.update_layers(scene.layers);
        let settings = scene.settings;

        // Follow-root toggles keep the view where it is.
        let follow_point = self.follow_point(scene);
        match (self.was_following, settings.follow_root) {
            (Some(true), false) => self.camera.target = follow_point + self.camera.pan,
            (Some(false), true) => self.camera.pan = Vec3::ZERO,
            _ => {}
        }
        self.was_following = Some(settings.follow_root);

        let target = if settings.follow_root { follow_point + self.camera.pan } else { self.camera.target };
        let path_took_pointer = match scene.path.filter(|p| p.editing) {
            Some(path) => self.edit_path(ui, &response, rect, path, target),
            None => {
                self.path_drag = None;
                false
            }
        };
        let pose_took_pointer = !path_took_pointer && self.pose_input(ui, &response, rect, scene, target);
        if !path_took_pointer && !pose_took_pointer {
            self.handle_input(ui, &response, rect);
        }
        if response.double_clicked() && !scene.path.is_some_and(|p| p.editing) {
            self.reframe = true;
        }
        if self.reframe && !self.layers.is_empty() {
            self.frame_scene(scene, follow_point);
            self.reframe = false;
        }

        let target = if settings.follow_root { follow_point + self.camera.pan } else { self.camera.target };
        if !ui.is_rect_visible(rect) || rect.width() < 1.0 || rect.height() < 1.0 {
            return response;
        }
        let ppp = ui.ctx().pixels_per_point();
        let size_px = [(rect.width() * ppp).round().max(1.0) as u32, (rect.height() * ppp).round().max(1.0) as u32];
        let callback = self.build(scene, target, size_px, rect.aspect_ratio());
        ui.painter().add(egui_wgpu::Callback::new_paint_callback(rect, callback));
        self.paint_handles(ui, rect, scene, target);
        self.last_view = Some((rect, target));
        response
    }

    fn update_layers(&mut self, layers: &[Layer]) {
        let same = self.layers.len() == layers.len() && self.layers.iter().zip(layers).all(|(a, b)| Arc::ptr_eq(&a.motion, &b.motion));
        if !same {
            let mut old = std::mem::take(&mut self.layers);
            self.layers = layers
                .iter()
                .map(|l| match old.iter().position(|i| Arc::ptr_eq(&i.motion, &l.motion)) {
                    Some(k) => old.swap_remove(k),
                    None => LayerInfo::new(&l.motion),
                })
                .collect();
        }
    }

    fn ground(&self) -> f32 {
        let g = self.layers.iter().filter(|i| i.motion.frames() > 0).map(|i| i.ground).fold(f32::INFINITY, f32::min);
        if g.is_finite() {
            g
        } else {
            0.0
        }
    }

    /// Path-edit mode: a press on a waypoint drags it, a click elsewhere on the ground adds
    /// one. Returns whether the pointer was used (the camera then does not move).
    fn edit_path(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect, path: PathOverlay, target: Vec3) -> bool {
        let pointer = response.interact_pointer_pos();
        if response.drag_started_by(egui::PointerButton::Primary) && !ui.input(|i| i.modifiers.shift) {
            let origin = ui.input(|i| i.pointer.press_origin()).or(pointer);
            self.path_drag = origin.and_then(|o| {
                let near = |k: &usize| self.screen_point(path.waypoints[*k], rect, target).is_some_and(|p| p.distance(o) <= GRAB_POINTS);
                (0..path.waypoints.len()).rev().find(near)
            });
            if self.path_drag.is_some() {
                self.path_edits.push(PathEdit::BeginDrag);
            }
        }
        if let Some(index) = self.path_drag {
            if let Some(to) = pointer.and_then(|p| self.ground_point(p, rect, target)) {
                self.path_edits.push(PathEdit::Move { index, to });
            }
            if !response.dragged() {
                self.path_drag = None;
            }
            return true;
        }
        if response.clicked_by(egui::PointerButton::Primary) {
            if let Some(point) = pointer.and_then(|p| self.ground_point(p, rect, target)) {
                self.path_edits.push(PathEdit::Add(point));
                return true;
            }
        }
        false
    }

    /// The path on the floor: three parallel lines per stretch (a line list is one pixel
    /// wide), just above the grid.
    fn path_vertices(&self, path: &PathOverlay) -> Vec<TrailVertex> {
        let y = self.ground() + 0.006;
        let [r, g, b] = PATH_RGB;
        let vertex = |x: f32, z: f32| TrailVertex { position: [x, y, z], frame: 0.0, last_frame: -1.0, color: [r, g, b, 255] };
        let mut out = Vec::new();
        for w in path.waypoints.windows(2) {
            let (a, b) = (glam::Vec2::from(w[0]), glam::Vec2::from(w[1]));
            let side = (b - a).perp().normalize_or_zero() * 0.012;
            for k in [-1.0, 0.0, 1.0] {
                let (p, q) = (a + side * k, b + side * k);
                out.push(vertex(p.x, p.y));
                out.push(vertex(q.x, q.y));
            }
        }
        out
    }

    fn build(&mut self, scene: &Scene, target: Vec3, size_px: [u32; 2], aspect: f32) -> SceneCallback {
        let settings = scene.settings;
        let cam = self.camera;
        let back = cam.back();
        let (view_proj, eye) = self.view_proj(target, aspect);
        let right = Vec3::Y.cross(back).normalize_or_zero();
        let light = (back * 0.55 + Vec3::Y * 0.75 - right * 0.35).normalize();

        let ground = self.ground();
        // Grid spacing grows with the view distance: 0.5 m up close.
        let spacing = 0.5 * 10f32.powf((cam.distance / 12.0).log10().max(0.0).floor());
        let half_lines = 24.0f32;
        let major = 2.0;
        let snap = spacing * major;
        let extent = half_lines * spacing;
        // The grid fades out at 0.9 of its extent: lines (and line ends) further out than
        // that are invisible, so only the lines that reach inside the fade radius are drawn,
        // and only as long (the shader draws `drawn_lines` each side, each that long).
        let drawn_lines = (half_lines * 0.9).ceil().min(half_lines);
        let highlight = (settings.ghosts * settings.ghost_step.max(1)).max(MIN_HIGHLIGHT);
        let globals = Globals {
            view_proj: view_proj.to_cols_array_2d(),
            eye: eye.extend(1.0).to_array(),
            light_dir: light.extend(0.0).to_array(),
            grid: [(target.x / snap).round() * snap, ground, (target.z / snap).round() * snap, spacing],
            grid2: [drawn_lines, extent * 0.2, extent * 0.9, major],
            trail: [scene.frame as f32, highlight as f32, 0.004, 0.0],
        };

        let mut solids = Solids::default();
        for (k, (layer, info)) in scene.layers.iter().zip(&self.layers).enumerate() {
            let m = &layer.motion;
            if m.frames() == 0 || m.joints() == 0 {
                continue;
            }
            let current = scene.frame.min(m.frames() - 1);
            let opacity = layer.opacity.clamp(0.0, 1.0);
            let step = settings.ghost_step.max(1);
            let ghosts = settings.ghosts.min(MAX_GHOSTS);
            let mut poses = vec![(current, opacity, 0.0)];
            for k in 1..=ghosts {
                let alpha = opacity * 0.4 * (1.0 - k as f32 / (ghosts + 1) as f32);
                if let Some(t) = current.checked_sub(k * step) {
                    poses.push((t, alpha, 0.35));
                }
                if current + k * step < m.frames() {
                    poses.push((current + k * step, alpha, 0.35));
                }
            }
            let mpu = m.skeleton.meters_per_unit();
            for (t, alpha, lighten) in poses {
                if alpha <= 0.01 {
                    continue;
                }
                let translucent = alpha < 0.999;
                let rgb = layer.frame_colors.get(t).copied().unwrap_or([200, 200, 200]);
                let bone_color = linear_rgba(rgb, lighten, alpha);
                let joint_color = linear_rgba(rgb, 0.45 + lighten * 0.5, alpha);
                let frame = self.frame_shown(k, m, t);
                let p = |j: usize| frame[j] * mpu + layer.offset;
                for &(a, b) in &info.bones {
                    let (pa, pb) = (p(a), p(b));
                    if let Some(inst) = cylinder(pa, pb, BONE_RADIUS, bone_color) {
                        solids.push(true, translucent, eye, (pa + pb) / 2.0, inst);
                    }
                }
                // The current pose's planted feet: their joints in the contact colour and a mark
                // on the floor under each.
                let planted: Vec<&[usize]> = match &layer.contacts {
                    Some(c) if t == current => Side::BOTH.iter().zip(&info.feet).filter(|(&side, _)| c.side(side).get(t) == Some(&true)).map(|(_, f)| f.as_slice()).collect(),
                    _ => Vec::new(),
                };
                let contact_color = linear_rgba(CONTACT_RGB, 0.0, alpha);
                for &j in &info.joints {
                    let c = p(j);
                    let color = if planted.iter().any(|f| f.contains(&j)) { contact_color } else { joint_color };
                    solids.push(false, translucent, eye, c, sphere(c, JOINT_RADIUS, color));
                }
                for foot in &planted {
                    let centre = foot.iter().map(|&j| p(j)).sum::<Vec3>() / foot.len() as f32;
                    let centre = Vec3::new(centre.x, ground + 0.005, centre.z);
                    solids.push(false, translucent, eye, centre, floor_disc(centre, CONTACT_RADIUS, 0.008, contact_color));
                }
                if let Some((h, parent, child)) = info.head {
                    let (ph, pp) = (p(h), p(parent));
                    let centre = match child {
                        Some(c) => (ph + p(c)) / 2.0,
                        None => ph + (ph - pp).normalize_or_zero() * HEAD_RADIUS * 0.7,
                    };
                    solids.push(false, translucent, eye, centre, sphere(centre, HEAD_RADIUS, bone_color));
                }
            }
        }
        if let Some(path) = &scene.path {
            for (k, w) in path.waypoints.iter().enumerate() {
                let lighten = if path.selected == Some(k) { 0.7 } else { 0.0 };
                let centre = Vec3::new(w[0], ground + 0.01, w[1]);
                solids.push(false, false, eye, centre, floor_disc(centre, WAYPOINT_RADIUS, 0.015, linear_rgba(PATH_RGB, lighten, 1.0)));
            }
        }
        let overlay = scene.path.as_ref().map_or_else(Vec::new, |p| self.path_vertices(p));
        let (instances, counts) = solids.finish();
        let trail = settings.trail.then(|| self.trail(scene, highlight));
        // The offscreen image holds sRGB-encoded values.
        let [r, g, b] = BACKGROUND.map(|c| c as f64 / 255.0);
        SceneCallback {
            view: self.id,
            size_px,
            clear: wgpu::Color { r, g, b, a: 1.0 },
            globals,
            instances,
            counts,
            grid_vertices: if settings.grid { (2 * drawn_lines as u32 + 1) * 2 * 2 } else { 0 },
            trail,
            overlay,
        }
    }
}
