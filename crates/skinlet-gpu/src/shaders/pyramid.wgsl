// The depth pyramid of two-phase occlusion culling (crowd_culling.rs): level 0 is the depth
// buffer (width × height), level k + 1 is ceil(w_k / 2) × ceil(h_k / 2) and each of its texels
// holds the farthest depth of the up to 2 × 2 texels of level k it covers (max; min for a
// reversed depth range), so a texel of level k holds the farthest depth over the pixels
// [x·2^k, (x+1)·2^k) × [y·2^k, (y+1)·2^k) of the screen. Levels are stored one after another
// in `state`, from `pyramid_base`. A multisampled depth buffer's level 0 holds each pixel's
// farthest sample. Prefixed by the declaration of `depth` and `level0` (the two variants in
// crowd_culling.rs).

struct Pyramid {
    width: u32,
    height: u32,
    // Where level 0 starts in `state` (after the visibility words).
    pyramid_base: u32,
    // 1: reversed depth (near 1, far 0: farthest is min).
    reverse: u32,
    // The level this pass writes.
    level: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> pyramid: Pyramid;
@group(0) @binding(2) var<storage, read_write> state: array<f32>;

fn level_of(k: u32) -> PyramidLevel {
    return pyramid_level_at(pyramid.pyramid_base, pyramid.width, pyramid.height, k);
}

fn farthest(a: f32, b: f32) -> f32 {
    return select(max(a, b), min(a, b), pyramid.reverse != 0u);
}

@compute @workgroup_size(8, 8)
fn reduce(@builtin(global_invocation_id) gid: vec3<u32>) {
    let out = level_of(pyramid.level);
    if gid.x >= out.width || gid.y >= out.height {
        return;
    }
    if pyramid.level == 0u {
        state[out.offset + gid.y * out.width + gid.x] = level0(vec2<i32>(gid.xy));
        return;
    }
    let src = level_of(pyramid.level - 1u);
    let x0 = 2u * gid.x;
    let y0 = 2u * gid.y;
    let x1 = min(x0 + 1u, src.width - 1u);
    let y1 = min(y0 + 1u, src.height - 1u);
    let a = farthest(state[src.offset + y0 * src.width + x0], state[src.offset + y0 * src.width + x1]);
    let b = farthest(state[src.offset + y1 * src.width + x0], state[src.offset + y1 * src.width + x1]);
    state[out.offset + gid.y * out.width + gid.x] = farthest(a, b);
}
