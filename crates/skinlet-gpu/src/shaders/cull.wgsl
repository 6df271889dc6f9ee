// Per-meshlet culling of many instances prepared on the CPU, in a compute pass (after
// cull_common.wgsl): one invocation per (instance, meshlet), survivors compacted per instance
// with an atomic counter. (GPU-prepared crowds: crowd_cull.wgsl.)

@group(0) @binding(0) var<uniform> cull_params: CullParams;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
@group(0) @binding(2) var<storage, read> joint_records: array<f32>;
// Per instance: visible, culled by the frustum, culled by the backface test only.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// Per instance, `slots` entries: the visible meshlets' ids, compacted.
@group(0) @binding(4) var<storage, read_write> visible: array<u32>;
// The culler's any-pose boxes (cull_common.wgsl).
@group(0) @binding(7) var<storage, read> any_pose_boxes: array<u32>;

// What testing one (instance, slot) gave: the meshlet, its category (0 visible, 1 culled by
// the frustum, 2 culled as back-facing only) and how many of that category the instance had
// before it (the visible one's place in the compacted list).
struct Tested {
    instance: u32,
    id: u32,
    category: u32,
    before: u32,
}

// Tests and counts (instance, slot) number `index` (instance × slots + slot).
fn test_slot(index: u32) -> Tested {
    var t: Tested;
    t.instance = index / cull_params.slots;
    let s = slots[index % cull_params.slots];
    let flag = meshlet_flag(s, t.instance);
    t.id = s.id;
    t.category = select(select(2u, 1u, (flag & 1u) != 0u), 0u, flag == 0u);
    t.before = atomicAdd(&counts[3u * t.instance + t.category], 1u);
    return t;
}

// Invocation index = y × 65535 × 64 + x (cull.rs dispatches a 2D grid past 65535 groups).
fn invocation(gid: vec3<u32>) -> u32 {
    return gid.y * 65535u * 64u + gid.x;
}

@compute @workgroup_size(64)
fn cull(@builtin(global_invocation_id) gid: vec3<u32>) {
    let index = invocation(gid);
    if index >= cull_params.slots * cull_params.instances {
        return;
    }
    let t = test_slot(index);
    if t.category == 0u {
        visible[t.instance * cull_params.slots + t.before] = t.id;
    }
}
