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
    pbr_types::{PbrInput, pbr_input_new, STANDARD_MATERIAL_FLAGS_UNLIT_BIT},
    pbr_functions,
    mesh_types::MESH_FLAGS_SHADOW_RECEIVER_BIT,
    view_transformations::position_world_to_clip,
}

// Group 2's shared bindings (corners, draw, attributes) are in meshlet_group2.wgsl, the
// materials, texture coordinates and textures in meshlet_materials.wgsl.

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) world_position: vec4<f32>,
    @location(1) world_normal: vec3<f32>,
    @location(2) @interpolate(flat) part: u32,
    @location(3) uv: vec4<f32>,
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
    let uv = material_uvs(p.material, in.uv);
    let normal = fragment_normal(p.material, in.part, uv, in.world_normal, in.world_tangent, is_front, view.mip_bias);
    p.world_normal = normal.world;
    p.N = normalize(p.world_normal);
    p.clearcoat_N = p.N;
    if normal.is_mapped {
        p.N = normal.mapped;
    }
#ifdef SKINLET_TEXTURES
    // As Bevy's pbr_input_from_standard_material applies them.
    let slots = texture_slots[2u * in.part];
    p.material.base_color *= sample_slot(slots.x, texture_uv(in.part, 0u, uv), view.mip_bias);
    let metallic_roughness = sample_slot(slots.y, texture_uv(in.part, 1u, uv), view.mip_bias);
    p.material.metallic *= metallic_roughness.b;
    p.material.perceptual_roughness *= metallic_roughness.g;
    let emissive = sample_slot(slots.z, texture_uv(in.part, 2u, uv), view.mip_bias).rgb;
    p.material.emissive = vec4(p.material.emissive.rgb * emissive, p.material.emissive.a);
    p.diffuse_occlusion = vec3(sample_slot(slots.w, texture_uv(in.part, 3u, uv), view.mip_bias).r);
#endif
    p.material.base_color = pbr_functions::alpha_discard(p.material, p.material.base_color);
    var color = p.material.base_color;
    if (p.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) == 0u {
        color = pbr_functions::apply_pbr_lighting(p);
    }
    return pbr_functions::main_pass_post_lighting_processing(p, color);
}
