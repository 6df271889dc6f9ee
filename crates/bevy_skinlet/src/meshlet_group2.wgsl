// Group 2 of skinlet's meshlet draw and depth draws (meshlet_draw.rs), beyond the crowd
// skinning's bindings 0–3: what the shaders share.

struct DrawParams {
    id_bits: u32,
    // 1: drawn unculled (vertex index the corner, instance index the instance).
    unculled: u32,
    // Words of shadow bits per instance (no_shadow).
    shadow_words: u32,
    pad: u32,
}

// Per corner: bake vertex, source attribute vertex, part, 0.
@group(2) @binding(4) var<storage, read> corners: array<vec4<u32>>;
@group(2) @binding(7) var<uniform> draw: DrawParams;
// Per instance, draw.shadow_words words: bit p % 32 of word p / 32 set where part p casts no
// shadow (Bevy's NotShadowCaster on the part's entity).
@group(2) @binding(9) var<storage, read> no_shadow: array<u32>;
// Per source attribute vertex: its normal (w 0).
@group(2) @binding(5) var<storage, read> normals: array<vec4<f32>>;

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

// The world normal of `corner` (bake vertex, source vertex, part) of `instance`: its source
// vertex's normal skinned as Bevy skins normals.
fn skinned_normal(instance: u32, corner: vec4<u32>) -> vec3<f32> {
    return normalize(inverse_transpose_3x3(skin_matrix(instance, corner.x)) * normals[corner.y].xyz);
}
