// Glocal Studio skeleton viewport.
//
// Scene passes render into an offscreen colour (Rgba8Unorm) plus depth target; the blit pass
// copies that texture into egui's render pass. Colours are shaded in linear RGB and written
// gamma-encoded (sRGB), like egui's own output on its preferred non-sRGB framebuffers, so the
// copy is a plain load; blending of translucent parts happens on the encoded values, as in
// egui.

struct Globals {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    // xyz: unit vector towards the key light.
    light_dir: vec4<f32>,
    // x, z: grid centre (snapped to the spacing), y: ground height, w: spacing.
    grid: vec4<f32>,
    // x: lines each side of the centre, y: fade start radius, z: fade end radius, w: every
    // how many lines a major line is drawn.
    grid2: vec4<f32>,
    // x: current frame, y: highlighted frames before it, z: trail lift above ground.
    trail: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

fn linear_to_srgb(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// ---- Solids: instanced bones (cylinders) and joints (spheres) ----

struct SolidIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) m0: vec4<f32>,
    @location(3) m1: vec4<f32>,
    @location(4) m2: vec4<f32>,
    @location(5) m3: vec4<f32>,
    // Linear RGB and alpha.
    @location(6) color: vec4<f32>,
};

struct SolidOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) world: vec3<f32>,
    @location(2) color: vec4<f32>,
};

@vertex
fn vs_solid(v: SolidIn) -> SolidOut {
    let model = mat4x4<f32>(v.m0, v.m1, v.m2, v.m3);
    let world = model * vec4<f32>(v.position, 1.0);
    var out: SolidOut;
    out.clip = globals.view_proj * world;
    // The instance scales are equal across the cylinder's axis and the unit meshes' normals
    // are radial or axial, so the model matrix keeps them perpendicular.
    out.normal = (model * vec4<f32>(v.normal, 0.0)).xyz;
    out.world = world.xyz;
    out.color = v.color;
    return out;
}

@fragment
fn fs_solid(in: SolidOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    let to_eye = normalize(globals.eye.xyz - in.world);
    let l = globals.light_dir.xyz;
    let diffuse = max(dot(n, l), 0.0);
    // Hemisphere ambient: brighter from the sky than from the floor.
    let ambient = mix(0.18, 0.38, n.y * 0.5 + 0.5);
    // A soft rim keeps the silhouette readable against the dark background.
    let edge = 1.0 - max(dot(n, to_eye), 0.0);
    let rim = edge * edge * edge * 0.25;
    let rgb = in.color.rgb * (ambient + 0.75 * diffuse) + vec3<f32>(rim);
    return vec4<f32>(linear_to_srgb(rgb), in.color.a);
}

// ---- Ground grid: line list generated from the vertex index ----

struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) color: vec4<f32>,
};

@vertex
fn vs_grid(@builtin(vertex_index) index: u32) -> LineOut {
    let half = i32(globals.grid2.x);
    let count = u32(2 * half + 1);
    let line = index / 2u;
    let end = f32(index % 2u) * 2.0 - 1.0;
    let along_x = line < count;
    let k = i32(line % count) - half;
    let s = globals.grid.w;
    let extent = f32(half) * s;
    var p = vec3<f32>(globals.grid.x, globals.grid.y, globals.grid.z);
    if along_x {
        p.x += end * extent;
        p.z += f32(k) * s;
    } else {
        p.x += f32(k) * s;
        p.z += end * extent;
    }
    // Lines through world multiples of `major` spacings are brighter; the axes brighter still.
    let major = globals.grid2.w;
    let world_k = round((select(p.x, p.z, along_x)) / s);
    let is_major = abs(world_k - major * round(world_k / major)) < 0.5;
    let is_axis = abs(world_k) < 0.5;
    var color = vec4<f32>(0.30, 0.32, 0.36, 0.22);
    if is_major {
        color = vec4<f32>(0.40, 0.42, 0.48, 0.45);
    }
    if is_axis {
        color = select(vec4<f32>(0.55, 0.22, 0.22, 0.7), vec4<f32>(0.22, 0.30, 0.60, 0.7), along_x);
    }
    var out: LineOut;
    out.clip = globals.view_proj * vec4<f32>(p, 1.0);
    out.world = p;
    out.color = color;
    return out;
}

@fragment
fn fs_line(in: LineOut) -> @location(0) vec4<f32> {
    let d = distance(in.world.xz, globals.grid.xz);
    let fade = 1.0 - smoothstep(globals.grid2.y, globals.grid2.z, d);
    return vec4<f32>(linear_to_srgb(in.color.rgb), in.color.a * fade);
}

// ---- Root trajectory trail: every take's whole ground path, simplified and faded, and its
// recent part at every frame, highlighted ----

struct TrailIn {
    @location(0) position: vec3<f32>,
    @location(1) frame: f32,
    @location(2) last_frame: f32,
    // sRGB bytes.
    @location(3) color: vec4<f32>,
};

// A trail or overlay vertex; `highlight` lightens the recent part (the full-resolution
// pass over the recent frames does; the simplified whole path underneath does not).
fn trail_line(v: TrailIn, highlight: bool) -> LineOut {
    let current = min(globals.trail.x, v.last_frame);
    let d = v.frame - current;
    var rgb = srgb_to_linear(v.color.rgb);
    var alpha = 0.22;
    if v.last_frame < 0.0 {
        // An overlay line (the root path): its own colour, opaque.
        alpha = 1.0;
    } else {
        if d <= 0.5 {
            alpha = 0.5;
        }
        if highlight && d <= 0.5 && d >= -globals.trail.y {
            // The recent part, lightened towards white.
            rgb = mix(rgb, vec3<f32>(1.0), 0.35);
            alpha = 1.0;
        }
    }
    var out: LineOut;
    let p = v.position + vec3<f32>(0.0, globals.trail.z, 0.0);
    out.clip = globals.view_proj * vec4<f32>(p, 1.0);
    // Trails never fade with the grid: put them at the grid centre for fs_line.
    out.world = vec3<f32>(globals.grid.x, p.y, globals.grid.z);
    out.color = vec4<f32>(rgb, alpha * v.color.a);
    return out;
}

@vertex
fn vs_trail(v: TrailIn) -> LineOut {
    return trail_line(v, true);
}

@vertex
fn vs_trail_faded(v: TrailIn) -> LineOut {
    return trail_line(v, false);
}

// ---- Blit of the offscreen image into egui's pass ----

@group(0) @binding(0) var scene_image: texture_2d<f32>;

struct BlitOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_blit(@builtin(vertex_index) index: u32) -> BlitOut {
    // One triangle covering the callback's viewport.
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u)) * 2.0 - 1.0;
    var out: BlitOut;
    out.clip = vec4<f32>(xy, 0.0, 1.0);
    out.uv = vec2<f32>(xy.x * 0.5 + 0.5, 0.5 - xy.y * 0.5);
    return out;
}

fn blit_texel(uv: vec2<f32>) -> vec3<f32> {
    let size = vec2<f32>(textureDimensions(scene_image));
    let texel = clamp(vec2<i32>(floor(uv * size)), vec2<i32>(0), vec2<i32>(size) - 1);
    return textureLoad(scene_image, texel, 0).rgb;
}

// egui's preferred non-sRGB framebuffer: copy the encoded values.
@fragment
fn fs_blit_gamma(in: BlitOut) -> @location(0) vec4<f32> {
    return vec4<f32>(blit_texel(in.uv), 1.0);
}

// An sRGB framebuffer encodes by itself: write linear values.
@fragment
fn fs_blit_linear(in: BlitOut) -> @location(0) vec4<f32> {
    return vec4<f32>(srgb_to_linear(blit_texel(in.uv)), 1.0);
}
