//! The GPU side of the viewport: pipelines built once in [`Resources::new`] and kept in
//! egui-wgpu's callback resources, per-view buffers and offscreen targets, and the
//! [`SceneCallback`] that uploads one frame's data in `prepare` and draws in `paint`.
//!
//! Depth: egui's render pass has no depth attachment unless the app asks for one (eframe's
//! `NativeOptions::depth_buffer`, off by default; egui_kittest never has one), so the scene is
//! drawn in `prepare`, on egui's command encoder (recorded before egui's own pass), into an
//! offscreen colour + depth target the size of the view; `paint` then copies that image into
//! egui's pass with one full-viewport triangle. This works the same under eframe, kittest and
//! lavapipe, whatever egui's pass looks like, as long as the blit pipeline matches egui's
//! pass ([`HostPass`]).

use std::collections::HashMap;
use std::num::NonZeroU64;
use std::ops::Range;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use eframe::egui_wgpu::{self, wgpu};

use super::mesh::{self, MeshVertex};

/// Colour format of the offscreen image: the shaders write sRGB-encoded values.
const SCENE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Multisampling of the offscreen scene: 4x on GPUs, off on software rasterisers (lavapipe,
/// llvmpipe), where it costs more than the whole rest of the frame. `GLOCAL_VIEWPORT_MSAA`
/// (1 or 4) overrides it.
fn scene_samples(adapter: &wgpu::Adapter) -> u32 {
    let env = std::env::var("GLOCAL_VIEWPORT_MSAA").ok().and_then(|s| s.parse().ok()).filter(|s| [1, 4].contains(s));
    env.unwrap_or(if adapter.get_info().device_type == wgpu::DeviceType::Cpu { 1 } else { 4 })
}

/// How egui's own render pass is set up, which the pipeline that copies the scene into it
/// must match. The defaults match eframe's defaults and egui_kittest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostPass {
    /// eframe's `NativeOptions::multisampling` (0 or 1: off).
    pub msaa_samples: u32,
    /// The depth/stencil format of egui's pass (eframe: from `NativeOptions::depth_buffer`
    /// and `stencil_buffer`, see `egui_wgpu::depth_format_from_bits`).
    pub depth_stencil_format: Option<wgpu::TextureFormat>,
}

impl Default for HostPass {
    fn default() -> Self {
        Self { msaa_samples: 1, depth_stencil_format: None }
    }
}

/// Uniforms shared by every scene pipeline (matches `Globals` in viewport.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(super) struct Globals {
    pub view_proj: [[f32; 4]; 4],
    pub eye: [f32; 4],
    pub light_dir: [f32; 4],
    pub grid: [f32; 4],
    pub grid2: [f32; 4],
    pub trail: [f32; 4],
}

/// One instanced solid: a column-major model matrix and a linear RGBA colour.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct Instance {
    pub model: [[f32; 4]; 4],
    pub color: [f32; 4],
}

/// One vertex of the trail's line list.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct TrailVertex {
    pub position: [f32; 3],
    pub frame: f32,
    pub last_frame: f32,
    /// sRGB, alpha.
    pub color: [u8; 4],
}

/// The root trail of every layer of a scene, built once per take (see `Viewport::trail`):
/// one line list holding, first, each layer's whole path simplified for the faded trail,
/// then each layer's path at every frame, of which only the highlighted recent part is drawn.
pub(super) struct TrailGeometry {
    pub vertices: Vec<TrailVertex>,
    /// The simplified paths' vertices (at the start of `vertices`).
    pub simplified: u32,
}

/// The trail in one frame's scene: its geometry (uploaded when `version` changes) and the
/// vertices of its highlighted part.
pub(super) struct TrailDraw {
    pub version: u64,
    pub geometry: Arc<TrailGeometry>,
    /// Vertex ranges of the full-resolution paths drawn highlighted (one per layer).
    pub highlighted: Vec<Range<u32>>,
}

/// One view's frame, built on the UI thread by `Viewport::ui`.
pub(super) struct SceneCallback {
    pub view: egui::Id,
    pub size_px: [u32; 2],
    pub clear: wgpu::Color,
    pub globals: Globals,
    /// Opaque bones, opaque joints, translucent bones, translucent joints, in this order.
    pub instances: Vec<Instance>,
    pub counts: [u32; 4],
    pub grid_vertices: u32,
    pub trail: Option<TrailDraw>,
    /// Lines in a fixed colour (the root path), `last_frame` negative; uploaded every frame
    /// (a path is a few vertices).
    pub overlay: Vec<TrailVertex>,
}

struct Target {
    size: [u32; 2],
    /// Multisampled colour when the scene is multisampled, else `None` (the resolve image is drawn).
    msaa: Option<wgpu::TextureView>,
    resolved: wgpu::TextureView,
    depth: wgpu::TextureView,
    blit_group: wgpu::BindGroup,
}

/// GPU state of one `Viewport` (keyed by its egui id).
struct ViewGpu {
    globals: wgpu::Buffer,
    globals_group: wgpu::BindGroup,
    instances: wgpu::Buffer,
    instance_capacity: u64,
    trail: wgpu::Buffer,
    trail_capacity: u64,
    trail_version: u64,
    overlay: wgpu::Buffer,
    overlay_capacity: u64,
    target: Option<Target>,
    /// Whether the last prepare produced an image to blit.
    ready: bool,
}

/// Everything the viewport keeps in `renderer.callback_resources`.
pub(super) struct Resources {
    globals_layout: wgpu::BindGroupLayout,
    blit_layout: wgpu::BindGroupLayout,
    solid_opaque: wgpu::RenderPipeline,
    solid_blend: wgpu::RenderPipeline,
    grid: wgpu::RenderPipeline,
    /// The trail's faded whole path, and its highlighted recent part.
    trail_faded: wgpu::RenderPipeline,
    trail: wgpu::RenderPipeline,
    blit: wgpu::RenderPipeline,
    mesh_vertices: wgpu::Buffer,
    mesh_indices: wgpu::Buffer,
    cylinder: (Range<u32>, i32),
    sphere: (Range<u32>, i32),
    views: HashMap<egui::Id, ViewGpu>,
    samples: u32,
    /// Uploads of a take's geometry (the trail's vertices) by every view so far: once per
    /// take shown, never per frame ([`super::Viewport::geometry_uploads`]).
    pub geometry_uploads: u64,
}

fn buffer(device: &wgpu::Device, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn alpha_blend() -> wgpu::BlendState {
    wgpu::BlendState {
        color: wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::SrcAlpha,
            dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
            operation: wgpu::BlendOperation::Add,
        },
        alpha: wgpu::BlendComponent::OVER,
    }
}

impl Resources {
    pub fn new(adapter: &wgpu::Adapter, device: &wgpu::Device, queue: &wgpu::Queue, target_format: wgpu::TextureFormat, host: HostPass) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("glocal_viewport"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../viewport.wgsl").into()),
        });
        let globals_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("glocal_viewport_globals"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: NonZeroU64::new(std::mem::size_of::<Globals>() as u64),
                },
                count: None,
            }],
        });
        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("glocal_viewport_blit"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let scene_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("glocal_viewport_scene"),
            bind_group_layouts: &[Some(&globals_layout)],
            immediate_size: 0,
        });
        let blit_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("glocal_viewport_blit"),
            bind_group_layouts: &[Some(&blit_layout)],
            immediate_size: 0,
        });

        let depth = |write: bool| {
            Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(write),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            })
        };
        let samples = scene_samples(adapter);
        let scene_multisample = wgpu::MultisampleState { count: samples, mask: !0, alpha_to_coverage_enabled: false };

        let mesh_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<MeshVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
        };
        let instance_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Instance>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &wgpu::vertex_attr_array![2 => Float32x4, 3 => Float32x4, 4 => Float32x4, 5 => Float32x4, 6 => Float32x4],
        };
        let solid = |label: &str, opaque: bool| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&scene_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_solid"),
                    buffers: &[Some(mesh_layout.clone()), Some(instance_layout.clone())],
                    compilation_options: Default::default(),
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    front_face: wgpu::FrontFace::Ccw,
                    cull_mode: Some(wgpu::Face::Back),
                    ..Default::default()
                },
                depth_stencil: depth(opaque),
                multisample: scene_multisample,
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_solid"),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: SCENE_FORMAT,
                        blend: if opaque { None } else { Some(alpha_blend()) },
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                    compilation_options: Default::default(),
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let solid_opaque = solid("glocal_viewport_solid_opaque", true);
        let solid_blend = solid("glocal_viewport_solid_blend", false);

        let trail_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<TrailVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32, 2 => Float32, 3 => Unorm8x4],
        };
        let lines = |label: &str, entry: &str, buffers: &[Option<wgpu::VertexBufferLayout>]| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&scene_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(entry),
                    buffers,
                    compilation_options: Default::default(),
                },
                primitive: wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::LineList, ..Default::default() },
                depth_stencil: depth(false),
                multisample: scene_multisample,
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_line"),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: SCENE_FORMAT,
                        blend: Some(alpha_blend()),
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                    compilation_options: Default::default(),
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let grid = lines("glocal_viewport_grid", "vs_grid", &[]);
        let trail_faded = lines("glocal_viewport_trail_faded", "vs_trail_faded", &[Some(trail_layout.clone())]);
        let trail = lines("glocal_viewport_trail", "vs_trail", &[Some(trail_layout)]);

        let blit = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("glocal_viewport_blit"),
            layout: Some(&blit_pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_blit"),
                buffers: &[],
                compilation_options: Default::default(),
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: host.depth_stencil_format.map(|format| wgpu::DepthStencilState {
                format,
                depth_write_enabled: Some(false),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState { count: host.msaa_samples.max(1), mask: !0, alpha_to_coverage_enabled: false },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if target_format.is_srgb() { "fs_blit_linear" } else { "fs_blit_gamma" }),
                targets: &[Some(wgpu::ColorTargetState { format: target_format, blend: None, write_mask: wgpu::ColorWrites::ALL })],
                compilation_options: Default::default(),
            }),
            multiview_mask: None,
            cache: None,
        });

        // Both unit meshes in one vertex and one index buffer.
        let cylinder = mesh::cylinder(12);
        let sphere = mesh::icosphere(1);
        let mut vertices = cylinder.vertices.clone();
        vertices.extend_from_slice(&sphere.vertices);
        let mut indices = cylinder.indices.clone();
        indices.extend_from_slice(&sphere.indices);
        if indices.len() % 2 == 1 {
            indices.push(0); // keeps the upload a multiple of 4 bytes
        }
        let mesh_vertices = buffer(device, "glocal_viewport_mesh_vertices", (vertices.len() * std::mem::size_of::<MeshVertex>()) as u64, wgpu::BufferUsages::VERTEX);
        let mesh_indices = buffer(device, "glocal_viewport_mesh_indices", (indices.len() * 2) as u64, wgpu::BufferUsages::INDEX);
        queue.write_buffer(&mesh_vertices, 0, bytemuck::cast_slice(&vertices));
        queue.write_buffer(&mesh_indices, 0, bytemuck::cast_slice(&indices));
        let cyl_count = cylinder.indices.len() as u32;
        let sphere_count = sphere.indices.len() as u32;
        Self {
            globals_layout,
            blit_layout,
            solid_opaque,
            solid_blend,
            grid,
            trail_faded,
            trail,
            blit,
            mesh_vertices,
            mesh_indices,
            cylinder: (0..cyl_count, 0),
            sphere: (cyl_count..cyl_count + sphere_count, cylinder.vertices.len() as i32),
            views: HashMap::new(),
            samples,
            geometry_uploads: 0,
        }
    }

    fn view(&mut self, device: &wgpu::Device, id: egui::Id) -> &mut ViewGpu {
        let globals_layout = &self.globals_layout;
        self.views.entry(id).or_insert_with(|| {
            let globals = buffer(device, "glocal_viewport_globals", std::mem::size_of::<Globals>() as u64, wgpu::BufferUsages::UNIFORM);
            let globals_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("glocal_viewport_globals"),
                layout: globals_layout,
                entries: &[wgpu::BindGroupEntry { binding: 0, resource: globals.as_entire_binding() }],
            });
            let instance_capacity = 256;
            let trail_capacity = 1024;
            ViewGpu {
                globals,
                globals_group,
                instances: buffer(device, "glocal_viewport_instances", instance_capacity * std::mem::size_of::<Instance>() as u64, wgpu::BufferUsages::VERTEX),
                instance_capacity,
                trail: buffer(device, "glocal_viewport_trail", trail_capacity * std::mem::size_of::<TrailVertex>() as u64, wgpu::BufferUsages::VERTEX),
                trail_capacity,
                trail_version: u64::MAX,
                overlay: buffer(device, "glocal_viewport_overlay", 64 * std::mem::size_of::<TrailVertex>() as u64, wgpu::BufferUsages::VERTEX),
                overlay_capacity: 64,
                target: None,
                ready: false,
            }
        })
    }
}

fn make_target(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, size: [u32; 2], samples: u32) -> Target {
    let extent = wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 };
    let texture = |label: &str, format, samples, usage| {
        device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
            .create_view(&wgpu::TextureViewDescriptor::default())
    };
    let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
    let resolved = texture("glocal_viewport_image", SCENE_FORMAT, 1, attach | wgpu::TextureUsages::TEXTURE_BINDING);
    let msaa = (samples > 1).then(|| texture("glocal_viewport_msaa", SCENE_FORMAT, samples, attach));
    let depth = texture("glocal_viewport_depth", DEPTH_FORMAT, samples, attach);
    let blit_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("glocal_viewport_blit"),
        layout,
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&resolved) }],
    });
    Target { size, msaa, resolved, depth, blit_group }
}

/// Grows `buffer` to hold at least `needed` items of `item` bytes (doubling), never shrinking.
fn ensure_capacity(device: &wgpu::Device, buffer: &mut wgpu::Buffer, capacity: &mut u64, needed: u64, item: u64, label: &str) {
    if needed > *capacity {
        let mut new_capacity = (*capacity).max(1);
        while new_capacity < needed {
            new_capacity *= 2;
        }
        *buffer = self::buffer(device, label, new_capacity * item, wgpu::BufferUsages::VERTEX);
        *capacity = new_capacity;
    }
}

impl egui_wgpu::CallbackTrait for SceneCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(res) = resources.get_mut::<Resources>() else {
            return Vec::new();
        };
        let blit_layout = res.blit_layout.clone();
        let samples = res.samples;
        let view = res.view(device, self.view);
        view.ready = false;
        if self.size_px[0] == 0 || self.size_px[1] == 0 {
            return Vec::new();
        }
        let max = device.limits().max_texture_dimension_2d;
        let size = [self.size_px[0].min(max), self.size_px[1].min(max)];
        if view.target.as_ref().is_none_or(|t| t.size != size) {
            view.target = Some(make_target(device, &blit_layout, size, samples));
        }

        queue.write_buffer(&view.globals, 0, bytemuck::bytes_of(&self.globals));
        let instance_size = std::mem::size_of::<Instance>() as u64;
        ensure_capacity(device, &mut view.instances, &mut view.instance_capacity, self.instances.len() as u64, instance_size, "glocal_viewport_instances");
        if !self.instances.is_empty() {
            queue.write_buffer(&view.instances, 0, bytemuck::cast_slice(&self.instances));
        }
        let mut uploaded = false;
        match &self.trail {
            Some(TrailDraw { version, geometry, .. }) if *version != view.trail_version => {
                let vertices = &geometry.vertices;
                let vertex_size = std::mem::size_of::<TrailVertex>() as u64;
                let needed = vertices.len() as u64;
                // A short take after a long one gives the long one's buffer back.
                if needed.max(1024) * 4 < view.trail_capacity {
                    view.trail_capacity = needed.max(1024).next_power_of_two();
                    view.trail = buffer(device, "glocal_viewport_trail", view.trail_capacity * vertex_size, wgpu::BufferUsages::VERTEX);
                }
                ensure_capacity(device, &mut view.trail, &mut view.trail_capacity, needed, vertex_size, "glocal_viewport_trail");
                if !vertices.is_empty() {
                    queue.write_buffer(&view.trail, 0, bytemuck::cast_slice(vertices.as_slice()));
                }
                view.trail_version = *version;
                uploaded = true;
            }
            _ => {}
        }
        if !self.overlay.is_empty() {
            let vertex_size = std::mem::size_of::<TrailVertex>() as u64;
            ensure_capacity(device, &mut view.overlay, &mut view.overlay_capacity, self.overlay.len() as u64, vertex_size, "glocal_viewport_overlay");
            queue.write_buffer(&view.overlay, 0, bytemuck::cast_slice(self.overlay.as_slice()));
        }

        if uploaded {
            res.geometry_uploads += 1;
        }
        // From here on only shared borrows of the resources are needed.
        let res: &Resources = res;
        let view = &res.views[&self.view];
        let target = view.target.as_ref().expect("target made above");
        {
            let (color_view, resolve_target) = match &target.msaa {
                Some(msaa) => (msaa, Some(&target.resolved)),
                None => (&target.resolved, None),
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("glocal_viewport_scene"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: color_view,
                    resolve_target,
                    depth_slice: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(self.clear),
                        store: if target.msaa.is_some() { wgpu::StoreOp::Discard } else { wgpu::StoreOp::Store },
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &view.globals_group, &[]);
            pass.set_vertex_buffer(0, res_mesh(&res.mesh_vertices));
            pass.set_index_buffer(res.mesh_indices.slice(..), wgpu::IndexFormat::Uint16);
            pass.set_vertex_buffer(1, view.instances.slice(..));
            let [opaque_bones, opaque_joints, blend_bones, blend_joints] = self.counts;
            let mut first = 0u32;
            let mut draw = |pass: &mut wgpu::RenderPass<'_>, mesh: &(Range<u32>, i32), count: u32| {
                if count > 0 {
                    pass.draw_indexed(mesh.0.clone(), mesh.1, first..first + count);
                }
                first += count;
            };
            // Opaque solids write depth; lines and translucent solids only test against it.
            pass.set_pipeline(&res.solid_opaque);
            draw(&mut pass, &res.cylinder, opaque_bones);
            draw(&mut pass, &res.sphere, opaque_joints);
            if self.grid_vertices > 0 {
                pass.set_pipeline(&res.grid);
                pass.draw(0..self.grid_vertices, 0..1);
            }
            if let Some(trail) = self.trail.as_ref().filter(|t| !t.geometry.vertices.is_empty()) {
                pass.set_vertex_buffer(0, view.trail.slice(..));
                pass.set_pipeline(&res.trail_faded);
                pass.draw(0..trail.geometry.simplified, 0..1);
                pass.set_pipeline(&res.trail);
                for range in trail.highlighted.iter().filter(|r| !r.is_empty()) {
                    pass.draw(range.clone(), 0..1);
                }
                pass.set_vertex_buffer(0, res_mesh(&res.mesh_vertices));
            }
            if !self.overlay.is_empty() {
                pass.set_pipeline(&res.trail);
                pass.set_vertex_buffer(0, view.overlay.slice(..));
                pass.draw(0..self.overlay.len() as u32, 0..1);
                pass.set_vertex_buffer(0, res_mesh(&res.mesh_vertices));
            }
            pass.set_pipeline(&res.solid_blend);
            draw(&mut pass, &res.cylinder, blend_bones);
            draw(&mut pass, &res.sphere, blend_joints);
        }
        if let Some(view) = resources.get_mut::<Resources>().and_then(|r| r.views.get_mut(&self.view)) {
            view.ready = true;
        }
        Vec::new()
    }

    fn paint(&self, _info: egui::PaintCallbackInfo, render_pass: &mut wgpu::RenderPass<'static>, resources: &egui_wgpu::CallbackResources) {
        let Some(res) = resources.get::<Resources>() else { return };
        let Some(view) = res.views.get(&self.view) else { return };
        let (true, Some(target)) = (view.ready, view.target.as_ref()) else { return };
        render_pass.set_pipeline(&res.blit);
        render_pass.set_bind_group(0, &target.blit_group, &[]);
        render_pass.draw(0..3, 0..1);
    }
}

fn res_mesh(buffer: &wgpu::Buffer) -> wgpu::BufferSlice<'_> {
    buffer.slice(..)
}
