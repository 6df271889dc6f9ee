// The parts' materials as skinlet's meshlet draw and its normal prepass read them
// (meshlet_draw.rs): Bevy's StandardMaterial per part, the source vertices' texture
// coordinates, the bake's textures (SKINLET_TEXTURES, group 3), and a fragment's normal as
// Bevy computes it from the interpolated normal and tangent and the part's normal map.

#import bevy_pbr::pbr_types::{StandardMaterial, STANDARD_MATERIAL_FLAGS_DOUBLE_SIDED_BIT,
    STANDARD_MATERIAL_FLAGS_TWO_COMPONENT_NORMAL_MAP, STANDARD_MATERIAL_FLAGS_FLIP_NORMAL_MAP_Y}

// Per part: its material as Bevy uploads a StandardMaterial.
@group(2) @binding(6) var<storage, read> materials: array<StandardMaterial>;
// Per source attribute vertex: its first and second texture coordinates (the second: the
// first where the mesh has none, as Bevy samples them).
@group(2) @binding(8) var<storage, read> uvs: array<vec4<f32>>;

#ifdef SKINLET_TEXTURES
// The bake's distinct textures (slot 0: white) and, per part, two entries: the slots of its
// base colour, metallic-roughness, emissive and occlusion textures (0 where it has none:
// multiplying by white changes nothing, so every texture is sampled unconditionally), then
// its normal map's (0: none, not applied) and which of the five its material samples at the
// second texture coordinates (bit k: the k-th, in that order).
@group(3) @binding(0) var textures: binding_array<texture_2d<f32>, 16>;
@group(3) @binding(1) var samplers: binding_array<sampler, 16>;
@group(3) @binding(2) var<storage, read> texture_slots: array<vec4<u32>>;

// Slot `slot`'s texture at `uv`, with the view's mip bias.
fn sample_slot(slot: u32, uv: vec2<f32>, mip_bias: f32) -> vec4<f32> {
    return textureSampleBias(textures[slot], samplers[slot], uv, mip_bias);
}

// The coordinates of the part's `k`-th texture (as in texture_slots) among both sets `uv`.
fn texture_uv(part: u32, k: u32, uv: vec4<f32>) -> vec2<f32> {
    return select(uv.xy, uv.zw, ((texture_slots[2u * part + 1u].y >> k) & 1u) != 0u);
}
#endif

// Both sets of texture coordinates as interpolated, with the material's transform applied
// (Bevy applies it to both).
fn material_uvs(m: StandardMaterial, uv: vec4<f32>) -> vec4<f32> {
    return vec4<f32>((m.uv_transform * vec3(uv.xy, 1.0)).xy, (m.uv_transform * vec3(uv.zw, 1.0)).xy);
}

// A fragment's normal: `world` as Bevy's prepare_world_normal leaves the interpolated normal
// (a double-sided part's back face reversed, unless the mesh has tangents: then the normal
// map reverses it, or nothing does), `mapped` where the part's normal map applies (`is_mapped`).
struct FragmentNormal {
    world: vec3<f32>,
    mapped: vec3<f32>,
    is_mapped: bool,
}

// `normal` and `tangent` as interpolated, `uv` both sets of texture coordinates
// (`material_uvs`), the view's mip bias; samples the normal map unconditionally (uniform
// control flow).
fn fragment_normal(m: StandardMaterial, part: u32, uv: vec4<f32>, normal: vec3<f32>, tangent: vec4<f32>,
    is_front: bool, mip_bias: f32) -> FragmentNormal {
    let double_sided = (m.flags & STANDARD_MATERIAL_FLAGS_DOUBLE_SIDED_BIT) != 0u;
    let tangents = any(tangent != vec4<f32>(0.0));
    var out: FragmentNormal;
    out.world = select(normal, -normal, double_sided && !is_front && !tangents);
    out.mapped = out.world;
    out.is_mapped = false;
#ifdef SKINLET_TEXTURES
    let slot = texture_slots[2u * part + 1u].x;
    // The map's tangent-space normal: two components (z from x and y) or three, y flipped for
    // maps authored for DirectX, reversed on a double-sided back face; then mikktspace's frame
    // (the interpolated normal and tangent, not normalized: as mikktspace bakes them).
    let rgb = sample_slot(slot, texture_uv(part, 4u, uv), mip_bias).rgb;
    var t = rgb * 2.0 - 1.0;
    if (m.flags & STANDARD_MATERIAL_FLAGS_TWO_COMPONENT_NORMAL_MAP) != 0u {
        t = vec3<f32>(t.xy, sqrt(1.0 - t.x * t.x - t.y * t.y));
    }
    if (m.flags & STANDARD_MATERIAL_FLAGS_FLIP_NORMAL_MAP_Y) != 0u {
        t.y = -t.y;
    }
    if double_sided && !is_front {
        t = -t;
    }
    if slot != 0u && tangents {
        let bitangent = tangent.w * cross(out.world, tangent.xyz);
        out.mapped = normalize(t.x * tangent.xyz + t.y * bitangent + t.z * out.world);
        out.is_mapped = true;
    }
#endif
    return out;
}
