// skinlet's own depth pass for occlusion culling among the characters (meshlet_draw.rs): each
// round's culled triangle lists drawn depth only, before Bevy's passes, into the depth the
// next round's tests read. The position is computed as the opaque pass computes it (the same
// crowd skinning, then the view's clip_from_world), so the depth is what that pass's
// characters write.

struct OcclusionView {
    clip_from_world: mat4x4<f32>,
    id_bits: u32,
    // Words of one bit per part (part_hidden).
    part_words: u32,
}

@group(0) @binding(0) var<uniform> occlusion_view: OcclusionView;
// Per corner: bake vertex, source attribute vertex, part, 1 where the part is drawn two-sided.
@group(0) @binding(1) var<storage, read> corners: array<vec4<u32>>;
// Per instance, bit p % 32 of word p / 32 set where part p is hidden (then the same for parts
// casting no shadow: meshlet_group2.wgsl's part_bits).
@group(0) @binding(2) var<storage, read> part_hidden: array<u32>;

struct OcclusionOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) two_sided: u32,
}

@vertex
fn vertex(@builtin(vertex_index) index: u32) -> OcclusionOut {
    let entry = triangle_entry(index, occlusion_view.id_bits);
    let corner = corners[entry.y];
    let bits = part_hidden[2u * entry.x * occlusion_view.part_words + corner.z / 32u];
    if ((bits >> (corner.z % 32u)) & 1u) != 0u {
        // A hidden part: every corner at one point outside the view.
        return OcclusionOut(vec4<f32>(2.0, 2.0, 0.5, 1.0), corner.w);
    }
    let world = skinned_position(entry.x, corner.x);
    return OcclusionOut(occlusion_view.clip_from_world * vec4<f32>(world, 1.0), corner.w);
}

// A bake with parts drawn two-sided is drawn with no faces culled: the other parts' back faces
// are discarded, as the opaque pass culls them.
@fragment
fn two_sided_fragment(in: OcclusionOut, @builtin(front_facing) is_front: bool) {
    if !is_front && in.two_sided == 0u {
        discard;
    }
}
