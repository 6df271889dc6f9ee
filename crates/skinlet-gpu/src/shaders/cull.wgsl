// Per-meshlet culling of many instances in a compute pass (after cull_common.wgsl): one
// invocation per (instance, meshlet), survivors compacted per instance with an atomic counter
// (`cull`), or written as indexed indirect draws, one per meshlet in meshlet order, culled
// ones with no instance (`cull_draws`: the draw path without mesh shaders).

@group(0) @binding(0) var<uniform> cull_params: CullParams;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
@group(0) @binding(2) var<storage, read> joint_records: array<f32>;
// Per instance: visible, culled by the frustum, culled by the backface test only.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// Per instance, `slots` entries: the visible meshlets' ids, compacted.
@group(0) @binding(4) var<storage, read_write> visible: array<u32>;
// Per meshlet: its index count and first index in the mesh's index buffer.
@group(0) @binding(5) var<storage, read> meshlet_draws: array<vec2<u32>>;
// Per instance and meshlet, DrawIndexedIndirectArgs: index count, instance count, first
// index, base vertex, first instance.
@group(0) @binding(6) var<storage, read_write> commands: array<u32>;

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

@compute @workgroup_size(64)
fn cull_draws(@builtin(global_invocation_id) gid: vec3<u32>) {
    let index = gid.y * 65535u * 64u + gid.x;
    if index >= cull_params.slots * cull_params.instances {
        return;
    }
    let instance = index / cull_params.slots;
    let s = slots[index % cull_params.slots];
    let flag = meshlet_flag(s, instance);
    let draw = meshlet_draws[s.id];
    let c = 5u * (instance * cull_params.slots + s.id);
    commands[c] = draw.x;
    commands[c + 1u] = select(0u, 1u, flag == 0u);
    commands[c + 2u] = draw.y;
    commands[c + 3u] = 0u;
    commands[c + 4u] = instance;
    if flag == 0u {
        atomicAdd(&counts[3u * instance], 1u);
    } else if (flag & 1u) != 0u {
        atomicAdd(&counts[3u * instance + 1u], 1u);
    } else {
        atomicAdd(&counts[3u * instance + 2u], 1u);
    }
}
