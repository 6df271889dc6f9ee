// Where each level of the depth pyramid lies in `state` (pyramid.wgsl writes it,
// occlusion_test.wgsl reads it): level 0 (the depth buffer, width × height) from `base`, level
// k + 1 (ceil(w_k / 2) × ceil(h_k / 2)) right after level k.

struct PyramidLevel {
    offset: u32,
    width: u32,
    height: u32,
}

fn pyramid_level_at(base: u32, width: u32, height: u32, level: u32) -> PyramidLevel {
    var l = PyramidLevel(base, width, height);
    for (var k = 0u; k < level; k++) {
        l.offset += l.width * l.height;
        l.width = (l.width + 1u) / 2u;
        l.height = (l.height + 1u) / 2u;
    }
    return l;
}
