// Per-meshlet culling of many instances in a compute pass (after cull_common.wgsl): one
// invocation per (instance, meshlet), survivors compacted per instance with an atomic counter.

@group(0) @binding(0) var<uniform> cull_params: CullParams;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
@group(0) @binding(2) var<storage, read> joint_records: array<f32>;
// Per instance: visible, culled by the frustum, culled by the backface test only.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// Per instance, `slots` entries: the visible meshlets' ids, compacted.
@group(0) @binding(4) var<storage, read_write> visible: array<u32>;

@compute @workgroup_size(64)
fn cull(@builtin(global_invocation_id) gid: vec3<u32>) {
    let index = gid.y * 65535u * 64u + gid.x;
    if index >= cull_params.slots * cull_params.instances {
        return;
    }
    let instance = index / cull_params.slots;
    let s = slots[index % cull_params.slots];
    let flag = meshlet_flag(s, instance);
    if flag == 0u {
        let k = atomicAdd(&counts[3u * instance], 1u);
        visible[instance * cull_params.slots + k] = s.id;
    } else if (flag & 1u) != 0u {
        atomicAdd(&counts[3u * instance + 1u], 1u);
    } else {
        atomicAdd(&counts[3u * instance + 2u], 1u);
    }
}
