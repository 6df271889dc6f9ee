// Group 2 of skinlet's meshlet draw and shadow draw (meshlet_draw.rs), beyond the crowd
// skinning's bindings 0–3: what both shaders read.

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
