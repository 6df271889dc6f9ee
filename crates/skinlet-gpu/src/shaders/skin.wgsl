// Compute-shader skinning (after common.wgsl): one invocation per vertex, results to buffers.

@group(0) @binding(6) var<storage, read_write> out_positions: array<f32>;
@group(0) @binding(7) var<storage, read_write> out_normals: array<f32>;

@compute @workgroup_size(64)
fn skin(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = id.x;
    if v >= params.vertices {
        return;
    }
    let s = skin_vertex(v);
    out_positions[3u * v] = s.position.x;
    out_positions[3u * v + 1u] = s.position.y;
    out_positions[3u * v + 2u] = s.position.z;
    if params.normals != 0u {
        out_normals[3u * v] = s.normal.x;
        out_normals[3u * v + 1u] = s.normal.y;
        out_normals[3u * v + 2u] = s.normal.z;
    }
}
