// The GPU-driven crowd's draws (gpu_crowd.rs): vertex skinning (crowd_skin.wgsl), faceted
// shading or meshlet ids. After skinlet-gpu's SURVIVORS_WGSL and TRIANGLES_WGSL.

struct View {
    view_proj: mat4x4<f32>,
    light: vec4<f32>,
    // Triangles per instance.
    triangles: u32,
    // Bits of a triangle list's index that hold the vertex.
    id_bits: u32,
    // 1: the pulled draw colours each triangle by its cluster's LOD level.
    by_level: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> view: View;
// The index buffer in meshlet order, read by the pulled and id draws.
@group(0) @binding(1) var<storage, read> indices: array<u32>;
// The survivors (skinlet's crowd culling), read by the pulled draw.
@group(0) @binding(2) var<storage, read> survivor_draws: array<u32>;
// Per triangle of the index buffer, its cluster's LOD level (0: full detail).
@group(0) @binding(3) var<storage, read> triangle_levels: array<u32>;

struct Shaded {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) tint: vec3<f32>,
}

struct Identified {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) id: u32,
}

fn shaded(v: u32, i: u32) -> Shaded {
    let world = skinned_position(i, v);
    return Shaded(view.view_proj * vec4<f32>(world, 1.0), world, vec3<f32>(1.0));
}

// A colour per LOD level: white at full detail, then blue, green, yellow, orange, red,
// magenta, purple, cyan from level 8 on.
fn level_colour(level: u32) -> vec3<f32> {
    var colours = array<vec3<f32>, 9>(
        vec3<f32>(1.0, 1.0, 1.0), vec3<f32>(0.35, 0.55, 1.0), vec3<f32>(0.35, 0.9, 0.4),
        vec3<f32>(1.0, 0.95, 0.3), vec3<f32>(1.0, 0.6, 0.2), vec3<f32>(1.0, 0.3, 0.3),
        vec3<f32>(1.0, 0.35, 0.9), vec3<f32>(0.6, 0.35, 1.0), vec3<f32>(0.3, 1.0, 1.0));
    return colours[min(level, 8u)];
}

// Unculled (draw_indexed over every instance) and the survivors' indexed draws
// (first_instance = the instance).
@vertex
fn vs_indexed(@builtin(vertex_index) v: u32, @builtin(instance_index) i: u32) -> Shaded {
    return shaded(v, i);
}

// The survivors pulled: one instance per survivor.
@vertex
fn vs_pulled(@builtin(vertex_index) corner: u32, @builtin(instance_index) survivor: u32) -> Shaded {
    let c = survivor_corner(survivor, corner);
    if !c.live {
        return Shaded(vec4<f32>(2.0, 2.0, 2.0, 1.0), vec3<f32>(0.0), vec3<f32>(1.0));
    }
    var out = shaded(indices[c.index], c.instance);
    if view.by_level != 0u {
        out.tint = level_colour(triangle_levels[c.index / 3u]);
    }
    return out;
}

// The triangle pass's list: each index an (instance, vertex).
@vertex
fn vs_triangles(@builtin(vertex_index) index: u32) -> Shaded {
    let iv = triangle_entry(index, view.id_bits);
    return shaded(iv.y, iv.x);
}

// Every instance's every triangle (draw(0..indices, 0..instances)), with its (instance,
// triangle) id + 1.
@vertex
fn vs_ids(@builtin(vertex_index) k: u32, @builtin(instance_index) i: u32) -> Identified {
    let world = skinned_position(i, indices[k]);
    return Identified(view.view_proj * vec4<f32>(world, 1.0), i * view.triangles + k / 3u + 1u);
}

@fragment
fn fs_shaded(in: Shaded) -> @location(0) vec4<f32> {
    let n = normalize(cross(dpdx(in.world), dpdy(in.world)));
    return vec4<f32>(in.tint * (0.2 + 0.8 * abs(dot(n, view.light.xyz))), 1.0);
}

@fragment
fn fs_ids(in: Identified) -> @location(0) u32 {
    return in.id;
}
