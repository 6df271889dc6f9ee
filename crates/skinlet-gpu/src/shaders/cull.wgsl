// Per-meshlet culling of many instances in a compute pass (after cull_common.wgsl): one
// invocation per (instance, meshlet), survivors compacted per instance with an atomic counter
// (`cull`), or compacted over the whole crowd into one list of indexed indirect draws with
// one counter (`cull_draws`, then `finish_draws`: the draw path without mesh shaders).

@group(0) @binding(0) var<uniform> cull_params: CullParams;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
@group(0) @binding(2) var<storage, read> joint_records: array<f32>;
// Per instance: visible, culled by the frustum, culled by the backface test only.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// Per instance, `slots` entries: the visible meshlets' ids, compacted.
@group(0) @binding(4) var<storage, read_write> visible: array<u32>;
// Per meshlet: its index count and first index in the mesh's index buffer.
@group(0) @binding(5) var<storage, read> meshlet_draws: array<vec2<u32>>;
// Per survivor (compacted, `cull_params.capacity` of them), DrawIndexedIndirectArgs: index
// count, instance count 1, first index, base vertex 0, first instance = the instance.
@group(0) @binding(6) var<storage, read_write> commands: array<u32>;
// The culler's any-pose boxes (cull_common.wgsl).
@group(0) @binding(7) var<storage, read> any_pose_boxes: array<u32>;
// The survivors' header: DrawIndirectArgs of the pulled draw (vertex count = the largest
// meshlet's corners, instance count = survivors drawn, 0, 0), then the survivors found (more
// than drawn when the list overflowed), written by `cull_draws` then `finish_draws`.
@group(0) @binding(8) var<storage, read_write> survivors: array<atomic<u32>>;

// This workgroup's survivors, and where they start in the list.
var<workgroup> group_survivors: atomic<u32>;
var<workgroup> group_base: u32;

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

// Survivors take places in the list a workgroup at a time: one global atomic per workgroup.
// A survivor past the capacity is counted in `survivors[4]` and not written.
@compute @workgroup_size(64)
fn cull_draws(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let index = invocation(gid);
    var t: Tested;
    var place = 0xffffffffu;
    if index < cull_params.slots * cull_params.instances {
        t = test_slot(index);
        if t.category == 0u {
            place = atomicAdd(&group_survivors, 1u);
        }
    }
    workgroupBarrier();
    if lane == 0u {
        group_base = atomicAdd(&survivors[4], atomicLoad(&group_survivors));
    }
    let base = workgroupUniformLoad(&group_base);
    if place != 0xffffffffu && base + place < cull_params.capacity {
        let draw = meshlet_draws[t.id];
        let c = 5u * (base + place);
        commands[c] = draw.x;
        commands[c + 1u] = 1u;
        commands[c + 2u] = draw.y;
        commands[c + 3u] = 0u;
        commands[c + 4u] = t.instance;
    }
}

// After `cull_draws`: the pulled draw's arguments, its instance count (and the count of the
// indexed draws) clamped to the list's capacity, so a frame draws only entries it wrote.
@compute @workgroup_size(1)
fn finish_draws() {
    atomicStore(&survivors[0], cull_params.corners);
    atomicStore(&survivors[1], min(atomicLoad(&survivors[4]), cull_params.capacity));
    atomicStore(&survivors[2], 0u);
    atomicStore(&survivors[3], 0u);
}
