//! The 3D skeleton viewport: a wgpu paint callback inside egui.
//! (Interface agreed between the studio's parts; the implementation is being written.)

use std::sync::Arc;

use crate::motion::Motion;

/// One take drawn in the viewport.
#[derive(Clone)]
pub struct Layer {
    pub motion: Arc<Motion>,
    /// RGB colour of each frame (e.g. its segment's class colour), `motion.frames()` long.
    pub frame_colors: Arc<Vec<[u8; 3]>>,
    /// Shift in world units, for side-by-side comparison (zero for overlay).
    pub offset: glam::Vec3,
    /// 0..1; a second overlaid take is drawn translucent.
    pub opacity: f32,
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
    pub frame: usize,
    pub settings: &'a ViewSettings,
}

/// Camera state and interaction (orbit: drag, pan: right/middle drag or shift+drag, zoom:
/// scroll). Create once with [`Viewport::new`]; call [`Viewport::register`] once with the
/// wgpu render state (eframe's `cc.wgpu_render_state`, or egui_kittest's) to install the
/// pipeline in the renderer's callback resources; then [`Viewport::ui`] every frame.
pub struct Viewport {
    _private: (),
}

impl Default for Viewport {
    fn default() -> Self {
        Self::new()
    }
}

impl Viewport {
    pub fn new() -> Self {
        Self { _private: () }
    }

    pub fn register(_render_state: &eframe::egui_wgpu::RenderState) {}

    /// Fills the available space with the 3D view.
    pub fn ui(&mut self, ui: &mut egui::Ui, _scene: &Scene) -> egui::Response {
        let size = ui.available_size();
        ui.allocate_response(size, egui::Sense::click_and_drag())
    }
}
