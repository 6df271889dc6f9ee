// Group 2 of skinlet's meshlet draw and depth draws (meshlet_draw.rs), beyond the crowd
// skinning's bindings 0–3: what the shaders share.

struct DrawParams {
    id_bits: u32,
    // 1: drawn unculled (vertex index the corner, instance index the instance).
    unculled: u32,
    // Words of one bit per part (part_bits).
    part_words: u32,
    // Instance i's palette and morph weights of the frame before are instance i + previous's.
    previous: u32,
}

// Per corner: bake vertex, source attribute vertex, part, 1 where the part is drawn two-sided
// (its material culls no faces).
@group(2) @binding(4) var<storage, read> corners: array<vec4<u32>>;
@group(2) @binding(7) var<uniform> draw: DrawParams;
// Per instance, two sets of draw.part_words words: bit p % 32 of word p / 32 set where part p
// is hidden (its visibility, or its node's), then where it casts no shadow (Bevy's
// NotShadowCaster on the part's entity).
@group(2) @binding(9) var<storage, read> part_bits: array<u32>;

// Whether part p of instance i has its bit in set k (0: hidden, 1: casts no shadow).
fn part_bit(i: u32, p: u32, k: u32) -> bool {
    return ((part_bits[(2u * i + k) * draw.part_words + p / 32u] >> (p % 32u)) & 1u) != 0u;
}

// Every corner of a part not drawn: at one point outside the view (its triangles draw nothing).
const NOT_DRAWN: vec4<f32> = vec4<f32>(2.0, 2.0, 0.5, 1.0);
// The source attribute vertices' normals and tangents, and their morph deltas (the floats'
// bits): per vertex v, entry 2v its normal and where its deltas start, 2v + 1 its tangent; the
// entry after the last vertex's says where its deltas end; per delta two entries: its normal
// delta and morph weight, its tangent delta.
@group(2) @binding(5) var<storage, read> attributes: array<vec4<u32>>;

// The inverse transpose of m's 3 × 3 part, as Bevy's `inverse_transpose_3x3` skins normals.
fn inverse_transpose_3x3(m: mat4x4<f32>) -> mat3x3<f32> {
    let a = m[0].xyz;
    let b = m[1].xyz;
    let c = m[2].xyz;
    let cof = mat3x3<f32>(cross(b, c), cross(c, a), cross(a, b));
    return cof * (1.0 / dot(a, cross(b, c)));
}

// The instance and corner a vertex of the camera's draw names: the culled list's entry
// (TRIANGLES_WGSL's `triangle_entry`), or unculled, the instance and vertex indices.
fn drawn_entry(index: u32, instance: u32) -> vec2<u32> {
    if draw.unculled != 0u {
        return vec2<u32>(instance, index);
    }
    return triangle_entry(index, draw.id_bits);
}

// Source attribute vertex a's normal (k = 0) or tangent (k = 1) of `instance`, morphed as
// Bevy morphs them (the tangent's w, its sign, is not).
fn morphed_attribute(instance: u32, a: u32, k: u32) -> vec4<f32> {
    var v = bitcast<vec4<f32>>(attributes[2u * a + k]);
    for (var d = attributes[2u * a].w; d < attributes[2u * a + 2u].w; d += 2u) {
        let weight = morph_weights[instance * skin.weights + attributes[d].w];
        v += vec4<f32>(bitcast<vec3<f32>>(attributes[d + k].xyz) * weight, 0.0);
    }
    return select(v, vec4<f32>(v.xyz, 0.0), k == 0u);
}

// A normal skinned by the skinning matrix m, as Bevy skins normals.
fn skin_normal(m: mat4x4<f32>, normal: vec4<f32>) -> vec3<f32> {
    return normalize(inverse_transpose_3x3(m) * normal.xyz);
}

// A tangent skinned by m, as Bevy moves tangents to world space (a zero tangent stays zero);
// its sign follows the skinning matrix's handedness.
fn skin_tangent(m: mat4x4<f32>, tangent: vec4<f32>) -> vec4<f32> {
    if all(tangent == vec4<f32>(0.0)) {
        return tangent;
    }
    let m3 = mat3x3<f32>(m[0].xyz, m[1].xyz, m[2].xyz);
    return vec4<f32>(normalize(m3 * tangent.xyz), tangent.w * select(1.0, -1.0, determinant(m3) < 0.0));
}

