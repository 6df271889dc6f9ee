// Linear blend skinning shared by the compute and vertex-shader paths: the same arithmetic
// as skinlet::skinning (the CPU reference): blend the joint matrices by weight, move the
// position, move the normal by the blended matrix's cofactor (sign-corrected), normalize.

struct Params {
    vertices: u32,
    stride: u32,
    normals: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<f32>;
@group(0) @binding(2) var<storage, read> normals: array<f32>;
@group(0) @binding(3) var<storage, read> joints: array<u32>;
@group(0) @binding(4) var<storage, read> weights: array<f32>;
// Per joint four columns (x, y, z axes, translation), as glam's Affine3A lays them out.
@group(0) @binding(5) var<storage, read> matrices: array<vec4<f32>>;

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
    let p = vec3<f32>(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
    var out: Skinned;
    out.position = x * p.x + y * p.y + z * p.z + t;
    out.normal = vec3<f32>(0.0);
    if params.normals != 0u {
        let n = vec3<f32>(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]);
        let c = cross(y, z) * n.x + cross(z, x) * n.y + cross(x, y) * n.z;
        let r = c * sign(dot(x, cross(y, z)));
        let len = length(r);
        out.normal = select(vec3<f32>(0.0), r * (1.0 / len), len > 0.0);
    }
    return out;
}
