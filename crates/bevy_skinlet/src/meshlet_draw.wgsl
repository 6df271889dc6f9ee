// skinlet's meshlet draw in Bevy's opaque pass (meshlet_draw.rs): the triangle list skinlet's
// culling wrote names (instance, corner); the corner's bake vertex is skinned by the crowd
// skinning the culling tested with (crowd_skin.wgsl, here in group 2), its normal and tangent
// come from the source primitive's vertex (welding merged hard edges away in the bake's
// vertices) and are morphed and skinned as Bevy does; the fragment shades like Bevy's
// StandardMaterial (its factors, and its base colour, metallic-roughness, emissive, occlusion
// and normal map textures where the device can index texture arrays per fragment:
// SKINLET_TEXTURES). SKINLET_TWO_SIDED: the bake has
// double-sided parts, drawn with no faces culled.

#import bevy_pbr::{
    mesh_view_bindings::view,
    pbr_types::{PbrInput, pbr_input_new, StandardMaterial, STANDARD_MATERIAL_FLAGS_DOUBLE_SIDED_BIT,
        STANDARD_MATERIAL_FLAGS_UNLIT_BIT},
    pbr_functions,
    mesh_types::MESH_FLAGS_SHADOW_RECEIVER_BIT,
    view_transformations::position_world_to_clip,
}

// Group 2's shared bindings (corners, draw, normals) are in meshlet_group2.wgsl.
// Per part: its material as Bevy uploads a StandardMaterial.
@group(2) @binding(6) var<storage, read> materials: array<StandardMaterial>;
// Per source attribute vertex: its first texture coordinates.
@group(2) @binding(8) var<storage, read> uvs: array<vec2<f32>>;

#ifdef SKINLET_TEXTURES
// The bake's distinct textures (slot 0: white) and, per part, two entries: the slots of its
// base colour, metallic-roughness, emissive and occlusion textures (0 where it has none:
// multiplying by white changes nothing, so every texture is sampled unconditionally), then
// its normal map's (0: none, not applied).
@group(3) @binding(0) var textures: binding_array<texture_2d<f32>, 16>;
@group(3) @binding(1) var samplers: binding_array<sampler, 16>;
@group(3) @binding(2) var<storage, read> texture_slots: array<vec4<u32>>;

fn sample_slot(slot: u32, uv: vec2<f32>) -> vec4<f32> {
    return textureSampleBias(textures[slot], samplers[slot], uv, view.mip_bias);
}
#endif

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) world_position: vec4<f32>,
    @location(1) world_normal: vec3<f32>,
    @location(2) @interpolate(flat) part: u32,
    @location(3) uv: vec2<f32>,
    @location(5) world_tangent: vec4<f32>,
#ifdef SKINLET_TWO_SIDED
    // 1 where the part is drawn two-sided.
    @location(4) @interpolate(flat) two_sided: u32,
#endif
}

@vertex
fn vertex(@builtin(vertex_index) index: u32, @builtin(instance_index) instance: u32) -> VertexOut {
    let entry = drawn_entry(index, instance);
    let corner = corners[entry.y];
    var out: VertexOut;
    if part_bit(entry.x, corner.z, 0u) {
        out.position = NOT_DRAWN;
        return out;
    }
    out.world_position = vec4<f32>(skinned_position(entry.x, corner.x), 1.0);
    out.position = position_world_to_clip(out.world_position.xyz);
    let m = skin_matrix(entry.x, corner.x);
    out.world_normal = skin_normal(m, morphed_attribute(entry.x, corner.y, 0u));
    out.world_tangent = skin_tangent(m, morphed_attribute(entry.x, corner.y, 1u));
    out.part = corner.z;
    out.uv = uvs[corner.y];
#ifdef SKINLET_TWO_SIDED
    out.two_sided = corner.w;
#endif
    return out;
}

@fragment
fn fragment(in: VertexOut, @builtin(front_facing) is_front: bool) -> @location(0) vec4<f32> {
#ifdef SKINLET_TWO_SIDED
    // A bake with parts drawn two-sided is drawn with no faces culled: the other parts' back
    // faces are discarded, as Bevy's pipeline culls them.
    if !is_front && in.two_sided == 0u {
        discard;
    }
#endif
    var p: PbrInput = pbr_input_new();
    p.material = materials[in.part];
    p.flags = MESH_FLAGS_SHADOW_RECEIVER_BIT;
    p.is_orthographic = view.clip_from_view[3].w == 1.0;
    p.V = pbr_functions::calculate_view(in.world_position, p.is_orthographic);
    p.frag_coord = in.position;
    p.world_position = in.world_position;
    let double_sided = (p.material.flags & STANDARD_MATERIAL_FLAGS_DOUBLE_SIDED_BIT) != 0u;
    // As Bevy's prepare_world_normal: a double-sided part's back face has its normal reversed
    // where the mesh has no tangents (else a normal map reverses it, or nothing does).
    let tangents = any(in.world_tangent != vec4<f32>(0.0));
    p.world_normal = select(
        pbr_functions::prepare_world_normal(in.world_normal, double_sided, is_front), in.world_normal, tangents);
    p.N = normalize(p.world_normal);
    p.clearcoat_N = p.N;
#ifdef SKINLET_TEXTURES
    // As Bevy's pbr_input_from_standard_material applies them.
    let uv = (p.material.uv_transform * vec3(in.uv, 1.0)).xy;
    let slots = texture_slots[2u * in.part];
    p.material.base_color *= sample_slot(slots.x, uv);
    let metallic_roughness = sample_slot(slots.y, uv);
    p.material.metallic *= metallic_roughness.b;
    p.material.perceptual_roughness *= metallic_roughness.g;
    p.material.emissive = vec4(p.material.emissive.rgb * sample_slot(slots.z, uv).rgb, p.material.emissive.a);
    p.diffuse_occlusion = vec3(sample_slot(slots.w, uv).r);
    // The normal map, where the part has one and tangents (as Bevy, with mikktspace).
    let normal_slot = texture_slots[2u * in.part + 1u].x;
    let Nt = sample_slot(normal_slot, uv).rgb;
    if normal_slot != 0u && tangents {
        let TBN = pbr_functions::calculate_tbn_mikktspace(p.world_normal, in.world_tangent);
        p.N = pbr_functions::apply_normal_mapping(p.material.flags, TBN, double_sided, is_front, Nt);
    }
#endif
    p.material.base_color = pbr_functions::alpha_discard(p.material, p.material.base_color);
    var color = p.material.base_color;
    if (p.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) == 0u {
        color = pbr_functions::apply_pbr_lighting(p);
    }
    return pbr_functions::main_pass_post_lighting_processing(p, color);
}
