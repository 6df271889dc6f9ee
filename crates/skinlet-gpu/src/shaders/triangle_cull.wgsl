// Per-triangle culling of the meshlet survivors (skinning thesis, the per-triangle stage after
// meshlet culling), after occlusion_test.wgsl and the caller's skinning WGSL (which defines
// `skinned_position(instance, vertex) -> vec3<f32>`, world space, from its bindings in group
// 1): one workgroup per survivor of crowd_cull.wgsl's list skins the meshlet's vertices once
// (into workgroup memory), then each lane takes one triangle at a time and keeps it unless it
// is certainly
// - outside one side plane of the clip volume (all three corners beyond it),
// - back-facing where the draw culls back faces (counter-clockwise front),
// - covering no pixel center,
// - or, in occlusion culling's phase 2, behind the depth pyramid;
// kept triangles go to a list of indices (instance << vertex_bits | vertex) a workgroup's
// chunk at a time (one atomic per chunk), drawn with one indexed indirect draw.
//
// Conservative against the draw: the caller's vertex shader runs the same skinning, which may
// round differently by `margin + relative × |p|` (world units) at most; the pass widens every
// corner by that and by its own projection's rounding, and every test above by what
// rasterizers do (vertices snapped to 1/16 pixel or finer). In phase 2 a survivor's visibility bit becomes whether one
// of its triangles passed every test, the pyramid's included, and its triangles are listed only
// if phase 1 did not draw it (its bit was set: crowd_cull.wgsl listed it in phase 1).

struct TriangleParams {
    // As cull_params.phase: 0 one phase, 1 and 2 occlusion culling's.
    phase: u32,
    // Triangles each list holds.
    capacity: u32,
    vertex_bits: u32,
    // bit 0: the draw culls back faces.
    flags: u32,
    width: u32,
    height: u32,
    // Survivors each of crowd_cull.wgsl's lists holds.
    survivor_capacity: u32,
    meshlets: u32,
    // How far the draw's skinned position may be from this pass's: margin + relative × |p|.
    margin: f32,
    relative: f32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> tri: TriangleParams;
@group(0) @binding(1) var<uniform> occlusion: Occlusion;
// crowd_cull.wgsl's survivors: index count, meshlet, first index, 0, instance.
@group(0) @binding(2) var<storage, read> commands: array<u32>;
// crowd_cull.wgsl's list headers (8 words each; word 1: survivors listed).
@group(0) @binding(3) var<storage, read> survivors: array<u32>;
// Visibility bits, then the depth pyramid (crowd_cull.wgsl, pyramid.wgsl).
@group(0) @binding(4) var<storage, read_write> state: array<u32>;
// The meshlets: per meshlet where its vertices start (in this array), their count, where its
// triangles start, their count; then the vertices (mesh vertex indices); then the triangles
// (local vertex indices in the low three bytes).
@group(0) @binding(5) var<storage, read> meshlet_words: array<u32>;
// Two headers of 8 words (lists A and B): DrawIndexedIndirectArgs (index count, 1, first
// index, 0, 0), triangles found, meshlets with a triangle listed, 0; then list A's indices,
// then list B's from 3 × capacity.
@group(0) @binding(6) var<storage, read_write> triangles: array<atomic<u32>>;

var<workgroup> group_kept: atomic<u32>;
var<workgroup> group_base: u32;
var<workgroup> group_seen: atomic<u32>;
// The survivor's vertices as corners (at most MAX_VERTICES).
const MAX_VERTICES: u32 = 128u;
var<workgroup> corner_clip: array<vec4<f32>, MAX_VERTICES>;
var<workgroup> corner_r: array<vec4<f32>, MAX_VERTICES>;
var<workgroup> corner_d: array<f32, MAX_VERTICES>;

// A corner: its position in clip space, how far (per world axis) the draw's skinned position
// may be from the pass's, and how far the two projections' rounding may set their clip
// coordinates apart (both products within 2^-20 of their terms' magnitude: four terms, a few
// ulps each).
struct Corner {
    clip: vec4<f32>,
    d: vec3<f32>,
    r: vec4<f32>,
}

fn corner(instance: u32, vertex: u32) -> Corner {
    let p = skinned_position(instance, vertex);
    let m = occlusion.view_proj;
    let a = mat4x4<f32>(abs(m[0]), abs(m[1]), abs(m[2]), abs(m[3]));
    let d = tri.margin + tri.relative * max(max(abs(p.x), abs(p.y)), abs(p.z));
    let r = (1.0 / 1048576.0) * (a * vec4<f32>(abs(p), 1.0));
    return Corner(m * vec4<f32>(p, 1.0), vec3<f32>(d), r);
}

// Whether all three corners are beyond the clip plane s·x ≤ w for component k (x or y) and
// sign s: s·x - w moves by at most |s·row_k - row_w|·d plus the rounding of both.
fn beyond(c: array<Corner, 3>, rows: mat4x4<f32>, k: u32, s: f32) -> bool {
    let g = abs(s * rows[k].xyz - rows[3].xyz);
    var all = true;
    for (var i = 0u; i < 3u; i++) {
        all = all && s * c[i].clip[k] - c[i].clip.w > dot(g, c[i].d) + c[i].r[k] + c[i].r.w;
    }
    return all;
}

// What the tests make of one triangle: 0 culled, 1 behind the pyramid (phase 2 only), 2
// drawn.
fn test_triangle(c: array<Corner, 3>) -> u32 {
    // The projection's rows.
    let rows = transpose(occlusion.view_proj);
    if beyond(c, rows, 0u, 1.0) || beyond(c, rows, 0u, -1.0) || beyond(c, rows, 1u, 1.0)
        || beyond(c, rows, 1u, -1.0) {
        return 0u;
    }
    // Each corner's NDC interval, the triangle's box. The draw's clip position is q + V δ + σ
    // (|δ| ≤ d per axis, σ the roundings), so its NDC coordinate k differs from q_k / q_w by
    // ((row_k - ndc_k row_w)·δ + σ_k - ndc_k σ_w) / (q_w + row_w·δ + σ_w): bounded with the
    // denominator's least value, which must be positive (else the corner may be at or behind
    // the eye's plane: no bounded screen box, drawn).
    var lo = vec3<f32>(1e30);
    var hi = vec3<f32>(-1e30);
    var mid: array<vec2<f32>, 3>;
    var half: array<f32, 3>;
    let size = vec2<f32>(f32(tri.width), f32(tri.height));
    for (var i = 0u; i < 3u; i++) {
        let q = c[i].clip;
        let d = c[i].d;
        let r = c[i].r;
        let wl = q.w - dot(abs(rows[3].xyz), d) - r.w;
        if !(wl > 1e-6 * (abs(q.x) + abs(q.y) + abs(q.z)) + 1e-30) {
            return 2u;
        }
        let ndc = q.xyz / q.w;
        let g = vec3<f32>(dot(abs(rows[0].xyz - ndc.x * rows[3].xyz), d),
            dot(abs(rows[1].xyz - ndc.y * rows[3].xyz), d), dot(abs(rows[2].xyz - ndc.z * rows[3].xyz), d));
        // (And the rounding of the division and of this bound, a few ulps.)
        let e = (g + r.xyz + abs(ndc) * r.w) / wl * (1.0 + 1e-6) + 1e-6 * abs(ndc) + 1e-30;
        lo = min(lo, ndc - e);
        hi = max(hi, ndc + e);
        // In pixels (y up: orientation kept): the middle and the half width of the interval.
        mid[i] = 0.5 * ndc.xy * size;
        half[i] = 0.5 * max(e.x * size.x, e.y * size.y);
    }
    let rect = pixel_rect(lo.xy, hi.xy, size);
    if rect_empty(rect) {
        return 0u;
    }
    if (tri.flags & 1u) != 0u {
        // Twice the signed area (counter-clockwise positive) and how far it can move when each
        // corner moves by its half width and a rasterizer's snapping (1/16 pixel).
        let a = mid[1] - mid[0];
        let b = mid[2] - mid[0];
        // (And the rounding of the middles and their differences, a few ulps of the middles.)
        let m0 = max(abs(mid[0].x), abs(mid[0].y));
        let da = half[0] + half[1] + 0.125 + 5e-7 * (m0 + max(abs(mid[1].x), abs(mid[1].y)));
        let db = half[0] + half[2] + 0.125 + 5e-7 * (m0 + max(abs(mid[2].x), abs(mid[2].y)));
        let area = a.x * b.y - a.y * b.x;
        let slack = da * (abs(b.x) + abs(b.y)) + db * (abs(a.x) + abs(a.y)) + 2.0 * da * db
            + 1e-6 * (abs(a.x * b.y) + abs(a.y * b.x));
        if area + slack < 0.0 {
            return 0u;
        }
    }
    if tri.phase == 2u && rect_behind(rect, lo.z, hi.z) {
        return 1u;
    }
    return 2u;
}

@compute @workgroup_size(64)
fn cull_triangles(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let survivor = wid.y * 65535u + wid.x;
    let phase = tri.phase;
    let list = select(0u, 1u, phase == 2u);
    if survivor >= survivors[8u * list + 1u] {
        return;
    }
    let c = 5u * (list * tri.survivor_capacity + survivor);
    let meshlet = commands[c + 1u];
    let instance = commands[c + 4u];
    let m = 4u * meshlet;
    let first_vertex = meshlet_words[m];
    let vertices = meshlet_words[m + 1u];
    let first_triangle = meshlet_words[m + 2u];
    let count = meshlet_words[m + 3u];
    let bit = instance * tri.meshlets + meshlet;
    for (var k = lane; k < vertices; k += 64u) {
        let q = corner(instance, meshlet_words[first_vertex + k]);
        corner_clip[k] = q.clip;
        corner_r[k] = q.r;
        corner_d[k] = q.d.x;
    }
    workgroupBarrier();
    // Phase 2 lists what phase 1 drew too: for its bit, not to draw it again.
    let drawn = phase == 2u && state[bit] != 0u;
    let header = 8u * list;
    let out = 16u + 3u * list * tri.capacity;
    var listed = false;
    for (var t0 = 0u; t0 < count; t0 += 64u) {
        let t = t0 + lane;
        var keep = false;
        var v: array<u32, 3>;
        if t < count {
            let local = meshlet_words[first_triangle + t];
            var k: array<Corner, 3>;
            for (var i = 0u; i < 3u; i++) {
                let l = (local >> (8u * i)) & 0xffu;
                v[i] = meshlet_words[first_vertex + l];
                k[i] = Corner(corner_clip[l], vec3<f32>(corner_d[l]), corner_r[l]);
            }
            let result = test_triangle(k);
            if result == 2u {
                atomicStore(&group_seen, 1u);
            }
            keep = select(result != 0u, result == 2u && !drawn, phase == 2u);
        }
        var place = 0u;
        if keep {
            place = atomicAdd(&group_kept, 1u);
        }
        workgroupBarrier();
        if lane == 0u {
            let n = atomicLoad(&group_kept);
            atomicStore(&group_kept, 0u);
            group_base = atomicAdd(&triangles[header + 5u], n);
            listed = listed || n > 0u;
        }
        let base = workgroupUniformLoad(&group_base);
        if keep && base + place < tri.capacity {
            let at = out + 3u * (base + place);
            for (var i = 0u; i < 3u; i++) {
                atomicStore(&triangles[at + i], (instance << tri.vertex_bits) | v[i]);
            }
        }
    }
    storageBarrier();
    workgroupBarrier();
    if lane == 0u {
        if listed {
            atomicAdd(&triangles[header + 6u], 1u);
        }
        if phase == 2u {
            state[bit] = atomicLoad(&group_seen);
        }
    }
}

// After `cull_triangles`: this phase's indexed draw, its count clamped to the list's capacity.
@compute @workgroup_size(1)
fn finish_triangles() {
    let list = select(0u, 1u, tri.phase == 2u);
    let header = 8u * list;
    atomicStore(&triangles[header], 3u * min(atomicLoad(&triangles[header + 5u]), tri.capacity));
    atomicStore(&triangles[header + 1u], 1u);
    atomicStore(&triangles[header + 2u], 3u * list * tri.capacity);
    atomicStore(&triangles[header + 3u], 0u);
    atomicStore(&triangles[header + 4u], 0u);
}
