// Contour edges as lines (after draw.wgsl: the camera), drawn indirectly: two vertices per
// edge id written by the extraction passes (contours.wgsl), over the skinned positions.

@group(0) @binding(0) var<storage, read> skinned: array<f32>;
@group(0) @binding(1) var<storage, read> contour_edges: array<u32>;
// Both vertices of every edge id.
@group(0) @binding(2) var<storage, read> endpoints: array<u32>;

@vertex
fn line_vertex(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    let i = endpoints[2u * contour_edges[v / 2u] + (v & 1u)];
    var clip = camera.view_proj * vec4<f32>(skinned[3u * i], skinned[3u * i + 1u], skinned[3u * i + 2u], 1.0);
    // A contour lies on its front face: pull it toward the viewer so it wins the depth test.
    clip.z -= 0.002 * clip.w;
    return clip;
}

@fragment
fn visible_line() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, 0.55, 0.1, 1.0);
}

@fragment
fn hidden_line() -> @location(0) vec4<f32> {
    return vec4<f32>(0.42, 0.27, 0.12, 1.0);
}
