// Mesh-shader skinning of common-influences meshlets (thesis section 3.1.1, listing A.4;
// after common.wgsl, draw.wgsl and mesh_skin.wgsl): a slim meshlet lists its joints once, its
// workgroup loads their matrices into workgroup memory, and its vertices read weights only
// (in the meshlet's joint order, which is each vertex's own: `prepare` sorts influences by
// joint), no joint IDs. Other meshlets skin their full vertices. The sums are skin_vertex's in
// the same order, so the image is the other pipelines' pixel for pixel.

@group(2) @binding(3) var<storage, read> meshlet_joints: array<u32>;

// Four columns per joint, up to MAX_SLIM_JOINTS (16) joints.
var<workgroup> slim_matrices: array<vec4<f32>, 64>;

fn skin_slim(v: u32, count: u32) -> vec3<f32> {
    var x = vec3<f32>(0.0);
    var y = vec3<f32>(0.0);
    var z = vec3<f32>(0.0);
    var t = vec3<f32>(0.0);
    for (var i = 0u; i < count; i++) {
        let w = weights[v * params.stride + i];
        x += slim_matrices[4u * i].xyz * w;
        y += slim_matrices[4u * i + 1u].xyz * w;
        z += slim_matrices[4u * i + 2u].xyz * w;
        t += slim_matrices[4u * i + 3u].xyz * w;
    }
    let p = morphed(v).position;
    return x * p.x + y * p.y + z * p.z + t;
}

@mesh(mesh_out)
@workgroup_size(32)
fn slim_mesh(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    emit_slim_meshlet(wg.y * ROW + wg.x, lid);
}

// Task-shader culling (task_cull.wgsl), then slim skinning of the survivors.
@mesh(mesh_out)
@payload(payload)
@workgroup_size(32)
fn culled_slim_mesh(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let id = payload.ids[wg.x];
    emit_slim_meshlet(id, lid);
    cull_triangles(id, lid);
}

// emit_meshlet for slim meshlets (and full ones among them).
fn emit_slim_meshlet(id: u32, lid: u32) {
    if id >= arrayLength(&meshlets) {
        mesh_out.vertex_count = 0u;
        mesh_out.primitive_count = 0u;
        return;
    }
    let m = meshlets[id];
    for (var k = lid; k < 4u * m.joint_count; k += 32u) {
        slim_matrices[k] = matrices[4u * meshlet_joints[m.joint_offset + k / 4u] + k % 4u];
    }
    workgroupBarrier();
    for (var i = lid; i < m.vertex_count; i += 32u) {
        let v = meshlet_vertices[m.vertex_offset + i];
        var p: vec3<f32>;
        if m.joint_count > 0u {
            p = skin_slim(v, m.joint_count);
        } else {
            p = skin_vertex(v).position;
        }
        mesh_out.vertices[i] = to_screen(p);
    }
    emit_triangles(m, lid, vec4<f32>(1.0));
}
