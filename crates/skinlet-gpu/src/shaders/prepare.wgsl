// Per-joint culling records of a whole crowd on the GPU: one invocation per (instance, joint)
// moves the camera into the joint's bind space and writes the record cull_common.wgsl reads
// (layout there: RECORD floats). It is MeshletCuller::prepare (and its any-pose box planes)
// without the CPU's group shortcuts: every joint gets its six planes, and with the frustum
// test every group straddles, so each meshlet gets its own sphere test.
//
// Rounding: the joint matrix G = model × S × bind is computed here in f32, so every margin
// is taken over |model|·|S|·|bind| (entrywise absolute values, ≥ |G| and ≥ the rounding
// error of G over 1e-6) where the CPU takes |G|, and the eye's margin adds |A⁻¹|·(|t| + |e|)
// for the rounding of e − t. A joint matrix that is not finite, or an instance whose mode is
// "keep" (or unknown), gets a record that culls nothing.

// The same layout as CullParams in cull_common.wgsl (the same uniform buffer).
struct PrepareParams {
    slots: u32,
    joints: u32,
    instances: u32,
    // bit 0: frustum test, bit 1: backface test, bit 2: orthographic camera.
    flags: u32,
    first: u32,
    capacity: u32,
    corners: u32,
    phase: u32,
}

struct CullCamera {
    // Frustum planes (n, w), unit n pointing inside.
    planes: array<vec4<f32>, 6>,
    // The eye (perspective) or the unit view direction (orthographic), w unused.
    view: vec4<f32>,
    // Largest |n| component and largest |w| over the planes (the box margins scale with them).
    nu: f32,
    omega: f32,
    // 1 when the character has any-pose boxes.
    has_boxes: u32,
    pad: u32,
}

// Per instance: its model matrix, how it is culled (0 bounds, 1 bounds and any-pose boxes,
// 2 any-pose boxes alone, 3 nothing culled) and its LOD threshold (crowd_cull.wgsl).
struct CullInstance {
    model: mat4x4<f32>,
    mode: u32,
    lod_threshold: f32,
    pad1: u32,
    pad2: u32,
}

// Per joint: its bind matrix (the inverse of its inverse bind matrix) and the largest
// |c| + r of its meshlets' spheres.
struct JointStatic {
    bind: mat4x4<f32>,
    extent: f32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

const RECORD: u32 = 40u;

@group(0) @binding(0) var<uniform> params: PrepareParams;
@group(0) @binding(1) var<uniform> camera: CullCamera;
// Per instance and joint (instance × joints + joint): the skinning matrix S = global × inverse bind.
@group(0) @binding(2) var<storage, read> palette: array<mat4x4<f32>>;
@group(0) @binding(3) var<storage, read> instances: array<CullInstance>;
@group(0) @binding(4) var<storage, read> joint_statics: array<JointStatic>;
@group(0) @binding(5) var<storage, read_write> records: array<f32>;

fn finite(v: vec4<f32>) -> bool {
    let e = bitcast<vec4<u32>>(v) & vec4<u32>(0x7f800000u);
    return all(e != vec4<u32>(0x7f800000u));
}

fn abs_matrix(m: mat4x4<f32>) -> mat4x4<f32> {
    return mat4x4<f32>(abs(m[0]), abs(m[1]), abs(m[2]), abs(m[3]));
}

fn sum(v: vec3<f32>) -> f32 {
    return v.x + v.y + v.z;
}

// After the records and the instances' LOD thresholds, with occlusion culling, per instance
// and joint 16 floats (crowd_cull.wgsl): the world matrix's three rows, a bound on its spectral norm, the mode
// (0 not occluded, 1 by the spheres, 2 by the any-pose boxes, 3 by both), and for the rounding of the
// product G was formed by, the largest row sum of |model|·|S|·|bind|'s linear part and its
// largest translation entry.
fn write_world(index: u32, g: mat4x4<f32>, m: mat4x4<f32>, mode: f32) {
    let b = params.instances * params.joints * RECORD + params.instances + index * 16u;
    for (var r = 0u; r < 3u; r++) {
        records[b + 4u * r] = g[0][r];
        records[b + 4u * r + 1u] = g[1][r];
        records[b + 4u * r + 2u] = g[2][r];
        records[b + 4u * r + 3u] = g[3][r];
    }
    // σ(G)² ≤ the largest absolute row sum of GᵀG (Gershgorin), with room for rounding.
    let x = g[0].xyz;
    let y = g[1].xyz;
    let z = g[2].xyz;
    let xy = abs(dot(x, y));
    let xz = abs(dot(x, z));
    let yz = abs(dot(y, z));
    let bound = max(max(dot(x, x) + xy + xz, xy + dot(y, y) + yz), xz + yz + dot(z, z));
    records[b + 12u] = sqrt(bound) * (1.0 + 1e-5);
    records[b + 13u] = mode;
    let rows = m[0].xyz + m[1].xyz + m[2].xyz;
    records[b + 14u] = max(max(rows.x, rows.y), rows.z);
    records[b + 15u] = max(max(m[3].x, m[3].y), m[3].z);
}

// Whether the records have occlusion culling's part: its rounds (the `first` word's second
// byte, crowd_cull.wgsl's `round`) are 0 without it.
fn occlusion_records() -> bool {
    return (params.first >> 8u) != 0u;
}

// A record that culls nothing: planes no point is outside of, every group inside, no
// backface test, no boxes.
fn keep(base: u32) {
    for (var k = 0u; k < 6u; k++) {
        records[base + 4u * k] = 0.0;
        records[base + 4u * k + 1u] = 0.0;
        records[base + 4u * k + 2u] = 0.0;
        records[base + 4u * k + 3u] = 1e30;
        records[base + 24u + k] = 0.0;
    }
    for (var k = 30u; k < RECORD; k++) {
        records[base + k] = 0.0;
    }
}

@compute @workgroup_size(64)
fn prepare(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Invocation index = y × 65535 × 64 + x (a 2D grid past 65535 groups).
    let index = gid.y * 65535u * 64u + gid.x;
    if index >= params.joints * params.instances {
        return;
    }
    let instance = instances[index / params.joints];
    let joint = joint_statics[index % params.joints];
    // The instance's LOD threshold after every joint's records (crowd_cull.wgsl): -1, full
    // detail, where it is negative or NaN or the bounds do not hold (the LOD errors hold for
    // the poses the bounds hold for).
    if index % params.joints == 0u {
        let lod = instance.mode <= 1u && instance.lod_threshold >= 0.0;
        records[params.instances * params.joints * RECORD + index / params.joints] =
            select(-1.0, instance.lod_threshold, lod);
    }
    let base = index * RECORD;
    let s = palette[index];
    let g = instance.model * s * joint.bind;
    let m = abs_matrix(instance.model) * abs_matrix(s) * abs_matrix(joint.bind);
    if instance.mode > 2u || !(finite(g[0]) && finite(g[1]) && finite(g[2]) && finite(g[3]) && finite(m[3])) {
        keep(base);
        if occlusion_records() {
            write_world(index, mat4x4<f32>(), mat4x4<f32>(), 0.0);
        }
        return;
    }
    let x = g[0].xyz;
    let y = g[1].xyz;
    let z = g[2].xyz;
    let t = g[3].xyz;
    let ax = m[0].xyz;
    let ay = m[1].xyz;
    let az = m[2].xyz;
    let at = m[3].xyz;
    let bounds = instance.mode <= 1u;
    let boxes = instance.mode >= 1u && camera.has_boxes != 0u;
    if occlusion_records() {
        write_world(index, g, m, select(0.0, 1.0, bounds) + select(0.0, 2.0, boxes));
    }
    let ext = joint.extent;
    // Frustum: n_j = Aᵀn, w_j = n·t + w, |n_j|, and the margin over the planes.
    let t_len = length(at);
    var margin = 0.0;
    for (var k = 0u; k < 6u; k++) {
        let p = camera.planes[k];
        let n = p.xyz;
        let an = abs(n);
        let nj = vec3<f32>(dot(x, n), dot(y, n), dot(z, n));
        let wj = dot(t, n) + p.w;
        // |n_j| and |w_j| bounded through |G|'s entrywise bound.
        let n_mag = vec3<f32>(dot(ax, an), dot(ay, an), dot(az, an));
        let w_mag = dot(at, an) + abs(p.w);
        margin = max(margin, 1e-5 * (w_mag + length(n_mag) * ext + t_len + abs(p.w)));
        records[base + 4u * k] = nj.x;
        records[base + 4u * k + 1u] = nj.y;
        records[base + 4u * k + 2u] = nj.z;
        records[base + 4u * k + 3u] = wj;
        records[base + 24u + k] = length(nj);
    }
    records[base + 30u] = margin;
    // Backface: the eye (or direction) through A⁻¹ = cof(A)ᵀ / det(A).
    var view = vec3<f32>(0.0);
    var sign_det = 0.0;
    var back_margin = 0.0;
    if bounds && (params.flags & 2u) != 0u {
        let c0 = cross(y, z);
        let c1 = cross(z, x);
        let c2 = cross(x, y);
        let det = dot(x, c0);
        let scale2 = max(max(dot(x, x), dot(y, y)), dot(z, z));
        let det2 = det * det;
        if finite(vec4<f32>(det2)) && det2 > 1e-18 * scale2 * scale2 * scale2 {
            let inv_frob2 = (dot(c0, c0) + dot(c1, c1) + dot(c2, c2)) / det2;
            let cond = sqrt((dot(ax, ax) + dot(ay, ay) + dot(az, az)) * inv_frob2);
            let e = camera.view.xyz;
            if (params.flags & 4u) != 0u {
                let v = vec3<f32>(dot(e, c0), dot(e, c1), dot(e, c2)) / det;
                if dot(v, v) > 0.0 {
                    view = normalize(v);
                    sign_det = sign(det);
                }
                back_margin = 1e-5 + 1e-6 * cond;
            } else {
                let d = e - t;
                view = vec3<f32>(dot(d, c0), dot(d, c1), dot(d, c2)) / det;
                sign_det = sign(det);
                let moved = sqrt(inv_frob2) * (sum(at) + sum(abs(e)));
                back_margin = (1e-5 + 1e-6 * cond) * (sum(abs(view)) + ext + moved);
            }
        }
    }
    records[base + 31u] = view.x;
    records[base + 32u] = view.y;
    records[base + 33u] = view.z;
    records[base + 34u] = sign_det;
    records[base + 35u] = back_margin;
    // Group: with the frustum test every group straddles (each meshlet tested); else inside.
    records[base + 36u] = bitcast<f32>(select(0u, 2u, bounds && (params.flags & 1u) != 0u));
    // Any-pose boxes: margin scale·magnitude + offset (MeshletCuller::box_planes).
    if boxes {
        let s_mag = camera.nu * max(max(sum(ax), sum(ay)), sum(az));
        records[base + 37u] = 1e-5 * s_mag;
        records[base + 38u] = 1e-5 * (camera.nu * sum(at) + camera.omega);
        records[base + 39u] = 1.0;
    } else {
        records[base + 37u] = 0.0;
        records[base + 38u] = 0.0;
        records[base + 39u] = 0.0;
    }
}
