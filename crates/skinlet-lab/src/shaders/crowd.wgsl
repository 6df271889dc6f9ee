// The GPU-driven crowd's draws (gpu_crowd.rs): vertex skinning (morph deltas, then linear
// blend skinning by the palette skinlet culls with), faceted shading or meshlet ids. After
// skinlet-gpu's SURVIVORS_WGSL.

struct View {
    view_proj: mat4x4<f32>,
    light: vec4<f32>,
    joints: u32,
    stride: u32,
    weights: u32,
    meshlets: u32,
}

@group(0) @binding(0) var<uniform> view: View;
// Per instance, per joint: the world-space skinning matrix.
@group(0) @binding(1) var<storage, read> palette: array<mat4x4<f32>>;
@group(0) @binding(2) var<storage, read> positions: array<f32>;
// Per vertex `stride` slots: (joint, weight bits).
@group(0) @binding(3) var<storage, read> influences: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> morph_offsets: array<u32>;
// (delta, target index bits).
@group(0) @binding(5) var<storage, read> morph_deltas: array<vec4<f32>>;
// Per instance `weights` morph weights.
@group(0) @binding(6) var<storage, read> morph_weights: array<f32>;
// The index buffer in meshlet order, read by the pulled and id draws.
@group(0) @binding(7) var<storage, read> indices: array<u32>;
// The survivors (skinlet's crowd culling), read by the pulled draw.
@group(0) @binding(8) var<storage, read> survivor_draws: array<u32>;
// Per triangle (in index buffer order) its meshlet, read by the id draw.
@group(0) @binding(9) var<storage, read> triangle_meshlets: array<u32>;

struct Shaded {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
}

struct Identified {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) id: u32,
}

fn skinned(v: u32, i: u32) -> vec3<f32> {
    var p = vec3<f32>(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
    for (var d = morph_offsets[v]; d < morph_offsets[v + 1u]; d++) {
        p += morph_deltas[d].xyz * morph_weights[i * view.weights + bitcast<u32>(morph_deltas[d].w)];
    }
    var s = mat4x4<f32>();
    for (var k = v * view.stride; k < (v + 1u) * view.stride; k++) {
        s += palette[i * view.joints + influences[k].x] * bitcast<f32>(influences[k].y);
    }
    return (s * vec4<f32>(p, 1.0)).xyz;
}

fn shaded(v: u32, i: u32) -> Shaded {
    let world = skinned(v, i);
    return Shaded(view.view_proj * vec4<f32>(world, 1.0), world);
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
        return Shaded(vec4<f32>(2.0, 2.0, 2.0, 1.0), vec3<f32>(0.0));
    }
    return shaded(indices[c.index], c.instance);
}

// Every instance's every triangle (draw(0..indices, 0..instances)), with its (instance,
// meshlet) id + 1.
@vertex
fn vs_ids(@builtin(vertex_index) k: u32, @builtin(instance_index) i: u32) -> Identified {
    let world = skinned(indices[k], i);
    return Identified(view.view_proj * vec4<f32>(world, 1.0), i * view.meshlets + triangle_meshlets[k / 3u] + 1u);
}

@fragment
fn fs_shaded(in: Shaded) -> @location(0) vec4<f32> {
    let n = normalize(cross(dpdx(in.world), dpdy(in.world)));
    return vec4<f32>(vec3<f32>(0.2 + 0.8 * abs(dot(n, view.light.xyz))), 1.0);
}

@fragment
fn fs_ids(in: Identified) -> @location(0) u32 {
    return in.id;
}
