// Drawing (after the vertex source: common.wgsl + vertex_skin.wgsl, or skinned.wgsl): the
// camera, and faceted shading from screen-space derivatives of the world position (the same
// for every pipeline, and for meshes without normals).

struct Camera {
    view_proj: mat4x4<f32>,
    light: vec4<f32>,
}

@group(1) @binding(0) var<uniform> camera: Camera;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
}

fn to_screen(p: vec3<f32>) -> VertexOut {
    var out: VertexOut;
    out.clip = camera.view_proj * vec4<f32>(p, 1.0);
    out.world = p;
    return out;
}

fn lit(in: VertexOut) -> vec4<f32> {
    let n = normalize(cross(dpdx(in.world), dpdy(in.world)));
    let l = 0.25 + 0.75 * abs(dot(n, camera.light.xyz));
    return vec4<f32>(vec3<f32>(l), 1.0);
}

@fragment
fn shade(in: VertexOut) -> @location(0) vec4<f32> {
    return lit(in);
}

// Overdraw: each fragment that passes the depth test adds 1 to the red channel (additive
// blending into RGBA8: exact counts up to 255).
@fragment
fn count_fragment() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0 / 255.0, 0.0, 0.0, 0.0);
}
