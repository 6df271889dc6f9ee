// skinlet's meshlet draw in Bevy's depth-only views (meshlet_draw.rs), with Bevy's prepass view
// bindings: the shadow views (each view's own culled list) and the camera's prepass (the culled list, as the main pass draws it; the normals and motion
// vectors where the camera has those prepasses, written as Bevy's prepass writes them). Both
// skin with the crowd skinning (group 2) as the main pass does; the motion vectors' previous
// positions skin with the frame before's palettes and weights (instance + draw.previous).

#import bevy_render::view::View

@group(0) @binding(0) var<uniform> view: View;
#ifdef MOTION_VECTOR_PREPASS
#import bevy_pbr::prepass_bindings::previous_view_uniforms
#endif
// Group 2's corners, draw, attributes and part bits are in meshlet_group2.wgsl.

struct DepthOut {
    @builtin(position) position: vec4<f32>,
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @location(0) unclipped_depth: f32,
#endif
#ifdef NORMAL_PREPASS
    @location(1) world_normal: vec3<f32>,
    @location(5) world_tangent: vec4<f32>,
    @location(6) uv: vec4<f32>,
    @location(7) @interpolate(flat) part: u32,
#endif
#ifdef SKINLET_TWO_SIDED
    // 1 where the part is drawn two-sided (the others' back faces are discarded).
    @location(2) @interpolate(flat) two_sided: u32,
#endif
#ifdef MOTION_VECTOR_PREPASS
    @location(3) world_position: vec4<f32>,
    @location(4) previous_world_position: vec4<f32>,
#endif
}

@vertex
fn shadow_vertex(@builtin(vertex_index) index: u32, @builtin(instance_index) instance: u32) -> DepthOut {
    var out: DepthOut;
    // (The shadow view's culled list, or unculled every corner of every instance.)
    let entry = drawn_entry(index, instance);
    let corner = corners[entry.y];
    if part_bit(entry.x, corner.z, 0u) || part_bit(entry.x, corner.z, 1u) {
        out.position = NOT_DRAWN;
        return out;
    }
    out.position = view.clip_from_world * vec4<f32>(skinned_position(entry.x, corner.x), 1.0);
#ifdef SKINLET_TWO_SIDED
    out.two_sided = corner.w;
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    // A directional light's casters in front of its near plane, clamped to it (as Bevy does).
    out.unclipped_depth = out.position.z;
    out.position.z = min(out.position.z, 1.0);
#endif
    return out;
}

@vertex
fn prepass_vertex(@builtin(vertex_index) index: u32, @builtin(instance_index) instance: u32) -> DepthOut {
    let entry = drawn_entry(index, instance);
    let corner = corners[entry.y];
    var out: DepthOut;
    if part_bit(entry.x, corner.z, 0u) {
        out.position = NOT_DRAWN;
        return out;
    }
    let world = vec4<f32>(skinned_position(entry.x, corner.x), 1.0);
    out.position = view.clip_from_world * world;
#ifdef MOTION_VECTOR_PREPASS
    out.world_position = world;
    out.previous_world_position = vec4<f32>(skinned_position(entry.x + draw.previous, corner.x), 1.0);
#endif
#ifdef NORMAL_PREPASS
    let m = skin_matrix(entry.x, corner.x);
    out.world_normal = skin_normal(m, morphed_attribute(entry.x, corner.y, 0u));
    out.world_tangent = skin_tangent(m, morphed_attribute(entry.x, corner.y, 1u));
    out.uv = uvs[corner.y];
    out.part = corner.z;
#endif
#ifdef SKINLET_TWO_SIDED
    out.two_sided = corner.w;
#endif
    return out;
}

// Whether the fragment is a back face of a part drawn one-sided (SKINLET_TWO_SIDED: drawn with
// no faces culled).
fn culled_face(in: DepthOut, is_front: bool) -> bool {
#ifdef SKINLET_TWO_SIDED
    return !is_front && in.two_sided == 0u;
#else
    return false;
#endif
}

// (DEPTH_FRAGMENT_OUTPUT: the normal, the motion vector or the depth written; else nothing.)
#ifdef DEPTH_FRAGMENT_OUTPUT
struct DepthFragment {
#ifdef NORMAL_PREPASS
    @location(0) normal: vec4<f32>,
#endif
#ifdef MOTION_VECTOR_PREPASS
    @location(1) motion_vector: vec2<f32>,
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @builtin(frag_depth) depth: f32,
#endif
}

@fragment
fn depth_fragment(in: DepthOut, @builtin(front_facing) is_front: bool) -> DepthFragment {
    if culled_face(in, is_front) {
        discard;
    }
    var out: DepthFragment;
#ifdef NORMAL_PREPASS
    // As Bevy's prepass writes a lit material's world normal (the interpolated one, not
    // normalized again, or the normal map's): into 0..1.
    let m = materials[in.part];
    let uv = material_uvs(m, in.uv);
    let n = fragment_normal(m, in.part, uv, in.world_normal, in.world_tangent, is_front, view.mip_bias);
    out.normal = vec4<f32>(select(n.world, n.mapped, n.is_mapped) * 0.5 + vec3<f32>(0.5), 1.0);
#endif
#ifdef MOTION_VECTOR_PREPASS
    // As Bevy's prepass: the unjittered clip position's move since the frame before, in
    // texture coordinates.
    let clip = view.unjittered_clip_from_world * in.world_position;
    let previous = previous_view_uniforms.clip_from_world * in.previous_world_position;
    out.motion_vector = (clip.xy / clip.w - previous.xy / previous.w) * vec2<f32>(0.5, -0.5);
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.depth = in.unclipped_depth;
#endif
    return out;
}
#else
@fragment
fn depth_fragment(in: DepthOut, @builtin(front_facing) is_front: bool) {
    if culled_face(in, is_front) {
        discard;
    }
}
#endif
