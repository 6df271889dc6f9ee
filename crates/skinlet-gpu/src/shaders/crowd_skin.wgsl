// A crowd's vertex skinning (crowd_skinning.rs): per instance, morph deltas, then linear
// blend skinning by the palette skinlet culls with (world space). The same functions serve the
// triangle pass (`skinned_position`) and the caller's draw. Bindings in group 1.

struct Skin {
    joints: u32,
    stride: u32,
    // Morph weights per instance.
    weights: u32,
    // Where the influences, the morph offsets and the morph deltas start in `mesh_words`.
    influences: u32,
    morph_offsets: u32,
    morph_deltas: u32,
    pad0: u32,
    pad1: u32,
}

@group(1) @binding(0) var<uniform> skin: Skin;
// Per instance, per joint: the world-space skinning matrix.
@group(1) @binding(1) var<storage, read> palette: array<mat4x4<f32>>;
// Positions (3 f32 per vertex); per vertex `stride` influences (joint, weight bits); per
// vertex its first morph delta (one more entry than vertices); the deltas (position delta,
// morph weight index).
@group(1) @binding(2) var<storage, read> mesh_words: array<u32>;
// Per instance `weights` morph weights.
@group(1) @binding(3) var<storage, read> morph_weights: array<f32>;

fn mesh_vec3(at: u32) -> vec3<f32> {
    return vec3<f32>(bitcast<f32>(mesh_words[at]), bitcast<f32>(mesh_words[at + 1u]), bitcast<f32>(mesh_words[at + 2u]));
}

// Vertex v of instance i morphed, in its bind space.
fn morphed_position(i: u32, v: u32) -> vec3<f32> {
    var p = mesh_vec3(3u * v);
    for (var d = mesh_words[skin.morph_offsets + v]; d < mesh_words[skin.morph_offsets + v + 1u]; d++) {
        let at = skin.morph_deltas + 4u * d;
        p += mesh_vec3(at) * morph_weights[i * skin.weights + mesh_words[at + 3u]];
    }
    return p;
}

// Vertex v's skinning matrix for instance i: its influences' palette matrices, blended.
fn skin_matrix(i: u32, v: u32) -> mat4x4<f32> {
    var s = mat4x4<f32>();
    for (var k = v * skin.stride; k < (v + 1u) * skin.stride; k++) {
        let at = skin.influences + 2u * k;
        s += palette[i * skin.joints + mesh_words[at]] * bitcast<f32>(mesh_words[at + 1u]);
    }
    return s;
}

// Vertex v of instance i, skinned, in world space.
fn skinned_position(i: u32, v: u32) -> vec3<f32> {
    return (skin_matrix(i, v) * vec4<f32>(morphed_position(i, v), 1.0)).xyz;
}
