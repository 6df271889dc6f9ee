// Per-triangle culling of the meshlet survivors (skinning thesis, the per-triangle stage after
// meshlet culling), after occlusion_test.wgsl and the caller's skinning WGSL (which defines
// `skinned_position(instance, vertex) -> vec3<f32>`, world space, from its bindings in group
// 1): one workgroup per survivor of crowd_cull.wgsl's list skins the meshlet's vertices once
// (into workgroup memory), then each lane takes one triangle at a time and keeps it unless it
// is certainly
// - outside one side plane of the clip volume (all three corners beyond it),
// - back-facing where the draw culls back faces (counter-clockwise front),
// - covering no pixel center (its box, then block by block of pixels by its edges),
// - or, in occlusion culling's phase 2 and in phase 1 past round 0, behind the depth pyramid
//   at every block of pixels where it may cover a center (single pixels for a triangle a few
//   pixels wide);
// kept triangles go to a list of indices (instance << id_bits | id, the id the mesh vertex or
// the corner 3·i + k of MLET's triangle i) a workgroup's chunk at a time (one atomic per chunk), drawn with one indexed indirect draw.
//
// Conservative against the draw: the caller's vertex shader runs the same skinning, which may
// round differently by `margin + relative × |p|` (world units) at most; the pass widens every
// corner by that, by its own projection's rounding and by the rasterizer's vertex snapping
// (`snap`: its sub-pixel grid).
//
// Visibility bits (what the first phase of the next frame draws; a choice, not a bound): in
// phase 2 a survivor's bit becomes whether one of its triangles looks visible: kept, and, a
// few pixels wide, covering a pixel center where its depth (as this pass computes it) is not
// behind the depth buffer (larger ones: kept). Its triangles are listed only if phase 1 did not draw it (its bit
// was set: crowd_cull.wgsl listed it in phase 1).

struct TriangleParams {
    // As cull_params.phase: 0 one phase, 1 and 2 occlusion culling's.
    phase: u32,
    // Triangles each list holds.
    capacity: u32,
    id_bits: u32,
    // bit 0: the draw culls back faces; bit 1: the lists name corners (else vertices); bit 2:
    // tested against the pyramid (phase 2 always).
    flags: u32,
    width: u32,
    height: u32,
    // Survivors each of crowd_cull.wgsl's lists holds.
    survivor_capacity: u32,
    meshlets: u32,
    // How far the draw's skinned position may be from this pass's: margin + relative × |p|.
    margin: f32,
    relative: f32,
    // The draw's vertex snapping: 2^-subpixel bits, in pixels.
    snap: f32,
    // Where MLET's triangle 0 is in `meshlet_words` (triangle i at triangle_base + i).
    triangle_base: u32,
}

@group(0) @binding(0) var<uniform> tri: TriangleParams;
@group(0) @binding(1) var<uniform> occlusion: Occlusion;
// crowd_cull.wgsl's survivors: index count, meshlet, first index, 0, instance.
@group(0) @binding(2) var<storage, read> commands: array<u32>;
// crowd_cull.wgsl's list headers (8 words each; word 1: survivors listed, word 3: where they
// start in `commands`).
@group(0) @binding(3) var<storage, read> survivors: array<u32>;
// Visibility bits, then the depth pyramid (crowd_cull.wgsl, pyramid.wgsl).
@group(0) @binding(4) var<storage, read_write> state: array<u32>;
// The meshlets: per meshlet where its vertices start (in this array), their count (the top bit
// set where the draw shows its back faces), where its triangles start, their count; then the vertices (mesh vertex indices); then, from
// triangle_base in MLET's order, the triangles (local vertex indices in the low three bytes).
@group(0) @binding(5) var<storage, read> meshlet_words: array<u32>;
// Two headers of 8 words (lists A and B): DrawIndexedIndirectArgs (index count, 1, first
// index, 0, 0: this phase's or round's triangles, past the earlier rounds'), triangles found,
// meshlets with a triangle listed (both over every round), 0; then list A's indices, then list
// B's from 3 × capacity.
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

// What the tests make of one triangle.
const CULLED: u32 = 0u;
// Behind the pyramid (when tested against it).
const BEHIND: u32 = 1u;
// Drawn, and (tested) no pixel where it looks visible.
const UNSEEN: u32 = 2u;
// Drawn, and (tested) a pixel where it looks visible, or too big to look at pixel by pixel.
const SEEN: u32 = 3u;

// Whether this pass tests against the depth pyramid.
fn tested() -> bool {
    return tri.phase == 2u || (tri.flags & 4u) != 0u;
}

// `two_sided`: the draw shows the triangle's back face (a double-sided material).
fn test_triangle(c: array<Corner, 3>, two_sided: bool) -> u32 {
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
    var z: vec3<f32>;
    var half: array<f32, 3>;
    let size = vec2<f32>(f32(tri.width), f32(tri.height));
    for (var i = 0u; i < 3u; i++) {
        let q = c[i].clip;
        let d = c[i].d;
        let r = c[i].r;
        let wl = q.w - dot(abs(rows[3].xyz), d) - r.w;
        if !(wl > 1e-6 * (abs(q.x) + abs(q.y) + abs(q.z)) + 1e-30) {
            return SEEN;
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
        z[i] = ndc.z;
        half[i] = 0.5 * max(e.x * size.x, e.y * size.y);
    }
    let rect = pixel_rect(lo.xy, hi.xy, size, tri.snap);
    if rect_empty(rect) {
        return CULLED;
    }
    // Twice the signed area (counter-clockwise positive) and how far it can move when each
    // corner moves by its half width and the rasterizer's snapping.
    let a = mid[1] - mid[0];
    let b = mid[2] - mid[0];
    // (And the rounding of the middles and their differences, a few ulps of the middles.)
    let m0 = max(abs(mid[0].x), abs(mid[0].y));
    let da = half[0] + half[1] + 2.0 * tri.snap + 5e-7 * (m0 + max(abs(mid[1].x), abs(mid[1].y)));
    let db = half[0] + half[2] + 2.0 * tri.snap + 5e-7 * (m0 + max(abs(mid[2].x), abs(mid[2].y)));
    let area = a.x * b.y - a.y * b.x;
    let slack = da * (abs(b.x) + abs(b.y)) + db * (abs(a.x) + abs(a.y)) + 2.0 * da * db
        + 1e-6 * (abs(a.x * b.y) + abs(a.y * b.x));
    let cull_back = (tri.flags & 1u) != 0u && !two_sided;
    if cull_back && area + slack < 0.0 {
        return CULLED;
    }
    // Its orientation as drawn: 1 counter-clockwise (all the draw keeps when it culls back
    // faces), -1 clockwise, 0 either.
    let orient = select(select(select(0.0, -1.0, area + slack < 0.0), 1.0, area - slack > 0.0), 1.0, cull_back);
    // Which pixel centers the drawn triangle may cover, block by block of the level where its
    // rectangle spans at most 8 × 8 blocks (single pixels for a triangle a few pixels wide),
    // and (tested) whether one of them is not behind the depth pyramid's texel there.
    let x0 = u32(rect.x);
    let y0 = u32(rect.y);
    let x1 = u32(rect.z);
    let y1 = u32(rect.w);
    var level = block_level(x0, y0, x1, y1);
    if tested() {
        level = min(level, occlusion.levels - 1u);
    }
    let pyramid = pyramid_level(level);
    var covered = false;
    var drawn = false;
    for (var ty = y0 >> level; ty <= y1 >> level; ty++) {
        for (var tx = x0 >> level; tx <= x1 >> level; tx++) {
            // The block's pixels in the rectangle, and their centers' extremes (y up).
            let bx = vec2<u32>(max(tx << level, x0), min(((tx + 1u) << level) - 1u, x1));
            let by = vec2<u32>(max(ty << level, y0), min(((ty + 1u) << level) - 1u, y1));
            let low = vec2<f32>(f32(bx.x) + 0.5 - 0.5 * size.x, 0.5 * size.y - f32(by.y) - 0.5);
            let high = vec2<f32>(f32(bx.y) + 0.5 - 0.5 * size.x, 0.5 * size.y - f32(by.x) - 0.5);
            if may_cover(mid, half, orient, low, high) {
                if !tested() {
                    return SEEN;
                }
                covered = true;
                let far = texel_far(pyramid, tx, ty);
                if !behind(far, lo.z, hi.z) {
                    drawn = true;
                    if level > 0u || looks_visible(mid, z, low, far) {
                        return SEEN;
                    }
                }
            }
        }
    }
    return select(select(CULLED, BEHIND, covered), UNSEEN, drawn);
}

// Whether the triangle as this pass computed it (corners at mid, NDC depths z) covers the
// pixel center p and is there at most a few ulps behind `buffer`, the depth buffer's: the
// visibility bit's test (what the first phase of the next frame draws), not a bound.
fn looks_visible(mid: array<vec2<f32>, 3>, z: vec3<f32>, p: vec2<f32>, buffer: f32) -> bool {
    var w: vec3<f32>;
    for (var i = 0u; i < 3u; i++) {
        let e = mid[(i + 2u) % 3u] - mid[(i + 1u) % 3u];
        let f = p - mid[(i + 1u) % 3u];
        w[i] = e.x * f.y - e.y * f.x;
    }
    let sum = w.x + w.y + w.z;
    if sum == 0.0 || any(w * sign(sum) < vec3<f32>(0.0)) {
        return false;
    }
    let depth = dot(w, z) / sum;
    let tolerance = 1e-5 * max(abs(depth), abs(buffer));
    if occlusion.reverse != 0u {
        return depth >= buffer - tolerance;
    }
    return depth <= buffer + tolerance;
}

// Whether the drawn triangle may cover a pixel center in the box low..high (pixels from the
// screen's center, y up), its corners within half[i] of mid[i] (per axis) and the
// rasterizer's snapping, of orientation `orient` (1 counter-clockwise, -1 clockwise, 0 either)
// whatever they are. A point is inside a counter-clockwise triangle when no edge function
// (b - a) × (p - a) is negative, inside a clockwise one when none is positive; so the box is
// certainly uncovered when one edge function is negative (counter-clockwise), positive
// (clockwise), or one each (either) over the whole box however the corners move: by at most
// (h_a + h_b)·|p - a|₁ + h_a·|b - a|₁ + 2 (h_a + h_b) h_a when a and b move by h_a and h_b (and
// by its rounding: the differences' as a few ulps more on each h, the products' relative).
// The edge function is linear and that bound convex in p, so their sum is largest (their
// difference least) at a corner of the box.
fn may_cover(mid: array<vec2<f32>, 3>, half: array<f32, 3>, orient: f32, low: vec2<f32>, high: vec2<f32>) -> bool {
    let far = max(max(abs(low.x), abs(low.y)), max(abs(high.x), abs(high.y)));
    let ulps = 5e-7 * (far + max(max(max(abs(mid[0].x), abs(mid[0].y)),
        max(abs(mid[1].x), abs(mid[1].y))), max(abs(mid[2].x), abs(mid[2].y))));
    let corners = array<vec2<f32>, 4>(low, vec2<f32>(high.x, low.y), vec2<f32>(low.x, high.y), high);
    var negative = false;
    var positive = false;
    for (var i = 0u; i < 3u; i++) {
        let j = (i + 1u) % 3u;
        let e = mid[j] - mid[i];
        let ha = half[i] + tri.snap + ulps;
        let hb = half[j] + tri.snap + ulps;
        let l1e = abs(e.x) + abs(e.y);
        var most = -1e30;
        var least = 1e30;
        for (var c = 0u; c < 4u; c++) {
            let f = corners[c] - mid[i];
            let edge = e.x * f.y - e.y * f.x;
            let l1f = abs(f.x) + abs(f.y);
            let moved = (ha + hb) * l1f + ha * l1e + 2.0 * (ha + hb) * ha + 1e-6 * l1e * l1f;
            most = max(most, edge + moved);
            least = min(least, edge - moved);
        }
        negative = negative || most < 0.0;
        positive = positive || least > 0.0;
    }
    if orient > 0.0 {
        return !negative;
    }
    if orient < 0.0 {
        return !positive;
    }
    return !(negative && positive);
}

@compute @workgroup_size(64)
fn cull_triangles(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let survivor = wid.y * 65535u + wid.x;
    let phase = tri.phase;
    let list = select(0u, 1u, phase == 2u);
    // This phase's (round's) survivors.
    if survivor >= survivors[8u * list + 1u] {
        return;
    }
    let c = 5u * (survivors[8u * list + 3u] + survivor);
    let meshlet = commands[c + 1u];
    let instance = commands[c + 4u];
    let m = 4u * meshlet;
    let first_vertex = meshlet_words[m];
    // (The top bit: the meshlet is drawn two-sided.)
    let vertices = meshlet_words[m + 1u] & 0xffffu;
    let two_sided = (meshlet_words[m + 1u] >> 31u) != 0u;
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
            let corners = (tri.flags & 2u) != 0u;
            for (var i = 0u; i < 3u; i++) {
                let l = (local >> (8u * i)) & 0xffu;
                v[i] = select(meshlet_words[first_vertex + l], 3u * (first_triangle + t - tri.triangle_base) + i, corners);
                k[i] = Corner(corner_clip[l], vec3<f32>(corner_d[l]), corner_r[l]);
            }
            let result = test_triangle(k, two_sided);
            if result == SEEN {
                atomicStore(&group_seen, 1u);
            }
            keep = result >= UNSEEN && !drawn;
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
                atomicStore(&triangles[at + i], (instance << tri.id_bits) | v[i]);
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

// After `cull_triangles`: this phase's (round's) indexed draw, its triangles past the earlier
// rounds' (a first index and count both 0: none yet), clamped to the list's capacity.
@compute @workgroup_size(1)
fn finish_triangles() {
    let list = select(0u, 1u, tri.phase == 2u);
    let header = 8u * list;
    let end = min(atomicLoad(&triangles[header + 5u]), tri.capacity);
    var start = 0u;
    let previous = atomicLoad(&triangles[header + 2u]);
    let count = atomicLoad(&triangles[header]);
    if previous != 0u || count != 0u {
        start = previous / 3u - list * tri.capacity + count / 3u;
    }
    atomicStore(&triangles[header], 3u * (end - start));
    atomicStore(&triangles[header + 1u], 1u);
    atomicStore(&triangles[header + 2u], 3u * (list * tri.capacity + start));
    atomicStore(&triangles[header + 3u], 0u);
    atomicStore(&triangles[header + 4u], 0u);
}

// After the last round: each list's draw over its triangles of every round (from the list's
// start, clamped to its capacity), for draws of the whole frame's survivors.
@compute @workgroup_size(1)
fn whole_lists() {
    for (var list = 0u; list < 2u; list++) {
        let header = 8u * list;
        atomicStore(&triangles[header], 3u * min(atomicLoad(&triangles[header + 5u]), tri.capacity));
        atomicStore(&triangles[header + 1u], 1u);
        atomicStore(&triangles[header + 2u], 3u * list * tri.capacity);
        atomicStore(&triangles[header + 3u], 0u);
        atomicStore(&triangles[header + 4u], 0u);
    }
}
