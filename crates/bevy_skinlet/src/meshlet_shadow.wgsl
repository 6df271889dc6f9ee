// skinlet's meshlet draw in Bevy's shadow views (meshlet_draw.rs): depth only, every corner of
// every instance (the culled list is the camera's), skinned by the crowd skinning (group 2) as
// the main pass skins it, projected with the light view's matrix as Bevy's prepass does.

#import bevy_render::view::View

@group(0) @binding(0) var<uniform> view: View;
// Group 2's corners, draw and no_shadow are in meshlet_group2.wgsl.

struct ShadowOut {
    @builtin(position) position: vec4<f32>,
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @location(0) unclipped_depth: f32,
#endif
}

@vertex
fn shadow_vertex(@builtin(vertex_index) index: u32, @builtin(instance_index) instance: u32) -> ShadowOut {
    var out: ShadowOut;
    let corner = corners[index];
    let bits = no_shadow[instance * draw.shadow_words + corner.z / 32u];
    if ((bits >> (corner.z % 32u)) & 1u) != 0u {
        // Every corner of the part's triangles at one point outside the view: nothing drawn.
        out.position = vec4<f32>(2.0, 2.0, 0.5, 1.0);
        return out;
    }
    out.position = view.clip_from_world * vec4<f32>(skinned_position(instance, corner.x), 1.0);
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    // A directional light's casters in front of its near plane, clamped to it (as Bevy does).
    out.unclipped_depth = out.position.z;
    out.position.z = min(out.position.z, 1.0);
#endif
    return out;
}

#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
@fragment
fn shadow_fragment(in: ShadowOut) -> @builtin(frag_depth) f32 {
    return in.unclipped_depth;
}
#endif
