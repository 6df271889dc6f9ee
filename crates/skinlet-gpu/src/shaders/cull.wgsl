// Per-meshlet frustum and backface culling of many instances, the CPU culling loop
// (skinlet::cull::meshlet::MeshletCuller::cull) operation for operation: one invocation per
// (instance, meshlet), per-joint values prepared on the CPU, survivors compacted per
// instance with an atomic counter.

struct Params {
    slots: u32,
    joints: u32,
    instances: u32,
    // bit 0: frustum test, bit 1: backface test, bit 2: orthographic camera.
    flags: u32,
}

struct Slot {
    center: vec3<f32>,
    radius: f32,
    axis: vec3<f32>,
    sin: f32,
    frustum_ok: u32,
    joint: u32,
    id: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
// Per instance and joint, 40 floats: 6 planes (24), their normal lengths (6), the frustum
// margin, the view (3), sign, the backface margin, the group (as bits: 0 inside, 1 outside,
// 2 straddles), padding.
@group(0) @binding(2) var<storage, read> joints: array<f32>;
// Per instance: visible, culled by the frustum, culled by the backface test only.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// Per instance, `slots` entries: the visible meshlets' ids, compacted.
@group(0) @binding(4) var<storage, read_write> visible: array<u32>;

const RECORD: u32 = 40u;

@compute @workgroup_size(64)
fn cull(@builtin(global_invocation_id) gid: vec3<u32>) {
    let index = gid.y * 65535u * 64u + gid.x;
    if index >= params.slots * params.instances {
        return;
    }
    let instance = index / params.slots;
    let s = slots[index % params.slots];
    let base = (instance * params.joints + s.joint) * RECORD;
    let do_frustum = (params.flags & 1u) != 0u;
    let do_back = (params.flags & 2u) != 0u;
    let group = bitcast<u32>(joints[base + 36u]);
    let sign = joints[base + 34u];
    var flag = 0u;
    if do_frustum && group == 1u {
        flag = s.frustum_ok;
    } else if do_frustum && group == 2u {
        var dmin = bitcast<f32>(0x7f800000u);
        for (var k = 0u; k < 6u; k++) {
            let p = base + 4u * k;
            let d = joints[p] * s.center.x + joints[p + 1u] * s.center.y + joints[p + 2u] * s.center.z + joints[p + 3u]
                + s.radius * joints[base + 24u + k];
            dmin = min(dmin, d);
        }
        flag = select(0u, 1u, dmin + joints[base + 30u] < 0.0) & s.frustum_ok;
    }
    if do_back && sign != 0.0 {
        let v = vec3<f32>(joints[base + 31u], joints[base + 32u], joints[base + 33u]);
        let bm = joints[base + 35u];
        var away: bool;
        if (params.flags & 4u) != 0u {
            away = sign * (v.x * s.axis.x + v.y * s.axis.y + v.z * s.axis.z) >= s.sin + bm;
        } else {
            let dx = s.center.x - v.x;
            let dy = s.center.y - v.y;
            let dz = s.center.z - v.z;
            let lhs = sign * (dx * s.axis.x + dy * s.axis.y + dz * s.axis.z) - s.radius * (1.0 + s.sin) - bm;
            away = (lhs >= 0.0) && (lhs * lhs >= (dx * dx + dy * dy + dz * dz) * s.sin * s.sin);
        }
        flag |= select(0u, 2u, away);
    }
    if flag == 0u {
        let k = atomicAdd(&counts[3u * instance], 1u);
        visible[instance * params.slots + k] = s.id;
    } else if (flag & 1u) != 0u {
        atomicAdd(&counts[3u * instance + 1u], 1u);
    } else {
        atomicAdd(&counts[3u * instance + 2u], 1u);
    }
}
