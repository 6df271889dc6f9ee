// Drawing vertices skinned beforehand by the compute pass.

@group(0) @binding(0) var<storage, read> skinned: array<f32>;

@vertex
fn vertex(@builtin(vertex_index) v: u32) -> VertexOut {
    return to_screen(vec3<f32>(skinned[3u * v], skinned[3u * v + 1u], skinned[3u * v + 2u]));
}
