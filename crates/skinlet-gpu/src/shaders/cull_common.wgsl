// The per-meshlet culling test of skinlet::cull::meshlet::MeshletCuller::cull, operation for
// operation, shared by crowd culling's compute pass (crowd_cull.wgsl) and task shaders
// (skinlet-lab's task_cull.wgsl).
// Bindings in group CULL_GROUP (set by the including module's prefix).

struct CullParams {
    slots: u32,
    joints: u32,
    instances: u32,
    // bit 0: frustum test, bit 1: backface test, bit 2: orthographic camera; crowd culling:
    // bit 3, the triangle pass follows (crowd_cull.wgsl).
    flags: u32,
    // Crowd culling's second phase: its round (low byte) and rounds (the next byte); round r of
    // R tests the instances r·n/R .. (r+1)·n/R.
    round: u32,
    // Crowd culling: how many survivors the compacted list holds, and the corners (indices)
    // of the largest meshlet (the vertex count of the pulled draw).
    capacity: u32,
    corners: u32,
    // Crowd culling: 0 one phase; occlusion culling's first phase (last frame's visible) 1,
    // second phase (the rest, against the depth pyramid) 2.
    phase: u32,
}

// The tests a pipeline is compiled with (bits as in `flags`): 3 for all, or per culling
// class (paper section 6: frustum and backface, frustum only, none); `flags` picks among them.
override CLASS_TESTS: u32 = 3u;

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

// Per instance and joint, 40 floats: 6 planes (24), their normal lengths (6), the frustum
// margin, the view (3), sign, the backface margin, the group (as bits: 0 inside, 1 outside,
// 2 straddles), the any-pose box margin (scale, offset), 1 when the any-pose boxes are tested
// (then the planes are set for every joint), else 0.
const RECORD: u32 = 40u;

// `any_pose_boxes` (declared by the including module): per meshlet (original index) the
// first word of its boxes, and after the last meshlet the end; then the boxes, 8 words each:
// joint, center (3), half extents (3), magnitude. MeshletCuller::boxes_outside, operation
// for operation: whether every box, moved by its joint, is beyond one and the same plane.
fn boxes_outside(id: u32, instance: u32) -> bool {
    let lo = any_pose_boxes[id];
    let hi = any_pose_boxes[id + 1u];
    var out = 63u;
    for (var b = lo; b < hi; b += 8u) {
        let joint = any_pose_boxes[b];
        if joint >= cull_params.joints {
            return false;
        }
        let base = (instance * cull_params.joints + joint) * RECORD;
        let cx = bitcast<f32>(any_pose_boxes[b + 1u]);
        let cy = bitcast<f32>(any_pose_boxes[b + 2u]);
        let cz = bitcast<f32>(any_pose_boxes[b + 3u]);
        let hx = bitcast<f32>(any_pose_boxes[b + 4u]);
        let hy = bitcast<f32>(any_pose_boxes[b + 5u]);
        let hz = bitcast<f32>(any_pose_boxes[b + 6u]);
        let margin = joint_records[base + 37u] * bitcast<f32>(any_pose_boxes[b + 7u]) + joint_records[base + 38u];
        for (var k = 0u; k < 6u; k++) {
            let p = base + 4u * k;
            let n0 = joint_records[p];
            let n1 = joint_records[p + 1u];
            let n2 = joint_records[p + 2u];
            let d = n0 * cx + n1 * cy + n2 * cz + joint_records[p + 3u] + (abs(n0) * hx + abs(n1) * hy + abs(n2) * hz);
            if !(d + margin < 0.0) {
                out &= ~(1u << k);
            }
        }
        if out == 0u {
            return false;
        }
    }
    return lo < hi && out != 0u;
}

// 0: visible; bit 0: outside the frustum; 2: back-facing (and not outside).
fn meshlet_flag(s: Slot, instance: u32) -> u32 {
    let base = (instance * cull_params.joints + s.joint) * RECORD;
    let do_frustum = (cull_params.flags & CLASS_TESTS & 1u) != 0u;
    let do_back = (cull_params.flags & CLASS_TESTS & 2u) != 0u;
    let group = bitcast<u32>(joint_records[base + 36u]);
    let sign = joint_records[base + 34u];
    var flag = 0u;
    if do_frustum && group == 1u {
        flag = s.frustum_ok;
    } else if do_frustum && group == 2u {
        var dmin = bitcast<f32>(0x7f800000u);
        for (var k = 0u; k < 6u; k++) {
            let p = base + 4u * k;
            let d = joint_records[p] * s.center.x + joint_records[p + 1u] * s.center.y + joint_records[p + 2u] * s.center.z
                + joint_records[p + 3u] + s.radius * joint_records[base + 24u + k];
            dmin = min(dmin, d);
        }
        flag = select(0u, 1u, dmin + joint_records[base + 30u] < 0.0) & s.frustum_ok;
    }
    if do_back && sign != 0.0 {
        let v = vec3<f32>(joint_records[base + 31u], joint_records[base + 32u], joint_records[base + 33u]);
        let bm = joint_records[base + 35u];
        var away: bool;
        if (cull_params.flags & 4u) != 0u {
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
    // The any-pose boxes, on what the bounds keep (whatever the class pipeline's tests).
    if flag == 0u && (cull_params.flags & 1u) != 0u && joint_records[base + 39u] != 0.0 && boxes_outside(s.id, instance) {
        flag = 1u;
    }
    return flag;
}
