// Task-shader culling (paper section 6; after common.wgsl, draw.wgsl, mesh_skin.wgsl and
// cull_common.wgsl; the module starts with `enable wgpu_mesh_shader;`): one invocation per
// meshlet slot of one instance runs the culling test, the survivors' ids go to the payload,
// and one mesh workgroup is launched per survivor.

@group(3) @binding(0) var<uniform> cull_params: CullParams;
@group(3) @binding(1) var<storage, read> slots: array<Slot>;
@group(3) @binding(2) var<storage, read> joint_records: array<f32>;

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
    let slot = wg.x * 32u + lid;
    if slot < cull_params.slots {
        let s = slots[slot];
        if meshlet_flag(s, 0u) == 0u {
            payload.ids[atomicAdd(&survivors, 1u)] = s.id;
        }
    }
    workgroupBarrier();
    return vec3<u32>(atomicLoad(&survivors), 1u, 1u);
}

@mesh(mesh_out)
@payload(payload)
@workgroup_size(32)
fn culled_mesh(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    emit_meshlet(payload.ids[wg.x], lid, vec4<f32>(1.0));
}
