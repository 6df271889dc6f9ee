// Task-shader culling (paper section 6; after common.wgsl, draw.wgsl, mesh_skin.wgsl and
// cull_common.wgsl; the module starts with `enable wgpu_mesh_shader;`): one invocation per
// meshlet slot of one instance runs the culling test on the joint records crowd culling
// prepared on the GPU (CrowdCulling::encode_prepare), the survivors' ids go to the payload,
// and one mesh workgroup is launched per survivor.

@group(3) @binding(0) var<uniform> cull_params: CullParams;
@group(3) @binding(1) var<storage, read> slots: array<Slot>;
@group(3) @binding(2) var<storage, read> joint_records: array<f32>;
// The culler's any-pose boxes (cull_common.wgsl).
@group(3) @binding(6) var<storage, read> any_pose_boxes: array<u32>;
// The slots this draw tests (first, count: a culling class's range) and its instance.
struct TaskRange {
    first: u32,
    count: u32,
    instance: u32,
    pad: u32,
}
@group(3) @binding(3) var<uniform> task_range: TaskRange;

struct TaskPayload {
    ids: array<u32, 32>,
}

var<task_payload> payload: TaskPayload;
// lavapipe does not zero task-shader workgroup memory: cleared before use.
var<workgroup> survivors: atomic<u32>;

@task
@payload(payload)
@workgroup_size(32)
fn task(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) -> @builtin(mesh_task_size) vec3<u32> {
    if lid == 0u {
        atomicStore(&survivors, 0u);
    }
    workgroupBarrier();
    let slot = task_range.first + wg.x * 32u + lid;
    if slot < task_range.first + task_range.count {
        let s = slots[slot];
        if meshlet_flag(s, task_range.instance) == 0u {
            payload.ids[atomicAdd(&survivors, 1u)] = s.id;
        }
    }
    return launch(lid);
}

// After a task workgroup listed its survivors: counts them (meshlets drawn) and launches one
// mesh workgroup per survivor.
fn launch(lid: u32) -> vec3<u32> {
    workgroupBarrier();
    let n = atomicLoad(&survivors);
    if lid == 0u {
        atomicAdd(&drawn[1], n);
    }
    return vec3<u32>(n, 1u, 1u);
}

// Per-triangle culling in the mesh shader (thesis 5.1.3): `mode` 0 none, 1 perspective
// (`view` = the eye), 2 orthographic (`view` = the view direction).
struct TriangleCull {
    view: vec4<f32>,
    mode: u32,
}

// Triangles the mesh shaders emitted and did not cull, meshlets the task shaders launched.
@group(3) @binding(4) var<storage, read_write> drawn: array<atomic<u32>>;
@group(3) @binding(5) var<uniform> triangle_cull: TriangleCull;

@mesh(mesh_out)
@payload(payload)
@workgroup_size(32)
fn culled_mesh(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let id = payload.ids[wg.x];
    emit_meshlet(id, lid, vec4<f32>(1.0));
    cull_triangles(id, lid);
}

// After meshlet `id` is emitted: marks its back-facing triangles culled (when asked) and counts
// the ones kept.
fn cull_triangles(id: u32, lid: u32) {
    let count = select(0u, meshlets[min(id, arrayLength(&meshlets) - 1u)].triangle_count, id < arrayLength(&meshlets));
    workgroupBarrier();
    // skinlet::cull::triangle::facing on the skinned positions, operation for operation:
    // culled when (p0 - eye)·((p1 - p0) × (p2 - p0)) is not negative.
    var kept = 0u;
    for (var i = lid; i < count; i += 32u) {
        let t = mesh_out.primitives[i].indices;
        let p0 = mesh_out.vertices[t.x].world;
        let e1 = mesh_out.vertices[t.y].world - p0;
        let e2 = mesh_out.vertices[t.z].world - p0;
        let n = vec3<f32>(e1.y * e2.z - e2.y * e1.z, e1.z * e2.x - e2.z * e1.x, e1.x * e2.y - e2.x * e1.y);
        var cull = false;
        if triangle_cull.mode != 0u {
            var d = triangle_cull.view.xyz;
            if triangle_cull.mode == 1u {
                d = p0 - triangle_cull.view.xyz;
            }
            cull = !(d.x * n.x + d.y * n.y + d.z * n.z < 0.0);
        }
        mesh_out.primitives[i].cull = cull;
        kept += select(1u, 0u, cull);
    }
    atomicAdd(&drawn[0], kept);
}
