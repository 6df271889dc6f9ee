// Vertex-shader skinning (after common.wgsl): each vertex skinned where it is drawn.

@vertex
fn vertex(@builtin(vertex_index) v: u32) -> VertexOut {
    return to_screen(skin_vertex(v).position);
}
