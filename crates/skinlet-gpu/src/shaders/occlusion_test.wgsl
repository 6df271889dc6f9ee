// The screen-space half of occlusion culling (after pyramid_layout.wgsl), shared by the
// meshlet test (crowd_cull.wgsl: a bounding box projected) and the triangle test
// (triangle_cull.wgsl: a triangle's corners):
// which pixel centers a rectangle in normalized device coordinates can cover, and whether
// something at its nearest depth is behind the depth pyramid (pyramid.wgsl) over them. The
// including shader declares `occlusion: Occlusion` and `state: array<u32>` (the pyramid from
// `occlusion.pyramid_base`).

struct Occlusion {
    view_proj: mat4x4<f32>,
    width: u32,
    height: u32,
    // Where the pyramid starts in `state` (pyramid.wgsl).
    pyramid_base: u32,
    // 1: reversed depth (near 1, far 0).
    reverse: u32,
    levels: u32,
    // The rasterizer's vertex snapping: 2^-subpixel bits, in pixels.
    snap: f32,
    pad1: u32,
    pad2: u32,
}

// The pixels (first x, first y, last x, last y, inclusive) whose centers lie in the NDC
// rectangle lo..hi widened by `snap` pixels, on a `size` screen: rasterizers snap vertices to
// their sub-pixel grid (`snap`, 1/16 pixel or finer), and a fragment is a pixel center a
// triangle covers. NDC y is up, pixel rows down; pixel i's center is at i + 0.5.
fn pixel_rect(lo: vec2<f32>, hi: vec2<f32>, size: vec2<f32>, snap: f32) -> vec4<f32> {
    let e = 0.5 + snap;
    let first = ceil(vec2<f32>((lo.x * 0.5 + 0.5) * size.x, (0.5 - hi.y * 0.5) * size.y) - e);
    let last = floor(vec2<f32>((hi.x * 0.5 + 0.5) * size.x, (0.5 - lo.y * 0.5) * size.y) - 0.5 + snap);
    return vec4<f32>(max(first, vec2<f32>(0.0)), min(last, size - 1.0));
}

// Whether `pixel_rect` found no pixel center on screen (what lies there draws nothing).
fn rect_empty(r: vec4<f32>) -> bool {
    return !(r.x <= r.z && r.y <= r.w);
}

// The level at which the pixels x0..=x1, y0..=y1 span at most 8 × 8 blocks of 2^level × 2^level
// pixels (the pyramid's texels at that level).
fn block_level(x0: u32, y0: u32, x1: u32, y1: u32) -> u32 {
    var level = 0u;
    while level < 31u && ((x1 >> level) - (x0 >> level) > 7u || (y1 >> level) - (y0 >> level) > 7u) {
        level += 1u;
    }
    return level;
}

fn pyramid_level(level: u32) -> PyramidLevel {
    return pyramid_level_at(occlusion.pyramid_base, occlusion.width, occlusion.height, level);
}

// The farthest depth over the pixels of texel (x, y) of level `l`.
fn texel_far(l: PyramidLevel, x: u32, y: u32) -> f32 {
    return bitcast<f32>(state[l.offset + min(y, l.height - 1u) * l.width + min(x, l.width - 1u)]);
}

// Whether depths from lo_z to hi_z (NDC) over the pixels of the non-empty rectangle `r` are
// all behind the pyramid: the nearest (lo_z; hi_z reversed), a few ulps nearer for rounding,
// against the farthest depth over those pixels at the level where they span at most 8 × 8
// texels (a fragment's depth is interpolated between its triangle's corners', so no nearer
// than their nearest).
fn rect_behind(r: vec4<f32>, lo_z: f32, hi_z: f32) -> bool {
    let x0 = u32(r.x);
    let y0 = u32(r.y);
    let x1 = u32(r.z);
    let y1 = u32(r.w);
    let level = min(block_level(x0, y0, x1, y1), occlusion.levels - 1u);
    let l = pyramid_level(level);
    let reverse = occlusion.reverse != 0u;
    var far = select(0.0, 1.0, reverse);
    for (var y = y0 >> level; y <= y1 >> level; y++) {
        for (var x = x0 >> level; x <= x1 >> level; x++) {
            let d = texel_far(l, x, y);
            far = select(max(far, d), min(far, d), reverse);
        }
    }
    return behind(far, lo_z, hi_z);
}

// Whether depths from lo_z to hi_z are all behind the depth `far`.
fn behind(far: f32, lo_z: f32, hi_z: f32) -> bool {
    if occlusion.reverse != 0u {
        return hi_z * (1.0 + 4e-7) + 1e-7 < far;
    }
    return lo_z * (1.0 - 4e-7) - 1e-7 > far;
}
