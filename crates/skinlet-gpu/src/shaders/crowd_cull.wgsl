// Per-meshlet culling of a crowd prepared on the GPU (prepare.wgsl), in a compute pass after
// cull_common.wgsl: one invocation per (instance, meshlet); survivors take places in one list
// of indexed indirect draws a workgroup at a time (one global atomic per workgroup), and
// `finish_draws` turns the list's header into the arguments of one draw.
//
// Phases (cull_params.phase): 0, frustum and backface; with occlusion, 1: the survivors that
// were visible last frame (list A), 2: every survivor tested against the depth pyramid of what
// was drawn so far (list B: those visible now and not drawn in phase 1; each one's visibility
// bit set to whether it is visible now). Phase 2 tests every meshlet against depth this
// frame's geometry wrote, so a meshlet with a visible fragment is drawn in phase 1 or 2
// whatever last frame's bits say (a camera cut or a teleport costs work, never a missing
// meshlet). Occlusion culling runs in rounds (cull_params.round), each over a consecutive
// range of instances (nearest first): phase 1 then phase 2 of the round, each drawn before the
// next step; past round 0, phase 1 also tests against the pyramid of the depth drawn so far.
// A phase's list then holds the round's survivors, placed after the earlier rounds' (its
// header's first instance says where they start). Depth only comes nearer within a frame, so
// a meshlet phase 1 finds behind the pyramid phase 2 finds behind it too (same test, nearer
// depth): phase 2's bit still says whether phase 1 drew it.
//
// With the triangle pass after it (cull_params.flags bit 3, triangle_cull.wgsl), an entry's
// instance count holds the meshlet's index instead (the lists are that pass's input, not
// draws), and phase 2 lists every survivor of its tests, drawn in phase 1 or not, and clears
// only the bits of those it culls: the triangle pass sets the others' from their triangles.
//
// With a cluster LOD hierarchy (GpuCharacter::with_lod) the slots hold its clusters beside the
// full-detail meshlets, and an instance tests only those of its cut (`in_cut`, the rule of
// skinlet_runtime's LodView::cut): the others are neither tested nor counted, and phase 2
// clears their visibility bits.

@group(0) @binding(0) var<uniform> cull_params: CullParams;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
// The joint records (RECORD floats per instance and joint), then per instance its LOD
// threshold, negative for full detail, then with occlusion culling per instance and joint 16
// floats: the joint's world matrix as three rows (x, y, z, t), a bound on its spectral norm,
// the occlusion mode (0 none, 1 the bounds' spheres, 2 the any-pose boxes, 3 both), the rounding
// bounds of forming it (prepare.wgsl).
@group(0) @binding(2) var<storage, read> joint_records: array<f32>;
// Per instance: visible, culled by the frustum, culled as back-facing only, occluded.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// Per meshlet: its index count and first index in the mesh's index buffer, the error of the
// LOD group that made it (negative: full detail, none made it) and of its parent group (+inf:
// none; a character without a hierarchy: every meshlet full detail without a parent).
@group(0) @binding(5) var<storage, read> meshlet_draws: array<vec4<u32>>;
// Per survivor, DrawIndexedIndirectArgs: index count, instance count 1, first index, base
// vertex 0, first instance = the instance. List A from 0, list B from `capacity`.
@group(0) @binding(6) var<storage, read_write> commands: array<u32>;
// The culler's any-pose boxes (cull_common.wgsl).
@group(0) @binding(7) var<storage, read> any_pose_boxes: array<u32>;
// The lists' headers, 8 words each (A at 0, B at 8): DrawIndirectArgs of the pulled draw
// (vertex count = the largest meshlet's corners, instance count = survivors drawn, first
// vertex 0, first instance = where they start in `commands`), the survivors found, and the
// triangle pass's workgroup counts (x, y, z).
@group(0) @binding(8) var<storage, read_write> survivors: array<atomic<u32>>;

@group(0) @binding(9) var<uniform> occlusion: Occlusion;
// Per (instance, meshlet) its visibility bit (a word) last frame, then the depth pyramid.
@group(0) @binding(10) var<storage, read_write> state: array<u32>;

// Whether meshlet `id` is in `instance`'s cut: its group's error at most the instance's
// threshold and its parent group's above it (full detail where the threshold is negative).
fn in_cut(id: u32, instance: u32) -> bool {
    let e = bitcast<vec2<f32>>(meshlet_draws[id].zw);
    let threshold = joint_records[cull_params.instances * cull_params.joints * RECORD + instance];
    if threshold < 0.0 {
        return e.x < 0.0;
    }
    // An infinite threshold draws the roots (their parents' errors are infinite).
    let t = min(threshold, 3.4028235e38);
    return e.x <= t && t < e.y;
}

// This workgroup's survivors, and where they start in the list.
var<workgroup> group_survivors: atomic<u32>;
var<workgroup> group_base: u32;

// Invocation index = y × 65535 × 64 + x (a 2D grid past 65535 groups).
fn invocation(gid: vec3<u32>) -> u32 {
    return gid.y * 65535u * 64u + gid.x;
}

// Where (instance, joint)'s world matrix starts.
fn world_of(instance: u32, joint: u32) -> u32 {
    return cull_params.instances * (cull_params.joints * RECORD + 1u) + (instance * cull_params.joints + joint) * 16u;
}

fn row(b: u32, r: u32) -> vec4<f32> {
    let k = b + 4u * r;
    return vec4<f32>(joint_records[k], joint_records[k + 1u], joint_records[k + 2u], joint_records[k + 3u]);
}

// A world-space box, lo to hi.
struct Box {
    lo: vec3<f32>,
    hi: vec3<f32>,
}

// A world box around the joint-space box `c ± h` grown by a sphere of radius `r`, moved by
// the world matrix at `b` (|G| h + r σ(G) around G c), widened for f32 rounding: of this
// product, and of G's, formed from |model|·|S|·|bind| (whose bounds prepare.wgsl stores).
fn moved_box(b: u32, c: vec3<f32>, h: vec3<f32>, r: f32) -> Box {
    let r0 = row(b, 0u);
    let r1 = row(b, 1u);
    let r2 = row(b, 2u);
    let center = vec3<f32>(dot(r0.xyz, c) + r0.w, dot(r1.xyz, c) + r1.w, dot(r2.xyz, c) + r2.w);
    let half = vec3<f32>(dot(abs(r0.xyz), h), dot(abs(r1.xyz), h), dot(abs(r2.xyz), h)) + r * joint_records[b + 12u];
    let mag = vec3<f32>(dot(abs(r0.xyz), abs(c)) + abs(r0.w), dot(abs(r1.xyz), abs(c)) + abs(r1.w),
        dot(abs(r2.xyz), abs(c)) + abs(r2.w));
    let formed = joint_records[b + 14u] * (max(max(abs(c.x), abs(c.y)), abs(c.z)) + max(max(h.x, h.y), h.z) + r)
        + joint_records[b + 15u];
    let grow = half * (1.0 + 1e-5) + 1e-5 * (mag + formed);
    return Box(center - grow, center + grow);
}

// Whether every point of the world box is behind the depth pyramid: its 8 corners projected
// (a corner at or behind the eye's plane: not occluded), then `ndc_hidden`.
fn box_occluded(bx: Box) -> bool {
    var lo = vec3<f32>(1e30);
    var hi = vec3<f32>(-1e30);
    for (var k = 0u; k < 8u; k++) {
        let p = vec3<f32>(select(bx.lo.x, bx.hi.x, (k & 1u) != 0u), select(bx.lo.y, bx.hi.y, (k & 2u) != 0u),
            select(bx.lo.z, bx.hi.z, (k & 4u) != 0u));
        let clip = occlusion.view_proj * vec4<f32>(p, 1.0);
        if !(clip.w > 1e-6 * (abs(clip.x) + abs(clip.y) + abs(clip.z)) + 1e-30) {
            return false;
        }
        let ndc = clip.xyz / clip.w;
        lo = min(lo, ndc);
        hi = max(hi, ndc);
    }
    let rect = pixel_rect(lo.xy, hi.xy, vec2<f32>(f32(occlusion.width), f32(occlusion.height)), occlusion.snap);
    return rect_empty(rect) || rect_behind(rect, lo.z, hi.z);
}

// The union of meshlet `s`'s any-pose boxes moved by their joints (a box around it for any
// pose); everything where it has none or a joint's matrix was not usable.
fn moved_boxes(s: Slot, instance: u32) -> Box {
    let everything = Box(vec3<f32>(-1e30), vec3<f32>(1e30));
    let lo = any_pose_boxes[s.id];
    let hi = any_pose_boxes[s.id + 1u];
    if lo >= hi {
        return everything;
    }
    var all = Box(vec3<f32>(1e30), vec3<f32>(-1e30));
    for (var k = lo; k < hi; k += 8u) {
        let joint = any_pose_boxes[k];
        if joint >= cull_params.joints {
            return everything;
        }
        let jb = world_of(instance, joint);
        if joint_records[jb + 13u] < 2.0 {
            return everything;
        }
        let c = vec3<f32>(bitcast<f32>(any_pose_boxes[k + 1u]), bitcast<f32>(any_pose_boxes[k + 2u]),
            bitcast<f32>(any_pose_boxes[k + 3u]));
        let h = vec3<f32>(bitcast<f32>(any_pose_boxes[k + 4u]), bitcast<f32>(any_pose_boxes[k + 5u]),
            bitcast<f32>(any_pose_boxes[k + 6u]));
        let one = moved_box(jb, c, h, 0.0);
        all = Box(min(all.lo, one.lo), max(all.hi, one.hi));
    }
    return all;
}

// Whether meshlet `s` of `instance` is hidden behind the pyramid: the box around its bounding
// sphere (the bounds' modes), the union of its moved any-pose boxes (the boxes' modes), or
// where the instance has both, their intersection (each holds the meshlet).
fn occluded(s: Slot, instance: u32) -> bool {
    let b = world_of(instance, s.joint);
    let mode = u32(joint_records[b + 13u]);
    if mode == 0u || mode > 3u {
        return false;
    }
    var bx = Box(vec3<f32>(-1e30), vec3<f32>(1e30));
    if (mode & 1u) != 0u {
        bx = moved_box(b, s.center, vec3<f32>(0.0), s.radius);
    }
    if (mode & 2u) != 0u {
        let boxes = moved_boxes(s, instance);
        bx = Box(max(bx.lo, boxes.lo), min(bx.hi, boxes.hi));
    }
    return box_occluded(bx);
}

// One (instance, slot) per invocation: the tests of this phase, the instance's counts
// (phases 0 and 2), the visibility bits (phase 2), and the survivor's place in its list.
@compute @workgroup_size(64)
fn cull_draws(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let phase = cull_params.phase;
    // This round's instances (all of them in one round or one phase).
    let round = cull_params.round & 0xffu;
    let rounds = select(max(cull_params.round >> 8u, 1u), 1u, phase == 0u);
    let first = round * cull_params.instances / rounds;
    let end = (round + 1u) * cull_params.instances / rounds;
    let index = invocation(gid) + first * cull_params.slots;
    let triangles = (cull_params.flags & 8u) != 0u;
    var instance = 0u;
    var id = 0u;
    var place = 0xffffffffu;
    if index < cull_params.slots * end {
        instance = index / cull_params.slots;
        let s = slots[index % cull_params.slots];
        id = s.id;
        let bit = instance * cull_params.slots + id;
        if !in_cut(id, instance) {
            if phase == 2u {
                state[bit] = 0u;
            }
        } else {
            let flag = meshlet_flag(s, instance);
            var category = select(select(2u, 1u, (flag & 1u) != 0u), 0u, flag == 0u);
            var survives = category == 0u;
            if phase == 1u {
                // Past round 0, against the pyramid of the depth drawn so far.
                survives = survives && state[bit] != 0u && !(round > 0u && occluded(s, instance));
            } else if phase == 2u {
                if survives && occluded(s, instance) {
                    category = 3u;
                    survives = false;
                }
                if triangles {
                    // The triangle pass sets the bits of the survivors (from their triangles) and
                    // skips drawing those phase 1 drew.
                    if !survives {
                        state[bit] = 0u;
                    }
                } else {
                    survives = survives && state[bit] == 0u;
                    state[bit] = select(0u, 1u, category == 0u);
                }
            }
            if phase != 1u {
                atomicAdd(&counts[4u * instance + category], 1u);
            }
            if survives {
                place = atomicAdd(&group_survivors, 1u);
            }
        }
    }
    let header = select(0u, 8u, phase == 2u);
    workgroupBarrier();
    if lane == 0u {
        group_base = atomicAdd(&survivors[header + 4u], atomicLoad(&group_survivors));
    }
    let base = workgroupUniformLoad(&group_base);
    if place != 0xffffffffu && base + place < cull_params.capacity {
        let draw = meshlet_draws[id];
        let c = 5u * (select(0u, cull_params.capacity, phase == 2u) + base + place);
        commands[c] = draw.x;
        commands[c + 1u] = select(1u, id, triangles);
        commands[c + 2u] = draw.y;
        commands[c + 3u] = 0u;
        commands[c + 4u] = instance;
    }
}

// After `cull_draws`: this phase's (round's) pulled draw arguments: its survivors, past the
// earlier rounds' (a first instance and count both 0: none yet), the count (also that of the
// indexed draws) clamped to the list's capacity, so a frame draws only entries it wrote; the
// triangle pass's workgroups (one per survivor, rows of at most 65535).
@compute @workgroup_size(1)
fn finish_draws() {
    let second = cull_params.phase == 2u;
    let header = select(0u, 8u, second);
    let base = select(0u, cull_params.capacity, second);
    let end = min(atomicLoad(&survivors[header + 4u]), cull_params.capacity);
    var start = 0u;
    let previous = atomicLoad(&survivors[header + 3u]);
    let count = atomicLoad(&survivors[header + 1u]);
    if previous != 0u || count != 0u {
        start = previous - base + count;
    }
    atomicStore(&survivors[header], cull_params.corners);
    atomicStore(&survivors[header + 1u], end - start);
    atomicStore(&survivors[header + 2u], 0u);
    atomicStore(&survivors[header + 3u], base + start);
    atomicStore(&survivors[header + 5u], min(end - start, 65535u));
    atomicStore(&survivors[header + 6u], (end - start + 65534u) / 65535u);
    atomicStore(&survivors[header + 7u], 1u);
}
