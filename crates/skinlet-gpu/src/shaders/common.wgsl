// Linear blend skinning shared by the compute and vertex-shader paths: the same arithmetic
// as skinlet::skinning::skin_mesh (the CPU reference): add the vertex's morph deltas times
// their weights, blend the joint matrices by weight, move the position, move the normal by
// the blended matrix's cofactor (sign-corrected), normalize.

struct Params {
    vertices: u32,
    stride: u32,
    normals: u32,
    // 1 when the mesh has morph deltas; its weights then start at matrices[morph_base].
    morphs: u32,
    morph_base: u32,
    // Where the deltas start in morph_data.
    delta_base: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<f32>;
@group(0) @binding(2) var<storage, read> normals: array<f32>;
@group(0) @binding(3) var<storage, read> joints: array<u32>;
@group(0) @binding(4) var<storage, read> weights: array<f32>;
// The pose: per joint four columns (x, y, z axes, translation), as glam's Affine3A lays them
// out, then the morph weights, four per vec4.
@group(0) @binding(5) var<storage, read> matrices: array<vec4<f32>>;
// Morph deltas: morph_data[v] .. morph_data[v + 1] are vertex v's deltas, each eight words
// from delta_base on: position delta (3 f32), weight index, normal delta (3 f32), 0.
@group(0) @binding(8) var<storage, read> morph_data: array<u32>;

struct Morphed {
    position: vec3<f32>,
    normal: vec3<f32>,
}

// Vertex v's bind-pose position and normal with its morph deltas added, in stored order.
fn morphed(v: u32) -> Morphed {
    var out: Morphed;
    out.position = vec3<f32>(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
    out.normal = vec3<f32>(0.0);
    if params.normals != 0u {
        out.normal = vec3<f32>(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]);
    }
    if params.morphs != 0u {
        for (var d = morph_data[v]; d < morph_data[v + 1u]; d++) {
            let at = params.delta_base + 8u * d;
            let dp = bitcast<vec3<f32>>(vec3<u32>(morph_data[at], morph_data[at + 1u], morph_data[at + 2u]));
            let dn = bitcast<vec3<f32>>(vec3<u32>(morph_data[at + 4u], morph_data[at + 5u], morph_data[at + 6u]));
            let k = morph_data[at + 3u];
            let w = matrices[params.morph_base + k / 4u][k % 4u];
            out.position += w * dp;
            out.normal += w * dn;
        }
    }
    return out;
}

struct Skinned {
    position: vec3<f32>,
    normal: vec3<f32>,
}

fn skin_vertex(v: u32) -> Skinned {
    var x = vec3<f32>(0.0);
    var y = vec3<f32>(0.0);
    var z = vec3<f32>(0.0);
    var t = vec3<f32>(0.0);
    for (var i = 0u; i < params.stride; i++) {
        let w = weights[v * params.stride + i];
        if w == 0.0 {
            break;
        }
        let j = joints[v * params.stride + i] * 4u;
        x += matrices[j].xyz * w;
        y += matrices[j + 1u].xyz * w;
        z += matrices[j + 2u].xyz * w;
        t += matrices[j + 3u].xyz * w;
    }
    let m = morphed(v);
    let p = m.position;
    var out: Skinned;
    out.position = x * p.x + y * p.y + z * p.z + t;
    out.normal = vec3<f32>(0.0);
    if params.normals != 0u {
        let n = m.normal;
        let c = cross(y, z) * n.x + cross(z, x) * n.y + cross(x, y) * n.z;
        let r = c * sign(dot(x, cross(y, z)));
        let len = length(r);
        out.normal = select(vec3<f32>(0.0), r * (1.0 / len), len > 0.0);
    }
    return out;
}
